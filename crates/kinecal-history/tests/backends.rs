//! The history's promises on both back ends: every test here runs on a SQLite file and on a
//! PostgreSQL database (`KINECAL_TEST_PG`, see `common/pg.rs`; skipped without one, unless `CI`
//! is set). Then what only a server has: roles, passwords; and moving a history between back
//! ends losslessly. The PostgreSQL tests need the `postgres` feature (on by default); without
//! it, a server location is refused with a clear error.

mod common;

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

#[cfg(feature = "postgres")]
use common::pg::{self, TestDb};
use common::report::{ge_a4_report, LINK1_XY_LINK3_Y};
use kinecal::report::CalibrationReport;
use kinecal::{model::examples, ParamId};
use kinecal_history::{
    current_segment, drift, fleet, AddOptions, Database, DriftOptions, Error, FleetOptions,
    Tolerances, Verdict,
};
use rand::{RngExt, SeedableRng};

/// A calibration of the GE A4 (link 1's x and y, link 3's y) on simulated data; `shift` moves
/// link 3's y (inches, the robot file's unit).
fn report(seed: u64, shift: f64) -> CalibrationReport {
    let mut truth = examples::ge_a4();
    truth.set(ParamId(13), truth.get(ParamId(13)) + shift * 0.0254);
    let key = format!("seed {seed}, shift {shift}");
    ge_a4_report(&truth, 10, seed, &LINK1_XY_LINK3_Y, Some(&key))
}

fn shared_report() -> CalibrationReport {
    static R: std::sync::OnceLock<CalibrationReport> = std::sync::OnceLock::new();
    R.get_or_init(|| report(1, 0.0)).clone()
}

const T0: i64 = 1_790_000_000;
const DAY: i64 = 86_400;

/// A location of each back end for one test: a SQLite file in a fresh folder, or a fresh
/// PostgreSQL database. Kept alive for the test.
enum Place {
    File(tempfile::TempDir),
    #[cfg(feature = "postgres")]
    Server(TestDb),
}

impl Place {
    fn location(&self) -> String {
        match self {
            Place::File(d) => d.path().join("h.sqlite").display().to_string(),
            #[cfg(feature = "postgres")]
            Place::Server(db) => db.url.clone(),
        }
    }
}

fn sqlite() -> Option<Place> {
    Some(Place::File(tempfile::tempdir().unwrap()))
}

#[cfg(feature = "postgres")]
fn postgres(tag: &str) -> Option<Place> {
    TestDb::new(tag).map(Place::Server)
}

/// Each test once per back end: `mod sqlite { fn name() }` and `mod postgres { fn name() }`.
macro_rules! on_both_backends {
    ($($name:ident),* $(,)?) => {
        mod on_sqlite {
            $(#[test]
            fn $name() {
                let place = super::sqlite().unwrap();
                super::$name(&place.location());
            })*
        }
        #[cfg(feature = "postgres")]
        mod on_postgres {
            $(#[test]
            fn $name() {
                if let Some(place) = super::postgres(stringify!($name)) {
                    super::$name(&place.location());
                }
            })*
        }
    };
}

on_both_backends!(
    records_round_trip,
    the_same_calibration_is_recorded_once,
    a_calibration_of_another_model_is_refused_unless_forced,
    reads_never_create_a_history,
    events_cut_drift_into_segments,
    the_fleet_is_sorted_by_urgency,
    concurrent_writers_killed_and_retried_leave_every_record_once,
    concurrent_first_writers_of_an_empty_history_all_write,
    a_forced_model_change_starts_a_new_segment,
    serials_with_white_space_at_their_ends_are_refused,
);

