//! One door for every job: the same job said by flags, by `--spec` (the spec `--write-spec`
//! wrote), and as a `[[jobs]]` entry of a batch manifest gives the same outputs and the same
//! document (up to a report's `created` and `timings`). Python's `kinecal.run` and named
//! functions are checked against the specs written here by `crates/kinecal-py/tests`.

use std::path::Path;

mod common;

use common::{argv, run};

fn ok(dir: &Path, args: &[&str]) -> String {
    let (code, out, err) = run(dir, args);
    assert!(code == 0 || code == 4, "{args:?} exited {code}: {err}");
    out
}

/// A document or output as compared: JSON without the keys that differ between any two runs
/// (`created`, `timings`); other text as it is.
fn normal(text: &str) -> String {
    match serde_json::from_str::<serde_json::Value>(text) {
        Ok(mut v) => {
            fn strip(v: &mut serde_json::Value) {
                match v {
                    serde_json::Value::Object(m) => {
                        m.remove("created");
                        m.remove("timings");
                        m.values_mut().for_each(strip);
                    }
                    serde_json::Value::Array(a) => a.iter_mut().for_each(strip),
                    _ => {}
                }
            }
            strip(&mut v);
            v.to_string()
        }
        Err(_) => text.to_string(),
    }
}

/// One job: the command line (outputs named `a_*`), whether it prints its document as JSON
/// (`--json`), and its outputs (`a_*` names).
struct Case {
    name: &'static str,
    args: Vec<&'static str>,
    json: bool,
    outputs: Vec<&'static str>,
}

fn case(name: &'static str, args: &[&'static str], json: bool, outputs: &[&'static str]) -> Case {
    Case {
        name,
        args: args.to_vec(),
        json,
        outputs: outputs.to_vec(),
    }
}

/// A spec's TOML as a `[[jobs]]` table of a manifest, named `name`.
fn as_job(spec: &str, name: &str) -> String {
    let doc: toml_edit::DocumentMut = spec.parse().unwrap();
    let mut table = doc.as_table().clone();
    table.insert("name", toml_edit::value(name));
    let mut jobs = toml_edit::ArrayOfTables::new();
    jobs.push(table);
    let mut manifest = toml_edit::DocumentMut::new();
    manifest.insert("jobs", toml_edit::Item::ArrayOfTables(jobs));
    manifest.to_string()
}

