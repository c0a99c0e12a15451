//! `simulate` (measurements of a robot made on purpose: a changed "true" robot, noise) and `fk`
//! (the forward kinematics of a robot at postures, streamed in flat memory).
//!
//! ```toml
//! job = "simulate"
//! robot = "ge-a4"
//! postures = 30
//! seed = 7
//! perturb = { p1 = 0.05, "joint2.offset" = -0.5 }
//! noise = { length = 0.0005, angle = 0.005 }
//! out = "data.csv"
//! truth = "truth.toml"
//! ```
//!
//! What a camera of the robot file sees of a board (a pixel file), at postures drawn within the
//! joint ranges until `postures` of them see at least `min_points` of the board's points:
//!
//! ```toml
//! job = "simulate"
//! robot = "cell.toml"
//! camera = "wrist"
//! board = "board"
//! postures = 25
//! noise = { pixel = 0.3 }
//! out = "views.csv"
//! ```

use std::collections::BTreeMap;
use std::io::Write as _;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::apps::simulate::{self, PerturbStd};
use crate::error::{Error, Location, Result, Setting};
use crate::files::controller::Brand;
use crate::files::stream::{cell, payload_at, payload_columns, Rows};
use crate::files::{parse_postures, write_measurements};
use crate::model::robot::Robot;
use crate::observe::Dataset;
use crate::units::Quantity;

use super::common::{count, invalid, is_default, robot_as, visit_opt};
use super::{Document, Done, Env, JobKind, Message, PathRole, Spec};

/// The most postures a simulation makes.
pub(crate) const MAX_POSTURES: usize = 10_000_000;

/// The most measurements (postures times the frames measured at each: the end effector and
/// every site) a simulation makes: they are held in memory, about 0.6 GB a million with the
/// file's text.
pub(crate) const MAX_MEASUREMENTS: usize = 10_000_000;

/// Random changes of every parameter (standard deviations; `[perturb_std]`).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct PerturbSpread {
    /// Of lengths (robot file's length unit).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub length: Option<f64>,
    /// Of angles (robot file's angle unit).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub angle: Option<f64>,
    /// Of slopes, as a fraction.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub slope: Option<f64>,
}

/// The fewest board points a simulated view sees, when not said.
pub const MIN_POINTS: usize = 12;

/// The most views a camera simulation makes.
pub(crate) const MAX_VIEWS: usize = 100_000;

/// How many postures a camera simulation draws, at most, per view asked for.
pub(crate) const DRAWS_PER_VIEW: usize = 1000;

/// The most postures a camera simulation draws (some seconds).
pub(crate) const MAX_DRAWS: usize = 1_000_000;

/// Gaussian noise on simulated measurements (`noise`): standard deviations of lengths and angles
/// (robot file's units) and of pixel coordinates (pixels).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct SimulateNoise {
    /// Of lengths (robot file's length unit).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub length: Option<f64>,
    /// Of angles (robot file's angle unit).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub angle: Option<f64>,
    /// Of pixel coordinates (pixels).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pixel: Option<f64>,
}

impl SimulateNoise {
    /// Noise of lengths and angles only.
    pub fn new(length: Option<f64>, angle: Option<f64>, pixel: Option<f64>) -> Self {
        SimulateNoise {
            length,
            angle,
            pixel,
        }
    }

    /// Reads `length=L,angle=A,pixel=P` (any of them); numbers must be finite and not negative.
    pub fn parse(text: &str) -> Result<SimulateNoise> {
        let mut out = SimulateNoise::default();
        for part in text.split(',').map(str::trim) {
            let (k, v) = part.split_once('=').ok_or_else(|| {
                invalid(
                    Setting::Noise,
                    format!("`{text}`: expected length=L,angle=A,pixel=P (any of them)"),
                )
            })?;
            let v: f64 = v
                .trim()
                .parse()
                .ok()
                .filter(|v: &f64| v.is_finite())
                .ok_or_else(|| {
                    invalid(
                        Setting::Noise,
                        format!("`{text}`: `{}` is not a finite number", v.trim()),
                    )
                })?;
            let slot = match k.trim() {
                "length" => &mut out.length,
                "angle" => &mut out.angle,
                "pixel" => &mut out.pixel,
                other => {
                    return Err(invalid(
                        Setting::Noise,
                        format!("`{text}`: unknown key `{other}` (expected length, angle, pixel)"),
                    ))
                }
            };
            *slot = Some(v);
        }
        out.check()?;
        Ok(out)
    }

