//! URDF: import a serial chain, and write a calibration back into the original file.
//!
//! Import: the chain from `base` to `tip`; revolute, continuous and prismatic joints become
//! joints, fixed joints merge into the neighbouring link transform. A joint origin `xyz rpy` is
//! `Trans(xyz) Rz(yaw) Ry(pitch) Rx(roll)`, the thesis's link transform. A joint axis other than
//! +z is handled exactly by a constant rotation `R_a` (with `R_a e_z = axis`) folded into the
//! link before the joint, and its inverse into the link after it. Readings are the URDF joint
//! values (rad, m; slope 1) and joint limits become reading ranges. Mimic joints, closed chains
//! and floating or planar joints in the chain are refused with the element named. The links'
//! `<inertial>` masses and centres of mass give the bodies of a mass model ([`urdf_bodies`]).
//!
//! Export: each movable joint's `<origin>` is rewritten so that the URDF's forward kinematics is
//! the calibrated one (joint offsets folded in); the first fixed joint after the last movable one
//! takes the tool-frame correction; a joint without `<origin>` gets one. Everything else in the
//! file (visuals, inertias, limits, comments, formatting, a byte-order mark) is kept byte for
//! byte. The result is read back and compared with the robot ([`super::readback`]).

use std::collections::HashMap;

use nalgebra::{Matrix3, Vector3};

use super::readback::{self, ReadBack, Tolerance};
use super::{inverse, rotation_from_xz, ImportedJoint, Lost};
use crate::error::{Error, Location, Result, Setting};
use crate::model::kinematics::{euler_zyx, rot_zyx, Frame};
use crate::model::robot::{Body, JointKind, Robot};
use crate::units::Units;
use crate::warning::Warning;

/// A URDF joint origin as a frame: `Trans(xyz) Rz(yaw) Ry(pitch) Rx(roll)`.
pub(crate) fn origin_frame(xyz: [f64; 3], rpy: [f64; 3]) -> Frame {
    Frame {
        rotation: rot_zyx(rpy[2], rpy[1], rpy[0]),
        translation: Vector3::from(xyz),
    }
}

/// The URDF chain behind an imported robot: what export needs.
#[derive(Debug, Clone, PartialEq)]
pub struct UrdfChain {
    /// Joint names from base to tip.
    pub joints: Vec<String>,
    /// Which of them are movable (in order, one per robot joint).
    pub movable: Vec<String>,
    /// For each movable joint, the constant rotation `R_a` (in its child frame) whose z is the
    /// joint axis; its x is chosen along the common normal with the previous joint's axis, which
    /// keeps the links' beta at 0, away from the Euler singularity.
    pub(crate) axis_frames: Vec<Matrix3<f64>>,
    /// Origin of every chain joint as in the file.
    pub origins: Vec<Frame>,
    /// The base link.
    pub base: String,
    /// The tip link.
    pub tip: String,
}

/// A joint whose origin export rewrites: (joint name, new origin, origin in the template).
pub(crate) type NewOrigin = (String, Frame, Frame);

/// The result of [`import_urdf`].
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct UrdfImport {
    /// The robot (metres and radians).
    pub robot: Robot,
    /// The chain it came from: the one to the end effector.
    pub chain: UrdfChain,
    /// A tree's other chains, one per site (in the order of the robot's sites).
    pub branches: Vec<UrdfChain>,
}

impl UrdfImport {
    /// Each chain with the site at its tip (`None`: the end effector's): the sites' first, in
    /// the order of the import.
    pub fn chains(&self) -> Vec<(&UrdfChain, Option<usize>)> {
        self.branches
            .iter()
            .enumerate()
            .map(|(s, c)| (c, Some(s)))
            .chain([(&self.chain, None)])
            .collect()
    }
}

/// A chain end that is not in `file` or not unique.
fn chain(setting: Setting, file: &str, message: String) -> Error {
    Error::ChainEnd {
        at: Location::file(file),
        setting,
        message,
    }
}

fn err(file: &str, message: impl Into<String>) -> Error {
    Error::input(Location::file(file), message)
}

/// Reads the chain from `base` to `tip` of a URDF. `base` defaults to the root link, `tip` to the
/// only leaf (an error lists the leaves when there are several). The end effector is named after
/// the tip link ([`Robot::end_effector`]): files' `site` column may call it so, or `ee`.
pub fn import_urdf(
    text: &str,
    file: &str,
    base: Option<&str>,
    tip: Option<&str>,
) -> Result<UrdfImport> {
    import_urdf_tree(text, file, base, &tip.into_iter().collect::<Vec<_>>())
}

