//! Several placements of the instrument pooled in one file without a `session` column.
//!
//! A tracker moved between series measures each series in a frame of its own. Pooled in one
//! file without a `session` column, the series cannot be fitted by one placement of the
//! measurement frame: the fit ends metres off, and what the data look like (a spread unlike the
//! robot's) suggests wrong length units. [`pooled_placements`] recognises the pattern before
//! any solving: the rows, in file order, fall into contiguous blocks each fitted by a rigid
//! placement of its own (the measurement frame and the measured frames placed in closed form,
//! the nominal robot held) to within 2 % of the reach, where one placement for all is not;
//! blocks that one placement fits together are one group. Nothing of this runs on data with
//! sessions, or when one placement fits all the rows.

use std::ops::Range;

use nalgebra::Vector3;

use crate::model::kinematics::Chain;
use crate::model::params::ParamId;
use crate::model::robot::Robot;
use crate::observe::{Dataset, Observation};
use crate::solve::registration::register;
use crate::units::Quantity;
use crate::warning::Warning;

/// Rows a block is first placed on (and grown by at a time).
const SEED_ROWS: usize = 12;

/// Consecutive rows beyond the tolerance that end a block (fewer are outliers).
const RUN: usize = 3;

/// One measured position, in file order.
struct Row {
    posture: usize,
    line: usize,
    target: crate::Target,
    position: Vector3<f64>,
}

/// The measured positions of `data` (positions and poses), in file order.
fn rows_of(data: &Dataset) -> Vec<Row> {
    let mut rows = Vec::with_capacity(data.observations.len());
    rows.extend(data.observations.iter().filter_map(|o| {
        let position = match o {
            Observation::Position(p) => p.position,
            Observation::Pose(p) => p.position,
            _ => return None,
        };
        let view = o.views().first()?;
        Some(Row {
            posture: view.posture,
            line: o.line(),
            target: view.target,
            position,
        })
    }));
    rows
}

/// `robot` with its measurement and measured frames placed in closed form on `rows` (the robot
/// as it is when that fails or does not help).
fn place(robot: &Robot, data: &Dataset, rows: &[&Row], ids: &[ParamId]) -> Robot {
    let mut keep = vec![false; data.postures.len()];
    for r in rows {
        keep[r.posture] = true;
    }
    register(robot, &data.subset(&keep), ids).map_or_else(|| robot.clone(), |r| r.robot)
}

/// The distance (m) between where `robot` puts each of `rows` and where it was measured.
fn misfits<'a>(robot: &Robot, data: &Dataset, rows: impl Iterator<Item = &'a Row>) -> Vec<f64> {
    let chain = Chain::new(robot);
    rows.map(|r| {
        let at = chain.frame_at(&data.postures[r.posture].readings, r.target);
        (at.translation - r.position).norm()
    })
    .collect()
}

/// The RMS distance (m) between the measured positions of `data` and the nominal robot's
/// (`predicted`, per observation), after the best rigid motion of the measured ones (Kabsch);
/// `None` without positions or when the motion is undetermined. Passes over the observations
/// (no copy of the pairs: memory flat in the number of postures).
fn rigid_rms(data: &Dataset, predicted: &[[Vector3<f64>; 2]]) -> Option<f64> {
    let pairs = || {
        data.observations
            .iter()
            .zip(predicted)
            .filter_map(|(o, p)| match o {
                Observation::Position(m) => Some((p[0], m.position)),
                Observation::Pose(m) => Some((p[0], m.position)),
                _ => None,
            })
    };
    let count = pairs().count();
    if count < 3 {
        return None;
    }
    let n = count as f64;
    let (cp, cm) = pairs().fold((Vector3::zeros(), Vector3::zeros()), |a, (p, m)| {
        (a.0 + p / n, a.1 + m / n)
    });
    let h = pairs().fold(nalgebra::Matrix3::zeros(), |h, (p, m)| {
        h + (m - cm) * (p - cp).transpose()
    });
    let svd = h.svd(true, true);
    let (u, vt) = (svd.u?, svd.v_t?);
    let mut d = nalgebra::Matrix3::identity();
    d[(2, 2)] = (u * vt).determinant().signum();
    // The rotation taking measured offsets onto the model's.
    let r = u * d * vt;
    let sum: f64 = pairs()
        .map(|(p, m)| (r.transpose() * (m - cm) - (p - cp)).norm_squared())
        .sum();
    let e = (sum / n).sqrt();
    e.is_finite().then_some(e)
}

fn rms(e: &[f64]) -> f64 {
    (e.iter().map(|v| v * v).sum::<f64>() / e.len().max(1) as f64).sqrt()
}

