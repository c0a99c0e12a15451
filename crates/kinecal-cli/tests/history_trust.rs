//! `kinecal history` under hostile conditions: mistyped, read-only, corrupt and damaged
//! databases, foreign robot models, control characters, bad thresholds, and what drift leaves
//! out. Nothing is created or written where it should not be, and nothing is left out silently.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

mod common;

use common::{argv, run, run_err, run_ok};

/// Two calibration reports of the built-in GE A4 (a month apart, different data), made once.
fn reports() -> &'static (String, String) {
    static REPORTS: OnceLock<(String, String)> = OnceLock::new();
    REPORTS.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let mut texts = Vec::new();
        for seed in ["1", "2"] {
            run_ok(
                d,
                &argv(&format!(
                    "simulate --robot ge-a4 --postures 30 --seed {seed}
                     --noise length=0.0005,angle=0.005 --out m.csv"
                )),
            );
            run_ok(
                d,
                &argv(
                    "calibrate --robot ge-a4 --data m.csv --solution min-change
                     --weights length=0.0005,angle=0.005 --report r.json",
                ),
            );
            texts.push(std::fs::read_to_string(d.join("r.json")).unwrap());
        }
        (texts[0].clone(), texts[1].clone())
    })
}

/// A folder with `r1.json`, `r2.json` and a history `h.sqlite` of robot A4-7 holding
/// `records` calibrations (alternately r1 and r2, a month apart, notes `NOTE-MARK-k`).
fn history(records: usize) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (r1, r2) = reports();
    std::fs::write(d.join("r1.json"), r1).unwrap();
    std::fs::write(d.join("r2.json"), r2).unwrap();
    for k in 0..records {
        let report = if k % 2 == 0 { "r1.json" } else { "r2.json" };
        let at = format!("2026-{:02}-01", k + 1);
        let note = format!("NOTE-MARK-{k}");
        run_ok(
            d,
            &[
                "history",
                "add",
                "--robot-id",
                "A4-7",
                "--report",
                report,
                "--db",
                "h.sqlite",
                "--at",
                &at,
                "--note",
                &note,
            ],
        );
    }
    dir
}

fn files_in(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    v.sort();
    v
}

#[test]
fn read_commands_never_create_a_database() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let before = files_in(d);
    for db in ["missing.sqlite", "no/such/folder/h.sqlite"] {
        let commands: [&[&str]; 6] = [
            &["history", "list", "--db", db],
            &["history", "list", "--db", db, "--robot-id", "A4-7"],
            &["history", "show", "--db", db, "--robot-id", "A4-7"],
            &["history", "export", "--db", db, "--format", "json"],
            &["history", "drift", "--db", db, "--robot-id", "A4-7"],
            &[
                "history",
                "plot",
                "--db",
                db,
                "--robot-id",
                "A4-7",
                "--out",
                "p.svg",
            ],
        ];
        for args in commands {
            let err = run_err(d, args);
            assert!(
                err.contains(db) && err.contains("no such history database"),
                "{args:?}: {err}"
            );
            assert_eq!(files_in(d), before, "{args:?} created a file");
        }
    }
}

#[test]
fn a_corrupt_database_is_refused_by_add_and_left_untouched() {
    let dir = history(2);
    let d = dir.path();
    let path = d.join("h.sqlite");
    // Garbage over the header of the second page (a table's b-tree page): the file still opens,
    // but fails its integrity check.
    let mut bytes = std::fs::read(&path).unwrap();
    bytes[4096..4104].copy_from_slice(&[0xff; 8]);
    std::fs::write(&path, &bytes).unwrap();
    let err = run_err(
        d,
        &argv("history add --robot-id A4-7 --report r1.json --db h.sqlite"),
    );
    assert!(
        err.contains("h.sqlite") && err.contains("integrity") && err.contains("not modified"),
        "{err}"
    );
    assert_eq!(std::fs::read(&path).unwrap(), bytes);
}

