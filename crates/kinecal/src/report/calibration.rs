//! The calibration report, and how a calibration's outcome fills it in.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::identifiability::format_combination;
use crate::model::params::ParamId;
use crate::model::robot::Robot;
use crate::observe::{target_name, Accuracy, Dataset};
use crate::solve::estimation::Calibration;
use crate::solve::outliers::Outlier;
use crate::source::Fingerprint;
use crate::uncertainty::{Uncertainty, NOISE_SIGMAS};
use crate::units::{Quantity, Units};
use crate::warning::Warning;

use super::accuracy::observation_errors;
use super::*;

/// The calibration report written by `kinecal calibrate --report`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
#[non_exhaustive]
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
    pub method: crate::solve::estimation::Method,
    /// `euler` or `rotvec`.
    pub orientation_error: crate::observe::OrientationError,
    /// False only when the iteration cap stopped the solver.
    pub converged: bool,
    /// Why the solver stopped.
    pub termination: crate::solve::estimation::Termination,
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
    /// number of rows tested ([`crate::solve::outliers::threshold`]).
    pub outlier_sigmas: f64,
    /// SHA-256 of the robot file, when the caller provides it (history fingerprints).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub robot_file_sha256: Option<String>,
    /// SHA-256 of the (first) measurement file, when the caller provides it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub data_file_sha256: Option<String>,
    /// Every file read, with its SHA-256.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sources: Vec<Fingerprint>,
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
    /// The 3-D scene the HTML report's view draws (the robots at chosen postures, the measured
    /// points, their residuals, the measurement frames: [`super::scene`]), when an HTML report
    /// was asked for; `kinecal export gltf --report` writes the same scene.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scene: Option<super::scene::Scene>,
    /// Why the calibration was refused (a unit check fired and the fit ended far above its
    /// stated noise): its robot was neither written nor recorded. Absent when it stands.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub refused: Option<String>,
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
            prior: crate::model::prior::describe(&cal.options.prior, robot),
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
            given: cal.termination == crate::solve::estimation::Termination::Given,
            robot: robot.name.clone(),
            length_unit: u.length,
            angle_unit: u.angle,
            method: cal.options.solver.method,
            orientation_error: cal.options.orientation,
            converged: cal.converged(),
            termination: cal.termination,
            stationarity: (cal.termination != crate::solve::estimation::Termination::Given).then(
                || StationarityReport {
                    predicted_reduction: cal.stationarity.predicted_reduction,
                    step: finite_or_none(cal.stationarity.step),
                    gradient: cal.stationarity.gradient,
                    rank: cal.stationarity.rank,
                },
            ),
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
                crate::solve::estimation::Loss::Squared => None,
                crate::solve::estimation::Loss::Huber { .. } => {
                    // The robust loss's part of the row scale: the floor's taken out.
                    let floor = match &cal.model_error {
                        Some(m) => crate::solve::estimation::weighting::floor_scale(
                            &crate::solve::estimation::weighting::row_kinds(data),
                            cal.problem(data).row_sigma(),
                            m,
                        ),
                        None => vec![1.0; cal.row_scale.len()],
                    };
                    Some(
                        cal.row_scale
                            .iter()
                            .zip(&floor)
                            .filter(|(&w, &f)| w < f * (1.0 - 1e-9))
                            .count(),
                    )
                }
            },
            timings: Vec::new(),
            outliers: Vec::new(),
            outlier_sigmas: crate::solve::outliers::DEFAULT_SIGMAS,
            robot_file_sha256: None,
            data_file_sha256: None,
            sources: Vec::new(),
            observation_errors: Some(observation_errors(cal, data)),
            spectrum: None,
            elastic: ElasticReport::new(robot, data, &cal.estimated),
            prediction: None,
            scene: None,
            refused: None,
        }
    }

    /// Lists the outliers (see [`crate::solve::outliers`]) found at threshold `k`.
    pub(crate) fn set_outliers(
        &mut self,
        outliers: &[Outlier],
        data: &Dataset,
        robot: &Robot,
        k: f64,
    ) {
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
    pub(crate) fn set_validation(
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
    pub(crate) fn set_nominal(&mut self, objective: f64, accuracy: &Accuracy, units: &Units) {
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
    pub(crate) fn set_validation_start(&mut self, start: &Accuracy, units: &Units) {
        if let Some(v) = &mut self.validation {
            v.start = Some(ErrorStats::new(start, units));
        }
    }

    /// Names the validation data's sessions whose frames were re-estimated.
    pub(crate) fn set_validation_sessions(&mut self, refitted: Vec<String>) {
        if let Some(v) = &mut self.validation {
            v.sessions_refitted = refitted;
        }
    }

    /// Sets the normalized RMS (before, after) of the identification data.
    pub(crate) fn set_normalized(&mut self, before_after: [f64; 2]) {
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
    pub(crate) fn set_pruning(&mut self, k: f64, removed: &[ParamId], full: &Calibration) {
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
    pub(crate) fn set_solution(&mut self, rule: &str) {
        self.solution = rule.to_string();
    }

    /// Sets the warnings.
    pub(crate) fn set_warnings(&mut self, warnings: &[Warning]) {
        self.warnings = warnings.iter().map(ToString::to_string).collect();
        self.warning_details = warnings.to_vec();
    }

    /// Records the files read: the first is the robot file, the second the (first) data file.
    pub(crate) fn set_sources(&mut self, sources: &[Fingerprint]) {
        self.robot_file_sha256 = sources.first().map(|s| s.sha256.clone());
        self.data_file_sha256 = sources.get(1).map(|s| s.sha256.clone());
        self.sources = sources.to_vec();
    }

    /// Pretty-printed JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("report serializes")
    }

    /// Reads a report written by [`CalibrationReport::to_json`], checked for sense before it
    /// is believed ([`super::validate`]): a field that makes none is refused by its JSON path
    /// (`prediction.covariance[3][3]: expected a variance of at least 0 ...`).
    pub fn from_json(text: &str) -> Result<Self, serde_json::Error> {
        let report: CalibrationReport = serde_json::from_str(text)?;
        if report.schema_version > SCHEMA_VERSION {
            return Err(serde::de::Error::custom(format!(
                "written by a newer kinecal (report schema version {}; this kinecal reads up to \
                 {SCHEMA_VERSION})",
                report.schema_version
            )));
        }
        let value: serde_json::Value = serde_json::from_str(text)?;
        super::validate::check(&value, &report).map_err(serde::de::Error::custom)?;
        Ok(report)
    }

    /// Whether `robot` (named `name` in messages) is this report's calibrated robot: every
    /// estimated parameter of the report is one of `robot`'s, at the estimated value (to 1e-9,
    /// relative). An error names the first that is not.
    pub fn check_calibrated(&self, robot: &Robot, name: &str) -> crate::error::Result<()> {
        for p in self.parameters.iter().filter(|p| p.estimated_flag) {
            let id = crate::model::param_list::parse_param_list(&p.id, robot)
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
