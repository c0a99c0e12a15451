#![cfg_attr(not(feature = "postgres"), allow(unused))]
//! The fleet's history through the command line, on SQLite and PostgreSQL (`KINECAL_TEST_PG`;
//! skipped without one unless `CI` is set): a history moved SQLite -> PostgreSQL -> SQLite prints
//! the same; `batch --record` in shards from many processes, killed and retried, records every
//! robot once; passwords are never printed.

mod common;
#[cfg(feature = "postgres")]
#[path = "../../kinecal-history/tests/common/pg.rs"]
mod pg;

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::run_ok as ok;
use common::{argv, run};
use rand::{RngExt, SeedableRng};

fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_kinecal")
}

fn repo() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// What the read commands print for a history: list, events, show (every record, text and
/// JSON), drift (every robot), plot (the SVG), fleet (text and JSON without the location).
fn outputs(dir: &Path, db: &str) -> Vec<(String, i32, String)> {
    let tol = repo().join("examples/fleet/tolerances.toml");
    let tol = tol.to_str().unwrap();
    let mut out = Vec::new();
    let mut cmd = |args: Vec<String>| {
        let mut a: Vec<&str> = args.iter().map(String::as_str).collect();
        a.extend(["--db", db]);
        let (code, o, e) = run(dir, &a);
        assert!(code == 0 || code == 3, "{a:?}: {e}");
        out.push((args.join(" "), code, o));
    };
    let s = |v: &[&str]| v.iter().map(|x| x.to_string()).collect::<Vec<_>>();
    cmd(s(&["history", "list"]));
    cmd(s(&["history", "events"]));
    for id in 1..=16 {
        cmd(s(&["history", "show", "--id", &id.to_string()]));
        cmd(s(&["history", "show", "--id", &id.to_string(), "--json"]));
    }
    for r in ["A4-0101", "A4-0102", "A4-0103", "A4-0104"] {
        cmd(s(&[
            "history",
            "drift",
            "--robot-id",
            r,
            "--tolerance",
            tol,
        ]));
        cmd(s(&["history", "drift", "--robot-id", r, "--json"]));
    }
    cmd(s(&[
        "history",
        "fleet",
        "--tolerance",
        tol,
        "--now",
        "2026-12-15",
        "--horizon",
        "180",
        "--json",
        "fleet.json",
    ]));
    cmd(s(&argv("history plot --robot-id A4-0103 --out plot.svg")));
    out.push((
        "plot.svg".into(),
        0,
        std::fs::read_to_string(dir.join("plot.svg")).unwrap(),
    ));
    let mut json = common::read_json(&dir.join("fleet.json"));
    json["history"] = serde_json::Value::Null;
    out.push(("fleet.json".into(), 0, json.to_string()));
    out
}

#[test]
#[cfg(feature = "postgres")]
fn a_history_moved_sqlite_postgres_sqlite_prints_the_same() {
    let Some(t) = pg::TestDb::new("cli_moves") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let example = repo().join("examples/fleet/history.json");
    ok(
        d,
        &[
            "history",
            "import",
            example.to_str().unwrap(),
            "--db",
            "a.sqlite",
        ],
    );
    ok(
        d,
        &argv("history export --format dump --db a.sqlite --out a.json"),
    );
    let (_, _, e) = run(d, &["history", "import", "a.json", "--db", &t.url]);
    assert!(e.contains("16 calibrations written"), "{e}");
    ok(
        d,
        &[
            "history", "export", "--format", "dump", "--db", &t.url, "--out", "p.json",
        ],
    );
    ok(d, &["history", "import", "p.json", "--db", "b.sqlite"]);
    ok(
        d,
        &argv("history export --format dump --db b.sqlite --out b.json"),
    );
    let read = |f: &str| std::fs::read_to_string(d.join(f)).unwrap();
    assert_eq!(read("a.json"), read("p.json"));
    assert_eq!(read("a.json"), read("b.json"));
    let a = outputs(d, "a.sqlite");
    let p = outputs(d, &t.url);
    let b = outputs(d, "b.sqlite");
    for ((x, y), z) in a.iter().zip(&p).zip(&b) {
        assert_eq!(x, y, "SQLite and PostgreSQL differ");
        assert_eq!(x, z, "the SQLite histories differ");
    }
    assert_eq!((a.len(), p.len(), b.len()), (46, 46, 46));
    // Something was compared: the drifting robot is flagged.
    assert!(a.iter().any(
        |(c, code, o)| c.starts_with("history drift --robot-id A4-0101")
            && *code == 3
            && o.contains("FLAG")
    ));
    // Importing again adds nothing.
    let (_, _, e) = run(d, &["history", "import", "a.json", "--db", &t.url]);
    assert!(
        e.contains("0 calibrations written, 16 already there"),
        "{e}"
    );
}

