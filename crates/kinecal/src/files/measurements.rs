//! The measurement file (poses and positions of the end effector or sites, as a laser tracker, a
//! camera or a CMM measures them) and the postures file: their columns, the [`ColumnMap`] of
//! other layouts, readers and writers (see the [module](super) for the formats).

use std::collections::HashMap;
use std::fmt::Write as _;

use nalgebra::Vector3;

use super::table::{self, PostureTable};
use super::{site_target, Format};
use crate::error::{Error, Location, Result};
use crate::model::kinematics::Target;
use crate::model::robot::{JointKind, Robot};
use crate::observe::point::{Pose, Position};
use crate::observe::{target_name, Dataset, Observation, Posture, View};
use crate::units::number::{self, Scale};
use crate::units::Quantity;

/// The measurement file format.
pub(super) const FORMAT: Format = Format {
    option: "data",
    kinds: &["pose", "position"],
    marks: &[],
    help: "Measurement file: poses or positions of the end effector or sites",
    header: "posture,site,v1..vn,x,y,z[,alpha,beta,gamma][,sigma_position|sigma_x,sigma_y,sigma_z][,sigma_angle][,payload_mass,payload_cx,payload_cy,payload_cz]",
    parse: parse_measurements,
};

/// The columns `kinecal compensate` adds to a measurement file it solved.
pub(crate) const COMPENSATED_COLUMNS: [&str; 4] =
    ["position_error", "attitude_error", "iterations", "flags"];

/// Says which of the columns `kinecal compensate` adds ([`COMPENSATED_COLUMNS`]) the file
/// `file` of header `spelled` carries, read past as postures are read from it (nothing when it
/// has none), as [`super::ReadingColumns::note`] says of other joints' columns.
pub(crate) fn note_compensated_columns(file: &str, spelled: &[String]) {
    let found: Vec<String> = spelled
        .iter()
        .filter(|h| {
            COMPENSATED_COLUMNS
                .iter()
                .any(|c| c.eq_ignore_ascii_case(h))
        })
        .map(|h| format!("`{h}`"))
        .collect();
    if found.is_empty() {
        return;
    }
    super::note(format!(
        "{file}: column{} {} {} what `kinecal compensate` adds (its remaining errors and flags): \
         read past",
        if found.len() == 1 { "" } else { "s" },
        found.join(", "),
        if found.len() == 1 { "is" } else { "are" },
    ));
}

/// The columns of the payload a posture's tool carries (kg; centre of mass in the end-effector
/// frame, in the file's length unit): an elastic robot's joints yield to its weight.
pub(crate) const PAYLOAD_COLUMNS: [&str; 4] =
    ["payload_mass", "payload_cx", "payload_cy", "payload_cz"];

/// Names of the columns of one measured target.
const MARKER_COLUMNS: [&str; 11] = [
    "x",
    "y",
    "z",
    "alpha",
    "beta",
    "gamma",
    "sigma_position",
    "sigma_angle",
    "sigma_x",
    "sigma_y",
    "sigma_z",
];

/// Mapped to this (`alpha=-`), a kinecal column is left out: not read even if the file has a
/// column of that name.
pub const NOT_READ: &str = "-";

fn reading_columns(n: usize) -> Vec<String> {
    (1..=n).map(|i| format!("v{i}")).collect()
}

/// The measurement header kinecal writes for `robot` (with the `site` column).
fn measurement_header(robot: &Robot) -> Vec<String> {
    let mut h = vec!["posture".to_string(), "site".to_string()];
    h.extend(reading_columns(robot.dof()));
    h.extend(["x", "y", "z", "alpha", "beta", "gamma"].map(String::from));
    h
}

/// The postures-file header for `robot`.
pub(crate) fn postures_header(robot: &Robot) -> Vec<String> {
    let mut h = vec!["posture".to_string()];
    h.extend(reading_columns(robot.dof()));
    h
}

/// How a measurement file's columns map to kinecal's (`posture`, `site`, `v1..vn`, `x, y, z`,
/// `alpha, beta, gamma`, `sigma_position` or `sigma_x, sigma_y, sigma_z`, `sigma_angle`):
/// pairs `(ours, theirs)`. A kinecal column not mapped is looked up under its own name; one
/// mapped to `-` ([`NOT_READ`]) is left out (`alpha=-,beta=-,gamma=-` reads a pose file's
/// positions only); other columns of the file are ignored. Two more entries state the file's
/// units, when they are not the robot file's: `length_unit=mm`, `angle_unit=deg`.
///
/// `markers` reads several targets measured side by side in one row (FIGAROH's wide layout
/// `x1,y1,z1,x2,y2,z2,...`): each marker is a site name (or `ee`) with the mapping of its
/// `x..sigma_angle` columns; the shared mapping then gives the posture and the readings, and
/// a marker whose position fields are all empty in a row was not measured there.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ColumnMap {
    /// Shared columns.
    pub shared: Vec<(String, String)>,
    /// Markers side by side: (site or `ee`, its columns).
    pub markers: Vec<(String, Vec<(String, String)>)>,
    /// The file's length unit, when stated (`length_unit=...`).
    pub length_unit: Option<crate::units::LengthUnit>,
    /// The file's angle unit, when stated (`angle_unit=...`).
    pub angle_unit: Option<crate::units::AngleUnit>,
}

