//! The least-squares solvers of thesis chapter 3: one driver and four step rules.
//!
//! The driver ([`solve`]) owns everything the methods share: the linearisation of the problem
//! ([`LeastSquares`]) at each point, the stationarity test, the iteration log and the observer. A
//! method is a `StepRule`: given the linearisation, it proposes steps until one lowers the
//! objective `f = |r|^2`.
//!
//! **The linearisation.** The Jacobian is never held: each evaluation pushes its rows
//! `[J_i | r_i]` into the `R` factor of a QR, 512 rows at a time, so memory does not grow with
//! the number of rows and every method works on the `n x n` upper-triangular `R` (`J = Q R`)
//! and `z = Q^T r`. Tiny standard deviations (rows weighted 10^9 times the others) are thus
//! never squared into `J^T J`, where the other rows' information would drown in its rounding.
//! Forming the Gram matrix `[J | r]^T [J | r]` instead costs half the arithmetic per row; the
//! driver does that only after a QR linearisation has shown the column-scaled Jacobian to be
//! well conditioned (condition below 10^4, so the Gram matrix's below 10^8 and its rounding far
//! below any tolerance here), takes `R` as its Cholesky factor, and goes back to QR for good
//! when a Cholesky factor says the conditioning has degraded.
//!
//! **Scaling.** Column `j` of `J` is measured by its Euclidean norm `d_j` (the norm of `R`'s
//! column), so that nothing depends on the units of the parameters (thesis 4.4.2). A column
//! below 1e-12 of the largest holds only rounding noise (a parameter no observation feels, e.g.
//! the tool's attitude under position-only data): it is zeroed, and the parameter stays where
//! it is.
//!
//! **Stationarity.** At every point the driver computes the Gauss-Newton step by a
//! column-pivoted QR of the scaled `R` (truncated at rank `rcond`, as [`Method::Svd`] does) and
//! stops, *converged*, only when one of these holds:
//! - the objective is zero, or below what rounding the parameters alone makes (`(16 eps sqrt(n)
//!   |D x|)^2`, `D` the column norms);
//! - **reduction**: the relative reduction the local linear model predicts for the
//!   Gauss-Newton step, `|P_J r|^2 / |r|^2`, is at most `ftol` (no direction the data can
//!   determine lowers the objective any further);
//! - **step**: the Gauss-Newton step is at most `xtol` of the scaled parameters (the point is
//!   a fixed point of the iteration, as at a zero-residual solution);
//! - **rounding**: no step of the method lowers the objective, and the predicted reduction is
//!   below [`ROUNDING_REDUCTION`] (1e-10): what is left cannot be told from the objective's
//!   rounding.
//!
//! The scaled gradient (the largest cosine between the residual and a column of `J`, MINPACK's
//! `gnorm`) is reported with them. A method whose steps no longer lower the objective at a
//! point that passes none of these tests has *stalled* ([`Termination::Stalled`]), and the cap
//! on iterations ends a run as not converged. The rank of the scaled Jacobian at the start and
//! at the end are both reported ([`Stationarity`]); a calibration that ends with fewer directions
//! determined than it started with has lost rank ([`Termination::RankLost`], decided by
//! [`super::calibrate`]: a test problem's genuine minimum may have a singular Jacobian, as
//! Freudenstein and Roth's local one does, a robot model's does not). So a run never reports
//! convergence where the local model still promises a reduction the objective could show.
//!
//! **The methods.**
//! - `lm`: Levenberg-Marquardt as a trust region (Moré 1978, as in MINPACK's `lmder`): the step
//!   minimises `|r + J p|^2` subject to `|D p| <= Delta`, with `D` the running maximum of the
//!   column norms (Marquardt's scaling `B_ii = sqrt(H_ii)` of eq. 3.15, kept from growing
//!   back); the damping `lambda` for which the step has length `Delta` is found by Newton's
//!   method on the secular equation, each trial solved from the QR of `[R_s; sqrt(lambda) I]`
//!   by Givens rotations; `Delta` grows or shrinks with the ratio of the actual to the
//!   predicted reduction. With [`Damping::Identity`] `D = I`: plain `lambda I` in the internal
//!   units (m, rad), as in eq. 3.14.
//! - `gn`: the Gauss-Newton step (eq. 3.13), refused when the scaled `R` is rank deficient
//!   (thesis 3.3.3); step halving when a full step does not lower the objective.
//! - `sd`: `y = -t g` (eq. 3.10) with `t = |g|^2 / |J_s g|^2`, the exact minimiser along `-g`
//!   of the local model, then halved until the objective decreases.
//! - `svd`: `y = -J_s^+ r` (eq. 3.20) with singular values below `rcond * s_max` dropped; step
//!   halving as for `gn`.

use super::least_squares::LeastSquares;
use crate::error::{Error, Result};
use crate::linalg::{self, GramAccumulator, Matrix, PivotedQr, QrAccumulator, QR_BLOCK};

/// A least-squares method (in a calibration spec: `lm`, `gn`, `sd`, `svd`).
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Eq,
    Default,
    serde::Serialize,
    serde::Deserialize,
    schemars::JsonSchema,
)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[non_exhaustive]
pub enum Method {
    /// Levenberg-Marquardt (thesis 3.3.4), as a scaled trust region.
    #[default]
    #[serde(rename = "lm")]
    #[cfg_attr(feature = "clap", value(name = "lm"))]
    LevenbergMarquardt,
    /// Gauss-Newton (3.3.2); refuses singular systems.
    #[serde(rename = "gn")]
    #[cfg_attr(feature = "clap", value(name = "gn"))]
    GaussNewton,
    /// Steepest descent with a line search (3.3.1).
    #[serde(rename = "sd")]
    #[cfg_attr(feature = "clap", value(name = "sd"))]
    SteepestDescent,
    /// Truncated SVD pseudo-inverse steps (3.4).
    #[serde(rename = "svd")]
    #[cfg_attr(feature = "clap", value(name = "svd"))]
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
    pub(crate) fn default_max_iterations(self) -> usize {
        match self {
            Method::SteepestDescent => 5000,
            _ => 100,
        }
    }

