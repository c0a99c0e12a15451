//! `export ros`: the calibration YAML, the xacro that reads it and the static transforms, on a
//! two-arm tree, a random 6-axis arm and the UR10, and the frames of cameras and boards
//! (eye-in-hand, eye-to-hand, on a site of a tree); checked with an independent URDF forward
//! kinematics (4x4 matrices from the expanded xacro's origins), an independent hash, and the
//! spec's door with its bad inputs. The real `xacro` tool's expansion is checked by the Python
//! tests (crates/kinecal-py/tests/test_ros_export.py).

use std::path::{Path, PathBuf};

use kinecal::apps::simulate;
use kinecal::import::ros::{
    expand_xacro, export_ros, parse_calibration, parse_transforms, values_hash, JointOrigin,
};
use kinecal::import::urdf::import_urdf_tree;
use kinecal::model::camera::{Board, Camera, Mount};
use kinecal::model::kinematics::{Frame, Target};
use kinecal::model::robot::{Link, Session};
use kinecal::spec::{Env, Job};
use kinecal::Robot;
use nalgebra::{Matrix4, Rotation3, Unit, UnitQuaternion, Vector3};
use rand::{RngExt, SeedableRng};

#[path = "common/shared_data.rs"]
mod shared_data;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
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

/// Forward kinematics straight from a URDF: `origin * motion(axis, q)` along the chain, 4x4
/// matrices; `q` by joint name.
fn urdf_fk(robot: &urdf_rs::Robot, base: &str, tip: &str, q: &dyn Fn(&str) -> f64) -> Matrix4<f64> {
    let mut t = Matrix4::identity();
    for j in chain_joints(robot, base, tip) {
        let [x, y, z] = j.origin.xyz.0;
        let [r, p, yw] = j.origin.rpy.0;
        t *= Matrix4::new_translation(&Vector3::new(x, y, z))
            * Rotation3::from_euler_angles(r, p, yw).to_homogeneous();
        let axis = Vector3::from(j.axis.xyz.0);
        match j.joint_type {
            urdf_rs::JointType::Revolute | urdf_rs::JointType::Continuous => {
                t *= Rotation3::from_axis_angle(&Unit::new_normalize(axis), q(&j.name))
                    .to_homogeneous();
            }
            urdf_rs::JointType::Prismatic => {
                t *= Matrix4::new_translation(&(axis.normalize() * q(&j.name)));
            }
            _ => {}
        }
    }
    t
}

fn homogeneous(f: &Frame) -> Matrix4<f64> {
    let mut m = Matrix4::identity();
    m.fixed_view_mut::<3, 3>(0, 0).copy_from(&f.rotation);
    m.fixed_view_mut::<3, 1>(0, 3).copy_from(&f.translation);
    m
}

/// A random serial arm as a URDF: `n` revolute joints with origins and axes drawn at random,
/// a fixed flange and a fixed tool link.
fn random_arm_urdf(n: usize, seed: u64) -> String {
    let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut text = String::from(
        "<?xml version=\"1.0\"?>\n<robot name=\"random_arm\">\n  <link name=\"base_link\"/>\n",
    );
    let mut parent = "base_link".to_string();
    for k in 1..=n + 1 {
        let mut v = || r.random_range(-0.4..0.4);
        let (xyz, rpy) = ([v(), v(), v() + 0.2], [v() * 4.0, v() * 4.0, v() * 4.0]);
        let axis = [v(), v(), 1.0];
        let child = if k <= n {
            format!("link{k}")
        } else {
            "tool0".into()
        };
        let kind = if k <= n { "revolute" } else { "fixed" };
        text += &format!(
            "  <link name=\"{child}\"/>\n  <joint name=\"j{k}\" type=\"{kind}\">\n    <parent \
             link=\"{parent}\"/>\n    <child link=\"{child}\"/>\n    <origin xyz=\"{} {} {}\" \
             rpy=\"{} {} {}\"/>\n    <axis xyz=\"{} {} {}\"/>\n    <limit lower=\"-3\" \
             upper=\"3\" effort=\"1\" velocity=\"1\"/>\n  </joint>\n",
            xyz[0], xyz[1], xyz[2], rpy[0], rpy[1], rpy[2], axis[0], axis[1], axis[2]
        );
        parent = child;
    }
    text + "</robot>\n"
}