impl ColumnMap {
    /// Parses mappings written `[SITE:]ours=theirs,...`, one per string: a mapping with a
    /// `SITE:` prefix is a marker, one without it the shared columns. `source` names them in
    /// errors.
    pub fn parse(specs: &[&str], source: &str) -> Result<ColumnMap> {
        let loc = Location::file(source);
        let mut map = ColumnMap::default();
        for spec in specs {
            let (site, body) = match spec.split_once(':') {
                Some((s, b)) if !s.contains('=') => (Some(s.trim().to_string()), b),
                _ => (None, *spec),
            };
            let mut pairs: Vec<(String, String)> = Vec::new();
            for part in body.split(',').map(str::trim).filter(|p| !p.is_empty()) {
                let (a, b) = part.split_once('=').ok_or_else(|| {
                    Error::input(
                        loc.clone(),
                        format!("`{part}`: expected KINECAL_COLUMN=FILE_COLUMN, e.g. v1=q1"),
                    )
                })?;
                let (a, b) = (a.trim().to_string(), b.trim().to_string());
                if site.is_none() && a == "length_unit" {
                    map.length_unit = Some(
                        b.parse()
                            .map_err(|m: String| Error::input(loc.clone(), m))?,
                    );
                    continue;
                }
                if site.is_none() && a == "angle_unit" {
                    map.angle_unit = Some(
                        b.parse()
                            .map_err(|m: String| Error::input(loc.clone(), m))?,
                    );
                    continue;
                }
                if a.is_empty() || b.is_empty() {
                    return Err(Error::input(
                        loc.clone(),
                        format!("`{part}`: both column names are needed"),
                    ));
                }
                if let Some((_, t)) = pairs.iter().find(|(o, _)| *o == a) {
                    return Err(Error::input(
                        loc.clone(),
                        format!("`{a}` is mapped twice (to `{t}` and to `{b}`)"),
                    ));
                }
                if let Some((o, _)) = pairs.iter().find(|(_, t)| *t == b && b != NOT_READ) {
                    return Err(Error::input(
                        loc.clone(),
                        format!("file column `{b}` is mapped to both `{o}` and `{a}`"),
                    ));
                }
                pairs.push((a, b));
            }
            match site {
                Some(s) => {
                    if s.is_empty() {
                        return Err(Error::input(loc.clone(), "empty site name before `:`"));
                    }
                    if let Some((o, _)) = pairs
                        .iter()
                        .find(|(o, _)| !MARKER_COLUMNS.contains(&o.as_str()))
                    {
                        return Err(Error::input(
                            loc.clone(),
                            format!(
                                "marker `{s}`: `{o}` is not a marker column (expected {})",
                                MARKER_COLUMNS.join(", ")
                            ),
                        ));
                    }
                    if map.markers.iter().any(|(m, _)| *m == s) {
                        return Err(Error::input(
                            loc.clone(),
                            format!("marker `{s}` is mapped twice"),
                        ));
                    }
                    map.markers.push((s, pairs));
                }
                None => {
                    if !map.shared.is_empty() {
                        return Err(Error::input(
                            loc.clone(),
                            "only one mapping without a SITE: prefix (the shared columns)",
                        ));
                    }
                    map.shared = pairs;
                }
            }
        }
        Ok(map)
    }

    fn is_identity(&self) -> bool {
        self.shared.is_empty() && self.markers.is_empty()
    }

    /// The units the file's numbers are in: the stated ones, else `robot`'s.
    pub fn units(&self, robot: &Robot) -> crate::units::Units {
        crate::units::Units {
            length: self.length_unit.unwrap_or(robot.units.length),
            angle: self.angle_unit.unwrap_or(robot.units.angle),
        }
    }
}

/// Parses a measurement file for `robot`. `file` names it in error messages.
pub fn parse_measurements(text: &str, file: &str, robot: &Robot) -> Result<Dataset> {
    parse_measurements_mapped(text, file, robot, &ColumnMap::default())
}

/// One target's columns in the file.
struct Marker {
    /// Fixed site (a marker of a wide layout), or read from the `site` column.
    target: Option<Target>,
    /// Column indices of [`MARKER_COLUMNS`].
    cols: [Option<usize>; 11],
    /// The file's names of those columns (for error messages).
    names: [String; 11],
}

