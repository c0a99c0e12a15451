//! The rows of a large dataset folded through a basis found on a subsample: the same `R` as
//! [`super::spectrum::rows`] gives (up to rounding), for a QR of the basis's columns only.
//!
//! Most of a calibration's candidate parameters are exact combinations of the others at every
//! posture (a base set of a 6R arm has 30 of its 54 link parameters), and the rank of a
//! Jacobian can only grow with its rows. So the columns of a basis `B` of a well-spread
//! subsample, and the coefficients `C` that write the other columns `D` as combinations of
//! them there (`J_D = J_B C`), are found on a few hundred postures; the pass over all the
//! data then folds only `[J_B | r]` into a QR (`R_B`) and *proves* the dependence on every
//! row, `|J_D - J_B C|` (the Jacobian times the subsample's null-space basis `[-C; I]`,
//! streamed row by row) at most [`SLACK`] times the rank tolerance of each
//! column's own norm. Then `[J | r] = Q [R_B | R_B C]` (columns in place), whose `R` is that
//! of the whole Jacobian: the analysis that follows runs unchanged. A column that is not
//! such a combination on all the data (the subsample missed an excitation: a session, a
//! target, a joint range) fails the proof, and the rows are folded whole, as without a
//! subsample.
//!
//! Worth it on large data only: the QR of `n` columns costs `2 m n^2`, of the basis's `b`
//! columns `2 m b^2`, the proof `2 m t`, `t` the coefficients that are not rounding (a base
//! set's dependences are mostly one column equal to another or its negative: on a UR10's
//! full poses 20 of 540), or `2 m b (n - b)` by a matrix product when more than a quarter are
//! terms. The pass computes the columns in the order basis first, so that each row's `J_B`
//! and `J_D` are contiguous.
//!
//! The basis's `R_B` is taken from the Gram matrix of `[J_B | r]` (a matrix product, several
//! times cheaper than a QR update of the same rows) when that is accurate: the basis has full
//! rank on the subsample, and the Gram path is accepted only where the solver accepts it
//! ([`crate::solve::estimation::solver::augmented_from_gram`]: its scaled condition below
//! 1e4), so that `R_B` keeps about 8 digits in its weakest direction, far above the rank
//! tolerance (`rcond`, 1e-9), and its `R^T R` is `[J_B | r]^T [J_B | r]` to rounding (the
//! analysis reads `R`'s columns of `J`; the residual's last entry, `sqrt(|r|^2 - |z|^2)`, loses
//! digits where the linear model explains nearly all of `|r|^2`, and nothing reads it). A basis
//! conditioned worse on the subsample is folded by QR at once; one that the Gram matrix of all
//! the rows shows worse (rare: more rows seldom worsen it) is folded again by QR.

use crate::linalg::{self, GramAccumulator, Matrix, QrAccumulator, RowSink, QR_BLOCK};
use crate::model::params::ParamId;
use crate::model::robot::Robot;
use crate::observe::Dataset;
use crate::solve::problem::Problem;

use super::base::{priority_order, select_base};
use super::spectrum::{dot, unclamped_typical, Rows, Scaled, Spectrum};
use super::AnalysisOptions;

/// Subsample rows per analysed parameter, a few times what the rank needs, at most
/// [`MAX_GROUPS_PER_PARAMETER`] groups: 2 `n` groups of postures measured by pose, 4 `n` by
/// position, distance or contact.
const ROWS_PER_PARAMETER: usize = 12;

/// The most subsample groups of postures per analysed parameter (where each holds few rows).
const MAX_GROUPS_PER_PARAMETER: usize = 4;

/// The fewest groups of each kind of observation (session, kind, frame) the subsample keeps
/// (all of them when there are fewer), per analysed parameter: a rare kind is seen a few times.
const FLOOR_PER_PARAMETER: usize = 2;

/// The subsample is used only when it holds at most this share of the groups: otherwise the
/// analysis of all the rows costs little more than the subsample's.
const MAX_SHARE: usize = 8;

