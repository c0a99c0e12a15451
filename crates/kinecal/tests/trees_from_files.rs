//! Trees from real files (issue 37, item 6): a dual-arm robot on a torso (one torso axis and two
//! 6-axis arms, 13 joints), built from the real UR5 URDF of `../shared/data` grafted twice onto a
//! torso, its joints named as a controller names them (upper case). Every command that reads
//! postures takes the joints' names as headers, in any order; a tool frame is called `ee` or by
//! its own name whether the robot is a chain or a tree; a chain reads a file written for the
//! tree past the other joints' columns, with a note naming them; and a DH table of the tree (a
//! table per branch, the shared joints named once) is the tree it describes.

#[path = "common/shared_data.rs"]
mod shared_data;

use std::f64::consts::FRAC_PI_2;
use std::path::Path;

use kinecal::files::{parse_measurements, parse_postures, site_target};
use kinecal::import::dh::import_dh;
use kinecal::import::urdf::{import_urdf, import_urdf_tree};
use kinecal::model::robot_file::write_robot_toml;
use kinecal::spec::{Done, Env, Job, Message};
use kinecal::{Chain, Robot, Target};
use nalgebra::{Matrix4, Vector3};
use rand::{RngExt, SeedableRng};

/// The torso's joint and each arm's six, as the robot's controller names them.
const ARM_JOINTS: [&str; 6] = ["S", "L", "U", "R", "B", "T"];
const UR5_JOINTS: [&str; 6] = [
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "elbow_joint",
    "wrist_1_joint",
    "wrist_2_joint",
    "wrist_3_joint",
];

/// The dual-arm URDF: the real UR5 description twice (its joints renamed `LEFT_S..LEFT_T`,
/// `RIGHT_S..RIGHT_T`, its links prefixed), each arm's `world` link mounted on a torso that
/// turns about the vertical (`TORSO`). `None` without the shared data.
fn dual_arm_urdf() -> Option<String> {
    let path = shared_data::shared_data("urdf/universal_robots/urdf_plain/ur5_robot.urdf")?;
    let ur5 = std::fs::read_to_string(path).unwrap();
    let open = ur5.find("<robot").unwrap();
    let body = &ur5[ur5[open..].find('>').unwrap() + open + 1..ur5.find("</robot>").unwrap()];
    let arm = |side: &str| {
        let mut text = body
            .replace(" name=\"", &format!(" name=\"{side}_"))
            .replace(" link=\"", &format!(" link=\"{side}_"));
        for (ur, ours) in UR5_JOINTS.iter().zip(ARM_JOINTS) {
            text = text.replace(&format!("\"{side}_{ur}\""), &format!("\"{side}_{ours}\""));
        }
        text
    };
    Some(format!(
        r#"<?xml version="1.0"?>
<robot name="dual_arm">
  <link name="world"/>
  <link name="torso"/>
  <joint name="TORSO" type="revolute">
    <parent link="world"/><child link="torso"/>
    <origin xyz="0 0 0.8" rpy="0 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="100" velocity="1"/>
  </joint>
  <joint name="LEFT_mount" type="fixed">
    <parent link="torso"/><child link="LEFT_world"/>
    <origin xyz="0 0.25 0.4" rpy="-1.5707963267948966 0 0"/>
  </joint>
  <joint name="RIGHT_mount" type="fixed">
    <parent link="torso"/><child link="RIGHT_world"/>
    <origin xyz="0 -0.25 0.4" rpy="1.5707963267948966 0 0"/>
  </joint>
{}{}</robot>
"#,
        arm("LEFT"),
        arm("RIGHT")
    ))
}

/// The tree: the left tool a site, the right tool the end effector.
fn dual_arm() -> Option<Robot> {
    let text = dual_arm_urdf()?;
    let robot = import_urdf_tree(&text, "dual_arm.urdf", None, &["LEFT_tool0", "RIGHT_tool0"])
        .unwrap()
        .robot;
    assert_eq!(robot.dof(), 13);
    Some(robot)
}

