//! Calibration recovers a perturbed robot from noise-free data; solvers behave on singular
//! problems; results do not depend on the file's units.

use kinecal::apps::simulate::{self, PerturbStd};
use kinecal::model::kinematics::{forward_pose, Target};
use kinecal::observe::OrientationError;
use kinecal::solve::estimation::{calibrate, CalibrationOptions, Method, SolverOptions};
use kinecal::{model::examples, parse_param_list, Error, JointKind, ParamId, Robot};

fn truth_and_nominal() -> (Robot, Robot) {
    let kinds = [
        JointKind::Revolute,
        JointKind::Revolute,
        JointKind::Prismatic,
        JointKind::Revolute,
        JointKind::Revolute,
        JointKind::Revolute,
    ];
    let nominal = simulate::random_robot(&kinds, 2024);
    let std = PerturbStd {
        length: 2e-3,
        angle: 0.5f64.to_radians(),
        slope_fraction: 0.005,
    };
    (simulate::perturb(&nominal, std, 7), nominal)
}

/// Largest position (mm) and attitude (deg) difference between two robots on fresh postures.
fn held_out_error(a: &Robot, b: &Robot) -> (f64, f64) {
    let postures = simulate::sample_postures(a, 50, 999);
    let (mut dp, mut da) = (0.0f64, 0.0f64);
    for p in &postures {
        let fa = kinecal::Chain::new(a).frame_at(&p.readings, Target::EndEffector);
        let fb = kinecal::Chain::new(b).frame_at(&p.readings, Target::EndEffector);
        dp = dp.max((fa.translation - fb.translation).norm() * 1e3);
        let r = fa.rotation.transpose() * fb.rotation;
        da = da.max(kinecal::model::kinematics::log_so3(&r).norm().to_degrees());
    }
    let _ = forward_pose;
    (dp, da)
}

fn run(
    method: Method,
    estimate: Vec<ParamId>,
    nominal: &Robot,
    data: &kinecal::Dataset,
) -> kinecal::Calibration {
    let mut opts = CalibrationOptions::new(estimate);
    opts.solver = SolverOptions::new(method);
    calibrate(nominal, data, &opts, &mut |_| {}).expect("calibration runs")
}

#[test]
fn lm_and_svd_recover_all_54_parameters() {
    let (truth, nominal) = truth_and_nominal();
    assert_eq!(nominal.param_count(), 54);
    let postures = simulate::sample_postures(&nominal, 40, 11);
    let data = simulate::measure(&truth, &postures, false);
    let all: Vec<ParamId> = nominal.param_ids().collect();
    for method in [Method::LevenbergMarquardt, Method::Svd] {
        let cal = run(method, all.clone(), &nominal, &data);
        assert!(cal.converged(), "{method:?}: {:?}", cal.termination);
        assert!(
            cal.objective_after < 1e-12 * cal.objective_before,
            "{method:?}: objective {} -> {}",
            cal.objective_before,
            cal.objective_after
        );
        let (dp, da) = held_out_error(&cal.calibrated, &truth);
        assert!(
            dp < 1e-6 && da < 1e-6,
            "{method:?}: held-out error {dp} mm, {da} deg"
        );
        for v in cal.calibrated.param_ids().map(|id| cal.calibrated.get(id)) {
            assert!(v.is_finite());
        }
    }
}

#[test]
fn gauss_newton_recovers_offsets_and_refuses_a_singular_system() {
    let (_, nominal) = truth_and_nominal();
    let offsets = parse_param_list("offsets", &nominal).unwrap();
    let mut truth = nominal.clone();
    for (k, &id) in offsets.iter().enumerate() {
        truth.set(id, truth.get(id) + 0.002 * (k as f64 + 1.0));
    }
    let postures = simulate::sample_postures(&nominal, 20, 3);
    let data = simulate::measure(&truth, &postures, false);
    let cal = run(Method::GaussNewton, offsets.clone(), &nominal, &data);
    assert!(cal.objective_after < 1e-12 * cal.objective_before);
    let (dp, da) = held_out_error(&cal.calibrated, &truth);
    assert!(dp < 1e-6 && da < 1e-6, "held-out {dp} mm {da} deg");

    // All 54 parameters: J^T J is singular, and Gauss-Newton says so.
    let all: Vec<ParamId> = nominal.param_ids().collect();
    let mut opts = CalibrationOptions::new(all);
    opts.solver = SolverOptions::new(Method::GaussNewton);
    match calibrate(&nominal, &data, &opts, &mut |_| {}) {
        Err(Error::SingularNormalEquations {
            rank, parameters, ..
        }) => {
            assert_eq!(parameters, 54);
            // 5 nr + 3 np + 6 = 5*5 + 3 + 6 = 34 (thesis eq. 4.2).
            assert_eq!(rank, 34);
        }
        other => panic!("expected a singular-system error, got {other:?}"),
    }
}