/// A dependent column passes the proof when its distance from the basis's span, over all the
/// rows, is at most `SLACK * rcond` of its own norm: 1,000 times below the tolerance at which
/// the rank is decided, so that the analysis on the reconstructed `R` decides what it decides
/// on the whole Jacobian's (which sees these columns at their rounding, ~1e-15 relative).
pub(super) const SLACK: f64 = 1e-3;

/// A coefficient of a dependent column whose term is at most `PRUNE * rcond / b` of the
/// column's norm (`b` the basis's size) is set to 0: together such terms stay below a tenth of
/// the proof's tolerance (`SLACK * rcond`).
const PRUNE: f64 = SLACK / 10.0;

/// A column at most this share of the largest column's norm is unfelt: no measurement feels
/// it, and the analysis zeroes it (the same threshold as there).
const UNFELT: f64 = 1e-12;

/// Per posture, whether a subsample of the data keeps it: `None` when the data is too small
/// for a subsample to pay ([`MAX_SHARE`]). Groups of linked postures (see
/// [`Dataset::posture_groups`]) are kept whole, keyed by the session, kind and frame of their
/// first observation; of each key's groups, evenly spaced ones in file order (every sweep of
/// sweep data), in proportion to the key's share and at least [`FLOOR_PER_PARAMETER`] `n`;
/// [`ROWS_PER_PARAMETER`] `n` rows in all at the data's mean rows per observed group (its
/// rows over its groups that hold an observation, rounded down), at most
/// [`MAX_GROUPS_PER_PARAMETER`] `n` groups.
pub(super) fn subsample(data: &Dataset, n: usize) -> Option<Vec<bool>> {
    let (group_of, groups) = data.posture_group_of();
    type Key<'d> = (
        Option<&'d str>,
        &'static str,
        crate::model::kinematics::Target,
    );
    let mut keys: Vec<Key<'_>> = Vec::new();
    let mut by_key: Vec<Vec<usize>> = Vec::new();
    let mut keyed = vec![false; groups];
    for o in &data.observations {
        let view = &o.views()[0];
        let g = group_of[view.posture];
        if keyed[g] {
            continue;
        }
        keyed[g] = true;
        let key = (
            data.postures[view.posture].session.as_deref(),
            o.kind(),
            view.target,
        );
        let k = match keys.iter().position(|x| *x == key) {
            Some(k) => k,
            None => {
                keys.push(key);
                by_key.push(Vec::new());
                keys.len() - 1
            }
        };
        by_key[k].push(g);
    }
    let total: usize = by_key.iter().map(Vec::len).sum();
    let rows: usize = data.observations.iter().map(|o| o.rows().len()).sum();
    let per_group = (rows / total.max(1)).max(1);
    let target = (ROWS_PER_PARAMETER * n)
        .div_ceil(per_group)
        .min(MAX_GROUPS_PER_PARAMETER * n);
    let floor = FLOOR_PER_PARAMETER * n;
    let mut chosen = vec![false; groups];
    let mut kept = 0;
    for gs in &by_key {
        let c = gs.len();
        let want = (target * c).div_ceil(total.max(1)).max(floor.min(c)).min(c);
        for i in 0..want {
            chosen[gs[i * c / want]] = true;
        }
        kept += want;
    }
    (kept * MAX_SHARE <= total).then(|| group_of.iter().map(|&g| chosen[g]).collect())
}

/// The rows of `problem` (over `params`, ascending) folded through a basis found on a
/// subsample of `data`, with the typical-row sums, or `None` when there is no subsample to
/// use, every column is in the basis, or the dependence fails its proof on all the rows (the
/// caller then folds them whole).
pub(super) fn rows(
    robot: &Robot,
    data: &Dataset,
    problem: &Problem<'_>,
    params: &[ParamId],
    opts: &AnalysisOptions,
    clamp: &[f64],
) -> crate::error::Result<Option<Rows>> {
    let n = params.len();
    let Some(keep) = subsample(data, n) else {
        return Ok(None);
    };
    let Some(basis) = Basis::of(robot, &data.subset(&keep), params, opts)? else {
        return Ok(None);
    };
    Ok(basis.fold_all(robot, problem, clamp, opts.rcond))
}

