//! `kinecal iso9283`: the test poses and the pose figures as text.

use kinecal::apps::iso9283::{pose_name, Evaluation, PoseFigures, Spread};
use kinecal::identifiability::fmt_sig;
use kinecal::spec::Document;
use kinecal_report::number::{num, signed};

/// Prints the test poses of a plan, or the figures of a log.
pub fn show(d: &Document) {
    match d {
        Document::Iso9283Plan(p) => print!("{}", plan_text(&p.document)),
        Document::Iso9283(e) => print!("{}", text(e)),
        _ => {}
    }
}

/// The test poses as text.
fn plan_text(p: &kinecal::spec::Iso9283PlanDocument) -> String {
    use std::fmt::Write as _;
    let (len, ang) = (&p.length_unit, &p.angle_unit);
    let mut s = String::new();
    let _ = writeln!(
        s,
        "cube: centre ({}, {}, {}) {len}, side {} {len}",
        num(p.centre[0]),
        num(p.centre[1]),
        num(p.centre[2]),
        num(p.side)
    );
    let _ = match p.search {
        Some((tested, step, reached)) => writeln!(
            s,
            "searched: {tested} grid points tested (step {} {len}), {reached} reached; the cube's \
             test poses and its 8 corners are reached inside the joint ranges (a search, not a \
             proof of the largest cube)",
            num(step),
        ),
        None => writeln!(
            s,
            "given: its test poses are reached inside the joint ranges"
        ),
    };
    let mut header = format!("pose  {:>10} {:>10} {:>10}", "x", "y", "z");
    if p.poses.iter().any(|t| t.attitude.is_some()) {
        header += &format!(" {:>9} {:>9} {:>9}", "a", "b", "c");
    }
    header += "  readings";
    let _ = writeln!(s, "{header}");
    for t in &p.poses {
        let mut line = format!(
            "{}    {:>10} {:>10} {:>10}",
            t.pose,
            num(t.position[0]),
            num(t.position[1]),
            num(t.position[2])
        );
        if let Some(att) = t.attitude {
            for v in att {
                line += &format!(" {:>9}", num(v));
            }
        }
        line += "  ";
        line += &t
            .readings
            .iter()
            .map(|&v| fmt_sig(v))
            .collect::<Vec<_>>()
            .join(",");
        let _ = writeln!(s, "{line}");
    }
    let _ = writeln!(
        s,
        "each cycle visits P1, P5, P4, P3, P2; ISO 9283 asks for 30 cycles (lengths in {len}, \
         angles in {ang})"
    );
    s
}

/// The figures as text: for one test, a table per pose, then the distances; for a series of
/// tests, the summary across them (the figures of each test are in the JSON).
fn text(e: &Evaluation) -> String {
    match &e.summary {
        Some(_) => summary_text(e),
        None => test_text(e),
    }
}

/// `count, mean, p95, max` of a spread, in columns.
fn spread_cells(v: Option<&Spread>) -> String {
    match v {
        Some(v) => format!(
            "{:>5} {:>10} {:>10} {:>10}",
            v.count,
            num(v.mean),
            num(v.p95),
            num(v.max)
        ),
        None => format!("{:>5} {:>10} {:>10} {:>10}", 0, "-", "-", "-"),
    }
}

/// The summary of a series of tests.
fn summary_text(e: &Evaluation) -> String {
    use std::fmt::Write as _;
    let Some(sum) = &e.summary else {
        return String::new();
    };
    let l = e
        .length_unit
        .map_or_else(|| "the log's length unit".to_string(), |u| u.to_string());
    let mut s = String::new();
    let _ = writeln!(
        s,
        "ISO 9283 pose characteristics of {}{}: {} tests, {} poses; lengths in {l}",
        e.file,
        if e.simulated { " (simulated)" } else { "" },
        sum.tests,
        e.poses.len()
    );
    let _ = writeln!(s);
    let _ = writeln!(
        s,
        "AP over the tests        count       mean        p95        max"
    );
    let name = |pose: usize| {
        if pose == 0 {
            "every pose".to_string()
        } else {
            pose_name(pose)
        }
    };
    for p in &sum.poses {
        let _ = writeln!(s, "{:<20} {}", name(p.pose), spread_cells(Some(&p.ap)));
    }
    if sum.poses.iter().any(|p| p.rp.is_some()) {
        let _ = writeln!(s);
        let _ = writeln!(
            s,
            "RP (2 cycles or more)    count       mean        p95        max"
        );
        for p in &sum.poses {
            let _ = writeln!(s, "{:<20} {}", name(p.pose), spread_cells(p.rp.as_ref()));
        }
    }
    if sum.poses.iter().any(|p| p.compensated_95.is_some()) {
        let _ = writeln!(s);
        let _ = writeln!(
            s,
            "compensated AP, predicted RMS / 95 % bound (mean over the tests); measured AP within"
        );
        for p in &sum.poses {
            if let (Some(rms), Some(b)) = (&p.compensated_rms, &p.compensated_95) {
                let _ = writeln!(
                    s,
                    "{:<20} {:>10} {:>10}   {:.1} %",
                    name(p.pose),
                    num(rms.mean),
                    num(b.mean),
                    100.0 * p.within_compensated_95.unwrap_or(0.0)
                );
            }
        }
    }
    let _ = writeln!(s);
    let _ = writeln!(
        s,
        "distances                count       mean        p95        max"
    );
    let _ = writeln!(s, "{:<20} {}", "|AD|", spread_cells(sum.ad.as_ref()));
    if sum.rd.is_some() {
        let _ = writeln!(s, "{:<20} {}", "RD", spread_cells(sum.rd.as_ref()));
    }
    s.lines().map(str::trim_end).collect::<Vec<_>>().join("\n") + "\n"
}

