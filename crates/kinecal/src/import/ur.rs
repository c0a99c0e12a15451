//! Universal Robots kinematics files (`default_kinematics.yaml` of the UR ROS description, and
//! the per-robot factory calibrations the UR drivers extract): import and export.
//!
//! The file gives, for the six joints `shoulder`, `upper_arm`, `forearm`, `wrist_1`, `wrist_2`,
//! `wrist_3`, the origin of each joint in its parent's frame (`x, y, z` in metres, `roll, pitch,
//! yaw` in radians, URDF style: `Trans(xyz) Rz(yaw) Ry(pitch) Rx(roll)`), every joint turning
//! about its z axis. The chain is the one the UR description's `ur_macro.xacro` builds from it:
//! `base_link` turned by pi about z to the controller's base, the six joints, then the fixed
//! `flange` (`rpy 0 -pi/2 -pi/2`) and `tool0` (`rpy pi/2 0 pi/2`) frames. Import builds that
//! chain and reads it as a URDF ([`super::urdf`]), from `base_link` to `tool0`; readings are the
//! joint values (rad, slope 1).
//!
//! Export writes a calibrated robot back into that form ([`export_ur`]). Joint offsets are
//! folded into the origins (exact). The controller's base stays the template's: the measurement
//! frame a calibration carries in its first link (and any session frames) is left out, and
//! said. The tool correction, which the file has no entry for (the flange and tool0 frames are
//! fixed by the description), is the TCP to enter on the controller. What the form cannot hold
//! is said, never dropped silently: a transducer slope other than 1 (the file has no gains) and
//! a coupling, each with the largest position and attitude deviation it causes over the joint
//! ranges.

use std::fmt::Write as _;

use super::readback::{self, ReadBack, Tolerance};
use super::urdf::{export_origins, import_urdf, UrdfImport};
use super::Lost;
use crate::error::{Error, Location, Result};
use crate::model::kinematics::{Chain, Frame, Target};
use crate::model::robot::Robot;

/// The joints of a UR kinematics file, in chain order: (file name, URDF joint name, link).
pub const JOINTS: [(&str, &str, &str); 6] = [
    ("shoulder", "shoulder_pan_joint", "shoulder_link"),
    ("upper_arm", "shoulder_lift_joint", "upper_arm_link"),
    ("forearm", "elbow_joint", "forearm_link"),
    ("wrist_1", "wrist_1_joint", "wrist_1_link"),
    ("wrist_2", "wrist_2_joint", "wrist_2_link"),
    ("wrist_3", "wrist_3_joint", "wrist_3_link"),
];

const KEYS: [&str; 6] = ["x", "y", "z", "roll", "pitch", "yaw"];

/// The contents of a UR kinematics file.
#[derive(Debug, Clone, PartialEq)]
pub struct UrKinematics {
    /// Per joint (in [`JOINTS`] order): `[x, y, z, roll, pitch, yaw]` (m, rad).
    pub origins: [[f64; 6]; 6],
    /// The calibration's hash (`calib_...`), when the file has one.
    pub hash: Option<String>,
}

