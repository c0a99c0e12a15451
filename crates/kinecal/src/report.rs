//! The machine-readable calibration report (JSON), in the robot file's units. The
//! [`workflow`](crate::workflow) fills it in; the history stores it.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::estimation::Calibration;
use crate::identifiability::{format_combination, Analysis};
use crate::observe::{target_name, Accuracy, Dataset};
use crate::outliers::Outlier;
use crate::params::ParamId;
use crate::robot::Robot;
use crate::source::Source;
use crate::uncertainty::{Uncertainty, NOISE_SIGMAS};
use crate::units::{Quantity, Units};
use crate::warning::Warning;

/// One parameter's line in the report.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
pub struct ParameterReport {
    /// `p1`, `p2`, ...
    pub id: String,
    /// `link1.x`, `joint3.offset`, ...
    pub name: String,
    /// The unit of `initial`, `estimated` and `change`.
    pub unit: String,
    /// Value before calibration.
    pub initial: f64,
    /// Value after calibration (equal to `initial` when not estimated).
    pub estimated: f64,
    /// `estimated - initial`.
    pub change: f64,
    /// Whether the parameter was estimated.
    pub estimated_flag: bool,
    /// Whether the data determines it individually (absent when not estimated or not analysed).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub determined: Option<bool>,
    /// Standard deviation (same unit), when determined.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sigma: Option<f64>,
    /// `|change| / sigma`, when determined.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub significance: Option<f64>,
    /// Whether the change is within the noise (below 2 sigma).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub within_noise: Option<bool>,
    /// The standard deviation of its prior (same unit), when the calibration had a prior on it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub prior_sigma: Option<f64>,
    /// With a prior: the data's share in its estimate, `1 - var_post / var_prior` on the
    /// information (1: the data determine it; 0: the prior alone does).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub data_share: Option<f64>,
    /// With a prior, what determines it: `data` (the data alone determine it individually),
    /// `data and prior` (the data determine only combinations of it with others, the prior
    /// splits them) or `prior` (the prior alone: the data give under 1 % of its information).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub determined_by: Option<String>,
}

/// The Gaussian prior of a calibration and its part in the result.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
pub struct PriorReport {
    /// The prior as written (the robot file's units): `length=0.1,angle=0.01,link3.y=0.5`.
    pub prior: String,
    /// Its residual rows: one per estimated parameter it covers.
    pub rows: usize,
    /// The data's part of the objective after (the report's `objective_after`).
    pub data_objective_after: f64,
    /// The prior's part of the objective after: `sum ((p - p0) / s_p)^2` (dimensionless).
    pub prior_objective_after: f64,
    /// The numerical rank of the estimated parameters on the data alone (the report's `rank`
    /// is that of the data and the prior together).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub data_rank: Option<usize>,
    /// Estimated parameters the prior alone determines: the data give under 1 % of their
    /// information (ids).
    #[serde(default)]
    pub determined_by_prior_alone: Vec<String>,
    /// Estimated parameters the data determine only in combination with others, which the
    /// prior splits (ids).
    #[serde(default)]
    pub split_by_prior: Vec<String>,
}

/// A member of a determined combination.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
pub struct TermReport {
    /// Parameter id.
    pub id: String,
    /// Parameter name.
    pub name: String,
    /// Coefficient (file units).
    pub coefficient: f64,
}

/// A combination of parameters the data determines although its members are not.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
pub struct CombinationReport {
    /// Readable form, e.g. `p3 - p9 - p15 - p21 - p27 - p33`.
    pub expression: String,
    /// The members.
    pub terms: Vec<TermReport>,
    /// Value before calibration.
    pub initial: f64,
    /// Value after.
    pub value: f64,
    /// Standard deviation.
    pub sigma: f64,
    /// `|value - initial| / sigma`.
    pub significance: f64,
    /// Whether the change is within the noise (below 2 sigma).
    pub within_noise: bool,
}

/// A pair of strongly correlated estimates.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
pub struct CorrelationReport {
    /// First parameter id.
    pub a: String,
    /// Second parameter id.
    pub b: String,
    /// Correlation coefficient.
    pub rho: f64,
}

/// Error statistics on one dataset, in the robot file's units.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
pub struct ErrorStats {
    /// Observations with a position error (poses and positions).
    #[serde(default)]
    pub positions: usize,
    /// RMS 3D position error.
    pub rms_position: f64,
    /// Mean 3D position error.
    pub mean_position: f64,
    /// 95th percentile (nearest rank) of the position errors.
    pub p95_position: f64,
    /// Largest position error.
    pub max_position: f64,
    /// RMS attitude error (absent without full-pose rows).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rms_orientation: Option<f64>,
    /// Mean attitude error.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mean_orientation: Option<f64>,
    /// 95th percentile of the attitude errors.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub p95_orientation: Option<f64>,
    /// Largest attitude error.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_orientation: Option<f64>,
    /// Errors of the other metrics (distances, contacts), when observed.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub other: Vec<MetricStats>,
}

/// Cross-validation by posture folds (length unit): the same calibration run on each training
/// fold and checked on the postures it left out.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
pub struct CrossValidationReport {
    /// The folds' shuffle seed (absent: interleaved in posture order).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
    /// The metric judged (`position`, else the first other one).
    pub metric: String,
    /// Each fold's held-out errors.
    pub folds: Vec<FoldReport>,
    /// All folds' held-out errors together.
    pub overall: MetricStats,
    /// Bootstrap 95 % interval of the overall held-out mean: low end.
    pub mean_low: f64,
    /// High end.
    pub mean_high: f64,
}

/// One candidate of a model choice (length unit).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
pub struct ChoiceReport {
    /// The candidate as written.
    pub candidate: String,
    /// Parameters estimated on all the data.
    pub parameters: usize,
    /// Cross-validated held-out mean.
    pub mean: f64,
    /// Its standard error (over the folds).
    pub standard_error: f64,
    /// Whether it was chosen.
    pub chosen: bool,
}

/// One fold of a cross-validation (length unit).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
pub struct FoldReport {
    /// Postures held out.
    pub postures: usize,
    /// Their labels.
    #[serde(default)]
    pub held_out: Vec<String>,
    /// Their errors.
    pub errors: MetricStats,
    /// The held-out posture with the largest error.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub worst_posture: Option<String>,
    /// Whether the fold's fit converged.
    pub converged: bool,
    /// The parameters the fold's fit estimated (names).
    #[serde(default)]
    pub estimated: Vec<String>,
    /// Their numerical rank in the fold's fit.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rank: Option<usize>,
}

/// The closed-form placement of a far start ([`crate::registration`]): RMS position error of
/// the start before and after it (length unit).
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq, JsonSchema)]
pub struct StartPlacement {
    /// Before.
    pub rms_before: f64,
    /// After.
    pub rms_after: f64,
}

