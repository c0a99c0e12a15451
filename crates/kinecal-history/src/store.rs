//! The store trait: what every back end does, on the records of [`crate::model`].
//!
//! A back end keeps [`StoredRecord`]s and [`Event`]s and reads them back as [`Records`] (the
//! SQLite store in `sqlite.rs`, the PostgreSQL store in `postgres.rs`); what is the same on every
//! back end (validation, keys, segments, dumps) is done once, by
//! [`Database`](crate::Database), over this trait.

use crate::error::{Error, Result};
use crate::model::{Added, Calibration, Event, Records, StoredRecord};
use crate::text::printable;

/// What an import wrote: for each record, then each event, of the dump, its id and whether it
/// was new.
pub(crate) type Imported = (Vec<Added>, Vec<Added>);

/// An error met while writing a record of a dump, naming the record.
pub(crate) fn in_record(e: Error, rec: &StoredRecord) -> Error {
    match e {
        Error::Database { path, message } => Error::Database {
            path,
            message: format!(
                "calibration {} (robot {}): {message}",
                rec.id,
                printable(&rec.robot_id)
            ),
        },
        e => e,
    }
}

/// The schema version this build writes, the same on every back end: each store's migrations
/// bring its schema from version `i` to `i + 1`. A store at a newer version is refused with the
/// version it needs.
pub const SCHEMA_VERSION: i64 = 2;

/// The kind of store.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
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
#[non_exhaustive]
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

/// How a store is opened.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Access {
    /// For reading only: nothing is created or written (a missing store is an error).
    ReadOnly,
    /// For writing: the store is created if needed, and its schema migrated.
    ReadWrite,
}

/// Keeps [`Store`] to this crate's back ends, so that it can grow without breaking anyone.
pub(crate) mod sealed {
    /// Implemented by this crate's stores only.
    pub trait Sealed {}
}

/// A history store: what each back end implements (this crate's back ends only; a
/// [`Database`](crate::Database) gives access to its store). Every write is one transaction:
/// a killed writer leaves the store as it was. Reads see one consistent snapshot.
pub trait Store: Send + sealed::Sealed {
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
    /// Writes the records, then the events, of a dump ([`Write::Import`]) in one transaction:
    /// all or nothing.
    fn import(
        &self,
        records: &[StoredRecord],
        events: &[Event],
    ) -> Result<(Vec<Added>, Vec<Added>)>;
    /// Checks the whole store on demand: `None` when it is sound, else the first problems
    /// found (a SQLite file: `PRAGMA integrity_check`; a server keeps its own checks).
    fn check(&self) -> Result<Option<String>> {
        Ok(None)
    }
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