fn records_round_trip(loc: &str) {
    let db = Database::open(loc).unwrap();
    let rep = shared_report();
    let id = db.add("R1", Some(T0), &rep, "first").unwrap();
    let c = db.calibration(id).unwrap().unwrap();
    assert_eq!(
        (c.robot_id.as_str(), c.note.as_str(), c.at),
        ("R1", "first", T0)
    );
    assert_eq!(c.parameters.len(), 38);
    for (p, r) in c.parameters.iter().zip(&rep.parameters) {
        assert_eq!(
            (&p.id, &p.name, p.estimated),
            (&r.id, &r.name, r.estimated_flag)
        );
        assert_eq!(p.value.to_bits(), r.estimated.to_bits(), "{}", p.id);
        assert_eq!(p.sigma.map(f64::to_bits), r.sigma.map(f64::to_bits));
    }
    assert_eq!(db.robots().unwrap(), vec![("R1".to_string(), 1)]);
    assert!(db.add(" ", None, &rep, "").is_err());
    // Oldest first, by robot; a reader sees the same.
    db.add("R0", Some(T0 + 5), &rep, "").unwrap();
    db.add("R1", Some(T0 - 5), &rep, "earlier").unwrap();
    let reader = Database::open_read_only(loc).unwrap();
    let all = reader.calibrations(None).unwrap();
    let order: Vec<(&str, i64)> = all.iter().map(|c| (c.robot_id.as_str(), c.at)).collect();
    assert_eq!(order, [("R0", T0 + 5), ("R1", T0 - 5), ("R1", T0)]);
    assert_eq!(all, db.calibrations(None).unwrap());
    assert!(reader.add("R9", None, &rep, "").is_err(), "a reader wrote");
}

fn the_same_calibration_is_recorded_once(loc: &str) {
    let db = Database::open(loc).unwrap();
    let rep = shared_report();
    let a = db
        .record("R1", Some(T0), &rep, "", AddOptions::default())
        .unwrap();
    assert!(a.new);
    // A retry (same robot, report and time): the same record, nothing written.
    let b = db
        .record("R1", Some(T0), &rep, "retry", AddOptions::default())
        .unwrap();
    assert_eq!((b.id, b.new), (a.id, false));
    // Without a time: keyed by the report alone, so a retry is found too.
    let c = db
        .record("R1", None, &rep, "", AddOptions::default())
        .unwrap();
    let d = db
        .record("R1", None, &rep, "", AddOptions::default())
        .unwrap();
    assert!(c.new && !d.new && c.id == d.id);
    // Another time, another robot, another calibration: new records.
    assert!(
        db.record("R1", Some(T0 + DAY), &rep, "", AddOptions::default())
            .unwrap()
            .new
    );
    assert!(
        db.record("R2", Some(T0), &rep, "", AddOptions::default())
            .unwrap()
            .new
    );
    assert!(
        db.record("R1", Some(T0), &report(2, 0.0), "", AddOptions::default())
            .unwrap()
            .new
    );
    assert_eq!(db.calibrations(None).unwrap().len(), 5);
    // Events too.
    let e = db.add_event("R1", T0, "gearbox J2 replaced").unwrap();
    let f = db.add_event("R1", T0, "gearbox J2 replaced").unwrap();
    assert!(e.new && !f.new && e.id == f.id);
    assert!(db.add_event("R1", T0, " ").is_err());
}

fn a_calibration_of_another_model_is_refused_unless_forced(loc: &str) {
    let db = Database::open(loc).unwrap();
    db.add("R1", Some(T0), &shared_report(), "").unwrap();
    let mut other = shared_report();
    other.parameters.pop();
    let e = db.add("R1", Some(T0 + 1), &other, "").unwrap_err();
    assert!(matches!(e, Error::ModelMismatch { .. }), "{e}");
    assert_eq!(db.calibrations(None).unwrap().len(), 1);
    db.add_with("R1", Some(T0 + 1), &other, "", AddOptions { force: true })
        .unwrap();
    assert_eq!(db.calibrations(None).unwrap().len(), 2);
}

fn reads_never_create_a_history(loc: &str) {
    match Database::open_read_only(loc) {
        Err(Error::NoDatabase { .. }) => {}
        Err(e) => panic!("unexpected error {e}"),
        Ok(_) => panic!("a reader found a history where none was"),
    }
    // Nothing was created: a writer then creates the schema at the current version.
    let db = Database::open(loc).unwrap();
    assert_eq!(db.store().schema_version(), kinecal_history::SCHEMA_VERSION);
    assert!(db.calibrations(None).unwrap().is_empty());
}

