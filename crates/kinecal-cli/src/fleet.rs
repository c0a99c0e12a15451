//! `kinecal history fleet`: every robot's state, most urgent first, as text, JSON and HTML.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{bail, Result};
use kinecal_history::{
    fleet, format_time, printable, samples, Calibration, DriftOptions, Event, FleetOptions,
    RobotState, Tolerances, Verdict,
};
use kinecal_report::fleet::{html_fleet, FleetChart, FleetPage, FleetRow};
use kinecal_report::{Line, Panel};

use crate::args::HistoryFleetArgs;
use crate::history::{db_file, parse_at, EXIT_FLAGGED};
use kinecal::files::output;

/// Reads a text file, naming it in errors.
fn read_text(path: &std::path::Path) -> Result<String> {
    Ok(kinecal::source::Source::read(path)?.text)
}

/// Why a robot is listed where it is, in words.
fn why(r: &RobotState) -> String {
    if let Some(p) = &r.problem {
        return format!("not analysed: {}", printable(p));
    }
    let mut parts = Vec::new();
    match r.verdict {
        Verdict::Flagged => parts.push(format!("flags: {}", printable(&r.flags.join(", ")))),
        Verdict::Serviced => {
            if let Some(e) = &r.since_event {
                parts.push(format!(
                    "serviced {} ({}) after its last calibration: calibrate it",
                    &e.at_text()[..10],
                    printable(&e.note)
                ));
            }
        }
        Verdict::Single => parts.push("one calibration since its latest event".into()),
        _ => {}
    }
    if let (Some((at, key)), false) = (&r.earliest_crossing, r.verdict == Verdict::Flagged) {
        parts.push(format!(
            "{} crosses its tolerance {}",
            printable(key),
            &format_time(*at)[..10]
        ));
    }
    if r.verdict != Verdict::Serviced {
        if let Some(e) = &r.since_event {
            parts.push(format!(
                "since {} ({})",
                &e.at_text()[..10],
                printable(&e.note)
            ));
        }
    }
    if parts.is_empty() {
        "-".into()
    } else {
        parts.join("; ")
    }
}

/// A number in 4 significant digits, without trailing zeros.
fn g(v: f64) -> String {
    if v == 0.0 {
        "0".into()
    } else if (1e-3..1e5).contains(&v.abs()) {
        let decimals = (3 - v.abs().log10().floor() as i32).max(0) as usize;
        let s = format!("{v:.decimals$}");
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
    } else {
        format!("{v:.3e}")
    }
}

/// The detail lines of a robot that is not ok: its flagged quantities and crossings.
fn details(r: &RobotState) -> Vec<String> {
    r.trends
        .iter()
        .filter(|t| t.flagged || t.crossing.is_some())
        .map(|t| {
            let rate = match (t.rate_per_month, t.rate_sigma) {
                (Some(v), Some(s)) => format!("{} +- {} {}/month", g(v), g(s), t.unit),
                _ => "-".into(),
            };
            let mut s = format!(
                "{} ({}): change {} {} ({:.1} sigma), rate {rate}",
                printable(&t.quantity),
                printable(&t.key),
                g(t.change),
                t.unit,
                t.significance
            );
            if let Some(tol) = t.tolerance {
                let _ = write!(s, ", tolerance {}", g(tol));
            }
            if let (Some(c), Some(at)) = (&t.crossing_at, t.crossing) {
                if t.samples.last().is_some_and(|l| at <= l.at) {
                    let _ = write!(s, ", its trend beyond it since {}", &c[..10]);
                } else {
                    let _ = write!(s, ", crosses it {}", &c[..10]);
                }
            }
            if t.flagged {
                let _ = write!(
                    s,
                    ": FLAGGED ({})",
                    printable(t.reason.as_deref().unwrap_or(""))
                );
            }
            s
        })
        .collect()
}

