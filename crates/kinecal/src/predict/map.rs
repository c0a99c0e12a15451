//! The accuracy map: the predicted 95 % position bound over the workspace, as colour maps on
//! slices through the reachable space and along each joint's range.
//!
//! The map's frame is the first link's distal frame (where joint 1 turns: `z` along its axis;
//! for a floor-mounted arm, up). Postures are drawn uniformly in the joint ranges and each is
//! predicted. A **horizontal slice** at height `z` collects the drawn postures whose target lies
//! within a slab of `+-4 %` of the targets' height range about it; a **vertical slice** through
//! joint 1's axis turns each drawn posture about that axis (a new reading of joint 1, within
//! its range) until its target lies in the slice's plane, alternately on either side, and
//! predicts it again (when joint 1 is not revolute, the postures within a slab are taken). A
//! cell's value is the **median** of the bounds of the postures whose target falls in it (what
//! a posture reaching that point typically gets); empty cells are not reached by any drawn
//! posture. The **joint sweeps** give, in bins of each joint's reading, the median and 95th
//! percentile of the bound over the drawn postures, and how many measured postures fall in
//! each bin. Measured postures are marked where their targets lie within a slice's slab.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use nalgebra::Vector3;

use super::Predictor;
use crate::model::kinematics::{Frame, Target};
use crate::model::robot::{JointKind, Robot};
use crate::units::Quantity;

/// One slice of the map (the robot file's length unit).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
#[non_exhaustive]
pub struct Slice {
    /// What it is, e.g. `horizontal slice at z = 0.512`.
    pub title: String,
    /// The names of its horizontal and vertical axes.
    pub axes: [String; 2],
    /// `[u_min, u_max, v_min, v_max]`.
    pub extent: [f64; 4],
    /// Cells along `u`.
    pub nu: usize,
    /// Cells along `v`.
    pub nv: usize,
    /// The median predicted bound in each cell, row by row from `v_min` (`null`: no posture
    /// drawn reaches it).
    pub values: Vec<Option<f64>>,
    /// The measured postures' targets within the slice's slab, `(u, v)`.
    pub measured: Vec<[f64; 2]>,
}

/// The predicted bound along one joint's reading range.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
#[non_exhaustive]
pub struct JointSweep {
    /// The joint (1-based).
    pub joint: usize,
    /// The bins' edges (readings), one more than the bins.
    pub edges: Vec<f64>,
    /// The median bound of the drawn postures in each bin.
    pub median: Vec<Option<f64>>,
    /// Their 95th percentile.
    pub p95: Vec<Option<f64>>,
    /// The measured postures in each bin.
    pub measured: Vec<usize>,
}

/// The accuracy map (see the module).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
#[non_exhaustive]
pub struct AccuracyMap {
    /// The length unit of every figure.
    pub unit: String,
    /// The target mapped.
    pub target: String,
    /// Postures drawn.
    pub samples: usize,
    /// The colour scale's ends (the smallest and the 99th percentile of the cells' values).
    pub scale: [f64; 2],
    /// The slices.
    pub slices: Vec<Slice>,
    /// The joint sweeps.
    pub joints: Vec<JointSweep>,
}

const CELLS: usize = 28;
const BINS: usize = 24;
const MARKS: usize = 600;

/// The accuracy map of `predictor` for `target` from `samples` drawn postures (`seed`), with
/// the measured postures marked.
pub fn accuracy_map(
    predictor: &Predictor<'_>,
    target: Target,
    measured: &[&[f64]],
    samples: usize,
    seed: u64,
) -> AccuracyMap {
    let robot = predictor.robot();
    let mut s = predictor.scratch();
    let sampled = Sampled::draw(predictor, target, measured, samples, seed, &mut s);
    let mut slices = sampled.horizontal_slices();
    slices.extend(sampled.vertical_slices(predictor, target, &mut s));
    let joints = (0..robot.dof())
        .map(|j| sampled.joint_sweep(j, measured))
        .collect();
    let mut all: Vec<f64> = slices
        .iter()
        .flat_map(|s| s.values.iter().flatten().copied())
        .collect();
    let lo = all.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = super::percentile(&mut all, 0.99);
    AccuracyMap {
        unit: robot.units.length.to_string(),
        target: crate::observe::target_name(robot, target).to_string(),
        samples,
        scale: if lo.is_finite() && hi > lo {
            [lo, hi]
        } else {
            [0.0, hi.max(1e-12)]
        },
        slices,
        joints,
    }
}

