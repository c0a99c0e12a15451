//! The least-squares problem: the weighted residuals of a dataset's observations and their
//! Jacobian with respect to the estimated parameters.
//!
//! Row `i` of the problem is observation row `i` divided by its standard deviation: the row's
//! own (`sigma_position`, `sigma_angle` columns) when given, else the default [`Weights`] of its
//! quantity; times the robust-loss weight of the row when one is set. The objective is the sum
//! of the squared weighted residuals: dimensionless, and independent of the files' units.
//!
//! **Priors.** A problem with a Gaussian prior ([`Problem::with_prior`], a [`Prior`]) has one
//! more row per estimated parameter `p` with a prior standard deviation `s_p`, after the data's
//! rows: `(p - p0) / s_p`, `p0` its value in the problem's base robot (the solver's start; an
//! angle's difference wrapped to +-180 deg), whose Jacobian is `1 / s_p` in the parameter's
//! column and 0 elsewhere. They are rows like any other: every solver, the linearisation
//! (`R` of the QR, Gram matrix), the identifiability analysis and the covariance see them, so
//! the objective is the data's plus the prior's, the information `J^T W J + diag(1 / s_p^2)`,
//! and a parameter the data cannot separate from others is held by its prior instead of
//! drifting. The robust loss leaves the prior rows at weight 1.

use crate::linalg::{Matrix, QrAccumulator, RowSink};
use crate::model::kinematics::{Chain, ColumnPlan, Frame, ReadingTrig, Target};
use crate::model::params::{LinkComponent, ParamId, ParamKind};
use crate::model::robot::{Prior, Robot};
use crate::observe::{
    Accuracy, AccuracyTally, Context, Dataset, Derivatives, FrameCache, KeptErrors, Observation,
    OrientationError, Weights,
};
use crate::units::{wrap_angle, Quantity};
use nalgebra::Vector3;

/// A function shown each observation with its frames.
type ObservationVisitor<'a> = dyn FnMut(&Observation, &[Frame]) + 'a;

/// Where an evaluation's derivatives go: a full rows x cols matrix, or, a row at a time (with
/// the residual as the last column), into a [`RowSink`] (the `R` of a QR, a Gram matrix).
enum Sink<'m> {
    Full(&'m mut Matrix),
    Rows(&'m mut dyn RowSink),
}

/// The linearisation of a problem at one robot, from one pass of forward kinematics: the
/// upper-triangular `R` of the QR of the weighted `[J | r]` over `params` (ascending, the
/// residual last; `(n + 1) x (n + 1)`), and the errors there. The `R` of any subset of the
/// parameters follows from it without another pass ([`Linearized::restricted`]).
#[derive(Debug, Clone)]
pub(crate) struct Linearized {
    /// The parameters of the columns of `r` (the residual column aside).
    pub params: Vec<ParamId>,
    /// `R` of the weighted `[J | r]`.
    pub r: Matrix,
    /// Per parameter of `params`, what one typical row tells about it: `e_j`, the RMS over
    /// the `m` rows of its weighted Jacobian column, each row's weight clamped at the median
    /// weight of the rows of its quantity (see
    /// [`crate::identifiability::Analysis::typical_row`]). It needs the rows themselves, which
    /// `r` no longer has, so it travels with it (read by an analysis that reuses this
    /// linearisation; none outside the tests does yet).
    #[cfg_attr(not(test), allow(dead_code))]
    pub typical_row: Vec<f64>,
    /// The errors at the robot.
    pub accuracy: Accuracy,
    /// Each observation's error at the robot, from the same pass (a fit starting there
    /// reports them without another pass).
    pub errors: KeptErrors,
}

impl Linearized {
    /// The `R` of the weighted `[J_S | r]` for the parameters `subset` (in that order), each
    /// among `params`: `J_S = Q R_S` with `R_S` the columns of `R` for `S`, so the QR of
    /// `[R_S | z]` (a few rows) gives it. `None` when a parameter is not among `params`.
    pub(crate) fn restricted(&self, subset: &[ParamId]) -> Option<Matrix> {
        let n = self.params.len();
        let mut cols: Vec<usize> = subset
            .iter()
            .map(|id| self.params.iter().position(|p| p == id))
            .collect::<Option<_>>()?;
        cols.push(n);
        Some(crate::linalg::r_of_columns(&self.r, &cols))
    }
}

/// Weighted residuals and Jacobian of a calibration over one dataset.
#[derive(Clone)]
pub struct Problem<'a> {
    base: &'a Robot,
    data: &'a Dataset,
    estimated: &'a [ParamId],
    orientation: OrientationError,
    /// Shared by the problem's clones (a column order, a prior, a row scale): 8 bytes a row
    /// each, not copied.
    sigma: std::sync::Arc<[f64]>,
    /// 1 / sigma, per row (residuals are multiplied by it).
    weight: std::sync::Arc<[f64]>,
    row_scale: Option<&'a [f64]>,
    /// Per parameter number: its column among the estimated, if estimated (the Jacobian
    /// columns to compute; observations that read parameters themselves, as contacts read
    /// their plane's, put those columns by it too).
    columns: Vec<Option<usize>>,
    /// The Jacobian columns of the end effector (first) and of each site, by `columns`.
    plans: Vec<ColumnPlan>,
    /// The joint angles' reading parts, when slopes and couplings stay fixed
    /// ([`Problem::with_reading_trig`]).
    trig: Option<std::sync::Arc<ReadingTrig>>,
    /// Per posture, the robot session whose measurement frame its poses and positions are in
    /// (empty when the robot has no sessions).
    posture_session: Vec<Option<usize>>,
    /// Per robot session, the estimated column of each of its six parameters.
    session_cols: Vec<[Option<usize>; 6]>,
    /// The prior's rows, after the data's: per row, the estimated column it holds, the
    /// parameter's value in `base` (the prior's centre), `1 / s_p`, and whether it is an angle
    /// (its difference wrapped).
    prior: Vec<PriorRow>,
}

