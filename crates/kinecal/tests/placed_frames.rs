//! What the start's closed-form placement sets from the data is estimated afterwards, however
//! loosely the data determine it.

use std::sync::Arc;

use kinecal::apps::datasets::ipa_ur10;
use kinecal::apps::simulate::{self, PerturbStd};
use kinecal::observe::{accuracy, Dataset, Posture};
use kinecal::workflow::{self, Request, Selection, Validation};
use kinecal::{Chain, Robot, Target, Warning};

/// A small deterministic generator (uniform in [0, 1)).
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
    fn between(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.next()
    }
}

/// `n` postures of `robot` with the flange axis within about `tilt` rad of pointing straight
/// down (the wrist held, the rest spread), as ISO 9283 cube poses are measured.
fn tool_down(robot: &Robot, n: usize, tilt: f64, seed: u64) -> Vec<Posture> {
    use std::f64::consts::{FRAC_PI_2, PI};
    let chain = Chain::new(robot);
    let axis_z = |q: &[f64]| chain.frame_at(q, Target::EndEffector).rotation[(2, 2)];
    // The wrist's sum q2 + q3 + q4 and q5 that point the flange axis down.
    let mut best = (0.0, 0.0, f64::INFINITY);
    for c in [-PI, -FRAC_PI_2, 0.0, FRAC_PI_2, PI] {
        for q5 in [-FRAC_PI_2, FRAC_PI_2] {
            let q = [0.3, -1.2, 1.5, c + 1.2 - 1.5, q5, 0.0];
            let e = (axis_z(&q) + 1.0).abs();
            if e < best.2 {
                best = (c, q5, e);
            }
        }
    }
    assert!(best.2 < 1e-6, "no wrist points down: {best:?}");
    let mut g = Lcg(seed);
    (1..=n)
        .map(|i| {
            let q1 = g.between(-1.0, 1.0);
            let q2 = g.between(-2.2, -1.0);
            let q3 = g.between(0.8, 2.0);
            let q4 = best.0 - q2 - q3 + tilt * g.between(-1.7, 1.7);
            let q5 = best.1 + tilt * g.between(-1.7, 1.7);
            let q6 = g.between(-PI, PI);
            Posture {
                label: i.to_string(),
                readings: vec![q1, q2, q3, q4, q5, q6],
                session: None,
                payload: None,
            }
        })
        .collect()
}

/// The UR10 with small errors (0.5 mm, 1 mrad), a probe 0.1 m along the flange axis the
/// nominal robot does not know, measured by a tracker metres away (0.05 mm of noise), at `n`
/// postures with the flange axis within about `tilt` of pointing down; held out, 200 postures
/// spread over the joint ranges in the same tracker frame.
fn tool_down_series(tilt: f64, n: usize) -> (Robot, Robot, Dataset, Dataset) {
    let nominal = ipa_ur10::nominal_robot();
    let mut truth = simulate::perturb(
        &nominal,
        PerturbStd {
            length: 0.0005,
            angle: 0.001,
            slope_fraction: 0.0,
        },
        7,
    );
    truth.links[0].x = 2.0;
    truth.links[0].y = -1.0;
    truth.links[0].z = -1.1;
    truth.links[0].alpha = 0.4;
    let last = truth.links.len() - 1;
    truth.links[last].z += 0.1;
    let mut data = simulate::measure(&truth, &tool_down(&nominal, n, tilt, 11), true);
    simulate::add_noise(&mut data, 5e-5, 0.0, 12);
    let held = simulate::measure(&truth, &simulate::sample_postures(&nominal, 200, 13), true);
    (nominal, truth, data, held)
}

fn calibrate(nominal: &Robot, data: &Dataset, held: &Dataset) -> workflow::Outcome {
    let mut req = Request::new(nominal.clone(), Arc::new(data.clone()));
    req.selection = Selection::parse("identifiable", None, nominal).unwrap();
    req.validation = Validation::Data(Arc::new(held.clone()));
    workflow::run(&req, &mut ()).unwrap()
}