    /// Refuses numbers that are not finite or negative.
    fn check(&self) -> Result<()> {
        for (name, v) in [
            ("length", self.length),
            ("angle", self.angle),
            ("pixel", self.pixel),
        ] {
            if let Some(v) = v.filter(|v| !(v.is_finite() && *v >= 0.0)) {
                return Err(invalid(
                    Setting::Noise,
                    format!("the {name} must be non-negative and finite, not {v}"),
                ));
            }
        }
        Ok(())
    }
}

/// A simulation. See the [module documentation](self).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct SimulateSpec {
    /// The nominal robot.
    #[serde(default)]
    pub robot: String,
    /// How many postures, sampled within the joint ranges.
    #[serde(default)]
    pub postures: usize,
    /// The random seed (default 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
    /// Changes of named parameters (robot file's units): the true robot.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub perturb: BTreeMap<String, f64>,
    /// Random changes of every parameter.
    #[serde(default, skip_serializing_if = "is_default")]
    pub perturb_std: PerturbSpread,
    /// Gaussian noise on the measurements (robot file's units; pixels).
    #[serde(default, skip_serializing_if = "is_default")]
    pub noise: SimulateNoise,
    /// Measure positions only.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub position_only: bool,
    /// Simulate what this camera of the robot file sees of `board`: a pixel file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera: Option<String>,
    /// The board the camera sees.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub board: Option<String>,
    /// The fewest board points a kept view sees (default 12).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub min_points: Option<usize>,
    /// The measurements to write.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub out: Option<String>,
    /// The true robot to write.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub truth: Option<String>,
}

impl Spec for SimulateSpec {
    const KIND: JobKind = JobKind::Simulate;

    fn visit_paths(&mut self, f: &mut dyn FnMut(PathRole, &mut String)) {
        f(PathRole::Robot, &mut self.robot);
        visit_opt(f, PathRole::Output, &mut self.out);
        visit_opt(f, PathRole::Output, &mut self.truth);
    }
}

/// The forward kinematics of a robot at postures. See the [module documentation](self).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct FkSpec {
    /// The robot.
    #[serde(default)]
    pub robot: String,
    /// The postures (`posture,v1..vn`, a table `compensate` writes with the format `table` or
    /// `joints-ur|abb|kuka|fanuc`, or a measurement file; `-` for standard input).
    #[serde(default)]
    pub postures: String,
    /// The poses to write (a measurement file; standard output when absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub out: Option<String>,
}

impl Spec for FkSpec {
    const KIND: JobKind = JobKind::Fk;

    fn visit_paths(&mut self, f: &mut dyn FnMut(PathRole, &mut String)) {
        f(PathRole::Robot, &mut self.robot);
        f(PathRole::Input, &mut self.postures);
        visit_opt(f, PathRole::Output, &mut self.out);
    }
}

/// The document of a simulation or of forward kinematics.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct SimulateOutcome {
    /// Postures.
    #[serde(default)]
    pub postures: usize,
    /// Measurements (poses or positions).
    #[serde(default)]
    pub measurements: usize,
    /// The measurement file (what `out` holds; empty when it streamed into a file).
    #[serde(default)]
    pub data: String,
    /// The true robot file (a simulation's).
    pub truth: Option<String>,
    /// The parameters of the true robot that differ from the nominal's: `(name, nominal,
    /// true)` in the robot file's units.
    pub changed: Vec<(String, f64, f64)>,
}

