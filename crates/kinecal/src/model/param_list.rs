//! Parameter lists as users write them: comma-separated ids (`p3`), ranges (`p1-p30`), names
//! (`link1.x`, `joint3.offset`, `joint4.slope`, `joint3.coupling`, `site.NAME.x`,
//! `plane.NAME.offset`, `session.NAME.x`, `joint2.compliance`, `joint2.lateral`), whole links,
//! joints, sites, planes or sessions (`link2`, `joint3` = its offset, slope and coupling,
//! `site.NAME`, `plane.NAME`, `session.NAME`) and the groups `all`, `links`, `offsets`, `slopes`,
//! `couplings`, `sites`, `planes`, `sessions`, `compliance`, `lateral` and `masses` (every
//! body's mass and centre, `body2.mass`, `body2.x`, `body2` its four). The two compliance
//! groups leave out the joints gravity cannot load ([`crate::model::kinematics::gravity_free_joints`]:
//! a vertical first axis): name such a joint's compliance to ask for it anyway.
//!
//! Cameras and boards ([`crate::model::camera`]): `NAME.x .. NAME.gamma` (a camera's or board's
//! pose), `NAME.fx, NAME.fy, NAME.cx, NAME.cy, NAME.k1, NAME.k2, NAME.p1, NAME.p2, NAME.k3` (a
//! camera's lens), `NAME` (all of a camera's or board's), and the groups `cameras` (every
//! camera's 15), `intrinsics` (every camera's lens), `extrinsics` (every camera's pose) and
//! `boards` (every board's pose).

use crate::error::{Error, Result};
use crate::model::params::{CameraComponent, LinkComponent, ParamId, ParamKind, PlaneComponent};
use crate::model::robot::Robot;

/// Parses a comma-separated parameter list (see the module docs) into sorted, distinct ids.
pub fn parse_param_list(list: &str, robot: &Robot) -> Result<Vec<ParamId>> {
    let err = |message: String| Error::ParamList {
        list: list.to_string(),
        message,
    };
    let mut out = Vec::new();
    for token in list.split(',').map(str::trim) {
        if token.is_empty() {
            return Err(err("empty entry".into()));
        }
        out.extend(parse_token(token, robot).map_err(err)?);
    }
    out.sort();
    out.dedup();
    Ok(out)
}

/// The words a parameter list takes for groups of parameters (`identifiable` is the selection's,
/// [`crate::workflow::Selection::parse`]).
const GROUP_WORDS: [&str; 16] = [
    "identifiable",
    "all",
    "links",
    "offsets",
    "slopes",
    "couplings",
    "sites",
    "planes",
    "sessions",
    "compliance",
    "lateral",
    "masses",
    "cameras",
    "intrinsics",
    "extrinsics",
    "boards",
];

/// The group word `token` most likely mistypes: the nearest of [`GROUP_WORDS`] within two
/// edits (insertions, deletions, substitutions; case ignored), when there is one.
fn did_you_mean(token: &str) -> Option<&'static str> {
    let token = token.to_ascii_lowercase();
    let distance = |a: &str, b: &str| -> usize {
        let b: Vec<char> = b.chars().collect();
        let mut row: Vec<usize> = (0..=b.len()).collect();
        for (i, ca) in a.chars().enumerate() {
            let mut diagonal = row[0];
            row[0] = i + 1;
            for (j, &cb) in b.iter().enumerate() {
                let above = row[j + 1];
                row[j + 1] = (diagonal + usize::from(ca != cb))
                    .min(above + 1)
                    .min(row[j] + 1);
                diagonal = above;
            }
        }
        row[b.len()]
    };
    GROUP_WORDS
        .iter()
        .map(|w| (distance(&token, w), *w))
        .filter(|&(d, _)| d > 0 && d <= 2)
        .min_by_key(|&(d, _)| d)
        .map(|(_, w)| w)
}

/// Parses one parameter reference (an id or a name) to exactly one parameter.
pub(crate) fn parse_param(token: &str, robot: &Robot) -> Result<ParamId> {
    let ids = parse_token(token, robot).map_err(|message| Error::ParamList {
        list: token.to_string(),
        message,
    })?;
    match ids.as_slice() {
        [one] => Ok(*one),
        _ => Err(Error::ParamList {
            list: token.to_string(),
            message: "names several parameters where one is expected".into(),
        }),
    }
}

