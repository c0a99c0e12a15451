//! Mutation fuzzing of `kinecal report --from`: a calibration report's JSON, read as every
//! reader reads it (`CalibrationReport::from_json`, which checks it for sense) and, when
//! accepted, drawn as the HTML page (the driver and the rules are those of
//! `crates/kinecal/tests/fuzz.rs`: no panic, no input over 1 s, the file named when refused).
//! An accepted report must draw, with no `NaN` or infinite coordinate in its pictures. The seed
//! is a report with everything a page draws: parameters with sigmas, the prediction and its
//! accuracy map, and the 3-D scene. Long run:
//! `KINECAL_FUZZ_ITERS=100000 cargo test -p kinecal-cli --test fuzz_report -- --nocapture`.

#[path = "../../kinecal/tests/fuzz_driver/mod.rs"]
mod fuzz_driver;

use fuzz_driver::{fuzz, Outcome};
use kinecal::report::CalibrationReport;
use kinecal::workflow::{Request, Selection};
use kinecal::{apps::simulate, model::examples};

#[test]
fn report_from() {
    let robot = examples::ge_a4();
    let mut truth = robot.clone();
    let id = kinecal::parse_param_list("p14", &robot).unwrap()[0];
    truth.set(id, truth.get(id) + 0.001);
    let data = simulate::measure(&truth, &simulate::sample_postures(&robot, 24, 5), false);
    let mut req = Request::new(robot.clone(), data.clone());
    req.selection = Selection::parse("p1,p14,offsets", None, &robot).unwrap();
    req.prediction = kinecal::predict::Level::Map;
    let mut out = kinecal::workflow::run(&req, &mut ()).unwrap();
    out.report.scene = kinecal::report::scene::Scene::new(
        Some(&robot),
        &out.calibration.calibrated,
        Some(&data),
        &Default::default(),
    )
    .ok();
    assert!(out.report.scene.is_some());
    let seeds = vec![out.report.to_json().into_bytes()];
    fuzz("report_from", "f.json", &seeds, &|b| {
        let t = match kinecal::source::Source::from_bytes("f.json", b.to_vec()) {
            Ok(s) => s.text,
            Err(e) => return Outcome::Refused(e.to_string()),
        };
        match CalibrationReport::from_json(&t) {
            Ok(r) => Outcome::Accepted(drawn(&r)),
            Err(e) => Outcome::Refused(format!("f.json: {e}")),
        }
    });
}

/// The page of an accepted report: drawn, no `NaN` or infinite number in a coordinate of its
/// pictures (the numeric attributes of its tags); its text and its labels may quote a report's
/// own words, `nan` and `inf` among them.
fn drawn(r: &CalibrationReport) -> Result<(), String> {
    const NUMERIC: [&str; 15] = [
        "x",
        "y",
        "x1",
        "x2",
        "y1",
        "y2",
        "cx",
        "cy",
        "r",
        "width",
        "height",
        "d",
        "points",
        "transform",
        "viewBox",
    ];
    let page = kinecal_report::html_report(r).map_err(|e| format!("not drawn: {e}"))?;
    for tag in page.split('<').skip(1) {
        let tag = tag.split('>').next().unwrap_or_default();
        for name in NUMERIC {
            let key = format!(" {name}=\"");
            let Some(at) = tag.find(&key) else { continue };
            let value = tag[at + key.len()..].split('"').next().unwrap_or_default();
            let bad = value
                .split(|c: char| !(c.is_ascii_alphanumeric() || c == '.'))
                .find(|t| ["nan", "inf", "infinity"].contains(&t.to_ascii_lowercase().as_str()));
            if let Some(t) = bad {
                return Err(format!("{name}=\"{value}\" holds `{t}`"));
            }
        }
    }
    Ok(())
}
