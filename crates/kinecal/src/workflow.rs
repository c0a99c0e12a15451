//! The calibration workflow: a [`Request`] in, an [`Outcome`] out.
//!
//! One entry point, [`run`], does what a calibration is: set aside the validation data, choose
//! the parameters (a list, or the identifiable set of one), estimate them with the chosen method
//! and loss, pick among equally good answers (the solver's, or the one closest to the nominal
//! robot), compute the uncertainty, prune insignificant changes if asked, check the result on
//! the validation data, list outliers, collect the warnings, and write it all into the
//! [`CalibrationReport`]. The command line, the HTML report, the history and bindings all call
//! it; [`assess`] builds the same outcome for a calibrated robot that already exists, and
//! [`check`] tells whether a robot still meets its accuracy.
//!
//! **Linearisation rule.** The identifiable set, the uncertainty and the significance that
//! pruning judges by all use the Jacobian at one point, the *reference* of the solution rule:
//! the nominal robot for minimum-change answers (whose undetermined coordinates it takes), the
//! robot the solver started from (the nominal, or the `initial` guess) for the solver's answer
//! (whose undetermined coordinates it keeps, as damped steps hardly move along directions no
//! residual feels). There the design's exact redundancies hold, and the determined combinations
//! are those of the answer; see [`crate::uncertainty`].

use std::sync::Arc;

use crate::error::{Error, Result};
use crate::estimation::{self, Calibration, CalibrationOptions, Iteration, Loss, SolverOptions};
use crate::identifiability::{self, AnalysisOptions};
use crate::observe::{accuracy, Accuracy, Dataset, OrientationError, Weights};
use crate::outliers::{self, Outlier};
use crate::param_list::parse_param_list;
use crate::params::{ParamId, ParamKind};
use crate::problem::{Linearized, Problem};
use crate::report::CalibrationReport;
use crate::robot::Robot;
use crate::source::Source;
use crate::uncertainty::{self, Uncertainty};
use crate::units::{wrap_angle, Quantity};
use crate::warning::Warning;

/// Which parameters to estimate.
#[derive(Debug, Clone, PartialEq)]
pub enum Selection {
    /// The default set (see [`default_parameters`]) minus `fix`.
    Default {
        /// Parameters held.
        fix: Vec<ParamId>,
    },
    /// These parameters.
    List(Vec<ParamId>),
    /// The identifiable (base) set of the default parameters and `with`, minus `fix`, as the
    /// data at the reference robot determines it (see [`crate::identifiability`]).
    Identifiable {
        /// Parameters added to the default set before the selection (`identifiable,slopes`).
        with: Vec<ParamId>,
        /// Parameters held.
        fix: Vec<ParamId>,
    },
}

impl Default for Selection {
    fn default() -> Self {
        Selection::Default { fix: Vec::new() }
    }
}

impl Selection {
    /// Parses a parameter list (see [`crate::param_list`]) and the parameters to hold. An empty
    /// list is the default set. The keyword `identifiable` asks for the identifiable set of the
    /// union of the default set and the other entries: `identifiable` alone is that of the
    /// default set, `identifiable,slopes` adds the slopes first, `all,identifiable` is that of
    /// every parameter.
    pub fn parse(estimate: &str, fix: Option<&str>, robot: &Robot) -> Result<Selection> {
        let tokens: Vec<&str> = if estimate.trim().is_empty() {
            Vec::new()
        } else {
            estimate.split(',').map(str::trim).collect()
        };
        let identifiable = tokens.contains(&"identifiable");
        let rest: Vec<&str> = tokens
            .iter()
            .copied()
            .filter(|t| *t != "identifiable")
            .collect();
        let listed = if rest.is_empty() {
            Vec::new()
        } else {
            parse_param_list(&rest.join(","), robot)?
        };
        let fix = match fix {
            Some(f) => parse_param_list(f, robot)?,
            None => Vec::new(),
        };
        Ok(if identifiable {
            Selection::Identifiable { with: listed, fix }
        } else if rest.is_empty() {
            Selection::Default { fix }
        } else {
            let mut ids = listed;
            ids.retain(|id| !fix.contains(id));
            if ids.is_empty() {
                // Say why: a group this robot has none of, or everything listed also fixed.
                let empty: Vec<&str> = rest
                    .iter()
                    .map(|t| t.trim())
                    .filter(|t| parse_param_list(t, robot).is_ok_and(|v| v.is_empty()))
                    .collect();
                let message = if empty.is_empty() {
                    "no parameter is left to estimate (every listed parameter is also fixed)"
                        .to_string()
                } else {
                    format!(
                        "no parameter to estimate: this robot has no {} (none declared in its file)",
                        empty
                            .iter()
                            .map(|g| match *g {
                                "couplings" => "coupled joints",
                                "planes" => "planes",
                                "sites" => "sites",
                                g => g,
                            })
                            .collect::<Vec<_>>()
                            .join(", ")
                    )
                };
                return Err(Error::ParamList {
                    list: estimate.to_string(),
                    message,
                });
            }
            Selection::List(ids)
        })
    }
}

/// The parameters a selection stands for on `data`, analysed at `robot` with `opts` (sorted),
/// and the default parameters left out because no observation sees them.
pub fn resolve(
    selection: &Selection,
    robot: &Robot,
    data: &Dataset,
    opts: &AnalysisOptions,
) -> Result<(Vec<ParamId>, Vec<ParamId>)> {
    resolve_linearized(selection, robot, data, opts).map(|(ids, unseen, _)| (ids, unseen))
}

/// [`resolve`], with the linearisation the identifiability analysis made at `robot` (over the
/// candidates) when it ran: a fit starting at `robot` needs no first pass.
fn resolve_linearized(
    selection: &Selection,
    robot: &Robot,
    data: &Dataset,
    opts: &AnalysisOptions,
) -> Result<(Vec<ParamId>, Vec<ParamId>, Option<Linearized>)> {
    let mut lin = None;
    let (mut ids, unseen) = match selection {
        Selection::Default { fix } => {
            let (mut ids, unseen) = default_parameters(robot, data);
            ids.retain(|id| !fix.contains(id));
            (ids, unseen)
        }
        Selection::List(ids) => (ids.clone(), Vec::new()),
        Selection::Identifiable { with, fix } => {
            let (mut ids, unseen) = default_parameters(robot, data);
            ids.extend(with.iter().copied());
            ids.sort();
            ids.dedup();
            ids.retain(|id| !fix.contains(id));
            if ids.is_empty() {
                return Err(Error::NothingToEstimate);
            }
            let (analysis, at) = identifiability::analyze_linearized(robot, data, &ids, opts)?;
            lin = Some(at);
            (analysis.identifiable, unseen)
        }
    };
    ids.sort();
    ids.dedup();
    if ids.is_empty() {
        return Err(Error::NothingToEstimate);
    }
    Ok((ids, unseen, lin))
}

