//! # kinecal-history: every calibration of every robot, and drift of what the data determines
//!
//! The thesis's purpose (sections 1.1-1.3, 5.3) is predictive maintenance: calibrate a robot at
//! regular intervals, keep the optimal parameters, and flag the physical quantities that change
//! more than expected. The trap it documents (Table 4.8) is that redundant parameters wander
//! from run to run with no physical change; so this crate tracks only *determined* quantities:
//! individually determined parameters and the combinations of identically redundant groups.
//!
//! Storage is SQLite (bundled, nothing to install): a versioned schema migrated on open, WAL
//! journal, every write in one transaction, a busy timeout so that concurrent writers wait for
//! each other instead of failing. A database from a newer kinecal, or a file that is not a
//! kinecal database, is refused and never written to.

pub mod drift;
mod store;
mod timefmt;

pub use drift::{drift, Baseline, DriftOptions, DriftReport, Quantity, Tolerances};
pub use kinecal::source::fingerprint;
pub use store::{default_db_path, Calibration, Combination, Database, Parameter, SCHEMA_VERSION};
pub use timefmt::{format_time, parse_time};

/// Errors of the history store.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// The database could not be opened, read or written.
    #[error("{path}: {message}")]
    Database {
        /// The database file.
        path: String,
        /// What went wrong.
        message: String,
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
    /// Bad input (a report, a time, a tolerance file).
    #[error("{0}")]
    Input(String),
    /// Nothing recorded for a robot.
    #[error("no calibration recorded for robot `{0}`")]
    NoHistory(String),
}

/// Result with this crate's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;
