//! ROS 2: a calibrated robot as the files a ROS 2 description package reads at launch.
//!
//! [`export_ros`] writes, for a robot imported from a URDF (a chain or a tree) and calibrated:
//!
//! - `calibration.yaml`: for every joint on the calibrated chains (from the base to each tip, in
//!   the order of the file; and the fixed joint of a calibrated tool link the URDF export adds),
//!   its `<origin>` as calibrated, `x, y, z` in metres and `roll, pitch, yaw` in radians (URDF:
//!   `Trans(xyz) Rz(yaw) Ry(pitch) Rx(roll)`), with the robot's name and a hash of the values
//!   ([`values_hash`]). Every number is written so that a YAML 1.1 reader (PyYAML, which xacro
//!   uses) takes it as the same double: a decimal point, a signed exponent.
//! - `<robot>.urdf.xacro`: the template, each of those origins read from that YAML through
//!   `xacro.load_yaml`, whose path is the xacro argument `calibration` (default
//!   `calibration.yaml`: xacro resolves a relative path beside the xacro file, so the pair works
//!   wherever it is copied, without ROS's `$(find)`). Expanded by the `xacro` tool with no
//!   argument, it is the URDF `export urdf` writes of the robot on its own base. Any `${` or
//!   `$(` of the template is escaped (`$${`), so that xacro keeps it literally.
//! - `static_transforms.yaml` and `static_transforms.launch.py`: the frames kinecal estimated
//!   outside the robot, each as parent frame, child frame, `x, y, z` (m) and the unit
//!   quaternion `qx, qy, qz, qw` (`qw >= 0`) of the child in the parent: the frame the robot
//!   was measured in (`measurement`, the robot file's global frame) in the robot's base link
//!   (the inverse of the placement the calibration put into the robot's first link beyond the
//!   template's), and each session's measurement frame in that frame. Hung below the base, the
//!   instrument's frames never give a link of the URDF a second parent. Then each camera, as
//!   `<camera>_optical_frame` (REP 103's optical frame: z along the optical axis, x right, y
//!   down, which is kinecal's camera frame, so its pose is written as estimated), and each
//!   board, as `<board>`: a fixed one (`mount = "base"`) in the measurement frame (its pose is
//!   in the robot's global frame, like the sessions'), one on the end effector or a site in
//!   the URDF link of that tool frame (the tip link of its chain, or the `<tip>_calibrated`
//!   link the URDF export adds); a site that is not a tip of the template is refused. No
//!   `<camera>_link` body frame: a camera driver publishes its own, and a frame with two
//!   parents breaks TF. The launch file starts one `tf2_ros` `static_transform_publisher` per
//!   entry of the YAML beside it.
//!
//! The URDF holds the robot on its own base: the template's first link, and every link that
//! starts at the global frame (a tree's other roots, a site on the base) moved by the inverse of
//! the placement. What is written is read back before anything is: the YAML files are parsed,
//! the xacro expanded with the parsed values (as xacro does: placeholders replaced, escapes
//! undone), the expansion compared joint by joint, bit for bit, with the URDF export, and each
//! of its chains, behind the placement parsed back from `static_transforms.yaml`, compared with
//! the calibrated robot over the joint ranges ([`super::readback`]).

use std::fmt::Write as _;

use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};
use quick_xml::events::Event;
use quick_xml::Reader;
use sha2::{Digest, Sha256};

use super::readback::{self, ReadBack, Tolerance};
use super::urdf::{export_urdf, import_urdf, import_urdf_tree, UrdfChain, UrdfImport};
use super::{inverse, link_of, Lost};
use crate::error::{Error, Location, Result};
use crate::model::camera::Mount;
use crate::model::kinematics::{log_so3, Frame};
use crate::model::robot::Robot;
use crate::units::Units;
use crate::warning::Warning;

/// The calibration's file name in the output folder.
pub const CALIBRATION_FILE: &str = "calibration.yaml";
/// The static transforms' file name.
pub const TRANSFORMS_FILE: &str = "static_transforms.yaml";
/// The launch file's name.
pub const LAUNCH_FILE: &str = "static_transforms.launch.py";
/// The frame the robot was measured in, unless named otherwise.
pub const DEFAULT_MEASUREMENT_FRAME: &str = "measurement";
/// The xacro argument that names the calibration file.
pub const XACRO_ARG: &str = "calibration";

/// The keys of a joint origin, in the order written.
pub const ORIGIN_KEYS: [&str; 6] = ["x", "y", "z", "roll", "pitch", "yaw"];
/// The keys of a static transform's values, in the order written.
pub const TRANSFORM_KEYS: [&str; 7] = ["x", "y", "z", "qx", "qy", "qz", "qw"];

/// One joint's calibrated origin.
#[derive(Debug, Clone, PartialEq)]
pub struct JointOrigin {
    /// The URDF joint's name.
    pub name: String,
    /// `[x, y, z, roll, pitch, yaw]` (m, rad).
    pub origin: [f64; 6],
}

/// What a static transform places.
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub enum FrameKind {
    /// The frame the robot was measured in, in the robot's base link.
    Measurement,
    /// A session's measurement frame (the instrument where it stood), by its name in the robot
    /// file.
    Session(String),
    /// A camera's optical frame (`<camera>_optical_frame`: z along the optical axis, x right,
    /// y down, REP 103's optical convention and kinecal's camera frame), by its name in the
    /// robot file.
    Camera(String),
    /// A calibration board's frame (`<board>`: its points in the x-y plane, point 0 at the
    /// origin), by its name in the robot file.
    Board(String),
}

/// A frame kinecal estimated outside the robot, as ROS publishes it.
#[derive(Debug, Clone, PartialEq)]
pub struct StaticTransform {
    /// The parent frame.
    pub parent: String,
    /// The child frame.
    pub child: String,
    /// What it is.
    pub kind: FrameKind,
    /// `[x, y, z, qx, qy, qz, qw]`: the child's origin (m) and orientation (unit quaternion,
    /// `qw >= 0`) in the parent.
    pub values: [f64; 7],
}

impl StaticTransform {
    /// The transform as a frame (the child in the parent).
    pub fn frame(&self) -> Frame {
        let [x, y, z, qx, qy, qz, qw] = self.values;
        let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(qw, qx, qy, qz));
        Frame {
            rotation: *q.to_rotation_matrix().matrix(),
            translation: Vector3::new(x, y, z),
        }
    }
}

/// A ROS export: the four files and what they reproduce.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct RosExport {
    /// The URDF's robot name.
    pub robot: String,
    /// The xacro's file name: the robot's name (characters other than letters, digits, `_`,
    /// `-` and `.` as `_`) and `.urdf.xacro`.
    pub xacro_file: String,
    /// `calibration.yaml`.
    pub calibration: String,
    /// The xacro.
    pub xacro: String,
    /// `static_transforms.yaml`.
    pub transforms_yaml: String,
    /// `static_transforms.launch.py`.
    pub launch: String,
    /// The calibrated origins, as written.
    pub joints: Vec<JointOrigin>,
    /// The static transforms, as written.
    pub transforms: Vec<StaticTransform>,
    /// The calibration's hash ([`values_hash`]).
    pub hash: String,
    /// The xacro expanded with the YAML as written, behind the placement as written, compared
    /// with the calibrated robot (every chain of a tree; the largest deviations).
    pub read_back: ReadBack,
    /// What URDF cannot hold (slopes other than 1), each with its deviation.
    pub lost: Vec<Lost>,
    /// What the URDF export says (a calibrated tool link added).
    pub warnings: Vec<Warning>,
    /// What a user must know (session frames renamed).
    pub notes: Vec<String>,
}

