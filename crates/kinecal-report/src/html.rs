//! The self-contained HTML calibration report: inline SVG, inline CSS, the 3-D view's own script
//! in the page, no link to anything outside the file. The page renders the calibration's view
//! ([`crate::view::CalibrationView`]), section after section ([`SECTIONS`]).

use std::fmt::Write as _;

use kinecal::report::CalibrationReport;

use crate::chart::render_svg;
use crate::display::{combination_unit, DisplayUnits};
use crate::number::{fixed, num};
use crate::page::{charts, esc, inline, page_head};
use crate::view::{cap, CalibrationView, ErrorRow};
use crate::DrawError;

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
    let v = CalibrationView::new(rep, units);
    let mut h = page_head(&format!("kinecal calibration report{}", named(&v)));
    for section in SECTIONS {
        h += &section(&v)?;
    }
    Ok(h)
}

/// A section of the page: its HTML, from the view.
type Section = fn(&CalibrationView) -> Result<String, DrawError>;

/// The page's sections, in order: what a reader needs first (the verdict, the facts of the run,
/// the accuracy), then how it was reached (the parameters, the spectrum), then the warnings.
const SECTIONS: [Section; 18] = [
    title,
    verdict,
    facts,
    run,
    summary,
    validation,
    model_choice,
    cross_validation,
    per_observation,
    view_3d,
    parameter_changes,
    prior,
    mass_model,
    spectrum,
    redundancy,
    prediction,
    warnings,
    footer,
];

/// `: ROBOT`, or nothing for a robot without a name (an imported DH table): no dangling colon.
fn named(v: &CalibrationView) -> String {
    if v.run.robot.trim().is_empty() {
        String::new()
    } else {
        format!(": {}", v.run.robot)
    }
}

fn title(v: &CalibrationView) -> Result<String, DrawError> {
    Ok(format!("<h1>Calibration report{}</h1>\n", esc(&named(v))))
}

/// The verdict, first on the page: a banner of its level, what happened, the accuracy reached,
/// and what to do next.
fn verdict(v: &CalibrationView) -> Result<String, DrawError> {
    let v = &v.verdict;
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
    Ok(h)
}

/// When the calibration was made, by which kinecal, from what (the files read, with their
/// fingerprints), and the job itself (its spec, which runs it again).
fn facts(v: &CalibrationView) -> Result<String, DrawError> {
    let rep = &v.shown;
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
    Ok(h)
}

/// What was solved and how it ended; a far start's placement; a robust loss's down-weighting.
fn run(v: &CalibrationView) -> Result<String, DrawError> {
    let r = &v.run;
    let mut h = String::new();
    let how = if r.given {
        format!(
            "{} orientation residuals; a given calibration, assessed on these data (not solved here)",
            esc(&r.orientation_error)
        )
    } else {
        format!(
            "method <b>{}</b>, {} orientation residuals, {} solution; {} after {} iterations ({})",
            esc(&r.method),
            esc(&r.orientation_error),
            esc(&r.solution),
            r.convergence(),
            r.iterations,
            esc(&r.termination)
        )
    };
    let _ = writeln!(
        h,
        "<p>{} postures, {} observations ({}), {} residuals; {how}.</p>",
        r.postures,
        r.measurements,
        esc(&r.observations),
        r.residuals
    );
    if let Some([before, after]) = r.start_placement {
        let _ = writeln!(
            h,
            "<p>Far start: the measurement frame and the measured frames were first placed in closed form (RMS position error {} &rarr; {} {}).</p>",
            num(before),
            num(after),
            esc(v.l())
        );
    }
    if let Some(n) = r.down_weighted_rows {
        let _ = writeln!(
            h,
            "<p>Loss {}: {n} of {} residual rows down-weighted.</p>",
            esc(&r.loss),
            r.residuals
        );
    }
    Ok(h)
}

/// The objective and the errors on the identification data: before, at the solver's start
/// (when it started elsewhere), after.
fn summary(v: &CalibrationView) -> Result<String, DrawError> {
    let t = &v.errors;
    let mut h = format!(
        "<h2 id=\"summary\">Summary</h2><table><tr><th class=\"l\"></th><th>before</th>{}<th>after</th></tr>\n",
        if t.start { "<th>start</th>" } else { "" }
    );
    for row in std::iter::once(&t.objective).chain(&t.rows) {
        let ErrorRow {
            label,
            before,
            start,
            after,
        } = row;
        let start = match (t.start, start) {
            (false, _) => String::new(),
            (true, s) => format!("<td>{}</td>", s.map_or(String::new(), num)),
        };
        let _ = writeln!(
            h,
            "<tr><td class=\"l\">{}</td><td>{}</td>{start}<td>{}</td></tr>",
            esc(label),
            num(*before),
            num(*after)
        );
    }
    h += "</table>\n";
    Ok(h)
}