/// Length errors of one metric other than positions (length unit).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
pub struct MetricStats {
    /// `distance` (error of a measured distance), `contact` (distance from the plane), ...
    pub metric: String,
    /// Observations.
    pub count: usize,
    /// RMS error.
    pub rms: f64,
    /// Mean error.
    pub mean: f64,
    /// 95th percentile (nearest rank).
    pub p95: f64,
    /// Largest error.
    pub max: f64,
}

impl ErrorStats {
    /// Converts an [`Accuracy`] to `units`.
    pub fn new(a: &Accuracy, units: &Units) -> Self {
        let len = |v: f64| units.from_si(Quantity::Length, v);
        let ang = |v: f64| (a.orientations > 0).then(|| units.from_si(Quantity::Angle, v));
        ErrorStats {
            positions: a.positions,
            rms_position: len(a.rms_position),
            mean_position: len(a.mean_position),
            p95_position: len(a.p95_position),
            max_position: len(a.max_position),
            rms_orientation: ang(a.rms_orientation),
            mean_orientation: ang(a.mean_orientation),
            p95_orientation: ang(a.p95_orientation),
            max_orientation: ang(a.max_orientation),
            other: a
                .other
                .iter()
                .map(|m| MetricStats {
                    metric: m.metric.to_string(),
                    count: m.count,
                    rms: len(m.rms),
                    mean: len(m.mean),
                    p95: len(m.p95),
                    max: len(m.max),
                })
                .collect(),
        }
    }
}

/// Accuracy before and after calibration on one dataset.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
pub struct DatasetAccuracy {
    /// Postures in the dataset.
    pub postures: usize,
    /// Observations in the dataset.
    pub measurements: usize,
    /// With the nominal robot (the request's).
    pub before: ErrorStats,
    /// With the solver's start, when it is not the nominal robot (its frames placed in closed
    /// form first, or an initial guess).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start: Option<ErrorStats>,
    /// With the calibrated robot.
    pub after: ErrorStats,
    /// RMS of the residuals in their own standard deviations (row sigmas, else the weights),
    /// before and after: about 1 when the stated uncertainties are right.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub normalized_rms: Option<[f64; 2]>,
    /// Measurement sessions of this data that the identification never saw: their frames were
    /// re-estimated (placed in closed form, then their six parameters fitted on this data with
    /// the robot held) before either robot was checked.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sessions_refitted: Vec<String>,
}

impl DatasetAccuracy {
    /// From the accuracies before and after on a dataset of `postures` and `observations`.
    pub fn new(
        postures: usize,
        observations: usize,
        before: &Accuracy,
        after: &Accuracy,
        units: &Units,
    ) -> Self {
        DatasetAccuracy {
            sessions_refitted: Vec::new(),
            postures,
            measurements: observations,
            before: ErrorStats::new(before, units),
            start: None,
            after: ErrorStats::new(after, units),
            normalized_rms: None,
        }
    }
}

/// How many observations of one kind.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
pub struct KindCount {
    /// `pose`, `position`, `distance`, `contact`.
    pub kind: String,
    /// How many.
    pub count: usize,
}

/// A file the calibration read, with the SHA-256 of the bytes read.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
pub struct SourceReport {
    /// The file name as given.
    pub name: String,
    /// SHA-256, hex.
    pub sha256: String,
}

/// An observation the calibrated model misses by far more than the rest.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
pub struct OutlierReport {
    /// Line in its file (0 when synthesized).
    pub line: usize,
    /// The observation's kind.
    #[serde(default)]
    pub kind: String,
    /// The metric of `position_error`: `position`, `distance`, `contact`.
    #[serde(default)]
    pub metric: String,
    /// Posture label (labels joined by `&` for observations of two postures).
    pub posture: String,
    /// Site (`ee` for the end effector).
    pub site: String,
    /// Length error in the observation's metric: the position error of a pose or position, the
    /// error of a distance, the distance from a plane (length unit).
    pub position_error: f64,
    /// Attitude error (angle unit), for a full pose.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub orientation_error: Option<f64>,
    /// Largest residual component in robust standard deviations.
    pub sigmas: f64,
}

/// The fit before pruning, when `--prune` was used.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
pub struct PruneReport {
    /// The significance threshold K.
    pub k: f64,
    /// Parameters removed, in order.
    pub removed: Vec<String>,
    /// The full fit's objective after.
    pub full_objective_after: f64,
    /// The full fit's RMS position error after.
    pub full_rms_position_after: f64,
    /// The full fit's RMS attitude error after (absent without full-pose observations).
    #[serde(default)]
    pub full_rms_orientation_after: Option<f64>,
}

/// The wall time of one phase.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
pub struct PhaseTime {
    /// The phase (`reading`, `preparation`, `selection`, `estimation`, `pruning`,
    /// `uncertainty`, `report`, `cross-validation`, `writing`).
    pub phase: String,
    /// Seconds.
    pub seconds: f64,
}

/// The figures of the solver's start on the identification data (robot file's units), when it
/// is not the nominal robot.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
pub struct StartFigures {
    /// Weighted sum of squared residuals.
    pub objective: f64,
    /// RMS 3D position error.
    pub rms_position: f64,
    /// Largest position error.
    pub max_position: f64,
    /// RMS attitude error (absent without poses).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rms_orientation: Option<f64>,
    /// Largest attitude error.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_orientation: Option<f64>,
}

/// The solver's stationarity measures at its last point ([`crate::estimation::Stationarity`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct StationarityReport {
    /// The relative reduction of the objective a Gauss-Newton step would bring by the local
    /// linear model (converged at or below `ftol`, 1e-15 by default).
    pub predicted_reduction: f64,
    /// The Gauss-Newton step's length relative to the parameters, both scaled by the column
    /// norms (converged at or below `xtol`, 1e-12); absent when every scaled parameter is 0.
    pub step: Option<f64>,
    /// The largest |cos| between the residual and a column of the Jacobian.
    pub gradient: f64,
    /// The numerical rank the Gauss-Newton step used.
    pub rank: usize,
}

/// Now, in UTC, as RFC 3339 to the second (`2026-11-25T18:21:58Z`).
pub fn now_utc() -> String {
    let now = time::OffsetDateTime::now_utc()
        .replace_nanosecond(0)
        .unwrap_or_else(|_| time::OffsetDateTime::now_utc());
    now.format(&time::format_description::well_known::Rfc3339)
        .unwrap_or_default()
}

/// The errors of every observation of `data` with `cal`'s initial and calibrated robots.
fn observation_errors(cal: &Calibration, data: &Dataset) -> ObservationErrors {
    let errors = |robot: &Robot| {
        let u = robot.units;
        let ctx = crate::observe::Context {
            robot,
            orientation: crate::observe::OrientationError::default(),
        };
        let mut out = Vec::with_capacity(data.observations.len());
        crate::observe::for_each_observation(robot, data, |_, o, frames| {
            let e = o.error(&ctx, frames);
            out.push((
                u.from_si(Quantity::Length, e.length),
                e.angle.map(|a| u.from_si(Quantity::Angle, a)),
            ));
        });
        out
    };
    let a = &cal.accuracy_after;
    let metric = if a.other.is_empty() {
        "position"
    } else if a.positions == 0 && a.other.len() == 1 {
        a.other[0].metric
    } else {
        "length"
    };
    ObservationErrors::new(metric, &errors(&cal.initial), &errors(&cal.calibrated))
}

