//! The run of a calibration: a [`Request`] (robot, data, what to estimate, how, what to check
//! it on) in, an [`Outcome`] out, with the [`Progress`] of its phases.

use std::sync::Arc;

use crate::error::{Error, Result};
use crate::identifiability::AnalysisOptions;
use crate::model::params::{ParamId, ParamKind};
use crate::model::robot::Robot;
use crate::observe::Dataset;
use crate::solve::estimation::{
    self, Calibration, CalibrationOptions, Iteration, Loss, SolverOptions,
};
use crate::solve::problem::{Linearized, Problem};
use crate::uncertainty;
use crate::units::{wrap_angle, Quantity};
use crate::warning::Warning;

use super::cross_validation::{cross_validate, cross_validation_report, CrossValidation, FoldFit};
use super::min_change::{project_min_change, SolutionRule};
use super::outcome::{data_warnings, finish, Outcome, Pruning, SIGMAS_TOO_SMALL};
pub use super::progress::{Phase, Progress};
use super::request::{Request, Validation};
use super::selection::{
    check_total_mass_kept, default_parameters, resolve_linearized, session_frames_for, Selection,
};

/// Passes progress on, and clocks each phase (wall time).
struct Clock<'a> {
    inner: &'a mut dyn Progress,
    current: (Phase, std::time::Instant),
    times: Vec<(Phase, f64)>,
}

impl Clock<'_> {
    fn lap(&mut self, next: Phase) {
        let (phase, since) =
            std::mem::replace(&mut self.current, (next, std::time::Instant::now()));
        let t = since.elapsed().as_secs_f64();
        match self.times.iter_mut().find(|(p, _)| *p == phase) {
            Some(e) => e.1 += t,
            None => self.times.push((phase, t)),
        }
    }
}

impl Progress for Clock<'_> {
    fn phase(&mut self, phase: Phase) {
        self.lap(phase);
        self.inner.phase(phase);
    }
    fn iteration(&mut self, it: &Iteration) {
        self.inner.iteration(it);
    }
    fn data_checked(&mut self, warnings: &[Warning]) -> bool {
        self.inner.data_checked(warnings)
    }
    fn say(&mut self, what: &str) {
        self.inner.say(what);
    }
}

/// Runs a calibration.
///
/// The report's `timings` give the wall time of each [`Phase`] that ran.
pub fn run(req: &Request, progress: &mut dyn Progress) -> Result<Outcome> {
    let mut clock = Clock {
        inner: progress,
        current: (Phase::Preparation, std::time::Instant::now()),
        times: Vec::new(),
    };
    let mut outcome = run_clocked(req, &mut clock)?;
    clock.lap(Phase::Report);
    outcome.report.timings = clock
        .times
        .iter()
        .map(|&(p, seconds)| crate::report::PhaseTime {
            phase: p.as_str().to_string(),
            seconds,
        })
        .collect();
    Ok(outcome)
}

