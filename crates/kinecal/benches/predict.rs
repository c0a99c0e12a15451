//! Predicted accuracy throughput, one core: 100,000 postures of a random 6-joint arm predicted
//! (forward kinematics, the Jacobian of its 30 estimated parameters, the covariance through it,
//! the nearest of 12,000 measured postures in the k-d tree, the 95 % bound), and the
//! cross-validated model-error term of a calibration on 2,000 positions.
//!
//! Run: `cargo bench -p kinecal --bench predict`

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use kinecal::apps::simulate::{self, PerturbStd};
use kinecal::predict::{self, Growth, JointMetric, ModelError, Predictor};
use kinecal::workflow::{self, Request, Selection};
use kinecal::{JointKind, Target};

fn prediction(c: &mut Criterion) {
    let mut nominal = simulate::random_robot(&[JointKind::Revolute; 6], 21);
    for j in 0..6 {
        nominal.joints[j].range = Some(simulate::reading_range(&nominal, j));
    }
    let std = PerturbStd {
        length: 1e-3,
        angle: 0.3f64.to_radians(),
        slope_fraction: 0.0,
    };
    let truth = simulate::perturb(&nominal, std, 22);
    let measured = simulate::sample_postures(&nominal, 12_000, 5);
    let mut data = simulate::measure(&truth, &measured[..2000], true);
    simulate::add_noise(&mut data, 2e-4, 0.0, 6);
    let mut req = Request::new(nominal.clone(), data.clone());
    req.selection = Selection::Identifiable {
        with: Vec::new(),
        fix: Vec::new(),
    };
    req.prediction = predict::Level::Off;
    let out = workflow::run(&req, &mut ()).unwrap();
    let u = out.uncertainty.as_ref().unwrap();
    let robot = &out.calibration.calibrated;
    let metric = JointMetric::new(robot, &predict::levers(robot, &data));
    let model = ModelError {
        position: Growth {
            s0: 2.5e-4,
            c: 5e-4,
            shape: 3.6,
        },
        attitude: None,
    };
    let p = Predictor::new(
        robot,
        &u.analysis.parameters,
        u.covariance_internal(),
        model,
        metric.clone(),
        measured.iter().map(|m| m.readings.as_slice()),
    )
    .unwrap();
    let postures = predict::sample_readings(robot, 100_000, 7);
    let mut s = p.scratch();
    let mut group = c.benchmark_group("predict_6R");
    group.sample_size(10);
    group.throughput(Throughput::Elements(100_000));
    group.bench_function(
        format!(
            "100000_postures_{}_parameters_12000_measured",
            u.analysis.parameters.len()
        ),
        |b| {
            b.iter(|| {
                let mut sum = 0.0;
                for r in postures.chunks(6) {
                    sum += p
                        .predict(r, Target::EndEffector, &mut s)
                        .position_error
                        .bound;
                }
                black_box(sum)
            })
        },
    );
    // The same without the search (one measured posture): what the k-d tree costs.
    let one = Predictor::new(
        robot,
        &u.analysis.parameters,
        u.covariance_internal(),
        model,
        metric.clone(),
        std::iter::once(measured[0].readings.as_slice()),
    )
    .unwrap();
    group.bench_function("100000_postures_1_measured", |b| {
        b.iter(|| {
            let mut sum = 0.0;
            for r in postures.chunks(6) {
                sum += one
                    .predict(r, Target::EndEffector, &mut s)
                    .position_error
                    .bound;
            }
            black_box(sum)
        })
    });
    group.finish();
    let mut group = c.benchmark_group("predict_model_error");
    group.sample_size(10);
    group.bench_function("cross_validation_2000_positions", |b| {
        b.iter(|| {
            let cv = predict::cross_validate(
                &out.calibration,
                &data,
                &out.calibration.initial,
                &metric,
                &[10, 3],
            )
            .unwrap();
            black_box(predict::fit_growth(&cv.position))
        })
    });
    group.finish();
}

criterion_group!(benches, prediction);
criterion_main!(benches);
