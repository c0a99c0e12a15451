//! The calibration workflow as a library capability: one request, one outcome, one
//! linearisation rule for the identifiable set, the uncertainty and pruning.

use kinecal::apps::simulate::{self, PerturbStd};
use kinecal::observe::Weights;
use kinecal::workflow::{self, Request, Selection, SolutionRule, Validation};
use kinecal::{model::examples, parse_param_list, ParamId, Warning};

fn session() -> (kinecal::Robot, kinecal::Dataset) {
    let nominal = examples::ge_a4();
    let mut truth = nominal.clone();
    for (name, delta) in [
        ("p1", 0.05),
        ("p14", -0.02),
        ("joint2.offset", -0.5),
        ("joint4.slope", 0.02),
    ] {
        let id = parse_param_list(name, &nominal).unwrap()[0];
        let q = nominal.param_quantity(id);
        truth.set(id, truth.get(id) + nominal.units.to_si(q, delta));
    }
    let mut data = simulate::measure(&truth, &simulate::sample_postures(&nominal, 30, 7), false);
    simulate::add_noise(&mut data, 0.0005 * 0.0254, 0.005f64.to_radians(), 7);
    (nominal, data)
}

/// Pruning judges significance where the report does: every change kept in the pruned fit is
/// significant in the report, whichever robot the solver started from.
#[test]
fn pruning_and_the_report_use_one_linearisation_point() {
    let (nominal, data) = session();
    for initial in [
        None,
        Some(simulate::perturb(
            &nominal,
            PerturbStd {
                length: 0.05 * 0.0254,
                angle: 0.0,
                slope_fraction: 0.001,
            },
            3,
        )),
    ] {
        for solution in [SolutionRule::Solver, SolutionRule::MinChange] {
            let mut req = Request::new(nominal.clone(), data.clone());
            req.selection = Selection::parse("identifiable", None, &nominal).unwrap();
            req.weights = Weights {
                length: 0.0005 * 0.0254,
                angle: 0.005f64.to_radians(),
            };
            req.initial = initial.clone();
            req.solution = solution;
            req.prune = Some(3.0);
            let out = workflow::run(&req, &mut ()).unwrap();
            let p = out.pruning.as_ref().unwrap();
            assert!(!p.removed.is_empty());
            for r in out.report.parameters.iter().filter(|r| r.estimated_flag) {
                let z = r.significance.expect("kept parameters are determined");
                assert!(z >= 3.0, "{solution:?} {}: {z}", r.name);
            }
            // From the nominal robot, the four changes made are the ones kept (from a wrong
            // guess, the corrections of the guess are changes too).
            if initial.is_some() {
                continue;
            }
            let kept: Vec<&str> = out
                .report
                .parameters
                .iter()
                .filter(|r| r.estimated_flag)
                .map(|r| r.id.as_str())
                .collect();
            assert_eq!(
                kept,
                ["p1", "p14", "p32", "p38"],
                "{solution:?} {initial:?}"
            );
        }
    }
}

