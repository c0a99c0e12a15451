//! `kinecal iso9283` as a user runs it: plan, simulate and evaluate end to end (text, JSON,
//! HTML), fewer cycles than the standard's, bad logs refused with file, line and field, outputs
//! through the safe writer, and AP and RP cross-checked with Python when it is there.

use std::path::{Path, PathBuf};

mod common;

use common::{argv, run, run_err};

fn irb120() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples/robots/abb_irb120.toml")
        .canonicalize()
        .unwrap()
}

/// Runs a command expected to succeed; its standard output and error.
fn run_ok(dir: &Path, args: &[&str]) -> (String, String) {
    let (code, out, err) = run(dir, args);
    assert_eq!(code, 0, "{args:?}: {err}");
    (out, err)
}

/// A plan in a given cube (no search: fast) and a simulated log of `cycles` cycles on the robot
/// with one link lengthened by 1 mm.
fn planned_log(dir: &Path, cycles: &str) {
    let robot = irb120();
    let robot = robot.to_str().unwrap();
    let (out, err) = run_ok(
        dir,
        &[
            "iso9283",
            "plan",
            "--robot",
            robot,
            "--cube",
            "0.35,0,0.35,0.2",
            "--attitude",
            "3.141592653589793,0,0",
            "--out",
            "poses.csv",
        ],
    );
    assert!(
        out.contains("cube: centre (0.3500, 0, 0.3500) m, side 0.2000 m"),
        "{out}"
    );
    assert!(
        out.contains("each cycle visits P1, P5, P4, P3, P2"),
        "{out}"
    );
    assert!(err.contains("wrote the test poses to poses.csv"), "{err}");
    run_ok(
        dir,
        &[
            "simulate",
            "--robot",
            robot,
            "--postures",
            "1",
            "--perturb",
            "link3.x=+0.001",
            "--out",
            "unused.csv",
            "--truth",
            "truth.toml",
        ],
    );
    let (_, err) = run_ok(
        dir,
        &argv(&format!(
            "iso9283 simulate --robot truth.toml --poses poses.csv --cycles {cycles}
             --noise length=0.00002,angle=0.00005 --seed 4 --out log.csv"
        )),
    );
    assert!(
        err.contains("wrote a simulated log (not a measurement)"),
        "{err}"
    );
}

#[test]
fn plan_simulate_evaluate_end_to_end() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    planned_log(d, "30");
    let (out, err) = run_ok(
        d,
        &argv("iso9283 evaluate --data log.csv --json iso.json --html iso.html"),
    );
    assert!(
        out.starts_with("ISO 9283 pose characteristics of log.csv (simulated): 5 poses"),
        "{out}"
    );
    for p in 1..=5 {
        assert!(
            out.contains(&format!("P{p}: 30 cycles, commanded")),
            "{out}"
        );
    }
    assert!(out.contains("RPa  +-"), "{out}");
    assert!(out.contains("P2-P4"), "{out}");
    assert!(!out.lines().any(|l| l.ends_with(' ')), "{out}");
    // 30 cycles: the only warning is that the log is simulated.
    assert!(!err.contains("fewer than"), "{err}");
    assert!(err.contains("warning: the log is simulated"), "{err}");
    let json = common::check_document_file("iso9283", &d.join("iso.json"));
    let poses = json["poses"].as_array().unwrap();
    assert_eq!(poses.len(), 5);
    for p in poses {
        assert_eq!(p["cycles"], 30);
        // The 1 mm longer link moves every pose by about a millimetre; noise 0.02 mm.
        let ap = p["ap"].as_f64().unwrap();
        assert!(ap > 0.0003 && ap < 0.002, "{p}");
        let rp = p["rp"].as_f64().unwrap();
        assert!(rp > 0.00003 && rp < 0.0002, "{p}");
    }
    assert_eq!(json["length_unit"], "m");
    assert_eq!(json["simulated"], true);
    let html = std::fs::read_to_string(d.join("iso.html")).unwrap();
    assert!(
        html.starts_with("<!DOCTYPE html>") && html.contains("<svg"),
        "{html}"
    );
    assert!(!html.contains("http"), "the page links to nothing");
    assert_eq!(html.matches("<h2>P").count(), 5);
}

