//! What kinecal writes, it reads back to the same numbers: tiny values (a 1e-300 joint limit,
//! subnormals, sigmas of 1e-15) are kept, float noise below 1e-12 of the file's scale of its
//! kind is written as 0, and every other number in the shortest text that reads back exactly
//! (see `kinecal::units::number`).

use kinecal::files::{parse_measurements, parse_postures, write_measurements, write_postures};
use kinecal::model::robot::JointKind;
use kinecal::model::robot_file::{parse_robot_toml, write_robot_toml};
use kinecal::observe::point::{Pose, Position};
use kinecal::observe::{Dataset, Observation, Posture};
use kinecal::units::number::{denoise, format_number, Scale};
use kinecal::units::{AngleUnit, LengthUnit, Quantity};
use kinecal::{apps::simulate, model::examples, Robot, Target};
use nalgebra::Vector3;
use rand::{RngExt, SeedableRng};

/// A robot in metres and radians: its file's numbers are its values, with no conversion.
fn si_robot(dof: usize, seed: u64) -> Robot {
    let mut r = simulate::random_robot(&vec![JointKind::Revolute; dof], seed);
    r.units.length = LengthUnit::M;
    r.units.angle = AngleUnit::Rad;
    r
}

#[test]
fn format_number_is_the_shortest_text_that_reads_back() {
    for (v, text) in [
        (0.0, "0"),
        (-0.0, "0"),
        (1807.0, "1807"),
        (0.25, "0.25"),
        (-15.28, "-15.28"),
        (1e-300, "1e-300"),
        (5e-324, "5e-324"),
        (-2.2250738585072014e-308, "-2.2250738585072014e-308"),
        (1.5e20, "1.5e20"),
        (0.00001, "0.00001"),
    ] {
        assert_eq!(format_number(v), text);
    }
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    for _ in 0..100_000 {
        let v = f64::from_bits(rng.random::<u64>());
        if v.is_finite() {
            let back: f64 = format_number(v).parse().unwrap();
            assert_eq!(
                back.to_bits(),
                v.to_bits(),
                "{v:e} written {}",
                format_number(v)
            );
        }
    }
    assert_eq!(denoise(-2.458164321405018e-11, Scale(1807.0)).to_bits(), 0);
    assert_eq!(denoise(1e-15, Scale(1e-15)).to_bits(), 1e-15f64.to_bits());
    assert_eq!(
        denoise(1e-300, Scale(1e-300)).to_bits(),
        1e-300f64.to_bits()
    );
}

#[test]
fn tiny_joint_limits_and_subnormals_are_kept_in_robot_files() {
    for range in [
        (0.0, 1e-300),
        (-5e-324, 5e-324),
        (-1e-300, 170.0),
        (1e-20, 2e-20),
    ] {
        let mut r = examples::ge_a4();
        r.joints[0].range = Some(range);
        let text = write_robot_toml(&r, None);
        let back = parse_robot_toml(&text, "r.toml").unwrap_or_else(|e| panic!("{e}\n{text}"));
        let (a, b) = back.joints[0].range.unwrap();
        // A bound is noise only next to its range's larger bound.
        let want = (
            denoise(range.0, Scale::of([range.0, range.1])),
            denoise(range.1, Scale::of([range.0, range.1])),
        );
        assert_eq!(
            (a.to_bits(), b.to_bits()),
            (want.0.to_bits(), want.1.to_bits()),
            "{range:?}\n{text}"
        );
        assert_eq!(write_robot_toml(&back, None), text);
    }
}

#[test]
fn float_noise_in_a_robot_file_is_written_as_0() {
    // A robot in millimetres whose lengths reach about a metre, with a computed z of
    // -2.458e-11 mm: float noise, written 0; a length of 1e-9 mm (1e-12 of 1000 mm) is kept.
    let mut r = examples::ge_a4();
    r.units.length = LengthUnit::Mm;
    r.links[0].z = 1.0; // 1000 mm
    r.links[1].z = -2.458164321405018e-14; // -2.458e-11 mm
    r.links[2].z = 1.5e-12; // 1.5e-9 mm
    let text = write_robot_toml(&r, None);
    assert!(!text.contains("2458"), "{text}");
    let back = parse_robot_toml(&text, "r.toml").unwrap();
    assert_eq!(back.links[1].z.to_bits(), 0.0f64.to_bits());
    assert!(
        (back.links[2].z - 1.5e-12).abs() < 1e-27,
        "{}",
        back.links[2].z
    );
    // Angles are their own kind: an attitude of 1e-13 rad next to 1 m lengths is kept when the
    // file's angles are all that small.
    let mut r = si_robot(2, 1);
    for l in &mut r.links {
        (l.alpha, l.beta, l.gamma) = (1e-13, -2e-13, 0.0);
    }
    for j in &mut r.joints {
        j.offset = 0.0;
    }
    let back = parse_robot_toml(&write_robot_toml(&r, None), "r.toml").unwrap();
    assert_eq!(back.links[0].alpha.to_bits(), 1e-13f64.to_bits());
    assert_eq!(back.links[0].beta.to_bits(), (-2e-13f64).to_bits());
}

