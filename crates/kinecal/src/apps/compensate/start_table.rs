//! The table of start postures' target frames, and the lookup of the starts nearest a goal.
//!
//! Nearness is the task distance of [`super::search`]: the squared position distance (m^2),
//! plus, for a pose goal, `reach^2 (3 - tr(R_goal^T R))` (`reach^2 theta^2` to second order in
//! the attitude angle `theta`). The starts are kept in a uniform grid of cubic cells over their
//! positions' bounding box (about four starts to a cell of the box), stored cell by cell. A
//! position goal's lookup visits the cells in rings of growing Chebyshev distance from the
//! goal's cell and stops once the last of the starts it keeps is nearer than any cell not yet
//! visited can be. A pose goal's attitude part dominates its distance, so that the rings would
//! end only after nearly every cell: the starts are also kept in leaves of a k-d tree over
//! position and rotation (about [`LEAF`] starts each, the rotation's numbers weighed by
//! `reach / sqrt 2`, so that the split follows the task distance), each with the box of its
//! numbers. A box bounds its starts' distances from below: the position's squared distance from
//! the box, plus `reach^2` times the larger of two bounds of `3 - tr(R_goal^T R)` (`3 - t`, `t`
//! the largest trace over the box, a linear function of `R`'s numbers: at a corner; and half the
//! squared distance of `R_goal` from the box, through `3 - tr(G^T R) = |G - R|^2 / 2 + (3 -
//! |G|^2) / 2 + (3 - |R|^2) / 2`). The lookup scans the [`FIRST_LEAVES`] leaves whose bounds are
//! smallest, then, in leaf order, every other leaf whose bound does not exceed the last kept
//! distance (by more than the bound's rounding). Either lookup returns the starts a scan of the
//! whole table in index order returns: the `keep` smallest by (distance, start index), each
//! distance worked out by the same operations in the same order (a goal whose every distance is
//! NaN gets some `keep` starts).

use super::Goal;

/// Starts per cell the grid is sized for, over its bounding box.
const PER_CELL: f64 = 4.0;
/// Most cells along an axis.
const MOST_CELLS: usize = 64;
/// Starts per leaf of the pose lookup's tree, at least (a table of more than 4,096 starts has
/// larger leaves, [`MOST_LEAVES`] of them).
const LEAF: usize = 16;
/// The most leaves of the pose lookup's tree (halving a table until its parts hold at most
/// `ceil(n / MOST_LEAVES)` starts makes at most this many).
const MOST_LEAVES: usize = 256;
/// Leaves whose bounds are worked out at once (loops over them vectorised).
const BLOCK: usize = 16;
/// Leaves a pose lookup scans first, those whose bounds are smallest: the distance it then
/// keeps rules most other leaves out.
const FIRST_LEAVES: usize = 8;

/// The target frames of a table of start postures, indexed by position.
pub(crate) struct StartTable {
    /// Per entry, in cell order: the position (m), then the rotation's columns; stored number
    /// by number: `columns[c][e]` is number `c` of entry `e`.
    columns: [Vec<f64>; 12],
    /// Per entry: the start's index in the table of postures.
    index: Vec<u32>,
    /// The entries of cell `c` are `offsets[c]..offsets[c + 1]`; cells x fastest, then y, z.
    offsets: Vec<u32>,
    /// The grid's lowest corner (m).
    origin: [f64; 3],
    /// The cells' edge (m).
    cell: f64,
    /// Cells along x, y, z.
    dims: [usize; 3],
    /// The same entries, leaf by leaf, for pose goals.
    leaves: Leaves,
}

/// The starts in the leaves of a k-d tree, for the lookup of pose goals (see the module's
/// documentation).
#[derive(Default)]
struct Leaves {
    /// Per entry, in leaf order, as [`StartTable`]'s `columns`.
    columns: [Vec<f64>; 12],
    /// Per entry: the start's index.
    index: Vec<u32>,
    /// The entries of leaf `l` are `offsets[l]..offsets[l + 1]`.
    offsets: Vec<u32>,
    /// Per leaf, the smallest and the largest of each number of its entries (`lo[c][l]`).
    lo: [Vec<f64>; 12],
    hi: [Vec<f64>; 12],
    /// Per leaf, the least `3 - |R|^2` of its entries' rotations `R` (0 to rounding).
    unit: Vec<f64>,
}