fn finite_or_none(v: f64) -> Option<f64> {
    v.is_finite().then_some(v)
}

/// The JSON Schema (draft 2020-12) of [`CalibrationReport`], as shipped in the repository's
/// `schemas/calibration-report.schema.json`.
pub fn calibration_report_schema() -> String {
    let schema = schemars::schema_for!(CalibrationReport);
    serde_json::to_string_pretty(&schema).expect("a schema is JSON") + "\n"
}

/// The version of the calibration report's schema: raised when a field is removed or changes
/// meaning (reports without the field are version 1). Readers refuse newer versions.
pub const SCHEMA_VERSION: u32 = 2;

fn version_one() -> u32 {
    1
}

/// The errors of each observation before and after calibration, as charts draw them: every
/// observation up to [`ObservationErrors::MAX_POINTS`], beyond that the largest of each run of
/// `run` consecutive observations (so that no large error disappears); and the histogram of
/// all the errors after.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
pub struct ObservationErrors {
    /// What the length errors are: `position`, a metric (`distance`, `contact`) when the data
    /// has only that, or `length` for a mix.
    pub metric: String,
    /// Observations.
    pub observations: usize,
    /// Observations per point.
    pub run: usize,
    /// Length error of each point before (length unit).
    pub before: Vec<f64>,
    /// After.
    pub after: Vec<f64>,
    /// Attitude error of each point before (angle unit; null for a run without attitudes),
    /// absent when no observation has an attitude.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub attitude_before: Option<Vec<Option<f64>>>,
    /// After.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub attitude_after: Option<Vec<Option<f64>>>,
    /// Histogram of the length errors after, over every observation: the bin width (length
    /// unit) and the count of each bin from 0.
    pub histogram_width: f64,
    /// Counts.
    pub histogram: Vec<usize>,
}

impl ObservationErrors {
    /// The most points a chart draws.
    pub const MAX_POINTS: usize = 2000;

    /// From the errors of every observation (file units): (length, attitude) before and after.
    pub fn new(
        metric: &str,
        before: &[(f64, Option<f64>)],
        after: &[(f64, Option<f64>)],
    ) -> ObservationErrors {
        let n = before.len();
        let run = n.div_ceil(Self::MAX_POINTS).max(1);
        let maxima = |v: &[(f64, Option<f64>)], angle: bool| -> Vec<Option<f64>> {
            v.chunks(run)
                .map(|c| {
                    c.iter()
                        .filter_map(|e| if angle { e.1 } else { Some(e.0) })
                        .filter(|x| x.is_finite())
                        .reduce(f64::max)
                })
                .collect()
        };
        let lengths = |v| {
            maxima(v, false)
                .into_iter()
                .map(|x| x.unwrap_or(0.0))
                .collect()
        };
        let attitudes = before.iter().any(|e| e.1.is_some());
        let max = after.iter().map(|e| e.0).fold(0.0, f64::max);
        let bins_wanted = ((n as f64).sqrt().ceil() as usize).clamp(5, 20);
        let width = if max > 0.0 {
            nice_width(max / bins_wanted as f64)
        } else {
            1.0
        };
        let bins = ((max / width).floor() as usize + 1).max(1);
        let mut histogram = vec![0; bins];
        for e in after {
            histogram[((e.0 / width) as usize).min(bins - 1)] += 1;
        }
        ObservationErrors {
            metric: metric.to_string(),
            observations: n,
            run,
            before: lengths(before),
            after: lengths(after),
            attitude_before: attitudes.then(|| maxima(before, true)),
            attitude_after: attitudes.then(|| maxima(after, true)),
            histogram_width: width,
            histogram,
        }
    }
}

/// A round bin width near `w` (1, 2 or 5 times a power of ten).
pub fn nice_width(w: f64) -> f64 {
    if !(w > 0.0 && w.is_finite()) {
        return 1.0;
    }
    let p = 10f64.powf(w.log10().floor());
    let m = w / p;
    let f = if m <= 1.0 {
        1.0
    } else if m <= 2.0 {
        2.0
    } else if m <= 5.0 {
        5.0
    } else {
        10.0
    };
    f * p
}

/// The singular-value spectrum of the scaled Jacobian at the solution, and what it says.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
pub struct SpectrumReport {
    /// Singular values of the scaled Jacobian, largest first.
    pub singular_values_scaled: Vec<f64>,
    /// The numerical rank.
    pub rank: usize,
    /// The relative tolerance of the rank cut.
    pub rcond: f64,
    /// The thesis's count of identifiable parameters, when it applies (`5nr + 3np + 6 = 26`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub expected: Option<String>,
    /// Identically redundant groups: their combination, its value and whether the data
    /// determines it.
    pub identical_groups: Vec<GroupReport>,
}

/// An identically redundant group of parameters.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
pub struct GroupReport {
    /// The combination, e.g. `p3 + p9`.
    pub expression: String,
    /// Its value.
    pub value: f64,
    /// Whether the data determines it (its members enter no other dependency).
    pub determined: bool,
}

