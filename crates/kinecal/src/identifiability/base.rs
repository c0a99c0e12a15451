//! The identifiable (base) set: a QR with column pivoting by priority, which leaves out what only
//! the noise determines.

use crate::linalg::{self, Matrix};
use crate::model::params::{ParamId, ParamKind};
use crate::model::robot::Robot;
use crate::observe::{Dataset, RowQuantity};
use crate::solve::problem::Problem;
use crate::units::Quantity;

use super::groups::tidy_coef;
use super::spectrum::{dot, Scaled, Spectrum};
use super::{fmt_sig, AnalysisOptions, NoiseDependent};

/// The default preference for the identifiable set (thesis 4.4.3 and 4.4.7: keep parameters
/// that carry physical meaning): joint offsets, then slopes, then link lengths and angles that
/// are non-zero in the nominal model, then zero-valued link components (redundant copies), then
/// site parameters. Earlier is preferred.
pub fn default_priority(robot: &Robot) -> Vec<ParamId> {
    let mut ids: Vec<ParamId> = robot.param_ids().collect();
    ids.sort_by_key(|&id| (default_tier(robot, id), id));
    ids
}

/// What [`identifiable_set`] chose: the set, what it left out within the noise and why, and the
/// `e_j` it judged with.
pub(super) struct IdentifiableSet {
    /// The identifiable parameters, ascending.
    pub identifiable: Vec<ParamId>,
    /// The parameters left out as dependent within the noise.
    pub noise_dependent: Vec<NoiseDependent>,
    /// The noise rule in words.
    pub noise_rule: String,
    /// The chosen parameters of [`AnalysisOptions::placed`] the rule would have left out, with
    /// their standard deviations given the whole set (file units, at the noise scale).
    pub placed_loose: Vec<(ParamId, f64)>,
    /// `e_j` per parameter.
    pub typical: Vec<f64>,
    /// The columns by preference.
    pub order: Vec<usize>,
}

/// The identifiable set of `params` by priority (column pivoting within each priority tier on
/// the noise-scaled columns), then without the loosest parameter given the whole set while one
/// is loose; `typical` the `e_j` from the rows, when they were at hand.
#[allow(clippy::too_many_arguments)]
pub(super) fn identifiable_set(
    robot: &Robot,
    params: &[ParamId],
    opts: &AnalysisOptions,
    scaled: &Scaled,
    spectrum: &Spectrum,
    clamp: &[f64],
    typical: Option<Vec<f64>>,
    col_factor: &[f64],
    m: usize,
) -> IdentifiableSet {
    let column_norms = &scaled.column_norms;
    let (order, tiers) = priority_order(robot, params, &opts.priority);
    let (typical, exact_typical) = typical_errors(typical, clamp, column_norms, m);
    let gain = noise_gains(scaled, &typical);
    // The rule's thresholds, and those it applies: none for the parameters the start already
    // placed from the data (only the rounding rule leaves them out).
    let rule = noise_thresholds(robot, params, opts.noise_scale, &typical);
    let placed: Vec<bool> = params.iter().map(|id| opts.placed.contains(id)).collect();
    let threshold: Vec<f64> = rule
        .iter()
        .zip(&placed)
        .map(|(&t, &p)| if p { 0.0 } else { t })
        .collect();
    let tol = opts.rcond * spectrum.largest;
    let (base, loose_sigma) =
        select_without_loose(scaled, &gain, &order, &tiers, spectrum.rank, tol, threshold);
    let placed_loose = if placed.iter().any(|p| *p) {
        let sigma = linalg::marginal_sigmas(&scaled.r, &base.chosen);
        base.chosen
            .iter()
            .zip(&sigma)
            .filter(|&(&j, &s)| placed[j] && gain[j] / s < rule[j])
            .map(|(&j, &s)| {
                let id = params[j];
                let si = opts.noise_scale * s / column_norms[j];
                (id, robot.units.from_si(robot.param_quantity(id), si))
            })
            .collect()
    } else {
        Vec::new()
    };
    let mut identifiable: Vec<ParamId> = base.chosen.iter().map(|&j| params[j]).collect();
    identifiable.sort();
    let noise_dependent = base
        .noise
        .iter()
        .map(|d| {
            noise_dependent(
                robot,
                params,
                opts.noise_scale,
                d,
                &base.chosen,
                &typical,
                col_factor,
                column_norms,
                gain[d.column],
                loose_sigma[d.column],
            )
        })
        .collect();
    IdentifiableSet {
        identifiable,
        noise_dependent,
        noise_rule: noise_rule_words(m, exact_typical, opts.noise_scale),
        placed_loose,
        typical,
        order,
    }
}

