//! The history jobs: record calibrations and maintenance events of robots, read them back, and
//! watch the determined quantities drift, one robot or a whole fleet.
//!
//! The library knows these jobs' specs; their store is the `kinecal-history` crate, whose
//! `Historian` the host hands to [`run`](super::run) in [`Env::historian`](super::Env) (the
//! command line and Python do). So a history job is said, written down, batched and checked
//! like every other job, and run by the crate that owns the database.
//!
//! ```toml
//! job = "history-drift"
//! db = "history.sqlite"        # or postgres://USER@HOST/DBNAME; default $KINECAL_DB
//! robot_id = "A4-0042"
//! sigma = 3                    # flag changes beyond 3 standard deviations
//! tolerance = "tolerances.toml"
//! ```
//!
//! Conventions: times (`at`, `now`) are RFC 3339 or `YYYY-MM-DD` (UTC); `horizon` is in days;
//! tolerances are in each quantity's unit (the robot's first record's).

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

use super::common::{is_default, visit_opt};
use super::{Done, Env, JobKind, PathRole, Spec};

/// What runs the history jobs: the `kinecal-history` crate's `Historian`.
pub trait Historian {
    /// Runs the history job `job` (one of the `History*` kinds).
    fn run(&self, job: &super::Job, env: &mut Env<'_>) -> Result<Done>;
}

/// The document of a history job, made by the [`Historian`]: the host downcasts it to the
/// history crate's document to show it.
pub trait HistoryDocument: std::fmt::Debug + Send {
    /// The document as JSON (the command line's `--json`).
    fn to_json_value(&self) -> serde_json::Value;
    /// The document, for a downcast.
    fn as_any(&self) -> &dyn std::any::Any;
}

/// Runs a history job through `env`'s historian.
fn through(job: super::Job, env: &mut Env<'_>) -> Result<Done> {
    match env.historian {
        Some(h) => h.run(&job, env),
        None => Err(Error::History(
            format!(
                "`{}`: this program keeps no history (it runs through kinecal-history's Historian)",
                job.kind()
            )
            .into(),
        )),
    }
}

/// The history's location, as every history job names it: `db`.
fn visit_db(f: &mut dyn FnMut(PathRole, &mut String), db: &mut Option<String>) {
    visit_opt(f, PathRole::History, db);
}

/// Declares a history spec's [`Spec`] and `run`.
macro_rules! history_spec {
    ($spec:ident, $kind:ident, |$s:ident, $f:ident| $visit:block) => {
        impl Spec for $spec {
            const KIND: JobKind = JobKind::$kind;

            fn visit_paths(&mut self, $f: &mut dyn FnMut(PathRole, &mut String)) {
                let $s = self;
                visit_db($f, &mut $s.db);
                $visit
            }
        }

        impl $spec {
            /// Runs it through `env`'s historian.
            pub(crate) fn run(&self, env: &mut Env<'_>) -> Result<Done> {
                through(super::Job::$kind(self.clone()), env)
            }
        }
    };
}

/// `history-add`: record a calibration report of a robot.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct HistoryAddSpec {
    /// The history (a SQLite file or a `postgres://` URL); default `$KINECAL_DB`, else
    /// `kinecal/history.sqlite` in the user's data folder.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub db: Option<String>,
    /// The robot's serial number.
    #[serde(default)]
    pub robot_id: String,
    /// The calibration report (`kinecal calibrate --report`).
    #[serde(default)]
    pub report: String,
    /// When it was calibrated; default now.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub at: Option<String>,
    /// A note.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub note: String,
    /// Record it even when the robot model differs from the serial's earlier records (the
    /// robot was rebuilt).
    #[serde(default, skip_serializing_if = "is_default")]
    pub force: bool,
}

history_spec!(HistoryAddSpec, HistoryAdd, |s, f| {
    f(PathRole::Input, &mut s.report);
});

