//! The elastic layer over the rigid chain: gravity torques, the static equilibrium and its
//! derivatives (a robot with a mass model, [`crate::model::robot::Elastic`]).
//!
//! Each revolute joint `i` has two deflections: a tilt `phi_i` about its lateral axis `l_i`
//! (fixed in the joint's frame, perpendicular to the joint axis), applied at the joint's origin
//! right after link `i`, then the turn `dq_i` added to the joint's angle. They answer the
//! gravity torques about the two axes through the joint's origin `o_i`, from every body distal
//! to the joint: with `S_i = sum_b m_b (c_b - o_i)` over those bodies (centres `c_b`, global)
//! and `g` the gravitational acceleration,
//!
//! ```text
//! tau_i = g . (a_i x S_i)        (a_i the joint axis, after the tilt)
//! lam_i = g . (w_i x S_i)        (w_i = R l_i the lateral axis, global)
//! dq_i  = k_i tau_i,   phi_i = k_lat_i lam_i
//! ```
//!
//! The deflections change the posture and so the torques: [`Chain::forward`] iterates
//! `delta <- K tau(delta)` from `delta = 0` until no deflection changes by more than
//! [`Elastic::TOLERANCE`] (or a fixed number of times, [`Elastic::iterations`]).
//!
//! Derivatives are those of the converged equilibrium (implicit function theorem): with `T` the
//! derivative of the torques by the deflections and `d` that of the torques by a parameter at
//! fixed deflections, the deflections move by `x = (I - K T)^-1 (K d + e_p tau_p)` (the last
//! term for the compliance `p` itself), and the target by the deflections' own motions times
//! `x`, added to the rigid column. Every parameter of the chain is a unit translation along, or
//! rotation about, a known axis at a known place of the chain, so `d` and `T` come from one
//! formula: a rotation `u` through `c` that moves a torque's axis and origin (it is proximal to
//! them) changes the torque by `g . (u x (v x S))`; one that does not moves only the bodies past
//! it, by `g . (v x (u x (MC - M c)))` with `M`, `MC` the mass and first moment of those bodies;
//! a translation `u` past the axis by `g . (v x u) M`, before it not at all.

use std::cell::RefCell;

use nalgebra::{Matrix3, Vector3};
use rand::{RngExt, SeedableRng};

use super::{Chain, Workspace};
use crate::model::robot::{Elastic, JointKind, Payload, Robot};

/// How the last equilibrium went ([`Workspace::equilibrium`]).
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct Equilibrium {
    /// Fixed-point iterations taken.
    pub iterations: usize,
    /// The largest change of a deflection in the last iteration (rad).
    pub change: f64,
    /// Whether the change fell below [`Elastic::TOLERANCE`]; with a fixed count
    /// ([`Elastic::iterations`]), whether the deflections are numbers.
    pub converged: bool,
    /// The largest deflection (rad).
    pub largest: f64,
}

/// A twist of the chain, for the torques' derivatives: a unit rotation about `u` through `c`, or
/// a unit translation along `u`, at chain position `at` (link `i`: `3i`; tilt of joint `i`:
/// `3i + 1`; turn of joint `i`: `3i + 2`). Everything past the position moves with it: in a
/// tree, the subtree of node `at / 3` (joint `i`'s node is `i`, the tool link's `n`).
#[derive(Debug, Clone, Copy)]
pub(super) enum Twist {
    Rotation {
        u: Vector3<f64>,
        c: Vector3<f64>,
        at: usize,
    },
    Translation {
        u: Vector3<f64>,
        at: usize,
    },
}

/// What moves the deflections, for [`Chain::elastic_column`].
#[derive(Debug, Clone, Copy)]
pub(super) enum Cause<'t> {
    /// The chain moving by a twist times a scale.
    Twist(&'t Twist, f64),
    /// The compliance of deflection `.0` (its own torque turns it).
    Compliance(usize),
    /// A component of body `.0`'s mass model (its mass, or a coordinate of its centre).
    Body(usize, crate::model::params::BodyComponent),
}

