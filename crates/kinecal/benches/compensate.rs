//! Compensation throughput, one core: programs of a random 6-joint arm compensated for its
//! perturbed twin (1 mm, 0.3 deg), full poses; and Cartesian targets without seeds (positions
//! and poses the twin reaches inside its joint ranges), searched for a usable solution.
//!
//! Run: `cargo bench -p kinecal --bench compensate`

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use kinecal::apps::compensate::{Compensator, Goal, Options, TargetSearch};
use kinecal::apps::simulate::{self, PerturbStd};
use kinecal::{Chain, JointKind, Target, Workspace};

fn compensation(c: &mut Criterion) {
    let mut nominal = simulate::random_robot(&[JointKind::Revolute; 6], 21);
    for j in 0..6 {
        nominal.joints[j].range = Some(simulate::reading_range(&nominal, j));
    }
    let std = PerturbStd {
        length: 1e-3,
        angle: 0.3f64.to_radians(),
        slope_fraction: 0.002,
    };
    let calibrated = simulate::perturb(&nominal, std, 22);
    let postures = simulate::sample_postures(&nominal, 1000, 5);
    let mut comp = Compensator::new(&calibrated, &nominal, Options::default()).unwrap();
    let mut out = vec![0.0; 6];
    let mut group = c.benchmark_group("compensate_6R");
    group.throughput(Throughput::Elements(postures.len() as u64));
    group.bench_function("1000_programs_full_pose", |b| {
        b.iter(|| {
            for p in &postures {
                black_box(comp.program(&p.readings, Target::EndEffector, false, &mut out));
            }
        })
    });
    // Goals the calibrated twin reaches at postures inside its ranges.
    let chain = Chain::new(&calibrated);
    let mut ws = Workspace::new(&calibrated);
    let frames: Vec<_> = postures
        .iter()
        .map(|p| {
            chain.forward(&p.readings, &mut ws);
            chain.target_frame(&ws, Target::EndEffector)
        })
        .collect();
    for (name, pose) in [
        ("1000_targets_position_unseeded", false),
        ("1000_targets_pose_unseeded", true),
    ] {
        let goals: Vec<Goal> = frames
            .iter()
            .map(|f| {
                if pose {
                    Goal::Pose(*f)
                } else {
                    Goal::Position(f.translation)
                }
            })
            .collect();
        let mut search = TargetSearch::new(&calibrated, &nominal, Options::default()).unwrap();
        group.bench_function(name, |b| {
            b.iter(|| {
                for g in &goals {
                    black_box(search.solve(g, Target::EndEffector, None, &mut out));
                }
            })
        });
    }
    group.finish();
}

criterion_group!(benches, compensation);
criterion_main!(benches);
