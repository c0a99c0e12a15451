//! The model-error term by cross-validation: the calibration fitted again with blocks of
//! nearby postures held out, the held-out errors, and the term fitted to them by maximum
//! likelihood.
//!
//! **Folds.** The measured postures (whole posture groups: postures an observation links stay
//! together) are split into `k` blocks, at two scales (10 blocks, then 3: the second holds out
//! a third of the measured region at a time, so that the held-out postures reach the distances
//! of an extrapolation), by k-means in the embedding of the joint-space metric
//! ([`super::nearest`]; seeded by farthest points from the first posture, then 20 Lloyd
//! rounds: deterministic). Holding out a block leaves its postures at distances from the
//! fitted ones ranging from a neighbour's spacing (at the block's edge) to the block's radius
//! (inside), which is what lets the likelihood tell `s0` from `c`. Each fold refits the
//! calibration's parameters (its options, from the calibrated robot, or from its start when it
//! has a prior, whose centre that is) and computes its covariance, linearised at the
//! calibration's reference.
//!
//! **Held-out errors.** For each held-out position or pose: the error `model - measured`
//! turned into the global frame (through its session's frame), the parameter part `J C J^T` of
//! the fold's fit, and the distance to the nearest posture the fold fitted.
//!
//! **The fit.** `s0` and `c` maximise `sum_i log N(e_i; 0, P_i + (s0^2 + c^2 d_i^2) I)` (a grid
//! over `log s0^2, log c^2` in steps of 1 (a factor 1.65 in `s0` or `c`), refined by 20 halvings; `c = 0` is a candidate). The held-out errors,
//! each divided by its predicted standard deviation, then give the shape
//! ([`Growth::shape`]): how unevenly they spread over the axes (on the UR10, mostly along one
//! direction of the tracker's frame), which widens the bound of `|e|`.

use nalgebra::{Matrix3, Vector3};

use super::nearest::JointMetric;
use super::{Bound, Growth, ModelError, Predictor};
use crate::error::{Error, Result};
use crate::model::kinematics::{log_so3, rot_zyx, Target};
use crate::model::robot::Robot;
use crate::observe::{for_each_observation, session_frame, Dataset, Observation};
use crate::solve::estimation::{self, Calibration};

/// One held-out observation's error and what the fold predicted of it (internal units).
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct HeldOut {
    /// Distance to the nearest fitted posture (m).
    pub distance: f64,
    /// `model - measured`, global frame; for a pixel, across its line of sight (the camera's
    /// `x`, `y`, and 0: [`super::pixel`]).
    pub error: [f64; 3],
    /// The parameter part of the fold's prediction, `J C J^T` (global frame; a pixel's in the
    /// same axes as its error, zero along the line of sight).
    pub parameters: [[f64; 3]; 3],
    /// The frame the observation measured.
    pub target: Target,
    /// How many of the error's components were measured: 3, or 2 for a pixel (the first two).
    pub axes: usize,
}

impl HeldOut {
    /// A held-out error of three measured components.
    pub fn new(
        distance: f64,
        error: [f64; 3],
        parameters: [[f64; 3]; 3],
        target: Target,
    ) -> HeldOut {
        HeldOut {
            distance,
            error,
            parameters,
            target,
            axes: 3,
        }
    }

    /// A pixel's error across its line of sight ([`super::pixel::Lateral`]) at `distance`.
    pub fn across(l: &super::pixel::Lateral, distance: f64) -> HeldOut {
        let p = l.parameters;
        HeldOut {
            distance,
            error: [l.error[0], l.error[1], 0.0],
            parameters: [[p[0][0], p[0][1], 0.0], [p[1][0], p[1][1], 0.0], [0.0; 3]],
            target: l.target,
            axes: 2,
        }
    }

