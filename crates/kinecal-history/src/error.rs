//! The errors of the history: what went wrong, naming the database (a path, or a URL without
//! its password) and what was or was not written.

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
    /// The database fails an integrity check (of the whole file, or of a page a write read):
    /// nothing is written to it.
    #[error(
        "{path}: the database fails its integrity check ({problem}); nothing was written and the \
         file was not modified: restore it from a backup, or recover what can be read with \
         `sqlite3 {path} .recover`"
    )]
    Corrupt {
        /// The file.
        path: String,
        /// The first problems the check reported.
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
    /// A PostgreSQL location given to a kinecal built without the `postgres` feature.
    #[error(
        "{location}: this kinecal was built without PostgreSQL: rebuild with the `postgres` feature"
    )]
    NoPostgres {
        /// The server's URL, without its password.
        location: String,
    },
}

/// Result with this crate's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;
