//! `predict`: the predicted accuracy of a calibrated robot at postures or Cartesian targets,
//! from its calibration report ([`crate::predict`]).
//!
//! ```toml
//! job = "predict"
//! robot = "calibrated.toml"
//! report = "report.json"          # calibrated with `validation.predict = true`
//! sample = 1000                   # or `postures = "p.csv"` or `targets = "t.csv"`
//!
//! [outputs]
//! predictions = "predicted.csv"
//! html = "map.html"
//! ```

use std::collections::BTreeMap;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::apps::compensate::{goal_in_file_units, GoalProblem, Options, TargetSearch};
use crate::error::{Error, Location, Result, Setting};
use crate::files::stream::{cell, Rows};
use crate::model::kinematics::Target;
use crate::model::robot::Robot;
use crate::predict::{self, PredictionReport, Predictor};
use crate::report::CalibrationReport;
use crate::units::{DisplayChoice, Quantity};

use super::common::{count, invalid, is_default, read_source, robot_as, visit_opt};
use super::{Document, Done, Env, JobKind, Message, Page, PathRole, Spec};

/// The most postures a prediction samples.
pub(crate) const MAX_SAMPLE: usize = 10_000_000;

/// What a prediction writes (`[outputs]`).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct PredictOutputs {
    /// The predictions (CSV: a row per posture; `-` for standard output).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub predictions: Option<String>,
    /// The accuracy map over the workspace (HTML).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub html: Option<String>,
    /// The units the page shows lengths and angles in (`default`: millimetres and degrees for
    /// a metre-radian robot; `robot`; or `mm-deg`, `um-deg`, ...).
    #[serde(default, skip_serializing_if = "DisplayChoice::is_default")]
    pub display_units: DisplayChoice,
}

/// A prediction. See the [module documentation](self).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct PredictSpec {
    /// The calibrated robot (the report's).
    #[serde(default)]
    pub robot: String,
    /// Its calibration report (JSON), with a prediction.
    #[serde(default)]
    pub report: String,
    /// Postures to predict at (`posture,v1..vn`; with a `site` column, each row at its own
    /// target, `ee` or a site; a measurement file: each position or pose at its target).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub postures: Option<String>,
    /// Instead, this many postures sampled within the joint ranges.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sample: Option<usize>,
    /// Instead, Cartesian goals (`target,x,y,z[,alpha,beta,gamma]`, robot file units, global
    /// frame), reached through the calibrated robot's inverse kinematics.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub targets: Option<String>,
    /// The seed of the sample and of the map (default 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
    /// The frame predicted: `ee` or a site (default: the report's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target: Option<String>,
    /// What is written.
    #[serde(default, skip_serializing_if = "is_default")]
    pub outputs: PredictOutputs,
}

impl Spec for PredictSpec {
    const KIND: JobKind = JobKind::Predict;

    fn visit_paths(&mut self, f: &mut dyn FnMut(PathRole, &mut String)) {
        f(PathRole::Robot, &mut self.robot);
        f(PathRole::Input, &mut self.report);
        visit_opt(f, PathRole::Input, &mut self.postures);
        visit_opt(f, PathRole::Input, &mut self.targets);
        visit_opt(f, PathRole::Output, &mut self.outputs.predictions);
        visit_opt(f, PathRole::Output, &mut self.outputs.html);
    }
}

/// The median, 95th percentile and largest of the predicted 95 % position bounds.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[non_exhaustive]
pub struct BoundSpread {
    /// Median.
    pub median: f64,
    /// 95th percentile.
    pub p95: f64,
    /// Largest.
    pub max: f64,
}