/// `history-list`: the recorded calibrations, of one robot or all.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct HistoryListSpec {
    /// The history (see [`HistoryAddSpec::db`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub db: Option<String>,
    /// Only this robot.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub robot_id: Option<String>,
}

history_spec!(HistoryListSpec, HistoryList, |_s, _f| {});

/// `history-show`: one calibration, by id or the latest of a robot.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct HistoryShowSpec {
    /// The history (see [`HistoryAddSpec::db`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub db: Option<String>,
    /// The latest calibration of this robot.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub robot_id: Option<String>,
    /// A calibration by id (over `robot_id`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub id: Option<i64>,
}

history_spec!(HistoryShowSpec, HistoryShow, |_s, _f| {});

/// The forms of a history export.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[non_exhaustive]
pub enum HistoryFormat {
    /// One row per calibration and parameter.
    #[default]
    Csv,
    /// Every calibration with its parameters and combinations.
    Json,
    /// Every stored field of every record and event, for `history-import` (lossless).
    Dump,
}

/// `history-export`: the history as CSV, JSON or a lossless dump.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct HistoryExportSpec {
    /// The history (see [`HistoryAddSpec::db`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub db: Option<String>,
    /// Only this robot (not with `dump`, which is the whole history).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub robot_id: Option<String>,
    /// The form.
    #[serde(default, skip_serializing_if = "is_default")]
    pub format: HistoryFormat,
    /// Where to write it; without it, the document carries the text.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub out: Option<String>,
}

history_spec!(HistoryExportSpec, HistoryExport, |s, f| {
    visit_opt(f, PathRole::Output, &mut s.out);
});

/// The calibration drift is measured from: `"first"` (of the segment since the latest
/// maintenance event), `"latest-ok"` (the latest calibration nothing was flagged in), or a
/// calibration's id.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum BaselineSpec {
    /// A calibration by id.
    Id(i64),
    /// `first` or `latest-ok`.
    Named(String),
}

impl Default for BaselineSpec {
    fn default() -> Self {
        BaselineSpec::Named("first".into())
    }
}

/// The default drift threshold, in standard deviations.
pub(crate) const DRIFT_SIGMA: f64 = 3.0;

/// The default horizon of a fleet's crossings, in days.
pub(crate) const HORIZON_DAYS: f64 = 90.0;

fn default_sigma() -> f64 {
    DRIFT_SIGMA
}

fn is_default_sigma(v: &f64) -> bool {
    *v == DRIFT_SIGMA
}

fn default_horizon() -> f64 {
    HORIZON_DAYS
}

fn is_default_horizon(v: &f64) -> bool {
    *v == HORIZON_DAYS
}

/// `history-drift`: the determined quantities of a robot that changed since a baseline.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct HistoryDriftSpec {
    /// The history (see [`HistoryAddSpec::db`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub db: Option<String>,
    /// The robot.
    #[serde(default)]
    pub robot_id: String,
    /// The calibration changes are measured from.
    #[serde(default, skip_serializing_if = "is_default")]
    pub baseline: BaselineSpec,
    /// Flag changes beyond this many standard deviations.
    #[serde(default = "default_sigma", skip_serializing_if = "is_default_sigma")]
    pub sigma: f64,
    /// A tolerance file (TOML `key = value`: parameter names or ids, or combination
    /// expressions, in the quantity's unit).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tolerance: Option<String>,
}

impl Default for HistoryDriftSpec {
    fn default() -> Self {
        HistoryDriftSpec {
            db: None,
            robot_id: String::new(),
            baseline: BaselineSpec::default(),
            sigma: DRIFT_SIGMA,
            tolerance: None,
        }
    }
}

history_spec!(HistoryDriftSpec, HistoryDrift, |s, f| {
    visit_opt(f, PathRole::Input, &mut s.tolerance);
});

