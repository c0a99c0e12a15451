//! Hot-path benchmarks on a 6-joint all-revolute robot with all 54 parameters: forward kinematics
//! (also four postures at once) and the analytic Jacobian per posture, and a full
//! Levenberg-Marquardt calibration from 1,000 full-pose postures; and the same arm made elastic (a
//! body per joint, compliances about both axes): its equilibrium, and its Jacobian with the
//! compliances; and a tree, a 2-joint torso carrying two 6-joint arms, both tools per posture.
//!
//! Run: `cargo bench -p kinecal --bench kinematics`

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use kinecal::apps::simulate::{self, PerturbStd};
use kinecal::model::kinematics::{ReadingTrig, BATCH};
use kinecal::solve::estimation::{calibrate, CalibrationOptions};
use kinecal::{Chain, JointKind, ParamId, Target, Workspace};

fn robot() -> kinecal::Robot {
    simulate::random_robot(&[JointKind::Revolute; 6], 42)
}

fn kinematics(c: &mut Criterion) {
    let robot = robot();
    let postures = simulate::sample_postures(&robot, 1000, 1);
    let chain = Chain::new(&robot);
    let mut ws = Workspace::new(&robot);
    let mut block = vec![0.0; 6 * robot.param_count()];
    let mut i = 0;
    c.bench_function("fk_pose_per_posture_6R", |b| {
        b.iter(|| {
            i = (i + 1) % postures.len();
            chain.forward(black_box(&postures[i].readings), &mut ws);
            black_box(chain.target_frame(&ws, Target::EndEffector).pose())
        })
    });
    c.bench_function("fk_frames_only_per_posture_6R", |b| {
        b.iter(|| {
            i = (i + 1) % postures.len();
            chain.forward(black_box(&postures[i].readings), &mut ws);
            black_box(ws.end_effector().translation.x)
        })
    });
    // The calibration's passes: the readings' sines and cosines from the table, one posture
    // at a time and four at once (the batched pass, per batch of four).
    let trig = ReadingTrig::new(&robot, postures.iter().map(|p| p.readings.as_slice()));
    c.bench_function("fk_frames_table_per_posture_6R", |b| {
        b.iter(|| {
            i = (i + 1) % postures.len();
            chain.forward_with(
                black_box(&postures[i].readings),
                Some(trig.posture(i)),
                &mut ws,
            );
            black_box(ws.end_effector().translation.x)
        })
    });
    let mut batch: [Workspace; BATCH] = std::array::from_fn(|_| Workspace::new(&robot));
    c.bench_function("fk_frames_table_4_postures_batched_6R", |b| {
        b.iter(|| {
            i = (i + BATCH) % (postures.len() - BATCH);
            let readings = std::array::from_fn(|k| black_box(postures[i + k].readings.as_slice()));
            let rows = std::array::from_fn(|k| trig.posture(i + k));
            chain.forward_batch(readings, Some(rows), &mut batch);
            black_box(batch[3].end_effector().translation.x)
        })
    });
    let plan = kinecal::model::kinematics::ColumnPlan::all(&robot, Target::EndEffector);
    c.bench_function("fk_plus_jacobian_54_per_posture_6R", |b| {
        b.iter(|| {
            i = (i + 1) % postures.len();
            chain.forward(black_box(&postures[i].readings), &mut ws);
            chain.jacobian_columns(&ws, &plan, &mut block);
            black_box(block[17])
        })
    });
}

/// The benchmark arm with a mass model: 2 kg per joint, compliances 2e-4 rad/(N m).
fn elastic_robot() -> kinecal::Robot {
    let mut robot = robot();
    let bodies = (1..=6)
        .map(|joint| kinecal::model::robot::Body {
            joint,
            mass: 2.0,
            com: nalgebra::Vector3::new(0.1, 0.0, 0.05),
        })
        .collect();
    let mut model = kinecal::model::robot::Elastic::new(&robot, bodies);
    for j in &mut model.joints {
        j.compliance = 2e-4;
        j.lateral = 1e-4;
    }
    robot.elastic = Some(model);
    robot
}

fn elastic(c: &mut Criterion) {
    let robot = elastic_robot();
    let postures = simulate::sample_postures(&robot, 1000, 1);
    let chain = Chain::new(&robot);
    let mut ws = Workspace::new(&robot);
    let mut i = 0;
    c.bench_function("elastic_fk_equilibrium_per_posture_6R", |b| {
        b.iter(|| {
            i = (i + 1) % postures.len();
            chain.forward(black_box(&postures[i].readings), &mut ws);
            black_box(ws.end_effector().translation.x)
        })
    });
    // The geometry and the 12 compliances (not the bodies): what a compliance calibration
    // estimates.
    let columns: Vec<Option<usize>> = robot
        .param_ids()
        .map(|id| match robot.param_kind(id) {
            kinecal::ParamKind::Body { .. } => None,
            _ => Some(id.0),
        })
        .collect();
    let plan = kinecal::model::kinematics::ColumnPlan::new(&robot, Target::EndEffector, &columns);
    let mut block = vec![0.0; 6 * plan.width()];
    c.bench_function("elastic_fk_plus_jacobian_66_per_posture_6R", |b| {
        b.iter(|| {
            i = (i + 1) % postures.len();
            chain.forward(black_box(&postures[i].readings), &mut ws);
            chain.jacobian_columns(&ws, &plan, &mut block);
            black_box(block[17])
        })
    });
}

fn calibration(c: &mut Criterion) {
    let nominal = robot();
    let std = PerturbStd {
        length: 1e-3,
        angle: 0.2f64.to_radians(),
        slope_fraction: 0.002,
    };
    let truth = simulate::perturb(&nominal, std, 3);
    let mut data = simulate::measure(&truth, &simulate::sample_postures(&nominal, 1000, 2), false);
    simulate::add_noise(&mut data, 2e-5, 2e-5, 4);
    let opts = CalibrationOptions::new(nominal.param_ids().collect::<Vec<ParamId>>());
    let mut group = c.benchmark_group("calibration");
    group.sample_size(20);
    group.bench_function("lm_54_params_1000_poses_6R", |b| {
        b.iter(|| {
            black_box(
                calibrate(&nominal, &data, &opts, &mut |_| {})
                    .unwrap()
                    .objective_after,
            )
        })
    });
    group.finish();
}

/// Two 6-joint arms on a 2-joint torso: one forward pass, then both tools' frames and Jacobians
/// (each arm's columns and the torso's).
fn tree(c: &mut Criterion) {
    let robot = simulate::random_tree(2, &[6, 6], 42);
    let postures = simulate::sample_postures(&robot, 1000, 1);
    let chain = Chain::new(&robot);
    let mut ws = Workspace::new(&robot);
    let mut block = vec![0.0; 6 * robot.param_count()];
    let plans = [Target::Site(0), Target::EndEffector]
        .map(|t| kinecal::model::kinematics::ColumnPlan::all(&robot, t));
    let mut i = 0;
    c.bench_function("tree_fk_plus_both_jacobians_per_posture_2+6+6R", |b| {
        b.iter(|| {
            i = (i + 1) % postures.len();
            chain.forward(black_box(&postures[i].readings), &mut ws);
            for plan in &plans {
                chain.jacobian_columns(&ws, plan, &mut block);
            }
            black_box(block[17])
        })
    });
}

criterion_group!(benches, kinematics, elastic, tree, calibration);
criterion_main!(benches);
