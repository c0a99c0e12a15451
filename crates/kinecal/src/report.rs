//! The machine-readable calibration report (JSON), in the robot file's units.

use serde::Serialize;

use crate::estimation::{Calibration, OrientationError};
use crate::units::Quantity;

/// One parameter's line in the report.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct ParameterReport {
    /// `p1`, `p2`, ...
    pub id: String,
    /// `link1.x`, `joint3.offset`, ...
    pub name: String,
    /// The unit of `initial`, `estimated` and `change`.
    pub unit: String,
    /// Value before calibration.
    pub initial: f64,
    /// Value after calibration (equal to `initial` when not estimated).
    pub estimated: f64,
    /// `estimated - initial`.
    pub change: f64,
    /// Whether the parameter was estimated.
    pub estimated_flag: bool,
}

/// The calibration report written by `kinecal calibrate --report`.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct CalibrationReport {
    /// Robot name.
    pub robot: String,
    /// Length unit of every length below.
    pub length_unit: String,
    /// Angle unit of every angle below.
    pub angle_unit: String,
    /// `lm`, `gn`, `sd` or `svd`.
    pub method: String,
    /// `euler` or `rotvec`.
    pub orientation_error: String,
    /// False only when the iteration cap stopped the solver.
    pub converged: bool,
    /// Why the solver stopped.
    pub termination: String,
    /// Iterations run.
    pub iterations: usize,
    /// Postures in the data.
    pub postures: usize,
    /// Measurements (rows) in the data.
    pub measurements: usize,
    /// Residuals (3 per position, 6 per pose).
    pub residuals: usize,
    /// Standard deviation weighting position residuals (length unit).
    pub weight_length: f64,
    /// Standard deviation weighting orientation residuals (angle unit).
    pub weight_angle: f64,
    /// Weighted sum of squared residuals before (dimensionless).
    pub objective_before: f64,
    /// Weighted sum of squared residuals after.
    pub objective_after: f64,
    /// RMS 3D position error before (length unit).
    pub rms_position_before: f64,
    /// RMS 3D position error after.
    pub rms_position_after: f64,
    /// Largest position error before.
    pub max_position_before: f64,
    /// Largest position error after.
    pub max_position_after: f64,
    /// RMS attitude error (angle of `R_measured^T R_model`) before (angle unit).
    pub rms_orientation_before: f64,
    /// RMS attitude error after.
    pub rms_orientation_after: f64,
    /// Largest attitude error before.
    pub max_orientation_before: f64,
    /// Largest attitude error after.
    pub max_orientation_after: f64,
    /// Every parameter of the model, in thesis order.
    pub parameters: Vec<ParameterReport>,
    /// Warnings.
    pub warnings: Vec<String>,
}

impl CalibrationReport {
    /// Builds the report of `cal` on a dataset of the given size.
    pub fn new(cal: &Calibration, postures: usize, measurements: usize, residuals: usize) -> Self {
        let robot = &cal.calibrated;
        let u = robot.units;
        let len = |v: f64| u.from_si(Quantity::Length, v);
        let ang = |v: f64| u.from_si(Quantity::Angle, v);
        let parameters = robot
            .param_ids()
            .map(|id| {
                let initial = cal.initial.get_user(id);
                let estimated = robot.get_user(id);
                ParameterReport {
                    id: id.to_string(),
                    name: robot.param_name(id),
                    unit: robot.param_unit(id),
                    initial,
                    estimated,
                    change: estimated - initial,
                    estimated_flag: cal.estimated.binary_search(&id).is_ok(),
                }
            })
            .collect();
        let (b, a) = (&cal.accuracy_before, &cal.accuracy_after);
        CalibrationReport {
            robot: robot.name.clone(),
            length_unit: u.length.to_string(),
            angle_unit: u.angle.to_string(),
            method: cal.options.solver.method.as_str().to_string(),
            orientation_error: match cal.options.orientation {
                OrientationError::Euler => "euler",
                OrientationError::RotVec => "rotvec",
            }
            .to_string(),
            converged: cal.converged(),
            termination: cal.termination.describe().to_string(),
            iterations: cal.iterations,
            postures,
            measurements,
            residuals,
            weight_length: len(cal.options.weights.length),
            weight_angle: ang(cal.options.weights.angle),
            objective_before: cal.objective_before,
            objective_after: cal.objective_after,
            rms_position_before: len(b.rms_position),
            rms_position_after: len(a.rms_position),
            max_position_before: len(b.max_position),
            max_position_after: len(a.max_position),
            rms_orientation_before: ang(b.rms_orientation),
            rms_orientation_after: ang(a.rms_orientation),
            max_orientation_before: ang(b.max_orientation),
            max_orientation_after: ang(a.max_orientation),
            parameters,
            warnings: cal.warnings.clone(),
        }
    }

    /// Pretty-printed JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("report serializes")
    }
}
