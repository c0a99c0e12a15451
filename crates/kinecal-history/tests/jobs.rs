//! The history jobs as every front end runs them (the command line's flags, a spec file and
//! Python's keywords all become these specs, run by `jobs::Historian`): what a refused write
//! leaves behind (nothing, not even a new file), what a read of an unknown robot says, what a
//! plot draws around maintenance events, and the bounds of a fleet's horizon.

mod common;

use std::path::Path;
use std::sync::Mutex;

use common::report::{ge_a4_report, LINK1_XY_LINK3_Y};
use kinecal::model::examples;
use kinecal::report::CalibrationReport;
use kinecal::spec::{Done, Env, Job, Message};
use kinecal_history::jobs::{Document, FleetView, Historian, Pages, PlotView};
use kinecal_history::Database;

const T0: i64 = 1_790_000_000;
const DAY: i64 = 86_400;

/// A calibration of the GE A4 (link 1's x and y, link 3's y) on simulated data.
fn report(seed: u64) -> CalibrationReport {
    let key = format!("seed {seed}");
    ge_a4_report(&examples::ge_a4(), 10, seed, &LINK1_XY_LINK3_Y, Some(&key))
}

/// What a plot was asked to draw: each series' key and calibration ids, the events' notes, the
/// x axis's origin.
type Drawn = (Vec<(String, Vec<i64>)>, Vec<String>, i64);

/// Draws nothing: keeps what a plot was asked to draw.
#[derive(Default)]
struct Recorder {
    drawn: Mutex<Option<Drawn>>,
}

impl Pages for Recorder {
    fn history_plot(&self, plot: &PlotView<'_>, _png: bool) -> Result<Vec<u8>, String> {
        let series = plot
            .series
            .iter()
            .map(|(q, s)| (q.key.clone(), s.iter().map(|s| s.id).collect()))
            .collect();
        let events = plot.events.iter().map(|e| e.note.clone()).collect();
        *self.drawn.lock().unwrap() = Some((series, events, plot.t0));
        Ok(b"<svg/>".to_vec())
    }

    fn fleet_page(&self, _fleet: &FleetView<'_>) -> Result<String, String> {
        Ok(String::new())
    }
}

/// Runs the job of `spec` (a spec's keys, `job` included) as a front end does.
fn run_with(pages: Option<&(dyn Pages + Sync)>, spec: serde_json::Value) -> kinecal::Result<Done> {
    let job = Job::from_value(spec, "test").unwrap();
    let historian = Historian::new(pages);
    let mut progress = ();
    let mut env = Env::new(&mut progress, None);
    env.historian = Some(&historian);
    kinecal::spec::run(&job, &mut env)
}

/// `history plot` of robot R1 of the history at `db` into `dir/r1.svg`: the job's outcome and
/// what it drew.
fn plot_r1(dir: &Path, db: &Path) -> (Done, Drawn) {
    let pages = Recorder::default();
    let out = dir.join("r1.svg");
    let done = run_with(
        Some(&pages),
        serde_json::json!({
            "job": "history-plot", "robot_id": "R1", "out": text(&out), "db": text(db),
        }),
    )
    .unwrap();
    assert!(out.exists());
    let drawn = pages.drawn.lock().unwrap().take().unwrap();
    (done, drawn)
}

fn run(spec: serde_json::Value) -> kinecal::Result<Done> {
    run_with(None, spec)
}

fn text(p: &Path) -> String {
    p.display().to_string()
}

/// The files in `dir`, by name.
fn files(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

fn cautions(done: &Done) -> Vec<String> {
    done.messages
        .iter()
        .filter_map(|m| match m {
            Message::Caution(c) => Some(c.clone()),
            _ => None,
        })
        .collect()
}

fn notes(done: &Done) -> Vec<String> {
    done.messages
        .iter()
        .filter_map(|m| match m {
            Message::Note(c) => Some(c.clone()),
            _ => None,
        })
        .collect()
}

/// `history add` of a report that says its calibration was REFUSED (a unit check fired, the
/// fit far above its noise) recorded it (exit 0, "recorded calibration 1"). Refused, naming
/// the report file and its refusal; nothing written, no history file created; an existing
/// history is left as it was.
#[test]
fn a_refused_calibration_report_is_not_recorded() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut rep = report(1);
    rep.refused = Some(
        "REFUSED: a unit check fired (the lengths look like millimetres) and the fit ends at \
         312.000 times its stated noise: no calibrated robot is written or recorded."
            .into(),
    );
    let refused = d.join("refused.json");
    std::fs::write(&refused, rep.to_json()).unwrap();
    let db = d.join("new").join("h.sqlite");
    let add = |db: &Path| {
        run(serde_json::json!({
            "job": "history-add", "robot_id": "RF", "report": text(&refused), "db": text(db),
        }))
    };
    let e = add(&db).unwrap_err().to_string();
    assert!(
        e.starts_with(&text(&refused))
            && e.contains("the report says the calibration was REFUSED (a unit check fired")
            && e.contains("a refused calibration is not recorded")
            && e.contains("nothing was written"),
        "{e}"
    );
    assert!(!db.exists() && !d.join("new").exists(), "{:?}", files(d));
    // Into an existing history: nothing written either.
    let existing = d.join("h.sqlite");
    Database::open(&existing)
        .unwrap()
        .add("RF", Some(T0), &report(2), "")
        .unwrap();
    add(&existing).unwrap_err();
    let db = Database::open_read_only(&existing).unwrap();
    assert_eq!(db.calibrations(None).unwrap().len(), 1);
    // The library refuses it too (`calibrate --record`, `batch --record`).
    let e = Database::open(&existing)
        .unwrap()
        .add("RF", Some(T0 + DAY), &rep, "")
        .unwrap_err()
        .to_string();
    assert!(e.contains("REFUSED") && e.contains("not recorded"), "{e}");
}

