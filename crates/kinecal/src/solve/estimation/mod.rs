//! Estimation: from a starting robot and observations to estimated parameters.
//!
//! [`calibrate`] minimises the weighted objective of a [`Problem`](crate::solve::problem)
//! over the chosen parameters with one of the thesis's methods (see [`solver`]), under least
//! squares or a robust Huber loss. What to estimate, which of several equally good answers to
//! return, pruning, validation and reporting are the [`workflow`](crate::workflow)'s.
//!
//! ```
//! use kinecal::{model::examples, solve::estimation::{calibrate, CalibrationOptions}, apps::simulate};
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

pub(crate) mod least_squares;
pub mod solver;
pub mod weighting;

pub use least_squares::{LeastSquares, RowSink};
pub use solver::{
    solve, Damping, Iteration, Method, Solution, SolverOptions, Stationarity, Termination,
    DEFAULT_RCOND,
};
pub use weighting::{ModelErrorFloor, ModelErrorMode};

use crate::error::{Error, Result};
use crate::linalg::{GramAccumulator, Matrix, QrAccumulator, QR_BLOCK};
use crate::model::params::ParamId;
use crate::model::robot::{Prior, Robot};
use crate::observe::{Accuracy, Dataset, KeptErrors, OrientationError, RowQuantity, Weights};
use crate::solve::problem::{Linearized, Problem};
use crate::units::{wrap_angle, Quantity};

/// Everything that decides an estimation.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct CalibrationOptions {
    /// The parameters to estimate (sorted, distinct); the others keep their values.
    pub estimate: Vec<ParamId>,
    /// Method and stopping rules.
    pub solver: SolverOptions,
    /// Default residual weights (rows with a standard deviation of their own use that).
    pub weights: Weights,
    /// Orientation residual.
    pub orientation: OrientationError,
    /// The loss applied to the weighted residuals.
    pub loss: Loss,
    /// A Gaussian prior on the estimated parameters' changes from the start (empty: none):
    /// one residual row per parameter it covers (see [`crate::solve::problem`]).
    pub prior: Prior,
    /// How rows with standard deviations of their own are weighted (see [`weighting`]).
    pub model_error: ModelErrorMode,
}

/// The loss applied to each weighted residual `r` (in standard deviations).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[non_exhaustive]
pub enum Loss {
    /// Least squares, `r^2` (the thesis's objective).
    #[default]
    Squared,
    /// Huber: `r^2` for `|r| <= k s`, linear beyond, so that a few bad rows cannot dominate.
    /// Solved by iteratively reweighted least squares (row weights `min(1, k s / |r|)`).
    /// `k` = 1.345 keeps 95 % efficiency on clean Gaussian data; `s` is the [`Spread`].
    Huber {
        /// The threshold, in spreads.
        k: f64,
        /// What one spread is.
        spread: Spread,
    },
}

/// The unit of a Huber threshold (in a calibration spec: `robust`, `stated`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[non_exhaustive]
pub enum Spread {
    /// The residuals' own robust spread, re-estimated at every reweighting: 1.4826 times the
    /// median absolute weighted residual of the rows alike (same kind and quantity; see
    /// `RobustSpread`). Right whatever the weights: stated standard
    /// deviations far above the real noise (the default weights on sub-millimetre data) would
    /// otherwise leave every row below the threshold and the loss would change nothing.
    #[default]
    Robust,
    /// The stated standard deviations (the weights, or each row's own sigma): trust them.
    Stated,
}

impl Loss {
    /// Huber with threshold `k` robust spreads.
    pub fn huber(k: f64) -> Loss {
        Loss::Huber {
            k,
            spread: Spread::Robust,
        }
    }
}

impl std::fmt::Display for Loss {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Loss::Squared => write!(f, "squared"),
            Loss::Huber {
                k,
                spread: Spread::Robust,
            } => write!(f, "huber {k} x robust spread"),
            Loss::Huber {
                k,
                spread: Spread::Stated,
            } => write!(f, "huber {k} x stated sigma"),
        }
    }
}

impl CalibrationOptions {
    /// Levenberg-Marquardt with default settings, estimating `estimate`.
    pub fn new(estimate: Vec<ParamId>) -> Self {
        CalibrationOptions {
            estimate,
            solver: SolverOptions::new(Method::LevenbergMarquardt),
            weights: Weights::default(),
            orientation: OrientationError::RotVec,
            loss: Loss::Squared,
            prior: Prior::default(),
            model_error: ModelErrorMode::Auto,
        }
    }
}

