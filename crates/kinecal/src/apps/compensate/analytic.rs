//! Closed-form inverse kinematics of the nominal robot: the starts of the search for Cartesian
//! pose targets on arms whose nominal geometry has one.
//!
//! Two families of arms of six revolute joints are told from the nominal model's joint axes at
//! the *reference posture* (every reading 0), whatever parameters the robot file writes them
//! with:
//!
//! - **spherical wrist** (Pieper): axes 4, 5 and 6 meet in one point, the wrist centre; axes 2
//!   and 3 are parallel and axis 1 is not parallel to them (ABB, KUKA, FANUC, Yaskawa arms;
//!   shoulder and elbow offsets allowed);
//! - **UR-type** (Hawkins' closed form of the Universal Robots arms): axes 2, 3 and 4 are
//!   parallel, axis 1 is not parallel to them, axes 5 and 6 meet, and axis 5 is parallel
//!   neither to axis 4 nor to axis 6.
//!
//! Any other arm of six revolute joints gets the general form (the `general` module: every
//! solution, up to 16, from a polynomial in joint 3's turn), [`Family::General`].
//!
//! Axes are parallel, or meet, to a millionth (of a radian; of the reach). The target frame
//! must hang off joint 6 (the end effector, or a site of the last link). Joints may have any
//! offset and slope, but no coupling.
//!
//! The forward kinematics as a product of exponentials, `F(V) = e_1(t_1) ... e_6(t_6) M`:
//! `e_i(t)` is the rotation by `t` about joint `i`'s axis as it lies at the reference posture,
//! `M` the target frame there, and `t_i = slope_i V_i` the joint's turn from it (rad). With
//! `D = G M^-1` for a goal `G`, the turns come from the Paden-Kahan subproblems in three
//! two-way choices, eight *branches*:
//!
//! - spherical wrist: the wrist centre `c` is fixed by joints 4 to 6, so `D c = e_1 e_2 e_3 c`.
//!   Turns about axes 2 and 3 keep a point's component along their direction `w_2`: `t_1`
//!   brings `D c` to the plane `w_2 . x = w_2 . c` (two solutions: the shoulder); then `t_3`
//!   gives `c` its distance to axis 2 (two: the elbow), `t_2` turns it onto the goal, and the
//!   wrist's rotation `R_4 R_5 R_6` is that of `(e_1 e_2 e_3)^-1 D`: `t_5` from the component of
//!   `R w_6` along `w_4` (two: the wrist flip), then `t_4` and `t_6`.
//! - UR-type: the point `c` where axes 5 and 6 meet gives `t_1` as above (with axes 2, 3 and 4
//!   parallel). A rotation about `w_2` leaves `w_2` as it is, so `w_2 . R_5 w_6 = w_2 . R_1^T
//!   R_D w_6` gives `t_5` (two), `R_6 (R_D^T R_1 w_2) = R_5^T w_2` gives `t_6`; then `e_2 e_3
//!   e_4 = e_1^-1 D (e_5 e_6)^-1` is a planar arm: `t_3` from a point of axis 4's distance to
//!   axis 2 (two), `t_2`, and `t_4` from what rotation is left.
//!
//! A subproblem without a real solution (a goal out of the nominal robot's reach, or at a
//! singularity) takes its nearest, and marks the branch inexact: still a start for the damped
//! least squares on the calibrated model.

use nalgebra::{Matrix3, Vector3};

use super::configuration::wrap_pi;
use crate::model::kinematics::{target_joint, Chain, Frame, Target, Workspace};
use crate::model::robot::{JointKind, Robot};

/// The family of a nominal robot with a closed-form inverse kinematics.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Family {
    /// Axes 4, 5 and 6 meet; axes 2 and 3 are parallel.
    SphericalWrist,
    /// Axes 2, 3 and 4 are parallel; axes 5 and 6 meet.
    UrType,
    /// Any other arm of six revolute joints (see the `general` module): up to 16 solutions.
    General,
}

/// Most solutions a goal has (a general arm's; the families have eight).
pub(crate) const MOST: usize = 16;

/// The solutions of one goal, `len` of them.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Branches {
    list: [Branch; MOST],
    len: usize,
    complete: bool,
}

impl Branches {
    fn new() -> Self {
        Branches {
            list: [Branch {
                readings: [0.0; 6],
                exact: false,
            }; MOST],
            len: 0,
            complete: true,
        }
    }

