//! `kinecal history ...`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail, Context, Result};
use kinecal::report::CalibrationReport;
use kinecal_history::{
    drift, parse_time, printable, samples, AddOptions, Baseline, Calibration, Database,
    DriftOptions, DriftReport, Location, Tolerances,
};

use crate::args::{
    DbArg, FormatArg, HistoryAddArgs, HistoryCommand, HistoryDriftArgs, HistoryEventArgs,
    HistoryEventsArgs, HistoryExportArgs, HistoryImportArgs, HistoryInitArgs, HistoryListArgs,
    HistoryPlotArgs, HistoryShowArgs,
};
use kinecal::files::output::{self, write_file};

/// Reads a text file, naming it in errors.
fn read_text(path: &Path) -> Result<String> {
    Ok(kinecal::source::Source::read(path)?.text)
}
use kinecal_report::{Line, Panel};

/// Exit code when drift or a check finds something: usable from cron and monitoring.
pub const EXIT_FLAGGED: u8 = 3;

/// The history named by `--db` (a file path or a `postgres://` URL), else by `$KINECAL_DB`,
/// else the default file.
pub fn location(db: Option<&Path>) -> Result<Location> {
    let given = db
        .map(|p| p.as_os_str().to_owned())
        .or_else(|| std::env::var_os("KINECAL_DB").filter(|v| !v.is_empty()));
    Ok(match given {
        Some(v) => Location::parse(&v),
        None => Location::File(kinecal_history::default_db_path().ok_or_else(|| {
            anyhow!("no home or data folder to keep the history in: give --db PATH or URL")
        })?),
    })
}

/// The history's file, when it is a file (for the checks that no output overwrites it).
pub fn db_file(db: Option<&Path>) -> Option<PathBuf> {
    location(db).ok()?.file().map(Path::to_path_buf)
}

/// Opens the history named by `--db` (or `$KINECAL_DB`, or the default file) for writing,
/// creating or migrating it if needed. An existing file is inspected read-only first and
/// refused, untouched, unless it is a sound kinecal history.
pub fn open_db(db: Option<&Path>) -> Result<Database> {
    Ok(Database::open(location(db)?)?)
}

/// Opens an existing history for reading only: never creates one (a mistyped `--db` is an
/// error), works on read-only files and folders, and on a server in a read-only session.
pub fn open_db_read(d: &DbArg) -> Result<Database> {
    let db = Database::open_read_only(location(d.db.as_deref())?)?;
    if let Some(problem) = db.integrity_problem() {
        eprintln!(
            "warning: {}: the database fails its integrity check ({}); showing what can be read",
            db.path(),
            printable(problem)
        );
    }
    Ok(db)
}

/// The readable calibrations of `robot_id` (all robots when `None`); each record that cannot
/// be read is named on standard error.
fn read_calibrations(db: &Database, robot_id: Option<&str>) -> Result<Vec<Calibration>> {
    let records = db.records(robot_id)?;
    for d in &records.damaged {
        eprintln!("warning: {}: {}", db.path(), printable(&d.to_string()));
    }
    Ok(records.calibrations)
}

/// Parses `--at`.
pub fn parse_at(at: Option<&str>) -> Result<Option<i64>> {
    at.map(|s| parse_time(s).map_err(|e| anyhow!("--at: {e}")))
        .transpose()
}

/// Runs a history command; returns the exit code.
pub fn run(c: HistoryCommand) -> Result<u8> {
    match c {
        HistoryCommand::Add(a) => {
            let options = AddOptions { force: a.force };
            add(a, options)
        }
        HistoryCommand::List(a) => list(a),
        HistoryCommand::Show(a) => show(a),
        HistoryCommand::Export(a) => export(a),
        HistoryCommand::Drift(a) => drift_cmd(a),
        HistoryCommand::Plot(a) => plot(a),
        HistoryCommand::Fleet(a) => crate::fleet::run(a),
        HistoryCommand::Event(a) => event(a),
        HistoryCommand::Events(a) => events(a),
        HistoryCommand::Import(a) => import(a),
        HistoryCommand::Init(a) => init(a),
    }
}

