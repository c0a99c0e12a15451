//! Issue 24, item 2: no export leaves a robot that misses the calibrated one. Every export is
//! read back by its importer and compared over the joint ranges; DH describes (near-)parallel
//! axes with the Hayati/Mooring beta and states its units; UR leaves the measurement frame out
//! and gives the TCP; URDF templates with a byte-order mark or a joint without `<origin>`
//! round-trip.

use kinecal::import::readback::Tolerance;
use kinecal::import::urdf::{export_urdf, import_urdf};

/// A URDF template with a byte-order mark, a movable joint and a fixed tool joint without
/// `<origin>`, as some exporters write them.
const BOM_TEMPLATE: &str = "\u{feff}<?xml version=\"1.0\"?>
<robot name=\"bom\">
  <link name=\"base\"/><link name=\"l1\"/><link name=\"l2\"/><link name=\"tool\"/>
  <joint name=\"j1\" type=\"revolute\"><parent link=\"base\"/><child link=\"l1\"/>
    <axis xyz=\"0 0 1\"/><limit lower=\"-3\" upper=\"3\" effort=\"1\" velocity=\"1\"/></joint>
  <joint name=\"j2\" type=\"revolute\">
    <parent link=\"l1\"/><child link=\"l2\"/>
    <origin xyz=\"0.3 0 0.2\" rpy=\"1.5707963267948966 0 0\"/>
    <axis xyz=\"0 0 1\"/><limit lower=\"-2\" upper=\"2\" effort=\"1\" velocity=\"1\"/></joint>
  <joint name=\"tool_joint\" type=\"fixed\"><parent link=\"l2\"/><child link=\"tool\"/></joint>
</robot>
";

#[test]
fn a_urdf_template_with_a_bom_and_joints_without_origin_round_trips() {
    let without_bom = BOM_TEMPLATE.trim_start_matches('\u{feff}');
    for template in [BOM_TEMPLATE, without_bom] {
        let nominal = import_urdf(template, "bom.urdf", None, None).unwrap().robot;
        let mut cal = nominal.clone();
        for (i, l) in cal.links.iter_mut().enumerate() {
            let s = 1e-3 * (i as f64 + 1.0);
            l.x += s;
            l.y -= 0.5 * s;
            l.z += 0.3 * s;
            l.alpha += 0.7 * s;
            l.beta -= 0.2 * s;
            l.gamma += 0.4 * s;
        }
        cal.joints[1].offset += 0.01;
        let e = export_urdf(&cal, template, "bom.urdf", None, &[]).unwrap();
        // Well-formed, by the XML scanner and by the URDF reader; the mark kept, and the two
        // joints without <origin> given one.
        kinecal::import::xml::scan(&e.text, "out.urdf").unwrap();
        urdf_rs::read_from_string(e.text.trim_start_matches('\u{feff}')).unwrap();
        assert_eq!(
            e.text.starts_with('\u{feff}'),
            template.starts_with('\u{feff}')
        );
        assert_eq!(e.text.matches("<origin ").count(), 3, "{}", e.text);
        let back = import_urdf(&e.text, "out.urdf", None, Some("tool"))
            .unwrap()
            .robot;
        let reach = cal.reach();
        let gap = fk_gap(&cal, &back, &|q| q.to_vec(), None);
        assert!(gap.0 < 1e-9 * reach && gap.1 < 1e-9, "{gap:?}");
        assert!(
            e.read_back.within(&Tolerance::default_for(&cal)),
            "{:?}",
            e.read_back
        );
        eprintln!(
            "URDF template{}: read back {:.1e} m, {:.1e} rad; here {:.1e} m, {:.1e} rad",
            if template.starts_with('\u{feff}') {
                " with a BOM"
            } else {
                ""
            },
            e.read_back.position,
            e.read_back.attitude,
            gap.0,
            gap.1
        );
    }
}

use std::path::{Path, PathBuf};

use kinecal::apps::simulate::{perturb, PerturbStd};
use kinecal::import::dh::{export_dh, import_dh, Convention};
use kinecal::import::ur::{export_ur, import_ur};
use kinecal::model::kinematics::log_so3;
use kinecal::{Chain, Frame, Robot, Target};