/// The outcome of an estimation.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
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
    /// How stationary the solver's last point is.
    pub stationarity: Stationarity,
    /// Iterations run.
    pub iterations: usize,
    /// Weighted sum of squared residuals of the data before (the prior's are 0 at the start).
    pub objective_before: f64,
    /// Weighted sum of squared residuals of the data after (with the robust loss's final row
    /// weights); the prior's are [`Calibration::prior_objective`], and the solver minimised
    /// their sum.
    pub objective_after: f64,
    /// The prior's part of the objective after: `sum ((p - p0) / s_p)^2` over the estimated
    /// parameters with a prior (0 without one).
    pub prior_objective: f64,
    /// Unweighted errors before.
    pub accuracy_before: Accuracy,
    /// Unweighted errors after.
    pub accuracy_after: Accuracy,
    /// Estimated parameters no residual felt at the start: they keep their initial values.
    pub unfelt: Vec<ParamId>,
    /// The final row scale, one per residual row of the data: the model-error floor's
    /// (`s_i / max(s_i, m)` for rows with their own standard deviation `s_i`) times the
    /// robust loss's (square roots of its weights); all 1 for least squares at the stated
    /// standard deviations.
    pub row_scale: Vec<f64>,
    /// The model error bounding the rows' own standard deviations from below (see
    /// [`weighting`]), when some rows carry their own.
    pub model_error: Option<ModelErrorFloor>,
    /// True when the fit started from uniform weights (the stated standard deviations spread
    /// over more than 1 / [`weighting::STAGE_RATIO`]; see [`weighting`]).
    pub staged: bool,
    /// Per-iteration log.
    pub log: Vec<Iteration>,
    /// The weighted residuals of `calibrated` (without the robust loss's row scale), one per
    /// row of the data (the prior's rows left out).
    pub residuals: Vec<f64>,
    /// The linearisation at `initial`: an `R` of the weighted `[J | r]` over `estimated`
    /// (`R^T R = [J | r]^T [J | r]`, by QR or from the Gram matrix; see
    /// [`solver::Solution::start_r`]), when the solver computed it there;
    /// the uncertainty at the start reuses it instead of another pass.
    pub(crate) start_r: Option<Matrix>,
    /// Each observation's error at `initial` and at `calibrated`, from the passes that gave
    /// the accuracy figures (the report's chart reuses them; see [`KeptErrors`]).
    pub(crate) errors_before: Option<KeptErrors>,
    /// At `calibrated`.
    pub(crate) errors_after: Option<KeptErrors>,
}

impl Calibration {
    /// True unless the solver stopped at the iteration cap or stalled.
    pub fn converged(&self) -> bool {
        self.termination.converged()
    }

    /// The problem the calibration solved, as its loss weighted it (with its prior's rows).
    pub fn problem<'a>(&'a self, data: &'a Dataset) -> Problem<'a> {
        Problem::new(
            &self.initial,
            data,
            &self.estimated,
            self.options.weights,
            self.options.orientation,
        )
        .with_row_scale(&self.row_scale)
        .with_prior(&self.options.prior)
    }

    /// The whole objective the solver minimised: the data's and the prior's.
    pub fn total_objective(&self) -> f64 {
        self.objective_after + self.prior_objective
    }
}

/// The weighted residuals of the data at `robot` (without the row scale) into `residuals`
/// (one per row of the data), the data's objective (with the row scale `row_scale`: the
/// model-error floor's and the robust loss's), the prior's, and the accuracy with each
/// observation's error: one pass of forward kinematics.
pub(crate) fn settle(
    problem: &Problem<'_>,
    robot: &Robot,
    row_scale: &[f64],
    residuals: &mut [f64],
) -> (f64, f64, Accuracy, KeptErrors) {
    let mut all = vec![0.0; problem.rows()];
    let (_, accuracy, kept) = problem.evaluate_checked(robot, &mut all);
    let nd = problem.data_rows();
    residuals.copy_from_slice(&all[..nd]);
    let prior = all[nd..].iter().map(|r| r * r).sum();
    // The row scale is the model-error floor's and the robust loss's (all 1 without either).
    let data = residuals
        .iter()
        .zip(row_scale)
        .map(|(r, s)| (r * s) * (r * s))
        .sum();
    (data, prior, accuracy, kept)
}

