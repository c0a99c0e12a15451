//! Estimation: from a nominal robot and measurements to calibrated parameters.
//!
//! ```
//! use kinecal::{examples, estimation::{calibrate, CalibrationOptions}, simulate};
//! let nominal = examples::ge_a4();
//! let mut truth = nominal.clone();
//! let p1 = kinecal::ParamId(0);
//! truth.set(p1, truth.get(p1) + 0.01); // link1.x grows 1 cm
//! let postures = simulate::sample_postures(&nominal, 20, 7);
//! let data = simulate::measure(&truth, &postures, false);
//! let opts = CalibrationOptions::new(vec![p1]);
//! let cal = calibrate(&nominal, &data, &opts, &mut |_| {}).unwrap();
//! assert!((cal.calibrated.get(p1) - truth.get(p1)).abs() < 1e-9);
//! ```

mod problem;
mod solver;

pub use problem::{accuracy, Accuracy, OrientationError, Problem, Weights};
pub use solver::{
    solve, Damping, Iteration, Method, Solution, SolverOptions, Termination, DEFAULT_RCOND,
};

use crate::error::{Error, Result};
use crate::measurement::Dataset;
use crate::params::ParamId;
use crate::robot::Robot;
use crate::units::{wrap_angle, Quantity};

/// Everything that decides a calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationOptions {
    /// The parameters to estimate (sorted, distinct); the others keep their values.
    pub estimate: Vec<ParamId>,
    /// Method and stopping rules.
    pub solver: SolverOptions,
    /// Residual weights.
    pub weights: Weights,
    /// Orientation residual.
    pub orientation: OrientationError,
}

impl CalibrationOptions {
    /// Levenberg-Marquardt with default settings, estimating `estimate`.
    pub fn new(estimate: Vec<ParamId>) -> Self {
        CalibrationOptions {
            estimate,
            solver: SolverOptions::new(Method::LevenbergMarquardt),
            weights: Weights::default(),
            orientation: OrientationError::Euler,
        }
    }
}

/// The outcome of a calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct Calibration {
    /// The robot the solver started from.
    pub initial: Robot,
    /// The calibrated robot.
    pub calibrated: Robot,
    /// The estimated parameters.
    pub estimated: Vec<ParamId>,
    /// The settings used.
    pub options: CalibrationOptions,
    /// Why the solver stopped.
    pub termination: Termination,
    /// Iterations run.
    pub iterations: usize,
    /// Weighted sum of squared residuals before.
    pub objective_before: f64,
    /// Weighted sum of squared residuals after.
    pub objective_after: f64,
    /// Unweighted errors before.
    pub accuracy_before: Accuracy,
    /// Unweighted errors after.
    pub accuracy_after: Accuracy,
    /// Things the user should know (gimbal lock, parameters no measurement can see).
    pub warnings: Vec<String>,
    /// Per-iteration log.
    pub log: Vec<Iteration>,
}

impl Calibration {
    /// True unless the iteration cap stopped the solver.
    pub fn converged(&self) -> bool {
        self.termination.converged()
    }
}

/// Warnings about a dataset measured with `orientation` residuals.
pub fn data_warnings(data: &Dataset, orientation: OrientationError) -> Vec<String> {
    let mut w = Vec::new();
    let near = data.near_gimbal_lock(1f64.to_radians());
    if orientation == OrientationError::Euler && !near.is_empty() {
        let lines: Vec<String> = near.iter().take(5).map(|m| m.line.to_string()).collect();
        w.push(format!(
            "{} measured pose(s) have beta within 1 deg of +-90 deg (gimbal lock; lines {}{}), \
             where ZYX Euler differences are ill-defined: use --orientation-error rotvec",
            near.len(),
            lines.join(", "),
            if near.len() > 5 { ", ..." } else { "" }
        ));
    }
    w
}

/// Calibrates `initial` on `data`: estimates `opts.estimate`, keeps the other parameters.
///
/// Angular results are reported within +-180 deg of their initial values (angles are periodic).
pub fn calibrate(
    initial: &Robot,
    data: &Dataset,
    opts: &CalibrationOptions,
    observer: &mut dyn FnMut(&Iteration),
) -> Result<Calibration> {
    if opts.estimate.is_empty() {
        return Err(Error::Problem("no parameters to estimate".into()));
    }
    if let Some(bad) = opts
        .estimate
        .iter()
        .find(|id| id.0 >= initial.param_count())
    {
        return Err(Error::Problem(format!(
            "parameter {bad} does not exist in this robot"
        )));
    }
    let problem = Problem::new(
        initial,
        data,
        &opts.estimate,
        opts.weights,
        opts.orientation,
    );
    if problem.rows() < problem.cols() {
        return Err(Error::Problem(format!(
            "{} residuals ({} measurements) cannot determine {} parameters: measure more \
             postures or estimate fewer parameters",
            problem.rows(),
            data.measurements.len(),
            problem.cols()
        )));
    }
    let mut warnings = data_warnings(data, opts.orientation);
    let unseen: Vec<String> = opts
        .estimate
        .iter()
        .filter(|&&id| match initial.param_kind(id) {
            crate::params::ParamKind::Site { site, .. } => !data
                .measurements
                .iter()
                .any(|m| m.target == crate::kinematics::Target::Site(site)),
            _ => false,
        })
        .map(|&id| initial.param_name(id))
        .collect();
    if !unseen.is_empty() {
        warnings.push(format!(
            "no measurement sees {}: these parameters stay at their initial values",
            unseen.join(", ")
        ));
    }
    let x0 = problem.values(initial);
    let mut log = Vec::new();
    let sol = solve(&problem, &x0, &opts.solver, &mut |it| {
        log.push(*it);
        observer(it);
    })?;
    let mut calibrated = problem.robot_at(&sol.x);
    for &id in &opts.estimate {
        let q = initial.param_quantity(id);
        if q == Quantity::Angle {
            let v0 = initial.get(id);
            calibrated.set(id, v0 + wrap_angle(calibrated.get(id) - v0));
        }
    }
    Ok(Calibration {
        accuracy_before: accuracy(initial, data),
        accuracy_after: accuracy(&calibrated, data),
        initial: initial.clone(),
        calibrated,
        estimated: opts.estimate.clone(),
        options: opts.clone(),
        termination: sol.termination,
        iterations: sol.iterations,
        objective_before: sol.objective_before,
        objective_after: sol.objective_after,
        warnings,
        log,
    })
}