#[test]
fn every_job_gives_the_same_outputs_by_flags_by_spec_and_in_a_batch() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // The data every job works on: the README's GE A4 session.
    ok(
        d,
        &argv(
            "simulate --robot ge-a4 --postures 30 --seed 7
             --perturb p1=+0.05,p14=-0.02,joint2.offset=-0.5,joint4.slope=+0.02
             --noise length=0.0005,angle=0.005 --out data.csv --truth truth.toml",
        ),
    );
    ok(
        d,
        &argv(
            "calibrate --robot ge-a4 --data data.csv --estimate p1,p2,p8,p14,offsets,slopes
             --predict --out cal.toml --report report.json -q",
        ),
    );
    std::fs::copy(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/robots/abb_irb120.toml"),
        d.join("irb.toml"),
    )
    .unwrap();
    ok(
        d,
        &argv(
            "iso9283 plan --robot irb.toml --attitude 3.141592653589793,0,0 --resolution 4
             --out poses.csv",
        ),
    );
    // A camera on the IRB 120's flange and its views of a board (docs/cameras.md).
    let cameras = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/cameras");
    std::fs::copy(cameras.join("eye_in_hand.toml"), d.join("cam.toml")).unwrap();
    std::fs::copy(
        cameras.join("eye_in_hand_truth.toml"),
        d.join("cam_truth.toml"),
    )
    .unwrap();
    ok(
        d,
        &argv(
            "simulate --robot cam_truth.toml --camera wrist --board board --postures 22 --seed 5
             --noise pixel=0.3 --out views.csv",
        ),
    );
    let cases = [
        case(
            "simulate",
            &argv(
                "simulate --robot ge-a4 --postures 12 --seed 3 --perturb p1=+0.05
                 --noise length=0.001 --out a_data.csv --truth a_truth.toml",
            ),
            false,
            &["a_data.csv", "a_truth.toml"],
        ),
        case(
            "calibrate",
            &argv(
                "calibrate --robot ge-a4 --data data.csv --estimate identifiable
                 --huber-spread stated --loss huber --folds 3 --out a_cal.toml
                 --report a_report.json -q",
            ),
            false,
            &["a_cal.toml", "a_report.json"],
        ),
        case(
            "analyze",
            &argv("analyze --robot ge-a4 --data data.csv --estimate all --rcond 1e-8 --json"),
            true,
            &[],
        ),
        case(
            "plan",
            &argv(
                "plan --robot ge-a4 --sample 150 --seed 3 --count 6 --criterion i --out a_plan.csv
                 --json",
            ),
            true,
            &["a_plan.csv"],
        ),
        case(
            "predict",
            &argv(
                "predict --robot cal.toml --report report.json --sample 40 --seed 2
                 --out a_predicted.csv",
            ),
            false,
            &["a_predicted.csv"],
        ),
        case(
            "compensate",
            &argv(
                "compensate --robot cal.toml --nominal ge-a4 --in data.csv --position-only
                 --tolerance length=1e-6 --out a_compensated.csv",
            ),
            false,
            &["a_compensated.csv"],
        ),
        case(
            "check",
            &argv("check --robot cal.toml --data data.csv --threshold 0.01,0.05 --json"),
            true,
            &[],
        ),
        case(
            "fk",
            &argv("fk --robot truth.toml --postures data.csv --out a_poses.csv"),
            false,
            &["a_poses.csv"],
        ),
        case(
            "export",
            &argv("export dh --robot irb.toml --convention modified --out a_dh.csv"),
            false,
            &["a_dh.csv"],
        ),
        case(
            "export-joints",
            &argv(
                "export joints --robot cal.toml --nominal ge-a4 --tolerance length=1,angle=1
                 --out a_joints.csv",
            ),
            false,
            &["a_joints.csv"],
        ),
        case(
            "import",
            &[
                "import",
                "dh",
                "../dh.csv",
                "--name",
                "from dh",
                "--out",
                "a_imported.toml",
            ],
            false,
            &["a_imported.toml"],
        ),
        case(
            "report",
            &["report", "--from", "report.json", "--out", "a_page.html"],
            false,
            &["a_page.html"],
        ),
        case(
            "curves",
            &argv(
                "curves pose --robot ge-a4 --readings 12.5,-16.25,1,10 --param p4 --span 360
                 --points 21 --out a_p4.csv",
            ),
            false,
            &["a_p4.csv"],
        ),
        case(
            "curves-objective",
            &argv(
                "curves objective --robot ge-a4 --data data.csv --param p1 --points 11
                 --out a_objective.csv",
            ),
            false,
            &["a_objective.csv"],
        ),
        case(
            "iso9283-simulate",
            &argv(
                "iso9283 simulate --robot irb.toml --poses poses.csv --cycles 3
                 --noise length=0.001 --out a_log.csv",
            ),
            false,
            &["a_log.csv"],
        ),
        case(
            "iso9283-plan",
            &argv(
                "iso9283 plan --robot irb.toml --attitude 3.141592653589793,0,0 --resolution 4
                 --out a_iso_poses.csv",
            ),
            false,
            &["a_iso_poses.csv"],
        ),
        case(
            "iso9283-log",
            &argv(
                "iso9283 log --robot ge-a4 --data data.csv --roles roles.csv --out a_iso_log.csv",
            ),
            false,
            &["a_iso_log.csv"],
        ),
        case(
            "iso9283-evaluate",
            &argv("iso9283 evaluate --data log.csv --json a_iso.json"),
            false,
            &["a_iso.json"],
        ),
        case(
            "simulate-camera",
            &argv(
                "simulate --robot cam_truth.toml --camera wrist --board board --postures 6
                 --seed 2 --noise pixel=0.5 --min-points 30 --out a_views.csv",
            ),
            false,
            &["a_views.csv"],
        ),
        case(
            "calibrate-camera",
            &argv(
                "calibrate --robot cam.toml --pixels views.csv --estimate extrinsics,boards
                 --predict --out a_cam.toml --report a_cam.json -q",
            ),
            false,
            &["a_cam.toml", "a_cam.json"],
        ),
        case(
            "analyze-camera",
            &argv(
                "analyze --robot cam_truth.toml --pixels views.csv
                 --estimate identifiable,cameras,boards --json",
            ),
            true,
            &[],
        ),
        case(
            "check-pixels",
            &argv("check --robot cam_truth.toml --pixels views.csv --threshold 0.001 --pixel-threshold 1.5 --json"),
            true,
            &[],
        ),
        case(
            "export-camera-info",
            &argv("export camera-info --robot cam_truth.toml --camera wrist --out a_wrist.yaml"),
            false,
            &["a_wrist.yaml"],
        ),
    ];
    // What three of the cases read.
    std::fs::create_dir(d.join("sub")).unwrap();
    // An ISO 9283 test in the GE A4's data: postures 1-27 as 3 cycles of 9 poses.
    let mut roles = String::from("posture,test,pose,cycle\n");
    for k in 0..27 {
        let pose = match k % 9 {
            0 => "P1".to_string(),
            c => format!("C{c}"),
        };
        roles += &format!("{},cube 1,{pose},{}\n", k + 1, k / 9 + 1);
    }
    std::fs::write(d.join("roles.csv"), roles).unwrap();
    ok(
        d,
        &argv("export dh --robot irb.toml --convention standard --out dh.csv"),
    );
    ok(
        d,
        &argv(
            "iso9283 simulate --robot irb.toml --poses poses.csv --cycles 3 --noise length=0.01
             --out log.csv",
        ),
    );
    let mut manifest = String::new();
    for c in &cases {
        // The import reads `../dh.csv`: it runs from the sub folder.
        let here = if c.name == "import" {
            d.join("sub")
        } else {
            d.to_path_buf()
        };
        let spec = format!("{}.toml", c.name);
        let mut args = c.args.clone();
        args.extend(["--write-spec", spec.as_str()]);
        let by_flags = ok(&here, &args);
        let text = std::fs::read_to_string(here.join(&spec)).unwrap();
        assert!(
            text.starts_with("job = "),
            "{}: the spec names its job:\n{text}",
            c.name
        );
        // The spec, its outputs renamed, run by --spec.
        let b = text.replace("a_", "b_");
        std::fs::write(here.join(format!("b_{spec}")), &b).unwrap();
        let mut args = vec![c.args[0]];
        if ["export", "import", "curves", "iso9283"].contains(&c.args[0]) {
            args.push(c.args[1]);
        }
        let b_spec = format!("b_{spec}");
        args.extend(["--spec", b_spec.as_str()]);
        if c.json {
            args.push("--json");
        }
        let by_spec = ok(&here, &args);
        if c.json {
            assert_eq!(normal(&by_flags), normal(&by_spec), "{}: --spec", c.name);
        }
        for o in &c.outputs {
            let a = std::fs::read_to_string(here.join(o)).unwrap();
            let b = std::fs::read_to_string(here.join(o.replace("a_", "b_"))).unwrap();
            assert_eq!(normal(&a), normal(&b), "{}: {o} by --spec", c.name);
        }
        // The same job in a batch, as the sub folder's manifest reads it when it runs there.
        let c_spec = text.replace("a_", "c_");
        if here == d {
            manifest += &as_job(&c_spec, c.name);
        } else {
            std::fs::write(here.join("jobs.toml"), as_job(&c_spec, c.name)).unwrap();
            let (code, _, err) = run(&here, &["batch", "jobs.toml", "--quiet"]);
            assert_eq!(code, 0, "{err}");
        }
        if c.json {
            std::fs::write(d.join(format!("{}.flags.json", c.name)), &by_flags).unwrap();
        }
    }
    std::fs::write(d.join("jobs.toml"), &manifest).unwrap();
    let (code, table, err) = run(
        d,
        &argv("batch jobs.toml --documents docs --quiet --jobs 2"),
    );
    assert_eq!(code, 0, "{table}\n{err}");
    assert!(err.contains("jobs: 22 done, 0 failed"), "{err}");
    for c in &cases {
        let here = if c.name == "import" {
            d.join("sub")
        } else {
            d.to_path_buf()
        };
        for o in &c.outputs {
            let a = std::fs::read_to_string(here.join(o)).unwrap();
            let c_out = std::fs::read_to_string(here.join(o.replace("a_", "c_"))).unwrap();
            assert_eq!(normal(&a), normal(&c_out), "{}: {o} in a batch", c.name);
        }
        if c.json {
            let flags = std::fs::read_to_string(d.join(format!("{}.flags.json", c.name))).unwrap();
            let doc =
                std::fs::read_to_string(d.join("docs").join(format!("{}.json", c.name))).unwrap();
            assert_eq!(
                normal(&flags),
                normal(&doc),
                "{}: its document in a batch",
                c.name
            );
        }
        if c.name == "calibrate" {
            let report = std::fs::read_to_string(d.join("a_report.json")).unwrap();
            let doc = std::fs::read_to_string(d.join("docs/calibrate.json")).unwrap();
            assert_eq!(normal(&report), normal(&doc), "the calibration's document");
        }
    }
}