/// The joint names of the tree, in its order.
fn joint_names(robot: &Robot) -> Vec<String> {
    robot
        .joints
        .iter()
        .map(|j| j.name.clone().unwrap())
        .collect()
}

/// Random readings (rad) for `n` joints, `count` postures.
fn random_postures(n: usize, count: usize, seed: u64) -> Vec<Vec<f64>> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    (0..count)
        .map(|_| (0..n).map(|_| rng.random_range(-2.5..2.5)).collect())
        .collect()
}

/// A postures file of `postures` for the joints `names`, its columns in the order `order`
/// (indices into `names`), headed by `header(name)`.
fn postures_file(
    names: &[String],
    postures: &[Vec<f64>],
    order: &[usize],
    header: impl Fn(&str) -> String,
) -> String {
    let mut text = String::from("posture");
    for &j in order {
        text += &format!(",{}", header(&names[j]));
    }
    text.push('\n');
    for (i, p) in postures.iter().enumerate() {
        text += &(i + 1).to_string();
        for &j in order {
            text += &format!(",{:?}", p[j]);
        }
        text.push('\n');
    }
    text
}

fn run(toml: &str) -> kinecal::Result<Done> {
    let job = Job::from_toml(toml, "job.toml")?;
    let mut quiet = ();
    kinecal::spec::run(&job, &mut Env::new(&mut quiet, None))
}

fn write(dir: &Path, name: &str, text: &str) -> String {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path.display().to_string()
}

fn notes(done: &Done) -> Vec<String> {
    done.messages
        .iter()
        .filter_map(|m| match m {
            Message::Note(n) => Some(n.clone()),
            _ => None,
        })
        .collect()
}

/// A shuffled column order of `n` joints.
fn shuffled(n: usize, seed: u64) -> Vec<usize> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut order: Vec<usize> = (0..n).collect();
    for i in (1..n).rev() {
        order.swap(i, rng.random_range(0..=i));
    }
    order
}

#[test]
fn every_command_that_reads_postures_takes_the_joints_names_in_any_order() {
    let Some(robot) = dual_arm() else { return };
    let dir = tempfile::tempdir().unwrap();
    let robot_path = write(dir.path(), "dual.toml", &write_robot_toml(&robot, None));
    let names = joint_names(&robot);
    let postures = random_postures(13, 12, 1);
    let order = shuffled(13, 2);
    let by_v = postures_file(&names, &postures, &(0..13).collect::<Vec<_>>(), |n| {
        format!("v{}", names.iter().position(|m| m == n).unwrap() + 1)
    });
    // As the controller writes them (upper case), and in lower case: headers ignore case.
    for (tag, header) in [
        (
            "upper",
            Box::new(|n: &str| n.to_string()) as Box<dyn Fn(&str) -> String>,
        ),
        ("lower", Box::new(|n: &str| n.to_ascii_lowercase())),
    ] {
        let named = write(
            dir.path(),
            &format!("named_{tag}.csv"),
            &postures_file(&names, &postures, &order, header),
        );
        let plain = write(dir.path(), "plain.csv", &by_v);
        // fk: the same poses, digit for digit, from either file.
        let fk = |postures: &str, out: &str| {
            let out = dir.path().join(out).display().to_string();
            run(&format!(
                "job = \"fk\"\nrobot = {robot_path:?}\npostures = {postures:?}\nout = {out:?}\n"
            ))
            .unwrap_or_else(|e| panic!("fk {postures}: {e}"));
            std::fs::read_to_string(out).unwrap()
        };
        assert_eq!(fk(&named, "named_poses.csv"), fk(&plain, "plain_poses.csv"));
        // compensate: a program of postures (the nominal robot is its own calibration here).
        let compensate = |input: &str, out: &str| {
            let out = dir.path().join(out).display().to_string();
            run(&format!(
                "job = \"compensate\"\nrobot = {robot_path:?}\nnominal = {robot_path:?}\n\
                 in = {input:?}\nout = {out:?}\n"
            ))
            .unwrap_or_else(|e| panic!("compensate {input}: {e}"));
            std::fs::read_to_string(out).unwrap()
        };
        assert_eq!(
            compensate(&named, "named_cal.csv"),
            compensate(&plain, "plain_cal.csv")
        );
        // analyze and plan: the same postures, so the same numbers.
        for job in [
            format!("job = \"analyze\"\nrobot = {robot_path:?}\npostures = "),
            format!("job = \"plan\"\nrobot = {robot_path:?}\ncount = 5\ncandidates = "),
        ] {
            let a = run(&format!("{job}{named:?}\n")).unwrap_or_else(|e| panic!("{job}: {e}"));
            let b = run(&format!("{job}{plain:?}\n")).unwrap();
            assert_eq!(
                a.document.to_json().replace(&named, "F"),
                b.document.to_json().replace(&plain, "F"),
                "{job}"
            );
        }
        // The library's reader, to the same readings.
        let read = parse_postures(&std::fs::read_to_string(&named).unwrap(), "n.csv", &robot);
        let read: Vec<Vec<f64>> = read.unwrap().into_iter().map(|p| p.readings).collect();
        assert_eq!(read, postures);
    }
}