/// Link 3 drifts by 0.01 a month; a repair on day 95 resets it; after it, drift is computed
/// from the repair on, and nothing is flagged.
fn events_cut_drift_into_segments(loc: &str) {
    let db = Database::open(loc).unwrap();
    let shifts = [0.0, 0.01, 0.02, 0.03, 0.0, 0.0, 0.0];
    for (k, s) in shifts.iter().enumerate() {
        db.add(
            "R1",
            Some(T0 + 30 * DAY * k as i64),
            &report(10 + k as u64, *s),
            "",
        )
        .unwrap();
    }
    let history = db.calibrations(Some("R1")).unwrap();
    let opts = DriftOptions::default();
    // Over the whole history (no event): the repair looks like no change, but the run of
    // months 1-3 does not.
    assert!(drift(&history[..4], &opts).unwrap().flags.len() == 1);
    db.add_event("R1", T0 + 95 * DAY, "gearbox J2 replaced")
        .unwrap();
    let events = db.events(Some("R1")).unwrap();
    assert_eq!(events.len(), 1);
    let (seg, ev) = current_segment(&history, &events);
    assert_eq!(seg.len(), 3);
    assert_eq!(seg[0].at, T0 + 120 * DAY);
    assert_eq!(ev.unwrap().note, "gearbox J2 replaced");
    assert!(drift(seg, &opts).unwrap().flags.is_empty());
    // An event after the latest calibration: nothing in the segment.
    db.add_event("R1", T0 + 400 * DAY, "motor 3 replaced")
        .unwrap();
    let events = db.events(None).unwrap();
    assert!(current_segment(&history, &events).0.is_empty());
}

/// `rep` as a calibration of a rebuilt robot: joint 3 revolute (it was prismatic), and link
/// 1's beta 180 degrees away (the tester's 6-joint robot under a 4-joint serial).
fn rebuilt(rep: &CalibrationReport) -> CalibrationReport {
    let mut r = rep.clone();
    for p in &mut r.parameters {
        match p.name.as_str() {
            "joint3.offset" => p.unit = "deg".into(),
            "joint3.slope" => p.unit = "deg/unit".into(),
            "link1.beta" => p.estimated -= 180.0,
            _ => {}
        }
    }
    r
}

