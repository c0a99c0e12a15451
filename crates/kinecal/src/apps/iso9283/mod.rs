//! ISO 9283 pose characteristics: the test poses in a cube ([`plan`]), and pose accuracy and
//! repeatability, distance accuracy and repeatability and multi-directional pose accuracy
//! variation computed from a measurement log ([`evaluate`]).
//!
//! # The test poses (ISO 9283:1998, 6.8)
//!
//! The standard places its test poses in a cube inside the robot's working space, on one of the
//! cube's diagonal planes (the rectangle through two opposite, parallel edges). kinecal's cube is
//! axis-aligned in the robot's global frame, and its measuring plane is the one through the edge
//! at low `y` and low `z` and the edge at high `y` and high `z` (both parallel to `x`): the corners
//! `C1 = (-,-,-)`, `C2 = (+,-,-)`, `C7 = (+,+,+)`, `C8 = (-,+,+)` (signs of `x, y, z` from the
//! centre). Its diagonals `C1-C7` and `C2-C8` are space diagonals of the cube, of length
//! `L = side * sqrt(3)`.
//!
//! - `P1` is the intersection of the diagonals: the cube's centre.
//! - `P2` to `P5` lie on the diagonals at 10 % of the diagonal's length from its ends (the
//!   standard allows 10 % +- 2 %): each is `P1 + 0.8 (C - P1)` for its corner `C`. kinecal numbers
//!   them round the plane: `P2` near `C8`, `P3` near `C7`, `P4` near `C2`, `P5` near `C1` (so `P2`
//!   and `P4`, `P3` and `P5` are the ends of one diagonal).
//! - One cycle visits them in the standard's order [`CYCLE`]: `P1, P5, P4, P3, P2` (then back to
//!   `P1` for the next cycle), approaching every pose from the same direction (unidirectional),
//!   for [`STANDARD_CYCLES`] cycles (6.9).
//!
//! Every pose has the same tool attitude, given as ISO 9283's `a, b, c`: rotations about the
//! global frame's `x`, `y` and `z` axes, `R = Rz(c) Ry(b) Rx(a)`, which is kinecal's ZYX Euler
//! attitude with `alpha = c`, `beta = b`, `gamma = a`. Without an attitude the poses are
//! positions (the tool's attitude is what the inverse kinematics gives).
//!
//! The cube is given ([`Cube`]) or searched for ([`PlanRequest::cube`] `None`): a grid over the
//! box of positions the end effector reaches within the joint ranges is tested point by point
//! (inverse kinematics through [`crate::apps::compensate::TargetSearch`], the solution's forward
//! kinematics compared with the goal; unreachable, outside a joint range or near a singularity
//! counts as not reached); the largest axis-aligned cube of reached grid points is then grown or
//! shrunk, by bisection of its side about its centre, until its five test poses *and its eight
//! corners* are reached, and its centre moved by half a grid step, then a quarter, along each
//! axis where that lets it grow. This is a search on a grid: it finds a large cube, not a proof of the
//! largest.
//!
//! # The figures (ISO 9283:1998, 7.2 and 7.3)
//!
//! A log holds, per row, the pose index `j` (1 to 5), the cycle, the commanded pose `x_c, y_c,
//! z_c` (and `a_c, b_c, c_c`) and the attained (measured) pose `x, y, z` (and `a, b, c`), and
//! optionally the approach direction. For one pose and its `n` attained poses `(x_i, y_i, z_i)`:
//!
//! | symbol | definition |
//! | --- | --- |
//! | `xbar, ybar, zbar` | the barycentre: mean of the attained positions |
//! | `APx, APy, APz` | `xbar - x_c`, `ybar - y_c`, `zbar - z_c` |
//! | `AP` | pose accuracy: `sqrt(APx^2 + APy^2 + APz^2)` |
//! | `APa, APb, APc` | attitude accuracy: mean of `a_i - a_c` (and for `b`, `c`), each difference wrapped into half a turn either side |
//! | `l_i` | `sqrt((x_i - xbar)^2 + (y_i - ybar)^2 + (z_i - zbar)^2)`, the distance from the barycentre |
//! | `lbar`, `S_l` | the mean of the `l_i` and their standard deviation (`n - 1` in the denominator) |
//! | `RP` | pose repeatability: `lbar + 3 S_l` |
//! | `RPa, RPb, RPc` | attitude repeatability: `+-3 S_a` with `S_a` the standard deviation (`n - 1`) of the `a_i` (wrapped as above), likewise `b`, `c` |
//! | `vAP` | multi-directional pose accuracy variation: the largest distance between the barycentres of the attained positions reached from different approach directions (`vAPa, vAPb, vAPc` likewise of the mean angles) |
//! | `D_i`, `D_c` | for two poses, the distance between their attained positions in cycle `i`, and between their commanded positions |
//! | `AD` | distance accuracy: `Dbar - D_c` (`ADx = mean(x1_i - x2_i) - (x1_c - x2_c)`, likewise `y`, `z`) |
//! | `RD` | distance repeatability: `+-3 S_D`, `S_D` the standard deviation (`n - 1`) of the `D_i` |
//!
//! The standard asks for 30 cycles; with fewer the figures are computed and the result carries a
//! warning. A pose measured in one cycle has its accuracy (`AP`, and `AD` to the poses of the
//! same cycle) but no repeatability (`RP`, `RD` need 2 cycles): a series that measures each pose
//! once still states its accuracy. Distances are reported for every pair of poses attained in
//! the same cycles (rows paired by cycle number and direction). With approach directions, `AP`
//! and `RP` pool every direction (the standard's are unidirectional: log the multi-directional
//! test apart), and a warning says so.
//!
//! A log may hold several tests (a `test` column: a series of cubes); the figures are computed
//! test by test, distances within a test, and [`Summary`] gives them across the tests. Besides
//! `P1..P5`, a log may name the cube's corners `C1..C8` (a series that measured the corners).
//! [`log_from_measurements`] makes a log from a measurement file and a robot model, and
//! [`predict_compensated`] adds the `AP` a calibration predicts once the program is compensated
//! (see [`measured`]).
//!
//! # Units and frames
//!
//! [`plan`] works in metres and radians in the robot's global frame, as the rest of the library;
//! its file ([`write_plan`], [`read_plan`]) is in the robot file's units. A log and its figures
//! are in the log's own units: lengths in its length unit (stated or not: the figures are in it
//! either way), angles in its angle unit, which must be known when the log has attitudes (wrapping
//! needs the turn: 360 deg or `2 pi` rad). A log states its units in comment lines before its
//! header (`# length_unit = mm`, `# angle_unit = deg`), or they are given ([`LogUnits`]); both must
//! agree. The commanded and attained poses must be in one frame (the robot's base frame, the
//! tracker registered to it).

