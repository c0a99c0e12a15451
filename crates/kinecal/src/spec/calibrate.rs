//! A calibration job as one document: the robot, the observation files and how to read them,
//! what to estimate and how, how to check the result, and where to write it.
//!
//! Every front end says a job in its own syntax and turns it into a [`CalibrationSpec`]: the
//! command line's flags (`kinecal calibrate`, and `--write-spec` writes them down), a spec file
//! (`kinecal calibrate --spec job.toml`, with flags overriding it), a `[[robots]]` or `[[jobs]]`
//! table of a manifest (`kinecal batch fleet.toml`) and Python (`kinecal.calibrate`,
//! `kinecal.run`). From there one path reads the files ([`crate::files::read_files`]) and builds
//! the [`Request`]: the same job gives the same calibration whichever way it was said.
//!
//! On disk a spec is TOML (every key optional but `robot`; a missing key takes the default):
//!
//! ```toml
//! job = "calibrate"               # the default
//! robot = "qkm_hl6.toml"          # a robot file, or a built-in robot's name
//!
//! [[observations]]
//! file = "identification.csv"     # kind told by the header unless `kind` says it
//! length_unit = "mm"              # the file's units, when not the robot file's
//!
//! [selection]
//! estimate = "identifiable"
//!
//! [validation]
//! folds = 5
//!
//! [outputs]
//! robot = "calibrated.toml"
//! report = "report.json"
//! ```
//!
//! Conventions: relative paths are relative to the spec file's folder (to the working folder
//! for a spec built in memory); lengths and angles (`residuals.weights`) are in the robot
//! file's units.

use std::path::Path;
use std::sync::Arc;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Location, Result, Setting};
use crate::files::{detect_format, kind_index, read_files, ObservationFile, ReadSettings, FORMATS};
use crate::model::robot::Robot;
use crate::observe::{Dataset, OrientationError};
use crate::solve::estimation::{Damping, Loss, Method, ModelErrorMode, SolverOptions, Spread};
use crate::source::{Fingerprint, Source};
use crate::units::DisplayChoice;
use crate::workflow::{self, Candidate, Outcome, Request, SolutionRule, Validation};

use super::common::{invalid, is_default, load_robot, selection, visit_opt, weights, LengthAngle};
use super::{Document, Done, Env, JobKind, Message, PathRole, Spec, Status};

/// One calibration job. See the [module documentation](self) for the file.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct CalibrationSpec {
    /// The nominal robot: a robot file, or a built-in robot's name (`ge-a4`) when no such file
    /// exists.
    #[serde(default)]
    pub robot: String,
    /// A robot file to start the solver from (same structure as `robot`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub initial: Option<String>,
    /// How every observation file is read, unless its own entry says otherwise.
    #[serde(default, skip_serializing_if = "is_default")]
    pub read: ReadSettings,
    /// The observation files the robot is identified on.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub observations: Vec<ObservationFile>,
    /// What to estimate.
    #[serde(default, skip_serializing_if = "is_default")]
    pub selection: SelectionSpec,
    /// The method and its stopping rules.
    #[serde(default, skip_serializing_if = "is_default")]
    pub solver: SolverSpec,
    /// The loss, the weights and the outlier rule.
    #[serde(default, skip_serializing_if = "is_default")]
    pub residuals: ResidualSpec,
    /// How the calibration is checked (and a model chosen).
    #[serde(default, skip_serializing_if = "is_default")]
    pub validation: ValidationSpec,
    /// What is written.
    #[serde(default, skip_serializing_if = "is_default")]
    pub outputs: OutputSpec,
    /// Treat warnings that say the result is most likely wrong (data in another unit than the
    /// robot file, readings outside the joint ranges, lengths moved beyond the robot's reach)
    /// as failures: nothing is written ([`Status::Implausible`]).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub strict: bool,
    /// Write the calibrated robot (and record it) even when a unit check fired and the fit
    /// ended far above the stated noise ([`Status::Refused`] otherwise).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub force_units: bool,
}

