//! Every job as one document: the one door of kinecal.
//!
//! A job is what a user asks kinecal to do: calibrate a robot, analyze what data can determine,
//! plan postures, predict accuracy, compensate a program, the ISO 9283 steps, simulate data,
//! check a robot, export or import a model, draw a report or curves. Each has one serde document,
//! its *spec* ([`CalibrationSpec`], [`AnalyzeSpec`], ...), and [`Job`] is the enum over them.
//! Every front end only says a job in its own syntax and hands the spec to [`run`]:
//!
//! - the command line (`kinecal analyze --robot r.toml --data d.csv`, or `--spec job.toml` with
//!   flags overriding the file; `--write-spec job.toml` writes the spec of a command line);
//! - a batch manifest (`kinecal batch jobs.toml`: `[[jobs]]` tables, each a spec);
//! - Python (`kinecal.run("job.toml")`, or a dict; the named functions such as
//!   `kinecal.analyze` build the same spec from their keywords).
//!
//! So the same job gives the same document whichever way it was said. Each spec turns its
//! settings into the library's typed request in one function (`request` of each spec module),
//! where every range and consistency check is made: a bad value is an
//! [`Error::InvalidOption`] naming the [`crate::Setting`], which each front end words as its flag, key
//! or keyword.
//!
//! On disk a spec is TOML with the kind of job in `job` (`calibrate` when absent):
//!
//! ```toml
//! job = "analyze"
//! robot = "qkm_hl6.toml"
//!
//! [[observations]]
//! file = "identification.csv"
//! ```
//!
//! Conventions: relative paths in a spec file are relative to the spec file's folder (to the
//! working folder for a spec built in memory); numbers are in the robot file's units unless a
//! key says otherwise.

use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::error::{Error, Location, Result};
use crate::source::Source;
use crate::warning::Warning;

pub mod analyze;
pub mod calibrate;
pub mod check;
mod common;
pub mod compensate;
pub mod curves;
pub mod export;
pub mod history;
pub mod iso9283;
pub mod limits;
pub mod plan;
pub mod predict;
pub mod report;
pub mod simulate;

pub use analyze::{AnalysisSelection, AnalyzeOutcome, AnalyzeSpec, MatrixKind, MatrixUnits};
pub use calibrate::{
    CalibrationJob, CalibrationSpec, LossKind, OutputSpec, ResidualSpec, SelectionSpec, SolverSpec,
    ValidationSpec,
};
pub use check::{CheckOutcome, CheckSpec};
pub use common::{load_robot, weights, LengthAngle, Residuals};
pub use compensate::{
    CompensateOutcome, CompensateSpec, CompensationSummary, ProgramFormat, ProgramZone,
};
pub use curves::{CurveKind, Curves, CurvesSpec, Sweep, SweptParameter};
pub use export::{ExportFormat, ExportOutcome, ExportSpec, ImportFormat, ImportSpec};
pub use history::{
    BaselineSpec, Historian, HistoryAddSpec, HistoryDocument, HistoryDriftSpec, HistoryEventSpec,
    HistoryEventsSpec, HistoryExportSpec, HistoryFleetSpec, HistoryFormat, HistoryImportSpec,
    HistoryInitSpec, HistoryListSpec, HistoryPlotSpec, HistoryShowSpec,
};
pub use iso9283::{
    Iso9283EvaluateSpec, Iso9283LogOutcome, Iso9283LogSpec, Iso9283PlanDocument,
    Iso9283PlanOutcome, Iso9283PlanSpec, Iso9283SimulateSpec, PlannedPose, SimulatedLog,
};
pub use plan::{PlanOutcome, PlanOutputs, PlanSpec, Pool};
pub use predict::{
    calibrated, BoundSpread, PredictOutcome, PredictOutputs, PredictSpec, PredictionTable,
};
pub use report::ReportSpec;
pub use simulate::{
    FkSpec, PerturbSpread, SimulateNoise, SimulateOutcome, SimulateSpec, MIN_POINTS,
};

