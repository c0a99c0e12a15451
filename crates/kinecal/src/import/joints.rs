//! Joint offset and gain tables, for controllers that take a calibration only as per-joint
//! corrections: `joint,offset,slope` in the robot file's units (the joint value at zero reading,
//! and joint units per reading unit), the thesis's two transducer parameters.
//!
//! Everything else a calibration found (link lengths and angles, the tool) cannot go into such
//! a table: [`joint_table`] says how much that is, as the largest deviation at the tool over the
//! joint ranges between the calibrated robot and the nominal one with only the table applied
//! (a changed coupling factor counts as lost too: the table has no column for it).

use std::fmt::Write as _;

use super::{deviation, Lost};
use crate::error::{Error, Result};
use crate::robot::Robot;

/// The table of `calibrated`'s joint offsets and slopes (file units), and what the nominal
/// robot with only those applied still misses (`None` when nothing).
pub fn joint_table(calibrated: &Robot, nominal: &Robot) -> Result<(String, Option<Lost>)> {
    if !calibrated.same_structure(nominal) {
        return Err(Error::Problem(
            "the calibrated and the nominal robot differ in structure (joints, kinds, sites)"
                .into(),
        ));
    }
    let u = calibrated.units;
    let mut text = String::from("joint,offset,slope,offset_change,slope_change\n");
    let mut applied = nominal.clone();
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
        applied.joints[j].offset = c.offset;
        applied.joints[j].slope = c.slope;
    }
    let (p, a) = deviation(calibrated, &applied);
    let lost = (p > 1e-12 || a > 1e-12).then(|| Lost {
        what: "link and tool changes (a joint table holds only offsets and slopes)".into(),
        position: p,
        attitude: a,
    });
    Ok((text, lost))
}
