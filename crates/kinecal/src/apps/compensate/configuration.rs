//! Configurations (branches) of an arm: which of the solutions of one Cartesian goal a
//! controller means.
//!
//! Two ways to name one:
//!
//! - For an arm of six revolute joints, the words industrial controllers use, each defined by
//!   the geometry of the solution (not by a particular brand's joint zeros):
//!   - `shoulder=front|back`: the *wrist centre* `W` (the point of joint 5's axis nearest joint
//!     4's axis) on the side of joint 1's axis where it is at the robot file's zero posture (all
//!     joint values 0), turned with joint 1 (`front`), or on the other side (`back`, reaching
//!     over the base). Measured in the plane perpendicular to joint 1's axis.
//!   - `elbow=up|down`: a point of joint 3's axis (the elbow) above (`up`) or below the line
//!     from a point of joint 2's axis (the shoulder) to `W`, "above" meaning along the base
//!     frame's +z (a ceiling-mounted arm has them the other way round). The points are taken
//!     in the plane perpendicular to joint 2's axis.
//!   - `wrist=noflip|flip`: the sign of `sin q5`, `q5` joint 5's angle (`q = offset + slope V`):
//!     `noflip` for `sin q5 >= 0`. The wrist is singular where `sin q5 = 0` on the arms this
//!     names (spherical wrists and UR-style wrists alike).
//! - For any robot, a sign pattern, one entry per joint: `+` (the joint's value, a revolute
//!   angle taken in (-180 deg, 180 deg], at least 0), `-` (below 0) or `*` (either).
//!
//! Written `shoulder=front,elbow=up,wrist=noflip` (any subset) or `+,*,-,*,+,*`.

use std::fmt;

use nalgebra::Vector3;

use crate::error::{Error, Result, Setting};
use crate::model::kinematics::{Chain, Workspace};
use crate::model::robot::{JointKind, Robot};

/// A side of a named configuration; `None` in [`Configuration::Arm`] means either.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    /// `front`, `up` or `noflip`.
    First,
    /// `back`, `down` or `flip`.
    Second,
}

/// A configuration a solution must be in.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Configuration {
    /// The named configuration of a 6R arm (see the module's documentation).
    Arm {
        /// `front` (First) or `back` (Second).
        shoulder: Option<Side>,
        /// `up` (First) or `down` (Second).
        elbow: Option<Side>,
        /// `noflip` (First) or `flip` (Second).
        wrist: Option<Side>,
    },
    /// One sign per joint: `Some(true)` for at least 0, `Some(false)` below 0, `None` either.
    Signs(Vec<Option<bool>>),
}

