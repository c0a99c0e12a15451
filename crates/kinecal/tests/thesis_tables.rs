//! The thesis's printed tables (Goswami 1988, chapter 4) reproduced on the built-in GE A4.

mod common;

use kinecal::model::kinematics::{forward_pose, Chain, Target, Workspace};
use kinecal::solve::estimation::{calibrate, CalibrationOptions};
use kinecal::{apps::simulate, model::examples, parse_param_list, ParamId, Robot};

/// Table 4.2: joint voltages and EECF poses (in, deg) of ten postures.
const TABLE_4_2: [([f64; 4], [f64; 6]); 10] = [
    (
        [-11.053, 12.369, 4.009, -11.583],
        [14.071, 19.083, 0.177, -69.233, 0.000, -90.000],
    ),
    (
        [-12.696, 9.037, 1.493, 5.156],
        [6.098, 14.220, 3.669, 175.940, 0.000, -90.000],
    ),
    (
        [-13.197, 9.964, 3.714, -1.898],
        [5.120, 15.465, 0.590, -123.644, 0.000, -90.000],
    ),
    (
        [-6.883, 13.301, 4.122, -28.645],
        [28.576, 13.995, 0.020, 47.600, 0.000, -90.000],
    ),
    (
        [-8.793, 12.922, 3.391, -20.333],
        [21.851, 17.546, 1.042, -10.730, 0.000, -90.000],
    ),
    (
        [-9.353, 6.637, 1.760, 11.523],
        [12.889, 13.330, 3.326, 111.850, 0.000, -90.000],
    ),
    (
        [-8.917, 11.267, 1.496, 5.202],
        [20.452, 16.645, 3.695, 132.262, 0.000, -90.000],
    ),
    (
        [-6.367, 12.479, 1.369, -4.141],
        [30.381, 14.222, 3.873, -170.732, 0.000, -90.000],
    ),
    (
        [-6.034, 12.081, 0.159, -11.348],
        [30.125, 14.500, 5.567, -105.410, 0.000, -90.000],
    ),
    (
        [-6.420, 6.843, 0.314, -14.182],
        [20.507, 14.236, 5.350, -39.404, 0.000, -90.000],
    ),
];

fn user_pose(robot: &Robot, v: &[f64]) -> [f64; 6] {
    let p = forward_pose(robot, v, Target::EndEffector);
    let inch = 0.0254;
    [
        p.position.x / inch,
        p.position.y / inch,
        p.position.z / inch,
        p.euler.x.to_degrees(),
        p.euler.y.to_degrees(),
        p.euler.z.to_degrees(),
    ]
}

#[test]
fn table_4_2_forward_kinematics() {
    let robot = examples::ge_a4();
    let mut checked = 0;
    for (i, (v, printed)) in TABLE_4_2.iter().enumerate() {
        let got = user_pose(&robot, v);
        for k in 0..6 {
            if i == 1 && k == 2 {
                continue; // posture 2's z is a misprint (3.669 for 3.700), see NOTES.md
            }
            // Printed to 3 decimals from voltages printed to 3 decimals: 0.01 in / 0.01 deg.
            let mut d = got[k] - printed[k];
            if k >= 3 {
                d = (d + 180.0).rem_euclid(360.0) - 180.0;
            }
            assert!(
                d.abs() < 0.01,
                "posture {} component {k}: model {} printed {}",
                i + 1,
                got[k],
                printed[k]
            );
            checked += 1;
        }
    }
    assert_eq!(checked, 59);
}

/// Forward-difference Jacobian of the user-unit pose (in, deg->rad rows) with step `h` in the
/// parameter's unit (in or rad).
fn forward_difference(robot: &Robot, v: &[f64], id: ParamId, h: f64) -> [f64; 6] {
    let inch = 0.0254;
    let is_len = robot.param_quantity(id) == kinecal::units::Quantity::Length;
    let step_si = if is_len { h * inch } else { h };
    let mut r2 = robot.clone();
    r2.set(id, robot.get(id) + step_si);
    let (a, b) = (user_pose(robot, v), user_pose(&r2, v));
    let mut out = [0.0; 6];
    for k in 0..6 {
        let mut d = b[k] - a[k];
        if k >= 3 {
            d = ((d + 180.0).rem_euclid(360.0) - 180.0).to_radians();
        }
        out[k] = d / h;
    }
    out
}