/// Estimates `opts.estimate` of `initial` from `data`, keeping the other parameters.
///
/// Angular results are reported within +-180 deg of their initial values (angles are periodic).
pub fn calibrate(
    initial: &Robot,
    data: &Dataset,
    opts: &CalibrationOptions,
    observer: &mut dyn FnMut(&Iteration),
) -> Result<Calibration> {
    calibrate_from(initial, data, opts, observer, None)
}

/// [`calibrate`], with a linearisation at `initial` at hand (over the estimated parameters or
/// more, with `opts`' weights and orientation residuals): the solver's first evaluation is then
/// taken from it instead of a pass.
pub(crate) fn calibrate_from(
    initial: &Robot,
    data: &Dataset,
    opts: &CalibrationOptions,
    observer: &mut dyn FnMut(&Iteration),
    start: Option<&Linearized>,
) -> Result<Calibration> {
    let problem = checked_problem(initial, data, opts)?;
    let x0 = problem.values(initial);
    // The linearisation at the start, with the errors there from the same pass: given, or
    // computed here (its R is what the uncertainty at the start reuses).
    let (start_r, accuracy_before, errors_before) = match start.and_then(|l| {
        let r = l.restricted(&opts.estimate)?;
        Some((r, l.accuracy.clone(), Some(l.errors.clone())))
    }) {
        Some(given) => given,
        None => linearize_start(&problem, initial, opts)?,
    };
    let mut log = Vec::new();
    let mut record = |it: &Iteration| {
        log.push(*it);
        observer(it);
    };
    let start_objective: f64 = (0..start_r.nrows())
        .map(|i| start_r[(i, start_r.ncols() - 1)].powi(2))
        .sum();
    let WeightedFit {
        mut sol,
        floor_scale,
        model_error,
        staged,
        start_rank,
        unfelt,
        own_rows,
    } = fit_weighted(&problem, opts, &x0, &start_r, &mut record)?;
    sol.objective_before = start_objective;
    let row_scale = match opts.loss {
        Loss::Huber { k, spread } => reweight_huber(
            &problem,
            data,
            opts,
            k,
            spread,
            &floor_scale,
            &mut sol,
            &mut record,
        )?,
        Loss::Squared => floor_scale.clone(),
    };
    sol.stationarity.start_rank = start_rank;
    let calibrated = angles_near(initial, problem.robot_at(&sol.x), &opts.estimate);
    let mut residuals = vec![0.0; problem.data_rows()];
    if model_error.is_some_and(|m| m.length > 0.0 || m.angle > 0.0) {
        // The objective before, as the floor weighs the rows (so that before and after
        // compare).
        (sol.objective_before, _, _, _) = settle(&problem, initial, &floor_scale, &mut residuals);
    }
    let (objective_after, prior_objective, accuracy_after, errors_after) =
        settle(&problem, &calibrated, &row_scale, &mut residuals);
    // The noise is stated when rows carry their own standard deviations or the weights were
    // given; the default 1 mm / 1 mrad is a scale, not a statement about the data.
    let noise_stated = own_rows || opts.weights != Weights::default();
    sol.termination = rank_verdict(
        sol.termination,
        &sol.stationarity,
        &residuals,
        problem.cols(),
        noise_stated,
    );
    Ok(Calibration {
        accuracy_before,
        accuracy_after,
        initial: initial.clone(),
        calibrated,
        estimated: opts.estimate.clone(),
        options: opts.clone(),
        termination: sol.termination,
        stationarity: sol.stationarity,
        iterations: sol.iterations,
        objective_before: sol.objective_before,
        objective_after,
        prior_objective,
        unfelt,
        row_scale,
        model_error,
        staged,
        log,
        residuals,
        start_r: Some(start_r),
        errors_before,
        errors_after: Some(errors_after),
    })
}

