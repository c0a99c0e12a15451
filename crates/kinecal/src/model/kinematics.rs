//! Forward kinematics and the analytic parameter Jacobian.
//!
//! Frames are rigid transforms `(R, p)` mapping distal to proximal coordinates; poses are given
//! in the global frame. Orientation is reported as ZYX Euler angles `(alpha, beta, gamma)` with
//! `R = Rz(alpha) Ry(beta) Rx(gamma)`, `beta` in `[-pi/2, pi/2]`.
//!
//! The Jacobian is the *geometric* one: for every parameter, the derivative of the target's
//! origin (rows 0-2, m per parameter unit) and the target's angular velocity in the global frame
//! (rows 3-5, rad per parameter unit). It is propagated through the chain: each parameter is a
//! unit translation along, or rotation about, a known axis of a known frame, so its column is
//! `(u, 0)` for a translation along `u`, or `(u x (e - c), u)` for a rotation about `u` through
//! `c`, with `e` the target origin. Slopes are the offset column times the reading.
//! [`euler_rates`] turns the angular rows into derivatives of the ZYX angles.
//!
//! A robot with a mass model ([`crate::model::robot::Elastic`]) is elastic: its joints yield to the
//! gravity torques, [`Chain::forward`] solves the static equilibrium and the Jacobian is that of
//! the deflected robot with the deflections' response included (see the `elastic` module's
//! documentation for the model and its derivatives).

mod elastic;

use nalgebra::{Matrix3, Vector3};

pub use elastic::{gravity_free_joints, Equilibrium, GravityFree};

pub(crate) use elastic::unconverged_posture;

use crate::model::params::{ParamId, ParamKind};
use crate::model::robot::{JointKind, Link, Robot};

/// A rigid transform: a point `v` in this frame is `rotation * v + translation` in the parent.
///
/// Laid out as 12 numbers, the rotation's columns then the translation (the batched pass
/// writes a frame in three 4-number stores).
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C)]
pub struct Frame {
    /// Orientation of the frame's axes in the parent frame.
    pub rotation: Matrix3<f64>,
    /// Origin of the frame in the parent frame.
    pub translation: Vector3<f64>,
}

impl Frame {
    /// The identity transform.
    pub fn identity() -> Self {
        Frame {
            rotation: Matrix3::identity(),
            translation: Vector3::zeros(),
        }
    }

    /// `self * other`: `other` expressed in `self`'s parent.
    #[inline]
    pub fn then(&self, other: &Frame) -> Frame {
        // Written out: nalgebra's generic 3x3 product is several times slower here.
        let a = &self.rotation;
        let b = &other.rotation;
        let t = &other.translation;
        let mut r = Matrix3::zeros();
        for i in 0..3 {
            for j in 0..3 {
                r[(i, j)] = a[(i, 0)] * b[(0, j)] + a[(i, 1)] * b[(1, j)] + a[(i, 2)] * b[(2, j)];
            }
        }
        let p = Vector3::new(
            self.translation.x + a[(0, 0)] * t.x + a[(0, 1)] * t.y + a[(0, 2)] * t.z,
            self.translation.y + a[(1, 0)] * t.x + a[(1, 1)] * t.y + a[(1, 2)] * t.z,
            self.translation.z + a[(2, 0)] * t.x + a[(2, 1)] * t.y + a[(2, 2)] * t.z,
        );
        Frame {
            rotation: r,
            translation: p,
        }
    }

    /// The link transform `Trans(x,y,z) Rz(alpha) Ry(beta) Rx(gamma)` (thesis eq. 2.1).
    pub fn from_link(l: &Link) -> Frame {
        Frame {
            rotation: rot_zyx(l.alpha, l.beta, l.gamma),
            translation: Vector3::new(l.x, l.y, l.z),
        }
    }

    /// The pose of this frame: origin and ZYX Euler angles.
    pub fn pose(&self) -> Pose {
        Pose {
            position: self.translation,
            euler: euler_zyx(&self.rotation),
        }
    }
}

/// A position and ZYX Euler attitude (m, rad).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// Origin `(x, y, z)`.
    pub position: Vector3<f64>,
    /// `(alpha, beta, gamma)`, `R = Rz(alpha) Ry(beta) Rx(gamma)`.
    pub euler: Vector3<f64>,
}

/// `Rz(alpha) Ry(beta) Rx(gamma)`.
pub fn rot_zyx(alpha: f64, beta: f64, gamma: f64) -> Matrix3<f64> {
    let (sa, ca) = alpha.sin_cos();
    let (sb, cb) = beta.sin_cos();
    let (sg, cg) = gamma.sin_cos();
    Matrix3::new(
        ca * cb,
        ca * sb * sg - sa * cg,
        ca * sb * cg + sa * sg,
        sa * cb,
        sa * sb * sg + ca * cg,
        sa * sb * cg - ca * sg,
        -sb,
        cb * sg,
        cb * cg,
    )
}

/// ZYX Euler angles `(alpha, beta, gamma)` of a rotation matrix, `beta` in `[-pi/2, pi/2]`,
/// `alpha` and `gamma` in `(-pi, pi]`. At `beta = +-pi/2` (gimbal lock) `gamma` is set to 0.
pub fn euler_zyx(r: &Matrix3<f64>) -> Vector3<f64> {
    let cb = (r[(0, 0)] * r[(0, 0)] + r[(1, 0)] * r[(1, 0)]).sqrt();
    let beta = (-r[(2, 0)]).atan2(cb);
    if cb > 1e-12 {
        Vector3::new(r[(1, 0)].atan2(r[(0, 0)]), beta, r[(2, 1)].atan2(r[(2, 2)]))
    } else {
        // Only alpha - gamma (beta = +pi/2) or alpha + gamma (beta = -pi/2) is defined.
        Vector3::new((-r[(0, 1)]).atan2(r[(1, 1)]), beta, 0.0)
    }
}

/// Converts an angular velocity `omega` (global frame) to the rates of the ZYX Euler angles of a
/// frame at attitude `(alpha, beta, _)`. Infinite at `beta = +-pi/2`; there `cos(beta)` is
/// clamped to 1e-12 so the result stays finite (callers warn about gimbal lock).
#[inline]
pub fn euler_rates(alpha: f64, beta: f64, omega: &Vector3<f64>) -> Vector3<f64> {
    let (sa, ca) = alpha.sin_cos();
    let (sb, mut cb) = beta.sin_cos();
    if cb.abs() < 1e-12 {
        cb = 1e-12f64.copysign(cb);
    }
    let h = (omega.x * ca + omega.y * sa) / cb;
    Vector3::new(omega.z + sb * h, -omega.x * sa + omega.y * ca, h)
}

/// Which frame of the robot is measured.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Target {
    /// The end-effector frame.
    EndEffector,
    /// Extra site number `i` (0-based index into `Robot::sites`).
    Site(usize),
}

