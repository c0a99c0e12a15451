//! The HTML page of a measurement plan: what was chosen, where the postures lie in joint space
//! against the candidates, and how much information each carries.

use std::fmt::Write as _;

use kinecal::apps::plan::Plan;
use kinecal::identifiability::fmt_sig;
use kinecal::observe::Dataset;
use kinecal::Robot;

use crate::chart::{Line, Panel};
use crate::number::{num, opt};
use crate::page::{charts, esc, page_head};
use crate::DrawError;
use kinecal::report::nice_width;

/// Bins of the joint-space histograms.
const BINS: usize = 12;

/// The unit of joint `j`'s readings: the joint's own (`deg`, `mm`) when its transducer reads
/// the joint variable (a slope of 1 in the robot file's units), else transducer units.
pub(crate) fn reading_unit(robot: &Robot, j: usize) -> String {
    let joint = &robot.joints[j];
    let slope = robot.units.from_si(joint.kind.slope(), joint.slope);
    if (slope - 1.0).abs() <= 1e-12 && joint.coupling.is_none() {
        robot.units.label(joint.kind.variable())
    } else {
        "transducer units".into()
    }
}

/// One panel per joint: how the chosen postures' readings spread over the joint's range
/// (bars), against the candidates' spread scaled to the plan's size (line).
fn joint_panels(plan: &Plan, robot: &Robot, pool: &Dataset) -> Vec<Panel> {
    let chosen = plan.postures.len() as f64;
    (0..robot.dof())
        .map(|j| {
            let values = pool
                .postures
                .iter()
                .map(|p| p.readings[j])
                .chain(plan.postures.iter().map(|q| q.readings[j]));
            let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(v), b.max(v))
            });
            let width = nice_width(((hi - lo) / BINS as f64).max(f64::MIN_POSITIVE));
            let start = (lo / width).floor() * width;
            let bins = (((hi - start) / width).floor() as usize + 1).max(1);
            let bin = |v: f64| (((v - start) / width).floor() as usize).min(bins - 1);
            let mut ours = vec![0.0; bins];
            for q in &plan.postures {
                ours[bin(q.readings[j])] += 1.0;
            }
            let mut pool_counts = vec![0.0; bins];
            for p in &pool.postures {
                pool_counts[bin(p.readings[j])] += 1.0;
            }
            let scale = chosen / pool.postures.len().max(1) as f64;
            Panel {
                title: format!("Joint {}: readings of the plan", j + 1),
                x_label: format!("reading v{} ({})", j + 1, reading_unit(robot, j)),
                y_label: "postures".into(),
                x: (0..bins)
                    .map(|b| start + (b as f64 + 0.5) * width)
                    .collect(),
                lines: vec![Line {
                    points: true,
                    ..Line::new(
                        "candidates (scaled)",
                        pool_counts.iter().map(|c| c * scale).collect(),
                    )
                }],
                bars: ours
                    .iter()
                    .enumerate()
                    .map(|(b, &c)| {
                        let x = start + b as f64 * width;
                        (x, x + width, c)
                    })
                    .collect(),
                ..Panel::default()
            }
        })
        .collect()
}

/// The leverage of each posture of the plan, with the average `n / postures`.
fn leverage_panel(plan: &Plan) -> Panel {
    let n = plan.parameters.len() as f64;
    let k = plan.postures.len();
    let labelled = k <= 40;
    Panel {
        title: "Information each posture carries".into(),
        x_label: if labelled {
            "posture".into()
        } else {
            "posture (in the plan's order)".into()
        },
        y_label: "leverage (parameters' worth)".into(),
        x: (0..k).map(|i| i as f64).collect(),
        x_names: if labelled {
            plan.postures.iter().map(|q| q.label.clone()).collect()
        } else {
            Vec::new()
        },
        lines: vec![Line {
            points: true,
            ..Line::new(
                "leverage",
                plan.postures.iter().map(|q| q.leverage).collect(),
            )
        }],
        h_lines: vec![(
            n / k as f64,
            format!("average ({} / {k})", plan.parameters.len()),
        )],
        ..Panel::default()
    }
}

/// The HTML page of `plan`, chosen for `robot` from `pool` (described in `source`): what was
/// chosen and how well, the postures in joint space, the information each carries, every
/// criterion, the postures' table and the parameters.
pub fn html_plan(
    plan: &Plan,
    robot: &Robot,
    pool: &Dataset,
    source: &str,
) -> Result<String, DrawError> {
    let mut h = page_head(&format!("kinecal measurement plan: {}", robot.name));
    h += &chosen(plan, robot, source);
    h += &against_random_plans(plan);
    h += "<h2>Postures in joint space</h2>\n";
    h += "<p>Bars: the plan's readings per joint; points: the candidates' readings, scaled to the plan's size. An optimal plan leaves the candidates' average: it goes where the parameters show.</p>\n";
    h += &charts(&joint_panels(plan, robot, pool))?;
    let n = plan.parameters.len();
    h += "<h2>Information per posture</h2>\n";
    let _ = writeln!(
        h,
        "<p>The leverage of a posture is how many of the {n} parameters' worth of information it carries (they sum to {n} when the plan determines every parameter). A posture far above the average holds directions few others see: measure it with care.</p>"
    );
    h += &charts(&[leverage_panel(plan)])?;
    h += &all_criteria(plan);
    h += &postures_table(plan, robot);
    let _ = writeln!(
        h,
        "<p>Parameters: {}.</p></body></html>",
        esc(&plan
            .parameters
            .iter()
            .map(|&id| robot.param_name(id))
            .collect::<Vec<_>>()
            .join(", "))
    );
    Ok(h)
}

