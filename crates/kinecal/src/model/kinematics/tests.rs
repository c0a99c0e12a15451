//! The rigid fast paths against the general ones they stand for: [`Chain::forward_serial`]
//! against [`Chain::forward_rigid`] (every frame of the workspace, with and without the table of
//! reading sines) and [`Chain::jacobian_columns`]' rigid path against
//! [`Chain::jacobian_general`], on random serial robots (revolute and prismatic joints,
//! couplings, sites, every target, random column sets); and a tree and an elastic robot, which
//! must not take them. The fast paths do the same arithmetic in the same order, so the frames and
//! columns are asked to agree to 1e-12 (m, rad, m or rad per parameter unit), far below any
//! calibration's resolution; in fact they agree to the bit.

use nalgebra::Vector3;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::{Chain, ColumnPlan, Frame, ReadingTrig, Target, Workspace, BATCH};
use crate::model::robot::{Body, Coupling, Elastic, Joint, JointKind, Link, Robot, Site};

const TOL: f64 = 1e-12;

fn random_link(r: &mut ChaCha8Rng, reach: f64) -> Link {
    Link {
        x: r.random_range(-reach..reach),
        y: r.random_range(-reach..reach),
        z: r.random_range(-reach..reach),
        alpha: r.random_range(-3.1..3.1),
        beta: r.random_range(-1.5..1.5),
        gamma: r.random_range(-3.1..3.1),
    }
}

/// A serial robot of `dof` joints, about a third prismatic, offsets far from zero, slopes of
/// either sign, a coupled joint on most, and one or two sites.
fn random_serial(dof: usize, seed: u64) -> Robot {
    let mut r = ChaCha8Rng::seed_from_u64(seed);
    let joints: Vec<Joint> = (0..dof)
        .map(|_| {
            let kind = if r.random_range(0.0..1.0) < 0.3 {
                JointKind::Prismatic
            } else {
                JointKind::Revolute
            };
            let mut j = Joint::new(kind, r.random_range(-6.0..6.0), r.random_range(-2.0..2.0));
            if kind == JointKind::Prismatic {
                j.offset *= 0.05;
            }
            j
        })
        .collect();
    let mut robot = Robot {
        name: format!("random-{seed}"),
        units: Default::default(),
        links: (0..=dof).map(|_| random_link(&mut r, 0.5)).collect(),
        joints,
        sites: Vec::new(),
        planes: Vec::new(),
        sessions: Vec::new(),
        tolerances: Default::default(),
        priors: Default::default(),
        elastic: None,
        end_effector: None,
        cameras: Vec::new(),
        boards: Vec::new(),
    };
    for s in 0..1 + seed as usize % 2 {
        robot.sites.push(Site {
            name: format!("s{s}"),
            joint: r.random_range(1..=dof),
            frame: random_link(&mut r, 0.2),
        });
    }
    if dof >= 2 && seed % 3 != 0 {
        let last = dof - 1;
        robot.joints[last].coupling = Some(Coupling {
            joint: r.random_range(0..last),
            factor: r.random_range(-1.0..1.0),
        });
    }
    robot
}

/// [`random_serial`]`(6, 4)` made elastic: a 3 kg body on each joint, 0.2 m out along x and
/// 0.1 m along z, and every joint yielding 2e-4 rad/(N m) about its axis, 1e-4 across it.
fn elastic_serial() -> Robot {
    let mut robot = random_serial(6, 4);
    let bodies = (1..=6)
        .map(|joint| Body {
            joint,
            mass: 3.0,
            com: Vector3::new(0.2, 0.0, 0.1),
        })
        .collect();
    let mut model = Elastic::new(&robot, bodies);
    for j in &mut model.joints {
        j.compliance = 2e-4;
        j.lateral = 1e-4;
    }
    robot.elastic = Some(model);
    robot
}

/// Two 3-joint arms on a 2-joint torso: the second arm's first link starts after the torso.
fn tree(seed: u64) -> Robot {
    let mut robot = random_serial(8, seed);
    for j in &mut robot.joints {
        j.coupling = None;
    }
    robot.joints[5].parent = Some(2);
    robot.sites = vec![Site {
        name: "arm1".into(),
        joint: 5,
        frame: Link {
            x: 0.1,
            y: 0.0,
            z: 0.05,
            alpha: 0.2,
            beta: -0.1,
            gamma: 0.3,
        },
    }];
    robot
}