impl RosExport {
    /// `Ok` when the files reproduce `robot` within `tolerance`.
    pub fn check(&self, robot: &Robot, tolerance: &Tolerance) -> Result<()> {
        self.read_back.check(
            tolerance,
            robot.units,
            "the xacro with its calibration YAML and the measurement frame's static transform \
             (its joint values are the readings: it cannot scale them)",
            &self.lost,
        )
    }

    /// The files, (name in the output folder, text), in the order written.
    pub fn files(&self) -> [(&str, &str); 4] {
        [
            (CALIBRATION_FILE, &self.calibration),
            (&self.xacro_file, &self.xacro),
            (TRANSFORMS_FILE, &self.transforms_yaml),
            (LAUNCH_FILE, &self.launch),
        ]
    }
}

fn err(file: &str, message: impl Into<String>) -> Error {
    Error::input(Location::file(file), message)
}

/// A number as a YAML 1.1 float that reads back to exactly `v`: the shortest round-trip
/// digits, always with a decimal point, an exponent always signed (`1.0e-7`, `2.5e+16`).
pub fn yaml_number(v: f64) -> String {
    let v = if v == 0.0 { 0.0 } else { v };
    let s = format!("{v:?}");
    match s.split_once('e') {
        Some((m, e)) => {
            let m = if m.contains('.') {
                m.to_string()
            } else {
                format!("{m}.0")
            };
            let e = if e.starts_with('-') {
                e.to_string()
            } else {
                format!("+{e}")
            };
            format!("{m}e{e}")
        }
        None if s.contains('.') || !v.is_finite() => s,
        None => format!("{s}.0"),
    }
}

/// A YAML scalar for `s`: plain when it is a plain identifier YAML 1.1 reads as a string,
/// double-quoted otherwise.
fn yaml_string(s: &str) -> String {
    const WORDS: [&str; 12] = [
        "y", "n", "yes", "no", "true", "false", "on", "off", "null", "nan", "inf", "~",
    ];
    let plain = s
        .chars()
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && s.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
        && !WORDS.contains(&s.to_ascii_lowercase().as_str());
    if plain {
        s.to_string()
    } else {
        format!("\"{}\"", s.replace('\\', "\\\\").replace('"', "\\\""))
    }
}

/// The calibration's hash: SHA-256 over, for each joint in the file's order, its name's UTF-8
/// bytes, a zero byte, and its six values as little-endian IEEE 754 doubles; `calib_kinecal_`
/// and the first 8 bytes in hex (as the UR kinematics files name theirs).
pub fn values_hash(joints: &[JointOrigin]) -> String {
    let mut h = Sha256::new();
    for j in joints {
        h.update(j.name.as_bytes());
        h.update([0u8]);
        for v in &j.origin {
            h.update(v.to_le_bytes());
        }
    }
    let hex: String = h.finalize()[..8]
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    format!("calib_kinecal_{hex}")
}

/// A name xacro and YAML can carry inside `${...['name']}` in an XML attribute: no quote,
/// backslash, `$`, brace, `&`, `<`, `>` or control character.
fn check_name(name: &str, what: &str, file: &str) -> Result<()> {
    if let Some(c) = name.chars().find(|c| {
        matches!(c, '\'' | '"' | '\\' | '$' | '{' | '}' | '&' | '<' | '>') || c.is_control()
    }) {
        return Err(err(
            file,
            format!(
                "{what} `{}` has the character {c:?}, which a xacro expression cannot carry: \
                 rename it in the template",
                name.escape_debug()
            ),
        ));
    }
    Ok(())
}

/// A TF frame name from a free name: letters, digits and `_` kept, anything else `_`.
fn frame_name(name: &str) -> String {
    let s: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect();
    if s.is_empty() {
        "_".into()
    } else {
        s
    }
}

/// The unit quaternion of a rotation, `qw >= 0`, as `[qx, qy, qz, qw]`.
fn quaternion(r: &Matrix3<f64>) -> [f64; 4] {
    let q = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(*r));
    let s = if q.w < 0.0 { -1.0 } else { 1.0 };
    [s * q.i, s * q.j, s * q.k, s * q.w]
}

/// `robot` on its own base: every link and site that starts at the global frame moved by the
/// inverse of `placement`, the first link exactly `first`; no sessions.
fn on_own_base(robot: &Robot, placement: &Frame, first: &crate::model::robot::Link) -> Robot {
    let mut own = robot.clone();
    let back = inverse(placement);
    for i in 0..own.links.len() {
        if robot.link_parent(i) == 0 {
            own.links[i] = link_of(&back.then(&Frame::from_link(&robot.links[i])));
        }
    }
    own.links[0] = *first;
    for s in &mut own.sites {
        if s.joint == 0 {
            s.frame = link_of(&back.then(&Frame::from_link(&s.frame)));
        }
    }
    own.sessions.clear();
    own
}

/// Writes `robot` (imported from the URDF `template` from `base` to `tips`, then calibrated) as
/// the files of a ROS 2 description (see the module documentation); `measurement` names the
/// frame it was measured in (default [`DEFAULT_MEASUREMENT_FRAME`]).
pub fn export_ros(
    robot: &Robot,
    template: &str,
    file: &str,
    base: Option<&str>,
    tips: &[&str],
    measurement: Option<&str>,
) -> Result<RosExport> {
    let mframe = measurement.unwrap_or(DEFAULT_MEASUREMENT_FRAME);
    check_measurement_frame(mframe)?;
    let imported = import_urdf_tree(template, file, base, tips)?;
    check_joint_count(robot, &imported, tips.len())?;
    let urdf_name = imported.robot.name.clone();
    check_name(&urdf_name, "the robot's name", file)?;
    let first = imported.robot.links[0];
    let placement = Frame::from_link(&robot.links[0]).then(&inverse(&Frame::from_link(&first)));
    let own = on_own_base(robot, &placement, &first);
    let e = export_urdf(&own, template, file, base, tips)?;
    let mut notes = Vec::new();

    // The joints on the chains (and the added tool joints), in the order of the file.
    let chains = imported.chains();
    let added: Vec<String> = e
        .warnings
        .iter()
        .filter_map(|w| match w {
            Warning::UrdfToolAdded { link } => Some(link.clone()),
            _ => None,
        })
        .collect();
    let written = parse_urdf(&e.text, file)?;
    let joints = joint_origins(&e.text, &written, &chains, &added, file)?;
    let hash = values_hash(&joints);
    let calibration = calibration_yaml(&urdf_name, &hash, &joints);
    let xacro = xacro_text(&e.text, file, &joints)?;

    // The frames outside the robot.
    let mut transforms = vec![StaticTransform {
        parent: imported.chain.base.clone(),
        child: mframe.to_string(),
        kind: FrameKind::Measurement,
        values: transform_values(&inverse(&placement)),
    }];
    let links: Vec<&str> = written.links.iter().map(|l| l.name.as_str()).collect();
    if links.contains(&mframe) {
        return Err(Error::Problem(format!(
            "the measurement frame `{mframe}` (measurement_frame) is a link of the URDF: name the \
             frame the robot was measured in otherwise"
        )));
    }
    session_transforms(robot, mframe, &links, &mut transforms, &mut notes)?;
    let mounts = Mounts {
        robot,
        imported: &imported,
        chains: &chains,
        added: &added,
        mframe,
        links: &links,
    };
    mounted_transforms(&mounts, &mut transforms, &mut notes)?;
    let transforms_yaml = transforms_yaml(&urdf_name, &transforms);
    let launch = launch_text(&urdf_name);

    // Read back: the files as a reader takes them.
    let cal = parse_calibration(&calibration, CALIBRATION_FILE)?;
    if cal.joints != joints || cal.hash != hash || values_hash(&cal.joints) != hash {
        return Err(Error::Problem(
            "calibration.yaml, read back, does not hold the values written (an export bug)".into(),
        ));
    }
    let tf = transforms_read_back(&transforms_yaml, &transforms, robot, &placement)?;
    let expanded = expand_xacro(&xacro, &cal.joints, file)?;
    same_urdf(&expanded, &e.text, file)?;
    let placed = inverse(&tf.transforms[0].frame());
    let read_back = chains_read_back(robot, &chains, &added, &expanded, &urdf_name, &placed)?;
    Ok(RosExport {
        xacro_file: xacro_file_name(&urdf_name),
        robot: urdf_name,
        calibration,
        xacro,
        transforms_yaml,
        launch,
        joints,
        transforms,
        hash,
        read_back,
        lost: e.lost,
        warnings: e.warnings,
        notes,
    })
}