/// Replaces every occurrence of `from` in the file by `to` (same length); with `after`, only
/// the first occurrence of `from` within 200 bytes after each occurrence of `after`. (Freed
/// pages may hold stale copies of a record: every copy is patched.)
fn patch(path: &Path, from: &[u8], to: &[u8], after: Option<&[u8]>) {
    assert_eq!(from.len(), to.len());
    let mut bytes = std::fs::read(path).unwrap();
    let find = |b: &[u8], what: &[u8], from_at: usize| {
        b[from_at..]
            .windows(what.len())
            .position(|w| w == what)
            .map(|p| p + from_at)
    };
    let mut at = 0;
    let mut patched = 0;
    loop {
        let hit = match after {
            None => find(&bytes, from, at),
            Some(anchor) => find(&bytes, anchor, at)
                .and_then(|a| find(&bytes, from, a).filter(|p| *p < a + anchor.len() + 200)),
        };
        let Some(p) = hit else { break };
        bytes[p..p + from.len()].copy_from_slice(to);
        patched += 1;
        at = p + from.len();
    }
    assert!(
        patched > 0,
        "{:?} not in the file",
        String::from_utf8_lossy(from)
    );
    std::fs::write(path, bytes).unwrap();
}

#[test]
fn a_damaged_record_is_named_and_the_others_served() {
    let dir = history(4);
    let d = dir.path();
    let path = d.join("h.sqlite");
    // Record 2's note stops being UTF-8; record 3's stored report stops being JSON.
    patch(&path, b"NOTE-MARK-1", b"NOTE-MARK\xff1", None);
    patch(
        &path,
        b"\"schema_version\": ",
        b"\"schema_version\"! ",
        Some(b"NOTE-MARK-2"),
    );
    let (code, out, err) = run(d, &["history", "list", "--db", "h.sqlite"]);
    assert_eq!(code, 0, "{err}");
    assert!(
        err.contains("calibration 2") && err.contains("note") && err.contains("UTF-8"),
        "{err}"
    );
    assert!(
        err.contains("calibration 3") && err.contains("stored report is not valid JSON"),
        "{err}"
    );
    let served = out.lines().filter(|l| l.contains("A4-7")).count();
    assert_eq!(served, 2, "{out}");
    assert!(
        out.contains("NOTE-MARK-0") && out.contains("NOTE-MARK-3"),
        "{out}"
    );
    let err = run_err(d, &["history", "show", "--db", "h.sqlite", "--id", "2"]);
    assert!(
        err.contains("calibration 2") && err.contains("note"),
        "{err}"
    );
    let (code, out, err) = run(
        d,
        &["history", "export", "--db", "h.sqlite", "--format", "json"],
    );
    assert_eq!(code, 0, "{err}");
    let json: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(json.as_array().unwrap().len(), 2);
    assert!(err.contains("calibration 2"), "{err}");
    let (code, out, err) = run(
        d,
        &["history", "drift", "--db", "h.sqlite", "--robot-id", "A4-7"],
    );
    assert!(code == 0 || code == 3, "{err}");
    assert!(out.contains("2 calibrations"), "{out}");
    assert!(err.contains("calibration 2"), "{err}");
    // And a new calibration can still be recorded beside them.
    run_ok(
        d,
        &argv("history add --robot-id A4-7 --report r1.json --db h.sqlite"),
    );
}

/// Whether this process runs as root (which file permissions do not stop).
fn is_root() -> bool {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("Uid:"))
                .map(|l| l.split_whitespace().nth(2) == Some("0"))
        })
        .unwrap_or(false)
}

