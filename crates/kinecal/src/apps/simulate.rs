//! Synthesized data (thesis 4.3): postures, perturbed "true" robots, measurements and noise.
//!
//! Random streams are ChaCha8 seeded from the user's seed, so a seed gives the same data on every
//! machine. Postures, perturbations and noise draw from separate streams: changing the noise
//! level does not move the postures.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use crate::error::{Error, Result};
use crate::model::kinematics::{Chain, Target, Workspace};
use crate::model::params::ParamKind;
use crate::model::robot::{JointKind, Link, Robot};
use crate::observe::point::{Pose, Position};
use crate::observe::{
    for_each_observation, Context, Dataset, Noise, Observation, OrientationError, Posture,
};
use crate::units::Quantity;

fn rng(seed: u64, stream: u64) -> ChaCha8Rng {
    let mut r = ChaCha8Rng::seed_from_u64(seed);
    r.set_stream(stream);
    r
}

/// The reading range used for a joint: its `min..max` from the robot file, otherwise the readings
/// that move a revolute joint +-150 deg, or a prismatic joint +-0.1 m, about its offset.
pub fn reading_range(robot: &Robot, joint: usize) -> (f64, f64) {
    let j = &robot.joints[joint];
    if let Some(r) = j.range {
        return r;
    }
    let span = match j.kind {
        JointKind::Revolute => 150f64.to_radians(),
        JointKind::Prismatic => 0.1,
    };
    let half = if j.slope != 0.0 {
        span / j.slope.abs()
    } else {
        1.0
    };
    (-half, half)
}

/// `count` postures with readings drawn uniformly in each joint's [`reading_range`], labelled
/// `1..count`.
pub fn sample_postures(robot: &Robot, count: usize, seed: u64) -> Vec<Posture> {
    let mut r = rng(seed, 1);
    let ranges: Vec<(f64, f64)> = (0..robot.dof()).map(|j| reading_range(robot, j)).collect();
    (1..=count)
        .map(|i| Posture {
            label: i.to_string(),
            readings: ranges.iter().map(|&(a, b)| r.random_range(a..=b)).collect(),
            session: None,
            payload: None,
        })
        .collect()
}

/// Standard deviations of a random perturbation (internal units).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PerturbStd {
    /// Lengths (link and site x, y, z; prismatic offsets), m.
    pub length: f64,
    /// Angles (link and site Euler angles; revolute offsets), rad.
    pub angle: f64,
    /// Slopes, as a fraction of their value.
    pub slope_fraction: f64,
}

/// Adds independent Gaussian perturbations to every geometric parameter of `robot` (coupling
/// factors like slopes, by a fraction of their magnitude or of 1, whichever is larger; the
/// cameras' and boards' poses as lengths and angles); the mass model (compliances, masses) and
/// the cameras' lenses (pixels and ratios, which no length or angle spread describes) are kept.
pub fn perturb(robot: &Robot, std: PerturbStd, seed: u64) -> Robot {
    let mut r = rng(seed, 2);
    let mut out = robot.clone();
    let unit = Normal::new(0.0, 1.0).expect("valid normal");
    for id in robot.param_ids() {
        let v = robot.get(id);
        let s = match (robot.param_kind(id), robot.param_quantity(id)) {
            (ParamKind::Slope { .. }, _) => std.slope_fraction * v.abs(),
            (ParamKind::Coupling { .. }, _) => std.slope_fraction * v.abs().max(1.0),
            (
                ParamKind::Compliance { .. } | ParamKind::Lateral { .. } | ParamKind::Body { .. },
                _,
            ) => 0.0,
            (_, Quantity::Length) => std.length,
            (_, Quantity::Angle) => std.angle,
            (_, _) => 0.0,
        };
        let z: f64 = unit.sample(&mut r);
        out.set(id, v + s * z);
    }
    out
}

/// `robot` with parameters changed by deltas in the robot file's units, e.g. a "true" robot for
/// synthesized data; an error when a value becomes infinite or not a number.
pub fn changed(robot: &Robot, changes: &[(crate::model::params::ParamId, f64)]) -> Result<Robot> {
    let mut out = robot.clone();
    for &(id, delta) in changes {
        let q = robot.param_quantity(id);
        let v = out.get(id) + robot.units.to_si(q, delta);
        if !crate::units::plausible(robot.units.from_si(q, v)) {
            return Err(Error::InvalidOption {
                setting: crate::error::Setting::ParameterChange,
                message: format!(
                    "{} ({}) would become {:e} {}, not a finite number within +-1e9",
                    id,
                    robot.param_name(id),
                    robot.units.from_si(q, v),
                    robot.param_unit(id)
                ),
            });
        }
        out.set(id, v);
    }
    Ok(out)
}

