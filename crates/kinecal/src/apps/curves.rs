//! Characteristic curves (thesis 4.4.1 and 4.4.4): the pose of the end effector, and the
//! objective, as one parameter varies with all others held.
//!
//! Values are in the robot file's units. Euler angles along a pose curve are unwrapped (made
//! continuous by whole turns), so a curve shows no false jump at +-180 deg.

use crate::model::kinematics::{Chain, Target, Workspace};
use crate::model::params::{ParamId, ParamKind};
use crate::model::robot::{JointKind, Robot};
use crate::observe::{Dataset, OrientationError, Weights};
use crate::solve::problem::Problem;
use crate::units::number::format_number;
use crate::units::Quantity;

/// Most samples a curve may have.
pub const MAX_POINTS: usize = 100_000;

/// `points` evenly spaced values from `from` to `to` (file units), checked: both ends finite
/// within +-1e9, `from < to` with a width the numbers can resolve, 3 to [`MAX_POINTS`] points.
pub fn sweep(from: f64, to: f64, points: usize) -> crate::Result<Vec<f64>> {
    let bad = |message: String| crate::Error::InvalidOption {
        setting: crate::error::Setting::Sweep,
        message,
    };
    if !(3..=MAX_POINTS).contains(&points) {
        return Err(bad(format!("{points} points: between 3 and {MAX_POINTS}")));
    }
    // The numbers as kinecal's tables write them (`5`, not `5e0`).
    let (a, b) = (format_number(from), format_number(to));
    if !(crate::units::plausible(from) && crate::units::plausible(to) && from < to) {
        return Err(bad(format!(
            "from {a} to {b}: a sweep runs from a smaller to a larger number within +-1e9"
        )));
    }
    if (to - from) < 1e-12 * from.abs().max(to.abs()) {
        return Err(bad(format!(
            "from {a} to {b}: too narrow for the numbers to tell its points apart"
        )));
    }
    Ok(samples(from, to, points))
}

/// The default half-width of a sweep of parameter `id` (file units), by its kind and the
/// robot's size: lengths the robot's reach (a fifth of it for the objective), angles 50 deg
/// (10 deg), slopes and coupling factors half their value (a tenth), at least 1 unit.
pub(crate) fn default_half_width(robot: &Robot, id: ParamId, objective: bool) -> f64 {
    let u = robot.units;
    let scale = if objective { 0.2 } else { 1.0 };
    match robot.param_quantity(id) {
        Quantity::Length => u.from_si(Quantity::Length, robot.reach()) * scale,
        Quantity::Angle => u.from_si(Quantity::Angle, 50f64.to_radians()) * scale,
        _ => (0.5 * robot.get_user(id).abs()).max(1.0) * scale,
    }
}

/// `count` evenly spaced values from `from` to `to` (inclusive).
pub fn samples(from: f64, to: f64, count: usize) -> Vec<f64> {
    let n = count.max(2);
    (0..n)
        .map(|i| from + (to - from) * i as f64 / (n - 1) as f64)
        .collect()
}

/// The end effector's (or a site's) pose `[x, y, z, alpha, beta, gamma]` (file units) at
/// `readings` as parameter `id` takes each of `values` (file units). Angles are unwrapped along
/// the curve.
pub fn pose_curve(
    robot: &Robot,
    readings: &[f64],
    target: Target,
    id: ParamId,
    values: &[f64],
) -> Vec<[f64; 6]> {
    let u = robot.units;
    let q = robot.param_quantity(id);
    let mut r = robot.clone();
    let mut ws = Workspace::new(robot);
    let mut out: Vec<[f64; 6]> = Vec::with_capacity(values.len());
    let turn = u.from_si(Quantity::Angle, std::f64::consts::TAU);
    for &v in values {
        r.set(id, u.to_si(q, v));
        let chain = Chain::new(&r);
        chain.forward(readings, &mut ws);
        let p = chain.target_frame(&ws, target).pose();
        // Rounding noise (below 1e-12 m or rad, a picometre) is 0: a constant angle of 0 is
        // drawn flat at 0, not as a curve across 1e-16.
        let snap = |v: f64| if v.abs() < 1e-12 { 0.0 } else { v };
        let mut row = [
            u.from_si(Quantity::Length, snap(p.position.x)),
            u.from_si(Quantity::Length, snap(p.position.y)),
            u.from_si(Quantity::Length, snap(p.position.z)),
            u.from_si(Quantity::Angle, snap(p.euler.x)),
            u.from_si(Quantity::Angle, snap(p.euler.y)),
            u.from_si(Quantity::Angle, snap(p.euler.z)),
        ];
        if let Some(prev) = out.last() {
            for k in 3..6 {
                row[k] -= turn * ((row[k] - prev[k]) / turn).round();
            }
        }
        out.push(row);
    }
    // Anchor the unwrapped angles at the robot's own value of the parameter: there they are the
    // pose's true angles, in (-180, 180].
    let v0 = robot.get_user(id);
    if let Some(k) =
        (0..values.len()).min_by(|&a, &b| (values[a] - v0).abs().total_cmp(&(values[b] - v0).abs()))
    {
        for c in 3..6 {
            let shift = turn * (out[k][c] / turn).round();
            for row in &mut out {
                row[c] -= shift;
            }
        }
    }
    out
}