impl Target {
    /// The tool frame of `robot` called `name`: the end effector by `ee` or by its own name
    /// ([`Robot::end_effector`]: an imported URDF's tip link, a chain's as a tree's), else the
    /// site so called. The one rule every file, option and spec names a target by.
    pub fn named(robot: &Robot, name: &str) -> Option<Target> {
        match name {
            "ee" => Some(Target::EndEffector),
            name if robot.end_effector.as_deref() == Some(name) => Some(Target::EndEffector),
            name => robot
                .sites
                .iter()
                .position(|s| s.name == name)
                .map(Target::Site),
        }
    }
}

/// Posture-independent data of one link (or site) transform, precomputed once per parameter set.
#[derive(Debug, Clone, Copy)]
struct LinkCache {
    frame: Frame,
    /// `Rz(alpha) e_y`: the axis of beta, in the proximal frame.
    beta_axis: Vector3<f64>,
    /// `Rz(alpha) Ry(beta) e_x`: the axis of gamma, in the proximal frame.
    gamma_axis: Vector3<f64>,
}

impl LinkCache {
    fn new(l: &Link) -> Self {
        let (sa, ca) = l.alpha.sin_cos();
        let (sb, cb) = l.beta.sin_cos();
        LinkCache {
            frame: Frame::from_link(l),
            beta_axis: Vector3::new(-sa, ca, 0.0),
            gamma_axis: Vector3::new(ca * cb, sa * cb, -sb),
        }
    }
}

/// The sines and cosines of the reading parts `b = slope * V_j + coupling * V_k` of every
/// revolute joint angle at every posture of a dataset, for a robot's slopes and couplings: a
/// solver that moves offsets and geometry but not slopes or couplings computes them once
/// instead of at every pass ([`Chain::forward_with`]). Prismatic joints get `(0, 1)`.
#[derive(Debug, Clone, PartialEq)]
pub struct ReadingTrig {
    /// `(slope, coupling)` of each joint the table was made for.
    made_for: Vec<(f64, Option<(usize, f64)>)>,
    /// Posture-major: `values[p * dof + j]`.
    values: Vec<(f64, f64)>,
    dof: usize,
}

impl ReadingTrig {
    /// The table for `robot`'s slopes and couplings over the readings of each posture.
    pub fn new<'a>(
        robot: &Robot,
        postures: impl ExactSizeIterator<Item = &'a [f64]>,
    ) -> ReadingTrig {
        let dof = robot.dof();
        let mut values = Vec::with_capacity(postures.len() * dof);
        for readings in postures {
            for (j, joint) in robot.joints.iter().enumerate() {
                values.push(match joint.kind {
                    JointKind::Revolute => {
                        let mut b = joint.slope * readings[j];
                        if let Some(c) = joint.coupling {
                            b += c.factor * readings[c.joint];
                        }
                        b.sin_cos()
                    }
                    JointKind::Prismatic => (0.0, 1.0),
                });
            }
        }
        ReadingTrig {
            made_for: ReadingTrig::signature(robot),
            values,
            dof,
        }
    }

    fn signature(robot: &Robot) -> Vec<(f64, Option<(usize, f64)>)> {
        robot
            .joints
            .iter()
            .map(|j| (j.slope, j.coupling.map(|c| (c.joint, c.factor))))
            .collect()
    }

    /// Whether the table holds for `robot` (the same slopes and couplings, bit for bit).
    pub fn fits(&self, robot: &Robot) -> bool {
        robot.dof() == self.dof
            && robot.joints.iter().zip(&self.made_for).all(|(j, (s, c))| {
                j.slope.to_bits() == s.to_bits()
                    && match (j.coupling, c) {
                        (None, None) => true,
                        (Some(a), Some((k, f))) => {
                            a.joint == *k && a.factor.to_bits() == f.to_bits()
                        }
                        _ => false,
                    }
            })
    }

    /// The row of posture `p`.
    pub fn posture(&self, p: usize) -> &[(f64, f64)] {
        &self.values[p * self.dof..(p + 1) * self.dof]
    }
}

/// The frames of one posture, filled by [`Chain::forward`]. Allocate once and reuse: the hot
/// path does not allocate.
#[derive(Debug, Clone)]
pub struct Workspace {
    /// `after[k]`: global frame right after joint k (1-based; `after[0]` is the global frame),
    /// where the links of k's children, its sites and its bodies start.
    after: Vec<Frame>,
    /// `dist[i]`: global frame at the distal end of link i (before joint i turns, after an
    /// elastic robot's joint tilted; `dist[n]` is the EECF).
    dist: Vec<Frame>,
    readings: Vec<f64>,
    /// The deflections and their response, for an elastic robot.
    elastic: Option<Box<elastic::ElasticState>>,
}

impl Workspace {
    /// A workspace for `robot`'s chain.
    pub fn new(robot: &Robot) -> Self {
        let n = robot.dof();
        Workspace {
            after: vec![Frame::identity(); n + 1],
            dist: vec![Frame::identity(); n + 1],
            readings: vec![0.0; n],
            elastic: robot
                .elastic
                .as_ref()
                .map(|_| Box::new(elastic::ElasticState::new(robot))),
        }
    }

    /// How the equilibrium of the last [`Chain::forward`] went (an elastic robot only).
    pub fn equilibrium(&self) -> Option<Equilibrium> {
        self.elastic.as_deref().map(|e| e.last)
    }

    /// The deflections of the last [`Chain::forward`] (an elastic robot only): `[2i]` the tilt
    /// of joint `i + 1` about its lateral axis, `[2i + 1]` its turn about its own axis (rad).
    pub fn deflections(&self) -> Option<&[f64]> {
        self.elastic.as_deref().map(|e| e.delta.as_slice())
    }

    /// The gravity torques of the last [`Chain::forward`] (an elastic robot only), in the
    /// order of [`Workspace::deflections`] (N m).
    pub fn gravity_torques(&self) -> Option<&[f64]> {
        self.elastic.as_deref().map(|e| e.tau.as_slice())
    }

    /// The global frame right after joint `k` (1-based; 0 is the global frame itself) of the
    /// last [`Chain::forward`]: the frame link `k + 1` and the sites of joint `k` hang off.
    pub fn after_joint(&self, k: usize) -> &Frame {
        &self.after[k]
    }

    /// The end-effector frame of the last [`Chain::forward`].
    pub fn end_effector(&self) -> &Frame {
        self.dist.last().expect("chain has links")
    }
}