#[test]
fn steepest_descent_reduces_the_objective() {
    let nominal = examples::ge_a4();
    let ids = parse_param_list("p1,p2,p3", &nominal).unwrap();
    let mut truth = nominal.clone();
    truth.set(ids[0], truth.get(ids[0]) + 0.01);
    truth.set(ids[1], truth.get(ids[1]) - 0.005);
    let data = simulate::measure(&truth, &simulate::sample_postures(&nominal, 10, 1), false);
    let cal = run(Method::SteepestDescent, ids, &nominal, &data);
    // Position-only parameters with unit Jacobian columns: steepest descent in the scaled space
    // is exact for translations of the base, so it converges quickly.
    assert!(
        cal.objective_after < 1e-12 * cal.objective_before,
        "{}",
        cal.objective_after
    );
}

#[test]
fn rank_deficient_lm_stays_finite_on_the_full_ge_a4() {
    let nominal = examples::ge_a4();
    let std = PerturbStd {
        length: 0.01 * 0.0254,
        angle: 0.2f64.to_radians(),
        slope_fraction: 0.001,
    };
    let truth = simulate::perturb(&nominal, std, 5);
    let data = simulate::measure(&truth, &simulate::sample_postures(&nominal, 30, 2), false);
    let all: Vec<ParamId> = nominal.param_ids().collect();
    for method in [Method::LevenbergMarquardt, Method::Svd] {
        let cal = run(method, all.clone(), &nominal, &data);
        assert!(cal.converged());
        assert!(
            cal.objective_after < 1e-12 * cal.objective_before,
            "{method:?} {}",
            cal.objective_after
        );
        assert!(cal
            .calibrated
            .param_ids()
            .all(|id| cal.calibrated.get(id).is_finite()));
    }
}

fn to_units(robot: &Robot, length: kinecal::LengthUnit, angle: kinecal::AngleUnit) -> Robot {
    let mut r = robot.clone();
    r.units = kinecal::Units { length, angle };
    r
}

#[test]
fn results_do_not_depend_on_units() {
    use kinecal::files::{parse_measurements, write_measurements};
    use kinecal::model::robot_file::{parse_robot_toml, write_robot_toml};
    let nominal = examples::ge_a4();
    let std = PerturbStd {
        length: 0.02 * 0.0254,
        angle: 0.3f64.to_radians(),
        slope_fraction: 0.0,
    };
    let truth = simulate::perturb(&nominal, std, 9);
    let mut data = simulate::measure(&truth, &simulate::sample_postures(&nominal, 30, 4), false);
    simulate::add_noise(&mut data, 0.001 * 0.0254, 0.01f64.to_radians(), 4);
    let ids = parse_param_list("p1-p3,p7,p8,p14,p31,p32,p33,p34,p35-p38", &nominal).unwrap();
    let mut results = Vec::new();
    for (l, a) in [
        (kinecal::LengthUnit::In, kinecal::AngleUnit::Deg),
        (kinecal::LengthUnit::Mm, kinecal::AngleUnit::Rad),
        (kinecal::LengthUnit::M, kinecal::AngleUnit::Deg),
    ] {
        // Through the files, as a user in these units would do it.
        let r = to_units(&nominal, l, a);
        let robot = parse_robot_toml(&write_robot_toml(&r, None), "robot.toml").unwrap();
        let d = parse_measurements(&write_measurements(&robot, &data), "data.csv", &robot).unwrap();
        for orientation in [OrientationError::Euler, OrientationError::RotVec] {
            let mut opts = CalibrationOptions::new(ids.clone());
            opts.orientation = orientation;
            let cal = calibrate(&robot, &d, &opts, &mut |_| {}).unwrap();
            results.push((
                orientation,
                cal.objective_after,
                ids.iter()
                    .map(|&id| cal.calibrated.get(id))
                    .collect::<Vec<_>>(),
            ));
        }
    }
    for w in results.chunks(2).collect::<Vec<_>>().windows(2) {
        for (a, b) in w[0].iter().zip(w[1]) {
            assert!(
                (a.1 - b.1).abs() <= 1e-9 * a.1.max(1e-300),
                "objective {} vs {}",
                a.1,
                b.1
            );
            for (x, y) in a.2.iter().zip(&b.2) {
                // Same SI values to 1 nm / 1 nrad (/unit): the solver stops when the objective
                // changes by 1e-12 relative, which pins parameters to ~1e-6 of their statistical
                // uncertainty (here ~1e-5 m), far below this tolerance.
                assert!((x - y).abs() <= 1e-9, "{x} vs {y}");
            }
        }
    }
}