/// The elastic part of a [`Workspace`]: deflections, torques and their derivatives at the last
/// posture. Allocated once with the workspace.
#[derive(Debug, Clone)]
pub(super) struct ElasticState {
    /// `2n` deflections: `[2i]` the tilt of joint i, `[2i + 1]` its turn (rad).
    pub delta: Vec<f64>,
    /// Compliance of each deflection (0 for prismatic joints).
    k: Vec<f64>,
    /// Axis of each deflection (global; 0 for prismatic joints).
    axis: Vec<Vector3<f64>>,
    /// Origin of each joint (global).
    origin: Vec<Vector3<f64>>,
    /// `mass[i]`: total mass of the bodies past joint i, its whole subtree in a tree (`n + 1`
    /// entries, the last the payload's).
    mass: Vec<f64>,
    /// `moment[i]`: their first moment `sum m c` (global).
    moment: Vec<Vector3<f64>>,
    /// Gravity torque about each deflection's axis (N m).
    pub tau: Vec<f64>,
    /// Gravity of the last equilibrium (m/s^2, global).
    gravity: Vector3<f64>,
    /// The parent node of each node (joint `i`'s node is `i`, the tool link's `n`), `None` at
    /// the base.
    parent: Vec<Option<usize>>,
    /// `below[a * (n + 1) + b]`: node `b` is node `a` or in its subtree.
    below: Vec<bool>,
    /// The response and its scratch: worked out when a Jacobian first asks after a
    /// [`Chain::forward`] (residual-only passes do without it).
    scratch: RefCell<Scratch>,
    pub last: Equilibrium,
}

#[derive(Debug, Clone)]
struct Scratch {
    /// `(I - K T)^-1`, row-major `2n x 2n`, when `fresh`.
    response: Vec<f64>,
    /// Whether `response` is the current posture's.
    fresh: bool,
    matrix: Vec<f64>,
    rhs: Vec<f64>,
    x: Vec<f64>,
}

impl ElasticState {
    pub fn new(robot: &Robot) -> ElasticState {
        let n = robot.dof();
        let m = 2 * n;
        let parent: Vec<Option<usize>> = (0..=n)
            .map(|b| robot.link_parent(b).checked_sub(1))
            .collect();
        let mut below = vec![false; (n + 1) * (n + 1)];
        for b in 0..=n {
            let mut a = Some(b);
            while let Some(x) = a {
                below[x * (n + 1) + b] = true;
                a = parent[x];
            }
        }
        ElasticState {
            parent,
            below,
            delta: vec![0.0; m],
            k: vec![0.0; m],
            axis: vec![Vector3::zeros(); m],
            origin: vec![Vector3::zeros(); n],
            mass: vec![0.0; n + 1],
            moment: vec![Vector3::zeros(); n + 1],
            tau: vec![0.0; m],
            gravity: Vector3::zeros(),
            scratch: RefCell::new(Scratch {
                response: vec![0.0; m * m],
                fresh: false,
                matrix: vec![0.0; m * m],
                rhs: vec![0.0; m],
                x: vec![0.0; m],
            }),
            last: Equilibrium {
                iterations: 0,
                change: 0.0,
                converged: true,
                largest: 0.0,
            },
        }
    }

    /// Whether node `b` is node `a` or in its subtree.
    #[inline]
    fn below(&self, a: usize, b: usize) -> bool {
        self.below[a * self.mass.len() + b]
    }

    /// Whether chain position `at` is proximal to position `t` (on the path to it), or past it
    /// (in its subtree); neither for another branch.
    #[inline]
    fn relation(&self, at: usize, t: usize) -> Relation {
        let (a, b) = (at / 3, t / 3);
        if a == b {
            if at < t {
                Relation::Proximal
            } else {
                Relation::Past
            }
        } else if self.below(a, b) {
            Relation::Proximal
        } else if self.below(b, a) {
            Relation::Past
        } else {
            Relation::Apart
        }
    }

    /// Position in the chain of deflection `e`.
    #[inline]
    fn position(e: usize) -> usize {
        3 * (e / 2) + 1 + e % 2
    }

