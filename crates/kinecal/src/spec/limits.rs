//! The bounds of the numbers and texts a user gives, checked at the door before anything is
//! computed or written: every front end (command-line flags, spec keys, batch rows, Python
//! keywords) meets the same limit, named in the refusal ("expected between 1 and 100 repeats,
//! not 1000000000").
//!
//! Each limit comes from what a run can hold or finish:
//!
//! - a seed is at most [`MAX_SEED`] (2^63 - 1), the largest integer a spec file (TOML) holds,
//!   so that every seed a command accepts is written by `--write-spec` and read back as the
//!   same number: the same data, bit for bit. A seed is a label; 2^63 of them are enough, and
//!   a spec keeps one spelling of a number;
//! - an iteration cap is at most [`MAX_ITERATIONS`]: a million iterations of even the smallest
//!   problem take minutes, and steepest descent, the slowest method, needs thousands;
//! - a model choice repeats its cross-validation at most [`MAX_REPEATS`] times: each repeat
//!   refits every candidate on every fold, and the standard error of the choice falls only as
//!   one over the square root of the repeats (100 give a tenth of one's);
//! - counts of postures, samples, cycles and grid points have their limits beside their
//!   settings (`simulate`, `plan`, `predict`, `iso9283`, `curves`), where the memory they take
//!   is known;
//! - a robot's serial is at most [`MAX_SERIAL_CHARS`] characters and a note at most
//!   [`MAX_NOTE_CHARS`]: a history stores them and every table and page of it draws them.

use crate::error::{Result, Setting};

use super::common::invalid;
use super::Job;

/// The largest seed: the largest integer a spec file can hold (2^63 - 1).
pub const MAX_SEED: u64 = i64::MAX as u64;

/// The largest iteration cap of a calibration's solver.
pub const MAX_ITERATIONS: usize = 1_000_000;

/// The most repeats of a model choice's cross-validation.
pub const MAX_REPEATS: usize = 100;

/// The longest robot serial (characters) a history records.
pub const MAX_SERIAL_CHARS: usize = 128;

/// The longest note (characters) a history records.
pub const MAX_NOTE_CHARS: usize = 1000;

/// Refuses a seed a spec file cannot hold.
pub(crate) fn seed(seed: Option<u64>) -> Result<()> {
    match seed {
        Some(s) if s > MAX_SEED => Err(invalid(
            Setting::Seed,
            format!(
                "expected a seed between 0 and {MAX_SEED} (the largest integer a spec file \
                 holds), not {s}"
            ),
        )),
        _ => Ok(()),
    }
}

/// Refuses a count above `max` (or 0).
fn count(setting: Setting, n: Option<usize>, max: usize, what: &str) -> Result<()> {
    match n {
        Some(n) => super::common::count(setting, n, max, what).map(|_| ()),
        None => Ok(()),
    }
}

/// Refuses a text of `setting` longer than `max` characters.
pub fn text(setting: Setting, value: &str, max: usize, what: &str) -> Result<()> {
    let n = value.chars().count();
    if n > max {
        return Err(invalid(
            setting,
            format!("expected a {what} of at most {max} characters, not {n}"),
        ));
    }
    Ok(())
}

/// Refuses a robot serial longer than [`MAX_SERIAL_CHARS`] (a history stores and draws it).
pub fn serial(setting: Setting, value: &str) -> Result<()> {
    text(setting, value, MAX_SERIAL_CHARS, "serial")
}

/// Refuses a note longer than [`MAX_NOTE_CHARS`].
pub fn note(value: &str) -> Result<()> {
    text(Setting::Note, value, MAX_NOTE_CHARS, "note")
}

/// Checks every bounded number and text of `job` (see the [module documentation](self)).
pub(crate) fn check(job: &Job) -> Result<()> {
    match job {
        Job::Calibrate(s) => {
            seed(s.validation.seed)?;
            count(
                Setting::MaxIterations,
                s.solver.max_iterations,
                MAX_ITERATIONS,
                "iterations",
            )?;
            count(
                Setting::Repeats,
                s.validation.repeats,
                MAX_REPEATS,
                "repeats",
            )
        }
        Job::Plan(s) => seed(s.seed),
        Job::Predict(s) => seed(s.seed),
        Job::Simulate(s) => seed(s.seed),
        Job::Iso9283Simulate(s) => seed(s.seed),
        Job::HistoryAdd(s) => {
            serial(Setting::RobotId, &s.robot_id)?;
            note(&s.note)
        }
        Job::HistoryEvent(s) => {
            serial(Setting::RobotId, &s.robot_id)?;
            note(&s.note)
        }
        _ => Ok(()),
    }
}