#[test]
fn too_few_residuals_is_an_error() {
    let nominal = examples::ge_a4();
    let data = simulate::measure(&nominal, &simulate::sample_postures(&nominal, 2, 1), true);
    let all: Vec<ParamId> = nominal.param_ids().collect();
    let err = calibrate(&nominal, &data, &CalibrationOptions::new(all), &mut |_| {}).unwrap_err();
    assert!(err.to_string().contains("6 residuals"), "{err}");
}

#[test]
fn position_only_data_leaves_unseen_parameters_alone() {
    // With positions only, the tool frame's attitude (the last link's three angles) has no
    // effect on any residual: the solver must not move those parameters.
    let (truth, nominal) = truth_and_nominal();
    let data = simulate::measure(&truth, &simulate::sample_postures(&nominal, 40, 5), true);
    let all: Vec<ParamId> = nominal.param_ids().collect();
    let cal = run(Method::LevenbergMarquardt, all, &nominal, &data);
    assert!(cal.objective_after < 1e-12 * cal.objective_before);
    for p in 6 * 6 + 3..6 * 6 + 6 {
        // Exactly unchanged: the solver zeroes these columns, so their steps are exactly 0.
        let (a, b) = (cal.calibrated.get(ParamId(p)), nominal.get(ParamId(p)));
        assert!(
            a.to_bits() == b.to_bits(),
            "{}: {a} vs {b}",
            nominal.param_name(ParamId(p))
        );
        // And the calibration says so.
        assert!(cal.unfelt.contains(&ParamId(p)), "{:?}", cal.unfelt);
    }
}

#[test]
fn a_method_that_stops_where_lm_still_descends_is_stalled_not_converged() {
    // Truncated SVD that drops every direction below half the largest singular value converges
    // within the directions it keeps; Levenberg-Marquardt from there goes further down.
    let nominal = examples::ge_a4();
    let ids = parse_param_list("p1,p2,p8,p14,offsets", &nominal).unwrap();
    let mut truth = nominal.clone();
    for (k, &id) in ids.iter().enumerate() {
        truth.set(id, truth.get(id) + 1e-3 * (k as f64 - 2.5));
    }
    let data = simulate::measure(&truth, &simulate::sample_postures(&nominal, 30, 3), false);
    let mut opts = CalibrationOptions::new(ids.clone());
    opts.solver = SolverOptions::new(Method::Svd);
    opts.solver.rcond = 0.5;
    let cal = calibrate(&nominal, &data, &opts, &mut |_| {}).unwrap();
    assert_eq!(
        cal.termination,
        kinecal::solve::estimation::Termination::Stalled
    );
    assert!(!cal.converged());
    // Levenberg-Marquardt on the same problem converges to the truth.
    let lm = run(Method::LevenbergMarquardt, ids, &nominal, &data);
    assert!(lm.converged());
    assert!(lm.objective_after < 1e-9 * cal.objective_after);
    // Gauss-Newton, a well-posed problem: converged, not stalled.
    let offsets = parse_param_list("offsets", &nominal).unwrap();
    let gn = run(Method::GaussNewton, offsets, &nominal, &data);
    assert!(gn.converged(), "{:?}", gn.termination);
}
