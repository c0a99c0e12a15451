//! A calibration's outcome as the Python package holds it (`kinecal.Calibration`): kept whole,
//! and turned into Python objects only when one is read. The report is written as JSON text
//! when `Calibration.report` or `to_json()` first needs it, and the arrays the report does not
//! carry (the parameter covariance, the residuals of the identification data and what each
//! residual row is) when their attribute is read: a calibration whose caller reads only a few
//! figures pays for no others.

use std::collections::HashMap;

use kinecal::observe::{target_name, RowQuantity};
use kinecal::units::Quantity;
use kinecal::workflow::Outcome;
use numpy::{IntoPyArray, PyArray1, PyArray2};
use pyo3::prelude::*;
use pyo3::types::{PyString, PyTuple};

use crate::bad;

/// A calibration's outcome (the library's, whole): the report and the arrays of
/// `kinecal.Calibration`, each made when it is asked for.
#[pyclass(module = "kinecal._native", name = "Outcome", frozen)]
pub struct CalibrationOutcome {
    outcome: Box<Outcome>,
}

impl CalibrationOutcome {
    /// Keeps `outcome` for Python.
    pub fn new(outcome: Box<Outcome>) -> Self {
        CalibrationOutcome { outcome }
    }

    /// The estimated parameters' positions in `calibration.estimated`, in the order of the
    /// report's parameters (ascending ids).
    fn report_order(&self) -> Vec<usize> {
        let estimated = &self.outcome.calibration.estimated;
        let mut order: Vec<usize> = (0..estimated.len()).collect();
        order.sort_by_key(|&k| estimated[k]);
        order
    }
}

#[pymethods]
impl CalibrationOutcome {
    /// The report as JSON text (what `kinecal calibrate --report` writes).
    fn report_json(&self, py: Python<'_>) -> String {
        let report = &self.outcome.report;
        py.detach(|| report.to_json())
    }

    /// The covariance of the estimated parameters, `(n, n)` in file units in the order of the
    /// report's estimated parameters (ascending ids), or None when the uncertainty could not
    /// be computed. Refused when that order is not the report's.
    fn covariance<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyArray2<f64>>>> {
        let cal = &self.outcome.calibration;
        let robot = &cal.calibrated;
        let order = self.report_order();
        let reported = self
            .outcome
            .report
            .parameters
            .iter()
            .filter(|p| p.estimated_flag)
            .map(|p| p.name.as_str());
        let names: Vec<String> = order
            .iter()
            .map(|&k| robot.param_name(cal.estimated[k]))
            .collect();
        if !reported.eq(names.iter().map(String::as_str)) {
            return Err(bad(
                "the covariance is not in the order of the estimated parameters",
            ));
        }
        let Some(u) = &self.outcome.uncertainty else {
            return Ok(None);
        };
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
        Ok(Some(crate::row_major_array(py, (n, n), flat)))
    }

    /// The residuals of the identification data, one per residual row, `model - measured` in
    /// file units (the solver's weighted residuals times each row's standard deviation).
    fn residuals<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let rows = self.rows()?;
        let residuals: Vec<f64> = rows.iter().map(|r| r.residual).collect();
        Ok(residuals.into_pyarray(py))
    }

    /// What each residual row is: `(posture, kind, target, row, sigma)`, sigma in file units.
    /// The labels are shared Python strings (one per posture and one per distinct name).
    fn residual_rows<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyTuple>>> {
        self.rows_as_tuples(py)
    }
}

impl CalibrationOutcome {
    /// [`CalibrationOutcome::residual_rows`].
    fn rows_as_tuples<'a, 'py>(&'a self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyTuple>>> {
        let rows = self.rows()?;
        let mut names: HashMap<&'a str, Bound<'py, PyString>> = HashMap::new();
        let mut name = |s: &'a str| {
            names
                .entry(s)
                .or_insert_with(|| PyString::new(py, s))
                .clone()
        };
        let postures = &self.outcome.data.postures;
        let mut label: Option<(usize, Bound<'py, PyString>)> = None;
        let mut out = Vec::with_capacity(rows.len());
        for r in &rows {
            let posture = match &label {
                Some((p, s)) if *p == r.posture => s.clone(),
                _ => {
                    let s = PyString::new(py, &postures[r.posture].label);
                    label = Some((r.posture, s.clone()));
                    s
                }
            };
            let items = [
                posture.into_any(),
                name(r.kind).into_any(),
                name(r.target).into_any(),
                name(r.row).into_any(),
                r.sigma.into_pyobject(py)?.into_any(),
            ];
            out.push(PyTuple::new(py, items)?);
        }
        Ok(out)
    }
}

/// One residual row of the identification data, in file units.
struct ResidualRow<'a> {
    /// The observation's (first) posture, an index into the data's postures.
    posture: usize,
    kind: &'static str,
    target: &'a str,
    row: &'static str,
    residual: f64,
    sigma: f64,
}

impl CalibrationOutcome {
    /// The identification data's residual rows, observation after observation.
    fn rows(&self) -> PyResult<Vec<ResidualRow<'_>>> {
        let cal = &self.outcome.calibration;
        let robot = &cal.calibrated;
        let data = &self.outcome.data;
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
        let mut rows = Vec::with_capacity(sigma.len());
        let mut k = 0;
        for o in &data.observations {
            let target = target_name(robot, o.target());
            for spec in o.rows() {
                let q = match spec.quantity {
                    RowQuantity::Length => Quantity::Length,
                    RowQuantity::Angle => Quantity::Angle,
                    RowQuantity::Pixel => Quantity::Pixel,
                };
                rows.push(ResidualRow {
                    posture: o.posture(),
                    kind: o.kind(),
                    target,
                    row: spec.label,
                    residual: units.from_si(q, cal.residuals[k] * sigma[k]),
                    sigma: units.from_si(q, sigma[k]),
                });
                k += 1;
            }
        }
        Ok(rows)
    }
}
