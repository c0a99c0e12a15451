//! Universal Robots kinematics files: the real factory calibrations of three UR3e arms (and the
//! description's defaults) reproduce their own forward kinematics, computed independently from
//! the file's numbers; export writes a calibration back exactly when the form can hold it and
//! says what it cannot.

use std::path::{Path, PathBuf};

use kinecal::import::ur::{export_ur, import_ur, parse_ur_kinematics};
use kinecal::model::kinematics::log_so3;
use kinecal::{Chain, Robot, Target};
use nalgebra::{Matrix3, Matrix4, Vector3};

#[path = "common/shared_data.rs"]
mod shared_data;

fn dir() -> Option<PathBuf> {
    shared_data::shared_data("urdf/universal_robots")
}

fn files(d: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = [
        "ur3e_calibration.yaml",
        "ur3e_calibration_1.yaml",
        "ur3e_calibration_4.yaml",
    ]
    .iter()
    .map(|f| d.join("real_factory_calibration_ur3e").join(f))
    .collect();
    for m in ["ur3e", "ur5e", "ur10e", "ur5", "ur10"] {
        v.push(d.join("config").join(m).join("default_kinematics.yaml"));
    }
    v
}

/// `Trans(xyz) Rz(yaw) Ry(pitch) Rx(roll)` as a 4x4 matrix.
fn origin(o: &[f64; 6]) -> Matrix4<f64> {
    let r = nalgebra::Rotation3::from_axis_angle(&Vector3::z_axis(), o[5])
        * nalgebra::Rotation3::from_axis_angle(&Vector3::y_axis(), o[4])
        * nalgebra::Rotation3::from_axis_angle(&Vector3::x_axis(), o[3]);
    let mut m = Matrix4::identity();
    m.fixed_view_mut::<3, 3>(0, 0).copy_from(r.matrix());
    m[(0, 3)] = o[0];
    m[(1, 3)] = o[1];
    m[(2, 3)] = o[2];
    m
}

/// The tool0 frame of the UR description's chain, straight from the file's numbers.
fn reference_fk(origins: &[[f64; 6]; 6], q: &[f64]) -> Matrix4<f64> {
    use std::f64::consts::PI;
    let mut t = origin(&[0.0, 0.0, 0.0, 0.0, 0.0, PI]);
    for (o, &qi) in origins.iter().zip(q) {
        t = t * origin(o) * origin(&[0.0, 0.0, 0.0, 0.0, 0.0, qi]);
    }
    t * origin(&[0.0, 0.0, 0.0, 0.0, -PI / 2.0, -PI / 2.0])
        * origin(&[0.0, 0.0, 0.0, PI / 2.0, 0.0, PI / 2.0])
}

fn postures(n: usize) -> Vec<Vec<f64>> {
    kinecal::apps::simulate::sample_postures(
        &kinecal::apps::simulate::random_robot(&[kinecal::JointKind::Revolute; 6], 1),
        n,
        3,
    )
    .into_iter()
    .map(|p| p.readings.iter().map(|v| v.clamp(-6.0, 6.0)).collect())
    .collect()
}

fn differ(a: &Robot, b: &Robot) -> (f64, f64) {
    let (ca, cb) = (Chain::new(a), Chain::new(b));
    let (mut p, mut r): (f64, f64) = (0.0, 0.0);
    for q in postures(300) {
        let (fa, fb) = (
            ca.frame_at(&q, Target::EndEffector),
            cb.frame_at(&q, Target::EndEffector),
        );
        p = p.max((fa.translation - fb.translation).norm());
        r = r.max(log_so3(&(fa.rotation * fb.rotation.transpose())).norm());
    }
    (p, r)
}