/// `calibrated` with its estimated angles within half a turn of `initial`'s (angles are
/// periodic). Only an angle that went round is moved: the others keep the solver's value to the
/// last bit (`v0 + wrap(v - v0)` rounds a negative change).
fn angles_near(initial: &Robot, mut calibrated: Robot, estimated: &[ParamId]) -> Robot {
    for &id in estimated {
        if initial.param_quantity(id) == Quantity::Angle {
            let (v0, v) = (initial.get(id), calibrated.get(id));
            if (v - v0).abs() > std::f64::consts::PI {
                calibrated.set(id, v0 + wrap_angle(v - v0));
            }
        }
    }
    calibrated
}

/// The problem of `opts` over `data` at `initial`, once the options are checked: something to
/// estimate, parameters the robot has, orientation residuals the data allow, at least as many
/// residuals as parameters and a Huber scale that is a number of standard deviations.
fn checked_problem<'a>(
    initial: &'a Robot,
    data: &'a Dataset,
    opts: &'a CalibrationOptions,
) -> Result<Problem<'a>> {
    if opts.estimate.is_empty() {
        return Err(Error::NothingToEstimate);
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
    data.check_orientation(initial, opts.orientation)?;
    let problem = Problem::new(
        initial,
        data,
        &opts.estimate,
        opts.weights,
        opts.orientation,
    )
    .with_reading_trig()
    .with_prior(&opts.prior);
    if problem.rows() < problem.cols() {
        return Err(Error::TooFewResiduals {
            residuals: problem.rows(),
            observations: data.observations.len(),
            parameters: problem.cols(),
        });
    }
    if let Loss::Huber { k, .. } = opts.loss {
        if !(k.is_finite() && k >= 1e-6) {
            return Err(Error::InvalidOption {
                setting: crate::error::Setting::HuberScale,
                message: format!(
                    "expected a number of standard deviations of at least 1e-6, got {k}"
                ),
            });
        }
    }
    Ok(problem)
}

/// The linearisation at `initial` over the data's rows (the prior's are folded in before the
/// solver starts from it, by [`fit_weighted`]: the uncertainty at the start wants the data's
/// `R`), with the accuracy and each observation's error from the same pass.
///
/// By the Gram matrix first, a pass about 40 % cheaper than by QR: its `R` is accurate enough
/// where the Jacobian is well conditioned (the solver's own test,
/// [`solver::augmented_from_gram`]); by a QR pass otherwise. With a prior the data alone seldom
/// determine every parameter (that is what priors are for): QR at once, not a Gram pass wasted
/// first. A start whose objective is not finite is an error that names the rows.
fn linearize_start(
    problem: &Problem<'_>,
    initial: &Robot,
    opts: &CalibrationOptions,
) -> Result<(Matrix, Accuracy, Option<KeptErrors>)> {
    let data_only = problem.clone().with_prior(&Prior::default());
    let n = problem.cols();
    let mut r = vec![0.0; data_only.rows()];
    let by_qr = |r: &mut Vec<f64>| {
        let mut acc = QrAccumulator::new(n + 1, QR_BLOCK);
        let (f, accuracy, kept) = data_only.evaluate_rows_kept(initial, r, &mut acc);
        let mut r0 = Matrix::zeros(0, 0);
        acc.r_into(&mut r0);
        (f, r0, accuracy, kept)
    };
    let (f, r0, accuracy, kept) = if opts.prior.is_empty() {
        let mut gram = GramAccumulator::new(n + 1, QR_BLOCK);
        let (f, accuracy, kept) = data_only.evaluate_rows_kept(initial, &mut r, &mut gram);
        let mut g = Matrix::zeros(0, 0);
        gram.gram_into(&mut g);
        match solver::augmented_from_gram(&g, f) {
            Some(r0) => (f, r0, accuracy, kept),
            None if f.is_finite() => by_qr(&mut r),
            None => (f, g, accuracy, kept),
        }
    } else {
        by_qr(&mut r)
    };
    if !f.is_finite() {
        return Err(non_finite_start(problem, &r));
    }
    Ok((r0, accuracy, Some(kept)))
}

/// The fit at the rows' weights ([`fit_weighted`]) before a robust loss reweighs it.
struct WeightedFit {
    sol: Solution,
    /// The model-error floor's row scale (`s_i / max(s_i, m)`; all 1 without a floor).
    floor_scale: Vec<f64>,
    /// The floor, when rows carry standard deviations of their own and it is estimated.
    model_error: Option<ModelErrorFloor>,
    /// Whether the fit started from uniform weights.
    staged: bool,
    /// The rank of the first solve's start.
    start_rank: usize,
    /// The estimated parameters no residual felt at the start.
    unfelt: Vec<ParamId>,
    /// Whether some rows carry standard deviations of their own.
    own_rows: bool,
}

