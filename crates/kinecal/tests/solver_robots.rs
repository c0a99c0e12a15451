//! The solver on calibration problems that defeated it before: rows whose standard deviations
//! differ by a factor of 10^7 or more within one file, and random robots started far from the
//! answer. Convergence is a claim about the point reached: it must be the lowest any start
//! finds.

use kinecal::apps::simulate::{self, PerturbStd};
use kinecal::identifiability::{analyze, AnalysisOptions};
use kinecal::model::robot::JointKind;
use kinecal::observe::{Dataset, Observation};
use kinecal::solve::estimation::{calibrate, CalibrationOptions};
use kinecal::{ParamId, Robot};

/// Position data of `truth` (noise `noise` m on every row), the rows `anchors` measured exactly
/// and given a standard deviation of `anchor_sigma` m of their own.
fn anchored_data(
    truth: &Robot,
    postures: usize,
    noise: f64,
    anchors: &[usize],
    anchor_sigma: f64,
    seed: u64,
) -> Dataset {
    let ps = simulate::sample_postures(truth, postures, seed);
    let exact = simulate::measure(truth, &ps, true);
    let mut data = exact.clone();
    simulate::add_noise(&mut data, noise, 0.0, seed + 1);
    for &k in anchors {
        data.observations[k] = exact.observations[k].clone();
        if let Observation::Position(p) = &mut data.observations[k] {
            p.sigma_position = Some(nalgebra::Vector3::repeat(anchor_sigma));
        }
    }
    data
}

/// 3 anchor rows with a standard deviation of 1e-6, 1e-7 and 1e-8 mm among 37 rows of 0.05 mm
/// (ratios of 5 x 10^4 to 5 x 10^6, squared up to 2.5 x 10^13 in `J^T J`): the default solver
/// converges in at most 50 iterations, honours the anchors to 1e-4 mm, and reaches the
/// objective a start at the truth reaches. The other rows' information must survive the
/// anchors' weight: the fit's error on them stays at their noise. (At 1e-9 mm the anchors are
/// equality constraints in all but name, and the first steps, made for them alone, can land
/// on another local minimum of the constrained problem: a genuine one, where the linear model
/// predicts no reduction.)
#[test]
fn anchor_rows_a_billion_times_more_precise_are_honoured() {
    let nominal = simulate::random_robot(&[JointKind::Revolute; 4], 11);
    let truth = simulate::perturb(
        &nominal,
        PerturbStd {
            length: 0.002,
            angle: 0.005,
            slope_fraction: 0.0,
        },
        12,
    );
    let anchors = [3, 17, 29];
    for anchor_sigma in [1e-9, 1e-10, 1e-11] {
        let data = anchored_data(&truth, 40, 5e-5, &anchors, anchor_sigma, 13);
        // The identifiable geometric parameters (slopes held): a unique answer.
        let all: Vec<ParamId> = nominal
            .param_ids()
            .filter(|&id| !matches!(nominal.param_kind(id), kinecal::ParamKind::Slope { .. }))
            .collect();
        let base = analyze(&nominal, &data, &all, &AnalysisOptions::default())
            .unwrap()
            .identifiable;
        let mut opts = CalibrationOptions::new(base.clone());
        opts.weights.length = 5e-5;
        let cal = calibrate(&nominal, &data, &opts, &mut |_| {}).unwrap();
        assert!(
            cal.converged() && cal.iterations <= 50,
            "sigma {anchor_sigma}: {:?} after {} iterations",
            cal.termination,
            cal.iterations
        );
        let from_truth = calibrate(&truth, &data, &opts, &mut |_| {}).unwrap();
        eprintln!(
            "anchors at {anchor_sigma} m: {:?} after {} iterations, objective {:.6e} (from the \
             truth {:.6e})",
            cal.termination, cal.iterations, cal.objective_after, from_truth.objective_after
        );
        assert!(
            cal.objective_after <= from_truth.objective_after * (1.0 + 1e-6) + 1e-9,
            "sigma {anchor_sigma}: {} ({:?}, {} iterations, {:?}) vs {} from the truth ({:?})",
            cal.objective_after,
            cal.termination,
            cal.iterations,
            cal.stationarity,
            from_truth.objective_after,
            from_truth.termination
        );
        let chain = kinecal::Chain::new(&cal.calibrated);
        let mut worst_other: f64 = 0.0;
        for (k, o) in data.observations.iter().enumerate() {
            let Observation::Position(p) = o else {
                unreachable!()
            };
            let at = chain.frame_at(&data.postures[p.view[0].posture].readings, p.view[0].target);
            let e = (at.translation - p.position).norm();
            if anchors.contains(&k) {
                assert!(e < 1e-7, "sigma {anchor_sigma}: anchor {k} off by {e} m");
            } else {
                worst_other = worst_other.max(e);
            }
        }
        assert!(worst_other < 5e-4, "{worst_other}");
    }
}

