//! Poses and positions of a target, as a laser tracker, a camera or a CMM measures them (in the
//! measurement frame: the global frame, or the session's). Their file, the measurement file, is
//! read and written in [`crate::files`].

use nalgebra::{Matrix3, Vector3};

use super::{
    target_name, Anchoring, Context, Derivatives, ErrorSample, Noise, Observe, OrientationError,
    Posture, Row, RowQuantity, View,
};
use crate::model::kinematics::{
    euler_rates, euler_zyx, log_so3, rot_zyx, so3_right_jacobian_inverse, Frame, Target,
};
use crate::model::robot::Robot;
use crate::units::wrap_angle;

const POSE_ROWS: &[Row] = &[
    Row {
        label: "x",
        quantity: RowQuantity::Length,
    },
    Row {
        label: "y",
        quantity: RowQuantity::Length,
    },
    Row {
        label: "z",
        quantity: RowQuantity::Length,
    },
    Row {
        label: "alpha",
        quantity: RowQuantity::Angle,
    },
    Row {
        label: "beta",
        quantity: RowQuantity::Angle,
    },
    Row {
        label: "gamma",
        quantity: RowQuantity::Angle,
    },
];

/// A measured pose of a target: its origin and ZYX Euler angles in the global frame. Six
/// residual rows: the position difference (m), then the orientation difference (rad): Euler
/// angle differences wrapped to (-pi, pi] (thesis eq. 3.1), or the rotation vector of
/// `R_measured^T R_model`.
#[derive(Debug, Clone)]
pub struct Pose {
    /// The posture and target.
    pub view: [View; 1],
    /// Measured origin (m).
    pub position: Vector3<f64>,
    /// Measured ZYX Euler angles `(alpha, beta, gamma)` (rad).
    pub euler: Vector3<f64>,
    /// The row's own standard deviations of the position's x, y, z (m, measurement frame), if
    /// given.
    pub sigma_position: Option<Vector3<f64>>,
    /// The row's own standard deviation of an angle (rad), if given.
    pub sigma_angle: Option<f64>,
    /// Line in the file (0 when synthesized).
    pub line: usize,
    /// The rotation of `euler`, made once rather than at every pass (three `sin_cos`s of each
    /// pose in every evaluation): see [`Pose::measured_rotation`].
    rotation: MeasuredRotation,
}

/// The measured rotation `R_zyx(euler)` and the angles it was made from: used only while they
/// are still `Pose::euler`, to the bit (the field is public and may be changed).
#[derive(Debug, Clone)]
struct MeasuredRotation {
    of: Vector3<f64>,
    matrix: Matrix3<f64>,
}

impl MeasuredRotation {
    fn of(euler: &Vector3<f64>) -> Self {
        MeasuredRotation {
            of: *euler,
            matrix: rot_zyx(euler.x, euler.y, euler.z),
        }
    }
}

/// Poses are equal when what was measured is: the kept rotation is a copy of what the angles
/// give. (A field added to [`Pose`] is compared here too.)
impl PartialEq for Pose {
    fn eq(&self, other: &Self) -> bool {
        self.view == other.view
            && self.position == other.position
            && self.euler == other.euler
            && self.sigma_position == other.sigma_position
            && self.sigma_angle == other.sigma_angle
            && self.line == other.line
    }
}

/// A measured position of a target's origin in the global frame. Three residual rows (m).
#[derive(Debug, Clone, PartialEq)]
pub struct Position {
    /// The posture and target.
    pub view: [View; 1],
    /// Measured origin (m).
    pub position: Vector3<f64>,
    /// The row's own standard deviations of x, y, z (m, measurement frame), if given.
    pub sigma_position: Option<Vector3<f64>>,
    /// Line in the file (0 when synthesized).
    pub line: usize,
}

impl Pose {
    /// A pose of `target` in `posture`, without a standard deviation of its own.
    pub fn new(
        posture: usize,
        target: Target,
        position: Vector3<f64>,
        euler: Vector3<f64>,
    ) -> Self {
        Pose::with_sigmas(View { posture, target }, position, euler, None, None, 0)
    }

