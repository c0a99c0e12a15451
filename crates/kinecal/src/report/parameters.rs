//! A calibration's parameters in its report: each one's change and uncertainty, the prior, the
//! determined combinations, correlations, the spectrum and the pruning.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// One parameter's line in the report.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
#[non_exhaustive]
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
#[non_exhaustive]
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
#[non_exhaustive]
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
#[non_exhaustive]
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
#[non_exhaustive]
pub struct CorrelationReport {
    /// First parameter id.
    pub a: String,
    /// Second parameter id.
    pub b: String,
    /// Correlation coefficient.
    pub rho: f64,
}

/// The fit before pruning, when `--prune` was used.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
#[non_exhaustive]
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

/// The singular-value spectrum of the scaled Jacobian at the solution, and what it says.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
#[non_exhaustive]
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
#[non_exhaustive]
pub struct GroupReport {
    /// The combination, e.g. `p3 + p9`.
    pub expression: String,
    /// Its value.
    pub value: f64,
    /// Whether the data determines it (its members enter no other dependency).
    pub determined: bool,
}
