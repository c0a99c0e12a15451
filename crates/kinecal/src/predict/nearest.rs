//! Distances in joint space, and the nearest measured posture.
//!
//! The distance between two postures is a length: each joint's reading difference `dV_j`
//! times the joint's *lever* `l_j`, the root mean square over the measured postures of how far
//! the target moves per unit of that reading (the norm of the position rows of the reading
//! Jacobian), summed in quadrature. A revolute joint counts the chord, so that readings a turn
//! apart are the same posture: `d^2 = sum_j (2 (l_j / w_j) sin(w_j dV_j / 2))^2` over revolute
//! joints (`w_j = |slope_j|`, radians per reading unit) plus `(l_j dV_j)^2` over prismatic
//! ones; for small differences `d^2 = sum (l_j dV_j)^2`, the distance the target would travel
//! if each joint moved alone at its mean lever. A wrist joint that hardly moves the target
//! hardly counts. Each posture is embedded as `(l/w) (cos w V, sin w V)` per revolute joint and
//! `l V` per prismatic one, where the distance is Euclidean, and the nearest measured posture is
//! found in a k-d tree of the embedded postures (exact; no allocation per query).

use crate::model::robot::{JointKind, Robot};

/// The joint-space metric of a calibration (see the module).
#[derive(Debug, Clone, PartialEq)]
pub struct JointMetric {
    /// Per joint: its lever (m per reading unit) and, for a revolute joint, `|slope|` (rad per
    /// reading unit; 0 for a prismatic joint).
    joints: Vec<(f64, f64)>,
}

impl JointMetric {
    /// The metric with these levers (m per reading unit, one per joint) for `robot`'s joints.
    pub fn new(robot: &Robot, levers: &[f64]) -> JointMetric {
        JointMetric {
            joints: robot
                .joints
                .iter()
                .zip(levers)
                .map(|(j, &l)| match j.kind {
                    JointKind::Revolute if j.slope != 0.0 => (l, j.slope.abs()),
                    _ => (l, 0.0),
                })
                .collect(),
        }
    }

    /// The levers (m per reading unit).
    pub fn levers(&self) -> Vec<f64> {
        self.joints.iter().map(|j| j.0).collect()
    }

    /// Coordinates of the embedding.
    pub(crate) fn dims(&self) -> usize {
        self.joints
            .iter()
            .map(|j| if j.1 > 0.0 { 2 } else { 1 })
            .sum()
    }

    /// Writes the embedding of `readings` into `out` ([`JointMetric::dims`] long).
    #[inline]
    pub(crate) fn embed(&self, readings: &[f64], out: &mut [f64]) {
        let mut k = 0;
        for (&(l, w), &v) in self.joints.iter().zip(readings) {
            if l <= 0.0 {
                continue;
            }
            if w > 0.0 {
                let (s, c) = (w * v).sin_cos();
                out[k] = l / w * c;
                out[k + 1] = l / w * s;
                k += 2;
            } else {
                out[k] = l * v;
                k += 1;
            }
        }
    }

    /// The distance between two postures (m), directly (for tests and single uses).
    pub fn distance(&self, a: &[f64], b: &[f64]) -> f64 {
        self.joints
            .iter()
            .zip(a.iter().zip(b))
            .map(|(&(l, w), (&x, &y))| {
                let d = if w > 0.0 {
                    2.0 * (l / w) * (0.5 * w * (x - y)).sin()
                } else {
                    l * (x - y)
                };
                d * d
            })
            .sum::<f64>()
            .sqrt()
    }
}

/// A k-d tree of embedded postures: the nearest one to a query, exactly.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct NearestIndex {
    dims: usize,
    /// The points, reordered into the tree (point `i` at `[i * dims..]`).
    points: Vec<f64>,
    /// The original index of each reordered point.
    index: Vec<usize>,
    /// The split coordinate of the node whose median is point `i` (leaves: unused).
    split: Vec<u8>,
}

const LEAF: usize = 32;