/// The payload of one row: none when its `payload_mass` cell is empty; else the mass (kg,
/// finite, 0 to 1e6) and the centre of mass (file length unit, 0 where a column is absent or
/// empty).
fn payload_of(
    t: &table::Table<'_>,
    line: usize,
    f: &table::Fields<'_>,
    cols: &[(Option<usize>, String)],
    units: &crate::units::Units,
) -> Result<Option<crate::model::robot::Payload>> {
    let Some(mass_col) = cols[0].0 else {
        return Ok(None);
    };
    if f.get(mass_col).trim().is_empty() {
        if let Some((_, name)) = cols[1..]
            .iter()
            .find(|(c, _)| c.is_some_and(|i| !f.get(i).trim().is_empty()))
        {
            return Err(Error::input(
                t.at(line, name),
                "a payload's centre of mass without its mass (`payload_mass` is empty)",
            ));
        }
        return Ok(None);
    }
    let mass = t.number(line, &cols[0].1, f.get(mass_col))?;
    if let Some(problem) = crate::model::robot::Payload::mass_problem(mass) {
        return Err(Error::input(t.at(line, &cols[0].1), problem));
    }
    let mut com = Vector3::zeros();
    for (k, (col, name)) in cols[1..].iter().enumerate() {
        if let Some(i) = col {
            let text = f.get(*i);
            if !text.trim().is_empty() {
                com[k] = units.to_si(Quantity::Length, t.number(line, name, text)?);
            }
        }
    }
    Ok(Some(crate::model::robot::Payload { mass, com }))
}

/// Parses a measurement file whose columns `map` maps to kinecal's (see [`ColumnMap`]).
pub fn parse_measurements_mapped(
    text: &str,
    file: &str,
    robot: &Robot,
    map: &ColumnMap,
) -> Result<Dataset> {
    let t = table::read(text, file)?;
    let mut known = canonical_columns(robot.dof());
    known.extend(COMPENSATED_COLUMNS.map(String::from));
    let known: Vec<&str> = known.iter().map(String::as_str).collect();
    let readings = super::ReadingColumns::of(robot, &t.header, &known);
    let plain = map.is_identity();
    let map = with_named_readings(&readings, map);
    let layout = Layout::of(&t, robot, &map)?;
    t.check_rows()?;
    layout.check_sigma_columns(&t)?;
    let mut rows = Rows {
        t: &t,
        robot,
        layout: &layout,
        units: map.units(robot),
        postures: PostureTable::with_capacity(t.rows().count()),
        observations: Vec::with_capacity(t.rows().count() * layout.markers.len()),
        seen: TargetsSeen::default(),
        sessions: Vec::new(),
    };
    let mut numbered = String::new();
    for (row_number, (line, f)) in t.rows().enumerate() {
        let label = match layout.posture {
            Some(i) => f.get(i),
            None => {
                numbered.clear();
                numbered.push_str(&(row_number + 1).to_string());
                &numbered
            }
        };
        rows.row(line, label, &f)?;
    }
    let data = rows
        .postures
        .into_dataset(rows.observations, file, "measurements", &rows.units)?;
    if plain {
        // A mapped file's other columns are read past without a word, as they always were.
        readings.note(file, robot);
    }
    Ok(data)
}

/// `map` with the readings headed by the joints' names instead of `vK` mapped (an implicit
/// mapping).
fn with_named_readings(readings: &super::ReadingColumns, map: &ColumnMap) -> ColumnMap {
    let mut named = map.clone();
    for (v, column) in reading_columns(readings.names.len())
        .iter()
        .zip(&readings.names)
    {
        if column != v && !named.shared.iter().any(|(o, _)| o == v) {
            named.shared.push((v.clone(), column.clone()));
        }
    }
    named
}

/// kinecal's own columns, in the order of the format's header.
fn canonical_columns(n: usize) -> Vec<String> {
    let mut canonical: Vec<String> = vec!["posture".into(), "site".into(), "session".into()];
    canonical.extend(PAYLOAD_COLUMNS.iter().map(|s| s.to_string()));
    canonical.extend(reading_columns(n));
    canonical.extend(MARKER_COLUMNS.iter().map(|s| s.to_string()));
    canonical
}

/// Where each of kinecal's columns is in a file, as its header and the column mapping say.
struct Layout {
    /// The posture labels (numbered by row without).
    posture: Option<usize>,
    /// The site of each row (the end effector without).
    site: Option<usize>,
    /// The session of each row, and the file's name of that column.
    session: (Option<usize>, String),
    /// The payload columns ([`PAYLOAD_COLUMNS`]).
    payload: Vec<(Option<usize>, String)>,
    /// The joint readings.
    readings: Vec<(usize, String)>,
    /// The measured targets' columns: one for a long layout, one per marker for a wide one.
    markers: Vec<Marker>,
    /// A wide layout: a row may leave a marker out.
    wide: bool,
}

/// Finds kinecal's columns in a table's header, through a column mapping.
struct Finder<'a, 't> {
    t: &'a table::Table<'t>,
    n: usize,
}

impl Finder<'_, '_> {
    /// The file's name for kinecal's column `ours` in `mapping`.
    fn theirs(mapping: &[(String, String)], ours: &str) -> String {
        mapping
            .iter()
            .find(|(o, _)| o == ours)
            .map_or(ours.to_string(), |(_, t)| t.clone())
    }

