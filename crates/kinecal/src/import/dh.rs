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

/// The frame on the line `(p, z)` reached from frame `f` by the common normal of `f`'s z axis
/// and the line: its origin where the normal meets the line, x along the normal (away from
/// `f`'s axis), z along `z`. Parallel lines take the normal through `f`'s origin; intersecting
/// ones `z_f x z` (or its opposite, whichever is nearer `f`'s x); coincident ones keep `f`'s x.
fn along_normal(f: &Frame, p: Vector3<f64>, z: Vector3<f64>) -> Frame {
    let (o, zp) = (f.translation, f.rotation.column(2).into_owned());
    let z = z.normalize();
    let n = zp.cross(&z);
    let eps = 1e-12;
    let (foot, x) = if n.norm() > eps {
        // Closest points of the two lines: o + s zp and p + t z.
        let w = o - p;
        let (b, d, e) = (zp.dot(&z), zp.dot(&w), z.dot(&w));
        let den = 1.0 - b * b;
        let s = (b * e - d) / den;
        let t = (e - b * d) / den;
        let (p1, p2) = (o + zp * s, p + z * t);
        let gap = p2 - p1;
        let x = if gap.norm() > 1e-9 {
            gap.normalize()
        } else {
            let x = n.normalize();
            if x.dot(&f.rotation.column(0)) < 0.0 {
                -x
            } else {
                x
            }
        };
        (p2, x)
    } else {
        // Parallel: the normal through f's origin.
        let foot = p + z * z.dot(&(o - p));
        let gap = foot - o;
        let x = if gap.norm() > 1e-9 {
            gap.normalize()
        } else {
            f.rotation.column(0).into_owned()
        };
        (foot, x)
    };
    let x = (x - z * x.dot(&z)).normalize();
    // Either way along the normal is a DH frame (a changes sign): the way nearer f's x, as DH
    // tables are written (theta near 0).
    let x = if x.dot(&f.rotation.column(0)) < -1e-12 {
        -x
    } else {
        x
    };
    Frame {
        rotation: Matrix3::from_columns(&[x, z.cross(&x), z]),
        translation: foot,
    }
}

/// Whether `tool` can be a standard DH frame after `prev`: its x perpendicular to `prev`'s z and
/// crossing it.
fn standard_fits(prev: &Frame, tool: &Frame) -> bool {
    let (zp, x) = (prev.rotation.column(2), tool.rotation.column(0));
    if x.dot(&zp).abs() > 1e-9 {
        return false;
    }
    let w = tool.translation - prev.translation;
    let n = zp.cross(&x);
    // Lines o_p + s z_p and o_t + t x_t cross when w is in their plane.
    n.norm() > 1e-12 && (w.dot(&n) / n.norm()).abs() < 1e-9
}

/// Whether `tool` can be the last modified DH frame, on the axis `(p, z)`: its z along the axis
/// and its origin on it.
fn modified_fits(p: Vector3<f64>, z: Vector3<f64>, tool: &Frame) -> bool {
    let zt = tool.rotation.column(2);
    let w = tool.translation - p;
    (zt.dot(&z) - 1.0).abs() < 1e-9 && (w - z * w.dot(&z)).norm() < 1e-9
}

