//! `kinecal history ...`: each command's flags become the library's history spec (over
//! `--spec`), which kinecal-history's historian runs; this module shows the documents.

use std::path::{Path, PathBuf};

use anyhow::{anyhow, Result};
use kinecal::spec::{
    BaselineSpec, HistoryAddSpec, HistoryDriftSpec, HistoryEventSpec, HistoryEventsSpec,
    HistoryExportSpec, HistoryFleetSpec, HistoryImportSpec, HistoryInitSpec, HistoryListSpec,
    HistoryPlotSpec, HistoryShowSpec, Job,
};
use kinecal_history::jobs::{Document, DriftDocument, FleetDocument};
use kinecal_history::{parse_time, printable, Calibration, Database, Event, Location};
use kinecal_report::number::sig;

use crate::args::{
    HistoryAddArgs, HistoryArgs, HistoryCommand, HistoryDriftArgs, HistoryEventArgs,
    HistoryExportArgs, HistoryFleetArgs, HistoryImportArgs, HistoryListArgs, HistoryPlotArgs,
    HistoryShowArgs, SpecArgs,
};
use crate::door::{base, over, path_text, set};

/// The history named by `--db` (a file path or a `postgres://` URL), else by `$KINECAL_DB`,
/// else the default file.
pub fn location(db: Option<&Path>) -> Result<Location> {
    let db = db.map(path_text).transpose()?;
    Ok(kinecal_history::jobs::location(db.as_deref())?)
}

/// The history's file, when it is a file (for the checks that no output overwrites it).
pub fn db_file(db: Option<&Path>) -> Option<PathBuf> {
    location(db).ok()?.file().map(Path::to_path_buf)
}

/// Opens the history named by `--db` for writing (a calibration's `--record`).
pub fn open_db(db: Option<&Path>) -> Result<Database> {
    Ok(Database::open(location(db)?)?)
}

/// Parses `--at`.
pub fn parse_at(at: Option<&str>) -> Result<Option<i64>> {
    at.map(|s| parse_time(s).map_err(|e| anyhow!("--at: {e}")))
        .transpose()
}

/// `--db` as a spec's `db`.
fn db(d: &HistoryArgs) -> Result<Option<String>> {
    d.db.as_deref().map(path_text).transpose()
}

/// An optional path as a spec's string.
fn opt_path(p: Option<&Path>) -> Result<Option<String>> {
    p.map(path_text).transpose()
}

/// The spec of a history command, with its `--spec`/`--write-spec` and whether it prints JSON.
struct Said<'a> {
    job: Job,
    door: &'a SpecArgs,
    json: bool,
}

/// Runs a history command; returns the exit code.
pub fn run(c: HistoryCommand) -> Result<u8> {
    let said = spec(&c)?;
    let Some(done) = crate::door::run(said.job, said.door, &mut crate::Talk::new(), &[])? else {
        return Ok(0);
    };
    let document = Document::of(&done.document)
        .ok_or_else(|| anyhow!("a history job gave no history document"))?;
    if said.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&done.document.to_json_value())?
        );
    } else {
        show(document);
    }
    crate::door::say(&done.messages);
    Ok(crate::door::exit_code(done.status))
}

/// The spec of a history command line.
fn spec(c: &HistoryCommand) -> Result<Said<'_>> {
    Ok(match c {
        HistoryCommand::Add(a) => Said {
            job: Job::HistoryAdd(add(a)?),
            door: &a.history.door,
            json: false,
        },
        HistoryCommand::List(a) => Said {
            job: Job::HistoryList(list(a)?),
            door: &a.history.door,
            json: a.json,
        },
        HistoryCommand::Show(a) => Said {
            job: Job::HistoryShow(show_spec(a)?),
            door: &a.history.door,
            json: a.json,
        },
        HistoryCommand::Export(a) => Said {
            job: Job::HistoryExport(export(a)?),
            door: &a.history.door,
            json: false,
        },
        HistoryCommand::Drift(a) => Said {
            job: Job::HistoryDrift(drift(a)?),
            door: &a.history.door,
            json: a.json,
        },
        HistoryCommand::Plot(a) => Said {
            job: Job::HistoryPlot(plot(a)?),
            door: &a.history.door,
            json: false,
        },
        HistoryCommand::Fleet(a) => Said {
            job: Job::HistoryFleet(fleet(a)?),
            door: &a.history.door,
            json: false,
        },
        HistoryCommand::Event(a) => Said {
            job: Job::HistoryEvent(event(a)?),
            door: &a.history.door,
            json: false,
        },
        HistoryCommand::Events(a) => Said {
            job: Job::HistoryEvents(events(a)?),
            door: &a.history.door,
            json: a.json,
        },
        HistoryCommand::Import(a) => Said {
            job: Job::HistoryImport(import(a)?),
            door: &a.history.door,
            json: false,
        },
        HistoryCommand::Init(a) => Said {
            job: Job::HistoryInit(init(a)?),
            door: &a.door,
            json: false,
        },
    })
}