/// A basis of the columns on a subsample, and the other columns as combinations of it.
#[derive(Clone)]
pub(super) struct Basis {
    /// The basis's columns, ascending.
    pub basis: Vec<usize>,
    /// The other columns, ascending.
    pub dependent: Vec<usize>,
    /// `b x k`: column `i` the coefficients writing `dependent[i]` on the basis's columns
    /// (those whose share is below rounding set to 0: see [`Basis::from_r`]).
    pub coef: Matrix,
    /// Per dependent column, its nonzero coefficients `(basis position, coefficient)`: the
    /// proof's product when they are few (a base set's dependences are mostly a column equal
    /// to another, or its negative), `None` when they are many (a matrix product then).
    terms: Option<SparseTerms>,
    /// The number of columns (the residual aside).
    pub n: usize,
    /// Whether the basis's columns are well enough conditioned on the subsample for their `R`
    /// to come from the Gram matrix of all the rows (the scaled condition below the solver's
    /// `GRAM_CONDITION`); otherwise the pass folds them by QR.
    pub gram: bool,
}

impl Basis {
    /// The same basis, its proof taken by a matrix product whatever the number of terms.
    #[cfg(test)]
    pub(super) fn dense(mut self) -> Basis {
        self.terms = None;
        self
    }

    /// Whether the proof takes the terms one by one (they are few).
    #[cfg(test)]
    pub(super) fn sparse(&self) -> bool {
        self.terms.is_some()
    }

    /// Per dependent column, how many terms the proof takes (`None` by a matrix product).
    #[cfg(test)]
    pub(super) fn term_counts(&self) -> Option<Vec<usize>> {
        self.terms
            .as_ref()
            .map(|t| t.columns().map(<[_]>::len).collect())
    }

    /// The basis of `params`' columns on `sub` (the rank at `opts.rcond`, chosen by a pivoted
    /// QR in the order of preference), `None` when it has every column.
    pub(super) fn of(
        robot: &Robot,
        sub: &Dataset,
        params: &[ParamId],
        opts: &AnalysisOptions,
    ) -> crate::error::Result<Option<Basis>> {
        let n = params.len();
        let problem = Problem::new(robot, sub, params, opts.weights, opts.orientation);
        let mut acc = QrAccumulator::new(n + 1, QR_BLOCK.max(n + 1));
        let mut r = vec![0.0; problem.rows()];
        problem.evaluate_rows(robot, &mut r, &mut acc);
        let mut raug = Matrix::zeros(0, 0);
        acc.r_into(&mut raug);
        if (0..=n).any(|j| raug.col(j).iter().any(|v| !v.is_finite())) {
            return Ok(None);
        }
        let scaled = Scaled::of(&raug, n, params)?;
        let spectrum = Spectrum::of(&scaled, opts.rcond, problem.rows());
        let (order, tiers) = priority_order(robot, params, &opts.priority);
        let gain: Vec<f64> = scaled
            .unfelt
            .iter()
            .map(|&u| if u { 0.0 } else { 1.0 })
            .collect();
        let none = vec![0.0; n];
        let tol = opts.rcond * spectrum.largest;
        let mut basis =
            select_base(&scaled.r, &gain, &order, &tiers, spectrum.rank, tol, &none).chosen;
        if basis.len() == n {
            return Ok(None);
        }
        basis.sort();
        let mut basis = Basis::from_r(&raug, basis, n, opts.rcond);
        // An unfelt column (rounding noise, zeroed by the analysis) is no combination.
        for (i, &j) in basis.dependent.iter().enumerate() {
            if scaled.unfelt[j] {
                for l in 0..basis.basis.len() {
                    basis.coef[(l, i)] = 0.0;
                }
            }
        }
        basis.terms = sparse_terms(&basis.coef);
        Ok(Some(basis))
    }