/// Which Jacobian columns to compute for one target, and where each goes: worked out once from
/// a robot's structure (joint kinds, couplings, sites) and the wanted parameters, then used at
/// every posture by [`Chain::jacobian_columns`] for any robot of that structure.
#[derive(Debug, Clone, PartialEq)]
pub struct ColumnPlan {
    target: Target,
    /// The columns of the output block.
    width: usize,
    /// Links (and the target site's frame) with a wanted parameter, upstream of the target.
    links: Vec<LinkColumns>,
    /// Joints with a wanted offset, slope or coupling factor, upstream of the target.
    joints: Vec<JointColumns>,
    /// Wanted columns of parameters that cannot move the target.
    zero: Vec<usize>,
    /// For an elastic robot: the wanted compliances, `(deflection, column)` (deflection `2i`
    /// the tilt of joint i, `2i + 1` its turn).
    elastic: Vec<(usize, usize)>,
    /// The wanted components of the mass model's bodies, `(body, component, column)`.
    bodies: Vec<(usize, crate::model::params::BodyComponent, usize)>,
    /// The node the target hangs off (0-based joint a site follows; `n` for the end
    /// effector), for an elastic robot's response.
    node: usize,
    /// Whether every planned link and joint is upstream of the target (a rigid robot's plan):
    /// [`Chain::jacobian_columns`] then takes its rigid path.
    rigid: bool,
}

/// The wanted columns of one link transform: its translations along and rotations about its
/// proximal frame's axes.
#[derive(Debug, Clone, PartialEq)]
struct LinkColumns {
    /// The proximal frame (`Workspace::after` index: the joint it starts after, 1-based).
    frame: usize,
    cache: LinkOf,
    /// Columns of `x, y, z`.
    translation: [Option<usize>; 3],
    /// Columns of `alpha, beta, gamma`.
    rotation: [Option<usize>; 3],
    /// Whether the transform is upstream of the target (an elastic robot plans the others too:
    /// they move the target through the gravity torques only).
    upstream: bool,
}

/// Whose transform: link `i` or site `s`.
#[derive(Debug, Clone, Copy, PartialEq)]
enum LinkOf {
    Link(usize),
    Site(usize),
}

/// The wanted columns of one joint.
#[derive(Debug, Clone, PartialEq)]
struct JointColumns {
    joint: usize,
    offset: Option<usize>,
    slope: Option<usize>,
    /// The coupling factor's column and the joint whose reading it multiplies.
    coupling: Option<(usize, usize)>,
    /// Whether the joint is upstream of the target (see [`LinkColumns::upstream`]).
    upstream: bool,
}

impl ColumnPlan {
    /// The plan for `target` of `robot`: `columns[p]` (one entry per parameter number) is the
    /// output column of parameter `p`, `None` when not wanted. The output is as wide as the
    /// largest column named, plus one.
    pub fn new(robot: &Robot, target: Target, columns: &[Option<usize>]) -> ColumnPlan {
        assert_eq!(
            columns.len(),
            robot.param_count(),
            "one entry per parameter"
        );
        let (nl, nj) = (robot.links.len(), robot.dof());
        // The joints on the path to the target (in a serial chain, those before it); the links
        // before them, and the tool link for the end effector.
        let attach = target_joint(robot, target);
        let path = robot.path_to(attach);
        let link_upstream = |i: usize| match path.get(i) {
            Some(&on) => on,
            None => target == Target::EndEffector,
        };
        let mut covered = vec![false; columns.len()];
        let mut take = |p: usize| {
            covered[p] = true;
            columns[p]
        };
        // An elastic robot's links and joints past the target move it through the torques.
        let elastic = robot.elastic.is_some();
        let mut links = Vec::new();
        let mut link = |first: usize, frame: usize, cache: LinkOf, upstream: bool| {
            let l = LinkColumns {
                frame,
                cache,
                translation: [take(first), take(first + 1), take(first + 2)],
                rotation: [take(first + 3), take(first + 4), take(first + 5)],
                upstream,
            };
            if l.translation.iter().chain(&l.rotation).any(Option::is_some) {
                links.push(l);
            }
        };
        for i in (0..nl).filter(|&i| elastic || link_upstream(i)) {
            link(
                6 * i,
                robot.link_parent(i),
                LinkOf::Link(i),
                link_upstream(i),
            );
        }
        if let Target::Site(s) = target {
            link(
                6 * nl + 2 * nj + 6 * s,
                robot.sites[s].joint,
                LinkOf::Site(s),
                true,
            );
        }
        let mut joints = Vec::new();
        for j in (0..nj).filter(|&j| elastic || path[j]) {
            let coupling = robot.joints[j].coupling.and_then(|c| {
                let p = robot.param_id(ParamKind::Coupling { joint: j }).0;
                take(p).map(|col| (col, c.joint))
            });
            let jc = JointColumns {
                joint: j,
                offset: take(6 * nl + j),
                slope: take(6 * nl + nj + j),
                coupling,
                upstream: path[j],
            };
            if jc.offset.is_some() || jc.slope.is_some() || jc.coupling.is_some() {
                joints.push(jc);
            }
        }
        let mut compliances = Vec::new();
        for j in robot.compliant_joints() {
            for (kind, deflection) in [
                (ParamKind::Compliance { joint: j }, 2 * j + 1),
                (ParamKind::Lateral { joint: j }, 2 * j),
            ] {
                if let Some(col) = take(robot.param_id(kind).0) {
                    compliances.push((deflection, col));
                }
            }
        }
        let mut bodies = Vec::new();
        for body in 0..robot.body_count() {
            for component in crate::model::params::BodyComponent::ALL {
                if let Some(col) = take(robot.param_id(ParamKind::Body { body, component }).0) {
                    bodies.push((body, component, col));
                }
            }
        }
        let zero = columns
            .iter()
            .zip(&covered)
            .filter_map(|(c, &done)| c.filter(|_| !done))
            .collect();
        let rigid = links.iter().all(|l: &LinkColumns| l.upstream)
            && joints.iter().all(|j: &JointColumns| j.upstream);
        ColumnPlan {
            rigid,
            target,
            width: columns.iter().flatten().max().map_or(0, |&c| c + 1),
            links,
            joints,
            zero,
            elastic: compliances,
            bodies,
            node: match target {
                Target::EndEffector => nj,
                Target::Site(_) => attach - 1,
            },
        }
    }

    /// The plan of every parameter of `robot`, each in its own column (parameter `p` in column
    /// `p`): [`Chain::jacobian`]'s.
    pub fn all(robot: &Robot, target: Target) -> ColumnPlan {
        let columns: Vec<Option<usize>> = (0..robot.param_count()).map(Some).collect();
        ColumnPlan::new(robot, target, &columns)
    }

    /// The number of columns of the output block.
    pub fn width(&self) -> usize {
        self.width
    }
}

/// A robot's chain with its posture-independent transforms precomputed.
#[derive(Debug, Clone)]
pub struct Chain<'r> {
    robot: &'r Robot,
    links: Vec<LinkCache>,
    sites: Vec<LinkCache>,
    /// `(sin, cos)` of each joint's offset (for [`Chain::forward_with`]).
    offset_trig: Vec<(f64, f64)>,
    /// [`Robot::link_parent`] of each link.
    parents: Vec<usize>,
    /// What each joint's variable needs, packed for the serial pass.
    joints: Vec<JointCache>,
    /// Whether every link starts right after the previous joint (no branch): the rigid forward
    /// kinematics then take [`Chain::forward_serial`], chosen here once.
    serial: bool,
}

