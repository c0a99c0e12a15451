//! The command line's `predict` and `iso9283 log|evaluate` as functions (wrapped by the Python
//! package's `kinecal.predict`, `Calibration.predict`, `kinecal.iso9283_log` and
//! `kinecal.iso9283`). Values are in the robot's units (a log's in its own); results come back as
//! dicts of numpy arrays, or the JSON document the command line writes.

use kinecal::apps::compensate::{goal_in_file_units, Options, TargetSearch};
use kinecal::apps::iso9283::{self, LogUnits, PlacedLog};
use kinecal::predict::{self as prediction, PredictionReport};
use kinecal::report::CalibrationReport;
use kinecal::units::Quantity;
use kinecal::Target;
use numpy::ndarray::Array1;
use numpy::IntoPyArray;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::commands::target_of;
use crate::{bad, error, numbers, readings_array, Measurements, Robot};

/// The calibration report `report_json` of `robot`, and its prediction. An error when the text
/// is not a report, the report has no prediction, or `robot` is not its calibrated robot.
fn calibrated_prediction(
    py: Python<'_>,
    robot: &kinecal::Robot,
    report_json: &str,
) -> PyResult<PredictionReport> {
    let report = CalibrationReport::from_json(report_json)
        .map_err(|e| bad(format!("report: not a calibration report: {e}")))?;
    let Some(pr) = report.prediction.clone() else {
        return Err(bad(format!(
            "report: the calibration made no prediction (calibrate with predict=True; it needs \
             at least {} postures measured by position or pose)",
            prediction::MIN_POSTURES
        )));
    };
    report
        .check_calibrated(robot, "robot")
        .map_err(|e| error(py, e))?;
    Ok(pr)
}

/// The target a prediction is for: `site`, else the report's.
fn predicted_target(
    robot: &kinecal::Robot,
    pr: &PredictionReport,
    site: Option<&str>,
) -> PyResult<Target> {
    target_of(robot, site.or(Some(pr.target.as_str())), "site")
}

/// The readings that reach each row of `targets` (`(n, 3)` positions or `(n, 6)` poses with
/// ZYX Euler angles, file units) through `robot`'s inverse kinematics; an error names a row out
/// of reach or outside a joint range.
fn reach(
    py: Python<'_>,
    robot: &kinecal::Robot,
    targets: &Bound<'_, PyAny>,
    target: Target,
) -> PyResult<Vec<f64>> {
    let (v, shape) = numbers(py, targets, "targets", 2)?;
    let cols = shape.get(1).copied().unwrap_or(0);
    if !(cols == 3 || cols == 6) || v.is_empty() {
        return Err(bad(format!(
            "targets: expected shape (n, 3) for positions or (n, 6) for poses, got {shape:?}"
        )));
    }
    let u = robot.units;
    let mut search =
        TargetSearch::new(robot, robot, Options::default()).map_err(|e| error(py, e))?;
    let dof = robot.dof();
    let mut out = vec![0.0; dof];
    let mut readings = Vec::with_capacity(v.len() / cols * dof);
    for (i, row) in v.chunks_exact(cols).enumerate() {
        let euler = (cols == 6).then(|| [row[3], row[4], row[5]]);
        let goal = goal_in_file_units(robot, [row[0], row[1], row[2]], euler)
            .map_err(|p| crate::commands::goal_problem(&p, i))?;
        let s = py.detach(|| search.solve(&goal, target, None, &mut out));
        if s.flags.unreachable || s.flags.out_of_range != 0 {
            return Err(bad(format!(
                "targets: row {i}: the calibrated robot does not reach it ({}): is it in the \
                 robot's global frame and length unit ({})?",
                s.flags.describe(),
                u.length
            )));
        }
        readings.extend_from_slice(&out);
    }
    Ok(readings)
}