/// One row of a prior: `(sum of the columns' parameters - center) * weight` (one column for a
/// parameter's prior, the masses for the total mass).
#[derive(Debug, Clone, PartialEq)]
struct PriorRow {
    columns: Vec<usize>,
    center: f64,
    weight: f64,
    angle: bool,
}

impl<'a> Problem<'a> {
    /// A problem estimating `estimated`, all other parameters held at `base`'s values; rows
    /// without a standard deviation of their own are weighted by `weights`.
    pub fn new(
        base: &'a Robot,
        data: &'a Dataset,
        estimated: &'a [ParamId],
        weights: Weights,
        orientation: OrientationError,
    ) -> Self {
        let mut sigma: Vec<f64> = Vec::with_capacity(data.rows());
        for o in &data.observations {
            o.push_sigmas(weights, &mut sigma);
        }
        let weight = sigma.iter().map(|s| 1.0 / s).collect();
        let sigma = sigma.into();
        let posture_session = if base.sessions.is_empty() {
            Vec::new()
        } else {
            data.postures
                .iter()
                .map(|p| p.session.as_deref().and_then(|s| base.session_index(s)))
                .collect()
        };
        let mut problem = Problem {
            base,
            data,
            estimated,
            orientation,
            sigma,
            weight,
            row_scale: None,
            columns: Vec::new(),
            plans: Vec::new(),
            trig: None,
            posture_session,
            session_cols: Vec::new(),
            prior: Vec::new(),
        };
        problem.place_columns();
        problem
    }

