//! From a calibration report to the record a store writes, and from a stored report back to
//! its figures: what every store shares.
//!
//! [`new_record`] checks a report (a robot serial, uncertainty, finite numbers) and turns it into
//! the [`StoredRecord`] every store writes, keyed by its [`idempotency_key`]; [`report_figures`]
//! and [`rms_errors`] read the RMS errors of a stored report when a store reads a calibration.

use kinecal::report::CalibrationReport;
use serde::Deserialize;

use crate::error::{Error, Result};
use crate::model::{RmsError, StoredCombination, StoredParameter, StoredRecord};
use crate::text::printable;
use crate::units::{parse_label, parse_units, quantity_words};
use kinecal::units::LengthUnit;

/// The idempotency key of a calibration of `robot_id`: SHA-256 over the serial, the time when
/// one was given, the fingerprints of the robot and measurement files, and what was estimated
/// how (method, solution rule, loss, weights, the estimated parameters). The same calibration
/// recorded again (a retried job, a rerun batch) has the same key and is not recorded twice;
/// another calibration of the same files (other options) or of other files is another record.
/// A report without fingerprints (one built by a program, not from files) is keyed by its
/// creation time and objective as well.
pub fn idempotency_key(robot_id: &str, at: Option<i64>, report: &CalibrationReport) -> String {
    let mut s = String::from("kinecal calibration key 1\n");
    let mut line = |v: &str| {
        s.push_str(v);
        s.push('\n');
    };
    line(robot_id);
    line(&at.map_or("-".into(), |t| t.to_string()));
    let (m, d) = (&report.robot_file_sha256, &report.data_file_sha256);
    line(m.as_deref().unwrap_or("-"));
    line(d.as_deref().unwrap_or("-"));
    line(report.method.as_str());
    line(&report.solution);
    line(&report.loss);
    line(&format!(
        "{:016x} {:016x}",
        report.weight_length.to_bits(),
        report.weight_angle.to_bits()
    ));
    let estimated: Vec<&str> = report
        .parameters
        .iter()
        .filter(|p| p.estimated_flag)
        .map(|p| p.id.as_str())
        .collect();
    line(&estimated.join(","));
    if m.is_none() || d.is_none() {
        line(&report.created);
        line(&format!("{:016x}", report.objective_after.to_bits()));
    }
    kinecal::source::fingerprint(s.as_bytes())
}

/// Refuses a report with a number a store could not keep (NaN and infinities).
fn check_finite(report: &CalibrationReport) -> Result<()> {
    let bad = |what: String| {
        Error::Input(format!(
            "the report's {what} is not a finite number; not recorded"
        ))
    };
    for (what, v) in [
        (
            "RMS position error before",
            Some(report.rms_position_before),
        ),
        ("RMS position error after", Some(report.rms_position_after)),
        ("RMS attitude error before", report.rms_orientation_before),
        ("RMS attitude error after", report.rms_orientation_after),
    ] {
        if v.is_some_and(|v| !v.is_finite()) {
            return Err(bad(what.to_string()));
        }
    }
    for p in &report.parameters {
        if !p.estimated.is_finite() {
            return Err(bad(format!("value of {} ({})", p.id, printable(&p.name))));
        }
        if p.sigma.is_some_and(|s| !s.is_finite()) {
            return Err(bad(format!("sigma of {} ({})", p.id, printable(&p.name))));
        }
    }
    for c in &report.combinations {
        if !(c.value.is_finite() && c.sigma.is_finite())
            || c.terms.iter().any(|t| !t.coefficient.is_finite())
        {
            return Err(bad(format!("combination `{}`", printable(&c.expression))));
        }
    }
    Ok(())
}

/// The words of a refused text of the door's limits.
fn limit_words(e: kinecal::Error) -> String {
    match e {
        kinecal::Error::InvalidOption { setting, message } => {
            format!("the {}: {message}", setting.name())
        }
        e => e.to_string(),
    }
}

/// Why `robot_id` cannot be a robot's serial in a history, if it cannot: empty, with a space
/// (or another white space) at its start or end (`" A4-0042"` would be another robot than
/// `A4-0042`: refused, never trimmed silently), or longer than the history keeps
/// ([`kinecal::spec::limits::serial`], the limit of `history add`). Every write checks it: a
/// calibration, an event, every record and event of an imported dump.
pub(crate) fn serial_problem(robot_id: &str) -> Option<String> {
    if robot_id.trim().is_empty() {
        return Some("the robot id (serial) must not be empty".into());
    }
    if robot_id.trim() != robot_id {
        return Some(format!(
            "the robot id (serial) `{}` has white space at its start or end; expected the serial \
             alone (`{}`): with the spaces it would be another robot",
            printable(robot_id),
            printable(robot_id.trim())
        ));
    }
    kinecal::spec::limits::serial(kinecal::Setting::RobotId, robot_id)
        .err()
        .map(limit_words)
}