/// The chart of a robot: its most urgent quantity over its whole history (points with +-1
/// sigma), the tolerance band around the segment's first value, the trend line of the segment
/// (extended to the crossing when that is near), and its maintenance events.
fn chart(r: &RobotState, history: &[Calibration], events: &[Event]) -> Option<FleetChart> {
    let t = r
        .trends
        .iter()
        .filter(|t| t.flagged)
        .max_by(|a, b| a.significance.total_cmp(&b.significance))
        .or_else(|| {
            r.trends
                .iter()
                .filter(|t| t.crossing.is_some())
                .min_by_key(|t| t.crossing)
        })?;
    let pts = samples(history, &t.key).ok()?;
    let t0 = history.first()?.at;
    let day = |at: i64| (at - t0) as f64 / 86_400.0;
    let mut x: Vec<f64> = pts.iter().map(|p| day(p.at)).collect();
    let mut y: Vec<f64> = pts.iter().map(|p| p.value).collect();
    let mut e: Vec<f64> = pts.iter().map(|p| p.sigma).collect();
    let span = x.last().copied().unwrap_or(0.0) - x.first().copied().unwrap_or(0.0);
    // The crossing drawn when it is no further than the history is long.
    if let Some(c) = t.crossing {
        let last = x.last().copied().unwrap_or(0.0);
        if day(c) > last && day(c) - last <= 2.0 * span.max(30.0) {
            x.push(day(c));
            y.push(f64::NAN);
            e.push(0.0);
        }
    }
    let seg_start = t.samples.first().map_or(f64::NEG_INFINITY, |s| day(s.at));
    let mut lines = vec![Line {
        points: true,
        error: Some(e),
        ..Line::new("value +-1 sigma", y)
    }];
    if let Some((tl, vl, slope)) = t.line {
        let trend: Vec<f64> = x
            .iter()
            .map(|&d| {
                if d >= seg_start - 1e-9 {
                    vl + slope * ((t0 as f64 + d * 86_400.0) - tl)
                } else {
                    f64::NAN
                }
            })
            .collect();
        lines.push(Line {
            color: Some(2),
            ..Line::new("trend (this segment)", trend)
        });
    }
    let mut h_lines = Vec::new();
    if let Some(tol) = t.tolerance {
        h_lines.push((t.reference - tol, "tolerance".to_string()));
        h_lines.push((t.reference + tol, "tolerance".to_string()));
    }
    let since: String = format_time(t0).chars().take(10).collect();
    let panel = Panel {
        title: printable(&t.quantity).into_owned(),
        x_label: format!("days since {since}"),
        y_label: format!("{} ({})", printable(&t.key), t.unit),
        x,
        lines,
        h_lines,
        v_lines: events
            .iter()
            .map(|ev| (day(ev.at), format!("event: {}", printable(&ev.note))))
            .collect(),
        ..Default::default()
    };
    Some(FleetChart {
        heading: format!("{}: {}", printable(&r.robot_id), r.verdict.word()),
        notes: std::iter::once(why(r)).chain(details(r)).collect(),
        panel,
    })
}

