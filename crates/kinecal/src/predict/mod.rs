//! Predicted accuracy: how far the calibrated robot's target will be from where its model puts
//! it, at any posture, with a 95 % bound.
//!
//! At a posture `q` the error of the calibrated model's target position (and attitude, when the
//! calibration measured attitudes) is taken as Gaussian, `e ~ N(0, S(q))`, with two parts:
//!
//! - **the parameters' uncertainty**, `J(q) C J(q)^T`: the covariance `C` of the estimated
//!   parameters ([`crate::uncertainty`]) propagated through the Jacobian of the target at `q`
//!   with respect to them ([`Chain::jacobian_columns`]);
//! - **the model error**, what the model misses (and the measurement noise of data like the
//!   calibration's): `v(d) I`, isotropic, with a variance per axis that grows with the distance
//!   `d` from `q` to the nearest measured posture,
//!
//!   `v(d) = s0^2 + (c d)^2`,
//!
//!   `d` a length ([`nearest`]: each joint's reading difference times its mean lever on the
//!   target, in quadrature). `s0` is the model error at the measured postures, `c` how fast it
//!   grows away from them (length per length). Both are estimated by cross-validation
//!   ([`cross_validate()`]): the calibration is fitted again with blocks of nearby postures held
//!   out (so that held-out postures lie at distances from the fitted ones that range from a
//!   neighbour's to a block's radius), and `s0, c` maximise the Gaussian likelihood of the
//!   held-out errors, each with its own parameter part from its fold's covariance. A single
//!   variance (`c = 0`) is what the held-out errors near the measured postures show and is too
//!   small away from them.
//!
//!   The held-out errors also give the model error's shape ([`Growth::shape`]): how unevenly
//!   it spreads over the three axes, in no assumed orientation.
//!
//! The 95 % bound is the 95th percentile of `|e|` ([`quantile`]); the report also gives the
//! bound without the model error (the parameters alone), to show what the term adds.
//!
//! `s0` is never below what the calibration's own residuals show at the measured postures
//! ([`fit_growth_floored`]: their mean square per axis less the parameters' part there), and
//! each measured target (a tree's arm, one of several reflectors) gets its own term.
//!
//! Pixels count as measurements of the frame they see move ([`pixel`]): their reprojection
//! errors, turned into lengths across the line of sight, enter the cross-validation, the floor
//! and the levers beside positions, so that a camera's calibration predicts its robot's
//! accuracy in metres.
//!
//! On the UR10 tracker data (identified on series A), 91.5 % and 93.4 % of the held-out errors
//! of series C and D fall within their bounds, 0.3 % with the parameters' part alone, and 94.2 %
//! of series A's own residuals (`tests/predict.rs`).
//!
//! Per posture nothing is allocated: a [`Scratch`] holds the frames, the Jacobian and the
//! embedding.

mod cross_validate;
mod map;
pub mod nearest;
pub mod pixel;
pub mod quantile;

use nalgebra::Vector3;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

pub use cross_validate::{
    cross_validate, fit_growth, fit_growth_floored, identification_residuals, CrossValidated,
    GrowthFit, HeldOut,
};

pub use map::{accuracy_map, AccuracyMap, JointSweep, Slice};
pub use nearest::JointMetric;
pub(crate) use nearest::NearestIndex;

use crate::error::{Error, Result};
use crate::model::kinematics::{Chain, ColumnPlan, Target, Workspace};
use crate::model::params::ParamId;
use crate::model::robot::Robot;
use crate::observe::{Dataset, Observation};
use crate::units::Quantity;

/// The largest standard deviation, model-error term (`s0`, `c`) and joint lever a prediction
/// takes, in its own units: 1e12 (10^9 m in millimetres: a million kilometres). The predicted
/// variance raises them to the fourth power with the readings (at most 1e9, as the measurement
/// files read them): at most about 1e140, finite; a standard deviation near 1e308 made the
/// report's pictures loop for ever. Reports are held to it when read
/// (`crate::report::validate`).
pub const MAX_SPREAD: f64 = 1e12;

/// A model-error term: mean per-axis variance `v(d) = s0^2 + (c d)^2` at distance `d`
/// (internal units: `s0` in m or rad, `c` in m or rad per m of distance), spread over the axes
/// as unevenly as `shape` says.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Growth {
    /// At the measured postures.
    pub s0: f64,
    /// Growth per unit of distance.
    pub c: f64,
    /// How unevenly the error spreads over the three axes: `tr L^2` of its covariance's shape
    /// `L` normalised to `tr L = 3` (3: evenly, isotropic; 9: along one axis), in no assumed
    /// orientation. The 95 % bound of an uneven error is wider than an even one of the same
    /// variance (up to 1.96 / 1.61 = 1.21 times).
    pub shape: f64,
}

impl Growth {
    /// No model error.
    pub const ZERO: Growth = Growth {
        s0: 0.0,
        c: 0.0,
        shape: 3.0,
    };

    /// The variance per axis at distance `d`.
    #[inline]
    pub fn variance(&self, d: f64) -> f64 {
        self.s0 * self.s0 + self.c * self.c * d * d
    }
}

/// The model-error terms of position and, when attitudes were measured, attitude.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModelError {
    /// Position (m, m/m).
    pub position: Growth,
    /// Attitude (rad, rad/m), when predicted.
    pub attitude: Option<Growth>,
}

impl ModelError {
    /// No model error (the parameters' uncertainty alone); attitude predicted when `attitude`.
    pub fn none(attitude: bool) -> ModelError {
        ModelError {
            position: Growth::ZERO,
            attitude: attitude.then_some(Growth::ZERO),
        }
    }
}

