//! The arrays of a calibration's outcome that the report does not carry: the parameter
//! covariance and the residuals of the identification data (the Python package's
//! `Calibration.covariance`, `Calibration.residuals` and `Calibration.residual_rows`).

use kinecal::observe::{target_name, RowQuantity};
use kinecal::units::Quantity;
use kinecal::workflow::Outcome;
use numpy::IntoPyArray;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::bad;

/// `covariance` (`(n, n)` in file units, the estimated parameters in id order, or None when the
/// uncertainty could not be computed), `covariance_names` (that order), `residuals` (one per
/// row of the identification data, `model - measured` in file units) and `residual_rows`
/// (`(posture, kind, target, row, sigma)` per row, sigma in file units).
pub fn details<'py>(py: Python<'py>, outcome: &Outcome) -> PyResult<Bound<'py, PyDict>> {
    let cal = &outcome.calibration;
    let robot = &cal.calibrated;
    let d = PyDict::new(py);
    // The covariance, in the order of the report's parameters (ascending ids).
    let mut order: Vec<usize> = (0..cal.estimated.len()).collect();
    order.sort_by_key(|&k| cal.estimated[k]);
    d.set_item(
        "covariance_names",
        order
            .iter()
            .map(|&k| robot.param_name(cal.estimated[k]))
            .collect::<Vec<_>>(),
    )?;
    match &outcome.uncertainty {
        Some(u) => {
            if u.analysis.parameters != cal.estimated {
                return Err(bad(
                    "the uncertainty is not over the estimated parameters: no covariance",
                ));
            }
            let c = u.covariance_file(robot);
            let n = order.len();
            let flat: Vec<f64> = order
                .iter()
                .flat_map(|&a| order.iter().map(|&b| c[a][b]).collect::<Vec<_>>())
                .collect();
            d.set_item("covariance", crate::row_major_array(py, (n, n), flat))?;
        }
        None => d.set_item("covariance", py.None())?,
    }
    // The residuals: the solver's weighted ones times each row's standard deviation.
    let data = &outcome.data;
    let problem = cal.problem(data);
    let sigma = problem.row_sigma();
    if cal.residuals.len() != sigma.len() {
        return Err(bad(format!(
            "the calibration has {} residuals for {} rows of data: no residuals",
            cal.residuals.len(),
            sigma.len()
        )));
    }
    let units = robot.units;
    let mut residuals = Vec::with_capacity(sigma.len());
    let mut rows = Vec::with_capacity(sigma.len());
    let mut k = 0;
    for o in &data.observations {
        let posture = &data.postures[o.posture()].label;
        let target = target_name(robot, o.target());
        for spec in o.rows() {
            let q = match spec.quantity {
                RowQuantity::Length => Quantity::Length,
                RowQuantity::Angle => Quantity::Angle,
                RowQuantity::Pixel => Quantity::Pixel,
            };
            residuals.push(units.from_si(q, cal.residuals[k] * sigma[k]));
            rows.push((
                posture.clone(),
                o.kind(),
                target.to_string(),
                spec.label,
                units.from_si(q, sigma[k]),
            ));
            k += 1;
        }
    }
    d.set_item("residuals", residuals.into_pyarray(py))?;
    d.set_item("residual_rows", rows)?;
    Ok(d)
}
