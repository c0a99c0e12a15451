//! Cameras and calibration boards: what a pixel observation looks through and at.
//!
//! Conventions (internal units: metres, radians, pixels):
//! - a camera or a board is *mounted* on the robot's global frame ([`Mount::Base`]: fixed
//!   beside the robot, eye-to-hand), on the end effector ([`Mount::EndEffector`]: eye-in-hand),
//!   or on a site ([`Mount::Site`]: a tree's other tool frames, a bracket);
//! - its `pose` is its frame in the mount's frame, by the same six parameters as a link:
//!   `Trans(x, y, z) Rz(alpha) Ry(beta) Rx(gamma)`;
//! - the camera frame is OpenCV's: z along the optical axis (out of the lens), x to the right of
//!   the image, y down; a point `(X, Y, Z)` of it (Z > 0) is seen at pixel `(u, v)` through the
//!   pinhole with OpenCV's plumb-bob distortion ([`Camera::project`]);
//! - a board is a grid of `cols x rows` points in its frame's x-y plane, `spacing` apart: point
//!   `k` (0-based, row-major) at `((k % cols) * spacing, (k / cols) * spacing, 0)`.
//!
//! Their parameters come after every other parameter of the robot (so adding a camera never
//! renumbers the robot's): 15 per camera (`NAME.x .. NAME.gamma`, `NAME.fx, NAME.fy, NAME.cx,
//! NAME.cy, NAME.k1, NAME.k2, NAME.p1, NAME.p2, NAME.k3`), then 6 per board (`NAME.x ..
//! NAME.gamma`).

use nalgebra::{Matrix2x3, Vector2, Vector3};

pub use crate::model::params::CameraComponent;
use crate::model::params::Link;

/// Where a camera or a board is fixed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mount {
    /// The robot's global frame (the measurement frame): fixed beside the robot.
    Base,
    /// The end effector (eye-in-hand for a camera).
    EndEffector,
    /// Site `i` (0-based index into the robot's sites): a tree's other tool frame, a bracket.
    Site(usize),
}

/// A camera: its mount, its pose there, and its lens (OpenCV's pinhole and plumb-bob model).
#[derive(Debug, Clone, PartialEq)]
pub struct Camera {
    /// The name in pixel files and parameter names (`wrist.fx`).
    pub name: String,
    /// What it is fixed to.
    pub mount: Mount,
    /// The camera frame in the mount's frame.
    pub pose: Link,
    /// Focal lengths and principal point (pixels).
    pub fx: f64,
    /// Focal length along y (pixels).
    pub fy: f64,
    /// Principal point x (pixels).
    pub cx: f64,
    /// Principal point y (pixels).
    pub cy: f64,
    /// `k1, k2, p1, p2, k3`, OpenCV's order.
    pub distortion: [f64; 5],
    /// Image size in pixels (points outside it are not seen).
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
}

/// A camera point's projection and its derivatives ([`Camera::project`]).
#[derive(Debug, Clone, Copy)]
pub struct Projection {
    /// The pixel.
    pub uv: Vector2<f64>,
    /// Its derivative with respect to the point in the camera frame (pixels per metre).
    pub d_point: Matrix2x3<f64>,
    /// Its derivative with respect to the nine lens parameters in [`CameraComponent::ALL`]'s
    /// order (`fx, fy, cx, cy, k1, k2, p1, p2, k3`).
    pub d_lens: [[f64; 2]; 9],
}

impl Camera {
    /// The smallest depth (m) a point is projected at: nearer or behind, it is projected as if
    /// at this depth, so that residuals stay finite (and large) for a point the camera cannot see.
    pub const MIN_DEPTH: f64 = 1e-6;

    /// The value of one parameter (internal units).
    pub fn get(&self, c: CameraComponent) -> f64 {
        match c {
            CameraComponent::Pose(l) => self.pose.get(l),
            CameraComponent::Fx => self.fx,
            CameraComponent::Fy => self.fy,
            CameraComponent::Cx => self.cx,
            CameraComponent::Cy => self.cy,
            CameraComponent::K1 => self.distortion[0],
            CameraComponent::K2 => self.distortion[1],
            CameraComponent::P1 => self.distortion[2],
            CameraComponent::P2 => self.distortion[3],
            CameraComponent::K3 => self.distortion[4],
        }
    }