/// A calibration, step by step: the settings checked, the data split, the start placed, the
/// parameters chosen and fitted (chosen again at the residuals' noise, pruned), then the
/// uncertainty, the report, cross-validation and the predicted accuracy.
fn run_clocked(req: &Request, progress: &mut dyn Progress) -> Result<Outcome> {
    check_settings(req)?;
    let (data, validation_data) = split_validation(req)?;
    // Sessions of the data with a measurement frame of their own: added to the model (the first
    // session, or the postures without one, are in the global frame).
    let with_frames;
    let req = match session_frames_for(&req.robot, &data) {
        Some(robot) => {
            with_frames = Request {
                robot,
                ..req.clone()
            };
            &with_frames
        }
        None => req,
    };
    check_equilibria(req, &data)?;
    let start = starting_robot(req)?;
    // Where the nominal robot puts the observed points: one pass, for the checks of the data
    // against it (scale) and, when the start is the nominal robot, of the start's distance.
    let nominal_points = crate::observe::sanity::predicted(&req.robot, &data);
    // The data against the nominal robot, before any solving: a unit mix-up is named now, not
    // after a solve that could not have made sense of it.
    let data_warns = data_warnings(&req.robot, &data, &nominal_points);
    if !progress.data_checked(&data_warns) {
        return Err(Error::Stopped {
            after: "the checks of the data against the nominal robot",
        });
    }
    let unplaced = start.clone();
    let (start, registration) = place_frames(req, start, &data, &nominal_points);
    let placed = placed_frames(&unplaced, &start);
    let reference = match req.solution {
        SolutionRule::MinChange => &req.robot,
        SolutionRule::Solver => &start,
    };
    if matches!(req.selection, Selection::Identifiable { .. }) {
        progress.phase(Phase::Selection);
    }
    let analysis_options = AnalysisOptions {
        placed,
        ..req.analysis_options()
    };
    let super::selection::Resolved {
        estimate,
        unseen,
        lin,
        placed_loose,
    } = resolve_linearized(&req.selection, reference, &data, &analysis_options)?;
    check_total_mass_kept(
        req.prior.total_mass,
        &req.selection,
        &estimate,
        reference,
        "the identifiability analysis",
    )?;
    // The analysis linearised the problem at the reference: the solver's start when they are
    // the same robot (and the loss starts as least squares, which it always does).
    let lin = lin.filter(|_| *reference == start);
    let opts = CalibrationOptions {
        estimate,
        solver: req.solver,
        weights: req.weights,
        orientation: req.orientation,
        loss: req.loss,
        prior: req.prior.clone(),
        model_error: req.model_error,
    };
    progress.phase(Phase::Estimation);
    let fitted = Fitted {
        req,
        start: &start,
        data: &data,
        reference,
        analysis_options: &analysis_options,
    };
    let cal = fitted.fit(&opts, lin.as_ref(), progress)?;
    let (cal, rechosen, placed_loose) =
        fitted.rechoose_at_residual_noise(cal, placed_loose, progress)?;
    // A fit that ended with the positions unfit: tried again from other starts (nothing runs
    // otherwise).
    let chosen = cal.options.clone();
    let (cal, restarted) = super::restart::restart_if_unfit(
        &req.robot,
        &start,
        &data,
        cal,
        &mut |s, progress| fit(req, s, &data, &chosen, None, progress),
        progress,
    )?;
    // Pruning refits with the first analysis's linearisation, as the first fit did.
    let (cal, pruning) = match req.prune {
        Some(k) => {
            progress.phase(Phase::Pruning);
            let (cal, p) = fitted.prune(cal, k, lin.as_ref(), &validation_data, &data_warns)?;
            (cal, Some(p))
        }
        None => (cal, None),
    };
    progress.phase(Phase::Uncertainty);
    let mut warnings = data_warns;
    warnings.extend(rechosen);
    warnings.extend(restarted);
    if !unseen.is_empty() {
        warnings.insert(
            0,
            Warning::Unseen {
                parameters: unseen.iter().map(|&id| req.robot.param_name(id)).collect(),
            },
        );
    }
    let unc = uncertainty::uncertainty_of_fit(&cal, &data, reference);
    warnings.extend(placed_loose_warning(
        &req.robot,
        &cal,
        unc.as_ref().ok(),
        &placed_loose,
    ));
    progress.phase(Phase::Report);
    let mut outcome = finish(
        req.robot.clone(),
        data,
        validation_data,
        cal,
        unc,
        pruning,
        req.outlier_sigmas,
        req.solution,
        &req.sources,
        &mut warnings,
    );
    if let Some(r) = &registration {
        let len = |v: f64| req.robot.units.from_si(Quantity::Length, v);
        outcome.report.start_placement = Some(crate::report::StartPlacement {
            rms_before: len(r.rms_before),
            rms_after: len(r.rms_after),
        });
    }
    outcome.registration = registration;
    if let Validation::Folds { k, seed } = req.validation {
        progress.phase(Phase::CrossValidation);
        let cv = cross_validate_runs(req, k, seed)?;
        outcome.report.cross_validation = Some(cross_validation_report(&cv, &req.robot));
        outcome.cross_validation = Some(cv);
    }
    if req.prediction != crate::predict::Level::Off && outcome.uncertainty.is_some() {
        progress.phase(Phase::Prediction);
        add_prediction_with(&mut outcome, reference, req.prediction, &mut |w| {
            progress.say(w)
        });
    }
    Ok(outcome)
}