/// Reads a UR kinematics file: a `kinematics:` mapping with the six joints, each with the six
/// keys, and an optional `hash`. Comments (`#`) and blank lines are allowed; anything else is
/// refused with its line.
pub fn parse_ur_kinematics(text: &str, file: &str) -> Result<UrKinematics> {
    let at = |line: usize| Location::file(file).at_line(line);
    let mut origins = [[f64::NAN; 6]; 6];
    let mut hash = None;
    let mut seen_root = false;
    let mut joint: Option<usize> = None;
    // The indentation of the joints' names (the first indented line's); keys are deeper.
    let mut joint_indent: Option<usize> = None;
    // After YAML's document end marker `...` ([`document_marker`]).
    let mut ended = false;
    for (i, raw) in text.trim_start_matches('\u{feff}').lines().enumerate() {
        let line = i + 1;
        let no_comment = raw.split('#').next().unwrap_or("");
        if no_comment.trim().is_empty() {
            continue;
        }
        let indent = no_comment.len() - no_comment.trim_start().len();
        let content = no_comment.trim();
        if document_marker(content, indent, seen_root, &mut ended, at(line))? {
            continue;
        }
        let Some((key, value)) = content.split_once(':') else {
            return Err(Error::input(
                at(line),
                format!("expected `key: value`, found `{content}`"),
            ));
        };
        let (key, value) = (key.trim(), value.trim());
        match (indent, seen_root) {
            (0, false) if key == "kinematics" && value.is_empty() => seen_root = true,
            (0, false) if key == "kinematics" && value.starts_with('{') => {
                return Err(Error::input(
                    at(line),
                    "`kinematics:` in flow style (`{...}`): write it in block style, a key \
                     per line as the UR description's files are",
                ))
            }
            (0, _) => {
                return Err(Error::input(
                    at(line),
                    format!("expected `kinematics:` as the only top-level key, found `{key}`"),
                ))
            }
            (_, false) => {
                return Err(Error::input(
                    at(line),
                    "the file must start with `kinematics:`",
                ))
            }
            (n, true) if n <= *joint_indent.get_or_insert(n) => {
                if n < joint_indent.unwrap_or(n) {
                    return Err(Error::input(at(line), "inconsistent indentation"));
                }
                if key == "hash" {
                    hash = Some(value.trim_matches('"').trim_matches('\'').to_string());
                    joint = None;
                    continue;
                }
                let j = joint_of(key, value, at(line))?;
                if origins[j].iter().any(|v| !v.is_nan()) {
                    return Err(Error::input(at(line), format!("joint `{key}` given twice")));
                }
                joint = Some(j);
            }
            (_, true) => {
                let j = joint.ok_or_else(|| {
                    Error::input(at(line), format!("`{key}` outside a joint's mapping"))
                })?;
                let (k, v) = origin_value(key, value, at(line))?;
                if !origins[j][k].is_nan() {
                    return Err(Error::input(
                        at(line).with_field(key.to_string()),
                        format!("`{key}` given twice for `{}`", JOINTS[j].0),
                    ));
                }
                origins[j][k] = v;
            }
        }
    }
    if !seen_root {
        return Err(Error::input(
            Location::file(file),
            "no `kinematics:` mapping",
        ));
    }
    for (j, o) in origins.iter().enumerate() {
        if let Some(k) = o.iter().position(|v| v.is_nan()) {
            return Err(Error::input(
                Location::file(file),
                format!("joint `{}` lacks `{}`", JOINTS[j].0, KEYS[k]),
            ));
        }
    }
    Ok(UrKinematics { origins, hash })
}

/// Whether a line is one of YAML's document markers: `---` before the mapping, `...` after it
/// (setting `ended`: nothing but comments may follow). A second document is refused.
fn document_marker(
    content: &str,
    indent: usize,
    seen_root: bool,
    ended: &mut bool,
    at: Location,
) -> Result<bool> {
    let marker = indent == 0 && (content == "---" || content == "...");
    if *ended || (marker && content == "---" && seen_root) {
        return Err(Error::input(
            at,
            format!("`{content}` after the end of the kinematics document: one document per file"),
        ));
    }
    *ended |= marker && content == "...";
    Ok(marker)
}

/// The joint a joint's line names (`shoulder:`, opening its mapping), in [`JOINTS`] order.
fn joint_of(key: &str, value: &str, at: Location) -> Result<usize> {
    let j = JOINTS
        .iter()
        .position(|(name, _, _)| *name == key)
        .ok_or_else(|| {
            Error::input(
                at.clone(),
                format!(
                    "unknown joint `{key}`: expected shoulder, upper_arm, forearm, wrist_1, \
                     wrist_2, wrist_3 or hash"
                ),
            )
        })?;
    if !value.is_empty() {
        return Err(Error::input(at, format!("`{key}:` must open a mapping")));
    }
    Ok(j)
}

