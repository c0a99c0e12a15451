//! Tree-structured robots (two arms on one torso): each branch is the serial chain through it
//! (an independent construction from the robot's fields), the robot file and the measurement
//! files carry the tree, the thesis's count holds for it, and one fit of the tree determines
//! both arms where two separate chains, each from its own few postures, cannot.

use kinecal::apps::simulate::{self, PerturbStd};
use kinecal::identifiability::{analyze, AnalysisOptions};
use kinecal::model::robot_file::{parse_robot_toml, write_robot_toml};
use kinecal::observe::point::Pose;
use kinecal::workflow::{run, Request, Selection};
use kinecal::{Chain, Dataset, Observation, ParamId, Posture, Robot, Target, Workspace};

/// The serial robot through `robot`'s tree to `target` ([`Robot::branch`]: built from the
/// robot's fields by walking the parents, not by the kinematics code).
fn branch(robot: &Robot, target: Target) -> (Robot, Vec<usize>) {
    let site = match target {
        Target::EndEffector => None,
        Target::Site(s) => Some(s),
    };
    robot.branch(site).expect("no couplings")
}

fn tips() -> [Target; 2] {
    [Target::Site(0), Target::EndEffector]
}

#[test]
fn each_branch_is_the_serial_chain_through_it() {
    // Two arms on a torso; and two robots measured in one frame (a tree with a fixed root:
    // the second robot's first joint hangs off the global frame).
    for (robot, lengths) in [
        (simulate::random_tree(3, &[4, 5], 7), [7, 8]),
        (simulate::random_tree(0, &[6, 6], 8), [6, 6]),
    ] {
        branches_match(&robot, lengths);
    }
    let two = simulate::random_tree(0, &[6, 6], 8);
    assert_eq!(two.joints[6].parent, Some(0));
}

fn branches_match(robot: &Robot, lengths: [usize; 2]) {
    let robot = robot.clone();
    assert!(robot.is_tree());
    let chain = Chain::new(&robot);
    let mut ws = Workspace::new(&robot);
    let n = robot.dof();
    let mut jac = vec![0.0; 6 * n];
    for target in tips() {
        let (serial, path) = branch(&robot, target);
        assert_eq!(
            path.len(),
            if target == Target::EndEffector {
                lengths[1]
            } else {
                lengths[0]
            }
        );
        let sc = Chain::new(&serial);
        let mut sws = Workspace::new(&serial);
        let mut sjac = vec![0.0; 6 * serial.dof()];
        for p in simulate::sample_postures(&robot, 20, 3) {
            chain.forward(&p.readings, &mut ws);
            let own: Vec<f64> = path.iter().map(|&j| p.readings[j]).collect();
            sc.forward(&own, &mut sws);
            let (a, b) = (
                chain.target_frame(&ws, target),
                sc.target_frame(&sws, Target::EndEffector),
            );
            assert!((a.translation - b.translation).norm() < 1e-12);
            assert!((a.rotation - b.rotation).norm() < 1e-12);
            // The readings Jacobian: the path's joints as in the serial chain, the other arm's
            // exactly zero.
            chain.reading_jacobian(&ws, target, &mut jac);
            sc.reading_jacobian(&sws, Target::EndEffector, &mut sjac);
            for j in 0..n {
                let col = &jac[6 * j..6 * j + 6];
                match path.iter().position(|&k| k == j) {
                    Some(k) => {
                        for r in 0..6 {
                            assert!((col[r] - sjac[6 * k + r]).abs() < 1e-12);
                        }
                    }
                    None => assert!(col.iter().all(|&x| x == 0.0), "joint {j} moves {target:?}"),
                }
            }
        }
    }
}

const TREE_FILE: &str = r#"
name = "two arms"
length_unit = "m"
angle_unit = "deg"
end_effector = "right"
[[links]]
z = 0.3
[[links]]
x = 0.1
[[links]]
y = 0.2
alpha = 90
[[links]]
y = -0.2
alpha = -90
[[links]]
x = 0.15
[[joints]]
name = "waist"
kind = "revolute"
[[joints]]
name = "left_shoulder"
kind = "revolute"
[[joints]]
name = "right_shoulder"
kind = "revolute"
parent = "waist"
[[joints]]
name = "right_elbow"
kind = "revolute"
[[sites]]
name = "left"
joint = "left_shoulder"
x = 0.25
"#;