/// `../shared/data/urdf`: on CI it must be there, elsewhere a test without it says so.
fn shared() -> Option<PathBuf> {
    shared_data::shared_data("urdf")
}

#[path = "common/shared_data.rs"]
mod shared_data;

/// Where a calibrated robot came from, and so which exports it has.
#[derive(Clone)]
enum Origin {
    /// A built-in robot: DH only.
    Builtin,
    /// A URDF (text, name, base, tip): URDF and DH.
    Urdf(String, String, Option<&'static str>, Option<&'static str>),
    /// A UR kinematics file (text, name): UR, and DH.
    Ur(String, String),
}

/// The largest position (m) and attitude (rad) gap at the tool between `a` at readings `q` and
/// `b` at `map(q)` (then `tool`), over 300 postures of this test's own (within the joint
/// ranges, or +-pi/+-0.1 m about the offset), independent of the library's sample.
fn fk_gap(
    a: &Robot,
    b: &Robot,
    map: &dyn Fn(&[f64]) -> Vec<f64>,
    tool: Option<&Frame>,
) -> (f64, f64) {
    use rand::{RngExt, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(99);
    let (ca, cb) = (Chain::new(a), Chain::new(b));
    let (mut p, mut r): (f64, f64) = (0.0, 0.0);
    for _ in 0..300 {
        let q: Vec<f64> = a
            .joints
            .iter()
            .map(|j| {
                let span = match j.kind {
                    kinecal::JointKind::Revolute => std::f64::consts::PI,
                    kinecal::JointKind::Prismatic => 0.1,
                } / j.slope.abs();
                let (lo, hi) = j.range.unwrap_or((-span, span));
                rng.random_range(lo..=hi)
            })
            .collect();
        let fa = ca.frame_at(&q, Target::EndEffector);
        let mut fb = cb.frame_at(&map(&q), Target::EndEffector);
        if let Some(t) = tool {
            fb = fb.then(t);
        }
        let dp = (fa.translation - fb.translation).norm();
        let dr = log_so3(&(fa.rotation * fb.rotation.transpose())).norm();
        assert!(dp.is_finite() && dr.is_finite());
        p = p.max(dp);
        r = r.max(dr);
    }
    (p, r)
}

/// The robots calibrations start from: the built-in GE A4 (voltage readings, slopes 7.2 deg/V
/// and so on) and the same with readings that are joint values; and the real descriptions
/// under ../shared/data/urdf (UR5 and UR10 with three parallel axes, KUKA iiwa14, Franka Panda
/// to its hand and to its prismatic finger; the UR5, UR10 and UR3e kinematics files).
fn nominal_robots(dir: &Path) -> Vec<(String, Robot, Origin)> {
    let ge = kinecal::model::examples::ge_a4();
    let mut ge_unit = ge.clone();
    for j in &mut ge_unit.joints {
        j.slope = ge_unit.units.factor(j.kind.slope());
        j.range = None;
    }
    let mut out = vec![
        ("GE A4".to_string(), ge, Origin::Builtin),
        (
            "GE A4, joint-value readings".to_string(),
            ge_unit,
            Origin::Builtin,
        ),
    ];
    for (rel, base, tip) in [
        (
            "universal_robots/urdf_plain/ur5_robot.urdf",
            Some("base_link"),
            Some("tool0"),
        ),
        (
            "universal_robots/urdf_plain/ur10_robot.urdf",
            Some("base_link"),
            Some("tool0"),
        ),
        ("kuka_iiwa14/iiwa14_mukca.urdf", None, Some("ball_link")),
        (
            "franka_panda/panda.urdf",
            Some("panda_link0"),
            Some("panda_hand_tcp"),
        ),
        (
            "franka_panda/panda.urdf",
            Some("panda_link0"),
            Some("panda_leftfinger"),
        ),
    ] {
        let text = std::fs::read_to_string(dir.join(rel)).unwrap();
        let robot = import_urdf(&text, rel, base, tip).unwrap().robot;
        out.push((
            format!("{rel} to {}", tip.unwrap_or("the leaf")),
            robot,
            Origin::Urdf(text, rel.to_string(), base, tip),
        ));
    }
    for rel in [
        "universal_robots/config/ur5/default_kinematics.yaml",
        "universal_robots/config/ur10/default_kinematics.yaml",
        "universal_robots/real_factory_calibration_ur3e/ur3e_calibration_1.yaml",
    ] {
        let text = std::fs::read_to_string(dir.join(rel)).unwrap();
        let robot = import_ur(&text, rel).unwrap().robot;
        out.push((rel.to_string(), robot, Origin::Ur(text, rel.to_string())));
    }
    out
}

/// Whether a robot's readings are its joint values in its file's units (slope 1, uncoupled).
fn unit_gains(r: &Robot) -> bool {
    r.joints.iter().all(|j| {
        let u = r.units.factor(j.kind.slope());
        (j.slope - u).abs() <= 1e-12 * u && j.coupling.is_none()
    })
}

#[test]
fn random_calibrated_robots_export_exactly_or_are_refused_with_the_reason() {
    let Some(dir) = shared() else { return };
    let nominal = nominal_robots(&dir);
    // The worst relative gap (position over reach, attitude in rad) of every accepted export,
    // by format, measured here independently of the library's read-back.
    let mut worst: std::collections::BTreeMap<&str, (f64, f64, usize, usize)> = Default::default();
    let mut largest_dh_length: f64 = 0.0;
    for i in 0..200u64 {
        let (name, base, origin) = &nominal[i as usize % nominal.len()];
        let u = base.units;
        // A calibration: every link, offset (and for one in five, slope) moved by about 1 mm and
        // 1 mrad, in the robot file's units.
        let std = PerturbStd {
            length: u.to_si(
                kinecal::units::Quantity::Length,
                u.from_si(kinecal::units::Quantity::Length, 1e-3),
            ),
            angle: 1e-3,
            slope_fraction: if i % 5 == 4 { 1e-3 } else { 0.0 },
        };
        let robot = perturb(base, std, i);
        let tol = Tolerance::default_for(&robot);
        let exact = unit_gains(&robot);
        let reach = robot.reach();
        let mut record = |format: &'static str, gap: Option<(f64, f64)>| {
            let e = worst.entry(format).or_insert((0.0, 0.0, 0, 0));
            match gap {
                Some((p, a)) => {
                    e.0 = e.0.max(p / reach);
                    e.1 = e.1.max(a);
                    e.2 += 1;
                }
                None => e.3 += 1,
            }
        };
        for convention in [Convention::Standard, Convention::Modified] {
            let what = format!("{name} #{i} {convention:?}");
            let e = export_dh(&robot, convention, robot.units).unwrap();
            assert!(
                !e.text.contains("NaN") && !e.text.contains("inf"),
                "{what}:\n{}",
                e.text
            );
            for r in &e.table.rows {
                largest_dh_length = largest_dh_length.max(r.a.abs().max(r.d.abs()) / reach);
                assert!(
                    r.a.abs() <= 2.0 * reach && r.d.abs() <= 2.0 * reach,
                    "{what}: a DH length beyond the robot's reach ({reach} m):\n{}",
                    e.text
                );
            }
            if exact {
                e.check(&robot, &tol)
                    .unwrap_or_else(|err| panic!("{what}: {err}\n{}", e.text));
                // Read back here, from the text alone (the units and convention it states).
                let back = import_dh(&e.text, "t.csv", "t", None, None, None).unwrap();
                let gap = fk_gap(&robot, &back, &|q| q.to_vec(), None);
                assert!(
                    gap.0 <= 1e-9 * reach && gap.1 <= 1e-9,
                    "{what}: {gap:?}\n{}",
                    e.text
                );
                record("dh", Some(gap));
            } else {
                let err = e.check(&robot, &tol).unwrap_err().to_string();
                assert!(
                    err.contains("slope") && err.contains("nothing written"),
                    "{what}: {err}"
                );
                record("dh", None);
            }
        }
        match origin {
            Origin::Builtin => {}
            Origin::Urdf(text, file, b, t) => {
                let what = format!("{name} #{i} URDF");
                let e = export_urdf(
                    &robot,
                    text,
                    file,
                    *b,
                    &t.iter().copied().collect::<Vec<_>>(),
                )
                .unwrap();
                if exact {
                    e.check(&robot, &tol)
                        .unwrap_or_else(|err| panic!("{what}: {err}"));
                    let tip = e
                        .warnings
                        .iter()
                        .find_map(|w| match w {
                            kinecal::Warning::UrdfToolAdded { link } => Some(link.clone()),
                            _ => None,
                        })
                        .or(t.map(String::from));
                    let back = import_urdf(&e.text, "out.urdf", *b, tip.as_deref())
                        .unwrap()
                        .robot;
                    let gap = fk_gap(&robot, &back, &|q| q.to_vec(), None);
                    assert!(gap.0 <= 1e-9 * reach && gap.1 <= 1e-9, "{what}: {gap:?}");
                    record("urdf", Some(gap));
                } else {
                    let err = e.check(&robot, &tol).unwrap_err().to_string();
                    assert!(
                        err.contains("slope") && err.contains("nothing written"),
                        "{what}: {err}"
                    );
                    record("urdf", None);
                }
            }
            Origin::Ur(text, file) => {
                let what = format!("{name} #{i} UR");
                let e = export_ur(&robot, text, file).unwrap();
                // The perturbed first link is the measurement frame: left out, and said.
                assert!(e.base.is_some(), "{what}");
                if exact {
                    e.check(&tol).unwrap_or_else(|err| panic!("{what}: {err}"));
                    let back = import_ur(&e.text, "out.yaml").unwrap().robot;
                    let gap = fk_gap(&e.robot, &back, &|q| q.to_vec(), e.tcp.as_ref());
                    assert!(gap.0 <= 1e-9 * reach && gap.1 <= 1e-9, "{what}: {gap:?}");
                    record("ur", Some(gap));
                } else {
                    let err = e.check(&tol).unwrap_err().to_string();
                    assert!(
                        err.contains("slope") && err.contains("nothing written"),
                        "{what}: {err}"
                    );
                    record("ur", None);
                }
            }
        }
    }
    for (format, (p, a, ok, refused)) in &worst {
        eprintln!(
            "{format}: {ok} exports within {p:.1e} of the reach and {a:.1e} rad; {refused} refused"
        );
    }
    eprintln!("largest DH length: {largest_dh_length:.3} of the reach");
}