    /// A pose seen in `view`, with the row's own standard deviations (see the fields) and its
    /// line in the file.
    pub fn with_sigmas(
        view: View,
        position: Vector3<f64>,
        euler: Vector3<f64>,
        sigma_position: Option<Vector3<f64>>,
        sigma_angle: Option<f64>,
        line: usize,
    ) -> Self {
        Pose {
            view: [view],
            position,
            euler,
            sigma_position,
            sigma_angle,
            line,
            rotation: MeasuredRotation::of(&euler),
        }
    }

    /// The measured rotation, `R_zyx(alpha, beta, gamma)` of [`Pose::euler`]: the one made
    /// with the pose while the angles are still those (compared to the bit), else made now.
    pub fn measured_rotation(&self) -> Matrix3<f64> {
        let same = |a: &Vector3<f64>, b: &Vector3<f64>| {
            a.iter()
                .zip(b.iter())
                .all(|(x, y)| x.to_bits() == y.to_bits())
        };
        if same(&self.rotation.of, &self.euler) {
            self.rotation.matrix
        } else {
            rot_zyx(self.euler.x, self.euler.y, self.euler.z)
        }
    }

    /// The same measurement without its attitude.
    pub fn to_position(&self) -> Position {
        Position {
            view: self.view,
            position: self.position,
            sigma_position: self.sigma_position,
            line: self.line,
        }
    }
}

impl Position {
    /// A position of `target` in `posture`, without a standard deviation of its own.
    pub fn new(posture: usize, target: Target, position: Vector3<f64>) -> Self {
        Position {
            view: [View { posture, target }],
            position,
            sigma_position: None,
            line: 0,
        }
    }
}

fn describe_view(view: &View, postures: &[Posture], robot: &Robot) -> String {
    format!(
        "posture {} site {}",
        postures[view.posture].label,
        target_name(robot, view.target)
    )
}

impl Observe for Pose {
    observe_fields!(kind: "pose", views: view, rows: POSE_ROWS);
    fn sigma(&self, row: usize) -> Option<f64> {
        if row < 3 {
            self.sigma_position.map(|s| s[row])
        } else {
            self.sigma_angle
        }
    }

    fn evaluate(
        &self,
        ctx: &Context<'_>,
        frames: &[Frame],
        res: &mut [f64],
        derivatives: Option<&mut Derivatives<'_>>,
    ) {
        let f = &frames[0];
        let dp = f.translation - self.position;
        res[..3].copy_from_slice(dp.as_slice());
        // How an angular velocity (global frame) maps to orientation-residual rates.
        enum Map {
            Euler(f64, f64),
            Matrix(nalgebra::Matrix3<f64>),
        }
        let map = match ctx.orientation {
            OrientationError::Euler => {
                let e = euler_zyx(&f.rotation);
                for k in 0..3 {
                    res[3 + k] = wrap_angle(e[k] - self.euler[k]);
                }
                Map::Euler(e.x, e.y)
            }
            OrientationError::RotVec => {
                let rm = self.measured_rotation();
                let phi = log_so3(&(rm.transpose() * f.rotation));
                res[3..6].copy_from_slice(phi.as_slice());
                Map::Matrix(so3_right_jacobian_inverse(&phi) * f.rotation.transpose())
            }
        };
        if let Some(d) = derivatives {
            for c in 0..d.cols {
                let dp = d.dp(0, c);
                let w = d.w(0, c);
                let rate = match &map {
                    Map::Euler(a, b) => euler_rates(*a, *b, &w),
                    Map::Matrix(m) => m * w,
                };
                for k in 0..3 {
                    d.set(k, c, dp[k]);
                    d.set(3 + k, c, rate[k]);
                }
            }
        }
    }

    fn error(&self, _ctx: &Context<'_>, frames: &[Frame]) -> ErrorSample {
        let f = &frames[0];
        let rm = self.measured_rotation();
        ErrorSample {
            metric: "position",
            length: (f.translation - self.position).norm(),
            angle: Some(log_so3(&(rm.transpose() * f.rotation)).norm()),
        }
    }

    fn measured_frame(&self) -> (Target, usize) {
        (self.view[0].target, 6)
    }

    fn anchoring(&self) -> Anchoring {
        Anchoring::Absolute
    }

