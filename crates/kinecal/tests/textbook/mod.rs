//! Textbook least-squares problems, written down from their published tables: the NIST StRD
//! nonlinear regression problems ([`nist`]) and the Moré-Garbow-Hillstrom test set ([`mgh`]),
//! each as a [`kinecal::solve::estimation::LeastSquares`] problem.

pub mod mgh;
pub mod nist;

use kinecal::solve::estimation::{LeastSquares, RowSink};

/// A NIST problem as a least-squares problem: residuals `model(x_i; b) - target_i`.
pub struct NistProblem(pub &'static nist::Nist);

impl LeastSquares for NistProblem {
    fn rows(&self) -> usize {
        self.0.x.len()
    }

    fn cols(&self) -> usize {
        self.0.start1.len()
    }

    fn residuals(&self, b: &[f64], r: &mut [f64]) -> f64 {
        let p = self.0;
        for (i, ri) in r.iter_mut().enumerate() {
            *ri = (p.model)(p.x[i], nist::x2_at(p, i), b) - nist::residual_target(p, i);
        }
        r.iter().map(|v| v * v).sum()
    }

    fn linearize(&self, b: &[f64], r: &mut [f64], rows: &mut dyn RowSink) -> f64 {
        let p = self.0;
        let n = b.len();
        let mut row = vec![0.0; n + 1];
        for (i, ri) in r.iter_mut().enumerate() {
            *ri = (p.model)(p.x[i], nist::x2_at(p, i), b) - nist::residual_target(p, i);
            (p.gradient)(p.x[i], nist::x2_at(p, i), b, &mut row[..n]);
            row[n] = *ri;
            rows.push(&row);
        }
        r.iter().map(|v| v * v).sum()
    }
}

/// An MGH problem as a least-squares problem.
pub struct MghProblem<'a>(pub &'a mgh::Mgh);

impl LeastSquares for MghProblem<'_> {
    fn rows(&self) -> usize {
        self.0.m
    }

    fn cols(&self) -> usize {
        self.0.n
    }

    fn residuals(&self, x: &[f64], r: &mut [f64]) -> f64 {
        (self.0.residuals)(x, r);
        r.iter().map(|v| v * v).sum()
    }

    fn linearize(&self, x: &[f64], r: &mut [f64], rows: &mut dyn RowSink) -> f64 {
        let (m, n) = (self.0.m, self.0.n);
        (self.0.residuals)(x, r);
        let mut jac = vec![0.0; m * n];
        (self.0.jacobian)(x, &mut jac);
        let mut row = vec![0.0; n + 1];
        for i in 0..m {
            row[..n].copy_from_slice(&jac[i * n..(i + 1) * n]);
            row[n] = r[i];
            rows.push(&row);
        }
        r.iter().map(|v| v * v).sum()
    }
}