/// The document of a prediction: the predictions by column, in the robot file's units.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct PredictionTable {
    /// The calibrated robot's name.
    #[serde(default)]
    pub robot: String,
    /// The frame predicted.
    #[serde(default)]
    pub target: String,
    /// The robot file's length unit.
    #[serde(default)]
    pub length_unit: String,
    /// Its angle unit.
    #[serde(default)]
    pub angle_unit: String,
    /// The postures' labels.
    #[serde(default)]
    pub postures: Vec<String>,
    /// Each row's target, when the postures file has a `site` column.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sites: Vec<String>,
    /// The spread of the 95 % position bound.
    pub position_bound95: BoundSpread,
    /// Every column of the CSV but `posture`, by its name (`v1`, ..., `x`, `y`, `z`,
    /// `distance`, `position_bound95`, ...).
    pub columns: BTreeMap<String, Vec<f64>>,
}

/// A finished prediction.
#[derive(Debug)]
#[non_exhaustive]
pub struct PredictOutcome {
    /// The document.
    pub summary: PredictionTable,
    /// The predictions as CSV (what `outputs.predictions` holds).
    pub csv: String,
}

/// The calibrated robot `robot` (a file or built-in name), its calibration report `report` and
/// the prediction it holds, checked to be that robot's, with the frame to predict (`target`, or
/// the report's).
pub fn calibrated(
    robot: &str,
    report: &str,
    target: Option<&str>,
) -> Result<(Robot, CalibrationReport, PredictionReport, String)> {
    let (loaded, _) = robot_as(robot, Setting::Robot)?;
    let source = read_source(report, Setting::Report)?;
    let parsed = CalibrationReport::from_json(&source.text).map_err(|e| {
        Error::input(
            Location::file(&source.name),
            format!("not a calibration report: {e}"),
        )
    })?;
    let Some(pr) = parsed.prediction.clone() else {
        return Err(Error::input(
            Location::file(&source.name),
            format!(
                "the report has no prediction (its calibration was not asked for one, had fewer \
                 than {} postures measured by position or pose, or its kinecal made none): \
                 calibrate again with a prediction (--predict, predict=True)",
                predict::MIN_POSTURES
            ),
        ));
    };
    parsed
        .check_calibrated(&loaded, robot)
        .map_err(|e| Error::input(Location::file(&source.name), e.to_string()))?;
    let target = target.unwrap_or(&pr.target).to_string();
    Ok((loaded, parsed, pr, target))
}

/// The error of a Cartesian goal whose numbers look like another unit's, at `place` (file and
/// line).
pub(crate) fn goal_error(p: &GoalProblem, file: &str, line: u64, target: &str) -> Error {
    let at = Location::file(file).at_line(line as usize);
    match p {
        GoalProblem::Far(m) => Error::input(at, format!("{target} {m}")),
        GoalProblem::Turn(m) => Error::input(at, m.clone()),
    }
}