impl SimulateSpec {
    /// The true robot of the spec: `nominal` changed as `perturb_std` and `perturb` say.
    pub fn truth(&self, nominal: &Robot) -> Result<Robot> {
        let units = nominal.units;
        let seed = self.seed.unwrap_or(1);
        let mut truth = nominal.clone();
        let s = self.perturb_std;
        for (name, v) in [("length", s.length), ("angle", s.angle), ("slope", s.slope)] {
            if let Some(v) = v.filter(|v| !(v.is_finite() && *v >= 0.0)) {
                return Err(invalid(
                    Setting::PerturbStd,
                    format!("the {name} spread must be finite and not negative, not {v}"),
                ));
            }
        }
        if s != PerturbSpread::default() {
            truth = simulate::perturb(
                &truth,
                PerturbStd {
                    length: units.to_si(Quantity::Length, s.length.unwrap_or(0.0)),
                    angle: units.to_si(Quantity::Angle, s.angle.unwrap_or(0.0)),
                    slope_fraction: s.slope.unwrap_or(0.0),
                },
                seed,
            );
        }
        let mut changes = Vec::new();
        for (name, &delta) in &self.perturb {
            if !delta.is_finite() {
                return Err(invalid(
                    Setting::ParameterChange,
                    format!("{name}: {delta} is not a finite number"),
                ));
            }
            let ids = crate::model::param_list::parse_param_list(name.trim(), nominal)
                .map_err(|e| invalid(Setting::ParameterChange, e.to_string()))?;
            for id in ids {
                changes.push((id, delta));
            }
        }
        simulate::changed(&truth, &changes).map_err(|e| match e {
            crate::Error::InvalidOption { .. } => e,
            e => invalid(Setting::ParameterChange, e.to_string()),
        })
    }

    /// The camera and the board of a camera simulation (indices in `robot`), `None` for
    /// measurements of poses and positions.
    pub fn camera_and_board(&self, robot: &Robot) -> Result<Option<(usize, usize)>> {
        let (camera, board) = match (&self.camera, &self.board) {
            (None, None) => return Ok(None),
            (Some(c), Some(b)) => (c.trim(), b.trim()),
            (Some(_), None) => {
                return Err(invalid(
                    Setting::Board,
                    "a camera's views need the board it sees (board = NAME)",
                ))
            }
            (None, Some(_)) => {
                return Err(invalid(
                    Setting::Camera,
                    "a board is seen by a camera: name it (camera = NAME)",
                ))
            }
        };
        let names = |v: Vec<&str>| {
            if v.is_empty() {
                "none".to_string()
            } else {
                v.join(", ")
            }
        };
        let c = robot.camera_index(camera).ok_or_else(|| {
            invalid(
                Setting::Camera,
                format!(
                    "unknown camera `{camera}` (the robot file's [[cameras]]: {})",
                    names(robot.cameras.iter().map(|c| c.name.as_str()).collect())
                ),
            )
        })?;
        let b = robot.board_index(board).ok_or_else(|| {
            invalid(
                Setting::Board,
                format!(
                    "unknown board `{board}` (the robot file's [[boards]]: {})",
                    names(robot.boards.iter().map(|b| b.name.as_str()).collect())
                ),
            )
        })?;
        if robot.cameras[c].mount == robot.boards[b].mount {
            return Err(invalid(
                Setting::Board,
                format!(
                    "camera `{camera}` and board `{board}` are fixed to the same frame: no posture \
                     moves one against the other"
                ),
            ));
        }
        if self.position_only {
            return Err(invalid(
                Setting::Camera,
                "a camera sees pixels, not positions: position_only is for trackers",
            ));
        }
        Ok(Some((c, b)))
    }

    /// The views of `truth`'s camera `camera` of board `board`, on `nominal`'s file.
    fn views(&self, truth: &Robot, (camera, board): (usize, usize)) -> Result<Dataset> {
        let n = count(Setting::Postures, self.postures, MAX_VIEWS, "views")?;
        let points = truth.boards[board].points();
        let min = self.min_points.unwrap_or(MIN_POINTS);
        if min == 0 || min > points {
            return Err(invalid(
                Setting::MinPoints,
                format!(
                    "expected between 1 and {points} (the points of board `{}`), not {min}",
                    truth.boards[board].name
                ),
            ));
        }
        let seed = self.seed.unwrap_or(1);
        let max_draws = n.saturating_mul(DRAWS_PER_VIEW).min(MAX_DRAWS);
        let (data, draws) = simulate::draw_views(truth, n, (camera, board), min, max_draws, seed);
        if data.postures.len() < n {
            return Err(invalid(
                Setting::Postures,
                format!(
                    "only {} of {draws} postures drawn within the joint ranges see at least {min} \
                     points of board `{}` from camera `{}` ({n} asked for): narrow the joint \
                     ranges (min, max in the robot file's [[joints]]) about a posture that sees \
                     the board, or ask for fewer postures or fewer points (min_points)",
                    data.postures.len(),
                    truth.boards[board].name,
                    truth.cameras[camera].name
                ),
            ));
        }
        Ok(data)
    }

