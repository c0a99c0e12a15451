//! The spectrum of the scaled Jacobian, from the `R` of a QR of its rows: the column norms, the
//! singular values, the numerical rank and its gap, the null space and what it leaves
//! determined.

use crate::error::{Error, Result};
use crate::linalg::{self, Matrix, QrAccumulator, RowSink, QR_BLOCK};
use crate::model::params::ParamId;
use crate::model::robot::Robot;
use crate::observe::{Accuracy, Dataset, KeptErrors, RowQuantity};
use crate::solve::problem::Problem;
use crate::warning::Warning;

/// What the rows give: the `R` of the weighted `[J | r]` (`(n + 1)` square, the residual
/// last), and when the rows were at hand, the typical-row information `e_j` and the accuracy.
pub(super) struct Rows {
    /// `R` of the weighted `[J | r]`.
    pub(crate) raug: Matrix,
    /// `e_j` per parameter ([`super::Analysis::typical_row`]), when the rows were at hand
    /// (tallied when some row's weight is clamped, else [`unclamped_typical`]).
    pub typical: Option<Vec<f64>>,
    /// The accuracy at the rows, and each observation's error, when they were evaluated.
    pub accuracy: Option<(Accuracy, KeptErrors)>,
}

/// The rows of `problem` folded into the `R` of a QR, a block at a time, or `known` (an `R`
/// and its `e_j`, at hand from a solver's evaluation).
///
/// The weighted Jacobian is never held: its rows go into the `R` of a QR, a block at a time
/// (the same inner products between columns, n long instead of m; memory flat in m). A block at
/// least n rows long keeps the folds' cost (a QR of R stacked on the block) within a constant
/// of the rows' own, O(m n^2), however many parameters.
pub(super) fn rows(
    robot: &Robot,
    problem: &Problem<'_>,
    clamp: &[f64],
    known: Option<(&Matrix, Option<&[f64]>)>,
    n: usize,
) -> Result<Rows> {
    match known {
        Some((known, e)) if known.nrows() == n + 1 && known.ncols() == n + 1 => {
            let typical =
                match e {
                    Some(e) if e.len() == n => Some(e.to_vec()),
                    Some(_) => return Err(Error::Numerical(
                        "the given typical-row information does not match the parameters analysed"
                            .into(),
                    )),
                    None => None,
                };
            Ok(Rows {
                raug: known.clone(),
                typical,
                accuracy: None,
            })
        }
        Some(_) => Err(Error::Numerical(
            "the given R does not match the parameters analysed".into(),
        )),
        None => {
            let m = problem.rows();
            let mut r = vec![0.0; m];
            let mut acc = QrAccumulator::new(n + 1, QR_BLOCK.max(n + 1));
            // No row clamped (`clamp` empty): `e_j` is the column's norm over `sqrt(m)`, from
            // `R` (below), and there is nothing to tally.
            let (accuracy, errors, typical) = if clamp.is_empty() {
                let (_, accuracy, errors) = problem.evaluate_rows_kept(robot, &mut r, &mut acc);
                (accuracy, errors, None)
            } else {
                let mut tally = TypicalRowTally {
                    acc: &mut acc,
                    clamp,
                    row: 0,
                    sums: vec![0.0; n],
                };
                let (_, accuracy, errors) = problem.evaluate_rows_kept(robot, &mut r, &mut tally);
                let mf = m.max(1) as f64;
                let typical = tally.sums.iter().map(|s| (s / mf).sqrt()).collect();
                (accuracy, errors, Some(typical))
            };
            let mut raug = Matrix::zeros(0, 0);
            acc.r_into(&mut raug);
            let typical = typical.unwrap_or_else(|| unclamped_typical(&raug, n, m));
            Ok(Rows {
                raug,
                typical: Some(typical),
                accuracy: Some((accuracy, errors)),
            })
        }
    }
}

/// The scaled Jacobian's `R`: every column divided by its norm (an unfelt column zeroed), and
/// its singular values and right vectors.
pub(super) struct Scaled {
    /// The norms of the weighted SI columns.
    pub(crate) column_norms: Vec<f64>,
    /// Per column, whether no measurement feels it (a zero column).
    pub unfelt: Vec<bool>,
    /// The parameters of the unfelt columns.
    pub unobservable: Vec<ParamId>,
    /// `R` with unit columns.
    pub r: Matrix,
    /// Its singular values, non-increasing.
    pub values: Vec<f64>,
    /// Its right singular vectors, in the order of the values.
    pub(crate) vectors: Matrix,
}

