//! One store, two back ends: the [`Store`] trait, and [`Database`], which opens the back end a
//! location names (a file path: SQLite; a `postgres://` URL: PostgreSQL) and adds what is the
//! same on both (validation, keys, segments).

use std::path::Path;

use kinecal::report::CalibrationReport;

use crate::record::{new_record, Added, Dump, Event, ImportSummary, StoredRecord, DUMP_FORMAT};
use crate::store::{AddOptions, Calibration, Records, SqliteStore};
use crate::text::printable;
use crate::timefmt::now;
use crate::{Error, Result};

/// The kind of store.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Backend {
    /// A SQLite file.
    Sqlite,
    /// A PostgreSQL server.
    Postgres,
}

impl Backend {
    /// `sqlite` or `postgres`.
    pub fn name(self) -> &'static str {
        match self {
            Backend::Sqlite => "sqlite",
            Backend::Postgres => "postgres",
        }
    }
}

/// How a record is written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Write {
    /// A new calibration: a record with the same idempotency key already there is not written
    /// again (its id is returned); the robot model must match the robot's earlier records
    /// unless `force`.
    New {
        /// Record even when the robot model differs from the robot's earlier records.
        force: bool,
    },
    /// A record of a dump, verbatim: skipped when already there (same key, or same id and
    /// contents); its id kept when free.
    Import,
}

/// A history store: what each back end implements. Every write is one transaction: a killed
/// writer leaves the store as it was. Reads see one consistent snapshot.
pub trait Store: Send {
    /// Where the store is, as shown to the user (a path; a URL without its password).
    fn location(&self) -> &str;
    /// Which back end.
    fn backend(&self) -> Backend;
    /// The schema version of the store (0: nothing created yet).
    fn schema_version(&self) -> i64;
    /// What an integrity check found wrong when the store was opened for reading, if anything.
    fn integrity_problem(&self) -> Option<&str> {
        None
    }
    /// Writes one calibration record (one transaction).
    fn insert(&self, record: &StoredRecord, write: Write) -> Result<Added>;
    /// The robots with a history, with their number of calibrations, by serial.
    fn robots(&self) -> Result<Vec<(String, i64)>>;
    /// Every calibration of `robot_id` (all when `None`), by robot then oldest first; records
    /// with a damaged field apart.
    fn records(&self, robot_id: Option<&str>) -> Result<Records>;
    /// One calibration by id.
    fn calibration(&self, id: i64) -> Result<Option<Calibration>>;
    /// Writes a maintenance event (one transaction); the same robot, time and note again is
    /// not written twice.
    fn insert_event(&self, event: &Event, write: Write) -> Result<Added>;
    /// The events of `robot_id` (all when `None`), oldest first.
    fn events(&self, robot_id: Option<&str>) -> Result<Vec<Event>>;
    /// Every record with every stored field, by id (for a dump).
    fn stored_records(&self) -> Result<Vec<StoredRecord>>;
}

/// Whether `location` names a PostgreSQL server (`postgres://` or `postgresql://`).
pub fn is_postgres_url(location: &str) -> bool {
    let l = location.trim_start().to_ascii_lowercase();
    l.starts_with("postgres://") || l.starts_with("postgresql://")
}

/// An open history, on either back end.
pub struct Database {
    store: Box<dyn Store>,
}

impl Database {
    /// A history kept by `store`.
    pub fn from_store(store: Box<dyn Store>) -> Database {
        Database { store }
    }

    /// Opens (creating if needed, and migrating) the SQLite history at `path` for writing. An
    /// existing file is first opened read-only and inspected: a file that is not a kinecal
    /// history (another schema, a negative or newer schema version, not SQLite at all) or that
    /// fails `PRAGMA quick_check` is refused, and nothing is written to it.
    pub fn open(path: &Path) -> Result<Database> {
        Ok(Database::from_store(Box::new(SqliteStore::open(path)?)))
    }

    /// Opens an existing SQLite history for reading only: never creates a file, never writes,
    /// and works on a read-only file in a read-only folder.
    pub fn open_read_only(path: &Path) -> Result<Database> {
        Ok(Database::from_store(Box::new(SqliteStore::open_read_only(
            path,
        )?)))
    }

    /// Opens the history at `location` for writing: a `postgres://user@host:port/dbname` URL
    /// (the server's schema created or migrated; see [`crate::pg`]) or a SQLite file path (as
    /// [`Database::open`]).
    pub fn connect(location: &str) -> Result<Database> {
        if is_postgres_url(location) {
            Ok(Database::from_store(Box::new(crate::pg::PgStore::connect(
                location, false,
            )?)))
        } else {
            Database::open(Path::new(location))
        }
    }

    /// Opens the history at `location` for reading only: nothing is created or written (on
    /// PostgreSQL, the session is read-only).
    pub fn connect_read_only(location: &str) -> Result<Database> {
        if is_postgres_url(location) {
            Ok(Database::from_store(Box::new(crate::pg::PgStore::connect(
                location, true,
            )?)))
        } else {
            Database::open_read_only(Path::new(location))
        }
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
        let rec = new_record(robot_id, at, at.unwrap_or_else(now), report, note)?;
        self.store.insert(
            &rec,
            Write::New {
                force: options.force,
            },
        )
    }

    /// Records a maintenance event of `robot_id` at `at` (Unix seconds): drift is computed
    /// within the segments between events. The same event again is not written twice.
    pub fn add_event(&self, robot_id: &str, at: i64, note: &str) -> Result<Added> {
        if robot_id.trim().is_empty() {
            return Err(Error::Input(
                "the robot id (serial) must not be empty".into(),
            ));
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

    /// Writes every record and event of `dump` that is not already here, each in its own
    /// transaction, keeping ids where they are free: importing into an empty store gives the
    /// same history, ids included; importing twice adds nothing.
    pub fn import(&self, dump: &Dump) -> Result<ImportSummary> {
        let mut s = ImportSummary::default();
        for r in &dump.calibrations {
            if r.robot_id.trim().is_empty() {
                return Err(Error::Input(format!(
                    "calibration {} of the dump has no robot serial",
                    r.id
                )));
            }
            let a = self.store.insert(r, Write::Import).map_err(|e| match e {
                Error::Database { path, message } => Error::Database {
                    path,
                    message: format!(
                        "calibration {} (robot {}): {message}",
                        r.id,
                        printable(&r.robot_id)
                    ),
                },
                e => e,
            })?;
            if !a.new {
                s.present += 1;
                continue;
            }
            s.added += 1;
            if a.id != r.id {
                s.renumbered.push((r.id, a.id));
            }
        }
        for e in &dump.events {
            let a = self.store.insert_event(e, Write::Import)?;
            if a.new {
                s.events_added += 1;
            } else {
                s.events_present += 1;
            }
        }
        Ok(s)
    }
}