    /// The 95 % bound of its error's length with a model error of variance `v` per axis and
    /// shape `shape` (a pixel's: isotropic across its line of sight).
    pub fn bound(&self, v: f64, shape: f64) -> Bound {
        if self.axes == 2 {
            Bound::across(&self.parameters, v)
        } else {
            Bound::of(&self.parameters, v, shape)
        }
    }
}

/// The held-out errors of a cross-validation.
#[derive(Debug, Clone, PartialEq, Default)]
#[non_exhaustive]
pub struct CrossValidated {
    /// Positions (m).
    pub position: Vec<HeldOut>,
    /// Attitudes (rad): the rotation vector of `R_model R_measured^T`.
    pub attitude: Vec<HeldOut>,
    /// Folds whose fit failed (left out).
    pub failed: usize,
}

/// The fold of each posture (`usize::MAX` for postures no position or pose measures).
pub fn blocks(data: &Dataset, metric: &JointMetric, k: usize) -> Vec<usize> {
    let groups = data.posture_groups();
    let dims = metric.dims();
    let mut points = vec![0.0; groups.len() * dims];
    for (g, members) in groups.iter().enumerate() {
        metric.embed(
            &data.postures[members[0]].readings,
            &mut points[g * dims..(g + 1) * dims],
        );
    }
    let d2 = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum::<f64>();
    let pt = |g: usize| &points[g * dims..(g + 1) * dims];
    let k = k.min(groups.len()).max(1);
    // Farthest-point seeds.
    let mut centres: Vec<f64> = pt(0).to_vec();
    let mut nearest: Vec<f64> = (0..groups.len()).map(|g| d2(pt(g), pt(0))).collect();
    for _ in 1..k {
        let far = (0..groups.len())
            .max_by(|&a, &b| nearest[a].total_cmp(&nearest[b]))
            .unwrap_or(0);
        let c = pt(far).to_vec();
        for (g, n) in nearest.iter_mut().enumerate() {
            *n = n.min(d2(pt(g), &c));
        }
        centres.extend(c);
    }
    let mut of = vec![0usize; groups.len()];
    for _round in 0..20 {
        for (g, o) in of.iter_mut().enumerate() {
            *o = (0..k)
                .min_by(|&a, &b| {
                    d2(pt(g), &centres[a * dims..(a + 1) * dims])
                        .total_cmp(&d2(pt(g), &centres[b * dims..(b + 1) * dims]))
                })
                .unwrap_or(0);
        }
        let mut sum = vec![0.0; k * dims];
        let mut count = vec![0usize; k];
        for (g, &o) in of.iter().enumerate() {
            count[o] += 1;
            for (s, v) in sum[o * dims..(o + 1) * dims].iter_mut().zip(pt(g)) {
                *s += v;
            }
        }
        for c in 0..k {
            if count[c] > 0 {
                for d in 0..dims {
                    centres[c * dims + d] = sum[c * dims + d] / count[c] as f64;
                }
            }
        }
    }
    let mut fold = vec![usize::MAX; data.postures.len()];
    for (g, members) in groups.iter().enumerate() {
        for &p in members {
            fold[p] = of[g];
        }
    }
    fold
}

/// Refits `cal` on blocks of `data` (see the module), `k` blocks for each `k` of `scales`,
/// and collects the held-out errors of every scale together.
pub fn cross_validate(
    cal: &Calibration,
    data: &Dataset,
    reference: &Robot,
    metric: &JointMetric,
    scales: &[usize],
) -> Result<CrossValidated> {
    cross_validate_with(cal, data, reference, metric, scales, &mut |_| {})
}

/// [`cross_validate`], saying which fold it fits (`prediction: fold 4 of 13`) to `say`.
pub(crate) fn cross_validate_with(
    cal: &Calibration,
    data: &Dataset,
    reference: &Robot,
    metric: &JointMetric,
    scales: &[usize],
    say: &mut dyn FnMut(&str),
) -> Result<CrossValidated> {
    let mut out = CrossValidated::default();
    let total: usize = scales.iter().sum();
    let mut done = 0;
    for &k in scales {
        let mut fold = |f: usize| {
            say(&format!("prediction: fold {} of {total}", done + f + 1));
        };
        cross_validate_at(cal, data, reference, metric, k, &mut fold, &mut out)?;
        done += k;
    }
    if out.position.is_empty() {
        return Err(Error::Problem(
            "the cross-validation of the model error held out no position (every fold's fit \
             failed)"
                .into(),
        ));
    }
    Ok(out)
}