fn readings(robot: &Robot, r: &mut ChaCha8Rng) -> Vec<f64> {
    (0..robot.dof())
        .map(|_| r.random_range(-4.0..4.0))
        .collect()
}

fn targets(robot: &Robot) -> Vec<Target> {
    std::iter::once(Target::EndEffector)
        .chain((0..robot.sites.len()).map(Target::Site))
        .collect()
}

fn assert_frames_close(a: &Frame, b: &Frame, what: &str) {
    let dp = (a.translation - b.translation).abs().max();
    let dr = (a.rotation - b.rotation).abs().max();
    assert!(dp <= TOL && dr <= TOL, "{what}: {dp:e} m, {dr:e} apart");
}

/// Every frame the two workspaces hold agrees.
fn assert_workspaces_close(a: &Workspace, b: &Workspace, what: &str) {
    for (k, (fa, fb)) in a.after.iter().zip(&b.after).enumerate() {
        assert_frames_close(fa, fb, &format!("{what}: after joint {k}"));
    }
    for (k, (fa, fb)) in a.dist.iter().zip(&b.dist).enumerate() {
        assert_frames_close(fa, fb, &format!("{what}: end of link {k}"));
    }
    assert_eq!(a.readings, b.readings, "{what}");
}

/// A random choice of about two thirds of the parameters, in shuffled columns.
fn random_columns(robot: &Robot, r: &mut ChaCha8Rng) -> Vec<Option<usize>> {
    let mut next = 0;
    let mut columns: Vec<Option<usize>> = (0..robot.param_count())
        .map(|_| {
            (r.random_range(0.0..1.0) < 0.65).then(|| {
                next += 1;
                next - 1
            })
        })
        .collect();
    // Reverse the order of the chosen columns: a plan must not assume they follow the ids.
    for c in columns.iter_mut().flatten() {
        *c = next - 1 - *c;
    }
    columns
}

fn assert_columns_close(a: &[f64], b: &[f64], what: &str) {
    for (k, (x, y)) in a.iter().zip(b).enumerate() {
        assert!((x - y).abs() <= TOL, "{what}: entry {k}: {x} against {y}");
    }
}

#[test]
fn the_serial_pass_is_the_general_one() {
    for seed in 0..80u64 {
        let robot = random_serial(1 + seed as usize % 8, seed);
        let chain = Chain::new(&robot);
        assert!(chain.is_serial(), "seed {seed}");
        let mut r = ChaCha8Rng::seed_from_u64(1000 + seed);
        let postures: Vec<Vec<f64>> = (0..20).map(|_| readings(&robot, &mut r)).collect();
        let trig = ReadingTrig::new(&robot, postures.iter().map(Vec::as_slice));
        let (mut fast, mut general) = (Workspace::new(&robot), Workspace::new(&robot));
        for (p, q) in postures.iter().enumerate() {
            for table in [None, Some(trig.posture(p))] {
                // Fill the fast workspace with another posture first: nothing may be left over.
                chain.forward_rigid(&postures[(p + 1) % 20], None, None, &mut fast);
                chain.forward_with(q, table, &mut fast);
                chain.forward_rigid(q, table, None, &mut general);
                let what = format!("seed {seed}, posture {p}, table {}", table.is_some());
                assert_workspaces_close(&fast, &general, &what);
                for t in targets(&robot) {
                    let (a, b) = (
                        chain.target_frame(&fast, t),
                        chain.target_frame(&general, t),
                    );
                    assert_frames_close(&a, &b, &what);
                }
            }
        }
    }
}