    /// The same problem with its columns in the order of `estimated`, the same parameters
    /// (each column's entries, to the bit, are where its parameter now stands). Without a prior
    /// (its rows name columns).
    pub(crate) fn with_column_order(&self, estimated: &'a [ParamId]) -> Problem<'a> {
        debug_assert!(self.prior.is_empty());
        debug_assert!({
            let (mut a, mut b) = (self.estimated.to_vec(), estimated.to_vec());
            a.sort();
            b.sort();
            a == b
        });
        let mut problem = self.clone();
        problem.estimated = estimated;
        problem.place_columns();
        problem
    }

    /// Each estimated parameter's column, the targets' column plans and the sessions'
    /// columns, from `estimated`.
    fn place_columns(&mut self) {
        let base = self.base;
        let mut columns = vec![None; base.param_count()];
        for (c, id) in self.estimated.iter().enumerate() {
            if let Some(slot) = columns.get_mut(id.0) {
                *slot = Some(c);
            }
        }
        self.plans = std::iter::once(Target::EndEffector)
            .chain((0..base.sites.len()).map(Target::Site))
            .map(|t| ColumnPlan::new(base, t, &columns))
            .collect();
        self.session_cols = (0..base.sessions.len())
            .map(|session| {
                LinkComponent::ALL.map(|component| {
                    columns[base.param_id(ParamKind::Session { session, component }).0]
                })
            })
            .collect();
        self.columns = columns;
    }

    /// The same problem with a row `(p - p0) / s_p` after the data's for each estimated
    /// parameter `p` the prior gives a standard deviation `s_p` (see the module documentation),
    /// `p0` its value in the base robot. An empty prior adds none.
    ///
    /// With a total mass `M`, one more row: `(sum of the bodies' masses - M) / (f M)`, `f`
    /// [`Prior::TOTAL_MASS_FRACTION`], over the estimated masses (the others held), when some
    /// mass is estimated.
    pub fn with_prior(mut self, prior: &Prior) -> Self {
        self.prior = self
            .estimated
            .iter()
            .enumerate()
            .filter_map(|(column, &id)| {
                let s = prior.sigma(self.base, id)?;
                Some(PriorRow {
                    columns: vec![column],
                    center: self.base.get(id),
                    weight: 1.0 / s,
                    angle: self.base.param_quantity(id) == Quantity::Angle,
                })
            })
            .collect();
        if let Some(total) = prior.total_mass {
            let mass = |id: ParamId| {
                matches!(
                    self.base.try_param_kind(id),
                    Some(ParamKind::Body {
                        component: crate::model::params::BodyComponent::Mass,
                        ..
                    })
                )
            };
            let columns: Vec<usize> = (0..self.estimated.len())
                .filter(|&c| mass(self.estimated[c]))
                .collect();
            if !columns.is_empty() {
                let held: f64 = (0..self.base.body_count())
                    .map(|body| {
                        self.base.param_id(ParamKind::Body {
                            body,
                            component: crate::model::params::BodyComponent::Mass,
                        })
                    })
                    .filter(|id| !self.estimated.contains(id))
                    .map(|id| self.base.get(id))
                    .sum();
                self.prior.push(PriorRow {
                    columns,
                    center: total - held,
                    weight: 1.0 / (Prior::TOTAL_MASS_FRACTION * total),
                    angle: false,
                });
            }
        }
        self
    }

    /// The same problem, computing the sines and cosines of the reading parts of the joint
    /// angles once for all evaluations (worth it for a solver's many passes), unless slopes or
    /// couplings are estimated. Evaluations at a robot with other slopes or couplings do
    /// without the table.
    pub(crate) fn with_reading_trig(self) -> Self {
        let moves_readings = self.estimated.iter().any(|&id| {
            matches!(
                self.base.try_param_kind(id),
                Some(ParamKind::Slope { .. } | ParamKind::Coupling { .. })
            )
        });
        if moves_readings {
            self
        } else {
            // The dataset's own table: the data check made it, the report reuses it.
            self.with_start_reading_trig()
        }
    }

    /// The same problem with the dataset's table of the readings' sines and cosines at its
    /// robot, whatever is estimated: for a pass at that robot alone (an identifiability
    /// analysis), which the table serves in full (the data check made it, so it costs a lookup).
    pub(crate) fn with_start_reading_trig(mut self) -> Self {
        self.trig = Some(self.data.reading_trig(self.base));
        self
    }

    /// Multiplies residual row `i` (and its Jacobian row) by `scale[i]`: the square roots of
    /// robust-loss weights.
    pub(crate) fn with_row_scale(mut self, scale: &'a [f64]) -> Self {
        self.row_scale = Some(scale);
        self
    }

    /// Number of residuals: the data's, then the prior's.
    pub fn rows(&self) -> usize {
        self.sigma.len() + self.prior.len()
    }

    /// Number of residuals of the data (the first [`Problem::rows`]; the prior's follow).
    pub(crate) fn data_rows(&self) -> usize {
        self.sigma.len()
    }

    /// Number of residuals of the prior: one per estimated parameter with a prior.
    pub fn prior_rows(&self) -> usize {
        self.prior.len()
    }

    /// The `R` of the weighted `[J | r]` of this problem with its prior's rows, from `r_data`,
    /// the `R` (`(cols + 1)` square) of the data's rows alone at the base robot: the prior's
    /// rows (residual 0 there, where a parameter's is centred; the total mass's distance)
    /// folded in by a QR of a few rows.
    /// `r_data` itself when there is no prior.
    pub(crate) fn with_prior_rows(&self, r_data: &Matrix) -> Matrix {
        let k = self.cols();
        if self.prior.is_empty() || r_data.nrows() != k + 1 || r_data.ncols() != k + 1 {
            return r_data.clone();
        }
        let mut acc = QrAccumulator::new(k + 1, k + 1 + self.prior.len());
        let mut row = vec![0.0; k + 1];
        for i in 0..=k {
            for (j, v) in row.iter_mut().enumerate() {
                *v = r_data[(i, j)];
            }
            acc.push(&row);
        }
        // The rows' residuals at the base robot: 0 for a parameter's (centred there), the
        // distance from the total for the masses'.
        for p in &self.prior {
            row.fill(0.0);
            for &c in &p.columns {
                row[c] = p.weight;
            }
            let at: f64 = p
                .columns
                .iter()
                .map(|&c| self.base.get(self.estimated[c]))
                .sum();
            row[k] = p.weight * (at - p.center);
            acc.push(&row);
        }
        let mut out = Matrix::zeros(0, 0);
        acc.r_into(&mut out);
        out
    }

    /// The estimated parameters with a prior (in [`Problem::estimated`]'s order) and the
    /// standard deviation of each (internal units).
    pub fn prior_sigmas(&self) -> Vec<(ParamId, f64)> {
        self.prior
            .iter()
            .filter_map(|p| match p.columns.as_slice() {
                [c] => Some((self.estimated[*c], 1.0 / p.weight)),
                _ => None,
            })
            .collect()
    }

    /// Number of estimated parameters.
    pub fn cols(&self) -> usize {
        self.estimated.len()
    }

    /// The estimated parameters.
    pub fn estimated(&self) -> &[ParamId] {
        self.estimated
    }

    /// The dataset.
    pub fn data(&self) -> &'a Dataset {
        self.data
    }

