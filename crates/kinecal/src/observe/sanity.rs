//! Checks that the data and the robot file speak the same units, before and after a fit.
//!
//! A calibration fits whatever it is given: measurements in millimetres against a robot in
//! metres "converge" to links a thousand times too long, joint readings in radians against a
//! degree robot let the offsets absorb whole turns. None of that is an error the solver can
//! see, so these checks look at what is independent of the unknown parameters:
//!
//! - **Scale.** The spread of the measured positions about their centroid (and the measured
//!   distances) against what the nominal robot predicts for the same postures. The spread is
//!   the same in every frame, so an unknown tracker placement does not matter; a ratio near
//!   1000, 25.4 or their inverses is a unit mix-up, and anything beyond a factor 3 is
//!   implausible for a robot whose nominal model is anywhere near right.
//! - **Attitudes.** The angle of the relative rotation between two measured poses of a target
//!   against the model's (the same in every measurement frame and for every tool frame): a
//!   median disagreement beyond 0.1 rad is attitudes in another angle unit (named when the
//!   other unit agrees) or another Euler convention.
//! - **Readings.** Readings outside a joint's range (`min`/`max` in the robot file) by more than
//!   5 % of its width; readings of a revolute joint read directly as angles (slope 1 in the
//!   file's angle unit) that look like radians against a degree robot (every joint within
//!   one turn, +-2 pi, and some moving over 0.3: no calibration keeps every joint within 6 deg) or like degrees against a radian robot (beyond +-7).
//! - **Result.** An estimated length that moves by more than the robot's reach (the first
//!   link, which carries the measurement frame, and plane offsets aside).
//!
//! Each finding is a [`Warning`] naming the joint, the postures and the ratio; the caller may
//! treat them as fatal ([`Warning::implausible`]).

use nalgebra::Vector3;

use crate::model::kinematics::Chain;
use crate::model::kinematics::Target;
use crate::model::params::{ParamId, ParamKind};
use crate::model::robot::{JointKind, Robot};
use crate::observe::{Dataset, Observation};
use crate::units::{AngleUnit, Quantity};
use crate::warning::Warning;

/// Beyond this factor between measured and predicted spreads, the scale is implausible.
pub(crate) const SCALE_FACTOR_LIMIT: f64 = 3.0;

/// The warnings about `data` against the nominal `robot` (scale, attitudes and readings), with
/// the nominal robot's [`predicted`] points at hand.
pub(crate) fn check_data_with(
    robot: &Robot,
    data: &Dataset,
    predicted: &[[Vector3<f64>; 2]],
) -> Vec<Warning> {
    let mut out = Vec::new();
    out.extend(scale(robot, data, predicted));
    out.extend(attitudes(robot, data));
    out.extend(readings(robot, data));
    out
}

/// Beyond this disagreement (rad; 5.7 deg) of attitudes, the measured attitudes are not the
/// model's: a calibration moves them by well under a degree.
pub(crate) const ATTITUDE_LIMIT: f64 = 0.1;

/// A calibrated robot whose RMS position error stays above this fraction of its reach fits
/// no calibration of it: a model that fits reaches a few tenths of a per cent of the reach
/// before calibration (a nominal industrial arm is off by millimetres over a metre) and less
/// after; 2 % (20 mm over a metre) is a local minimum of a start far from the robot, a wrong
/// unit, or a wrong robot file ([`Warning::PositionsUnfit`]).
pub(crate) const POSITION_LIMIT: f64 = 0.02;

/// At most this many pairs of poses are compared (spread over the file).
const ATTITUDE_PAIRS: usize = 200;