/// `e_j` per column: from the rows when they were at hand (`typical`), else its lower bound
/// from the column norms (exact when no row's weight is clamped); and whether it is exact.
fn typical_errors(
    typical: Option<Vec<f64>>,
    clamp: &[f64],
    column_norms: &[f64],
    m: usize,
) -> (Vec<f64>, bool) {
    let least_clamp = clamp.iter().copied().fold(1.0, f64::min);
    let exact = typical.is_some() || least_clamp >= 1.0;
    let typical = typical.unwrap_or_else(|| {
        let root_m = (m.max(1) as f64).sqrt();
        column_norms
            .iter()
            .map(|c| least_clamp * c / root_m)
            .collect()
    });
    (typical, exact)
}

/// The factor from the unit columns to the noise-scaled ones, `|a_j| / e_j` (the noise-scaled
/// column `a_j / e_j` is the unit column times it); 0 for a column the rows do not feel.
fn noise_gains(scaled: &Scaled, typical: &[f64]) -> Vec<f64> {
    (0..scaled.column_norms.len())
        .map(|j| {
            let g = scaled.column_norms[j] / typical[j];
            if scaled.unfelt[j] || !g.is_finite() {
                0.0
            } else {
                g
            }
        })
        .collect()
}

/// [`select_base`] on `R`'s columns (n long, the same inner products as the scaled Jacobian's
/// m-long ones), then again without the loosest parameter given the whole set while one is
/// loose; the selection, and the standard deviation (internal units) given the whole set of
/// each parameter so left out.
///
/// A parameter chosen early (a high tier) is judged given only the columns before it: given
/// the whole set, it may be as loose as the rule forbids (a joint offset and a link length one
/// the same lever at the noise). Then the loosest of those goes, and the set is chosen again
/// without it. Of the loose ones, the least preferred goes (its partner in the near-dependence,
/// if any, is then judged again without it): priorities decide, as they do in the pivoting.
fn select_without_loose(
    scaled: &Scaled,
    gain: &[f64],
    order: &[usize],
    tiers: &[usize],
    rank: usize,
    tol: f64,
    mut threshold: Vec<f64>,
) -> (BaseSelection, Vec<Option<f64>>) {
    let n = gain.len();
    let rank_of: Vec<usize> = {
        let mut r = vec![usize::MAX; n];
        for (k, &j) in order.iter().enumerate() {
            r[j] = r[j].min(k);
        }
        r
    };
    let loose_given_all = |chosen: &[usize], threshold: &[f64]| -> Option<(usize, f64)> {
        let sigma = linalg::marginal_sigmas(&scaled.r, chosen);
        chosen
            .iter()
            .zip(&sigma)
            .filter(|&(&j, &s)| {
                // Given all the others, a unit column's remaining norm is 1 / s (s its
                // standard deviation on unit columns): gain[j] / s in the gained metric.
                gain[j] / s < threshold[j]
            })
            .max_by_key(|&(&j, _)| (tiers[j], rank_of[j]))
            .map(|(&j, &s)| (j, s / scaled.column_norms[j]))
    };
    let select =
        |threshold: &[f64]| select_base(&scaled.r, gain, order, tiers, rank, tol, threshold);
    let mut base = select(&threshold);
    let mut loose_sigma: Vec<Option<f64>> = vec![None; n];
    for _ in 0..n {
        let Some((j, sigma)) = loose_given_all(&base.chosen, &threshold) else {
            break;
        };
        threshold[j] = f64::INFINITY;
        loose_sigma[j] = Some(sigma);
        base = select(&threshold);
    }
    (base, loose_sigma)
}

/// The noise threshold of each column, in the gained metric: below one typical row's worth
/// (r_jj < e_j) and so loosely determined that its standard deviation given the columns chosen
/// before it, 1 / r_jj = 1 / (ratio e_j), exceeds [`LOOSE`] of its scale.
fn noise_thresholds(
    robot: &Robot,
    params: &[ParamId],
    noise_scale: f64,
    typical: &[f64],
) -> Vec<f64> {
    params
        .iter()
        .zip(typical)
        .map(|(&id, &e)| {
            let scale = match robot.param_kind(id) {
                ParamKind::Slope { .. } | ParamKind::Coupling { .. } => robot.get(id).abs(),
                _ => match robot.param_quantity(id) {
                    Quantity::Length => robot.reach(),
                    _ => 1.0,
                },
            };
            let loose = noise_scale / (LOOSE * e * scale);
            if loose.is_finite() {
                loose
            } else {
                0.0
            }
        })
        .collect()
}

