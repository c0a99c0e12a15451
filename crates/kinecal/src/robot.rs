//! The robot model of the thesis (section 2.3): n joints, n+1 links, optional measurement sites.
//!
//! Conventions (all values internal: metres, radians):
//! - a link is `Trans(x, y, z) Rz(alpha) Ry(beta) Rx(gamma)` (eq. 2.1): the distal frame's origin
//!   at `(x, y, z)` in the proximal frame, its attitude the ZYX Euler angles `alpha, beta, gamma`;
//! - a revolute joint is `Rz(q)`, a prismatic joint `Trans(0, 0, q)`, with `q = offset + slope * V`
//!   for the transducer reading `V` (eqs. 2.2-2.5);
//! - the end-effector frame (EECF) is `T = L1 J1 L2 J2 ... Ln Jn L(n+1)` (eq. 2.6) in the global
//!   frame;
//! - a site is a frame rigidly attached to the frame right after joint `k` (1-based), by the same
//!   six-parameter transform as a link.

use crate::params::{LinkComponent, ParamId, ParamKind};
use crate::units::{Quantity, Units};

/// The six parameters of a link (or of a site's attachment), internal units.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Link {
    /// Distal origin along the proximal x axis (m).
    pub x: f64,
    /// Distal origin along the proximal y axis (m).
    pub y: f64,
    /// Distal origin along the proximal z axis (m).
    pub z: f64,
    /// First ZYX Euler angle, about z (rad).
    pub alpha: f64,
    /// Second ZYX Euler angle, about the new y (rad).
    pub beta: f64,
    /// Third ZYX Euler angle, about the newest x (rad).
    pub gamma: f64,
}

impl Link {
    /// The value of one component.
    pub fn get(&self, c: LinkComponent) -> f64 {
        match c {
            LinkComponent::X => self.x,
            LinkComponent::Y => self.y,
            LinkComponent::Z => self.z,
            LinkComponent::Alpha => self.alpha,
            LinkComponent::Beta => self.beta,
            LinkComponent::Gamma => self.gamma,
        }
    }

    /// A mutable reference to one component.
    pub fn get_mut(&mut self, c: LinkComponent) -> &mut f64 {
        match c {
            LinkComponent::X => &mut self.x,
            LinkComponent::Y => &mut self.y,
            LinkComponent::Z => &mut self.z,
            LinkComponent::Alpha => &mut self.alpha,
            LinkComponent::Beta => &mut self.beta,
            LinkComponent::Gamma => &mut self.gamma,
        }
    }
}

/// Kind of a joint.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JointKind {
    /// Rotation `Rz(q)` about the local z axis.
    Revolute,
    /// Translation `Trans(0, 0, q)` along the local z axis.
    Prismatic,
}

impl JointKind {
    /// The spelling used in robot files.
    pub fn as_str(self) -> &'static str {
        match self {
            JointKind::Revolute => "revolute",
            JointKind::Prismatic => "prismatic",
        }
    }

    /// The quantity of the joint variable `q` (and of the offset).
    pub fn variable(self) -> Quantity {
        match self {
            JointKind::Revolute => Quantity::Angle,
            JointKind::Prismatic => Quantity::Length,
        }
    }

    /// The quantity of the transducer slope.
    pub fn slope(self) -> Quantity {
        match self {
            JointKind::Revolute => Quantity::AnglePerReading,
            JointKind::Prismatic => Quantity::LengthPerReading,
        }
    }
}

/// A joint and its linear transducer, `q = offset + slope * V`.
#[derive(Debug, Clone, PartialEq)]
pub struct Joint {
    /// Revolute or prismatic.
    pub kind: JointKind,
    /// Transducer zero-point offset (rad or m).
    pub offset: f64,
    /// Transducer output slope (rad or m per transducer unit).
    pub slope: f64,
    /// Range of transducer readings `(min, max)` the robot can take, in transducer units.
    pub range: Option<(f64, f64)>,
}