/// Measured attitudes against the nominal robot's: the angle of the relative rotation between
/// two poses of one target, `angle(R_a^T R_b)`, is the same in every measurement frame and for
/// every tool frame, so it needs neither placed. Read in the wrong angle unit (or another Euler
/// convention), the measured attitudes give other angles than the model's.
fn attitudes(robot: &Robot, data: &Dataset) -> Option<Warning> {
    use crate::model::kinematics::rot_zyx;
    let poses: Vec<(usize, Target, Vector3<f64>)> = data
        .observations
        .iter()
        .filter_map(|o| match o {
            Observation::Pose(p) => Some((p.view[0].posture, p.view[0].target, p.euler)),
            _ => None,
        })
        .collect();
    // Consecutive poses of the same target in the same session, spread over the file.
    let session = |p: usize| data.postures[p].session.as_deref();
    let mut pairs = Vec::new();
    for (i, a) in poses.iter().enumerate() {
        if let Some(b) = poses[i + 1..]
            .iter()
            .find(|b| b.1 == a.1 && session(b.0) == session(a.0))
        {
            pairs.push((a, b));
        }
    }
    if pairs.len() < 5 {
        return None;
    }
    let stride = pairs.len().div_ceil(ATTITUDE_PAIRS);
    let chain = Chain::new(robot);
    let angle = |r: nalgebra::Matrix3<f64>| ((r.trace() - 1.0) / 2.0).clamp(-1.0, 1.0).acos();
    let deg = std::f64::consts::PI / 180.0;
    // As read; as if the file's numbers were degrees read as radians; or radians read as
    // degrees (the factor that would turn the numbers as read into the true angles).
    let factors = [1.0, deg, 1.0 / deg];
    let mut errors: [Vec<f64>; 3] = Default::default();
    for (a, b) in pairs.iter().step_by(stride) {
        let ra = chain.frame_at(&data.postures[a.0].readings, a.1).rotation;
        let rb = chain.frame_at(&data.postures[b.0].readings, b.1).rotation;
        let model = angle(ra.transpose() * rb);
        for (e, s) in errors.iter_mut().zip(factors) {
            let (ea, eb) = (a.2 * s, b.2 * s);
            let ma = rot_zyx(ea.x, ea.y, ea.z);
            let mb = rot_zyx(eb.x, eb.y, eb.z);
            e.push((angle(ma.transpose() * mb) - model).abs());
        }
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let [mut as_read, mut in_deg, mut in_rad] = errors;
    let (as_read, in_deg, in_rad) = (
        median(&mut as_read),
        median(&mut in_deg),
        median(&mut in_rad),
    );
    if as_read <= ATTITUDE_LIMIT {
        return None;
    }
    let read_as = robot.units.angle;
    let likely = [(in_deg, AngleUnit::Deg), (in_rad, AngleUnit::Rad)]
        .into_iter()
        .filter(|&(e, u)| u != read_as && e <= ATTITUDE_LIMIT && e < as_read / 3.0)
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, u)| u.to_string());
    Some(Warning::AttitudeMismatch {
        median_deg: as_read.to_degrees(),
        likely,
        read_as: read_as.to_string(),
    })
}

/// Where `robot` puts the target of each view of each observation of `data` (global frame; a
/// second view's slot is zero for observations of one view): one pass of forward kinematics,
/// once per posture, shared by the checks that compare the data with the nominal model.
pub(crate) fn predicted(robot: &Robot, data: &Dataset) -> Vec<[Vector3<f64>; 2]> {
    let chain = Chain::new(robot);
    let mut cache = crate::observe::FrameCache::new(robot);
    // The readings' sines and cosines, made here and kept with the data for the fit's passes.
    let trig = data.reading_trig(robot);
    data.observations
        .iter()
        .map(|o| {
            let mut at = [Vector3::zeros(); 2];
            for (p, v) in at.iter_mut().zip(o.views()) {
                let ws = cache.posture_with(&chain, data, v.posture, Some(&trig));
                *p = chain.target_frame(ws, v.target).translation;
            }
            at
        })
        .collect()
}

/// The warning when an estimated length moved by more than the robot's reach from `initial`
/// to `calibrated`.
pub(crate) fn check_result(
    initial: &Robot,
    calibrated: &Robot,
    estimated: &[ParamId],
) -> Vec<Warning> {
    let reach = initial.reach();
    let moved: Vec<String> = estimated
        .iter()
        .filter(|&&id| initial.param_quantity(id) == Quantity::Length)
        // The first link carries the measurement frame (a tracker metres away is fine), and a
        // plane's offset its placement.
        .filter(|&&id| {
            !matches!(
                initial.param_kind(id),
                ParamKind::Link { link: 0, .. } | ParamKind::Plane { .. }
            )
        })
        .filter(|&&id| (calibrated.get(id) - initial.get(id)).abs() > reach)
        .map(|&id| initial.param_name(id))
        .collect();
    if moved.is_empty() {
        return Vec::new();
    }
    let u = initial.units;
    vec![Warning::ChangeBeyondReach {
        parameters: moved,
        reach: u.from_si(Quantity::Length, reach),
        unit: u.length.to_string(),
    }]
}

