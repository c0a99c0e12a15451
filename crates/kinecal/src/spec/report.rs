//! `report`: the HTML page of a calibration, from its report, or of a calibrated robot assessed
//! on observations (with the accuracy it is predicted to reach).
//!
//! ```toml
//! job = "report"
//! from = "report.json"            # or robot, observations and calibrated (or calibration)
//! out = "report.html"
//! display_units = "mm-deg"        # default: mm and deg for a metre-radian robot; or "robot"
//! ```

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Location, Result, Setting};
use crate::files::{ObservationFile, ReadSettings};
use crate::model::robot::Robot;
use crate::report::CalibrationReport;
use crate::units::DisplayChoice;

use super::common::{
    invalid, is_default, read_observations, read_source, robot_as, visit_observations, visit_opt,
    Residuals,
};
use super::{Document, Done, Env, JobKind, Page, PathRole, Spec};

/// A report page. See the [module documentation](self).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct ReportSpec {
    /// A calibration report (JSON) to draw as it is.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub from: Option<String>,
    /// The nominal robot (without `from`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub robot: Option<String>,
    /// How the observation files are read.
    #[serde(default, skip_serializing_if = "is_default")]
    pub read: ReadSettings,
    /// The observations the calibrated robot is assessed on.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub observations: Vec<ObservationFile>,
    /// The calibrated robot.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub calibrated: Option<String>,
    /// Instead, a calibration report whose estimates make the calibrated robot.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub calibration: Option<String>,
    /// The weights and the orientation residual.
    #[serde(default, skip_serializing_if = "is_default")]
    pub residuals: Residuals,
    /// The page to write.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub out: Option<String>,
    /// The units the page shows lengths and angles in (`default`: millimetres and degrees for
    /// a metre-radian robot; `robot`; or `mm-deg`, `um-deg`, ...).
    #[serde(default, skip_serializing_if = "DisplayChoice::is_default")]
    pub display_units: DisplayChoice,
}

impl Spec for ReportSpec {
    const KIND: JobKind = JobKind::Report;

    fn visit_paths(&mut self, f: &mut dyn FnMut(PathRole, &mut String)) {
        visit_opt(f, PathRole::Input, &mut self.from);
        visit_opt(f, PathRole::Robot, &mut self.robot);
        visit_observations(f, &mut self.observations);
        visit_opt(f, PathRole::Robot, &mut self.calibrated);
        visit_opt(f, PathRole::Input, &mut self.calibration);
        visit_opt(f, PathRole::Output, &mut self.out);
    }
}

/// A calibration report read from `path`.
fn read_report(path: &str, setting: Setting) -> Result<CalibrationReport> {
    let s = read_source(path, setting)?;
    CalibrationReport::from_json(&s.text).map_err(|e| {
        Error::input(
            Location::file(&s.name),
            format!("not a kinecal calibration report: {e}"),
        )
    })
}

impl ReportSpec {
    /// The calibrated robot: `calibrated`, or `nominal` with the estimates of `calibration`.
    fn calibrated_robot(&self, nominal: &Robot) -> Result<Robot> {
        match (&self.calibrated, &self.calibration) {
            (Some(name), None) => Ok(robot_as(name, Setting::Calibrated)?.0),
            (None, Some(path)) => {
                let rep = read_report(path, Setting::Calibrated)?;
                if rep.parameters.len() != nominal.param_count() {
                    return Err(Error::input(
                        Location::file(path.as_str()),
                        format!(
                            "the report has {} parameters, the robot {}",
                            rep.parameters.len(),
                            nominal.param_count()
                        ),
                    ));
                }
                let mut c = nominal.clone();
                for (id, p) in nominal.param_ids().zip(&rep.parameters) {
                    c.set(
                        id,
                        nominal.units.to_si(nominal.param_quantity(id), p.estimated),
                    );
                }
                Ok(c)
            }
            _ => Err(invalid(
                Setting::Calibrated,
                "give the calibrated robot or its calibration report (one of them)",
            )),
        }
    }

    /// The report the page draws.
    pub fn report(&self) -> Result<CalibrationReport> {
        if let Some(from) = &self.from {
            if self.robot.is_some()
                || self.calibrated.is_some()
                || self.calibration.is_some()
                || !self.observations.is_empty()
            {
                return Err(invalid(
                    Setting::Calibrated,
                    "a report drawn from its JSON takes no robot, observations or calibration",
                ));
            }
            return read_report(from, Setting::Report);
        }
        let name = self.robot.as_deref().ok_or_else(|| {
            invalid(
                Setting::Robot,
                "give the robot with its observations, or a report to draw",
            )
        })?;
        let (nominal, source) = robot_as(name, Setting::Robot)?;
        let (data, sources) = read_observations(&self.read, &self.observations, &nominal)?;
        let (weights, orientation) = self.residuals.resolve(&nominal)?;
        let calibrated = self.calibrated_robot(&nominal)?;
        let sources: Vec<_> = std::iter::once(source.fingerprint())
            .chain(sources)
            .collect();
        let mut outcome =
            crate::workflow::assess(&nominal, &calibrated, &data, weights, orientation, &sources)?;
        // The predicted accuracy and its map, as a calibration's HTML report gives them.
        crate::workflow::add_prediction(&mut outcome, &nominal, crate::predict::Level::Map);
        // And its 3-D view.
        outcome.report.scene = crate::report::scene::Scene::new(
            Some(&nominal),
            &calibrated,
            Some(&data),
            &Default::default(),
        )
        .ok();
        Ok(outcome.report)
    }

    /// Draws and writes the page.
    pub(crate) fn run(&self, env: &mut Env<'_>) -> Result<Done> {
        let out = self
            .out
            .as_deref()
            .ok_or_else(|| invalid(Setting::Output, "no page to write given"))?;
        let report = self.report()?;
        let units = self
            .display_units
            .resolve(report.length_unit, report.angle_unit);
        let page = env.draw(
            Page::Calibration {
                report: &report,
                units,
            },
            out,
        )?;
        let mut staged = crate::files::output::Staged::new();
        staged.bytes(Path::new(out), &page)?;
        staged.commit()?;
        let mut done = Done::ok(Document::Page {
            path: out.to_string(),
        });
        done.note(format!("wrote {out}"));
        Ok(done)
    }
}