/// The readings that reach each Cartesian goal of `path` (`target,x,y,z[,alpha,beta,gamma]`,
/// `robot`'s file units and global frame) through `robot`'s inverse kinematics, labelled by the
/// goals' names. A goal out of reach or outside a joint range is an error naming its line.
fn reach_targets(
    robot: &Robot,
    path: &str,
    target: Target,
    messages: &mut Vec<Message>,
) -> Result<Vec<(String, Vec<f64>)>> {
    let mut rows = Rows::open(Path::new(path))?;
    let expected = "target,x,y,z[,alpha,beta,gamma]";
    let col = |rows: &Rows, name: &str| {
        rows.column(name).ok_or_else(|| {
            Error::input(
                Location::file(&rows.file).at_line(1),
                format!("no column `{name}` in the header (expected {expected})"),
            )
        })
    };
    let label = col(&rows, "target")?;
    let xyz = [col(&rows, "x")?, col(&rows, "y")?, col(&rows, "z")?];
    let euler: Option<Vec<usize>> = ["alpha", "beta", "gamma"]
        .iter()
        .map(|n| rows.column(n))
        .collect();
    if let Some(h) = rows.header.iter().find(|h| {
        !["target", "x", "y", "z", "alpha", "beta", "gamma"]
            .iter()
            .any(|k| h.eq_ignore_ascii_case(k))
    }) {
        return Err(Error::input(
            Location::file(&rows.file).at_line(1),
            format!("unknown column `{h}` (expected {expected})"),
        ));
    }
    let u = robot.units;
    let mut search = TargetSearch::new(robot, robot, Options::default())
        .map_err(|e| Error::input(Location::file(path), e.to_string()))?;
    let mut out = vec![0.0; robot.dof()];
    let mut reached = Vec::new();
    while let Some(line) = rows.advance()? {
        let mut p = [0.0; 3];
        for (k, &c) in xyz.iter().enumerate() {
            p[k] = cell(&rows, line, c)?;
        }
        let euler = match &euler {
            Some(e) if e.iter().any(|&c| !rows.field(c).is_empty()) => {
                let mut r = [0.0; 3];
                for (k, &c) in e.iter().enumerate() {
                    r[k] = cell(&rows, line, c)?;
                }
                Some(r)
            }
            _ => None,
        };
        let name = rows.field(label).to_string();
        let goal = goal_in_file_units(robot, p, euler)
            .map_err(|p| goal_error(&p, &rows.file, line, &format!("target `{name}`")))?;
        let s = search.solve(&goal, target, None, &mut out);
        if s.flags.unreachable || s.flags.out_of_range != 0 {
            return Err(Error::input(
                Location::file(&rows.file).at_line(line as usize),
                format!(
                    "target `{name}`: the calibrated robot does not reach it ({}): is it in the \
                     robot's global frame and length unit ({})?",
                    s.flags.describe(),
                    u.length
                ),
            ));
        }
        if s.flags.singular {
            messages.push(Message::Caution(format!(
                "{}:{line}: target `{name}` is reached near a singularity",
                rows.file
            )));
        }
        reached.push((name, out.clone()));
    }
    if reached.is_empty() {
        return Err(Error::input(
            Location::file(&rows.file),
            "no targets: the file has a header but no rows",
        ));
    }
    Ok(reached)
}

/// A posture to predict at: its label, readings and, from a `site` column, its own target
/// (name and frame).
type Row = (String, Vec<f64>, Option<(String, Target)>);

/// The rows of a postures file with a `site` column (`posture,site,v1..vn`, joint columns by
/// name in any order; or a measurement file: each position or pose), each at its target;
/// `None` when the file has no `site` column, or is a measurement file that measures `target`
/// alone (then a row per posture, as a postures file).
fn sited_postures(
    text: &str,
    file: &str,
    robot: &Robot,
    target: Target,
) -> Result<Option<Vec<Row>>> {
    use crate::observe::Observation;
    let t = crate::files::table::read(text, file)?;
    let Some(site) = t.column("site") else {
        return Ok(None);
    };
    if t.column("x").is_some() {
        let data = crate::files::parse_measurements(text, file, robot)?;
        let rows: Vec<Row> = data
            .observations
            .iter()
            .filter(|o| matches!(o, Observation::Position(_) | Observation::Pose(_)))
            .map(|o| {
                let p = &data.postures[o.posture()];
                let name = crate::observe::target_name(robot, o.target()).to_string();
                (
                    p.label.clone(),
                    p.readings.clone(),
                    Some((name, o.target())),
                )
            })
            .collect();
        if rows
            .iter()
            .all(|r| r.2.as_ref().is_some_and(|o| o.1 == target))
        {
            return Ok(None);
        }
        return Ok(Some(rows));
    }
    let mut expected = vec!["posture".to_string(), "site".to_string()];
    expected.extend((0..robot.dof()).map(|j| crate::files::reading_column(robot, &t.header, j)));
    let cols: Option<Vec<usize>> = expected.iter().map(|c| t.column(c)).collect();
    let cols = match cols {
        Some(cols) if t.header.len() == expected.len() => cols,
        _ => {
            let mut want = crate::files::postures_header(robot);
            want.insert(1, "site".into());
            return Err(Error::input(
                t.header_at(),
                format!(
                    "unexpected header `{}`: expected `{}` (joint columns may carry the \
                     joints' names, in any order)",
                    t.header.join(","),
                    want.join(",")
                ),
            ));
        }
    };
    t.check_rows()?;
    let mut rows = Vec::new();
    for (line, f) in t.rows() {
        let readings = (0..robot.dof())
            .map(|j| t.number(line, &expected[2 + j], &f[cols[2 + j]]))
            .collect::<Result<Vec<_>>>()?;
        let name = f[site].trim().to_string();
        let target = crate::files::site_target(robot, &name)
            .map_err(|m| Error::input(t.at(line, "site"), m))?;
        let name = crate::observe::target_name(robot, target).to_string();
        rows.push((f[cols[0]].to_string(), readings, Some((name, target))));
    }
    if rows.is_empty() {
        return Err(Error::input(
            Location::file(file),
            "no postures: the file has a header but no rows",
        ));
    }
    Ok(Some(rows))
}

