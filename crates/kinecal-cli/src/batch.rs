//! `kinecal batch`: calibrate every robot of a manifest, in parallel (the fleet case).
//!
//! Each robot is a calibration spec: a TOML `[[robots]]` table over the `[defaults]` one, or a
//! CSV row's arguments read as `kinecal calibrate` reads them ([`crate::calibrate::spec_of`]).
//! It runs as `calibrate` runs it; its outputs are written when it succeeds, whatever the others
//! do. The calibrations run on a thread pool (`rayon`); recording in the history is done
//! afterwards, in manifest order, by one writer. Before any robot runs, an output that another
//! robot reads or writes, or that is the manifest, the summary or the database, is refused
//! ([`check_files`], paths compared as [`output::identity`] resolves them).

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use anyhow::{anyhow, bail, Context as _, Result};
use clap::Parser as _;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use kinecal::units::Quantity;
use kinecal::workflow::Outcome;
use rayon::prelude::*;

use crate::args::{BatchArgs, Cli, Command};
use crate::calibrate::{prepare, stage_outputs, Prepared};
use crate::{history, output, EXIT_IMPLAUSIBLE, EXIT_NOT_CONVERGED};
use kinecal::spec::CalibrationSpec;

/// One robot of the manifest.
struct Entry {
    serial: String,
    /// Where the row is (`fleet.csv:3`), for messages.
    at: String,
    /// The job (paths relative to the working folder), or why the row cannot be run.
    job: std::result::Result<CalibrationSpec, String>,
    /// `--strict` for this robot.
    strict: bool,
}

/// How one robot's calibration ended.
enum Status {
    Ok,
    NotConverged,
    /// `--strict` and a warning that the result is most likely wrong: nothing written.
    Flagged,
    Failed(String),
}