/// Refuses a measurement frame name that is not a TF frame name.
fn check_measurement_frame(mframe: &str) -> Result<()> {
    if mframe.is_empty()
        || mframe.starts_with('/')
        || !mframe
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '/' | '-' | '.'))
    {
        return Err(Error::Problem(format!(
            "the measurement frame `{}` (measurement_frame) is not a TF frame name: letters, \
             digits, `_`, `/`, `-` and `.` only, not beginning with `/` (ROS 2 refuses those)",
            mframe.escape_debug()
        )));
    }
    Ok(())
}

/// Refuses a template whose chains from the base to the `tips` (`tips` of them) do not have the
/// robot's joints.
fn check_joint_count(robot: &Robot, imported: &UrdfImport, tips: usize) -> Result<()> {
    if imported.robot.dof() != robot.dof() || imported.robot.links.is_empty() {
        return Err(Error::Problem(format!(
            "the robot has {} joints, but the URDF's chain{} from `{}` to {} has {} movable joints",
            robot.dof(),
            if tips > 1 { "s" } else { "" },
            imported.chain.base,
            imported
                .branches
                .iter()
                .chain([&imported.chain])
                .map(|c| format!("`{}`", c.tip))
                .collect::<Vec<_>>()
                .join(", "),
            imported.robot.dof()
        )));
    }
    Ok(())
}

/// The origins of the joints on the `chains` and of the tool joints the URDF export `added`
/// (their links' names), in the order of the exported file `text` (`written` as parsed).
fn joint_origins(
    text: &str,
    written: &urdf_rs::Robot,
    chains: &[(&UrdfChain, Option<usize>)],
    added: &[String],
    file: &str,
) -> Result<Vec<JointOrigin>> {
    let index = super::xml::scan(text, file)?;
    let wanted = |name: &str| {
        chains
            .iter()
            .any(|(c, _)| c.joints.iter().any(|j| j == name))
            || added.iter().any(|l| format!("{l}_joint") == name)
    };
    let mut joints = Vec::new();
    for span in &index.joints {
        if !wanted(&span.name) || joints.iter().any(|j: &JointOrigin| j.name == span.name) {
            continue;
        }
        check_name(&span.name, "joint", file)?;
        let j = written
            .joints
            .iter()
            .find(|j| j.name == span.name)
            .ok_or_else(|| err(file, format!("joint `{}` not read", span.name)))?;
        let [x, y, z] = j.origin.xyz.0;
        let [roll, pitch, yaw] = j.origin.rpy.0;
        let clean = |v: f64| if v == 0.0 { 0.0 } else { v };
        joints.push(JointOrigin {
            name: span.name.clone(),
            origin: [x, y, z, roll, pitch, yaw].map(clean),
        });
    }
    Ok(joints)
}

/// The sessions' frames (the global frame in each session's), published on the measurement
/// frame `mframe`; a name that is not a TF frame name is published cleaned (with a note), and
/// one that clashes with a link, the measurement frame or another frame is refused.
fn session_transforms(
    robot: &Robot,
    mframe: &str,
    links: &[&str],
    transforms: &mut Vec<StaticTransform>,
    notes: &mut Vec<String>,
) -> Result<()> {
    for s in &robot.sessions {
        let child = frame_name(&s.name);
        if child != s.name {
            notes.push(format!(
                "session `{}` is published as the frame `{child}` (TF frame names: letters, \
                 digits, `_`)",
                s.name
            ));
        }
        if child == mframe || links.contains(&child.as_str()) {
            return Err(Error::Problem(format!(
                "session `{}`'s frame `{child}` is also {}: rename the session",
                s.name,
                if child == mframe {
                    "the measurement frame"
                } else {
                    "a link of the URDF"
                }
            )));
        }
        if transforms.iter().any(|t| t.child == child) {
            return Err(Error::Problem(format!(
                "two sessions are published as the frame `{child}`: rename one"
            )));
        }
        transforms.push(StaticTransform {
            parent: mframe.to_string(),
            child,
            kind: FrameKind::Session(s.name.clone()),
            // The session's frame holds the global frame in the measurement frame.
            values: transform_values(&inverse(&Frame::from_link(&s.frame))),
        });
    }
    Ok(())
}

/// What [`mounted_transforms`] hangs cameras and boards from.
struct Mounts<'a> {
    robot: &'a Robot,
    imported: &'a UrdfImport,
    /// The template's chains, each with its site (`None`: the end effector's).
    chains: &'a [(&'a UrdfChain, Option<usize>)],
    /// The links the URDF export added (`<tip>_calibrated`).
    added: &'a [String],
    /// The measurement frame.
    mframe: &'a str,
    /// The exported URDF's links.
    links: &'a [&'a str],
}

