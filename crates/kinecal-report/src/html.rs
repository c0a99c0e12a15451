//! The self-contained HTML calibration report: inline SVG, inline CSS, no script, no link to
//! anything outside the file.

use std::fmt::Write as _;

use kinecal::identifiability::format_combination;
use kinecal::observe::{for_each_observation, Context, Dataset, OrientationError};
use kinecal::units::Quantity;
use kinecal::workflow::Outcome;

use crate::chart::{render_svg, Line, Panel};
use crate::DrawError;

/// A number as a person reads it: six decimals, or four significant digits below 1e-5, where six
/// decimals would keep fewer than two.
fn num(v: f64) -> String {
    if v != 0.0 && v.abs() < 1e-5 {
        format!("{v:.3e}")
    } else {
        format!("{v:.6}")
    }
}

fn cap(s: &str) -> String {
    let mut c = s.chars();
    c.next()
        .map(|f| f.to_uppercase().chain(c).collect())
        .unwrap_or_default()
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// Inline SVG: the namespace declaration is dropped (HTML5 knows inline SVG), so the file holds
/// no URL at all.
fn inline(svg: String) -> String {
    svg.replace(" xmlns=\"http://www.w3.org/2000/svg\"", "")
        .replace(" xmlns:xlink=\"http://www.w3.org/1999/xlink\"", "")
}

/// Per observation: (length error in its metric, attitude error) in file units, for `robot`.
fn errors(robot: &kinecal::Robot, data: &Dataset) -> Vec<(f64, Option<f64>)> {
    let u = robot.units;
    let ctx = Context {
        robot,
        orientation: OrientationError::default(),
    };
    let mut out = Vec::with_capacity(data.observations.len());
    for_each_observation(robot, data, |_, o, frames| {
        let e = o.error(&ctx, frames);
        out.push((
            u.from_si(Quantity::Length, e.length),
            e.angle.map(|a| u.from_si(Quantity::Angle, a)),
        ));
    });
    out
}

/// The HTML report of a calibration outcome.
pub fn html_report(outcome: &Outcome) -> Result<String, DrawError> {
    let (cal, data, rep, u) = (
        &outcome.calibration,
        &outcome.data,
        &outcome.report,
        outcome.uncertainty.as_ref(),
    );
    let (l, a) = (&rep.length_unit, &rep.angle_unit);
    let mut h = String::new();
    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>kinecal calibration report: {}</title>\n\
         <style>body{{font-family:sans-serif;max-width:1200px;margin:2em auto;color:#222}}\
         table{{border-collapse:collapse;margin:1em 0}}td,th{{border:1px solid #bbb;padding:3px 8px;text-align:right}}\
         th{{background:#eee}}td.l,th.l{{text-align:left}}.warn{{color:#a33}}svg{{max-width:100%;height:auto}}</style></head><body>\n",
        esc(&rep.robot)
    );
    let _ = writeln!(h, "<h1>Calibration report: {}</h1>", esc(&rep.robot));
    let _ = writeln!(
        h,
        "<p>{} postures, {} observations ({}), {} residuals; method <b>{}</b>, {} orientation residuals, {} solution; {} after {} iterations ({}).</p>",
        rep.postures,
        rep.measurements,
        esc(&rep
            .observations
            .iter()
            .map(|k| format!("{} {}{}", k.count, k.kind, if k.count == 1 { "" } else { "s" }))
            .collect::<Vec<_>>()
            .join(", ")),
        rep.residuals,
        esc(&rep.method),
        esc(&rep.orientation_error),
        esc(&rep.solution),
        if rep.converged { "converged" } else { "NOT converged" },
        rep.iterations,
        esc(&rep.termination)
    );
    let _ = writeln!(h, "<h2 id=\"summary\">Summary</h2><table><tr><th class=\"l\"></th><th>before</th><th>after</th></tr>");
    let (ib, ia) = (&rep.identification.before, &rep.identification.after);
    let mut rows = vec![(
        "objective (weighted)".to_string(),
        rep.objective_before,
        rep.objective_after,
    )];
    if ib.positions > 0 {
        rows.push((
            format!("RMS position error ({l})"),
            rep.rms_position_before,
            rep.rms_position_after,
        ));
        rows.push((
            format!("max position error ({l})"),
            rep.max_position_before,
            rep.max_position_after,
        ));
    }
    for (b, af) in ib.other.iter().zip(&ia.other) {
        rows.push((format!("RMS {} error ({l})", b.metric), b.rms, af.rms));
        rows.push((format!("max {} error ({l})", b.metric), b.max, af.max));
    }
    if let (Some(rb), Some(ra), Some(mb), Some(ma)) = (
        rep.rms_orientation_before,
        rep.rms_orientation_after,
        rep.max_orientation_before,
        rep.max_orientation_after,
    ) {
        rows.push((format!("RMS attitude error ({a})"), rb, ra));
        rows.push((format!("max attitude error ({a})"), mb, ma));
    }
    for (name, b, af) in rows {
        let _ = writeln!(
            h,
            "<tr><td class=\"l\">{}</td><td>{}</td><td>{}</td></tr>",
            esc(&name),
            num(b),
            num(af)
        );
    }
    let _ = writeln!(h, "</table>");
    if let Some(v) = &rep.validation {
        let _ = writeln!(
            h,
            "<p>Validation ({} postures): position error RMS {:.6} &rarr; {:.6} {l}, max {:.6} &rarr; {:.6} {l}.</p>",
            v.postures, v.before.rms_position, v.after.rms_position, v.before.max_position, v.after.max_position
        );
    }

    // Residuals per observation, before and after: positions, or lengths of several metrics.
    let kind_of_error = if outcome.identification.after.other.is_empty() {
        "position"
    } else if outcome.identification.after.positions == 0
        && outcome.identification.after.other.len() == 1
    {
        outcome.identification.after.other[0].metric
    } else {
        "length"
    };
    let (eb, ea) = (errors(&cal.initial, data), errors(&cal.calibrated, data));
    let x: Vec<f64> = (1..=eb.len()).map(|i| i as f64).collect();
    let mut panels = vec![Panel {
        title: format!("{} error per observation", cap(kind_of_error)),
        x_label: "observation (file order by posture)".into(),
        y_label: format!("{kind_of_error} error ({l})"),
        x: x.clone(),
        lines: vec![
            Line {
                points: true,
                ..Line::new("before", eb.iter().map(|e| e.0).collect())
            },
            Line {
                points: true,
                ..Line::new("after", ea.iter().map(|e| e.0).collect())
            },
        ],
        ..Default::default()
    }];
    if eb.iter().any(|e| e.1.is_some()) {
        panels.push(Panel {
            title: "Attitude error per observation".into(),
            x_label: "observation".into(),
            y_label: format!("attitude error ({a})"),
            x,
            lines: vec![
                Line {
                    points: true,
                    ..Line::new(
                        "before",
                        eb.iter().map(|e| e.1.unwrap_or(f64::NAN)).collect(),
                    )
                },
                Line {
                    points: true,
                    ..Line::new(
                        "after",
                        ea.iter().map(|e| e.1.unwrap_or(f64::NAN)).collect(),
                    )
                },
            ],
            ..Default::default()
        });
    }
    let _ = writeln!(
        h,
        "<h2 id=\"residuals\">Residuals per posture</h2>\n{}",
        inline(render_svg(&panels, 2)?)
    );

    // Histogram of the position errors after calibration.
    let after: Vec<f64> = ea.iter().map(|e| e.0).collect();
    let max = after
        .iter()
        .copied()
        .fold(0.0, f64::max)
        .max(f64::MIN_POSITIVE);
    let bins = 20usize;
    let mut counts = vec![0.0; bins];
    for e in &after {
        counts[((e / max * bins as f64) as usize).min(bins - 1)] += 1.0;
    }
    let centers: Vec<f64> = (0..bins)
        .map(|i| (i as f64 + 0.5) * max / bins as f64)
        .collect();
    let hist = Panel {
        title: format!("Histogram of {kind_of_error} errors after calibration"),
        x_label: format!("{kind_of_error} error ({l})"),
        y_label: "measurements".into(),
        x: centers,
        lines: vec![Line {
            points: true,
            error: Some(counts.iter().map(|c| c / 2.0).collect()),
            ..Line::new("count", counts.iter().map(|c| c / 2.0).collect())
        }],
        ..Default::default()
    };
    let _ = writeln!(
        h,
        "<h2 id=\"histogram\">Error histogram</h2>\n{}",
        inline(render_svg(&[hist], 1)?)
    );

    // Parameter changes with +-sigma bars, one chart per unit.
    // (unit, [(parameter number, change, sigma)])
    type Group = (String, Vec<(f64, f64, f64)>);
    let mut groups: Vec<Group> = Vec::new();
    for p in rep.parameters.iter().filter(|p| p.estimated_flag) {
        let n: f64 = p.id[1..].parse().unwrap_or(0.0);
        let entry = match groups.iter_mut().find(|g| g.0 == p.unit) {
            Some(g) => g,
            None => {
                groups.push((p.unit.clone(), Vec::new()));
                groups.last_mut().expect("just pushed")
            }
        };
        entry.1.push((n, p.change, p.sigma.unwrap_or(0.0)));
    }
    let panels: Vec<Panel> = groups
        .iter()
        .map(|(unit, pts)| Panel {
            title: format!("Parameter changes ({unit}), +-1 sigma"),
            x_label: "parameter number (p#)".into(),
            y_label: format!("change ({unit})"),
            x: pts.iter().map(|p| p.0).collect(),
            lines: vec![Line {
                points: true,
                error: Some(pts.iter().map(|p| p.2).collect()),
                ..Line::new("change", pts.iter().map(|p| p.1).collect())
            }],
            h_lines: vec![(0.0, "no change".into())],
            ..Default::default()
        })
        .collect();
    let _ = writeln!(h, "<h2 id=\"changes\">Parameter changes</h2>");
    if !panels.is_empty() {
        let _ = writeln!(h, "{}", inline(render_svg(&panels, 2)?));
    }
    let _ = writeln!(h, "<table><tr><th class=\"l\">id</th><th class=\"l\">name</th><th class=\"l\">unit</th><th>initial</th><th>estimated</th><th>change</th><th>sigma</th><th>change/sigma</th></tr>");
    for p in rep.parameters.iter().filter(|p| p.estimated_flag) {
        let _ = writeln!(
            h,
            "<tr><td class=\"l\">{}</td><td class=\"l\">{}</td><td class=\"l\">{}</td><td>{:.6}</td><td>{:.6}</td><td>{:+.6}</td><td>{}</td><td>{}</td></tr>",
            p.id,
            esc(&p.name),
            esc(&p.unit),
            p.initial,
            p.estimated,
            p.change,
            p.sigma.map_or("not determined alone".into(), |s| format!("{s:.3e}")),
            p.significance.map_or(String::new(), |z| format!("{z:.1}{}", if z < 2.0 { " (within noise)" } else { "" }))
        );
    }
    let _ = writeln!(h, "</table>");

    // Singular values.
    if let Some(u) = u {
        let an = &u.analysis;
        let n = an.singular_values_scaled.len();
        let smax = an.singular_values_scaled.first().copied().unwrap_or(1.0);
        let floor = smax * 1e-18;
        let spectrum = Panel {
            title: format!(
                "Singular values of the scaled Jacobian: rank {} of {n}",
                an.rank
            ),
            x_label: "index".into(),
            y_label: "singular value (scaled)".into(),
            x: (1..=n).map(|i| i as f64).collect(),
            lines: vec![Line {
                points: true,
                ..Line::new(
                    "singular value",
                    an.singular_values_scaled
                        .iter()
                        .map(|s| s.max(floor))
                        .collect(),
                )
            }],
            h_lines: vec![(
                an.rcond * smax,
                format!("rank cut ({:e} x largest)", an.rcond),
            )],
            log_y: true,
            ..Default::default()
        };
        let _ = writeln!(
            h,
            "<h2 id=\"spectrum\">Singular-value spectrum</h2>\n{}",
            inline(render_svg(&[spectrum], 1)?)
        );
        if let Some(e) = &an.expected {
            let _ = writeln!(
                h,
                "<p>Thesis count: {}; measured rank {}.</p>",
                esc(&e.formula),
                an.rank
            );
        }
        let _ = writeln!(
            h,
            "<h2 id=\"redundancy\">Redundant groups and determined combinations</h2>"
        );
        if an.identical_groups.is_empty() {
            let _ = writeln!(
                h,
                "<p>No identical redundancy among the estimated parameters.</p>"
            );
        } else {
            let _ = writeln!(h, "<table><tr><th class=\"l\">combination</th><th>value</th><th class=\"l\">determined</th></tr>");
            for g in &an.identical_groups {
                let _ = writeln!(
                    h,
                    "<tr><td class=\"l\">{}</td><td>{:.6}</td><td class=\"l\">{}</td></tr>",
                    esc(&format_combination(&g.terms)),
                    g.value,
                    if g.determined {
                        "yes"
                    } else {
                        "no: members also enter other dependencies"
                    }
                );
            }
            let _ = writeln!(h, "</table>");
        }
        for c in &rep.combinations {
            let _ = writeln!(
                h,
                "<p>{} = {:.6} (was {:.6}, sigma {:.3e}, change {:.1} sigma)</p>",
                esc(&c.expression),
                c.value,
                c.initial,
                c.sigma,
                c.significance
            );
        }
        if !rep.undetermined.is_empty() {
            let _ = writeln!(
                h,
                "<p>Not individually determined: {}.</p>",
                esc(&rep.undetermined.join(", "))
            );
        }
    }
    let _ = writeln!(h, "<h2 id=\"warnings\">Warnings</h2>");
    if rep.warnings.is_empty() && rep.outliers.is_empty() {
        let _ = writeln!(h, "<p>None.</p>");
    }
    for w in &rep.warnings {
        let _ = writeln!(h, "<p class=\"warn\">{}</p>", esc(w));
    }
    for o in &rep.outliers {
        let _ = writeln!(
            h,
            "<p class=\"warn\">Outlier: line {} posture {} site {}: position error {:.6} {l} ({:.1} sigma)</p>",
            o.line,
            esc(&o.posture),
            esc(&o.site),
            o.position_error,
            o.sigmas
        );
    }
    let _ = writeln!(
        h,
        "<p><small>Written by kinecal {}.</small></p></body></html>",
        env!("CARGO_PKG_VERSION")
    );
    Ok(h)
}