/// The fit at the rows' weights. Rows with standard deviations of their own get a staged
/// start (from uniform weights: always when a floor is to be estimated, which needs a fit its
/// residuals can be read from; otherwise when the sigmas spread far) and, with
/// [`ModelErrorMode::Auto`], a model-error floor when their residuals show more than they state
/// ([`choose_floor`]); see [`weighting`].
fn fit_weighted(
    problem: &Problem<'_>,
    opts: &CalibrationOptions,
    x0: &[f64],
    start_r: &Matrix,
    record: &mut dyn FnMut(&Iteration),
) -> Result<WeightedFit> {
    let kinds = weighting::row_kinds(problem.data());
    let sigma = problem.row_sigma().to_vec();
    let own_rows = kinds.iter().any(|(_, own)| *own);
    let auto = own_rows && opts.model_error == ModelErrorMode::Auto;
    let staged_scale = match (own_rows, auto) {
        (false, _) => None,
        (true, true) => Some(
            weighting::staged_scale(&kinds, &sigma)
                .unwrap_or_else(|| weighting::uniform_scale(&kinds, &sigma)),
        ),
        (true, false) => weighting::staged_scale(&kinds, &sigma),
    };
    let uniform = match &staged_scale {
        Some(scale) => {
            let floored = problem.clone().with_row_scale(scale);
            Some(solve(&floored, x0, &opts.solver, record)?)
        }
        None => None,
    };
    // The fit at the stated standard deviations (with a floor to weigh it against, a probe
    // of at most `weighting::STATED_PROBE` iterations first: continued if it is chosen).
    let mut probe = opts.solver;
    if auto {
        probe.max_iterations = probe.max_iterations.min(weighting::STATED_PROBE);
    }
    let mut sol = match &uniform {
        Some(first) => {
            let mut sol = solve(problem, &first.x, &probe, record)?;
            sol.iterations += first.iterations;
            sol.unfelt = first.unfelt.clone();
            sol
        }
        None => {
            // The solver's start: the data's R with the prior's rows folded in (0 there).
            let solver_start = problem.with_prior_rows(start_r);
            solver::drive(
                problem,
                x0,
                &opts.solver,
                opts.solver.method.rule(&opts.solver).as_mut(),
                record,
                Some(&solver_start),
            )?
        }
    };
    // The rank at the start of the estimation: that of the first solve's start.
    let start_rank = uniform
        .as_ref()
        .map_or(sol.stationarity.start_rank, |u| u.stationarity.start_rank);
    let unfelt: Vec<ParamId> = sol.unfelt.iter().map(|&j| opts.estimate[j]).collect();
    let (floor_scale, model_error) = match (auto, &uniform) {
        (true, Some(first)) => {
            let (scale, floor) =
                choose_floor(problem, opts, &kinds, &sigma, first, &mut sol, record)?;
            (scale, Some(floor))
        }
        _ => (vec![1.0; problem.data_rows()], None),
    };
    Ok(WeightedFit {
        sol,
        floor_scale,
        model_error,
        staged: uniform.is_some(),
        start_rank,
        unfelt,
        own_rows,
    })
}

