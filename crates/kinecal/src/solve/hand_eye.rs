//! Cameras and boards placed from nothing, before the solver runs: the closed forms of
//! `super::camera_start` applied to a calibration's pixel observations.
//!
//! For each camera whose pose or whose boards' poses are to be estimated and are all zero (not
//! given), from the views in which it saw at least 4 points of one board:
//! 1. its lens by Zhang's method, when the lens is estimated and there are 3 views or more (the
//!    distortion is left as given: the fit estimates it);
//! 2. each view's board pose in the camera frame `P_i`, from the homography of the undistorted
//!    points;
//! 3. the camera's pose `X` in its mount and the board's pose `Y` in its own from `A_i X = Y
//!    P_i^-1`, `A_i = B_i^-1 C_i` with `C_i` and `B_i` the frames the camera and the board are
//!    mounted on in view `i` (the identity for the base): the one equation covers eye-in-hand
//!    (`B_i` the identity), eye-to-hand (`C_i` the identity) and both moving. With one of the
//!    two given, the other is the average of its per-view values.
//!
//! The placement is kept only when it lowers the pixels' RMS reprojection error.

use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};

use super::camera_start::{self, Lens};
use crate::model::camera::CameraComponent;
use crate::model::kinematics::{euler_zyx, Frame};
use crate::model::params::{Link, LinkComponent, ParamId, ParamKind};
use crate::model::robot::Robot;
use crate::observe::pixel::Seen;
use crate::observe::{for_each_observation, Dataset, Observation};

/// One camera's sightings of one board in one posture.
struct View {
    posture: usize,
    /// The frames the camera and the board are mounted on.
    camera_mount: Frame,
    board_mount: Frame,
    /// Board plane points (m) and their pixels.
    plane: Vec<[f64; 2]>,
    pixels: Vec<[f64; 2]>,
}

fn isometry(f: &Frame) -> Isometry3<f64> {
    let r = Rotation3::from_matrix_unchecked(f.rotation);
    Isometry3::from_parts(
        Translation3::from(f.translation),
        UnitQuaternion::from_rotation_matrix(&r),
    )
}

fn link_of(iso: &Isometry3<f64>) -> Link {
    let r: Matrix3<f64> = *iso.rotation.to_rotation_matrix().matrix();
    let e = euler_zyx(&r);
    let t = iso.translation.vector;
    Link {
        x: t.x,
        y: t.y,
        z: t.z,
        alpha: e.x,
        beta: e.y,
        gamma: e.z,
    }
}

fn iso_of(l: &Link) -> Isometry3<f64> {
    isometry(&Frame::from_link(l))
}

fn is_zero(l: &Link) -> bool {
    LinkComponent::ALL
        .iter()
        .all(|&c| l.get(c).abs() < f64::MIN_POSITIVE)
}

/// The mean of rigid transforms: the mean translation, the rotation nearest the mean rotation
/// matrix.
fn mean(isos: &[Isometry3<f64>]) -> Option<Isometry3<f64>> {
    if isos.is_empty() {
        return None;
    }
    let n = isos.len() as f64;
    let t: Vector3<f64> = isos
        .iter()
        .map(|i| i.translation.vector)
        .sum::<Vector3<f64>>()
        / n;
    let m: Matrix3<f64> = isos
        .iter()
        .map(|i| *i.rotation.to_rotation_matrix().matrix())
        .sum();
    let r = Rotation3::from_matrix_eps(&m, 1e-12, 100, Rotation3::identity());
    let out = Isometry3::from_parts(
        Translation3::from(t),
        UnitQuaternion::from_rotation_matrix(&r),
    );
    out.to_homogeneous()
        .iter()
        .all(|v| v.is_finite())
        .then_some(out)
}

/// The RMS reprojection error (pixels) of `data`'s pixels for `robot`, `None` without pixels.
pub(crate) fn pixel_rms(robot: &Robot, data: &Dataset) -> Option<f64> {
    let e: Vec<f64> = crate::observe::errors(robot, data)
        .into_iter()
        .filter(|e| e.metric == "pixel")
        .map(|e| e.length * e.length)
        .collect();
    (!e.is_empty()).then(|| (e.iter().sum::<f64>() / e.len() as f64).sqrt())
}

