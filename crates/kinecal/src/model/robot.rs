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
//!   six-parameter transform as a link;
//! - a joint may be *coupled* to another joint's reading: `q_j = offset_j + slope_j * V_j +
//!   coupling_j * V_k` (a controller that measures joint 3 from the horizontal makes the model's
//!   joint 3 `J2 + J3`, coupling 1 to joint 2);
//! - a plane (for contact measurements) is the set of points `p` with `n . p = offset` in the
//!   global frame, `n` its unit normal. Its three parameters are the offset and two tilts of the
//!   normal about the axes of the plane's reference frame (see [`Plane`]).
//! - a robot may branch (a *tree*: two arms on one torso, a second robot measured in the same
//!   frame): each joint's link starts from the frame right after its *parent* joint (the
//!   previous joint unless [`Joint::parent`] says otherwise; 0 is the global frame), parents
//!   come before their children, and the end effector ends the last joint's branch; the other
//!   branches end in sites (their tool frames). A parameter moves only the frames of its own
//!   subtree, so the shared links are estimated once from every branch's data;
//! - a robot may carry a mass model ([`Elastic`]): bodies, gravity and joint compliances, so that
//!   its joints yield to the gravity torques (the elastic equilibrium that the kinematics
//!   module's `Chain::forward` solves).

use nalgebra::{Matrix3, Vector3};

use crate::model::camera::{Board, Camera, CameraComponent, Mount};
pub use crate::model::params::Link;
use crate::model::params::{BodyComponent, LinkComponent, ParamId, ParamKind, PlaneComponent};
use crate::units::{Quantity, Units};

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

/// A joint's dependence on another joint's reading: `factor * V_joint` adds to its variable.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Coupling {
    /// The other joint (0-based index).
    pub joint: usize,
    /// Joint units (rad or m) per transducer unit of the other joint.
    pub factor: f64,
}

/// A joint and its linear transducer, `q = offset + slope * V` (plus `factor * V_k` when
/// coupled to joint `k`).
#[derive(Debug, Clone, PartialEq)]
pub struct Joint {
    /// Revolute or prismatic.
    pub kind: JointKind,
    /// Transducer zero-point offset (rad or m).
    pub offset: f64,
    /// Transducer output slope (rad or m per transducer unit).
    pub slope: f64,
    /// Dependence on another joint's reading, if any.
    pub coupling: Option<Coupling>,
    /// Range of transducer readings `(min, max)` the robot can take, in transducer units.
    pub range: Option<(f64, f64)>,
    /// The joint's name (a URDF joint name, say): measurement and postures files may head its
    /// reading column with it instead of `vK`.
    pub name: Option<String>,
    /// The joint (1-based; 0 the global frame) after which this joint's link starts, when it is
    /// not the previous joint: a tree's branch. `None` is the serial chain's previous joint.
    pub parent: Option<usize>,
}

impl Joint {
    /// An uncoupled joint without a reading range.
    pub fn new(kind: JointKind, offset: f64, slope: f64) -> Self {
        Joint {
            kind,
            offset,
            slope,
            coupling: None,
            range: None,
            name: None,
            parent: None,
        }
    }

    /// The joint variable (rad or m) of this joint, number `own`, for a posture's `readings`.
    #[inline]
    pub fn value(&self, readings: &[f64], own: usize) -> f64 {
        let mut q = self.offset + self.slope * readings[own];
        if let Some(c) = self.coupling {
            q += c.factor * readings[c.joint];
        }
        q
    }
}

/// A plane the robot's targets touch (contact measurements), in the global frame.
///
/// The plane is `{p : n . p = offset}` with `n` its unit normal. The normal is parameterised by
/// two tilts about the axes of a *reference frame* fixed when the plane is created (from the
/// robot file's `normal`): `z_ref` the given normal, `x_ref` the global axis least aligned with
/// it (x before y before z on ties) made perpendicular to it, `y_ref = z_ref x x_ref`. Then
/// `n = R_ref Rx(tilt_x) Ry(tilt_y) e_z`, so both tilts are 0 for the normal as written and the
/// parameterisation is regular there (a horizontal table `normal = [0, 0, 1]` has `x_ref = x`,
/// `y_ref = y`: `tilt_x` turns the normal about the global x axis). Written back, the file gets
/// the tilted normal, and the tilts start at 0 again.
#[derive(Debug, Clone, PartialEq)]
pub struct Plane {
    /// The name used in contact files and parameter names (`plane.NAME.offset`).
    pub name: String,
    reference: Matrix3<f64>,
    /// Rotation of the normal about `x_ref` (rad).
    pub tilt_x: f64,
    /// Rotation of the normal about `y_ref` (after `tilt_x`) (rad).
    pub tilt_y: f64,
    /// Signed distance of the plane from the global origin along the normal (m).
    pub offset: f64,
}

impl Plane {
    /// A plane with the given normal (any non-zero length) and offset (m); `None` if the normal
    /// is zero or not finite.
    pub fn new(name: impl Into<String>, normal: Vector3<f64>, offset: f64) -> Option<Plane> {
        let len = normal.norm();
        if !(len.is_finite() && len > 0.0 && offset.is_finite()) {
            return None;
        }
        // A normal already of unit length (to rounding, as kinecal writes them) is kept as it
        // is, so that reading and writing a file again gives the same digits.
        let z = if (len - 1.0).abs() <= 16.0 * f64::EPSILON {
            normal
        } else {
            normal / len
        };
        let axes = [Vector3::x(), Vector3::y(), Vector3::z()];
        let least = axes
            .iter()
            .min_by(|a, b| a.dot(&z).abs().total_cmp(&b.dot(&z).abs()))
            .expect("three axes");
        let x = (least - z * least.dot(&z)).normalize();
        let y = z.cross(&x);
        Some(Plane {
            name: name.into(),
            reference: Matrix3::from_columns(&[x, y, z]),
            tilt_x: 0.0,
            tilt_y: 0.0,
            offset,
        })
    }

