//! The `kinecal` command as a user runs it.

use std::path::Path;

mod common;
#[path = "../../kinecal/tests/common/shared_data.rs"]
mod shared_data;
#[path = "../../kinecal/tests/common/synthetic_datasets.rs"]
mod synthetic;

use common::{argv, kinecal, run, run_err, run_ok};

#[test]
fn demo_shows_returning_and_redundant_parameters() {
    let out = run_ok(Path::new("."), &["demo"]);
    assert!(out.contains("returned to its true value"), "{out}");
    assert!(out.contains("estimated 5.790000"), "{out}");
    assert!(out.contains("redundant"), "{out}");
}

#[test]
fn every_command_has_help_with_an_example() {
    let commands: [&[&str]; 33] = [
        &["demo"],
        &["iso9283"],
        &["iso9283", "plan"],
        &["iso9283", "simulate"],
        &["iso9283", "evaluate"],
        &["export", "dh"],
        &["export", "stiffness"],
        &["export", "joints"],
        &["import", "ur"],
        &["export", "ur"],
        &["compensate"],
        &["plan"],
        &["batch"],
        &["fk"],
        &["simulate"],
        &["calibrate"],
        &["analyze"],
        &["check"],
        &["report"],
        &["import", "urdf"],
        &["import", "dh"],
        &["import", "poe"],
        &["export", "urdf"],
        &["export", "ros"],
        &["curves", "pose"],
        &["curves", "objective"],
        &["history", "add"],
        &["history", "list"],
        &["history", "show"],
        &["history", "export"],
        &["history", "drift"],
        &["history", "plot"],
        &[],
    ];
    for cmd in commands {
        let mut args = cmd.to_vec();
        args.push("--help");
        let out = run_ok(Path::new("."), &args);
        assert!(out.contains("Example"), "{cmd:?}: {out}");
    }
}

/// The completion scripts hold every command's options: a command's arguments are built only
/// when it runs (`args::Deferred`), and a script must build them all.
#[test]
fn completion_scripts_hold_every_commands_options() {
    for shell in ["bash", "zsh", "fish"] {
        let out = run_ok(Path::new("."), &["completions", shell]);
        // One option of a top-level command, of a nested one and the global one.
        for option in [
            "huber-scale",
            "min-points",
            "robot-id",
            "measurement-frame",
            "quiet",
        ] {
            assert!(out.contains(option), "{shell}: no {option}");
        }
    }
}

#[test]
fn fk_reproduces_table_4_2_posture_4() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("p.csv"),
        "posture,v1,v2,v3,v4\n4,-6.883,13.301,4.122,-28.645\n",
    )
    .unwrap();
    let out = run_ok(
        dir.path(),
        &["fk", "--robot", "ge-a4", "--postures", "p.csv"],
    );
    let mut lines = out.lines();
    assert_eq!(
        lines.next(),
        Some("posture,site,v1,v2,v3,v4,x,y,z,alpha,beta,gamma")
    );
    let f: Vec<f64> = lines
        .next()
        .unwrap()
        .split(',')
        .skip(2)
        .map(|v| v.parse().unwrap())
        .collect();
    let printed = [28.576, 13.995, 0.020, 47.600, 0.000, -90.000];
    for k in 0..6 {
        assert!(
            (f[4 + k] - printed[k]).abs() < 0.01,
            "{k}: {} vs {}",
            f[4 + k],
            printed[k]
        );
    }
}

#[test]
fn simulate_then_calibrate_recovers_the_truth_and_keeps_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::copy(
        concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../examples/robots/ge_a4.toml"
        ),
        d.join("a4.toml"),
    )
    .unwrap();
    run_ok(
        d,
        &argv(
            "simulate --robot a4.toml --postures 30 --seed 3
             --perturb p1=+0.2,joint2.offset=-0.5,p38=+0.05 --out data.csv --truth truth.toml",
        ),
    );
    let out = run_ok(
        d,
        &argv(
            "calibrate --robot a4.toml --data data.csv --estimate p1,p32,p38 --out cal.toml
             --report rep.json",
        ),
    );
    assert!(out.contains("converged"), "{out}");
    let rep = common::read_json(&d.join("rep.json"));
    for key in [
        "method",
        "converged",
        "iterations",
        "objective_before",
        "objective_after",
        "rms_position_before",
        "rms_position_after",
        "rms_orientation_before",
        "rms_orientation_after",
        "parameters",
    ] {
        assert!(rep.get(key).is_some(), "report lacks {key}");
    }
    assert_eq!(rep["method"], "lm");
    assert_eq!(rep["converged"], true);
    assert!(rep["rms_position_after"].as_f64().unwrap() < 1e-9);
    let params = rep["parameters"].as_array().unwrap();
    assert_eq!(params.len(), 38);
    let p1 = &params[0];
    assert_eq!(p1["id"], "p1");
    assert_eq!(p1["name"], "link1.x");
    assert_eq!(p1["estimated_flag"], true);
    assert!((p1["estimated"].as_f64().unwrap() - 15.28).abs() < 1e-9);
    assert!((params[31]["estimated"].as_f64().unwrap() + 117.5).abs() < 1e-9);
    assert_eq!(params[1]["estimated_flag"], false);
    // The calibrated file keeps the comments and layout of the original, with new numbers.
    let cal = std::fs::read_to_string(d.join("cal.toml")).unwrap();
    assert!(cal.contains("# Link 1: global frame to joint 1 (p1-p6)"));
    assert!(cal.contains("x = 15.28\n"), "{cal}");
    assert!(cal.contains("offset = -117.5\n"));
    assert!(cal.contains("slope = 9.05\n"));
    // ... and reads back as a robot giving the same poses as the truth.
    let truth = run_ok(
        d,
        &["fk", "--robot", "truth.toml", "--postures", "data.csv"],
    );
    let calibrated = run_ok(d, &["fk", "--robot", "cal.toml", "--postures", "data.csv"]);
    for (a, b) in truth.lines().zip(calibrated.lines()).skip(1) {
        for (x, y) in a.split(',').zip(b.split(',')).skip(2) {
            let (x, y): (f64, f64) = (x.parse().unwrap(), y.parse().unwrap());
            assert!((x - y).abs() < 1e-8, "{a}\n{b}");
        }
    }
}

#[test]
fn position_only_data_and_all_methods() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    run_ok(
        d,
        &argv(
            "simulate --robot ge-a4 --postures 25 --perturb p31=+1,p2=-0.1 --position-only
             --out pos.csv",
        ),
    );
    let text = std::fs::read_to_string(d.join("pos.csv")).unwrap();
    assert!(text.lines().nth(1).unwrap().ends_with(",,,"));
    for method in ["lm", "gn", "svd", "sd"] {
        let out = run_ok(
            d,
            &argv(&format!(
                "calibrate --robot ge-a4 --data pos.csv --estimate p2,p31 --method {method}
                 --report r.json"
            )),
        );
        let rep = common::read_json(&d.join("r.json"));
        assert!(
            rep["rms_position_after"].as_f64().unwrap() < 1e-6,
            "{method}: {out}"
        );
    }
    // Gauss-Newton on the full, singular model says so.
    let err = run_err(
        d,
        &argv("calibrate --robot ge-a4 --data pos.csv --method gn"),
    );
    assert!(err.contains("singular"), "{err}");
}

#[test]
fn euler_residuals_refused_at_gimbal_lock_rotvec_by_default() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A 1-joint robot whose tool frame is Rz(q) Ry(90 deg): beta = 90 deg at every posture.
    std::fs::write(
        d.join("r.toml"),
        "name = \"locked\"\nlength_unit = \"mm\"\nangle_unit = \"deg\"\n\
         [[links]]\nz = 100\n[[links]]\nx = 300\nbeta = 90\n[[joints]]\nkind = \"revolute\"\n",
    )
    .unwrap();
    run_ok(
        d,
        &argv("simulate --robot r.toml --postures 20 --perturb link2.x=+1 --out data.csv"),
    );
    let (code, _, err) = run(
        d,
        &argv(
            "calibrate --robot r.toml --data data.csv --estimate link2.x --orientation-error euler",
        ),
    );
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("gimbal lock") && err.contains("lines 2, 3, 4, 5, 6, ..."),
        "{err}"
    );
    let out = run_ok(
        d,
        &argv("calibrate --robot r.toml --data data.csv --estimate link2.x --report rep.json"),
    );
    let rep = common::read_json(&d.join("rep.json"));
    assert!(
        (rep["parameters"][6]["estimated"].as_f64().unwrap() - 301.0).abs() < 1e-6,
        "{out}"
    );
}

#[test]
fn bad_input_names_file_line_and_field() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let a4 = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../examples/robots/ge_a4.toml"
    ))
    .unwrap();
    let cases: Vec<(&str, String, &str)> = vec![
        (
            "unit.toml",
            a4.replace("length_unit = \"in\"", "length_unit = \"ft\""),
            "unit.toml:4: field `length_unit`: unknown length unit `ft`",
        ),
        (
            "kind.toml",
            a4.replacen("kind = \"prismatic\"", "kind = \"helical\"", 1),
            "field `joints[2].kind`: unknown joint kind `helical`",
        ),
        (
            "num.toml",
            a4.replace("beta = 180.0", "beta = \"x\""),
            "num.toml:13: field `links[0].beta`: expected a number",
        ),
        (
            "nan.toml",
            a4.replace("beta = 180.0", "beta = nan"),
            "field `links[0].beta`: expected a finite number",
        ),
        (
            "syntax.toml",
            a4.replace("x = 15.08", "x = = 15.08"),
            "syntax.toml:9: invalid TOML",
        ),
        (
            "links.toml",
            a4.replacen("[[links]]", "[[linkz]]", 1),
            "5 links",
        ),
    ];
    std::fs::write(d.join("p.csv"), "posture,v1,v2,v3,v4\n1,0,0,0,0\n").unwrap();
    for (file, text, expected) in &cases {
        std::fs::write(d.join(file), text).unwrap();
        let err = run_err(d, &["fk", "--robot", file, "--postures", "p.csv"]);
        assert!(err.contains(expected), "{file}: {err}");
    }
    let header = "posture,site,v1,v2,v3,v4,x,y,z,alpha,beta,gamma\n";
    let csv_cases = [
        (
            "cols.csv",
            format!("{header}1,ee,0,0,0,0,1,2,3,4,5\n"),
            "cols.csv:2: expected 12 fields",
        ),
        (
            "num.csv",
            format!("{header}1,ee,0,0,0,0,1,abc,3,4,5,6\n"),
            "num.csv:2: field `y`: expected a number, found `abc`",
        ),
        (
            "inf.csv",
            format!("{header}1,ee,0,0,inf,0,1,2,3,4,5,6\n"),
            "inf.csv:2: field `v3`: expected a finite number",
        ),
        (
            "site.csv",
            format!("{header}1,wrist,0,0,0,0,1,2,3,4,5,6\n"),
            "site.csv:2: field `site`: unknown site `wrist`",
        ),
        (
            "head.csv",
            "posture,v1,v2,x\n1,2,3,4\n".to_string(),
            "head.csv:1: field `v3`: no column `v3` in the header",
        ),
        (
            "angles.csv",
            format!("{header}1,ee,0,0,0,0,1,2,3,4,,6\n"),
            "angles.csv:2: field `beta`: empty angle",
        ),
        (
            "same.csv",
            format!("{header}1,ee,0,0,0,0,1,2,3,4,5,6\n1,ee,0,0,0,1,1,2,3,4,5,6\n"),
            "same.csv:3: field `v4`",
        ),
    ];
    for (file, text, expected) in &csv_cases {
        std::fs::write(d.join(file), text).unwrap();
        let err = run_err(d, &["calibrate", "--robot", "ge-a4", "--data", file]);
        assert!(err.contains(expected), "{file}: {err}");
    }
    std::fs::write(
        d.join("ok.csv"),
        format!("{header}1,ee,0,0,0,0,1,2,3,4,5,6\n"),
    )
    .unwrap();
    for (args, expected) in [
        (vec!["--estimate", "p39"], "out of range"),
        (vec!["--estimate", "link1.q"], "unknown link component"),
        (vec!["--estimate", "site.hand.x"], "no site named `hand`"),
        (vec!["--estimate", "p1,p2,p3,p4,p5,p6,p7"], "6 residuals"),
        (vec!["--weights", "length=0"], "positive"),
    ] {
        let mut a = vec!["calibrate", "--robot", "ge-a4", "--data", "ok.csv"];
        a.extend(args);
        let err = run_err(d, &a);
        assert!(err.contains(expected), "{a:?}: {err}");
    }
    let err = run_err(
        d,
        &["calibrate", "--robot", "nope.toml", "--data", "ok.csv"],
    );
    assert!(err.contains("no such robot file"), "{err}");
    // A failed run leaves an existing output file untouched.
    std::fs::write(d.join("keep.toml"), "precious").unwrap();
    run_err(
        d,
        &argv("calibrate --robot ge-a4 --data num.csv --out keep.toml"),
    );
    assert_eq!(
        std::fs::read_to_string(d.join("keep.toml")).unwrap(),
        "precious"
    );
}

#[test]
fn analyze_reports_the_thesis_structure_as_text_and_json() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    run_ok(
        d,
        &argv("simulate --robot ge-a4 --postures 30 --seed 2 --out data.csv"),
    );
    let text = run_ok(d, &["analyze", "--robot", "ge-a4", "--data", "data.csv"]);
    assert!(text.contains("Numerical rank 24 of 38"), "{text}");
    assert!(text.contains("= 24."), "{text}");
    assert!(
        text.contains("p3 - p9 - p15 - p21 - p27 - p33 = 5.79"),
        "{text}"
    );
    let json = common::check_document(
        "analysis",
        &run_ok(d, &argv("analyze --robot ge-a4 --data data.csv --json")),
    );
    for key in [
        "parameters",
        "rank",
        "expected_rank",
        "singular_values_jacobian",
        "singular_values_hessian",
        "condition_number",
        "identical_groups",
        "null_space",
        "identifiable",
    ] {
        assert!(json.get(key).is_some(), "analyze --json lacks {key}");
    }
    assert_eq!(json["parameters"], 38);
    assert_eq!(json["rank"], 24);
    assert_eq!(json["expected_rank"], 24);
    assert_eq!(json["identical_groups"].as_array().unwrap().len(), 6);
    assert_eq!(json["null_space"].as_array().unwrap().len(), 14);
    assert_eq!(json["identifiable"].as_array().unwrap().len(), 24);
    // Without slopes, from a postures file: rank 20 (eq. 4.3).
    std::fs::write(d.join("p.csv"), {
        let mut s = String::from("posture,v1,v2,v3,v4\n");
        for line in std::fs::read_to_string(d.join("data.csv"))
            .unwrap()
            .lines()
            .skip(1)
        {
            let f: Vec<&str> = line.split(',').collect();
            s.push_str(&format!("{},{}\n", f[0], f[2..6].join(",")));
        }
        s
    })
    .unwrap();
    let json = common::check_document(
        "analysis",
        &run_ok(
            d,
            &argv("analyze --robot ge-a4 --postures p.csv --fix slopes --json"),
        ),
    );
    assert_eq!(
        (json["parameters"].as_u64(), json["rank"].as_u64()),
        (Some(34), Some(20))
    );
    // The thesis's Table 4.5 layout: J^T J in file units.
    let out = run_ok(
        d,
        &argv("analyze --robot ge-a4 --data data.csv --estimate p1-p6,p14,p29 --print hessian"),
    );
    assert!(out.contains("J^T J (in, deg)"), "{out}");
    let out = run_ok(
        d,
        &argv(
            "analyze --robot ge-a4 --data data.csv --estimate p1,p2 --print jacobian
             --units scaled",
        ),
    );
    assert!(out.contains("1 ee alpha"), "{out}");
}