/// The noise-free measurements `robot` gives at `postures`: the end effector and every site,
/// full poses, or positions only when `position_only`; in a posture's session frame when its
/// session has one in `robot`.
pub fn measure(robot: &Robot, postures: &[Posture], position_only: bool) -> Dataset {
    let chain = Chain::new(robot);
    let mut ws = Workspace::new(robot);
    let targets: Vec<Target> = std::iter::once(Target::EndEffector)
        .chain((0..robot.sites.len()).map(Target::Site))
        .collect();
    let mut observations: Vec<Observation> = Vec::with_capacity(postures.len() * targets.len());
    for (i, p) in postures.iter().enumerate() {
        chain.forward_loaded(&p.readings, None, p.payload.as_ref(), &mut ws);
        let session = crate::observe::session_frame(robot, p);
        for &t in &targets {
            let f = chain.target_frame(&ws, t);
            let pose = session.map_or(f, |s| s.then(&f)).pose();
            observations.push(if position_only {
                Position::new(i, t, pose.position).into()
            } else {
                Pose::new(i, t, pose.position, pose.euler).into()
            });
        }
    }
    Dataset::new(postures.to_vec(), observations)
}

/// The same observations as `data`, with the measured values `robot` gives (noise-free).
pub fn remeasure(robot: &Robot, data: &Dataset) -> Dataset {
    let ctx = Context {
        robot,
        orientation: OrientationError::default(),
    };
    let mut out = data.clone();
    let mut measured = Vec::with_capacity(data.observations.len());
    for_each_observation(robot, data, |_, o, frames| {
        let mut o = o.clone();
        o.remeasure(&ctx, frames);
        measured.push(o);
    });
    out.observations = measured;
    out
}

/// Adds Gaussian noise to every observation: `length` (m) to each measured length (a position
/// coordinate, a distance), `angle` (rad) to each measured Euler angle (pixels get none: see
/// [`add_noise_with`]).
pub fn add_noise(data: &mut Dataset, length: f64, angle: f64, seed: u64) {
    let noise = Noise {
        length,
        angle,
        pixel: 0.0,
    };
    add_noise_with(data, &noise, seed);
}

/// Adds Gaussian noise of the standard deviations `noise` gives to every observation: to each
/// measured length, Euler angle and pixel coordinate.
pub fn add_noise_with(data: &mut Dataset, noise: &Noise, seed: u64) {
    let mut r = rng(seed, 3);
    let unit = Normal::new(0.0, 1.0).expect("valid normal");
    let mut draw = || -> f64 { unit.sample(&mut r) };
    for o in &mut data.observations {
        o.add_noise(&mut draw, noise);
    }
}

/// What camera `camera` of `robot` sees of board `board` in each of `postures`: a pixel
/// observation of every board point in front of the camera (at least 1 cm) and inside its
/// image, for the postures that see at least `min_points` of them (the others are left out;
/// their labels are kept). The pixels are the model's: add noise with [`add_noise_with`].
pub fn camera_views(
    robot: &Robot,
    postures: &[Posture],
    camera: usize,
    board: usize,
    min_points: usize,
) -> Dataset {
    let chain = Chain::new(robot);
    let mut ws = Workspace::new(robot);
    let mut kept = Vec::new();
    let mut observations: Vec<Observation> = Vec::new();
    for p in postures {
        chain.forward_loaded(&p.readings, None, p.payload.as_ref(), &mut ws);
        let seen = seen_pixels(robot, &chain, &ws, kept.len(), camera, board);
        if seen.len() >= min_points.max(1) {
            kept.push(p.clone());
            observations.extend(seen);
        }
    }
    Dataset::new(kept, observations)
}

