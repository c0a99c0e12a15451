//! The minimum-change answer: among the equally good answers of data that leaves some parameters
//! undetermined, the one closest to the nominal robot in tolerance units.

use crate::error::{Error, Result};
use crate::identifiability::{self, AnalysisOptions};
use crate::model::robot::Robot;
use crate::observe::Dataset;
use crate::solve::estimation::CalibrationOptions;
use crate::solve::problem::Problem;
use crate::units::{wrap_angle, Quantity};

/// Which of several equally good answers a calibration returns when the data leaves some
/// parameters undetermined (in a calibration spec: `solver`, `min-change`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[non_exhaustive]
pub enum SolutionRule {
    /// Wherever the solver stops: in the undetermined directions this depends on the starting
    /// point and the solver's path (thesis Table 4.8).
    #[default]
    Solver,
    /// Among the equally good answers, the one closest to the nominal robot in the metric
    /// `sum ((p - p_nominal) / tolerance)^2`, tolerances from the nominal robot file's
    /// `[tolerances]`. It does not depend on the starting point.
    MinChange,
}

impl SolutionRule {
    /// `solver` or `min-change`.
    pub fn as_str(self) -> &'static str {
        match self {
            SolutionRule::Solver => "solver",
            SolutionRule::MinChange => "min-change",
        }
    }
}

/// Moves `x` along the undetermined directions to the point closest to `reference` in the
/// tolerance-scaled metric. Returns the new point and the size of the move in tolerance units.
///
/// The undetermined directions are the null space of the Jacobian at the reference (nominal)
/// model, where the design's exact redundancies hold; noise in the data would otherwise turn
/// them into barely determined directions at `x`.
pub(super) fn project_min_change(
    problem: &Problem<'_>,
    x: &[f64],
    reference: &Robot,
    data: &Dataset,
    opts: &CalibrationOptions,
) -> Result<(Vec<f64>, f64)> {
    let mut robot = problem.robot_at(x);
    for &id in problem.estimated() {
        robot.set(id, reference.get(id));
    }
    // With a prior, the answers equally good for the data and the prior together: none where
    // the prior covers every estimated parameter.
    let aopts = AnalysisOptions {
        weights: opts.weights,
        orientation: opts.orientation,
        prior: opts.prior.clone(),
        ..Default::default()
    };
    let a = identifiability::analyze_core(&robot, data, problem.estimated(), &aopts)?;
    let n = x.len();
    // analyze sorts its parameters; map them back to the problem's order.
    let pos: Vec<usize> = problem
        .estimated()
        .iter()
        .map(|id| {
            a.parameters
                .iter()
                .position(|p| p == id)
                .expect("same parameters")
        })
        .collect();
    // Back from scaled to parameter units; a column no observation feels was zeroed in the
    // scaled Jacobian (its null direction is the parameter alone), so it stays unscaled, as
    // dividing by its rounding-level norm would swamp every other direction. Each direction is
    // then normalised, which keeps the small system below well conditioned.
    let null: Vec<Vec<f64>> = (a.rank..n)
        .map(|k| {
            let mut v: Vec<f64> = pos
                .iter()
                .map(|&j| {
                    let v = a.right_singular_vectors[(j, k)];
                    if a.unobservable.contains(&a.parameters[j]) || a.column_norms[j] <= 0.0 {
                        v
                    } else {
                        v / a.column_norms[j]
                    }
                })
                .collect();
            let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
            if norm > 0.0 {
                v.iter_mut().for_each(|x| *x /= norm);
            }
            v
        })
        .collect();
    if null.is_empty() {
        return Ok((x.to_vec(), 0.0));
    }
    let ids = problem.estimated();
    let w: Vec<f64> = ids
        .iter()
        .map(|&id| 1.0 / reference.tolerance(id).powi(2))
        .collect();
    let dx: Vec<f64> = ids
        .iter()
        .zip(x)
        .map(|(&id, &v)| {
            let d = v - reference.get(id);
            if reference.param_quantity(id) == Quantity::Angle {
                wrap_angle(d)
            } else {
                d
            }
        })
        .collect();
    let k = null.len();
    let ata = crate::linalg::Matrix::from_fn(k, k, |a, b| {
        (0..n).map(|j| null[a][j] * w[j] * null[b][j]).sum()
    });
    let atb: Vec<f64> = (0..k)
        .map(|a| (0..n).map(|j| null[a][j] * w[j] * dx[j]).sum())
        .collect();
    let z = crate::linalg::solve_spd(&ata, &atb)
        .ok_or_else(|| Error::Numerical("minimum-change projection is singular".into()))?;
    let mut out = x.to_vec();
    let mut size = 0.0;
    for j in 0..n {
        let step: f64 = (0..k).map(|a| null[a][j] * z[a]).sum();
        out[j] -= step;
        size += step * step * w[j];
    }
    Ok((out, size.sqrt()))
}
