//! Measurement planning: 30 postures chosen from 1,000 sampled candidates of a 6-joint arm
//! measured by a tracker (positions of the tool), for the identifiable set (33 parameters),
//! with each criterion whose search differs (D: greedy and log-det exchange; I: then the
//! trace exchange; E: then the eigenvalue exchange), the 100 random plans it is compared with
//! included.
//!
//! Run: `cargo bench -p kinecal --bench plan`

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use kinecal::apps::plan::{candidates, plan, Criterion as Optimality, PlanRequest};
use kinecal::{apps::simulate, JointKind, Target};

fn planning(c: &mut Criterion) {
    let robot = simulate::random_robot(&[JointKind::Revolute; 6], 31);
    let pool = candidates(
        &robot,
        simulate::sample_postures(&robot, 1000, 3),
        &[Target::EndEffector],
        true,
    );
    let mut group = c.benchmark_group("plan_30_of_1000_positions_6R");
    group.sample_size(10);
    for criterion in [Optimality::D, Optimality::I, Optimality::E] {
        let mut req = PlanRequest::new(robot.clone(), pool.clone(), 30);
        req.criterion = criterion;
        group.bench_function(criterion.as_str(), |b| {
            b.iter(|| black_box(plan(&req).unwrap().value))
        });
    }
    group.finish();
}

criterion_group!(benches, planning);
criterion_main!(benches);