/// Views drawn at random: postures drawn uniformly within the joint ranges (as
/// [`sample_postures`] draws them, from the same stream) until `count` of them see at least
/// `min_points` points of board `board` from camera `camera` of `robot` (as [`camera_views`]
/// keeps them), at most `max_draws` drawn. The views (labelled `1..`, their pixels the model's)
/// and how many postures were drawn; fewer than `count` views when the draws ran out.
pub fn draw_views(
    robot: &Robot,
    count: usize,
    (camera, board): (usize, usize),
    min_points: usize,
    max_draws: usize,
    seed: u64,
) -> (Dataset, usize) {
    let mut r = rng(seed, 1);
    let ranges: Vec<(f64, f64)> = (0..robot.dof()).map(|j| reading_range(robot, j)).collect();
    let chain = Chain::new(robot);
    let mut ws = Workspace::new(robot);
    let mut kept: Vec<Posture> = Vec::new();
    let mut observations: Vec<Observation> = Vec::new();
    let mut draws = 0;
    while kept.len() < count && draws < max_draws {
        draws += 1;
        let readings: Vec<f64> = ranges.iter().map(|&(a, b)| r.random_range(a..=b)).collect();
        chain.forward_loaded(&readings, None, None, &mut ws);
        let seen = seen_pixels(robot, &chain, &ws, kept.len(), camera, board);
        if seen.len() >= min_points.max(1) {
            kept.push(Posture {
                label: (kept.len() + 1).to_string(),
                readings,
                session: None,
                payload: None,
            });
            observations.extend(seen);
        }
    }
    (Dataset::new(kept, observations), draws)
}

/// The pixels camera `camera` sees of board `board` at the posture whose frames `ws` holds
/// (numbered `posture`): every point at least 1 cm in front of the camera and inside its
/// image, at the model's pixel.
pub(crate) fn seen_pixels(
    robot: &Robot,
    chain: &Chain<'_>,
    ws: &Workspace,
    posture: usize,
    camera: usize,
    board: usize,
) -> Vec<Observation> {
    use crate::observe::pixel::{Pixel, Seen};
    use crate::observe::Observe as _;
    let mut frames = [crate::model::kinematics::Frame::identity(); 2];
    let mut seen = Vec::new();
    for k in 0..robot.boards[board].points() {
        let Ok(mut o) = Pixel::new(
            robot,
            posture,
            camera,
            Seen::Board { board, index: k },
            [0.0; 2],
        ) else {
            // Nothing moves: the camera and the board are both fixed, or on one frame.
            return Vec::new();
        };
        for (slot, v) in frames.iter_mut().zip(o.views()) {
            *slot = chain.target_frame(ws, v.target);
        }
        let n = o.views().len();
        let q = o.in_camera(robot, &frames[..n]);
        let uv = o.predicted(robot, &frames[..n]);
        if q.z >= 0.01 && robot.cameras[camera].inside(&uv) {
            o.uv = [uv.x, uv.y];
            seen.push(o.into());
        }
    }
    seen
}

/// A random link (metres and radians): offsets `x, y, z` up to `reach` per axis, Euler angles
/// `alpha, gamma` anywhere and `beta` within +-70 deg (away from the gimbal lock), drawn in
/// that order.
fn random_link(r: &mut ChaCha8Rng, reach: f64) -> Link {
    Link {
        x: r.random_range(-reach..reach),
        y: r.random_range(-reach..reach),
        z: r.random_range(-reach..reach),
        alpha: r.random_range(-3.1..3.1),
        beta: r.random_range(-1.2..1.2),
        gamma: r.random_range(-3.1..3.1),
    }
}

/// A random robot with the given joint kinds (metres and radians): link offsets up to 0.4 m per
/// axis, Euler angles anywhere (beta within +-70 deg), offsets anywhere, slopes of either sign
/// between 0.5 and 2. For tests and benchmarks of arbitrary geometry.
pub fn random_robot(kinds: &[JointKind], seed: u64) -> Robot {
    use crate::model::robot::Joint;
    let mut r = rng(seed, 4);
    let links = (0..=kinds.len())
        .map(|_| random_link(&mut r, 0.4))
        .collect();
    let joints = kinds
        .iter()
        .map(|&kind| {
            let sign = if r.random_range(0.0..1.0) < 0.5 {
                -1.0
            } else {
                1.0
            };
            Joint {
                kind,
                offset: match kind {
                    JointKind::Revolute => r.random_range(-3.1..3.1),
                    JointKind::Prismatic => r.random_range(-0.2..0.2),
                },
                slope: sign * r.random_range(0.5..2.0),
                coupling: None,
                range: None,
                name: None,
                parent: None,
            }
        })
        .collect();
    Robot {
        name: format!("random-{seed}"),
        units: crate::units::Units::default(),
        links,
        joints,
        sites: Vec::new(),
        planes: Vec::new(),
        sessions: Vec::new(),
        tolerances: Default::default(),
        priors: Default::default(),
        elastic: None,
        end_effector: None,
        cameras: Vec::new(),
        boards: Vec::new(),
    }
}

