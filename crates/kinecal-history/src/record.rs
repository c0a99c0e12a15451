//! A record as the stores keep it (the rows of one calibration), the idempotency key, maintenance
//! events, and the dump that moves a history between back ends.

use kinecal::report::CalibrationReport;
use serde::{Deserialize, Serialize};

use crate::store::{rms_errors, Calibration, Combination, Parameter};
use crate::text::printable;
use crate::timefmt::format_time;
use crate::{Error, Result};

/// One parameter row of a stored calibration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StoredParameter {
    /// `p1`, ...
    pub id: String,
    /// `link1.x`, ...
    pub name: String,
    /// Unit.
    pub unit: String,
    /// Value after calibration.
    pub value: f64,
    /// Standard deviation, when determined.
    pub sigma: Option<f64>,
    /// Whether it was estimated.
    pub estimated: bool,
    /// Whether the data determined it individually.
    pub determined: bool,
}

/// One determined-combination row of a stored calibration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StoredCombination {
    /// `p3 - p9 - ...`.
    pub expression: String,
    /// Its members as stored: JSON `[[id, name, coefficient], ...]`.
    pub terms: String,
    /// Value.
    pub value: f64,
    /// Standard deviation.
    pub sigma: f64,
}

/// Every stored field of one calibration, as a back end keeps it: what [`crate::Dump`] carries
/// between back ends, field for field.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StoredRecord {
    /// The record's id.
    pub id: i64,
    /// Its idempotency key (absent on records written before schema version 2).
    pub key: Option<String>,
    /// The robot's serial.
    pub robot_id: String,
    /// Unix seconds.
    pub at: i64,
    /// The robot model's name.
    pub robot_name: String,
    /// SHA-256 of the nominal robot file (empty when unknown).
    pub model_fingerprint: String,
    /// SHA-256 of the measurement files (empty when unknown).
    pub data_fingerprint: String,
    /// Method.
    pub method: String,
    /// Solution rule.
    pub solution: String,
    /// Length unit.
    pub length_unit: String,
    /// Angle unit.
    pub angle_unit: String,
    /// RMS position error before.
    pub rms_position_before: f64,
    /// RMS position error after.
    pub rms_position_after: f64,
    /// RMS attitude error before.
    pub rms_orientation_before: f64,
    /// RMS attitude error after.
    pub rms_orientation_after: f64,
    /// Note.
    pub note: String,
    /// The stored report (JSON text, byte for byte).
    pub report: String,
    /// Parameter rows.
    pub parameters: Vec<StoredParameter>,
    /// Combination rows.
    pub combinations: Vec<StoredCombination>,
}

/// A maintenance event of a robot (a gearbox replaced, a crash, a motor changed): drift is
/// computed within the segments between a robot's events.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Event {
    /// The event's id.
    pub id: i64,
    /// The robot's serial.
    pub robot_id: String,
    /// When (Unix seconds).
    pub at: i64,
    /// What was done.
    pub note: String,
}

impl Event {
    /// The time as RFC 3339.
    pub fn at_text(&self) -> String {
        format_time(self.at)
    }
}

/// What a write did: the record's id, and whether it was new (not an earlier write of the same
/// record, found by its key).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Added {
    /// The id of the record (the existing one when it was already there).
    pub id: i64,
    /// `false` when the record was already there (a retry).
    pub new: bool,
}

/// The format name of a dump.
pub const DUMP_FORMAT: &str = "kinecal-history-dump";

/// A whole history, every stored field of every record and event: `kinecal history export
/// --format dump` writes it, `kinecal history import` reads it into any back end.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Dump {
    /// [`DUMP_FORMAT`].
    pub format: String,
    /// The version of this layout (1).
    pub version: u32,
    /// Every calibration, by id.
    pub calibrations: Vec<StoredRecord>,
    /// Every maintenance event, by id.
    pub events: Vec<Event>,
}

impl Dump {
    /// Reads a dump, refusing another document or a newer layout.
    pub fn from_json(text: &str, file: &str) -> Result<Dump> {
        let v: serde_json::Value = serde_json::from_str(text)
            .map_err(|e| Error::Input(format!("{file}: not JSON ({e})")))?;
        if v.get("format").and_then(|f| f.as_str()) != Some(DUMP_FORMAT) {
            return Err(Error::Input(format!(
                "{file}: not a kinecal history dump (no \"format\": \"{DUMP_FORMAT}\"; write one with `kinecal history export --format dump`)"
            )));
        }
        match v.get("version").and_then(|f| f.as_u64()) {
            Some(1) => {}
            other => {
                return Err(Error::Input(format!(
                    "{file}: dump version {} is not one this kinecal reads (1)",
                    other.map_or("(none)".to_string(), |v| v.to_string())
                )))
            }
        }
        serde_json::from_value(v).map_err(|e| Error::Input(format!("{file}: {e}")))
    }