/// `robot` calibrated: every parameter changed (1 mm, 0.2 deg; slopes kept), the measurement
/// frame moved far from the base (a tracker 2 m away, turned), and two sessions.
fn calibrated(robot: &Robot, seed: u64) -> Robot {
    let mut c = simulate::perturb(
        robot,
        simulate::PerturbStd {
            length: 1e-3,
            angle: 0.2f64.to_radians(),
            slope_fraction: 0.0,
        },
        seed,
    );
    let tracker = Frame::from_link(&Link {
        x: 2.1,
        y: -0.7,
        z: 0.35,
        alpha: 0.3,
        beta: -0.2,
        gamma: 2.5,
    });
    for i in 0..c.links.len() {
        if i == 0 || c.joints.get(i).is_some_and(|j| j.parent == Some(0)) {
            c.links[i] = kinecal::import::link_of(&tracker.then(&Frame::from_link(&c.links[i])));
        }
    }
    c.sessions = vec![
        Session {
            name: "A".into(),
            frame: Link {
                x: 0.01,
                y: 0.02,
                z: -0.03,
                alpha: 0.001,
                beta: 0.002,
                gamma: -0.003,
            },
        },
        Session {
            name: "tracker 2".into(),
            frame: Link {
                x: -1.5,
                y: 3.0,
                z: 0.2,
                alpha: 0.1,
                beta: 1.2,
                gamma: -2.9,
            },
        },
    ];
    c
}

/// Exports `cal` and checks everything against an independent reading of the files: the
/// YAML's values are the expanded xacro's origins, the hash is recomputed, and the expanded
/// URDF behind the parsed base transform puts every tip where the calibrated robot does (to
/// 1e-9 m and 1e-9 rad at 200 postures); the sessions are their frames. Returns the largest
/// position deviation.
fn check_export(
    cal: &Robot,
    template: &str,
    base: Option<&str>,
    tips: &[&str],
    targets: &[Target],
) -> f64 {
    let e = export_ros(cal, template, "t.urdf", base, tips, None).unwrap();
    assert!(
        e.read_back.position < 1e-9 && e.read_back.attitude < 1e-9,
        "{:?}",
        e.read_back
    );
    let parsed = parse_calibration(&e.calibration, "calibration.yaml").unwrap();
    assert_eq!(parsed.joints, e.joints);
    assert_eq!(parsed.hash, e.hash);
    assert_eq!(
        hash(&parsed.joints),
        e.hash,
        "an independent SHA-256 of the values"
    );
    // Every value of the YAML is an origin of the expansion.
    let expanded = expand_xacro(&e.xacro, &parsed.joints, "x").unwrap();
    let urdf = urdf_rs::read_from_string(&expanded).unwrap();
    for j in &parsed.joints {
        let u = urdf.joints.iter().find(|u| u.name == j.name).unwrap();
        let o = [u.origin.xyz.0, u.origin.rpy.0].concat();
        assert_eq!(o, j.origin, "{}", j.name);
    }
    // The xacro has no literal origin left on the chains, and loads the YAML beside it.
    assert!(e
        .xacro
        .contains("<xacro:arg name=\"calibration\" default=\"calibration.yaml\"/>"));
    assert!(e.xacro.contains("${xacro.load_yaml('$(arg calibration)')}"));
    assert_eq!(e.xacro.matches("xmlns:xacro=").count(), 1);
    // Static transforms: the base where the calibration put it, the sessions' frames.
    let tf = parse_transforms(&e.transforms_yaml, "static_transforms.yaml").unwrap();
    assert_eq!(tf.transforms.len(), 1 + cal.sessions.len());
    let frame = |v: &[f64; 7]| {
        let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(v[6], v[3], v[4], v[5]));
        let mut m = q.to_homogeneous();
        m.fixed_view_mut::<3, 1>(0, 3)
            .copy_from(&Vector3::new(v[0], v[1], v[2]));
        m
    };
    for (t, s) in tf.transforms[1..].iter().zip(&cal.sessions) {
        assert_eq!(t.parent, "measurement");
        assert_eq!(t.child, s.name.replace(' ', "_"));
        // The session's frame maps the global frame into the measurement frame: its inverse.
        let m = frame(&t.values) * homogeneous(&Frame::from_link(&s.frame));
        assert!((m - Matrix4::identity()).norm() < 1e-14, "{}", s.name);
        assert!(t.values[6] >= 0.0);
    }
    // The measurement frame in the base: the base in the measurement frame is its inverse.
    let placement = frame(&tf.transforms[0].values).try_inverse().unwrap();
    assert_eq!(tf.transforms[0].child, "measurement");
    let base = tf.transforms[0].parent.clone();
    let chain = kinecal::Chain::new(cal);
    let names: Vec<String> = cal.joints.iter().map(|j| j.name.clone().unwrap()).collect();
    let mut worst: f64 = 0.0;
    for p in simulate::sample_postures(cal, 200, 11) {
        for (tip, target) in tips.iter().zip(targets) {
            let added = format!("{tip}_calibrated");
            let tip_link = if urdf.links.iter().any(|l| l.name == added) {
                &added
            } else {
                *tip
            };
            let q = |n: &str| p.readings[names.iter().position(|m| m == n).unwrap()];
            let u = placement * urdf_fk(&urdf, &base, tip_link, &q);
            let f = homogeneous(&chain.frame_at(&p.readings, *target));
            let dp = (u.fixed_view::<3, 1>(0, 3) - f.fixed_view::<3, 1>(0, 3)).norm();
            let dr = (u.fixed_view::<3, 3>(0, 0) - f.fixed_view::<3, 3>(0, 0)).norm();
            assert!(dp < 1e-9 && dr < 1e-9, "{tip}: {dp} m, {dr}");
            worst = worst.max(dp);
        }
    }
    worst
}