    /// The dependent columns' coefficients on `basis` from the `R` (`(n + 1)` square) of the
    /// subsample's `[J | r]`: the least-squares fit of each on the basis's columns. A
    /// coefficient whose term is at most [`PRUNE`] `* rcond / b` of its column's norm on the
    /// subsample (`b` the basis's size) is rounding (the exact combinations of a base set are
    /// a few terms of order 1) and set to 0: all of a column's such terms together stay under
    /// a tenth of the proof's tolerance, and the proof checks the coefficients kept.
    pub(super) fn from_r(raug: &Matrix, basis: Vec<usize>, n: usize, rcond: f64) -> Basis {
        let dependent: Vec<usize> = (0..n).filter(|j| !basis.contains(j)).collect();
        let b = basis.len();
        let cols: Vec<usize> = basis.iter().chain(&dependent).copied().collect();
        let t = linalg::r_of_columns(raug, &cols);
        let norms: Vec<f64> = (0..cols.len()).map(|j| linalg::col_norm(&t, j)).collect();
        let mut coef = Matrix::zeros(b, dependent.len());
        for i in 0..dependent.len() {
            let c = linalg::solve_upper(&t, &t.col(b + i)[..b], b);
            let negligible = PRUNE * rcond * norms[b + i] / b as f64;
            for (l, v) in c.into_iter().enumerate() {
                coef[(l, i)] = if v.is_finite() && (v * norms[l]).abs() > negligible {
                    v
                } else {
                    0.0
                };
            }
        }
        // The basis's own R on the subsample, conditioned as the solver's test asks.
        let gram =
            crate::solve::estimation::solver::gram_conditioned(&Matrix::from_fn(b, b, |i, j| {
                t[(i, j)]
            }));
        let terms = sparse_terms(&coef);
        Basis {
            basis,
            dependent,
            coef,
            terms,
            n,
            gram,
        }
    }

    /// One pass over `problem`'s rows: `[J_B | r]` folded into its Gram matrix (or, when that
    /// is too ill-conditioned to give `R_B`, a second pass into a QR), the dependence proved
    /// on every row at `SLACK * rcond`, the typical-row sums tallied; the `R` of the whole
    /// `[J | r]` rebuilt from them, or `None` when the proof fails.
    pub(super) fn fold_all(
        &self,
        robot: &Robot,
        problem: &Problem<'_>,
        clamp: &[f64],
        rcond: f64,
    ) -> Option<Rows> {
        let by = if self.gram { Fold::Gram } else { Fold::Qr };
        match self.fold_all_by(robot, problem, clamp, rcond, by)? {
            Folded::Rows(rows) => Some(*rows),
            Folded::NeedsQr => match self.fold_all_by(robot, problem, clamp, rcond, Fold::Qr)? {
                Folded::Rows(rows) => Some(*rows),
                Folded::NeedsQr => None,
            },
        }
    }

    /// [`Basis::fold_all`] with `R_B` made as `by` says: `NeedsQr` when by the Gram matrix
    /// and that is not accurate enough (never by QR).
    pub(super) fn fold_all_by(
        &self,
        robot: &Robot,
        problem: &Problem<'_>,
        clamp: &[f64],
        rcond: f64,
        by: Fold,
    ) -> Option<Folded> {
        let n = self.n;
        // The columns in the basis's order, then the dependent ones': each row's `J_B` and
        // `J_D` are then contiguous.
        let order: Vec<ParamId> = self
            .basis
            .iter()
            .chain(&self.dependent)
            .map(|&j| problem.estimated()[j])
            .collect();
        let problem = problem.with_column_order(&order);
        let mut sink = BasisRows::new(self, by, clamp);
        let mut r = vec![0.0; problem.rows()];
        let (_, accuracy, errors) = problem.evaluate_rows_kept(robot, &mut r, &mut sink);
        let Some(rb) = sink.finish(rcond * SLACK)? else {
            return Some(Folded::NeedsQr);
        };
        // The typical-row sums back in the columns' order (none tallied when no row is
        // clamped: `e_j` is then the column's norm over `sqrt(m)`).
        let m = problem.rows();
        let raug = self.rebuild(&rb);
        let typical = if clamp.is_empty() {
            unclamped_typical(&raug, n, m)
        } else {
            let mut sums = vec![0.0; n];
            for (&j, &s) in self.basis.iter().zip(&sink.typical_b) {
                sums[j] = s;
            }
            for (&j, &s) in self.dependent.iter().zip(&sink.typical_d) {
                sums[j] = s;
            }
            let mf = m.max(1) as f64;
            sums.iter().map(|s| (s / mf).sqrt()).collect()
        };
        Some(Folded::Rows(Box::new(Rows {
            raug,
            typical: Some(typical),
            accuracy: Some((accuracy, errors)),
        })))
    }