    fn push(&mut self, b: Branch) {
        self.list[self.len] = b;
        self.len += 1;
    }

    /// The solutions.
    pub(crate) fn as_slice(&self) -> &[Branch] {
        &self.list[..self.len]
    }

    /// Whether the exact branches are every solution the nominal robot has: always for the
    /// families' eight; for the general form, when it can tell (see `general::Solutions`).
    pub(crate) fn complete(&self) -> bool {
        self.complete
    }
}

/// One of the solutions: readings (robot file's units), and whether every subproblem on
/// the way had a real solution (else the nearest was taken: a start, not a solution); for the
/// general form, whether the turns reach the goal to 1e-9 (of the reach; rad).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Branch {
    /// Readings of joints 1 to 6, each joint's turn from the reference posture in `(-pi, pi]`
    /// divided by its slope.
    pub(crate) readings: [f64; 6],
    /// Whether the branch solves the goal exactly on the nominal model.
    pub(crate) exact: bool,
}

/// The closed-form inverse kinematics of one nominal robot and target frame.
#[derive(Debug, Clone)]
pub(crate) struct Analytic {
    family: Family,
    /// Joint axes' unit directions at the reference posture (global frame).
    w: [Vector3<f64>; 6],
    /// A point of each joint axis at the reference posture (m).
    r: [Vector3<f64>; 6],
    /// The target frame at the reference posture, inverted: `M^-1`.
    home_inv: Frame,
    /// The wrist centre (spherical wrist) or where axes 5 and 6 meet (UR-type), at the
    /// reference posture (m).
    centre: Vector3<f64>,
    /// Each joint's slope: radians of turn per reading unit.
    slope: [f64; 6],
    /// The general closed form ([`Family::General`] only).
    general: Option<Box<super::general::General>>,
    /// Whether the robot has an elastic model: its sag may bring solutions the rigid
    /// geometry misses (see `general::General::solve`).
    sag: bool,
}

impl Analytic {
    /// The closed form of `nominal` for `target`, when the robot is of a [`Family`] (see the
    /// module's documentation); `None` otherwise.
    pub(crate) fn new(nominal: &Robot, target: Target) -> Option<Analytic> {
        if nominal.dof() != 6
            || nominal.is_tree()
            || target_joint(nominal, target) != 6
            || nominal.joints.iter().any(|j| {
                j.kind != JointKind::Revolute
                    || j.coupling.is_some()
                    || j.slope == 0.0
                    || !j.slope.is_finite()
            })
        {
            return None;
        }
        // The rigid geometry: a mass model's sag is the calibrated model's to refine.
        let mut rigid = nominal.clone();
        rigid.elastic = None;
        let chain = Chain::new(&rigid);
        let mut ws = Workspace::new(&rigid);
        chain.forward(&[0.0; 6], &mut ws);
        let w: [Vector3<f64>; 6] =
            std::array::from_fn(|i| ws.after_joint(i + 1).rotation.column(2).into_owned());
        let r: [Vector3<f64>; 6] = std::array::from_fn(|i| ws.after_joint(i + 1).translation);
        let home = chain.target_frame(&ws, target);
        let length = 1e-6 * rigid.reach();
        let parallel = |a: usize, b: usize| w[a].cross(&w[b]).norm() < 1e-6;
        // Where axes a and b meet, when they do (and are not parallel).
        let meet = |a: usize, b: usize| -> Option<Vector3<f64>> {
            if parallel(a, b) {
                return None;
            }
            let (pa, pb) = closest_points(&r[a], &w[a], &r[b], &w[b]);
            ((pa - pb).norm() < length).then_some(0.5 * (pa + pb))
        };
        let on_axis = |p: &Vector3<f64>, a: usize| {
            let d = p - r[a];
            (d - w[a] * w[a].dot(&d)).norm() < length
        };
        let shoulder = !parallel(0, 1) && parallel(1, 2);
        let (family, centre) = if let Some(c) =
            meet(3, 4).filter(|c| shoulder && on_axis(c, 5) && !parallel(4, 5))
        {
            (Family::SphericalWrist, c)
        } else if let Some(c) = meet(4, 5).filter(|_| shoulder && parallel(1, 3) && !parallel(3, 4))
        {
            (Family::UrType, c)
        } else {
            (Family::General, r[5])
        };
        let general = match family {
            Family::General => Some(Box::new(super::general::General::new(
                &w,
                &r,
                rigid.reach(),
            )?)),
            _ => None,
        };
        Some(Analytic {
            family,
            w,
            r,
            home_inv: inverse(&home),
            centre,
            slope: std::array::from_fn(|i| rigid.joints[i].slope),
            general,
            sag: nominal.elastic.is_some(),
        })
    }

