//! Database faults: concurrent writers, a writer killed mid-transaction, a newer schema, a
//! corrupt file, a read-only location. Each behaves as documented, and no data is lost.

mod common;

use std::path::Path;
use std::time::{Duration, Instant};

use common::report::ge_a4_report;
use kinecal::report::CalibrationReport;
use kinecal::{model::examples, ParamId};
use kinecal_history::{Database, Error};

/// A calibration of the GE A4 (link 1's x and y) on simulated data.
fn report() -> CalibrationReport {
    ge_a4_report(&examples::ge_a4(), 10, 1, &[ParamId(0), ParamId(1)], None)
}

fn count(path: &Path) -> i64 {
    let c = rusqlite::Connection::open(path).unwrap();
    let ok: String = c
        .query_row("PRAGMA integrity_check", [], |r| r.get(0))
        .unwrap();
    assert_eq!(ok, "ok");
    c.query_row("SELECT count(*) FROM calibrations", [], |r| r.get(0))
        .unwrap()
}

#[test]
fn records_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let db = Database::open(dir.path().join("sub/folder/h.sqlite")).unwrap();
    let rep = report();
    let id = db.add("R1", Some(1_790_000_000), &rep, "first").unwrap();
    let c = db.calibration(id).unwrap().unwrap();
    assert_eq!(
        (c.robot_id.as_str(), c.note.as_str(), c.at),
        ("R1", "first", 1_790_000_000)
    );
    assert_eq!(c.parameters.len(), 38);
    let p1 = &c.parameters[0];
    assert_eq!(
        (
            p1.id.as_str(),
            p1.name.as_str(),
            p1.estimated,
            p1.determined
        ),
        ("p1", "link1.x", true, true)
    );
    assert!(
        (p1.value - rep.parameters[0].estimated).abs() < 1e-15
            && p1.sigma == rep.parameters[0].sigma
    );
    assert!(!c.parameters[2].estimated);
    assert_eq!(db.robots().unwrap(), vec![("R1".to_string(), 1)]);
    // The stored report is the report but for the chart of every observation.
    assert!(rep.observation_errors.is_some());
    let stored: String = rusqlite::Connection::open(dir.path().join("sub/folder/h.sqlite"))
        .unwrap()
        .query_row("SELECT report FROM calibrations WHERE id = ?1", [id], |r| {
            r.get(0)
        })
        .unwrap();
    let stored = CalibrationReport::from_json(&stored).unwrap();
    let mut kept = rep.clone();
    kept.observation_errors = None;
    assert_eq!(stored, kept);
    assert!(db.add(" ", None, &rep, "").is_err());
}

#[test]
fn concurrent_writers_all_succeed() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("h.sqlite");
    Database::open(&path).unwrap();
    let rep = report();
    let threads: Vec<_> = (0..4)
        .map(|t| {
            let (path, rep) = (path.clone(), rep.clone());
            std::thread::spawn(move || {
                // Each thread its own connection, as separate processes would have.
                let db = Database::open(&path).unwrap();
                for k in 0..25 {
                    db.add(&format!("R{t}"), Some(1_790_000_000 + k), &rep, "")
                        .unwrap();
                }
            })
        })
        .collect();
    for t in threads {
        t.join().unwrap();
    }
    assert_eq!(count(&path), 100);
}

/// Run by `killed_writer_leaves_the_database_consistent` in a child process: open a write
/// transaction, insert, signal, and hang until killed.
#[test]
fn killed_writer_child() {
    let Some(path) = std::env::var_os("KINECAL_TEST_CHILD_DB") else {
        return;
    };
    let mut c = rusqlite::Connection::open(&path).unwrap();
    let tx = c
        .transaction_with_behavior(rusqlite::TransactionBehavior::Immediate)
        .unwrap();
    for _ in 0..100 {
        tx.execute("INSERT INTO calibrations (robot_id, at, robot_name, model_fingerprint, data_fingerprint, method, solution, length_unit, angle_unit, rms_position_before, rms_position_after, rms_orientation_before, rms_orientation_after, note, report) VALUES ('X', 0, '', '', '', '', '', '', '', 0, 0, 0, 0, '', '')", []).unwrap();
    }
    std::fs::write(Path::new(&path).with_extension("ready"), "").unwrap();
    std::thread::sleep(Duration::from_secs(60));
    drop(tx);
}