#[test]
fn a_tool_frame_is_called_ee_or_by_its_link_in_a_chain_as_in_a_tree() {
    let Some(text) = dual_arm_urdf() else { return };
    let tree = import_urdf_tree(&text, "dual_arm.urdf", None, &["LEFT_tool0", "RIGHT_tool0"])
        .unwrap()
        .robot;
    let chain = import_urdf(&text, "dual_arm.urdf", None, Some("RIGHT_tool0"))
        .unwrap()
        .robot;
    let left = import_urdf(&text, "dual_arm.urdf", None, Some("LEFT_tool0"))
        .unwrap()
        .robot;
    for (robot, what) in [(&tree, "tree"), (&chain, "chain")] {
        for name in ["ee", "RIGHT_tool0"] {
            assert_eq!(
                site_target(robot, name),
                Ok(Target::EndEffector),
                "{what}: {name}"
            );
        }
        // Written to its robot file and read back, the name stays.
        let back =
            kinecal::model::robot_file::parse_robot_toml(&write_robot_toml(robot, None), "r.toml")
                .unwrap();
        assert_eq!(
            Target::named(&back, "RIGHT_tool0"),
            Some(Target::EndEffector)
        );
    }
    assert_eq!(site_target(&tree, "LEFT_tool0"), Ok(Target::Site(0)));
    assert_eq!(site_target(&left, "LEFT_tool0"), Ok(Target::EndEffector));
    let e = site_target(&chain, "LEFT_tool0").unwrap_err();
    assert!(e.contains("ee, RIGHT_tool0"), "{e}");

    // The same measurement file, `site` naming the right tool by its link, read by both: the
    // chain (the torso and the right arm, 7 joints) past the left arm's columns.
    let names = joint_names(&tree);
    let postures = random_postures(13, 3, 5);
    let chain_tree = Chain::new(&tree);
    let mut file = format!("posture,site,{},x,y,z\n", names.join(","));
    for (i, p) in postures.iter().enumerate() {
        let at = chain_tree.frame_at(p, Target::EndEffector).translation;
        let readings: Vec<String> = p.iter().map(|v| format!("{v:?}")).collect();
        for site in ["RIGHT_tool0", "ee"] {
            file += &format!(
                "{}{site},{site},{},{:?},{:?},{:?}\n",
                i + 1,
                readings.join(","),
                at.x,
                at.y,
                at.z
            );
        }
    }
    let by_tree = parse_measurements(&file, "m.csv", &tree).unwrap();
    let by_chain = parse_measurements(&file, "m.csv", &chain).unwrap();
    assert_eq!(by_tree.observations.len(), 6);
    assert_eq!(by_tree.observations, by_chain.observations);
    assert!(by_chain
        .observations
        .iter()
        .all(|o| o.measured_frame().0 == Target::EndEffector));
}

