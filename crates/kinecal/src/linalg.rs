//! Dense linear algebra. [`Matrix`] is kinecal's own column-major matrix (the type public
//! signatures use); this module is also the one place that talks to the dense linear-algebra
//! crate (faer), so that an upgrade of it touches this file only.

use std::ops::{Index, IndexMut};

use faer::linalg::solvers::SolveCore;
use faer::{Accum, Mat, MatRef, Par, Side};

/// A dense column-major matrix of `f64`.
#[derive(Clone, PartialEq)]
pub struct Matrix {
    rows: usize,
    cols: usize,
    data: Vec<f64>,
}

impl std::fmt::Debug for Matrix {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Matrix {}x{}", self.rows, self.cols)
    }
}

impl Matrix {
    /// A zero matrix.
    pub fn zeros(rows: usize, cols: usize) -> Self {
        Matrix {
            rows,
            cols,
            data: vec![0.0; rows * cols],
        }
    }

    /// A matrix with entries `f(i, j)`.
    pub fn from_fn(rows: usize, cols: usize, f: impl FnMut(usize, usize) -> f64) -> Self {
        let mut m = Matrix::zeros(0, 0);
        m.refill(rows, cols, f);
        m
    }

    /// Number of rows.
    pub fn nrows(&self) -> usize {
        self.rows
    }

    /// Number of columns.
    pub fn ncols(&self) -> usize {
        self.cols
    }

    /// Column `j`.
    pub fn col(&self, j: usize) -> &[f64] {
        &self.data[j * self.rows..(j + 1) * self.rows]
    }

    /// Column `j`, mutable.
    pub(crate) fn col_mut(&mut self, j: usize) -> &mut [f64] {
        &mut self.data[j * self.rows..(j + 1) * self.rows]
    }

    /// Resizes to `rows x cols` (contents unspecified afterwards), reusing the allocation.
    pub(crate) fn resize(&mut self, rows: usize, cols: usize) {
        self.rows = rows;
        self.cols = cols;
        self.data.resize(rows * cols, 0.0);
    }

    /// Resizes to `rows x cols`, reusing the allocation, and sets every entry to `f(i, j)`.
    pub(crate) fn refill(
        &mut self,
        rows: usize,
        cols: usize,
        mut f: impl FnMut(usize, usize) -> f64,
    ) {
        self.resize(rows, cols);
        for j in 0..cols {
            for i in 0..rows {
                self.data[j * rows + i] = f(i, j);
            }
        }
    }

    fn faer(&self) -> MatRef<'_, f64> {
        MatRef::from_column_major_slice(&self.data, self.rows, self.cols)
    }
}

impl Index<(usize, usize)> for Matrix {
    type Output = f64;
    #[inline]
    fn index(&self, (i, j): (usize, usize)) -> &f64 {
        debug_assert!(i < self.rows && j < self.cols);
        &self.data[j * self.rows + i]
    }
}

impl IndexMut<(usize, usize)> for Matrix {
    #[inline]
    fn index_mut(&mut self, (i, j): (usize, usize)) -> &mut f64 {
        debug_assert!(i < self.rows && j < self.cols);
        &mut self.data[j * self.rows + i]
    }
}

fn from_faer(m: MatRef<'_, f64>) -> Matrix {
    Matrix::from_fn(m.nrows(), m.ncols(), |i, j| m[(i, j)])
}

/// `A^T A` (symmetric, full storage).
#[cfg(test)]
pub(crate) fn gram(a: &Matrix) -> Matrix {
    let mut out = Mat::zeros(a.ncols(), a.ncols());
    faer::linalg::matmul::matmul(
        out.as_mut(),
        Accum::Replace,
        a.faer().transpose(),
        a.faer(),
        1.0,
        Par::Seq,
    );
    from_faer(out.as_ref())
}

/// `A v`.
pub(crate) fn a_v(a: &Matrix, v: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; a.nrows()];
    for (j, &vj) in v.iter().enumerate() {
        if vj != 0.0 {
            for (o, x) in out.iter_mut().zip(a.col(j)) {
                *o += x * vj;
            }
        }
    }
    out
}