#[test]
fn the_robot_file_and_the_measurement_files_carry_the_tree() {
    let robot = parse_robot_toml(TREE_FILE, "tree.toml").expect("a tree robot file");
    assert_eq!(robot.joints[2].parent, Some(1), "by name: after the waist");
    assert_eq!(robot.joints[1].parent, None, "the previous joint");
    assert_eq!(robot.sites[0].joint, 2);
    assert_eq!(robot.end_effector.as_deref(), Some("right"));
    assert!(robot.joint_moves(0, 4) && !robot.joint_moves(1, 4) && robot.joint_moves(1, 2));
    // Written back, the names stay names and the numbers read back the same.
    let text = write_robot_toml(&robot, Some(TREE_FILE));
    assert!(text.contains("parent = \"waist\"") && text.contains("joint = \"left_shoulder\""));
    assert_eq!(parse_robot_toml(&text, "back.toml").unwrap(), robot);
    let fresh = write_robot_toml(&robot, None);
    assert!(fresh.contains("parent = 1"), "{fresh}");
    assert_eq!(parse_robot_toml(&fresh, "fresh.toml").unwrap(), robot);

    // Readings headed by the joints' names, in any order; rows name the tool they measured.
    let named = "posture,site,right_elbow,waist,left_shoulder,right_shoulder,x,y,z\n\
                 1,left,0.4,0.1,0.2,0.3,0.5,0.1,0.2\n\
                 2,right,0.4,0.1,0.2,0.3,0.4,0.0,0.1\n";
    let plain = "posture,site,v1,v2,v3,v4,x,y,z\n\
                 1,left,0.1,0.2,0.3,0.4,0.5,0.1,0.2\n\
                 2,ee,0.1,0.2,0.3,0.4,0.4,0.0,0.1\n";
    let a = kinecal::files::parse_measurements(named, "named.csv", &robot).unwrap();
    let b = kinecal::files::parse_measurements(plain, "plain.csv", &robot).unwrap();
    assert_eq!(a.postures[0].readings, vec![0.1, 0.2, 0.3, 0.4]);
    assert_eq!(a.observations, b.observations);
    let postures = kinecal::files::parse_postures(
        "posture,waist,right_elbow,right_shoulder,left_shoulder\n1,1,4,3,2\n",
        "p.csv",
        &robot,
    )
    .unwrap();
    assert_eq!(postures[0].readings, vec![1.0, 2.0, 3.0, 4.0]);
    // What kinecal writes names the end effector as the file does.
    let written = kinecal::files::write_measurements(&robot, &a);
    assert!(written.contains(",right,"), "{written}");

    // Bad trees are refused with the field that is wrong.
    for (bad, field, says) in [
        (
            "parent = \"waist\"",
            "parent = \"elbow\"",
            "no joint named `elbow`",
        ),
        (
            "parent = \"waist\"",
            "parent = 4",
            "a parent comes before its children",
        ),
        ("parent = \"waist\"", "parent = -1", "a joint number"),
        (
            "end_effector = \"right\"",
            "end_effector = \"left\"",
            "a site's name",
        ),
        ("name = \"right_elbow\"", "name = \"waist\"", "used twice"),
        (
            "name = \"right_elbow\"",
            "name = \"v2\"",
            "looks like a reading column",
        ),
    ] {
        let text = TREE_FILE.replace(bad, field);
        let e = parse_robot_toml(&text, "bad.toml").unwrap_err().to_string();
        assert!(e.contains(says) && e.contains("bad.toml"), "{field}: {e}");
    }
    let e = kinecal::files::parse_measurements(
        &named.replace("right_elbow", "elbow"),
        "named.csv",
        &robot,
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("no column `v4`"), "{e}");
}

#[test]
fn the_thesis_count_holds_for_a_tree() {
    let robot = simulate::random_tree(2, &[3, 4], 17);
    let n = robot.dof();
    let postures = simulate::sample_postures(&robot, 40, 5);
    let all: Vec<ParamId> = robot.param_ids().collect();
    let slopes = kinecal::parse_param_list("slopes", &robot).unwrap();
    let no_slopes: Vec<ParamId> = all
        .iter()
        .copied()
        .filter(|id| !slopes.contains(id))
        .collect();
    let both = simulate::measure(&robot, &postures, false);
    let a = analyze(&robot, &both, &no_slopes, &AnalysisOptions::default()).unwrap();
    // Every joint once (the torso's are shared), two tool frames.
    assert_eq!(a.rank, 4 * n + 12);
    assert_eq!(a.expected.unwrap().rank, 4 * n + 12);
    let a = analyze(&robot, &both, &all, &AnalysisOptions::default()).unwrap();
    assert_eq!(a.rank, 5 * n + 12, "slopes too");
    // One arm measured: the other arm's joints are not seen at all.
    let mut right = both.clone();
    right
        .observations
        .retain(|o| o.measured_frame().0 == Target::EndEffector);
    let a = analyze(&robot, &right, &no_slopes, &AnalysisOptions::default()).unwrap();
    assert_eq!(a.rank, 4 * (2 + 4) + 6);
    assert_eq!(a.expected.unwrap().rank, 4 * (2 + 4) + 6);
}