impl Scaled {
    /// The scaled `R` of the leading `n x n` block of `raug` (the `R` of `W J` alone).
    pub(super) fn of(raug: &Matrix, n: usize, params: &[ParamId]) -> Result<Scaled> {
        let rw = Matrix::from_fn(n, n, |i, j| raug[(i, j)]);
        let column_norms: Vec<f64> = (0..n).map(|j| linalg::col_norm(&rw, j)).collect();
        let max_norm = column_norms.iter().copied().fold(0.0, f64::max);
        let unfelt: Vec<bool> = column_norms
            .iter()
            .map(|&c| c <= 1e-12 * max_norm.max(1e-300))
            .collect();
        let unobservable = (0..n).filter(|&j| unfelt[j]).map(|j| params[j]).collect();
        let mut r = rw;
        for (j, &c) in column_norms.iter().enumerate() {
            // Unobservable columns hold only rounding noise: zero them rather than blow it up.
            let s = if unfelt[j] { 0.0 } else { 1.0 / c };
            linalg::scale_col(&mut r, j, s);
        }
        // Singular values and right vectors of the scaled Jacobian are those of its R (n x n).
        let (values, vectors, _) =
            linalg::right_svd(&r).ok_or_else(|| Error::Numerical("SVD did not converge".into()))?;
        Ok(Scaled {
            column_norms,
            unfelt,
            unobservable,
            r,
            values,
            vectors,
        })
    }
}

/// The singular values of the Jacobian in file units: rows back from weighted to file units,
/// columns to the file's units (`col_factor`); a second pass, again through a QR's `R` only.
pub(super) fn file_singular_values(
    robot: &Robot,
    data: &Dataset,
    problem: &Problem<'_>,
    col_factor: &[f64],
) -> Result<Vec<f64>> {
    let n = col_factor.len();
    let row_scale = file_row_scale(robot, data, problem);
    let fp = problem.clone().with_row_scale(&row_scale);
    let mut r = vec![0.0; problem.rows()];
    let mut acc = QrAccumulator::new(n + 1, QR_BLOCK.max(n + 1));
    fp.evaluate_qr(robot, &mut r, &mut acc);
    let mut raug = Matrix::zeros(0, 0);
    acc.r_into(&mut raug);
    let rf = Matrix::from_fn(n, n, |i, j| raug[(i, j)] * col_factor[j]);
    linalg::singular_values_qr(&rf).ok_or_else(|| Error::Numerical("SVD did not converge".into()))
}

/// The numerical rank of a spectrum and its largest gap.
pub(super) struct Spectrum {
    /// The singular values, non-increasing.
    pub values: Vec<f64>,
    /// Values above `rcond` times the largest.
    pub rank: usize,
    /// The rank the largest gap suggests.
    pub gap_rank: usize,
    /// That gap's ratio.
    pub gap_ratio: f64,
    /// Whether the two agree (at full rank: no gap over 1e3 elsewhere).
    pub consistent: bool,
    /// The largest value.
    pub largest: f64,
}

impl Spectrum {
    /// The rank at `rcond` of the values of `scaled`, and the largest gap (on a log scale)
    /// between consecutive values, `m` rows deep.
    pub(super) fn of(scaled: &Scaled, rcond: f64, m: usize) -> Spectrum {
        let s = &scaled.values;
        let n = s.len();
        let largest = s.first().copied().unwrap_or(0.0);
        let rank = s.iter().filter(|&&v| v > rcond * largest).count();
        // Values below the rounding level of the SVD are all "zero": clamp them there, so that
        // the gap between two rounding-level values (or an exact 0) is not taken for the real
        // one.
        let floor = f64::EPSILON * largest * m.max(n) as f64;
        let (mut gap_rank, mut gap_ratio) = (n, 1.0);
        for i in 0..n.saturating_sub(1) {
            let (a, b) = (s[i].max(floor), s[i + 1].max(floor));
            let ratio = if b > 0.0 { a / b } else { f64::INFINITY };
            if ratio > gap_ratio {
                gap_rank = i + 1;
                gap_ratio = ratio;
            }
        }
        // The tolerance and the largest gap disagree: below full rank, whenever they differ;
        // at full rank, when the spectrum has a clear gap (over 1e3) somewhere else.
        let consistent = gap_rank == rank || (rank == n && gap_ratio <= 1e3);
        Spectrum {
            values: s.clone(),
            rank,
            gap_rank,
            gap_ratio,
            consistent,
            largest,
        }
    }

    /// What the spectrum of `n` parameters warns of: a rank the gap disagrees with, a small
    /// gap, a barely determined direction.
    pub(super) fn warnings(&self, n: usize, rcond: f64) -> Vec<Warning> {
        let (rank, s) = (self.rank, &self.values);
        if !self.consistent {
            vec![Warning::UnclearRank {
                rank,
                rcond,
                gap_rank: self.gap_rank,
                gap_ratio: self.gap_ratio,
            }]
        } else if rank < n && self.gap_ratio < 1e4 {
            vec![Warning::SmallGap {
                rank,
                gap_ratio: self.gap_ratio,
            }]
        } else if rank == n && self.largest > 0.0 && s[n - 1] / self.largest < 1e-6 {
            vec![Warning::BarelyDetermined {
                ratio: s[n - 1] / self.largest,
            }]
        } else {
            Vec::new()
        }
    }
}