#[test]
fn a_chain_reads_a_file_of_the_tree_past_the_other_joints_columns() {
    let Some(text) = dual_arm_urdf() else { return };
    let tree = import_urdf_tree(&text, "dual_arm.urdf", None, &["LEFT_tool0", "RIGHT_tool0"])
        .unwrap()
        .robot;
    // The torso and the right arm as a chain of their own.
    let right = import_urdf(&text, "dual_arm.urdf", None, Some("RIGHT_tool0"))
        .unwrap()
        .robot;
    assert_eq!(right.dof(), 7);
    let names = joint_names(&tree);
    let path: Vec<usize> = joint_names(&right)
        .iter()
        .map(|n| names.iter().position(|m| m == n).unwrap())
        .collect();
    let postures = random_postures(13, 10, 7);
    let dir = tempfile::tempdir().unwrap();
    let right_path = write(dir.path(), "right.toml", &write_robot_toml(&right, None));
    let file = write(
        dir.path(),
        "tree_postures.csv",
        &postures_file(&names, &postures, &shuffled(13, 8), |n| n.to_string()),
    );
    // The library's reader: the chain's own readings.
    let text13 = std::fs::read_to_string(&file).unwrap();
    let read = parse_postures(&text13, "tree_postures.csv", &right).unwrap();
    for (p, q) in read.iter().zip(&postures) {
        let own: Vec<f64> = path.iter().map(|&j| q[j]).collect();
        assert_eq!(p.readings, own);
    }
    // fk of the chain at the tree's postures: where the tree puts its right tool, and a note
    // naming the six left-arm columns it read past.
    let out = dir.path().join("poses.csv").display().to_string();
    let done = run(&format!(
        "job = \"fk\"\nrobot = {right_path:?}\npostures = {file:?}\nout = {out:?}\n"
    ))
    .unwrap();
    let note = notes(&done).join("\n");
    for j in ARM_JOINTS {
        assert!(note.contains(&format!("`LEFT_{j}`")), "{note}");
        assert!(!note.contains(&format!("`RIGHT_{j}`")), "{note}");
    }
    assert!(
        note.contains("tree_postures.csv") && note.contains("read past"),
        "{note}"
    );
    let poses =
        parse_measurements(&std::fs::read_to_string(&out).unwrap(), "p.csv", &right).unwrap();
    let tree_chain = Chain::new(&tree);
    for o in &poses.observations {
        let kinecal::Observation::Pose(p) = o else {
            panic!("poses")
        };
        let want = tree_chain
            .frame_at(&postures[o.posture()], Target::EndEffector)
            .translation;
        assert!((p.position - want).norm() < 1e-12, "{}", p.position - want);
    }
    // A measurement file of the tree's right tool, read by the chain: the same note.
    let mut measured = format!("posture,site,{},x,y,z\n", names.join(","));
    for (i, p) in postures.iter().enumerate() {
        let readings: Vec<String> = p.iter().map(|v| format!("{v:?}")).collect();
        measured += &format!("{},RIGHT_tool0,{},0,0,0\n", i + 1, readings.join(","));
    }
    let _ = kinecal::files::take_notes();
    let data = parse_measurements(&measured, "m.csv", &right).unwrap();
    assert_eq!(data.postures.len(), 10);
    let said = kinecal::files::take_notes().join("\n");
    assert!(
        said.contains("m.csv") && said.contains("`LEFT_T`"),
        "{said}"
    );
    // A joint of the chain missing by name is still an error naming it, not a note.
    let short = text13.replace("RIGHT_B", "RIGHT_X");
    let e = parse_postures(&short, "short.csv", &right)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("short.csv") && e.contains("unexpected header"),
        "{e}"
    );
    // `vK` columns say nothing of which joint they are: still refused.
    let by_v = postures_file(&names, &postures, &(0..13).collect::<Vec<_>>(), |n| {
        format!("v{}", names.iter().position(|m| m == n).unwrap() + 1)
    });
    assert!(parse_postures(&by_v, "v.csv", &right).is_err());
}

