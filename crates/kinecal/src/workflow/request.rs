//! What decides a calibration: the [`Request`] (robot, data, what to estimate, how, what to
//! check it on) and its [`Validation`].

use std::sync::Arc;

use crate::identifiability::{self, AnalysisOptions};
use crate::model::params::ParamId;
use crate::model::robot::Robot;
use crate::observe::{Dataset, OrientationError, Weights};
use crate::solve::estimation::{self, Loss, SolverOptions};
use crate::solve::outliers;
use crate::source::Fingerprint;

use super::min_change::SolutionRule;
use super::selection::Selection;

/// Held-out data to check the calibration on.
#[derive(Debug, Clone, PartialEq, Default)]
#[non_exhaustive]
pub enum Validation {
    /// None.
    #[default]
    None,
    /// A separate dataset (shared, not copied, into the outcome).
    Data(Arc<Dataset>),
    /// A fraction of the posture groups (postures an observation links stay together), drawn
    /// with a seed.
    Holdout {
        /// Fraction, strictly between 0 and 1.
        fraction: f64,
        /// Seed of the draw.
        seed: u64,
    },
    /// Cross-validation: the calibration is made on all the data, and the same request run
    /// on `k` training folds, each checked on the postures it left out ([`Dataset::folds`]:
    /// interleaved in posture order, or shuffled with `seed`).
    Folds {
        /// Number of folds, at least 2.
        k: usize,
        /// Shuffle seed; `None` interleaves in posture order.
        seed: Option<u64>,
    },
}

/// Everything that decides a calibration.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct Request {
    /// The nominal robot: the model, the starting point unless `initial` is given, and the
    /// reference of minimum-change answers. The uncertainty is linearised at the reference of
    /// the solution rule (this robot, or `initial` under the solver rule: see the module's
    /// linearisation rule).
    pub robot: Robot,
    /// The observations (shared, not copied, into the outcome).
    pub data: Arc<Dataset>,
    /// What to estimate.
    pub selection: Selection,
    /// Start the solver from this robot's parameter values instead (same structure).
    pub initial: Option<Robot>,
    /// Method and stopping rules.
    pub solver: SolverOptions,
    /// Least squares or Huber.
    pub loss: Loss,
    /// Default residual weights.
    pub weights: Weights,
    /// How rows with standard deviations of their own are weighted (a model-error floor, by
    /// default: see [`crate::solve::estimation::weighting`]).
    pub model_error: crate::solve::estimation::ModelErrorMode,
    /// Orientation residuals.
    pub orientation: OrientationError,
    /// Which of equally good answers.
    pub solution: SolutionRule,
    /// Remove, one at a time, changes below this many standard deviations, refitting after
    /// each.
    pub prune: Option<f64>,
    /// Held-out data.
    pub validation: Validation,
    /// Outlier threshold, in robust standard deviations.
    pub outlier_sigmas: f64,
    /// Parameters to prefer in an identifiable set, most preferred first.
    pub priority: Vec<ParamId>,
    /// Relative singular-value tolerance of the identifiability analysis.
    pub rank_rcond: f64,
    /// A Gaussian prior on the estimated parameters' changes from the solver's start (empty:
    /// none; see [`crate::solve::problem`]). It enters the fit, the uncertainty and the minimum-change
    /// answer; the identifiable set of a [`Selection::Identifiable`] is the data's alone.
    pub prior: crate::model::robot::Prior,
    /// The files read (for the report's fingerprints): the robot file first, then the data.
    pub sources: Vec<Fingerprint>,
    /// How much of the predicted accuracy to work out ([`crate::predict`]): by default the
    /// model-error term and the summary over the joint ranges; the accuracy map too for an HTML
    /// report. The refits of cross-validation and model choice make none.
    pub prediction: crate::predict::Level,
}

impl Request {
    /// Default settings: the default parameters by Levenberg-Marquardt, least squares, default
    /// weights and rotation-vector residuals, the solver's answer, no pruning or validation.
    pub fn new(robot: Robot, data: impl Into<Arc<Dataset>>) -> Request {
        Request {
            robot,
            data: data.into(),
            selection: Selection::default(),
            initial: None,
            solver: SolverOptions::new(estimation::Method::LevenbergMarquardt),
            loss: Loss::Squared,
            weights: Weights::default(),
            model_error: Default::default(),
            orientation: OrientationError::RotVec,
            solution: SolutionRule::Solver,
            prune: None,
            validation: Validation::None,
            outlier_sigmas: outliers::DEFAULT_SIGMAS,
            priority: Vec::new(),
            rank_rcond: identifiability::DEFAULT_RANK_RCOND,
            prior: crate::model::robot::Prior::default(),
            sources: Vec::new(),
            prediction: crate::predict::Level::default(),
        }
    }

    pub(super) fn analysis_options(&self) -> AnalysisOptions {
        AnalysisOptions {
            rcond: self.rank_rcond,
            weights: self.weights,
            orientation: self.orientation,
            priority: self.priority.clone(),
            noise_scale: 1.0,
            prior: crate::model::robot::Prior::default(),
            placed: Vec::new(),
        }
    }
}