/// The cameras' and boards' frames, each pose as estimated, in the frame it was estimated in.
fn mounted_transforms(
    m: &Mounts<'_>,
    transforms: &mut Vec<StaticTransform>,
    notes: &mut Vec<String>,
) -> Result<()> {
    let Mounts {
        robot,
        mframe,
        links,
        ..
    } = *m;
    // Cameras and boards: on the measurement frame when fixed (their poses are in the robot's
    // global frame, as the sessions' are), else on the URDF link of the tool frame they move
    // with (the end effector's or a site's tip link, or its `_calibrated` link when the URDF
    // export added one): each pose as estimated, in the frame it was estimated in.
    let mounted = robot
        .cameras
        .iter()
        .map(|c| (true, &c.name, c.mount, &c.pose))
        .chain(
            robot
                .boards
                .iter()
                .map(|b| (false, &b.name, b.mount, &b.pose)),
        );
    for (camera, name, mount, pose) in mounted {
        let what = if camera { "camera" } else { "board" };
        let base_name = frame_name(name);
        let child = if camera {
            format!("{base_name}_optical_frame")
        } else {
            base_name.clone()
        };
        if &base_name != name {
            notes.push(format!(
                "{what} `{name}` is published as the frame `{child}` (TF frame names: letters, \
                 digits, `_`)"
            ));
        }
        if child == mframe || links.contains(&child.as_str()) {
            return Err(Error::Problem(format!(
                "{what} `{name}`'s frame `{child}` is also {}: rename the {what}",
                if child == mframe {
                    "the measurement frame"
                } else {
                    "a link of the URDF"
                }
            )));
        }
        if transforms.iter().any(|t| t.child == child) {
            return Err(Error::Problem(format!(
                "{what} `{name}`'s frame `{child}` is published twice (a session, camera or \
                 board of that frame name): rename one"
            )));
        }
        let parent = match mount {
            Mount::Base => {
                if !robot.sessions.is_empty() {
                    notes.push(format!(
                        "{what} `{name}` is fixed (mount = \"base\") and the robot has \
                         sessions: it is published in `{mframe}`, the robot's global frame"
                    ));
                }
                mframe.to_string()
            }
            Mount::EndEffector => tool_link(m, None)?,
            Mount::Site(s) => tool_link(m, Some(s))?,
        };
        transforms.push(StaticTransform {
            parent,
            child,
            kind: if camera {
                FrameKind::Camera(name.clone())
            } else {
                FrameKind::Board(name.clone())
            },
            values: transform_values(&Frame::from_link(pose)),
        });
    }
    Ok(())
}

/// The URDF link a camera or board mounted on the end effector (`site` `None`) or on a site
/// hangs from: the tip link of its chain, or the `_calibrated` link the URDF export added there.
fn tool_link(m: &Mounts<'_>, site: Option<usize>) -> Result<String> {
    let chain = match site {
        None => &m.imported.chain,
        Some(s) => m.imported.branches.get(s).ok_or_else(|| {
            Error::Problem(format!(
                "site `{}` is not a tip of the template (its tips: {}): a camera or board \
                 on it has no URDF link to hang from; import the template with that tip \
                 (--tip) or mount the camera on the end effector",
                m.robot.sites[s].name,
                m.chains
                    .iter()
                    .map(|(c, _)| format!("`{}`", c.tip))
                    .collect::<Vec<_>>()
                    .join(", ")
            ))
        })?,
    };
    let calibrated = format!("{}_calibrated", chain.tip);
    Ok(if m.added.contains(&calibrated) {
        calibrated
    } else {
        chain.tip.clone()
    })
}

/// `static_transforms.yaml` read back: each frame where it was written (to 1e-12) and none
/// missing; an export bug otherwise.
fn transforms_read_back(
    yaml: &str,
    transforms: &[StaticTransform],
    robot: &Robot,
    placement: &Frame,
) -> Result<Transforms> {
    let tf = parse_transforms(yaml, TRANSFORMS_FILE)?;
    for (a, b) in tf.transforms.iter().zip(transforms) {
        let fa = a.frame();
        let expected = match &b.kind {
            FrameKind::Measurement => inverse(placement),
            FrameKind::Session(name) => {
                let Some(s) = robot.sessions.iter().find(|s| &s.name == name) else {
                    return Err(Error::Problem(format!(
                        "session `{name}` is not the robot's (an export bug)"
                    )));
                };
                inverse(&Frame::from_link(&s.frame))
            }
            FrameKind::Camera(name) => match robot.cameras.iter().find(|c| &c.name == name) {
                Some(c) => Frame::from_link(&c.pose),
                None => {
                    return Err(Error::Problem(format!(
                        "camera `{name}` is not the robot's (an export bug)"
                    )))
                }
            },
            FrameKind::Board(name) => match robot.boards.iter().find(|b| &b.name == name) {
                Some(b) => Frame::from_link(&b.pose),
                None => {
                    return Err(Error::Problem(format!(
                        "board `{name}` is not the robot's (an export bug)"
                    )))
                }
            },
        };
        let apart = (fa.translation - expected.translation).norm()
            + log_so3(&(fa.rotation.transpose() * expected.rotation)).norm();
        if a.parent != b.parent || a.child != b.child || apart > 1e-12 {
            return Err(Error::Problem(format!(
                "static_transforms.yaml, read back, misses the frame `{}` by {apart:e} (an \
                 export bug)",
                b.child
            )));
        }
    }
    if tf.transforms.len() != transforms.len() {
        return Err(Error::Problem(
            "static_transforms.yaml, read back, lacks transforms (an export bug)".into(),
        ));
    }
    Ok(tf)
}

/// Each chain of the expanded xacro, imported again and placed by the measurement frame's
/// transform read back (`placed`), against the robot's branch over its joint ranges: the worst
/// position and attitude apart, and the postures compared.
fn chains_read_back(
    robot: &Robot,
    chains: &[(&UrdfChain, Option<usize>)],
    added: &[String],
    expanded: &str,
    urdf_name: &str,
    placed: &Frame,
) -> Result<ReadBack> {
    let mut read_back = ReadBack {
        position: 0.0,
        attitude: 0.0,
        postures: 0,
    };
    for &(chain, site) in chains {
        let (serial, _) = robot.branch(site).map_err(Error::Problem)?;
        let added_link = format!("{}_calibrated", chain.tip);
        let tip = if added.contains(&added_link) {
            added_link
        } else {
            chain.tip.clone()
        };
        let mut back = import_urdf(
            expanded,
            &format!("{} (expanded)", xacro_file_name(urdf_name)),
            Some(&chain.base),
            Some(&tip),
        )?
        .robot;
        back.links[0] = link_of(&placed.then(&Frame::from_link(&back.links[0])));
        let scale = readback::unit_scale(&serial, Units::default());
        let couplings: Vec<Option<usize>> = serial
            .joints
            .iter()
            .map(|j| j.coupling.map(|c| c.joint))
            .collect();
        let r = readback::compare(
            &serial,
            &back,
            &|v, out| {
                for (j, o) in out.iter_mut().enumerate() {
                    *o = v[j] * scale[j] + couplings[j].map_or(0.0, |k| v[k] * scale[j]);
                }
            },
            None,
        );
        read_back.position = read_back.position.max(r.position);
        read_back.attitude = read_back.attitude.max(r.attitude);
        read_back.postures += r.postures;
    }
    Ok(read_back)
}

/// The xacro's file name for a robot called `name`.
fn xacro_file_name(name: &str) -> String {
    let s: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.') {
                c
            } else {
                '_'
            }
        })
        .collect();
    let s = s.trim_start_matches('.');
    format!("{}.urdf.xacro", if s.is_empty() { "robot" } else { s })
}

fn parse_urdf(text: &str, file: &str) -> Result<urdf_rs::Robot> {
    urdf_rs::read_from_string(text.strip_prefix('\u{feff}').unwrap_or(text))
        .map_err(|e| err(file, format!("not a valid URDF: {e}")))
}