/// The settings a calibration checks before it reads anything.
fn check_settings(req: &Request) -> Result<()> {
    use crate::error::Setting;
    let invalid = |setting, message| Err(Error::InvalidOption { setting, message });
    if !(req.outlier_sigmas.is_finite() && req.outlier_sigmas > 0.0) {
        return invalid(
            Setting::OutlierThreshold,
            format!(
                "expected a positive number of standard deviations, got {}",
                req.outlier_sigmas
            ),
        );
    }
    if let Some(k) = req.prune.filter(|k| !(k.is_finite() && *k > 0.0)) {
        return invalid(
            Setting::PruningThreshold,
            format!("expected a positive number of standard deviations, got {k}"),
        );
    }
    if !(req.solver.rcond > 0.0 && req.solver.rcond < 1.0) {
        return invalid(
            Setting::Rcond,
            format!(
                "expected a number between 0 and 1, got {}",
                req.solver.rcond
            ),
        );
    }
    if req.data.is_empty() {
        return Err(Error::NoObservations);
    }
    Ok(())
}

/// The identification data and the validation data (held-out files, or a fraction held out).
fn split_validation(req: &Request) -> Result<(Arc<Dataset>, Option<Arc<Dataset>>)> {
    Ok(match &req.validation {
        Validation::None | Validation::Folds { .. } => (req.data.clone(), None),
        Validation::Data(v) => (req.data.clone(), Some(v.clone())),
        Validation::Holdout { fraction, seed } => {
            let invalid = |message| Error::InvalidOption {
                setting: crate::error::Setting::HoldoutFraction,
                message,
            };
            if !(*fraction > 0.0 && *fraction < 1.0) {
                return Err(invalid(format!(
                    "expected a fraction between 0 and 1, got {fraction}"
                )));
            }
            let (ident, held) = req.data.split(*fraction, *seed);
            if held.is_empty() || ident.is_empty() {
                return Err(invalid(format!(
                    "{fraction} leaves an empty identification or validation set"
                )));
            }
            (Arc::new(ident), Some(Arc::new(held)))
        }
    })
}

/// An elastic robot whose gravity equilibrium does not converge at a posture gives no answer
/// there: refused, for the nominal robot and the initial guess.
fn check_equilibria(req: &Request, data: &Dataset) -> Result<()> {
    for (robot, what) in std::iter::once((&req.robot, "nominal robot"))
        .chain(req.initial.as_ref().map(|r| (r, "initial guess")))
    {
        let readings = data
            .postures
            .iter()
            .map(|p| (p.readings.as_slice(), p.payload.as_ref()));
        if let Some((i, eq)) = crate::model::kinematics::unconverged_posture(robot, readings) {
            return Err(Error::EquilibriumNotConverged {
                robot: what,
                posture: data.postures[i].label.clone(),
                equilibrium: eq.to_string(),
                change: eq.change,
                iterations: eq.iterations,
            });
        }
    }
    Ok(())
}

/// The robot the solver starts from: the nominal robot, with the initial guess's values when
/// there is one (of the same structure).
fn starting_robot(req: &Request) -> Result<Robot> {
    let Some(guess) = &req.initial else {
        return Ok(req.robot.clone());
    };
    if !req.robot.same_structure(guess) {
        return Err(Error::OtherStructure {
            robot: "the initial guess",
        });
    }
    let mut start = req.robot.clone();
    for id in req
        .robot
        .param_ids()
        .filter(|id| id.0 < guess.param_count())
    {
        start.set(id, guess.get(id));
    }
    for (p, g) in start.planes.iter_mut().zip(&guess.planes) {
        // Tilts are relative to each file's own reference normal.
        p.set_normal(&g.normal());
    }
    Ok(start)
}

