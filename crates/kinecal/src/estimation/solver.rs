//! The least-squares solvers of thesis chapter 3: one driver and four step rules.
//!
//! The driver ([`solve`]) owns everything the methods share: evaluating the problem, the scaled
//! space, termination, the iteration log and the observer. Every method works on `J_s = W J
//! D^-1`: residuals weighted by their standard deviations `W` (see
//! [`Problem`](crate::problem)), and columns divided by their Euclidean norms `D`
//! (recomputed every iteration). `J_s^T J_s` then has a unit diagonal: this is exactly
//! Marquardt's scaling `B_ii = sqrt(H_ii)` of eq. 3.15, and it makes every method independent of
//! the units parameters are expressed in (thesis 4.4.2: the conditioning that units spoil). A
//! column below 1e-12 of the largest holds only rounding noise (a parameter no observation feels,
//! e.g. the tool's attitude under position-only data): it is zeroed, not scaled up, so the
//! parameter stays where it is.
//!
//! The Jacobian itself is never held: each evaluation pushes its rows `[W J | W r]` into the `R`
//! factor of a QR, 512 rows at a time, and the methods work on that `(n+1) x (n+1)`
//! factor ([`Scaled`]), so memory does not grow with the number of postures and no m x n
//! matrix is copied, multiplied or decomposed per iteration. The column norms `D` are those of
//! `R`'s columns.
//!
//! A method is a [`StepRule`]: given the scaled system, it proposes steps until one lowers the
//! objective.
//! - `lm`: `(C + lambda I) y = -g` with `C = J_s^T J_s`, `g = J_s^T r`; lambda divided by 10 after
//!   a successful step, multiplied by 10 after a failed one (eqs. 3.14-3.15). With
//!   [`Damping::Identity`] no column scaling is applied, so the damping is plain `lambda I` in
//!   the internal units (m, rad), as in eq. 3.14.
//! - `gn`: `C y = -g` (eq. 3.13), refused when `C` is singular (thesis 3.3.3); step halving
//!   when a full step does not reduce the objective.
//! - `sd`: `y = -t g` (eq. 3.10) with `t = |g|^2 / |J_s g|^2`, the exact minimiser along `-g` of
//!   the local quadratic model, then halved until the objective decreases.
//! - `svd`: `y = -J_s^+ r` (eq. 3.20) with singular values below `rcond * s_max` dropped; step
//!   halving as for `gn`.
//!
//! Stopping: an accepted step that lowers the objective by less than `ftol` relative, a scaled
//! step below `xtol`, a zero objective, no step that lowers the objective, or the iteration cap.
//! When Gauss-Newton, steepest descent or SVD stop short of the cap (no step of theirs lowers
//! the objective, or the last one lowered it by less than `ftol`, or was below `xtol`), the
//! driver tries one Levenberg-Marquardt step from the same point: if that lowers the objective
//! by more than 1e-6 of it (and the objective is not already at the rounding floor, 1e-16 of
//! its start), the method stalled ([`Termination::Stalled`], not converged): it stopped where
//! the objective still goes down.

use crate::error::{Error, Result};
use crate::linalg::{self, GramAccumulator, Matrix, QrAccumulator, QR_BLOCK};
use crate::observe::Accuracy;
use crate::problem::Problem;
use crate::robot::Robot;

/// A least-squares method.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Method {
    /// Levenberg-Marquardt (thesis 3.3.4).
    #[default]
    LevenbergMarquardt,
    /// Gauss-Newton (3.3.2).
    GaussNewton,
    /// Steepest descent with a line search (3.3.1).
    SteepestDescent,
    /// Truncated SVD pseudo-inverse steps (3.4).
    Svd,
}

impl Method {
    /// Short name used on the command line and in reports.
    pub fn as_str(self) -> &'static str {
        match self {
            Method::LevenbergMarquardt => "lm",
            Method::GaussNewton => "gn",
            Method::SteepestDescent => "sd",
            Method::Svd => "svd",
        }
    }

    /// A sensible iteration cap: steepest descent needs many more iterations.
    pub fn default_max_iterations(self) -> usize {
        match self {
            Method::SteepestDescent => 5000,
            _ => 100,
        }
    }

    pub(crate) fn rule(self, opts: &SolverOptions) -> Box<dyn StepRule> {
        match self {
            Method::LevenbergMarquardt => Box::new(LevenbergMarquardt::new(opts.damping)),
            Method::GaussNewton => Box::new(GaussNewton { rcond: opts.rcond }),
            Method::SteepestDescent => Box::new(SteepestDescent),
            Method::Svd => Box::new(TruncatedSvd { rcond: opts.rcond }),
        }
    }
}