/// `[x, y, z, qx, qy, qz, qw]` of a frame.
fn transform_values(f: &Frame) -> [f64; 7] {
    let [qx, qy, qz, qw] = quaternion(&f.rotation);
    let t = f.translation;
    [t.x, t.y, t.z, qx, qy, qz, qw].map(|v| if v == 0.0 { 0.0 } else { v })
}

fn calibration_yaml(robot: &str, hash: &str, joints: &[JointOrigin]) -> String {
    let mut t = String::new();
    let _ = writeln!(
        t,
        "# Written by kinecal export ros: the calibrated joint origins of `{robot}`, which\n\
         # {} reads (xacro.load_yaml). Each is the joint's <origin> in its parent link:\n\
         # x, y, z in metres, roll, pitch, yaw in radians (Trans(xyz) Rz(yaw) Ry(pitch) Rx(roll)).\n\
         # hash: SHA-256 over each joint's name, a zero byte and its six values as little-endian\n\
         # doubles, in this order; its first 8 bytes in hex.",
        xacro_file_name(robot)
    );
    let _ = writeln!(t, "robot: {}", yaml_string(robot));
    let _ = writeln!(t, "hash: {hash}");
    if joints.is_empty() {
        t.push_str("joints: {}\n");
        return t;
    }
    t.push_str("joints:\n");
    for j in joints {
        let _ = writeln!(t, "  {}:", yaml_string(&j.name));
        for (k, v) in ORIGIN_KEYS.iter().zip(&j.origin) {
            let _ = writeln!(t, "    {k}: {}", yaml_number(*v));
        }
    }
    t
}

fn transforms_yaml(robot: &str, transforms: &[StaticTransform]) -> String {
    let mut t = String::new();
    let _ = writeln!(
        t,
        "# Written by kinecal export ros: the frames kinecal estimated outside the robot `{robot}`,\n\
         # which {LAUNCH_FILE} publishes. Each: the child frame's origin (x, y, z,\n\
         # metres) and orientation (unit quaternion qx, qy, qz, qw) in the parent frame."
    );
    let _ = writeln!(t, "robot: {}", yaml_string(robot));
    if transforms.is_empty() {
        t.push_str("transforms: []\n");
        return t;
    }
    t.push_str("transforms:\n");
    for s in transforms {
        let what = match &s.kind {
            FrameKind::Measurement => {
                "the frame the robot was measured in, in its base (the calibration's placement)"
                    .to_string()
            }
            FrameKind::Session(name) => format!(
                "the measurement frame of session `{}` (where the instrument stood)",
                name.escape_debug()
            ),
            FrameKind::Camera(name) => format!(
                "camera `{}`'s optical frame (z along the optical axis, x right, y down)",
                name.escape_debug()
            ),
            FrameKind::Board(name) => format!(
                "board `{}` (its points in the x-y plane, point 0 at the origin)",
                name.escape_debug()
            ),
        };
        let _ = writeln!(t, "  # {what}");
        let _ = writeln!(t, "  - parent: {}", yaml_string(&s.parent));
        let _ = writeln!(t, "    child: {}", yaml_string(&s.child));
        for (k, v) in TRANSFORM_KEYS.iter().zip(&s.values) {
            let _ = writeln!(t, "    {k}: {}", yaml_number(*v));
        }
    }
    t
}

fn launch_text(robot: &str) -> String {
    format!(
        r#"# Written by kinecal export ros: publishes the frames kinecal estimated outside the robot
# `{robot}` (static_transforms.yaml beside this file, read at launch), one tf2_ros
# static_transform_publisher each.
import os
import re

import yaml
from launch import LaunchDescription
from launch_ros.actions import Node

TRANSFORMS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "{TRANSFORMS_FILE}")


def transforms(path=TRANSFORMS):
    """The transforms of the YAML file: dicts of parent, child, x, y, z, qx, qy, qz, qw."""
    with open(path, encoding="utf-8") as f:
        return yaml.safe_load(f)["transforms"] or []


def generate_launch_description():
    nodes = []
    for t in transforms():
        arguments = []
        for key in ("x", "y", "z", "qx", "qy", "qz", "qw"):
            arguments += ["--" + key, repr(float(t[key]))]
        arguments += ["--frame-id", str(t["parent"]), "--child-frame-id", str(t["child"])]
        nodes.append(
            Node(
                package="tf2_ros",
                executable="static_transform_publisher",
                name="kinecal_" + re.sub("[^A-Za-z0-9_]", "_", str(t["child"])),
                arguments=arguments,
                output="screen",
            )
        )
    return LaunchDescription(nodes)
"#
    )
}

/// The expression a placeholder of joint `name`'s value `key` is.
fn placeholder(name: &str, key: &str) -> String {
    format!("${{{XACRO_ARG}['joints']['{name}']['{key}']}}")
}

fn xacro_origin(name: &str) -> String {
    let p = |k: &str| placeholder(name, k);
    format!(
        "<origin xyz=\"{} {} {}\" rpy=\"{} {} {}\"/>",
        p("x"),
        p("y"),
        p("z"),
        p("roll"),
        p("pitch"),
        p("yaw")
    )
}

/// The text xacro reads as `text` literally: every run of `$` before `{` or `(` in elements and
/// character data one `$` longer (comments, CDATA, processing instructions kept as they are).
fn escape_dollars(text: &str, file: &str) -> Result<String> {
    let bom = if text.starts_with('\u{feff}') { 3 } else { 0 };
    let mut reader = Reader::from_str(&text[bom..]);
    let mut out = String::with_capacity(text.len() + 64);
    out.push_str(&text[..bom]);
    loop {
        let before = bom + reader.buffer_position() as usize;
        let event = reader
            .read_event()
            .map_err(|e| err(file, format!("not well-formed XML: {e}")))?;
        let after = bom + reader.buffer_position() as usize;
        let raw = &text[before..after];
        match event {
            Event::Eof => {
                out.push_str(&text[before..]);
                break;
            }
            Event::Start(_) | Event::Empty(_) | Event::End(_) | Event::Text(_) => {
                let b = raw.as_bytes();
                let mut i = 0;
                while i < b.len() {
                    if b[i] == b'$' {
                        let start = i;
                        while i < b.len() && b[i] == b'$' {
                            i += 1;
                        }
                        out.push_str(&raw[start..i]);
                        if i < b.len() && (b[i] == b'{' || b[i] == b'(') {
                            out.push('$');
                        }
                    } else {
                        let start = i;
                        while i < b.len() && b[i] != b'$' {
                            i += 1;
                        }
                        out.push_str(&raw[start..i]);
                    }
                }
            }
            _ => out.push_str(raw),
        }
    }
    Ok(out)
}

/// What xacro does to an escaped text: one `$` less before `{` or `(`.
fn unescape_dollars(text: &str) -> String {
    let b = text.as_bytes();
    let mut out = String::with_capacity(text.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'$' {
            let start = i;
            while i < b.len() && b[i] == b'$' {
                i += 1;
            }
            let run = &text[start..i];
            if i - start > 1 && i < b.len() && (b[i] == b'{' || b[i] == b'(') {
                out.push_str(&run[1..]);
            } else {
                out.push_str(run);
            }
        } else {
            let start = i;
            while i < b.len() && b[i] != b'$' {
                i += 1;
            }
            out.push_str(&text[start..i]);
        }
    }
    out
}