/// A far start (a measurement frame placed roughly or not at all): the measurement frame, the
/// measured frames and each session's frame placed in closed form among the parameters that may
/// move, then fitted by least squares with the robot held (a rigid fit of the nominal robot),
/// so that the solver starts, and "start" is reported, at the nominal robot's best placement.
fn place_frames(
    req: &Request,
    start: Robot,
    data: &Dataset,
    nominal_points: &[[nalgebra::Vector3<f64>; 2]],
) -> (Robot, Option<crate::solve::registration::Registration>) {
    let start_points =
        (start != req.robot).then(|| crate::observe::sanity::predicted(&start, data));
    let start_points = start_points.as_deref().unwrap_or(nominal_points);
    let candidates: Vec<ParamId> = match &req.selection {
        Selection::List(ids) => ids.clone(),
        Selection::Default { fix } | Selection::Identifiable { fix, .. } => {
            let (mut ids, _) = default_parameters(&start, data);
            if let Selection::Identifiable { with, .. } = &req.selection {
                ids.extend(with.iter().copied());
            }
            ids.retain(|id| !fix.contains(id));
            ids
        }
    };
    let registration = crate::solve::registration::register_far_start_with(
        &start,
        data,
        &candidates,
        start_points,
    );
    let start = match &registration {
        Some(r) => r.robot.clone(),
        None => start,
    };
    let session_ids: Vec<ParamId> = start
        .param_ids()
        .filter(|&id| matches!(start.param_kind(id), ParamKind::Session { .. }))
        .collect();
    let sessions_placed = crate::solve::registration::place_sessions(&start, data, &session_ids);
    let start = match sessions_placed.as_ref() {
        Some((placed, _, _)) => placed.clone(),
        None => start,
    };
    let cameras_placed = crate::solve::hand_eye::place_cameras(&start, data, &candidates);
    let placed = registration.is_some() || sessions_placed.is_some() || cameras_placed.is_some();
    let start = cameras_placed.unwrap_or(start);
    let start = if placed {
        rigid_fit(&start, data, &candidates, req)
    } else {
        start
    };
    (start, registration)
}

/// Parameters the identifiable set kept only because the start's placement had set them, with
/// their standard deviations at the analysis's weights (file units; see
/// [`crate::identifiability::Analysis::placed_loose`]).
type PlacedLoose = Vec<(ParamId, f64)>;

/// A [`Warning::PlacedLoose`] for the parameters of `placed_loose` (with their standard
/// deviations at the analysis's weights, file units) that `cal` estimated: kept in the
/// identifiable set only because the start's placement had set them from the data. Each is
/// named with its standard deviation as the fit's uncertainty `unc` gives it (the analysis's
/// without one) and its change, in mm or degrees.
fn placed_loose_warning(
    robot: &Robot,
    cal: &Calibration,
    unc: Option<&uncertainty::Uncertainty>,
    placed_loose: &[(ParamId, f64)],
) -> Option<Warning> {
    let shown = |id: ParamId, v: f64| {
        let q = robot.param_quantity(id);
        let si = robot.units.to_si(q, v);
        match q {
            Quantity::Length => format!("{:.1} mm", si * 1e3),
            Quantity::Angle => format!("{:.3} deg", si.to_degrees()),
            _ => format!(
                "{} {}",
                crate::identifiability::fmt_sig(v),
                robot.units.label(q)
            ),
        }
    };
    let parameters: Vec<String> = placed_loose
        .iter()
        .filter(|(id, _)| cal.estimated.contains(id))
        .map(|&(id, analysed)| {
            let sigma = unc
                .and_then(|u| u.parameters.iter().find(|p| p.id == id))
                .and_then(|p| p.sigma)
                .unwrap_or(analysed);
            let change = cal.calibrated.get(id) - cal.initial.get(id);
            format!(
                "{} (sigma {}, moved {})",
                robot.param_name(id),
                shown(id, sigma),
                shown(id, robot.units.from_si(robot.param_quantity(id), change))
            )
        })
        .collect();
    (!parameters.is_empty()).then_some(Warning::PlacedLoose { parameters })
}

