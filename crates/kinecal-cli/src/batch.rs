//! `kinecal batch`: run every job of a manifest, in parallel (the fleet case).
//!
//! Each entry is a library spec: a TOML `[[jobs]]` table of any kind (`job = "analyze"`, ...),
//! a `[[robots]]` table (a calibration spec with its serial) over the `[defaults]` one, or a
//! CSV row's options, read as a calibration spec by [`CALIBRATE_FLAGS`] (no command-line parser
//! involved). Every job runs as its command runs it ([`kinecal::spec::run`]); its outputs are
//! written when it succeeds, whatever the others do. The jobs run on a thread pool (`rayon`);
//! calibrations hold their outputs until they are recorded in the history, afterwards, in
//! manifest order, by one writer. Before any job runs, an output that another job reads or
//! writes, or that is the manifest, the summary or the database, is refused ([`check_files`],
//! paths compared as [`output::identity`] resolves them).

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use anyhow::{anyhow, bail, Context as _, Result};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use kinecal::files::output;
use kinecal::spec::{Document, Env, Job, Pending};
use kinecal::units::Quantity;
use kinecal::workflow::Outcome;
use rayon::prelude::*;

use crate::args::BatchArgs;
use crate::{history, EXIT_FLAGGED, EXIT_NOT_CONVERGED};

/// One job of the manifest.
struct Entry {
    /// The robot's serial (a calibration), or the job's name.
    serial: String,
    /// Where the entry is (`fleet.csv:3`), for messages.
    at: String,
    /// The job (paths relative to the working folder), or why the entry cannot be run.
    job: std::result::Result<Job, String>,
}

/// How one job ended.
enum Status {
    Ok,
    NotConverged,
    /// What needs a person, in words: a strict calibration and a warning that the result is
    /// most likely wrong (nothing written), a calibration refused for its units, or a job that
    /// flagged something (a check out of its accuracy, a drift, compensated rows).
    Flagged(&'static str),
    Failed(String),
}

impl Status {
    fn word(&self) -> String {
        match self {
            Status::Ok => "ok".into(),
            Status::NotConverged => "not converged".into(),
            Status::Flagged(why) => (*why).into(),
            Status::Failed(e) => format!("failed: {e}"),
        }
    }