/// RMS distance of points from their centroid.
/// The spread of a set of points (the root mean square distance from their centroid), taken
/// a point at a time (Welford's update of the mean and the sum of squared deviations: the sum
/// is formed from deviations, not from the points' squares, so points far from the origin lose
/// only the digits `p - mean` loses, as a two-pass sum does), so that no copy of the points is
/// kept.
#[derive(Clone, Copy, Default)]
struct Spread {
    count: usize,
    mean: Vector3<f64>,
    /// The sum of squared distances from the running mean.
    m2: f64,
}

impl Spread {
    fn push(&mut self, p: Vector3<f64>) {
        self.count += 1;
        let d = p - self.mean;
        self.mean += d / self.count as f64;
        self.m2 += d.dot(&(p - self.mean));
    }

    /// The sum of squared distances from the centroid: the squared spread times the count.
    fn sum_of_squares(&self) -> f64 {
        self.m2.max(0.0)
    }
}

fn scale(robot: &Robot, data: &Dataset, predicted: &[[Vector3<f64>; 2]]) -> Vec<Warning> {
    let mut out = Vec::new();
    // Positions: per target, as different targets are different points, and per measurement
    // session, as each has its own frame: the measured points' spread and the modelled ones'.
    let mut spreads: Vec<(Spread, Spread)> = Vec::new();
    let mut targets: Vec<(Target, Option<&str>)> = Vec::new();
    for (o, at) in data.observations.iter().zip(predicted) {
        let (view, position) = match o {
            Observation::Pose(p) => (p.view[0], p.position),
            Observation::Position(p) => (p.view[0], p.position),
            _ => continue,
        };
        let key = (view.target, data.postures[view.posture].session.as_deref());
        let k = targets.iter().position(|t| *t == key).unwrap_or_else(|| {
            targets.push(key);
            spreads.push(Default::default());
            targets.len() - 1
        });
        spreads[k].0.push(position);
        spreads[k].1.push(at[0]);
    }
    let (mut sm, mut sp) = (0.0f64, 0.0f64);
    for (m, p) in &spreads {
        if m.count >= 3 {
            sm += m.sum_of_squares();
            sp += p.sum_of_squares();
        }
    }
    if let Some(w) = ratio_warning("position", sm.sqrt(), sp.sqrt(), robot) {
        out.push(w);
    }
    // Distances: the measured lengths against the predicted ones.
    let (mut dm, mut dp) = (0.0f64, 0.0f64);
    let mut count = 0;
    for (o, at) in data.observations.iter().zip(predicted) {
        if let Observation::Distance(d) = o {
            dm += d.distance.powi(2);
            dp += (at[0] - at[1]).norm_squared();
            count += 1;
        }
    }
    if count >= 3 {
        if let Some(w) = ratio_warning("distance", dm.sqrt(), dp.sqrt(), robot) {
            out.push(w);
        }
    }
    out
}

fn ratio_warning(metric: &str, measured: f64, predicted: f64, robot: &Robot) -> Option<Warning> {
    // Too little motion to judge (a few micrometres either way).
    if !(measured > 1e-6 && predicted > 1e-6) {
        return None;
    }
    let ratio = measured / predicted;
    if (1.0 / SCALE_FACTOR_LIMIT..=SCALE_FACTOR_LIMIT).contains(&ratio) {
        return None;
    }
    // The unit mix-ups that give such a ratio (data unit per robot-file unit).
    let file = robot.units.length.metres();
    let guesses: Vec<String> = [("m", 1.0), ("mm", 1e-3), ("cm", 1e-2), ("in", 0.0254)]
        .iter()
        .filter(|(_, metres)| {
            let r = file / metres;
            (ratio / r - 1.0).abs() < 0.15 && (r - 1.0).abs() > 1e-9
        })
        .map(|(name, _)| name.to_string())
        .collect();
    Some(Warning::ScaleMismatch {
        metric: metric.to_string(),
        ratio,
        unit: robot.units.length.to_string(),
        likely: guesses.into_iter().next(),
    })
}

