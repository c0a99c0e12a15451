//! Observations that the calibrated model misses by much more than the others.
//!
//! Each residual row is taken in its own standard deviations (the row's own `sigma_*`, or the
//! default weights) and compared with a robust scale of the rows *like it*: the rows of the same
//! kind of observation and the same quantity (lengths apart from angles), scale 1.4826 times
//! their median absolute value, which a few bad rows cannot inflate. Pooling lengths and angles
//! would make whichever the weights overstate look clean and the other look bad. An observation
//! is an outlier when one of its rows is beyond `k` such scales. Outliers are listed for the user
//! to look at, never dropped.

use crate::estimation::Calibration;
use crate::observe::{Context, Dataset, ErrorSample, RobustSpread};
use crate::problem::Problem;

/// Default threshold, in robust standard deviations.
pub const DEFAULT_SIGMAS: f64 = 4.0;

/// An observation the calibrated model misses by far more than the rest.
#[derive(Debug, Clone, PartialEq)]
pub struct Outlier {
    /// Index into the dataset's observations.
    pub observation: usize,
    /// Its largest residual row in robust standard deviations of rows like it.
    pub sigmas: f64,
    /// Its error in its own metric.
    pub error: ErrorSample,
}

/// The observations of `data` with a residual row beyond `k` robust standard deviations, for
/// the calibrated robot of `cal`.
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
    // The robust scale of each (kind, quantity) group of rows.
    let scale = RobustSpread::of(data, r).per_row;
    let ctx = Context {
        robot,
        orientation: cal.options.orientation,
    };
    // The residuals tell which observations are outliers; forward kinematics runs again only
    // for those, to give their errors.
    let chain = crate::kinematics::Chain::new(robot);
    let mut out = Vec::new();
    let mut row = 0;
    for (i, o) in data.observations.iter().enumerate() {
        let n = o.rows().len();
        let worst = (row..row + n)
            .map(|j| r[j].abs() / scale[j])
            .fold(0.0f64, f64::max);
        if worst > k {
            let views = o.views();
            let mut frames = [crate::kinematics::Frame::identity(); 2];
            for (f, v) in frames.iter_mut().zip(views) {
                *f = chain.frame_at(&data.postures[v.posture].readings, v.target);
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