/// An origin's line (`x: 0.1`): the key's index in [`KEYS`] and its value (metres or radians,
/// finite and at most 1,000 in size).
fn origin_value(key: &str, value: &str, at: Location) -> Result<(usize, f64)> {
    let at = at.with_field(key.to_string());
    let k = KEYS.iter().position(|k| *k == key).ok_or_else(|| {
        Error::input(
            at.clone(),
            "unknown key: expected x, y, z, roll, pitch, yaw",
        )
    })?;
    let v: f64 = value
        .parse()
        .map_err(|_| Error::input(at.clone(), format!("expected a number, found `{value}`")))?;
    if !(v.is_finite() && v.abs() <= 1e3) {
        return Err(Error::input(
            at,
            format!("{v:e} is not a plausible origin value (metres or radians)"),
        ));
    }
    Ok((k, v))
}

/// The shortest text that reads back to the same number; small magnitudes with an exponent,
/// written as YAML 1.1 readers (PyYAML) take a float: a decimal point and a signed exponent.
fn num(v: f64) -> String {
    // Below a picometre or picoradian: the rounding of the chain's products, not a value.
    if v.abs() < 1e-12 {
        return "0".into();
    }
    if v.abs() < 1e-4 {
        let s = format!("{v:e}");
        let (m, e) = s.split_once('e').expect("an exponent");
        let m = if m.contains('.') {
            m.to_string()
        } else {
            format!("{m}.0")
        };
        return format!("{m}e{e}");
    }
    format!("{v}")
}

/// The URDF the UR description's macro builds from `k` (kinematic elements only).
pub(crate) fn ur_urdf(k: &UrKinematics) -> String {
    let pi = std::f64::consts::PI;
    let mut u = String::from("<?xml version=\"1.0\"?>\n<robot name=\"ur\">\n");
    let mut links = vec!["base_link", "base_link_inertia"];
    links.extend(JOINTS.iter().map(|j| j.2));
    links.extend(["flange", "tool0"]);
    for l in &links {
        let _ = writeln!(u, "  <link name=\"{l}\"/>");
    }
    let _ = writeln!(
        u,
        "  <joint name=\"base_link-base_link_inertia\" type=\"fixed\"><parent link=\"base_link\"/><child link=\"base_link_inertia\"/><origin xyz=\"0 0 0\" rpy=\"0 0 {}\"/></joint>",
        num(pi)
    );
    let mut parent = "base_link_inertia";
    for (j, (_, name, link)) in JOINTS.iter().enumerate() {
        let o = k.origins[j];
        let _ = writeln!(
            u,
            "  <joint name=\"{name}\" type=\"revolute\"><parent link=\"{parent}\"/><child link=\"{link}\"/><origin xyz=\"{} {} {}\" rpy=\"{} {} {}\"/><axis xyz=\"0 0 1\"/><limit lower=\"{}\" upper=\"{}\" effort=\"1\" velocity=\"1\"/></joint>",
            num(o[0]), num(o[1]), num(o[2]), num(o[3]), num(o[4]), num(o[5]),
            num(-2.0 * pi), num(2.0 * pi)
        );
        parent = link;
    }
    let _ = writeln!(
        u,
        "  <joint name=\"wrist_3-flange\" type=\"fixed\"><parent link=\"wrist_3_link\"/><child link=\"flange\"/><origin xyz=\"0 0 0\" rpy=\"0 {} {}\"/></joint>",
        num(-pi / 2.0),
        num(-pi / 2.0)
    );
    let _ = writeln!(
        u,
        "  <joint name=\"flange-tool0\" type=\"fixed\"><parent link=\"flange\"/><child link=\"tool0\"/><origin xyz=\"0 0 0\" rpy=\"{} 0 {}\"/></joint>",
        num(pi / 2.0),
        num(pi / 2.0)
    );
    u.push_str("</robot>\n");
    u
}

