//! The PostgreSQL store: one history for a fleet, on the server a maintenance team already runs.
//!
//! Built with the `postgres` cargo feature (on by default); without it, a `postgres://`
//! location is refused with [`Error::NoPostgres`] and no PostgreSQL client (nor tokio) is
//! compiled.
//!
//! The client is the synchronous `postgres` crate (rust-postgres): pure Rust, no libpq and no
//! system library at build time, well kept (the most used PostgreSQL client in Rust). It is used
//! without TLS: connect over a trusted network, a VPN, or an SSH tunnel (`ssh -L`); a server that
//! requires TLS (`hostssl` only) refuses the connection with that reason.
//!
//! The location is a URL, `postgres://USER[:PASSWORD]@HOST[:PORT]/DBNAME`. The password comes
//! from the URL, else `PGPASSWORD`, else the password file (`PGPASSFILE`, else `~/.pgpass`,
//! lines `host:port:database:user:password` as libpq reads them); the user from the URL, else
//! `PGUSER`, else the login name; host and port from `PGHOST` and `PGPORT` when the URL has
//! none. The password is never shown: the location is printed without it, and it is removed
//! from every error message.
//!
//! Everything lives in the schema `kinecal` (tables `schema_version`, `calibrations`,
//! `parameters`, `combinations`, `events`), so that access is granted per schema: a read-only
//! role needs `USAGE` on the schema and `SELECT` on its tables; a writer role also `INSERT` on
//! the tables and `USAGE, SELECT, UPDATE` on the sequences. Creating and migrating the schema
//! takes the database owner (or a role with `CREATE` on the database). `docs/history.md` gives
//! the SQL of the roles.
//!
//! Every write is one transaction. A calibration's idempotency key is `UNIQUE`: concurrent
//! writers of the same record (a retried job) leave one row. The model check of a robot's
//! records runs under a transaction-scoped advisory lock per robot, so two writers of the same
//! robot are checked one after the other. The schema is created or migrated under a session's
//! advisory lock, so that concurrent first writers create it once.

use std::collections::{BTreeMap, HashMap};
use std::path::PathBuf;
use std::sync::Mutex;
use std::time::Duration;

use postgres::error::SqlState;
use postgres::{Client, NoTls, Transaction};

use crate::error::{Error, Result};
use crate::location::redact;
use crate::model::{
    Added, Calibration, Combination, DamagedRecord, Event, Parameter, Records, StoredCombination,
    StoredParameter, StoredRecord,
};
use crate::record::{report_figures, rms_errors};
use crate::robot_model::RobotModel;
use crate::store::{in_record, sealed, Access, Backend, Imported, Store, Write, SCHEMA_VERSION};
use crate::text::printable;
use crate::timefmt::format_time;

/// The schema migrations: entry `i` brings the schema from version `i` to `i + 1` (the same
/// versions as the SQLite file's).
const MIGRATIONS: &[&str] = &[
    // 0 -> 1
    "CREATE SCHEMA IF NOT EXISTS kinecal;
    CREATE TABLE kinecal.schema_version (version BIGINT NOT NULL);
    INSERT INTO kinecal.schema_version VALUES (0);
    CREATE TABLE kinecal.calibrations (
        id BIGSERIAL PRIMARY KEY,
        robot_id TEXT NOT NULL,
        at BIGINT NOT NULL,
        robot_name TEXT NOT NULL,
        model_fingerprint TEXT NOT NULL,
        data_fingerprint TEXT NOT NULL,
        method TEXT NOT NULL,
        solution TEXT NOT NULL,
        length_unit TEXT NOT NULL,
        angle_unit TEXT NOT NULL,
        rms_position_before DOUBLE PRECISION NOT NULL,
        rms_position_after DOUBLE PRECISION NOT NULL,
        rms_orientation_before DOUBLE PRECISION NOT NULL,
        rms_orientation_after DOUBLE PRECISION NOT NULL,
        note TEXT NOT NULL,
        report TEXT NOT NULL
    );
    CREATE INDEX calibrations_robot_at ON kinecal.calibrations (robot_id, at);
    CREATE TABLE kinecal.parameters (
        calibration_id BIGINT NOT NULL REFERENCES kinecal.calibrations (id) ON DELETE CASCADE,
        param_id TEXT NOT NULL,
        name TEXT NOT NULL,
        unit TEXT NOT NULL,
        value DOUBLE PRECISION NOT NULL,
        sigma DOUBLE PRECISION,
        estimated BOOLEAN NOT NULL,
        determined BOOLEAN NOT NULL,
        PRIMARY KEY (calibration_id, param_id)
    );
    CREATE TABLE kinecal.combinations (
        calibration_id BIGINT NOT NULL REFERENCES kinecal.calibrations (id) ON DELETE CASCADE,
        expression TEXT NOT NULL,
        terms TEXT NOT NULL,
        value DOUBLE PRECISION NOT NULL,
        sigma DOUBLE PRECISION NOT NULL,
        PRIMARY KEY (calibration_id, expression)
    );",
    // 1 -> 2
    "ALTER TABLE kinecal.calibrations ADD COLUMN idempotency_key TEXT UNIQUE;
    CREATE TABLE kinecal.events (
        id BIGSERIAL PRIMARY KEY,
        robot_id TEXT NOT NULL,
        at BIGINT NOT NULL,
        note TEXT NOT NULL,
        UNIQUE (robot_id, at, note)
    );",
];