/// One table per kind of error present (positions, attitudes, distances, contacts): RMS, mean,
/// p95 and max on the identification and validation data, before (at the start) and after;
/// `n/a` where a set has none of that kind.
fn validation(v: &CalibrationView) -> Result<String, DrawError> {
    let Some(val) = &v.validation else {
        return Ok(String::new());
    };
    let mut h = String::from("<h2 id=\"validation\">Validation</h2>\n");
    for t in &val.tables {
        let _ = writeln!(
            h,
            "<table><tr><th class=\"l\">{}</th><th>RMS</th><th>mean</th><th>p95</th><th>max</th></tr>",
            esc(&cap(&t.title))
        );
        for row in &t.rows {
            let cells: Vec<String> = match row.stats {
                Some(s) => s.iter().map(|&x| num(x)).collect(),
                None => vec!["n/a".into(); 4],
            };
            let _ = writeln!(
                h,
                "<tr><td class=\"l\">{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                esc(&row.label),
                cells[0],
                cells[1],
                cells[2],
                cells[3]
            );
        }
        h += "</table>\n";
    }
    for note in &val.notes {
        let note = esc(&cap(note)).replace(" -&gt; ", " &rarr; ");
        let _ = writeln!(h, "<p>{note}.</p>");
    }
    Ok(h)
}

/// The candidates of a model choice, the chosen one marked.
fn model_choice(v: &CalibrationView) -> Result<String, DrawError> {
    let rep = &v.shown;
    if rep.model_choice.is_empty() {
        return Ok(String::new());
    }
    let mut h = format!(
        "<h2 id=\"model-choice\">Model choice</h2><p>Candidates from the simplest up, cross-validated on the same folds; chosen: the first within one standard error of the best held-out mean ({}).</p>\n",
        v.l()
    );
    h += "<table><tr><th class=\"l\">candidate</th><th>parameters</th><th>held-out mean</th><th>std. error</th><th class=\"l\"></th></tr>\n";
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
    h += "</table>\n";
    Ok(h)
}

/// The held-out errors of each fold, all folds together, and the held-out mean's interval.
fn cross_validation(v: &CalibrationView) -> Result<String, DrawError> {
    let Some(cv) = &v.cross_validation else {
        return Ok(String::new());
    };
    let mut h = format!(
        "<h2 id=\"cross-validation\">Cross-validation</h2><p>{}: each fold's calibration checked on the postures it left out; {}.</p>\n",
        cv.folds_by,
        esc(&cv.measure)
    );
    h += "<table><tr><th class=\"l\">fold</th><th>postures</th><th>observations</th><th>mean</th><th>RMS</th><th>p95</th><th>max</th></tr>\n";
    for (i, f) in cv.folds.iter().enumerate() {
        let [mean, rms, p95, max] = f.stats;
        let _ = writeln!(
            h,
            "<tr><td class=\"l\">{}{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            i + 1,
            if f.converged { "" } else { " (NOT converged)" },
            f.postures,
            f.observations,
            num(mean),
            num(rms),
            num(p95),
            num(max)
        );
    }
    let o = &cv.all;
    let [mean, rms, p95, max] = o.stats;
    let _ = writeln!(
        h,
        "<tr><th class=\"l\">all</th><th>{}</th><th>{}</th><th>{}</th><th>{}</th><th>{}</th><th>{}</th></tr></table>",
        o.postures,
        o.observations,
        num(mean),
        num(rms),
        num(p95),
        num(max)
    );
    let l = v.l();
    let _ = writeln!(
        h,
        "<p>Held-out mean {} {l}; bootstrap 95 % interval {} to {} {l}.</p>",
        num(mean),
        num(cv.mean_interval[0]),
        num(cv.mean_interval[1])
    );
    Ok(h)
}