/// Imports a UR kinematics file: the chain from `base_link` to `tool0` (metres, radians,
/// readings the joint values, ranges +-2 pi).
pub fn import_ur(text: &str, file: &str) -> Result<UrdfImport> {
    let k = parse_ur_kinematics(text, file)?;
    let mut imported = import_urdf(&ur_urdf(&k), file, Some("base_link"), Some("tool0"))?;
    imported.robot.name = format!(
        "UR ({})",
        k.hash.as_deref().unwrap_or("kinematics without a hash")
    );
    Ok(imported)
}

/// A UR export: the kinematics file's text, what it reproduces of the robot, and what the user
/// must know.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct UrExport {
    /// The kinematics file.
    pub text: String,
    /// The file read back ([`import_ur`]), with [`UrExport::tcp`] as the controller's TCP,
    /// compared with the robot without its measurement frame ([`UrExport::robot`]).
    pub read_back: ReadBack,
    /// The robot the file and the TCP reproduce: the calibrated one on the template's base
    /// (its first link the template's), without session frames.
    pub robot: Robot,
    /// The measurement frame left out: where the robot's `base_link` is in the robot file's
    /// global frame (the frame the calibration was measured in), when the calibration moved it
    /// from the template's. The controller's base is the robot's own.
    pub base: Option<Frame>,
    /// The names of the session frames left out (instrument placements, not part of the robot).
    pub sessions: Vec<String>,
    /// The TCP to enter on the controller: the calibrated tool frame in `tool0` (the tool
    /// flange frame the controller's TCP is given in), when it is not `tool0` itself.
    pub tcp: Option<Frame>,
    /// What the file cannot hold (slopes other than 1, couplings), each with its deviation.
    pub lost: Vec<Lost>,
}

impl UrExport {
    /// `Ok` when the file (with the TCP) reproduces the robot within `tolerance`.
    pub fn check(&self, tolerance: &Tolerance) -> Result<()> {
        self.read_back.check(
            tolerance,
            self.robot.units,
            "the UR kinematics file with the TCP (its joint values are the readings: it has no \
             gains)",
            &self.lost,
        )
    }
}

impl UrExport {
    /// What was left out, in sentences (the robot file's units): the measurement frame, the
    /// session frames.
    pub fn left_out(&self) -> Vec<String> {
        use crate::import::readback::fmt_deviation;
        use crate::units::Quantity;
        let u = self.robot.units;
        let mut out = Vec::new();
        if let Some(b) = &self.base {
            let p = pose_vector(b);
            let l = |v: f64| fmt_deviation(u.from_si(Quantity::Length, v));
            out.push(format!(
                "left out: the measurement frame, what the robot's first link holds beyond the \
                 template's base (base_link at x {} y {} z {} {}, rotation vector {} {} {} rad, in \
                 the frame the robot was measured in): the controller's base is the robot's own",
                l(p[0]),
                l(p[1]),
                l(p[2]),
                u.length,
                fmt_deviation(p[3]),
                fmt_deviation(p[4]),
                fmt_deviation(p[5]),
            ));
        }
        if !self.sessions.is_empty() {
            out.push(format!(
                "left out: the session frame{} {} (where the instrument stood; not part of the \
                 robot)",
                if self.sessions.len() > 1 { "s" } else { "" },
                self.sessions.join(", ")
            ));
        }
        out
    }