fn add(a: HistoryAddArgs, options: AddOptions) -> Result<u8> {
    let text = read_text(&a.report)?;
    let report = CalibrationReport::from_json(&text)
        .with_context(|| format!("{}: not a kinecal calibration report", a.report.display()))?;
    let at = parse_at(a.at.as_deref())?;
    let db = open_db(a.db.db.as_deref())?;
    let added = db.record(&a.robot_id, at, &report, &a.note, options)?;
    if added.new {
        eprintln!(
            "recorded calibration {} of robot {}",
            added.id,
            printable(&a.robot_id)
        );
    } else {
        eprintln!(
            "already recorded as calibration {} of robot {} (the same calibration: nothing written)",
            added.id,
            printable(&a.robot_id)
        );
    }
    Ok(0)
}

fn event(a: HistoryEventArgs) -> Result<u8> {
    let at = parse_at(a.at.as_deref())?.unwrap_or_else(|| {
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_secs() as i64)
    });
    let db = open_db(a.db.db.as_deref())?;
    let added = db.add_event(&a.robot_id, at, &a.note)?;
    eprintln!(
        "{} event {} of robot {} at {}: {}",
        if added.new {
            "recorded"
        } else {
            "already recorded:"
        },
        added.id,
        printable(&a.robot_id),
        kinecal_history::format_time(at),
        printable(&a.note)
    );
    Ok(0)
}

fn events(a: HistoryEventsArgs) -> Result<u8> {
    let db = open_db_read(&a.db)?;
    let events = db.events(a.robot_id.as_deref())?;
    if events.is_empty() {
        println!("(no maintenance events recorded)");
        return Ok(0);
    }
    println!("{:>5}  {:<14} {:<21} note", "id", "robot", "at");
    for e in events {
        println!(
            "{:>5}  {:<14} {:<21} {}",
            e.id,
            printable(&e.robot_id),
            e.at_text(),
            printable(&e.note)
        );
    }
    Ok(0)
}

fn import(a: HistoryImportArgs) -> Result<u8> {
    let text = read_text(&a.dump)?;
    let dump = kinecal_history::Dump::from_json(&text, &a.dump.display().to_string())?;
    let db = open_db(a.db.db.as_deref())?;
    let s = db.import(&dump)?;
    eprintln!(
        "imported into {}: {} calibrations written, {} already there; {} events written, {} already there",
        db.path(),
        s.added,
        s.present,
        s.events_added,
        s.events_present
    );
    if !s.renumbered.is_empty() {
        let pairs: Vec<String> = s
            .renumbered
            .iter()
            .map(|(a, b)| format!("{a} -> {b}"))
            .collect();
        eprintln!(
            "ids taken by other records, so renumbered: {}",
            pairs.join(", ")
        );
    }
    Ok(0)
}

fn init(a: HistoryInitArgs) -> Result<u8> {
    let db = open_db(a.db.db.as_deref())?;
    eprintln!(
        "{}: a kinecal history ({}), schema version {}",
        db.path(),
        db.backend().name(),
        db.store().schema_version()
    );
    Ok(0)
}

fn list(a: HistoryListArgs) -> Result<u8> {
    let db = open_db_read(&a.db)?;
    let cals = read_calibrations(&db, a.robot_id.as_deref())?;
    if cals.is_empty() {
        match &a.robot_id {
            Some(r) => bail!("no calibration recorded for robot `{}`", printable(r)),
            None => {
                println!("(no calibrations recorded)");
                return Ok(0);
            }
        }
    }
    println!(
        "{:>5}  {:<14} {:<21} {:<12} {:<8} {:<40} note",
        "id", "robot", "at", "model", "method", "RMS error before -> after"
    );
    for c in cals {
        println!(
            "{:>5}  {:<14} {:<21} {:<12} {:<8} {:<40} {}",
            c.id,
            printable(&c.robot_id),
            c.at_text,
            printable(&c.robot_name),
            printable(&c.method),
            errors_line(&c),
            printable(&c.note)
        );
    }
    Ok(0)
}

