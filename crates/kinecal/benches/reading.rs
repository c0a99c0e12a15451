//! Reading measurement files: 1,000 and 10,000 full-pose rows of a 6-joint robot (the reader
//! must stay linear in the file's length).
//!
//! Run: `cargo bench -p kinecal --bench reading`

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use kinecal::files::{parse_measurements, write_measurements};
use kinecal::{apps::simulate, JointKind};

fn reading(c: &mut Criterion) {
    let robot = simulate::random_robot(&[JointKind::Revolute; 6], 3);
    let mut group = c.benchmark_group("read_measurements_6R");
    group.sample_size(10);
    for n in [1_000, 10_000] {
        let data = simulate::measure(&robot, &simulate::sample_postures(&robot, n, 1), false);
        let text = write_measurements(&robot, &data);
        group.throughput(Throughput::Elements(n as u64));
        group.bench_function(format!("{n}_rows"), |b| {
            b.iter(|| black_box(parse_measurements(&text, "m.csv", &robot).unwrap().rows()))
        });
    }
    group.finish();
}

criterion_group!(benches, reading);
criterion_main!(benches);
