//! Closed-form placement of the measurement frame and of the measured frames on the robot,
//! before the solver runs.
//!
//! An instrument's frame (a laser tracker, a camera) is often known only roughly, or not at all:
//! metres away from the robot and turned. The least-squares problem is then far from linear
//! at the start, and a damped Gauss-Newton solver can end in a local minimum or at its
//! iteration cap. But the two frames the data leaves unknown at first order enter the model
//! rigidly, `M_i = T P_i S_k`, with `T` the measurement frame (the first link), `P_i` the frame
//! a target hangs off at posture `i`, and `S_k` the target's own frame (the last link for the
//! end effector, the site frame for a site). Given the others, each has a closed form:
//!
//! - `T` from the measured and predicted origins by the SVD solution of the orthogonal
//!   Procrustes problem (Kabsch; Umeyama 1991, without scale);
//! - a target's origin `s_k` as the mean of `R_Pi^T (T^-1 m_i - t_Pi)`;
//! - a pose target's attitude `R_Sk` as the rotation nearest to `sum R_Pi^T R_T^T R_Mi`.
//!
//! [`register`] alternates these (the `AX = ZB` problem of robot-world/hand-eye calibration,
//! solved by block coordinate descent, as calibration tools such as FIGAROH place the base and
//! tool before identification), touching only what is estimated, and keeps the result only when
//! it lowers the RMS position error.

use nalgebra::{Matrix3, Vector3};

use crate::model::kinematics::{euler_zyx, Chain, Frame, Target, Workspace};
use crate::model::params::{LinkComponent, ParamId, ParamKind};
use crate::model::robot::{Link, Robot};
use crate::observe::{Dataset, Observation};

/// The start is re-placed when its RMS position error exceeds this fraction of the robot's
/// reach: a measurement frame placed roughly or not at all. Nearer starts are left as given
/// (the solver's answer in undetermined directions depends on the start).
pub const FAR_START: f64 = 0.05;

/// What [`register`] did.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct Registration {
    /// The re-placed robot.
    pub robot: Robot,
    /// RMS position error (m) before.
    pub rms_before: f64,
    /// RMS position error (m) after.
    pub rms_after: f64,
}

/// One measured point or frame.
struct Sample {
    posture: usize,
    target: Target,
    position: Vector3<f64>,
    rotation: Option<Matrix3<f64>>,
}

/// The measured points and frames in the global frame's own measurement frame (those of
/// sessions with frames of their own in `robot` are left to [`place_sessions`]).
fn samples(robot: &Robot, data: &Dataset) -> Vec<Sample> {
    let framed =
        |posture: usize| crate::observe::session_frame(robot, &data.postures[posture]).is_some();
    data.observations
        .iter()
        .filter(|o| !framed(o.posture()))
        .filter_map(|o| match o {
            Observation::Pose(p) => Some(Sample {
                posture: p.view[0].posture,
                target: p.view[0].target,
                position: p.position,
                rotation: Some(crate::model::kinematics::rot_zyx(
                    p.euler.x, p.euler.y, p.euler.z,
                )),
            }),
            Observation::Position(p) => Some(Sample {
                posture: p.view[0].posture,
                target: p.view[0].target,
                position: p.position,
                rotation: None,
            }),
            _ => None,
        })
        .collect()
}

/// The rotation nearest (Frobenius) to `m`.
fn nearest_rotation(m: &Matrix3<f64>) -> Option<Matrix3<f64>> {
    let svd = m.svd(true, true);
    let (u, vt) = (svd.u?, svd.v_t?);
    let mut d = Matrix3::identity();
    if (u * vt).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    Some(u * d * vt)
}