    pub(crate) fn rule(self, opts: &SolverOptions) -> Box<dyn StepRule> {
        match self {
            Method::LevenbergMarquardt => {
                Box::new(LevenbergMarquardt::new(opts.damping, opts.rcond))
            }
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

/// The damping matrix of Levenberg-Marquardt (in a calibration spec: `marquardt`, `identity`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[non_exhaustive]
pub enum Damping {
    /// Marquardt's diagonal scaling `B^2`, `B_ii = sqrt(H_ii)` (eq. 3.15): the trust region is
    /// measured in the column norms (their running maximum, as MINPACK does).
    #[default]
    Marquardt,
    /// Plain `lambda I` in internal units (eq. 3.14).
    Identity,
}

/// Solver settings.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct SolverOptions {
    /// The method.
    pub method: Method,
    /// Iteration cap.
    pub max_iterations: usize,
    /// LM damping.
    pub damping: Damping,
    /// Relative threshold on the scaled Jacobian's singular values (or the pivoted QR's
    /// diagonal): `svd` drops, `gn` refuses, and the stationarity test's Gauss-Newton step
    /// leaves out, directions below `rcond` times the largest.
    pub rcond: f64,
    /// Converged when the relative reduction of the objective that the local linear model
    /// predicts for a Gauss-Newton step is at most this.
    pub ftol: f64,
    /// Converged when the Gauss-Newton step is at most this fraction of the scaled parameters.
    pub xtol: f64,
}

/// Default relative singular-value threshold ([`SolverOptions::rcond`]).
pub const DEFAULT_RCOND: f64 = 1e-9;

/// A method that finds no lower point where the local model predicts a relative reduction
/// below this has converged to the precision of the objective ([`Termination::RoundingLimited`]);
/// above it, the method has stalled.
pub const ROUNDING_REDUCTION: f64 = 1e-10;

/// A Levenberg-Marquardt trial whose predicted relative reduction is below this cannot be
/// told from the objective's rounding: the rule stops trying.
const RESOLVABLE: f64 = 1e-14;

impl SolverOptions {
    /// Defaults for `method`.
    pub fn new(method: Method) -> Self {
        SolverOptions {
            method,
            max_iterations: method.default_max_iterations(),
            damping: Damping::Marquardt,
            rcond: DEFAULT_RCOND,
            ftol: 1e-15,
            xtol: 1e-12,
        }
    }
}

/// Why a solver stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Termination {
    /// Converged: the objective is zero, or below what rounding the parameters alone makes
    /// (`(16 eps sqrt(n) |D x|)^2`).
    ZeroObjective,
    /// Converged: the local model predicts a relative reduction below `ftol` for a
    /// Gauss-Newton step.
    SmallPredictedReduction,
    /// Converged: the Gauss-Newton step is below `xtol` of the scaled parameters.
    SmallStep,
    /// Converged to the precision of the objective: no step lowers it any more, and the
    /// reduction the local model predicts is below [`ROUNDING_REDUCTION`] of it (what is left
    /// is rounding: the objective's own rounding error is of that order).
    RoundingLimited,
    /// Not converged: no step of the method lowers the objective any more, yet the point is
    /// not stationary (the local model still predicts a reduction).
    Stalled,
    /// Not converged: the iteration cap was reached first.
    MaxIterations,
    /// Not converged: a calibration's stationarity test passed, but with the scaled Jacobian's
    /// rank (at `rcond`) below the start's: the model lost a direction on the way (two joint
    /// axes lined up, a frame folded onto another), and the tests see only the directions left.
    /// Decided by [`super::calibrate`], not by [`solve`], and only while the residuals stay
    /// above the stated noise (where it explains them, no point fits better).
    RankLost,
    /// Not converged: a stationary point whose measured positions stay beyond 2 % of the
    /// robot's reach from every start tried (the given one, the closed-form placement and a
    /// short multi-start; see [`crate::workflow`]): a local minimum far above any calibration
    /// of this robot, or data that are not this robot's.
    LocalMinimum,
    /// Not solved here: a calibration given from elsewhere (a robot file or a report) was
    /// assessed on the data ([`crate::workflow::assess`]).
    Given,
}

impl Termination {
    /// Every way a solve ends.
    pub const ALL: [Termination; 9] = [
        Termination::ZeroObjective,
        Termination::SmallPredictedReduction,
        Termination::SmallStep,
        Termination::RoundingLimited,
        Termination::Stalled,
        Termination::MaxIterations,
        Termination::RankLost,
        Termination::LocalMinimum,
        Termination::Given,
    ];

    /// True when the solver stopped at a stationary point (not at the cap, not stalled, not
    /// where the Jacobian lost rank, not at a local minimum that fits no start).
    pub fn converged(self) -> bool {
        !matches!(
            self,
            Termination::MaxIterations
                | Termination::Stalled
                | Termination::RankLost
                | Termination::LocalMinimum
        )
    }

    /// A sentence for reports.
    pub fn describe(self) -> &'static str {
        match self {
            Termination::ZeroObjective => "the objective is zero to rounding",
            Termination::SmallPredictedReduction => "stationary: predicted reduction below ftol",
            Termination::SmallStep => "stationary: Gauss-Newton step below xtol",
            Termination::RoundingLimited => "stationary to rounding: no step lowers the objective",
            Termination::Stalled => {
                "stalled: no step lowers the objective, yet the model predicts a reduction"
            }
            Termination::MaxIterations => "iteration cap reached before convergence",
            Termination::RankLost => {
                "stalled: the Jacobian lost rank on the way (fewer directions determined than at \
                 the start)"
            }
            Termination::LocalMinimum => {
                "stalled at a local minimum: the positions stay unfit (beyond 2 % of the reach) \
                 from every start tried"
            }
            Termination::Given => "a given calibration, assessed (not solved here)",
        }
    }
}

/// How stationary the solver's last point is: the three measures its tests use.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[non_exhaustive]
pub struct Stationarity {
    /// The relative reduction of the objective the local linear model predicts for a
    /// Gauss-Newton step, `|P_J r|^2 / |r|^2` (0 at a stationary point; compared with
    /// `ftol`).
    pub predicted_reduction: f64,
    /// The Gauss-Newton step's length relative to the parameters, both scaled by the column
    /// norms (compared with `xtol`; infinite when every scaled parameter is 0).
    pub step: f64,
    /// The scaled gradient: the largest `|cos|` between the residual and a column of the
    /// Jacobian (MINPACK's `gnorm`).
    pub gradient: f64,
    /// The numerical rank of the scaled Jacobian (at `rcond`) the Gauss-Newton step used.
    pub rank: usize,
    /// That rank at the start (of the solve; of the whole estimation in a
    /// [`super::Calibration`]): a calibration whose rank falls below it ends as
    /// [`Termination::RankLost`].
    pub start_rank: usize,
}

/// One line of the per-iteration log.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct Iteration {
    /// 1-based iteration number.
    pub iteration: usize,
    /// Objective after the iteration.
    pub objective: f64,
    /// Norm of the accepted step in scaled units (the parameters times their column norms).
    pub step: f64,
    /// LM damping used for the accepted step (relative to the scaled problem), or the
    /// line-search factor for the others.
    pub lambda: f64,
    /// Objective evaluations spent in this iteration (rejected trials included).
    pub evaluations: usize,
}

/// What a solver returns.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct Solution {
    /// Estimated values, in the problem's order.
    pub x: Vec<f64>,
    /// Objective at the start.
    pub objective_before: f64,
    /// Objective at the end.
    pub objective_after: f64,
    /// Iterations run.
    pub iterations: usize,
    /// Why it stopped.
    pub termination: Termination,
    /// How stationary the last point is.
    pub stationarity: Stationarity,
    /// Columns (in the problem's order) that no residual felt at the start: their Jacobian
    /// column was zero, or below 1e-12 of the largest.
    pub unfelt: Vec<usize>,
    /// The linearisation at the start: the `(cols + 1) x (cols + 1)` upper-triangular `R` of
    /// `[J | r]` at `x0` (the residual last; by QR, or from the Gram matrix where that is
    /// accurate), as the first evaluation left it.
    pub(crate) start_r: Matrix,
}