    /// The reference frame's axes `[x_ref, y_ref, z_ref]` as columns (global frame).
    pub fn reference(&self) -> &Matrix3<f64> {
        &self.reference
    }

    /// The unit normal.
    pub fn normal(&self) -> Vector3<f64> {
        let (sx, cx) = self.tilt_x.sin_cos();
        let (sy, cy) = self.tilt_y.sin_cos();
        self.reference * Vector3::new(sy, -sx * cy, cx * cy)
    }

    /// Derivatives of the normal with respect to `tilt_x` and `tilt_y`.
    pub fn normal_derivatives(&self) -> [Vector3<f64>; 2] {
        let (sx, cx) = self.tilt_x.sin_cos();
        let (sy, cy) = self.tilt_y.sin_cos();
        [
            self.reference * Vector3::new(0.0, -cx * cy, -sx * cy),
            self.reference * Vector3::new(cy, sx * sy, -cx * sy),
        ]
    }

    /// Sets the tilts so that the normal is `n` (any non-zero length), keeping the reference
    /// frame; `false` (nothing changed) if `n` is zero or faces away from the reference normal
    /// by 90 deg or more.
    pub fn set_normal(&mut self, n: &Vector3<f64>) -> bool {
        let len = n.norm();
        if !(len.is_finite() && len > 0.0) {
            return false;
        }
        let l = self.reference.transpose() * (n / len);
        if l.z <= 0.0 {
            return false;
        }
        self.tilt_y = l.x.clamp(-1.0, 1.0).asin();
        self.tilt_x = (-l.y).atan2(l.z);
        true
    }

    /// The signed distance of point `p` (m) from the plane, positive on the normal's side.
    pub fn distance(&self, p: &Vector3<f64>) -> f64 {
        self.normal().dot(p) - self.offset
    }

    fn get(&self, c: PlaneComponent) -> f64 {
        match c {
            PlaneComponent::TiltX => self.tilt_x,
            PlaneComponent::TiltY => self.tilt_y,
            PlaneComponent::Offset => self.offset,
        }
    }

    fn get_mut(&mut self, c: PlaneComponent) -> &mut f64 {
        match c {
            PlaneComponent::TiltX => &mut self.tilt_x,
            PlaneComponent::TiltY => &mut self.tilt_y,
            PlaneComponent::Offset => &mut self.offset,
        }
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

/// A session of measurements with its own measurement frame (a laser tracker moved between
/// series, a camera re-mounted): `frame` is the pose of the robot's global frame in the
/// session's measurement frame, so that a point `p` of the global frame is measured at
/// `R p + t` there. The robot's global frame is the measurement frame of observations outside
/// every listed session.
#[derive(Debug, Clone, PartialEq)]
pub struct Session {
    /// The session's name (the observations' `session`).
    pub name: String,
    /// The global frame in the session's measurement frame (x, y, z, ZYX Euler angles).
    pub frame: Link,
}

/// A rigid body of the robot's mass model: a point mass at its centre of mass, carried by the
/// frame right after joint `joint` (the frame link `joint + 1` starts from, as for sites).
#[derive(Debug, Clone, PartialEq)]
pub struct Body {
    /// The joint (1-based) right after which the body is attached.
    pub joint: usize,
    /// Mass (kg).
    pub mass: f64,
    /// Centre of mass in the frame after that joint (m).
    pub com: Vector3<f64>,
}

/// What the tool carries at a posture (a workpiece, a gripper's load): a point mass at its
/// centre of mass in the end-effector frame. It loads an elastic robot's joints like a body
/// carried by the last joint; a rigid robot does not feel it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Payload {
    /// Mass (kg).
    pub mass: f64,
    /// Centre of mass in the end-effector frame (m).
    pub com: Vector3<f64>,
}

impl Payload {
    /// Why `mass` (kg) cannot be a payload's: not a number from 0 to 1e6 kg.
    pub(crate) fn mass_problem(mass: f64) -> Option<String> {
        (!(0.0..=1e6).contains(&mass))
            .then(|| format!("a payload mass is 0 to 1e6 kg, found {mass}"))
    }
}

/// How one joint yields under gravity: about its own axis, and about a lateral axis
/// perpendicular to it (the bending of the joint's bearing and the link before it).
#[derive(Debug, Clone, PartialEq)]
pub struct JointElasticity {
    /// Compliance about the joint axis (rad/(N m)): the joint turns by `compliance * tau`, `tau`
    /// the gravity torque about its axis (positive by the right-hand rule about the axis).
    pub compliance: f64,
    /// Compliance about the lateral axis (rad/(N m)).
    pub lateral: f64,
    /// The lateral axis, a unit vector perpendicular to the joint axis in the joint's frame
    /// (the frame at the distal end of the link before the joint, whose z is the joint axis).
    /// The joint first tilts about this axis by `lateral * tau_lateral`, then turns about its
    /// (tilted) z axis. Fixed data, not a parameter: see [`Elastic::lateral_axis`] for how it
    /// is chosen.
    pub lateral_axis: Vector3<f64>,
}

/// A robot's mass model: bodies, gravity and joint compliances (beyond the thesis; Tenhumberg
/// and Bauml, Humanoids 2021, for the model). With it, every revolute joint has two parameters
/// more, its compliance and its lateral compliance ([`ParamKind::Compliance`],
/// [`ParamKind::Lateral`]), and forward kinematics solves the static equilibrium: the deflected
/// posture gives the gravity torques, the torques give the deflection.
#[derive(Debug, Clone, PartialEq)]
pub struct Elastic {
    /// Gravitational acceleration in the robot's global frame, the one link 1 starts from
    /// (m/s^2); default 9.81 along -z. When that frame is an instrument's (a tracker that is not
    /// levelled), give gravity in it.
    pub gravity: Vector3<f64>,
    /// A fixed number of fixed-point iterations of the equilibrium (as in the paper); `None`
    /// (the default) iterates until the deflection changes by less than
    /// [`Elastic::TOLERANCE`].
    pub iterations: Option<usize>,
    /// The bodies.
    pub bodies: Vec<Body>,
    /// One per joint (prismatic joints' entries are unused: they have no compliance).
    pub joints: Vec<JointElasticity>,
}

impl Elastic {
    fn validate(&self, robot: &Robot) -> Result<(), String> {
        let g = &self.gravity;
        if !g.iter().all(|v| crate::units::plausible(*v)) {
            return Err(format!(
                "gravity [{}, {}, {}] is not three finite numbers within +-1e9",
                g.x, g.y, g.z
            ));
        }
        if self.iterations == Some(0) {
            return Err("gravity.iterations must be at least 1 (or left out to converge)".into());
        }
        if self.joints.len() != robot.dof() {
            return Err(format!(
                "the mass model has {} joints, the robot {}",
                self.joints.len(),
                robot.dof()
            ));
        }
        for (i, b) in self.bodies.iter().enumerate() {
            if b.joint == 0 || b.joint > robot.dof() {
                return Err(format!(
                    "body {}: joint = {} but the robot has joints 1..{} (a body on the base \
                     feels no joint)",
                    i + 1,
                    b.joint,
                    robot.dof()
                ));
            }
            if !(b.mass.is_finite() && b.mass >= 0.0 && b.mass <= 1e9) {
                return Err(format!(
                    "body {}: mass {} is not a finite number of kg in [0, 1e9]",
                    i + 1,
                    b.mass
                ));
            }
            if !b.com.iter().all(|v| v.is_finite()) {
                return Err(format!("body {}: com is not finite", i + 1));
            }
        }
        for (i, j) in self.joints.iter().enumerate() {
            let a = &j.lateral_axis;
            if !((a.norm() - 1.0).abs() < 1e-6 && a.z.abs() < 1e-6) {
                return Err(format!(
                    "joint {}: lateral_axis [{}, {}, {}] must be a unit vector perpendicular to \
                     the joint axis (its z component 0)",
                    i + 1,
                    a.x,
                    a.y,
                    a.z
                ));
            }
        }
        Ok(())
    }

