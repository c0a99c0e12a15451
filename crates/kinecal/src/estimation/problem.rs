//! The least-squares problem: weighted residuals and their Jacobian over a dataset.

use nalgebra::Vector3;

use crate::kinematics::{
    euler_rates, log_so3, rot_zyx, so3_right_jacobian_inverse, Chain, Workspace,
};
use crate::linalg::Matrix;
use crate::measurement::Dataset;
use crate::params::ParamId;
use crate::robot::Robot;
use crate::units::wrap_angle;

/// How an orientation residual is formed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum OrientationError {
    /// Differences of the ZYX Euler angles, each wrapped to (-180, 180] deg (thesis eq. 3.1).
    #[default]
    Euler,
    /// The rotation vector of `R_measured^T R_model`: defined everywhere, including at
    /// beta = +-90 deg where Euler angles lock.
    RotVec,
}

/// The measurement standard deviations that weight the residuals (internal units).
///
/// The objective is `sum (position error / length)^2 + (angle error / angle)^2`, which makes it
/// dimensionless and the same whatever units the files use. Defaults: 1 mm and 1 mrad
/// (0.0573 deg), i.e. an attitude error of 1 mrad counts like a 1 mm error, as it would at the
/// end of a 1 m lever.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Weights {
    /// Standard deviation of a position coordinate (m).
    pub length: f64,
    /// Standard deviation of an orientation component (rad).
    pub angle: f64,
}

impl Default for Weights {
    fn default() -> Self {
        Weights {
            length: 1e-3,
            angle: 1e-3,
        }
    }
}

/// Weighted residuals and Jacobian of a calibration over one dataset.
#[derive(Clone)]
pub struct Problem<'a> {
    base: &'a Robot,
    data: &'a Dataset,
    estimated: &'a [ParamId],
    weights: Weights,
    orientation: OrientationError,
    row_scale: Option<&'a [f64]>,
}

impl<'a> Problem<'a> {
    /// Multiplies residual row `i` (and its Jacobian row) by `scale[i]`: the square roots of
    /// robust-loss weights.
    pub fn with_row_scale(mut self, scale: &'a [f64]) -> Self {
        self.row_scale = Some(scale);
        self
    }

    /// A problem estimating `estimated`, all other parameters held at `base`'s values.
    pub fn new(
        base: &'a Robot,
        data: &'a Dataset,
        estimated: &'a [ParamId],
        weights: Weights,
        orientation: OrientationError,
    ) -> Self {
        Problem {
            base,
            data,
            estimated,
            weights,
            orientation,
            row_scale: None,
        }
    }

    /// Number of residuals.
    pub fn rows(&self) -> usize {
        self.data.rows()
    }

    /// Number of estimated parameters.
    pub fn cols(&self) -> usize {
        self.estimated.len()
    }

    /// The estimated parameters.
    pub fn estimated(&self) -> &[ParamId] {
        self.estimated
    }

    /// The estimated parameters' values in `robot` (internal units).
    pub fn values(&self, robot: &Robot) -> Vec<f64> {
        self.estimated.iter().map(|&id| robot.get(id)).collect()
    }

    /// The base robot with the estimated parameters set to `x`.
    pub fn robot_at(&self, x: &[f64]) -> Robot {
        let mut r = self.base.clone();
        for (&id, &v) in self.estimated.iter().zip(x) {
            r.set(id, v);
        }
        r
    }

