//! Parameter identities and lists, numbered as the thesis numbers them.
//!
//! Order: the 6 parameters of each link (`x, y, z, alpha, beta, gamma`, links 1..n+1), then the n
//! joint offsets, then the n slopes, then 6 per extra site; then, beyond the thesis, one coupling
//! factor per coupled joint and 3 per plane (`tilt_x, tilt_y, offset`), 6 per measurement session,
//! and, for a robot with a mass model ([`crate::model::robot::Elastic`]), one joint compliance per
//! revolute joint followed by one lateral compliance per revolute joint and 4 per body (mass and
//! centre of mass), then 15 per camera and 6 per board ([`crate::model::camera`]), so that a
//! robot without couplings and planes keeps the thesis's numbering. `ParamId(0)` is the thesis's `p1`.
//! Lists of parameters are read by [`crate::model::param_list`].

use std::fmt;

use crate::units::Quantity;

/// Identity of one model parameter; displayed 1-based as `p1`, `p2`, ...
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct ParamId(pub usize);

impl fmt::Display for ParamId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "p{}", self.0 + 1)
    }
}

/// One of the six components of a link (or site) transform.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LinkComponent {
    /// Translation along x.
    X,
    /// Translation along y.
    Y,
    /// Translation along z.
    Z,
    /// Rotation about z (first ZYX angle).
    Alpha,
    /// Rotation about y (second).
    Beta,
    /// Rotation about x (third).
    Gamma,
}

impl LinkComponent {
    /// The six in parameter order.
    pub const ALL: [LinkComponent; 6] = [
        LinkComponent::X,
        LinkComponent::Y,
        LinkComponent::Z,
        LinkComponent::Alpha,
        LinkComponent::Beta,
        LinkComponent::Gamma,
    ];

    /// Name as used in parameter names and robot files.
    pub fn as_str(self) -> &'static str {
        match self {
            LinkComponent::X => "x",
            LinkComponent::Y => "y",
            LinkComponent::Z => "z",
            LinkComponent::Alpha => "alpha",
            LinkComponent::Beta => "beta",
            LinkComponent::Gamma => "gamma",
        }
    }

    /// Length for x, y, z; angle for the Euler angles.
    pub fn quantity(self) -> Quantity {
        match self {
            LinkComponent::X | LinkComponent::Y | LinkComponent::Z => Quantity::Length,
            _ => Quantity::Angle,
        }
    }

    /// The component called `s`.
    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|c| c.as_str() == s)
    }
}

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

/// One of the 15 parameters of a camera: its pose in the mount frame, then its lens.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CameraComponent {
    /// A component of the camera's pose in its mount frame.
    Pose(LinkComponent),
    /// Focal length along the image's x, in pixels.
    Fx,
    /// Focal length along the image's y, in pixels.
    Fy,
    /// Principal point, x (pixels).
    Cx,
    /// Principal point, y (pixels).
    Cy,
    /// Radial distortion, r^2 term.
    K1,
    /// Radial distortion, r^4 term.
    K2,
    /// Tangential distortion p1.
    P1,
    /// Tangential distortion p2.
    P2,
    /// Radial distortion, r^6 term.
    K3,
}

impl CameraComponent {
    /// The 15 in parameter order.
    pub const ALL: [CameraComponent; 15] = [
        CameraComponent::Pose(LinkComponent::X),
        CameraComponent::Pose(LinkComponent::Y),
        CameraComponent::Pose(LinkComponent::Z),
        CameraComponent::Pose(LinkComponent::Alpha),
        CameraComponent::Pose(LinkComponent::Beta),
        CameraComponent::Pose(LinkComponent::Gamma),
        CameraComponent::Fx,
        CameraComponent::Fy,
        CameraComponent::Cx,
        CameraComponent::Cy,
        CameraComponent::K1,
        CameraComponent::K2,
        CameraComponent::P1,
        CameraComponent::P2,
        CameraComponent::K3,
    ];

    /// Its index in [`CameraComponent::ALL`].
    pub fn index(self) -> usize {
        match self {
            CameraComponent::Pose(c) => c as usize,
            CameraComponent::Fx => 6,
            CameraComponent::Fy => 7,
            CameraComponent::Cx => 8,
            CameraComponent::Cy => 9,
            CameraComponent::K1 => 10,
            CameraComponent::K2 => 11,
            CameraComponent::P1 => 12,
            CameraComponent::P2 => 13,
            CameraComponent::K3 => 14,
        }
    }

    /// Name as used in parameter names (`wrist.fx`) and robot files.
    pub fn as_str(self) -> &'static str {
        match self {
            CameraComponent::Pose(c) => c.as_str(),
            CameraComponent::Fx => "fx",
            CameraComponent::Fy => "fy",
            CameraComponent::Cx => "cx",
            CameraComponent::Cy => "cy",
            CameraComponent::K1 => "k1",
            CameraComponent::K2 => "k2",
            CameraComponent::P1 => "p1",
            CameraComponent::P2 => "p2",
            CameraComponent::K3 => "k3",
        }
    }

    /// The component called `s`.
    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|c| c.as_str() == s)
    }

    /// Length or angle for the pose, pixels for the pinhole, a pure number for distortion.
    pub fn quantity(self) -> Quantity {
        match self {
            CameraComponent::Pose(c) => c.quantity(),
            CameraComponent::Fx
            | CameraComponent::Fy
            | CameraComponent::Cx
            | CameraComponent::Cy => Quantity::Pixel,
            _ => Quantity::Ratio,
        }
    }

    /// Whether it is one of the lens's nine (not the pose).
    pub fn is_intrinsic(self) -> bool {
        !matches!(self, CameraComponent::Pose(_))
    }
}