mod figures;
pub mod measured;

use std::collections::BTreeMap;

pub use figures::{
    evaluate, evaluation_schema, Compensated, DistanceFigures, Evaluation, Multidirectional,
    PoseFigures, PoseSummary, Spread, Summary, SCHEMA_VERSION,
};

pub use measured::{
    cube_roles, log_from_measurements, log_placed, predict_compensated, read_roles, write_roles,
    PlacedLog, Role, Roles,
};

use nalgebra::{Matrix3, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};

use crate::apps::compensate::{Goal, Options, TargetSearch};
use crate::error::{Error, Location, Result, Setting};
use crate::files::table;
use crate::model::kinematics::{euler_zyx, log_so3, rot_zyx, Chain, Frame, Target};
use crate::model::robot::Robot;
use crate::units::{number, AngleUnit, LengthUnit, Quantity};

/// The order in which one cycle visits the poses (ISO 9283:1998, 7.2): `P1, P5, P4, P3, P2`,
/// then `P1` again to start the next cycle.
pub const CYCLE: [usize; 5] = [1, 5, 4, 3, 2];

/// The number of cycles the standard asks for (ISO 9283:1998, 6.9).
pub const STANDARD_CYCLES: usize = 30;

/// Where `P2` to `P5` lie on the diagonals: this fraction of the diagonal's length from its
/// corner (the standard's 10 %).
pub(crate) const CORNER_FRACTION: f64 = 0.1;

/// The corner of the measuring plane each of `P2..P5` is near, as signs of `x, y, z` from the
/// centre.
const NEAR: [[f64; 3]; 4] = [
    [-1.0, 1.0, 1.0],   // P2: C8
    [1.0, 1.0, 1.0],    // P3: C7
    [1.0, -1.0, -1.0],  // P4: C2
    [-1.0, -1.0, -1.0], // P5: C1
];

/// An axis-aligned cube in the robot's global frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Cube {
    /// Its centre.
    pub centre: [f64; 3],
    /// The length of its edges.
    pub side: f64,
}

impl Cube {
    fn centre(&self) -> Vector3<f64> {
        Vector3::from(self.centre)
    }

    /// Its eight corners, `x` changing fastest (from `(-,-,-)` to `(+,+,+)`).
    pub fn corners(&self) -> [[f64; 3]; 8] {
        let h = 0.5 * self.side;
        std::array::from_fn(|k| {
            let s = |bit: usize| if k & (1 << bit) != 0 { h } else { -h };
            [
                self.centre[0] + s(0),
                self.centre[1] + s(1),
                self.centre[2] + s(2),
            ]
        })
    }

    /// The positions of the test poses `P1..P5` (see the module's documentation).
    pub fn test_positions(&self) -> [[f64; 3]; 5] {
        let c = self.centre();
        let h = 0.5 * self.side;
        // From the corner, 10 % of the diagonal towards the opposite corner: 80 % of the way
        // from the centre to the corner.
        let k = 1.0 - 2.0 * CORNER_FRACTION;
        std::array::from_fn(|i| {
            if i == 0 {
                return self.centre;
            }
            let s = NEAR[i - 1];
            (c + k * h * Vector3::new(s[0], s[1], s[2])).into()
        })
    }
}

/// What [`plan`] is asked.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlanRequest {
    /// The cube (m, global frame); `None` to search for a large one.
    pub cube: Option<Cube>,
    /// The tool attitude `a, b, c` (rad; see the module's documentation); `None` for positions.
    pub attitude: Option<[f64; 3]>,
    /// Grid points along the longest side of the searched box (at least 3).
    pub resolution: usize,
}

impl Default for PlanRequest {
    fn default() -> Self {
        PlanRequest {
            cube: None,
            attitude: None,
            resolution: 10,
        }
    }
}

/// One test pose of a plan, reached by the robot's inverse kinematics.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[non_exhaustive]
pub struct TestPose {
    /// Its index: 1 to 5 for `P1..P5`.
    pub pose: usize,
    /// Its position (m, global frame).
    pub position: [f64; 3],
    /// Its attitude `a, b, c` (rad), when the plan has one.
    pub attitude: Option<[f64; 3]>,
    /// The readings that reach it, inside the joint ranges.
    pub readings: Vec<f64>,
    /// The distance from the goal of the forward kinematics at the readings (m).
    pub position_error: f64,
    /// The angle between the goal's and the forward kinematics' attitudes (rad).
    pub attitude_error: Option<f64>,
}

/// How a cube was searched for.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[non_exhaustive]
pub struct SearchInfo {
    /// The grid's step (m).
    pub step: f64,
    /// Grid points tested with the inverse kinematics.
    pub tested: usize,
    /// Grid points reached.
    pub reached: usize,
}

/// The test poses of ISO 9283 for one robot.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[non_exhaustive]
pub struct TestPlan {
    /// The cube (m).
    pub cube: Cube,
    /// The attitude `a, b, c` (rad), if any.
    pub attitude: Option<[f64; 3]>,
    /// `P1..P5`, in index order.
    pub poses: Vec<TestPose>,
    /// How the cube was found, when it was searched for (its corners are then reached too).
    pub search: Option<SearchInfo>,
}

/// Inverse kinematics with a check: a position (and the plan's attitude) counts as reached when
/// a usable solution exists and its forward kinematics agrees with the goal.
struct Reacher<'r> {
    search: TargetSearch<'r>,
    chain: Chain<'r>,
    rotation: Option<Matrix3<f64>>,
    out: Vec<f64>,
    tolerance: f64,
}

impl<'r> Reacher<'r> {
    fn new(robot: &'r Robot, attitude: Option<[f64; 3]>) -> Result<Self> {
        Ok(Reacher {
            search: TargetSearch::new(robot, robot, Options::default())?,
            chain: Chain::new(robot),
            rotation: attitude.map(|[a, b, c]| rot_zyx(c, b, a)),
            out: vec![0.0; robot.dof()],
            tolerance: 1e-6,
        })
    }

    fn reach(&mut self, p: [f64; 3]) -> Option<TestPose> {
        let p = Vector3::from(p);
        let goal = match self.rotation {
            Some(r) => Goal::Pose(Frame {
                rotation: r,
                translation: p,
            }),
            None => Goal::Position(p),
        };
        let s = self
            .search
            .solve(&goal, Target::EndEffector, None, &mut self.out);
        if s.flags.unreachable || s.flags.out_of_range != 0 || s.flags.singular {
            return None;
        }
        let f = self.chain.frame_at(&self.out, Target::EndEffector);
        let position_error = (f.translation - p).norm();
        let attitude_error = self
            .rotation
            .map(|r| log_so3(&(r * f.rotation.transpose())).norm());
        let within = self
            .chain
            .robot()
            .joints
            .iter()
            .enumerate()
            .all(|(j, joint)| {
                joint
                    .range
                    .is_none_or(|(lo, hi)| (lo..=hi).contains(&self.out[j]))
            });
        (within
            && position_error <= self.tolerance
            && attitude_error.is_none_or(|a| a <= self.tolerance))
        .then(|| TestPose {
            pose: 0,
            position: p.into(),
            attitude: None,
            readings: self.out.clone(),
            position_error,
            attitude_error,
        })
    }