/// Refuses a serial (see [`serial_problem`]) or a note longer than the history keeps (every
/// table and page of it draws them): [`kinecal::spec::limits`].
pub(crate) fn bounded_texts(robot_id: &str, note: &str) -> Result<()> {
    if let Some(problem) = serial_problem(robot_id) {
        return Err(Error::Input(problem));
    }
    kinecal::spec::limits::note(note).map_err(|e| Error::Input(limit_words(e)))
}

/// Why a report cannot be recorded because it says the calibration was refused (a unit check
/// fired and the fit ended far above its stated noise: its robot was neither written nor
/// recorded), if it does.
pub(crate) fn refusal(report: &CalibrationReport) -> Option<String> {
    report.refused.as_ref().map(|why| {
        let why = why.trim();
        let why = why.strip_prefix("REFUSED:").unwrap_or(why).trim_start();
        format!(
            "the report says the calibration was REFUSED ({}); a refused calibration is not \
             recorded (calibrate again once the cause is fixed)",
            printable(why.trim_end_matches('.'))
        )
    })
}

/// The record of a calibration report, ready to store (its id 0: the store assigns one).
/// `at_given` is the time the caller gave (part of the key); `at` the time stored.
pub(crate) fn new_record(
    robot_id: &str,
    at_given: Option<i64>,
    at: i64,
    report: &CalibrationReport,
    note: &str,
) -> Result<StoredRecord> {
    bounded_texts(robot_id, note)?;
    if let Some(problem) = refusal(report) {
        return Err(Error::Input(format!("{problem}; not recorded")));
    }
    if report.rank.is_none() {
        return Err(Error::Input(
            "the report has no uncertainty (no rank or sigmas): recalibrate with a kinecal that writes them".into(),
        ));
    }
    check_finite(report)?;
    // The history keeps the figures, not the chart of every observation (up to 2,000 points
    // before and after: the bulk of a report, of no use for drift), nor the measured postures,
    // the covariance and the accuracy map of the prediction (its model-error terms and summary
    // stay; `kinecal predict` reads the report file).
    let mut kept = report.clone();
    kept.observation_errors = None;
    if let Some(p) = &mut kept.prediction {
        p.measured = Vec::new();
        p.covariance = Vec::new();
        p.estimated = Vec::new();
        p.map = None;
    }
    let json = kept.to_json();
    let combinations = report
        .combinations
        .iter()
        .map(|c| {
            let terms: Vec<(String, String, f64)> = c
                .terms
                .iter()
                .map(|t| (t.id.clone(), t.name.clone(), t.coefficient))
                .collect();
            StoredCombination {
                expression: c.expression.clone(),
                terms: serde_json::to_string(&terms).expect("terms serialize"),
                value: c.value,
                sigma: c.sigma,
            }
        })
        .collect();
    Ok(StoredRecord {
        id: 0,
        key: Some(idempotency_key(robot_id, at_given, report)),
        robot_id: robot_id.to_string(),
        at,
        robot_name: report.robot.clone(),
        model_fingerprint: report.robot_file_sha256.clone().unwrap_or_default(),
        data_fingerprint: report.data_file_sha256.clone().unwrap_or_default(),
        method: report.method.as_str().to_string(),
        solution: report.solution.clone(),
        length_unit: report.length_unit.as_str().to_string(),
        angle_unit: report.angle_unit.as_str().to_string(),
        rms_position_before: report.rms_position_before,
        rms_position_after: report.rms_position_after,
        rms_orientation_before: report.rms_orientation_before.unwrap_or(0.0),
        rms_orientation_after: report.rms_orientation_after.unwrap_or(0.0),
        note: note.to_string(),
        report: json,
        parameters: report
            .parameters
            .iter()
            .map(|p| StoredParameter {
                id: p.id.clone(),
                name: p.name.clone(),
                unit: p.unit.clone(),
                value: p.estimated,
                sigma: p.sigma,
                estimated: p.estimated_flag,
                determined: p.determined.unwrap_or(false),
            })
            .collect(),
        combinations,
    })
}

