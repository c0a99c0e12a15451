//! URDF import and export against an independent URDF forward kinematics, on real robot files.

use std::path::PathBuf;

use kinecal::import::urdf::{export_urdf, import_urdf};
use kinecal::model::kinematics::Target;
use kinecal::solve::estimation::{calibrate, CalibrationOptions};
use kinecal::{apps::simulate, ParamId};
use nalgebra::{Matrix4, Rotation3, Unit, Vector3};
use rand::{RngExt, SeedableRng};

#[path = "common/shared_data.rs"]
mod shared_data;

fn shared(rel: &str) -> Option<PathBuf> {
    shared_data::shared_data(&format!("urdf/{rel}"))
}

/// The joints from `base` to `tip`, in order.
fn chain_joints(robot: &urdf_rs::Robot, base: &str, tip: &str) -> Vec<urdf_rs::Joint> {
    let mut chain = Vec::new();
    let mut at = tip.to_string();
    while at != base {
        let j = robot.joints.iter().find(|j| j.child.link == at).unwrap();
        chain.push(j.clone());
        at = j.parent.link.clone();
    }
    chain.reverse();
    chain
}

/// Forward kinematics straight from the URDF: the product of `origin * motion(axis, q)` along
/// the chain from `base` to `tip`, with 4x4 matrices. Returns also the movable joint count.
fn urdf_fk(text: &str, base: &str, tip: &str, q: &[f64]) -> Matrix4<f64> {
    let robot = urdf_rs::read_from_string(text).unwrap();
    let chain = chain_joints(&robot, base, tip);
    let mut t = Matrix4::identity();
    let mut k = 0;
    for j in chain {
        let [x, y, z] = j.origin.xyz.0;
        let [r, p, yw] = j.origin.rpy.0;
        let rot = Rotation3::from_euler_angles(r, p, yw); // URDF: Rz(yaw) Ry(pitch) Rx(roll)
        t *= Matrix4::new_translation(&Vector3::new(x, y, z)) * rot.to_homogeneous();
        let axis = Vector3::from(j.axis.xyz.0);
        match j.joint_type {
            urdf_rs::JointType::Revolute | urdf_rs::JointType::Continuous => {
                t *= Rotation3::from_axis_angle(&Unit::new_normalize(axis), q[k]).to_homogeneous();
                k += 1;
            }
            urdf_rs::JointType::Prismatic => {
                t *= Matrix4::new_translation(&(axis.normalize() * q[k]));
                k += 1;
            }
            _ => {}
        }
    }
    assert_eq!(k, q.len());
    t
}

fn check_fk(robot: &kinecal::Robot, text: &str, base: &str, tip: &str, seed: u64) {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let chain = kinecal::Chain::new(robot);
    for _ in 0..100 {
        let q: Vec<f64> = robot
            .joints
            .iter()
            .map(|j| match j.range {
                Some((a, b)) => rng.random_range(a..=b),
                None => rng.random_range(-3.0..3.0),
            })
            .collect();
        let f = chain.frame_at(&q, Target::EndEffector);
        let e = urdf_fk(text, base, tip, &q);
        for i in 0..3 {
            assert!(
                (f.translation[i] - e[(i, 3)]).abs() < 1e-9,
                "{tip} position {i}: {} vs {}",
                f.translation[i],
                e[(i, 3)]
            );
            for j in 0..3 {
                assert!(
                    (f.rotation[(i, j)] - e[(i, j)]).abs() < 1e-9,
                    "{tip} rotation ({i},{j})"
                );
            }
        }
    }
}

