//! `kinecal calibrate`: arguments to a library calibration spec, the outcome rendered and
//! written.
//!
//! [`spec_of`] turns the flags (over `--spec`'s file) into a [`CalibrationSpec`]; [`prepare`]
//! has the library read it into a job, which runs; [`finish`] prints, writes the outputs and
//! records in the history. `kinecal batch` runs the same steps for every robot of a manifest.

use std::path::Path;

use std::path::PathBuf;

use anyhow::{anyhow, Result};
use kinecal::estimation::{Damping, Method, Spread};
use kinecal::files::ObservationFile;
use kinecal::files::FORMATS;
use kinecal::robot_file::write_robot_toml_checked;
use kinecal::spec::{CalibrationSpec, Job, LossKind};
use kinecal::workflow::{self, Outcome, SolutionRule};

use crate::args::{CalibrateArgs, DampingArg, LossArg, MethodArg, SolutionArg, SpreadArg};
use crate::{
    history, orientation_of, output, report, weights_of, word, EXIT_IMPLAUSIBLE, EXIT_NOT_CONVERGED,
};

/// Progress for `-v`: one line per iteration.
pub struct Verbose(pub bool);

impl workflow::Progress for Verbose {
    fn phase(&mut self, phase: workflow::Phase) {
        if self.0 && phase == workflow::Phase::Estimation {
            eprintln!(
                "{:>5} {:>14} {:>11} {:>10} {:>5}",
                "iter", "objective", "step", "lambda/t", "evals"
            );
        }
    }

    fn iteration(&mut self, it: &kinecal::estimation::Iteration) {
        if self.0 {
            eprintln!(
                "{:>5} {:>14.6e} {:>11.3e} {:>10.1e} {:>5}",
                it.iteration, it.objective, it.step, it.lambda, it.evaluations
            );
        }
    }
}

/// A calibration ready to run: the library's job (spec, request, robot file).
pub struct Prepared {
    /// The job.
    pub job: Job,
}

/// A path of the command line as a spec's string.
fn path_text(p: &Path) -> Result<String> {
    p.to_str()
        .map(str::to_string)
        .ok_or_else(|| anyhow!("{}: the path is not valid UTF-8", p.display()))
}

/// The job of a command line: `--spec`'s, with the flags given overriding it (observation or
/// validation files given replace the spec's lists; a way of checking given replaces the
/// spec's).
pub fn spec_of(a: &CalibrateArgs) -> Result<CalibrationSpec> {
    let mut s = match &a.spec {
        Some(path) => CalibrationSpec::read(path)?,
        None => CalibrationSpec::default(),
    };
    if let Some(r) = &a.robot {
        s.robot = r.clone();
    }
    if let Some(i) = &a.initial {
        s.initial = Some(i.clone());
    }
    let o = &a.observations;
    if !o.files.is_empty() {
        s.observations = o
            .files
            .iter()
            .map(|(k, p)| {
                Ok(ObservationFile {
                    kind: Some(FORMATS[*k].option.to_string()),
                    ..ObservationFile::new(path_text(p)?)
                })
            })
            .collect::<Result<_>>()?;
    }
    let read = &mut s.read;
    if !o.columns.is_empty() {
        read.columns = o.columns.clone();
    }
    read.length_unit = o.length_unit.clone().or(read.length_unit.take());
    read.angle_unit = o.angle_unit.clone().or(read.angle_unit.take());
    read.position_only |= o.position_only;
    read.session_per_file |= o.session_per_file;
    let sel = &mut s.selection;
    if a.choose.is_some() {
        (sel.estimate, sel.prune) = (None, None);
    }
    if a.estimate.is_some() || a.prune.is_some() {
        s.validation.choose = None;
    }
    sel.estimate = a.estimate.clone().or(sel.estimate.take());
    sel.fix = a.fix.clone().or(sel.fix.take());
    sel.prior = a.prior.clone().or(sel.prior.take());
    sel.total_mass = a.total_mass.or(sel.total_mass);
    sel.prune = a.prune.or(sel.prune);
    let sol = &mut s.solver;
    if let Some(m) = a.method {
        sol.method = match m {
            MethodArg::Lm => Method::LevenbergMarquardt,
            MethodArg::Gn => Method::GaussNewton,
            MethodArg::Sd => Method::SteepestDescent,
            MethodArg::Svd => Method::Svd,
        };
    }
    sol.max_iterations = a.max_iter.or(sol.max_iterations);
    if let Some(d) = a.damping {
        sol.damping = match d {
            DampingArg::Marquardt => Damping::Marquardt,
            DampingArg::Identity => Damping::Identity,
        };
    }
    sol.rcond = a.rcond.or(sol.rcond);
    if let Some(r) = a.solution {
        sol.solution = match r {
            SolutionArg::Solver => SolutionRule::Solver,
            SolutionArg::MinChange => SolutionRule::MinChange,
        };
    }
    let res = &mut s.residuals;
    if let Some(l) = a.loss {
        res.loss = match l {
            LossArg::Squared => LossKind::Squared,
            LossArg::Huber => LossKind::Huber,
        };
    }
    res.huber_scale = a.huber_scale.or(res.huber_scale);
    if let Some(h) = a.huber_spread {
        res.huber_spread = match h {
            SpreadArg::Robust => Spread::Robust,
            SpreadArg::Stated => Spread::Stated,
        };
    }
    if let Some(w) = weights_of(&a.residuals)? {
        res.weights = w;
    }
    if let Some(e) = orientation_of(&a.residuals) {
        res.orientation_error = e;
    }
    res.outlier_sigma = a.outlier_sigma.or(res.outlier_sigma);
    let v = &mut s.validation;
    if !a.validate.is_empty() || a.holdout.is_some() || a.folds.is_some() {
        v.files = a
            .validate
            .iter()
            .map(|p| Ok(ObservationFile::new(path_text(p)?)))
            .collect::<Result<_>>()?;
        (v.holdout, v.folds) = (a.holdout, a.folds);
    }
    v.seed = a.seed.or(v.seed);
    if a.choose.is_some() {
        v.choose = a.choose.clone();
    }
    v.repeats = a.repeats.or(v.repeats);
    v.predict |= a.predict;
    let out = &mut s.outputs;
    for (flag, slot) in [
        (&a.out, &mut out.robot),
        (&a.report, &mut out.report),
        (&a.html, &mut out.html),
    ] {
        if let Some(p) = flag {
            *slot = Some(path_text(p)?);
        }
    }
    Ok(s)
}

