//! The SQLite store: one file, bundled SQLite (nothing to install), the embedded default.
//!
//! Nothing is written to a file until it is known to be a kinecal history: an existing file is
//! first opened read-only and inspected (schema version, tables and columns); a file from a
//! newer kinecal and one that is not a kinecal database are refused and never written to.
//!
//! Integrity costs what a write costs, not what the file holds: a file of up to
//! [`WHOLE_CHECK_BYTES`] is checked whole (`PRAGMA quick_check`, a few milliseconds) when opened
//! for writing, and refused when it fails; a larger one is not read whole for each write (at
//! 20,000 records, 390 MB, that took 0.3 s of CPU per check, twice per `history add`). Instead,
//! every page a write reads is checked as SQLite reads it (`PRAGMA cell_size_check`), and a
//! write that meets a damaged page is rolled back and refused ([`Error::Corrupt`]).
//! [`SqliteStore::check`] checks the whole file on demand (`PRAGMA integrity_check`; `kinecal
//! history init` runs it), and a reader runs `quick_check` when it opens the file (a reader
//! reads the records anyway). The file uses the WAL journal and a busy timeout, so that
//! concurrent writers wait for each other instead of failing. A reader never creates a file, and
//! works on read-only files and folders.

use std::collections::BTreeMap;
use std::path::Path;
use std::time::Duration;

use rusqlite::types::ValueRef;
use rusqlite::{params, Connection, ErrorCode, OpenFlags, OptionalExtension, Row, Transaction};

use crate::error::{Error, Result};
use crate::model::{
    Added, Calibration, Combination, DamagedRecord, Event, Parameter, Records, StoredCombination,
    StoredParameter, StoredRecord,
};
use crate::record::{report_figures, rms_errors};
use crate::robot_model::RobotModel;
use crate::store::{in_record, sealed, Access, Backend, Imported, Store, Write, SCHEMA_VERSION};
use crate::text::{names, printable};
use crate::timefmt::format_time;

/// The migrations of the file: entry `i` brings it from schema version `i` to `i + 1`
/// ([`SCHEMA_VERSION`]; the version is SQLite's `user_version`).
const MIGRATIONS: &[&str] = &[
    // 0 -> 1
    "CREATE TABLE calibrations (
        id INTEGER PRIMARY KEY,
        robot_id TEXT NOT NULL,
        at INTEGER NOT NULL,
        robot_name TEXT NOT NULL,
        model_fingerprint TEXT NOT NULL,
        data_fingerprint TEXT NOT NULL,
        method TEXT NOT NULL,
        solution TEXT NOT NULL,
        length_unit TEXT NOT NULL,
        angle_unit TEXT NOT NULL,
        rms_position_before REAL NOT NULL,
        rms_position_after REAL NOT NULL,
        rms_orientation_before REAL NOT NULL,
        rms_orientation_after REAL NOT NULL,
        note TEXT NOT NULL,
        report TEXT NOT NULL
    );
    CREATE INDEX calibrations_robot_at ON calibrations (robot_id, at);
    CREATE TABLE parameters (
        calibration_id INTEGER NOT NULL REFERENCES calibrations (id) ON DELETE CASCADE,
        param_id TEXT NOT NULL,
        name TEXT NOT NULL,
        unit TEXT NOT NULL,
        value REAL NOT NULL,
        sigma REAL,
        estimated INTEGER NOT NULL,
        determined INTEGER NOT NULL,
        PRIMARY KEY (calibration_id, param_id)
    );
    CREATE TABLE combinations (
        calibration_id INTEGER NOT NULL REFERENCES calibrations (id) ON DELETE CASCADE,
        expression TEXT NOT NULL,
        terms TEXT NOT NULL,
        value REAL NOT NULL,
        sigma REAL NOT NULL,
        PRIMARY KEY (calibration_id, expression)
    );",
    // 1 -> 2: the idempotency key of each calibration (none on the records of version 1), and
    // the maintenance events.
    "ALTER TABLE calibrations ADD COLUMN idempotency_key TEXT;
    CREATE UNIQUE INDEX calibrations_key ON calibrations (idempotency_key);
    CREATE TABLE events (
        id INTEGER PRIMARY KEY,
        robot_id TEXT NOT NULL,
        at INTEGER NOT NULL,
        note TEXT NOT NULL
    );
    CREATE UNIQUE INDEX events_robot_at_note ON events (robot_id, at, note);",
];

/// An open SQLite history.
pub(crate) struct SqliteStore {
    conn: Connection,
    path: String,
    read_only: bool,
    /// Schema version of the file (0: an empty file, no tables yet).
    version: i64,
    /// What `quick_check` reported when opened for reading, if not "ok".
    integrity: Option<String>,
}

/// The tables (with their columns) and the views and triggers of a database.
#[derive(Debug, Default, PartialEq)]
struct Schema {
    tables: BTreeMap<String, Vec<String>>,
    others: Vec<(String, String)>,
}

/// A column read as text, whatever its bytes.
fn lossy(r: &Row<'_>, i: usize) -> rusqlite::Result<String> {
    Ok(match r.get_ref(i)? {
        ValueRef::Text(b) | ValueRef::Blob(b) => String::from_utf8_lossy(b).into_owned(),
        ValueRef::Integer(v) => v.to_string(),
        ValueRef::Real(v) => v.to_string(),
        ValueRef::Null => String::new(),
    })
}

