//! What a calibration produced: the [`Outcome`] (the fit, its uncertainty, pruning, accuracy
//! before and after on the identification and validation data, outliers, warnings) and its
//! assembly into the report. Accuracies are in metres and radians; the report's figures are in
//! the robot file's units.

use std::sync::Arc;

use crate::error::Result;
use crate::model::kinematics::Target;
use crate::model::params::{ParamId, ParamKind};
use crate::model::robot::Robot;
use crate::observe::{Accuracy, Dataset};
use crate::report::CalibrationReport;
use crate::solve::estimation::{self, Calibration, Loss};
use crate::solve::outliers::{self, Outlier};
use crate::solve::problem::Problem;
use crate::source::Fingerprint;
use crate::uncertainty::Uncertainty;
use crate::units::Quantity;
use crate::warning::Warning;

use super::cross_validation::CrossValidation;
use super::min_change::SolutionRule;
use super::selection::refit_sessions;

/// A variance factor above this says the stated sigmas are more than 10 times too small
/// ([`Warning::SigmasOff`]); the identifiable set is then chosen again at the residuals' noise.
pub(crate) const SIGMAS_TOO_SMALL: f64 = 100.0;

/// A variance factor below this says the stated sigmas are more than 10 times too large
/// ([`Warning::SigmasOff`]). The set is not chosen again then: the rule at overstated noise
/// errs towards fewer parameters, which the warning names.
pub(crate) const SIGMAS_TOO_LARGE: f64 = 0.01;

/// The pruned refit and what it removed.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct Pruning {
    /// The significance threshold, in standard deviations.
    pub k: f64,
    /// The fit of every selected parameter, before pruning.
    pub full: Calibration,
    /// The full fit's report.
    pub full_report: Box<CalibrationReport>,
    /// The parameters removed, in removal order.
    pub removed: Vec<ParamId>,
}

/// Accuracy before and after calibration on a dataset.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct Checked {
    /// Postures in the dataset.
    pub postures: usize,
    /// Observations in the dataset.
    pub observations: usize,
    /// With the nominal robot (the request's).
    pub before: Accuracy,
    /// With the solver's start, when it is not the nominal robot (its frames placed in
    /// closed form first, or an initial guess).
    pub start: Option<Accuracy>,
    /// With the calibrated robot.
    pub after: Accuracy,
    /// The RMS of the residuals in their own standard deviations (each row's `sigma_*`, else
    /// the weights), with the nominal robot: how far the errors are from what the stated
    /// uncertainties allow (about 1 when they are right).
    pub(crate) normalized_before: f64,
    /// The same with the calibrated robot.
    pub(crate) normalized_after: f64,
}

impl Checked {
    /// `cal` checked on the data it was fitted to: its accuracies are already known.
    /// Under least squares, the objectives before and after are the sums of squared
    /// normalized residuals too.
    fn fitted(cal: &Calibration, data: &Dataset) -> Checked {
        let (before, after) = (cal.accuracy_before.clone(), cal.accuracy_after.clone());
        // The objectives are in the stated sigmas when no row scale (floor or loss) applies.
        let floored = cal
            .model_error
            .is_some_and(|m| m.length > 0.0 || m.angle > 0.0);
        if matches!(cal.options.loss, Loss::Squared) && !floored {
            let m = data.rows().max(1) as f64;
            return Checked {
                postures: data.postures.len(),
                observations: data.observations.len(),
                before,
                start: None,
                after,
                normalized_before: (cal.objective_before / m).sqrt(),
                normalized_after: (cal.objective_after / m).sqrt(),
            };
        }
        Checked {
            before,
            after,
            ..Checked::new(cal, data, data, &cal.initial).0
        }
    }