/// One joint's variable `q = offset + slope * V_own + factor * V_other`, packed: the serial
/// pass reads these 40 bytes instead of the robot's [`crate::model::robot::Joint`].
#[derive(Debug, Clone, Copy)]
struct JointCache {
    revolute: bool,
    offset: f64,
    slope: f64,
    /// `(joint whose reading is added, factor)`.
    coupling: Option<(usize, f64)>,
}

impl JointCache {
    fn new(j: &crate::model::robot::Joint) -> Self {
        JointCache {
            revolute: j.kind == JointKind::Revolute,
            offset: j.offset,
            slope: j.slope,
            coupling: j.coupling.map(|c| (c.joint, c.factor)),
        }
    }
}

impl<'r> Chain<'r> {
    /// Precomputes the link and site transforms of `robot`.
    pub fn new(robot: &'r Robot) -> Self {
        Chain {
            robot,
            links: robot.links.iter().map(LinkCache::new).collect(),
            sites: robot
                .sites
                .iter()
                .map(|s| LinkCache::new(&s.frame))
                .collect(),
            offset_trig: robot.joints.iter().map(|j| j.offset.sin_cos()).collect(),
            parents: (0..=robot.dof()).map(|i| robot.link_parent(i)).collect(),
            joints: robot.joints.iter().map(JointCache::new).collect(),
            serial: !robot.is_tree(),
        }
    }

    /// Whether the rigid forward kinematics take the serial pass (no branch in the chain: each
    /// link starts after the previous joint, so no frame is looked up per link), else the
    /// general one that also serves trees and an elastic robot's deflections.
    pub fn is_serial(&self) -> bool {
        self.serial
    }