/// How far above its stated noise a fit may end (the RMS of its residuals in their own standard
/// deviations) before a unit check that fired refuses it: a right model on data in the right
/// units ends near 1, and an unmodelled effect a few times above (the model-error floor's
/// regime); data in the wrong unit ends hundreds of times above.
pub const FAR_ABOVE_NOISE: f64 = 10.0;

/// Why `outcome` is refused, when it is: a unit check fired ([`crate::Warning::names_units`])
/// and the fit ended far from the data ([`FAR_ABOVE_NOISE`] times its stated noise, or a fit
/// check fired: [`crate::Warning::fit_far_off`]).
pub fn refusal(outcome: &workflow::Outcome) -> Option<String> {
    let units: Vec<String> = outcome
        .warnings
        .iter()
        .filter(|w| w.names_units())
        .map(|w| w.to_string())
        .collect();
    if units.is_empty() {
        return None;
    }
    let normalized = outcome.identification.normalized_after;
    let off = outcome.warnings.iter().any(crate::Warning::fit_far_off);
    if !(off || normalized > FAR_ABOVE_NOISE) {
        return None;
    }
    Some(format!(
        "REFUSED: a unit check fired ({}) and the fit ends at {normalized:.3} times its stated \
         noise{}: no calibrated robot is written or recorded. Read the data in its own units \
         (the warning names them), or pass --force-units (force_units = true) to write the \
         robot anyway",
        units.join("; "),
        if off {
            ", with residuals or changes beyond any calibration error"
        } else {
            ""
        }
    ))
}

/// What to estimate (`[selection]`).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct SelectionSpec {
    /// The parameter list to estimate
    /// ([`Selection::parse`](crate::workflow::Selection::parse)); the default parameters when
    /// absent (an empty list is refused).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub estimate: Option<String>,
    /// Parameters to hold at their nominal values.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fix: Option<String>,
    /// Remove, one at a time, changes below this many standard deviations.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub prune: Option<f64>,
    /// A Gaussian prior on the parameters' changes from the start
    /// ([`crate::model::prior::parse_prior`]): `length=L,angle=A[,slope=F][,compliance=C]` and
    /// parameters `NAME=V` in the robot file's units, `tolerances` or `none`; the robot file's
    /// `[priors]` when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub prior: Option<String>,
    /// The bodies' total mass (kg), held while their masses are estimated: it fixes their
    /// scale, which positions cannot (twice the masses and half the compliances sag the same).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub total_mass: Option<f64>,
}

/// The method and its stopping rules (`[solver]`).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct SolverSpec {
    /// `lm` (default), `gn`, `sd` or `svd`.
    #[serde(default, skip_serializing_if = "is_default")]
    pub method: Method,
    /// The iteration cap (default [`SolverOptions::new`]'s).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_iterations: Option<usize>,
    /// Levenberg-Marquardt's damping: `marquardt` (default) or `identity`.
    #[serde(default, skip_serializing_if = "is_default")]
    pub damping: Damping,
    /// The relative singular-value tolerance of the SVD method (default
    /// [`crate::solve::estimation::DEFAULT_RCOND`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rcond: Option<f64>,
    /// Which of equally good answers: `solver` (default) or `min-change`.
    #[serde(default, skip_serializing_if = "is_default")]
    pub solution: SolutionRule,
}

/// The loss of a calibration: least squares or Huber.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[non_exhaustive]
pub enum LossKind {
    /// Least squares.
    #[default]
    Squared,
    /// Huber ([`Loss::Huber`]).
    Huber,
}