    /// Where kinecal's column `ours` is (its index, the file's name for it); an error when a
    /// `required` one, or one the mapping names, is not there.
    fn find(
        &self,
        mapping: &[(String, String)],
        ours: &str,
        required: bool,
    ) -> Result<(Option<usize>, String)> {
        let t = self.t;
        let name = Self::theirs(mapping, ours);
        let explicit = mapping.iter().any(|(o, _)| o == ours);
        if name == NOT_READ {
            return if required {
                Err(Error::input(
                    t.header_at(),
                    format!("column mapping `{ours}=-`: `{ours}` cannot be left out"),
                ))
            } else {
                Ok((None, name))
            };
        }
        match t.column(&name) {
            Some(i) => Ok((Some(i), name)),
            None if explicit => Err(Error::input(
                t.header_at().with_field(name.clone()),
                format!(
                    "column mapping `{ours}={name}`: no column `{name}` in the header `{}`",
                    t.header.join(",")
                ),
            )),
            None if !required => Ok((None, name)),
            None => Err(Error::input(
                t.header_at().with_field(name.clone()),
                format!(
                    "no column `{name}`{} in the header `{}` (expected {}){}",
                    if name == ours {
                        String::new()
                    } else {
                        format!(" (for kinecal's `{ours}`)")
                    },
                    t.header.join(","),
                    FORMAT.header.replace("v1..vn", &format!("v1..v{}", self.n)),
                    super::table::header_hint(&t.header)
                ),
            )),
        }
    }

    /// The columns of one measured target.
    fn marker(&self, mapping: &[(String, String)], target: Option<Target>) -> Result<Marker> {
        let mut cols = [None; 11];
        let mut names: [String; 11] = Default::default();
        for (k, c) in MARKER_COLUMNS.iter().enumerate() {
            let (i, name) = self.find(mapping, c, k < 3)?;
            cols[k] = i;
            names[k] = name;
        }
        Ok(Marker {
            target,
            cols,
            names,
        })
    }
}

impl Layout {
    /// The layout of table `t` for `robot` through `map`.
    fn of(t: &table::Table<'_>, robot: &Robot, map: &ColumnMap) -> Result<Layout> {
        let n = robot.dof();
        let canonical = canonical_columns(n);
        if let Some((ours, _)) = map.shared.iter().find(|(o, _)| !canonical.contains(o)) {
            return Err(Error::input(
                t.header_at(),
                format!(
                    "column mapping: `{ours}` is not a kinecal column (expected one of {})",
                    canonical.join(", ")
                ),
            ));
        }
        let finder = Finder { t, n };
        let find = |ours: &str| finder.find(&map.shared, ours, false);
        let posture = find("posture")?.0;
        let site = find("site")?.0;
        let session = find("session")?;
        let payload = PAYLOAD_COLUMNS
            .iter()
            .map(|c| find(c))
            .collect::<Result<Vec<_>>>()?;
        if payload[0].0.is_none() {
            if let Some((_, name)) = payload[1..].iter().find(|(i, _)| i.is_some()) {
                return Err(Error::input(
                    t.header_at().with_field(name.clone()),
                    "a payload's centre of mass without `payload_mass` (kg)",
                ));
            }
        }
        let readings = reading_columns(n)
            .iter()
            .map(|r| {
                let (i, name) = finder.find(&map.shared, r, true)?;
                // A required column is found or refused.
                Ok((i.unwrap_or_default(), name))
            })
            .collect::<Result<Vec<_>>>()?;
        let layout = Layout {
            posture,
            site,
            session,
            payload,
            readings,
            markers: markers(&finder, robot, map, site.is_some())?,
            wide: !map.markers.is_empty(),
        };
        if map.is_identity() {
            check_plain_header(t, n, &canonical)?;
        }
        Ok(layout)
    }

    /// Each target's standard deviations: all three axes or none, and not with a
    /// `sigma_position` as well.
    fn check_sigma_columns(&self, t: &table::Table<'_>) -> Result<()> {
        for m in &self.markers {
            let axes = m.cols[8..11].iter().filter(|c| c.is_some()).count();
            if axes > 0 && axes < 3 {
                return Err(Error::input(
                    t.header_at(),
                    "per-axis standard deviations: give all of sigma_x, sigma_y, sigma_z",
                ));
            }
            if axes == 3 && m.cols[6].is_some() {
                return Err(Error::input(
                    t.header_at().with_field(m.names[6].clone()),
                    "give sigma_position (every axis) or sigma_x, sigma_y, sigma_z (each axis), \
                     not both",
                ));
            }
        }
        Ok(())
    }
}