#[test]
fn calibrate_identifiable_min_change_initial_and_prune() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    run_ok(
        d,
        &argv(
            "simulate --robot ge-a4 --postures 30 --seed 7
             --perturb p1=+0.05,p14=-0.02,joint2.offset=-0.5,joint4.slope=+0.02
             --noise length=0.0005,angle=0.005 --out data.csv",
        ),
    );
    // Only the identifiable set, then pruned to the real changes.
    run_ok(
        d,
        &argv(
            "calibrate --robot ge-a4 --data data.csv --estimate identifiable
             --weights length=0.0005,angle=0.005 --prune 3 --report r.json",
        ),
    );
    let rep = common::read_json(&d.join("r.json"));
    let kept: Vec<&str> = rep["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|p| p["estimated_flag"] == true)
        .map(|p| p["id"].as_str().unwrap())
        .collect();
    assert_eq!(kept, vec!["p1", "p14", "p32", "p38"]);
    assert!((rep["variance_factor"].as_f64().unwrap() - 1.0).abs() < 0.5);
    assert_eq!(rep["pruning"]["k"], 3.0);
    assert!(rep["undetermined"].as_array().unwrap().is_empty());
    // Table 4.8 from the command line: the min-change answer from a far guess is Table 4.1.
    run_ok(
        d,
        &argv("simulate --robot ge-a4 --postures 30 --seed 1 --out clean.csv"),
    );
    let a4 = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../examples/robots/ge_a4.toml"
    ))
    .unwrap();
    let guess = a4
        .replacen("x = 15.08", "x = 14.08", 1)
        .replacen("z = 10.54", "z = 10.0", 1);
    std::fs::write(d.join("guess.toml"), guess).unwrap();
    run_ok(
        d,
        &argv(
            "calibrate --robot ge-a4 --data clean.csv --initial guess.toml
             --estimate p1,p3,p9,p10,p15,p21,p27,p33 --solution min-change --report m.json",
        ),
    );
    let rep = common::read_json(&d.join("m.json"));
    assert_eq!(rep["solution"], "min-change");
    let p = |i: usize| rep["parameters"][i]["estimated"].as_f64().unwrap();
    assert!(
        (p(0) - 15.08).abs() < 1e-6 && (p(2) - 10.54).abs() < 1e-6,
        "{} {}",
        p(0),
        p(2)
    );
    assert!((rep["parameters"][2]["initial"].as_f64().unwrap() - 10.0).abs() < 1e-12);
    assert_eq!(
        rep["combinations"][0]["expression"],
        "p3 - p9 - p15 - p21 - p27 - p33"
    );
    assert!((rep["combinations"][0]["value"].as_f64().unwrap() - 5.79).abs() < 1e-6);
    assert!(rep["undetermined"]
        .as_array()
        .unwrap()
        .iter()
        .any(|v| v == "p3"));
}

#[test]
fn import_dh_and_poe_then_calibrate_with_validation() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(
        d.join("puma.csv"),
        "kind,a,alpha,d,theta\nrevolute,0,0,0,0\nrevolute,0,-90,0,0\nrevolute,0.4318,0,0.15005,0\n\
         revolute,0.0203,-90,0.4318,0\nrevolute,0,90,0,0\nrevolute,0,-90,0,0\n",
    )
    .unwrap();
    run_ok(
        d,
        &argv(
            "import dh --convention modified puma.csv --length-unit m --angle-unit deg
             --out puma.toml",
        ),
    );
    // Zero configuration of Craig's PUMA 560: the wrist centre at (a2 + a3, d3, -d4).
    std::fs::write(
        d.join("zero.csv"),
        "posture,v1,v2,v3,v4,v5,v6\n0,0,0,0,0,0,0\n",
    )
    .unwrap();
    let out = run_ok(d, &["fk", "--robot", "puma.toml", "--postures", "zero.csv"]);
    let f: Vec<f64> = out
        .lines()
        .nth(1)
        .unwrap()
        .split(',')
        .skip(8)
        .take(3)
        .map(|v| v.parse().unwrap())
        .collect();
    for (got, want) in f.iter().zip([0.4521, 0.15005, -0.4318]) {
        assert!((got - want).abs() < 1e-9, "{f:?}");
    }
    // Readings are joint values (slope 1): by default the slopes are not estimated.
    run_ok(
        d,
        &argv(
            "simulate --robot puma.toml --postures 60 --perturb p8=+0.001,joint3.offset=+0.2
             --out all.csv",
        ),
    );
    run_ok(
        d,
        &argv("calibrate --robot puma.toml --data all.csv --holdout 0.25 --report r.json"),
    );
    let rep = common::read_json(&d.join("r.json"));
    assert!(rep["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|p| p["name"].as_str().unwrap().ends_with(".slope"))
        .all(|p| p["estimated_flag"] == false));
    assert_eq!(rep["validation"]["postures"], 15);
    assert_eq!(rep["identification"]["postures"], 45);
    assert!(rep["validation"]["after"]["max_position"].as_f64().unwrap() < 1e-9);
    assert!(
        rep["validation"]["before"]["p95_position"]
            .as_f64()
            .unwrap()
            > 1e-4
    );
    // --validate with a separate file.
    run_ok(
        d,
        &argv(
            "simulate --robot puma.toml --postures 10 --seed 9
             --perturb p8=+0.001,joint3.offset=+0.2 --out v.csv",
        ),
    );
    let out = run_ok(
        d,
        &argv("calibrate --robot puma.toml --data all.csv --validate v.csv"),
    );
    assert!(out.contains("validation (10 postures) before"), "{out}");

    // A POE file, and its errors.
    std::fs::write(
        d.join("poe.toml"),
        "length_unit = \"mm\"\nangle_unit = \"deg\"\n[[joints]]\nkind = \"revolute\"\naxis = [0, 0, 1]\npoint = [0, 0, 0]\n\
         [[joints]]\nkind = \"revolute\"\naxis = [0, 1, 0]\npoint = [0, 0, 300]\n[tool]\nposition = [250, 0, 300]\n",
    )
    .unwrap();
    run_ok(d, &["import", "poe", "poe.toml", "--out", "r2.toml"]);
    std::fs::write(d.join("p2.csv"), "posture,v1,v2\n1,90,0\n").unwrap();
    let out = run_ok(d, &["fk", "--robot", "r2.toml", "--postures", "p2.csv"]);
    let f: Vec<f64> = out
        .lines()
        .nth(1)
        .unwrap()
        .split(',')
        .skip(4)
        .take(3)
        .map(|v| v.parse().unwrap())
        .collect();
    assert!(
        f[0].abs() < 1e-9 && (f[1] - 250.0).abs() < 1e-9 && (f[2] - 300.0).abs() < 1e-9,
        "{f:?}"
    );
    std::fs::write(d.join("bad.toml"), "length_unit = \"mm\"\nangle_unit = \"deg\"\n[[joints]]\nkind = \"revolute\"\naxis = [0, 0, 1]\n").unwrap();
    let err = run_err(d, &["import", "poe", "bad.toml", "--out", "x.toml"]);
    assert!(
        err.contains("bad.toml") && err.contains("joints[0].point"),
        "{err}"
    );
    assert!(!d.join("x.toml").exists());
}

#[test]
fn urdf_import_calibrate_export_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let urdf = r#"<?xml version="1.0"?>
<!-- a small arm: the comment must survive export -->
<robot name="arm">
  <link name="base"/><link name="l1"/><link name="l2"/><link name="l3"/><link name="tool"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
    <origin xyz="0 0 0.3" rpy="0 0 0"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
    <origin xyz="0 0.1 0.2" rpy="1.5707963 0 0"/><axis xyz="0 0 1"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
  <joint name="j3" type="continuous"><parent link="l2"/><child link="l3"/>
    <origin xyz="0.4 0 0" rpy="0 0 0"/><axis xyz="0 1 0"/></joint>
  <joint name="tool_joint" type="fixed"><parent link="l3"/><child link="tool"/>
    <origin xyz="0.1 0 0" rpy="0 0 0"/></joint>
</robot>
"#;
    std::fs::write(d.join("arm.urdf"), urdf).unwrap();
    run_ok(d, &["import", "urdf", "arm.urdf", "--out", "arm.toml"]);
    run_ok(
        d,
        &argv(
            "simulate --robot arm.toml --postures 30 --perturb link2.y=+0.002,joint2.offset=+0.01
             --out d.csv --truth t.toml",
        ),
    );
    run_ok(
        d,
        &argv("calibrate --robot arm.toml --data d.csv --out c.toml"),
    );
    run_ok(
        d,
        &argv("export urdf --robot c.toml --template arm.urdf --out c.urdf"),
    );
    let out = std::fs::read_to_string(d.join("c.urdf")).unwrap();
    assert!(out.contains("<!-- a small arm: the comment must survive export -->"));
    assert!(out.contains(r#"<limit lower="-2" upper="2" effort="1" velocity="1"/>"#));
    // Importing the exported URDF gives the true robot's poses.
    run_ok(d, &["import", "urdf", "c.urdf", "--out", "c2.toml"]);
    let a = run_ok(d, &["fk", "--robot", "t.toml", "--postures", "d.csv"]);
    let b = run_ok(d, &["fk", "--robot", "c2.toml", "--postures", "d.csv"]);
    for (x, y) in a.lines().zip(b.lines()).skip(1) {
        for (u, v) in x.split(',').zip(y.split(',')).skip(5).take(3) {
            assert!(
                (u.parse::<f64>().unwrap() - v.parse::<f64>().unwrap()).abs() < 1e-9,
                "{x}\n{y}"
            );
        }
    }
    let err = run_err(d, &argv("import urdf arm.urdf --tip nowhere --out x.toml"));
    assert!(
        err.contains("no link named `nowhere` (the chain's tip)") && err.contains("--tip LINK"),
        "{err}"
    );
}

#[test]
fn history_record_drift_plot_and_check() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let run_code = |args: &[&str]| -> (i32, String, String) {
        let out = kinecal().current_dir(d).args(args).output().unwrap();
        (
            out.status.code().unwrap(),
            String::from_utf8(out.stdout).unwrap(),
            String::from_utf8(out.stderr).unwrap(),
        )
    };
    for (m, delta) in [(1, "0"), (2, "0"), (3, "0.02")] {
        let data = format!("m{m}.csv");
        run_ok(
            d,
            &argv(&format!(
                "simulate --robot ge-a4 --postures 30 --seed {m} --perturb p14=+{delta}
                 --noise length=0.0005,angle=0.005 --out {data}"
            )),
        );
        let at = format!("2026-0{m}-01");
        if m < 3 {
            run_ok(
                d,
                &argv(&format!(
                    "calibrate --robot ge-a4 --data {data} --solution min-change
                     --weights length=0.0005,angle=0.005 --record A4-7 --db h.sqlite --at {at}
                     --note monthly"
                )),
            );
        } else {
            run_ok(
                d,
                &argv(&format!(
                    "calibrate --robot ge-a4 --data {data} --solution min-change
                     --weights length=0.0005,angle=0.005 --report r3.json"
                )),
            );
            run_ok(
                d,
                &argv(&format!(
                    "history add --robot-id A4-7 --report r3.json --db h.sqlite --at {at}"
                )),
            );
        }
    }
    let list = run_ok(d, &["history", "list", "--db", "h.sqlite"]);
    assert_eq!(
        list.lines().filter(|l| l.contains("A4-7")).count(),
        3,
        "{list}"
    );
    let show = run_ok(
        d,
        &["history", "show", "--robot-id", "A4-7", "--db", "h.sqlite"],
    );
    assert!(show.contains("p14 + p20 ="), "{show}");
    let csv = run_ok(
        d,
        &["history", "export", "--db", "h.sqlite", "--format", "csv"],
    );
    assert!(csv.starts_with("calibration,robot_id,at,"));
    let json: serde_json::Value = serde_json::from_str(&run_ok(
        d,
        &["history", "export", "--db", "h.sqlite", "--format", "json"],
    ))
    .unwrap();
    assert_eq!(json.as_array().unwrap().len(), 3);
    // Drift: the wear of link 3 (with link 4, which the data cannot separate) is flagged; exit 3.
    let (code, out, _) = run_code(&argv("history drift --robot-id A4-7 --db h.sqlite --json"));
    assert_eq!(code, 3, "{out}");
    let r: serde_json::Value = serde_json::from_str(&out).unwrap();
    let flags = r["flags"].as_array().unwrap();
    assert!(
        flags
            .iter()
            .any(|f| f["quantity"] == "y lengths of links 3 and 4, together"),
        "{out}"
    );
    for key in ["quantity", "parameters", "change", "sigma", "significance"] {
        assert!(flags[0].get(key).is_some(), "{key}");
    }
    assert!(r["quantities"].as_array().unwrap().len() > 10);
    // Against the second calibration as baseline, month 2 vs month 1 would be clean; and a
    // tolerance wider than the change with a huge K: nothing flagged, exit 0.
    std::fs::write(d.join("tol.toml"), "[tolerances]\n\"p14 + p20\" = 0.5\n").unwrap();
    let (code, out, _) = run_code(&argv(
        "history drift --robot-id A4-7 --db h.sqlite --sigma 1000 --tolerance tol.toml",
    ));
    assert_eq!(code, 0, "{out}");
    let (code, out, _) = run_code(&argv(
        "history drift --robot-id A4-7 --db h.sqlite --sigma 1000 --baseline latest-ok",
    ));
    assert_eq!(code, 0, "{out}");
    // The latest calibration as the baseline: nothing to compare, said, and no table of zeros.
    let latest = r["latest_id"].as_i64().unwrap();
    let (code, out, _) = run_code(&argv(&format!(
        "history drift --robot-id A4-7 --db h.sqlite --baseline {latest}"
    )));
    assert_eq!(code, 0, "{out}");
    assert!(
        out.contains("nothing to compare: the baseline is the latest calibration itself")
            && !out.contains("nothing flagged")
            && !out.contains("link 1"),
        "{out}"
    );
    run_ok(
        d,
        &[
            "history",
            "plot",
            "--robot-id",
            "A4-7",
            "--db",
            "h.sqlite",
            "--param",
            "p14 + p20,link1.x",
            "--out",
            "h.svg",
        ],
    );
    let svg = std::fs::read_to_string(d.join("h.svg")).unwrap();
    // Three calibrations of two quantities: six points, plus a legend marker per panel.
    assert!(
        svg.starts_with("<svg")
            && svg.contains("y lengths of links 3 and 4")
            && svg.matches("<circle").count() == 6 + 2
    );
    // Errors.
    let err = run_err(
        d,
        &["history", "drift", "--robot-id", "NOPE", "--db", "h.sqlite"],
    );
    assert!(
        err.contains("no calibration recorded for robot `NOPE`"),
        "{err}"
    );
    std::fs::write(
        d.join("junk.sqlite"),
        "this is not a database at all, not even close........................",
    )
    .unwrap();
    let err = run_err(d, &["history", "list", "--db", "junk.sqlite"]);
    assert!(
        err.contains("junk.sqlite") && err.contains("not modified"),
        "{err}"
    );

    // check: the month-3 robot (link 3 grown) against the original calibration.
    run_ok(
        d,
        &argv("calibrate --robot ge-a4 --data m1.csv --out cal1.toml"),
    );
    let (code, out, _) = run_code(&argv(
        "check --robot cal1.toml --data m2.csv --threshold 0.005,0.05",
    ));
    assert_eq!(code, 0, "{out}");
    let (code, out, _) = run_code(&argv(
        "check --robot cal1.toml --data m3.csv --threshold 0.005,0.05",
    ));
    assert_eq!(code, 3, "{out}");
    assert!(out.contains("RECALIBRATE"));
    // The verdict as a document: the check's schema, the same verdict and exit code.
    let (code, out, _) = run_code(&argv(
        "check --robot cal1.toml --data m3.csv --threshold 0.005,0.05 --json",
    ));
    assert_eq!(code, 3, "{out}");
    let v = common::check_document("check", &out);
    assert_eq!(v["ok"], false);
    assert_eq!(v["threshold_length"], 0.005);
    let err = run_err(
        d,
        &argv("check --robot cal1.toml --data m3.csv --threshold abc"),
    );
    assert!(err.contains("--threshold"), "{err}");
}