    /// `cal` checked on other data: one pass of forward kinematics per robot gives both the
    /// accuracy and the normalized residuals. Sessions of `data` that neither the robots frame
    /// nor `identification` has (a tracker moved since) first get their frames re-estimated on
    /// `data` for each robot ([`refit_sessions`]); their names are returned.
    fn new(
        cal: &Calibration,
        data: &Dataset,
        identification: &Dataset,
        nominal: &Robot,
    ) -> (Checked, Vec<String>) {
        let seen = identification.sessions();
        let unseen: Vec<String> = data
            .sessions()
            .iter()
            .filter(|s| cal.calibrated.session_index(s).is_none() && !seen.contains(s))
            .map(|s| s.to_string())
            .collect();
        let refit = |r: &Robot| {
            if unseen.is_empty() {
                r.clone()
            } else {
                refit_sessions(r, data, &unseen, &cal.options)
            }
        };
        let (initial, calibrated) = (refit(&cal.initial), refit(&cal.calibrated));
        let nominal = (cal.initial != *nominal).then(|| refit(nominal));
        // One table of the readings' sines and cosines serves both robots when the calibration
        // kept the slopes and couplings.
        let p = Problem::new(
            &initial,
            data,
            &[],
            cal.options.weights,
            cal.options.orientation,
        )
        .with_reading_trig();
        let mut r = vec![0.0; p.rows()];
        let mut check = |robot: &Robot| {
            let m = p.rows().max(1);
            let (f, acc, _) = p.evaluate_checked(robot, &mut r);
            ((f / m as f64).sqrt(), acc)
        };
        let (normalized_start, start) = check(&initial);
        let (normalized_after, after) = check(&calibrated);
        let (normalized_before, before, start) = match &nominal {
            Some(n) => {
                let (nb, b) = check(n);
                (nb, b, Some(start))
            }
            None => (normalized_start, start, None),
        };
        (
            Checked {
                postures: data.postures.len(),
                observations: data.observations.len(),
                before,
                start,
                after,
                normalized_before,
                normalized_after,
            },
            unseen,
        )
    }
}

/// What a calibration produced.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct Outcome {
    /// The nominal robot of the request.
    pub nominal: Robot,
    /// The identification data (the request's data minus any hold-out).
    pub data: Arc<Dataset>,
    /// The validation data, when there was some.
    pub validation_data: Option<Arc<Dataset>>,
    /// The calibration (after pruning, when pruned).
    pub calibration: Calibration,
    /// Its uncertainty, linearised at the reference of the solution rule (the module's
    /// linearisation rule); `None` when it cannot be computed
    /// (a warning says why).
    pub uncertainty: Option<Uncertainty>,
    /// The pruning, when asked for.
    pub pruning: Option<Pruning>,
    /// Accuracy on the identification data.
    pub identification: Checked,
    /// Accuracy on the validation data.
    pub validation: Option<Checked>,
    /// Outliers of the identification data.
    pub outliers: Vec<Outlier>,
    /// Everything the user should know.
    pub warnings: Vec<Warning>,
    /// The closed-form placement of the measurement and target frames done first, when the
    /// start was far ([`crate::solve::registration`]).
    pub registration: Option<crate::solve::registration::Registration>,
    /// The cross-validation, when asked for ([`Validation::Folds`](super::Validation::Folds)).
    pub cross_validation: Option<CrossValidation>,
    /// The report document.
    pub report: CalibrationReport,
}

/// The fitted values outside their physical range: negative compliances (beyond twice their
/// standard deviation, when `unc` gives one: a compliance the data puts at 0 may land a little
/// below it), slopes far from the robot file's ([`crate::warning`]'s limits), named with their
/// values in file units.
fn plausibility(nominal: &Robot, cal: &Calibration, unc: Option<&Uncertainty>) -> Vec<Warning> {
    let sigma = |id: ParamId| {
        unc.and_then(|u| u.parameters.iter().find(|p| p.id == id))
            .and_then(|p| p.sigma)
    };
    let robot = &cal.calibrated;
    let value = |id: ParamId| {
        format!(
            "{} = {:.6} {}",
            robot.param_name(id),
            robot.get_user(id),
            robot.param_unit(id)
        )
    };
    let negative: Vec<String> = cal
        .estimated
        .iter()
        .copied()
        .filter(|&id| {
            matches!(
                robot.param_kind(id),
                ParamKind::Compliance { .. } | ParamKind::Lateral { .. }
            ) && robot.get(id) < 0.0
                && sigma(id).is_none_or(|s| robot.get_user(id).abs() > 2.0 * s)
        })
        .map(value)
        .collect();
    let slopes: Vec<String> = cal
        .estimated
        .iter()
        .copied()
        .filter(|&id| {
            let was = nominal.get(id);
            matches!(robot.param_kind(id), ParamKind::Slope { .. })
                && was.abs() > 0.0
                && ((robot.get(id) - was) / was).abs() > crate::warning::SLOPE_CHANGE
        })
        .map(value)
        .collect();
    let mut out = Vec::new();
    if !negative.is_empty() {
        out.push(Warning::NegativeCompliance {
            parameters: negative,
        });
    }
    if !slopes.is_empty() {
        out.push(Warning::SlopeFarOff { parameters: slopes });
    }
    out
}