    /// The standard deviation of each row of the data (internal units).
    pub fn row_sigma(&self) -> &[f64] {
        &self.sigma
    }

    /// How orientation residuals are formed.
    pub fn orientation(&self) -> OrientationError {
        self.orientation
    }

    /// The estimated parameters' values in `robot` (internal units).
    pub fn values(&self, robot: &Robot) -> Vec<f64> {
        self.estimated.iter().map(|&id| robot.get(id)).collect()
    }

    /// The base robot with the estimated parameters set to `x`.
    pub fn robot_at(&self, x: &[f64]) -> Robot {
        let mut r = self.base.clone();
        for (&id, &v) in self.estimated.iter().zip(x) {
            r.set(id, v);
        }
        r
    }

    /// Fills `res` (length [`Problem::rows`]) with the weighted residuals `(model - measured) /
    /// sigma` of `robot`, and, if given, `jac` (resized to rows x cols) with their derivatives
    /// with respect to the estimated parameters. Returns the objective, the sum of squared
    /// residuals.
    pub fn evaluate(&self, robot: &Robot, res: &mut [f64], jac: Option<&mut Matrix>) -> f64 {
        self.evaluate_with(robot, res, jac.map(Sink::Full), None)
    }

    /// [`Problem::evaluate`] that never holds the Jacobian: each row `[J_i | r_i]` (the
    /// weighted derivatives, then the weighted residual) is pushed into `acc` (cleared first;
    /// `cols + 1` columns), which keeps only the `R` of their QR. Memory is flat in the number
    /// of rows.
    pub(crate) fn evaluate_qr(
        &self,
        robot: &Robot,
        res: &mut [f64],
        acc: &mut QrAccumulator,
    ) -> f64 {
        assert_eq!(acc.cols(), self.cols() + 1);
        acc.clear();
        self.evaluate_with(robot, res, Some(Sink::Rows(acc)), None)
    }

    /// [`Problem::evaluate`], each row `[J_i | r_i]` (weighted) pushed into `rows`, which is not
    /// cleared first.
    pub(crate) fn evaluate_rows(
        &self,
        robot: &Robot,
        res: &mut [f64],
        rows: &mut dyn RowSink,
    ) -> f64 {
        self.evaluate_with(robot, res, Some(Sink::Rows(rows)), None)
    }

    /// [`Problem::evaluate_rows`] (each weighted row `[J_i | r_i]` pushed into `rows`, which is
    /// not cleared first), with the errors of every observation summarised (the
    /// [`crate::observe::accuracy`] of `robot`) and kept, from the same pass of forward
    /// kinematics.
    pub(crate) fn evaluate_rows_kept(
        &self,
        robot: &Robot,
        res: &mut [f64],
        rows: &mut dyn RowSink,
    ) -> (f64, Accuracy, KeptErrors) {
        self.evaluate_tallied(robot, res, Some(Sink::Rows(rows)))
    }