impl Leaves {
    /// The leaves of `keys` (position, then the rotation's columns); `reach` (m) weighs the
    /// rotation's numbers when choosing where to split.
    fn new(keys: &[[f64; 12]], reach: f64) -> Leaves {
        let n = keys.len();
        let size = LEAF.max(n.div_ceil(MOST_LEAVES));
        let weight = if reach.is_finite() && reach > 0.0 {
            reach / std::f64::consts::SQRT_2
        } else {
            1.0
        };
        let scale = |c: usize| if c < 3 { 1.0 } else { weight };
        let mut order: Vec<u32> = (0..n as u32).collect();
        let mut leaves = Leaves::default();
        leaves.offsets.push(0);
        // Each range of `order` is split at its middle along its widest number, until it
        // holds at most `size` entries.
        let mut ranges = vec![(0, n)];
        let mut done = Vec::new();
        while let Some((a, b)) = ranges.pop() {
            if b - a <= size {
                done.push((a, b));
                continue;
            }
            let part = &mut order[a..b];
            let spread = |c: usize| {
                let (lo, hi) =
                    part.iter()
                        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &i| {
                            let x = keys[i as usize][c];
                            (l.min(x), h.max(x))
                        });
                (hi - lo) * scale(c)
            };
            let widest = (0..12)
                .map(|c| (spread(c), c))
                .fold(
                    (f64::NEG_INFINITY, 0),
                    |best, s| if s.0 > best.0 { s } else { best },
                )
                .1;
            part.sort_by(|&i, &j| {
                keys[i as usize][widest]
                    .total_cmp(&keys[j as usize][widest])
                    .then(i.cmp(&j))
            });
            let mid = a + (b - a) / 2;
            // Popped last first: the leaves come out in the order of the split.
            ranges.push((mid, b));
            ranges.push((a, mid));
        }
        for (a, b) in done {
            for &i in &order[a..b] {
                leaves.index.push(i);
                for (column, x) in leaves.columns.iter_mut().zip(keys[i as usize]) {
                    column.push(x);
                }
            }
            leaves.offsets.push(b as u32);
            for (c, (lo, hi)) in leaves.lo.iter_mut().zip(&mut leaves.hi).enumerate() {
                let numbers = order[a..b].iter().map(|&i| keys[i as usize][c]);
                // `min`/`max` pass over a NaN: a start whose frame is not finite has a NaN
                // distance and is never kept.
                lo.push(numbers.clone().fold(f64::INFINITY, f64::min));
                hi.push(numbers.fold(f64::NEG_INFINITY, f64::max));
            }
            leaves.unit.push(
                order[a..b]
                    .iter()
                    .map(|&i| 3.0 - keys[i as usize][3..].iter().map(|x| x * x).sum::<f64>())
                    .fold(f64::INFINITY, f64::min),
            );
        }
        leaves
    }

    /// The number of leaves.
    fn len(&self) -> usize {
        self.offsets.len() - 1
    }

    /// Per leaf from leaf `from` on (as many as `out` holds), a lower bound of its entries'
    /// squared task distances from the pose goal at position `p` with rotation `r`
    /// (column-major), less the bound's rounding, into `out`.
    fn bounds(&self, p: &[f64; 3], r: &[f64], reach2: f64, from: usize, out: &mut [f64]) {
        // A block of leaves at a time.
        for (k, out) in out.chunks_mut(BLOCK).enumerate() {
            self.block_bounds(p, r, reach2, from + k * BLOCK, out);
        }
    }

    /// [`Leaves::bounds`] of at most [`BLOCK`] leaves.
    fn block_bounds(&self, p: &[f64; 3], r: &[f64], reach2: f64, from: usize, out: &mut [f64]) {
        let n = out.len();
        let leaves = from..from + n;
        // Per leaf, accumulated number by number (loops over the leaves, which the compiler
        // vectorises): the position's squared distance from the box; the largest trace
        // `tr(G^T R)` over the box; the squared distance of `G` from the rotation's box; and the
        // sizes of the terms, for the margin.
        let mut position = [0.0f64; BLOCK];
        let mut trace = [0.0f64; BLOCK];
        let mut apart = [0.0f64; BLOCK];
        let mut size = [0.0f64; BLOCK];
        let (position, trace, apart, size) = (
            &mut position[..n],
            &mut trace[..n],
            &mut apart[..n],
            &mut size[..n],
        );
        for (a, &x) in p.iter().enumerate() {
            let (lo, hi) = (&self.lo[a][leaves.clone()], &self.hi[a][leaves.clone()]);
            for l in 0..n {
                let gap = (lo[l] - x).max(x - hi[l]).max(0.0);
                position[l] += gap * gap;
                size[l] += 2.0 * (x * x + (lo[l] * lo[l]).max(hi[l] * hi[l]));
            }
        }
        for (k, &g) in r.iter().enumerate() {
            let (lo, hi) = (
                &self.lo[3 + k][leaves.clone()],
                &self.hi[3 + k][leaves.clone()],
            );
            for l in 0..n {
                let (glo, ghi) = (g * lo[l], g * hi[l]);
                trace[l] += glo.max(ghi);
                let gap = (lo[l] - g).max(g - hi[l]).max(0.0);
                apart[l] += gap * gap;
                size[l] += reach2
                    * (glo.abs().max(ghi.abs()) + g * g + (lo[l] * lo[l]).max(hi[l] * hi[l]));
            }
        }
        // `|G|^2` (3 for a rotation).
        let norm2: f64 = r.iter().map(|g| g * g).sum();
        for l in 0..n {
            // The attitude's part, `3 - tr(G^T R)`, bounded twice: by the largest trace over
            // the box (linear in `R`: at a corner), and through `3 - tr(G^T R) = |G - R|^2 / 2
            // + (3 - |G|^2) / 2 + (3 - |R|^2) / 2`, whose first term is at least half the
            // squared distance of `G` from the box, and whose last the leaf's least.
            let linear = 3.0 - trace[l];
            let quadratic = 0.5 * (apart[l] + (3.0 - norm2) + self.unit[from + l]);
            let bound = position[l] + reach2 * linear.max(quadratic);
            // The distances are worked out by other operations: each is within a few
            // roundings (1e-16) of the sizes of its terms, which the margin covers 1,000 times
            // over.
            out[l] = bound - 1e-12 * (size[l] + 3.0 * reach2);
        }
    }
}

