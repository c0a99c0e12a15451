//! Three placements of a tracker pooled in one file without a `session` column: recognised as
//! such, the rows of each placement named, the remedy said.

use std::sync::Arc;

use kinecal::apps::datasets::ipa_ur10;
use kinecal::apps::simulate::{self, PerturbStd};
use kinecal::observe::Dataset;
use kinecal::workflow::{self, Request, Selection};
use kinecal::{Robot, Warning};

/// The UR10 with small errors and a probe 0.1 m off the flange, and three tracker placements
/// metres and tens of degrees apart, `n` postures each.
fn placements(n: usize) -> (Robot, Vec<Dataset>) {
    let nominal = ipa_ur10::nominal_robot();
    let truth = simulate::perturb(
        &nominal,
        PerturbStd {
            length: 0.0005,
            angle: 0.001,
            slope_fraction: 0.0,
        },
        7,
    );
    let places = [
        (2.0, -1.0, 0.3, 0.4, 0.0),
        (-1.5, 2.5, -0.2, 2.1, 0.1),
        (0.5, 3.5, 0.6, -1.0, -0.2),
    ];
    let mut series = Vec::new();
    for (k, &(x, y, z, yaw, tilt)) in places.iter().enumerate() {
        let mut t = truth.clone();
        t.links[0].x = x;
        t.links[0].y = y;
        t.links[0].z = z;
        t.links[0].alpha = yaw;
        t.links[0].beta = tilt;
        let last = t.links.len() - 1;
        t.links[last].z += 0.1;
        let ps = simulate::sample_postures(&nominal, n, 100 + k as u64);
        let mut d = simulate::measure(&t, &ps, true);
        simulate::add_noise(&mut d, 5e-5, 0.0, 200 + k as u64);
        series.push(d);
    }
    (nominal, series)
}

fn run(nominal: &Robot, data: &Dataset, sel: &str) -> kinecal::Result<workflow::Outcome> {
    let mut req = Request::new(nominal.clone(), Arc::new(data.clone()));
    req.selection = Selection::parse(sel, None, nominal).unwrap();
    workflow::run(&req, &mut ())
}

/// The three series pooled in file order without a `session` column: the data check names
/// the three placements by their rows (40 each, in order) and says to add a `session` column,
/// instead of hinting at the length unit (before: "the measured positions spread 3.077 times
/// as widely as the nominal robot predicts ... state the file's unit", and with
/// `--estimate identifiable` only "no parameters to estimate").
#[test]
fn placements_pooled_without_sessions_are_named() {
    let (nominal, series) = placements(40);
    let pooled = series.iter().cloned().reduce(|a, b| a.merge(b)).unwrap();
    // The rows' lines as a file would number them (a header, then one row each).
    let mut pooled = pooled;
    for (k, o) in pooled.observations.iter_mut().enumerate() {
        if let kinecal::Observation::Position(p) = o {
            p.line = k + 2;
        }
    }
    let mut seen = None;
    let mut progress = Seen(&mut seen);
    let mut req = Request::new(nominal.clone(), Arc::new(pooled.clone()));
    req.selection = Selection::parse("identifiable", None, &nominal).unwrap();
    // Whatever the fit does after, the data check has said it.
    let _ = workflow::run(&req, &mut progress);
    let warnings = seen.expect("the data were checked");
    let named = warnings.iter().find_map(|w| match w {
        Warning::PooledPlacements { blocks, .. } => Some(blocks.clone()),
        _ => None,
    });
    assert_eq!(
        named.as_deref(),
        Some(
            &[
                "placement 1: lines 2-41 (40 rows)".to_string(),
                "placement 2: lines 42-81 (40 rows)".to_string(),
                "placement 3: lines 82-121 (40 rows)".to_string(),
            ][..]
        ),
        "{warnings:?}"
    );
    assert!(
        !warnings
            .iter()
            .any(|w| matches!(w, Warning::ScaleMismatch { .. })),
        "{warnings:?}"
    );
    let text = warnings
        .iter()
        .find(|w| matches!(w, Warning::PooledPlacements { .. }))
        .unwrap()
        .to_string();
    assert!(text.contains("`session` column"), "{text}");
    assert!(warnings.iter().any(|w| w.implausible()));
    // The default set: the fit's outcome carries it too.
    let out = run(&nominal, &pooled, "").unwrap();
    assert!(out
        .warnings
        .iter()
        .any(|w| matches!(w, Warning::PooledPlacements { .. })));
}

/// The same rows with a `session` column: each placement gets a frame of its own, the fit
/// reaches the noise (0.05 mm per coordinate), and nothing says "pooled".
#[test]
fn the_same_placements_with_sessions_fit() {
    let (nominal, series) = placements(40);
    let with_sessions = series
        .into_iter()
        .zip(["A", "B", "C"])
        .map(|(mut d, s)| {
            d.set_session(s);
            d
        })
        .reduce(|a, b| a.merge(b))
        .unwrap();
    let out = run(&nominal, &with_sessions, "identifiable").unwrap();
    assert!(
        out.calibration.converged(),
        "{:?}",
        out.calibration.termination
    );
    assert!(
        !out.warnings.iter().any(|w| matches!(
            w,
            Warning::PooledPlacements { .. } | Warning::ScaleMismatch { .. }
        )),
        "{:?}",
        out.warnings
    );
    let rms = out.calibration.accuracy_after.rms_position;
    assert!(rms < 2e-4, "{rms}");
}

/// One placement, no sessions: nothing said.
#[test]
fn one_placement_is_not_called_pooled() {
    let (nominal, series) = placements(60);
    let out = run(&nominal, &series[1], "identifiable").unwrap();
    assert!(out.calibration.converged());
    assert!(!out
        .warnings
        .iter()
        .any(|w| matches!(w, Warning::PooledPlacements { .. })));
}

/// Keeps the warnings of the data check.
struct Seen<'a>(&'a mut Option<Vec<Warning>>);

impl workflow::Progress for Seen<'_> {
    fn data_checked(&mut self, warnings: &[Warning]) -> bool {
        *self.0 = Some(warnings.to_vec());
        true
    }
}
