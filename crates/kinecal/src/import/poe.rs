//! Product-of-exponentials models: `T(q) = exp([S1] q1) ... exp([Sn] qn) M`.
//!
//! File (TOML, in its own units):
//!
//! ```toml
//! name = "QKM HL6"
//! length_unit = "mm"
//! angle_unit = "deg"
//! [[joints]]
//! kind = "revolute"            # or "prismatic"
//! axis = [0, 0, 1]             # direction at the zero configuration (any length)
//! point = [-590, 410, 300]     # a point on the axis (revolute; ignored for prismatic)
//! offset = 0                   # joint value at zero reading; default 0
//! min = -147                   # optional reading range
//! max = 111
//! coupling = { joint = 2, factor = 1 }  # optional: the joint value also adds factor * V2
//! [tool]                       # the tool frame M at the zero configuration
//! position = [-240, 410, 841]
//! euler = [0, 0, 0]            # ZYX alpha, beta, gamma; default: the last joint frame's
//! [[sites]]                    # optional measured frames, rigidly attached after `joint`
//! name = "smr1"
//! joint = 6                    # default: the last joint
//! position = [-100, 400, 900]  # at the zero configuration, global frame
//! euler = [0, 0, 0]            # optional; default: the frame of its joint
//! ```
//!
//! Joint frames are placed on the axes with local z along the axis, the x axis along the common
//! normal with the previous joint's z (for parallel axes, the previous x), and the origin at the
//! foot of that common normal. This keeps every interior link's beta at 0, away from the Euler
//! singularity at +-90 deg, and gives link lengths their physical meaning. The tool and the
//! sites take the orientation of the joint frame they follow unless `euler` is given, so their
//! angles are 0 too; given angles are the user's, whatever their beta. Readings are the joint
//! values minus `offset` (slope 1 in the file's units).

use nalgebra::Vector3;
use toml_edit::Table;

use super::{chain_from_frames, inverse, link_of, rotation_from_xz, ImportedJoint};
use crate::error::{Error, Location, Result};
use crate::model::kinematics::{rot_zyx, Frame};
use crate::model::robot::{JointKind, Robot, Site};
use crate::model::robot_file::Reader;
use crate::units::{Quantity, Units};

/// Places joint frames on the given axes (global frame, zero configuration), as described in the
/// module docs. `axes[i] = (kind, direction, point)`.
pub(crate) fn joint_frames(axes: &[(JointKind, Vector3<f64>, Vector3<f64>)]) -> Vec<Frame> {
    let mut prev = Frame::identity();
    let mut out = Vec::with_capacity(axes.len());
    for (kind, dir, point) in axes {
        let z = dir.normalize();
        let pz = prev.rotation.column(2).into_owned();
        let po = prev.translation;
        let n = pz.cross(&z);
        // A prismatic joint's axis has no location: keep the previous origin.
        let point = if *kind == JointKind::Prismatic {
            po
        } else {
            *point
        };
        let (x, origin) = if n.norm() > 1e-9 {
            // Foot of the common normal on this axis.
            let w = po - point;
            let (a, b, c) = (pz.dot(&pz), pz.dot(&z), z.dot(&z));
            let (d, e) = (pz.dot(&w), z.dot(&w));
            let t = (a * e - b * d) / (a * c - b * b);
            (n.normalize(), point + z * t)
        } else {
            let px = prev.rotation.column(0).into_owned();
            let x = if (px - z * px.dot(&z)).norm() > 1e-9 {
                px
            } else {
                prev.rotation.column(1).into_owned()
            };
            (x, point + z * (po - point).dot(&z))
        };
        let f = Frame {
            rotation: rotation_from_xz(&x, &z),
            translation: origin,
        };
        out.push(f);
        prev = f;
    }
    out
}

/// The frame at `position` with ZYX `euler` angles; without `euler`, oriented as `default` (the
/// frame of the joint it follows, so that its link's angles are 0, away from +-90 deg).
fn frame_at(
    r: &Reader<'_>,
    t: &Table,
    what: &str,
    units: &Units,
    default: &nalgebra::Matrix3<f64>,
) -> Result<Frame> {
    let p = r
        .vec3(t, "position", &format!("{what}.position"))?
        .ok_or_else(|| {
            r.err(
                t.span(),
                &format!("{what}.position"),
                "missing `position = [x, y, z]`",
            )
        })?;
    let a = |v: f64| units.to_si(Quantity::Angle, v);
    let rotation = match r.vec3(t, "euler", &format!("{what}.euler"))? {
        Some(e) => rot_zyx(a(e[0]), a(e[1]), a(e[2])),
        None => *default,
    };
    Ok(Frame {
        rotation,
        translation: Vector3::from(p.map(|v| units.to_si(Quantity::Length, v))),
    })
}