#[test]
fn fewer_cycles_than_the_standard_are_computed_with_a_warning() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    planned_log(d, "5");
    let (out, err) = run_ok(d, &["iso9283", "evaluate", "--data", "log.csv"]);
    assert!(out.contains("P3: 5 cycles"), "{out}");
    assert!(
        err.contains("warning: P1, P2, P3, P4, P5: 5 cycles, fewer than the 30 ISO 9283 asks for"),
        "{err}"
    );
    // One cycle: the accuracy, no repeatability, and a warning that says so.
    planned_log(d, "1");
    let (out, err) = run_ok(d, &["iso9283", "evaluate", "--data", "log.csv"]);
    assert!(out.contains("P3: 1 cycle, commanded"), "{out}");
    assert!(out.contains("RP   n/a (1 cycle)"), "{out}");
    assert!(
        err.contains(
            "warning: P1, P2, P3, P4, P5: 1 cycle: its accuracy (AP, AD) is computed; its \
             repeatability"
        ),
        "{err}"
    );
}

/// A measurement series (18 postures of the IRB 120 whose third link is 1 mm longer than its
/// file says, measured by position) as two tests of nine poses, before calibration (the
/// nominal model drives it) and after (a calibration on 30 other postures), with the AP
/// predicted once compensated.
#[test]
fn a_measurement_series_gives_iso_figures_before_and_after_calibration() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let robot = irb120();
    let robot = robot.to_str().unwrap();
    for (postures, seed, out) in [("30", "1", "cal.csv"), ("19", "2", "series.csv")] {
        run_ok(
            d,
            &[
                "simulate",
                "--robot",
                robot,
                "--postures",
                postures,
                "--seed",
                seed,
                "--perturb",
                "link3.x=+0.001",
                "--noise",
                "length=0.00001,angle=0",
                "--position-only",
                "--out",
                out,
                "--truth",
                "truth.toml",
            ],
        );
    }
    run_ok(
        d,
        &[
            "calibrate",
            "--robot",
            robot,
            "--data",
            "cal.csv",
            "--estimate",
            "identifiable",
            "--predict",
            "--out",
            "cal.toml",
            "--report",
            "cal.json",
            "--quiet",
        ],
    );
    // Postures 1..18 in two tests (the centre, then the corners); posture 19 has no role.
    let mut roles = String::from("posture,test,pose,cycle\n");
    for k in 0..18 {
        let pose = match k % 9 {
            0 => "P1".to_string(),
            c => format!("C{c}"),
        };
        roles += &format!("{},cube {},{pose},1\n", k + 1, k / 9 + 1);
    }
    std::fs::write(d.join("roles.csv"), roles).unwrap();
    let (_, err) = run_ok(
        d,
        &[
            "iso9283",
            "log",
            "--robot",
            robot,
            "--data",
            "series.csv",
            "--roles",
            "roles.csv",
            "--out",
            "before.csv",
        ],
    );
    assert!(
        err.contains("left out 1 measured posture without a role in roles.csv (19)"),
        "{err}"
    );
    assert!(
        err.contains("wrote the ISO 9283 log of 18 rows (2 tests;"),
        "{err}"
    );
    run_ok(
        d,
        &argv("iso9283 log --robot cal.toml --data series.csv --roles roles.csv --out after.csv"),
    );
    let mut ap = Vec::new();
    for log in ["before.csv", "after.csv"] {
        let (out, _) = run_ok(
            d,
            &argv(&format!(
                "iso9283 evaluate --data {log} --robot cal.toml --report cal.json --json iso.json
                 --html iso.html"
            )),
        );
        assert!(out.contains("2 tests, 18 poses; lengths in m"), "{out}");
        assert!(
            out.contains("compensated AP, predicted RMS / 95 % bound"),
            "{out}"
        );
        let e = common::check_document_file("iso9283", &d.join("iso.json"));
        let poses = e["poses"].as_array().unwrap();
        assert_eq!(poses.len(), 18);
        for p in poses {
            assert_eq!(p["compensated"]["readings_from"], "log", "{p}");
            assert!(p["compensated"]["ap_95"].as_f64().unwrap() > 0.0);
            assert!(p["rp"].is_null());
        }
        let every = e["summary"]["poses"]
            .as_array()
            .unwrap()
            .iter()
            .find(|p| p["pose"] == 0)
            .unwrap()
            .clone();
        ap.push(every["ap"]["mean"].as_f64().unwrap());
        let html = std::fs::read_to_string(d.join("iso.html")).unwrap();
        assert!(html.contains("Across the 2 tests") && html.contains("Every test"));
    }
    // A 1 mm longer link leaves AP near a millimetre before; the calibration, near the 0.01 mm
    // noise after.
    assert!(ap[0] > 3e-4 && ap[1] < 1e-4, "{ap:?}");
    // A robot that is not the report's is refused.
    let err = run_err(
        d,
        &[
            "iso9283",
            "evaluate",
            "--data",
            "before.csv",
            "--robot",
            robot,
            "--report",
            "cal.json",
        ],
    );
    assert!(
        err.contains("cal.json: ") && err.contains("is not the calibrated robot of this report"),
        "{err}"
    );
    // A roles file naming a posture twice.
    std::fs::write(
        d.join("bad.csv"),
        "posture,test,pose,cycle\n1,t,P1,1\n1,t,C1,1\n",
    )
    .unwrap();
    let err = run_err(
        d,
        &[
            "iso9283",
            "log",
            "--robot",
            robot,
            "--data",
            "series.csv",
            "--roles",
            "bad.csv",
            "--out",
            "x.csv",
        ],
    );
    assert!(
        err.contains("error: bad.csv:3: field `posture`: posture `1` is given a role twice"),
        "{err}"
    );
    assert!(!d.join("x.csv").exists());
}