    /// The family told from the nominal geometry.
    pub(crate) fn family(&self) -> Family {
        self.family
    }

    /// The general closed form and the motion it solves for `goal` (tests look at its roots).
    #[cfg(test)]
    pub(crate) fn general_motion(&self, goal: &Frame) -> Option<(&super::general::General, Frame)> {
        Some((self.general.as_deref()?, goal.then(&self.home_inv)))
    }

    /// The eight branches for the goal frame `goal` (global frame, m), some inexact when the
    /// goal is out of the nominal robot's reach; the same solution may come more than once at a
    /// singularity.
    pub(crate) fn solve(&self, goal: &Frame) -> Branches {
        let d = goal.then(&self.home_inv);
        let mut branches = Branches::new();
        if let Some(g) = &self.general {
            let mut turns = [([0.0; 6], false); MOST];
            let found = g.solve(&d.rotation, &d.translation, self.sag, &mut turns);
            for &(t, exact) in &turns[..found.count] {
                branches.push(self.branch(t, exact));
            }
            branches.complete = found.complete;
            return branches;
        }
        let mut out = [Branch {
            readings: [0.0; 6],
            exact: false,
        }; 8];
        let (w, r) = (&self.w, &self.r);
        // t_1: D c onto the plane w_2 . x = w_2 . c (a turn by -t_1 about axis 1).
        let pc = apply(&d, &self.centre);
        let (minus_t1, exact1) = plane_angles(&w[0], &r[0], &pc, &w[1], w[1].dot(&self.centre));
        let mut k = 0;
        for &mt1 in &minus_t1 {
            let t1 = -mt1;
            let e1_inv = screw(&w[0], &r[0], mt1);
            match self.family {
                Family::SphericalWrist => {
                    let p = apply(&e1_inv, &pc);
                    for (t2, t3, exact3) in self.planar(&p, &self.centre) {
                        let r123 = rot(&w[0], t1) * rot(&w[1], t2) * rot(&w[2], t3);
                        let rw = r123.transpose() * d.rotation;
                        let wrist = self.wrist(&rw);
                        for (t4, t5, t6, exact5) in wrist {
                            out[k] =
                                self.branch([t1, t2, t3, t4, t5, t6], exact1 && exact3 && exact5);
                            k += 1;
                        }
                    }
                }
                Family::UrType => {
                    let r1 = rot(&w[0], t1);
                    let zero = Vector3::zeros();
                    // w_2 . R_5 w_6 = w_2 . R_1^T R_D w_6.
                    let (t5s, exact5) = plane_angles(
                        &w[4],
                        &zero,
                        &w[5],
                        &w[1],
                        w[1].dot(&(r1.transpose() * d.rotation * w[5])),
                    );
                    for &t5 in &t5s {
                        // R_6 (R_D^T R_1 w_2) = R_5^T w_2.
                        let u = rot(&w[4], t5).transpose() * w[1];
                        let v = d.rotation.transpose() * r1 * w[1];
                        let t6 = rotate_to(&w[5], &v, &u);
                        // e_2 e_3 e_4 = e_1^-1 D e_6^-1 e_5^-1.
                        let h = e1_inv
                            .then(&d)
                            .then(&screw(&w[5], &r[5], -t6))
                            .then(&screw(&w[4], &r[4], -t5));
                        let p = apply(&h, &r[3]);
                        for (t2, t3, exact3) in self.planar(&p, &r[3]) {
                            let r23 = rot(&w[1], t2) * rot(&w[2], t3);
                            let x = perpendicular(&w[3]);
                            let t4 = rotate_to(&w[3], &x, &(r23.transpose() * h.rotation * x));
                            out[k] =
                                self.branch([t1, t2, t3, t4, t5, t6], exact1 && exact3 && exact5);
                            k += 1;
                        }
                    }
                }
                Family::General => unreachable!("solved above"),
            }
        }
        for b in out {
            branches.push(b);
        }
        branches
    }

