//! Identifiability (thesis 3.4, 4.4.2-4.4.8): what the data can and cannot determine.
//!
//! Everything here works on the Jacobian of the estimated parameters over a dataset, in two
//! unit systems:
//! - *scaled*: residuals weighted by the measurement standard deviations and every column divided
//!   by its norm, the space the solvers work in (see [`crate::solve::estimation`]); ranks, gaps and
//!   dependencies are decided here, where units cannot distort them;
//! - *file*: rows in the robot file's length and angle units, columns per unit of each parameter,
//!   as the thesis prints its Tables 4.3-4.7.
//!
//! ```
//! use kinecal::{model::examples, apps::simulate, identifiability::{analyze, AnalysisOptions}};
//! let robot = examples::ge_a4();
//! let data = simulate::measure(&robot, &simulate::sample_postures(&robot, 30, 1), false);
//! let all: Vec<_> = robot.param_ids().collect();
//! let a = analyze(&robot, &data, &all, &AnalysisOptions::default()).unwrap();
//! assert_eq!(a.rank, 24); // 5 nr + 3 np + 6 (eq. 4.2)
//! assert_eq!(a.expected.unwrap().rank, 24);
//! ```

//!
//! The analysis is a sequence of steps, each in its own module: the rows are folded into the
//! `R` of a QR (`spectrum`), whose scaled columns give the singular values, the rank and the
//! null space; `groups` finds the identically redundant parameters and writes directions in
//! reduced form; `base` chooses an identifiable set by priority and leaves out what only
//! the noise determines; `expected` is the thesis's count ([`expected_rank`]); `table` the Jacobian for
//! display ([`jacobian_table`]).

mod base;
mod basis;
mod expected;
mod groups;
mod spectrum;
mod table;
#[cfg(test)]
mod tests;

use crate::error::{Error, Result};
use crate::linalg::Matrix;
use crate::model::params::{LinkComponent, ParamId, ParamKind};
use crate::model::robot::Robot;
use crate::observe::{Dataset, OrientationError, Weights};
use crate::solve::problem::{Linearized, Problem};
use crate::warning::Warning;

pub use base::default_priority;
pub use expected::expected_rank;
pub use groups::format_combination;
pub use table::{jacobian_table, JacobianTable};

/// Settings of an analysis.
#[derive(Debug, Clone, PartialEq)]
pub struct AnalysisOptions {
    /// Relative tolerance: singular values of the scaled Jacobian below `rcond * s_max` count as
    /// zero.
    pub rcond: f64,
    /// Residual weights (as in calibration).
    pub weights: Weights,
    /// Orientation residual (as in calibration).
    pub orientation: OrientationError,
    /// Parameters to prefer in the identifiable set, most preferred first; the rest follow in the
    /// default order (see [`default_priority`]).
    pub priority: Vec<ParamId>,
    /// The noise the noise-level rule assumes, as a multiple of the stated sigmas (1: the
    /// stated ones). A fit whose residuals are `k` times the stated sigmas (variance factor
    /// `k^2`) shows that the rows are `k` times as noisy as stated (a tracker's own sigmas
    /// under a model error): the rule judged at `k` times them leaves out what only the
    /// stated precision made look determined.
    pub noise_scale: f64,
    /// A Gaussian prior on the parameters' changes (empty: none). Its rows (see
    /// [`crate::solve::problem`]) count as information: the rank, the null space, what is determined
    /// and the covariance are those of the data and the prior together, and
    /// [`Analysis::determined_by_data`] says what the data alone determines.
    pub prior: crate::model::robot::Prior,
    /// Parameters whose values the start already took from the data (a calibration's
    /// closed-form placement of the measurement and tool frames, see
    /// [`crate::solve::registration`]): the noise-level rule does not leave them out, only
    /// dependence at the rounding level does. Held, such a parameter would keep the value a fit
    /// of the nominal robot gave it, and along a direction the data barely determine the
    /// nominal model's error moves it furthest (the IPA UR10's series D, measured at one tool
    /// attitude: the tool's length along the flange axis placed 38 mm from where every other
    /// series puts it); estimated, the data place it together with the rest, and
    /// [`Analysis::placed_loose`] names those the rule would have left out.
    pub placed: Vec<ParamId>,
}

/// Default relative singular-value tolerance for the numerical rank.
pub const DEFAULT_RANK_RCOND: f64 = 1e-9;

impl Default for AnalysisOptions {
    fn default() -> Self {
        AnalysisOptions {
            rcond: DEFAULT_RANK_RCOND,
            weights: Weights::default(),
            orientation: OrientationError::RotVec,
            priority: Vec::new(),
            noise_scale: 1.0,
            prior: crate::model::robot::Prior::default(),
            placed: Vec::new(),
        }
    }
}