/// The RMS errors of a record, one `metric before -> after` per kind of observation.
fn errors_line(c: &Calibration) -> String {
    if c.errors.is_empty() {
        return "-".into();
    }
    c.errors
        .iter()
        .map(|e| {
            format!(
                "{} {} -> {}",
                printable(&e.metric),
                crate::report::num(e.before),
                crate::report::num(e.after)
            )
        })
        .collect::<Vec<_>>()
        .join("; ")
}

fn show(a: HistoryShowArgs) -> Result<u8> {
    let db = open_db_read(&a.db)?;
    let cal = match (a.id, &a.robot_id) {
        (Some(id), _) => db
            .calibration(id)?
            .ok_or_else(|| anyhow!("no calibration with id {id}"))?,
        (None, Some(r)) => read_calibrations(&db, Some(r))?
            .pop()
            .ok_or_else(|| anyhow!("no calibration recorded for robot `{}`", printable(r)))?,
        (None, None) => bail!("give --id or --robot-id"),
    };
    if a.json {
        println!("{}", serde_json::to_string_pretty(&cal)?);
        return Ok(0);
    }
    println!(
        "calibration {} of robot {} at {} ({}, {} {}, solution {})",
        cal.id,
        printable(&cal.robot_id),
        cal.at_text,
        printable(&cal.robot_name),
        printable(&cal.method),
        printable(&cal.length_unit),
        printable(&cal.solution)
    );
    for e in &cal.errors {
        println!(
            "RMS {} error {} -> {} {}",
            printable(&e.metric),
            crate::report::num(e.before),
            crate::report::num(e.after),
            printable(&e.unit)
        );
    }
    println!(
        "model sha256 {}  data sha256 {}",
        or_dash(&cal.model_fingerprint),
        or_dash(&cal.data_fingerprint)
    );
    if !cal.note.is_empty() {
        println!("note: {}", printable(&cal.note));
    }
    println!();
    println!(
        "{:<5} {:<20} {:<9} {:>16} {:>12}  status",
        "id", "name", "unit", "value", "sigma"
    );
    for p in cal.parameters.iter().filter(|p| p.estimated) {
        println!(
            "{:<5} {:<20} {:<9} {:>16.6} {:>12}  {}",
            printable(&p.id),
            printable(&p.name),
            printable(&p.unit),
            p.value,
            p.sigma.map_or("-".into(), |s| format!("{s:.3e}")),
            if p.determined {
                "determined"
            } else {
                "not determined alone"
            }
        );
    }
    for c in &cal.combinations {
        println!(
            "  {} = {:.6} (sigma {:.3e})",
            printable(&c.expression),
            c.value,
            c.sigma
        );
    }
    Ok(0)
}

/// The first 16 characters of a fingerprint, or `-`.
fn or_dash(s: &str) -> String {
    if s.is_empty() {
        "-".into()
    } else {
        printable(&s.chars().take(16).collect::<String>()).into_owned()
    }
}

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