/// A measurement file with every kind of row: poses and positions, per-axis and scalar sigmas.
fn dataset(robot: &Robot, rng: &mut rand_chacha::ChaCha8Rng, exp: std::ops::Range<i32>) -> Dataset {
    let num = |rng: &mut rand_chacha::ChaCha8Rng| {
        let e = rng.random_range(exp.clone());
        let m: f64 = rng.random_range(-1.0..1.0);
        m * 10f64.powi(e)
    };
    let postures: Vec<Posture> = (0..6)
        .map(|i| Posture {
            label: format!("{}", i + 1),
            readings: (0..robot.dof()).map(|_| num(rng)).collect(),
            session: None,
            payload: None,
        })
        .collect();
    let mut observations: Vec<Observation> = Vec::new();
    // Sigmas of any size down to 1e-135, those of one file within 10^5 of each other (a row far
    // below its file's median is refused: tests/units_at_the_door.rs).
    let e0 = rng.random_range(-135..-5);
    for i in 0..6 {
        let v = |rng: &mut rand_chacha::ChaCha8Rng| Vector3::new(num(rng), num(rng), num(rng));
        let sigma = |rng: &mut rand_chacha::ChaCha8Rng| {
            10f64.powi(e0 + rng.random_range(0..6)) * rng.random_range(0.5..1.0)
        };
        if i % 2 == 0 {
            let mut p = Pose::new(i, Target::EndEffector, v(rng), v(rng));
            p.sigma_position = Some(Vector3::new(sigma(rng), sigma(rng), sigma(rng)));
            p.sigma_angle = Some(sigma(rng));
            observations.push(p.into());
        } else {
            let mut p = Position::new(i, Target::EndEffector, v(rng));
            p.sigma_position = Some(Vector3::repeat(sigma(rng)));
            observations.push(p.into());
        }
    }
    Dataset::new(postures, observations)
}

/// Every number of a CSV text after its first `skip` fields, row by row.
fn numbers(text: &str, skip: usize) -> Vec<Vec<Option<f64>>> {
    text.lines()
        .skip(1)
        .map(|l| l.split(',').skip(skip).map(|f| f.parse().ok()).collect())
        .collect()
}

#[test]
fn measurement_and_posture_files_read_back_to_the_numbers_written() {
    let robot = si_robot(3, 2);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
    for k in 0..300 {
        // Values of every size, from subnormals to 1e9, or all tiny.
        let exp = [-320..9, -16..-14, -310..-300, -3..3][k % 4].clone();
        let d = dataset(&robot, &mut rng, exp);
        let text = write_measurements(&robot, &d);
        let back =
            parse_measurements(&text, "m.csv", &robot).unwrap_or_else(|e| panic!("{e}\n{text}"));
        // Written again: the same text.
        assert_eq!(write_measurements(&robot, &back), text, "not a fixed point");
        // Each number is the value, or 0 when it is noise next to its kind's largest.
        let written = numbers(&text, 2);
        let raw: Vec<Vec<Option<f64>>> = d
            .observations
            .iter()
            .map(|o| {
                let p = &d.postures[o.views()[0].posture];
                let mut row: Vec<Option<f64>> = p.readings.iter().map(|v| Some(*v)).collect();
                match o {
                    Observation::Pose(x) => {
                        row.extend(x.position.iter().chain(x.euler.iter()).map(|v| Some(*v)));
                        row.extend(x.sigma_position.unwrap().iter().map(|v| Some(*v)));
                        row.push(x.sigma_angle);
                    }
                    Observation::Position(x) => {
                        row.extend(x.position.iter().map(|v| Some(*v)));
                        row.extend([None; 3]);
                        row.extend(x.sigma_position.unwrap().iter().map(|v| Some(*v)));
                        row.push(None);
                    }
                    _ => unreachable!(),
                }
                row
            })
            .collect();
        // Readings, positions, angles by the scale of each; sigmas exactly.
        let groups: [(std::ops::Range<usize>, bool); 5] = [
            (0..3, true),
            (3..6, true),
            (6..9, true),
            (9..12, false),
            (12..13, false),
        ];
        for (g, noise) in groups {
            let s = if noise {
                Scale::of(
                    raw.iter()
                        .flat_map(|r| r[g.clone()].iter().flatten().copied()),
                )
            } else {
                Scale(0.0)
            };
            for (r, w) in raw.iter().zip(&written) {
                for c in g.clone() {
                    let want = r[c].map(|v| denoise(v, s));
                    assert_eq!(
                        want.map(f64::to_bits),
                        w[c].map(f64::to_bits),
                        "column {c}: {:?} written {:?}\n{text}",
                        r[c],
                        w[c]
                    );
                }
            }
        }
        // Postures files likewise.
        let text = write_postures(&robot, &d.postures);
        let back = parse_postures(&text, "p.csv", &robot).unwrap();
        assert_eq!(write_postures(&robot, &back), text);
    }
}

#[test]
fn sigmas_of_1e_15_are_kept_and_below_1e_140_refused_naming_the_file() {
    let robot = examples::ge_a4();
    let postures = simulate::sample_postures(&robot, 4, 1);
    let mut d = simulate::measure(&robot, &postures, false);
    for o in &mut d.observations {
        if let Observation::Pose(p) = o {
            // 1e-15 in the file's units.
            let u = robot.units;
            p.sigma_position = Some(Vector3::repeat(u.to_si(Quantity::Length, 1e-15)));
            p.sigma_angle = Some(u.to_si(Quantity::Angle, 1e-15));
        }
    }
    let text = write_measurements(&robot, &d);
    let back = parse_measurements(&text, "m.csv", &robot).unwrap_or_else(|e| panic!("{e}\n{text}"));
    for o in &back.observations {
        let Observation::Pose(p) = o else { panic!() };
        let s = robot
            .units
            .from_si(Quantity::Length, p.sigma_position.unwrap().x);
        assert!((s - 1e-15).abs() < 1e-29, "{s}");
    }
    let tiny = text.replace(",1e-15,1e-15", ",1e-160,1e-15");
    assert_ne!(tiny, text);
    let e = parse_measurements(&tiny, "m.csv", &robot)
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("m.csv:2: field `sigma_position`: a standard deviation below 1e-140"),
        "{e}"
    );
}