/// The frame parameters [`place_frames`] set from the data (`unplaced` before, `placed` after):
/// the identifiable set's noise-level rule keeps them (see
/// [`crate::identifiability::AnalysisOptions::placed`]). A lens's closed form is not a
/// placement: a camera's intrinsics are judged as any parameter.
fn placed_frames(unplaced: &Robot, placed: &Robot) -> Vec<ParamId> {
    placed
        .param_ids()
        .filter(|&id| placed.get(id).to_bits() != unplaced.get(id).to_bits())
        .filter(|&id| match placed.param_kind(id) {
            ParamKind::Camera { component, .. } => !component.is_intrinsic(),
            _ => true,
        })
        .collect()
}

/// What every fit of one calibration shares: the request, the start, the data, the robot the
/// solution rule measures changes from, and the identifiability analysis's options (with what
/// the start's placement set).
struct Fitted<'a> {
    req: &'a Request,
    start: &'a Robot,
    data: &'a Arc<Dataset>,
    reference: &'a Robot,
    analysis_options: &'a AnalysisOptions,
}

impl Fitted<'_> {
    /// A fit with `opts`.
    fn fit(
        &self,
        opts: &CalibrationOptions,
        lin: Option<&Linearized>,
        progress: &mut dyn Progress,
    ) -> Result<Calibration> {
        fit(self.req, self.start, self.data, opts, lin, progress)
    }

    /// The noise-level rule judged the set at the stated sigmas. Residuals far beyond them (a
    /// tracker's own sigmas under a model error ten times larger) show the rows' real noise: the
    /// set is chosen again at it, and fitted again when that leaves parameters out (those only
    /// the stated precision made look determined, along whose valley the solver crawls).
    /// `placed_loose` is the first analysis's ([`crate::identifiability::Analysis::placed_loose`]);
    /// returned is that of the set fitted.
    fn rechoose_at_residual_noise(
        &self,
        cal: Calibration,
        placed_loose: PlacedLoose,
        progress: &mut dyn Progress,
    ) -> Result<(Calibration, Option<Warning>, PlacedLoose)> {
        let req = self.req;
        if !matches!(req.selection, Selection::Identifiable { .. }) {
            return Ok((cal, None, placed_loose));
        }
        let (m, n) = (cal.residuals.len(), cal.options.estimate.len());
        // In the stated sigmas (without a model-error floor's row scale).
        let stated: f64 = cal.residuals.iter().map(|r| r * r).sum();
        let vf = if m > n {
            stated / (m - n) as f64
        } else {
            f64::NAN
        };
        if vf.is_nan() || vf <= SIGMAS_TOO_SMALL {
            return Ok((cal, None, placed_loose));
        }
        let aopts = AnalysisOptions {
            noise_scale: vf.sqrt(),
            ..self.analysis_options.clone()
        };
        progress.phase(Phase::Selection);
        let again = resolve_linearized(&req.selection, self.reference, self.data, &aopts)?;
        let (estimate, new_lin) = (again.estimate, again.lin);
        if estimate == cal.options.estimate {
            return Ok((cal, None, again.placed_loose));
        }
        check_total_mass_kept(
            req.prior.total_mass,
            &req.selection,
            &estimate,
            self.reference,
            "the identifiability analysis at the residuals' noise",
        )?;
        let left_out = cal
            .options
            .estimate
            .iter()
            .filter(|id| !estimate.contains(id))
            .map(|&id| req.robot.param_name(id))
            .collect();
        let new_lin = new_lin.filter(|_| self.reference == self.start);
        let mut opts = cal.options.clone();
        opts.estimate = estimate;
        progress.phase(Phase::Estimation);
        let cal = self.fit(&opts, new_lin.as_ref(), progress)?;
        let warning = Warning::ChosenAtResidualNoise {
            scale: vf.sqrt(),
            left_out,
        };
        Ok((cal, Some(warning), again.placed_loose))
    }

    /// Pruning: the least significant parameter below `k` standard deviations left out and the
    /// rest fitted again, until none is; the full fit's outcome kept for the report.
    fn prune(
        &self,
        cal: Calibration,
        k: f64,
        lin: Option<&Linearized>,
        validation_data: &Option<Arc<Dataset>>,
        data_warns: &[Warning],
    ) -> Result<(Calibration, Pruning)> {
        let (req, data, reference) = (self.req, self.data, self.reference);
        let full = cal.clone();
        let mut cal = cal;
        let mut removed = Vec::new();
        while let Ok(u) = uncertainty::uncertainty_of_fit(&cal, data, reference) {
            let weakest = u
                .parameters
                .iter()
                .filter_map(|p| p.significance.map(|s| (p.id, s)))
                .filter(|&(_, s)| s < k)
                .min_by(|a, b| a.1.total_cmp(&b.1));
            let Some((id, _)) = weakest else { break };
            let mut o = cal.options.clone();
            o.estimate.retain(|&p| p != id);
            if o.estimate.is_empty() {
                break;
            }
            check_total_mass_kept(
                req.prior.total_mass,
                &req.selection,
                &o.estimate,
                reference,
                "pruning",
            )?;
            removed.push(id);
            cal = self.fit(&o, lin, &mut ())?;
        }
        let full_outcome = finish(
            req.robot.clone(),
            data.clone(),
            validation_data.clone(),
            full.clone(),
            uncertainty::uncertainty_of_fit(&full, data, reference),
            None,
            req.outlier_sigmas,
            req.solution,
            &req.sources,
            &mut data_warns.to_vec(),
        );
        let pruning = Pruning {
            k,
            full,
            full_report: Box::new(full_outcome.report),
            removed,
        };
        Ok((cal, pruning))
    }
}