    /// The robot.
    pub fn robot(&self) -> &'r Robot {
        self.robot
    }

    /// Computes every frame of the chain for transducer `readings` (one per joint).
    #[inline]
    #[allow(clippy::needless_range_loop)] // i indexes links, frames and joints together
    pub fn forward(&self, readings: &[f64], ws: &mut Workspace) {
        self.forward_with(readings, None, ws);
    }

    /// [`Chain::forward`], with the sines and cosines of the reading parts of the joint angles
    /// given (`reading_trig[j] = (sin b, cos b)`, `b = slope * V_j + coupling * V_k`, the angle
    /// without its offset; see [`ReadingTrig`]): each revolute joint's angle then costs four
    /// products (`sin(offset + b)` by the addition formula) instead of a sine and a cosine.
    #[inline]
    #[allow(clippy::needless_range_loop)] // i indexes links, frames and joints together
    pub fn forward_with(
        &self,
        readings: &[f64],
        reading_trig: Option<&[(f64, f64)]>,
        ws: &mut Workspace,
    ) {
        self.forward_loaded(readings, reading_trig, None, ws);
    }

    /// [`Chain::forward_with`] with the tool carrying `payload` (an elastic robot's joints yield
    /// to its weight too; a rigid robot ignores it).
    #[inline]
    pub fn forward_loaded(
        &self,
        readings: &[f64],
        reading_trig: Option<&[(f64, f64)]>,
        payload: Option<&crate::model::robot::Payload>,
        ws: &mut Workspace,
    ) {
        match &self.robot.elastic {
            Some(model) if ws.elastic.is_some() => {
                self.forward_elastic(model, readings, payload, ws)
            }
            _ if self.serial => self.forward_serial(readings, reading_trig, ws),
            _ => self.forward_rigid(readings, reading_trig, None, ws),
        }
    }

    /// The rigid serial chain at `readings`: [`Chain::forward_rigid`] without its tree and
    /// deflection cases, the joints read from their packed copies. Same arithmetic, same frames
    /// to the last bit (`tests::the_serial_pass_is_the_general_one`).
    #[inline]
    fn forward_serial(
        &self,
        readings: &[f64],
        reading_trig: Option<&[(f64, f64)]>,
        ws: &mut Workspace,
    ) {
        let n = self.joints.len();
        debug_assert_eq!(readings.len(), n);
        debug_assert!(self.serial);
        ws.readings.copy_from_slice(readings);
        ws.after[0] = Frame::identity();
        let (after, dist) = (&mut ws.after[1..=n], &mut ws.dist[..n]);
        let mut current = Frame::identity().then(&self.links[0].frame);
        for (i, joint) in self.joints.iter().enumerate() {
            dist[i] = current;
            // Joint::value, from the packed copy.
            let q = || {
                let q = joint.offset + joint.slope * readings[i];
                match joint.coupling {
                    Some((k, factor)) => q + factor * readings[k],
                    None => q,
                }
            };
            if joint.revolute {
                let (s, c) = match reading_trig {
                    Some(t) => {
                        let ((so, co), (sb, cb)) = (self.offset_trig[i], t[i]);
                        (so * cb + co * sb, co * cb - so * sb)
                    }
                    None => q().sin_cos(),
                };
                let r = &mut current.rotation;
                for row in 0..3 {
                    let (x, y) = (r[(row, 0)], r[(row, 1)]);
                    r[(row, 0)] = x * c + y * s;
                    r[(row, 1)] = y * c - x * s;
                }
            } else {
                let z = current.rotation.column(2).into_owned();
                current.translation += z * q();
            }
            after[i] = current;
            current = current.then(&self.links[i + 1].frame);
        }
        ws.dist[n] = current;
    }

    /// The rigid chain at `readings`, with the deflections `delta` (see [`Workspace::deflections`])
    /// added when given.
    #[inline]
    #[allow(clippy::needless_range_loop)] // i indexes links, frames and joints together
    fn forward_rigid(
        &self,
        readings: &[f64],
        reading_trig: Option<&[(f64, f64)]>,
        delta: Option<&[f64]>,
        ws: &mut Workspace,
    ) {
        let n = self.robot.dof();
        debug_assert_eq!(readings.len(), n);
        ws.readings.copy_from_slice(readings);
        ws.after[0] = Frame::identity();
        let mut current = Frame::identity();
        for i in 0..=n {
            // A serial chain goes on from the last frame; a tree's branch from its parent's.
            let parent = self.parents[i];
            if parent != i {
                current = ws.after[parent];
            }
            current = current.then(&self.links[i].frame);
            if i < n {
                let joint = &self.robot.joints[i];
                let mut q = joint.value(readings, i);
                if let (Some(d), Some(model)) = (delta, &self.robot.elastic) {
                    if joint.kind == JointKind::Revolute {
                        current.rotation = elastic::turn_about_local(
                            &current.rotation,
                            &model.joints[i].lateral_axis,
                            d[2 * i],
                        );
                        q += d[2 * i + 1];
                    }
                }
                ws.dist[i] = current;
                match joint.kind {
                    JointKind::Revolute => {
                        let (s, c) = match reading_trig {
                            Some(t) => {
                                let ((so, co), (sb, cb)) = (self.offset_trig[i], t[i]);
                                (so * cb + co * sb, co * cb - so * sb)
                            }
                            None => q.sin_cos(),
                        };
                        let r = current.rotation;
                        current
                            .rotation
                            .set_column(0, &(r.column(0) * c + r.column(1) * s));
                        current
                            .rotation
                            .set_column(1, &(r.column(1) * c - r.column(0) * s));
                    }
                    JointKind::Prismatic => {
                        current.translation += current.rotation.column(2) * q;
                    }
                }
                ws.after[i + 1] = current;
            } else {
                ws.dist[i] = current;
            }
        }
    }

    /// The global frame of `target` after [`Chain::forward`].
    #[inline]
    pub fn target_frame(&self, ws: &Workspace, target: Target) -> Frame {
        match target {
            Target::EndEffector => *ws.end_effector(),
            Target::Site(s) => {
                // The frame right after joint k is the proximal frame of link k+1.
                let k = self.robot.sites[s].joint;
                ws.after[k].then(&self.sites[s].frame)
            }
        }
    }

    /// Convenience: the global frame of `target` at `readings` (allocates a workspace).
    pub fn frame_at(&self, readings: &[f64], target: Target) -> Frame {
        let mut ws = Workspace::new(self.robot);
        self.forward(readings, &mut ws);
        self.target_frame(&ws, target)
    }

    /// Writes the geometric Jacobian of `target` (after [`Chain::forward`]) into `out`, a
    /// column-major 6 x `param_count` block: column `p` holds `d(origin)/dp` in rows 0-2 and the
    /// global angular velocity per unit `p` in rows 3-5. Parameters that cannot move the target
    /// get zero columns. Works out its [`ColumnPlan`] at every call (allocates): a loop over
    /// postures makes the plan once and calls [`Chain::jacobian_columns`].
    pub fn jacobian(&self, ws: &Workspace, target: Target, out: &mut [f64]) {
        assert_eq!(
            out.len(),
            6 * self.robot.param_count(),
            "Jacobian block has the wrong size"
        );
        self.jacobian_columns(ws, &ColumnPlan::all(self.robot, target), out);
    }

    /// The Jacobian columns `plan` names, packed into `out` (6 x [`ColumnPlan::width`],
    /// column-major), after [`Chain::forward`]: each as in [`Chain::jacobian`]. Only the
    /// planned columns are touched, and each is written (zero for a parameter that cannot move
    /// the target); nothing is allocated and no parameter is looked at that is not wanted.
    ///
    /// Of an elastic robot (solved by [`Chain::forward`] with its equilibrium), each column
    /// also carries the motion of the target that the deflections' response to the parameter
    /// causes (see the `elastic` module), and the compliance and body columns are only that.
    pub fn jacobian_columns(&self, ws: &Workspace, plan: &ColumnPlan, out: &mut [f64]) {
        assert!(out.len() >= 6 * plan.width, "Jacobian block too small");
        if plan.rigid && !(ws.elastic.is_some() && self.robot.elastic.is_some()) {
            self.jacobian_rigid(ws, plan, out);
        } else {
            self.jacobian_general(ws, plan, out);
        }
    }

    /// [`Chain::jacobian_columns`] of a rigid robot: every planned link and joint is upstream
    /// of the target (a rigid plan holds no other), no deflection responds, and the compliance
    /// and body columns are zero. The same columns as [`Chain::jacobian_general`], to the bit.
    fn jacobian_rigid(&self, ws: &Workspace, plan: &ColumnPlan, out: &mut [f64]) {
        let e = self.target_frame(ws, plan.target).translation;
        let zero = Vector3::zeros();
        for l in &plan.links {
            let prox = &ws.after[l.frame];
            let r = &prox.rotation;
            for (k, col) in l.translation.iter().enumerate() {
                if let Some(col) = *col {
                    put(out, col, &r.column(k).into_owned(), &zero);
                }
            }
            if l.rotation.iter().all(Option::is_none) {
                continue;
            }
            let cache = match l.cache {
                LinkOf::Link(i) => &self.links[i],
                LinkOf::Site(s) => &self.sites[s],
            };
            let c = prox.translation + r * cache.frame.translation;
            let lever = e - c;
            for (k, axis_local) in [Vector3::z(), cache.beta_axis, cache.gamma_axis]
                .iter()
                .enumerate()
            {
                if let Some(col) = l.rotation[k] {
                    let u = r * axis_local;
                    put(out, col, &u.cross(&lever), &u);
                }
            }
        }
        for j in &plan.joints {
            let (dp, w) = self.joint_motion(ws, j.joint, &e);
            if let Some(col) = j.offset {
                put(out, col, &dp, &w);
            }
            if let Some(col) = j.slope {
                let v = ws.readings[j.joint];
                put(out, col, &(dp * v), &(w * v));
            }
            if let Some((col, k)) = j.coupling {
                let v = ws.readings[k];
                put(out, col, &(dp * v), &(w * v));
            }
        }
        for &(_, col) in &plan.elastic {
            put(out, col, &zero, &zero);
        }
        for &(_, _, col) in &plan.bodies {
            put(out, col, &zero, &zero);
        }
        for &col in &plan.zero {
            put(out, col, &zero, &zero);
        }
    }

    /// [`Chain::jacobian_columns`] for any robot, elastic or rigid.
    fn jacobian_general(&self, ws: &Workspace, plan: &ColumnPlan, out: &mut [f64]) {
        assert!(out.len() >= 6 * plan.width, "Jacobian block too small");
        let elastic = ws.elastic.is_some() && self.robot.elastic.is_some();
        let e = self.target_frame(ws, plan.target).translation;
        let zero = Vector3::zeros();
        let upto = plan.node;
        for l in &plan.links {
            let prox = &ws.after[l.frame];
            let r = &prox.rotation;
            // Where the link sits in the chain, for the torques (a site carries no body).
            let at = match l.cache {
                LinkOf::Link(i) if elastic => Some(3 * i),
                _ => None,
            };
            for (k, col) in l.translation.iter().enumerate() {
                if let Some(col) = *col {
                    let u = r.column(k).into_owned();
                    put(out, col, if l.upstream { &u } else { &zero }, &zero);
                    if let Some(at) = at {
                        let twist = elastic::Twist::Translation { u, at };
                        let c = &mut out[6 * col..6 * col + 6];
                        self.elastic_column(ws, elastic::Cause::Twist(&twist, 1.0), &e, upto, c);
                    }
                }
            }
            if l.rotation.iter().all(Option::is_none) {
                continue;
            }
            let cache = match l.cache {
                LinkOf::Link(i) => &self.links[i],
                LinkOf::Site(s) => &self.sites[s],
            };
            let c = prox.translation + r * cache.frame.translation;
            let lever = e - c;
            for (k, axis_local) in [Vector3::z(), cache.beta_axis, cache.gamma_axis]
                .iter()
                .enumerate()
            {
                if let Some(col) = l.rotation[k] {
                    let u = r * axis_local;
                    if l.upstream {
                        put(out, col, &u.cross(&lever), &u);
                    } else {
                        put(out, col, &zero, &zero);
                    }
                    if let Some(at) = at {
                        let twist = elastic::Twist::Rotation { u, c, at };
                        let o = &mut out[6 * col..6 * col + 6];
                        self.elastic_column(ws, elastic::Cause::Twist(&twist, 1.0), &e, upto, o);
                    }
                }
            }
        }
        for j in &plan.joints {
            let (dp, w) = if j.upstream {
                self.joint_motion(ws, j.joint, &e)
            } else {
                (zero, zero)
            };
            let twist = elastic.then(|| self.joint_twist(ws, j.joint));
            let mut column = |col: usize, scale: f64| {
                put(out, col, &(dp * scale), &(w * scale));
                if let Some(twist) = &twist {
                    let o = &mut out[6 * col..6 * col + 6];
                    self.elastic_column(ws, elastic::Cause::Twist(twist, scale), &e, upto, o);
                }
            };
            if let Some(col) = j.offset {
                column(col, 1.0);
            }
            if let Some(col) = j.slope {
                column(col, ws.readings[j.joint]);
            }
            if let Some((col, k)) = j.coupling {
                column(col, ws.readings[k]);
            }
        }
        for &(deflection, col) in &plan.elastic {
            put(out, col, &zero, &zero);
            if elastic {
                let o = &mut out[6 * col..6 * col + 6];
                self.elastic_column(ws, elastic::Cause::Compliance(deflection), &e, upto, o);
            }
        }
        for &(body, component, col) in &plan.bodies {
            put(out, col, &zero, &zero);
            if elastic {
                let o = &mut out[6 * col..6 * col + 6];
                self.elastic_column(ws, elastic::Cause::Body(body, component), &e, upto, o);
            }
        }
        for &col in &plan.zero {
            put(out, col, &zero, &zero);
        }
    }
}

