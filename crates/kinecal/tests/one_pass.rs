//! The workflow reuses evaluations instead of running forward kinematics again: the uncertainty
//! comes from the solver's first evaluation at the start, the outliers from the fit's final
//! residuals. What it reports must be what fresh passes give.

use kinecal::apps::simulate::{self, PerturbStd};
use kinecal::observe::Observation;
use kinecal::workflow::{self, Request, Selection};
use kinecal::{JointKind, ParamId};

fn data(position_only: bool, seed: u64) -> (kinecal::Robot, kinecal::Dataset) {
    let nominal = simulate::random_robot(&[JointKind::Revolute; 6], seed);
    let std = PerturbStd {
        length: 1e-3,
        angle: 0.2f64.to_radians(),
        slope_fraction: 0.001,
    };
    let truth = simulate::perturb(&nominal, std, seed + 1);
    let postures = simulate::sample_postures(&nominal, 80, seed + 2);
    let mut data = simulate::measure(&truth, &postures, position_only);
    simulate::add_noise(&mut data, 2e-5, 2e-5, seed + 3);
    (nominal, data)
}

/// On a redundant problem (all 54 parameters of a 6R arm, rank below 54, with noise), the
/// reported uncertainty is a fresh analysis's at the start.
#[test]
fn the_uncertainty_from_the_solvers_start_is_a_fresh_passs() {
    let (nominal, data) = data(false, 5);
    let mut req = Request::new(nominal.clone(), data.clone());
    req.selection = Selection::List(nominal.param_ids().collect::<Vec<ParamId>>());
    let out = workflow::run(&req, &mut ()).unwrap();
    let reused = out.uncertainty.as_ref().unwrap();
    let fresh = kinecal::uncertainty::uncertainty(&out.calibration, &data, &nominal).unwrap();
    assert!(reused.analysis.rank < 54);
    assert_eq!(reused.analysis.rank, fresh.analysis.rank);
    assert_eq!(reused.analysis.identifiable, fresh.analysis.identifiable);
    assert_eq!(reused.combinations.len(), fresh.combinations.len());
    assert_eq!(
        reused.variance_factor.to_bits(),
        fresh.variance_factor.to_bits()
    );
    // The two evaluations differ only in how the joint angles' sines and cosines are formed
    // (the solver's table of the readings' against sin_cos of the sum): rounding, 1e-16
    // relative, grown by the problem's conditioning (below 1e6 here) to well under 1e-8.
    for (a, b) in reused.parameters.iter().zip(&fresh.parameters) {
        assert_eq!(a.determined, b.determined, "{}", a.id);
        if let (Some(sa), Some(sb)) = (a.sigma, b.sigma) {
            assert!((sa - sb).abs() <= 1e-8 * sb, "{}: {sa} against {sb}", a.id);
        }
    }
    for (a, b) in reused.combinations.iter().zip(&fresh.combinations) {
        assert!((a.sigma - b.sigma).abs() <= 1e-8 * b.sigma);
    }
}

/// With another start (`initial`), the solver's start is not the reference of the solution
/// rule's minimum change: the uncertainty is then taken at the nominal robot, as a fresh pass
/// there gives it.
#[test]
fn another_start_is_not_mistaken_for_the_reference() {
    let (nominal, data) = data(false, 15);
    let mut req = Request::new(nominal.clone(), data.clone());
    let mut initial = nominal.clone();
    let id = nominal.param_ids().next().unwrap();
    initial.set(id, nominal.get(id) + 1e-3);
    req.initial = Some(initial);
    req.solution = workflow::SolutionRule::MinChange;
    let out = workflow::run(&req, &mut ()).unwrap();
    let reused = out.uncertainty.as_ref().unwrap();
    let fresh = kinecal::uncertainty::uncertainty(&out.calibration, &data, &nominal).unwrap();
    for (a, b) in reused.parameters.iter().zip(&fresh.parameters) {
        assert_eq!(a.sigma, b.sigma, "{}", a.id);
    }
}

/// The fit's own final residuals flag the same observations, by the same amounts, as a fresh
/// pass of forward kinematics at the calibrated robot.
#[test]
fn the_outliers_from_the_fits_residuals_are_a_fresh_passs() {
    let (nominal, mut data) = data(true, 8);
    for i in [5, 40, 77] {
        if let Observation::Position(p) = &mut data.observations[i] {
            p.position.x += 1e-3;
        }
    }
    let req = Request::new(nominal.clone(), data.clone());
    let out = workflow::run(&req, &mut ()).unwrap();
    let fresh = kinecal::solve::outliers::outliers(&out.calibration, &data, req.outlier_sigmas);
    let found: Vec<usize> = out.outliers.iter().map(|o| o.observation).collect();
    // The gross errors, and whatever least squares smeared them into.
    assert!([5, 40, 77].iter().all(|i| found.contains(i)), "{found:?}");
    assert_eq!(
        found,
        fresh.iter().map(|o| o.observation).collect::<Vec<_>>()
    );
    for (a, b) in out.outliers.iter().zip(&fresh) {
        assert!((a.sigmas - b.sigmas).abs() <= 1e-9 * b.sigmas);
    }
}

