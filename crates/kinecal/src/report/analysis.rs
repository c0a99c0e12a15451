//! The document of an identifiability analysis (`kinecal analyze --json`).

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::identifiability::{format_combination, Analysis};
use crate::model::params::ParamId;
use crate::model::robot::Robot;
use crate::warning::Warning;

use super::SCHEMA_VERSION;

fn ids(list: &[ParamId]) -> Vec<String> {
    list.iter().map(ToString::to_string).collect()
}

/// The identifiability analysis as a document: what `kinecal analyze --json` prints and the
/// Python bindings return. Rank, singular values (of the scaled Jacobian and of `J^T J`, also
/// in file units), the identifiable set, identically redundant groups and their combinations,
/// the null space, the parameters dependent within the noise, and warnings.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
#[non_exhaustive]
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
#[non_exhaustive]
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
#[non_exhaustive]
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