/// The lines put right after the `<robot>` tag.
fn xacro_head() -> String {
    format!(
        "\n  <!-- Added by kinecal export ros: the calibrated joint origins, from {CALIBRATION_FILE} \
         beside this file\n       unless the argument {XACRO_ARG}:=FILE names another (relative \
         to this file's folder). -->\n  <xacro:arg name=\"{XACRO_ARG}\" \
         default=\"{CALIBRATION_FILE}\"/>\n  <xacro:property name=\"{XACRO_ARG}\" \
         value=\"${{xacro.load_yaml('$(arg {XACRO_ARG})')}}\"/>"
    )
}

const XACRO_NS: &str = " xmlns:xacro=\"http://www.ros.org/wiki/xacro\"";

/// The xacro of the URDF `urdf`: escaped, each of `joints`' origins a placeholder, the xacro
/// namespace and the calibration's loading added to `<robot>`.
fn xacro_text(urdf: &str, file: &str, joints: &[JointOrigin]) -> Result<String> {
    let mut text = escape_dollars(urdf, file)?;
    let index = super::xml::scan(&text, file)?;
    let mut edits: Vec<(usize, usize, String)> = Vec::new();
    for j in joints {
        let span = index
            .joint(&j.name)
            .ok_or_else(|| err(file, format!("joint `{}` not found", j.name)))?;
        match span.origin {
            Some((s, e)) => edits.push((s, e, xacro_origin(&j.name))),
            None => edits.push((
                span.after_open,
                span.after_open,
                format!("\n    {}", xacro_origin(&j.name)),
            )),
        }
    }
    // The <robot> tag: where it ends, and whether it declares the xacro namespace.
    let (tag_end, has_ns) = robot_tag(&text, file)?;
    let ns = if has_ns { "" } else { XACRO_NS };
    edits.push((tag_end - 1, tag_end - 1, ns.to_string()));
    edits.push((tag_end, tag_end, xacro_head()));
    edits.sort_by_key(|e| std::cmp::Reverse(e.0));
    for (s, e, r) in edits {
        text.replace_range(s..e, &r);
    }
    Ok(text)
}

/// The byte after the `<robot ...>` opening tag, and whether it declares `xmlns:xacro`.
fn robot_tag(text: &str, file: &str) -> Result<(usize, bool)> {
    let bom = if text.starts_with('\u{feff}') { 3 } else { 0 };
    let mut reader = Reader::from_str(&text[bom..]);
    loop {
        let event = reader
            .read_event()
            .map_err(|e| err(file, format!("not well-formed XML: {e}")))?;
        let after = bom + reader.buffer_position() as usize;
        match event {
            Event::Start(e) => {
                if e.name().as_ref() != b"robot" {
                    return Err(err(file, "the root element is not <robot>: not a URDF"));
                }
                let has = e
                    .attributes()
                    .flatten()
                    .any(|a| a.key.as_ref() == b"xmlns:xacro");
                return Ok((after, has));
            }
            Event::Empty(_) | Event::Eof => {
                return Err(err(file, "no <robot> element with content: not a URDF"))
            }
            _ => {}
        }
    }
}

/// The URDF xacro makes of `xacro` with the calibration `joints`: the head removed, each
/// placeholder replaced by its value (as Python prints a float: the shortest text that reads
/// back), the escapes undone.
pub fn expand_xacro(xacro: &str, joints: &[JointOrigin], file: &str) -> Result<String> {
    let head = xacro_head();
    let Some(at) = xacro.find(&head) else {
        return Err(err(file, "not a xacro written by kinecal export ros"));
    };
    let mut text = format!("{}{}", &xacro[..at], &xacro[at + head.len()..]);
    text = text.replacen(XACRO_NS, "", 1);
    let mut out = String::with_capacity(text.len());
    let open = format!("${{{XACRO_ARG}['joints']['");
    let mut rest = text.as_str();
    while let Some(i) = rest.find(&open) {
        out.push_str(&unescape_dollars(&rest[..i]));
        let tail = &rest[i + open.len()..];
        let end = tail
            .find("']}")
            .ok_or_else(|| err(file, "an unterminated calibration expression"))?;
        let (name, key) = tail[..end]
            .split_once("']['")
            .ok_or_else(|| err(file, "a calibration expression without a key"))?;
        let j = joints
            .iter()
            .find(|j| j.name == name)
            .ok_or_else(|| err(file, format!("joint `{name}` is not in the calibration")))?;
        let k = ORIGIN_KEYS
            .iter()
            .position(|k| *k == key)
            .ok_or_else(|| err(file, format!("no key `{key}` in a joint's origin")))?;
        let _ = write!(out, "{:?}", j.origin[k]);
        rest = &tail[end + 3..];
    }
    out.push_str(&unescape_dollars(rest));
    Ok(out)
}

/// `Ok` when the URDFs `a` and `b` have the same links and joints, each joint of the same kind,
/// parent, child and axis and of bit for bit the same origin.
fn same_urdf(a: &str, b: &str, file: &str) -> Result<()> {
    let (ra, rb) = (parse_urdf(a, file)?, parse_urdf(b, file)?);
    let links = |r: &urdf_rs::Robot| r.links.iter().map(|l| l.name.clone()).collect::<Vec<_>>();
    let bits = |v: [f64; 3]| v.map(f64::to_bits);
    let same = ra.name == rb.name
        && links(&ra) == links(&rb)
        && ra.joints.len() == rb.joints.len()
        && ra.joints.iter().zip(&rb.joints).all(|(x, y)| {
            x.name == y.name
                && x.joint_type == y.joint_type
                && x.parent.link == y.parent.link
                && x.child.link == y.child.link
                && bits(x.axis.xyz.0) == bits(y.axis.xyz.0)
                && bits(x.origin.xyz.0) == bits(y.origin.xyz.0)
                && bits(x.origin.rpy.0) == bits(y.origin.rpy.0)
        });
    if same {
        Ok(())
    } else {
        Err(Error::Problem(
            "the xacro, expanded with its calibration YAML, is not the calibrated URDF (an \
             export bug)"
                .into(),
        ))
    }
}

/// A `calibration.yaml`, read.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct Calibration {
    /// The robot's name.
    pub robot: String,
    /// The hash, as written.
    pub hash: String,
    /// The joints' origins, in the file's order.
    pub joints: Vec<JointOrigin>,
}

/// A `static_transforms.yaml`, read.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct Transforms {
    /// The robot's name.
    pub robot: String,
    /// The transforms, in the file's order (the file does not say what each is: the first is
    /// taken as the placement, the others as [`FrameKind::Session`] with an empty name; the
    /// exporter knows the cameras' and boards' entries by their order).
    pub transforms: Vec<StaticTransform>,
}

/// One meaningful line of the YAML subset these files are: indentation, an optional `- `, the
/// key and the value (unquoted).
struct Line<'a> {
    number: usize,
    indent: usize,
    item: bool,
    key: String,
    value: &'a str,
}