/// The null space of the scaled Jacobian past its rank, and what it leaves determined.
pub(super) struct NullSpace {
    /// Its basis in file units (for estimability checks and the reduced form).
    pub file: Vec<Vec<f64>>,
    /// Per parameter, whether it has no component in it (individually determined).
    pub determined: Vec<bool>,
}

impl NullSpace {
    /// The null space of `scaled` past `rank`, in file units through `col_factor`.
    pub(super) fn of(scaled: &Scaled, rank: usize, col_factor: &[f64]) -> NullSpace {
        let n = scaled.column_norms.len();
        let basis: Vec<Vec<f64>> = (rank..n)
            .map(|k| (0..n).map(|j| scaled.vectors[(j, k)]).collect())
            .collect();
        let determined = (0..n)
            .map(|j| basis.iter().map(|v| v[j] * v[j]).sum::<f64>().sqrt() < 1e-6)
            .collect();
        let norms = &scaled.column_norms;
        let file = basis
            .iter()
            .map(|v| {
                (0..n)
                    .map(|j| {
                        if norms[j] > 0.0 {
                            v[j] / norms[j] / col_factor[j]
                        } else {
                            v[j]
                        }
                    })
                    .collect()
            })
            .collect();
        NullSpace { file, determined }
    }
}

/// The rank of the data alone and, per parameter, whether it determines it individually, from
/// the `R` (`(n + 1)` square, the residual last) of the data's weighted `[J | r]`: the same rule
/// as the analysis's (scaled columns, rank at `rcond`, no component in the null space).
pub(super) fn data_determined(raug: &Matrix, n: usize, rcond: f64) -> (usize, Vec<bool>) {
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
pub(super) fn file_row_scale(robot: &Robot, data: &Dataset, problem: &Problem<'_>) -> Vec<f64> {
    let units = robot.units;
    let sigma = problem.row_sigma();
    let mut scale = Vec::with_capacity(problem.rows());
    for o in &data.observations {
        for row in o.rows() {
            let i = scale.len();
            scale.push(match row.quantity {
                RowQuantity::Length => sigma[i] / units.length.metres(),
                RowQuantity::Angle => sigma[i] / units.angle.radians(),
                RowQuantity::Pixel => sigma[i],
            });
        }
    }
    scale
}

/// `x . y`, four partial sums (the order of a dot product's rounding is immaterial here).
pub(super) fn dot(x: &[f64], y: &[f64]) -> f64 {
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

/// `e_j` of rows none of which is clamped, from the `R` of their `[J | r]` (the data's rows
/// only, no prior's): each column's norm over `sqrt(m)`, what the tally of its squares gives
/// (to rounding).
pub(super) fn unclamped_typical(raug: &Matrix, n: usize, m: usize) -> Vec<f64> {
    let root_m = (m.max(1) as f64).sqrt();
    (0..n)
        .map(|j| crate::linalg::col_norm(raug, j) / root_m)
        .collect()
}

/// A [`RowSink`] that passes each row `[J_i | r_i]` on to another (the `R` of a QR, or the
/// fold through a subsample's basis) and adds up, per parameter column, the squares of the
/// row's entries times its clamp factor: the sums behind `e_j` ([`Analysis::typical_row`]),
/// from the same pass that builds `R`.
pub(super) struct TypicalRowTally<'a> {
    /// Where the rows go (the `R` of a QR).
    pub acc: &'a mut dyn RowSink,
    /// Each row's clamp factor.
    pub clamp: &'a [f64],
    /// The rows passed so far.
    pub row: usize,
    /// Per column, the sum of the clamped squares.
    pub sums: Vec<f64>,
}

impl RowSink for TypicalRowTally<'_> {
    fn push(&mut self, row: &[f64]) {
        self.acc.push(row);
        let f = self.clamp.get(self.row).copied().unwrap_or(1.0);
        self.row += 1;
        add_clamped_squares(&mut self.sums, row, f);
    }
}

/// Adds to each of `sums` the square of its entry of `row` times the row's clamp factor `f`
/// (the typical row's sums, one row at a time).
pub(super) fn add_clamped_squares(sums: &mut [f64], row: &[f64], f: f64) {
    for (s, &c) in sums.iter_mut().zip(row) {
        let v = c * f;
        *s += v * v;
    }
}