/// SHA-256 of the values as `values_hash` documents it, computed here.
fn hash(joints: &[JointOrigin]) -> String {
    use sha2::{Digest, Sha256};
    let mut bytes = Vec::new();
    for j in joints {
        bytes.extend(j.name.as_bytes());
        bytes.push(0);
        for v in j.origin {
            bytes.extend(v.to_le_bytes());
        }
    }
    let d = Sha256::digest(&bytes);
    format!(
        "calib_kinecal_{}",
        d[..8]
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect::<String>()
    )
}

#[test]
fn a_two_arm_tree_gets_one_yaml_and_every_tip_reads_back() {
    let text = std::fs::read_to_string(repo().join("examples/trees/upper_body.urdf")).unwrap();
    let tips = ["left_marker", "right_marker"];
    let robot = import_urdf_tree(&text, "upper_body.urdf", None, &tips)
        .unwrap()
        .robot;
    let cal = calibrated(&robot, 3);
    let worst = check_export(
        &cal,
        &text,
        None,
        &tips,
        &[Target::Site(0), Target::EndEffector],
    );
    eprintln!("two-arm tree: largest position deviation {worst:e} m");
    let e = export_ros(&cal, &text, "t.urdf", None, &tips, None).unwrap();
    assert_eq!(e.xacro_file, "upper_body.urdf.xacro");
    // One YAML: the torso, both arms, the fixed joints on the chains, each once.
    let names: Vec<&str> = e.joints.iter().map(|j| j.name.as_str()).collect();
    for n in [
        "torso_yaw",
        "torso_pitch",
        "chest_joint",
        "left_elbow",
        "right_elbow",
        "left_marker_joint",
        "right_marker_joint",
    ] {
        assert_eq!(
            names.iter().filter(|m| **m == n).count(),
            1,
            "{n}: {names:?}"
        );
    }
}

#[test]
fn a_random_six_axis_arm_reads_back() {
    for seed in [1, 2, 3] {
        let text = random_arm_urdf(6, seed);
        let robot = import_urdf_tree(&text, "arm.urdf", None, &["tool0"])
            .unwrap()
            .robot;
        let cal = calibrated(&robot, seed + 10);
        let worst = check_export(&cal, &text, None, &["tool0"], &[Target::EndEffector]);
        eprintln!("random arm {seed}: largest position deviation {worst:e} m");
    }
}

#[test]
fn the_ur10_reads_back() {
    let Some(path) = shared_data::shared_data("urdf/universal_robots/urdf_plain/ur10_robot.urdf")
    else {
        return;
    };
    let text = std::fs::read_to_string(path).unwrap();
    let robot = import_urdf_tree(&text, "ur10.urdf", Some("base_link"), &["tool0"])
        .unwrap()
        .robot;
    let cal = calibrated(&robot, 5);
    let worst = check_export(
        &cal,
        &text,
        Some("base_link"),
        &["tool0"],
        &[Target::EndEffector],
    );
    eprintln!("UR10: largest position deviation {worst:e} m");
}