/// A parameter left out within the noise, with its near-combination of the chosen ones.
///
/// `a_j / e_j ~= sum c_l a_k / e_k`: per file unit, `c_l (e_j / e_k) (f_j / f_k)`; on unit
/// columns, `c_l (e_j / e_k) (|a_k| / |a_j|)`.
#[allow(clippy::too_many_arguments)]
fn noise_dependent(
    robot: &Robot,
    params: &[ParamId],
    noise_scale: f64,
    d: &NoiseColumn,
    chosen: &[usize],
    typical: &[f64],
    col_factor: &[f64],
    column_norms: &[f64],
    gain: f64,
    loose_sigma: Option<f64>,
) -> NoiseDependent {
    let j = d.column;
    let mut terms: Vec<(usize, f64, f64)> = chosen
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
            noise_scale * loose_sigma.unwrap_or(1.0 / (d.ratio * typical[j])),
        ),
        sine: d.ratio / gain,
        terms: terms[..shown]
            .iter()
            .map(|&(k, c, _)| (params[k], tidy_coef(c)))
            .collect(),
        omitted: terms.len() - shown,
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

/// Per row of `problem` (in row order), `min(1, w_med / w_i)`: the factor that clamps the
/// row's weight `w_i = 1 / sigma_i` at `w_med`, the (lower) median weight of the rows of the
/// same quantity. Per quantity, because comparing a length row's weight (1/m) with an angle
/// row's (1/rad) would depend on the internal units; the lower median, so that of two equally
/// common weights the larger is the one clamped.
///
/// Empty when no row is clamped (every factor 1: a row beyond the slice's end counts 1), as
/// with uniform weights per quantity, found in one pass without the medians: the passes over
/// the rows then tally no typical-row sums, since `e_j` is the column's norm over `sqrt(m)`.
pub(super) fn row_clamp(data: &Dataset, problem: &Problem<'_>) -> Vec<f64> {
    let sigma = problem.row_sigma();
    let quantities = || {
        data.observations
            .iter()
            .flat_map(|o| o.rows().iter().map(|row| row.quantity))
            .take(sigma.len())
    };
    // One weight per quantity (uniform weights, the default) and no pixel rows (weighed
    // against the lengths' median below): nothing is clamped.
    let (mut length, mut angle) = (None, None);
    let uniform = quantities().zip(sigma).all(|(q, &s)| {
        let first = match q {
            RowQuantity::Length => &mut length,
            RowQuantity::Angle => &mut angle,
            RowQuantity::Pixel => return false,
        };
        // The same weight to the bit.
        first.get_or_insert(s).to_bits() == s.to_bits()
    });
    if uniform {
        return Vec::new();
    }
    let quantity: Vec<RowQuantity> = quantities().collect();
    let weight = |i: usize| 1.0 / sigma[i];
    // The weights of the length rows and of the angle rows, in one pass.
    let (mut lengths, mut angles) = (Vec::new(), Vec::new());
    for (i, q) in quantity.iter().enumerate() {
        match q {
            RowQuantity::Length => lengths.push(weight(i)),
            RowQuantity::Angle => angles.push(weight(i)),
            _ => {}
        }
    }
    let median = |mut w: Vec<f64>| -> f64 {
        if w.is_empty() {
            return f64::INFINITY;
        }
        let k = (w.len() - 1) / 2;
        *w.select_nth_unstable_by(k, f64::total_cmp).1
    };
    let (length, angle) = (median(lengths), median(angles));
    let clamp: Vec<f64> = (0..sigma.len())
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
        .collect();
    if clamp.iter().all(|&c| c >= 1.0) {
        Vec::new()
    } else {
        clamp
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
pub(super) struct NoiseColumn {
    /// The column.
    pub column: usize,
    /// Its remaining norm at its pivot step, noise-scaled: `r_jj / e_j`.
    pub ratio: f64,
    /// Its regression on the chosen columns (in their pivot order), noise-scaled:
    /// `a_j / e_j ~= sum_l coef[l] a_chosen[l] / e_chosen[l]`.
    pub(crate) coef: Vec<f64>,
}

/// What [`select_base`] chose.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct BaseSelection {
    /// The chosen columns, in pivot order.
    pub chosen: Vec<usize>,
    /// The columns left out as dependent within the noise (not those dependent at the
    /// rounding level), in the order they were found.
    pub noise: Vec<NoiseColumn>,
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
pub(super) fn select_base(
    units: &Matrix,
    gain: &[f64],
    order: &[usize],
    tier: &[usize],
    rank: usize,
    tol: f64,
    noise: &[f64],
) -> BaseSelection {
    let tol = tol.max(1e-12);
    let mut qr = Pivoting::new(units, gain, order);
    let rows = units.nrows();
    while qr.chosen.len() < rank && qr.chosen.len() < rows {
        let Some(t) = qr.lowest_tier(tier) else {
            break;
        };
        let Some(p) = qr.pivot(tier, t) else {
            continue;
        };
        let (ratio, sine) = (qr.norms[p], qr.norms[p] / gain[p]);
        if ratio < noise[p] {
            qr.leave_out_within_noise(p, tol);
        } else if sine <= tol {
            qr.state[p] = State::Out;
        } else {
            qr.choose(p);
        }
    }
    qr.selection()
}

/// Where a column stands in [`select_base`]'s pivoting.
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

/// The working state of [`select_base`]: the gained columns, transformed by the Householder
/// reflections of the columns chosen so far (step `k` = how many), with each candidate's
/// remaining norm below row `k` (downdated, and as last computed afresh).
struct Pivoting<'a> {
    gain: &'a [f64],
    /// The gained columns `units[.., j] * gain[j]` of the candidates (zero for the others),
    /// transformed step by step.
    w: Matrix,
    state: Vec<State>,
    /// Each column's place in the order of preference (`usize::MAX`: not considered).
    pref: Vec<usize>,
    /// Remaining norms below the current step, downdated.
    norms: Vec<f64>,
    /// Each remaining norm as last computed afresh (to see cancellation coming).
    exact: Vec<f64>,
    chosen: Vec<usize>,
    /// Columns left out within the noise, with their remaining norm then.
    noisy: Vec<(usize, f64)>,
    /// The Householder vector of the last reflection.
    v: Vec<f64>,
    tier_cands: Vec<usize>,
}

impl<'a> Pivoting<'a> {
    /// The candidates: the columns listed in `order` with a positive, finite gain.
    fn new(units: &Matrix, gain: &'a [f64], order: &[usize]) -> Self {
        let (rows, n) = (units.nrows(), units.ncols());
        let mut state = vec![State::Out; n];
        let mut pref = vec![usize::MAX; n];
        for (k, &j) in order.iter().enumerate() {
            if j < n && pref[j] == usize::MAX && gain[j] > 0.0 && gain[j].is_finite() {
                pref[j] = k;
                state[j] = State::Candidate;
            }
        }
        let w = Matrix::from_fn(rows, n, |i, j| {
            if state[j] == State::Candidate {
                units[(i, j)] * gain[j]
            } else {
                0.0
            }
        });
        let mut qr = Pivoting {
            gain,
            w,
            state,
            pref,
            norms: Vec::new(),
            exact: Vec::new(),
            chosen: Vec::new(),
            noisy: Vec::new(),
            v: vec![0.0; rows],
            tier_cands: Vec::with_capacity(n),
        };
        qr.norms = (0..n).map(|j| qr.norm_from(j, 0)).collect();
        qr.exact = qr.norms.clone();
        qr
    }

    /// The norm of column `j` from row `k` down, computed afresh.
    fn norm_from(&self, j: usize, k: usize) -> f64 {
        let c = &self.w.col(j)[k..];
        dot(c, c).sqrt()
    }

    /// The lowest tier a candidate is left in.
    fn lowest_tier(&self, tier: &[usize]) -> Option<usize> {
        (0..self.state.len())
            .filter(|&j| self.state[j] == State::Candidate)
            .map(|j| tier[j])
            .min()
    }

    /// The pivot among tier `t`'s candidates: the largest remaining norm (norms near the
    /// largest computed afresh), ties within [`TIE`] to the earliest preferred. `None` when the
    /// tier's norms are all NaN (a column of NaN): the tier is then left out.
    fn pivot(&mut self, tier: &[usize], t: usize) -> Option<usize> {
        let k = self.chosen.len();
        let mut cands = std::mem::take(&mut self.tier_cands);
        cands.clear();
        cands.extend(
            (0..self.state.len()).filter(|&j| self.state[j] == State::Candidate && tier[j] == t),
        );
        // Near the largest, downdated norms are not accurate enough for ties: afresh.
        let big = cands.iter().map(|&j| self.norms[j]).fold(0.0, f64::max);
        for &j in &cands {
            if self.norms[j] >= big * (1.0 - NEAR) {
                self.norms[j] = self.norm_from(j, k);
                self.exact[j] = self.norms[j];
            }
        }
        let big = cands.iter().map(|&j| self.norms[j]).fold(0.0, f64::max);
        let p = cands
            .iter()
            .copied()
            .filter(|&j| self.norms[j] >= big * (1.0 - TIE))
            .min_by_key(|&j| self.pref[j]);
        if p.is_none() {
            for &j in &cands {
                self.state[j] = State::Out;
            }
        }
        self.tier_cands = cands;
        p
    }

    /// Leaves out column `p`, below its noise threshold: dependent within the noise, or, within
    /// the rounding tolerance `tol` on the unit columns, dependent.
    fn leave_out_within_noise(&mut self, p: usize, tol: f64) {
        let r = self.norm_from(p, self.chosen.len());
        if r / self.gain[p] > tol {
            self.state[p] = State::Noise;
            self.noisy.push((p, r));
        } else {
            self.state[p] = State::Out;
        }
    }

    /// Chooses column `p`: reflects it onto row `k` (the step) and the other candidates and
    /// noise columns with it, then downdates the candidates' norms.
    fn choose(&mut self, p: usize) {
        let k = self.chosen.len();
        let rows = self.w.nrows();
        // Householder reflection H = I - tau v v^T (v_k = 1) with H w[k.., p] = (mu, 0, ...).
        let alpha = self.w[(k, p)];
        let sigma: f64 = {
            let c = &self.w.col(p)[k + 1..];
            dot(c, c)
        };
        self.state[p] = State::Chosen;
        self.chosen.push(p);
        if sigma != 0.0 {
            // (Already zero below row k otherwise: nothing to reflect.)
            let (mu, beta, tau) = linalg::householder(alpha, sigma);
            self.v[k] = 1.0;
            for i in k + 1..rows {
                self.v[i] = self.w[(i, p)] / beta;
            }
            {
                let col = self.w.col_mut(p);
                col[k] = mu;
                col[k + 1..].fill(0.0);
            }
            let vk = &self.v[k..rows];
            for (j, st) in self.state.iter().enumerate() {
                if !matches!(st, State::Candidate | State::Noise) {
                    continue;
                }
                let col = &mut self.w.col_mut(j)[k..];
                let s = tau * dot(vk, col);
                if s != 0.0 {
                    for (x, &y) in col.iter_mut().zip(vk) {
                        *x -= s * y;
                    }
                }
            }
        }
        self.downdate(k);
    }

    /// Downdates the candidates' norms by their entry in row `k`; afresh when cancellation has
    /// eaten half their digits (LAPACK's `dgeqp3`).
    fn downdate(&mut self, k: usize) {
        let tol3z = f64::EPSILON.sqrt();
        for j in 0..self.state.len() {
            if self.state[j] != State::Candidate || self.norms[j] == 0.0 {
                continue;
            }
            let q = self.w[(k, j)].abs() / self.norms[j];
            let left = (1.0 - q * q).max(0.0);
            let since = self.norms[j] / self.exact[j];
            if left * since * since <= tol3z {
                self.norms[j] = self.norm_from(j, k + 1);
                self.exact[j] = self.norms[j];
            } else {
                self.norms[j] *= left.sqrt();
            }
        }
    }

    /// The chosen columns, and each noise-dependent column's regression on them:
    /// `T_SS c = (its first K entries)`.
    fn selection(self) -> BaseSelection {
        let w = &self.w;
        let chosen = self.chosen;
        let kk = chosen.len();
        let noise = self
            .noisy
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
}

/// The analysed columns (`params`, by position) in order of preference, and each one's tier:
/// the user's `priority` first, each parameter its own tier, then [`default_priority`] in its
/// tiers.
pub(super) fn priority_order(
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
        ParamKind::Camera { .. } => 11,
        ParamKind::Board { .. } => 12,
    }
}