    /// [`Problem::evaluate`] without derivatives, and with the errors of every observation
    /// summarised (the [`crate::observe::accuracy`] of `robot`) and kept, from the same pass of
    /// forward kinematics.
    pub(crate) fn evaluate_checked(
        &self,
        robot: &Robot,
        res: &mut [f64],
    ) -> (f64, Accuracy, KeptErrors) {
        self.evaluate_tallied(robot, res, None)
    }

    /// [`Problem::evaluate_with`] into `jac`, with the errors of every observation summarised
    /// (the [`crate::observe::accuracy`] of `robot`, under the default orientation error) from
    /// the same pass of forward kinematics.
    fn evaluate_tallied(
        &self,
        robot: &Robot,
        res: &mut [f64],
        jac: Option<Sink<'_>>,
    ) -> (f64, Accuracy, KeptErrors) {
        let ctx = Context {
            robot,
            orientation: OrientationError::default(),
        };
        let mut tally = AccuracyTally::for_observations(self.data.observations.len());
        let f = self.evaluate_with(
            robot,
            res,
            jac,
            Some(&mut |o: &Observation, frames: &[Frame]| tally.push(o.error(&ctx, frames))),
        );
        let (accuracy, samples) = tally.finish_keeping();
        (f, accuracy, KeptErrors::new(robot, samples))
    }

    fn evaluate_with(
        &self,
        robot: &Robot,
        res: &mut [f64],
        mut jac: Option<Sink<'_>>,
        mut each: Option<&mut ObservationVisitor<'_>>,
    ) -> f64 {
        assert_eq!(res.len(), self.rows());
        let chain = Chain::new(robot);
        let mut cache = FrameCache::new(robot);
        let trig = self.trig.as_deref().filter(|t| t.fits(robot));
        let ctx = Context {
            robot,
            orientation: self.orientation,
        };
        let k = self.cols();
        let mut blocks = [vec![0.0; 6 * k], vec![0.0; 6 * k]];
        let mut out = Vec::new();
        let mut qr_row = vec![0.0; k + 1];
        if let Some(Sink::Full(j)) = jac.as_mut() {
            j.resize(self.rows(), k);
        }
        let mut frames = [Frame::identity(); 2];
        let sessions = SessionFrames::new(robot);
        let mut row = 0;
        for o in &self.data.observations {
            let views = o.views();
            let nrows = o.rows().len();
            // Measured in a session's frame: the target's frame is seen through it.
            let absolute = !self.posture_session.is_empty()
                && matches!(o.anchoring(), crate::observe::Anchoring::Absolute);
            for (vi, v) in views.iter().enumerate() {
                let ws = cache.posture_with(&chain, self.data, v.posture, trig);
                frames[vi] = chain.target_frame(ws, v.target);
                if jac.is_some() {
                    let plan = match v.target {
                        Target::EndEffector => &self.plans[0],
                        Target::Site(s) => &self.plans[1 + s],
                    };
                    chain.jacobian_columns(ws, plan, &mut blocks[vi]);
                }
                let session = if absolute {
                    self.posture_session[v.posture]
                } else {
                    None
                };
                if let Some(s) = session {
                    let t = &sessions.frames[s];
                    if jac.is_some() {
                        for c in blocks[vi][..6 * k].chunks_exact_mut(6) {
                            let dp = t.rotation * Vector3::new(c[0], c[1], c[2]);
                            let w = t.rotation * Vector3::new(c[3], c[4], c[5]);
                            c[..3].copy_from_slice(dp.as_slice());
                            c[3..].copy_from_slice(w.as_slice());
                        }
                    }
                    frames[vi] = t.then(&frames[vi]);
                }
                if jac.is_some() {
                    // The session frames' columns: the view's own session's, else zero.
                    for (si, cols) in self.session_cols.iter().enumerate() {
                        for (comp, col) in cols.iter().enumerate() {
                            let Some(c) = *col else { continue };
                            let out = &mut blocks[vi][6 * c..6 * c + 6];
                            out.fill(0.0);
                            if session == Some(si) {
                                let (dp, w) =
                                    sessions.derivative(si, comp, &frames[vi].translation);
                                out[..3].copy_from_slice(dp.as_slice());
                                out[3..].copy_from_slice(w.as_slice());
                            }
                        }
                    }
                }
            }
            let r = &mut res[row..row + nrows];
            match jac.as_mut() {
                Some(sink) => {
                    // Each row's derivatives with a slot for its residual after them: the
                    // row `[J_i | r_i]` is then weighted in place and pushed as it stands.
                    let stride = k + 1;
                    out.clear();
                    out.resize(nrows * stride, 0.0);
                    let refs = [blocks[0].as_slice(), blocks[1].as_slice()];
                    let mut d = Derivatives {
                        cols: k,
                        stride,
                        blocks: &refs[..views.len()],
                        columns: &self.columns,
                        out: &mut out,
                    };
                    o.evaluate(&ctx, &frames[..views.len()], r, Some(&mut d));
                    for (i, jr) in out.chunks_exact_mut(stride).enumerate() {
                        let (w, s) = (self.weight[row + i], self.row_scale.map(|s| s[row + i]));
                        jr[k] = r[i];
                        for v in jr.iter_mut() {
                            *v = s.map_or(*v * w, |s| *v * w * s);
                        }
                        match sink {
                            Sink::Full(j) => {
                                for (c, &v) in jr[..k].iter().enumerate() {
                                    j[(row + i, c)] = v;
                                }
                            }
                            Sink::Rows(acc) => acc.push(jr),
                        }
                    }
                }
                None => o.evaluate(&ctx, &frames[..views.len()], r, None),
            }
            if let Some(f) = each.as_deref_mut() {
                f(o, &frames[..views.len()]);
            }
            for i in 0..nrows {
                r[i] *= self.weight[row + i];
                if let Some(s) = self.row_scale {
                    r[i] *= s[row + i];
                }
            }
            row += nrows;
        }
        for p in &self.prior {
            let v = p
                .columns
                .iter()
                .map(|&c| robot.get(self.estimated[c]))
                .sum::<f64>()
                - p.center;
            let r = p.weight * if p.angle { wrap_angle(v) } else { v };
            res[row] = r;
            match jac.as_mut() {
                Some(Sink::Full(j)) => {
                    for c in 0..k {
                        j[(row, c)] = 0.0;
                    }
                    for &c in &p.columns {
                        j[(row, c)] = p.weight;
                    }
                }
                Some(Sink::Rows(acc)) => {
                    qr_row.fill(0.0);
                    for &c in &p.columns {
                        qr_row[c] = p.weight;
                    }
                    qr_row[k] = r;
                    acc.push(&qr_row);
                }
                None => {}
            }
            row += 1;
        }
        res.iter().map(|r| r * r).sum()
    }
}