/// Reads the tree from `base` to each of `tips` (a robot with several tool frames: two arms on
/// one torso, a tool and a marker). The movable joints of every chain become the robot's joints,
/// each once, named as in the URDF, in the order the chains first reach them (parents before
/// children); the last tip is the end effector (named after its link) and ends the last joint's
/// branch, each other tip is a site named after its link, hanging off the last movable joint on
/// its chain (fixed joints to marker or tool links become these estimated tool frames). With
/// one tip or none, this is [`import_urdf`]'s chain.
pub fn import_urdf_tree(
    text: &str,
    file: &str,
    base: Option<&str>,
    tips: &[&str],
) -> Result<UrdfImport> {
    let index = super::xml::scan(text, file)?;
    let urdf = urdf_rs::read_from_string(text.strip_prefix('\u{feff}').unwrap_or(text))
        .map_err(|e| err(file, format!("not a valid URDF: {e}")))?;
    check_joint_numbers(&urdf, &index, file)?;
    let links: Vec<&str> = urdf.links.iter().map(|l| l.name.as_str()).collect();
    let parent_of = parent_joints(&urdf, &links, file)?;
    let base = chain_base(base, &links, &parent_of, file)?;
    let tip_names = tip_links(tips, &links, &urdf, file)?;
    let Joined {
        tree,
        names,
        parents,
        mut chains,
        ends,
    } = joined_chains(&urdf, &parent_of, file, base, &tip_names)?;
    let (ee_joint, ee_frame) = *ends.last().expect("a tip");
    if ee_joint != tree.len() {
        return Err(chain(
            Setting::ChainTip,
            file,
            format!(
                "the last tip, `{}`, is the end effector and must end the last branch: name it \
                 before the tips whose chains go on past it",
                tip_names.last().expect("a tip")
            ),
        ));
    }
    let mut robot =
        super::tree_from_frames(&urdf.name, Units::default(), &tree, &parents, &ee_frame);
    for (joint, name) in robot.joints.iter_mut().zip(&names) {
        // A URDF joint name heads its reading column (unless it reads like `vK`).
        let reads_like_v = name.starts_with('v') && name[1..].parse::<usize>().is_ok();
        joint.name = (!reads_like_v && !name.trim().is_empty()).then(|| name.clone());
    }
    let ee_chain = chains.pop().expect("a tip");
    // The end effector is called by its link's name, as well as `ee`, whether it is a chain's
    // only tip or a tree's last (`ee` itself needs no second name).
    if ee_chain.tip != "ee" {
        robot.end_effector = Some(ee_chain.tip.clone());
    }
    add_sites(&mut robot, &tree, &chains, &ends, base, file)?;
    robot.validate().map_err(|m| err(file, m))?;
    Ok(UrdfImport {
        robot,
        chain: ee_chain,
        branches: chains,
    })
}

/// Every number of every joint is finite and of a plausible size (a metre is a metre): an
/// error names the joint, its field and its line (from `index`) otherwise.
fn check_joint_numbers(urdf: &urdf_rs::Robot, index: &super::xml::Index, file: &str) -> Result<()> {
    for j in &urdf.joints {
        let line = index.joint(&j.name).map(|s| s.line);
        let bad = |field: &str, what: String| {
            let mut at = Location::file(file).with_field(format!("joint `{}` {field}", j.name));
            at.line = line;
            Error::input(at, what)
        };
        for (field, v) in [
            ("origin xyz", j.origin.xyz.0),
            ("origin rpy", j.origin.rpy.0),
            ("axis xyz", j.axis.xyz.0),
        ] {
            if let Some(x) = v.iter().find(|x| !x.is_finite() || x.abs() > 1e6) {
                return Err(bad(
                    field,
                    format!("{x} is not a finite number of plausible size (|x| <= 1e6)"),
                ));
            }
        }
        for (field, v) in [
            ("limit lower", j.limit.lower),
            ("limit upper", j.limit.upper),
        ] {
            if !crate::units::plausible(v) {
                return Err(bad(
                    field,
                    format!("{v:e} is not a finite number within +-1e9"),
                ));
            }
        }
    }
    Ok(())
}

/// Each link's parent joint, keyed by the link's name: an error when a joint names a link
/// that `links` lacks, or a link is the child of two joints (a closed chain).
fn parent_joints<'u>(
    urdf: &'u urdf_rs::Robot,
    links: &[&str],
    file: &str,
) -> Result<HashMap<&'u str, &'u urdf_rs::Joint>> {
    let mut parent_of: HashMap<&str, &urdf_rs::Joint> = HashMap::new();
    for j in &urdf.joints {
        for (role, l) in [("parent", &j.parent.link), ("child", &j.child.link)] {
            if !links.contains(&l.as_str()) {
                return Err(err(
                    file,
                    format!("joint `{}`: its {role} link `{l}` is not defined", j.name),
                ));
            }
        }
        if let Some(other) = parent_of.insert(&j.child.link, j) {
            return Err(err(
                file,
                format!(
                    "link `{}` is the child of two joints (`{}` and `{}`): a closed chain, which a serial model cannot describe",
                    j.child.link, other.name, j.name
                ),
            ));
        }
    }
    Ok(parent_of)
}

