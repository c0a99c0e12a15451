//! Measurement planning (optimal experiment design): which postures to measure.
//!
//! A plan chooses `count` postures from a pool of candidates (postures sampled within the joint
//! ranges, or a file of candidates) so that the data they give determine the estimated
//! parameters best. "Best" is a criterion of the *information matrix* `M = J^T J` of the scaled
//! identification Jacobian `J` of the chosen postures, evaluated at the nominal robot:
//!
//! - rows are residuals divided by their standard deviation (the row's own, or the
//!   [`Weights`](crate::observe::Weights) of the analysis options), as in calibration;
//! - columns are the estimated parameters (by default the identifiable set the whole pool
//!   determines, see [`crate::workflow::resolve`]), each divided by its root-mean-square over the
//!   pool's candidates, so that the pool's *average* candidate carries unit information on
//!   every parameter and no unit (mm against degrees, a slope against a length) weighs more
//!   than another.
//!
//! The criteria ([`Criterion`]), with `s_i` the singular values of `J` (`s_i^2` the eigenvalues of
//! `M`), `n` parameters and `m` rows: D-optimality `log det M = sum ln s_i^2` (Fedorov; the volume
//! of the confidence ellipsoid), A-optimality `trace M^-1 = sum 1/s_i^2` (the mean variance,
//! smaller is better), I-optimality `trace(W M^-1)` with `W` the pool's average information per
//! candidate (the variance of the calibrated robot's predictions averaged over the pool: the
//! criterion of held-out accuracy; smaller is better), E-optimality `s_min^2`, and the
//! observability indices of the calibration literature: O1 `(prod s_i)^(1/n) / sqrt(m)` (Borm &
//! Menq 1991), O2 `s_min / s_max` (Driels & Pathre 1990), O3 `s_min` (Nahvi, Hollerbach & Hayward
//! 1994), O4 `s_min^2 / s_max` (the noise amplification index, Nahvi & Hollerbach 1996) and O5 `1 /
//! sum 1/s_i` (Sun & Hollerbach 2008).
//!
//! The search: postures given to keep (already measured) are always in; then a greedy start adds
//! the candidate that raises `log det` most (a small ridge `1e-8 I` keeps `M` invertible while
//! fewer postures than parameters are chosen), then an exchange (Fedorov's, as in DETMAX) swaps a
//! chosen posture for a candidate while that improves the criterion, until no swap does. Every
//! other criterion starts from the D-optimal plan. For D, A and I every swap is tried, by rank-r
//! updates (Sherman-Morrison-Woodbury) with one Cholesky factor per removed posture; for the
//! criteria of the eigenvalues (E, O1-O5), for each removed posture the [`EXCHANGE_SHORTLIST`]
//! candidates adding most `log det` are tried. Everything is deterministic: ties go to the lower
//! candidate index, and the random plans the result is compared with are drawn from the given seed.
//!
//! A candidate is a group of postures the pool's observations link (`Dataset::posture_groups`):
//! a posture with all its targets (tool, reflectors), or the two ends of a distance.

use rand::seq::SliceRandom;
use rand::SeedableRng;

use crate::error::{Error, Result};
use crate::identifiability::AnalysisOptions;
use crate::linalg::{self, Matrix};
use crate::model::kinematics::{Chain, Target, Workspace};
use crate::model::params::ParamId;
use crate::model::robot::Robot;
use crate::observe::point::{Pose, Position};
use crate::observe::{Dataset, Observation, Posture};
use crate::solve::problem::Problem;
use crate::workflow::{self, Selection};

/// For criteria other than D, the number of candidates tried in place of each chosen posture in
/// the exchange: those that add most `log det` to the plan without it.
pub const EXCHANGE_SHORTLIST: usize = 48;

/// Ridge added to the information matrix while choosing (the pool's average candidate carries
/// unit information per parameter): keeps `M` invertible with fewer postures than parameters.
const RIDGE: f64 = 1e-8;

/// The exchange stops after this many passes even if a swap still improves the criterion.
const MAX_PASSES: usize = 100;

/// How many random plans the result is compared with.
pub(crate) const RANDOM_PLANS: usize = 100;

/// What a plan maximises (see the [module documentation](self) for the formulas).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[non_exhaustive]
pub enum Criterion {
    /// `log det M`: the volume of the confidence ellipsoid of the parameters.
    #[default]
    D,
    /// `trace M^-1`: the mean variance of the (scaled) parameters; smaller is better.
    A,
    /// `trace(W M^-1)` with `W` the pool's average information per candidate: the variance of
    /// the calibrated robot's predictions, averaged over the pool (in units of the measurement
    /// variance, summed over a candidate's rows); smaller is better. The criterion of held-out
    /// accuracy when the pool samples where the robot will work.
    I,
    /// `s_min^2`: the variance of the worst-determined combination.
    E,
    /// `(prod s_i)^(1/n) / sqrt(m)` (Borm & Menq).
    O1,
    /// `s_min / s_max`, the inverse condition number (Driels & Pathre).
    O2,
    /// `s_min` (Nahvi, Hollerbach & Hayward).
    O3,
    /// `s_min^2 / s_max`, the noise amplification index (Nahvi & Hollerbach).
    O4,
    /// `1 / sum 1/s_i` (Sun & Hollerbach).
    O5,
}

impl Criterion {
    /// Every criterion, in the order reports list them.
    pub const ALL: [Criterion; 9] = [
        Criterion::D,
        Criterion::A,
        Criterion::I,
        Criterion::E,
        Criterion::O1,
        Criterion::O2,
        Criterion::O3,
        Criterion::O4,
        Criterion::O5,
    ];