fn cross_validate_at(
    cal: &Calibration,
    data: &Dataset,
    reference: &Robot,
    metric: &JointMetric,
    k: usize,
    fold: &mut dyn FnMut(usize),
    out: &mut CrossValidated,
) -> Result<()> {
    let fold_of = blocks(data, metric, k);
    let start = if cal.options.prior.is_empty() {
        &cal.calibrated
    } else {
        &cal.initial
    };
    let (_, pose) = super::predictable(data);
    for f in 0..k {
        fold(f);
        let held: Vec<bool> = fold_of.iter().map(|&x| x == f).collect();
        if !held.iter().any(|&h| h) {
            continue;
        }
        let kept: Vec<bool> = held.iter().map(|h| !h).collect();
        let (train, test) = (data.subset(&kept), data.subset(&held));
        let fit = match estimation::calibrate(start, &train, &cal.options, &mut |_| {}) {
            Ok(fit) => fit,
            Err(_) => {
                out.failed += 1;
                continue;
            }
        };
        let u = match crate::uncertainty::uncertainty(&fit, &train, reference) {
            Ok(u) => u,
            Err(_) => {
                out.failed += 1;
                continue;
            }
        };
        let fitted = super::measured_postures(&train);
        if fitted.is_empty() {
            out.failed += 1;
            continue;
        }
        let robot = &fit.calibrated;
        let predictor = Predictor::new(
            robot,
            &u.analysis.parameters,
            u.covariance_internal(),
            ModelError::none(pose),
            metric.clone(),
            fitted.iter().copied(),
        )?;
        let mut s = predictor.scratch();
        let mut collect = |o: &Observation, frame: &crate::model::kinematics::Frame| {
            let posture = &test.postures[o.posture()];
            let rs = session_frame(robot, posture)
                .filter(|_| !robot.sessions.is_empty())
                .map_or(Matrix3::identity(), |t| t.rotation);
            let (position, attitude) = match o {
                Observation::Position(m) => (m.position, None),
                Observation::Pose(m) => {
                    (m.position, Some(rot_zyx(m.euler.x, m.euler.y, m.euler.z)))
                }
                _ => return,
            };
            let d = predictor.distance(&posture.readings, &mut s);
            let (p, a, _) = predictor.parameter_part(&posture.readings, o.target(), &mut s);
            let e: Vector3<f64> = rs.transpose() * (frame.translation - position);
            out.position
                .push(HeldOut::new(d, [e.x, e.y, e.z], p, o.target()));
            if let Some(rm) = attitude {
                let w = rs.transpose() * log_so3(&(frame.rotation * rm.transpose()));
                out.attitude
                    .push(HeldOut::new(d, [w.x, w.y, w.z], a, o.target()));
            }
        };
        for_each_observation(robot, &test, |_, o, frames| collect(o, &frames[0]));
        let pixels = super::pixel::lateral_errors(
            robot,
            &test,
            &u.analysis.parameters,
            Some(u.covariance_internal()),
        )?;
        for l in &pixels {
            let d = predictor.distance(&test.postures[l.posture].readings, &mut s);
            out.position.push(HeldOut::across(l, d));
        }
    }
    Ok(())
}