impl Configuration {
    /// Parses `shoulder=front,elbow=up,wrist=noflip` (any subset) or a sign pattern `+,-,*`.
    pub fn parse(text: &str) -> Result<Configuration> {
        let bad = |message: String| Error::InvalidOption {
            setting: Setting::Configuration,
            message,
        };
        let text = text.trim();
        if text.contains('=') {
            let (mut shoulder, mut elbow, mut wrist) = (None, None, None);
            for part in text.split(',') {
                let (key, value) = part
                    .split_once('=')
                    .ok_or_else(|| bad(format!("`{part}`: expected key=value (e.g. elbow=up)")))?;
                let (slot, first, second) = match key.trim() {
                    "shoulder" => (&mut shoulder, "front", "back"),
                    "elbow" => (&mut elbow, "up", "down"),
                    "wrist" => (&mut wrist, "noflip", "flip"),
                    other => {
                        return Err(bad(format!(
                            "unknown part `{other}`: expected shoulder, elbow or wrist"
                        )))
                    }
                };
                if slot.is_some() {
                    return Err(bad(format!("`{}` given twice", key.trim())));
                }
                *slot = Some(match value.trim() {
                    v if v == first => Side::First,
                    v if v == second => Side::Second,
                    v => {
                        return Err(bad(format!(
                            "{}={v}: expected {first} or {second}",
                            key.trim()
                        )))
                    }
                });
            }
            return Ok(Configuration::Arm {
                shoulder,
                elbow,
                wrist,
            });
        }
        let signs = text
            .split(',')
            .map(|s| match s.trim() {
                "+" => Ok(Some(true)),
                "-" => Ok(Some(false)),
                "*" => Ok(None),
                other => Err(bad(format!(
                    "`{other}`: a sign pattern has one of +, - or * per joint (e.g. +,*,-,*,+,*), \
                     or name the parts (shoulder=front,elbow=up,wrist=noflip)"
                ))),
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Configuration::Signs(signs))
    }
}

impl Configuration {
    /// Whether `robot` at `readings` is in this configuration (an error when the configuration
    /// cannot be told on `robot`; see [`Configuration`]).
    pub fn holds(&self, robot: &Robot, readings: &[f64]) -> Result<bool> {
        let c = Classifier::new(robot, self.clone())?;
        let mut ws = Workspace::new(robot);
        Chain::new(robot).forward(readings, &mut ws);
        Ok(c.matches(robot, readings, &ws))
    }
}

impl fmt::Display for Configuration {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Configuration::Arm {
                shoulder,
                elbow,
                wrist,
            } => {
                let parts: Vec<String> = [
                    ("shoulder", shoulder, "front", "back"),
                    ("elbow", elbow, "up", "down"),
                    ("wrist", wrist, "noflip", "flip"),
                ]
                .iter()
                .filter_map(|(k, s, a, b)| {
                    s.map(|s| format!("{k}={}", if s == Side::First { a } else { b }))
                })
                .collect();
                f.write_str(&parts.join(","))
            }
            Configuration::Signs(s) => {
                let parts: Vec<&str> = s
                    .iter()
                    .map(|s| match s {
                        Some(true) => "+",
                        Some(false) => "-",
                        None => "*",
                    })
                    .collect();
                f.write_str(&parts.join(","))
            }
        }
    }
}

/// A [`Configuration`] checked against one robot, ready to classify its solutions.
#[derive(Debug, Clone)]
pub(crate) struct Classifier {
    configuration: Configuration,
    /// For `shoulder`: the radial direction from joint 1's axis to the wrist centre at the
    /// zero posture, in the frame right after joint 1 (so that it turns with joint 1).
    front: Vector3<f64>,
}

impl Classifier {
    /// Checks that `configuration` can be told on `robot` (a named one needs six revolute
    /// joints, non-parallel axes 1-2 and 4-5 and a wrist centre off joint 1's axis at the zero
    /// posture; a sign pattern one entry per joint).
    pub(crate) fn new(robot: &Robot, configuration: Configuration) -> Result<Classifier> {
        let bad = |message: String| Error::InvalidOption {
            setting: Setting::Configuration,
            message,
        };
        let n = robot.dof();
        let mut front = Vector3::zeros();
        match &configuration {
            Configuration::Signs(s) if s.len() != n => {
                return Err(bad(format!(
                    "{} signs for a robot of {n} joints: give one per joint",
                    s.len()
                )))
            }
            Configuration::Signs(_) => {}
            Configuration::Arm { .. } => {
                if n != 6 || robot.joints.iter().any(|j| j.kind != JointKind::Revolute) {
                    return Err(bad(format!(
                        "shoulder, elbow and wrist name the configurations of an arm of six \
                         revolute joints; this robot has {n} joints: give a sign pattern (one \
                         of +, - or * per joint) instead"
                    )));
                }
                // The zero posture: every joint value 0.
                let zero: Vec<f64> = robot
                    .joints
                    .iter()
                    .map(|j| {
                        if j.slope != 0.0 {
                            -j.offset / j.slope
                        } else {
                            0.0
                        }
                    })
                    .collect();
                let chain = Chain::new(robot);
                let mut ws = Workspace::new(robot);
                chain.forward(&zero, &mut ws);
                let g = Geometry::of(&ws).ok_or_else(|| {
                    bad(
                        "joints 1 and 2, or 4 and 5, have parallel axes: the shoulder and the \
                         wrist centre are not defined; give a sign pattern instead"
                            .into(),
                    )
                })?;
                if g.radial.norm() < 1e-3 * robot.reach().max(1e-3) {
                    return Err(bad(
                        "at the zero posture the wrist centre lies on joint 1's \
                                    axis: front and back are not defined; give a sign \
                                    pattern instead"
                            .into(),
                    ));
                }
                let r1 = ws.after_joint(1).rotation;
                front = r1.transpose() * g.radial.normalize();
            }
        }
        Ok(Classifier {
            configuration,
            front,
        })
    }