/// The chain's base link: `base` when `links` has it, else the only root (a link no joint
/// is the parent of).
fn chain_base<'a>(
    base: Option<&'a str>,
    links: &[&'a str],
    parent_of: &HashMap<&str, &urdf_rs::Joint>,
    file: &str,
) -> Result<&'a str> {
    let roots: Vec<&str> = links
        .iter()
        .copied()
        .filter(|l| !parent_of.contains_key(l))
        .collect();
    match base {
        Some(b) if links.contains(&b) => Ok(b),
        Some(b) => Err(chain(
            Setting::ChainBase,
            file,
            format!("no link named `{b}` (the chain's base)"),
        )),
        None => match roots.as_slice() {
            [one] => Ok(*one),
            _ => Err(chain(
                Setting::ChainBase,
                file,
                format!(
                    "several root links ({}): name the chain's base",
                    roots.join(", ")
                ),
            )),
        },
    }
}

/// The chains' tip links: `tips`, each a link of `links` named once, else the only leaf (a
/// link no joint is the parent of).
fn tip_links<'a>(
    tips: &[&'a str],
    links: &[&'a str],
    urdf: &urdf_rs::Robot,
    file: &str,
) -> Result<Vec<&'a str>> {
    let has_children: Vec<&str> = urdf.joints.iter().map(|j| j.parent.link.as_str()).collect();
    let mut tip_names: Vec<&str> = Vec::new();
    for &t in tips {
        if !links.contains(&t) {
            return Err(chain(
                Setting::ChainTip,
                file,
                format!("no link named `{t}` (the chain's tip)"),
            ));
        }
        if tip_names.contains(&t) {
            return Err(chain(
                Setting::ChainTip,
                file,
                format!("tip `{t}` named twice"),
            ));
        }
        tip_names.push(t);
    }
    if tip_names.is_empty() {
        let leaves: Vec<&str> = links
            .iter()
            .copied()
            .filter(|l| !has_children.contains(l))
            .collect();
        match leaves.as_slice() {
            [one] => tip_names.push(*one),
            _ => {
                return Err(chain(
                    Setting::ChainTip,
                    file,
                    format!(
                        "several leaf links ({}): name the chain's tip",
                        leaves.join(", ")
                    ),
                ))
            }
        }
    }
    Ok(tip_names)
}

/// The tree the tips' chains make: its movable joints each once (parents before children).
struct Joined {
    /// The joints, each frame global at the zero configuration.
    tree: Vec<ImportedJoint>,
    /// Their URDF names.
    names: Vec<String>,
    /// Per joint, its parent joint (1-based; 0 the base).
    parents: Vec<usize>,
    /// Per tip, its chain.
    chains: Vec<UrdfChain>,
    /// Per tip: the last movable joint on its chain (1-based) and the tip's frame.
    ends: Vec<(usize, Frame)>,
}

/// Each tip's chain from `base`, then the tree they make: a joint already met on an earlier
/// chain is shared, not repeated.
fn joined_chains(
    urdf: &urdf_rs::Robot,
    parent_of: &HashMap<&str, &urdf_rs::Joint>,
    file: &str,
    base: &str,
    tip_names: &[&str],
) -> Result<Joined> {
    let mut tree: Vec<ImportedJoint> = Vec::new();
    let mut names: Vec<String> = Vec::new();
    let mut parents: Vec<usize> = Vec::new();
    let mut chains: Vec<UrdfChain> = Vec::new();
    let mut ends: Vec<(usize, Frame)> = Vec::new();
    for &tip in tip_names {
        let (c, movables, tip_frame) = tip_chain(urdf, parent_of, file, base, tip)?;
        let mut last = 0;
        for (name, joint) in movables {
            match names.iter().position(|n| *n == name) {
                Some(k) => last = k + 1,
                None => {
                    names.push(name);
                    tree.push(joint);
                    parents.push(last);
                    last = tree.len();
                }
            }
        }
        chains.push(c);
        ends.push((last, tip_frame));
    }
    Ok(Joined {
        tree,
        names,
        parents,
        chains,
        ends,
    })
}

/// Each of `chains`' tips (all but the end effector's) as a site of `robot` named after its
/// link, on the last movable joint of its chain (`ends`, in the chains' order), its frame
/// relative to that joint's (`tree`, global frames at zero).
fn add_sites(
    robot: &mut Robot,
    tree: &[ImportedJoint],
    chains: &[UrdfChain],
    ends: &[(usize, Frame)],
    base: &str,
    file: &str,
) -> Result<()> {
    for (c, &(joint, frame)) in chains.iter().zip(ends) {
        if joint == 0 {
            return Err(chain(
                Setting::ChainTip,
                file,
                format!("no movable joint between `{base}` and tip `{}`", c.tip),
            ));
        }
        let carrier = tree[joint - 1].frame;
        robot.sites.push(crate::model::robot::Site {
            name: c.tip.clone(),
            joint,
            frame: super::link_of(&inverse(&carrier).then(&frame)),
        });
    }
    Ok(())
}