#[test]
fn concurrent_processes_recording_all_succeed() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    run_ok(d, &argv("simulate --robot ge-a4 --postures 12 --out d.csv"));
    run_ok(
        d,
        &argv("calibrate --robot ge-a4 --data d.csv --estimate p1,p2 --report r.json"),
    );
    let bin = assert_cmd::cargo::cargo_bin("kinecal");
    let children: Vec<_> = (0..12)
        .map(|k| {
            std::process::Command::new(&bin)
                .current_dir(d)
                .args([
                    "history",
                    "add",
                    "--robot-id",
                    &format!("R{}", k % 3),
                    "--report",
                    "r.json",
                    "--db",
                    "h.sqlite",
                    // Each its own time: 12 calibrations. (The same report at the same time
                    // again is the same calibration, recorded once: checked below.)
                    "--at",
                    &format!("2026-11-{:02}", k + 1),
                ])
                .stderr(std::process::Stdio::piped())
                .spawn()
                .unwrap()
        })
        .collect();
    for c in children {
        let out = c.wait_with_output().unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let list = run_ok(d, &["history", "list", "--db", "h.sqlite"]);
    assert_eq!(list.lines().count(), 13, "{list}");
    // Retried: nothing recorded twice.
    let (code, _, err) = run(
        d,
        &argv("history add --robot-id R0 --report r.json --db h.sqlite --at 2026-11-01"),
    );
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("already recorded as calibration"), "{err}");
    let list = run_ok(d, &["history", "list", "--db", "h.sqlite"]);
    assert_eq!(list.lines().count(), 13, "{list}");
}

#[test]
fn curves_and_html_report() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // Pose curves at Table 4.2's posture 4, in the three formats.
    for out in ["pose.svg", "pose.png", "pose.csv"] {
        let text = run_ok(
            d,
            &argv(&format!(
                "curves pose --robot ge-a4 --readings -6.883,13.301,4.122,-28.645
                 --param p1,p4,p35 --out {out}"
            )),
        );
        assert!(
            text.contains("p35 (joint1.slope): periodic, period 52.30"),
            "{text}"
        );
    }
    let svg = std::fs::read_to_string(d.join("pose.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.len() > 20_000 && svg.contains("link1.alpha"));
    let png = std::fs::read(d.join("pose.png")).unwrap();
    assert!(png.starts_with(b"\x89PNG\r\n\x1a\n") && png.len() > 20_000);
    let csv = std::fs::read_to_string(d.join("pose.csv")).unwrap();
    assert!(csv.starts_with("param,value,x,y,z,alpha,beta,gamma\n"));
    assert_eq!(csv.lines().count(), 1 + 3 * 201);
    // At the nominal value the curve passes through Table 4.2's pose (28.576, 13.995, 0.020, 47.6).
    let row: Vec<f64> = csv
        .lines()
        .filter(|l| l.starts_with("p4,"))
        .nth(100)
        .unwrap()
        .split(',')
        .skip(1)
        .map(|v| v.parse().unwrap())
        .collect();
    assert!(
        row[0].abs() < 1e-9 && (row[1] - 28.576).abs() < 0.01 && (row[4] - 47.6).abs() < 0.01,
        "{row:?}"
    );

    // The objective of Fig 4.11 (postures 1 and 2 of Table 4.2) against p38.
    std::fs::write(
        d.join("p.csv"),
        "posture,v1,v2,v3,v4\n1,-11.053,12.369,4.009,-11.583\n2,-12.696,9.037,1.493,5.156\n",
    )
    .unwrap();
    run_ok(d, &argv("fk --robot ge-a4 --postures p.csv --out d.csv"));
    let text = run_ok(
        d,
        &argv(
            "curves objective --robot ge-a4 --data d.csv --param p38 --span 100 --points 2001
             --out o.csv",
        ),
    );
    // At the true value the objective is zero (to the rounding of the file's numbers).
    let at_9 = text
        .lines()
        .find(|l| l.contains("local minimum at 9.000000 deg/unit: objective"))
        .unwrap_or_else(|| panic!("{text}"));
    let objective: f64 = at_9.rsplit(' ').next().unwrap().parse().unwrap();
    assert!(objective < 1e-20, "{at_9}");
    assert!(text.contains("not convex"), "{text}");
    assert!(
        text.contains("1: 31.080") && text.contains("2: 69.82"),
        "{text}"
    );
    let o = std::fs::read_to_string(d.join("o.csv")).unwrap();
    assert!(o.starts_with("param,value,objective\n") && o.lines().count() == 2002);
    run_ok(
        d,
        &argv("curves objective --robot ge-a4 --data d.csv --param p1,p38 --out o.svg"),
    );
    let err = run_err(
        d,
        &argv("curves objective --robot ge-a4 --data d.csv --param p1 --out o.txt"),
    );
    assert!(err.contains(".svg, .png or .csv"), "{err}");

    // The HTML report, from calibrate --html and from files.
    run_ok(
        d,
        &argv(
            "simulate --robot ge-a4 --postures 30 --perturb p1=+0.05,joint2.offset=-0.5
             --noise length=0.0005,angle=0.005 --out data.csv",
        ),
    );
    run_ok(
        d,
        &argv("calibrate --robot ge-a4 --data data.csv --html a.html --report r.json --out c.toml"),
    );
    run_ok(
        d,
        &argv("report --robot ge-a4 --data data.csv --calibrated c.toml --out b.html"),
    );
    run_ok(
        d,
        &argv("report --robot ge-a4 --data data.csv --calibration r.json --out c.html"),
    );
    for f in ["a.html", "b.html", "c.html"] {
        let h = std::fs::read_to_string(d.join(f)).unwrap();
        assert!(
            h.starts_with("<!DOCTYPE html>") && h.trim_end().ends_with("</html>"),
            "{f}"
        );
        for id in [
            "summary",
            "residuals",
            "histogram",
            "changes",
            "spectrum",
            "redundancy",
            "warnings",
        ] {
            assert!(
                h.contains(&format!("id=\"{id}\"")),
                "{f} lacks section {id}"
            );
        }
        // Self-contained: no URL, no external resource; the only script is the 3-D view's, in
        // the page (its data and its renderer).
        for bad in ["http:", "https:", "src=", "<link", "@import"] {
            assert!(!h.contains(bad), "{f} contains {bad}");
        }
        assert_eq!(h.matches("<script").count(), 2, "{f}");
        assert!(h.contains("id=\"view3d\"") && h.contains("<canvas"), "{f}");
        assert_eq!(h.matches("<svg").count(), h.matches("</svg>").count());
        assert!(h.matches("<svg").count() >= 4);
        assert!(h.contains("p3 - p9 - p15 - p21 - p27 - p33"), "{f}");
        // The predicted accuracy and its map, whether calibrated here or given (30 postures);
        // `calibrate --html` alone did not ask for it, and its page says how to.
        assert!(h.contains("id=\"prediction\""), "{f} lacks the prediction");
        assert_eq!(
            h.contains("--predict</code>"),
            f == "a.html",
            "{f}: how to get the prediction"
        );
    }
    // `--html` alone runs no prediction (no cross-validation folds): the report has none and no
    // prediction phase among its timings; `--predict` runs it, and the page then shows the map.
    let phases = |file: &str| -> (bool, Vec<String>) {
        let r: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(d.join(file)).unwrap()).unwrap();
        let phases = r["timings"]
            .as_array()
            .unwrap()
            .iter()
            .map(|t| t["phase"].as_str().unwrap().to_string())
            .collect();
        (r.get("prediction").is_some(), phases)
    };
    let (predicted, timed) = phases("r.json");
    assert!(
        !predicted && !timed.iter().any(|p| p == "prediction"),
        "{timed:?}"
    );
    run_ok(
        d,
        &argv(
            "calibrate --robot ge-a4 --data data.csv --html p.html --report p.json --predict
             --quiet",
        ),
    );
    let (predicted, timed) = phases("p.json");
    assert!(
        predicted && timed.iter().any(|p| p == "prediction"),
        "{timed:?}"
    );
    let h = std::fs::read_to_string(d.join("p.html")).unwrap();
    assert!(h.contains("id=\"prediction\"") && !h.contains("--predict</code>"));
    // The page rebuilt from the JSON report alone is the one calibrate wrote.
    run_ok(d, &["report", "--from", "r.json", "--html", "d.html"]);
    assert_eq!(
        std::fs::read_to_string(d.join("d.html")).unwrap(),
        std::fs::read_to_string(d.join("a.html")).unwrap()
    );
    // A report from a newer kinecal is refused, naming the version; nothing is written.
    let text = std::fs::read_to_string(d.join("r.json")).unwrap();
    assert!(text.contains("\"schema_version\": 2,"), "{text}");
    std::fs::write(
        d.join("r99.json"),
        text.replace("\"schema_version\": 2,", "\"schema_version\": 99,"),
    )
    .unwrap();
    let err = run_err(d, &["report", "--from", "r99.json", "--html", "e.html"]);
    assert!(err.contains("schema version 99"), "{err}");
    assert!(!d.join("e.html").exists());
}

/// Without a tracker: a ballbar's distances and probe contacts with a table, each from its own
/// file, calibrate the robot; the analysis says what the placement leaves undetermined.
#[test]
fn distances_and_contacts_calibrate_without_a_tracker() {
    use std::fmt::Write as _;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let text = kinecal::model::examples::GE_A4_TOML.to_string()
        + "\n# The table the probe touches.\n[[planes]]\nname = \"table\"\nnormal = [0, 0, 1]\noffset = -1.5\n";
    std::fs::write(d.join("a4.toml"), &text).unwrap();
    let nominal = kinecal::model::robot_file::parse_robot_toml(&text, "a4.toml").unwrap();
    let mut truth = nominal.clone();
    for (name, delta) in [
        ("link3.y", -0.02),
        ("joint2.offset", 0.3),
        ("link2.y", 0.01),
    ] {
        let id = kinecal::parse_param_list(name, &nominal).unwrap()[0];
        let q = nominal.param_quantity(id);
        truth.set(id, truth.get(id) + nominal.units.to_si(q, delta));
    }
    let postures = kinecal::apps::simulate::sample_postures(&nominal, 120, 4);
    let (mut contacts, mut distances) = (
        String::from("posture,site,plane,v1,v2,v3,v4,gap\n"),
        String::from("pair,a1,a2,a3,a4,b1,b2,b3,b4,distance,sigma_position\n"),
    );
    let chain = kinecal::Chain::new(&truth);
    let at = |k: usize| {
        chain
            .frame_at(&postures[k].readings, kinecal::Target::EndEffector)
            .translation
            / 0.0254
    };
    let v = |k: usize| {
        postures[k]
            .readings
            .iter()
            .map(|x| x.to_string())
            .collect::<Vec<_>>()
            .join(",")
    };
    for k in 0..60 {
        let _ = writeln!(contacts, "{},ee,table,{},{}", k + 1, v(k), at(k).z + 1.5);
    }
    for k in 0..30 {
        let (a, b) = (60 + 2 * k, 61 + 2 * k);
        let _ = writeln!(
            distances,
            "{},{},{},{},0.0004",
            k + 1,
            v(a),
            v(b),
            (at(a) - at(b)).norm()
        );
    }
    std::fs::write(d.join("contacts.csv"), contacts).unwrap();
    std::fs::write(d.join("ballbar.csv"), distances).unwrap();
    let out = run_ok(
        d,
        &argv("analyze --robot a4.toml --distances ballbar.csv --estimate links,offsets"),
    );
    assert!(out.contains("30 distances"), "{out}");
    assert!(
        out.contains("- 6 (motions of the world no observation sees: no observation in the global frame) = 11."),
        "{out}"
    );
    assert!(out.contains("Numerical rank 11 of 34"), "{out}");
    let out = run_ok(
        d,
        &argv(
            "calibrate --robot a4.toml --contacts contacts.csv --distances ballbar.csv
             --estimate identifiable --report rep.json --out cal.toml",
        ),
    );
    assert!(out.contains("30 distances, 60 contacts"), "{out}");
    assert!(out.contains("RMS contact error (in)"), "{out}");
    let rep = common::read_json(&d.join("rep.json"));
    assert_eq!(rep["converged"], true);
    assert_eq!(rep["observations"][0]["kind"], "distance");
    let other = &rep["identification"]["after"]["other"];
    assert!(other[0]["max"].as_f64().unwrap() < 1e-8, "{other}");
    let cal = std::fs::read_to_string(d.join("cal.toml")).unwrap();
    assert!(cal.contains("# The table the probe touches."), "{cal}");
    // The changes the data can see are found: link 3's y length, to 1e-6 in.
    let p14 = &rep["parameters"][13];
    assert!(
        (p14["estimated"].as_f64().unwrap() - 11.79).abs() < 1e-6,
        "{p14}"
    );
    // The minimum-change rule works without a tracker too (parameters no observation feels,
    // such as the probe's attitude, stay at nominal), converging to the same fit.
    let out = run_ok(
        d,
        &argv(
            "calibrate --robot a4.toml --contacts contacts.csv --distances ballbar.csv
             --solution min-change --report mc.json",
        ),
    );
    assert!(out.contains("min-change solution"), "{out}");
    let mc = common::read_json(&d.join("mc.json"));
    assert_eq!(mc["converged"], true);
    assert!(
        mc["identification"]["after"]["other"][0]["max"]
            .as_f64()
            .unwrap()
            < 1e-8
    );
    // Validation and the history show the errors of the kinds observed, not zero positions.
    let out = run_ok(
        d,
        &argv(
            "calibrate --robot a4.toml --contacts contacts.csv --distances ballbar.csv
             --holdout 0.3 --record A4-9 --db h.sqlite",
        ),
    );
    assert!(out.contains("distance error (in)"), "{out}");
    assert!(out.contains("contact error (in)"), "{out}");
    assert!(!out.contains("position error"), "{out}");
    let validation = out
        .lines()
        .find(|l| l.starts_with("validation after"))
        .unwrap();
    assert!(!validation.contains("0.000000"), "{out}");
    let list = run_ok(d, &["history", "list", "--db", "h.sqlite"]);
    assert!(
        list.contains("distance 0.0") && list.contains("; contact "),
        "{list}"
    );
    assert!(!list.contains("position"), "{list}");
    let show = run_ok(d, &["history", "show", "--db", "h.sqlite", "--id", "1"]);
    assert!(show.contains("RMS distance error 0.0"), "{show}");
    // Validation files of any kind, told by their header: fit on the contacts, check on the
    // ballbar.
    let out = run_ok(
        d,
        &argv(
            "calibrate --robot a4.toml --contacts contacts.csv --validate ballbar.csv
             --estimate link3.y,joint2.offset",
        ),
    );
    assert!(out.contains("distance error (in)"), "{out}");
    let after = out
        .lines()
        .filter(|l| l.starts_with("validation after"))
        .collect::<Vec<_>>();
    assert_eq!(after.len(), 2, "{out}");
    // Observations are needed.
    let err = run_err(d, &["calibrate", "--robot", "a4.toml"]);
    assert!(
        err.contains("--data/--distances/--contacts: no observation file given"),
        "{err}"
    );
}