#[cfg(unix)]
#[test]
fn a_read_only_database_in_a_read_only_folder_serves_the_read_commands() {
    use std::os::unix::fs::PermissionsExt;
    let dir = history(2);
    let d = dir.path();
    let path = d.join("h.sqlite");
    let before = std::fs::read(&path).unwrap();
    let out_dir = tempfile::tempdir().unwrap();
    std::fs::set_permissions(out_dir.path(), std::fs::Permissions::from_mode(0o777)).unwrap();
    let plot_out = out_dir.path().join("p.svg");
    let plot_out = plot_out.to_str().unwrap();
    // As root, permissions stop nothing: run the reads as `nobody`, to whom the folder and the
    // file are read-only. Otherwise take the write permissions away.
    let root = is_root();
    let setpriv = Path::new("/usr/bin/setpriv");
    if root && !setpriv.exists() {
        eprintln!("skipped: running as root without setpriv");
        return;
    }
    if root {
        std::fs::set_permissions(d, std::fs::Permissions::from_mode(0o755)).unwrap();
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o644)).unwrap();
    } else {
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o444)).unwrap();
        std::fs::set_permissions(d, std::fs::Permissions::from_mode(0o555)).unwrap();
    }
    let bin = assert_cmd::cargo::cargo_bin("kinecal");
    let read = |args: &[&str]| -> (i32, String, String) {
        let mut c = if root {
            let mut c = std::process::Command::new(setpriv);
            c.args(["--reuid=65534", "--regid=65534", "--clear-groups"])
                .arg(&bin);
            c
        } else {
            std::process::Command::new(&bin)
        };
        let out = c.current_dir(d).args(args).output().unwrap();
        (
            out.status.code().unwrap_or(-1),
            String::from_utf8_lossy(&out.stdout).to_string(),
            String::from_utf8_lossy(&out.stderr).to_string(),
        )
    };
    let commands: [&[&str]; 5] = [
        &["history", "list", "--db", "h.sqlite"],
        &["history", "show", "--db", "h.sqlite", "--robot-id", "A4-7"],
        &["history", "export", "--db", "h.sqlite", "--format", "csv"],
        &["history", "drift", "--db", "h.sqlite", "--robot-id", "A4-7"],
        &[
            "history",
            "plot",
            "--db",
            "h.sqlite",
            "--robot-id",
            "A4-7",
            "--out",
            plot_out,
        ],
    ];
    for args in commands {
        let (code, out, err) = read(args);
        assert!(code == 0 || code == 3, "{args:?}: {code} {out} {err}");
    }
    assert!(std::fs::read_to_string(plot_out)
        .unwrap()
        .starts_with("<svg"));
    // A write is refused with a message, and the file is unchanged.
    let (code, _, err) = read(&argv(
        "history add --robot-id A4-7 --report r1.json --db h.sqlite",
    ));
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("h.sqlite"), "{err}");
    std::fs::set_permissions(d, std::fs::Permissions::from_mode(0o755)).unwrap();
    std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o644)).unwrap();
    assert_eq!(std::fs::read(&path).unwrap(), before);
}

#[test]
fn a_report_of_another_robot_model_is_refused() {
    let dir = history(1);
    let d = dir.path();
    // The same report, but joint 3 revolute instead of prismatic.
    let mut r = common::read_json(&d.join("r1.json"));
    for p in r["parameters"].as_array_mut().unwrap() {
        match p["name"].as_str().unwrap() {
            "joint3.offset" => p["unit"] = "deg".into(),
            "joint3.slope" => p["unit"] = "deg/unit".into(),
            _ => {}
        }
    }
    std::fs::write(d.join("other.json"), r.to_string()).unwrap();
    let before = std::fs::read(d.join("h.sqlite")).unwrap();
    let err = run_err(
        d,
        &argv("history add --robot-id A4-7 --report other.json --db h.sqlite"),
    );
    assert!(
        err.contains("A4-7") && err.contains("joint 3") && err.contains("revolute"),
        "{err}"
    );
    assert_eq!(std::fs::read(d.join("h.sqlite")).unwrap(), before);
    // Under another serial it is a history of its own.
    run_ok(
        d,
        &argv("history add --robot-id OTHER-1 --report other.json --db h.sqlite"),
    );
    // A rebuilt robot keeps its serial with --force: the record starts a new segment, said.
    let (code, _, err) = run(
        d,
        &argv("history add --robot-id A4-7 --report other.json --db h.sqlite --force"),
    );
    assert_eq!(code, 0, "{err}");
    assert!(
        err.contains("calibration 3 changes the robot model of robot A4-7")
            && err.contains("joint 3 is revolute, earlier prismatic"),
        "{err}"
    );
    let list = run_ok(
        d,
        &["history", "list", "--db", "h.sqlite", "--robot-id", "A4-7"],
    );
    assert_eq!(
        list.lines().filter(|l| l.contains("A4-7")).count(),
        2,
        "{list}"
    );
    // Drift never compares the two models: the earlier one is left out, saying why.
    let out = run_ok(d, &argv("history drift --robot-id A4-7 --db h.sqlite"));
    assert!(
        out.contains("since the change of robot model at calibration 3")
            && out.contains("calibration 1 is not compared")
            && out.contains("nothing to compare: one calibration"),
        "{out}"
    );
}

