//! Compensation throughput: programs of a random 6-joint arm compensated for its perturbed
//! twin (1 mm, 0.3 deg), full poses, one core.
//!
//! Run: `cargo bench -p kinecal --bench compensate`

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use kinecal::compensate::{Compensator, Options};
use kinecal::simulate::{self, PerturbStd};
use kinecal::{JointKind, Target};

fn compensation(c: &mut Criterion) {
    let nominal = simulate::random_robot(&[JointKind::Revolute; 6], 21);
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
    group.finish();
}

criterion_group!(benches, compensation);
criterion_main!(benches);
