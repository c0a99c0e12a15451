//! `curves`: the thesis's characteristic curves (Figs 4.2-4.11): the pose at one posture, or
//! the objective over observations, against one parameter swept over a span.
//!
//! ```toml
//! job = "curves"
//! curve = "pose"                  # or "objective" (with observations)
//! robot = "ge-a4"
//! readings = [12.5, -16.25, 1.0, 10.0]
//! sweep = { param = "p4", span = 360.0 }
//! out = "p4.svg"                  # .svg, .png or .csv; "-": the table on standard output
//! ```

use std::fmt::Write as _;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::apps::curves::{is_convex, local_minima, objective_curve, period, pose_curve};
use crate::error::{Error, Location, Result, Setting};
use crate::files::{parse_postures, ObservationFile, ReadSettings};
use crate::model::robot::Robot;
use crate::units::number::format_number;
use crate::{JointKind, ParamId, ParamKind};

use super::common::{
    invalid, is_default, read_observations, read_source, robot_as, visit_observations, visit_opt,
    Residuals,
};
use super::{Document, Done, Env, Image, JobKind, Page, PathRole, Spec};

/// Which curve.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
#[non_exhaustive]
pub enum CurveKind {
    /// The pose at one posture.
    #[default]
    Pose,
    /// The objective over observations.
    Objective,
}

/// The sweep of the parameters (`sweep`): over `span` around the value, or `from`..`to`, or by
/// default over a span that depends on the parameter.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct Sweep {
    /// The parameters, each on its own curve (a parameter list).
    #[serde(default)]
    pub param: String,
    /// The width of the sweep around each value (robot file's units).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub span: Option<f64>,
    /// Its start (with `to`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub from: Option<f64>,
    /// Its end (with `from`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub to: Option<f64>,
    /// The number of points (default 201).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub points: Option<usize>,
}

/// Characteristic curves. See the [module documentation](self).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct CurvesSpec {
    /// Which curve.
    #[serde(default)]
    pub curve: CurveKind,
    /// The robot, at its values.
    #[serde(default)]
    pub robot: String,
    /// The posture's readings (pose).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub readings: Option<Vec<f64>>,
    /// Instead, a postures file (pose; with `posture`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub postures: Option<String>,
    /// The posture's label in that file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub posture: Option<String>,
    /// The frame whose pose is drawn: `ee` (default) or a site (pose).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub site: Option<String>,
    /// How the observation files are read (objective).
    #[serde(default, skip_serializing_if = "is_default")]
    pub read: ReadSettings,
    /// The observations (objective).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub observations: Vec<ObservationFile>,
    /// The weights and the orientation residual (objective).
    #[serde(default, skip_serializing_if = "is_default")]
    pub residuals: Residuals,
    /// The sweep.
    #[serde(default)]
    pub sweep: Sweep,
    /// The file to write: `.svg`, `.png` or `.csv` by its extension; `-` writes the table
    /// (CSV) on standard output.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub out: Option<String>,
}

impl Spec for CurvesSpec {
    const KIND: JobKind = JobKind::Curves;

    fn visit_paths(&mut self, f: &mut dyn FnMut(PathRole, &mut String)) {
        f(PathRole::Robot, &mut self.robot);
        visit_opt(f, PathRole::Input, &mut self.postures);
        visit_observations(f, &mut self.observations);
        visit_opt(f, PathRole::Output, &mut self.out);
    }
}

/// One chart of curves.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct SweptParameter {
    /// Its title.
    #[serde(default)]
    pub title: String,
    /// The x axis's label (with unit).
    #[serde(default)]
    pub x_label: String,
    /// The y axis's label (with unit).
    #[serde(default)]
    pub y_label: String,
    /// The parameter's values.
    pub x: Vec<f64>,
    /// The curves: a name and its values.
    pub lines: Vec<(String, Vec<f64>)>,
    /// The parameter's value in the robot (marked).
    pub mark_x: f64,
}

/// The document of curves: the charts, their table and what they show in words.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct Curves {
    /// Which curve.
    #[serde(default)]
    pub curve: CurveKind,
    /// The charts, in order.
    pub charts: Vec<SweptParameter>,
    /// Charts per row in a picture.
    #[serde(default)]
    pub columns: usize,
    /// The table (what a `.csv` output holds).
    #[serde(default)]
    pub csv: String,
    /// What the curves show: periods, minima, convexity.
    #[serde(default)]
    pub findings: Vec<String>,
}

/// What an output's name says to write.
enum Out {
    Image(Image),
    Csv,
}

fn out_kind(path: &str) -> Result<Out> {
    // Standard output gets the table.
    if path == "-" {
        return Ok(Out::Csv);
    }
    match Path::new(path)
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .as_deref()
    {
        Some("svg") => Ok(Out::Image(Image::Svg)),
        Some("png") => Ok(Out::Image(Image::Png)),
        Some("csv") => Ok(Out::Csv),
        _ => Err(invalid(
            Setting::Output,
            format!(
                "{path}: the name must end in .svg, .png or .csv (or be `-`: the table on \
                 standard output)"
            ),
        )),
    }
}