/// The objective (weighted sum of squares, as the solvers minimise it) over `data` as parameter
/// `id` takes each of `values` (file units).
pub fn objective_curve(
    robot: &Robot,
    data: &Dataset,
    id: ParamId,
    values: &[f64],
    weights: Weights,
    orientation: OrientationError,
) -> Vec<f64> {
    let u = robot.units;
    let q = robot.param_quantity(id);
    let ids = [id];
    let problem = Problem::new(robot, data, &ids, weights, orientation);
    let mut res = vec![0.0; problem.rows()];
    values
        .iter()
        .map(|&v| problem.evaluate(&problem.robot_at(&[u.to_si(q, v)]), &mut res, None))
        .collect()
}

/// Interior local minima of a sampled curve `f(x)`: `(x, f)` where `f` is below both
/// neighbours (plateaus count once).
pub fn local_minima(x: &[f64], f: &[f64]) -> Vec<(f64, f64)> {
    let mut out = Vec::new();
    let n = f.len();
    let mut i = 1;
    while i + 1 < n {
        if f[i] < f[i - 1] {
            // Walk over a plateau (exactly equal samples).
            let mut j = i;
            while j + 1 < n && f[j + 1].to_bits() == f[i].to_bits() {
                j += 1;
            }
            if j + 1 < n && f[j + 1] > f[i] {
                out.push((x[(i + j) / 2], f[i]));
            }
            i = j + 1;
        } else {
            i += 1;
        }
    }
    out
}

/// Whether a sampled curve is convex: no second difference below `-tol` times its range.
pub fn is_convex(f: &[f64]) -> bool {
    let range = f.iter().copied().fold(f64::NEG_INFINITY, f64::max)
        - f.iter().copied().fold(f64::INFINITY, f64::min);
    f.windows(3)
        .all(|w| w[0] - 2.0 * w[1] + w[2] >= -1e-9 * range.max(f64::MIN_POSITIVE))
}

/// The period of the pose (and objective) in parameter `id` (file units), when it has one:
/// a full turn for link, site and plane angles and revolute offsets; for a revolute slope (or
/// coupling factor), a full turn divided by the reading (of the other joint), which only exists
/// for a single posture (`readings` of that posture).
pub fn period(robot: &Robot, id: ParamId, readings: Option<&[f64]>) -> Option<f64> {
    let u = robot.units;
    let turn = u.from_si(Quantity::Angle, std::f64::consts::TAU);
    match robot.param_kind(id) {
        ParamKind::Link { component, .. }
        | ParamKind::Site { component, .. }
        | ParamKind::Session { component, .. }
        | ParamKind::Board { component, .. } => {
            (component.quantity() == Quantity::Angle).then_some(turn)
        }
        ParamKind::Camera { component, .. } => {
            (component.quantity() == Quantity::Angle).then_some(turn)
        }
        ParamKind::Offset { joint } => {
            (robot.joints[joint].kind == JointKind::Revolute).then_some(turn)
        }
        ParamKind::Slope { joint } => {
            let v = readings?.get(joint).copied()?;
            (robot.joints[joint].kind == JointKind::Revolute && v != 0.0).then(|| turn / v.abs())
        }
        ParamKind::Coupling { joint } => {
            let other = robot.joints[joint].coupling?.joint;
            let v = readings?.get(other).copied()?;
            (robot.joints[joint].kind == JointKind::Revolute && v != 0.0).then(|| turn / v.abs())
        }
        ParamKind::Compliance { .. } | ParamKind::Lateral { .. } | ParamKind::Body { .. } => None,
        ParamKind::Plane { component, .. } => {
            (component.quantity() == Quantity::Angle).then_some(turn)
        }
    }
}
