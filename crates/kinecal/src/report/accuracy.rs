//! A calibration's errors in its report: before and after, on the identification and the
//! validation data, per observation, by cross-validation, and the outliers.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::model::robot::Robot;
use crate::observe::{Accuracy, Dataset, MetricAccuracy};
use crate::solve::estimation::Calibration;
use crate::units::{Quantity, Units};

/// Error statistics on one dataset, in the robot file's units.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
#[non_exhaustive]
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
            other: a.other.iter().map(|m| MetricStats::new(m, units)).collect(),
        }
    }
}

/// Errors of one metric other than positions (the length unit; pixels for `pixel`, a camera's
/// reprojection error).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
#[non_exhaustive]
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

impl MetricStats {
    /// Converts a [`MetricAccuracy`] to the length unit of `units` (pixels stay pixels).
    pub fn new(m: &MetricAccuracy, units: &Units) -> Self {
        let len = |v: f64| {
            if m.metric == "pixel" {
                v
            } else {
                units.from_si(Quantity::Length, v)
            }
        };
        MetricStats {
            metric: m.metric.to_string(),
            count: m.count,
            rms: len(m.rms),
            mean: len(m.mean),
            p95: len(m.p95),
            max: len(m.max),
        }
    }
}

/// Accuracy before and after calibration on one dataset.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
#[non_exhaustive]
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
#[non_exhaustive]
pub struct KindCount {
    /// `pose`, `position`, `distance`, `contact`.
    pub kind: String,
    /// How many.
    pub count: usize,
}

/// Cross-validation by posture folds (length unit): the same calibration run on each training
/// fold and checked on the postures it left out.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
#[non_exhaustive]
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
#[non_exhaustive]
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
#[non_exhaustive]
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

/// The closed-form placement of a far start ([`crate::solve::registration`]): RMS position error of
/// the start before and after it (length unit).
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq, JsonSchema)]
#[non_exhaustive]
pub struct StartPlacement {
    /// Before.
    pub rms_before: f64,
    /// After.
    pub rms_after: f64,
}

/// The figures of the solver's start on the identification data (robot file's units), when it
/// is not the nominal robot.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
#[non_exhaustive]
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

/// The solver's stationarity measures at its last point ([`crate::solve::estimation::Stationarity`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[non_exhaustive]
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

/// An observation the calibrated model misses by far more than the rest.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
#[non_exhaustive]
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

/// The errors of every observation of `data` with `cal`'s initial and calibrated robots.
pub(crate) fn observation_errors(cal: &Calibration, data: &Dataset) -> ObservationErrors {
    let errors = |robot: &Robot, kept: Option<&crate::observe::KeptErrors>| {
        let u = robot.units;
        let shown = |e: crate::observe::ErrorSample| {
            (
                // Pixels stay pixels.
                if e.metric == "pixel" {
                    e.length
                } else {
                    u.from_si(Quantity::Length, e.length)
                },
                e.angle.map(|a| u.from_si(Quantity::Angle, a)),
            )
        };
        // The errors the calibration's own pass computed for this robot, else a pass here.
        let n = data.observations.len();
        if let Some(samples) = kept.and_then(|k| k.for_robot(robot, n)) {
            return samples.iter().map(|&e| shown(e)).collect();
        }
        let ctx = crate::observe::Context {
            robot,
            orientation: crate::observe::OrientationError::default(),
        };
        let mut out = Vec::with_capacity(n);
        crate::observe::for_each_observation(robot, data, |_, o, frames| {
            out.push(shown(o.error(&ctx, frames)));
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
    ObservationErrors::new(
        metric,
        &errors(&cal.initial, cal.errors_before.as_ref()),
        &errors(&cal.calibrated, cal.errors_after.as_ref()),
    )
}

/// The errors of each observation before and after calibration, as charts draw them: every
/// observation up to [`ObservationErrors::MAX_POINTS`], beyond that the largest of each run of
/// `run` consecutive observations (so that no large error disappears); and the histogram of
/// all the errors after.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
#[non_exhaustive]
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

#[cfg(test)]
mod observation_error_tests {
    use super::*;

    #[test]
    fn typed_fields_read_back_as_written() {
        use crate::solve::estimation::Termination;
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