    /// A mutable reference to one parameter.
    pub fn get_mut(&mut self, c: CameraComponent) -> &mut f64 {
        match c {
            CameraComponent::Pose(l) => self.pose.get_mut(l),
            CameraComponent::Fx => &mut self.fx,
            CameraComponent::Fy => &mut self.fy,
            CameraComponent::Cx => &mut self.cx,
            CameraComponent::Cy => &mut self.cy,
            CameraComponent::K1 => &mut self.distortion[0],
            CameraComponent::K2 => &mut self.distortion[1],
            CameraComponent::P1 => &mut self.distortion[2],
            CameraComponent::P2 => &mut self.distortion[3],
            CameraComponent::K3 => &mut self.distortion[4],
        }
    }

    /// The pixel at which point `p` of the camera frame (m) is seen, with its derivatives.
    ///
    /// OpenCV's model: `x = X/Z, y = Y/Z, r2 = x^2 + y^2, radial = 1 + k1 r2 + k2 r2^2 + k3
    /// r2^3, x' = x radial + 2 p1 x y + p2 (r2 + 2 x^2), y' = y radial + p1 (r2 + 2 y^2) + 2 p2 x
    /// y, u = fx x' + cx, v = fy y' + cy`. `Z` is floored at [`Camera::MIN_DEPTH`].
    pub fn project(&self, p: &Vector3<f64>) -> Projection {
        let [k1, k2, p1, p2, k3] = self.distortion;
        let z = p.z.max(Self::MIN_DEPTH);
        let (x, y) = (p.x / z, p.y / z);
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
        let xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
        let yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
        // d radial / d r2, and the 2x2 derivative of (x', y') over (x, y).
        let dradial = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2);
        let dxd_dx = radial + 2.0 * x * x * dradial + 2.0 * p1 * y + 6.0 * p2 * x;
        let dxd_dy = 2.0 * x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y;
        let dyd_dx = 2.0 * x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y;
        let dyd_dy = radial + 2.0 * y * y * dradial + 6.0 * p1 * y + 2.0 * p2 * x;
        // d (x, y) / d p (zero along z when the depth is floored: the point is not seen).
        let seen = p.z >= Self::MIN_DEPTH;
        let (iz, xz, yz) = if seen {
            (1.0 / z, -x / z, -y / z)
        } else {
            (1.0 / z, 0.0, 0.0)
        };
        let dx = [iz, 0.0, xz];
        let dy = [0.0, iz, yz];
        let mut d_point = Matrix2x3::zeros();
        for k in 0..3 {
            d_point[(0, k)] = self.fx * (dxd_dx * dx[k] + dxd_dy * dy[k]);
            d_point[(1, k)] = self.fy * (dyd_dx * dx[k] + dyd_dy * dy[k]);
        }
        let (fx, fy) = (self.fx, self.fy);
        let d_lens = [
            [xd, 0.0],
            [0.0, yd],
            [1.0, 0.0],
            [0.0, 1.0],
            [fx * x * r2, fy * y * r2],
            [fx * x * r2 * r2, fy * y * r2 * r2],
            [fx * 2.0 * x * y, fy * (r2 + 2.0 * y * y)],
            [fx * (r2 + 2.0 * x * x), fy * 2.0 * x * y],
            [fx * x * r2 * r2 * r2, fy * y * r2 * r2 * r2],
        ];
        Projection {
            uv: Vector2::new(fx * xd + self.cx, fy * yd + self.cy),
            d_point,
            d_lens,
        }
    }

    /// Whether pixel `uv` lies inside the image.
    pub fn inside(&self, uv: &Vector2<f64>) -> bool {
        uv.x >= 0.0 && uv.y >= 0.0 && uv.x <= self.width as f64 && uv.y <= self.height as f64
    }

    /// Checks the lens: focal lengths positive, image size positive, every value finite.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.fx > 0.0 && self.fy > 0.0 && self.fx.is_finite() && self.fy.is_finite()) {
            return Err(format!(
                "camera `{}`: fx and fy must be positive numbers of pixels (found {} and {})",
                self.name, self.fx, self.fy
            ));
        }
        if self.width == 0 || self.height == 0 {
            return Err(format!(
                "camera `{}`: width and height must be positive numbers of pixels",
                self.name
            ));
        }
        Ok(())
    }
}

/// A calibration board: a planar grid of points (chessboard corners, circle centres).
#[derive(Debug, Clone, PartialEq)]
pub struct Board {
    /// The name in pixel files (`board:17`) and parameter names (`board.x`).
    pub name: String,
    /// What it is fixed to.
    pub mount: Mount,
    /// The board frame in the mount's frame.
    pub pose: Link,
    /// Points along the board's x.
    pub cols: u32,
    /// Points along its y.
    pub rows: u32,
    /// Distance between neighbouring points (m).
    pub spacing: f64,
}