fn slope_joint(robot: &Robot, id: ParamId) -> usize {
    match robot.param_kind(id) {
        ParamKind::Slope { joint } | ParamKind::Offset { joint } => joint,
        _ => 0,
    }
}

impl CurvesSpec {
    /// The values swept for `id` of `robot`.
    fn values(&self, robot: &Robot, id: ParamId) -> Result<Vec<f64>> {
        let s = &self.sweep;
        let v = robot.get_user(id);
        let (a, b) = match (s.from, s.to, s.span) {
            (Some(a), Some(b), None) => (a, b),
            (None, None, Some(w)) => {
                if !(w.is_finite() && w > 0.0) {
                    return Err(invalid(
                        Setting::Span,
                        format!(
                            "{}: expected a positive number, the width of the sweep (from the \
                             parameter's value less half of it to the value plus half, in the \
                             robot file's units)",
                            format_number(w)
                        ),
                    ));
                }
                (v - w / 2.0, v + w / 2.0)
            }
            (None, None, None) => {
                let half = crate::apps::curves::default_half_width(
                    robot,
                    id,
                    self.curve == CurveKind::Objective,
                );
                (v - half, v + half)
            }
            _ => {
                return Err(invalid(
                    Setting::Sweep,
                    "give a span, or from and to, or neither",
                ))
            }
        };
        crate::apps::curves::sweep(a, b, s.points.unwrap_or(201))
    }

    /// The readings of the pose curve's posture.
    fn readings(&self, robot: &Robot) -> Result<Vec<f64>> {
        let readings = match (&self.readings, &self.postures, &self.posture) {
            (Some(r), None, None) => r.clone(),
            (None, Some(path), Some(label)) => {
                let s = read_source(path, Setting::Postures)?;
                parse_postures(&s.text, &s.name, robot)?
                    .into_iter()
                    .find(|p| &p.label == label)
                    .ok_or_else(|| {
                        Error::input(
                            Location::file(path.as_str()),
                            format!("no posture `{label}`"),
                        )
                    })?
                    .readings
            }
            _ => {
                return Err(invalid(
                    Setting::Postures,
                    "give the readings, or a postures file and a posture's label",
                ))
            }
        };
        // What was wrong is the readings given, or the posture read from the file.
        let setting = if self.readings.is_some() {
            Setting::Readings
        } else {
            Setting::Postures
        };
        if readings.len() != robot.dof() {
            return Err(invalid(
                setting,
                format!(
                    "{} readings for a robot with {} joints",
                    readings.len(),
                    robot.dof()
                ),
            ));
        }
        if let Some(v) = readings.iter().find(|v| !v.is_finite()) {
            return Err(invalid(setting, format!("{v} is not a finite reading")));
        }
        Ok(readings)
    }

    /// The curves of the pose at one posture.
    fn pose(&self, robot: &Robot) -> Result<Curves> {
        if !self.observations.is_empty() {
            return Err(invalid(
                Setting::Observations,
                "the pose curve is of one posture: observations are for the objective",
            ));
        }
        let readings = self.readings(robot)?;
        let target = crate::files::site_target(robot, self.site.as_deref().unwrap_or("ee"))
            .map_err(|m| invalid(Setting::Site, m))?;
        let ids = crate::model::param_list::parse_param_list(&self.sweep.param, robot)?;
        let (l, an) = (
            robot.units.length.to_string(),
            robot.units.angle.to_string(),
        );
        let mut charts = Vec::new();
        let mut findings = Vec::new();
        let mut csv = String::from("param,value,x,y,z,alpha,beta,gamma\n");
        for &id in &ids {
            let x = self.values(robot, id)?;
            let c = pose_curve(robot, &readings, target, id, &x);
            let name = robot.param_name(id);
            let unit = robot.param_unit(id);
            for (v, row) in x.iter().zip(&c) {
                let _ = write!(csv, "{id},{}", format_number(*v));
                for r in row {
                    let _ = write!(csv, ",{}", format_number(*r));
                }
                csv.push('\n');
            }
            let col = |k: usize| c.iter().map(|r| r[k]).collect::<Vec<_>>();
            let mark_x = robot.get_user(id);
            charts.push(SweptParameter {
                title: format!("{id} ({name}): position"),
                x_label: format!("{name} ({unit})"),
                y_label: format!("position ({l})"),
                x: x.clone(),
                lines: vec![
                    ("x".into(), col(0)),
                    ("y".into(), col(1)),
                    ("z".into(), col(2)),
                ],
                mark_x,
            });
            charts.push(SweptParameter {
                title: format!("{id} ({name}): attitude (unwrapped)"),
                x_label: format!("{name} ({unit})"),
                y_label: format!("ZYX Euler angle ({an})"),
                x,
                lines: vec![
                    ("alpha".into(), col(3)),
                    ("beta".into(), col(4)),
                    ("gamma".into(), col(5)),
                ],
                mark_x,
            });
            findings.push(match period(robot, id, Some(&readings)) {
                Some(t) => format!("{id} ({name}): periodic, period {t:.6} {unit}"),
                None => format!("{id} ({name}): not periodic"),
            });
        }
        Ok(Curves {
            curve: CurveKind::Pose,
            charts,
            columns: 2,
            csv,
            findings,
        })
    }