/// The kinds of job, as a spec's `job` key names them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum JobKind {
    /// [`CalibrationSpec`].
    Calibrate,
    /// [`AnalyzeSpec`].
    Analyze,
    /// [`PlanSpec`].
    Plan,
    /// [`PredictSpec`].
    Predict,
    /// [`CompensateSpec`].
    Compensate,
    /// [`Iso9283PlanSpec`].
    Iso9283Plan,
    /// [`Iso9283SimulateSpec`].
    Iso9283Simulate,
    /// [`Iso9283LogSpec`].
    Iso9283Log,
    /// [`Iso9283EvaluateSpec`].
    Iso9283Evaluate,
    /// [`SimulateSpec`].
    Simulate,
    /// [`FkSpec`].
    Fk,
    /// [`CheckSpec`].
    Check,
    /// [`ExportSpec`].
    Export,
    /// [`ImportSpec`].
    Import,
    /// [`ReportSpec`].
    Report,
    /// [`CurvesSpec`].
    Curves,
    /// [`HistoryAddSpec`].
    HistoryAdd,
    /// [`HistoryListSpec`].
    HistoryList,
    /// [`HistoryShowSpec`].
    HistoryShow,
    /// [`HistoryExportSpec`].
    HistoryExport,
    /// [`HistoryDriftSpec`].
    HistoryDrift,
    /// [`HistoryPlotSpec`].
    HistoryPlot,
    /// [`HistoryFleetSpec`].
    HistoryFleet,
    /// [`HistoryEventSpec`].
    HistoryEvent,
    /// [`HistoryEventsSpec`].
    HistoryEvents,
    /// [`HistoryImportSpec`].
    HistoryImport,
    /// [`HistoryInitSpec`].
    HistoryInit,
}

impl JobKind {
    /// Every kind.
    pub const ALL: [JobKind; 27] = [
        JobKind::Calibrate,
        JobKind::Analyze,
        JobKind::Plan,
        JobKind::Predict,
        JobKind::Compensate,
        JobKind::Iso9283Plan,
        JobKind::Iso9283Simulate,
        JobKind::Iso9283Log,
        JobKind::Iso9283Evaluate,
        JobKind::Simulate,
        JobKind::Fk,
        JobKind::Check,
        JobKind::Export,
        JobKind::Import,
        JobKind::Report,
        JobKind::Curves,
        JobKind::HistoryAdd,
        JobKind::HistoryList,
        JobKind::HistoryShow,
        JobKind::HistoryExport,
        JobKind::HistoryDrift,
        JobKind::HistoryPlot,
        JobKind::HistoryFleet,
        JobKind::HistoryEvent,
        JobKind::HistoryEvents,
        JobKind::HistoryImport,
        JobKind::HistoryInit,
    ];

    /// The name in a spec's `job` key (the command's name; `iso9283-plan` for
    /// `kinecal iso9283 plan`).
    pub fn name(self) -> &'static str {
        match self {
            JobKind::Calibrate => "calibrate",
            JobKind::Analyze => "analyze",
            JobKind::Plan => "plan",
            JobKind::Predict => "predict",
            JobKind::Compensate => "compensate",
            JobKind::Iso9283Plan => "iso9283-plan",
            JobKind::Iso9283Simulate => "iso9283-simulate",
            JobKind::Iso9283Log => "iso9283-log",
            JobKind::Iso9283Evaluate => "iso9283-evaluate",
            JobKind::Simulate => "simulate",
            JobKind::Fk => "fk",
            JobKind::Check => "check",
            JobKind::Export => "export",
            JobKind::Import => "import",
            JobKind::Report => "report",
            JobKind::Curves => "curves",
            JobKind::HistoryAdd => "history-add",
            JobKind::HistoryList => "history-list",
            JobKind::HistoryShow => "history-show",
            JobKind::HistoryExport => "history-export",
            JobKind::HistoryDrift => "history-drift",
            JobKind::HistoryPlot => "history-plot",
            JobKind::HistoryFleet => "history-fleet",
            JobKind::HistoryEvent => "history-event",
            JobKind::HistoryEvents => "history-events",
            JobKind::HistoryImport => "history-import",
            JobKind::HistoryInit => "history-init",
        }
    }

    /// The kind named `name`.
    pub fn parse(name: &str) -> Option<JobKind> {
        JobKind::ALL.into_iter().find(|k| k.name() == name)
    }
}

impl std::fmt::Display for JobKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// What a path of a spec is, for rebasing and for keeping outputs off inputs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PathRole {
    /// A robot: a file, or a built-in robot's name when no such file exists.
    Robot,
    /// A file the job reads.
    Input,
    /// A file the job writes.
    Output,
    /// A history: a SQLite file (read, and written by the jobs that record), or a PostgreSQL
    /// server's URL (never rebased, never a file).
    History,
}