    /// Simulates the measurements of `truth` at the spec's postures, on `nominal`'s file.
    pub fn measurements(&self, nominal: &Robot, truth: &Robot) -> Result<Dataset> {
        if let Some(cb) = self.camera_and_board(nominal)? {
            let mut data = self.views(truth, cb)?;
            self.add_noise(nominal, &mut data)?;
            return Ok(data);
        }
        let n = count(Setting::Postures, self.postures, MAX_POSTURES, "postures")?;
        let frames = 1 + nominal.sites.len();
        if n.saturating_mul(frames) > MAX_MEASUREMENTS {
            return Err(invalid(
                Setting::Postures,
                format!(
                    "expected at most {MAX_MEASUREMENTS} measurements ({frames} frames measured \
                     at each posture: at most {} postures), not {}",
                    MAX_MEASUREMENTS / frames,
                    n.saturating_mul(frames)
                ),
            ));
        }
        let seed = self.seed.unwrap_or(1);
        let postures = simulate::sample_postures(nominal, n, seed);
        let readings = postures
            .iter()
            .map(|p| (p.readings.as_slice(), p.payload.as_ref()));
        if let Some((i, eq)) = crate::model::kinematics::unconverged_posture(truth, readings) {
            return Err(invalid(
                Setting::ParameterChange,
                format!(
                    "the true robot's gravity equilibrium at posture {} {eq}",
                    postures[i].label
                ),
            ));
        }
        let mut data = simulate::measure(truth, &postures, self.position_only);
        self.add_noise(nominal, &mut data)?;
        Ok(data)
    }

    /// Adds the spec's noise (in `nominal`'s file units) to `data` (a noise no instrument has
    /// refused: see `common::check_noise`).
    pub fn add_noise(&self, nominal: &Robot, data: &mut Dataset) -> Result<()> {
        self.noise.check()?;
        let units = nominal.units;
        let l = self.noise.length.map(|v| units.to_si(Quantity::Length, v));
        let a = self.noise.angle.map(|v| units.to_si(Quantity::Angle, v));
        super::common::check_noise(
            Setting::Noise,
            nominal,
            [self.noise.length, self.noise.angle, self.noise.pixel],
        )?;
        if l.is_some() || a.is_some() || self.noise.pixel.is_some() {
            let seed = self.seed.unwrap_or(1);
            let noise = crate::observe::Noise {
                length: l.unwrap_or(0.0),
                angle: a.unwrap_or(0.0),
                pixel: self.noise.pixel.unwrap_or(0.0),
            };
            simulate::add_noise_with(data, &noise, seed);
        }
        Ok(())
    }

    /// Simulates and writes the files.
    pub(crate) fn run(&self, _env: &mut Env<'_>) -> Result<Done> {
        let (nominal, source) = robot_as(&self.robot, Setting::Robot)?;
        let truth = self.truth(&nominal)?;
        let data = self.measurements(&nominal, &truth)?;
        let pixels = self.camera.is_some();
        let text = if pixels {
            crate::files::write_pixels(&nominal, &data)
        } else {
            write_measurements(&nominal, &data)
        };
        let truth_text =
            crate::model::robot_file::write_robot_toml_checked(&truth, Some(&source.text))?;
        let mut staged = crate::files::output::Staged::new();
        if let Some(p) = &self.out {
            staged.text(Path::new(p), &text)?;
        }
        if let Some(p) = &self.truth {
            staged.text(Path::new(p), &truth_text)?;
        }
        staged.commit()?;
        let mut messages = Vec::new();
        if let Some(p) = &self.out {
            messages.push(Message::Note(if pixels {
                format!(
                    "wrote {} pixels ({} views) to {p}",
                    data.observations.len(),
                    data.postures.len()
                )
            } else {
                format!(
                    "wrote {} measurements ({} postures) to {p}",
                    data.observations.len(),
                    data.postures.len()
                )
            }));
        }
        if let Some(p) = &self.truth {
            messages.push(Message::Note(format!("wrote the true robot to {p}")));
        }
        let changed = nominal
            .param_ids()
            .filter(|&id| nominal.get(id).to_bits() != truth.get(id).to_bits())
            .map(|id| {
                (
                    nominal.param_name(id),
                    nominal.get_user(id),
                    truth.get_user(id),
                )
            })
            .collect();
        Ok(Done {
            document: Document::Simulation(SimulateOutcome {
                postures: data.postures.len(),
                measurements: data.observations.len(),
                data: text,
                truth: Some(truth_text),
                changed,
            }),
            messages,
            status: super::Status::Ok,
            pending: None,
        })
    }
}