/// The figures of one test as text: the log, a table per pose, then the distances.
fn test_text(e: &Evaluation) -> String {
    use std::fmt::Write as _;
    let l = e
        .length_unit
        .map_or_else(|| "the log's length unit".to_string(), |u| u.to_string());
    let a = e
        .angle_unit
        .map_or_else(|| "the log's angle unit".to_string(), |u| u.to_string());
    let mut s = String::new();
    let _ = writeln!(
        s,
        "ISO 9283 pose characteristics of {}{}: {} pose{}; lengths in {l}, angles in {a}",
        e.file,
        if e.simulated { " (simulated)" } else { "" },
        e.poses.len(),
        if e.poses.len() == 1 { "" } else { "s" }
    );
    for f in &e.poses {
        s += "\n";
        s += &pose_text(f);
    }
    s += &distances_text(e);
    // No padding left at the ends of lines.
    s.lines().map(str::trim_end).collect::<Vec<_>>().join("\n") + "\n"
}

/// A figure and its value, in columns.
fn cell(name: &str, v: String) -> String {
    format!("{name:<4} {v:<12}")
}

/// One pose's figures: the commanded pose, AP, RP, the attitude's AP and RP, vAP, and AP once
/// compensated.
fn pose_text(f: &PoseFigures) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let mut commanded = format!(
        "x {}, y {}, z {}",
        num(f.commanded[0]),
        num(f.commanded[1]),
        num(f.commanded[2])
    );
    if let Some(c) = f.commanded_attitude {
        commanded += &format!("; a {}, b {}, c {}", num(c[0]), num(c[1]), num(c[2]));
    }
    let _ = writeln!(
        s,
        "{}{}: {} cycle{}, commanded {commanded}",
        f.test
            .as_deref()
            .map(|t| format!("{t}, "))
            .unwrap_or_default(),
        pose_name(f.pose),
        f.cycles,
        if f.cycles == 1 { "" } else { "s" }
    );
    let _ = writeln!(
        s,
        "  {} {} {} {}",
        cell("AP", num(f.ap)),
        cell("APx", signed(f.ap_xyz[0], 4)),
        cell("APy", signed(f.ap_xyz[1], 4)),
        cell("APz", signed(f.ap_xyz[2], 4))
    );
    if let (Some(rp), Some(l_mean), Some(s_l)) = (f.rp, f.l_mean, f.s_l) {
        let _ = writeln!(
            s,
            "  {} {} {}",
            cell("RP", num(rp)),
            cell("lbar", num(l_mean)),
            cell("S_l", num(s_l))
        );
    } else {
        let _ = writeln!(s, "  RP   n/a (1 cycle)");
    }
    if let Some(ap) = f.ap_abc {
        let _ = writeln!(
            s,
            "  {} {} {}",
            cell("APa", signed(ap[0], 4)),
            cell("APb", signed(ap[1], 4)),
            cell("APc", signed(ap[2], 4))
        );
    }
    if let Some(rp) = f.rp_abc {
        let _ = writeln!(
            s,
            "  {} {} {}",
            cell("RPa", format!("+-{}", num(rp[0]))),
            cell("RPb", format!("+-{}", num(rp[1]))),
            cell("RPc", format!("+-{}", num(rp[2])))
        );
    }
    if let Some(m) = &f.multidirectional {
        let mut line = format!(
            "  {} from {} directions ({})",
            cell("vAP", num(m.vap)),
            m.directions.len(),
            m.directions.join(", ")
        );
        if let Some(v) = m.vap_abc {
            line += &format!(
                "; vAPa {}, vAPb {}, vAPc {}",
                num(v[0]),
                num(v[1]),
                num(v[2])
            );
        }
        let _ = writeln!(s, "{line}");
    }
    if let Some(c) = &f.compensated {
        let _ = writeln!(
            s,
            "  compensated (predicted): AP RMS {}, 95 % bound {} (readings from the {})",
            num(c.ap_rms),
            num(c.ap_95),
            c.readings_from
        );
    }
    s
}

/// The distance accuracy and repeatability between pairs of poses.
fn distances_text(e: &Evaluation) -> String {
    use std::fmt::Write as _;
    if e.distances.is_empty() {
        return String::new();
    }
    let mut s = String::new();
    let _ = writeln!(
        s,
        "\ndistances  {:>6} {:>12} {:>12} {:>12} {:>12}",
        "cycles", "Dc", "Dbar", "AD", "RD (+-)"
    );
    for d in &e.distances {
        let _ = writeln!(
            s,
            "{:<10} {:>6} {:>12} {:>12} {:>12} {:>12}",
            format!("{}-{}", pose_name(d.from), pose_name(d.to)),
            d.cycles,
            num(d.commanded),
            num(d.mean),
            signed(d.ad, 4),
            d.rd.map_or_else(|| "n/a".to_string(), num)
        );
    }
    s
}
