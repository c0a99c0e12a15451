//! Predictions at every target (issue 37): on a two-arm tree each arm gets its own model-error
//! term, and the 95 % bound covers the calibrated model's own residuals at the postures it was
//! identified on (at least 90 %) and at held-out postures (at least 90 %).
//!
//! The stand-in: a random tree (2 torso joints, two 4-joint arms) whose right arm (the end
//! effector) has an unmodelled, smooth error of about 1 mm (a function of its readings no
//! parameter reproduces), the left arm (site `arm1`) 0.05 mm of noise only.

use kinecal::apps::simulate;
use kinecal::observe::errors;
use kinecal::predict::{self, PredictionReport};
use kinecal::workflow::{self, Request, Selection};
use kinecal::{Dataset, Observation, Robot, Target};

/// Positions of both arms at `count` postures (seed `seed`), the right arm's moved by the
/// unmodelled effect, every one with 0.05 mm of noise.
fn measured(robot: &Robot, count: usize, seed: u64) -> Dataset {
    let postures = simulate::sample_postures(robot, count, seed);
    let mut data = simulate::measure(robot, &postures, true);
    simulate::add_noise(&mut data, 0.05e-3, 0.0, seed + 100);
    for o in &mut data.observations {
        let q = data.postures[o.posture()].readings.clone();
        if let Observation::Position(p) = o {
            if p.view[0].target == Target::EndEffector {
                let n = q.len();
                p.position.x += 1.0e-3 * (2.0 * q[n - 1]).sin() * q[n - 2].cos();
                p.position.y += 0.8e-3 * (3.0 * q[n - 3]).cos();
                p.position.z += 0.6e-3 * (q[n - 2] + q[n - 4]).sin();
            }
        }
    }
    data
}

/// The share of `data`'s observations at `target` within their predicted 95 % bound.
fn coverage(robot: &Robot, report: &PredictionReport, data: &Dataset, target: Target) -> f64 {
    let p = predict::from_report(robot, report).unwrap();
    let mut s = p.scratch();
    let e = errors(robot, data);
    let (mut inside, mut n) = (0usize, 0usize);
    for (o, err) in data.observations.iter().zip(&e) {
        if o.target() != target {
            continue;
        }
        let q = p.predict(&data.postures[o.posture()].readings, target, &mut s);
        n += 1;
        inside += usize::from(err.length <= q.position_error.bound);
    }
    inside as f64 / n as f64
}

#[test]
fn each_arm_has_its_own_term_and_the_bounds_cover_the_residuals() {
    let robot = simulate::random_tree(2, &[4, 4], 11);
    let identification = measured(&robot, 150, 1);
    let held_out = measured(&robot, 300, 2);
    let mut req = Request::new(robot.clone(), identification.clone());
    req.selection = Selection::parse("identifiable", None, &robot).unwrap();
    req.prediction = predict::Level::Summary;
    req.weights.length = 0.5e-3;
    let out = workflow::run(&req, &mut ()).unwrap();
    let pr = out.report.prediction.as_ref().expect("a prediction");
    let cal = &out.calibration.calibrated;
    // A term per arm: the right arm's (the unmodelled effect) several times the left's.
    assert_eq!(pr.targets.len(), 2, "{:?}", pr.targets);
    let term = |name: &str| {
        pr.targets
            .iter()
            .find(|t| t.target == name)
            .unwrap_or_else(|| panic!("no term for {name}: {:?}", pr.targets))
            .position
            .clone()
    };
    let (left, right) = (term("arm1"), term(&pr.target));
    eprintln!(
        "left: s0 {:.4} mm (residuals {:.4}), c {:.5}; right: s0 {:.4} mm (residuals {:.4}), c \
         {:.5}",
        left.s0 * 1e3,
        left.s0_floor * 1e3,
        left.c,
        right.s0 * 1e3,
        right.s0_floor * 1e3,
        right.c
    );
    assert!(right.s0 > 3.0 * left.s0, "{left:?} {right:?}");
    for g in [&left, &right] {
        assert!(g.s0 >= g.s0_floor, "{g:?}");
    }
    assert!(right.s0_floor > 0.0, "{right:?}");
    for (name, target) in [("left", Target::Site(0)), ("right", Target::EndEffector)] {
        let at_identification = coverage(cal, pr, &identification, target);
        let at_held_out = coverage(cal, pr, &held_out, target);
        eprintln!(
            "{name}: within the 95 % bound at the identification postures {:.1} %, held out \
             {:.1} %",
            at_identification * 100.0,
            at_held_out * 100.0
        );
        assert!(at_identification >= 0.9, "{name}: {at_identification}");
        // Held out: at least 90 % (seen: 99 %; the parameters' part, scaled by the one variance
        // factor the right arm's misfit raises, is wide here; the 90-98 % window is checked
        // on the UR10 tracker data, tests/predict.rs).
        assert!(at_held_out >= 0.9, "{name}: {at_held_out}");
    }
}