/// The movable joints of one chain: (name, joint), each joint's frame global at the zero
/// configuration.
type Movables = Vec<(String, ImportedJoint)>;

/// The chain from `base` to `tip`, its movable joints and the tip's frame (global, at zero).
fn tip_chain(
    urdf: &urdf_rs::Robot,
    parent_of: &HashMap<&str, &urdf_rs::Joint>,
    file: &str,
    base: &str,
    tip: &str,
) -> Result<(UrdfChain, Movables, Frame)> {
    // Walk from the tip up to the base.
    let mut chain: Vec<&urdf_rs::Joint> = Vec::new();
    let mut at = tip;
    while at != base {
        let Some(j) = parent_of.get(at) else {
            return Err(err(
                file,
                format!("link `{tip}` is not below link `{base}`: base and tip are not connected"),
            ));
        };
        chain.push(j);
        at = &j.parent.link;
        if chain.len() > urdf.joints.len() {
            return Err(err(file, "the joints form a loop"));
        }
    }
    chain.reverse();
    let mut acc = Frame::identity();
    let mut joints = Vec::new();
    let mut movable = Vec::new();
    let mut axis_frames = Vec::new();
    let mut origins = Vec::new();
    let mut prev_joint = Frame::identity();
    for j in &chain {
        if let Some(m) = &j.mimic {
            return Err(err(
                file,
                format!(
                    "joint `{}` mimics joint `{}`: mimic joints are not supported in the chain",
                    j.name, m.joint
                ),
            ));
        }
        let o = origin_frame(j.origin.xyz.0, j.origin.rpy.0);
        origins.push(o);
        acc = acc.then(&o);
        let kind = match j.joint_type {
            urdf_rs::JointType::Fixed => continue,
            urdf_rs::JointType::Revolute | urdf_rs::JointType::Continuous => JointKind::Revolute,
            urdf_rs::JointType::Prismatic => JointKind::Prismatic,
            ref other => {
                return Err(err(file, format!("joint `{}` is {other:?}: only revolute, continuous, prismatic and fixed joints can be calibrated", j.name)))
            }
        };
        let axis = Vector3::from(j.axis.xyz.0);
        if axis.norm() < 1e-12 {
            return Err(err(file, format!("joint `{}` has a zero axis", j.name)));
        }
        // x along the common normal with the previous joint's axis (global), or, for a parallel
        // axis, the previous joint frame's x.
        let zg = acc.rotation * axis.normalize();
        let pz = prev_joint.rotation.column(2).into_owned();
        let n = pz.cross(&zg);
        let xg = if n.norm() > 1e-9 {
            n
        } else {
            prev_joint.rotation.column(0).into_owned()
        };
        let xg = if (xg - zg * xg.dot(&zg)).norm() > 1e-9 {
            xg
        } else {
            prev_joint.rotation.column(1).into_owned()
        };
        let ra = rotation_from_xz(&(acc.rotation.transpose() * xg), &axis);
        prev_joint = acc.then(&Frame {
            rotation: ra,
            translation: Vector3::zeros(),
        });
        let range = (j.limit.lower < j.limit.upper
            && j.joint_type != urdf_rs::JointType::Continuous)
            .then_some((j.limit.lower, j.limit.upper));
        joints.push((
            j.name.clone(),
            ImportedJoint {
                kind,
                frame: acc.then(&Frame {
                    rotation: ra,
                    translation: Vector3::zeros(),
                }),
                offset: 0.0,
                range,
            },
        ));
        movable.push(j.name.clone());
        axis_frames.push(ra);
    }
    if joints.is_empty() {
        return Err(err(
            file,
            format!("no movable joint between `{base}` and `{tip}`"),
        ));
    }
    let c = UrdfChain {
        joints: chain.iter().map(|j| j.name.clone()).collect(),
        movable,
        axis_frames,
        origins,
        base: base.to_string(),
        tip: tip.to_string(),
    };
    Ok((c, joints, acc))
}

