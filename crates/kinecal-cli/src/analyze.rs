//! `kinecal analyze`: the analysis as text.

use std::fmt::Write as _;

use kinecal::identifiability::{fmt_sig, format_combination};
use kinecal::spec::{AnalyzeOutcome, Document, MatrixKind, MatrixUnits};
use kinecal::Robot;

use crate::args::AnalyzeArgs;
use crate::word;

/// Prints an analysis: its JSON document with `--json`, else as text; the matrix asked for
/// after it.
pub fn show(d: &Document, a: &AnalyzeArgs) {
    let Document::Analysis(o) = d else { return };
    if a.json {
        println!("{}", o.report.to_json());
    } else {
        print!("{}", text(o));
    }
    if let Some((kind, units, table)) = &o.matrix {
        print!("{}", matrix(o, *kind, *units, table));
    }
}

fn ids(list: &[kinecal::ParamId]) -> Vec<String> {
    list.iter().map(ToString::to_string).collect()
}

fn names(robot: &Robot, list: &[kinecal::ParamId]) -> String {
    list.iter()
        .map(|&id| format!("{id} ({})", robot.param_name(id)))
        .collect::<Vec<_>>()
        .join(", ")
}

fn text(o: &AnalyzeOutcome) -> String {
    let (an, robot) = (&o.analysis, &o.robot);
    let mut s = String::new();
    let n = an.parameters.len();
    let kinds: Vec<String> = o
        .kinds
        .iter()
        .map(|(k, c)| format!("{c} {k}{}", if *c == 1 { "" } else { "s" }))
        .collect();
    let _ = writeln!(
        s,
        "{}: {} parameters over {} postures, {} observations ({}), {} residuals",
        if robot.name.is_empty() {
            "robot"
        } else {
            &robot.name
        },
        n,
        o.postures,
        o.observations,
        kinds.join(", "),
        an.residuals
    );
    let _ = writeln!(s);
    if an.prior_rows > 0 {
        let needs = an.prior_dependent();
        let _ = writeln!(
            s,
            "With the prior: {} of its rows after the data's; the rank is of both together. {}",
            an.prior_rows,
            if needs.is_empty() {
                "The data alone determines every parameter it determines.".to_string()
            } else {
                format!(
                    "Determined only with the prior ({}): {}.",
                    needs.len(),
                    needs
                        .iter()
                        .map(|&id| robot.param_name(id))
                        .collect::<Vec<_>>()
                        .join(", ")
                )
            }
        );
        let _ = writeln!(s);
    }
    let gap = if an.gap_ratio.is_finite() {
        format!("{:.2e}", an.gap_ratio)
    } else {
        "infinite".into()
    };
    let _ = writeln!(
        s,
        "Numerical rank {} of {n}: scaled singular values above {:e} x the largest. Largest gap in the \
         spectrum: after value {} (ratio {gap}){}.",
        an.rank,
        an.rcond,
        an.gap_rank,
        if an.rank_consistent { ", consistent" } else { ", NOT consistent with the tolerance" }
    );
    match &an.expected {
        Some(e) => {
            let _ = writeln!(s, "Thesis count (eqs. 4.2, 4.3, 4.5): {}.", e.formula);
            let verdict = match an.rank.cmp(&e.rank) {
                _ if an.prior_rows > 0 => "It counts what the data alone determines; the rank above is of the data and the prior together.".to_string(),
                std::cmp::Ordering::Equal => "The measured rank matches: every loss of rank is the model's inherent redundancy.".to_string(),
                std::cmp::Ordering::Less => format!(
                    "The measured rank is {} below it: the postures do not excite every direction (too few, too alike, or a joint \
                     that barely moves), or the geometry is special (a link at beta = +-90 deg).",
                    e.rank - an.rank
                ),
                std::cmp::Ordering::Greater => format!(
                    "The measured rank is {} above it: nearly-redundant directions are counted as determined; check the gap and --rcond.",
                    an.rank - e.rank
                ),
            };
            let _ = writeln!(s, "{verdict}");
        }
        None => {
            let _ = writeln!(
                s,
                "Thesis count: not applicable (it assumes every link parameter and joint offset on the way to a measured \
                 frame estimated, and every measured site's parameters estimated)."
            );
        }
    }
    let _ =
        writeln!(
        s,
        "{} redundant parameter(s): the data{} determines {} independent combinations of the {n}.",
        n - an.rank,
        if an.prior_rows > 0 { " with the prior" } else { "" },
        an.rank
    );
    let _ = writeln!(s);
    let _ = writeln!(
        s,
        "Singular values (scaled: the solver's units; file: {} and {}):",
        robot.units.length, robot.units.angle
    );
    let _ = writeln!(
        s,
        "{:>4} {:>12} {:>12} {:>12} {:>12}",
        "#", "J scaled", "J^TJ scaled", "J file", "J^TJ file"
    );
    for k in 0..n {
        let (a, b) = (
            an.singular_values_scaled[k],
            an.singular_values_file.get(k).copied().unwrap_or(0.0),
        );
        let _ = writeln!(
            s,
            "{:>4} {:>12.4e} {:>12.4e} {:>12.4e} {:>12.4e}{}",
            k + 1,
            a,
            a * a,
            b,
            b * b,
            if k + 1 == an.rank && an.rank < n {
                "   <- rank"
            } else {
                ""
            }
        );
    }
    let _ = writeln!(
        s,
        "Condition number over the rank, s1/s{}: scaled {:.4e} (J^TJ {:.4e}); file units {:.4e} (J^TJ {:.4e}).",
        an.rank,
        an.condition_number(),
        an.condition_number().powi(2),
        an.condition_number_file(),
        an.condition_number_file().powi(2)
    );
    if !an.unobservable.is_empty() {
        let _ = writeln!(s);
        let _ = writeln!(
            s,
            "No measurement feels: {}.",
            names(robot, &an.unobservable)
        );
    }
    if !an.identical_groups.is_empty() {
        let _ = writeln!(s);
        let count: usize = an.identical_groups.iter().map(|g| g.terms.len() - 1).sum();
        let _ = writeln!(
            s,
            "Identical redundancies ({count}, in {} groups; equal or opposite Jacobian columns at every posture). The data \
             determines at most each group's combination:",
            an.identical_groups.len()
        );
        for g in &an.identical_groups {
            let members: Vec<String> = g
                .terms
                .iter()
                .map(|(id, _)| robot.param_name(*id))
                .collect();
            let status = if g.determined {
                ""
            } else {
                "   NOT determined: members also enter other dependencies below"
            };
            let _ = writeln!(
                s,
                "  {} = {}   ({}){status}",
                format_combination(&g.terms),
                fmt_sig(g.value),
                members.join(", ")
            );
        }
    }
    if !an.null_space.is_empty() {
        let _ = writeln!(s);
        let _ = writeln!(
            s,
            "Undetermined directions (a basis of the null space in reduced form, file units): moving the parameters by \
             any multiple of one of these changes no prediction:"
        );
        for row in &an.null_space {
            let terms: Vec<String> = row
                .iter()
                .map(|&(id, c)| format!("{} {}", fmt_sig(c), robot.param_name(id)))
                .collect();
            let _ = writeln!(s, "  [{}]", terms.join(", "));
        }
    }
    let _ = writeln!(s);
    let _ = writeln!(
        s,
        "Identifiable set ({} of rank {}; QR with column pivoting on noise-scaled columns, by priority): {}",
        an.identifiable.len(),
        an.rank,
        ids(&an.identifiable).join(" ")
    );
    if !an.noise_dependent.is_empty() {
        let _ = writeln!(
            s,
            "Not determined at the noise level ({}; at the stated weights, each only to worse than \
             0.02 rad, 2 % of the reach or 2 % of a slope, given the parameters chosen before it):",
            an.noise_dependent.len()
        );
        for d in &an.noise_dependent {
            let _ = writeln!(
                s,
                "  {}   ({}; sigma {} {}, sin {:.2e})",
                d.expression(),
                robot.param_name(d.id),
                kinecal::identifiability::fmt_sig(d.sigma),
                robot.param_unit(d.id),
                d.sine
            );
        }
    }
    let undetermined: Vec<kinecal::ParamId> = an
        .parameters
        .iter()
        .zip(&an.determined)
        .filter(|(_, d)| !**d)
        .map(|(id, _)| *id)
        .collect();
    if !undetermined.is_empty() {
        let _ = writeln!(
            s,
            "Not individually determined ({}): {}",
            undetermined.len(),
            ids(&undetermined).join(" ")
        );
    }
    for w in &an.warnings {
        let _ = writeln!(s, "warning: {}", word(w));
    }
    s
}