/// Numbers that do not mislead and exit codes scripts can rely on: a run stopped by the
/// iteration cap exits 4; position-only data has no attitude error (JSON null, not 0); output
/// piped into a closed reader ends quietly.
#[test]
fn exit_codes_and_absent_figures() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    run_ok(
        d,
        &argv(
            "simulate --robot ge-a4 --postures 20 --seed 3 --perturb p1=0.1,joint2.offset=5
             --position-only --out pos.csv",
        ),
    );
    let out = kinecal()
        .current_dir(d)
        .args(argv(
            "calibrate --robot ge-a4 --data pos.csv --estimate p1,p2,p8,joint2.offset --max-iter 1
             --report r.json",
        ))
        .output()
        .unwrap();
    assert_eq!(
        out.status.code(),
        Some(4),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("NOT converged"));
    assert!(String::from_utf8_lossy(&out.stderr).contains("iteration cap"));
    let rep = common::read_json(&d.join("r.json"));
    assert_eq!(rep["converged"], false);
    assert!(
        rep["rms_orientation_after"].is_null(),
        "{}",
        rep["rms_orientation_after"]
    );
    assert!(!String::from_utf8_lossy(&out.stdout).contains("attitude"));
    // A closed pipe: no panic.
    let mut child = std::process::Command::new(assert_cmd::cargo::cargo_bin("kinecal"))
        .current_dir(d)
        .args(argv(
            "analyze --robot ge-a4 --data pos.csv --print jacobian",
        ))
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let status = child.wait().unwrap();
    let mut err = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
    assert!(!err.contains("panicked"), "{err}");
    assert_ne!(status.code(), Some(101));
}

/// Outputs never replace an input, follow a planted symlink, or land half-way: a run that fails
/// at its last step leaves every earlier output as it was, and no temporary file behind.
#[test]
fn outputs_are_written_only_when_the_whole_run_succeeds() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    run_ok(
        d,
        &argv("simulate --robot ge-a4 --postures 20 --seed 3 --out d.csv"),
    );
    let data = std::fs::read(d.join("d.csv")).unwrap();
    let err = run_err(d, &argv("calibrate --robot ge-a4 --data d.csv --out d.csv"));
    assert!(
        err.contains("refusing to write an output over an input"),
        "{err}"
    );
    assert_eq!(std::fs::read(d.join("d.csv")).unwrap(), data);
    let err = run_err(d, &argv("fk --robot ge-a4 --postures d.csv --out ./d.csv"));
    assert!(err.contains("over an input"), "{err}");
    // An existing output stays as it was when a later output cannot be written.
    std::fs::write(d.join("out.toml"), "keep me").unwrap();
    std::fs::create_dir(d.join("rep.json")).unwrap();
    let err = run_err(
        d,
        &argv(
            "calibrate --robot ge-a4 --data d.csv --estimate p1 --out out.toml --report rep.json",
        ),
    );
    assert!(err.contains("rep.json"), "{err}");
    assert_eq!(
        std::fs::read_to_string(d.join("out.toml")).unwrap(),
        "keep me"
    );
    // Symlinks planted under temporary-file names (the old fixed ones, and the new scheme's
    // `.kinecal-tmp-PID-RANDOM-NAME` with this live process's pid) are not followed.
    let victim = d.join("victim.txt");
    std::fs::write(&victim, "untouched").unwrap();
    let planted = [
        ".out.toml.kinecal-tmp".to_string(),
        ".out.toml.kinecal-tmp.toml".to_string(),
        format!(".kinecal-tmp-{}-0-out.toml", std::process::id()),
    ];
    #[cfg(unix)]
    for name in &planted {
        std::os::unix::fs::symlink(&victim, d.join(name)).unwrap();
    }
    run_ok(
        d,
        &argv("calibrate --robot ge-a4 --data d.csv --estimate p1 --out out.toml"),
    );
    assert_eq!(std::fs::read_to_string(&victim).unwrap(), "untouched");
    assert!(std::fs::read_to_string(d.join("out.toml"))
        .unwrap()
        .contains("[[links]]"));
    // No temporary file is left behind.
    let left: Vec<String> = std::fs::read_dir(d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
        .filter(|n| n.contains("kinecal-tmp") && !planted.contains(n))
        .collect();
    assert!(left.is_empty(), "{left:?}");
}

/// Numbers no file should hold are refused by file, line and field, and nothing kinecal writes
/// holds NaN or infinity.
#[test]
fn impossible_numbers_are_refused_by_file_line_and_field() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let err = run_err(
        d,
        &argv("simulate --robot ge-a4 --postures 3 --perturb all=-1e308 --out x.csv"),
    );
    assert!(
        err.contains("--perturb") && err.contains("within +-1e9"),
        "{err}"
    );
    assert!(!d.join("x.csv").exists());
    run_ok(d, &argv("simulate --robot ge-a4 --postures 10 --out d.csv"));
    let data = std::fs::read_to_string(d.join("d.csv")).unwrap();
    let mut lines: Vec<&str> = data.lines().collect();
    let row = lines[3].to_string();
    let mut fields: Vec<&str> = row.split(',').collect();
    fields[7] = "1e308";
    let bad_row = fields.join(",");
    lines[3] = &bad_row;
    std::fs::write(d.join("big.csv"), lines.join("\n")).unwrap();
    let err = run_err(d, &["calibrate", "--robot", "ge-a4", "--data", "big.csv"]);
    assert!(
        err.contains("big.csv:4: field `y`") && err.contains("within +-1e9"),
        "{err}"
    );
    let robot = kinecal::model::examples::GE_A4_TOML.replacen("y = -8.5", "y = -1e308", 1);
    std::fs::write(d.join("r.toml"), robot).unwrap();
    let err = run_err(d, &["calibrate", "--robot", "r.toml", "--data", "d.csv"]);
    assert!(err.contains("r.toml:10: field `links[0].y`"), "{err}");
    std::fs::write(
        d.join("dh.csv"),
        "kind,a,alpha,d,theta\nrevolute,1e308,0,0,0\n",
    )
    .unwrap();
    let err = run_err(
        d,
        &argv(
            "import dh --convention standard --length-unit m --angle-unit deg dh.csv --out dh.toml",
        ),
    );
    assert!(err.contains("dh.csv:2: field `a`"), "{err}");
    assert!(!d.join("dh.toml").exists());
}

/// Sweeps are bounded (no run without end), and the default span fits the parameter: the
/// robot's reach for a length, 50 deg for an angle.
#[test]
fn curve_sweeps_are_bounded_and_sized_to_the_parameter() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let r = argv("curves pose --robot ge-a4 --readings -6.883,13.301,4.122,-28.645");
    for (extra, expect) in [
        (vec!["--from", "-1e308", "--to", "50"], "within +-1e9"),
        (vec!["--points", "100000000"], "between 3 and 100000"),
        (
            vec!["--from", "1", "--to", "1.0000000000000002"],
            "too narrow",
        ),
    ] {
        let mut a: Vec<&str> = r.to_vec();
        a.extend(["--param", "p1", "--out", "c.csv"]);
        a.extend(extra);
        let err = run_err(d, &a);
        assert!(err.contains(expect), "{err}");
    }
    // Readings given inline are named as such (they were named `--postures`).
    let err = run_err(
        d,
        &argv("curves pose --robot ge-a4 --readings 1,2,3 --param p1 --out c.csv"),
    );
    assert!(
        err.contains("--readings: 3 readings for a robot with 4 joints"),
        "{err}"
    );
    let mut a: Vec<&str> = r.to_vec();
    a.extend(["--param", "p1,p4", "--points", "3", "--out", "c.csv"]);
    run_ok(d, &a);
    let csv = std::fs::read_to_string(d.join("c.csv")).unwrap();
    let values: Vec<(String, f64)> = csv
        .lines()
        .skip(1)
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            (f[0].to_string(), f[1].parse().unwrap())
        })
        .collect();
    // p1 (15.08 in) +- the GE A4's reach (about 52 in); p4 (0 deg) +- 50 deg.
    let p1: Vec<f64> = values.iter().filter(|v| v.0 == "p1").map(|v| v.1).collect();
    assert!(
        (p1[2] - p1[0] - 2.0 * kinecal::model::examples::ge_a4().reach() / 0.0254).abs() < 1e-9
    );
    let p4: Vec<f64> = values.iter().filter(|v| v.0 == "p4").map(|v| v.1).collect();
    assert_eq!(p4, [-50.0, 0.0, 50.0]);
}

/// A sweep that is refused says its numbers as kinecal's tables write them (`5`, not `5e0`), and
/// a span that is not positive is named, by its flag or its spec key, with its value and what it
/// must be. Before, `--span 0` said "from 9e0 to 9e0: a sweep runs from a smaller to a larger
/// number" under `--from/--to/--span/--points`.
#[test]
fn a_bad_sweep_is_said_plainly_and_a_span_must_be_positive() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let r = argv("curves pose --robot ge-a4 --readings -6.883,13.301,4.122,-28.645 --param p4");
    for span in ["0", "-5", "-0.25"] {
        let mut a: Vec<&str> = r.to_vec();
        a.extend(["--span", span, "--out", "c.csv"]);
        let err = run_err(d, &a);
        assert!(
            err.contains(&format!(
                "--span: {span}: expected a positive number, the width of the sweep (from the \
                 parameter's value less half of it to the value plus half, in the robot file's \
                 units)"
            )),
            "{err}"
        );
    }
    let mut a: Vec<&str> = r.to_vec();
    a.extend(["--from", "5", "--to", "5", "--out", "c.csv"]);
    let err = run_err(d, &a);
    assert!(
        err.contains("from 5 to 5: a sweep runs from a smaller to a larger number within +-1e9"),
        "{err}"
    );
    // A spec's span is named by its key.
    std::fs::write(
        d.join("s.toml"),
        "job = \"curves\"\ncurve = \"pose\"\nrobot = \"ge-a4\"\n\
         readings = [1.0, 2.0, 3.0, 4.0]\nsweep = { param = \"p4\", span = 0.0 }\n\
         out = \"c.csv\"\n",
    )
    .unwrap();
    let err = run_err(d, &argv("curves pose --spec s.toml"));
    assert!(
        err.contains("s.toml: span: 0: expected a positive number"),
        "{err}"
    );
    assert!(!d.join("c.csv").exists());
}

/// `curves --out -` writes the table on standard output, as `fk` and `predict` do with
/// `--out -` (the shared output writer), and what the curves show then goes to standard error;
/// the table is the file `--out o.csv` writes, its numbers as kinecal's tables write them (the
/// objective of Fig 4.11 at the true value, 4e-26, with its exponent, not in 26 zeros). Before,
/// `-` was refused: "the name must end in .svg, .png or .csv".
#[test]
fn curves_write_their_table_on_standard_output() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(
        d.join("p.csv"),
        "posture,v1,v2,v3,v4\n1,-11.053,12.369,4.009,-11.583\n2,-12.696,9.037,1.493,5.156\n",
    )
    .unwrap();
    run_ok(d, &argv("fk --robot ge-a4 --postures p.csv --out d.csv"));
    let curve = "curves objective --robot ge-a4 --data d.csv --param p38 --span 100 --points 11";
    let (code, shown, said) = run(d, &argv(&format!("{curve} --out o.csv")));
    assert_eq!(code, 0, "{said}");
    assert_eq!(said, "wrote o.csv\n");
    let file = std::fs::read_to_string(d.join("o.csv")).unwrap();
    let (code, table, said) = run(d, &argv(&format!("{curve} --out -")));
    assert_eq!(code, 0, "{said}");
    assert_eq!(table, file);
    assert_eq!(said, shown);
    let at_9 = table
        .lines()
        .find_map(|l| l.strip_prefix("p38,9,"))
        .unwrap_or_else(|| panic!("{table}"));
    assert!(
        at_9.contains("e-") && at_9.parse::<f64>().unwrap() < 1e-20,
        "{table}"
    );
    // The pose curve too.
    let (code, table, said) = run(
        d,
        &argv("curves pose --robot ge-a4 --readings 0,0,0,0 --param p4 --points 3 --out -"),
    );
    assert_eq!(code, 0, "{said}");
    assert!(
        table.starts_with("param,value,x,y,z,alpha,beta,gamma\np4,-50,"),
        "{table}"
    );
    assert_eq!(table.lines().count(), 4, "{table}");
    assert_eq!(said, "p4 (link1.alpha): periodic, period 360.000000 deg\n");
}

/// Data in millimetres against the built-in robot in inches: a warning that names the likely
/// unit, the fit refused for it (exit 3), and with --strict exit 3 with nothing solved.
#[test]
fn data_in_another_unit_is_said_and_strict_refuses_it() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    run_ok(
        d,
        &argv("simulate --robot ge-a4 --postures 30 --seed 2 --out in.csv"),
    );
    // The same measurements in millimetres.
    let text = std::fs::read_to_string(d.join("in.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let mut mm = header.join(",") + "\n";
    for l in lines {
        let f: Vec<String> = l
            .split(',')
            .zip(&header)
            .map(|(v, h)| match *h {
                "x" | "y" | "z" => (v.parse::<f64>().unwrap() * 25.4).to_string(),
                _ => v.to_string(),
            })
            .collect();
        mm += &(f.join(",") + "\n");
    }
    std::fs::write(d.join("mm.csv"), mm).unwrap();
    let (code, _, err) = run(d, &["calibrate", "--robot", "ge-a4", "--data", "mm.csv"]);
    // The fit runs, ends far above its noise, and is refused for its units (exit 3).
    assert_eq!(code, 3, "{err}");
    assert!(err.contains("REFUSED: a unit check fired"), "{err}");
    assert!(
        err.contains("warning: the measured positions spread 25 times as widely as the nominal robot predicts for the same postures: are they in mm? the data is read in the robot file's length unit (in): state the file's unit when it is another (--length-unit)"),
        "{err}"
    );
    // Stated, the same file calibrates without a word about units.
    let (code, _, err) = run(
        d,
        &argv("calibrate --robot ge-a4 --data mm.csv --length-unit mm --strict"),
    );
    assert_eq!(code, 0, "{err}");
    assert!(!err.contains("spread"), "{err}");
    let out = kinecal()
        .current_dir(d)
        .args(argv(
            "calibrate --robot ge-a4 --data mm.csv --strict --out cal.toml --report r.json",
        ))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(3), "{err}");
    assert!(err.contains("STRICT:"), "{err}");
    assert!(!d.join("cal.toml").exists() && !d.join("r.json").exists());
    // The data in the right unit passes --strict.
    run_ok(
        d,
        &argv("calibrate --robot ge-a4 --data in.csv --strict --out cal.toml"),
    );
    assert!(d.join("cal.toml").exists());
}