/// The loss, the weights and the outlier rule (`[residuals]`).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct ResidualSpec {
    /// `squared` (default) or `huber`.
    #[serde(default, skip_serializing_if = "is_default")]
    pub loss: LossKind,
    /// Huber's threshold, in spreads (default 1.345).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub huber_scale: Option<f64>,
    /// What one spread is: `robust` (default) or `stated`.
    #[serde(default, skip_serializing_if = "is_default")]
    pub huber_spread: Spread,
    /// Default residual standard deviations.
    #[serde(default, skip_serializing_if = "is_default")]
    pub weights: LengthAngle,
    /// Orientation residuals: `rotvec` (default) or `euler`.
    #[serde(default, skip_serializing_if = "is_default")]
    pub orientation_error: OrientationError,
    /// Rows with standard deviations of their own (sigma columns): `auto` (default: weighted by
    /// `max(sigma, m)`, the model error `m` estimated from the residuals when they show more
    /// than the sigmas) or `none` (by their sigmas alone).
    #[serde(default, skip_serializing_if = "is_default")]
    pub model_error: ModelErrorMode,
    /// The outlier threshold, in robust standard deviations (default
    /// [`crate::solve::outliers::DEFAULT_SIGMAS`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub outlier_sigma: Option<f64>,
}

/// How the calibration is checked (`[validation]`): held-out files, a hold-out fraction, or
/// folds; with `choose`, the folds choose the model (and held-out files check it).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct ValidationSpec {
    /// Held-out observation files.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub files: Vec<ObservationFile>,
    /// A fraction of the postures held out.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub holdout: Option<f64>,
    /// Cross-validation folds.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub folds: Option<usize>,
    /// The seed of the hold-out draw (default 1) or of the folds' shuffle (interleaved when
    /// absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
    /// Choose among these model candidates by cross-validation (empty: the default
    /// candidates).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub choose: Option<Vec<String>>,
    /// How many shuffles the choice's cross-validation repeats (default
    /// [`workflow::CHOICE_REPEATS`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub repeats: Option<usize>,
    /// Predict the calibrated robot's accuracy over the workspace: the model-error term by
    /// cross-validation and the summary over the joint ranges ([`crate::predict`]; what
    /// `kinecal predict` needs), and with an HTML report its accuracy map. Not done unasked
    /// (an HTML report alone does not ask for it): the cross-validation refits the
    /// calibration some 13 times.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub predict: bool,
}

/// What is written (`[outputs]`).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct OutputSpec {
    /// The calibrated robot file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub robot: Option<String>,
    /// The report (JSON).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub report: Option<String>,
    /// The HTML report.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub html: Option<String>,
    /// The units the HTML report and the summary show lengths and angles in (`default`:
    /// millimetres and degrees for a metre-radian robot; `robot`; or `mm-deg`, `um-deg`, ...).
    /// The report and the robot file keep the robot file's units.
    #[serde(default, skip_serializing_if = "DisplayChoice::is_default")]
    pub display_units: DisplayChoice,
}

impl Spec for CalibrationSpec {
    const KIND: JobKind = JobKind::Calibrate;

    fn visit_paths(&mut self, f: &mut dyn FnMut(PathRole, &mut String)) {
        f(PathRole::Robot, &mut self.robot);
        visit_opt(f, PathRole::Robot, &mut self.initial);
        for o in self
            .observations
            .iter_mut()
            .chain(self.validation.files.iter_mut())
        {
            f(PathRole::Input, &mut o.file);
        }
        let o = &mut self.outputs;
        for p in [&mut o.robot, &mut o.report, &mut o.html] {
            visit_opt(f, PathRole::Output, p);
        }
    }
}

impl CalibrationSpec {
    /// Reads the files, calibrates and writes the outputs.
    pub(crate) fn run(&self, env: &mut Env<'_>) -> Result<Done> {
        self.load()?.run(env)
    }

    /// Reads the observation files of `list` for `robot` into one dataset, and their
    /// fingerprints.
    fn read_files(
        &self,
        list: &[ObservationFile],
        robot: &Robot,
    ) -> Result<(Dataset, Vec<Fingerprint>)> {
        let all: Vec<&Path> = self
            .observations
            .iter()
            .chain(&self.validation.files)
            .map(|f| Path::new(&f.file))
            .collect();
        read_files(&self.read, list, robot, &all)
    }

