//! The ISO 9283 jobs: the test poses of a robot (`iso9283-plan`), a simulated log
//! (`iso9283-simulate`), a log made from measurements (`iso9283-log`) and the pose figures of a
//! log (`iso9283-evaluate`). The arithmetic is [`crate::apps::iso9283`]'s.
//!
//! ```toml
//! job = "iso9283-evaluate"
//! data = "log.csv"
//! json = "iso.json"
//! html = "iso.html"
//! ```

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::apps::iso9283::{
    evaluate, log_placed, plan, predict_compensated, read_log, read_plan, read_roles, simulate,
    write_log, write_plan, Cube, Evaluation, LogUnits, PlacedLog, PlanRequest, SimulateRequest,
    TestPlan,
};
use crate::error::{Error, Result, Setting};
use crate::model::robot::Robot;
use crate::units::Quantity;

use super::common::{count, invalid, is_default, read_source, robot_as, visit_opt, LengthAngle};
use super::{Document, Done, Env, JobKind, Message, Page, PathRole, Spec};

/// The most cycles a simulated log runs.
pub(crate) const MAX_CYCLES: usize = 100_000;

/// The finest grid a cube is searched on (points per axis).
pub(crate) const MAX_RESOLUTION: usize = 200;

/// The test poses of a robot. Lengths and angles in the robot file's units.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct Iso9283PlanSpec {
    /// The robot (its model reaches the poses).
    #[serde(default)]
    pub robot: String,
    /// The cube: `[cx, cy, cz, side]` in the global frame (default: searched for, as large as
    /// the robot reaches with its test poses and corners).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cube: Option<[f64; 4]>,
    /// The attitude of every test pose (`[a, b, c]`, ZYX Euler angles; default: the tool's
    /// attitude at the cube's centre).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub attitude: Option<[f64; 3]>,
    /// Grid points per axis of the cube's search (default 10).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub resolution: Option<usize>,
    /// The plan file to write (what `iso9283-simulate` reads).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub out: Option<String>,
}

/// A log simulated at a plan's poses (no measurement).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct Iso9283SimulateSpec {
    /// The robot that moves (a "true" robot).
    #[serde(default)]
    pub robot: String,
    /// The plan's poses (`iso9283-plan`'s file).
    #[serde(default)]
    pub poses: String,
    /// Cycles round the poses (default 30, as ISO 9283 asks).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cycles: Option<usize>,
    /// The noise on each attained coordinate and angle (robot file's units).
    #[serde(default, skip_serializing_if = "is_default")]
    pub noise: LengthAngle,
    /// The random seed (default 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
    /// The log to write.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub out: Option<String>,
}

/// A log made from measurements: the commanded poses from the robot's model at the readings, the
/// attained ones measured.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct Iso9283LogSpec {
    /// The robot whose model commands the poses.
    #[serde(default)]
    pub robot: String,
    /// The measurements (a measurement file).
    #[serde(default)]
    pub data: String,
    /// The postures' roles (`posture,test,pose,cycle`).
    #[serde(default)]
    pub roles: String,
    /// The log's length unit (default: the robot file's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub length_unit: Option<String>,
    /// The log to write.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub out: Option<String>,
}

/// The pose figures of a log, and with a calibrated robot and its report, the accuracy a
/// compensated program is predicted to reach.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct Iso9283EvaluateSpec {
    /// The log.
    #[serde(default)]
    pub data: String,
    /// Its length unit, when it does not state it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub length_unit: Option<String>,
    /// Its angle unit, when it does not state it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub angle_unit: Option<String>,
    /// A calibrated robot (with `report`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub robot: Option<String>,
    /// Its calibration report, with a prediction (with `robot`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub report: Option<String>,
    /// The frame predicted (default: the report's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target: Option<String>,
    /// The figures as JSON.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub json: Option<String>,
    /// The figures as an HTML page.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub html: Option<String>,
}

impl Spec for Iso9283PlanSpec {
    const KIND: JobKind = JobKind::Iso9283Plan;

    fn visit_paths(&mut self, f: &mut dyn FnMut(PathRole, &mut String)) {
        f(PathRole::Robot, &mut self.robot);
        visit_opt(f, PathRole::Output, &mut self.out);
    }
}

impl Spec for Iso9283SimulateSpec {
    const KIND: JobKind = JobKind::Iso9283Simulate;

