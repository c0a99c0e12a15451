//! Python's door to every job: `kinecal.run(spec)` runs a spec (a file, TOML text or a dict) as
//! the command line runs it, and the named functions (`kinecal.calibrate`, `kinecal.analyze`,
//! ...) send their keywords as a spec ([`settings`]), which the library translates as it
//! translates every other front end's.

use std::path::Path;

use kinecal::spec::{Env, Job, Message, Spec, Status};
use pyo3::prelude::*;

use crate::{bad, error};

/// The file name of specs made of a function's keywords: their errors name the key path, which
/// the Python package words as its keyword.
pub const KEYWORDS: &str = "keywords";

/// The spec `S` of a named function's keywords (JSON, a spec's keys; see the Python package's
/// `_settings`).
pub fn settings<S: Spec>(py: Python<'_>, json: &str) -> PyResult<S> {
    let value: serde_json::Value =
        serde_json::from_str(json).map_err(|e| bad(format!("the keywords' spec: {e}")))?;
    kinecal::spec::spec_from_value(value, KEYWORDS).map_err(|e| error(py, e))
}

/// The job of a spec given as `form` (`path`, `toml` or `json`).
fn job_of(py: Python<'_>, spec: &str, form: &str) -> PyResult<Job> {
    match form {
        "path" => Job::read(Path::new(spec)),
        "toml" => Job::from_toml(spec, "spec"),
        "json" => Job::from_json(spec, "spec"),
        // A named function's keywords: errors name the key path, which Python words as the
        // keyword.
        "keywords" => Job::from_json(spec, KEYWORDS),
        other => return Err(bad(format!("run: unknown form `{other}`"))),
    }
    .map_err(|e| error(py, e))
}

/// Runs `job` through the library's door, the GIL released.
fn run_job(py: Python<'_>, job: &Job, spec_file: Option<&str>) -> PyResult<kinecal::spec::Done> {
    py.detach(|| {
        let artist = kinecal_report::Artist;
        let historian = kinecal_history::jobs::Historian::new(Some(&artist));
        let mut quiet = ();
        let mut env = Env::new(&mut quiet, Some(&artist));
        env.historian = Some(&historian);
        env.also_inputs.extend(spec_file.map(Into::into));
        kinecal::spec::run(job, &mut env)
    })
    .map_err(|e| error(py, e))
}

/// What a job said, as `(kind, text)` pairs: `note` or `warning`.
fn said(done: &kinecal::spec::Done) -> Said {
    done.messages
        .iter()
        .filter_map(|m| match m {
            Message::Note(t) => Some(("note".to_string(), t.clone())),
            Message::Warning(w) => Some(("warning".to_string(), w.to_string())),
            Message::Caution(t) => Some(("warning".to_string(), t.clone())),
            _ => None,
        })
        .collect()
}

/// What a job said: `(kind, text)` pairs, `note` or `warning`.
type Said = Vec<(String, String)>;

/// A calibration job's result for Python: the calibrated robot, the outcome (its report and
/// arrays made when read) and what it said.
type Calibrated = (crate::Robot, crate::outcome::CalibrationOutcome, Said);

/// A job's result for Python: its kind, its document (JSON), what it said and its status.
type Ran = (String, String, Said, String);

/// Runs a calibration spec (`form` as for [`run`]) as `kinecal calibrate --spec` runs it, its
/// outputs written: the calibrated robot, the outcome and what it said (an error when the spec
/// is not a calibration's).
#[pyfunction]
pub fn calibrate_job(py: Python<'_>, spec: &str, form: &str) -> PyResult<Calibrated> {
    let job = job_of(py, spec, form)?;
    if !matches!(job, Job::Calibrate(_)) {
        return Err(bad(format!(
            "calibrate: the spec is of the job `{}`: kinecal.run runs it",
            job.kind()
        )));
    }
    let done = run_job(py, &job, (form == "path").then_some(spec))?;
    let messages = said(&done);
    let kinecal::spec::Document::Calibration(outcome) = done.document else {
        return Err(bad(
            "calibrate: the strict calibration stopped before solving: the data's warnings say \
             the result would most likely be wrong",
        ));
    };
    if let Some(why) = outcome.report.refused.as_ref() {
        return Err(bad(format!("calibrate: {why}")));
    }
    let text = match &job {
        Job::Calibrate(s) => kinecal::spec::load_robot(&s.robot)
            .map(|(_, source)| source.text)
            .ok(),
        _ => None,
    };
    let robot = crate::Robot {
        robot: outcome.calibration.calibrated.clone(),
        text,
    };
    Ok((
        robot,
        crate::outcome::CalibrationOutcome::new(outcome),
        messages,
    ))
}

/// Runs a spec (`form`: `path` for a spec file, `toml` for its text, `json` for a dict's JSON)
/// as `kinecal <job> --spec` runs it, its outputs written through the library's one writer.
/// Returns the job's kind, its document (JSON), what it said (`(kind, text)`: `note` or
/// `warning`) and its status (`ok`, `not-converged`, `implausible`, `flagged`).
#[pyfunction]
pub fn run(py: Python<'_>, spec: &str, form: &str) -> PyResult<Ran> {
    let job = job_of(py, spec, form)?;
    let done = run_job(py, &job, (form == "path").then_some(spec))?;
    let messages = said(&done);
    let status = match done.status {
        Status::Ok => "ok",
        Status::NotConverged => "not-converged",
        Status::Implausible => "implausible",
        Status::Refused => "refused",
        Status::Flagged => "flagged",
        _ => "other",
    };
    Ok((
        job.kind().name().to_string(),
        done.document.to_json(),
        messages,
        status.to_string(),
    ))
}