/// The frame whose position `o` measures, for a prediction: a position's or a pose's target,
/// or the robot frame a pixel sees move; `None` for the kinds that measure no position
/// (distances, contacts).
pub(crate) fn measured_frame(o: &Observation) -> Option<Target> {
    match o {
        Observation::Position(_) | Observation::Pose(_) => Some(o.target()),
        Observation::Pixel(p) => Some(p.robot_frame()),
        _ => None,
    }
}

/// The predicted error of one quantity (position or attitude) at a posture (internal units).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Bound {
    /// The RMS length of the parameters' part, `sqrt(tr J C J^T)`.
    pub parameters: f64,
    /// The RMS length of the model-error part, `sqrt(3 v(d))`.
    pub model: f64,
    /// The 95 % bound on the error's length, both parts together.
    pub bound: f64,
    /// The 95 % bound of the parameters' part alone.
    pub parameters_bound: f64,
}

impl Bound {
    /// The bound of `p` (the parameters' 3x3 covariance) plus a model error `M` of mean
    /// per-axis variance `v` and [`Growth::shape`] `shape`: `tr S = tr P + 3 v`, `tr S^2 =
    /// tr P^2 + 2 v tr P + shape v^2` (the cross term `2 tr(P M)` averaged over the
    /// orientations of `M`, which is not assumed; exact when either part is isotropic).
    #[inline]
    pub fn of(p: &[[f64; 3]; 3], v: f64, shape: f64) -> Bound {
        let (t, t2) = quantile::traces(p);
        Bound {
            parameters: t.max(0.0).sqrt(),
            model: (3.0 * v).sqrt(),
            bound: quantile::bound_95(t + 3.0 * v, t2 + 2.0 * v * t + shape * v * v),
            parameters_bound: quantile::bound_95(t, t2),
        }
    }

    /// The bound of an error measured across a line of sight (two components, a pixel's:
    /// [`pixel`]): `p` the parameters' covariance in those axes, zero along the third, plus an
    /// isotropic model error of variance `v` per axis in the two.
    #[inline]
    pub fn across(p: &[[f64; 3]; 3], v: f64) -> Bound {
        let (t, t2) = quantile::traces(p);
        Bound {
            parameters: t.max(0.0).sqrt(),
            model: (2.0 * v).sqrt(),
            bound: quantile::bound_95(t + 2.0 * v, t2 + 2.0 * v * t + 2.0 * v * v),
            parameters_bound: quantile::bound_95(t, t2),
        }
    }
}

/// The prediction at one posture (internal units).
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct Prediction {
    /// Where the calibrated model puts the target (global frame, m).
    pub position: Vector3<f64>,
    /// The distance to the nearest measured posture (m; see [`nearest`]).
    pub distance: f64,
    /// The position error.
    pub position_error: Bound,
    /// The attitude error (rad), when predicted.
    pub attitude_error: Option<Bound>,
}

/// What a [`Predictor`] needs per posture (reuse it: nothing is allocated per posture).
#[derive(Debug, Clone)]
pub struct Scratch {
    ws: Workspace,
    jac: Vec<f64>,
    jf: Vec<f64>,
    embedded: Vec<f64>,
}

/// Predicts the calibrated robot's error at postures (see the module).
#[derive(Debug, Clone)]
pub struct Predictor<'r> {
    chain: Chain<'r>,
    /// The column plan of the end effector, then of each site.
    plans: Vec<ColumnPlan>,
    /// `C = F F^T`, `F` column-major `n x r` (internal units).
    factor: Vec<f64>,
    n: usize,
    r: usize,
    /// The model-error term of the end effector, then of each site.
    models: Vec<ModelError>,
    metric: JointMetric,
    tree: NearestIndex,
}

