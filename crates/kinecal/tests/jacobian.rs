//! The analytic Jacobian against central differences, on random robots of 1 to 7 joints of
//! random kinds, with sites, slopes, coupled joints, a plane and a measurement session with a
//! frame of its own, full poses, positions, distances and plane contacts, rows with their own
//! standard deviations (per axis too), and both orientation residuals.

use kinecal::model::kinematics::{euler_zyx, forward_pose, rot_zyx, Target};
use kinecal::observe::contact::Contact;
use kinecal::observe::distance::Distance;
use kinecal::observe::{Observation, OrientationError, Weights};
use kinecal::solve::problem::Problem;
use kinecal::{apps::simulate, JointKind, Link, ParamId, Robot, Site};
use nalgebra::Vector3;
use rand::{RngExt, SeedableRng};

fn robot_with_sites(dof: usize, seed: u64) -> Robot {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let kinds: Vec<JointKind> = (0..dof)
        .map(|_| {
            if rng.random_range(0.0..1.0) < 0.3 {
                JointKind::Prismatic
            } else {
                JointKind::Revolute
            }
        })
        .collect();
    let mut robot = simulate::random_robot(&kinds, seed);
    // One or two sites on random joints.
    for s in 0..(1 + seed as usize % 2) {
        robot.sites.push(Site {
            name: format!("s{s}"),
            joint: rng.random_range(1..=dof),
            frame: Link {
                x: 0.05,
                y: -0.1,
                z: 0.2,
                alpha: 0.3,
                beta: -0.4,
                gamma: 1.0,
            },
        });
    }
    // A tilted plane for contacts, away from the origin.
    robot.planes.push(
        kinecal::model::robot::Plane::new("table", Vector3::new(0.2, -0.3, 1.0), 0.4).unwrap(),
    );
    robot.planes[0].tilt_x = 0.05;
    robot.planes[0].tilt_y = -0.1;
    // A session measured from elsewhere: its poses and positions seen through its frame.
    robot.sessions.push(kinecal::model::robot::Session {
        name: "far".into(),
        frame: Link {
            x: 1.5,
            y: -0.7,
            z: 0.3,
            alpha: 0.8,
            beta: -0.3,
            gamma: 0.5,
        },
    });
    // Most robots of two joints or more get a coupled joint (like the FANUC J2/J3 coupling).
    if dof >= 2 && seed % 3 != 0 {
        let last = dof - 1;
        robot.joints[last].coupling = Some(kinecal::model::robot::Coupling {
            joint: seed as usize % last,
            factor: 0.6,
        });
    }
    robot
}

/// Measurements near (not at) the model's poses, so orientation residuals are non-zero; rows
/// at beta within ~6 deg of +-90 are dropped for the Euler check (the Euler map is singular
/// there, and differences would not resolve its derivative). Some rows are positions, some
/// carry their own standard deviations, and distances join consecutive postures.
fn data_for(robot: &Robot, seed: u64, euler: bool) -> kinecal::Dataset {
    let postures = simulate::sample_postures(robot, 6, seed);
    let mut data = simulate::measure(robot, &postures, false);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed + 99);
    for (i, o) in data.observations.iter_mut().enumerate() {
        let Observation::Pose(p) = o else { continue };
        p.position += Vector3::new(0.01, -0.02, 0.015);
        let r = rot_zyx(p.euler.x, p.euler.y, p.euler.z)
            * rot_zyx(rng.random_range(-0.3..0.3), 0.2, -0.1);
        p.euler = euler_zyx(&r);
        if i % 3 == 1 {
            p.sigma_position = Some(Vector3::new(2e-4, 5e-4, 3e-4));
            p.sigma_angle = Some(3e-3);
        }
        if i % 4 == 3 {
            *o = p.to_position().into(); // some position-only rows
        }
    }
    if euler {
        data.observations.retain(|o| match o {
            Observation::Pose(p) => p.euler.y.cos() > 0.1,
            _ => true,
        });
    }
    // Every other posture in the session with a frame of its own.
    for (k, p) in data.postures.iter_mut().enumerate() {
        if k % 2 == 0 {
            p.session = Some("far".into());
        }
    }
    for a in 0..postures.len() - 1 {
        let mut d = Distance::new(a, a + 1, Target::EndEffector, 0.3);
        d.sigma = (a % 2 == 0).then_some(5e-4);
        data.observations.push(d.into());
        let mut c = Contact::new(a, Target::Site(0), 0);
        c.gap = 0.01;
        c.sigma = (a % 2 == 1).then_some(2e-4);
        data.observations.push(c.into());
    }
    kinecal::Dataset::new(data.postures, data.observations)
}