/// `kinecal plan` as a user runs it: sampled candidates to a postures file and an HTML page;
/// a measurement file as candidates gives the chosen rows of that file; postures kept;
/// mistakes refused with a message.
#[test]
fn plan_chooses_postures_and_refuses_mistakes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = run_ok(
        d,
        &argv(
            "plan --robot ge-a4 --sample 500 --seed 3 --count 12 --out plan.csv --html plan.html",
        ),
    );
    assert!(out.contains("chose 12 of 500 candidates"), "{out}");
    assert!(out.contains("rank 24 of 24"), "{out}");
    assert!(out.contains("at least as good as 100 of them"), "{out}");
    let csv = std::fs::read_to_string(d.join("plan.csv")).unwrap();
    assert!(csv.starts_with("posture,v1,v2,v3,v4\n"), "{csv}");
    assert_eq!(csv.lines().count(), 13);
    let html = std::fs::read_to_string(d.join("plan.html")).unwrap();
    assert!(html.contains("<svg") && html.contains("Joint 4: readings of the plan"));
    assert!(!html.contains("http://") && !html.contains("https://"));

    // The chosen postures measured (simulated), then planned again from that measurement file
    // with the first 6 kept: the output is the chosen rows of the file.
    run_ok(
        d,
        &argv("simulate --robot ge-a4 --postures 60 --seed 4 --out measured.csv"),
    );
    run_ok(
        d,
        &argv("plan --robot ge-a4 --sample 10 --count 6 --out kept.csv"),
    );
    let json = run_ok(
        d,
        &argv(
            "plan --robot ge-a4 --candidates measured.csv --count 8 --keep kept.csv --criterion i
             --json --out chosen.csv",
        ),
    );
    let v = common::check_document("plan", &json);
    assert_eq!(v["criterion"], "i");
    assert_eq!(v["postures"].as_array().unwrap().len(), 14);
    assert_eq!(v["postures"][0]["kept"], true);
    assert_eq!(v["rank"], v["parameters"].as_array().unwrap().len());
    let chosen = std::fs::read_to_string(d.join("chosen.csv")).unwrap();
    assert!(chosen.starts_with("posture,site,v1"), "{chosen}");
    assert_eq!(chosen.lines().count(), 9);

    let err = run_err(
        d,
        &argv("plan --robot ge-a4 --sample 5 --count 6 --out p.csv"),
    );
    assert!(err.contains("the pool has 5 candidates"), "{err}");
    let err = run_err(
        d,
        &argv("plan --robot ge-a4 --sample 5 --count 0 --out p.csv"),
    );
    assert!(err.contains("--count: must be at least 1"), "{err}");
    let err = run_err(
        d,
        &argv("plan --robot ge-a4 --sample 50 --count 5 --sites nope --out p.csv"),
    );
    assert!(err.contains("unknown site `nope`"), "{err}");
    let err = run_err(
        d,
        &argv("plan --robot ge-a4 --candidates measured.csv --count 5 --sites ee --out p.csv"),
    );
    assert!(err.contains("observation file"), "{err}");
    // Its poses may be read as positions (a tracker that measures positions only).
    let out = run_ok(
        d,
        &argv(
            "plan --robot ge-a4 --candidates measured.csv --count 10 --position-only
             --out positions.csv",
        ),
    );
    assert!(out.contains("30 residual rows"), "{out}");
    let err = run_err(
        d,
        &argv("plan --robot ge-a4 --candidates measured.csv --count 5 --out measured.csv"),
    );
    assert!(err.contains("over an input"), "{err}");
    assert!(!d.join("p.csv").exists(), "a refused run writes nothing");
}

/// `kinecal batch`: every robot of a manifest (CSV or TOML) calibrated, outputs written per
/// robot, one robot's failure never stopping the others, the exit code saying some failed;
/// results identical on one thread and on several; records in the history.
#[test]
fn batch_calibrates_a_fleet_and_survives_a_bad_row() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::create_dir(d.join("fleet")).unwrap();
    let mut csv = String::from("serial,robot,data,options\n");
    for i in 1..=6 {
        run_ok(
            d,
            &argv(&format!(
                "simulate --robot ge-a4 --postures 40 --seed {i}
                 --perturb-std length=0.01,angle=0.1 --noise length=0.001,angle=0.01
                 --out fleet/d{i}.csv"
            )),
        );
        csv += &format!("A4-{i},ge-a4,d{i}.csv,--estimate identifiable --holdout 0.2\n");
    }
    csv += "A4-missing,ge-a4,nope.csv,\n";
    csv += "A4-typo,ge-a4,d1.csv,--estimat identifiable\n";
    csv += "A4-out,ge-a4,d2.csv,\"--out 'calibrated 2.toml' --report r2.json\"\n";
    std::fs::write(d.join("fleet/fleet.csv"), &csv).unwrap();
    let out = kinecal()
        .current_dir(d)
        .args(argv("batch fleet/fleet.csv --summary summary.csv --jobs 2"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1), "some robots failed");
    let text = String::from_utf8(out.stdout).unwrap();
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(!err.contains("panicked"), "{err}");
    assert!(err.contains("9 robots: 7 calibrated, 2 failed"), "{err}");
    for i in 1..=6 {
        let line = text
            .lines()
            .find(|l| l.starts_with(&format!("A4-{i} ")))
            .unwrap();
        assert!(line.ends_with("ok"), "{line}");
    }
    assert!(text.contains("nope.csv"), "{text}");
    assert!(
        text.contains("fleet.csv:9: unknown option `--estimat`"),
        "{text}"
    );
    // Outputs of a row are written relative to the manifest.
    assert!(d.join("fleet/calibrated 2.toml").exists());
    assert!(d.join("fleet/r2.json").exists());
    let summary = std::fs::read_to_string(d.join("summary.csv")).unwrap();
    assert!(summary.starts_with("serial,status,parameters,iterations,metric,unit,"));
    assert_eq!(summary.lines().count(), 10);

    // One thread gives the same table.
    let one = kinecal()
        .current_dir(d)
        .args(["batch", "fleet/fleet.csv", "--jobs", "1", "--quiet"])
        .output()
        .unwrap();
    assert_eq!(String::from_utf8(one.stdout).unwrap(), text);

    // TOML manifest, common options, recorded in the history.
    let toml = "[defaults]\nrobot = \"ge-a4\"\nselection = { estimate = \"identifiable\" }\n\
                [[robots]]\nserial = \"A4-1\"\nobservations = [{ file = \"d1.csv\" }]\n\
                [[robots]]\nserial = \"A4-2\"\nobservations = [{ file = \"d2.csv\" }]\n\
                validation = { holdout = 0.25 }\n";
    std::fs::write(d.join("fleet/fleet.toml"), toml).unwrap();
    let text = run_ok(
        d,
        &argv("batch fleet/fleet.toml --record --db h.sqlite --quiet"),
    );
    assert_eq!(
        text.lines().filter(|l| l.ends_with("ok")).count(),
        2,
        "{text}"
    );
    let list = run_ok(d, &["history", "list", "--db", "h.sqlite"]);
    assert!(list.contains("A4-1") && list.contains("A4-2"), "{list}");

    // Manifest mistakes stop everything before any work.
    for (name, body, says) in [
        ("m1.csv", "serial,robot\nA,ge-a4\nA,ge-a4\n", "listed twice"),
        ("m2.csv", "serial,robots,data\n", "unknown column `robots`"),
        (
            "m3.csv",
            "robot,data\n",
            "expected the header serial,robot,data",
        ),
        (
            "m4.csv",
            "serial,robot,data,options\nA,ge-a4,d1.csv,--out x.toml\nB,ge-a4,d2.csv,--out x.toml\n",
            "is also written for A",
        ),
        (
            "m5.toml",
            "[[robots]]\nrobot = \"ge-a4\"\n",
            "`serial` is required",
        ),
        (
            "m8.toml",
            "[[robots]]\nserial = \"A\"\nrobot = \"ge-a4\"\nsolver = { method = \"xx\" }\n",
            "fleet/m8.toml: robot 1 (A): unknown variant `xx`",
        ),
        (
            "m7.toml",
            "[[robot]]\nserial = \"A\"\nrobot = \"ge-a4\"\n",
            "`[[robot]]` tables with `options` are no longer read",
        ),
        // A spec of one job (what `calibrate --write-spec` writes) is named as one.
        (
            "m9.toml",
            "robot = \"ge-a4\"\ndata = [\"d1.csv\"]\n",
            "fleet/m9.toml: a spec of one job, not a batch manifest: run it with `kinecal \
             calibrate --spec fleet/m9.toml`",
        ),
        (
            "m10.toml",
            "job = \"analyze\"\nrobot = \"ge-a4\"\n",
            "run it with `kinecal analyze --spec fleet/m10.toml`",
        ),
        (
            "m6.csv",
            "serial,robot,data,options\nA,ge-a4,d1.csv,--record A\n",
            "not a per-robot option",
        ),
    ] {
        std::fs::write(d.join("fleet").join(name), body).unwrap();
        let out = kinecal()
            .current_dir(d)
            .args(["batch", &format!("fleet/{name}"), "--quiet"])
            .output()
            .unwrap();
        let all = String::from_utf8_lossy(&out.stdout).to_string()
            + &String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{name}: {all}");
        assert!(all.contains(says), "{name}: {all}");
    }
}

/// `kinecal compensate` as a user runs it: a program through a calibrated twin (each row
/// reaches, through the calibrated robot's `fk`, the pose the nominal robot gives the original
/// readings), Cartesian targets with and without seeds, flags and exit code 3 for what cannot be
/// done, and mistakes refused with the file, line and field.
#[test]
fn compensate_programs_and_targets() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    run_ok(
        d,
        &argv(
            "simulate --robot ge-a4 --postures 40 --seed 3
             --perturb p1=+0.05,p14=-0.02,joint2.offset=-0.5 --out m.csv --truth true.toml",
        ),
    );
    // The program: the readings of m.csv.
    let m = std::fs::read_to_string(d.join("m.csv")).unwrap();
    let mut program = String::from("posture;v1;v2;v3;v4\n# a comment, ; delimited\n");
    for l in m.lines().skip(1) {
        let f: Vec<&str> = l.split(',').collect();
        program += &format!("{};{}\n", f[0], f[2..6].join(";"));
    }
    std::fs::write(d.join("program.csv"), &program).unwrap();
    let out = kinecal()
        .current_dir(d)
        .args(argv(
            "compensate --robot true.toml --nominal ge-a4 --in program.csv --out comp.csv",
        ))
        .output()
        .unwrap();
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(err.contains("compensated 40 rows"), "{err}");
    let comp = std::fs::read_to_string(d.join("comp.csv")).unwrap();
    assert!(
        comp.starts_with("posture,v1,v2,v3,v4,position_error,attitude_error,iterations,flags\n")
    );
    // Through the calibrated robot, the compensated readings give the nominal poses.
    let mut readings = String::from("posture,v1,v2,v3,v4\n");
    for l in comp.lines().skip(1) {
        let f: Vec<&str> = l.split(',').collect();
        readings += &format!("{}\n", f[..5].join(","));
    }
    std::fs::write(d.join("compensated.csv"), &readings).unwrap();
    run_ok(
        d,
        &argv("fk --robot true.toml --postures compensated.csv --out reached.csv"),
    );
    run_ok(
        d,
        &argv("fk --robot ge-a4 --postures program.csv --out meant.csv"),
    );
    let nums = |p: &str| -> Vec<Vec<f64>> {
        std::fs::read_to_string(d.join(p))
            .unwrap()
            .lines()
            .skip(1)
            .map(|l| l.split(',').skip(6).map(|v| v.parse().unwrap()).collect())
            .collect()
    };
    let (reached, meant) = (nums("reached.csv"), nums("meant.csv"));
    assert_eq!(reached.len(), 40);
    for (r, m) in reached.iter().zip(&meant) {
        for k in 0..6 {
            // The file's 15 significant digits on values up to 360: 1e-9 is rounding.
            assert!((r[k] - m[k]).abs() < 1e-9, "{r:?} {m:?}");
        }
    }
    // The program's rows outside the GE A4's reading ranges, if any, are flagged, and the exit
    // code says so.
    let flagged = comp.lines().skip(1).filter(|l| !l.ends_with(',')).count();
    assert_eq!(
        out.status.code(),
        Some(if flagged > 0 { 3 } else { 0 }),
        "{err}"
    );

    // Targets: positions with seeds, and one far away: flagged unreachable, exit 3.
    let mut targets = String::from("target,x,y,z,v1,v2,v3,v4\n");
    for l in m.lines().skip(1).take(5) {
        let f: Vec<&str> = l.split(',').collect();
        targets += &format!("t{},{},{}\n", f[0], f[6..9].join(","), f[2..6].join(","));
    }
    targets += "far,100,0,0,-10,10,2,0\n";
    std::fs::write(d.join("targets.csv"), &targets).unwrap();
    let out = kinecal()
        .current_dir(d)
        .args(argv(
            "compensate --robot true.toml --nominal ge-a4 --in targets.csv --out t.csv",
        ))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(3));
    let t = std::fs::read_to_string(d.join("t.csv")).unwrap();
    let far = t.lines().last().unwrap();
    assert!(
        far.starts_with("far,") && far.contains("unreachable"),
        "{far}"
    );
    assert!(t.lines().count() == 7);

    // Mistakes.
    std::fs::write(d.join("bad.csv"), "posture,v1,v2,v3,v4\n1,0,0,zero,0\n").unwrap();
    let err = run_err(
        d,
        &argv("compensate --robot true.toml --nominal ge-a4 --in bad.csv --out o.csv"),
    );
    assert!(
        err.contains("bad.csv:2: field `v3`: expected a number, found `zero`"),
        "{err}"
    );
    assert!(!d.join("o.csv").exists(), "a failed run writes nothing");
    std::fs::write(d.join("odd.csv"), "id,a,b\n1,2,3\n").unwrap();
    let err = run_err(
        d,
        &argv("compensate --robot true.toml --nominal ge-a4 --in odd.csv --out o.csv"),
    );
    assert!(
        err.contains("expected a program (posture,v1,...,v4) or targets"),
        "{err}"
    );
    let err = run_err(
        d,
        &argv(
            "compensate --robot true.toml --nominal ge-a4 --in targets.csv --out o.csv --site tcp",
        ),
    );
    assert!(err.contains("--site: unknown site `tcp`"), "{err}");
    let err = run_err(
        d,
        &argv("compensate --robot true.toml --nominal ge-a4 --in targets.csv --out targets.csv"),
    );
    assert!(err.contains("over an input"), "{err}");
}