fn read_schema(conn: &Connection) -> rusqlite::Result<(i64, Schema)> {
    let version: i64 = conn.query_row("PRAGMA user_version", [], |r| r.get(0))?;
    let mut schema = Schema::default();
    let objects: Vec<(String, String)> = {
        let mut st = conn.prepare(
            "SELECT type, name FROM sqlite_master WHERE name NOT LIKE 'sqlite\\_%' ESCAPE '\\'",
        )?;
        let rows = st.query_map([], |r| Ok((lossy(r, 0)?, lossy(r, 1)?)))?;
        rows.collect::<rusqlite::Result<_>>()?
    };
    for (kind, name) in objects {
        match kind.as_str() {
            "table" => {
                let mut st = conn.prepare("SELECT name FROM pragma_table_info(?1) ORDER BY cid")?;
                let columns = st
                    .query_map([&name], |r| lossy(r, 0))?
                    .collect::<rusqlite::Result<Vec<_>>>()?;
                schema.tables.insert(name, columns);
            }
            "index" => {}
            _ => schema.others.push((kind, name)),
        }
    }
    Ok((version, schema))
}

/// The schema kinecal's migrations give at `version`.
fn reference_schema(version: i64) -> rusqlite::Result<Schema> {
    let conn = Connection::open_in_memory()?;
    for sql in MIGRATIONS
        .iter()
        .take(version.clamp(0, SCHEMA_VERSION) as usize)
    {
        conn.execute_batch(sql)?;
    }
    Ok(read_schema(&conn)?.1)
}

/// Why `found` is not kinecal's schema at `version`, if it is not.
fn schema_difference(version: i64, found: &Schema, reference: &Schema) -> Option<String> {
    if found == reference {
        return None;
    }
    if version == 0 {
        return Some(format!(
            "it holds tables ({}) but no kinecal schema version",
            names(found.tables.keys())
        ));
    }
    let mut parts = Vec::new();
    let extra: Vec<&String> = found
        .tables
        .keys()
        .filter(|t| !reference.tables.contains_key(*t))
        .collect();
    if !extra.is_empty() {
        parts.push(format!("tables kinecal never creates: {}", names(extra)));
    }
    let missing: Vec<&String> = reference
        .tables
        .keys()
        .filter(|t| !found.tables.contains_key(*t))
        .collect();
    if !missing.is_empty() {
        parts.push(format!("no table {}", names(missing)));
    }
    for (table, columns) in &found.tables {
        if let Some(want) = reference.tables.get(table) {
            if columns != want {
                parts.push(format!(
                    "table `{}` has columns ({}), kinecal's has ({})",
                    printable(table),
                    printable(&columns.join(", ")),
                    want.join(", ")
                ));
            }
        }
    }
    for (kind, name) in &found.others {
        parts.push(format!("a {} `{}`", printable(kind), printable(name)));
    }
    Some(format!(
        "schema version {version}, but {}",
        parts.join("; ")
    ))
}

/// The largest file checked whole (`PRAGMA quick_check`) each time it is opened for writing:
/// 4 MiB (about 200 records), checked in a few milliseconds. A larger file is checked page by
/// page as a write reads it, and whole on demand ([`SqliteStore::check`]).
pub(crate) const WHOLE_CHECK_BYTES: u64 = 4 << 20;

/// `PRAGMA quick_check`: `None` when the file is sound, else the first problems reported.
fn quick_check(conn: &Connection) -> Option<String> {
    sound(conn, "PRAGMA quick_check(5)")
}

/// `PRAGMA integrity_check` (`quick_check` and every index against its table): `None` when the
/// file is sound, else the first problems reported.
fn integrity_check(conn: &Connection) -> Option<String> {
    sound(conn, "PRAGMA integrity_check(5)")
}

/// Runs a check pragma: `None` when it answers `ok`, else what it reported.
fn sound(conn: &Connection, pragma: &str) -> Option<String> {
    let rows = (|| -> rusqlite::Result<Vec<String>> {
        let mut st = conn.prepare(pragma)?;
        let rows = st.query_map([], |r| lossy(r, 0))?;
        rows.collect()
    })();
    match rows {
        Ok(v) if v.len() == 1 && v[0] == "ok" => None,
        Ok(v) => Some(v.join("; ")),
        Err(e) => Some(e.to_string()),
    }
}

/// The file as an SQLite URI opening it immutable (no locks, no shared-memory file).
fn immutable_uri(path: &Path) -> std::io::Result<String> {
    let abs = std::path::absolute(path)?;
    #[cfg(unix)]
    let bytes = {
        use std::os::unix::ffi::OsStrExt;
        abs.as_os_str().as_bytes().to_vec()
    };
    #[cfg(not(unix))]
    let bytes = abs.to_string_lossy().replace('\\', "/").into_bytes();
    let mut uri = String::from("file:");
    if !bytes.starts_with(b"/") {
        uri.push('/');
    }
    for b in bytes {
        if b.is_ascii_alphanumeric() || b"-._~/:".contains(&b) {
            uri.push(b as char);
        } else {
            uri.push_str(&format!("%{b:02X}"));
        }
    }
    uri.push_str("?immutable=1");
    Ok(uri)
}

/// Decoders of one stored field: a damaged value gives a sentence naming the field.
mod field {
    use rusqlite::types::ValueRef;
    use rusqlite::Row;

    pub(super) type Decoded<T> = std::result::Result<T, String>;

    pub(super) fn text(r: &Row<'_>, i: usize, field: &str) -> Decoded<String> {
        match r.get_ref(i) {
            Ok(ValueRef::Text(b)) => std::str::from_utf8(b)
                .map(str::to_owned)
                .map_err(|_| format!("{field} is not valid UTF-8 text")),
            Ok(ValueRef::Null) => Err(format!("{field} is missing")),
            Ok(_) => Err(format!("{field} is not text")),
            Err(e) => Err(format!("{field}: {e}")),
        }
    }

    pub(super) fn number(r: &Row<'_>, i: usize, field: &str) -> Decoded<f64> {
        optional_number(r, i, field)?.ok_or_else(|| format!("{field} is missing"))
    }