    fn visit_paths(&mut self, f: &mut dyn FnMut(PathRole, &mut String)) {
        f(PathRole::Robot, &mut self.robot);
        f(PathRole::Input, &mut self.poses);
        visit_opt(f, PathRole::Output, &mut self.out);
    }
}

impl Spec for Iso9283LogSpec {
    const KIND: JobKind = JobKind::Iso9283Log;

    fn visit_paths(&mut self, f: &mut dyn FnMut(PathRole, &mut String)) {
        f(PathRole::Robot, &mut self.robot);
        f(PathRole::Input, &mut self.data);
        f(PathRole::Input, &mut self.roles);
        visit_opt(f, PathRole::Output, &mut self.out);
    }
}

impl Spec for Iso9283EvaluateSpec {
    const KIND: JobKind = JobKind::Iso9283Evaluate;

    fn visit_paths(&mut self, f: &mut dyn FnMut(PathRole, &mut String)) {
        f(PathRole::Input, &mut self.data);
        visit_opt(f, PathRole::Robot, &mut self.robot);
        visit_opt(f, PathRole::Input, &mut self.report);
        visit_opt(f, PathRole::Output, &mut self.json);
        visit_opt(f, PathRole::Output, &mut self.html);
    }
}

/// A test pose in the robot file's units.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct PlannedPose {
    /// `P1` .. `P5`.
    #[serde(default)]
    pub pose: String,
    /// Its position (length unit, global frame).
    pub position: [f64; 3],
    /// Its attitude (ZYX Euler angles, angle unit).
    pub attitude: Option<[f64; 3]>,
    /// The readings that reach it.
    pub readings: Vec<f64>,
}

/// The document of ISO 9283 test poses, in the robot file's units.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct Iso9283PlanDocument {
    /// The robot file's length unit.
    #[serde(default)]
    pub length_unit: String,
    /// Its angle unit.
    #[serde(default)]
    pub angle_unit: String,
    /// The cube's centre.
    pub centre: [f64; 3],
    /// Its side.
    pub side: f64,
    /// How it was searched for: grid points tested, the step, points reached (none when
    /// given).
    pub search: Option<(usize, f64, usize)>,
    /// The test poses.
    pub poses: Vec<PlannedPose>,
}

/// A finished ISO 9283 plan.
#[derive(Debug)]
#[non_exhaustive]
pub struct Iso9283PlanOutcome {
    /// The plan (SI).
    pub plan: TestPlan,
    /// The document.
    pub document: Iso9283PlanDocument,
}

/// The document of a simulated log.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct SimulatedLog {
    /// Cycles.
    #[serde(default)]
    pub cycles: usize,
    /// Poses per cycle.
    #[serde(default)]
    pub poses: usize,
    /// Rows of the log.
    #[serde(default)]
    pub rows: usize,
    /// The log as written.
    #[serde(default)]
    pub log: String,
}

/// The document of a log made from measurements.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct Iso9283LogOutcome {
    /// Rows of the log.
    #[serde(default)]
    pub rows: usize,
    /// Tests in it.
    #[serde(default)]
    pub tests: usize,
    /// Measured postures without a role (left out).
    #[serde(default)]
    pub left_out: Vec<String>,
    /// Sessions whose measurement frame was placed on the data.
    #[serde(default)]
    pub placed: Vec<String>,
    /// The log as written.
    #[serde(default)]
    pub log: String,
}

/// A unit of a log, parsed, named by `setting`.
fn unit<U: std::str::FromStr<Err = String>>(
    u: Option<&str>,
    setting: Setting,
) -> Result<Option<U>> {
    u.map(str::parse)
        .transpose()
        .map_err(|m: String| invalid(setting, m))
}

/// Stages `text` for `path` (when given) and commits, with a note.
fn write_one(
    path: Option<&str>,
    text: &str,
    what: impl FnOnce(&str) -> String,
) -> Result<Vec<Message>> {
    let Some(p) = path else {
        return Ok(Vec::new());
    };
    crate::files::output::write_file(Path::new(p), text)?;
    Ok(vec![Message::Note(what(p))])
}