/// A report of another robot model recorded with the force option under a serial (the robot
/// was rebuilt) starts a new segment: drift and the fleet never compare it with the earlier
/// model's calibrations (they compared link 1's beta across the models: 180 degrees, flagged
/// at thousands of sigma), and say which calibrations they left out and why.
fn a_forced_model_change_starts_a_new_segment(loc: &str) {
    let db = Database::open(loc).unwrap();
    for k in 0..3i64 {
        db.add(
            "R1",
            Some(T0 + 30 * DAY * k),
            &report(60 + k as u64, 0.0),
            "",
        )
        .unwrap();
    }
    let force = AddOptions { force: true };
    let first_new = db
        .add_with(
            "R1",
            Some(T0 + 100 * DAY),
            &rebuilt(&report(63, 0.0)),
            "",
            force,
        )
        .unwrap();
    let history = db.calibrations(Some("R1")).unwrap();
    let before: Vec<i64> = history[..3].iter().map(|c| c.id).collect();
    // One calibration of the new model: nothing to compare, nothing flagged.
    let r = drift(&history, &DriftOptions::default()).unwrap();
    assert!(r.flags.is_empty(), "{:?}", r.flags);
    assert!(r.nothing_to_compare.is_some());
    let m = r.since_model_change.as_ref().expect("the change is said");
    assert_eq!((m.first_id, m.earlier_id), (first_new, before[2]));
    assert_eq!(m.left_out, before);
    assert!(
        m.difference
            .contains("joint 3 is revolute, earlier prismatic"),
        "{}",
        m.difference
    );
    assert!(
        m.reason().contains("of another robot model"),
        "{}",
        m.reason()
    );
    // Two: compared with each other only.
    let latest = db
        .add("R1", Some(T0 + 130 * DAY), &rebuilt(&report(64, 0.0)), "")
        .unwrap();
    let history = db.calibrations(Some("R1")).unwrap();
    let r = drift(&history, &DriftOptions::default()).unwrap();
    assert_eq!((r.baseline_id, r.latest_id), (first_new, latest));
    assert_eq!(r.calibrations, 2);
    assert!(r.flags.is_empty(), "{:?}", r.flags);
    assert!(!r.quantities.is_empty());
    assert_eq!(r.since_model_change.as_ref().unwrap().left_out, before);
    // A baseline of the earlier model is refused, saying why.
    let e = drift(
        &history,
        &DriftOptions {
            baseline: kinecal_history::Baseline::Id(before[0]),
            ..Default::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("of another robot model"), "{e}");
    let events = db.events(Some("R1")).unwrap();
    let seg = kinecal_history::segment_of(&history, &events);
    assert_eq!(seg.calibrations.len(), 2);
    assert_eq!(seg.model_change.unwrap().left_out, before);
    let f = fleet(
        &history,
        &events,
        &FleetOptions {
            drift: DriftOptions::default(),
            now: T0 + 140 * DAY,
            horizon: 90 * DAY,
        },
    )
    .unwrap();
    assert_eq!(f[0].verdict, Verdict::Ok, "{:?}", f[0]);
    assert_eq!((f[0].calibrations, f[0].in_segment), (5, 2));
    assert_eq!(f[0].model_change.as_ref().unwrap().first_id, first_new);
    // A maintenance event after the change: the segment is cut there, as before.
    db.add_event("R1", T0 + 120 * DAY, "J3 encoder replaced")
        .unwrap();
    let events = db.events(Some("R1")).unwrap();
    let seg = kinecal_history::segment_of(&history, &events);
    assert_eq!(seg.calibrations.len(), 1);
    assert!(seg.model_change.is_none() && seg.event.is_some());
}

/// `history add` kept the spaces around a serial: "  X  " and "X" were two robots. Refused,
/// saying so (never trimmed silently), for a calibration and for an event.
fn serials_with_white_space_at_their_ends_are_refused(loc: &str) {
    let db = Database::open(loc).unwrap();
    for serial in [
        "  X  ", "X ", "	X", "X
",
    ] {
        let e = db.add(serial, Some(T0), &shared_report(), "").unwrap_err();
        assert!(matches!(e, Error::Input(_)), "{e}");
        assert!(
            e.to_string()
                .contains("has white space at its start or end"),
            "{e}"
        );
        let e = db.add_event(serial, T0, "cable").unwrap_err().to_string();
        assert!(e.contains("has white space at its start or end"), "{e}");
    }
    assert!(db.robots().unwrap().is_empty());
    assert!(db.events(None).unwrap().is_empty());
    // Spaces inside a serial are the serial's.
    db.add("A4 0042", Some(T0), &shared_report(), "").unwrap();
}

/// Three robots: one drifting past its tolerance (flagged), one drifting slowly (due within the
/// horizon), one steady (ok); sorted flagged, due, ok; the due robot's crossing is where its
/// trend line meets the tolerance.
fn the_fleet_is_sorted_by_urgency(loc: &str) {
    let db = Database::open(loc).unwrap();
    for k in 0..5i64 {
        let at = Some(T0 + 30 * DAY * k);
        db.add("C-steady", at, &report(30 + k as u64, 0.0), "")
            .unwrap();
        db.add("A-fast", at, &report(40 + k as u64, 0.01 * k as f64), "")
            .unwrap();
        db.add("B-slow", at, &report(50 + k as u64, 0.002 * k as f64), "")
            .unwrap();
    }
    let records = db.records(None).unwrap();
    let key = drift(&records.calibrations[..5], &DriftOptions::default())
        .unwrap()
        .quantities
        .iter()
        .find(|q| q.parameters.contains(&"p14".to_string()))
        .expect("link 3's y is tracked")
        .key
        .clone();
    // Flags by the tolerance alone (K so large that no change reaches it).
    let opts = FleetOptions {
        drift: DriftOptions {
            tolerances: Tolerances::from_entries(vec![(key.clone(), 0.02)]),
            sigma: 1e6,
            ..Default::default()
        },
        now: T0 + 120 * DAY,
        horizon: 365 * DAY,
    };
    let f = fleet(&records.calibrations, &db.events(None).unwrap(), &opts).unwrap();
    let order: Vec<(&str, Verdict)> = f.iter().map(|r| (r.robot_id.as_str(), r.verdict)).collect();
    assert_eq!(
        order,
        [
            ("A-fast", Verdict::Flagged),
            ("B-slow", Verdict::Due),
            ("C-steady", Verdict::Ok)
        ]
    );
    // B drifts 0.002 a month (link 3's y shrinks the sum): 0.02 is crossed ~10 months after
    // the first calibration.
    let t = f[1].trends.iter().find(|t| t.key == key).unwrap();
    let rate = t.rate_per_month.unwrap();
    assert!(
        (rate.abs() - 0.002).abs() < 4.0 * t.rate_sigma.unwrap(),
        "{rate}"
    );
    let months = (t.crossing.unwrap() - T0) as f64 / (30.0 * DAY as f64);
    assert!((7.0..14.0).contains(&months), "{months}");
    assert_eq!(f[0].flags, vec![key]);
}

/// One writer process (run by the test below in children): 50 calibrations of 5 robots,
/// each with its time.
#[test]
fn writer_child() {
    let (Ok(loc), Ok(id)) = (
        std::env::var("KINECAL_TEST_WRITER_DB"),
        std::env::var("KINECAL_TEST_WRITER_ID"),
    ) else {
        return;
    };
    let rep = shared_report();
    let db = Database::open(&loc).unwrap();
    for k in 0..50i64 {
        db.add(&format!("W{id}-{}", k % 5), Some(T0 + k * DAY), &rep, "")
            .unwrap();
    }
}

/// 20 processes write 50 records each at once; some are killed at random moments (SIGKILL, mid
/// transaction or not) and run again, as a job system retries a failed task. In the end: 1,000
/// records, each once, each whole (every parameter and combination).
fn concurrent_writers_killed_and_retried_leave_every_record_once(loc: &str) {
    // The schema first, as `kinecal history init` would: then the children only write.
    Database::open(loc).unwrap();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(28);
    let spawn = |w: usize| {
        Command::new(std::env::current_exe().unwrap())
            .args(["--exact", "writer_child", "--nocapture"])
            .env("KINECAL_TEST_WRITER_DB", loc)
            .env("KINECAL_TEST_WRITER_ID", w.to_string())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap()
    };
    let t = Instant::now();
    let mut children: Vec<_> = (0..20).map(|w| (w, spawn(w))).collect();
    let mut kills = 0;
    let mut round = 0;
    while !children.is_empty() {
        round += 1;
        // Kill a random third of the running writers after a random delay (the first rounds).
        if round <= 3 {
            std::thread::sleep(Duration::from_millis(rng.random_range(20..200)));
            for (_, c) in children.iter_mut() {
                if rng.random_range(0..3) == 0 && c.try_wait().unwrap().is_none() {
                    let _ = c.kill();
                    kills += 1;
                }
            }
        }
        let mut again = Vec::new();
        for (w, mut c) in children {
            let status = c.wait().unwrap();
            if !status.success() {
                again.push((w, spawn(w)));
            }
        }
        children = again;
        assert!(round < 50, "writers keep failing");
    }
    assert!(kills > 0, "no writer was killed: the retry was not tested");
    let db = Database::open_read_only(loc).unwrap();
    let records = db.records(None).unwrap();
    assert!(records.damaged.is_empty());
    assert_eq!(records.calibrations.len(), 1000);
    let mut seen: Vec<(String, i64)> = records
        .calibrations
        .iter()
        .map(|c| (c.robot_id.clone(), c.at))
        .collect();
    seen.sort();
    seen.dedup();
    assert_eq!(seen.len(), 1000, "duplicates");
    let rep = shared_report();
    for c in &records.calibrations {
        assert_eq!(c.parameters.len(), rep.parameters.len(), "a partial record");
        assert_eq!(
            c.combinations.len(),
            rep.combinations.len(),
            "a partial record"
        );
    }
    eprintln!(
        "20 writers x 50 records, {kills} killed and rerun: 1000 records in {:.1} s",
        t.elapsed().as_secs_f64()
    );
}

/// 20 writers start at once on a location where no history is yet (no `history init`), each
/// opening its own connection and adding 10 records: the schema is created once, while the
/// others wait for it (PostgreSQL: an advisory lock, the schema read again in a transaction that
/// begins once the lock is held; SQLite: the migration in an IMMEDIATE transaction that reads
/// the version again). Every writer succeeds and all 200 records are there.
fn concurrent_first_writers_of_an_empty_history_all_write(loc: &str) {
    let rep = shared_report();
    let start = std::sync::Barrier::new(20);
    let failures: Vec<String> = std::thread::scope(|s| {
        let writers: Vec<_> = (0..20)
            .map(|w| {
                let (rep, start) = (&rep, &start);
                s.spawn(move || -> Result<(), String> {
                    start.wait();
                    let db = Database::open(loc).map_err(|e| format!("writer {w} opens: {e}"))?;
                    for k in 0..10i64 {
                        db.add(&format!("F{w}"), Some(T0 + k * DAY), rep, "")
                            .map_err(|e| format!("writer {w}, record {k}: {e}"))?;
                    }
                    Ok(())
                })
            })
            .collect();
        writers
            .into_iter()
            .filter_map(|h| h.join().unwrap().err())
            .collect()
    });
    assert!(
        failures.is_empty(),
        "{} writers failed: {failures:#?}",
        failures.len()
    );
    let records = Database::open_read_only(loc)
        .unwrap()
        .records(None)
        .unwrap();
    assert!(records.damaged.is_empty());
    assert_eq!(records.calibrations.len(), 200);
}

/// A history written by kinecal before schema version 2 (tests/data/README.md) opens for
/// reading as it is, migrates on the first write, and reads the same after.
#[test]
fn a_version_1_file_migrates() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("v1.sqlite");
    std::fs::copy(
        concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/v1-history.sqlite"),
        &path,
    )
    .unwrap();
    let version = |p: &std::path::Path| -> i64 {
        rusqlite::Connection::open(p)
            .unwrap()
            .query_row("PRAGMA user_version", [], |r| r.get(0))
            .unwrap()
    };
    assert_eq!(version(&path), 1);
    let before = Database::open_read_only(&path)
        .unwrap()
        .calibrations(None)
        .unwrap();
    assert_eq!(before.len(), 2);
    assert_eq!(version(&path), 1, "a reader migrated");
    let db = Database::open(&path).unwrap();
    assert_eq!(version(&path), 2);
    assert_eq!(db.calibrations(None).unwrap(), before);
    // The old records have no key; new ones do, and events work.
    let dump = db.dump().unwrap();
    assert!(dump.calibrations.iter().all(|r| r.key.is_none()));
    let added = db
        .record(
            "A4-0042",
            Some(T0),
            &shared_report(),
            "",
            AddOptions::default(),
        )
        .unwrap();
    assert!(added.new && added.id == 3);
    assert!(db.dump().unwrap().calibrations[2].key.is_some());
    db.add_event("A4-0042", T0, "gearbox J2 replaced").unwrap();
    assert_eq!(db.events(None).unwrap().len(), 1);
}