/// The columns of the joint targets of a brand that `robot` fits (`kinecal compensate --format
/// joints-ur|abb|kuka|fanuc`), when `rows` has every one of them: the brand, and per joint its
/// column.
fn brand_columns(robot: &Robot, rows: &Rows) -> Option<(Brand, Vec<usize>)> {
    Brand::ALL.into_iter().find_map(|brand| {
        let names = brand.columns(robot).ok()?;
        let found: Option<Vec<usize>> = names.iter().map(|c| rows.column(c)).collect();
        found.map(|found| (brand, found))
    })
}

/// The error of a header `fk` does not read, saying exactly what it reads: postures, a
/// measurement file, and the tables `kinecal compensate` writes for this robot.
fn fk_header_error(robot: &Robot, rows: &Rows) -> Error {
    let mut tables = vec!["`--format table`".to_string()];
    for brand in Brand::ALL {
        if let Some(names) = brand.columns(robot).ok().filter(|n| !n.is_empty()) {
            tables.push(format!(
                "`joints-{}` (`{}..{}` in {})",
                brand.as_str(),
                names[0],
                names[names.len() - 1],
                brand.angle_unit().as_str()
            ));
        }
    }
    let last = tables.pop().unwrap_or_default();
    let tables = if tables.is_empty() {
        last
    } else {
        format!("{} or {last}", tables.join(", "))
    };
    Error::input(
        Location::file(&rows.file).at_line(1),
        format!(
            "unexpected header `{}`: expected postures `{}` (the joints' columns may carry their \
             names, in any order), a measurement file, or a table of `kinecal compensate`: \
             {tables}; not its programs (`urscript`, `krl`, `rapid`, `tp`)",
            rows.spelled.join(","),
            crate::files::postures_header(robot).join(",")
        ),
    )
}