    /// The `R` of `[J | r]` (`(n + 1)` square) from `rb`, the `R` of `[J_B | r]`:
    /// `[J | r] = Q G`, `G`'s columns `R_B`'s for the basis and the residual, `R_B C` for the
    /// others, and `R` that of `G`.
    pub(super) fn rebuild(&self, rb: &Matrix) -> Matrix {
        let (n, b) = (self.n, self.basis.len());
        let mut g = Matrix::zeros(b + 1, n + 1);
        for (p, &j) in self.basis.iter().enumerate() {
            for i in 0..=b {
                g[(i, j)] = rb[(i, p)];
            }
        }
        for (k, &j) in self.dependent.iter().enumerate() {
            for i in 0..=b {
                let mut s = 0.0;
                for l in i..b {
                    s += rb[(i, l)] * self.coef[(l, k)];
                }
                g[(i, j)] = s;
            }
        }
        for i in 0..=b {
            g[(i, n)] = rb[(i, b)];
        }
        let all: Vec<usize> = (0..=n).collect();
        linalg::r_of_columns(&g, &all)
    }
}

/// The nonzero entries `(row, value)` of each column of a coefficient matrix, flat: column
/// `j`'s are `terms[ends[j - 1]..ends[j]]`.
#[derive(Clone)]
struct SparseTerms {
    terms: Vec<(usize, f64)>,
    ends: Vec<usize>,
}

impl SparseTerms {
    /// Each column's terms, in order.
    fn columns(&self) -> impl Iterator<Item = &[(usize, f64)]> {
        let starts = std::iter::once(0).chain(self.ends.iter().copied());
        starts.zip(&self.ends).map(|(a, &b)| &self.terms[a..b])
    }
}

/// The nonzero entries of `coef`'s columns, when they are at most a quarter of the entries (a
/// product term by term then costs less than a matrix product).
fn sparse_terms(coef: &Matrix) -> Option<SparseTerms> {
    let (b, k) = (coef.nrows(), coef.ncols());
    let mut terms = Vec::new();
    let mut ends = Vec::with_capacity(k);
    for i in 0..k {
        terms.extend(
            (0..b)
                .filter(|&l| coef[(l, i)] != 0.0)
                .map(|l| (l, coef[(l, i)])),
        );
        ends.push(terms.len());
    }
    (4 * terms.len() <= b * k).then_some(SparseTerms { terms, ends })
}

/// How [`Basis::fold_all_by`] makes `R_B`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Fold {
    /// From the Gram matrix of `[J_B | r]`, when that is accurate enough.
    Gram,
    /// By a QR of `[J_B | r]`.
    Qr,
}

/// What [`Basis::fold_all_by`] found (when the proof held).
pub(super) enum Folded {
    Rows(Box<Rows>),
    /// The Gram matrix was too ill-conditioned for `R_B`: fold again by QR.
    NeedsQr,
}

/// Where the basis's rows `[J_B | r]` go.
enum BasisSink {
    Gram(GramAccumulator),
    Qr(QrAccumulator),
}