/// `history add` of a report whose calibration `calibrate` refused (its units) recorded it,
/// exit 0: refused, naming the report and why, and no history file is created.
#[test]
fn a_refused_calibration_is_not_recorded() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut r: serde_json::Value = serde_json::from_str(&reports().0).unwrap();
    r["refused"] = "REFUSED: a unit check fired (are they in mm?): no calibrated robot is \
                    written or recorded."
        .into();
    std::fs::write(d.join("refused.json"), r.to_string()).unwrap();
    let err = run_err(
        d,
        &argv("history add --robot-id RF --report refused.json --db h.sqlite"),
    );
    assert!(
        err.contains("refused.json: the report says the calibration was REFUSED (a unit check")
            && err.contains("nothing was written"),
        "{err}"
    );
    assert!(!d.join("h.sqlite").exists());
}

#[test]
fn control_characters_in_serials_and_notes_are_escaped() {
    let dir = history(0);
    let d = dir.path();
    let serial = "A4\u{1b}[31m-RED";
    // Two calibrations (a time each: the same report at the same time is recorded once).
    for (note, at) in [
        ("line one\nline two\u{1b}[0m", "2026-10-01"),
        ("tab\there\r", "2026-11-01"),
    ] {
        run_ok(
            d,
            &[
                "history",
                "add",
                "--robot-id",
                serial,
                "--report",
                "r1.json",
                "--db",
                "h.sqlite",
                "--note",
                note,
                "--at",
                at,
            ],
        );
    }
    let outputs = [
        run_ok(d, &["history", "list", "--db", "h.sqlite"]),
        run_ok(d, &["history", "show", "--db", "h.sqlite", "--id", "1"]),
        run(
            d,
            &["history", "drift", "--db", "h.sqlite", "--robot-id", serial],
        )
        .1,
    ];
    for out in &outputs {
        assert!(
            !out.contains(['\u{1b}', '\r', '\t']),
            "control characters printed: {out:?}"
        );
        assert!(out.contains("A4\\x1b[31m-RED"), "{out}");
    }
    assert!(
        outputs[0].contains("line one\\nline two\\x1b[0m"),
        "{}",
        outputs[0]
    );
    assert!(outputs[0].contains("tab\\there\\r"), "{}", outputs[0]);
    // One line per record (and the header).
    assert_eq!(outputs[0].lines().count(), 3, "{}", outputs[0]);
    // JSON is escaped by JSON itself and keeps the text.
    let json: serde_json::Value = serde_json::from_str(&run_ok(
        d,
        &["history", "show", "--db", "h.sqlite", "--id", "1", "--json"],
    ))
    .unwrap();
    assert_eq!(json["note"], "line one\nline two\u{1b}[0m");
}

#[test]
fn drift_refuses_a_threshold_that_is_not_a_positive_number() {
    let dir = history(2);
    let d = dir.path();
    for sigma in ["--sigma=inf", "--sigma=NaN", "--sigma=0", "--sigma=-1"] {
        let err = run_err(
            d,
            &argv(&format!(
                "history drift --db h.sqlite --robot-id A4-7 {sigma}"
            )),
        );
        assert!(
            err.contains("--sigma") && err.contains("positive") && err.contains("finite"),
            "{sigma}: {err}"
        );
    }
}