/// The calibrated model's own residuals at the measured postures, per target: for each frame
/// measured by position, pose or pixel (index 0 the end effector, `1 + s` site `s`), the
/// number of observations and the mean per-axis square of the position residuals (m^2; a
/// pixel's two components across its line of sight, [`super::pixel`]) and of the attitude
/// residuals (rad^2; 0 when no pose measures it), global frame.
pub fn identification_residuals(robot: &Robot, data: &Dataset) -> Vec<(usize, f64, f64)> {
    let mut out = vec![(0usize, 0.0, 0.0); robot.sites.len() + 1];
    let mut poses = vec![0usize; robot.sites.len() + 1];
    // Measured components per frame.
    let mut axes = vec![0usize; robot.sites.len() + 1];
    for_each_observation(robot, data, |_, o, frames| {
        let (position, attitude) = match o {
            Observation::Position(m) => (m.position, None),
            Observation::Pose(m) => (m.position, Some(rot_zyx(m.euler.x, m.euler.y, m.euler.z))),
            _ => return,
        };
        let k = match o.target() {
            Target::EndEffector => 0,
            Target::Site(s) => 1 + s,
        };
        let frame = &frames[0];
        out[k].0 += 1;
        axes[k] += 3;
        out[k].1 += (frame.translation - position).norm_squared();
        if let Some(rm) = attitude {
            poses[k] += 1;
            out[k].2 += log_so3(&(frame.rotation * rm.transpose())).norm_squared();
        }
    });
    // Pixels' errors need no covariance: this cannot fail.
    for l in super::pixel::lateral_errors(robot, data, &[], None).unwrap_or_default() {
        let k = super::target_index(l.target);
        out[k].0 += 1;
        axes[k] += 2;
        out[k].1 += l.error[0] * l.error[0] + l.error[1] * l.error[1];
    }
    for ((o, p), &a) in out.iter_mut().zip(&poses).zip(&axes) {
        if a > 0 {
            o.1 /= a as f64;
        }
        if *p > 0 {
            o.2 /= 3.0 * *p as f64;
        }
    }
    out
}

/// The model-error term fitted to held-out errors, and how it and the alternatives cover them.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct GrowthFit {
    /// The term (maximum likelihood).
    pub growth: Growth,
    /// Held-out observations.
    pub points: usize,
    /// Their share within the 95 % bound with the term.
    pub coverage: f64,
    /// With a single variance instead (`c = 0`, `s0` by maximum likelihood).
    pub coverage_constant: f64,
    /// The single variance's `s0`.
    pub s0_constant: f64,
    /// With the parameters' uncertainty alone.
    pub coverage_parameters_only: f64,
    /// The held-out distances' median.
    pub distance_median: f64,
    /// Their largest.
    pub distance_max: f64,
}

/// Fits `s0, c` to `samples` by maximum likelihood (see the module).
pub fn fit_growth(samples: &[HeldOut]) -> GrowthFit {
    fit_growth_floored(samples, 0.0)
}

/// [`fit_growth`] with `s0` at least `min_s0` (what the identification residuals show at the
/// measured postures): when the likelihood's `s0` is below it, `s0 = min_s0` and `c` is fitted
/// again with that `s0` (m or rad).
pub fn fit_growth_floored(samples: &[HeldOut], min_s0: f64) -> GrowthFit {
    let prepared = eigen_parts(samples);
    let nll = |s2: f64, c2: f64| negative_log_likelihood(&prepared, s2, c2);
    let components = samples.iter().map(|h| h.axes).sum::<usize>().max(1) as f64;
    let m2 = (samples
        .iter()
        .map(|h| h.error.iter().map(|x| x * x).sum::<f64>())
        .sum::<f64>()
        / components)
        .max(1e-30);
    let mut ds: Vec<f64> = samples.iter().map(|h| h.distance).collect();
    let distance_median = super::percentile(&mut ds, 0.5);
    let distance_max = ds.last().copied().unwrap_or(0.0);
    let dscale = if distance_median > 0.0 {
        distance_median
    } else if distance_max > 0.0 {
        distance_max
    } else {
        1.0
    };
    let (a0, b0) = (m2.ln(), (m2 / (dscale * dscale)).ln());
    let constant = constant_fit(&nll, a0);
    let best = growing_fit(&nll, constant, a0, b0);
    let mut growth = Growth {
        s0: term(best.1, a0),
        c: term(best.2, b0),
        shape: 3.0,
    };
    let minimum = if min_s0.is_finite() { min_s0 } else { 0.0 };
    if growth.s0 < minimum {
        // `s0` held at the floor, `c` by maximum likelihood again (0 a candidate).
        growth.s0 = minimum;
        growth.c = term(growth_at(&nll, minimum * minimum, b0), b0);
    }
    growth.shape = error_shape(samples, &growth);
    let s0_constant = term(constant.1, a0);
    GrowthFit {
        growth,
        points: samples.len(),
        coverage: coverage(samples, growth),
        coverage_constant: coverage(
            samples,
            Growth {
                s0: s0_constant,
                c: 0.0,
                shape: 3.0,
            },
        ),
        s0_constant,
        coverage_parameters_only: coverage(samples, Growth::ZERO),
        distance_median,
        distance_max,
    }
}