    /// The equilibrium's convergence tolerance: the largest change of any deflection in the last
    /// iteration (rad).
    pub const TOLERANCE: f64 = 1e-10;

    /// The iteration limit when converging: an equilibrium that takes more is reported as not
    /// converged (the deflections then oscillate or creep instead of settling: the compliances
    /// are implausibly large).
    pub const MAX_ITERATIONS: usize = 200;

    /// Standard gravity, 9.81 m/s^2 along -z of the global frame.
    pub(crate) fn standard_gravity() -> Vector3<f64> {
        Vector3::new(0.0, 0.0, -9.81)
    }

    /// A mass model with `bodies`, standard gravity and zero compliances, the lateral axes
    /// chosen from `robot`'s geometry ([`Elastic::lateral_axis`]).
    pub fn new(robot: &Robot, bodies: Vec<Body>) -> Elastic {
        Elastic {
            gravity: Elastic::standard_gravity(),
            iterations: None,
            bodies,
            joints: (0..robot.dof())
                .map(|j| JointElasticity {
                    compliance: 0.0,
                    lateral: 0.0,
                    lateral_axis: Elastic::lateral_axis(robot, j),
                })
                .collect(),
        }
    }

    /// A lumped mass model for a robot whose masses are not known: one point mass per joint,
    /// `total / n` each, halfway along the link that joint moves (the midpoint of the next
    /// link's offset, in the frame after the joint). Positions alone cannot tell the masses'
    /// scale from the compliances' (twice the masses and half the compliances deflect the same):
    /// estimate the shares with `masses` and the compliances with one mass held (`--fix
    /// body1.mass`), and the compliances are then relative to that mass.
    pub fn lumped(robot: &Robot, total: f64) -> Vec<Body> {
        let n = robot.dof();
        (1..=n)
            .map(|joint| {
                // The link that starts after the joint (a tree's first branch, the tool link
                // after the last joint).
                let next = (0..=n).find(|&i| robot.link_parent(i) == joint).map_or(
                    Vector3::zeros(),
                    |i| {
                        let l = &robot.links[i];
                        Vector3::new(l.x, l.y, l.z)
                    },
                );
                Body {
                    joint,
                    mass: total / n as f64,
                    com: next * 0.5,
                }
            })
            .collect()
    }