    /// `S_i = MC_i - M_i o_i` of joint `i`.
    #[inline]
    fn lever(&self, i: usize) -> Vector3<f64> {
        self.moment[i] - self.origin[i] * self.mass[i]
    }

    /// Fills axes, origins, body sums and torques from the frames of the last rigid pass.
    fn torques(
        &mut self,
        model: &Elastic,
        robot: &Robot,
        payload: Option<&Payload>,
        ws: &Workspace,
    ) {
        let n = robot.dof();
        self.mass.fill(0.0);
        self.moment.fill(Vector3::zeros());
        // The payload hangs off the end-effector frame: past every joint and the tool link
        // (chain position 3n), so it sits in the last entry.
        if let Some(p) = payload {
            let f = &ws.dist[n];
            self.mass[n] = p.mass;
            self.moment[n] = (f.translation + f.rotation * p.com) * p.mass;
        }
        for b in &model.bodies {
            let f = &ws.after[b.joint];
            let c = f.translation + f.rotation * b.com;
            self.mass[b.joint - 1] += b.mass;
            self.moment[b.joint - 1] += c * b.mass;
        }
        // Children before parents (a parent comes first), each into its parent.
        for b in (1..=n).rev() {
            if let Some(p) = self.parent[b] {
                self.mass[p] += self.mass[b];
                let next = self.moment[b];
                self.moment[p] += next;
            }
        }
        let g = model.gravity;
        for i in 0..n {
            let f = &ws.dist[i];
            self.origin[i] = f.translation;
            let revolute = robot.joints[i].kind == JointKind::Revolute;
            let (w, a) = if revolute {
                (
                    f.rotation * model.joints[i].lateral_axis,
                    f.rotation.column(2).into_owned(),
                )
            } else {
                (Vector3::zeros(), Vector3::zeros())
            };
            self.axis[2 * i] = w;
            self.axis[2 * i + 1] = a;
            let s = self.lever(i);
            self.tau[2 * i] = g.dot(&w.cross(&s));
            self.tau[2 * i + 1] = g.dot(&a.cross(&s));
            let j = &model.joints[i];
            self.k[2 * i] = if revolute { j.lateral } else { 0.0 };
            self.k[2 * i + 1] = if revolute { j.compliance } else { 0.0 };
        }
    }

    /// The change of deflection `e`'s torque per unit `twist`, at fixed deflections.
    #[inline]
    fn torque_rate(&self, g: &Vector3<f64>, e: usize, twist: &Twist) -> f64 {
        let v = &self.axis[e];
        let i = e / 2;
        let t = ElasticState::position(e);
        match *twist {
            Twist::Rotation { u, c, at } => match self.relation(at, t) {
                Relation::Proximal => g.dot(&u.cross(&v.cross(&self.lever(i)))),
                Relation::Past => {
                    let b = at / 3;
                    let moved = self.moment[b] - c * self.mass[b];
                    g.dot(&v.cross(&u.cross(&moved)))
                }
                Relation::Apart => 0.0,
            },
            Twist::Translation { u, at } => match self.relation(at, t) {
                Relation::Past => g.dot(&v.cross(&u)) * self.mass[at / 3],
                Relation::Proximal | Relation::Apart => 0.0,
            },
        }
    }

    /// The twist of deflection `f` (a rotation about its axis through its joint's origin).
    #[inline]
    fn twist(&self, f: usize) -> Twist {
        Twist::Rotation {
            u: self.axis[f],
            c: self.origin[f / 2],
            at: ElasticState::position(f),
        }
    }