/// The UR5: a calibrated UR5 (every link and offset moved by about 1 mm and 1 mrad)
/// exported to standard DH had link offsets of hundreds of metres. Its parallel shoulder,
/// elbow and wrist-1 axes now take beta, and every length is of the robot's size.
#[test]
fn a_calibrated_ur5s_parallel_axes_take_beta() {
    let Some(dir) = shared() else { return };
    let rel = "universal_robots/urdf_plain/ur5_robot.urdf";
    let text = std::fs::read_to_string(dir.join(rel)).unwrap();
    let nominal = import_urdf(&text, rel, Some("base_link"), Some("tool0"))
        .unwrap()
        .robot;
    let std = PerturbStd {
        length: 1e-3,
        angle: 1e-3,
        slope_fraction: 0.0,
    };
    for seed in 0..20 {
        let cal = perturb(&nominal, std, seed);
        for (convention, pairs) in [
            (Convention::Standard, ["2-3", "3-4"]),
            (Convention::Modified, ["2-3", "3-4"]),
        ] {
            let e = export_dh(&cal, convention, cal.units).unwrap();
            let have = e.hayati_pairs();
            assert!(
                pairs.iter().all(|p| have.iter().any(|h| h == p)),
                "{convention:?}: {have:?}\n{}",
                e.text
            );
            let longest = e
                .table
                .rows
                .iter()
                .map(|r| r.a.abs().max(r.d.abs()))
                .fold(0.0, f64::max);
            // The UR5's longest link is its 425 mm upper arm.
            assert!(longest < 0.43, "{convention:?}: {longest} m\n{}", e.text);
            assert!(e.read_back.position < 1e-12 && e.read_back.attitude < 1e-12);
        }
    }
}

