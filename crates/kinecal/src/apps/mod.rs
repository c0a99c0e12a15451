//! What a calibration is used for, and what surrounds it: [`simulate`] (data of a robot with
//! known errors), [`plan`] (the postures to measure), [`compensate`] (readings that make the
//! real robot reach what was meant), [`iso9283`] (pose accuracy and repeatability as the
//! standard states them), [`curves`] (characteristic curves) and [`datasets`] (the public
//! data sets, read as they are published).

pub mod simulate;

pub mod plan;

pub mod compensate;

pub mod iso9283;

pub mod curves;

pub mod datasets;
