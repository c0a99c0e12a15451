//! Human-readable summaries.

use std::fmt::Write as _;

use kinecal::report::CalibrationReport;

use kinecal_report::display::{self, combination_unit, Convert, DisplayUnits};
use kinecal_report::number::{fixed, fixed_signed, ratio};

/// A number in the summary's columns: six decimals, or four significant digits where six
/// decimals would keep fewer than two ([`kinecal_report::number::fixed`]; the history's and the
/// fleet's tables call it too).
pub fn num(v: f64) -> String {
    fixed(v, 6)
}

/// The text summary `kinecal calibrate` prints, its lengths and angles in `units`.
pub fn summary(r: &CalibrationReport, units: DisplayUnits) -> String {
    let mut s = String::new();
    let c = Convert::of(r, units);
    // Every number below is in display units, every unit from `c`.
    let r = &display::calibration(r, &c);
    let (l, a) = (c.l(), c.a());
    let kinds: Vec<String> = r
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
        .collect();
    let _ = writeln!(
        s,
        "{}: {} postures, {} observations ({}), {} residuals; method {}, {} orientation residuals, {} solution",
        if r.robot.is_empty() { "robot" } else { &r.robot },
        r.postures,
        r.measurements,
        kinds.join(", "),
        r.residuals,
        r.method.as_str(),
        r.orientation_error.as_str(),
        r.solution
    );
    let measures = r
        .stationarity
        .as_ref()
        .map(|st| {
            format!(
                " (reduction {:.1e}, step {}, gradient {:.1e})",
                st.predicted_reduction,
                st.step.map_or("-".to_string(), |v| format!("{v:.1e}")),
                st.gradient
            )
        })
        .unwrap_or_default();
    let _ = writeln!(
        s,
        "{} after {} iterations: {}{measures}",
        if r.converged {
            "converged"
        } else {
            "NOT converged"
        },
        r.iterations,
        r.termination.describe()
    );
    if let Some(p) = &r.start_placement {
        let _ = writeln!(
            s,
            "far start: the measurement frame and the measured frames were first placed in \
             closed form (RMS position error {} -> {} {})",
            num(p.rms_before),
            num(p.rms_after),
            l
        );
    }
    if let Some(n) = r.down_weighted_rows {
        let _ = writeln!(
            s,
            "loss {}: {n} of {} residual rows down-weighted",
            r.loss, r.residuals
        );
    }
    let _ = writeln!(s);
    // Columns: before (the nominal robot), the solver's start when it is elsewhere, after.
    let start = r.start.as_ref();
    let row = |s: &mut String, label: String, cells: [String; 3]| {
        let _ = match start {
            Some(_) => writeln!(
                s,
                "{label:<28} {:>14} {:>14} {:>14}",
                cells[0], cells[1], cells[2]
            ),
            None => writeln!(s, "{label:<28} {:>14} {:>14}", cells[0], cells[2]),
        };
    };
    row(
        &mut s,
        String::new(),
        ["before".into(), "start".into(), "after".into()],
    );
    row(
        &mut s,
        "objective (weighted)".into(),
        [
            format!("{:.6e}", r.objective_before),
            start.map_or(String::new(), |st| format!("{:.6e}", st.objective)),
            format!("{:.6e}", r.objective_after),
        ],
    );
    let (ib, ia) = (&r.identification.before, &r.identification.after);
    let is = r.identification.start.as_ref();
    if ib.positions > 0 {
        row(
            &mut s,
            format!("RMS position error ({l})"),
            [
                num(r.rms_position_before),
                start.map_or(String::new(), |st| num(st.rms_position)),
                num(r.rms_position_after),
            ],
        );
        row(
            &mut s,
            format!("max position error ({l})"),
            [
                num(r.max_position_before),
                start.map_or(String::new(), |st| num(st.max_position)),
                num(r.max_position_after),
            ],
        );
    }
    for (k, (b, a)) in ib.other.iter().zip(&ia.other).enumerate() {
        let st = is.and_then(|st| st.other.get(k));
        row(
            &mut s,
            format!("RMS {} error ({l})", b.metric),
            [
                num(b.rms),
                st.map_or(String::new(), |m| num(m.rms)),
                num(a.rms),
            ],
        );
        row(
            &mut s,
            format!("max {} error ({l})", b.metric),
            [
                num(b.max),
                st.map_or(String::new(), |m| num(m.max)),
                num(a.max),
            ],
        );
    }
    if let (Some(rb), Some(ra), Some(mb), Some(ma)) = (
        r.rms_orientation_before,
        r.rms_orientation_after,
        r.max_orientation_before,
        r.max_orientation_after,
    ) {
        row(
            &mut s,
            format!("RMS attitude error ({a})"),
            [
                num(rb),
                start
                    .and_then(|st| st.rms_orientation)
                    .map_or(String::new(), num),
                num(ra),
            ],
        );
        row(
            &mut s,
            format!("max attitude error ({a})"),
            [
                num(mb),
                start
                    .and_then(|st| st.max_orientation)
                    .map_or(String::new(), num),
                num(ma),
            ],
        );
    }
    if let Some(v) = &r.validation {
        let _ = writeln!(s);
        let mut rows = vec![(
            format!(
                "identification ({} postures) before",
                r.identification.postures
            ),
            &r.identification.before,
        )];
        if let Some(st) = &r.identification.start {
            rows.push(("identification start".to_string(), st));
        }
        rows.push(("identification after".to_string(), &r.identification.after));
        rows.push((
            format!("validation ({} postures) before", v.postures),
            &v.before,
        ));
        if let Some(st) = &v.start {
            rows.push(("validation start".to_string(), st));
        }
        rows.push(("validation after".to_string(), &v.after));
        // One table per error metric present in the data: positions, attitudes, then the
        // other metrics (distances, contacts), each row [rms, mean, p95, max] or n/a.
        type Pick = Box<dyn Fn(&kinecal::report::ErrorStats) -> Option<[f64; 4]>>;
        let mut tables: Vec<(String, Pick)> = Vec::new();
        let any = |f: &dyn Fn(&kinecal::report::ErrorStats) -> bool| rows.iter().any(|(_, e)| f(e));
        if any(&|e| e.positions > 0) {
            tables.push((
                format!("position error ({l})"),
                Box::new(|e| {
                    (e.positions > 0).then_some([
                        e.rms_position,
                        e.mean_position,
                        e.p95_position,
                        e.max_position,
                    ])
                }),
            ));
        }
        if any(&|e| e.rms_orientation.is_some()) {
            tables.push((
                format!("attitude error ({a})"),
                Box::new(|e| {
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
            let title = format!("{metric} error ({l})");
            tables.push((
                title,
                Box::new(move |e| {
                    e.other
                        .iter()
                        .find(|m| m.metric == metric)
                        .map(|m| [m.rms, m.mean, m.p95, m.max])
                }),
            ));
        }
        for (title, pick) in &tables {
            let _ = writeln!(
                s,
                "{title:<34} {:>11} {:>11} {:>11} {:>11}",
                "rms", "mean", "p95", "max"
            );
            for (name, e) in &rows {
                let cells: Vec<String> = match pick(e) {
                    Some(v) => v.iter().map(|&x| num(x)).collect(),
                    None => vec!["n/a".to_string(); 4],
                };
                let _ = writeln!(
                    s,
                    "{name:<34} {:>11} {:>11} {:>11} {:>11}",
                    cells[0], cells[1], cells[2], cells[3]
                );
            }
        }
        if let (Some(ni), Some(nv)) = (r.identification.normalized_rms, v.normalized_rms) {
            let _ = writeln!(
                s,
                "residuals in their standard deviations (RMS): identification {} -> {}, validation {} -> {}",
                ratio(ni[0]), ratio(ni[1]), ratio(nv[0]), ratio(nv[1])
            );
        }
        if !v.sessions_refitted.is_empty() {
            let _ = writeln!(
                s,
                "validation sessions identification never saw ({}): their measurement frames \
                 re-estimated on the validation data first (6 parameters each, the robot held), \
                 for both robots",
                v.sessions_refitted.join(", ")
            );
        }
    }
    if let Some(cv) = &r.cross_validation {
        let _ = writeln!(s);
        let _ = writeln!(
            s,
            "cross-validation, {} folds by posture ({}): held-out {} error ({l})",
            cv.folds.len(),
            match cv.seed {
                Some(seed) => format!("shuffled with seed {seed}"),
                None => "interleaved in file order".to_string(),
            },
            cv.metric
        );
        let _ = writeln!(
            s,
            "{:<8} {:>8} {:>12} {:>11} {:>11} {:>11} {:>11}  {:<14} rank/estimated",
            "fold", "postures", "observations", "mean", "rms", "p95", "max", "worst posture",
        );
        for (i, f) in cv.folds.iter().enumerate() {
            let e = &f.errors;
            let _ = writeln!(
                s,
                "{:<8} {:>8} {:>12} {:>11} {:>11} {:>11} {:>11}  {:<14} {}/{}{}",
                i + 1,
                f.postures,
                e.count,
                num(e.mean),
                num(e.rms),
                num(e.p95),
                num(e.max),
                f.worst_posture.as_deref().unwrap_or("-"),
                f.rank.map_or("-".to_string(), |r| r.to_string()),
                f.estimated.len(),
                if f.converged { "" } else { "  NOT converged" }
            );
        }
        let o = &cv.overall;
        let _ = writeln!(
            s,
            "{:<8} {:>8} {:>12} {:>11} {:>11} {:>11} {:>11}",
            "all",
            cv.folds.iter().map(|f| f.postures).sum::<usize>(),
            o.count,
            num(o.mean),
            num(o.rms),
            num(o.p95),
            num(o.max)
        );
        let _ = writeln!(
            s,
            "held-out mean {} {l}, bootstrap 95 % interval {} .. {}",
            num(o.mean),
            num(cv.mean_low),
            num(cv.mean_high)
        );
    }
    if let (Some(vf), Some(rank)) = (r.variance_factor, r.rank) {
        let estimated = r.parameters.iter().filter(|p| p.estimated_flag).count();
        let _ = writeln!(
            s,
            "rank {rank} of {estimated} estimated parameters; variance factor {} (about 1 when --weights match the noise)",
            ratio(vf)
        );
    }
    if let Some(p) = &r.prior {
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
    }
    let _ = writeln!(s);
    let _ = writeln!(
        s,
        "{:<5} {:<20} {:<9} {:>14} {:>14} {:>13} {:>11} {:>7}",
        "id", "name", "unit", "initial", "estimated", "change", "sigma", "change/sigma"
    );
    for p in r.parameters.iter().filter(|p| p.estimated_flag) {
        let (sigma, sig) = match (p.sigma, p.significance, p.determined) {
            (Some(sd), Some(z), _) => (
                format!("{sd:>11.3e}"),
                format!(
                    "{z:>7.1}{}",
                    if p.within_noise == Some(true) {
                        "  within noise"
                    } else {
                        ""
                    }
                ),
            ),
            (_, _, Some(false)) => (format!("{:>11}", "-"), "  not determined alone".to_string()),
            _ => (String::new(), String::new()),
        };
        let sig = match p.determined_by.as_deref() {
            Some("prior") => format!("{sig}  prior alone"),
            _ => sig,
        };
        // Compliances (angle per torque, 1e-6..1e-3) in four significant digits.
        let compliance = p.unit.contains("/(N ");
        let value = |v: f64| match (compliance, v == 0.0) {
            (true, true) => "0".to_string(),
            (true, false) => format!("{v:.4e}"),
            (false, _) => num(v),
        };
        let change = match (compliance, p.change == 0.0) {
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
    if let Some(e) = &r.elastic {
        let _ = writeln!(s);
        let _ = writeln!(
            s,
            "Mass model: {} bodies, {} kg; equilibrium {} at {} of {} postures (at most {} \
             iterations); largest deflection {} {a} under torques up to {:.1} N m",
            e.bodies,
            kinecal::units::number::format_number((e.total_mass * 1e3).round() / 1e3),
            e.equilibrium,
            r.postures.saturating_sub(e.unconverged_postures),
            r.postures,
            e.iterations_max,
            num(e.largest_deflection),
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
    }
    if !r.combinations.is_empty() {
        let _ = writeln!(s);
        let _ = writeln!(
            s,
            "Determined combinations of parameters the data cannot separate:"
        );
        for c in &r.combinations {
            let _ = writeln!(
                s,
                "  {} = {} {} (was {}, sigma {:.3e}, change {:.1} sigma{})",
                c.expression,
                num(c.value),
                combination_unit(r, &c.expression),
                num(c.initial),
                c.sigma,
                c.significance,
                if c.within_noise { ", within noise" } else { "" }
            );
        }
    }
    if !r.outliers.is_empty() {
        let _ = writeln!(s);
        let _ = writeln!(
            s,
            "Outliers ({}; a residual beyond {} robust sigmas; kept in the fit{}):",
            r.outliers.len(),
            (r.outlier_sigmas * 100.0).round() / 100.0,
            if r.loss == "squared" {
                ", consider --loss huber"
            } else {
                ""
            }
        );
        for o in &r.outliers {
            let _ = writeln!(
                s,
                "  {:<9} line {:<5} posture {:<10} site {:<8} {} error {} {l}{}  ({:.1} sigma)",
                o.kind,
                o.line,
                o.posture,
                o.site,
                if o.metric.is_empty() {
                    "position"
                } else {
                    &o.metric
                },
                num(o.position_error),
                o.orientation_error.map_or(String::new(), |e| format!(
                    ", attitude error {} {a}",
                    num(e)
                )),
                o.sigmas
            );
        }
    }
    if !r.undetermined.is_empty() {
        let _ = writeln!(s);
        let _ = writeln!(
            s,
            "Not individually determined ({}): {}. Their changes mean nothing one by one (see the combinations \
             above); --estimate identifiable estimates only a determined set, --solution min-change picks the \
             answer closest to nominal.",
            r.undetermined.len(),
            r.undetermined.join(", ")
        );
    }
    if let Some(p) = &r.pruning {
        let _ = writeln!(s);
        let _ =
            writeln!(
            s,
            "Pruned at {} sigma: removed {}; full fit had objective {:.6e}, RMS position {} {l}{}",
            p.k,
            if p.removed.is_empty() { "nothing".to_string() } else { p.removed.join(", ") },
            p.full_objective_after,
            num(p.full_rms_position_after),
            p.full_rms_orientation_after
                .map_or(String::new(), |v| format!(", RMS attitude {} {a}", num(v)))
        );
    }
    if let Some(p) = &r.prediction {
        s += &prediction_lines(p, l, a);
    }
    if !r.timings.is_empty() {
        let _ = writeln!(
            s,
            "\ntime: {:.3} s ({})",
            r.timings.iter().map(|t| t.seconds).sum::<f64>(),
            r.timings
                .iter()
                .map(|t| format!("{} {:.3}", t.phase, t.seconds))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    s
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