/// Assembles an outcome: validation, outliers, warnings, the report.
#[allow(clippy::too_many_arguments)]
pub(super) fn finish(
    nominal: Robot,
    data: Arc<Dataset>,
    validation_data: Option<Arc<Dataset>>,
    cal: Calibration,
    unc: Result<Uncertainty>,
    pruning: Option<Pruning>,
    outlier_sigmas: f64,
    solution: SolutionRule,
    sources: &[Fingerprint],
    warnings: &mut Vec<Warning>,
) -> Outcome {
    result_warnings(&nominal, &data, &cal, unc.as_ref().ok(), warnings);
    let uncertainty = match unc {
        Ok(u) => {
            uncertainty_warnings(&nominal, &u, warnings);
            Some(u)
        }
        Err(e) => {
            warnings.push(Warning::NoUncertainty {
                reason: e.to_string(),
            });
            None
        }
    };
    warnings.extend(termination_warning(&cal));
    let outliers = outliers::outliers_of_fit(&cal, &data, outlier_sigmas);
    let mut identification = Checked::fitted(&cal, &data);
    let validation = validation_data
        .as_ref()
        .map(|v| Checked::new(&cal, v, &data, &nominal));
    let mut report = CalibrationReport::new(&cal, &data);
    if let Some(v) = &validation_data {
        warnings.extend(unseen_targets(&data, v, &cal.calibrated));
    }
    if let Some(e) = report.elastic.as_ref() {
        warnings.extend(elastic_warnings(e, &cal.calibrated, &data));
    }
    if let Some((objective, accuracy)) = &nominal_figures(&nominal, &cal, &data) {
        report.set_nominal(*objective, accuracy, &nominal.units);
        identification.start = Some(std::mem::replace(
            &mut identification.before,
            accuracy.clone(),
        ));
        identification.normalized_before = (objective / data.rows().max(1) as f64).sqrt();
    }
    report.set_normalized([
        identification.normalized_before,
        identification.normalized_after,
    ]);
    report.set_outliers(
        &outliers,
        &data,
        &cal.calibrated,
        outliers::threshold(outlier_sigmas, data.rows()),
    );
    if let Some((v, refitted)) = &validation {
        report.set_validation(
            v.postures,
            v.observations,
            &v.before,
            &v.after,
            [v.normalized_before, v.normalized_after],
            &cal.calibrated,
        );
        report.set_validation_sessions(refitted.clone());
        if let Some(s) = &v.start {
            report.set_validation_start(s, &nominal.units);
        }
    }
    let validation = validation.map(|(v, _)| v);
    if let Some(v) = &validation {
        warnings.extend(worse_on_validation(v, &cal.calibrated));
    }
    if let Some(u) = &uncertainty {
        report.set_uncertainty(&cal, u);
    }
    if let Some(p) = &pruning {
        report.set_pruning(p.k, &p.removed, &p.full);
    }
    report.set_warnings(warnings);
    report.set_sources(sources);
    report.set_solution(solution.as_str());
    Outcome {
        nominal,
        data,
        validation_data,
        calibration: cal,
        uncertainty,
        pruning,
        identification,
        validation,
        outliers,
        warnings: std::mem::take(warnings),
        registration: None,
        cross_validation: None,
        report,
    }
}