impl Joint {
    /// The joint variable for a reading.
    #[inline]
    pub fn value(&self, reading: f64) -> f64 {
        self.offset + self.slope * reading
    }
}

/// A measured point on the robot body other than the EECF (thesis 4.4.8).
#[derive(Debug, Clone, PartialEq)]
pub struct Site {
    /// The name used in measurement files' `site` column and in parameter names.
    pub name: String,
    /// The joint (1-based) right after which the site is attached.
    pub joint: usize,
    /// The site frame relative to the frame after that joint.
    pub frame: Link,
}

/// A serial robot: the thesis model plus the units its files are written in.
#[derive(Debug, Clone, PartialEq)]
pub struct Robot {
    /// Human-readable name.
    pub name: String,
    /// Units of the robot file and its measurement files.
    pub units: Units,
    /// n+1 links: `links[0]` from the global frame to joint 1, the last one to the EECF.
    pub links: Vec<Link>,
    /// n joints.
    pub joints: Vec<Joint>,
    /// Extra measurement sites.
    pub sites: Vec<Site>,
    /// Expected deviations from nominal, the metric of minimum-change solutions.
    pub tolerances: Tolerances,
}

/// How far each parameter is expected to deviate from its nominal value (internal units): the
/// metric in which a minimum-change calibration picks, among equally good answers, the one
/// closest to nominal. Set in the robot file's `[tolerances]` table:
///
/// ```toml
/// [tolerances]
/// length = 0.04     # file length unit; default 1 mm
/// angle = 0.1       # file angle unit; default 0.1 deg
/// slope = 0.01      # fraction of each slope; default 1 %
/// "link3.y" = 0.01  # any parameter by id or name, in its own unit
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct Tolerances {
    /// For link and site lengths and prismatic offsets (m).
    pub length: f64,
    /// For link and site angles and revolute offsets (rad).
    pub angle: f64,
    /// For slopes, as a fraction of the slope's magnitude.
    pub slope_fraction: f64,
    /// Per-parameter values (internal units), overriding the above.
    pub overrides: Vec<(ParamId, f64)>,
}

impl Default for Tolerances {
    fn default() -> Self {
        Tolerances {
            length: 1e-3,
            angle: 0.1f64.to_radians(),
            slope_fraction: 0.01,
            overrides: Vec::new(),
        }
    }
}

impl Robot {
    /// The tolerance of parameter `id` (internal units, always positive).
    pub fn tolerance(&self, id: ParamId) -> f64 {
        if let Some(&(_, t)) = self.tolerances.overrides.iter().find(|(p, _)| *p == id) {
            return t;
        }
        let t = match (self.param_kind(id), self.param_quantity(id)) {
            (ParamKind::Slope { .. }, _) => self.tolerances.slope_fraction * self.get(id).abs(),
            (_, Quantity::Length) => self.tolerances.length,
            _ => self.tolerances.angle,
        };
        if t > 0.0 {
            t
        } else {
            self.tolerances.slope_fraction.max(1e-6)
        }
    }

    /// Number of joints n.
    pub fn dof(&self) -> usize {
        self.joints.len()
    }

    /// Number of parameters: `6(n+1) + 2n + 6 * sites`.
    pub fn param_count(&self) -> usize {
        6 * self.links.len() + 2 * self.joints.len() + 6 * self.sites.len()
    }

    /// All parameter ids, in the thesis's order.
    pub fn param_ids(&self) -> impl Iterator<Item = ParamId> {
        (0..self.param_count()).map(ParamId)
    }

    /// What parameter `id` is. Panics if `id` is out of range.
    #[track_caller]
    pub fn param_kind(&self, id: ParamId) -> ParamKind {
        ParamKind::of(id, self.links.len(), self.joints.len(), self.sites.len())
            .expect("parameter id out of range")
    }

