//! The history's pictures and pages: the fleet's table (text and HTML alike), its page with one
//! small chart per robot that needs attention, and a robot's history plot. The figures come
//! from kinecal-history's documents; nothing is computed here.

use std::fmt::Write as _;

use kinecal_history::jobs::{FleetDocument, FleetView, Pages, PlotView};
use kinecal_history::{format_time, printable, samples, Calibration, Event, RobotState, Verdict};

use crate::number::sig;
use crate::page::{esc, inline, page_head};
use crate::{render_png, render_svg, Artist, DrawError, Line, Panel};

/// One row of the fleet table.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FleetRow {
    /// The cells, as text.
    pub cells: Vec<String>,
    /// The verdict, used as the row's class (`flagged`, `serviced`, `due`, `ok`, `single`).
    pub verdict: String,
}

/// One robot's chart.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FleetChart {
    /// The heading (serial and verdict).
    pub heading: String,
    /// Lines of text under the heading (the flagged quantities, the crossing).
    pub notes: Vec<String>,
    /// The chart.
    pub panel: Panel,
}

/// The fleet page's contents.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FleetPage {
    /// Title.
    pub title: String,
    /// A sentence under the title.
    pub summary: String,
    /// Column headings.
    pub columns: Vec<String>,
    /// Rows, most urgent first.
    pub rows: Vec<FleetRow>,
    /// Charts, in the rows' order.
    pub charts: Vec<FleetChart>,
}

/// The fleet page as a self-contained HTML document (inline SVG; opens offline).
pub fn html_fleet(p: &FleetPage) -> Result<String, DrawError> {
    let mut h = page_head(&p.title);
    h.push_str(
        "<style>tr.flagged td{background:#fbe3e3}tr.serviced td{background:#ece4f7}\
         tr.due td{background:#fff4d6}td.v{font-weight:bold;text-align:left}\
         .robots{display:grid;grid-template-columns:repeat(auto-fill,minmax(480px,1fr));gap:12px}\
         .robot{border:1px solid #ccc;padding:6px}.robot h3{margin:2px 0;font-size:15px}\
         .robot p{margin:2px 0;font-size:12px}.robot svg{width:100%;height:auto}</style>\n",
    );
    let _ = writeln!(h, "<h1>{}</h1>\n<p>{}</p>", esc(&p.title), esc(&p.summary));
    h.push_str("<table><tr>");
    for (k, c) in p.columns.iter().enumerate() {
        let class = if k == 0 || k == 1 || k + 1 == p.columns.len() {
            " class=\"l\""
        } else {
            ""
        };
        let _ = write!(h, "<th{class}>{}</th>", esc(c));
    }
    h.push_str("</tr>\n");
    for r in &p.rows {
        let _ = write!(h, "<tr class=\"{}\">", esc(&r.verdict));
        for (k, c) in r.cells.iter().enumerate() {
            let class = if k == 1 {
                " class=\"v\""
            } else if k == 0 || k + 1 == r.cells.len() {
                " class=\"l\""
            } else {
                ""
            };
            let _ = write!(h, "<td{class}>{}</td>", esc(c));
        }
        h.push_str("</tr>\n");
    }
    h.push_str("</table>\n");
    if !p.charts.is_empty() {
        h.push_str("<h2>Robots that need attention</h2>\n<div class=\"robots\">\n");
        for c in &p.charts {
            let _ = write!(h, "<div class=\"robot\"><h3>{}</h3>", esc(&c.heading));
            for n in &c.notes {
                let _ = write!(h, "<p>{}</p>", esc(n));
            }
            h.push_str(&inline(render_svg(std::slice::from_ref(&c.panel), 1)?));
            h.push_str("</div>\n");
        }
        h.push_str("</div>\n");
    }
    h.push_str("</body></html>\n");
    Ok(h)
}

/// Why a robot is listed where it is, in words.
pub fn why(r: &RobotState) -> String {
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
                    day_of(e.at),
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
            day_of(*at)
        ));
    }
    if r.verdict != Verdict::Serviced {
        if let Some(e) = &r.since_event {
            parts.push(format!("since {} ({})", day_of(e.at), printable(&e.note)));
        }
    }
    if parts.is_empty() {
        "-".into()
    } else {
        parts.join("; ")
    }
}

/// The date (`YYYY-MM-DD`) of a Unix time.
fn day_of(at: i64) -> String {
    format_time(at).chars().take(10).collect()
}