/// The rigid transform `(R, t)` minimising `sum |R a_i + t - b_i|^2`, when the points `a` span
/// a plane at least (not all on a line).
fn kabsch(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> Option<(Matrix3<f64>, Vector3<f64>)> {
    let n = a.len() as f64;
    let ca = a.iter().sum::<Vector3<f64>>() / n;
    let cb = b.iter().sum::<Vector3<f64>>() / n;
    let h: Matrix3<f64> = a
        .iter()
        .zip(b)
        .map(|(p, q)| (q - cb) * (p - ca).transpose())
        .sum();
    let sv = h.svd(false, false).singular_values;
    // Collinear or coincident points leave a turn about their line undetermined.
    if sv[1].is_nan() || sv[1] <= 1e-9 * sv[0].max(1e-300) {
        return None;
    }
    let r = nearest_rotation(&h)?;
    Some((r, cb - r * ca))
}

/// RMS distance between the measured origins and those `robot` predicts.
fn rms(robot: &Robot, data: &Dataset, s: &[Sample]) -> f64 {
    let chain = Chain::new(robot);
    let mut ws = Workspace::new(robot);
    let mut sum = 0.0;
    for x in s {
        chain.forward(&data.postures[x.posture].readings, &mut ws);
        sum += (chain.target_frame(&ws, x.target).translation - x.position).norm_squared();
    }
    (sum / s.len().max(1) as f64).sqrt()
}

/// Sets link or site frame `l` to the transform `f`, with angles as near as possible to `l`'s
/// own (the two ZYX triples of one rotation, each angle wrapped to its old value).
fn set_frame(l: &mut Link, f: &Frame) {
    let e = euler_zyx(&f.rotation);
    let pi = std::f64::consts::PI;
    let near = |v: f64, to: f64| to + crate::units::wrap_angle(v - to);
    let candidates = [(e.x, e.y, e.z), (e.x + pi, pi - e.y, e.z + pi)];
    let (a, b, g) = candidates
        .iter()
        .map(|&(a, b, g)| (near(a, l.alpha), near(b, l.beta), near(g, l.gamma)))
        .min_by(|p, q| {
            let d = |t: &(f64, f64, f64)| {
                (t.0 - l.alpha).powi(2) + (t.1 - l.beta).powi(2) + (t.2 - l.gamma).powi(2)
            };
            d(p).total_cmp(&d(q))
        })
        .expect("two candidates");
    *l = Link {
        x: f.translation.x,
        y: f.translation.y,
        z: f.translation.z,
        alpha: a,
        beta: b,
        gamma: g,
    };
}

/// Which of a frame's components are estimated: (all of the origin, all of the attitude).
fn estimated_parts(robot: &Robot, estimated: &[ParamId], frame: FrameRef) -> (bool, bool) {
    let has = |c: LinkComponent| {
        let kind = match frame {
            FrameRef::Link(link) => ParamKind::Link { link, component: c },
            FrameRef::Site(site) => ParamKind::Site { site, component: c },
        };
        estimated.contains(&robot.param_id(kind))
    };
    use LinkComponent::*;
    (
        [X, Y, Z].into_iter().all(has),
        [Alpha, Beta, Gamma].into_iter().all(has),
    )
}

#[derive(Clone, Copy)]
enum FrameRef {
    Link(usize),
    Site(usize),
}

fn frame_of(robot: &Robot, target: Target) -> FrameRef {
    match target {
        Target::EndEffector => FrameRef::Link(robot.links.len() - 1),
        Target::Site(s) => FrameRef::Site(s),
    }
}

fn link_mut(robot: &mut Robot, f: FrameRef) -> &mut Link {
    match f {
        FrameRef::Link(i) => &mut robot.links[i],
        FrameRef::Site(s) => &mut robot.sites[s].frame,
    }
}

/// Re-places the measurement frame (the first link, when all six of its parameters are
/// estimated) and the measured targets' frames (their origins, and for targets measured as
/// full poses their attitudes, when estimated) of `robot` to fit `data`'s positions and poses
/// in closed form. `None` when there is nothing to place, too little data (three points not on
/// a line are needed), or no improvement.
pub fn register(robot: &Robot, data: &Dataset, estimated: &[ParamId]) -> Option<Registration> {
    let s = samples(robot, data);
    if s.len() < 3 {
        return None;
    }
    let base = estimated_parts(robot, estimated, FrameRef::Link(0));
    let place_base = base.0 && base.1;
    let mut targets: Vec<Target> = Vec::new();
    for x in &s {
        if !targets.contains(&x.target) {
            targets.push(x.target);
        }
    }
    // The targets whose frame may move, and how.
    let movable: Vec<(Target, bool, bool)> = targets
        .iter()
        .map(|&t| {
            let (o, a) = estimated_parts(robot, estimated, frame_of(robot, t));
            let posed = s.iter().any(|x| x.target == t && x.rotation.is_some());
            (t, o, a && posed)
        })
        .filter(|&(_, o, a)| o || a)
        .collect();
    if !place_base && movable.is_empty() {
        return None;
    }
    let before = rms(robot, data, &s);
    let mut r = robot.clone();
    // The frame each sample's target hangs off (posture-dependent, fixed during the search:
    // neither the first link nor the target frames change it, up to T which is applied apart).
    let parents: Vec<Frame> = {
        let chain = Chain::new(robot);
        let mut ws = Workspace::new(robot);
        let base_inv = inverse(&Frame::from_link(&robot.links[0]));
        s.iter()
            .map(|x| {
                chain.forward(&data.postures[x.posture].readings, &mut ws);
                let k = match x.target {
                    Target::EndEffector => robot.dof(),
                    Target::Site(i) => robot.sites[i].joint,
                };
                // Without the first link: P = L1^-1 prox_k.
                base_inv.then(ws.after_joint(k))
            })
            .collect()
    };
    let mut t = Frame::from_link(&robot.links[0]);
    let mut tool: Vec<Frame> = targets
        .iter()
        .map(|&tg| match frame_of(robot, tg) {
            FrameRef::Link(i) => Frame::from_link(&robot.links[i]),
            FrameRef::Site(i) => Frame::from_link(&robot.sites[i].frame),
        })
        .collect();
    let index = |tg: Target| targets.iter().position(|&x| x == tg).expect("listed");
    for _ in 0..50 {
        let t_old = t;
        if place_base {
            let predicted: Vec<Vector3<f64>> = s
                .iter()
                .zip(&parents)
                .map(|(x, p)| p.then(&tool[index(x.target)]).translation)
                .collect();
            let measured: Vec<Vector3<f64>> = s.iter().map(|x| x.position).collect();
            let (rot, tr) = kabsch(&predicted, &measured)?;
            t = Frame {
                rotation: rot,
                translation: tr,
            };
        }
        let t_inv = inverse(&t);
        for &(tg, origin, attitude) in &movable {
            let k = index(tg);
            let mine: Vec<(&Sample, &Frame)> = s
                .iter()
                .zip(&parents)
                .filter(|(x, _)| x.target == tg)
                .collect();
            if attitude {
                let m: Matrix3<f64> = mine
                    .iter()
                    .filter_map(|(x, p)| {
                        x.rotation
                            .map(|rm| p.rotation.transpose() * t.rotation.transpose() * rm)
                    })
                    .sum();
                if let Some(rot) = nearest_rotation(&m) {
                    tool[k].rotation = rot;
                }
            }
            if origin {
                let sum: Vector3<f64> = mine
                    .iter()
                    .map(|(x, p)| {
                        let local = t_inv.rotation * x.position + t_inv.translation;
                        p.rotation.transpose() * (local - p.translation)
                    })
                    .sum();
                tool[k].translation = sum / mine.len() as f64;
            }
        }
        let moved = (t.translation - t_old.translation).norm()
            + (t.rotation - t_old.rotation).norm() * robot.reach();
        if place_base && moved < 1e-12 * robot.reach() {
            break;
        }
        if !place_base {
            break;
        }
    }
    if place_base {
        set_frame(&mut r.links[0], &t);
    }
    for &(tg, origin, attitude) in &movable {
        let k = index(tg);
        let f = frame_of(robot, tg);
        let l = link_mut(&mut r, f);
        let mut new = tool[k];
        if !attitude {
            new.rotation = crate::model::kinematics::rot_zyx(l.alpha, l.beta, l.gamma);
        }
        if !origin {
            new.translation = Vector3::new(l.x, l.y, l.z);
        }
        set_frame(l, &new);
    }
    let after = rms(&r, data, &s);
    if !(after.is_finite() && after < before) || r.validate().is_err() {
        return None;
    }
    Some(Registration {
        robot: r,
        rms_before: before,
        rms_after: after,
    })
}

/// [`register`] when the start is far: its RMS position error beyond [`FAR_START`] of the
/// robot's reach.
pub fn register_far_start(
    robot: &Robot,
    data: &Dataset,
    estimated: &[ParamId],
) -> Option<Registration> {
    register_far_start_with(
        robot,
        data,
        estimated,
        &crate::observe::sanity::predicted(robot, data),
    )
}

/// [`register_far_start`] with `robot`'s predicted points at hand ([`crate::observe::sanity::predicted`]).
pub(crate) fn register_far_start_with(
    robot: &Robot,
    data: &Dataset,
    estimated: &[ParamId],
    predicted: &[[Vector3<f64>; 2]],
) -> Option<Registration> {
    let (mut sum, mut count) = (0.0, 0usize);
    for (o, at) in data.observations.iter().zip(predicted) {
        if crate::observe::session_frame(robot, &data.postures[o.posture()]).is_some() {
            continue; // measured in a session's own frame, placed apart
        }
        let position = match o {
            Observation::Pose(p) => p.position,
            Observation::Position(p) => p.position,
            _ => continue,
        };
        sum += (at[0] - position).norm_squared();
        count += 1;
    }
    if count < 3 || (sum / count as f64).sqrt() <= FAR_START * robot.reach() {
        return None;
    }
    register(robot, data, estimated)
}

fn inverse(f: &Frame) -> Frame {
    let rt = f.rotation.transpose();
    Frame {
        rotation: rt,
        translation: -(rt * f.translation),
    }
}

/// Places the frames of `robot`'s sessions whose six parameters are all in `estimated`, in
/// closed form: for each, the rigid transform (Kabsch) taking the points `robot` predicts (in
/// its global frame) to the positions measured in the session. A session is re-placed only when
/// that lowers its RMS position error. Returns the robot and the RMS position errors (m) of the
/// placed sessions before and after (over their observations together), or `None` when no
/// session was placed.
pub(crate) fn place_sessions(
    robot: &Robot,
    data: &Dataset,
    estimated: &[ParamId],
) -> Option<(Robot, f64, f64)> {
    let mut r = robot.clone();
    let chain = Chain::new(robot);
    let mut ws = Workspace::new(robot);
    let (mut before, mut after, mut count) = (0.0, 0.0, 0usize);
    for (si, session) in robot.sessions.iter().enumerate() {
        let all = LinkComponent::ALL.iter().all(|&component| {
            estimated.contains(&robot.param_id(ParamKind::Session {
                session: si,
                component,
            }))
        });
        if !all {
            continue;
        }
        let (mut predicted, mut measured) = (Vec::new(), Vec::new());
        for o in &data.observations {
            let (view, position) = match o {
                Observation::Pose(p) => (p.view[0], p.position),
                Observation::Position(p) => (p.view[0], p.position),
                _ => continue,
            };
            if data.postures[view.posture].session.as_deref() != Some(session.name.as_str()) {
                continue;
            }
            chain.forward(&data.postures[view.posture].readings, &mut ws);
            predicted.push(chain.target_frame(&ws, view.target).translation);
            measured.push(position);
        }
        if predicted.len() < 3 {
            continue;
        }
        let Some((rot, tr)) = kabsch(&predicted, &measured) else {
            continue;
        };
        let now = Frame::from_link(&session.frame);
        let placed = Frame {
            rotation: rot,
            translation: tr,
        };
        let err = |f: &Frame| -> f64 {
            predicted
                .iter()
                .zip(&measured)
                .map(|(p, m)| (f.rotation * p + f.translation - m).norm_squared())
                .sum()
        };
        let (e0, e1) = (err(&now), err(&placed));
        before += e0;
        count += predicted.len();
        if e1 < e0 {
            set_frame(&mut r.sessions[si].frame, &placed);
            after += e1;
        } else {
            after += e0;
        }
    }
    if count == 0 || r == *robot {
        return None;
    }
    let n = count as f64;
    Some((r, (before / n).sqrt(), (after / n).sqrt()))
}