/// A held-out error in the eigenbasis of its parameter part (of its measured components):
/// its squared components, the part's eigenvalues (negative ones as 0), its distance (m), and
/// its number of components.
type EigenPart = ([f64; 3], [f64; 3], f64, usize);

/// Each sample in the eigenbasis of its parameter part.
fn eigen_parts(samples: &[HeldOut]) -> Vec<EigenPart> {
    samples
        .iter()
        .map(|h| {
            let sym = |i: usize, j: usize| 0.5 * (h.parameters[i][j] + h.parameters[j][i]);
            let (g2, l) = if h.axes == 2 {
                let eig = nalgebra::Matrix2::from_fn(sym).symmetric_eigen();
                let g =
                    eig.eigenvectors.transpose() * nalgebra::Vector2::new(h.error[0], h.error[1]);
                (
                    [g.x * g.x, g.y * g.y, 0.0],
                    [eig.eigenvalues.x.max(0.0), eig.eigenvalues.y.max(0.0), 0.0],
                )
            } else {
                let eig = Matrix3::from_fn(sym).symmetric_eigen();
                let g = eig.eigenvectors.transpose() * Vector3::from(h.error);
                (
                    [g.x * g.x, g.y * g.y, g.z * g.z],
                    [
                        eig.eigenvalues.x.max(0.0),
                        eig.eigenvalues.y.max(0.0),
                        eig.eigenvalues.z.max(0.0),
                    ],
                )
            };
            (g2, l, h.distance, h.axes.min(3))
        })
        .collect()
}

/// Twice the negative log-likelihood (less constants) of the held-out errors with the model
/// error's variance `s2 + c2 d^2` per component added to the parameters' part.
fn negative_log_likelihood(prepared: &[EigenPart], s2: f64, c2: f64) -> f64 {
    prepared
        .iter()
        .map(|(g2, l, d, axes)| {
            let v = s2 + c2 * d * d;
            (0..*axes)
                .map(|k| {
                    let t = (l[k] + v).max(1e-300);
                    t.ln() + g2[k] / t
                })
                .sum::<f64>()
        })
        .sum()
}

/// The constant term's fit `(nll, log s0^2)`: a grid of `log s0^2` in steps of 1 from `a0 -
/// 14` to `a0 + 2`, refined by halving 20 times.
fn constant_fit(nll: &dyn Fn(f64, f64) -> f64, a0: f64) -> (f64, f64) {
    let mut best = (f64::INFINITY, a0);
    let mut step = 1.0;
    for i in -14..=2 {
        let a = a0 + i as f64 * step;
        let f = nll(a.exp(), 0.0);
        if f < best.0 {
            best = (f, a);
        }
    }
    for _ in 0..20 {
        step *= 0.5;
        for a in [best.1 - step, best.1 + step] {
            let f = nll(a.exp(), 0.0);
            if f < best.0 {
                best = (f, a);
            }
        }
    }
    best
}