/// One of the four parameters of a body of the mass model.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BodyComponent {
    /// The mass (kg).
    Mass,
    /// The centre of mass along x of its frame (m).
    X,
    /// Along y.
    Y,
    /// Along z.
    Z,
}

impl BodyComponent {
    /// The four in parameter order.
    pub const ALL: [BodyComponent; 4] = [
        BodyComponent::Mass,
        BodyComponent::X,
        BodyComponent::Y,
        BodyComponent::Z,
    ];

    /// Name as used in parameter names (`body2.mass`, `body2.x`).
    pub fn as_str(self) -> &'static str {
        match self {
            BodyComponent::Mass => "mass",
            BodyComponent::X => "x",
            BodyComponent::Y => "y",
            BodyComponent::Z => "z",
        }
    }

    /// Mass or length.
    pub fn quantity(self) -> Quantity {
        match self {
            BodyComponent::Mass => Quantity::Mass,
            _ => Quantity::Length,
        }
    }

    /// The component called `s`.
    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|c| c.as_str() == s)
    }
}

/// One of the three parameters of a plane.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlaneComponent {
    /// Tilt of the normal about the reference frame's x axis.
    TiltX,
    /// Tilt of the normal about the reference frame's y axis.
    TiltY,
    /// Signed distance from the global origin along the normal.
    Offset,
}

impl PlaneComponent {
    /// The three in parameter order.
    pub const ALL: [PlaneComponent; 3] = [
        PlaneComponent::TiltX,
        PlaneComponent::TiltY,
        PlaneComponent::Offset,
    ];

    /// Name as used in parameter names.
    pub fn as_str(self) -> &'static str {
        match self {
            PlaneComponent::TiltX => "tilt_x",
            PlaneComponent::TiltY => "tilt_y",
            PlaneComponent::Offset => "offset",
        }
    }

    /// Angle for the tilts, length for the offset.
    pub fn quantity(self) -> Quantity {
        match self {
            PlaneComponent::Offset => Quantity::Length,
            _ => Quantity::Angle,
        }
    }

    /// The component called `s`.
    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|c| c.as_str() == s)
    }
}

/// What a parameter is (0-based link, joint, site and plane indices).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum ParamKind {
    /// A component of link `link`.
    Link {
        /// 0-based link index.
        link: usize,
        /// Which component.
        component: LinkComponent,
    },
    /// The transducer zero offset of joint `joint`.
    Offset {
        /// 0-based joint index.
        joint: usize,
    },
    /// The transducer slope of joint `joint`.
    Slope {
        /// 0-based joint index.
        joint: usize,
    },
    /// A component of site `site`'s attachment.
    Site {
        /// 0-based site index.
        site: usize,
        /// Which component.
        component: LinkComponent,
    },
    /// The coupling factor of joint `joint` (to another joint's reading).
    Coupling {
        /// 0-based index of the coupled joint.
        joint: usize,
    },
    /// A component of plane `plane`.
    Plane {
        /// 0-based plane index.
        plane: usize,
        /// Which component.
        component: PlaneComponent,
    },
    /// A component of measurement session `session`'s frame: the pose of the robot's global
    /// frame in that session's measurement frame (an instrument moved between series).
    Session {
        /// 0-based session index ([`crate::model::robot::Robot::sessions`]).
        session: usize,
        /// Which component.
        component: LinkComponent,
    },
    /// The compliance of revolute joint `joint` about its own axis: the joint turns by
    /// `compliance * tau` under the gravity torque `tau` about its axis (rad/(N m) internally).
    Compliance {
        /// 0-based joint index.
        joint: usize,
    },
    /// A component of body `body`'s mass model: its mass (kg) or a coordinate of its centre of
    /// mass in the frame that carries it (m).
    Body {
        /// 0-based index into the mass model's bodies.
        body: usize,
        /// Which component.
        component: BodyComponent,
    },
    /// A parameter of camera `camera` ([`crate::model::camera::Camera`]): its pose in its mount
    /// frame or its lens.
    Camera {
        /// 0-based index into the robot's cameras.
        camera: usize,
        /// Which parameter.
        component: CameraComponent,
    },
    /// A component of board `board`'s pose in its mount frame
    /// ([`crate::model::camera::Board`]).
    Board {
        /// 0-based index into the robot's boards.
        board: usize,
        /// Which component.
        component: LinkComponent,
    },
    /// The lateral compliance of revolute joint `joint`: the joint tilts about its lateral axis
    /// ([`crate::model::robot::JointElasticity::lateral_axis`]) by `lateral * tau_lateral`, the gravity
    /// torque about that axis (rad/(N m) internally).
    Lateral {
        /// 0-based joint index.
        joint: usize,
    },
}
