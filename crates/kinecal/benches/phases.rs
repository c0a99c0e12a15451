//! Each phase of a full-pose calibration at 1,000, 10,000 and 100,000 postures, on a 6-joint
//! all-revolute robot with its identifiable parameters (the `--estimate identifiable` set), so
//! that each can be compared with the floor: one pass of forward kinematics with the Jacobian
//! of the estimated columns (`fk_jacobian`) and forming `J^T J` from it (`normal_equations`).
//!
//! - `fk_jacobian`: `Problem::evaluate` with the full m x n Jacobian (the floor's first half);
//! - `normal_equations`: `J^T J` of that Jacobian (faer's matrix product, the fastest at hand;
//!   the second half);
//! - `selection`: the base-set choice (`workflow::resolve` of `identifiable`), one analysis;
//! - `analysis`: `identifiability::analyze` as `kinecal analyze` runs it (with the file-unit
//!   singular values, a second pass);
//! - `estimation`: the Levenberg-Marquardt fit from the nominal robot;
//! - `uncertainty`: covariances and sigmas of the fit, as the workflow takes them (from the
//!   solver's linearisation at the start: no pass).
//!
//! Run: `cargo bench -p kinecal --bench phases` (the 100,000 group takes a few minutes).

use std::hint::black_box;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use kinecal::apps::simulate::{self, PerturbStd};
use kinecal::identifiability::{analyze, AnalysisOptions};
use kinecal::linalg::Matrix;
use kinecal::solve::estimation::{calibrate, CalibrationOptions};
use kinecal::solve::problem::Problem;
use kinecal::uncertainty::uncertainty_of_fit;
use kinecal::workflow::{resolve, Selection};
use kinecal::{Dataset, JointKind, Robot};

fn problem(postures: usize) -> (Robot, Dataset) {
    let nominal = simulate::random_robot(&[JointKind::Revolute; 6], 42);
    let std = PerturbStd {
        length: 1e-3,
        angle: 0.2f64.to_radians(),
        slope_fraction: 0.0,
    };
    let truth = simulate::perturb(&nominal, std, 3);
    let sample = simulate::sample_postures(&nominal, postures, 2);
    let mut data = simulate::measure(&truth, &sample, false);
    simulate::add_noise(&mut data, 2e-5, 2e-5, 4);
    (nominal, data)
}

fn phases(c: &mut Criterion) {
    for postures in [1_000usize, 10_000, 100_000] {
        let (nominal, data) = problem(postures);
        let aopts = AnalysisOptions::default();
        let selection = Selection::parse("identifiable", None, &nominal).unwrap();
        let (ids, _) = resolve(&selection, &nominal, &data, &aopts).unwrap();
        let opts = CalibrationOptions::new(ids.clone());
        let cal = calibrate(&nominal, &data, &opts, &mut |_| {}).unwrap();

        let mut group = c.benchmark_group(format!("phases_{postures}"));
        group.sample_size(10);
        if postures >= 100_000 {
            group.measurement_time(Duration::from_secs(20));
        }
        let p = Problem::new(&nominal, &data, &ids, aopts.weights, aopts.orientation);
        let mut r = vec![0.0; p.rows()];
        let mut jac = Matrix::zeros(p.rows(), p.cols());
        group.bench_function(BenchmarkId::new("fk_jacobian", ids.len()), |b| {
            b.iter(|| black_box(p.evaluate(&nominal, &mut r, Some(&mut jac))))
        });
        p.evaluate(&nominal, &mut r, Some(&mut jac));
        let j = faer::Mat::from_fn(p.rows(), p.cols(), |i, k| jac[(i, k)]);
        let mut jtj = faer::Mat::<f64>::zeros(p.cols(), p.cols());
        group.bench_function(BenchmarkId::new("normal_equations", ids.len()), |b| {
            b.iter(|| {
                faer::linalg::matmul::matmul(
                    jtj.as_mut(),
                    faer::Accum::Replace,
                    j.transpose(),
                    j.as_ref(),
                    1.0,
                    faer::Par::Seq,
                );
                black_box(jtj[(0, 0)])
            })
        });
        drop(j);
        drop(jac);
        group.bench_function(BenchmarkId::new("selection", ids.len()), |b| {
            b.iter(|| {
                black_box(
                    resolve(&selection, &nominal, &data, &aopts)
                        .unwrap()
                        .0
                        .len(),
                )
            })
        });
        group.bench_function(BenchmarkId::new("analysis", ids.len()), |b| {
            b.iter(|| black_box(analyze(&nominal, &data, &ids, &aopts).unwrap().rank))
        });
        group.bench_function(BenchmarkId::new("estimation", ids.len()), |b| {
            b.iter(|| {
                black_box(
                    calibrate(&nominal, &data, &opts, &mut |_| {})
                        .unwrap()
                        .objective_after,
                )
            })
        });
        group.bench_function(BenchmarkId::new("uncertainty", ids.len()), |b| {
            b.iter(|| {
                black_box(
                    uncertainty_of_fit(&cal, &data, &nominal)
                        .unwrap()
                        .parameters
                        .len(),
                )
            })
        });
        group.finish();
    }
}

criterion_group!(benches, phases);
criterion_main!(benches);