#[test]
fn real_ur3e_calibrations_reproduce_their_own_forward_kinematics() {
    let Some(d) = dir() else { return };
    for f in files(&d) {
        let text = std::fs::read_to_string(&f).unwrap();
        let name = f.display().to_string();
        let k = parse_ur_kinematics(&text, &name).unwrap();
        let robot = import_ur(&text, &name).unwrap().robot;
        assert_eq!(robot.dof(), 6);
        let chain = Chain::new(&robot);
        for q in postures(200) {
            let f = chain.frame_at(&q, Target::EndEffector);
            let t = reference_fk(&k.origins, &q);
            let r: Matrix3<f64> = t.fixed_view::<3, 3>(0, 0).into_owned();
            let dp = (f.translation - Vector3::new(t[(0, 3)], t[(1, 3)], t[(2, 3)])).norm();
            let da = log_so3(&(f.rotation * r.transpose())).norm();
            assert!(dp < 1e-12 && da < 1e-12, "{name}: {dp} m, {da} rad");
        }
        // Written back as it is: the same kinematics, nothing lost.
        let e = export_ur(&robot, &text, &name).unwrap();
        assert!(e.lost.is_empty(), "{name}: {:?}", e.lost);
        assert!(e.base.is_none() && e.tcp.is_none() && e.sessions.is_empty());
        assert!(e.read_back.position < 1e-12, "{name}: {:?}", e.read_back);
        let out = e.text;
        let back = import_ur(&out, "out.yaml").unwrap().robot;
        let (dp, da) = differ(&robot, &back);
        assert!(dp < 1e-9 && da < 1e-9, "{name}: {dp} m, {da} rad");
        // And the numbers themselves, to 1e-9.
        let k2 = parse_ur_kinematics(&out, "out.yaml").unwrap();
        for (a, b) in k.origins.iter().zip(&k2.origins) {
            for (x, y) in a.iter().zip(b) {
                assert!((x - y).abs() < 1e-9, "{name}: {a:?} vs {b:?}");
            }
        }
        assert!(k2.hash.unwrap().starts_with("calib_kinecal_"));
    }
}

#[test]
fn a_calibration_is_written_exactly_and_what_the_form_cannot_hold_is_said() {
    let Some(d) = dir() else { return };
    let f = d.join("config/ur3e/default_kinematics.yaml");
    let text = std::fs::read_to_string(&f).unwrap();
    let nominal = import_ur(&text, "ur3e.yaml").unwrap().robot;
    // A calibration of every link before the tool and of the joint offsets: exact, but for the
    // first link, which carries the measurement frame.
    let mut cal = nominal.clone();
    for (i, l) in cal.links.iter_mut().take(6).enumerate() {
        let s = 1e-3 * (i as f64 + 1.0);
        l.x += s;
        l.y -= 0.5 * s;
        l.z += 0.3 * s;
        l.alpha += 0.7 * s;
        l.beta -= 0.2 * s;
        l.gamma += 0.4 * s;
    }
    for (j, joint) in cal.joints.iter_mut().enumerate() {
        joint.offset += 1e-3 * (j as f64 - 2.5);
    }
    let e = export_ur(&cal, &text, "ur3e.yaml").unwrap();
    assert!(e.lost.is_empty() && e.tcp.is_none(), "{:?}", e.lost);
    // The first link's change is where the robot was measured from: left out, and said.
    let base = e.base.expect("the first link moved");
    let moved = kinecal::Frame::from_link(&cal.links[0]).then(&kinecal::import::inverse(
        &kinecal::Frame::from_link(&nominal.links[0]),
    ));
    assert!((base.translation - moved.translation).norm() < 1e-15);
    // The file is the robot on the template's base, exactly.
    let back = import_ur(&e.text, "out.yaml").unwrap().robot;
    let (dp, da) = differ(&e.robot, &back);
    assert!(dp < 1e-9 && da < 1e-9, "{dp} m, {da} rad");
    assert!(e.read_back.position < 1e-9, "{:?}", e.read_back);
    let k = parse_ur_kinematics(&e.text, "out.yaml").unwrap();
    let k0 = parse_ur_kinematics(&text, "ur3e.yaml").unwrap();
    assert_eq!(
        k.origins[0][..5],
        k0.origins[0][..5],
        "the base stays the template's"
    );

    // A slope cannot be written: it is named with its deviation. A tool correction is the TCP.
    cal.joints[1].slope = 1.0005;
    cal.links[6].z += 0.002;
    let e = export_ur(&cal, &text, "ur3e.yaml").unwrap();
    assert_eq!(e.lost.len(), 1, "{:?}", e.lost);
    assert!(e.lost[0].what.contains("joint 2") && e.lost[0].what.contains("slope"));
    assert!(e.lost[0].attitude > 1e-4, "{:?}", e.lost);
    let tcp = e.tcp.expect("a tool correction");
    assert!((tcp.translation - nalgebra::Vector3::new(0.0, 0.0, 0.002)).norm() < 1e-12);
    let err = e
        .check(&kinecal::import::readback::Tolerance::default_for(&cal))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("joint 2 (shoulder_lift_joint) slope 1.0005"),
        "{err}"
    );
}