/// The predicted accuracy of `robot` (a calibrated robot) from its calibration report at
/// `postures` (readings) or `targets` (Cartesian goals through the inverse kinematics): a dict
/// of arrays in the robot's units (`readings`, `position`, `distance`, and per quantity its
/// parameters' and model error's RMS parts, the 95 % bound, the bound of the parameters alone).
#[pyfunction]
#[pyo3(signature = (robot, report_json, *, postures=None, targets=None, site=None))]
pub fn predict<'py>(
    py: Python<'py>,
    robot: &Robot,
    report_json: &str,
    postures: Option<&Bound<'py, PyAny>>,
    targets: Option<&Bound<'py, PyAny>>,
    site: Option<&str>,
) -> PyResult<Bound<'py, PyDict>> {
    let r = &robot.robot;
    let pr = calibrated_prediction(py, r, report_json)?;
    let (predictor, target) =
        kinecal::spec::PredictSpec::predictor(r, &pr, site.unwrap_or(&pr.target))
            .map_err(|e| error(py, e))?;
    let dof = r.dof();
    let readings = match (postures, targets) {
        (Some(p), None) => readings_array(py, p, dof)?.0,
        (None, Some(t)) => reach(py, r, t, target)?,
        _ => return Err(bad("give postures or targets (one of them)")),
    };
    if readings.iter().any(|v| !v.is_finite()) {
        return Err(bad("postures: a reading is not finite"));
    }
    let n = readings.len() / dof;
    let u = r.units;
    let l = |v: f64| u.from_si(Quantity::Length, v);
    let a = |v: f64| u.from_si(Quantity::Angle, v);
    let attitude = pr.attitude.is_some();
    let mut position = Vec::with_capacity(3 * n);
    let mut cols: Vec<Vec<f64>> = (0..9).map(|_| Vec::with_capacity(n)).collect();
    py.detach(|| {
        let mut s = predictor.scratch();
        for q in readings.chunks_exact(dof) {
            let p = predictor.predict(q, target, &mut s);
            position.extend(p.position.iter().map(|&v| l(v)));
            let b = p.position_error;
            for (c, v) in cols.iter_mut().zip([
                l(p.distance),
                l(b.parameters),
                l(b.model),
                l(b.bound),
                l(b.parameters_bound),
            ]) {
                c.push(v);
            }
            if let Some(b) = p.attitude_error {
                for (c, v) in cols[5..].iter_mut().zip([
                    a(b.parameters),
                    a(b.model),
                    a(b.bound),
                    a(b.parameters_bound),
                ]) {
                    c.push(v);
                }
            }
        }
    });
    let d = PyDict::new(py);
    d.set_item("readings", crate::row_major_array(py, (n, dof), readings))?;
    d.set_item("position", crate::row_major_array(py, (n, 3), position))?;
    let names = [
        "distance",
        "position_parameters",
        "position_model",
        "position_bound95",
        "position_bound95_parameters",
        "attitude_parameters",
        "attitude_model",
        "attitude_bound95",
        "attitude_bound95_parameters",
    ];
    for (k, (name, c)) in names.iter().zip(cols).enumerate() {
        if k >= 5 && !attitude {
            break;
        }
        d.set_item(*name, Array1::from(c).into_pyarray(py))?;
    }
    Ok(d)
}

/// An ISO 9283 log of `measurements` for `robot` with the postures' `roles` (CSV text
/// `posture,test,pose,cycle`): `(log CSV, postures left out, sessions placed)`; lengths in
/// `length_unit` when given, else the robot's.
#[pyfunction]
#[pyo3(signature = (robot, measurements, roles, *, roles_file="roles", length_unit=None))]
pub fn iso9283_log(
    py: Python<'_>,
    robot: &Robot,
    measurements: &Measurements,
    roles: &str,
    roles_file: &str,
    length_unit: Option<&str>,
) -> PyResult<(String, Vec<String>, Vec<String>)> {
    measurements.check(&robot.robot, "measurements")?;
    let roles = iso9283::read_roles(roles, roles_file).map_err(|e| error(py, e))?;
    let unit = length_unit
        .map(|u| {
            u.parse()
                .map_err(|e: String| bad(format!("length_unit: {e}")))
        })
        .transpose()?;
    let PlacedLog {
        mut log,
        left_out,
        placed,
    } = py
        .detach(|| iso9283::log_placed(&robot.robot, &measurements.data, &roles))
        .map_err(|e| error(py, e))?;
    if let Some(u) = unit {
        log = log.with_length_unit(u).map_err(|e| error(py, e))?;
    }
    Ok((iso9283::write_log(&log), left_out, placed))
}

/// The ISO 9283 figures of a log (CSV text) as the JSON document `kinecal iso9283 evaluate
/// --json` writes; with `robot` and `report_json` (a calibrated robot and its report), each pose
/// also gets the accuracy predicted once compensated.
#[pyfunction]
#[pyo3(signature = (log, *, file="log", length_unit=None, angle_unit=None, robot=None, report_json=None, site=None))]
#[allow(clippy::too_many_arguments)]
pub fn iso9283_evaluate(
    py: Python<'_>,
    log: &str,
    file: &str,
    length_unit: Option<&str>,
    angle_unit: Option<&str>,
    robot: Option<&Robot>,
    report_json: Option<&str>,
    site: Option<&str>,
) -> PyResult<String> {
    let units = LogUnits {
        length: length_unit
            .map(|u| {
                u.parse()
                    .map_err(|e: String| bad(format!("length_unit: {e}")))
            })
            .transpose()?,
        angle: angle_unit
            .map(|u| {
                u.parse()
                    .map_err(|e: String| bad(format!("angle_unit: {e}")))
            })
            .transpose()?,
    };
    let log = iso9283::read_log(log, file, units).map_err(|e| error(py, e))?;
    let mut e = iso9283::evaluate(&log).map_err(|e| error(py, e))?;
    match (robot, report_json) {
        (Some(robot), Some(report)) => {
            let r = &robot.robot;
            let pr = calibrated_prediction(py, r, report)?;
            let target = predicted_target(r, &pr, site)?;
            let predictor = prediction::from_report(r, &pr).map_err(|e| error(py, e))?;
            iso9283::predict_compensated(&mut e, &log, &predictor, target)
                .map_err(|e| error(py, e))?;
        }
        (None, None) => {}
        _ => {
            return Err(bad(
                "give robot and report together (a calibrated robot and its report)",
            ))
        }
    }
    serde_json::to_string_pretty(&e).map_err(|e| bad(format!("the figures as JSON: {e}")))
}
