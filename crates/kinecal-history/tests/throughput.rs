//! Measured, not asserted (ignored by default; the figures are in the README):
//!
//! ```sh
//! eval "$(bash scripts/pg-test-server.sh start)"   # for the PostgreSQL figures
//! cargo test -p kinecal-history --test throughput -- --ignored --nocapture --test-threads 1
//! ```
//!
//! Write throughput (records per second) of one writer and of 20 writers at once (each its own
//! connection, as 20 processes would have), on SQLite and PostgreSQL; and the time of the fleet
//! analysis (read every record, drift, trends, crossings) for 1,000 robots x 20 calibrations.

mod common;

use std::time::Instant;

#[cfg(feature = "postgres")]
use common::pg::TestDb;
use common::report::ge_a4_report;
use kinecal::report::CalibrationReport;
use kinecal::{model::examples, ParamId};
use kinecal_history::{fleet, Database, DriftOptions, FleetOptions, Tolerances};

const T0: i64 = 1_790_000_000;
const DAY: i64 = 86_400;

/// A calibration of the GE A4 on 30 simulated postures (every parameter but the z lengths).
fn report() -> CalibrationReport {
    let params: Vec<ParamId> = (0..38)
        .filter(|i| ![2, 8].contains(i))
        .map(ParamId)
        .collect();
    ge_a4_report(&examples::ge_a4(), 30, 1, &params, Some("data"))
}

/// Records/s of `writers` threads writing `per_writer` records each into `loc`.
fn throughput(loc: &str, writers: usize, per_writer: usize, rep: &CalibrationReport) -> f64 {
    Database::open(loc).unwrap();
    let t = Instant::now();
    std::thread::scope(|s| {
        for w in 0..writers {
            s.spawn(move || {
                let db = Database::open(loc).unwrap();
                for k in 0..per_writer {
                    let robot = format!("T{w}-{}", k % 20);
                    db.add(&robot, Some(T0 + (k as i64) * DAY), rep, "")
                        .unwrap();
                }
            });
        }
    });
    (writers * per_writer) as f64 / t.elapsed().as_secs_f64()
}

/// What keeps a place alive for the measurement: its folder, or its database on the server.
#[allow(dead_code)]
enum Keep {
    Folder(tempfile::TempDir),
    #[cfg(feature = "postgres")]
    Server(TestDb),
}

/// The places measured: a SQLite file, and a database on the test server (with the `postgres`
/// feature, when there is one), as (back end, location, what keeps it).
fn places(tag: &str) -> Vec<(String, String, Keep)> {
    let mut v = Vec::new();
    let dir = tempfile::tempdir().unwrap();
    v.push((
        "sqlite".to_string(),
        dir.path().join("h.sqlite").display().to_string(),
        Keep::Folder(dir),
    ));
    #[cfg(feature = "postgres")]
    if let Some(db) = TestDb::new(tag) {
        v.push(("postgres".to_string(), db.url.clone(), Keep::Server(db)));
    }
    #[cfg(not(feature = "postgres"))]
    let _ = tag;
    v
}

#[test]
#[ignore = "a measurement: run with --ignored --nocapture"]
fn write_throughput() {
    let rep = report();
    eprintln!("report stored: {} bytes of JSON", rep.to_json().len());
    for (name, loc, _keep) in places("throughput1") {
        let one = throughput(&loc, 1, 500, &rep);
        eprintln!("{name}: 1 writer: {one:.0} records/s (500 records)");
    }
    for (name, loc, _keep) in places("throughput20") {
        let many = throughput(&loc, 20, 50, &rep);
        eprintln!("{name}: 20 writers: {many:.0} records/s (1000 records)");
    }
}

