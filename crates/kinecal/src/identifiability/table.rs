//! The Jacobian of an analysis for display (`kinecal analyze --print`).

use crate::linalg::Matrix;
use crate::model::robot::Robot;
use crate::observe::Dataset;
use crate::solve::problem::Problem;

use super::spectrum::file_row_scale;
use super::{Analysis, AnalysisOptions};

/// The Jacobian of an [`Analysis`], row by row, for display (`kinecal analyze --print`): an
/// m x n matrix and a label per row, so build it only to show it; the analysis itself never
/// holds it.
#[derive(Debug, Clone)]
pub struct JacobianTable {
    /// Per row: posture label(s) (`a&b` for a pair), target, row label.
    pub row_labels: Vec<(String, String, &'static str)>,
    /// The scaled Jacobian `W J D^-1` (unit columns; unfelt columns zeroed), as analysed.
    pub scaled: Matrix,
    /// The Jacobian in file units: rows in the file's length or angle unit per the parameter's
    /// file unit.
    pub file: Matrix,
}

/// The Jacobian that `analysis` (of `data` on `robot`, with `opts`) analysed, for display.
pub fn jacobian_table(
    robot: &Robot,
    data: &Dataset,
    analysis: &Analysis,
    opts: &AnalysisOptions,
) -> JacobianTable {
    let params = &analysis.parameters;
    let problem = Problem::new(robot, data, params, opts.weights, opts.orientation);
    let (m, n) = (problem.rows(), params.len());
    let mut r = vec![0.0; m];
    let mut jw = Matrix::zeros(m, n);
    problem.evaluate(robot, &mut r, Some(&mut jw));
    let mut row_labels = Vec::with_capacity(m);
    for o in &data.observations {
        let postures: Vec<&str> = o
            .views()
            .iter()
            .map(|v| data.postures[v.posture].label.as_str())
            .collect();
        let postures = postures.join("&");
        let site = crate::observe::target_name(robot, o.target()).to_string();
        for row in o.rows() {
            row_labels.push((postures.clone(), site.clone(), row.label));
        }
    }
    let row_scale = file_row_scale(robot, data, &problem);
    let units = robot.units;
    let col_factor: Vec<f64> = params
        .iter()
        .map(|&id| units.factor(robot.param_quantity(id)))
        .collect();
    let file = Matrix::from_fn(m, n, |i, j| jw[(i, j)] * row_scale[i] * col_factor[j]);
    let scaled = Matrix::from_fn(m, n, |i, j| {
        let c = analysis.column_norms[j];
        if analysis.unobservable.contains(&params[j]) || c <= 0.0 {
            0.0
        } else {
            jw[(i, j)] / c
        }
    });
    JacobianTable {
        row_labels,
        scaled,
        file,
    }
}
