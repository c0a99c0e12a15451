//! The history jobs run: the [`Historian`] the library's door hands every `history-*` spec to
//! (`kinecal::spec::history`), and the typed [`Document`] each one returns.
//!
//! A front end builds a spec (flags, a spec file, Python keywords, a batch entry), puts a
//! `Historian` in the run's environment and calls `kinecal::spec::run`; what it shows is the
//! document (downcast with [`Document::of`]). Pictures and pages (a history plot, the fleet's
//! page) are drawn by the host's [`Pages`] (the `kinecal-report` crate's).

use std::fmt::Write as _;
use std::path::Path;

use kinecal::files::output::{self, Staged};
use kinecal::report::CalibrationReport;
use kinecal::spec::{
    BaselineSpec, Done, Env, HistoryAddSpec, HistoryDocument, HistoryDriftSpec, HistoryEventSpec,
    HistoryEventsSpec, HistoryExportSpec, HistoryFleetSpec, HistoryFormat, HistoryImportSpec,
    HistoryInitSpec, HistoryListSpec, HistoryPlotSpec, HistoryShowSpec, Job, Message, Status,
};
use kinecal::Setting;
use serde::Serialize;

use crate::{
    drift, fleet, format_time, parse_time, printable, segment_of, AddOptions, Baseline,
    Calibration, Database, DriftOptions, DriftReport, Dump, Error, Event, FleetOptions,
    ImportSummary, Location, Quantity, RobotState, Sample, Segment, Tolerances, Verdict,
};

/// What draws the history's pictures and pages: the `kinecal-report` crate's artist.
pub trait Pages {
    /// The picture of a robot's tracked quantities over time (`png`: PNG bytes, else SVG).
    fn history_plot(&self, plot: &PlotView<'_>, png: bool) -> std::result::Result<Vec<u8>, String>;
    /// The fleet's page (HTML).
    fn fleet_page(&self, fleet: &FleetView<'_>) -> std::result::Result<String, String>;
}

/// What a history plot shows.
#[derive(Debug)]
#[non_exhaustive]
pub struct PlotView<'a> {
    /// The robot.
    pub robot_id: &'a str,
    /// Each quantity drawn, with every calibration's value of it (history units).
    pub series: &'a [(Quantity, Vec<Sample>)],
    /// The time the x axis counts days from (the first calibration drawn, Unix seconds).
    pub t0: i64,
    /// The robot's maintenance events (those since the first calibration drawn when the robot
    /// changed model).
    pub events: &'a [Event],
}

/// What the fleet's page shows.
#[derive(Debug)]
#[non_exhaustive]
pub struct FleetView<'a> {
    /// The fleet's document.
    pub fleet: &'a FleetDocument,
    /// Every robot's calibrations (all segments), in time order.
    pub calibrations: &'a [Calibration],
    /// Every maintenance event.
    pub events: &'a [Event],
}

/// Runs the history jobs for the library's door (`kinecal::spec::Env::historian`).
#[derive(Clone, Copy, Default)]
pub struct Historian<'a> {
    pages: Option<&'a (dyn Pages + Sync)>,
}

impl std::fmt::Debug for Historian<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Historian")
            .field("pages", &self.pages.is_some())
            .finish()
    }
}

impl<'a> Historian<'a> {
    /// A historian whose pictures and pages `pages` draws (`None`: a plot or a fleet page asked
    /// for is an error).
    pub const fn new(pages: Option<&'a (dyn Pages + Sync)>) -> Historian<'a> {
        Historian { pages }
    }
}

/// The document of a history job.
#[derive(Debug, Serialize)]
#[serde(untagged)]
#[non_exhaustive]
pub enum Document {
    /// A calibration recorded (`history-add`).
    Added(Recorded),
    /// Calibrations (`history-list`).
    Calibrations(Vec<Calibration>),
    /// One calibration (`history-show`).
    Calibration(Box<Calibration>),
    /// An export.
    Export(Exported),
    /// A robot's drift.
    Drift(Box<DriftDocument>),
    /// A written plot.
    Plot(Plotted),
    /// The fleet's state.
    Fleet(Box<FleetDocument>),
    /// A maintenance event recorded (`history-event`).
    Event(RecordedEvent),
    /// Maintenance events (`history-events`).
    Events(Vec<Event>),
    /// What an import wrote.
    Import(Imported),
    /// The schema made or migrated (`history-init`).
    Init(Initialized),
}

impl Document {
    /// The history document of a finished job's, if it is one.
    pub fn of(document: &kinecal::spec::Document) -> Option<&Document> {
        match document {
            kinecal::spec::Document::History(h) => h.as_any().downcast_ref(),
            _ => None,
        }
    }
}

impl HistoryDocument for Document {
    fn to_json_value(&self) -> serde_json::Value {
        serde_json::to_value(self).expect("a history document is plain data JSON can hold")
    }