    /// The test poses of `cube`, when all are reached (and, with `corners`, its corners too).
    fn cube(&mut self, cube: &Cube, corners: bool) -> Option<Vec<TestPose>> {
        let mut poses = Vec::with_capacity(5);
        for (i, p) in cube.test_positions().into_iter().enumerate() {
            let mut t = self.reach(p)?;
            t.pose = i + 1;
            poses.push(t);
        }
        if corners {
            for c in cube.corners() {
                self.reach(c)?;
            }
        }
        Some(poses)
    }
}

/// The ISO 9283 test poses for `robot` (see the module's documentation): in the cube given, or
/// in a large cube searched for. An error when a pose of a given cube, or every cube tried, is
/// out of reach.
pub fn plan(robot: &Robot, request: &PlanRequest) -> Result<TestPlan> {
    let mut reacher = Reacher::new(robot, request.attitude)?;
    let with_attitude = |mut poses: Vec<TestPose>| {
        for p in &mut poses {
            p.attitude = request.attitude;
        }
        poses
    };
    if let Some(cube) = request.cube {
        if !(cube.side.is_finite() && cube.side > 0.0) {
            return Err(Error::Problem(format!(
                "the cube's side must be a positive number, got {}",
                cube.side
            )));
        }
        if let Some(v) = cube.centre.iter().find(|v| !v.is_finite()) {
            return Err(Error::Problem(format!(
                "the cube's centre must be finite, got {v}"
            )));
        }
        let mut poses = Vec::new();
        for (i, p) in cube.test_positions().into_iter().enumerate() {
            match reacher.reach(p) {
                Some(mut t) => {
                    t.pose = i + 1;
                    poses.push(t);
                }
                None => {
                    let u = robot.units;
                    let l = |v: f64| number::format_number(u.from_si(Quantity::Length, v));
                    return Err(Error::CubeOutOfReach {
                        pose: i + 1,
                        message: format!(
                            "P{} ({}, {}, {} {}) of the cube is out of reach{}: no solution \
                             inside the joint ranges, away from singularities (a smaller cube, \
                             or another centre or attitude)",
                            i + 1,
                            l(p[0]),
                            l(p[1]),
                            l(p[2]),
                            u.length,
                            if request.attitude.is_some() {
                                " at the attitude"
                            } else {
                                ""
                            }
                        ),
                    });
                }
            }
        }
        return Ok(TestPlan {
            cube,
            attitude: request.attitude,
            poses: with_attitude(poses),
            search: None,
        });
    }
    let (cube, poses, info) = search(robot, &mut reacher, request.resolution.max(3))?;
    Ok(TestPlan {
        cube,
        attitude: request.attitude,
        poses: with_attitude(poses),
        search: Some(info),
    })
}

/// The grid search for a large cube (see the module's documentation).
fn search(
    robot: &Robot,
    reacher: &mut Reacher<'_>,
    resolution: usize,
) -> Result<(Cube, Vec<TestPose>, SearchInfo)> {
    let samples = sample_workspace(robot);
    let grid = SearchGrid::over(&samples, resolution)?;
    let (reached, info) = reach_grid(reacher, &grid, &samples);
    let size = reached_cube_sizes(&grid, &reached);
    let largest = size.iter().copied().max().unwrap_or(0);
    if largest == 0 {
        return Err(Error::Problem(format!(
            "no grid point of the working space (step {} {}) is reached{}: no cube found",
            number::format_number(robot.units.from_si(Quantity::Length, grid.step)),
            robot.units.length,
            if reacher.rotation.is_some() {
                " at the attitude"
            } else {
                ""
            }
        )));
    }
    let best = best_grid_cube(reacher, &grid, &size, largest)
        .map(|best| recentre(reacher, best, grid.step));
    match best {
        Some((cube, poses)) => Ok((cube, poses, info)),
        None => Err(Error::Problem(
            "no cube whose test poses and corners are all reached was found".into(),
        )),
    }
}

/// Positions the end effector reaches within the joint ranges, at any attitude (m, global
/// frame): its forward kinematics at 2000 postures sampled across the joint ranges (seed 9283:
/// the same sample on every run).
fn sample_workspace(robot: &Robot) -> Vec<Vector3<f64>> {
    let chain = Chain::new(robot);
    crate::apps::simulate::sample_postures(robot, 2000, 9283)
        .iter()
        .map(|p| chain.frame_at(&p.readings, Target::EndEffector).translation)
        .collect()
}

/// The search's grid of positions (m, global frame): `n[a]` points along axis `a`, `step`
/// apart (the same along every axis), from the low corner `lo` of the box of sampled positions.
struct SearchGrid {
    /// The low corner of the box (m).
    lo: Vector3<f64>,
    /// The distance between neighbouring points (m).
    step: f64,
    /// The number of points along `x`, `y`, `z`.
    n: [usize; 3],
}

impl SearchGrid {
    /// The grid over the box bounding `samples` (m), `resolution` points (at least 2) along its
    /// longest side; an error when the box has no extent (the end effector does not move).
    fn over(samples: &[Vector3<f64>], resolution: usize) -> Result<Self> {
        let mut lo = Vector3::repeat(f64::INFINITY);
        let mut hi = Vector3::repeat(f64::NEG_INFINITY);
        for s in samples {
            lo = lo.inf(s);
            hi = hi.sup(s);
        }
        let extent = (hi - lo).max();
        if !(extent.is_finite() && extent > 0.0) {
            return Err(Error::Problem(
                "the end effector does not move within the joint ranges: no cube to search".into(),
            ));
        }
        let step = extent / (resolution - 1) as f64;
        let n = std::array::from_fn(|a| ((hi[a] - lo[a]) / step).round() as usize + 1);
        Ok(SearchGrid { lo, step, n })
    }

    /// The position of grid point `(i, j, k)` (m, global frame).
    fn at(&self, i: usize, j: usize, k: usize) -> [f64; 3] {
        [
            self.lo.x + i as f64 * self.step,
            self.lo.y + j as f64 * self.step,
            self.lo.z + k as f64 * self.step,
        ]
    }

    /// The index of grid point `(i, j, k)` in a per-point array (`i` changing fastest).
    fn index(&self, i: usize, j: usize, k: usize) -> usize {
        (k * self.n[1] + j) * self.n[0] + i
    }