impl std::str::FromStr for Method {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "lm" => Ok(Method::LevenbergMarquardt),
            "gn" => Ok(Method::GaussNewton),
            "sd" => Ok(Method::SteepestDescent),
            "svd" => Ok(Method::Svd),
            _ => Err(format!("unknown method `{s}` (expected lm, gn, sd or svd)")),
        }
    }
}

/// The damping matrix of Levenberg-Marquardt.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Damping {
    /// Marquardt's diagonal scaling `B^2`, `B_ii = sqrt(H_ii)` (eq. 3.15).
    #[default]
    Marquardt,
    /// Plain `lambda I` in internal units (eq. 3.14).
    Identity,
}

/// Solver settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolverOptions {
    /// The method.
    pub method: Method,
    /// Iteration cap.
    pub max_iterations: usize,
    /// LM damping.
    pub damping: Damping,
    /// Relative singular-value threshold: `svd` drops, and `gn` refuses, singular values of the
    /// scaled Jacobian below `rcond * s_max`.
    pub rcond: f64,
    /// Stop when an accepted step reduces the objective by less than this fraction.
    pub ftol: f64,
    /// Stop when the scaled step is below `xtol * (|scaled parameters| + xtol)`.
    pub xtol: f64,
}

/// Default relative singular-value threshold ([`SolverOptions::rcond`]).
pub const DEFAULT_RCOND: f64 = 1e-9;

impl SolverOptions {
    /// Defaults for `method`.
    pub fn new(method: Method) -> Self {
        SolverOptions {
            method,
            max_iterations: method.default_max_iterations(),
            damping: Damping::Marquardt,
            rcond: DEFAULT_RCOND,
            ftol: 1e-12,
            xtol: 1e-12,
        }
    }
}

/// Why a solver stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Termination {
    /// The objective reached exactly zero.
    ZeroObjective,
    /// An accepted step reduced the objective by less than `ftol` relative.
    SmallReduction,
    /// The step fell below `xtol`.
    SmallStep,
    /// No step along the method's direction reduces the objective, nor does a
    /// Levenberg-Marquardt step: a minimum to numerical precision.
    NoFurtherReduction,
    /// The method's steps no longer reduce the objective, but a Levenberg-Marquardt step from
    /// the same point does: not a minimum.
    Stalled,
    /// The iteration cap was reached first.
    MaxIterations,
    /// Not solved here: a calibration given from elsewhere (a robot file or a report) was
    /// assessed on the data ([`crate::workflow::assess`]).
    Given,
}

impl Termination {
    /// True when the solver stopped at a minimum (not at the cap, not stalled).
    pub fn converged(self) -> bool {
        !matches!(self, Termination::MaxIterations | Termination::Stalled)
    }

    /// A sentence for reports.
    pub fn describe(self) -> &'static str {
        match self {
            Termination::ZeroObjective => "objective is exactly zero",
            Termination::SmallReduction => "relative reduction of the objective below ftol",
            Termination::SmallStep => "parameter step below xtol",
            Termination::NoFurtherReduction => "no step reduces the objective any further",
            Termination::Stalled => {
                "stalled: the method's steps no longer reduce the objective, a Levenberg-Marquardt step does"
            }
            Termination::MaxIterations => "iteration cap reached before convergence",
            Termination::Given => "a given calibration, assessed (not solved here)",
        }
    }
}

/// One line of the per-iteration log.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Iteration {
    /// 1-based iteration number.
    pub iteration: usize,
    /// Objective after the iteration.
    pub objective: f64,
    /// Norm of the accepted step in scaled units.
    pub step: f64,
    /// LM damping used for the accepted step, or the line-search factor for the others.
    pub lambda: f64,
    /// Objective evaluations spent in this iteration (rejected trials included).
    pub evaluations: usize,
}