/// The drawn postures, predicted, and the measured postures' targets, in the map's frame.
struct Sampled<'r> {
    robot: &'r Robot,
    /// The map's frame: the first link's distal frame.
    base: Frame,
    /// The drawn readings, one posture after another.
    readings: Vec<f64>,
    /// (map position, bound) of each drawn posture.
    drawn: Vec<(Vector3<f64>, f64)>,
    /// The measured postures' targets.
    marks: Vec<Vector3<f64>>,
    /// The drawn targets' lowest and highest heights.
    zmin: f64,
    zmax: f64,
    /// Half a slice's slab: 4 % of the drawn targets' height range.
    slab: f64,
}

impl<'r> Sampled<'r> {
    /// Draws `samples` postures (`seed`) and predicts them; places the `measured` postures'
    /// targets.
    fn draw(
        predictor: &Predictor<'r>,
        target: Target,
        measured: &[&[f64]],
        samples: usize,
        seed: u64,
        s: &mut super::Scratch,
    ) -> Self {
        let robot = predictor.robot();
        let dof = robot.dof();
        let base = Frame::from_link(&robot.links[0]);
        let to_map = |p: &Vector3<f64>| base.rotation.transpose() * (p - base.translation);
        let readings = super::sample_readings(robot, samples, seed);
        let drawn: Vec<(Vector3<f64>, f64)> = readings
            .chunks(dof)
            .map(|r| {
                let p = predictor.predict(r, target, s);
                (to_map(&p.position), p.position_error.bound)
            })
            .collect();
        let marks: Vec<Vector3<f64>> = measured
            .iter()
            .map(|r| {
                let (_, _, p) = predictor.parameter_part(r, target, s);
                to_map(&p)
            })
            .collect();
        let (zmin, zmax) = drawn
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |a, (p, _)| {
                (a.0.min(p.z), a.1.max(p.z))
            });
        let zspan = (zmax - zmin).max(1e-9);
        Sampled {
            robot,
            base,
            readings,
            drawn,
            marks,
            zmin,
            zmax,
            slab: 0.04 * zspan,
        }
    }

    /// A position in the map's frame.
    fn to_map(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.base.rotation.transpose() * (p - self.base.translation)
    }

    /// A length in the robot file's unit.
    fn len(&self, v: f64) -> f64 {
        self.robot.units.from_si(Quantity::Length, v)
    }

    /// Horizontal slices: at the measured targets' median height, and a quartile of the drawn
    /// targets' heights away from it.
    fn horizontal_slices(&self) -> Vec<Slice> {
        let (zmin, zmax, slab) = (self.zmin, self.zmax, self.slab);
        let len = |v: f64| self.len(v);
        let mut zm: Vec<f64> = self.marks.iter().map(|p| p.z).collect();
        let z1 = if zm.is_empty() {
            0.5 * (zmin + zmax)
        } else {
            super::percentile(&mut zm, 0.5)
        };
        let mut zd: Vec<f64> = self.drawn.iter().map(|(p, _)| p.z).collect();
        let (q1, q3) = (
            super::percentile(&mut zd, 0.25),
            super::percentile(&mut zd, 0.75),
        );
        let z2 = if (q3 - z1).abs() >= (q1 - z1).abs() {
            q3
        } else {
            q1
        };
        [z1, z2]
            .into_iter()
            .map(|z| {
                let mut cells = Grid::default();
                for (p, b) in &self.drawn {
                    if (p.z - z).abs() <= slab {
                        cells.add(p.x, p.y, *b);
                    }
                }
                let measured = self
                    .marks
                    .iter()
                    .filter(|p| (p.z - z).abs() <= slab)
                    .map(|p| [len(p.x), len(p.y)])
                    .collect();
                cells.slice(
                    format!("horizontal slice at z = {:.3} (+-{:.3})", len(z), len(slab)),
                    ["x", "y"].map(String::from),
                    stride(measured),
                    &len,
                )
            })
            .collect()
    }

    /// Joint 1's reading that puts drawn posture `i` at azimuth `phi` (`side`: pi for the far
    /// side), when within its range.
    fn turned(&self, i: usize, phi: f64, side: f64) -> Option<f64> {
        let j1 = &self.robot.joints[0];
        let range = super::reading_range(self.robot, 0);
        let turn = 2.0 * std::f64::consts::PI / j1.slope.abs().max(1e-300);
        let p = self.drawn[i].0;
        let v = self.readings[i * self.robot.dof()] + (phi + side - p.y.atan2(p.x)) / j1.slope;
        let v = range.0 + (v - range.0).rem_euclid(turn);
        (v <= range.1).then_some(v)
    }

    /// Vertical slices through joint 1's axis: through the measured targets' mean azimuth,
    /// and a quarter turn from it (or less, as far as joint 1's range turns most drawn
    /// postures).
    fn vertical_slices(
        &self,
        predictor: &Predictor<'_>,
        target: Target,
        s: &mut super::Scratch,
    ) -> Vec<Slice> {
        let j1 = &self.robot.joints[0];
        let turnable = j1.kind == JointKind::Revolute && j1.slope != 0.0;
        let (sx, sy) = self.marks.iter().fold((0.0, 0.0), |a, p| {
            let r = p.x.hypot(p.y).max(1e-300);
            (a.0 + p.x / r, a.1 + p.y / r)
        });
        let phi1 = if sx == 0.0 && sy == 0.0 {
            0.0
        } else {
            sy.atan2(sx)
        };
        let usable = |phi: f64| {
            (0..self.drawn.len())
                .filter(|&i| self.turned(i, phi, far_side(i)).is_some())
                .count()
                * 3
                >= self.drawn.len()
        };
        let phi2 = [
            90.0f64, -90.0, 60.0, -60.0, 45.0, -45.0, 30.0, -30.0, 15.0, -15.0,
        ]
        .iter()
        .map(|d| phi1 + d.to_radians())
        .find(|&p| !turnable || usable(p))
        .unwrap_or(phi1 + std::f64::consts::FRAC_PI_2);
        [phi1, phi2]
            .into_iter()
            .map(|phi| self.vertical_slice(phi, turnable, predictor, target, s))
            .collect()
    }

    /// The vertical slice through joint 1's axis at azimuth `phi`: the drawn postures turned
    /// into its plane by joint 1 and predicted again (`turnable`), else those within its slab.
    fn vertical_slice(
        &self,
        phi: f64,
        turnable: bool,
        predictor: &Predictor<'_>,
        target: Target,
        s: &mut super::Scratch,
    ) -> Slice {
        let dof = self.robot.dof();
        let slab = self.slab;
        let len = |v: f64| self.len(v);
        let dir = Vector3::new(phi.cos(), phi.sin(), 0.0);
        let normal = Vector3::new(-phi.sin(), phi.cos(), 0.0);
        let mut cells = Grid::default();
        if turnable {
            let mut r = vec![0.0; dof];
            for i in 0..self.drawn.len() {
                let Some(v) = self.turned(i, phi, far_side(i)) else {
                    continue;
                };
                r.copy_from_slice(&self.readings[i * dof..(i + 1) * dof]);
                r[0] = v;
                let q = predictor.predict(&r, target, s);
                let m = self.to_map(&q.position);
                cells.add(m.dot(&dir), m.z, q.position_error.bound);
            }
        } else {
            for (p, b) in &self.drawn {
                if p.dot(&normal).abs() <= slab {
                    cells.add(p.dot(&dir), p.z, *b);
                }
            }
        }
        let measured = self
            .marks
            .iter()
            .filter(|p| p.dot(&normal).abs() <= slab)
            .map(|p| [len(p.dot(&dir)), len(p.z)])
            .collect();
        let deg = phi.to_degrees().rem_euclid(360.0);
        cells.slice(
            format!(
                "vertical slice through joint 1's axis at {deg:.0} deg (measured within +-{:.3})",
                len(slab)
            ),
            ["from the axis (signed)".to_string(), "z".to_string()],
            stride(measured),
            &len,
        )
    }

    /// The bound along joint `j`'s reading range: the drawn postures' median and 95th
    /// percentile in each bin, and the `measured` postures there.
    fn joint_sweep(&self, j: usize, measured: &[&[f64]]) -> JointSweep {
        let dof = self.robot.dof();
        let len = |v: f64| self.len(v);
        let (a, b) = super::reading_range(self.robot, j);
        let width = ((b - a) / BINS as f64).max(1e-300);
        let bin = |v: f64| (((v - a) / width).floor().max(0.0) as usize).min(BINS - 1);
        let mut per: Vec<Vec<f64>> = vec![Vec::new(); BINS];
        for (r, (_, bound)) in self.readings.chunks(dof).zip(&self.drawn) {
            per[bin(r[j])].push(*bound);
        }
        let mut measured_count = vec![0usize; BINS];
        for r in measured {
            if r[j] >= a && r[j] <= b {
                measured_count[bin(r[j])] += 1;
            }
        }
        JointSweep {
            joint: j + 1,
            edges: (0..=BINS).map(|k| a + k as f64 * width).collect(),
            median: per
                .iter_mut()
                .map(|v| (!v.is_empty()).then(|| len(super::percentile(v, 0.5))))
                .collect(),
            p95: per
                .iter_mut()
                .map(|v| (!v.is_empty()).then(|| len(super::percentile(v, 0.95))))
                .collect(),
            measured: measured_count,
        }
    }
}