    /// The parameter's name: `link1.x`, `joint3.offset`, `joint4.slope`, `site.NAME.gamma`.
    pub fn param_name(&self, id: ParamId) -> String {
        match self.param_kind(id) {
            ParamKind::Link { link, component } => {
                format!("link{}.{}", link + 1, component.as_str())
            }
            ParamKind::Offset { joint } => format!("joint{}.offset", joint + 1),
            ParamKind::Slope { joint } => format!("joint{}.slope", joint + 1),
            ParamKind::Site { site, component } => {
                format!("site.{}.{}", self.sites[site].name, component.as_str())
            }
        }
    }

    /// The physical quantity of parameter `id` (decides its unit).
    pub fn param_quantity(&self, id: ParamId) -> Quantity {
        match self.param_kind(id) {
            ParamKind::Link { component, .. } | ParamKind::Site { component, .. } => {
                component.quantity()
            }
            ParamKind::Offset { joint } => self.joints[joint].kind.variable(),
            ParamKind::Slope { joint } => self.joints[joint].kind.slope(),
        }
    }

    /// Value of parameter `id`, internal units.
    pub fn get(&self, id: ParamId) -> f64 {
        match self.param_kind(id) {
            ParamKind::Link { link, component } => self.links[link].get(component),
            ParamKind::Offset { joint } => self.joints[joint].offset,
            ParamKind::Slope { joint } => self.joints[joint].slope,
            ParamKind::Site { site, component } => self.sites[site].frame.get(component),
        }
    }

    /// Sets parameter `id`, internal units.
    pub fn set(&mut self, id: ParamId, value: f64) {
        match self.param_kind(id) {
            ParamKind::Link { link, component } => *self.links[link].get_mut(component) = value,
            ParamKind::Offset { joint } => self.joints[joint].offset = value,
            ParamKind::Slope { joint } => self.joints[joint].slope = value,
            ParamKind::Site { site, component } => {
                *self.sites[site].frame.get_mut(component) = value
            }
        }
    }

    /// Value of parameter `id` in the robot file's units.
    pub fn get_user(&self, id: ParamId) -> f64 {
        self.units.from_si(self.param_quantity(id), self.get(id))
    }

    /// Unit label of parameter `id` in the robot file's units.
    pub fn param_unit(&self, id: ParamId) -> String {
        self.units.label(self.param_quantity(id))
    }

    /// Index of the site called `name`.
    pub fn site_index(&self, name: &str) -> Option<usize> {
        self.sites.iter().position(|s| s.name == name)
    }

    /// A characteristic length of the robot (m): the sum of its link offsets' lengths, at least
    /// 1 mm. Used where a lever arm converts angles to lengths.
    pub fn reach(&self) -> f64 {
        let sum: f64 = self
            .links
            .iter()
            .map(|l| (l.x * l.x + l.y * l.y + l.z * l.z).sqrt())
            .sum();
        sum.max(1e-3)
    }

    /// Checks the model's structural invariants (n+1 links, finite values, valid sites).
    pub fn validate(&self) -> Result<(), String> {
        if self.joints.is_empty() {
            return Err("a robot needs at least one joint".into());
        }
        if self.links.len() != self.joints.len() + 1 {
            return Err(format!(
                "{} joints need {} links (one before each joint and one to the end effector), \
                 found {}",
                self.joints.len(),
                self.joints.len() + 1,
                self.links.len()
            ));
        }
        for (i, s) in self.sites.iter().enumerate() {
            if s.joint == 0 || s.joint > self.joints.len() {
                return Err(format!(
                    "site {} (`{}`): joint = {} but the robot has joints 1..{}",
                    i + 1,
                    s.name,
                    s.joint,
                    self.joints.len()
                ));
            }
            if s.name == "ee"
                || s.name.is_empty()
                || self.sites[..i].iter().any(|o| o.name == s.name)
            {
                return Err(format!(
                    "site {}: name `{}` is empty, reserved (`ee`) or used twice",
                    i + 1,
                    s.name
                ));
            }
        }
        if let Some(id) = self.param_ids().find(|&id| !self.get(id).is_finite()) {
            return Err(format!(
                "parameter {} ({}) is not finite",
                id,
                self.param_name(id)
            ));
        }
        Ok(())
    }
}