    /// Computes `(I - K T)^-1` into `sc.response` (Gauss-Jordan with partial pivoting, no
    /// allocation). A singular matrix (an equilibrium at the point of buckling, which the
    /// fixed-point iteration does not converge to either) gives NaN, so that no Jacobian made
    /// from it passes for a number.
    fn respond(&self, sc: &mut Scratch) {
        let m = self.delta.len();
        let g = &self.gravity;
        let Scratch {
            response: inv,
            matrix: a,
            fresh,
            ..
        } = sc;
        *fresh = true;
        for e in 0..m {
            for f in 0..m {
                let t = if self.k[e] == 0.0 {
                    0.0
                } else {
                    self.k[e] * self.torque_rate(g, e, &self.twist(f))
                };
                a[e * m + f] = if e == f { 1.0 } else { 0.0 } - t;
            }
        }
        inv.fill(0.0);
        for e in 0..m {
            inv[e * m + e] = 1.0;
        }
        for col in 0..m {
            let pivot = (col..m)
                .max_by(|&x, &y| a[x * m + col].abs().total_cmp(&a[y * m + col].abs()))
                .expect("rows left");
            let p = a[pivot * m + col];
            if p.is_nan() || p.abs() < 1e-12 {
                inv.fill(f64::NAN);
                return;
            }
            if pivot != col {
                for f in 0..m {
                    a.swap(pivot * m + f, col * m + f);
                    inv.swap(pivot * m + f, col * m + f);
                }
            }
            for f in 0..m {
                a[col * m + f] /= p;
                inv[col * m + f] /= p;
            }
            for r in 0..m {
                if r == col {
                    continue;
                }
                let factor = a[r * m + col];
                if factor == 0.0 {
                    continue;
                }
                for f in 0..m {
                    a[r * m + f] -= factor * a[col * m + f];
                    inv[r * m + f] -= factor * inv[col * m + f];
                }
            }
        }
    }

    /// Adds to the 6-vector `out` the motion of point `e` caused by the deflections' response
    /// to `rates` (the torques' change, set by `fill`, plus `own` torque injected into deflection
    /// `own.0`), for the deflections of the joints on the path to node `target` (the target's
    /// frame hangs off it: the joint a site follows, `n` for the end effector).
    fn add_response(
        &self,
        e: &Vector3<f64>,
        target: usize,
        out: &mut [f64],
        fill: impl Fn(usize) -> f64,
        own: Option<(usize, f64)>,
    ) {
        let m = self.delta.len();
        let mut sc = self.scratch.borrow_mut();
        if !sc.fresh {
            self.respond(&mut sc);
        }
        let Scratch {
            rhs, x, response, ..
        } = &mut *sc;
        let mut any = false;
        for (r, (rhs, k)) in rhs.iter_mut().zip(&self.k).enumerate() {
            *rhs = if *k == 0.0 { 0.0 } else { k * fill(r) };
            any |= *rhs != 0.0;
        }
        if let Some((f, t)) = own {
            rhs[f] += t;
            any |= t != 0.0;
        }
        if !any {
            return;
        }
        for (f, x) in x.iter_mut().enumerate() {
            *x = response[f * m..(f + 1) * m]
                .iter()
                .zip(rhs.iter())
                .map(|(a, b)| a * b)
                .sum();
        }
        for (f, &xf) in x.iter().enumerate() {
            if xf == 0.0 || !self.below(f / 2, target) {
                continue;
            }
            let u = &self.axis[f];
            let dp = u.cross(&(e - self.origin[f / 2]));
            for k in 0..3 {
                out[k] += dp[k] * xf;
                out[3 + k] += u[k] * xf;
            }
        }
    }
}

/// Where one chain position lies from another.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Relation {
    /// On the path to it: moves it.
    Proximal,
    /// In its subtree: moved by it.
    Past,
    /// In another branch.
    Apart,
}

/// `R * Rot(l, phi)`: `r` turned by `phi` about its own local axis `l` (unit).
#[inline]
pub(super) fn turn_about_local(r: &Matrix3<f64>, l: &Vector3<f64>, phi: f64) -> Matrix3<f64> {
    if phi == 0.0 {
        return *r;
    }
    let (s, c) = phi.sin_cos();
    let k = l.cross_matrix();
    r * (Matrix3::identity() + k * s + k * k * (1.0 - c))
}