/// Random robots, each calibrated from five starts (the nominal and four far ones: lengths
/// off by 5 cm, angles by 0.1 rad): every run that reports convergence has reached the lowest
/// objective any start reached (to 1e-7 relative), and at least the nominal start converges.
#[test]
fn no_run_converges_above_the_lowest_objective_any_start_reaches() {
    let mut checked = 0;
    for seed in 0..12u64 {
        let kinds = match seed % 3 {
            0 => vec![JointKind::Revolute; 6],
            1 => vec![
                JointKind::Revolute,
                JointKind::Prismatic,
                JointKind::Revolute,
                JointKind::Revolute,
            ],
            _ => vec![JointKind::Revolute; 5],
        };
        let nominal = simulate::random_robot(&kinds, 100 + seed);
        let truth = simulate::perturb(
            &nominal,
            PerturbStd {
                length: 0.003,
                angle: 0.01,
                slope_fraction: 0.0,
            },
            200 + seed,
        );
        let ps = simulate::sample_postures(&nominal, 40, 300 + seed);
        let position_only = seed % 2 == 0;
        let mut data = simulate::measure(&truth, &ps, position_only);
        simulate::add_noise(&mut data, 1e-4, 2e-4, 400 + seed);
        let geometric: Vec<ParamId> = nominal
            .param_ids()
            .filter(|&id| !matches!(nominal.param_kind(id), kinecal::ParamKind::Slope { .. }))
            .collect();
        let base = analyze(&nominal, &data, &geometric, &AnalysisOptions::default())
            .unwrap()
            .identifiable;
        let mut runs = Vec::new();
        for start in 0..5u64 {
            let initial = if start == 0 {
                nominal.clone()
            } else {
                let mut far = simulate::perturb(
                    &nominal,
                    PerturbStd {
                        length: 0.05,
                        angle: 0.1,
                        slope_fraction: 0.0,
                    },
                    500 + 10 * seed + start,
                );
                // Only the estimated parameters start elsewhere.
                for id in nominal.param_ids() {
                    if !base.contains(&id) {
                        far.set(id, nominal.get(id));
                    }
                }
                far
            };
            let cal = calibrate(
                &initial,
                &data,
                &CalibrationOptions::new(base.clone()),
                &mut |_| {},
            )
            .unwrap();
            runs.push((start, cal));
        }
        let best = runs
            .iter()
            .map(|(_, c)| c.objective_after)
            .fold(f64::INFINITY, f64::min);
        assert!(
            runs[0].1.converged(),
            "seed {seed}: the nominal start did not converge"
        );
        for (start, cal) in &runs {
            if cal.converged() {
                checked += 1;
                assert!(
                    cal.objective_after <= best * (1.0 + 1e-7),
                    "seed {seed}, start {start}: converged ({:?}, {} iterations) at {} while {best} is reachable",
                    cal.termination,
                    cal.iterations,
                    cal.objective_after
                );
            }
        }
    }
    assert!(checked >= 40, "only {checked} converged runs");
}