impl StartTable {
    /// The table of the frames `keys` (position, then the rotation's columns), start `i` the
    /// `i`-th; `reach` (m) the arm's, which weighs attitudes in the task distance.
    pub(crate) fn new(keys: &[[f64; 12]], reach: f64) -> Self {
        let n = keys.len();
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for k in keys {
            for a in 0..3 {
                // `min`/`max` pass over a NaN: a start whose frame is not finite lands in a
                // border cell and is still looked at when the ring reaches it.
                lo[a] = lo[a].min(k[a]);
                hi[a] = hi[a].max(k[a]);
            }
        }
        if n == 0 || lo.iter().chain(&hi).any(|v| !v.is_finite()) {
            lo = [0.0; 3];
            hi = [0.0; 3];
        }
        let extent: [f64; 3] = std::array::from_fn(|a| hi[a] - lo[a]);
        let widest = extent.iter().cloned().fold(0.0, f64::max);
        let volume: f64 = extent.iter().product();
        let cells = (n as f64 / PER_CELL).max(1.0);
        // A flat or straight workspace (no volume) is cut by its widest extent.
        let cell = (volume / cells)
            .cbrt()
            .max(widest / MOST_CELLS as f64)
            .max(widest / cells.sqrt())
            .max(1e-9);
        let dims = extent.map(|e| ((e / cell).floor() as usize + 1).min(MOST_CELLS));
        let mut table = StartTable {
            columns: Default::default(),
            index: Vec::with_capacity(n),
            offsets: vec![0; dims[0] * dims[1] * dims[2] + 1],
            origin: lo,
            cell,
            dims,
            leaves: Leaves::new(keys, reach),
        };
        let homes: Vec<usize> = keys.iter().map(|k| table.home(k)).collect();
        for &h in &homes {
            table.offsets[h + 1] += 1;
        }
        for c in 1..table.offsets.len() {
            table.offsets[c] += table.offsets[c - 1];
        }
        let mut order: Vec<u32> = (0..n as u32).collect();
        order.sort_by_key(|&i| (homes[i as usize], i));
        for &i in &order {
            table.index.push(i);
            for (column, x) in table.columns.iter_mut().zip(keys[i as usize]) {
                column.push(x);
            }
        }
        table
    }

