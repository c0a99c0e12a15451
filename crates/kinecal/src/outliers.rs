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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimation::{calibrate, CalibrationOptions};
    use crate::simulate::{self, PerturbStd};
    use crate::{JointKind, ParamId};

    /// The calibration's own final residuals flag the same observations, by the same amounts,
    /// as a fresh pass of forward kinematics.
    #[test]
    fn the_fits_residuals_flag_what_a_fresh_pass_flags() {
        let nominal = simulate::random_robot(&[JointKind::Revolute; 6], 8);
        let std = PerturbStd {
            length: 1e-3,
            angle: 0.2f64.to_radians(),
            slope_fraction: 0.0,
        };
        let truth = simulate::perturb(&nominal, std, 1);
        let mut data = simulate::measure(&truth, &simulate::sample_postures(&nominal, 80, 2), true);
        simulate::add_noise(&mut data, 2e-5, 0.0, 3);
        // Three gross errors.
        for i in [5, 40, 77] {
            if let crate::observe::Observation::Position(p) = &mut data.observations[i] {
                p.position.x += 1e-3;
            }
        }
        let ids: Vec<ParamId> = crate::workflow::default_parameters(&nominal, &data).0;
        let base = crate::identifiability::analyze_core(
            &nominal,
            &data,
            &ids,
            &crate::identifiability::AnalysisOptions::default(),
        )
        .unwrap()
        .identifiable;
        let cal = calibrate(&nominal, &data, &CalibrationOptions::new(base), &mut |_| {}).unwrap();
        let reused = outliers_of_fit(&cal, &data, DEFAULT_SIGMAS);
        let fresh = outliers(&cal, &data, DEFAULT_SIGMAS);
        let found: Vec<usize> = reused.iter().map(|o| o.observation).collect();
        assert_eq!(found, vec![5, 40, 77]);
        assert_eq!(
            found,
            fresh.iter().map(|o| o.observation).collect::<Vec<_>>()
        );
        for (a, b) in reused.iter().zip(&fresh) {
            assert!((a.sigmas - b.sigmas).abs() <= 1e-9 * b.sigmas);
        }
    }
}