/// `kinecal compensate` on Cartesian targets as a controller needs them: targets without seeds
/// all land inside the joint ranges (checked through `fk` reading compensate's own output),
/// in the configuration asked for; a measurement file is taken as targets with its sites and
/// readings as seeds; URScript and joint targets are written only when no row is flagged;
/// attitudes in degrees in a radian file and positions in mm in a metre file are refused with
/// the line.
#[test]
fn compensate_targets_for_a_controller() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::copy(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/robots/abb_irb120.toml"),
        d.join("irb120.toml"),
    )
    .unwrap();
    // The "real" robot and postures inside its ranges; the targets are where it goes.
    run_ok(
        d,
        &argv(
            "simulate --robot irb120.toml --postures 300 --seed 4
             --perturb-std length=0.001,angle=0.005 --out m.csv --truth true.toml",
        ),
    );
    let m = std::fs::read_to_string(d.join("m.csv")).unwrap();
    let mut targets = String::from("target,x,y,z\n");
    let mut poses = String::from("target,x,y,z,alpha,beta,gamma\n");
    for l in m.lines().skip(1) {
        let f: Vec<&str> = l.split(',').collect();
        targets += &format!("{},{}\n", f[0], f[8..11].join(","));
        poses += &format!("{},{}\n", f[0], f[8..14].join(","));
    }
    std::fs::write(d.join("targets.csv"), &targets).unwrap();
    std::fs::write(d.join("poses.csv"), &poses).unwrap();
    let comp = |input: &str, extra: &[&str], out: &str| {
        let mut args = vec![
            "compensate",
            "--robot",
            "true.toml",
            "--nominal",
            "irb120.toml",
            "--in",
            input,
            "--out",
            out,
        ];
        args.extend(extra);
        let o = kinecal().current_dir(d).args(&args).output().unwrap();
        let err = String::from_utf8(o.stderr).unwrap();
        assert!(!err.contains("panicked"), "{err}");
        (o.status.code(), err)
    };
    let nums = |p: &str, skip: usize, take: usize| -> Vec<Vec<f64>> {
        std::fs::read_to_string(d.join(p))
            .unwrap()
            .lines()
            .skip(1)
            .map(|l| {
                l.split(',')
                    .skip(skip)
                    .take(take)
                    .map(|v| v.parse().unwrap())
                    .collect()
            })
            .collect()
    };
    let ranges: Vec<(f64, f64)> = [
        (-165.0f64, 165.0f64),
        (-110.0, 110.0),
        (-110.0, 70.0),
        (-160.0, 160.0),
        (-120.0, 120.0),
        (-400.0, 400.0),
    ]
    .iter()
    .map(|(a, b)| (a.to_radians(), b.to_radians()))
    .collect();
    for (input, cols) in [("targets.csv", 3), ("poses.csv", 6)] {
        let (code, err) = comp(input, &[], "c.csv");
        // A target drawn next to a singularity may be flagged so; nothing else.
        let c = std::fs::read_to_string(d.join("c.csv")).unwrap();
        for l in c.lines().skip(1) {
            let flags = l.rsplit(',').next().unwrap();
            assert!(
                flags.is_empty() || flags == "near singularity",
                "{input}: {l}"
            );
        }
        assert!(err.contains("compensated 300 rows"), "{err}");
        assert!(code == Some(0) || code == Some(3), "{err}");
        for r in nums("c.csv", 1, 6) {
            for (v, (lo, hi)) in r.iter().zip(&ranges) {
                assert!(v >= lo && v <= hi, "{input}: {r:?}");
            }
        }
        // Through the real robot, the compensated readings land on the targets.
        run_ok(
            d,
            &argv("fk --robot true.toml --postures c.csv --out landed.csv"),
        );
        let (landed, meant) = (nums("landed.csv", 8, cols), nums(input, 1, cols));
        assert_eq!(landed.len(), 300);
        for (a, b) in landed.iter().zip(&meant) {
            for k in 0..cols {
                assert!((a[k] - b[k]).abs() < 1e-9, "{input}: {a:?} {b:?}");
            }
        }
    }
    // In a configuration: every row of the solution is in it or flagged.
    let (_, err) = comp(
        "poses.csv",
        &["--configuration", "shoulder=front,elbow=up,wrist=noflip"],
        "c.csv",
    );
    assert!(err.contains("not in the configuration"), "{err}");
    let c = std::fs::read_to_string(d.join("c.csv")).unwrap();
    let kept = c.lines().skip(1).filter(|l| l.ends_with(',')).count();
    assert!(kept > 0, "{c}");
    // The measurement file itself: its readings are the seeds, its sites the frames.
    let (code, err) = comp("m.csv", &[], "back.csv");
    assert!(code == Some(0) || code == Some(3), "{err}");
    let back = std::fs::read_to_string(d.join("back.csv")).unwrap();
    for l in back.lines().skip(1) {
        let flags = l.rsplit(',').next().unwrap();
        assert!(flags.is_empty() || flags == "near singularity", "{l}");
    }
    assert!(
        back.starts_with("posture,site,v1,v2,v3,v4,v5,v6,x,y,z,alpha,beta,gamma,position_error"),
        "{back}"
    );
    for (a, b) in nums("back.csv", 2, 6).iter().zip(nums("m.csv", 2, 6)) {
        for k in 0..6 {
            assert!((a[k] - b[k]).abs() < 1e-9, "{a:?} {b:?}");
        }
    }
    // And it is a measurement file: through the real robot, its readings land on its poses.
    let out = run_ok(
        d,
        &argv("check --robot true.toml --data back.csv --threshold 1e-9"),
    );
    assert!(out.contains("OK: the robot meets its accuracy"), "{out}");

    // Controller programs: the first 3 targets, with the same readings as the table.
    let three: String = targets.lines().take(4).map(|l| format!("{l}\n")).collect();
    std::fs::write(d.join("three.csv"), &three).unwrap();
    let (code, err) = comp("three.csv", &[], "three_table.csv");
    assert_eq!(code, Some(0), "{err}");
    let table = nums("three_table.csv", 1, 6);
    let (code, err) = comp("three.csv", &["--format", "urscript"], "p.script");
    assert_eq!(code, Some(0), "{err}");
    let script = std::fs::read_to_string(d.join("p.script")).unwrap();
    assert!(script.contains("def kinecal_program():\n"), "{script}");
    assert!(script.ends_with("end\nkinecal_program()\n"), "{script}");
    let moves: Vec<Vec<f64>> = script
        .lines()
        .filter_map(|l| l.trim().strip_prefix("movej(["))
        .map(|l| {
            l.split(']')
                .next()
                .unwrap()
                .split(',')
                .map(|v| v.trim().parse().unwrap())
                .collect()
        })
        .collect();
    assert_eq!(moves.len(), 3, "{script}");
    for (a, b) in moves.iter().zip(&table) {
        for k in 0..6 {
            assert!((a[k] - b[k]).abs() < 1e-9, "{a:?} {b:?}");
        }
    }
    for (format, header, scale) in [
        (
            "joints-abb",
            "target,rax_1,rax_2,rax_3,rax_4,rax_5,rax_6",
            180.0 / std::f64::consts::PI,
        ),
        (
            "joints-kuka",
            "target,A1,A2,A3,A4,A5,A6",
            180.0 / std::f64::consts::PI,
        ),
        (
            "joints-fanuc",
            "target,J1,J2,J3,J4,J5,J6",
            180.0 / std::f64::consts::PI,
        ),
        (
            "joints-ur",
            "target,base,shoulder,elbow,wrist1,wrist2,wrist3",
            1.0,
        ),
    ] {
        let (code, err) = comp("three.csv", &["--format", format], "j.csv");
        assert_eq!(code, Some(0), "{err}");
        let j = std::fs::read_to_string(d.join("j.csv")).unwrap();
        assert!(j.starts_with(&format!("{header}\n")), "{j}");
        for (a, b) in nums("j.csv", 1, 6).iter().zip(&table) {
            for k in 0..6 {
                assert!((a[k] - b[k] * scale).abs() < 1e-7, "{format}: {a:?} {b:?}");
            }
        }
    }
    // A flagged row: no controller program, exit 3, the row named.
    std::fs::write(d.join("far.csv"), format!("{three}far,2,0,0.5\n")).unwrap();
    std::fs::remove_file(d.join("p.script")).unwrap();
    let (code, err) = comp("far.csv", &["--format", "urscript"], "p.script");
    assert_eq!(code, Some(3), "{err}");
    assert!(err.contains("nothing written to p.script"), "{err}");
    assert!(err.contains("far: unreachable"), "{err}");
    assert!(!d.join("p.script").exists());

    // Unit mistakes: degrees in a radian file, millimetres in a metre file.
    std::fs::write(
        d.join("deg.csv"),
        "target,x,y,z,alpha,beta,gamma\n1,0.3,0,0.5,0,90,0\n",
    )
    .unwrap();
    let (code, err) = comp("deg.csv", &[], "o.csv");
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("deg.csv:2: beta = 90 rad is more than a turn"),
        "{err}"
    );
    std::fs::write(d.join("mm.csv"), "target,x,y,z\n1,300,0,500\n").unwrap();
    let (code, err) = comp("mm.csv", &[], "o.csv");
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("mm.csv:2: target 1 lies"), "{err}");
    assert!(
        err.contains("reaches (583.095189 m) from the robot's base"),
        "{err}"
    );
    assert!(err.contains("are the positions in m"), "{err}");
    // A number beyond any length, named as written.
    std::fs::write(d.join("huge.csv"), "target,x,y,z\n1,1e308,0,0\n").unwrap();
    let (code, err) = comp("huge.csv", &[], "o.csv");
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("huge.csv:2: field `x`: 1e308 is not a finite number within +-1e9"),
        "{err}"
    );
    // A configuration that cannot be told, or for a program.
    let (code, err) = comp(
        "targets.csv",
        &["--configuration", "elbow=sideways"],
        "o.csv",
    );
    assert_eq!(code, Some(1));
    assert!(
        err.contains("--configuration: elbow=sideways: expected up or down"),
        "{err}"
    );
    assert!(!d.join("o.csv").exists(), "a refused run writes nothing");
}

/// `kinecal import ur` and `kinecal export ur` on a real UR3e factory calibration: the round
/// trip is exact (and read back, said so), and a slope the file cannot hold is refused, or
/// under a looser tolerance named with its deviation.
#[test]
fn ur_kinematics_round_trip_and_what_is_not_written() {
    let Some(d) = shared_data::shared_data("urdf/universal_robots/real_factory_calibration_ur3e")
    else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let t = dir.path();
    std::fs::copy(d.join("ur3e_calibration_1.yaml"), t.join("cal.yaml")).unwrap();
    run_ok(t, &["import", "ur", "cal.yaml", "--out", "ur3e.toml"]);
    let out = kinecal()
        .current_dir(t)
        .args(argv(
            "export ur --robot ur3e.toml --template cal.yaml --out back.yaml",
        ))
        .output()
        .unwrap();
    assert!(out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("read back: largest deviation "), "{err}");
    assert!(!err.contains("left out"), "{err}");
    assert_eq!(
        String::from_utf8_lossy(&out.stdout),
        "TCP to enter on the controller: none (the calibrated tool frame is tool0)\n"
    );
    // The same poses from the file written back.
    std::fs::write(
        t.join("p.csv"),
        "posture,v1,v2,v3,v4,v5,v6\n1,0.1,-1.2,1.5,-0.3,1.57,0.2\n2,2,-0.5,-1,1,-1,3\n",
    )
    .unwrap();
    run_ok(t, &["import", "ur", "back.yaml", "--out", "back.toml"]);
    let a = run_ok(t, &["fk", "--robot", "ur3e.toml", "--postures", "p.csv"]);
    let b = run_ok(t, &["fk", "--robot", "back.toml", "--postures", "p.csv"]);
    let nums = |s: &str| -> Vec<f64> {
        s.lines()
            .skip(1)
            .flat_map(|l| {
                l.split(',')
                    .skip(8)
                    .map(|v| v.parse::<f64>().unwrap())
                    .collect::<Vec<_>>()
            })
            .collect()
    };
    for (x, y) in nums(&a).iter().zip(nums(&b)) {
        assert!((x - y).abs() < 1e-9, "{a}\n{b}");
    }
    // A transducer slope: refused, nothing written, the slope named.
    let toml = std::fs::read_to_string(t.join("ur3e.toml")).unwrap();
    let changed = toml.replacen("slope = 1.0", "slope = 1.001", 1);
    assert_ne!(toml, changed, "the robot file has slopes");
    std::fs::write(t.join("sloped.toml"), changed).unwrap();
    let args = argv("export ur --robot sloped.toml --template cal.yaml --out s.yaml");
    let err = run_err(t, &args);
    assert!(
        err.contains("misses the robot by up to")
            && err.contains("it cannot hold joint 1 (shoulder_pan_joint) slope 1.001 rad/unit")
            && err.contains("hint: --tolerance length=L,angle=A"),
        "{err}"
    );
    assert!(!t.join("s.yaml").exists());
    // Under a looser tolerance: written without it, and said so.
    let out = kinecal()
        .current_dir(t)
        .args(args)
        .args(["--tolerance", "length=0.01,angle=0.01"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("not written: joint 1 (shoulder_pan_joint) slope 1.001"),
        "{err}"
    );
    assert!(t.join("s.yaml").exists());
}

/// A UR10 calibrated against a laser tracker 3.8 m away, with one series in a session of its
/// own and a 150 mm tool: `export ur` keeps the controller's base (the tracker placement and
/// the session are left out, and said), prints the TCP to enter, and the file with that TCP is
/// the calibrated robot on its own base.
#[test]
fn ur_export_leaves_the_tracker_out_and_prints_the_tcp() {
    use kinecal::{Frame, Link};
    let Some(d) = shared_data::shared_data("urdf/universal_robots/config/ur10") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let t = dir.path();
    std::fs::copy(d.join("default_kinematics.yaml"), t.join("ur10.yaml")).unwrap();
    let template = std::fs::read_to_string(t.join("ur10.yaml")).unwrap();
    let nominal = kinecal::import::ur::import_ur(&template, "ur10.yaml")
        .unwrap()
        .robot;
    let mut cal = nominal.clone();
    let placement = Frame {
        rotation: kinecal::model::kinematics::rot_zyx(0.7, 0.0, 0.0),
        translation: nalgebra::Vector3::new(3.2, -2.0, 0.5),
    };
    cal.links[0] = kinecal::import::link_of(&placement.then(&Frame::from_link(&nominal.links[0])));
    cal.links[2].x += 0.0004;
    cal.links[6].z += 0.15;
    cal.sessions.push(kinecal::model::robot::Session {
        name: "B".into(),
        frame: Link {
            x: 0.4,
            ..Link::default()
        },
    });
    std::fs::write(
        t.join("cal.toml"),
        kinecal::model::robot_file::write_robot_toml(&cal, None),
    )
    .unwrap();
    let out = kinecal()
        .current_dir(t)
        .args(argv(
            "export ur --robot cal.toml --template ur10.yaml --out new.yaml",
        ))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("left out: the measurement frame")
            && err.contains("base_link at x 3.2 y -2 z 0.5 m")
            && err.contains("left out: the session frame B"),
        "{err}"
    );
    let tcp = String::from_utf8_lossy(&out.stdout);
    assert!(
        tcp.starts_with("TCP to enter on the controller (Installation > General > TCP")
            && tcp.contains("set_tcp(p["),
        "{tcp}"
    );
    // The shoulder stays where the UR10 has it.
    let written = std::fs::read_to_string(t.join("new.yaml")).unwrap();
    let k = kinecal::import::ur::parse_ur_kinematics(&written, "new.yaml").unwrap();
    let k0 = kinecal::import::ur::parse_ur_kinematics(&template, "ur10.yaml").unwrap();
    assert_eq!(k.origins[0][..5], k0.origins[0][..5]);
    // The printed TCP is the tool: 150 mm along tool0's z (tool0 is the nominal tool frame).
    let z: f64 = tcp
        .split("Z ")
        .nth(1)
        .and_then(|r| r.split(" mm").next())
        .unwrap()
        .parse()
        .unwrap();
    let expected = kinecal::import::inverse(&Frame::from_link(&nominal.links[6]))
        .then(&Frame::from_link(&cal.links[6]));
    assert!((z - expected.translation.z * 1e3).abs() < 1e-6, "{tcp}");
}