fn readings(robot: &Robot, data: &Dataset) -> Vec<Warning> {
    let mut out = Vec::new();
    if data.postures.is_empty() {
        return out;
    }
    let labels = |pick: &dyn Fn(f64) -> bool, j: usize| -> (usize, Vec<String>) {
        let hits: Vec<&str> = data
            .postures
            .iter()
            .filter(|p| pick(p.readings[j]))
            .map(|p| p.label.as_str())
            .collect();
        (
            hits.len(),
            hits.iter().take(5).map(|s| s.to_string()).collect(),
        )
    };
    for (j, joint) in robot.joints.iter().enumerate() {
        if let Some((lo, hi)) = joint.range {
            let margin = 0.05 * (hi - lo);
            let outside = |v: f64| v < lo - margin || v > hi + margin;
            let (count, postures) = labels(&outside, j);
            if count > 0 {
                out.push(Warning::ReadingsOutOfRange {
                    joint: j + 1,
                    count,
                    postures,
                    min: lo,
                    max: hi,
                });
            }
        }
    }
    // Angles read directly (slope 1 in the file's angle unit): do they look like the other
    // angle unit?
    let u = robot.units;
    let direct: Vec<usize> = robot
        .joints
        .iter()
        .enumerate()
        .filter(|(_, jt)| {
            jt.kind == JointKind::Revolute
                && jt.coupling.is_none()
                && (u.from_si(Quantity::Angle, jt.slope) - 1.0).abs() < 1e-6
        })
        .map(|(j, _)| j)
        .collect();
    if direct.is_empty() {
        return out;
    }
    let column = |j: usize| data.postures.iter().map(move |p| p.readings[j]);
    let max_abs = |j: usize| column(j).fold(0.0f64, |m, v| m.max(v.abs()));
    let width = |j: usize| {
        let (lo, hi) = column(j).fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
        hi - lo
    };
    let degrees = u.angle == AngleUnit::Deg;
    let radians = u.angle == AngleUnit::Rad;
    if degrees && data.postures.len() >= 5 {
        let all_small = direct
            .iter()
            .all(|&j| max_abs(j) <= std::f64::consts::TAU + 1e-6);
        let moving = direct.iter().any(|&j| width(j) > 0.3);
        if all_small && moving {
            out.push(Warning::AngleUnitMismatch {
                joints: direct.iter().map(|j| j + 1).collect(),
                file_unit: "deg".into(),
                looks_like: "rad".into(),
            });
        }
    } else if radians {
        let big: Vec<usize> = direct
            .iter()
            .copied()
            .filter(|&j| max_abs(j) > 7.0)
            .collect();
        if !big.is_empty() {
            out.push(Warning::AngleUnitMismatch {
                joints: big.iter().map(|j| j + 1).collect(),
                file_unit: "rad".into(),
                looks_like: "deg".into(),
            });
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The running spread is the two-pass one (the centroid first, then the squared
    /// distances from it) for clouds near the origin and far from it, loose and tightly
    /// packed: both form deviations `p - mean` rounded to `eps` of the offset, `eps * offset /
    /// size` of the spread, so the sums agree to `1e-12` plus ten times twice that (a sum of
    /// squares doubles a relative error). A single point and a repeated one have no spread.
    #[test]
    fn the_running_spread_is_the_two_pass_spread() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        for (offset, size) in [(0.0, 1.0), (3.0, 0.5), (1e4, 1e-3), (-50.0, 1e-6)] {
            let points: Vec<Vector3<f64>> = (0..500)
                .map(|_| Vector3::from_fn(|_, _| offset + size * rng.random_range(-1.0..1.0)))
                .collect();
            let mut running = Spread::default();
            for &p in &points {
                running.push(p);
            }
            let c = points.iter().sum::<Vector3<f64>>() / points.len() as f64;
            let two_pass: f64 = points.iter().map(|p| (p - c).norm_squared()).sum();
            let d = (running.sum_of_squares() - two_pass).abs();
            let carried = 20.0 * f64::EPSILON * (offset.abs() + size) / size;
            assert!(
                d <= (1e-12 + carried) * two_pass,
                "offset {offset}, size {size}: {d:e}"
            );
            assert_eq!(running.count, 500);
        }
        let mut one = Spread::default();
        one.push(Vector3::new(1.0, 2.0, 3.0));
        assert_eq!(one.sum_of_squares().to_bits(), 0.0f64.to_bits());
        let mut same = Spread::default();
        for _ in 0..10 {
            same.push(Vector3::new(0.1, 0.2, 0.3));
        }
        assert_eq!(same.sum_of_squares().to_bits(), 0.0f64.to_bits());
    }
}