#[test]
#[ignore = "a measurement: run with --ignored --nocapture"]
fn fleet_of_1000_robots_with_20_calibrations_each() {
    let rep = report();
    for (name, loc, _keep) in places("fleet1000") {
        let t = Instant::now();
        let db = Database::open(&loc).unwrap();
        if name == "postgres" {
            // As a fleet writes it: 20 writers at once.
            std::thread::scope(|s| {
                for w in 0..20 {
                    let (loc, rep) = (&loc, &rep);
                    s.spawn(move || {
                        let db = Database::open(loc).unwrap();
                        for r in (w..1000).step_by(20) {
                            for k in 0..20i64 {
                                db.add(&format!("R{r:04}"), Some(T0 + k * 30 * DAY), rep, "")
                                    .unwrap();
                            }
                        }
                    });
                }
            });
            eprintln!(
                "{name}: 20,000 records written by 20 writers in {:.1} s",
                t.elapsed().as_secs_f64()
            );
        } else {
            // SQLite checks the whole file (`PRAGMA quick_check`) in every write transaction,
            // so 20,000 single writes cost O(n^2): the file is built from one record, its rows
            // copied in one transaction.
            db.add("R0000", Some(T0), &rep, "").unwrap();
            drop(db);
            let mut c = rusqlite::Connection::open(&loc).unwrap();
            let tx = c.transaction().unwrap();
            for r in 0..1000 {
                for k in 0..20i64 {
                    if r == 0 && k == 0 {
                        continue;
                    }
                    tx.execute(
                        "INSERT INTO calibrations (robot_id, at, robot_name, model_fingerprint, data_fingerprint,
                           method, solution, length_unit, angle_unit, rms_position_before, rms_position_after,
                           rms_orientation_before, rms_orientation_after, note, report, idempotency_key)
                         SELECT ?1, ?2, robot_name, model_fingerprint, data_fingerprint, method, solution,
                           length_unit, angle_unit, rms_position_before, rms_position_after,
                           rms_orientation_before, rms_orientation_after, note, report, ?3
                         FROM calibrations WHERE id = 1",
                        rusqlite::params![format!("R{r:04}"), T0 + k * 30 * DAY, format!("{r}-{k}")],
                    )
                    .unwrap();
                    let id = tx.last_insert_rowid();
                    tx.execute(
                        "INSERT INTO parameters SELECT ?1, param_id, name, unit, value, sigma, estimated, determined FROM parameters WHERE calibration_id = 1",
                        [id],
                    )
                    .unwrap();
                    tx.execute(
                        "INSERT INTO combinations SELECT ?1, expression, terms, value, sigma FROM combinations WHERE calibration_id = 1",
                        [id],
                    )
                    .unwrap();
                }
            }
            tx.commit().unwrap();
        }
        if let (Some(keep), "sqlite") = (std::env::var_os("KINECAL_BENCH_KEEP"), name.as_str()) {
            // To time the command itself: kinecal history fleet --db KEEP.
            std::fs::copy(&loc, keep).unwrap();
        }
        let db = Database::open_read_only(&loc).unwrap();
        let t = Instant::now();
        let records = db.records(None).unwrap();
        let read = t.elapsed().as_secs_f64();
        let events = db.events(None).unwrap();
        let key = rep.combinations[0].expression.clone();
        let opts = FleetOptions {
            drift: DriftOptions {
                tolerances: Tolerances::from_entries(vec![(key, 0.01)]),
                ..Default::default()
            },
            now: T0 + 600 * DAY,
            horizon: 90 * DAY,
        };
        let f = fleet(&records.calibrations, &events, &opts).unwrap();
        assert_eq!(f.len(), 1000);
        eprintln!(
            "{name}: history fleet of 1,000 robots x 20 calibrations: {:.2} s (reading {:.2} s, analysis {:.2} s)",
            t.elapsed().as_secs_f64(),
            read,
            t.elapsed().as_secs_f64() - read
        );
    }
}

