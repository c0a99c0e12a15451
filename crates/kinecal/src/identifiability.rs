//! Identifiability (thesis 3.4, 4.4.2-4.4.8): what the data can and cannot determine.
//!
//! Everything here works on the Jacobian of the estimated parameters over a dataset, in two
//! unit systems:
//! - *scaled*: residuals weighted by the measurement standard deviations and every column divided
//!   by its norm, the space the solvers work in (see [`crate::estimation`]); ranks, gaps and
//!   dependencies are decided here, where units cannot distort them;
//! - *file*: rows in the robot file's length and angle units, columns per unit of each parameter,
//!   as the thesis prints its Tables 4.3-4.7.
//!
//! ```
//! use kinecal::{examples, simulate, identifiability::{analyze, AnalysisOptions}};
//! let robot = examples::ge_a4();
//! let data = simulate::measure(&robot, &simulate::sample_postures(&robot, 30, 1), false);
//! let all: Vec<_> = robot.param_ids().collect();
//! let a = analyze(&robot, &data, &all, &AnalysisOptions::default()).unwrap();
//! assert_eq!(a.rank, 24); // 5 nr + 3 np + 6 (eq. 4.2)
//! assert_eq!(a.expected.unwrap().rank, 24);
//! ```

use crate::error::{Error, Result};
use crate::kinematics::Target;
use crate::linalg::{self, Matrix, QrAccumulator, RowSink, QR_BLOCK};
use crate::observe::{Anchoring, Dataset, OrientationError, RowQuantity, Weights};
use crate::params::{LinkComponent, ParamId, ParamKind, PlaneComponent};
use crate::problem::{Linearized, Problem};
use crate::robot::{JointKind, Robot};
use crate::units::Quantity;
use crate::warning::Warning;

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
    /// [`crate::problem`]) count as information: the rank, the null space, what is determined
    /// and the covariance are those of the data and the prior together, and
    /// [`Analysis::determined_by_data`] says what the data alone determines.
    pub prior: crate::robot::Prior,
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
            prior: crate::robot::Prior::default(),
        }
    }
}

/// The rank the thesis's formulas predict (eqs. 4.2, 4.3, 4.5).
#[derive(Debug, Clone, PartialEq)]
pub struct ExpectedRank {
    /// The predicted number of independent parameters.
    pub rank: usize,
    /// How it was computed, e.g. `4*4 + 2*1 ... `.
    pub formula: String,
}