/// Adds to `outcome`'s report the predicted accuracy of its calibrated robot
/// ([`crate::predict::assess`] at `level`; `reference` is the robot the solver started from).
/// Not every calibration can give one (no uncertainty, or too few postures measured by position
/// or pose): the report then has none.
pub(crate) fn add_prediction(
    outcome: &mut Outcome,
    reference: &Robot,
    level: crate::predict::Level,
) {
    add_prediction_with(outcome, reference, level, &mut |_| {});
}

/// [`add_prediction`], saying what it does to `say` (`prediction: fold 4 of 13`).
fn add_prediction_with(
    outcome: &mut Outcome,
    reference: &Robot,
    level: crate::predict::Level,
    say: &mut dyn FnMut(&str),
) {
    if level == crate::predict::Level::Off {
        return;
    }
    let Some(u) = &outcome.uncertainty else {
        // The uncertainty's own warning says why.
        return;
    };
    match crate::predict::assess_with(
        &outcome.calibration,
        &outcome.data,
        reference,
        &u.analysis.parameters,
        u.covariance_internal(),
        level,
        say,
    ) {
        Ok(p) => outcome.report.prediction = Some(p),
        Err(e) => {
            outcome.warnings.push(Warning::NoPrediction {
                reason: e.to_string(),
            });
            outcome.report.set_warnings(&outcome.warnings);
        }
    }
}