impl NearestIndex {
    /// The tree of `points` (`dims` coordinates each, concatenated).
    pub fn new(dims: usize, points: &[f64]) -> NearestIndex {
        assert!(dims > 0 && dims < 256 && points.len() % dims == 0);
        let n = points.len() / dims;
        let mut index: Vec<usize> = (0..n).collect();
        let mut split = vec![0u8; n];
        fn build(
            dims: usize,
            points: &[f64],
            index: &mut [usize],
            split: &mut [u8],
            offset: usize,
        ) {
            let n = index.len();
            if n <= LEAF {
                return;
            }
            // Split along the coordinate of largest spread, at the median.
            let mut best = (0, -1.0);
            for d in 0..dims {
                let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
                for &i in index.iter() {
                    let v = points[i * dims + d];
                    lo = lo.min(v);
                    hi = hi.max(v);
                }
                if hi - lo > best.1 {
                    best = (d, hi - lo);
                }
            }
            let d = best.0;
            let mid = n / 2;
            index.select_nth_unstable_by(mid, |&a, &b| {
                points[a * dims + d].total_cmp(&points[b * dims + d])
            });
            split[offset + mid] = d as u8;
            let (left, right) = index.split_at_mut(mid);
            build(dims, points, left, split, offset);
            build(dims, points, &mut right[1..], split, offset + mid + 1);
        }
        build(dims, points, &mut index, &mut split, 0);
        let mut reordered = Vec::with_capacity(points.len());
        for &i in &index {
            reordered.extend_from_slice(&points[i * dims..(i + 1) * dims]);
        }
        NearestIndex {
            dims,
            points: reordered,
            index,
            split,
        }
    }

    /// Points in the tree.
    pub fn len(&self) -> usize {
        self.index.len()
    }

    /// Whether the tree is empty.
    pub fn is_empty(&self) -> bool {
        self.index.is_empty()
    }

    /// The nearest point to `q` (embedded): its original index and distance; `None` for an
    /// empty tree. The search descends to `q`'s cell first and visits another cell only when
    /// the distance from `q` to that cell's box (accumulated axis by axis as the search
    /// crosses splitting planes: Arya and Mount's incremental distance) is below the best
    /// found: a far query, whose nearest point is far away too, still prunes most of the tree.
    pub fn nearest(&self, q: &[f64]) -> Option<(usize, f64)> {
        if self.is_empty() {
            return None;
        }
        let mut best = (usize::MAX, f64::INFINITY);
        // Per axis, how far `q` lies outside the current cell along it (0 inside).
        let mut off = [0.0f64; 256];
        self.search(0, self.len(), q, 0.0, &mut off[..self.dims], &mut best);
        Some((self.index[best.0], best.1.sqrt()))
    }

    #[inline]
    fn d2(&self, i: usize, q: &[f64]) -> f64 {
        let p = &self.points[i * self.dims..(i + 1) * self.dims];
        p.iter().zip(q).map(|(a, b)| (a - b) * (a - b)).sum()
    }