fn export(a: HistoryExportArgs) -> Result<u8> {
    let db = open_db_read(&a.db)?;
    if let FormatArg::Dump = a.format {
        if a.robot_id.is_some() {
            bail!("--format dump exports the whole history: leave out --robot-id");
        }
        let text = db.dump()?.to_json();
        match a.out {
            Some(p) => write_file(&p, &text)?,
            None => print!("{text}"),
        }
        return Ok(0);
    }
    let cals = read_calibrations(&db, a.robot_id.as_deref())?;
    let text = match a.format {
        FormatArg::Dump => unreachable!("written above"),
        FormatArg::Json => serde_json::to_string_pretty(&cals)? + "\n",
        FormatArg::Csv => {
            let mut s = String::from("calibration,robot_id,at,method,solution,kind,id,name,unit,value,sigma,estimated,determined\n");
            for c in &cals {
                for p in &c.parameters {
                    let _ = writeln!(
                        s,
                        "{},{},{},{},{},parameter,{},{},{},{},{},{},{}",
                        c.id,
                        csv_field(&c.robot_id),
                        c.at_text,
                        csv_field(&c.method),
                        csv_field(&c.solution),
                        csv_field(&p.id),
                        csv_field(&p.name),
                        csv_field(&p.unit),
                        p.value,
                        p.sigma.map_or(String::new(), |v| v.to_string()),
                        p.estimated,
                        p.determined
                    );
                }
                for comb in &c.combinations {
                    let _ = writeln!(
                        s,
                        "{},{},{},{},{},combination,,{},,{},{},true,true",
                        c.id,
                        csv_field(&c.robot_id),
                        c.at_text,
                        csv_field(&c.method),
                        csv_field(&c.solution),
                        csv_field(&comb.expression),
                        comb.value,
                        comb.sigma
                    );
                }
            }
            s
        }
    };
    match a.out {
        Some(p) => write_file(&p, &text)?,
        None => print!("{text}"),
    }
    Ok(0)
}

fn tolerances(path: Option<&Path>) -> Result<Tolerances> {
    Ok(match path {
        Some(p) => Tolerances::parse_toml(&read_text(p)?, &p.display().to_string())?,
        None => Tolerances::default(),
    })
}

/// Refuses a `--sigma` that is not a positive, finite number (`inf`, `NaN`, 0, negative).
fn check_sigma(sigma: f64) -> Result<()> {
    if !(sigma.is_finite() && sigma > 0.0) {
        bail!("--sigma {sigma}: expected a positive, finite number of standard deviations");
    }
    Ok(())
}

fn drift_report(
    history: &[Calibration],
    robot_id: &str,
    baseline: &str,
    sigma: f64,
    tolerances: Tolerances,
) -> Result<DriftReport> {
    if history.is_empty() {
        bail!(
            "no calibration recorded for robot `{}`",
            printable(robot_id)
        );
    }
    let baseline = match baseline {
        "first" => Baseline::First,
        "latest-ok" => Baseline::LatestOk,
        id => Baseline::Id(id.parse().map_err(|_| {
            anyhow!(
                "--baseline `{}`: expected first, latest-ok or a calibration id",
                printable(id)
            )
        })?),
    };
    let opts = DriftOptions {
        baseline,
        sigma,
        tolerances,
    };
    Ok(drift(history, &opts)?)
}

/// The calibrations of a robot's history since its latest maintenance event (drift is computed
/// within segments), and that event; an error when it has none since.
fn segment<'a>(
    all: &'a [Calibration],
    events: &'a [kinecal_history::Event],
    robot_id: &str,
) -> Result<(&'a [Calibration], Option<&'a kinecal_history::Event>)> {
    let (seg, event) = kinecal_history::current_segment(all, events);
    if let (true, Some(e)) = (seg.is_empty() && !all.is_empty(), event) {
        bail!(
            "robot `{}`: no calibration since its maintenance event of {} ({}): drift is computed \
             within the segments between events; calibrate it",
            printable(robot_id),
            e.at_text(),
            printable(&e.note)
        );
    }
    Ok((seg, event))
}

