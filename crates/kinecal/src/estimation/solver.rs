//! The least-squares solvers of thesis chapter 3, run in a scaled parameter space.
//!
//! Every method works on `J_s = W J D^-1`: residuals weighted by the measurement standard
//! deviations `W` (see [`Weights`](super::Weights)), and columns divided by their Euclidean norms
//! `D` (recomputed every iteration). `J_s^T J_s` then has a unit diagonal: this is exactly
//! Marquardt's scaling `B_ii = sqrt(H_ii)` of eq. 3.15, and it makes every method independent of
//! the units parameters are expressed in (thesis 4.4.2: the conditioning that units spoil).
//!
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

use crate::error::{Error, Result};
use crate::linalg::{self, Matrix};

use super::problem::Problem;

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
    /// No step along the method's direction reduces the objective: a minimum to numerical
    /// precision.
    NoFurtherReduction,
    /// The iteration cap was reached first.
    MaxIterations,
}

impl Termination {
    /// True for every reason but the iteration cap.
    pub fn converged(self) -> bool {
        self != Termination::MaxIterations
    }

    /// A sentence for reports.
    pub fn describe(self) -> &'static str {
        match self {
            Termination::ZeroObjective => "objective is exactly zero",
            Termination::SmallReduction => "relative reduction of the objective below ftol",
            Termination::SmallStep => "parameter step below xtol",
            Termination::NoFurtherReduction => "no step reduces the objective any further",
            Termination::MaxIterations => "iteration cap reached before convergence",
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
}

/// An accepted trial: new parameters, scaled step, objective, damping and step factor.
struct Accepted {
    x: Vec<f64>,
    y: Vec<f64>,
    f: f64,
    lambda: f64,
    t: f64,
}

struct State {
    x: Vec<f64>,
    r: Vec<f64>,
    jac: Matrix,
    f: f64,
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Minimises the problem's objective from `x0`, calling `observer` after every iteration.
pub fn solve(
    problem: &Problem<'_>,
    x0: &[f64],
    opts: &SolverOptions,
    observer: &mut dyn FnMut(&Iteration),
) -> Result<Solution> {
    let (m, n) = (problem.rows(), problem.cols());
    let mut st = State {
        x: x0.to_vec(),
        r: vec![0.0; m],
        jac: linalg::zeros(m, n),
        f: 0.0,
    };
    st.f = problem.evaluate(&problem.robot_at(&st.x), &mut st.r, Some(&mut st.jac));
    if !st.f.is_finite() {
        return Err(Error::Numerical(
            "the objective is not finite at the starting point".into(),
        ));
    }
    let objective_before = st.f;
    let mut trial_r = vec![0.0; m];
    let mut lambda = f64::NAN;
    let mut termination = Termination::MaxIterations;
    let mut iterations = 0;

    // Tries x + y/d; returns the trial objective (residuals left in trial_r).
    let try_step = |st: &State, y: &[f64], d: &[f64], t: f64, trial_r: &mut Vec<f64>| {
        let x: Vec<f64> =
            st.x.iter()
                .zip(y)
                .zip(d)
                .map(|((x, y), d)| x + t * y / d)
                .collect();
        let f = problem.evaluate(&problem.robot_at(&x), trial_r, None);
        (x, if f.is_finite() { f } else { f64::INFINITY })
    };

    while iterations < opts.max_iterations {
        if st.f == 0.0 {
            termination = Termination::ZeroObjective;
            break;
        }
        iterations += 1;
        // Column scaling D (Marquardt's B) and the scaled Jacobian.
        // A column below 1e-12 of the largest holds only rounding noise (a parameter no
        // measurement feels, e.g. the tool's attitude under position-only data): it is zeroed,
        // not scaled up, so the parameter stays where it is.
        let norms: Vec<f64> = (0..n).map(|j| linalg::col_norm(&st.jac, j)).collect();
        let max_norm = norms.iter().copied().fold(0.0, f64::max);
        let dead: Vec<bool> = norms
            .iter()
            .map(|&c| c.is_nan() || c <= 1e-12 * max_norm)
            .collect();
        let d: Vec<f64> = (0..n)
            .map(|j| match opts.damping {
                _ if dead[j] => 1.0,
                Damping::Identity if opts.method == Method::LevenbergMarquardt => 1.0,
                _ => norms[j],
            })
            .collect();
        let mut js = st.jac.clone();
        for (j, &dj) in d.iter().enumerate() {
            linalg::scale_col(&mut js, j, if dead[j] { 0.0 } else { 1.0 / dj });
        }
        let g = linalg::at_v(&js, &st.r);
        let mut evaluations = 0;
        let accepted: Option<Accepted> = match opts.method {
            Method::LevenbergMarquardt => {
                let c = linalg::gram(&js);
                if lambda.is_nan() {
                    let max_diag = (0..n).map(|i| c[(i, i)]).fold(0.0, f64::max);
                    lambda = 1e-3 * if max_diag > 0.0 { max_diag } else { 1.0 };
                }
                let lambda_cap = 1e12 * (0..n).map(|i| c[(i, i)]).fold(1.0, f64::max);
                let rhs: Vec<f64> = g.iter().map(|v| -v).collect();
                let mut result = None;
                while lambda <= lambda_cap {
                    let mut a = c.clone();
                    for i in 0..n {
                        a[(i, i)] += lambda;
                    }
                    if let Some(y) = linalg::solve_spd(&a, &rhs) {
                        evaluations += 1;
                        let (x, f) = try_step(&st, &y, &d, 1.0, &mut trial_r);
                        if f < st.f {
                            result = Some(Accepted {
                                x,
                                y,
                                f,
                                lambda,
                                t: 1.0,
                            });
                            lambda = (lambda / 10.0).max(1e-15);
                            break;
                        }
                    }
                    lambda *= 10.0;
                }
                result
            }
            Method::GaussNewton | Method::Svd | Method::SteepestDescent => {
                let y: Vec<f64> = match opts.method {
                    Method::GaussNewton => {
                        let s = linalg::singular_values(&js).ok_or_else(|| {
                            Error::Numerical("SVD of the Jacobian did not converge".into())
                        })?;
                        let smax = s.first().copied().unwrap_or(0.0);
                        let rank = s.iter().filter(|&&v| v > opts.rcond * smax).count();
                        if rank < n {
                            return Err(Error::SingularNormalEquations {
                                rank,
                                parameters: n,
                                rcond: opts.rcond,
                            });
                        }
                        let c = linalg::gram(&js);
                        let rhs: Vec<f64> = g.iter().map(|v| -v).collect();
                        linalg::solve_spd(&c, &rhs).ok_or(Error::SingularNormalEquations {
                            rank,
                            parameters: n,
                            rcond: opts.rcond,
                        })?
                    }
                    Method::Svd => {
                        let svd = linalg::thin_svd(&js).ok_or_else(|| {
                            Error::Numerical("SVD of the Jacobian did not converge".into())
                        })?;
                        let smax = svd.s.first().copied().unwrap_or(0.0);
                        let mut y = vec![0.0; n];
                        for (k, &s) in svd.s.iter().enumerate() {
                            if s > opts.rcond * smax {
                                let coef = -svd
                                    .u
                                    .col(k)
                                    .iter()
                                    .zip(&st.r)
                                    .map(|(u, r)| u * r)
                                    .sum::<f64>()
                                    / s;
                                for (yi, vi) in y.iter_mut().zip(svd.v.col(k).iter()) {
                                    *yi += coef * vi;
                                }
                            }
                        }
                        y
                    }
                    _ => {
                        let jg = linalg::a_v(&js, &g);
                        let denom = dot(&jg, &jg);
                        let t = if denom > 0.0 {
                            dot(&g, &g) / denom
                        } else {
                            0.0
                        };
                        g.iter().map(|v| -t * v).collect()
                    }
                };
                let mut t = 1.0;
                let mut result = None;
                if y.iter().all(|v| v.is_finite()) && y.iter().any(|&v| v != 0.0) {
                    for _ in 0..40 {
                        evaluations += 1;
                        let (x, f) = try_step(&st, &y, &d, t, &mut trial_r);
                        if f < st.f {
                            let ys = y.iter().map(|v| v * t).collect();
                            result = Some(Accepted {
                                x,
                                y: ys,
                                f,
                                lambda: f64::NAN,
                                t,
                            });
                            break;
                        }
                        t *= 0.5;
                    }
                }
                result
            }
        };
        let Some(Accepted {
            x,
            y,
            f: f_new,
            lambda: lam,
            t,
        }) = accepted
        else {
            termination = Termination::NoFurtherReduction;
            iterations -= 1;
            break;
        };
        let reduction = st.f - f_new;
        let f_old = st.f;
        let step = dot(&y, &y).sqrt();
        let xnorm =
            st.x.iter()
                .zip(&d)
                .map(|(x, d)| (x * d) * (x * d))
                .sum::<f64>()
                .sqrt();
        st.x = x;
        std::mem::swap(&mut st.r, &mut trial_r);
        st.f = problem.evaluate(&problem.robot_at(&st.x), &mut st.r, Some(&mut st.jac));
        observer(&Iteration {
            iteration: iterations,
            objective: st.f,
            step,
            lambda: if lam.is_nan() { t } else { lam },
            evaluations,
        });
        if st.f == 0.0 {
            termination = Termination::ZeroObjective;
            break;
        }
        if reduction <= opts.ftol * f_old {
            termination = Termination::SmallReduction;
            break;
        }
        if step <= opts.xtol * (xnorm + opts.xtol) {
            termination = Termination::SmallStep;
            break;
        }
    }
    Ok(Solution {
        x: st.x,
        objective_before,
        objective_after: st.f,
        iterations,
        termination,
    })
}