/// The advisory lock taken while the schema is created or migrated (any number, fixed).
const MIGRATION_LOCK: i64 = 0x6b69_6e65_6361_6c01;

/// `text` with every occurrence of `secret` (and its percent-encoded form) replaced by `***`.
fn scrub(text: &str, secret: Option<&str>) -> String {
    match secret.filter(|s| !s.is_empty()) {
        Some(s) => {
            let encoded: String = s
                .bytes()
                .map(|b| {
                    if b.is_ascii_alphanumeric() || b"-._~".contains(&b) {
                        (b as char).to_string()
                    } else {
                        format!("%{b:02X}")
                    }
                })
                .collect();
            text.replace(s, "***").replace(&encoded, "***")
        }
        None => text.to_string(),
    }
}

/// The password for `host:port:dbname:user` in a libpq password file, if any.
fn pgpass_lookup(text: &str, host: &str, port: u16, dbname: &str, user: &str) -> Option<String> {
    let port = port.to_string();
    for line in text.lines() {
        if line.trim_start().starts_with('#') || line.trim().is_empty() {
            continue;
        }
        // Fields separated by unescaped colons; `\:` and `\\` escape.
        let mut fields = Vec::new();
        let mut cur = String::new();
        let mut chars = line.chars();
        while let Some(c) = chars.next() {
            match c {
                '\\' => cur.extend(chars.next()),
                ':' if fields.len() < 4 => fields.push(std::mem::take(&mut cur)),
                c => cur.push(c),
            }
        }
        fields.push(cur);
        if fields.len() != 5 {
            continue;
        }
        let ok = |pattern: &str, value: &str| pattern == "*" || pattern == value;
        let host_ok = ok(&fields[0], host)
            || (fields[0] == "localhost" && (host.starts_with('/') || host == "127.0.0.1"));
        if host_ok && ok(&fields[1], &port) && ok(&fields[2], dbname) && ok(&fields[3], user) {
            return Some(fields[4].clone());
        }
    }
    None
}

/// An open PostgreSQL history.
pub(crate) struct PgStore {
    client: Mutex<Client>,
    shown: String,
    secret: Option<String>,
    read_only: bool,
    version: i64,
}

/// A database error's words: the server's message (with its detail and hint), or the client's
/// error and its cause.
fn words(e: &postgres::Error) -> String {
    if let Some(db) = e.as_db_error() {
        return db.to_string();
    }
    let mut s = e.to_string();
    let mut source = std::error::Error::source(e);
    while let Some(c) = source {
        s.push_str(": ");
        s.push_str(&c.to_string());
        source = c.source();
    }
    s
}