impl<'r> Predictor<'r> {
    /// A predictor for `robot` (calibrated), whose parameters `estimated` have the covariance
    /// `covariance` (internal units, in that order), with the model error `model`, the metric
    /// `metric` and the measured postures `measured` (readings).
    pub fn new<'a>(
        robot: &'r Robot,
        estimated: &[ParamId],
        covariance: &[Vec<f64>],
        model: ModelError,
        metric: JointMetric,
        measured: impl IntoIterator<Item = &'a [f64]>,
    ) -> Result<Predictor<'r>> {
        let n = estimated.len();
        if let Some(j) = metric.levers().iter().position(|l| !lever_plausible(*l)) {
            return Err(Error::Problem(format!(
                "the lever of joint {} is {} m per reading unit: expected at least 0 and at most \
                 {:e}",
                j + 1,
                crate::units::number::format_number(metric.levers()[j]),
                MAX_SPREAD
            )));
        }
        if covariance.len() != n || covariance.iter().any(|r| r.len() != n) {
            return Err(Error::Problem(format!(
                "the covariance is not {n} x {n} (one row and column per estimated parameter)"
            )));
        }
        if covariance.iter().flatten().any(|v| !v.is_finite()) {
            return Err(Error::Problem(
                "the covariance has a value that is not finite".into(),
            ));
        }
        if let Some(id) = estimated.iter().find(|id| id.0 >= robot.param_count()) {
            return Err(Error::Problem(format!(
                "parameter {id} is not one of this robot's"
            )));
        }
        let (factor, r) = symmetric_factor(covariance);
        let mut columns = vec![None; robot.param_count()];
        for (k, id) in estimated.iter().enumerate() {
            columns[id.0] = Some(k);
        }
        let mut plans = vec![ColumnPlan::new(robot, Target::EndEffector, &columns)];
        for s in 0..robot.sites.len() {
            plans.push(ColumnPlan::new(robot, Target::Site(s), &columns));
        }
        let dims = metric.dims();
        let mut points = Vec::new();
        let mut e = vec![0.0; dims];
        for readings in measured {
            if readings.len() != robot.dof() {
                return Err(Error::Problem(format!(
                    "a measured posture has {} readings; the robot has {} joints",
                    readings.len(),
                    robot.dof()
                )));
            }
            metric.embed(readings, &mut e);
            points.extend_from_slice(&e);
            if dims == 0 {
                // No joint moves the target but joint 1: every posture is at distance 0.
                points.push(0.0);
            }
        }
        if points.iter().any(|v| !v.is_finite()) {
            return Err(Error::Problem(
                "a measured posture's reading is not finite".into(),
            ));
        }
        let tree = NearestIndex::new(dims.max(1), &points);
        if tree.is_empty() {
            return Err(Error::Problem(
                "no measured posture to measure distances from".into(),
            ));
        }
        Ok(Predictor {
            chain: Chain::new(robot),
            plans,
            factor,
            n,
            r,
            models: vec![model; 1 + robot.sites.len()],
            metric,
            tree,
        })
    }

    /// Predicts `target` with a model-error term of its own (a tree's arm, one of several
    /// reflectors); `model` must predict attitudes when the others do.
    pub fn set_target_model(&mut self, target: Target, model: ModelError) -> Result<()> {
        if model.attitude.is_some() != self.models[0].attitude.is_some() {
            return Err(Error::Problem(
                "a target's model-error term must predict attitudes when the others do".into(),
            ));
        }
        let k = target_index(target);
        let slot = self.models.get_mut(k).ok_or_else(|| {
            Error::Problem(format!("target {k} is not one of this robot's frames"))
        })?;
        *slot = model;
        Ok(())
    }

    /// The model-error term of `target`.
    pub fn model(&self, target: Target) -> &ModelError {
        &self.models[target_index(target).min(self.models.len() - 1)]
    }

    /// The robot.
    pub fn robot(&self) -> &'r Robot {
        self.chain.robot()
    }

    /// The metric.
    pub fn metric(&self) -> &JointMetric {
        &self.metric
    }

    /// A scratch space for [`Predictor::predict`].
    pub fn scratch(&self) -> Scratch {
        Scratch {
            ws: Workspace::new(self.robot()),
            jac: vec![0.0; 6 * self.n.max(1)],
            jf: vec![0.0; 6 * self.r.max(1)],
            embedded: vec![0.0; self.metric.dims().max(1)],
        }
    }

    /// The distance from `readings` to the nearest measured posture (m).
    pub fn distance(&self, readings: &[f64], scratch: &mut Scratch) -> f64 {
        self.metric.embed(readings, &mut scratch.embedded);
        self.tree.nearest(&scratch.embedded).map_or(0.0, |x| x.1)
    }

    /// The prediction for `target` at `readings` (one per joint, finite).
    pub fn predict(&self, readings: &[f64], target: Target, s: &mut Scratch) -> Prediction {
        let distance = self.distance(readings, s);
        let (p, a, position) = self.parameter_part(readings, target, s);
        let model = self.model(target);
        Prediction {
            position,
            distance,
            position_error: Bound::of(&p, model.position.variance(distance), model.position.shape),
            attitude_error: model
                .attitude
                .map(|g| Bound::of(&a, g.variance(distance), g.shape)),
        }
    }

    /// The covariances of the target's position and attitude (global frame) from the
    /// parameters' uncertainty alone, and the target's position.
    pub(crate) fn parameter_part(
        &self,
        readings: &[f64],
        target: Target,
        s: &mut Scratch,
    ) -> ([[f64; 3]; 3], [[f64; 3]; 3], Vector3<f64>) {
        self.chain.forward(readings, &mut s.ws);
        let frame = self.chain.target_frame(&s.ws, target);
        let plan = match target {
            Target::EndEffector => &self.plans[0],
            Target::Site(k) => &self.plans[1 + k],
        };
        let (n, r) = (self.n, self.r);
        let (mut p, mut a) = ([[0.0; 3]; 3], [[0.0; 3]; 3]);
        if n > 0 && r > 0 {
            self.chain
                .jacobian_columns(&s.ws, plan, &mut s.jac[..6 * n]);
            // JF (6 x r, column-major).
            for k in 0..r {
                let f = &self.factor[k * n..(k + 1) * n];
                let out = &mut s.jf[6 * k..6 * k + 6];
                out.fill(0.0);
                for (c, &fc) in f.iter().enumerate() {
                    if fc != 0.0 {
                        let col = &s.jac[6 * c..6 * c + 6];
                        for i in 0..6 {
                            out[i] += col[i] * fc;
                        }
                    }
                }
            }
            for k in 0..r {
                let col = &s.jf[6 * k..6 * k + 6];
                for i in 0..3 {
                    for j in 0..3 {
                        p[i][j] += col[i] * col[j];
                        a[i][j] += col[3 + i] * col[3 + j];
                    }
                }
            }
        }
        (p, a, frame.translation)
    }
}

/// Whether `l` can be a joint's lever (length per reading unit): at least 0 and at most
/// [`MAX_SPREAD`]. A lever of 1e308 made the distances to the measured
/// postures infinite, and the search for the nearest one index past its points.
fn lever_plausible(l: f64) -> bool {
    (0.0..=MAX_SPREAD).contains(&l)
}

/// The index of `target` among a robot's frames: 0 the end effector, `1 + s` site `s`.
fn target_index(target: Target) -> usize {
    match target {
        Target::EndEffector => 0,
        Target::Site(s) => 1 + s,
    }
}