/// The UR5's standard DH lengths from its description (`physical_parameters.yaml`):
/// `d1, a2, a3, d4, d5, d6` (m).
fn ur5_dh() -> Option<[f64; 6]> {
    let path =
        shared_data::shared_data("urdf/universal_robots/config/ur5/physical_parameters.yaml")?;
    let text = std::fs::read_to_string(path).unwrap();
    let value = |key: &str| -> f64 {
        text.lines()
            .find_map(|l| l.trim().strip_prefix(&format!("{key}:")))
            .unwrap()
            .split('#')
            .next()
            .unwrap()
            .trim()
            .parse()
            .unwrap()
    };
    Some(["d1", "a2", "a3", "d4", "d5", "d6"].map(value))
}

/// A standard DH row's transform at joint value `q` (revolute): `Rz(theta + q) Tz(d) Tx(a)
/// Rx(alpha)`, as the textbook multiplies it.
fn dh_matrix(a: f64, alpha: f64, d: f64, theta: f64) -> Matrix4<f64> {
    let (st, ct) = theta.sin_cos();
    let (sa, ca) = alpha.sin_cos();
    Matrix4::new(
        ct,
        -st * ca,
        st * sa,
        a * ct,
        st,
        ct * ca,
        -ct * sa,
        a * st,
        0.0,
        sa,
        ca,
        d,
        0.0,
        0.0,
        0.0,
        1.0,
    )
}

