//! A pixel: where a camera of the robot file saw a point (a board's corner, a marker on a site),
//! in the image. Two residual rows, `u` and `v`: the reprojection error in pixels through the
//! camera's full lens model ([`crate::model::camera::Camera::project`]).
//!
//! The camera and the point each sit on the robot's global frame or on a frame of the robot
//! (the end effector, a site); whichever moves with the robot is one of the observation's views
//! (one or two, in the same posture). So the residual depends on the robot's kinematics, on the
//! camera's pose and lens and on the board's pose, and a fit estimates any of them together.
//!
//! Their file, the pixel file, is read in [`crate::files`].

use nalgebra::{Matrix3, Vector2, Vector3};

use super::{
    target_name, Anchoring, Context, Derivatives, ErrorSample, Observe, Posture, Row, RowQuantity,
    View,
};
use crate::model::camera::{CameraComponent, Mount};
use crate::model::kinematics::{Frame, Target};
use crate::model::params::{LinkComponent, ParamKind};
use crate::model::robot::Robot;

const ROWS: &[Row] = &[
    Row {
        label: "u",
        quantity: RowQuantity::Pixel,
    },
    Row {
        label: "v",
        quantity: RowQuantity::Pixel,
    },
];

/// The point a pixel observation saw.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Seen {
    /// Point `index` (0-based, row-major) of board `board`.
    Board {
        /// Index into the robot's boards.
        board: usize,
        /// The point's index on the board.
        index: usize,
    },
    /// The origin of a frame of the robot (a marker on the end effector or a site).
    Target(Target),
}

/// The robot frame a mount moves with, `None` for the global frame.
pub fn mount_target(m: Mount) -> Option<Target> {
    match m {
        Mount::Base => None,
        Mount::EndEffector => Some(Target::EndEffector),
        Mount::Site(s) => Some(Target::Site(s)),
    }
}

/// A camera's view of a point: the pixel `(u, v)` it was seen at.
#[derive(Debug, Clone, PartialEq)]
pub struct Pixel {
    /// The views (the moving frames among the camera's mount and the point's frame); the first
    /// `count` are used.
    pub view: [View; 2],
    count: usize,
    /// Which view is the camera's mount (`None`: the camera is fixed).
    camera_view: Option<usize>,
    /// Which view is the point's frame (`None`: the point is fixed).
    point_view: Option<usize>,
    /// The camera (index into the robot's cameras).
    pub camera: usize,
    /// What it saw.
    pub seen: Seen,
    /// The measured pixel.
    pub uv: [f64; 2],
    /// The row's own standard deviation (pixels), if given.
    pub sigma: Option<f64>,
    /// Line in the file (0 when synthesized).
    pub line: usize,
}

impl Pixel {
    /// Camera `camera` of `robot` seeing `seen` in `posture` at pixel `uv`; an error (its
    /// message) when nothing in it moves with the robot (the camera and the point both fixed, or
    /// both on one frame): such a pixel says nothing of the robot.
    pub fn new(
        robot: &Robot,
        posture: usize,
        camera: usize,
        seen: Seen,
        uv: [f64; 2],
    ) -> Result<Pixel, String> {
        let cam = &robot.cameras[camera];
        let point_frame = match seen {
            Seen::Board { board, .. } => mount_target(robot.boards[board].mount),
            Seen::Target(t) => Some(t),
        };
        let mut view = [View {
            posture,
            target: Target::EndEffector,
        }; 2];
        let mut count = 0;
        let mut place = |t: Option<Target>| {
            t.map(|target| {
                view[count] = View { posture, target };
                count += 1;
                count - 1
            })
        };
        let camera_view = place(mount_target(cam.mount));
        if point_frame.is_some() && point_frame == mount_target(cam.mount) {
            return Err(format!(
                "camera `{}` and the point it sees are on the same frame: the pixel does not \
                 depend on the robot",
                cam.name
            ));
        }
        let point_view = place(point_frame);
        if count == 0 {
            return Err(format!(
                "camera `{}` and the point it sees are both fixed (mount = \"base\"): the pixel \
                 does not depend on the robot",
                cam.name
            ));
        }
        Ok(Pixel {
            view,
            count,
            camera_view,
            point_view,
            camera,
            seen,
            uv,
            sigma: None,
            line: 0,
        })
    }