/// The measured targets' columns: the shared mapping's one target (its site from the `site`
/// column), or one per marker of a wide layout (each mapped to its own columns, none twice).
fn markers(
    finder: &Finder<'_, '_>,
    robot: &Robot,
    map: &ColumnMap,
    has_site: bool,
) -> Result<Vec<Marker>> {
    let t = finder.t;
    if map.markers.is_empty() {
        return Ok(vec![finder.marker(&map.shared, None)?]);
    }
    if let Some((o, th)) = map
        .shared
        .iter()
        .find(|(o, _)| MARKER_COLUMNS.contains(&o.as_str()))
    {
        return Err(Error::input(
            t.header_at(),
            format!(
                "column mapping: `{o}={th}` in the shared mapping is not used when markers are \
                 given: map it in each marker (`SITE:{o}={th}`)"
            ),
        ));
    }
    let mut used: HashMap<&str, &str> = HashMap::new();
    for (site, mapping) in &map.markers {
        for (_, th) in mapping {
            match used.insert(th.as_str(), site.as_str()) {
                Some(other) if other != site => {
                    return Err(Error::input(
                        t.header_at().with_field(th.clone()),
                        format!(
                            "column mapping: file column `{th}` is mapped for both markers \
                             `{other}` and `{site}`"
                        ),
                    ));
                }
                _ => {}
            }
        }
    }
    if has_site && map.shared.iter().any(|(o, _)| o == "site") {
        return Err(Error::input(
            t.header_at(),
            "column mapping: a `site` column cannot be mapped when markers name their sites",
        ));
    }
    map.markers
        .iter()
        .map(|(site, mapping)| {
            let target = site_target(robot, site)
                .map_err(|m| Error::input(t.header_at(), format!("column mapping: {m}")))?;
            finder.marker(mapping, Some(target))
        })
        .collect()
}

/// A plain file (no column mapping): every column must be one of kinecal's (what `kinecal
/// compensate` adds to a measurement file, its solutions' remaining errors and flags, is read
/// past).
fn check_plain_header(t: &table::Table<'_>, n: usize, canonical: &[String]) -> Result<()> {
    let Some(h) = t.header.iter().find(|h| {
        !h.is_empty()
            && !canonical.iter().any(|c| c.eq_ignore_ascii_case(h))
            && !COMPENSATED_COLUMNS.contains(&h.as_str())
    }) else {
        return Ok(());
    };
    let hint =
        if h.len() > 1 && h.starts_with(['v', 'V']) && h[1..].parse::<usize>().is_ok_and(|j| j > n)
        {
            format!(" (the robot has {n} joints)")
        } else {
            String::new()
        };
    Err(Error::input(
        t.header_at().with_field(h.clone()),
        format!(
            "unknown column `{h}`{hint}: expected {} (other layouts can be read through a column \
             mapping)",
            FORMAT.header.replace("v1..vn", &format!("v1..v{n}"))
        ),
    ))
}

/// The rows of a measurement file read into postures and observations.
struct Rows<'a, 't> {
    t: &'a table::Table<'t>,
    robot: &'a Robot,
    layout: &'a Layout,
    units: crate::units::Units,
    postures: PostureTable,
    observations: Vec<Observation>,
    seen: TargetsSeen,
    /// The sessions named so far (each name shared by its postures).
    sessions: Vec<std::sync::Arc<str>>,
}

impl Rows<'_, '_> {
    /// Reads the row on `line` (its posture labelled `label`).
    fn row(&mut self, line: usize, label: &str, f: &table::Fields<'_>) -> Result<()> {
        let t = self.t;
        let mut values = Vec::with_capacity(self.layout.readings.len());
        for (i, name) in &self.layout.readings {
            values.push(t.number(line, name, &f[*i])?);
        }
        let field_of = |j: usize| self.layout.readings[j].1.clone();
        let known = self.postures.postures.len();
        let posture = self
            .postures
            .get_or_insert(t, line, label, values, &field_of)?;
        let new = posture == known;
        if self.layout.payload[0].0.is_some() {
            self.payload(line, label, f, posture, new)?;
        }
        if let Some(i) = self.layout.session.0 {
            self.session(line, label, f.get(i).trim(), posture, new)?;
        }
        for m in &self.layout.markers {
            self.marker(line, label, f, m, posture)?;
        }
        Ok(())
    }

    /// The row's payload: a posture's rows share it.
    fn payload(
        &mut self,
        line: usize,
        label: &str,
        f: &table::Fields<'_>,
        posture: usize,
        new: bool,
    ) -> Result<()> {
        let payload = payload_of(self.t, line, f, &self.layout.payload, &self.units)?;
        let p = &mut self.postures.postures[posture];
        if new {
            p.payload = payload;
            return Ok(());
        }
        if p.payload == payload {
            return Ok(());
        }
        let units = &self.units;
        let say = |p: Option<crate::model::robot::Payload>| {
            p.map_or("no payload".to_string(), |p| {
                let c = p.com.map(|v| units.from_si(Quantity::Length, v));
                format!("{} kg at [{}, {}, {}]", p.mass, c.x, c.y, c.z)
            })
        };
        Err(Error::input(
            self.t.at(line, &self.layout.payload[0].1),
            format!(
                "posture `{label}` carries {} on an earlier line and {} here: rows of one posture \
                 share its payload",
                say(p.payload),
                say(payload)
            ),
        ))
    }