    /// The number of grid points.
    fn point_count(&self) -> usize {
        self.n[0] * self.n[1] * self.n[2]
    }

    /// Every grid point `(i, j, k)` in index order (`i` changing fastest, then `j`, then `k`).
    fn points(&self) -> impl Iterator<Item = (usize, usize, usize)> {
        let n = self.n;
        (0..n[2]).flat_map(move |k| (0..n[1]).flat_map(move |j| (0..n[0]).map(move |i| (i, j, k))))
    }

    /// Every grid point `(i, j, k)` in serpentine order: layer by layer in `z`, each row of a
    /// layer (along `x`) the other way from the one before, the rows of a layer the other way
    /// from the layer before, so that each point is next to the one before.
    fn serpentine(&self) -> impl Iterator<Item = (usize, usize, usize)> {
        let n = self.n;
        (0..n[2]).flat_map(move |k| {
            (0..n[1]).flat_map(move |jj| {
                let j = if k % 2 == 0 { jj } else { n[1] - 1 - jj };
                (0..n[0]).map(move |ii| {
                    let i = if (k * n[1] + jj) % 2 == 0 {
                        ii
                    } else {
                        n[0] - 1 - ii
                    };
                    (i, j, k)
                })
            })
        })
    }
}

/// Which grid points the end effector reaches (per [`SearchGrid::index`]), and how many were
/// tested and reached. The points are tested with the inverse kinematics in serpentine order
/// (each search starts from the previous solution); a point farther than a grid step from every
/// sampled position is out of reach, not worth a search, and not tested.
fn reach_grid(
    reacher: &mut Reacher<'_>,
    grid: &SearchGrid,
    samples: &[Vector3<f64>],
) -> (Vec<bool>, SearchInfo) {
    let h = grid.step;
    let mut reached = vec![false; grid.point_count()];
    let (mut tested, mut count) = (0, 0);
    for (i, j, k) in grid.serpentine() {
        let p = Vector3::from(grid.at(i, j, k));
        if !samples.iter().any(|s| (s - p).norm_squared() <= h * h) {
            continue;
        }
        tested += 1;
        if reacher.reach(p.into()).is_some() {
            reached[grid.index(i, j, k)] = true;
            count += 1;
        }
    }
    let info = SearchInfo {
        step: h,
        tested,
        reached: count,
    };
    (reached, info)
}

/// Per grid point (per [`SearchGrid::index`]): the number of points along the edge of the
/// largest cube of reached grid points whose high corner (`+x, +y, +z`) it is; 0 where the point
/// is not reached.
fn reached_cube_sizes(grid: &SearchGrid, reached: &[bool]) -> Vec<usize> {
    let idx = |i: usize, j: usize, k: usize| grid.index(i, j, k);
    let mut size = vec![0usize; reached.len()];
    for (i, j, k) in grid.points() {
        if !reached[idx(i, j, k)] {
            continue;
        }
        let m = if i == 0 || j == 0 || k == 0 {
            0
        } else {
            [
                idx(i - 1, j, k),
                idx(i, j - 1, k),
                idx(i, j, k - 1),
                idx(i - 1, j - 1, k),
                idx(i - 1, j, k - 1),
                idx(i, j - 1, k - 1),
                idx(i - 1, j - 1, k - 1),
            ]
            .iter()
            .map(|&q| size[q])
            .min()
            .unwrap_or(0)
        };
        size[idx(i, j, k)] = m + 1;
    }
    size
}

/// The largest cube [`fit`] finds about the grid's candidates: the first 4 (in index order) of
/// the largest cubes of reached grid points (`largest` points along the edge, per
/// `size`), then, unless one of those verified holds its size, the first 4 one grid step
/// smaller. `None` when no candidate has its test poses and corners all reached.
fn best_grid_cube(
    reacher: &mut Reacher<'_>,
    grid: &SearchGrid,
    size: &[usize],
    largest: usize,
) -> Option<(Cube, Vec<TestPose>)> {
    let h = grid.step;
    let mut best: Option<(Cube, Vec<TestPose>)> = None;
    for m in (largest.saturating_sub(1).max(1)..=largest).rev() {
        let candidates = grid
            .points()
            .filter(|&(i, j, k)| size[grid.index(i, j, k)] == m)
            .take(4);
        for (i, j, k) in candidates {
            let side = (m - 1) as f64 * h;
            let top = grid.at(i, j, k);
            let centre = std::array::from_fn(|a| top[a] - 0.5 * side);
            if let Some(found) = fit(reacher, centre, side, h, true) {
                if best.as_ref().is_none_or(|b| found.0.side > b.0.side) {
                    best = Some(found);
                }
            }
        }
        if let Some(b) = &best {
            // A cube of this size class was verified; a smaller class cannot beat it by much.
            if b.0.side >= (m as f64 - 1.0) * h {
                break;
            }
        }
    }
    best
}

/// `best` with its centre moved (m, global frame) by half the grid step `h`, then a quarter
/// step, along each axis either way, keeping each move that lets the cube grow (by more than a
/// part in 10^9): the grid puts the centre within half a step of the best one.
fn recentre(
    reacher: &mut Reacher<'_>,
    mut best: (Cube, Vec<TestPose>),
    h: f64,
) -> (Cube, Vec<TestPose>) {
    let mut centre = best.0.centre;
    for shift in [0.5 * h, 0.25 * h] {
        for axis in 0..3 {
            for sign in [-1.0, 1.0] {
                let mut c = centre;
                c[axis] += sign * shift;
                let side = best.0.side;
                if let Some(found) = fit(reacher, c, side, 0.25 * h, false) {
                    if found.0.side > side * (1.0 + 1e-9) {
                        centre = c;
                        best = found;
                    }
                }
            }
        }
    }
    best
}

/// The largest side, about `centre`, found from `side` by steps of `h` and bisection, whose test
/// poses and corners are all reached; `None` when not even a tiny one is, or (without `shrink`)
/// when `side` is not.
fn fit(
    reacher: &mut Reacher<'_>,
    centre: [f64; 3],
    side: f64,
    h: f64,
    shrink: bool,
) -> Option<(Cube, Vec<TestPose>)> {
    let mut check = |s: f64| {
        reacher
            .cube(&Cube { centre, side: s }, true)
            .map(|p| (Cube { centre, side: s }, p))
    };
    let (mut good, mut bad) = match (side > 0.0).then(|| check(side)).flatten() {
        Some(g) => {
            // Grow a grid step at a time, then bisect.
            let mut good = g;
            let mut bad = None;
            for step in 1..=3 {
                let s = side + step as f64 * h;
                match check(s) {
                    Some(g) => good = g,
                    None => {
                        bad = Some(s);
                        break;
                    }
                }
            }
            (Some(good), bad.unwrap_or(f64::NAN))
        }
        None if !shrink => return None,
        None => (None, if side > 0.0 { side } else { h }),
    };
    if bad.is_nan() {
        return good;
    }
    let mut lo = good.as_ref().map_or(0.0, |g| g.0.side);
    for _ in 0..6 {
        let mid = 0.5 * (lo + bad);
        match check(mid) {
            Some(g) => {
                lo = mid;
                good = Some(g);
            }
            None => bad = mid,
        }
    }
    good
}