    pub(super) fn optional_number(r: &Row<'_>, i: usize, field: &str) -> Decoded<Option<f64>> {
        match r.get_ref(i) {
            Ok(ValueRef::Real(v)) if v.is_finite() => Ok(Some(v)),
            Ok(ValueRef::Integer(v)) => Ok(Some(v as f64)),
            Ok(ValueRef::Null) => Ok(None),
            Ok(_) => Err(format!("{field} is not a finite number")),
            Err(e) => Err(format!("{field}: {e}")),
        }
    }

    pub(super) fn integer(r: &Row<'_>, i: usize, field: &str) -> Decoded<i64> {
        match r.get_ref(i) {
            Ok(ValueRef::Integer(v)) => Ok(v),
            Ok(_) => Err(format!("{field} is not an integer")),
            Err(e) => Err(format!("{field}: {e}")),
        }
    }

    pub(super) fn flag(r: &Row<'_>, i: usize, field: &str) -> Decoded<bool> {
        match r.get_ref(i) {
            Ok(ValueRef::Integer(0)) => Ok(false),
            Ok(ValueRef::Integer(1)) => Ok(true),
            Ok(_) => Err(format!("{field} is not true or false")),
            Err(e) => Err(format!("{field}: {e}")),
        }
    }
}

fn open_connection(path: &Path, shown: &str, flags: OpenFlags) -> Result<Connection> {
    let fail = |m: String| Error::Database {
        path: shown.to_string(),
        message: m,
    };
    let conn =
        Connection::open_with_flags(path, flags).map_err(|e| fail(format!("cannot open: {e}")))?;
    conn.busy_timeout(Duration::from_secs(30))
        .map_err(|e| fail(e.to_string()))?;
    Ok(conn)
}

/// A database that can be read but not written here.
fn read_only_location(path: &str, e: impl std::fmt::Display) -> Error {
    Error::Database {
        path: path.to_string(),
        message: format!(
            "cannot write here: the file or its folder is read-only ({e}); nothing was written \
             (the read commands still work)"
        ),
    }
}

/// An error met while reading the file's schema, as the user should read it.
fn classify(path: &str, e: rusqlite::Error) -> Error {
    match e.sqlite_error_code() {
        Some(ErrorCode::NotADatabase) => Error::Foreign {
            path: path.to_string(),
            reason: format!("not an SQLite database: {e}"),
        },
        Some(ErrorCode::DatabaseCorrupt) => Error::Corrupt {
            path: path.to_string(),
            problem: e.to_string(),
        },
        _ => Error::Database {
            path: path.to_string(),
            message: format!("cannot read: {e}"),
        },
    }
}

/// Reads the file's schema version and schema in one read transaction, and checks that they
/// are kinecal's. Reads only.
fn inspect(conn: &Connection, path: &str) -> Result<i64> {
    conn.execute_batch("BEGIN DEFERRED")
        .map_err(|e| classify(path, e))?;
    let read = read_schema(conn);
    let _ = conn.execute_batch("COMMIT");
    let (version, schema) = read.map_err(|e| classify(path, e))?;
    if version < 0 {
        return Err(Error::Foreign {
            path: path.to_string(),
            reason: format!(
                "its schema version (user_version) is {version}, which kinecal never writes"
            ),
        });
    }
    if version > SCHEMA_VERSION {
        return Err(Error::NewerSchema {
            path: path.to_string(),
            found: version,
            supported: SCHEMA_VERSION,
        });
    }
    let reference = reference_schema(version).map_err(|e| Error::Database {
        path: path.to_string(),
        message: e.to_string(),
    })?;
    if let Some(reason) = schema_difference(version, &schema, &reference) {
        return Err(Error::Foreign {
            path: path.to_string(),
            reason,
        });
    }
    Ok(version)
}

impl SqliteStore {
    fn err(&self, e: impl std::fmt::Display) -> Error {
        Error::Database {
            path: self.path.clone(),
            message: e.to_string(),
        }
    }

    /// Opens the history file at `path`: for writing (creating and migrating it if needed, see
    /// [`SqliteStore::open_for_writing`]) or for reading only (see
    /// [`SqliteStore::open_for_reading`]).
    pub(crate) fn open(path: &Path, access: Access) -> Result<SqliteStore> {
        match access {
            Access::ReadWrite => SqliteStore::open_for_writing(path),
            Access::ReadOnly => SqliteStore::open_for_reading(path),
        }
    }

