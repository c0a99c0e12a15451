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
    pub fn from_fn(rows: usize, cols: usize, mut f: impl FnMut(usize, usize) -> f64) -> Self {
        let mut m = Matrix::zeros(rows, cols);
        for j in 0..cols {
            for i in 0..rows {
                m.data[j * rows + i] = f(i, j);
            }
        }
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
    pub fn col_mut(&mut self, j: usize) -> &mut [f64] {
        &mut self.data[j * self.rows..(j + 1) * self.rows]
    }

    /// Resizes to `rows x cols` (contents unspecified afterwards), reusing the allocation.
    pub fn resize(&mut self, rows: usize, cols: usize) {
        self.rows = rows;
        self.cols = cols;
        self.data.resize(rows * cols, 0.0);
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
        out.resize(self.cols, self.cols);
        for j in 0..self.cols {
            for i in 0..self.cols {
                out[(i, j)] = self.stack[(i, j)];
            }
        }
    }
}

/// Accumulates `A^T A` of a tall matrix `A` pushed a row at a time, without holding `A`: rows
/// are gathered in blocks of [`QR_BLOCK`] and each block's `B^T B` is added (a matrix product
/// of the block, `cols^2` multiply-adds per row, against about `2 cols^2` for a QR update).
///
/// The entries of `A^T A` are as accurate as `R^T R` from a QR (each is an inner product of two
/// columns); what the Gram matrix loses is the small singular values of `A` (squared, they fall
/// under rounding), so it serves rules that form `A^T A` anyway (Levenberg-Marquardt), not rank
/// decisions.
pub(crate) struct GramAccumulator {
    cols: usize,
    /// The rows pushed since the last fold (`block x cols`, column-major).
    block: Matrix,
    filled: usize,
    gram: Mat<f64>,
}

impl GramAccumulator {
    /// An empty accumulator of `cols` columns, folding every `block` rows.
    pub(crate) fn new(cols: usize, block: usize) -> Self {
        GramAccumulator {
            cols,
            block: Matrix::zeros(block.max(1), cols),
            filled: 0,
            gram: Mat::zeros(cols, cols),
        }
    }

    /// Number of columns.
    pub(crate) fn cols(&self) -> usize {
        self.cols
    }

    /// Starts again from no rows, keeping the allocations.
    pub(crate) fn clear(&mut self) {
        self.gram.fill(0.0);
        self.filled = 0;
    }

    /// Appends one row (length [`GramAccumulator::cols`]).
    pub(crate) fn push(&mut self, row: &[f64]) {
        debug_assert_eq!(row.len(), self.cols);
        if self.filled == self.block.rows {
            self.fold();
        }
        let i = self.filled;
        for (j, &v) in row.iter().enumerate() {
            self.block[(i, j)] = v;
        }
        self.filled += 1;
    }

    fn fold(&mut self) {
        if self.filled == 0 {
            return;
        }
        let b = MatRef::from_column_major_slice_with_stride(
            &self.block.data,
            self.filled,
            self.cols,
            self.block.rows,
        );
        faer::linalg::matmul::matmul(
            self.gram.as_mut(),
            Accum::Add,
            b.transpose(),
            b,
            1.0,
            Par::Seq,
        );
        self.filled = 0;
    }

    /// `A^T A` of all the rows pushed so far (`cols x cols`, symmetric), written to `out`.
    pub(crate) fn gram_into(&mut self, out: &mut Matrix) {
        self.fold();
        out.resize(self.cols, self.cols);
        for j in 0..self.cols {
            for i in 0..self.cols {
                out[(i, j)] = self.gram[(i, j)];
            }
        }
    }
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
        for (rows, block) in [(1, 4), (7, 7), (8, 7), (50, 7), (1000, 64)] {
            let cols = 5;
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
}