    /// The robot frame whose motion the pixel measures: the point's frame when it moves with
    /// the robot, else the camera's mount (one of them moves: [`Pixel::new`]).
    pub fn robot_frame(&self) -> Target {
        self.view[self.point_view.or(self.camera_view).unwrap_or(0)].target
    }

    /// The frames the camera and the point are mounted on, in the measurement frame (the
    /// identity for the base), from the views' frames.
    pub fn mounts(&self, frames: &[Frame]) -> (Frame, Frame) {
        let at = |v: Option<usize>| v.map_or(Frame::identity(), |v| frames[v]);
        (at(self.camera_view), at(self.point_view))
    }

    /// The point's frame in the measurement frame, and the point there.
    fn point(&self, robot: &Robot, frames: &[Frame]) -> (Frame, Vector3<f64>) {
        let mount = self.point_view.map_or(Frame::identity(), |v| frames[v]);
        match self.seen {
            Seen::Board { board, index } => {
                let b = &robot.boards[board];
                let f = mount.then(&Frame::from_link(&b.pose));
                let p = f.rotation * b.point(index) + f.translation;
                (f, p)
            }
            Seen::Target(_) => (mount, mount.translation),
        }
    }

    /// The camera's frame in the measurement frame, from the views' frames.
    pub fn camera_frame(&self, robot: &Robot, frames: &[Frame]) -> Frame {
        let mount = self.camera_view.map_or(Frame::identity(), |v| frames[v]);
        mount.then(&Frame::from_link(&robot.cameras[self.camera].pose))
    }

    /// The point in the camera frame (m; in front of the camera when `z > 0`) from the views'
    /// frames.
    pub fn in_camera(&self, robot: &Robot, frames: &[Frame]) -> Vector3<f64> {
        let c = self.camera_frame(robot, frames);
        let (_, p) = self.point(robot, frames);
        c.rotation.transpose() * (p - c.translation)
    }

    /// The pixel the model predicts from the views' frames.
    pub fn predicted(&self, robot: &Robot, frames: &[Frame]) -> Vector2<f64> {
        robot.cameras[self.camera]
            .project(&self.in_camera(robot, frames))
            .uv
    }
}

/// The angular velocities (in the frame the pose is expressed in) of a unit change of each of a
/// pose's three ZYX angles: about `z`, about `Rz(alpha) y`, about `Rz(alpha) Ry(beta) x`.
fn euler_axes(alpha: f64, beta: f64) -> [Vector3<f64>; 3] {
    let (sa, ca) = alpha.sin_cos();
    let (sb, cb) = beta.sin_cos();
    [
        Vector3::z(),
        Vector3::new(-sa, ca, 0.0),
        Vector3::new(ca * cb, sa * cb, -sb),
    ]
}