    fn as_any(&self) -> &dyn std::any::Any {
        self
    }
}

/// A calibration recorded.
#[derive(Debug, Clone, Serialize)]
#[non_exhaustive]
pub struct Recorded {
    /// The history (a path, or a URL without its password).
    pub history: String,
    /// The robot.
    pub robot_id: String,
    /// The calibration's id.
    pub id: i64,
    /// Whether it was new (else the same calibration was there: nothing written).
    pub new: bool,
}

/// A maintenance event recorded.
#[derive(Debug, Clone, Serialize)]
#[non_exhaustive]
pub struct RecordedEvent {
    /// The history.
    pub history: String,
    /// The event.
    pub event: Event,
    /// Whether it was new.
    pub new: bool,
}

/// An export: written to a file, or its text.
#[derive(Debug, Clone, Serialize)]
#[non_exhaustive]
pub struct Exported {
    /// The form.
    pub format: HistoryFormat,
    /// The file written, if one was asked for.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub written: Option<String>,
    /// The text, when no file was asked for.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub text: Option<String>,
}

/// A robot's drift: the report of the current segment, and what was left out of it.
#[derive(Debug, Clone, Serialize)]
#[non_exhaustive]
pub struct DriftDocument {
    /// The comparison.
    #[serde(flatten)]
    pub report: DriftReport,
    /// The calibrations before the latest maintenance event (not compared; those after it of
    /// another robot model are in the report's `since_model_change`).
    pub before_event: usize,
    /// The compared calibrations recorded in other units than the first (converted), as
    /// `id (length unit and angle unit)`.
    pub converted: Vec<String>,
}

/// A written history plot.
#[derive(Debug, Clone, Serialize)]
#[non_exhaustive]
pub struct Plotted {
    /// The file.
    pub written: String,
    /// The quantities drawn (their keys), one panel each.
    pub quantities: Vec<String>,
}

/// The fleet's state (the JSON `history-fleet` writes).
#[derive(Debug, Clone, Serialize)]
#[non_exhaustive]
pub struct FleetDocument {
    /// The history.
    pub history: String,
    /// "Now" (RFC 3339).
    pub now: String,
    /// The horizon, days.
    pub horizon_days: f64,
    /// The drift threshold, standard deviations.
    pub sigma: f64,
    /// Every robot, most urgent first.
    pub robots: Vec<RobotState>,
}

impl FleetDocument {
    /// Robots with the verdict `v`.
    pub fn count(&self, v: Verdict) -> usize {
        self.robots.iter().filter(|r| r.verdict == v).count()
    }

    /// Whether any robot needs attention (flagged, unknown, serviced or due).
    pub fn attention(&self) -> bool {
        self.robots.iter().any(|r| {
            matches!(
                r.verdict,
                Verdict::Flagged | Verdict::Unknown | Verdict::Serviced | Verdict::Due
            )
        })
    }
}

/// What an import wrote.
#[derive(Debug, Clone, Serialize)]
#[non_exhaustive]
pub struct Imported {
    /// The history.
    pub history: String,
    /// The counts.
    #[serde(flatten)]
    pub summary: ImportSummary,
}

/// A history's schema made or migrated.
#[derive(Debug, Clone, Serialize)]
#[non_exhaustive]
pub struct Initialized {
    /// The history.
    pub history: String,
    /// `sqlite` or `postgres`.
    pub backend: String,
    /// Its schema version.
    pub schema_version: i64,
}

/// The library's error of a setting.
fn invalid(setting: Setting, message: impl Into<String>) -> kinecal::Error {
    kinecal::Error::InvalidOption {
        setting,
        message: message.into(),
    }
}

impl From<Error> for kinecal::Error {
    fn from(e: Error) -> kinecal::Error {
        kinecal::Error::History(Box::new(e))
    }
}

type Result<T> = kinecal::Result<T>;

/// The location a spec's `db` names: it, else `$KINECAL_DB`, else the default file.
pub fn location(db: Option<&str>) -> Result<Location> {
    let given = db
        .map(|s| s.to_string())
        .or_else(|| std::env::var("KINECAL_DB").ok().filter(|v| !v.is_empty()));
    match given {
        Some(v) => Ok(Location::parse(&v)),
        None => crate::default_db_path().map(Location::File).ok_or_else(|| {
            invalid(
                Setting::History,
                "no home or data folder to keep the history in: name the history",
            )
        }),
    }
}

/// A time of a spec.
fn time(text: Option<&str>, setting: Setting) -> Result<Option<i64>> {
    text.map(|s| parse_time(s).map_err(|e| invalid(setting, e.to_string())))
        .transpose()
}

/// Now, Unix seconds.
fn now() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs() as i64)
}

