use super::*;

/// The GE A4 of the thesis, read from the example file (the `examples` module comes after this
/// one in the library's layers).
fn ge_a4() -> Robot {
    crate::model::robot_file::parse_robot_toml(
        include_str!("../../../../examples/robots/ge_a4.toml"),
        "ge_a4.toml",
    )
    .unwrap()
}
use crate::model::kinematics::Target;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, StandardNormal};

/// A covariance over the GE A4's first parameters, positive definite (internal units).
fn some_covariance(n: usize, seed: u64) -> Vec<Vec<f64>> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let a: Vec<Vec<f64>> = (0..n)
        .map(|_| (0..n).map(|_| rng.random_range(-1e-3..1e-3)).collect())
        .collect();
    (0..n)
        .map(|i| {
            (0..n)
                .map(|j| {
                    (0..n).map(|k| a[i][k] * a[j][k]).sum::<f64>() + if i == j { 1e-8 } else { 0.0 }
                })
                .collect()
        })
        .collect()
}

#[test]
fn the_parameter_part_is_the_covariance_through_a_finite_difference_jacobian() {
    let robot = ge_a4();
    let ids: Vec<ParamId> = [0usize, 1, 7, 13, 30, 31, 34, 37, 3, 10]
        .iter()
        .map(|&k| ParamId(k))
        .collect();
    let cov = some_covariance(ids.len(), 1);
    let metric = JointMetric::new(&robot, &vec![0.3; robot.dof()]);
    let measured = [vec![0.0; robot.dof()]];
    let pr = Predictor::new(
        &robot,
        &ids,
        &cov,
        ModelError::none(true),
        metric,
        measured.iter().map(Vec::as_slice),
    )
    .unwrap();
    let mut s = pr.scratch();
    let readings = [-6.883, 13.301, 4.122, -28.645];
    let (p, a, _) = pr.parameter_part(&readings, Target::EndEffector, &mut s);
    // Central differences of the position and of the attitude (rotation vector of R R0^T).
    let h = 1e-6;
    let f0 = crate::model::kinematics::Chain::new(&robot).frame_at(&readings, Target::EndEffector);
    let jfd: Vec<[f64; 6]> = ids
        .iter()
        .map(|&id| {
            let at = |step: f64| {
                let mut r = robot.clone();
                r.set(id, robot.get(id) + step);
                crate::model::kinematics::Chain::new(&r).frame_at(&readings, Target::EndEffector)
            };
            let (fp, fm) = (at(h), at(-h));
            let dp = (fp.translation - fm.translation) / (2.0 * h);
            let w = (crate::model::kinematics::log_so3(&(fp.rotation * f0.rotation.transpose()))
                - crate::model::kinematics::log_so3(&(fm.rotation * f0.rotation.transpose())))
                / (2.0 * h);
            [dp.x, dp.y, dp.z, w.x, w.y, w.z]
        })
        .collect();
    for i in 0..3 {
        for j in 0..3 {
            let sum = |oi: usize, oj: usize| -> f64 {
                (0..ids.len())
                    .map(|a| {
                        (0..ids.len())
                            .map(|b| jfd[a][oi] * cov[a][b] * jfd[b][oj])
                            .sum::<f64>()
                    })
                    .sum()
            };
            let (ep, ea) = (sum(i, j), sum(3 + i, 3 + j));
            assert!(
                (p[i][j] - ep).abs() <= 1e-6 * (ep.abs() + p[0][0].abs()),
                "{i}{j}: {} {ep}",
                p[i][j]
            );
            assert!(
                (a[i][j] - ea).abs() <= 1e-6 * (ea.abs() + a[0][0].abs()),
                "{i}{j}: {} {ea}",
                a[i][j]
            );
        }
    }
    // And the bound: the parameters alone, then with a model error that dominates (isotropic:
    // 2.7955 times its per-axis sigma).
    let b = Bound::of(&p, 0.0, 3.0);
    assert!((b.parameters - (p[0][0] + p[1][1] + p[2][2]).sqrt()).abs() < 1e-15);
    let big = Bound::of(&p, 1e6 * (p[0][0] + p[1][1] + p[2][2]), 3.0);
    assert!((big.bound / big.model * 3f64.sqrt() - 2.795_483).abs() < 1e-3);
}

