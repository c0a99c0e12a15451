//! Bad values in a spec file are refused in the spec's own terms (issue 38, scope item 4): the
//! error names the spec file and the key, never a command-line flag the user did not type; the
//! same value given by its flag is named by the flag. A mistyped group word in a parameter list
//! gets a "did you mean".

mod common;

use common::run;

/// The measurements every case reads (a GE A4 at 30 poses).
fn data(dir: &std::path::Path) {
    let (code, _, e) = run(
        dir,
        &common::argv("simulate --robot ge-a4 --postures 30 --seed 7 --out data.csv"),
    );
    assert_eq!(code, 0, "{e}");
}

#[test]
fn every_bad_spec_value_names_the_file_and_the_key_not_a_flag() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    data(d);
    let calibrate = "job = \"calibrate\"\nrobot = \"ge-a4\"\n";
    let observations = "[[observations]]\nfile = \"data.csv\"\n";
    let analyze = "job = \"analyze\"\nrobot = \"ge-a4\"\n";
    let simulate = "job = \"simulate\"\nrobot = \"ge-a4\"\nout = \"s.csv\"\n";
    // (job, spec text, the key the error must name, the words it must say)
    let cases: Vec<(&str, String, &str, &str)> = vec![
        (
            "calibrate",
            format!("{calibrate}{observations}[validation]\nholdout = 2.0\n"),
            "holdout",
            "expected a fraction between 0 and 1",
        ),
        (
            "calibrate",
            format!("{calibrate}{observations}[validation]\nfolds = 1\n"),
            "folds",
            "expected between 2",
        ),
        (
            "calibrate",
            format!("{calibrate}{observations}[selection]\nprune = -3.0\n"),
            "prune",
            "positive number of standard deviations",
        ),
        (
            "calibrate",
            format!("{calibrate}{observations}[selection]\nestimate = \"idntifiable\"\n"),
            "estimate",
            "unknown parameter `idntifiable`: did you mean `identifiable`?",
        ),
        (
            "calibrate",
            format!("{calibrate}{observations}[selection]\nfix = \"p99\"\n"),
            "fix",
            "`p99` is out of range",
        ),
        (
            "calibrate",
            format!("{calibrate}{observations}[selection]\ntotal_mass = 3.0\n"),
            "total_mass",
            "the robot has no bodies",
        ),
        (
            "calibrate",
            format!("{calibrate}{observations}[solver]\nmax_iterations = 0\n"),
            "max_iterations",
            "expected between 1 and 1000000 iterations",
        ),
        (
            "calibrate",
            format!("{calibrate}{observations}[residuals]\nhuber_scale = -1.0\n"),
            "huber_scale",
            "expected a positive number of spreads",
        ),
        (
            "calibrate",
            format!("{calibrate}{observations}[residuals]\nweights = {{ length = -1.0 }}\n"),
            "weights",
            "must be positive and finite",
        ),
        (
            "calibrate",
            format!("{calibrate}{observations}[read]\nlength_unit = \"furlong\"\n"),
            "length_unit",
            "unknown length unit `furlong`",
        ),
        (
            "analyze",
            format!("{analyze}rcond = -1.0\n{observations}"),
            "rcond",
            "expected a tolerance between 0 and 1",
        ),
        (
            "analyze",
            format!("{analyze}{observations}[selection]\npriority = \"p99\"\n"),
            "priority",
            "`p99` is out of range",
        ),
        (
            "analyze",
            format!("{analyze}{observations}[selection]\nfix = \"lnks\"\n"),
            "fix",
            "did you mean `links`?",
        ),
        (
            "simulate",
            format!("{simulate}postures = 0\n"),
            "postures",
            "expected between 1 and 10000000 postures",
        ),
        (
            "simulate",
            format!("{simulate}postures = 100000000000\n"),
            "postures",
            "expected between 1 and 10000000 postures",
        ),
    ];
    for (job, text, key, words) in &cases {
        std::fs::write(d.join("job.toml"), text).unwrap();
        let (code, _, e) = run(d, &[job, "--spec", "job.toml"]);
        assert_eq!(code, 1, "{text}: {e}");
        assert!(
            e.contains(&format!("job.toml: {key}: ")) && e.contains(words),
            "{text}: {e}"
        );
        assert!(
            !e.contains("--"),
            "a flag named for a spec key: {text}: {e}"
        );
    }
    // Given by its flag, the same value is named by the flag.
    let (code, _, e) = run(
        d,
        &common::argv("calibrate --robot ge-a4 --data data.csv --estimate slops,offsets"),
    );
    assert_eq!(code, 1, "{e}");
    assert!(
        e.contains("--estimate: parameter list `slops,offsets`: unknown parameter `slops`: did you mean `slopes`?"),
        "{e}"
    );
}