    /// The row's session: a posture's rows share it.
    fn session(
        &mut self,
        line: usize,
        label: &str,
        name: &str,
        posture: usize,
        new: bool,
    ) -> Result<()> {
        let name = match self.sessions.iter().find(|s| &***s == name) {
            Some(s) => s.clone(),
            None => {
                self.sessions.push(name.into());
                self.sessions.last().expect("pushed").clone()
            }
        };
        let p = &mut self.postures.postures[posture];
        let name = (!name.is_empty()).then_some(name);
        match &p.session {
            _ if new => p.session = name,
            Some(s) if Some(s) == name.as_ref() => {}
            None if name.is_none() => {}
            was => {
                let say = |s: Option<&std::sync::Arc<str>>| {
                    s.map_or("no session".to_string(), |s| format!("session `{s}`"))
                };
                return Err(Error::input(
                    self.t.at(line, &self.layout.session.1),
                    format!(
                        "posture `{label}` is in {} on an earlier line and in {} here",
                        say(was.as_ref()),
                        say(name.as_ref())
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The row's measurement of the target of marker `m` (none when a wide layout's row left
    /// it out).
    fn marker(
        &mut self,
        line: usize,
        label: &str,
        f: &table::Fields<'_>,
        m: &Marker,
        posture: usize,
    ) -> Result<()> {
        let (t, units) = (self.t, &self.units);
        let target = match (m.target, self.layout.site) {
            (Some(target), _) => target,
            (None, Some(i)) => site_target(self.robot, &f[i])
                .map_err(|msg| Error::input(t.at(line, "site"), msg))?,
            (None, None) => Target::EndEffector,
        };
        let field = |k: usize| m.cols[k].map_or("", |i| f.get(i));
        if self.layout.wide && (0..3).all(|k| field(k).is_empty()) {
            return Ok(());
        }
        let mut pos = [0.0; 3];
        for (k, p) in pos.iter_mut().enumerate() {
            *p = units.to_si(Quantity::Length, t.number(line, &m.names[k], field(k))?);
        }
        let euler = self.angles(line, m, &field)?;
        let sigma_position = self.sigma_position(line, m, &field)?;
        let sigma_angle = t
            .sigma(line, &m.names[7], field(7))?
            .map(|s| units.to_si(Quantity::Angle, s));
        if euler.is_none() && sigma_angle.is_some() {
            return Err(Error::input(
                t.at(line, &m.names[7]),
                "sigma_angle on a position-only row (no alpha, beta, gamma)",
            ));
        }
        if !self.seen.insert(posture, target) {
            // The first measurement of the same target in the same posture.
            let first = self
                .observations
                .iter()
                .find(|o| o.views()[0] == View { posture, target })
                .map_or(0, |o| o.line());
            return Err(Error::input(
                Location::file(&t.file).at_line(line),
                format!(
                    "posture `{label}` measures {} twice (first on line {first})",
                    target_name(self.robot, target)
                ),
            ));
        }
        let view = [View { posture, target }];
        let position = Vector3::from(pos);
        self.observations.push(match euler {
            Some(euler) => {
                Pose::with_sigmas(view[0], position, euler, sigma_position, sigma_angle, line)
                    .into()
            }
            None => Position {
                view,
                position,
                sigma_position,
                line,
            }
            .into(),
        });
        Ok(())
    }

    /// A row's ZYX angles (SI): all three or none (a position).
    fn angles<'f>(
        &self,
        line: usize,
        m: &Marker,
        field: &impl Fn(usize) -> &'f str,
    ) -> Result<Option<Vector3<f64>>> {
        let angles = [field(3), field(4), field(5)];
        if angles.iter().all(|a| a.is_empty()) {
            return Ok(None);
        }
        let mut e = [0.0; 3];
        for k in 0..3 {
            if angles[k].is_empty() {
                return Err(Error::input(
                    self.t.at(line, &m.names[3 + k]),
                    "empty angle: give all of alpha, beta, gamma (a full pose) or none (a \
                     position)",
                ));
            }
            let v = self.t.number(line, &m.names[3 + k], angles[k])?;
            e[k] = self.units.to_si(Quantity::Angle, v);
        }
        Ok(Some(Vector3::from(e)))
    }

    /// A row's position standard deviations (SI): one for every axis, or one per axis.
    fn sigma_position<'f>(
        &self,
        line: usize,
        m: &Marker,
        field: &impl Fn(usize) -> &'f str,
    ) -> Result<Option<Vector3<f64>>> {
        let t = self.t;
        let sigma = match m.cols[8] {
            Some(_) => {
                let mut axes = [None; 3];
                for (k, a) in axes.iter_mut().enumerate() {
                    *a = t.sigma(line, &m.names[8 + k], field(8 + k))?;
                }
                match axes {
                    [Some(x), Some(y), Some(z)] => Some(Vector3::new(x, y, z)),
                    [None, None, None] => None,
                    _ => {
                        return Err(Error::input(
                            t.at(line, &m.names[8]),
                            "give all of sigma_x, sigma_y, sigma_z in a row, or none",
                        ))
                    }
                }
            }
            None => t.sigma(line, &m.names[6], field(6))?.map(Vector3::repeat),
        };
        Ok(sigma.map(|s| s.map(|v| self.units.to_si(Quantity::Length, v))))
    }
}

/// Which targets each posture has a measurement of: a bit per target (the end effector and the
/// first 63 sites) per posture, a set for the others.
#[derive(Default)]
struct TargetsSeen {
    bits: Vec<u64>,
    more: rustc_hash::FxHashSet<(usize, Target)>,
}

impl TargetsSeen {
    /// Records `target` in `posture`; false if it was there already.
    fn insert(&mut self, posture: usize, target: Target) -> bool {
        let bit = match target {
            Target::EndEffector => 0,
            Target::Site(s) if s < 63 => s + 1,
            Target::Site(_) => return self.more.insert((posture, target)),
        };
        if self.bits.len() <= posture {
            self.bits.resize(posture + 1, 0);
        }
        let new = self.bits[posture] & (1 << bit) == 0;
        self.bits[posture] |= 1 << bit;
        new
    }
}

/// Parses a postures file (`posture,v1,...,vn`) for `robot`. A measurement file is accepted too
/// (its readings are used).
pub fn parse_postures(text: &str, file: &str, robot: &Robot) -> Result<Vec<Posture>> {
    let t = table::read(text, file)?;
    if t.column("x").is_some() {
        return Ok(parse_measurements(text, file, robot)?.postures);
    }
    // `posture` and one column per joint (`vK` or the joint's name), in any order; other
    // joints' columns read past.
    let readings = super::ReadingColumns::of(robot, &t.header, &["posture"]);
    readings.check_brand_clash(robot, file)?;
    let mut expected = vec!["posture".to_string()];
    expected.extend(readings.names.iter().cloned());
    let cols: Option<Vec<usize>> = expected.iter().map(|c| t.column(c)).collect();
    let cols = match cols {
        Some(cols) if t.header.len() == expected.len() + readings.others.len() => cols,
        _ => {
            return Err(Error::input(
                t.header_at(),
                format!(
                    "unexpected header `{}`: expected `{}` (joint columns may carry the \
                     joints' names, in any order)",
                    t.header.join(","),
                    postures_header(robot).join(",")
                ),
            ))
        }
    };
    t.check_rows()?;
    let mut table = PostureTable::new();
    for (line, f) in t.rows() {
        let readings = (0..robot.dof())
            .map(|j| t.number(line, &expected[1 + j], &f[cols[1 + j]]))
            .collect::<Result<Vec<_>>>()?;
        let label = &f[cols[0]];
        if table.contains(label) {
            return Err(Error::input(
                t.at(line, "posture"),
                format!("posture `{label}` listed twice"),
            ));
        }
        table.get_or_insert(&t, line, label, readings, &|j| expected[1 + j].clone())?;
    }
    if table.postures.is_empty() {
        return Err(Error::input(
            Location::file(file),
            "no postures: the file has a header but no rows",
        ));
    }
    readings.note(file, robot);
    Ok(table.postures)
}

/// The scales of a file's joint readings (see [`crate::units::number`]): one for the readings of
/// revolute joints, one for prismatic ones.
pub(crate) fn reading_scales(robot: &Robot, postures: &[Posture]) -> Vec<Scale> {
    reading_scales_of(robot, postures.iter().map(|p| p.readings.as_slice()))
}

/// [`reading_scales`] of postures given by their readings.
fn reading_scales_of<'a>(
    robot: &Robot,
    postures: impl IntoIterator<Item = &'a [f64]>,
) -> Vec<Scale> {
    let mut by_kind = [Scale::default(); 2];
    let kind =
        |j: usize| usize::from(robot.joints.get(j).map(|j| j.kind) == Some(JointKind::Prismatic));
    for readings in postures {
        for (j, v) in readings.iter().enumerate() {
            by_kind[kind(j)].include(*v);
        }
    }
    (0..robot.dof()).map(|j| by_kind[kind(j)]).collect()
}

/// One posture's readings, each `,value`, with the scales of that posture alone: a row of a
/// table written one posture at a time, as `kinecal fk` streams a postures file.
pub(crate) fn write_posture_readings(robot: &Robot, out: &mut String, readings: &[f64]) {
    write_readings(out, readings, &reading_scales_of(robot, [readings]));
}

/// A posture's readings, each `,value` ([`number::write`] with its scale).
pub(crate) fn write_readings(out: &mut String, readings: &[f64], scales: &[Scale]) {
    for (j, v) in readings.iter().enumerate() {
        let scale = scales.get(j).copied().unwrap_or(Scale(v.abs()));
        out.push(',');
        out.push_str(&number::write(*v, scale));
    }
}

/// Writes the poses and positions of `data` as a measurement file in `robot`'s units, each
/// number as [`crate::units::number`] says, with the file's scale of its kind (positions,
/// angles, readings of revolute and of prismatic joints): float noise as 0, every other value
/// exactly, so that the file reads back to the same numbers. Standard deviations are stated,
/// never noise (and 0 is none): they are written exactly, however small.
/// Observations of other kinds are not written (see [`super::write_observations`]). The optional `sigma_position` and
/// `sigma_angle` columns are written when some row has them (`sigma_x, sigma_y, sigma_z`
/// instead of `sigma_position` when some row's axes differ).
pub fn write_measurements(robot: &Robot, data: &Dataset) -> String {
    let units = robot.units;
    let with_sigma = data.observations.iter().any(|o| match o {
        Observation::Pose(p) => p.sigma_position.is_some() || p.sigma_angle.is_some(),
        Observation::Position(p) => p.sigma_position.is_some(),
        _ => false,
    });
    let per_axis = data.observations.iter().any(|o| {
        let s = match o {
            Observation::Pose(p) => p.sigma_position,
            Observation::Position(p) => p.sigma_position,
            _ => None,
        };
        // Bit equality: one column is written only when it reproduces every axis exactly.
        s.is_some_and(|s| s.x.to_bits() != s.y.to_bits() || s.x.to_bits() != s.z.to_bits())
    });
    let with_session = data.postures.iter().any(|p| p.session.is_some());
    let with_payload = data.postures.iter().any(|p| p.payload.is_some());
    let mut header = measurement_header(robot);
    if with_session {
        header.insert(1, "session".into());
    }
    let mut out = header.join(",");
    if with_sigma {
        out.push_str(if per_axis {
            ",sigma_x,sigma_y,sigma_z,sigma_angle"
        } else {
            ",sigma_position,sigma_angle"
        });
    }
    if with_payload {
        out.push(',');
        out.push_str(&PAYLOAD_COLUMNS.join(","));
    }
    out.push('\n');
    // The scales of the file's kinds of numbers.
    let len = |v: f64| units.from_si(Quantity::Length, v);
    let ang = |v: f64| units.from_si(Quantity::Angle, v);
    let (mut positions, mut angles) = (Scale::default(), Scale::default());
    for o in &data.observations {
        let (position, euler) = match o {
            Observation::Pose(p) => (p.position, Some(p.euler)),
            Observation::Position(p) => (p.position, None),
            _ => continue,
        };
        position.iter().for_each(|v| positions.include(len(*v)));
        euler.iter().flatten().for_each(|v| angles.include(ang(*v)));
    }
    let readings = reading_scales(robot, &data.postures);
    let opt = |v: Option<f64>, f: &dyn Fn(f64) -> f64| {
        v.map_or(String::new(), |v| number::format_number(f(v)))
    };
    for o in &data.observations {
        let (view, position, euler, sp, sa) = match o {
            Observation::Pose(p) => (
                p.view[0],
                p.position,
                Some(p.euler),
                p.sigma_position,
                p.sigma_angle,
            ),
            Observation::Position(p) => (p.view[0], p.position, None, p.sigma_position, None),
            _ => continue,
        };
        let p = &data.postures[view.posture];
        let _ = write!(out, "{}", p.label);
        if with_session {
            let _ = write!(out, ",{}", p.session.as_deref().unwrap_or(""));
        }
        let _ = write!(out, ",{}", target_name(robot, view.target));
        write_readings(&mut out, &p.readings, &readings);
        for k in 0..3 {
            let _ = write!(out, ",{}", number::write(len(position[k]), positions));
        }
        match euler {
            Some(e) => {
                for k in 0..3 {
                    let _ = write!(out, ",{}", number::write(ang(e[k]), angles));
                }
            }
            None => out.push_str(",,,"),
        }
        if with_sigma {
            let sigma = |v: f64| number::format_number(len(v));
            match (per_axis, sp) {
                (true, Some(s)) => {
                    let _ = write!(out, ",{},{},{}", sigma(s.x), sigma(s.y), sigma(s.z));
                }
                (true, None) => out.push_str(",,,"),
                (false, s) => {
                    let _ = write!(out, ",{}", opt(s.map(|s| s.x), &len));
                }
            }
            let _ = write!(out, ",{}", opt(sa, &ang));
        }
        if with_payload {
            match &p.payload {
                Some(load) => {
                    let _ = write!(out, ",{}", number::format_number(load.mass));
                    for k in 0..3 {
                        let _ = write!(out, ",{}", number::format_number(len(load.com[k])));
                    }
                }
                None => out.push_str(",,,,"),
            }
        }
        out.push('\n');
    }
    out
}

/// Writes a postures file, the readings as [`crate::units::number`] says (the file's scale of
/// the readings of revolute joints, and of prismatic ones).
pub fn write_postures(robot: &Robot, postures: &[Posture]) -> String {
    let mut out = postures_header(robot).join(",");
    out.push('\n');
    let scales = reading_scales(robot, postures);
    for p in postures {
        out.push_str(&p.label);
        write_readings(&mut out, &p.readings, &scales);
        out.push('\n');
    }
    out
}
