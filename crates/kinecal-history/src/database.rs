//! The handle front ends use: [`Database`] opens the store a [`Location`] names (a SQLite file,
//! or a PostgreSQL server with the `postgres` feature) and does, once for every back end, what
//! is the same on all of them: checking what is recorded, keying it, dumps and imports.

use kinecal::report::CalibrationReport;

use crate::error::{Error, Result};
#[cfg(not(feature = "postgres"))]
use crate::location::redact;
use crate::location::Location;
use crate::model::{
    AddOptions, Added, Calibration, Dump, Event, ImportSummary, Records, StoredRecord, DUMP_FORMAT,
};
#[cfg(feature = "postgres")]
use crate::postgres::PgStore;
use crate::record::{check_rows, new_record, serial_problem};
use crate::sqlite::SqliteStore;
use crate::store::{Access, Backend, Store, Write};
use crate::text::printable;
use crate::timefmt::{now, time_problem};

/// The PostgreSQL store at `url`.
#[cfg(feature = "postgres")]
fn open_server(url: &str, access: Access) -> Result<Box<dyn Store>> {
    Ok(Box::new(PgStore::open(url, access)?))
}

/// A build without PostgreSQL: a server location is refused, naming the feature.
#[cfg(not(feature = "postgres"))]
fn open_server(url: &str, _access: Access) -> Result<Box<dyn Store>> {
    Err(Error::NoPostgres {
        location: redact(url),
    })
}

/// An open history, on either back end: what front ends use.
pub struct Database {
    store: Box<dyn Store>,
}

impl Database {
    /// Opens the history at `location` for writing, creating it if needed and migrating its
    /// schema: a SQLite file path, or a `postgres://USER@HOST:PORT/DBNAME` URL (see
    /// [`Location`]).
    ///
    /// An existing SQLite file is first opened read-only and inspected: a file that is not a
    /// kinecal history (another schema, a negative or newer schema version, not SQLite at all),
    /// or a small one (up to 4 MiB) that fails `PRAGMA quick_check`, is refused, and nothing is
    /// written to it; a larger file is checked page by page as a write reads it (see
    /// [`Database::check`] for the whole file). On a
    /// server, the schema `kinecal` is created or migrated (which takes the database owner).
    /// A kinecal built without the `postgres` feature refuses a URL ([`Error::NoPostgres`]).
    pub fn open(location: impl Into<Location>) -> Result<Database> {
        Database::open_as(location.into(), Access::ReadWrite)
    }

    /// Opens the existing history at `location` for reading only (see [`Database::open`] for
    /// the locations): nothing is created or written, and a missing history is an error
    /// ([`Error::NoDatabase`]). A SQLite file may be read-only, in a read-only folder; on a
    /// server, the session is read-only.
    pub fn open_read_only(location: impl Into<Location>) -> Result<Database> {
        Database::open_as(location.into(), Access::ReadOnly)
    }

    /// The one place where a location becomes a store.
    fn open_as(location: Location, access: Access) -> Result<Database> {
        let store: Box<dyn Store> = match location {
            Location::File(path) => Box::new(SqliteStore::open(&path, access)?),
            Location::Server(url) => open_server(&url, access)?,
        };
        Ok(Database { store })
    }

    /// The store.
    pub fn store(&self) -> &dyn Store {
        self.store.as_ref()
    }

    /// The location, as shown (a URL without its password).
    pub fn path(&self) -> &str {
        self.store.location()
    }

    /// The back end.
    pub fn backend(&self) -> Backend {
        self.store.backend()
    }

    /// When opened for reading: what the integrity check reported, if the store is not sound.
    pub fn integrity_problem(&self) -> Option<&str> {
        self.store.integrity_problem()
    }

    /// Records a calibration report for robot `robot_id` at `at` (Unix seconds; now if `None`);
    /// refuses a report of another robot model than the robot's earlier records (see
    /// [`Database::add_with`]).
    pub fn add(
        &self,
        robot_id: &str,
        at: Option<i64>,
        report: &CalibrationReport,
        note: &str,
    ) -> Result<i64> {
        self.add_with(robot_id, at, report, note, AddOptions::default())
    }

    /// Records a calibration report for robot `robot_id` at `at` (Unix seconds; now if `None`)
    /// and returns its id. The model and data fingerprints are the report's (SHA-256 of the
    /// robot and measurement files, see [`crate::fingerprint`]), empty when it has none.
    ///
    /// The same calibration recorded again (same [`crate::idempotency_key`]) is not written
    /// twice: the earlier record's id is returned ([`Database::record`] says which happened).
    /// In the write transaction, before anything is written, the report's robot model (joint
    /// count, joint kinds, parameter names) must be the model of one of the robot's earlier
    /// records ([`Error::ModelMismatch`] otherwise, unless `options.force`). Its units may
    /// differ.
    pub fn add_with(
        &self,
        robot_id: &str,
        at: Option<i64>,
        report: &CalibrationReport,
        note: &str,
        options: AddOptions,
    ) -> Result<i64> {
        Ok(self.record(robot_id, at, report, note, options)?.id)
    }