fn drift_cmd(a: HistoryDriftArgs) -> Result<u8> {
    // Arguments first: nothing is opened for a command that cannot run.
    check_sigma(a.sigma)?;
    let tol = tolerances(a.tolerance.as_deref())?;
    let db = open_db_read(&a.db)?;
    let all = read_calibrations(&db, Some(&a.robot_id))?;
    let events = db.events(Some(&a.robot_id))?;
    let (history, event) = segment(&all, &events, &a.robot_id)?;
    let mut r = drift_report(history, &a.robot_id, &a.baseline, a.sigma, tol)?;
    r.since_event = event.cloned();
    if a.json {
        println!("{}", serde_json::to_string_pretty(&r)?);
    } else {
        println!(
            "robot {}: {} calibrations; latest {} ({}) against baseline {} ({}); flag beyond {} sigma",
            printable(&r.robot_id),
            r.calibrations,
            r.latest_id,
            r.latest_at,
            r.baseline_id,
            r.baseline_at,
            r.sigma_threshold
        );
        if let Some(e) = event {
            println!(
                "since the maintenance event of {} ({}): the {} earlier calibrations are not compared",
                e.at_text(),
                printable(&e.note),
                all.len() - history.len()
            );
        }
        let converted: Vec<String> = history
            .iter()
            .filter(|c| c.length_unit != r.length_unit || c.angle_unit != r.angle_unit)
            .map(|c| {
                format!(
                    "{} ({} and {})",
                    c.id,
                    printable(&c.length_unit),
                    printable(&c.angle_unit)
                )
            })
            .collect();
        if !converted.is_empty() {
            println!(
                "values in {} and {}, the units of the first calibration; converted from other units: calibration {}",
                r.length_unit,
                r.angle_unit,
                converted.join(", ")
            );
        }
        println!();
        println!(
            "{:<50} {:>13} {:>11} {:>8} {:>22}  ",
            "quantity", "change", "sigma", "z", "trend per 30 days"
        );
        for q in &r.quantities {
            let trend = match (q.trend_per_30_days, q.trend_sigma) {
                (Some(t), Some(s)) => format!("{t:+.3e} +- {s:.1e}"),
                _ => "-".into(),
            };
            // Compliances (1e-6..1e-3 rad/(N m)) in significant digits, not 6 decimals.
            let change = if q.unit.contains("/(N ") {
                format!("{:>+13.4e}", q.change)
            } else {
                format!("{:>+13.6}", q.change)
            };
            println!(
                "{:<50} {change} {:>11.3e} {:>8.1} {:>22}  {}",
                format!("{} [{}]", printable(&q.quantity), q.unit),
                q.sigma,
                q.significance,
                trend,
                if q.flagged { "FLAGGED" } else { "" }
            );
        }
        if !r.left_out.is_empty() {
            println!();
            println!("not compared (only one of the two runs tracks them):");
            for q in &r.left_out {
                println!(
                    "  {} ({}): {}",
                    printable(&q.quantity),
                    printable(&q.key),
                    printable(&q.reason)
                );
            }
        }
        if !r.unused_tolerances.is_empty() {
            println!();
            println!("tolerances not applied:");
            for t in &r.unused_tolerances {
                println!("  {}: {}", printable(&t.key), printable(&t.reason));
            }
        }
        println!();
        if r.flags.is_empty() {
            println!("nothing flagged");
        } else {
            for q in &r.flags {
                let change = if q.unit.contains("/(N ") {
                    format!("{:+.4e}", q.change)
                } else {
                    format!("{:+.6}", q.change)
                };
                println!(
                    "FLAG: {} ({}) changed by {change} {} ({})",
                    printable(&q.quantity),
                    printable(&q.parameters.join(", ")),
                    q.unit,
                    q.reason.clone().unwrap_or_default()
                );
            }
        }
    }
    Ok(if r.flags.is_empty() { 0 } else { EXIT_FLAGGED })
}

/// The picture formats `history plot` writes, by the extension of `--out`.
enum PlotFormat {
    Svg,
    Png,
}

fn plot_format(path: &Path) -> Result<PlotFormat> {
    match path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .as_deref()
    {
        Some("svg") => Ok(PlotFormat::Svg),
        Some("png") => Ok(PlotFormat::Png),
        _ => bail!(
            "--out {}: the name must end in .svg or .png (the format written)",
            path.display()
        ),
    }
}