impl Iso9283PlanSpec {
    /// The library request for `robot` (file units converted).
    pub fn request(&self, robot: &Robot) -> Result<PlanRequest> {
        let u = robot.units;
        let cube = match self.cube {
            Some([x, y, z, side]) => {
                if side.is_nan() || side <= 0.0 {
                    return Err(invalid(
                        Setting::Cube,
                        format!("the side must be positive, not {side}"),
                    ));
                }
                Some(Cube {
                    centre: [x, y, z].map(|v| u.to_si(Quantity::Length, v)),
                    side: u.to_si(Quantity::Length, side),
                })
            }
            None => None,
        };
        let resolution = self.resolution.unwrap_or(10);
        if !(3..=MAX_RESOLUTION).contains(&resolution) {
            return Err(invalid(
                Setting::Resolution,
                format!("expected 3 to {MAX_RESOLUTION} grid points per axis, not {resolution}"),
            ));
        }
        Ok(PlanRequest {
            cube,
            attitude: self
                .attitude
                .map(|a| a.map(|x| u.to_si(Quantity::Angle, x))),
            resolution,
        })
    }

    /// Plans and writes the plan file.
    pub(crate) fn run(&self, env: &mut Env<'_>) -> Result<Done> {
        let (robot, _) = robot_as(&self.robot, Setting::Robot)?;
        let request = self.request(&robot)?;
        env.progress.say("searching the test cube");
        let p = plan(&robot, &request)?;
        let messages = write_one(self.out.as_deref(), &write_plan(&robot, &p), |o| {
            format!("wrote the test poses to {o}")
        })?;
        let u = robot.units;
        let l = |v: f64| u.from_si(Quantity::Length, v);
        let document = Iso9283PlanDocument {
            length_unit: u.length.to_string(),
            angle_unit: u.angle.to_string(),
            centre: p.cube.centre.map(l),
            side: l(p.cube.side),
            search: p.search.map(|s| (s.tested, l(s.step), s.reached)),
            poses: p
                .poses
                .iter()
                .map(|t| PlannedPose {
                    pose: format!("P{}", t.pose),
                    position: t.position.map(l),
                    attitude: t.attitude.map(|a| a.map(|x| u.from_si(Quantity::Angle, x))),
                    readings: t.readings.clone(),
                })
                .collect(),
        };
        Ok(Done {
            document: Document::Iso9283Plan(Box::new(Iso9283PlanOutcome { plan: p, document })),
            messages,
            status: super::Status::Ok,
            pending: None,
        })
    }
}

impl Iso9283SimulateSpec {
    /// Simulates and writes the log.
    pub(crate) fn run(&self, _env: &mut Env<'_>) -> Result<Done> {
        let (robot, _) = robot_as(&self.robot, Setting::Robot)?;
        let s = read_source(&self.poses, Setting::Postures)?;
        let poses = read_plan(&s.text, &s.name, &robot)?;
        let cycles = count(
            Setting::Cycles,
            self.cycles.unwrap_or(30),
            MAX_CYCLES,
            "cycles",
        )?;
        self.noise.check(Setting::Noise, false)?;
        super::common::check_noise(
            Setting::Noise,
            &robot,
            [self.noise.length, self.noise.angle, None],
        )?;
        let (length, angle) = self.noise.si(&robot);
        let log = simulate(
            &robot,
            &poses,
            &SimulateRequest {
                cycles,
                length_noise: length.unwrap_or(0.0),
                angle_noise: angle.unwrap_or(0.0),
                seed: self.seed.unwrap_or(1),
            },
        )?;
        let text = write_log(&log);
        let messages = write_one(self.out.as_deref(), &text, |o| {
            format!(
                "wrote a simulated log (not a measurement) of {cycles} cycles at {} poses ({} \
                 rows) to {o}",
                poses.len(),
                log.rows.len()
            )
        })?;
        Ok(Done {
            document: Document::Iso9283Simulated(SimulatedLog {
                cycles,
                poses: poses.len(),
                rows: log.rows.len(),
                log: text,
            }),
            messages,
            status: super::Status::Ok,
            pending: None,
        })
    }
}