impl PgStore {
    /// Connects to the server named by `url`. For writing, creates the schema or migrates it;
    /// for reading only, sets the session read-only and refuses a database without a kinecal
    /// history ([`Error::NoDatabase`]). A newer schema is refused with the version it is at
    /// ([`Error::NewerSchema`]).
    pub(crate) fn open(url: &str, access: Access) -> Result<PgStore> {
        let read_only = access == Access::ReadOnly;
        let shown = redact(url);
        let mut config: postgres::Config =
            url.trim()
                .parse()
                .map_err(|e: postgres::Error| Error::Database {
                    path: shown.clone(),
                    message: format!(
                        "not a PostgreSQL URL ({}); expected postgres://USER@HOST:PORT/DBNAME",
                        words(&e)
                    ),
                })?;
        let env = |k: &str| std::env::var(k).ok().filter(|v| !v.is_empty());
        if config.get_user().is_none() {
            let user = env("PGUSER")
                .or_else(|| env("USER"))
                .or_else(|| env("LOGNAME"))
                .ok_or_else(|| Error::Database {
                    path: shown.clone(),
                    message:
                        "no user name: put it in the URL (postgres://USER@HOST/DBNAME) or PGUSER"
                            .into(),
                })?;
            config.user(&user);
        }
        if config.get_hosts().is_empty() {
            config.host(&env("PGHOST").unwrap_or_else(|| "localhost".into()));
        }
        if config.get_ports().is_empty() {
            if let Some(p) = env("PGPORT").and_then(|p| p.parse().ok()) {
                config.port(p);
            }
        }
        let user = config.get_user().unwrap_or_default().to_string();
        if config.get_dbname().is_none() {
            config.dbname(&env("PGDATABASE").unwrap_or_else(|| user.clone()));
        }
        if config.get_password().is_none() {
            let password = env("PGPASSWORD").or_else(|| {
                let file = env("PGPASSFILE").map(PathBuf::from).or_else(|| {
                    std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".pgpass"))
                })?;
                let text = std::fs::read_to_string(file).ok()?;
                let host = match config.get_hosts().first()? {
                    postgres::config::Host::Tcp(h) => h.clone(),
                    #[cfg(unix)]
                    postgres::config::Host::Unix(p) => p.display().to_string(),
                };
                let port = config.get_ports().first().copied().unwrap_or(5432);
                pgpass_lookup(
                    &text,
                    &host,
                    port,
                    config.get_dbname().unwrap_or_default(),
                    &user,
                )
            });
            if let Some(p) = password {
                config.password(p);
            }
        }
        let secret = config
            .get_password()
            .map(|p| String::from_utf8_lossy(p).into_owned());
        // No JIT: a history's statements are small, and a table without statistics yet (after
        // an import) makes the planner's estimates large enough to compile each one (15 ms a
        // statement, 0.2 s a write at 20,000 records).
        config
            .connect_timeout(Duration::from_secs(10))
            .application_name("kinecal")
            .options("-c jit=off");
        let fail = |m: String| Error::Database {
            path: shown.clone(),
            message: scrub(&m, secret.as_deref()),
        };
        let mut client = config.connect(NoTls).map_err(|e| {
            let mut m = format!("cannot connect: {}", words(&e));
            if e.code() == Some(&SqlState::INVALID_PASSWORD) {
                m.push_str(" (the password comes from the URL, PGPASSWORD or ~/.pgpass)");
            }
            fail(m)
        })?;
        if read_only {
            client
                .batch_execute("SET SESSION CHARACTERISTICS AS TRANSACTION READ ONLY")
                .map_err(|e| fail(words(&e)))?;
        }
        let mut store = PgStore {
            client: Mutex::new(client),
            shown: shown.clone(),
            secret,
            read_only,
            version: 0,
        };
        let version = store.read_version()?;
        if version > SCHEMA_VERSION {
            return Err(Error::NewerSchema {
                path: shown,
                found: version,
                supported: SCHEMA_VERSION,
            });
        }
        if read_only {
            if version == 0 {
                return Err(Error::NoDatabase { path: shown });
            }
            store.version = version;
        } else {
            store.migrate()?;
            store.version = SCHEMA_VERSION;
        }
        Ok(store)
    }

    fn err(&self, e: postgres::Error) -> Error {
        let mut m = words(&e);
        match e.code() {
            Some(c) if *c == SqlState::INSUFFICIENT_PRIVILEGE => {
                m = format!(
                    "permission denied: this role may not do that ({m}); writes need the writer \
                     role (kinecal_writer in docs/history.md, \"A fleet's history on a PostgreSQL server\"); \
                     nothing was written"
                );
            }
            Some(c) if *c == SqlState::READ_ONLY_SQL_TRANSACTION => {
                m = "opened for reading only; nothing was written".into();
            }
            _ => {}
        }
        Error::Database {
            path: self.shown.clone(),
            message: scrub(&m, self.secret.as_deref()),
        }
    }

    fn client(&self) -> std::sync::MutexGuard<'_, Client> {
        self.client.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// The schema version: 0 without a `kinecal` schema. A `kinecal` schema without its
    /// version table is not kinecal's ([`Error::Foreign`]).
    fn read_version(&self) -> Result<i64> {
        let mut c = self.client();
        let row = c
            .query_one(
                "SELECT to_regnamespace('kinecal') IS NOT NULL, to_regclass('kinecal.schema_version') IS NOT NULL",
                &[],
            )
            .map_err(|e| self.err(e))?;
        let (schema, table): (bool, bool) = (row.get(0), row.get(1));
        if !schema {
            return Ok(0);
        }
        if !table {
            let tables: i64 = c
                .query_one(
                    "SELECT count(*) FROM pg_tables WHERE schemaname = 'kinecal'",
                    &[],
                )
                .map_err(|e| self.err(e))?
                .get(0);
            if tables == 0 {
                return Ok(0);
            }
            return Err(Error::Foreign {
                path: self.shown.clone(),
                reason: "its schema `kinecal` holds tables but no kinecal schema version".into(),
            });
        }
        let v = c
            .query_opt("SELECT max(version) FROM kinecal.schema_version", &[])
            .map_err(|e| self.err(e))?
            .and_then(|r| r.get::<_, Option<i64>>(0));
        Ok(v.unwrap_or(0))
    }

    /// Creates or migrates the schema, under an advisory lock: concurrent first writers wait
    /// for each other, and the version is read again once the lock is held.
    ///
    /// The lock is the session's, taken before the migration's transaction begins. A
    /// transaction that waited for a transaction-scoped lock would still see the catalog as it
    /// was when it began (PostgreSQL takes in other sessions' catalog changes when a
    /// transaction starts, not when an advisory lock is granted; this connection's version read
    /// has cached the schema as missing): it would create the schema a second time and fail
    /// with "relation schema_version already exists".
    fn migrate(&self) -> Result<()> {
        let mut c = self.client();
        c.execute("SELECT pg_advisory_lock($1)", &[&MIGRATION_LOCK])
            .map_err(|e| self.err(e))?;
        let migrated = self.migrate_locked(&mut c);
        let unlocked = c.execute("SELECT pg_advisory_unlock($1)", &[&MIGRATION_LOCK]);
        migrated?;
        unlocked.map(|_| ()).map_err(|e| self.err(e))
    }

    /// [`PgStore::migrate`] once the migration lock is held.
    fn migrate_locked(&self, c: &mut Client) -> Result<()> {
        let mut tx = c.transaction().map_err(|e| self.err(e))?;
        let exists: bool = tx
            .query_one(
                "SELECT to_regclass('kinecal.schema_version') IS NOT NULL",
                &[],
            )
            .map_err(|e| self.err(e))?
            .get(0);
        let version: i64 = if exists {
            tx.query_one("SELECT max(version) FROM kinecal.schema_version", &[])
                .map_err(|e| self.err(e))?
                .get::<_, Option<i64>>(0)
                .unwrap_or(0)
        } else {
            0
        };
        if version > SCHEMA_VERSION {
            return Err(Error::NewerSchema {
                path: self.shown.clone(),
                found: version,
                supported: SCHEMA_VERSION,
            });
        }
        if version == SCHEMA_VERSION {
            return Ok(());
        }
        for (k, sql) in MIGRATIONS.iter().enumerate().skip(version as usize) {
            tx.batch_execute(sql).map_err(|e| {
                let denied = e.code() == Some(&SqlState::INSUFFICIENT_PRIVILEGE);
                let mut e = self.err(e);
                if denied {
                    if let Error::Database { message, .. } = &mut e {
                        *message = format!(
                            "the history's schema is at version {version}; bringing it to version \
                             {SCHEMA_VERSION} takes the database owner: run `kinecal history init \
                             --db URL` as the owner once ({message})"
                        );
                    }
                } else if let Error::Database { message, .. } = &mut e {
                    *message = format!("migration to version {}: {message}", k + 1);
                }
                e
            })?;
        }
        tx.execute(
            "UPDATE kinecal.schema_version SET version = $1",
            &[&SCHEMA_VERSION],
        )
        .map_err(|e| self.err(e))?;
        tx.commit().map_err(|e| self.err(e))
    }

    fn key_column(&self) -> &'static str {
        if self.version >= 2 {
            "idempotency_key"
        } else {
            "NULL::text"
        }
    }

    /// The stored records selected by `filter` (`""`, or a `WHERE` on `c`), with their
    /// parameters and combinations, in one read-only snapshot; unordered.
    fn read_stored(
        &self,
        filter: &str,
        args: &[&(dyn postgres::types::ToSql + Sync)],
    ) -> Result<Vec<StoredRecord>> {
        if self.version == 0 {
            return Ok(Vec::new());
        }
        let mut c = self.client();
        let mut tx = c
            .build_transaction()
            .isolation_level(postgres::IsolationLevel::RepeatableRead)
            .read_only(true)
            .start()
            .map_err(|e| self.err(e))?;
        let mut out: Vec<StoredRecord> = Vec::new();
        let mut index: HashMap<i64, usize> = HashMap::new();
        let rows = tx
            .query(
                &format!(
                    "SELECT c.id, c.{}, c.robot_id, c.at, c.robot_name, c.model_fingerprint, c.data_fingerprint,
                            c.method, c.solution, c.length_unit, c.angle_unit, c.rms_position_before,
                            c.rms_position_after, c.rms_orientation_before, c.rms_orientation_after,
                            c.note, c.report
                     FROM kinecal.calibrations c {filter}",
                    self.key_column()
                ),
                args,
            )
            .map_err(|e| self.err(e))?;
        for r in rows {
            index.insert(r.get(0), out.len());
            out.push(StoredRecord {
                id: r.get(0),
                key: r.get(1),
                robot_id: r.get(2),
                at: r.get(3),
                robot_name: r.get(4),
                model_fingerprint: r.get(5),
                data_fingerprint: r.get(6),
                method: r.get(7),
                solution: r.get(8),
                length_unit: r.get(9),
                angle_unit: r.get(10),
                rms_position_before: r.get(11),
                rms_position_after: r.get(12),
                rms_orientation_before: r.get(13),
                rms_orientation_after: r.get(14),
                note: r.get(15),
                report: r.get(16),
                parameters: Vec::new(),
                combinations: Vec::new(),
            });
        }
        let rows = tx
            .query(
                &format!(
                    "SELECT p.calibration_id, p.param_id, p.name, p.unit, p.value, p.sigma, p.estimated, p.determined
                     FROM kinecal.parameters p JOIN kinecal.calibrations c ON c.id = p.calibration_id {filter}"
                ),
                args,
            )
            .map_err(|e| self.err(e))?;
        for r in rows {
            if let Some(&k) = index.get(&r.get::<_, i64>(0)) {
                out[k].parameters.push(StoredParameter {
                    id: r.get(1),
                    name: r.get(2),
                    unit: r.get(3),
                    value: r.get(4),
                    sigma: r.get(5),
                    estimated: r.get(6),
                    determined: r.get(7),
                });
            }
        }
        let rows = tx
            .query(
                &format!(
                    "SELECT m.calibration_id, m.expression, m.terms, m.value, m.sigma
                     FROM kinecal.combinations m JOIN kinecal.calibrations c ON c.id = m.calibration_id {filter}"
                ),
                args,
            )
            .map_err(|e| self.err(e))?;
        for r in rows {
            if let Some(&k) = index.get(&r.get::<_, i64>(0)) {
                out[k].combinations.push(StoredCombination {
                    expression: r.get(1),
                    terms: r.get(2),
                    value: r.get(3),
                    sigma: r.get(4),
                });
            }
        }
        tx.commit().map_err(|e| self.err(e))?;
        for r in &mut out {
            r.parameters.sort_by_key(|p| param_number(&p.id));
            r.combinations
                .sort_by(|a, b| a.expression.as_bytes().cmp(b.expression.as_bytes()));
        }
        Ok(out)
    }

    /// Refuses `rec`'s model unless it is the model of one of its robot's earlier records (or
    /// the robot has none): reads the robot's records, not the table.
    fn check_model(&self, tx: &mut Transaction<'_>, rec: &StoredRecord) -> Result<()> {
        tx.execute(
            "SELECT pg_advisory_xact_lock(hashtextextended($1, 0))",
            &[&rec.robot_id],
        )
        .map_err(|e| self.err(e))?;
        let rows = tx
            .query(
                // The robot's records by their index, then each one's parameters by theirs
                // (`OFFSET 0` keeps the planner from making it one join, which it answers with
                // a scan of every parameter row while the tables have no statistics yet, as
                // after an import: 0.1 s a write at 20,000 records).
                "SELECT c.id, p.name, p.unit FROM kinecal.calibrations c
                 CROSS JOIN LATERAL (SELECT name, unit FROM kinecal.parameters
                     WHERE calibration_id = c.id OFFSET 0) p
                 WHERE c.robot_id = $1",
                &[&rec.robot_id],
            )
            .map_err(|e| self.err(e))?;
        let mut earlier: BTreeMap<i64, RobotModel> = BTreeMap::new();
        for r in rows {
            earlier
                .entry(r.get(0))
                .or_default()
                .add_parameter(r.get(1), r.get(2));
        }
        RobotModel::of_parameters(&rec.parameters).check_against(&rec.robot_id, &earlier)
    }

    /// Writes `rec` within `tx` (not committed).
    fn insert_in(
        &self,
        tx: &mut Transaction<'_>,
        rec: &StoredRecord,
        write: Write,
    ) -> Result<Added> {
        let existing = |tx: &mut Transaction<'_>| -> Result<Option<i64>> {
            match &rec.key {
                Some(key) => Ok(tx
                    .query_opt(
                        "SELECT id FROM kinecal.calibrations WHERE idempotency_key = $1",
                        &[key],
                    )
                    .map_err(|e| self.err(e))?
                    .map(|r| r.get(0))),
                None => Ok(None),
            }
        };
        if let Some(id) = existing(tx)? {
            return Ok(Added { id, new: false });
        }
        let mut id: Option<i64> = None;
        match write {
            Write::New { force } => {
                if !force {
                    self.check_model(tx, rec)?;
                }
            }
            Write::Import => {
                let same = tx
                    .query_opt(
                        "SELECT robot_id, at, report FROM kinecal.calibrations WHERE id = $1",
                        &[&rec.id],
                    )
                    .map_err(|e| self.err(e))?;
                match same {
                    Some(r)
                        if r.get::<_, String>(0) == rec.robot_id
                            && r.get::<_, i64>(1) == rec.at
                            && r.get::<_, String>(2) == rec.report =>
                    {
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
        let row = self
            .serial_insert(
                tx,
                "calibrations",
                "INSERT INTO kinecal.calibrations (id, robot_id, at, robot_name, model_fingerprint, data_fingerprint,
                    method, solution, length_unit, angle_unit, rms_position_before, rms_position_after,
                    rms_orientation_before, rms_orientation_after, note, report, idempotency_key)
                 VALUES (COALESCE($1, nextval('kinecal.calibrations_id_seq')), $2, $3, $4, $5, $6, $7, $8, $9,
                    $10, $11, $12, $13, $14, $15, $16, $17)
                 ON CONFLICT (idempotency_key) DO NOTHING RETURNING id",
                &[
                    &id,
                    &rec.robot_id,
                    &rec.at,
                    &rec.robot_name,
                    &rec.model_fingerprint,
                    &rec.data_fingerprint,
                    &rec.method,
                    &rec.solution,
                    &rec.length_unit,
                    &rec.angle_unit,
                    &rec.rms_position_before,
                    &rec.rms_position_after,
                    &rec.rms_orientation_before,
                    &rec.rms_orientation_after,
                    &rec.note,
                    &rec.report,
                    &rec.key,
                ],
            )?;
        let Some(row) = row else {
            // Another writer recorded the same calibration meanwhile (committed: this
            // statement sees it).
            let id = existing(tx)?.ok_or_else(|| Error::Database {
                path: self.shown.clone(),
                message: "the record's key was taken by a record that cannot be found".into(),
            })?;
            return Ok(Added { id, new: false });
        };
        let new_id: i64 = row.get(0);
        let p = &rec.parameters;
        let col = |f: fn(&StoredParameter) -> String| p.iter().map(f).collect::<Vec<String>>();
        let (ids, names, units) = (
            col(|p| p.id.clone()),
            col(|p| p.name.clone()),
            col(|p| p.unit.clone()),
        );
        let values: Vec<f64> = p.iter().map(|p| p.value).collect();
        let sigmas: Vec<Option<f64>> = p.iter().map(|p| p.sigma).collect();
        let estimated: Vec<bool> = p.iter().map(|p| p.estimated).collect();
        let determined: Vec<bool> = p.iter().map(|p| p.determined).collect();
        tx.execute(
            "INSERT INTO kinecal.parameters (calibration_id, param_id, name, unit, value, sigma, estimated, determined)
             SELECT $1, * FROM unnest($2::text[], $3::text[], $4::text[], $5::float8[], $6::float8[], $7::bool[], $8::bool[])",
            &[&new_id, &ids, &names, &units, &values, &sigmas, &estimated, &determined],
        )
        .map_err(|e| self.err(e))?;
        let m = &rec.combinations;
        let expressions: Vec<&str> = m.iter().map(|c| c.expression.as_str()).collect();
        let terms: Vec<&str> = m.iter().map(|c| c.terms.as_str()).collect();
        let values: Vec<f64> = m.iter().map(|c| c.value).collect();
        let sigmas: Vec<f64> = m.iter().map(|c| c.sigma).collect();
        tx.execute(
            "INSERT INTO kinecal.combinations (calibration_id, expression, terms, value, sigma)
             SELECT $1, * FROM unnest($2::text[], $3::text[], $4::float8[], $5::float8[])",
            &[&new_id, &expressions, &terms, &values, &sigmas],
        )
        .map_err(|e| self.err(e))?;
        if id.is_some() {
            // An id given by the dump: the sequence moves past it.
            self.move_past(tx, "calibrations", new_id)?;
        }
        Ok(Added {
            id: new_id,
            new: true,
        })
    }

    /// Writes the event `e` within `tx` (not committed).
    fn insert_event_in(&self, tx: &mut Transaction<'_>, e: &Event, write: Write) -> Result<Added> {
        let id: Option<i64> = match write {
            Write::Import => {
                let taken = tx
                    .query_opt("SELECT 1 FROM kinecal.events WHERE id = $1", &[&e.id])
                    .map_err(|x| self.err(x))?;
                taken.is_none().then_some(e.id)
            }
            Write::New { .. } => None,
        };
        let row = self.serial_insert(
            tx,
            "events",
            "INSERT INTO kinecal.events (id, robot_id, at, note)
             VALUES (COALESCE($1, nextval('kinecal.events_id_seq')), $2, $3, $4)
             ON CONFLICT (robot_id, at, note) DO NOTHING RETURNING id",
            &[&id, &e.robot_id, &e.at, &e.note],
        )?;
        let added = match row {
            Some(r) => Added {
                id: r.get(0),
                new: true,
            },
            None => Added {
                id: tx
                    .query_one(
                        "SELECT id FROM kinecal.events WHERE robot_id = $1 AND at = $2 AND note = $3",
                        &[&e.robot_id, &e.at, &e.note],
                    )
                    .map_err(|x| self.err(x))?
                    .get(0),
                new: false,
            },
        };
        if added.new && id.is_some() {
            // An id given by the dump: the sequence moves past it.
            self.move_past(tx, "events", added.id)?;
        }
        Ok(added)
    }

    /// Moves the id sequence of `table` past `id`, unless it is past it already. (A sequence
    /// never used hands out its `last_value` next: `is_called` says whether it was.)
    fn move_past(&self, tx: &mut Transaction<'_>, table: &str, id: i64) -> Result<()> {
        tx.execute(
            &format!(
                "SELECT setval('kinecal.{table}_id_seq', $1) FROM kinecal.{table}_id_seq
                 WHERE $1 > CASE WHEN is_called THEN last_value ELSE last_value - 1 END"
            ),
            &[&id],
        )
        .map(|_| ())
        .map_err(|e| self.err(e))
    }

    /// Runs `insert` (a row of `table` whose id is `COALESCE($1, nextval(...))`), and returns
    /// its row. When the sequence hands out an id a row already has (a history imported by a
    /// kinecal that did not move the sequence past the imported ids), the sequence is moved
    /// past every id of the table and the row inserted again: the write succeeds.
    fn serial_insert(
        &self,
        tx: &mut Transaction<'_>,
        table: &str,
        insert: &str,
        args: &[&(dyn postgres::types::ToSql + Sync)],
    ) -> Result<Option<postgres::Row>> {
        let mut retried = false;
        loop {
            let mut sp = tx.transaction().map_err(|e| self.err(e))?;
            match sp.query_opt(insert, args) {
                Ok(row) => {
                    sp.commit().map_err(|e| self.err(e))?;
                    return Ok(row);
                }
                Err(e)
                    if !retried
                        && e.code() == Some(&SqlState::UNIQUE_VIOLATION)
                        && e.as_db_error().and_then(|d| d.constraint())
                            == Some(&format!("{table}_pkey")) =>
                {
                    drop(sp);
                    retried = true;
                    tx.execute(
                        &format!(
                            "SELECT setval('kinecal.{table}_id_seq', GREATEST(
                                 (SELECT max(id) FROM kinecal.{table}),
                                 (SELECT last_value FROM kinecal.{table}_id_seq)))"
                        ),
                        &[],
                    )
                    .map_err(|e| self.err(e))?;
                }
                Err(e) => return Err(self.err(e)),
            }
        }
    }

    fn refuse_if_read_only(&self) -> Result<()> {
        if self.read_only {
            return Err(Error::Database {
                path: self.shown.clone(),
                message: "opened for reading only; nothing was written".into(),
            });
        }
        Ok(())
    }
}