/// A row of the test's table: name, kind, a, alpha, d, theta.
type Row = (String, &'static str, f64, f64, f64, f64);

#[test]
fn a_dh_table_per_branch_is_the_tree_it_describes() {
    let Some([d1, a2, a3, d4, d5, d6]) = ur5_dh() else {
        return;
    };
    let arm = |side: &str, sign: f64| -> Vec<Row> {
        let r = |j: usize, a, alpha, d| {
            (
                format!("{side}_{}", ARM_JOINTS[j]),
                "revolute",
                a,
                alpha,
                d,
                0.0,
            )
        };
        vec![
            // The shoulder: 0.4 m up the torso, the arm's first axis turned to point out to
            // its side, and 0.25 m along it.
            (
                format!("{side}_shoulder"),
                "fixed",
                0.0,
                -sign * FRAC_PI_2,
                0.4,
                0.0,
            ),
            (format!("{side}_mount"), "fixed", 0.0, 0.0, 0.25, 0.0),
            r(0, 0.0, FRAC_PI_2, d1),
            r(1, a2, 0.0, 0.0),
            r(2, a3, 0.0, 0.0),
            r(3, 0.0, FRAC_PI_2, d4),
            r(4, 0.0, -FRAC_PI_2, d5),
            r(5, 0.0, 0.0, d6),
        ]
    };
    let torso: Vec<Row> = vec![("TORSO".into(), "revolute", 0.0, 0.0, 0.8, 0.3)];
    let (left, right) = (arm("LEFT", 1.0), arm("RIGHT", -1.0));
    let rows = |rows: &[Row]| -> String {
        rows.iter()
            .map(|(n, k, a, al, d, t)| format!("{n},{k},{a:?},{al:?},{d:?},{t:?}\n"))
            .collect()
    };
    let head = "# a torso and two UR5 arms\n# length_unit = m\n# angle_unit = rad\n\
                # convention = standard\nname,kind,a,alpha,d,theta\n";
    let table = format!(
        "{head}{}# branch = LEFT_tool0, from = TORSO\n{}# branch = RIGHT_tool0, from = TORSO\n{}",
        rows(&torso),
        rows(&left),
        rows(&right)
    );
    let tree = import_dh(&table, "dual.csv", "dual", None, None, None).unwrap();
    assert_eq!(tree.dof(), 13);
    assert_eq!(tree.end_effector.as_deref(), Some("RIGHT_tool0"));
    assert_eq!(tree.sites[0].name, "LEFT_tool0");
    let names = joint_names(&tree);
    assert_eq!(names[0], "TORSO");
    assert_eq!(names[1], "LEFT_S");
    assert_eq!(names[12], "RIGHT_T");
    assert_eq!(
        tree.joints[7].parent,
        Some(1),
        "the right arm hangs from the torso"
    );

    // Each branch as a plain chain table (the torso's rows, then the arm's) through the chain
    // importer, and each as the textbook's product of DH matrices: the tree's tips agree with
    // both at random postures.
    let chain_of = |arm: &[Row]| {
        let text = format!("{head}{}{}", rows(&torso), rows(arm));
        import_dh(&text, "chain.csv", "chain", None, None, None).unwrap()
    };
    let tree_chain = Chain::new(&tree);
    let mut largest = 0.0f64;
    for (arm, target, first) in [
        (&left, Target::Site(0), 1),
        (&right, Target::EndEffector, 7),
    ] {
        let serial = chain_of(arm);
        let serial_chain = Chain::new(&serial);
        for q in random_postures(13, 50, 11) {
            let own: Vec<f64> = std::iter::once(q[0])
                .chain(q[first..first + 6].iter().copied())
                .collect();
            let a = tree_chain.frame_at(&q, target);
            let b = serial_chain.frame_at(&own, Target::EndEffector);
            let mut m = Matrix4::identity();
            let mut k = 0;
            for (_, kind, a_, al, d, t) in torso.iter().chain(arm.iter()) {
                let q = if *kind == "revolute" {
                    k += 1;
                    own[k - 1]
                } else {
                    0.0
                };
                m *= dh_matrix(*a_, *al, *d, t + q);
            }
            let textbook = Vector3::new(m[(0, 3)], m[(1, 3)], m[(2, 3)]);
            let rotation = m.fixed_view::<3, 3>(0, 0).into_owned();
            for (p, r) in [(b.translation, b.rotation), (textbook, rotation)] {
                largest = largest
                    .max((a.translation - p).norm())
                    .max((a.rotation - r).norm());
            }
        }
    }
    eprintln!(
        "largest difference of the tree's tips from the chains and the textbook: {largest:e}"
    );
    assert!(largest < 1e-12, "{largest:e}");

    // The names head the reading columns.
    let header = names.iter().rev().cloned().collect::<Vec<_>>().join(",");
    let values: Vec<String> = (0..13).rev().map(|j| j.to_string()).collect();
    let p = parse_postures(
        &format!("posture,{header}\n1,{}\n", values.join(",")),
        "p.csv",
        &tree,
    )
    .unwrap();
    assert_eq!(p[0].readings, (0..13).map(f64::from).collect::<Vec<_>>());

    // What a slip in the table says.
    for (from, to, says) in [
        (
            "from = TORSO\nRIGHT",
            "from = TORSE\nRIGHT",
            "dual.csv:16: field `from`: no row named `TORSE`",
        ),
        (
            "# branch = RIGHT_tool0",
            "# branch = RIGHT_tool0, to = x",
            "unknown key `to`",
        ),
        ("LEFT_L,", "LEFT_S,", "row name `LEFT_S` used twice"),
    ] {
        let bad = table.replacen(from, to, 1);
        let e = import_dh(&bad, "dual.csv", "dual", None, None, None)
            .unwrap_err()
            .to_string();
        assert!(e.contains(says), "{to}: {e}");
    }
    // The end effector's branch has joints of its own, and comes last.
    let marker_last = format!("{table}# branch = marker, from = TORSO\n");
    let e = import_dh(&marker_last, "dual.csv", "dual", None, None, None)
        .unwrap_err()
        .to_string();
    assert!(e.contains("must end with the table's last joint"), "{e}");
}
