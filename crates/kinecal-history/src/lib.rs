//! # kinecal-history: every calibration of every robot, and drift of what the data determines
//!
//! The thesis's purpose (sections 1.1-1.3, 5.3) is predictive maintenance: calibrate a robot at
//! regular intervals, keep the optimal parameters, and flag the physical quantities that change
//! more than expected. The trap it documents (Table 4.8) is that redundant parameters wander
//! from run to run with no physical change; so this crate tracks only *determined* quantities:
//! individually determined parameters and the combinations of identically redundant groups.
//!
//! One store, two back ends behind the [`Store`] trait, chosen by the location
//! ([`Database::connect`]): a SQLite file (bundled, nothing to install; the default, for one
//! engineer and one cell) or a PostgreSQL server (`postgres://...`, for a fleet: many writers on
//! many machines, roles, backups; see [`pg`]). On both: a versioned schema migrated on open (a
//! newer one refused with the version it needs), every write in one transaction, an
//! idempotency key per calibration so that a retried write never records it twice
//! ([`idempotency_key`]), maintenance events ([`Event`]) that split a robot's history into
//! segments, and a lossless [`Dump`] that moves a history between back ends. SQLite uses the
//! WAL journal and a busy timeout, so that concurrent writers wait for each other instead of
//! failing.
//!
//! Nothing is written to a file until it is known to be a kinecal history: an existing file is
//! first opened read-only and inspected (schema version, tables and columns, `PRAGMA
//! quick_check`); a database from a newer kinecal, a file that is not a kinecal database, and
//! one that fails its integrity check are refused and never written to. Every write runs the
//! integrity check again inside its transaction. Readers ([`Database::open_read_only`]) never
//! create a file and work on read-only files and folders; a record with a damaged field is
//! reported by id ([`Records::damaged`]) while the others are served.
//!
//! A history is one robot model: a record whose model (joints, joint kinds, parameter names)
//! differs from the robot's earlier records is refused unless forced ([`AddOptions`]). Its unit
//! system may change: [`drift()`] converts every value to the units of the robot's first record.

mod backend;
pub mod drift;
pub mod fleet;
pub mod pg;
mod record;
mod store;
mod text;
mod timefmt;
mod units;

pub use backend::{is_postgres_url, Backend, Database, Store, Write};
pub use drift::{
    all_samples, drift, samples, Baseline, DriftOptions, DriftReport, LeftOut, Quantity, Sample,
    Tolerances, UnusedTolerance,
};
pub use fleet::{current_segment, fleet, FleetOptions, RobotState, Trend, Verdict};
pub use kinecal::source::fingerprint;
pub use record::{
    idempotency_key, Added, Dump, Event, ImportSummary, StoredCombination, StoredParameter,
    StoredRecord, DUMP_FORMAT,
};
pub use store::{
    default_db_path, AddOptions, Calibration, Combination, DamagedRecord, Parameter, Records,
    RmsError, SqliteStore, SCHEMA_VERSION,
};
pub use text::printable;
pub use timefmt::{format_time, parse_time};

/// Errors of the history store.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// The database could not be opened, read or written.
    #[error("{path}: {message}")]
    Database {
        /// The database file, or the server's URL without its password.
        path: String,
        /// What went wrong.
        message: String,
    },
    /// A read found no database at the path (reads never create one).
    #[error("{path}: no such history database (nothing was created)")]
    NoDatabase {
        /// The path given.
        path: String,
    },
    /// The database was written by a newer kinecal.
    #[error(
        "{path}: the database has schema version {found}, newer than this kinecal understands ({supported}); \
         upgrade kinecal (the file was not modified)"
    )]
    NewerSchema {
        /// The database file.
        path: String,
        /// Its schema version.
        found: i64,
        /// The newest this build knows.
        supported: i64,
    },
    /// The file is not a kinecal history (another application's database, or no database).
    #[error("{path}: not a kinecal history database ({reason}); the file was not modified")]
    Foreign {
        /// The file.
        path: String,
        /// What gave it away.
        reason: String,
    },
    /// The database fails `PRAGMA quick_check`: nothing is written to it.
    #[error(
        "{path}: the database fails its integrity check ({problem}); nothing was written and the \
         file was not modified: restore it from a backup, or recover what can be read with \
         `sqlite3 {path} .recover`"
    )]
    Corrupt {
        /// The file.
        path: String,
        /// The first problems `quick_check` reported.
        problem: String,
    },
    /// A record could not be read (a damaged field).
    #[error("{path}: calibration {id} cannot be read: {problem}")]
    DamagedRecord {
        /// The database file.
        path: String,
        /// The record's id.
        id: i64,
        /// Which field is damaged, and how.
        problem: String,
    },
    /// A calibration of another robot model than the robot's earlier records.
    #[error(
        "robot `{robot_id}`: this calibration is of another robot model than its earlier ones \
         ({difference}; compared with calibration {earlier_id}); not recorded: a history is one \
         robot model (use another serial; if the robot really was rebuilt, record it with the force option)"
    )]
    ModelMismatch {
        /// The robot (escaped for printing).
        robot_id: String,
        /// The most recent earlier calibration compared with.
        earlier_id: i64,
        /// The differences, in words.
        difference: String,
    },
    /// The drift threshold is not a positive, finite number.
    #[error(
        "the drift threshold must be a positive, finite number of standard deviations, not {value}"
    )]
    InvalidSigma {
        /// The value given.
        value: f64,
    },
    /// A tolerance file that cannot be used.
    #[error("{file}: {message}")]
    Tolerance {
        /// The file.
        file: String,
        /// What is wrong (naming the key).
        message: String,
    },
    /// Bad input (a report, a time).
    #[error("{0}")]
    Input(String),
    /// Nothing recorded for a robot.
    #[error("no calibration recorded for robot `{0}`")]
    NoHistory(String),
}

/// Result with this crate's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;