    /// The library request of this job for `robot` on `data`, starting from `initial` and
    /// checked on `held_out` (the files' data, read by the caller): the one translation of the
    /// settings, for jobs read from files and for data given in memory (Python).
    pub fn request(
        &self,
        robot: &Robot,
        data: impl Into<Arc<Dataset>>,
        initial: Option<Robot>,
        held_out: Option<Dataset>,
    ) -> Result<Request> {
        let v = &self.validation;
        let given = [held_out.is_some(), v.holdout.is_some(), v.folds.is_some()];
        if v.holdout.is_some() && (v.folds.is_some() || held_out.is_some()) {
            return Err(invalid(
                Setting::Validation,
                "a hold-out fraction, held-out files and folds are three ways to check a \
                 calibration: give one",
            ));
        }
        if given[0] && given[2] && v.choose.is_none() {
            return Err(invalid(
                Setting::Validation,
                "folds and held-out files are two ways to check a calibration: give one (with a \
                 model choice, the folds choose the model and the held-out files check it)",
            ));
        }
        if v.choose.is_some()
            && (self.selection.estimate.is_some()
                || self.selection.prune.is_some()
                || v.holdout.is_some())
        {
            return Err(invalid(
                Setting::ModelCandidate,
                "a model choice is made among its candidates by folds: give the parameters and \
                 the pruning in the candidates, not as estimate, prune or a hold-out fraction",
            ));
        }
        if v.repeats.is_some() && v.choose.is_none() {
            return Err(invalid(
                Setting::ModelCandidate,
                "repeats is the number of shuffles of a model choice, and no choice is asked for",
            ));
        }
        let mut req = Request::new(robot.clone(), data);
        // The prediction only when asked for (its cross-validation costs several fits); the
        // HTML report then shows the accuracy map too, which the report must hold. An HTML
        // report without it says how to get it.
        if self.validation.predict {
            req.prediction = if self.outputs.html.is_some() {
                crate::predict::Level::Map
            } else {
                crate::predict::Level::Summary
            };
        }
        let s = &self.selection;
        if s.estimate.is_some() || s.fix.is_some() {
            req.selection = selection(s.estimate.as_deref(), "", s.fix.as_deref(), robot)?;
        }
        req.prune = s.prune;
        req.prior = match &s.prior {
            Some(text) => crate::model::prior::parse_prior(text, robot)?,
            None => robot.priors.clone(),
        };
        if let Some(total) = s.total_mass {
            crate::model::prior::set_total_mass(&mut req.prior, total, robot)
                .map_err(|m| invalid(Setting::TotalMass, m))?;
            if let Some(m) = crate::workflow::total_mass_problem(&req.selection, robot) {
                return Err(invalid(Setting::TotalMass, m));
            }
        }
        if let Some(guess) = &initial {
            if !robot.same_structure(guess) {
                return Err(invalid(
                    Setting::InitialRobot,
                    "not the same robot structure as the robot to calibrate",
                ));
            }
        }
        req.initial = initial;
        let mut solver = SolverOptions::new(self.solver.method);
        if let Some(n) = self.solver.max_iterations {
            if n == 0 {
                return Err(invalid(Setting::MaxIterations, "must be at least 1"));
            }
            solver.max_iterations = n;
        }
        solver.damping = self.solver.damping;
        if let Some(r) = self.solver.rcond {
            if !(r > 0.0 && r < 1.0) {
                return Err(invalid(
                    Setting::Rcond,
                    format!("expected a tolerance between 0 and 1, not {r}"),
                ));
            }
            solver.rcond = r;
        }
        req.solver = solver;
        req.solution = self.solver.solution;
        let r = &self.residuals;
        if let Some(k) = r.huber_scale {
            if !(k > 0.0 && k.is_finite()) {
                return Err(invalid(
                    Setting::HuberScale,
                    format!("expected a positive number of spreads, not {k}"),
                ));
            }
            if r.loss != LossKind::Huber {
                return Err(invalid(
                    Setting::HuberScale,
                    "the threshold of the Huber loss, and the loss is least squares (give loss \
                     huber)",
                ));
            }
        }
        req.loss = match r.loss {
            LossKind::Squared => Loss::Squared,
            LossKind::Huber => Loss::Huber {
                k: r.huber_scale.unwrap_or(HUBER_SCALE),
                spread: r.huber_spread,
            },
        };
        req.weights = weights(robot, &r.weights)?;
        req.orientation = r.orientation_error;
        req.model_error = r.model_error;
        if let Some(k) = r.outlier_sigma {
            req.outlier_sigmas = k;
        }
        req.validation = match (held_out, v.holdout, v.folds) {
            (Some(d), _, _) => Validation::Data(d.into()),
            (None, Some(fraction), _) => Validation::Holdout {
                fraction,
                seed: v.seed.unwrap_or(1),
            },
            (None, None, Some(k)) => Validation::Folds { k, seed: v.seed },
            (None, None, None) => Validation::None,
        };
        Ok(req)
    }