/// The growing term's fit `(nll, log s0^2, log c^2)`, from the `constant` fit (`log c^2`
/// minus infinity): a grid over (log s0^2, log c^2) around `(a0, b0)`, refined by halving.
fn growing_fit(
    nll: &dyn Fn(f64, f64) -> f64,
    constant: (f64, f64),
    a0: f64,
    b0: f64,
) -> (f64, f64, f64) {
    let mut best = (constant.0, constant.1, f64::NEG_INFINITY);
    let mut step = 1.0;
    for i in -14..=2 {
        for j in -14..=4 {
            let (a, b) = (a0 + i as f64 * step, b0 + j as f64 * step);
            let f = nll(a.exp(), b.exp());
            if f < best.0 {
                best = (f, a, b);
            }
        }
    }
    if best.2.is_finite() {
        for _ in 0..20 {
            step *= 0.5;
            let centre = best;
            for i in -1..=1 {
                for j in -1..=1 {
                    let (a, b) = (centre.1 + i as f64 * step, centre.2 + j as f64 * step);
                    let f = nll(a.exp(), b.exp());
                    if f < best.0 {
                        best = (f, a, b);
                    }
                }
            }
        }
    }
    best
}

/// `log c^2` by maximum likelihood with `s0^2` held at `s2` (minus infinity, no growth, a
/// candidate): a grid around `b0`, refined by halving.
fn growth_at(nll: &dyn Fn(f64, f64) -> f64, s2: f64, b0: f64) -> f64 {
    let mut best = (nll(s2, 0.0), f64::NEG_INFINITY);
    let mut step = 1.0;
    for j in -14..=4 {
        let b = b0 + j as f64 * step;
        let f = nll(s2, b.exp());
        if f < best.0 {
            best = (f, b);
        }
    }
    if best.1.is_finite() {
        for _ in 0..20 {
            step *= 0.5;
            let centre = best.1;
            for b in [centre - step, centre + step] {
                let f = nll(s2, b.exp());
                if f < best.0 {
                    best = (f, b);
                }
            }
        }
    }
    best.1
}

/// A term from its fitted `log_sq` (its square's logarithm): none at the grid's lower end
/// (13.5 below `log_ref`), where a term is not told from none (the parameters' part covers the
/// held-out errors).
fn term(log_sq: f64, log_ref: f64) -> f64 {
    if log_sq.is_finite() && log_sq > log_ref - 13.5 {
        (0.5 * log_sq).exp()
    } else {
        0.0
    }
}

/// The shape of the errors under `growth`: the second-moment matrix of the errors, each in its
/// own predicted standard deviations, `9 tr M^2 / (tr M)^2` within 3 to 9 (of three-component
/// errors only: a pixel's says nothing along its line of sight); 3 when no error counts.
fn error_shape(samples: &[HeldOut], growth: &Growth) -> f64 {
    let mut m = Matrix3::zeros();
    for h in samples.iter().filter(|h| h.axes == 3) {
        let p = h.parameters[0][0] + h.parameters[1][1] + h.parameters[2][2];
        let v = growth.variance(h.distance) + p / 3.0;
        if v > 0.0 {
            let e = Vector3::from(h.error);
            m += e * e.transpose() / v;
        }
    }
    let tr = m.trace();
    if tr > 0.0 {
        (9.0 * (m * m).trace() / (tr * tr)).clamp(3.0, 9.0)
    } else {
        growth.shape
    }
}

/// The share of `samples` whose error lies within its predicted 95 % bound under `g`.
fn coverage(samples: &[HeldOut], g: Growth) -> f64 {
    let n = samples.len().max(1) as f64;
    let inside = samples
        .iter()
        .filter(|h| {
            let e = Vector3::from(h.error).norm();
            e <= h.bound(g.variance(h.distance), g.shape).bound
        })
        .count();
    inside as f64 / n
}