    /// The name on the command line and in reports (`d`, `a`, ..., `o5`).
    pub fn as_str(self) -> &'static str {
        match self {
            Criterion::D => "d",
            Criterion::A => "a",
            Criterion::I => "i",
            Criterion::E => "e",
            Criterion::O1 => "o1",
            Criterion::O2 => "o2",
            Criterion::O3 => "o3",
            Criterion::O4 => "o4",
            Criterion::O5 => "o5",
        }
    }

    /// What the value is, in words.
    pub fn describe(self) -> &'static str {
        match self {
            Criterion::D => "log det of the information",
            Criterion::A => "trace of the inverse information (smaller is better)",
            Criterion::I => "mean prediction variance over the pool (smaller is better)",
            Criterion::E => "smallest eigenvalue of the information",
            Criterion::O1 => "geometric mean of the singular values / sqrt(rows)",
            Criterion::O2 => "inverse condition number",
            Criterion::O3 => "smallest singular value",
            Criterion::O4 => "noise amplification index",
            Criterion::O5 => "1 / sum of inverse singular values",
        }
    }

    /// Whether a larger value is better (all but A and I).
    pub fn larger_is_better(self) -> bool {
        !matches!(self, Criterion::A | Criterion::I)
    }

    /// The criterion of a design with singular values `s` (any order, zero for undetermined
    /// directions) over `rows` rows, and, for I, the mean prediction variance `mean_variance`;
    /// `None` when the design does not determine every parameter and the criterion needs it
    /// (all but E, O2, O3, O4, which are then 0).
    fn value(self, s: &[f64], rows: usize, mean_variance: Option<f64>) -> Option<f64> {
        let n = s.len() as f64;
        let min = s.iter().copied().fold(f64::INFINITY, f64::min);
        let max = s.iter().copied().fold(0.0, f64::max);
        let singular = min.is_nan() || min <= 0.0;
        let v = match self {
            Criterion::D if singular => return None,
            Criterion::D => s.iter().map(|s| 2.0 * s.ln()).sum(),
            Criterion::A if singular => return None,
            Criterion::A => s.iter().map(|s| 1.0 / (s * s)).sum(),
            Criterion::I if singular => return None,
            Criterion::I => mean_variance?,
            Criterion::E => min.max(0.0).powi(2),
            Criterion::O1 if singular => return None,
            Criterion::O1 => {
                (s.iter().map(|s| s.ln()).sum::<f64>() / n).exp() / (rows as f64).sqrt()
            }
            Criterion::O2 if max > 0.0 => min.max(0.0) / max,
            Criterion::O2 => 0.0,
            Criterion::O3 => min.max(0.0),
            Criterion::O4 if max > 0.0 => min.max(0.0).powi(2) / max,
            Criterion::O4 => 0.0,
            Criterion::O5 if singular => return None,
            Criterion::O5 => 1.0 / s.iter().map(|s| 1.0 / s).sum::<f64>(),
        };
        Some(v)
    }

    /// The value as a score to maximise (`-infinity` for a design the criterion cannot rate).
    fn score(self, s: &[f64], rows: usize) -> f64 {
        match self.value(s, rows, None) {
            Some(v) if self.larger_is_better() => v,
            Some(v) => -v,
            None => f64::NEG_INFINITY,
        }
    }
}

impl std::str::FromStr for Criterion {
    type Err = Error;
    fn from_str(s: &str) -> Result<Criterion> {
        Criterion::ALL
            .into_iter()
            .find(|c| c.as_str().eq_ignore_ascii_case(s.trim()))
            .ok_or_else(|| Error::InvalidOption {
                setting: crate::error::Setting::PlanCriterion,
                message: format!(
                    "`{s}` is not a criterion: expected d, a, i, e, o1, o2, o3, o4 or o5"
                ),
            })
    }
}

/// A planning problem.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct PlanRequest {
    /// The nominal robot (the plan is evaluated at it).
    pub robot: Robot,
    /// The candidates: observations at candidate postures (their measured values are not used).
    /// See [`candidates`] to build them from postures.
    pub pool: Dataset,
    /// Observations already made (or to be made in any case): always in the plan. May be empty.
    pub keep: Dataset,
    /// How many candidates to add to the kept ones.
    pub count: usize,
    /// What to maximise.
    pub criterion: Criterion,
    /// The parameters to determine (by default the identifiable set of the default parameters
    /// on the pool and the kept observations together).
    pub selection: Selection,
    /// Row weights, orientation error and rank tolerance.
    pub analysis: AnalysisOptions,
    /// Seed of the random plans the result is compared with.
    pub seed: u64,
}

impl PlanRequest {
    /// A D-optimal plan of `count` candidates of `pool` for the identifiable set, nothing kept.
    pub fn new(robot: Robot, pool: Dataset, count: usize) -> PlanRequest {
        PlanRequest {
            robot,
            pool,
            keep: Dataset::default(),
            count,
            criterion: Criterion::D,
            selection: Selection::Identifiable {
                with: Vec::new(),
                fix: Vec::new(),
            },
            analysis: AnalysisOptions::default(),
            seed: 1,
        }
    }
}

/// One posture of a plan and what it contributes.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct PlannedPosture {
    /// Index into the pool's postures, or `None` for a kept posture.
    pub candidate: Option<usize>,
    /// The posture's label.
    pub label: String,
    /// The readings (transducer units).
    pub readings: Vec<f64>,
    /// Its leverage: `trace(J_p M^-1 J_p^T)` for its rows `J_p`, the number of the `n`
    /// parameters' worth of information it carries (the leverages of a plan that determines
    /// every parameter sum to `n`). A posture of leverage near its row count cannot be left out
    /// without losing a direction.
    pub leverage: f64,
}

/// Random plans of the same size, for comparison.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct RandomPlans {
    /// How many were drawn.
    pub draws: usize,
    /// The median criterion value (`None` when the median random plan does not determine every
    /// parameter and the criterion needs it).
    pub median_value: Option<f64>,
    /// The median D-efficiency relative to the pool (see [`Plan::efficiency`]).
    pub median_efficiency: Option<f64>,
    /// How many of them the chosen plan is at least as good as, by the criterion.
    pub beaten: usize,
}

