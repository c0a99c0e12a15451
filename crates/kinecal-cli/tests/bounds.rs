//! Every number and text a user gives has a bound, refused before any work with the limit named
//! (`--repeats: expected between 1 and 100 repeats, not 1000000000`), and every value a command
//! accepts is one its spec file holds and reads back (issue 38, item 2).

use std::path::Path;

mod common;

use common::{argv, run, run_err, run_ok};

/// Simulated measurements of the built-in GE A4 in `d`: `m.csv`.
fn data(d: &Path) {
    run_ok(
        d,
        &argv("simulate --robot ge-a4 --postures 20 --seed 3 --noise length=0.0005 --out m.csv"),
    );
}

#[test]
fn seeds_and_iteration_caps_beyond_a_spec_file_are_refused_and_the_rest_read_back() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    data(d);
    // 2^63: more than a spec file (TOML) holds. Refused, naming the flag and the limit (it
    // panicked in --write-spec).
    let e = run_err(
        d,
        &argv("calibrate --robot ge-a4 --data m.csv --seed 9223372036854775808 --write-spec -"),
    );
    assert!(
        e.contains(
            "--seed: expected a seed between 0 and 9223372036854775807 (the largest integer a \
             spec file holds), not 9223372036854775808"
        ),
        "{e}"
    );
    let e = run_err(
        d,
        &argv("calibrate --robot ge-a4 --data m.csv --max-iter 9223372036854775808 --write-spec -"),
    );
    assert!(
        e.contains(
            "--max-iter: expected between 1 and 1000000 iterations, not 9223372036854775808"
        ),
        "{e}"
    );
    // Refused when run too, not only when written.
    let e = run_err(
        d,
        &argv("simulate --robot ge-a4 --postures 3 --seed 18446744073709551615 --out s.csv"),
    );
    assert!(e.contains("--seed: expected a seed between 0 and"), "{e}");
    assert!(!d.join("s.csv").exists());
    // The largest seed is written and read back as itself: the same data, byte for byte.
    run_ok(
        d,
        &argv(
            "simulate --robot ge-a4 --postures 5 --seed 9223372036854775807 --noise length=0.01
             --out a.csv --write-spec s.toml",
        ),
    );
    let spec = std::fs::read_to_string(d.join("s.toml")).unwrap();
    assert!(spec.contains("seed = 9223372036854775807"), "{spec}");
    run_ok(d, &argv("simulate --spec s.toml --out b.csv"));
    assert_eq!(
        std::fs::read(d.join("a.csv")).unwrap(),
        std::fs::read(d.join("b.csv")).unwrap()
    );
    // So is the largest iteration cap.
    let out = run_ok(
        d,
        &argv("calibrate --robot ge-a4 --data m.csv --max-iter 1000000 --write-spec -"),
    );
    assert!(out.contains("max_iterations = 1000000"), "{out}");
    // A spec file's key is named as the file's key.
    std::fs::write(
        d.join("job.toml"),
        "robot = \"ge-a4\"\n[[observations]]\nfile = \"m.csv\"\n[solver]\nmax_iterations = 2000000\n",
    )
    .unwrap();
    let e = run_err(d, &argv("calibrate --spec job.toml"));
    assert!(
        e.contains(
            "job.toml: max_iterations: expected between 1 and 1000000 iterations, not 2000000"
        ),
        "{e}"
    );
}

#[test]
fn a_model_choice_repeats_its_cross_validation_at_most_100_times() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    data(d);
    // It ran away (a billion rounds of fits); now refused before the first fit.
    let started = std::time::Instant::now();
    let e = run_err(
        d,
        &argv("calibrate --robot ge-a4 --data m.csv --choose --repeats 1000000000 --out r.toml"),
    );
    assert!(
        e.contains("--repeats: expected between 1 and 100 repeats, not 1000000000"),
        "{e}"
    );
    assert!(started.elapsed().as_secs() < 30);
    assert!(!d.join("r.toml").exists());
    // The same limit through a batch row (the row's options are a calibration spec).
    std::fs::write(
        d.join("fleet.csv"),
        "serial,robot,data,options\nA1,ge-a4,m.csv,--choose --repeats 101\n",
    )
    .unwrap();
    let (_, out, err) = run(d, &argv("batch fleet.csv --quiet"));
    assert!(
        (out.clone() + &err).contains("expected between 1 and 100 repeats, not 101"),
        "{out}{err}"
    );
}