/// The linearisation a step rule works on, at the current point: with `J = Q R` (the thin QR
/// of the Jacobian) and `z = Q^T r`, `|r + J p|^2 = |z + R p|^2 + (|r|^2 - |z|^2)`, so `R` and
/// `z` are all a step needs; no `m`-row matrix exists.
pub(crate) struct System<'s> {
    /// `R`, `n x n` upper triangular (unscaled; dead columns zeroed).
    pub r: &'s Matrix,
    /// `z = Q^T r`.
    pub z: &'s [f64],
    /// The objective `|r|^2`.
    pub f: f64,
    /// The current point.
    pub x: &'s [f64],
    /// The column norms of `J` (those of `R`); 1 for dead columns.
    pub norms: &'s [f64],
    /// Columns no residual feels (below 1e-12 of the largest norm).
    pub dead: &'s [bool],
    /// The Gauss-Newton step from the point (unscaled; rank-truncated at `rcond`).
    pub(crate) gauss_newton: &'s [f64],
    /// The numerical rank of the scaled `R` (at `rcond`).
    pub rank: usize,
}

impl System<'_> {
    /// `R_s = R D^-1` (columns divided by their norms, dead ones zeroed).
    fn scaled_r(&self) -> Matrix {
        let n = self.r.ncols();
        Matrix::from_fn(n, n, |i, j| {
            if self.dead[j] {
                0.0
            } else {
                self.r[(i, j)] / self.norms[j]
            }
        })
    }

    /// The scaled gradient `g = R_s^T z`.
    fn scaled_gradient(&self, rs: &Matrix) -> Vec<f64> {
        let n = rs.ncols();
        (0..n)
            .map(|j| (0..=j).map(|i| rs[(i, j)] * self.z[i]).sum())
            .collect()
    }

    /// The unscaled step of a scaled one.
    fn unscale(&self, y: &[f64]) -> Vec<f64> {
        y.iter()
            .enumerate()
            .map(|(j, v)| if self.dead[j] { 0.0 } else { v / self.norms[j] })
            .collect()
    }
}

/// A step a rule had accepted.
pub(crate) struct Step {
    /// The step in the problem's parameters.
    pub p: Vec<f64>,
    /// LM damping, or line-search factor.
    pub lambda: f64,
    /// Objective evaluations spent.
    pub evaluations: usize,
}

/// What a step rule may ask of the problem at the current point `x`.
pub(crate) trait Trials {
    /// The objective at `x + p` (infinite where it is not finite).
    fn objective(&mut self, p: &[f64]) -> f64;
}

/// What a step rule found.
pub(crate) enum Proposal {
    /// A step that lowers the objective.
    Step(Step),
    /// No step lowers the objective. `at_rounding`: the last steps tried were so short that
    /// the reduction the local model promised for them (below 1e-14 of the objective) could
    /// not be told from the objective's rounding, so the point is stationary within the region
    /// where the model was found to hold.
    Exhausted {
        /// Whether the rule gave up at the rounding of the objective.
        at_rounding: bool,
    },
}