/// Postures in tight clusters (every block the cross-validation holds out is whole clusters
/// away from the fitted ones, so it sees no error near the measured postures) with a smooth
/// unmodelled effect: the bound at the identification postures still covers the residuals
/// there (the floor; without it 66.9 %: `s0` 0.16 mm where the residuals show 0.25), and held
/// out at least 90 % (seen: 99 %, as without the floor, 98 %: the held-out clusters lie where
/// `c` dominates; the 90-98 % window is checked on the UR10 tracker data, tests/predict.rs).
#[test]
fn clustered_postures_bounds_cover_their_own_residuals() {
    let robot = simulate::random_tree(0, &[6], 5);
    let make = |clusters: usize, seed: u64| {
        let centres = simulate::sample_postures(&robot, clusters, seed);
        let mut postures = Vec::new();
        let jitter = simulate::sample_postures(&robot, clusters * 8, seed + 50);
        for (i, c) in centres.iter().enumerate() {
            for k in 0..8 {
                let j = &jitter[i * 8 + k];
                let mut p = c.clone();
                p.label = format!("{}_{k}", c.label);
                for (r, dj) in p.readings.iter_mut().zip(&j.readings) {
                    *r += 0.01 * dj;
                }
                postures.push(p);
            }
        }
        let mut data = simulate::measure(&robot, &postures, true);
        simulate::add_noise(&mut data, 0.05e-3, 0.0, seed + 100);
        for o in &mut data.observations {
            let q = data.postures[o.posture()].readings.clone();
            if let Observation::Position(p) = o {
                p.position.x += 1.0e-3 * (2.0 * q[5]).sin() * q[4].cos();
                p.position.y += 0.8e-3 * (3.0 * q[3]).cos();
                p.position.z += 0.6e-3 * (q[4] + q[2]).sin();
            }
        }
        data
    };
    let identification = make(20, 1);
    let held_out = make(40, 2);
    let mut req = Request::new(robot.clone(), identification.clone());
    req.selection = Selection::parse("identifiable", None, &robot).unwrap();
    req.prediction = predict::Level::Summary;
    req.weights.length = 0.5e-3;
    let out = workflow::run(&req, &mut ()).unwrap();
    let pr = out.report.prediction.as_ref().expect("a prediction");
    let cal = &out.calibration.calibrated;
    let at_identification = coverage(cal, pr, &identification, Target::EndEffector);
    let at_held_out = coverage(cal, pr, &held_out, Target::EndEffector);
    eprintln!(
        "clustered: s0 {:.4} mm (floor {:.4}), c {:.5}; within the 95 % bound at the \
         identification postures {:.1} %, held out {:.1} %",
        pr.position.s0 * 1e3,
        pr.position.s0_floor * 1e3,
        pr.position.c,
        at_identification * 100.0,
        at_held_out * 100.0
    );
    assert!(pr.position.s0 >= pr.position.s0_floor && pr.position.s0_floor > 0.0);
    assert!(at_identification >= 0.9, "{at_identification}");
    assert!(at_held_out >= 0.9, "{at_held_out}");
}
