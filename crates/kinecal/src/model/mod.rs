//! The robot model: what a robot is and how its frames move.
//!
//! In the order each uses the ones before it: [`params`] (how the parameters are numbered and
//! named), [`robot`] (links, joints, sites, planes, sessions, the mass model), [`camera`] (cameras and calibration boards), [`kinematics`]
//! (frames, the analytic Jacobian, the elastic equilibrium), [`param_list`] (lists of
//! parameters as users write them), [`prior`] (the Gaussian prior on parameter changes),
//! [`robot_file`] (the robot TOML file) and [`examples`] (the built-in robots).

pub mod params;
pub mod robot;

pub mod camera;

pub mod kinematics;

pub mod param_list;
pub mod prior;

pub mod robot_file;

pub mod examples;
