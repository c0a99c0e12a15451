//! Human-readable summaries.

use std::fmt::Write as _;

use kinecal::report::CalibrationReport;

use kinecal_report::display::{Convert, DisplayUnits};
use kinecal_report::number::{fixed, fixed_signed, ratio};
use kinecal_report::view::CalibrationView;

/// A number in the summary's columns: six decimals, or four significant digits where six
/// decimals would keep fewer than two ([`kinecal_report::number::fixed`]; the history's and the
/// fleet's tables call it too).
pub fn num(v: f64) -> String {
    fixed(v, 6)
}

/// The text summary `kinecal calibrate` prints, its lengths and angles in `units`: the
/// calibration's view ([`CalibrationView`], which the HTML page renders too), section after
/// section ([`SECTIONS`]).
pub fn summary(r: &CalibrationReport, units: DisplayUnits) -> String {
    let v = CalibrationView::new(r, units);
    SECTIONS.iter().map(|section| section(&v)).collect()
}

/// A section of the summary: its lines, from the view.
type Section = fn(&CalibrationView) -> String;

/// The summary's sections, in order: the verdict, what was solved, the accuracy, the
/// parameters, what the data cannot separate, then the prediction and the time taken.
const SECTIONS: [Section; 15] = [
    verdict,
    run,
    errors,
    validation,
    cross_validation,
    rank,
    prior,
    parameters,
    mass_model,
    combinations,
    outliers,
    undetermined,
    pruning,
    prediction,
    timings,
];

/// The verdict ([`kinecal_report::verdict::text`]): converged or not, the accuracy reached,
/// what to do next.
fn verdict(v: &CalibrationView) -> String {
    kinecal_report::verdict::text(&v.verdict) + "\n"
}

/// What was solved and how it ended; a far start's placement; a robust loss's down-weighting.
fn run(v: &CalibrationView) -> String {
    let r = &v.run;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{}: {} postures, {} observations ({}), {} residuals; method {}, {} orientation residuals, {} solution",
        if r.robot.is_empty() { "robot" } else { &r.robot },
        r.postures,
        r.measurements,
        r.observations,
        r.residuals,
        r.method,
        r.orientation_error,
        r.solution
    );
    let _ = writeln!(
        s,
        "{} after {} iterations: {}{}",
        r.convergence(),
        r.iterations,
        r.termination,
        r.stationarity
            .as_ref()
            .map_or(String::new(), |m| format!(" ({m})"))
    );
    if let Some([before, after]) = r.start_placement {
        let _ = writeln!(
            s,
            "far start: the measurement frame and the measured frames were first placed in \
             closed form (RMS position error {} -> {} {})",
            num(before),
            num(after),
            v.l()
        );
    }
    if let Some(n) = r.down_weighted_rows {
        let _ = writeln!(
            s,
            "loss {}: {n} of {} residual rows down-weighted",
            r.loss, r.residuals
        );
    }
    s + "\n"
}

/// The objective and the errors on the identification data: before (the nominal robot), at
/// the solver's start when it is elsewhere, after.
fn errors(v: &CalibrationView) -> String {
    let t = &v.errors;
    let mut s = String::new();
    let mut row = |label: &str, cells: [String; 3]| {
        let _ = if t.start {
            writeln!(
                s,
                "{label:<28} {:>14} {:>14} {:>14}",
                cells[0], cells[1], cells[2]
            )
        } else {
            writeln!(s, "{label:<28} {:>14} {:>14}", cells[0], cells[2])
        };
    };
    row("", ["before".into(), "start".into(), "after".into()]);
    let o = &t.objective;
    let objective = |x: f64| format!("{x:.6e}");
    row(
        &o.label,
        [
            objective(o.before),
            o.start.map_or(String::new(), objective),
            objective(o.after),
        ],
    );
    for e in &t.rows {
        row(
            &e.label,
            [
                num(e.before),
                e.start.map_or(String::new(), num),
                num(e.after),
            ],
        );
    }
    s
}

/// One table per kind of error on the identification and the validation data (rms, mean,
/// p95, max, or n/a), and the notes on them.
fn validation(v: &CalibrationView) -> String {
    let Some(val) = &v.validation else {
        return String::new();
    };
    let mut s = String::from("\n");
    for t in &val.tables {
        let _ = writeln!(
            s,
            "{:<34} {:>11} {:>11} {:>11} {:>11}",
            t.title, "rms", "mean", "p95", "max"
        );
        for row in &t.rows {
            let cells: Vec<String> = match row.stats {
                Some(v) => v.iter().map(|&x| num(x)).collect(),
                None => vec!["n/a".to_string(); 4],
            };
            let _ = writeln!(
                s,
                "{:<34} {:>11} {:>11} {:>11} {:>11}",
                row.label, cells[0], cells[1], cells[2], cells[3]
            );
        }
    }
    for note in &val.notes {
        let _ = writeln!(s, "{note}");
    }
    s
}