/// `--write-spec -` prints the spec and runs nothing; a spec of another job is refused naming
/// both; a spec never replaces an input or an output of its job.
#[test]
fn specs_are_written_checked_and_refused_as_inputs() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = ok(
        d,
        &argv("plan --robot ge-a4 --sample 50 --count 5 --out p.csv --write-spec -"),
    );
    assert!(out.starts_with("job = \"plan\"\n"), "{out}");
    assert!(out.contains("count = 5"), "{out}");
    assert!(!d.join("p.csv").exists(), "nothing run");
    std::fs::write(d.join("plan.toml"), &out).unwrap();
    let (code, _, err) = run(d, &["analyze", "--spec", "plan.toml"]);
    assert_eq!(code, 1);
    assert!(
        err.contains("a spec of the job `plan`, not of `analyze`"),
        "{err}"
    );
    // The spec over its own output, or over the spec it was read from.
    let (code, _, err) = run(d, &["plan", "--spec", "plan.toml", "--write-spec", "p.csv"]);
    assert_eq!(code, 1);
    assert!(err.contains("p.csv"), "{err}");
    let (code, _, err) = run(d, &["plan", "--spec", "plan.toml", "--out", "plan.toml"]);
    assert_eq!(code, 1);
    assert!(
        err.contains("refusing to write an output over an input"),
        "{err}"
    );
    assert!(std::fs::read_to_string(d.join("plan.toml"))
        .unwrap()
        .starts_with("job"));
}