fn matrix(
    o: &AnalyzeOutcome,
    which: MatrixKind,
    units: MatrixUnits,
    table: &kinecal::identifiability::JacobianTable,
) -> String {
    let (an, robot) = (&o.analysis, &o.robot);
    let mut s = String::new();
    let m = match units {
        MatrixUnits::File => &table.file,
        MatrixUnits::Scaled => &table.scaled,
    };
    let unit_label = match units {
        MatrixUnits::File => format!("{}, {}", robot.units.length, robot.units.angle),
        MatrixUnits::Scaled => "scaled".to_string(),
    };
    let _ = writeln!(s);
    let head: String = an
        .parameters
        .iter()
        .map(|id| format!("{:>11}", id.to_string()))
        .collect();
    match which {
        MatrixKind::Jacobian => {
            let _ = writeln!(s, "Jacobian ({unit_label}):");
            let _ = writeln!(s, "{:<22}{head}", "posture site comp");
            for (i, (p, site, c)) in table.row_labels.iter().enumerate() {
                let row: String = (0..m.ncols())
                    .map(|j| format!("{:>11.4}", m[(i, j)]))
                    .collect();
                let _ = writeln!(s, "{:<22}{row}", format!("{p} {site} {c}"));
            }
        }
        MatrixKind::Hessian => {
            let _ = writeln!(s, "J^T J ({unit_label}):");
            let _ = writeln!(s, "{:<8}{head}", "");
            for a in 0..m.ncols() {
                let row: String = (0..m.ncols())
                    .map(|b| {
                        format!(
                            "{:>11.4}",
                            (0..m.nrows()).map(|i| m[(i, a)] * m[(i, b)]).sum::<f64>()
                        )
                    })
                    .collect();
                let _ = writeln!(s, "{:<8}{row}", an.parameters[a].to_string());
            }
        }
    }
    s
}
