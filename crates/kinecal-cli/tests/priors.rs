//! `kinecal calibrate --prior`: every parameter of a 6R from 10 postures, on the command line.

use std::path::Path;

mod common;

use common::{argv, kinecal, run_err, run_ok};

fn report(dir: &Path, name: &str) -> serde_json::Value {
    common::read_json(&dir.join(name))
}

fn held_out_rms(r: &serde_json::Value) -> f64 {
    r["validation"]["after"]["rms_position"].as_f64().unwrap()
}

/// A calibration of the 6R that the flags added to it make fail.
const BAD: [&str; 5] = ["calibrate", "--robot", "r6.toml", "--data", "data.csv"];

const PRIOR: &str = "length=0.001,angle=0.001,slope=0.001";

/// A random 6R (metres, radians), a true robot 1 mm / 1 mrad off it, 10 postures of poses with
/// 0.1 mm / 0.1 mrad of noise, and 200 fresh postures of the truth.
fn six_r(dir: &Path, seed: u64) {
    let robot = kinecal::apps::simulate::random_robot(&[kinecal::JointKind::Revolute; 6], seed);
    std::fs::write(
        dir.join("r6.toml"),
        kinecal::model::robot_file::write_robot_toml(&robot, None),
    )
    .unwrap();
    let seed = seed.to_string();
    let noise = "length=0.0001,angle=0.0001";
    run_ok(
        dir,
        &argv(&format!(
            "simulate --robot r6.toml --postures 10 --seed {seed} --perturb-std {PRIOR}
             --noise {noise} --out data.csv --truth truth.toml"
        )),
    );
    let fresh = argv("simulate --robot truth.toml --postures 200 --seed 99 --out fresh.csv");
    run_ok(dir, &fresh);
}

/// The done-when on the command line, on 12 random 6Rs: `--estimate all` with a prior of the
/// perturbation's size exits 0, says what the prior determined, and predicts the held-out
/// postures at least as well as the identifiable-only fit on average, no robot more than 5 %
/// worse: the two determine the same 36 combinations from the data, and the prior only shrinks
/// them towards the drawing, which helps or costs a few per cent per draw (measured: mean
/// 2.157e-4 m identifiable, 2.147e-4 m with the prior; per robot from 6.3 % better to 3.9 %
/// worse).
#[test]
fn every_parameter_of_a_6r_from_10_postures_with_a_prior() {
    let (mut sum_a, mut sum_b) = (0.0, 0.0);
    for seed in 1..=12 {
        let (ea, eb) = compare(seed);
        println!(
            "seed {seed}: held-out RMS position identifiable {ea:.4e} m, all with the prior \
             {eb:.4e} m"
        );
        assert!(eb <= 1.05 * ea, "seed {seed}: {eb} vs {ea}");
        sum_a += ea;
        sum_b += eb;
    }
    println!(
        "mean: identifiable {:.4e} m, with the prior {:.4e} m",
        sum_a / 12.0,
        sum_b / 12.0
    );
    assert!(sum_b <= sum_a, "{sum_b} vs {sum_a}");
}

/// The held-out RMS position errors of the identifiable-only fit and of `--estimate all
/// --prior` on the 6R of `seed`; on the first, what the output and the files say too.
fn compare(seed: u64) -> (f64, f64) {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    six_r(dir, seed);
    let common = argv(
        "calibrate --robot r6.toml --data data.csv --weights length=0.0001,angle=0.0001
         --validate fresh.csv",
    );
    let mut a = common.to_vec();
    a.extend(["--estimate", "identifiable", "--report", "a.json"]);
    run_ok(dir, &a);
    let mut b = common.to_vec();
    b.extend([
        "--estimate",
        "all",
        "--prior",
        PRIOR,
        "--report",
        "b.json",
        "--write-spec",
        "job.toml",
    ]);
    let out = run_ok(dir, &b);
    let (ra, rb) = (report(dir, "a.json"), report(dir, "b.json"));
    assert_eq!(rb["converged"], true);
    let (ea, eb) = (held_out_rms(&ra), held_out_rms(&rb));
    if seed > 1 {
        return (ea, eb);
    }
    assert!(
        out.contains(&format!("prior {PRIOR} on 54 parameters: objective ")),
        "{out}"
    );
    assert!(out.contains("; rank 36 on the data alone"), "{out}");
    assert!(
        out.contains("determined by the data only in combinations the prior splits ("),
        "{out}"
    );
    assert!(out.contains("rank 54 of 54 estimated parameters"), "{out}");
    assert_eq!(rb["prior"]["rows"], 54);
    assert_eq!(rb["prior"]["data_rank"], 36);
    assert!(rb["undetermined"].as_array().unwrap().is_empty());
    // The HTML report shows the prior: its rows, and per parameter what determines it.
    run_ok(dir, &["report", "--from", "b.json", "--out", "b.html"]);
    let html = std::fs::read_to_string(dir.join("b.html")).unwrap();
    assert!(
        html.contains("<h2 id=\"prior\">Prior</h2>"),
        "no prior section"
    );
    assert!(
        html.contains(&format!("<code>{PRIOR}</code>: 54 rows")),
        "prior line"
    );
    assert!(
        html.contains("Rank 54 (36 on the data alone) of 54"),
        "ranks"
    );
    let rows = html.matches("<td class=\"l\">data and prior</td>").count()
        + html.matches("<td class=\"l\">data</td>").count()
        + html.matches("<td class=\"l\">prior</td>").count();
    assert_eq!(rows, 54, "one row per parameter with a prior");
    // The spec written holds the prior.
    let spec = std::fs::read_to_string(dir.join("job.toml")).unwrap();
    assert!(spec.contains(&format!("prior = \"{PRIOR}\"")), "{spec}");
    // Without the prior, Gauss-Newton refuses the rank-deficient system; with it, it solves.
    let mut gn = common.to_vec();
    gn.extend(["--estimate", "all", "--method", "gn"]);
    let refused = kinecal().current_dir(dir).args(&gn).output().unwrap();
    assert_ne!(refused.status.code(), Some(0));
    gn.extend(["--prior", PRIOR]);
    run_ok(dir, &gn);
    (ea, eb)
}