#[test]
fn real_urdfs_import_with_identical_fk() {
    // UR5: parallel shoulder/elbow/wrist-1 axes. iiwa14: 7 axes. Panda to a finger: 7 revolute
    // joints, fixed joints, and a prismatic joint.
    let cases = [
        (
            "universal_robots/urdf_plain/ur5_robot.urdf",
            "base_link",
            "tool0",
        ),
        ("kuka_iiwa14/iiwa14_mukca.urdf", "", "ball_link"),
        ("franka_panda/panda.urdf", "panda_link0", "panda_leftfinger"),
    ];
    for (k, (rel, base, tip)) in cases.iter().enumerate() {
        let Some(path) = shared(rel) else { return };
        let text = std::fs::read_to_string(&path).unwrap();
        let opt = |s: &'static str| (!s.is_empty()).then_some(s);
        let imp = import_urdf(&text, rel, opt(base), opt(tip)).unwrap();
        let urdf = urdf_rs::read_from_string(&text).unwrap();
        let children: Vec<&str> = urdf.joints.iter().map(|j| j.child.link.as_str()).collect();
        let parents: Vec<&str> = urdf.joints.iter().map(|j| j.parent.link.as_str()).collect();
        let root = urdf
            .links
            .iter()
            .find(|l| !children.contains(&l.name.as_str()))
            .unwrap()
            .name
            .clone();
        let leaf = urdf
            .links
            .iter()
            .find(|l| !parents.contains(&l.name.as_str()))
            .unwrap()
            .name
            .clone();
        let (b, t) = (
            opt(base).map_or(root, String::from),
            opt(tip).map_or(leaf, String::from),
        );
        check_fk(&imp.robot, &text, &b, &t, k as u64);
        // Frames on the common normals: no link between two joints is near beta = +-90 deg.
        for l in &imp.robot.links[1..imp.robot.dof()] {
            assert!(l.beta.abs() < 1e-9, "{rel}: beta {}", l.beta);
        }
        if rel.contains("panda") {
            assert!(imp
                .robot
                .joints
                .iter()
                .any(|j| j.kind == kinecal::JointKind::Prismatic));
            assert_eq!(imp.robot.dof(), 8);
        }
    }
}

#[test]
fn export_after_calibration_then_import_gives_the_calibrated_fk() {
    let Some(path) = shared("universal_robots/urdf_plain/ur5_robot.urdf") else {
        return;
    };
    let text = std::fs::read_to_string(&path).unwrap();
    let nominal = import_urdf(&text, "ur5", Some("base_link"), Some("tool0"))
        .unwrap()
        .robot;
    let std = simulate::PerturbStd {
        length: 5e-4,
        angle: 0.1f64.to_radians(),
        slope_fraction: 0.0,
    };
    let truth = simulate::perturb(&nominal, std, 12);
    let data = simulate::measure(&truth, &simulate::sample_postures(&nominal, 40, 3), false);
    let mut est: Vec<ParamId> = kinecal::parse_param_list("links,offsets", &nominal).unwrap();
    est.sort();
    let cal = calibrate(&nominal, &data, &CalibrationOptions::new(est), &mut |_| {}).unwrap();
    assert!(cal.accuracy_after.rms_position < 1e-9);
    let e = export_urdf(&cal.calibrated, &text, "ur5", Some("base_link"), &["tool0"]).unwrap();
    let (new_text, warnings) = (e.text, e.warnings);
    assert!(warnings.is_empty(), "{warnings:?}");
    // Read back by the library, as the command line does before writing: exact, to the
    // rounding of the chain's products (the numbers are written in the shortest text that
    // reads back to themselves; 12 decimals left up to 5e-13 m per number).
    assert!(
        e.read_back.position < 1e-14 && e.read_back.attitude < 1e-14,
        "{:?}",
        e.read_back
    );
    // Everything but the origins is kept: same line count, visuals and limits untouched.
    assert_eq!(new_text.lines().count(), text.lines().count());
    assert!(new_text.contains("<mesh filename="));
    let again = import_urdf(&new_text, "new", Some("base_link"), Some("tool0"))
        .unwrap()
        .robot;
    let (c1, c2) = (
        kinecal::Chain::new(&cal.calibrated),
        kinecal::Chain::new(&again),
    );
    for p in simulate::sample_postures(&nominal, 50, 8) {
        let (a, b) = (
            c1.frame_at(&p.readings, Target::EndEffector),
            c2.frame_at(&p.readings, Target::EndEffector),
        );
        assert!((a.translation - b.translation).norm() < 1e-9);
        assert!((a.rotation - b.rotation).norm() < 1e-9);
        // And the URDF itself, by the independent FK, is the calibrated robot.
        let e = urdf_fk(&new_text, "base_link", "tool0", &p.readings);
        assert!((a.translation - Vector3::new(e[(0, 3)], e[(1, 3)], e[(2, 3)])).norm() < 1e-9);
    }
}