/// Measured with the flange axis held within 0.05 deg of vertical (the ISO 9283 cubes of the
/// IPA UR10's series D hold one tool attitude too), the probe's length along that axis is
/// nearly a shift of the tracker frame: at the default weights (1 mm) the data determine it
/// only to about 0.13 m given the rest (6.6 mm at the residuals' noise), beyond the
/// identifiable set's noise rule (2 % of the reach), and so is the flange length (link6.y) it
/// adds to. The start's closed-form placement put it at 0.197 m (the truth: 0.0997), fitting
/// the nominal robot's errors along that valley. Before, the identifiable set left it out and
/// the calibration kept it there: held out at other attitudes, 134.7 mm mean error after
/// calibration (134.6 at the start). Now what the placement set is estimated whatever the
/// noise rule says: the probe's length ends 0.1 mm from the truth, the held-out error at
/// 1.1 mm (the wrist's other parameters are what data at one attitude cannot give), and a
/// warning names it with its standard deviation.
#[test]
fn a_probe_length_the_placement_set_is_estimated_however_loosely_determined() {
    let (nominal, truth, data, held) = tool_down_series(0.0005, 150);
    let out = calibrate(&nominal, &data, &held);
    let cal = &out.calibration;
    let last = nominal.links.len() - 1;
    let probe = nominal.param_id(kinecal::ParamKind::Link {
        link: last,
        component: kinecal::model::params::LinkComponent::Z,
    });
    let (start, after) = (cal.initial.get(probe), cal.calibrated.get(probe));
    let sigma = out
        .uncertainty
        .as_ref()
        .and_then(|u| u.parameters.iter().find(|p| p.id == probe))
        .and_then(|p| p.sigma)
        .expect("the probe length's standard deviation");
    let held_start = accuracy(&cal.initial, &held).mean_position;
    let held_after = accuracy(&cal.calibrated, &held).mean_position;
    eprintln!(
        "probe z: start {:.4} mm, after {:.4} (sigma {:.4}), truth {:.4}; held-out mean {:.3} -> {:.3} mm",
        start * 1e3,
        after * 1e3,
        sigma * 1e3,
        truth.get(probe) * 1e3,
        held_start * 1e3,
        held_after * 1e3
    );
    assert!(cal.converged(), "{:?}", cal.termination);
    // The placement's value was far off (many of the fit's standard deviations): this is the
    // case the test is about.
    let off = |v: f64| (v - truth.get(probe)).abs();
    assert!(off(start) > 10.0 * sigma, "{start} for sigma {sigma}");
    assert!(cal.estimated.contains(&probe));
    // Within three of its standard deviations (the noise is the model's only error here).
    assert!(off(after) < 3.0 * sigma, "{after} for sigma {sigma}");
    // Held out at other attitudes the error is what data at one attitude leave of the wrist
    // (1.09 mm), a twentieth of the start's at most (before: the start's, 134.7 mm).
    assert!(
        held_after < 2e-3 && held_after < 0.05 * held_start,
        "{held_after}"
    );
    let named = out.warnings.iter().find_map(|w| match w {
        Warning::PlacedLoose { parameters } => Some(parameters.join("; ")),
        _ => None,
    });
    let named = named.expect("the loosely determined probe length is named");
    assert!(named.contains("link7.z (sigma "), "{named}");
}

/// The same postures with the flange axis within 0.5 deg of vertical: the flange length (link6.y,
/// the one the identifiable set prefers) is determined and carries the probe's error; the
/// probe length, placed, is left out as its exact copy, and nothing is said.
#[test]
fn a_placed_length_an_estimated_one_copies_stays_out_unnamed() {
    let (nominal, truth, data, held) = tool_down_series(0.005, 150);
    let out = calibrate(&nominal, &data, &held);
    let cal = &out.calibration;
    let last = nominal.links.len() - 1;
    let id = |link, component| nominal.param_id(kinecal::ParamKind::Link { link, component });
    use kinecal::model::params::LinkComponent::{Y, Z};
    let (flange, probe) = (id(last - 1, Y), id(last, Z));
    assert!(cal.converged(), "{:?}", cal.termination);
    assert!(cal.estimated.contains(&flange) && !cal.estimated.contains(&probe));
    let sum = |r: &Robot| r.get(flange) + r.get(probe);
    assert!((sum(&cal.calibrated) - sum(&truth)).abs() < 2e-3);
    assert!(!out
        .warnings
        .iter()
        .any(|w| matches!(w, Warning::PlacedLoose { .. })));
}