impl Board {
    /// Number of points.
    pub fn points(&self) -> usize {
        self.cols as usize * self.rows as usize
    }

    /// Point `k` (0-based, row-major) in the board frame (m).
    pub fn point(&self, k: usize) -> Vector3<f64> {
        let cols = self.cols.max(1) as usize;
        Vector3::new(
            (k % cols) as f64 * self.spacing,
            (k / cols) as f64 * self.spacing,
            0.0,
        )
    }

    /// Checks the grid: at least 2 x 2 points, a positive finite spacing.
    pub fn validate(&self) -> Result<(), String> {
        if self.cols < 2 || self.rows < 2 || self.points() > 1_000_000 {
            return Err(format!(
                "board `{}`: cols and rows must be at least 2 (and the grid at most 1,000,000 \
                 points); found {} x {}",
                self.name, self.cols, self.rows
            ));
        }
        if !(self.spacing > 0.0 && self.spacing.is_finite()) {
            return Err(format!(
                "board `{}`: spacing must be a positive length",
                self.name
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> Camera {
        Camera {
            name: "c".into(),
            mount: Mount::Base,
            pose: Link::default(),
            fx: 600.0,
            fy: 610.0,
            cx: 320.0,
            cy: 240.0,
            distortion: [-0.2, 0.05, 1e-3, -5e-4, 0.01],
            width: 640,
            height: 480,
        }
    }

    /// The analytic derivatives against central differences: steps of 1e-6 of each variable's
    /// scale leave truncation errors of about 1e-12 relative, far below the 1e-6 asked.
    #[test]
    fn projection_derivatives_match_finite_differences() {
        let c = camera();
        let p = Vector3::new(0.11, -0.07, 0.6);
        let pr = c.project(&p);
        for k in 0..3 {
            let h = 1e-7;
            let mut a = p;
            let mut b = p;
            a[k] += h;
            b[k] -= h;
            let fd = (c.project(&a).uv - c.project(&b).uv) / (2.0 * h);
            for r in 0..2 {
                let an = pr.d_point[(r, k)];
                assert!(
                    (an - fd[r]).abs() <= 1e-6 * (1.0 + an.abs()),
                    "{k} {r}: {an} {fd}"
                );
            }
        }
        for (i, comp) in CameraComponent::ALL[6..].iter().enumerate() {
            // Steps of 1e-6 of the value, at least 1e-6: rounding (1e-16 * 300 px / h) stays
            // below 1e-7 px per unit, truncation (h^2 |f'''|) far below.
            let h = 1e-6 * c.get(*comp).abs().max(1.0);
            let (mut a, mut b) = (c.clone(), c.clone());
            *a.get_mut(*comp) += h;
            *b.get_mut(*comp) -= h;
            let fd = (a.project(&p).uv - b.project(&p).uv) / (2.0 * h);
            for r in 0..2 {
                let an = pr.d_lens[i][r];
                assert!(
                    (an - fd[r]).abs() <= 1e-6 * (1.0 + an.abs()),
                    "{}: {an} {}",
                    comp.as_str(),
                    fd[r]
                );
            }
        }
    }

    #[test]
    fn the_optical_axis_meets_the_principal_point() {
        let c = camera();
        let uv = c.project(&Vector3::new(0.0, 0.0, 2.0)).uv;
        assert!((uv.x - 320.0).abs() < 1e-12 && (uv.y - 240.0).abs() < 1e-12);
        // A point right of the axis is right in the image (x right), below is down (y down).
        let uv = c.project(&Vector3::new(0.01, 0.02, 1.0)).uv;
        assert!(uv.x > 320.0 && uv.y > 240.0);
        // Behind the camera: finite.
        let uv = c.project(&Vector3::new(0.01, 0.02, -1.0)).uv;
        assert!(uv.x.is_finite() && uv.y.is_finite());
    }

    #[test]
    fn board_points_are_row_major() {
        let b = Board {
            name: "b".into(),
            mount: Mount::Base,
            pose: Link::default(),
            cols: 9,
            rows: 6,
            spacing: 0.025,
        };
        assert_eq!(b.points(), 54);
        assert_eq!(b.point(17), Vector3::new(8.0 * 0.025, 0.025, 0.0));
        assert!(b.validate().is_ok());
    }
}
