//! Denavit-Hartenberg tables, standard and modified (Craig), converted exactly.
//!
//! A table is CSV with the header `kind,a,alpha,d,theta`, one row per joint, in the given units.
//! Standard: joint i contributes `Rz(theta + q) Tz(d) Tx(a) Rx(alpha)`; modified:
//! `Rx(alpha) Tx(a) Rz(theta + q) Tz(d)`. For a prismatic joint `q` adds to `d` instead of
//! `theta`. Readings are the joint values `q` (slope 1); `theta` (revolute) or `d` (prismatic)
//! becomes the joint offset.

use nalgebra::{Matrix3, Vector3};

use super::{chain_from_frames, ImportedJoint};
use crate::error::{Error, Location, Result};
use crate::kinematics::Frame;
use crate::robot::{JointKind, Robot};
use crate::units::{Quantity, Units};

/// Which DH convention a table uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Convention {
    /// `Rz(theta) Tz(d) Tx(a) Rx(alpha)` per joint.
    Standard,
    /// `Rx(alpha) Tx(a) Rz(theta) Tz(d)` per joint (Craig).
    Modified,
}

/// One row of a DH table (internal units).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DhRow {
    /// Joint kind.
    pub kind: JointKind,
    /// Link length (m).
    pub a: f64,
    /// Link twist (rad).
    pub alpha: f64,
    /// Link offset (m).
    pub d: f64,
    /// Joint angle (rad).
    pub theta: f64,
}

fn rz(t: f64) -> Frame {
    let (s, c) = t.sin_cos();
    Frame {
        rotation: Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0),
        translation: Vector3::zeros(),
    }
}

fn rx(t: f64) -> Frame {
    let (s, c) = t.sin_cos();
    Frame {
        rotation: Matrix3::new(1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c),
        translation: Vector3::zeros(),
    }
}

fn tr(x: f64, z: f64) -> Frame {
    Frame {
        rotation: Matrix3::identity(),
        translation: Vector3::new(x, 0.0, z),
    }
}

/// The robot with the same forward kinematics as the DH `rows`.
///
/// The chain is walked at joint value 0 (`q_model = 0`, so `Rz(0)` for a revolute joint and
/// `Tz(0)` for a prismatic one), recording the global frame in which each joint acts; `theta`
/// (revolute) or `d` (prismatic) becomes that joint's offset, `q_model = offset + V`.
pub fn robot_from_dh(name: &str, units: Units, rows: &[DhRow], convention: Convention) -> Robot {
    let mut current = Frame::identity();
    let mut joints = Vec::with_capacity(rows.len());
    for row in rows {
        let (frame, offset) = match (convention, row.kind) {
            (Convention::Standard, JointKind::Revolute) => (current, row.theta),
            (Convention::Standard, JointKind::Prismatic) => (current.then(&rz(row.theta)), row.d),
            (Convention::Modified, JointKind::Revolute) => (
                current.then(&rx(row.alpha)).then(&tr(row.a, 0.0)),
                row.theta,
            ),
            (Convention::Modified, JointKind::Prismatic) => (
                current
                    .then(&rx(row.alpha))
                    .then(&tr(row.a, 0.0))
                    .then(&rz(row.theta)),
                row.d,
            ),
        };
        joints.push(ImportedJoint {
            kind: row.kind,
            frame,
            offset,
            range: None,
        });
        current = match (convention, row.kind) {
            (Convention::Standard, JointKind::Revolute) => {
                frame.then(&tr(row.a, row.d)).then(&rx(row.alpha))
            }
            (Convention::Standard, JointKind::Prismatic) => {
                frame.then(&tr(row.a, 0.0)).then(&rx(row.alpha))
            }
            (Convention::Modified, JointKind::Revolute) => frame.then(&tr(0.0, row.d)),
            (Convention::Modified, JointKind::Prismatic) => frame,
        };
    }
    chain_from_frames(name, units, &joints, &current)
}

/// Reads a DH table file (`text`, named `file` in errors) in `units` and builds the robot
/// ([`robot_from_dh`]), refusing a table whose robot is not usable (values beyond +-1e9 once
/// converted).
pub fn import_dh(
    text: &str,
    file: &str,
    name: &str,
    units: Units,
    convention: Convention,
) -> Result<Robot> {
    let rows = parse_dh_csv(text, file, units)?;
    let robot = robot_from_dh(name, units, &rows, convention);
    robot.validate().map_err(|m| {
        Error::input(
            Location::file(file),
            format!("the robot these rows describe is not usable: {m}"),
        )
    })?;
    Ok(robot)
}

/// Parses a DH table (`kind,a,alpha,d,theta`) in `units`.
pub fn parse_dh_csv(text: &str, file: &str, units: Units) -> Result<Vec<DhRow>> {
    let mut rdr = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .comment(Some(b'#'))
        .from_reader(text.as_bytes());
    let loc = Location::file(file);
    let header: Vec<String> = rdr
        .headers()
        .map_err(|e| Error::input(loc.at_line(1), format!("invalid CSV: {e}")))?
        .iter()
        .map(|h| h.to_ascii_lowercase())
        .collect();
    if header != ["kind", "a", "alpha", "d", "theta"] {
        return Err(Error::input(
            loc.at_line(1),
            format!(
                "unexpected header `{}`: expected `kind,a,alpha,d,theta`",
                header.join(",")
            ),
        ));
    }
    let mut rows = Vec::new();
    for rec in rdr.records() {
        let rec = rec.map_err(|e| {
            let line = e.position().map_or(0, |p| p.line() as usize);
            Error::input(loc.at_line(line), format!("invalid CSV: {e}"))
        })?;
        let line = rec.position().map_or(0, |p| p.line() as usize);
        let at = |f: &str| loc.at_line(line).with_field(f);
        let kind = match &rec[0] {
            "revolute" | "R" | "r" => JointKind::Revolute,
            "prismatic" | "P" | "p" => JointKind::Prismatic,
            other => {
                return Err(Error::input(
                    at("kind"),
                    format!("unknown joint kind `{other}` (expected revolute or prismatic)"),
                ))
            }
        };
        let mut v = [0.0; 4];
        for (k, name) in ["a", "alpha", "d", "theta"].iter().enumerate() {
            v[k] = rec[k + 1]
                .parse::<f64>()
                .ok()
                .filter(|x| crate::units::plausible(*x))
                .ok_or_else(|| {
                    Error::input(
                        at(name),
                        format!(
                            "expected a finite number within +-1e9, found `{}`",
                            &rec[k + 1]
                        ),
                    )
                })?;
        }
        rows.push(DhRow {
            kind,
            a: units.to_si(Quantity::Length, v[0]),
            alpha: units.to_si(Quantity::Angle, v[1]),
            d: units.to_si(Quantity::Length, v[2]),
            theta: units.to_si(Quantity::Angle, v[3]),
        });
    }
    if rows.is_empty() {
        return Err(Error::input(
            loc,
            "no joints: the table has a header but no rows",
        ));
    }
    Ok(rows)
}