    /// The cell coordinate of `x` along axis `a`, clamped to the grid.
    fn coordinate(&self, a: usize, x: f64) -> usize {
        let c = ((x - self.origin[a]) / self.cell).floor();
        // A NaN, or a position below the grid, is cell 0 (`as` saturates).
        (c.max(0.0) as usize).min(self.dims[a] - 1)
    }

    /// The cell holding position `k[..3]`.
    fn home(&self, k: &[f64]) -> usize {
        let [x, y, z] = [0, 1, 2].map(|a| self.coordinate(a, k[a]));
        x + self.dims[0] * (y + self.dims[1] * z)
    }

    /// Fills `out` with the `keep` starts nearest `goal`, nearest first, as `(squared task
    /// distance, start index)`; `reach2` weighs the attitude (m^2 per unit of `3 - trace`).
    pub(crate) fn nearest(&self, goal: &Goal, reach2: f64, keep: usize, out: &mut Vec<(f64, u32)>) {
        out.clear();
        if keep == 0 || self.index.is_empty() {
            return;
        }
        let p = match goal {
            Goal::Position(p) => p,
            Goal::Pose(g) => &g.translation,
        };
        let p = [p.x, p.y, p.z];
        let q = Query {
            goal,
            p,
            reach2,
            keep,
        };
        if let Goal::Pose(g) = goal {
            // The attitude's part of the distance dominates (the starts nearest in position
            // are seldom nearest in attitude): the leaves of the tree, not the rings.
            self.nearest_pose(&q, g.rotation.as_slice(), out);
            return;
        }
        let home = [0, 1, 2].map(|a| self.coordinate(a, p[a]));
        let [nx, ny, nz] = self.dims;
        let rings = nx.max(ny).max(nz);
        for r in 0..rings {
            // The cells at Chebyshev distance `r` from the goal's cell.
            let span = |a: usize| {
                let lo = home[a].saturating_sub(r);
                let hi = (home[a] + r).min(self.dims[a] - 1);
                (lo, hi)
            };
            let ((x0, x1), (y0, y1), (z0, z1)) = (span(0), span(1), span(2));
            for z in z0..=z1 {
                let z_on = z.abs_diff(home[2]) == r;
                for y in y0..=y1 {
                    let yz_on = z_on || y.abs_diff(home[1]) == r;
                    let row = self.dims[0] * (y + self.dims[1] * z);
                    if yz_on {
                        self.scan(row + x0, row + x1 + 1, &q, out);
                    } else {
                        // Inside the ring along y and z (so r > 0): only its two x ends.
                        if home[0] >= r {
                            let x = row + home[0] - r;
                            self.scan(x, x + 1, &q, out);
                        }
                        if home[0] + r < nx {
                            let x = row + home[0] + r;
                            self.scan(x, x + 1, &q, out);
                        }
                    }
                }
            }
            // How near a cell outside the rings visited can be: the nearest face of their
            // block that does not lie on the grid's border.
            let mut bound = f64::INFINITY;
            for a in 0..3 {
                if home[a] > r {
                    let face = self.origin[a] + (home[a] - r) as f64 * self.cell;
                    bound = bound.min(p[a] - face);
                }
                if home[a] + r + 1 < self.dims[a] {
                    let face = self.origin[a] + (home[a] + r + 1) as f64 * self.cell;
                    bound = bound.min(face - p[a]);
                }
            }
            if bound == f64::INFINITY {
                break;
            }
            if out.len() == keep {
                // Less a margin for the rounding of the cells' assignment.
                let b = (bound - 1e-9 * self.cell).max(0.0);
                // NaN distances (a goal that is not finite) never prove the search done.
                if b * b > out[keep - 1].0 {
                    break;
                }
            }
        }
    }