/// A least-squares method: proposes steps `p` (the parameters move to `x + p`) and evaluates
/// them with `trials`, until one lowers the objective.
pub(crate) trait StepRule {
    /// Proposes steps until one lowers `sys.f`.
    fn step(&mut self, sys: &System<'_>, trials: &mut dyn Trials) -> Result<Proposal>;
}

/// Levenberg-Marquardt as a scaled trust region (Moré 1978).
pub struct LevenbergMarquardt {
    damping: Damping,
    rcond: f64,
    /// The trust region's radius (in scaled units); NaN before the first step.
    delta: f64,
    /// The last damping found.
    par: f64,
    /// The scaling `D` (running maximum of the column norms); empty before the first step.
    diag: Vec<f64>,
}

/// The initial trust region: the scaled parameters' length (MINPACK's `factor` = 1: its default
/// 100 lets the first step of BoxBOD, MGH09 and MGH17 from NIST's first start leap onto a
/// plateau).
const INITIAL_RADIUS: f64 = 1.0;

impl LevenbergMarquardt {
    /// With damping `damping`; Gauss-Newton steps truncated at `rcond`.
    pub fn new(damping: Damping, rcond: f64) -> Self {
        LevenbergMarquardt {
            damping,
            rcond,
            delta: f64::NAN,
            par: 0.0,
            diag: Vec::new(),
        }
    }
}

impl StepRule for LevenbergMarquardt {
    fn step(&mut self, sys: &System<'_>, trials: &mut dyn Trials) -> Result<Proposal> {
        let n = sys.r.ncols();
        let first = self.diag.is_empty();
        if first {
            self.diag = vec![1.0; n];
        }
        for j in 0..n {
            self.diag[j] = match self.damping {
                Damping::Identity => 1.0,
                Damping::Marquardt if sys.dead[j] => 1.0,
                Damping::Marquardt if first => sys.norms[j],
                Damping::Marquardt => self.diag[j].max(sys.norms[j]),
            };
        }
        let rs = Matrix::from_fn(n, n, |i, j| {
            if sys.dead[j] {
                0.0
            } else {
                sys.r[(i, j)] / self.diag[j]
            }
        });
        let qr = PivotedQr::new(&rs);
        let mut w = sys.z.to_vec();
        qr.apply_qt(&mut w);
        let t = qr.t();
        let rank = qr.rank(self.rcond);
        let xnorm = sys
            .x
            .iter()
            .zip(&self.diag)
            .map(|(x, d)| (x * d) * (x * d))
            .sum::<f64>()
            .sqrt();
        if self.delta.is_nan() {
            self.delta = if xnorm > 0.0 {
                INITIAL_RADIUS * xnorm
            } else {
                INITIAL_RADIUS
            };
        }
        let fnorm = sys.f.sqrt();
        let mut first_trial = first;
        // Each rejection at least halves the radius: 60 of them take it from any size to the
        // rounding of the parameters.
        for evaluations in 1..=60 {
            let (par, u) = trust_region_step(t, &w, rank, self.delta, self.par);
            self.par = par;
            let pnorm = norm(&u);
            if first_trial {
                self.delta = self.delta.min(pnorm);
                first_trial = false;
            }
            let mut p = vec![0.0; n];
            for (k, &uk) in u.iter().enumerate() {
                let j = qr.perm()[k];
                p[j] = if sys.dead[j] { 0.0 } else { uk / self.diag[j] };
            }
            let f1 = trials.objective(&p);
            let fnorm1 = f1.sqrt();
            let actred = if 0.1 * fnorm1 < fnorm {
                1.0 - (fnorm1 / fnorm).powi(2)
            } else {
                -1.0
            };
            // The linear model's relative reduction, `(|w|^2 - |w + T u|^2) / f = (|T u|^2 + 2
            // par |u|^2) / f` for the damped step.
            let tu = upper_times(t, &u);
            let temp1 = norm(&tu) / fnorm;
            let temp2 = par.sqrt() * pnorm / fnorm;
            let dirder = -(temp1 * temp1 + temp2 * temp2);
            let prered = temp1 * temp1 + 2.0 * temp2 * temp2;
            let ratio = if prered != 0.0 { actred / prered } else { 0.0 };
            if ratio <= 0.25 {
                let mut temp = if actred >= 0.0 {
                    0.5
                } else {
                    0.5 * dirder / (dirder + 0.5 * actred)
                };
                if 0.1 * fnorm1 >= fnorm || temp.is_nan() || temp < 0.1 {
                    temp = 0.1;
                }
                self.delta = temp * self.delta.min(pnorm / 0.1);
                self.par /= temp;
            } else if self.par == 0.0 || ratio >= 0.75 {
                self.delta = pnorm / 0.5;
                self.par *= 0.5;
            }
            if ratio >= 1e-4 && f1 < sys.f {
                return Ok(Proposal::Step(Step {
                    p,
                    lambda: par,
                    evaluations,
                }));
            }
            if prered <= RESOLVABLE {
                return Ok(Proposal::Exhausted { at_rounding: true });
            }
            if self.delta.is_nan() || self.delta <= f64::EPSILON * xnorm || pnorm == 0.0 {
                break;
            }
        }
        Ok(Proposal::Exhausted { at_rounding: false })
    }
}

/// The step `u` minimising `|T u + w|^2` subject to `|u| <= delta` (Moré's `lmpar`): the
/// Gauss-Newton step (truncated at `rank`) when it is within 1.1 `delta`, else the damped
/// step `(T^T T + par I) u = -T^T w` with `par` found by Newton's method on `1/|u(par)| -
/// 1/delta` within safeguarding bounds, to 10 % of `delta` (at most 10 solves). Returns `par`
/// (0 for the Gauss-Newton step) and `u`. `par0` is the previous call's `par`, a good start.
fn trust_region_step(t: &Matrix, w: &[f64], rank: usize, delta: f64, par0: f64) -> (f64, Vec<f64>) {
    let n = t.ncols();
    let mut u = linalg::min_norm_solve(t, w, rank);
    let mut dxnorm = norm(&u);
    let mut fp = dxnorm - delta;
    if fp <= 0.1 * delta {
        return (0.0, u);
    }
    // Lower bound: Newton's step at par = 0 when T is nonsingular.
    let mut parl = 0.0;
    if rank == n {
        let a: Vec<f64> = u.iter().map(|v| v / dxnorm).collect();
        let b = linalg::solve_upper_transposed(t, &a, n);
        let bn = norm(&b);
        parl = fp / delta / (bn * bn);
    }
    // Upper bound: |T^T w| / delta.
    let g: Vec<f64> = (0..n)
        .map(|j| (0..=j.min(t.nrows() - 1)).map(|i| t[(i, j)] * w[i]).sum())
        .collect();
    let gnorm = norm(&g);
    let mut paru = gnorm / delta;
    if paru == 0.0 {
        paru = f64::MIN_POSITIVE / delta.min(0.1);
    }
    let mut par = par0.max(parl).min(paru);
    if par == 0.0 {
        par = gnorm / dxnorm;
    }
    for iter in 0..10 {
        if par == 0.0 {
            par = f64::MIN_POSITIVE.max(0.001 * paru);
        }
        let (step, s) = damped_solve(t, w, par);
        u = step;
        dxnorm = norm(&u);
        let temp = fp;
        fp = dxnorm - delta;
        if fp.abs() <= 0.1 * delta || (parl == 0.0 && fp <= temp && temp < 0.0) || iter == 9 {
            break;
        }
        // Newton's correction on 1/|u(par)|.
        let a: Vec<f64> = u.iter().map(|v| v / dxnorm).collect();
        let b = linalg::solve_upper_transposed(&s, &a, n);
        let bn = norm(&b);
        let parc = fp / delta / (bn * bn);
        if fp > 0.0 {
            parl = parl.max(par);
        }
        if fp < 0.0 {
            paru = paru.min(par);
        }
        par = parl.max(par + parc);
    }
    (par, u)
}

/// The least-squares solution of `[T; sqrt(par) I] u = [-w; 0]` (`par > 0`), from the QR of
/// the stacked matrix by Givens rotations (the damping rows folded into `T` one at a time),
/// and that QR's triangular factor `S` (`S^T S = T^T T + par I`).
fn damped_solve(t: &Matrix, w: &[f64], par: f64) -> (Vec<f64>, Matrix) {
    let n = t.ncols();
    let mut s = Matrix::from_fn(n, n, |i, j| {
        if i <= j && i < t.nrows() {
            t[(i, j)]
        } else {
            0.0
        }
    });
    let mut b: Vec<f64> = (0..n)
        .map(|i| if i < w.len() { -w[i] } else { 0.0 })
        .collect();
    let root = par.sqrt();
    let mut row = vec![0.0; n];
    for j in 0..n {
        row.fill(0.0);
        row[j] = root;
        let mut rb = 0.0;
        for k in j..n {
            if row[k] == 0.0 {
                continue;
            }
            let (a, c) = (s[(k, k)], row[k]);
            let h = a.hypot(c);
            let (cos, sin) = (a / h, c / h);
            for l in k..n {
                let (x, y) = (s[(k, l)], row[l]);
                s[(k, l)] = cos * x + sin * y;
                row[l] = -sin * x + cos * y;
            }
            let (x, y) = (b[k], rb);
            b[k] = cos * x + sin * y;
            rb = -sin * x + cos * y;
        }
    }
    let u = linalg::solve_upper(&s, &b, n);
    (u, s)
}

/// `T u` for an upper-triangular `T`.
fn upper_times(t: &Matrix, u: &[f64]) -> Vec<f64> {
    (0..t.nrows())
        .map(|i| (i..t.ncols()).map(|j| t[(i, j)] * u[j]).sum())
        .collect()
}

fn norm(v: &[f64]) -> f64 {
    dot(v, v).sqrt()
}

/// Gauss-Newton (eq. 3.13), refusing a rank-deficient system.
pub struct GaussNewton {
    /// The relative threshold of the rank test (the same as the driver's).
    pub rcond: f64,
}

impl StepRule for GaussNewton {
    fn step(&mut self, sys: &System<'_>, trials: &mut dyn Trials) -> Result<Proposal> {
        let live = sys.dead.iter().filter(|d| !**d).count();
        if sys.rank < live {
            return Err(Error::SingularNormalEquations {
                rank: sys.rank,
                parameters: sys.r.ncols(),
                rcond: self.rcond,
            });
        }
        Ok(halving(sys.gauss_newton.to_vec(), sys.f, trials))
    }
}

/// Steepest descent with the model's exact step length, then halving (eq. 3.10).
pub struct SteepestDescent;

impl StepRule for SteepestDescent {
    fn step(&mut self, sys: &System<'_>, trials: &mut dyn Trials) -> Result<Proposal> {
        let rs = sys.scaled_r();
        let g = sys.scaled_gradient(&rs);
        // |J_s g| = |Q R_s g| = |R_s g|.
        let jg = linalg::a_v(&rs, &g);
        let denom = dot(&jg, &jg);
        let t = if denom > 0.0 {
            dot(&g, &g) / denom
        } else {
            0.0
        };
        let y: Vec<f64> = g.iter().map(|v| -t * v).collect();
        Ok(halving(sys.unscale(&y), sys.f, trials))
    }
}

/// Truncated-SVD pseudo-inverse steps (eq. 3.20).
pub(crate) struct TruncatedSvd {
    /// Singular values below `rcond * s_max` are dropped.
    pub rcond: f64,
}

impl StepRule for TruncatedSvd {
    fn step(&mut self, sys: &System<'_>, trials: &mut dyn Trials) -> Result<Proposal> {
        // J_s = (Q U) S V^T with R_s = U S V^T: u_k^T r of J_s's vectors is U's u_k^T z.
        let rs = sys.scaled_r();
        let svd = linalg::thin_svd(&rs)
            .ok_or_else(|| Error::Numerical("SVD of the Jacobian did not converge".into()))?;
        let smax = svd.s.first().copied().unwrap_or(0.0);
        let mut y = vec![0.0; rs.ncols()];
        for (k, &s) in svd.s.iter().enumerate() {
            if s > self.rcond * smax {
                let coef = -dot(svd.u.col(k), sys.z) / s;
                for (yi, vi) in y.iter_mut().zip(svd.v.col(k)) {
                    *yi += coef * vi;
                }
            }
        }
        Ok(halving(sys.unscale(&y), sys.f, trials))
    }
}

/// Tries `p`, `p/2`, `p/4`, ... (40 times) until the objective drops below `f`.
fn halving(p: Vec<f64>, f: f64, trials: &mut dyn Trials) -> Proposal {
    let exhausted = Proposal::Exhausted { at_rounding: false };
    if !(p.iter().all(|v| v.is_finite()) && p.iter().any(|&v| v != 0.0)) {
        return exhausted;
    }
    let mut t = 1.0;
    let mut ps = p.clone();
    for evaluations in 1..=40 {
        let fv = trials.objective(&ps);
        if fv < f {
            return Proposal::Step(Step {
                p: ps,
                lambda: t,
                evaluations,
            });
        }
        t *= 0.5;
        for (s, v) in ps.iter_mut().zip(&p) {
            *s = v * t;
        }
    }
    exhausted
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Minimises the problem's objective from `x0` with `opts.method`, calling `observer` after
/// every iteration.
pub fn solve(
    problem: &dyn LeastSquares,
    x0: &[f64],
    opts: &SolverOptions,
    observer: &mut dyn FnMut(&Iteration),
) -> Result<Solution> {
    drive(
        problem,
        x0,
        opts,
        opts.method.rule(opts).as_mut(),
        observer,
        None,
    )
}

/// The Jacobian's condition (of the column-scaled `R`, by the pivoted QR's diagonal) below
/// which the Gram matrix is accurate enough to stand in for the QR.
const GRAM_CONDITION: f64 = 1e4;

/// A linearisation: `R` (`n x n`), `z` and the objective, at one point.
struct Linearization {
    r: Matrix,
    z: Vec<f64>,
    f: f64,
}

impl Linearization {
    fn new(n: usize) -> Self {
        Linearization {
            r: Matrix::zeros(n, n),
            z: vec![0.0; n],
            f: f64::NAN,
        }
    }

    /// From the `R` of `[J | r]` (`(n + 1)` square).
    fn set_from_augmented(&mut self, raug: &Matrix, f: f64) {
        let n = self.z.len();
        for j in 0..n {
            for i in 0..n {
                self.r[(i, j)] = raug[(i, j)];
            }
            self.z[j] = raug[(j, n)];
        }
        self.f = f;
    }

    /// From the Gram matrix of `[J | r]`: `R` the Cholesky factor of `J^T J` (with dead columns
    /// left zero), `z = R^-T J^T r`. False when the scaled Gram matrix is not comfortably
    /// positive definite (its Cholesky pivots below `1 / GRAM_CONDITION`).
    fn set_from_gram(&mut self, gram: &Matrix, f: f64) -> bool {
        let n = self.z.len();
        let norms: Vec<f64> = (0..n).map(|j| gram[(j, j)].max(0.0).sqrt()).collect();
        let max = norms.iter().copied().fold(0.0, f64::max);
        let live: Vec<usize> = (0..n).filter(|&j| norms[j] > 1e-12 * max).collect();
        let k = live.len();
        let c = Matrix::from_fn(k, k, |a, b| {
            let (i, j) = (live[a], live[b]);
            gram[(i, j)] / (norms[i] * norms[j])
        });
        let Some(l) = linalg::cholesky(&c) else {
            return false;
        };
        if (0..k).any(|i| l[(i, i)] < 1.0 / GRAM_CONDITION) {
            return false;
        }
        // R (scaled) = L^T; unscale: R_ij = L_ji * norm_j; z = R^-T g.
        self.r = Matrix::zeros(n, n);
        self.z.fill(0.0);
        let mut rl = Matrix::zeros(k, k);
        for a in 0..k {
            for b in a..k {
                rl[(a, b)] = l[(b, a)] * norms[live[b]];
            }
        }
        let g: Vec<f64> = live.iter().map(|&j| gram[(j, n)]).collect();
        let zl = linalg::solve_upper_transposed(&rl, &g, k);
        for a in 0..k {
            for b in a..k {
                self.r[(live[a], live[b])] = rl[(a, b)];
            }
            self.z[live[a]] = zl[a];
        }
        self.f = f;
        true
    }
}

/// The `R` of `[J | r]` (`(n + 1)` square, upper triangular; `n + 1` the side of `gram`, the
/// Gram matrix of `[J | r]`, and `f = |r|^2`) as the Gram matrix gives it, when `J` is well
/// enough conditioned for that: every entry finite, the Cholesky factor of the scaled Gram
/// matrix made ([`Linearization::set_from_gram`]; dead columns zero), and its condition below
/// `GRAM_CONDITION` by the pivoted QR's diagonal, the test by which the solver starts trusting
/// the Gram matrix (`certify`). The Gram matrix squares the condition, so at 1e4 its `R` keeps
/// about 8 of the QR's 16 digits in the weakest direction. Rows `[R | z]`, then the residual the
/// linear model leaves, `sqrt(f - |z|^2)` (0 where rounding makes that negative), so that the
/// last column's squares sum to `f`. `None` otherwise: a QR is then needed.
pub(crate) fn augmented_from_gram(gram: &Matrix, f: f64) -> Option<Matrix> {
    let n = gram.nrows() - 1;
    if !f.is_finite() || !(0..=n).all(|i| (0..=n).all(|j| gram[(i, j)].is_finite())) {
        return None;
    }
    let mut lin = Linearization::new(n);
    if !lin.set_from_gram(gram, f) {
        return None;
    }
    let live: Vec<usize> = (0..n)
        .filter(|&j| linalg::col_norm(&lin.r, j) > 0.0)
        .collect();
    // The live rows and columns (a dead column's row and column are zero).
    let r = Matrix::from_fn(live.len(), live.len(), |a, b| lin.r[(live[a], live[b])]);
    if !gram_conditioned(&r) {
        return None;
    }
    let explained: f64 = lin.z.iter().map(|z| z * z).sum();
    Some(Matrix::from_fn(n + 1, n + 1, |i, j| match (i < n, j < n) {
        (true, true) => lin.r[(i, j)],
        (true, false) => lin.z[i],
        (false, false) => (f - explained).max(0.0).sqrt(),
        (false, true) => 0.0,
    }))
}

/// Whether the upper-triangular `r` (square) is conditioned well enough for the Gram matrix to
/// stand in for a QR: the pivoted QR's diagonal of its copy with columns scaled to unit norm
/// spans less than `GRAM_CONDITION`. Not with no columns or a zero one.
pub(crate) fn gram_conditioned(r: &Matrix) -> bool {
    let k = r.ncols();
    let norms: Vec<f64> = (0..k).map(|j| linalg::col_norm(r, j)).collect();
    if norms.iter().any(|&v| v.is_nan() || v <= 0.0) {
        return false;
    }
    let scaled = Matrix::from_fn(k, k, |i, j| r[(i, j)] / norms[j]);
    let diag = PivotedQr::new(&scaled).diagonal();
    match (diag.first(), diag.last()) {
        (Some(first), Some(last)) => last.abs() >= first.abs() / GRAM_CONDITION,
        _ => false,
    }
}

/// Evaluates a problem into linearisations, by QR, or by the Gram matrix once that is known to
/// be accurate.
struct Evaluator<'p> {
    problem: &'p dyn LeastSquares,
    qr: QrAccumulator,
    gram: Option<GramAccumulator>,
    use_gram: bool,
    res: Vec<f64>,
    raug: Matrix,
}

impl<'p> Evaluator<'p> {
    fn new(problem: &'p dyn LeastSquares) -> Self {
        let n = problem.cols();
        Evaluator {
            problem,
            qr: QrAccumulator::new(n + 1, QR_BLOCK),
            gram: None,
            use_gram: false,
            res: vec![0.0; problem.rows()],
            raug: Matrix::zeros(n + 1, n + 1),
        }
    }

