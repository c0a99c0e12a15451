//! Joint offset and gain tables, for controllers that take a calibration only as per-joint
//! corrections: `joint,offset,slope` in the robot file's units (the joint value at zero reading,
//! and joint units per reading unit), the thesis's two transducer parameters.
//!
//! Everything else a calibration found (link lengths and angles, the tool) cannot go into such
//! a table: [`joint_table`] says how much that is, as the largest deviation at the tool over the
//! joint ranges between the calibrated robot and the nominal one with only the table applied
//! (a changed coupling factor counts as lost too: the table has no column for it).

use std::fmt::Write as _;

use super::readback::{self, ReadBack, Tolerance};
use super::Lost;
use crate::error::{Error, Location, Result};
use crate::model::robot::Robot;

/// A joint-table export: the text, and what the nominal robot with it applied reproduces of the
/// calibrated one.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct JointTableExport {
    /// The table.
    pub text: String,
    /// The table read back (`apply_joint_table`) onto the nominal robot, compared with the
    /// calibrated one at the same readings.
    pub read_back: ReadBack,
    /// What the table cannot carry (link and tool changes, couplings), when anything.
    pub lost: Option<Lost>,
}

impl JointTableExport {
    /// `Ok` when the nominal robot with the table applied reproduces `calibrated` within
    /// `tolerance`.
    pub fn check(&self, calibrated: &Robot, tolerance: &Tolerance) -> Result<()> {
        self.read_back.check(
            tolerance,
            calibrated.units,
            "the joint table (applied to the nominal robot)",
            self.lost.as_slice(),
        )
    }
}

/// The table of `calibrated`'s joint offsets and slopes (file units), read back onto `nominal`
/// and compared with `calibrated`; what the nominal robot with only those applied still misses
/// is [`JointTableExport::lost`].
pub fn joint_table(calibrated: &Robot, nominal: &Robot) -> Result<JointTableExport> {
    if !calibrated.same_structure(nominal) {
        return Err(Error::Problem(
            "the calibrated and the nominal robot differ in structure (joints, kinds, sites)"
                .into(),
        ));
    }
    let u = calibrated.units;
    let mut text = String::from("joint,offset,slope,offset_change,slope_change\n");
    for (j, (c, n)) in calibrated.joints.iter().zip(&nominal.joints).enumerate() {
        let q = c.kind.variable();
        let (off, off0) = (u.from_si(q, c.offset), u.from_si(q, n.offset));
        let (slope, slope0) = (
            u.from_si(c.kind.slope(), c.slope),
            u.from_si(c.kind.slope(), n.slope),
        );
        let _ = writeln!(
            text,
            "{},{off},{slope},{},{}",
            j + 1,
            off - off0,
            slope - slope0
        );
    }
    let applied = apply_joint_table(nominal, &text, "<the joint table written>", u)?;
    let read_back = readback::compare(calibrated, &applied, &|v, out| out.copy_from_slice(v), None);
    let (p, a) = (read_back.position, read_back.attitude);
    let lost = (p > 1e-12 || a > 1e-12).then(|| Lost {
        what: "link and tool changes (a joint table holds only offsets and slopes)".into(),
        position: p,
        attitude: a,
    });
    Ok(JointTableExport {
        text,
        read_back,
        lost,
    })
}

/// `nominal` with the offsets and slopes of a joint table (`joint,offset,slope,...` in `units`)
/// applied, as a controller that takes only those would.
pub(crate) fn apply_joint_table(
    nominal: &Robot,
    text: &str,
    file: &str,
    units: crate::units::Units,
) -> Result<Robot> {
    let mut out = nominal.clone();
    let mut seen = vec![false; out.dof()];
    let at = |line: usize| Location::file(file).at_line(line);
    let mut lines = text.lines().enumerate();
    match lines.next() {
        Some((_, h)) if h.trim().starts_with("joint,offset,slope") => {}
        _ => {
            return Err(Error::input(
                at(1),
                "expected the header `joint,offset,slope,...`",
            ))
        }
    }
    for (i, line) in lines {
        if line.trim().is_empty() {
            continue;
        }
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        let num = |k: usize| -> Result<f64> {
            f.get(k)
                .and_then(|v| v.parse::<f64>().ok())
                .filter(|v| crate::units::plausible(*v))
                .ok_or_else(|| Error::input(at(i + 1), format!("column {}: not a number", k + 1)))
        };
        let j = f
            .first()
            .and_then(|v| v.parse::<usize>().ok())
            .filter(|&j| j >= 1 && j <= out.dof())
            .ok_or_else(|| Error::input(at(i + 1), "not a joint of the robot"))?;
        let joint = &mut out.joints[j - 1];
        joint.offset = units.to_si(joint.kind.variable(), num(1)?);
        joint.slope = units.to_si(joint.kind.slope(), num(2)?);
        seen[j - 1] = true;
    }
    if let Some(j) = seen.iter().position(|s| !s) {
        return Err(Error::input(
            Location::file(file),
            format!("no row for joint {}", j + 1),
        ));
    }
    Ok(out)
}