/// The default parameters on `data`: every link and site parameter and every joint offset, and
/// the slopes unless every slope is 1 in the file's units (readings that are already joint
/// values); coupling factors and planes only when named. Left out, and returned second, are the
/// parameters of frames no observation sees: a site or the end effector never observed (their
/// link's six), or observed by position only (its three angles).
pub fn default_parameters(robot: &Robot, data: &Dataset) -> (Vec<ParamId>, Vec<ParamId>) {
    use crate::kinematics::Target;
    use crate::params::LinkComponent;
    let unit_slopes = robot
        .joints
        .iter()
        .all(|j| (robot.units.from_si(j.kind.slope(), j.slope) - 1.0).abs() < 1e-12);
    // The degrees of freedom observed of a frame (0, 3 or 6).
    let seen = |t: Target| {
        data.observations
            .iter()
            .filter(|o| o.measured_frame().0 == t)
            .map(|o| o.measured_frame().1)
            .max()
            .unwrap_or(0)
    };
    let ee = seen(Target::EndEffector);
    let last = robot.links.len() - 1;
    let unseen_component = |dof: usize, c: LinkComponent| {
        dof == 0 || (dof < 6 && c.quantity() == crate::units::Quantity::Angle)
    };
    let (mut ids, mut unseen) = (Vec::new(), Vec::new());
    for id in robot.param_ids() {
        let default = match robot.param_kind(id) {
            ParamKind::Link { link, component } => {
                if link == last && unseen_component(ee, component) {
                    unseen.push(id);
                    false
                } else {
                    true
                }
            }
            ParamKind::Site { site, component } => {
                if unseen_component(seen(Target::Site(site)), component) {
                    unseen.push(id);
                    false
                } else {
                    true
                }
            }
            ParamKind::Offset { .. } => true,
            ParamKind::Slope { .. } => !unit_slopes,
            ParamKind::Coupling { .. } | ParamKind::Plane { .. } => false,
            // A session's frame is estimated wherever its observations are.
            ParamKind::Session { session, .. } => {
                let name = robot.sessions[session].name.as_str();
                data.postures
                    .iter()
                    .any(|p| p.session.as_deref() == Some(name))
            }
        };
        if default {
            ids.push(id);
        }
    }
    (ids, unseen)
}

/// `robot` with its rigid frames fitted to `data` by least squares, the rest held: the first
/// link (the measurement frame), the last link and the sites (the measured targets' frames) and
/// the sessions' frames, those of them among `candidates`; `robot` itself when the fit does not
/// lower the objective.
fn rigid_fit(robot: &Robot, data: &Dataset, candidates: &[ParamId], req: &Request) -> Robot {
    let last = robot.links.len() - 1;
    let ids: Vec<ParamId> = candidates
        .iter()
        .copied()
        .filter(|&id| {
            matches!(
                robot.param_kind(id),
                ParamKind::Link { link: 0, .. }
                    | ParamKind::Site { .. }
                    | ParamKind::Session { .. }
            ) || matches!(robot.param_kind(id), ParamKind::Link { link, .. } if link == last)
        })
        .collect();
    if ids.is_empty() {
        return robot.clone();
    }
    let mut ids = ids;
    ids.sort();
    ids.dedup();
    let opts = CalibrationOptions {
        estimate: ids,
        solver: SolverOptions::new(estimation::Method::LevenbergMarquardt),
        weights: req.weights,
        orientation: req.orientation,
        loss: Loss::Squared,
    };
    match estimation::calibrate(robot, data, &opts, &mut |_| {}) {
        Ok(c) if c.objective_after < c.objective_before && c.calibrated.validate().is_ok() => {
            c.calibrated
        }
        _ => robot.clone(),
    }
}

/// `robot` with frames for the sessions `names` of `data`, placed in closed form and then
/// estimated on `data` (their six parameters each, the robot held, with `opts`' weights and
/// residuals): how a robot is checked on data measured from somewhere it has not been told.
pub fn refit_sessions(
    robot: &Robot,
    data: &Dataset,
    names: &[String],
    opts: &CalibrationOptions,
) -> Robot {
    let mut r = robot.clone();
    let first = r.sessions.len();
    for name in names {
        r.sessions.push(crate::robot::Session {
            name: name.clone(),
            frame: crate::robot::Link::default(),
        });
    }
    let ids: Vec<ParamId> = r
        .param_ids()
        .filter(|&id| matches!(r.param_kind(id), ParamKind::Session { session, .. } if session >= first))
        .collect();
    if let Some((placed, _, _)) = crate::registration::place_sessions(&r, data, &ids) {
        r = placed;
    }
    let fit = CalibrationOptions {
        estimate: ids,
        solver: opts.solver,
        weights: opts.weights,
        orientation: opts.orientation,
        loss: Loss::Squared,
    };
    match estimation::calibrate(&r, data, &fit, &mut |_| {}) {
        Ok(c) => c.calibrated,
        Err(_) => r,
    }
}

/// `robot` with a measurement frame for each session of `data` that needs one and it lacks:
/// every session but the first (in data order) when every posture has a session, every session
/// otherwise (the postures without one are in the global frame); `None` when none is missing.
/// A frame starts at the identity, to be placed in closed form and estimated.
pub fn session_frames_for(robot: &Robot, data: &Dataset) -> Option<Robot> {
    let sessions = data.sessions();
    let unframed: Vec<&std::sync::Arc<str>> = sessions
        .iter()
        .filter(|s| robot.session_index(s).is_none())
        .collect();
    let all_in_sessions = data.postures.iter().all(|p| p.session.is_some());
    // The global frame is the first session's unless some posture is in none, or the robot
    // already frames some session (then the global frame is the robot's own).
    let skip = usize::from(all_in_sessions && robot.sessions.is_empty());
    let new: Vec<&std::sync::Arc<str>> = unframed.into_iter().skip(skip).collect();
    if new.is_empty() {
        return None;
    }
    let mut r = robot.clone();
    for name in new {
        r.sessions.push(crate::robot::Session {
            name: name.to_string(),
            frame: crate::robot::Link::default(),
        });
    }
    Some(r)
}