    /// Reads the robot and the files and builds the job (paths as they are: relative to the
    /// working folder).
    pub fn load(&self) -> Result<CalibrationJob> {
        let started = std::time::Instant::now();
        let (robot, robot_source) = load_robot(&self.robot)?;
        let initial = match &self.initial {
            None => None,
            Some(name) => Some(load_robot(name).map_err(|e| match e {
                Error::InvalidOption { message, .. } => invalid(Setting::InitialRobot, message),
                e => e,
            })?),
        };
        if self.observations.is_empty() {
            return Err(invalid(Setting::Observations, "no observation file given"));
        }
        let (data, sources) = self.read_files(&self.observations, &robot)?;
        let held_out = if self.validation.files.is_empty() {
            None
        } else {
            Some(self.read_files(&self.validation.files, &robot)?.0)
        };
        let mut request = self.request(&robot, data, initial.map(|(r, _)| r), held_out)?;
        request.sources = std::iter::once(robot_source.fingerprint())
            .chain(sources)
            .collect();
        let choice = candidates(self, &robot)?;
        Ok(CalibrationJob {
            spec: self.clone(),
            request,
            robot_source,
            choice,
            reading: started.elapsed().as_secs_f64(),
        })
    }
}

/// The model candidates of `spec`'s choice, when it asks for one.
fn candidates(spec: &CalibrationSpec, robot: &Robot) -> Result<Option<Vec<Candidate>>> {
    Ok(match &spec.validation.choose {
        None => None,
        Some(list) if list.is_empty() => Some(Candidate::defaults(robot)?),
        Some(list) => Some(
            list.iter()
                .map(|t| Candidate::parse(t, robot))
                .collect::<Result<_>>()?,
        ),
    })
}

/// Huber's threshold by default, in spreads (95 % efficiency under normal noise).
pub(crate) const HUBER_SCALE: f64 = 1.345;

/// A calibration ready to run: the spec, the request it gives, and what writing its outputs
/// needs.
#[derive(Debug, Clone)]
pub struct CalibrationJob {
    /// The spec (paths relative to the working folder).
    pub spec: CalibrationSpec,
    /// The library request.
    pub request: Request,
    /// The robot file as read (the template of the calibrated robot file).
    pub(crate) robot_source: Source,
    /// The model candidates to choose among, when the spec asks for a choice.
    pub choice: Option<Vec<Candidate>>,
    /// The time reading the files took (s): the report's first phase, `reading`.
    pub reading: f64,
}

impl CalibrationJob {
    /// The job of `spec` with its request built (and its data read) by the caller, as Python
    /// does for data given in memory; the model candidates of `spec`'s choice are read here.
    pub fn new(
        spec: CalibrationSpec,
        request: Request,
        robot_source: Source,
    ) -> Result<CalibrationJob> {
        let choice = candidates(&spec, &request.robot)?;
        Ok(CalibrationJob {
            spec,
            request,
            robot_source,
            choice,
            reading: 0.0,
        })
    }