    /// [`StartTable::nearest`] of a pose goal (`q`, its rotation `r` column-major): the leaves
    /// whose bounds are smallest, then every other leaf that can hold a start nearer than the
    /// last kept.
    fn nearest_pose(&self, q: &Query<'_>, r: &[f64], out: &mut Vec<(f64, u32)>) {
        let leaves = &self.leaves;
        let n = leaves.len();
        let keep = q.keep;
        let mut bound = [0.0f64; MOST_LEAVES];
        let bound = &mut bound[..n];
        leaves.bounds(&q.p, r, q.reach2, 0, bound);
        let scan = |l: usize, out: &mut Vec<(f64, u32)>| {
            let (a, b) = (leaves.offsets[l] as usize, leaves.offsets[l + 1] as usize);
            scan_entries(&leaves.columns, &leaves.index, a, b, q, out);
        };
        // The leaves with the smallest bounds first (NaN bounds last).
        let mut first = [(0.0f64, 0u32); MOST_LEAVES];
        let first = &mut first[..n];
        for (l, f) in first.iter_mut().enumerate() {
            *f = (bound[l], l as u32);
        }
        let m = FIRST_LEAVES.min(n);
        if m < n {
            first.select_nth_unstable_by(m, |a, b| a.0.total_cmp(&b.0));
        }
        let mut scanned = [false; MOST_LEAVES];
        for &(_, l) in &first[..m] {
            scan(l as usize, out);
            scanned[l as usize] = true;
        }
        for (l, &b) in bound.iter().enumerate() {
            // Scanned already; or a bound beyond the last kept distance: no start kept there
            // (a NaN bound or distance proves nothing: the leaf is scanned).
            if scanned[l] || (out.len() == keep && b > out[keep - 1].0) {
                continue;
            }
            scan(l, out);
        }
    }

    /// Whether some start lies nearer than `threshold` (squared task distance, finite) to the
    /// pose goal `goal` (its distance worked out as [`StartTable::nearest`] does): only the
    /// leaves whose bounds lie below it are looked at, none when the threshold is small (the
    /// previous solution of a path's goal).
    pub(crate) fn pose_nearer(&self, goal: &Goal, reach2: f64, threshold: f64) -> bool {
        let Goal::Pose(g) = goal else {
            return false;
        };
        let leaves = &self.leaves;
        let n = leaves.len();
        if self.index.is_empty() {
            return false;
        }
        let t = &g.translation;
        let q = Query {
            goal,
            p: [t.x, t.y, t.z],
            reach2,
            keep: 1,
        };
        // Leaves a block at a time, in leaf order: a far threshold is passed in the first.
        let mut bound = [0.0f64; BLOCK];
        let mut d = [0.0f64; CHUNK];
        for from in (0..n).step_by(BLOCK) {
            let bound = &mut bound[..BLOCK.min(n - from)];
            leaves.bounds(&q.p, g.rotation.as_slice(), reach2, from, bound);
            for (l, &b) in bound.iter().enumerate() {
                // Every start of the leaf at or beyond the bound: none nearer.
                if b >= threshold {
                    continue;
                }
                let l = from + l;
                let (a, b) = (leaves.offsets[l] as usize, leaves.offsets[l + 1] as usize);
                let mut start = a;
                while start < b {
                    let end = (start + CHUNK).min(b);
                    let d = &mut d[..end - start];
                    chunk_distances(&leaves.columns, start, end, &q, d);
                    if d.iter().any(|&d| d < threshold) {
                        return true;
                    }
                    start = end;
                }
            }
        }
        false
    }