/// `kinecal history add`'s spec.
pub fn add(a: &HistoryAddArgs) -> Result<HistoryAddSpec> {
    let mut s: HistoryAddSpec = base(&a.history.door)?;
    over(&mut s.db, db(&a.history)?);
    set(&mut s.robot_id, a.robot_id.clone());
    set(&mut s.report, opt_path(a.report.as_deref())?);
    over(&mut s.at, a.at.clone());
    set(&mut s.note, a.note.clone());
    s.force |= a.force;
    Ok(s)
}

/// `kinecal history list`'s spec.
pub fn list(a: &HistoryListArgs) -> Result<HistoryListSpec> {
    let mut s: HistoryListSpec = base(&a.history.door)?;
    over(&mut s.db, db(&a.history)?);
    over(&mut s.robot_id, a.robot_id.clone());
    Ok(s)
}

/// `kinecal history show`'s spec.
pub fn show_spec(a: &HistoryShowArgs) -> Result<HistoryShowSpec> {
    let mut s: HistoryShowSpec = base(&a.history.door)?;
    over(&mut s.db, db(&a.history)?);
    over(&mut s.robot_id, a.robot_id.clone());
    over(&mut s.id, a.id);
    Ok(s)
}

/// `kinecal history export`'s spec.
pub fn export(a: &HistoryExportArgs) -> Result<HistoryExportSpec> {
    let mut s: HistoryExportSpec = base(&a.history.door)?;
    over(&mut s.db, db(&a.history)?);
    over(&mut s.robot_id, a.robot_id.clone());
    set(&mut s.format, a.format);
    over(&mut s.out, opt_path(a.out.as_deref())?);
    Ok(s)
}

/// `kinecal history drift`'s spec.
pub fn drift(a: &HistoryDriftArgs) -> Result<HistoryDriftSpec> {
    let mut s: HistoryDriftSpec = base(&a.history.door)?;
    over(&mut s.db, db(&a.history)?);
    set(&mut s.robot_id, a.robot_id.clone());
    set(&mut s.baseline, a.baseline.clone().map(BaselineSpec::Named));
    set(&mut s.sigma, a.sigma);
    over(&mut s.tolerance, opt_path(a.tolerance.as_deref())?);
    Ok(s)
}

/// `kinecal history plot`'s spec.
pub fn plot(a: &HistoryPlotArgs) -> Result<HistoryPlotSpec> {
    let mut s: HistoryPlotSpec = base(&a.history.door)?;
    over(&mut s.db, db(&a.history)?);
    set(&mut s.robot_id, a.robot_id.clone());
    if let Some(list) = &a.param {
        s.param = list
            .split(',')
            .map(|k| k.trim().to_string())
            .filter(|k| !k.is_empty())
            .collect();
    }
    over(&mut s.tolerance, opt_path(a.tolerance.as_deref())?);
    set(&mut s.out, opt_path(a.out.as_deref())?);
    Ok(s)
}

/// `kinecal history fleet`'s spec.
pub fn fleet(a: &HistoryFleetArgs) -> Result<HistoryFleetSpec> {
    let mut s: HistoryFleetSpec = base(&a.history.door)?;
    over(&mut s.db, db(&a.history)?);
    set(&mut s.sigma, a.sigma);
    over(&mut s.tolerance, opt_path(a.tolerance.as_deref())?);
    set(&mut s.horizon, a.horizon);
    over(&mut s.now, a.now.clone());
    over(&mut s.json, opt_path(a.json.as_deref())?);
    over(&mut s.html, opt_path(a.html.as_deref())?);
    Ok(s)
}