/// How many postures [`Chain::forward_batch`] computes at once.
pub const BATCH: usize = 4;

/// One matrix entry of [`BATCH`] postures.
type Lanes = [f64; BATCH];

/// The same frame of [`BATCH`] postures, entry by entry (structure of arrays): each operation
/// on it is one vector operation, lane `k` doing exactly what the scalar pass does for posture
/// `k`.
#[derive(Clone, Copy)]
struct Frames {
    /// `rotation[(i, j)]` of each posture.
    rotation: [[Lanes; 3]; 3],
    /// `translation[i]` of each posture.
    translation: [Lanes; 3],
}

#[inline(always)]
fn lanes_add(a: Lanes, b: Lanes) -> Lanes {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2], a[3] + b[3]]
}

#[inline(always)]
fn lanes_sub(a: Lanes, b: Lanes) -> Lanes {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2], a[3] - b[3]]
}

#[inline(always)]
fn lanes_mul(a: Lanes, b: Lanes) -> Lanes {
    [a[0] * b[0], a[1] * b[1], a[2] * b[2], a[3] * b[3]]
}

/// `a * s` in every lane.
#[inline(always)]
fn lanes_scale(a: Lanes, s: f64) -> Lanes {
    [a[0] * s, a[1] * s, a[2] * s, a[3] * s]
}

/// Writes lane `k` of `f` to `out[k]`.
#[inline(always)]
fn store_lanes(f: &Frames, out: [&mut Frame; BATCH]) {
    for (k, o) in out.into_iter().enumerate() {
        *o = f.lane(k);
    }
}

// The layout `store_lanes_avx2` writes: 12 numbers, the rotation's columns then the translation.
const _: () = assert!(
    std::mem::size_of::<Frame>() == 12 * 8 && std::mem::offset_of!(Frame, translation) == 9 * 8
);

/// [`store_lanes`] by 4 x 4 transposes: the 12 entries of a frame in [`Frame`]'s order (the
/// rotation column by column, then the translation), in three groups of four, each group's
/// four lanes turned into four postures' rows and stored in one instruction each.
///
/// # Safety
///
/// The processor must have AVX2.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn store_lanes_avx2(f: &Frames, out: [&mut Frame; BATCH]) {
    use std::arch::x86_64::{
        _mm256_loadu_pd, _mm256_permute2f128_pd, _mm256_storeu_pd, _mm256_unpackhi_pd,
        _mm256_unpacklo_pd,
    };
    let (r, t) = (&f.rotation, &f.translation);
    let groups = [
        [&r[0][0], &r[1][0], &r[2][0], &r[0][1]],
        [&r[1][1], &r[2][1], &r[0][2], &r[1][2]],
        [&r[2][2], &t[0], &t[1], &t[2]],
    ];
    let out = out.map(|o| o as *mut Frame as *mut f64);
    for (g, [a, b, c, d]) in groups.into_iter().enumerate() {
        // SAFETY: each lane array holds 4 numbers; each frame 12 (the assertion above), so
        // numbers 4g..4g+4 are in it.
        unsafe {
            let (a, b) = (_mm256_loadu_pd(a.as_ptr()), _mm256_loadu_pd(b.as_ptr()));
            let (c, d) = (_mm256_loadu_pd(c.as_ptr()), _mm256_loadu_pd(d.as_ptr()));
            // (a0 b0 a2 b2), (a1 b1 a3 b3), (c0 d0 c2 d2), (c1 d1 c3 d3).
            let (ab02, ab13) = (_mm256_unpacklo_pd(a, b), _mm256_unpackhi_pd(a, b));
            let (cd02, cd13) = (_mm256_unpacklo_pd(c, d), _mm256_unpackhi_pd(c, d));
            _mm256_storeu_pd(out[0].add(4 * g), _mm256_permute2f128_pd(ab02, cd02, 0x20));
            _mm256_storeu_pd(out[1].add(4 * g), _mm256_permute2f128_pd(ab13, cd13, 0x20));
            _mm256_storeu_pd(out[2].add(4 * g), _mm256_permute2f128_pd(ab02, cd02, 0x31));
            _mm256_storeu_pd(out[3].add(4 * g), _mm256_permute2f128_pd(ab13, cd13, 0x31));
        }
    }
}

impl Frames {
    #[inline(always)]
    fn splat(f: &Frame) -> Frames {
        Frames {
            rotation: std::array::from_fn(|i| std::array::from_fn(|j| [f.rotation[(i, j)]; BATCH])),
            translation: std::array::from_fn(|i| [f.translation[i]; BATCH]),
        }
    }