/// A measurement plan.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct Plan {
    /// The parameters it is designed to determine (sorted).
    pub parameters: Vec<ParamId>,
    /// The criterion maximised.
    pub criterion: Criterion,
    /// Its value for the plan (kept and chosen postures together); `None` when the plan does
    /// not determine every parameter and the criterion needs it.
    pub value: Option<f64>,
    /// Every criterion's value for the plan, in [`Criterion::ALL`] order.
    pub values: Vec<(Criterion, Option<f64>)>,
    /// The kept postures, then the chosen ones in the pool's order.
    pub postures: Vec<PlannedPosture>,
    /// The chosen candidates' observations (a subset of the pool, renumbered).
    pub chosen: Dataset,
    /// Residual rows of the plan (kept and chosen).
    pub rows: usize,
    /// Numerical rank of the plan's scaled Jacobian (singular values above `rcond * s_max`).
    pub rank: usize,
    /// Ratio of the largest to the smallest singular value; `None` when the plan does not
    /// determine every parameter.
    pub condition_number: Option<f64>,
    /// Number of candidates in the pool, and of its postures.
    pub pool_candidates: usize,
    /// The fraction of the pool's information the plan retains, per posture: the D-efficiency
    /// `(det(M_plan / k) / det(M_pool / N))^(1/n)` of the plan's `k` candidates against the
    /// pool's `N` (each with the kept postures counted in). 1 means the chosen postures carry,
    /// on average, as much information as the pool's average candidate; above 1, more: a plan
    /// concentrates on the informative ones. `None` when either does not determine every
    /// parameter.
    pub efficiency: Option<f64>,
    /// Random plans of the same size from the same pool.
    pub random: Option<RandomPlans>,
    /// Swaps the exchange made after the greedy start, and its passes over the plan.
    pub exchanges: usize,
    /// Passes of the exchange.
    pub passes: usize,
}

/// A plan as a document: what `kinecal plan --json` prints (values in the robot file's units:
/// readings as its transducer values).
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize, PartialEq, schemars::JsonSchema)]
#[non_exhaustive]
pub struct PlanReport {
    /// The version of this document's schema ([`crate::report::SCHEMA_VERSION`]).
    pub schema_version: u32,
    /// Robot name.
    pub robot: String,
    /// The criterion maximised (`d`, `a`, `i`, `e`).
    pub criterion: String,
    /// Its value for the plan (null when the plan does not determine every parameter).
    pub value: Option<f64>,
    /// Every criterion's value.
    pub values: std::collections::BTreeMap<String, Option<f64>>,
    /// The parameters it is designed to determine (ids).
    pub parameters: Vec<String>,
    /// Their names.
    pub parameter_names: Vec<String>,
    /// Residual rows of the plan.
    pub rows: usize,
    /// Numerical rank of its scaled Jacobian.
    pub rank: usize,
    /// Its condition number (null when it does not determine every parameter).
    pub condition_number: Option<f64>,
    /// Candidates in the pool.
    pub pool_candidates: usize,
    /// D-efficiency against the pool (see [`Plan::efficiency`]).
    pub efficiency: Option<f64>,
    /// Random plans of the same size, for comparison.
    pub random: Option<RandomPlansReport>,
    /// Swaps the exchange made.
    pub exchanges: usize,
    /// Its passes.
    pub passes: usize,
    /// The kept postures, then the chosen ones.
    pub postures: Vec<PlannedPostureReport>,
}

/// Random plans of a plan's size (in a [`PlanReport`]).
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize, PartialEq, schemars::JsonSchema)]
#[non_exhaustive]
pub struct RandomPlansReport {
    /// How many were drawn.
    pub draws: usize,
    /// Their median criterion value.
    pub median_value: Option<f64>,
    /// Their median efficiency.
    pub median_efficiency: Option<f64>,
    /// How many the plan is at least as good as.
    pub at_least_as_good_as: usize,
}

/// A posture of a plan (in a [`PlanReport`]).
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize, PartialEq, schemars::JsonSchema)]
#[non_exhaustive]
pub struct PlannedPostureReport {
    /// Its label.
    pub label: String,
    /// Kept (given), not chosen.
    pub kept: bool,
    /// The candidate's index in the pool (null when kept).
    pub candidate: Option<usize>,
    /// Its readings (transducer values).
    pub readings: Vec<f64>,
    /// Its leverage in the plan.
    pub leverage: f64,
}

impl PlanReport {
    /// The document of `p` for `robot`.
    pub fn new(p: &Plan, robot: &Robot) -> PlanReport {
        PlanReport {
            schema_version: crate::report::SCHEMA_VERSION,
            robot: robot.name.clone(),
            criterion: p.criterion.as_str().to_string(),
            value: p.value,
            values: p
                .values
                .iter()
                .map(|(c, v)| (c.as_str().to_string(), *v))
                .collect(),
            parameters: p.parameters.iter().map(ToString::to_string).collect(),
            parameter_names: p
                .parameters
                .iter()
                .map(|&id| robot.param_name(id))
                .collect(),
            rows: p.rows,
            rank: p.rank,
            condition_number: p.condition_number,
            pool_candidates: p.pool_candidates,
            efficiency: p.efficiency,
            random: p.random.as_ref().map(|r| RandomPlansReport {
                draws: r.draws,
                median_value: r.median_value,
                median_efficiency: r.median_efficiency,
                at_least_as_good_as: r.beaten,
            }),
            exchanges: p.exchanges,
            passes: p.passes,
            postures: p
                .postures
                .iter()
                .map(|q| PlannedPostureReport {
                    label: q.label.clone(),
                    kept: q.candidate.is_none(),
                    candidate: q.candidate,
                    readings: q.readings.clone(),
                    leverage: q.leverage,
                })
                .collect(),
        }
    }

    /// Pretty-printed JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("a report is plain data JSON can hold")
    }
}

/// The JSON Schema of [`PlanReport`], as shipped in `schemas/plan.schema.json`.
pub fn plan_schema() -> String {
    let schema = schemars::schema_for!(PlanReport);
    serde_json::to_string_pretty(&schema).expect("a schema is JSON") + "\n"
}

impl Plan {
    /// The file of the postures to measure, for `robot`: the chosen candidates' observations as
    /// a measurement file when the pool was measured observations of poses and positions only
    /// (`observed`), else their postures as a postures file. Returns the text and what it is
    /// (`measurements` or `postures`).
    pub fn chosen_file(&self, robot: &Robot, observed: bool) -> (String, &'static str) {
        let points_only = self
            .chosen
            .observations
            .iter()
            .all(|o| matches!(o, Observation::Pose(_) | Observation::Position(_)));
        if observed && points_only {
            return (
                crate::files::write_measurements(robot, &self.chosen),
                "measurements",
            );
        }
        let chosen: Vec<Posture> = self
            .postures
            .iter()
            .filter(|q| q.candidate.is_some())
            .map(|q| Posture {
                label: q.label.clone(),
                readings: q.readings.clone(),
                session: None,
                payload: None,
            })
            .collect();
        (crate::files::write_postures(robot, &chosen), "postures")
    }
}