/// The sink of [`Basis::fold_all`]: each row (`[J_B | J_D | r]`) has its `[J_B | r]` folded
/// into a Gram matrix or a QR as it comes (row-major, as a fit's pass folds its rows), and the
/// dependence proved on it: with few terms and no row clamped (the common case), `J_D - J_B C`
/// at once, each dependent column less its terms, summed up in squares per column; otherwise
/// the rows are kept until a block is full, its columns gathered column-major, the typical-row
/// sums tallied when some row is clamped (each column's clamped squares, row after row: the
/// sums [`super::spectrum::TypicalRowTally`] makes, to the bit), and `J_D - J_B C` formed down
/// the columns (by a matrix product when the terms are many).
struct BasisRows<'a> {
    basis: &'a Basis,
    acc: BasisSink,
    /// Each row's clamp factor (1 beyond its end; empty when no row is clamped, and then no
    /// typical-row sums are tallied).
    clamp: &'a [f64],
    /// The rows pushed so far (the block's last).
    row: usize,
    /// Per basis column, the sum of its clamped squares...
    typical_b: Vec<f64>,
    /// ...and per dependent column.
    typical_d: Vec<f64>,
    /// `J_B` of the block's rows, column-major ([`QR_BLOCK`] long, `b` columns), when rows
    /// are kept ([`BasisRows::flush`]).
    block_b: Vec<f64>,
    /// `J_D` of the block's rows, column-major ([`QR_BLOCK`] long, `k` columns), likewise.
    block_d: Vec<f64>,
    /// The block's rows as pushed, row-major (`b + k + 1` wide), when rows are kept.
    rows: Vec<f64>,
    /// Whether each row is proved as it comes (few terms, no row clamped).
    by_rows: bool,
    /// When proved as it comes: the dependent columns of a single term, `(dependent
    /// position, basis position, coefficient)` (most of a base set's: a column equal to
    /// another, or its negative)...
    single: Vec<(usize, usize, f64)>,
    /// ...and the others, `(dependent position, their terms' range in the flat terms)`.
    multiple: Vec<(usize, std::ops::Range<usize>)>,
    /// One row's `[J_B | r]`, as the QR takes it.
    row_b: Vec<f64>,
    filled: usize,
    /// Per dependent column, the sum of squares of `J_D - J_B C`.
    off: Vec<f64>,
}

impl<'a> BasisRows<'a> {
    fn new(basis: &'a Basis, by: Fold, clamp: &'a [f64]) -> Self {
        let (b, k) = (basis.basis.len(), basis.dependent.len());
        // With few terms and no row clamped (the common case), each row is proved as it comes;
        // otherwise its rows are kept, a block at a time.
        let by_rows = basis.terms.is_some() && clamp.is_empty();
        let kept = if by_rows { 0 } else { QR_BLOCK };
        let (mut single, mut multiple) = (Vec::new(), Vec::new());
        if let (true, Some(terms)) = (by_rows, &basis.terms) {
            let mut start = 0;
            for (j, &end) in terms.ends.iter().enumerate() {
                match &terms.terms[start..end] {
                    &[(l, a)] => single.push((j, l, a)),
                    _ => multiple.push((j, start..end)),
                }
                start = end;
            }
        }
        BasisRows {
            basis,
            acc: match by {
                Fold::Gram => BasisSink::Gram(GramAccumulator::new(b + 1, QR_BLOCK)),
                Fold::Qr => BasisSink::Qr(QrAccumulator::new(b + 1, QR_BLOCK.max(b + 1))),
            },
            clamp,
            row: 0,
            typical_b: vec![0.0; b],
            typical_d: vec![0.0; k],
            block_b: vec![0.0; kept * b],
            block_d: vec![0.0; kept * k],
            rows: vec![0.0; kept * (b + k + 1)],
            by_rows,
            single,
            multiple,
            row_b: vec![0.0; b + 1],
            filled: 0,
            off: vec![0.0; k],
        }
    }