/// The parameters one reference names: a group word, an id or a range of ids, or a name.
fn parse_token(token: &str, robot: &Robot) -> std::result::Result<Vec<ParamId>, String> {
    let all: Vec<ParamId> = robot.param_ids().collect();
    if let Some(ids) = group(token, robot, &all) {
        return ids;
    }
    if let Some(ids) = numbered(token, all.len()) {
        return ids;
    }
    if let Some(ids) = frame_named(token, robot) {
        return ids;
    }
    let (head, comp) = match token.split_once('.') {
        Some((h, c)) => (h, Some(c)),
        None => (token, None),
    };
    if let Some(ids) = camera_or_board(token, head, comp, robot) {
        return ids;
    }
    if let Some(num) = head.strip_prefix("body") {
        return body_params(token, num, comp, robot);
    }
    if let Some(num) = head.strip_prefix("link") {
        return link_params(token, num, comp, robot);
    }
    if let Some(num) = head.strip_prefix("joint") {
        return joint_params(token, num, comp, robot);
    }
    Err(unknown(token))
}

/// A group word's parameters (`all`, `links`, `offsets`, ..., `compliance`, `lateral`; empty
/// when the robot has none of the kind), or an error for `cameras`, `intrinsics`,
/// `extrinsics`, `boards`, `masses`, `compliance` or `lateral` on a robot without cameras,
/// boards or a mass model; `None` for any other token (`identifiable` among them: the selection
/// resolves it, not this list).
fn group(
    token: &str,
    robot: &Robot,
    all: &[ParamId],
) -> Option<std::result::Result<Vec<ParamId>, String>> {
    let pick = |f: &dyn Fn(ParamKind) -> bool| -> Vec<ParamId> {
        all.iter()
            .copied()
            .filter(|&p| f(robot.param_kind(p)))
            .collect()
    };
    Some(Ok(match token {
        "all" => all.to_vec(),
        "links" => pick(&|k| matches!(k, ParamKind::Link { .. })),
        "offsets" => pick(&|k| matches!(k, ParamKind::Offset { .. })),
        "slopes" => pick(&|k| matches!(k, ParamKind::Slope { .. })),
        "sites" => pick(&|k| matches!(k, ParamKind::Site { .. })),
        "couplings" => pick(&|k| matches!(k, ParamKind::Coupling { .. })),
        "planes" => pick(&|k| matches!(k, ParamKind::Plane { .. })),
        "sessions" => pick(&|k| matches!(k, ParamKind::Session { .. })),
        "cameras" | "intrinsics" | "extrinsics" | "boards" => {
            let (cameras, boards) = (robot.cameras.is_empty(), robot.boards.is_empty());
            if token == "boards" && boards || token != "boards" && cameras {
                let what = if token == "boards" {
                    "boards"
                } else {
                    "cameras"
                };
                return Some(Err(format!(
                    "`{token}`: the robot has no {what} (add `[[{what}]]` to the robot file)"
                )));
            }
            pick(&|k| match k {
                ParamKind::Camera { component, .. } => match token {
                    "cameras" => true,
                    "intrinsics" => component.is_intrinsic(),
                    "extrinsics" => !component.is_intrinsic(),
                    _ => false,
                },
                ParamKind::Board { .. } => token == "boards",
                _ => false,
            })
        }
        "masses" => {
            if robot.elastic.is_none() {
                return Some(Err(format!(
                    "`{token}`: the robot has no mass model (add `[[bodies]]` to the robot file)"
                )));
            }
            pick(&|k| matches!(k, ParamKind::Body { .. }))
        }
        "compliance" | "lateral" => {
            if robot.elastic.is_none() {
                return Some(Err(format!(
                    "`{token}`: the robot has no mass model (add `[[bodies]]` with masses and \
                     centres of mass to the robot file, or import a URDF with <inertial>)"
                )));
            }
            let free = crate::model::kinematics::gravity_free_joints(robot);
            let lateral = token == "lateral";
            pick(&|k| match k {
                ParamKind::Compliance { joint } => !lateral && !free.joint.contains(&joint),
                ParamKind::Lateral { joint } => lateral && !free.lateral.contains(&joint),
                _ => false,
            })
        }
        _ => return None,
    }))
}

/// An id (`p3`) or a range of ids (`p1-p30`) of a robot with `count` parameters; `None` when
/// `token` is neither.
fn numbered(token: &str, count: usize) -> Option<std::result::Result<Vec<ParamId>, String>> {
    let p_number = |s: &str| -> Option<std::result::Result<ParamId, String>> {
        let digits = s.strip_prefix('p').or_else(|| s.strip_prefix('P'))?;
        let n: usize = digits.parse().ok()?;
        Some(if n >= 1 && n <= count {
            Ok(ParamId(n - 1))
        } else {
            Err(format!(
                "`{s}` is out of range: this robot has parameters p1..p{count}"
            ))
        })
    };
    if let Some((a, b)) = token.split_once('-') {
        if let (Some(a), Some(b)) = (p_number(a), p_number(b)) {
            return Some((|| {
                let (a, b) = (a?, b?);
                if a > b {
                    return Err(format!("range `{token}` runs backwards"));
                }
                Ok((a.0..=b.0).map(ParamId).collect())
            })());
        }
    }
    p_number(token).map(|p| p.map(|p| vec![p]))
}