/// The side of joint 1's axis drawn posture `i` is turned to: alternately the near (0) and
/// the far (pi).
fn far_side(i: usize) -> f64 {
    if i % 2 == 0 {
        0.0
    } else {
        std::f64::consts::PI
    }
}

/// At most [`MARKS`] of the measured points, evenly.
fn stride(v: Vec<[f64; 2]>) -> Vec<[f64; 2]> {
    let step = v.len().div_ceil(MARKS).max(1);
    v.into_iter().step_by(step).collect()
}

/// Bounds at points of a slice, gridded over the points' extent (the measured ones included).
#[derive(Default)]
struct Grid {
    points: Vec<(f64, f64, f64)>,
}

impl Grid {
    fn add(&mut self, u: f64, v: f64, bound: f64) {
        if u.is_finite() && v.is_finite() && bound.is_finite() {
            self.points.push((u, v, bound));
        }
    }

    /// The slice: `CELLS` cells along the longer side, square cells.
    fn slice(
        self,
        title: String,
        axes: [String; 2],
        measured: Vec<[f64; 2]>,
        len: &dyn Fn(f64) -> f64,
    ) -> Slice {
        let mut e = [
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ];
        for &(u, v, _) in &self.points {
            e = [e[0].min(u), e[1].max(u), e[2].min(v), e[3].max(v)];
        }
        if !e[0].is_finite() {
            e = [-1.0, 1.0, -1.0, 1.0];
        }
        let side = (e[1] - e[0]).max(e[3] - e[2]).max(1e-9);
        let cell = side / CELLS as f64;
        let nu = (((e[1] - e[0]) / cell).ceil() as usize).clamp(1, CELLS);
        let nv = (((e[3] - e[2]) / cell).ceil() as usize).clamp(1, CELLS);
        // Centred on the points, whole cells.
        let (cu, cv) = (0.5 * (e[0] + e[1]), 0.5 * (e[2] + e[3]));
        let extent = [
            cu - 0.5 * nu as f64 * cell,
            cu + 0.5 * nu as f64 * cell,
            cv - 0.5 * nv as f64 * cell,
            cv + 0.5 * nv as f64 * cell,
        ];
        let mut cells = vec![Vec::new(); nu * nv];
        for &(u, v, b) in &self.points {
            let iu = (((u - extent[0]) / cell).floor().max(0.0) as usize).min(nu - 1);
            let iv = (((v - extent[2]) / cell).floor().max(0.0) as usize).min(nv - 1);
            cells[iv * nu + iu].push(b);
        }
        Slice {
            title,
            axes,
            extent: extent.map(len),
            nu,
            nv,
            values: cells
                .iter_mut()
                .map(|c| (!c.is_empty()).then(|| len(super::percentile(c, 0.5))))
                .collect(),
            measured,
        }
    }
}