/// A factor `F` (column-major `n x r`) with `C = F F^T`, from the eigenvalues of the symmetric
/// `C` above 1e-13 of the largest (negative rounding dropped).
fn symmetric_factor(c: &[Vec<f64>]) -> (Vec<f64>, usize) {
    let n = c.len();
    if n == 0 {
        return (Vec::new(), 0);
    }
    let m = nalgebra::DMatrix::from_fn(n, n, |i, j| 0.5 * (c[i][j] + c[j][i]));
    let eig = m.symmetric_eigen();
    let top = eig.eigenvalues.iter().cloned().fold(0.0, f64::max);
    let mut f = Vec::new();
    let mut r = 0;
    for k in 0..n {
        let l = eig.eigenvalues[k];
        if l > 1e-13 * top && l > 0.0 {
            let s = l.sqrt();
            f.extend((0..n).map(|i| eig.eigenvectors[(i, k)] * s));
            r += 1;
        }
    }
    (f, r)
}

/// The levers of `robot`'s joints on the targets `data` measures (positions and poses): the
/// root mean square over those observations of the norm of the position rows of the reading
/// Jacobian, m per reading unit (see [`nearest`]). A revolute first joint gets none: it turns
/// the whole arm, and the model's errors with it, so the size of the error does not depend on
/// its reading (what the model misses downstream of it is `R1(q1) e(q2..qn)`, of a length
/// independent of `q1`).
pub fn levers(robot: &Robot, data: &Dataset) -> Vec<f64> {
    let dof = robot.dof();
    let chain = Chain::new(robot);
    let mut ws = Workspace::new(robot);
    let mut jac = vec![0.0; 6 * dof];
    let mut sum = vec![0.0; dof];
    let mut count = 0usize;
    for o in &data.observations {
        let Some(target) = measured_frame(o) else {
            continue;
        };
        let p = &data.postures[o.posture()];
        chain.forward_loaded(&p.readings, None, p.payload.as_ref(), &mut ws);
        chain.reading_jacobian(&ws, target, &mut jac);
        for (j, s) in sum.iter_mut().enumerate() {
            let c = &jac[6 * j..6 * j + 3];
            *s += c[0] * c[0] + c[1] * c[1] + c[2] * c[2];
        }
        count += 1;
    }
    let first_turns = robot.joints[0].kind == crate::model::robot::JointKind::Revolute;
    sum.iter()
        .enumerate()
        .map(|(j, s)| {
            if j == 0 && first_turns {
                0.0
            } else {
                (s / count.max(1) as f64).sqrt()
            }
        })
        .collect()
}

/// Whether `data` has observations a prediction is made for (positions, poses or pixels), and
/// whether any of them is a pose (then attitudes are predicted too).
pub(crate) fn predictable(data: &Dataset) -> (bool, bool) {
    let any = data
        .observations
        .iter()
        .any(|o| measured_frame(o).is_some());
    let pose = data
        .observations
        .iter()
        .any(|o| matches!(o, Observation::Pose(_)));
    (any, pose)
}

/// The target a calibration's predictions are made for by default: the one its data measures
/// most often (the end effector on a tie).
pub(crate) fn default_target(robot: &Robot, data: &Dataset) -> Target {
    let mut counts = vec![0usize; robot.sites.len() + 1];
    for o in data.observations.iter().filter_map(measured_frame) {
        counts[target_index(o)] += 1;
    }
    let best = (0..counts.len())
        .max_by_key(|&k| (counts[k], usize::MAX - k))
        .unwrap_or(0);
    if best == 0 {
        Target::EndEffector
    } else {
        Target::Site(best - 1)
    }
}

/// The reading range a joint's predictions are sampled in: its `min..max` from the robot file,
/// else the readings that turn a revolute joint +-150 deg, or move a prismatic one +-0.1 m (as
/// `kinecal simulate` draws them).
pub fn reading_range(robot: &Robot, joint: usize) -> (f64, f64) {
    let j = &robot.joints[joint];
    if let Some(r) = j.range {
        return r;
    }
    let span = match j.kind {
        crate::model::robot::JointKind::Revolute => 150f64.to_radians(),
        crate::model::robot::JointKind::Prismatic => 0.1,
    };
    let half = if j.slope != 0.0 {
        span / j.slope.abs()
    } else {
        1.0
    };
    (-half, half)
}

/// `count` postures drawn uniformly in the joints' [`reading_range`]s (ChaCha8, `seed`),
/// concatenated (`dof` readings each).
pub fn sample_readings(robot: &Robot, count: usize, seed: u64) -> Vec<f64> {
    use rand::{RngExt, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed ^ 0x9e37_79b9_7f4a_7c15);
    let ranges: Vec<(f64, f64)> = (0..robot.dof()).map(|j| reading_range(robot, j)).collect();
    let mut out = Vec::with_capacity(count * robot.dof());
    for _ in 0..count {
        for &(a, b) in &ranges {
            out.push(if b > a { rng.random_range(a..=b) } else { a });
        }
    }
    out
}

/// The model-error term of one quantity in a report (the robot file's units).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
#[non_exhaustive]
pub struct GrowthReport {
    /// Per-axis standard deviation at the measured postures (length or angle unit).
    pub s0: f64,
    /// Its growth per length unit of distance from them (length unit per length unit, or angle
    /// unit per length unit).
    pub c: f64,
    /// How unevenly the error spreads over the axes (3: evenly; 9: along one axis; see
    /// [`Growth::shape`]).
    pub shape: f64,
    /// The floor of `s0`: what the calibrated model's residuals at the measured postures (of
    /// this target) show, per axis (their mean square less the parameters' part there,
    /// `tr J C J^T / 3`); `s0` is never below it.
    #[serde(default)]
    pub s0_floor: f64,
    /// The held-out observations of the cross-validation it was estimated from.
    pub points: usize,
    /// The share of them within their 95 % bound, with this term.
    pub coverage: f64,
    /// The same with a single variance fitted instead (`c = 0`, `s0` by maximum likelihood).
    pub coverage_constant: f64,
    /// The single variance's `s0`.
    pub s0_constant: f64,
    /// The same with the parameters' uncertainty alone (no model-error term).
    pub coverage_parameters_only: f64,
    /// The median and largest distance of the held-out postures from the fitted ones (length
    /// unit).
    pub distance_median: f64,
    /// See `distance_median`.
    pub distance_max: f64,
}

