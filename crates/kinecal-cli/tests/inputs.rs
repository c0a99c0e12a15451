//! Values a user gives, read as the user meant them or refused in the user's terms: an empty
//! parameter list is not "the default parameters", and a sign pattern that starts with `-` is
//! a value, not a flag.

mod common;

use common::{argv, run, run_err, run_ok};

#[test]
fn an_empty_parameter_list_is_refused_by_flag_by_key_and_in_a_batch() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    run_ok(
        d,
        &argv("simulate --robot ge-a4 --postures 12 --seed 2 --out data.csv"),
    );
    let said = "an empty parameter list: leave it out for the default parameters";
    for args in [
        vec![
            "calibrate",
            "--robot",
            "ge-a4",
            "--data",
            "data.csv",
            "--estimate",
            "",
        ],
        vec![
            "analyze",
            "--robot",
            "ge-a4",
            "--data",
            "data.csv",
            "--estimate",
            " ",
        ],
        vec![
            "plan",
            "--robot",
            "ge-a4",
            "--sample",
            "40",
            "--count",
            "4",
            "--estimate",
            "",
            "--out",
            "p.csv",
        ],
    ] {
        let err = run_err(d, &args);
        assert!(
            err.contains(&format!("--estimate: {said}")),
            "{args:?}: {err}"
        );
    }
    // Given absent, the default set runs.
    run_ok(d, &argv("calibrate --robot ge-a4 --data data.csv -q"));
    std::fs::write(
        d.join("job.toml"),
        "job = \"calibrate\"\nrobot = \"ge-a4\"\n[[observations]]\nfile = \"data.csv\"\n\
         [selection]\nestimate = \"\"\n",
    )
    .unwrap();
    let err = run_err(d, &argv("calibrate --spec job.toml -q"));
    assert!(
        err.contains(&format!("job.toml: estimate: {said}")),
        "{err}"
    );
    // The same spec as a batch job fails, and says why.
    std::fs::write(
        d.join("jobs.toml"),
        "[[jobs]]\njob = \"calibrate\"\nname = \"empty\"\nrobot = \"ge-a4\"\n\
         [[jobs.observations]]\nfile = \"data.csv\"\n[jobs.selection]\nestimate = \"\"\n",
    )
    .unwrap();
    let (code, out, err) = run(d, &argv("batch jobs.toml --quiet"));
    assert_ne!(code, 0, "{out}\n{err}");
    assert!(
        format!("{out}{err}").contains("an empty parameter list"),
        "{out}\n{err}"
    );
}

#[test]
fn a_sign_pattern_that_starts_with_a_minus_is_a_value() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("targets.csv"), "target,x,y,z\nt1,18,15,1\n").unwrap();
    // Read as the configuration: a pattern of the wrong length is refused as one.
    let err = run_err(
        d,
        &argv(
            "compensate --robot ge-a4 --nominal ge-a4 --in targets.csv --position-only
             --configuration -,- --out c.csv",
        ),
    );
    assert!(
        err.contains("--configuration: 2 signs for a robot of 4 joints"),
        "{err}"
    );
    // Joint 1 of this solution is positive (its value, not its reading): `+,*,*,*` holds,
    // `-,*,*,*` flags the row (exit 3), so the pattern was read, sign by sign.
    run_ok(
        d,
        &argv(
            "compensate --robot ge-a4 --nominal ge-a4 --in targets.csv --position-only
             --configuration +,*,*,* --out c.csv",
        ),
    );
    let (code, _, err) = run(
        d,
        &argv(
            "compensate --robot ge-a4 --nominal ge-a4 --in targets.csv --position-only
             --configuration -,*,*,* --out c.csv",
        ),
    );
    assert_eq!(code, 3, "{err}");
    let table = std::fs::read_to_string(d.join("c.csv")).unwrap();
    assert!(table.contains("not in the configuration"), "{table}");
}

#[test]
fn a_validation_flag_does_not_silently_drop_the_spec_s_own() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    run_ok(
        d,
        &argv("simulate --robot ge-a4 --postures 20 --seed 2 --out data.csv"),
    );
    run_ok(
        d,
        &argv("simulate --robot ge-a4 --postures 5 --seed 3 --out other.csv"),
    );
    std::fs::write(
        d.join("job.toml"),
        "job = \"calibrate\"\nrobot = \"ge-a4\"\n[[observations]]\nfile = \"data.csv\"\n\
         [validation]\nholdout = 0.2\n",
    )
    .unwrap();
    // Held-out files over a spec that holds out postures: two ways to check, refused.
    for extra in ["--validate other.csv", "--folds 3"] {
        let err = run_err(d, &argv(&format!("calibrate --spec job.toml {extra} -q")));
        assert!(
            err.contains("three ways to check a calibration: give one"),
            "{extra}: {err}"
        );
    }
    // The same key given by a flag overrides the spec's.
    let spec = run_ok(
        d,
        &argv("calibrate --spec job.toml --holdout 0.3 --write-spec -"),
    );
    assert!(spec.contains("holdout = 0.3"), "{spec}");
}