/// What a solver returns.
#[derive(Debug, Clone, PartialEq)]
pub struct Solution {
    /// Estimated values (internal units), in the problem's parameter order.
    pub x: Vec<f64>,
    /// Objective at the start.
    pub objective_before: f64,
    /// Objective at the end.
    pub objective_after: f64,
    /// Iterations run.
    pub iterations: usize,
    /// Why it stopped.
    pub termination: Termination,
    /// Columns (in the problem's parameter order) that no residual felt at the start: their
    /// Jacobian column was zero, or below 1e-12 of the largest.
    pub unfelt: Vec<usize>,
    /// The linearisation at the start: the `(cols + 1) x (cols + 1)` upper-triangular `R` of the
    /// QR of the weighted `[J | r]` at `x0` (columns in the problem's parameter order, the
    /// residual last), as the first evaluation left it.
    pub start_r: Matrix,
    /// The errors at `x0`, from the same first evaluation.
    pub start_accuracy: Accuracy,
}

/// The scaled system a step rule works on, at the current point, in the `R` form that needs no
/// m-row matrix: with `W J = Q R` (thin QR of the weighted Jacobian) and `z = Q^T r`, the
/// scaled Jacobian `J_s = W J D^-1` is `Q R_s` with `R_s = R D^-1`, so `J_s^T J_s = R_s^T R_s`,
/// `J_s^T r = R_s^T z`, and `J_s`'s singular values and right vectors are `R_s`'s.
///
/// A rule that only forms `J_s^T J_s` (see [`StepRule::needs_r`]) gets it computed from the
/// Gram matrix of `[J | r]` after the first iteration, and `rs` and `z` empty.
pub struct Scaled<'s> {
    /// `R_s = R D^-1`, n x n upper triangular (dead columns zeroed); empty (0 x 0) for a rule
    /// that does not need it.
    pub rs: &'s Matrix,
    /// `z = Q^T r`, the residuals' component in the Jacobian's column space; empty for a rule
    /// that does not need `rs`.
    pub z: &'s [f64],
    /// `C = J_s^T J_s` (`= R_s^T R_s`), n x n symmetric.
    pub c: &'s Matrix,
    /// The gradient `g = J_s^T r = R_s^T z`.
    pub g: &'s [f64],
    /// The objective.
    pub f: f64,
}

/// A step a rule had accepted: the scaled step, the objective it reached, the damping (LM) or
/// line-search factor (others), and the evaluations spent.
pub struct Step {
    /// Scaled step.
    pub y: Vec<f64>,
    /// Objective after the step.
    pub f: f64,
    /// LM damping, or line-search factor.
    pub lambda: f64,
    /// Objective evaluations spent.
    pub evaluations: usize,
}

/// A least-squares method: proposes scaled steps `y` (the parameters move by `D^-1 y`) and
/// evaluates them with `trial`, which returns the objective there (infinite when not finite),
/// until one lowers the objective. `None` when none does.
pub trait StepRule {
    /// Whether the driver divides columns by their norms (plain LM damping does not).
    fn scales_columns(&self) -> bool {
        true
    }
    /// Whether the rule works on `R_s` and `z` ([`Scaled`]); a rule that forms only
    /// `J_s^T J_s` and `g` says no, and the driver then accumulates the Gram matrix of the
    /// Jacobian instead of a QR (half the arithmetic per residual row).
    fn needs_r(&self) -> bool {
        true
    }
    /// Proposes steps until one lowers `sys.f`.
    fn step(
        &mut self,
        sys: &Scaled<'_>,
        trial: &mut dyn FnMut(&[f64]) -> f64,
    ) -> Result<Option<Step>>;
}

/// Levenberg-Marquardt (eqs. 3.14-3.15).
pub struct LevenbergMarquardt {
    damping: Damping,
    lambda: f64,
}

impl LevenbergMarquardt {
    /// With damping `damping`, lambda chosen at the first step.
    pub fn new(damping: Damping) -> Self {
        LevenbergMarquardt {
            damping,
            lambda: f64::NAN,
        }
    }
}

impl StepRule for LevenbergMarquardt {
    fn scales_columns(&self) -> bool {
        self.damping == Damping::Marquardt
    }

    fn needs_r(&self) -> bool {
        false
    }