/// A random tree of revolute joints (see [`random_robot`] for the geometry): a torso of `torso`
/// joints (`torso1..`) carrying one arm per entry of `arms` (`arm1_1..`, each its given number
/// of joints), every arm starting from the torso's last joint. Each arm ends in a tool frame
/// named `arm<k>`: the last arm's is the end effector, the others are sites. For tests and
/// benchmarks of branched robots (two arms on one torso).
pub fn random_tree(torso: usize, arms: &[usize], seed: u64) -> Robot {
    use crate::model::robot::Site;
    let n = torso + arms.iter().sum::<usize>();
    let mut robot = random_robot(&vec![JointKind::Revolute; n], seed);
    robot.name = format!("random-tree-{seed}");
    for (j, joint) in robot.joints.iter_mut().enumerate().take(torso) {
        joint.name = Some(format!("torso{}", j + 1));
    }
    let mut r = rng(seed, 5);
    let mut first = torso;
    for (a, &count) in arms.iter().enumerate() {
        for k in 0..count {
            let joint = &mut robot.joints[first + k];
            joint.name = Some(format!("arm{}_{}", a + 1, k + 1));
            if k == 0 && first != torso {
                joint.parent = Some(torso);
            }
        }
        first += count;
        let tool = format!("arm{}", a + 1);
        if a + 1 < arms.len() {
            robot.sites.push(Site {
                name: tool,
                joint: first,
                frame: random_link(&mut r, 0.2),
            });
        } else {
            robot.end_effector = Some(tool);
        }
    }
    robot
}

/// The report's chart of errors, from a simulated calibration (here, where the simulation is).
#[cfg(test)]
mod report_tests {
    /// The errors the calibration's own passes kept (its start and its settled end) are the
    /// errors a pass of forward kinematics gives, and are not used for another robot.
    #[test]
    fn kept_errors_are_the_errors_of_a_fresh_pass_and_only_of_their_robot() {
        use crate::apps::simulate;
        use crate::report::accuracy::observation_errors;
        use crate::solve::estimation::{calibrate, CalibrationOptions};
        let truth = crate::model::examples::ge_a4();
        let mut data = simulate::measure(&truth, &simulate::sample_postures(&truth, 40, 3), false);
        simulate::add_noise(&mut data, 1e-5, 1e-5, 4);
        let spread = simulate::PerturbStd {
            length: 1e-3,
            angle: 1e-3,
            ..Default::default()
        };
        let nominal = simulate::perturb(&truth, spread, 5);
        let all: Vec<_> = nominal.param_ids().collect();
        let opts = crate::identifiability::AnalysisOptions::default();
        let estimate = crate::identifiability::analyze(&nominal, &data, &all, &opts)
            .unwrap()
            .identifiable;
        let opts = CalibrationOptions::new(estimate);
        let mut cal = calibrate(&nominal, &data, &opts, &mut |_| {}).unwrap();
        assert!(cal.errors_before.is_some() && cal.errors_after.is_some());
        let kept = observation_errors(&cal, &data);
        let (before, after) = (cal.errors_before.take(), cal.errors_after.take());
        let fresh = observation_errors(&cal, &data);
        let close = |a: &[f64], b: &[f64]| {
            a.len() == b.len()
                && a.iter()
                    .zip(b)
                    .all(|(x, y)| (x - y).abs() <= 1e-12 * (1.0 + y.abs()))
        };
        assert!(close(&kept.before, &fresh.before));
        assert!(close(&kept.after, &fresh.after));
        assert!(kept.before.iter().zip(&kept.after).any(|(b, a)| a < b));
        // Another robot than the one they were computed for: not used.
        cal.errors_before = before;
        cal.errors_after = after;
        let moved = cal.estimated[0];
        cal.calibrated.set(moved, cal.calibrated.get(moved) + 0.01);
        let stale = observation_errors(&cal, &data);
        cal.errors_after = None;
        let recomputed = observation_errors(&cal, &data);
        assert!(close(&stale.after, &recomputed.after));
        assert!(!close(&stale.after, &kept.after));
    }
}