#[test]
fn the_files_say_what_they_are() {
    let text = random_arm_urdf(6, 1);
    let robot = import_urdf_tree(&text, "arm.urdf", None, &["tool0"])
        .unwrap()
        .robot;
    let cal = calibrated(&robot, 4);
    let e = export_ros(&cal, &text, "arm.urdf", None, &["tool0"], Some("tracker")).unwrap();
    // The YAML: the robot, the hash, each joint's six keys in order, PyYAML floats.
    let c = &e.calibration;
    assert!(c.contains("\nrobot: random_arm\n"), "{c}");
    assert!(c.contains(&format!("\nhash: {}\n", e.hash)));
    assert!(c.contains("\njoints:\n  j1:\n    x: "), "{c}");
    for line in c.lines().filter(|l| l.starts_with("    ")) {
        let (k, v) = line.trim().split_once(": ").unwrap();
        assert!(["x", "y", "z", "roll", "pitch", "yaw"].contains(&k));
        assert!(
            v.contains('.'),
            "{line}: YAML 1.1 reads a float with a point"
        );
    }
    // The xacro: each origin of the chain an expression.
    assert!(e.xacro.contains(
        "<origin xyz=\"${calibration['joints']['j3']['x']} ${calibration['joints']['j3']['y']} \
         ${calibration['joints']['j3']['z']}\" rpy=\"${calibration['joints']['j3']['roll']} \
         ${calibration['joints']['j3']['pitch']} ${calibration['joints']['j3']['yaw']}\"/>"
    ));
    // Static transforms: the named measurement frame below the base, the sessions below it.
    let t = &e.transforms_yaml;
    assert!(
        t.contains("  - parent: base_link\n    child: tracker\n    x: "),
        "{t}"
    );
    assert!(
        t.contains("  - parent: tracker\n    child: tracker_2\n"),
        "{t}"
    );
    assert!(
        e.notes.iter().any(|n| n.contains("`tracker_2`")),
        "{:?}",
        e.notes
    );
    // The launch file: tf2_ros static_transform_publisher nodes from the YAML beside it.
    let l = &e.launch;
    for s in [
        "from launch_ros.actions import Node",
        "package=\"tf2_ros\"",
        "executable=\"static_transform_publisher\"",
        "\"static_transforms.yaml\"",
        "\"--frame-id\"",
        "\"--child-frame-id\"",
        "def generate_launch_description():",
    ] {
        assert!(l.contains(s), "{s}\n{l}");
    }
}

#[test]
fn the_hash_changes_with_any_value_and_name() {
    let j = |name: &str, v: f64| JointOrigin {
        name: name.into(),
        origin: [0.1, 0.2, v, 0.0, 0.0, 0.0],
    };
    let a = values_hash(&[j("a", 0.3), j("b", 0.3)]);
    assert_eq!(a, hash(&[j("a", 0.3), j("b", 0.3)]));
    assert!(a.starts_with("calib_kinecal_") && a.len() == 14 + 16, "{a}");
    assert_ne!(a, values_hash(&[j("a", 0.3), j("b", 0.3 + 1e-16)]));
    assert_ne!(a, values_hash(&[j("a", 0.3), j("c", 0.3)]));
    assert_ne!(a, values_hash(&[j("b", 0.3), j("a", 0.3)]));
}

#[test]
fn a_template_escapes_its_dollars_and_keeps_its_namespace() {
    // A URDF that already declares the xacro namespace and has `${` in a comment and an
    // attribute: one namespace declaration, the attribute escaped, the comment kept.
    let text = random_arm_urdf(6, 2)
        .replace(
            "<robot name=\"random_arm\">",
            "<robot name=\"random_arm\" xmlns:xacro=\"http://www.ros.org/wiki/xacro\">\n  <!-- ${not} -->",
        )
        .replace("<link name=\"link1\"/>", "<link name=\"link1\"><visual><geometry><mesh filename=\"$(find x)/${y}.stl\"/></geometry></visual></link>");
    let robot = import_urdf_tree(&text, "arm.urdf", None, &["tool0"])
        .unwrap()
        .robot;
    let e = export_ros(&robot, &text, "arm.urdf", None, &["tool0"], None).unwrap();
    assert_eq!(e.xacro.matches("xmlns:xacro").count(), 1);
    assert!(
        e.xacro.contains("filename=\"$$(find x)/$${y}.stl\""),
        "{}",
        e.xacro
    );
    assert!(e.xacro.contains("<!-- ${not} -->"));
    let expanded = expand_xacro(&e.xacro, &e.joints, "x").unwrap();
    assert!(expanded.contains("filename=\"$(find x)/${y}.stl\""));
}

fn run(toml: &str) -> kinecal::Result<kinecal::spec::Done> {
    let job = Job::from_toml(toml, "job.toml")?;
    let mut quiet = ();
    kinecal::spec::run(&job, &mut Env::new(&mut quiet, None))
}