impl sealed::Sealed for PgStore {}

impl Store for PgStore {
    fn location(&self) -> &str {
        &self.shown
    }

    fn backend(&self) -> Backend {
        Backend::Postgres
    }

    fn schema_version(&self) -> i64 {
        self.version
    }

    fn insert(&self, rec: &StoredRecord, write: Write) -> Result<Added> {
        self.refuse_if_read_only()?;
        let mut c = self.client();
        let mut tx = c.transaction().map_err(|e| self.err(e))?;
        let added = self.insert_in(&mut tx, rec, write)?;
        tx.commit().map_err(|e| self.err(e))?;
        Ok(added)
    }

    fn import(&self, records: &[StoredRecord], events: &[Event]) -> Result<Imported> {
        self.refuse_if_read_only()?;
        let mut c = self.client();
        let mut tx = c.transaction().map_err(|e| self.err(e))?;
        let mut out: Imported = (Vec::new(), Vec::new());
        for rec in records {
            out.0.push(
                self.insert_in(&mut tx, rec, Write::Import)
                    .map_err(|e| in_record(e, rec))?,
            );
        }
        for e in events {
            out.1.push(self.insert_event_in(&mut tx, e, Write::Import)?);
        }
        tx.commit().map_err(|e| self.err(e))?;
        Ok(out)
    }

