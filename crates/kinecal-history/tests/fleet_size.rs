//! A history at fleet size (issue 39): 20,000 records (1,000 robots x 20 calibrations), built
//! through the library in one transaction (`Database::import`), on SQLite and PostgreSQL. What
//! is checked is behaviour, not time: a write into the big history records, keys and checks the
//! robot's model as into a small one; on SQLite it reads the pages it writes, not the file (a
//! damaged page elsewhere does not stop it, and the check on demand finds that page), and a
//! damaged page it reads refuses it with the file untouched. `tests/throughput.rs` measures the
//! rates (ignored by default).

mod common;

use std::path::Path;

#[cfg(feature = "postgres")]
use common::pg::TestDb;
use common::report::{ge_a4_report, LINK1_XY_LINK3_Y};
use kinecal::model::examples;
use kinecal::report::CalibrationReport;
use kinecal_history::{AddOptions, Database, Dump, Error};

const T0: i64 = 1_790_000_000;
const DAY: i64 = 86_400;
const ROBOTS: usize = 1_000;
const EACH: usize = 20;

/// A calibration of the GE A4 (link 1's x and y, link 3's y) on simulated data.
fn report() -> CalibrationReport {
    static R: std::sync::OnceLock<CalibrationReport> = std::sync::OnceLock::new();
    R.get_or_init(|| ge_a4_report(&examples::ge_a4(), 10, 1, &LINK1_XY_LINK3_Y, Some("data")))
        .clone()
}