    /// The linearisation at `x` into `out`; returns the objective (non-finite ones as they
    /// are, `out` then unusable).
    fn linearize(&mut self, x: &[f64], out: &mut Linearization) -> f64 {
        let n = self.problem.cols();
        if self.use_gram {
            let gram = self
                .gram
                .get_or_insert_with(|| GramAccumulator::new(n + 1, QR_BLOCK));
            gram.clear();
            let f = self.problem.linearize(x, &mut self.res, gram);
            if !f.is_finite() {
                return f;
            }
            gram.gram_into(&mut self.raug);
            if out.set_from_gram(&self.raug, f) {
                return f;
            }
            // The conditioning degraded: QR from here on.
            self.use_gram = false;
        }
        self.qr.clear();
        let f = self.problem.linearize(x, &mut self.res, &mut self.qr);
        if f.is_finite() {
            self.qr.r_into(&mut self.raug);
            out.set_from_augmented(&self.raug, f);
        }
        f
    }
}

/// The driver's [`Trials`]: each objective is evaluated with its linearisation (a rule accepts
/// the last point it tried nearly always, and then the next iteration needs no second pass).
struct DriverTrials<'a, 'p> {
    ev: &'a mut Evaluator<'p>,
    x: &'a [f64],
    trial_x: &'a mut Vec<f64>,
    trial_lin: &'a mut Linearization,
    /// The objective at the last trial.
    last: f64,
}

impl Trials for DriverTrials<'_, '_> {
    fn objective(&mut self, p: &[f64]) -> f64 {
        for (t, (x, p)) in self.trial_x.iter_mut().zip(self.x.iter().zip(p)) {
            *t = x + p;
        }
        let v = self.ev.linearize(self.trial_x, self.trial_lin);
        self.last = v;
        if v.is_finite() {
            v
        } else {
            f64::INFINITY
        }
    }
}

/// The stationarity measures at a linearisation, and the Gauss-Newton step.
struct Certificate {
    stationarity: Stationarity,
    gauss_newton: Vec<f64>,
    well_conditioned: bool,
}

fn certify(
    lin: &Linearization,
    x: &[f64],
    norms: &[f64],
    dead: &[bool],
    rcond: f64,
) -> Certificate {
    let n = x.len();
    let rs = Matrix::from_fn(n, n, |i, j| {
        if dead[j] {
            0.0
        } else {
            lin.r[(i, j)] / norms[j]
        }
    });
    let qr = PivotedQr::new(&rs);
    let mut w = lin.z.clone();
    qr.apply_qt(&mut w);
    let rank = qr.rank(rcond);
    let u = linalg::min_norm_solve(qr.t(), &w, rank);
    let mut y = vec![0.0; n];
    for (k, &uk) in u.iter().enumerate() {
        y[qr.perm()[k]] = uk;
    }
    let p: Vec<f64> = (0..n)
        .map(|j| if dead[j] { 0.0 } else { y[j] / norms[j] })
        .collect();
    let predicted: f64 = w[..rank].iter().map(|v| v * v).sum();
    let xs = x
        .iter()
        .zip(norms)
        .zip(dead)
        .map(|((x, d), &dd)| if dd { 0.0 } else { (x * d) * (x * d) })
        .sum::<f64>()
        .sqrt();
    let ynorm = norm(&y);
    let step = if ynorm == 0.0 {
        0.0
    } else if xs > 0.0 {
        ynorm / xs
    } else {
        f64::INFINITY
    };
    let fnorm = lin.f.sqrt();
    let gradient = if fnorm > 0.0 {
        (0..n)
            .map(|j| (0..=j).map(|i| rs[(i, j)] * lin.z[i]).sum::<f64>().abs() / fnorm)
            .fold(0.0, f64::max)
    } else {
        0.0
    };
    let live = dead.iter().filter(|d| !**d).count();
    let diag = qr.diagonal();
    let well_conditioned = rank == live && live > 0 && diag[live - 1] >= diag[0] / GRAM_CONDITION;
    Certificate {
        stationarity: Stationarity {
            predicted_reduction: if lin.f > 0.0 { predicted / lin.f } else { 0.0 },
            step,
            gradient,
            rank,
            start_rank: rank,
        },
        gauss_newton: p,
        well_conditioned,
    }
}

/// The driver: runs `rule` from `x0` (see the module documentation). `start`, when given, is
/// the `R` of `[J | r]` at `x0` (`(cols + 1)` square), as a QR pass there would make it: the
/// first evaluation is then skipped.
pub(crate) fn drive(
    problem: &dyn LeastSquares,
    x0: &[f64],
    opts: &SolverOptions,
    rule: &mut dyn StepRule,
    observer: &mut dyn FnMut(&Iteration),
    start: Option<&Matrix>,
) -> Result<Solution> {
    let n = problem.cols();
    assert_eq!(x0.len(), n, "x0 must have one value per unknown");
    let mut x = x0.to_vec();
    let mut ev = Evaluator::new(problem);
    let mut lin = Linearization::new(n);
    let start_r = linearize_start(&mut ev, &mut lin, &x, start)?;
    let objective_before = lin.f;
    let mut trial_lin = Linearization::new(n);
    let termination;
    let mut iterations = 0;
    let mut unfelt = None;
    let mut trial_x = vec![0.0; n];
    let mut norms = vec![1.0; n];
    let mut dead = vec![false; n];
    let mut stationarity;
    let mut start_rank = None;
    let mut decided = false;
    loop {
        let f = lin.f;
        scale_columns(&lin, &mut unfelt, &mut norms, &mut dead);
        let cert = certify(&lin, &x, &norms, &dead, opts.rcond);
        stationarity = cert.stationarity;
        let start_rank = *start_rank.get_or_insert(stationarity.rank);
        stationarity.start_rank = start_rank;
        if !decided {
            ev.use_gram = cert.well_conditioned;
            decided = true;
        }
        if let Some(t) = stop_at(
            problem, opts, &cert, &mut x, &mut lin.f, &norms, &dead, iterations,
        ) {
            termination = t;
            break;
        }
        iterations += 1;
        let sys = System {
            r: &lin.r,
            z: &lin.z,
            f,
            x: &x,
            norms: &norms,
            dead: &dead,
            gauss_newton: &cert.gauss_newton,
            rank: stationarity.rank,
        };
        let mut trials = DriverTrials {
            ev: &mut ev,
            x: &x,
            trial_x: &mut trial_x,
            trial_lin: &mut trial_lin,
            last: f64::NAN,
        };
        let step = match rule.step(&sys, &mut trials)? {
            Proposal::Step(step) => step,
            Proposal::Exhausted { at_rounding } => {
                termination = exhausted(at_rounding, &stationarity);
                iterations -= 1;
                break;
            }
        };
        let last_trial = trials.last;
        let step_norm = scaled_norm(&step.p, &norms);
        let x_new: Vec<f64> = x.iter().zip(&step.p).map(|(a, b)| a + b).collect();
        if x_new == trial_x && last_trial.is_finite() {
            // The accepted point is the last one evaluated: its linearisation is at hand.
            std::mem::swap(&mut lin, &mut trial_lin);
        } else if !ev.linearize(&x_new, &mut lin).is_finite() {
            return Err(Error::NonFiniteObjective {
                at: "an accepted point",
            });
        }
        x = x_new;
        observer(&Iteration {
            iteration: iterations,
            objective: lin.f,
            step: step_norm,
            lambda: step.lambda,
            evaluations: step.evaluations,
        });
    }
    Ok(Solution {
        x,
        objective_before,
        objective_after: lin.f,
        iterations,
        termination,
        stationarity,
        unfelt: unfelt.unwrap_or_default(),
        start_r,
    })
}

/// How a solve ends when its step rule finds no step that lowers the objective: converged to
/// the objective's precision when the rule says it is at rounding or the local model predicts
/// a reduction below [`ROUNDING_REDUCTION`], else stalled.
fn exhausted(at_rounding: bool, stationarity: &Stationarity) -> Termination {
    if at_rounding || stationarity.predicted_reduction <= ROUNDING_REDUCTION {
        Termination::RoundingLimited
    } else {
        Termination::Stalled
    }
}

/// `|D p|`: the step `p` in the columns' scales `norms`.
fn scaled_norm(p: &[f64], norms: &[f64]) -> f64 {
    p.iter()
        .zip(norms)
        .map(|(p, d)| (p * d) * (p * d))
        .sum::<f64>()
        .sqrt()
}

/// The linearisation at the start into `lin`: from `start` (an augmented `R` of the right
/// size: the last column holds `Q^T r`, its squares summing to the objective), else from the
/// residuals at `x`; the augmented `R` kept as the solution's `start_r`.
fn linearize_start(
    ev: &mut Evaluator<'_>,
    lin: &mut Linearization,
    x: &[f64],
    start: Option<&Matrix>,
) -> Result<Matrix> {
    let n = x.len();
    match start.filter(|r0| r0.nrows() == n + 1 && r0.ncols() == n + 1) {
        Some(r0) => {
            let f: f64 = (0..=n).map(|i| r0[(i, n)] * r0[(i, n)]).sum();
            lin.set_from_augmented(r0, f);
            Ok(r0.clone())
        }
        None => {
            let f = ev.linearize(x, lin);
            if !f.is_finite() {
                return Err(Error::NonFiniteObjective {
                    at: "the starting point",
                });
            }
            Ok(ev.raug.clone())
        }
    }
}

/// The columns' scales at this linearisation, `norms[j] = |R e_j|`, and which columns are
/// `dead` (left out of the step; their scale then 1). Columns no residual feels (rounding noise,
/// below 1e-12 of the largest) are left out. Column norms may legitimately span many orders of
/// magnitude away from the start, so after it a column is left out that way only if it was
/// unfelt at the start too (`unfelt`, set at the first call: a parameter the observations
/// cannot see), or is exactly zero.
fn scale_columns(
    lin: &Linearization,
    unfelt: &mut Option<Vec<usize>>,
    norms: &mut [f64],
    dead: &mut [bool],
) {
    let n = norms.len();
    for (j, c) in norms.iter_mut().enumerate() {
        *c = linalg::col_norm(&lin.r, j);
    }
    let max_norm = norms.iter().copied().fold(0.0, f64::max);
    let faint: Vec<bool> = norms
        .iter()
        .map(|&c| !c.is_finite() || c <= 1e-12 * max_norm)
        .collect();
    let unfelt = unfelt.get_or_insert_with(|| (0..n).filter(|&j| faint[j]).collect::<Vec<_>>());
    for j in 0..n {
        dead[j] = (faint[j] && unfelt.contains(&j)) || norms[j] == 0.0 || !norms[j].is_finite();
        if dead[j] {
            norms[j] = 1.0;
        }
    }
}

/// How the iteration ends at `x` (objective `*f`), if it does: a zero objective (to the
/// rounding the parameters alone make), a predicted reduction below `ftol`, a Gauss-Newton step
/// below `xtol` (taken first when it does not raise the objective: `x` and `*f` updated), or
/// the iteration cap.
#[allow(clippy::too_many_arguments)]
fn stop_at(
    problem: &dyn LeastSquares,
    opts: &SolverOptions,
    cert: &Certificate,
    x: &mut Vec<f64>,
    f: &mut f64,
    norms: &[f64],
    dead: &[bool],
    iterations: usize,
) -> Option<Termination> {
    let n = x.len();
    // The residual rounding the parameters alone would make: `|J dx|` for `|dx_j| <= eps
    // |x_j|`, at most `eps sqrt(n) |D x|`.
    let xs = (0..n)
        .filter(|&j| !dead[j])
        .map(|j| (x[j] * norms[j]).powi(2))
        .sum::<f64>()
        .sqrt();
    let floor = 16.0 * f64::EPSILON * (n as f64).sqrt() * xs;
    if *f == 0.0 || *f <= floor * floor {
        return Some(Termination::ZeroObjective);
    }
    if cert.stationarity.predicted_reduction <= opts.ftol {
        return Some(Termination::SmallPredictedReduction);
    }
    if cert.stationarity.step <= opts.xtol {
        // The last Gauss-Newton step is below xtol: taken when it does not raise the
        // objective (one pass of the residuals), it leaves the parameters at rounding
        // rather than at xtol (at a zero-residual solution, the step is the error).
        let polished: Vec<f64> = x
            .iter()
            .zip(&cert.gauss_newton)
            .map(|(a, b)| a + b)
            .collect();
        let mut r = vec![0.0; problem.rows()];
        let fp = problem.residuals(&polished, &mut r);
        if fp.is_finite() && fp <= *f {
            *x = polished;
            *f = fp;
        }
        return Some(Termination::SmallStep);
    }
    (iterations >= opts.max_iterations).then_some(Termination::MaxIterations)
}

// In reports a termination is its sentence ([`Termination::describe`]), read back exactly.
impl serde::Serialize for Termination {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        s.serialize_str(self.describe())
    }
}