/// The header of a plan file for `robot`: `pose,x,y,z[,a,b,c],v1..vn`.
fn plan_header(robot: &Robot, attitude: bool) -> Vec<String> {
    let mut h: Vec<String> = ["pose", "x", "y", "z"].map(String::from).to_vec();
    if attitude {
        h.extend(["a", "b", "c"].map(String::from));
    }
    h.extend((1..=robot.dof()).map(|j| format!("v{j}")));
    h
}

/// A plan as a CSV file in the robot file's units: comment lines (the cube, the cycle order,
/// the units), then `pose,x,y,z[,a,b,c],v1..vn` for `P1..P5` (the readings that reach each pose
/// within the joint ranges). [`read_plan`] reads it back.
pub fn write_plan(robot: &Robot, plan: &TestPlan) -> String {
    let u = robot.units;
    let l = |v: f64| u.from_si(Quantity::Length, v);
    let a = |v: f64| u.from_si(Quantity::Angle, v);
    let ls = number::Scale::of(plan.poses.iter().flat_map(|p| p.position.map(l)));
    let as_ = number::Scale::of(
        plan.poses
            .iter()
            .flat_map(|p| p.attitude.unwrap_or_default().map(a)),
    );
    let mut out = String::new();
    let c = plan.cube;
    out += &format!(
        "# ISO 9283 test poses P1..P5 (kinecal iso9283 plan) in the cube centred at ({}, {}, {}), side {} ({}{})\n",
        number::write(l(c.centre[0]), ls),
        number::write(l(c.centre[1]), ls),
        number::write(l(c.centre[2]), ls),
        number::format_number(l(c.side)),
        u.length,
        if plan.search.is_some() {
            ", searched: its corners are reached too"
        } else {
            ", given"
        }
    );
    out += "# each cycle visits P1, P5, P4, P3, P2 (ISO 9283:1998, 7.2); attitudes a,b,c about x,y,z: R = Rz(c) Ry(b) Rx(a)\n";
    out += &format!("# length_unit = {}\n# angle_unit = {}\n", u.length, u.angle);
    out += &plan_header(robot, plan.attitude.is_some()).join(",");
    out.push('\n');
    for p in &plan.poses {
        let mut row = vec![p.pose.to_string()];
        row.extend(p.position.iter().map(|&v| number::write(l(v), ls)));
        if let Some(att) = p.attitude.or(plan.attitude) {
            row.extend(att.iter().map(|&v| number::write(a(v), as_)));
        }
        row.extend(p.readings.iter().map(|&v| number::format_number(v)));
        out += &row.join(",");
        out.push('\n');
    }
    out
}

/// Reads a plan file ([`write_plan`]) for `robot`: the poses in metres and radians. The units the
/// file states must be the robot file's.
pub fn read_plan(text: &str, file: &str, robot: &Robot) -> Result<Vec<TestPose>> {
    let stated = crate::import::dh::stated(text, file)?;
    let u = robot.units;
    if let Some((s, line)) = stated.length.filter(|(s, _)| *s != u.length) {
        return Err(Error::input(
            Location::file(file).at_line(line).with_field("length_unit"),
            format!(
                "the plan is in {s}, the robot file in {}: plan with this robot",
                u.length
            ),
        ));
    }
    if let Some((s, line)) = stated.angle.filter(|(s, _)| *s != u.angle) {
        return Err(Error::input(
            Location::file(file).at_line(line).with_field("angle_unit"),
            format!(
                "the plan is in {s}, the robot file in {}: plan with this robot",
                u.angle
            ),
        ));
    }
    let t = table::read(text, file)?;
    let attitude = t.column("a").is_some() || t.column("b").is_some() || t.column("c").is_some();
    let header = plan_header(robot, attitude);
    let expected = header.join(",");
    t.refuse_unknown(&header, &expected)?;
    let cols: Vec<usize> = header
        .iter()
        .map(|h| t.require(h, &expected))
        .collect::<Result<_>>()?;
    t.check_rows()?;
    let mut out: Vec<TestPose> = Vec::new();
    for (line, f) in t.rows() {
        let pose = pose_index(&t, line, &f[cols[0]], false)?;
        if out.iter().any(|p| p.pose == pose) {
            return Err(Error::input(
                t.at(line, "pose"),
                format!("P{pose} appears twice"),
            ));
        }
        let num = |c: usize| t.number(line, &header[c], &f[cols[c]]);
        let position = [
            u.to_si(Quantity::Length, num(1)?),
            u.to_si(Quantity::Length, num(2)?),
            u.to_si(Quantity::Length, num(3)?),
        ];
        let (att, first_reading) = if attitude {
            (
                Some([
                    u.to_si(Quantity::Angle, num(4)?),
                    u.to_si(Quantity::Angle, num(5)?),
                    u.to_si(Quantity::Angle, num(6)?),
                ]),
                7,
            )
        } else {
            (None, 4)
        };
        let readings = (first_reading..header.len())
            .map(num)
            .collect::<Result<Vec<f64>>>()?;
        out.push(TestPose {
            pose,
            position,
            attitude: att,
            readings,
            position_error: 0.0,
            attitude_error: None,
        });
    }
    if out.is_empty() {
        return Err(Error::input(
            Location::file(file),
            "no poses: the file has a header but no rows",
        ));
    }
    out.sort_by_key(|p| p.pose);
    Ok(out)
}

/// The first pose number of the cube's corners: `C1..C8` are poses `CORNERS + 1 ..= CORNERS + 8`
/// (after `P1..P5`, 1 to 5).
pub const CORNERS: usize = 5;

/// The name of pose number `pose`: `P1..P5` for 1 to 5, `C1..C8` (the cube's corners, for a log
/// that measured them: [`CORNERS`]) for 6 to 13.
pub fn pose_name(pose: usize) -> String {
    if pose > CORNERS {
        format!("C{}", pose - CORNERS)
    } else {
        format!("P{pose}")
    }
}