#[test]
fn drift_and_plot_say_what_they_left_out() {
    let dir = history(1);
    let d = dir.path();
    // The second run did not determine link1.x (as if the data had not seen it).
    let mut r = common::read_json(&d.join("r2.json"));
    let p = r["parameters"]
        .as_array_mut()
        .unwrap()
        .iter_mut()
        .find(|p| p["name"] == "link1.x")
        .unwrap();
    assert_eq!(
        p["determined"], true,
        "link1.x is determined in the fixture"
    );
    p["determined"] = false.into();
    p.as_object_mut().unwrap().remove("sigma");
    std::fs::write(d.join("r2b.json"), r.to_string()).unwrap();
    run_ok(
        d,
        &argv("history add --robot-id A4-7 --report r2b.json --db h.sqlite --at 2026-05-01"),
    );
    // An unquoted dotted key is natural TOML; link9.x and p99 match nothing.
    std::fs::write(
        d.join("tol.toml"),
        "[tolerances]\nlink1.y = 0.5\nlink9.x = 0.1\np99 = 0.2\n\"p14 + p20\" = 0.5\n",
    )
    .unwrap();
    let (code, out, err) = run(
        d,
        &argv("history drift --db h.sqlite --robot-id A4-7 --tolerance tol.toml"),
    );
    assert!(code == 0 || code == 3, "{err}");
    let text = format!("{out}{err}");
    assert!(
        text.contains("link1.x") && text.contains("not determined") && text.contains("latest"),
        "{text}"
    );
    assert!(text.contains("link9.x") && text.contains("p99"), "{text}");
    let (_, out, err) = run(
        d,
        &argv("history drift --db h.sqlite --robot-id A4-7 --tolerance tol.toml --json"),
    );
    let j: serde_json::Value = serde_json::from_str(&out).unwrap_or_else(|e| panic!("{e}: {err}"));
    let left = j["left_out"].as_array().unwrap();
    assert!(
        left.iter()
            .any(|q| q["key"] == "link1.x"
                && q["reason"].as_str().unwrap().contains("not determined")),
        "{out}"
    );
    let unused: Vec<&str> = j["unused_tolerances"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t["key"].as_str().unwrap())
        .collect();
    assert_eq!(unused, ["link9.x", "p99"], "{out}");
    let y = j["quantities"]
        .as_array()
        .unwrap()
        .iter()
        .find(|q| q["key"] == "link1.y")
        .expect("link1.y tracked");
    assert_eq!(y["tolerance"], 0.5);
    // plot: an entry that matches nothing is named.
    let (code, _, err) = run(
        d,
        &argv(
            "history plot --db h.sqlite --robot-id A4-7 --param link1.y,nothing.here,link1.x
             --out p.svg",
        ),
    );
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("nothing.here"), "{err}");
    assert!(
        err.contains("link1.x") && err.contains("not determined"),
        "{err}"
    );
}

#[test]
fn plot_writes_the_format_its_name_asks_for() {
    let dir = history(2);
    let d = dir.path();
    let plot = |out: &str| {
        run(
            d,
            &[
                "history",
                "plot",
                "--db",
                "h.sqlite",
                "--robot-id",
                "A4-7",
                "--param",
                "p14 + p20",
                "--out",
                out,
            ],
        )
    };
    let (code, _, err) = plot("a4.png");
    assert_eq!(code, 0, "{err}");
    assert!(std::fs::read(d.join("a4.png"))
        .unwrap()
        .starts_with(b"\x89PNG\r\n\x1a\n"));
    let (code, _, err) = plot("A4.SVG");
    assert_eq!(code, 0, "{err}");
    assert!(std::fs::read_to_string(d.join("A4.SVG"))
        .unwrap()
        .starts_with("<svg"));
    for bad in ["a4.pdf", "a4"] {
        let (code, _, err) = plot(bad);
        assert_eq!(code, 1, "{err}");
        assert!(err.contains(".svg") && err.contains(".png"), "{err}");
        assert!(!d.join(bad).exists());
    }
}
