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

/// The analysis as text, section after section ([`SECTIONS`]).
fn text(o: &AnalyzeOutcome) -> String {
    SECTIONS.iter().map(|section| section(o)).collect()
}

/// A section of the text: its lines, from the analysis.
type Section = fn(&AnalyzeOutcome) -> String;

/// The sections, in order: the data, the prior's part, the rank against the thesis's count,
/// the spectrum, what no measurement feels, the identical redundancies, the undetermined
/// directions, and the identifiable set with what is not determined.
const SECTIONS: [Section; 8] = [
    data,
    prior,
    rank,
    spectrum,
    unobservable,
    identical_groups,
    null_space,
    identifiable,
];

/// The robot, its parameters and the data: postures, observations by kind, residuals.
fn data(o: &AnalyzeOutcome) -> String {
    let (an, robot) = (&o.analysis, &o.robot);
    let kinds: Vec<String> = o
        .kinds
        .iter()
        .map(|(k, c)| format!("{c} {k}{}", if *c == 1 { "" } else { "s" }))
        .collect();
    format!(
        "{}: {} parameters over {} postures, {} observations ({}), {} residuals\n\n",
        if robot.name.is_empty() {
            "robot"
        } else {
            &robot.name
        },
        an.parameters.len(),
        o.postures,
        o.observations,
        kinds.join(", "),
        an.residuals
    )
}

/// With a prior: its rows, and what only it determines.
fn prior(o: &AnalyzeOutcome) -> String {
    let (an, robot) = (&o.analysis, &o.robot);
    if an.prior_rows == 0 {
        return String::new();
    }
    let needs = an.prior_dependent();
    format!(
        "With the prior: {} of its rows after the data's; the rank is of both together. {}\n\n",
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
    )
}

/// The numerical rank and the spectrum's gap, the thesis's count of it and what the
/// difference means, and the number of redundant parameters.
fn rank(o: &AnalyzeOutcome) -> String {
    let an = &o.analysis;
    let n = an.parameters.len();
    let mut s = String::new();
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
    s += &thesis_count(o);
    let _ =
        writeln!(
        s,
        "{} redundant parameter(s): the data{} determines {} independent combinations of the {n}.",
        n - an.rank,
        if an.prior_rows > 0 { " with the prior" } else { "" },
        an.rank
    );
    s + "\n"
}

/// The thesis's count of the rank (eqs. 4.2, 4.3, 4.5), when it applies, and what the measured
/// rank's difference from it means.
fn thesis_count(o: &AnalyzeOutcome) -> String {
    let an = &o.analysis;
    let Some(e) = &an.expected else {
        return "Thesis count: not applicable (it assumes every link parameter and joint offset \
                on the way to a measured frame estimated, and every measured site's parameters \
                estimated).\n"
            .to_string();
    };
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
    format!(
        "Thesis count (eqs. 4.2, 4.3, 4.5): {}.\n{verdict}\n",
        e.formula
    )
}

/// The singular values of J and J^T J, scaled and in file units, the rank marked; the
/// condition numbers over the rank.
fn spectrum(o: &AnalyzeOutcome) -> String {
    let (an, robot) = (&o.analysis, &o.robot);
    let n = an.parameters.len();
    let mut s = String::new();
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
    s
}

/// The parameters no measurement feels.
fn unobservable(o: &AnalyzeOutcome) -> String {
    let (an, robot) = (&o.analysis, &o.robot);
    if an.unobservable.is_empty() {
        return String::new();
    }
    format!(
        "\nNo measurement feels: {}.\n",
        names(robot, &an.unobservable)
    )
}

/// The groups of parameters with equal or opposite Jacobian columns, and each group's
/// combination the data determines.
fn identical_groups(o: &AnalyzeOutcome) -> String {
    let (an, robot) = (&o.analysis, &o.robot);
    if an.identical_groups.is_empty() {
        return String::new();
    }
    let mut s = String::new();
    let count: usize = an.identical_groups.iter().map(|g| g.terms.len() - 1).sum();
    let _ = writeln!(
        s,
        "\nIdentical redundancies ({count}, in {} groups; equal or opposite Jacobian columns at every posture). The data \
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
    s
}

/// A basis of the null space: the directions the parameters can move in unseen.
fn null_space(o: &AnalyzeOutcome) -> String {
    let (an, robot) = (&o.analysis, &o.robot);
    if an.null_space.is_empty() {
        return String::new();
    }
    let mut s = String::from(
        "\nUndetermined directions (a basis of the null space in reduced form, file units): moving the parameters by \
         any multiple of one of these changes no prediction:\n",
    );
    for row in &an.null_space {
        let terms: Vec<String> = row
            .iter()
            .map(|&(id, c)| format!("{} {}", fmt_sig(c), robot.param_name(id)))
            .collect();
        let _ = writeln!(s, "  [{}]", terms.join(", "));
    }
    s
}

/// The identifiable set (QR with column pivoting), the parameters not determined at the
/// noise level or not individually, and the warnings.
fn identifiable(o: &AnalyzeOutcome) -> String {
    let (an, robot) = (&o.analysis, &o.robot);
    let mut s = String::new();
    let _ = writeln!(
        s,
        "\nIdentifiable set ({} of rank {}; QR with column pivoting on noise-scaled columns, by priority): {}",
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
                fmt_sig(d.sigma),
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