/// A bad value names its flag on the command line, its key in a spec file, and negative numbers
/// are values.
#[test]
fn a_bad_value_names_the_flag_or_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    ok(
        d,
        &argv("simulate --robot ge-a4 --postures 10 --out data.csv"),
    );
    for (args, expected) in [
        (
            &argv("calibrate --robot ge-a4 --data data.csv --huber-scale -1")[..],
            "--huber-scale",
        ),
        (
            &argv("calibrate --robot ge-a4 --data data.csv --holdout -0.5")[..],
            "--holdout",
        ),
        (
            &argv("analyze --robot ge-a4 --data data.csv --rcond -1")[..],
            "--rcond: expected a tolerance between 0 and 1, not -1",
        ),
        (
            &["plan", "--robot", "ge-a4", "--sample", "-3", "--count", "2"][..],
            "invalid value '-3' for '--sample <N>'",
        ),
        (
            &argv(
                "compensate --robot ge-a4 --nominal ge-a4 --in data.csv --singular -0.1
                 --out c.csv",
            )[..],
            "--singular: expected a fraction from 0 to below 1, not -0.1",
        ),
        (
            &argv("check --robot ge-a4 --data data.csv --threshold -1")[..],
            "--threshold: the length must be positive and finite, not -1",
        ),
        (
            &argv("iso9283 simulate --robot ge-a4 --poses data.csv --cycles 0 --out l.csv")[..],
            "data.csv",
        ),
    ] {
        let (code, _, err) = run(d, args);
        assert_ne!(code, 0, "{args:?}");
        assert!(err.contains(expected), "{args:?}: {err}");
        assert!(!err.contains("unexpected argument"), "{args:?}: {err}");
    }
    // A spec file names the key, with its line.
    std::fs::write(
        d.join("a.toml"),
        "job = \"analyze\"\nrobot = \"ge-a4\"\n[[observations]]\nfile = \"data.csv\"\n\
         [residuals]\norientation_error = \"quaternion\"\n",
    )
    .unwrap();
    let (code, _, err) = run(d, &["analyze", "--spec", "a.toml"]);
    assert_eq!(code, 1);
    assert!(
        err.contains("a.toml:6") && err.contains("quaternion"),
        "{err}"
    );
    std::fs::write(
        d.join("r.toml"),
        "job = \"analyze\"\nrobot = \"ge-a4\"\nrcond = 2.0\n[[observations]]\nfile = \"data.csv\"\n",
    )
    .unwrap();
    let (_, _, err) = run(d, &["analyze", "--spec", "r.toml"]);
    assert!(
        err.contains("r.toml: rcond: expected a tolerance between 0 and 1, not 2"),
        "{err}"
    );
    // Given on the command line over the spec, the flag is named.
    let (_, _, err) = run(d, &["analyze", "--spec", "r.toml", "--rcond", "3"]);
    assert!(
        err.contains("--rcond: expected a tolerance between 0 and 1, not 3"),
        "{err}"
    );
}