#[cfg(feature = "postgres")]
#[test]
fn a_newer_schema_is_refused_with_its_version() {
    // SQLite: covered for the file in tests/store.rs; here the server.
    let Some(t) = TestDb::new("newer") else {
        return;
    };
    Database::open(&t.url).unwrap();
    t.client()
        .batch_execute("UPDATE kinecal.schema_version SET version = 7")
        .unwrap();
    for r in [Database::open(&t.url), Database::open_read_only(&t.url)] {
        match r {
            Err(e @ Error::NewerSchema { found: 7, .. }) => {
                assert!(e.to_string().contains("schema version 7"), "{e}")
            }
            Err(e) => panic!("unexpected error {e}"),
            Ok(_) => panic!("opened a newer schema"),
        }
    }
}

/// SQLite -> PostgreSQL -> SQLite: every stored field identical, ids included; importing again
/// adds nothing.
#[cfg(feature = "postgres")]
#[test]
fn a_history_moves_between_back_ends_losslessly() {
    let Some(t) = TestDb::new("moves") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let a = Database::open(dir.path().join("a.sqlite")).unwrap();
    for k in 0..4i64 {
        a.add(
            "R1",
            Some(T0 + k * DAY),
            &report(60 + k as u64, 0.003 * k as f64),
            "n\u{e9}e\n",
        )
        .unwrap();
        a.add("R2", None, &report(70 + k as u64, 0.0), "").unwrap();
    }
    a.add_event("R1", T0 + DAY, "gearbox J2 replaced").unwrap();
    let dump = a.dump().unwrap();
    let pg = Database::open(&t.url).unwrap();
    let s = pg.import(&dump).unwrap();
    assert_eq!((s.added, s.present, s.events_added), (8, 0, 1));
    assert_eq!(pg.dump().unwrap(), dump);
    assert_eq!(pg.import(&dump).unwrap().added, 0);
    let b = Database::open(dir.path().join("b.sqlite")).unwrap();
    b.import(&kinecal_history::Dump::from_json(&pg.dump().unwrap().to_json(), "dump").unwrap())
        .unwrap();
    assert_eq!(b.dump().unwrap(), dump);
    assert_eq!(b.calibrations(None).unwrap(), a.calibrations(None).unwrap());
    // New records after an import get new ids.
    let id = pg.add("R3", Some(T0), &shared_report(), "").unwrap();
    assert!(id > dump.calibrations.iter().map(|r| r.id).max().unwrap());
}

