//! `kinecal calibrate`: arguments to a library request, the outcome rendered and written.
//!
//! Three steps, so that `kinecal batch` runs the same calibration for every robot of a
//! manifest: [`prepare`] (read the files, build the request), [`solve`] (the library's
//! workflow), [`finish`] (print, write the outputs, record in the history).

use std::path::Path;

use anyhow::{anyhow, bail, Result};
use kinecal::estimation::{Damping, Loss, Method, SolverOptions};
use kinecal::files::FORMATS;
use kinecal::observe::Dataset;
use kinecal::robot_file::write_robot_toml_checked;
use kinecal::workflow::{self, Outcome, Request, Selection, SolutionRule, Validation};

use crate::args::{CalibrateArgs, DampingArg, LossArg, MethodArg, SolutionArg, SpreadArg};
use crate::{
    history, load_observations, load_robot, output, read_any, report, residual_settings, word,
    LoadedRobot, EXIT_IMPLAUSIBLE, EXIT_NOT_CONVERGED,
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

/// A calibration ready to run: the request, and what writing its outputs needs.
pub struct Prepared {
    /// The library request.
    pub req: Request,
    /// The robot as read (its file text is the template of the calibrated robot file).
    pub robot: LoadedRobot,
    /// The observation files (to name the file of a bad row).
    files: Vec<(usize, std::path::PathBuf)>,
}

/// Reads the files and builds the request; refuses outputs over inputs.
pub fn prepare(a: &CalibrateArgs) -> Result<Prepared> {
    let outputs: Vec<&Path> = [&a.out, &a.report, &a.html]
        .into_iter()
        .flatten()
        .map(|p| p.as_path())
        .collect();
    let mut inputs: Vec<&Path> = a
        .observations
        .files
        .iter()
        .map(|(_, p)| p.as_path())
        .collect();
    inputs.extend(a.validate.iter().map(|p| p.as_path()));
    inputs.push(Path::new(&a.robot));
    if let Some(i) = &a.initial {
        inputs.push(Path::new(i));
    }
    if let Some(db) = &a.db {
        inputs.push(db);
    }
    output::check_distinct(&outputs, &inputs)?;
    let r = load_robot(&a.robot)?;
    let robot = &r.robot;
    let (data, data_sources) = load_observations(&a.observations, robot)?;
    let (weights, orientation) = residual_settings(&a.residuals, robot)?;
    if a.folds.is_some() && !a.validate.is_empty() && a.choose.is_none() {
        bail!(
            "--folds and --validate are two ways to check a calibration: give one (with --choose, \
             the folds choose the model and the validation file checks it)"
        );
    }
    let validation = match (a.validate.is_empty(), a.holdout) {
        (false, _) => {
            let mut v = Dataset::default();
            for path in &a.validate {
                v = v.merge(read_any(path, &a.observations, robot)?.0);
            }
            Validation::Data(v.into())
        }
        (true, Some(fraction)) => Validation::Holdout {
            fraction,
            seed: a.seed.unwrap_or(1),
        },
        (true, None) => match a.folds {
            Some(k) => Validation::Folds { k, seed: a.seed },
            None => Validation::None,
        },
    };
    let mut solver = SolverOptions::new(match a.method {
        MethodArg::Lm => Method::LevenbergMarquardt,
        MethodArg::Gn => Method::GaussNewton,
        MethodArg::Sd => Method::SteepestDescent,
        MethodArg::Svd => Method::Svd,
    });
    if let Some(n) = a.max_iter {
        solver.max_iterations = n;
    }
    solver.damping = match a.damping {
        DampingArg::Marquardt => Damping::Marquardt,
        DampingArg::Identity => Damping::Identity,
    };
    solver.rcond = a.rcond;
    let mut req = Request::new(robot.clone(), data);
    if a.estimate.is_some() || a.fix.is_some() {
        req.selection =
            Selection::parse(a.estimate.as_deref().unwrap_or(""), a.fix.as_deref(), robot)?;
    }
    req.initial = match &a.initial {
        None => None,
        Some(spec) => {
            let guess = load_robot(spec)?.robot;
            if !robot.same_structure(&guess) {
                bail!(
                    "--initial {spec}: not the same robot structure as --robot {}",
                    a.robot
                );
            }
            Some(guess)
        }
    };
    req.solver = solver;
    req.loss = match a.loss {
        LossArg::Squared => Loss::Squared,
        LossArg::Huber => Loss::Huber {
            k: a.huber_scale,
            spread: match a.huber_spread {
                SpreadArg::Robust => kinecal::estimation::Spread::Robust,
                SpreadArg::Stated => kinecal::estimation::Spread::Stated,
            },
        },
    };
    req.weights = weights;
    req.orientation = orientation;
    req.solution = match a.solution {
        SolutionArg::Solver => SolutionRule::Solver,
        SolutionArg::MinChange => SolutionRule::MinChange,
    };
    req.prune = a.prune;
    req.validation = validation;
    req.outlier_sigmas = a.outlier_sigma;
    req.sources = std::iter::once(r.source.clone())
        .chain(data_sources)
        .collect();
    Ok(Prepared {
        req,
        robot: r,
        files: a.observations.files.clone(),
    })
}

/// Runs the workflow (or the model choice, whose table is returned too).
pub fn solve(
    a: &CalibrateArgs,
    p: &Prepared,
    progress: &mut dyn workflow::Progress,
) -> Result<(Outcome, Option<String>)> {
    let (req, robot, files) = (&p.req, &p.robot.robot, &p.files);
    let result = match &a.choose {
        None => workflow::run(req, progress).map(|o| (o, None)),
        Some(list) => {
            let candidates = if list.is_empty() {
                workflow::Candidate::defaults(robot)
            } else {
                list.iter()
                    .map(|t| workflow::Candidate::parse(t, robot))
                    .collect()
            };
            candidates
                .and_then(|c| workflow::choose(req, &c, a.folds.unwrap_or(5), a.seed, a.repeats))
                .map(|choice| {
                    let table = report::choice_table(&choice.outcome.report);
                    (choice.outcome, Some(table))
                })
        }
    };
    result.map_err(|e| match e {
        kinecal::Error::NonFiniteResidual { line, kind, .. } => {
            // Name the file the observation came from (or the files it may have come from).
            let of_kind: Vec<String> = files
                .iter()
                .filter(|(i, _)| FORMATS[*i].kinds.contains(&kind))
                .map(|(_, p)| p.display().to_string())
                .collect();
            match of_kind.as_slice() {
                [one] => anyhow!("{one}:{line}: {e}"),
                many => anyhow!("line {line} of one of {}: {e}", many.join(", ")),
            }
        }
        e => e.into(),
    })
}

/// Stages the outputs `a` names (`--out`, `--report`, `--html`) for `outcome`.
pub fn stage_outputs(
    a: &CalibrateArgs,
    p: &Prepared,
    outcome: &Outcome,
    staged: &mut output::Staged,
) -> Result<()> {
    if let Some(path) = &a.out {
        staged.text(
            path,
            &write_robot_toml_checked(&outcome.calibration.calibrated, Some(&p.robot.source.text))?,
        )?;
    }
    if let Some(path) = &a.report {
        staged.text(path, &(outcome.report.to_json() + "\n"))?;
    }
    if let Some(path) = &a.html {
        staged.text(path, &kinecal_report::html_report(outcome)?)?;
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
    let read = std::time::Instant::now();
    let p = prepare(&a)?;
    let reading = read.elapsed().as_secs_f64();
    // Open the history first, so that an unwritable database fails before the work.
    let record_at = history::parse_at(a.at.as_deref())?;
    let record_db = match &a.record {
        Some(_) => Some(history::open_db(a.db.as_deref())?),
        None => None,
    };
    let solved = solve(&a, &p, &mut display);
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
    let (mut outcome, choice) = solved?;
    outcome.report.timings.insert(
        0,
        kinecal::report::PhaseTime {
            phase: "reading".into(),
            seconds: reading,
        },
    );
    if let Some(table) = choice {
        display.suspend(|| print!("{table}"));
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
    stage_outputs(a, p, outcome, &mut staged)?;
    if let (Some(serial), Some(db)) = (&a.record, record_db) {
        display.say("recording in the history");
        let options = kinecal_history::AddOptions { force: a.force };
        let id = db.add_with(serial, record_at, &outcome.report, &a.note, options)?;
        display.suspend(|| eprintln!("recorded as calibration {id} of robot {serial}"));
    }
    staged.commit()?;
    display.done();
    for (path, what) in [
        (&a.out, "the calibrated robot"),
        (&a.report, "the report"),
        (&a.html, "the HTML report"),
    ] {
        if let Some(p) = path {
            eprintln!("wrote {what} to {}", p.display());
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