#[test]
fn the_rigid_jacobian_is_the_general_one() {
    for seed in 0..80u64 {
        let robot = random_serial(1 + seed as usize % 8, seed);
        let chain = Chain::new(&robot);
        let mut r = ChaCha8Rng::seed_from_u64(2000 + seed);
        let mut ws = Workspace::new(&robot);
        for t in targets(&robot) {
            let all = ColumnPlan::all(&robot, t);
            let some = ColumnPlan::new(&robot, t, &random_columns(&robot, &mut r));
            for plan in [all, some] {
                assert!(plan.rigid, "seed {seed}: a rigid robot's plan");
                let (mut fast, mut general) =
                    (vec![f64::NAN; 6 * plan.width], vec![0.0; 6 * plan.width]);
                for p in 0..10 {
                    chain.forward(&readings(&robot, &mut r), &mut ws);
                    chain.jacobian_columns(&ws, &plan, &mut fast);
                    chain.jacobian_general(&ws, &plan, &mut general);
                    let what = format!("seed {seed}, {t:?}, posture {p}");
                    assert_columns_close(&fast, &general, &what);
                }
            }
        }
    }
}

#[test]
fn a_tree_and_an_elastic_robot_take_the_general_paths() {
    let mut r = ChaCha8Rng::seed_from_u64(7);
    // A tree: the branch starts from its parent's frame, which the serial pass would not do.
    let robot = tree(3);
    let chain = Chain::new(&robot);
    assert!(!chain.is_serial());
    let (mut ws, mut general) = (Workspace::new(&robot), Workspace::new(&robot));
    for _ in 0..20 {
        let q = readings(&robot, &mut r);
        chain.forward(&q, &mut ws);
        chain.forward_rigid(&q, None, None, &mut general);
        assert_workspaces_close(&ws, &general, "tree");
        // Taken as serial, the second arm would hang off the first arm's end instead.
        let mut serial = chain.clone();
        serial.serial = true;
        serial.forward(&q, &mut general);
        let (a, b) = (ws.end_effector(), general.end_effector());
        assert!(
            (a.translation - b.translation).norm() > 1e-6,
            "the tree's own pass"
        );
        for t in targets(&robot) {
            let plan = ColumnPlan::all(&robot, t);
            let (mut fast, mut slow) = (vec![0.0; 6 * plan.width], vec![0.0; 6 * plan.width]);
            chain.jacobian_columns(&ws, &plan, &mut fast);
            chain.jacobian_general(&ws, &plan, &mut slow);
            assert_columns_close(&fast, &slow, &format!("tree, {t:?}"));
        }
    }

    // An elastic robot: its joints sag under the bodies' weight, so the pass solves the
    // equilibrium and the Jacobian carries the deflections' response.
    let robot = elastic_serial();
    let chain = Chain::new(&robot);
    let rigid = robot.rigid();
    let rigid_chain = Chain::new(&rigid);
    let (mut ws, mut stiff) = (Workspace::new(&robot), Workspace::new(&rigid));
    for _ in 0..10 {
        let q = readings(&robot, &mut r);
        chain.forward(&q, &mut ws);
        assert!(ws.equilibrium().is_some(), "the elastic pass ran");
        rigid_chain.forward(&q, &mut stiff);
        let sag = (ws.end_effector().translation - stiff.end_effector().translation).norm();
        assert!(sag > 1e-6, "the robot sags: {sag:e} m");
        for t in targets(&robot) {
            let plan = ColumnPlan::all(&robot, t);
            let (mut a, mut b) = (vec![0.0; 6 * plan.width], vec![0.0; 6 * plan.width]);
            chain.jacobian_columns(&ws, &plan, &mut a);
            chain.jacobian_general(&ws, &plan, &mut b);
            assert_columns_close(&a, &b, &format!("elastic, {t:?}"));
            // The rigid columns would miss the deflections' response.
            let mut c = vec![0.0; 6 * plan.width];
            chain.jacobian_rigid(&ws, &plan, &mut c);
            let apart = a
                .iter()
                .zip(&c)
                .map(|(x, y)| (x - y).abs())
                .fold(0.0, f64::max);
            assert!(
                apart > 1e-9,
                "elastic, {t:?}: the response is in the columns"
            );
        }
    }
}

