//! DH export: a robot that came from a DH table goes back to the same table (exact), and any
//! robot gets a table whose stated deviation is what its forward kinematics misses.

use kinecal::import::dh::{
    export_dh, parse_dh_csv, robot_from_dh, write_dh_table, Convention, DhRow, RowKind,
};
use kinecal::import::readback::Tolerance;
use kinecal::units::{AngleUnit, LengthUnit};
use kinecal::{apps::simulate, JointKind, Units};

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
        let e = export_dh(&robot, convention, units()).unwrap();
        let (dp, da) = (e.read_back.position, e.read_back.attitude);
        assert!(dp < 1e-9 && da < 1e-9, "{convention:?}: {dp} m, {da} rad");
        // The same kinematics; the rows themselves where the DH frames are unique.
        let again = robot_from_dh("again", units(), &e.table.rows, convention);
        let (p, a) = kinecal::import::deviation(&robot, &again);
        assert!(p < 1e-9 && a < 1e-9);
        // Written, it is the original table, digit for digit: no fixed row, no beta column.
        assert_eq!(
            e.text,
            write_dh_table(&rows, units(), convention),
            "{convention:?}"
        );
        assert!(e.text.ends_with(text), "{convention:?}: {}", e.text);
        assert_eq!(e.fixed_rows(), (false, false));
        assert!(e.hayati_pairs().is_empty());
    }
}

/// Any robot's geometry goes into a DH table exactly (a base and a tool row where the DH frames
/// cannot be them, beta where axes are nearly parallel); its transducer gains cannot, and the
/// table is refused, naming each and the deviation it causes.
#[test]
fn any_geometry_is_exact_and_gains_are_named() {
    let robot = simulate::random_robot(&[JointKind::Revolute; 6], 12);
    for convention in [Convention::Standard, Convention::Modified] {
        let mut unit = robot.clone();
        for j in &mut unit.joints {
            j.slope = 1.0;
        }
        let e = export_dh(&unit, convention, unit.units).unwrap();
        assert!(
            e.read_back.position < 1e-9 && e.read_back.attitude < 1e-9,
            "{convention:?}: {:?}\n{}",
            e.read_back,
            e.text
        );
        assert!(e.lost.is_empty());
        e.check(&unit, &Tolerance::default_for(&unit)).unwrap();
        // The random robot's slopes (0.5 to 2): the table takes the readings as joint values.
        let e = export_dh(&robot, convention, robot.units).unwrap();
        assert_eq!(e.lost.len(), 6, "{:?}", e.lost);
        for (j, l) in e.lost.iter().enumerate() {
            assert!(
                l.what.starts_with(&format!("joint {} slope", j + 1)),
                "{}",
                l.what
            );
            assert!(l.position > 1e-3, "{l:?}");
        }
        // The read-back's deviation is of the size of the slopes' together.
        assert!(e.read_back.position > 0.05, "{:?}", e.read_back);
        let err = e
            .check(&robot, &Tolerance::default_for(&robot))
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with(
                "the DH table (its joint variables are the readings), read back, misses"
            ) && err.contains("joint 1 slope")
                && err.ends_with("nothing written"),
            "{err}"
        );
        // A tolerance beyond the deviation accepts it.
        let loose = Tolerance {
            position: 2.0 * e.read_back.position,
            attitude: 2.0 * e.read_back.attitude,
        };
        e.check(&robot, &loose).unwrap();
    }
}