    /// The configuration asked for.
    pub(crate) fn configuration(&self) -> &Configuration {
        &self.configuration
    }

    /// Whether the solution at `readings`, whose forward kinematics `ws` holds, is in the
    /// configuration.
    pub(crate) fn matches(&self, robot: &Robot, readings: &[f64], ws: &Workspace) -> bool {
        match &self.configuration {
            Configuration::Signs(signs) => {
                signs
                    .iter()
                    .zip(&robot.joints)
                    .enumerate()
                    .all(|(j, (s, joint))| {
                        let Some(s) = s else { return true };
                        let mut q = joint.value(readings, j);
                        if joint.kind == JointKind::Revolute {
                            q = wrap_pi(q);
                        }
                        (q >= 0.0) == *s
                    })
            }
            Configuration::Arm {
                shoulder,
                elbow,
                wrist,
            } => {
                let Some(g) = Geometry::of(ws) else {
                    return false;
                };
                let side = |b: bool| if b { Side::First } else { Side::Second };
                let front = ws.after_joint(1).rotation * self.front;
                let got_shoulder = side(g.radial.dot(&front) >= 0.0);
                let got_elbow = side(g.elbow_height >= 0.0);
                let got_wrist = side(robot.joints[4].value(readings, 4).sin() >= 0.0);
                shoulder.is_none_or(|s| s == got_shoulder)
                    && elbow.is_none_or(|s| s == got_elbow)
                    && wrist.is_none_or(|s| s == got_wrist)
            }
        }
    }
}

/// An angle brought into (-pi, pi].
pub(crate) fn wrap_pi(q: f64) -> f64 {
    let tau = std::f64::consts::TAU;
    let r = q - tau * (q / tau).round();
    if r <= -std::f64::consts::PI {
        r + tau
    } else {
        r
    }
}

/// The geometric quantities behind the named configuration of a 6R arm at one posture.
struct Geometry {
    /// The wrist centre's offset from joint 1's axis, perpendicular to it.
    radial: Vector3<f64>,
    /// The elbow's height (along base +z) above the shoulder-wrist line, in the plane
    /// perpendicular to joint 2's axis.
    elbow_height: f64,
}

impl Geometry {
    fn of(ws: &Workspace) -> Option<Geometry> {
        let axis = |k: usize| {
            let f = ws.after_joint(k);
            (f.translation, f.rotation.column(2).into_owned())
        };
        let (o1, z1) = axis(1);
        let (o2, z2) = axis(2);
        let (o3, _) = axis(3);
        let (o4, z4) = axis(4);
        let (o5, z5) = axis(5);
        if z1.cross(&z2).norm() < 1e-6 {
            return None;
        }
        // The point of axis 5 nearest axis 4.
        let w0 = o5 - o4;
        let b = z4.dot(&z5);
        let denom = 1.0 - b * b;
        if denom < 1e-12 {
            return None;
        }
        let t = (b * z4.dot(&w0) - z5.dot(&w0)) / denom;
        let w = o5 + z5 * t;
        let d = w - o1;
        let radial = d - z1 * z1.dot(&d);
        // In the plane perpendicular to joint 2's axis: shoulder s, elbow e, wrist w.
        let flat = |v: Vector3<f64>| v - z2 * z2.dot(&v);
        let (e, wr) = (flat(o3 - o2), flat(w - o2));
        let line = wr.try_normalize(1e-12)?;
        let off = e - line * line.dot(&e);
        Some(Geometry {
            radial,
            elbow_height: off.z,
        })
    }
}
