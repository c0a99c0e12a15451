//! A robot already calibrated: [`assess`] builds the outcome of a calibration that exists (a
//! calibrated robot file against its nominal), [`check`] tells whether a robot in service still
//! meets its accuracy on check observations (thresholds in metres and radians).

use std::sync::Arc;

use crate::error::{Error, Result};
use crate::estimation::{self, Calibration, CalibrationOptions};
use crate::observe::{accuracy, Accuracy, Dataset, OrientationError, Weights};
use crate::outliers;
use crate::params::ParamId;
use crate::problem::Problem;
use crate::robot::Robot;
use crate::source::Source;
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
    sources: &[Source],
) -> Result<Outcome> {
    if !nominal.same_structure(calibrated) {
        return Err(Error::Problem(
            "the calibrated robot does not have the nominal robot's structure (joints, couplings, \
             sites, planes)"
                .into(),
        ));
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
    let (objective_before, accuracy_before) = problem.evaluate_checked(nominal, &mut residuals);
    let (objective_after, accuracy_after) = problem.evaluate_checked(&calibrated, &mut residuals);
    let cal = Calibration {
        objective_before,
        objective_after,
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
        log: Vec::new(),
        residuals,
        start_r: None,
    };
    let mut warnings = data_warnings(nominal, data, &crate::sanity::predicted(nominal, data));
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
pub struct Thresholds {
    /// Largest acceptable length error (m): position errors, and the errors of other length
    /// metrics (distances, contacts).
    pub length: f64,
    /// Largest acceptable attitude error (rad), when attitudes are checked.
    pub angle: Option<f64>,
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
    if !ok_threshold(thresholds.length) || !thresholds.angle.is_none_or(ok_threshold) {
        return Err(Error::InvalidOption {
            setting: crate::error::Setting::CheckThreshold,
            message: "thresholds must be positive finite numbers".into(),
        });
    }
    let acc = accuracy(robot, data);
    let mut ok = acc.max_position <= thresholds.length
        && acc.other.iter().all(|m| m.max <= thresholds.length);
    if let Some(t) = thresholds.angle {
        ok &= acc.orientations == 0 || acc.max_orientation <= t;
    }
    Ok(Verdict {
        ok,
        accuracy: acc,
        thresholds,
    })
}
