//! A robot already calibrated: [`assess`] builds the outcome of a calibration that exists (a
//! calibrated robot file against its nominal), [`check`] tells whether a robot in service still
//! meets its accuracy on check observations (thresholds in metres and radians).

use std::sync::Arc;

use crate::error::{Error, Result};
use crate::model::params::ParamId;
use crate::model::robot::Robot;
use crate::observe::{accuracy, Accuracy, Dataset, OrientationError, Weights};
use crate::solve::estimation::{self, Calibration, CalibrationOptions};
use crate::solve::outliers;
use crate::solve::problem::Problem;
use crate::source::Fingerprint;
use crate::uncertainty;

use super::min_change::SolutionRule;
use super::outcome::{data_warnings, finish, Outcome};

/// The outcome of a calibration that already exists: `calibrated` (a robot file written by a
/// calibration of `nominal`) assessed on `data`. The estimated parameters are those that
/// differ from the nominal ones.
pub fn assess(
    nominal: &Robot,
    calibrated: &Robot,
    data: &Dataset,
    weights: Weights,
    orientation: OrientationError,
    sources: &[Fingerprint],
) -> Result<Outcome> {
    if !nominal.same_structure(calibrated) {
        return Err(Error::OtherStructure {
            robot: "the calibrated robot",
        });
    }
    let mut calibrated = calibrated.clone();
    for (p, c) in nominal.planes.iter().zip(calibrated.planes.iter_mut()) {
        let (n, offset) = (c.normal(), c.offset);
        *c = p.clone();
        c.offset = offset;
        c.set_normal(&n);
    }
    let mut estimated: Vec<ParamId> = nominal
        .param_ids()
        .filter(|&id| (nominal.get(id) - calibrated.get(id)).abs() > 0.0)
        .collect();
    if estimated.is_empty() {
        estimated = nominal.param_ids().collect();
    }
    let mut options = CalibrationOptions::new(estimated.clone());
    options.weights = weights;
    options.orientation = orientation;
    let problem = Problem::new(nominal, data, &estimated, weights, orientation);
    let mut residuals = vec![0.0; problem.rows()];
    let (objective_before, accuracy_before, errors_before) =
        problem.evaluate_checked(nominal, &mut residuals);
    let (objective_after, accuracy_after, errors_after) =
        problem.evaluate_checked(&calibrated, &mut residuals);
    let cal = Calibration {
        objective_before,
        objective_after,
        prior_objective: 0.0,
        accuracy_before,
        accuracy_after,
        initial: nominal.clone(),
        calibrated,
        estimated: estimated.clone(),
        options,
        termination: estimation::Termination::Given,
        stationarity: Default::default(),
        iterations: 0,
        unfelt: Vec::new(),
        row_scale: vec![1.0; problem.rows()],
        model_error: None,
        staged: false,
        log: Vec::new(),
        residuals,
        start_r: None,
        errors_before: Some(errors_before),
        errors_after: Some(errors_after),
    };
    let mut warnings = data_warnings(
        nominal,
        data,
        &crate::observe::sanity::predicted(nominal, data),
    );
    let unc = uncertainty::uncertainty(&cal, data, nominal);
    Ok(finish(
        nominal.clone(),
        Arc::new(data.clone()),
        None,
        cal,
        unc,
        None,
        outliers::DEFAULT_SIGMAS,
        SolutionRule::Solver,
        sources,
        &mut warnings,
    ))
}

/// The largest acceptable errors of a robot in service.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct Thresholds {
    /// Largest acceptable length error (m): position errors, and the errors of other length
    /// metrics (distances, contacts); needed when the data has any of them (a check of pixels
    /// alone needs none).
    pub length: Option<f64>,
    /// Largest acceptable attitude error (rad), when attitudes are checked.
    pub angle: Option<f64>,
    /// Largest acceptable reprojection error (pixels), when pixels are checked.
    pub pixel: Option<f64>,
}

/// Whether a robot still meets its accuracy on check observations.
#[derive(Debug, Clone, PartialEq)]
pub struct Verdict {
    /// True when every error is within the thresholds.
    pub ok: bool,
    /// The errors.
    pub accuracy: Accuracy,
    /// The thresholds.
    pub thresholds: Thresholds,
}