/// The history jobs through the same door: each said by flags, by `--spec` (the spec
/// `--write-spec` wrote) and as a `[[jobs]]` entry gives the same document and outputs. Each way
/// writes its own history (`a_h.sqlite`, `b_h.sqlite`, `c_h.sqlite`), which end up equal.
#[test]
fn history_jobs_are_the_same_by_flags_by_spec_and_in_a_batch() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let examples = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/fleet");
    std::fs::copy(examples.join("history.json"), d.join("fleet.json")).unwrap();
    std::fs::copy(examples.join("tolerances.toml"), d.join("tol.toml")).unwrap();
    ok(
        d,
        &argv("simulate --robot ge-a4 --postures 20 --seed 3 --out data.csv"),
    );
    ok(
        d,
        &argv("calibrate --robot ge-a4 --data data.csv --report report.json -q"),
    );
    let cases = [
        case(
            "history-import",
            &["history", "import", "fleet.json", "--db", "a_h.sqlite"],
            false,
            &[],
        ),
        case(
            "history-event",
            &argv("history event A4-0104 --at 2026-12-10 --note cable --db a_h.sqlite"),
            false,
            &[],
        ),
        case(
            "history-add",
            &argv(
                "history add --robot-id A4-0105 --report report.json --at 2026-12-12
                 --db a_h.sqlite",
            ),
            false,
            &[],
        ),
        case(
            "history-list",
            &argv("history list --robot-id A4-0101 --db a_h.sqlite"),
            true,
            &[],
        ),
        case(
            "history-show",
            &["history", "show", "--id", "3", "--db", "a_h.sqlite"],
            true,
            &[],
        ),
        case(
            "history-drift",
            &argv(
                "history drift --robot-id A4-0101 --tolerance tol.toml --sigma 2.5 --db a_h.sqlite",
            ),
            true,
            &[],
        ),
        case(
            "history-events",
            &["history", "events", "--db", "a_h.sqlite"],
            true,
            &[],
        ),
        case(
            "history-export",
            &argv("history export --format csv --out a_export.csv --db a_h.sqlite"),
            false,
            &["a_export.csv"],
        ),
        case(
            "history-plot",
            &[
                "history",
                "plot",
                "--robot-id",
                "A4-0101",
                "--param",
                "p14 + p20",
                "--out",
                "a_plot.svg",
                "--db",
                "a_h.sqlite",
            ],
            false,
            &["a_plot.svg"],
        ),
        case(
            "history-fleet",
            &argv(
                "history fleet --now 2026-12-15 --tolerance tol.toml --json a_fleet.json
                 --html a_fleet.html --db a_h.sqlite",
            ),
            false,
            &["a_fleet.json", "a_fleet.html"],
        ),
    ];
    // The histories' names aside, the documents are the same.
    let same = |text: &str| {
        normal(
            &text
                .replace("b_h.sqlite", "a_h.sqlite")
                .replace("c_h.sqlite", "a_h.sqlite"),
        )
    };
    let mut manifest = String::new();
    for c in &cases {
        let spec = format!("{}.toml", c.name);
        let mut args = c.args.clone();
        args.extend(["--write-spec", spec.as_str()]);
        if c.json {
            args.push("--json");
        }
        let (code, by_flags, err) = run(d, &args);
        assert!(code == 0 || code == 3, "{args:?} exited {code}: {err}");
        let text = std::fs::read_to_string(d.join(&spec)).unwrap();
        assert!(text.starts_with(&format!("job = \"{}\"", c.name)), "{text}");
        let b_spec = format!("b_{spec}");
        std::fs::write(d.join(&b_spec), text.replace("a_", "b_")).unwrap();
        let mut args = vec![c.args[0], c.args[1], "--spec", b_spec.as_str()];
        if c.json {
            args.push("--json");
        }
        let (code_b, by_spec, err) = run(d, &args);
        assert_eq!(code, code_b, "{}: {err}", c.name);
        if c.json {
            assert_eq!(same(&by_flags), same(&by_spec), "{}: --spec", c.name);
            std::fs::write(d.join(format!("{}.flags.json", c.name)), &by_flags).unwrap();
        }
        for o in &c.outputs {
            let a = std::fs::read_to_string(d.join(o)).unwrap();
            let b = std::fs::read_to_string(d.join(o.replace("a_", "b_"))).unwrap();
            assert_eq!(same(&a), same(&b), "{}: {o} by --spec", c.name);
        }
        manifest += &as_job(&text.replace("a_", "c_"), c.name);
    }
    std::fs::write(d.join("jobs.toml"), &manifest).unwrap();
    let (code, table, err) = run(
        d,
        &argv("batch jobs.toml --documents docs --quiet --jobs 1"),
    );
    // A robot drifted: its drift and the fleet are flagged, and the exit code says so.
    assert!(code == 0 || code == 3, "{table}\n{err}");
    assert!(
        err.contains("10 jobs: 8 done, 0 failed, 2 flagged"),
        "{err}"
    );
    // A flagged drift is not a strict calibration's refusal.
    let drift_row = table
        .lines()
        .find(|l| l.starts_with("history-drift "))
        .expect("a row per job");
    assert!(
        drift_row.ends_with("flagged") && !table.contains("--strict"),
        "{table}"
    );
    for c in &cases {
        for o in &c.outputs {
            let a = std::fs::read_to_string(d.join(o)).unwrap();
            let c_out = std::fs::read_to_string(d.join(o.replace("a_", "c_"))).unwrap();
            assert_eq!(same(&a), same(&c_out), "{}: {o} in a batch", c.name);
        }
        if c.json {
            let flags = std::fs::read_to_string(d.join(format!("{}.flags.json", c.name))).unwrap();
            let doc =
                std::fs::read_to_string(d.join("docs").join(format!("{}.json", c.name))).unwrap();
            assert_eq!(
                same(&flags),
                same(&doc),
                "{}: its document in a batch",
                c.name
            );
        }
    }
    // The three histories hold the same records and events.
    let dump = |db: &str| ok(d, &["history", "export", "--format", "dump", "--db", db]);
    let a = dump("a_h.sqlite");
    assert!(a.contains("A4-0105") && a.contains("cable"), "{a}");
    assert_eq!(a, dump("b_h.sqlite"));
    assert_eq!(a, dump("c_h.sqlite"));
}

