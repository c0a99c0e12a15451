//! Every export is read back before it is written: the exported text is parsed by the matching
//! importer, and the forward kinematics of what it holds is compared with the robot's over a
//! deterministic sample of postures within the joint ranges ([`POSTURES`] of them, plus the zero
//! posture). The largest position and attitude deviation at the tool is the export's
//! [`ReadBack`]; beyond the [`Tolerance`] (by default a millionth of the robot's reach and a
//! nanoradian) the export is refused ([`ReadBack::check`]), naming what the form cannot hold.
//!
//! The export's joint values are the robot's readings, converted from the robot file's units to
//! the export's (a DH table in radians of a robot in degrees takes the readings times pi/180): a
//! transducer slope other than 1 in the robot file's units, or a coupling, is not a unit and is
//! not converted away.
//!
//! No export form holds a mass model: an elastic robot's export is its rigid geometry, read back
//! against that, and the gravity deflection it leaves out is said as lost (`gains_lost`).

use nalgebra::Vector3;

use super::Lost;
use crate::error::{Error, Result};
use crate::model::kinematics::{log_so3, Chain, Frame, Target, Workspace};
use crate::model::robot::{JointKind, Robot};
use crate::units::{Quantity, Units};

/// Postures drawn within the joint ranges (the zero posture comes on top).
pub const POSTURES: usize = 200;

/// The default position tolerance, as a fraction of the robot's reach ([`Robot::reach`]).
pub const RELATIVE_POSITION: f64 = 1e-6;

/// The default attitude tolerance (rad).
pub const ATTITUDE: f64 = 1e-9;

/// How far an export may miss the robot.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tolerance {
    /// Position at the tool (m).
    pub position: f64,
    /// Attitude at the tool (rad).
    pub attitude: f64,
}

impl Tolerance {
    /// The default for `robot`: [`RELATIVE_POSITION`] of its reach and [`ATTITUDE`].
    pub fn default_for(robot: &Robot) -> Tolerance {
        Tolerance {
            position: RELATIVE_POSITION * robot.reach(),
            attitude: ATTITUDE,
        }
    }
}

/// What an export reproduces of the robot, read back.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct ReadBack {
    /// Largest position deviation at the tool (m).
    pub position: f64,
    /// Largest attitude deviation at the tool (rad).
    pub attitude: f64,
    /// The postures compared.
    pub postures: usize,
}

/// A small or large number as the read-back line writes it: `0`, `3.2e-10`, `0.3501`, `2.5e4`.
pub(crate) fn fmt_deviation(v: f64) -> String {
    if v == 0.0 {
        "0".into()
    } else if (1e-3..1e4).contains(&v.abs()) {
        let s = format!(
            "{:.*}",
            (3 - v.abs().log10().floor() as i32).max(0) as usize,
            v
        );
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
    } else {
        format!("{v:.1e}")
    }
}

impl ReadBack {
    /// Whether it is within `tolerance`.
    pub fn within(&self, tolerance: &Tolerance) -> bool {
        self.position <= tolerance.position && self.attitude <= tolerance.attitude
    }

    /// The line the command line prints: `read back: largest deviation 3.2e-10 mm, 1.1e-12 deg
    /// over 201 postures` (the robot file's units).
    pub fn line(&self, units: Units) -> String {
        format!(
            "read back: largest deviation {} {}, {} {} over {} postures",
            fmt_deviation(units.from_si(Quantity::Length, self.position)),
            units.length,
            fmt_deviation(units.from_si(Quantity::Angle, self.attitude)),
            units.angle,
            self.postures
        )
    }

    /// `Ok` within `tolerance`; otherwise [`Error::ExportMisses`], saying what was exported
    /// (`what`: "the DH table"), by how much it misses, and what the form cannot hold (`lost`,
    /// each with the deviation it alone causes), in `units` (the robot file's).
    pub fn check(
        &self,
        tolerance: &Tolerance,
        units: Units,
        what: &str,
        lost: &[Lost],
    ) -> Result<()> {
        if self.within(tolerance) {
            return Ok(());
        }
        let l = |v: f64| {
            format!(
                "{} {}",
                fmt_deviation(units.from_si(Quantity::Length, v)),
                units.length
            )
        };
        let a = |v: f64| {
            format!(
                "{} {}",
                fmt_deviation(units.from_si(Quantity::Angle, v)),
                units.angle
            )
        };
        let reasons: Vec<String> = lost
            .iter()
            .map(|x| format!("{} (up to {} and {})", x.what, l(x.position), a(x.attitude)))
            .collect();
        let message = format!(
            "{what}, read back, misses the robot by up to {} and {} at the tool over {} postures \
             within the joint ranges, more than the tolerance of {} and {}: {}; nothing written",
            l(self.position),
            a(self.attitude),
            self.postures,
            l(tolerance.position),
            a(tolerance.attitude),
            if reasons.is_empty() {
                "its form cannot reproduce the robot to this precision".to_string()
            } else {
                format!("it cannot hold {}", reasons.join("; "))
            }
        );
        Err(Error::ExportMisses {
            position: self.position,
            attitude: self.attitude,
            tolerance: (tolerance.position, tolerance.attitude),
            reasons,
            message,
        })
    }
}