/// `robot` with its cameras' and boards' unknown poses (all zero, and among `estimated`)
/// placed in closed form from `data`'s pixels, the lenses started by Zhang's method when
/// estimated; `None` when nothing was placed or the placement did not lower the RMS
/// reprojection error.
pub fn place_cameras(robot: &Robot, data: &Dataset, estimated: &[ParamId]) -> Option<Robot> {
    if robot.cameras.is_empty() {
        return None;
    }
    let wanted = |kind: ParamKind| estimated.contains(&robot.param_id(kind));
    // The views of each (camera, board) pair, by posture.
    let mut views: Vec<((usize, usize), View)> = Vec::new();
    for_each_observation(robot, data, |_, o, frames| {
        let Observation::Pixel(p) = o else { return };
        let Seen::Board { board, index } = p.seen else {
            return;
        };
        let posture = p.view[0].posture;
        let (camera_mount, board_mount) = p.mounts(frames);
        let b = &robot.boards[board];
        let at = b.point(index);
        let key = (p.camera, board);
        let v = match views
            .iter_mut()
            .find(|(k, v)| *k == key && v.posture == posture)
        {
            Some((_, v)) => v,
            None => {
                views.push((
                    key,
                    View {
                        posture,
                        camera_mount,
                        board_mount,
                        plane: Vec::new(),
                        pixels: Vec::new(),
                    },
                ));
                &mut views.last_mut().expect("pushed").1
            }
        };
        v.plane.push([at.x, at.y]);
        v.pixels.push(p.uv);
    });
    views.retain(|(_, v)| v.plane.len() >= 4);
    let mut placed = robot.clone();
    let mut any = false;
    for camera in 0..robot.cameras.len() {
        let pose_ids = LinkComponent::ALL.map(|l| ParamKind::Camera {
            camera,
            component: CameraComponent::Pose(l),
        });
        let camera_unknown =
            is_zero(&robot.cameras[camera].pose) && pose_ids.iter().all(|&k| wanted(k));
        let boards: Vec<usize> = (0..robot.boards.len())
            .filter(|&b| views.iter().any(|((c, bb), _)| *c == camera && *bb == b))
            .collect();
        let board_unknown = |b: usize| {
            is_zero(&robot.boards[b].pose)
                && LinkComponent::ALL.iter().all(|&component| {
                    wanted(ParamKind::Board {
                        board: b,
                        component,
                    })
                })
        };
        if !camera_unknown && !boards.iter().any(|&b| board_unknown(b)) {
            continue;
        }
        // The lens: Zhang's when estimated and there are enough views.
        let lens_estimated = wanted(ParamKind::Camera {
            camera,
            component: CameraComponent::Fx,
        });
        let mine: Vec<&View> = views
            .iter()
            .filter(|((c, _), _)| *c == camera)
            .map(|(_, v)| v)
            .collect();
        if lens_estimated && mine.len() >= 3 {
            let hs: Vec<Matrix3<f64>> = mine
                .iter()
                .filter_map(|v| camera_start::homography(&v.plane, &v.pixels))
                .collect();
            if let Some([fx, fy, cx, cy]) = camera_start::intrinsics_zhang(&hs) {
                let c = &mut placed.cameras[camera];
                (c.fx, c.fy, c.cx, c.cy) = (fx, fy, cx, cy);
            }
        }
        let cam = &placed.cameras[camera];
        let lens = Lens {
            fx: cam.fx,
            fy: cam.fy,
            cx: cam.cx,
            cy: cam.cy,
            distortion: cam.distortion,
        };
        // Each view's board pose in the camera frame, from the undistorted points.
        let pose_in_camera = |v: &View| -> Option<Isometry3<f64>> {
            let image: Option<Vec<[f64; 2]>> = v
                .pixels
                .iter()
                .map(|p| lens.undistort(p[0], p[1]))
                .collect();
            let h = camera_start::homography(&v.plane, &image?)?;
            camera_start::board_pose_normalized(&h)
        };
        for &board in &boards {
            let mut a = Vec::new();
            let mut b = Vec::new();
            for ((c, bb), v) in &views {
                if (*c, *bb) != (camera, board) {
                    continue;
                }
                let Some(p) = pose_in_camera(v) else { continue };
                a.push(isometry(&v.board_mount).inverse() * isometry(&v.camera_mount));
                b.push(p.inverse());
            }
            if a.len() < 3 {
                continue;
            }
            let x_given = (!camera_unknown).then(|| iso_of(&placed.cameras[camera].pose));
            let y_given = (!board_unknown(board)).then(|| iso_of(&placed.boards[board].pose));
            // A_i X = Y B_i.
            let (x, y) = match (x_given, y_given) {
                (Some(x), Some(y)) => (x, y),
                (Some(x), None) => {
                    let ys: Vec<_> = a.iter().zip(&b).map(|(a, b)| a * x * b.inverse()).collect();
                    (x, mean(&ys)?)
                }
                (None, Some(y)) => {
                    let xs: Vec<_> = a.iter().zip(&b).map(|(a, b)| a.inverse() * y * b).collect();
                    (mean(&xs)?, y)
                }
                (None, None) => match camera_start::hand_eye_ax_yb(&a, &b) {
                    Some(xy) => xy,
                    None => continue,
                },
            };
            if camera_unknown {
                placed.cameras[camera].pose = link_of(&x);
            }
            if board_unknown(board) {
                placed.boards[board].pose = link_of(&y);
            }
            any = true;
        }
    }
    if !any || placed.validate().is_err() {
        return None;
    }
    let before = pixel_rms(robot, data)?;
    let after = pixel_rms(&placed, data)?;
    (after < before).then_some(placed)
}
