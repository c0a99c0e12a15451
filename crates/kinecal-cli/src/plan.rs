//! `kinecal plan`: the plan as text.

use std::fmt::Write as _;

use kinecal::apps::plan::Plan;
use kinecal::identifiability::fmt_sig;
use kinecal::spec::Document;
use kinecal::Robot;
use kinecal_report::number::opt;

/// Prints a plan: its JSON document with `--json`, else as text.
pub fn show(d: &Document, json: bool) {
    let Document::Plan(o) = d else { return };
    if json {
        println!("{}", o.report.to_json());
    } else {
        print!("{}", text(&o.plan, &o.robot, &o.described));
    }
}

/// The plan as text: what was chosen, how good it is, and the postures.
pub fn text(p: &Plan, robot: &Robot, described: &str) -> String {
    chosen(p, robot, described) + &quality(p) + &postures(p, robot)
}

/// What was chosen from how many candidates, for which parameters.
fn chosen(p: &Plan, robot: &Robot, described: &str) -> String {
    let mut s = String::new();
    let n = p.parameters.len();
    let kept = p.postures.iter().filter(|q| q.candidate.is_none()).count();
    let chosen = p.postures.len() - kept;
    let _ = writeln!(s, "plan for {}: {described}", robot.name);
    let _ = writeln!(
        s,
        "chose {chosen} of {} candidates{}; {} residual rows for {n} parameters",
        p.pool_candidates,
        if kept > 0 {
            format!(", with {kept} kept postures")
        } else {
            String::new()
        },
        p.rows
    );
    let _ = writeln!(
        s,
        "parameters: {}",
        p.parameters
            .iter()
            .map(|&id| robot.param_name(id))
            .collect::<Vec<_>>()
            .join(", ")
    );
    s
}

/// How good the plan is: its rank and condition, its criterion, its information per posture
/// against random plans of its size, the search, every criterion.
fn quality(p: &Plan) -> String {
    let mut s = String::new();
    let n = p.parameters.len();
    let _ = writeln!(
        s,
        "rank {} of {n}{}; condition number {}",
        p.rank,
        if p.rank < n {
            " (too few postures: the plan cannot determine every parameter)"
        } else {
            ""
        },
        opt(p.condition_number)
    );
    let _ = writeln!(
        s,
        "criterion {} ({}): {}",
        p.criterion.as_str(),
        p.criterion.describe(),
        opt(p.value)
    );
    if let Some(e) = p.efficiency {
        let _ = writeln!(
            s,
            "information per posture: {:.0} % of the candidates' average (D-efficiency)",
            100.0 * e
        );
    }
    if let Some(r) = &p.random {
        let _ = writeln!(
            s,
            "{} random plans of the same size: criterion median {}, information per posture \
             median {}; this plan is at least as good as {} of them",
            r.draws,
            opt(r.median_value),
            r.median_efficiency
                .map(|e| format!("{:.0} %", 100.0 * e))
                .unwrap_or_else(|| "n/a".into()),
            r.beaten
        );
    }
    let _ = writeln!(
        s,
        "search: greedy start, exchange {} swap{} in {} pass{}",
        p.exchanges,
        if p.exchanges == 1 { "" } else { "s" },
        p.passes,
        if p.passes == 1 { "" } else { "es" }
    );
    let _ = writeln!(
        s,
        "all criteria: {}",
        p.values
            .iter()
            .map(|(c, v)| format!("{} {}", c.as_str(), opt(*v)))
            .collect::<Vec<_>>()
            .join(", ")
    );
    s
}

/// The postures (kept ones marked) with their leverage and readings.
fn postures(p: &Plan, robot: &Robot) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "\npostures (leverage: how many of the {} parameters' worth of information each carries)",
        p.parameters.len()
    );
    let _ = write!(s, "  {:<10} {:>8}", "posture", "leverage");
    for j in 0..robot.dof() {
        let _ = write!(s, " {:>10}", format!("v{}", j + 1));
    }
    let _ = writeln!(s);
    for q in &p.postures {
        let _ = write!(
            s,
            "  {:<10} {:>8.3}",
            if q.candidate.is_none() {
                format!("{} (kept)", q.label)
            } else {
                q.label.clone()
            },
            q.leverage
        );
        for v in &q.readings {
            let _ = write!(s, " {:>10}", fmt_sig(*v));
        }
        let _ = writeln!(s);
    }
    s
}