/// A folder with a template and a calibrated robot file of the random arm.
fn setup(dir: &Path) -> (PathBuf, PathBuf) {
    let text = random_arm_urdf(6, 1);
    let robot = import_urdf_tree(&text, "arm.urdf", None, &["tool0"])
        .unwrap()
        .robot;
    let cal = calibrated(&robot, 4);
    let template = dir.join("arm.urdf");
    std::fs::write(&template, &text).unwrap();
    let robot_file = dir.join("cal.toml");
    std::fs::write(
        &robot_file,
        kinecal::model::robot_file::write_robot_toml(&cal, None),
    )
    .unwrap();
    (template, robot_file)
}

fn spec(robot: &Path, template: &Path, out: &Path) -> String {
    format!(
        "job = \"export\"\nformat = \"ros\"\nrobot = {:?}\ntemplate = {:?}\nout = {:?}\n",
        robot.display().to_string(),
        template.display().to_string(),
        out.display().to_string()
    )
}

fn listing(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn the_spec_writes_the_four_files_into_the_folder() {
    let tmp = tempfile::tempdir().unwrap();
    let (template, robot) = setup(tmp.path());
    // A folder that does not exist yet is made.
    let out = tmp.path().join("description");
    let done = run(&spec(&robot, &template, &out)).unwrap();
    assert_eq!(
        listing(&out),
        [
            "calibration.yaml",
            "random_arm.urdf.xacro",
            "static_transforms.launch.py",
            "static_transforms.yaml"
        ]
    );
    let kinecal::spec::Document::Export(d) = &done.document else {
        panic!()
    };
    for (name, text) in &d.files {
        assert_eq!(
            &std::fs::read_to_string(out.join(name)).unwrap(),
            text,
            "{name}"
        );
    }
    assert!(
        d.read_back.as_deref().unwrap().starts_with("read back"),
        "{:?}",
        d.read_back
    );
    // Run again: the outputs of the last run are replaced (they are not inputs).
    std::fs::write(out.join("calibration.yaml"), "old").unwrap();
    run(&spec(&robot, &template, &out)).unwrap();
    assert_eq!(
        std::fs::read_to_string(out.join("calibration.yaml")).unwrap(),
        d.files[0].1
    );
    // The spec reads back with its keys.
    let job = Job::from_toml(
        &format!(
            "{}measurement_frame = \"tracker\"\n",
            spec(&robot, &template, &out)
        ),
        "j.toml",
    )
    .unwrap();
    assert_eq!(
        Job::from_toml(&job.to_toml().unwrap(), "j.toml").unwrap(),
        job
    );
}

#[test]
fn bad_inputs_are_refused_and_nothing_is_written() {
    let tmp = tempfile::tempdir().unwrap();
    let (template, robot) = setup(tmp.path());
    let out = tmp.path().join("out");
    std::fs::create_dir(&out).unwrap();
    let refused = |toml: &str| run(toml).map(|_| ()).unwrap_err().to_string();

    // The template lacks joints: a chain of 5 for a robot of 6.
    let short = tmp.path().join("short.urdf");
    std::fs::write(&short, random_arm_urdf(5, 1)).unwrap();
    let e = refused(&spec(&robot, &short, &out));
    assert!(
        e.contains("6 joints") && e.contains("5 movable joints"),
        "{e}"
    );

    // A template that is not a URDF.
    let not = tmp.path().join("not.urdf");
    std::fs::write(&not, "kinematics:\n  shoulder:\n    x: 0\n").unwrap();
    let e = refused(&spec(&robot, &not, &out));
    assert!(e.contains("not.urdf") && e.contains("not"), "{e}");
    std::fs::write(&not, "<robot name=\"r\"><link name=\"a\"/></robot").unwrap();
    let e = refused(&spec(&robot, &not, &out));
    assert!(e.contains("not.urdf") && e.contains("XML"), "{e}");

    // The folder is a file: the robot file (an input), another file; a folder in a folder
    // that does not exist.
    let e = refused(&spec(&robot, &template, &robot));
    assert!(e.contains("cal.toml") && e.contains("input"), "{e}");
    let file = tmp.path().join("file");
    std::fs::write(&file, "keep").unwrap();
    let e = refused(&spec(&robot, &template, &file));
    assert!(e.contains("file") && e.contains("is not a folder"), "{e}");
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "keep");
    let e = refused(&spec(&robot, &template, &tmp.path().join("missing/deeper")));
    assert!(e.contains("missing") && e.contains("no folder"), "{e}");

    // The template inside the folder under the name of an output: refused before writing.
    let inside = out.join("random_arm.urdf.xacro");
    std::fs::copy(&template, &inside).unwrap();
    let e = refused(&spec(&robot, &inside, &out));
    assert!(
        e.contains("random_arm.urdf.xacro") && e.contains("input"),
        "{e}"
    );
    assert_eq!(listing(&out), ["random_arm.urdf.xacro"]);
    assert_eq!(
        std::fs::read_to_string(&inside).unwrap(),
        std::fs::read_to_string(&template).unwrap()
    );
    // ... and as calibration.yaml.
    let e = refused(&spec(&robot, &out.join("calibration.yaml"), &out));
    assert!(e.contains("calibration.yaml"), "{e}");
    std::fs::remove_file(&inside).unwrap();

    // A folder that cannot be written (unless this user writes everywhere).
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt as _;
        let locked = tmp.path().join("locked");
        std::fs::create_dir(&locked).unwrap();
        std::fs::set_permissions(&locked, std::fs::Permissions::from_mode(0o555)).unwrap();
        if std::fs::write(locked.join("probe"), "").is_err() {
            let e = refused(&spec(&robot, &template, &locked));
            assert!(e.contains("locked"), "{e}");
            assert!(listing(&locked).is_empty());
        }
        std::fs::set_permissions(&locked, std::fs::Permissions::from_mode(0o755)).unwrap();
    }
    // A folder no one can create files in, even root: the first file named, nothing written.
    #[cfg(target_os = "linux")]
    {
        let e = refused(&spec(&robot, &template, Path::new("/proc/self")));
        assert!(e.contains("/proc/self/calibration.yaml"), "{e}");
    }

    // Keys other formats take, and a measurement frame that is a link.
    let e = refused(&format!(
        "{}nominal = \"ge-a4\"\n",
        spec(&robot, &template, &out)
    ));
    assert!(e.contains("ros export takes no nominal"), "{e}");
    let e = refused(&format!(
        "{}measurement_frame = \"link3\"\n",
        spec(&robot, &template, &out)
    ));
    assert!(
        e.contains("`link3`") && e.contains("link of the URDF"),
        "{e}"
    );
    let e = refused(&format!(
        "{}measurement_frame = \"a b\"\n",
        spec(&robot, &template, &out)
    ));
    assert!(e.contains("not a TF frame name"), "{e}");
    assert!(listing(&out).is_empty(), "{:?}", listing(&out));
}

