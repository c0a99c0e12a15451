//! The observation files: CSV readers and writers of the measurement, postures, distance and
//! contact files, each format told by its header ([`FORMATS`], [`detect_format`]). What the
//! observations mean (their residuals and Jacobian rows) is [`crate::observe`]'s.
//!
//! Tables: a header naming the columns, `#` comment lines anywhere (also before the header),
//! blank lines ignored, fields trimmed, the delimiter (`,`, `;` or tab) detected from the header
//! line; in a `;` or tab separated file a number may be written with a decimal comma.
//!
//! Units: a file's numbers are in its robot file's units unless it states its own (a
//! [`ColumnMap`]'s `length_unit` and `angle_unit`, or [`ReadOptions`]); readers return metres and
//! radians, writers write the robot file's units with full precision. Frames: poses and
//! positions are in the measurement frame, the global frame or that of the posture's session
//! (`session` column; [`crate::model::robot::Session`]).
//!
//! The formats:
//! - Measurement file ([`parse_measurements`], [`write_measurements`]): columns `posture, site,
//!   v1..vn, x, y, z`, optionally `alpha, beta, gamma` (a row whose three angles are empty is a
//!   position) and the row's own standard deviations, replacing the default weights for that
//!   row: `sigma_position` (every axis) or `sigma_x, sigma_y, sigma_z` (each axis of the
//!   measurement frame), and `sigma_angle`. Columns may come in any order; `site` may be left
//!   out (every row is then the end effector, `ee`) and so may `posture` (each row is then its
//!   own posture, numbered from 1). Rows of one posture must carry the same readings. A
//!   [`ColumnMap`] reads files laid out otherwise, including several markers side by side in one
//!   row.
//! - Postures file ([`parse_postures`], [`write_postures`]): `posture,v1,...,vn`.
//! - Distance file ([`parse_distances`]): `pair, site, a1..an, b1..bn, distance` and optionally
//!   `sigma_position` (the row's own standard deviation of the distance). `a*` and `b*` are the
//!   readings of the two postures, `site` as in measurement files (`ee` when left out). The two
//!   postures of pair `P` are labelled `P/a` and `P/b`.
//! - Contact file ([`parse_contacts`]): `posture, site, plane, v1..vn` and optionally `gap` (the
//!   target's known distance from the plane along its normal: a probe ball's radius, a gauge
//!   block; default 0) and `sigma_position` (the row's own standard deviation). `site` as in
//!   measurement files (`ee` when left out); `plane` names a plane of the robot file and may be
//!   left out when the robot has only one.
//! - Pixel file ([`parse_pixels`]): `posture, camera, point, v1..vn, u, v` and optionally
//!   `sigma_px` (the row's own standard deviation, pixels). `camera` names a camera of the robot
//!   file (left out when it has one); `point` a board's point as `BOARD:K` (0-based, row-major)
//!   or a target as in measurement files (a marker the camera sees); `u, v` the pixel where it
//!   was seen (OpenCV's image coordinates: the origin at the top-left pixel's centre, u to the
//!   right, v down), from the user's corner or marker detector.

mod cleanup;
mod contacts;
pub mod controller;
mod distances;
mod measurements;
pub mod output;
mod pixels;
mod read;
pub mod stream;
pub(crate) mod table;

use std::fmt;

use crate::error::{Error, Result};
use crate::model::kinematics::Target;
use crate::model::robot::Robot;
use crate::observe::{Dataset, Observation};

pub use contacts::parse_contacts;
pub use distances::parse_distances;
pub use measurements::{
    parse_measurements, parse_measurements_mapped, parse_postures, write_measurements,
    write_postures, ColumnMap, NOT_READ,
};
pub use pixels::parse_pixels;
pub use read::{read_files, ObservationFile, ReadSettings};

pub(crate) use contacts::write_contacts;
pub(crate) use distances::write_distances;
pub(crate) use measurements::{
    note_compensated_columns, postures_header, write_posture_readings, COMPENSATED_COLUMNS,
    PAYLOAD_COLUMNS,
};
pub(crate) use pixels::write_pixels;
pub(crate) use read::kind_index;