/// The calibration report written by `kinecal calibrate --report`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
pub struct CalibrationReport {
    /// The version of this document's schema ([`SCHEMA_VERSION`]).
    #[serde(default = "version_one")]
    pub schema_version: u32,
    /// The kinecal that wrote it.
    #[serde(default)]
    pub kinecal_version: String,
    /// When it was made (UTC, RFC 3339).
    #[serde(default)]
    pub created: String,
    /// The calibration spec that produced it (outputs left out), when it came from one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spec: Option<serde_json::Value>,
    /// A given calibration, assessed on the data (not solved here).
    #[serde(default)]
    pub given: bool,
    /// Robot name.
    pub robot: String,
    /// Length unit of every length below.
    pub length_unit: crate::units::LengthUnit,
    /// Angle unit of every angle below.
    pub angle_unit: crate::units::AngleUnit,
    /// `lm`, `gn`, `sd` or `svd`.
    pub method: crate::estimation::Method,
    /// `euler` or `rotvec`.
    pub orientation_error: crate::observe::OrientationError,
    /// False only when the iteration cap stopped the solver.
    pub converged: bool,
    /// Why the solver stopped.
    pub termination: crate::estimation::Termination,
    /// How stationary the solver's last point is (absent for a calibration assessed, not
    /// solved).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stationarity: Option<StationarityReport>,
    /// Iterations run.
    pub iterations: usize,
    /// Postures in the data.
    pub postures: usize,
    /// Observations in the data.
    pub measurements: usize,
    /// Observations of each kind.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub observations: Vec<KindCount>,
    /// Residuals (3 per position, 6 per pose, 1 per distance or contact).
    pub residuals: usize,
    /// Standard deviation weighting position residuals (length unit).
    pub weight_length: f64,
    /// Standard deviation weighting orientation residuals (angle unit).
    pub weight_angle: f64,
    /// The solver's start, when it is not the nominal robot (the `*_before` figures are the
    /// nominal robot's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start: Option<StartFigures>,
    /// Weighted sum of squared residuals before (dimensionless): the nominal robot's.
    pub objective_before: f64,
    /// Weighted sum of squared residuals after.
    pub objective_after: f64,
    /// RMS 3D position error before (length unit).
    pub rms_position_before: f64,
    /// RMS 3D position error after.
    pub rms_position_after: f64,
    /// Largest position error before.
    pub max_position_before: f64,
    /// Largest position error after.
    pub max_position_after: f64,
    /// RMS attitude error (angle of `R_measured^T R_model`) before (angle unit; null without
    /// full-pose observations).
    #[serde(default)]
    pub rms_orientation_before: Option<f64>,
    /// RMS attitude error after.
    #[serde(default)]
    pub rms_orientation_after: Option<f64>,
    /// Largest attitude error before.
    #[serde(default)]
    pub max_orientation_before: Option<f64>,
    /// Largest attitude error after.
    #[serde(default)]
    pub max_orientation_after: Option<f64>,
    /// Every parameter of the model, in thesis order.
    pub parameters: Vec<ParameterReport>,
    /// Warnings, worded.
    pub warnings: Vec<String>,
    /// The same warnings with their quantities.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warning_details: Vec<Warning>,
    /// `solver` or `min-change`.
    pub solution: String,
    /// Variance factor `SSR / (m - rank)` (with a prior, `SSR / (m - tr H_data)`, the data's rows
    /// less their leverage): about 1 when the weights match the noise.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub variance_factor: Option<f64>,
    /// Numerical rank of the estimated parameters (with a prior, of the data and the prior
    /// together).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rank: Option<usize>,
    /// The Gaussian prior on the parameters' changes, when the calibration had one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub prior: Option<PriorReport>,
    /// Estimated parameters the data does not determine individually (with a prior, the data
    /// and the prior together).
    pub undetermined: Vec<String>,
    /// Determined combinations of identically redundant groups.
    pub combinations: Vec<CombinationReport>,
    /// Correlations above 0.95 between determined estimates.
    pub correlations: Vec<CorrelationReport>,
    /// The fit before pruning, when pruning was asked for.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pruning: Option<PruneReport>,
    /// Accuracy on the identification data (the data calibrated on).
    pub identification: DatasetAccuracy,
    /// Accuracy on held-out validation data, when given.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub validation: Option<DatasetAccuracy>,
    /// `squared`, or `huber K x robust spread` / `huber K x stated sigma`.
    pub loss: String,
    /// The model choice this calibration came out of, when asked for: every candidate with its
    /// cross-validated held-out mean.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub model_choice: Vec<ChoiceReport>,
    /// Over how many shuffles of the postures the model choice repeated its cross-validation.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub model_choice_repeats: Option<usize>,
    /// Cross-validation by posture folds, when asked for.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cross_validation: Option<CrossValidationReport>,
    /// When the start was far, the closed-form placement of the measurement and target frames
    /// done before the solver.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start_placement: Option<StartPlacement>,
    /// Under a Huber loss, the residual rows it down-weighted (beyond its threshold).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub down_weighted_rows: Option<usize>,
    /// Wall time of each phase of the calibration, in the order they first ran (a caller may
    /// add its own, such as reading the files).
    #[serde(default)]
    pub timings: Vec<PhaseTime>,
    /// Measurements beyond the outlier threshold (listed, not dropped).
    pub outliers: Vec<OutlierReport>,
    /// The threshold used, in robust standard deviations: the one asked for, raised for the
    /// number of rows tested ([`crate::outliers::threshold`]).
    pub outlier_sigmas: f64,
    /// SHA-256 of the robot file, when the caller provides it (history fingerprints).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub robot_file_sha256: Option<String>,
    /// SHA-256 of the (first) measurement file, when the caller provides it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub data_file_sha256: Option<String>,
    /// Every file read, with its SHA-256.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sources: Vec<SourceReport>,
    /// The errors of each observation of the identification data, before and after.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub observation_errors: Option<ObservationErrors>,
    /// The singular-value spectrum (absent when the uncertainty could not be computed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spectrum: Option<SpectrumReport>,
    /// The mass model of an elastic robot: its equilibrium at the identification postures and
    /// the joints' stiffnesses.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub elastic: Option<ElasticReport>,
    /// The predicted accuracy over the workspace (see [`crate::predict`]): the model-error term
    /// estimated by cross-validation, the covariance and measured postures `kinecal predict`
    /// needs, the predicted 95 % bound over the joint ranges and, when an HTML report was asked
    /// for, the accuracy map. Absent when the data cannot give one (fewer than 20 postures
    /// measured by position or pose, no uncertainty).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub prediction: Option<crate::predict::PredictionReport>,
}

/// The mass model of an elastic robot (see [`crate::robot::Elastic`]), after calibration.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
pub struct ElasticReport {
    /// Bodies of the model.
    pub bodies: usize,
    /// Their total mass (kg).
    pub total_mass: f64,
    /// Magnitude of gravity (length unit / s^2).
    pub gravity: f64,
    /// `converged` (to 1e-10 rad) or `N fixed iterations`.
    pub equilibrium: String,
    /// The most fixed-point iterations any identification posture took.
    pub iterations_max: usize,
    /// Postures whose equilibrium did not converge (0 when it is sound).
    pub unconverged_postures: usize,
    /// The largest deflection at any identification posture (angle unit).
    pub largest_deflection: f64,
    /// The largest gravity torque about any joint axis there (N m).
    pub largest_torque: f64,
    /// Each revolute joint's compliances, as compliance and as stiffness.
    pub joints: Vec<StiffnessReport>,
}

/// One compliance of one joint.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
pub struct StiffnessReport {
    /// The parameter, `joint2.compliance` or `joint2.lateral`.
    pub name: String,
    /// Its compliance (angle unit / (N length unit)).
    pub compliance: f64,
    /// Its standard deviation, when estimated and determined.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub compliance_sigma: Option<f64>,
    /// The stiffness `1 / compliance` (N length unit / angle unit), when the compliance is
    /// positive.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stiffness: Option<f64>,
    /// Its standard deviation, `sigma / compliance^2` (first order), when both exist.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stiffness_sigma: Option<f64>,
    /// The stiffness's unit, `N m/rad`.
    pub stiffness_unit: String,
    /// Whether it was estimated.
    pub estimated: bool,
}

/// The header of [`ElasticReport::table`].
pub const STIFFNESS_COLUMNS: [&str; 9] = [
    "parameter",
    "joint",
    "axis",
    "compliance",
    "compliance_sigma",
    "stiffness",
    "stiffness_sigma",
    "stiffness_unit",
    "estimated",
];