    /// Opens the database at `path` for writing, creating it and its folder if needed, and
    /// migrates it. An existing file is first opened read-only and inspected: a file that is
    /// not a kinecal history (another schema, a negative or newer schema version, not SQLite
    /// at all) or that fails `PRAGMA quick_check` is refused, and nothing is written to it.
    fn open_for_writing(path: &Path) -> Result<SqliteStore> {
        let shown = path.display().to_string();
        let fail = |m: String| Error::Database {
            path: shown.clone(),
            message: m,
        };
        // (An error here, e.g. a file where a folder should be, is reported by the creation.)
        let existed = matches!(path.try_exists(), Ok(true));
        if existed {
            if path.is_dir() {
                return Err(fail("is a folder, not a database file".into()));
            }
            let ro = open_connection(
                path,
                &shown,
                OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX,
            )?;
            if let Err(e) = ro.query_row("PRAGMA user_version", [], |r| r.get::<_, i64>(0)) {
                if matches!(
                    e.sqlite_error_code(),
                    Some(ErrorCode::CannotOpen | ErrorCode::ReadOnly)
                ) {
                    return Err(read_only_location(&shown, e));
                }
            }
            inspect(&ro, &shown)?;
            // A small file is checked whole (milliseconds); a larger one page by page as the
            // write reads it (see the module's documentation).
            let small = std::fs::metadata(path).is_ok_and(|m| m.len() <= WHOLE_CHECK_BYTES);
            if small {
                if let Some(problem) = quick_check(&ro) {
                    return Err(Error::Corrupt {
                        path: shown,
                        problem,
                    });
                }
            }
        } else if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir)
                .map_err(|e| fail(format!("cannot create the folder: {e}")))?;
        }
        let mut flags = OpenFlags::SQLITE_OPEN_READ_WRITE | OpenFlags::SQLITE_OPEN_NO_MUTEX;
        if !existed {
            flags |= OpenFlags::SQLITE_OPEN_CREATE;
        }
        let conn = open_connection(path, &shown, flags)?;
        // SQLite opens a write-protected file read-only rather than failing.
        if conn.is_readonly(rusqlite::MAIN_DB).unwrap_or(false) {
            return Err(read_only_location(&shown, "the file is write-protected"));
        }
        // The schema again, on the connection that writes (reading only): another kinecal may
        // have created or migrated the file meanwhile. Version and tables are read in one read
        // transaction, so that a migration is seen either before or after, never half.
        let version = inspect(&conn, &shown)?;
        let db = SqliteStore {
            conn,
            path: shown,
            read_only: false,
            version: SCHEMA_VERSION,
            integrity: None,
        };
        db.enable_wal()?;
        db.conn
            .execute_batch(
                "PRAGMA foreign_keys = ON; PRAGMA synchronous = NORMAL; PRAGMA cell_size_check = ON;",
            )
            .map_err(|e| db.err(e))?;
        db.migrate(version)?;
        Ok(db)
    }

    /// Switches the file to the WAL journal unless it already is. SQLite answers a journal-mode
    /// change that meets another process's lock with "database is locked" at once, without
    /// calling the busy handler (typical when several processes create the same file at the
    /// same moment), so the change is retried here within the same 30 s as any other lock.
    fn enable_wal(&self) -> Result<()> {
        let mode = |sql: &str| self.conn.query_row(sql, [], |r| r.get::<_, String>(0));
        let deadline = std::time::Instant::now() + Duration::from_secs(30);
        let mut pause = Duration::from_millis(2);
        loop {
            let attempt = match mode("PRAGMA journal_mode") {
                Ok(m) if m.eq_ignore_ascii_case("wal") => return Ok(()),
                Ok(_) => mode("PRAGMA journal_mode = WAL").map(|_| ()),
                Err(e) => Err(e),
            };
            match attempt {
                Ok(()) => return Ok(()),
                Err(e)
                    if matches!(
                        e.sqlite_error_code(),
                        Some(ErrorCode::DatabaseBusy | ErrorCode::DatabaseLocked)
                    ) && std::time::Instant::now() < deadline =>
                {
                    std::thread::sleep(pause);
                    pause = (pause * 2).min(Duration::from_millis(100));
                }
                Err(e) => {
                    return Err(self.err(format!(
                        "cannot enable the WAL journal (is the location writable?): {e}"
                    )))
                }
            }
        }
    }

    /// Opens an existing database for reading only (`SQLITE_OPEN_READ_ONLY`): never creates a
    /// file, never writes, and works on a read-only file in a read-only folder. The file is
    /// inspected as by [`SqliteStore::open_for_writing`]; a failed `quick_check` does not stop
    /// the reading (see [`Store::integrity_problem`]).
    fn open_for_reading(path: &Path) -> Result<SqliteStore> {
        let shown = path.display().to_string();
        let fail = |m: String| Error::Database {
            path: shown.clone(),
            message: m,
        };
        match path.try_exists() {
            Ok(true) => {}
            Ok(false) => return Err(Error::NoDatabase { path: shown }),
            Err(e) if e.kind() == std::io::ErrorKind::NotADirectory => {
                return Err(Error::NoDatabase { path: shown })
            }
            Err(e) => return Err(fail(format!("cannot open: {e}"))),
        }
        if path.is_dir() {
            return Err(fail("is a folder, not a database file".into()));
        }
        let flags = OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX;
        let mut conn = open_connection(path, &shown, flags)?;
        if let Err(e) = conn.query_row("PRAGMA user_version", [], |r| r.get::<_, i64>(0)) {
            // A WAL database in a folder that cannot be written: SQLite cannot create the
            // shared-memory file a reader needs. No writer can be at work there either, so the
            // file is read as it stands.
            if matches!(
                e.sqlite_error_code(),
                Some(ErrorCode::CannotOpen | ErrorCode::ReadOnly)
            ) {
                let uri = immutable_uri(path).map_err(|e| fail(format!("cannot open: {e}")))?;
                conn =
                    open_connection(Path::new(&uri), &shown, flags | OpenFlags::SQLITE_OPEN_URI)?;
            }
        }
        let version = inspect(&conn, &shown)?;
        let integrity = quick_check(&conn);
        Ok(SqliteStore {
            conn,
            path: shown,
            read_only: true,
            version,
            integrity,
        })
    }

    fn migrate(&self, from: i64) -> Result<()> {
        if from >= SCHEMA_VERSION {
            return Ok(());
        }
        let tx = self.begin()?;
        // Re-read inside the write transaction: another process may have migrated meanwhile.
        let now_version: i64 = tx
            .query_row("PRAGMA user_version", [], |r| r.get(0))
            .map_err(|e| self.err(e))?;
        for (k, sql) in MIGRATIONS
            .iter()
            .enumerate()
            .skip(now_version.clamp(0, SCHEMA_VERSION) as usize)
        {
            tx.execute_batch(sql)
                .map_err(|e| self.err(format!("migration to version {}: {e}", k + 1)))?;
        }
        tx.execute_batch(&format!("PRAGMA user_version = {SCHEMA_VERSION}"))
            .map_err(|e| self.err(e))?;
        tx.commit().map_err(|e| self.err(e))
    }

    /// An IMMEDIATE transaction: takes the write lock at once (waiting up to the busy timeout),
    /// so two writers never deadlock half way.
    fn begin(&self) -> Result<Transaction<'_>> {
        Transaction::new_unchecked(&self.conn, rusqlite::TransactionBehavior::Immediate)
            .map_err(|e| self.sql(e))
    }

    /// An SQLite error met while writing: a damaged page the write read is
    /// [`Error::Corrupt`] (the transaction is rolled back: nothing was written).
    fn sql(&self, e: rusqlite::Error) -> Error {
        match e.sqlite_error_code() {
            Some(ErrorCode::DatabaseCorrupt | ErrorCode::NotADatabase) => Error::Corrupt {
                path: self.path.clone(),
                problem: e.to_string(),
            },
            _ => self.err(e),
        }
    }

    /// The whole file checked (`PRAGMA integrity_check`): `None` when it is sound, else the
    /// first problems found.
    pub(crate) fn check(&self) -> Result<Option<String>> {
        if self.version == 0 {
            return Ok(None);
        }
        Ok(integrity_check(&self.conn))
    }

    /// Writes `rec` in one IMMEDIATE transaction (see [`Store::insert`]). Every page the write
    /// reads is checked as it is read: a damaged one refuses the write ([`Error::Corrupt`]),
    /// and nothing is written.
    fn insert_record(&self, rec: &StoredRecord, write: Write) -> Result<Added> {
        if self.read_only {
            return Err(self.err("opened for reading only; nothing was written"));
        }
        let tx = self.begin()?;
        let added = self.insert_in(&tx, rec, write)?;
        tx.commit().map_err(|e| self.sql(e))?;
        Ok(added)
    }

    /// Writes the records and events of a dump in one IMMEDIATE transaction (see
    /// [`Store::import`]).
    fn import_all(&self, records: &[StoredRecord], events: &[Event]) -> Result<Imported> {
        if self.read_only {
            return Err(self.err("opened for reading only; nothing was written"));
        }
        let tx = self.begin()?;
        let mut out: Imported = (Vec::new(), Vec::new());
        for rec in records {
            out.0.push(
                self.insert_in(&tx, rec, Write::Import)
                    .map_err(|e| in_record(e, rec))?,
            );
        }
        for e in events {
            out.1.push(self.insert_event_in(&tx, e, Write::Import)?);
        }
        tx.commit().map_err(|e| self.sql(e))?;
        Ok(out)
    }

    /// Writes `rec` within `tx` (not committed).
    fn insert_in(&self, tx: &Transaction<'_>, rec: &StoredRecord, write: Write) -> Result<Added> {
        if let Some(key) = &rec.key {
            let existing: Option<i64> = tx
                .query_row(
                    "SELECT id FROM calibrations WHERE idempotency_key = ?1",
                    [key],
                    |r| r.get(0),
                )
                .optional()
                .map_err(|e| self.sql(e))?;
            if let Some(id) = existing {
                return Ok(Added { id, new: false });
            }
        }
        let mut id = None;
        match write {
            Write::New { force } => {
                if !force {
                    self.check_model(
                        tx,
                        &rec.robot_id,
                        &RobotModel::of_parameters(&rec.parameters),
                    )?;
                }
            }
            Write::Import => {
                let same: Option<(String, i64, String)> = tx
                    .query_row(
                        "SELECT robot_id, at, report FROM calibrations WHERE id = ?1",
                        [rec.id],
                        |r| Ok((lossy(r, 0)?, r.get(1)?, lossy(r, 2)?)),
                    )
                    .optional()
                    .map_err(|e| self.sql(e))?;
                match same {
                    Some(s) if s == (rec.robot_id.clone(), rec.at, rec.report.clone()) => {
                        return Ok(Added {
                            id: rec.id,
                            new: false,
                        })
                    }
                    Some(_) => {}
                    None => id = Some(rec.id),
                }
            }
        }
        tx.execute(
            "INSERT INTO calibrations (id, robot_id, at, robot_name, model_fingerprint, data_fingerprint, method, solution,
                length_unit, angle_unit, rms_position_before, rms_position_after, rms_orientation_before,
                rms_orientation_after, note, report, idempotency_key)
             VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15, ?16, ?17)",
            params![
                id,
                rec.robot_id,
                rec.at,
                rec.robot_name,
                rec.model_fingerprint,
                rec.data_fingerprint,
                rec.method,
                rec.solution,
                rec.length_unit,
                rec.angle_unit,
                rec.rms_position_before,
                rec.rms_position_after,
                rec.rms_orientation_before,
                rec.rms_orientation_after,
                rec.note,
                rec.report,
                rec.key,
            ],
        )
        .map_err(|e| self.sql(e))?;
        let id = tx.last_insert_rowid();
        for p in &rec.parameters {
            tx.execute(
                "INSERT INTO parameters (calibration_id, param_id, name, unit, value, sigma, estimated, determined)
                 VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8)",
                params![id, p.id, p.name, p.unit, p.value, p.sigma, p.estimated, p.determined],
            )
            .map_err(|e| self.sql(e))?;
        }
        for c in &rec.combinations {
            tx.execute(
                "INSERT INTO combinations (calibration_id, expression, terms, value, sigma) VALUES (?1, ?2, ?3, ?4, ?5)",
                params![id, c.expression, c.terms, c.value, c.sigma],
            )
            .map_err(|e| self.sql(e))?;
        }
        Ok(Added { id, new: true })
    }

    /// Refuses `model` unless it is the model of one of `robot_id`'s earlier records (or the
    /// robot has none).
    fn check_model(&self, tx: &Transaction<'_>, robot_id: &str, model: &RobotModel) -> Result<()> {
        let mut earlier: BTreeMap<i64, RobotModel> = BTreeMap::new();
        let mut st = tx
            .prepare(
                "SELECT p.calibration_id, p.name, p.unit FROM parameters p
                 JOIN calibrations c ON c.id = p.calibration_id WHERE c.robot_id = ?1",
            )
            .map_err(|e| self.sql(e))?;
        let rows = st
            .query_map([robot_id], |r| {
                Ok((r.get::<_, i64>(0)?, lossy(r, 1)?, lossy(r, 2)?))
            })
            .map_err(|e| self.sql(e))?;
        for row in rows {
            let (id, name, unit) = row.map_err(|e| self.sql(e))?;
            earlier.entry(id).or_default().add_parameter(name, &unit);
        }
        model.check_against(robot_id, &earlier)
    }

    fn insert_event_row(&self, e: &Event, write: Write) -> Result<Added> {
        if self.read_only {
            return Err(self.err("opened for reading only; nothing was written"));
        }
        let tx = self.begin()?;
        let added = self.insert_event_in(&tx, e, write)?;
        tx.commit().map_err(|x| self.sql(x))?;
        Ok(added)
    }

    /// Writes the event `e` within `tx` (not committed).
    fn insert_event_in(&self, tx: &Transaction<'_>, e: &Event, write: Write) -> Result<Added> {
        let existing: Option<i64> = tx
            .query_row(
                "SELECT id FROM events WHERE robot_id = ?1 AND at = ?2 AND note = ?3",
                params![e.robot_id, e.at, e.note],
                |r| r.get(0),
            )
            .optional()
            .map_err(|x| self.sql(x))?;
        if let Some(id) = existing {
            return Ok(Added { id, new: false });
        }
        let id = match write {
            Write::Import => {
                let taken: Option<i64> = tx
                    .query_row("SELECT id FROM events WHERE id = ?1", [e.id], |r| r.get(0))
                    .optional()
                    .map_err(|x| self.sql(x))?;
                taken.is_none().then_some(e.id)
            }
            Write::New { .. } => None,
        };
        tx.execute(
            "INSERT INTO events (id, robot_id, at, note) VALUES (?1, ?2, ?3, ?4)",
            params![id, e.robot_id, e.at, e.note],
        )
        .map_err(|x| self.sql(x))?;
        let id = tx.last_insert_rowid();
        Ok(Added { id, new: true })
    }

    fn event_rows(&self, robot_id: Option<&str>) -> Result<Vec<Event>> {
        if self.version < 2 {
            return Ok(Vec::new());
        }
        let mut st = self
            .conn
            .prepare("SELECT id, robot_id, at, note FROM events ORDER BY at, id")
            .map_err(|e| self.err(e))?;
        let rows = st
            .query_map([], |r| {
                Ok(Event {
                    id: r.get(0)?,
                    robot_id: lossy(r, 1)?,
                    at: r.get(2)?,
                    note: lossy(r, 3)?,
                })
            })
            .map_err(|e| self.err(e))?;
        let mut out = Vec::new();
        for e in rows {
            let e = e.map_err(|e| self.err(e))?;
            if robot_id.is_none_or(|r| r == e.robot_id) {
                out.push(e);
            }
        }
        Ok(out)
    }

    /// Every record with every stored field, by id; an error naming the first record that
    /// cannot be read exactly (a dump must be lossless).
    fn all_stored(&self) -> Result<Vec<StoredRecord>> {
        if self.version == 0 {
            return Ok(Vec::new());
        }
        let _tx = self.conn.unchecked_transaction().map_err(|e| self.err(e))?;
        let ids: Vec<i64> = {
            let mut st = self
                .conn
                .prepare("SELECT id FROM calibrations ORDER BY id")
                .map_err(|e| self.err(e))?;
            let rows = st.query_map([], |r| r.get(0)).map_err(|e| self.err(e))?;
            rows.collect::<rusqlite::Result<_>>()
                .map_err(|e| self.err(e))?
        };
        let damaged = |id: i64, problem: String| Error::DamagedRecord {
            path: self.path.clone(),
            id,
            problem,
        };
        let key_column = if self.version >= 2 {
            "idempotency_key"
        } else {
            "NULL"
        };
        let mut out = Vec::with_capacity(ids.len());
        for id in ids {
            use field::{flag, integer, number, optional_number, text};
            let mut rec = self
                .conn
                .query_row(
                    &format!(
                        "SELECT robot_id, at, robot_name, model_fingerprint, data_fingerprint, method, solution,
                                length_unit, angle_unit, rms_position_before, rms_position_after,
                                rms_orientation_before, rms_orientation_after, note, report, {key_column}
                         FROM calibrations WHERE id = ?1"
                    ),
                    [id],
                    |r| {
                        Ok((|| -> field::Decoded<StoredRecord> {
                            Ok(StoredRecord {
                                id,
                                key: match r.get_ref(15) {
                                    Ok(ValueRef::Null) => None,
                                    _ => Some(text(r, 15, "its key")?),
                                },
                                robot_id: text(r, 0, "its robot serial")?,
                                at: integer(r, 1, "its time")?,
                                robot_name: text(r, 2, "its robot model name")?,
                                model_fingerprint: text(r, 3, "its model fingerprint")?,
                                data_fingerprint: text(r, 4, "its data fingerprint")?,
                                method: text(r, 5, "its method")?,
                                solution: text(r, 6, "its solution rule")?,
                                length_unit: text(r, 7, "its length unit")?,
                                angle_unit: text(r, 8, "its angle unit")?,
                                rms_position_before: number(r, 9, "its RMS position error before")?,
                                rms_position_after: number(r, 10, "its RMS position error after")?,
                                rms_orientation_before: number(r, 11, "its RMS attitude error before")?,
                                rms_orientation_after: number(r, 12, "its RMS attitude error after")?,
                                note: text(r, 13, "its note")?,
                                report: text(r, 14, "its stored report")?,
                                parameters: Vec::new(),
                                combinations: Vec::new(),
                            })
                        })())
                    },
                )
                .map_err(|e| self.err(e))?
                .map_err(|p| damaged(id, p))?;
            let mut st = self
                .conn
                .prepare(
                    "SELECT param_id, name, unit, value, sigma, estimated, determined FROM parameters
                     WHERE calibration_id = ?1 ORDER BY CAST(substr(param_id, 2) AS INTEGER)",
                )
                .map_err(|e| self.err(e))?;
            let rows = st
                .query_map([id], |r| {
                    Ok((|| -> field::Decoded<StoredParameter> {
                        Ok(StoredParameter {
                            id: text(r, 0, "a parameter id")?,
                            name: text(r, 1, "a parameter name")?,
                            unit: text(r, 2, "a parameter unit")?,
                            value: number(r, 3, "a parameter value")?,
                            sigma: optional_number(r, 4, "a parameter sigma")?,
                            estimated: flag(r, 5, "a parameter's estimated flag")?,
                            determined: flag(r, 6, "a parameter's determined flag")?,
                        })
                    })())
                })
                .map_err(|e| self.err(e))?;
            for p in rows {
                rec.parameters
                    .push(p.map_err(|e| self.err(e))?.map_err(|p| damaged(id, p))?);
            }
            let mut st = self
                .conn
                .prepare("SELECT expression, terms, value, sigma FROM combinations WHERE calibration_id = ?1 ORDER BY expression")
                .map_err(|e| self.err(e))?;
            let rows = st
                .query_map([id], |r| {
                    Ok((|| -> field::Decoded<StoredCombination> {
                        Ok(StoredCombination {
                            expression: text(r, 0, "a combination's expression")?,
                            terms: text(r, 1, "a combination's terms")?,
                            value: number(r, 2, "a combination's value")?,
                            sigma: number(r, 3, "a combination's sigma")?,
                        })
                    })())
                })
                .map_err(|e| self.err(e))?;
            for c in rows {
                rec.combinations
                    .push(c.map_err(|e| self.err(e))?.map_err(|p| damaged(id, p))?);
            }
            out.push(rec);
        }
        Ok(out)
    }

    /// The robots with a history, with their number of calibrations.
    fn robot_counts(&self) -> Result<Vec<(String, i64)>> {
        if self.version == 0 {
            return Ok(Vec::new());
        }
        let mut st = self
            .conn
            .prepare(
                "SELECT robot_id, count(*) FROM calibrations GROUP BY robot_id ORDER BY robot_id",
            )
            .map_err(|e| self.err(e))?;
        let rows = st
            .query_map([], |r| Ok((lossy(r, 0)?, r.get(1)?)))
            .map_err(|e| self.err(e))?;
        rows.collect::<rusqlite::Result<Vec<_>>>()
            .map_err(|e| self.err(e))
    }

    /// Every calibration of `robot_id` (all robots when `None`), by robot then oldest first;
    /// the records with a damaged field are listed apart, by id, and the others served.
    fn read_records(&self, robot_id: Option<&str>) -> Result<Records> {
        if self.version == 0 {
            return Ok(Records::default());
        }
        // One read transaction: a consistent snapshot while other processes write.
        let tx = self.conn.unchecked_transaction().map_err(|e| self.err(e))?;
        // A full scan, not the index: the list must not depend on more of the file than needed,
        // and robots are compared by their stored bytes.
        let mut keys: Vec<(Vec<u8>, i64, i64)> = Vec::new();
        {
            let mut st = tx
                .prepare("SELECT id, robot_id, at FROM calibrations NOT INDEXED")
                .map_err(|e| self.err(e))?;
            let mut rows = st.query([]).map_err(|e| self.err(e))?;
            while let Some(r) = rows.next().map_err(|e| self.err(e))? {
                let id: i64 = r.get(0).map_err(|e| self.err(e))?;
                let robot = match r.get_ref(1).map_err(|e| self.err(e))? {
                    ValueRef::Text(b) | ValueRef::Blob(b) => b.to_vec(),
                    _ => Vec::new(),
                };
                if robot_id.is_some_and(|want| want.as_bytes() != robot.as_slice()) {
                    continue;
                }
                let at = r
                    .get_ref(2)
                    .ok()
                    .and_then(|v| v.as_i64().ok())
                    .unwrap_or(i64::MIN);
                keys.push((robot, at, id));
            }
        }
        keys.sort();
        let mut out = Records::default();
        for (_, _, id) in keys {
            match self.read_record(id) {
                Ok(Some(c)) => out.calibrations.push(c),
                Ok(None) => {}
                Err(problem) => out.damaged.push(DamagedRecord { id, problem }),
            }
        }
        drop(tx);
        Ok(out)
    }

    /// One calibration by id ([`Error::DamagedRecord`] when it cannot be read).
    fn read_calibration(&self, id: i64) -> Result<Option<Calibration>> {
        if self.version == 0 {
            return Ok(None);
        }
        self.read_record(id)
            .map_err(|problem| Error::DamagedRecord {
                path: self.path.clone(),
                id,
                problem,
            })
    }

    /// One record, or the sentence saying which of its fields is damaged.
    fn read_record(&self, id: i64) -> field::Decoded<Option<Calibration>> {
        use field::{flag, integer, number, optional_number, text};
        let unreadable = |e: rusqlite::Error| format!("the record cannot be read: {e}");
        let head = self
            .conn
            .query_row(
                "SELECT robot_id, at, robot_name, model_fingerprint, data_fingerprint, method, solution, length_unit,
                        angle_unit, rms_position_before, rms_position_after, rms_orientation_before,
                        rms_orientation_after, note, report
                 FROM calibrations WHERE id = ?1",
                [id],
                |r| {
                    Ok((|| -> field::Decoded<Calibration> {
                        let at = integer(r, 1, "its time")?;
                        let report = text(r, 14, "its stored report")?;
                        let report = report_figures(&report)?;
                        let length_unit = text(r, 7, "its length unit")?;
                        let angle_unit = text(r, 8, "its angle unit")?;
                        Ok(Calibration {
                            errors: rms_errors(&report, &length_unit, &angle_unit),
                            id,
                            robot_id: text(r, 0, "its robot serial")?,
                            at,
                            at_text: format_time(at),
                            robot_name: text(r, 2, "its robot model name")?,
                            model_fingerprint: text(r, 3, "its model fingerprint")?,
                            data_fingerprint: text(r, 4, "its data fingerprint")?,
                            method: text(r, 5, "its method")?,
                            solution: text(r, 6, "its solution rule")?,
                            length_unit,
                            angle_unit,
                            rms_position_before: number(r, 9, "its RMS position error before")?,
                            rms_position_after: number(r, 10, "its RMS position error after")?,
                            rms_orientation_before: number(r, 11, "its RMS attitude error before")?,
                            rms_orientation_after: number(r, 12, "its RMS attitude error after")?,
                            note: text(r, 13, "its note")?,
                            parameters: Vec::new(),
                            combinations: Vec::new(),
                        })
                    })())
                },
            )
            .optional()
            .map_err(unreadable)?;
        let Some(head) = head else { return Ok(None) };
        let mut c = head?;
        let mut st = self
            .conn
            .prepare(
                "SELECT param_id, name, unit, value, sigma, estimated, determined FROM parameters
                 WHERE calibration_id = ?1 ORDER BY CAST(substr(param_id, 2) AS INTEGER)",
            )
            .map_err(unreadable)?;
        let rows = st
            .query_map([id], |r| {
                Ok((|| -> field::Decoded<Parameter> {
                    let pid = text(r, 0, "a parameter id")?;
                    let f = |what: &str| format!("parameter {}'s {what}", printable(&pid));
                    Ok(Parameter {
                        name: text(r, 1, &f("name"))?,
                        unit: text(r, 2, &f("unit"))?,
                        value: number(r, 3, &f("value"))?,
                        sigma: optional_number(r, 4, &f("sigma"))?,
                        estimated: flag(r, 5, &f("estimated flag"))?,
                        determined: flag(r, 6, &f("determined flag"))?,
                        id: pid,
                    })
                })())
            })
            .map_err(unreadable)?;
        for row in rows {
            c.parameters.push(row.map_err(unreadable)??);
        }
        let mut st = self
            .conn
            .prepare("SELECT expression, terms, value, sigma FROM combinations WHERE calibration_id = ?1 ORDER BY expression")
            .map_err(unreadable)?;
        let rows = st
            .query_map([id], |r| {
                Ok((|| -> field::Decoded<Combination> {
                    let expression = text(r, 0, "a combination's expression")?;
                    let f =
                        |what: &str| format!("combination `{}`'s {what}", printable(&expression));
                    let terms = text(r, 1, &f("terms"))?;
                    let terms: Vec<(String, String, f64)> = serde_json::from_str(&terms)
                        .map_err(|e| format!("{} are not valid JSON ({e})", f("terms")))?;
                    Ok(Combination {
                        terms,
                        value: number(r, 2, &f("value"))?,
                        sigma: number(r, 3, &f("sigma"))?,
                        expression,
                    })
                })())
            })
            .map_err(unreadable)?;
        for row in rows {
            c.combinations.push(row.map_err(unreadable)??);
        }
        Ok(Some(c))
    }
}