    fn robots(&self) -> Result<Vec<(String, i64)>> {
        if self.version == 0 {
            return Ok(Vec::new());
        }
        let rows = self
            .client()
            .query(
                "SELECT robot_id, count(*) FROM kinecal.calibrations GROUP BY robot_id ORDER BY robot_id COLLATE \"C\"",
                &[],
            )
            .map_err(|e| self.err(e))?;
        Ok(rows.iter().map(|r| (r.get(0), r.get(1))).collect())
    }

    fn records(&self, robot_id: Option<&str>) -> Result<Records> {
        let mut stored = match robot_id {
            Some(r) => self.read_stored("WHERE c.robot_id = $1", &[&r])?,
            None => self.read_stored("", &[])?,
        };
        stored.sort_by(|a, b| {
            (a.robot_id.as_bytes(), a.at, a.id).cmp(&(b.robot_id.as_bytes(), b.at, b.id))
        });
        let mut out = Records::default();
        for r in stored {
            let id = r.id;
            match to_calibration(r) {
                Ok(c) => out.calibrations.push(c),
                Err(problem) => out.damaged.push(DamagedRecord { id, problem }),
            }
        }
        out.damaged.sort_by_key(|d| d.id);
        Ok(out)
    }

    fn calibration(&self, id: i64) -> Result<Option<Calibration>> {
        match self.read_stored("WHERE c.id = $1", &[&id])?.pop() {
            None => Ok(None),
            Some(r) => to_calibration(r)
                .map(Some)
                .map_err(|problem| Error::DamagedRecord {
                    path: self.shown.clone(),
                    id,
                    problem,
                }),
        }
    }