/// Warnings about the fit's result: implausible values ([`crate::observe::sanity`]), a
/// model-error floor in use, positions or attitudes left far off, physical quantities out of
/// their range ([`plausibility`]), parameters no residual felt.
fn result_warnings(
    nominal: &Robot,
    data: &Dataset,
    cal: &Calibration,
    unc: Option<&Uncertainty>,
    warnings: &mut Vec<Warning>,
) {
    warnings.extend(crate::observe::sanity::check_result(
        nominal,
        &cal.calibrated,
        &cal.estimated,
    ));
    if let Some(m) = cal.model_error.filter(|m| m.length > 0.0 || m.angle > 0.0) {
        let kinds = crate::solve::estimation::weighting::row_kinds(data);
        let own: Vec<f64> = kinds
            .iter()
            .zip(&cal.residuals)
            .filter(|((_, own), _)| *own)
            .map(|(_, r)| r * r)
            .collect();
        let (rows, above) = crate::solve::estimation::weighting::rows_above_floor(data, &m);
        warnings.push(Warning::ModelErrorFloor {
            scale: (own.iter().sum::<f64>() / own.len().max(1) as f64).sqrt(),
            length_mm: m.length * 1e3,
            angle_deg: m.angle.to_degrees(),
            rows,
            above,
        });
    }
    if super::restart::positions_unfit(nominal, cal) {
        let (u, reach) = (nominal.units, nominal.reach());
        warnings.push(Warning::PositionsUnfit {
            rms: u.from_si(Quantity::Length, cal.accuracy_after.rms_position),
            reach: u.from_si(Quantity::Length, reach),
            unit: u.length.to_string(),
        });
    }
    if cal.accuracy_after.orientations > 0
        && cal.accuracy_after.rms_orientation > crate::observe::sanity::ATTITUDE_LIMIT
    {
        warnings.push(Warning::AttitudesUnfit {
            rms_deg: cal.accuracy_after.rms_orientation.to_degrees(),
        });
    }
    warnings.extend(plausibility(nominal, cal, unc));
    if !cal.unfelt.is_empty() {
        warnings.push(Warning::Unfelt {
            parameters: cal
                .unfelt
                .iter()
                .map(|&id| cal.calibrated.param_name(id))
                .collect(),
        });
    }
}

/// Warnings about the uncertainty: standard deviations that do not describe the residuals,
/// parameters determined loosely yet moved by many sigmas, strong correlations, and the
/// analysis's own (those not already in `warnings`).
fn uncertainty_warnings(nominal: &Robot, u: &Uncertainty, warnings: &mut Vec<Warning>) {
    if u.dof > 0 && !(SIGMAS_TOO_LARGE..=SIGMAS_TOO_SMALL).contains(&u.variance_factor) {
        warnings.push(Warning::SigmasOff {
            variance_factor: u.variance_factor,
        });
    }
    let loose: Vec<String> = u
        .parameters
        .iter()
        .filter_map(|p| {
            let s = p.sigma?;
            let q = nominal.param_quantity(p.id);
            let tolerance = nominal.units.from_si(q, nominal.tolerance(p.id));
            let moved = p.change.abs() / s;
            (s > tolerance && moved > crate::warning::LOOSE_MOVE_SIGMAS)
                .then(|| format!("{} ({moved:.1} sigma)", nominal.param_name(p.id)))
        })
        .collect();
    if !loose.is_empty() {
        warnings.push(Warning::LooseAndMoved { parameters: loose });
    }
    for &(a, b, rho) in &u.correlations {
        warnings.push(Warning::Correlated {
            a: a.to_string(),
            b: b.to_string(),
            rho,
        });
    }
    for w in &u.analysis.warnings {
        if !warnings.contains(w) {
            warnings.push(w.clone());
        }
    }
}

/// The nominal robot's objective and accuracy on `data`, when the solver started elsewhere
/// (frames placed in closed form, an initial guess): "before" is then the nominal robot, and
/// the start is said apart.
fn nominal_figures(nominal: &Robot, cal: &Calibration, data: &Dataset) -> Option<(f64, Accuracy)> {
    (cal.initial != *nominal).then(|| {
        let p = Problem::new(
            nominal,
            data,
            &[],
            cal.options.weights,
            cal.options.orientation,
        );
        let mut r = vec![0.0; p.rows()];
        let (objective, accuracy, _) = p.evaluate_checked(nominal, &mut r);
        (objective, accuracy)
    })
}