#[test]
fn malformed_yaml_is_refused_with_its_line() {
    let good = "robot: r\nhash: h\njoints:\n  a:\n    x: 1.0\n    y: 0.0\n    z: 0.0\n    roll: 0.0\n    pitch: 0.0\n    yaw: 0.0\n";
    assert_eq!(parse_calibration(good, "c.yaml").unwrap().joints.len(), 1);
    for (bad, line, what) in [
        (
            good.replace("    y: 0.0", "    y: zero"),
            "c.yaml:6",
            "expected a number",
        ),
        (good.replace("    y: 0.0\n", ""), "c.yaml", "lacks `y`"),
        (good.replace("    yaw", "    w"), "c.yaml:10", "unknown key"),
        (
            good.replace("hash: h", "hash: h\nhash: g"),
            "c.yaml:3",
            "given twice",
        ),
        (
            good.replace("robot: r", "robot r"),
            "c.yaml:1",
            "expected `key: value`",
        ),
    ] {
        let e = parse_calibration(&bad, "c.yaml").unwrap_err().to_string();
        assert!(e.contains(line) && e.contains(what), "{e}");
    }
    let t = "robot: r\ntransforms:\n  - parent: w\n    child: b\n    x: 0.0\n    y: 0.0\n    z: 0.0\n    qx: 0.0\n    qy: 0.0\n    qz: 0.0\n    qw: 0.5\n";
    let e = parse_transforms(t, "t.yaml").unwrap_err().to_string();
    assert!(e.contains("quaternion"), "{e}");
}

/// A 640 x 480 camera of 600 px focal length (the set-up of tests/cameras.rs).
fn camera(name: &str, mount: Mount, pose: Link) -> Camera {
    Camera {
        name: name.into(),
        mount,
        pose,
        fx: 600.0,
        fy: 610.0,
        cx: 320.0,
        cy: 240.0,
        distortion: [-0.2, 0.0, 0.0, 0.0, 0.0],
        width: 640,
        height: 480,
    }
}

/// A 9 x 6 board of 25 mm.
fn board(name: &str, mount: Mount, pose: Link) -> Board {
    Board {
        name: name.into(),
        mount,
        pose,
        cols: 9,
        rows: 6,
        spacing: 0.025,
    }
}