impl Observe for Pixel {
    fn kind(&self) -> &'static str {
        "pixel"
    }
    fn views(&self) -> &[View] {
        &self.view[..self.count]
    }
    fn views_mut(&mut self) -> &mut [View] {
        &mut self.view[..self.count]
    }
    fn rows(&self) -> &'static [Row] {
        ROWS
    }
    fn line(&self) -> usize {
        self.line
    }
    fn sigma(&self, _row: usize) -> Option<f64> {
        self.sigma
    }

    fn evaluate(
        &self,
        ctx: &Context<'_>,
        frames: &[Frame],
        res: &mut [f64],
        derivatives: Option<&mut Derivatives<'_>>,
    ) {
        let robot = ctx.robot;
        let cam = &robot.cameras[self.camera];
        let c = self.camera_frame(robot, frames);
        let (pf, p) = self.point(robot, frames);
        let rt: Matrix3<f64> = c.rotation.transpose();
        let q = rt * (p - c.translation);
        let pr = cam.project(&q);
        res[0] = pr.uv.x - self.uv[0];
        res[1] = pr.uv.y - self.uv[1];
        let Some(d) = derivatives else {
            return;
        };
        let put = |d: &mut Derivatives<'_>, col: usize, dq: Vector3<f64>| {
            let g = pr.d_point * dq;
            d.set(0, col, g.x);
            d.set(1, col, g.y);
        };
        // The robot's parameters move the camera's mount and the point's frame.
        let camera_mount = self.camera_view.map(|v| frames[v].translation);
        let point_mount = self.point_view.map(|v| frames[v].translation);
        for col in 0..d.cols {
            let mut dp = Vector3::zeros();
            if let (Some(v), Some(origin)) = (self.point_view, point_mount) {
                dp += d.dp(v, col) + d.w(v, col).cross(&(p - origin));
            }
            if let (Some(v), Some(origin)) = (self.camera_view, camera_mount) {
                let w = d.w(v, col);
                let dt = d.dp(v, col) + w.cross(&(c.translation - origin));
                dp -= dt + w.cross(&(p - c.translation));
            }
            put(d, col, rt * dp);
        }
        // The camera's own parameters.
        let ra = self
            .camera_view
            .map_or(Matrix3::identity(), |v| frames[v].rotation);
        let axes = euler_axes(cam.pose.alpha, cam.pose.beta);
        for component in CameraComponent::ALL {
            let id = robot.param_id(ParamKind::Camera {
                camera: self.camera,
                component,
            });
            let Some(col) = d.column(id) else { continue };
            match component {
                CameraComponent::Pose(l) => {
                    let i = l as usize;
                    let dq = if i < 3 {
                        -(rt * ra.column(i))
                    } else {
                        -(rt * (ra * axes[i - 3]).cross(&(p - c.translation)))
                    };
                    put(d, col, dq);
                }
                lens => {
                    let g = pr.d_lens[lens.index() - 6];
                    d.set(0, col, g[0]);
                    d.set(1, col, g[1]);
                }
            }
        }
        // The board's pose.
        if let Seen::Board { board, .. } = self.seen {
            let b = &robot.boards[board];
            let rb = self
                .point_view
                .map_or(Matrix3::identity(), |v| frames[v].rotation);
            let axes = euler_axes(b.pose.alpha, b.pose.beta);
            for l in LinkComponent::ALL {
                let id = robot.param_id(ParamKind::Board {
                    board,
                    component: l,
                });
                let Some(col) = d.column(id) else { continue };
                let i = l as usize;
                let dp = if i < 3 {
                    rb.column(i).into_owned()
                } else {
                    (rb * axes[i - 3]).cross(&(p - pf.translation))
                };
                put(d, col, rt * dp);
            }
        }
    }

    fn error(&self, ctx: &Context<'_>, frames: &[Frame]) -> ErrorSample {
        let uv = self.predicted(ctx.robot, frames);
        ErrorSample {
            metric: "pixel",
            length: (uv - Vector2::new(self.uv[0], self.uv[1])).norm(),
            angle: None,
        }
    }

    fn measured_frame(&self) -> (Target, usize) {
        // A board's corners seen together fix its pose relative to the camera (6 degrees of
        // freedom); a marker's pixels, seen from several places, its position (3).
        let dof = match self.seen {
            Seen::Board { .. } => 6,
            Seen::Target(_) => 3,
        };
        (self.view[0].target, dof)
    }

    fn anchoring(&self) -> Anchoring {
        if self.count == 1 {
            Anchoring::Absolute
        } else {
            Anchoring::Relative
        }
    }

    fn remeasure(&mut self, ctx: &Context<'_>, frames: &[Frame]) {
        let uv = self.predicted(ctx.robot, frames);
        self.uv = [uv.x, uv.y];
    }

    fn add_noise(&mut self, unit: &mut dyn FnMut() -> f64, noise: &super::Noise) {
        self.uv[0] += unit() * noise.pixel;
        self.uv[1] += unit() * noise.pixel;
    }

    fn describe(&self, postures: &[Posture], robot: &Robot) -> String {
        let seen = match self.seen {
            Seen::Board { board, index } => format!("{}:{index}", robot.boards[board].name),
            Seen::Target(t) => target_name(robot, t).to_string(),
        };
        format!(
            "posture {} camera {} point {seen}",
            postures[self.view[0].posture].label, robot.cameras[self.camera].name
        )
    }
}