    /// The dump as JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("a dump serializes") + "\n"
    }
}

/// What an import did.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize)]
pub struct ImportSummary {
    /// Records written.
    pub added: usize,
    /// Records already there (same key, or same id and contents): skipped.
    pub present: usize,
    /// Records written under another id than in the dump (theirs was taken), as (dump id, new id).
    pub renumbered: Vec<(i64, i64)>,
    /// Events written.
    pub events_added: usize,
    /// Events already there.
    pub events_present: usize,
}

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

/// The record of a calibration report, ready to store (its id 0: the store assigns one).
/// `at_given` is the time the caller gave (part of the key); `at` the time stored.
pub(crate) fn new_record(
    robot_id: &str,
    at_given: Option<i64>,
    at: i64,
    report: &CalibrationReport,
    note: &str,
) -> Result<StoredRecord> {
    if robot_id.trim().is_empty() {
        return Err(Error::Input(
            "the robot id (serial) must not be empty".into(),
        ));
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
    let json = CalibrationReport {
        observation_errors: None,
        prediction: report
            .prediction
            .clone()
            .map(|p| kinecal::predict::PredictionReport {
                measured: Vec::new(),
                covariance: Vec::new(),
                estimated: Vec::new(),
                map: None,
                ..p
            }),
        ..report.clone()
    }
    .to_json();
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

/// The number of a parameter id (`p14` -> 14), for ordering.
pub(crate) fn param_number(id: &str) -> i64 {
    id.strip_prefix('p')
        .and_then(|n| n.parse().ok())
        .unwrap_or(0)
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

/// A stored record read as a [`Calibration`], or the sentence naming its damaged field.
pub(crate) fn to_calibration(r: StoredRecord) -> std::result::Result<Calibration, String> {
    let report = report_figures(&r.report)?;
    let finite = |v: f64, what: &str| {
        if v.is_finite() {
            Ok(v)
        } else {
            Err(format!("{what} is not a finite number"))
        }
    };
    let mut parameters: Vec<Parameter> = Vec::with_capacity(r.parameters.len());
    for p in r.parameters {
        let f = |what: &str| format!("parameter {}'s {what}", printable(&p.id));
        parameters.push(Parameter {
            value: finite(p.value, &f("value"))?,
            sigma: p.sigma.map(|s| finite(s, &f("sigma"))).transpose()?,
            id: p.id,
            name: p.name,
            unit: p.unit,
            estimated: p.estimated,
            determined: p.determined,
        });
    }
    parameters.sort_by_key(|p| param_number(&p.id));
    let mut combinations = Vec::with_capacity(r.combinations.len());
    for c in r.combinations {
        let f = |what: &str| format!("combination `{}`'s {what}", printable(&c.expression));
        let terms: Vec<(String, String, f64)> = serde_json::from_str(&c.terms)
            .map_err(|e| format!("{} are not valid JSON ({e})", f("terms")))?;
        combinations.push(Combination {
            terms,
            value: finite(c.value, &f("value"))?,
            sigma: finite(c.sigma, &f("sigma"))?,
            expression: c.expression,
        });
    }
    combinations.sort_by(|a, b| a.expression.as_bytes().cmp(b.expression.as_bytes()));
    Ok(Calibration {
        errors: rms_errors(&report, &r.length_unit, &r.angle_unit),
        id: r.id,
        robot_id: r.robot_id,
        at: r.at,
        at_text: format_time(r.at),
        robot_name: r.robot_name,
        model_fingerprint: r.model_fingerprint,
        data_fingerprint: r.data_fingerprint,
        method: r.method,
        solution: r.solution,
        length_unit: r.length_unit,
        angle_unit: r.angle_unit,
        rms_position_before: finite(r.rms_position_before, "its RMS position error before")?,
        rms_position_after: finite(r.rms_position_after, "its RMS position error after")?,
        rms_orientation_before: finite(r.rms_orientation_before, "its RMS attitude error before")?,
        rms_orientation_after: finite(r.rms_orientation_after, "its RMS attitude error after")?,
        note: r.note,
        parameters,
        combinations,
    })
}