/// The DH table states its units: a robot in radians comes back in radians from `import dh`
/// without flags (it was read in degrees by default, 0.35 m off). A table that states none
/// needs them; flags that contradict it are refused. A robot the table cannot hold (the GE A4's
/// transducer slopes) is refused with the reason and nothing is written, unless the tolerance is
/// loosened.
#[test]
fn dh_tables_state_their_units_and_exports_refuse_what_misses() {
    let Some(d) = shared_data::shared_data("urdf/universal_robots/urdf_plain") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let t = dir.path();
    std::fs::copy(d.join("ur5_robot.urdf"), t.join("ur5.urdf")).unwrap();
    run_ok(
        t,
        &argv("import urdf ur5.urdf --base base_link --tip tool0 --out ur5.toml"),
    );
    std::fs::write(
        t.join("p.csv"),
        "posture,v1,v2,v3,v4,v5,v6\n1,0.1,-1.2,1.5,-0.3,1.57,0.2\n2,2,-0.5,-1,1,-1,3\n",
    )
    .unwrap();
    let a = run_ok(t, &["fk", "--robot", "ur5.toml", "--postures", "p.csv"]);
    for convention in ["standard", "modified"] {
        let out = kinecal()
            .current_dir(t)
            .args(argv(&format!(
                "export dh --robot ur5.toml --convention {convention} --out ur5.csv"
            )))
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{err}");
        assert!(err.contains("read back: largest deviation "), "{err}");
        let table = std::fs::read_to_string(t.join("ur5.csv")).unwrap();
        assert!(
            table.contains("# length_unit = m\n# angle_unit = rad\n"),
            "{table}"
        );
        // The URDF's joint names go into the table and come back; the robot is named after the
        // table's file (it was named "").
        assert!(
            table.contains(",name\n") && table.contains(",shoulder_pan_joint\n"),
            "{table}"
        );
        run_ok(t, &["import", "dh", "ur5.csv", "--out", "back.toml"]);
        let back = std::fs::read_to_string(t.join("back.toml")).unwrap();
        assert!(back.starts_with("name = \"ur5\"\n"), "{back}");
        std::fs::write(
            t.join("named.csv"),
            "posture,wrist_3_joint,wrist_2_joint,wrist_1_joint,elbow_joint,shoulder_lift_joint,\
             shoulder_pan_joint\n1,0.2,1.57,-0.3,1.5,-1.2,0.1\n2,3,-1,1,-1,-0.5,2\n",
        )
        .unwrap();
        let by_name = run_ok(
            t,
            &["fk", "--robot", "back.toml", "--postures", "named.csv"],
        );
        let b = run_ok(t, &["fk", "--robot", "back.toml", "--postures", "p.csv"]);
        // The poses (the columns after the site and the readings) of each posture.
        let poses = |fk: &str| -> Vec<String> {
            fk.lines()
                .skip(1)
                .map(|l| l.split(',').skip(8).collect::<Vec<_>>().join(","))
                .collect()
        };
        assert_eq!(poses(&b).len(), 2);
        assert_eq!(poses(&by_name), poses(&b));
        for (x, y) in a.lines().zip(b.lines()).skip(1) {
            for (u, v) in x.split(',').zip(y.split(',')).skip(7) {
                let (u, v): (f64, f64) = (u.parse().unwrap(), v.parse().unwrap());
                assert!((u - v).abs() < 1e-9, "{convention}:\n{x}\n{y}");
            }
        }
        let err = run_err(t, &argv("import dh ur5.csv --angle-unit deg --out x.toml"));
        assert!(
            err.contains("--angle-unit: ur5.csv:3 states `angle_unit = rad`, not deg"),
            "{err}"
        );
    }
    std::fs::write(
        t.join("old.csv"),
        "kind,a,alpha,d,theta\nrevolute,0,90,0.1,0\n",
    )
    .unwrap();
    let err = run_err(
        t,
        &argv("import dh old.csv --convention standard --out x.toml"),
    );
    assert!(
        err.contains("--length-unit: old.csv does not state its length unit"),
        "{err}"
    );
    assert!(!t.join("x.toml").exists());
    // The GE A4: readings are voltages, a DH table's joint variables are joint values.
    let err = run_err(
        t,
        &argv("export dh --robot ge-a4 --convention standard --out ge.csv"),
    );
    assert!(
        err.contains("it cannot hold joint 1 slope 7.2 deg/unit")
            && err.contains("nothing written"),
        "{err}"
    );
    assert!(!t.join("ge.csv").exists());
    let (code, _, err) = run(
        t,
        &argv(
            "export dh --robot ge-a4 --convention standard --tolerance length=100,angle=360
             --out ge.csv",
        ),
    );
    assert_eq!(code, 0, "{err}");
    assert!(
        err.contains("not written: joint 1 slope 7.2 deg/unit; up to "),
        "{err}"
    );
    assert!(t.join("ge.csv").exists());
}

/// A URDF template saved with a byte-order mark, with joints without `<origin>`: the calibrated
/// URDF is well-formed, keeps the mark, and reads back as the calibrated robot.
#[test]
fn urdf_export_of_a_template_with_a_bom_and_no_origins() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let urdf = "\u{feff}<?xml version=\"1.0\"?>
<robot name=\"arm\">
  <link name=\"base\"/><link name=\"l1\"/><link name=\"l2\"/><link name=\"tool\"/>
  <joint name=\"j1\" type=\"revolute\"><parent link=\"base\"/><child link=\"l1\"/>
    <axis xyz=\"0 0 1\"/><limit lower=\"-3\" upper=\"3\" effort=\"1\" velocity=\"1\"/></joint>
  <joint name=\"j2\" type=\"revolute\"><parent link=\"l1\"/><child link=\"l2\"/>
    <origin xyz=\"0.3 0 0.2\" rpy=\"1.5707963 0 0\"/><axis xyz=\"0 0 1\"/><limit lower=\"-2\" upper=\"2\" effort=\"1\" velocity=\"1\"/></joint>
  <joint name=\"tool_joint\" type=\"fixed\"><parent link=\"l2\"/><child link=\"tool\"/></joint>
</robot>
";
    std::fs::write(d.join("arm.urdf"), urdf).unwrap();
    run_ok(d, &["import", "urdf", "arm.urdf", "--out", "arm.toml"]);
    run_ok(
        d,
        &argv(
            "simulate --robot arm.toml --postures 5
             --perturb link1.x=+0.002,link2.y=+0.001,link3.z=+0.003,joint2.offset=+0.01
             --out d.csv --truth t.toml",
        ),
    );
    let out = kinecal()
        .current_dir(d)
        .args(argv(
            "export urdf --robot t.toml --template arm.urdf --out t.urdf",
        ))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("read back: largest deviation "), "{err}");
    let written = std::fs::read_to_string(d.join("t.urdf")).unwrap();
    assert!(written.starts_with('\u{feff}'));
    run_ok(d, &["import", "urdf", "t.urdf", "--out", "back.toml"]);
    let a = run_ok(d, &["fk", "--robot", "t.toml", "--postures", "d.csv"]);
    let b = run_ok(d, &["fk", "--robot", "back.toml", "--postures", "d.csv"]);
    for (x, y) in a.lines().zip(b.lines()).skip(1) {
        for (u, v) in x.split(',').zip(y.split(',')).skip(4) {
            let (u, v): (f64, f64) = (u.parse().unwrap(), v.parse().unwrap());
            assert!((u - v).abs() < 1e-9, "{x}\n{y}");
        }
    }
}

/// Another lab's tracker export, as a user meets it: `;`-separated with decimal commas, in mm
/// and degrees (attitudes unused) for a robot in metres, its own column names and per-axis
/// standard deviations, two series measured from two tracker placements, and a third series
/// from a third one for validation. Stated at the door (`--columns`, `--length-unit`,
/// `--position-only`, `--session-per-file`), it calibrates and validates; unstated, the unit
/// mix-up is named before any solving and `--strict` stops there (exit 3).
#[test]
fn tracker_series_from_moved_placements() {
    use kinecal::model::robot::{Link, Session};
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let nominal = kinecal::apps::simulate::random_robot(&[kinecal::JointKind::Revolute; 6], 77);
    std::fs::write(
        d.join("r.toml"),
        kinecal::model::robot_file::write_robot_toml(&nominal, None),
    )
    .unwrap();
    let mut truth = kinecal::apps::simulate::perturb(
        &nominal,
        kinecal::apps::simulate::PerturbStd {
            length: 0.001,
            angle: 0.002,
            slope_fraction: 0.0,
        },
        78,
    );
    let frame = |x: f64, a: f64| Link {
        x,
        y: -1.0,
        z: 0.4,
        alpha: a,
        beta: 0.02,
        gamma: -0.03,
    };
    truth.sessions = vec![
        Session {
            name: "B".into(),
            frame: frame(2.0, 1.2),
        },
        Session {
            name: "C".into(),
            frame: frame(-1.5, -2.0),
        },
    ];
    let export = |session: &str, seed: u64, path: &str| {
        let mut ps = kinecal::apps::simulate::sample_postures(&nominal, 50, seed);
        for p in &mut ps {
            p.session = Some(session.into());
        }
        let mut data = kinecal::apps::simulate::measure(&truth, &ps, false);
        kinecal::apps::simulate::add_noise(&mut data, 2e-5, 1e-4, seed + 1);
        let mut out = String::from("J1;J2;J3;J4;J5;J6;X;sX;Y;sY;Z;sZ;RX;RY;RZ\n");
        for o in &data.observations {
            let kinecal::Observation::Pose(p) = o else {
                unreachable!()
            };
            let v = &data.postures[p.view[0].posture].readings;
            let mut cells: Vec<String> = v.iter().map(|x| format!("{x}")).collect();
            for k in 0..3 {
                cells.push(format!("{}", p.position[k] * 1e3));
                cells.push("0,02".into());
            }
            for k in 0..3 {
                cells.push(format!("{}", p.euler[k].to_degrees()));
            }
            out.push_str(&cells.join(";").replace('.', ","));
            out.push('\n');
        }
        std::fs::write(d.join(path), out).unwrap();
    };
    export("A", 1, "A.csv");
    export("B", 3, "B.csv");
    export("C", 5, "C.csv");
    let cols = "v1=J1,v2=J2,v3=J3,v4=J4,v5=J5,v6=J6,x=X,y=Y,z=Z,sigma_x=sX,sigma_y=sY,sigma_z=sZ";
    // Unstated units: named before the solve; --strict stops there.
    let out = kinecal()
        .current_dir(d)
        .args(argv(&format!(
            "calibrate --robot r.toml --data A.csv --columns {cols} --strict"
        )))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(3), "{err}");
    assert!(
        err.contains("are they in mm?") && err.contains("nothing solved"),
        "{err}"
    );
    assert!(out.stdout.is_empty(), "nothing solved, nothing printed");
    // Stated: two series from two placements identify the robot and the second placement; the
    // third series is validated after its placement is re-estimated on it.
    let out = run_ok(
        d,
        &argv(&format!(
            "calibrate --robot r.toml --data A.csv --data B.csv --validate C.csv --columns {cols}
             --length-unit mm --position-only --session-per-file --estimate identifiable
             --report rep.json --out cal.toml"
        )),
    );
    assert!(out.contains("converged after"), "{out}");
    assert!(
        out.contains("validation sessions identification never saw (C)"),
        "{out}"
    );
    let rep = common::read_json(&d.join("rep.json"));
    assert_eq!(rep["validation"]["sessions_refitted"][0], "C");
    // 0.02 mm per axis: about 0.035 mm in 3D.
    let after = rep["validation"]["after"]["rms_position"].as_f64().unwrap();
    assert!(after < 6e-5, "{after} m");
    let cal = std::fs::read_to_string(d.join("cal.toml")).unwrap();
    assert!(
        cal.contains("[[sessions]]") && cal.contains("name = \"B\""),
        "{cal}"
    );
}

/// A calibration that makes the held-out errors worse than the nominal robot's is said, and
/// `--strict` refuses it with exit 3 (nothing written): identified on a robot measured with
/// perturbations, validated on postures of the nominal robot itself.
#[test]
fn a_calibration_worse_held_out_than_before_is_a_warning_and_strict_refuses_it() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let words = |line: &'static str| line.split_whitespace().collect::<Vec<_>>();
    run_ok(
        d,
        &words(
            "simulate --robot ge-a4 --postures 30 --seed 7 --perturb \
             p1=+0.05,p14=-0.02,joint2.offset=-0.5 --noise length=0.0005,angle=0.005 \
             --out data.csv",
        ),
    );
    run_ok(
        d,
        &words(
            "simulate --robot ge-a4 --postures 20 --seed 8 \
             --noise length=0.0005,angle=0.005 --out held.csv",
        ),
    );
    let args = words(
        "calibrate --robot ge-a4 --data data.csv --validate held.csv \
         --estimate p1,p14,offsets --out cal.toml",
    );
    let out = kinecal().current_dir(d).args(&args).output().unwrap();
    let text = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(out.status.success(), "{text}");
    assert!(
        text.contains("the calibration made the held-out position errors worse"),
        "{text}"
    );
    std::fs::remove_file(d.join("cal.toml")).unwrap();
    let out = kinecal()
        .current_dir(d)
        .args(&args)
        .arg("--strict")
        .output()
        .unwrap();
    assert_eq!(
        out.status.code(),
        Some(3),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        !d.join("cal.toml").exists(),
        "--strict wrote the calibration"
    );
}