#[test]
fn the_outcome_carries_validation_outliers_warnings_and_the_report() {
    let (nominal, mut data) = session();
    // One bad row: a reflector bumped by 1 mm.
    if let kinecal::Observation::Pose(p) = &mut data.observations[4] {
        p.position.x += 1e-3;
    }
    let mut req = Request::new(nominal.clone(), data);
    req.selection = Selection::parse("p1,p2,p8,p14,offsets,slopes", None, &nominal).unwrap();
    req.weights = Weights {
        length: 0.0005 * 0.0254,
        angle: 0.005f64.to_radians(),
    };
    req.validation = Validation::Holdout {
        fraction: 0.2,
        seed: 1,
    };
    let out = workflow::run(&req, &mut ()).unwrap();
    assert_eq!(out.validation.as_ref().unwrap().postures, 6);
    assert_eq!(out.identification.postures, 24);
    assert_eq!(out.report.validation.as_ref().unwrap().postures, 6);
    // The bumped row stays in the identification data with this seed.
    let bad_line_held = out
        .validation_data
        .as_ref()
        .unwrap()
        .postures
        .iter()
        .any(|p| p.label == "5");
    assert!(!bad_line_held);
    {
        // Least squares smears the bad row over its neighbours, but it stands out most.
        let worst = out
            .report
            .outliers
            .iter()
            .max_by(|a, b| a.sigmas.total_cmp(&b.sigmas))
            .unwrap();
        assert_eq!(worst.posture, "5");
        // The robust loss leaves it alone.
        let mut huber = req.clone();
        huber.loss = kinecal::solve::estimation::Loss::huber(1.345);
        let out = workflow::run(&huber, &mut ()).unwrap();
        let flagged: Vec<&str> = out
            .report
            .outliers
            .iter()
            .map(|o| o.posture.as_str())
            .collect();
        assert_eq!(flagged, ["5"]);
    }
    // Warnings are structured and worded alike in the report.
    assert_eq!(out.report.warnings.len(), out.warnings.len());
    assert_eq!(out.report.warning_details, out.warnings);
    // A cap of 1 iteration is reported as not converged.
    req.solver.max_iterations = 1;
    req.validation = Validation::None;
    let out = workflow::run(&req, &mut ()).unwrap();
    assert!(out
        .warnings
        .iter()
        .any(|w| matches!(w, Warning::NotConverged { iterations: 1 })));
    assert!(!out.report.converged);
    // Bad settings are refused by name.
    for (mutate, option) in [
        (
            Box::new(|r: &mut Request| r.outlier_sigmas = f64::NAN) as Box<dyn Fn(&mut Request)>,
            kinecal::Setting::OutlierThreshold,
        ),
        (
            Box::new(|r: &mut Request| r.prune = Some(-1.0)),
            kinecal::Setting::PruningThreshold,
        ),
        (
            Box::new(|r: &mut Request| {
                r.validation = Validation::Holdout {
                    fraction: 1.5,
                    seed: 1,
                }
            }),
            kinecal::Setting::HoldoutFraction,
        ),
        (
            Box::new(|r: &mut Request| r.loss = kinecal::solve::estimation::Loss::huber(1e-320)),
            kinecal::Setting::HuberScale,
        ),
    ] {
        let mut r = req.clone();
        mutate(&mut r);
        match workflow::run(&r, &mut ()) {
            Err(kinecal::Error::InvalidOption { setting, .. }) => assert_eq!(setting, option),
            other => panic!("{option:?}: {:?}", other.map(|o| o.report.converged)),
        }
    }
    let _ = ParamId(0);
}

/// With the default weights (1 mm and 1 mrad, far above this data's 0.0127 mm noise) a Huber
/// threshold in stated standard deviations is never reached and changes nothing; in the
/// residuals' robust spread it down-weights the bad rows, the fit is not pulled by them, and
/// the report says how many rows it down-weighted.
#[test]
fn huber_takes_its_scale_from_the_residuals_unless_told_to_trust_the_weights() {
    use kinecal::solve::estimation::{Loss, Spread};
    let (nominal, mut data) = session();
    for k in [4, 11, 23] {
        if let kinecal::Observation::Pose(p) = &mut data.observations[k] {
            p.position.x += 0.05 * 0.0254;
        }
    }
    let fit = |loss: Loss| {
        let mut req = Request::new(nominal.clone(), data.clone());
        req.selection = Selection::parse("p1,p2,p8,p14,offsets,slopes", None, &nominal).unwrap();
        req.loss = loss;
        workflow::run(&req, &mut ()).unwrap()
    };
    let ls = fit(Loss::Squared);
    let stated = fit(Loss::Huber {
        k: 1.345,
        spread: Spread::Stated,
    });
    let robust = fit(Loss::huber(1.345));
    assert_eq!(ls.report.down_weighted_rows, None);
    assert_eq!(stated.report.down_weighted_rows, Some(0));
    let p1 = |o: &kinecal::workflow::Outcome| o.report.parameters[0].estimated;
    assert!((p1(&stated) - p1(&ls)).abs() < 1e-9);
    // 180 rows: the 3 bad x rows and the Gaussian tail beyond 1.345 spreads (about 18 %).
    let n = robust.report.down_weighted_rows.unwrap();
    assert!((3..=60).contains(&n), "{n}");
    // link1.x was moved by +0.05 in: the robust fit finds it to 0.002 in, least squares is
    // pulled by the three bumped rows.
    let err = |o: &kinecal::workflow::Outcome| (p1(o) - (15.08 + 0.05)).abs();
    assert!(err(&robust) < 0.002, "robust {}", err(&robust));
    assert!(
        err(&robust) < 0.5 * err(&ls),
        "robust {} vs squared {}",
        err(&robust),
        err(&ls)
    );
    assert_eq!(robust.report.loss, "huber 1.345 x robust spread");
}