/// A DH robot placed elsewhere in the world: its base placement is a fixed row, and its joints
/// still go to the original rows.
#[test]
fn a_base_placement_is_a_fixed_row() {
    let rows = parse_dh_csv(PUMA_STANDARD, "puma.csv", units()).unwrap();
    let mut robot = robot_from_dh("puma", units(), &rows, Convention::Standard);
    robot.links[0].x += 0.5;
    let e = export_dh(&robot, Convention::Standard, units()).unwrap();
    assert!(e.read_back.position < 1e-9, "{:?}", e.read_back);
    assert_eq!(e.fixed_rows(), (true, false));
    let base = e.table.rows[0];
    assert_eq!(base.kind, RowKind::Fixed);
    assert!(
        (base.a - 0.5).abs() < 1e-12 && base.d.abs() < 1e-12,
        "{base:?}"
    );
    assert_eq!(
        write_dh_table(&e.table.rows[1..], units(), Convention::Standard),
        write_dh_table(&rows, units(), Convention::Standard)
    );
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
            .map(|_| {
                DhRow::new(
                    if rng.random_range(0..4) == 0 {
                        JointKind::Prismatic
                    } else {
                        JointKind::Revolute
                    },
                    rng.random_range(-0.5..0.5),
                    rng.random_range(-3.0..3.0),
                    rng.random_range(-0.5..0.5),
                    rng.random_range(-3.0..3.0),
                )
            })
            .collect();
        for convention in [Convention::Standard, Convention::Modified] {
            let u = Units {
                length: LengthUnit::M,
                angle: AngleUnit::Rad,
            };
            let robot = robot_from_dh("r", u, &rows, convention);
            let e = export_dh(&robot, convention, u).unwrap();
            let (dp, da) = (e.read_back.position, e.read_back.attitude);
            assert!(
                dp < 1e-9 && da < 1e-9,
                "{convention:?} {rows:?}: {dp} m, {da} rad"
            );
            // A DH robot needs neither a base nor a tool row in its own convention.
            assert_eq!(e.fixed_rows(), (false, false), "{convention:?}\n{}", e.text);
        }
    }
}