/// Why a record cannot be stored as it is, if it cannot: no parameters, a parameter id or a
/// combination's expression twice (each is one row of its calibration), a length or angle
/// unit that is not a kinecal unit, a parameter whose unit is not the record's unit of its
/// quantity (`mm` in a record in inches: drift would convert it wrongly), a value or sigma that
/// is not a finite number, a sigma that is not positive (drift divides by it), or
/// (`against_report`: a record of a dump, whose rows may have been damaged apart from its
/// report) parameter rows that are not the stored report's parameters, or of other units.
pub(crate) fn check_rows(
    rec: &StoredRecord,
    against_report: bool,
) -> std::result::Result<(), String> {
    let reported = if against_report {
        report_parameters(&rec.report)
    } else {
        None
    };
    let units = parse_units(&rec.length_unit, &rec.angle_unit).ok_or_else(|| {
        let (field, value, expected) = if rec.length_unit.parse::<LengthUnit>().is_err() {
            ("length_unit", &rec.length_unit, "m, mm or in")
        } else {
            ("angle_unit", &rec.angle_unit, "deg or rad")
        };
        format!(
            "its {field} `{}` is not a kinecal unit; expected {expected}",
            printable(value)
        )
    })?;
    for p in &rec.parameters {
        let which = || format!("parameter {} ({})", printable(&p.id), printable(&p.name));
        let Some((quantity, _)) = parse_label(&p.unit) else {
            return Err(format!(
                "{} has the unit `{}`, which is not a kinecal unit; expected a unit of the \
                 record's units ({} and {}: e.g. `{}`, `{}`, `{}/unit`)",
                which(),
                printable(&p.unit),
                units.length,
                units.angle,
                units.length,
                units.angle,
                units.angle
            ));
        };
        let expected = units.label(quantity);
        if p.unit != expected {
            return Err(format!(
                "{} has the unit `{}`; expected `{expected}`, the unit of {} in a record in {} \
                 and {} (its length_unit and angle_unit)",
                which(),
                printable(&p.unit),
                quantity_words(quantity),
                units.length,
                units.angle
            ));
        }
        if !p.value.is_finite() {
            return Err(format!(
                "{} has the value {}; expected a finite number",
                which(),
                p.value
            ));
        }
        if let Some(sigma) = p.sigma.filter(|s| !(s.is_finite() && *s > 0.0)) {
            return Err(format!(
                "{} has the sigma {sigma}; expected a positive, finite standard deviation (or \
                 none, for a parameter the data did not determine)",
                which()
            ));
        }
    }
    for c in &rec.combinations {
        if !c.value.is_finite() {
            return Err(format!(
                "the combination `{}` has the value {}; expected a finite number",
                printable(&c.expression),
                c.value
            ));
        }
        if !(c.sigma.is_finite() && c.sigma > 0.0) {
            return Err(format!(
                "the combination `{}` has the sigma {}; expected a positive, finite standard \
                 deviation",
                printable(&c.expression),
                c.sigma
            ));
        }
    }
    if rec.parameters.is_empty() {
        return Err(format!(
            "it has no parameters; expected one row per parameter of its robot model{} (a \
             calibration without them cannot be compared: drift would find nothing changed)",
            reported
                .as_ref()
                .filter(|r| !r.is_empty())
                .map_or(String::new(), |r| format!(
                    " (its report lists {})",
                    r.len()
                ))
        ));
    }
    let mut seen = std::collections::HashMap::new();
    for (k, p) in rec.parameters.iter().enumerate() {
        if let Some(first) = seen.insert(p.id.as_str(), k) {
            return Err(format!(
                "parameter {} appears twice (as {} and as {}); expected each parameter once",
                printable(&p.id),
                printable(&rec.parameters[first].name),
                printable(&p.name)
            ));
        }
    }
    let mut expressions = std::collections::HashSet::new();
    for c in &rec.combinations {
        if !expressions.insert(c.expression.as_str()) {
            return Err(format!(
                "the combination `{}` appears twice; expected each combination once",
                printable(&c.expression)
            ));
        }
    }
    if let Some(reported) = reported.filter(|r| !r.is_empty()) {
        let rows: std::collections::BTreeSet<&str> =
            rec.parameters.iter().map(|p| p.id.as_str()).collect();
        let listed: std::collections::BTreeSet<&str> =
            reported.iter().map(|l| l.id.as_str()).collect();
        if rows != listed {
            let missing: Vec<&str> = listed.difference(&rows).copied().collect();
            let extra: Vec<&str> = rows.difference(&listed).copied().collect();
            let mut why = Vec::new();
            if !missing.is_empty() {
                why.push(format!("no row for {}", printable(&short_list(&missing))));
            }
            if !extra.is_empty() {
                why.push(format!(
                    "rows for {} that the report does not list",
                    printable(&short_list(&extra))
                ));
            }
            return Err(format!(
                "its {} parameter rows are not the {} parameters of its report ({}); expected \
                 one row per parameter of the report",
                rows.len(),
                listed.len(),
                why.join(", ")
            ));
        }
        for p in &rec.parameters {
            let unit = reported
                .iter()
                .find(|l| l.id == p.id)
                .and_then(|l| l.unit.as_deref());
            if let Some(unit) = unit.filter(|u| *u != p.unit) {
                return Err(format!(
                    "parameter {} ({}) has the unit `{}`; expected `{}`, its unit in the \
                     record's report",
                    printable(&p.id),
                    printable(&p.name),
                    printable(&p.unit),
                    printable(unit)
                ));
            }
        }
    }
    Ok(())
}