    /// The default lateral axis of joint `j` (0-based), in the joint's frame: the direction of
    /// the common normal from the parent joint's axis to this one at the zero posture (`z_parent
    /// x z`; the parent of joint 1 is the global z axis). When the two axes are parallel (within
    /// 1e-6 rad), the direction from the parent axis to this one, perpendicular to both; when
    /// they coincide as well, the joint frame's x axis.
    pub fn lateral_axis(robot: &Robot, j: usize) -> Vector3<f64> {
        let link = &robot.links[j];
        // The parent joint's frame and axis, expressed in joint j's frame: link j maps joint
        // j's frame into the parent's, the parent's axis is the parent frame's z.
        // Rz(alpha) Ry(beta) Rx(gamma).
        let r = *nalgebra::Rotation3::from_euler_angles(link.gamma, link.beta, link.alpha).matrix();
        let parent_axis = r.transpose() * Vector3::z();
        let parent_origin = -(r.transpose() * Vector3::new(link.x, link.y, link.z));
        let normal = parent_axis.cross(&Vector3::z());
        if normal.norm() > 1e-6 {
            return normal.normalize();
        }
        let offset = -Vector3::new(parent_origin.x, parent_origin.y, 0.0);
        if offset.norm() > 1e-9 {
            return offset.normalize();
        }
        Vector3::x()
    }
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
    /// Planes touched in contact measurements.
    pub planes: Vec<Plane>,
    /// Measurement sessions with frames of their own.
    pub sessions: Vec<Session>,
    /// Expected deviations from nominal, the metric of minimum-change solutions.
    pub tolerances: Tolerances,
    /// The robot file's `[priors]`: the Gaussian prior a calibration puts on each parameter's
    /// change unless told otherwise (empty when the file has none).
    pub priors: Prior,
    /// The mass model, for a robot whose joints yield under gravity.
    pub elastic: Option<Elastic>,
    /// The end-effector frame's name, when it has one: measurement files' `site` column may
    /// name it (besides `ee`). A tree's other tool frames are sites.
    pub end_effector: Option<String>,
    /// Cameras whose pixel observations calibrate the robot ([`crate::model::camera`]).
    pub cameras: Vec<Camera>,
    /// Calibration boards the cameras see.
    pub boards: Vec<Board>,
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

/// A Gaussian prior on the parameters' changes from their starting values: per parameter, the
/// standard deviation (internal units) of its change, by group and per parameter. A calibration
/// with a prior minimises the data's weighted squared residuals plus `sum ((p - p0) / s_p)^2`
/// over the estimated parameters with a standard deviation `s_p` (see [`crate::solve::problem`]).
/// Written as `length=L,angle=A,slope=F,compliance=C,NAME=V` (the robot file's units; slopes as
/// a fraction, as in [`Tolerances`]) on the command line and in a robot file's `[priors]` table
/// (read by `crate::model::prior`). Groups not given leave their parameters without a prior; an empty
/// prior is none.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Prior {
    /// For link, site and session positions, plane offsets and prismatic offsets (m).
    pub length: Option<f64>,
    /// For link, site and session angles, plane tilts and revolute offsets (rad).
    pub angle: Option<f64>,
    /// For slopes and coupling factors, as a fraction of the value (of at least 1 for a
    /// coupling factor), as for [`Tolerances::slope_fraction`].
    pub slope: Option<f64>,
    /// For joint and lateral compliances (rad/(N m)).
    pub compliance: Option<f64>,
    /// Per-parameter standard deviations (internal units), overriding the groups.
    pub overrides: Vec<(ParamId, f64)>,
    /// The bodies' total mass (kg), held by one row on the sum of their masses with a standard
    /// deviation of [`Prior::TOTAL_MASS_FRACTION`] of it: what fixes the masses' scale when they
    /// are estimated, which positions alone cannot (`--total-mass`).
    pub total_mass: Option<f64>,
}

impl Prior {
    /// The standard deviation of the total-mass row, as a fraction of the total: the sum is
    /// held, not merely suggested.
    pub const TOTAL_MASS_FRACTION: f64 = 1e-6;

    /// No prior at all: no group and no parameter has a standard deviation.
    pub fn is_empty(&self) -> bool {
        self.length.is_none()
            && self.angle.is_none()
            && self.slope.is_none()
            && self.compliance.is_none()
            && self.overrides.is_empty()
            && self.total_mass.is_none()
    }

    /// The prior the tolerances make: the same expected deviations (`[tolerances]` read as
    /// standard deviations), compliances without one.
    pub(crate) fn from_tolerances(t: &Tolerances) -> Prior {
        Prior {
            length: Some(t.length),
            angle: Some(t.angle),
            slope: Some(t.slope_fraction),
            compliance: None,
            overrides: t.overrides.clone(),
            total_mass: None,
        }
    }

    /// The standard deviation (internal units) of parameter `id`'s change, when it has a
    /// prior; `robot` gives the parameter's kind and, for slopes and couplings, the value the
    /// fraction is of.
    pub fn sigma(&self, robot: &Robot, id: ParamId) -> Option<f64> {
        if let Some(&(_, s)) = self.overrides.iter().find(|(p, _)| *p == id) {
            return Some(s);
        }
        let s = match (robot.param_kind(id), robot.param_quantity(id)) {
            (ParamKind::Slope { .. }, _) => self.slope? * robot.get(id).abs(),
            (ParamKind::Coupling { .. }, _) => self.slope? * robot.get(id).abs().max(1.0),
            (_, Quantity::Length) => self.length?,
            (_, Quantity::Compliance) => self.compliance?,
            // A lens has no group of its own: a prior on it is given per parameter.
            (_, Quantity::Pixel | Quantity::Ratio | Quantity::Mass) => return None,
            _ => self.angle?,
        };
        // A slope of 0 (never a valid one) has no scale to take a fraction of.
        (s > 0.0 && s.is_finite()).then_some(s)
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
            (ParamKind::Coupling { .. }, _) => {
                self.tolerances.slope_fraction * self.get(id).abs().max(1.0)
            }
            (_, Quantity::Length) => self.tolerances.length,
            // A lens: a pixel of focal length or principal point, a hundredth of distortion.
            (_, Quantity::Pixel) => 1.0,
            (_, Quantity::Ratio) => 0.01,
            _ => self.tolerances.angle,
        };
        if t > 0.0 {
            t
        } else {
            self.tolerances.slope_fraction.max(1e-6)
        }
    }

    /// The same robot without its mass model: the rigid geometry an export writes.
    pub fn rigid(&self) -> Robot {
        Robot {
            elastic: None,
            ..self.clone()
        }
    }

    /// Number of joints n.
    pub fn dof(&self) -> usize {
        self.joints.len()
    }

    /// The joint (1-based; 0 the global frame) right after which link `i` (0-based, `0..=n`)
    /// starts: the joint's parent for a link before a joint, the last joint for the tool link.
    #[inline]
    pub(crate) fn link_parent(&self, i: usize) -> usize {
        match self.joints.get(i) {
            Some(j) => j.parent.unwrap_or(i),
            None => self.joints.len(),
        }
    }