/// `kinecal history event`'s spec.
pub fn event(a: &HistoryEventArgs) -> Result<HistoryEventSpec> {
    let mut s: HistoryEventSpec = base(&a.history.door)?;
    over(&mut s.db, db(&a.history)?);
    set(&mut s.robot_id, a.robot_id.clone());
    over(&mut s.at, a.at.clone());
    set(&mut s.note, a.note.clone());
    Ok(s)
}

/// `kinecal history events`'s spec.
pub fn events(a: &HistoryListArgs) -> Result<HistoryEventsSpec> {
    let mut s: HistoryEventsSpec = base(&a.history.door)?;
    over(&mut s.db, db(&a.history)?);
    over(&mut s.robot_id, a.robot_id.clone());
    Ok(s)
}

/// `kinecal history import`'s spec.
pub fn import(a: &HistoryImportArgs) -> Result<HistoryImportSpec> {
    let mut s: HistoryImportSpec = base(&a.history.door)?;
    over(&mut s.db, db(&a.history)?);
    set(&mut s.dump, opt_path(a.dump.as_deref())?);
    Ok(s)
}

/// `kinecal history init`'s spec.
pub fn init(a: &HistoryArgs) -> Result<HistoryInitSpec> {
    let mut s: HistoryInitSpec = base(&a.door)?;
    over(&mut s.db, db(a)?);
    Ok(s)
}

/// Shows a history document as text on standard output (what a job wrote or recorded it says
/// on standard error).
fn show(d: &Document) {
    match d {
        Document::Calibrations(cals) => show_list(cals),
        Document::Calibration(c) => show_calibration(c),
        Document::Export(e) => {
            if let Some(t) = &e.text {
                print!("{t}");
            }
        }
        Document::Drift(r) => show_drift(r),
        Document::Fleet(f) => show_fleet(f),
        Document::Events(e) => show_events(e),
        // Recorded, written, imported, made: said on standard error.
        _ => {}
    }
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
                sig(e.before, 4),
                sig(e.after, 4)
            )
        })
        .collect::<Vec<_>>()
        .join("; ")
}

fn show_list(cals: &[Calibration]) {
    if cals.is_empty() {
        println!("(no calibrations recorded)");
        return;
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
            errors_line(c),
            printable(&c.note)
        );
    }
}

/// The first 16 characters of a fingerprint, or `-`.
fn or_dash(s: &str) -> String {
    if s.is_empty() {
        "-".into()
    } else {
        printable(&s.chars().take(16).collect::<String>()).into_owned()
    }
}

fn show_calibration(cal: &Calibration) {
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
            sig(e.before, 4),
            sig(e.after, 4),
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
}

