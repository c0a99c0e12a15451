//! The one place that talks to the dense linear-algebra crate (faer), so that an upgrade of it
//! touches this file only.

use faer::linalg::solvers::SolveCore;
use faer::{Accum, Mat, Par, Side};

/// A dense column-major matrix of `f64`.
pub type Matrix = Mat<f64>;

/// A zero matrix.
pub fn zeros(rows: usize, cols: usize) -> Matrix {
    Mat::zeros(rows, cols)
}

/// `A^T A` (symmetric, full storage).
pub fn gram(a: &Matrix) -> Matrix {
    let mut out = Mat::zeros(a.ncols(), a.ncols());
    faer::linalg::matmul::matmul(
        out.as_mut(),
        Accum::Replace,
        a.transpose(),
        a.as_ref(),
        1.0,
        Par::Seq,
    );
    out
}

/// `A^T v`.
pub fn at_v(a: &Matrix, v: &[f64]) -> Vec<f64> {
    (0..a.ncols())
        .map(|j| a.col(j).iter().zip(v).map(|(x, y)| x * y).sum())
        .collect()
}

/// `A v`.
pub fn a_v(a: &Matrix, v: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; a.nrows()];
    for (j, &vj) in v.iter().enumerate() {
        if vj != 0.0 {
            for (o, x) in out.iter_mut().zip(a.col(j).iter()) {
                *o += x * vj;
            }
        }
    }
    out
}

/// Euclidean norm of column `j`.
pub fn col_norm(a: &Matrix, j: usize) -> f64 {
    a.col(j).iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// Multiplies column `j` by `s`.
pub fn scale_col(a: &mut Matrix, j: usize, s: f64) {
    for x in a.col_mut(j).iter_mut() {
        *x *= s;
    }
}

/// Solves the symmetric positive definite system `A x = b` by Cholesky; `None` if `A` is not
/// numerically positive definite.
pub fn solve_spd(a: &Matrix, b: &[f64]) -> Option<Vec<f64>> {
    let llt = a.llt(Side::Lower).ok()?;
    let mut rhs = Mat::from_fn(b.len(), 1, |i, _| b[i]);
    llt.solve_in_place_with_conj(faer::Conj::No, rhs.as_mut());
    let x: Vec<f64> = (0..b.len()).map(|i| rhs[(i, 0)]).collect();
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// A thin singular value decomposition `A = U diag(s) V^T`, `s` non-increasing.
pub struct ThinSvd {
    /// Left singular vectors (m x k).
    pub u: Matrix,
    /// Singular values (k).
    pub s: Vec<f64>,
    /// Right singular vectors (n x k).
    pub v: Matrix,
}

/// Thin SVD of `a`; `None` if the iteration did not converge.
pub fn thin_svd(a: &Matrix) -> Option<ThinSvd> {
    let svd = a.thin_svd().ok()?;
    let s = svd.S().column_vector().iter().copied().collect();
    Some(ThinSvd {
        u: svd.U().to_owned(),
        s,
        v: svd.V().to_owned(),
    })
}

/// Singular values of `a`, non-increasing.
pub fn singular_values(a: &Matrix) -> Option<Vec<f64>> {
    a.singular_values().ok()
}