    /// Runs the calibration (or the model choice); an observation whose residual cannot be
    /// computed is named with its file. Writes nothing.
    pub fn calibrate(&self, progress: &mut dyn workflow::Progress) -> Result<Outcome> {
        let v = &self.spec.validation;
        let result = match &self.choice {
            None => workflow::run(&self.request, progress),
            Some(c) => workflow::choose(
                &self.request,
                c,
                v.folds.unwrap_or(5),
                v.seed,
                v.repeats.unwrap_or(workflow::CHOICE_REPEATS),
            )
            .map(|choice| choice.outcome),
        };
        let reading = crate::report::PhaseTime {
            phase: "reading".into(),
            seconds: self.reading,
        };
        let mut spec = self.spec.clone();
        spec.outputs = OutputSpec::default();
        let spec = serde_json::to_value(&spec).expect("a spec is plain data JSON can hold");
        let html = self.spec.outputs.html.is_some();
        result
            .map(|mut o| {
                o.report.timings.insert(0, reading);
                o.report.spec = Some(spec);
                // The HTML report's 3-D view draws the scene, which the report then holds.
                if html {
                    o.report.scene = crate::report::scene::Scene::new(
                        Some(&o.nominal),
                        &o.calibration.calibrated,
                        Some(&o.data),
                        &Default::default(),
                    )
                    .ok();
                }
                o
            })
            .map_err(|e| match e {
                Error::NonFiniteResidual { line, kind, .. } => {
                    // Name the file the observation came from (or the files it may have come from).
                    let of_kind: Vec<&str> = self
                        .spec
                        .observations
                        .iter()
                        .filter(|f| {
                            let k = match f.kind.as_deref() {
                                Some(k) => kind_index(k).unwrap_or(0),
                                None => Source::read(Path::new(&f.file))
                                    .map(|s| detect_format(&s.text))
                                    .unwrap_or(0),
                            };
                            FORMATS[k].kinds.contains(&kind)
                        })
                        .map(|f| f.file.as_str())
                        .collect();
                    let file = match of_kind.as_slice() {
                        [one] => one.to_string(),
                        many => format!("one of {}", many.join(", ")),
                    };
                    Error::input(Location::file(file).at_line(line), e.to_string())
                }
                e => e,
            })
    }