/// The Huber loss refits until its weights settle (or a refit moves the parameters by less than
/// 1e-3 of a standard deviation): the fit reports the iterations of every fit it ran (its log
/// holds each one), and one whose weights have not settled when the refits end is not
/// converged. Before, the count was the last refit's alone ("converged after 0 iterations" for
/// a fit that moved the objective from 2.7e3 to 1.9), and weights still moving after the last
/// refit ended "converged".
#[test]
fn huber_refits_count_their_iterations_and_unsettled_weights_are_not_converged() {
    use kinecal::solve::estimation::{Loss, Termination};
    let (nominal, mut data) = session();
    for k in [4, 11, 23] {
        if let kinecal::Observation::Pose(p) = &mut data.observations[k] {
            p.position.x += 0.05 * 0.0254;
        }
    }
    let fit = |loss: Loss, cap: Option<usize>| {
        let mut req = Request::new(nominal.clone(), data.clone());
        req.selection = Selection::parse("p1,p2,p8,p14,offsets,slopes", None, &nominal).unwrap();
        req.loss = loss;
        if let Some(cap) = cap {
            req.solver.max_iterations = cap;
        }
        workflow::run(&req, &mut ()).unwrap()
    };
    let squared = fit(Loss::Squared, None);
    let robust = fit(Loss::huber(1.345), None);
    for o in [&squared, &robust] {
        let c = &o.calibration;
        assert_eq!(c.iterations, c.log.len(), "{:?}", c.termination);
        assert_eq!(o.report.iterations, c.iterations);
        assert!(c.termination.converged(), "{:?}", c.termination);
    }
    // The robust fit refits after the least-squares one: more iterations in all.
    assert!(
        robust.calibration.iterations > squared.calibration.iterations,
        "{} vs {}",
        robust.calibration.iterations,
        squared.calibration.iterations
    );
    // A cap of one iteration per fit: the refits still settle, and the count is all of them.
    let capped = fit(Loss::huber(1.345), Some(1));
    let c = &capped.calibration;
    assert!(c.termination.converged(), "{:?}", c.termination);
    assert_eq!(c.iterations, c.log.len());
    assert!(c.iterations > 5, "{}", c.iterations);
    // A threshold of 0.01 spreads down-weights every row (least absolute deviations, where the
    // reweighting stagnates): after 100 refits each still moves the parameters by 2.3e-3 of a
    // standard deviation, no less than the one before, and the fit says so.
    let unsettled = fit(Loss::huber(0.01), None);
    let c = &unsettled.calibration;
    assert_eq!(c.termination, Termination::MaxIterations);
    assert!(!unsettled.report.converged);
    assert_eq!(c.iterations, c.log.len());
}

/// Folds partition the postures (each held out exactly once, linked postures together), and
/// cross-validation runs the same request on each: on clean data with known noise the held-out
/// mean is the noise's (a 3D Gaussian of 0.0005 in per axis: mean distance 0.0008 in), inside
/// its bootstrap interval, and every fold converges.
#[test]
fn cross_validation_folds_partition_the_postures_and_check_each() {
    let (nominal, data) = session();
    for seed in [None, Some(3)] {
        let folds = data.folds(5, seed).unwrap();
        assert_eq!(folds.len(), 5);
        let held: usize = folds.iter().map(|(_, h)| h.postures.len()).sum();
        assert_eq!(held, data.postures.len());
        let mut labels: Vec<String> = folds
            .iter()
            .flat_map(|(_, h)| h.postures.iter().map(|p| p.label.clone()))
            .collect();
        labels.sort();
        labels.dedup();
        assert_eq!(labels.len(), data.postures.len());
        for (t, h) in &folds {
            assert_eq!(t.postures.len() + h.postures.len(), data.postures.len());
        }
    }
    assert!(data.folds(1, None).is_none());
    assert!(data.folds(31, None).is_none());
    let mut req = Request::new(nominal.clone(), data);
    req.selection = Selection::parse("p1,p2,p8,p14,offsets,slopes", None, &nominal).unwrap();
    req.weights = Weights {
        length: 0.0005 * 0.0254,
        angle: 0.005f64.to_radians(),
    };
    req.validation = Validation::Folds { k: 5, seed: None };
    let out = workflow::run(&req, &mut ()).unwrap();
    let cv = out.cross_validation.as_ref().unwrap();
    assert_eq!(cv.folds.len(), 5);
    assert!(cv.folds.iter().all(|f| f.converged && f.postures == 6));
    assert_eq!(cv.overall.count, 30);
    let mean = cv.overall.mean / 0.0254;
    // Held-out errors include the fit's own error: between the noise's mean (0.0008 in) and
    // twice it.
    assert!((0.0006..0.0016).contains(&mean), "{mean}");
    let (lo, hi) = cv.mean_interval;
    assert!(lo < cv.overall.mean && cv.overall.mean < hi, "{lo} {hi}");
    let rep = out.report.cross_validation.as_ref().unwrap();
    assert!((rep.overall.mean - mean).abs() < 1e-12);
    assert_eq!(rep.metric, "position");
    // The calibration itself is made on all the data.
    assert_eq!(out.identification.postures, 30);
    // Bad fold counts are refused by name.
    req.validation = Validation::Folds { k: 99, seed: None };
    let e = workflow::run(&req, &mut ()).unwrap_err().to_string();
    assert!(e.contains("folds") && e.contains("99"), "{e}");
}