/// A site's, session's or plane's parameters (`site.NAME.x`, `session.NAME`,
/// `plane.NAME.offset`; without a component, all of its), or an error naming what the robot
/// lacks; `None` when `token` has none of the prefixes `site.`, `session.` or `plane.`.
fn frame_named(token: &str, robot: &Robot) -> Option<std::result::Result<Vec<ParamId>, String>> {
    let id = |k: ParamKind| robot.param_id(k);
    // The name and the component: a last dot-separated part that `parse` takes is one.
    fn split<'t>(rest: &'t str, parse: &dyn Fn(&str) -> bool) -> (&'t str, Option<&'t str>) {
        match rest.rsplit_once('.') {
            Some((n, c)) if parse(c) => (n, Some(c)),
            _ => (rest, None),
        }
    }
    if let Some(rest) = token.strip_prefix("site.") {
        let (name, comp) = split(rest, &|c| LinkComponent::parse(c).is_some());
        let Some(site) = robot.site_index(name) else {
            return Some(Err(format!(
                "`{token}`: the robot has no site named `{name}`"
            )));
        };
        return Some(Ok(match comp.and_then(LinkComponent::parse) {
            Some(component) => vec![id(ParamKind::Site { site, component })],
            None => LinkComponent::ALL
                .map(|component| id(ParamKind::Site { site, component }))
                .to_vec(),
        }));
    }
    if let Some(rest) = token.strip_prefix("session.") {
        let (name, comp) = split(rest, &|c| LinkComponent::parse(c).is_some());
        let Some(session) = robot.session_index(name) else {
            return Some(Err(format!(
                "`{token}`: the robot has no session named `{name}`"
            )));
        };
        return Some(Ok(match comp.and_then(LinkComponent::parse) {
            Some(component) => vec![id(ParamKind::Session { session, component })],
            None => LinkComponent::ALL
                .map(|component| id(ParamKind::Session { session, component }))
                .to_vec(),
        }));
    }
    let rest = token.strip_prefix("plane.")?;
    let (name, comp) = split(rest, &|c| PlaneComponent::parse(c).is_some());
    let Some(plane) = robot.plane_index(name) else {
        return Some(Err(format!(
            "`{token}`: the robot has no plane named `{name}`"
        )));
    };
    Some(Ok(match comp.and_then(PlaneComponent::parse) {
        Some(component) => vec![id(ParamKind::Plane { plane, component })],
        None => PlaneComponent::ALL
            .map(|component| id(ParamKind::Plane { plane, component }))
            .to_vec(),
    }))
}

/// A camera's or board's parameters (`NAME`, `NAME.fx`); `None` when `head` names neither.
fn camera_or_board(
    token: &str,
    head: &str,
    comp: Option<&str>,
    robot: &Robot,
) -> Option<std::result::Result<Vec<ParamId>, String>> {
    let id = |k: ParamKind| robot.param_id(k);
    if let Some(camera) = robot.camera_index(head) {
        return Some(match comp {
            None => Ok(CameraComponent::ALL
                .map(|component| id(ParamKind::Camera { camera, component }))
                .to_vec()),
            Some(c) => {
                let component = CameraComponent::parse(c).ok_or_else(|| {
                    format!(
                        "`{token}`: unknown camera parameter `{c}` (expected x, y, z, alpha, beta, \
                         gamma, fx, fy, cx, cy, k1, k2, p1, p2 or k3)"
                    )
                });
                component.map(|component| vec![id(ParamKind::Camera { camera, component })])
            }
        });
    }
    let board = robot.board_index(head)?;
    Some(match comp {
        None => Ok(LinkComponent::ALL
            .map(|component| id(ParamKind::Board { board, component }))
            .to_vec()),
        Some(c) => {
            let component = LinkComponent::parse(c).ok_or_else(|| {
                format!(
                    "`{token}`: unknown board parameter `{c}` (expected x, y, z, alpha, beta \
                     or gamma)"
                )
            });
            component.map(|component| vec![id(ParamKind::Board { board, component })])
        }
    })
}