/// A refused `history import` created a 40 KB history while saying nothing was imported: a
/// history that was not there before is not there after (its folder neither); a refused
/// write into one that was is refused as before.
#[test]
fn a_refused_import_creates_no_history() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let source = d.join("source.sqlite");
    {
        let db = Database::open(&source).unwrap();
        db.add("R1", Some(T0), &report(1), "").unwrap();
        db.add("R1", Some(T0 + 30 * DAY), &report(2), "").unwrap();
    }
    let mut v: serde_json::Value =
        serde_json::from_str(&Database::open(&source).unwrap().dump().unwrap().to_json()).unwrap();
    v["calibrations"][1]["parameters"][0]["sigma"] = serde_json::json!(-1.0);
    let bad = d.join("bad.json");
    std::fs::write(&bad, v.to_string()).unwrap();
    let before = files(d);
    for db in [d.join("h.sqlite"), d.join("a").join("b").join("h.sqlite")] {
        let e = run(serde_json::json!({
            "job": "history-import", "dump": text(&bad), "db": text(&db),
        }))
        .unwrap_err()
        .to_string();
        assert!(
            e.starts_with(&text(&bad))
                && e.contains("calibration 2 of the dump")
                && e.contains("has the sigma -1")
                && e.contains("nothing was imported"),
            "{e}"
        );
        assert_eq!(files(d), before, "{}", db.display());
    }
    // A refused `history add` into a new file leaves no file either.
    let report_file = d.join("r.json");
    std::fs::write(&report_file, report(3).to_json()).unwrap();
    let e = run(serde_json::json!({
        "job": "history-add", "robot_id": " R1", "report": text(&report_file),
        "db": text(&d.join("h.sqlite")),
    }))
    .unwrap_err()
    .to_string();
    assert!(e.contains("has white space at its start or end"), "{e}");
    let mut expected = [before, vec!["r.json".into()]].concat();
    expected.sort();
    assert_eq!(files(d), expected);
}

/// `history export --robot-id NOPE` printed a header-only CSV (`[]` in JSON) and exited 0,
/// where `list`, `show`, `drift` and `plot` say that nothing is recorded for the robot.
#[test]
fn export_of_an_unknown_robot_says_nothing_is_recorded() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("h.sqlite");
    Database::open(&db)
        .unwrap()
        .add("R1", Some(T0), &report(1), "")
        .unwrap();
    for job in ["history-list", "history-export"] {
        for format in ["csv", "json"] {
            let mut spec = serde_json::json!({"job": job, "robot_id": "NOPE", "db": text(&db)});
            if job == "history-export" {
                spec["format"] = serde_json::json!(format);
            }
            let e = run(spec).unwrap_err().to_string();
            assert!(
                e.contains("no calibration recorded for robot `NOPE`"),
                "{job} {format}: {e}"
            );
        }
    }
    // A known robot, and the whole history, export as before.
    let done = run(serde_json::json!({
        "job": "history-export", "robot_id": "R1", "db": text(&db), "format": "json",
    }))
    .unwrap();
    let Some(Document::Export(e)) = Document::of(&done.document) else {
        panic!("not an export");
    };
    assert!(e.text.as_deref().unwrap().contains("\"robot_id\": \"R1\""));
    run(serde_json::json!({"job": "history-export", "db": text(&db)})).unwrap();
}