/// Reads the files and builds the job; refuses outputs over inputs.
pub fn prepare(spec: &CalibrationSpec, db: Option<&Path>) -> Result<Prepared> {
    let outputs = spec.outputs();
    let mut inputs = spec.inputs();
    inputs.extend(db.map(Path::to_path_buf));
    output::check_distinct(
        &outputs.iter().map(PathBuf::as_path).collect::<Vec<_>>(),
        &inputs.iter().map(PathBuf::as_path).collect::<Vec<_>>(),
    )?;
    Ok(Prepared { job: spec.load()? })
}

/// Stages the job's outputs (the calibrated robot, the report, the HTML report) for `outcome`.
pub fn stage_outputs(p: &Prepared, outcome: &Outcome, staged: &mut output::Staged) -> Result<()> {
    let o = &p.job.spec.outputs;
    if let Some(path) = &o.robot {
        staged.text(
            Path::new(path),
            &write_robot_toml_checked(
                &outcome.calibration.calibrated,
                Some(&p.job.robot_source.text),
            )?,
        )?;
    }
    if let Some(path) = &o.report {
        staged.text(Path::new(path), &(outcome.report.to_json() + "\n"))?;
    }
    if let Some(path) = &o.html {
        staged.text(
            Path::new(path),
            &kinecal_report::html_report(&outcome.report)?,
        )?;
    }
    Ok(())
}

/// The progress of a calibration on standard error: a spinner naming the phase (and the
/// iteration and its objective), drawn only on a terminal, not with `--quiet` or `-v`.
pub struct Display {
    bar: indicatif::ProgressBar,
    verbose: Verbose,
    /// `--strict`: a warning that the result would be wrong stops the run.
    strict: bool,
    /// The warnings printed before the solve (not printed again after it).
    shown: Vec<kinecal::Warning>,
    /// Whether the data checks stopped the run.
    stopped: bool,
}

impl Display {
    /// A display for `a`'s options.
    pub fn new(a: &CalibrateArgs) -> Display {
        let target = if a.quiet || a.verbose {
            indicatif::ProgressDrawTarget::hidden()
        } else {
            indicatif::ProgressDrawTarget::stderr()
        };
        let bar = indicatif::ProgressBar::with_draw_target(None, target);
        bar.set_style(
            indicatif::ProgressStyle::with_template("{spinner} {elapsed} {msg}")
                .expect("a valid template"),
        );
        // No ticking thread for a display nobody sees (--quiet, -v, or not a terminal).
        if !bar.is_hidden() {
            bar.enable_steady_tick(std::time::Duration::from_millis(120));
        }
        Display {
            bar,
            verbose: Verbose(a.verbose),
            strict: a.strict,
            shown: Vec::new(),
            stopped: false,
        }
    }

    /// Names what happens now.
    pub fn say(&self, what: &str) {
        self.bar.set_message(what.to_string());
    }

    /// Clears the display.
    pub fn done(&self) {
        self.bar.finish_and_clear();
    }

    /// Runs `f` (which prints) with the display cleared, then draws it again.
    pub fn suspend<R>(&self, f: impl FnOnce() -> R) -> R {
        self.bar.suspend(f)
    }
}

impl workflow::Progress for Display {
    fn phase(&mut self, phase: workflow::Phase) {
        self.say(phase.as_str());
        self.verbose.phase(phase);
    }

    fn iteration(&mut self, it: &kinecal::estimation::Iteration) {
        self.bar.set_message(format!(
            "estimation: iteration {}, objective {:.6e}",
            it.iteration, it.objective
        ));
        self.verbose.iteration(it);
    }