/// The RMS position error (mm, per coordinate) of `fit` against `truth` at `target`, over 100
/// fresh postures.
fn held_out(fit: &Robot, truth: &Robot, target: Target) -> f64 {
    let (a, b) = (Chain::new(fit), Chain::new(truth));
    let postures = simulate::sample_postures(truth, 100, 99);
    let sum: f64 = postures
        .iter()
        .map(|p| {
            let d = a.frame_at(&p.readings, target).translation
                - b.frame_at(&p.readings, target).translation;
            d.norm_squared()
        })
        .sum();
    (sum / (3.0 * postures.len() as f64)).sqrt() * 1e3
}

fn fit(nominal: &Robot, data: &Dataset, noise: f64) -> Robot {
    let mut req = Request::new(nominal.clone(), data.clone());
    req.selection = Selection::parse("identifiable", None, nominal).unwrap();
    req.weights = kinecal::observe::Weights {
        length: noise,
        angle: noise,
    };
    let out = run(&req, &mut ()).expect("calibration runs");
    assert!(out.calibration.converged());
    out.calibration.calibrated
}

#[test]
fn one_fit_of_the_tree_determines_both_arms_where_two_chains_cannot() {
    // A torso of 4 joints carrying two 7-joint arms (the humanoid of the issue), geometry off by
    // 1 mm and 0.1 deg. Each arm is measured (poses, 0.01 mm and 1e-5 rad noise) in 10
    // postures of its own: 60 rows per arm, against the 50 parameters a chain through torso and
    // arm has (4 x 11 + 6), while the tree has 2 x 60 rows for 84 (4 x 18 + 12): the torso,
    // estimated once from both arms' rows, leaves each arm's rows for its own parameters.
    let nominal = simulate::random_tree(4, &[7, 7], 23);
    let truth = simulate::perturb(
        &nominal,
        PerturbStd {
            length: 1e-3,
            angle: 0.1f64.to_radians(),
            slope_fraction: 0.0,
        },
        4,
    );
    let noise = 1e-5;
    let per_arm = 10;
    let postures = simulate::sample_postures(&truth, 2 * per_arm, 31);
    let mut data = simulate::measure(&truth, &postures, false);
    // The first postures measure the left arm, the others the right.
    data.observations.retain(|o| {
        let left = o.posture() < per_arm;
        (o.measured_frame().0 == Target::Site(0)) == left
    });
    simulate::add_noise(&mut data, noise, noise, 5);
    assert_eq!(data.observations.len(), 2 * per_arm);

    let tree = fit(&nominal, &data, noise);
    let tree_errors = tips().map(|t| held_out(&tree, &truth, t));

    // Each arm as its own chain, from the same rows.
    let chain_errors = tips().map(|target| {
        let (serial, path) = branch(&nominal, target);
        let (serial_truth, _) = branch(&truth, target);
        let own: Vec<Posture> = data
            .observations
            .iter()
            .filter(|o| o.measured_frame().0 == target)
            .map(|o| {
                let p = &data.postures[o.posture()];
                Posture {
                    readings: path.iter().map(|&j| p.readings[j]).collect(),
                    ..p.clone()
                }
            })
            .collect();
        let observations: Vec<Observation> = data
            .observations
            .iter()
            .filter(|o| o.measured_frame().0 == target)
            .enumerate()
            .map(|(i, o)| match o {
                Observation::Pose(p) => {
                    Pose::new(i, Target::EndEffector, p.position, p.euler).into()
                }
                other => panic!("poses only: {other:?}"),
            })
            .collect();
        let chain = fit(&serial, &Dataset::new(own, observations), noise);
        held_out(&chain, &serial_truth, Target::EndEffector)
    });
    eprintln!("held-out max error (mm): tree {tree_errors:?}, separate chains {chain_errors:?}");
    for (t, c) in tree_errors.iter().zip(&chain_errors) {
        // 0.01 mm noise: the tree predicts fresh postures within a few times that.
        assert!(*t < 0.05, "tree {tree_errors:?}");
        assert!(
            *c > 4.0 * t,
            "chains {chain_errors:?} vs tree {tree_errors:?}"
        );
    }
}