/// The held-out errors of each fold (with its worst posture and its fit's rank), all folds
/// together, and the held-out mean's interval.
fn cross_validation(v: &CalibrationView) -> String {
    let Some(cv) = &v.cross_validation else {
        return String::new();
    };
    let mut s = String::new();
    let _ = writeln!(s, "\ncross-validation, {}: {}", cv.folds_by, cv.measure);
    let _ = writeln!(
        s,
        "{:<8} {:>8} {:>12} {:>11} {:>11} {:>11} {:>11}  {:<14} rank/estimated",
        "fold", "postures", "observations", "mean", "rms", "p95", "max", "worst posture",
    );
    for (i, f) in cv.folds.iter().enumerate() {
        let [mean, rms, p95, max] = f.stats.map(num);
        let _ = writeln!(
            s,
            "{:<8} {:>8} {:>12} {mean:>11} {rms:>11} {p95:>11} {max:>11}  {:<14} {}/{}{}",
            i + 1,
            f.postures,
            f.observations,
            f.worst_posture.as_deref().unwrap_or("-"),
            f.rank.map_or("-".to_string(), |r| r.to_string()),
            f.estimated,
            if f.converged { "" } else { "  NOT converged" }
        );
    }
    let o = &cv.all;
    let [mean, rms, p95, max] = o.stats.map(num);
    let _ = writeln!(
        s,
        "{:<8} {:>8} {:>12} {mean:>11} {rms:>11} {p95:>11} {max:>11}",
        "all", o.postures, o.observations,
    );
    let _ = writeln!(
        s,
        "held-out mean {mean} {}, bootstrap 95 % interval {} .. {}",
        v.l(),
        num(cv.mean_interval[0]),
        num(cv.mean_interval[1])
    );
    s
}

/// The rank of the estimated parameters and the variance factor.
fn rank(v: &CalibrationView) -> String {
    let r = &v.shown;
    match (r.variance_factor, r.rank) {
        (Some(vf), Some(rank)) => format!(
            "rank {rank} of {} estimated parameters; variance factor {} (about 1 when --weights \
             match the noise)\n",
            v.parameters.len(),
            ratio(vf)
        ),
        _ => String::new(),
    }
}

/// The prior: its share of the objective, and what it (not the data) determines.
fn prior(v: &CalibrationView) -> String {
    let r = &v.shown;
    let Some(p) = &r.prior else {
        return String::new();
    };
    let mut s = String::new();
    let _ = writeln!(
        s,
        "prior {} on {} parameters: objective {:.6e} (data) + {:.6e} (prior){}",
        p.prior,
        p.rows,
        p.data_objective_after,
        p.prior_objective_after,
        p.data_rank
            .map_or(String::new(), |k| format!("; rank {k} on the data alone"))
    );
    let names = |ids: &[String]| -> String {
        ids.iter()
            .map(|id| {
                r.parameters
                    .iter()
                    .find(|q| &q.id == id)
                    .map_or(id.as_str(), |q| q.name.as_str())
            })
            .collect::<Vec<_>>()
            .join(", ")
    };
    if !p.split_by_prior.is_empty() {
        let _ = writeln!(
            s,
            "determined by the data only in combinations the prior splits ({}): {}",
            p.split_by_prior.len(),
            names(&p.split_by_prior)
        );
    }
    if !p.determined_by_prior_alone.is_empty() {
        let _ = writeln!(
            s,
            "determined by the prior alone ({}): {}",
            p.determined_by_prior_alone.len(),
            names(&p.determined_by_prior_alone)
        );
    }
    s
}