/// The schema check of the tests finds the reports and catches one that breaks the schema (a
/// non-finite number written as null, a flag written as a string).
#[test]
fn reports_are_checked_against_the_shipped_schema() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    run_ok(
        d,
        &argv("simulate --robot ge-a4 --postures 20 --out data.csv"),
    );
    run_ok(
        d,
        &argv("calibrate --robot ge-a4 --data data.csv --report r.json"),
    );
    assert_eq!(common::check_reports(d), 1);
    let good = common::read_json(&d.join("r.json"));
    for (path, value) in [
        ("/parameters/0/estimated", serde_json::Value::Null),
        ("/converged", serde_json::Value::from("yes")),
        ("/observation_errors/after", serde_json::Value::from(1.0)),
    ] {
        let bad_dir = tempfile::tempdir().unwrap();
        let mut bad = good.clone();
        *bad.pointer_mut(path).unwrap() = value;
        std::fs::write(bad_dir.path().join("bad.json"), bad.to_string()).unwrap();
        let caught = std::panic::catch_unwind(|| common::check_reports(bad_dir.path()));
        assert!(caught.is_err(), "{path}: a broken report passed");
    }
}

/// Input files can be streams: `/dev/stdin` and `-` as a postures file (`fk`) and as an
/// observation file (`calibrate --data`) are read once, to their end, as the file would be.
#[test]
fn inputs_read_from_standard_input() {
    let dir = tempfile::tempdir().unwrap();
    let t = dir.path();
    run_ok(
        t,
        &argv("simulate --robot ge-a4 --postures 8 --perturb p3=+0.1 --out data.csv"),
    );
    let data = std::fs::read_to_string(t.join("data.csv")).unwrap();
    // A postures file with a comment and a blank line before its header.
    let postures = format!(
        "# postures\n\nposture,v1,v2,v3,v4\n{}",
        data.lines()
            .skip(1)
            .map(|l| l
                .split(',')
                .take(6)
                .filter(|f| *f != "ee")
                .collect::<Vec<_>>()
                .join(",")
                + "\n")
            .collect::<String>()
    );
    std::fs::write(t.join("p.csv"), &postures).unwrap();
    let from_file = run_ok(t, &["fk", "--robot", "ge-a4", "--postures", "p.csv"]);
    for input in ["/dev/stdin", "-"] {
        let out = kinecal()
            .current_dir(t)
            .args(["fk", "--robot", "ge-a4", "--postures", input])
            .write_stdin(postures.clone())
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{input}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert_eq!(String::from_utf8(out.stdout).unwrap(), from_file, "{input}");
        let out = kinecal()
            .current_dir(t)
            .args(argv(&format!(
                "calibrate --robot ge-a4 --data {input} --estimate p3"
            )))
            .write_stdin(data.clone())
            .output()
            .unwrap();
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success(),
            "{input}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(stdout.contains("8 postures"), "{stdout}");
    }
    // An empty stream is an empty file, said as such.
    let out = kinecal()
        .current_dir(t)
        .args(["fk", "--robot", "ge-a4", "--postures", "/dev/stdin"])
        .write_stdin("")
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("/dev/stdin:1: empty file"));
}

/// `kinecal dataset` on a damaged folder: refused with the file, line and count (exit 1), never
/// a panic (exit 101).
#[test]
fn dataset_refuses_a_damaged_folder_without_panicking() {
    let dir = tempfile::tempdir().unwrap();
    let t = dir.path();
    let folder = synthetic::with(
        synthetic::fanuc(),
        "TransTractoWorld0.csv",
        b"1 0 0 5\n0 1 0 6\n",
    );
    for (name, bytes) in &folder {
        std::fs::write(t.join(name), bytes).unwrap();
    }
    let err = run_err(t, &["dataset", "fanuc-r2000ic", ".", "--out", "out"]);
    assert!(
        err.contains("./TransTractoWorld0.csv:3: expected 3 rows of 4 numbers, found 2"),
        "{err}"
    );
    let folder = synthetic::fanuc();
    for (name, bytes) in &folder {
        std::fs::write(t.join(name), bytes).unwrap();
    }
    run_ok(t, &["dataset", "fanuc-r2000ic", ".", "--out", "out"]);
}

/// `kinecal dataset ipa-ur10` on a folder shaped like the data set (made-up values, the
/// README's row counts): the robot, the four series and the temperatures written, the suggested
/// calibration and the README's held-out figures printed; a series missing is refused naming
/// its file, with the hint.
#[test]
fn dataset_ipa_ur10_writes_the_series_and_prints_the_suggested_calibration() {
    let dir = tempfile::tempdir().unwrap();
    let t = dir.path();
    let folder = synthetic::folder("ipa-ur10");
    for (name, bytes) in &folder {
        let p = t.join("ipa_ur10_tracker").join(name);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(p, bytes).unwrap();
    }
    let out = run_ok(
        t,
        &["dataset", "ipa-ur10", "ipa_ur10_tracker", "--out", "ipa"],
    );
    let lines: Vec<&str> = out.lines().collect();
    assert!(
        lines[0].starts_with("UR10 + Leica laser tracker: "),
        "{out}"
    );
    assert!(
        lines[0].contains("A 11911 (a grid, overnight runs)"),
        "{out}"
    );
    assert_eq!(
        lines[1],
        "wrote ur10.toml, series_A.csv, series_B.csv, series_C.csv, series_D.csv, \
         temperatures.csv, series_D_iso.csv to ipa"
    );
    assert_eq!(
        lines[2],
        "next, in ipa: kinecal calibrate --robot ur10.toml --data series_A.csv --validate \
         series_C.csv --validate series_D.csv --estimate identifiable"
    );
    assert_eq!(
        lines[3],
        "held out, the data set's README gives for a correct calibration a mean position error \
         of about 0.52 mm on series_C.csv and 0.43 mm on series_D.csv (each alone; about 0.50 mm pooled over the \
         --validate files, as kinecal reports it)"
    );
    for f in [
        "ur10.toml",
        "series_A.csv",
        "series_D.csv",
        "temperatures.csv",
    ] {
        assert!(t.join("ipa").join(f).is_file(), "{f}");
    }
    let temperatures = std::fs::read_to_string(t.join("ipa/temperatures.csv")).unwrap();
    assert_eq!(
        temperatures.lines().count(),
        1 + 11_911 + 1_495 + 2_773 + 632
    );
    std::fs::remove_file(t.join("ipa_ur10_tracker/Series_C/measurements_random_poses.csv"))
        .unwrap();
    let err = run_err(
        t,
        &["dataset", "ipa-ur10", "ipa_ur10_tracker", "--out", "ipa2"],
    );
    assert!(
        err.contains("ipa_ur10_tracker/Series_C/measurements_random_poses.csv")
            && err.contains("hint: is ipa_ur10_tracker the folder of the data set"),
        "{err}"
    );
    assert!(!t.join("ipa2/ur10.toml").exists());
}

/// An arm that sags: a 3R with a horizontal shoulder and elbow, 2 kg bodies, metres.
const ELASTIC_ARM: &str = r#"name = "sagging arm"
length_unit = "m"
angle_unit = "rad"
[[links]]
z = 0.3
[[links]]
gamma = 1.5707963267948966
[[links]]
x = 0.6
[[links]]
x = 0.5
[[joints]]
kind = "revolute"
min = -3.0
max = 3.0
[[joints]]
kind = "revolute"
min = -3.0
max = 3.0
[[joints]]
kind = "revolute"
min = -3.0
max = 3.0
[[bodies]]
joint = 2
mass = 3.0
com = [0.3, 0.0, 0.0]
[[bodies]]
joint = 3
mass = 2.0
com = [0.3, 0.0, 0.05]
"#;

#[test]
fn an_elastic_calibration_recovers_stiffness_and_exports_its_table() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("arm.toml"), ELASTIC_ARM).unwrap();
    run_ok(
        d,
        &argv(
            "simulate --robot arm.toml --postures 40 --seed 2
             --perturb joint2.compliance=+4e-5,joint3.compliance=+1e-4
             --noise length=0.000005,angle=0.000005 --out data.csv",
        ),
    );
    let out = run_ok(
        d,
        &argv(
            "calibrate --robot arm.toml --data data.csv --estimate offsets,compliance
             --weights length=0.000005,angle=0.000005 --report r.json --html r.html",
        ),
    );
    assert!(out.contains("stiffness"), "{out}");
    let html = std::fs::read_to_string(d.join("r.html")).unwrap();
    assert!(
        html.contains("<h2 id=\"mass-model\">Mass model</h2>") && html.contains("N m/deg"),
        "the HTML report shows the stiffnesses (in degrees, as every angle of the page)"
    );
    run_ok(d, &argv("export stiffness --report r.json --out k.csv"));
    // Read back with the csv crate, as another program would.
    let mut rows = csv::Reader::from_path(d.join("k.csv")).unwrap();
    let header: Vec<String> = rows.headers().unwrap().iter().map(String::from).collect();
    assert_eq!(header, kinecal::report::STIFFNESS_COLUMNS);
    let mut seen = 0;
    for row in rows.records() {
        let row = row.unwrap();
        let (name, estimated) = (&row[0], &row[8]);
        let truth = match name {
            "joint2.compliance" => 4e-5,
            "joint3.compliance" => 1e-4,
            _ => continue,
        };
        assert_eq!(estimated, "1", "{row:?}");
        let c: f64 = row[3].parse().unwrap();
        let sc: f64 = row[4].parse().unwrap();
        let k: f64 = row[5].parse().unwrap();
        assert!(
            (c - truth).abs() < 3.0 * sc,
            "{name}: {c} +- {sc}, true {truth}"
        );
        assert!(
            (k * c - 1.0).abs() < 1e-12,
            "stiffness is 1/compliance: {row:?}"
        );
        assert_eq!(&row[7], "N m/rad");
        seen += 1;
    }
    // Joint 1 is vertical: gravity never loads it, and `compliance` leaves it out.
    assert_eq!(seen, 2);
    // A rigid robot's report has no compliances to export.
    run_ok(d, &argv("simulate --robot ge-a4 --postures 10 --out g.csv"));
    run_ok(
        d,
        &argv("calibrate --robot ge-a4 --data g.csv --report g.json"),
    );
    let err = run_err(d, &argv("export stiffness --report g.json --out x.csv"));
    assert!(err.contains("has no mass model"), "{err}");
    assert!(!d.join("x.csv").exists());
}

#[test]
fn a_stiffness_that_drifts_is_flagged_by_the_history() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("arm.toml"), ELASTIC_ARM).unwrap();
    // The same arm, its elbow 30 % softer three months later.
    for (data, compliance, at) in [
        ("jan.csv", "+4e-5", "2026-01-05T08:00:00Z"),
        ("apr.csv", "+5.2e-5", "2026-04-05T08:00:00Z"),
    ] {
        run_ok(
            d,
            &argv(&format!(
                "simulate --robot arm.toml --postures 40 --seed 2
                 --perturb joint3.compliance={compliance} --noise length=0.000005,angle=0.000005
                 --out {data}"
            )),
        );
        run_ok(
            d,
            &argv(&format!(
                "calibrate --robot arm.toml --data {data} --estimate offsets,compliance
                 --weights length=0.000005,angle=0.000005 --record ARM-7 --db h.db --at {at}"
            )),
        );
    }
    let out = kinecal()
        .current_dir(d)
        .args(["history", "drift", "--robot-id", "ARM-7", "--db", "h.db"])
        .output()
        .unwrap();
    let text = String::from_utf8(out.stdout).unwrap();
    assert_ne!(out.status.code(), Some(0), "{text}");
    let flagged: Vec<&str> = text.lines().filter(|l| l.starts_with("FLAG:")).collect();
    assert_eq!(flagged.len(), 1, "{text}");
    assert!(
        flagged[0].contains("joint 3 compliance") && flagged[0].contains("rad/(N m)"),
        "{text}"
    );
}

#[test]
fn compensation_and_fk_carry_each_rows_payload() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("nominal.toml"), ELASTIC_ARM).unwrap();
    // The calibrated arm: its shoulder and elbow yield.
    let soft = ELASTIC_ARM.replacen(
        "[[joints]]\nkind = \"revolute\"\nmin = -3.0\nmax = 3.0\n[[joints]]\nkind = \"revolute\"\nmin = -3.0\nmax = 3.0\n",
        "[[joints]]\nkind = \"revolute\"\nmin = -3.0\nmax = 3.0\n[[joints]]\nkind = \"revolute\"\nmin = -3.0\nmax = 3.0\ncompliance = 2e-4\n",
        1,
    );
    assert_ne!(soft, ELASTIC_ARM);
    std::fs::write(d.join("cal.toml"), &soft).unwrap();
    // The same point, empty-handed and with 8 kg in the gripper.
    std::fs::write(
        d.join("targets.csv"),
        "target,x,y,z,payload_mass,payload_cx,payload_cy,payload_cz\n\
         free,0.6,0.2,0.6,,,,\nloaded,0.6,0.2,0.6,8,0,0,0.05\n",
    )
    .unwrap();
    run_ok(
        d,
        &argv("compensate --robot cal.toml --nominal nominal.toml --in targets.csv --out out.csv"),
    );
    let text = std::fs::read_to_string(d.join("out.csv")).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap();
    assert!(
        header.starts_with("target,v1,v2,v3,payload_mass,payload_cx,payload_cy,payload_cz,"),
        "{header}"
    );
    let readings: Vec<Vec<f64>> = lines
        .map(|l| {
            l.split(',')
                .skip(1)
                .take(3)
                .map(|v| v.parse().unwrap())
                .collect()
        })
        .collect();
    // The load needs other readings (the arm sags under 8 kg)...
    let moved: f64 = (0..3)
        .map(|j| (readings[0][j] - readings[1][j]).abs())
        .sum();
    assert!(moved > 1e-4, "{readings:?}");
    // ... and fk, reading the same file with its payloads, puts both on the target.
    run_ok(
        d,
        &argv("fk --robot cal.toml --postures out.csv --out poses.csv"),
    );
    let poses = std::fs::read_to_string(d.join("poses.csv")).unwrap();
    let mut rows = csv::Reader::from_reader(poses.as_bytes());
    let h = rows.headers().unwrap().clone();
    let col = |n: &str| h.iter().position(|c| c == n).unwrap();
    for row in rows.records() {
        let row = row.unwrap();
        let p: Vec<f64> = ["x", "y", "z"]
            .iter()
            .map(|c| row[col(c)].parse().unwrap())
            .collect();
        let miss = ((p[0] - 0.6).powi(2) + (p[1] - 0.2).powi(2) + (p[2] - 0.6).powi(2)).sqrt();
        assert!(miss < 1e-6, "{row:?}: {miss} m from the target");
    }
    // A bad payload is refused with its line.
    std::fs::write(
        d.join("bad.csv"),
        "target,x,y,z,payload_mass\nfree,0.6,0.2,0.6,-3\n",
    )
    .unwrap();
    let err = run_err(
        d,
        &argv("compensate --robot cal.toml --nominal nominal.toml --in bad.csv --out bad_out.csv"),
    );
    assert!(
        err.contains("bad.csv:2") && err.contains("payload_mass"),
        "{err}"
    );
}