/// The readings at which exports are compared: the zero posture, then [`POSTURES`] drawn
/// uniformly within each joint's reading range (where it has none, the readings that turn a
/// revolute joint a whole turn, or move a prismatic one +-0.1 m, about its offset), the same on
/// every machine.
pub fn postures(robot: &Robot) -> Vec<Vec<f64>> {
    use rand::{RngExt, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(24);
    let ranges: Vec<(f64, f64)> = robot
        .joints
        .iter()
        .map(|j| {
            let span = match j.kind {
                JointKind::Revolute => std::f64::consts::PI,
                JointKind::Prismatic => 0.1,
            } / j.slope.abs().max(1e-12);
            j.range.unwrap_or((-span, span))
        })
        .collect();
    let mut out = vec![vec![0.0; ranges.len()]];
    for _ in 0..POSTURES {
        out.push(
            ranges
                .iter()
                .map(|&(lo, hi)| rng.random_range(lo..=hi))
                .collect(),
        );
    }
    out
}

/// The scale of each joint's readings from `robot`'s file units to `to` (the export's): the
/// joint value an export takes for a reading of 1.
pub(crate) fn unit_scale(robot: &Robot, to: Units) -> Vec<f64> {
    robot
        .joints
        .iter()
        .map(|j| robot.units.factor(j.kind.variable()) / to.factor(j.kind.variable()))
        .collect()
}

/// Whether `robot`'s joint `j` has the gain an export takes for granted: slope 1 in the robot
/// file's units.
pub(crate) fn unit_gain(robot: &Robot, j: usize) -> bool {
    let joint = &robot.joints[j];
    let unit = robot.units.factor(joint.kind.slope());
    (joint.slope - unit).abs() <= 1e-12 * unit
}

/// Compares `robot` with `back` (what an export holds, read back) at [`postures`]: `back` takes
/// the readings mapped by `map` (robot readings to the export's joint values), and `tool` (when
/// given: a frame the controller adds after the export's tool, such as a TCP) after its end
/// effector.
pub fn compare(
    robot: &Robot,
    back: &Robot,
    map: &dyn Fn(&[f64], &mut [f64]),
    tool: Option<&Frame>,
) -> ReadBack {
    if robot.elastic.is_some() {
        return deviation(&robot.rigid(), back, map, tool);
    }
    deviation(robot, back, map, tool)
}

fn deviation(
    robot: &Robot,
    back: &Robot,
    map: &dyn Fn(&[f64], &mut [f64]),
    tool: Option<&Frame>,
) -> ReadBack {
    let (ca, cb) = (Chain::new(robot), Chain::new(back));
    let (mut wa, mut wb) = (Workspace::new(robot), Workspace::new(back));
    let (mut p, mut r): (f64, f64) = (0.0, 0.0);
    let all = postures(robot);
    let mut mapped = vec![0.0; back.dof()];
    for q in &all {
        map(q, &mut mapped);
        ca.forward(q, &mut wa);
        cb.forward(&mapped, &mut wb);
        let fa = ca.target_frame(&wa, Target::EndEffector);
        let mut fb = cb.target_frame(&wb, Target::EndEffector);
        if let Some(t) = tool {
            fb = fb.then(t);
        }
        let d: Vector3<f64> = fa.translation - fb.translation;
        let dp = d.norm();
        let dr = log_so3(&(fa.rotation * fb.rotation.transpose())).norm();
        // A NaN anywhere is the worst deviation, not one that compares as small.
        p = if dp.is_nan() {
            f64::INFINITY
        } else {
            p.max(dp)
        };
        r = if dr.is_nan() {
            f64::INFINITY
        } else {
            r.max(dr)
        };
    }
    ReadBack {
        position: p,
        attitude: r,
        postures: all.len(),
    }
}

/// What an export that takes the readings as its joint values (slope 1 in the robot file's
/// units, no coupling) cannot hold of `robot`: each joint with another slope or a coupling
/// (`joint 2 slope 1.001 deg/unit`, the joint named by `names`), with the deviation at the tool
/// that joint alone causes over the same postures ([`postures`]). `skip_coupling(j)` says a
/// joint's coupling is written (a URDF's sum convention).
pub(crate) fn gains_lost(
    robot: &Robot,
    names: &dyn Fn(usize) -> String,
    skip_coupling: &dyn Fn(usize) -> bool,
) -> Vec<Lost> {
    let mut lost = Vec::new();
    if robot.elastic.is_some() {
        let rigid = robot.rigid();
        let d = deviation(robot, &rigid, &|v, out| out.copy_from_slice(v), None);
        lost.push(Lost {
            what: "the mass model and joint compliances (the gravity deflection; `kinecal fk` \
                   and `kinecal compensate` apply it)"
                .into(),
            position: d.position,
            attitude: d.attitude,
        });
    }
    for (j, joint) in robot.joints.iter().enumerate() {
        let coupled = joint.coupling.is_some() && !skip_coupling(j);
        if unit_gain(robot, j) && !coupled {
            continue;
        }
        let mut without = robot.rigid();
        let unit = robot.units.factor(joint.kind.slope());
        without.joints[j].slope = unit;
        if let Some(c) = without.joints[j].coupling.as_mut() {
            if coupled {
                without.joints[j].coupling = None;
            } else {
                c.factor = unit;
            }
        }
        let alone = compare(robot, &without, &|v, out| out.copy_from_slice(v), None);
        let (p, a) = (alone.position, alone.attitude);
        lost.push(Lost {
            what: format!(
                "{} slope {} {}{}",
                names(j),
                {
                    let v = robot.units.from_si(joint.kind.slope(), joint.slope);
                    crate::units::tidy(v, crate::units::number::Scale::of([v]))
                },
                robot.units.label(joint.kind.slope()),
                if coupled { " and its coupling" } else { "" },
            ),
            position: p,
            attitude: a,
        });
    }
    lost
}