/// A scalar: double-quoted (with `\"` and `\\`), single-quoted (with `''`) or plain.
fn unquote(s: &str) -> Option<String> {
    if let Some(inner) = s.strip_prefix('"') {
        let inner = inner.strip_suffix('"')?;
        let mut out = String::new();
        let mut chars = inner.chars();
        while let Some(c) = chars.next() {
            match c {
                '\\' => match chars.next()? {
                    c @ ('"' | '\\') => out.push(c),
                    _ => return None,
                },
                '"' => return None,
                c => out.push(c),
            }
        }
        Some(out)
    } else if let Some(inner) = s.strip_prefix('\'') {
        Some(inner.strip_suffix('\'')?.replace("''", "'"))
    } else {
        Some(s.to_string())
    }
}

/// Where a comment starts in `s` (a `#` at the start or after a blank, outside quotes).
fn comment_start(s: &str) -> usize {
    let mut quote: Option<char> = None;
    let mut prev = ' ';
    for (i, c) in s.char_indices() {
        match quote {
            Some('"') if c == '\\' => {}
            Some(q) if c == q && !(q == '"' && prev == '\\') => quote = None,
            Some(_) => {}
            None if c == '"' || c == '\'' => quote = Some(c),
            None if c == '#' && (prev == ' ' || prev == '\t' || i == 0) => return i,
            None => {}
        }
        prev = if prev == '\\' && c == '\\' { ' ' } else { c };
    }
    s.len()
}

fn lines<'a>(text: &'a str, file: &str) -> Result<Vec<Line<'a>>> {
    let mut out = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let number = i + 1;
        let content = &raw[..comment_start(raw)];
        if content.trim().is_empty() {
            continue;
        }
        if content.contains('\t') {
            return Err(Error::input(
                Location::file(file).at_line(number),
                "a tab in the indentation or a value: YAML indents with spaces",
            ));
        }
        let indent = content.len() - content.trim_start().len();
        let mut body = content.trim();
        let item = body.starts_with("- ");
        if item {
            body = body[2..].trim_start();
        }
        // The key: quoted, or up to the first `: ` (or a final `:`).
        let (key, value) = if body.starts_with('"') || body.starts_with('\'') {
            let close = comment_start_quote_end(body).ok_or_else(|| {
                Error::input(
                    Location::file(file).at_line(number),
                    "an unterminated quoted key",
                )
            })?;
            let (k, rest) = body.split_at(close);
            let rest = rest.trim_start().strip_prefix(':').ok_or_else(|| {
                Error::input(
                    Location::file(file).at_line(number),
                    format!("expected `key: value`, found `{body}`"),
                )
            })?;
            (k, rest.trim())
        } else {
            let Some(c) = body
                .find(": ")
                .or_else(|| body.strip_suffix(':').map(|k| k.len()))
            else {
                return Err(Error::input(
                    Location::file(file).at_line(number),
                    format!("expected `key: value`, found `{body}`"),
                ));
            };
            (&body[..c], body[c + 1..].trim())
        };
        let key = unquote(key).ok_or_else(|| {
            Error::input(
                Location::file(file).at_line(number),
                format!("a malformed quoted key `{key}`"),
            )
        })?;
        out.push(Line {
            number,
            indent: indent + if item { 2 } else { 0 },
            item,
            key,
            value,
        });
    }
    Ok(out)
}

/// The byte after the closing quote of the quoted scalar `s` starts with.
fn comment_start_quote_end(s: &str) -> Option<usize> {
    let q = s.chars().next()?;
    let mut escaped = false;
    for (i, c) in s.char_indices().skip(1) {
        if q == '"' && c == '\\' && !escaped {
            escaped = true;
            continue;
        }
        if c == q && !escaped {
            return Some(i + 1);
        }
        escaped = false;
    }
    None
}

fn number(l: &Line<'_>, file: &str) -> Result<f64> {
    let v: f64 = l.value.parse().map_err(|_| {
        Error::input(
            Location::file(file)
                .at_line(l.number)
                .with_field(l.key.clone()),
            format!("expected a number, found `{}`", l.value),
        )
    })?;
    if !v.is_finite() {
        return Err(Error::input(
            Location::file(file)
                .at_line(l.number)
                .with_field(l.key.clone()),
            format!("{} is not a finite number", l.value),
        ));
    }
    Ok(v)
}

fn text_value(l: &Line<'_>, file: &str) -> Result<String> {
    unquote(l.value).ok_or_else(|| {
        Error::input(
            Location::file(file)
                .at_line(l.number)
                .with_field(l.key.clone()),
            format!("a malformed quoted string `{}`", l.value),
        )
    })
}

/// The values of `keys` on the lines of one mapping, each once.
fn values<const N: usize>(
    lines: &[Line<'_>],
    keys: [&str; N],
    what: &str,
    file: &str,
) -> Result<[f64; N]> {
    let mut out = [f64::NAN; N];
    for l in lines {
        let k = keys.iter().position(|k| *k == l.key).ok_or_else(|| {
            Error::input(
                Location::file(file)
                    .at_line(l.number)
                    .with_field(l.key.clone()),
                format!("unknown key in {what}: expected {}", keys.join(", ")),
            )
        })?;
        if !out[k].is_nan() {
            return Err(Error::input(
                Location::file(file)
                    .at_line(l.number)
                    .with_field(l.key.clone()),
                format!("`{}` given twice in {what}", l.key),
            ));
        }
        out[k] = number(l, file)?;
    }
    if let Some(k) = out.iter().position(|v| v.is_nan()) {
        return Err(Error::input(
            Location::file(file),
            format!("{what} lacks `{}`", keys[k]),
        ));
    }
    Ok(out)
}

/// The top-level keys of `lines`: (key line, the lines under it).
fn top<'a, 'b>(lines: &'b [Line<'a>], file: &str) -> Result<Vec<(&'b Line<'a>, &'b [Line<'a>])>> {
    let mut out: Vec<(&Line<'_>, &[Line<'_>])> = Vec::new();
    let mut i = 0;
    while i < lines.len() {
        let l = &lines[i];
        if l.indent != 0 || l.item {
            return Err(Error::input(
                Location::file(file).at_line(l.number),
                "expected a top-level key",
            ));
        }
        let mut j = i + 1;
        while j < lines.len() && lines[j].indent > 0 {
            j += 1;
        }
        if out.iter().any(|(k, _)| k.key == l.key) {
            return Err(Error::input(
                Location::file(file).at_line(l.number),
                format!("`{}` given twice", l.key),
            ));
        }
        out.push((l, &lines[i + 1..j]));
        i = j;
    }
    Ok(out)
}