    fn insert_event(&self, e: &Event, write: Write) -> Result<Added> {
        self.refuse_if_read_only()?;
        let mut c = self.client();
        let mut tx = c.transaction().map_err(|x| self.err(x))?;
        let added = self.insert_event_in(&mut tx, e, write)?;
        tx.commit().map_err(|x| self.err(x))?;
        Ok(added)
    }

    fn events(&self, robot_id: Option<&str>) -> Result<Vec<Event>> {
        if self.version < 2 {
            return Ok(Vec::new());
        }
        let rows = match robot_id {
            Some(r) => self.client().query(
                "SELECT id, robot_id, at, note FROM kinecal.events WHERE robot_id = $1 ORDER BY at, id",
                &[&r],
            ),
            None => self.client().query(
                "SELECT id, robot_id, at, note FROM kinecal.events ORDER BY at, id",
                &[],
            ),
        }
        .map_err(|e| self.err(e))?;
        Ok(rows
            .iter()
            .map(|r| Event {
                id: r.get(0),
                robot_id: r.get(1),
                at: r.get(2),
                note: r.get(3),
            })
            .collect())
    }

    fn stored_records(&self) -> Result<Vec<StoredRecord>> {
        let mut v = self.read_stored("", &[])?;
        v.sort_by_key(|r| r.id);
        Ok(v)
    }
}