/// Observations at `postures` of the given `targets` (the end effector and sites), full poses
/// or positions only, with the values the `robot` predicts: a pool of candidates or a plan to
/// measure. A robot with cameras and boards is measured by its cameras: the candidates are then
/// the pixels each camera sees of each board (at least 4 points of one; postures that see less
/// are left out).
pub fn candidates(
    robot: &Robot,
    postures: Vec<Posture>,
    targets: &[Target],
    position_only: bool,
) -> Dataset {
    let chain = Chain::new(robot);
    let mut ws = Workspace::new(robot);
    if !robot.cameras.is_empty() && !robot.boards.is_empty() {
        let mut kept = Vec::new();
        let mut observations: Vec<Observation> = Vec::new();
        for p in postures {
            chain.forward_loaded(&p.readings, None, p.payload.as_ref(), &mut ws);
            let mut seen = Vec::new();
            for camera in 0..robot.cameras.len() {
                for board in 0..robot.boards.len() {
                    let pixels = crate::apps::simulate::seen_pixels(
                        robot,
                        &chain,
                        &ws,
                        kept.len(),
                        camera,
                        board,
                    );
                    if pixels.len() >= 4 {
                        seen.extend(pixels);
                    }
                }
            }
            if !seen.is_empty() {
                kept.push(p);
                observations.extend(seen);
            }
        }
        return Dataset::new(kept, observations);
    }
    let mut observations: Vec<Observation> = Vec::with_capacity(postures.len() * targets.len());
    for (i, p) in postures.iter().enumerate() {
        chain.forward(&p.readings, &mut ws);
        for &t in targets {
            let pose = chain.target_frame(&ws, t).pose();
            observations.push(if position_only {
                Position::new(i, t, pose.position).into()
            } else {
                Pose::new(i, t, pose.position, pose.euler).into()
            });
        }
    }
    Dataset::new(postures, observations)
}

/// The scaled Jacobian rows of each candidate, stored candidate after candidate.
struct Design {
    /// Parameters (columns).
    n: usize,
    /// Rows, `n` values each, candidate after candidate.
    rows: Vec<f64>,
    /// Candidate `c` owns rows `start[c]..start[c + 1]`.
    start: Vec<usize>,
}

impl Design {
    fn candidates(&self) -> usize {
        self.start.len() - 1
    }

    fn block(&self, c: usize) -> &[f64] {
        &self.rows[self.start[c] * self.n..self.start[c + 1] * self.n]
    }

    fn block_rows(&self, c: usize) -> usize {
        self.start[c + 1] - self.start[c]
    }

    /// `m += sign * B_c^T B_c`.
    fn add(&self, m: &mut [f64], c: usize, sign: f64) {
        let n = self.n;
        for row in self.block(c).chunks_exact(n) {
            for (i, &ri) in row.iter().enumerate() {
                let a = sign * ri;
                if a == 0.0 {
                    continue;
                }
                for (mij, &rj) in m[i * n..i * n + n].iter_mut().zip(row) {
                    *mij += a * rj;
                }
            }
        }
    }

    /// The information of candidates `set` plus `ridge * I`.
    fn information(&self, set: impl IntoIterator<Item = usize>, ridge: f64) -> Vec<f64> {
        let n = self.n;
        let mut m = vec![0.0; n * n];
        for i in 0..n {
            m[i * n + i] = ridge;
        }
        for c in set {
            self.add(&mut m, c, 1.0);
        }
        m
    }

    /// Singular values of the stacked rows of `set`.
    fn singular_values(&self, set: &[usize]) -> Vec<f64> {
        let rows: usize = set.iter().map(|&c| self.block_rows(c)).sum();
        let mut a = Matrix::zeros(rows.max(1), self.n);
        let mut i = 0;
        for &c in set {
            for row in self.block(c).chunks_exact(self.n) {
                for (j, &v) in row.iter().enumerate() {
                    a[(i, j)] = v;
                }
                i += 1;
            }
        }
        let mut s = linalg::singular_values(&a).unwrap_or_default();
        s.resize(self.n, 0.0);
        s
    }
}

/// Lower Cholesky factor of the symmetric `m` (n x n, row-major) into `l`; its `log det`, or
/// `None` when `m` is not numerically positive definite.
fn cholesky(m: &[f64], n: usize, l: &mut [f64]) -> Option<f64> {
    l.fill(0.0);
    let mut logdet = 0.0;
    for j in 0..n {
        let mut d = m[j * n + j];
        for k in 0..j {
            d -= l[j * n + k] * l[j * n + k];
        }
        if d.is_nan() || d <= 0.0 {
            return None;
        }
        let d = d.sqrt();
        l[j * n + j] = d;
        logdet += 2.0 * d.ln();
        for i in j + 1..n {
            let mut v = m[i * n + j];
            for k in 0..j {
                v -= l[i * n + k] * l[j * n + k];
            }
            l[i * n + j] = v / d;
        }
    }
    Some(logdet)
}

/// Work space of [`gain`] and [`trace_reduction`], reused from candidate to candidate.
#[derive(Default)]
struct Scratch {
    /// `L^-1 B^T` (then `M^-1 B^T`), one row of `B` after another.
    y: Vec<f64>,
    /// `G = I + B M^-1 B^T` and its Cholesky factor.
    g: Vec<f64>,
    lg: Vec<f64>,
    /// `Z^T W Z`, `W z` and a column.
    h: Vec<f64>,
    wz: Vec<f64>,
    col: Vec<f64>,
}

