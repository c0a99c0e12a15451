//! # kinecal: robot kinematic calibration
//!
//! kinecal implements the calibration model and methods of Goswami (1988): a serial robot of n
//! revolute or prismatic joints described by six parameters per link (`x, y, z` and ZYX Euler
//! angles `alpha, beta, gamma`) and two per joint transducer (`q = offset + slope * V`), plus
//! optional measurement sites; forward kinematics and an analytic parameter Jacobian; and
//! least-squares estimation by Levenberg-Marquardt, Gauss-Newton, steepest descent or truncated
//! SVD.
//!
//! The data flows through the modules in this order, with no cycle: [`robot`] (the model,
//! [`params`] its numbering, [`units`]) -> [`kinematics`] (frames, analytic Jacobian, the elastic
//! equilibrium of a robot with a mass model) -> [`param_list`] (lists of parameters) ->
//! [`observe`] (the measurement model: one type per kind of observation, owning its residuals)
//! -> [`problem`] (weighted residuals and Jacobian of a dataset) ->
//! [`estimation`] (one solver driver, four step rules, robust loss) -> [`identifiability`]
//! (rank, redundancies, base set) -> [`uncertainty`] (covariance, significance) and
//! [`outliers`] -> [`workflow`] (request to outcome: the calibration procedure) -> [`report`]
//! (the outcome as a document). Before a calibration, [`plan`] chooses the postures to
//! measure; after it, [`compensate`] puts it to work (readings that make the real robot reach
//! what was meant), and [`iso9283`] states its pose accuracy and repeatability as ISO 9283 does
//! (test poses in a cube, figures from a measurement log). Around them: [`robot_file`] (robot TOML), [`files`] (the observation files:
//! CSV readers and writers), [`import`] (URDF, DH, POE and UR kinematics in, URDF, DH, UR
//! kinematics and joint tables out), [`datasets`] (public data sets), [`simulate`], [`curves`],
//! [`source`] (files with their fingerprints), [`warning`] and [`error`].
//!
//! Conventions: internally metres and radians (see [`units`]); files are in the units their robot
//! file declares, unless an observation file states its own (see [`files`]). Parameters are numbered as the thesis numbers them (see [`params`]).

pub mod compensate;
pub mod curves;
pub mod datasets;
pub mod error;
pub mod estimation;
pub mod examples;
pub mod files;
pub mod identifiability;
pub mod import;
pub mod iso9283;
pub mod kinematics;
pub mod linalg;
pub mod observe;
pub mod outliers;
pub mod param_list;
pub mod params;
pub mod plan;
pub mod predict;
pub mod prior;
pub mod problem;
pub mod registration;
pub mod report;
pub mod robot;
pub mod robot_file;
pub mod sanity;
pub mod simulate;
pub mod source;
pub mod spec;
pub mod uncertainty;
pub mod units;
pub mod warning;
pub mod workflow;

pub use error::{Error, Location, Result, Setting};
pub use estimation::{calibrate, Calibration, CalibrationOptions, Method};
pub use kinematics::{Chain, Frame, Pose, Target, Workspace};
pub use observe::{Dataset, Observation, Posture};
pub use param_list::parse_param_list;
pub use params::{ParamId, ParamKind};
pub use robot::{Joint, JointKind, Link, Robot, Site};
pub use units::{AngleUnit, DisplayChoice, DisplayUnits, LengthUnit, Units};
pub use warning::Warning;

/// The library page's examples compile (`cargo test --doc`).
#[cfg(doctest)]
#[doc = include_str!("../../../docs/library.md")]
pub struct LibraryDoctests;