fn check(robot: &Robot, data: &kinecal::Dataset, mode: OrientationError) {
    let ids: Vec<ParamId> = robot.param_ids().collect();
    let w = Weights::default();
    let problem = Problem::new(robot, data, &ids, w, mode);
    let m = problem.rows();
    let mut r = vec![0.0; m];
    let mut jac = kinecal::linalg::Matrix::zeros(m, ids.len());
    problem.evaluate(robot, &mut r, Some(&mut jac));
    let scale = (0..m)
        .flat_map(|i| (0..ids.len()).map(move |j| (i, j)))
        .map(|(i, j)| jac[(i, j)].abs())
        .fold(1.0, f64::max);
    // Central differences: truncation ~h^2 |f'''| (lever arms <= ~3 m: 1e-12 m), rounding
    // ~eps |r| / h with |r| ~ 1e3 (weighted): ~1e-7. Tolerance 1e-6 of the Jacobian's scale.
    let h = 1e-6;
    let x0 = problem.values(robot);
    let (mut rp, mut rm) = (vec![0.0; m], vec![0.0; m]);
    for (c, _) in ids.iter().enumerate() {
        let mut x = x0.clone();
        x[c] += h;
        problem.evaluate(&problem.robot_at(&x), &mut rp, None);
        x[c] -= 2.0 * h;
        problem.evaluate(&problem.robot_at(&x), &mut rm, None);
        for i in 0..m {
            let mut d = rp[i] - rm[i];
            // Euler rows wrap at +-180 deg: unwrap the difference (rows weighted by 1/w.angle).
            let period = 2.0 * std::f64::consts::PI / w.angle;
            d -= period * (d / period).round();
            let fd = d / (2.0 * h);
            assert!(
                (fd - jac[(i, c)]).abs() <= 1e-6 * scale,
                "{mode:?} row {i} {} ({}): analytic {} vs central difference {fd}",
                ids[c],
                robot.param_name(ids[c]),
                jac[(i, c)]
            );
        }
    }
}

#[test]
fn analytic_jacobian_matches_central_differences() {
    for dof in 1..=7 {
        for seed in 0..4u64 {
            let s = 100 * dof as u64 + seed;
            let robot = robot_with_sites(dof, s);
            check(&robot, &data_for(&robot, s, true), OrientationError::Euler);
            check(
                &robot,
                &data_for(&robot, s, false),
                OrientationError::RotVec,
            );
        }
    }
}

#[test]
fn zero_columns_for_parameters_a_site_cannot_feel() {
    let mut robot = simulate::random_robot(&[JointKind::Revolute; 3], 5);
    robot.sites.push(Site {
        name: "a".into(),
        joint: 1,
        frame: Link::default(),
    });
    let chain = kinecal::Chain::new(&robot);
    let mut ws = kinecal::Workspace::new(&robot);
    chain.forward(&[0.1, 0.2, 0.3], &mut ws);
    let mut block = vec![1.0; 6 * robot.param_count()];
    chain.jacobian(&ws, Target::Site(0), &mut block);
    let name_of = |p: usize| robot.param_name(ParamId(p));
    for p in 0..robot.param_count() {
        let nonzero = block[6 * p..6 * p + 6].iter().any(|v| *v != 0.0);
        let n = name_of(p);
        let upstream =
            n.starts_with("link1.") || n.starts_with("joint1.") || n.starts_with("site.a.");
        // link1.x/y/z move the site; every upstream parameter has some effect here.
        assert_eq!(nonzero, upstream, "{n}");
    }
    // And the end effector does not feel the site's parameters.
    chain.jacobian(&ws, Target::EndEffector, &mut block);
    for p in 6 * 4 + 6..robot.param_count() {
        assert!(block[6 * p..6 * p + 6].iter().all(|v| *v == 0.0));
    }
}

#[test]
fn euler_extraction_round_trips() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    for _ in 0..1000 {
        let e = Vector3::new(
            rng.random_range(-3.1..3.1),
            rng.random_range(-1.56..1.56),
            rng.random_range(-3.1..3.1),
        );
        let back = euler_zyx(&rot_zyx(e.x, e.y, e.z));
        assert!((back - e).norm() < 1e-9, "{e} -> {back}");
    }
    // A pose's Euler angles rebuild its rotation.
    let robot = simulate::random_robot(&[JointKind::Revolute, JointKind::Prismatic], 1);
    let p = forward_pose(&robot, &[0.3, -0.2], Target::EndEffector);
    let f = kinecal::Chain::new(&robot).frame_at(&[0.3, -0.2], Target::EndEffector);
    assert!((rot_zyx(p.euler.x, p.euler.y, p.euler.z) - f.rotation).norm() < 1e-12);
}