    /// Lane `k`'s frame.
    #[inline(always)]
    fn lane(&self, k: usize) -> Frame {
        let r = &self.rotation;
        let t = &self.translation;
        Frame {
            rotation: Matrix3::new(
                r[0][0][k], r[0][1][k], r[0][2][k], r[1][0][k], r[1][1][k], r[1][2][k], r[2][0][k],
                r[2][1][k], r[2][2][k],
            ),
            translation: Vector3::new(t[0][k], t[1][k], t[2][k]),
        }
    }

    /// [`Frame::then`] in every lane, `other` the same for all: the same products and sums in
    /// the same order.
    #[inline(always)]
    fn then(&self, other: &Frame) -> Frames {
        let a = &self.rotation;
        let b = &other.rotation;
        let t = &other.translation;
        let mut rotation = [[[0.0; BATCH]; 3]; 3];
        for (i, row) in rotation.iter_mut().enumerate() {
            for (j, entry) in row.iter_mut().enumerate() {
                *entry = lanes_add(
                    lanes_add(
                        lanes_scale(a[i][0], b[(0, j)]),
                        lanes_scale(a[i][1], b[(1, j)]),
                    ),
                    lanes_scale(a[i][2], b[(2, j)]),
                );
            }
        }
        let translation = std::array::from_fn(|i| {
            lanes_add(
                lanes_add(
                    lanes_add(self.translation[i], lanes_scale(a[i][0], t.x)),
                    lanes_scale(a[i][1], t.y),
                ),
                lanes_scale(a[i][2], t.z),
            )
        });
        Frames {
            rotation,
            translation,
        }
    }
}

impl Chain<'_> {
    /// [`Chain::forward_with`] at [`BATCH`] postures at once: `ws[k]` gets the frames of
    /// `readings[k]` (with `reading_trig[k]`, the rows of a [`ReadingTrig`] for them, when
    /// given), the same frames to the last bit as [`BATCH`] calls of [`Chain::forward_with`].
    /// A rigid serial chain computes them together, each matrix entry of the postures side by
    /// side in one vector (AVX2 when the processor has it, with the 32 vector registers of
    /// AVX-512 when it has those; elsewhere the same code, compiled for any processor, to the
    /// same bits); a tree or an elastic robot computes them one by one.
    pub fn forward_batch(
        &self,
        readings: [&[f64]; BATCH],
        reading_trig: Option<[&[(f64, f64)]; BATCH]>,
        ws: &mut [Workspace; BATCH],
    ) {
        let elastic = self.robot.elastic.is_some() && ws.iter().any(|w| w.elastic.is_some());
        if !self.serial || elastic {
            for (k, w) in ws.iter_mut().enumerate() {
                self.forward_with(readings[k], reading_trig.map(|t| t[k]), w);
            }
            return;
        }
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx512f")
            && std::arch::is_x86_feature_detected!("avx512vl")
        {
            // SAFETY: the processor has AVX-512 F and VL, checked just above (and so AVX2).
            unsafe { self.forward_serial_batch_avx512(readings, reading_trig, ws) };
            return;
        }
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the processor has AVX2, checked just above.
            unsafe { self.forward_serial_batch_avx2(readings, reading_trig, ws) };
            return;
        }
        self.forward_serial_batch(readings, reading_trig, ws, store_lanes);
    }

    /// [`Chain::forward_serial_batch`] compiled for AVX2: the lanes of a matrix entry are one
    /// 256-bit vector.
    ///
    /// # Safety
    ///
    /// The processor must have AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn forward_serial_batch_avx2(
        &self,
        readings: [&[f64]; BATCH],
        reading_trig: Option<[&[(f64, f64)]; BATCH]>,
        ws: &mut [Workspace; BATCH],
    ) {
        self.forward_serial_batch(readings, reading_trig, ws, |f, out| {
            // SAFETY: the processor has AVX2 (this function's contract).
            unsafe { store_lanes_avx2(f, out) }
        });
    }

    /// [`Chain::forward_serial_batch_avx2`] with AVX-512's 32 vector registers (the frame and
    /// the temporaries of a product fit without going through memory): 1.6 times as fast in
    /// `cargo bench -p kinecal --bench kinematics`. No fused multiply-add: Rust does not
    /// contract a product and a sum, so the lanes keep the scalar pass's rounding.
    ///
    /// # Safety
    ///
    /// The processor must have AVX-512 F and VL.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,avx512f,avx512vl")]
    unsafe fn forward_serial_batch_avx512(
        &self,
        readings: [&[f64]; BATCH],
        reading_trig: Option<[&[(f64, f64)]; BATCH]>,
        ws: &mut [Workspace; BATCH],
    ) {
        self.forward_serial_batch(readings, reading_trig, ws, |f, out| {
            // SAFETY: the processor has AVX2 (this function's contract).
            unsafe { store_lanes_avx2(f, out) }
        });
    }

    /// [`Chain::forward_serial`] at [`BATCH`] postures, lane `k` doing for posture `k` the
    /// same arithmetic in the same order (`tests::the_batched_pass_is_the_serial_one`); `store`
    /// writes each lane's frame to its posture's workspace.
    #[inline(always)]
    fn forward_serial_batch(
        &self,
        readings: [&[f64]; BATCH],
        reading_trig: Option<[&[(f64, f64)]; BATCH]>,
        ws: &mut [Workspace; BATCH],
        store: impl Fn(&Frames, [&mut Frame; BATCH]),
    ) {
        let n = self.joints.len();
        debug_assert!(self.serial);
        for (w, r) in ws.iter_mut().zip(readings) {
            debug_assert_eq!(r.len(), n);
            w.readings.copy_from_slice(r);
            w.after[0] = Frame::identity();
        }
        let mut current = Frames::splat(&Frame::identity().then(&self.links[0].frame));
        for (i, joint) in self.joints.iter().enumerate() {
            store(&current, ws.each_mut().map(|w| &mut w.dist[i]));
            // Joint::value of each posture, from the packed copy.
            let q = |k: usize| {
                let q = joint.offset + joint.slope * readings[k][i];
                match joint.coupling {
                    Some((c, factor)) => q + factor * readings[k][c],
                    None => q,
                }
            };
            if joint.revolute {
                let (s, c): (Lanes, Lanes) = match reading_trig {
                    Some(t) => {
                        let (so, co) = self.offset_trig[i];
                        let sb: Lanes = std::array::from_fn(|k| t[k][i].0);
                        let cb: Lanes = std::array::from_fn(|k| t[k][i].1);
                        (
                            lanes_add(lanes_scale(cb, so), lanes_scale(sb, co)),
                            lanes_sub(lanes_scale(cb, co), lanes_scale(sb, so)),
                        )
                    }
                    None => {
                        let sc: [(f64, f64); BATCH] = std::array::from_fn(|k| q(k).sin_cos());
                        (sc.map(|v| v.0), sc.map(|v| v.1))
                    }
                };
                for row in &mut current.rotation {
                    let (x, y) = (row[0], row[1]);
                    row[0] = lanes_add(lanes_mul(x, c), lanes_mul(y, s));
                    row[1] = lanes_sub(lanes_mul(y, c), lanes_mul(x, s));
                }
            } else {
                let q: Lanes = std::array::from_fn(q);
                for (t, row) in current.translation.iter_mut().zip(&current.rotation) {
                    *t = lanes_add(*t, lanes_mul(row[2], q));
                }
            }
            store(&current, ws.each_mut().map(|w| &mut w.after[i + 1]));
            current = current.then(&self.links[i + 1].frame);
        }
        store(&current, ws.each_mut().map(|w| &mut w.dist[n]));
    }
}