/// A stand-in for an ABB IRB 120 measured by another lab: 108 positions at 0.2 mm noise under
/// the default weights (1 mm) and 5 more measured exactly and stated at 0.001 mm (a weight
/// ratio of 1,000), the identifiable set estimated from a start 5 cm and 0.1 rad off. Every run
/// ends where a start at the truth ends (to 1e-6 relative), within 15 iterations, the anchors
/// honoured to 0.01 mm. Before the staged start (uniform weights first, then the stated ones),
/// one of these runs "converged" at 3,300 times the optimum (a point where the model had lost
/// a rank), one stopped at the cap at 8 times it, and two took 39 and 71 iterations.
#[test]
fn anchored_rows_from_a_far_start_reach_the_optimum() {
    use kinecal::workflow::{self, Request, Selection};
    for seed in 0..10u64 {
        let nominal = simulate::random_robot(&[JointKind::Revolute; 6], 1000 + seed);
        let truth = simulate::perturb(
            &nominal,
            PerturbStd {
                length: 0.003,
                angle: 0.01,
                slope_fraction: 0.0,
            },
            2000 + seed,
        );
        let ps = simulate::sample_postures(&nominal, 113, 3000 + seed);
        let exact = simulate::measure(&truth, &ps, true);
        let mut data = exact.clone();
        simulate::add_noise(&mut data, 2e-4, 0.0, 4000 + seed);
        for k in 108..113 {
            data.observations[k] = exact.observations[k].clone();
            if let Observation::Position(p) = &mut data.observations[k] {
                p.sigma_position = Some(nalgebra::Vector3::repeat(1e-6));
            }
        }
        let start = simulate::perturb(
            &nominal,
            PerturbStd {
                length: 0.05,
                angle: 0.1,
                slope_fraction: 0.0,
            },
            5000 + seed,
        );
        let run = |initial: &Robot| {
            let mut req = Request::new(initial.clone(), data.clone());
            req.selection = Selection::parse("identifiable", None, &nominal).unwrap();
            workflow::run(&req, &mut ()).unwrap()
        };
        let (out, best) = (run(&start), run(&truth));
        let (c, b) = (&out.calibration, &best.calibration);
        assert!(
            c.converged() && c.iterations <= 15,
            "seed {seed}: {:?} after {}",
            c.termination,
            c.iterations
        );
        assert!(
            c.objective_after <= b.objective_after * (1.0 + 1e-6),
            "seed {seed}: {} where the truth's start reaches {}",
            c.objective_after,
            b.objective_after
        );
        let chain = kinecal::Chain::new(&c.calibrated);
        for k in 108..113 {
            let Observation::Position(p) = &data.observations[k] else {
                unreachable!()
            };
            let at = chain.frame_at(&data.postures[p.view[0].posture].readings, p.view[0].target);
            let e = (at.translation - p.position).norm();
            assert!(e < 1e-5, "seed {seed}: anchor {k} off by {e} m");
        }
        // The anchors fit their sigmas: no model-error floor.
        let m = c.model_error.expect("rows with their own sigma");
        assert_eq!((m.length, m.angle), (0.0, 0.0), "seed {seed}");
    }
}