/// The model-error terms of one measured target (a tree's arm, one of several reflectors).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
#[non_exhaustive]
pub struct TargetModelError {
    /// The target: `ee` or a site's name.
    pub target: String,
    /// Its position model-error term.
    pub position: GrowthReport,
    /// Its attitude model-error term, when attitudes were measured.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub attitude: Option<GrowthReport>,
}

/// The median and 95th percentile of the predicted 95 % bound over postures drawn in the joint
/// ranges (the robot file's units).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
#[non_exhaustive]
pub struct BoundSummary {
    /// Median (length or angle unit).
    pub median: f64,
    /// 95th percentile.
    pub p95: f64,
    /// The same at the measured postures themselves (median).
    pub median_measured: f64,
}

/// What a calibration predicts of its accuracy: everything `kinecal predict` needs (with the
/// calibrated robot) and the figures the report shows. The robot file's units throughout.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
#[non_exhaustive]
pub struct PredictionReport {
    /// The target predicted by default (`ee` or a site's name).
    pub target: String,
    /// The estimated parameters (ids), in the order of `covariance`.
    pub estimated: Vec<String>,
    /// Their covariance (entry `(a, b)` in the unit of parameter `a` times that of `b`).
    pub covariance: Vec<Vec<f64>>,
    /// Each joint's lever on the target (length unit per reading unit): the joint-space
    /// distance's weights.
    pub levers: Vec<f64>,
    /// The measured postures' readings (the distances are to the nearest of them).
    pub measured: Vec<Vec<f64>>,
    /// The position model-error term.
    pub position: GrowthReport,
    /// The attitude model-error term, when attitudes were measured.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub attitude: Option<GrowthReport>,
    /// When the data measures more than one target (a tree's arms, several reflectors), each
    /// one's own terms (fitted to its own held-out errors when it has at least 20 postures, floored by
    /// its own residuals); a prediction at a target uses its own. `position` and `attitude`
    /// are the default target's.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub targets: Vec<TargetModelError>,
    /// The blocks of nearby postures of each scale of the cross-validation.
    pub folds: Vec<usize>,
    /// Postures drawn in the joint ranges for the summary (seed 0).
    pub samples: usize,
    /// The predicted 95 % position bound over them.
    pub position_summary: BoundSummary,
    /// The predicted 95 % attitude bound over them, when attitudes are predicted.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub attitude_summary: Option<BoundSummary>,
    /// The accuracy map, when made.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub map: Option<AccuracyMap>,
}

/// How much of the prediction a calibration makes. Off unless asked for (`--predict`, an HTML
/// report): its cross-validation costs many times a fit of a thousand postures.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[non_exhaustive]
pub enum Level {
    /// None.
    #[default]
    Off,
    /// The model-error term and the summary over the joint ranges.
    Summary,
    /// And the accuracy map (for the HTML report).
    Map,
}

/// Postures drawn for the summary.
pub(crate) const SUMMARY_SAMPLES: usize = 2000;

/// Postures drawn for the accuracy map (each vertical slice predicts them again, turned into
/// its plane).
pub(crate) const MAP_SAMPLES: usize = 12_000;

/// The fewest postures measured by position or pose for a prediction (the cross-validation
/// needs blocks of several).
pub const MIN_POSTURES: usize = 20;

/// The folds of the cross-validation's fine scale (fewer with fewer than 40 postures).
pub(crate) const FOLDS: usize = 10;

/// The folds of its coarse scale (a third of the measured region held out at a time).
pub(crate) const COARSE_FOLDS: usize = 3;

/// Everything a calibration predicts (see the module): the model-error term by
/// cross-validation (refitting `cal` on folds of `data`, linearised at `reference`), the
/// summary over the joint ranges and, at [`Level::Map`], the accuracy map. `covariance` is the
/// calibration's (internal units, in the order of `estimated`).
pub fn assess(
    cal: &crate::solve::estimation::Calibration,
    data: &Dataset,
    reference: &Robot,
    estimated: &[ParamId],
    covariance: &[Vec<f64>],
    level: Level,
) -> Result<PredictionReport> {
    assess_with(
        cal,
        data,
        reference,
        estimated,
        covariance,
        level,
        &mut |_| {},
    )
}

