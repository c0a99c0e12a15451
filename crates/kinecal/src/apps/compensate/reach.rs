//! A proof that a pose goal lies out of a six-revolute arm's reach, from its geometry alone: the
//! search for a solution ([`super::TargetSearch`]) need not try its starts on such a goal.
//!
//! Every distance below is between two points fixed in one link, so it is the same in every
//! posture (worked out once, at the reference posture, from the calibrated model's joint axes):
//!
//! - the *wrist point* `c`: the point of axis 4 nearest axis 5 (fixed in links 3 and 4). It
//!   lies `r_5` from its foot `p_5` on axis 5, and `p_5` lies `r_6` from its foot `p_6` on axis
//!   6; `p_6` is fixed in link 6, so for a pose goal `G` it lies at `G M^-1 p_6` (`M` the target
//!   frame at the reference posture), and `c` within `r_5 + r_6` of it, however joints 4 to 6
//!   turn. On a spherical wrist (axes 4 to 6 meeting) `r_5 = r_6 = 0`: `c` is the wrist centre.
//! - from the base: `c` lies `R_3` from its foot `f_3` on axis 3, `f_3` lies `R_2` from its foot
//!   `f_2` on axis 2, so `|c - f_2|` is between `|R_2 - R_3|` and `R_2 + R_3` (the triangle
//!   inequality: the elbow folded and stretched); `f_2` lies on the circle of radius `R_1` about
//!   axis 1 through its foot `o_1` there.
//!
//! So a goal is out of reach when `p_6` lies farther from that circle than `R_2 + R_3 + r_5 +
//! r_6`, or nearer every point of it than `|R_2 - R_3| - r_5 - r_6`, by more than the
//! tolerances let a solution miss the goal. The bound never refuses a goal that some posture
//! reaches (whatever the joint ranges: it ignores them); it refuses only goals that the arm
//! misses by more than its wrist's offsets `r_5 + r_6` and the slack of the triangle inequality
//! (none when axes 2 and 3 are parallel), which for an arm calibrated to a spherical wrist are
//! the calibration's corrections.

use nalgebra::Vector3;

use crate::model::kinematics::{target_joint, Chain, Frame, Target, Workspace};
use crate::model::robot::{JointKind, Robot};

/// The reach of one calibrated six-revolute arm's wrist point, for one target frame.
#[derive(Debug, Clone)]
pub(crate) struct ReachBound {
    /// A point of axis 1 (m) and the axis' unit direction (global frame).
    axis: (Vector3<f64>, Vector3<f64>),
    /// The radius of the circle of `f_2` about axis 1 (m).
    shoulder: f64,
    /// The largest distance of `p_6` from that circle with the goal reached (m): `R_2 + R_3 +
    /// r_5 + r_6` and the tolerances' margin.
    farthest: f64,
    /// The smallest (m): `|R_2 - R_3| - r_5 - r_6` less the margin (may be negative).
    nearest: f64,
    /// `p_6` in the target frame (m).
    wrist: Vector3<f64>,
}

impl ReachBound {
    /// The bound of `calibrated` for `target`, when the robot is a rigid serial arm of six
    /// revolute joints with `target` on its last link, and axes 4 and 5 not parallel; a goal
    /// counts as reached within `position_tolerance` (m) and `attitude_tolerance` (rad).
    pub(crate) fn new(
        calibrated: &Robot,
        target: Target,
        position_tolerance: f64,
        attitude_tolerance: f64,
    ) -> Option<ReachBound> {
        if calibrated.dof() != 6
            || calibrated.is_tree()
            || calibrated.elastic.is_some()
            || target_joint(calibrated, target) != 6
            || calibrated
                .joints
                .iter()
                .any(|j| j.kind != JointKind::Revolute)
        {
            return None;
        }
        let chain = Chain::new(calibrated);
        let mut ws = Workspace::new(calibrated);
        chain.forward(&[0.0; 6], &mut ws);
        let w: [Vector3<f64>; 6] =
            std::array::from_fn(|i| ws.after_joint(i + 1).rotation.column(2).into_owned());
        let r: [Vector3<f64>; 6] = std::array::from_fn(|i| ws.after_joint(i + 1).translation);
        let home = chain.target_frame(&ws, target);
        let foot = |p: &Vector3<f64>, k: usize| r[k] + w[k] * w[k].dot(&(p - r[k]));
        // The point of axis 4 nearest axis 5.
        let d = r[4] - r[3];
        let b = w[3].dot(&w[4]);
        let den = 1.0 - b * b;
        if den < 1e-12 {
            return None;
        }
        let c = r[3] + w[3] * ((w[3].dot(&d) - b * w[4].dot(&d)) / den);
        // Axes 4 and 5 nearly parallel put that point far out along axis 4, where the
        // geometry's rounding outgrows the margin below: no bound (real wrists' axes cross).
        if (c - r[3]).norm() > calibrated.reach().max(1.0) {
            return None;
        }
        let p5 = foot(&c, 4);
        let p6 = foot(&p5, 5);
        let offsets = (c - p5).norm() + (p5 - p6).norm();
        let f3 = foot(&c, 2);
        let f2 = foot(&f3, 1);
        let o1 = foot(&f2, 0);
        let (r3, r2) = ((c - f3).norm(), (f3 - f2).norm());
        let wrist = home.rotation.transpose() * (p6 - home.translation);
        // A goal reached within the tolerances moves p6 by at most the position tolerance and
        // the attitude tolerance times p6's distance from the target; a millionth of a
        // micrometre per metre of reach covers the rounding of the geometry above.
        let margin = position_tolerance
            + attitude_tolerance * wrist.norm()
            + 1e-12 * calibrated.reach().max(1.0);
        Some(ReachBound {
            axis: (o1, w[0]),
            shoulder: (f2 - o1).norm(),
            farthest: r2 + r3 + offsets + margin,
            nearest: (r2 - r3).abs() - offsets - margin,
            wrist,
        })
    }

    /// Whether no posture puts the target frame at `goal` (global frame, m) within the
    /// tolerances: `p_6` too far from, or too near, every point of the shoulder's circle.
    pub(crate) fn out_of_reach(&self, goal: &Frame) -> bool {
        let p = goal.rotation * self.wrist + goal.translation;
        let (o, w) = &self.axis;
        let v = p - o;
        let h = w.dot(&v);
        let rho = (v - w * h).norm();
        let nearest = (rho - self.shoulder).hypot(h);
        let farthest = (rho + self.shoulder).hypot(h);
        nearest > self.farthest || farthest < self.nearest
    }
}