/// The roles of the documentation, created by its SQL: the roles by an administrator (with
/// CREATEROLE), their rights by the database's owner, a role without CREATEROLE (issue 38: the
/// SQL assumed an owner that can create roles); a reader reads and cannot write (a clear error),
/// a writer writes; passwords never appear in a message.
#[cfg(feature = "postgres")]
#[test]
fn roles_as_the_readme_creates_them() {
    let Some(t) = TestDb::new("roles") else {
        return;
    };
    // Roles belong to the server, not the database: suffixed, so tests never collide.
    let suffix = format!("_{}", std::process::id());
    let dbname = t.url.rsplit('/').next().unwrap().to_string();
    // The database's owner: may log in, may not create roles.
    let (owner, owner_pw) = (format!("kowner{suffix}"), "owner-secret-77c1");
    let mut admin = t.client();
    admin
        .batch_execute(&format!(
            "CREATE ROLE {owner} LOGIN NOCREATEROLE NOSUPERUSER PASSWORD '{owner_pw}';
             ALTER DATABASE {dbname} OWNER TO {owner};"
        ))
        .unwrap();
    let owner_url = pg::with_user(&t.url, &owner, owner_pw);
    // The schema, by its owner.
    let db = Database::open(&owner_url).unwrap();
    db.add("R1", Some(T0), &shared_report(), "").unwrap();
    drop(db);
    // The roles' SQL as the documentation gives it: the roles, then the rights.
    let text = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/history.md"),
    )
    .unwrap();
    let block = |k: usize| {
        text.split("```sql\n")
            .nth(k)
            .and_then(|b| b.split("```").next())
            .expect("the documentation's roles SQL")
            .replace("kinecal_reader", &format!("kinecal_reader{suffix}"))
            .replace("kinecal_writer", &format!("kinecal_writer{suffix}"))
            .replace("maint ", &format!("maint{suffix} "))
            .replace("cell07 ", &format!("cell07{suffix} "))
            .replace("DATABASE kinecal", &format!("DATABASE {dbname}"))
    };
    let (roles, rights) = (block(1), block(2));
    assert!(roles.contains("CREATE ROLE") && !rights.contains("CREATE ROLE"));
    let mut as_owner = postgres::Client::connect(&owner_url, postgres::NoTls).unwrap();
    // The owner cannot create the roles (what the documentation says)...
    let e = as_owner.batch_execute(&roles).unwrap_err();
    assert!(
        e.as_db_error()
            .is_some_and(|d| d.message().contains("permission denied to create role")),
        "{e:?}"
    );
    // ... the administrator does, and the owner grants the rights.
    admin.batch_execute(&roles).unwrap();
    as_owner.batch_execute(&rights).unwrap();
    drop(as_owner);
    let (reader_pw, writer_pw) = ("maint-secret-5af3", "cell07-secret-91bd");
    let reader_url = pg::with_user(&t.url, &format!("maint{suffix}"), reader_pw);
    let writer_url = pg::with_user(&t.url, &format!("cell07{suffix}"), writer_pw);
    admin
        .batch_execute(&format!(
            "ALTER ROLE maint{suffix} PASSWORD '{reader_pw}'; ALTER ROLE cell07{suffix} PASSWORD '{writer_pw}';"
        ))
        .unwrap();
    // The reader reads...
    let r = Database::open_read_only(&reader_url).unwrap();
    assert_eq!(r.calibrations(None).unwrap().len(), 1);
    assert!(r.events(None).unwrap().is_empty());
    assert!(!r.path().contains(reader_pw));
    // ... and cannot write, even opened for writing: a clear error, no password in it.
    let w = Database::open(&reader_url).unwrap();
    let e = w
        .add("R1", Some(T0 + 1), &shared_report(), "")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("permission denied") && e.contains("writer"),
        "{e}"
    );
    assert!(!e.contains(reader_pw), "{e}");
    let e = w.add_event("R1", T0, "x").unwrap_err().to_string();
    assert!(e.contains("permission denied"), "{e}");
    // The writer writes, retries without duplicates.
    let w = Database::open(&writer_url).unwrap();
    let a = w
        .record(
            "R1",
            Some(T0 + 1),
            &shared_report(),
            "",
            AddOptions::default(),
        )
        .unwrap();
    let b = w
        .record(
            "R1",
            Some(T0 + 1),
            &shared_report(),
            "",
            AddOptions::default(),
        )
        .unwrap();
    assert!(a.new && !b.new);
    w.add_event("R1", T0, "gearbox J2 replaced").unwrap();
    // A wrong password: refused, the password not shown.
    let wrong = pg::with_user(&t.url, &format!("maint{suffix}"), "Wr0ng-pa55word");
    let e = Database::open_read_only(&wrong).err().unwrap().to_string();
    assert!(e.contains("password authentication failed"), "{e}");
    assert!(!e.contains("Wr0ng-pa55word"), "{e}");
    // The roles go with the test.
    drop((r, w));
    let _ = admin.batch_execute(&format!(
        "REVOKE ALL ON ALL TABLES IN SCHEMA kinecal FROM kinecal_reader{suffix}, kinecal_writer{suffix};
         REVOKE ALL ON ALL SEQUENCES IN SCHEMA kinecal FROM kinecal_writer{suffix};
         ALTER DATABASE {dbname} OWNER TO CURRENT_USER;
         DROP OWNED BY maint{suffix}, cell07{suffix}, kinecal_reader{suffix}, kinecal_writer{suffix}, {owner};
         DROP ROLE maint{suffix}; DROP ROLE cell07{suffix}; DROP ROLE kinecal_writer{suffix}; DROP ROLE kinecal_reader{suffix};
         DROP ROLE {owner};"
    ));
}