/// A dump of 1,000 robots x 20 calibrations (ids 1..=20,000, robot by robot), each with six
/// parameters of a small robot model and a short report listing them.
fn fleet_dump() -> Dump {
    let names = [
        "link1.x", "link1.y", "link1.z", "link2.x", "link2.y", "link2.z",
    ];
    let report = format!(
        "{{\"parameters\": [{}]}}",
        (1..=6)
            .map(|k| format!("{{\"id\": \"p{k}\"}}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let mut calibrations = Vec::with_capacity(ROBOTS * EACH);
    for r in 0..ROBOTS {
        for k in 0..EACH {
            let parameters: Vec<serde_json::Value> = names
                .iter()
                .enumerate()
                .map(|(j, name)| {
                    serde_json::json!({
                        "id": format!("p{}", j + 1),
                        "name": name,
                        "unit": "in",
                        "value": 1.0 + j as f64 + 1e-4 * k as f64,
                        "sigma": 1e-3,
                        "estimated": true,
                        "determined": true,
                    })
                })
                .collect();
            calibrations.push(serde_json::json!({
                "id": r * EACH + k + 1,
                "key": format!("fleet {r}-{k}"),
                "robot_id": format!("R{r:04}"),
                "at": T0 + k as i64 * 30 * DAY,
                "robot_name": "six",
                "model_fingerprint": "",
                "data_fingerprint": "",
                "method": "lm",
                "solution": "solution",
                "length_unit": "in",
                "angle_unit": "deg",
                "rms_position_before": 0.01,
                "rms_position_after": 0.001,
                "rms_orientation_before": 0.0,
                "rms_orientation_after": 0.0,
                "note": "",
                "report": report,
                "parameters": parameters,
                "combinations": [],
            }));
        }
    }
    let dump = serde_json::json!({
        "format": "kinecal-history-dump",
        "version": 1,
        "calibrations": calibrations,
        "events": [{"id": 1, "robot_id": "R0003", "at": T0 + 45 * DAY, "note": "gearbox J2 replaced"}],
    });
    Dump::from_json(&dump.to_string(), "fleet dump").unwrap()
}

/// What a history of fleet size does with one more write, on either back end.
fn writes_as_into_a_small_one(loc: &str) {
    let db = Database::open(loc).unwrap();
    let s = db.import(&fleet_dump()).unwrap();
    assert_eq!((s.added, s.present, s.events_added), (ROBOTS * EACH, 0, 1));
    assert!(s.renumbered.is_empty());
    drop(db);
    // One command's write: open, record a new robot's calibration; the id follows the
    // imported ones.
    let db = Database::open(loc).unwrap();
    let rep = report();
    let a = db
        .record("NEW-1", Some(T0), &rep, "", AddOptions::default())
        .unwrap();
    assert!(a.new);
    assert_eq!(a.id, (ROBOTS * EACH + 1) as i64);
    // The same calibration again: found by its key, not written twice.
    let b = db
        .record("NEW-1", Some(T0), &rep, "", AddOptions::default())
        .unwrap();
    assert_eq!((b.id, b.new), (a.id, false));
    // A robot with 20 earlier records: its model is checked against them.
    let e = db.add("R0999", Some(T0 + 900 * DAY), &rep, "").unwrap_err();
    assert!(matches!(e, Error::ModelMismatch { .. }), "{e}");
    // An event after the imported one gets a new id.
    let ev = db
        .add_event("R0003", T0 + 900 * DAY, "motor J1 replaced")
        .unwrap();
    assert!(ev.new && ev.id == 2, "{ev:?}");
    // Read back: every robot, the new one with its record.
    let robots = db.robots().unwrap();
    assert_eq!(robots.len(), ROBOTS + 1);
    assert_eq!(
        robots.iter().map(|r| r.1).sum::<i64>(),
        (ROBOTS * EACH + 1) as i64
    );
    let r = db.records(Some("R0003")).unwrap();
    assert_eq!(r.calibrations.len(), EACH);
    assert!(r.damaged.is_empty());
    assert_eq!(db.check().unwrap(), None);
}

#[test]
fn sqlite_a_write_into_20000_records_reads_its_own_pages() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("h.sqlite");
    let loc = path.display().to_string();
    writes_as_into_a_small_one(&loc);
    // Larger than the files checked whole on every open for writing (4 MiB).
    let len = std::fs::metadata(&path).unwrap().len();
    assert!(len > 4 << 20, "{len} bytes");

    checkpoint(&path);
    let (first, last) = (
        leaf(&path, "parameters", "ASC"),
        leaf(&path, "parameters", "DESC"),
    );
    assert_ne!(first, last);

    // A damaged page the write reads (the last leaf of the parameters, where the next
    // calibration's rows go), in a copy: refused, nothing written, the file as it was.
    let copy = dir.path().join("copy.sqlite");
    std::fs::copy(&path, &copy).unwrap();
    damage(&copy, last);
    let before = std::fs::read(&copy).unwrap();
    let e = Database::open(&copy)
        .and_then(|db| db.add("NEW-3", Some(T0), &report(), ""))
        .unwrap_err();
    assert!(matches!(e, Error::Corrupt { .. }), "{e}");
    let e = e.to_string();
    assert!(
        e.contains("integrity") && e.contains("nothing was written"),
        "{e}"
    );
    assert_eq!(std::fs::read(&copy).unwrap(), before, "the file changed");

    // A damaged page the next write does not read: the first leaf of the parameters (robot
    // R0000's rows). SQLite's own check of the whole file fails.
    damage(&path, first);
    assert_ne!(quick_check(&path), "ok");
    // The write does not read the whole file, so it records (a robot without earlier
    // records: nothing of R0000's is read)...
    let db = Database::open(&path).unwrap();
    let id = db.add("NEW-2", Some(T0), &report(), "").unwrap();
    assert_eq!(id, (ROBOTS * EACH + 2) as i64);
    // ... and the check on demand (what `kinecal history init` runs) finds the page.
    let problem = db.check().unwrap().expect("the damaged page is found");
    assert!(
        problem.contains("malformed") || problem.to_lowercase().contains("page"),
        "{problem}"
    );
    drop(db);
    // A reader is told when it opens the file.
    let r = Database::open_read_only(&path).unwrap();
    assert!(r.integrity_problem().is_some());
}

#[cfg(feature = "postgres")]
#[test]
fn postgres_a_write_into_20000_records() {
    let Some(t) = TestDb::new("fleetsize") else {
        return;
    };
    writes_as_into_a_small_one(&t.url);
}

/// Moves the WAL's pages into the file, so that the file holds every page.
fn checkpoint(path: &Path) {
    let c = rusqlite::Connection::open(path).unwrap();
    c.query_row("PRAGMA wal_checkpoint(TRUNCATE)", [], |_| Ok(()))
        .unwrap();
}

/// The first (`ASC`) or last (`DESC`) leaf page of `table`'s b-tree.
fn leaf(path: &Path, table: &str, order: &str) -> i64 {
    let c = rusqlite::Connection::open(path).unwrap();
    c.query_row(
        &format!(
            "SELECT pageno FROM dbstat WHERE name = ?1 AND pagetype = 'leaf' ORDER BY path {order} LIMIT 1"
        ),
        [table],
        |r| r.get(0),
    )
    .unwrap()
}

/// Damages page `page` (not the first): its cell count made impossible.
fn damage(path: &Path, page: i64) {
    let mut bytes = std::fs::read(path).unwrap();
    let size = u16::from_be_bytes([bytes[16], bytes[17]]) as usize;
    let at = (page as usize - 1) * size;
    bytes[at + 3] = 0xff;
    bytes[at + 4] = 0xff;
    std::fs::write(path, bytes).unwrap();
}

/// SQLite's `quick_check` of the file, on its own connection.
fn quick_check(path: &Path) -> String {
    let c = rusqlite::Connection::open_with_flags(path, rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY)
        .unwrap();
    c.query_row("PRAGMA quick_check", [], |r| r.get(0)).unwrap()
}