/// A robot serial a job needs.
fn serial(robot_id: &str) -> Result<&str> {
    if robot_id.trim().is_empty() {
        return Err(invalid(
            Setting::RobotId,
            "the robot's serial number is needed",
        ));
    }
    Ok(robot_id)
}

/// A robot serial a job records (a calibration, an event): as [`serial`], and one the history
/// keeps (no white space at its ends: never trimmed silently).
fn serial_to_write(robot_id: &str) -> Result<&str> {
    let robot_id = serial(robot_id)?;
    match crate::record::serial_problem(robot_id) {
        Some(problem) => Err(invalid(Setting::RobotId, problem)),
        None => Ok(robot_id),
    }
}

/// Reads a text file, naming it in errors.
fn read_text(path: &str) -> Result<String> {
    Ok(kinecal::source::Source::read(Path::new(path))?.text)
}

/// The tolerances of a tolerance file (none without one).
fn tolerances(path: Option<&str>) -> Result<Tolerances> {
    Ok(match path {
        Some(p) => Tolerances::parse_toml(&read_text(p)?, p)?,
        None => Tolerances::default(),
    })
}

/// The longest horizon of a fleet's crossings, days (100 years): a date beyond it means
/// nothing to maintenance, and the horizon's end is shown as a date.
pub const MAX_HORIZON_DAYS: f64 = 36_500.0;

/// A drift threshold: positive and finite.
fn check_sigma(sigma: f64) -> Result<()> {
    if !(sigma.is_finite() && sigma > 0.0) {
        return Err(invalid(
            Setting::DriftSigma,
            format!("{sigma}: expected a positive, finite number of standard deviations"),
        ));
    }
    Ok(())
}

/// The history at `location` opened for writing, and whether this created its file (a
/// SQLite file that was not there; a server's database is never created).
fn open_to_write(location: Location) -> Result<(Database, Option<Created>)> {
    let created = location.file().and_then(Created::before);
    Ok((Database::open(location)?, created))
}

/// A history file (and the folders above it) a write is about to create, to remove again when
/// the write fails: a refused write leaves no file behind.
struct Created {
    file: std::path::PathBuf,
    /// The folders above the file that were not there, innermost first.
    folders: Vec<std::path::PathBuf>,
}

impl Created {
    /// What opening `file` would create; `None` when it exists.
    fn before(file: &Path) -> Option<Created> {
        if !matches!(file.try_exists(), Ok(false)) {
            return None;
        }
        let folders = file
            .ancestors()
            .skip(1)
            .filter(|d| !d.as_os_str().is_empty())
            .take_while(|d| matches!(d.try_exists(), Ok(false)))
            .map(Path::to_path_buf)
            .collect();
        Some(Created {
            file: file.to_path_buf(),
            folders,
        })
    }

    /// Removes the file, its journal files and the folders created for it (each only if it is
    /// still empty).
    fn remove(&self) {
        for suffix in ["", "-wal", "-shm", "-journal"] {
            let mut name = self.file.clone().into_os_string();
            name.push(suffix);
            let _ = std::fs::remove_file(name);
        }
        for d in &self.folders {
            let _ = std::fs::remove_dir(d);
        }
    }
}

/// Runs `write` into `db`; when it fails and opening `db` created its file, that file is
/// removed again (when nothing is in it: another writer may have written meanwhile), so that
/// a refused write leaves no history behind.
fn write_into<T>(
    db: Database,
    created: Option<Created>,
    write: impl FnOnce(&Database) -> std::result::Result<T, Error>,
) -> Result<(Database, T)> {
    match write(&db) {
        Ok(v) => Ok((db, v)),
        Err(e) => {
            if let Some(c) = created {
                let empty = db.robots().is_ok_and(|r| r.is_empty())
                    && db.events(None).is_ok_and(|e| e.is_empty());
                // Closed before its files go.
                drop(db);
                if empty {
                    c.remove();
                }
            }
            Err(e.into())
        }
    }
}

/// What a job says as it goes, and its outputs.
#[derive(Default)]
struct Said {
    messages: Vec<Message>,
}

impl Said {
    fn note(&mut self, text: impl Into<String>) {
        self.messages.push(Message::Note(text.into()));
    }

    fn caution(&mut self, text: impl Into<String>) {
        self.messages.push(Message::Caution(text.into()));
    }

    fn done(&mut self, document: Document, status: Status) -> Done {
        Done {
            document: kinecal::spec::Document::History(Box::new(document)),
            messages: std::mem::take(&mut self.messages),
            status,
            pending: None,
        }
    }