/// Checks `robot`'s predictions against check observations.
pub fn check(robot: &Robot, data: &Dataset, thresholds: Thresholds) -> Result<Verdict> {
    let ok_threshold = |v: f64| v.is_finite() && v > 0.0;
    if !thresholds.length.is_none_or(ok_threshold) || !thresholds.angle.is_none_or(ok_threshold) {
        return Err(Error::InvalidOption {
            setting: crate::error::Setting::CheckThreshold,
            message: "thresholds must be positive finite numbers".into(),
        });
    }
    if thresholds.pixel.is_some_and(|p| !ok_threshold(p)) {
        return Err(Error::InvalidOption {
            setting: crate::error::Setting::CheckThreshold,
            message: "thresholds must be positive finite numbers".into(),
        });
    }
    let acc = accuracy(robot, data);
    // Pixels against the pixel threshold, never against a length.
    if thresholds.pixel.is_none() && acc.other.iter().any(|m| m.metric == "pixel") {
        return Err(Error::InvalidOption {
            setting: crate::error::Setting::CheckThreshold,
            message: "pixel observations are checked against a pixel threshold: give one \
                      (pixel_threshold, --pixel-threshold PX)"
                .into(),
        });
    }
    let lengths = acc.positions + acc.other.iter().filter(|m| m.metric != "pixel").count();
    let Some(length) = thresholds
        .length
        .or((lengths == 0).then_some(f64::INFINITY))
    else {
        return Err(Error::InvalidOption {
            setting: crate::error::Setting::CheckThreshold,
            message: "the data has positions, poses, distances or contacts: a length threshold \
                      is needed (threshold, --threshold LENGTH[,ANGLE])"
                .into(),
        });
    };
    let mut ok = (acc.positions == 0 || acc.max_position <= length)
        && acc.other.iter().all(|m| match m.metric {
            "pixel" => thresholds.pixel.is_some_and(|p| m.max <= p),
            _ => m.max <= length,
        });
    if let Some(t) = thresholds.angle {
        ok &= acc.orientations == 0 || acc.max_orientation <= t;
    }
    Ok(Verdict {
        ok,
        accuracy: acc,
        thresholds,
    })
}

/// A check's verdict as a document: what `kinecal check --json` prints (robot file's units).
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize, PartialEq, schemars::JsonSchema)]
#[non_exhaustive]
pub struct CheckReport {
    /// The version of this document's schema ([`crate::report::SCHEMA_VERSION`]).
    pub schema_version: u32,
    /// True when every error is within the thresholds.
    pub ok: bool,
    /// Check observations.
    pub measurements: usize,
    /// Largest position error (length unit).
    pub max_position_error: f64,
    /// RMS position error.
    pub rms_position_error: f64,
    /// Largest attitude error (angle unit; null without attitudes).
    pub max_orientation_error: Option<f64>,
    /// The other length metrics (distances, contacts).
    pub other: Vec<CheckMetric>,
    /// The length threshold (absent for a check of pixels alone given none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub threshold_length: Option<f64>,
    /// The angle threshold, when attitudes are checked.
    pub threshold_angle: Option<f64>,
    /// The pixel threshold, when pixels are checked.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub threshold_pixel: Option<f64>,
}

/// A length metric of a check (in a [`CheckReport`]).
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize, PartialEq, schemars::JsonSchema)]
#[non_exhaustive]
pub struct CheckMetric {
    /// `distance`, `contact`, `pixel`.
    pub metric: String,
    /// Its largest error (length unit; pixels for `pixel`).
    pub max: f64,
    /// Its RMS error.
    pub rms: f64,
}

impl CheckReport {
    /// The document of `v`, a check of `robot` on `observations` observations.
    pub fn new(v: &Verdict, robot: &Robot, observations: usize) -> CheckReport {
        use crate::units::Quantity;
        let u = robot.units;
        let len = |x: f64| u.from_si(Quantity::Length, x);
        let ang = |x: f64| u.from_si(Quantity::Angle, x);
        let acc = &v.accuracy;
        CheckReport {
            schema_version: crate::report::SCHEMA_VERSION,
            ok: v.ok,
            measurements: observations,
            max_position_error: len(acc.max_position),
            rms_position_error: len(acc.rms_position),
            max_orientation_error: (acc.orientations > 0).then(|| ang(acc.max_orientation)),
            other: acc
                .other
                .iter()
                .map(|m| {
                    // Pixels stay pixels.
                    let of = |x: f64| if m.metric == "pixel" { x } else { len(x) };
                    CheckMetric {
                        metric: m.metric.to_string(),
                        max: of(m.max),
                        rms: of(m.rms),
                    }
                })
                .collect(),
            threshold_length: v.thresholds.length.map(len),
            threshold_angle: v.thresholds.angle.map(ang),
            threshold_pixel: v.thresholds.pixel,
        }
    }

    /// Pretty-printed JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("a report is plain data JSON can hold")
    }
}

/// The JSON Schema of [`CheckReport`], as shipped in `schemas/check.schema.json`.
pub fn check_schema() -> String {
    let schema = schemars::schema_for!(CheckReport);
    serde_json::to_string_pretty(&schema).expect("a schema is JSON") + "\n"
}