/// A bad value of a history job names its flag, or its key in a spec file.
#[test]
fn a_bad_history_value_names_the_flag_or_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for (args, expected) in [
        (
            &argv("history drift --robot-id A --sigma -1 --db h.sqlite")[..],
            "--sigma: -1: expected a positive, finite number of standard deviations",
        ),
        (
            &["history", "fleet", "--horizon", "-3", "--db", "h.sqlite"][..],
            "--horizon: -3: expected a number of days from 0 to 36500",
        ),
        (
            &argv("history drift --robot-id A --baseline last --db h.sqlite")[..],
            "--baseline: `last`: expected first, latest-ok or a calibration id",
        ),
        (
            &argv("history event A --note x --at yesterday --db h.sqlite")[..],
            "--at: ",
        ),
        (
            &argv("history plot --robot-id A --out p.jpg --db h.sqlite")[..],
            "--out: `p.jpg`: the name must end in .svg or .png",
        ),
    ] {
        let (code, _, err) = run(d, args);
        assert_ne!(code, 0, "{args:?}");
        assert!(err.contains(expected), "{args:?}: {err}");
    }
    // Nothing was created by the refused jobs.
    assert!(!d.join("h.sqlite").exists());
    std::fs::write(
        d.join("drift.toml"),
        "job = \"history-drift\"\ndb = \"h.sqlite\"\nrobot_id = \"A\"\nsigma = -1\n",
    )
    .unwrap();
    let (code, _, err) = run(d, &["history", "drift", "--spec", "drift.toml"]);
    assert_ne!(code, 0);
    assert!(
        err.contains("drift.toml: sigma: -1: expected a positive"),
        "{err}"
    );
    // A spec of another job is refused naming both.
    let (code, _, err) = run(d, &["history", "fleet", "--spec", "drift.toml"]);
    assert_ne!(code, 0);
    assert!(
        err.contains("`history-drift`, not of `history-fleet`"),
        "{err}"
    );
}

/// `--display-units` is the spec's `display_units` for the jobs that draw pages.
#[test]
fn display_units_is_a_flag_of_the_jobs_that_draw_pages() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for args in [
        &["calibrate", "--robot", "ge-a4", "--data", "d.csv"][..],
        &argv("predict --robot ge-a4 --report r.json --sample 3")[..],
        &["report", "--from", "r.json", "--out", "p.html"][..],
    ] {
        let mut args = args.to_vec();
        args.extend(["--display-units", "m-rad", "--write-spec", "-"]);
        let (code, out, err) = run(d, &args);
        assert_eq!(code, 0, "{args:?}: {err}");
        assert!(out.contains("display_units = \"m-rad\""), "{args:?}: {out}");
    }
    let (code, _, err) = run(
        d,
        &["report", "--from", "r.json", "--display-units", "ft-deg"],
    );
    assert_ne!(code, 0);
    assert!(err.contains("--display-units"), "{err}");
}