impl Scratch {
    /// Fills `y` with `L^-1 B^T` and `g` with `I + B M^-1 B^T`; returns `trace(B M^-1 B^T)`.
    fn prepare(&mut self, l: &[f64], n: usize, b: &[f64]) -> f64 {
        let r = b.len() / n;
        self.y.clear();
        self.y.extend_from_slice(b);
        for yk in self.y.chunks_exact_mut(n) {
            forward(l, n, yk);
        }
        let (y, g) = (&self.y, &mut self.g);
        g.clear();
        g.resize(r * r, 0.0);
        let mut trace = 0.0;
        for a in 0..r {
            for c in 0..=a {
                let d: f64 = y[a * n..a * n + n]
                    .iter()
                    .zip(&y[c * n..c * n + n])
                    .map(|(p, q)| p * q)
                    .sum();
                g[a * r + c] = d;
                g[c * r + a] = d;
            }
            trace += g[a * r + a];
            g[a * r + a] += 1.0;
        }
        self.lg.resize(r * r, 0.0);
        trace
    }
}

/// With `l` the Cholesky factor of `M`, returns `log det(I + B M^-1 B^T)` (how much adding the
/// rows `b` raises `log det M`) and `trace(B M^-1 B^T)` (their leverage).
fn gain(l: &[f64], n: usize, b: &[f64], s: &mut Scratch) -> (f64, f64) {
    let trace = s.prepare(l, n, b);
    let r = b.len() / n;
    let logdet = cholesky(&s.g, r, &mut s.lg).unwrap_or(f64::NEG_INFINITY);
    (logdet, trace)
}

/// Singular values with those at or below `rcond * s_max` set to zero: directions the design
/// leaves undetermined.
fn cut(mut s: Vec<f64>, rcond: f64) -> Vec<f64> {
    let max = s.iter().copied().fold(0.0, f64::max);
    for v in &mut s {
        if *v <= rcond * max {
            *v = 0.0;
        }
    }
    s
}

/// Eigenvalues of the symmetric `m`, as singular values (their square roots, negatives as 0).
fn root_eigenvalues(m: &[f64], n: usize) -> Vec<f64> {
    let a = nalgebra::DMatrix::from_row_slice(n, n, m);
    a.symmetric_eigenvalues()
        .iter()
        .map(|&e| e.max(0.0).sqrt())
        .collect()
}

/// Chooses the plan (see the [module documentation](self)).
pub fn plan(req: &PlanRequest) -> Result<Plan> {
    plan_with(req, &mut |_| {})
}

/// [`plan`], saying what it does to `say` (`planning: posture 12 of 30`).
pub(crate) fn plan_with(req: &PlanRequest, say: &mut dyn FnMut(&str)) -> Result<Plan> {
    let robot = &req.robot;
    if req.pool.is_empty() {
        return Err(Error::InvalidOption {
            setting: crate::error::Setting::PlanCandidates,
            message: "no candidate observations to choose from".into(),
        });
    }
    let kept_postures = req.keep.postures.len();
    let all = req.keep.clone().merge(req.pool.clone());
    say("planning: the parameters");
    let (parameters, _) = workflow::resolve(&req.selection, robot, &all, &req.analysis)?;
    let n = parameters.len();
    say("planning: the candidates' information");

    // Candidates: groups of linked postures; the groups holding kept postures are forced.
    let groups = all.posture_groups();
    let (jac, group_rows) = group_jacobian(req, &all, &parameters, &groups);
    let forced: Vec<bool> = groups.iter().map(|ps| ps[0] < kept_postures).collect();
    let pool_groups: Vec<usize> = (0..groups.len()).filter(|&g| !forced[g]).collect();
    let pool_candidates = pool_groups.len();
    check_count(req.count, pool_candidates)?;
    let design = Design::scaled(&jac, &group_rows, n);
    drop(jac);

    let kept: Vec<usize> = (0..groups.len()).filter(|&g| forced[g]).collect();
    // The pool's average information per candidate (I-optimality's weight).
    let mut average = design.information(0..groups.len(), 0.0);
    average.iter_mut().for_each(|v| *v /= groups.len() as f64);
    let search = Search {
        design: &design,
        kept: &kept,
        pool: &pool_groups,
        average: &average,
    };
    let (chosen, exchanges, passes) = search.run(req.count, req.criterion, say);

    let mut set: Vec<usize> = kept.iter().chain(&chosen).copied().collect();
    set.sort_unstable();
    let rater = Rater::new(&design, &average, req.analysis.rcond);
    let own = rater.rate(&set);
    let values: Vec<(Criterion, Option<f64>)> =
        Criterion::ALL.iter().map(|&c| (c, own.value(c))).collect();
    let value = own.value(req.criterion);
    let condition_number = (own.rank == n).then(|| {
        let max = own.s.iter().copied().fold(0.0, f64::max);
        let min = own.s.iter().copied().fold(f64::INFINITY, f64::min);
        max / min
    });
    let efficiency = rater.efficiency(&own, set.len());
    let leverage = leverages(&design, &set, own.rank == n);
    let (postures, chosen_postures) =
        planned_postures(&all, &groups, &set, &leverage, kept_postures);
    let chosen_data = req.pool.subset(&chosen_postures[kept_postures..]);
    let random = (pool_candidates > req.count).then(|| {
        say("planning: against random plans");
        random_plans(req, &rater, &kept, &pool_groups, value)
    });

    Ok(Plan {
        parameters,
        criterion: req.criterion,
        value,
        values,
        postures,
        chosen: chosen_data,
        rows: own.rows,
        rank: own.rank,
        condition_number,
        pool_candidates,
        efficiency,
        random,
        exchanges,
        passes,
    })
}

/// The weighted Jacobian of every candidate observation at the nominal robot, with the rows of
/// each posture group, in row order.
fn group_jacobian(
    req: &PlanRequest,
    all: &Dataset,
    parameters: &[ParamId],
    groups: &[Vec<usize>],
) -> (Matrix, Vec<Vec<usize>>) {
    let robot = &req.robot;
    let mut group_of = vec![0; all.postures.len()];
    for (g, ps) in groups.iter().enumerate() {
        for &p in ps {
            group_of[p] = g;
        }
    }
    let problem = Problem::new(
        robot,
        all,
        parameters,
        req.analysis.weights,
        req.analysis.orientation,
    );
    let mut res = vec![0.0; problem.rows()];
    let mut jac = Matrix::zeros(0, 0);
    problem.evaluate(robot, &mut res, Some(&mut jac));
    drop(res);
    let mut group_rows: Vec<Vec<usize>> = vec![Vec::new(); groups.len()];
    let mut row = 0;
    for o in &all.observations {
        let g = group_of[o.views()[0].posture];
        for _ in 0..o.rows().len() {
            group_rows[g].push(row);
            row += 1;
        }
    }
    (jac, group_rows)
}