/// A hand-eye pose: a few centimetres off the flange, turned.
const HAND_EYE: Link = Link {
    x: 0.03,
    y: -0.05,
    z: 0.04,
    alpha: 0.05,
    beta: -0.03,
    gamma: 2.9,
};

/// A fixed camera or board, in the global frame: a metre out, turned.
const BESIDE: Link = Link {
    x: 0.9,
    y: -0.4,
    z: 0.6,
    alpha: 2.2,
    beta: 0.4,
    gamma: -2.6,
};

/// Exports `cal` and checks each camera's and board's static transform: the chain of the
/// written files to `<camera>_optical_frame` (or `<board>`) in the measurement frame (the
/// measurement frame's transform inverted, the expanded xacro's origins and joint motions from
/// the base link to the parent link, the camera's own transform; or the camera's transform
/// alone when its parent is the measurement frame) equals kinecal's frame of the camera (its mount's frame at the
/// posture then its pose) to 1e-12 m and 1e-12 at 50 postures. Returns the parents.
fn check_cameras(cal: &Robot, template: &str, tips: &[&str]) -> Vec<(String, String)> {
    let e = export_ros(cal, template, "t.urdf", None, tips, None).unwrap();
    let tf = parse_transforms(&e.transforms_yaml, "static_transforms.yaml").unwrap();
    assert_eq!(
        tf.transforms.len(),
        1 + cal.sessions.len() + cal.cameras.len() + cal.boards.len()
    );
    let cal_yaml = parse_calibration(&e.calibration, "calibration.yaml").unwrap();
    let urdf =
        urdf_rs::read_from_string(&expand_xacro(&e.xacro, &cal_yaml.joints, "x").unwrap()).unwrap();
    let frame = |v: &[f64; 7]| {
        let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(v[6], v[3], v[4], v[5]));
        let mut m = q.to_homogeneous();
        m.fixed_view_mut::<3, 1>(0, 3)
            .copy_from(&Vector3::new(v[0], v[1], v[2]));
        m
    };
    let base = tf.transforms[0].parent.clone();
    let mframe = tf.transforms[0].child.clone();
    let placement = frame(&tf.transforms[0].values).try_inverse().unwrap();
    let names: Vec<String> = cal.joints.iter().map(|j| j.name.clone().unwrap()).collect();
    let chain = kinecal::Chain::new(cal);
    let mounted: Vec<(String, Mount, Link)> = cal
        .cameras
        .iter()
        .map(|c| (format!("{}_optical_frame", c.name), c.mount, c.pose))
        .chain(cal.boards.iter().map(|b| (b.name.clone(), b.mount, b.pose)))
        .collect();
    let mut parents = Vec::new();
    for (child, mount, pose) in &mounted {
        let t = tf.transforms.iter().find(|t| &t.child == child).unwrap();
        assert!(t.values[6] >= 0.0);
        parents.push((child.clone(), t.parent.clone()));
        let mut worst: (f64, f64) = (0.0, 0.0);
        for p in simulate::sample_postures(cal, 50, 3) {
            let q = |n: &str| p.readings[names.iter().position(|m| m == n).unwrap()];
            // The written chain in the measurement frame (kinecal's global frame): the base
            // link there (the inverse of the measurement frame's transform), the URDF to the
            // parent link, then the static transform.
            let to_parent = if t.parent == mframe {
                Matrix4::identity()
            } else {
                placement * urdf_fk(&urdf, &base, &t.parent, &q)
            };
            let written = to_parent * frame(&t.values);
            // kinecal's: the mount's frame at the posture, then the pose.
            let at = match mount {
                Mount::Base => Frame::identity(),
                Mount::EndEffector => chain.frame_at(&p.readings, Target::EndEffector),
                Mount::Site(s) => chain.frame_at(&p.readings, Target::Site(*s)),
            };
            let f = homogeneous(&at.then(&Frame::from_link(pose)));
            let dp = (written.fixed_view::<3, 1>(0, 3) - f.fixed_view::<3, 1>(0, 3)).norm();
            let dr = (written.fixed_view::<3, 3>(0, 0) - f.fixed_view::<3, 3>(0, 0)).norm();
            worst = (worst.0.max(dp), worst.1.max(dr));
        }
        assert!(worst.0 < 1e-12 && worst.1 < 1e-12, "{child}: {worst:?}");
        eprintln!(
            "{child} (on {}): largest deviation {:e} m, {:e}",
            t.parent, worst.0, worst.1
        );
    }
    parents
}