    /// Opens an existing history to read (never creating one), saying when it fails its
    /// integrity check.
    fn read(&mut self, location: Location) -> Result<Database> {
        let db = Database::open_read_only(location)?;
        if let Some(problem) = db.integrity_problem() {
            self.caution(format!(
                "{}: the database fails its integrity check ({}); showing what can be read",
                db.path(),
                printable(problem)
            ));
        }
        Ok(db)
    }

    /// The readable calibrations of `robot_id` (all robots when `None`); each record that
    /// cannot be read is named.
    fn calibrations(&mut self, db: &Database, robot_id: Option<&str>) -> Result<Vec<Calibration>> {
        let records = db.records(robot_id)?;
        for d in &records.damaged {
            self.caution(format!("{}: {}", db.path(), printable(&d.to_string())));
        }
        Ok(records.calibrations)
    }
}

impl kinecal::spec::Historian for Historian<'_> {
    fn run(&self, job: &Job, env: &mut Env<'_>) -> Result<Done> {
        // The history a job names by default (or by $KINECAL_DB) is an input too: no output
        // replaces it.
        let db = history_of(job);
        if let Some(file) = location(db.as_deref())?.file() {
            let outputs = job.outputs();
            output::check_distinct(
                &outputs.iter().map(|p| p.as_path()).collect::<Vec<_>>(),
                &[file],
            )?;
        }
        let mut said = Said::default();
        let _ = env;
        match job {
            Job::HistoryAdd(s) => add(s, &mut said),
            Job::HistoryList(s) => list(s, &mut said),
            Job::HistoryShow(s) => show(s, &mut said),
            Job::HistoryExport(s) => export(s, &mut said),
            Job::HistoryDrift(s) => drift_job(s, &mut said),
            Job::HistoryPlot(s) => self.plot(s, &mut said),
            Job::HistoryFleet(s) => self.fleet(s, &mut said),
            Job::HistoryEvent(s) => event(s, &mut said),
            Job::HistoryEvents(s) => events(s, &mut said),
            Job::HistoryImport(s) => import(s, &mut said),
            Job::HistoryInit(s) => init(s, &mut said),
            other => Err(kinecal::Error::History(
                format!("`{}` is not a history job", other.kind()).into(),
            )),
        }
    }
}

/// The `db` of a history job.
fn history_of(job: &Job) -> Option<String> {
    match job {
        Job::HistoryAdd(s) => s.db.clone(),
        Job::HistoryList(s) => s.db.clone(),
        Job::HistoryShow(s) => s.db.clone(),
        Job::HistoryExport(s) => s.db.clone(),
        Job::HistoryDrift(s) => s.db.clone(),
        Job::HistoryPlot(s) => s.db.clone(),
        Job::HistoryFleet(s) => s.db.clone(),
        Job::HistoryEvent(s) => s.db.clone(),
        Job::HistoryEvents(s) => s.db.clone(),
        Job::HistoryImport(s) => s.db.clone(),
        Job::HistoryInit(s) => s.db.clone(),
        _ => None,
    }
}

fn add(s: &HistoryAddSpec, said: &mut Said) -> Result<Done> {
    let robot_id = serial_to_write(&s.robot_id)?;
    if s.report.is_empty() {
        return Err(invalid(
            Setting::Report,
            "the calibration report to record is needed",
        ));
    }
    let at = time(s.at.as_deref(), Setting::At)?;
    let text = read_text(&s.report)?;
    let report = CalibrationReport::from_json(&text).map_err(|e| {
        kinecal::Error::input(
            kinecal::Location::file(&s.report),
            format!("not a kinecal calibration report: {e}"),
        )
    })?;
    // Every check of the report before the history is opened: a refused report creates no
    // file.
    if let Some(problem) = crate::record::refusal(&report) {
        return Err(kinecal::Error::input(
            kinecal::Location::file(&s.report),
            format!("{problem}; nothing was written"),
        ));
    }
    let rec = crate::database::prepare(robot_id, at, &report, &s.note)?;
    let (db, created) = open_to_write(location(s.db.as_deref())?)?;
    let (db, added) = write_into(db, created, |db| {
        db.insert_prepared(&rec, AddOptions { force: s.force })
    })?;
    if added.new {
        said.note(format!(
            "recorded calibration {} of robot {}",
            added.id,
            printable(robot_id)
        ));
        // A forced record of another model starts a new segment: say so.
        if s.force {
            let cals = db.calibrations(Some(robot_id)).unwrap_or_default();
            if let Some(m) = crate::robot_model::latest_model_start(&cals)
                .1
                .filter(|m| m.first_id == added.id)
            {
                said.note(format!(
                    "calibration {} changes the robot model of robot {} ({}, against calibration \
                     {}): drift, fleet and plot compare it only with the calibrations after it",
                    added.id,
                    printable(robot_id),
                    printable(&m.difference),
                    m.earlier_id
                ));
            }
        }
    } else {
        said.note(format!(
            "already recorded as calibration {} of robot {} (the same calibration: nothing written)",
            added.id,
            printable(robot_id)
        ));
    }
    Ok(said.done(
        Document::Added(Recorded {
            history: db.path().to_string(),
            robot_id: robot_id.to_string(),
            id: added.id,
            new: added.new,
        }),
        Status::Ok,
    ))
}