    /// Whether the robot branches (some joint's link starts elsewhere than after the previous
    /// joint).
    pub fn is_tree(&self) -> bool {
        (0..self.joints.len()).any(|i| self.link_parent(i) != i)
    }

    /// Whether joint `j` (0-based) moves the frame right after joint `k` (1-based; 0 the
    /// global frame): whether `j` is on the path from the base to that frame.
    pub fn joint_moves(&self, j: usize, k: usize) -> bool {
        let mut a = k;
        while a > j + 1 {
            a = self.link_parent(a - 1);
        }
        a == j + 1
    }

    /// The joints (0-based) on the path from the base to the frame right after joint `k`
    /// (1-based), one flag per joint.
    pub(crate) fn path_to(&self, k: usize) -> Vec<bool> {
        let mut on = vec![false; self.joints.len()];
        let mut a = k;
        while a > 0 {
            on[a - 1] = true;
            a = self.link_parent(a - 1);
        }
        on
    }

    /// The rigid serial robot through this tree to one tool frame (`site`, or the end effector
    /// when `None`), and the joints (0-based, ascending) it keeps: the links and joints on the
    /// path, the tool frame as its last link; readings are those of the kept joints. What a
    /// serial-only format (a URDF chain, DH) and a per-arm comparison work with. An error when a
    /// kept joint is coupled to a reading off the path.
    pub fn branch(&self, site: Option<usize>) -> Result<(Robot, Vec<usize>), String> {
        let (last, tool) = match site {
            None => (self.dof(), *self.links.last().expect("links")),
            Some(s) => (self.sites[s].joint, self.sites[s].frame),
        };
        let path: Vec<usize> = self
            .path_to(last)
            .iter()
            .enumerate()
            .filter_map(|(j, &on)| on.then_some(j))
            .collect();
        let mut links: Vec<Link> = path.iter().map(|&j| self.links[j]).collect();
        links.push(tool);
        let joints = path
            .iter()
            .map(|&j| {
                let joint = &self.joints[j];
                let coupling = match joint.coupling {
                    None => None,
                    Some(c) => Some(Coupling {
                        joint: path.iter().position(|&k| k == c.joint).ok_or_else(|| {
                            format!(
                                "joint {} is coupled to joint {}, which is not on the way to \
                                 this tool frame",
                                j + 1,
                                c.joint + 1
                            )
                        })?,
                        factor: c.factor,
                    }),
                };
                Ok(Joint {
                    parent: None,
                    coupling,
                    ..joint.clone()
                })
            })
            .collect::<Result<Vec<_>, String>>()?;
        let serial = Robot {
            links,
            joints,
            sites: Vec::new(),
            planes: Vec::new(),
            sessions: Vec::new(),
            cameras: Vec::new(),
            boards: Vec::new(),
            elastic: None,
            end_effector: None,
            tolerances: Tolerances::default(),
            priors: Prior::default(),
            ..self.clone()
        };
        Ok((serial, path))
    }

    /// Index of the joint called `name`.
    pub fn joint_index(&self, name: &str) -> Option<usize> {
        self.joints
            .iter()
            .position(|j| j.name.as_deref() == Some(name))
    }