/// The warning for a fit that did not converge: stopped at the iteration cap, stalled, or at
/// a point where the Jacobian lost rank.
fn termination_warning(cal: &Calibration) -> Option<Warning> {
    match cal.termination {
        estimation::Termination::MaxIterations => Some(Warning::NotConverged {
            iterations: cal.iterations,
        }),
        estimation::Termination::Stalled => Some(Warning::Stalled {
            method: cal.options.solver.method.as_str().to_string(),
        }),
        estimation::Termination::RankLost => Some(Warning::RankLost {
            start_rank: cal.stationarity.start_rank,
            rank: cal.stationarity.rank,
        }),
        _ => None,
    }
}

/// The validation data's targets (sites, end effector) that no identification row measures,
/// named: their held-out errors say nothing about the calibration.
fn unseen_targets(data: &Dataset, validation: &Dataset, calibrated: &Robot) -> Option<Warning> {
    let seen: std::collections::HashSet<Target> = data
        .observations
        .iter()
        .flat_map(|o| o.views().iter().map(|v| v.target))
        .collect();
    let mut unseen: Vec<String> = Vec::new();
    for o in &validation.observations {
        for view in o.views() {
            let name = crate::observe::target_name(calibrated, view.target).to_string();
            if !seen.contains(&view.target) && !unseen.contains(&name) {
                unseen.push(name);
            }
        }
    }
    (!unseen.is_empty()).then_some(Warning::ValidationTargetsUnseen { targets: unseen })
}

/// An elastic robot's warnings: a deflection beyond [`crate::warning::DEFLECTION_LIMIT`], and
/// postures whose equilibrium did not converge.
fn elastic_warnings(
    e: &crate::report::ElasticReport,
    calibrated: &Robot,
    data: &Dataset,
) -> Vec<Warning> {
    let mut out = Vec::new();
    let deflection = calibrated
        .units
        .to_si(Quantity::Angle, e.largest_deflection.abs());
    if deflection > crate::warning::DEFLECTION_LIMIT {
        out.push(Warning::LargeDeflection {
            degrees: deflection.to_degrees(),
        });
    }
    if e.unconverged_postures > 0 {
        out.push(Warning::EquilibriumNotConverged {
            postures: e.unconverged_postures,
            of: data.postures.len(),
        });
    }
    out
}

/// Held-out errors that grew with the calibration (by more than a part in a million), per
/// metric, against the start when it is not the nominal robot (a nominal whose frames were far
/// off says nothing); a camera's in pixels, the others in the robot file's length unit.
fn worse_on_validation(v: &Checked, calibrated: &Robot) -> Vec<Warning> {
    let len = |x: f64| calibrated.units.from_si(Quantity::Length, x);
    let mut out = Vec::new();
    let mut worse = |metric: &str, before: f64, after: f64| {
        if after > before * (1.0 + 1e-6) {
            let pixel = metric == "pixel";
            out.push(Warning::WorseOnValidation {
                metric: metric.to_string(),
                before: if pixel { before } else { len(before) },
                after: if pixel { after } else { len(after) },
                unit: if pixel {
                    "px".to_string()
                } else {
                    calibrated.units.length.to_string()
                },
            });
        }
    };
    let base = v.start.as_ref().unwrap_or(&v.before);
    if base.positions > 0 {
        worse("position", base.mean_position, v.after.mean_position);
    }
    for (b, a) in base.other.iter().zip(&v.after.other) {
        worse(b.metric, b.mean, a.mean);
    }
    out
}

/// Warnings about the data itself: units that do not match the robot file's, readings the
/// robot cannot take ([`crate::observe::sanity`]; `predicted`: `robot`'s points,
/// [`crate::observe::sanity::predicted`]).
pub(super) fn data_warnings(
    robot: &Robot,
    data: &Dataset,
    predicted: &[[nalgebra::Vector3<f64>; 2]],
) -> Vec<Warning> {
    let mut warnings = crate::observe::sanity::check_data_with(robot, data, predicted);
    // Placements pooled without sessions spread unlike the robot too: said as what they are,
    // not as a unit mix-up.
    if let Some(pooled) = super::placements::pooled_placements(robot, data, predicted) {
        warnings.retain(|w| !matches!(w, Warning::ScaleMismatch { .. }));
        warnings.push(pooled);
    }
    warnings
}