/// The detail lines of a robot that is not ok: its flagged quantities and crossings.
pub fn details(r: &RobotState) -> Vec<String> {
    r.trends
        .iter()
        .filter(|t| t.flagged || t.crossing.is_some())
        .map(|t| {
            let rate = match (t.rate_per_month, t.rate_sigma) {
                (Some(v), Some(s)) => format!("{} +- {} {}/month", sig(v, 4), sig(s, 4), t.unit),
                _ => "-".into(),
            };
            let mut s = format!(
                "{} ({}): change {} {} ({:.1} sigma), rate {rate}",
                printable(&t.quantity),
                printable(&t.key),
                sig(t.change, 4),
                t.unit,
                t.significance
            );
            // The tolerance as the user wrote it.
            if let Some(tol) = t.tolerance {
                let _ = write!(s, ", tolerance {tol}");
            }
            if let (Some(c), Some(at)) = (&t.crossing_at, t.crossing) {
                let c: String = c.chars().take(10).collect();
                if t.samples.last().is_some_and(|l| at <= l.at) {
                    let _ = write!(s, ", its trend beyond it since {c}");
                } else {
                    let _ = write!(s, ", crosses it {c}");
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

/// The fleet as a table, the same for text and HTML: a sentence, the columns, one row per
/// robot (most urgent first), and the details of every robot that is not ok.
#[derive(Debug, Clone, Default, PartialEq)]
#[non_exhaustive]
pub struct FleetTable {
    /// The sentence that sums the fleet up.
    pub summary: String,
    /// Column headings.
    pub columns: Vec<String>,
    /// Rows.
    pub rows: Vec<FleetRow>,
    /// Each robot that is not ok and has details: its heading and lines.
    pub details: Vec<(String, Vec<String>)>,
}

/// The fleet's table.
pub fn fleet_table(f: &FleetDocument) -> FleetTable {
    let horizon_end = kinecal_history::parse_time(&f.now)
        .map(|now| day_of(now.saturating_add((f.horizon_days * 86_400.0).round() as i64)))
        .unwrap_or_default();
    let summary = format!(
        "{} robots: {} flagged, {} unknown, {} serviced, {} due, {} ok, {} with a single \
         calibration (flag beyond {} sigma or a tolerance; due when a trend crosses a tolerance \
         by {horizon_end})",
        f.robots.len(),
        f.count(Verdict::Flagged),
        f.count(Verdict::Unknown),
        f.count(Verdict::Serviced),
        f.count(Verdict::Due),
        f.count(Verdict::Ok),
        f.count(Verdict::Single),
        f.sigma,
    );
    let columns = [
        "serial",
        "verdict",
        "calibrations",
        "last calibration",
        "rms after",
        "why",
    ];
    let rows = f
        .robots
        .iter()
        .map(|r| FleetRow {
            cells: vec![
                printable(&r.robot_id).into_owned(),
                r.verdict.word().to_string(),
                if r.in_segment == r.calibrations {
                    r.calibrations.to_string()
                } else {
                    format!("{} ({} since event)", r.calibrations, r.in_segment)
                },
                format!(
                    "{} ({})",
                    r.last_at.chars().take(10).collect::<String>(),
                    r.last_id
                ),
                format!("{} {}", sig(r.last_rms_after, 4), r.length_unit),
                why(r),
            ],
            verdict: r.verdict.word().to_ascii_lowercase(),
        })
        .collect();
    let details = f
        .robots
        .iter()
        .filter(|r| r.verdict != Verdict::Ok)
        .map(|r| {
            (
                format!("{} ({})", printable(&r.robot_id), r.verdict.word()),
                details(r),
            )
        })
        .filter(|(_, d)| !d.is_empty())
        .collect();
    FleetTable {
        summary,
        columns: columns.iter().map(|c| c.to_string()).collect(),
        rows,
        details,
    }
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
    let panel = Panel {
        title: printable(&t.quantity).into_owned(),
        x_label: format!("days since {}", day_of(t0)),
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

/// The fleet's page: its table, and a chart of every flagged or due robot.
pub fn fleet_page(v: &FleetView<'_>) -> Result<String, DrawError> {
    let table = fleet_table(v.fleet);
    let charts = v
        .fleet
        .robots
        .iter()
        .filter(|r| matches!(r.verdict, Verdict::Flagged | Verdict::Due))
        .filter_map(|r| {
            let history: Vec<Calibration> = v
                .calibrations
                .iter()
                .filter(|c| c.robot_id == r.robot_id)
                .cloned()
                .collect();
            let own: Vec<Event> = v
                .events
                .iter()
                .filter(|e| e.robot_id == r.robot_id)
                .cloned()
                .collect();
            chart(r, &history, &own)
        })
        .collect();
    html_fleet(&FleetPage {
        title: "kinecal fleet".into(),
        summary: format!(
            "{} (history {}, {}).",
            table.summary, v.fleet.history, v.fleet.now
        ),
        columns: table.columns,
        rows: table.rows,
        charts,
    })
}

/// A robot's history plot: one panel per quantity, its values with +-1 sigma bars against days
/// since the first calibration, the first value +-3 sigma and the tolerance as reference lines,
/// maintenance events as vertical lines.
pub fn history_panels(v: &PlotView<'_>) -> Vec<Panel> {
    let since = day_of(v.t0);
    v.series
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
                x: pts.iter().map(|p| (p.at - v.t0) as f64 / 86400.0).collect(),
                lines: vec![Line {
                    points: true,
                    error: Some(pts.iter().map(|p| p.sigma).collect()),
                    ..Line::new("value +-1 sigma", pts.iter().map(|p| p.value).collect())
                }],
                h_lines,
                v_lines: v
                    .events
                    .iter()
                    .map(|e| {
                        (
                            (e.at - v.t0) as f64 / 86400.0,
                            format!("event: {}", printable(&e.note)),
                        )
                    })
                    .collect(),
                ..Default::default()
            }
        })
        .collect()
}

impl Pages for Artist {
    fn history_plot(&self, plot: &PlotView<'_>, png: bool) -> Result<Vec<u8>, String> {
        let panels = history_panels(plot);
        if png {
            render_png(&panels, 1).map_err(|e| e.to_string())
        } else {
            render_svg(&panels, 1)
                .map(String::into_bytes)
                .map_err(|e| e.to_string())
        }
    }

    fn fleet_page(&self, fleet: &FleetView<'_>) -> Result<String, String> {
        fleet_page(fleet).map_err(|e| e.to_string())
    }
}