/// A pose: `1..5` or `P1..P5`, and with `corners` also `C1..C8` (the cube's corners, numbered
/// from [`CORNERS`] + 1).
fn pose_index(t: &table::Table<'_>, line: usize, s: &str, corners: bool) -> Result<usize> {
    let expected = if corners {
        "1..5, P1..P5 or the cube's corners C1..C8"
    } else {
        "1..5 (or P1..P5)"
    };
    if let Some(c) = s.strip_prefix(['C', 'c']).filter(|_| corners) {
        return match c.parse::<usize>() {
            Ok(i) if (1..=8).contains(&i) => Ok(CORNERS + i),
            _ => Err(Error::input(
                t.at(line, "pose"),
                format!("expected a pose {expected}, found `{s}`"),
            )),
        };
    }
    let digits = s.strip_prefix(['P', 'p']).unwrap_or(s);
    match digits.parse::<usize>() {
        Ok(i) if (1..=5).contains(&i) => Ok(i),
        Ok(i) => Err(Error::input(
            t.at(line, "pose"),
            format!(
                "pose index {i} is out of 1..5 (ISO 9283's P1..P5{})",
                if corners {
                    "; the cube's corners are C1..C8"
                } else {
                    ""
                }
            ),
        )),
        Err(_) => Err(Error::input(
            t.at(line, "pose"),
            format!("expected a pose {expected}, found `{s}`"),
        )),
    }
}

/// One row of a measurement log: a pose attained in one cycle, in the log's units.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LogRow {
    /// The row's line in its file (0 when it has none).
    pub line: usize,
    /// The test the row belongs to, when the log holds several (a label: one cube of a series
    /// of cubes); the figures are computed test by test.
    pub test: Option<String>,
    /// The pose: 1 to 5 for `P1..P5`, 6 to 13 for the cube's corners `C1..C8` ([`pose_name`]).
    pub pose: usize,
    /// The cycle.
    pub cycle: u64,
    /// The commanded position `x_c, y_c, z_c`.
    pub commanded: [f64; 3],
    /// The commanded attitude `a_c, b_c, c_c`.
    pub commanded_attitude: Option<[f64; 3]>,
    /// The attained (measured) position `x, y, z`.
    pub attained: [f64; 3],
    /// The attained attitude `a, b, c`.
    pub attained_attitude: Option<[f64; 3]>,
    /// The approach direction (a label), for the multi-directional test.
    pub direction: Option<String>,
    /// The joint readings the robot attained the pose at (`v1..vn`), when logged.
    pub readings: Option<Vec<f64>>,
}

/// A measurement log: the attained poses of a pose test.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Log {
    /// Where it came from (a file name).
    pub file: String,
    /// Its length unit, when known.
    pub length_unit: Option<LengthUnit>,
    /// Its angle unit, when known (needed with attitudes).
    pub angle_unit: Option<AngleUnit>,
    /// Whether it was simulated (no measurement).
    pub simulated: bool,
    /// Its rows.
    pub rows: Vec<LogRow>,
}

impl Log {
    /// The log with its lengths (commanded and attained positions) in `unit`; an error when it
    /// states no length unit to convert from.
    pub fn with_length_unit(mut self, unit: LengthUnit) -> Result<Log> {
        let Some(from) = self.length_unit else {
            return Err(Error::Problem(format!(
                "{} states no length unit to convert from",
                self.file
            )));
        };
        let f = from.metres() / unit.metres();
        for r in &mut self.rows {
            r.commanded = r.commanded.map(|v| v * f);
            r.attained = r.attained.map(|v| v * f);
        }
        self.length_unit = Some(unit);
        Ok(self)
    }
}

/// Units given for a log that may not state its own.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct LogUnits {
    /// The length unit.
    pub length: Option<LengthUnit>,
    /// The angle unit.
    pub angle: Option<AngleUnit>,
}

/// The columns of a log, in the order [`write_log`] writes them.
pub const LOG_COLUMNS: [&str; 16] = [
    "test",
    "pose",
    "cycle",
    "xc",
    "yc",
    "zc",
    "ac",
    "bc",
    "cc",
    "x",
    "y",
    "z",
    "a",
    "b",
    "c",
    "direction",
];

/// The header a log needs, for error messages.
const LOG_EXPECTED: &str =
    "[test,]pose,cycle,xc,yc,zc[,ac,bc,cc],x,y,z[,a,b,c][,direction][,v1..vn]";

/// Reads a measurement log (CSV, see the module's documentation): columns `pose` (1..5 or
/// P1..P5, or a corner C1..C8), `cycle` (a whole number), `xc,yc,zc` and `x,y,z`, optionally
/// `ac,bc,cc` with `a,b,c`, `direction`, `test` (a label: the log holds several tests) and the
/// joint readings `v1..vn`. Units as the file states them in comment lines before its header,
/// or as `given` (both: they must agree). Every error names the file, line and field.
pub fn read_log(text: &str, file: &str, given: LogUnits) -> Result<Log> {
    let (length_unit, angle_unit) = log_units(text, file, given)?;
    let t = table::read(text, file)?;
    let columns = LogColumns::locate(&t)?;
    if columns.attitude.is_some() && angle_unit.is_none() {
        return Err(Error::input(
            Location::file(file),
            "the log has attitudes but states no angle unit: give it (--angle-unit), or write \
             `# angle_unit = deg` (or rad) before the header",
        ));
    }
    t.check_rows()?;
    let rows = read_log_rows(&t, &columns)?;
    if rows.is_empty() {
        return Err(Error::input(
            Location::file(file),
            "no rows: the log has a header but no measurements",
        ));
    }
    Ok(Log {
        file: file.to_string(),
        length_unit,
        angle_unit,
        simulated: says_simulated(text),
        rows,
    })
}

/// A log's length and angle units: those its comment lines state before its header (`#
/// length_unit = mm`, `# angle_unit = deg`), else those `given`; an error (naming the line)
/// when a unit stated and the one given differ.
fn log_units(
    text: &str,
    file: &str,
    given: LogUnits,
) -> Result<(Option<LengthUnit>, Option<AngleUnit>)> {
    let stated = crate::import::dh::stated(text, file)?;
    refuse_unit_conflict(
        file,
        stated.length.map(|(u, l)| (u.to_string(), l)),
        given.length.map(|u| u.to_string()),
        Setting::LengthUnit,
        "length_unit",
    )?;
    refuse_unit_conflict(
        file,
        stated.angle.map(|(u, l)| (u.to_string(), l)),
        given.angle.map(|u| u.to_string()),
        Setting::AngleUnit,
        "angle_unit",
    )?;
    let length_unit = stated.length.map(|s| s.0).or(given.length);
    let angle_unit = stated.angle.map(|s| s.0).or(given.angle);
    Ok((length_unit, angle_unit))
}