/// [`assess`], saying what it does (`prediction: fold 4 of 13`, `prediction: the accuracy
/// map`) to `say`: its cross-validation refits the calibration some 13 times.
pub(crate) fn assess_with(
    cal: &crate::solve::estimation::Calibration,
    data: &Dataset,
    reference: &Robot,
    estimated: &[ParamId],
    covariance: &[Vec<f64>],
    level: Level,
    say: &mut dyn FnMut(&str),
) -> Result<PredictionReport> {
    let robot = &cal.calibrated;
    let (any, pose) = predictable(data);
    let measured: Vec<&[f64]> = measured_postures(data);
    if !any || measured.len() < MIN_POSTURES {
        return Err(Error::TooFewPostures {
            needed: MIN_POSTURES,
            found: measured.len(),
        });
    }
    let metric = JointMetric::new(robot, &levers(robot, data));
    let mut folds = vec![FOLDS.min(measured.len() / 4).max(2), COARSE_FOLDS];
    folds.dedup();
    let cv = cross_validate::cross_validate_with(cal, data, reference, &metric, &folds, say)?;
    // Each measured target's own term, its `s0` at least what the calibrated model's residuals
    // show there; the default target's is the report's `position` and `attitude`.
    let target = default_target(robot, data);
    let att = pose && !cv.attitude.is_empty();
    let mut predictor = Predictor::new(
        robot,
        estimated,
        covariance,
        ModelError::none(att),
        metric.clone(),
        measured.iter().copied(),
    )?;
    let residuals = identification_residuals(robot, data);
    let held = held_parts(
        robot,
        data,
        estimated,
        covariance,
        &predictor,
        residuals.len(),
    )?;
    let terms = target_terms(&residuals, &held, &cv, folds.len(), att);
    let Some(default_k) = terms.iter().position(|x| x.target == target) else {
        return Err(Error::Problem(
            "the default target has no measured position or pose".into(),
        ));
    };
    let (position, attitude) = (terms[default_k].position, terms[default_k].attitude);
    for x in &terms {
        predictor.set_target_model(
            x.target,
            ModelError {
                position: x.position.growth,
                attitude: x.attitude.as_ref().map(|a| a.growth),
            },
        )?;
    }
    let units = &robot.units;
    let len = |v: f64| units.from_si(Quantity::Length, v);
    say("prediction: the bound over the joint ranges");
    let samples = sample_readings(robot, SUMMARY_SAMPLES, 0);
    let summarise =
        |attitude: bool| bound_summary(&predictor, target, &measured, &samples, robot, attitude);
    let position_summary = summarise(false);
    let attitude_summary = pose.then(|| summarise(true));
    let map = (level == Level::Map).then(|| {
        say("prediction: the accuracy map");
        accuracy_map(&predictor, target, &measured, MAP_SAMPLES, 0)
    });
    Ok(PredictionReport {
        target: crate::observe::target_name(robot, target).to_string(),
        estimated: estimated.iter().map(ToString::to_string).collect(),
        covariance: covariance_in_units(robot, estimated, covariance),
        levers: metric.levers().iter().map(|&l| len(l)).collect(),
        measured: measured.iter().map(|r| r.to_vec()).collect(),
        position: growth_report(&position, false, terms[default_k].floor_position, units),
        attitude: attitude
            .as_ref()
            .map(|a| growth_report(a, true, terms[default_k].floor_attitude, units)),
        targets: target_reports(robot, &terms),
        folds,
        samples: SUMMARY_SAMPLES,
        position_summary,
        attitude_summary,
        map,
    })
}

/// Per target (0 the end effector, `k` site `k - 1`), what the parameters' part of the bound
/// already holds at the measured postures: `(position sum, attitude sum, position count,
/// attitude count)`, each term a third of `tr J C J^T` (a pixel's half the trace across its
/// line of sight), in squared internal units.
fn held_parts(
    robot: &Robot,
    data: &Dataset,
    estimated: &[ParamId],
    covariance: &[Vec<f64>],
    predictor: &Predictor<'_>,
    targets: usize,
) -> Result<Vec<(f64, f64, usize, usize)>> {
    let mut held = vec![(0.0, 0.0, 0usize, 0usize); targets];
    // A pixel's part is across its line of sight: per axis, half its trace.
    for l in pixel::lateral_errors(robot, data, estimated, Some(covariance))? {
        let h = &mut held[target_index(l.target)];
        h.0 += 0.5 * (l.parameters[0][0] + l.parameters[1][1]);
        h.2 += 1;
    }
    let mut s = predictor.scratch();
    for o in &data.observations {
        let is_pose = match o {
            Observation::Position(_) => false,
            Observation::Pose(_) => true,
            _ => continue,
        };
        let t = o.target();
        let (p, a, _) = predictor.parameter_part(&data.postures[o.posture()].readings, t, &mut s);
        let h = &mut held[target_index(t)];
        h.0 += (p[0][0] + p[1][1] + p[2][2]) / 3.0;
        h.2 += 1;
        if is_pose {
            h.1 += (a[0][0] + a[1][1] + a[2][2]) / 3.0;
            h.3 += 1;
        }
    }
    Ok(held)
}

/// One measured target's model-error terms, and the floors under their `s0` (internal units).
struct TargetTerm {
    target: Target,
    position: GrowthFit,
    attitude: Option<GrowthFit>,
    floor_position: f64,
    floor_attitude: f64,
}

/// Each measured target's own term, its `s0` at least what the calibrated model's residuals
/// show there: per axis, the residuals' mean square (`residuals`, per target as
/// [`identification_residuals`] gives them) less what the parameters' part of the bound
/// already holds (`held`, [`held_parts`]), so that the bound at the measured postures is at
/// least the residuals' size. A target held out fewer than [`MIN_POSTURES`] times per scale
/// (`scales` of them) is fitted on every target's held-out errors, floored by its own
/// residuals; `attitude` says whether attitudes have a term.
fn target_terms(
    residuals: &[(usize, f64, f64)],
    held: &[(f64, f64, usize, usize)],
    cv: &CrossValidated,
    scales: usize,
    attitude: bool,
) -> Vec<TargetTerm> {
    let mut terms = Vec::new();
    for (k, &(count, p2, a2)) in residuals.iter().enumerate() {
        if count == 0 {
            continue;
        }
        let t = if k == 0 {
            Target::EndEffector
        } else {
            Target::Site(k - 1)
        };
        let mean = |sum: f64, n: usize| if n > 0 { sum / n as f64 } else { 0.0 };
        let floor_p = (p2 - mean(held[k].0, held[k].2)).max(0.0).sqrt();
        let floor_a = (a2 - mean(held[k].1, held[k].3)).max(0.0).sqrt();
        let own = |v: &[HeldOut]| -> Vec<HeldOut> {
            v.iter().filter(|h| h.target == t).copied().collect()
        };
        let (mut position, mut attitudes) = (own(&cv.position), own(&cv.attitude));
        // Too few held out at this target for a term of its own (fewer than MIN_POSTURES
        // postures: each is held out once per scale): all of them, floored by its residuals.
        let fewest = MIN_POSTURES * scales;
        if position.len() < fewest {
            position = cv.position.clone();
        }
        if attitudes.len() < fewest {
            attitudes = cv.attitude.clone();
        }
        terms.push(TargetTerm {
            target: t,
            position: fit_growth_floored(&position, floor_p),
            attitude: attitude.then(|| fit_growth_floored(&attitudes, floor_a)),
            floor_position: floor_p,
            floor_attitude: floor_a,
        });
    }
    terms
}