/// The rank the thesis's formulas predict (eqs. 4.2, 4.3, 4.5).
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct ExpectedRank {
    /// The predicted number of independent parameters.
    pub rank: usize,
    /// How it was computed, e.g. `4*4 + 2*1 ... `.
    pub formula: String,
}

/// A set of parameters whose Jacobian columns are equal or opposite at every posture (thesis
/// 4.4.3): the data determines only one combination of them.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct IdenticalGroup {
    /// Members and the coefficients of the determined combination (file units, first member 1).
    pub terms: Vec<(ParamId, f64)>,
    /// Value of the combination for the analysed robot (file units).
    pub value: f64,
    /// Whether the data determines the combination. It does unless members also take part in
    /// other dependencies (then only a larger combination is determined).
    pub determined: bool,
}

/// A parameter left out of the identifiable set because the data does not determine it at the
/// noise level: given the parameters chosen before it, at the stated weights, its standard
/// deviation exceeds 0.02 rad (an angle), 2 % of the robot's reach (a length) or 2 % of its
/// value (a slope, a coupling factor) (see [`Analysis::noise_rule`]). Its column is nearly
/// a combination of the chosen ones, or barely felt at all; an estimate of it would be
/// meaningless, and would slow a solver down along its valley.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct NoiseDependent {
    /// The parameter.
    pub id: ParamId,
    /// `r_jj / e_j` at its pivot step: its remaining weighted column norm (the information
    /// the data gives about it once the parameters chosen before it are estimated too) over
    /// the information one typical row gives about it alone ([`Analysis::typical_row`]).
    pub ratio: f64,
    /// Its standard deviation at the stated weights times [`AnalysisOptions::noise_scale`] (the
    /// robot file's unit of the parameter):
    /// given the parameters chosen before it, `1 / r_jj`, or given the whole identifiable set
    /// when that is what left it out.
    pub sigma: f64,
    /// The sine of the angle between its column and the span of the columns chosen before
    /// it, on unit-norm scaled columns (the quantity the rounding tolerance `rcond * s_max`
    /// is applied to; above it).
    pub sine: f64,
    /// Its near-combination, the regression of its Jacobian column on the columns of the
    /// identifiable set: column(`id`) ~= `sum c_k` column(`k`), file units, the largest terms
    /// first (largest by `|c_k|` times the ratio of the columns' norms, i.e. on unit-norm
    /// columns). Moving `id` by 1 changes the predictions almost as moving each `k` by `c_k`
    /// does, which is why the data cannot tell them apart.
    pub terms: Vec<(ParamId, f64)>,
    /// The number of smaller terms of the regression left out of `terms`.
    pub(crate) omitted: usize,
}

impl NoiseDependent {
    /// `p29 ~= -p30 + 0.0012 p35`, with `+ ...` when smaller terms are left out.
    pub fn expression(&self) -> String {
        let mut s = format!("{} ~= ", self.id);
        if self.terms.is_empty() {
            s.push('0');
        } else {
            s.push_str(&format_combination(&self.terms));
        }
        if self.omitted > 0 {
            s.push_str(" + ...");
        }
        s
    }
}

