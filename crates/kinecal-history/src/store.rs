//! The SQLite store.

use std::path::{Path, PathBuf};
use std::time::Duration;

use kinecal::report::CalibrationReport;
use rusqlite::{params, Connection, OpenFlags, OptionalExtension, Transaction};
use serde::Serialize;

use crate::timefmt::{format_time, now};
use crate::{Error, Result};

/// The schema version this build writes. Each entry of `MIGRATIONS` brings a database from
/// version `i` to `i + 1`.
pub const SCHEMA_VERSION: i64 = 1;

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
];

/// One parameter of a recorded calibration (robot file's units).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Parameter {
    /// `p1`, ...
    pub id: String,
    /// `link1.x`, ...
    pub name: String,
    /// Unit.
    pub unit: String,
    /// Value after calibration.
    pub value: f64,
    /// Standard deviation, when determined.
    pub sigma: Option<f64>,
    /// Whether it was estimated.
    pub estimated: bool,
    /// Whether the data determined it individually.
    pub determined: bool,
}

/// A determined combination of a recorded calibration.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Combination {
    /// `p3 - p9 - p15 - ...`.
    pub expression: String,
    /// Members as (id, name, coefficient).
    pub terms: Vec<(String, String, f64)>,
    /// Value.
    pub value: f64,
    /// Standard deviation.
    pub sigma: f64,
}

/// A recorded calibration.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Calibration {
    /// Database id.
    pub id: i64,
    /// The robot's serial number.
    pub robot_id: String,
    /// When (Unix seconds).
    pub at: i64,
    /// When (RFC 3339).
    pub at_text: String,
    /// The robot model's name.
    pub robot_name: String,
    /// SHA-256 of the nominal robot file.
    pub model_fingerprint: String,
    /// SHA-256 of the measurement file.
    pub data_fingerprint: String,
    /// Method.
    pub method: String,
    /// Solution rule.
    pub solution: String,
    /// Length unit.
    pub length_unit: String,
    /// Angle unit.
    pub angle_unit: String,
    /// RMS position error before.
    pub rms_position_before: f64,
    /// RMS position error after.
    pub rms_position_after: f64,
    /// RMS attitude error before (0 without full-pose observations).
    pub rms_orientation_before: f64,
    /// RMS attitude error after.
    pub rms_orientation_after: f64,
    /// Free-form note.
    pub note: String,
    /// Every parameter.
    pub parameters: Vec<Parameter>,
    /// Every determined combination.
    pub combinations: Vec<Combination>,
}

/// Where the history lives by default: `$XDG_DATA_HOME/kinecal/history.sqlite`, else
/// `~/.local/share/kinecal/history.sqlite` (`%APPDATA%\kinecal` on Windows).
pub fn default_db_path() -> Option<PathBuf> {
    let base = std::env::var_os("XDG_DATA_HOME")
        .map(PathBuf::from)
        .filter(|p| p.is_absolute())
        .or_else(|| std::env::var_os("APPDATA").map(PathBuf::from))
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".local/share")))?;
    Some(base.join("kinecal").join("history.sqlite"))
}

/// An open history database.
pub struct Database {
    conn: Connection,
    path: String,
}

impl Database {
    fn err(&self, e: impl std::fmt::Display) -> Error {
        Error::Database {
            path: self.path.clone(),
            message: e.to_string(),
        }
    }