    /// Searches the cell of points `lo..hi`, `q` at squared distance `rd` from its box
    /// (`off` per axis).
    fn search(
        &self,
        lo: usize,
        hi: usize,
        q: &[f64],
        rd: f64,
        off: &mut [f64],
        best: &mut (usize, f64),
    ) {
        let n = hi - lo;
        if n <= LEAF {
            for i in lo..hi {
                let d = self.d2(i, q);
                // The first point seen is taken even at an infinite or NaN distance (a query
                // beyond the doubles' range): the search always names one.
                if d < best.1 || best.0 == usize::MAX {
                    *best = (i, d);
                }
            }
            return;
        }
        let mid = lo + n / 2;
        let d = self.split[mid] as usize;
        let diff = q[d] - self.points[mid * self.dims + d];
        let here = self.d2(mid, q);
        if here < best.1 || best.0 == usize::MAX {
            *best = (mid, here);
        }
        let (near, far) = if diff < 0.0 {
            ((lo, mid), (mid + 1, hi))
        } else {
            ((mid + 1, hi), (lo, mid))
        };
        self.search(near.0, near.1, q, rd, off, best);
        // The far cell lies beyond the splitting plane along `d`: `q`'s offset along `d`
        // becomes its distance to the plane.
        let old = off[d];
        let far_rd = rd - old * old + diff * diff;
        if far_rd < best.1 {
            off[d] = diff;
            self.search(far.0, far.1, q, far_rd, off, best);
            off[d] = old;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};

    fn ge_a4() -> Robot {
        crate::model::robot_file::parse_robot_toml(
            include_str!("../../../../examples/robots/ge_a4.toml"),
            "ge_a4.toml",
        )
        .unwrap()
    }

    #[test]
    fn the_tree_finds_what_a_search_of_every_point_finds() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        // Spread over the queries' box, and clustered in a corner of it (every query far from
        // every point: the pruning by the distance to a cell's box must not lose the nearest).
        for (n, dims, spread) in [
            (1, 3, 1.0),
            (7, 2, 1.0),
            (100, 12, 1.0),
            (3000, 12, 1.0),
            (2000, 5, 1.0),
            (3000, 12, 0.1),
            (2000, 5, 0.05),
        ] {
            let pts: Vec<f64> = (0..n * dims)
                .map(|_| 0.9 + spread * rng.random_range(-1.0..1.0))
                .map(|v| if spread < 1.0 { v } else { v - 0.9 })
                .collect();
            let tree = NearestIndex::new(dims, &pts);
            for _ in 0..300 {
                let q: Vec<f64> = (0..dims).map(|_| rng.random_range(-1.3..1.3)).collect();
                let brute = (0..n)
                    .map(|i| {
                        let d: f64 = (0..dims).map(|k| (pts[i * dims + k] - q[k]).powi(2)).sum();
                        (i, d.sqrt())
                    })
                    .min_by(|a, b| a.1.total_cmp(&b.1))
                    .unwrap();
                let (i, d) = tree.nearest(&q).unwrap();
                assert!((d - brute.1).abs() < 1e-12, "n {n}: {d} for {}", brute.1);
                assert!(
                    (d - {
                        let s: f64 = (0..dims).map(|k| (pts[i * dims + k] - q[k]).powi(2)).sum();
                        s.sqrt()
                    })
                    .abs()
                        < 1e-12
                );
            }
        }
        assert!(NearestIndex::new(3, &[]).nearest(&[0.0; 3]).is_none());
    }

    #[test]
    fn the_embedding_gives_the_chord_distance_and_readings_a_turn_apart_coincide() {
        let robot = ge_a4();
        let levers: Vec<f64> = (0..robot.dof()).map(|j| 0.3 + 0.1 * j as f64).collect();
        let m = JointMetric::new(&robot, &levers);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        let (mut ea, mut eb) = (vec![0.0; m.dims()], vec![0.0; m.dims()]);
        for _ in 0..200 {
            let a: Vec<f64> = (0..robot.dof())
                .map(|_| rng.random_range(-20.0..20.0))
                .collect();
            let b: Vec<f64> = (0..robot.dof())
                .map(|_| rng.random_range(-20.0..20.0))
                .collect();
            m.embed(&a, &mut ea);
            m.embed(&b, &mut eb);
            let e: f64 = ea
                .iter()
                .zip(&eb)
                .map(|(x, y)| (x - y).powi(2))
                .sum::<f64>()
                .sqrt();
            assert!((e - m.distance(&a, &b)).abs() < 1e-9 * (1.0 + e));
        }
        // Small differences: the lever times the reading difference.
        let a = vec![1.0, 2.0, 0.1, 3.0];
        let mut b = a.clone();
        b[1] += 1e-4;
        assert!((m.distance(&a, &b) - levers[1] * 1e-4).abs() < 1e-12);
        // A revolute joint a whole turn on: the same posture.
        let mut c = a.clone();
        let turn = 2.0 * std::f64::consts::PI / robot.joints[0].slope.abs();
        c[0] += turn;
        assert!(m.distance(&a, &c) < 1e-12);
    }
}