    /// As [`Database::add_with`], saying whether the record is new or was already there.
    pub fn record(
        &self,
        robot_id: &str,
        at: Option<i64>,
        report: &CalibrationReport,
        note: &str,
        options: AddOptions,
    ) -> Result<Added> {
        let rec = prepare(robot_id, at, report, note)?;
        self.insert_prepared(&rec, options)
    }

    /// Writes a record [`prepare`] made.
    pub(crate) fn insert_prepared(&self, rec: &StoredRecord, options: AddOptions) -> Result<Added> {
        self.store.insert(
            rec,
            Write::New {
                force: options.force,
            },
        )
    }

    /// Records a maintenance event of `robot_id` at `at` (Unix seconds): drift is computed
    /// within the segments between events. The same event again is not written twice.
    pub fn add_event(&self, robot_id: &str, at: i64, note: &str) -> Result<Added> {
        crate::record::bounded_texts(robot_id, note)?;
        if let Some(problem) = time_problem(at) {
            return Err(Error::Input(format!("the event's time: {problem}")));
        }
        if note.trim().is_empty() {
            return Err(Error::Input(
                "an event needs a note saying what was done (e.g. \"gearbox J2 replaced\")".into(),
            ));
        }
        self.store.insert_event(
            &Event {
                id: 0,
                robot_id: robot_id.to_string(),
                at,
                note: note.to_string(),
            },
            Write::New { force: false },
        )
    }

    /// The maintenance events of `robot_id` (all when `None`), oldest first.
    pub fn events(&self, robot_id: Option<&str>) -> Result<Vec<Event>> {
        self.store.events(robot_id)
    }

    /// The robots with a history, with their number of calibrations.
    pub fn robots(&self) -> Result<Vec<(String, i64)>> {
        self.store.robots()
    }

    /// Every calibration of `robot_id` (all robots when `None`), by robot then oldest first;
    /// the records with a damaged field are listed apart, by id, and the others served.
    pub fn records(&self, robot_id: Option<&str>) -> Result<Records> {
        self.store.records(robot_id)
    }

    /// Every calibration of `robot_id` (all robots when `None`), oldest first; an error
    /// ([`Error::DamagedRecord`]) when one cannot be read ([`Database::records`] serves the
    /// others).
    pub fn calibrations(&self, robot_id: Option<&str>) -> Result<Vec<Calibration>> {
        let r = self.records(robot_id)?;
        match r.damaged.into_iter().next() {
            Some(d) => Err(Error::DamagedRecord {
                path: self.path().to_string(),
                id: d.id,
                problem: d.problem,
            }),
            None => Ok(r.calibrations),
        }
    }

    /// One calibration by id ([`Error::DamagedRecord`] when it cannot be read).
    pub fn calibration(&self, id: i64) -> Result<Option<Calibration>> {
        self.store.calibration(id)
    }

    /// The whole history, every stored field (see [`Dump`]).
    pub fn dump(&self) -> Result<Dump> {
        Ok(Dump {
            format: DUMP_FORMAT.to_string(),
            version: 1,
            calibrations: self.store.stored_records()?,
            events: self.store.events(None)?,
        })
    }

    /// Checks the whole history on demand: `None` when it is sound, else the first problems
    /// found. A SQLite file is checked whole (`PRAGMA integrity_check`: every page, every index
    /// against its table), which a write does not do (it checks the pages it reads); a server
    /// keeps its own checks. Every record is read back as well: a record with a damaged field
    /// is named.
    pub fn check(&self) -> Result<Option<String>> {
        let mut problems = Vec::new();
        if let Some(p) = self.store.check()? {
            problems.push(p);
        }
        if problems.is_empty() {
            for d in self.store.records(None)?.damaged.iter().take(5) {
                problems.push(format!("calibration {}: {}", d.id, d.problem));
            }
        }
        Ok((!problems.is_empty()).then(|| problems.join("; ")))
    }

    /// Writes every record and event of `dump` that is not already here, in one transaction
    /// (all or nothing), keeping ids where they are free: importing into an empty store gives
    /// the same history, ids included; importing twice adds nothing. On PostgreSQL the id
    /// sequences move past the imported ids, so that the next record and event get new ones.
    ///
    /// Every record and event is checked first ([`check_dump`]), and a damaged dump is
    /// refused before anything is written.
    pub fn import(&self, dump: &Dump) -> Result<ImportSummary> {
        check_dump(dump)?;
        self.import_checked(dump)
    }