fn show_events(events: &[Event]) {
    if events.is_empty() {
        println!("(no maintenance events recorded)");
        return;
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
}

/// `calibration 3 is` or `calibrations 1, 2 and 3 are`.
fn ids(ids: &[i64]) -> String {
    let ids: Vec<String> = ids.iter().map(i64::to_string).collect();
    match ids.split_last() {
        Some((last, [])) => format!("calibration {last} is"),
        Some((last, rest)) => format!("calibrations {} and {last} are", rest.join(", ")),
        None => "no calibration is".into(),
    }
}

/// A change: compliances (1e-6..1e-3 rad/(N m)) in significant digits, others in 6 decimals.
fn change(v: f64, unit: &str) -> String {
    if unit.contains("/(N ") {
        format!("{v:+.4e}")
    } else {
        format!("{v:+.6}")
    }
}

fn show_drift(d: &DriftDocument) {
    let r = &d.report;
    println!(
        "robot {}: {} calibration{}; latest {} ({}) against baseline {} ({}); flag beyond {} sigma",
        printable(&r.robot_id),
        r.calibrations,
        if r.calibrations == 1 { "" } else { "s" },
        r.latest_id,
        r.latest_at,
        r.baseline_id,
        r.baseline_at,
        r.sigma_threshold
    );
    if let Some(e) = &r.since_event {
        println!(
            "since the maintenance event of {} ({}): the {} earlier calibrations are not compared",
            e.at_text(),
            printable(&e.note),
            d.before_event
        );
    }
    if let Some(m) = &r.since_model_change {
        println!(
            "since the change of robot model at calibration {} ({}; against calibration {}: {}): \
             {} not compared",
            m.first_id,
            m.first_at,
            m.earlier_id,
            printable(&m.difference),
            ids(&m.left_out)
        );
    }
    if let Some(why) = &r.nothing_to_compare {
        println!("nothing to compare: {}", printable(why));
        return;
    }
    if !d.converted.is_empty() {
        println!(
            "values in {} and {}, the units of the first calibration; converted from other units: calibration {}",
            r.length_unit,
            r.angle_unit,
            d.converted.join(", ")
        );
    }
    println!();
    let name = |q: &kinecal_history::Quantity| format!("{} [{}]", printable(&q.quantity), q.unit);
    // The longest name sets the column (a combination's words run long).
    let width = r
        .quantities
        .iter()
        .map(|q| name(q).chars().count())
        .fold(50, usize::max);
    println!(
        "{:<width$} {:>13} {:>11} {:>8} {:>22}  ",
        "quantity", "change", "sigma", "z", "trend per 30 days"
    );
    for q in &r.quantities {
        let trend = match (q.trend_per_30_days, q.trend_sigma) {
            (Some(t), Some(s)) => format!("{t:+.3e} +- {s:.1e}"),
            _ => "-".into(),
        };
        println!(
            "{:<width$} {:>13} {:>11.3e} {:>8.1} {:>22}  {}",
            name(q),
            change(q.change, &q.unit),
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
    }
    for q in &r.flags {
        println!(
            "FLAG: {} ({}) changed by {} {} ({})",
            printable(&q.quantity),
            printable(&q.parameters.join(", ")),
            change(q.change, &q.unit),
            q.unit,
            q.reason.clone().unwrap_or_default()
        );
    }
}

/// The fleet's table as text: the sentence, the table, the details of every robot that is not
/// ok (the same table as the page's: `kinecal_report::fleet::fleet_table`).
fn show_fleet(f: &FleetDocument) {
    let t = kinecal_report::fleet::fleet_table(f);
    let last = t.columns.len() - 1;
    let widths: Vec<usize> = (0..last)
        .map(|k| {
            t.rows
                .iter()
                .map(|r| r.cells[k].chars().count())
                .chain([t.columns[k].len()])
                .max()
                .unwrap_or(0)
        })
        .collect();
    let line = |cells: &[String]| {
        let mut s = String::new();
        for (k, c) in cells.iter().enumerate() {
            if k == last {
                s.push_str(c);
            } else if k == 2 || k == 4 {
                s.push_str(&crate::render::pad_left(c, widths[k]));
                s.push_str("  ");
            } else {
                // By hand: a history written before serials were bounded may hold one longer
                // than a format width can be.
                s.push_str(&crate::render::pad_right(c, widths[k]));
                s.push_str("  ");
            }
        }
        s.trim_end().to_string()
    };
    println!("{}", t.summary);
    println!();
    println!("{}", line(&t.columns));
    for r in &t.rows {
        println!("{}", line(&r.cells));
    }
    for (heading, lines) in &t.details {
        println!();
        println!("{heading}:");
        for l in lines {
            println!("  {l}");
        }
    }
    // Robots whose current segment starts at a change of robot model (the table counts
    // those calibrations as "since event").
    let changed: Vec<_> = f
        .robots
        .iter()
        .filter_map(|r| r.model_change.as_ref().map(|m| (r, m)))
        .collect();
    if !changed.is_empty() {
        println!();
        println!("changes of robot model (the calibrations before are not compared):");
        for (r, m) in changed {
            println!(
                "  {}: {} not compared: {}",
                printable(&r.robot_id),
                ids(&m.left_out),
                m.reason()
            );
        }
    }
}