/// `--estimate identifiable`: the solver starts from the linearisation the identifiability
/// analysis made over all candidates (no first pass of its own). The fit, its iterations and
/// its uncertainty are those of the same parameters estimated directly.
#[test]
fn the_identifiable_fit_starts_from_the_analysis_linearisation() {
    let (nominal, data) = data(false, 21);
    let mut req = Request::new(nominal.clone(), data.clone());
    req.selection = Selection::Identifiable {
        with: Vec::new(),
        fix: Vec::new(),
    };
    let out = workflow::run(&req, &mut ()).unwrap();
    let chosen = out.calibration.estimated.clone();
    assert!(chosen.len() < 54);
    let direct = kinecal::solve::estimation::calibrate(
        &nominal,
        &data,
        &kinecal::solve::estimation::CalibrationOptions::new(chosen.clone()),
        &mut |_| {},
    )
    .unwrap();
    assert_eq!(out.calibration.iterations, direct.iterations);
    let (a, b) = (
        out.calibration.accuracy_before.rms_position,
        direct.accuracy_before.rms_position,
    );
    assert!((a - b).abs() <= 1e-12 * b, "{a} against {b}");
    // The first step comes from R restricted by a small QR instead of a pass: the same to
    // rounding, which the iterations do not amplify (a well-determined problem).
    for &id in &chosen {
        let (a, b) = (
            out.calibration.calibrated.get(id),
            direct.calibrated.get(id),
        );
        assert!(
            (a - b).abs() <= 1e-9 * (1.0 + b.abs()),
            "{id}: {a} against {b}"
        );
    }
    let fresh = kinecal::uncertainty::uncertainty(&direct, &data, &nominal).unwrap();
    for (a, b) in out
        .uncertainty
        .as_ref()
        .unwrap()
        .parameters
        .iter()
        .zip(&fresh.parameters)
    {
        if let (Some(sa), Some(sb)) = (a.sigma, b.sigma) {
            assert!((sa - sb).abs() <= 1e-8 * sb, "{}: {sa} against {sb}", a.id);
        }
    }
}

/// The outlier threshold grows with the number of rows tested: 4 standard deviations is a
/// large value among a few hundred rows and an ordinary one among a million.
#[test]
fn the_outlier_threshold_grows_with_the_rows_tested() {
    use kinecal::solve::outliers::threshold;
    // Without a floor: the two-sided normal quantile with rows * P(|z| > t) = 0.1 (values of
    // scipy.stats.norm.isf: 1.6449 at 10 %, 2.5758 at 1 %, 4.8916 at 1e-6).
    for (rows, t) in [
        (1, 1.6448536269514722),
        (10, 2.5758293035489004),
        (100_000, 4.891638475698553),
    ] {
        assert!(
            (threshold(0.0, rows) - t).abs() < 1e-9,
            "{rows}: {}",
            threshold(0.0, rows)
        );
    }
    // The floor stands for small data, the quantile takes over for large.
    assert_eq!(threshold(4.0, 1000).to_bits(), 4.0f64.to_bits());
    assert!((threshold(4.0, 3000) - 4.15).abs() < 0.01);
    assert!((threshold(4.0, 6_000_000) - 5.6435).abs() < 1e-3);
    // Monotone in the rows.
    let mut last = 0.0;
    for rows in [1, 10, 100, 1000, 10_000, 100_000, 1_000_000, 100_000_000] {
        let t = threshold(0.0, rows);
        assert!(t > last);
        last = t;
    }
}

/// Clean data of 40,000 residual rows (Gaussian noise only): no outlier (at a fixed 4 sigmas
/// about 2.5 rows would be flagged); a gross error among them is still found.
#[test]
fn clean_data_of_many_rows_shows_no_outlier_and_a_gross_error_still_shows() {
    let nominal = kinecal::apps::simulate::random_robot(&[JointKind::Revolute; 6], 31);
    let std = PerturbStd {
        length: 1e-3,
        angle: 0.2f64.to_radians(),
        slope_fraction: 0.0,
    };
    let truth = kinecal::apps::simulate::perturb(&nominal, std, 32);
    let postures = kinecal::apps::simulate::sample_postures(&nominal, 13_334, 33);
    let mut data = kinecal::apps::simulate::measure(&truth, &postures, true);
    kinecal::apps::simulate::add_noise(&mut data, 2e-5, 0.0, 34);
    let req = Request::new(nominal.clone(), data.clone());
    let out = workflow::run(&req, &mut ()).unwrap();
    assert!(out.outliers.is_empty(), "{} flagged", out.outliers.len());
    assert!(out.report.outlier_sigmas > 4.5);
    if let Observation::Position(p) = &mut data.observations[777] {
        p.position.y += 4e-4; // 20 standard deviations
    }
    let out = workflow::run(&Request::new(nominal, data), &mut ()).unwrap();
    let found: Vec<usize> = out.outliers.iter().map(|o| o.observation).collect();
    assert_eq!(found, vec![777]);
}
