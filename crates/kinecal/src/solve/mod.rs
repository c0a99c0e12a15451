//! Solving for the parameters: in the order each uses the ones before it, [`problem`] (the
//! weighted residuals and Jacobian of a dataset), [`estimation`] (one solver driver, four step
//! rules, a robust loss), [`registration`] (the closed-form placement of a far start: the
//! measurement frame, the measured frames, each session's frame), `camera_start` (the closed
//! forms of camera calibration: homographies, Zhang's lens, board poses, hand-eye), [`hand_eye`]
//! (cameras and boards placed from nothing with them) and [`outliers`].

pub mod problem;

pub mod estimation;

pub mod registration;

pub(crate) mod camera_start;
pub mod hand_eye;

pub mod outliers;