impl sealed::Sealed for SqliteStore {}

impl Store for SqliteStore {
    fn location(&self) -> &str {
        &self.path
    }

    fn backend(&self) -> Backend {
        Backend::Sqlite
    }

    fn schema_version(&self) -> i64 {
        self.version
    }

    /// When opened for reading: what `PRAGMA quick_check` reported, if the file is not sound.
    /// The records that can still be read are served.
    fn integrity_problem(&self) -> Option<&str> {
        self.integrity.as_deref()
    }

    fn insert(&self, record: &StoredRecord, write: Write) -> Result<Added> {
        self.insert_record(record, write)
    }

    fn import(&self, records: &[StoredRecord], events: &[Event]) -> Result<Imported> {
        self.import_all(records, events)
    }

    fn check(&self) -> Result<Option<String>> {
        SqliteStore::check(self)
    }

    fn robots(&self) -> Result<Vec<(String, i64)>> {
        self.robot_counts()
    }

    fn records(&self, robot_id: Option<&str>) -> Result<Records> {
        self.read_records(robot_id)
    }

    fn calibration(&self, id: i64) -> Result<Option<Calibration>> {
        self.read_calibration(id)
    }

    fn insert_event(&self, event: &Event, write: Write) -> Result<Added> {
        self.insert_event_row(event, write)
    }

    fn events(&self, robot_id: Option<&str>) -> Result<Vec<Event>> {
        self.event_rows(robot_id)
    }

    fn stored_records(&self) -> Result<Vec<StoredRecord>> {
        self.all_stored()
    }
}
