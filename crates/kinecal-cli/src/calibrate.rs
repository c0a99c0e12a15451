//! `kinecal calibrate`: arguments to a library calibration spec, the outcome rendered.
//!
//! [`spec_of`] turns the flags (over `--spec`'s file) into a [`CalibrationSpec`]; the library
//! runs it (reading, calibrating, writing the outputs) with this module's progress display, and
//! records it in the history through [`Record`] before its outputs are put in place.
//! `kinecal batch` runs the same spec for every robot of a manifest.

use anyhow::Result;
use kinecal::files::ObservationFile;
use kinecal::spec::{CalibrationSpec, Document, Job, Message, Status};
use kinecal::workflow::{self, Outcome};

use crate::args::CalibrateArgs;
use crate::door::{base, length_angle, observations, over, path_text, set};
use crate::{history, report, word};

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

    fn iteration(&mut self, it: &kinecal::solve::estimation::Iteration) {
        if self.0 {
            eprintln!(
                "{:>5} {:>14.6e} {:>11.3e} {:>10.1e} {:>5}",
                it.iteration, it.objective, it.step, it.lambda, it.evaluations
            );
        }
    }
}

/// The job of a command line: `--spec`'s, with the flags given overriding it (observation or
/// validation files given replace the spec's lists; a way of checking given replaces the
/// spec's).
pub fn spec_of(a: &CalibrateArgs) -> Result<CalibrationSpec> {
    let mut s: CalibrationSpec = base(&a.door)?;
    set(&mut s.robot, a.robot.clone());
    over(&mut s.initial, a.initial.clone());
    observations(&a.observations, &mut s.read, &mut s.observations)?;
    let sel = &mut s.selection;
    if a.choose.is_some() {
        (sel.estimate, sel.prune) = (None, None);
    }
    if a.estimate.is_some() || a.prune.is_some() {
        s.validation.choose = None;
    }
    over(&mut sel.estimate, a.estimate.clone());
    over(&mut sel.fix, a.fix.clone());
    over(&mut sel.prior, a.prior.clone());
    over(&mut sel.total_mass, a.total_mass);
    over(&mut sel.prune, a.prune);
    let sol = &mut s.solver;
    set(&mut sol.method, a.method);
    over(&mut sol.max_iterations, a.max_iter);
    set(&mut sol.damping, a.damping);
    over(&mut sol.rcond, a.rcond);
    set(&mut sol.solution, a.solution);
    let res = &mut s.residuals;
    set(&mut res.loss, a.loss);
    over(&mut res.huber_scale, a.huber_scale);
    set(&mut res.huber_spread, a.huber_spread);
    set(
        &mut res.weights,
        length_angle(a.residuals.weights.as_deref(), kinecal::Setting::Weights)?,
    );
    set(&mut res.orientation_error, a.residuals.orientation_error);
    set(&mut res.model_error, a.model_error);
    over(&mut res.outlier_sigma, a.outlier_sigma);
    let v = &mut s.validation;
    // Each flag overrides its own key; a spec that checks the calibration another way keeps
    // it, and the library refuses the two together rather than one silently dropping the other.
    if !a.validate.is_empty() {
        v.files = a
            .validate
            .iter()
            .map(|p| Ok(ObservationFile::new(path_text(p)?)))
            .collect::<Result<_>>()?;
    }
    over(&mut v.holdout, a.holdout);
    over(&mut v.folds, a.folds);
    over(&mut v.seed, a.seed);
    over(&mut v.choose, a.choose.clone());
    over(&mut v.repeats, a.repeats);
    v.predict |= a.predict;
    let out = &mut s.outputs;
    if let Some(d) = a.shown.display_units {
        out.display_units = d;
    }
    for (flag, slot) in [
        (&a.out, &mut out.robot),
        (&a.report, &mut out.report),
        (&a.html, &mut out.html),
    ] {
        if let Some(p) = flag {
            *slot = Some(path_text(p)?);
        }
    }
    s.strict |= a.strict;
    s.force_units |= a.force_units;
    Ok(s)
}

/// Records calibrations in a history under a serial.
pub struct Record<'a> {
    /// The history.
    pub db: &'a kinecal_history::Database,
    /// The robot's serial.
    pub serial: String,
    /// When (seconds since the epoch; now when absent).
    pub at: Option<i64>,
    /// The note stored with it.
    pub note: String,
    /// Record even over a different robot model.
    pub force: bool,
}

impl kinecal::spec::Recorder for Record<'_> {
    fn record(&mut self, report: &kinecal::report::CalibrationReport) -> kinecal::Result<String> {
        let options = kinecal_history::AddOptions { force: self.force };
        let added = self
            .db
            .record(&self.serial, self.at, report, &self.note, options)
            .map_err(|e| kinecal::Error::Record(e.to_string()))?;
        let (id, serial) = (added.id, &self.serial);
        Ok(if added.new {
            format!("recorded as calibration {id} of robot {serial}")
        } else {
            format!(
                "already recorded as calibration {id} of robot {serial} (the same calibration: \
                 not recorded twice)"
            )
        })
    }
}