/// Cross-validation of `req` on `k` folds (shuffled with `seed`), each fold fitted by [`run`].
pub(super) fn cross_validate_runs(
    req: &Request,
    k: usize,
    seed: Option<u64>,
) -> Result<CrossValidation> {
    cross_validate(req, k, seed, &mut |sub| {
        let o = run(sub, &mut ())?;
        Ok(FoldFit {
            converged: o.calibration.converged(),
            estimated: o.calibration.estimated.clone(),
            rank: o.uncertainty.as_ref().map(|u| u.analysis.rank),
            calibrated: o.calibration.calibrated,
        })
    })
}

/// `robot` with its rigid frames fitted to `data` by least squares, the rest held: the first
/// link (the measurement frame), the last link and the sites (the measured targets' frames) and
/// the sessions' frames, those of them among `candidates`; `robot` itself when the fit does not
/// lower the objective.
fn rigid_fit(robot: &Robot, data: &Dataset, candidates: &[ParamId], req: &Request) -> Robot {
    let last = robot.links.len() - 1;
    let ids: Vec<ParamId> = candidates
        .iter()
        .copied()
        .filter(|&id| {
            matches!(
                robot.param_kind(id),
                ParamKind::Link { link: 0, .. }
                    | ParamKind::Site { .. }
                    | ParamKind::Session { .. }
                    | ParamKind::Camera { .. }
                    | ParamKind::Board { .. }
            ) || matches!(robot.param_kind(id), ParamKind::Link { link, .. } if link == last)
        })
        .collect();
    if ids.is_empty() {
        return robot.clone();
    }
    let mut ids = ids;
    ids.sort();
    ids.dedup();
    let opts = CalibrationOptions {
        estimate: ids,
        solver: SolverOptions::new(estimation::Method::LevenbergMarquardt),
        weights: req.weights,
        orientation: req.orientation,
        loss: Loss::Squared,
        prior: crate::model::robot::Prior::default(),
        model_error: req.model_error,
    };
    match estimation::calibrate(robot, data, &opts, &mut |_| {}) {
        Ok(c) if c.objective_after < c.objective_before && c.calibrated.validate().is_ok() => {
            c.calibrated
        }
        _ => robot.clone(),
    }
}

/// Estimates, then applies the solution rule.
fn fit(
    req: &Request,
    start: &Robot,
    data: &Dataset,
    opts: &CalibrationOptions,
    lin: Option<&Linearized>,
    progress: &mut dyn Progress,
) -> Result<Calibration> {
    let mut cal =
        estimation::calibrate_from(start, data, opts, &mut |it| progress.iteration(it), lin)?;
    if req.solution == SolutionRule::MinChange {
        let problem = Problem::new(start, data, &opts.estimate, opts.weights, opts.orientation);
        let problem = problem
            .with_row_scale(&cal.row_scale)
            .with_prior(&opts.prior);
        let mut x = problem.values(&cal.calibrated);
        for _round in 0..10 {
            let (projected, size) = project_min_change(&problem, &x, &req.robot, data, opts)?;
            let again = estimation::solve(&problem, &projected, &opts.solver, &mut |it| {
                cal.log.push(*it);
                progress.iteration(it)
            })?;
            x = again.x;
            cal.iterations += again.iterations;
            cal.termination = again.termination;
            if size < 1e-9 {
                break;
            }
        }
        let mut calibrated = problem.robot_at(&x);
        for &id in &opts.estimate {
            if start.param_quantity(id) == Quantity::Angle {
                let v0 = start.get(id);
                calibrated.set(id, v0 + wrap_angle(calibrated.get(id) - v0));
            }
        }
        let plain = Problem::new(start, data, &opts.estimate, opts.weights, opts.orientation)
            .with_prior(&opts.prior);
        let kept;
        (
            cal.objective_after,
            cal.prior_objective,
            cal.accuracy_after,
            kept,
        ) = estimation::settle(&plain, &calibrated, &cal.row_scale, &mut cal.residuals);
        cal.errors_after = Some(kept);
        cal.calibrated = calibrated;
    }
    Ok(cal)
}