/// The observations of `data` as one file of kinecal's, read back to the same numbers: a
/// measurement file for poses and positions ([`write_measurements`]), a distance file for
/// distances (`write_distances`), a contact file for contacts (`write_contacts`), a pixel file
/// for pixels (`write_pixels`). A file holds one of these four; observations of two of them
/// are refused, naming the kinds found.
pub fn write_observations(robot: &Robot, data: &Dataset) -> Result<String> {
    let kinds = data.kinds();
    let family = |k: &str| match k {
        "pose" | "position" => 0,
        "distance" => 1,
        "pixel" => 3,
        _ => 2,
    };
    let families: std::collections::BTreeSet<usize> =
        kinds.iter().map(|(k, _)| family(k)).collect();
    if families.len() > 1 {
        return Err(Error::Problem(format!(
            "one file holds poses and positions, or distances, or contacts, or pixels; these \
             observations hold {}: write each kind from its own measurements (before merging \
             them)",
            kinds
                .iter()
                .map(|(k, n)| format!("{n} {k}"))
                .collect::<Vec<_>>()
                .join(", ")
        )));
    }
    Ok(match families.first() {
        Some(1) => write_distances(robot, data),
        Some(2) => write_contacts(robot, data),
        Some(3) => write_pixels(robot, data),
        _ => write_measurements(robot, data),
    })
}

/// A file format of observations, for the command line and other front ends.
#[derive(Clone, Copy)]
pub struct Format {
    /// The name of such files (`data`, `distances`, `contacts`); front ends name their options
    /// after it.
    pub option: &'static str,
    /// One line for help texts.
    pub help: &'static str,
    /// The header, e.g. `posture,site,v1..vn,x,y,z[,alpha,beta,gamma]`.
    pub header: &'static str,
    /// The kinds of observation its rows become.
    pub kinds: &'static [&'static str],
    /// Columns that tell such a file by its header ([`detect_format`]); empty for the
    /// measurement file, the format of any other header.
    pub marks: &'static [&'static str],
    /// Reads a file (`text`, named `file` in errors) for `robot`.
    pub parse: fn(&str, &str, &Robot) -> Result<Dataset>,
}

impl fmt::Debug for Format {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Format({})", self.option)
    }
}

/// Every observation file format, the measurement file (`data`) first.
pub const FORMATS: &[Format] = &[
    measurements::FORMAT,
    distances::FORMAT,
    contacts::FORMAT,
    pixels::FORMAT,
];

/// The format of an observation file, told by its header (the first line that is not blank or
/// a `#` comment): the first format all of whose [`Format::marks`] columns it names, else the
/// measurement file. Returns the index into [`FORMATS`].
pub fn detect_format(text: &str) -> usize {
    let delimiter = table::detect_delimiter(text) as char;
    let header: Vec<String> = text
        .lines()
        .map(str::trim)
        .find(|l| !l.is_empty() && !table::is_comment(l))
        .unwrap_or("")
        .trim_start_matches('\u{feff}')
        .split(delimiter)
        .map(|c| c.trim().trim_matches('"').to_ascii_lowercase())
        .collect();
    FORMATS
        .iter()
        .position(|f| !f.marks.is_empty() && f.marks.iter().all(|m| header.iter().any(|h| h == m)))
        .unwrap_or(0)
}

/// How an observation file is read, beyond its header: the column mapping of a measurement
/// file (which may state the file's units), the units of its numbers, and whether to read its
/// poses as positions only.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ReadOptions {
    /// The column mapping of a measurement file ([`ColumnMap`]); files of the other
    /// formats are read by their own headers.
    pub columns: ColumnMap,
    /// The unit of the file's lengths, when not the robot file's (a mapping's `length_unit`
    /// must agree).
    pub length_unit: Option<crate::units::LengthUnit>,
    /// The unit of the file's angles, when not the robot file's.
    pub angle_unit: Option<crate::units::AngleUnit>,
    /// Read poses as positions (their attitudes and `sigma_angle` left out).
    pub position_only: bool,
}

impl ReadOptions {
    /// The units of a file read with these options for `robot`; an error when the mapping and
    /// the options state different ones.
    pub fn units(&self, robot: &Robot, file: &str) -> Result<crate::units::Units> {
        let conflict = |what: &str, a: String, b: String| {
            Error::input(
                crate::error::Location::file(file),
                format!("the {what} unit is stated twice: `{a}` in the column mapping, `{b}` as an option"),
            )
        };
        if let (Some(a), Some(b)) = (self.columns.length_unit, self.length_unit) {
            if a != b {
                return Err(conflict("length", a.to_string(), b.to_string()));
            }
        }
        if let (Some(a), Some(b)) = (self.columns.angle_unit, self.angle_unit) {
            if a != b {
                return Err(conflict("angle", a.to_string(), b.to_string()));
            }
        }
        Ok(crate::units::Units {
            length: self
                .columns
                .length_unit
                .or(self.length_unit)
                .unwrap_or(robot.units.length),
            angle: self
                .columns
                .angle_unit
                .or(self.angle_unit)
                .unwrap_or(robot.units.angle),
        })
    }
}

