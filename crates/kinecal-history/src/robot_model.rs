//! A history is one robot model: the check every store runs, inside its write transaction,
//! before a calibration is recorded.
//!
//! A history cannot see the robot file, only the parameters of its records: their names and
//! what their units measure. A new record must have the model of one of the robot's earlier
//! records (its units may differ); otherwise the difference is said in words (joints, joint
//! kinds, parameters added, missing or of another quantity) and nothing is written, unless the
//! write is forced.

use std::collections::{BTreeMap, BTreeSet};

use serde::Serialize;

use crate::error::{Error, Result};
use crate::model::{Calibration, StoredParameter};
use crate::text::{names, printable};
use crate::units::{parse_label, quantity_words};

/// A robot model as far as a history can tell it from the parameters: name -> quantity.
#[derive(Debug, Default, PartialEq)]
pub(crate) struct RobotModel(BTreeMap<String, ParameterKind>);

/// What a parameter measures, from its unit label (a label that is no kinecal unit is kept as
/// it is).
#[derive(Debug, Clone, PartialEq)]
enum ParameterKind {
    Known(kinecal::units::Quantity),
    Unknown(String),
}

impl ParameterKind {
    fn of(unit: &str) -> ParameterKind {
        match parse_label(unit) {
            Some((q, _)) => ParameterKind::Known(q),
            None => ParameterKind::Unknown(unit.to_string()),
        }
    }

    fn words(&self) -> String {
        match self {
            ParameterKind::Known(q) => quantity_words(*q).to_string(),
            ParameterKind::Unknown(u) => format!("in `{}`", printable(u)),
        }
    }
}

/// `jointN.xxx` -> N.
fn joint_of(name: &str) -> Option<usize> {
    name.strip_prefix("joint")?.split_once('.')?.0.parse().ok()
}

impl RobotModel {
    /// The model of a record's parameter rows.
    pub(crate) fn of_parameters(parameters: &[StoredParameter]) -> RobotModel {
        let mut model = RobotModel::default();
        for p in parameters {
            model.add_parameter(p.name.clone(), &p.unit);
        }
        model
    }

    /// The model of a calibration read back.
    pub(crate) fn of_calibration(c: &Calibration) -> RobotModel {
        let mut model = RobotModel::default();
        for p in &c.parameters {
            model.add_parameter(p.name.clone(), &p.unit);
        }
        model
    }

    /// Adds parameter `name` of unit label `unit` (a store reading a robot's earlier records
    /// builds their models row by row).
    pub(crate) fn add_parameter(&mut self, name: String, unit: &str) {
        self.0.insert(name, ParameterKind::of(unit));
    }

    /// Refuses this model unless it is the model of one of `robot_id`'s `earlier` records (by
    /// id), or there are none.
    pub(crate) fn check_against(
        &self,
        robot_id: &str,
        earlier: &BTreeMap<i64, RobotModel>,
    ) -> Result<()> {
        if earlier.is_empty() || earlier.values().any(|m| m == self) {
            return Ok(());
        }
        let (&earlier_id, latest) = earlier.iter().next_back().expect("not empty");
        Err(Error::ModelMismatch {
            robot_id: printable(robot_id).into_owned(),
            earlier_id,
            difference: self.difference(latest),
        })
    }

    fn joints(&self) -> BTreeSet<usize> {
        self.0.keys().filter_map(|n| joint_of(n)).collect()
    }

    fn joint_kind(&self, j: usize) -> Option<&'static str> {
        use kinecal::units::Quantity;
        match self.0.get(&format!("joint{j}.offset"))? {
            ParameterKind::Known(Quantity::Angle) => Some("revolute"),
            ParameterKind::Known(Quantity::Length) => Some("prismatic"),
            _ => None,
        }
    }

    /// What differs from `earlier`, in words.
    fn difference(&self, earlier: &RobotModel) -> String {
        let mut parts = Vec::new();
        let (jn, je) = (self.joints(), earlier.joints());
        if jn.len() != je.len() {
            parts.push(format!("{} joints, earlier {}", jn.len(), je.len()));
        }
        let mut kind_changed = BTreeSet::new();
        for &j in jn.intersection(&je) {
            if let (Some(a), Some(b)) = (self.joint_kind(j), earlier.joint_kind(j)) {
                if a != b {
                    parts.push(format!("joint {j} is {a}, earlier {b}"));
                    kind_changed.insert(j);
                }
            }
        }
        let added: Vec<&String> = self
            .0
            .keys()
            .filter(|n| !earlier.0.contains_key(*n))
            .collect();
        if !added.is_empty() {
            parts.push(format!(
                "parameters not in the earlier model: {}",
                names(added)
            ));
        }
        let missing: Vec<&String> = earlier
            .0
            .keys()
            .filter(|n| !self.0.contains_key(*n))
            .collect();
        if !missing.is_empty() {
            parts.push(format!("parameters missing: {}", names(missing)));
        }
        for (name, kind) in &self.0 {
            if let Some(old) = earlier.0.get(name) {
                let joint_reported = joint_of(name).is_some_and(|j| kind_changed.contains(&j));
                if old != kind && !joint_reported {
                    parts.push(format!(
                        "`{}` is {}, earlier {}",
                        printable(name),
                        kind.words(),
                        old.words()
                    ));
                }
            }
        }
        if parts.is_empty() {
            "the parameters differ".into()
        } else {
            parts.join("; ")
        }
    }
}

/// Where a robot's calibrations change robot model: a calibration recorded with the force
/// option (the robot was rebuilt: other joints, joint kinds or parameters). Drift never
/// compares calibrations of two models: like a maintenance event, the change starts a new
/// segment, and the calibrations before it are not compared.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
#[non_exhaustive]
pub struct ModelChange {
    /// The first calibration of the latest robot model.
    pub first_id: i64,
    /// Its time (RFC 3339).
    pub first_at: String,
    /// The calibration before it, of another model.
    pub earlier_id: i64,
    /// How the latest model differs from that one, in words ("6 joints, earlier 4; ...").
    pub difference: String,
    /// The calibrations before the change (and after the latest maintenance event, when the
    /// segment is cut by one too), by id: not compared.
    pub left_out: Vec<i64>,
}

impl ModelChange {
    /// Why the calibrations before the change are not compared, in words.
    pub fn reason(&self) -> String {
        format!(
            "calibration {} ({}) is of another robot model than calibration {} before it ({}): \
             drift compares only the calibrations since the latest change of robot model",
            self.first_id,
            self.first_at,
            self.earlier_id,
            printable(&self.difference)
        )
    }
}

/// Where the run of calibrations of the latest robot model begins in `history` (one robot's,
/// oldest first), and the change of model before it, if any. A calibration without parameters
/// (a damaged record) has no model to tell: it neither starts nor ends a run.
pub(crate) fn latest_model_start(history: &[Calibration]) -> (usize, Option<ModelChange>) {
    let Some(last) = history.iter().rposition(|c| !c.parameters.is_empty()) else {
        return (0, None);
    };
    let model = RobotModel::of_calibration(&history[last]);
    let mut start = last;
    for k in (0..last).rev() {
        let c = &history[k];
        if c.parameters.is_empty() {
            start = k;
            continue;
        }
        let other = RobotModel::of_calibration(c);
        if other != model {
            let first = &history[start];
            return (
                start,
                Some(ModelChange {
                    first_id: first.id,
                    first_at: first.at_text.clone(),
                    earlier_id: c.id,
                    difference: model.difference(&other),
                    left_out: history[..start].iter().map(|c| c.id).collect(),
                }),
            );
        }
        start = k;
    }
    (0, None)
}