/// Every frame and reading the two workspaces hold is the same number, to the bit.
fn assert_workspaces_identical(a: &Workspace, b: &Workspace, what: &str) {
    let bits = |f: &Frame| -> Vec<u64> {
        f.rotation
            .iter()
            .chain(f.translation.iter())
            .map(|v| v.to_bits())
            .collect()
    };
    for (k, (fa, fb)) in a.after.iter().zip(&b.after).enumerate() {
        assert_eq!(bits(fa), bits(fb), "{what}: after joint {k}");
    }
    for (k, (fa, fb)) in a.dist.iter().zip(&b.dist).enumerate() {
        assert_eq!(bits(fa), bits(fb), "{what}: end of link {k}");
    }
    let readings = |w: &Workspace| w.readings.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    assert_eq!(readings(a), readings(b), "{what}: readings");
}

/// The batched pass (the one the processor takes, its AVX2 build when the processor has AVX2, and
/// the portable build of the same code) against one serial pass per posture, every frame to the
/// bit, with and without the table of reading sines; the workspaces hold another posture
/// first, so nothing may be left over.
#[test]
fn the_batched_pass_is_the_serial_one() {
    for seed in 0..80u64 {
        let robot = random_serial(1 + seed as usize % 8, seed);
        let chain = Chain::new(&robot);
        let mut r = ChaCha8Rng::seed_from_u64(3000 + seed);
        let postures: Vec<Vec<f64>> = (0..4 * BATCH).map(|_| readings(&robot, &mut r)).collect();
        let trig = ReadingTrig::new(&robot, postures.iter().map(Vec::as_slice));
        let mut one = Workspace::new(&robot);
        let mut batch: [Workspace; BATCH] = std::array::from_fn(|_| Workspace::new(&robot));
        for first in (0..postures.len()).step_by(BATCH) {
            let readings = std::array::from_fn(|k| postures[first + k].as_slice());
            for table in [None, Some(std::array::from_fn(|k| trig.posture(first + k)))] {
                for build in ["dispatched", "avx2", "portable"] {
                    for (k, w) in batch.iter_mut().enumerate() {
                        chain.forward(&postures[(first + k + 5) % postures.len()], w);
                    }
                    match build {
                        "portable" => chain.forward_serial_batch(
                            readings,
                            table,
                            &mut batch,
                            super::store_lanes,
                        ),
                        #[cfg(target_arch = "x86_64")]
                        "avx2" if std::arch::is_x86_feature_detected!("avx2") => {
                            // SAFETY: the processor has AVX2, checked just above.
                            unsafe { chain.forward_serial_batch_avx2(readings, table, &mut batch) }
                        }
                        _ => chain.forward_batch(readings, table, &mut batch),
                    }
                    for (k, w) in batch.iter().enumerate() {
                        chain.forward_with(readings[k], table.map(|t| t[k]), &mut one);
                        let what = format!(
                            "seed {seed}, posture {}, table {}, {build} build",
                            first + k,
                            table.is_some()
                        );
                        assert_workspaces_identical(w, &one, &what);
                    }
                }
            }
        }
    }
}

/// A tree and an elastic robot computed in a batch: each posture by its own pass (the tree's
/// branches, the elastic robot's equilibrium), not the serial one.
#[test]
fn a_batch_of_a_tree_or_an_elastic_robot_is_posture_by_posture() {
    let mut r = ChaCha8Rng::seed_from_u64(11);
    let elastic = elastic_serial();
    for (robot, what) in [(tree(3), "tree"), (elastic, "elastic")] {
        let chain = Chain::new(&robot);
        let postures: [Vec<f64>; BATCH] = std::array::from_fn(|_| readings(&robot, &mut r));
        let mut batch: [Workspace; BATCH] = std::array::from_fn(|_| Workspace::new(&robot));
        chain.forward_batch(
            std::array::from_fn(|k| postures[k].as_slice()),
            None,
            &mut batch,
        );
        let mut one = Workspace::new(&robot);
        for (k, w) in batch.iter().enumerate() {
            chain.forward(&postures[k], &mut one);
            assert_workspaces_identical(w, &one, &format!("{what}, posture {k}"));
            assert_eq!(
                w.deflections().map(<[f64]>::to_vec),
                one.deflections().map(<[f64]>::to_vec),
                "{what}, posture {k}"
            );
        }
    }
}