/// The bodies of a mass model ([`crate::model::robot::Elastic`]) for an imported chain, from the
/// `<inertial>` (`mass`, `origin xyz`) of the links it moves: each chain link after the first
/// movable joint, and every link hanging off one outside the chain (a gripper's fingers, a
/// camera: taken at their joints' zero values), becomes a body carried by the last movable
/// joint before it, its centre of mass in that joint's frame. The inertia tensors are not needed
/// for statics. Links without mass are left out; a mass or centre that is not finite and
/// plausible is refused with the link named.
pub fn urdf_bodies(text: &str, file: &str, import: &UrdfImport) -> Result<Vec<Body>> {
    let urdf = urdf_rs::read_from_string(text.strip_prefix('\u{feff}').unwrap_or(text))
        .map_err(|e| err(file, format!("not a valid URDF: {e}")))?;
    let link = |name: &str| urdf.links.iter().find(|l| l.name == name);
    let mut bodies = Vec::new();
    // Every chain of a tree; a joint two chains share is visited once.
    let chains: Vec<&UrdfChain> = import.branches.iter().chain([&import.chain]).collect();
    let in_a_chain = |name: &str| chains.iter().any(|c| c.joints.iter().any(|j| j == name));
    let mut visited: Vec<&str> = Vec::new();
    for chain in &chains {
        // The frame of the last movable joint at the zero configuration, and its number (1-based).
        let mut carrier: Option<(Frame, usize)> = None;
        let mut acc = Frame::identity();
        let mut movable = 0;
        for (c, name) in chain.joints.iter().enumerate() {
            let Some(j) = urdf.joints.iter().find(|j| &j.name == name) else {
                continue;
            };
            acc = acc.then(&chain.origins[c]);
            if chain.movable.get(movable) == Some(name) {
                // The robot's number of this joint (a tree numbers a branch's joints after the
                // chains before it).
                let number = import
                    .robot
                    .joint_index(name)
                    .map_or(movable + 1, |k| k + 1);
                carrier = Some((
                    acc.then(&Frame {
                        rotation: chain.axis_frames[movable],
                        translation: Vector3::zeros(),
                    }),
                    number,
                ));
                movable += 1;
            }
            let Some((frame, joint)) = &carrier else {
                continue;
            };
            if visited.contains(&name.as_str()) {
                continue;
            }
            visited.push(name);
            // The child link and everything below it that is not the chain.
            let mut stack = vec![(j.child.link.as_str(), acc)];
            while let Some((name, at)) = stack.pop() {
                if let Some(l) = link(name) {
                    let mass = l.inertial.mass.value;
                    let xyz = l.inertial.origin.xyz.0;
                    let bad = |what: String| {
                        Error::input(
                            Location::file(file).with_field(format!("link `{name}` inertial")),
                            what,
                        )
                    };
                    if !(mass.is_finite() && (0.0..=1e6).contains(&mass)) {
                        return Err(bad(format!(
                            "mass {mass} is not a finite number of kg in [0, 1e6]"
                        )));
                    }
                    if let Some(x) = xyz.iter().find(|x| !x.is_finite() || x.abs() > 1e6) {
                        return Err(bad(format!(
                            "origin {x} is not a finite number within +-1e6 m"
                        )));
                    }
                    if mass > 0.0 {
                        let global = at.translation + at.rotation * Vector3::from(xyz);
                        let local = frame.rotation.transpose() * (global - frame.translation);
                        bodies.push(Body {
                            joint: *joint,
                            mass,
                            com: local,
                        });
                    }
                }
                for k in urdf.joints.iter().filter(|k| k.parent.link == name) {
                    if in_a_chain(&k.name) {
                        continue;
                    }
                    let o = origin_frame(k.origin.xyz.0, k.origin.rpy.0);
                    stack.push((k.child.link.as_str(), at.then(&o)));
                }
            }
        }
    }
    Ok(bodies)
}

/// [`import_urdf_tree`], with the mass model of [`urdf_bodies`] when `masses` (an error when the
/// chain's links carry no mass).
pub fn import_urdf_with(
    text: &str,
    file: &str,
    base: Option<&str>,
    tips: &[&str],
    masses: bool,
) -> Result<UrdfImport> {
    let mut imported = import_urdf_tree(text, file, base, tips)?;
    if masses {
        let bodies = urdf_bodies(text, file, &imported)?;
        if bodies.is_empty() {
            return Err(err(
                file,
                "no link after the first movable joint has an <inertial> mass: there is no mass \
                 model to take",
            ));
        }
        imported.robot.elastic = Some(crate::model::robot::Elastic::new(&imported.robot, bodies));
    }
    Ok(imported)
}

/// The new origins (by joint name) that make `chain`'s URDF reproduce `robot`'s forward
/// kinematics, the tool joint to add when the tip hangs off the last movable joint, and
/// warnings for what a URDF cannot express (slopes other than 1).
pub(crate) fn export_origins(robot: &Robot, chain: &UrdfChain) -> Result<Exported> {
    export_origins_keeping(robot, chain, &|_| false)
}