/// Which of several equally good answers a calibration returns when the data leaves some
/// parameters undetermined (in a calibration spec: `solver`, `min-change`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SolutionRule {
    /// Wherever the solver stops: in the undetermined directions this depends on the starting
    /// point and the solver's path (thesis Table 4.8).
    #[default]
    Solver,
    /// Among the equally good answers, the one closest to the nominal robot in the metric
    /// `sum ((p - p_nominal) / tolerance)^2`, tolerances from the nominal's
    /// [`Tolerances`](crate::robot::Tolerances). It does not depend on the starting point.
    MinChange,
}

impl SolutionRule {
    /// `solver` or `min-change`.
    pub fn as_str(self) -> &'static str {
        match self {
            SolutionRule::Solver => "solver",
            SolutionRule::MinChange => "min-change",
        }
    }
}

/// Held-out data to check the calibration on.
#[derive(Debug, Clone, PartialEq, Default)]
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

/// The result of cross-validation ([`Validation::Folds`]), in the metric that judges the
/// model: positions when the data has them, else the first other length metric.
#[derive(Debug, Clone, PartialEq)]
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

/// Everything that decides a calibration.
#[derive(Debug, Clone)]
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
    /// The files read (for the report's fingerprints): the robot file first, then the data.
    pub sources: Vec<Source>,
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
            orientation: OrientationError::RotVec,
            solution: SolutionRule::Solver,
            prune: None,
            validation: Validation::None,
            outlier_sigmas: outliers::DEFAULT_SIGMAS,
            priority: Vec::new(),
            rank_rcond: identifiability::DEFAULT_RANK_RCOND,
            sources: Vec::new(),
        }
    }

    fn analysis_options(&self) -> AnalysisOptions {
        AnalysisOptions {
            rcond: self.rank_rcond,
            weights: self.weights,
            orientation: self.orientation,
            priority: self.priority.clone(),
            noise_scale: 1.0,
        }
    }
}

/// The phases of a calibration, for progress displays and the report's timings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
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
        }
    }
}

/// Passes progress on, and clocks each phase (wall time).
struct Clock<'a> {
    inner: &'a mut dyn Progress,
    current: (Phase, std::time::Instant),
    times: Vec<(Phase, f64)>,
}

impl Clock<'_> {
    fn lap(&mut self, next: Phase) {
        let (phase, since) =
            std::mem::replace(&mut self.current, (next, std::time::Instant::now()));
        let t = since.elapsed().as_secs_f64();
        match self.times.iter_mut().find(|(p, _)| *p == phase) {
            Some(e) => e.1 += t,
            None => self.times.push((phase, t)),
        }
    }
}

impl Progress for Clock<'_> {
    fn phase(&mut self, phase: Phase) {
        self.lap(phase);
        self.inner.phase(phase);
    }
    fn iteration(&mut self, it: &Iteration) {
        self.inner.iteration(it);
    }
    fn data_checked(&mut self, warnings: &[Warning]) -> bool {
        self.inner.data_checked(warnings)
    }
}

/// Receives the progress of a calibration. Every method does nothing by default.
pub trait Progress {
    /// A phase starts.
    fn phase(&mut self, _phase: Phase) {}
    /// An iteration of the solver ended.
    fn iteration(&mut self, _it: &Iteration) {}
    /// The data was checked against the nominal robot before any solving (units, attitudes,
    /// readings; [`crate::sanity::check_data`]): `warnings` are what was found, empty when all
    /// is well. Returning false stops the run there ([`Error::Stopped`]), e.g. for a caller
    /// that treats a warning saying the result would be wrong ([`Warning::implausible`]) as
    /// fatal.
    fn data_checked(&mut self, _warnings: &[Warning]) -> bool {
        true
    }
}

/// No progress display.
impl Progress for () {}

/// The pruned refit and what it removed.
#[derive(Debug, Clone)]
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
    pub normalized_before: f64,
    /// The same with the calibrated robot.
    pub normalized_after: f64,
}