#[test]
fn counts_of_postures_samples_and_cycles_are_refused_beyond_their_limits() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let e = run_err(
        d,
        &argv("plan --robot ge-a4 --sample 100000000000 --count 5 --out p.csv"),
    );
    assert!(
        e.contains("--sample: expected between 1 and 1000000 sampled postures, not 100000000000"),
        "{e}"
    );
    let e = run_err(
        d,
        &argv("simulate --robot ge-a4 --postures 1000000000000 --out s.csv"),
    );
    assert!(
        e.contains("--postures: expected between 1 and 10000000 postures, not 1000000000000"),
        "{e}"
    );
    // A robot measured at three frames (its end effector and two sites): a third of the
    // postures, as each makes three measurements held in memory.
    let markers =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/layouts/a4_markers.toml");
    let mut args = argv("simulate --postures 5000000 --out s.csv --robot");
    args.push(markers.to_str().unwrap());
    let e = run_err(d, &args);
    assert!(
        e.contains(
            "--postures: expected at most 10000000 measurements (3 frames measured at each \
             posture: at most 3333333 postures), not 15000000"
        ),
        "{e}"
    );
    run_ok(d, &argv("iso9283 plan --robot ge-a4 --out poses.csv"));
    let e = run_err(
        d,
        &argv(
            "iso9283 simulate --robot ge-a4 --poses poses.csv --cycles 1000000000000 --out l.csv",
        ),
    );
    assert!(e.contains("--cycles: expected between 1 and 100000"), "{e}");
    let e = run_err(
        d,
        &argv("iso9283 plan --robot ge-a4 --resolution 5000 --out p2.csv"),
    );
    assert!(e.contains("--resolution: expected 3 to 200"), "{e}");
}

#[test]
fn batch_jobs_beyond_two_per_core_run_two_per_core_with_a_note() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    data(d);
    std::fs::write(d.join("fleet.csv"), "serial,robot,data\nA1,ge-a4,m.csv\n").unwrap();
    let (code, out, err) = run(d, &argv("batch fleet.csv --jobs 100000 --quiet"));
    assert_eq!(code, 0, "{out}{err}");
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    assert!(
        err.contains(&format!(
            "--jobs 100000: running {} at once (2 per core of this machine's {cores})",
            2 * cores
        )),
        "{err}"
    );
    // Within the bound: no note.
    let (code, out, err) = run(d, &argv("batch fleet.csv --jobs 2 --quiet"));
    assert_eq!(code, 0, "{out}{err}");
    assert!(!err.contains("--jobs"), "{err}");
}

#[test]
fn a_serial_longer_than_128_characters_is_refused_and_a_stored_one_is_drawn() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    data(d);
    let long = "S".repeat(65_536);
    // A batch manifest's serial (it panicked drawing the summary table).
    std::fs::write(
        d.join("fleet.csv"),
        format!("serial,robot,data\n{long},ge-a4,m.csv\n"),
    )
    .unwrap();
    let e = run_err(d, &argv("batch fleet.csv --quiet --record --db h.sqlite"));
    assert!(
        e.contains("fleet.csv:2: serial: expected a serial of at most 128 characters, not 65536"),
        "{e}"
    );
    std::fs::write(
        d.join("fleet.toml"),
        format!("[[robots]]\nserial = \"{long}\"\nrobot = \"ge-a4\"\n[[robots.observations]]\nfile = \"m.csv\"\n"),
    )
    .unwrap();
    let e = run_err(d, &argv("batch fleet.toml --quiet"));
    assert!(
        e.contains("robot 1: serial: expected a serial of at most 128 characters, not 65536"),
        "{e}"
    );
    // calibrate --record, history add and event: refused before anything is computed.
    let mut args =
        argv("calibrate --robot ge-a4 --data m.csv --report r.json --db h.sqlite --record");
    args.push(&long);
    let e = run_err(d, &args);
    assert!(
        e.contains("--record: expected a serial of at most 128 characters, not 65536"),
        "{e}"
    );
    assert!(!d.join("r.json").exists());
    run_ok(
        d,
        &argv("calibrate --robot ge-a4 --data m.csv --report r.json --record A1 --db h.sqlite"),
    );
    let serial = "S".repeat(129);
    let mut args = argv("history event --db h.sqlite --note serviced");
    args.push(&serial);
    let e = run_err(d, &args);
    assert!(
        e.contains("expected a serial of at most 128 characters, not 129"),
        "{e}"
    );
    let note = "n".repeat(1001);
    let mut args = argv("history event A1 --db h.sqlite --note");
    args.push(&note);
    let e = run_err(d, &args);
    assert!(
        e.contains("--note: expected a note of at most 1000 characters, not 1001"),
        "{e}"
    );
    // A history written before the bound may hold a long serial (written here into the file
    // itself): its fleet is drawn, the serial whole. A dump holding it is refused, as
    // `history add` would refuse the serial.
    std::fs::copy(d.join("h.sqlite"), d.join("old.sqlite")).unwrap();
    let long = "S".repeat(70_000);
    let db = rusqlite::Connection::open(d.join("old.sqlite")).unwrap();
    db.execute(
        "UPDATE calibrations SET robot_id = ?1 WHERE robot_id = 'A1'",
        [&long],
    )
    .unwrap();
    drop(db);
    let out = run_ok(d, &argv("history fleet --db old.sqlite"));
    assert!(out.contains(&long), "the serial drawn whole");
    run_ok(
        d,
        &argv("history export --format dump --db old.sqlite --out dump.json"),
    );
    let e = run_err(d, &argv("history import dump.json --db new.sqlite"));
    assert!(
        e.contains("expected a serial of at most 128 characters, not 70000"),
        "{e}"
    );
    assert!(!d.join("new.sqlite").exists());
}

