//! `identifiability::analyze` (as `kinecal analyze` runs it: the pass that builds `R` with the
//! typical-row sums, the SVD, the file-unit pass, identical groups, the base set by a tiered
//! QR with column pivoting, the null space in reduced form) on serial chains of revolute
//! joints, every parameter analysed: 12, 37 and 130 joints, 102, 302 and 1,046 parameters
//! (6 per link, 2 per joint), over 300 simulated full poses (1,800 rows) each.
//!
//! The analysis is `O(m n^2 + n^3)`: at a fixed number of rows, time grows as about `n^3` once
//! the `n x n` work dominates. Run: `cargo bench -p kinecal --bench analyze`.

use std::hint::black_box;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use kinecal::identifiability::{analyze, AnalysisOptions};
use kinecal::{apps::simulate, JointKind, ParamId};

fn analyze_all(c: &mut Criterion) {
    let mut group = c.benchmark_group("analyze");
    group.sample_size(10);
    for joints in [12usize, 37, 130] {
        let robot = simulate::random_robot(&vec![JointKind::Revolute; joints], 1);
        let postures = simulate::sample_postures(&robot, 300, 2);
        let data = simulate::measure(&robot, &postures, false);
        let all: Vec<ParamId> = robot.param_ids().collect();
        let opts = AnalysisOptions::default();
        if joints >= 100 {
            // About 1.5 s an analysis: ten of them take longer than the default 5 s.
            group.measurement_time(Duration::from_secs(20));
        }
        group.bench_function(BenchmarkId::new("parameters", all.len()), |b| {
            b.iter(|| black_box(analyze(&robot, &data, &all, &opts).unwrap().rank))
        });
    }
    group.finish();
}

criterion_group!(benches, analyze_all);
criterion_main!(benches);