/// Refuses a unit a log states (its name and the line stating it) that differs from the one
/// given for it (`setting`, whose comment key is `key`: `length_unit` or `angle_unit`).
fn refuse_unit_conflict(
    file: &str,
    stated: Option<(String, usize)>,
    given: Option<String>,
    setting: Setting,
    key: &str,
) -> Result<()> {
    match (stated, given) {
        (Some((s, line)), Some(g)) if s != g => Err(Error::InvalidOption {
            setting,
            message: format!("{file}:{line} states `{key} = {s}`, not {g}"),
        }),
        _ => Ok(()),
    }
}

/// Where a log's fields are: the index of each column in its header.
struct LogColumns {
    /// `test`, when the log holds several tests.
    test: Option<usize>,
    /// `pose`.
    pose: usize,
    /// `cycle`.
    cycle: usize,
    /// The commanded position `xc, yc, zc`.
    commanded: [usize; 3],
    /// The attained position `x, y, z`.
    attained: [usize; 3],
    /// The commanded then the attained attitude, `ac, bc, cc, a, b, c`, when the log has them.
    attitude: Option<[usize; 6]>,
    /// `direction`, when the log has approach directions.
    direction: Option<usize>,
    /// The joint readings `v1..vn` (none when the log has no readings).
    readings: Vec<usize>,
}

impl LogColumns {
    /// Finds the columns in the header of `t`; an error (naming the field) for an unknown
    /// column, a required one missing, or only some of the attitude columns.
    fn locate(t: &table::Table<'_>) -> Result<Self> {
        let readings_count = (1..)
            .take_while(|k| t.column(&format!("v{k}")).is_some())
            .count();
        let mut known: Vec<String> = LOG_COLUMNS.map(String::from).to_vec();
        known.extend((1..=readings_count).map(|k| format!("v{k}")));
        t.refuse_unknown(&known, LOG_EXPECTED)?;
        let readings: Vec<usize> = (1..=readings_count)
            .map(|k| t.column(&format!("v{k}")).unwrap_or(0))
            .collect();
        let test = t.column("test");
        let col = |name: &str| t.require(name, LOG_EXPECTED);
        let pose = col("pose")?;
        let cycle = col("cycle")?;
        let commanded = [col("xc")?, col("yc")?, col("zc")?];
        let attained = [col("x")?, col("y")?, col("z")?];
        let attitude = attitude_columns(t)?;
        Ok(LogColumns {
            test,
            pose,
            cycle,
            commanded,
            attained,
            attitude,
            direction: t.column("direction"),
            readings,
        })
    }
}

/// The attitude columns of a log, commanded then attained (`ac, bc, cc, a, b, c`), when it has
/// them all; `None` when it has none; an error listing the missing ones when it has only some.
fn attitude_columns(t: &table::Table<'_>) -> Result<Option<[usize; 6]>> {
    let angles = ["ac", "bc", "cc", "a", "b", "c"];
    let present: [Option<usize>; 6] = angles.map(|n| t.column(n));
    if present.iter().all(Option::is_some) {
        Ok(Some(present.map(|c| c.unwrap_or(0))))
    } else if present.iter().any(Option::is_some) {
        let missing = angles
            .iter()
            .zip(&present)
            .filter(|(_, c)| c.is_none())
            .map(|(n, _)| *n)
            .collect::<Vec<_>>();
        // The field is the first column missing (it named the first one present).
        Err(Error::input(
            t.header_at().with_field(missing[0]),
            format!(
                "attitudes need all of ac,bc,cc,a,b,c (commanded and attained); missing {}",
                missing.join(",")
            ),
        ))
    } else {
        Ok(None)
    }
}

/// The rows of a log's table, in file order; an error when a test's pose is logged twice in one
/// cycle from one direction.
fn read_log_rows(t: &table::Table<'_>, columns: &LogColumns) -> Result<Vec<LogRow>> {
    let mut rows = Vec::new();
    let mut seen: BTreeMap<(Option<String>, usize, u64, Option<String>), usize> = BTreeMap::new();
    for (line, f) in t.rows() {
        let row = read_log_row(t, columns, line, f)?;
        let key = (row.test.clone(), row.pose, row.cycle, row.direction.clone());
        if let Some(first) = seen.insert(key, line) {
            return Err(repeated_pose(t, &row, first));
        }
        rows.push(row);
    }
    Ok(rows)
}

/// The log row on `line` (fields `f`): its test, pose, cycle, commanded and attained poses (in
/// the log's units), direction and readings; an error names the line and the field.
fn read_log_row(
    t: &table::Table<'_>,
    columns: &LogColumns,
    line: usize,
    f: table::Fields<'_>,
) -> Result<LogRow> {
    let pose = pose_index(t, line, &f[columns.pose], true)?;
    let test = columns
        .test
        .map(|c| f[c].to_string())
        .filter(|d| !d.is_empty());
    let cycle = cycle_number(t, line, &f[columns.cycle])?;
    let triple = |cols: &[usize]| read_triple(t, line, f, cols);
    let commanded = triple(&columns.commanded)?;
    let attained = triple(&columns.attained)?;
    let (commanded_attitude, attained_attitude) = match &columns.attitude {
        Some(c) => (Some(triple(&c[..3])?), Some(triple(&c[3..])?)),
        None => (None, None),
    };
    let direction = columns
        .direction
        .map(|c| f[c].to_string())
        .filter(|d| !d.is_empty());
    let readings = if columns.readings.is_empty() {
        None
    } else {
        Some(
            columns
                .readings
                .iter()
                .map(|&c| t.number(line, &t.header[c], &f[c]))
                .collect::<Result<Vec<f64>>>()?,
        )
    };
    Ok(LogRow {
        line,
        test,
        pose,
        cycle,
        commanded,
        commanded_attitude,
        attained,
        attained_attitude,
        direction,
        readings,
    })
}

/// The cycle of a log row: a whole number `s` (an error naming the line and the `cycle` field).
fn cycle_number(t: &table::Table<'_>, line: usize, s: &str) -> Result<u64> {
    s.parse().map_err(|_| {
        Error::input(
            t.at(line, "cycle"),
            format!("expected a cycle number (a whole number), found `{s}`"),
        )
    })
}

/// Three numbers of the row on `line` (fields `f`), from the columns `cols` (three of them): a
/// position `x, y, z` or an attitude `a, b, c`, in the log's units.
fn read_triple(
    t: &table::Table<'_>,
    line: usize,
    f: table::Fields<'_>,
    cols: &[usize],
) -> Result<[f64; 3]> {
    let mut v = [0.0; 3];
    for (k, &c) in cols.iter().enumerate() {
        v[k] = t.number(line, &t.header[c], &f[c])?;
    }
    Ok(v)
}