    /// Looks at the entries of cells `from..to` (one row of cells), keeping the nearest in
    /// `out` (at most `keep`, by distance then start index).
    fn scan(&self, from: usize, to: usize, q: &Query<'_>, out: &mut Vec<(f64, u32)>) {
        let (a, b) = (self.offsets[from] as usize, self.offsets[to] as usize);
        scan_entries(&self.columns, &self.index, a, b, q, out);
    }
}

/// Looks at entries `a..b` of `columns` (start indices `index`), keeping the nearest in `out`
/// (at most `keep`, by distance then start index).
fn scan_entries(
    columns: &[Vec<f64>; 12],
    index: &[u32],
    a: usize,
    b: usize,
    q: &Query<'_>,
    out: &mut Vec<(f64, u32)>,
) {
    let keep = q.keep;
    let mut d = [0.0f64; CHUNK];
    let mut start = a;
    while start < b {
        let end = (start + CHUNK).min(b);
        let d = &mut d[..end - start];
        chunk_distances(columns, start, end, q, d);
        for (e, &d) in d.iter().enumerate() {
            let i = index[start + e];
            if out.len() == keep {
                // Not before the last kept (NaN: never kept once the list is full).
                if !before(d, i, out[keep - 1]) {
                    continue;
                }
                out.pop();
            }
            let at = out.partition_point(|&(f, j)| before(f, j, (d, i)));
            out.insert(at, (d, i));
        }
        start = end;
    }
}

/// Entries a scan works out the distances of at once.
const CHUNK: usize = 64;

/// The squared task distances of entries `start..end` of `columns` from `q`'s goal into `d`,
/// number by number (loops the compiler vectorises): the same operations in the same order
/// whichever lookup asks.
fn chunk_distances(
    columns: &[Vec<f64>; 12],
    start: usize,
    end: usize,
    q: &Query<'_>,
    d: &mut [f64],
) {
    let (p, m) = (q.p, end - start);
    let [x, y, z] = [0, 1, 2].map(|c| &columns[c][start..end]);
    for e in 0..m {
        d[e] = (p[0] - x[e]).powi(2) + (p[1] - y[e]).powi(2) + (p[2] - z[e]).powi(2);
    }
    if let Goal::Pose(g) = q.goal {
        let r = g.rotation.as_slice();
        let c: [&[f64]; 9] = std::array::from_fn(|k| &columns[3 + k][start..end]);
        for e in 0..m {
            let mut trace = 0.0;
            for k in 0..9 {
                trace += r[k] * c[k][e];
            }
            d[e] += q.reach2 * (3.0 - trace);
        }
    }
}

/// One lookup: the goal, its position (m), the weight of attitudes (m^2 per unit of `3 -
/// trace`) and how many starts to keep.
struct Query<'g> {
    goal: &'g Goal,
    p: [f64; 3],
    reach2: f64,
    keep: usize,
}

