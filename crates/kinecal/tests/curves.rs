//! Characteristic curves against the thesis's figures (4.2-4.11) and known invariants.
#![allow(clippy::needless_range_loop)] // pose components are indexed by number, as in the thesis

use kinecal::apps::curves::{
    is_convex, local_minima, objective_curve, period, pose_curve, samples,
};
use kinecal::model::kinematics::Target;
use kinecal::observe::Posture;
use kinecal::observe::{OrientationError, Weights};
use kinecal::{apps::simulate, model::examples, ParamId};

const P1: [f64; 4] = [-11.053, 12.369, 4.009, -11.583];
const P2: [f64; 4] = [-12.696, 9.037, 1.493, 5.156];
const P4: [f64; 4] = [-6.883, 13.301, 4.122, -28.645];

fn nominal(id: ParamId) -> f64 {
    examples::ge_a4().get_user(id)
}

#[test]
fn linear_parameters_give_straight_lines_and_leave_the_attitude_alone() {
    let robot = examples::ge_a4();
    for p in [1, 2, 3, 8, 14, 26, 33] {
        let id = ParamId(p - 1);
        let x = samples(nominal(id) - 50.0, nominal(id) + 50.0, 101);
        let c = pose_curve(&robot, &P4, Target::EndEffector, id, &x);
        for w in c.windows(3) {
            for k in 0..3 {
                assert!(
                    (w[0][k] - 2.0 * w[1][k] + w[2][k]).abs() < 1e-9,
                    "p{p} component {k} is not a straight line"
                );
            }
            for k in 3..6 {
                assert!(
                    (w[0][k] - w[2][k]).abs() < 1e-9,
                    "p{p} changes the attitude"
                );
            }
        }
    }
}

#[test]
fn angles_and_revolute_offsets_repeat_every_turn() {
    let robot = examples::ge_a4();
    for p in [4, 5, 6, 16, 28, 29, 31, 32, 34] {
        let id = ParamId(p - 1);
        assert_eq!(period(&robot, id, None), Some(360.0));
        let x0 = nominal(id) - 5.0;
        let a = pose_curve(&robot, &P4, Target::EndEffector, id, &[x0, x0 + 360.0]);
        for k in 0..3 {
            assert!((a[0][k] - a[1][k]).abs() < 1e-9, "p{p}");
        }
    }
    // A prismatic offset is not periodic.
    assert_eq!(period(&robot, ParamId(32), None), None);
}

#[test]
fn slope_of_joint_1_at_posture_4_has_period_52_303() {
    let robot = examples::ge_a4();
    let id = ParamId(34); // p35
    let t = period(&robot, id, Some(&P4)).unwrap();
    assert!((t - 52.303).abs() < 0.001, "{t}");
    let x = samples(nominal(id) - 50.0, nominal(id) + 50.0, 41);
    let shifted: Vec<f64> = x.iter().map(|v| v + t).collect();
    let (a, b) = (
        pose_curve(&robot, &P4, Target::EndEffector, id, &x),
        pose_curve(&robot, &P4, Target::EndEffector, id, &shifted),
    );
    for (u, v) in a.iter().zip(&b) {
        for k in 0..3 {
            assert!((u[k] - v[k]).abs() < 1e-9);
        }
    }
}