/// Writes one Jacobian column: `dp` in rows 0-2, `w` in rows 3-5.
#[inline]
fn put(out: &mut [f64], col: usize, dp: &Vector3<f64>, w: &Vector3<f64>) {
    let c = &mut out[6 * col..6 * col + 6];
    c[0] = dp.x;
    c[1] = dp.y;
    c[2] = dp.z;
    c[3] = w.x;
    c[4] = w.y;
    c[5] = w.z;
}

impl Chain<'_> {
    /// How a point `e` (global) moves per unit of joint `j`'s variable, and the frame's angular
    /// velocity: `(u x (e - o), u)` for a revolute joint of axis `u` through `o`, `(u, 0)` for a
    /// prismatic one (after [`Chain::forward`]).
    #[inline]
    fn joint_motion(
        &self,
        ws: &Workspace,
        j: usize,
        e: &Vector3<f64>,
    ) -> (Vector3<f64>, Vector3<f64>) {
        let f = &ws.dist[j];
        let u = f.rotation.column(2).into_owned();
        match self.robot.joints[j].kind {
            JointKind::Revolute => (u.cross(&(e - f.translation)), u),
            JointKind::Prismatic => (u, Vector3::zeros()),
        }
    }

    /// Writes the Jacobian of `target` (after [`Chain::forward`]) with respect to the
    /// transducer *readings* into `out`, a column-major 6 x `dof` block: column `i` holds
    /// `d(origin)/dV_i` in rows 0-2 and the global angular velocity per unit `V_i` in rows 3-5.
    /// A reading moves its own joint by `slope` and every joint coupled to it by the coupling
    /// factor. Joints downstream of a site's joint get zero columns for that site. Does not
    /// allocate.
    pub fn reading_jacobian(&self, ws: &Workspace, target: Target, out: &mut [f64]) {
        let robot = self.robot;
        let nj = robot.dof();
        assert_eq!(
            out.len(),
            6 * nj,
            "reading Jacobian block has the wrong size"
        );
        out.fill(0.0);
        let e = self.target_frame(ws, target).translation;
        let attach = target_joint(robot, target);
        let node = match target {
            Target::EndEffector => nj,
            Target::Site(_) => attach - 1,
        };
        // An elastic robot's joints past the target move it through the torques.
        let elastic = ws.elastic.is_some() && robot.elastic.is_some();
        for j in 0..nj {
            let upstream = robot.joint_moves(j, attach);
            if !(elastic || upstream) {
                continue;
            }
            let (dp, w) = if upstream {
                self.joint_motion(ws, j, &e)
            } else {
                (Vector3::zeros(), Vector3::zeros())
            };
            let twist = elastic.then(|| self.joint_twist(ws, j));
            // dq_j/dV_j = slope_j; dq_j/dV_k = factor for the reading it is coupled to.
            let joint = &robot.joints[j];
            let mut add = |col: usize, scale: f64| {
                let c = &mut out[6 * col..6 * col + 6];
                for k in 0..3 {
                    c[k] += dp[k] * scale;
                    c[3 + k] += w[k] * scale;
                }
                if let Some(t) = &twist {
                    let cause = elastic::Cause::Twist(t, scale);
                    self.elastic_column(ws, cause, &e, node, c);
                }
            };
            add(j, joint.slope);
            if let Some(c) = joint.coupling {
                add(c.joint, c.factor);
            }
        }
    }
}

/// The joint (1-based) right after which `target`'s frame hangs: the last joint for the end
/// effector (the tool link starts there), a site's own joint.
pub(crate) fn target_joint(robot: &Robot, target: Target) -> usize {
    match target {
        Target::EndEffector => robot.dof(),
        Target::Site(s) => robot.sites[s].joint,
    }
}

/// The pose of `target` for `robot` at `readings` (convenience; allocates).
pub fn forward_pose(robot: &Robot, readings: &[f64], target: Target) -> Pose {
    Chain::new(robot).frame_at(readings, target).pose()
}

/// Column of the Jacobian block for parameter `id` (for reading [`Chain::jacobian`] output).
pub fn block_column(block: &[f64], id: ParamId) -> &[f64] {
    &block[6 * id.0..6 * id.0 + 6]
}

/// The rotation vector (axis times angle, rad) of a rotation matrix, angle in `[0, pi]`.
///
/// Accurate for small angles (computed from the skew-symmetric part, not from `acos` of the
/// trace, which loses half the digits near the identity).
pub fn log_so3(r: &Matrix3<f64>) -> Vector3<f64> {
    let s = 0.5
        * Vector3::new(
            r[(2, 1)] - r[(1, 2)],
            r[(0, 2)] - r[(2, 0)],
            r[(1, 0)] - r[(0, 1)],
        );
    let c = 0.5 * (r.trace() - 1.0);
    let sn = s.norm();
    let theta = sn.atan2(c);
    if theta < 3.0 {
        if sn < 1e-300 {
            return Vector3::zeros();
        }
        // theta / sin(theta), with its series near 0.
        let k = if theta < 1e-4 {
            1.0 + theta * theta / 6.0
        } else {
            theta / sn
        };
        s * k
    } else {
        nalgebra::Rotation3::from_matrix_unchecked(*r).scaled_axis()
    }
}

/// Inverse of the right Jacobian of SO(3) at `phi`: maps a body-frame angular velocity to the
/// rate of the rotation vector `phi` of `E` when `dE = E [w]x`.
pub(crate) fn so3_right_jacobian_inverse(phi: &Vector3<f64>) -> Matrix3<f64> {
    let theta = phi.norm();
    let k = phi.cross_matrix();
    let coef = if theta < 1e-6 {
        1.0 / 12.0 + theta * theta / 720.0
    } else {
        1.0 / (theta * theta) - (1.0 + theta.cos()) / (2.0 * theta * theta.sin())
    };
    Matrix3::identity() + 0.5 * k + coef * k * k
}

#[cfg(test)]
mod tests;