/// What every spec is: a serde document that names its files.
pub trait Spec:
    Serialize + serde::de::DeserializeOwned + Default + Clone + PartialEq + std::fmt::Debug + Into<Job>
{
    /// Its kind.
    const KIND: JobKind;

    /// Calls `f` on every path of the spec, with its role.
    fn visit_paths(&mut self, f: &mut dyn FnMut(PathRole, &mut String));
}

/// Declares [`Job`] over the specs, with the dispatch of its methods.
macro_rules! jobs {
    ($($kind:ident($spec:ty)),* $(,)?) => {
        /// One job of any kind: the spec that [`run`] runs.
        #[derive(Debug, Clone, PartialEq)]
        #[non_exhaustive]
        pub enum Job {
            $(
                #[doc = concat!("A [`", stringify!($spec), "`].")]
                $kind($spec),
            )*
        }

        impl Job {
            /// Its kind.
            pub fn kind(&self) -> JobKind {
                match self {
                    $(Job::$kind(_) => JobKind::$kind,)*
                }
            }

            /// Calls `f` on every path of the spec, with its role.
            pub(crate) fn visit_paths(&mut self, f: &mut dyn FnMut(PathRole, &mut String)) {
                match self {
                    $(Job::$kind(s) => s.visit_paths(f),)*
                }
            }

            /// The spec as a TOML table's text (keys that differ from the defaults), without
            /// the `job` key.
            fn body_toml(&self) -> String {
                match self {
                    $(Job::$kind(s) => toml_edit::ser::to_string_pretty(s),)*
                }
                .expect("a spec is plain data TOML can hold")
            }

            /// The spec as JSON (keys that differ from the defaults), with its `job` key.
            pub fn to_json(&self) -> String {
                let mut v = match self {
                    $(Job::$kind(s) => serde_json::to_value(s),)*
                }
                .expect("a spec is plain data JSON can hold");
                if let serde_json::Value::Object(m) = &mut v {
                    m.insert("job".into(), self.kind().name().into());
                }
                v.to_string()
            }

            /// The spec of `kind` read from `text` (TOML, named `file` in errors; the `job`
            /// key already taken out).
            fn from_toml_of(kind: JobKind, text: &str, file: &str) -> Result<Job> {
                $(
                    if kind == JobKind::$kind {
                        return common::from_toml::<$spec>(text, file).map(Job::$kind);
                    }
                )*
                unreachable!("every kind has a spec")
            }

            /// The spec of `kind` read from a JSON value (the `job` key taken out).
            fn from_value_of(kind: JobKind, value: serde_json::Value, file: &str) -> Result<Job> {
                $(
                    if kind == JobKind::$kind {
                        return common::from_value::<$spec>(value, file).map(Job::$kind);
                    }
                )*
                unreachable!("every kind has a spec")
            }

            /// Runs the job (see [`run`]).
            fn run_in(&self, env: &mut Env<'_>) -> Result<Done> {
                match self {
                    $(Job::$kind(s) => s.run(env),)*
                }
            }
        }

        $(
            impl From<$spec> for Job {
                fn from(s: $spec) -> Job {
                    Job::$kind(s)
                }
            }

            /// The spec of a job of this kind; the job itself when it is of another.
            impl TryFrom<Job> for $spec {
                type Error = Job;

                fn try_from(job: Job) -> std::result::Result<$spec, Job> {
                    match job {
                        Job::$kind(s) => Ok(s),
                        other => Err(other),
                    }
                }
            }
        )*
    };
}

jobs! {
    Calibrate(CalibrationSpec),
    Analyze(AnalyzeSpec),
    Plan(PlanSpec),
    Predict(PredictSpec),
    Compensate(CompensateSpec),
    Iso9283Plan(Iso9283PlanSpec),
    Iso9283Simulate(Iso9283SimulateSpec),
    Iso9283Log(Iso9283LogSpec),
    Iso9283Evaluate(Iso9283EvaluateSpec),
    Simulate(SimulateSpec),
    Fk(FkSpec),
    Check(CheckSpec),
    Export(ExportSpec),
    Import(ImportSpec),
    Report(ReportSpec),
    Curves(CurvesSpec),
    HistoryAdd(HistoryAddSpec),
    HistoryList(HistoryListSpec),
    HistoryShow(HistoryShowSpec),
    HistoryExport(HistoryExportSpec),
    HistoryDrift(HistoryDriftSpec),
    HistoryPlot(HistoryPlotSpec),
    HistoryFleet(HistoryFleetSpec),
    HistoryEvent(HistoryEventSpec),
    HistoryEvents(HistoryEventsSpec),
    HistoryImport(HistoryImportSpec),
    HistoryInit(HistoryInitSpec),
}