/// Fig 4.11: the objective against p38 (joint 4's slope) for postures 1 and 2 of Table 4.2.
#[test]
fn p38_objective_valleys_fig_4_11() {
    let robot = examples::ge_a4();
    let id = ParamId(37);
    let one = |v: [f64; 4], label: &str| {
        simulate::measure(
            &robot,
            &[Posture {
                label: label.into(),
                readings: v.to_vec(),
                session: None,
                payload: None,
            }],
            false,
        )
    };
    let (d1, d2) = (one(P1, "1"), one(P2, "2"));
    let both = simulate::measure(
        &robot,
        &[
            Posture {
                label: "1".into(),
                readings: P1.to_vec(),
                session: None,
                payload: None,
            },
            Posture {
                label: "2".into(),
                readings: P2.to_vec(),
                session: None,
                payload: None,
            },
        ],
        false,
    );
    let (w, o) = (Weights::default(), OrientationError::Euler);
    assert!((period(&robot, id, Some(&P1)).unwrap() - 31.08).abs() < 0.01);
    assert!((period(&robot, id, Some(&P2)).unwrap() - 69.819).abs() < 0.01);
    // Each posture alone repeats with its period.
    for (d, t) in [(&d1, 360.0 / 11.583), (&d2, 360.0 / 5.156)] {
        let x = samples(-20.0, 20.0, 41);
        let xs: Vec<f64> = x.iter().map(|v| v + t).collect();
        let (a, b) = (
            objective_curve(&robot, d, id, &x, w, o),
            objective_curve(&robot, d, id, &xs, w, o),
        );
        for (u, v) in a.iter().zip(&b) {
            assert!((u - v).abs() <= 1e-6 * u.abs().max(1.0), "{u} vs {v}");
        }
    }
    // Together, within 50 deg/V of 9.0: zero only at 9.0, every other valley above zero.
    let x = samples(9.0 - 50.0, 9.0 + 50.0, 20001);
    let f = objective_curve(&robot, &both, id, &x, w, o);
    let minima = local_minima(&x, &f);
    assert!(minima.len() > 2, "several valleys expected");
    let zero: Vec<_> = minima.iter().filter(|m| m.1 < 1e-12).collect();
    assert_eq!(zero.len(), 1);
    assert!((zero[0].0 - 9.0).abs() < 0.01);
    let others = minima
        .iter()
        .filter(|m| (m.0 - 9.0).abs() > 0.01)
        .map(|m| m.1)
        .fold(f64::INFINITY, f64::min);
    assert!(others > 1.0, "a false valley reaches {others}");
    assert!(!is_convex(&f));
}

#[test]
fn noise_free_objective_is_zero_at_the_truth_for_every_parameter() {
    let robot = examples::ge_a4();
    let data = simulate::measure(&robot, &simulate::sample_postures(&robot, 10, 4), false);
    for id in robot.param_ids() {
        let v = robot.get_user(id);
        let span = match robot.param_quantity(id) {
            kinecal::units::Quantity::Length => 1.0,
            kinecal::units::Quantity::Angle => 5.0,
            _ => 0.1,
        };
        let x = samples(v - span, v + span, 201);
        let f = objective_curve(
            &robot,
            &data,
            id,
            &x,
            Weights::default(),
            OrientationError::Euler,
        );
        let (k, fmin) =
            f.iter().enumerate().fold(
                (0, f64::INFINITY),
                |a, (i, &y)| if y < a.1 { (i, y) } else { a },
            );
        assert!(fmin < 1e-18, "{}: minimum {fmin}", robot.param_name(id));
        assert!(
            (x[k] - v).abs() < 1e-9,
            "{}: minimum at {} not {v}",
            robot.param_name(id),
            x[k]
        );
    }
}

#[test]
fn euler_angles_have_no_false_jumps() {
    let robot = examples::ge_a4();
    let id = ParamId(3); // p4, swept over 370 deg as in Fig 4.5
    let x = samples(-5.0, 365.0, 371);
    let c = pose_curve(&robot, &P4, Target::EndEffector, id, &x);
    for w in c.windows(2) {
        for k in 3..6 {
            assert!(
                (w[1][k] - w[0][k]).abs() < 5.0,
                "jump in angle {k}: {} -> {}",
                w[0][k],
                w[1][k]
            );
        }
    }
    // At the nominal value the angles are the pose's own: Table 4.2 posture 4, alpha 47.6.
    let k = x.iter().position(|v| v.abs() < 1e-9).unwrap();
    assert!((c[k][3] - 47.6).abs() < 0.01, "{}", c[k][3]);
}