/// The title, what was chosen from where by which criterion, and a warning when the plan does
/// not reach full rank.
fn chosen(plan: &Plan, robot: &Robot, source: &str) -> String {
    let n = plan.parameters.len();
    let kept = plan
        .postures
        .iter()
        .filter(|q| q.candidate.is_none())
        .count();
    let mut h = format!("<h1>Measurement plan: {}</h1>\n", esc(&robot.name));
    let _ = writeln!(
        h,
        "<p>{} postures chosen from {}{}, criterion <b>{}</b> ({}); {} residual rows for {n} parameters.</p>",
        plan.postures.len() - kept,
        esc(source),
        if kept > 0 {
            format!(", with {kept} postures already measured")
        } else {
            String::new()
        },
        plan.criterion.as_str(),
        esc(plan.criterion.describe()),
        plan.rows,
    );
    if plan.rank < n {
        let _ = writeln!(
            h,
            "<p class=\"warn\">The plan reaches rank {} of {n}: too few postures to determine every parameter.</p>",
            plan.rank
        );
    }
    h
}

/// The plan's criterion, information per posture and rank beside the median random plan's,
/// and how many random plans it beats.
fn against_random_plans(plan: &Plan) -> String {
    let pct = |v: Option<f64>| {
        v.map(|e| format!("{:.0} %", 100.0 * e))
            .unwrap_or_else(|| "n/a".into())
    };
    let mut h = String::from(
        "<table><tr><th class=\"l\"></th><th>this plan</th><th>median of random plans</th></tr>\n",
    );
    let random = plan.random.as_ref();
    let _ = writeln!(
        h,
        "<tr><td class=\"l\">criterion {}</td><td>{}</td><td>{}</td></tr>",
        plan.criterion.as_str(),
        opt(plan.value),
        opt(random.and_then(|r| r.median_value))
    );
    let _ = writeln!(
        h,
        "<tr><td class=\"l\">information per posture (D-efficiency against the candidates' average)</td><td>{}</td><td>{}</td></tr>",
        pct(plan.efficiency),
        pct(random.and_then(|r| r.median_efficiency))
    );
    let _ = writeln!(
        h,
        "<tr><td class=\"l\">rank / condition number</td><td>{} / {}</td><td></td></tr></table>",
        plan.rank,
        opt(plan.condition_number)
    );
    if let Some(r) = random {
        let _ = writeln!(
            h,
            "<p>The plan is at least as good as {} of {} random plans of the same size by its criterion.</p>",
            r.beaten, r.draws
        );
    }
    h
}

/// Every criterion's value for the plan.
fn all_criteria(plan: &Plan) -> String {
    let mut h = String::from(
        "<h2>All criteria</h2><table><tr><th class=\"l\">criterion</th><th>value</th></tr>\n",
    );
    for (c, v) in &plan.values {
        let _ = writeln!(
            h,
            "<tr><td class=\"l\">{} ({})</td><td>{}</td></tr>",
            c.as_str(),
            esc(c.describe()),
            opt(*v)
        );
    }
    h += "</table>\n";
    h
}

/// Each posture (kept ones marked) with its leverage and readings.
fn postures_table(plan: &Plan, robot: &Robot) -> String {
    let mut h = String::from(
        "<h2>The postures</h2><table><tr><th class=\"l\">posture</th><th>leverage</th>\n",
    );
    for j in 0..robot.dof() {
        let _ = write!(h, "<th>v{}</th>", j + 1);
    }
    h += "</tr>\n";
    for q in &plan.postures {
        let _ = write!(
            h,
            "<tr><td class=\"l\">{}{}</td><td>{}</td>",
            esc(&q.label),
            if q.candidate.is_none() { " (kept)" } else { "" },
            num(q.leverage)
        );
        for v in &q.readings {
            let _ = write!(h, "<td>{}</td>", fmt_sig(*v));
        }
        h += "</tr>\n";
    }
    h += "</table>\n";
    h
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn readings_are_labelled_in_the_joints_unit_when_they_are_its_values() {
        // The GE A4's transducers read 7.2 deg per unit: transducer units.
        let a4 = kinecal::model::examples::ge_a4();
        assert_eq!(reading_unit(&a4, 0), "transducer units");
        // A robot whose readings are its joint angles (slope 1): degrees, or its own unit.
        let mut deg = a4.clone();
        for j in &mut deg.joints {
            j.slope = deg.units.to_si(j.kind.slope(), 1.0);
        }
        assert_eq!(reading_unit(&deg, 0), "deg");
        deg.units.angle = kinecal::AngleUnit::Rad;
        for j in &mut deg.joints {
            j.slope = 1.0;
        }
        assert_eq!(reading_unit(&deg, 0), "rad");
    }
}