/// The result of [`analyze`].
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct Analysis {
    /// The analysed parameters, in order.
    pub parameters: Vec<ParamId>,
    /// Number of residuals: the data's, and the prior's ([`Analysis::prior_rows`]).
    pub residuals: usize,
    /// Number of residual rows of the prior: one per analysed parameter it covers (0 without
    /// one).
    pub prior_rows: usize,
    /// Singular values of the scaled Jacobian (non-increasing).
    pub singular_values_scaled: Vec<f64>,
    /// Singular values of the Jacobian in file units.
    pub singular_values_file: Vec<f64>,
    /// Numerical rank: scaled singular values above `rcond * s_max`.
    pub rank: usize,
    /// The tolerance used.
    pub rcond: f64,
    /// Position of the largest gap in the scaled spectrum: the rank it suggests.
    pub gap_rank: usize,
    /// The gap's size, `s[gap_rank - 1] / s[gap_rank]` (infinite for an exact zero).
    pub gap_ratio: f64,
    /// Whether the rank from the tolerance and the largest gap agree (at full rank: no gap over
    /// 1e3 elsewhere); a warning says so when not.
    pub rank_consistent: bool,
    /// The thesis's count, when it applies to the analysed parameters.
    pub expected: Option<ExpectedRank>,
    /// Parameters with a zero column: no measurement feels them.
    pub unobservable: Vec<ParamId>,
    /// Identically redundant groups.
    pub identical_groups: Vec<IdenticalGroup>,
    /// A basis of the null space in reduced form: each entry is a direction (file units) along
    /// which the parameters can move without changing any prediction.
    pub null_space: Vec<Vec<(ParamId, f64)>>,
    /// An identifiable (base) parameter set, by priority: a maximal subset independent at the
    /// rounding level (`rcond`), less the parameters dependent within the noise
    /// ([`Analysis::noise_dependent`]). Its size is at most [`Analysis::rank`], which stays
    /// the rounding rank.
    pub identifiable: Vec<ParamId>,
    /// The parameters left out of the identifiable set as dependent within the noise, in the
    /// order they were found.
    pub noise_dependent: Vec<NoiseDependent>,
    /// The noise-level rule, in words, with this analysis's threshold.
    pub noise_rule: String,
    /// The identifiable parameters among [`AnalysisOptions::placed`] that the noise-level rule
    /// would have left out, each with its standard deviation given the whole identifiable set
    /// (at the stated weights times [`AnalysisOptions::noise_scale`], the robot file's unit of
    /// the parameter): kept because the start already took their values from the data.
    pub placed_loose: Vec<(ParamId, f64)>,
    /// Per analysed parameter, `e_j`: what one typical row tells about it, the RMS over the
    /// `m` rows of its weighted Jacobian column (internal units), each row's weight
    /// `w_i = 1 / sigma_i` clamped at the median weight of the rows of its quantity (lengths
    /// or angles): `sqrt((1/m) sum_i (c_ij min(1, w_med / w_i))^2)`. The clamp keeps a few
    /// rows of tiny sigma (anchors) from making every other parameter look negligible.
    pub typical_row: Vec<f64>,
    /// For each analysed parameter: whether the data determines it individually (it has no
    /// component in the null space); with a prior, the data and the prior together.
    pub determined: Vec<bool>,
    /// For each analysed parameter: whether the data alone, without the prior, determines it
    /// individually (the same as [`Analysis::determined`] without a prior). A parameter
    /// determined but not by the data needs the prior ([`Analysis::prior_dependent`]).
    pub determined_by_data: Vec<bool>,
    /// The numerical rank of the data alone (the same as [`Analysis::rank`] without a prior).
    pub data_rank: usize,
    /// Links or sites whose beta is near +-90 deg: alpha and gamma then act alike, a singularity
    /// of the Euler parameterisation rather than a physical redundancy.
    pub euler_singular: Vec<String>,
    /// Warnings (unclear gap, ...).
    pub warnings: Vec<Warning>,
    /// Column scale factors (norms of the weighted SI columns).
    pub(crate) column_norms: Vec<f64>,
    /// Right singular vectors of the scaled Jacobian (n x n), in the order of the singular
    /// values: columns `rank..` span the null space.
    pub(crate) right_singular_vectors: Matrix,
}

impl Analysis {
    /// Condition number over the numerical rank, `s_1 / s_rank` (scaled units).
    pub fn condition_number(&self) -> f64 {
        cond(&self.singular_values_scaled, self.rank)
    }

    /// The same in file units.
    pub fn condition_number_file(&self) -> f64 {
        cond(&self.singular_values_file, self.rank)
    }

    /// The analysed parameters determined with the prior but not by the data alone (none
    /// without a prior): the data leave them free, or fix only combinations of them with others,
    /// which the prior splits.
    pub fn prior_dependent(&self) -> Vec<ParamId> {
        (0..self.parameters.len())
            .filter(|&k| self.determined[k] && !self.determined_by_data[k])
            .map(|k| self.parameters[k])
            .collect()
    }
}

fn cond(s: &[f64], rank: usize) -> f64 {
    if rank == 0 {
        return f64::INFINITY;
    }
    s[0] / s[rank - 1]
}

/// Analyses what `data` determines about `params` of `robot`.
pub fn analyze(
    robot: &Robot,
    data: &Dataset,
    params: &[ParamId],
    opts: &AnalysisOptions,
) -> Result<Analysis> {
    analyze_with(robot, data, params, opts, None, true, false).map(|(a, _)| a)
}

/// [`analyze`] without what only a display needs: the row labels, the file-unit Jacobian and
/// its singular values are left empty (the uncertainty needs none of them, and they cost an
/// m x n copy, a second factorization and a string per row).
pub(crate) fn analyze_core(
    robot: &Robot,
    data: &Dataset,
    params: &[ParamId],
    opts: &AnalysisOptions,
) -> Result<Analysis> {
    analyze_with(robot, data, params, opts, None, false, false).map(|(a, _)| a)
}