impl ElasticReport {
    /// The compliance table as CSV ([`STIFFNESS_COLUMNS`]): one row per compliance, `joint` its
    /// number, `axis` `joint` or `lateral`, compliance and stiffness in the report's units with
    /// their sigmas (empty when not determined or not positive), `estimated` 1 or 0. Numbers are
    /// written as [`crate::units::number`] says: the shortest text that reads back to the same
    /// value.
    pub fn table(&self) -> String {
        use crate::units::number::{write, Scale};
        let mut out = STIFFNESS_COLUMNS.join(",");
        out.push('\n');
        let num = |v: Option<f64>| v.map_or(String::new(), |v| write(v, Scale::of([v])));
        for j in &self.joints {
            let (joint, axis) = j
                .name
                .strip_prefix("joint")
                .and_then(|r| r.split_once('.'))
                .unwrap_or(("", ""));
            let axis = if axis == "lateral" {
                "lateral"
            } else {
                "joint"
            };
            out.push_str(&format!(
                "{},{joint},{axis},{},{},{},{},{},{}\n",
                j.name,
                num(Some(j.compliance)),
                num(j.compliance_sigma),
                num(j.stiffness),
                num(j.stiffness_sigma),
                j.stiffness_unit,
                u8::from(j.estimated)
            ));
        }
        out
    }

    /// The report of `robot`'s mass model at the postures of `data` (`None` for a rigid robot).
    pub fn new(robot: &Robot, data: &Dataset, estimated: &[ParamId]) -> Option<ElasticReport> {
        let model = robot.elastic.as_ref()?;
        let u = robot.units;
        let chain = crate::kinematics::Chain::new(robot);
        let mut ws = crate::kinematics::Workspace::new(robot);
        let (mut iterations_max, mut unconverged) = (0, 0);
        let (mut largest, mut torque) = (0.0f64, 0.0f64);
        for p in &data.postures {
            chain.forward_loaded(&p.readings, None, p.payload.as_ref(), &mut ws);
            let eq = ws.equilibrium()?;
            iterations_max = iterations_max.max(eq.iterations);
            unconverged += usize::from(!eq.converged);
            largest = largest.max(eq.largest);
            for t in ws.gravity_torques()?.iter() {
                torque = torque.max(t.abs());
            }
        }
        let stiffness_unit = format!("N {}/{}", u.length, u.angle);
        let joints = robot
            .param_ids()
            .filter(|&id| {
                matches!(
                    robot.param_kind(id),
                    crate::params::ParamKind::Compliance { .. }
                        | crate::params::ParamKind::Lateral { .. }
                )
            })
            .map(|id| {
                let compliance = robot.get_user(id);
                StiffnessReport {
                    name: robot.param_name(id),
                    compliance,
                    compliance_sigma: None,
                    stiffness: (compliance > 0.0).then(|| 1.0 / compliance),
                    stiffness_sigma: None,
                    stiffness_unit: stiffness_unit.clone(),
                    estimated: estimated.contains(&id),
                }
            })
            .collect();
        Some(ElasticReport {
            bodies: model.bodies.len(),
            total_mass: model.bodies.iter().map(|b| b.mass).sum(),
            gravity: u.from_si(Quantity::Length, model.gravity.norm()),
            equilibrium: match model.iterations {
                Some(n) => format!("{n} fixed iterations"),
                None => "converged".into(),
            },
            iterations_max,
            unconverged_postures: unconverged,
            largest_deflection: u.from_si(Quantity::Angle, largest),
            largest_torque: torque,
            joints,
        })
    }
}

impl CalibrationReport {
    /// The report of `cal`, calibrated on `data` (identification accuracy from `cal`).
    pub fn new(cal: &Calibration, data: &Dataset) -> Self {
        let (postures, measurements, residuals) =
            (data.postures.len(), data.observations.len(), data.rows());
        let robot = &cal.calibrated;
        let u = robot.units;
        let len = |v: f64| u.from_si(Quantity::Length, v);
        let ang = |v: f64| u.from_si(Quantity::Angle, v);
        let parameters = robot
            .param_ids()
            .map(|id| {
                let initial = cal.initial.get_user(id);
                let estimated = robot.get_user(id);
                ParameterReport {
                    id: id.to_string(),
                    name: robot.param_name(id),
                    unit: robot.param_unit(id),
                    initial,
                    estimated,
                    change: estimated - initial,
                    estimated_flag: cal.estimated.binary_search(&id).is_ok(),
                    determined: None,
                    sigma: None,
                    significance: None,
                    within_noise: None,
                    prior_sigma: None,
                    data_share: None,
                    determined_by: None,
                }
            })
            .collect();
        let (b, a) = (&cal.accuracy_before, &cal.accuracy_after);
        let prior = (!cal.options.prior.is_empty()).then(|| PriorReport {
            prior: crate::prior::describe(&cal.options.prior, robot),
            rows: cal
                .estimated
                .iter()
                .filter(|&&id| cal.options.prior.sigma(&cal.initial, id).is_some())
                .count(),
            data_objective_after: cal.objective_after,
            prior_objective_after: cal.prior_objective,
            data_rank: None,
            determined_by_prior_alone: Vec::new(),
            split_by_prior: Vec::new(),
        });
        let poses = b.orientations > 0;
        CalibrationReport {
            schema_version: SCHEMA_VERSION,
            kinecal_version: env!("CARGO_PKG_VERSION").to_string(),
            created: now_utc(),
            spec: None,
            given: cal.termination == crate::estimation::Termination::Given,
            robot: robot.name.clone(),
            length_unit: u.length,
            angle_unit: u.angle,
            method: cal.options.solver.method,
            orientation_error: cal.options.orientation,
            converged: cal.converged(),
            termination: cal.termination,
            stationarity: (cal.termination != crate::estimation::Termination::Given).then(|| {
                StationarityReport {
                    predicted_reduction: cal.stationarity.predicted_reduction,
                    step: finite_or_none(cal.stationarity.step),
                    gradient: cal.stationarity.gradient,
                    rank: cal.stationarity.rank,
                }
            }),
            iterations: cal.iterations,
            postures,
            measurements,
            observations: data
                .kinds()
                .into_iter()
                .map(|(kind, count)| KindCount {
                    kind: kind.to_string(),
                    count,
                })
                .collect(),
            residuals,
            weight_length: len(cal.options.weights.length),
            weight_angle: ang(cal.options.weights.angle),
            start: None,
            objective_before: cal.objective_before,
            objective_after: cal.objective_after,
            rms_position_before: len(b.rms_position),
            rms_position_after: len(a.rms_position),
            max_position_before: len(b.max_position),
            max_position_after: len(a.max_position),
            rms_orientation_before: poses.then(|| ang(b.rms_orientation)),
            rms_orientation_after: poses.then(|| ang(a.rms_orientation)),
            max_orientation_before: poses.then(|| ang(b.max_orientation)),
            max_orientation_after: poses.then(|| ang(a.max_orientation)),
            parameters,
            warnings: Vec::new(),
            warning_details: Vec::new(),
            solution: "solver".to_string(),
            variance_factor: None,
            rank: None,
            prior,
            undetermined: Vec::new(),
            combinations: Vec::new(),
            correlations: Vec::new(),
            pruning: None,
            identification: DatasetAccuracy::new(postures, measurements, b, a, &u),
            validation: None,
            loss: cal.options.loss.to_string(),
            start_placement: None,
            cross_validation: None,
            model_choice: Vec::new(),
            model_choice_repeats: None,
            down_weighted_rows: match cal.options.loss {
                crate::estimation::Loss::Squared => None,
                crate::estimation::Loss::Huber { .. } => {
                    Some(cal.row_scale.iter().filter(|&&w| w < 1.0 - 1e-9).count())
                }
            },
            timings: Vec::new(),
            outliers: Vec::new(),
            outlier_sigmas: crate::outliers::DEFAULT_SIGMAS,
            robot_file_sha256: None,
            data_file_sha256: None,
            sources: Vec::new(),
            observation_errors: Some(observation_errors(cal, data)),
            spectrum: None,
            elastic: ElasticReport::new(robot, data, &cal.estimated),
            prediction: None,
        }
    }