    fn remeasure(&mut self, _ctx: &Context<'_>, frames: &[Frame]) {
        let p = frames[0].pose();
        self.position = p.position;
        self.euler = p.euler;
        self.rotation = MeasuredRotation::of(&self.euler);
    }

    fn add_noise(&mut self, unit: &mut dyn FnMut() -> f64, noise: &Noise) {
        for k in 0..3 {
            self.position[k] += unit() * noise.length;
        }
        for k in 0..3 {
            self.euler[k] += unit() * noise.angle;
        }
        self.rotation = MeasuredRotation::of(&self.euler);
    }

    fn degenerate(&self, ctx: &Context<'_>) -> bool {
        ctx.orientation == OrientationError::Euler
            && (self.euler.y.abs() - std::f64::consts::FRAC_PI_2).abs() < 1f64.to_radians()
    }

    fn describe(&self, postures: &[Posture], robot: &Robot) -> String {
        describe_view(&self.view[0], postures, robot)
    }
}

impl Observe for Position {
    observe_fields!(kind: "position", views: view, rows: &POSE_ROWS[..3]);
    fn sigma(&self, row: usize) -> Option<f64> {
        self.sigma_position.map(|s| s[row])
    }

    fn evaluate(
        &self,
        _ctx: &Context<'_>,
        frames: &[Frame],
        res: &mut [f64],
        derivatives: Option<&mut Derivatives<'_>>,
    ) {
        let dp = frames[0].translation - self.position;
        res[..3].copy_from_slice(dp.as_slice());
        if let Some(d) = derivatives {
            for c in 0..d.cols {
                let dp = d.dp(0, c);
                for k in 0..3 {
                    d.set(k, c, dp[k]);
                }
            }
        }
    }

    fn error(&self, _ctx: &Context<'_>, frames: &[Frame]) -> ErrorSample {
        ErrorSample {
            metric: "position",
            length: (frames[0].translation - self.position).norm(),
            angle: None,
        }
    }

    fn measured_frame(&self) -> (Target, usize) {
        (self.view[0].target, 3)
    }

    fn anchoring(&self) -> Anchoring {
        Anchoring::Absolute
    }

    fn remeasure(&mut self, _ctx: &Context<'_>, frames: &[Frame]) {
        self.position = frames[0].translation;
    }

    fn add_noise(&mut self, unit: &mut dyn FnMut() -> f64, noise: &Noise) {
        for k in 0..3 {
            self.position[k] += unit() * noise.length;
        }
    }

    fn describe(&self, postures: &[Posture], robot: &Robot) -> String {
        describe_view(&self.view[0], postures, robot)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bits(m: &Matrix3<f64>) -> Vec<u64> {
        m.iter().map(|v| v.to_bits()).collect()
    }

    /// The kept rotation is what the angles give, to the bit, and is not used once the public
    /// angles are changed behind its back; equality ignores it.
    #[test]
    fn a_pose_keeps_its_measured_rotation_only_while_its_angles_are_the_same() {
        let euler = Vector3::new(0.3, -1.2, 2.9);
        let mut p = Pose::new(0, Target::EndEffector, Vector3::new(1.0, 2.0, 3.0), euler);
        assert_eq!(bits(&p.measured_rotation()), bits(&rot_zyx(0.3, -1.2, 2.9)));
        let fresh = Pose::new(
            0,
            Target::EndEffector,
            p.position,
            Vector3::new(0.3, 0.4, 2.9),
        );
        p.euler.y = 0.4;
        assert_eq!(bits(&p.measured_rotation()), bits(&rot_zyx(0.3, 0.4, 2.9)));
        assert_eq!(p, fresh);
        let mut noisy = fresh.clone();
        let mut unit = || 0.5;
        noisy.add_noise(
            &mut unit,
            &Noise {
                length: 0.0,
                angle: 0.1,
                pixel: 0.0,
            },
        );
        assert_eq!(
            bits(&noisy.measured_rotation()),
            bits(&rot_zyx(0.3 + 0.5 * 0.1, 0.4 + 0.5 * 0.1, 2.9 + 0.5 * 0.1))
        );
        assert_eq!(
            bits(&noisy.rotation.matrix),
            bits(&noisy.measured_rotation())
        );
    }
}