/// [`analyze_core`], keeping the linearisation it made at `robot` (for a solver that starts
/// there: its first evaluation then costs no pass). On large data the rows are folded through
/// a basis of the columns found on a subsample and proved on every row (see `basis`): the same
/// `R` up to rounding, for a QR of fewer columns.
pub(crate) fn analyze_linearized(
    robot: &Robot,
    data: &Dataset,
    params: &[ParamId],
    opts: &AnalysisOptions,
) -> Result<(Analysis, Linearized)> {
    let (analysis, lin) = analyze_with(robot, data, params, opts, None, false, true)?;
    let lin = lin.ok_or_else(|| Error::Numerical("no linearisation was made".into()))?;
    Ok((analysis, lin))
}

/// [`analyze_core`] from the `R` of the QR of the weighted `[J | r]` at `robot`, over `params`
/// in ascending order, already at hand (a solver's first evaluation at its start is one): no
/// pass of forward kinematics.
///
/// `R` alone does not give the typical-row information `e_j` of the noise-level rule (it needs
/// the rows): it is bounded below from the column norms, `e_j >= f |c_j| / sqrt(m)` with `f`
/// the smallest clamp factor `min(1, w_med / w_i)` of any row, exact when no row weighs more
/// than its quantity's median (uniform weights per quantity). Otherwise the bound lowers the
/// threshold: the rule then errs towards keeping parameters ([`Analysis::noise_rule`] says so).
pub(crate) fn analyze_from_r(
    robot: &Robot,
    data: &Dataset,
    params: &[ParamId],
    opts: &AnalysisOptions,
    raug: &Matrix,
) -> Result<Analysis> {
    analyze_with(robot, data, params, opts, Some((raug, None)), false, false).map(|(a, _)| a)
}

/// [`analyze_core`] from a linearisation at `robot` made by [`analyze_linearized`] over
/// `lin.params` (its `R` and its `e_j`): the same analysis, without a pass.
#[cfg(test)]
pub(crate) fn analyze_from_linearized(
    robot: &Robot,
    data: &Dataset,
    lin: &Linearized,
    opts: &AnalysisOptions,
) -> Result<Analysis> {
    let known = Some((&lin.r, Some(lin.typical_row.as_slice())));
    analyze_with(robot, data, &lin.params, opts, known, false, false).map(|(a, _)| a)
}

fn analyze_with(
    robot: &Robot,
    data: &Dataset,
    params: &[ParamId],
    opts: &AnalysisOptions,
    known_r: Option<(&Matrix, Option<&[f64]>)>,
    display: bool,
    subsample: bool,
) -> Result<(Analysis, Option<Linearized>)> {
    let params = checked_parameters(robot, params, opts)?;
    let n = params.len();
    data.check_orientation(robot, opts.orientation)?;
    let problem = Problem::new(robot, data, &params, opts.weights, opts.orientation);
    // A pass over the rows (none when `R` is known) takes the readings' sines and cosines from
    // the dataset's table.
    let problem = if known_r.is_none() {
        problem.with_start_reading_trig()
    } else {
        problem
    };
    let m = problem.rows();
    let clamp = base::row_clamp(data, &problem);
    let through_basis = if subsample && known_r.is_none() {
        basis::rows(robot, data, &problem, &params, opts, &clamp)?
    } else {
        None
    };
    let rows = match through_basis {
        Some(rows) => rows,
        None => spectrum::rows(robot, &problem, &clamp, known_r, n)?,
    };
    // With a prior, its rows folded in: the analysis is of the data and the prior together,
    // and what the data alone determines is decided on the data's R.
    let with_prior = problem.clone().with_prior(&opts.prior);
    let prior_rows = with_prior.prior_rows();
    let data_only = (prior_rows > 0).then(|| spectrum::data_determined(&rows.raug, n, opts.rcond));
    let raug_all = with_prior.with_prior_rows(&rows.raug);
    let col_factor: Vec<f64> = params
        .iter()
        .map(|&id| robot.units.factor(robot.param_quantity(id)))
        .collect();
    let scaled = spectrum::Scaled::of(&raug_all, n, &params)?;
    let singular_values_file = if display {
        spectrum::file_singular_values(robot, data, &problem, &col_factor)?
    } else {
        Vec::new()
    };
    let spectrum = spectrum::Spectrum::of(&scaled, opts.rcond, m);
    let mut warnings = spectrum.warnings(n, opts.rcond);
    let null = spectrum::NullSpace::of(&scaled, spectrum.rank, &col_factor);
    let (data_rank, determined_by_data) =
        data_only.unwrap_or_else(|| (spectrum.rank, null.determined.clone()));
    let identical_groups = groups::identical(robot, &params, &scaled, &null, &col_factor);
    let set = base::identifiable_set(
        robot,
        &params,
        opts,
        &scaled,
        &spectrum,
        &clamp,
        rows.typical.clone(),
        &col_factor,
        m,
    );
    let null_space = groups::reduced_null_space(&null.file, &set.order, &params);
    let euler_singular = euler_singular_frames(robot, &params, &scaled.unobservable);
    warnings.extend(euler_singular.iter().map(|frame| Warning::EulerSingular {
        frame: frame.clone(),
    }));
    let lin = rows.accuracy.map(|(accuracy, errors)| Linearized {
        params: params.clone(),
        r: rows.raug,
        typical_row: set.typical.clone(),
        accuracy,
        errors,
    });
    let analysis = Analysis {
        expected: expected_rank(robot, data, &params),
        parameters: params,
        residuals: m + prior_rows,
        prior_rows,
        singular_values_scaled: spectrum.values,
        singular_values_file,
        rank: spectrum.rank,
        rcond: opts.rcond,
        gap_rank: spectrum.gap_rank,
        gap_ratio: spectrum.gap_ratio,
        rank_consistent: spectrum.consistent,
        unobservable: scaled.unobservable,
        identical_groups,
        null_space,
        identifiable: set.identifiable,
        noise_dependent: set.noise_dependent,
        noise_rule: set.noise_rule,
        placed_loose: set.placed_loose,
        typical_row: set.typical,
        determined: null.determined,
        determined_by_data,
        data_rank,
        euler_singular,
        warnings,
        column_norms: scaled.column_norms,
        right_singular_vectors: scaled.vectors,
    };
    Ok((analysis, lin))
}