/// `history plot` refused to draw a robot serviced after its latest calibration ("no
/// calibration since its maintenance event ... calibrate it"), though the plot draws the
/// events. It draws the whole history, every segment, the events as lines, the quantities of
/// its latest segment with calibrations, and says the robot needs calibrating.
#[test]
fn plot_draws_the_history_of_a_robot_serviced_after_its_latest_calibration() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("h.sqlite");
    let db = Database::open(&path).unwrap();
    let mut ids = Vec::new();
    for k in 0..4i64 {
        ids.push(
            db.add("R1", Some(T0 + 30 * DAY * k), &report(10 + k as u64), "")
                .unwrap(),
        );
    }
    db.add_event("R1", T0 + 45 * DAY, "gearbox J2 replaced")
        .unwrap();
    db.add_event("R1", T0 + 100 * DAY, "motor J3 replaced")
        .unwrap();
    let (done, (series, events, t0)) = plot_r1(dir.path(), &path);
    assert_eq!(t0, T0);
    assert!(!series.is_empty());
    for (key, drawn) in &series {
        assert_eq!(drawn, &ids, "{key}");
    }
    assert_eq!(events, ["gearbox J2 replaced", "motor J3 replaced"]);
    let c = cautions(&done);
    assert!(
        c.iter()
            .any(|c| c.contains("serviced after its latest calibration")
                && c.contains("motor J3 replaced")
                && c.contains("calibrate it")),
        "{c:?}"
    );
    // Drift still refuses: there is nothing since the event to compare.
    let e = run(serde_json::json!({"job": "history-drift", "robot_id": "R1", "db": text(&path)}))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("no calibration since its maintenance event"),
        "{e}"
    );
}

/// After a rebuild recorded with the force option, drift compares only the new model's
/// calibrations and says which it left out; the plot draws only the new model's.
#[test]
fn jobs_never_compare_two_robot_models() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("h.sqlite");
    let db = Database::open(&path).unwrap();
    let old: Vec<i64> = (0..2)
        .map(|k| {
            db.add("R1", Some(T0 + 30 * DAY * k), &report(20 + k as u64), "")
                .unwrap()
        })
        .collect();
    let rebuilt = |seed: u64| {
        let mut r = report(seed);
        r.parameters.retain(|p| !p.name.starts_with("joint4."));
        r
    };
    let force = kinecal_history::AddOptions { force: true };
    let new: Vec<i64> = (0..2)
        .map(|k| {
            db.add_with(
                "R1",
                Some(T0 + 100 * DAY + 30 * DAY * k),
                &rebuilt(30 + k as u64),
                "",
                force,
            )
            .unwrap()
        })
        .collect();
    let done =
        run(serde_json::json!({"job": "history-drift", "robot_id": "R1", "db": text(&path)}))
            .unwrap();
    let Some(Document::Drift(d)) = Document::of(&done.document) else {
        panic!("not a drift");
    };
    assert_eq!((d.report.baseline_id, d.report.latest_id), (new[0], new[1]));
    assert_eq!(d.before_event, 0);
    let m = d.report.since_model_change.as_ref().unwrap();
    assert_eq!(m.left_out, old);
    assert!(
        m.difference.contains("3 joints, earlier 4"),
        "{}",
        m.difference
    );
    let json = done.document.to_json_value();
    assert_eq!(
        json["since_model_change"]["left_out"],
        serde_json::json!(old)
    );
    let (done, (series, _, t0)) = plot_r1(dir.path(), &path);
    assert_eq!(t0, T0 + 100 * DAY);
    for (key, drawn) in &series {
        assert_eq!(drawn, &new, "{key}");
    }
    let n = notes(&done);
    assert!(
        n.iter().any(|n| n.contains(&format!(
            "not drawn: calibrations {} and {}",
            old[0], old[1]
        ))),
        "{n:?}"
    );
}

/// `history fleet --horizon 1e9` printed its dates as raw seconds: the horizon is at most
/// 36,500 days (100 years), and its end must be a date.
#[test]
fn the_fleet_horizon_is_bounded() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("h.sqlite");
    Database::open(&path)
        .unwrap()
        .add("R1", Some(T0), &report(1), "")
        .unwrap();
    let fleet = |horizon: f64, now: &str| {
        run(serde_json::json!({
            "job": "history-fleet", "db": text(&path), "horizon": horizon, "now": now,
        }))
    };
    for h in [1e9, 36_500.5, -1.0] {
        let e = fleet(h, "2026-12-15").unwrap_err().to_string();
        assert!(
            e.contains("expected a number of days from 0 to 36500 (100 years)"),
            "{h}: {e}"
        );
    }
    let e = fleet(36_500.0, "9990-01-01").unwrap_err().to_string();
    assert!(e.contains("beyond the year 9999"), "{e}");
    for h in [0.0, 90.0, 36_500.0] {
        fleet(h, "2026-12-15").unwrap();
    }
}