/// [`export_origins`], leaving the fixed joints `shared` names (ones other chains of a tree go
/// through) as they are: a tool correction then goes into an added link.
fn export_origins_keeping(
    robot: &Robot,
    chain: &UrdfChain,
    shared: &dyn Fn(&str) -> bool,
) -> Result<Exported> {
    if robot.dof() != chain.movable.len() {
        return Err(Error::Problem(format!(
            "the robot has {} joints but the URDF chain has {} movable joints",
            robot.dof(),
            chain.movable.len()
        )));
    }
    let mut warnings = Vec::new();
    // Calibrated frames at zero readings: C'_i = L1 J1(off1) ... L_i.
    let mut c = Frame::identity();
    let mut w_frames = Vec::new(); // W_i: the frame the URDF joint must act in
    for (i, (link, joint)) in robot.links.iter().zip(&robot.joints).enumerate() {
        c = c.then(&Frame::from_link(link));
        // URDF joint values are in rad / m: a reading of one robot file unit is one unit's
        // worth of radians or metres.
        let unit_slope = robot.units.factor(joint.kind.slope());
        if let Some(c) = joint.coupling {
            // A URDF joint value is one number per joint. The coupled convention (controller J3
            // measured from the horizontal, URDF joint 3 = J2 + J3) is exact when the coupling
            // scales the other reading like the joint's own slope: the URDF joint's value is then
            // slope * (V_j + V_k), which drivers publish. Anything else cannot be written.
            if (c.factor - joint.slope).abs() > 1e-9 * joint.slope.abs().max(1e-300) {
                return Err(Error::Problem(format!(
                    "joint {} (`{}`) is coupled to joint {} with factor {} rad or m per unit but \
                     its own slope is {}: a URDF joint value is one number per joint, so only the \
                     coupled convention (factor equal to the slope: the URDF joint is the sum of \
                     the two readings, as controller drivers publish it) can be written; calibrate \
                     with the coupling factor fixed",
                    i + 1,
                    chain.movable[i],
                    c.joint + 1,
                    c.factor,
                    joint.slope
                )));
            }
            warnings.push(Warning::UrdfCoupled {
                joint: i + 1,
                name: chain.movable[i].clone(),
                other: c.joint + 1,
            });
        }
        if (joint.slope - unit_slope).abs() > 1e-12 * unit_slope {
            warnings.push(Warning::UrdfSlope {
                joint: i + 1,
                name: chain.movable[i].clone(),
                slope: joint.slope,
            });
        }
        let off = match joint.kind {
            JointKind::Revolute => Frame {
                rotation: rot_zyx(joint.offset, 0.0, 0.0),
                translation: Vector3::zeros(),
            },
            JointKind::Prismatic => Frame {
                rotation: Matrix3::identity(),
                translation: Vector3::new(0.0, 0.0, joint.offset),
            },
        };
        c = c.then(&off);
        let ra = chain.axis_frames[i];
        w_frames.push(c.then(&Frame {
            rotation: ra.transpose(),
            translation: Vector3::zeros(),
        }));
    }
    let ee = c.then(&Frame::from_link(robot.links.last().expect("links")));
    let mut out = Vec::new();
    let mut fixed_before = Frame::identity(); // fixed origins since the last movable joint
    let mut prev_w = Frame::identity();
    let mut k = 0;
    let mut tool_joint = None;
    for (name, origin) in chain.joints.iter().zip(&chain.origins) {
        if k < chain.movable.len() && *name == chain.movable[k] {
            let o = inverse(&fixed_before)
                .then(&inverse(&prev_w))
                .then(&w_frames[k]);
            out.push((name.clone(), o, *origin));
            prev_w = w_frames[k];
            fixed_before = Frame::identity();
            k += 1;
        } else {
            if k == chain.movable.len() && tool_joint.is_none() && !shared(name) {
                tool_joint = Some((out.len(), fixed_before));
                out.push((name.clone(), *origin, *origin));
            }
            fixed_before = fixed_before.then(origin);
        }
    }
    // The tool: W_n * F_after must equal the calibrated end-effector frame.
    let needed = inverse(&prev_w).then(&ee);
    let mut tool = None;
    match tool_joint {
        Some((t, before)) => {
            // F_after = A * O_t * rest (A the fixed joints kept before it); replace O_t so that
            // A * O_t' * rest = needed.
            let rest = inverse(&before.then(&out[t].1)).then(&fixed_before);
            out[t].1 = inverse(&before).then(&needed).then(&inverse(&rest));
        }
        None => {
            // The tip hangs off the last movable joint (through fixed joints left as they are):
            // an added fixed joint after the tip carries the correction.
            let needed = inverse(&fixed_before).then(&needed);
            let d = needed.translation.norm()
                + crate::model::kinematics::log_so3(&needed.rotation).norm();
            if d > 1e-12 {
                tool = Some(needed);
            }
        }
    }
    Ok(Exported {
        origins: out,
        tool,
        warnings,
    })
}

/// What a calibrated robot changes in its URDF.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct Exported {
    /// Joints whose origin is rewritten.
    pub origins: Vec<NewOrigin>,
    /// When the tip link is the child of the last movable joint and the calibrated tool frame
    /// differs from it: the origin of a fixed joint from the tip to a new link that is the
    /// calibrated tool frame.
    pub tool: Option<Frame>,
    /// What the URDF cannot express.
    pub warnings: Vec<Warning>,
}