/// A plan of `count` postures out of `pool_candidates`: at least 1, at most all.
fn check_count(count: usize, pool_candidates: usize) -> Result<()> {
    if count == 0 {
        return Err(Error::InvalidOption {
            setting: crate::error::Setting::PlanCount,
            message: "a plan of 0 postures: ask for at least 1".into(),
        });
    }
    if count > pool_candidates {
        return Err(Error::InvalidOption {
            setting: crate::error::Setting::PlanCount,
            message: format!(
                "{count} postures asked for, but the pool has {pool_candidates} candidates"
            ),
        });
    }
    Ok(())
}

impl Design {
    /// The design of the candidates whose rows of `jac` are `group_rows`, its columns scaled
    /// by their root-mean-square per candidate over the pool (kept ones included).
    fn scaled(jac: &Matrix, group_rows: &[Vec<usize>], n: usize) -> Design {
        let scale: Vec<f64> = (0..n)
            .map(|c| {
                let ss: f64 = jac.col(c).iter().map(|v| v * v).sum();
                let rms = (ss / group_rows.len() as f64).sqrt();
                if rms > 0.0 {
                    1.0 / rms
                } else {
                    1.0
                }
            })
            .collect();
        let mut design = Design {
            n,
            rows: Vec::with_capacity(jac.nrows() * n),
            start: vec![0],
        };
        for rows in group_rows {
            for &i in rows {
                design.rows.extend((0..n).map(|c| jac[(i, c)] * scale[c]));
            }
            design
                .start
                .push(design.start.last().copied().unwrap_or(0) + rows.len());
        }
        design
    }
}

/// Rates sets of candidates: their criteria, and their D-efficiency against the pool.
struct Rater<'a> {
    design: &'a Design,
    /// The pool's average information per candidate.
    average: &'a [f64],
    rcond: f64,
    /// `log det` of the pool's average information; `None` when the pool leaves a parameter
    /// undetermined.
    pool_logdet: Option<f64>,
}

impl<'a> Rater<'a> {
    fn new(design: &'a Design, average: &'a [f64], rcond: f64) -> Self {
        // D-efficiency against the pool (its information from the normal equations: an
        // eigenvalue's relative accuracy, about 1e-16 of the largest, is plenty to tell a pool
        // that determines every parameter).
        let pool_logdet = {
            let e = root_eigenvalues(average, design.n);
            let max = e.iter().copied().fold(0.0, f64::max);
            e.iter()
                .all(|&v| v > 1e-7 * max)
                .then(|| e.iter().map(|v| 2.0 * v.ln()).sum::<f64>())
        };
        Rater {
            design,
            average,
            rcond,
            pool_logdet,
        }
    }

    /// What the criteria of the candidates `set` are computed from.
    fn rate(&self, set: &[usize]) -> Rating {
        let (design, n) = (self.design, self.design.n);
        let rows: usize = set.iter().map(|&c| design.block_rows(c)).sum();
        let s = cut(design.singular_values(set), self.rcond);
        let rank = s.iter().filter(|&&v| v > 0.0).count();
        let mean_variance = (rank == n)
            .then(|| {
                trace_weighted_inverse(
                    &design.information(set.iter().copied(), 0.0),
                    self.average,
                    n,
                )
            })
            .flatten();
        Rating {
            rows,
            rank,
            s,
            mean_variance,
        }
    }

    /// The D-efficiency of a plan of `k` candidates rated `r`, against the pool.
    fn efficiency(&self, r: &Rating, k: usize) -> Option<f64> {
        let n = self.design.n;
        let ld = r.value(Criterion::D)? - n as f64 * (k as f64).ln();
        Some(((ld - self.pool_logdet?) / n as f64).exp())
    }
}

/// The leverage of each posture group of the plan `set` (ridged when the plan leaves a
/// parameter undetermined: `full_rank` false).
fn leverages(design: &Design, set: &[usize], full_rank: bool) -> Vec<f64> {
    let n = design.n;
    let m = design.information(set.iter().copied(), if full_rank { 0.0 } else { RIDGE });
    let mut l = vec![0.0; n * n];
    match cholesky(&m, n, &mut l) {
        Some(_) => {
            let mut scratch = Scratch::default();
            set.iter()
                .map(|&c| gain(&l, n, design.block(c), &mut scratch).1)
                .collect()
        }
        None => vec![0.0; set.len()],
    }
}

/// The postures of the plan `set` (kept ones first, then the pool's in the pool's order), each
/// with its share of its group's leverage; and which postures of `all` the pool gave to it.
fn planned_postures(
    all: &Dataset,
    groups: &[Vec<usize>],
    set: &[usize],
    leverage: &[f64],
    kept_postures: usize,
) -> (Vec<PlannedPosture>, Vec<bool>) {
    let mut postures = Vec::new();
    let mut chosen_postures = vec![false; all.postures.len()];
    for (k, &g) in set.iter().enumerate() {
        for &p in &groups[g] {
            let candidate = (p >= kept_postures).then(|| p - kept_postures);
            if candidate.is_some() {
                chosen_postures[p] = true;
            }
            postures.push(PlannedPosture {
                candidate,
                label: all.postures[p].label.clone(),
                readings: all.postures[p].readings.clone(),
                leverage: leverage[k] / groups[g].len() as f64,
            });
        }
    }
    postures.sort_by_key(|p| p.candidate.map_or((0, 0), |c| (1, c)));
    (postures, chosen_postures)
}