/// `--choose` compares prior strengths by cross-validation; bad priors are refused naming the
/// flag and the key.
#[test]
fn choose_compares_prior_strengths_and_bad_priors_are_named() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    six_r(dir, 3);
    let out = run_ok(
        dir,
        &[
            "calibrate",
            "--robot",
            "r6.toml",
            "--data",
            "data.csv",
            "--weights",
            "length=0.0001,angle=0.0001",
            "--folds",
            "5",
            "--repeats",
            "1",
            "--report",
            "c.json",
            "--choose",
            "all prior=length=0.00001,angle=0.00001,slope=0.00001",
            "all prior=length=0.001,angle=0.001,slope=0.001",
            "all prior=length=0.1,angle=0.1,slope=0.1",
        ],
    );
    let r = report(dir, "c.json");
    let choice = r["model_choice"].as_array().unwrap();
    assert_eq!(choice.len(), 3, "{out}");
    let means: Vec<f64> = choice.iter().map(|c| c["mean"].as_f64().unwrap()).collect();
    // Holding every parameter 100 times tighter than the changes are cannot fit them.
    assert!(means[0] > means[1], "{means:?}");
    assert!(r["prior"].is_object());
    for (prior, words) in [
        (
            "length=-0.1",
            "--prior: `length`: a prior's standard deviation must be positive",
        ),
        ("length=0", "--prior: `length`"),
        ("lenght=0.1", "--prior: `lenght`"),
        ("angle=nan", "--prior: `angle`"),
    ] {
        let err = run_err(dir, &[&BAD[..], &["--prior", prior]].concat());
        assert!(err.contains(words), "{prior}: {err}");
    }
    // A total mass needs a mass model, and a mass.
    for (total, words) in [
        ("28", "--total-mass: the robot has no bodies"),
        ("-3", "--total-mass: expected a mass in kg"),
    ] {
        let flag = format!("--total-mass={total}");
        let err = run_err(dir, &[&BAD[..], &[&flag[..]]].concat());
        assert!(err.contains(words), "{total}: {err}");
    }
    std::fs::write(
        dir.join("bad.toml"),
        std::fs::read_to_string(dir.join("r6.toml")).unwrap() + "\n[priors]\nangle = -1\n",
    )
    .unwrap();
    let out = kinecal()
        .current_dir(dir)
        .args(["calibrate", "--robot", "bad.toml", "--data", "data.csv"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("priors.angle"), "{err}");
}

#[test]
fn analyze_with_a_prior_says_what_the_prior_alone_determines() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    six_r(dir, 5);
    let base = argv("analyze --robot r6.toml --data data.csv --estimate all");
    let without = run_ok(dir, &base);
    assert!(without.contains("Numerical rank 36 of 54"), "{without}");
    assert!(!without.contains("With the prior"));
    let mut args = base.to_vec();
    args.extend(["--prior", PRIOR]);
    let with = run_ok(dir, &args);
    assert!(with.contains("Numerical rank 54 of 54"), "{with}");
    assert!(with.contains("With the prior: 54 of its rows"), "{with}");
    // Individually, the data determines only the slopes and two tool angles here: every other
    // parameter is in a combination the data cannot split.
    assert!(
        with.contains("Determined only with the prior (46): ") && with.contains("joint1.offset"),
        "{with}"
    );
    assert!(with.contains("It counts what the data alone determines"));
    let out = kinecal()
        .current_dir(dir)
        .args(base)
        .arg("--total-mass=10")
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--total-mass: the robot has no bodies"));
}