impl PredictSpec {
    /// The predictor of `robot` from the prediction `pr` of its report, and the frame
    /// `target` names: the one translation, for files and for Python's arrays.
    pub fn predictor<'r>(
        robot: &'r Robot,
        pr: &PredictionReport,
        target: &str,
    ) -> Result<(Predictor<'r>, Target)> {
        let predictor = predict::from_report(robot, pr)?;
        let target =
            crate::files::site_target(robot, target).map_err(|m| invalid(Setting::Target, m))?;
        Ok((predictor, target))
    }

    /// The postures the spec names, labelled, each with its own target when the postures file
    /// has a `site` column.
    fn postures(
        &self,
        robot: &Robot,
        target: Target,
        messages: &mut Vec<Message>,
    ) -> Result<Vec<Row>> {
        let given = [
            self.postures.is_some(),
            self.sample.is_some(),
            self.targets.is_some(),
        ];
        if given.iter().filter(|g| **g).count() != 1 {
            return Err(invalid(
                Setting::Postures,
                "give one of postures (a file), a sample size or targets (a file)",
            ));
        }
        if let Some(path) = &self.postures {
            let s = read_source(path, Setting::Postures)?;
            if let Some(rows) = sited_postures(&s.text, &s.name, robot, target)? {
                return Ok(rows);
            }
            return Ok(crate::files::parse_postures(&s.text, &s.name, robot)?
                .into_iter()
                .map(|p| (p.label, p.readings, None))
                .collect());
        }
        if let Some(n) = self.sample {
            let n = count(Setting::Sample, n, MAX_SAMPLE, "postures")?;
            return Ok(predict::sample_readings(robot, n, self.seed.unwrap_or(1))
                .chunks(robot.dof())
                .enumerate()
                .map(|(i, r)| ((i + 1).to_string(), r.to_vec(), None))
                .collect());
        }
        let path = self.targets.as_deref().unwrap_or_default();
        Ok(reach_targets(robot, path, target, messages)?
            .into_iter()
            .map(|(l, r)| (l, r, None))
            .collect())
    }

    /// Reads the files, predicts and writes the outputs.
    pub(crate) fn run(&self, env: &mut Env<'_>) -> Result<Done> {
        let (robot, report, pr, target_name) =
            calibrated(&self.robot, &self.report, self.target.as_deref())?;
        let (predictor, target) =
            PredictSpec::predictor(&robot, &pr, &target_name).map_err(|e| match e {
                Error::InvalidOption { .. } => e,
                e => Error::input(Location::file(&self.report), e.to_string()),
            })?;
        let mut messages = Vec::new();
        let postures = self.postures(&robot, target, &mut messages)?;
        env.progress
            .say(&format!("predicting {} postures", postures.len()));
        let attitude = pr.attitude.is_some();
        let sited = postures.iter().any(|p| p.2.is_some());
        let header = predict::csv_header(&robot, attitude, sited);
        let mut csv = header.clone();
        csv.push('\n');
        let names: Vec<String> = header
            .split(',')
            .skip(if sited { 2 } else { 1 })
            .map(str::to_string)
            .collect();
        let mut columns: Vec<Vec<f64>> = names
            .iter()
            .map(|_| Vec::with_capacity(postures.len()))
            .collect();
        let u = robot.units;
        let (l, a) = (
            |v: f64| u.from_si(Quantity::Length, v),
            |v: f64| u.from_si(Quantity::Angle, v),
        );
        let mut s = predictor.scratch();
        let mut bounds = Vec::with_capacity(postures.len());
        for (k, (label, readings, own)) in postures.iter().enumerate() {
            if k % 5000 == 0 && k > 0 {
                env.progress
                    .say(&format!("predicting: {k} of {} postures", postures.len()));
            }
            let at = own.as_ref().map_or(target, |o| o.1);
            let p = predictor.predict(readings, at, &mut s);
            bounds.push(l(p.position_error.bound));
            let site = own.as_ref().map(|o| o.0.as_str());
            predict::csv_row(&robot, label, site, readings, &p, &mut csv);
            let b = p.position_error;
            let mut values: Vec<f64> = readings.clone();
            values.extend([
                l(p.position.x),
                l(p.position.y),
                l(p.position.z),
                l(p.distance),
                l(b.parameters),
                l(b.model),
                l(b.bound),
                l(b.parameters_bound),
            ]);
            if let Some(b) = p.attitude_error {
                values.extend([
                    a(b.parameters),
                    a(b.model),
                    a(b.bound),
                    a(b.parameters_bound),
                ]);
            }
            for (c, v) in columns.iter_mut().zip(values) {
                c.push(v);
            }
        }
        let mut staged = crate::files::output::Staged::new();
        if let Some(path) = &self.outputs.predictions {
            staged.text(Path::new(path), &csv)?;
        }
        if let Some(path) = &self.outputs.html {
            let measured: Vec<&[f64]> = pr.measured.iter().map(Vec::as_slice).collect();
            let map = predict::accuracy_map(
                &predictor,
                target,
                &measured,
                predict::MAP_SAMPLES,
                self.seed.unwrap_or(1),
            );
            let mut with_map = pr.clone();
            with_map.map = Some(map);
            let page = env.draw(
                Page::Prediction {
                    prediction: &with_map,
                    robot: &report.robot,
                    length_unit: report.length_unit,
                    angle_unit: report.angle_unit,
                    units: self
                        .outputs
                        .display_units
                        .resolve(report.length_unit, report.angle_unit),
                },
                path,
            )?;
            staged.bytes(Path::new(path), &page)?;
        }
        staged.commit()?;
        let mut sorted = bounds;
        sorted.sort_by(f64::total_cmp);
        let pick = |q: f64| {
            let rank = ((q * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len());
            sorted[rank - 1]
        };
        let summary = PredictionTable {
            robot: report.robot.clone(),
            target: target_name.clone(),
            length_unit: u.length.to_string(),
            angle_unit: u.angle.to_string(),
            postures: postures.iter().map(|p| p.0.clone()).collect(),
            sites: if sited {
                postures
                    .iter()
                    .map(|p| p.2.as_ref().map_or(target_name.clone(), |o| o.0.clone()))
                    .collect()
            } else {
                Vec::new()
            },
            position_bound95: BoundSpread {
                median: pick(0.5),
                p95: pick(0.95),
                max: pick(1.0),
            },
            columns: names.into_iter().zip(columns).collect(),
        };
        for (path, what) in [
            (&self.outputs.predictions, "the predictions"),
            (&self.outputs.html, "the accuracy map"),
        ] {
            if let Some(p) = path.as_deref().filter(|p| *p != "-") {
                messages.push(Message::Note(format!("wrote {what} to {p}")));
            }
        }
        Ok(Done {
            document: Document::Prediction(Box::new(PredictOutcome { summary, csv })),
            messages,
            status: super::Status::Ok,
            pending: None,
        })
    }
}
