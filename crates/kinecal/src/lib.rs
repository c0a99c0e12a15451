//! # kinecal: robot kinematic calibration
//!
//! kinecal implements the calibration model and methods of Goswami (1988): a serial robot of n
//! revolute or prismatic joints described by six parameters per link (`x, y, z` and ZYX Euler
//! angles `alpha, beta, gamma`) and two per joint transducer (`q = offset + slope * V`), plus
//! optional measurement sites; forward kinematics and an analytic parameter Jacobian; and
//! least-squares estimation by Levenberg-Marquardt, Gauss-Newton, steepest descent or truncated
//! SVD.
//!
//! The modules follow the data, each using only those before it (a test keeps it so):
//!
//! 1. [`model`]: the robot (links, joints, sites; [`model::params`] numbers its parameters),
//!    its [`model::kinematics`] (frames, the analytic Jacobian, the elastic equilibrium of a
//!    robot with a mass model), lists of parameters, priors, the robot file and the built-in
//!    robots;
//! 2. [`import`]: robots from URDF, DH tables, POE and UR kinematics, and back out;
//! 3. [`observe`]: the measurement model, one type per kind of observation owning its
//!    residuals, and the checks of data against a robot; [`files`]: the observation files;
//! 4. [`solve`]: the weighted residuals and Jacobian of a dataset ([`solve::problem`]), the
//!    closed-form placement of a far start, one solver driver with four step rules and a robust
//!    loss ([`solve::estimation`]), and outliers;
//! 5. [`identifiability`] (rank, redundancies, base set) and [`uncertainty`] (covariance,
//!    significance);
//! 6. [`predict`]: the accuracy a calibration predicts, with its bounds;
//! 7. [`report`] (the documents) and [`workflow`] (a request to an outcome: the calibration
//!    procedure);
//! 8. [`apps`]: what a calibration is used for: planning postures, compensating programs, ISO
//!    9283 figures, characteristic curves, simulated data and the public data sets;
//! 9. [`spec`]: the one door, every job as a document, run through the modules above.
//!
//! Under them all: [`error`], [`units`], [`warning`], [`source`] (files with their
//! fingerprints) and [`linalg`] (the one place the linear algebra crate is used).
//!
//! Conventions: internally metres and radians (see [`units`]); files are in the units their robot
//! file declares, unless an observation file states its own (see [`files`]). Parameters are
//! numbered as the thesis numbers them (see [`model::params`]).

pub mod error;
pub mod linalg;
pub mod source;
pub mod units;
pub mod warning;

pub mod model;

pub mod import;

pub mod files;
pub mod observe;

pub mod solve;

pub mod identifiability;
pub mod uncertainty;

pub mod predict;

pub mod report;
pub mod workflow;

pub mod apps;

pub mod spec;

pub use error::{Error, Location, Result, Setting};
pub use model::kinematics::{Chain, Frame, Pose, Target, Workspace};
pub use model::param_list::parse_param_list;
pub use model::params::{ParamId, ParamKind};
pub use model::robot::{Joint, JointKind, Link, Robot, Site};
pub use observe::{Dataset, Observation, Posture};
pub use solve::estimation::{calibrate, Calibration, CalibrationOptions, Method};
pub use units::{AngleUnit, DisplayChoice, DisplayUnits, LengthUnit, Units};
pub use warning::Warning;

/// The library page's examples compile (`cargo test --doc`).
#[cfg(doctest)]
#[doc = include_str!("../../../docs/library.md")]
pub struct LibraryDoctests;