/// The model-error floor against the stated standard deviations, from the uniform fit `first`
/// and the stated fit `sol` (a probe): rows whose residuals match their sigmas at the stated fit
/// keep them; for the others the floor is estimated, fitted and estimated again until it
/// settles, and kept when it wins by the likelihood of the residuals (its extra parameters
/// charged as Akaike's criterion charges them). `sol` becomes the fit chosen (the stated probe
/// continued to the iteration cap when the floor loses). Returns the floor's row scale (all 1
/// when it loses) and the floor (its row counts alone when it loses).
fn choose_floor(
    problem: &Problem<'_>,
    opts: &CalibrationOptions,
    kinds: &[(RowQuantity, bool)],
    sigma: &[f64],
    first: &Solution,
    sol: &mut Solution,
    record: &mut dyn FnMut(&Iteration),
) -> Result<(Vec<f64>, ModelErrorFloor)> {
    let mut floor = ModelErrorFloor {
        rows: [RowQuantity::Length, RowQuantity::Angle]
            .map(|q| kinds.iter().filter(|&&k| k == (q, true)).count()),
        ..Default::default()
    };
    let nd = problem.data_rows() as f64;
    let dof_fraction = ((nd - problem.cols() as f64) / nd).max(0.0);
    let mut all = vec![0.0; problem.rows()];
    let residuals_at = |x: &[f64], all: &mut Vec<f64>| {
        problem.evaluate(&problem.robot_at(x), all, None);
    };
    // The stated probe continued to the iteration cap (`rest` of it left).
    let finish_stated = |sol: &mut Solution, record: &mut dyn FnMut(&Iteration)| -> Result<()> {
        let used = sol.iterations - first.iterations;
        if sol.termination == Termination::MaxIterations && used < opts.solver.max_iterations {
            let mut rest = opts.solver;
            rest.max_iterations -= used;
            let more = solve(problem, &sol.x, &rest, record)?;
            sol.iterations += more.iterations;
            sol.x = more.x;
            sol.termination = more.termination;
            sol.stationarity = more.stationarity;
        }
        Ok(())
    };
    // Which quantities' rows match their sigmas at the stated fit: those keep them.
    residuals_at(&sol.x, &mut all);
    let first_test = weighting::estimate_floor(
        kinds,
        sigma,
        &all[..problem.data_rows()],
        dof_fraction,
        true,
    );
    let held = first_test.map(|m| m.is_none_or(|m| m <= 0.0));
    if !held.iter().all(|h| *h) {
        let (fitted, floor_iterations) = iterate_floor(
            problem,
            opts,
            (kinds, sigma),
            held,
            dof_fraction,
            first,
            &mut floor,
            record,
        )?;
        let x = fitted.as_ref().map_or(&first.x, |f| &f.x);
        // The floored fit against the stated one, by the likelihood of the residuals under
        // each one's standard deviations, the floor's extra parameters (one per quantity
        // floored) charged as Akaike's criterion charges them. A probe stopped at its cap
        // is finished first when the floor would win against it.
        residuals_at(x, &mut all);
        let floor_cost =
            weighting::likelihood_cost(kinds, sigma, &all[..problem.data_rows()], &floor)
                + 2.0 * held.iter().filter(|h| !**h).count() as f64;
        let mut stated_cost = f64::INFINITY;
        for _ in 0..2 {
            residuals_at(&sol.x, &mut all);
            stated_cost = weighting::likelihood_cost(
                kinds,
                sigma,
                &all[..problem.data_rows()],
                &ModelErrorFloor::default(),
            );
            let capped = sol.termination == Termination::MaxIterations
                && sol.iterations - first.iterations < opts.solver.max_iterations;
            if floor_cost < stated_cost && capped {
                finish_stated(sol, record)?;
            } else {
                break;
            }
        }
        if let Some(f) = fitted.filter(|_| floor_cost < stated_cost) {
            // The iterations of the path taken: the uniform fit's and the floor's.
            sol.iterations = first.iterations + floor_iterations;
            sol.x = f.x;
            sol.termination = f.termination;
            sol.stationarity = f.stationarity;
            return Ok((weighting::floor_scale(kinds, sigma, &floor), floor));
        }
    }
    // The stated fit stands: the probe continued to the iteration cap.
    finish_stated(sol, record)?;
    Ok((
        vec![1.0; problem.data_rows()],
        ModelErrorFloor {
            rows: floor.rows,
            ..Default::default()
        },
    ))
}