#[test]
fn bad_urdfs_name_the_element() {
    let base = r#"<robot name="r">
  <link name="a"/><link name="b"/><link name="c"/>
  <joint name="j1" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="j2" type="revolute"><parent link="b"/><child link="c"/><axis xyz="0 1 0"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
</robot>"#;
    assert_eq!(
        import_urdf(base, "ok.urdf", None, None)
            .unwrap()
            .robot
            .dof(),
        2
    );
    let cases = [
        (
            base.replace(r#"<child link="c"/>"#, r#"<child link="b"/>"#),
            "child of two joints",
        ),
        (
            base.replace(r#"<child link="c"/>"#, r#"<child link="zz"/>"#),
            "`zz` is not defined",
        ),
        (
            base.replace(
                r#"<axis xyz="0 1 0"/>"#,
                r#"<axis xyz="0 1 0"/><mimic joint="j1"/>"#,
            ),
            "joint `j2` mimics joint `j1`",
        ),
        (
            base.replace(r#"<link name="c"/>"#, r#"<link name="c"/><link name="d"/>"#),
            "several root links",
        ),
    ];
    for (text, expected) in cases {
        let e = import_urdf(&text, "bad.urdf", None, Some("c"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("bad.urdf") && e.contains(expected), "{e}");
    }
    let e = import_urdf(base, "bad.urdf", Some("c"), Some("a"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("not connected"), "{e}");
}

/// A coupled joint exports exactly when its coupling is the controller's sum convention (the
/// URDF joint's value is slope * (V_j + V_k), as drivers of coupled arms publish it), with a
/// warning that says so; any other factor is refused.
#[test]
fn coupled_joints_export_where_exact_and_are_refused_otherwise() {
    let Some(path) = shared("universal_robots/urdf_plain/ur5_robot.urdf") else {
        return;
    };
    let text = std::fs::read_to_string(&path).unwrap();
    let mut robot = import_urdf(&text, "ur5", Some("base_link"), Some("tool0"))
        .unwrap()
        .robot;
    robot.joints[2].coupling = Some(kinecal::model::robot::Coupling {
        joint: 1,
        factor: robot.joints[2].slope,
    });
    let e = export_urdf(&robot, &text, "ur5", Some("base_link"), &["tool0"]).unwrap();
    // The read-back takes the URDF's joint 3 as the sum of the two readings: exact.
    assert!(e.read_back.position < 1e-9, "{:?}", e.read_back);
    assert!(e.lost.is_empty(), "{:?}", e.lost);
    let (out, warnings) = (e.text, e.warnings);
    assert!(
        warnings.iter().any(|w| matches!(
            w,
            kinecal::Warning::UrdfCoupled {
                joint: 3,
                other: 2,
                ..
            }
        )),
        "{warnings:?}"
    );
    // The URDF's joint 3 value is V3 + V2: its FK at (V2, V3 + V2) is the model's at (V2, V3).
    for p in simulate::sample_postures(&robot, 20, 4) {
        let mut urdf_q = p.readings.clone();
        urdf_q[2] += urdf_q[1];
        let e = urdf_fk(&out, "base_link", "tool0", &urdf_q);
        let f = kinecal::Chain::new(&robot).frame_at(&p.readings, Target::EndEffector);
        assert!((f.translation - Vector3::new(e[(0, 3)], e[(1, 3)], e[(2, 3)])).norm() < 1e-9);
    }
    robot.joints[2].coupling.as_mut().unwrap().factor *= 1.001;
    let e = export_urdf(&robot, &text, "ur5", Some("base_link"), &["tool0"])
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("coupled to joint 2") && e.contains("fixed"),
        "{e}"
    );
}

/// URDFs as people keep them: a commented-out joint before the real one, a transmission naming
/// the joint, a tip that hangs off the last movable joint. Export touches only the real
/// elements, adds the tool joint it needs, and the result is the calibrated robot.
#[test]
fn export_finds_real_elements_and_adds_the_tool_joint() {
    let template = r#"<?xml version="1.0"?>
<robot name="arm">
  <!-- An old version of the first joint, kept for reference:
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
    <origin xyz="9 9 9" rpy="0 0 0"/><axis xyz="0 0 1"/></joint> -->
  <link name="base"/><link name="l1"/><link name="l2"/>
  <joint name="j1" type="revolute">
    <parent link="base"/><child link="l1"/>
    <origin xyz="0 0 0.3" rpy="0 0 0"/>
    <axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/>
  </joint>
  <joint name="j2" type="revolute">
    <parent link="l1"/><child link="l2"/>
    <origin xyz="0.4 0 0" rpy="0 0 0"/>
    <axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/>
  </joint>
  <transmission name="t1"><joint name="j1"><hardwareInterface>E</hardwareInterface></joint></transmission>
</robot>
"#;
    let nominal = import_urdf(template, "arm.urdf", Some("base"), Some("l2"))
        .unwrap()
        .robot;
    let mut cal = nominal.clone();
    cal.links[0].x += 0.002;
    cal.links[1].y -= 0.001;
    cal.links[2].z += 0.05; // a tool 5 cm beyond the last joint: the URDF has no place for it
    cal.links[2].alpha += 0.1;
    let e = export_urdf(&cal, template, "arm.urdf", Some("base"), &["l2"]).unwrap();
    // Read back to the added tool link: exact.
    assert!(e.read_back.position < 1e-9, "{:?}", e.read_back);
    let (text, warnings) = (e.text, e.warnings);
    assert!(
        warnings.iter().any(
            |w| matches!(w, kinecal::Warning::UrdfToolAdded { link } if link == "l2_calibrated")
        ),
        "{warnings:?}"
    );
    // The comment and the transmission are untouched.
    assert!(text.contains(r#"<origin xyz="9 9 9" rpy="0 0 0"/><axis xyz="0 0 1"/></joint> -->"#));
    assert!(text.contains(r#"<transmission name="t1"><joint name="j1"><hardwareInterface>E"#));
    let again = import_urdf(&text, "new.urdf", Some("base"), Some("l2_calibrated"))
        .unwrap()
        .robot;
    let (c1, c2) = (kinecal::Chain::new(&cal), kinecal::Chain::new(&again));
    for q in [[0.0, 0.0], [0.5, -1.0], [2.0, 1.5]] {
        let (a, b) = (
            c1.frame_at(&q, Target::EndEffector),
            c2.frame_at(&q, Target::EndEffector),
        );
        assert!((a.translation - b.translation).norm() < 1e-9, "{q:?}");
        assert!((a.rotation - b.rotation).norm() < 1e-9);
    }
}

/// Numbers a URDF cannot mean, and XML nobody should parse, are refused by line and joint.
#[test]
fn impossible_urdfs_are_refused_with_their_line() {
    let base = "<robot name=\"r\">\n  <link name=\"a\"/><link name=\"b\"/>\n  <joint name=\"j\" type=\"revolute\">\n    <parent link=\"a\"/><child link=\"b\"/>\n    <origin xyz=\"0 0 1\" rpy=\"0 0 0\"/>\n    <axis xyz=\"0 0 1\"/>\n    <limit lower=\"-1\" upper=\"1\" effort=\"1\" velocity=\"1\"/>\n  </joint>\n</robot>\n";
    assert!(import_urdf(base, "ok.urdf", None, None).is_ok());
    for (text, expect) in [
        (
            base.replace("xyz=\"0 0 1\"", "xyz=\"0 0 1e400\""),
            "ok.urdf:3: field `joint `j` origin xyz`",
        ),
        (
            base.replace("axis xyz=\"0 0 1\"", "axis xyz=\"0 nan 0\""),
            "joint `j` axis xyz",
        ),
        (
            base.replace("upper=\"1\"", "upper=\"inf\""),
            "joint `j` limit upper",
        ),
        (base.replace("</joint>", ""), "ok.urdf:9: not well-formed"),
        (
            format!(
                "<robot name=\"r\">{}{}</robot>",
                "<x>".repeat(20_000),
                "</x>".repeat(20_000)
            ),
            "nested deeper than 256",
        ),
    ] {
        let e = import_urdf(&text, "ok.urdf", None, None)
            .err()
            .unwrap_or_else(|| panic!("accepted: {expect}"))
            .to_string();
        assert!(e.contains(expect), "expected `{expect}` in {e}");
    }
}

/// Gravity torques straight from the URDF: for each movable joint of the chain, the torque about
/// its axis of every chain link after it (their `<inertial>` mass at its origin), computed with
/// 4x4 matrices along the chain; gravity 9.81 m/s^2 along -z of the base.
fn urdf_gravity_torques(text: &str, base: &str, tip: &str, q: &[f64]) -> Vec<f64> {
    let robot = urdf_rs::read_from_string(text).unwrap();
    let chain = chain_joints(&robot, base, tip);
    let g = Vector3::new(0.0, 0.0, -9.81);
    let mut t = Matrix4::identity();
    let mut k = 0;
    // (axis, origin) of each movable joint so far; the torques.
    let mut axes: Vec<(Vector3<f64>, Vector3<f64>)> = Vec::new();
    let mut tau = vec![0.0; q.len()];
    for j in chain {
        let [x, y, z] = j.origin.xyz.0;
        let [r, p, yw] = j.origin.rpy.0;
        let rot = Rotation3::from_euler_angles(r, p, yw);
        t *= Matrix4::new_translation(&Vector3::new(x, y, z)) * rot.to_homogeneous();
        let axis = Vector3::from(j.axis.xyz.0).normalize();
        if matches!(
            j.joint_type,
            urdf_rs::JointType::Revolute | urdf_rs::JointType::Continuous
        ) {
            let r3 = t.fixed_view::<3, 3>(0, 0).into_owned();
            axes.push((r3 * axis, t.fixed_view::<3, 1>(0, 3).into_owned()));
            t *= Rotation3::from_axis_angle(&Unit::new_normalize(axis), q[k]).to_homogeneous();
            k += 1;
        }
        let link = robot.links.iter().find(|l| l.name == j.child.link).unwrap();
        let m = link.inertial.mass.value;
        let c = t * Vector3::from(link.inertial.origin.xyz.0).push(1.0);
        let c = Vector3::new(c.x, c.y, c.z);
        for (i, (a, o)) in axes.iter().enumerate() {
            tau[i] += a.dot(&(c - o).cross(&(g * m)));
        }
    }
    tau
}

#[test]
fn urdf_masses_give_the_gravity_torques_of_the_urdf() {
    let Some(path) = shared("universal_robots/urdf_plain/ur10_robot.urdf") else {
        return;
    };
    let text = std::fs::read_to_string(path).unwrap();
    let mut imp = import_urdf(&text, "ur10", Some("base_link"), Some("tool0")).unwrap();
    let bodies = kinecal::import::urdf::urdf_bodies(&text, "ur10", &imp).unwrap();
    // The six moving links of the UR10 description (the base's 4 kg does not move).
    assert_eq!(bodies.len(), 6, "{bodies:?}");
    let total: f64 = bodies.iter().map(|b| b.mass).sum();
    assert!(
        (total - (7.778 + 12.93 + 3.87 + 1.96 + 1.96 + 0.202)).abs() < 1e-9,
        "{total}"
    );
    imp.robot.elastic = Some(kinecal::model::robot::Elastic::new(&imp.robot, bodies));
    let robot = imp.robot;
    let chain = kinecal::Chain::new(&robot);
    let mut ws = kinecal::Workspace::new(&robot);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
    for _ in 0..50 {
        let q: Vec<f64> = (0..6).map(|_| rng.random_range(-3.0..3.0)).collect();
        chain.forward(&q, &mut ws);
        let ours = ws.gravity_torques().unwrap();
        let theirs = urdf_gravity_torques(&text, "base_link", "tool0", &q);
        for i in 0..6 {
            assert!(
                (ours[2 * i + 1] - theirs[i]).abs() < 1e-9,
                "joint {}: {} vs {} N m",
                i + 1,
                ours[2 * i + 1],
                theirs[i]
            );
        }
    }
}

/// An upper body as a URDF: a torso of two joints (axes not along z), a fixed chest and a
/// fixed chest marker, and two arms of three joints, each ending in a fixed marker link. Origins
/// and axes drawn at random.
fn two_arm_urdf(seed: u64) -> String {
    let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut joint = |name: &str, kind: &str, parent: &str, child: &str| {
        let mut v = || r.random_range(-0.3..0.3);
        let (xyz, rpy) = ([v(), v(), v()], [v() * 3.0, v() * 3.0, v() * 3.0]);
        let axis = [v(), v(), 1.0];
        format!(
            "  <link name=\"{child}\"/>\n  <joint name=\"{name}\" type=\"{kind}\">\n    <parent \
             link=\"{parent}\"/>\n    <child link=\"{child}\"/>\n    <origin xyz=\"{} {} {}\" \
             rpy=\"{} {} {}\"/>\n    <axis xyz=\"{} {} {}\"/>\n    <limit lower=\"-2\" \
             upper=\"2\" effort=\"1\" velocity=\"1\"/>\n  </joint>\n",
            xyz[0], xyz[1], xyz[2], rpy[0], rpy[1], rpy[2], axis[0], axis[1], axis[2]
        )
    };
    let mut text = String::from("<robot name=\"upper_body\">\n  <link name=\"base\"/>\n");
    text += &joint("torso_1", "revolute", "base", "torso_link1");
    text += &joint("torso_2", "revolute", "torso_link1", "torso_link2");
    text += &joint("chest_joint", "fixed", "torso_link2", "chest");
    text += &joint("chest_marker_joint", "fixed", "chest", "chest_marker");
    for side in ["left", "right"] {
        let mut parent = "chest".to_string();
        for k in 1..=3 {
            let child = format!("{side}_link{k}");
            text += &joint(&format!("{side}_{k}"), "revolute", &parent, &child);
            parent = child;
        }
        text += &joint(
            &format!("{side}_tool"),
            "fixed",
            &parent,
            &format!("{side}_marker"),
        );
    }
    text + "</robot>\n"
}

#[test]
fn a_two_arm_urdf_imports_as_a_tree_and_exports_back() {
    use kinecal::import::urdf::import_urdf_tree;
    let text = two_arm_urdf(3);
    let tips = ["chest_marker", "left_marker", "right_marker"];
    let robot = import_urdf_tree(&text, "arms.urdf", None, &tips)
        .unwrap()
        .robot;
    assert_eq!(robot.dof(), 8);
    assert!(robot.is_tree());
    let names: Vec<&str> = robot
        .joints
        .iter()
        .map(|j| j.name.as_deref().unwrap())
        .collect();
    assert_eq!(
        names,
        ["torso_1", "torso_2", "left_1", "left_2", "left_3", "right_1", "right_2", "right_3"]
    );
    assert_eq!(
        robot.joints[5].parent,
        Some(2),
        "the right arm starts at the torso"
    );
    let sites: Vec<(&str, usize)> = robot
        .sites
        .iter()
        .map(|s| (s.name.as_str(), s.joint))
        .collect();
    assert_eq!(sites, [("chest_marker", 2), ("left_marker", 5)]);
    assert_eq!(robot.end_effector.as_deref(), Some("right_marker"));

    // Each marker where the URDF's own product of transforms puts it, readings by joint name.
    let urdf = urdf_rs::read_from_string(&text).unwrap();
    let check = |robot: &kinecal::Robot, text: &str, tolerance: f64| {
        let chain = kinecal::Chain::new(robot);
        for p in simulate::sample_postures(robot, 10, 9) {
            for (k, tip) in tips.iter().enumerate() {
                let target = if k < 2 {
                    Target::Site(k)
                } else {
                    Target::EndEffector
                };
                let q: Vec<f64> = chain_joints(&urdf, "base", tip)
                    .iter()
                    .filter(|j| j.joint_type != urdf_rs::JointType::Fixed)
                    .map(|j| p.readings[robot.joint_index(&j.name).unwrap()])
                    .collect();
                let t = urdf_fk(text, "base", tip, &q);
                let f = chain.frame_at(&p.readings, target);
                let d = (f.translation - t.fixed_view::<3, 1>(0, 3)).norm()
                    + (f.rotation - t.fixed_view::<3, 3>(0, 0)).norm();
                assert!(d < tolerance, "{tip}: {d}");
            }
        }
    };
    check(&robot, &text, 1e-12);

    // A calibrated tree written back into the file: every chain reads back, and the shared
    // torso joints get one origin.
    let calibrated = simulate::perturb(
        &robot,
        simulate::PerturbStd {
            length: 1e-3,
            angle: 0.2f64.to_radians(),
            slope_fraction: 0.0,
        },
        5,
    );
    let e = export_urdf(&calibrated, &text, "arms.urdf", None, &tips).unwrap();
    assert!(
        e.read_back.position < 1e-9 && e.read_back.attitude < 1e-9,
        "{:?}",
        e.read_back
    );
    // The chest marker's correction goes into its own fixed joint, not into the chest joint
    // that the arms go through too.
    let written = urdf_rs::read_from_string(&e.text).unwrap();
    let origin = |r: &urdf_rs::Robot, name: &str| {
        let j = r.joints.iter().find(|j| j.name == name).unwrap();
        (j.origin.xyz.0, j.origin.rpy.0)
    };
    assert_eq!(
        origin(&written, "chest_joint"),
        origin(&urdf, "chest_joint")
    );
    assert_ne!(
        origin(&written, "chest_marker_joint"),
        origin(&urdf, "chest_marker_joint")
    );
    let back = import_urdf_tree(&e.text, "back.urdf", None, &tips).unwrap();
    let chain_a = kinecal::Chain::new(&calibrated);
    let chain_b = kinecal::Chain::new(&back.robot);
    for p in simulate::sample_postures(&robot, 10, 4) {
        for target in [Target::Site(0), Target::Site(1), Target::EndEffector] {
            let (a, b) = (
                chain_a.frame_at(&p.readings, target),
                chain_b.frame_at(&p.readings, target),
            );
            assert!((a.translation - b.translation).norm() < 1e-9, "{target:?}");
        }
    }

    // A tip right after a fixed joint the arms share: its correction is an added link.
    let tips = ["chest", "left_marker", "right_marker"];
    let robot = import_urdf_tree(&text, "arms.urdf", None, &tips)
        .unwrap()
        .robot;
    let calibrated = simulate::perturb(
        &robot,
        simulate::PerturbStd {
            length: 1e-3,
            angle: 0.2f64.to_radians(),
            slope_fraction: 0.0,
        },
        6,
    );
    let e = export_urdf(&calibrated, &text, "arms.urdf", None, &tips).unwrap();
    assert!(e.read_back.position < 1e-9 && e.read_back.attitude < 1e-9);
    assert!(e.text.contains("<link name=\"chest_calibrated\"/>"));
    let written = urdf_rs::read_from_string(&e.text).unwrap();
    assert_eq!(
        origin(&written, "chest_joint"),
        origin(&urdf, "chest_joint")
    );

    // The end effector must end the last branch; a tip is named once.
    for bad in [
        &["right_marker", "chest_marker"][..],
        &["left_marker", "left_marker"],
    ] {
        let e = import_urdf_tree(&text, "arms.urdf", None, bad)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("must end the last branch") || e.contains("named twice"),
            "{e}"
        );
    }
}