/// The errors of each observation before and after, and their histogram after.
fn per_observation(v: &CalibrationView) -> Result<String, DrawError> {
    let f = &v.figures;
    let mut h = String::new();
    if !f.per_observation.is_empty() {
        let _ = writeln!(
            h,
            "<h2 id=\"residuals\">Errors per observation</h2>\n{}",
            charts(&f.per_observation)?
        );
    }
    if let Some(hist) = &f.histogram {
        let _ = writeln!(
            h,
            "<h2 id=\"histogram\">Error histogram</h2>\n{}",
            inline(render_svg(std::slice::from_ref(hist), 1)?)
        );
    }
    Ok(h)
}

/// The robots, the measured points and their residuals in 3-D ([`crate::view3d`]).
fn view_3d(v: &CalibrationView) -> Result<String, DrawError> {
    Ok(crate::view3d::section(
        v.shown.scene.as_ref(),
        v.convert.units,
    ))
}

/// The estimated parameters: their changes charted with +-1 sigma bars, and their table.
fn parameter_changes(v: &CalibrationView) -> Result<String, DrawError> {
    let mut h = String::from("<h2 id=\"changes\">Parameter changes</h2>\n");
    if !v.figures.changes.is_empty() {
        let _ = writeln!(h, "{}", charts(&v.figures.changes)?);
    }
    h += "<table><tr><th class=\"l\">id</th><th class=\"l\">name</th><th class=\"l\">unit</th><th>initial</th><th>estimated</th><th>change</th><th>sigma</th><th>change/sigma</th></tr>\n";
    for p in &v.parameters {
        // Six decimals for lengths and angles; a compliance (1e-6..1e-3) in significant digits.
        let value = |x: f64| if p.compliance { num(x) } else { fixed(x, 6) };
        let _ = writeln!(
            h,
            "<tr><td class=\"l\">{}</td><td class=\"l\">{}</td><td class=\"l\">{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            p.id,
            esc(&p.name),
            esc(&p.unit),
            value(p.initial),
            value(p.estimated),
            crate::number::signed(p.change, 4),
            p.sigma.map_or("not determined alone".into(), num),
            p.significance.map_or(String::new(), |z| format!(
                "{z:.1}{}",
                if p.within_noise { " (within noise)" } else { "" }
            ))
        );
    }
    h += "</table>\n";
    Ok(h)
}

/// The prior: what it added to the objective, and what it (not the data) determines.
fn prior(v: &CalibrationView) -> Result<String, DrawError> {
    let rep = &v.shown;
    let Some(pr) = &rep.prior else {
        return Ok(String::new());
    };
    let mut h = String::new();
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
        v.parameters.len(),
        pr.determined_by_prior_alone.len(),
        pr.split_by_prior.len()
    );
    h += "<table><tr><th class=\"l\">id</th><th class=\"l\">name</th><th class=\"l\">unit</th><th>prior sigma</th><th>sigma</th><th>data share</th><th class=\"l\">determined by</th></tr>\n";
    let opt = |v: Option<f64>| v.map_or(String::new(), num);
    for p in rep
        .parameters
        .iter()
        .filter(|p| p.estimated_flag && p.prior_sigma.is_some())
    {
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
    h += "</table>\n";
    Ok(h)
}