/// 200 simulated robots in a manifest, run as 4 shards at once, each recording into the one
/// server; shards are killed at random moments and rerun, as a job system retries a task: in
/// the end every robot is recorded exactly once.
#[test]
#[cfg(feature = "postgres")]
fn batch_shards_killed_and_retried_record_every_robot_once() {
    let Some(t) = pg::TestDb::new("cli_shards") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut manifest = String::from("serial,robot,data,options\n");
    for k in 0..200 {
        let f = format!("r{k:03}.csv");
        ok(
            d,
            &argv(&format!(
                "simulate --robot ge-a4 --postures 20 --seed {k} --perturb p1=+0.05,p14=-0.02
                 --noise length=0.0005,angle=0.005 --out {f}"
            )),
        );
        manifest += &format!(
            "FLEET-{k:03},ge-a4,{f},\"--estimate p1-p2,p14 --weights length=0.0005,angle=0.005\"\n"
        );
    }
    std::fs::write(d.join("fleet.csv"), manifest).unwrap();
    // The schema first (as the owner's `history init`).
    ok(d, &["history", "init", "--db", &t.url]);
    let spawn = |k: usize| {
        Command::new(bin())
            .current_dir(d)
            .args(["batch", "fleet.csv", "--record", "--quiet", "--jobs", "1"])
            .args(["--shard", &format!("{k}/4"), "--db", &t.url])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap()
    };
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2028);
    let started = Instant::now();
    let mut running: Vec<_> = (1..=4).map(|k| (k, spawn(k))).collect();
    let (mut round, mut kills) = (0, 0);
    while !running.is_empty() {
        round += 1;
        if round <= 3 {
            std::thread::sleep(Duration::from_millis(rng.random_range(30..400)));
            // In the first round one shard is always killed, then any with probability 1/2.
            let always = rng.random_range(0..running.len());
            for (i, (_, c)) in running.iter_mut().enumerate() {
                let kill = (round == 1 && i == always) || rng.random_range(0..2) == 0;
                if kill && c.try_wait().unwrap().is_none() {
                    let _ = c.kill();
                    kills += 1;
                }
            }
        }
        let mut again = Vec::new();
        for (k, mut c) in running {
            if !c.wait().unwrap().success() {
                again.push((k, spawn(k)));
            }
        }
        running = again;
        assert!(round < 30, "the shards keep failing");
    }
    assert!(kills > 0, "no shard was killed: the retry was not tested");
    let mut c = t.client();
    let rows = c
        .query(
            "SELECT robot_id, count(*) FROM kinecal.calibrations GROUP BY robot_id",
            &[],
        )
        .unwrap();
    assert_eq!(rows.len(), 200, "robots recorded");
    assert!(
        rows.iter().all(|r| r.get::<_, i64>(1) == 1),
        "a robot recorded twice"
    );
    let params: i64 = c
        .query_one("SELECT count(*) FROM kinecal.parameters", &[])
        .unwrap()
        .get(0);
    assert_eq!(params, 200 * 38, "a partial record");
    // A whole rerun of every shard adds nothing.
    for k in 1..=4 {
        assert!(spawn(k).wait().unwrap().success());
    }
    let n: i64 = c
        .query_one("SELECT count(*) FROM kinecal.calibrations", &[])
        .unwrap()
        .get(0);
    assert_eq!(n, 200);
    eprintln!(
        "200 robots in 4 shards, {kills} shard runs killed and rerun: {:.1} s",
        started.elapsed().as_secs_f64()
    );
}

#[test]
fn shards_are_checked_and_cover_the_manifest_once() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let example = repo().join("examples/fleet/fleet.csv");
    let m = example.to_str().unwrap();
    for bad in ["0/3", "4/3", "1/0", "x", "1/2/3"] {
        let (code, _, e) = run(d, &["batch", m, "--shard", bad]);
        assert_eq!(code, 1, "--shard {bad}");
        assert!(e.contains("expected K/N with 1 <= K <= N"), "{e}");
    }
    // 3 robots in 2 shards: 2 and 1, together each robot once.
    let mut seen = Vec::new();
    for k in ["1/2", "2/2"] {
        let (_, out, e) = run(d, &["batch", m, "--shard", k, "--quiet"]);
        assert!(e.contains(&format!("shard {k}: ")), "{e}");
        seen.extend(
            out.lines()
                .filter(|l| l.starts_with("A4-") && l.contains("  "))
                .map(|l| l.split_whitespace().next().unwrap().to_string()),
        );
    }
    seen.sort();
    assert_eq!(seen, ["A4-0042", "A4-0043", "A4-0044"]);
    // More shares than robots (an indexed job with more completions): the extra shares have
    // nothing to do, and succeed, so that the job does.
    let (code, out, e) = run(d, &["batch", m, "--shard", "5/5", "--quiet"]);
    assert_eq!(code, 0, "{out}\n{e}");
    assert!(
        e.contains("shard 5/5 of 3 robots is empty: nothing to do"),
        "{e}"
    );
    assert!(!out.contains("A4-"), "{out}");
}