fn plot(a: HistoryPlotArgs) -> Result<u8> {
    let format = plot_format(&a.out)?;
    let tol = tolerances(a.tolerance.as_deref())?;
    let db = open_db_read(&a.db)?;
    let history = read_calibrations(&db, Some(&a.robot_id))?;
    if history.is_empty() {
        bail!(
            "no calibration recorded for robot `{}`",
            printable(&a.robot_id)
        );
    }
    let events = db.events(Some(&a.robot_id))?;
    let (seg, _) = segment(&history, &events, &a.robot_id)?;
    let r = drift(
        seg,
        &DriftOptions {
            tolerances: tol,
            ..Default::default()
        },
    )?;
    let wanted: Option<Vec<String>> = a.param.as_ref().map(|l| {
        l.split(',')
            .map(|s| s.trim().to_string())
            .filter(|s| !s.is_empty())
            .collect()
    });
    let matches = |k: &str, key: &str, parameters: &[String]| {
        k == key || (parameters.len() == 1 && k == parameters[0])
    };
    // Say which entries of --param match nothing, and why.
    let mut unmatched = Vec::new();
    for k in wanted.iter().flatten() {
        if r.quantities
            .iter()
            .any(|q| matches(k, &q.key, &q.parameters))
        {
            continue;
        }
        let why = match r
            .left_out
            .iter()
            .find(|q| matches(k, &q.key, &q.parameters))
        {
            Some(q) => format!("left out: {}", q.reason),
            None => format!(
                "matches no tracked quantity of robot {} (a determined parameter's name or id, or a determined combination's expression)",
                r.robot_id
            ),
        };
        unmatched.push(format!("--param `{}`: {}", printable(k), printable(&why)));
    }
    let mut series = Vec::new();
    for q in &r.quantities {
        if let Some(w) = &wanted {
            if !w.iter().any(|k| matches(k, &q.key, &q.parameters)) {
                continue;
            }
        }
        // Every calibration's value of this quantity, in the history's units.
        series.push((q.clone(), samples(&history, &q.key)?));
    }
    if series.is_empty() {
        bail!(
            "nothing to plot: {}",
            if unmatched.is_empty() {
                "no tracked quantity".to_string()
            } else {
                unmatched.join("; ")
            }
        );
    }
    for u in &unmatched {
        eprintln!("warning: {u}");
    }
    // One panel per quantity: values with +-1 sigma bars against days since the first
    // calibration; the first value +-3 sigma, and the tolerance, as reference lines.
    let t0 = history[0].at;
    let since: String = kinecal_history::format_time(t0).chars().take(10).collect();
    let panels: Vec<Panel> = series
        .iter()
        .map(|(q, pts)| {
            let (v0, s0) = pts
                .first()
                .map_or((q.baseline, q.sigma), |p| (p.value, p.sigma));
            let mut h_lines = vec![
                (v0 - 3.0 * s0, "first -3 sigma".to_string()),
                (v0 + 3.0 * s0, "first +3 sigma".to_string()),
            ];
            if let Some(t) = q.tolerance {
                h_lines.push((v0 - t, "tolerance".into()));
                h_lines.push((v0 + t, "tolerance".into()));
            }
            Panel {
                title: format!(
                    "{}{}",
                    printable(&q.quantity),
                    if q.flagged { " (FLAGGED)" } else { "" }
                ),
                x_label: format!("days since {since}"),
                y_label: format!("{} ({})", printable(&q.key), q.unit),
                x: pts.iter().map(|p| (p.at - t0) as f64 / 86400.0).collect(),
                lines: vec![Line {
                    points: true,
                    error: Some(pts.iter().map(|p| p.sigma).collect()),
                    ..Line::new("value +-1 sigma", pts.iter().map(|p| p.value).collect())
                }],
                h_lines,
                v_lines: events
                    .iter()
                    .map(|e| {
                        (
                            (e.at - t0) as f64 / 86400.0,
                            format!("event: {}", printable(&e.note)),
                        )
                    })
                    .collect(),
                ..Default::default()
            }
        })
        .collect();
    match format {
        PlotFormat::Svg => write_file(&a.out, &kinecal_report::render_svg(&panels, 1)?)?,
        PlotFormat::Png => {
            let mut staged = output::Staged::new();
            staged.by_path(&a.out, |tmp| {
                std::fs::write(tmp, kinecal_report::render_png(&panels, 1)?)
                    .context("cannot write the picture")
            })?;
            staged.commit()?;
        }
    }
    eprintln!("wrote {} panels to {}", panels.len(), a.out.display());
    Ok(0)
}