    /// Opens (creating it and its folder if needed) and migrates the database at `path`.
    pub fn open(path: &Path) -> Result<Database> {
        let shown = path.display().to_string();
        let fail = |m: String| Error::Database {
            path: shown.clone(),
            message: m,
        };
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir)
                .map_err(|e| fail(format!("cannot create the folder: {e}")))?;
        }
        let conn = Connection::open_with_flags(
            path,
            OpenFlags::SQLITE_OPEN_READ_WRITE
                | OpenFlags::SQLITE_OPEN_CREATE
                | OpenFlags::SQLITE_OPEN_NO_MUTEX,
        )
        .map_err(|e| fail(format!("cannot open: {e}")))?;
        conn.busy_timeout(Duration::from_secs(30))
            .map_err(|e| fail(e.to_string()))?;
        let db = Database { conn, path: shown };
        // Reading the schema version is the first access: a non-database file fails here,
        // before anything is written. Version and tables are read in one read transaction, so
        // that another process migrating meanwhile is seen either before or after, never half.
        let (version, tables, has_calibrations) = db.snapshot()?;
        if version > SCHEMA_VERSION {
            return Err(Error::NewerSchema {
                path: db.path.clone(),
                found: version,
                supported: SCHEMA_VERSION,
            });
        }
        if (version > 0 && !has_calibrations) || (version == 0 && tables > 0) {
            return Err(
                db.err("a SQLite database, but not a kinecal history; the file was not modified")
            );
        }
        db.conn
            .query_row("PRAGMA journal_mode = WAL", [], |r| r.get::<_, String>(0))
            .map_err(|e| {
                db.err(format!(
                    "cannot enable the WAL journal (is the location writable?): {e}"
                ))
            })?;
        db.conn
            .execute_batch("PRAGMA foreign_keys = ON; PRAGMA synchronous = NORMAL;")
            .map_err(|e| db.err(e))?;
        db.migrate(version)?;
        Ok(db)
    }

    /// (schema version, number of schema objects, whether the calibrations table exists).
    fn snapshot(&self) -> Result<(i64, i64, bool)> {
        let not_db = |e: rusqlite::Error| {
            self.err(format!(
                "not a kinecal history database ({e}); the file was not modified"
            ))
        };
        self.conn.execute_batch("BEGIN DEFERRED").map_err(not_db)?;
        let read = || -> rusqlite::Result<(i64, i64, bool)> {
            let v: i64 = self
                .conn
                .query_row("PRAGMA user_version", [], |r| r.get(0))?;
            let n: i64 = self
                .conn
                .query_row("SELECT count(*) FROM sqlite_master", [], |r| r.get(0))?;
            let c: i64 = self.conn.query_row(
                "SELECT count(*) FROM sqlite_master WHERE name = 'calibrations'",
                [],
                |r| r.get(0),
            )?;
            Ok((v, n, c > 0))
        };
        let result = read();
        let _ = self.conn.execute_batch("COMMIT");
        result.map_err(not_db)
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
        for (k, sql) in MIGRATIONS.iter().enumerate().skip(now_version as usize) {
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
            .map_err(|e| self.err(e))
    }

    /// Records a calibration report for robot `robot_id` at `at` (Unix seconds; now if `None`).
    /// The model and data fingerprints are the report's (SHA-256 of the robot and measurement
    /// files, see [`crate::fingerprint`]), empty when it has none.
    pub fn add(
        &self,
        robot_id: &str,
        at: Option<i64>,
        report: &CalibrationReport,
        note: &str,
    ) -> Result<i64> {
        if robot_id.trim().is_empty() {
            return Err(Error::Input(
                "the robot id (serial) must not be empty".into(),
            ));
        }
        if report.rank.is_none() {
            return Err(Error::Input(
                "the report has no uncertainty (no rank or sigmas): recalibrate with a kinecal that writes them".into(),
            ));
        }
        let at = at.unwrap_or_else(now);
        let json = report.to_json();
        let tx = self.begin()?;
        tx.execute(
            "INSERT INTO calibrations (robot_id, at, robot_name, model_fingerprint, data_fingerprint, method, solution,
                length_unit, angle_unit, rms_position_before, rms_position_after, rms_orientation_before,
                rms_orientation_after, note, report)
             VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15)",
            params![
                robot_id,
                at,
                report.robot,
                report.robot_file_sha256.clone().unwrap_or_default(),
                report.data_file_sha256.clone().unwrap_or_default(),
                report.method,
                report.solution,
                report.length_unit,
                report.angle_unit,
                report.rms_position_before,
                report.rms_position_after,
                report.rms_orientation_before.unwrap_or(0.0),
                report.rms_orientation_after.unwrap_or(0.0),
                note,
                json
            ],
        )
        .map_err(|e| self.err(e))?;
        let id = tx.last_insert_rowid();
        for p in &report.parameters {
            tx.execute(
                "INSERT INTO parameters (calibration_id, param_id, name, unit, value, sigma, estimated, determined)
                 VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8)",
                params![id, p.id, p.name, p.unit, p.estimated, p.sigma, p.estimated_flag, p.determined.unwrap_or(false)],
            )
            .map_err(|e| self.err(e))?;
        }
        for c in &report.combinations {
            let terms: Vec<(String, String, f64)> = c
                .terms
                .iter()
                .map(|t| (t.id.clone(), t.name.clone(), t.coefficient))
                .collect();
            tx.execute(
                "INSERT INTO combinations (calibration_id, expression, terms, value, sigma) VALUES (?1, ?2, ?3, ?4, ?5)",
                params![id, c.expression, serde_json::to_string(&terms).expect("terms serialize"), c.value, c.sigma],
            )
            .map_err(|e| self.err(e))?;
        }
        tx.commit().map_err(|e| self.err(e))?;
        Ok(id)
    }

    /// The robots with a history, with their number of calibrations.
    pub fn robots(&self) -> Result<Vec<(String, i64)>> {
        let mut st = self
            .conn
            .prepare(
                "SELECT robot_id, count(*) FROM calibrations GROUP BY robot_id ORDER BY robot_id",
            )
            .map_err(|e| self.err(e))?;
        let rows = st
            .query_map([], |r| Ok((r.get(0)?, r.get(1)?)))
            .map_err(|e| self.err(e))?;
        rows.collect::<rusqlite::Result<Vec<_>>>()
            .map_err(|e| self.err(e))
    }

    /// Every calibration of `robot_id` (all robots when `None`), oldest first.
    pub fn calibrations(&self, robot_id: Option<&str>) -> Result<Vec<Calibration>> {
        let ids: Vec<i64> = {
            let mut st = self
                .conn
                .prepare("SELECT id FROM calibrations WHERE ?1 IS NULL OR robot_id = ?1 ORDER BY robot_id, at, id")
                .map_err(|e| self.err(e))?;
            let rows = st
                .query_map([robot_id], |r| r.get(0))
                .map_err(|e| self.err(e))?;
            rows.collect::<rusqlite::Result<Vec<_>>>()
                .map_err(|e| self.err(e))?
        };
        ids.into_iter()
            .map(|id| {
                self.calibration(id)
                    .and_then(|c| c.ok_or_else(|| self.err("vanished")))
            })
            .collect()
    }

    /// One calibration by id.
    pub fn calibration(&self, id: i64) -> Result<Option<Calibration>> {
        let head = self
            .conn
            .query_row(
                "SELECT robot_id, at, robot_name, model_fingerprint, data_fingerprint, method, solution, length_unit,
                        angle_unit, rms_position_before, rms_position_after, rms_orientation_before,
                        rms_orientation_after, note
                 FROM calibrations WHERE id = ?1",
                [id],
                |r| {
                    Ok(Calibration {
                        id,
                        robot_id: r.get(0)?,
                        at: r.get(1)?,
                        at_text: format_time(r.get(1)?),
                        robot_name: r.get(2)?,
                        model_fingerprint: r.get(3)?,
                        data_fingerprint: r.get(4)?,
                        method: r.get(5)?,
                        solution: r.get(6)?,
                        length_unit: r.get(7)?,
                        angle_unit: r.get(8)?,
                        rms_position_before: r.get(9)?,
                        rms_position_after: r.get(10)?,
                        rms_orientation_before: r.get(11)?,
                        rms_orientation_after: r.get(12)?,
                        note: r.get(13)?,
                        parameters: Vec::new(),
                        combinations: Vec::new(),
                    })
                },
            )
            .optional()
            .map_err(|e| self.err(e))?;
        let Some(mut c) = head else { return Ok(None) };
        let mut st = self
            .conn
            .prepare(
                "SELECT param_id, name, unit, value, sigma, estimated, determined FROM parameters
                 WHERE calibration_id = ?1 ORDER BY CAST(substr(param_id, 2) AS INTEGER)",
            )
            .map_err(|e| self.err(e))?;
        c.parameters = st
            .query_map([id], |r| {
                Ok(Parameter {
                    id: r.get(0)?,
                    name: r.get(1)?,
                    unit: r.get(2)?,
                    value: r.get(3)?,
                    sigma: r.get(4)?,
                    estimated: r.get(5)?,
                    determined: r.get(6)?,
                })
            })
            .map_err(|e| self.err(e))?
            .collect::<rusqlite::Result<Vec<_>>>()
            .map_err(|e| self.err(e))?;
        let mut st = self
            .conn
            .prepare("SELECT expression, terms, value, sigma FROM combinations WHERE calibration_id = ?1 ORDER BY expression")
            .map_err(|e| self.err(e))?;
        c.combinations = st
            .query_map([id], |r| {
                let terms: String = r.get(1)?;
                Ok(Combination {
                    expression: r.get(0)?,
                    terms: serde_json::from_str(&terms).unwrap_or_default(),
                    value: r.get(2)?,
                    sigma: r.get(3)?,
                })
            })
            .map_err(|e| self.err(e))?
            .collect::<rusqlite::Result<Vec<_>>>()
            .map_err(|e| self.err(e))?;
        Ok(Some(c))
    }
}
