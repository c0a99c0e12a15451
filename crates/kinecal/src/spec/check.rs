//! `check`: whether a robot still meets its accuracy on fresh measurements.
//!
//! ```toml
//! job = "check"
//! robot = "calibrated.toml"
//! threshold = { length = 0.5, angle = 0.1 }   # robot file's units; the angle optional
//!
//! [[observations]]
//! file = "check.csv"
//! ```

use serde::{Deserialize, Serialize};

use crate::error::{Result, Setting};
use crate::files::{ObservationFile, ReadSettings};
use crate::model::robot::Robot;
use crate::observe::Dataset;
use crate::workflow::{CheckReport, Thresholds, Verdict};

use super::common::{
    invalid, is_default, read_observations, robot_as, visit_observations, LengthAngle,
};
use super::{Document, Done, Env, JobKind, PathRole, Spec, Status};

/// A check. See the [module documentation](self).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct CheckSpec {
    /// The robot (as calibrated).
    #[serde(default)]
    pub robot: String,
    /// How the observation files are read.
    #[serde(default, skip_serializing_if = "is_default")]
    pub read: ReadSettings,
    /// The check observations.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub observations: Vec<ObservationFile>,
    /// The largest acceptable errors: a length (required unless every observation is a pixel)
    /// and an angle (robot file's units).
    #[serde(default)]
    pub threshold: LengthAngle,
    /// The largest acceptable reprojection error of pixel observations (pixels; required with
    /// them).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pixel_threshold: Option<f64>,
}

impl Spec for CheckSpec {
    const KIND: JobKind = JobKind::Check;

    fn visit_paths(&mut self, f: &mut dyn FnMut(PathRole, &mut String)) {
        f(PathRole::Robot, &mut self.robot);
        visit_observations(f, &mut self.observations);
    }
}

/// A finished check.
#[derive(Debug)]
#[non_exhaustive]
pub struct CheckOutcome {
    /// The verdict (SI).
    pub verdict: Verdict,
    /// The robot checked.
    pub robot: Robot,
    /// The thresholds (SI).
    pub thresholds: Thresholds,
    /// The document.
    pub report: CheckReport,
}

impl CheckSpec {
    /// The thresholds in SI for `robot`.
    pub fn thresholds(&self, robot: &Robot) -> Result<Thresholds> {
        self.threshold.check(Setting::CheckThreshold, true)?;
        let (length, angle) = self.threshold.si(robot);
        if length.is_none() && (angle.is_some() || self.pixel_threshold.is_none()) {
            return Err(invalid(
                Setting::CheckThreshold,
                "a length is needed (and an angle when attitudes are checked; pixels alone need \
                 only the pixel threshold)",
            ));
        }
        if let Some(p) = self
            .pixel_threshold
            .filter(|p| !(p.is_finite() && *p > 0.0))
        {
            return Err(invalid(
                Setting::CheckThreshold,
                format!("the pixel threshold must be positive and finite, not {p}"),
            ));
        }
        Ok(Thresholds {
            length,
            angle,
            pixel: self.pixel_threshold,
        })
    }

    /// Checks `robot` on `data`.
    pub fn check(&self, robot: &Robot, data: &Dataset) -> Result<Done> {
        let thresholds = self.thresholds(robot)?;
        let verdict = crate::workflow::check(robot, data, thresholds)?;
        let report = CheckReport::new(&verdict, robot, data.observations.len());
        let status = if verdict.ok {
            Status::Ok
        } else {
            Status::Flagged
        };
        Ok(Done {
            document: Document::Check(Box::new(CheckOutcome {
                verdict,
                robot: robot.clone(),
                thresholds,
                report,
            })),
            messages: Vec::new(),
            status,
            pending: None,
        })
    }

    /// Reads the files and checks.
    pub(crate) fn run(&self, _env: &mut Env<'_>) -> Result<Done> {
        let (robot, _) = robot_as(&self.robot, Setting::Robot)?;
        let data = read_observations(&self.read, &self.observations, &robot)?.0;
        self.check(&robot, &data)
    }
}