    /// Lists the outliers (see [`crate::outliers`]) found at threshold `k`.
    pub fn set_outliers(&mut self, outliers: &[Outlier], data: &Dataset, robot: &Robot, k: f64) {
        let u = robot.units;
        self.outlier_sigmas = k;
        self.outliers = outliers
            .iter()
            .map(|o| {
                let obs = &data.observations[o.observation];
                OutlierReport {
                    line: obs.line(),
                    kind: obs.kind().to_string(),
                    metric: o.error.metric.to_string(),
                    posture: obs
                        .views()
                        .iter()
                        .map(|v| data.postures[v.posture].label.as_str())
                        .collect::<Vec<_>>()
                        .join("&"),
                    site: target_name(robot, obs.target()).to_string(),
                    position_error: u.from_si(Quantity::Length, o.error.length),
                    orientation_error: o.error.angle.map(|a| u.from_si(Quantity::Angle, a)),
                    sigmas: o.sigmas,
                }
            })
            .collect();
    }

    /// Sets the accuracy on held-out validation data, with its normalized RMS (before, after).
    pub fn set_validation(
        &mut self,
        postures: usize,
        observations: usize,
        before: &Accuracy,
        after: &Accuracy,
        normalized: [f64; 2],
        robot: &Robot,
    ) {
        let mut v = DatasetAccuracy::new(postures, observations, before, after, &robot.units);
        v.normalized_rms = Some(normalized);
        self.validation = Some(v);
    }

    /// Makes the nominal robot's figures (its weighted objective and accuracy on the
    /// identification data) the `before` ones, keeping the solver's start's as `start`: for a
    /// start that is not the nominal robot (frames placed in closed form, an initial guess).
    pub fn set_nominal(&mut self, objective: f64, accuracy: &Accuracy, units: &Units) {
        let len = |v: f64| units.from_si(Quantity::Length, v);
        let ang = |v: f64| units.from_si(Quantity::Angle, v);
        self.start = Some(StartFigures {
            objective: self.objective_before,
            rms_position: self.rms_position_before,
            max_position: self.max_position_before,
            rms_orientation: self.rms_orientation_before,
            max_orientation: self.max_orientation_before,
        });
        self.objective_before = objective;
        self.rms_position_before = len(accuracy.rms_position);
        self.max_position_before = len(accuracy.max_position);
        let poses = accuracy.orientations > 0;
        self.rms_orientation_before = poses.then(|| ang(accuracy.rms_orientation));
        self.max_orientation_before = poses.then(|| ang(accuracy.max_orientation));
        let start = std::mem::replace(
            &mut self.identification.before,
            ErrorStats::new(accuracy, units),
        );
        self.identification.start = Some(start);
    }

    /// Sets the validation data's accuracy with the solver's start, when it is not the
    /// nominal robot.
    pub fn set_validation_start(&mut self, start: &Accuracy, units: &Units) {
        if let Some(v) = &mut self.validation {
            v.start = Some(ErrorStats::new(start, units));
        }
    }

    /// Names the validation data's sessions whose frames were re-estimated.
    pub fn set_validation_sessions(&mut self, refitted: Vec<String>) {
        if let Some(v) = &mut self.validation {
            v.sessions_refitted = refitted;
        }
    }

    /// Sets the normalized RMS (before, after) of the identification data.
    pub fn set_normalized(&mut self, before_after: [f64; 2]) {
        self.identification.normalized_rms = Some(before_after);
    }

    /// Sets the uncertainty of the calibration: sigmas, significance, determined combinations,
    /// correlations, and the parameters the data does not determine.
    pub fn set_uncertainty(&mut self, cal: &Calibration, u: &Uncertainty) {
        let robot = &cal.calibrated;
        self.variance_factor = Some(u.variance_factor);
        self.rank = Some(u.analysis.rank);
        let an = &u.analysis;
        self.spectrum = Some(SpectrumReport {
            singular_values_scaled: an.singular_values_scaled.clone(),
            rank: an.rank,
            rcond: an.rcond,
            expected: an.expected.as_ref().map(|e| e.formula.clone()),
            identical_groups: an
                .identical_groups
                .iter()
                .map(|g| GroupReport {
                    expression: format_combination(&g.terms),
                    value: g.value,
                    determined: g.determined,
                })
                .collect(),
        });
        for pu in &u.parameters {
            if let (Some(e), Some(sigma)) = (self.elastic.as_mut(), pu.sigma) {
                let name = robot.param_name(pu.id);
                if let Some(j) = e.joints.iter_mut().find(|j| j.name == name) {
                    j.compliance_sigma = Some(sigma);
                    j.stiffness_sigma = j.stiffness.map(|s| sigma * s * s);
                }
            }
            let p = &mut self.parameters[pu.id.0];
            p.determined = Some(pu.determined);
            p.sigma = pu.sigma;
            p.significance = pu.significance;
            p.within_noise = pu.significance.map(|s| s < NOISE_SIGMAS);
            p.prior_sigma = pu.prior_sigma;
            p.data_share = pu.data_share;
            p.determined_by = pu.determined_by.map(|d| d.as_str().to_string());
            if let Some(prior) = self.prior.as_mut() {
                use crate::uncertainty::DeterminedBy;
                match pu.determined_by {
                    Some(DeterminedBy::Prior) => {
                        prior.determined_by_prior_alone.push(pu.id.to_string())
                    }
                    Some(DeterminedBy::DataAndPrior) => {
                        prior.split_by_prior.push(pu.id.to_string())
                    }
                    _ => {}
                }
            }
            if !pu.determined {
                self.undetermined.push(pu.id.to_string());
            }
        }
        if let Some(prior) = self.prior.as_mut() {
            prior.data_rank = Some(an.data_rank);
        }
        self.combinations = u
            .combinations
            .iter()
            .map(|c| CombinationReport {
                expression: format_combination(&c.terms),
                terms: c
                    .terms
                    .iter()
                    .map(|&(id, coefficient)| TermReport {
                        id: id.to_string(),
                        name: robot.param_name(id),
                        coefficient,
                    })
                    .collect(),
                initial: c.initial,
                value: c.value,
                sigma: c.sigma,
                significance: c.significance,
                within_noise: c.significance < NOISE_SIGMAS,
            })
            .collect();
        self.correlations = u
            .correlations
            .iter()
            .map(|&(a, b, rho)| CorrelationReport {
                a: a.to_string(),
                b: b.to_string(),
                rho,
            })
            .collect();
    }