/// Euclidean norm of column `j`.
pub(crate) fn col_norm(a: &Matrix, j: usize) -> f64 {
    a.col(j).iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// Multiplies column `j` by `s`.
pub(crate) fn scale_col(a: &mut Matrix, j: usize, s: f64) {
    for x in a.col_mut(j) {
        *x *= s;
    }
}

/// Solves the symmetric positive definite system `A x = b` by Cholesky; `None` if `A` is not
/// numerically positive definite.
pub(crate) fn solve_spd(a: &Matrix, b: &[f64]) -> Option<Vec<f64>> {
    let llt = a.faer().llt(Side::Lower).ok()?;
    let mut rhs = Mat::from_fn(b.len(), 1, |i, _| b[i]);
    llt.solve_in_place_with_conj(faer::Conj::No, rhs.as_mut());
    let x: Vec<f64> = (0..b.len()).map(|i| rhs[(i, 0)]).collect();
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// A thin singular value decomposition `A = U diag(s) V^T`, `s` non-increasing.
pub(crate) struct ThinSvd {
    /// Left singular vectors (m x k).
    pub u: Matrix,
    /// Singular values (k).
    pub s: Vec<f64>,
    /// Right singular vectors (n x k).
    pub v: Matrix,
}

/// Thin SVD of `a`; `None` if the iteration did not converge.
pub(crate) fn thin_svd(a: &Matrix) -> Option<ThinSvd> {
    let svd = a.faer().thin_svd().ok()?;
    let s = svd.S().column_vector().iter().copied().collect();
    Some(ThinSvd {
        u: from_faer(svd.U()),
        s,
        v: from_faer(svd.V()),
    })
}

/// The singular values (non-increasing) and right singular vectors of `a`, without the left
/// ones: for a tall `a` (m >= n) from the SVD of the n x n `R` of `a = QR` (Householder QR is
/// backward stable, so the small singular values are as accurate as a direct SVD's: to about
/// `eps * s_max`), costing about a quarter of a thin SVD with U and no m x n storage beyond the
/// QR's.
///
/// Also returns `R` (n x n, upper triangular): its columns have the inner products of `a`'s
/// (`a^T a = R^T R`), so anything built from those (projections, residual norms) can work on
/// n-long columns instead of m-long ones. `a` must be tall.
pub(crate) fn right_svd(a: &Matrix) -> Option<(Vec<f64>, Matrix, Matrix)> {
    assert!(a.nrows() >= a.ncols(), "right_svd needs a tall matrix");
    let qr = a.faer().qr();
    let r = qr.thin_R();
    let svd = r.svd().ok()?;
    let s = svd.S().column_vector().iter().copied().collect();
    Some((s, from_faer(svd.V()), from_faer(r)))
}

/// Singular values of `a`, non-increasing (from the `R` of a QR when `a` is tall).
pub(crate) fn singular_values_qr(a: &Matrix) -> Option<Vec<f64>> {
    if a.nrows() < a.ncols() {
        return singular_values(a);
    }
    let qr = a.faer().qr();
    qr.thin_R().singular_values().ok()
}

/// Singular values of `a`, non-increasing.
pub(crate) fn singular_values(a: &Matrix) -> Option<Vec<f64>> {
    a.faer().singular_values().ok()
}

/// The upper-triangular `R` (`cols.len()` square) of the QR of the columns `cols` of `a`:
/// for `a` the `R` of some tall matrix `M`, the `R` of those columns of `M`.
pub(crate) fn r_of_columns(a: &Matrix, cols: &[usize]) -> Matrix {
    let k = cols.len();
    let rows = a.nrows().max(k);
    // Padded with zero rows when `a` has fewer rows than columns wanted (QR of a tall matrix).
    let m = Mat::from_fn(
        rows,
        k,
        |i, j| {
            if i < a.nrows() {
                a[(i, cols[j])]
            } else {
                0.0
            }
        },
    );
    let r = m.qr().thin_R().to_owned();
    Matrix::from_fn(k, k, |i, j| if i <= j { r[(i, j)] } else { 0.0 })
}

/// Rows folded into a [`QrAccumulator`]'s `R` at a time: large enough that the QR of a block
/// runs at matrix speed, small enough (a few hundred KB) that memory does not grow with the
/// postures.
pub(crate) const QR_BLOCK: usize = 512;

/// The `R` factor of a tall matrix's QR, accumulated a block of rows at a time, so that the
/// matrix itself is never held: rows are pushed one by one, and every `block` of them is folded
/// into `R` by a QR of `R` stacked on the block. `R^T R` equals `A^T A` of all the rows pushed
/// (up to rounding), which is all a least-squares step or a rank analysis needs; memory is
/// `(cols + block) x cols` whatever the number of rows.
pub(crate) struct QrAccumulator {
    cols: usize,
    /// `cols + block` rows: `R` on top, then the rows pushed since the last fold.
    stack: Matrix,
    filled: usize,
    /// The Householder coefficients of a fold (not used after it), and the factorization's
    /// workspace: kept, so that folding allocates nothing.
    q_coeff: Mat<f64>,
    workspace: faer::dyn_stack::MemBuffer,
}

impl QrAccumulator {
    /// An empty accumulator of `cols` columns, folding every `block` rows.
    pub(crate) fn new(cols: usize, block: usize) -> Self {
        use faer::linalg::qr::no_pivoting::factor;
        let rows = cols + block.max(1);
        // The block size of the largest fold is the largest of any.
        let bs = factor::recommended_block_size::<f64>(rows, cols);
        QrAccumulator {
            cols,
            stack: Matrix::zeros(rows, cols),
            filled: 0,
            q_coeff: Mat::zeros(bs, cols),
            workspace: faer::dyn_stack::MemBuffer::new(factor::qr_in_place_scratch::<f64>(
                rows,
                cols,
                bs,
                faer::get_global_parallelism(),
                Default::default(),
            )),
        }
    }

    /// Number of columns.
    pub(crate) fn cols(&self) -> usize {
        self.cols
    }

    /// Starts again from no rows, keeping the allocation.
    pub(crate) fn clear(&mut self) {
        self.stack.data.fill(0.0);
        self.filled = 0;
    }

    /// Appends one row (length [`QrAccumulator::cols`]).
    pub(crate) fn push(&mut self, row: &[f64]) {
        debug_assert_eq!(row.len(), self.cols);
        if self.cols + self.filled == self.stack.rows {
            self.fold();
        }
        let i = self.cols + self.filled;
        for (j, &v) in row.iter().enumerate() {
            self.stack[(i, j)] = v;
        }
        self.filled += 1;
    }

    fn fold(&mut self) {
        if self.filled == 0 || self.cols == 0 {
            return;
        }
        use faer::linalg::qr::no_pivoting::factor;
        let (rows, cols) = (self.cols + self.filled, self.cols);
        // Householder QR in place, as faer's `Qr::new` does it (same block size, same
        // parallelism): `R` is left in the upper triangle.
        let bs = factor::recommended_block_size::<f64>(rows, cols);
        let ld = self.stack.rows;
        factor::qr_in_place(
            faer::MatMut::from_column_major_slice_with_stride_mut(
                &mut self.stack.data,
                rows,
                cols,
                ld,
            ),
            self.q_coeff.as_mut().get_mut(..bs, ..),
            faer::get_global_parallelism(),
            faer::dyn_stack::MemStack::new(&mut self.workspace),
            Default::default(),
        );
        // Below `R`: the Householder vectors, cleared for the next rows.
        for j in 0..cols {
            for i in j + 1..rows {
                self.stack[(i, j)] = 0.0;
            }
        }
        self.filled = 0;
    }

    /// The `cols x cols` upper-triangular `R` of all the rows pushed so far, written to `out`.
    pub(crate) fn r_into(&mut self, out: &mut Matrix) {
        self.fold();
        out.refill(self.cols, self.cols, |i, j| self.stack[(i, j)]);
    }
}

/// The Householder reflection `I - tau v v^T` that maps a column `x` (its leading entry
/// `alpha`, `sigma > 0` the sum of squares of the entries below it) onto `mu e1`, `mu = |x|`
/// (Golub and Van Loan's `house`, free of cancellation for either sign of `alpha`). Returns
/// `(mu, beta, tau)`: `v` is 1, then the entries below the leading one divided by `beta`.
pub(crate) fn householder(alpha: f64, sigma: f64) -> (f64, f64, f64) {
    let mu = (alpha * alpha + sigma).sqrt();
    let beta = if alpha <= 0.0 {
        alpha - mu
    } else {
        -sigma / (alpha + mu)
    };
    let tau = 2.0 * beta * beta / (sigma + beta * beta);
    (mu, beta, tau)
}

/// Accumulates `A^T A` of a tall matrix `A` pushed a row at a time, without holding `A`: rows
/// are gathered in blocks of [`QR_BLOCK`] and each block's `B^T B` is added to the lower
/// triangle (a matrix product of the block, `cols^2 / 2` multiply-adds per row, against about
/// `2 cols^2` for a QR update; 0.71 of the whole product's time at 32 columns).
///
/// The entries of `A^T A` are as accurate as `R^T R` from a QR (each is an inner product of two
/// columns); what the Gram matrix loses is the small singular values of `A` (squared, they fall
/// under rounding), so it serves rules that form `A^T A` anyway (Levenberg-Marquardt), not rank
/// decisions.
pub(crate) struct GramAccumulator {
    cols: usize,
    /// The rows pushed since the last fold, row-major (`block x cols`, row `i` at
    /// `i * cols`): a row is one contiguous copy.
    block: Vec<f64>,
    /// The rows `block` holds.
    capacity: usize,
    filled: usize,
    gram: Mat<f64>,
}

impl GramAccumulator {
    /// An empty accumulator of `cols` columns, folding every `block` rows.
    pub(crate) fn new(cols: usize, block: usize) -> Self {
        let capacity = block.max(1);
        GramAccumulator {
            cols,
            block: vec![0.0; capacity * cols],
            capacity,
            filled: 0,
            gram: Mat::zeros(cols, cols),
        }
    }

    /// Starts again from no rows, keeping the allocations.
    pub(crate) fn clear(&mut self) {
        self.gram.fill(0.0);
        self.filled = 0;
    }

    /// Appends one row (length [`GramAccumulator::cols`]).
    pub(crate) fn push(&mut self, row: &[f64]) {
        debug_assert_eq!(row.len(), self.cols);
        self.push_with(|slot| slot.copy_from_slice(row));
    }

    /// Appends one row written in place by `fill` (given the row's [`GramAccumulator::cols`]
    /// entries, to be overwritten whole): a row put together from parts takes no copy of its
    /// own.
    pub(crate) fn push_with(&mut self, fill: impl FnOnce(&mut [f64])) {
        if self.filled == self.capacity {
            self.fold();
        }
        let at = self.filled * self.cols;
        fill(&mut self.block[at..at + self.cols]);
        self.filled += 1;
    }

    fn fold(&mut self) {
        if self.filled == 0 {
            return;
        }
        add_gram_of(&mut self.gram, &self.block, self.filled, self.cols);
        self.filled = 0;
    }

    /// `A^T A` of all the rows pushed so far (`cols x cols`, symmetric), written to `out`.
    pub(crate) fn gram_into(&mut self, out: &mut Matrix) {
        self.fold();
        out.refill(self.cols, self.cols, |i, j| self.gram[(i.max(j), i.min(j))]);
    }
}

/// Adds `B^T B` to the lower triangle of `gram` (the upper one is not kept), `B` the first
/// `rows` rows of the row-major block `block` (`cols` wide): a matrix product.
fn add_gram_of(gram: &mut Mat<f64>, block: &[f64], rows: usize, cols: usize) {
    add_gram(
        gram,
        MatRef::from_row_major_slice(&block[..rows * cols], rows, cols),
    );
}

/// Adds `B^T B` to the lower triangle of `gram` (the upper one is not kept): a matrix product.
fn add_gram(gram: &mut Mat<f64>, b: MatRef<'_, f64>) {
    use faer::linalg::matmul::triangular::{matmul, BlockStructure};
    matmul(
        gram.as_mut(),
        BlockStructure::TriangularLower,
        Accum::Add,
        b.transpose(),
        BlockStructure::Rectangular,
        b,
        BlockStructure::Rectangular,
        1.0,
        Par::Seq,
    );
}

/// `d -= b c` on column-major blocks of `rows` rows (leading dimension `ld`, entry `(i, j)` at
/// `[j * ld + i]`): `d` (`rows x k`) less the first `l` columns of `b` times `c` (`l x k`), a
/// matrix product.
pub(crate) fn sub_product_col_major(d: &mut [f64], b: &[f64], ld: usize, c: &Matrix, rows: usize) {
    let (l, k) = (c.rows, c.cols);
    if rows == 0 || k == 0 {
        return;
    }
    assert!(ld >= rows && d.len() >= (k - 1) * ld + rows);
    assert!(l == 0 || b.len() >= (l - 1) * ld + rows);
    let dst = faer::MatMut::from_column_major_slice_with_stride_mut(d, rows, k, ld);
    let lhs = MatRef::from_column_major_slice_with_stride(b, rows, l, ld);
    faer::linalg::matmul::matmul(dst, Accum::Add, lhs, c.faer(), -1.0, Par::Seq);
}

/// Something rows of a tall matrix are pushed into, one at a time: the `R` of a QR being
/// accumulated, a Gram matrix `A^T A`, or a test's dense matrix. A least-squares problem
/// hands its Jacobian to a solver this way ([`crate::solve::estimation::LeastSquares`]), so that no
/// m x n matrix need exist.
pub trait RowSink {
    /// Appends one row (its length is the sink's number of columns).
    fn push(&mut self, row: &[f64]);
}

impl RowSink for QrAccumulator {
    fn push(&mut self, row: &[f64]) {
        QrAccumulator::push(self, row);
    }
}

impl RowSink for GramAccumulator {
    fn push(&mut self, row: &[f64]) {
        GramAccumulator::push(self, row);
    }
}

/// Column norms within this relative distance of the largest are tied: a pivoted QR then
/// takes the first of them in its order of preference, so that the choice among identical or
/// opposite columns is deterministic (and follows the caller's priorities), not rounding's.
const TIE: f64 = 1e-10;

/// The QR factorization with column pivoting `A P = Q T` of a small dense matrix (Householder
/// reflections; Businger and Golub, 1965): at each step the remaining column of largest norm
/// (orthogonal to the columns already taken) is brought forward, so `|T_00| >= |T_11| >= ...`
/// and the diagonal reveals the numerical rank. Column norms are downdated after each step and
/// recomputed when cancellation has eaten half their digits (LAPACK's `dgeqp3` safeguard), so
/// the whole costs `O(m n^2)`.
///
/// Ties (norms within 1e-10 relative of the largest) go to the column listed first in the
/// `order` given to [`PivotedQr::with_order`] (by default, the lowest index).
#[derive(Debug, Clone)]
pub(crate) struct PivotedQr {
    /// `T` (upper triangular, `min(m, n) x n`, column `k` is column `perm[k]` of `A`).
    t: Matrix,
    /// The Householder vectors (below the diagonal, column `k` for step `k`; `v_k = 1` at
    /// `k`) and their coefficients.
    v: Matrix,
    tau: Vec<f64>,
    /// `perm[k]`: the column of `A` in position `k`.
    perm: Vec<usize>,
}

impl PivotedQr {
    /// `A P = Q T`, ties to the lowest index.
    pub fn new(a: &Matrix) -> Self {
        let order: Vec<usize> = (0..a.ncols()).collect();
        Self::with_order(a, &order)
    }

    /// `A P = Q T`, ties to the column listed first in `order` (a permutation of the columns).
    pub(crate) fn with_order(a: &Matrix, order: &[usize]) -> Self {
        let (m, n) = (a.nrows(), a.ncols());
        assert_eq!(order.len(), n, "order must list every column");
        let steps = m.min(n);
        // Work on the columns in preference order; `perm` maps back.
        let mut w = Matrix::from_fn(m, n, |i, j| a[(i, order[j])]);
        let mut perm = order.to_vec();
        // The preference of each column of `A`: its place in `order`.
        let mut pref = vec![0; n];
        for (k, &c) in order.iter().enumerate() {
            pref[c] = k;
        }
        let mut norms: Vec<f64> = (0..n).map(|j| col_norm(&w, j)).collect();
        let mut exact = norms.clone();
        let mut tau = vec![0.0; steps];
        for k in 0..steps {
            // Pivot: the largest remaining norm, the first in preference order among ties.
            let big = norms[k..].iter().copied().fold(0.0, f64::max);
            let p = (k..n)
                .filter(|&j| norms[j] >= big * (1.0 - TIE))
                .min_by_key(|&j| pref[perm[j]])
                .unwrap_or(k);
            if p != k {
                for i in 0..m {
                    let tmp = w[(i, k)];
                    w[(i, k)] = w[(i, p)];
                    w[(i, p)] = tmp;
                }
                perm.swap(k, p);
                norms.swap(k, p);
                exact.swap(k, p);
            }
            // Householder reflection zeroing w[k+1.., k].
            let alpha = w[(k, k)];
            let sigma: f64 = (k + 1..m).map(|i| w[(i, k)] * w[(i, k)]).sum();
            if sigma == 0.0 {
                tau[k] = 0.0;
            } else {
                let (mu, beta, t) = householder(alpha, sigma);
                tau[k] = t;
                for i in k + 1..m {
                    w[(i, k)] /= beta;
                }
                w[(k, k)] = mu;
                // Apply (I - tau v v^T) to the remaining columns.
                for j in k + 1..n {
                    let mut s = w[(k, j)];
                    for i in k + 1..m {
                        s += w[(i, k)] * w[(i, j)];
                    }
                    s *= tau[k];
                    w[(k, j)] -= s;
                    for i in k + 1..m {
                        let vik = w[(i, k)];
                        w[(i, j)] -= s * vik;
                    }
                }
            }
            // Downdate the remaining norms (recompute when cancellation is severe).
            for j in k + 1..n {
                if norms[j] == 0.0 {
                    continue;
                }
                let ratio = w[(k, j)].abs() / norms[j];
                let left = (1.0 - ratio * ratio).max(0.0);
                let updated = norms[j] * left.sqrt();
                if left * (norms[j] / exact[j]).powi(2) <= 1e-8 {
                    let s: f64 = (k + 1..m).map(|i| w[(i, j)] * w[(i, j)]).sum();
                    norms[j] = s.sqrt();
                    exact[j] = norms[j];
                } else {
                    norms[j] = updated;
                }
            }
        }
        let t = Matrix::from_fn(steps, n, |i, j| if i <= j { w[(i, j)] } else { 0.0 });
        let v = Matrix::from_fn(m, steps, |i, j| {
            if i > j {
                w[(i, j)]
            } else if i == j {
                1.0
            } else {
                0.0
            }
        });
        PivotedQr { t, v, tau, perm }
    }

    /// `T`: upper triangular, `min(m, n) x n`.
    pub fn t(&self) -> &Matrix {
        &self.t
    }

    /// The permutation: `perm()[k]` is the column of `A` in position `k`.
    pub(crate) fn perm(&self) -> &[usize] {
        &self.perm
    }

    /// `|T_kk|`, the diagonal's magnitudes (non-increasing up to the ties' tolerance).
    pub fn diagonal(&self) -> Vec<f64> {
        (0..self.t.nrows()).map(|k| self.t[(k, k)].abs()).collect()
    }

    /// The numerical rank: the number of diagonal entries above `rcond` times the first.
    pub fn rank(&self, rcond: f64) -> usize {
        let d = self.diagonal();
        let first = d.first().copied().unwrap_or(0.0);
        d.iter()
            .take_while(|&&x| x > rcond * first && x > 0.0)
            .count()
    }

    /// `Q b` in place (`b` has `m` entries).
    pub(crate) fn apply_q(&self, b: &mut [f64]) {
        let m = self.v.nrows();
        assert_eq!(b.len(), m);
        for k in (0..self.tau.len()).rev() {
            let v = &self.v.col(k)[k..];
            let s = self.tau[k] * v.iter().zip(&b[k..]).map(|(x, y)| x * y).sum::<f64>();
            for (bi, vi) in b[k..].iter_mut().zip(v) {
                *bi -= s * vi;
            }
        }
    }

    /// `Q^T b` in place (`b` has `m` entries).
    pub(crate) fn apply_qt(&self, b: &mut [f64]) {
        let m = self.v.nrows();
        assert_eq!(b.len(), m);
        for k in 0..self.tau.len() {
            let v = &self.v.col(k)[k..];
            let s = self.tau[k] * v.iter().zip(&b[k..]).map(|(x, y)| x * y).sum::<f64>();
            for (bi, vi) in b[k..].iter_mut().zip(v) {
                *bi -= s * vi;
            }
        }
    }
}

/// The minimum-norm least-squares solution of `T u = -w` restricted to the leading `rank` rows
/// of an upper-triangular (pivoted-QR) factor `T` (`rank x n`, the rows below taken as zero):
/// back substitution when the columns beyond `rank` are zero there (a basic solution that is
/// also the shortest), else through a QR of `T[..rank, ..]^T` (a complete orthogonal
/// decomposition): `T_k = P S^T Q^T`, `u = Q S^-T P^T (-w)`. Identical columns then share a
/// change equally instead of one of them taking all of it.
pub(crate) fn min_norm_solve(t: &Matrix, w: &[f64], rank: usize) -> Vec<f64> {
    let n = t.ncols();
    let neg: Vec<f64> = w[..rank].iter().map(|v| -v).collect();
    let coupled = (0..rank).any(|i| (rank..n).any(|j| t[(i, j)] != 0.0));
    if !coupled {
        let mut u = solve_upper(t, &neg, rank);
        u.resize(n, 0.0);
        return u;
    }
    let at = Matrix::from_fn(n, rank, |i, j| t[(j, i)]);
    let qr = PivotedQr::new(&at);
    // A = T_k, A^T P = Q S: A = P S^T Q^T; A u = b with u = Q c: P S^T c = b, S^T c = P^T b.
    let pb: Vec<f64> = qr.perm().iter().map(|&i| neg[i]).collect();
    let c = solve_upper_transposed(qr.t(), &pb, rank);
    let mut u = vec![0.0; n];
    u[..rank].copy_from_slice(&c);
    qr.apply_q(&mut u);
    u
}

/// The standard deviations of least-squares estimates of the columns `cols` of a tall matrix
/// `A` (given by its `R`, `a`: the same inner products) estimated together with unit-variance
/// residuals: `sqrt(diag((A_S^T A_S)^-1))`, the row norms of `R_S^-1` (`R_S` the `R` of the
/// chosen columns). Infinite for a column dependent on the others.
pub(crate) fn marginal_sigmas(a: &Matrix, cols: &[usize]) -> Vec<f64> {
    let k = cols.len();
    let r = r_of_columns(a, cols);
    // R^-1 column by column (upper triangular), accumulating the squared row norms.
    let mut sq = vec![0.0; k];
    let mut x = vec![0.0; k];
    for c in 0..k {
        x.fill(0.0);
        for i in (0..=c).rev() {
            let mut s = if i == c { 1.0 } else { 0.0 };
            for (j, xj) in x.iter().enumerate().take(c + 1).skip(i + 1) {
                s -= r[(i, j)] * xj;
            }
            x[i] = s / r[(i, i)];
        }
        for (q, v) in sq.iter_mut().zip(&x) {
            *q += v * v;
        }
    }
    sq.iter()
        .map(|v| {
            if v.is_finite() {
                v.sqrt()
            } else {
                f64::INFINITY
            }
        })
        .collect()
}

/// Solves `T x = b` for the leading `k x k` block of the upper-triangular `t` (back
/// substitution); `x` has `k` entries.
pub(crate) fn solve_upper(t: &Matrix, b: &[f64], k: usize) -> Vec<f64> {
    let mut x = b[..k].to_vec();
    for i in (0..k).rev() {
        let mut s = x[i];
        for j in i + 1..k {
            s -= t[(i, j)] * x[j];
        }
        x[i] = s / t[(i, i)];
    }
    x
}

/// Solves `T^T x = b` for the leading `k x k` block of the upper-triangular `t` (forward
/// substitution).
pub(crate) fn solve_upper_transposed(t: &Matrix, b: &[f64], k: usize) -> Vec<f64> {
    let mut x = b[..k].to_vec();
    for i in 0..k {
        let mut s = x[i];
        for j in 0..i {
            s -= t[(j, i)] * x[j];
        }
        x[i] = s / t[(i, i)];
    }
    x
}

/// The lower Cholesky factor `L` of a symmetric positive definite matrix (`A = L L^T`), or
/// `None` when a pivot is not positive.
pub(crate) fn cholesky(a: &Matrix) -> Option<Matrix> {
    let n = a.ncols();
    let mut l = Matrix::zeros(n, n);
    for j in 0..n {
        let mut d = a[(j, j)];
        for k in 0..j {
            d -= l[(j, k)] * l[(j, k)];
        }
        if d.is_nan() || d <= 0.0 {
            return None;
        }
        let d = d.sqrt();
        l[(j, j)] = d;
        for i in j + 1..n {
            let mut s = a[(i, j)];
            for k in 0..j {
                s -= l[(i, k)] * l[(j, k)];
            }
            l[(i, j)] = s / d;
        }
    }
    Some(l)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn svd_reconstructs_and_gram_is_a_transpose_a() {
        let a = Matrix::from_fn(5, 3, |i, j| {
            ((i * 3 + j) as f64).sin() + (i == j) as u8 as f64
        });
        let svd = thin_svd(&a).unwrap();
        for i in 0..5 {
            for j in 0..3 {
                let r: f64 = (0..3)
                    .map(|k| svd.u[(i, k)] * svd.s[k] * svd.v[(j, k)])
                    .sum();
                assert!((r - a[(i, j)]).abs() < 1e-12);
            }
        }
        let g = gram(&a);
        for p in 0..3 {
            for q in 0..3 {
                let d: f64 = (0..5).map(|i| a[(i, p)] * a[(i, q)]).sum();
                assert!((g[(p, q)] - d).abs() < 1e-12);
            }
        }
        let x = solve_spd(&g, &[1.0, 2.0, 3.0]).unwrap();
        let gx = a_v(&g, &x);
        assert!((gx[0] - 1.0).abs() + (gx[1] - 2.0).abs() + (gx[2] - 3.0).abs() < 1e-10);
    }

    /// The accumulated R against the matrix it summarises: R^T R = A^T A (the normal
    /// equations, formed directly) and the same singular values as the QR of all of A, for row
    /// counts below, at and across block boundaries, including fewer rows than columns.
    #[test]
    fn accumulated_r_summarises_every_row_pushed() {
        for (rows, block) in [(2, 4), (7, 7), (8, 7), (50, 7), (1000, 64)] {
            let cols = 5;
            let a = Matrix::from_fn(rows, cols, |i, j| {
                ((i * 7 + j * 3) as f64 * 0.37).sin() + 0.1 * (j as f64) * (i % 3) as f64
            });
            let mut acc = QrAccumulator::new(cols, block);
            let mut row = vec![0.0; cols];
            for i in 0..rows {
                for (j, v) in row.iter_mut().enumerate() {
                    *v = a[(i, j)];
                }
                acc.push(&row);
            }
            let mut r = Matrix::zeros(0, 0);
            acc.r_into(&mut r);
            let (g, rtr) = (gram(&a), gram(&r));
            let scale = (0..cols).map(|j| g[(j, j)]).fold(0.0, f64::max);
            for i in 0..cols {
                for j in 0..cols {
                    assert!(
                        (g[(i, j)] - rtr[(i, j)]).abs() < 1e-12 * scale,
                        "{rows} rows, block {block}: ({i},{j}) {} vs {}",
                        g[(i, j)],
                        rtr[(i, j)]
                    );
                }
                for k in i + 1..cols {
                    assert!(r[(k, i)].abs() < f64::MIN_POSITIVE, "R is upper triangular");
                }
            }
            let (sa, sr) = (singular_values(&a).unwrap(), singular_values(&r).unwrap());
            for (x, y) in sa.iter().zip(&sr) {
                assert!((x - y).abs() < 1e-12 * sa[0], "{rows} rows: {x} vs {y}");
            }
            // Cleared, it starts again from no rows.
            acc.clear();
            acc.push(&row);
            acc.r_into(&mut r);
            let n2: f64 = row.iter().map(|v| v * v).sum();
            assert!((gram(&r)[(0, 0)] - row[0] * row[0]).abs() < 1e-12 * n2);
        }
    }

    #[test]
    fn accumulated_gram_is_a_transpose_a() {
        // 40 columns: the triangular product splits into blocks (its lower triangle only).
        for (rows, block, cols) in [
            (1, 4, 5),
            (7, 7, 5),
            (8, 7, 5),
            (50, 7, 5),
            (1000, 64, 5),
            (1200, 512, 40),
        ] {
            let a = Matrix::from_fn(rows, cols, |i, j| {
                ((i * 7 + j * 3) as f64 * 0.37).sin() + 0.1 * (j as f64) * (i % 3) as f64
            });
            let mut acc = GramAccumulator::new(cols, block);
            let mut row = vec![0.0; cols];
            // Twice: clearing starts again from no rows.
            for _ in 0..2 {
                acc.clear();
                for i in 0..rows {
                    for (j, v) in row.iter_mut().enumerate() {
                        *v = a[(i, j)];
                    }
                    acc.push(&row);
                }
                let mut g = Matrix::zeros(0, 0);
                acc.gram_into(&mut g);
                // Against the inner products summed one term at a time.
                for i in 0..cols {
                    for j in 0..cols {
                        let direct: f64 = (0..rows).map(|k| a[(k, i)] * a[(k, j)]).sum();
                        let size: f64 = (0..rows).map(|k| (a[(k, i)] * a[(k, j)]).abs()).sum();
                        assert!(
                            (g[(i, j)] - direct).abs() <= 1e-13 * size.max(1e-300),
                            "{rows} rows, block {block}: ({i},{j}) {} vs {direct}",
                            g[(i, j)]
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn r_of_some_columns_is_the_r_of_those_columns_of_the_tall_matrix() {
        let (rows, cols) = (40, 6);
        let a = Matrix::from_fn(rows, cols, |i, j| ((i * 5 + j * 11) as f64 * 0.21).cos());
        let mut acc = QrAccumulator::new(cols, 16);
        let mut row = vec![0.0; cols];
        for i in 0..rows {
            for (j, v) in row.iter_mut().enumerate() {
                *v = a[(i, j)];
            }
            acc.push(&row);
        }
        let mut r = Matrix::zeros(0, 0);
        acc.r_into(&mut r);
        for pick in [vec![0, 2, 5], vec![4, 1], vec![5], vec![0, 1, 2, 3, 4, 5]] {
            let sub = r_of_columns(&r, &pick);
            let direct = Matrix::from_fn(rows, pick.len(), |i, j| a[(i, pick[j])]);
            // R_S^T R_S is the Gram matrix of the chosen columns, R_S upper triangular.
            let (g, rtr) = (gram(&direct), gram(&sub));
            for i in 0..pick.len() {
                for j in 0..pick.len() {
                    assert!((g[(i, j)] - rtr[(i, j)]).abs() < 1e-12 * rows as f64);
                }
                for k in i + 1..pick.len() {
                    assert!(sub[(k, i)].abs() < f64::MIN_POSITIVE);
                }
            }
        }
    }

    /// The pivoted QR reconstructs `A P`, orders its diagonal, reveals the rank of a matrix with
    /// dependent columns, breaks exact ties by the order given, and `Q` is orthogonal.
    #[test]
    fn pivoted_qr_reconstructs_and_reveals_rank() {
        let (m, n) = (7, 5);
        let mut a = Matrix::from_fn(m, n, |i, j| {
            ((i * i * 5 + j * j * 3 + i * j) as f64 * 0.77).sin()
        });
        // Column 3 = column 0 - 2 column 1: rank 4.
        for i in 0..m {
            a[(i, 3)] = a[(i, 0)] - 2.0 * a[(i, 1)];
        }
        let qr = PivotedQr::new(&a);
        let d = qr.diagonal();
        for k in 1..d.len() {
            assert!(d[k] <= d[k - 1] * (1.0 + 1e-9));
        }
        assert_eq!(qr.rank(1e-9), 4);
        // Q T = A P, column by column.
        for k in 0..n {
            let mut col = vec![0.0; m];
            for (i, c) in col.iter_mut().enumerate().take(qr.t().nrows()) {
                *c = qr.t()[(i, k)];
            }
            qr.apply_q(&mut col);
            for i in 0..m {
                assert!((col[i] - a[(i, qr.perm()[k])]).abs() < 1e-12);
            }
        }
        // Q^T Q b = b.
        let mut b: Vec<f64> = (0..m).map(|i| i as f64 - 2.5).collect();
        let orig = b.clone();
        qr.apply_qt(&mut b);
        qr.apply_q(&mut b);
        for (x, y) in b.iter().zip(&orig) {
            assert!((x - y).abs() < 1e-12);
        }
        // Two identical columns: the one listed first in the order wins.
        let mut c = Matrix::from_fn(m, 3, |i, j| ((i + j) as f64 * 0.3).cos());
        for i in 0..m {
            c[(i, 2)] = c[(i, 0)];
        }
        assert_eq!(PivotedQr::with_order(&c, &[2, 1, 0]).perm()[0], 2);
        assert_eq!(PivotedQr::with_order(&c, &[0, 1, 2]).perm()[0], 0);
    }

    /// The minimum-norm solution against the pseudo-inverse (by SVD) on a rank-deficient
    /// triangular factor; and the Cholesky factor reconstructs its matrix.
    #[test]
    fn min_norm_solve_is_the_pseudo_inverse_solution() {
        let (m, n) = (8, 4);
        let mut a = Matrix::from_fn(m, n, |i, j| {
            ((i * i * 3 + j * j * 7 + 2 * i * j) as f64 * 0.41).cos()
        });
        for i in 0..m {
            a[(i, 2)] = a[(i, 0)]; // identical columns: the change is shared
        }
        let qr = PivotedQr::new(&a);
        let rank = qr.rank(1e-9);
        assert_eq!(rank, 3);
        let w: Vec<f64> = (0..n).map(|i| 1.0 + i as f64).collect();
        let u = min_norm_solve(qr.t(), &w, rank);
        let svd = thin_svd(qr.t()).unwrap();
        let mut want = vec![0.0; n];
        for k in 0..svd.s.len() {
            if svd.s[k] > 1e-9 * svd.s[0] {
                let c = -(0..n).map(|i| svd.u[(i, k)] * w[i]).sum::<f64>() / svd.s[k];
                for (j, wj) in want.iter_mut().enumerate() {
                    *wj += c * svd.v[(j, k)];
                }
            }
        }
        for (x, y) in u.iter().zip(&want) {
            assert!((x - y).abs() < 1e-10, "{u:?} vs {want:?}");
        }
        let g = gram(&a);
        let mut g2 = g.clone();
        for i in 0..n {
            g2[(i, i)] += 1.0;
        }
        let l = cholesky(&g2).unwrap();
        for i in 0..n {
            for j in 0..n {
                let llt: f64 = (0..n).map(|k| l[(i, k)] * l[(j, k)]).sum();
                assert!((llt - g2[(i, j)]).abs() < 1e-12);
            }
        }
        assert!(cholesky(&g).is_none() || cholesky(&g).unwrap()[(3, 3)].abs() < 1e-6);
    }

    /// The block product against three loops, on column-major blocks longer than the rows
    /// the product reads (a leading dimension past them), and wider (columns it does not read).
    #[test]
    fn sub_product_col_major_is_the_product() {
        let (rows, l, k, w, ld) = (7, 3, 2, 5, 9);
        let b: Vec<f64> = (0..w * ld).map(|i| (i as f64 * 0.37).sin()).collect();
        let mut d: Vec<f64> = (0..k * ld).map(|i| (i as f64 * 0.11).cos()).collect();
        let c = Matrix::from_fn(l, k, |i, j| (i * 3 + j) as f64 * 0.5 - 1.0);
        let mut want = d.clone();
        for i in 0..rows {
            for j in 0..k {
                for p in 0..l {
                    want[j * ld + i] -= b[p * ld + i] * c[(p, j)];
                }
            }
        }
        sub_product_col_major(&mut d, &b, ld, &c, rows);
        for (x, y) in d.iter().zip(&want) {
            assert!((x - y).abs() < 1e-14, "{d:?} vs {want:?}");
        }
    }
}
