//! The calibration workflow: a [`Request`] in, an [`Outcome`] out.
//!
//! One entry point, [`run`](fn@run), does what a calibration is: set aside the validation data,
//! choose the parameters (a list, or the identifiable set of one), estimate them with the chosen
//! method and loss, pick among equally good answers (the solver's, or the one closest to the
//! nominal robot), compute the uncertainty, prune insignificant changes if asked, check the
//! result on the validation data, list outliers, collect the warnings, and write it all into the
//! [`CalibrationReport`](crate::report::CalibrationReport). The command line, the HTML report,
//! the history and bindings all call it; [`assess`] builds the same outcome for a calibrated
//! robot that already exists, and [`check`](fn@check) tells whether a robot still meets its
//! accuracy.
//!
//! **Linearisation rule.** The identifiable set, the uncertainty and the significance that
//! pruning judges by all use the Jacobian at one point, the *reference* of the solution rule:
//! the nominal robot for minimum-change answers (whose undetermined coordinates it takes), the
//! robot the solver started from (the nominal, or the `initial` guess) for the solver's answer
//! (whose undetermined coordinates it keeps, as damped steps hardly move along directions no
//! residual feels). There the design's exact redundancies hold, and the determined combinations
//! are those of the answer; see [`crate::uncertainty`].

// One file per job: which parameters (`selection`), the run itself (`run`) and what it returns
// (`outcome`), cross-validation (`cross_validation`), the choice among candidate models
// (`model_choice`), the minimum-change answer (`min_change`), and the assessment and check of a
// robot already calibrated (`check`). Everything public is re-exported here.
mod check;
mod cross_validation;
mod min_change;
mod model_choice;
mod outcome;
mod placements;
mod progress;
mod request;
mod restart;
mod run;
mod selection;

pub use check::{assess, check, check_schema, CheckMetric, CheckReport, Thresholds, Verdict};
pub use cross_validation::{CrossValidation, Fold};
pub use min_change::SolutionRule;
pub use model_choice::{choose, Candidate, Choice, Scored, CHOICE_REPEATS};
pub use outcome::{Checked, Outcome, Pruning};
pub use request::{Request, Validation};
pub use run::{run, Phase, Progress};
pub(crate) use selection::{check_total_mass_kept, total_mass_problem};
pub use selection::{default_parameters, refit_sessions, resolve, Selection};

pub(crate) use run::add_prediction;