#[test]
fn bad_logs_are_refused_with_file_line_and_field() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let good = "pose,cycle,xc,yc,zc,x,y,z\n1,1,0,0,0,1,0,0\n1,2,0,0,0,1,0,0\n";
    let cases = [
        (
            "pose,cycle,xc,yc,zc,x,y\n1,1,0,0,0,1,0\n",
            "error: log.csv:1: field `z`: no column `z` in the header",
        ),
        (
            "pose,cycle,xc,yc,zc,x,y,z\n1,1,0,0,0,1,oops,0\n",
            "error: log.csv:2: field `y`: expected a number, found `oops`",
        ),
        (
            "pose,cycle,xc,yc,zc,x,y,z\n1,1,0,0,0,1,0,0\n9,1,0,0,0,1,0,0\n",
            "error: log.csv:3: field `pose`: pose index 9 is out of 1..5",
        ),
        (
            "pose,cycle,xc,yc,zc,x,y,z\n1,1,0,0,0,1,0,nan\n",
            "error: log.csv:2: field `z`: expected a finite number",
        ),
        (
            "pose,cycle,xc,yc,zc,ac,bc,cc,x,y,z,a,b,c\n1,1,0,0,0,0,0,0,1,0,0,0,0,0\n",
            "error: log.csv: the log has attitudes but states no angle unit",
        ),
    ];
    for (text, want) in cases {
        std::fs::write(d.join("log.csv"), text).unwrap();
        let err = run_err(d, &argv("iso9283 evaluate --data log.csv --json out.json"));
        assert!(err.contains(want), "{text:?}: {err}");
        assert!(!d.join("out.json").exists(), "nothing written on an error");
    }
    std::fs::write(d.join("log.csv"), good).unwrap();
    // An output over the input is refused.
    let err = run_err(d, &argv("iso9283 evaluate --data log.csv --json log.csv"));
    assert!(
        err.contains("refusing to write an output over an input"),
        "{err}"
    );
    // The flags: a cube of no side, an attitude of two angles.
    let robot = irb120();
    let robot = robot.to_str().unwrap();
    let err = run_err(
        d,
        &["iso9283", "plan", "--robot", robot, "--cube", "0,0,0,-1"],
    );
    assert!(
        err.contains("--cube: the side must be positive, not -1"),
        "{err}"
    );
    let err = run_err(
        d,
        &["iso9283", "plan", "--robot", robot, "--attitude", "1,2"],
    );
    assert!(err.contains("--attitude `1,2`: expected A,B,C"), "{err}");
    let err = run_err(
        d,
        &["iso9283", "plan", "--robot", robot, "--cube", "3,0,0,0.1"],
    );
    assert!(
        err.contains("P1 (3, 0, 0 m) of the cube is out of reach"),
        "{err}"
    );
}