impl Job {
    /// A job read from TOML `text` (named `file` in errors): its kind from the `job` key
    /// (`calibrate` when absent), then the spec of that kind. Unknown keys, wrong types and
    /// numbers that are not finite are errors with the line and the key.
    pub fn from_toml(text: &str, file: &str) -> Result<Job> {
        let (kind, rest) = common::take_job_key(text, file)?;
        Job::from_toml_of(kind.unwrap_or(JobKind::Calibrate), &rest, file)
    }

    /// A job read from JSON `text` (a spec's keys, with `job`).
    pub fn from_json(text: &str, file: &str) -> Result<Job> {
        let value: serde_json::Value = serde_json::from_str(text).map_err(|e| {
            Error::input(
                Location {
                    file: file.to_string(),
                    line: Some(e.line()),
                    field: None,
                },
                e.to_string(),
            )
        })?;
        Job::from_value(value, file)
    }

    /// A job from a JSON value (a spec's keys, with `job`; `calibrate` when absent), as
    /// Python's dicts arrive.
    pub fn from_value(mut value: serde_json::Value, file: &str) -> Result<Job> {
        let kind = match &mut value {
            serde_json::Value::Object(m) => match m.remove("job") {
                None => JobKind::Calibrate,
                Some(serde_json::Value::String(s)) => common::kind_named(&s, file)?,
                Some(other) => {
                    return Err(Error::input(
                        Location::file(file).with_field("job"),
                        format!("expected the name of a job, not {other}"),
                    ))
                }
            },
            other => {
                return Err(Error::input(
                    Location::file(file),
                    format!("expected a table of a spec's keys, not {other}"),
                ))
            }
        };
        Job::from_value_of(kind, value, file)
    }

    /// Reads a spec file; its relative paths are made relative to the working folder (joined
    /// to the spec file's folder).
    pub fn read(path: &Path) -> Result<Job> {
        let source = Source::read(path)?;
        let job = Job::from_toml(&source.text, &source.name)?;
        Ok(job.rebased(path.parent().unwrap_or(Path::new(""))))
    }

    /// The spec as TOML, its `job` key first; refused when a number or text is beyond its
    /// bound ([`limits`]: every accepted value is one a spec file holds and reads back).
    pub fn to_toml(&self) -> Result<String> {
        limits::check(self)?;
        let body = self.body_toml();
        Ok(format!("job = \"{}\"\n{}{body}", self.kind().name(), {
            // A blank line before the first table, none before the first key.
            if body.starts_with('[') {
                "\n"
            } else {
                ""
            }
        }))
    }

    /// The same job with every relative path taken relative to `base` (the folder of the
    /// file it was read from); a built-in robot's name stays unless a file of that name is
    /// there.
    pub fn rebased(mut self, base: &Path) -> Job {
        self.visit_paths(&mut |role, p| {
            *p = match role {
                PathRole::Robot => common::rebase_robot(base, p),
                PathRole::Input | PathRole::Output => common::rebase(base, p),
                PathRole::History if common::is_url(p) => p.clone(),
                PathRole::History => common::rebase(base, p),
            }
        });
        self
    }

    /// The spec to write in the file `path`, its paths (relative to the working folder) made
    /// to work from there: kept when the file is in the working folder, else made absolute.
    pub fn written_to(&self, path: &Path) -> Result<Job> {
        let folder = path.parent().unwrap_or(Path::new(""));
        if folder.as_os_str().is_empty() || folder == Path::new(".") {
            return Ok(self.clone());
        }
        let cwd = std::env::current_dir().map_err(|cause| Error::Io {
            path: ".".into(),
            cause,
        })?;
        Ok(self.clone().rebased(&cwd))
    }

