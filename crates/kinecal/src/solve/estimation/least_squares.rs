//! What a solver needs of a problem: residuals, and the rows of their Jacobian.
//!
//! A nonlinear least-squares problem minimises `f(x) = sum_i r_i(x)^2` over `n` unknowns `x`
//! from `m` residuals. A calibration's [`Problem`] is one (its
//! residuals weighted by their standard deviations, its unknowns the estimated parameters in
//! internal units); so is any textbook problem a test writes down, which is how the step rules
//! are checked on the NIST StRD and Moré-Garbow-Hillstrom problems. The Jacobian is handed over
//! a row at a time ([`RowSink`]), so the solver never needs an `m x n` matrix.

pub use crate::linalg::RowSink;
use crate::solve::problem::Problem;

/// A nonlinear least-squares problem: `m` residuals `r_i(x)` of `n` unknowns.
pub trait LeastSquares {
    /// `m`, the number of residuals.
    fn rows(&self) -> usize;

    /// `n`, the number of unknowns.
    fn cols(&self) -> usize;

    /// The residuals at `x` into `r` (length `m`); returns `sum r_i^2`, which may be infinite
    /// or NaN where the problem is not defined (the solver then treats the point as worse
    /// than any other).
    fn residuals(&self, x: &[f64], r: &mut [f64]) -> f64;

    /// [`LeastSquares::residuals`], and each row `[dr_i/dx_1 .. dr_i/dx_n | r_i]` (`n + 1`
    /// numbers: the Jacobian row, then the residual) pushed into `rows`, in row order.
    fn linearize(&self, x: &[f64], r: &mut [f64], rows: &mut dyn RowSink) -> f64;
}

/// The calibration as a solver sees it: the unknowns are the estimated parameters (internal
/// units, in [`Problem::estimated`]'s order), the residuals the weighted ones.
impl LeastSquares for Problem<'_> {
    fn rows(&self) -> usize {
        Problem::rows(self)
    }

    fn cols(&self) -> usize {
        Problem::cols(self)
    }

    fn residuals(&self, x: &[f64], r: &mut [f64]) -> f64 {
        self.evaluate(&self.robot_at(x), r, None)
    }

    fn linearize(&self, x: &[f64], r: &mut [f64], rows: &mut dyn RowSink) -> f64 {
        self.evaluate_rows(&self.robot_at(x), r, rows)
    }
}