    /// Records that this report is the pruned refit of `full`.
    pub fn set_pruning(&mut self, k: f64, removed: &[ParamId], full: &Calibration) {
        let u = full.calibrated.units;
        self.pruning = Some(PruneReport {
            k,
            removed: removed.iter().map(ToString::to_string).collect(),
            full_objective_after: full.objective_after,
            full_rms_position_after: u.from_si(Quantity::Length, full.accuracy_after.rms_position),
            full_rms_orientation_after: (full.accuracy_after.orientations > 0)
                .then(|| u.from_si(Quantity::Angle, full.accuracy_after.rms_orientation)),
        });
    }

    /// Sets the solution rule's name (`solver`, `min-change`).
    pub fn set_solution(&mut self, rule: &str) {
        self.solution = rule.to_string();
    }

    /// Sets the warnings.
    pub fn set_warnings(&mut self, warnings: &[Warning]) {
        self.warnings = warnings.iter().map(ToString::to_string).collect();
        self.warning_details = warnings.to_vec();
    }

    /// Records the files read: the first is the robot file, the second the (first) data file.
    pub fn set_sources(&mut self, sources: &[Source]) {
        self.robot_file_sha256 = sources.first().map(|s| s.sha256.clone());
        self.data_file_sha256 = sources.get(1).map(|s| s.sha256.clone());
        self.sources = sources
            .iter()
            .map(|s| SourceReport {
                name: s.name.clone(),
                sha256: s.sha256.clone(),
            })
            .collect();
    }

    /// Pretty-printed JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("report serializes")
    }

    /// Reads a report written by [`CalibrationReport::to_json`].
    pub fn from_json(text: &str) -> Result<Self, serde_json::Error> {
        let report: CalibrationReport = serde_json::from_str(text)?;
        if report.schema_version > SCHEMA_VERSION {
            return Err(serde::de::Error::custom(format!(
                "written by a newer kinecal (report schema version {}; this kinecal reads up to \
                 {SCHEMA_VERSION})",
                report.schema_version
            )));
        }
        Ok(report)
    }

    /// Whether `robot` (named `name` in messages) is this report's calibrated robot: every
    /// estimated parameter of the report is one of `robot`'s, at the estimated value (to 1e-9,
    /// relative). An error names the first that is not.
    pub fn check_calibrated(&self, robot: &Robot, name: &str) -> crate::error::Result<()> {
        for p in self.parameters.iter().filter(|p| p.estimated_flag) {
            let id = crate::param_list::parse_param_list(&p.id, robot)
                .ok()
                .and_then(|v| v.first().copied())
                .ok_or_else(|| {
                    crate::error::Error::Problem(format!(
                        "the report's parameter {} ({}) is not one of {name}'s: not the robot of \
                         this report",
                        p.id, p.name
                    ))
                })?;
            let v = robot.get_user(id);
            if (v - p.estimated).abs() > 1e-9 * p.estimated.abs().max(1.0) {
                return Err(crate::error::Error::Problem(format!(
                    "{name} is not the calibrated robot of this report: {} ({}) is {v} in the \
                     robot, {} in the report",
                    p.id, p.name, p.estimated
                )));
            }
        }
        Ok(())
    }
}

fn ids(list: &[ParamId]) -> Vec<String> {
    list.iter().map(ToString::to_string).collect()
}

/// The identifiability analysis as a document: what `kinecal analyze --json` prints and the
/// Python bindings return. Rank, singular values (of the scaled Jacobian and of `J^T J`, also
/// in file units), the identifiable set, identically redundant groups and their combinations,
/// the null space, the parameters dependent within the noise, and warnings.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
pub struct AnalysisReport {
    /// The version of this document's schema ([`SCHEMA_VERSION`]).
    pub schema_version: u32,
    /// Robot name.
    pub robot: String,
    /// Parameters analysed.
    pub parameters: usize,
    /// Their ids.
    pub parameter_ids: Vec<String>,
    /// Residual rows.
    pub residuals: usize,
    /// Numerical rank.
    pub rank: usize,
    /// Relative singular-value tolerance of the rank.
    pub rcond: f64,
    /// The rank the largest gap in the spectrum suggests.
    pub gap_rank: usize,
    /// That gap's ratio (null when infinite).
    pub gap_ratio: Option<f64>,
    /// Whether the two ranks agree.
    pub rank_consistent: bool,
    /// The thesis's count, when it applies.
    pub expected_rank: Option<usize>,
    /// Its formula (`5nr + 3np + 6 = 26`).
    pub expected_rank_formula: Option<String>,
    /// Singular values of the scaled Jacobian, largest first.
    pub singular_values_jacobian: Vec<f64>,
    /// Their squares: the eigenvalues of the scaled `J^T J`.
    pub singular_values_hessian: Vec<f64>,
    /// Singular values of the Jacobian in file units.
    pub singular_values_jacobian_file_units: Vec<f64>,
    /// Their squares.
    pub singular_values_hessian_file_units: Vec<f64>,
    /// Condition number of the scaled Jacobian (null when infinite).
    pub condition_number: Option<f64>,
    /// In file units.
    pub condition_number_file_units: Option<f64>,
    /// Parameters no residual feels.
    pub unobservable: Vec<String>,
    /// Identically redundant groups (their members' ids).
    pub identical_groups: Vec<Vec<String>>,
    /// The combination each group determines.
    pub identical_combinations: Vec<IdenticalCombination>,
    /// A basis of the null space: coefficients by parameter id.
    pub null_space: Vec<std::collections::BTreeMap<String, f64>>,
    /// The identifiable (base) set.
    pub identifiable: Vec<String>,
    /// Parameters the data does not determine individually.
    pub undetermined: Vec<String>,
    /// Rows whose Euler angles are near gimbal lock.
    pub euler_singular: Vec<String>,
    /// Warnings, worded.
    pub warnings: Vec<String>,
    /// The same warnings with their quantities.
    pub warning_details: Vec<Warning>,
    /// Parameters left out of the identifiable set as dependent on it within the noise.
    pub noise_dependent: Vec<NoiseDependentReport>,
    /// The rule that decided them.
    pub noise_rule: String,
    /// Parameters left out of the default selection because no observation sees them.
    pub unseen: Vec<String>,
}

/// An identically redundant group's combination.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
pub struct IdenticalCombination {
    /// `p3 + p9`.
    pub expression: String,
    /// Coefficients by parameter id.
    pub coefficients: std::collections::BTreeMap<String, f64>,
    /// Its value.
    pub value: f64,
    /// Whether the data determines it.
    pub determined: bool,
}