/// Reads an observation file of any format (told by its header, [`detect_format`]) for
/// `robot`: `text`, named `file` in errors, its numbers in the units `opts` states (by default
/// the robot file's), converted to metres and radians.
pub fn read_observations(
    text: &str,
    file: &str,
    robot: &Robot,
    opts: &ReadOptions,
) -> Result<Dataset> {
    read_observations_as(text, file, robot, opts, detect_format(text))
}

/// [`read_observations`] as a file of the format `FORMATS[format]`, whatever its header (which
/// that format's reader then checks).
pub(crate) fn read_observations_as(
    text: &str,
    file: &str,
    robot: &Robot,
    opts: &ReadOptions,
    format: usize,
) -> Result<Dataset> {
    let units = opts.units(robot, file)?;
    // Every reader converts with its robot's units: give it the file's.
    let mut reading = robot.clone();
    reading.units = units;
    let mut data = if format == 0 {
        let mut columns = opts.columns.clone();
        columns.length_unit = Some(units.length);
        columns.angle_unit = Some(units.angle);
        measurements::parse_measurements_mapped(text, file, &reading, &columns)?
    } else {
        let pairs = &opts.columns;
        if !(pairs.shared.is_empty() && pairs.markers.is_empty()) {
            return Err(Error::input(
                crate::error::Location::file(file),
                format!(
                    "a column mapping applies to measurement files, and this is a {} file",
                    FORMATS[format].option
                ),
            ));
        }
        (FORMATS[format].parse)(text, file, &reading)?
    };
    if opts.position_only {
        for o in &mut data.observations {
            if let Observation::Pose(p) = o {
                *o = p.to_position().into();
            }
        }
    }
    Ok(data)
}

/// The column that heads joint `j`'s (0-based) readings in a file of `header`: `vK` (K = j + 1),
/// or the joint's name (robot file `[[joints]] name`) when the file has that column and not `vK`.
/// Names are compared as the header's other columns are, ignoring ASCII case.
pub(crate) fn reading_column(robot: &Robot, header: &[String], j: usize) -> String {
    let v = format!("v{}", j + 1);
    let has = |c: &str| header.iter().any(|h| h.eq_ignore_ascii_case(c));
    match &robot.joints[j].name {
        Some(name) if !has(&v) && has(name) => name.clone(),
        _ => v,
    }
}

/// Where a file's joint readings are, told by its header: each joint's column
/// ([`reading_column`]), and the columns of other joints the file carries.
///
/// A file written for a larger robot (the 13 joints of two arms on a torso, read against one
/// arm's chain) carries joints this robot does not have. When every joint of the robot is read
/// by its own name, the header's columns that are neither the format's (`known`) nor this
/// robot's readings are those other joints': they are read past, with a note naming them
/// ([`ReadingColumns::note`]). A file read by `vK` columns has no such columns: `vK` says
/// nothing of which joint it is.
pub(crate) struct ReadingColumns {
    /// Per joint (0-based), the column heading its readings.
    pub names: Vec<String>,
    /// The other joints' columns, read past, as the header spells them.
    pub others: Vec<String>,
}

impl ReadingColumns {
    /// The reading columns of `robot` in a file of `header`, whose format's own columns are
    /// `known` (ASCII case ignored, as everywhere in headers).
    pub fn of(robot: &Robot, header: &[String], known: &[&str]) -> ReadingColumns {
        let names: Vec<String> = (0..robot.dof())
            .map(|j| reading_column(robot, header, j))
            .collect();
        let by_name = robot
            .joints
            .iter()
            .zip(&names)
            .all(|(joint, c)| joint.name.as_deref() == Some(c.as_str()));
        let others = if by_name {
            header
                .iter()
                .filter(|h| {
                    !h.is_empty()
                        && !known.iter().any(|k| k.eq_ignore_ascii_case(h))
                        && !names.iter().any(|c| c.eq_ignore_ascii_case(h))
                })
                .cloned()
                .collect()
        } else {
            Vec::new()
        };
        ReadingColumns { names, others }
    }