/// The robot's session frames at one evaluation, and the axes of their Euler angles.
struct SessionFrames {
    frames: Vec<Frame>,
    /// Per session, the rotation axes (session frame) of alpha, beta, gamma: `R = Rz(alpha)
    /// Ry(beta) Rx(gamma)`, so `dR/dalpha = [z]x R`, `dR/dbeta = [Rz(alpha) y]x R`, `dR/dgamma
    /// = [Rz(alpha) Ry(beta) x]x R`.
    axes: Vec<[Vector3<f64>; 3]>,
}

impl SessionFrames {
    fn new(robot: &Robot) -> Self {
        let frames = robot
            .sessions
            .iter()
            .map(|s| Frame::from_link(&s.frame))
            .collect();
        let axes = robot
            .sessions
            .iter()
            .map(|s| {
                let l = &s.frame;
                let rz = crate::model::kinematics::rot_zyx(l.alpha, 0.0, 0.0);
                let rzy = crate::model::kinematics::rot_zyx(l.alpha, l.beta, 0.0);
                [Vector3::z(), rz * Vector3::y(), rzy * Vector3::x()]
            })
            .collect();
        SessionFrames { frames, axes }
    }

    /// The derivative of a point `p` (session frame) and of its frame's attitude with respect
    /// to component `comp` (x, y, z, alpha, beta, gamma) of session `s`'s frame.
    fn derivative(&self, s: usize, comp: usize, p: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
        if comp < 3 {
            let mut dp = Vector3::zeros();
            dp[comp] = 1.0;
            (dp, Vector3::zeros())
        } else {
            let w = self.axes[s][comp - 3];
            (w.cross(&(p - self.frames[s].translation)), w)
        }
    }
}