#[test]
fn maximum_likelihood_recovers_a_known_growing_term() {
    // Held-out errors drawn from the model itself: s0 = 0.3 mm, c = 2e-3 (0.2 mm more per 10 cm
    // of distance), parameter parts of varied shape, distances 0..0.5 m.
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
    let truth = Growth {
        s0: 3e-4,
        c: 2e-3,
        shape: 3.0,
    };
    let samples: Vec<HeldOut> = (0..4000)
        .map(|_| {
            let d: f64 = rng.random_range(0.0..0.5);
            let l: [f64; 3] = std::array::from_fn(|_| rng.random_range(0.0..(2e-4f64).powi(2)));
            let v = truth.variance(d);
            let e: [f64; 3] = std::array::from_fn(|k| {
                let z: f64 = StandardNormal.sample(&mut rng);
                z * (l[k] + v).sqrt()
            });
            let mut p = [[0.0; 3]; 3];
            for k in 0..3 {
                p[k][k] = l[k];
            }
            HeldOut::new(d, e, p, Target::EndEffector)
        })
        .collect();
    let fit = fit_growth(&samples);
    // 4000 points of 3 components: the estimates' relative standard errors are a few percent.
    assert!(
        (fit.growth.s0 / truth.s0 - 1.0).abs() < 0.08,
        "{:?}",
        fit.growth
    );
    assert!(
        (fit.growth.c / truth.c - 1.0).abs() < 0.08,
        "{:?}",
        fit.growth
    );
    // Drawn from the model, the 95 % bounds cover 95 % (binomial sd 0.34 %).
    assert!((fit.coverage - 0.95).abs() < 0.012, "{}", fit.coverage);
    // A single variance covers the near postures too much and the far ones too little; the
    // parameters alone cover little.
    assert!(fit.coverage_parameters_only < 0.5);
    // With no growth in the data, c comes out small.
    let flat: Vec<HeldOut> = samples
        .iter()
        .map(|h| {
            let v = truth.variance(h.distance);
            let r = (truth.s0 * truth.s0 / v).sqrt();
            HeldOut {
                error: h.error.map(|x| x * r),
                ..*h
            }
        })
        .collect();
    let f2 = fit_growth(&flat);
    assert!(f2.growth.c * 0.25 < 0.2 * f2.growth.s0, "{:?}", f2.growth);
    // A floor above the likelihood's s0 holds s0 there and fits c again (smaller: the floor
    // covers some of the far errors' variance); a floor below it changes nothing.
    let floored = fit_growth_floored(&samples, 2.0 * truth.s0);
    assert!(
        (floored.growth.s0 - 2.0 * truth.s0).abs() < 1e-15,
        "{:?}",
        floored.growth
    );
    assert!(
        floored.growth.c <= fit.growth.c * 1.0001,
        "{:?}",
        floored.growth
    );
    assert!(floored.growth.c > 0.5 * truth.c, "{:?}", floored.growth);
    assert_eq!(
        fit_growth_floored(&samples, 0.1 * truth.s0).growth,
        fit.growth
    );
}