impl<'de> serde::Deserialize<'de> for Termination {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        let text = String::deserialize(d)?;
        Termination::ALL
            .into_iter()
            .find(|t| t.describe() == text)
            .ok_or_else(|| serde::de::Error::custom(format!("unknown termination `{text}`")))
    }
}

impl schemars::JsonSchema for Termination {
    fn schema_name() -> std::borrow::Cow<'static, str> {
        "Termination".into()
    }

    fn json_schema(_: &mut schemars::SchemaGenerator) -> schemars::Schema {
        let sentences: Vec<&str> = Termination::ALL.iter().map(|t| t.describe()).collect();
        schemars::json_schema!({
            "description": "Why the solver stopped (a sentence per way).",
            "type": "string",
            "enum": sentences,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The start's `R` of `[J | r]` from the Gram matrix is the QR's (each row up to its
    /// sign), and the squares of its last column sum to `|r|^2`, where `J` is well conditioned
    /// (here its scaled condition is about 10: the Gram matrix squares it, so 1e-12 of the
    /// entries' size is a hundred times the rounding it can add); a `J` with two columns equal
    /// to 1e-9 gets none (a QR is needed), nor one whose Cholesky pivots look fine while its
    /// condition is 1e6.
    #[test]
    fn the_gram_start_is_the_qr_start_where_j_is_well_conditioned() {
        use crate::linalg::{GramAccumulator, QrAccumulator};
        let (m, n) = (40, 5);
        let rows = |near: bool| -> Vec<Vec<f64>> {
            (0..m)
                .map(|i| {
                    let mut row: Vec<f64> = (0..=n)
                        .map(|j| ((i * 7 + j * 13) as f64 * 0.37).sin() + (i % (j + 2)) as f64)
                        .collect();
                    if near {
                        row[2] = row[1] + 1e-9 * ((i * 3) as f64).cos();
                    }
                    row
                })
                .collect()
        };
        fn factors_of(n: usize, rows: &[Vec<f64>]) -> (Matrix, Matrix, f64) {
            let (mut qr, mut gram) = (QrAccumulator::new(n + 1, 8), GramAccumulator::new(n + 1, 8));
            for row in rows {
                qr.push(row);
                gram.push(row);
            }
            let (mut r, mut g) = (Matrix::zeros(0, 0), Matrix::zeros(0, 0));
            qr.r_into(&mut r);
            gram.gram_into(&mut g);
            let f: f64 = rows.iter().map(|row| row[n] * row[n]).sum();
            (r, g, f)
        }
        let factors = |rows: &[Vec<f64>]| factors_of(n, rows);
        let (r, g, f) = factors(&rows(false));
        let r0 = augmented_from_gram(&g, f).expect("well conditioned");
        let scale = (0..=n).map(|i| r[(i, i)].abs()).fold(0.0, f64::max);
        for i in 0..=n {
            // Rows are determined up to their sign: compare with the diagonal's made positive.
            let (s, s0) = (r[(i, i)].signum(), r0[(i, i)].signum());
            for j in 0..=n {
                let (a, b) = (s * r[(i, j)], s0 * r0[(i, j)]);
                assert!((a - b).abs() <= 1e-12 * scale, "({i}, {j}): {a} vs {b}");
            }
        }
        let (_, g, f) = factors(&rows(true));
        assert!(augmented_from_gram(&g, f).is_none());
        // Cholesky pivots can all stay above 1 / GRAM_CONDITION while the condition is far
        // above it: J unit upper triangular with -1 above the diagonal (20 columns, scaled:
        // pivots at least 0.22, condition 1.3e6; a pivoted QR's diagonal falls to 3.3e-6 of
        // its first entry, numpy's QR with pivoting). The pivoted QR refuses it.
        let k = 20;
        let (_, g, f) = factors_of(
            k,
            &(0..k)
                .map(|i| {
                    let mut row: Vec<f64> = (0..k)
                        .map(|j| match j.cmp(&i) {
                            std::cmp::Ordering::Less => 0.0,
                            std::cmp::Ordering::Equal => 1.0,
                            std::cmp::Ordering::Greater => -1.0,
                        })
                        .collect();
                    row.push(1.0);
                    row
                })
                .collect::<Vec<_>>(),
        );
        let mut lin = Linearization::new(k);
        assert!(lin.set_from_gram(&g, f), "the pivots alone would take it");
        assert!(augmented_from_gram(&g, f).is_none());
    }

    /// The damped solve against the normal equations `(T^T T + par I) u = -T^T w`.
    #[test]
    fn damped_solve_solves_the_damped_normal_equations() {
        let n = 5;
        let t = Matrix::from_fn(n, n, |i, j| {
            if i <= j {
                1.0 + ((i * 7 + j * 3) as f64 * 0.31).sin()
            } else {
                0.0
            }
        });
        let w: Vec<f64> = (0..n).map(|i| (i as f64 * 1.3).cos()).collect();
        for par in [1e-6, 0.3, 7.0] {
            let (u, s) = damped_solve(&t, &w, par);
            for i in 0..n {
                let mut lhs = par * u[i];
                let mut rhs = 0.0;
                for k in 0..n {
                    let tki = t[(k, i)];
                    rhs -= tki * w[k];
                    let tu: f64 = (0..n).map(|j| t[(k, j)] * u[j]).sum();
                    lhs += tki * tu;
                }
                assert!((lhs - rhs).abs() < 1e-12, "par {par}: {lhs} vs {rhs}");
                // S^T S = T^T T + par I.
                for j in 0..n {
                    let sts: f64 = (0..n).map(|k| s[(k, i)] * s[(k, j)]).sum();
                    let ttt: f64 = (0..n).map(|k| t[(k, i)] * t[(k, j)]).sum();
                    let want = ttt + if i == j { par } else { 0.0 };
                    assert!((sts - want).abs() < 1e-12);
                }
            }
        }
    }

    /// The trust-region step: the Gauss-Newton step inside the region; on its boundary (to
    /// 10 %) otherwise, with a damping that makes it the damped step.
    #[test]
    fn trust_region_step_lands_on_the_boundary() {
        let n = 4;
        let t = Matrix::from_fn(n, n, |i, j| {
            if i <= j {
                (1 + i + j) as f64 * if i == j { 2.0 } else { 0.3 }
            } else {
                0.0
            }
        });
        let w = vec![1.0, -2.0, 0.5, 3.0];
        let (par, gn) = trust_region_step(&t, &w, n, 1e6, 0.0);
        assert!(par.abs() == 0.0, "{par}");
        let gn_norm = norm(&gn);
        for delta in [0.5 * gn_norm, 0.1 * gn_norm, 1e-3 * gn_norm] {
            let (par, u) = trust_region_step(&t, &w, n, delta, 0.0);
            assert!(par > 0.0);
            assert!(
                (norm(&u) - delta).abs() <= 0.1 * delta,
                "{} vs {delta}",
                norm(&u)
            );
            let (v, _) = damped_solve(&t, &w, par);
            for (a, b) in u.iter().zip(&v) {
                assert!((a - b).abs() < 1e-12);
            }
        }
    }
}
