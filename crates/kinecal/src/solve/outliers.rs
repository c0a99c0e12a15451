//! Observations that the calibrated model misses by much more than the others.
//!
//! Each residual row is taken in its own standard deviations (the row's own `sigma_*`, or the
//! default weights) and compared with a robust scale of the rows *like it*: the rows of the same
//! kind of observation and the same quantity (lengths apart from angles), scale 1.4826 times
//! their median absolute value, which a few bad rows cannot inflate. Pooling lengths and angles
//! would make whichever the weights overstate look clean and the other look bad. An observation
//! is an outlier when one of its rows is beyond `k` such scales. Outliers are listed for the user
//! to look at, never dropped.
//!
//! Every row is a test, and many tests of clean data find some large values: among a million
//! rows of Gaussian noise, 63 lie beyond 4 standard deviations. So `k` is a floor: it is raised
//! to the [`threshold`] beyond which the data's rows of pure Gaussian noise would put
//! [`FALSE_ROWS`] of a row on average (4.15 for 3,000 rows, 4.8 for 60,000, 5.6 for 6,000,000;
//! below about 1,600 rows, `k = 4` stands).

use crate::observe::{Context, Dataset, ErrorSample, RobustSpread};
use crate::solve::estimation::Calibration;
use crate::solve::problem::Problem;

/// Default threshold, in robust standard deviations.
pub const DEFAULT_SIGMAS: f64 = 4.0;

/// The expected number of rows of pure Gaussian noise flagged that the [`threshold`] allows,
/// whatever the number of rows.
pub const FALSE_ROWS: f64 = 0.1;

/// The threshold, in robust standard deviations, that `k` becomes for `rows` residual rows: the
/// larger of `k` and the level `t` with `rows * P(|z| > t) = FALSE_ROWS` for standard normal
/// `z` (so that clean data is expected to show no outlier whatever its size).
pub fn threshold(k: f64, rows: usize) -> f64 {
    // Two-sided tail P(|z| > t) = erfc(t / sqrt 2), decreasing in t: bisection on [0, 40] to
    // well below 1e-12 (60 halvings of 40).
    let p = FALSE_ROWS / rows.max(1) as f64;
    let (mut lo, mut hi) = (0.0f64, 40.0f64);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if libm::erfc(mid / std::f64::consts::SQRT_2) > p {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    k.max(hi)
}

/// An observation the calibrated model misses by far more than the rest.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct Outlier {
    /// Index into the dataset's observations.
    pub observation: usize,
    /// Its largest residual row in robust standard deviations of rows like it.
    pub sigmas: f64,
    /// Its error in its own metric.
    pub error: ErrorSample,
}

/// The observations of `data` with a residual row beyond the [`threshold`] `k` becomes for
/// the data's rows, in robust standard deviations, for the calibrated robot of `cal`.
pub fn outliers(cal: &Calibration, data: &Dataset, k: f64) -> Vec<Outlier> {
    let robot = &cal.calibrated;
    let problem = Problem::new(
        robot,
        data,
        &cal.estimated,
        cal.options.weights,
        cal.options.orientation,
    );
    let mut r = vec![0.0; problem.rows()];
    problem.evaluate(robot, &mut r, None);
    flag(cal, data, &r, k)
}

/// [`outliers`] of a calibration on the data it was fitted to: its final residuals are those
/// wanted, and no further pass of forward kinematics is needed.
pub(crate) fn outliers_of_fit(cal: &Calibration, data: &Dataset, k: f64) -> Vec<Outlier> {
    if cal.residuals.len() != data.rows() {
        return outliers(cal, data, k);
    }
    flag(cal, data, &cal.residuals, k)
}

/// The observations with a row of `r` (the weighted residuals of `cal.calibrated` on `data`)
/// beyond `k` robust scales.
fn flag(cal: &Calibration, data: &Dataset, r: &[f64], k: f64) -> Vec<Outlier> {
    let robot = &cal.calibrated;
    let k = threshold(k, r.len());
    // The robust scale of each (kind, quantity) group of rows.
    let scale = RobustSpread::of(data, r).per_row;
    let ctx = Context {
        robot,
        orientation: cal.options.orientation,
    };
    // The residuals tell which observations are outliers; forward kinematics runs again only
    // for those, to give their errors.
    let chain = crate::model::kinematics::Chain::new(robot);
    let mut out = Vec::new();
    let mut row = 0;
    for (i, o) in data.observations.iter().enumerate() {
        let n = o.rows().len();
        let worst = (row..row + n)
            .map(|j| r[j].abs() / scale[j])
            .fold(0.0f64, f64::max);
        if worst > k {
            let views = o.views();
            let mut frames = [crate::model::kinematics::Frame::identity(); 2];
            for (f, v) in frames.iter_mut().zip(views) {
                let at = chain.frame_at(&data.postures[v.posture].readings, v.target);
                *f = crate::observe::observed_frame(robot, data, o, *v, at);
            }
            out.push(Outlier {
                observation: i,
                sigmas: worst,
                error: o.error(&ctx, &frames[..views.len()]),
            });
        }
        row += n;
    }
    out
}