/// A parameter dependent on the identifiable set within the noise.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
pub struct NoiseDependentReport {
    /// Its id.
    pub id: String,
    /// Its name.
    pub name: String,
    /// Its sigma over the rule's limit.
    pub ratio: f64,
    /// Its sigma (its unit).
    pub sigma: f64,
    /// Its unit.
    pub unit: String,
    /// The sine of its angle to the span of the chosen set.
    pub sine: f64,
    /// Its regression on the chosen set.
    pub expression: String,
    /// The regression's coefficients by parameter id.
    pub coefficients: std::collections::BTreeMap<String, f64>,
    /// Terms left out of the expression as negligible.
    pub omitted_terms: usize,
}

impl AnalysisReport {
    /// The document of `an` for `robot`; `unseen` the parameters the default selection left
    /// out.
    pub fn new(an: &Analysis, robot: &Robot, unseen: &[ParamId]) -> AnalysisReport {
        let sq = |v: &[f64]| v.iter().map(|s| s * s).collect::<Vec<_>>();
        let finite = |v: f64| v.is_finite().then_some(v);
        let coefficients = |terms: &[(ParamId, f64)]| {
            terms
                .iter()
                .map(|(id, c)| (id.to_string(), *c))
                .collect::<std::collections::BTreeMap<_, _>>()
        };
        AnalysisReport {
            schema_version: SCHEMA_VERSION,
            robot: robot.name.clone(),
            parameters: an.parameters.len(),
            parameter_ids: ids(&an.parameters),
            residuals: an.residuals,
            rank: an.rank,
            rcond: an.rcond,
            gap_rank: an.gap_rank,
            gap_ratio: finite(an.gap_ratio),
            rank_consistent: an.rank_consistent,
            expected_rank: an.expected.as_ref().map(|e| e.rank),
            expected_rank_formula: an.expected.as_ref().map(|e| e.formula.clone()),
            singular_values_jacobian: an.singular_values_scaled.clone(),
            singular_values_hessian: sq(&an.singular_values_scaled),
            singular_values_jacobian_file_units: an.singular_values_file.clone(),
            singular_values_hessian_file_units: sq(&an.singular_values_file),
            condition_number: finite(an.condition_number()),
            condition_number_file_units: finite(an.condition_number_file()),
            unobservable: ids(&an.unobservable),
            identical_groups: an
                .identical_groups
                .iter()
                .map(|g| g.terms.iter().map(|(id, _)| id.to_string()).collect())
                .collect(),
            identical_combinations: an
                .identical_groups
                .iter()
                .map(|g| IdenticalCombination {
                    expression: format_combination(&g.terms),
                    coefficients: coefficients(&g.terms),
                    value: g.value,
                    determined: g.determined,
                })
                .collect(),
            null_space: an.null_space.iter().map(|row| coefficients(row)).collect(),
            identifiable: ids(&an.identifiable),
            undetermined: an
                .parameters
                .iter()
                .zip(&an.determined)
                .filter(|(_, d)| !**d)
                .map(|(id, _)| id.to_string())
                .collect(),
            euler_singular: an.euler_singular.clone(),
            warnings: an.warnings.iter().map(ToString::to_string).collect(),
            warning_details: an.warnings.clone(),
            noise_dependent: an
                .noise_dependent
                .iter()
                .map(|d| NoiseDependentReport {
                    id: d.id.to_string(),
                    name: robot.param_name(d.id),
                    ratio: d.ratio,
                    sigma: d.sigma,
                    unit: robot.param_unit(d.id),
                    sine: d.sine,
                    expression: d.expression(),
                    coefficients: coefficients(&d.terms),
                    omitted_terms: d.omitted,
                })
                .collect(),
            noise_rule: an.noise_rule.clone(),
            unseen: ids(unseen),
        }
    }

    /// Pretty-printed JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("a report is plain data JSON can hold")
    }
}

/// The JSON Schema of [`AnalysisReport`], as shipped in `schemas/analysis.schema.json`.
pub fn analysis_schema() -> String {
    let schema = schemars::schema_for!(AnalysisReport);
    serde_json::to_string_pretty(&schema).expect("a schema is JSON") + "\n"
}

#[cfg(test)]
mod observation_error_tests {
    use super::*;

    #[test]
    fn typed_fields_read_back_as_written() {
        use crate::estimation::Termination;
        for t in Termination::ALL {
            let text = serde_json::to_string(&t).unwrap();
            assert_eq!(text, format!("\"{}\"", t.describe()));
            assert_eq!(serde_json::from_str::<Termination>(&text).unwrap(), t);
        }
        assert!(serde_json::from_str::<Termination>("\"done\"").is_err());
        let u: crate::units::LengthUnit = serde_json::from_str("\"mm\"").unwrap();
        assert_eq!(u, crate::units::LengthUnit::Mm);
        assert!(serde_json::from_str::<crate::units::LengthUnit>("\"furlong\"").is_err());
    }

    #[test]
    fn bin_widths_are_round() {
        assert!((nice_width(0.00043) - 0.0005).abs() < 1e-15);
        assert!((nice_width(1.5) - 2.0).abs() < 1e-15);
        assert!((nice_width(7.0) - 10.0).abs() < 1e-15);
        assert!((nice_width(0.0) - 1.0).abs() < 1e-15);
    }

    #[test]
    #[allow(clippy::float_cmp)] // the maxima are copies of the values: equal, not close
    fn long_series_are_kept_as_the_largest_of_each_run() {
        // Up to the limit, every value at its own observation number.
        let e = |v: &[f64]| v.iter().map(|&x| (x, None)).collect::<Vec<_>>();
        let r = ObservationErrors::new("position", &e(&[1.0, 5.0, 2.0]), &e(&[1.0, 5.0, 2.0]));
        assert_eq!((r.run, r.after.clone()), (1, vec![1.0, 5.0, 2.0]));
        assert!(r.attitude_after.is_none());
        assert_eq!(r.histogram.iter().sum::<usize>(), 3);
        // Beyond it, runs of equal length (the last shorter), each point its run's largest
        // value; one large value among a million is kept; the histogram counts every one.
        let n = 1_000_001;
        let mut v: Vec<(f64, Option<f64>)> = vec![(1.0, Some(0.5)); n];
        v[777_777] = (9.0, None);
        let r = ObservationErrors::new("position", &v, &v);
        assert_eq!(r.run, 501);
        assert!(
            r.after.len() <= ObservationErrors::MAX_POINTS,
            "{}",
            r.after.len()
        );
        assert_eq!(r.after.iter().filter(|&&y| y == 9.0).count(), 1);
        assert_eq!(r.after[777_777 / 501], 9.0);
        assert!(r.after.iter().all(|&y| y == 1.0 || y == 9.0));
        // Attitudes: a run's largest, the run with the position-only row still has others.
        let att = r.attitude_after.as_ref().unwrap();
        assert!(att.iter().all(|a| *a == Some(0.5)));
        assert_eq!(r.histogram.iter().sum::<usize>(), n);
        let all_none = vec![(1.0, None), (2.0, Some(1.0))];
        let r = ObservationErrors::new("position", &all_none, &all_none);
        assert_eq!(r.attitude_after, Some(vec![None, Some(1.0)]));
    }
}