/// The estimated parameters: initial, estimated, change, sigma and change in sigmas.
fn parameters(v: &CalibrationView) -> String {
    let mut s = String::from("\n");
    let _ = writeln!(
        s,
        "{:<5} {:<20} {:<9} {:>14} {:>14} {:>13} {:>11} {:>7}",
        "id", "name", "unit", "initial", "estimated", "change", "sigma", "change/sigma"
    );
    for p in &v.parameters {
        let (sigma, sig) = match (p.sigma, p.significance, p.determined) {
            (Some(sd), Some(z), _) => (
                format!("{sd:>11.3e}"),
                format!(
                    "{z:>7.1}{}",
                    if p.within_noise { "  within noise" } else { "" }
                ),
            ),
            (_, _, Some(false)) => (format!("{:>11}", "-"), "  not determined alone".to_string()),
            _ => (String::new(), String::new()),
        };
        let sig = if p.by_prior_alone {
            format!("{sig}  prior alone")
        } else {
            sig
        };
        // Compliances (angle per torque, 1e-6..1e-3) in four significant digits.
        let value = |v: f64| match (p.compliance, v == 0.0) {
            (true, true) => "0".to_string(),
            (true, false) => format!("{v:.4e}"),
            (false, _) => num(v),
        };
        let change = match (p.compliance, p.change == 0.0) {
            (true, true) => "0".to_string(),
            (true, false) => format!("{:+.4e}", p.change),
            (false, _) => fixed_signed(p.change, 6),
        };
        let _ = writeln!(
            s,
            "{:<5} {:<20} {:<9} {:>14} {:>14} {:>13} {sigma} {sig}",
            p.id,
            p.name,
            p.unit,
            value(p.initial),
            value(p.estimated),
            change
        );
    }
    s
}

/// The mass model of an elastic robot: its equilibrium, and the estimated joints' stiffnesses.
fn mass_model(v: &CalibrationView) -> String {
    let r = &v.shown;
    let Some(e) = &r.elastic else {
        return String::new();
    };
    let mut s = String::new();
    let _ = writeln!(
        s,
        "\nMass model: {} bodies, {} kg; equilibrium {} at {} of {} postures (at most {} \
         iterations); largest deflection {} {} under torques up to {:.1} N m",
        e.bodies,
        kinecal::units::number::format_number((e.total_mass * 1e3).round() / 1e3),
        e.equilibrium,
        r.postures.saturating_sub(e.unconverged_postures),
        r.postures,
        e.iterations_max,
        num(e.largest_deflection),
        v.a(),
        e.largest_torque
    );
    for j in e.joints.iter().filter(|j| j.estimated) {
        let stiffness = match (j.stiffness, j.stiffness_sigma) {
            (Some(k), Some(sd)) => format!("{k:.4e} +- {sd:.2e} {}", j.stiffness_unit),
            (Some(k), None) => format!("{k:.4e} {}", j.stiffness_unit),
            (None, _) => "none: the compliance is not positive".to_string(),
        };
        let _ = writeln!(s, "  {:<20} stiffness {stiffness}", j.name);
    }
    s
}

/// The combinations of parameters the data determines but cannot separate.
fn combinations(v: &CalibrationView) -> String {
    if v.combinations.is_empty() {
        return String::new();
    }
    let mut s = String::from("\nDetermined combinations of parameters the data cannot separate:\n");
    for c in &v.combinations {
        let _ = writeln!(
            s,
            "  {} = {} {} (was {}, sigma {:.3e}, change {:.1} sigma{})",
            c.expression,
            num(c.value),
            c.unit,
            num(c.initial),
            c.sigma,
            c.significance,
            if c.within_noise { ", within noise" } else { "" }
        );
    }
    s
}

/// The observations beyond the outlier threshold (kept in the fit).
fn outliers(v: &CalibrationView) -> String {
    if v.outliers.is_empty() {
        return String::new();
    }
    let r = &v.shown;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "\nOutliers ({}; a residual beyond {} robust sigmas; kept in the fit{}):",
        v.outliers.len(),
        (r.outlier_sigmas * 100.0).round() / 100.0,
        if r.loss == "squared" {
            ", consider --loss huber"
        } else {
            ""
        }
    );
    for o in &v.outliers {
        let _ = writeln!(
            s,
            "  {:<9} line {:<5} posture {:<10} site {:<8} {} error {} {}{}  ({:.1} sigma)",
            o.kind,
            o.line,
            o.posture,
            o.site,
            o.metric,
            num(o.error),
            v.l(),
            o.attitude.map_or(String::new(), |e| format!(
                ", attitude error {} {}",
                num(e),
                v.a()
            )),
            o.sigmas
        );
    }
    s
}

/// The estimated parameters the data does not determine one by one, and what to do about it.
fn undetermined(v: &CalibrationView) -> String {
    let u = &v.shown.undetermined;
    if u.is_empty() {
        return String::new();
    }
    format!(
        "\nNot individually determined ({}): {}. Their changes mean nothing one by one (see the \
         combinations above); --estimate identifiable estimates only a determined set, \
         --solution min-change picks the answer closest to nominal.\n",
        u.len(),
        u.join(", ")
    )
}