    /// The planar part: turns `(t_2, t_3)` of the parallel axes 2 and 3 that bring point `x`
    /// (reference posture) to `p`, which lies at `x`'s height along `w_2`; both elbows, and
    /// whether the distance was reachable.
    fn planar(&self, p: &Vector3<f64>, x: &Vector3<f64>) -> [(f64, f64, bool); 2] {
        let (w, r) = (&self.w, &self.r);
        let flat = |v: Vector3<f64>| v - w[1] * w[1].dot(&v);
        let delta2 = flat(p - r[1]).norm_squared();
        // |c + R_3 u|^2 = delta^2 in the plane perpendicular to the axes.
        let c = flat(r[2] - r[1]);
        let u = flat(x - r[2]);
        let a = 2.0 * c.dot(&u);
        let b = 2.0 * c.dot(&w[2].cross(&u));
        let (t3s, exact) = cos_sin_eq(a, b, delta2 - c.norm_squared() - u.norm_squared());
        t3s.map(|t3| {
            let moved = apply(&screw(&w[2], &r[2], t3), x);
            (rotate_to(&w[1], &(moved - r[1]), &(p - r[1])), t3, exact)
        })
    }

    /// The spherical wrist: turns `(t_4, t_5, t_6, exact)` with `R_4 R_5 R_6 = rw`, both flips.
    fn wrist(&self, rw: &Matrix3<f64>) -> [(f64, f64, f64, bool); 2] {
        let w = &self.w;
        let goal6 = rw * w[5];
        let (t5s, exact) = plane_angles(&w[4], &Vector3::zeros(), &w[5], &w[3], w[3].dot(&goal6));
        t5s.map(|t5| {
            let t4 = rotate_to(&w[3], &(rot(&w[4], t5) * w[5]), &goal6);
            let r45 = rot(&w[3], t4) * rot(&w[4], t5);
            let x = perpendicular(&w[5]);
            let t6 = rotate_to(&w[5], &x, &(r45.transpose() * rw * x));
            (t4, t5, t6, exact)
        })
    }

    fn branch(&self, turns: [f64; 6], exact: bool) -> Branch {
        Branch {
            readings: std::array::from_fn(|i| wrap_pi(turns[i]) / self.slope[i]),
            exact,
        }
    }
}

/// Rotation by `t` (rad) about the unit axis `w` (Rodrigues).
fn rot(w: &Vector3<f64>, t: f64) -> Matrix3<f64> {
    let (s, c) = t.sin_cos();
    let k = Matrix3::new(0.0, -w.z, w.y, w.z, 0.0, -w.x, -w.y, w.x, 0.0);
    Matrix3::identity() + k * s + k * k * (1.0 - c)
}

/// The rigid motion turning by `t` about the line through `r` along the unit `w`.
fn screw(w: &Vector3<f64>, r: &Vector3<f64>, t: f64) -> Frame {
    let rotation = rot(w, t);
    Frame {
        rotation,
        translation: r - rotation * r,
    }
}

fn inverse(f: &Frame) -> Frame {
    let rt = f.rotation.transpose();
    Frame {
        rotation: rt,
        translation: -(rt * f.translation),
    }
}

fn apply(f: &Frame, p: &Vector3<f64>) -> Vector3<f64> {
    f.rotation * p + f.translation
}

/// A unit vector perpendicular to the unit `w`.
fn perpendicular(w: &Vector3<f64>) -> Vector3<f64> {
    let e = if w.x.abs() < 0.6 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    w.cross(&e).normalize()
}

/// The points of two lines (point, unit direction; not parallel) nearest each other.
fn closest_points(
    pa: &Vector3<f64>,
    wa: &Vector3<f64>,
    pb: &Vector3<f64>,
    wb: &Vector3<f64>,
) -> (Vector3<f64>, Vector3<f64>) {
    let d = pb - pa;
    let b = wa.dot(wb);
    let den = 1.0 - b * b;
    let s = (wa.dot(&d) - b * wb.dot(&d)) / den;
    let t = (b * wa.dot(&d) - wb.dot(&d)) / den;
    (pa + wa * s, pb + wb * t)
}

/// The angle about the unit `w` that turns `u`'s part perpendicular to `w` onto `v`'s
/// (subproblem 1); 0 when either part vanishes.
fn rotate_to(w: &Vector3<f64>, u: &Vector3<f64>, v: &Vector3<f64>) -> f64 {
    let up = u - w * w.dot(u);
    let vp = v - w * w.dot(v);
    w.dot(&up.cross(&vp)).atan2(up.dot(&vp))
}