    fn step(
        &mut self,
        sys: &Scaled<'_>,
        trial: &mut dyn FnMut(&[f64]) -> f64,
    ) -> Result<Option<Step>> {
        let c = sys.c;
        let n = c.ncols();
        let max_diag = (0..n).map(|i| c[(i, i)]).fold(0.0, f64::max);
        if self.lambda.is_nan() {
            self.lambda = 1e-3 * if max_diag > 0.0 { max_diag } else { 1.0 };
        }
        let cap = 1e12 * max_diag.max(1.0);
        let rhs: Vec<f64> = sys.g.iter().map(|v| -v).collect();
        let mut evaluations = 0;
        let mut a = c.clone();
        while self.lambda <= cap {
            for i in 0..n {
                a[(i, i)] = c[(i, i)] + self.lambda;
            }
            if let Some(y) = linalg::solve_spd(&a, &rhs) {
                evaluations += 1;
                let f = trial(&y);
                if f < sys.f {
                    let used = self.lambda;
                    self.lambda = (self.lambda / 10.0).max(1e-15);
                    return Ok(Some(Step {
                        y,
                        f,
                        lambda: used,
                        evaluations,
                    }));
                }
            }
            self.lambda *= 10.0;
        }
        Ok(None)
    }
}

/// Gauss-Newton (eq. 3.13), refusing a singular system.
pub struct GaussNewton {
    /// Relative singular-value threshold for the rank test.
    pub rcond: f64,
}

impl StepRule for GaussNewton {
    fn step(
        &mut self,
        sys: &Scaled<'_>,
        trial: &mut dyn FnMut(&[f64]) -> f64,
    ) -> Result<Option<Step>> {
        let n = sys.rs.ncols();
        let s = linalg::singular_values(sys.rs)
            .ok_or_else(|| Error::Numerical("SVD of the Jacobian did not converge".into()))?;
        let smax = s.first().copied().unwrap_or(0.0);
        let rank = s.iter().filter(|&&v| v > self.rcond * smax).count();
        let singular = Error::SingularNormalEquations {
            rank,
            parameters: n,
            rcond: self.rcond,
        };
        if rank < n {
            return Err(singular);
        }
        let rhs: Vec<f64> = sys.g.iter().map(|v| -v).collect();
        let y = linalg::solve_spd(sys.c, &rhs).ok_or(singular)?;
        Ok(halving(y, sys.f, trial))
    }
}

/// Steepest descent with the model's exact step length, then halving (eq. 3.10).
pub struct SteepestDescent;

impl StepRule for SteepestDescent {
    fn step(
        &mut self,
        sys: &Scaled<'_>,
        trial: &mut dyn FnMut(&[f64]) -> f64,
    ) -> Result<Option<Step>> {
        // |J_s g| = |Q R_s g| = |R_s g|.
        let jg = linalg::a_v(sys.rs, sys.g);
        let denom = dot(&jg, &jg);
        let t = if denom > 0.0 {
            dot(sys.g, sys.g) / denom
        } else {
            0.0
        };
        let y = sys.g.iter().map(|v| -t * v).collect();
        Ok(halving(y, sys.f, trial))
    }
}

/// Truncated-SVD pseudo-inverse steps (eq. 3.20).
pub struct TruncatedSvd {
    /// Singular values below `rcond * s_max` are dropped.
    pub rcond: f64,
}

impl StepRule for TruncatedSvd {
    fn step(
        &mut self,
        sys: &Scaled<'_>,
        trial: &mut dyn FnMut(&[f64]) -> f64,
    ) -> Result<Option<Step>> {
        // J_s = (Q U) S V^T with R_s = U S V^T: u_k^T r of J_s's vectors is U's u_k^T z.
        let svd = linalg::thin_svd(sys.rs)
            .ok_or_else(|| Error::Numerical("SVD of the Jacobian did not converge".into()))?;
        let smax = svd.s.first().copied().unwrap_or(0.0);
        let mut y = vec![0.0; sys.rs.ncols()];
        for (k, &s) in svd.s.iter().enumerate() {
            if s > self.rcond * smax {
                let coef = -dot(svd.u.col(k), sys.z) / s;
                for (yi, vi) in y.iter_mut().zip(svd.v.col(k)) {
                    *yi += coef * vi;
                }
            }
        }
        Ok(halving(y, sys.f, trial))
    }
}