/// A model choice's timings add up: the chosen model's phases and the phase `model choice` (the
/// other candidates' fits, the repeated folds) sum to the wall time of the choice, within 10 %
/// (what lies outside the clock: the scoring and the report's few lines).
#[test]
fn model_choice_timings_add_up_to_its_wall_time() {
    use kinecal::workflow::{choose, Candidate};
    let nominal = examples::ge_a4();
    let mut truth = nominal.clone();
    let id = parse_param_list("p14", &nominal).unwrap()[0];
    truth.set(id, truth.get(id) + 0.001);
    let mut data = simulate::measure(&truth, &simulate::sample_postures(&nominal, 30, 4), true);
    simulate::add_noise(&mut data, 0.0005 * 0.0254, 0.0, 4);
    let mut req = Request::new(nominal.clone(), data);
    req.weights = Weights {
        length: 0.0005 * 0.0254,
        angle: 0.005f64.to_radians(),
    };
    let candidates = Candidate::defaults(&nominal).unwrap();
    let t = std::time::Instant::now();
    let choice = choose(&req, &candidates, 5, None, 2).unwrap();
    let wall = t.elapsed().as_secs_f64();
    let timings = &choice.outcome.report.timings;
    let sum: f64 = timings.iter().map(|t| t.seconds).sum();
    assert!(
        (sum - wall).abs() <= 0.1 * wall,
        "phases {sum:.4} s against {wall:.4} s of wall time: {timings:?}"
    );
    let choice_phase = timings.iter().find(|t| t.phase == "model choice");
    assert!(choice_phase.is_some_and(|t| t.seconds > 0.0), "{timings:?}");
}