/// A robot in radians exported to DH and imported again: the table states its units, and
/// `import dh` reads them (it took degrees by default, and the UR5 came back 0.35 m off).
/// A table that states none needs them given; given ones that contradict it are refused.
#[test]
fn a_radian_robots_dh_table_reads_back_in_radians() {
    let Some(dir) = shared() else { return };
    let rel = "universal_robots/urdf_plain/ur5_robot.urdf";
    let text = std::fs::read_to_string(dir.join(rel)).unwrap();
    let robot = import_urdf(&text, rel, Some("base_link"), Some("tool0"))
        .unwrap()
        .robot;
    assert_eq!(robot.units.angle, kinecal::AngleUnit::Rad);
    for convention in [Convention::Standard, Convention::Modified] {
        let e = export_dh(&robot, convention, robot.units).unwrap();
        assert!(e.text.contains("# angle_unit = rad\n") && e.text.contains("# length_unit = m\n"));
        let back = import_dh(&e.text, "ur5.csv", "ur5", None, None, None).unwrap();
        assert_eq!(back.units, robot.units);
        let gap = fk_gap(&robot, &back, &|q| q.to_vec(), None);
        assert!(gap.0 < 1e-12 && gap.1 < 1e-12, "{convention:?}: {gap:?}");
        // The same table in millimetres and degrees: the readings are converted, the robot the
        // same.
        let mmdeg = kinecal::Units {
            length: kinecal::LengthUnit::Mm,
            angle: kinecal::AngleUnit::Deg,
        };
        let e = export_dh(&robot, convention, mmdeg).unwrap();
        assert!(e.read_back.position < 1e-12, "{:?}", e.read_back);
        let back = import_dh(&e.text, "ur5.csv", "ur5", None, None, None).unwrap();
        let gap = fk_gap(
            &robot,
            &back,
            &|q| q.iter().map(|v| v.to_degrees()).collect(),
            None,
        );
        assert!(gap.0 < 1e-12 && gap.1 < 1e-12, "{convention:?}: {gap:?}");
        // Contradicted: refused, naming the line.
        let err = import_dh(
            &e.text,
            "ur5.csv",
            "ur5",
            None,
            Some(kinecal::AngleUnit::Rad),
            None,
        )
        .unwrap_err()
        .to_string();
        assert!(
            err.contains("ur5.csv:3 states `angle_unit = deg`, not rad"),
            "{err}"
        );
        let other = match convention {
            Convention::Standard => Convention::Modified,
            Convention::Modified => Convention::Standard,
        };
        let err = import_dh(&e.text, "ur5.csv", "ur5", None, None, Some(other))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("ur5.csv:4") && err.contains("convention"),
            "{err}"
        );
    }
    // A table of old, without the comment lines: its units must be given.
    let bare = "kind,a,alpha,d,theta\nrevolute,0,1.5707963267949,0.089159,0\n";
    let err = import_dh(
        bare,
        "old.csv",
        "old",
        None,
        None,
        Some(Convention::Standard),
    )
    .unwrap_err()
    .to_string();
    assert!(
        err.contains("old.csv does not state its length unit"),
        "{err}"
    );
    let r = import_dh(
        bare,
        "old.csv",
        "old",
        Some(kinecal::LengthUnit::M),
        Some(kinecal::AngleUnit::Rad),
        Some(Convention::Standard),
    )
    .unwrap();
    // Its twist read as the 90 deg it is: the tool's z axis horizontal.
    let t = Chain::new(&r).frame_at(&[0.0], Target::EndEffector);
    assert!(t.rotation[(2, 2)].abs() < 1e-12, "{t:?}");
}