impl Checked {
    /// `cal` checked on the data it was fitted to: its accuracies are already known.
    /// Under least squares, the objectives before and after are the sums of squared
    /// normalized residuals too.
    fn fitted(cal: &Calibration, data: &Dataset) -> Checked {
        let (before, after) = (cal.accuracy_before.clone(), cal.accuracy_after.clone());
        if matches!(cal.options.loss, Loss::Squared) {
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
            let (f, acc) = p.evaluate_checked(robot, &mut r);
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
    /// start was far ([`crate::registration`]).
    pub registration: Option<crate::registration::Registration>,
    /// The cross-validation, when asked for ([`Validation::Folds`]).
    pub cross_validation: Option<CrossValidation>,
    /// The report document.
    pub report: CalibrationReport,
}

/// Runs a calibration.
///
/// The report's `timings` give the wall time of each [`Phase`] that ran.
pub fn run(req: &Request, progress: &mut dyn Progress) -> Result<Outcome> {
    let mut clock = Clock {
        inner: progress,
        current: (Phase::Preparation, std::time::Instant::now()),
        times: Vec::new(),
    };
    let mut outcome = run_clocked(req, &mut clock)?;
    clock.lap(Phase::Report);
    outcome.report.timings = clock
        .times
        .iter()
        .map(|&(p, seconds)| crate::report::PhaseTime {
            phase: p.as_str().to_string(),
            seconds,
        })
        .collect();
    Ok(outcome)
}

fn run_clocked(req: &Request, progress: &mut dyn Progress) -> Result<Outcome> {
    if !(req.outlier_sigmas.is_finite() && req.outlier_sigmas > 0.0) {
        return Err(Error::InvalidOption {
            setting: crate::error::Setting::OutlierThreshold,
            message: format!(
                "expected a positive number of standard deviations, got {}",
                req.outlier_sigmas
            ),
        });
    }
    if let Some(k) = req.prune {
        if !(k.is_finite() && k > 0.0) {
            return Err(Error::InvalidOption {
                setting: crate::error::Setting::PruningThreshold,
                message: format!("expected a positive number of standard deviations, got {k}"),
            });
        }
    }
    if !(req.solver.rcond > 0.0 && req.solver.rcond < 1.0) {
        return Err(Error::InvalidOption {
            setting: crate::error::Setting::Rcond,
            message: format!(
                "expected a number between 0 and 1, got {}",
                req.solver.rcond
            ),
        });
    }
    if req.data.is_empty() {
        return Err(Error::Problem("no observations to calibrate from".into()));
    }
    let (data, validation_data) = match &req.validation {
        Validation::None => (req.data.clone(), None),
        Validation::Data(v) => (req.data.clone(), Some(v.clone())),
        Validation::Holdout { fraction, seed } => {
            if !(*fraction > 0.0 && *fraction < 1.0) {
                return Err(Error::InvalidOption {
                    setting: crate::error::Setting::HoldoutFraction,
                    message: format!("expected a fraction between 0 and 1, got {fraction}"),
                });
            }
            let (ident, held) = req.data.split(*fraction, *seed);
            if held.is_empty() || ident.is_empty() {
                return Err(Error::InvalidOption {
                    setting: crate::error::Setting::HoldoutFraction,
                    message: format!("{fraction} leaves an empty identification or validation set"),
                });
            }
            (Arc::new(ident), Some(Arc::new(held)))
        }
        Validation::Folds { .. } => (req.data.clone(), None),
    };
    // Sessions of the data with a measurement frame of their own: added to the model (the first
    // session, or the postures without one, are in the global frame).
    let with_frames;
    let req = match session_frames_for(&req.robot, &data) {
        Some(robot) => {
            with_frames = Request {
                robot,
                ..req.clone()
            };
            &with_frames
        }
        None => req,
    };
    let start = match &req.initial {
        None => req.robot.clone(),
        Some(guess) => {
            if !req.robot.same_structure(guess) {
                return Err(Error::Problem(
                    "the initial guess does not have the nominal robot's structure (joints, \
                     couplings, sites, planes)"
                        .into(),
                ));
            }
            let mut start = req.robot.clone();
            for id in req
                .robot
                .param_ids()
                .filter(|id| id.0 < guess.param_count())
            {
                start.set(id, guess.get(id));
            }
            for (p, g) in start.planes.iter_mut().zip(&guess.planes) {
                // Tilts are relative to each file's own reference normal.
                p.set_normal(&g.normal());
            }
            start
        }
    };
    // Where the nominal robot puts the observed points: one pass, for the checks of the data
    // against it (scale) and, when the start is the nominal robot, of the start's distance.
    let nominal_points = crate::sanity::predicted(&req.robot, &data);
    // The data against the nominal robot, before any solving: a unit mix-up is named now, not
    // after a solve that could not have made sense of it.
    let data_warns = data_warnings(&req.robot, &data, &nominal_points);
    if !progress.data_checked(&data_warns) {
        return Err(Error::Stopped {
            after: "the checks of the data against the nominal robot",
        });
    }
    let start_points = if start == req.robot {
        None
    } else {
        Some(crate::sanity::predicted(&start, &data))
    };
    let start_points = start_points.as_deref().unwrap_or(&nominal_points);
    // A far start (a measurement frame placed roughly or not at all): place the measurement
    // frame and the measured frames in closed form first, among the parameters that may move.
    let candidates: Vec<ParamId> = match &req.selection {
        Selection::List(ids) => ids.clone(),
        Selection::Default { fix } | Selection::Identifiable { fix, .. } => {
            let (mut ids, _) = default_parameters(&start, &data);
            if let Selection::Identifiable { with, .. } = &req.selection {
                ids.extend(with.iter().copied());
            }
            ids.retain(|id| !fix.contains(id));
            ids
        }
    };
    let registration =
        crate::registration::register_far_start_with(&start, &data, &candidates, start_points);
    let start = match &registration {
        Some(r) => r.robot.clone(),
        None => start,
    };
    // Each session's frame placed in closed form (they start unknown).
    let session_ids: Vec<ParamId> = start
        .param_ids()
        .filter(|&id| matches!(start.param_kind(id), ParamKind::Session { .. }))
        .collect();
    let sessions_placed = crate::registration::place_sessions(&start, &data, &session_ids);
    let placed = registration.is_some() || sessions_placed.is_some();
    let start = match sessions_placed {
        Some((placed, _, _)) => placed,
        None => start,
    };
    // Placed in closed form, the frames are then fitted by least squares with the robot held
    // (a rigid fit of the nominal robot: the measurement frames, the measured targets' frames),
    // so that the solver starts, and "start" is reported, at the nominal robot's best placement.
    let start = if placed {
        rigid_fit(&start, &data, &candidates, req)
    } else {
        start
    };
    let reference = match req.solution {
        SolutionRule::MinChange => &req.robot,
        SolutionRule::Solver => &start,
    };
    if matches!(req.selection, Selection::Identifiable { .. }) {
        progress.phase(Phase::Selection);
    }
    let (estimate, unseen, lin) =
        resolve_linearized(&req.selection, reference, &data, &req.analysis_options())?;
    // The analysis linearised the problem at the reference: the solver's start when they are
    // the same robot (and the loss starts as least squares, which it always does).
    let lin = lin.filter(|_| *reference == start);
    let opts = CalibrationOptions {
        estimate,
        solver: req.solver,
        weights: req.weights,
        orientation: req.orientation,
        loss: req.loss,
    };
    progress.phase(Phase::Estimation);
    let mut opts = opts;
    let mut cal = fit(req, &start, &data, &opts, lin.as_ref(), progress)?;
    // The noise-level rule judged the set at the stated sigmas. Residuals far beyond them (a
    // tracker's own sigmas under a model error ten times larger) show the rows' real noise:
    // the set is chosen again at it, and fitted again when that leaves parameters out (those
    // only the stated precision made look determined, along whose valley the solver crawls).
    let mut rechosen = None;
    if matches!(req.selection, Selection::Identifiable { .. }) {
        let (m, n) = (cal.residuals.len(), opts.estimate.len());
        let vf = if m > n {
            cal.objective_after / (m - n) as f64
        } else {
            f64::NAN
        };
        if vf > SIGMAS_TOO_SMALL {
            let aopts = AnalysisOptions {
                noise_scale: vf.sqrt(),
                ..req.analysis_options()
            };
            progress.phase(Phase::Selection);
            let (estimate, _, lin) = resolve_linearized(&req.selection, reference, &data, &aopts)?;
            if estimate != opts.estimate {
                let left_out = opts
                    .estimate
                    .iter()
                    .filter(|id| !estimate.contains(id))
                    .map(|&id| req.robot.param_name(id))
                    .collect();
                let lin = lin.filter(|_| *reference == start);
                opts.estimate = estimate;
                progress.phase(Phase::Estimation);
                cal = fit(req, &start, &data, &opts, lin.as_ref(), progress)?;
                rechosen = Some(Warning::ChosenAtResidualNoise {
                    scale: vf.sqrt(),
                    left_out,
                });
            }
        }
    }
    let mut pruning = None;
    if let Some(k) = req.prune {
        progress.phase(Phase::Pruning);
        let full = cal.clone();
        let mut removed = Vec::new();
        while let Ok(u) = uncertainty::uncertainty_of_fit(&cal, &data, reference) {
            let weakest = u
                .parameters
                .iter()
                .filter_map(|p| p.significance.map(|s| (p.id, s)))
                .filter(|&(_, s)| s < k)
                .min_by(|a, b| a.1.total_cmp(&b.1));
            let Some((id, _)) = weakest else { break };
            let mut o = cal.options.clone();
            o.estimate.retain(|&p| p != id);
            if o.estimate.is_empty() {
                break;
            }
            removed.push(id);
            cal = fit(req, &start, &data, &o, lin.as_ref(), &mut ())?;
        }
        let full_outcome = finish(
            req.robot.clone(),
            data.clone(),
            validation_data.clone(),
            full.clone(),
            uncertainty::uncertainty_of_fit(&full, &data, reference),
            None,
            req.outlier_sigmas,
            req.solution,
            &req.sources,
            &mut data_warns.clone(),
        );
        pruning = Some(Pruning {
            k,
            full,
            full_report: Box::new(full_outcome.report),
            removed,
        });
    }
    progress.phase(Phase::Uncertainty);
    let mut warnings = data_warns;
    warnings.extend(rechosen);
    if !unseen.is_empty() {
        warnings.insert(
            0,
            Warning::Unseen {
                parameters: unseen.iter().map(|&id| req.robot.param_name(id)).collect(),
            },
        );
    }
    let unc = uncertainty::uncertainty_of_fit(&cal, &data, reference);
    progress.phase(Phase::Report);
    let mut outcome = finish(
        req.robot.clone(),
        data,
        validation_data,
        cal,
        unc,
        pruning,
        req.outlier_sigmas,
        req.solution,
        &req.sources,
        &mut warnings,
    );
    if let Some(r) = &registration {
        let len = |v: f64| req.robot.units.from_si(Quantity::Length, v);
        outcome.report.start_placement = Some(crate::report::StartPlacement {
            rms_before: len(r.rms_before),
            rms_after: len(r.rms_after),
        });
    }
    outcome.registration = registration;
    if let Validation::Folds { k, seed } = req.validation {
        progress.phase(Phase::CrossValidation);
        let cv = cross_validate(req, k, seed)?;
        outcome.report.cross_validation = Some(cross_validation_report(&cv, &req.robot));
        outcome.cross_validation = Some(cv);
    }
    Ok(outcome)
}

/// A variance factor above this says the stated sigmas are more than 10 times too small
/// ([`Warning::SigmasOff`]); the identifiable set is then chosen again at the residuals' noise.
pub const SIGMAS_TOO_SMALL: f64 = 100.0;

/// A variance factor below this says the stated sigmas are more than 10 times too large
/// ([`Warning::SigmasOff`]). The set is not chosen again then: the rule at overstated noise
/// errs towards fewer parameters, which the warning names.
pub const SIGMAS_TOO_LARGE: f64 = 0.01;

/// Runs `req` on each training fold and checks it on the postures left out.
fn cross_validate(req: &Request, k: usize, seed: Option<u64>) -> Result<CrossValidation> {
    use crate::observe::{stats, MetricAccuracy};
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
    let summary = |e: Vec<f64>| {
        let count = e.len();
        let (rms, mean, p95, max) = stats(e);
        MetricAccuracy {
            metric,
            count,
            rms,
            mean,
            p95,
            max,
        }
    };
    let mut all = Vec::new();
    let mut out = Vec::with_capacity(k);
    for (train, held) in folds {
        let mut sub = req.clone();
        sub.data = Arc::new(train);
        sub.validation = Validation::None;
        sub.sources = Vec::new();
        let o = run(&sub, &mut ())?;
        let mut worst: Option<(String, f64)> = None;
        let mut e = Vec::new();
        for (o, err) in held
            .observations
            .iter()
            .zip(crate::observe::errors(&o.calibration.calibrated, &held))
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
            converged: o.calibration.converged(),
            estimated: o.calibration.estimated.clone(),
            rank: o.uncertainty.as_ref().map(|u| u.analysis.rank),
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
fn cross_validation_report(
    cv: &CrossValidation,
    robot: &Robot,
) -> crate::report::CrossValidationReport {
    let units = &robot.units;
    use crate::report::{CrossValidationReport, FoldReport, MetricStats};
    let len = |v: f64| units.from_si(Quantity::Length, v);
    let stats = |m: &crate::observe::MetricAccuracy| MetricStats {
        metric: m.metric.to_string(),
        count: m.count,
        rms: len(m.rms),
        mean: len(m.mean),
        p95: len(m.p95),
        max: len(m.max),
    };
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

/// A candidate model for [`choose`]: what to estimate, and whether to prune.
#[derive(Debug, Clone, PartialEq)]
pub struct Candidate {
    /// How it is written (`identifiable,slopes prune=3`).
    pub label: String,
    /// What to estimate.
    pub selection: Selection,
    /// Pruning threshold, if any.
    pub prune: Option<f64>,
}

impl Candidate {
    /// Parses `LIST [fix=LIST] [prune=K]` (a parameter list as for [`Selection::parse`]).
    pub fn parse(text: &str, robot: &Robot) -> Result<Candidate> {
        let mut words = text.split_whitespace();
        let list = words.next().unwrap_or("");
        let (mut fix, mut prune) = (None, None);
        for w in words {
            match w.split_once('=') {
                Some(("fix", f)) => fix = Some(f),
                Some(("prune", k)) => {
                    prune = Some(
                        k.parse::<f64>()
                            .ok()
                            .filter(|k| k.is_finite() && *k > 0.0)
                            .ok_or_else(|| Error::InvalidOption {
                                setting: crate::error::Setting::ModelCandidate,
                                message: format!("`{text}`: prune={k} is not a positive number"),
                            })?,
                    )
                }
                _ => {
                    return Err(Error::InvalidOption {
                        setting: crate::error::Setting::ModelCandidate,
                        message: format!(
                            "`{text}`: expected `LIST [fix=LIST] [prune=K]`, found `{w}`"
                        ),
                    })
                }
            }
        }
        Ok(Candidate {
            label: text.split_whitespace().collect::<Vec<_>>().join(" "),
            selection: Selection::parse(list, fix, robot)?,
            prune,
        })
    }

    /// The default candidates, from the simplest up: the identifiable set of the geometric
    /// model (links, offsets, sites: slopes held); with the coupling factors, when the robot
    /// has coupled joints; with the joint transducer slopes (and the couplings); and the latter
    /// pruned stepwise at 2 and at 3 standard deviations.
    pub fn defaults(robot: &Robot) -> Result<Vec<Candidate>> {
        let mut texts = vec!["identifiable fix=slopes"];
        let coupled = robot.coupled_joints().next().is_some();
        if coupled {
            texts.push("identifiable,couplings fix=slopes");
            texts.extend([
                "identifiable,slopes,couplings",
                "identifiable,slopes,couplings prune=2",
                "identifiable,slopes,couplings prune=3",
            ]);
        } else {
            texts.extend([
                "identifiable,slopes",
                "identifiable,slopes prune=2",
                "identifiable,slopes prune=3",
            ]);
        }
        texts.iter().map(|t| Candidate::parse(t, robot)).collect()
    }
}

/// One candidate of a model choice, cross-validated.
#[derive(Debug, Clone, PartialEq)]
pub struct Scored {
    /// The candidate.
    pub candidate: Candidate,
    /// Parameters its fit on all the data estimates.
    pub parameters: usize,
    /// Its held-out mean (m).
    pub mean: f64,
    /// The standard error of that mean: the standard deviation of the folds' means over the
    /// square root of the number of folds.
    pub standard_error: f64,
}

/// The result of [`choose`].
#[derive(Debug)]
pub struct Choice {
    /// Every candidate, in the order given.
    pub scored: Vec<Scored>,
    /// The index of the chosen one.
    pub chosen: usize,
    /// The chosen candidate's calibration on all the data, with its cross-validation.
    pub outcome: Outcome,
}

/// How many times [`choose`] repeats its cross-validation, over as many shuffles of the
/// postures, by default.
pub const CHOICE_REPEATS: usize = 5;

/// Chooses among `candidates`, listed from the simplest model up, by `k`-fold cross-validation
/// repeated over `repeats` shuffles of the postures (the same folds for all candidates; the
/// first repeat with `seed`, the others with the seeds after it), so that the choice does not
/// hang on one split: the first whose held-out mean over all repeats is within one standard
/// error of the best (the one-standard-error rule: a more elaborate model must earn its place
/// by more than the noise of the estimate; a pruned fit counts as more elaborate than the set it
/// prunes, as its parameters were chosen from the data), and returns its calibration (checked on
/// `req`'s validation data too, when it is a separate dataset). The standard error is that of
/// one `k`-fold estimate: the spread of the folds' means over `sqrt(k)`.
pub fn choose(
    req: &Request,
    candidates: &[Candidate],
    k: usize,
    seed: Option<u64>,
    repeats: usize,
) -> Result<Choice> {
    if candidates.is_empty() {
        return Err(Error::InvalidOption {
            setting: crate::error::Setting::ModelCandidate,
            message: "no candidate to choose from".into(),
        });
    }
    let mut scored = Vec::with_capacity(candidates.len());
    let mut outcomes = Vec::with_capacity(candidates.len());
    for c in candidates {
        let mut sub = req.clone();
        sub.selection = c.selection.clone();
        sub.prune = c.prune;
        sub.validation = Validation::Folds { k, seed };
        let out = run(&sub, &mut ())?;
        let cv = out.cross_validation.as_ref().expect("folds asked for");
        let mut means: Vec<f64> = cv.folds.iter().map(|f| f.errors.mean).collect();
        let (mut sum, mut count) = (cv.overall.mean * cv.overall.count as f64, cv.overall.count);
        for r in 1..repeats.max(1) {
            let shuffle = seed.unwrap_or(0).wrapping_add(r as u64);
            let again = cross_validate(&sub, k, Some(shuffle))?;
            means.extend(again.folds.iter().map(|f| f.errors.mean));
            sum += again.overall.mean * again.overall.count as f64;
            count += again.overall.count;
        }
        let m = means.iter().sum::<f64>() / means.len() as f64;
        let var =
            means.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (means.len() - 1).max(1) as f64;
        scored.push(Scored {
            candidate: c.clone(),
            parameters: out.calibration.estimated.len(),
            mean: sum / count.max(1) as f64,
            standard_error: (var / k as f64).sqrt(),
        });
        outcomes.push(out);
    }
    let best = (0..scored.len())
        .min_by(|&a, &b| scored[a].mean.total_cmp(&scored[b].mean))
        .expect("candidates");
    let limit = scored[best].mean + scored[best].standard_error;
    let chosen = (0..scored.len())
        .find(|&i| scored[i].mean <= limit)
        .expect("the best qualifies");
    let mut outcome = outcomes.swap_remove(chosen);
    // Held-out data of its own (a separate file) checks the chosen model too.
    if let Validation::Data(_) = &req.validation {
        let mut sub = req.clone();
        sub.selection = candidates[chosen].selection.clone();
        sub.prune = candidates[chosen].prune;
        let mut checked = run(&sub, &mut ())?;
        checked.report.cross_validation = outcome.report.cross_validation.take();
        checked.cross_validation = outcome.cross_validation.take();
        outcome = checked;
    }
    let len = |v: f64| req.robot.units.from_si(Quantity::Length, v);
    outcome.report.model_choice_repeats = Some(repeats.max(1));
    outcome.report.model_choice = scored
        .iter()
        .enumerate()
        .map(|(i, s)| crate::report::ChoiceReport {
            candidate: s.candidate.label.clone(),
            parameters: s.parameters,
            mean: len(s.mean),
            standard_error: len(s.standard_error),
            chosen: i == chosen,
        })
        .collect();
    Ok(Choice {
        scored,
        chosen,
        outcome,
    })
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

/// Assembles an outcome: validation, outliers, warnings, the report.
#[allow(clippy::too_many_arguments)]
fn finish(
    nominal: Robot,
    data: Arc<Dataset>,
    validation_data: Option<Arc<Dataset>>,
    cal: Calibration,
    unc: Result<Uncertainty>,
    pruning: Option<Pruning>,
    outlier_sigmas: f64,
    solution: SolutionRule,
    sources: &[Source],
    warnings: &mut Vec<Warning>,
) -> Outcome {
    warnings.extend(crate::sanity::check_result(
        &nominal,
        &cal.calibrated,
        &cal.estimated,
    ));
    if cal.accuracy_after.orientations > 0
        && cal.accuracy_after.rms_orientation > crate::sanity::ATTITUDE_LIMIT
    {
        warnings.push(Warning::AttitudesUnfit {
            rms_deg: cal.accuracy_after.rms_orientation.to_degrees(),
        });
    }
    if !cal.unfelt.is_empty() {
        warnings.push(Warning::Unfelt {
            parameters: cal
                .unfelt
                .iter()
                .map(|&id| cal.calibrated.param_name(id))
                .collect(),
        });
    }
    let uncertainty = match unc {
        Ok(u) => {
            if u.dof > 0 && !(SIGMAS_TOO_LARGE..=SIGMAS_TOO_SMALL).contains(&u.variance_factor) {
                warnings.push(Warning::SigmasOff {
                    variance_factor: u.variance_factor,
                });
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
            Some(u)
        }
        Err(e) => {
            warnings.push(Warning::NoUncertainty {
                reason: e.to_string(),
            });
            None
        }
    };
    match cal.termination {
        estimation::Termination::MaxIterations => warnings.push(Warning::NotConverged {
            iterations: cal.iterations,
        }),
        estimation::Termination::Stalled => warnings.push(Warning::Stalled {
            method: cal.options.solver.method.as_str().to_string(),
        }),
        _ => {}
    }
    let outliers = outliers::outliers_of_fit(&cal, &data, outlier_sigmas);
    let mut identification = Checked::fitted(&cal, &data);
    let validation = validation_data
        .as_ref()
        .map(|v| Checked::new(&cal, v, &data, &nominal));
    let mut report = CalibrationReport::new(&cal, &data);
    // The solver started elsewhere than the nominal robot (frames placed in closed form, an
    // initial guess): "before" is the nominal robot, the start is said apart.
    let nominal_figures = (cal.initial != nominal).then(|| {
        let p = Problem::new(
            &nominal,
            &data,
            &[],
            cal.options.weights,
            cal.options.orientation,
        );
        let mut r = vec![0.0; p.rows()];
        p.evaluate_checked(&nominal, &mut r)
    });
    if let Some((objective, accuracy)) = &nominal_figures {
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
        let len = |x: f64| cal.calibrated.units.from_si(Quantity::Length, x);
        let mut worse = |metric: &str, before: f64, after: f64| {
            // Beyond rounding: a held-out error that grew by more than a part in a million.
            if after > before * (1.0 + 1e-6) {
                warnings.push(Warning::WorseOnValidation {
                    metric: metric.to_string(),
                    before: len(before),
                    after: len(after),
                    unit: cal.calibrated.units.length.to_string(),
                });
            }
        };
        // Against the start when it is not the nominal robot (a nominal whose frames were far
        // off says nothing).
        let base = v.start.as_ref().unwrap_or(&v.before);
        if base.positions > 0 {
            worse("position", base.mean_position, v.after.mean_position);
        }
        for (b, a) in base.other.iter().zip(&v.after.other) {
            worse(b.metric, b.mean, a.mean);
        }
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

/// Warnings about the data itself: units that do not match the robot file's, readings the
/// robot cannot take ([`crate::sanity`]; `predicted`: `robot`'s points,
/// [`crate::sanity::predicted`]).
fn data_warnings(
    robot: &Robot,
    data: &Dataset,
    predicted: &[[nalgebra::Vector3<f64>; 2]],
) -> Vec<Warning> {
    crate::sanity::check_data_with(robot, data, predicted)
}

/// Estimates, then applies the solution rule.
fn fit(
    req: &Request,
    start: &Robot,
    data: &Dataset,
    opts: &CalibrationOptions,
    lin: Option<&Linearized>,
    progress: &mut dyn Progress,
) -> Result<Calibration> {
    let mut cal =
        estimation::calibrate_from(start, data, opts, &mut |it| progress.iteration(it), lin)?;
    if req.solution == SolutionRule::MinChange {
        let problem = Problem::new(start, data, &opts.estimate, opts.weights, opts.orientation);
        let problem = problem.with_row_scale(&cal.row_scale);
        let mut x = problem.values(&cal.calibrated);
        for _round in 0..10 {
            let (projected, size) = project_min_change(&problem, &x, &req.robot, data, opts)?;
            let again = estimation::solve(&problem, &projected, &opts.solver, &mut |it| {
                cal.log.push(*it);
                progress.iteration(it)
            })?;
            x = again.x;
            cal.iterations += again.iterations;
            cal.termination = again.termination;
            if size < 1e-9 {
                break;
            }
        }
        let mut calibrated = problem.robot_at(&x);
        for &id in &opts.estimate {
            if start.param_quantity(id) == Quantity::Angle {
                let v0 = start.get(id);
                calibrated.set(id, v0 + wrap_angle(calibrated.get(id) - v0));
            }
        }
        let plain = Problem::new(start, data, &opts.estimate, opts.weights, opts.orientation);
        (cal.objective_after, cal.accuracy_after) = estimation::settle(
            &plain,
            &calibrated,
            opts.loss,
            &cal.row_scale,
            &mut cal.residuals,
        );
        cal.calibrated = calibrated;
    }
    Ok(cal)
}

/// Moves `x` along the undetermined directions to the point closest to `reference` in the
/// tolerance-scaled metric. Returns the new point and the size of the move in tolerance units.
///
/// The undetermined directions are the null space of the Jacobian at the reference (nominal)
/// model, where the design's exact redundancies hold; noise in the data would otherwise turn
/// them into barely determined directions at `x`.
fn project_min_change(
    problem: &Problem<'_>,
    x: &[f64],
    reference: &Robot,
    data: &Dataset,
    opts: &CalibrationOptions,
) -> Result<(Vec<f64>, f64)> {
    let mut robot = problem.robot_at(x);
    for &id in problem.estimated() {
        robot.set(id, reference.get(id));
    }
    let aopts = AnalysisOptions {
        weights: opts.weights,
        orientation: opts.orientation,
        ..Default::default()
    };
    let a = identifiability::analyze_core(&robot, data, problem.estimated(), &aopts)?;
    let n = x.len();
    // analyze sorts its parameters; map them back to the problem's order.
    let pos: Vec<usize> = problem
        .estimated()
        .iter()
        .map(|id| {
            a.parameters
                .iter()
                .position(|p| p == id)
                .expect("same parameters")
        })
        .collect();
    // Back from scaled to parameter units; a column no observation feels was zeroed in the
    // scaled Jacobian (its null direction is the parameter alone), so it stays unscaled, as
    // dividing by its rounding-level norm would swamp every other direction. Each direction is
    // then normalised, which keeps the small system below well conditioned.
    let null: Vec<Vec<f64>> = (a.rank..n)
        .map(|k| {
            let mut v: Vec<f64> = pos
                .iter()
                .map(|&j| {
                    let v = a.right_singular_vectors[(j, k)];
                    if a.unobservable.contains(&a.parameters[j]) || a.column_norms[j] <= 0.0 {
                        v
                    } else {
                        v / a.column_norms[j]
                    }
                })
                .collect();
            let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
            if norm > 0.0 {
                v.iter_mut().for_each(|x| *x /= norm);
            }
            v
        })
        .collect();
    if null.is_empty() {
        return Ok((x.to_vec(), 0.0));
    }
    let ids = problem.estimated();
    let w: Vec<f64> = ids
        .iter()
        .map(|&id| 1.0 / reference.tolerance(id).powi(2))
        .collect();
    let dx: Vec<f64> = ids
        .iter()
        .zip(x)
        .map(|(&id, &v)| {
            let d = v - reference.get(id);
            if reference.param_quantity(id) == Quantity::Angle {
                wrap_angle(d)
            } else {
                d
            }
        })
        .collect();
    let k = null.len();
    let ata = crate::linalg::Matrix::from_fn(k, k, |a, b| {
        (0..n).map(|j| null[a][j] * w[j] * null[b][j]).sum()
    });
    let atb: Vec<f64> = (0..k)
        .map(|a| (0..n).map(|j| null[a][j] * w[j] * dx[j]).sum())
        .collect();
    let z = crate::linalg::solve_spd(&ata, &atb)
        .ok_or_else(|| Error::Numerical("minimum-change projection is singular".into()))?;
    let mut out = x.to_vec();
    let mut size = 0.0;
    for j in 0..n {
        let step: f64 = (0..k).map(|a| null[a][j] * z[a]).sum();
        out[j] -= step;
        size += step * step * w[j];
    }
    Ok((out, size.sqrt()))
}

/// The outcome of a calibration that already exists: `calibrated` (a robot file written by a
/// calibration of `nominal`) assessed on `data`. The estimated parameters are those that
/// differ from the nominal ones.
pub fn assess(
    nominal: &Robot,
    calibrated: &Robot,
    data: &Dataset,
    weights: Weights,
    orientation: OrientationError,
    sources: &[Source],
) -> Result<Outcome> {
    if !nominal.same_structure(calibrated) {
        return Err(Error::Problem(
            "the calibrated robot does not have the nominal robot's structure (joints, couplings, \
             sites, planes)"
                .into(),
        ));
    }
    let mut calibrated = calibrated.clone();
    for (p, c) in nominal.planes.iter().zip(calibrated.planes.iter_mut()) {
        let (n, offset) = (c.normal(), c.offset);
        *c = p.clone();
        c.offset = offset;
        c.set_normal(&n);
    }
    let mut estimated: Vec<ParamId> = nominal
        .param_ids()
        .filter(|&id| (nominal.get(id) - calibrated.get(id)).abs() > 0.0)
        .collect();
    if estimated.is_empty() {
        estimated = nominal.param_ids().collect();
    }
    let mut options = CalibrationOptions::new(estimated.clone());
    options.weights = weights;
    options.orientation = orientation;
    let problem = Problem::new(nominal, data, &estimated, weights, orientation);
    let mut residuals = vec![0.0; problem.rows()];
    let (objective_before, accuracy_before) = problem.evaluate_checked(nominal, &mut residuals);
    let (objective_after, accuracy_after) = problem.evaluate_checked(&calibrated, &mut residuals);
    let cal = Calibration {
        objective_before,
        objective_after,
        accuracy_before,
        accuracy_after,
        initial: nominal.clone(),
        calibrated,
        estimated: estimated.clone(),
        options,
        termination: estimation::Termination::Given,
        stationarity: Default::default(),
        iterations: 0,
        unfelt: Vec::new(),
        row_scale: vec![1.0; problem.rows()],
        log: Vec::new(),
        residuals,
        start_r: None,
    };
    let mut warnings = data_warnings(nominal, data, &crate::sanity::predicted(nominal, data));
    let unc = uncertainty::uncertainty(&cal, data, nominal);
    Ok(finish(
        nominal.clone(),
        Arc::new(data.clone()),
        None,
        cal,
        unc,
        None,
        outliers::DEFAULT_SIGMAS,
        SolutionRule::Solver,
        sources,
        &mut warnings,
    ))
}

/// The largest acceptable errors of a robot in service.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Thresholds {
    /// Largest acceptable length error (m): position errors, and the errors of other length
    /// metrics (distances, contacts).
    pub length: f64,
    /// Largest acceptable attitude error (rad), when attitudes are checked.
    pub angle: Option<f64>,
}

/// Whether a robot still meets its accuracy on check observations.
#[derive(Debug, Clone, PartialEq)]
pub struct Verdict {
    /// True when every error is within the thresholds.
    pub ok: bool,
    /// The errors.
    pub accuracy: Accuracy,
    /// The thresholds.
    pub thresholds: Thresholds,
}

/// Checks `robot`'s predictions against check observations.
pub fn check(robot: &Robot, data: &Dataset, thresholds: Thresholds) -> Result<Verdict> {
    let ok_threshold = |v: f64| v.is_finite() && v > 0.0;
    if !ok_threshold(thresholds.length) || !thresholds.angle.is_none_or(ok_threshold) {
        return Err(Error::InvalidOption {
            setting: crate::error::Setting::CheckThreshold,
            message: "thresholds must be positive finite numbers".into(),
        });
    }
    let acc = accuracy(robot, data);
    let mut ok = acc.max_position <= thresholds.length
        && acc.other.iter().all(|m| m.max <= thresholds.length);
    if let Some(t) = thresholds.angle {
        ok &= acc.orientations == 0 || acc.max_orientation <= t;
    }
    Ok(Verdict {
        ok,
        accuracy: acc,
        thresholds,
    })
}
