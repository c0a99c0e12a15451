//! Fitted values outside their physical range are named, with the remedy (issue 37, item 5):
//! slopes far from the robot file's, parameters the data barely holds that moved many of their
//! standard deviations, validation targets the identification never measured. (Negative
//! compliances and large deflections: `tests/elastic.rs`.)

use kinecal::apps::simulate::{self, PerturbStd};
use kinecal::model::robot::Site;
use kinecal::workflow::{run, Request, Selection, Validation};
use kinecal::{JointKind, Robot, Warning};

fn arm(seed: u64) -> Robot {
    let mut robot = simulate::random_robot(&[JointKind::Revolute; 6], seed);
    robot.sites.push(Site {
        name: "elbow".into(),
        joint: 3,
        frame: kinecal::Link {
            x: 0.05,
            z: 0.1,
            ..Default::default()
        },
    });
    robot
}

/// Readings of joint 2 through a 1.5 gear ratio the file does not state: the fitted slope is
/// 1.5 times the file's, and a warning names it; the right slopes raise none.
#[test]
fn a_slope_far_from_the_files_is_named() {
    let nominal = arm(3);
    let mut truth = nominal.clone();
    truth.joints[1].slope *= 1.5;
    let postures = simulate::sample_postures(&nominal, 40, 5);
    let fit = |truth: &Robot| {
        let data = simulate::measure(truth, &postures, false);
        let mut req = Request::new(nominal.clone(), data);
        req.selection = Selection::parse("identifiable,slopes", None, &nominal).unwrap();
        run(&req, &mut ()).unwrap()
    };
    let out = fit(&truth);
    assert!(
        out.warnings.iter().any(|w| matches!(
            w,
            Warning::SlopeFarOff { parameters } if parameters.len() == 1 && parameters[0].starts_with("joint2.slope")
        )),
        "{:?}",
        out.warnings
    );
    let out = fit(&simulate::perturb(
        &nominal,
        PerturbStd {
            length: 1e-3,
            angle: 1e-3,
            slope_fraction: 1e-3,
        },
        5,
    ));
    assert!(!out
        .warnings
        .iter()
        .any(|w| matches!(w, Warning::SlopeFarOff { .. })));
}

/// Identification on the end effector, validation on the elbow site too: the site, never
/// identified, is named.
#[test]
fn validation_targets_never_identified_are_named() {
    let nominal = arm(4);
    let truth = simulate::perturb(
        &nominal,
        PerturbStd {
            length: 1e-3,
            angle: 1e-3,
            slope_fraction: 0.0,
        },
        6,
    );
    let ee_only = |data: kinecal::Dataset| {
        let observations = data
            .observations
            .into_iter()
            .filter(|o| o.target() == kinecal::model::kinematics::Target::EndEffector)
            .collect();
        kinecal::Dataset::new(data.postures, observations)
    };
    let data = ee_only(simulate::measure(
        &truth,
        &simulate::sample_postures(&nominal, 30, 1),
        false,
    ));
    let fresh = simulate::measure(&truth, &simulate::sample_postures(&nominal, 10, 2), false);
    let mut req = Request::new(nominal.clone(), data);
    req.validation = Validation::Data(std::sync::Arc::new(fresh));
    let out = run(&req, &mut ()).unwrap();
    assert!(
        out.warnings.iter().any(|w| matches!(
            w,
            Warning::ValidationTargetsUnseen { targets } if targets == &["elbow".to_string()]
        )),
        "{:?}",
        out.warnings
    );
}

/// Positions alone of 12 postures, every parameter asked for without a prior: parameters the
/// data barely holds, left to move many of their sigmas, are named.
#[test]
fn loose_parameters_that_moved_far_are_named() {
    let nominal = simulate::random_robot(&[JointKind::Revolute; 6], 9);
    let truth = simulate::perturb(
        &nominal,
        PerturbStd {
            length: 2e-2,
            angle: 2e-2,
            slope_fraction: 0.0,
        },
        3,
    );
    let mut data = simulate::measure(&truth, &simulate::sample_postures(&nominal, 12, 4), true);
    simulate::add_noise(&mut data, 1e-3, 0.0, 2);
    let mut req = Request::new(nominal.clone(), data);
    req.selection = Selection::parse("identifiable", None, &nominal).unwrap();
    let out = run(&req, &mut ()).unwrap();
    let named = out.warnings.iter().find_map(|w| match w {
        Warning::LooseAndMoved { parameters } => Some(parameters.clone()),
        _ => None,
    });
    // Check the rule against the uncertainty itself: every parameter whose sigma exceeds its
    // tolerance and that moved over 5 sigma is named, and only those.
    let u = out.uncertainty.as_ref().unwrap();
    let expected: Vec<String> = u
        .parameters
        .iter()
        .filter_map(|p| {
            let s = p.sigma?;
            let q = nominal.param_quantity(p.id);
            let t = nominal.units.from_si(q, nominal.tolerance(p.id));
            (s > t && p.change.abs() / s > 5.0).then(|| nominal.param_name(p.id))
        })
        .collect();
    let got: Vec<String> = named
        .unwrap_or_default()
        .iter()
        .map(|p| p.split(' ').next().unwrap().to_string())
        .collect();
    assert!(
        !expected.is_empty(),
        "nothing loose: the case does not test the rule"
    );
    assert_eq!(got, expected);
}
