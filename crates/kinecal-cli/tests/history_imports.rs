#![cfg_attr(not(feature = "postgres"), allow(unused))]
//! `kinecal history import` of the README's example dump, damaged and whole, on SQLite and
//! PostgreSQL (`KINECAL_TEST_PG`; skipped without one unless `CI` is set), issue 38: a damaged
//! dump is refused naming the file, the record and what was expected, and nothing is imported;
//! after an import into PostgreSQL the next event and calibration get new ids.

mod common;
#[cfg(feature = "postgres")]
#[path = "../../kinecal-history/tests/common/pg.rs"]
mod pg;

use std::path::Path;

use common::{argv, run, run_err, run_ok};

fn example() -> serde_json::Value {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/fleet/history.json");
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// The example dump with its third calibration's parameters removed, as `bad.json` in `d`.
fn damaged(d: &Path) {
    let mut v = example();
    v["calibrations"][2]["parameters"] = serde_json::json!([]);
    std::fs::write(d.join("bad.json"), v.to_string()).unwrap();
}

/// The refusal of `bad.json` into `db`, and the history left empty.
fn refused(d: &Path, db: &str) {
    let e = run_err(d, &["history", "import", "bad.json", "--db", db]);
    assert!(
        e.contains(
            "bad.json: calibration 3 of the dump (the 3rd in its list, robot A4-0101): it has no \
             parameters; expected one row per parameter of its robot model (its report lists"
        ) && e.contains("nothing was imported"),
        "{e}"
    );
    if db.contains("://") {
        // The dump is checked before the server is written to: not even the schema is made.
        let e = run_err(d, &["history", "list", "--db", db]);
        assert!(
            e.contains("no such history database (nothing was created)"),
            "{e}"
        );
    } else {
        // A history file that was not there is not created by a refused import.
        assert!(!d.join(db).exists(), "a refused import created {db}");
    }
}

#[test]
fn a_dump_with_a_calibration_without_parameters_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    damaged(d);
    refused(d, "h.sqlite");
}

#[test]
#[cfg(feature = "postgres")]
fn postgres_a_damaged_dump_is_refused_and_ids_after_an_import_are_new() {
    let Some(t) = pg::TestDb::new("cli_import_ids") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    damaged(d);
    refused(d, &t.url);
    // The README's example, then an event and a calibration: new ids (the next event failed
    // with a raw duplicate key: the dump's one event has id 1).
    let v = example();
    std::fs::write(d.join("history.json"), v.to_string()).unwrap();
    let (code, _, e) = run(d, &["history", "import", "history.json", "--db", &t.url]);
    assert_eq!(code, 0, "{e}");
    assert!(e.contains("16 calibrations written"), "{e}");
    let mut args = argv("history event A4-0104 --at 2026-12-10 --note");
    args.extend(["motor J1 replaced", "--db", &t.url]);
    let (code, _, e) = run(d, &args);
    assert_eq!(code, 0, "{e}");
    assert!(!e.contains("duplicate key"), "{e}");
    let out = run_ok(d, &["history", "events", "--db", &t.url]);
    assert!(
        out.lines()
            .any(|l| l.trim_start().starts_with("2 ") && l.contains("motor J1 replaced")),
        "{out}"
    );
    std::fs::write(
        d.join("r.json"),
        v["calibrations"][15]["report"].as_str().unwrap(),
    )
    .unwrap();
    let (code, _, e) = run(
        d,
        &[
            "history",
            "add",
            "--robot-id",
            "A4-0104",
            "--report",
            "r.json",
            "--at",
            "2026-12-20",
            "--db",
            &t.url,
        ],
    );
    assert_eq!(code, 0, "{e}");
    assert!(
        e.contains("recorded calibration 17 of robot A4-0104"),
        "{e}"
    );
}