/// The predicted 95 % bound of `target`'s position (or attitude) over `samples` (readings,
/// `robot.dof()` a sample) and at the `measured` postures: medians and 95th percentile, in
/// the robot's units.
fn bound_summary(
    predictor: &Predictor<'_>,
    target: Target,
    measured: &[&[f64]],
    samples: &[f64],
    robot: &Robot,
    attitude: bool,
) -> BoundSummary {
    let mut s = predictor.scratch();
    let dof = robot.dof();
    // The predicted 95 % bound at readings `r`: of the attitude or of the position.
    let mut bound = |r: &[f64]| {
        let p = predictor.predict(r, target, &mut s);
        if attitude {
            p.attitude_error.map_or(0.0, |b| b.bound)
        } else {
            p.position_error.bound
        }
    };
    let mut bounds: Vec<f64> = samples.chunks(dof).map(&mut bound).collect();
    let mut at: Vec<f64> = measured.iter().map(|r| bound(r)).collect();
    let quantity = if attitude {
        Quantity::Angle
    } else {
        Quantity::Length
    };
    let conv = |v: f64| robot.units.from_si(quantity, v);
    BoundSummary {
        median: conv(percentile(&mut bounds, 0.5)),
        p95: conv(percentile(&mut bounds, 0.95)),
        median_measured: conv(percentile(&mut at, 0.5)),
    }
}

/// The parameters' covariance (internal units, in the order of `estimated`) in the robot's
/// units.
fn covariance_in_units(
    robot: &Robot,
    estimated: &[ParamId],
    covariance: &[Vec<f64>],
) -> Vec<Vec<f64>> {
    let f: Vec<f64> = estimated
        .iter()
        .map(|&id| robot.units.factor(robot.param_quantity(id)))
        .collect();
    covariance
        .iter()
        .zip(&f)
        .map(|(row, fa)| row.iter().zip(&f).map(|(c, fb)| c / (fa * fb)).collect())
        .collect()
}

/// Each target's terms as reported, when there are several targets (none when one).
fn target_reports(robot: &Robot, terms: &[TargetTerm]) -> Vec<TargetModelError> {
    if terms.len() <= 1 {
        return Vec::new();
    }
    let units = &robot.units;
    terms
        .iter()
        .map(|x| TargetModelError {
            target: crate::observe::target_name(robot, x.target).to_string(),
            position: growth_report(&x.position, false, x.floor_position, units),
            attitude: x
                .attitude
                .as_ref()
                .map(|a| growth_report(a, true, x.floor_attitude, units)),
        })
        .collect()
}

/// A model-error term fitted by cross-validation as reported, in `units` (`angle`: an
/// attitude's), with `residuals` the floor under its `s0` (internal units).
fn growth_report(
    g: &GrowthFit,
    angle: bool,
    residuals: f64,
    units: &crate::units::Units,
) -> GrowthReport {
    let len = |v: f64| units.from_si(Quantity::Length, v);
    let q = |v: f64| {
        if angle {
            units.from_si(Quantity::Angle, v)
        } else {
            len(v)
        }
    };
    GrowthReport {
        s0: q(g.growth.s0),
        s0_floor: q(residuals),
        // Per length unit of distance.
        c: q(g.growth.c) / len(1.0),
        shape: g.growth.shape,
        points: g.points,
        coverage: g.coverage,
        coverage_constant: g.coverage_constant,
        s0_constant: q(g.s0_constant),
        coverage_parameters_only: g.coverage_parameters_only,
        distance_median: len(g.distance_median),
        distance_max: len(g.distance_max),
    }
}

/// The readings of the postures `data` measures by position, pose or pixel, in posture order.
pub(crate) fn measured_postures(data: &Dataset) -> Vec<&[f64]> {
    let mut seen = vec![false; data.postures.len()];
    for o in &data.observations {
        if measured_frame(o).is_some() {
            seen[o.posture()] = true;
        }
    }
    data.postures
        .iter()
        .zip(&seen)
        .filter(|(_, s)| **s)
        .map(|(p, _)| p.readings.as_slice())
        .collect()
}

/// The `q` quantile (nearest rank) of `v` (sorted in place); 0 for an empty slice.
pub(crate) fn percentile(v: &mut [f64], q: f64) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    let rank = ((q * v.len() as f64).ceil() as usize).clamp(1, v.len());
    v[rank - 1]
}

