//! The progress of a calibration: its phases, and what receives them ([`Progress`]), apart
//! from the run so that the steps the run calls (a restart from other starts) can report too.

use crate::solve::estimation::Iteration;
use crate::warning::Warning;

/// The phases of a calibration, for progress displays and the report's timings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Phase {
    /// Checking the data and placing the measurement frame (before the first other phase).
    Preparation,
    /// Choosing the identifiable parameters.
    Selection,
    /// Estimating (iterations follow).
    Estimation,
    /// Computing the uncertainty.
    Uncertainty,
    /// Pruning (refits follow).
    Pruning,
    /// Validation, outliers and the report.
    Report,
    /// Cross-validation (a calibration per fold).
    CrossValidation,
    /// The predicted accuracy (the model error's cross-validation, the summary, the map).
    Prediction,
    /// Writing the outputs (after the calibration: not among the report's timings).
    Writing,
}

impl Phase {
    /// The phase's name in reports (`estimation`, ...).
    pub fn as_str(self) -> &'static str {
        match self {
            Phase::Preparation => "preparation",
            Phase::Selection => "selection",
            Phase::Estimation => "estimation",
            Phase::Uncertainty => "uncertainty",
            Phase::Pruning => "pruning",
            Phase::Report => "report",
            Phase::CrossValidation => "cross-validation",
            Phase::Prediction => "prediction",
            Phase::Writing => "writing",
        }
    }
}

/// Receives the progress of a calibration. Every method does nothing by default.
pub trait Progress {
    /// A phase starts.
    fn phase(&mut self, _phase: Phase) {}
    /// An iteration of the solver ended.
    fn iteration(&mut self, _it: &Iteration) {}
    /// The data was checked against the nominal robot before any solving (units, attitudes,
    /// readings): `warnings` are what was found, empty when all
    /// is well. Returning false stops the run there ([`crate::error::Error::Stopped`]), e.g. for a caller
    /// that treats a warning saying the result would be wrong ([`Warning::implausible`]) as
    /// fatal.
    fn data_checked(&mut self, _warnings: &[Warning]) -> bool {
        true
    }
    /// What is being done now, in words, for a job without phases (`planning: 2000
    /// candidates`, `predicting 100000 postures`).
    fn say(&mut self, _what: &str) {}
}

/// No progress display.
impl Progress for () {}
