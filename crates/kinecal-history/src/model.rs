//! The data model: what a history holds, the same on every back end.
//!
//! A calibration is written as a [`StoredRecord`] (every field as the store keeps it, the
//! report's JSON text included) and read back as a [`Calibration`] (typed, with the RMS errors
//! of its report); a history read as a whole is [`Records`] (the readable calibrations, and the
//! [`DamagedRecord`]s that are named, not served). Maintenance [`Event`]s cut a robot's history
//! into segments. A [`Dump`] carries every stored field of a history from one back end to
//! another. Nothing here knows how or where a store keeps these: the stores depend on this
//! module, never the other way round.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::timefmt::format_time;

// What is read: a calibration, with its parameters, combinations and errors.

/// One parameter of a recorded calibration (robot file's units).
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct Parameter {
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

/// A determined combination of a recorded calibration.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct Combination {
    /// `p3 - p9 - p15 - ...`.
    pub expression: String,
    /// Members as (id, name, coefficient).
    pub terms: Vec<(String, String, f64)>,
    /// Value.
    pub value: f64,
    /// Standard deviation.
    pub sigma: f64,
}

/// A recorded calibration.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct Calibration {
    /// Database id.
    pub id: i64,
    /// The robot's serial number.
    pub robot_id: String,
    /// When (Unix seconds).
    pub at: i64,
    /// When (RFC 3339).
    pub at_text: String,
    /// The robot model's name.
    pub robot_name: String,
    /// SHA-256 of the nominal robot file.
    pub model_fingerprint: String,
    /// SHA-256 of the measurement file.
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
    /// RMS attitude error before (0 without full-pose observations).
    pub rms_orientation_before: f64,
    /// RMS attitude error after.
    pub rms_orientation_after: f64,
    /// Free-form note.
    pub note: String,
    /// The RMS error of each kind of observation the calibration used (positions, attitudes,
    /// distances, contacts), before and after, from its stored report.
    pub errors: Vec<RmsError>,
    /// Every parameter.
    pub parameters: Vec<Parameter>,
    /// Every determined combination.
    pub combinations: Vec<Combination>,
}

/// The RMS error of one kind of observation before and after a calibration.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct RmsError {
    /// `position`, `attitude`, `distance`, `contact`, ...
    pub metric: String,
    /// Its unit (the record's length or angle unit).
    pub unit: String,
    /// Before (the initial robot).
    pub before: f64,
    /// After (the calibrated robot).
    pub after: f64,
}

// What a read of a history gives: the readable records, and the damaged ones by id.

/// The records of a history: those that could be read, and those that could not.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
#[non_exhaustive]
pub struct Records {
    /// The readable calibrations, by robot, then oldest first.
    pub calibrations: Vec<Calibration>,
    /// The records with a damaged field, by id.
    pub damaged: Vec<DamagedRecord>,
}

/// A record that could not be read, and why.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
#[non_exhaustive]
pub struct DamagedRecord {
    /// The record's id.
    pub id: i64,
    /// Which field is damaged, and how (e.g. "its note is not valid UTF-8 text").
    pub problem: String,
}

impl std::fmt::Display for DamagedRecord {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "calibration {} cannot be read ({}); left out",
            self.id, self.problem
        )
    }
}

// Maintenance events.

/// A maintenance event of a robot (a gearbox replaced, a crash, a motor changed): drift is
/// computed within the segments between a robot's events.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[non_exhaustive]
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

// What is written: the options of a write, and what it did.

/// Options of [`Database::add_with`](crate::Database::add_with).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct AddOptions {
    /// Record the calibration even when its robot model (joints, joint kinds, parameter names)
    /// differs from every earlier record of the robot.
    pub force: bool,
}

/// What a write did: the record's id, and whether it was new (not an earlier write of the same
/// record, found by its key).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub struct Added {
    /// The id of the record (the existing one when it was already there).
    pub id: i64,
    /// `false` when the record was already there (a retry).
    pub new: bool,
}

// What a store keeps: every field of a calibration, row by row.

/// Every stored field of one calibration, as a back end keeps it: what [`Dump`] carries
/// between back ends, field for field.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[non_exhaustive]
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

/// One parameter row of a stored calibration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[non_exhaustive]
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
#[non_exhaustive]
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

// What moves a history between back ends.

/// The format name of a dump.
pub const DUMP_FORMAT: &str = "kinecal-history-dump";

/// A whole history, every stored field of every record and event: `kinecal history export
/// --format dump` writes it, `kinecal history import` reads it into any back end.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[non_exhaustive]
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
#[non_exhaustive]
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