    /// Fills `res` (length [`Problem::rows`]) with the weighted residuals `(model - measured) /
    /// sigma` of `robot`, and, if given, `jac` (rows x cols) with their derivatives with respect
    /// to the estimated parameters. Returns the objective, the sum of squared residuals.
    pub fn evaluate(&self, robot: &Robot, res: &mut [f64], mut jac: Option<&mut Matrix>) -> f64 {
        assert_eq!(res.len(), self.rows());
        let chain = Chain::new(robot);
        let mut ws = Workspace::new(robot);
        let np = robot.param_count();
        let mut block = vec![0.0; 6 * np];
        let (wl, wa) = (1.0 / self.weights.length, 1.0 / self.weights.angle);
        let mut row = 0;
        for (posture, measurements) in self.data.by_posture() {
            chain.forward(&posture.readings, &mut ws);
            for m in measurements {
                let frame = chain.target_frame(&ws, m.target);
                let dp = frame.translation - m.position;
                for k in 0..3 {
                    res[row + k] = dp[k] * wl;
                }
                // How to map an angular velocity (global frame) to orientation-residual rates.
                let mut map = None;
                if let Some(measured) = m.orientation {
                    match self.orientation {
                        OrientationError::Euler => {
                            let e = crate::kinematics::euler_zyx(&frame.rotation);
                            for k in 0..3 {
                                res[row + 3 + k] = wrap_angle(e[k] - measured[k]) * wa;
                            }
                            map = Some(OrientationMap::Euler(e.x, e.y));
                        }
                        OrientationError::RotVec => {
                            let rm = rot_zyx(measured.x, measured.y, measured.z);
                            let phi = log_so3(&(rm.transpose() * frame.rotation));
                            for k in 0..3 {
                                res[row + 3 + k] = phi[k] * wa;
                            }
                            let m = so3_right_jacobian_inverse(&phi) * frame.rotation.transpose();
                            map = Some(OrientationMap::Matrix(m));
                        }
                    }
                }
                if let Some(jac) = jac.as_deref_mut() {
                    chain.jacobian(&ws, m.target, &mut block);
                    for (c, &id) in self.estimated.iter().enumerate() {
                        let col = &block[6 * id.0..6 * id.0 + 6];
                        for k in 0..3 {
                            jac[(row + k, c)] = col[k] * wl;
                        }
                        if let Some(map) = &map {
                            let w = Vector3::new(col[3], col[4], col[5]);
                            let d = match map {
                                OrientationMap::Euler(a, b) => euler_rates(*a, *b, &w),
                                OrientationMap::Matrix(m) => m * w,
                            };
                            for k in 0..3 {
                                jac[(row + 3 + k, c)] = d[k] * wa;
                            }
                        }
                    }
                }
                row += m.rows();
            }
        }
        if let Some(scale) = self.row_scale {
            for (i, &w) in scale.iter().enumerate() {
                res[i] *= w;
                if let Some(jac) = jac.as_deref_mut() {
                    for c in 0..jac.ncols() {
                        jac[(i, c)] *= w;
                    }
                }
            }
        }
        res.iter().map(|r| r * r).sum()
    }
}

enum OrientationMap {
    Euler(f64, f64),
    Matrix(nalgebra::Matrix3<f64>),
}

/// Unweighted accuracy of a robot on a dataset (internal units).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Accuracy {
    /// Root mean square of the 3D position errors (m).
    pub rms_position: f64,
    /// Mean 3D position error (m).
    pub mean_position: f64,
    /// 95th percentile of the 3D position errors (m; nearest rank).
    pub p95_position: f64,
    /// Largest 3D position error (m).
    pub max_position: f64,
    /// Root mean square of the attitude errors (rad): the angle of `R_measured^T R_model`, over
    /// full-pose measurements.
    pub rms_orientation: f64,
    /// Mean attitude error (rad).
    pub mean_orientation: f64,
    /// 95th percentile of the attitude errors (rad).
    pub p95_orientation: f64,
    /// Largest attitude error (rad).
    pub max_orientation: f64,
}

/// RMS, mean, 95th percentile (nearest rank) and max of non-negative errors.
fn stats(mut e: Vec<f64>) -> (f64, f64, f64, f64) {
    if e.is_empty() {
        return (0.0, 0.0, 0.0, 0.0);
    }
    e.sort_by(f64::total_cmp);
    let n = e.len() as f64;
    let rms = (e.iter().map(|x| x * x).sum::<f64>() / n).sqrt();
    let mean = e.iter().sum::<f64>() / n;
    let rank = ((0.95 * n).ceil() as usize).clamp(1, e.len());
    (rms, mean, e[rank - 1], e[e.len() - 1])
}

/// How far `robot`'s predictions are from the measurements in `data`.
pub fn accuracy(robot: &Robot, data: &Dataset) -> Accuracy {
    let chain = Chain::new(robot);
    let mut ws = Workspace::new(robot);
    let (mut ep, mut eo) = (Vec::new(), Vec::new());
    for (posture, measurements) in data.by_posture() {
        chain.forward(&posture.readings, &mut ws);
        for m in measurements {
            let f = chain.target_frame(&ws, m.target);
            ep.push((f.translation - m.position).norm());
            if let Some(meas) = m.orientation {
                let rm = rot_zyx(meas.x, meas.y, meas.z);
                eo.push(log_so3(&(rm.transpose() * f.rotation)).norm());
            }
        }
    }
    let (rms_position, mean_position, p95_position, max_position) = stats(ep);
    let (rms_orientation, mean_orientation, p95_orientation, max_orientation) = stats(eo);
    Accuracy {
        rms_position,
        mean_position,
        p95_position,
        max_position,
        rms_orientation,
        mean_orientation,
        p95_orientation,
        max_orientation,
    }
}