/// Random plans of the plan's size, for comparison: how many the plan's `value` beats, and
/// their median value and D-efficiency.
fn random_plans(
    req: &PlanRequest,
    rater: &Rater<'_>,
    kept: &[usize],
    pool_groups: &[usize],
    value: Option<f64>,
) -> RandomPlans {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(req.seed);
    let mut order = pool_groups.to_vec();
    let sign = if req.criterion.larger_is_better() {
        1.0
    } else {
        -1.0
    };
    let score = |v: Option<f64>| v.map_or(f64::NEG_INFINITY, |v| sign * v);
    let mut draws: Vec<(f64, Option<f64>, Option<f64>)> = (0..RANDOM_PLANS)
        .map(|_| {
            order.shuffle(&mut rng);
            let mut set: Vec<usize> = kept.iter().chain(&order[..req.count]).copied().collect();
            set.sort_unstable();
            let r = rater.rate(&set);
            let v = r.value(req.criterion);
            (score(v), v, rater.efficiency(&r, set.len()))
        })
        .collect();
    let beaten = draws.iter().filter(|d| d.0 <= score(value)).count();
    draws.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut eff: Vec<f64> = draws.iter().filter_map(|d| d.2).collect();
    eff.sort_by(f64::total_cmp);
    RandomPlans {
        draws: draws.len(),
        median_value: draws[draws.len() / 2].1,
        median_efficiency: (eff.len() == draws.len()).then(|| eff[eff.len() / 2]),
        beaten,
    }
}

/// What a design's criteria are computed from.
struct Rating {
    rows: usize,
    rank: usize,
    /// Singular values, zero below the rank cut.
    s: Vec<f64>,
    /// `trace(W M^-1)`, when the design determines every parameter.
    mean_variance: Option<f64>,
}

impl Rating {
    fn value(&self, c: Criterion) -> Option<f64> {
        c.value(&self.s, self.rows, self.mean_variance)
    }
}

/// `trace(W M^-1)` for symmetric positive definite `M`; `None` when it is not.
fn trace_weighted_inverse(m: &[f64], w: &[f64], n: usize) -> Option<f64> {
    let mut l = vec![0.0; n * n];
    cholesky(m, n, &mut l)?;
    let mut x = vec![0.0; n];
    let mut trace = 0.0;
    for j in 0..n {
        // Column j of M^-1, then row j of W times it.
        x.fill(0.0);
        x[j] = 1.0;
        forward(&l, n, &mut x);
        backward(&l, n, &mut x);
        trace += w[j * n..j * n + n]
            .iter()
            .zip(&x)
            .map(|(a, b)| a * b)
            .sum::<f64>();
    }
    Some(trace)
}

/// Solves `L x = b` in place (`l` lower triangular, row-major).
fn forward(l: &[f64], n: usize, x: &mut [f64]) {
    for i in 0..n {
        let mut v = x[i];
        for k in 0..i {
            v -= l[i * n + k] * x[k];
        }
        x[i] = v / l[i * n + i];
    }
}

/// Solves `L^T x = b` in place.
fn backward(l: &[f64], n: usize, x: &mut [f64]) {
    for i in (0..n).rev() {
        let mut v = x[i];
        for k in i + 1..n {
            v -= l[k * n + i] * x[k];
        }
        x[i] = v / l[i * n + i];
    }
}

/// With `l` the Cholesky factor of `M`, how much adding the rows `b` lowers `trace(W M^-1)`:
/// `trace(G^-1 Z^T W Z)` with `Z = M^-1 B^T`, `G = I + B M^-1 B^T` (Sherman-Morrison-Woodbury).
fn trace_reduction(l: &[f64], n: usize, b: &[f64], w: &[f64], s: &mut Scratch) -> f64 {
    let r = b.len() / n;
    s.prepare(l, n, b);
    for zk in s.y.chunks_exact_mut(n) {
        backward(l, n, zk);
    }
    let z = &s.y;
    // H = Z^T W Z (r x r).
    s.wz.resize(n, 0.0);
    s.h.resize(r * r, 0.0);
    for c in 0..r {
        let zc = &z[c * n..c * n + n];
        for (i, v) in s.wz.iter_mut().enumerate() {
            *v = w[i * n..i * n + n].iter().zip(zc).map(|(p, q)| p * q).sum();
        }
        for a in 0..r {
            s.h[a * r + c] = z[a * n..a * n + n]
                .iter()
                .zip(&s.wz)
                .map(|(p, q)| p * q)
                .sum();
        }
    }
    // trace(G^-1 H): solve G X = H column by column.
    if cholesky(&s.g, r, &mut s.lg).is_none() {
        return 0.0;
    }
    s.col.resize(r, 0.0);
    let mut trace = 0.0;
    for c in 0..r {
        for a in 0..r {
            s.col[a] = s.h[a * r + c];
        }
        forward(&s.lg, r, &mut s.col);
        backward(&s.lg, r, &mut s.col);
        trace += s.col[c];
    }
    trace
}

/// Given the Cholesky factor of the plan's information without one chosen candidate, that
/// information, the candidate and which candidates are in the plan: the best replacement that
/// improves the criterion, if any.
type Replacement<'a> = dyn FnMut(&[f64], &[f64], usize, &[bool]) -> Option<usize> + 'a;

/// The greedy start and the exchange.
struct Search<'a> {
    design: &'a Design,
    kept: &'a [usize],
    pool: &'a [usize],
    /// The pool's average information per candidate.
    average: &'a [f64],
}