/// `history-plot`: each tracked quantity of a robot over time, with its sigma bars, the first
/// value's 3-sigma band, tolerances and maintenance events (SVG or PNG, by `out`'s extension).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct HistoryPlotSpec {
    /// The history (see [`HistoryAddSpec::db`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub db: Option<String>,
    /// The robot.
    #[serde(default)]
    pub robot_id: String,
    /// Only these quantities (parameter names or ids, or combination expressions); all when
    /// empty.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub param: Vec<String>,
    /// A tolerance file, drawn as lines around the first value.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tolerance: Option<String>,
    /// The picture: `.svg` or `.png`.
    #[serde(default)]
    pub out: String,
}

history_spec!(HistoryPlotSpec, HistoryPlot, |s, f| {
    visit_opt(f, PathRole::Input, &mut s.tolerance);
    f(PathRole::Output, &mut s.out);
});

/// `history-fleet`: every robot's state, most urgent first: flagged, serviced, due (a trend
/// crosses a tolerance within the horizon), ok, or single.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct HistoryFleetSpec {
    /// The history (see [`HistoryAddSpec::db`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub db: Option<String>,
    /// Flag changes beyond this many standard deviations.
    #[serde(default = "default_sigma", skip_serializing_if = "is_default_sigma")]
    pub sigma: f64,
    /// A tolerance file, the same for every robot.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tolerance: Option<String>,
    /// A robot is due when a trend crosses a tolerance within this many days of `now`.
    #[serde(
        default = "default_horizon",
        skip_serializing_if = "is_default_horizon"
    )]
    pub horizon: f64,
    /// "Now" for the horizon; default the current time.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub now: Option<String>,
    /// Also write the fleet's document here (JSON).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub json: Option<String>,
    /// Also write a page here (HTML, a chart per flagged or due robot).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub html: Option<String>,
}

impl Default for HistoryFleetSpec {
    fn default() -> Self {
        HistoryFleetSpec {
            db: None,
            sigma: DRIFT_SIGMA,
            tolerance: None,
            horizon: HORIZON_DAYS,
            now: None,
            json: None,
            html: None,
        }
    }
}

history_spec!(HistoryFleetSpec, HistoryFleet, |s, f| {
    visit_opt(f, PathRole::Input, &mut s.tolerance);
    visit_opt(f, PathRole::Output, &mut s.json);
    visit_opt(f, PathRole::Output, &mut s.html);
});

/// `history-event`: record a maintenance event; drift is computed within the segments between
/// events.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct HistoryEventSpec {
    /// The history (see [`HistoryAddSpec::db`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub db: Option<String>,
    /// The robot.
    #[serde(default)]
    pub robot_id: String,
    /// When; default now.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub at: Option<String>,
    /// What was done ("gearbox J2 replaced").
    #[serde(default)]
    pub note: String,
}

history_spec!(HistoryEventSpec, HistoryEvent, |_s, _f| {});

/// `history-events`: the maintenance events, of one robot or all.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct HistoryEventsSpec {
    /// The history (see [`HistoryAddSpec::db`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub db: Option<String>,
    /// Only this robot.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub robot_id: Option<String>,
}

history_spec!(HistoryEventsSpec, HistoryEvents, |_s, _f| {});

/// `history-import`: a dump (`history-export` with `format = "dump"`) read into the history;
/// what is already there is skipped.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct HistoryImportSpec {
    /// The history (see [`HistoryAddSpec::db`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub db: Option<String>,
    /// The dump.
    #[serde(default)]
    pub dump: String,
}

history_spec!(HistoryImportSpec, HistoryImport, |s, f| {
    f(PathRole::Input, &mut s.dump);
});

/// `history-init`: create the history's schema, or migrate it to this kinecal's version.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct HistoryInitSpec {
    /// The history (see [`HistoryAddSpec::db`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub db: Option<String>,
}

history_spec!(HistoryInitSpec, HistoryInit, |_s, _f| {});