    /// The block of rows kept (none when each row is proved as it comes): its `J_B` and `J_D`
    /// gathered column-major (eight rows at a time), the typical-row sums tallied when some
    /// row is clamped, and `J_D - J_B C` formed down the columns (by a matrix product when the
    /// terms are many).
    fn flush(&mut self) {
        let (ld, f) = (QR_BLOCK, self.filled);
        if f == 0 {
            return;
        }
        let (b, k) = (self.basis.basis.len(), self.basis.dependent.len());
        let w = b + k + 1;
        let rows = &self.rows[..f * w];
        for (t, tile) in rows.chunks(8 * w).enumerate() {
            let columns = self.block_b.chunks_exact_mut(ld).take(b);
            for (c, col) in columns.chain(self.block_d.chunks_exact_mut(ld)).enumerate() {
                for (to, row) in col[8 * t..].iter_mut().zip(tile.chunks_exact(w)) {
                    *to = row[c];
                }
            }
        }
        // While the block is in cache: the typical-row sums (each column's sum takes its rows
        // in order: the tally's sums to the bit)...
        if !self.clamp.is_empty() {
            let first = self.row - f;
            let clamp = |i: usize| self.clamp.get(first + i).copied().unwrap_or(1.0);
            let blocks = [
                (&self.block_b, &mut self.typical_b),
                (&self.block_d, &mut self.typical_d),
            ];
            for (block, sums) in blocks {
                for (j, s) in sums.iter_mut().enumerate() {
                    for (i, &v) in block[j * ld..j * ld + f].iter().enumerate() {
                        let v = v * clamp(i);
                        *s += v * v;
                    }
                }
            }
        }
        // ...then per dependent column the squares of `J_D - J_B C`: with few terms, down each
        // column (its terms' columns subtracted in place), else by a matrix product.
        // `block_d` is spent.
        match &self.basis.terms {
            Some(terms) => {
                for (j, terms) in terms.columns().enumerate() {
                    let d = &mut self.block_d[j * ld..j * ld + f];
                    for &(l, a) in terms {
                        for (e, &v) in d.iter_mut().zip(&self.block_b[l * ld..l * ld + f]) {
                            *e -= a * v;
                        }
                    }
                }
            }
            None => linalg::sub_product_col_major(
                &mut self.block_d,
                &self.block_b,
                ld,
                &self.basis.coef,
                f,
            ),
        }
        for (s, d) in self.off.iter_mut().zip(self.block_d.chunks_exact(ld)) {
            *s += dot(&d[..f], &d[..f]);
        }
        self.filled = 0;
    }

    /// `R` of `[J_B | r]` when every dependent column is within `tol` of its norm from the
    /// basis's span, or it and its combination are both unfelt (below [`UNFELT`] times
    /// [`SLACK`] of the largest column's norm, where the analysis zeroes them), and
    /// `Some(None)` when it is proved but the Gram matrix it was folded into is too
    /// ill-conditioned to give `R`; `None` when the proof fails (non-finite rows too).
    ///
    /// A dependent column's own norm is not summed: it lies within `off` (the norm of
    /// `J_D - J_B C`) of its combination's, `|J_B c|`, which `R_B` or the Gram matrix gives.
    /// So the tests take the bounds that make them stricter: `off <= tol (|J_B c| - off)`,
    /// `|J_B c| + 2 off` for `|J_D| + off`, and the largest norm at least `|J_B c| - off`.
    fn finish(&mut self, tol: f64) -> Option<Option<Matrix>> {
        self.flush();
        let b = self.basis.basis.len();
        let coef = &self.basis.coef;
        // The basis's columns' norms and the combinations' `|J_B c|`: from `R_B`, or from the
        // Gram matrix (`c^T G c`).
        let (rb, norms, combined) = match &mut self.acc {
            BasisSink::Qr(acc) => {
                let mut rb = Matrix::zeros(0, 0);
                acc.r_into(&mut rb);
                let norms = (0..b).map(|j| linalg::col_norm(&rb, j)).collect::<Vec<_>>();
                let combined = combination_norms(coef, CrossProducts::R(&rb));
                (Some(rb), norms, combined)
            }
            BasisSink::Gram(acc) => {
                let mut gram = Matrix::zeros(0, 0);
                acc.gram_into(&mut gram);
                let norms = (0..b).map(|j| gram[(j, j)].max(0.0).sqrt()).collect();
                let combined = combination_norms(coef, CrossProducts::Gram(&gram));
                let f = gram[(b, b)];
                (
                    crate::solve::estimation::solver::augmented_from_gram(&gram, f),
                    norms,
                    combined,
                )
            }
        };
        let off: Vec<f64> = self.off.iter().map(|s| s.sqrt()).collect();
        let largest = norms
            .into_iter()
            .chain(combined.iter().zip(&off).map(|(c, o)| c - o))
            .fold(0.0, f64::max);
        let proved = off
            .iter()
            .zip(&combined)
            .all(|(&off, &c)| off <= tol * (c - off) || c + 2.0 * off <= UNFELT * SLACK * largest);
        if !proved {
            return None;
        }
        // `None` for a Gram matrix too ill-conditioned for `R_B`: the QR pass gives it.
        Some(rb)
    }
}