/// Table 4.3, third block (posture 1 of Table 4.2; radians, inches). 44 of its 48 entries equal
/// the analytic Jacobian to print precision. The other 4 (y and z against p4, p5, p6) differ by up
/// to 0.07: the thesis differentiated numerically, and a forward difference with a step of
/// about 0.28 deg (fitted: 0.26-0.29 deg all work) reproduces every printed entry, those 4 included, while the analytic values agree with
/// a central difference. So the test checks the analytic Jacobian against the table where the
/// thesis's truncation error is below print precision, and checks that the table is the forward
/// difference of this same model everywhere.
#[test]
fn table_4_3_jacobian_of_posture_1() {
    // Rows x, y, z, alpha, beta, gamma; columns p1, p2, p3, p4, p5, p6, p14, p29.
    let printed: [[f64; 8]; 6] = [
        [1.00, 0.00, 0.00, -27.58, -10.36, 0.00, -0.30, 0.00],
        [0.00, 1.00, 0.00, -1.08, 0.00, -10.43, 0.95, 0.00],
        [0.00, 0.00, 1.00, 0.00, 1.03, -27.56, 0.00, 0.00],
        [0.00, 0.00, 0.00, 1.00, 0.00, 0.00, 0.00, 0.00],
        [0.00, 0.00, 0.00, 0.00, 0.35, -0.93, 0.00, -1.00],
        [0.00, 0.00, 0.00, 0.00, -0.93, -0.35, 0.00, 0.00],
    ];
    let cols = [1, 2, 3, 4, 5, 6, 14, 29];
    let robot = examples::ge_a4();
    let v = &TABLE_4_2[0].0;
    let chain = Chain::new(&robot);
    let mut ws = Workspace::new(&robot);
    chain.forward(v, &mut ws);
    let mut block = vec![0.0; 6 * robot.param_count()];
    chain.jacobian(&ws, Target::EndEffector, &mut block);
    let pose = chain.target_frame(&ws, Target::EndEffector).pose();
    let inch = 0.0254;
    let mut analytic_matches = 0;
    for (c, &p) in cols.iter().enumerate() {
        let id = ParamId(p - 1);
        let col = kinecal::model::kinematics::block_column(&block, id);
        let is_length = robot.param_quantity(id) == kinecal::units::Quantity::Length;
        let per = if is_length { inch } else { 1.0 };
        let w = nalgebra::Vector3::new(col[3], col[4], col[5]);
        let e = kinecal::model::kinematics::euler_rates(pose.euler.x, pose.euler.y, &w);
        let analytic = [
            col[0] / inch * per,
            col[1] / inch * per,
            col[2] / inch * per,
            e.x * per,
            e.y * per,
            e.z * per,
        ];
        // Lengths enter linearly, so their step does not matter; 0.28 deg for angles.
        let fd = forward_difference(
            &robot,
            v,
            id,
            if is_length { 0.3 } else { 0.28f64.to_radians() },
        );
        for r in 0..6 {
            // Printed to 2 decimals: 0.005, plus 1e-4 for the 3-decimal voltages.
            let tol = 0.0051;
            assert!(
                (fd[r] - printed[r][c]).abs() <= tol,
                "forward difference row {r} p{p}: {:.4} vs {}",
                fd[r],
                printed[r][c]
            );
            let truncation = (fd[r] - analytic[r]).abs();
            assert!(
                (analytic[r] - printed[r][c]).abs() <= tol + truncation,
                "analytic row {r} p{p}: {:.4} vs printed {} (thesis truncation {truncation:.4})",
                analytic[r],
                printed[r][c]
            );
            if (analytic[r] - printed[r][c]).abs() <= tol {
                analytic_matches += 1;
            }
        }
    }
    assert_eq!(analytic_matches, 44);
}

#[test]
fn eq_4_1_holds_at_nominal() {
    let r = examples::ge_a4();
    let g = |p: usize| r.get_user(ParamId(p - 1));
    let s = g(3) - (g(9) + g(15) + g(21) + g(27) + g(33));
    assert!((s - 5.79).abs() < 1e-12, "{s}");
}

/// Table 4.8: from each run's printed initial guesses, with only p1, p3, p9, p10, p15, p21, p27,
/// p33 estimated, LM returns p1 = 15.08 and p10 = 0, the objective to ~0, and eq. 4.1 holds.
#[test]
fn table_4_8_levenberg_marquardt_runs() {
    let runs = common::TABLE_4_8_GUESSES;
    let nominal = examples::ge_a4();
    let ids = parse_param_list(common::TABLE_4_8_PARAMS, &nominal).unwrap();
    let postures = simulate::sample_postures(&nominal, 30, 1988);
    let data = simulate::measure(&nominal, &postures, false);
    let printed_final: [Option<[f64; 6]>; 5] = [
        Some([10.09, -0.49, 0.71, 0.91, 2.91, 0.26]),
        Some([11.87, -0.47, 0.53, 1.33, 4.12, 0.57]),
        None,
        Some([12.44, 1.16, 0.16, 1.56, 3.06, 0.71]),
        Some([11.86, -0.47, 0.52, 1.32, 4.13, 0.57]),
    ];
    for (k, run) in runs.into_iter().enumerate() {
        let mut start = nominal.clone();
        for (&id, &v) in ids.iter().zip(&run) {
            let q = start.param_quantity(id);
            start.set(id, start.units.to_si(q, v));
        }
        let cal = calibrate(
            &start,
            &data,
            &CalibrationOptions::new(ids.clone()),
            &mut |_| {},
        )
        .unwrap();
        let c = &cal.calibrated;
        let g = |p: usize| c.get_user(ParamId(p - 1));
        assert!(cal.converged());
        assert!(
            cal.objective_after < 1e-12 * cal.objective_before,
            "{} -> {}",
            cal.objective_before,
            cal.objective_after
        );
        assert!((g(1) - 15.08).abs() < 1e-6, "p1 = {}", g(1));
        assert!(g(10).abs() < 1e-6, "p10 = {}", g(10));
        let sum = g(3) - (g(9) + g(15) + g(21) + g(27) + g(33));
        assert!((sum - 5.79).abs() < 1e-6, "eq. 4.1: {sum}");
        // The redundant members did move away from their starting guesses.
        assert!((g(3) - run[1]).abs() > 1e-3);
        // Marquardt's scaling gives identical columns identical steps, so LM shares the change of
        // the sum equally among the group's members, as the thesis's runs 1, 2, 4 and 5 did: their
        // printed redundant values are reproduced to 0.015 (runs 1 and 4 exactly to 2 decimals; the
        // thesis's own split in runs 2 and 5 deviates from equal by up to 0.013). Run 3's is not
        // (p33 moves 0.42 while the others move 0.03), so no path-independent check applies.
        if let Some(expected) = printed_final[k] {
            for (p, e) in [3, 9, 15, 21, 27, 33].iter().zip(expected) {
                assert!(
                    (g(*p) - e).abs() <= 0.015,
                    "run {} p{p}: {} vs printed {e}",
                    k + 1,
                    g(*p)
                );
            }
        }
    }
}