    /// The joints that are coupled to another joint's reading (0-based, ascending).
    pub(crate) fn coupled_joints(&self) -> impl Iterator<Item = usize> + '_ {
        (0..self.joints.len()).filter(|&j| self.joints[j].coupling.is_some())
    }

    /// The revolute joints of a robot with a mass model: the joints with a compliance and a
    /// lateral compliance (0-based, ascending; none for a rigid robot).
    pub fn compliant_joints(&self) -> impl Iterator<Item = usize> + '_ {
        let elastic = self.elastic.is_some();
        (0..self.joints.len())
            .filter(move |&j| elastic && self.joints[j].kind == JointKind::Revolute)
    }

    /// Number of parameters: `6(n+1) + 2n + 6 * sites + couplings + 3 * planes + 6 * sessions +
    /// 2 * compliant joints`. Robots without couplings, planes, sessions and a mass model have
    /// the thesis's numbering and count.
    pub fn param_count(&self) -> usize {
        6 * self.links.len()
            + 2 * self.joints.len()
            + 6 * self.sites.len()
            + self.coupled_joints().count()
            + 3 * self.planes.len()
            + 6 * self.sessions.len()
            + 2 * self.compliant_joints().count()
            + 4 * self.body_count()
            + 15 * self.cameras.len()
            + 6 * self.boards.len()
    }

    /// The bodies of the mass model (0 for a rigid robot).
    pub(crate) fn body_count(&self) -> usize {
        self.elastic.as_ref().map_or(0, |e| e.bodies.len())
    }

    /// All parameter ids, in the thesis's order.
    pub fn param_ids(&self) -> impl Iterator<Item = ParamId> {
        (0..self.param_count()).map(ParamId)
    }

    /// What parameter `id` is. Panics if `id` is out of range.
    #[track_caller]
    pub fn param_kind(&self, id: ParamId) -> ParamKind {
        self.try_param_kind(id).expect("parameter id out of range")
    }

    /// What parameter `id` is, `None` when out of range. Order: the 6 of each link, the n
    /// offsets, the n slopes, the 6 of each site, one coupling factor per coupled joint (in
    /// joint order), the 3 of each plane, the 6 of each session.
    pub(crate) fn try_param_kind(&self, id: ParamId) -> Option<ParamKind> {
        let (nl, nj, ns) = (self.links.len(), self.joints.len(), self.sites.len());
        let mut i = id.0;
        if i < 6 * nl {
            return Some(ParamKind::Link {
                link: i / 6,
                component: LinkComponent::ALL[i % 6],
            });
        }
        i -= 6 * nl;
        if i < nj {
            return Some(ParamKind::Offset { joint: i });
        }
        i -= nj;
        if i < nj {
            return Some(ParamKind::Slope { joint: i });
        }
        i -= nj;
        if i < 6 * ns {
            return Some(ParamKind::Site {
                site: i / 6,
                component: LinkComponent::ALL[i % 6],
            });
        }
        i -= 6 * ns;
        let nc = self.coupled_joints().count();
        if i < nc {
            let joint = self.coupled_joints().nth(i).expect("counted");
            return Some(ParamKind::Coupling { joint });
        }
        i -= nc;
        if i < 3 * self.planes.len() {
            return Some(ParamKind::Plane {
                plane: i / 3,
                component: PlaneComponent::ALL[i % 3],
            });
        }
        i -= 3 * self.planes.len();
        if i < 6 * self.sessions.len() {
            return Some(ParamKind::Session {
                session: i / 6,
                component: LinkComponent::ALL[i % 6],
            });
        }
        i -= 6 * self.sessions.len();
        let ne = self.compliant_joints().count();
        if i < ne {
            let joint = self.compliant_joints().nth(i).expect("counted");
            return Some(ParamKind::Compliance { joint });
        }
        i -= ne;
        if i < ne {
            let joint = self.compliant_joints().nth(i).expect("counted");
            return Some(ParamKind::Lateral { joint });
        }
        i -= ne;
        if i < 4 * self.body_count() {
            return Some(ParamKind::Body {
                body: i / 4,
                component: BodyComponent::ALL[i % 4],
            });
        }
        i -= 4 * self.body_count();
        if i < 15 * self.cameras.len() {
            return Some(ParamKind::Camera {
                camera: i / 15,
                component: CameraComponent::ALL[i % 15],
            });
        }
        i -= 15 * self.cameras.len();
        if i < 6 * self.boards.len() {
            return Some(ParamKind::Board {
                board: i / 6,
                component: LinkComponent::ALL[i % 6],
            });
        }
        None
    }

    /// The id of a parameter of this robot. Panics if it does not exist (a coupling of an
    /// uncoupled joint, an index out of range).
    #[track_caller]
    pub fn param_id(&self, kind: ParamKind) -> ParamId {
        let (nl, nj, ns) = (self.links.len(), self.joints.len(), self.sites.len());
        let couplings = 6 * nl + 2 * nj + 6 * ns;
        let id = match kind {
            ParamKind::Link { link, component } => 6 * link + component as usize,
            ParamKind::Offset { joint } => 6 * nl + joint,
            ParamKind::Slope { joint } => 6 * nl + nj + joint,
            ParamKind::Site { site, component } => 6 * nl + 2 * nj + 6 * site + component as usize,
            ParamKind::Coupling { joint } => {
                couplings
                    + self
                        .coupled_joints()
                        .position(|j| j == joint)
                        .expect("the joint is coupled")
            }
            ParamKind::Plane { plane, component } => {
                couplings + self.coupled_joints().count() + 3 * plane + component as usize
            }
            ParamKind::Session { session, component } => {
                couplings
                    + self.coupled_joints().count()
                    + 3 * self.planes.len()
                    + 6 * session
                    + component as usize
            }
            ParamKind::Compliance { joint } | ParamKind::Lateral { joint } => {
                let ne = self.compliant_joints().count();
                let first = couplings
                    + self.coupled_joints().count()
                    + 3 * self.planes.len()
                    + 6 * self.sessions.len()
                    + if matches!(kind, ParamKind::Lateral { .. }) {
                        ne
                    } else {
                        0
                    };
                first
                    + self
                        .compliant_joints()
                        .position(|j| j == joint)
                        .expect("the joint is compliant")
            }
            ParamKind::Body { body, component } => {
                couplings
                    + self.coupled_joints().count()
                    + 3 * self.planes.len()
                    + 6 * self.sessions.len()
                    + 2 * self.compliant_joints().count()
                    + 4 * body
                    + component as usize
            }
            ParamKind::Camera { camera, component } => {
                self.param_count() - 6 * self.boards.len() - 15 * self.cameras.len()
                    + 15 * camera
                    + component.index()
            }
            ParamKind::Board { board, component } => {
                self.param_count() - 6 * self.boards.len() + 6 * board + component as usize
            }
        };
        assert!(id < self.param_count(), "parameter out of range");
        ParamId(id)
    }

    /// The parameter's name: `link1.x`, `joint3.offset`, `joint4.slope`, `joint3.coupling`,
    /// `site.NAME.gamma`, `plane.NAME.offset`, `session.NAME.x`, `joint2.compliance`,
    /// `joint2.lateral`, `body3.mass`, `body3.x`.
    pub fn param_name(&self, id: ParamId) -> String {
        match self.param_kind(id) {
            ParamKind::Link { link, component } => {
                format!("link{}.{}", link + 1, component.as_str())
            }
            ParamKind::Offset { joint } => format!("joint{}.offset", joint + 1),
            ParamKind::Slope { joint } => format!("joint{}.slope", joint + 1),
            ParamKind::Coupling { joint } => format!("joint{}.coupling", joint + 1),
            ParamKind::Compliance { joint } => format!("joint{}.compliance", joint + 1),
            ParamKind::Lateral { joint } => format!("joint{}.lateral", joint + 1),
            ParamKind::Body { body, component } => {
                format!("body{}.{}", body + 1, component.as_str())
            }
            ParamKind::Site { site, component } => {
                format!("site.{}.{}", self.sites[site].name, component.as_str())
            }
            ParamKind::Plane { plane, component } => {
                format!("plane.{}.{}", self.planes[plane].name, component.as_str())
            }
            ParamKind::Session { session, component } => {
                format!(
                    "session.{}.{}",
                    self.sessions[session].name,
                    component.as_str()
                )
            }
            ParamKind::Camera { camera, component } => {
                format!("{}.{}", self.cameras[camera].name, component.as_str())
            }
            ParamKind::Board { board, component } => {
                format!("{}.{}", self.boards[board].name, component.as_str())
            }
        }
    }

    /// The physical quantity of parameter `id` (decides its unit).
    pub fn param_quantity(&self, id: ParamId) -> Quantity {
        match self.param_kind(id) {
            ParamKind::Link { component, .. }
            | ParamKind::Site { component, .. }
            | ParamKind::Session { component, .. } => component.quantity(),
            ParamKind::Offset { joint } => self.joints[joint].kind.variable(),
            ParamKind::Slope { joint } | ParamKind::Coupling { joint } => {
                self.joints[joint].kind.slope()
            }
            ParamKind::Plane { component, .. } => component.quantity(),
            ParamKind::Compliance { .. } | ParamKind::Lateral { .. } => Quantity::Compliance,
            ParamKind::Body { component, .. } => component.quantity(),
            ParamKind::Camera { component, .. } => component.quantity(),
            ParamKind::Board { component, .. } => component.quantity(),
        }
    }

    /// Value of parameter `id`, internal units.
    pub fn get(&self, id: ParamId) -> f64 {
        match self.param_kind(id) {
            ParamKind::Link { link, component } => self.links[link].get(component),
            ParamKind::Offset { joint } => self.joints[joint].offset,
            ParamKind::Slope { joint } => self.joints[joint].slope,
            ParamKind::Coupling { joint } => self.joints[joint].coupling.map_or(0.0, |c| c.factor),
            ParamKind::Site { site, component } => self.sites[site].frame.get(component),
            ParamKind::Plane { plane, component } => self.planes[plane].get(component),
            ParamKind::Session { session, component } => {
                self.sessions[session].frame.get(component)
            }
            ParamKind::Compliance { joint } => self.elasticity(joint).compliance,
            ParamKind::Lateral { joint } => self.elasticity(joint).lateral,
            ParamKind::Body { body, component } => {
                let b = &self.elastic.as_ref().expect("a mass model").bodies[body];
                match component {
                    BodyComponent::Mass => b.mass,
                    BodyComponent::X => b.com.x,
                    BodyComponent::Y => b.com.y,
                    BodyComponent::Z => b.com.z,
                }
            }
            ParamKind::Camera { camera, component } => self.cameras[camera].get(component),
            ParamKind::Board { board, component } => self.boards[board].pose.get(component),
        }
    }

    #[track_caller]
    fn elasticity(&self, joint: usize) -> &JointElasticity {
        &self.elastic.as_ref().expect("a mass model").joints[joint]
    }

    /// Sets parameter `id`, internal units.
    pub fn set(&mut self, id: ParamId, value: f64) {
        match self.param_kind(id) {
            ParamKind::Link { link, component } => *self.links[link].get_mut(component) = value,
            ParamKind::Offset { joint } => self.joints[joint].offset = value,
            ParamKind::Slope { joint } => self.joints[joint].slope = value,
            ParamKind::Coupling { joint } => {
                if let Some(c) = self.joints[joint].coupling.as_mut() {
                    c.factor = value;
                }
            }
            ParamKind::Site { site, component } => {
                *self.sites[site].frame.get_mut(component) = value
            }
            ParamKind::Plane { plane, component } => *self.planes[plane].get_mut(component) = value,
            ParamKind::Session { session, component } => {
                *self.sessions[session].frame.get_mut(component) = value
            }
            ParamKind::Compliance { joint } => {
                self.elastic.as_mut().expect("a mass model").joints[joint].compliance = value
            }
            ParamKind::Lateral { joint } => {
                self.elastic.as_mut().expect("a mass model").joints[joint].lateral = value
            }
            ParamKind::Body { body, component } => {
                let b = &mut self.elastic.as_mut().expect("a mass model").bodies[body];
                match component {
                    BodyComponent::Mass => b.mass = value,
                    BodyComponent::X => b.com.x = value,
                    BodyComponent::Y => b.com.y = value,
                    BodyComponent::Z => b.com.z = value,
                }
            }
            ParamKind::Camera { camera, component } => {
                *self.cameras[camera].get_mut(component) = value
            }
            ParamKind::Board { board, component } => {
                *self.boards[board].pose.get_mut(component) = value
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
    pub(crate) fn site_index(&self, name: &str) -> Option<usize> {
        self.sites.iter().position(|s| s.name == name)
    }

    /// Every name [`crate::model::kinematics::Target::named`] takes: `ee`, the end effector's
    /// own name, the sites'.
    pub fn target_names(&self) -> Vec<&str> {
        std::iter::once("ee")
            .chain(self.end_effector.as_deref())
            .chain(self.sites.iter().map(|s| s.name.as_str()))
            .collect()
    }

    /// Index of the session called `name`.
    pub fn session_index(&self, name: &str) -> Option<usize> {
        self.sessions.iter().position(|s| s.name == name)
    }

    /// Index of the camera called `name`.
    pub fn camera_index(&self, name: &str) -> Option<usize> {
        self.cameras.iter().position(|c| c.name == name)
    }

    /// Index of the board called `name`.
    pub fn board_index(&self, name: &str) -> Option<usize> {
        self.boards.iter().position(|b| b.name == name)
    }

    /// The cameras' and boards' own checks, their mounts, and their names: unique among
    /// them, and not a name the robot's other parameters start with (their parameters are
    /// `NAME.x`, `NAME.fx`).
    fn validate_optics(&self) -> Result<(), String> {
        let mut names: Vec<&str> = Vec::new();
        let mounts = self
            .cameras
            .iter()
            .map(|c| ("camera", &c.name, c.mount))
            .chain(self.boards.iter().map(|b| ("board", &b.name, b.mount)));
        for (what, name, mount) in mounts {
            let reserved = ["site", "plane", "session", "ee", "base"].contains(&name.as_str())
                || ["link", "joint", "body"].iter().any(|p| {
                    name.strip_prefix(p)
                        .is_some_and(|n| !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()))
                });
            if name.trim().is_empty()
                || reserved
                || name.contains(['.', ':', ',', '"'])
                || names.contains(&name.as_str())
            {
                return Err(format!(
                    "{what} `{name}`: a camera's or board's name must be unique among them,                      without `.`, `:`, `,` or quotes, and not `ee`, `base`, `site`, `plane`,                      `session`, `linkK`, `jointK` or `bodyK` (its parameters are `{name}.x`, ...)"
                ));
            }
            names.push(name);
            if let Mount::Site(s) = mount {
                if s >= self.sites.len() {
                    return Err(format!(
                        "{what} `{name}`: mounted on site {} but the robot has {} sites",
                        s + 1,
                        self.sites.len()
                    ));
                }
            }
        }
        for c in &self.cameras {
            c.validate()?;
        }
        for b in &self.boards {
            b.validate()?;
        }
        Ok(())
    }

    /// Index of the plane called `name`.
    pub(crate) fn plane_index(&self, name: &str) -> Option<usize> {
        self.planes.iter().position(|p| p.name == name)
    }

    /// Whether `other` has the same structure (joint kinds and couplings, links, site and plane
    /// names), so that its parameters can be copied into this robot one by one.
    pub fn same_structure(&self, other: &Robot) -> bool {
        self.links.len() == other.links.len()
            && self.joints.len() == other.joints.len()
            && self.joints.iter().zip(&other.joints).all(|(a, b)| {
                a.kind == b.kind
                    && a.coupling.map(|c| c.joint) == b.coupling.map(|c| c.joint)
                    && a.parent == b.parent
            })
            && self
                .sites
                .iter()
                .map(|s| (&s.name, s.joint))
                .eq(other.sites.iter().map(|s| (&s.name, s.joint)))
            && self
                .planes
                .iter()
                .map(|p| &p.name)
                .eq(other.planes.iter().map(|p| &p.name))
            && self.elastic.is_some() == other.elastic.is_some()
            && self.body_count() == other.body_count()
            && self
                .cameras
                .iter()
                .map(|c| (&c.name, c.mount))
                .eq(other.cameras.iter().map(|c| (&c.name, c.mount)))
            && self
                .boards
                .iter()
                .map(|b| (&b.name, b.mount, b.cols, b.rows))
                .eq(other
                    .boards
                    .iter()
                    .map(|b| (&b.name, b.mount, b.cols, b.rows)))
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

    /// Checks the model's structural invariants (n+1 links, finite values, valid sites,
    /// couplings and planes).
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
            if s.name.trim().is_empty()
                || s.name == "ee"
                || self.sites[..i].iter().any(|o| o.name == s.name)
            {
                return Err(format!(
                    "site {}: name `{}` is empty, reserved (`ee`) or used twice",
                    i + 1,
                    s.name
                ));
            }
        }
        for (i, j) in self.joints.iter().enumerate() {
            if let Some(p) = j.parent {
                if p > i {
                    return Err(format!(
                        "joint {}: parent = {p}, but a joint's parent must come before it (0, the \
                         global frame, to {i})",
                        i + 1
                    ));
                }
            }
            if let Some(name) = &j.name {
                if name.trim().is_empty()
                    || self.joints[..i]
                        .iter()
                        .any(|o| o.name.as_deref() == Some(name))
                    || name.starts_with('v') && name[1..].parse::<usize>().is_ok()
                {
                    return Err(format!(
                        "joint {}: name `{name}` is empty, used twice or looks like a reading \
                         column (`vK`)",
                        i + 1
                    ));
                }
            }
            if let Some((lo, hi)) = j.range {
                if !(crate::units::plausible(lo) && crate::units::plausible(hi) && lo < hi) {
                    return Err(format!(
                        "joint {}: reading range [{lo}, {hi}] is not two finite numbers within \
                         +-1e9, min < max",
                        i + 1
                    ));
                }
            }
            if let Some(c) = j.coupling {
                if c.joint >= self.joints.len() || c.joint == i {
                    return Err(format!(
                        "joint {}: coupled to joint {} but the robot has joints 1..{} (and a joint \
                         cannot be coupled to itself)",
                        i + 1,
                        c.joint + 1,
                        self.joints.len()
                    ));
                }
            }
        }
        if let Some(name) = &self.end_effector {
            if name.trim().is_empty() || name == "ee" || self.site_index(name).is_some() {
                return Err(format!(
                    "end effector: name `{name}` is empty, reserved (`ee`) or a site's name"
                ));
            }
        }
        for (i, s) in self.sessions.iter().enumerate() {
            if s.name.trim().is_empty() || self.sessions[..i].iter().any(|o| o.name == s.name) {
                return Err(format!(
                    "session {}: name `{}` is empty or used twice",
                    i + 1,
                    s.name
                ));
            }
        }
        for (i, p) in self.planes.iter().enumerate() {
            if p.name.trim().is_empty() || self.planes[..i].iter().any(|o| o.name == p.name) {
                return Err(format!(
                    "plane {}: name `{}` is empty or used twice",
                    i + 1,
                    p.name
                ));
            }
        }
        if let Some(e) = &self.elastic {
            e.validate(self)?;
        }
        self.validate_optics()?;
        if let Some(id) = self
            .param_ids()
            .find(|&id| !crate::units::plausible(self.get_user(id)))
        {
            return Err(format!(
                "parameter {} ({}) is {}: not a finite number within +-1e9 {}",
                id,
                self.param_name(id),
                self.get_user(id),
                self.param_unit(id)
            ));
        }
        Ok(())
    }
}
