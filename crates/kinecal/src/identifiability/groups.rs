//! Identically redundant parameters (thesis 4.4.3: equal or opposite Jacobian columns at every
//! posture) and directions written in reduced form.

use crate::model::params::ParamId;
use crate::model::robot::Robot;

use super::spectrum::{dot, NullSpace, Scaled};
use super::{fmt_sig, IdenticalGroup};

/// The groups of parameters whose scaled columns are equal or opposite, each with the
/// combination the data determines (file units, first member 1) and whether it does.
pub(super) fn identical(
    robot: &Robot,
    params: &[ParamId],
    scaled: &Scaled,
    null: &NullSpace,
    col_factor: &[f64],
) -> Vec<IdenticalGroup> {
    let n = params.len();
    let (r, norms, unfelt) = (&scaled.r, &scaled.column_norms, &scaled.unfelt);
    let mut group_of: Vec<Option<usize>> = vec![None; n];
    let mut groups: Vec<Vec<(usize, f64)>> = Vec::new();
    // R is upper triangular: a column's entries below its last non-zero one add nothing to an
    // inner product (a third of the work of full columns, over all pairs).
    let height: Vec<usize> = (0..n)
        .map(|j| {
            r.col(j)
                .iter()
                .rposition(|&x| x != 0.0)
                .map_or(0, |k| k + 1)
        })
        .collect();
    for i in 0..n {
        if group_of[i].is_some() || norms[i] == 0.0 || unfelt[i] {
            continue;
        }
        let mut g = vec![(i, 1.0)];
        for j in i + 1..n {
            if group_of[j].is_some() || unfelt[j] {
                continue;
            }
            // On R's columns: the same inner products as the Jacobian's, n long instead of m.
            let h = height[i].min(height[j]);
            let dot = dot(&r.col(i)[..h], &r.col(j)[..h]);
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
    let file_norm = |j: usize| norms[j] * col_factor[j];
    groups
        .iter()
        .map(|g| {
            let first = g[0].0;
            let terms: Vec<(ParamId, f64)> = g
                .iter()
                .map(|&(j, sign)| (params[j], tidy_coef(sign * file_norm(j) / file_norm(first))))
                .collect();
            let value = terms.iter().map(|&(id, c)| c * robot.get_user(id)).sum();
            // Determined iff the combination does not change along any undetermined direction.
            let determined = null.file.iter().all(|nv| {
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
        .collect()
}

/// The null space (file units) in reduced form, its pivots on the least preferred parameters
/// (`order`: the columns by preference).
pub(super) fn reduced_null_space(
    file_null: &[Vec<f64>],
    order: &[usize],
    params: &[ParamId],
) -> Vec<Vec<(ParamId, f64)>> {
    let reverse: Vec<usize> = order.iter().rev().copied().collect();
    reduced_form(file_null, &reverse)
        .into_iter()
        .map(|row| {
            row.into_iter()
                .map(|(j, c)| (params[j], tidy_coef(c)))
                .collect()
        })
        .collect()
}

/// Rounds coefficients within 1e-9 of an integer to it, and drops float noise.
pub(super) fn tidy_coef(c: f64) -> f64 {
    let r = c.round();
    if (c - r).abs() < 1e-9 {
        r
    } else {
        c
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