impl FkSpec {
    /// Writes the poses of the postures' file: a postures file streams through row by row
    /// (flat memory, any length); a measurement file is read whole.
    fn emit(&self, robot: &Robot, w: &mut dyn std::io::Write, poses: &mut usize) -> Result<()> {
        let io = |e: std::io::Error| Error::Io {
            path: self.out.clone().unwrap_or_else(|| "-".into()),
            cause: e,
        };
        let mut rows = Rows::open(Path::new(&self.postures))?;
        if rows.column("x").is_some() {
            let s = crate::source::Source::read(Path::new(&self.postures))?;
            let postures = parse_postures(&s.text, &s.name, robot)?;
            let readings = postures
                .iter()
                .map(|p| (p.readings.as_slice(), p.payload.as_ref()));
            if let Some((i, eq)) = crate::model::kinematics::unconverged_posture(robot, readings) {
                return Err(Error::input(
                    Location::file(&s.name),
                    format!(
                        "posture `{}`: the gravity equilibrium {eq}",
                        postures[i].label
                    ),
                ));
            }
            let data = simulate::measure(robot, &postures, false);
            *poses = data.observations.len();
            w.write_all(write_measurements(robot, &data).as_bytes())
                .map_err(io)?;
            crate::files::note_compensated_columns(&rows.file, &rows.spelled);
            return Ok(());
        }
        // A postures file, or a table `compensate` writes: `--format table` (its label `target`
        // or `posture`, a `site`, and the remaining errors and flags, read past) or a brand's
        // joint targets (`--format joints-ur|abb|kuka|fanuc`: the brand's names and unit).
        let label = rows.column("posture").or_else(|| rows.column("target"));
        let mut known = vec!["posture", "target", "site"];
        known.extend(crate::files::COMPENSATED_COLUMNS);
        known.extend(crate::files::PAYLOAD_COLUMNS);
        let columns = crate::files::ReadingColumns::of(robot, &rows.spelled, &known);
        let own: Option<Vec<usize>> = columns.names.iter().map(|c| rows.column(c)).collect();
        // A table `compensate --format table` writes holds the robot's own readings.
        let compensated = crate::files::COMPENSATED_COLUMNS
            .iter()
            .any(|c| rows.column(c).is_some());
        if own.is_some() && !compensated {
            columns.check_brand_clash(robot, &rows.file)?;
        }
        let (readings, brand) = match own {
            Some(own) => (Some(own), None),
            None => match brand_columns(robot, &rows) {
                Some((brand, found)) => (Some(found), Some(brand)),
                None => (None, None),
            },
        };
        let payload_cols = payload_columns(&rows)?;
        // Another joint's column is read past in a table of the robot's own columns only.
        let other = |h: &str| brand.is_none() && columns.is_other(h);
        let unknown = rows.header.iter().enumerate().find(|(i, h)| {
            Some(*i) != label
                && !readings.as_ref().is_some_and(|r| r.contains(i))
                && !known[2..].contains(&h.as_str())
                && !other(h)
        });
        let (Some(label), Some(readings), None) = (label, readings, unknown) else {
            return Err(fk_header_error(robot, &rows));
        };
        let mut first = true;
        let mut posture = crate::Posture {
            label: String::new(),
            readings: vec![0.0; robot.dof()],
            session: None,
            payload: None,
        };
        while let Some(line) = rows.advance()? {
            posture.label.clear();
            posture.label.push_str(rows.field(label));
            for (j, &c) in readings.iter().enumerate() {
                let v = cell(&rows, line, c)?;
                posture.readings[j] = brand.map_or(v, |b| b.reading(robot, v));
            }
            // With payload columns every row writes them: an empty one is no load, 0 kg.
            posture.payload = payload_at(&rows, line, &payload_cols, &robot.units)?.or_else(|| {
                payload_cols[0].map(|_| crate::model::robot::Payload {
                    mass: 0.0,
                    com: nalgebra::Vector3::zeros(),
                })
            });
            if let Some((_, eq)) = crate::model::kinematics::unconverged_posture(
                robot,
                [(posture.readings.as_slice(), posture.payload.as_ref())],
            ) {
                return Err(Error::input(
                    Location::file(&rows.file).at_line(line as usize),
                    format!("the gravity equilibrium {eq}"),
                ));
            }
            let data = simulate::measure(robot, std::slice::from_ref(&posture), false);
            *poses += data.observations.len();
            let text = write_measurements(robot, &data);
            let body = if first {
                text.as_str()
            } else {
                text.split_once('\n').map_or("", |(_, rest)| rest)
            };
            w.write_all(body.as_bytes()).map_err(io)?;
            first = false;
        }
        if first {
            return Err(Error::input(
                Location::file(&rows.file),
                "no postures: the file has a header but no rows",
            ));
        }
        if brand.is_none() {
            columns.note(&rows.file, robot);
        }
        crate::files::note_compensated_columns(&rows.file, &rows.spelled);
        Ok(())
    }

    /// Computes and writes the poses.
    pub(crate) fn run(&self, _env: &mut Env<'_>) -> Result<Done> {
        let (robot, _) = robot_as(&self.robot, Setting::Robot)?;
        if self.postures.is_empty() {
            return Err(invalid(Setting::Postures, "no postures file given"));
        }
        let mut poses = 0;
        let path = self.out.as_deref().unwrap_or("-");
        if path == "-" {
            // Streamed as it is made: flat memory for any number of postures.
            let stdout = std::io::stdout();
            let mut w = std::io::BufWriter::new(stdout.lock());
            self.emit(&robot, &mut w, &mut poses)?;
            w.flush().map_err(|cause| Error::Io {
                path: path.to_string(),
                cause,
            })?;
            return Ok(Done::ok(Document::Simulation(SimulateOutcome {
                postures: poses,
                measurements: poses,
                data: String::new(),
                truth: None,
                changed: Vec::new(),
            })));
        }
        let mut staged = crate::files::output::Staged::new();
        staged.by_path(Path::new(path), |tmp| -> Result<()> {
            let file = std::fs::File::create(tmp).map_err(|cause| Error::Io {
                path: path.to_string(),
                cause,
            })?;
            let mut w = std::io::BufWriter::new(file);
            self.emit(&robot, &mut w, &mut poses)?;
            w.flush().map_err(|cause| Error::Io {
                path: path.to_string(),
                cause,
            })
        })?;
        staged.commit()?;
        let mut done = Done::ok(Document::Simulation(SimulateOutcome {
            postures: poses,
            measurements: poses,
            data: String::new(),
            truth: None,
            changed: Vec::new(),
        }));
        if let Some(p) = &self.out {
            done.note(format!("wrote {poses} poses to {p}"));
        }
        Ok(done)
    }
}