/// A set of parameters whose Jacobian columns are equal or opposite at every posture (thesis
/// 4.4.3): the data determines only one combination of them.
#[derive(Debug, Clone, PartialEq)]
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
    pub omitted: usize,
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
    pub column_norms: Vec<f64>,
    /// Right singular vectors of the scaled Jacobian (n x n), in the order of the singular
    /// values: columns `rank..` span the null space.
    pub right_singular_vectors: Matrix,
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

    /// Whether parameter `id` (one of the analysed) is individually determined.
    pub fn is_determined(&self, id: ParamId) -> bool {
        self.parameters
            .iter()
            .position(|&p| p == id)
            .is_some_and(|k| self.determined[k])
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

/// The default preference for the identifiable set (thesis 4.4.3 and 4.4.7: keep parameters
/// that carry physical meaning): joint offsets, then slopes, then link lengths and angles that
/// are non-zero in the nominal model, then zero-valued link components (redundant copies), then
/// site parameters. Earlier is preferred.
pub fn default_priority(robot: &Robot) -> Vec<ParamId> {
    let mut ids: Vec<ParamId> = robot.param_ids().collect();
    ids.sort_by_key(|&id| (default_tier(robot, id), id));
    ids
}

/// The thesis's predicted rank for estimating `params` on `data`, generalised to coupled joints,
/// planes and observations that do not fix the robot's placement; `None` when its assumptions
/// fail.
///
/// Assumptions: every link parameter and joint offset on the way to an observed frame estimated,
/// the six parameters of every observed site estimated (of a frame observed only as a point,
/// its position parameters suffice), and each plane touched either fully estimated or fully
/// fixed. Then each revolute joint that some observed frame hangs past contributes 4, each such
/// prismatic one 2 (eq. 4.3; in a tree, a branch no observation sees contributes nothing, and
/// the shared joints count once), each estimated slope or coupling factor 1 (eq. 4.2), each
/// observed frame 6 when a pose of it
/// is measured or 3 when only its origin is (positions, distances, contacts; eq. 4.5), and each
/// estimated plane 3. From this, the motions of the whole world that change no observation are
/// subtracted: none when some observation is in the global frame (poses, positions); otherwise
/// the rigid motions that keep every fixed plane touched in place: 6 with none (distances
/// only), 3 with one normal direction (slides in the plane and turns about its normal), 1 with
/// two (slides along their intersection), 0 with three independent normals.
pub fn expected_rank(robot: &Robot, data: &Dataset, params: &[ParamId]) -> Option<ExpectedRank> {
    let has = |id: ParamId| params.binary_search(&id).is_ok();
    let (nl, nj) = (robot.links.len(), robot.dof());
    // The degrees of freedom observed of a frame (0, 3 or 6).
    let seen = |t: Target| {
        data.observations
            .iter()
            .filter(|o| o.measured_frame().0 == t)
            .map(|o| o.measured_frame().1)
            .max()
            .unwrap_or(0)
    };
    // A frame observed as a point needs only its position parameters: its angles change nothing.
    let needed = |dof: usize, c: LinkComponent| dof == 6 || c.quantity() == Quantity::Length;
    let ee = seen(Target::EndEffector);
    // The joints some observed frame hangs past (all of them for a serial robot whose end
    // effector is observed): in a tree, a branch no observation sees adds nothing.
    let mut observed = vec![false; nj];
    let mut any = false;
    for t in std::iter::once(Target::EndEffector).chain((0..robot.sites.len()).map(Target::Site)) {
        if seen(t) > 0 {
            any = true;
            let path = robot.path_to(crate::kinematics::target_joint(robot, t));
            for (o, p) in observed.iter_mut().zip(path) {
                *o |= p;
            }
        }
    }
    let link_observed = |i: usize| observed.get(i).copied().unwrap_or(ee > 0);
    let all_links = (0..6 * nl).all(|i| {
        has(ParamId(i))
            || !link_observed(i / 6)
            || (i / 6 == nl - 1 && !needed(ee, LinkComponent::ALL[i % 6]))
    });
    let all_offsets = (0..nj)
        .filter(|&j| observed[j])
        .all(|j| has(robot.param_id(ParamKind::Offset { joint: j })));
    if !(all_links && all_offsets && any) {
        return None;
    }
    let nr = (0..nj)
        .filter(|&j| observed[j] && robot.joints[j].kind == JointKind::Revolute)
        .count();
    let np = (0..nj).filter(|&j| observed[j]).count() - nr;
    let slopes = (0..nj)
        .filter(|&j| observed[j] && has(robot.param_id(ParamKind::Slope { joint: j })))
        .count();
    let couplings = robot
        .coupled_joints()
        .filter(|&j| observed[j] && has(robot.param_id(ParamKind::Coupling { joint: j })))
        .count();
    let mut frames = Vec::new();
    let mut targets: Vec<Target> = vec![Target::EndEffector];
    targets.extend((0..robot.sites.len()).map(Target::Site));
    for t in targets {
        let dof = seen(t);
        if dof == 0 {
            continue;
        }
        if let Target::Site(s) = t {
            let all = LinkComponent::ALL.iter().all(|&component| {
                has(robot.param_id(ParamKind::Site { site: s, component }))
                    || !needed(dof, component)
            });
            if !all {
                return None;
            }
        }
        frames.push(dof);
    }
    let mut absolute = false;
    let mut touched: Vec<usize> = Vec::new();
    for o in &data.observations {
        match o.anchoring() {
            Anchoring::Absolute => absolute = true,
            Anchoring::Relative => {}
            Anchoring::Plane(k) => {
                if !touched.contains(&k) {
                    touched.push(k);
                }
            }
        }
    }
    touched.sort();
    let mut estimated_planes = 0;
    let mut fixed_normals = Vec::new();
    for &k in &touched {
        let n = PlaneComponent::ALL
            .iter()
            .filter(|&&component| {
                has(robot.param_id(ParamKind::Plane {
                    plane: k,
                    component,
                }))
            })
            .count();
        match n {
            3 => estimated_planes += 1,
            0 => fixed_normals.push(robot.planes[k].normal()),
            _ => return None,
        }
    }
    let free_motions = if absolute {
        0
    } else {
        match independent_directions(&fixed_normals) {
            0 => 6,
            1 => 3,
            2 => 1,
            _ => 0,
        }
    };
    let positive =
        4 * nr + 2 * np + slopes + couplings + frames.iter().sum::<usize>() + 3 * estimated_planes;
    let rank = positive.checked_sub(free_motions)?;
    let frame_terms: Vec<String> = frames.iter().map(|f| f.to_string()).collect();
    let mut formula = format!(
        "4*{nr} (revolute) + 2*{np} (prismatic) + {slopes} (slopes) + {} (observed frames: 6 per pose, 3 per point)",
        frame_terms.join(" + ")
    );
    if couplings > 0 {
        formula.push_str(&format!(" + {couplings} (couplings)"));
    }
    if estimated_planes > 0 {
        formula.push_str(&format!(" + 3*{estimated_planes} (planes)"));
    }
    if free_motions > 0 {
        formula.push_str(&format!(
            " - {free_motions} (motions of the world no observation sees: {})",
            match free_motions {
                6 => "no observation in the global frame",
                3 => "sliding in the touched plane and turning about its normal",
                _ => "sliding along the touched planes' intersection",
            }
        ));
    }
    formula.push_str(&format!(" = {rank}"));
    Some(ExpectedRank { rank, formula })
}

/// The number of linearly independent directions among unit vectors (0 to 3).
fn independent_directions(normals: &[nalgebra::Vector3<f64>]) -> usize {
    let Some(a) = normals.first() else { return 0 };
    let Some(b) = normals.iter().find(|n| a.cross(n).norm() > 1e-6) else {
        return 1;
    };
    let c = a.cross(b);
    if normals.iter().any(|n| c.dot(n).abs() > 1e-6 * c.norm()) {
        3
    } else {
        2
    }
}

/// Analyses what `data` determines about `params` of `robot`.
pub fn analyze(
    robot: &Robot,
    data: &Dataset,
    params: &[ParamId],
    opts: &AnalysisOptions,
) -> Result<Analysis> {
    analyze_with(robot, data, params, opts, None, true).map(|(a, _)| a)
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
    analyze_with(robot, data, params, opts, None, false).map(|(a, _)| a)
}

/// [`analyze_core`], keeping the linearisation it made at `robot` (for a solver that starts
/// there: its first evaluation then costs no pass).
pub(crate) fn analyze_linearized(
    robot: &Robot,
    data: &Dataset,
    params: &[ParamId],
    opts: &AnalysisOptions,
) -> Result<(Analysis, Linearized)> {
    let (analysis, lin) = analyze_with(robot, data, params, opts, None, false)?;
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
    analyze_with(robot, data, params, opts, Some((raug, None)), false).map(|(a, _)| a)
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
    analyze_with(robot, data, &lin.params, opts, known, false).map(|(a, _)| a)
}

fn analyze_with(
    robot: &Robot,
    data: &Dataset,
    params: &[ParamId],
    opts: &AnalysisOptions,
    known_r: Option<(&Matrix, Option<&[f64]>)>,
    display: bool,
) -> Result<(Analysis, Option<Linearized>)> {
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
    let n = params.len();
    data.check_orientation(robot, opts.orientation)?;
    let problem = Problem::new(robot, data, &params, opts.weights, opts.orientation);
    let m = problem.rows();
    // The weighted Jacobian is never held: its rows go into the R of a QR, a block at a time
    // (the same inner products between columns, n long instead of m; memory flat in m). A
    // block at least n rows long keeps the folds' cost (a QR of R stacked on the block) within
    // a constant of the rows' own, O(m n^2), however many parameters.
    let mut r = Vec::new();
    let mut acc = QrAccumulator::new(n + 1, QR_BLOCK.max(n + 1));
    let mut raug = Matrix::zeros(0, 0);
    let mut accuracy = None;
    let clamp = row_clamp(data, &problem);
    // e_j, and whether it is exact (from the rows) or the bound from the column norms.
    let mut typical: Option<Vec<f64>> = None;
    match known_r {
        Some((known, e)) if known.nrows() == n + 1 && known.ncols() == n + 1 => {
            raug = known.clone();
            match e {
                Some(e) if e.len() == n => typical = Some(e.to_vec()),
                Some(_) => {
                    return Err(Error::Numerical(
                        "the given typical-row information does not match the parameters analysed"
                            .into(),
                    ))
                }
                None => {}
            }
        }
        Some(_) => {
            return Err(Error::Numerical(
                "the given R does not match the parameters analysed".into(),
            ))
        }
        None => {
            r.resize(m, 0.0);
            acc.clear();
            let mut tally = TypicalRowTally {
                acc: &mut acc,
                clamp: &clamp,
                row: 0,
                sums: vec![0.0; n],
            };
            accuracy = Some(problem.evaluate_rows_checked(robot, &mut r, &mut tally).1);
            let mf = m.max(1) as f64;
            typical = Some(tally.sums.iter().map(|s| (s / mf).sqrt()).collect());
            acc.r_into(&mut raug);
        }
    }
    // With a prior, its rows folded in: the analysis is of the data and the prior together,
    // and what the data alone determines is decided on the data's R.
    let with_prior = problem.clone().with_prior(&opts.prior);
    let prior_rows = with_prior.prior_rows();
    let data_only = (prior_rows > 0).then(|| data_determined(&raug, n, opts.rcond));
    let raug_all = with_prior.with_prior_rows(&raug);
    // R of [W J | W r]: its leading n x n block is the R of W J alone.
    let rw = Matrix::from_fn(n, n, |i, j| raug_all[(i, j)]);

    let units = robot.units;
    let col_factor: Vec<f64> = params
        .iter()
        .map(|&id| units.factor(robot.param_quantity(id)))
        .collect();

    let column_norms: Vec<f64> = (0..n).map(|j| linalg::col_norm(&rw, j)).collect();
    let max_norm = column_norms.iter().copied().fold(0.0, f64::max);
    let unfelt: Vec<bool> = column_norms
        .iter()
        .map(|&c| c <= 1e-12 * max_norm.max(1e-300))
        .collect();
    let unobservable: Vec<ParamId> = (0..n).filter(|&j| unfelt[j]).map(|j| params[j]).collect();
    let mut r_scaled = rw;
    for (j, &c) in column_norms.iter().enumerate() {
        // Unobservable columns hold only rounding noise: zero them rather than blow it up.
        let s = if unfelt[j] { 0.0 } else { 1.0 / c };
        linalg::scale_col(&mut r_scaled, j, s);
    }
    // Singular values and right vectors of the scaled Jacobian are those of its R (n x n).
    let (s_scaled, v_scaled, _) = linalg::right_svd(&r_scaled)
        .ok_or_else(|| Error::Numerical("SVD did not converge".into()))?;
    let sv_file = if display {
        // The Jacobian in file units: rows back from weighted to file units, columns to the
        // file's units; a second pass, again through a QR's R only.
        let row_scale = file_row_scale(robot, data, &problem);
        let fp = problem.with_row_scale(&row_scale);
        r.resize(m, 0.0);
        acc.clear();
        fp.evaluate_qr(robot, &mut r, &mut acc);
        acc.r_into(&mut raug);
        let rf = Matrix::from_fn(n, n, |i, j| raug[(i, j)] * col_factor[j]);
        linalg::singular_values_qr(&rf)
            .ok_or_else(|| Error::Numerical("SVD did not converge".into()))?
    } else {
        Vec::new()
    };
    let s = &s_scaled;
    let smax = s.first().copied().unwrap_or(0.0);
    let rank = s.iter().filter(|&&v| v > opts.rcond * smax).count();
    // The largest gap, on a log scale, between consecutive singular values.
    // Values below the rounding level of the SVD are all "zero": clamp them there, so that
    // the gap between two rounding-level values (or an exact 0) is not taken for the real one.
    let floor = f64::EPSILON * smax * m.max(n) as f64;
    let (mut gap_rank, mut gap_ratio) = (s.len(), 1.0);
    for i in 0..s.len().saturating_sub(1) {
        let (a, b) = (s[i].max(floor), s[i + 1].max(floor));
        let ratio = if b > 0.0 { a / b } else { f64::INFINITY };
        if ratio > gap_ratio {
            gap_rank = i + 1;
            gap_ratio = ratio;
        }
    }
    let mut warnings = Vec::new();
    // The tolerance and the largest gap disagree: below full rank, whenever they differ; at
    // full rank, when the spectrum has a clear gap (over 1e3) somewhere else.
    let rank_consistent = gap_rank == rank || (rank == n && gap_ratio <= 1e3);
    if !rank_consistent {
        warnings.push(Warning::UnclearRank {
            rank,
            rcond: opts.rcond,
            gap_rank,
            gap_ratio,
        });
    } else if rank < n && gap_ratio < 1e4 {
        warnings.push(Warning::SmallGap { rank, gap_ratio });
    } else if rank == n && smax > 0.0 && s[n - 1] / smax < 1e-6 {
        warnings.push(Warning::BarelyDetermined {
            ratio: s[n - 1] / smax,
        });
    }

    // Null space (scaled coordinates) and which parameters it touches.
    let null: Vec<Vec<f64>> = (rank..n)
        .map(|k| (0..n).map(|j| v_scaled[(j, k)]).collect())
        .collect();
    let determined: Vec<bool> = (0..n)
        .map(|j| null.iter().map(|v| v[j] * v[j]).sum::<f64>().sqrt() < 1e-6)
        .collect();
    let (data_rank, determined_by_data) = data_only.unwrap_or_else(|| (rank, determined.clone()));

    // Identical redundancies: equal or opposite unit columns.
    let mut group_of: Vec<Option<usize>> = vec![None; n];
    let mut groups: Vec<Vec<(usize, f64)>> = Vec::new();
    // R is upper triangular: a column's entries below its last non-zero one add nothing to an
    // inner product (a third of the work of full columns, over all pairs).
    let height: Vec<usize> = (0..n)
        .map(|j| {
            r_scaled
                .col(j)
                .iter()
                .rposition(|&x| x != 0.0)
                .map_or(0, |k| k + 1)
        })
        .collect();
    for i in 0..n {
        if group_of[i].is_some() || column_norms[i] == 0.0 || unfelt[i] {
            continue;
        }
        let mut g = vec![(i, 1.0)];
        for j in i + 1..n {
            if group_of[j].is_some() || unfelt[j] {
                continue;
            }
            // On R's columns: the same inner products as the Jacobian's, n long instead of m.
            let h = height[i].min(height[j]);
            let dot = dot(&r_scaled.col(i)[..h], &r_scaled.col(j)[..h]);
            if (dot.abs() - 1.0).abs() < 1e-10 {
                g.push((j, dot.signum()));
            }
        }
        if g.len() > 1 {
            for &(j, _) in &g {
                group_of[j] = Some(groups.len());
            }
            groups.push(g);
        }
    }
    // Null space in file units, for estimability checks and the reduced form below.
    let file_null: Vec<Vec<f64>> = null
        .iter()
        .map(|v| {
            (0..n)
                .map(|j| {
                    if column_norms[j] > 0.0 {
                        v[j] / column_norms[j] / col_factor[j]
                    } else {
                        v[j]
                    }
                })
                .collect()
        })
        .collect();
    let file_norm = |j: usize| column_norms[j] * col_factor[j];
    let identical_groups = groups
        .iter()
        .map(|g| {
            let first = g[0].0;
            let terms: Vec<(ParamId, f64)> = g
                .iter()
                .map(|&(j, sign)| (params[j], tidy_coef(sign * file_norm(j) / file_norm(first))))
                .collect();
            let value = terms.iter().map(|&(id, c)| c * robot.get_user(id)).sum();
            // Determined iff the combination does not change along any undetermined direction.
            let determined = file_null.iter().all(|nv| {
                let along: f64 = g
                    .iter()
                    .zip(&terms)
                    .map(|(&(j, _), &(_, c))| c * nv[j])
                    .sum();
                let scale: f64 = g
                    .iter()
                    .zip(&terms)
                    .map(|(&(j, _), &(_, c))| (c * nv[j]).abs())
                    .sum::<f64>()
                    + nv.iter().map(|x| x.abs()).fold(0.0, f64::max);
                along.abs() <= 1e-8 * scale
            });
            IdenticalGroup {
                terms,
                value,
                determined,
            }
        })
        .collect();

    // Identifiable set: by priority, column pivoting within each priority tier.
    let (order, tiers) = priority_order(robot, &params, &opts.priority);
    // e_j: from the rows when they were at hand, else its lower bound from the column norms
    // (exact when no row's weight is clamped).
    let least_clamp = clamp.iter().copied().fold(1.0, f64::min);
    let exact_typical = typical.is_some() || least_clamp >= 1.0;
    let typical = typical.unwrap_or_else(|| {
        let root_m = (m.max(1) as f64).sqrt();
        column_norms
            .iter()
            .map(|c| least_clamp * c / root_m)
            .collect()
    });
    // The noise-scaled columns a_j / e_j are the unit columns times |a_j| / e_j.
    let gain: Vec<f64> = (0..n)
        .map(|j| {
            let g = column_norms[j] / typical[j];
            if unfelt[j] || !g.is_finite() {
                0.0
            } else {
                g
            }
        })
        .collect();
    // The noise threshold of each column, in the gained metric: below one typical row's worth
    // (r_jj < e_j) and so loosely determined that its standard deviation given the columns
    // chosen before it, 1 / r_jj = 1 / (ratio e_j), exceeds LOOSE of its scale.
    let threshold: Vec<f64> = (0..n)
        .map(|j| {
            let id = params[j];
            let scale = match robot.param_kind(id) {
                ParamKind::Slope { .. } | ParamKind::Coupling { .. } => robot.get(id).abs(),
                _ => match robot.param_quantity(id) {
                    Quantity::Length => robot.reach(),
                    _ => 1.0,
                },
            };
            let loose = opts.noise_scale / (LOOSE * typical[j] * scale);
            if loose.is_finite() {
                loose
            } else {
                0.0
            }
        })
        .collect();
    // On R's columns (n long, the same inner products as the scaled Jacobian's m-long ones).
    // A parameter chosen early (a high tier) is judged given only the columns before it: given
    // the whole set, it may be as loose as the rule forbids (a joint offset and a link length
    // one the same lever at the noise). Then the loosest of those goes, and the set is chosen
    // again without it.
    let mut threshold = threshold;
    // Of the loose ones, the least preferred goes (its partner in the near-dependence, if any,
    // is then judged again without it): priorities decide, as they do in the pivoting.
    let rank_of: Vec<usize> = {
        let mut r = vec![usize::MAX; n];
        for (k, &j) in order.iter().enumerate() {
            r[j] = r[j].min(k);
        }
        r
    };
    let loose_given_all = |chosen: &[usize], threshold: &[f64]| -> Option<(usize, f64)> {
        let sigma = linalg::marginal_sigmas(&r_scaled, chosen);
        chosen
            .iter()
            .zip(&sigma)
            .filter(|&(&j, &s)| {
                // Given all the others, a unit column's remaining norm is 1 / s (s its
                // standard deviation on unit columns): gain[j] / s in the gained metric.
                gain[j] / s < threshold[j]
            })
            .max_by_key(|&(&j, _)| (tiers[j], rank_of[j]))
            .map(|(&j, &s)| (j, s / column_norms[j]))
    };
    let mut base = select_base(
        &r_scaled,
        &gain,
        &order,
        &tiers,
        rank,
        opts.rcond * smax,
        &threshold,
    );
    // The standard deviation (internal units) of those left out given the whole set.
    let mut loose_sigma: Vec<Option<f64>> = vec![None; n];
    for _ in 0..n {
        let Some((j, sigma)) = loose_given_all(&base.chosen, &threshold) else {
            break;
        };
        threshold[j] = f64::INFINITY;
        loose_sigma[j] = Some(sigma);
        base = select_base(
            &r_scaled,
            &gain,
            &order,
            &tiers,
            rank,
            opts.rcond * smax,
            &threshold,
        );
    }
    let mut identifiable: Vec<ParamId> = base.chosen.iter().map(|&j| params[j]).collect();
    identifiable.sort();
    let noise_dependent: Vec<NoiseDependent> = base
        .noise
        .iter()
        .map(|d| {
            // a_j / e_j ~= sum c_l a_k / e_k: per file unit, c_l (e_j / e_k) (f_j / f_k); on
            // unit columns, c_l (e_j / e_k) (|a_k| / |a_j|).
            let j = d.column;
            let mut terms: Vec<(usize, f64, f64)> = base
                .chosen
                .iter()
                .zip(&d.coef)
                .map(|(&k, &c)| {
                    let raw = c * typical[j] / typical[k];
                    (
                        k,
                        raw * col_factor[j] / col_factor[k],
                        raw * column_norms[k] / column_norms[j],
                    )
                })
                .filter(|t| t.2 != 0.0)
                .collect();
            terms.sort_by(|a, b| b.2.abs().total_cmp(&a.2.abs()).then(a.0.cmp(&b.0)));
            let big = terms.first().map_or(0.0, |t| t.2.abs());
            let shown = terms
                .iter()
                .take(COMBINATION_TERMS)
                .take_while(|t| t.2.abs() >= COMBINATION_SHARE * big)
                .count();
            NoiseDependent {
                id: params[j],
                ratio: d.ratio,
                sigma: robot.units.from_si(
                    robot.param_quantity(params[j]),
                    opts.noise_scale * loose_sigma[j].unwrap_or(1.0 / (d.ratio * typical[j])),
                ),
                sine: d.ratio / gain[j],
                terms: terms[..shown]
                    .iter()
                    .map(|&(k, c, _)| (params[k], tidy_coef(c)))
                    .collect(),
                omitted: terms.len() - shown,
            }
        })
        .collect();
    let noise_rule = noise_rule_words(m, exact_typical, opts.noise_scale);

    // Null space in reduced form, pivots on the least preferred parameters, in file units.
    let reverse: Vec<usize> = order.iter().rev().copied().collect();
    let null_space = reduced_form(&file_null, &reverse)
        .into_iter()
        .map(|row| {
            row.into_iter()
                .map(|(j, c)| (params[j], tidy_coef(c)))
                .collect()
        })
        .collect();

    // A frame at beta = +-90 deg matters only when its alpha and gamma are both analysed and
    // felt by some measurement.
    let felt = |k: ParamKind| {
        let id = robot.param_id(k);
        params.contains(&id) && !unobservable.contains(&id)
    };
    let euler_singular = robot
        .links
        .iter()
        .enumerate()
        .filter(|(i, l)| {
            l.beta.cos().abs() < 1e-3
                && felt(ParamKind::Link {
                    link: *i,
                    component: LinkComponent::Alpha,
                })
                && felt(ParamKind::Link {
                    link: *i,
                    component: LinkComponent::Gamma,
                })
        })
        .map(|(i, _)| format!("link{}", i + 1))
        .chain(
            robot
                .sites
                .iter()
                .enumerate()
                .filter(|(k, s)| {
                    s.frame.beta.cos().abs() < 1e-3
                        && felt(ParamKind::Site {
                            site: *k,
                            component: LinkComponent::Alpha,
                        })
                        && felt(ParamKind::Site {
                            site: *k,
                            component: LinkComponent::Gamma,
                        })
                })
                .map(|(_, s)| format!("site.{}", s.name)),
        )
        .collect::<Vec<_>>();
    for name in &euler_singular {
        warnings.push(Warning::EulerSingular {
            frame: name.clone(),
        });
    }

    let lin = accuracy.map(|accuracy| Linearized {
        params: params.clone(),
        r: raug,
        typical_row: typical.clone(),
        accuracy,
    });
    let analysis = Analysis {
        expected: expected_rank(robot, data, &params),
        parameters: params,
        residuals: m + prior_rows,
        prior_rows,
        singular_values_scaled: s.clone(),
        singular_values_file: sv_file,
        rank,
        rcond: opts.rcond,
        gap_rank,
        gap_ratio,
        rank_consistent,
        unobservable,
        identical_groups,
        null_space,
        identifiable,
        noise_dependent,
        noise_rule,
        typical_row: typical,
        determined,
        determined_by_data,
        data_rank,
        euler_singular,
        warnings,
        column_norms,
        right_singular_vectors: v_scaled,
    };
    Ok((analysis, lin))
}

/// The rank of the data alone and, per parameter, whether it determines it individually, from
/// the `R` (`(n + 1)` square, the residual last) of the data's weighted `[J | r]`: the same rule
/// as the analysis's (scaled columns, rank at `rcond`, no component in the null space).
fn data_determined(raug: &Matrix, n: usize, rcond: f64) -> (usize, Vec<bool>) {
    let mut rs = Matrix::from_fn(n, n, |i, j| raug[(i, j)]);
    let norms: Vec<f64> = (0..n).map(|j| linalg::col_norm(&rs, j)).collect();
    let max = norms.iter().copied().fold(0.0, f64::max);
    for (j, &c) in norms.iter().enumerate() {
        let s = if c <= 1e-12 * max.max(1e-300) {
            0.0
        } else {
            1.0 / c
        };
        linalg::scale_col(&mut rs, j, s);
    }
    let Some((sv, v, _)) = linalg::right_svd(&rs) else {
        return (0, vec![false; n]);
    };
    let smax = sv.first().copied().unwrap_or(0.0);
    let rank = sv.iter().filter(|&&x| x > rcond * smax).count();
    let determined = (0..n)
        .map(|j| (rank..n).map(|k| v[(j, k)] * v[(j, k)]).sum::<f64>().sqrt() < 1e-6)
        .collect();
    (rank, determined)
}

/// Per row of `problem`, the factor from its weighted residual to file units (its sigma in
/// the file's length or angle unit).
fn file_row_scale(robot: &Robot, data: &Dataset, problem: &Problem<'_>) -> Vec<f64> {
    let units = robot.units;
    let sigma = problem.row_sigma();
    let mut scale = Vec::with_capacity(problem.rows());
    for o in &data.observations {
        for row in o.rows() {
            let i = scale.len();
            scale.push(match row.quantity {
                RowQuantity::Length => sigma[i] / units.length.metres(),
                RowQuantity::Angle => sigma[i] / units.angle.radians(),
            });
        }
    }
    scale
}

/// The Jacobian of an [`Analysis`], row by row, for display (`kinecal analyze --print`): an
/// m x n matrix and a label per row, so build it only to show it; the analysis itself never
/// holds it.
#[derive(Debug, Clone)]
pub struct JacobianTable {
    /// Per row: posture label(s) (`a&b` for a pair), target, row label.
    pub row_labels: Vec<(String, String, &'static str)>,
    /// The scaled Jacobian `W J D^-1` (unit columns; unfelt columns zeroed), as analysed.
    pub scaled: Matrix,
    /// The Jacobian in file units: rows in the file's length or angle unit per the parameter's
    /// file unit.
    pub file: Matrix,
}

/// The Jacobian that `analysis` (of `data` on `robot`, with `opts`) analysed, for display.
pub fn jacobian_table(
    robot: &Robot,
    data: &Dataset,
    analysis: &Analysis,
    opts: &AnalysisOptions,
) -> JacobianTable {
    let params = &analysis.parameters;
    let problem = Problem::new(robot, data, params, opts.weights, opts.orientation);
    let (m, n) = (problem.rows(), params.len());
    let mut r = vec![0.0; m];
    let mut jw = Matrix::zeros(m, n);
    problem.evaluate(robot, &mut r, Some(&mut jw));
    let mut row_labels = Vec::with_capacity(m);
    for o in &data.observations {
        let postures: Vec<&str> = o
            .views()
            .iter()
            .map(|v| data.postures[v.posture].label.as_str())
            .collect();
        let postures = postures.join("&");
        let site = crate::observe::target_name(robot, o.target()).to_string();
        for row in o.rows() {
            row_labels.push((postures.clone(), site.clone(), row.label));
        }
    }
    let row_scale = file_row_scale(robot, data, &problem);
    let units = robot.units;
    let col_factor: Vec<f64> = params
        .iter()
        .map(|&id| units.factor(robot.param_quantity(id)))
        .collect();
    let file = Matrix::from_fn(m, n, |i, j| jw[(i, j)] * row_scale[i] * col_factor[j]);
    let scaled = Matrix::from_fn(m, n, |i, j| {
        let c = analysis.column_norms[j];
        if analysis.unobservable.contains(&params[j]) || c <= 0.0 {
            0.0
        } else {
            jw[(i, j)] / c
        }
    });
    JacobianTable {
        row_labels,
        scaled,
        file,
    }
}

/// Rounds coefficients within 1e-9 of an integer to it, and drops float noise.
fn tidy_coef(c: f64) -> f64 {
    let r = c.round();
    if (c - r).abs() < 1e-9 {
        r
    } else {
        c
    }
}

/// A candidate is left out when its standard deviation given the columns chosen before it (at
/// the stated weights) exceeds this share of its scale: 0.02 rad (1.1 deg) for an angle, 2 % of the
/// robot's reach for a length, 2 % of its value for a slope or a coupling factor. Estimates
/// that loose are meaningless, and the solver crawls along their valleys (a probe 0.3 mm off
/// the last joint's axis leaves that joint's offset and the last link's attitude determined to
/// 0.05-0.1 rad only); parameters near-dependent but determined to well under a degree (a
/// FANUC R-2000iC's base tilt against its first offset, 0.009 rad) still help held out.
const LOOSE: f64 = 0.02;

/// Near-combinations show at most this many terms...
const COMBINATION_TERMS: usize = 4;
/// ...each at least this share of the largest (on unit-norm columns).
const COMBINATION_SHARE: f64 = 0.05;

/// Remaining norms within this relative distance of the largest are a tie, won by the column
/// earliest in the priority order: far above the rounding of norms computed afresh
/// (identical columns of `R` differ by a few ulps of their original norm), far below any
/// difference that means something.
const TIE: f64 = 1e-9;

/// Downdated norms within this relative distance of the largest are computed afresh before a
/// pivot is chosen: downdating keeps a norm to about `sqrt(eps)` ~ 1.5e-8 relative (it is
/// recomputed when cancellation would cost more), so a tie at [`TIE`] must be decided on
/// norms computed afresh, and 1e-6 leaves a margin of about 70.
const NEAR: f64 = 1e-6;

/// `x . y`, four partial sums (the order of a dot product's rounding is immaterial here).
fn dot(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len().min(y.len());
    let (x, y) = (&x[..n], &y[..n]);
    let mut acc = [0.0f64; 4];
    let mut cx = x.chunks_exact(4);
    let mut cy = y.chunks_exact(4);
    for (a, b) in (&mut cx).zip(&mut cy) {
        for k in 0..4 {
            acc[k] += a[k] * b[k];
        }
    }
    let tail: f64 = cx
        .remainder()
        .iter()
        .zip(cy.remainder())
        .map(|(a, b)| a * b)
        .sum();
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

/// Per row of `problem` (in row order), `min(1, w_med / w_i)`: the factor that clamps the
/// row's weight `w_i = 1 / sigma_i` at `w_med`, the (lower) median weight of the rows of the
/// same quantity. Per quantity, because comparing a length row's weight (1/m) with an angle
/// row's (1/rad) would depend on the internal units; the lower median, so that of two equally
/// common weights the larger is the one clamped.
fn row_clamp(data: &Dataset, problem: &Problem<'_>) -> Vec<f64> {
    let sigma = problem.row_sigma();
    let mut quantity = Vec::with_capacity(sigma.len());
    for o in &data.observations {
        for row in o.rows() {
            quantity.push(row.quantity);
        }
    }
    let weight = |i: usize| 1.0 / sigma[i];
    let median = |q: RowQuantity| -> f64 {
        let mut w: Vec<f64> = (0..sigma.len())
            .filter(|&i| quantity.get(i) == Some(&q))
            .map(weight)
            .collect();
        if w.is_empty() {
            return f64::INFINITY;
        }
        let k = (w.len() - 1) / 2;
        *w.select_nth_unstable_by(k, f64::total_cmp).1
    };
    let (length, angle) = (median(RowQuantity::Length), median(RowQuantity::Angle));
    (0..sigma.len())
        .map(|i| {
            let med = match quantity.get(i) {
                Some(RowQuantity::Angle) => angle,
                _ => length,
            };
            let w = weight(i);
            // Written so that no pair of infinities or NaN makes a NaN: such a row counts 1.
            if w > med {
                med / w
            } else {
                1.0
            }
        })
        .collect()
}

/// A [`RowSink`] that passes each row `[J_i | r_i]` on to a QR accumulator and adds up, per
/// parameter column, the squares of the row's entries times its clamp factor: the sums
/// behind `e_j` ([`Analysis::typical_row`]), from the same pass that builds `R`.
struct TypicalRowTally<'a> {
    acc: &'a mut QrAccumulator,
    clamp: &'a [f64],
    row: usize,
    sums: Vec<f64>,
}

impl RowSink for TypicalRowTally<'_> {
    fn push(&mut self, row: &[f64]) {
        self.acc.push(row);
        let f = self.clamp.get(self.row).copied().unwrap_or(1.0);
        self.row += 1;
        for (s, &c) in self.sums.iter_mut().zip(row) {
            let v = c * f;
            *s += v * v;
        }
    }
}

/// The noise-level rule in words, for `m` rows; `exact` when `e_j` came from the rows.
fn noise_rule_words(m: usize, exact: bool, noise_scale: f64) -> String {
    let root = (m.max(1) as f64).sqrt();
    let mut s = format!(
        "a parameter is not determined at the noise level when, given the parameters chosen before \
         it (in priority order, then given the whole set), its standard deviation at the stated \
         weights, 1 / r_jj, exceeds 0.02 rad for an angle, 2 % of the robot's reach for a length, \
         2 % of its value for a slope or coupling factor; r_jj is its remaining weighted column \
         norm; columns are pivoted on a_j / e_j, e_j the RMS of the weighted column over the {m} \
         rows (each row's weight clamped at the median of its quantity; with uniform weights \
         r_jj / e_j = sqrt({m}) sin(angle to the chosen columns), sqrt({m}) = {})",
        fmt_sig(root)
    );
    if (noise_scale - 1.0).abs() > f64::EPSILON {
        s.push_str(&format!(
            "; judged at {} times the stated sigmas (the noise a fit's residuals showed)",
            fmt_sig(noise_scale)
        ));
    }
    if !exact {
        s.push_str(
            "; e_j bounded below from the column norms (the rows were not at hand): a lower \
             threshold, erring towards keeping parameters",
        );
    }
    s
}

/// A column left out as dependent within the noise by [`select_base`].
#[derive(Debug, Clone, PartialEq)]
struct NoiseColumn {
    column: usize,
    /// Its remaining norm at its pivot step, noise-scaled: `r_jj / e_j`.
    ratio: f64,
    /// Its regression on the chosen columns (in their pivot order), noise-scaled:
    /// `a_j / e_j ~= sum_l coef[l] a_chosen[l] / e_chosen[l]`.
    coef: Vec<f64>,
}

/// What [`select_base`] chose.
#[derive(Debug, Clone, PartialEq)]
struct BaseSelection {
    /// The chosen columns, in pivot order.
    chosen: Vec<usize>,
    /// The columns left out as dependent within the noise (not those dependent at the
    /// rounding level), in the order they were found.
    noise: Vec<NoiseColumn>,
}

/// The identifiable (base) set by a QR with column pivoting, in tiers: `units` holds the
/// unit-norm columns (or the `R` of their QR: the same inner products, fewer rows), `gain[j]`
/// the factor to the metric the pivots are chosen in (`|a_j| / e_j`, the noise-scaled column
/// `a_j / e_j`; 0 for a column not to consider), `order` the columns by preference (columns
/// not listed are not considered) and `tier[j]` each column's tier (lower first).
///
/// At each step the candidates are the columns of the lowest tier left; the pivot is the one
/// of largest remaining norm in the gained metric, ties (within [`TIE`], on norms computed
/// afresh) to the earliest in `order`. It is
/// - chosen when its remaining norm is at least `noise` and its remaining norm on the unit
///   columns (the sine of its angle to the chosen columns) exceeds the rounding tolerance
///   `tol` (and 1e-12);
/// - left out alone when it is within the rounding tolerance (dependent);
/// - below `noise`: then so is every candidate of the tier (the threshold is the same for all
///   in this metric) and the tier ends; those within the rounding tolerance are dependent,
///   the others dependent within the noise (reported, with their remaining norm and their
///   regression on the finally chosen columns).
///
/// It stops at `rank` chosen columns. Householder reflections, the remaining norms downdated
/// and computed afresh when cancellation has eaten half their digits (LAPACK's `dgeqp3`):
/// `O(rows n rank)`, `O(n^3)` on an n x n `R`. With `noise = 0` it is the greedy selection
/// of the rounding rule alone.
fn select_base(
    units: &Matrix,
    gain: &[f64],
    order: &[usize],
    tier: &[usize],
    rank: usize,
    tol: f64,
    noise: &[f64],
) -> BaseSelection {
    #[derive(Clone, Copy, PartialEq)]
    enum State {
        Candidate,
        Chosen,
        /// Left out as dependent within the noise: its column is still transformed, for its
        /// regression on the chosen ones at the end.
        Noise,
        /// Left out (dependent at the rounding level) or not considered.
        Out,
    }
    let (rows, n) = (units.nrows(), units.ncols());
    let tol = tol.max(1e-12);
    let mut state = vec![State::Out; n];
    let mut pref = vec![usize::MAX; n];
    for (k, &j) in order.iter().enumerate() {
        if j < n && pref[j] == usize::MAX && gain[j] > 0.0 && gain[j].is_finite() {
            pref[j] = k;
            state[j] = State::Candidate;
        }
    }
    // The working matrix: the gained columns, transformed step by step.
    let mut w = Matrix::from_fn(rows, n, |i, j| {
        if state[j] == State::Candidate {
            units[(i, j)] * gain[j]
        } else {
            0.0
        }
    });
    let norm_from = |w: &Matrix, j: usize, k: usize| {
        let c = &w.col(j)[k..];
        dot(c, c).sqrt()
    };
    let mut norms: Vec<f64> = (0..n).map(|j| norm_from(&w, j, 0)).collect();
    let mut exact = norms.clone();
    let mut chosen: Vec<usize> = Vec::new();
    let mut noisy: Vec<(usize, f64)> = Vec::new();
    let mut v = vec![0.0; rows];
    let tol3z = f64::EPSILON.sqrt();
    let mut tier_cands: Vec<usize> = Vec::with_capacity(n);
    while chosen.len() < rank && chosen.len() < rows {
        let k = chosen.len();
        let Some(t) = (0..n)
            .filter(|&j| state[j] == State::Candidate)
            .map(|j| tier[j])
            .min()
        else {
            break;
        };
        tier_cands.clear();
        tier_cands.extend((0..n).filter(|&j| state[j] == State::Candidate && tier[j] == t));
        // Near the largest, downdated norms are not accurate enough for ties: afresh.
        let big = tier_cands.iter().map(|&j| norms[j]).fold(0.0, f64::max);
        for &j in &tier_cands {
            if norms[j] >= big * (1.0 - NEAR) {
                norms[j] = norm_from(&w, j, k);
                exact[j] = norms[j];
            }
        }
        let big = tier_cands.iter().map(|&j| norms[j]).fold(0.0, f64::max);
        let Some(p) = tier_cands
            .iter()
            .copied()
            .filter(|&j| norms[j] >= big * (1.0 - TIE))
            .min_by_key(|&j| pref[j])
        else {
            // Only NaN norms (a column of NaN): nothing in this tier can be chosen.
            for &j in &tier_cands {
                state[j] = State::Out;
            }
            continue;
        };
        let (ratio, sine) = (norms[p], norms[p] / gain[p]);
        if ratio < noise[p] {
            // Dependent within the noise (or, within the rounding tolerance, dependent).
            let r = norm_from(&w, p, k);
            if r / gain[p] > tol {
                state[p] = State::Noise;
                noisy.push((p, r));
            } else {
                state[p] = State::Out;
            }
            continue;
        }
        if sine <= tol {
            state[p] = State::Out;
            continue;
        }
        // Householder reflection H = I - tau v v^T (v_k = 1) with H w[k.., p] = (mu, 0, ...).
        let alpha = w[(k, p)];
        let sigma: f64 = {
            let c = &w.col(p)[k + 1..];
            dot(c, c)
        };
        state[p] = State::Chosen;
        chosen.push(p);
        if sigma == 0.0 {
            // Already zero below row k: nothing to reflect.
        } else {
            let mu = (alpha * alpha + sigma).sqrt();
            let beta = if alpha <= 0.0 {
                alpha - mu
            } else {
                -sigma / (alpha + mu)
            };
            let tau = 2.0 * beta * beta / (sigma + beta * beta);
            v[k] = 1.0;
            for i in k + 1..rows {
                v[i] = w[(i, p)] / beta;
            }
            {
                let col = w.col_mut(p);
                col[k] = mu;
                col[k + 1..].fill(0.0);
            }
            let vk = &v[k..rows];
            for (j, st) in state.iter().enumerate() {
                if !matches!(st, State::Candidate | State::Noise) {
                    continue;
                }
                let col = &mut w.col_mut(j)[k..];
                let s = tau * dot(vk, col);
                if s != 0.0 {
                    for (x, &y) in col.iter_mut().zip(vk) {
                        *x -= s * y;
                    }
                }
            }
        }
        // Downdate the candidates' norms by their entry in row k; afresh on cancellation.
        for j in 0..n {
            if state[j] != State::Candidate || norms[j] == 0.0 {
                continue;
            }
            let q = w[(k, j)].abs() / norms[j];
            let left = (1.0 - q * q).max(0.0);
            let since = norms[j] / exact[j];
            if left * since * since <= tol3z {
                norms[j] = norm_from(&w, j, k + 1);
                exact[j] = norms[j];
            } else {
                norms[j] *= left.sqrt();
            }
        }
    }
    // Each noise-dependent column on the chosen ones: T_SS c = (its first K entries).
    let kk = chosen.len();
    let noise = noisy
        .into_iter()
        .map(|(j, ratio)| {
            let mut c: Vec<f64> = w.col(j)[..kk].to_vec();
            for l in (0..kk).rev() {
                let mut s = c[l];
                for (m, &cm) in c.iter().enumerate().skip(l + 1) {
                    s -= w[(l, chosen[m])] * cm;
                }
                let d = w[(l, chosen[l])];
                c[l] = if d != 0.0 { s / d } else { 0.0 };
            }
            NoiseColumn {
                column: j,
                ratio,
                coef: c,
            }
        })
        .collect();
    BaseSelection { chosen, noise }
}

/// The analysed columns (`params`, by position) in order of preference, and each one's tier:
/// the user's `priority` first, each parameter its own tier, then [`default_priority`] in its
/// tiers.
fn priority_order(
    robot: &Robot,
    params: &[ParamId],
    priority: &[ParamId],
) -> (Vec<usize>, Vec<usize>) {
    let mut order = priority.to_vec();
    for id in default_priority(robot) {
        if !order.contains(&id) {
            order.push(id);
        }
    }
    let order: Vec<usize> = order
        .iter()
        .filter_map(|id| params.iter().position(|p| p == id))
        .collect();
    let tiers: Vec<usize> = params
        .iter()
        .map(|&id| match priority.iter().position(|&p| p == id) {
            Some(k) => k,
            None => priority.len() + default_tier(robot, id),
        })
        .collect();
    (order, tiers)
}

fn default_tier(robot: &Robot, id: ParamId) -> usize {
    let nonzero = robot.get(id).abs() > 1e-12;
    match robot.param_kind(id) {
        ParamKind::Offset { .. } => 0,
        ParamKind::Slope { .. } | ParamKind::Coupling { .. } => 1,
        ParamKind::Link { component, .. } => match (component.quantity(), nonzero) {
            (Quantity::Length, true) => 2,
            (_, true) => 3,
            (Quantity::Length, false) => 4,
            _ => 5,
        },
        ParamKind::Site { .. } => 6,
        ParamKind::Plane { .. } => 7,
        ParamKind::Session { .. } => 8,
        ParamKind::Compliance { .. } | ParamKind::Lateral { .. } => 9,
        ParamKind::Body { .. } => 10,
    }
}

/// Gauss-Jordan reduction of the rows `vectors` (each of length n) with pivots searched in the
/// column order `order`; entries below 1e-9 of their row's largest are dropped. Returns each
/// reduced row as (column, coefficient) with the pivot's coefficient 1.
fn reduced_form(vectors: &[Vec<f64>], order: &[usize]) -> Vec<Vec<(usize, f64)>> {
    let mut rows: Vec<Vec<f64>> = vectors.to_vec();
    let k = rows.len();
    let mut pivots = Vec::new();
    let mut r = 0;
    // The largest entry of all rows: it changes only when a pivot step changes the rows, so
    // it is worked out again then, not at every column looked at (O(k^2 n) in all).
    let largest = |rows: &[Vec<f64>]| rows.iter().flatten().fold(0.0f64, |a, &b| a.max(b.abs()));
    let mut scale = largest(&rows);
    for &c in order {
        if r == k {
            break;
        }
        // Partial pivoting among the remaining rows.
        let (best, val) = (r..k)
            .map(|i| (i, rows[i][c].abs()))
            .fold((r, 0.0), |a, b| if b.1 > a.1 { b } else { a });
        if val <= 1e-8 * scale {
            continue;
        }
        rows.swap(r, best);
        let p = rows[r][c];
        for x in rows[r].iter_mut() {
            *x /= p;
        }
        let pivot_row = rows[r].clone();
        for (i, row) in rows.iter_mut().enumerate() {
            if i != r {
                let f = row[c];
                if f != 0.0 {
                    for (x, y) in row.iter_mut().zip(&pivot_row) {
                        *x -= f * y;
                    }
                }
            }
        }
        scale = largest(&rows);
        pivots.push(c);
        r += 1;
    }
    rows.truncate(r);
    rows.iter()
        .zip(&pivots)
        .map(|(row, &pc)| {
            let big = row.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
            let mut terms: Vec<(usize, f64)> = row
                .iter()
                .enumerate()
                .filter(|(_, &v)| v.abs() > 1e-9 * big)
                .map(|(j, &v)| (j, v))
                .collect();
            // Pivot first, then by parameter order.
            terms.sort_by_key(|&(j, _)| (j != pc, j));
            terms
        })
        .collect()
}

/// Writes `sum c_j p_j` readably: `p3 - p9 - p15`, `p4 + 0.5 p31`.
pub fn format_combination(terms: &[(ParamId, f64)]) -> String {
    let mut s = String::new();
    for (k, &(id, c)) in terms.iter().enumerate() {
        let sign = if c < 0.0 { "-" } else { "+" };
        let mag = c.abs();
        let coef = if (mag - 1.0).abs() < 1e-12 {
            String::new()
        } else {
            format!("{} ", fmt_sig(mag))
        };
        if k == 0 {
            s.push_str(if c < 0.0 { "-" } else { "" });
        } else {
            s.push_str(&format!(" {sign} "));
        }
        s.push_str(&format!("{coef}{id}"));
    }
    s
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::files::parse_measurements;

    /// The greedy selection this module made before the pivoted QR (Gram-Schmidt, twice, on
    /// every candidate at every step: O(n^4)), kept verbatim but for the tiers, which it is
    /// handed: the reference the pivoted QR must agree with under the rounding rule alone.
    fn greedy(js: &Matrix, order: &[usize], tier: &[usize], rank: usize, tol: f64) -> Vec<usize> {
        let m = js.nrows();
        let mut chosen: Vec<usize> = Vec::new();
        let mut q: Vec<Vec<f64>> = Vec::new(); // orthonormal basis of chosen columns
        let mut remaining: Vec<usize> = order.to_vec();
        while chosen.len() < rank && !remaining.is_empty() {
            let t = remaining.iter().map(|&j| tier[j]).min().expect("non-empty");
            let mut best: Option<(usize, f64, Vec<f64>)> = None;
            for &j in remaining.iter().filter(|&&j| tier[j] == t) {
                let mut v: Vec<f64> = (0..m).map(|i| js[(i, j)]).collect();
                for _ in 0..2 {
                    for b in &q {
                        let d: f64 = v.iter().zip(b).map(|(x, y)| x * y).sum();
                        for (x, y) in v.iter_mut().zip(b) {
                            *x -= d * y;
                        }
                    }
                }
                let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
                if best.as_ref().is_none_or(|b| norm > b.1 * (1.0 + 1e-9)) {
                    best = Some((j, norm, v));
                }
            }
            let (j, norm, v) = best.expect("tier has a candidate");
            if norm > tol.max(1e-12) {
                chosen.push(j);
                q.push(v.iter().map(|x| x / norm).collect());
                remaining.retain(|&k| k != j);
            } else {
                remaining.retain(|&k| tier[k] != t);
            }
        }
        chosen.sort();
        chosen
    }

    fn sorted(mut v: Vec<usize>) -> Vec<usize> {
        v.sort();
        v
    }

    /// Random matrices with dependent and nearly dependent columns, random tiers and orders:
    /// the pivoted QR (with downdated norms) chooses what the greedy Gram-Schmidt does.
    #[test]
    fn random_matrices_choose_as_the_greedy_selection_does() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        for trial in 0..300 {
            let m = rng.random_range(6..30usize);
            let n = rng.random_range(2..14usize);
            let mut a = Matrix::from_fn(m, n, |_, _| rng.random_range(-1.0..1.0));
            // Some columns combinations of others (exactly, or with widely different scales).
            for j in 0..n {
                if j >= 2 && rng.random_range(0.0..1.0) < 0.3 {
                    let (p, q) = (rng.random_range(0..j), rng.random_range(0..j));
                    let (x, y) = (rng.random_range(-2.0..2.0), rng.random_range(-1e3..1e3));
                    for i in 0..m {
                        a[(i, j)] = x * a[(i, p)] + y * a[(i, q)];
                    }
                }
                if rng.random_range(0.0..1.0) < 0.2 {
                    linalg::scale_col(&mut a, j, 10f64.powi(rng.random_range(-6..6)));
                }
            }
            let norms: Vec<f64> = (0..n).map(|j| linalg::col_norm(&a, j)).collect();
            let js = Matrix::from_fn(m, n, |i, j| a[(i, j)] / norms[j]);
            let mut order: Vec<usize> = (0..n).collect();
            for k in (1..n).rev() {
                order.swap(k, rng.random_range(0..=k));
            }
            let tiers: Vec<usize> = (0..n).map(|_| rng.random_range(0..3)).collect();
            let s = linalg::singular_values(&js).unwrap();
            let tol = 1e-9 * s[0];
            let rank = s.iter().filter(|&&v| v > tol).count();
            let old = greedy(&js, &order, &tiers, rank, tol);
            let new = select_base(&js, &vec![1.0; n], &order, &tiers, rank, tol, &vec![0.0; n]);
            assert_eq!(sorted(new.chosen.clone()), old, "trial {trial}");
            // And on the R of the same columns (what the analysis works on).
            let r = linalg::r_of_columns(&js, &(0..n).collect::<Vec<_>>());
            let on_r = select_base(&r, &vec![1.0; n], &order, &tiers, rank, tol, &vec![0.0; n]);
            assert_eq!(on_r.chosen, new.chosen, "trial {trial}");
        }
    }

    /// Identical columns (equal to rounding, or opposite) tie: the earliest in the order wins,
    /// whatever the order, the same every time.
    #[test]
    fn ties_go_to_the_earliest_in_the_order() {
        let m = 9;
        let mut a = Matrix::from_fn(m, 4, |i, j| ((i * 7 + j * 3) as f64 * 0.9).sin());
        for i in 0..m {
            a[(i, 2)] = a[(i, 0)] * (1.0 + 3e-16);
            a[(i, 3)] = -a[(i, 0)];
        }
        let norms: Vec<f64> = (0..4).map(|j| linalg::col_norm(&a, j)).collect();
        let js = Matrix::from_fn(m, 4, |i, j| a[(i, j)] / norms[j]);
        let r = linalg::r_of_columns(&js, &[0, 1, 2, 3]);
        for first in [0, 2, 3] {
            let mut order = vec![first, 1];
            order.extend([0, 2, 3].iter().filter(|&&j| j != first));
            for mat in [&js, &r] {
                let sel = select_base(mat, &[1.0; 4], &order, &[0; 4], 2, 1e-9, &[0.0; 4]);
                assert_eq!(
                    sorted(sel.chosen),
                    sorted(vec![first, 1]),
                    "order {order:?}"
                );
            }
        }
    }

    /// A column at a known angle to the span of two others: left out within the noise when
    /// its sine is below 1/sqrt(m) (uniform weights), with its ratio r/e = sin sqrt(m) and its
    /// regression on the two; kept above; left out silently (not reported) when it is
    /// dependent at the rounding level.
    #[test]
    fn the_noise_rule_on_a_column_at_a_known_angle() {
        let m = 100;
        let root = (m as f64).sqrt();
        // Orthonormal u0, u1, u2 (by Gram-Schmidt of smooth columns).
        let mut u = Matrix::from_fn(m, 3, |i, j| ((i * (j + 2)) as f64 * 0.173 + j as f64).cos());
        for j in 0..3 {
            for k in 0..j {
                let d = dot(u.col(j), u.col(k));
                for i in 0..m {
                    u[(i, j)] -= d * u[(i, k)];
                }
            }
            let nrm = linalg::col_norm(&u, j);
            linalg::scale_col(&mut u, j, 1.0 / nrm);
        }
        for (sine, noisy, kept) in [
            (0.5 / root, true, false),
            (0.99 / root, true, false),
            (1.01 / root, false, true),
            (0.3, false, true),
            (1e-13, false, false),
        ] {
            // c0 = u0, c1 = (u0 + u1) / sqrt 2, c2 = cos t (0.6 c0 + 0.8 c1)^ + sin t u2.
            let c1: Vec<f64> = (0..m)
                .map(|i| (u[(i, 0)] + u[(i, 1)]) / 2f64.sqrt())
                .collect();
            let mut mix: Vec<f64> = (0..m).map(|i| 0.6 * u[(i, 0)] + 0.8 * c1[i]).collect();
            let mn = dot(&mix, &mix).sqrt();
            mix.iter_mut().for_each(|x| *x /= mn);
            let cos = (1.0 - sine * sine).sqrt();
            let a = Matrix::from_fn(m, 3, |i, j| match j {
                0 => u[(i, 0)],
                1 => c1[i],
                _ => cos * mix[i] + sine * u[(i, 2)],
            });
            // Uniform weights: e_j = |a_j| / sqrt(m), so the gain of a unit column is sqrt(m).
            let sel = select_base(&a, &[root; 3], &[0, 1, 2], &[0, 0, 1], 3, 1e-9, &[1.0; 3]);
            assert_eq!(sel.chosen.contains(&2), kept, "sine {sine}");
            assert_eq!(sel.noise.len(), noisy as usize, "sine {sine}");
            if let Some(d) = sel.noise.first() {
                assert_eq!(d.column, 2);
                assert!(
                    (d.ratio - sine * root).abs() < 1e-12,
                    "{} vs {}",
                    d.ratio,
                    sine * root
                );
                // c2 = (cos / mn) (0.6 c0 + 0.8 c1) + sine u2, in the order chosen (c0, c1).
                let want = [0.6 * cos / mn, 0.8 * cos / mn];
                for (l, want) in want.iter().enumerate() {
                    let c = d.coef[sel.chosen.iter().position(|&k| k == l).unwrap()];
                    assert!((c - want).abs() < 1e-12, "{c} vs {want}");
                }
            }
        }
    }

    /// Odd input: nothing to choose from, zero and NaN columns, a rank of 0. No panic.
    #[test]
    fn odd_input_chooses_what_it_can() {
        let z = Matrix::zeros(3, 2);
        assert!(
            select_base(&z, &[0.0; 2], &[0, 1], &[0, 0], 2, 1e-9, &[1.0; 2])
                .chosen
                .is_empty()
        );
        let a = Matrix::from_fn(3, 2, |i, j| if j == 0 { f64::NAN } else { i as f64 });
        let s = select_base(&a, &[1.0; 2], &[0, 1], &[0, 0], 2, 1e-9, &[0.0; 2]);
        assert!(s.chosen.len() <= 2);
        let b = Matrix::from_fn(3, 2, |i, j| (i + j) as f64);
        assert!(
            select_base(&b, &[1.0; 2], &[0, 1], &[0, 1], 0, 1e-9, &[0.0; 2])
                .chosen
                .is_empty()
        );
        assert!(select_base(&b, &[1.0; 2], &[], &[0, 1], 2, 1e-9, &[0.0; 2])
            .chosen
            .is_empty());
    }

    /// A 5-joint arm (metres, radians) and `count` positions of its end effector at
    /// pseudo-random readings, in CSV with a standard deviation per row: the first `anchors`
    /// at `tiny`, the others at `sigma` (m). Made here from the forward kinematics (this module
    /// may not use the simulation, which comes after it).
    fn arm_positions(count: usize, anchors: usize, tiny: f64, sigma: f64) -> (Robot, Dataset) {
        let quarter = std::f64::consts::FRAC_PI_2;
        let links = [
            (0.0, 0.0, 0.3, 0.0, 0.0, 0.0),
            (0.05, 0.0, 0.1, 0.0, quarter, 0.0),
            (0.4, 0.02, 0.0, 0.1, 0.0, 0.0),
            (0.35, 0.0, 0.05, 0.0, -0.2, quarter),
            (0.0, 0.1, 0.12, 0.3, 0.1, -quarter),
            (0.02, 0.03, 0.15, 0.0, 0.0, 0.0),
        ];
        let mut toml = String::from("name = \"arm\"\nlength_unit = \"m\"\nangle_unit = \"rad\"\n");
        for (x, y, z, a, b, g) in links {
            toml.push_str(&format!(
                "[[links]]\nx = {x}\ny = {y}\nz = {z}\nalpha = {a}\nbeta = {b}\ngamma = {g}\n"
            ));
        }
        for k in 0..5 {
            toml.push_str(&format!(
                "[[joints]]\nkind = \"revolute\"\noffset = {}\nslope = {}\n",
                0.1 * k as f64,
                1.0 + 0.1 * k as f64
            ));
        }
        let robot = crate::robot_file::parse_robot_toml(&toml, "arm.toml").unwrap();
        let chain = crate::kinematics::Chain::new(&robot);
        let mut ws = crate::kinematics::Workspace::new(&robot);
        let mut csv = String::from("posture,v1,v2,v3,v4,v5,x,y,z,sigma_position\n");
        for i in 0..count {
            let v: Vec<f64> = (0..5)
                .map(|k| 2.5 * ((i * 7 + k * 13) as f64 * 0.618).sin())
                .collect();
            chain.forward(&v, &mut ws);
            let p = chain
                .target_frame(&ws, crate::kinematics::Target::EndEffector)
                .pose()
                .position;
            let s = if i < anchors { tiny } else { sigma };
            let v: Vec<String> = v.iter().map(|x| x.to_string()).collect();
            csv.push_str(&format!(
                "{},{},{},{},{},{s}\n",
                i + 1,
                v.join(","),
                p.x,
                p.y,
                p.z
            ));
        }
        let data = parse_measurements(&csv, "arm.csv", &robot).unwrap();
        (robot, data)
    }

    /// The e_j travel with a linearisation: an analysis from it (no pass) is the analysis
    /// that made it. From a bare R, e_j is bounded from the column norms: exact with uniform
    /// weights; with anchors, below the exact values, and it leaves out no more than the rule.
    #[test]
    fn a_linearisation_carries_the_typical_rows() {
        for anchors in [0, 3] {
            let (robot, data) = arm_positions(40, anchors, 1e-9, 5e-5);
            // Every parameter: the tool link's angles, unseen by positions, are unobservable.
            let params: Vec<ParamId> = robot.param_ids().collect();
            let opts = AnalysisOptions::default();
            let (an, lin) = analyze_linearized(&robot, &data, &params, &opts).unwrap();
            assert_eq!(an.unobservable.len(), 3);
            assert_eq!(lin.typical_row, an.typical_row);
            let again = analyze_from_linearized(&robot, &data, &lin, &opts).unwrap();
            assert_eq!(again.identifiable, an.identifiable);
            assert_eq!(again.typical_row, an.typical_row);
            assert_eq!(again.noise_dependent, an.noise_dependent);
            assert_eq!(again.noise_rule, an.noise_rule);
            let bare = analyze_from_r(&robot, &data, &params, &opts, &lin.r).unwrap();
            if anchors == 0 {
                for (a, b) in bare.typical_row.iter().zip(&an.typical_row) {
                    assert!((a - b).abs() <= 1e-12 * b, "{a} vs {b}");
                }
                assert_eq!(bare.identifiable, an.identifiable);
                assert!(!bare.noise_rule.contains("bounded below"));
            } else {
                assert!(bare.noise_rule.contains("bounded below"));
                for (a, b) in bare.typical_row.iter().zip(&an.typical_row) {
                    assert!(*a <= b * (1.0 + 1e-12), "{a} vs {b}");
                }
                assert!(bare.noise_dependent.len() <= an.noise_dependent.len());
            }
        }
    }
}