    /// The files the job reads (robots that are files, not built-in names).
    pub fn inputs(&self) -> Vec<PathBuf> {
        let mut v = Vec::new();
        self.clone().visit_paths(&mut |role, p| match role {
            PathRole::Robot if common::is_robot_file(p) => v.push(PathBuf::from(p.as_str())),
            PathRole::Input => v.push(PathBuf::from(p.as_str())),
            PathRole::History if !common::is_url(p) => v.push(PathBuf::from(p.as_str())),
            _ => {}
        });
        v
    }

    /// The files the job writes.
    pub fn outputs(&self) -> Vec<PathBuf> {
        let mut v = Vec::new();
        self.clone().visit_paths(&mut |role, p| {
            if role == PathRole::Output {
                v.push(PathBuf::from(p.as_str()));
            }
        });
        v
    }
}

/// The spec `S` from a JSON value (its keys, with or without a `job` key naming `S`'s kind), as
/// the named functions of Python send their keywords: errors name the key path.
pub fn spec_from_value<S: Spec>(mut value: serde_json::Value, file: &str) -> Result<S> {
    if let serde_json::Value::Object(m) = &mut value {
        if let Some(job) = m.remove("job") {
            if job.as_str() != Some(S::KIND.name()) {
                return Err(Error::input(
                    Location::file(file).with_field("job"),
                    format!("expected `{}`, not {job}", S::KIND.name()),
                ));
            }
        }
    }
    let spec: S = common::from_value(value, file)?;
    limits::check(&spec.clone().into())?;
    Ok(spec)
}

/// What a job's run reports as it goes, and asks of its host. Every method has a default that
/// does nothing.
pub use crate::workflow::Progress;

/// What draws the pages and pictures of jobs: the `kinecal-report` crate's `Artist`. A job
/// asked for a page runs without one only to fail, naming the output.
pub trait Artist {
    /// The bytes of `page`.
    fn draw(&self, page: Page<'_>) -> Result<Vec<u8>>;
}

/// A page or picture a job writes.
#[non_exhaustive]
pub enum Page<'a> {
    /// The HTML page of a calibration report.
    Calibration {
        /// The report.
        report: &'a crate::report::CalibrationReport,
        /// The units the page shows lengths and angles in.
        units: crate::units::DisplayUnits,
    },
    /// The HTML page of a measurement plan.
    Plan {
        /// The plan.
        plan: &'a crate::apps::plan::Plan,
        /// Its robot.
        robot: &'a crate::Robot,
        /// The candidates it chose from.
        pool: &'a crate::Dataset,
        /// Where they came from, in words.
        described: &'a str,
    },
    /// The HTML page of a predicted accuracy (with its map).
    Prediction {
        /// The prediction.
        prediction: &'a crate::predict::PredictionReport,
        /// The robot's name.
        robot: &'a str,
        /// Its length unit.
        length_unit: crate::units::LengthUnit,
        /// Its angle unit.
        angle_unit: crate::units::AngleUnit,
        /// The units the page shows lengths and angles in.
        units: crate::units::DisplayUnits,
    },
    /// The HTML page of ISO 9283 figures.
    Iso9283(&'a crate::apps::iso9283::Evaluation),
    /// Characteristic curves as a picture.
    Curves {
        /// The curves.
        curves: &'a Curves,
        /// SVG or PNG.
        image: Image,
    },
}

/// The form of a picture.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Image {
    /// SVG text.
    Svg,
    /// PNG bytes.
    Png,
}

/// What records a calibration in a history (the `kinecal-history` crate's stores): called once
/// the outputs are ready and before they are put in place, so that a failure to record leaves
/// every output as it was.
pub trait Recorder {
    /// Records the calibration of `report`; what to tell the user.
    fn record(&mut self, report: &crate::report::CalibrationReport) -> Result<String>;
}

/// What a job's run may use: where its progress goes and what draws its pages.
pub struct Env<'a> {
    /// Told of the phases (and a calibration's iterations and data checks).
    pub progress: &'a mut dyn Progress,
    /// Draws pages and pictures; `None` when the host has no drawing (a page asked for is then
    /// an error).
    pub artist: Option<&'a dyn Artist>,
    /// Files that are inputs of the run besides the spec's own (the spec file itself, a
    /// history database): no output may replace them.
    pub also_inputs: Vec<PathBuf>,
    /// Records a calibration in a history, when asked.
    pub recorder: Option<&'a mut dyn Recorder>,
    /// Runs the history jobs: `kinecal-history`'s `Historian` (a history job without one is
    /// an error).
    pub historian: Option<&'a dyn Historian>,
    /// Hold a calibration's outputs: staged beside their targets, returned in
    /// [`Done::pending`] for the caller to put in place (a batch records its robots in order,
    /// then commits each). Other jobs write as they finish.
    pub hold: bool,
}