impl Chain<'_> {
    /// The equilibrium at `readings` (see the module docs), leaving the deflected frames in
    /// `ws` and the response for the Jacobian.
    pub(super) fn forward_elastic(
        &self,
        model: &Elastic,
        readings: &[f64],
        payload: Option<&Payload>,
        ws: &mut Workspace,
    ) {
        let mut st = ws.elastic.take().expect("an elastic workspace");
        st.delta.fill(0.0);
        let fixed = model.iterations;
        let limit = fixed.unwrap_or(Elastic::MAX_ITERATIONS);
        let mut change = 0.0;
        let mut iterations = 0;
        let mut converged = false;
        while iterations < limit {
            self.forward_rigid(readings, None, Some(&st.delta), ws);
            st.torques(model, self.robot, payload, ws);
            change = 0.0f64;
            for ((d, k), t) in st.delta.iter_mut().zip(&st.k).zip(&st.tau) {
                let new = k * t;
                // A parameter that is not a number makes the deflections NaN: not converged.
                let step = (new - *d).abs();
                change = if step.is_nan() {
                    f64::INFINITY
                } else {
                    change.max(step)
                };
                *d = new;
            }
            iterations += 1;
            if !change.is_finite() {
                break;
            }
            if fixed.is_none() && change < Elastic::TOLERANCE {
                converged = true;
                break;
            }
        }
        self.forward_rigid(readings, None, Some(&st.delta), ws);
        st.torques(model, self.robot, payload, ws);
        st.gravity = model.gravity;
        st.scratch.get_mut().fresh = false;
        st.last = Equilibrium {
            iterations,
            change,
            // A fixed count is what the model asks for, converged or not, but never NaN.
            converged: change.is_finite() && (converged || fixed.is_some()),
            largest: st.delta.iter().fold(0.0, |a: f64, d| {
                if a.is_nan() || d.is_nan() {
                    f64::NAN
                } else {
                    a.max(d.abs())
                }
            }),
        };
        ws.elastic = Some(st);
    }

    /// The twist of joint `j`'s variable (a rotation about its axis through its origin, or a
    /// translation along it), after [`Chain::forward`].
    pub(super) fn joint_twist(&self, ws: &Workspace, j: usize) -> Twist {
        let f = &ws.dist[j];
        let u = f.rotation.column(2).into_owned();
        match self.robot.joints[j].kind {
            JointKind::Revolute => Twist::Rotation {
                u,
                c: f.translation,
                at: 3 * j + 2,
            },
            JointKind::Prismatic => Twist::Translation { u, at: 3 * j + 2 },
        }
    }

    /// Adds to the Jacobian column `out` (6 entries) what the deflections add when the chain
    /// moves by `cause`, for point `e` of a target hanging off node `target` (the joint a site
    /// follows, 0-based; `n` for the end effector).
    pub(super) fn elastic_column(
        &self,
        ws: &Workspace,
        cause: Cause<'_>,
        e: &Vector3<f64>,
        target: usize,
        out: &mut [f64],
    ) {
        let (Some(model), Some(st)) = (&self.robot.elastic, ws.elastic.as_deref()) else {
            return;
        };
        let g = model.gravity;
        match cause {
            Cause::Twist(t, scale) => {
                st.add_response(e, target, out, |r| scale * st.torque_rate(&g, r, t), None)
            }
            Cause::Compliance(deflection) => st.add_response(
                e,
                target,
                out,
                |_| 0.0,
                Some((deflection, st.tau[deflection])),
            ),
            Cause::Body(body, component) => {
                use crate::model::params::BodyComponent;
                let b = &model.bodies[body];
                let frame = &ws.after[b.joint];
                let carried = b.joint - 1;
                // The body's force moves (mass) or its point of application (centre).
                let lever_rate = |r: usize| -> Vector3<f64> {
                    match component {
                        BodyComponent::Mass => {
                            frame.translation + frame.rotation * b.com - st.origin[r / 2]
                        }
                        BodyComponent::X => frame.rotation.column(0) * b.mass,
                        BodyComponent::Y => frame.rotation.column(1) * b.mass,
                        BodyComponent::Z => frame.rotation.column(2) * b.mass,
                    }
                };
                st.add_response(
                    e,
                    target,
                    out,
                    |r| {
                        if st.below(r / 2, carried) {
                            g.dot(&st.axis[r].cross(&lever_rate(r)))
                        } else {
                            0.0
                        }
                    },
                    None,
                )
            }
        }
    }
}

