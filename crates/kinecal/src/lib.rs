//! # kinecal: robot kinematic calibration
//!
//! kinecal implements the calibration model and methods of Goswami (1988): a serial robot of n
//! revolute or prismatic joints described by six parameters per link (`x, y, z` and ZYX Euler
//! angles `alpha, beta, gamma`) and two per joint transducer (`q = offset + slope * V`), plus
//! optional measurement sites; forward kinematics and an analytic parameter Jacobian; and
//! least-squares estimation by Levenberg-Marquardt, Gauss-Newton, steepest descent or truncated
//! SVD.
//!
//! The data flows through the modules in this order: [`robot`] (the model, [`params`] its
//! numbering) -> [`kinematics`] (poses, Jacobian) -> [`measurement`] (what was measured) ->
//! [`estimation`] (solvers) -> [`report`] (what the user reads). [`robot_file`] and
//! [`measurement_file`] read and write the file formats; [`simulate`] synthesizes data.
//!
//! Conventions: internally metres and radians (see [`units`]); files are in the units their robot
//! file declares. Parameters are numbered as the thesis numbers them (see [`params`]).

pub mod curves;
pub mod datasets;
pub mod error;
pub mod estimation;
pub mod examples;
pub mod identifiability;
pub mod import;
pub mod kinematics;
mod linalg;
pub mod measurement;
pub mod measurement_file;
pub mod params;
pub mod report;
pub mod robot;
pub mod robot_file;
pub mod simulate;
pub mod uncertainty;
pub mod units;

pub use error::{Error, Location, Result};
pub use estimation::{calibrate, Calibration, CalibrationOptions, Method};
pub use kinematics::{Chain, Frame, Pose, Target, Workspace};
pub use measurement::{Dataset, Measurement, Posture};
pub use params::{parse_param_list, ParamId, ParamKind};
pub use robot::{Joint, JointKind, Link, Robot, Site};
pub use units::{AngleUnit, LengthUnit, Units};