    /// [`Database::import`] of a dump [`check_dump`] accepted.
    pub(crate) fn import_checked(&self, dump: &Dump) -> Result<ImportSummary> {
        let (records, events) = self.store.import(&dump.calibrations, &dump.events)?;
        let mut s = ImportSummary::default();
        for (r, a) in dump.calibrations.iter().zip(records) {
            if !a.new {
                s.present += 1;
                continue;
            }
            s.added += 1;
            if a.id != r.id {
                s.renumbered.push((r.id, a.id));
            }
        }
        for a in events {
            if a.new {
                s.events_added += 1;
            } else {
                s.events_present += 1;
            }
        }
        Ok(s)
    }
}

/// The record of a calibration report, checked as [`Database::record`] checks it (nothing is
/// opened: a front end checks a report before it opens, or creates, a history).
pub(crate) fn prepare(
    robot_id: &str,
    at: Option<i64>,
    report: &CalibrationReport,
    note: &str,
) -> Result<StoredRecord> {
    if let Some(problem) = at.and_then(time_problem) {
        return Err(Error::Input(format!("the calibration's time: {problem}")));
    }
    let rec = new_record(robot_id, at, at.unwrap_or_else(now), report, note)?;
    check_rows(&rec, false).map_err(|problem| {
        Error::Input(format!(
            "the report of robot {}: {problem}; not recorded",
            printable(robot_id)
        ))
    })?;
    Ok(rec)
}

/// Checks every record and event of `dump` as a write would check it, before anything is
/// written: a damaged dump is refused ([`Error::Input`], naming the record or event by its
/// place in the dump, its id and robot, the field, its value and what was expected; nothing
/// was imported). A calibration is refused when its robot serial is one `history add` refuses
/// (empty, with white space at its start or end, longer than 128 characters), its time is
/// outside years 0000-9999 (it could not be shown as a date), its length or angle unit is
/// not a kinecal unit, a parameter's unit is not the record's unit of its quantity or not its
/// report's, a value is not finite, a sigma is not positive and finite, it has no parameters,
/// a parameter or combination twice, or parameter rows that are not its report's; an event,
/// when its serial or time is refused, or it has no note.
pub fn check_dump(dump: &Dump) -> Result<()> {
    // What a write refuses in a record's or event's robot serial and time.
    let identity_problem = |robot_id: &str, at: i64| {
        serial_problem(robot_id)
            .map(|p| format!("its robot_id: {p}"))
            .or_else(|| time_problem(at).map(|p| format!("its at: {p}")))
    };
    let refused = |what: String, problem: String| {
        Error::Input(format!("{what}: {problem}; nothing was imported"))
    };
    for (k, r) in dump.calibrations.iter().enumerate() {
        let which = || {
            format!(
                "calibration {} of the dump (the {} in its list, robot {})",
                r.id,
                ordinal(k + 1),
                shown_serial(&r.robot_id)
            )
        };
        if let Some(problem) = identity_problem(&r.robot_id, r.at) {
            return Err(refused(which(), problem));
        }
        check_rows(r, true).map_err(|problem| refused(which(), problem))?;
    }
    for (k, e) in dump.events.iter().enumerate() {
        let which = || {
            format!(
                "event {} of the dump (the {} in its list of events, robot {})",
                e.id,
                ordinal(k + 1),
                shown_serial(&e.robot_id)
            )
        };
        if let Some(problem) = identity_problem(&e.robot_id, e.at) {
            return Err(refused(which(), problem));
        }
        if e.note.trim().is_empty() {
            return Err(refused(
                which(),
                "its note is empty; expected what was done (e.g. \"gearbox J2 replaced\")".into(),
            ));
        }
    }
    Ok(())
}

/// A serial for a message: printable, and cut after 40 characters when longer.
fn shown_serial(robot_id: &str) -> String {
    let n = robot_id.chars().count();
    if n > 40 {
        format!(
            "{}... ({n} characters)",
            printable(&robot_id.chars().take(40).collect::<String>())
        )
    } else {
        printable(robot_id).into_owned()
    }
}

/// `1st`, `2nd`, `3rd`, `4th`, ..., `11th`, `21st`, ...
fn ordinal(n: usize) -> String {
    let suffix = match (n % 10, n % 100) {
        (_, 11..=13) => "th",
        (1, _) => "st",
        (2, _) => "nd",
        (3, _) => "rd",
        _ => "th",
    };
    format!("{n}{suffix}")
}