/// A simulation's noise is bounded by what an instrument could have: at most the robot's reach,
/// half a turn, the larger side of the robot file's largest image. Beyond, refused with the
/// bound and no file written (a noise of 1e300 wrote coordinates the readers refuse); at the
/// bound, the file written reads back.
#[test]
fn simulated_noise_beyond_any_instrument_is_refused_and_at_the_bound_reads_back() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let examples = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples");
    let cameras = examples.join("cameras");
    let robot = cameras.join("eye_in_hand_truth.toml");
    let robot = robot.to_str().unwrap();
    // The GE A4's file is in inches and degrees.
    for (noise, message) in [
        (
            "length=1e300",
            "--noise: the length noise 1e300 in is more than any instrument's: at most \
             52.454418 in (the robot's reach)",
        ),
        (
            "angle=200",
            "--noise: the angle noise 200 deg is more than any instrument's: at most 180 deg \
             (half a turn)",
        ),
    ] {
        let e = run_err(
            d,
            &argv(&format!(
                "simulate --robot ge-a4 --postures 5 --noise {noise} --out m.csv"
            )),
        );
        assert!(e.contains(message), "{e}");
        assert!(!d.join("m.csv").exists());
    }
    let e = run_err(
        d,
        &argv(&format!(
            "simulate --robot {robot} --camera wrist --board board --postures 3 --seed 1 \
             --noise pixel=641 --out px.csv"
        )),
    );
    assert!(
        e.contains(
            "the pixel noise 641 px is more than any instrument's: at most 640 px (the larger \
             side of the robot file's largest image)"
        ),
        "{e}"
    );
    assert!(!d.join("px.csv").exists());
    // The ISO 9283 log's simulation too.
    run_ok(d, &argv("iso9283 plan --robot ge-a4 --out poses.csv"));
    let e = run_err(
        d,
        &argv("iso9283 simulate --robot ge-a4 --poses poses.csv --cycles 2 --noise length=1e300 --out log.csv"),
    );
    assert!(e.contains("the length noise 1e300 in is more than"), "{e}");
    assert!(!d.join("log.csv").exists());
    // At the bounds: written, and read back (the fits may go where they like; the readers
    // take every row).
    run_ok(
        d,
        &argv("simulate --robot ge-a4 --postures 20 --seed 2 --noise length=52.45,angle=180 --out m.csv"),
    );
    let (_, out, err) = run(
        d,
        &argv("calibrate --robot ge-a4 --data m.csv --out fit.toml"),
    );
    assert!(!err.contains("m.csv:"), "{out}{err}");
    run_ok(
        d,
        &argv(&format!(
            "simulate --robot {robot} --camera wrist --board board --postures 3 --seed 1 \
             --noise pixel=640 --out px.csv"
        )),
    );
    let model = cameras.join("eye_in_hand.toml");
    let (_, out, err) = run(
        d,
        &argv(&format!(
            "calibrate --robot {} --pixels px.csv --out cam.toml",
            model.to_str().unwrap()
        )),
    );
    assert!(!err.contains("px.csv:"), "{out}{err}");
    run_ok(
        d,
        &argv("iso9283 simulate --robot ge-a4 --poses poses.csv --cycles 2 --noise length=52.45 --out log.csv"),
    );
    run_ok(d, &argv("iso9283 evaluate --data log.csv"));
}
