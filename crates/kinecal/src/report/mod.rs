//! The machine-readable documents of a calibration and of an analysis (JSON, with JSON Schemas
//! shipped in `schemas/`), in the robot file's units. The [`workflow`](crate::workflow) fills the
//! calibration report in; the history stores it; every renderer reads only it.
//!
//! - [`calibration`]: the report itself and how a calibration's outcome fills it in;
//! - [`parameters`]: its parameters, their combinations, correlations, spectrum and pruning;
//! - [`accuracy`]: errors before and after, validation, cross-validation, outliers;
//! - [`elastic`]: the compliances of an elastic robot;
//! - [`analysis`]: the document of an identifiability analysis;
//! - [`scene`]: the 3-D scene of a calibration (robots, measured points, residuals, frames),
//!   drawn by the HTML report and written as glTF by [`gltf`];
//! - [`validate`]: the checks a report read from a file passes before it is believed.

pub mod accuracy;
pub mod analysis;
pub mod calibration;
pub mod elastic;
pub mod gltf;
pub mod parameters;
pub mod scene;
pub mod validate;

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

pub use accuracy::{
    nice_width, ChoiceReport, CrossValidationReport, DatasetAccuracy, ErrorStats, FoldReport,
    KindCount, MetricStats, ObservationErrors, OutlierReport, StartFigures, StartPlacement,
    StationarityReport,
};
pub use analysis::{analysis_schema, AnalysisReport, IdenticalCombination, NoiseDependentReport};
pub use calibration::CalibrationReport;
pub use elastic::{ElasticReport, StiffnessReport, STIFFNESS_COLUMNS};
pub use parameters::{
    CombinationReport, CorrelationReport, GroupReport, ParameterReport, PriorReport, PruneReport,
    SpectrumReport, TermReport,
};

/// The wall time of one phase.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
#[non_exhaustive]
pub struct PhaseTime {
    /// The phase (`reading`, `preparation`, `selection`, `estimation`, `pruning`,
    /// `uncertainty`, `report`, `cross-validation`, `prediction`, `model choice`: with a
    /// model choice, the chosen model's phases and the other candidates' fits).
    pub phase: String,
    /// Seconds.
    pub seconds: f64,
}

/// Now, in UTC, as RFC 3339 to the second (`2026-11-25T18:21:58Z`).
pub fn now_utc() -> String {
    let now = time::OffsetDateTime::now_utc()
        .replace_nanosecond(0)
        .unwrap_or_else(|_| time::OffsetDateTime::now_utc());
    now.format(&time::format_description::well_known::Rfc3339)
        .unwrap_or_default()
}

pub(crate) fn finite_or_none(v: f64) -> Option<f64> {
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

pub(crate) fn version_one() -> u32 {
    1
}