/// A DH table for `robot` in `convention`, and the largest position and attitude deviation at
/// the end effector, over the joint ranges, between the robot and the table's robot: what the
/// DH form (4 parameters per joint, no base or tool frame, no gains) cannot represent.
///
/// The table's joint variables are the readings (slope 1); each joint's `theta` (revolute) or
/// `d` (prismatic) holds its value at zero reading. The frames are the classical ones, built
/// from the joint axes at zero readings: standard DH puts frame `k` on the axis of joint `k + 1`
/// at the common normal from axis `k`, the last frame on the tool's z axis; modified DH puts
/// frame `k` on the axis of joint `k`, its x along the common normal to the next axis (the
/// tool's z axis after the last). The base frame is the robot's global frame: a robot whose
/// first axis is not where the DH form expects it (standard: the global z axis; modified:
/// perpendicular to and crossing the global x axis) shows the difference in the deviation.
pub fn export_dh(robot: &Robot, convention: Convention) -> (Vec<DhRow>, (f64, f64)) {
    use crate::kinematics::{Chain, Target, Workspace};
    let n = robot.dof();
    let chain = Chain::new(robot);
    let mut ws = Workspace::new(robot);
    chain.forward(&vec![0.0; n], &mut ws);
    // The global frame in which joint k acts is the one after joint k - 1 through link k.
    let lines: Vec<(Vector3<f64>, Vector3<f64>)> = (0..n)
        .map(|k| {
            let f = ws.after_joint(k).then(&Frame::from_link(&robot.links[k]));
            (f.translation, f.rotation.column(2).into_owned())
        })
        .collect();
    let tool = chain.target_frame(&ws, Target::EndEffector);
    let tool_line = (tool.translation, tool.rotation.column(2).into_owned());
    let mut rows = Vec::with_capacity(n);
    match convention {
        Convention::Standard => {
            // Frame 0: the global frame (joint 1 turns about its z).
            let mut prev = Frame::identity();
            for k in 0..n {
                let (p, z) = if k + 1 < n { lines[k + 1] } else { tool_line };
                // Frame k-1's z is taken as axis k (for k = 0 the global z: if the first axis
                // is elsewhere, the deviation shows it). The last frame is the tool itself when
                // its x crosses the last axis at a right angle (a DH robot's tool does).
                let next = if k + 1 == n && standard_fits(&prev, &tool) {
                    tool
                } else {
                    along_normal(&prev, p, z)
                };
                let rel = super::inverse(&prev).then(&next);
                let theta = rel.rotation[(1, 0)].atan2(rel.rotation[(0, 0)]);
                let (c, s) = (theta.cos(), theta.sin());
                let a = rel.translation.x * c + rel.translation.y * s;
                let d = rel.translation.z;
                // R = Rz(theta) Rx(alpha): alpha from Rz(-theta) R.
                let m = Matrix3::new(c, s, 0.0, -s, c, 0.0, 0.0, 0.0, 1.0) * rel.rotation;
                let alpha = m[(2, 1)].atan2(m[(1, 1)]);
                rows.push(DhRow {
                    kind: robot.joints[k].kind,
                    a,
                    alpha,
                    d,
                    theta,
                });
                prev = next;
            }
        }
        Convention::Modified => {
            let mut prev = Frame::identity();
            for k in 0..n {
                let (p, z) = lines[k];
                // Frame k on axis k, x along the common normal to the next line.
                let fallback = along_normal(&prev, p, z).rotation.column(0).into_owned();
                let (np, nz) = if k + 1 < n { lines[k + 1] } else { tool_line };
                // x_k: the common normal from axis k to the next line, origin on axis k.
                let toward = along_normal(
                    &Frame {
                        rotation: Matrix3::from_columns(&[
                            nz.cross(&z).try_normalize(1e-12).unwrap_or(fallback),
                            Vector3::zeros(),
                            nz,
                        ]),
                        translation: np,
                    },
                    p,
                    z,
                );
                // `toward` has its origin on axis k and x from the next line to axis k: turn
                // it around so x points to the next line.
                let mut xk = -toward.rotation.column(0).into_owned();
                // x may point either way along the normal (a then changes sign): the way nearer
                // the previous x, as DH tables are written (theta near 0).
                if xk.dot(&prev.rotation.column(0)) < -1e-12 {
                    xk = -xk;
                }
                let frame = if k + 1 == n && modified_fits(p, z, &tool) {
                    // The last frame is the tool when the tool sits on the last axis.
                    tool
                } else {
                    Frame {
                        rotation: Matrix3::from_columns(&[xk, z.cross(&xk), z]),
                        translation: toward.translation,
                    }
                };
                let rel = super::inverse(&prev).then(&frame);
                let zl = rel.rotation.column(2);
                let alpha = (-zl.y).atan2(zl.z);
                let (ca, sa) = (alpha.cos(), alpha.sin());
                let t = rel.translation;
                let a = t.x;
                let d = -t.y * sa + t.z * ca;
                // R = Rx(alpha) Rz(theta): theta from Rx(-alpha) R.
                let m = Matrix3::new(1.0, 0.0, 0.0, 0.0, ca, sa, 0.0, -sa, ca) * rel.rotation;
                let theta = m[(1, 0)].atan2(m[(0, 0)]);
                rows.push(DhRow {
                    kind: robot.joints[k].kind,
                    a,
                    alpha,
                    d,
                    theta,
                });
                prev = frame;
            }
        }
    }
    let mut table = robot_from_dh(&robot.name, robot.units, &rows, convention);
    for (t, j) in table.joints.iter_mut().zip(&robot.joints) {
        t.range = j.range;
    }
    let lost = super::deviation(robot, &table);
    (rows, lost)
}

/// A DH table as CSV (`kind,a,alpha,d,theta`) in `units`, read back by [`parse_dh_csv`]. Values
/// are written to 15 significant digits (the frames are built from products of the chain, whose
/// last digit is rounding), and below 1e-12 as 0.
pub fn write_dh_csv(rows: &[DhRow], units: Units) -> String {
    let f = |v: f64| -> String {
        if v.abs() < 1e-12 {
            return "0".into();
        }
        let r: f64 = format!("{v:.14e}").parse().unwrap_or(v);
        format!("{r}")
    };
    let mut out = String::from("kind,a,alpha,d,theta\n");
    for r in rows {
        out.push_str(&format!(
            "{},{},{},{},{}\n",
            r.kind.as_str(),
            f(units.from_si(Quantity::Length, r.a)),
            f(units.from_si(Quantity::Angle, r.alpha)),
            f(units.from_si(Quantity::Length, r.d)),
            f(units.from_si(Quantity::Angle, r.theta))
        ));
    }
    out
}