    /// Refuses readings whose columns are both this robot's joint names and a controller
    /// brand's joint targets in another angle unit (`J1..J6` of a radian robot are FANUC's
    /// degrees too, as `kinecal compensate --format joints-fanuc` writes them): the file's unit
    /// cannot be told, and the wrong one moves every joint (such a table was read back in
    /// radians). `file` names the file in the error.
    pub fn check_brand_clash(&self, robot: &Robot, file: &str) -> Result<()> {
        use crate::files::controller::Brand;
        let Some(brand) = Brand::ALL.into_iter().find(|b| {
            !self.names.is_empty()
                && b.angle_unit() != robot.units.angle
                && b.columns(robot).is_ok_and(|names| {
                    names.len() == self.names.len()
                        && names
                            .iter()
                            .zip(&self.names)
                            .all(|(a, b)| a.eq_ignore_ascii_case(b))
                })
        }) else {
            return Ok(());
        };
        let n = self.names.len();
        Err(Error::input(
            crate::error::Location::file(file).at_line(1),
            format!(
                "the columns `{}..{}` are this robot's joint names (readings in {}) and {}'s \
                 joint targets too (`kinecal compensate --format joints-{}` writes them in {}): \
                 the file's unit cannot be told; head the readings `v1..v{n}` (in {}), or give \
                 the robot's joints other names",
                self.names[0],
                self.names[n - 1],
                robot.units.angle.as_str(),
                brand.as_str().to_uppercase(),
                brand.as_str(),
                brand.angle_unit().as_str(),
                robot.units.angle.as_str(),
            ),
        ))
    }

    /// Whether header column `h` is another joint's, read past.
    pub fn is_other(&self, h: &str) -> bool {
        self.others.iter().any(|o| o.eq_ignore_ascii_case(h))
    }

    /// Says which columns of `file` were read past as other joints' (nothing when none were).
    pub fn note(&self, file: &str, robot: &Robot) {
        if self.others.is_empty() {
            return;
        }
        note(format!(
            "{file}: column{} {} {} no joint of this robot (its {} joints are read by their \
             names): read past, as another robot's joints",
            if self.others.len() == 1 { "" } else { "s" },
            self.others
                .iter()
                .map(|o| format!("`{o}`"))
                .collect::<Vec<_>>()
                .join(", "),
            if self.others.len() == 1 {
                "names"
            } else {
                "name"
            },
            robot.dof()
        ));
    }
}

thread_local! {
    /// What the readers said of the files they read on this thread ([`take_notes`]).
    static NOTES: std::cell::RefCell<Vec<String>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// At most this many notes wait to be taken (a program that never takes them keeps no more).
const MAX_NOTES: usize = 64;

/// Keeps a note of a reader's, once, for [`take_notes`].
pub(crate) fn note(text: String) {
    NOTES.with(|n| {
        let mut n = n.borrow_mut();
        if n.len() < MAX_NOTES && !n.contains(&text) {
            n.push(text);
        }
    });
}

/// The notes the file readers made on this thread since the last call, in order, each once
/// (columns read past, ...). A job ([`crate::spec::run`]) returns them among its messages; a
/// program calling the readers itself takes them here.
pub fn take_notes() -> Vec<String> {
    NOTES.with(|n| std::mem::take(&mut *n.borrow_mut()))
}

/// Puts `notes` back, before any made since (a job run inside another keeps the outer one's).
pub(crate) fn restore_notes(mut notes: Vec<String>) {
    NOTES.with(|n| {
        let mut n = n.borrow_mut();
        notes.append(&mut n);
        *n = notes;
    });
}

/// The target a `site` field names: the end effector when it is empty, else as
/// [`Target::named`] says (`ee` or the end effector's own name, or a site's); otherwise
/// the message of the error, which lists the robot's targets.
pub fn site_target(robot: &Robot, name: &str) -> std::result::Result<Target, String> {
    if name.is_empty() {
        return Ok(Target::EndEffector);
    }
    Target::named(robot, name).ok_or_else(|| {
        format!(
            "unknown site `{name}` (the robot file defines: {})",
            robot.target_names().join(", ")
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formats_are_told_by_their_header() {
        let name = |t: &str| FORMATS[detect_format(t)].option;
        assert_eq!(name("posture,site,v1,v2,x,y,z\n"), "data");
        assert_eq!(
            name("# ballbar\n\npair,a1,a2,b1,b2,distance\n"),
            "distances"
        );
        assert_eq!(name("\u{feff}posture;plane;v1;v2\n"), "contacts");
        assert_eq!(name("Point,J1,J2,X,Y,Z\n"), "data");
        assert_eq!(name(""), "data");
    }
}