#[test]
fn a_robot_written_to_standard_output_is_all_that_goes_there() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    run_ok(
        d,
        &argv("simulate --robot ge-a4 --postures 20 --seed 2 --perturb p1=+0.05 --out data.csv"),
    );
    let (code, out, err) = run(
        d,
        &argv("calibrate --robot ge-a4 --data data.csv --out - -q"),
    );
    assert_eq!(code, 0, "{err}");
    // Standard output is the robot file: it reads back as one, and the summary is on stderr.
    std::fs::write(d.join("cal.toml"), &out).unwrap();
    run_ok(
        d,
        &argv("fk --robot cal.toml --postures data.csv --out poses.csv"),
    );
    assert!(!out.contains("verdict"), "{out}");
    assert!(err.contains("verdict: Converged"), "{err}");
    // Without `-`, the summary is the standard output, as before.
    let (_, out, _) = run(
        d,
        &argv("calibrate --robot ge-a4 --data data.csv --out c.toml -q"),
    );
    assert!(out.contains("verdict: Converged"), "{out}");
}

#[test]
fn a_standard_deviation_finer_than_any_instrument_is_refused_naming_weights() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    run_ok(
        d,
        &argv("simulate --robot ge-a4 --postures 12 --seed 2 --out data.csv"),
    );
    for args in [
        "calibrate --robot ge-a4 --data data.csv --weights length=1e-300",
        "analyze --robot ge-a4 --data data.csv --weights angle=1e-20",
    ] {
        let err = run_err(d, &argv(args));
        assert!(
            err.contains("--weights: a standard deviation of")
                && err.contains("finer than any instrument resolves"),
            "{args}: {err}"
        );
    }
    // A nanometre (in inches) is fine.
    run_ok(
        d,
        &argv("calibrate --robot ge-a4 --data data.csv --weights length=4e-8 -q"),
    );
}

/// Mix-ups are named with what to do (issue 38): a URDF given as the robot, a robot file given
/// as data, joint columns named `j1..jn`, and Excel's `sep=;` line; each used to get a correct
/// but undiagnostic error ("invalid TOML: key with no value", "no column `v1` in the header").
#[test]
fn mix_ups_are_named_with_what_to_do() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    run_ok(
        d,
        &argv("simulate --robot ge-a4 --postures 5 --seed 1 --out data.csv"),
    );
    let data = std::fs::read_to_string(d.join("data.csv")).unwrap();
    let urdf = "<?xml version=\"1.0\"?>\n<robot name=\"arm\">\n  <link name=\"base\"/>\n</robot>\n";
    std::fs::write(d.join("arm.urdf"), urdf).unwrap();
    let err = run_err(d, &argv("calibrate --robot arm.urdf --data data.csv"));
    assert!(
        err.contains("arm.urdf: this is a URDF, not a kinecal robot file")
            && err.contains("kinecal import urdf arm.urdf --out robot.toml"),
        "{err}"
    );
    std::fs::copy(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/robots/ge_a4.toml"),
        d.join("ge.toml"),
    )
    .unwrap();
    let err = run_err(d, &argv("calibrate --robot ge-a4 --data ge.toml"));
    assert!(
        err.contains("looks like a robot file (TOML), not a data file: give it as --robot"),
        "{err}"
    );
    let renamed = data.replacen("v1,v2,v3,v4", "j1,j2,j3,j4", 1);
    std::fs::write(d.join("j.csv"), renamed).unwrap();
    let err = run_err(d, &argv("calibrate --robot ge-a4 --data j.csv"));
    assert!(err.contains("map them with --columns v1=j1"), "{err}");
    // And the mapping the hint gives reads it.
    run_ok(
        d,
        &argv("analyze --robot ge-a4 --data j.csv --columns v1=j1,v2=j2,v3=j3,v4=j4"),
    );
    let excel = format!("sep=;\n{}", data.replace(',', ";"));
    std::fs::write(d.join("excel.csv"), excel).unwrap();
    let err = run_err(d, &argv("calibrate --robot ge-a4 --data excel.csv"));
    assert!(err.contains("Excel's `sep=` line"), "{err}");
}