fn event(s: &HistoryEventSpec, said: &mut Said) -> Result<Done> {
    let robot_id = serial_to_write(&s.robot_id)?;
    if s.note.trim().is_empty() {
        return Err(invalid(
            Setting::Note,
            "say what was done (\"gearbox J2 replaced\")",
        ));
    }
    let at = time(s.at.as_deref(), Setting::At)?.unwrap_or_else(now);
    let db = Database::open(location(s.db.as_deref())?)?;
    let added = db.add_event(robot_id, at, &s.note)?;
    said.note(format!(
        "{} event {} of robot {} at {}: {}",
        if added.new {
            "recorded"
        } else {
            "already recorded:"
        },
        added.id,
        printable(robot_id),
        format_time(at),
        printable(&s.note)
    ));
    Ok(said.done(
        Document::Event(RecordedEvent {
            history: db.path().to_string(),
            event: Event {
                id: added.id,
                robot_id: robot_id.to_string(),
                at,
                note: s.note.clone(),
            },
            new: added.new,
        }),
        Status::Ok,
    ))
}

fn events(s: &HistoryEventsSpec, said: &mut Said) -> Result<Done> {
    let db = said.read(location(s.db.as_deref())?)?;
    let events = db.events(s.robot_id.as_deref())?;
    Ok(said.done(Document::Events(events), Status::Ok))
}

fn list(s: &HistoryListSpec, said: &mut Said) -> Result<Done> {
    let db = said.read(location(s.db.as_deref())?)?;
    let cals = said.calibrations(&db, s.robot_id.as_deref())?;
    if let (true, Some(r)) = (cals.is_empty(), &s.robot_id) {
        return Err(Error::NoHistory(printable(r).into_owned()).into());
    }
    Ok(said.done(Document::Calibrations(cals), Status::Ok))
}

fn show(s: &HistoryShowSpec, said: &mut Said) -> Result<Done> {
    let neither = || {
        invalid(
            Setting::CalibrationId,
            "give a calibration's id or a robot's serial (its latest calibration)",
        )
    };
    if s.id.is_none() && s.robot_id.is_none() {
        return Err(neither());
    }
    let db = said.read(location(s.db.as_deref())?)?;
    let cal = match (s.id, &s.robot_id) {
        (Some(id), _) => db.calibration(id)?.ok_or_else(|| {
            invalid(
                Setting::CalibrationId,
                format!("no calibration with id {id}"),
            )
        })?,
        (None, Some(r)) => said
            .calibrations(&db, Some(r))?
            .pop()
            .ok_or_else(|| Error::NoHistory(printable(r).into_owned()))?,
        (None, None) => return Err(neither()),
    };
    Ok(said.done(Document::Calibration(Box::new(cal)), Status::Ok))
}

/// A CSV field, quoted when it must be.
fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// The CSV export: one row per calibration and parameter or combination.
fn csv(cals: &[Calibration]) -> String {
    let mut s = String::from(
        "calibration,robot_id,at,method,solution,kind,id,name,unit,value,sigma,estimated,determined\n",
    );
    for c in cals {
        let head = format!(
            "{},{},{},{},{}",
            c.id,
            csv_field(&c.robot_id),
            c.at_text,
            csv_field(&c.method),
            csv_field(&c.solution)
        );
        for p in &c.parameters {
            let _ = writeln!(
                s,
                "{head},parameter,{},{},{},{},{},{},{}",
                csv_field(&p.id),
                csv_field(&p.name),
                csv_field(&p.unit),
                p.value,
                p.sigma.map_or(String::new(), |v| v.to_string()),
                p.estimated,
                p.determined
            );
        }
        for comb in &c.combinations {
            let _ = writeln!(
                s,
                "{head},combination,,{},,{},{},true,true",
                csv_field(&comb.expression),
                comb.value,
                comb.sigma
            );
        }
    }
    s
}