/// The analysed parameters sorted and without repeats, each one of `robot`'s; the options
/// checked.
fn checked_parameters(
    robot: &Robot,
    params: &[ParamId],
    opts: &AnalysisOptions,
) -> Result<Vec<ParamId>> {
    let mut params = params.to_vec();
    params.sort();
    params.dedup();
    if params.is_empty() {
        return Err(Error::NothingToEstimate);
    }
    if let Some(bad) = params.iter().find(|id| id.0 >= robot.param_count()) {
        return Err(Error::Problem(format!(
            "parameter {bad} does not exist in this robot"
        )));
    }
    if !(opts.noise_scale.is_finite() && opts.noise_scale > 0.0) {
        return Err(Error::InvalidOption {
            setting: crate::error::Setting::NoiseScale,
            message: format!(
                "expected a positive multiple of the stated sigmas, got {}",
                opts.noise_scale
            ),
        });
    }
    Ok(params)
}

/// The links and sites at beta = +-90 deg whose alpha and gamma are both analysed and felt by
/// some measurement: a singularity of the Euler parameterisation, not a physical redundancy.
fn euler_singular_frames(
    robot: &Robot,
    params: &[ParamId],
    unobservable: &[ParamId],
) -> Vec<String> {
    let felt = |k: ParamKind| {
        let id = robot.param_id(k);
        params.contains(&id) && !unobservable.contains(&id)
    };
    let locked = |beta: f64, alpha: ParamKind, gamma: ParamKind| {
        beta.cos().abs() < 1e-3 && felt(alpha) && felt(gamma)
    };
    let links = robot.links.iter().enumerate().filter(|(i, l)| {
        let c = |component| ParamKind::Link {
            link: *i,
            component,
        };
        locked(l.beta, c(LinkComponent::Alpha), c(LinkComponent::Gamma))
    });
    let sites = robot.sites.iter().enumerate().filter(|(k, s)| {
        let c = |component| ParamKind::Site {
            site: *k,
            component,
        };
        locked(
            s.frame.beta,
            c(LinkComponent::Alpha),
            c(LinkComponent::Gamma),
        )
    });
    links
        .map(|(i, _)| format!("link{}", i + 1))
        .chain(sites.map(|(_, s)| format!("site.{}", s.name)))
        .collect()
}

/// A number with 6 significant digits and no trailing zeros.
pub fn fmt_sig(v: f64) -> String {
    let s = format!("{:.6}", v);
    let s = if v != 0.0 && v.abs() < 1e-3 {
        format!("{v:.4e}")
    } else {
        s
    };
    if s.contains('.') && !s.contains('e') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}