/// Random 6R robots started far away (every length 0.5 m and every angle 1 rad off, at
/// random): no run ends "converged" above the objective a start at the truth reaches. A fit
/// whose positions end unfit (beyond 2 % of the reach) is tried again from the closed-form
/// placement and a few well-spread starts, the best kept, and says what it tried; one that
/// still ends unfit is "stalled at a local minimum", not converged, and warned about.
/// Before the restarts, 8 of these 20 runs said "converged" at 10^6-10^7 times the optimum
/// (flagged as unfit, but converged; 10 at the optimum, 2 at the cap); before that flag, they
/// said so with exit 0.
#[test]
fn a_local_minimum_far_above_the_optimum_is_never_called_a_calibration() {
    use kinecal::workflow::{self, Request, Selection};
    use kinecal::Warning;
    let (mut optimum, mut restarted_to_optimum, mut said, mut above) = (0, 0, 0, 0);
    for seed in 0..20u64 {
        let nominal = simulate::random_robot(&[JointKind::Revolute; 6], 1000 + seed);
        let truth = simulate::perturb(
            &nominal,
            PerturbStd {
                length: 0.003,
                angle: 0.01,
                slope_fraction: 0.0,
            },
            2000 + seed,
        );
        let ps = simulate::sample_postures(&nominal, 50, 3000 + seed);
        let mut data = simulate::measure(&truth, &ps, seed % 2 == 0);
        simulate::add_noise(&mut data, 1e-4, 2e-4, 4000 + seed);
        let start = simulate::perturb(
            &nominal,
            PerturbStd {
                length: 0.5,
                angle: 1.0,
                slope_fraction: 0.0,
            },
            5000 + seed,
        );
        let run = |initial: &Robot| {
            let mut req = Request::new(initial.clone(), data.clone());
            req.selection = Selection::parse("", None, &nominal).unwrap();
            workflow::run(&req, &mut ())
        };
        let at_truth = run(&truth).unwrap();
        assert!(
            !at_truth
                .warnings
                .iter()
                .any(|w| matches!(w, Warning::Restarted { .. })),
            "seed {seed}: a fit at the truth restarted"
        );
        let best = at_truth.calibration.objective_after;
        let out = run(&start).unwrap();
        let c = &out.calibration;
        let unfit = out
            .warnings
            .iter()
            .any(|w| matches!(w, Warning::PositionsUnfit { .. }));
        let restarted = out.warnings.iter().find_map(|w| match w {
            Warning::Restarted { starts, kept } => Some((starts, kept)),
            _ => None,
        });
        if let Some((starts, kept)) = restarted {
            // Every start tried is listed, the given one first, the kept one the lowest.
            assert_eq!(starts[0].start, "given", "seed {seed}");
            assert!(starts.len() >= 9, "seed {seed}: {starts:?}");
            let lowest = starts
                .iter()
                .map(|s| s.objective)
                .fold(f64::INFINITY, f64::min);
            let kept = starts
                .iter()
                .find(|s| &s.start == kept)
                .expect("kept is listed");
            assert_eq!(kept.objective.to_bits(), lowest.to_bits(), "seed {seed}");
            assert!(
                (c.total_objective() - lowest).abs() <= 1e-9 * lowest,
                "seed {seed}"
            );
        }
        let at_optimum = c.objective_after <= best * (1.0 + 1e-6);
        if c.converged() && at_optimum {
            optimum += 1;
            restarted_to_optimum += usize::from(restarted.is_some());
            assert!(
                !unfit,
                "seed {seed}: at the optimum, yet {:?}",
                out.warnings
            );
        } else if !c.converged() {
            said += 1;
            eprintln!(
                "seed {seed}: {:?} at {:.3e} times the optimum",
                c.termination,
                c.objective_after / best
            );
            if c.termination == kinecal::solve::estimation::Termination::LocalMinimum {
                assert!(
                    unfit && restarted.is_some() && out.warnings.iter().any(|w| w.implausible()),
                    "seed {seed}: {:?}",
                    out.warnings
                );
            }
        } else {
            above += 1;
            eprintln!(
                "seed {seed}: converged ({:?}) at {} where {best} is reachable",
                c.termination, c.objective_after
            );
        }
    }
    eprintln!(
        "far starts: {optimum} converged at the optimum ({restarted_to_optimum} of them after a \
         restart), {said} not converged and said so, {above} \"converged\" above it"
    );
    assert_eq!(above, 0, "runs called converged above the optimum");
    assert!(optimum >= 12, "{optimum}");
}