/// The header of the predictions table `kinecal predict` writes: the posture and its readings,
/// where the target is (`x, y, z`), the distance to the nearest measured posture, and per
/// quantity the RMS lengths of the parameters' and the model error's parts, the 95 % bound, and
/// the 95 % bound of the parameters alone (the robot file's units). With `sites`, each row's
/// target follows the posture (`site`).
pub(crate) fn csv_header(robot: &Robot, attitude: bool, sites: bool) -> String {
    let mut h = String::from("posture");
    if sites {
        h += ",site";
    }
    for j in 1..=robot.dof() {
        h += &format!(",v{j}");
    }
    h += ",x,y,z,distance,position_parameters,position_model,position_bound95,position_bound95_parameters";
    if attitude {
        h += ",attitude_parameters,attitude_model,attitude_bound95,attitude_bound95_parameters";
    }
    h
}

/// One row of the predictions table ([`csv_header`]), appended to `out` with its line end
/// (`site`: its target, when the table has the column). Numbers are written as `kinecal fk`
/// writes a posture's row ([`crate::units::number`]): the readings and the position with the
/// row's scales (float noise and `-0` as 0), the figures exactly.
pub(crate) fn csv_row(
    robot: &Robot,
    label: &str,
    site: Option<&str>,
    readings: &[f64],
    p: &Prediction,
    out: &mut String,
) {
    use crate::units::number::{format_number, write, Scale};
    let units = &robot.units;
    let len = |v: f64| units.from_si(Quantity::Length, v);
    let ang = |v: f64| units.from_si(Quantity::Angle, v);
    out.push_str(label);
    if let Some(site) = site {
        out.push(',');
        out.push_str(site);
    }
    crate::files::write_posture_readings(robot, out, readings);
    let position = [p.position.x, p.position.y, p.position.z].map(len);
    let scale = Scale::of(position);
    for v in position {
        out.push(',');
        out.push_str(&write(v, scale));
    }
    let e = &p.position_error;
    let mut figures = vec![
        len(p.distance),
        len(e.parameters),
        len(e.model),
        len(e.bound),
        len(e.parameters_bound),
    ];
    if let Some(a) = &p.attitude_error {
        figures.extend([a.parameters, a.model, a.bound, a.parameters_bound].map(ang));
    }
    for v in figures {
        out.push(',');
        out.push_str(&format_number(v));
    }
    out.push('\n');
}

/// A predictor from a calibrated robot and its report's prediction (file units converted).
/// Refuses a report whose parameters are not this robot's.
pub fn from_report<'r>(robot: &'r Robot, report: &PredictionReport) -> Result<Predictor<'r>> {
    let units = &robot.units;
    let mut estimated = Vec::with_capacity(report.estimated.len());
    for s in &report.estimated {
        let id = crate::model::param_list::parse_param_list(s, robot)?;
        match id.as_slice() {
            [id] => estimated.push(*id),
            _ => {
                return Err(Error::Problem(format!(
                    "the report's parameter `{s}` is not one parameter of this robot"
                )))
            }
        }
    }
    let f: Vec<f64> = estimated
        .iter()
        .map(|&id| units.factor(robot.param_quantity(id)))
        .collect();
    if report.covariance.len() != f.len() || report.covariance.iter().any(|r| r.len() != f.len()) {
        return Err(Error::Problem(format!(
            "the report's covariance is not {0} x {0}",
            f.len()
        )));
    }
    let covariance: Vec<Vec<f64>> = report
        .covariance
        .iter()
        .zip(&f)
        .map(|(row, fa)| row.iter().zip(&f).map(|(c, fb)| c * fa * fb).collect())
        .collect();
    if report.levers.len() != robot.dof() {
        return Err(Error::Problem(format!(
            "the report has {} joint levers; the robot has {} joints",
            report.levers.len(),
            robot.dof()
        )));
    }
    if let Some(j) = report.levers.iter().position(|l| !lever_plausible(*l)) {
        return Err(Error::Problem(format!(
            "the report's lever of joint {} is {}: expected at least 0 and at most {:e} (length \
             unit per reading unit)",
            j + 1,
            crate::units::number::format_number(report.levers[j]),
            MAX_SPREAD
        )));
    }
    let si = |v: f64| units.to_si(Quantity::Length, v);
    let metric = JointMetric::new(
        robot,
        &report.levers.iter().map(|&l| si(l)).collect::<Vec<_>>(),
    );
    let growth = |g: &GrowthReport, angle: bool| -> Result<Growth> {
        let q = |v: f64| {
            if angle {
                units.to_si(Quantity::Angle, v)
            } else {
                si(v)
            }
        };
        let out = Growth {
            s0: q(g.s0),
            c: q(g.c) / si(1.0),
            shape: g.shape,
        };
        if !(out.s0.is_finite() && out.c.is_finite() && out.s0 >= 0.0 && out.c >= 0.0) {
            return Err(Error::Problem(
                "the report's model-error term is not finite and non-negative".into(),
            ));
        }
        if !(3.0..=9.0).contains(&out.shape) {
            return Err(Error::Problem(format!(
                "the report's model-error shape is {}: it must be between 3 (even) and 9 (along \
                 one axis)",
                g.shape
            )));
        }
        Ok(out)
    };
    let model = ModelError {
        position: growth(&report.position, false)?,
        attitude: report
            .attitude
            .as_ref()
            .map(|a| growth(a, true))
            .transpose()?,
    };
    let mut predictor = Predictor::new(
        robot,
        &estimated,
        &covariance,
        model,
        metric,
        report.measured.iter().map(Vec::as_slice),
    )?;
    for t in &report.targets {
        let target = crate::files::site_target(robot, &t.target)
            .map_err(|m| Error::Problem(format!("the report's model-error terms: {m}")))?;
        let model = ModelError {
            position: growth(&t.position, false)?,
            attitude: t.attitude.as_ref().map(|a| growth(a, true)).transpose()?,
        };
        predictor.set_target_model(target, model)?;
    }
    Ok(predictor)
}

#[cfg(test)]
mod tests;