/// Pixels' errors across their lines of sight (two components, parameter parts of varied
/// shape there) drawn from a known term: the same likelihood recovers it, and the bound of two
/// components covers 95 % of them. The three-component bound would cover more (its quantile is
/// that of three components: 2.80 sigma against 2.45), which is what the two-component one is
/// for.
#[test]
fn a_known_term_is_recovered_from_pixels_across_their_lines_of_sight() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
    let truth = Growth {
        s0: 2e-4,
        c: 1e-3,
        shape: 3.0,
    };
    let samples: Vec<HeldOut> = (0..4000)
        .map(|_| {
            let d: f64 = rng.random_range(0.0..0.5);
            // A parameter part of two components, turned by a random angle.
            let (a, b): (f64, f64) = (
                rng.random_range(0.0..(2e-4f64).powi(2)),
                rng.random_range(0.0..(5e-5f64).powi(2)),
            );
            let t: f64 = rng.random_range(0.0..std::f64::consts::PI);
            let (c, s) = (t.cos(), t.sin());
            let v = truth.variance(d);
            let (z1, z2): (f64, f64) = (
                StandardNormal.sample(&mut rng),
                StandardNormal.sample(&mut rng),
            );
            let (e1, e2) = (z1 * (a + v).sqrt(), z2 * (b + v).sqrt());
            let lateral = pixel::Lateral {
                posture: 0,
                target: Target::EndEffector,
                error: [c * e1 - s * e2, s * e1 + c * e2],
                parameters: [
                    [c * c * a + s * s * b, c * s * (a - b)],
                    [c * s * (a - b), s * s * a + c * c * b],
                ],
            };
            HeldOut::across(&lateral, d)
        })
        .collect();
    let fit = fit_growth(&samples);
    // 4000 points of 2 components: relative standard errors of a few percent.
    assert!(
        (fit.growth.s0 / truth.s0 - 1.0).abs() < 0.08,
        "{:?}",
        fit.growth
    );
    assert!(
        (fit.growth.c / truth.c - 1.0).abs() < 0.08,
        "{:?}",
        fit.growth
    );
    // Binomial sd 0.34 %; the moment-matched quantile is within 1.5 % of the exact one.
    assert!((fit.coverage - 0.95).abs() < 0.015, "{}", fit.coverage);
    // The shape is of three-component errors only: none here, so isotropic.
    assert_eq!(fit.growth.shape.to_bits(), 3f64.to_bits());
    // The bound of two components of variance v each is 2.4477 sigma (chi-square, 2 degrees of
    // freedom); the three-component bound of the same variance per axis is 2.7955.
    let b = Bound::across(&[[0.0; 3]; 3], 1.0);
    assert!((b.bound - 2.447_747).abs() < 1e-4, "{}", b.bound);
}

#[test]
fn a_report_of_another_robot_or_a_broken_one_is_refused() {
    let robot = ge_a4();
    let report = PredictionReport {
        target: "ee".into(),
        estimated: vec!["p1".into(), "p2".into()],
        covariance: vec![vec![1e-6, 0.0], vec![0.0, 1e-6]],
        levers: vec![1.0; 4],
        measured: vec![vec![0.0; 4]],
        position: GrowthReport {
            s0: 0.001,
            s0_floor: 0.0,
            c: 0.01,
            shape: 3.0,
            points: 10,
            coverage: 0.95,
            coverage_constant: 0.9,
            s0_constant: 0.001,
            coverage_parameters_only: 0.1,
            distance_median: 1.0,
            distance_max: 2.0,
        },
        attitude: None,
        targets: Vec::new(),
        folds: vec![5, 3],
        samples: 10,
        position_summary: BoundSummary {
            median: 0.0,
            p95: 0.0,
            median_measured: 0.0,
        },
        attitude_summary: None,
        map: None,
    };
    assert!(from_report(&robot, &report).is_ok());
    let mut r = report.clone();
    r.levers = vec![1.0; 6];
    assert!(from_report(&robot, &r)
        .unwrap_err()
        .to_string()
        .contains("6 joint levers"));
    let mut r = report.clone();
    r.covariance[1][0] = f64::NAN;
    assert!(from_report(&robot, &r)
        .unwrap_err()
        .to_string()
        .contains("not finite"));
    let mut r = report.clone();
    r.estimated[1] = "p99".into();
    assert!(from_report(&robot, &r).is_err());
    let mut r = report.clone();
    r.position.c = -1.0;
    assert!(from_report(&robot, &r)
        .unwrap_err()
        .to_string()
        .contains("non-negative"));
    let mut r = report;
    r.measured = vec![vec![0.0; 3]];
    assert!(from_report(&robot, &r)
        .unwrap_err()
        .to_string()
        .contains("3 readings"));
}