/// The compliant joints whose gravity torque is always zero, so that their compliance cannot
/// be estimated (a vertical first axis: its torque is 0 in every posture): those with no torque
/// above 1e-3 of the robot's largest in 256 postures drawn uniformly over the joint ranges
/// (`[-pi, pi]` or `[-1, 1]` m for a joint without a range; seed fixed), at zero compliance. The
/// threshold counts an axis within about 0.06 deg of vertical as vertical: a calibrated base
/// tilts by a fraction of that, and the torque it leaves cannot determine a compliance.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct GravityFree {
    /// Joints (0-based) without a torque about their axis.
    pub joint: Vec<usize>,
    /// Joints (0-based) without a torque about their lateral axis.
    pub lateral: Vec<usize>,
}

/// See [`GravityFree`]; empty for a rigid robot.
pub fn gravity_free_joints(robot: &Robot) -> GravityFree {
    if robot.elastic.is_none() {
        return GravityFree::default();
    }
    let mut rigid = robot.clone();
    if let Some(e) = rigid.elastic.as_mut() {
        for j in &mut e.joints {
            j.compliance = 0.0;
            j.lateral = 0.0;
        }
    }
    let chain = Chain::new(&rigid);
    let mut ws = Workspace::new(&rigid);
    let n = robot.dof();
    let mut largest = vec![0.0f64; 2 * n];
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0x6772_6176);
    let mut readings = vec![0.0; n];
    for _ in 0..256 {
        for (v, j) in readings.iter_mut().zip(&robot.joints) {
            let (lo, hi) = j.range.unwrap_or(match j.kind {
                JointKind::Revolute => {
                    let turn = std::f64::consts::PI / j.slope.abs().max(1e-12);
                    (-turn, turn)
                }
                JointKind::Prismatic => {
                    let metre = 1.0 / j.slope.abs().max(1e-12);
                    (-metre, metre)
                }
            });
            *v = rng.random_range(lo..=hi);
        }
        chain.forward(&readings, &mut ws);
        let st = ws.elastic.as_deref().expect("elastic workspace");
        for (l, t) in largest.iter_mut().zip(&st.tau) {
            *l = l.max(t.abs());
        }
    }
    let top = largest.iter().fold(0.0f64, |a, b| a.max(*b));
    // No body at all (a payload the only load): nothing to tell apart.
    let free = |r: usize| top > 0.0 && largest[r] <= 1e-3 * top;
    GravityFree {
        joint: robot
            .compliant_joints()
            .filter(|&j| free(2 * j + 1))
            .collect(),
        lateral: robot.compliant_joints().filter(|&j| free(2 * j)).collect(),
    }
}

/// The first of `postures` (readings, and the payload when there is one) at which `robot`'s
/// gravity equilibrium does not converge, with how it went; `None` when it converges at all of
/// them, or for a rigid robot. Front ends refuse such a posture rather than report deflections
/// that mean nothing.
pub(crate) fn unconverged_posture<'a>(
    robot: &Robot,
    postures: impl IntoIterator<Item = (&'a [f64], Option<&'a Payload>)>,
) -> Option<(usize, Equilibrium)> {
    robot.elastic.as_ref()?;
    let chain = Chain::new(robot);
    let mut ws = Workspace::new(robot);
    postures
        .into_iter()
        .enumerate()
        .find_map(|(i, (readings, payload))| {
            chain.forward_loaded(readings, None, payload, &mut ws);
            ws.equilibrium().filter(|e| !e.converged).map(|e| (i, e))
        })
}

impl std::fmt::Display for Equilibrium {
    /// `did not converge: the deflections still changed by 3.2e-2 rad after 200 iterations
    /// (largest 1.7 rad)`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.converged {
            write!(f, "converged in {} iterations", self.iterations)
        } else {
            write!(
                f,
                "did not converge: the deflections still changed by {:.1e} rad after {} \
                 iterations (largest {:.3} rad); the compliances are implausibly large, or the \
                 robot would buckle",
                self.change, self.iterations, self.largest
            )
        }
    }
}