/// A URDF number (metres, radians): below a picometre or picoradian, the rounding of the
/// chain's products, written as 0; else the shortest text that reads back to exactly `v`.
fn fmt_num(v: f64) -> String {
    use crate::units::number;
    number::write(v, number::Scale(1.0))
}

/// The URDF `rpy` of a rotation: of the two equivalent ZYX solutions, the one closer to `near`
/// (the origin's previous angles), so that a small calibration gives small changes.
pub(crate) fn rpy_near(r: &Matrix3<f64>, near: &Matrix3<f64>) -> [f64; 3] {
    use crate::units::wrap_angle;
    use std::f64::consts::PI;
    let e = euler_zyx(r);
    let n = euler_zyx(near);
    let alt = Vector3::new(
        wrap_angle(e.x + PI),
        wrap_angle(PI - e.y),
        wrap_angle(e.z + PI),
    );
    let dist = |a: &Vector3<f64>| (0..3).map(|k| wrap_angle(a[k] - n[k]).abs()).sum::<f64>();
    let best = if dist(&alt) < dist(&e) { alt } else { e };
    [best.z, best.y, best.x]
}

/// Rewrites the `<origin>` of the named joints in URDF `text`, keeping everything else. Each
/// entry is (joint name, new origin, old origin).
pub(crate) fn rewrite_origins(text: &str, file: &str, origins: &[NewOrigin]) -> Result<String> {
    let index = super::xml::scan(text, file)?;
    // (start, end, replacement), applied from the end of the text so spans stay valid.
    let mut edits: Vec<(usize, usize, String)> = Vec::new();
    for (name, f, old) in origins {
        let [roll, pitch, yaw] = rpy_near(&f.rotation, &old.rotation);
        let xyz = format!(
            "{} {} {}",
            fmt_num(f.translation.x),
            fmt_num(f.translation.y),
            fmt_num(f.translation.z)
        );
        let rpy = format!("{} {} {}", fmt_num(roll), fmt_num(pitch), fmt_num(yaw));
        let new_origin = format!("<origin xyz=\"{xyz}\" rpy=\"{rpy}\"/>");
        let joint = index
            .joint(name)
            .ok_or_else(|| err(file, format!("joint `{name}` not found in the template")))?;
        match joint.origin {
            Some((s, e)) => edits.push((s, e, new_origin)),
            None => edits.push((
                joint.after_open,
                joint.after_open,
                format!("\n    {new_origin}"),
            )),
        }
    }
    edits.sort_by_key(|e| std::cmp::Reverse(e.0));
    let mut out = text.to_string();
    for (s, e, r) in edits {
        out.replace_range(s..e, &r);
    }
    Ok(out)
}

/// A URDF export: the text, its warnings, and what it reproduces of the robot.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct UrdfExport {
    /// The URDF.
    pub text: String,
    /// What it cannot express, or added.
    pub warnings: Vec<Warning>,
    /// The text read back ([`import_urdf`], from the same base to the tip, or to the added
    /// calibrated tool link) and compared with the robot: the URDF's joint values are the
    /// readings in radians and metres (for a joint coupled by the sum convention, plus the other
    /// joint's reading).
    pub read_back: ReadBack,
    /// What the URDF cannot hold (slopes other than 1), each with its deviation.
    pub lost: Vec<Lost>,
}

impl UrdfExport {
    /// `Ok` when the URDF reproduces `robot` within `tolerance`.
    pub fn check(&self, robot: &Robot, tolerance: &Tolerance) -> Result<()> {
        self.read_back.check(
            tolerance,
            robot.units,
            "the URDF (its joint values are the readings: it cannot scale them)",
            &self.lost,
        )
    }
}