    /// The TCP to enter on the controller, in its units: the Installation screen's millimetres
    /// and rotation vector, and the URScript `set_tcp` pose (metres, radians).
    pub fn tcp_line(&self) -> String {
        match &self.tcp {
            Some(t) => {
                let p = pose_vector(t);
                // Fixed decimals, without a sign on a value that rounds to zero.
                let fixed = |v: f64, d: usize| {
                    let s = format!("{v:.d$}");
                    match s.strip_prefix('-') {
                        Some(u) if u.chars().all(|c| c == '0' || c == '.') => u.to_string(),
                        _ => s,
                    }
                };
                let (mm, rad) = (|v: f64| fixed(v * 1e3, 6), |v: f64| fixed(v, 9));
                format!(
                    "TCP to enter on the controller (Installation > General > TCP, in the tool \
                     flange frame tool0): X {} mm, Y {} mm, Z {} mm, RX {} rad, RY {} rad, RZ {} \
                     rad (rotation vector); in URScript: set_tcp(p[{}, {}, {}, {}, {}, {}])",
                    mm(p[0]),
                    mm(p[1]),
                    mm(p[2]),
                    rad(p[3]),
                    rad(p[4]),
                    rad(p[5]),
                    rad(p[0]),
                    rad(p[1]),
                    rad(p[2]),
                    rad(p[3]),
                    rad(p[4]),
                    rad(p[5])
                )
            }
            None => {
                "TCP to enter on the controller: none (the calibrated tool frame is tool0)".into()
            }
        }
    }
}

/// A frame as a UR controller takes a pose: position (m) and rotation vector (rad).
pub fn pose_vector(f: &Frame) -> [f64; 6] {
    let r = crate::model::kinematics::log_so3(&f.rotation);
    [
        f.translation.x,
        f.translation.y,
        f.translation.z,
        r.x,
        r.y,
        r.z,
    ]
}

/// Writes `robot` (imported from the UR kinematics file `template`, then calibrated) as a UR
/// kinematics file.
///
/// The file holds the arm from the controller's base to `tool0`: the template's base stays, and
/// what the calibration put before it (its first link beyond the template's: the measurement
/// frame, where the instrument saw the robot; and any session frames) is left out and said.
/// Joint offsets are folded into the origins (exact). The tool correction (the calibrated tool
/// frame in `tool0`) is the TCP to enter on the controller. The text is read back, the TCP
/// appended, and compared with the robot on its own base over the joint ranges; slopes other
/// than 1 and couplings, which the file has no place for, are listed with their deviations.
pub fn export_ur(robot: &Robot, template: &str, file: &str) -> Result<UrExport> {
    let k0 = parse_ur_kinematics(template, file)?;
    // The robot file keeps the name the import gave it, `UR (<hash>)`: another file's base
    // (another model, or the nominal instead of the factory calibration) would be written as
    // this robot's without a word.
    let template_is = k0.hash.as_deref().unwrap_or("kinematics without a hash");
    let imported_from = robot
        .name
        .strip_prefix("UR (")
        .and_then(|s| s.strip_suffix(')'));
    if let Some(from) = imported_from.filter(|from| *from != template_is) {
        return Err(Error::Problem(format!(
            "the robot was imported from the UR kinematics file `{from}`, and the template \
             {file} is `{template_is}`: give the file the robot was imported from (the \
             template's base is kept, and another file's would be written as this robot's)"
        )));
    }
    let imported = import_urdf(&ur_urdf(&k0), file, Some("base_link"), Some("tool0"))?;
    if !robot.same_structure(&imported.robot) {
        return Err(Error::Problem(
            "the robot does not have the structure of a UR arm imported from this file (six \
             revolute joints, no sites)"
                .into(),
        ));
    }
    // The robot on the template's base: the first link as imported, no sessions.
    let mut own = robot.clone();
    own.links[0] = imported.robot.links[0];
    own.sessions.clear();
    let placement = Frame::from_link(&robot.links[0])
        .then(&super::inverse(&Frame::from_link(&imported.robot.links[0])));
    let base = (placement.translation.norm() > 1e-12
        || crate::model::kinematics::log_so3(&placement.rotation).norm() > 1e-12)
        .then_some(placement);
    let e = export_origins(&own, &imported.chain)?;
    let mut k = k0.clone();
    for (j, (_, name, _)) in JOINTS.iter().enumerate() {
        let (_, f, _) = e
            .origins
            .iter()
            .find(|(n, _, _)| n == name)
            .ok_or_else(|| Error::Problem(format!("joint `{name}` missing from the chain")))?;
        let [roll, pitch, yaw] = rpy_near_literal(&f.rotation, &k0.origins[j]);
        k.origins[j] = [
            f.translation.x,
            f.translation.y,
            f.translation.z,
            roll,
            pitch,
            yaw,
        ];
    }
    k.hash = Some(format!("calib_kinecal_{}", digest(&k.origins)));
    let mut text = String::from("kinematics:\n");
    for (j, (name, _, _)) in JOINTS.iter().enumerate() {
        let _ = writeln!(text, "  {name}:");
        for (key, v) in KEYS.iter().zip(&k.origins[j]) {
            let _ = writeln!(text, "    {key}: {}", num(*v));
        }
    }
    let _ = writeln!(text, "  hash: {}", k.hash.as_deref().unwrap_or(""));
    // Read back: the file as the importer reads it, the TCP after its tool0.
    let written = import_ur(&text, file)?.robot;
    let zero = vec![0.0; own.dof()];
    let tcp = super::inverse(&Chain::new(&written).frame_at(&zero, Target::EndEffector))
        .then(&Chain::new(&own).frame_at(&zero, Target::EndEffector));
    let tcp = (tcp.translation.norm() > 1e-12
        || crate::model::kinematics::log_so3(&tcp.rotation).norm() > 1e-12)
        .then_some(tcp);
    let scale = readback::unit_scale(&own, crate::units::Units::default());
    let read_back = readback::compare(
        &own,
        &written,
        &|v, out| {
            for ((o, v), s) in out.iter_mut().zip(v).zip(&scale) {
                *o = v * s;
            }
        },
        tcp.as_ref(),
    );
    let lost = readback::gains_lost(
        &own,
        &|j| format!("joint {} ({})", j + 1, JOINTS[j].1),
        &|_| false,
    );
    Ok(UrExport {
        text,
        read_back,
        robot: own,
        base,
        sessions: robot.sessions.iter().map(|s| s.name.clone()).collect(),
        tcp,
        lost,
    })
}