    /// The curves of the objective over observations.
    fn objective(&self, robot: &Robot) -> Result<Curves> {
        if self.readings.is_some() || self.postures.is_some() || self.site.is_some() {
            return Err(invalid(
                Setting::Observations,
                "the objective curve is over observations: readings, postures and site are for \
                 the pose curve",
            ));
        }
        let (data, _) = read_observations(&self.read, &self.observations, robot)?;
        let (weights, orientation) = self.residuals.resolve(robot)?;
        let ids = crate::model::param_list::parse_param_list(&self.sweep.param, robot)?;
        let mut charts = Vec::new();
        let mut findings = Vec::new();
        let mut csv = String::from("param,value,objective\n");
        let single = (data.postures.len() == 1).then(|| data.postures[0].readings.clone());
        for &id in &ids {
            let x = self.values(robot, id)?;
            let f = objective_curve(robot, &data, id, &x, weights, orientation);
            let name = robot.param_name(id);
            let unit = robot.param_unit(id);
            for (v, o) in x.iter().zip(&f) {
                let _ = writeln!(csv, "{id},{},{}", format_number(*v), format_number(*o));
            }
            let minima = local_minima(&x, &f);
            findings.push(format!(
                "{id} ({name}), {} .. {} {unit}:",
                format_number(x[0]),
                format_number(x[x.len() - 1])
            ));
            if minima.is_empty() {
                findings.push(
                    "  no interior local minimum (the minimum is at an end of the span)".into(),
                );
            }
            for (v, o) in &minima {
                findings.push(format!(
                    "  local minimum at {v:.6} {unit}: objective {o:.6e}"
                ));
            }
            if !is_convex(&f) {
                findings.push(format!(
                    "  warning: the objective is not convex over this span ({} valleys): a solver \
                     started here could stop in a false valley",
                    minima.len()
                ));
            }
            match period(robot, id, single.as_deref()) {
                Some(t) => findings.push(format!("  periodic: period {t:.6} {unit}")),
                None if matches!(robot.param_kind(id), ParamKind::Slope { .. })
                    && robot.joints[slope_joint(robot, id)].kind == JointKind::Revolute =>
                {
                    let periods: Vec<String> = data
                        .postures
                        .iter()
                        .filter_map(|p| {
                            period(robot, id, Some(&p.readings))
                                .map(|t| format!("{}: {t:.3}", p.label))
                        })
                        .take(8)
                        .collect();
                    findings.push(format!(
                        "  each posture alone repeats every 360/V {unit} ({}{})",
                        periods.join(", "),
                        if data.postures.len() > 8 { ", ..." } else { "" }
                    ));
                }
                None => {}
            }
            charts.push(SweptParameter {
                title: format!("Objective against {id} ({name})"),
                x_label: format!("{name} ({unit})"),
                y_label: "objective (weighted sum of squares)".into(),
                x,
                lines: vec![("objective".into(), f)],
                mark_x: robot.get_user(id),
            });
        }
        Ok(Curves {
            curve: CurveKind::Objective,
            charts,
            columns: 1,
            csv,
            findings,
        })
    }

    /// The curves of the spec.
    pub fn curves(&self) -> Result<Curves> {
        let (robot, _) = robot_as(&self.robot, Setting::Robot)?;
        match self.curve {
            CurveKind::Pose => self.pose(&robot),
            CurveKind::Objective => self.objective(&robot),
        }
    }

    /// Computes, draws and writes the curves.
    pub(crate) fn run(&self, env: &mut Env<'_>) -> Result<Done> {
        let kind = self.out.as_deref().map(out_kind).transpose()?;
        let curves = self.curves()?;
        if let (Some(path), Some(kind)) = (&self.out, kind) {
            let bytes = match kind {
                Out::Csv => curves.csv.clone().into_bytes(),
                Out::Image(image) => env.draw(
                    Page::Curves {
                        curves: &curves,
                        image,
                    },
                    path,
                )?,
            };
            let mut staged = crate::files::output::Staged::new();
            staged.bytes(Path::new(path), &bytes)?;
            staged.commit()?;
        }
        let mut done = Done::ok(Document::Curves(Box::new(curves)));
        if let Some(p) = self.out.as_deref().filter(|p| *p != "-") {
            done.note(format!("wrote {p}"));
        }
        Ok(done)
    }
}