    fn data_checked(&mut self, warnings: &[kinecal::Warning]) -> bool {
        // Said at once, before a solve that could not make sense of such data.
        self.suspend(|| {
            for w in warnings {
                eprintln!("warning: {}", word(w));
            }
        });
        self.shown.extend(warnings.iter().cloned());
        let implausible = warnings.iter().filter(|w| w.implausible()).count();
        if self.strict && implausible > 0 {
            self.stopped = true;
            return false;
        }
        true
    }
}

/// Runs `kinecal calibrate`.
pub fn run(a: CalibrateArgs) -> Result<u8> {
    let mut display = Display::new(&a);
    display.say("reading");
    let spec = spec_of(&a)?;
    let p = prepare(
        &spec,
        history::db_file(a.db.as_deref())
            .filter(|_| a.record.is_some())
            .as_deref(),
    )?;
    // Written once the job has been read and checked, before it runs.
    if let Some(path) = &a.write_spec {
        output::check_distinct(
            &[path.as_path()],
            &spec
                .inputs()
                .iter()
                .map(PathBuf::as_path)
                .collect::<Vec<_>>(),
        )?;
        crate::write_file(path, &spec.written_to(path)?.to_toml())?;
        display.suspend(|| eprintln!("wrote the spec to {}", path.display()));
    }
    // Open the history first, so that an unwritable database fails before the work.
    let record_at = history::parse_at(a.at.as_deref())?;
    let record_db = match &a.record {
        Some(_) => Some(history::open_db(a.db.as_deref())?),
        None => None,
    };
    let solved = p.job.run(&mut display);
    if solved.is_err() {
        display.done();
    }
    if display.stopped {
        eprintln!(
            "STRICT: the warning(s) above say the result would most likely be wrong (units, \
             attitudes or readings that do not fit this robot); nothing solved, written or recorded"
        );
        return Ok(EXIT_IMPLAUSIBLE);
    }
    let outcome = solved?;
    if p.job.choice.is_some() {
        display.suspend(|| print!("{}", report::choice_table(&outcome.report)));
    }
    let code = finish(&a, &p, &outcome, record_at, record_db.as_ref(), &display);
    display.done();
    // The process ends here: the operating system takes the memory back at once, where freeing
    // the datasets' hundreds of thousands of small allocations one by one would cost several
    // milliseconds per 10,000 postures.
    std::mem::forget(outcome);
    std::mem::forget(p);
    code
}

/// Prints the outcome, writes the outputs and records the calibration; the exit code.
fn finish(
    a: &CalibrateArgs,
    p: &Prepared,
    outcome: &Outcome,
    record_at: Option<i64>,
    record_db: Option<&kinecal_history::Database>,
    display: &Display,
) -> Result<u8> {
    display.suspend(|| print_outcome(outcome, &display.shown));
    let implausible = outcome.warnings.iter().filter(|w| w.implausible()).count();
    if a.strict && implausible > 0 {
        display.suspend(|| {
            eprintln!(
                "STRICT: {implausible} warning(s) above say the result is most likely wrong \
                 (units, readings or a model that does not fit this robot); nothing written or \
                 recorded"
            )
        });
        return Ok(EXIT_IMPLAUSIBLE);
    }
    // Everything is computed, and every output written beside its target, before anything is
    // replaced; the history record is the last step that can fail.
    display.say("writing");
    let mut staged = output::Staged::new();
    stage_outputs(p, outcome, &mut staged)?;
    if let (Some(serial), Some(db)) = (&a.record, record_db) {
        display.say("recording in the history");
        let options = kinecal_history::AddOptions { force: a.force };
        let added = db.record(serial, record_at, &outcome.report, &a.note, options)?;
        let id = added.id;
        if added.new {
            display.suspend(|| eprintln!("recorded as calibration {id} of robot {serial}"));
        } else {
            display.suspend(|| {
                eprintln!(
                    "already recorded as calibration {id} of robot {serial} (the same calibration: not recorded twice)"
                )
            });
        }
    }
    staged.commit()?;
    display.done();
    let o = &p.job.spec.outputs;
    for (path, what) in [
        (&o.robot, "the calibrated robot"),
        (&o.report, "the report"),
        (&o.html, "the HTML report"),
    ] {
        if let Some(p) = path {
            eprintln!("wrote {what} to {p}");
        }
    }
    Ok(if outcome.calibration.converged() {
        0
    } else {
        EXIT_NOT_CONVERGED
    })
}

/// Prints the summary (of the full fit too, when pruned) and the warnings (but those in
/// `shown`, printed before the solve).
fn print_outcome(outcome: &Outcome, shown: &[kinecal::Warning]) {
    if let Some(p) = &outcome.pruning {
        println!("== full fit ==");
        print!("{}", report::summary(&p.full_report));
        println!();
        println!(
            "== pruned fit: removed {} (changes below {} sigma, one at a time) ==",
            if p.removed.is_empty() {
                "nothing".to_string()
            } else {
                p.removed
                    .iter()
                    .map(|id| id.to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            },
            p.k
        );
    }
    print!("{}", report::summary(&outcome.report));
    for w in outcome.warnings.iter().filter(|w| !shown.contains(w)) {
        eprintln!("warning: {}", word(w));
    }
}