/// UR-like arms (the UR5's table, each value moved by up to 5 mm or 0.5 deg) calibrated in a
/// tracker's frame 3.5 m away (link1 holds the placement, turned anyhow): the standard table's
/// fixed base row holds the placement, its joint rows stay within the robot's size (`a`, `d`
/// below the reach without link1), and it reads back to the robot's forward kinematics exactly.
/// The modified convention, whose joint 1 row would hold it, is refused, naming link1 and the
/// remedy.
#[test]
fn a_tracker_placement_stays_in_the_base_row() {
    use rand::{RngExt, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(37);
    let u = Units {
        length: LengthUnit::M,
        angle: AngleUnit::Rad,
    };
    let ur5 = [
        (0.0, 90f64, 0.089159),
        (-0.425, 0.0, 0.0),
        (-0.39225, 0.0, 0.0),
        (0.0, 90.0, 0.10915),
        (0.0, -90.0, 0.09465),
        (0.0, 0.0, 0.0823),
    ];
    let mut refused = 0;
    for case in 0..40 {
        let (phi, theta) = (
            rng.random_range(-1.5..1.5f64),
            rng.random_range(-3.1..3.1f64),
        );
        let mut rows = vec![DhRow {
            kind: RowKind::Fixed,
            a: 3.5 * phi.cos(),
            alpha: rng.random_range(-3.1..3.1),
            d: 3.5 * phi.sin(),
            theta,
            beta: rng.random_range(-0.5..0.5),
        }];
        for &(a, alpha, d) in &ur5 {
            rows.push(DhRow::new(
                JointKind::Revolute,
                a + rng.random_range(-0.005..0.005),
                (alpha + rng.random_range(-0.5..0.5)).to_radians(),
                d + rng.random_range(-0.005..0.005),
                rng.random_range(-0.01..0.01),
            ));
        }
        let robot = robot_from_dh("ur-like", u, &rows, Convention::Standard);
        let placement = robot.links[0];
        let from_tracker = (placement.x.powi(2) + placement.y.powi(2) + placement.z.powi(2)).sqrt();
        assert!((from_tracker - 3.5).abs() < 0.2, "{from_tracker}");
        let size: f64 = robot.links[1..]
            .iter()
            .map(|l| (l.x * l.x + l.y * l.y + l.z * l.z).sqrt())
            .sum();
        assert!(size < 1.5, "{size}");
        let e = export_dh(&robot, Convention::Standard, u).unwrap();
        assert!(
            e.read_back.position < 1e-9 && e.read_back.attitude < 1e-9,
            "case {case}: {:?}\n{}",
            e.read_back,
            e.text
        );
        e.check(&robot, &Tolerance::default_for(&robot)).unwrap();
        assert!(e.fixed_rows().0, "case {case}\n{}", e.text);
        for r in e.table.rows.iter().filter(|r| r.kind != RowKind::Fixed) {
            assert!(
                r.a.abs() < size && r.d.abs() < size,
                "case {case}: a joint row beyond the robot's size ({size:.3} m): {r:?}\n{}",
                e.text
            );
        }
        match export_dh(&robot, Convention::Modified, u) {
            Ok(m) => {
                assert!(
                    m.read_back.position < 1e-9,
                    "case {case}: {:?}",
                    m.read_back
                );
                for r in m.table.rows.iter().filter(|r| r.kind != RowKind::Fixed) {
                    assert!(r.a.abs() < size && r.d.abs() < size, "case {case}: {r:?}");
                }
            }
            Err(err) => {
                let err = err.to_string();
                assert!(
                    err.contains("link1") && err.contains("--convention standard"),
                    "{err}"
                );
                refused += 1;
            }
        }
    }
    assert!(
        refused > 0,
        "no modified table was refused: the refusal was not tested"
    );
}

/// A robot whose joints have names (a DH table's `name` column, a URDF's joints) is exported
/// with them, so that the table read back heads its postures columns the same way (the names
/// were dropped: `posture,S,L,E` was then refused); names that CSV must quote are quoted, and a
/// robot without names gets no column.
#[test]
fn joint_names_go_into_the_table_and_come_back() {
    let named = "kind,a,alpha,d,theta,name\n\
                 revolute,0,90,0.6718,0,S\n\
                 revolute,0.4318,0,0,0,\"L, lower arm\"\n\
                 revolute,0.0203,-90,0.15005,0,\"E \"\"elbow\"\"\"\n";
    let robot = kinecal::import::dh::import_dh(
        named,
        "named.csv",
        "arm",
        Some(LengthUnit::M),
        Some(AngleUnit::Deg),
        Some(Convention::Standard),
    )
    .unwrap();
    let names = |r: &kinecal::Robot| -> Vec<Option<String>> {
        r.joints.iter().map(|j| j.name.clone()).collect()
    };
    assert_eq!(
        names(&robot),
        [
            Some("S".to_string()),
            Some("L, lower arm".to_string()),
            Some("E \"elbow\"".to_string())
        ]
    );
    for convention in [Convention::Standard, Convention::Modified] {
        let e = export_dh(&robot, convention, units()).unwrap();
        assert!(e.text.contains(",name\n"), "{}", e.text);
        let back =
            kinecal::import::dh::import_dh(&e.text, "back.csv", "arm", None, None, None).unwrap();
        assert_eq!(names(&back), names(&robot), "{convention:?}: {}", e.text);
        // Postures headed by the names read on the table read back.
        let postures = "posture,S,\"L, lower arm\",\"E \"\"elbow\"\"\"\np1,10,20,30\n";
        let p = kinecal::files::parse_postures(postures, "p.csv", &back).unwrap();
        assert_eq!(p[0].readings, [10.0, 20.0, 30.0]);
    }
    let rows = parse_dh_csv(PUMA_STANDARD, "puma.csv", units()).unwrap();
    let unnamed = robot_from_dh("puma", units(), &rows, Convention::Standard);
    let e = export_dh(&unnamed, Convention::Standard, units()).unwrap();
    assert!(!e.text.contains("name"), "{}", e.text);
}