/// The 0-based index of `what` number `num` (1-based, as written) of `max`.
fn index_of(token: &str, what: &str, num: &str, max: usize) -> std::result::Result<usize, String> {
    let i = num.parse::<usize>().map_err(|_| unknown(token))?;
    if i == 0 || i > max {
        return Err(format!(
            "`{token}`: {what} `{num}` does not exist (this robot has {what}s 1..{max})"
        ));
    }
    Ok(i - 1)
}

/// A body's mass-model parameters (`body2`, `body2.mass`).
fn body_params(
    token: &str,
    num: &str,
    comp: Option<&str>,
    robot: &Robot,
) -> std::result::Result<Vec<ParamId>, String> {
    use crate::model::params::BodyComponent;
    let body = index_of(token, "body", num, robot.body_count())?;
    let id = |component| robot.param_id(ParamKind::Body { body, component });
    match comp {
        None => Ok(BodyComponent::ALL.map(id).to_vec()),
        Some(c) => {
            let component = BodyComponent::parse(c).ok_or_else(|| {
                format!("`{token}`: unknown body component `{c}` (expected mass, x, y or z)")
            })?;
            Ok(vec![id(component)])
        }
    }
}

/// A link's parameters (`link3`, `link3.x`).
fn link_params(
    token: &str,
    num: &str,
    comp: Option<&str>,
    robot: &Robot,
) -> std::result::Result<Vec<ParamId>, String> {
    let link = index_of(token, "link", num, robot.links.len())?;
    let id = |component| robot.param_id(ParamKind::Link { link, component });
    match comp {
        None => Ok(LinkComponent::ALL.map(id).to_vec()),
        Some(c) => {
            let component = LinkComponent::parse(c).ok_or_else(|| {
                format!("`{token}`: unknown link component `{c}` (expected x, y, z, alpha, beta or gamma)")
            })?;
            Ok(vec![id(component)])
        }
    }
}

/// A joint's parameters (`joint2`: its offset and slope, and its coupling when it is coupled;
/// `joint2.offset`, `.slope`, `.coupling`, `.compliance`, `.lateral`).
fn joint_params(
    token: &str,
    num: &str,
    comp: Option<&str>,
    robot: &Robot,
) -> std::result::Result<Vec<ParamId>, String> {
    let joint = index_of(token, "joint", num, robot.joints.len())?;
    let id = |k: ParamKind| robot.param_id(k);
    let coupled = robot.joints[joint].coupling.is_some();
    match comp {
        None => {
            let mut v = vec![
                id(ParamKind::Offset { joint }),
                id(ParamKind::Slope { joint }),
            ];
            if coupled {
                v.push(id(ParamKind::Coupling { joint }));
            }
            Ok(v)
        }
        Some("offset") => Ok(vec![id(ParamKind::Offset { joint })]),
        Some("slope") => Ok(vec![id(ParamKind::Slope { joint })]),
        Some("coupling") if coupled => Ok(vec![id(ParamKind::Coupling { joint })]),
        Some("coupling") => Err(format!(
            "`{token}`: joint {} is not coupled to another joint (add `coupling = {{ joint = K, \
             factor = F }}` to it in the robot file)",
            joint + 1
        )),
        Some(c @ ("compliance" | "lateral")) => {
            if robot.compliant_joints().any(|j| j == joint) {
                Ok(vec![id(if c == "compliance" {
                    ParamKind::Compliance { joint }
                } else {
                    ParamKind::Lateral { joint }
                })])
            } else if robot.elastic.is_none() {
                Err(format!(
                    "`{token}`: the robot has no mass model (add `[[bodies]]` to the robot \
                     file)"
                ))
            } else {
                Err(format!(
                    "`{token}`: joint {} is prismatic: only revolute joints have compliances",
                    joint + 1
                ))
            }
        }
        Some(c) => Err(format!(
            "`{token}`: unknown joint parameter `{c}` (expected offset, slope, coupling, \
             compliance or lateral)"
        )),
    }
}

/// The error for a reference that names no parameter, with the closest word when there is one.
fn unknown(token: &str) -> String {
    let hint = did_you_mean(token)
        .map(|w| format!(": did you mean `{w}`?"))
        .unwrap_or_default();
    format!(
        "unknown parameter `{token}`{hint} (expected an id like p3, a range like p1-p30, a \
         name like link1.x, joint2.offset, joint2.slope, joint3.coupling, site.NAME.x, \
         plane.NAME.offset, session.NAME.x or joint2.compliance, or one of {}, or a \
         camera's or board's NAME.x, NAME.fx)",
        GROUP_WORDS.join(", ")
    )
}