fn export(s: &HistoryExportSpec, said: &mut Said) -> Result<Done> {
    if s.format == HistoryFormat::Dump && s.robot_id.is_some() {
        return Err(invalid(
            Setting::RobotId,
            "a dump is the whole history: leave out the robot",
        ));
    }
    let db = said.read(location(s.db.as_deref())?)?;
    let text = match s.format {
        HistoryFormat::Dump => db.dump()?.to_json(),
        format => {
            let cals = said.calibrations(&db, s.robot_id.as_deref())?;
            // A robot named with nothing recorded: the error `list` gives, not an empty file.
            if let (true, Some(r)) = (cals.is_empty(), &s.robot_id) {
                return Err(Error::NoHistory(printable(r).into_owned()).into());
            }
            if format == HistoryFormat::Json {
                serde_json::to_string_pretty(&cals).expect("calibrations are plain data") + "\n"
            } else {
                csv(&cals)
            }
        }
    };
    let (written, text) = match &s.out {
        Some(p) => {
            output::write_file(Path::new(p), &text)?;
            said.note(format!("wrote {p}"));
            (Some(p.clone()), None)
        }
        None => (None, Some(text)),
    };
    Ok(said.done(
        Document::Export(Exported {
            format: s.format,
            written,
            text,
        }),
        Status::Ok,
    ))
}

/// The current segment of a robot's history ([`segment_of`]: since its latest maintenance
/// event and its latest change of robot model; drift is computed within segments); an error
/// when it has no calibration since its latest event.
fn segment<'a>(all: &'a [Calibration], events: &'a [Event], robot_id: &str) -> Result<Segment<'a>> {
    if all.is_empty() {
        return Err(Error::NoHistory(printable(robot_id).into_owned()).into());
    }
    let seg = segment_of(all, events);
    if let (true, Some(e)) = (seg.calibrations.is_empty(), seg.event) {
        return Err(Error::Input(format!(
            "robot `{}`: no calibration since its maintenance event of {} ({}): drift is \
             computed within the segments between events; calibrate it",
            printable(robot_id),
            e.at_text(),
            printable(&e.note)
        ))
        .into());
    }
    Ok(seg)
}

/// `calibration 3` or `calibrations 1, 2 and 3`.
fn calibration_ids(ids: &[i64]) -> String {
    let ids: Vec<String> = ids.iter().map(i64::to_string).collect();
    match ids.split_last() {
        Some((last, [])) => format!("calibration {last}"),
        Some((last, rest)) => format!("calibrations {} and {last}", rest.join(", ")),
        None => "no calibration".into(),
    }
}

/// The baseline a spec names.
fn baseline(b: &BaselineSpec) -> Result<Baseline> {
    match b {
        BaselineSpec::Id(id) => Ok(Baseline::Id(*id)),
        BaselineSpec::Named(n) => match n.as_str() {
            "first" => Ok(Baseline::First),
            "latest-ok" => Ok(Baseline::LatestOk),
            other => other.parse().map(Baseline::Id).map_err(|_| {
                invalid(
                    Setting::Baseline,
                    format!(
                        "`{}`: expected first, latest-ok or a calibration id",
                        printable(other)
                    ),
                )
            }),
        },
    }
}

fn drift_job(s: &HistoryDriftSpec, said: &mut Said) -> Result<Done> {
    // Settings first: nothing is opened for a job that cannot run.
    let robot_id = serial(&s.robot_id)?;
    check_sigma(s.sigma)?;
    let baseline = baseline(&s.baseline)?;
    let tolerances = tolerances(s.tolerance.as_deref())?;
    let db = said.read(location(s.db.as_deref())?)?;
    let all = said.calibrations(&db, Some(robot_id))?;
    let events = db.events(Some(robot_id))?;
    let seg = segment(&all, &events, robot_id)?;
    let history = seg.calibrations;
    let mut report = drift(
        history,
        &DriftOptions {
            baseline,
            sigma: s.sigma,
            tolerances,
        },
    )?;
    report.since_event = seg.event.cloned();
    if report.since_model_change.is_none() {
        report.since_model_change = seg.model_change.clone();
    }
    let other_model = seg.model_change.as_ref().map_or(0, |m| m.left_out.len());
    let converted = history
        .iter()
        .filter(|c| c.length_unit != report.length_unit || c.angle_unit != report.angle_unit)
        .map(|c| {
            format!(
                "{} ({} and {})",
                c.id,
                printable(&c.length_unit),
                printable(&c.angle_unit)
            )
        })
        .collect();
    let status = if report.flags.is_empty() {
        Status::Ok
    } else {
        Status::Flagged
    };
    Ok(said.done(
        Document::Drift(Box::new(DriftDocument {
            report,
            before_event: all.len() - history.len() - other_model,
            converted,
        })),
        status,
    ))
}