/// The model-error floor from the uniform fit `first` on: estimated from the residuals,
/// fitted, estimated again until it settles (each quantity's floor within 2 % of the last) or
/// [`weighting::FLOOR_ROUNDS`] rounds; quantities whose rows `held` their sigmas get none.
/// `floor` holds the last floor fitted; returns that fit (none only when
/// [`weighting::FLOOR_ROUNDS`] is 0) and the iterations of all the fits.
#[allow(clippy::too_many_arguments)]
fn iterate_floor(
    problem: &Problem<'_>,
    opts: &CalibrationOptions,
    (kinds, sigma): (&[(RowQuantity, bool)], &[f64]),
    held: [bool; 2],
    dof_fraction: f64,
    first: &Solution,
    floor: &mut ModelErrorFloor,
    record: &mut dyn FnMut(&Iteration),
) -> Result<(Option<Solution>, usize)> {
    let mut all = vec![0.0; problem.rows()];
    let mut fitted: Option<Solution> = None;
    let mut iterations = 0;
    for round in 0..=weighting::FLOOR_ROUNDS {
        let x = fitted.as_ref().map_or(&first.x, |f| &f.x);
        problem.evaluate(&problem.robot_at(x), &mut all, None);
        let est = weighting::estimate_floor(
            kinds,
            sigma,
            &all[..problem.data_rows()],
            dof_fraction,
            false,
        );
        let next = [0, 1].map(|q| if held[q] { 0.0 } else { est[q].unwrap_or(0.0) });
        let prev = [floor.length, floor.angle];
        let settled = fitted.is_some()
            && next
                .iter()
                .zip(prev)
                .all(|(n, p)| (n - p).abs() <= 0.02 * p.max(*n));
        if settled || round == weighting::FLOOR_ROUNDS {
            break;
        }
        floor.length = next[0];
        floor.angle = next[1];
        let scale = weighting::floor_scale(kinds, sigma, floor);
        let floored = problem.clone().with_row_scale(&scale);
        let again = solve(&floored, x, &opts.solver, record)?;
        floor.refits += 1;
        iterations += again.iterations;
        fitted = Some(again);
    }
    Ok((fitted, iterations))
}

/// The Huber loss by iteratively reweighted least squares: weights `min(1, k s_i / |r_i|)` per
/// residual, on the residuals as the floor weighs them (`floor_scale`; `s_i` the robust or the
/// stated spread), refitted until they change by less than 1e-9 or a refit moves the
/// parameters by less than [`SETTLED_MOVE`] of a standard deviation (at most [`HUBER_ROUNDS`]
/// refits, each with the solver's iteration cap, as the model-error floor's refits have it).
/// `sol` becomes the last fit (its objective before and unfelt columns kept), its iterations
/// those of every fit so far; when the weights have not settled after the last refit, it is not
/// converged ([`Termination::MaxIterations`]: the refits' cap was reached first). Returns the
/// final row scale (the floor's times the loss's square-root weights).
#[allow(clippy::too_many_arguments)]
fn reweight_huber(
    problem: &Problem<'_>,
    data: &Dataset,
    opts: &CalibrationOptions,
    k: f64,
    spread: Spread,
    floor_scale: &[f64],
    sol: &mut Solution,
    record: &mut dyn FnMut(&Iteration),
) -> Result<Vec<f64>> {
    let mut row_scale = floor_scale.to_vec();
    let mut all = vec![0.0; problem.rows()];
    let mut iterations = sol.iterations;
    let mut settled = false;
    for round in 0..=HUBER_ROUNDS {
        problem.evaluate(&problem.robot_at(&sol.x), &mut all, None);
        // The data's rows: the prior's keep weight 1.
        let r: Vec<f64> = all[..problem.data_rows()]
            .iter()
            .zip(floor_scale)
            .map(|(r, f)| r * f)
            .collect();
        let s = match spread {
            Spread::Robust => crate::observe::RobustSpread::of(data, &r).per_row,
            Spread::Stated => vec![1.0; r.len()],
        };
        let new: Vec<f64> = r
            .iter()
            .zip(&s)
            .zip(floor_scale)
            .map(|((&ri, &si), f)| f * (k * si / ri.abs()).min(1.0).sqrt())
            .collect();
        let change = new
            .iter()
            .zip(&row_scale)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        if change < 1e-9 {
            settled = true;
            row_scale = new;
            break;
        }
        if round == HUBER_ROUNDS {
            // The last fit's weights, not the next ones: `sol` is that fit.
            break;
        }
        row_scale = new;
        let weighted = problem.clone().with_row_scale(&row_scale);
        let before = sol.objective_before;
        let unfelt = std::mem::take(&mut sol.unfelt);
        let x_before = std::mem::take(&mut sol.x);
        *sol = solve(&weighted, &x_before, &opts.solver, record)?;
        iterations += sol.iterations;
        sol.objective_before = before;
        sol.unfelt = unfelt;
        if refit_moved_within_precision(sol, &x_before, problem.rows()) {
            settled = true;
            break;
        }
    }
    sol.iterations = iterations;
    if !settled && sol.termination.converged() {
        sol.termination = Termination::MaxIterations;
    }
    Ok(row_scale)
}