#[cfg(unix)]
#[test]
fn outputs_go_through_the_safe_writer() {
    use std::os::unix::fs::PermissionsExt as _;
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    std::fs::write(
        d.join("log.csv"),
        "# length_unit = mm\npose,cycle,xc,yc,zc,x,y,z\n1,1,0,0,0,1,0,0\n1,2,0,0,0,0,1,0\n1,3,0,0,0,0,0,1\n",
    )
    .unwrap();
    // Through a symlink: the file it points to is written, the link stays.
    std::fs::write(d.join("real.json"), "old").unwrap();
    std::fs::set_permissions(d.join("real.json"), std::fs::Permissions::from_mode(0o640)).unwrap();
    std::os::unix::fs::symlink("real.json", d.join("link.json")).unwrap();
    run_ok(d, &argv("iso9283 evaluate --data log.csv --json link.json"));
    assert!(std::fs::symlink_metadata(d.join("link.json"))
        .unwrap()
        .file_type()
        .is_symlink());
    let json = std::fs::read_to_string(d.join("real.json")).unwrap();
    assert!(json.contains("\"ap\""), "{json}");
    // Its mode is kept.
    let mode = std::fs::metadata(d.join("real.json"))
        .unwrap()
        .permissions()
        .mode();
    assert_eq!(mode & 0o777, 0o640);
    // Standard output as a file name.
    let (out, _) = run_ok(
        d,
        &["iso9283", "evaluate", "--data", "log.csv", "--json", "-"],
    );
    assert!(out.contains("\"rp\""), "{out}");
    // No temporary file left behind.
    for e in std::fs::read_dir(d).unwrap() {
        let name = e.unwrap().file_name();
        assert!(
            !name.to_string_lossy().starts_with(".kinecal-tmp"),
            "{name:?}"
        );
    }
}

/// AP and RP of the simulated log, computed by a few lines of Python from the CSV, agree with
/// kinecal's. Skipped when no `python3` is on the path.
#[test]
fn ap_and_rp_agree_with_python() {
    if std::process::Command::new("python3")
        .arg("--version")
        .output()
        .is_err()
    {
        eprintln!("skipped: no python3");
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    planned_log(d, "30");
    run_ok(d, &argv("iso9283 evaluate --data log.csv --json iso.json"));
    let script = r##"
import csv, json, math, statistics
rows = [r for r in csv.reader(l for l in open("log.csv") if not l.startswith("#"))]
head, rows = rows[0], rows[1:]
col = {h: i for i, h in enumerate(head)}
out = {}
for pose in sorted({int(r[col["pose"]]) for r in rows}):
    mine = [r for r in rows if int(r[col["pose"]]) == pose]
    att = [[float(r[col[k]]) for k in "xyz"] for r in mine]
    cmd = [float(mine[0][col[k + "c"]]) for k in "xyz"]
    bary = [statistics.fmean(p[k] for p in att) for k in range(3)]
    ap = math.dist(bary, cmd)
    l = [math.dist(p, bary) for p in att]
    out[pose] = [ap, statistics.fmean(l) + 3 * statistics.stdev(l)]
print(json.dumps(out))
"##;
    let py = std::process::Command::new("python3")
        .current_dir(d)
        .args(["-c", script])
        .output()
        .unwrap();
    assert!(
        py.status.success(),
        "{}",
        String::from_utf8_lossy(&py.stderr)
    );
    let theirs: serde_json::Value = serde_json::from_slice(&py.stdout).unwrap();
    let ours = common::check_document_file("iso9283", &d.join("iso.json"));
    for p in ours["poses"].as_array().unwrap() {
        let k = p["pose"].to_string();
        let (ap, rp) = (p["ap"].as_f64().unwrap(), p["rp"].as_f64().unwrap());
        let t = &theirs[&k];
        assert!(
            (ap - t[0].as_f64().unwrap()).abs() < 1e-12,
            "P{k}: {ap} vs {t}"
        );
        assert!(
            (rp - t[1].as_f64().unwrap()).abs() < 1e-12,
            "P{k}: {rp} vs {t}"
        );
    }
}