/// The two `t` with `a cos t + b sin t = c`, and whether they are real (else the `t` nearest
/// to it, twice).
fn cos_sin_eq(a: f64, b: f64, c: f64) -> ([f64; 2], bool) {
    let h = a.hypot(b);
    if h < 1e-300 {
        return ([0.0, std::f64::consts::PI], false);
    }
    let phi = b.atan2(a);
    let x = c / h;
    let exact = x.abs() <= 1.0;
    let d = x.clamp(-1.0, 1.0).acos();
    ([phi + d, phi - d], exact)
}

/// The turns `t` about the line through `r` along the unit `w` that bring point `p` to the plane
/// `n . x = level`: `n . (r + R(t) (p - r)) = level`.
fn plane_angles(
    w: &Vector3<f64>,
    r: &Vector3<f64>,
    p: &Vector3<f64>,
    n: &Vector3<f64>,
    level: f64,
) -> ([f64; 2], bool) {
    let u = p - r;
    let along = w * w.dot(&u);
    let across = u - along;
    cos_sin_eq(
        n.dot(&across),
        n.dot(&w.cross(&across)),
        level - n.dot(r) - n.dot(&along),
    )
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::import::dh::{robot_from_dh, Convention, DhRow};
    use crate::model::kinematics::log_so3;
    use rand::{RngExt, SeedableRng};
    use std::f64::consts::FRAC_PI_2;

    /// A random arm of `family` (standard DH with the family's twists and zero lengths, the
    /// others drawn; random joint offsets, slopes of either sign, a tool off joint 6's axis).
    pub(crate) fn random_arm(family: Family, seed: u64) -> Robot {
        let mut g = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let mut len = |lo: f64, hi: f64| g.random_range(lo..hi);
        let sign = |x: f64| if x < 0.5 { -1.0 } else { 1.0 };
        let s: Vec<f64> = (0..6)
            .map(|k| sign(((seed * 7 + k) % 11) as f64 / 11.0))
            .collect();
        let rows: Vec<(f64, f64, f64)> = match family {
            Family::SphericalWrist => vec![
                (len(-0.2, 0.3), s[0] * FRAC_PI_2, len(0.2, 0.6)),
                (len(0.3, 0.9), 0.0, len(-0.1, 0.1)),
                (len(-0.2, 0.2), s[2] * FRAC_PI_2, len(-0.1, 0.1)),
                (0.0, s[3] * FRAC_PI_2, len(0.3, 0.9)),
                (0.0, s[4] * FRAC_PI_2, 0.0),
                (len(-0.05, 0.05), len(-1.0, 1.0), len(0.05, 0.2)),
            ],
            Family::UrType => vec![
                (len(-0.1, 0.1), s[0] * FRAC_PI_2, len(0.1, 0.2)),
                (len(-0.7, -0.3), 0.0, len(-0.1, 0.1)),
                (len(-0.6, -0.3), 0.0, len(-0.1, 0.1)),
                (0.0, s[3] * FRAC_PI_2, len(0.1, 0.2)),
                (0.0, s[4] * FRAC_PI_2, len(0.08, 0.15)),
                (len(-0.05, 0.05), len(-1.0, 1.0), len(0.05, 0.2)),
            ],
            Family::General => (0..6)
                .map(|_| (len(-0.5, 0.5), len(-3.0, 3.0), len(-0.5, 0.5)))
                .collect(),
        };
        let mut g = rand_chacha::ChaCha8Rng::seed_from_u64(seed + 1000);
        let dh: Vec<DhRow> = rows
            .iter()
            .map(|&(a, alpha, d)| {
                DhRow::new(JointKind::Revolute, a, alpha, d, g.random_range(-3.0..3.0))
            })
            .collect();
        let mut robot = robot_from_dh(
            "family",
            crate::units::Units::default(),
            &dh,
            Convention::Standard,
        );
        for j in &mut robot.joints {
            j.offset += g.random_range(-1.0..1.0);
            j.slope = sign(g.random_range(0.0..1.0)) * g.random_range(0.5..2.0);
        }
        robot
    }

    /// Readings that turn each joint by up to 3.1 rad either way.
    pub(crate) fn random_readings(robot: &Robot, g: &mut impl rand::Rng) -> Vec<f64> {
        robot
            .joints
            .iter()
            .map(|j| g.random_range(-3.1..3.1) / j.slope.abs())
            .collect()
    }

    fn frame(robot: &Robot, readings: &[f64]) -> Frame {
        Chain::new(robot).frame_at(readings, Target::EndEffector)
    }

    /// Every exact branch reaches the goal to 1e-10 (m and rad), the posture the goal came
    /// from is among them (whole turns aside), and generic postures have all eight exact.
    fn round_trip(family: Family) {
        let mut all_eight = 0;
        for seed in 0..20 {
            let robot = random_arm(family, seed);
            let a = Analytic::new(&robot, Target::EndEffector).expect("in the family");
            assert_eq!(a.family(), family, "seed {seed}");
            let mut g = rand_chacha::ChaCha8Rng::seed_from_u64(seed + 99);
            for _ in 0..50 {
                let v = random_readings(&robot, &mut g);
                let goal = frame(&robot, &v);
                let branches = a.solve(&goal);
                let mut found = false;
                let mut exact = 0;
                for b in branches.as_slice().iter().filter(|b| b.exact) {
                    exact += 1;
                    let f = frame(&robot, &b.readings);
                    let dp = (f.translation - goal.translation).norm();
                    let da = log_so3(&(f.rotation * goal.rotation.transpose())).norm();
                    assert!(
                        dp < 1e-10 && da < 1e-10,
                        "{family:?} seed {seed}: {dp} m, {da} rad"
                    );
                    found |= b
                        .readings
                        .iter()
                        .zip(&v)
                        .zip(&robot.joints)
                        .all(|((x, y), j)| wrap_pi((x - y) * j.slope).abs() < 1e-7);
                }
                assert!(
                    found,
                    "{family:?} seed {seed}: the posture itself is not a branch"
                );
                all_eight += (exact == 8) as usize;
            }
        }
        assert!(
            all_eight > 100,
            "{family:?}: {all_eight} of 1000 goals with 8 branches"
        );
    }

    #[test]
    fn spherical_wrist_branches_reach_their_goals() {
        round_trip(Family::SphericalWrist);
    }

    #[test]
    fn ur_type_branches_reach_their_goals() {
        round_trip(Family::UrType);
    }

    #[test]
    fn arms_outside_the_families_have_the_general_form_or_none() {
        // A random arm of six joints with a prismatic one, the UR's twists with joint 5's axis
        // moved off joint 6's (the general form), a robot of 5 joints, a coupled wrist, and a
        // site on link 3.
        use JointKind::{Prismatic, Revolute};
        let kinds = [Revolute, Revolute, Prismatic, Revolute, Revolute, Revolute];
        let random = crate::apps::simulate::random_robot(&kinds, 21);
        assert!(Analytic::new(&random, Target::EndEffector).is_none());
        let ur = random_arm(Family::UrType, 3);
        assert_eq!(
            Analytic::new(&ur, Target::EndEffector).map(|a| a.family()),
            Some(Family::UrType)
        );
        let mut off = ur.clone();
        off.links[5].x += 0.01;
        assert_eq!(
            Analytic::new(&off, Target::EndEffector).map(|a| a.family()),
            Some(Family::General)
        );
        let five = crate::apps::simulate::random_robot(&[JointKind::Revolute; 5], 2);
        assert!(Analytic::new(&five, Target::EndEffector).is_none());
        let mut coupled = random_arm(Family::SphericalWrist, 4);
        assert!(Analytic::new(&coupled, Target::EndEffector).is_some());
        coupled.joints[5].coupling = Some(crate::model::robot::Coupling {
            joint: 4,
            factor: 0.5,
        });
        assert!(Analytic::new(&coupled, Target::EndEffector).is_none());
        let mut sited = ur.clone();
        sited.sites.push(crate::model::robot::Site {
            name: "elbow".into(),
            joint: 3,
            frame: sited.links[0],
        });
        assert!(Analytic::new(&sited, Target::Site(0)).is_none());
    }

    #[test]
    fn the_examples_arms_are_told() {
        let irb = crate::model::robot_file::parse_robot_toml(
            include_str!("../../../../../examples/robots/abb_irb120.toml"),
            "abb_irb120.toml",
        )
        .unwrap();
        let a = Analytic::new(&irb, Target::EndEffector).expect("IRB 120");
        assert_eq!(a.family(), Family::SphericalWrist);
        let ge = crate::model::examples::ge_a4();
        assert!(Analytic::new(&ge, Target::EndEffector).is_none());
    }
}