/// The mass model of an elastic robot: its equilibrium and the joints' stiffnesses.
fn mass_model(v: &CalibrationView) -> Result<String, DrawError> {
    let rep = &v.shown;
    let Some(e) = &rep.elastic else {
        return Ok(String::new());
    };
    let mut h = String::new();
    let _ = writeln!(
        h,
        "<h2 id=\"mass-model\">Mass model</h2>\n<p>{} bodies, {} kg, gravity {} {}/s&sup2;; \
         equilibrium {} at {} of {} postures (at most {} iterations); largest deflection {} \
         {} under gravity torques up to {} N m.</p>",
        e.bodies,
        num(e.total_mass),
        num(e.gravity),
        esc(v.l()),
        esc(&e.equilibrium),
        rep.postures.saturating_sub(e.unconverged_postures),
        rep.postures,
        e.iterations_max,
        num(e.largest_deflection),
        esc(v.a()),
        num(e.largest_torque)
    );
    h += "<table><tr><th class=\"l\">compliance</th><th>value</th><th>sigma</th><th>stiffness</th><th>sigma</th><th class=\"l\">unit</th><th class=\"l\">estimated</th></tr>\n";
    let opt = |v: Option<f64>| v.map_or(String::new(), num);
    for j in &e.joints {
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
    h += "</table>\n";
    Ok(h)
}

/// The singular values of the scaled Jacobian, and the thesis's count of the rank.
fn spectrum(v: &CalibrationView) -> Result<String, DrawError> {
    let (Some(an), Some(chart)) = (&v.shown.spectrum, &v.figures.spectrum) else {
        return Ok(String::new());
    };
    let mut h = format!(
        "<h2 id=\"spectrum\">Singular-value spectrum</h2>\n{}\n",
        inline(render_svg(std::slice::from_ref(chart), 1)?)
    );
    if let Some(formula) = &an.expected {
        let _ = writeln!(
            h,
            "<p>Thesis count: {}; measured rank {}.</p>",
            esc(formula),
            an.rank
        );
    }
    Ok(h)
}

/// The redundant groups, the determined combinations, the parameters not determined alone
/// (with the spectrum: they come from its analysis).
fn redundancy(v: &CalibrationView) -> Result<String, DrawError> {
    let rep = &v.shown;
    let Some(an) = &rep.spectrum else {
        return Ok(String::new());
    };
    let mut h =
        String::from("<h2 id=\"redundancy\">Redundant groups and determined combinations</h2>\n");
    if an.identical_groups.is_empty() {
        h += "<p>No identical redundancy among the estimated parameters.</p>\n";
    } else {
        h += "<table><tr><th class=\"l\">combination</th><th>value</th><th class=\"l\">unit</th><th class=\"l\">determined</th></tr>\n";
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
        h += "</table>\n";
    }
    for c in &v.combinations {
        let _ = writeln!(
            h,
            "<p>{} = {} {unit} (was {}, sigma {}, change {:.1} sigma)</p>",
            esc(&c.expression),
            fixed(c.value, 6),
            fixed(c.initial, 6),
            num(c.sigma),
            c.significance,
            unit = esc(&c.unit)
        );
    }
    if !rep.undetermined.is_empty() {
        let _ = writeln!(
            h,
            "<p>Not individually determined: {}.</p>",
            esc(&rep.undetermined.join(", "))
        );
    }
    Ok(h)
}

/// The predicted accuracy and its map ([`crate::predict::section`]); without them, how to get
/// them and what they cost.
fn prediction(v: &CalibrationView) -> Result<String, DrawError> {
    Ok(match &v.shown.prediction {
        Some(p) => crate::predict::section(p, v.l(), v.a()),
        // A given calibration is always predicted when it can be.
        None if v.run.given => String::from(
            "<h2 id=\"prediction\">Predicted accuracy</h2>\n<p>Not worked out: a prediction \
             needs at least 20 postures measured by position or pose.</p>\n",
        ),
        None => String::from(
            "<h2 id=\"prediction\">Predicted accuracy</h2>\n<p>Not worked out for this report: \
             it was not asked for. <code>kinecal calibrate ... --predict</code> (a spec's \
             <code>predict = true</code> under <code>[validation]</code>) adds the 95 % error \
             bound over the joint ranges and, with <code>--html</code>, its map, from a \
             cross-validation that refits the calibration on blocks of nearby postures (some 13 \
             more fits; it needs at least 20 postures measured by position or pose).</p>\n",
        ),
    })
}

/// The warnings ranked (errors, then cautions, then notes), then the outliers.
fn warnings(v: &CalibrationView) -> Result<String, DrawError> {
    let mut h = String::from("<h2 id=\"warnings\">Warnings</h2>\n");
    if v.warnings.is_empty() && v.outliers.is_empty() {
        h += "<p>None.</p>\n";
    }
    for w in &v.warnings {
        let class = w.severity.as_str();
        let _ = writeln!(
            h,
            "<p class=\"{class}\"><b>{class}:</b> {}</p>",
            esc(&w.text)
        );
    }
    for o in &v.outliers {
        let _ = writeln!(
            h,
            "<p class=\"warn\">Outlier: line {} posture {} site {}: {} error {} {} ({:.1} sigma)</p>",
            o.line,
            esc(&o.posture),
            esc(&o.site),
            esc(&o.metric),
            num(o.error),
            v.l(),
            o.sigmas
        );
    }
    Ok(h)
}

/// Which kinecal wrote the page.
fn footer(_: &CalibrationView) -> Result<String, DrawError> {
    Ok(format!(
        "<p><small>Written by kinecal {}.</small></p></body></html>\n",
        env!("CARGO_PKG_VERSION")
    ))
}