impl Status {
    fn word(&self) -> String {
        match self {
            Status::Ok => "ok".into(),
            Status::NotConverged => "not converged".into(),
            Status::Flagged => "flagged (--strict): nothing written".into(),
            Status::Failed(e) => format!("failed: {e}"),
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

/// A path of the manifest, relative to its folder.
fn rebase(dir: &Path, p: &Path) -> PathBuf {
    if p.is_absolute() {
        p.to_path_buf()
    } else {
        dir.join(p)
    }
}

/// A robot argument: a built-in name stays, a file is taken relative to the manifest.
fn rebase_robot(dir: &Path, spec: &str) -> String {
    if kinecal::examples::builtin(spec).is_some() {
        spec.to_string()
    } else {
        rebase(dir, Path::new(spec)).to_string_lossy().into_owned()
    }
}

/// The job of one CSV row: `--robot`, `--data` and the options, parsed by the same definitions
/// as `kinecal calibrate`, with every path taken relative to the manifest; and `--strict`.
fn row_job(
    dir: &Path,
    robot: &str,
    data: &str,
    options: &[String],
) -> std::result::Result<(CalibrationSpec, bool), String> {
    let mut argv: Vec<String> = vec!["kinecal".into(), "calibrate".into(), "--robot".into()];
    argv.push(robot.to_string());
    if !data.is_empty() {
        argv.push("--data".into());
        argv.push(data.to_string());
    }
    argv.extend(options.iter().cloned());
    let cli = Cli::try_parse_from(&argv).map_err(|e| {
        e.to_string()
            .lines()
            .next()
            .unwrap_or("invalid options")
            .trim_start_matches("error: ")
            .to_string()
    })?;
    let Command::Calibrate(mut a) = cli.command else {
        unreachable!("the arguments name calibrate")
    };
    for (flag, given) in [
        ("--record", a.record.is_some()),
        ("--db", a.db.is_some()),
        ("--at", a.at.is_some()),
        ("--verbose", a.verbose),
        ("--write-spec", a.write_spec.is_some()),
    ] {
        if given {
            return Err(format!(
                "{flag} is not a per-robot option here: `kinecal batch --record` records every \
                 robot under its serial"
            ));
        }
    }
    a.robot = a.robot.map(|r| rebase_robot(dir, &r));
    a.initial = a.initial.map(|r| rebase_robot(dir, &r));
    for (_, p) in &mut a.observations.files {
        *p = rebase(dir, p);
    }
    for p in a
        .validate
        .iter_mut()
        .chain(&mut a.out)
        .chain(&mut a.report)
        .chain(&mut a.html)
        .chain(&mut a.spec)
    {
        *p = rebase(dir, p);
    }
    let spec = crate::calibrate::spec_of(&a).map_err(|e| crate::in_flags(&e))?;
    Ok((spec, a.strict))
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

/// The jobs of a TOML manifest: a `[[robots]]` table per robot, a calibration spec with its
/// `serial` (and `strict = true` to refuse a result most likely wrong), over the `[defaults]`
/// table every robot shares.
fn toml_jobs(doc: &toml_edit::DocumentMut, dir: &Path, name: &str) -> Result<Vec<Entry>> {
    if doc.get("robot").is_some() {
        bail!(
            "{name}: `[[robot]]` tables with `options` are no longer read: write each robot as a \
             `[[robots]]` table holding its calibration spec and `serial` (see the README's \
             \"The calibration spec\"), or use a CSV manifest"
        );
    }
    for key in doc.iter().map(|(k, _)| k) {
        if !["defaults", "robots"].contains(&key) {
            bail!("{name}: unknown key `{key}` (expected [defaults] and [[robots]])");
        }
    }
    let defaults = match doc.get("defaults") {
        None => toml_edit::Table::new(),
        Some(d) => d
            .as_table()
            .cloned()
            .ok_or_else(|| anyhow!("{name}: `defaults` must be a table"))?,
    };
    let robots = doc
        .get("robots")
        .and_then(|r| r.as_array_of_tables())
        .ok_or_else(|| anyhow!("{name}: no [[robots]] tables"))?;
    let mut entries = Vec::new();
    for (k, t) in robots.iter().enumerate() {
        let mut at = format!("{name}: robot {}", k + 1);
        let mut table = defaults.clone();
        merge_tables(&mut table, t);
        let serial = match table.remove("serial") {
            Some(v) => v
                .as_str()
                .map(str::to_string)
                .ok_or_else(|| anyhow!("{at}: `serial` must be a string"))?,
            None => bail!("{at}: `serial` is required"),
        };
        if serial.is_empty() {
            bail!("{at}: the serial is empty");
        }
        at = format!("{at} ({serial})");
        let strict = match table.remove("strict") {
            Some(v) => v
                .as_bool()
                .ok_or_else(|| anyhow!("{at}: `strict` must be true or false"))?,
            None => false,
        };
        let text = toml_edit::DocumentMut::from(table).to_string();
        // The row's failure is said after `at` (the manifest and the robot): the message only
        // (a line would count in the merged table, not in the manifest).
        let job = CalibrationSpec::from_toml(&text, &at)
            .map(|s| s.rebased(dir))
            .map_err(|e| match e {
                kinecal::Error::Input { message, .. } => message,
                e => e.to_string(),
            });
        entries.push(Entry {
            serial,
            at,
            job,
            strict,
        });
    }
    Ok(entries)
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
            let job =
                split_options(&get(o)).and_then(|opts| row_job(dir, &get(Some(r)), &get(d), &opts));
            let strict = job.as_ref().is_ok_and(|j| j.1);
            entries.push(Entry {
                serial,
                at,
                job: job.map(|j| j.0),
                strict,
            });
        }
    }
    if entries.is_empty() {
        bail!("{name}: no robots listed");
    }
    let mut serials: Vec<&str> = entries.iter().map(|e| e.serial.as_str()).collect();
    serials.sort_unstable();
    if let Some(w) = serials.windows(2).find(|w| w[0] == w[1]) {
        bail!("{name}: serial `{}` listed twice", w[0]);
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
fn figures(serial: &str, status: Status, p: &Prepared, o: &Outcome) -> Row {
    let robot = &p.job.request.robot;
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

/// A calibrated robot waiting to be recorded and have its outputs put in place.
struct Done {
    row: Row,
    staged: Option<output::Staged>,
    report: Option<kinecal::report::CalibrationReport>,
}

/// Calibrates one robot and stages its outputs.
fn calibrate_one(e: &Entry) -> Done {
    let spec = match &e.job {
        Ok(s) => s,
        Err(msg) => {
            return Done {
                row: failed(&e.serial, format!("{}: {msg}", e.at)),
                staged: None,
                report: None,
            }
        }
    };
    let run = || -> Result<Done> {
        let p = prepare(spec, None)?;
        let o = p.job.run(&mut ())?;
        let implausible = o.warnings.iter().any(|w| w.implausible());
        if e.strict && implausible {
            return Ok(Done {
                row: figures(&e.serial, Status::Flagged, &p, &o),
                staged: None,
                report: None,
            });
        }
        let mut staged = output::Staged::new();
        stage_outputs(&p, &o, &mut staged)?;
        let status = if o.calibration.converged() {
            Status::Ok
        } else {
            Status::NotConverged
        };
        Ok(Done {
            row: figures(&e.serial, status, &p, &o),
            staged: Some(staged),
            report: Some(o.report),
        })
    };
    run().unwrap_or_else(|err| Done {
        row: failed(&e.serial, format!("{err:#}")),
        staged: None,
        report: None,
    })
}

fn fmt(v: Option<f64>) -> String {
    v.map(|v| format!("{v:.6}")).unwrap_or_else(|| "-".into())
}

/// The summary as text.
fn table(rows: &[Row]) -> String {
    use std::fmt::Write as _;
    let w = rows
        .iter()
        .map(|r| r.serial.len())
        .max()
        .unwrap_or(6)
        .max(6);
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{:<w$}  {:>6} {:>5} {:>12} {:>12} {:>12} {:>4} {:>8}  status",
        "serial", "params", "iter", "rms before", "rms after", "held out", "unit", "warnings"
    );
    for r in rows {
        let _ = writeln!(
            s,
            "{:<w$}  {:>6} {:>5} {:>12} {:>12} {:>12} {:>4} {:>8}  {}{}",
            r.serial,
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
            Status::Flagged => "flagged".into(),
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

/// Runs `kinecal batch`.
pub fn run(a: BatchArgs) -> Result<u8> {
    let shard_of = a.shard.as_deref().map(parse_shard).transpose()?;
    let mut entries = read_manifest(&a.manifest)?;
    let db_file = history::db_file(a.db.as_deref()).filter(|_| a.record);
    check_files(
        &entries,
        &a.manifest,
        a.summary.as_deref(),
        db_file.as_deref(),
    )?;
    if let Some((k, n)) = shard_of {
        let total = entries.len();
        entries = shard(entries, k, n);
        eprintln!(
            "shard {k}/{n}: {} of the manifest's {total} robots",
            entries.len()
        );
        if entries.is_empty() {
            bail!("shard {k}/{n} of {total} robots is empty: nothing to do");
        }
    }
    let db = if a.record {
        Some(history::open_db(a.db.as_deref())?)
    } else {
        None
    };
    let jobs = match a.jobs {
        Some(0) => bail!("--jobs must be at least 1"),
        Some(n) => n,
        None => std::thread::available_parallelism().map_or(1, |n| n.get()),
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(jobs)
        .build()
        .context("cannot start the worker threads")?;
    let bar = ProgressBar::with_draw_target(
        Some(entries.len() as u64),
        if a.quiet {
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
    let done: Vec<Done> = pool.install(|| {
        entries
            .par_iter()
            .map(|e| {
                let d = calibrate_one(e);
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
    // One writer: record in manifest order, then put each robot's outputs in place.
    let mut rows = Vec::with_capacity(done.len());
    for d in done {
        let Done {
            mut row,
            staged,
            report,
        } = d;
        // One transaction per record; a record already there (a rerun after an interrupted
        // batch, another shard's retry) is found by its key and not written twice.
        let recorded = match (&db, &report) {
            (Some(db), Some(rep)) => db
                .record(&row.serial, None, rep, "", Default::default())
                .map(|_| ())
                .map_err(|e| format!("not recorded: {e}")),
            _ => Ok(()),
        };
        match (recorded, staged) {
            (Err(e), _) => row.status = Status::Failed(e),
            (Ok(()), Some(s)) => {
                if let Err(e) = s.commit() {
                    row.status = Status::Failed(format!("{e:#}"));
                }
            }
            (Ok(()), None) => {}
        }
        rows.push(row);
    }
    print!("{}", table(&rows));
    for r in &rows {
        for w in &r.implausible {
            println!("{}: {w}", r.serial);
        }
    }
    if let Some(path) = &a.summary {
        crate::write_file(path, &summary_csv(&rows)?)?;
        eprintln!("wrote the summary to {}", path.display());
    }
    let count = |f: fn(&Status) -> bool| rows.iter().filter(|r| f(&r.status)).count();
    let (failed, flagged, unconverged) = (
        count(|s| matches!(s, Status::Failed(_))),
        count(|s| matches!(s, Status::Flagged)),
        count(|s| matches!(s, Status::NotConverged)),
    );
    eprintln!(
        "{} robots: {} calibrated, {failed} failed, {flagged} flagged, {unconverged} not converged",
        rows.len(),
        rows.len() - failed - flagged
    );
    Ok(if failed > 0 {
        1
    } else if flagged > 0 {
        EXIT_IMPLAUSIBLE
    } else if unconverged > 0 {
        EXIT_NOT_CONVERGED
    } else {
        0
    })
}
