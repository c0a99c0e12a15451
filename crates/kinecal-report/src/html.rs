//! The self-contained HTML calibration report: inline SVG, inline CSS, no script, no link to
//! anything outside the file.

use std::fmt::Write as _;

use kinecal::report::CalibrationReport;

use crate::chart::{render_svg, Line, Panel};
use crate::display::{combination_unit, Convert, DisplayUnits};
use crate::number::{fixed, num};
use crate::DrawError;

fn cap(s: &str) -> String {
    let mut c = s.chars();
    c.next()
        .map(|f| f.to_uppercase().chain(c).collect())
        .unwrap_or_default()
}

pub(crate) fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// Inline SVG: the namespace declaration is dropped (HTML5 knows inline SVG), so the file holds
/// no URL at all.
pub(crate) fn inline(svg: String) -> String {
    svg.replace(" xmlns=\"http://www.w3.org/2000/svg\"", "")
        .replace(" xmlns:xlink=\"http://www.w3.org/1999/xlink\"", "")
}

/// One table per kind of error present (positions, attitudes, distances, contacts): RMS, mean,
/// p95 and max on the identification and validation data, before and after; `n/a` where a set
/// has none of that kind.
fn validation_tables(
    h: &mut String,
    rep: &kinecal::report::CalibrationReport,
    v: &kinecal::report::DatasetAccuracy,
    l: &str,
    a: &str,
) {
    use kinecal::report::ErrorStats;
    let rows: [(String, &ErrorStats); 4] = [
        (
            format!(
                "identification ({} postures) before",
                rep.identification.postures
            ),
            &rep.identification.before,
        ),
        ("identification after".into(), &rep.identification.after),
        (
            format!("validation ({} postures) before", v.postures),
            &v.before,
        ),
        ("validation after".into(), &v.after),
    ];
    type Pick<'a> = Box<dyn Fn(&ErrorStats) -> Option<[f64; 4]> + 'a>;
    let mut tables: Vec<(String, Pick<'_>)> = Vec::new();
    if rows.iter().any(|(_, e)| e.positions > 0) {
        tables.push((
            format!("Position error ({l})"),
            Box::new(|e: &ErrorStats| {
                (e.positions > 0).then_some([
                    e.rms_position,
                    e.mean_position,
                    e.p95_position,
                    e.max_position,
                ])
            }),
        ));
    }
    if rows.iter().any(|(_, e)| e.rms_orientation.is_some()) {
        tables.push((
            format!("Attitude error ({a})"),
            Box::new(|e: &ErrorStats| {
                Some([
                    e.rms_orientation?,
                    e.mean_orientation?,
                    e.p95_orientation?,
                    e.max_orientation?,
                ])
            }),
        ));
    }
    let mut metrics: Vec<String> = Vec::new();
    for (_, e) in &rows {
        for m in &e.other {
            if !metrics.contains(&m.metric) {
                metrics.push(m.metric.clone());
            }
        }
    }
    for metric in metrics {
        tables.push((
            format!("{} error ({l})", cap(&metric)),
            Box::new(move |e: &ErrorStats| {
                e.other
                    .iter()
                    .find(|m| m.metric == metric)
                    .map(|m| [m.rms, m.mean, m.p95, m.max])
            }),
        ));
    }
    for (title, pick) in &tables {
        let _ = writeln!(
            h,
            "<table><tr><th class=\"l\">{}</th><th>RMS</th><th>mean</th><th>p95</th><th>max</th></tr>",
            esc(title)
        );
        for (name, e) in &rows {
            let cells: Vec<String> = match pick(e) {
                Some(v) => v.iter().map(|&x| num(x)).collect(),
                None => vec!["n/a".into(); 4],
            };
            let _ = writeln!(
                h,
                "<tr><td class=\"l\">{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                esc(name),
                cells[0],
                cells[1],
                cells[2],
                cells[3]
            );
        }
        let _ = writeln!(h, "</table>");
    }
}

/// The start of a self-contained page titled `title` (escaped here): the shared inline style,
/// up to the opening `<body>`.
pub(crate) fn page_head(title: &str) -> String {
    format!(
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{}</title>\n\
         <style>body{{font-family:sans-serif;max-width:1200px;margin:2em auto;color:#222}}\
         table{{border-collapse:collapse;margin:1em 0}}td,th{{border:1px solid #bbb;padding:3px 8px;text-align:right}}\
         th{{background:#eee}}td.l,th.l{{text-align:left}}.warn{{color:#a33}}svg{{max-width:100%;height:auto}}.charts{{display:flex;flex-wrap:wrap;gap:0}}.charts svg{{max-width:50%}}\
         .verdict{{border-left:8px solid #4a4;background:#f2f8f2;padding:0.6em 1em;margin:1em 0}}.verdict.caution{{border-color:#c90;background:#fbf6ea}}.verdict.failed{{border-color:#c33;background:#fbeeee}}.verdict p.head{{font-size:1.15em;font-weight:bold;margin:0.2em 0}}\
         .error{{color:#a22;font-weight:bold}}.caution{{color:#8a5a00}}.note{{color:#555}}dl.facts{{display:grid;grid-template-columns:max-content auto;gap:2px 1em;font-size:0.9em}}dl.facts dt{{color:#555}}dl.facts dd{{margin:0}}</style></head><body>\n",
        esc(title)
    )
}

/// Each panel as its own inline SVG, side by side while the page is wide enough.
pub(crate) fn charts(panels: &[Panel]) -> Result<String, DrawError> {
    let mut out = String::from("<div class=\"charts\">");
    for p in panels {
        out += &inline(render_svg(std::slice::from_ref(p), 1)?);
    }
    out += "</div>";
    Ok(out)
}

/// The HTML report of a calibration, drawn from its report alone (`kinecal report --from`
/// rebuilds the same page from the JSON), in the default display units of its robot
/// ([`DisplayUnits::for_robot`]: millimetres and degrees for a metre-radian robot).
pub fn html_report(rep: &CalibrationReport) -> Result<String, DrawError> {
    html_report_in(
        rep,
        DisplayUnits::for_robot(rep.length_unit, rep.angle_unit),
    )
}

/// [`html_report`] with its lengths and angles shown in `units`.
pub fn html_report_in(rep: &CalibrationReport, units: DisplayUnits) -> Result<String, DrawError> {
    let c = Convert::of(rep, units);
    let verdict = verdict_section(rep, units);
    // Every number below is in display units, every unit from `c`.
    let rep = &crate::display::calibration(rep, &c);
    let (l, a) = (c.l(), c.a());
    // A robot without a name (an imported DH table) gets none, not a dangling colon.
    let named = if rep.robot.trim().is_empty() {
        String::new()
    } else {
        format!(": {}", rep.robot)
    };
    let mut h = page_head(&format!("kinecal calibration report{named}"));
    let _ = writeln!(h, "<h1>Calibration report{}</h1>", esc(&named));
    h += &verdict;
    h += &facts_section(rep);
    let kinds = rep
        .observations
        .iter()
        .map(|k| {
            format!(
                "{} {}{}",
                k.count,
                k.kind,
                if k.count == 1 { "" } else { "s" }
            )
        })
        .collect::<Vec<_>>()
        .join(", ");
    let how = if rep.given {
        format!(
            "{} orientation residuals; a given calibration, assessed on these data (not solved here)",
            esc(rep.orientation_error.as_str())
        )
    } else {
        format!(
            "method <b>{}</b>, {} orientation residuals, {} solution; {} after {} iterations ({})",
            esc(rep.method.as_str()),
            esc(rep.orientation_error.as_str()),
            esc(&rep.solution),
            if rep.converged {
                "converged"
            } else {
                "NOT converged"
            },
            rep.iterations,
            esc(rep.termination.describe())
        )
    };
    let _ = writeln!(
        h,
        "<p>{} postures, {} observations ({}), {} residuals; {how}.</p>",
        rep.postures,
        rep.measurements,
        esc(&kinds),
        rep.residuals
    );
    if let Some(p) = &rep.start_placement {
        let _ = writeln!(
            h,
            "<p>Far start: the measurement frame and the measured frames were first placed in closed form (RMS position error {} &rarr; {} {}).</p>",
            num(p.rms_before),
            num(p.rms_after),
            esc(l)
        );
    }
    if let Some(n) = rep.down_weighted_rows {
        let _ = writeln!(
            h,
            "<p>Loss {}: {n} of {} residual rows down-weighted.</p>",
            esc(&rep.loss),
            rep.residuals
        );
    }
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
        let _ = writeln!(h, "<h2 id=\"validation\">Validation</h2>");
        validation_tables(&mut h, rep, v, l, a);
    }
    if !rep.model_choice.is_empty() {
        let _ = writeln!(
            h,
            "<h2 id=\"model-choice\">Model choice</h2><p>Candidates from the simplest up, cross-validated on the same folds; chosen: the first within one standard error of the best held-out mean ({l}).</p>"
        );
        let _ = writeln!(h, "<table><tr><th class=\"l\">candidate</th><th>parameters</th><th>held-out mean</th><th>std. error</th><th class=\"l\"></th></tr>");
        for c in &rep.model_choice {
            let _ = writeln!(
                h,
                "<tr><td class=\"l\">{}</td><td>{}</td><td>{}</td><td>{}</td><td class=\"l\">{}</td></tr>",
                esc(&c.candidate),
                c.parameters,
                num(c.mean),
                num(c.standard_error),
                if c.chosen { "<b>chosen</b>" } else { "" }
            );
        }
        let _ = writeln!(h, "</table>");
    }
    if let Some(cv) = &rep.cross_validation {
        let _ = writeln!(
            h,
            "<h2 id=\"cross-validation\">Cross-validation</h2><p>{} folds by posture ({}): each fold's calibration checked on the postures it left out; held-out {} error ({l}).</p>",
            cv.folds.len(),
            match cv.seed {
                Some(seed) => format!("shuffled with seed {seed}"),
                None => "interleaved in file order".to_string(),
            },
            esc(&cv.metric)
        );
        let _ = writeln!(h, "<table><tr><th class=\"l\">fold</th><th>postures</th><th>observations</th><th>mean</th><th>RMS</th><th>p95</th><th>max</th></tr>");
        for (i, f) in cv.folds.iter().enumerate() {
            let e = &f.errors;
            let _ = writeln!(
                h,
                "<tr><td class=\"l\">{}{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                i + 1,
                if f.converged { "" } else { " (NOT converged)" },
                f.postures,
                e.count,
                num(e.mean),
                num(e.rms),
                num(e.p95),
                num(e.max)
            );
        }
        let o = &cv.overall;
        let _ = writeln!(
            h,
            "<tr><th class=\"l\">all</th><th>{}</th><th>{}</th><th>{}</th><th>{}</th><th>{}</th><th>{}</th></tr></table>",
            cv.folds.iter().map(|f| f.postures).sum::<usize>(),
            o.count,
            num(o.mean),
            num(o.rms),
            num(o.p95),
            num(o.max)
        );
        let _ = writeln!(
            h,
            "<p>Held-out mean {} {l}; bootstrap 95 % interval {} to {} {l}.</p>",
            num(o.mean),
            num(cv.mean_low),
            num(cv.mean_high)
        );
    }

    // Errors per observation, before and after: positions, or lengths of several metrics.
    if let Some(oe) = &rep.observation_errors {
        let kind_of_error = oe.metric.as_str();
        let note = if oe.run == 1 {
            String::new()
        } else {
            format!(" (largest of each {} consecutive)", oe.run)
        };
        let x: Vec<f64> = (0..oe.before.len())
            .map(|i| (i * oe.run + 1) as f64)
            .collect();
        let nan = |v: &[Option<f64>]| v.iter().map(|a| a.unwrap_or(f64::NAN)).collect();
        // Log axes: the errors after calibration are 10-1000 times smaller than before, and
        // both must be readable.
        let mut panels = vec![Panel {
            title: format!("{} error per observation{note}", cap(kind_of_error)),
            x_label: "observation (file order by posture)".into(),
            y_label: format!("{kind_of_error} error ({l}, log scale)"),
            log_y: true,
            x: x.clone(),
            lines: vec![
                Line {
                    points: true,
                    ..Line::new("before", oe.before.clone())
                },
                Line {
                    points: true,
                    ..Line::new("after", oe.after.clone())
                },
            ],
            ..Default::default()
        }];
        if let (Some(ab), Some(aa)) = (&oe.attitude_before, &oe.attitude_after) {
            panels.push(Panel {
                title: format!("Attitude error per observation{note}"),
                x_label: "observation (file order by posture)".into(),
                y_label: format!("attitude error ({a}, log scale)"),
                log_y: true,
                x,
                lines: vec![
                    Line {
                        points: true,
                        ..Line::new("before", nan(ab))
                    },
                    Line {
                        points: true,
                        ..Line::new("after", nan(aa))
                    },
                ],
                ..Default::default()
            });
        }
        let _ = writeln!(
            h,
            "<h2 id=\"residuals\">Errors per observation</h2>\n{}",
            charts(&panels)?
        );

        // Histogram of the errors after calibration: bars of a round width, integer counts.
        let width = oe.histogram_width;
        let hist = Panel {
            title: format!(
                "Histogram of {kind_of_error} errors after calibration ({} observations)",
                oe.observations
            ),
            x_label: format!(
                "{kind_of_error} error ({l}; bins of {})",
                crate::chart::tick_label(width, width)
            ),
            y_label: "observations".into(),
            bars: oe
                .histogram
                .iter()
                .enumerate()
                .map(|(i, &c)| (i as f64 * width, (i + 1) as f64 * width, c as f64))
                .collect(),
            ..Default::default()
        };
        let _ = writeln!(
            h,
            "<h2 id=\"histogram\">Error histogram</h2>\n{}",
            inline(render_svg(&[hist], 1)?)
        );
    }

    // Parameter changes with +-sigma bars, one chart per unit.
    // (unit, [(parameter id, change, sigma)])
    type Group = (String, Vec<(String, f64, f64)>);
    let mut groups: Vec<Group> = Vec::new();
    for p in rep.parameters.iter().filter(|p| p.estimated_flag) {
        let entry = match groups.iter_mut().find(|g| g.0 == p.unit) {
            Some(g) => g,
            None => {
                groups.push((p.unit.clone(), Vec::new()));
                groups.last_mut().expect("just pushed")
            }
        };
        entry
            .1
            // No bar for a sigma not determined.
            .push((p.id.clone(), p.change, p.sigma.unwrap_or(f64::NAN)));
    }
    let panels: Vec<Panel> = groups
        .iter()
        .map(|(unit, pts)| Panel {
            title: format!("Parameter changes ({unit}), +-1 sigma"),
            x_label: "parameter".into(),
            y_label: format!("change ({unit})"),
            x: (0..pts.len()).map(|i| i as f64).collect(),
            x_names: pts.iter().map(|p| p.0.clone()).collect(),
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
        let _ = writeln!(h, "{}", charts(&panels)?);
    }
    let _ = writeln!(h, "<table><tr><th class=\"l\">id</th><th class=\"l\">name</th><th class=\"l\">unit</th><th>initial</th><th>estimated</th><th>change</th><th>sigma</th><th>change/sigma</th></tr>");
    for p in rep.parameters.iter().filter(|p| p.estimated_flag) {
        let _ = writeln!(
            h,
            "<tr><td class=\"l\">{}</td><td class=\"l\">{}</td><td class=\"l\">{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            p.id,
            esc(&p.name),
            esc(&p.unit),
            // Six decimals for lengths and angles; a compliance (1e-6..1e-3) in significant
            // digits.
            if p.unit.contains("/(N ") { num(p.initial) } else { fixed(p.initial, 6) },
            if p.unit.contains("/(N ") { num(p.estimated) } else { fixed(p.estimated, 6) },
            crate::number::signed(p.change, 4),
            p.sigma.map_or("not determined alone".into(), num),
            p.significance.map_or(String::new(), |z| format!("{z:.1}{}", if p.within_noise == Some(true) { " (within noise)" } else { "" }))
        );
    }
    let _ = writeln!(h, "</table>");

    // The prior: what it added to the objective, and what it (not the data) determines.
    if let Some(pr) = &rep.prior {
        let estimated = rep.parameters.iter().filter(|p| p.estimated_flag).count();
        let _ = writeln!(
            h,
            "<h2 id=\"prior\">Prior</h2>\n<p>A Gaussian prior on the changes, <code>{}</code>: {} \
             rows after the data's. Objective after: data {}, prior {}. Rank {}{} of {} \
             estimated parameters with the prior. The prior alone determines {} of them and \
             splits {} from the combinations the data determines (the last column).</p>",
            esc(&pr.prior),
            pr.rows,
            num(pr.data_objective_after),
            num(pr.prior_objective_after),
            rep.rank.map_or("?".into(), |r| r.to_string()),
            pr.data_rank
                .map_or(String::new(), |r| format!(" ({r} on the data alone)")),
            estimated,
            pr.determined_by_prior_alone.len(),
            pr.split_by_prior.len()
        );
        let _ = writeln!(h, "<table><tr><th class=\"l\">id</th><th class=\"l\">name</th><th class=\"l\">unit</th><th>prior sigma</th><th>sigma</th><th>data share</th><th class=\"l\">determined by</th></tr>");
        for p in rep
            .parameters
            .iter()
            .filter(|p| p.estimated_flag && p.prior_sigma.is_some())
        {
            let opt = |v: Option<f64>| v.map_or(String::new(), num);
            let _ = writeln!(
                h,
                "<tr><td class=\"l\">{}</td><td class=\"l\">{}</td><td class=\"l\">{}</td><td>{}</td><td>{}</td><td>{}</td><td class=\"l\">{}</td></tr>",
                p.id,
                esc(&p.name),
                esc(&p.unit),
                opt(p.prior_sigma),
                opt(p.sigma),
                p.data_share.map_or(String::new(), |f| format!("{:.0} %", 100.0 * f)),
                esc(p.determined_by.as_deref().unwrap_or(""))
            );
        }
        let _ = writeln!(h, "</table>");
    }

    // The mass model of an elastic robot: its equilibrium and the joints' stiffnesses.
    if let Some(e) = &rep.elastic {
        let _ = writeln!(
            h,
            "<h2 id=\"mass-model\">Mass model</h2>\n<p>{} bodies, {} kg, gravity {} {}/s&sup2;; \
             equilibrium {} at {} of {} postures (at most {} iterations); largest deflection {} \
             {} under gravity torques up to {} N m.</p>",
            e.bodies,
            num(e.total_mass),
            num(e.gravity),
            esc(l),
            esc(&e.equilibrium),
            rep.postures.saturating_sub(e.unconverged_postures),
            rep.postures,
            e.iterations_max,
            num(e.largest_deflection),
            esc(a),
            num(e.largest_torque)
        );
        let _ = writeln!(h, "<table><tr><th class=\"l\">compliance</th><th>value</th><th>sigma</th><th>stiffness</th><th>sigma</th><th class=\"l\">unit</th><th class=\"l\">estimated</th></tr>");
        for j in &e.joints {
            let opt = |v: Option<f64>| v.map_or(String::new(), num);
            let _ = writeln!(
                h,
                "<tr><td class=\"l\">{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td class=\"l\">{}</td><td class=\"l\">{}</td></tr>",
                esc(&j.name),
                num(j.compliance),
                opt(j.compliance_sigma),
                opt(j.stiffness),
                opt(j.stiffness_sigma),
                esc(&j.stiffness_unit),
                if j.estimated { "yes" } else { "no" }
            );
        }
        let _ = writeln!(h, "</table>");
    }

    // Singular values.
    if let Some(an) = &rep.spectrum {
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
        if let Some(formula) = &an.expected {
            let _ = writeln!(
                h,
                "<p>Thesis count: {}; measured rank {}.</p>",
                esc(formula),
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
            let _ = writeln!(h, "<table><tr><th class=\"l\">combination</th><th>value</th><th class=\"l\">unit</th><th class=\"l\">determined</th></tr>");
            for g in &an.identical_groups {
                let _ = writeln!(
                    h,
                    "<tr><td class=\"l\">{}</td><td>{}</td><td class=\"l\">{}</td><td class=\"l\">{}</td></tr>",
                    esc(&g.expression),
                    fixed(g.value, 6),
                    esc(&combination_unit(rep, &g.expression)),
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
                "<p>{} = {} {unit} (was {}, sigma {}, change {:.1} sigma)</p>",
                esc(&c.expression),
                fixed(c.value, 6),
                fixed(c.initial, 6),
                num(c.sigma),
                c.significance,
                unit = esc(&combination_unit(rep, &c.expression))
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
    if let Some(p) = &rep.prediction {
        h += &crate::predict::section(p, l, a);
    }
    let _ = writeln!(h, "<h2 id=\"warnings\">Warnings</h2>");
    if rep.warnings.is_empty() && rep.outliers.is_empty() {
        let _ = writeln!(h, "<p>None.</p>");
    }
    for w in crate::verdict::ranked_warnings(rep) {
        let class = w.severity.as_str();
        let _ = writeln!(
            h,
            "<p class=\"{class}\"><b>{class}:</b> {}</p>",
            esc(&w.text)
        );
    }
    for o in &rep.outliers {
        let _ = writeln!(
            h,
            "<p class=\"warn\">Outlier: line {} posture {} site {}: {} error {} {l} ({:.1} sigma)</p>",
            o.line,
            esc(&o.posture),
            esc(&o.site),
            esc(&o.metric),
            num(o.position_error),
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

/// The verdict, first on the page: a banner of its level, what happened, the accuracy reached,
/// and what to do next.
fn verdict_section(rep: &CalibrationReport, units: DisplayUnits) -> String {
    let v = crate::verdict::verdict(rep, units);
    let mut h = format!(
        "<div class=\"verdict {}\" id=\"verdict\"><p class=\"head\">{}</p>\n",
        v.level.as_str(),
        esc(&v.headline)
    );
    if !v.figures.is_empty() {
        h += "<table>";
        for (label, value) in &v.figures {
            let _ = write!(
                h,
                "<tr><td class=\"l\">{}</td><td class=\"l\"><b>{}</b></td></tr>",
                esc(label),
                esc(value)
            );
        }
        h += "</table>\n";
    }
    h += "<p>Next:</p><ul>";
    for n in &v.next {
        let _ = write!(h, "<li>{}</li>", esc(n));
    }
    h += "</ul></div>\n";
    h
}

/// When the calibration was made, by which kinecal, from what (the files read, with their
/// fingerprints), and the job itself (its spec, which runs it again).
fn facts_section(rep: &CalibrationReport) -> String {
    let mut h = String::from("<dl class=\"facts\">");
    let _ = write!(
        h,
        "<dt>made</dt><dd>{} by kinecal {}</dd>",
        esc(&rep.created),
        esc(&rep.kinecal_version)
    );
    for s in &rep.sources {
        let _ = write!(
            h,
            "<dt>read</dt><dd>{} <small>(SHA-256 {})</small></dd>",
            esc(&s.name),
            esc(s.sha256.get(..16).unwrap_or(&s.sha256))
        );
    }
    if let Some(spec) = &rep.spec {
        let _ = write!(
            h,
            "<dt>job</dt><dd><code>{}</code></dd>",
            esc(&spec.to_string())
        );
    }
    h += "</dl>\n";
    h
}
