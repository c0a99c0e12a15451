//! Robots described in other conventions, converted exactly into the thesis model.
//!
//! Each importer produces joint frames (global pose of each joint's frame at the zero
//! configuration, local z along the joint axis) and a tool frame; `chain_from_frames` turns
//! them into links: `L1 = F1`, `L(i+1) = Fi^-1 F(i+1)`, `L(n+1) = Fn^-1 Tool`. With readings equal
//! to the joint values (slope 1), the imported model has the same forward kinematics.

pub mod camera_info;
pub mod dh;
pub mod joints;
pub mod poe;
pub mod readback;
pub mod ros;
pub mod ur;
pub mod urdf;
pub mod xml;

use nalgebra::{Matrix3, Vector3};

use crate::model::kinematics::{euler_zyx, Frame};
use crate::model::robot::{Joint, JointKind, Link, Robot, Tolerances};
use crate::units::Units;

/// The inverse of a rigid transform.
pub fn inverse(f: &Frame) -> Frame {
    let rt = f.rotation.transpose();
    Frame {
        rotation: rt,
        translation: -(rt * f.translation),
    }
}

/// The six link parameters of a frame (m, rad). Components within rounding noise of zero (below
/// 1e-13 m or rad) are written as exact zeros, not as float noise.
pub fn link_of(f: &Frame) -> Link {
    let e = euler_zyx(&f.rotation);
    let snap = |v: f64| if v.abs() < 1e-13 { 0.0 } else { v };
    Link {
        x: snap(f.translation.x),
        y: snap(f.translation.y),
        z: snap(f.translation.z),
        alpha: snap(e.x),
        beta: snap(e.y),
        gamma: snap(e.z),
    }
}

/// A rotation taking local axes to `x` and `z` (orthonormalised; `z` kept).
pub(crate) fn rotation_from_xz(x: &Vector3<f64>, z: &Vector3<f64>) -> Matrix3<f64> {
    let z = z.normalize();
    let x = (x - z * x.dot(&z)).normalize();
    let y = z.cross(&x);
    Matrix3::from_columns(&[x, y, z])
}

/// One joint of an imported chain.
#[derive(Debug, Clone)]
pub(crate) struct ImportedJoint {
    /// Revolute or prismatic.
    pub kind: JointKind,
    /// Global frame of the joint at the zero configuration; the joint moves about/along its z.
    pub frame: Frame,
    /// Joint value at zero reading (rad or m).
    pub offset: f64,
    /// Reading range, in reading units.
    pub range: Option<(f64, f64)>,
}

/// Builds a robot from joint frames and a tool frame (internal units). Readings are the joint
/// values minus `offset` (slope 1).
pub(crate) fn chain_from_frames(
    name: &str,
    units: Units,
    joints: &[ImportedJoint],
    tool: &Frame,
) -> Robot {
    let parents: Vec<usize> = (0..joints.len()).collect();
    tree_from_frames(name, units, joints, &parents, tool)
}

/// `chain_from_frames` for a tree: joint `i`'s link starts from joint `parents[i]`'s frame
/// (1-based; 0 the global frame; each parent before its children), the tool from the last
/// joint's.
pub(crate) fn tree_from_frames(
    name: &str,
    units: Units,
    joints: &[ImportedJoint],
    parents: &[usize],
    tool: &Frame,
) -> Robot {
    let frame_of = |k: usize| {
        k.checked_sub(1)
            .map_or(Frame::identity(), |i| joints[i].frame)
    };
    let mut links = Vec::with_capacity(joints.len() + 1);
    for (j, &p) in joints.iter().zip(parents) {
        links.push(link_of(&inverse(&frame_of(p)).then(&j.frame)));
    }
    links.push(link_of(&inverse(&frame_of(joints.len())).then(tool)));
    Robot {
        name: name.to_string(),
        units,
        links,
        joints: joints
            .iter()
            // Readings are joint values in the file's units: slope 1 there.
            .map(|j| Joint {
                kind: j.kind,
                offset: j.offset,
                slope: units.factor(j.kind.slope()),
                coupling: None,
                range: j.range,
                name: None,
                parent: None,
            })
            .enumerate()
            .map(|(i, mut j)| {
                j.parent = (parents[i] != i).then_some(parents[i]);
                j
            })
            .collect(),
        sites: Vec::new(),
        planes: Vec::new(),
        sessions: Vec::new(),
        tolerances: Tolerances::default(),
        priors: Default::default(),
        elastic: None,
        end_effector: None,
        cameras: Vec::new(),
        boards: Vec::new(),
    }
}

/// What an export could not write: the largest deviation over the joint ranges between the
/// robot and what the file holds.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct Lost {
    /// What it is (`joint 2 slope 1.0003`, `tool correction`, ...).
    pub what: String,
    /// Largest position deviation of `tool0` over the joint ranges (m).
    pub position: f64,
    /// Largest attitude deviation (rad).
    pub attitude: f64,
}

impl Lost {
    /// The sentence the command line prints (and Python warns), in `units`: `not written: joint
    /// 2 slope 1.001 rad/unit; up to 0.3 mm and 0.05 deg at the tool over the joint ranges`.
    pub fn line(&self, units: Units) -> String {
        use crate::units::Quantity;
        use readback::fmt_deviation;
        format!(
            "not written: {}; up to {} {} and {} {} at the tool over the joint ranges",
            self.what,
            fmt_deviation(units.from_si(Quantity::Length, self.position)),
            units.length,
            fmt_deviation(units.from_si(Quantity::Angle, self.attitude)),
            units.angle
        )
    }
}

/// Largest position and attitude difference of the end effector between two robots over 2,000
/// postures drawn within the first one's joint ranges (where it has none, a whole turn of a
/// revolute joint, +-0.1 m of a prismatic one).
pub fn deviation(a: &Robot, b: &Robot) -> (f64, f64) {
    use crate::model::kinematics::{log_so3, Chain, Target, Workspace};
    let (ca, cb) = (Chain::new(a), Chain::new(b));
    let (mut wa, mut wb) = (Workspace::new(a), Workspace::new(b));
    let (mut p, mut r): (f64, f64) = (0.0, 0.0);
    use rand::{RngExt, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let ranges: Vec<(f64, f64)> = a
        .joints
        .iter()
        .map(|j| {
            // Without a range: the readings that turn a revolute joint a whole turn (a
            // prismatic one +-0.1 m) about its offset.
            let span = match j.kind {
                crate::model::robot::JointKind::Revolute => std::f64::consts::PI,
                crate::model::robot::JointKind::Prismatic => 0.1,
            } / j.slope.abs().max(1e-12);
            j.range.unwrap_or((-span, span))
        })
        .collect();
    let mut q = vec![0.0; ranges.len()];
    for _ in 0..2000 {
        for (v, &(lo, hi)) in q.iter_mut().zip(&ranges) {
            *v = rng.random_range(lo..=hi);
        }
        ca.forward(&q, &mut wa);
        cb.forward(&q, &mut wb);
        let (fa, fb): (Frame, Frame) = (
            ca.target_frame(&wa, Target::EndEffector),
            cb.target_frame(&wb, Target::EndEffector),
        );
        p = p.max((fa.translation - fb.translation).norm());
        r = r.max(log_so3(&(fa.rotation * fb.rotation.transpose())).norm());
    }
    (p, r)
}