/// At most this many refits of the Huber loss's weights.
const HUBER_ROUNDS: usize = 100;

/// Whether the refit `sol` (from `x_before`, over `rows` residual rows) moved the parameters by
/// less than [`SETTLED_MOVE`] of a standard deviation in every direction: `|R dx| <= SETTLED_MOVE
/// s`, with `R` the refit's linearisation at `x_before` and `s^2` the residual variance
/// `objective / (rows - cols)` (the Mahalanobis length of the move under the covariance
/// `s^2 (R^T R)^-1` bounds every parameter's move, and every combination's, in its own standard
/// deviations). Reweighting converges linearly (its moves shrink by a constant factor: 0.85 per
/// refit with a threshold of 0.3 spreads on the ge-a4 session of `tests/workflow.rs`), so the
/// weights themselves may take hundreds of refits to settle to rounding while the fit has long
/// stopped moving at the data's precision. `rows` counts the prior's rows too, and the
/// objective includes them.
fn refit_moved_within_precision(sol: &Solution, x_before: &[f64], rows: usize) -> bool {
    let n = sol.x.len();
    let r = &sol.start_r;
    if r.nrows() < n || r.ncols() < n {
        return false;
    }
    let dx: Vec<f64> = sol.x.iter().zip(x_before).map(|(a, b)| a - b).collect();
    let moved2: f64 = (0..n)
        .map(|i| {
            let v: f64 = (i..n).map(|j| r[(i, j)] * dx[j]).sum();
            v * v
        })
        .sum();
    let variance = sol.objective_after / rows.saturating_sub(n).max(1) as f64;
    moved2.is_finite() && moved2 <= SETTLED_MOVE * SETTLED_MOVE * variance
}

/// How far (in standard deviations) a refit of the Huber loss may move the parameters and the
/// weights count as settled: 1e-3, so that even at 0.9 per refit the moves still to come add up
/// to less than a hundredth of a standard deviation. (The robust spread is re-estimated at each
/// refit, and on few rows its median jumps between rows: with a prior on all 54 parameters of
/// an 8-posture session, `tests/priors.rs`, the moves wander between 1e-3 and 7e-3 before they
/// shrink, and fall below 1e-3 after 47 refits.)
const SETTLED_MOVE: f64 = 1e-3;

/// The verdict on a stationary point where the scaled Jacobian determines fewer directions than
/// at the start (two joint axes lined up on the way, a frame folded onto another):
/// [`Termination::RankLost`], not converged, unless the residuals are at the stated noise.
///
/// The stationarity tests certify a minimum only in the directions the Jacobian still
/// determines. A point whose weighted residuals `residuals` (at the stated standard deviations,
/// without the model-error floor's or the robust loss's row scale) the stated noise explains,
/// their chi-square within three of its standard deviations of its mean `N - p` (`p` =
/// `estimated`; the test the model-error floor starts with), is a minimum to the data's
/// precision in every direction: no point fits significantly better. The direction lost there
/// is one the data leave undetermined at the answer (a tool pitched at a right angle: its ZYX
/// angles `alpha` and `gamma` turn about one axis at `beta` = 90 deg), which the uncertainty
/// reports, not a stall. Any other termination is returned as it is.
///
/// The test needs a noise someone stated (`noise_stated`: rows with their own standard
/// deviations, or weights given): at the default weights (1 mm, 1 mrad, a scale and not a
/// statement about the data) residuals of 0.5 mm would pass it whatever a better point could
/// reach. Without a stated noise only an exact fit (the objective zero to rounding) is exempt.
fn rank_verdict(
    termination: Termination,
    stationarity: &Stationarity,
    residuals: &[f64],
    estimated: usize,
    noise_stated: bool,
) -> Termination {
    if !termination.converged() || stationarity.rank >= stationarity.start_rank {
        return termination;
    }
    if termination == Termination::ZeroObjective {
        return termination;
    }
    let dof = residuals.len().saturating_sub(estimated) as f64;
    let chi2: f64 = residuals.iter().map(|r| r * r).sum();
    if noise_stated && chi2 <= dof + 3.0 * (2.0 * dof).sqrt() {
        termination
    } else {
        Termination::RankLost
    }
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
    Error::NonFiniteObjective {
        at: "the starting point",
    }
}