/// Model choice by cross-validation: when a joint's gear ratio really changed (joint 4's slope
/// +0.02 deg/unit), the slope models earn their place and the geometric set is not chosen; when
/// only lengths and zeros changed, no slope is kept (the one-standard-error rule keeps the
/// simplest model the data cannot beat, and pruning drops what the data does not support).
#[test]
fn model_choice_keeps_slopes_only_when_the_data_earns_them() {
    use kinecal::workflow::{choose, Candidate};
    let nominal = examples::ge_a4();
    for slope_changed in [true, false] {
        let mut truth = nominal.clone();
        let mut changes = vec![("p1", 0.05), ("p14", -0.02), ("joint2.offset", -0.5)];
        if slope_changed {
            changes.push(("joint4.slope", 0.02));
        }
        for (name, delta) in changes {
            let id = parse_param_list(name, &nominal).unwrap()[0];
            let q = nominal.param_quantity(id);
            truth.set(id, truth.get(id) + nominal.units.to_si(q, delta));
        }
        let mut data = simulate::measure(&truth, &simulate::sample_postures(&nominal, 40, 9), true);
        simulate::add_noise(&mut data, 0.0005 * 0.0254, 0.0, 9);
        let mut req = Request::new(nominal.clone(), data);
        req.weights = Weights {
            length: 0.0005 * 0.0254,
            angle: 0.005f64.to_radians(),
        };
        let candidates = Candidate::defaults(&nominal).unwrap();
        let choice = choose(
            &req,
            &candidates,
            5,
            None,
            kinecal::workflow::CHOICE_REPEATS,
        )
        .unwrap();
        let label = &choice.scored[choice.chosen].candidate.label;
        if slope_changed {
            assert_ne!(label, "identifiable fix=slopes", "{:?}", choice.scored);
            // The geometric model cannot follow a gear-ratio change: far worse held out.
            assert!(choice.scored[0].mean > 3.0 * choice.scored[1].mean);
        } else {
            // No slope changed: no slope survives in the chosen model (the geometric set, or a
            // pruned one that dropped them: only p1, p14 and joint2.offset changed).
            let cal = &choice.outcome.calibration;
            let slopes = parse_param_list("slopes", &nominal).unwrap();
            assert!(
                cal.estimated.iter().all(|id| !slopes.contains(id)),
                "{label}: {:?}",
                cal.estimated
            );
        }
        let rep = &choice.outcome.report;
        assert_eq!(rep.model_choice.len(), 4);
        assert_eq!(rep.model_choice.iter().filter(|c| c.chosen).count(), 1);
        assert!(rep.cross_validation.is_some());
    }
    // Candidates are parsed with their options, and mistakes named.
    let c = Candidate::parse("identifiable,slopes  prune=3", &nominal).unwrap();
    assert_eq!(
        (c.label.as_str(), c.prune),
        ("identifiable,slopes prune=3", Some(3.0))
    );
    let e = Candidate::parse("links prune=-1", &nominal)
        .unwrap_err()
        .to_string();
    assert!(e.contains("prune=-1"), "{e}");
    let e = Candidate::parse("links fixx=slopes", &nominal)
        .unwrap_err()
        .to_string();
    assert!(e.contains("fixx=slopes"), "{e}");
}

/// The report clocks every phase that ran, in the order they first ran, and the phases a
/// progress display is told about are the same.
#[test]
fn the_report_gives_the_time_of_each_phase() {
    struct Seen(Vec<workflow::Phase>);
    impl workflow::Progress for Seen {
        fn phase(&mut self, p: workflow::Phase) {
            self.0.push(p);
        }
    }
    let (robot, data) = session();
    let mut req = Request::new(robot, data);
    req.selection = Selection::parse("identifiable", None, &req.robot).unwrap();
    req.validation = Validation::Folds { k: 3, seed: None };
    req.prediction = kinecal::predict::Level::Summary;
    let mut seen = Seen(Vec::new());
    let out = workflow::run(&req, &mut seen).unwrap();
    let names: Vec<&str> = out
        .report
        .timings
        .iter()
        .map(|t| t.phase.as_str())
        .collect();
    assert_eq!(
        names,
        [
            "preparation",
            "selection",
            "estimation",
            "uncertainty",
            "report",
            "cross-validation",
            "prediction"
        ]
    );
    let told: Vec<&str> = seen.0.iter().map(|p| p.as_str()).collect();
    assert_eq!(told, names[1..]);
    assert!(out
        .report
        .timings
        .iter()
        .all(|t| t.seconds.is_finite() && t.seconds >= 0.0));
    // The JSON report carries them.
    assert!(out.report.to_json().contains("\"timings\""));
}

/// The refusals a caller can act on are variants, with the message the command line prints.
#[test]
fn refusals_a_caller_can_act_on_are_typed() {
    let (nominal, data) = session();
    let empty = Request::new(nominal.clone(), kinecal::Dataset::default());
    let e = workflow::run(&empty, &mut ()).unwrap_err();
    assert!(matches!(e, kinecal::Error::NoObservations), "{e:?}");
    assert_eq!(e.to_string(), "no observations to calibrate from");

    let mut other = Request::new(nominal.clone(), data);
    let mut guess = nominal.clone();
    guess.joints[0].kind = match guess.joints[0].kind {
        kinecal::JointKind::Revolute => kinecal::JointKind::Prismatic,
        kinecal::JointKind::Prismatic => kinecal::JointKind::Revolute,
    };
    other.initial = Some(guess);
    let e = workflow::run(&other, &mut ()).unwrap_err();
    assert!(
        matches!(e, kinecal::Error::OtherStructure { robot } if robot == "the initial guess"),
        "{e:?}"
    );
    assert_eq!(
        e.to_string(),
        "the initial guess does not have the nominal robot's structure (joints, couplings, sites, \
         planes)"
    );
}