/// The inner products of the basis's columns: `R_B` (upper triangular, `J_B = Q R_B`), or the
/// Gram matrix `J_B^T J_B` (at least `b` square, the residual's row and column past it
/// ignored).
pub(super) enum CrossProducts<'m> {
    R(&'m Matrix),
    Gram(&'m Matrix),
}

/// Per column `c` of `coef` (`b x k`), `|J_B c|`: `|R_B c|`, or `sqrt(c^T G c)`.
pub(super) fn combination_norms(coef: &Matrix, of: CrossProducts<'_>) -> Vec<f64> {
    let b = coef.nrows();
    (0..coef.ncols())
        .map(|j| match of {
            CrossProducts::R(rb) => (0..b)
                .map(|i| (i..b).map(|l| rb[(i, l)] * coef[(l, j)]).sum::<f64>())
                .map(|v| v * v)
                .sum::<f64>()
                .sqrt(),
            CrossProducts::Gram(gram) => {
                let q: f64 = (0..b)
                    .filter(|&l| coef[(l, j)] != 0.0)
                    .map(|l| {
                        let gc: f64 = (0..b).map(|i| gram[(l, i)] * coef[(i, j)]).sum();
                        coef[(l, j)] * gc
                    })
                    .sum();
                q.max(0.0).sqrt()
            }
        })
        .collect()
}

impl RowSink for BasisRows<'_> {
    fn push(&mut self, row: &[f64]) {
        if self.filled == QR_BLOCK {
            self.flush();
        }
        // The row is `[J_B | J_D | r]` (the problem's columns in that order): its `[J_B | r]`
        // folded now.
        let (b, w) = (self.basis.basis.len(), row.len());
        let put = |to: &mut [f64]| {
            to[..b].copy_from_slice(&row[..b]);
            to[b] = row[w - 1];
        };
        match &mut self.acc {
            BasisSink::Gram(acc) => acc.push_with(put),
            BasisSink::Qr(acc) => {
                put(&mut self.row_b);
                acc.push(&self.row_b);
            }
        }
        self.row += 1;
        match &self.basis.terms {
            // Each dependent column less its few terms, in this row (the columns of one term
            // in a loop of their own: the common case, and the pass's inner loop).
            Some(terms) if self.by_rows => {
                let d = &row[b..];
                for &(j, l, a) in &self.single {
                    let e = d[j] - a * row[l];
                    self.off[j] += e * e;
                }
                for (j, range) in &self.multiple {
                    let e = terms.terms[range.clone()]
                        .iter()
                        .fold(d[*j], |e, &(l, a)| e - a * row[l]);
                    self.off[*j] += e * e;
                }
            }
            // Kept until the block is full (a copy; `flush` gathers it).
            _ => {
                self.rows[self.filled * w..(self.filled + 1) * w].copy_from_slice(row);
                self.filled += 1;
            }
        }
    }
}
