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
    /// Which of several equally good answers to return.
    pub solution: SolutionRule,
    /// The loss applied to the weighted residuals.
    pub loss: Loss,
}

/// The loss applied to each weighted residual `r` (in standard deviations).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Loss {
    /// Least squares, `r^2` (the thesis's objective).
    #[default]
    Squared,
    /// Huber: `r^2` for `|r| <= k`, linear beyond, so that a few bad rows cannot dominate.
    /// Solved by iteratively reweighted least squares. `k` is in standard deviations (of
    /// `--weights`); 1.345 keeps 95 % efficiency on clean Gaussian data.
    Huber(f64),
}

/// Which answer a calibration returns when the data leaves some parameters undetermined.
#[derive(Debug, Clone, PartialEq, Default)]
pub enum SolutionRule {
    /// Wherever the solver stops: in the undetermined directions this depends on the starting
    /// point and the solver's path (thesis Table 4.8).
    #[default]
    Solver,
    /// Among the equally good answers, the one closest to this reference robot (the nominal
    /// model) in the metric `sum ((p - p_ref) / tolerance)^2`, tolerances from the reference's
    /// [`Tolerances`](crate::robot::Tolerances). It does not depend on the starting point.
    MinChange(Box<Robot>),
}

impl CalibrationOptions {
    /// Levenberg-Marquardt with default settings, estimating `estimate`.
    pub fn new(estimate: Vec<ParamId>) -> Self {
        CalibrationOptions {
            estimate,
            solver: SolverOptions::new(Method::LevenbergMarquardt),
            weights: Weights::default(),
            orientation: OrientationError::Euler,
            solution: SolutionRule::Solver,
            loss: Loss::Squared,
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
    let mut sol = solve(&problem, &x0, &opts.solver, &mut |it: &Iteration| {
        log.push(*it);
        observer(it);
    })?;
    // Huber loss: iteratively reweighted least squares, weights min(1, k/|r|) per residual.
    let mut row_scale = vec![1.0; problem.rows()];
    if let Loss::Huber(k) = opts.loss {
        if !(k > 0.0 && k.is_finite()) {
            return Err(Error::Problem(format!(
                "the Huber scale must be positive, got {k}"
            )));
        }
        let mut r = vec![0.0; problem.rows()];
        for _ in 0..50 {
            problem.evaluate(&problem.robot_at(&sol.x), &mut r, None);
            let new: Vec<f64> = r.iter().map(|&ri| (k / ri.abs()).min(1.0).sqrt()).collect();
            let change = new
                .iter()
                .zip(&row_scale)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            row_scale = new;
            if change < 1e-9 {
                break;
            }
            let weighted = problem.clone().with_row_scale(&row_scale);
            let before = sol.objective_before;
            sol = solve(&weighted, &sol.x, &opts.solver, &mut |it: &Iteration| {
                log.push(*it);
                observer(it);
            })?;
            sol.objective_before = before;
        }
    }
    // From here on, the problem as the loss weighted it.
    let problem = problem.clone().with_row_scale(&row_scale);
    let (mut x, mut iterations, mut termination) = (sol.x, sol.iterations, sol.termination);
    if let SolutionRule::MinChange(reference) = &opts.solution {
        for _round in 0..10 {
            let (projected, size) = project_min_change(&problem, &x, reference, data, opts)?;
            let again = solve(&problem, &projected, &opts.solver, &mut |it| {
                log.push(*it);
                observer(it);
            })?;
            x = again.x;
            iterations += again.iterations;
            termination = again.termination;
            if size < 1e-9 {
                break;
            }
        }
    }
    let mut calibrated = problem.robot_at(&x);
    for &id in &opts.estimate {
        let q = initial.param_quantity(id);
        if q == Quantity::Angle {
            let v0 = initial.get(id);
            calibrated.set(id, v0 + wrap_angle(calibrated.get(id) - v0));
        }
    }
    let objective_after = problem.evaluate(&calibrated, &mut vec![0.0; problem.rows()], None);
    Ok(Calibration {
        accuracy_before: accuracy(initial, data),
        accuracy_after: accuracy(&calibrated, data),
        initial: initial.clone(),
        calibrated,
        estimated: opts.estimate.clone(),
        options: opts.clone(),
        termination,
        iterations,
        objective_before: sol.objective_before,
        objective_after,
        warnings,
        log,
    })
}

/// Moves `x` along the undetermined directions to the point closest to `reference` in the
/// tolerance-scaled metric. Returns the new point and the size of the move in tolerance units.
///
/// The undetermined directions are the null space of the Jacobian at the reference (nominal)
/// model, where the design's exact redundancies hold; noise in the data would otherwise turn
/// them into barely determined directions at `x`.
fn project_min_change(
    problem: &Problem<'_>,
    x: &[f64],
    reference: &Robot,
    data: &Dataset,
    opts: &CalibrationOptions,
) -> Result<(Vec<f64>, f64)> {
    let mut robot = problem.robot_at(x);
    for &id in problem.estimated() {
        robot.set(id, reference.get(id));
    }
    let aopts = crate::identifiability::AnalysisOptions {
        weights: opts.weights,
        orientation: opts.orientation,
        ..Default::default()
    };
    let a = crate::identifiability::analyze(&robot, data, problem.estimated(), &aopts)?;
    let n = x.len();
    // analyze sorts its parameters; map them back to the problem's order.
    let pos: Vec<usize> = problem
        .estimated()
        .iter()
        .map(|id| {
            a.parameters
                .iter()
                .position(|p| p == id)
                .expect("same parameters")
        })
        .collect();
    let null: Vec<Vec<f64>> = (a.rank..n)
        .map(|k| {
            pos.iter()
                .map(|&j| {
                    let v = a.right_singular_vectors[(j, k)];
                    if a.column_norms[j] > 0.0 {
                        v / a.column_norms[j]
                    } else {
                        v
                    }
                })
                .collect()
        })
        .collect();
    if null.is_empty() {
        return Ok((x.to_vec(), 0.0));
    }
    let ids = problem.estimated();
    let w: Vec<f64> = ids
        .iter()
        .map(|&id| 1.0 / reference.tolerance(id).powi(2))
        .collect();
    let dx: Vec<f64> = ids
        .iter()
        .zip(x)
        .map(|(&id, &v)| {
            let d = v - reference.get(id);
            if reference.param_quantity(id) == Quantity::Angle {
                wrap_angle(d)
            } else {
                d
            }
        })
        .collect();
    let k = null.len();
    let ata = crate::linalg::Matrix::from_fn(k, k, |a, b| {
        (0..n).map(|j| null[a][j] * w[j] * null[b][j]).sum()
    });
    let atb: Vec<f64> = (0..k)
        .map(|a| (0..n).map(|j| null[a][j] * w[j] * dx[j]).sum())
        .collect();
    let z = crate::linalg::solve_spd(&ata, &atb)
        .ok_or_else(|| Error::Numerical("minimum-change projection is singular".into()))?;
    let mut out = x.to_vec();
    let mut size = 0.0;
    for j in 0..n {
        let step: f64 = (0..k).map(|a| null[a][j] * z[a]).sum();
        out[j] -= step;
        size += step * step * w[j];
    }
    Ok((out, size.sqrt()))
}

/// Calibrates, then removes, one at a time, the determined parameter whose change is least
/// significant while it is below `k` standard deviations, refitting after each removal (pruning
/// everything below `k` at once makes held-out accuracy worse when parameters are correlated).
/// Returns the full fit, the pruned fit and the removed parameters in removal order.
pub fn calibrate_pruned(
    initial: &Robot,
    data: &Dataset,
    opts: &CalibrationOptions,
    k: f64,
) -> Result<(Calibration, Calibration, Vec<ParamId>)> {
    let full = calibrate(initial, data, opts, &mut |_| {})?;
    let mut current = full.clone();
    let mut removed = Vec::new();
    loop {
        let u = crate::uncertainty::uncertainty(&current, data)?;
        let weakest = u
            .parameters
            .iter()
            .filter_map(|p| p.significance.map(|s| (p.id, s)))
            .filter(|&(_, s)| s < k)
            .min_by(|a, b| a.1.total_cmp(&b.1));
        let Some((id, _)) = weakest else { break };
        let mut o = current.options.clone();
        o.estimate.retain(|&p| p != id);
        if o.estimate.is_empty() {
            break;
        }
        removed.push(id);
        current = calibrate(initial, data, &o, &mut |_| {})?;
    }
    Ok((full, current, removed))
}

/// A measurement that the calibrated model misses by much more than the others.
#[derive(Debug, Clone, PartialEq)]
pub struct Outlier {
    /// Index into the dataset's measurements.
    pub measurement: usize,
    /// Its largest weighted residual component, in robust standard deviations.
    pub sigmas: f64,
    /// Its position error (m).
    pub position_error: f64,
    /// Its attitude error (rad), for a full pose.
    pub orientation_error: Option<f64>,
}

/// Measurements with a residual component beyond `k` robust standard deviations of all the
/// residuals (1.4826 x their median absolute value, which a few bad rows cannot inflate). They
/// are listed for the user to look at, never dropped silently.
pub fn outliers(cal: &Calibration, data: &Dataset, k: f64) -> Vec<Outlier> {
    let problem = Problem::new(
        &cal.calibrated,
        data,
        &cal.estimated,
        cal.options.weights,
        cal.options.orientation,
    );
    let mut r = vec![0.0; problem.rows()];
    problem.evaluate(&cal.calibrated, &mut r, None);
    let mut abs: Vec<f64> = r.iter().map(|v| v.abs()).collect();
    abs.sort_by(f64::total_cmp);
    let median = if abs.is_empty() {
        0.0
    } else {
        abs[abs.len() / 2]
    };
    // Floor: 1e-6 of the stated standard deviation, so noise-free data never flags rounding.
    let sigma = (1.4826 * median).max(1e-6);
    let chain = crate::kinematics::Chain::new(&cal.calibrated);
    let mut out = Vec::new();
    let mut row = 0;
    for (i, m) in data.measurements.iter().enumerate() {
        let n = m.rows();
        let worst = r[row..row + n].iter().fold(0.0f64, |a, v| a.max(v.abs())) / sigma;
        if worst > k {
            let f = chain.frame_at(&data.postures[m.posture].readings, m.target);
            out.push(Outlier {
                measurement: i,
                sigmas: worst,
                position_error: (f.translation - m.position).norm(),
                orientation_error: m.orientation.map(|e| {
                    let rm = crate::kinematics::rot_zyx(e.x, e.y, e.z);
                    crate::kinematics::log_so3(&(rm.transpose() * f.rotation)).norm()
                }),
            });
        }
        row += n;
    }
    out
}