#[cfg(feature = "postgres")]
#[test]
fn a_server_that_is_not_there_is_named_without_the_password() {
    // Port 1 on loopback: nothing listens.
    let e = Database::open("postgres://alice:Sup3r-s3cret@127.0.0.1:1/kinecal")
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("postgres://alice@127.0.0.1:1/kinecal") && e.contains("cannot connect"),
        "{e}"
    );
    assert!(!e.contains("Sup3r-s3cret"), "{e}");
    let e = Database::open("postgres://alice:Sup3r-s3cret@127.0.0.1:notaport/kinecal")
        .err()
        .unwrap()
        .to_string();
    assert!(!e.contains("Sup3r-s3cret"), "{e}");
}

/// A build without PostgreSQL refuses a server location, naming the feature, the password not
/// shown; nothing is created (no file named like the URL).
#[cfg(not(feature = "postgres"))]
#[test]
fn a_server_location_needs_the_postgres_feature() {
    for url in [
        "postgres://alice:Sup3r-s3cret@127.0.0.1:1/kinecal",
        "postgresql://alice@db.plant/kinecal",
    ] {
        for r in [Database::open(url), Database::open_read_only(url)] {
            let e = r.err().expect("refused");
            assert!(matches!(e, Error::NoPostgres { .. }), "{e}");
            let e = e.to_string();
            assert!(
                e.contains("built without PostgreSQL")
                    && e.contains("rebuild with the `postgres` feature"),
                "{e}"
            );
            assert!(!e.contains("Sup3r-s3cret"), "{e}");
        }
    }
    for made in ["postgres:", "postgresql:"] {
        assert!(!std::path::Path::new(made).exists(), "{made} was created");
    }
}