/// Writes `robot` (calibrated) into the URDF `template`: the chain from `base` to `tip` is
/// re-imported from the template to know its structure. Only origins change, except when the
/// tip link is the child of the last movable joint: then a fixed joint `<tip>_calibrated_joint`
/// and a link `<tip>_calibrated` are added after the tip, and that new link is the calibrated
/// tool frame (a warning names it). A joint without an `<origin>` gets one; a byte-order mark
/// is kept. The text is read back and compared with the robot ([`UrdfExport::read_back`]).
///
/// A tree (several `tips`, as [`import_urdf_tree`] imported it) is written chain by chain: each
/// tip's chain takes the robot's branch to that tool frame ([`Robot::branch`]), the joints two
/// chains share get the same origin from both, and each chain is read back.
pub fn export_urdf(
    robot: &Robot,
    template: &str,
    file: &str,
    base: Option<&str>,
    tips: &[&str],
) -> Result<UrdfExport> {
    let imported = import_urdf_tree(template, file, base, tips)?;
    if imported.robot.dof() != robot.dof() || imported.robot.sites.len() > robot.sites.len() {
        return Err(Error::Problem(format!(
            "the robot has {} joints and {} sites, but the URDF's tree to {} has {} movable \
             joints and {} other tips",
            robot.dof(),
            robot.sites.len(),
            tips.join(", "),
            imported.robot.dof(),
            imported.robot.sites.len()
        )));
    }
    // Each chain with the robot's branch to its tool frame: the sites first, as imported.
    let chains = imported.chains();
    let mut origins: Vec<NewOrigin> = Vec::new();
    let mut warnings: Vec<Warning> = Vec::new();
    let mut tools = Vec::new();
    let mut branches = Vec::new();
    for &(chain, site) in &chains {
        let (serial, path) = robot.branch(site).map_err(Error::Problem)?;
        let others = |name: &str| {
            chains
                .iter()
                .any(|(c, _)| c.tip != chain.tip && c.joints.iter().any(|j| j == name))
        };
        let mut e = export_origins_keeping(&serial, chain, &others)?;
        for (name, o, old) in e.origins.drain(..) {
            match origins.iter().find(|(n, _, _)| *n == name) {
                None => origins.push((name, o, old)),
                Some((_, first, _)) => {
                    let apart = (first.translation - o.translation).norm()
                        + crate::model::kinematics::log_so3(
                            &(first.rotation.transpose() * o.rotation),
                        )
                        .norm();
                    if apart > 1e-9 {
                        return Err(Error::Problem(format!(
                            "joint `{name}` is shared by two chains of the tree but their \
                             calibrations give it different origins"
                        )));
                    }
                }
            }
        }
        for mut w in e.warnings {
            // Numbered as the robot numbers its joints, not as the branch does.
            match &mut w {
                Warning::UrdfSlope { joint, .. } => *joint = path[*joint - 1] + 1,
                Warning::UrdfCoupled { joint, other, .. } => {
                    *joint = path[*joint - 1] + 1;
                    *other = path[*other - 1] + 1;
                }
                _ => {}
            }
            if !warnings.contains(&w) {
                warnings.push(w);
            }
        }
        tools.push(e.tool);
        branches.push((serial, path));
    }
    let mut text = rewrite_origins(template, file, &origins)?;
    let mut read_tips = Vec::new();
    for (&(chain, _), tool) in chains.iter().zip(&tools) {
        let mut read_tip = chain.tip.clone();
        if let Some(tool) = tool {
            let tip = &chain.tip;
            let link = format!("{tip}_calibrated");
            let [roll, pitch, yaw] = rpy_near(&tool.rotation, &Matrix3::identity());
            let block = format!(
                "  <!-- Added by kinecal export: the calibrated tool frame. -->\n  <link name=\"{link}\"/>\n  \
                 <joint name=\"{link}_joint\" type=\"fixed\">\n    <parent link=\"{tip}\"/>\n    \
                 <child link=\"{link}\"/>\n    <origin xyz=\"{} {} {}\" rpy=\"{} {} {}\"/>\n  </joint>\n",
                fmt_num(tool.translation.x),
                fmt_num(tool.translation.y),
                fmt_num(tool.translation.z),
                fmt_num(roll),
                fmt_num(pitch),
                fmt_num(yaw)
            );
            let end = super::xml::scan(&text, file)?
                .robot_end
                .ok_or_else(|| err(file, "no </robot> to add the tool joint before"))?;
            text.insert_str(end, &block);
            warnings.push(Warning::UrdfToolAdded { link: link.clone() });
            read_tip = link;
        }
        read_tips.push(read_tip);
    }
    // Each chain read back from the text as written, against the robot's branch to it.
    let mut read_back = ReadBack {
        position: 0.0,
        attitude: 0.0,
        postures: 0,
    };
    for ((&(chain, _), read_tip), (serial, _)) in chains.iter().zip(&read_tips).zip(&branches) {
        let back = import_urdf(
            &text,
            &format!("{file} (as written)"),
            Some(&chain.base),
            Some(read_tip),
        )?
        .robot;
        // The URDF's joint values: the readings in radians and metres, plus the other joint's
        // for a joint coupled by the sum convention (the only coupling written).
        let scale = readback::unit_scale(serial, Units::default());
        let couplings: Vec<Option<usize>> = serial
            .joints
            .iter()
            .map(|j| j.coupling.map(|c| c.joint))
            .collect();
        let r = readback::compare(
            serial,
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
    let names: Vec<String> = imported
        .robot
        .joints
        .iter()
        .enumerate()
        .map(|(j, joint)| {
            joint
                .name
                .clone()
                .unwrap_or_else(|| format!("joint{}", j + 1))
        })
        .collect();
    let lost = readback::gains_lost(
        robot,
        &|j| format!("joint {} (`{}`)", j + 1, names[j]),
        &|_| true,
    );
    Ok(UrdfExport {
        text,
        warnings,
        read_back,
        lost,
    })
}