/// Runs `kinecal history fleet`.
pub fn run(a: HistoryFleetArgs) -> Result<u8> {
    if !(a.sigma.is_finite() && a.sigma > 0.0) {
        bail!(
            "--sigma {}: expected a positive, finite number of standard deviations",
            a.sigma
        );
    }
    if !(a.horizon.is_finite() && a.horizon >= 0.0) {
        bail!(
            "--horizon {}: expected a number of days, 0 or more",
            a.horizon
        );
    }
    let tolerances = match &a.tolerance {
        Some(p) => Tolerances::parse_toml(&read_text(p)?, &p.display().to_string())?,
        None => Tolerances::default(),
    };
    let now = parse_at(a.now.as_deref())?.unwrap_or_else(|| {
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_secs() as i64)
    });
    let outputs: Vec<&Path> = a.json.iter().chain(&a.html).map(|p| p.as_path()).collect();
    let inputs: Vec<std::path::PathBuf> = db_file(a.db.db.as_deref())
        .into_iter()
        .chain(a.tolerance.clone())
        .collect();
    output::check_distinct(
        &outputs,
        &inputs.iter().map(|p| p.as_path()).collect::<Vec<_>>(),
    )?;
    let db = crate::history::open_db_read(&a.db)?;
    let records = db.records(None)?;
    for d in &records.damaged {
        eprintln!("warning: {}: {}", db.path(), printable(&d.to_string()));
    }
    let events = db.events(None)?;
    let opts = FleetOptions {
        drift: DriftOptions {
            sigma: a.sigma,
            tolerances,
            ..Default::default()
        },
        now,
        horizon: (a.horizon * 86_400.0).round() as i64,
    };
    let robots = fleet(&records.calibrations, &events, &opts)?;
    let count = |v: Verdict| robots.iter().filter(|r| r.verdict == v).count();
    let summary = format!(
        "{} robots: {} flagged, {} serviced, {} due, {} ok, {} with a single calibration (flag beyond {} sigma or a tolerance; due when a trend crosses a tolerance by {})",
        robots.len(),
        count(Verdict::Flagged),
        count(Verdict::Serviced),
        count(Verdict::Due),
        count(Verdict::Ok),
        count(Verdict::Single),
        a.sigma,
        &format_time(now.saturating_add(opts.horizon))[..10]
    );
    let columns = [
        "serial",
        "verdict",
        "calibrations",
        "last calibration",
        "rms after",
        "why",
    ];
    let rows: Vec<Vec<String>> = robots
        .iter()
        .map(|r| {
            vec![
                printable(&r.robot_id).into_owned(),
                r.verdict.word().to_string(),
                if r.in_segment == r.calibrations {
                    r.calibrations.to_string()
                } else {
                    format!("{} ({} since event)", r.calibrations, r.in_segment)
                },
                format!("{} ({})", &r.last_at[..10], r.last_id),
                format!("{} {}", crate::report::num(r.last_rms_after), r.length_unit),
                why(r),
            ]
        })
        .collect();
    // Text: the table, then the details of every robot that is not ok.
    let widths: Vec<usize> = (0..columns.len() - 1)
        .map(|k| {
            rows.iter()
                .map(|r| r[k].chars().count())
                .chain([columns[k].len()])
                .max()
                .unwrap_or(0)
        })
        .collect();
    println!("{summary}");
    println!();
    let line = |cells: &[&str]| {
        let mut s = String::new();
        for (k, c) in cells.iter().enumerate() {
            if k + 1 == cells.len() {
                s.push_str(c);
            } else if k == 2 || k == 4 {
                let _ = write!(s, "{c:>w$}  ", w = widths[k]);
            } else {
                let _ = write!(s, "{c:<w$}  ", w = widths[k]);
            }
        }
        s.trim_end().to_string()
    };
    println!("{}", line(&columns));
    for r in &rows {
        println!(
            "{}",
            line(&r.iter().map(String::as_str).collect::<Vec<_>>())
        );
    }
    for r in robots.iter().filter(|r| r.verdict != Verdict::Ok) {
        let d = details(r);
        if d.is_empty() {
            continue;
        }
        println!();
        println!("{} ({}):", printable(&r.robot_id), r.verdict.word());
        for l in d {
            println!("  {l}");
        }
    }
    let mut staged = output::Staged::new();
    if let Some(p) = &a.json {
        let doc = serde_json::json!({
            "history": db.path(),
            "now": format_time(now),
            "horizon_days": a.horizon,
            "sigma": a.sigma,
            "robots": robots,
        });
        staged.text(p, &(serde_json::to_string_pretty(&doc)? + "\n"))?;
    }
    if let Some(p) = &a.html {
        let mut charts = Vec::new();
        for r in robots
            .iter()
            .filter(|r| matches!(r.verdict, Verdict::Flagged | Verdict::Due))
        {
            let history: Vec<Calibration> = records
                .calibrations
                .iter()
                .filter(|c| c.robot_id == r.robot_id)
                .cloned()
                .collect();
            let own: Vec<Event> = events
                .iter()
                .filter(|e| e.robot_id == r.robot_id)
                .cloned()
                .collect();
            charts.extend(chart(r, &history, &own));
        }
        let page = FleetPage {
            title: "kinecal fleet".into(),
            summary: format!("{} (history {}, {}).", summary, db.path(), format_time(now)),
            columns: columns.iter().map(|c| c.to_string()).collect(),
            rows: robots
                .iter()
                .zip(rows)
                .map(|(r, cells)| FleetRow {
                    cells,
                    verdict: r.verdict.word().to_ascii_lowercase(),
                })
                .collect(),
            charts,
        };
        staged.text(p, &html_fleet(&page)?)?;
    }
    staged.commit()?;
    for p in a.json.iter().chain(&a.html) {
        eprintln!("wrote {}", p.display());
    }
    let attention = robots.iter().any(|r| {
        matches!(
            r.verdict,
            Verdict::Flagged | Verdict::Serviced | Verdict::Due
        )
    });
    Ok(if attention { EXIT_FLAGGED } else { 0 })
}