#[test]
fn passwords_are_never_printed() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let secret = "Sup3r-s3cret-pw";
    let url = format!("postgres://alice:{secret}@127.0.0.1:1/kinecal");
    for args in [
        vec!["history", "list", "--db", &url],
        vec!["history", "fleet", "--db", &url],
        vec!["history", "init", "--db", &url],
        vec!["history", "event", "R1", "--note", "x", "--db", &url],
    ] {
        let (code, out, err) = run(d, &args);
        assert_eq!(code, 1, "{args:?}");
        assert!(
            err.contains("postgres://alice@127.0.0.1:1/kinecal"),
            "{err}"
        );
        assert!(!out.contains(secret) && !err.contains(secret), "{err}");
    }
    // Through $KINECAL_DB too.
    let out = Command::new(bin())
        .current_dir(d)
        .args(["history", "list"])
        .env("KINECAL_DB", &url)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && !err.contains(secret) && err.contains("cannot connect"),
        "{err}"
    );
    // A wrong password on a real server.
    #[cfg(feature = "postgres")]
    if let Some(t) = pg::TestDb::new("cli_password") {
        let wrong = pg::with_user(&t.url, "postgres", secret);
        let (code, out, err) = run(d, &["history", "list", "--db", &wrong]);
        assert_eq!(code, 1);
        assert!(err.contains("password authentication failed"), "{err}");
        assert!(!out.contains(secret) && !err.contains(secret), "{err}");
    }
}

/// A history of schema version 1 (written by kinecal before version 2; see
/// crates/kinecal-history/tests/data/README.md) prints what that kinecal printed, read as it
/// is and after its migration.
#[test]
fn a_version_1_history_prints_the_same_before_and_after_its_migration() {
    let data = repo().join("crates/kinecal-history/tests/data");
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::copy(data.join("v1-history.sqlite"), d.join("v1.sqlite")).unwrap();
    let show = std::fs::read_to_string(data.join("v1-history.show.txt")).unwrap();
    let drift = std::fs::read_to_string(data.join("v1-history.drift.txt")).unwrap();
    let check = |when: &str| {
        let (code, out, e) = run(d, &argv("history show --robot-id A4-0042 --db v1.sqlite"));
        assert_eq!((code, out.as_str()), (0, show.as_str()), "show {when}: {e}");
        let (code, out, e) = run(d, &argv("history drift --robot-id A4-0042 --db v1.sqlite"));
        assert_eq!(
            (code, out.as_str()),
            (3, drift.as_str()),
            "drift {when}: {e}"
        );
    };
    check("before the migration");
    let (code, _, e) = run(d, &["history", "init", "--db", "v1.sqlite"]);
    assert_eq!(code, 0, "{e}");
    assert!(e.contains("schema version 2"), "{e}");
    check("after the migration");
}

/// A robot whose latest record lost its parameters (a damaged history) is UNKNOWN in the
/// fleet's table, and the summary sentence counts it (issue 38: it counted the flagged,
/// serviced, due, ok and single robots only, so its figures did not add up to the robots).
#[test]
fn the_fleet_summary_counts_the_unknown_robots() {
    let dir = tempfile::tempdir().unwrap();
    let dump = repo().join("examples/fleet/history.json");
    ok(
        dir.path(),
        &[
            "history",
            "import",
            dump.to_str().unwrap(),
            "--db",
            "h.sqlite",
        ],
    );
    let db = rusqlite::Connection::open(dir.path().join("h.sqlite")).unwrap();
    let latest: i64 = db
        .query_row(
            "SELECT MAX(id) FROM calibrations WHERE robot_id = 'A4-0102'",
            [],
            |r| r.get(0),
        )
        .unwrap();
    db.execute("DELETE FROM parameters WHERE calibration_id = ?1", [latest])
        .unwrap();
    drop(db);
    let (code, out, err) = run(
        dir.path(),
        &argv("history fleet --db h.sqlite --now 2026-12-15"),
    );
    assert_eq!(code, 3, "{out}{err}");
    let summary = out.lines().next().unwrap();
    assert!(
        summary.starts_with("4 robots: 1 flagged, 1 unknown, 0 serviced, 0 due, 2 ok, 0 with"),
        "{out}"
    );
    assert!(
        out.lines()
            .any(|l| l.starts_with("A4-0102") && l.contains("UNKNOWN")),
        "{out}"
    );
}