/// `a, b, c` (at most 6, then `and N more`).
fn short_list(ids: &[&str]) -> String {
    let mut s = ids.iter().take(6).copied().collect::<Vec<_>>().join(", ");
    if ids.len() > 6 {
        s.push_str(&format!(" and {} more", ids.len() - 6));
    }
    s
}

/// A parameter a stored report lists: its id, and its unit when the report gives one.
#[derive(Deserialize)]
struct Listed {
    id: String,
    #[serde(default)]
    unit: Option<String>,
}

/// The parameters a stored report lists, when it is a report with a parameter list.
fn report_parameters(text: &str) -> Option<Vec<Listed>> {
    #[derive(Deserialize)]
    struct Parameters {
        parameters: Vec<Listed>,
    }
    serde_json::from_str::<Parameters>(text)
        .ok()
        .map(|p| p.parameters)
}

/// The fields of a stored report that [`rms_errors`] reads (the rest is skipped unparsed: a
/// fleet reads thousands of reports).
#[derive(Deserialize)]
struct ReportFigures {
    #[serde(default)]
    rms_position_before: serde_json::Value,
    #[serde(default)]
    rms_position_after: serde_json::Value,
    #[serde(default)]
    rms_orientation_before: serde_json::Value,
    #[serde(default)]
    rms_orientation_after: serde_json::Value,
    #[serde(default)]
    identification: serde_json::Value,
}

/// The figures of a stored report as JSON (only what [`rms_errors`] reads), or why it is not
/// valid JSON.
pub(crate) fn report_figures(text: &str) -> std::result::Result<serde_json::Value, String> {
    match serde_json::from_str::<ReportFigures>(text) {
        Ok(f) => Ok(serde_json::json!({
            "rms_position_before": f.rms_position_before,
            "rms_position_after": f.rms_position_after,
            "rms_orientation_before": f.rms_orientation_before,
            "rms_orientation_after": f.rms_orientation_after,
            "identification": f.identification,
        })),
        // Valid JSON of another shape reads as before (no figures); invalid JSON is named.
        Err(_) => serde_json::from_str::<serde_json::Value>(text)
            .map_err(|e| format!("its stored report is not valid JSON ({e})")),
    }
}

/// The RMS errors a stored report gives, one per kind of observation present. Reports written
/// before distances and contacts existed have no observation counts: their position errors are
/// taken as present.
pub(crate) fn rms_errors(
    report: &serde_json::Value,
    length_unit: &str,
    angle_unit: &str,
) -> Vec<RmsError> {
    let mut out = Vec::new();
    let num = |v: &serde_json::Value| v.as_f64();
    let ident = &report["identification"];
    let positions = ident["before"]["positions"].as_u64();
    if positions != Some(0) {
        if let (Some(b), Some(a)) = (
            num(&report["rms_position_before"]),
            num(&report["rms_position_after"]),
        ) {
            out.push(RmsError {
                metric: "position".into(),
                unit: length_unit.into(),
                before: b,
                after: a,
            });
        }
    }
    if let (Some(b), Some(a)) = (
        num(&report["rms_orientation_before"]),
        num(&report["rms_orientation_after"]),
    ) {
        out.push(RmsError {
            metric: "attitude".into(),
            unit: angle_unit.into(),
            before: b,
            after: a,
        });
    }
    if let (Some(before), Some(after)) = (
        ident["before"]["other"].as_array(),
        ident["after"]["other"].as_array(),
    ) {
        for m in before {
            let Some(metric) = m["metric"].as_str() else {
                continue;
            };
            let a = after.iter().find(|x| x["metric"].as_str() == Some(metric));
            if let (Some(b), Some(a)) = (num(&m["rms"]), a.and_then(|a| num(&a["rms"]))) {
                out.push(RmsError {
                    metric: metric.into(),
                    unit: length_unit.into(),
                    before: b,
                    after: a,
                });
            }
        }
    }
    out
}