    /// How a job that ended with `status` is summed up.
    fn of(status: kinecal::spec::Status) -> Status {
        use kinecal::spec::Status as S;
        match status {
            S::NotConverged => Status::NotConverged,
            S::Implausible => Status::Flagged("flagged (--strict): nothing written"),
            S::Refused => Status::Flagged("refused: no robot written or recorded"),
            S::Flagged => Status::Flagged("flagged"),
            _ => Status::Ok,
        }
    }
}

/// A summary row.
struct Row {
    serial: String,
    status: Status,
    parameters: Option<usize>,
    iterations: Option<usize>,
    /// RMS error before and after (robot file's length unit), and its metric.
    rms: Option<(f64, f64, &'static str)>,
    /// Held-out mean error (validation data, hold-out or cross-validation).
    held_out: Option<f64>,
    unit: String,
    warnings: Vec<String>,
    /// The warnings that say the result is most likely wrong.
    implausible: Vec<String>,
}

/// What a calibrate option of a CSV row sets in the spec.
#[derive(Clone, Copy)]
pub enum Sets {
    /// A value at this key path.
    Value(&'static str),
    /// `true` at this key path.
    Flag(&'static str),
    /// An observation file of this kind (`data`, `distances`, `contacts`).
    File(&'static str),
    /// A held-out file.
    Validate,
    /// One more column mapping.
    Column,
    /// `length=L,angle=A` as a table at this key path.
    LengthAngle(&'static str),
    /// The model candidates (any number of values, up to the next option).
    Candidates,
}

/// The options of `kinecal calibrate` a CSV manifest's row may give, and where each goes in a
/// calibration spec: the command line's flags, read without its parser (a test checks every
/// one is a flag of `kinecal calibrate`, and every such flag is here or refused).
pub const CALIBRATE_FLAGS: &[(&str, Sets)] = &[
    ("--spec", Sets::Value("")),
    ("--initial", Sets::Value("initial")),
    ("--data", Sets::File("data")),
    ("--distances", Sets::File("distances")),
    ("--contacts", Sets::File("contacts")),
    ("--columns", Sets::Column),
    ("--length-unit", Sets::Value("read.length_unit")),
    ("--angle-unit", Sets::Value("read.angle_unit")),
    ("--position-only", Sets::Flag("read.position_only")),
    ("--session-per-file", Sets::Flag("read.session_per_file")),
    ("--method", Sets::Value("solver.method")),
    ("--estimate", Sets::Value("selection.estimate")),
    ("--fix", Sets::Value("selection.fix")),
    ("--prior", Sets::Value("selection.prior")),
    ("--total-mass", Sets::Value("selection.total_mass")),
    ("--prune", Sets::Value("selection.prune")),
    ("--max-iter", Sets::Value("solver.max_iterations")),
    ("--damping", Sets::Value("solver.damping")),
    ("--rcond", Sets::Value("solver.rcond")),
    ("--solution", Sets::Value("solver.solution")),
    ("--weights", Sets::LengthAngle("residuals.weights")),
    (
        "--orientation-error",
        Sets::Value("residuals.orientation_error"),
    ),
    ("--loss", Sets::Value("residuals.loss")),
    ("--huber-scale", Sets::Value("residuals.huber_scale")),
    ("--huber-spread", Sets::Value("residuals.huber_spread")),
    ("--outlier-sigma", Sets::Value("residuals.outlier_sigma")),
    ("--validate", Sets::Validate),
    ("--holdout", Sets::Value("validation.holdout")),
    ("--folds", Sets::Value("validation.folds")),
    ("--seed", Sets::Value("validation.seed")),
    ("--choose", Sets::Candidates),
    ("--repeats", Sets::Value("validation.repeats")),
    ("--predict", Sets::Flag("validation.predict")),
    ("--out", Sets::Value("outputs.robot")),
    ("--report", Sets::Value("outputs.report")),
    ("--html", Sets::Value("outputs.html")),
    ("--display-units", Sets::Value("outputs.display_units")),
    ("--strict", Sets::Flag("strict")),
];

/// Options of `kinecal calibrate` that are not a robot's in a batch.
pub const NOT_PER_ROBOT: &[&str] = &[
    "--robot",
    "--record",
    "--db",
    "--at",
    "--note",
    "--force",
    "--verbose",
    "--quiet",
    "--write-spec",
    "--help",
];

/// Splits an options string as a shell would: whitespace separates, single and double quotes
/// group, a backslash escapes the next character.
fn split_options(s: &str) -> std::result::Result<Vec<String>, String> {
    let mut out = Vec::new();
    let mut cur = String::new();
    let mut any = false;
    let mut quote: Option<char> = None;
    let mut chars = s.chars();
    while let Some(c) = chars.next() {
        match (quote, c) {
            (Some(q), c) if c == q => quote = None,
            (Some(_), c) => cur.push(c),
            (None, '\'' | '"') => {
                quote = Some(c);
                any = true;
            }
            (None, '\\') => {
                cur.extend(chars.next());
                any = true;
            }
            (None, c) if c.is_whitespace() => {
                if any || !cur.is_empty() {
                    out.push(std::mem::take(&mut cur));
                    any = false;
                }
            }
            (None, c) => cur.push(c),
        }
    }
    if let Some(q) = quote {
        return Err(format!("unclosed {q} in the options"));
    }
    if any || !cur.is_empty() {
        out.push(cur);
    }
    Ok(out)
}

/// A value of an option as a spec's: a whole number, a number, or text.
fn value_of(v: &str) -> serde_json::Value {
    if let Ok(i) = v.parse::<i64>() {
        return i.into();
    }
    match v.parse::<f64>() {
        Ok(x) if x.is_finite() => x.into(),
        _ => v.into(),
    }
}

/// Sets `value` at the dotted `path` of the JSON object `root`.
fn put(root: &mut serde_json::Value, path: &str, value: serde_json::Value) {
    let mut at = root;
    let parts: Vec<&str> = path.split('.').collect();
    for (i, k) in parts.iter().enumerate() {
        let map = at.as_object_mut().expect("spec tables are objects");
        if i + 1 == parts.len() {
            map.insert((*k).to_string(), value);
            return;
        }
        at = map
            .entry((*k).to_string())
            .or_insert_with(|| serde_json::json!({}));
    }
}

/// Appends `value` to the list at the dotted `path` of `root`.
fn push(root: &mut serde_json::Value, path: &str, value: serde_json::Value) {
    let mut list = root
        .pointer(&format!("/{}", path.replace('.', "/")))
        .cloned()
        .unwrap_or_else(|| serde_json::json!([]));
    if let Some(l) = list.as_array_mut() {
        l.push(value);
    }
    put(root, path, list);
}

/// The calibration spec of one CSV row: `robot`, `data` and the options (calibrate's flags, see
/// [`CALIBRATE_FLAGS`]), every path taken relative to the manifest's folder `dir`; over the
/// spec file its `--spec` names, if any. An error names the option.
fn row_job(
    dir: &Path,
    robot: &str,
    data: &str,
    options: &[String],
) -> std::result::Result<Job, String> {
    let mut row = RowSpec::new(robot, data);
    let mut i = 0;
    while i < options.len() {
        let opt = options[i].as_str();
        let (flag, inline, sets) = option(opt)?;
        i += 1;
        if let Sets::Candidates = sets {
            // Every value up to the next option.
            let mut list = Vec::new();
            if let Some(v) = &inline {
                list.push(serde_json::Value::from(v.as_str()));
            }
            while let Some(v) = options.get(i).filter(|v| !v.starts_with("--")) {
                list.push(v.as_str().into());
                i += 1;
            }
            put(&mut row.spec, "validation.choose", list.into());
            continue;
        }
        let value = match (&sets, inline) {
            (Sets::Flag(_), _) => String::new(),
            (_, Some(v)) => v,
            (_, None) => {
                let v = options
                    .get(i)
                    .ok_or_else(|| format!("{flag}: a value is expected"))?
                    .clone();
                i += 1;
                v
            }
        };
        row.set(flag, sets, value)?;
    }
    let RowSpec { spec, base, .. } = row;
    let row = Job::from_value(spec, "options")
        .map_err(|e| word_row_error(&e))?
        .rebased(dir);
    match base {
        None => Ok(row),
        Some(path) => over_spec_file(dir, &path, row),
    }
}

/// An option of a row: its flag (`-v` and `-q` spelled out), its value when given inline
/// (`--estimate=all`), and what it sets; an option that is not calibrate's, or not a robot's
/// in a batch, is refused.
fn option(opt: &str) -> std::result::Result<(&str, Option<String>, Sets), String> {
    let (flag, inline) = match opt.split_once('=') {
        Some((f, v)) if f.starts_with("--") => (f, Some(v.to_string())),
        _ => (opt, None),
    };
    let flag = match flag {
        "-v" => "--verbose",
        "-q" => "--quiet",
        f => f,
    };
    if NOT_PER_ROBOT.contains(&flag) {
        return Err(format!(
            "{flag} is not a per-robot option here (the robot is the row's; `kinecal batch \
             --record` records every robot under its serial)"
        ));
    }
    let Some(&(_, sets)) = CALIBRATE_FLAGS.iter().find(|(f, _)| *f == flag) else {
        return Err(format!(
            "unknown option `{opt}` (calibrate's options: see kinecal calibrate --help)"
        ));
    };
    Ok((flag, inline, sets))
}

/// A row's calibration spec as its options build it (JSON, a spec's keys).
struct RowSpec {
    spec: serde_json::Value,
    /// The spec file `--spec` names, the row's options over it.
    base: Option<String>,
    /// Observation files so far.
    files: usize,
}

impl RowSpec {
    /// The spec of `robot` calibrated on `data` (none when empty).
    fn new(robot: &str, data: &str) -> RowSpec {
        let mut row = RowSpec {
            spec: serde_json::json!({ "robot": robot }),
            base: None,
            files: 0,
        };
        if !data.is_empty() {
            push(
                &mut row.spec,
                "observations",
                serde_json::json!({ "file": data, "kind": "data" }),
            );
            row.files += 1;
        }
        row
    }

    /// What option `flag` sets, to `value` (empty for a flag without one).
    fn set(&mut self, flag: &str, sets: Sets, value: String) -> std::result::Result<(), String> {
        let spec = &mut self.spec;
        match sets {
            Sets::Value("") => self.base = Some(value),
            Sets::Value(path) => put(spec, path, value_of(&value)),
            Sets::Flag(path) => put(spec, path, true.into()),
            Sets::File(kind) => {
                if self.files == 0 || !spec["observations"].is_array() {
                    put(spec, "observations", serde_json::json!([]));
                }
                push(
                    spec,
                    "observations",
                    serde_json::json!({ "file": value, "kind": kind }),
                );
                self.files += 1;
            }
            Sets::Validate => push(
                spec,
                "validation.files",
                serde_json::json!({ "file": value }),
            ),
            Sets::Column => push(spec, "read.columns", value.into()),
            Sets::LengthAngle(path) => {
                let la = kinecal::spec::LengthAngle::parse(&value, kinecal::Setting::Weights)
                    .map_err(|e| format!("{flag}: {}", message_of(&e)))?;
                put(spec, path, serde_json::to_value(la).expect("plain data"));
            }
            Sets::Candidates => unreachable!("the candidates are read with the options"),
        }
        Ok(())
    }
}

/// The row's options over its spec file's (at `path` in `dir`), as `calibrate --spec` reads
/// them (each file's paths taken from its own folder).
fn over_spec_file(dir: &Path, path: &str, row: Job) -> std::result::Result<Job, String> {
    let file = dir.join(path);
    let over = Job::read(&file).map_err(|e| format!("--spec {path}: {e}"))?;
    if !matches!(over, Job::Calibrate(_)) {
        return Err(format!("--spec {path}: not a calibration spec"));
    }
    let value = |j: &Job| -> serde_json::Value {
        serde_json::from_str(&j.to_json()).expect("a spec's JSON reads back")
    };
    let mut merged = value(&over);
    merge_json(&mut merged, &value(&row));
    Job::from_value(merged, "options").map_err(|e| word_row_error(&e))
}

/// Deep-merges `over` into `base` (objects key by key, other values replaced).
fn merge_json(base: &mut serde_json::Value, over: &serde_json::Value) {
    match (base, over) {
        (serde_json::Value::Object(b), serde_json::Value::Object(o)) => {
            for (k, v) in o {
                merge_json(b.entry(k.clone()).or_insert(serde_json::Value::Null), v);
            }
        }
        (b, o) => *b = o.clone(),
    }
}

/// An error's message without its place (the row is named by the caller).
fn message_of(e: &kinecal::Error) -> String {
    match e {
        kinecal::Error::InvalidOption { message, .. } | kinecal::Error::Input { message, .. } => {
            message.clone()
        }
        e => e.to_string(),
    }
}

/// A spec error of a row's options, the key named as the option that set it.
fn word_row_error(e: &kinecal::Error) -> String {
    if let kinecal::Error::Input { at, message } = e {
        if let Some(field) = &at.field {
            let flag = CALIBRATE_FLAGS
                .iter()
                .find(|(_, s)| match s {
                    Sets::Value(p) | Sets::Flag(p) | Sets::LengthAngle(p) => {
                        !p.is_empty() && field.starts_with(p)
                    }
                    _ => false,
                })
                .map(|(f, _)| *f);
            return match flag {
                Some(f) => format!("{f}: {message}"),
                None => format!("{field}: {message}"),
            };
        }
        return message.clone();
    }
    e.to_string()
}

/// Deep-merges `over` into `base` (tables merged key by key, other values replaced).
fn merge_tables(base: &mut toml_edit::Table, over: &toml_edit::Table) {
    for (k, v) in over.iter() {
        match (base.get_mut(k), v) {
            (Some(toml_edit::Item::Table(b)), toml_edit::Item::Table(o)) => merge_tables(b, o),
            _ => {
                base.insert(k, v.clone());
            }
        }
    }
}

/// Takes a string key out of `table`, for an entry at `at`.
/// A compensation job writing a controller program takes the job's name (`label`) as its
/// program's too, as its spec run alone does (a KRL module's DEF, a RAPID module, a TP
/// program); other jobs keep it as their label alone.
fn name_the_program(table: &mut toml_edit::Table, kind: &str, label: Option<&str>) {
    let controller = ["krl", "rapid", "tp"]
        .contains(&table.get("format").and_then(|f| f.as_str()).unwrap_or(""));
    if let (true, true, Some(l)) = (kind == "compensate", controller, label) {
        table.insert("name", toml_edit::value(l));
    }
}

fn take_string(table: &mut toml_edit::Table, key: &str, at: &str) -> Result<Option<String>> {
    match table.remove(key) {
        Some(v) => {
            Ok(Some(v.as_str().map(str::to_string).ok_or_else(|| {
                anyhow!("{at}: `{key}` must be a string")
            })?))
        }
        None => Ok(None),
    }
}

/// The job of one table: its spec read (paths from the manifest's folder), or why not.
fn table_job(table: toml_edit::Table, dir: &Path, at: &str) -> std::result::Result<Job, String> {
    let text = toml_edit::DocumentMut::from(table).to_string();
    // The failure is said after `at` (the manifest and the entry): the message only (a line
    // would count in the merged table, not in the manifest).
    Job::from_toml(&text, at)
        .map(|j| j.rebased(dir))
        .map_err(|e| match e {
            kinecal::Error::Input { message, at } => match at.field {
                Some(f) => format!("{f}: {message}"),
                None => message,
            },
            e => e.to_string(),
        })
}

/// The jobs of a TOML manifest: a `[[robots]]` table per robot (a calibration spec with its
/// `serial`, over the `[defaults]` table every robot shares), and `[[jobs]]` tables, each a
/// spec of any job (`job = "analyze"`, ...; a calibration when absent) with an optional `name`
/// (a calibration's `serial` records it with `--record`).
fn toml_jobs(doc: &toml_edit::DocumentMut, dir: &Path, name: &str) -> Result<Vec<Entry>> {
    if doc.get("job").is_some() || doc.get("robot").is_some_and(|r| !r.is_array_of_tables()) {
        let job = doc
            .get("job")
            .and_then(|j| j.as_str())
            .unwrap_or("calibrate");
        bail!(
            "{name}: a spec of one job, not a batch manifest: run it with `kinecal {job} --spec \
             {name}`, or list it in a manifest as a `[[jobs]]` table (see docs/spec.md)"
        );
    }
    if doc.get("robot").is_some() {
        bail!(
            "{name}: `[[robot]]` tables with `options` are no longer read: write each robot as a \
             `[[robots]]` table holding its calibration spec and `serial` (see docs/spec.md), \
             or use a CSV manifest"
        );
    }
    for key in doc.iter().map(|(k, _)| k) {
        if !["defaults", "robots", "jobs"].contains(&key) {
            bail!("{name}: unknown key `{key}` (expected [defaults], [[robots]] and [[jobs]])");
        }
    }
    let defaults = match doc.get("defaults") {
        None => toml_edit::Table::new(),
        Some(d) => d
            .as_table()
            .cloned()
            .ok_or_else(|| anyhow!("{name}: `defaults` must be a table"))?,
    };
    let tables = |key: &str| -> Result<Vec<toml_edit::Table>> {
        match doc.get(key) {
            None => Ok(Vec::new()),
            Some(item) => Ok(item
                .as_array_of_tables()
                .ok_or_else(|| anyhow!("{name}: `{key}` must be [[{key}]] tables"))?
                .iter()
                .cloned()
                .collect()),
        }
    };
    let (robots, jobs) = (tables("robots")?, tables("jobs")?);
    if robots.is_empty() && jobs.is_empty() {
        bail!("{name}: no [[robots]] or [[jobs]] tables");
    }
    let mut entries = Vec::new();
    for (k, t) in robots.iter().enumerate() {
        let mut at = format!("{name}: robot {}", k + 1);
        let mut table = defaults.clone();
        merge_tables(&mut table, t);
        if table
            .get("job")
            .is_some_and(|j| j.as_str() != Some("calibrate"))
        {
            bail!("{at}: a [[robots]] table is a calibration: write other jobs as [[jobs]]");
        }
        let Some(serial) = take_string(&mut table, "serial", &at)? else {
            bail!("{at}: `serial` is required");
        };
        if serial.is_empty() {
            bail!("{at}: the serial is empty");
        }
        bounded(&at, "serial", &serial)?;
        at = format!("{at} ({serial})");
        let job = table_job(table, dir, &at);
        entries.push(Entry { serial, at, job });
    }
    for (k, t) in jobs.iter().enumerate() {
        let mut at = format!("{name}: job {}", k + 1);
        let mut table = t.clone();
        let serial = take_string(&mut table, "serial", &at)?;
        let label = take_string(&mut table, "name", &at)?;
        let kind = table
            .get("job")
            .and_then(|j| j.as_str())
            .unwrap_or("calibrate")
            .to_string();
        if serial.is_some() && kind != "calibrate" {
            bail!("{at}: a serial names a robot whose calibration is recorded: give other jobs a `name`");
        }
        name_the_program(&mut table, &kind, label.as_deref());
        let label = serial
            .or(label)
            .unwrap_or_else(|| format!("{kind} {}", k + 1));
        if label.is_empty() {
            bail!("{at}: the name is empty");
        }
        bounded(&at, "serial or name", &label)?;
        at = format!("{at} ({label})");
        let job = table_job(table, dir, &at);
        entries.push(Entry {
            serial: label,
            at,
            job,
        });
    }
    Ok(entries)
}

/// Refuses a serial (or a job's name) longer than a history records and its tables draw
/// ([`kinecal::spec::limits::MAX_SERIAL_CHARS`]), naming the manifest's row and `key`.
fn bounded(at: &str, key: &str, serial: &str) -> Result<()> {
    kinecal::spec::limits::serial(kinecal::Setting::RobotId, serial)
        .map_err(|e| anyhow!("{at}: {key}: {}", message_of(&e)))
}

/// Reads the manifest (CSV, or TOML by its `.toml` extension).
fn read_manifest(path: &Path) -> Result<Vec<Entry>> {
    let source = kinecal::source::Source::read(path)?;
    let dir = path.parent().unwrap_or(Path::new(""));
    let name = path.display().to_string();
    let mut entries = Vec::new();
    let is_toml = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("toml"));
    if is_toml {
        let doc: toml_edit::DocumentMut = source
            .text
            .parse()
            .map_err(|e: toml_edit::TomlError| anyhow!("{name}: {}", e.to_string().trim()))?;
        entries = toml_jobs(&doc, dir, &name)?;
    } else {
        let mut rdr = csv::ReaderBuilder::new()
            .comment(Some(b'#'))
            .trim(csv::Trim::All)
            .flexible(false)
            .from_reader(source.text.as_bytes());
        let header: Vec<String> = rdr
            .headers()
            .map_err(|e| anyhow!("{name}: {e}"))?
            .iter()
            .map(|h| h.trim_start_matches('\u{feff}').to_ascii_lowercase())
            .collect();
        let col = |c: &str| header.iter().position(|h| h == c);
        if let Some(extra) = header
            .iter()
            .find(|h| !["serial", "robot", "data", "options"].contains(&h.as_str()))
        {
            bail!("{name}:1: unknown column `{extra}` (expected serial, robot, data, options)");
        }
        let (Some(s), Some(r)) = (col("serial"), col("robot")) else {
            bail!(
                "{name}:1: expected the header serial,robot,data[,options], found `{}`",
                header.join(",")
            );
        };
        let (d, o) = (col("data"), col("options"));
        for rec in rdr.records() {
            let rec = rec.map_err(|e| anyhow!("{name}: {e}"))?;
            let line = rec.position().map_or(0, |p| p.line());
            let at = format!("{name}:{line}");
            let get = |i: Option<usize>| i.and_then(|i| rec.get(i)).unwrap_or("").to_string();
            let serial = get(Some(s));
            if serial.is_empty() {
                bail!("{at}: the serial is empty");
            }
            bounded(&at, "serial", &serial)?;
            let job =
                split_options(&get(o)).and_then(|opts| row_job(dir, &get(Some(r)), &get(d), &opts));
            entries.push(Entry { serial, at, job });
        }
    }
    if entries.is_empty() {
        bail!("{name}: no robots or jobs listed");
    }
    let mut serials: Vec<&str> = entries.iter().map(|e| e.serial.as_str()).collect();
    serials.sort_unstable();
    if let Some(w) = serials.windows(2).find(|w| w[0] == w[1]) {
        bail!(
            "{name}: `{}` listed twice (each robot's serial, each job's name once)",
            w[0]
        );
    }
    Ok(entries)
}

/// Who reads or writes a file of the batch.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Owner {
    /// The robot of this manifest entry.
    Row(usize),
    Manifest,
    Summary,
    Database,
}

/// One file the batch reads or writes.
struct BatchFile {
    id: output::Identity,
    shown: PathBuf,
    owner: Owner,
    writes: bool,
}

/// Refuses, before anything runs, an output that is a file another robot reads or writes, the
/// manifest, the summary or the history database: every path is resolved (canonical folder,
/// links followed; device and inode compared), so `r.json`, `./r.json` and a link to it are one
/// file. One robot's own outputs over its own inputs are refused with that robot alone, as
/// `calibrate` refuses them. Outputs written in place (devices, FIFOs, standard output) are
/// not compared.
fn check_files(
    entries: &[Entry],
    manifest: &Path,
    summary: Option<&Path>,
    db: Option<&Path>,
) -> Result<()> {
    let mut files: Vec<BatchFile> = Vec::new();
    let mut add = |p: &Path, owner: Owner, writes: bool| {
        if let Some(id) = output::identity(p) {
            files.push(BatchFile {
                id,
                shown: p.to_path_buf(),
                owner,
                writes,
            });
        }
    };
    add(manifest, Owner::Manifest, false);
    for (k, e) in entries.iter().enumerate() {
        if let Ok(spec) = &e.job {
            for p in spec.inputs() {
                add(&p, Owner::Row(k), false);
            }
            for p in spec.outputs() {
                add(&p, Owner::Row(k), true);
            }
        }
    }
    if let Some(p) = summary {
        add(p, Owner::Summary, true);
    }
    if let Some(p) = db {
        add(p, Owner::Database, true);
    }
    let row = |k: usize| format!("{} ({})", entries[k].serial, entries[k].at);
    for (j, b) in files.iter().enumerate() {
        for a in &files[..j] {
            if a.owner == b.owner || !(a.writes || b.writes) || a.id != b.id {
                continue;
            }
            // Named from the writer's side (the later one when both write).
            let (w, other) = if b.writes { (b, a) } else { (a, b) };
            let who = match w.owner {
                Owner::Row(k) => format!("{}: the output {}", entries[k].at, w.shown.display()),
                Owner::Summary => format!("--summary {}", w.shown.display()),
                Owner::Database => format!("the history database {}", w.shown.display()),
                Owner::Manifest => unreachable!("the manifest is only read"),
            };
            let what = match (other.owner, other.writes) {
                (Owner::Row(k), true) => format!("is also written for {}", row(k)),
                (Owner::Row(k), false) => format!("is an input of {}", row(k)),
                (Owner::Manifest, _) => "is the manifest itself".to_string(),
                (Owner::Summary, _) => "is also the --summary".to_string(),
                (Owner::Database, _) => "is the history database".to_string(),
            };
            bail!(
                "{who} {what}: each output must be a file of its own, that nothing else in the \
                 batch reads or writes"
            );
        }
    }
    Ok(())
}

/// The summary figures of one calibration.
fn figures(serial: &str, status: Status, o: &Outcome) -> Row {
    let robot = &o.nominal;
    let l = |v: f64| robot.units.from_si(Quantity::Length, v);
    let (b, a) = (&o.identification.before, &o.identification.after);
    let rms = if b.positions > 0 {
        Some((l(b.rms_position), l(a.rms_position), "position"))
    } else {
        b.other
            .first()
            .zip(a.other.first())
            .map(|(x, y)| (l(x.rms), l(y.rms), x.metric))
    };
    let mean = |acc: &kinecal::observe::Accuracy| {
        if acc.positions > 0 {
            Some(acc.mean_position)
        } else {
            acc.other.first().map(|m| m.mean)
        }
    };
    let held_out = o
        .validation
        .as_ref()
        .and_then(|v| mean(&v.after))
        .or_else(|| o.cross_validation.as_ref().map(|c| c.overall.mean))
        .map(l);
    Row {
        serial: serial.to_string(),
        status,
        parameters: Some(o.calibration.estimated.len()),
        iterations: Some(o.calibration.iterations),
        rms,
        held_out,
        unit: robot.units.length.as_str().to_string(),
        warnings: o.warnings.iter().map(crate::word).collect(),
        implausible: o
            .warnings
            .iter()
            .filter(|w| w.implausible())
            .map(crate::word)
            .collect(),
    }
}

fn failed(serial: &str, e: String) -> Row {
    Row {
        serial: serial.to_string(),
        status: Status::Failed(e),
        parameters: None,
        iterations: None,
        rms: None,
        held_out: None,
        unit: String::new(),
        warnings: Vec::new(),
        implausible: Vec::new(),
    }
}

/// A finished job: a calibration waiting to be recorded and have its outputs put in place.
struct Finished {
    row: Row,
    pending: Option<Pending>,
    report: Option<kinecal::report::CalibrationReport>,
    /// The job's document (JSON).
    document: Option<String>,
}

/// Runs one job (a calibration's outputs held).
fn run_one(e: &Entry) -> Finished {
    let job = match &e.job {
        Ok(j) => j,
        Err(msg) => {
            return Finished {
                row: failed(&e.serial, format!("{}: {msg}", e.at)),
                pending: None,
                report: None,
                document: None,
            }
        }
    };
    let run = || -> Result<Finished> {
        let artist = kinecal_report::Artist;
        let mut quiet = ();
        let mut env = Env::new(&mut quiet, Some(&artist));
        env.hold = true;
        env.historian = Some(&crate::door::HISTORIAN);
        let done = kinecal::spec::run(job, &mut env)?;
        let status = Status::of(done.status);
        let document = Some(done.document.to_json());
        // A job other than a calibration: its warnings are the row's (what it flagged).
        let said: Vec<String> = done
            .messages
            .iter()
            .filter_map(|m| match m {
                kinecal::spec::Message::Warning(w) => Some(w.to_string()),
                kinecal::spec::Message::Caution(c) => Some(c.clone()),
                _ => None,
            })
            .collect();
        Ok(match done.document {
            Document::Calibration(o) => Finished {
                row: figures(&e.serial, status, &o),
                pending: done.pending,
                report: Some(o.report),
                document,
            },
            _ => Finished {
                row: Row {
                    status,
                    warnings: said,
                    ..failed(&e.serial, String::new())
                },
                pending: done.pending,
                report: None,
                document,
            },
        })
    };
    run().unwrap_or_else(|err| Finished {
        row: failed(&e.serial, crate::in_flags(&err)),
        pending: None,
        report: None,
        document: None,
    })
}

fn fmt(v: Option<f64>) -> String {
    v.map(|v| format!("{v:.6}")).unwrap_or_else(|| "-".into())
}

/// The summary as text.
fn table(rows: &[Row]) -> String {
    use std::fmt::Write as _;
    // Padded by hand: a format width is at most 65,535 (a longer serial panics in `{:<w$}`).
    let w = rows
        .iter()
        .map(|r| r.serial.chars().count())
        .max()
        .unwrap_or(6)
        .max(6);
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{}  {:>6} {:>5} {:>12} {:>12} {:>12} {:>4} {:>8}  status",
        crate::render::pad_right("serial", w),
        "params",
        "iter",
        "rms before",
        "rms after",
        "held out",
        "unit",
        "warnings"
    );
    for r in rows {
        let _ = writeln!(
            s,
            "{}  {:>6} {:>5} {:>12} {:>12} {:>12} {:>4} {:>8}  {}{}",
            crate::render::pad_right(&r.serial, w),
            r.parameters.map_or("-".into(), |v| v.to_string()),
            r.iterations.map_or("-".into(), |v| v.to_string()),
            fmt(r.rms.map(|x| x.0)),
            fmt(r.rms.map(|x| x.1)),
            fmt(r.held_out),
            if r.unit.is_empty() { "-" } else { &r.unit },
            r.warnings.len(),
            r.status.word(),
            r.rms
                .filter(|x| x.2 != "position")
                .map(|x| format!(" ({} errors)", x.2))
                .unwrap_or_default()
        );
    }
    s
}

/// The summary as CSV.
fn summary_csv(rows: &[Row]) -> Result<String> {
    let mut w = csv::Writer::from_writer(Vec::new());
    w.write_record([
        "serial",
        "status",
        "parameters",
        "iterations",
        "metric",
        "unit",
        "rms_before",
        "rms_after",
        "held_out_mean",
        "warnings",
    ])?;
    for r in rows {
        let status = match &r.status {
            Status::Ok => "ok".to_string(),
            Status::NotConverged => "not converged".into(),
            Status::Flagged(_) => "flagged".into(),
            Status::Failed(_) => "failed".into(),
        };
        let detail = match &r.status {
            Status::Failed(e) => e.clone(),
            _ => r.warnings.join(" | "),
        };
        w.write_record([
            r.serial.clone(),
            status,
            r.parameters.map_or(String::new(), |v| v.to_string()),
            r.iterations.map_or(String::new(), |v| v.to_string()),
            r.rms.map_or(String::new(), |x| x.2.to_string()),
            r.unit.clone(),
            r.rms.map_or(String::new(), |x| x.0.to_string()),
            r.rms.map_or(String::new(), |x| x.1.to_string()),
            r.held_out.map_or(String::new(), |v| v.to_string()),
            detail,
        ])?;
    }
    Ok(String::from_utf8(
        w.into_inner().map_err(|e| anyhow!("{e}"))?,
    )?)
}

/// A serial or a job's name as a file name: letters, digits, `.`, `_` and `-` kept, the rest
/// written `_`.
fn file_name(name: &str) -> String {
    name.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || matches!(c, '.' | '_' | '-') {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// Parses `--shard K/N`.
fn parse_shard(s: &str) -> Result<(usize, usize)> {
    let bad =
        || anyhow!("--shard `{s}`: expected K/N with 1 <= K <= N (the K-th of N shares), e.g. 3/8");
    let (k, n) = s.split_once('/').ok_or_else(bad)?;
    let (k, n): (usize, usize) = (
        k.trim().parse().map_err(|_| bad())?,
        n.trim().parse().map_err(|_| bad())?,
    );
    if k == 0 || n == 0 || k > n {
        return Err(bad());
    }
    Ok((k, n))
}

/// The K-th of N shares of the manifest's robots: rows K, K+N, K+2N, ... (1-based), so the N
/// shares are disjoint, cover the manifest, and differ in size by one at most.
fn shard<T>(entries: Vec<T>, k: usize, n: usize) -> Vec<T> {
    entries
        .into_iter()
        .enumerate()
        .filter(|(i, _)| i % n == k - 1)
        .map(|(_, e)| e)
        .collect()
}

/// Runs `kinecal batch`: the manifest's entries (this shard's), every job in parallel, then
/// one writer records and puts outputs in place in manifest order; the table, the summary, the
/// exit code.
pub fn run(a: BatchArgs) -> Result<u8> {
    let entries = entries(&a)?;
    let calibrations_only = entries
        .iter()
        .all(|e| matches!(e.job, Ok(Job::Calibrate(_)) | Err(_)));
    if let Some(dir) = &a.documents {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    let db = if a.record {
        Some(history::open_db(a.db.as_deref())?)
    } else {
        None
    };
    let done = run_all(&entries, a.jobs, a.quiet)?;
    let rows = put_in_place(done, db.as_ref(), a.documents.as_deref())?;
    print!("{}", table(&rows));
    for r in &rows {
        for w in &r.implausible {
            println!("{}: {w}", r.serial);
        }
    }
    if let Some(path) = &a.summary {
        output::write_file(path, &summary_csv(&rows)?)?;
        eprintln!("wrote the summary to {}", path.display());
    }
    Ok(exit_code(&rows, calibrations_only))
}

/// The manifest's entries, its files checked first (no output over an input, no two entries
/// writing one file); with `--shard K/N`, the K-th share.
fn entries(a: &BatchArgs) -> Result<Vec<Entry>> {
    let shard_of = a.shard.as_deref().map(parse_shard).transpose()?;
    let entries = read_manifest(&a.manifest)?;
    let db_file = history::db_file(a.db.as_deref()).filter(|_| a.record);
    check_files(
        &entries,
        &a.manifest,
        a.summary.as_deref(),
        db_file.as_deref(),
    )?;
    let Some((k, n)) = shard_of else {
        return Ok(entries);
    };
    let total = entries.len();
    let entries = shard(entries, k, n);
    eprintln!(
        "shard {k}/{n}: {} of the manifest's {total} robots",
        entries.len()
    );
    // More shares than robots (an indexed job with more completions than robots): the extra
    // shares succeed with nothing to do, so that the job as a whole does.
    if entries.is_empty() {
        eprintln!("shard {k}/{n} of {total} robots is empty: nothing to do");
    }
    Ok(entries)
}

/// The most robots calibrated at once, per core: a calibration keeps its core busy, so more
/// only hold more data in memory (a larger `--jobs` runs this many, with a note).
const JOBS_PER_CORE: usize = 2;

/// Runs every entry on `jobs` threads (default: one per core; at most [`JOBS_PER_CORE`] per
/// core), a progress bar on standard error unless `quiet`; the finished jobs in manifest
/// order.
fn run_all(entries: &[Entry], jobs: Option<usize>, quiet: bool) -> Result<Vec<Finished>> {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let jobs = match jobs {
        Some(0) => bail!("--jobs must be at least 1"),
        Some(n) if n > cores * JOBS_PER_CORE => {
            eprintln!(
                "--jobs {n}: running {} at once ({JOBS_PER_CORE} per core of this machine's \
                 {cores}): more calibrations at once hold more memory and finish no sooner",
                cores * JOBS_PER_CORE
            );
            cores * JOBS_PER_CORE
        }
        Some(n) => n,
        None => cores,
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(jobs)
        .build()
        .context("cannot start the worker threads")?;
    let bar = ProgressBar::with_draw_target(
        Some(entries.len() as u64),
        if quiet {
            ProgressDrawTarget::hidden()
        } else {
            ProgressDrawTarget::stderr()
        },
    );
    bar.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} robots, {elapsed} ({msg})")
            .expect("a valid template"),
    );
    let failures = AtomicUsize::new(0);
    let done: Vec<Finished> = pool.install(|| {
        entries
            .par_iter()
            .map(|e| {
                let d = run_one(e);
                if matches!(d.row.status, Status::Failed(_)) {
                    failures.fetch_add(1, Ordering::Relaxed);
                }
                bar.set_message(format!("{} failed", failures.load(Ordering::Relaxed)));
                bar.inc(1);
                d
            })
            .collect()
    });
    bar.finish_and_clear();
    Ok(done)
}

/// One writer, in manifest order: each job's document in `documents`, its calibration
/// recorded in `db` (one transaction per record; a record already there, from a rerun after an
/// interrupted batch or another shard's retry, is found by its key and not written twice), then
/// its outputs put in place. The summary's rows, a failure to record or write in its row.
fn put_in_place(
    done: Vec<Finished>,
    db: Option<&kinecal_history::Database>,
    documents: Option<&Path>,
) -> Result<Vec<Row>> {
    let mut rows = Vec::with_capacity(done.len());
    let mut staged = output::Staged::new();
    for d in done {
        let Finished {
            mut row,
            pending,
            report,
            document,
        } = d;
        if let (Some(dir), Some(doc)) = (documents, &document) {
            staged.text(
                &dir.join(file_name(&row.serial) + ".json"),
                &(doc.clone() + "\n"),
            )?;
        }
        let recorded = match (db, &report) {
            (Some(db), Some(rep)) => db
                .record(&row.serial, None, rep, "", Default::default())
                .map(|_| ())
                .map_err(|e| format!("not recorded: {e}")),
            _ => Ok(()),
        };
        match (recorded, pending) {
            (Err(e), _) => row.status = Status::Failed(e),
            (Ok(()), Some(s)) => {
                if let Err(e) = s.commit() {
                    row.status = Status::Failed(e.to_string());
                }
            }
            (Ok(()), None) => {}
        }
        rows.push(row);
    }
    staged.commit()?;
    if let Some(dir) = documents {
        eprintln!("wrote the documents to {}", dir.display());
    }
    Ok(rows)
}

/// The count of each ending (on standard error), and the exit code: 1 when any failed, else
/// [`EXIT_FLAGGED`] when any was flagged, else [`EXIT_NOT_CONVERGED`] when any did not
/// converge, else 0.
fn exit_code(rows: &[Row], calibrations_only: bool) -> u8 {
    let count = |f: fn(&Status) -> bool| rows.iter().filter(|r| f(&r.status)).count();
    let (failed, flagged, unconverged) = (
        count(|s| matches!(s, Status::Failed(_))),
        count(|s| matches!(s, Status::Flagged(_))),
        count(|s| matches!(s, Status::NotConverged)),
    );
    let (what, done) = if calibrations_only {
        ("robots", "calibrated")
    } else {
        ("jobs", "done")
    };
    eprintln!(
        "{} {what}: {} {done}, {failed} failed, {flagged} flagged, {unconverged} not converged",
        rows.len(),
        rows.len() - failed - flagged
    );
    if failed > 0 {
        1
    } else if flagged > 0 {
        EXIT_FLAGGED
    } else if unconverged > 0 {
        EXIT_NOT_CONVERGED
    } else {
        0
    }
}

#[cfg(test)]
mod tests {
    use crate::fuzz_driver::{fuzz, Outcome};

    /// Manifests (issue 38), CSV and TOML: a mutated manifest is read as `batch` reads it (no
    /// panic, no hang, a refusal that names the manifest); an accepted one lists at most as
    /// many entries as it has lines (ended by `\n` or `\r`), each serial within the history's
    /// bound.
    fn manifests(target: &str, name: &str, seeds: &[&str]) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(name);
        let shown = path.display().to_string();
        let seeds: Vec<Vec<u8>> = seeds.iter().map(|s| s.as_bytes().to_vec()).collect();
        fuzz(target, &shown, &seeds, &|b| {
            if let Err(e) = std::fs::write(&path, b) {
                return Outcome::Accepted(Err(format!("the manifest could not be written: {e}")));
            }
            match super::read_manifest(&path) {
                Ok(entries) => Outcome::Accepted(
                    if entries.len() <= b.split(|&c| c == b'\n' || c == b'\r').count()
                        && entries.iter().all(|e| {
                            e.serial.chars().count() <= kinecal::spec::limits::MAX_SERIAL_CHARS
                        })
                    {
                        Ok(())
                    } else {
                        Err(format!(
                            "{} entries, or a serial beyond the bound",
                            entries.len()
                        ))
                    },
                ),
                Err(e) => Outcome::Refused(format!("{e:#}")),
            }
        });
    }

    #[test]
    fn csv_manifests() {
        manifests(
            "batch manifest csv",
            "robots.csv",
            &[
                "serial,robot,data,options\nR1,ge-a4,r1.csv,--estimate identifiable\nR2,ge-a4,r2.csv,\n",
                "# a fleet\nserial,robot,data\nA-7,robot.toml,a7.csv\n",
            ],
        );
    }

    #[test]
    fn toml_manifests() {
        manifests(
            "batch manifest toml",
            "jobs.toml",
            &[
                "[[jobs]]\nname = \"R1\"\njob = \"calibrate\"\nrobot = \"ge-a4\"\n\n[[jobs.observations]]\nfile = \"r1.csv\"\n",
                "[[jobs]]\nname = \"plan\"\njob = \"plan\"\nrobot = \"ge-a4\"\nsample = 150\ncount = 6\n",
            ],
        );
    }
}