impl Historian<'_> {
    fn pages(&self, path: &str) -> Result<&(dyn Pages + Sync)> {
        self.pages.ok_or_else(|| kinecal::Error::Output {
            path: path.to_string(),
            message: "this program draws no pages or pictures".into(),
        })
    }

    fn plot(&self, s: &HistoryPlotSpec, said: &mut Said) -> Result<Done> {
        let robot_id = serial(&s.robot_id)?;
        let lower = s.out.to_ascii_lowercase();
        let png = if lower.ends_with(".png") {
            true
        } else if lower.ends_with(".svg") {
            false
        } else {
            return Err(invalid(
                Setting::Output,
                format!(
                    "`{}`: the name must end in .svg or .png (the format written)",
                    s.out
                ),
            ));
        };
        let tolerances = tolerances(s.tolerance.as_deref())?;
        let pages = self.pages(&s.out)?;
        let db = said.read(location(s.db.as_deref())?)?;
        let all = said.calibrations(&db, Some(robot_id))?;
        if all.is_empty() {
            return Err(Error::NoHistory(printable(robot_id).into_owned()).into());
        }
        let mut events = db.events(Some(robot_id))?;
        // The whole history of the robot's latest model is drawn, every segment, the events as
        // vertical lines; calibrations of an earlier model (before a rebuild recorded with the
        // force option) are not: their quantities are another robot's.
        let (start, model_change) = crate::robot_model::latest_model_start(&all);
        let history = &all[start..];
        if let Some(m) = &model_change {
            let t0 = history[0].at;
            events.retain(|e| e.at >= t0);
            said.note(format!(
                "not drawn: {}, before calibration {} changed the robot model ({})",
                calibration_ids(&m.left_out),
                m.first_id,
                printable(&m.difference)
            ));
        }
        // The quantities drawn: those the latest segment with calibrations tracks (since the
        // latest event at or before the latest calibration).
        let last_at = history[history.len() - 1].at;
        let until_last: Vec<Event> = events.iter().filter(|e| e.at <= last_at).cloned().collect();
        let seg = segment_of(history, &until_last).calibrations;
        if let Some(e) = events
            .iter()
            .filter(|e| e.at > last_at)
            .max_by_key(|e| (e.at, e.id))
        {
            said.caution(format!(
                "robot {} was serviced after its latest calibration (maintenance event of {}: \
                 {}): calibrate it; drawn: its calibrations up to the event, the event as a line",
                printable(robot_id),
                e.at_text(),
                printable(&e.note)
            ));
        }
        // One calibration plots too: the quantities it tracks.
        let r = crate::drift::drift_or_tracked(
            seg,
            &DriftOptions {
                tolerances,
                ..Default::default()
            },
        )?;
        let matches = |k: &str, key: &str, parameters: &[String]| {
            k == key || (parameters.len() == 1 && k == parameters[0])
        };
        // Say which asked-for quantities match nothing, and why.
        let mut unmatched = Vec::new();
        for k in &s.param {
            if r.quantities
                .iter()
                .any(|q| matches(k, &q.key, &q.parameters))
            {
                continue;
            }
            let why = match r
                .left_out
                .iter()
                .find(|q| matches(k, &q.key, &q.parameters))
            {
                Some(q) => format!("left out: {}", q.reason),
                None => format!(
                    "matches no tracked quantity of robot {} (a determined parameter's name or \
                     id, or a determined combination's expression)",
                    r.robot_id
                ),
            };
            unmatched.push(format!("`{}`: {}", printable(k), printable(&why)));
        }
        let mut series = Vec::new();
        for q in &r.quantities {
            if !s.param.is_empty() && !s.param.iter().any(|k| matches(k, &q.key, &q.parameters)) {
                continue;
            }
            // In the units the quantity is given in: those of the segment's first record.
            series.push((
                q.clone(),
                crate::drift::samples_like(history, &seg[0], &q.key)?,
            ));
        }
        if series.is_empty() {
            return Err(invalid(
                Setting::Quantities,
                format!(
                    "nothing to plot: {}",
                    if unmatched.is_empty() {
                        "no tracked quantity".to_string()
                    } else {
                        unmatched.join("; ")
                    }
                ),
            ));
        }
        for u in &unmatched {
            said.caution(format!("{}: {u}", Setting::Quantities.key()));
        }
        let view = PlotView {
            robot_id,
            series: &series,
            t0: history[0].at,
            events: &events,
        };
        let bytes = pages
            .history_plot(&view, png)
            .map_err(|message| kinecal::Error::Output {
                path: s.out.clone(),
                message,
            })?;
        let mut staged = Staged::new();
        staged.bytes(Path::new(&s.out), &bytes)?;
        staged.commit()?;
        said.note(format!("wrote {} panels to {}", series.len(), s.out));
        Ok(said.done(
            Document::Plot(Plotted {
                written: s.out.clone(),
                quantities: series.iter().map(|(q, _)| q.key.clone()).collect(),
            }),
            Status::Ok,
        ))
    }

    fn fleet(&self, s: &HistoryFleetSpec, said: &mut Said) -> Result<Done> {
        check_sigma(s.sigma)?;
        if !(s.horizon.is_finite() && (0.0..=MAX_HORIZON_DAYS).contains(&s.horizon)) {
            return Err(invalid(
                Setting::Horizon,
                format!(
                    "{}: expected a number of days from 0 to {MAX_HORIZON_DAYS} (100 years)",
                    s.horizon
                ),
            ));
        }
        let tolerances = tolerances(s.tolerance.as_deref())?;
        let now = time(s.now.as_deref(), Setting::Now)?.unwrap_or_else(now);
        let horizon = (s.horizon * 86_400.0).round() as i64;
        // The horizon's end is shown as a date ("due ... by 2027-06-13").
        if crate::timefmt::time_problem(now + horizon).is_some() {
            return Err(invalid(
                Setting::Horizon,
                format!(
                    "{} days after {} is beyond the year 9999: give a shorter horizon or an \
                     earlier now",
                    s.horizon,
                    format_time(now)
                ),
            ));
        }
        let pages = match &s.html {
            Some(p) => Some(self.pages(p)?),
            None => None,
        };
        let db = said.read(location(s.db.as_deref())?)?;
        let calibrations = said.calibrations(&db, None)?;
        let events = db.events(None)?;
        let opts = FleetOptions {
            drift: DriftOptions {
                sigma: s.sigma,
                tolerances,
                ..Default::default()
            },
            now,
            horizon,
        };
        let document = FleetDocument {
            history: db.path().to_string(),
            now: format_time(now),
            horizon_days: s.horizon,
            sigma: s.sigma,
            robots: fleet(&calibrations, &events, &opts)?,
        };
        let mut staged = Staged::new();
        if let Some(p) = &s.json {
            let text = serde_json::to_string_pretty(&document).expect("plain data") + "\n";
            staged.text(Path::new(p), &text)?;
        }
        if let (Some(p), Some(pages)) = (&s.html, pages) {
            let view = FleetView {
                fleet: &document,
                calibrations: &calibrations,
                events: &events,
            };
            let page = pages
                .fleet_page(&view)
                .map_err(|message| kinecal::Error::Output {
                    path: p.clone(),
                    message,
                })?;
            staged.text(Path::new(p), &page)?;
        }
        staged.commit()?;
        for p in s.json.iter().chain(&s.html) {
            said.note(format!("wrote {p}"));
        }
        let status = if document.attention() {
            Status::Flagged
        } else {
            Status::Ok
        };
        Ok(said.done(Document::Fleet(Box::new(document)), status))
    }
}