/// Tries `y`, `y/2`, `y/4`, ... (40 times) until the objective drops below `f`.
fn halving(y: Vec<f64>, f: f64, trial: &mut dyn FnMut(&[f64]) -> f64) -> Option<Step> {
    if !(y.iter().all(|v| v.is_finite()) && y.iter().any(|&v| v != 0.0)) {
        return None;
    }
    let mut t = 1.0;
    let mut ys = y.clone();
    for evaluations in 1..=40 {
        let fv = trial(&ys);
        if fv < f {
            return Some(Step {
                y: ys,
                f: fv,
                lambda: t,
                evaluations,
            });
        }
        t *= 0.5;
        for (s, v) in ys.iter_mut().zip(&y) {
            *s = v * t;
        }
    }
    None
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Minimises the problem's objective from `x0` with `opts.method`, calling `observer` after
/// every iteration.
pub fn solve(
    problem: &Problem<'_>,
    x0: &[f64],
    opts: &SolverOptions,
    observer: &mut dyn FnMut(&Iteration),
) -> Result<Solution> {
    drive(problem, x0, opts, opts.method.rule(opts).as_mut(), observer)
}

/// What an evaluation kept of the weighted `[J | r]`: the `R` of its QR, or its Gram matrix.
struct Linearization {
    cols: usize,
    /// Made on first use: a step rule that forms only `J^T J` needs one QR (the start) and
    /// Gram matrices after, so most of these are never made.
    qr_acc: Option<QrAccumulator>,
    gram_acc: Option<GramAccumulator>,
    /// Which of the two the last evaluation filled.
    by_qr: bool,
}

impl Linearization {
    fn new(cols: usize) -> Self {
        Linearization {
            cols,
            qr_acc: None,
            gram_acc: None,
            by_qr: true,
        }
    }

    /// The QR accumulator.
    fn qr(&mut self) -> &mut QrAccumulator {
        let cols = self.cols;
        self.qr_acc
            .get_or_insert_with(|| QrAccumulator::new(cols, QR_BLOCK))
    }

    /// The Gram accumulator.
    fn gram(&mut self) -> &mut GramAccumulator {
        let cols = self.cols;
        self.gram_acc
            .get_or_insert_with(|| GramAccumulator::new(cols, QR_BLOCK))
    }

    /// Evaluates `problem` at `robot` into `res` and the QR (`by_qr`) or the Gram matrix.
    fn evaluate(
        &mut self,
        problem: &Problem<'_>,
        robot: &Robot,
        res: &mut [f64],
        by_qr: bool,
    ) -> f64 {
        self.by_qr = by_qr;
        if by_qr {
            problem.evaluate_qr(robot, res, self.qr())
        } else {
            problem.evaluate_gram(robot, res, self.gram())
        }
    }
}

/// The driver: runs `rule` from `x0` (see the module documentation).
pub fn drive(
    problem: &Problem<'_>,
    x0: &[f64],
    opts: &SolverOptions,
    rule: &mut dyn StepRule,
    observer: &mut dyn FnMut(&Iteration),
) -> Result<Solution> {
    drive_from(problem, x0, opts, rule, observer, None)
}

/// [`drive`], with the linearisation at `x0` at hand when `start` gives it: the `R` of the
/// weighted `[J | r]` there (`(cols + 1)` square, in the problem's column order) and the
/// errors there, as a pass at `x0` would make them. The first evaluation is then skipped.
pub(crate) fn drive_from(
    problem: &Problem<'_>,
    x0: &[f64],
    opts: &SolverOptions,
    rule: &mut dyn StepRule,
    observer: &mut dyn FnMut(&Iteration),
    start: Option<(&Matrix, &Accuracy)>,
) -> Result<Solution> {
    let (m, n) = (problem.rows(), problem.cols());
    let mut x = x0.to_vec();
    let mut r = vec![0.0; m];
    // The Jacobian is never held: its rows (with the residual) go into the R of a QR, or the
    // Gram matrix, a block of rows at a time, so memory is flat in the number of postures.
    // The start is always by QR (its R is the linearisation the uncertainty reuses).
    let mut lin = Linearization::new(n + 1);
    lin.by_qr = true;
    let given = start.filter(|(r0, _)| r0.nrows() == n + 1 && r0.ncols() == n + 1);
    let (mut f, start_accuracy) = match given {
        Some((r0, accuracy)) => {
            // Its rows are their own R: pushed into the accumulator, the iterations read it
            // back as from a pass. The last column is [Q^T r; rho]: its squared norm is the
            // objective.
            lin.qr().clear();
            let mut row = vec![0.0; n + 1];
            for i in 0..=n {
                for (j, v) in row.iter_mut().enumerate() {
                    *v = r0[(i, j)];
                }
                lin.qr().push(&row);
            }
            let f: f64 = (0..=n).map(|i| r0[(i, n)] * r0[(i, n)]).sum();
            (f, accuracy.clone())
        }
        None => problem.evaluate_qr_checked(&problem.robot_at(&x), &mut r, lin.qr()),
    };
    if !f.is_finite() {
        problem.evaluate(&problem.robot_at(&x), &mut r, None);
        return Err(non_finite_start(problem, &r));
    }
    let objective_before = f;
    let mut start_r = Matrix::zeros(0, 0);
    lin.qr().r_into(&mut start_r);
    let by_qr = rule.needs_r();
    let mut trial_r = vec![0.0; m];
    // The linearisation at the last trial point, computed with its residuals: a step rule
    // accepts the last point it tried (nearly always), and then the next iteration needs no
    // second pass of forward kinematics there.
    let mut trial_lin = Linearization::new(n + 1);
    let mut termination = Termination::MaxIterations;
    let mut iterations = 0;
    let mut unfelt = None;
    let mut trial_x = vec![0.0; n];
    let mut raug = Matrix::zeros(n + 1, n + 1);
    let mut rs = Matrix::zeros(n, n);
    let mut c = Matrix::zeros(n, n);
    let mut z = vec![0.0; n];
    let mut g = vec![0.0; n];
    let mut norms = vec![0.0; n];
    let mut d = vec![1.0; n];
    let mut dead = vec![false; n];
    while iterations < opts.max_iterations {
        if f == 0.0 {
            termination = Termination::ZeroObjective;
            break;
        }
        iterations += 1;
        if lin.by_qr {
            lin.qr().r_into(&mut raug);
            // Column norms of J are those of R (Q has orthonormal columns).
            for (j, c) in norms.iter_mut().enumerate() {
                *c = linalg::col_norm(&raug, j);
            }
        } else {
            // `raug` holds the Gram matrix of [J | r].
            lin.gram().gram_into(&mut raug);
            for (j, c) in norms.iter_mut().enumerate() {
                *c = raug[(j, j)].max(0.0).sqrt();
            }
        }
        let max_norm = norms.iter().copied().fold(0.0, f64::max);
        for j in 0..n {
            dead[j] = norms[j].is_nan() || norms[j] <= 1e-12 * max_norm;
            d[j] = if dead[j] || !rule.scales_columns() {
                1.0
            } else {
                norms[j]
            };
        }
        if unfelt.is_none() {
            unfelt = Some((0..n).filter(|&j| dead[j]).collect::<Vec<_>>());
        }
        let inv = |j: usize| if dead[j] { 0.0 } else { 1.0 / d[j] };
        if lin.by_qr {
            rs.resize(n, n);
            z.resize(n, 0.0);
            for j in 0..n {
                let s = inv(j);
                for i in 0..n {
                    rs[(i, j)] = raug[(i, j)] * s;
                }
                z[j] = raug[(j, n)];
            }
            for j in 0..n {
                g[j] = (0..=j).map(|i| rs[(i, j)] * z[i]).sum();
            }
            c = linalg::gram(&rs);
        } else {
            // J_s^T J_s = D^-1 (J^T J) D^-1 and g = D^-1 J^T r, from the Gram matrix.
            rs.resize(0, 0);
            z.clear();
            c.resize(n, n);
            for j in 0..n {
                for i in 0..n {
                    c[(i, j)] = raug[(i, j)] * inv(i) * inv(j);
                }
                g[j] = raug[(j, n)] * inv(j);
            }
        }
        let sys = Scaled {
            rs: &rs,
            z: &z,
            c: &c,
            g: &g,
            f,
        };
        let xnorm = x
            .iter()
            .zip(&d)
            .map(|(x, d)| (x * d) * (x * d))
            .sum::<f64>()
            .sqrt();
        let final_step = opts.xtol * (xnorm + opts.xtol);
        let mut last_trial = f64::NAN;
        let mut last_with_jacobian = false;
        let mut trial = |y: &[f64]| {
            for j in 0..n {
                trial_x[j] = x[j] + y[j] / d[j];
            }
            let robot = problem.robot_at(&trial_x);
            // A step this small ends the run whether it is taken or not (below xtol, or no
            // further reduction): the Jacobian there would never be used.
            last_with_jacobian = dot(y, y).sqrt() > final_step;
            let v = if last_with_jacobian {
                trial_lin.evaluate(problem, &robot, &mut trial_r, by_qr)
            } else {
                problem.evaluate(&robot, &mut trial_r, None)
            };
            last_trial = v;
            if v.is_finite() {
                v
            } else {
                f64::INFINITY
            }
        };
        let accepted = rule.step(&sys, &mut trial)?;
        let Some(step) = accepted else {
            termination = Termination::NoFurtherReduction;
            iterations -= 1;
            break;
        };
        let reduction = f - step.f;
        let f_old = f;
        let step_norm = dot(&step.y, &step.y).sqrt();
        for j in 0..n {
            x[j] += step.y[j] / d[j];
        }
        // Whether `acc` is still the R at the previous point (the accepted one was evaluated
        // without its Jacobian).
        let mut stale = false;
        if x == trial_x && last_trial.is_finite() {
            // The accepted point is the last one evaluated: its residuals (and Jacobian, unless
            // the step was final) are at hand (the same arithmetic, so the same numbers).
            std::mem::swap(&mut r, &mut trial_r);
            if last_with_jacobian {
                std::mem::swap(&mut lin, &mut trial_lin);
            } else {
                stale = true;
            }
            f = last_trial;
        } else {
            f = lin.evaluate(problem, &problem.robot_at(&x), &mut r, by_qr);
        }
        observer(&Iteration {
            iteration: iterations,
            objective: f,
            step: step_norm,
            lambda: step.lambda,
            evaluations: step.evaluations,
        });
        if f == 0.0 {
            termination = Termination::ZeroObjective;
            break;
        }
        if reduction <= opts.ftol * f_old {
            termination = Termination::SmallReduction;
            break;
        }
        if step_norm <= final_step {
            termination = Termination::SmallStep;
            break;
        }
        if stale {
            f = lin.evaluate(problem, &problem.robot_at(&x), &mut r, by_qr);
        }
    }
    // A method other than Levenberg-Marquardt that stopped short of the cap has converged only
    // if Levenberg-Marquardt cannot go down from the same point either.
    if opts.method != Method::LevenbergMarquardt
        && matches!(
            termination,
            Termination::NoFurtherReduction | Termination::SmallReduction | Termination::SmallStep
        )
        && f > 1e-16 * objective_before
        && lm_descends(problem, &x, f, opts)?
    {
        termination = Termination::Stalled;
    }
    Ok(Solution {
        x,
        objective_before,
        objective_after: f,
        iterations,
        termination,
        unfelt: unfelt.unwrap_or_default(),
        start_r,
        start_accuracy,
    })
}

/// Whether one Levenberg-Marquardt step from `x` (objective `f`) lowers the objective by more
/// than 1e-6 of it.
fn lm_descends(problem: &Problem<'_>, x: &[f64], f: f64, opts: &SolverOptions) -> Result<bool> {
    let mut lm = LevenbergMarquardt::new(Damping::Marquardt);
    let probe = SolverOptions {
        method: Method::LevenbergMarquardt,
        max_iterations: 1,
        ..*opts
    };
    let s = drive(problem, x, &probe, &mut lm, &mut |_| {})?;
    Ok(f - s.objective_after > 1e-6 * f)
}

/// The error for a start where the objective is not finite, naming the first observation with a
/// non-finite residual.
fn non_finite_start(problem: &Problem<'_>, r: &[f64]) -> Error {
    let mut row = 0;
    for o in &problem.data().observations {
        let n = o.rows().len();
        if let Some(k) = (0..n).find(|&k| !r[row + k].is_finite()) {
            return Error::NonFiniteResidual {
                line: o.line(),
                kind: o.kind(),
                row: o.rows()[k].label,
            };
        }
        row += n;
    }
    Error::Numerical("the objective is not finite at the starting point".into())
}