#[test]
fn broken_kinematics_files_are_refused_with_their_line() {
    let good = "kinematics:\n  shoulder:\n    x: 0\n    y: 0\n    z: 0.15\n    roll: 0\n    pitch: 0\n    yaw: 0\n";
    for (text, says) in [
        ("", "no `kinematics:`"),
        ("robot:\n", "1: expected `kinematics:`"),
        (good, "joint `upper_arm` lacks `x`"),
        ("kinematics:\n  elbow:\n", "2: unknown joint `elbow`"),
        (
            "kinematics:\n  shoulder:\n    x: one\n",
            "3: field `x`: expected a number, found `one`",
        ),
        ("kinematics:\n  shoulder:\n    x: 1e400\n", "plausible"),
        (
            "kinematics:\n  shoulder:\n    x: 0\n    x: 1\n",
            "given twice",
        ),
        ("kinematics:\n  shoulder:\n    twist: 0\n", "unknown key"),
        ("kinematics:\n    x: 0\n", "unknown joint `x`"),
        (
            "kinematics: {shoulder: {x: 0}}\n",
            "1: `kinematics:` in flow style",
        ),
        (
            "---\nkinematics:\n---\nkinematics:\n",
            "3: `---` after the end of the kinematics document",
        ),
        (
            "kinematics:\n...\n  shoulder:\n",
            "3: `shoulder:` after the end",
        ),
    ] {
        let e = parse_ur_kinematics(text, "k.yaml").unwrap_err().to_string();
        assert!(e.contains("k.yaml") && e.contains(says), "{text:?}: {e}");
    }
}

/// A robot imported from one kinematics file is exported only onto that file: another model's
/// defaults, or the model's defaults instead of the arm's factory calibration, would put their
/// base (and, for another model, their geometry) in the file as this robot's.
#[test]
fn export_refuses_a_template_other_than_the_file_the_robot_came_from() {
    let Some(d) = dir() else { return };
    let read = |p: &str| std::fs::read_to_string(d.join(p)).unwrap();
    let factory = read("real_factory_calibration_ur3e/ur3e_calibration.yaml");
    let robot = import_ur(&factory, "ur3e_calibration.yaml").unwrap().robot;
    for other in [
        "config/ur3e/default_kinematics.yaml",
        "config/ur10e/default_kinematics.yaml",
    ] {
        let err = export_ur(&robot, &read(other), "template.yaml")
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("imported from the UR kinematics file `calib_13258964235769181718`")
                && err.contains("template.yaml is `calib_"),
            "{other}: {err}"
        );
    }
    let e = export_ur(&robot, &factory, "ur3e_calibration.yaml").unwrap();
    assert!(e.read_back.position < 1e-9, "{:?}", e.read_back);
    // A robot renamed by its user is not checked by name (nothing to compare).
    let mut renamed = robot.clone();
    renamed.name = "cell 4 arm".into();
    export_ur(
        &renamed,
        &read("config/ur3e/default_kinematics.yaml"),
        "t.yaml",
    )
    .unwrap();
}

/// What YAML writers add around the mapping (a byte order mark, the document markers `---` and
/// `...`, comments after them) reads as the file without it.
#[test]
fn yaml_document_markers_and_a_byte_order_mark_are_read() {
    let Some(d) = dir() else { return };
    let text =
        std::fs::read_to_string(d.join("real_factory_calibration_ur3e/ur3e_calibration.yaml"))
            .unwrap();
    let plain = parse_ur_kinematics(&text, "k.yaml").unwrap();
    for wrapped in [
        format!("\u{feff}{text}"),
        format!("---\n{text}"),
        format!("--- # written by ur_calibration\n{text}\n...\n# end\n"),
        format!("\u{feff}---\n{text}\n...\n"),
    ] {
        assert_eq!(parse_ur_kinematics(&wrapped, "k.yaml").unwrap(), plain);
    }
}