/// Reads a `calibration.yaml` as [`export_ros`] writes it (`robot`, `hash`, `joints`: a mapping
/// of joint names to mappings of `x, y, z, roll, pitch, yaw`); anything else is refused with its
/// line.
pub fn parse_calibration(text: &str, file: &str) -> Result<Calibration> {
    let lines = lines(text, file)?;
    let (mut robot, mut hash, mut joints) = (None, None, None);
    for (l, under) in top(&lines, file)? {
        match l.key.as_str() {
            "robot" => robot = Some(text_value(l, file)?),
            "hash" => hash = Some(text_value(l, file)?),
            "joints" => {
                let mut out: Vec<JointOrigin> = Vec::new();
                if l.value == "{}" {
                    joints = Some(out);
                    continue;
                }
                if !l.value.is_empty() {
                    return Err(Error::input(
                        Location::file(file).at_line(l.number),
                        "`joints:` must open a mapping",
                    ));
                }
                let indent = under.first().map_or(0, |f| f.indent);
                let mut i = 0;
                while i < under.len() {
                    let h = &under[i];
                    if h.indent != indent || h.item || !h.value.is_empty() {
                        return Err(Error::input(
                            Location::file(file).at_line(h.number),
                            "expected a joint's name opening a mapping",
                        ));
                    }
                    let mut j = i + 1;
                    while j < under.len() && under[j].indent > indent {
                        j += 1;
                    }
                    if out.iter().any(|o| o.name == h.key) {
                        return Err(Error::input(
                            Location::file(file).at_line(h.number),
                            format!("joint `{}` given twice", h.key),
                        ));
                    }
                    let what = format!("joint `{}`", h.key);
                    out.push(JointOrigin {
                        name: h.key.clone(),
                        origin: values(&under[i + 1..j], ORIGIN_KEYS, &what, file)?,
                    });
                    i = j;
                }
                joints = Some(out);
            }
            other => {
                return Err(Error::input(
                    Location::file(file).at_line(l.number),
                    format!("unknown key `{other}`: expected robot, hash, joints"),
                ))
            }
        }
    }
    let missing = |k: &str| Error::input(Location::file(file), format!("no `{k}`"));
    Ok(Calibration {
        robot: robot.ok_or_else(|| missing("robot"))?,
        hash: hash.ok_or_else(|| missing("hash"))?,
        joints: joints.ok_or_else(|| missing("joints"))?,
    })
}

/// Reads a `static_transforms.yaml` as [`export_ros`] writes it (`robot`, `transforms`: a list
/// of mappings of `parent`, `child`, `x, y, z, qx, qy, qz, qw`); anything else is refused with
/// its line. The quaternions must be of unit length (within 1e-9).
pub fn parse_transforms(text: &str, file: &str) -> Result<Transforms> {
    let lines = lines(text, file)?;
    let (mut robot, mut transforms) = (None, None);
    for (l, under) in top(&lines, file)? {
        match l.key.as_str() {
            "robot" => robot = Some(text_value(l, file)?),
            "transforms" => {
                let mut out: Vec<StaticTransform> = Vec::new();
                if l.value == "[]" {
                    transforms = Some(out);
                    continue;
                }
                if !l.value.is_empty() {
                    return Err(Error::input(
                        Location::file(file).at_line(l.number),
                        "`transforms:` must open a list",
                    ));
                }
                let mut i = 0;
                while i < under.len() {
                    let h = &under[i];
                    if !h.item {
                        return Err(Error::input(
                            Location::file(file).at_line(h.number),
                            "expected `- parent: ...` opening a transform",
                        ));
                    }
                    let mut j = i + 1;
                    while j < under.len() && !under[j].item {
                        j += 1;
                    }
                    let what = format!("transform {}", out.len() + 1);
                    let (mut parent, mut child) = (None, None);
                    let mut numbers = Vec::new();
                    for m in &under[i..j] {
                        if m.indent != h.indent {
                            return Err(Error::input(
                                Location::file(file).at_line(m.number),
                                format!("inconsistent indentation in {what}"),
                            ));
                        }
                        match m.key.as_str() {
                            "parent" if parent.is_none() => parent = Some(text_value(m, file)?),
                            "child" if child.is_none() => child = Some(text_value(m, file)?),
                            _ => numbers.push(Line {
                                value: m.value,
                                key: m.key.clone(),
                                ..*m
                            }),
                        }
                    }
                    let values = values(&numbers, TRANSFORM_KEYS, &what, file)?;
                    let norm = values[3..].iter().map(|v| v * v).sum::<f64>().sqrt();
                    if (norm - 1.0).abs() > 1e-9 {
                        return Err(Error::input(
                            Location::file(file).at_line(h.number),
                            format!("{what}: the quaternion's length is {norm}, not 1"),
                        ));
                    }
                    let missing = |k: &str| {
                        Error::input(
                            Location::file(file).at_line(h.number),
                            format!("{what} lacks `{k}`"),
                        )
                    };
                    out.push(StaticTransform {
                        parent: parent.ok_or_else(|| missing("parent"))?,
                        child: child.ok_or_else(|| missing("child"))?,
                        kind: if out.is_empty() {
                            FrameKind::Measurement
                        } else {
                            FrameKind::Session(String::new())
                        },
                        values,
                    });
                    i = j;
                }
                transforms = Some(out);
            }
            other => {
                return Err(Error::input(
                    Location::file(file).at_line(l.number),
                    format!("unknown key `{other}`: expected robot, transforms"),
                ))
            }
        }
    }
    let missing = |k: &str| Error::input(Location::file(file), format!("no `{k}`"));
    Ok(Transforms {
        robot: robot.ok_or_else(|| missing("robot"))?,
        transforms: transforms.ok_or_else(|| missing("transforms"))?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_read_back_exactly_and_as_yaml_floats() {
        for v in [
            0.0,
            -0.0,
            1.0,
            -2.5,
            0.1273,
            1e-7,
            -3.3e-17,
            6.02e23,
            std::f64::consts::PI,
            f64::MIN_POSITIVE,
            f64::MAX,
        ] {
            let s = yaml_number(v);
            let expected: f64 = if v == 0.0 { 0.0 } else { v };
            assert_eq!(
                s.parse::<f64>().unwrap().to_bits(),
                expected.to_bits(),
                "{s}"
            );
            // PyYAML's float: digits, a point, an optional signed exponent.
            let (m, e) = s.split_once('e').unwrap_or((&s, "+0"));
            assert!(m.contains('.'), "{s}");
            assert!(e.starts_with('+') || e.starts_with('-'), "{s}");
        }
        assert_eq!(yaml_number(-0.0), "0.0");
        assert_eq!(yaml_number(1e-7), "1.0e-7");
        assert_eq!(yaml_number(6.02e23), "6.02e+23");
    }

    #[test]
    fn dollars_are_escaped_for_xacro_outside_comments_and_back() {
        let t = "<robot name=\"a${b}\"><!-- ${c} --><link name=\"$$(d)\"/>x$ y${z}</robot>";
        let e = escape_dollars(t, "t").unwrap();
        assert_eq!(
            e,
            "<robot name=\"a$${b}\"><!-- ${c} --><link name=\"$$$(d)\"/>x$ y$${z}</robot>"
        );
        // Undoing it (a lone `$` stays) gives the text back.
        assert_eq!(unescape_dollars(&e), t);
    }

    /// Names a xacro attribute cannot carry unescaped (`&`, `<`, `>` would make the xacro
    /// malformed XML while the read-back, substituting numbers first, passed) are refused, as
    /// quotes and `$` are; a measurement frame may not begin with `/`.
    #[test]
    fn names_that_break_the_xacro_are_refused() {
        for bad in ["j&1", "j<1", "j>1", "j'1", "j$1"] {
            assert!(check_name(bad, "joint", "t.urdf").is_err(), "{bad}");
        }
        assert!(check_name("shoulder_pan-joint.1", "joint", "t.urdf").is_ok());
    }
}