impl Iso9283LogSpec {
    /// Makes and writes the log.
    pub(crate) fn run(&self, _env: &mut Env<'_>) -> Result<Done> {
        let (robot, _) = robot_as(&self.robot, Setting::Robot)?;
        let d = read_source(&self.data, Setting::Observations)?;
        let data = crate::files::parse_measurements(&d.text, &d.name, &robot)?;
        let r = read_source(&self.roles, Setting::Roles)?;
        let roles = read_roles(&r.text, &r.name)?;
        let PlacedLog {
            mut log,
            left_out,
            placed,
        } = log_placed(&robot, &data, &roles)?;
        if let Some(u) = unit(self.length_unit.as_deref(), Setting::LengthUnit)? {
            log = log.with_length_unit(u)?;
        }
        let tests = {
            let mut t: Vec<&str> = log.rows.iter().filter_map(|r| r.test.as_deref()).collect();
            t.sort_unstable();
            t.dedup();
            t.len()
        };
        let mut messages = Vec::new();
        if !placed.is_empty() {
            messages.push(Message::Note(format!(
                "placed the measurement frame of session{} {} on {} (6 parameters{}, the robot \
                 held)",
                if placed.len() == 1 { "" } else { "s" },
                placed.join(", "),
                d.name,
                if placed.len() == 1 { "" } else { " each" }
            )));
        }
        if !left_out.is_empty() {
            messages.push(Message::Note(format!(
                "left out {} measured posture{} without a role in {} ({})",
                left_out.len(),
                if left_out.len() == 1 { "" } else { "s" },
                r.name,
                left_out
                    .iter()
                    .take(5)
                    .cloned()
                    .collect::<Vec<_>>()
                    .join(", ")
                    + if left_out.len() > 5 { ", ..." } else { "" }
            )));
        }
        let text = write_log(&log);
        messages.extend(write_one(self.out.as_deref(), &text, |o| {
            format!(
                "wrote the ISO 9283 log of {} row{} ({tests} test{}; commanded: {}'s model at the \
                 readings; attained: measured, in its base frame) to {o}",
                log.rows.len(),
                if log.rows.len() == 1 { "" } else { "s" },
                if tests == 1 { "" } else { "s" },
                self.robot,
            )
        })?);
        Ok(Done {
            document: Document::Iso9283Log(Iso9283LogOutcome {
                rows: log.rows.len(),
                tests,
                left_out,
                placed,
                log: text,
            }),
            messages,
            status: super::Status::Ok,
            pending: None,
        })
    }
}

impl Iso9283EvaluateSpec {
    /// The figures of the log (and the compensated accuracy predicted, with a robot and its
    /// report).
    pub fn evaluation(&self) -> Result<Evaluation> {
        let units = LogUnits {
            length: unit(self.length_unit.as_deref(), Setting::LengthUnit)?,
            angle: unit(self.angle_unit.as_deref(), Setting::AngleUnit)?,
        };
        let s = read_source(&self.data, Setting::Observations)?;
        let log = read_log(&s.text, &s.name, units)?;
        let mut e = evaluate(&log)?;
        match (&self.robot, &self.report) {
            (Some(robot), Some(report)) => {
                let (robot, _, pr, target) =
                    super::predict::calibrated(robot, report, self.target.as_deref())?;
                let (predictor, target) = super::PredictSpec::predictor(&robot, &pr, &target)?;
                predict_compensated(&mut e, &log, &predictor, target)?;
            }
            (None, None) if self.target.is_none() => {}
            _ => {
                return Err(invalid(
                    Setting::Report,
                    "a predicted compensated accuracy needs the calibrated robot and its report \
                     (and a target only with them)",
                ))
            }
        }
        Ok(e)
    }

    /// Evaluates and writes the figures.
    pub(crate) fn run(&self, env: &mut Env<'_>) -> Result<Done> {
        let e = self.evaluation()?;
        let mut staged = crate::files::output::Staged::new();
        if let Some(path) = &self.json {
            let json = serde_json::to_string_pretty(&e).map_err(|m| Error::Output {
                path: path.clone(),
                message: m.to_string(),
            })? + "\n";
            staged.text(Path::new(path), &json)?;
        }
        if let Some(path) = &self.html {
            let page = env.draw(Page::Iso9283(&e), path)?;
            staged.bytes(Path::new(path), &page)?;
        }
        staged.commit()?;
        let mut messages: Vec<Message> = e
            .warnings
            .iter()
            .map(|w| Message::Caution(w.clone()))
            .collect();
        for p in self.json.iter().chain(&self.html) {
            messages.push(Message::Note(format!("wrote {p}")));
        }
        Ok(Done {
            document: Document::Iso9283(Box::new(e)),
            messages,
            status: super::Status::Ok,
            pending: None,
        })
    }
}
