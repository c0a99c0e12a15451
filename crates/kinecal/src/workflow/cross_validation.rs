//! Cross-validation: the same request run on training folds, each checked on the postures it
//! left out, and the held-out errors summarised (lengths in metres).

use std::sync::Arc;

use crate::error::{Error, Result};
use crate::model::params::ParamId;
use crate::model::robot::Robot;
use crate::units::Quantity;

use super::request::{Request, Validation};

/// The result of cross-validation ([`Validation::Folds`]), in the metric that judges the
/// model: positions when the data has them, else the first other length metric.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct CrossValidation {
    /// The folds' shuffle seed (`None`: interleaved).
    pub seed: Option<u64>,
    /// Each fold: its held-out postures and errors (m).
    pub folds: Vec<Fold>,
    /// The held-out errors of all folds together (m).
    pub overall: crate::observe::MetricAccuracy,
    /// A bootstrap 95 % interval of the overall held-out mean (m): 2000 resamples of the
    /// held-out errors, percentiles 2.5 and 97.5.
    pub mean_interval: (f64, f64),
}

/// One fold of a cross-validation: what was held out, what the fit on the rest estimated and
/// could determine, and how it did on the held-out postures.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct Fold {
    /// Postures held out.
    pub postures: usize,
    /// Their labels.
    pub held_out: Vec<String>,
    /// The held-out errors (m).
    pub errors: crate::observe::MetricAccuracy,
    /// The held-out posture with the largest error, and that error (m).
    pub worst: Option<(String, f64)>,
    /// Whether the fold's fit converged.
    pub converged: bool,
    /// The parameters the fold's fit estimated.
    pub estimated: Vec<ParamId>,
    /// The numerical rank of its estimated parameters (absent when the uncertainty could not
    /// be computed).
    pub rank: Option<usize>,
}

/// What cross-validation keeps of a fold's fit.
pub(super) struct FoldFit {
    /// The robot the fold's fit calibrated.
    pub calibrated: Robot,
    /// Whether the fit converged.
    pub converged: bool,
    /// The parameters it estimated.
    pub estimated: Vec<ParamId>,
    /// The numerical rank of those parameters, when the uncertainty was computed.
    pub rank: Option<usize>,
}

/// Runs `req` through `fit` on each training fold and checks it on the postures left out.
/// `fit` is the calibration workflow itself ([`super::run()`](fn@super::run)), passed in so
/// that the fold loop does not depend on it.
pub(super) fn cross_validate(
    req: &Request,
    k: usize,
    seed: Option<u64>,
    fit: &mut dyn FnMut(&Request) -> Result<FoldFit>,
) -> Result<CrossValidation> {
    use crate::observe::MetricAccuracy;
    let folds = req
        .data
        .folds(k, seed)
        .ok_or_else(|| Error::InvalidOption {
            setting: crate::error::Setting::Folds,
            message: format!(
                "expected between 2 and the number of posture groups ({}), got {k}",
                req.data.posture_groups().len()
            ),
        })?;
    let metrics: Vec<&'static str> = crate::observe::errors(&req.robot, &req.data)
        .iter()
        .map(|e| e.metric)
        .collect();
    let metric = if metrics.contains(&"position") {
        "position"
    } else {
        metrics.first().copied().unwrap_or("position")
    };
    let summary = |e: Vec<f64>| MetricAccuracy::of_errors(metric, e);
    let mut all = Vec::new();
    let mut out = Vec::with_capacity(k);
    for (train, held) in folds {
        let mut sub = req.clone();
        sub.data = Arc::new(train);
        sub.validation = Validation::None;
        sub.prediction = crate::predict::Level::Off;
        sub.sources = Vec::new();
        let o = fit(&sub)?;
        let mut worst: Option<(String, f64)> = None;
        let mut e = Vec::new();
        for (o, err) in held
            .observations
            .iter()
            .zip(crate::observe::errors(&o.calibrated, &held))
        {
            if err.metric != metric {
                continue;
            }
            if worst.as_ref().is_none_or(|w| err.length > w.1) {
                worst = Some((held.postures[o.posture()].label.clone(), err.length));
            }
            e.push(err.length);
        }
        all.extend(e.iter().copied());
        out.push(Fold {
            postures: held.postures.len(),
            held_out: held.postures.iter().map(|p| p.label.clone()).collect(),
            errors: summary(e),
            worst,
            converged: o.converged,
            estimated: o.estimated,
            rank: o.rank,
        });
    }
    let mean_interval = bootstrap_mean_interval(&all, seed.unwrap_or(0));
    Ok(CrossValidation {
        seed,
        folds: out,
        overall: summary(all),
        mean_interval,
    })
}

/// The report of `cv` in `units`.
pub(super) fn cross_validation_report(
    cv: &CrossValidation,
    robot: &Robot,
) -> crate::report::CrossValidationReport {
    let units = &robot.units;
    use crate::report::{CrossValidationReport, FoldReport, MetricStats};
    let len = |v: f64| units.from_si(Quantity::Length, v);
    let stats = |m: &crate::observe::MetricAccuracy| MetricStats::new(m, units);
    CrossValidationReport {
        seed: cv.seed,
        metric: cv.overall.metric.to_string(),
        folds: cv
            .folds
            .iter()
            .map(|f| FoldReport {
                postures: f.postures,
                held_out: f.held_out.clone(),
                errors: stats(&f.errors),
                worst_posture: f.worst.as_ref().map(|w| w.0.clone()),
                converged: f.converged,
                estimated: f.estimated.iter().map(|&id| robot.param_name(id)).collect(),
                rank: f.rank,
            })
            .collect(),
        overall: stats(&cv.overall),
        mean_low: len(cv.mean_interval.0),
        mean_high: len(cv.mean_interval.1),
    }
}

/// The 2.5 and 97.5 percentiles of the mean of 2000 resamples (with replacement) of `e`.
fn bootstrap_mean_interval(e: &[f64], seed: u64) -> (f64, f64) {
    use rand::{RngExt, SeedableRng};
    if e.is_empty() {
        return (0.0, 0.0);
    }
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed ^ 0x000b_0075_78a9);
    let mut means: Vec<f64> = (0..2000)
        .map(|_| {
            (0..e.len())
                .map(|_| e[rng.random_range(0..e.len())])
                .sum::<f64>()
                / e.len() as f64
        })
        .collect();
    means.sort_by(f64::total_cmp);
    (means[49], means[1949])
}
