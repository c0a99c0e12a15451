//! The uncertainty of a fit whose rows carry an instrument's standard deviations far below what
//! their residuals show: the model-error floor weighs the rows by `1 / (s_i^2 + m^2)`, and the
//! parameters' standard deviations must be those of the rows so weighed. Before, the
//! information was taken at the stated sigmas while the objective that scales it was the
//! floored one: on the IPA UR10 tracker files every sigma was 36-57 times too small (and every
//! "moved by many sigmas" judgement wrong with it).

use kinecal::apps::simulate::{self, PerturbStd};
use kinecal::model::robot::JointKind;
use kinecal::workflow::{self, Request, Selection};
use kinecal::{Dataset, Observation, Robot};

fn with_sigma(data: &Dataset, sigma: Option<f64>) -> Dataset {
    let mut data = data.clone();
    for o in &mut data.observations {
        if let Observation::Position(p) = o {
            p.sigma_position = sigma.map(nalgebra::Vector3::repeat);
        }
    }
    data
}

/// A random six-axis arm (seeds from `seed` on) and 300 of its positions measured with 0.2 mm
/// of noise, no sigma columns.
fn noisy_arm(seed: u64) -> (Robot, Dataset) {
    let nominal = simulate::random_robot(&[JointKind::Revolute; 6], seed);
    let truth = simulate::perturb(
        &nominal,
        PerturbStd {
            length: 0.001,
            angle: 0.002,
            slope_fraction: 0.0,
        },
        seed + 1,
    );
    let postures = simulate::sample_postures(&nominal, 300, seed + 2);
    let mut data = simulate::measure(&truth, &postures, true);
    simulate::add_noise(&mut data, 2e-4, 0.0, seed + 3);
    (nominal, data)
}

#[test]
fn sigmas_under_a_model_error_floor_are_those_of_the_rows_as_weighed() {
    // 0.2 mm of noise; the rows state 0.005 mm, 40 times less.
    let (nominal, data) = noisy_arm(71);
    let run = |data: Dataset| {
        let mut req = Request::new(nominal.clone(), data);
        req.selection = Selection::parse("identifiable", None, &nominal).unwrap();
        workflow::run(&req, &mut ()).unwrap()
    };
    let stated = run(with_sigma(&data, Some(5e-6)));
    let plain = run(with_sigma(&data, None));
    let floor = stated
        .calibration
        .model_error
        .expect("rows with their own sigma");
    assert!(
        (1.5e-4..2.5e-4).contains(&floor.length),
        "the floor {} m, where the noise is 2e-4 m",
        floor.length
    );
    let (us, up) = (
        stated.uncertainty.as_ref().unwrap(),
        plain.uncertainty.as_ref().unwrap(),
    );
    let mut compared = 0;
    for p in &up.parameters {
        let (Some(a), Some(b)) = (us.parameter(p.id).and_then(|q| q.sigma), p.sigma) else {
            continue;
        };
        // Weights within 1 + (0.005 / 0.2)^2 of uniform: the same sigmas as the unweighted fit
        // (whose variance factor scales its 1 mm default to the residuals), up to the two
        // fits' own spread of the residuals (a few per cent at 900 rows).
        assert!(
            (0.85..1.15).contains(&(a / b)),
            "{}: sigma {a} with the floor, {b} without ({}x)",
            nominal.param_name(p.id),
            a / b
        );
        compared += 1;
    }
    assert!(compared >= 20, "only {compared} parameters compared");
}

/// A tenth of the points stated at 1 mm, above the 0.2 mm model error, the rest at 0.005 mm:
/// the note counts the rows that keep their own sigma (the 1 mm ones) among those with one,
/// and the fit weighs them by it, so they pull less than the rest.
#[test]
fn the_note_counts_the_rows_stated_above_the_floor() {
    let (nominal, data) = noisy_arm(81);
    let mut data = with_sigma(&data, Some(5e-6));
    for o in data.observations.iter_mut().take(30) {
        if let Observation::Position(p) = o {
            p.sigma_position = Some(nalgebra::Vector3::repeat(1e-3));
        }
    }
    let mut req = Request::new(nominal.clone(), data);
    req.selection = Selection::parse("identifiable", None, &nominal).unwrap();
    let out = workflow::run(&req, &mut ()).unwrap();
    let note = out
        .warnings
        .iter()
        .find(|w| matches!(w, kinecal::Warning::ModelErrorFloor { .. }))
        .expect("the floor named");
    let kinecal::Warning::ModelErrorFloor {
        length_mm,
        rows,
        above,
        ..
    } = note
    else {
        unreachable!()
    };
    assert!((0.15..0.25).contains(length_mm), "{length_mm} mm");
    assert_eq!((*rows, *above), (900, 90));
    assert!(
        note.to_string()
            .contains("90 of the 900 rows state more and keep their own"),
        "{note}"
    );
    // The row scale: s / max(s, m), so 1 for the 1 mm rows and 0.005 / m for the others.
    let scale = &out.calibration.row_scale;
    assert!(scale[..90].iter().all(|&k| k.to_bits() == 1f64.to_bits()));
    let m = length_mm * 1e-3;
    assert!(scale[90..].iter().all(|&k| (k - 5e-6 / m).abs() < 1e-12));
}