impl<'a> Env<'a> {
    /// An environment with `progress`, `artist` and nothing more.
    pub fn new(progress: &'a mut dyn Progress, artist: Option<&'a dyn Artist>) -> Env<'a> {
        Env {
            progress,
            artist,
            also_inputs: Vec::new(),
            recorder: None,
            historian: None,
            hold: false,
        }
    }

    /// Draws `page` for the output `path`.
    pub(crate) fn draw(&self, page: Page<'_>, path: &str) -> Result<Vec<u8>> {
        match self.artist {
            Some(a) => a.draw(page),
            None => Err(Error::Output {
                path: path.to_string(),
                message: "this program draws no pages or pictures".into(),
            }),
        }
    }
}

/// How a job ended, for a front end's exit status.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
#[serde(rename_all = "kebab-case")]
#[non_exhaustive]
pub enum Status {
    /// Done as asked.
    #[default]
    Ok,
    /// A calibration's solver stopped at its cap or stalled; the outputs are written.
    NotConverged,
    /// A warning says the result is most likely wrong and the spec is strict: nothing written.
    Implausible,
    /// A unit check fired and the fit ended far above the stated noise: the calibration is
    /// refused (the report and the HTML page written, with the reason; no robot file and no
    /// history record unless the spec says `force_units`).
    Refused,
    /// A check or compensation found what needs a person: a robot out of its accuracy, rows
    /// flagged (a controller program then not written).
    Flagged,
}

/// A line a front end shows beside the document (standard error on the command line, a
/// warning in Python).
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub enum Message {
    /// What was done: `wrote the calibrated robot to cal.toml`.
    Note(String),
    /// A warning of the library, with its quantities.
    Warning(Warning),
    /// A warning in words only.
    Caution(String),
}

/// Outputs written beside their targets, not yet in place ([`Env::hold`]).
pub struct Pending(pub crate::files::output::Staged);

impl std::fmt::Debug for Pending {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Pending(..)")
    }
}

impl Pending {
    /// Puts the outputs in place.
    pub fn commit(self) -> Result<()> {
        self.0.commit()
    }
}

/// A finished job: its document, what it wrote and what it said.
#[derive(Debug)]
pub struct Done {
    /// The job's document (the command line's `--json` or report).
    pub document: Document,
    /// What was said, in order.
    pub messages: Vec<Message>,
    /// How it ended.
    pub status: Status,
    /// Its outputs, when held ([`Env::hold`]).
    pub pending: Option<Pending>,
}

impl Done {
    /// A job done as asked with `document`.
    pub(crate) fn ok(document: Document) -> Done {
        Done {
            document,
            messages: Vec::new(),
            status: Status::Ok,
            pending: None,
        }
    }

    /// Adds a note.
    pub(crate) fn note(&mut self, text: impl Into<String>) {
        self.messages.push(Message::Note(text.into()));
    }
}

/// The document of a finished job, one variant per kind of job.
#[derive(Debug)]
#[non_exhaustive]
pub enum Document {
    /// A strict calibration stopped by the data checks before solving: nothing computed.
    Stopped,
    /// A calibration (its report is the document).
    Calibration(Box<crate::workflow::Outcome>),
    /// An identifiability analysis.
    Analysis(Box<AnalyzeOutcome>),
    /// A measurement plan.
    Plan(Box<PlanOutcome>),
    /// Predicted accuracy at postures.
    Prediction(Box<PredictOutcome>),
    /// A compensated program or targets.
    Compensation(Box<CompensateOutcome>),
    /// ISO 9283 test poses.
    Iso9283Plan(Box<iso9283::Iso9283PlanOutcome>),
    /// A simulated ISO 9283 log.
    Iso9283Simulated(SimulatedLog),
    /// An ISO 9283 log made from measurements.
    Iso9283Log(Iso9283LogOutcome),
    /// ISO 9283 figures.
    Iso9283(Box<crate::apps::iso9283::Evaluation>),
    /// Simulated measurements (or forward kinematics).
    Simulation(SimulateOutcome),
    /// A check of a robot against fresh measurements.
    Check(Box<CheckOutcome>),
    /// An export or an import.
    Export(ExportOutcome),
    /// A written page (the report job).
    Page {
        /// Where.
        path: String,
    },
    /// Characteristic curves.
    Curves(Box<Curves>),
    /// A history job's document (made by the [`Historian`]).
    History(Box<dyn HistoryDocument>),
}