/// Builds a history of 1,000 robots x 20 calibrations (20,000 records) at `loc` in one
/// transaction: the rows of one recorded calibration copied (SQL, so that the figures of any
/// kinecal version compare).
fn fleet_size_history(name: &str, loc: &str, rep: &CalibrationReport) {
    let db = Database::open(loc).unwrap();
    db.add("R0000", Some(T0), rep, "").unwrap();
    drop(db);
    let (calibrations, parameters, combinations) = (
        "INSERT INTO {s}calibrations (robot_id, at, robot_name, model_fingerprint, data_fingerprint,
           method, solution, length_unit, angle_unit, rms_position_before, rms_position_after,
           rms_orientation_before, rms_orientation_after, note, report, idempotency_key)
         SELECT {serial}, {t0} + k * 30 * 86400, robot_name, model_fingerprint,
           data_fingerprint, method, solution, length_unit, angle_unit, rms_position_before,
           rms_position_after, rms_orientation_before, rms_orientation_after, note, report,
           r || '-' || k
         FROM {s}calibrations, {series} WHERE id = 1 AND (r, k) <> (0, 0) ORDER BY r, k",
        "INSERT INTO {s}parameters SELECT c.id, param_id, name, unit, value, sigma, estimated, determined
         FROM {s}parameters p, {s}calibrations c WHERE p.calibration_id = 1 AND c.id > 1",
        "INSERT INTO {s}combinations SELECT c.id, expression, terms, value, sigma
         FROM {s}combinations m, {s}calibrations c WHERE m.calibration_id = 1 AND c.id > 1",
    );
    let sql = |q: &str, s: &str, series: &str| {
        let serial = if s.is_empty() {
            "printf('R%04d', r)"
        } else {
            "'R' || lpad(r::text, 4, '0')"
        };
        q.replace("{s}", s)
            .replace("{serial}", serial)
            .replace("{t0}", &T0.to_string())
            .replace("{series}", series)
    };
    if name == "sqlite" {
        let mut c = rusqlite::Connection::open(loc).unwrap();
        let tx = c.transaction().unwrap();
        let series =
            "(WITH RECURSIVE n(v) AS (SELECT 0 UNION ALL SELECT v + 1 FROM n WHERE v < 999)
                       SELECT a.v AS r, b.v AS k FROM n a, n b WHERE b.v < 20)";
        for q in [calibrations, parameters, combinations] {
            tx.execute_batch(&sql(q, "", series)).unwrap();
        }
        tx.commit().unwrap();
    } else {
        #[cfg(feature = "postgres")]
        {
            let mut c = postgres::Client::connect(loc, postgres::NoTls).unwrap();
            let mut tx = c.transaction().unwrap();
            let series = "generate_series(0, 999) r, generate_series(0, 19) k";
            for q in [calibrations, parameters, combinations] {
                tx.batch_execute(&sql(q, "kinecal.", series)).unwrap();
            }
            tx.execute(
                "SELECT setval('kinecal.calibrations_id_seq', (SELECT max(id) FROM kinecal.calibrations))",
                &[],
            )
            .unwrap();
            tx.commit().unwrap();
        }
    }
    let n: usize = Database::open_read_only(loc)
        .unwrap()
        .robots()
        .unwrap()
        .iter()
        .map(|r| r.1 as usize)
        .sum();
    assert_eq!(n, 20_000);
}

/// Records/s of `n` single `history add`s, each as one command runs it: open the history for
/// writing, record one calibration (of a robot with earlier records when the history has them).
fn single_adds(loc: &str, n: usize, rep: &CalibrationReport) -> f64 {
    let t = Instant::now();
    for k in 0..n {
        let db = Database::open(loc).unwrap();
        db.add(
            &format!("R{:04}", k % 1000),
            Some(T0 + 2000 * DAY + k as i64),
            rep,
            "",
        )
        .unwrap();
    }
    n as f64 / t.elapsed().as_secs_f64()
}

/// Issue 39, "history at fleet size": `history add` into a 20,000-record history against a
/// fresh one, on both back ends, in the same run.
#[test]
#[ignore = "a measurement: run with --ignored --nocapture"]
fn add_into_a_fleet_size_history() {
    let rep = report();
    for (name, loc, _keep) in places("fresh") {
        let fresh = single_adds(&loc, 200, &rep);
        eprintln!("{name}: history add into a fresh history: {fresh:.1} records/s (200 adds)");
    }
    for (name, loc, _keep) in places("fleetsize") {
        let t = Instant::now();
        fleet_size_history(&name, &loc, &rep);
        eprintln!(
            "{name}: 20,000 records built in {:.1} s",
            t.elapsed().as_secs_f64()
        );
        if name == "sqlite" {
            let bytes = std::fs::metadata(&loc).unwrap().len();
            eprintln!("sqlite: the file holds {:.0} MB", bytes as f64 / 1e6);
        }
        let n = if name == "sqlite" && std::env::var_os("KINECAL_BENCH_FEW").is_some() {
            10
        } else {
            200
        };
        let full = single_adds(&loc, n, &rep);
        eprintln!(
            "{name}: history add into a 20,000-record history: {full:.1} records/s ({n} adds)"
        );
    }
}