/// The error for `row`, a test's pose logged again in one cycle from one direction (first on
/// line `first`).
fn repeated_pose(t: &table::Table<'_>, row: &LogRow, first: usize) -> Error {
    Error::input(
        t.at(row.line, "cycle"),
        format!(
            "{}{} in cycle {}{} appears twice (also on line {first})",
            row.test
                .as_deref()
                .map(|t| format!("test `{t}`: "))
                .unwrap_or_default(),
            pose_name(row.pose),
            row.cycle,
            row.direction
                .as_deref()
                .map(|d| format!(" from direction `{d}`"))
                .unwrap_or_default()
        ),
    )
}

/// Whether a log says it was simulated: `SIMULATED` in a comment line at its start (before its
/// header).
fn says_simulated(text: &str) -> bool {
    text.lines()
        .take_while(|l| crate::files::table::is_comment(l))
        .any(|l| l.contains("SIMULATED"))
}

/// A log as CSV: comment lines (what it is, its units), then [`LOG_COLUMNS`] (the attitude
/// columns when its rows have attitudes, `direction` when any row has one). Numbers are written
/// to read back exactly.
pub fn write_log(log: &Log) -> String {
    let mut out = String::new();
    if log.simulated {
        out += "# SIMULATED by kinecal iso9283 simulate: not a measurement\n";
    }
    out += "# ISO 9283 pose test log: commanded (xc..cc) and attained (x..c) poses per cycle\n";
    if let Some(u) = log.length_unit {
        out += &format!("# length_unit = {u}\n");
    }
    if let Some(u) = log.angle_unit {
        out += &format!("# angle_unit = {u}\n");
    }
    let attitude = log.rows.iter().any(|r| r.attained_attitude.is_some());
    let direction = log.rows.iter().any(|r| r.direction.is_some());
    let test = log.rows.iter().any(|r| r.test.is_some());
    // Readings only when every row has them, as many.
    let readings = log
        .rows
        .first()
        .and_then(|r| r.readings.as_ref())
        .map(Vec::len)
        .filter(|&k| {
            log.rows
                .iter()
                .all(|r| r.readings.as_ref().map(Vec::len) == Some(k))
        })
        .unwrap_or(0);
    let mut header: Vec<String> = LOG_COLUMNS
        .iter()
        .copied()
        .filter(|c| {
            (attitude || !["ac", "bc", "cc", "a", "b", "c"].contains(c))
                && (direction || *c != "direction")
                && (test || *c != "test")
        })
        .map(String::from)
        .collect();
    header.extend((1..=readings).map(|k| format!("v{k}")));
    out += &header.join(",");
    out.push('\n');
    let n = number::format_number;
    for r in &log.rows {
        let mut row = Vec::with_capacity(header.len());
        if test {
            row.push(csv_field(r.test.as_deref().unwrap_or_default()));
        }
        // P1..P5 as their numbers (as logs have always been written), corners by name.
        row.push(if r.pose > CORNERS {
            pose_name(r.pose)
        } else {
            r.pose.to_string()
        });
        row.push(r.cycle.to_string());
        row.extend(r.commanded.map(n));
        if attitude {
            row.extend(r.commanded_attitude.unwrap_or_default().map(n));
        }
        row.extend(r.attained.map(n));
        if attitude {
            row.extend(r.attained_attitude.unwrap_or_default().map(n));
        }
        if direction {
            row.push(csv_field(r.direction.as_deref().unwrap_or_default()));
        }
        if readings > 0 {
            row.extend(r.readings.iter().flatten().map(|&v| n(v)));
        }
        out += &row.join(",");
        out.push('\n');
    }
    out
}

/// A label as one CSV field: quoted (quotes doubled) when it holds a comma, a quote or a line
/// break, starts with `#` (a comment line unquoted) or with or ends in white space.
fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r', ';', '\t']) || s.starts_with('#') || s.trim() != s {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// What [`simulate`] is asked.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimulateRequest {
    /// Cycles (each visits the poses in [`CYCLE`] order).
    pub cycles: usize,
    /// Standard deviation of the Gaussian noise on each attained coordinate (m).
    pub length_noise: f64,
    /// Standard deviation of the Gaussian noise on each attained angle (rad).
    pub angle_noise: f64,
    /// The random seed (the same seed gives the same log on every machine).
    pub seed: u64,
}

/// A simulated log (no measurement): `robot` (the robot that moves: a "true" robot) is sent
/// `cycles` times round the plan's poses at their readings; the commanded pose is the plan's
/// (the nominal model's), the attained one is `robot`'s forward kinematics at the readings plus
/// Gaussian noise (the repeatability). In `robot`'s file units.
pub fn simulate(robot: &Robot, poses: &[TestPose], request: &SimulateRequest) -> Result<Log> {
    if request.cycles == 0 {
        return Err(Error::Problem("a simulation needs at least 1 cycle".into()));
    }
    if let Some(p) = poses.iter().find(|p| p.readings.len() != robot.dof()) {
        return Err(Error::Problem(format!(
            "P{} has {} readings, the robot {} joints",
            p.pose,
            p.readings.len(),
            robot.dof()
        )));
    }
    let unit = Normal::new(0.0, 1.0).expect("a valid normal");
    let (sl, sa) = (request.length_noise.max(0.0), request.angle_noise.max(0.0));
    let mut rng = ChaCha8Rng::seed_from_u64(request.seed);
    let chain = Chain::new(robot);
    let u = robot.units;
    let l = |v: f64| u.from_si(Quantity::Length, v);
    let a = |v: f64| u.from_si(Quantity::Angle, v);
    let mut rows = Vec::new();
    for cycle in 1..=request.cycles as u64 {
        for index in CYCLE {
            let Some(p) = poses.iter().find(|p| p.pose == index) else {
                continue;
            };
            let f = chain.frame_at(&p.readings, Target::EndEffector);
            let attained: [f64; 3] =
                std::array::from_fn(|k| l(f.translation[k] + sl * unit.sample(&mut rng)));
            let attained_attitude = p.attitude.map(|c| {
                // kinecal's ZYX (alpha, beta, gamma) is ISO's (c, b, a); each angle as near the
                // commanded one as a whole turn allows.
                let e = euler_zyx(&f.rotation);
                let abc = [e.z, e.y, e.x];
                std::array::from_fn(|k| {
                    let v = c[k] + crate::units::wrap_angle(abc[k] - c[k]);
                    a(v + sa * unit.sample(&mut rng))
                })
            });
            rows.push(LogRow {
                line: 0,
                test: None,
                pose: index,
                cycle,
                commanded: p.position.map(l),
                commanded_attitude: p.attitude.map(|c| c.map(a)),
                attained,
                attained_attitude,
                direction: None,
                readings: Some(p.readings.clone()),
            });
        }
    }
    Ok(Log {
        file: "simulation".into(),
        length_unit: Some(u.length),
        angle_unit: Some(u.angle),
        simulated: true,
        rows,
    })
}