/// The `[roll, pitch, yaw]` of `r`: of its two ZYX solutions, the one nearer the file's own
/// angles `o[3..6]` (so that an unchanged origin is written with the same numbers).
fn rpy_near_literal(r: &nalgebra::Matrix3<f64>, o: &[f64; 6]) -> [f64; 3] {
    use crate::units::wrap_angle;
    use std::f64::consts::PI;
    let e = crate::model::kinematics::euler_zyx(r);
    let alt = nalgebra::Vector3::new(
        wrap_angle(e.x + PI),
        wrap_angle(PI - e.y),
        wrap_angle(e.z + PI),
    );
    let near = [o[5], o[4], o[3]];
    let dist = |a: &nalgebra::Vector3<f64>| {
        (0..3)
            .map(|k| wrap_angle(a[k] - near[k]).abs())
            .sum::<f64>()
    };
    let best = if dist(&alt) < dist(&e) { alt } else { e };
    // Each angle as close to the file's literal value as a whole turn allows (pi and -pi).
    let lit = |v: f64, n: f64| n + wrap_angle(v - n);
    [
        lit(best.z, near[2]),
        lit(best.y, near[1]),
        lit(best.x, near[0]),
    ]
}

/// A short hex digest of the origins (the new calibration's hash).
fn digest(origins: &[[f64; 6]; 6]) -> String {
    use sha2::{Digest, Sha256};
    let mut h = Sha256::new();
    for o in origins {
        for v in o {
            h.update(v.to_le_bytes());
        }
    }
    h.finalize()[..8]
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}