/// The number of a parameter id (`p14` -> 14), for ordering.
fn param_number(id: &str) -> i64 {
    id.strip_prefix('p')
        .and_then(|n| n.parse().ok())
        .unwrap_or(0)
}

/// A stored record read as a [`Calibration`], or the sentence naming its damaged field.
fn to_calibration(r: StoredRecord) -> std::result::Result<Calibration, String> {
    let report = report_figures(&r.report)?;
    let finite = |v: f64, what: &str| {
        if v.is_finite() {
            Ok(v)
        } else {
            Err(format!("{what} is not a finite number"))
        }
    };
    let mut parameters: Vec<Parameter> = Vec::with_capacity(r.parameters.len());
    for p in r.parameters {
        let f = |what: &str| format!("parameter {}'s {what}", printable(&p.id));
        parameters.push(Parameter {
            value: finite(p.value, &f("value"))?,
            sigma: p.sigma.map(|s| finite(s, &f("sigma"))).transpose()?,
            id: p.id,
            name: p.name,
            unit: p.unit,
            estimated: p.estimated,
            determined: p.determined,
        });
    }
    parameters.sort_by_key(|p| param_number(&p.id));
    let mut combinations = Vec::with_capacity(r.combinations.len());
    for c in r.combinations {
        let f = |what: &str| format!("combination `{}`'s {what}", printable(&c.expression));
        let terms: Vec<(String, String, f64)> = serde_json::from_str(&c.terms)
            .map_err(|e| format!("{} are not valid JSON ({e})", f("terms")))?;
        combinations.push(Combination {
            terms,
            value: finite(c.value, &f("value"))?,
            sigma: finite(c.sigma, &f("sigma"))?,
            expression: c.expression,
        });
    }
    combinations.sort_by(|a, b| a.expression.as_bytes().cmp(b.expression.as_bytes()));
    Ok(Calibration {
        errors: rms_errors(&report, &r.length_unit, &r.angle_unit),
        id: r.id,
        robot_id: r.robot_id,
        at: r.at,
        at_text: format_time(r.at),
        robot_name: r.robot_name,
        model_fingerprint: r.model_fingerprint,
        data_fingerprint: r.data_fingerprint,
        method: r.method,
        solution: r.solution,
        length_unit: r.length_unit,
        angle_unit: r.angle_unit,
        rms_position_before: finite(r.rms_position_before, "its RMS position error before")?,
        rms_position_after: finite(r.rms_position_after, "its RMS position error after")?,
        rms_orientation_before: finite(r.rms_orientation_before, "its RMS attitude error before")?,
        rms_orientation_after: finite(r.rms_orientation_after, "its RMS attitude error after")?,
        note: r.note,
        parameters,
        combinations,
    })
}

#[cfg(test)]
mod tests {
    use super::{pgpass_lookup, scrub};

    #[test]
    fn passwords_are_scrubbed_from_messages() {
        assert_eq!(
            scrub("bad s3cr@t and s3cr%40t", Some("s3cr@t")),
            "bad *** and ***"
        );
    }

    #[test]
    fn password_file_lines_match_as_libpq_matches_them() {
        let file =
            "# comment\nother:5432:*:alice:no\ndb.plant:*:kinecal:alice:pa\\:ss\n*:*:*:*:any\n";
        assert_eq!(
            pgpass_lookup(file, "db.plant", 5433, "kinecal", "alice").as_deref(),
            Some("pa:ss")
        );
        assert_eq!(
            pgpass_lookup(file, "x", 1, "y", "z").as_deref(),
            Some("any")
        );
        assert_eq!(pgpass_lookup("h:1:d:u:p\n", "h", 2, "d", "u"), None);
    }
}