/// Parses a product-of-exponentials file into a robot with the same forward kinematics.
pub fn parse_poe_toml(text: &str, file: &str) -> Result<Robot> {
    let r = Reader { text, file };
    let doc = r.parse()?;
    let root = doc.as_table();
    r.check_keys(
        root,
        &[
            "name",
            "length_unit",
            "angle_unit",
            "joints",
            "tool",
            "sites",
        ],
        "file",
    )?;
    let name = r.string(root, "name", "name")?.unwrap_or("").to_string();
    let units = r.units(root)?;
    let len = |v: [f64; 3]| Vector3::from(v.map(|x| units.to_si(Quantity::Length, x)));
    let mut axes = Vec::new();
    let mut extra = Vec::new();
    let mut couplings = Vec::new();
    let joint_tables = r.tables(root, "joints")?;
    let joint_count = joint_tables.len();
    for (i, t) in joint_tables.iter().enumerate() {
        let t: &Table = t;
        let what = format!("joints[{i}]");
        r.check_keys(
            t,
            &["kind", "axis", "point", "offset", "min", "max", "coupling"],
            &what,
        )?;
        let kind = match r.string(t, "kind", &format!("{what}.kind"))? {
            Some("revolute") => JointKind::Revolute,
            Some("prismatic") => JointKind::Prismatic,
            other => {
                return Err(r.err(
                    t.get("kind").and_then(toml_edit::Item::span).or(t.span()),
                    &format!("{what}.kind"),
                    format!("expected \"revolute\" or \"prismatic\", found {other:?}"),
                ))
            }
        };
        let axis = r.vec3(t, "axis", &format!("{what}.axis"))?.ok_or_else(|| {
            r.err(
                t.span(),
                &format!("{what}.axis"),
                "missing `axis = [x, y, z]`",
            )
        })?;
        if Vector3::from(axis).norm() < 1e-12 {
            return Err(r.err(
                t.get("axis").and_then(toml_edit::Item::span),
                &format!("{what}.axis"),
                "the axis is the zero vector",
            ));
        }
        let point = match (kind, r.vec3(t, "point", &format!("{what}.point"))?) {
            (_, Some(p)) => len(p),
            (JointKind::Prismatic, None) => Vector3::zeros(),
            (JointKind::Revolute, None) => {
                return Err(r.err(
                    t.span(),
                    &format!("{what}.point"),
                    "a revolute joint needs `point = [x, y, z]` on its axis",
                ))
            }
        };
        let offset = r
            .number(t, "offset", &format!("{what}.offset"))?
            .unwrap_or(0.0);
        let (min, max) = (
            r.number(t, "min", &format!("{what}.min"))?,
            r.number(t, "max", &format!("{what}.max"))?,
        );
        let range = match (min, max) {
            (Some(a), Some(b)) if a < b => Some((a, b)),
            (None, None) => None,
            _ => return Err(r.err(t.span(), &what, "give both `min` < `max`, or neither")),
        };
        axes.push((kind, Vector3::from(axis), point));
        extra.push((units.to_si(kind.variable(), offset), range));
        couplings.push(r.coupling(t, &what, kind, &units, (i, joint_count))?);
    }
    if axes.is_empty() {
        return Err(Error::input(Location::file(file), "no [[joints]]"));
    }
    let frames = joint_frames(&axes);
    let tool = match r.table(root, "tool")? {
        Some(t) => {
            r.check_keys(&t, &["position", "euler"], "tool")?;
            let last = frames.last().expect("at least one joint").rotation;
            frame_at(&r, &t, "tool", &units, &last)?
        }
        None => {
            return Err(r.err(
                None,
                "tool",
                "missing [tool] table with the tool frame at zero",
            ))
        }
    };
    let joints: Vec<ImportedJoint> = frames
        .iter()
        .zip(&axes)
        .zip(&extra)
        .map(|((f, a), e)| ImportedJoint {
            kind: a.0,
            frame: *f,
            offset: e.0,
            range: e.1,
        })
        .collect();
    let mut robot = chain_from_frames(&name, units, &joints, &tool);
    for (j, c) in robot.joints.iter_mut().zip(couplings) {
        j.coupling = c;
    }
    for (i, t) in r.tables(root, "sites")?.iter().enumerate() {
        let t: &Table = t;
        let what = format!("sites[{i}]");
        r.check_keys(t, &["name", "joint", "position", "euler"], &what)?;
        let name = r
            .string(t, "name", &format!("{what}.name"))?
            .ok_or_else(|| r.err(t.span(), &format!("{what}.name"), "missing `name`"))?
            .to_string();
        let joint = match t.get("joint") {
            None => frames.len(),
            Some(item) => match item.as_integer() {
                Some(j) if j >= 1 && (j as usize) <= frames.len() => j as usize,
                _ => {
                    return Err(r.err(
                        item.span(),
                        &format!("{what}.joint"),
                        format!("expected a joint number 1..{}", frames.len()),
                    ))
                }
            },
        };
        let global = frame_at(&r, t, &what, &units, &frames[joint - 1].rotation)?;
        robot.sites.push(Site {
            name,
            joint,
            frame: link_of(&inverse(&frames[joint - 1]).then(&global)),
        });
    }
    robot
        .validate()
        .map_err(|m| Error::input(Location::file(file), m))?;
    Ok(robot)
}