/// What pruning removed, and the full fit's figures.
fn pruning(v: &CalibrationView) -> String {
    let Some(p) = &v.shown.pruning else {
        return String::new();
    };
    format!(
        "\nPruned at {} sigma: removed {}; full fit had objective {:.6e}, RMS position {} {}{}\n",
        p.k,
        if p.removed.is_empty() {
            "nothing".to_string()
        } else {
            p.removed.join(", ")
        },
        p.full_objective_after,
        num(p.full_rms_position_after),
        v.l(),
        p.full_rms_orientation_after
            .map_or(String::new(), |x| format!(
                ", RMS attitude {} {}",
                num(x),
                v.a()
            ))
    )
}

/// The predicted accuracy ([`prediction_lines`]).
fn prediction(v: &CalibrationView) -> String {
    v.shown
        .prediction
        .as_ref()
        .map_or(String::new(), |p| prediction_lines(p, v.l(), v.a()))
}

/// The wall time of each phase.
fn timings(v: &CalibrationView) -> String {
    let t = &v.shown.timings;
    if t.is_empty() {
        return String::new();
    }
    format!(
        "\ntime: {:.3} s ({})\n",
        t.iter().map(|t| t.seconds).sum::<f64>(),
        t.iter()
            .map(|t| format!("{} {:.3}", t.phase, t.seconds))
            .collect::<Vec<_>>()
            .join(", ")
    )
}

/// The summary's lines on the predicted accuracy (see `kinecal::predict`).
pub fn prediction_lines(p: &kinecal::predict::PredictionReport, l: &str, a: &str) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "\npredicted 95 % position bound ({l}): median {}, 95th percentile {} over {} postures in the \
         joint ranges ({} at the measured postures)",
        num(p.position_summary.median),
        num(p.position_summary.p95),
        p.samples,
        num(p.position_summary.median_measured)
    );
    if let Some(at) = &p.attitude_summary {
        let _ = writeln!(
            s,
            "predicted 95 % attitude bound ({a}): median {}, 95th percentile {} ({} at the measured \
             postures)",
            num(at.median),
            num(at.p95),
            num(at.median_measured)
        );
    }
    let term = |g: &kinecal::predict::GrowthReport, unit: &str| {
        format!(
            "s0 {} {unit}, c {} {unit} per {l} of joint-space distance, shape {:.2}; \
             cross-validated, {:.1} % of {} held-out points within their bound (a single variance \
             {:.1} %, the parameters alone {:.1} %)",
            num(g.s0),
            num(g.c),
            g.shape,
            100.0 * g.coverage,
            g.points,
            100.0 * g.coverage_constant,
            100.0 * g.coverage_parameters_only
        )
    };
    let _ = writeln!(s, "model error (position): {}", term(&p.position, l));
    if let Some(at) = &p.attitude {
        let _ = writeln!(s, "model error (attitude): {}", term(at, a));
    }
    s
}

/// The table of a model choice (`calibrate --choose`), its errors in `units`.
pub fn choice_table(r: &CalibrationReport, units: DisplayUnits) -> String {
    let mut s = String::new();
    let c = Convert::of(r, units);
    let folds = r.cross_validation.as_ref().map_or(0, |c| c.folds.len());
    let metric = r
        .cross_validation
        .as_ref()
        .map_or("position", |c| c.metric.as_str());
    let repeats = r.model_choice_repeats.unwrap_or(1);
    let _ = writeln!(
        s,
        "model choice: {folds} folds by posture{}, the same for every candidate; held-out {metric} error ({})",
        if repeats > 1 {
            format!(" over {repeats} shuffles")
        } else {
            String::new()
        },
        c.l()
    );
    let _ = writeln!(
        s,
        "{:<36} {:>10} {:>11} {:>11}",
        "candidate", "parameters", "mean", "std. error"
    );
    for m in &r.model_choice {
        let _ = writeln!(
            s,
            "{:<36} {:>10} {:>11} {:>11}{}",
            m.candidate,
            m.parameters,
            num(c.length(m.mean)),
            num(c.length(m.standard_error)),
            if m.chosen {
                "  <- chosen: the first (simplest) within one std. error of the best"
            } else {
                ""
            }
        );
    }
    let _ = writeln!(s);
    s
}