/// The progress of a calibration on standard error: a spinner naming the phase (and the
/// iteration and its objective), drawn only on a terminal, not with `--quiet` or `-v`.
pub struct Display {
    bar: indicatif::ProgressBar,
    verbose: Verbose,
    /// `--strict` (or the spec's): a warning that the result would be wrong stops the run.
    strict: bool,
    /// The warnings printed before the solve (not printed again after it).
    shown: Vec<kinecal::Warning>,
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

    fn iteration(&mut self, it: &kinecal::solve::estimation::Iteration) {
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
        !(self.strict && warnings.iter().any(kinecal::Warning::implausible))
    }

    fn say(&mut self, what: &str) {
        Display::say(self, what);
    }
}

/// Runs `kinecal calibrate`.
pub fn run(a: CalibrateArgs) -> Result<u8> {
    let mut display = Display::new(&a);
    display.say("reading");
    let spec = spec_of(&a)?;
    display.strict = spec.strict;
    let choice = spec.validation.choose.is_some();
    let shown = spec.outputs.display_units;
    // A serial or note the history would refuse (too long to store and draw), refused now.
    if let Some(serial) = &a.record {
        kinecal::spec::limits::serial(kinecal::Setting::RobotId, serial).map_err(|e| match e {
            kinecal::Error::InvalidOption { message, .. } => anyhow::anyhow!("--record: {message}"),
            e => e.into(),
        })?;
        kinecal::spec::limits::note(&a.note)?;
    }
    // Open the history first, so that an unwritable database fails before the work.
    let record_at = history::parse_at(a.at.as_deref())?;
    let db = match &a.record {
        Some(_) => Some(history::open_db(a.db.as_deref())?),
        None => None,
    };
    let also: Vec<std::path::PathBuf> = history::db_file(a.db.as_deref())
        .filter(|_| a.record.is_some())
        .into_iter()
        .collect();
    let mut record = match (&a.record, &db) {
        (Some(serial), Some(db)) => Some(Record {
            db,
            serial: serial.clone(),
            at: record_at,
            note: a.note.clone(),
            force: a.force,
        }),
        _ => None,
    };
    // An output written to standard output (`--out -`) owns it: the summary goes to standard
    // error then, so that `--out - > cal.toml` is a robot file and nothing else.
    let summary_to_stderr = [
        &spec.outputs.robot,
        &spec.outputs.report,
        &spec.outputs.html,
    ]
    .iter()
    .any(|o| o.as_deref() == Some("-"));
    let job = Job::Calibrate(spec);
    let solved = crate::door::run_with(
        job,
        &a.door,
        &mut display,
        &also,
        record
            .as_mut()
            .map(|r| r as &mut dyn kinecal::spec::Recorder),
    );
    display.done();
    let Some(done) = solved? else {
        return Ok(0);
    };
    if let Document::Calibration(outcome) = &done.document {
        let r = &outcome.report;
        let units = shown.resolve(r.length_unit, r.angle_unit);
        let mut text = String::new();
        if choice {
            text += &report::choice_table(r, units);
        }
        text += &outcome_text(outcome, units);
        if summary_to_stderr {
            eprint!("{text}");
        } else {
            print!("{text}");
        }
    }
    let shown = &display.shown;
    let fresh: Vec<Message> = done
        .messages
        .iter()
        .filter(|m| !matches!(m, Message::Warning(w) if shown.contains(w)))
        .cloned()
        .collect();
    crate::door::say(&fresh);
    if done.status == Status::Implausible {
        say_strict(&done.document);
    }
    let code = crate::door::exit_code(done.status);
    // The process ends here: the operating system takes the memory back at once, where freeing
    // the datasets' hundreds of thousands of small allocations one by one would cost several
    // milliseconds per 10,000 postures.
    std::mem::forget(done);
    Ok(code)
}

/// Why `--strict` wrote nothing: the implausible warnings of the outcome, or of the data when
/// nothing was solved.
fn say_strict(document: &Document) {
    let implausible = match document {
        Document::Calibration(o) => o.warnings.iter().filter(|w| w.implausible()).count(),
        _ => 0,
    };
    if implausible == 0 {
        eprintln!(
            "STRICT: the warning(s) above say the result would most likely be wrong (units, \
             attitudes or readings that do not fit this robot); nothing solved, written or \
             recorded"
        );
    } else {
        eprintln!(
            "STRICT: {implausible} warning(s) above say the result is most likely wrong \
             (units, readings or a model that does not fit this robot); nothing written or \
             recorded"
        );
    }
}

/// The summary (of the full fit too, when pruned), in `units`.
fn outcome_text(outcome: &Outcome, units: kinecal::DisplayUnits) -> String {
    let mut text = String::new();
    if let Some(p) = &outcome.pruning {
        text += "== full fit ==\n";
        text += &report::summary(&p.full_report, units);
        text += &format!(
            "\n== pruned fit: removed {} (changes below {} sigma, one at a time) ==\n",
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
    text + &report::summary(&outcome.report, units)
}