/// The contiguous blocks of `rows`, each with its own placement: a block grows while its
/// placement fits the next rows within `tol`, and ends before the first [`RUN`] rows that it
/// does not.
fn blocks(
    robot: &Robot,
    data: &Dataset,
    rows: &[Row],
    ids: &[ParamId],
    tol: f64,
) -> Vec<Range<usize>> {
    let n = rows.len();
    let mut out = Vec::new();
    let mut i = 0;
    while i < n {
        let mut end = (i + SEED_ROWS).min(n);
        let mut placed = place(robot, data, &rows[i..end].iter().collect::<Vec<_>>(), ids);
        let mut placed_on = end - i;
        while end < n {
            let look = (end + SEED_ROWS + RUN).min(n);
            let bad: Vec<bool> = misfits(&placed, data, rows[end..look].iter())
                .into_iter()
                .map(|e| e > tol)
                .collect();
            let run = (0..(look - end).min(SEED_ROWS))
                .find(|&k| bad[k..(k + RUN).min(bad.len())].iter().all(|b| *b));
            if let Some(k) = run {
                end += k;
                break;
            }
            end = (end + SEED_ROWS).min(n);
            if end - i >= 2 * placed_on {
                placed = place(robot, data, &rows[i..end].iter().collect::<Vec<_>>(), ids);
                placed_on = end - i;
            }
        }
        out.push(i..end);
        i = end;
    }
    out
}

/// A [`Warning::PooledPlacements`] when `data` (without sessions) falls into groups of rows each
/// fitted by a placement of its own and not by one for all (see the module documentation).
pub(super) fn pooled_placements(
    robot: &Robot,
    data: &Dataset,
    predicted: &[[Vector3<f64>; 2]],
) -> Option<Warning> {
    if !data.sessions().is_empty() {
        return None;
    }
    let rows = rows_of(data);
    if rows.len() < 2 * SEED_ROWS {
        return None;
    }
    let tol = crate::observe::sanity::POSITION_LIMIT * robot.reach();
    // The common case first, from the nominal points the data check already has: one rigid
    // motion of the measurement frame puts every measured position within the tolerance, so
    // there is one placement (a pass over the rows, where the closed-form placement below costs
    // as much as the rest of a whole calibration's preparation).
    if rigid_rms(data, predicted).is_some_and(|e| e <= tol) {
        return None;
    }
    let ids: Vec<ParamId> = robot.param_ids().collect();
    let all: Vec<&Row> = rows.iter().collect();
    let pooled = rms(&misfits(&place(robot, data, &all, &ids), data, rows.iter()));
    if pooled.is_nan() || pooled <= tol {
        return None;
    }
    // Blocks, then groups of blocks one placement fits together.
    let mut groups: Vec<(Vec<Range<usize>>, Robot)> = Vec::new();
    for b in blocks(robot, data, &rows, &ids, tol) {
        let mine: Vec<&Row> = rows[b.clone()].iter().collect();
        let joins = groups
            .iter()
            .position(|(_, g)| rms(&misfits(g, data, mine.iter().copied())) <= tol);
        match joins {
            Some(g) => groups[g].0.push(b),
            None => groups.push((vec![b], place(robot, data, &mine, &ids))),
        }
    }
    if groups.len() < 2 {
        return None;
    }
    // Each group placed on all its rows: together they must fit.
    let mut errors = Vec::with_capacity(rows.len());
    for (ranges, _) in &groups {
        let mine: Vec<&Row> = ranges.iter().flat_map(|r| &rows[r.clone()]).collect();
        let placed = place(robot, data, &mine, &ids);
        errors.extend(misfits(&placed, data, mine.iter().copied()));
    }
    let per_block = rms(&errors);
    if per_block.is_nan() || per_block > tol {
        return None;
    }
    let blocks = groups
        .iter()
        .enumerate()
        .map(|(k, (ranges, _))| {
            let lines: Vec<String> = ranges
                .iter()
                .map(|r| format!("{}-{}", rows[r.start].line, rows[r.end - 1].line))
                .collect();
            let count: usize = ranges.iter().map(|r| r.len()).sum();
            format!(
                "placement {}: lines {} ({count} rows)",
                k + 1,
                lines.join(", ")
            )
        })
        .collect();
    let length = |v: f64| robot.units.from_si(Quantity::Length, v);
    Some(Warning::PooledPlacements {
        blocks,
        rms_pooled: length(pooled),
        rms_per_block: length(per_block),
        unit: robot.units.length.to_string(),
    })
}