    /// Runs the calibration and writes its outputs (none when the spec is strict and a warning
    /// says the result is most likely wrong): the job's [`Done`]. A progress that stops the run
    /// at the data checks ([`workflow::Progress::data_checked`]) of a strict spec ends it with
    /// [`Document::Stopped`].
    pub fn run(&self, env: &mut Env<'_>) -> Result<Done> {
        let outcome = match self.calibrate(&mut *env.progress) {
            // The host stopped the run at the data checks (a strict front end that met a
            // warning saying the result would be wrong): nothing solved or written.
            Err(Error::Stopped { .. }) if self.spec.strict => {
                return Ok(Done {
                    document: Document::Stopped,
                    messages: Vec::new(),
                    status: Status::Implausible,
                    pending: None,
                })
            }
            solved => solved?,
        };
        let mut messages: Vec<Message> = outcome
            .warnings
            .iter()
            .cloned()
            .map(Message::Warning)
            .collect();
        if self.spec.strict && outcome.warnings.iter().any(crate::Warning::implausible) {
            return Ok(Done {
                document: Document::Calibration(Box::new(outcome)),
                messages,
                status: Status::Implausible,
                pending: None,
            });
        }
        // Wrong units end the run: the report and the page say why, no robot is written.
        let refused = refusal(&outcome).filter(|_| !self.spec.force_units);
        let mut outcome = outcome;
        if let Some(why) = &refused {
            outcome.report.refused = Some(why.clone());
            messages.push(Message::Caution(why.clone()));
        }
        env.progress.phase(workflow::Phase::Writing);
        let o = &self.spec.outputs;
        let mut staged = crate::files::output::Staged::new();
        if let Some(path) = o.robot.as_ref().filter(|_| refused.is_none()) {
            let text = crate::model::robot_file::write_robot_toml_checked(
                &outcome.calibration.calibrated,
                Some(&self.robot_source.text),
            )?;
            staged.text(Path::new(path), &text)?;
        }
        if let Some(path) = &o.report {
            staged.text(Path::new(path), &(outcome.report.to_json() + "\n"))?;
        }
        if let Some(path) = &o.html {
            let units = o
                .display_units
                .resolve(outcome.report.length_unit, outcome.report.angle_unit);
            let page = env.draw(
                super::Page::Calibration {
                    report: &outcome.report,
                    units,
                },
                path,
            )?;
            staged.bytes(Path::new(path), &page)?;
        }
        if let Some(r) = env.recorder.as_deref_mut().filter(|_| refused.is_none()) {
            env.progress.say("recording in the history");
            messages.push(Message::Note(r.record(&outcome.report)?));
        }
        let pending = if env.hold {
            Some(super::Pending(staged))
        } else {
            staged.commit()?;
            None
        };
        let robot_written = o.robot.as_ref().filter(|_| refused.is_none());
        for (path, what) in [
            (robot_written, "the calibrated robot"),
            (o.report.as_ref(), "the report"),
            (o.html.as_ref(), "the HTML report"),
        ] {
            if let Some(p) = path {
                messages.push(Message::Note(format!("wrote {what} to {p}")));
            }
        }
        let status = if refused.is_some() {
            Status::Refused
        } else if outcome.calibration.converged() {
            Status::Ok
        } else {
            Status::NotConverged
        };
        Ok(Done {
            document: Document::Calibration(Box::new(outcome)),
            messages,
            status,
            pending,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spec::Job;

    #[test]
    fn toml_round_trip_keeps_every_setting() {
        let spec = CalibrationSpec {
            robot: "r.toml".into(),
            initial: Some("g.toml".into()),
            read: ReadSettings {
                columns: vec!["v1=J1".into()],
                length_unit: Some("mm".into()),
                angle_unit: Some("deg".into()),
                position_only: true,
                session_per_file: true,
            },
            observations: vec![
                ObservationFile::new("a.csv"),
                ObservationFile {
                    file: "d.csv".into(),
                    kind: Some("distances".into()),
                    session: Some("B".into()),
                    ..ObservationFile::default()
                },
            ],
            selection: SelectionSpec {
                estimate: Some("identifiable,slopes".into()),
                fix: Some("base".into()),
                prune: Some(2.0),
                prior: Some("length=0.1,angle=0.01".into()),
                total_mass: Some(28.5),
            },
            solver: SolverSpec {
                method: Method::Svd,
                max_iterations: Some(7),
                damping: Damping::Identity,
                rcond: Some(1e-9),
                solution: SolutionRule::MinChange,
            },
            residuals: ResidualSpec {
                loss: LossKind::Huber,
                huber_scale: Some(2.0),
                huber_spread: Spread::Stated,
                weights: LengthAngle {
                    length: Some(0.05),
                    angle: None,
                },
                orientation_error: OrientationError::Euler,
                model_error: ModelErrorMode::None,
                outlier_sigma: Some(4.0),
            },
            validation: ValidationSpec {
                files: vec![ObservationFile::new("v.csv")],
                holdout: None,
                folds: Some(5),
                seed: Some(3),
                choose: Some(vec![]),
                repeats: Some(2),
                predict: true,
            },
            outputs: OutputSpec {
                robot: Some("out.toml".into()),
                report: Some("r.json".into()),
                html: None,
                display_units: "um-deg".parse().unwrap(),
            },
            strict: true,
            force_units: true,
        };
        let job = Job::Calibrate(spec);
        let text = job.to_toml().unwrap();
        assert_eq!(Job::from_toml(&text, "t").unwrap(), job, "{text}");
        let json = job.to_json();
        assert_eq!(Job::from_json(&json, "j").unwrap(), job);
        // Defaults are left out.
        let bare = Job::Calibrate(CalibrationSpec {
            robot: "ge-a4".into(),
            ..CalibrationSpec::default()
        });
        assert_eq!(
            bare.to_toml().unwrap().trim(),
            "job = \"calibrate\"\nrobot = \"ge-a4\""
        );
    }

    #[test]
    fn unknown_keys_and_values_are_refused_with_the_line() {
        let e = Job::from_toml("robot = \"r\"\n\n[solver]\nmethod = \"xx\"\n", "j.toml")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("j.toml:4"), "{e}");
        assert!(e.contains("lm") && e.contains("svd"), "{e}");
        let e = Job::from_toml("robot = \"r\"\n[selection]\nestimat = \"all\"\n", "j")
            .unwrap_err()
            .to_string();
        assert!(e.contains("estimat") && e.contains("estimate"), "{e}");
        let e = Job::from_toml("robot = \"r\"\n[validation]\nholdout = nan\n", "j")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("validation.holdout") && e.contains("finite"),
            "{e}"
        );
        // A spec without its robot reads, and is refused naming the robot when loaded.
        let Job::Calibrate(spec) = Job::from_toml("[solver]\n", "j").unwrap() else {
            unreachable!()
        };
        let e = spec.load().unwrap_err();
        assert!(
            matches!(
                e,
                Error::InvalidOption {
                    setting: Setting::Robot,
                    ..
                }
            ),
            "{e}"
        );
    }

    #[test]
    fn paths_are_taken_from_the_spec_folder_and_built_in_robots_stay() {
        let Job::Calibrate(spec) = Job::Calibrate(CalibrationSpec {
            robot: "ge-a4".into(),
            initial: Some("guess.toml".into()),
            observations: vec![
                ObservationFile::new("a.csv"),
                ObservationFile::new("/abs/b.csv"),
            ],
            outputs: OutputSpec {
                report: Some("r.json".into()),
                ..OutputSpec::default()
            },
            ..CalibrationSpec::default()
        })
        .rebased(Path::new("jobs")) else {
            unreachable!()
        };
        assert_eq!(spec.robot, "ge-a4");
        assert_eq!(spec.initial.as_deref(), Some("jobs/guess.toml"));
        assert_eq!(spec.observations[0].file, "jobs/a.csv");
        assert_eq!(spec.observations[1].file, "/abs/b.csv");
        assert_eq!(spec.outputs.report.as_deref(), Some("jobs/r.json"));
    }

    #[test]
    fn settings_errors_name_the_setting() {
        let robot = crate::model::examples::ge_a4();
        let mut spec = CalibrationSpec::default();
        let data = Dataset::default();
        spec.validation.holdout = Some(0.2);
        spec.validation.folds = Some(3);
        let e = spec.request(&robot, data.clone(), None, None).unwrap_err();
        assert!(matches!(
            e,
            Error::InvalidOption {
                setting: Setting::Validation,
                ..
            }
        ));
        let mut spec = CalibrationSpec::default();
        spec.residuals.weights.length = Some(-1.0);
        let e = spec.request(&robot, data.clone(), None, None).unwrap_err();
        assert!(matches!(
            e,
            Error::InvalidOption {
                setting: Setting::Weights,
                ..
            }
        ));
        let mut spec = CalibrationSpec::default();
        spec.solver.max_iterations = Some(0);
        let e = spec.request(&robot, data, None, None).unwrap_err();
        assert!(matches!(
            e,
            Error::InvalidOption {
                setting: Setting::MaxIterations,
                ..
            }
        ));
        let e = load_robot("no-such-robot").unwrap_err();
        assert!(matches!(
            e,
            Error::InvalidOption {
                setting: Setting::Robot,
                ..
            }
        ));
    }
}