/// Whether `(d, i)` comes before `(w, j)`: a smaller distance, or the same and a smaller start
/// index (a NaN distance comes before nothing).
fn before(d: f64, i: u32, (w, j): (f64, u32)) -> bool {
    match d.partial_cmp(&w) {
        Some(std::cmp::Ordering::Less) => true,
        Some(std::cmp::Ordering::Equal) => i < j,
        _ => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::kinematics::Frame;
    use nalgebra::{Matrix3, Rotation3, Vector3};
    use rand::{RngExt, SeedableRng};

    /// The whole table scanned in index order: the `keep` smallest by (distance, index).
    fn scanned(keys: &[[f64; 12]], goal: &Goal, reach2: f64, keep: usize) -> Vec<(f64, u32)> {
        let mut all: Vec<(f64, u32)> = keys
            .iter()
            .enumerate()
            .map(|(i, k)| {
                let (p, att) = match goal {
                    Goal::Position(p) => (p, 0.0),
                    Goal::Pose(g) => {
                        let r = g.rotation.as_slice();
                        let trace: f64 = (0..9).fold(0.0, |t, c| t + r[c] * k[3 + c]);
                        (&g.translation, reach2 * (3.0 - trace))
                    }
                };
                let d = (p.x - k[0]).powi(2) + (p.y - k[1]).powi(2) + (p.z - k[2]).powi(2);
                (
                    if matches!(goal, Goal::Pose(_)) {
                        d + att
                    } else {
                        d
                    },
                    i as u32,
                )
            })
            .collect();
        all.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        all.truncate(keep);
        all
    }

    fn rotation(rng: &mut impl rand::Rng) -> Matrix3<f64> {
        let v = Vector3::new(
            rng.random_range(-3.0..3.0),
            rng.random_range(-3.0..3.0),
            rng.random_range(-3.0..3.0),
        );
        *Rotation3::new(v).matrix()
    }

    /// `n` frames at random: positions in the cube of side 2 m about the origin, rotations at
    /// random.
    fn cube_keys(rng: &mut rand_chacha::ChaCha8Rng, n: usize) -> Vec<[f64; 12]> {
        (0..n)
            .map(|_| {
                let mut k = [0.0; 12];
                for x in &mut k[..3] {
                    *x = rng.random_range(-1.0..1.0);
                }
                k[3..].copy_from_slice(rotation(rng).as_slice());
                k
            })
            .collect()
    }

    /// The grid's lookup returns exactly what a scan of the whole table returns (the same
    /// starts, order and distances to the bit), for position and pose goals inside, at the
    /// border of and far outside the starts' box, with ties (starts repeated), on a workspace
    /// that fills a ball, one that is flat (a planar arm) and one that is a single point.
    #[test]
    fn the_grid_finds_what_a_scan_of_the_whole_table_finds() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let ball = |rng: &mut rand_chacha::ChaCha8Rng| {
            let mut k = [0.0; 12];
            loop {
                let v: [f64; 3] = std::array::from_fn(|_| rng.random_range(-1.3..1.3));
                if v.iter().map(|x| x * x).sum::<f64>() < 1.69 {
                    k[..3].copy_from_slice(&v);
                    break;
                }
            }
            k[3..].copy_from_slice(rotation(rng).as_slice());
            k
        };
        let flat = |rng: &mut rand_chacha::ChaCha8Rng| {
            let mut k = ball(rng);
            k[2] = 0.4;
            k
        };
        let point = |rng: &mut rand_chacha::ChaCha8Rng| {
            let mut k = ball(rng);
            k[..3].copy_from_slice(&[0.1, -0.2, 0.3]);
            k
        };
        type Maker<'a> = &'a dyn Fn(&mut rand_chacha::ChaCha8Rng) -> [f64; 12];
        let makers: [Maker<'_>; 3] = [&ball, &flat, &point];
        for make in makers {
            for n in [1, 7, 300, 4096] {
                let mut keys: Vec<[f64; 12]> = (0..n).map(|_| make(&mut rng)).collect();
                // Ties: some starts twice.
                for i in (0..n).step_by(5) {
                    keys.push(keys[i]);
                }
                let table = StartTable::new(&keys, 1.3);
                let mut out = Vec::new();
                for q in 0..200 {
                    let scale = [0.5, 1.0, 1.5, 10.0][q % 4];
                    let p = Vector3::from_fn(|_, _| scale * rng.random_range(-1.3..1.3));
                    // Some goals exactly at a start.
                    let at = (q % 7 == 0).then(|| keys[q % keys.len()]);
                    let p = at.map_or(p, |k| Vector3::new(k[0], k[1], k[2]));
                    let goals = [
                        Goal::Position(p),
                        Goal::Pose(Frame {
                            rotation: at.map_or_else(
                                || rotation(&mut rng),
                                |k| Matrix3::from_column_slice(&k[3..]),
                            ),
                            translation: p,
                        }),
                    ];
                    for goal in &goals {
                        for keep in [1, 8, 32] {
                            let reach2 = 1.69;
                            table.nearest(goal, reach2, keep, &mut out);
                            let expected = scanned(&keys, goal, reach2, keep);
                            assert_eq!(out.len(), expected.len());
                            for (a, b) in out.iter().zip(&expected) {
                                assert_eq!(a.1, b.1, "n {n}, goal {q}, keep {keep}");
                                assert_eq!(a.0.to_bits(), b.0.to_bits());
                            }
                        }
                    }
                }
            }
        }
    }

    /// Pose goals far away (1e200 m or infinitely), or with a rotation that is no rotation,
    /// get what a scan of the whole table gives them too; goals whose every distance is NaN
    /// get as many starts as asked.
    #[test]
    fn extreme_pose_goals_get_what_a_scan_gives() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(12);
        let keys = cube_keys(&mut rng, 4096);
        let table = StartTable::new(&keys, 1.3);
        let mut out = Vec::new();
        let far = Vector3::new(1e200, -1e200, 3.0);
        let nan = Vector3::new(f64::NAN, 0.0, 0.0);
        let inf = Vector3::new(0.0, f64::INFINITY, 0.0);
        let near = Vector3::new(0.1, 0.2, 0.3);
        let goals = [
            (far, rotation(&mut rng)),
            (nan, rotation(&mut rng)),
            (inf, rotation(&mut rng)),
            (near, Matrix3::from_element(f64::NAN)),
            (near, Matrix3::from_element(1e10)),
            (near, Matrix3::zeros()),
            (near, 3.0 * rotation(&mut rng)),
        ];
        for (k, (translation, rotation)) in goals.into_iter().enumerate() {
            let goal = Goal::Pose(Frame {
                rotation,
                translation,
            });
            for keep in [1, 8, 32] {
                table.nearest(&goal, 1.69, keep, &mut out);
                let expected = scanned(&keys, &goal, 1.69, keep);
                let ids = |v: &[(f64, u32)]| v.iter().map(|x| x.1).collect::<Vec<_>>();
                if k == 1 || k == 3 {
                    // NaN distances, every one: any starts, as many as asked.
                    assert_eq!(out.len(), keep);
                } else {
                    assert_eq!(ids(&out), ids(&expected), "goal {k}, keep {keep}");
                }
            }
        }
    }

    /// Whether a start lies nearer a pose goal than a threshold, as a scan of the whole table
    /// tells it: at the nearest start's distance itself (no start strictly nearer), just above
    /// and below it, at 0 and far above, for goals inside and outside the starts' box.
    #[test]
    fn a_start_nearer_than_a_threshold_is_found_as_a_scan_finds_it() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(13);
        let keys = cube_keys(&mut rng, 4096);
        let table = StartTable::new(&keys, 1.3);
        let mut checked = 0;
        for q in 0..300 {
            let scale = [0.3, 1.0, 3.0][q % 3];
            let goal = Goal::Pose(Frame {
                rotation: rotation(&mut rng),
                translation: Vector3::from_fn(|_, _| scale * rng.random_range(-1.0..1.0)),
            });
            let nearest = scanned(&keys, &goal, 1.69, 1)[0].0;
            for t in [
                nearest,
                nearest * (1.0 + 1e-15),
                nearest * (1.0 - 1e-15),
                nearest.next_up(),
                0.0,
                2.0 * nearest,
                1e6,
            ] {
                assert_eq!(
                    table.pose_nearer(&goal, 1.69, t),
                    nearest < t,
                    "goal {q}, threshold {t:e}, nearest {nearest:e}"
                );
                checked += 1;
            }
        }
        assert_eq!(checked, 2100);
    }

    /// A goal that is not finite gets starts and no panic.
    #[test]
    fn a_goal_that_is_not_finite_is_looked_up_without_a_panic() {
        let keys = vec![[0.0; 12], [1.0; 12]];
        let table = StartTable::new(&keys, 1.3);
        let mut out = Vec::new();
        table.nearest(
            &Goal::Position(Vector3::new(f64::NAN, 0.0, f64::INFINITY)),
            1.0,
            2,
            &mut out,
        );
        assert_eq!(out.len(), 2);
    }
}