#[test]
fn killed_writer_leaves_the_database_consistent() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("h.sqlite");
    let db = Database::open(&path).unwrap();
    db.add("R", Some(1), &report(), "kept").unwrap();
    drop(db);
    let mut child = std::process::Command::new(std::env::current_exe().unwrap())
        .args(["--exact", "killed_writer_child", "--nocapture"])
        .env("KINECAL_TEST_CHILD_DB", &path)
        .stdout(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let ready = path.with_extension("ready");
    let t0 = Instant::now();
    while !ready.exists() {
        assert!(
            t0.elapsed() < Duration::from_secs(30),
            "the child never got the write lock"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    child.kill().unwrap(); // SIGKILL mid-transaction
    child.wait().unwrap();
    // The half-done transaction is gone, the earlier record is intact, and writing works.
    assert_eq!(count(&path), 1);
    let db = Database::open(&path).unwrap();
    assert_eq!(db.calibrations(Some("R")).unwrap()[0].note, "kept");
    db.add("R", Some(2), &report(), "").unwrap();
    assert_eq!(count(&path), 2);
}

#[test]
fn newer_schema_and_foreign_files_are_refused_untouched() {
    let dir = tempfile::tempdir().unwrap();
    // A database from a newer kinecal.
    let newer = dir.path().join("newer.sqlite");
    Database::open(&newer)
        .unwrap()
        .add("R", Some(1), &report(), "")
        .unwrap();
    {
        let c = rusqlite::Connection::open(&newer).unwrap();
        c.execute_batch("PRAGMA journal_mode = DELETE; PRAGMA user_version = 99;")
            .unwrap();
    }
    let before = std::fs::read(&newer).unwrap();
    match Database::open(&newer) {
        Err(Error::NewerSchema { found: 99, .. }) => {}
        Err(e) => panic!("unexpected error {e}"),
        Ok(_) => panic!("opened a newer schema"),
    }
    assert_eq!(std::fs::read(&newer).unwrap(), before);
    // A corrupt file.
    let corrupt = dir.path().join("corrupt.sqlite");
    let garbage: Vec<u8> = (0..8192u32).map(|i| (i * 7919 % 251) as u8).collect();
    std::fs::write(&corrupt, &garbage).unwrap();
    let e = Database::open(&corrupt).err().expect("refused").to_string();
    assert!(
        e.contains("corrupt.sqlite") && e.contains("not modified"),
        "{e}"
    );
    assert_eq!(std::fs::read(&corrupt).unwrap(), garbage);
    // Another application's SQLite database.
    let other = dir.path().join("other.sqlite");
    rusqlite::Connection::open(&other)
        .unwrap()
        .execute_batch("CREATE TABLE foo (x); INSERT INTO foo VALUES (1);")
        .unwrap();
    let before = std::fs::read(&other).unwrap();
    let e = Database::open(&other).err().expect("refused").to_string();
    assert!(e.contains("not a kinecal history"), "{e}");
    assert_eq!(std::fs::read(&other).unwrap(), before);
}

#[test]
fn read_only_location_gives_a_clear_error() {
    // /proc is read-only for everyone, root included.
    let e = Database::open(Path::new("/proc/kinecal-test/h.sqlite"))
        .err()
        .expect("refused")
        .to_string();
    assert!(
        e.contains("/proc/kinecal-test/h.sqlite") && e.contains("cannot"),
        "{e}"
    );
    // A file standing where the folder should be.
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("file"), "x").unwrap();
    let e = Database::open(dir.path().join("file/h.sqlite"))
        .err()
        .expect("refused")
        .to_string();
    assert!(e.contains("cannot create the folder"), "{e}");
}