impl Document {
    /// The document as JSON, as the command line's `--json` or the job's report gives it.
    pub fn to_json_value(&self) -> serde_json::Value {
        let v = match self {
            Document::Stopped => Ok(serde_json::json!({ "stopped": true })),
            Document::Calibration(o) => serde_json::to_value(&o.report),
            Document::Analysis(a) => serde_json::to_value(a.document()),
            Document::Plan(p) => serde_json::to_value(p.document()),
            Document::Prediction(p) => serde_json::to_value(&p.summary),
            Document::Compensation(c) => serde_json::to_value(&c.summary),
            Document::Iso9283Plan(p) => serde_json::to_value(&p.document),
            Document::Iso9283Simulated(s) => serde_json::to_value(s),
            Document::Iso9283Log(l) => serde_json::to_value(l),
            Document::Iso9283(e) => serde_json::to_value(e),
            Document::Simulation(s) => serde_json::to_value(s),
            Document::Check(c) => serde_json::to_value(&c.report),
            Document::Export(e) => serde_json::to_value(e),
            Document::Page { path } => Ok(serde_json::json!({ "written": path })),
            Document::Curves(c) => serde_json::to_value(c),
            Document::History(h) => Ok(h.to_json_value()),
        };
        v.expect("a document is plain data JSON can hold")
    }

    /// [`Document::to_json_value`] as text.
    pub fn to_json(&self) -> String {
        self.to_json_value().to_string()
    }
}

/// Runs `job`: reads its inputs, computes, writes its outputs (all of them or none, through
/// [`crate::files::output`], never over an input of the run) and returns its document.
pub fn run(job: &Job, env: &mut Env<'_>) -> Result<Done> {
    limits::check(job)?;
    let outputs = job.outputs();
    let mut inputs = job.inputs();
    inputs.extend(env.also_inputs.iter().cloned());
    crate::files::output::check_distinct(
        &outputs.iter().map(PathBuf::as_path).collect::<Vec<_>>(),
        &inputs.iter().map(PathBuf::as_path).collect::<Vec<_>>(),
    )?;
    // The readers' notes of this job's files (an enclosing job's kept aside), said first.
    let outer = crate::files::take_notes();
    let done = job.run_in(env);
    let notes = crate::files::take_notes();
    crate::files::restore_notes(outer);
    let mut done = done?;
    done.messages
        .splice(0..0, notes.into_iter().map(Message::Note));
    Ok(done)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_kind_is_named_once_and_read_back() {
        for k in JobKind::ALL {
            assert_eq!(JobKind::parse(k.name()), Some(k));
        }
        let names: std::collections::BTreeSet<_> = JobKind::ALL.iter().map(|k| k.name()).collect();
        assert_eq!(names.len(), JobKind::ALL.len());
    }

    #[test]
    fn a_spec_without_job_is_a_calibration_and_a_written_spec_reads_back() {
        let job = Job::from_toml("robot = \"ge-a4\"\n", "j.toml").unwrap();
        assert_eq!(job.kind(), JobKind::Calibrate);
        let text = job.to_toml().unwrap();
        assert!(text.starts_with("job = \"calibrate\"\n"), "{text}");
        assert_eq!(Job::from_toml(&text, "j.toml").unwrap(), job);
        let json = job.to_json();
        assert_eq!(Job::from_json(&json, "j.json").unwrap(), job);
    }

    #[test]
    fn an_unknown_job_is_named_with_the_known_ones() {
        let e = Job::from_toml("robot = \"r\"\njob = \"calibrat\"\n", "j.toml")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("j.toml:2"), "{e}");
        assert!(e.contains("calibrat") && e.contains("analyze"), "{e}");
        // The key's line kept: the error of a later key names its own line.
        let e = Job::from_toml(
            "job = \"analyze\"\nrobot = \"r\"\nrcond = \"x\"\n",
            "j.toml",
        )
        .unwrap_err()
        .to_string();
        assert!(e.starts_with("j.toml:3"), "{e}");
    }
}