impl Search<'_> {
    /// Chooses `count` of the pool; returns them and the swaps and passes of the exchange.
    fn run(
        &self,
        count: usize,
        criterion: Criterion,
        say: &mut dyn FnMut(&str),
    ) -> (Vec<usize>, usize, usize) {
        let d = self.design;
        let n = d.n;
        let mut chosen: Vec<usize> = Vec::with_capacity(count);
        let mut in_plan = vec![false; d.candidates()];
        let mut m = d.information(self.kept.iter().copied(), RIDGE);
        let mut l = vec![0.0; n * n];
        let mut scratch = Scratch::default();
        // Greedy: the candidate that raises log det most.
        while chosen.len() < count {
            say(&format!(
                "planning: posture {} of {count} from {} candidates",
                chosen.len() + 1,
                self.pool.len()
            ));
            cholesky(&m, n, &mut l).expect("the ridge keeps the information positive definite");
            let mut best: Option<(usize, f64)> = None;
            for &c in self.pool {
                if in_plan[c] {
                    continue;
                }
                let (gc, _) = gain(&l, n, d.block(c), &mut scratch);
                if best.is_none_or(|(_, b)| gc > b) {
                    best = Some((c, gc));
                }
            }
            let (c, _) = best.expect("count is at most the pool's size");
            in_plan[c] = true;
            chosen.push(c);
            d.add(&mut m, c, 1.0);
        }
        // Exchange, D first (the start of every other criterion).
        say("planning: exchanging postures");
        let (mut swaps, mut passes) = self.exchange_d(&mut chosen, &mut in_plan, &mut m);
        let identity: Vec<f64> = (0..n * n)
            .map(|k| if k % (n + 1) == 0 { 1.0 } else { 0.0 })
            .collect();
        let (s2, p2) = match criterion {
            Criterion::D => (0, 0),
            Criterion::A => self.exchange_trace(&mut chosen, &mut in_plan, &mut m, &identity),
            Criterion::I => self.exchange_trace(&mut chosen, &mut in_plan, &mut m, self.average),
            _ => self.exchange_eigen(&mut chosen, &mut in_plan, &mut m, criterion),
        };
        swaps += s2;
        passes += p2;
        (chosen, swaps, passes)
    }

    /// Fedorov's exchange: for each chosen candidate in turn, `better` is given the plan
    /// without it (its information and that information's Cholesky factor) and the candidate,
    /// and names the best replacement that improves the criterion, if any; repeated until a
    /// pass makes no swap (or [`MAX_PASSES`]). Returns the swaps and the passes.
    fn exchange(
        &self,
        chosen: &mut [usize],
        in_plan: &mut [bool],
        m: &mut [f64],
        better: &mut Replacement<'_>,
    ) -> (usize, usize) {
        let d = self.design;
        let n = d.n;
        let mut l = vec![0.0; n * n];
        let mut without = vec![0.0; n * n];
        let (mut swaps, mut passes) = (0, 0);
        loop {
            passes += 1;
            let mut improved = false;
            for slot in chosen.iter_mut() {
                let out = *slot;
                without.copy_from_slice(m);
                d.add(&mut without, out, -1.0);
                if cholesky(&without, n, &mut l).is_none() {
                    continue;
                }
                if let Some(c) = better(&l, &without, out, in_plan) {
                    in_plan[out] = false;
                    in_plan[c] = true;
                    *slot = c;
                    m.copy_from_slice(&without);
                    d.add(m, c, 1.0);
                    swaps += 1;
                    improved = true;
                }
            }
            if !improved || passes >= MAX_PASSES {
                return (swaps, passes);
            }
        }
    }

    /// The exchange on `log det`: every replacement of every chosen candidate, by rank-r
    /// updates.
    fn exchange_d(
        &self,
        chosen: &mut [usize],
        in_plan: &mut [bool],
        m: &mut [f64],
    ) -> (usize, usize) {
        let d = self.design;
        let n = d.n;
        let mut scratch = Scratch::default();
        let mut better = |l: &[f64], _: &[f64], out: usize, in_plan: &[bool]| {
            let (back, _) = gain(l, n, d.block(out), &mut scratch);
            let mut best: Option<(usize, f64)> = None;
            for &c in self.pool {
                if in_plan[c] {
                    continue;
                }
                let (gc, _) = gain(l, n, d.block(c), &mut scratch);
                if gc > back + 1e-9 && best.is_none_or(|(_, b)| gc > b) {
                    best = Some((c, gc));
                }
            }
            best.map(|(c, _)| c)
        };
        self.exchange(chosen, in_plan, m, &mut better)
    }

    /// The exchange on `trace(W M^-1)` (A with `W = I`, I with the pool's average information):
    /// every replacement of every chosen candidate, by rank-r updates.
    fn exchange_trace(
        &self,
        chosen: &mut [usize],
        in_plan: &mut [bool],
        m: &mut [f64],
        w: &[f64],
    ) -> (usize, usize) {
        let d = self.design;
        let n = d.n;
        let mut scratch = Scratch::default();
        let mut better = |l: &[f64], _: &[f64], out: usize, in_plan: &[bool]| {
            let back = trace_reduction(l, n, d.block(out), w, &mut scratch);
            let mut best: Option<(usize, f64)> = None;
            for &c in self.pool {
                if in_plan[c] {
                    continue;
                }
                let rc = trace_reduction(l, n, d.block(c), w, &mut scratch);
                if rc > back * (1.0 + 1e-9) && best.is_none_or(|(_, b)| rc > b) {
                    best = Some((c, rc));
                }
            }
            best.map(|(c, _)| c)
        };
        self.exchange(chosen, in_plan, m, &mut better)
    }

    /// The exchange on a criterion of the eigenvalues, trying for each chosen candidate the
    /// [`EXCHANGE_SHORTLIST`] candidates that add most `log det` in its place.
    fn exchange_eigen(
        &self,
        chosen: &mut [usize],
        in_plan: &mut [bool],
        m: &mut [f64],
        criterion: Criterion,
    ) -> (usize, usize) {
        let d = self.design;
        let n = d.n;
        let mut rows: usize = self
            .kept
            .iter()
            .chain(chosen.iter())
            .map(|&c| d.block_rows(c))
            .sum();
        let mut current = criterion.score(&root_eigenvalues(m, n), rows);
        let mut trial = vec![0.0; n * n];
        let mut scratch = Scratch::default();
        let mut better = |l: &[f64], without: &[f64], out: usize, in_plan: &[bool]| {
            let mut shortlist: Vec<(usize, f64)> = self
                .pool
                .iter()
                .filter(|&&c| !in_plan[c])
                .map(|&c| (c, gain(l, n, d.block(c), &mut scratch).0))
                .collect();
            shortlist.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
            shortlist.truncate(EXCHANGE_SHORTLIST);
            let mut best: Option<(usize, f64)> = None;
            for &(c, _) in &shortlist {
                trial.copy_from_slice(without);
                d.add(&mut trial, c, 1.0);
                let r = rows - d.block_rows(out) + d.block_rows(c);
                let sc = criterion.score(&root_eigenvalues(&trial, n), r);
                let margin = 1e-9 * current.abs().max(1e-300);
                if sc > current + margin && best.is_none_or(|(_, b)| sc > b) {
                    best = Some((c, sc));
                }
            }
            let (c, sc) = best?;
            rows = rows - d.block_rows(out) + d.block_rows(c);
            current = sc;
            Some(c)
        };
        self.exchange(chosen, in_plan, m, &mut better)
    }
}
