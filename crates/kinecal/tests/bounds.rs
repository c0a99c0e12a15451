//! The bounds of the numbers and texts a user gives (`kinecal::spec::limits`): every front end
//! meets them at the library's door, and every value the door accepts is one a spec file holds
//! and reads back (issue 38, item 2).

use kinecal::spec::{limits, CalibrationSpec, Env, HistoryEventSpec, Job, SimulateSpec};
use kinecal::{Error, Setting};

fn refused(r: kinecal::Result<impl std::fmt::Debug>) -> (Setting, String) {
    match r {
        Err(Error::InvalidOption { setting, message }) => (setting, message),
        other => panic!("expected a refused setting, got {other:?}"),
    }
}

#[test]
fn a_seed_beyond_a_spec_file_is_refused_before_it_is_written_and_the_largest_reads_back() {
    let mut spec = SimulateSpec::default();
    spec.robot = "ge-a4".into();
    spec.postures = 3;
    spec.seed = Some(limits::MAX_SEED + 1);
    let job = Job::Simulate(spec.clone());
    // It panicked: TOML's integers are i64.
    let (setting, message) = refused(job.to_toml());
    assert_eq!(setting, Setting::Seed);
    assert_eq!(
        message,
        "expected a seed between 0 and 9223372036854775807 (the largest integer a spec file \
         holds), not 9223372036854775808"
    );
    let mut quiet = ();
    let (setting, _) = refused(kinecal::spec::run(&job, &mut Env::new(&mut quiet, None)));
    assert_eq!(setting, Setting::Seed);
    spec.seed = Some(limits::MAX_SEED);
    let job = Job::Simulate(spec);
    let text = job.to_toml().unwrap();
    assert_eq!(Job::from_toml(&text, "job.toml").unwrap(), job, "{text}");
    assert_eq!(Job::from_json(&job.to_json(), "job.json").unwrap(), job);
}

#[test]
fn iteration_caps_and_repeats_are_bounded_for_every_front_end() {
    // Python's keywords arrive as a spec's JSON value.
    let e = kinecal::spec::spec_from_value::<CalibrationSpec>(
        serde_json::json!({"robot": "ge-a4", "validation": {"choose": [], "repeats": 1_000_000_000u64}}),
        "keywords",
    );
    assert_eq!(
        refused(e),
        (
            Setting::Repeats,
            "expected between 1 and 100 repeats, not 1000000000".to_string()
        )
    );
    let e = kinecal::spec::spec_from_value::<CalibrationSpec>(
        serde_json::json!({"robot": "ge-a4", "solver": {"max_iterations": 1u64 << 63}}),
        "keywords",
    );
    assert_eq!(
        refused(e),
        (
            Setting::MaxIterations,
            "expected between 1 and 1000000 iterations, not 9223372036854775808".to_string()
        )
    );
    // The largest accepted cap is written and read back.
    let mut spec = CalibrationSpec::default();
    spec.robot = "ge-a4".into();
    spec.solver.max_iterations = Some(limits::MAX_ITERATIONS);
    let job = Job::Calibrate(spec);
    assert_eq!(
        Job::from_toml(&job.to_toml().unwrap(), "job.toml").unwrap(),
        job
    );
}

#[test]
fn a_serial_or_note_a_history_would_draw_is_bounded_at_the_door() {
    let mut spec = HistoryEventSpec::default();
    spec.db = Some("never-opened.sqlite".into());
    spec.robot_id = "S".repeat(65_536);
    spec.note = "serviced".into();
    let mut quiet = ();
    // Refused before any history is asked for (none is given here).
    let e = kinecal::spec::run(
        &Job::HistoryEvent(spec.clone()),
        &mut Env::new(&mut quiet, None),
    );
    assert_eq!(
        refused(e),
        (
            Setting::RobotId,
            "expected a serial of at most 128 characters, not 65536".to_string()
        )
    );
    spec.robot_id = "A1".into();
    spec.note = "n".repeat(limits::MAX_NOTE_CHARS + 1);
    let e = kinecal::spec::run(&Job::HistoryEvent(spec), &mut Env::new(&mut quiet, None));
    assert_eq!(refused(e).0, Setting::Note);
    assert!(!std::path::Path::new("never-opened.sqlite").exists());
}
