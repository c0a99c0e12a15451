//! DH export: a robot that came from a DH table goes back to the same table (exact), and any
//! robot gets a table whose stated deviation is what its forward kinematics misses.

use kinecal::import::dh::{
    export_dh, parse_dh_csv, robot_from_dh, write_dh_csv, Convention, DhRow,
};
use kinecal::units::{AngleUnit, LengthUnit};
use kinecal::{simulate, JointKind, Units};

const PUMA_STANDARD: &str = "kind,a,alpha,d,theta\n\
revolute,0,90,0.6718,0\n\
revolute,0.4318,0,0,0\n\
revolute,0.0203,-90,0.15005,0\n\
revolute,0,90,0.4318,0\n\
revolute,0,-90,0,0\n\
revolute,0,0,0,0\n";

const PUMA_MODIFIED: &str = "kind,a,alpha,d,theta\n\
revolute,0,0,0,0\n\
revolute,0,-90,0.2435,0\n\
revolute,0.4318,0,-0.0934,0\n\
revolute,-0.0203,90,0.4331,0\n\
revolute,0,-90,0,0\n\
revolute,0,90,0,0\n";

fn units() -> Units {
    Units {
        length: LengthUnit::M,
        angle: AngleUnit::Deg,
    }
}

#[test]
fn a_dh_robot_goes_back_to_its_table() {
    for (text, convention) in [
        (PUMA_STANDARD, Convention::Standard),
        (PUMA_MODIFIED, Convention::Modified),
    ] {
        let rows = parse_dh_csv(text, "puma.csv", units()).unwrap();
        let robot = robot_from_dh("puma", units(), &rows, convention);
        let (back, (dp, da)) = export_dh(&robot, convention);
        assert!(dp < 1e-9 && da < 1e-9, "{convention:?}: {dp} m, {da} rad");
        // The same kinematics; the rows themselves where the DH frames are unique.
        let again = robot_from_dh("again", units(), &back, convention);
        let (p, a) = kinecal::import::deviation(&robot, &again);
        assert!(p < 1e-9 && a < 1e-9);
        // Written, it is the original table, digit for digit.
        assert_eq!(write_dh_csv(&back, units()), text, "{convention:?}");
    }
}

#[test]
fn the_stated_deviation_is_what_the_table_misses() {
    // A thesis-model robot with link twists and a tool DH cannot express: the table's robot
    // misses it by the deviation stated (2,000 postures), checked here on 500 others.
    let robot = simulate::random_robot(&[JointKind::Revolute; 6], 12);
    for convention in [Convention::Standard, Convention::Modified] {
        let (rows, (dp, _)) = export_dh(&robot, convention);
        assert_eq!(rows.len(), 6);
        let table = robot_from_dh("t", robot.units, &rows, convention);
        let (a, b) = (kinecal::Chain::new(&robot), kinecal::Chain::new(&table));
        let mut worst: f64 = 0.0;
        for p in simulate::sample_postures(&robot, 500, 99) {
            // The same readings: the table's joint variables are the readings (slope 1).
            let fa = a.frame_at(&p.readings, kinecal::Target::EndEffector);
            let fb = b.frame_at(&p.readings, kinecal::Target::EndEffector);
            worst = worst.max((fa.translation - fb.translation).norm());
        }
        assert!(
            dp > 1e-3,
            "{convention:?}: a random robot is not DH-representable"
        );
        // Sampled elsewhere, the worst miss is of the stated size and not above it by more
        // than sampling explains (the statement takes the worst of 2,000 postures).
        assert!(
            worst <= 1.05 * dp && worst >= 0.5 * dp,
            "{convention:?}: {worst} against the stated {dp}"
        );
    }
}

/// A DH robot placed elsewhere in the world: its base transform is what the table cannot hold,
/// and the deviation says so; its joints still go to the original rows.
#[test]
fn a_base_placement_is_stated_as_lost() {
    let rows = parse_dh_csv(PUMA_STANDARD, "puma.csv", units()).unwrap();
    let mut robot = robot_from_dh("puma", units(), &rows, Convention::Standard);
    robot.links[0].x += 0.5;
    let (back, (dp, _)) = export_dh(&robot, Convention::Standard);
    // Joint 1 turns about the global z in the table, 0.5 m beside it in the robot: up to a
    // metre apart when it turns half a turn.
    assert!(dp > 0.9 && dp <= 1.0 + 1e-9, "{dp}");
    let _: &DhRow = &back[0];
}

/// Random DH tables (both conventions, revolute and prismatic joints): the exported table has
/// the same kinematics, exactly.
#[test]
fn random_dh_robots_are_exported_exactly() {
    use rand::{RngExt, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    for _ in 0..200 {
        let n = rng.random_range(2..=7);
        let rows: Vec<DhRow> = (0..n)
            .map(|_| DhRow {
                kind: if rng.random_range(0..4) == 0 {
                    JointKind::Prismatic
                } else {
                    JointKind::Revolute
                },
                a: rng.random_range(-0.5..0.5),
                alpha: rng.random_range(-3.0..3.0),
                d: rng.random_range(-0.5..0.5),
                theta: rng.random_range(-3.0..3.0),
            })
            .collect();
        for convention in [Convention::Standard, Convention::Modified] {
            let u = Units {
                length: LengthUnit::M,
                angle: AngleUnit::Rad,
            };
            let robot = robot_from_dh("r", u, &rows, convention);
            let (_, (dp, da)) = export_dh(&robot, convention);
            assert!(
                dp < 1e-9 && da < 1e-9,
                "{convention:?} {rows:?}: {dp} m, {da} rad"
            );
        }
    }
}