/// A UR10 calibrated against a laser tracker 3.8 m away (the robot file's first link carries
/// where the tracker saw the robot; one series in a session of its own) and with a 150 mm tool:
/// the kinematics file keeps the controller's base (the tracker placement is left out, and
/// said), and the tool correction is the TCP to enter. File and TCP are the calibrated robot on
/// its own base.
#[test]
fn ur_export_leaves_the_measurement_frame_out_and_gives_the_tcp() {
    let Some(dir) = shared() else { return };
    let rel = "universal_robots/config/ur10/default_kinematics.yaml";
    let template = std::fs::read_to_string(dir.join(rel)).unwrap();
    let nominal = import_ur(&template, rel).unwrap().robot;
    let mut cal = perturb(
        &nominal,
        PerturbStd {
            length: 5e-4,
            angle: 5e-4,
            slope_fraction: 0.0,
        },
        7,
    );
    // The tracker: 3.8 m away and turned.
    let placement = Frame {
        rotation: kinecal::model::kinematics::rot_zyx(0.7, 0.01, -0.02),
        translation: nalgebra::Vector3::new(3.2, -2.0, 0.5),
    };
    cal.links[0] = kinecal::import::link_of(&placement.then(&Frame::from_link(&nominal.links[0])));
    cal.sessions.push(kinecal::model::robot::Session {
        name: "B".into(),
        frame: kinecal::Link {
            x: 0.4,
            y: 1.0,
            ..Default::default()
        },
    });
    // A 150 mm tool, 2 mm off the flange axis, tilted.
    let tool = Frame {
        rotation: kinecal::model::kinematics::rot_zyx(0.0, 0.03, 0.0),
        translation: nalgebra::Vector3::new(0.002, 0.0, 0.15),
    };
    cal.links[6] = kinecal::import::link_of(&Frame::from_link(&cal.links[6]).then(&tool));
    let e = export_ur(&cal, &template, rel).unwrap();
    e.check(&Tolerance::default_for(&cal)).unwrap();
    // Left out, and said: the tracker placement (to rounding) and the session.
    let base = e.base.expect("the measurement frame");
    assert!(
        (base.translation - placement.translation).norm() < 1e-12,
        "{base:?}"
    );
    assert!((base.rotation - placement.rotation).norm() < 1e-12);
    assert_eq!(e.sessions, ["B"]);
    // The controller's base is the template's: the shoulder where the UR10 has it, not 3.8 m
    // away.
    let k = kinecal::import::ur::parse_ur_kinematics(&e.text, "out.yaml").unwrap();
    let k0 = kinecal::import::ur::parse_ur_kinematics(&template, rel).unwrap();
    for (a, b) in k.origins[0].iter().zip(&k0.origins[0]).take(5) {
        assert!(
            (a - b).abs() < 1e-12,
            "{:?} vs {:?}",
            k.origins[0],
            k0.origins[0]
        );
    }
    // The TCP is the calibrated tool link in the nominal one (tool0): the tool, and the
    // calibration's change of the last link.
    let tcp = e.tcp.expect("a TCP");
    let expected = kinecal::import::inverse(&Frame::from_link(&nominal.links[6]))
        .then(&Frame::from_link(&cal.links[6]));
    assert!(
        (tcp.translation - expected.translation).norm() < 1e-12,
        "{tcp:?}"
    );
    assert!((tcp.rotation - expected.rotation).norm() < 1e-12);
    let v = kinecal::import::ur::pose_vector(&tcp);
    assert!(
        (v[2] - 0.15).abs() < 2e-3 && (v[4] - 0.03).abs() < 2e-3,
        "{v:?}"
    );
    // Read back here: the file and the TCP are the calibrated robot seen from its own base.
    let back = import_ur(&e.text, "out.yaml").unwrap().robot;
    let reach = cal.reach();
    let gap = fk_gap(&e.robot, &back, &|q| q.to_vec(), Some(&tcp));
    assert!(gap.0 < 1e-9 * reach && gap.1 < 1e-9, "{gap:?}");
    let mut seen_from_tracker = back.clone();
    seen_from_tracker.links[0] =
        kinecal::import::link_of(&base.then(&Frame::from_link(&back.links[0])));
    let gap = fk_gap(&cal, &seen_from_tracker, &|q| q.to_vec(), Some(&tcp));
    assert!(gap.0 < 1e-9 * reach && gap.1 < 1e-9, "{gap:?}");
}