fn import(s: &HistoryImportSpec, said: &mut Said) -> Result<Done> {
    if s.dump.is_empty() {
        return Err(invalid(Setting::Dump, "the dump to import is needed"));
    }
    let text = read_text(&s.dump)?;
    let dump = Dump::from_json(&text, &s.dump)?;
    // A damaged record: the file it is in. Checked before the history is opened: a refused
    // dump creates no file.
    let in_dump = |e: Error| match e {
        Error::Input(m) => Error::Input(format!("{}: {m}", s.dump)),
        e => e,
    };
    crate::check_dump(&dump).map_err(in_dump)?;
    let (db, created) = open_to_write(location(s.db.as_deref())?)?;
    let (db, summary) = write_into(db, created, |db| db.import_checked(&dump).map_err(in_dump))?;
    said.note(format!(
        "imported into {}: {} calibrations written, {} already there; {} events written, {} \
         already there",
        db.path(),
        summary.added,
        summary.present,
        summary.events_added,
        summary.events_present
    ));
    if !summary.renumbered.is_empty() {
        let pairs: Vec<String> = summary
            .renumbered
            .iter()
            .map(|(a, b)| format!("{a} -> {b}"))
            .collect();
        said.note(format!(
            "ids taken by other records, so renumbered: {}",
            pairs.join(", ")
        ));
    }
    Ok(said.done(
        Document::Import(Imported {
            history: db.path().to_string(),
            summary,
        }),
        Status::Ok,
    ))
}

fn init(s: &HistoryInitSpec, said: &mut Said) -> Result<Done> {
    let db = Database::open(location(s.db.as_deref())?)?;
    // The whole history checked, on demand (a write checks only the pages it reads).
    if let Some(problem) = db.check()? {
        return Err(Error::Corrupt {
            path: db.path().to_string(),
            problem,
        }
        .into());
    }
    said.note(format!(
        "{}: a kinecal history ({}), schema version {}, checked whole: sound",
        db.path(),
        db.backend().name(),
        db.store().schema_version()
    ));
    Ok(said.done(
        Document::Init(Initialized {
            history: db.path().to_string(),
            backend: db.backend().name().to_string(),
            schema_version: db.store().schema_version(),
        }),
        Status::Ok,
    ))
}