/// The Jacobian of some parameters only, packed: each wanted parameter's column equals the full
/// Jacobian's, bit for bit, at its place; on robots with sites, couplings and prismatic joints,
/// for the end effector and a site.
#[test]
fn the_packed_jacobian_of_some_parameters_is_the_full_ones_columns() {
    use rand::{RngExt, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(8);
    for seed in 0..12u64 {
        let robot = robot_with_sites(1 + (seed % 7) as usize, seed);
        let chain = kinecal::Chain::new(&robot);
        let mut ws = kinecal::Workspace::new(&robot);
        let np = robot.param_count();
        let mut full = vec![0.0; 6 * np];
        for p in kinecal::apps::simulate::sample_postures(&robot, 10, seed) {
            chain.forward(&p.readings, &mut ws);
            // A random subset, in a random order.
            let mut chosen: Vec<usize> = (0..np).filter(|_| rng.random_range(0..3) == 0).collect();
            for i in (1..chosen.len()).rev() {
                chosen.swap(i, rng.random_range(0..=i));
            }
            let mut columns = vec![None; np];
            for (c, &p) in chosen.iter().enumerate() {
                columns[p] = Some(c);
            }
            for target in [kinecal::Target::EndEffector, kinecal::Target::Site(0)] {
                chain.jacobian(&ws, target, &mut full);
                let mut some = vec![f64::NAN; 6 * chosen.len()];
                let plan = kinecal::model::kinematics::ColumnPlan::new(&robot, target, &columns);
                chain.jacobian_columns(&ws, &plan, &mut some);
                for (c, &p) in chosen.iter().enumerate() {
                    for k in 0..6 {
                        assert_eq!(
                            some[6 * c + k].to_bits(),
                            full[6 * p + k].to_bits(),
                            "seed {seed}, parameter {p} at column {c}"
                        );
                    }
                }
            }
        }
    }
}

#[test]
fn precomputed_reading_sines_give_the_same_kinematics_and_only_for_their_robot() {
    // The addition formula sin(offset + b) = sin(offset) cos b + cos(offset) sin b against a
    // direct sine: equal to rounding (a few ulps of 1), on random robots with prismatic and
    // coupled joints, offsets far from zero, and readings of either sign.
    use kinecal::model::kinematics::{Chain, ReadingTrig, Workspace};
    for seed in 0..60u64 {
        let dof = 1 + (seed % 7) as usize;
        let mut robot = robot_with_sites(dof, seed);
        for (j, joint) in robot.joints.iter_mut().enumerate() {
            joint.offset += 2.5 * (j as f64 - 3.0);
        }
        let data = data_for(&robot, seed, true);
        let trig = ReadingTrig::new(&robot, data.postures.iter().map(|p| p.readings.as_slice()));
        assert!(trig.fits(&robot));
        let chain = Chain::new(&robot);
        let (mut a, mut b) = (Workspace::new(&robot), Workspace::new(&robot));
        for (k, p) in data.postures.iter().enumerate() {
            chain.forward(&p.readings, &mut a);
            chain.forward_with(&p.readings, Some(trig.posture(k)), &mut b);
            for t in
                std::iter::once(Target::EndEffector).chain((0..robot.sites.len()).map(Target::Site))
            {
                let (fa, fb) = (chain.target_frame(&a, t), chain.target_frame(&b, t));
                let scale = 1.0 + fa.translation.norm();
                assert!(
                    (fa.translation - fb.translation).norm() < 1e-14 * scale,
                    "seed {seed}"
                );
                assert!(
                    (fa.rotation - fb.rotation).abs().max() < 1e-14,
                    "seed {seed}"
                );
            }
        }
        // Another slope (or coupling) is another table.
        let mut other = robot.clone();
        other.joints[dof - 1].slope *= 1.0 + 1e-12;
        assert!(!trig.fits(&other), "seed {seed}");
        let mut other = robot.clone();
        other.joints[0].offset += 0.1;
        assert!(trig.fits(&other), "offsets are not in the table");
    }
}