#[test]
fn an_eye_in_hand_camera_hangs_from_the_tool_link_and_its_board_from_the_measurement_frame() {
    let text = random_arm_urdf(6, 1);
    for tip in ["tool0", "link6"] {
        let robot = import_urdf_tree(&text, "arm.urdf", None, &[tip])
            .unwrap()
            .robot;
        let mut cal = calibrated(&robot, 4);
        cal.cameras
            .push(camera("wrist", Mount::EndEffector, HAND_EYE));
        cal.boards.push(board("board", Mount::Base, BESIDE));
        cal.validate().unwrap();
        // The tool link: the template's tip, or the `_calibrated` link added after a tip that
        // is the last movable joint's child.
        let tool = if tip == "link6" {
            "link6_calibrated"
        } else {
            "tool0"
        };
        assert_eq!(
            check_cameras(&cal, &text, &[tip]),
            [
                ("wrist_optical_frame".to_string(), tool.to_string()),
                ("board".to_string(), "measurement".to_string())
            ]
        );
    }
}

#[test]
fn an_eye_to_hand_camera_hangs_from_the_measurement_frame() {
    let text = random_arm_urdf(6, 2);
    let robot = import_urdf_tree(&text, "arm.urdf", None, &["tool0"])
        .unwrap()
        .robot;
    let mut cal = calibrated(&robot, 5);
    cal.cameras.push(camera("fixed cam", Mount::Base, BESIDE));
    cal.boards
        .push(board("target", Mount::EndEffector, HAND_EYE));
    cal.validate().unwrap();
    let e = export_ros(&cal, &text, "t.urdf", None, &["tool0"], None).unwrap();
    // A name TF cannot carry is published with `_`, and said so.
    assert!(
        e.notes
            .iter()
            .any(|n| n.contains("`fixed_cam_optical_frame`")),
        "{:?}",
        e.notes
    );
    assert!(
        e.transforms_yaml.contains(
            "  # camera `fixed cam`'s optical frame (z along the optical axis, x right, y down)\n  - parent: measurement\n    child: fixed_cam_optical_frame\n"
        ),
        "{}",
        e.transforms_yaml
    );
    cal.cameras[0].name = "fixed_cam".into();
    assert_eq!(
        check_cameras(&cal, &text, &["tool0"]),
        [
            (
                "fixed_cam_optical_frame".to_string(),
                "measurement".to_string()
            ),
            ("target".to_string(), "tool0".to_string())
        ]
    );
}

#[test]
fn a_camera_on_a_site_hangs_from_that_tip_and_bad_frames_are_refused() {
    let text = std::fs::read_to_string(repo().join("examples/trees/upper_body.urdf")).unwrap();
    let tips = ["left_marker", "right_marker"];
    let robot = import_urdf_tree(&text, "upper_body.urdf", None, &tips)
        .unwrap()
        .robot;
    let mut cal = calibrated(&robot, 3);
    cal.cameras
        .push(camera("left_cam", Mount::Site(0), HAND_EYE));
    cal.boards.push(board("board", Mount::EndEffector, BESIDE));
    cal.validate().unwrap();
    assert_eq!(
        check_cameras(&cal, &text, &tips),
        [
            (
                "left_cam_optical_frame".to_string(),
                "left_marker".to_string()
            ),
            ("board".to_string(), "right_marker".to_string())
        ]
    );
    // A frame that is a link, the measurement frame or a session's is refused.
    let refused = |cal: &Robot| {
        export_ros(cal, &text, "t.urdf", None, &tips, None)
            .unwrap_err()
            .to_string()
    };
    let mut bad = cal.clone();
    bad.boards[0].name = "chest".into();
    let e = refused(&bad);
    assert!(
        e.contains("`chest`") && e.contains("link of the URDF"),
        "{e}"
    );
    bad.boards[0].name = "measurement".into();
    let e = refused(&bad);
    assert!(e.contains("the measurement frame"), "{e}");
    bad.boards[0].name = "A".into();
    let e = refused(&bad);
    assert!(e.contains("`A`") && e.contains("published twice"), "{e}");
    // A site the template does not end in has no link to hang from.
    let mut extra = cal.clone();
    extra.sites.push(kinecal::model::robot::Site {
        name: "bracket".into(),
        joint: 1,
        frame: HAND_EYE,
    });
    extra.cameras[0].mount = Mount::Site(extra.sites.len() - 1);
    extra.validate().unwrap();
    let e = refused(&extra);
    assert!(e.contains("`bracket`") && e.contains("not a tip"), "{e}");
}
