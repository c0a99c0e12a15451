//! Pixels in the predicted accuracy: a camera's reprojection error turned into a length at the
//! point it saw.
//!
//! A pixel's residual `r = (u, v)_model - (u, v)_measured` is the image of an error of the
//! point in the camera's frame. Across the line of sight (along the camera's `x` and `y` at the
//! point's depth) that error is `e = A^-1 r`, with `A = d(u, v) / d(x, y)` the lens's derivative
//! at the point (pixels per metre, about `f / z`; the distortion included); along the line of
//! sight a pixel says nothing. So each pixel gives a two-component error of the robot frame it
//! measures ([`crate::observe::pixel::Pixel::robot_frame`]: the point's frame, or the camera's
//! mount when the point is fixed), in metres, and the parameters' part of it,
//! `A^-1 J C J^T A^-T` (`J` the pixel's two rows' derivatives with respect to the estimated
//! parameters, the camera's and the board's among them; `C` their covariance). The model-error
//! term, a variance per axis, is fitted to these two components as to a position's three
//! ([`super::fit_growth`]).
//!
//! A pixel's length therefore holds the camera's noise at the point's depth (0.3 px at 0.45 m
//! with `f = 600` px is 0.22 mm): the bound is that of what a camera like the calibration's
//! would see, as a position's bound holds the tracker's noise.

use nalgebra::{Matrix2, Vector2};

use crate::error::{Error, Result};
use crate::linalg::Matrix;
use crate::model::camera::Camera;
use crate::model::kinematics::Target;
use crate::model::params::ParamId;
use crate::model::robot::Robot;
use crate::observe::{for_each_observation, Dataset, Observation, OrientationError, Weights};
use crate::solve::problem::Problem;

/// One pixel's error across the line of sight (internal units: m, m^2).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lateral {
    /// The posture it was seen in.
    pub posture: usize,
    /// The robot frame it measures.
    pub target: Target,
    /// `model - measured` along the camera's `x` and `y` at the point's depth (m).
    pub error: [f64; 2],
    /// The parameters' part of it, `A^-1 J C J^T A^-T` (m^2; zero without a covariance).
    pub parameters: [[f64; 2]; 2],
}

/// The pixels of `data` as errors across their lines of sight for `robot`, each with its
/// parameters' part when `covariance` (of `estimated`, internal units, in that order) is given.
/// A pixel whose point is behind its camera, or where the lens folds over (`A` singular), is
/// left out: no length across the line of sight corresponds to it.
pub fn lateral_errors(
    robot: &Robot,
    data: &Dataset,
    estimated: &[ParamId],
    covariance: Option<&[Vec<f64>]>,
) -> Result<Vec<Lateral>> {
    let pixels = Dataset::new(
        data.postures.clone(),
        data.observations
            .iter()
            .filter(|o| matches!(o, Observation::Pixel(_)))
            .cloned()
            .collect(),
    );
    if pixels.observations.is_empty() {
        return Ok(Vec::new());
    }
    let rows = covariance
        .filter(|_| !estimated.is_empty())
        .map(|c| pixel_rows(robot, &pixels, estimated, c))
        .transpose()?;
    let mut out = Vec::with_capacity(pixels.observations.len());
    for_each_observation(robot, &pixels, |i, o, frames| {
        let Observation::Pixel(p) = o else { return };
        let camera: &Camera = &robot.cameras[p.camera];
        let point = p.in_camera(robot, frames);
        if point.z < Camera::MIN_DEPTH {
            return;
        }
        let projection = camera.project(&point);
        let a = Matrix2::new(
            projection.d_point[(0, 0)],
            projection.d_point[(0, 1)],
            projection.d_point[(1, 0)],
            projection.d_point[(1, 1)],
        );
        let Some(inverse) = a.try_inverse() else {
            return;
        };
        let r = projection.uv - Vector2::new(p.uv[0], p.uv[1]);
        let e = inverse * r;
        let parameters = match &rows {
            Some(pp) => {
                let m = inverse * pp[i] * inverse.transpose();
                [[m[(0, 0)], m[(0, 1)]], [m[(1, 0)], m[(1, 1)]]]
            }
            None => [[0.0; 2]; 2],
        };
        if e.iter()
            .chain(parameters.iter().flatten())
            .all(|v| v.is_finite())
        {
            out.push(Lateral {
                posture: o.posture(),
                target: p.robot_frame(),
                error: [e.x, e.y],
                parameters,
            });
        }
    });
    Ok(out)
}

/// Per pixel of `pixels` (a data set of pixels only), `J C J^T` of its two rows (px^2).
fn pixel_rows(
    robot: &Robot,
    pixels: &Dataset,
    estimated: &[ParamId],
    covariance: &[Vec<f64>],
) -> Result<Vec<Matrix2<f64>>> {
    let n = estimated.len();
    if covariance.len() != n || covariance.iter().any(|r| r.len() != n) {
        return Err(Error::Problem(format!(
            "the covariance is not {n} x {n} (one row and column per estimated parameter)"
        )));
    }
    let problem = Problem::new(
        robot,
        pixels,
        estimated,
        Weights::default(),
        OrientationError::default(),
    );
    let mut res = vec![0.0; problem.rows()];
    let mut jac = Matrix::zeros(problem.rows(), n);
    problem.evaluate(robot, &mut res, Some(&mut jac));
    let sigma = problem.row_sigma();
    // J C (2 x n) per pixel, then times J^T.
    let mut jc = [vec![0.0; n], vec![0.0; n]];
    Ok((0..problem.rows() / 2)
        .map(|k| {
            for (i, out) in jc.iter_mut().enumerate() {
                let row = 2 * k + i;
                for (c, v) in out.iter_mut().enumerate() {
                    *v = (0..n)
                        .map(|a| jac[(row, a)] * sigma[row] * covariance[a][c])
                        .sum();
                }
            }
            Matrix2::from_fn(|i, j| {
                let row = 2 * k + j;
                (0..n).map(|c| jc[i][c] * jac[(row, c)] * sigma[row]).sum()
            })
        })
        .collect())
}
