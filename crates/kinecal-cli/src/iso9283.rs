//! `kinecal iso9283`: the ISO 9283 test poses of a robot, simulated logs, and the pose figures of
//! a log (the arithmetic is the library's `kinecal::iso9283`).

use std::path::Path;

use anyhow::{anyhow, bail, Result};
use kinecal::identifiability::fmt_sig;
use kinecal::iso9283::{
    evaluate, log_placed, plan, pose_name, predict_compensated, read_log, read_plan, read_roles,
    simulate, write_log, write_plan, Cube, Evaluation, LogUnits, PlacedLog, PlanRequest,
    SimulateRequest, Spread,
};
use kinecal::source::Source;
use kinecal::units::Quantity;

use crate::args::{
    Iso9283Command, Iso9283EvaluateArgs, Iso9283LogArgs, Iso9283PlanArgs, Iso9283SimulateArgs,
};
use crate::{load_robot, output, parse_spec, spec_value};

/// Runs an `iso9283` command.
pub fn run(c: Iso9283Command) -> Result<()> {
    match c {
        Iso9283Command::Plan(a) => run_plan(a),
        Iso9283Command::Simulate(a) => run_simulate(a),
        Iso9283Command::Evaluate(a) => run_evaluate(a),
        Iso9283Command::Log(a) => run_log(a),
    }
}

/// `N` comma-separated finite numbers for `option`.
fn numbers<const N: usize>(option: &str, s: &str, what: &str) -> Result<[f64; N]> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    if parts.len() != N {
        bail!("{option} `{s}`: expected {what}");
    }
    let mut out = [0.0; N];
    for (o, p) in out.iter_mut().zip(&parts) {
        *o = p
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| anyhow!("{option} `{s}`: `{p}` is not a finite number"))?;
    }
    Ok(out)
}

/// A number as a person reads it: four significant digits, plain decimals from 0.001 to 1e9
/// (an exponent outside: `6.493e-5`, so columns stay narrow).
fn sig(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    if !v.is_finite() {
        return "n/a".into();
    }
    let e = v.abs().log10().floor() as i32;
    if !(-3..9).contains(&e) {
        return format!("{v:.3e}");
    }
    let decimals = (3 - e).max(0) as usize;
    format!("{v:.decimals$}")
}

/// [`sig`] with a sign.
fn signed(v: f64) -> String {
    if v > 0.0 {
        format!("+{}", sig(v))
    } else {
        sig(v)
    }
}

fn run_plan(a: Iso9283PlanArgs) -> Result<()> {
    if let Some(out) = &a.out {
        output::check_distinct(&[out], &[Path::new(&a.robot)])?;
    }
    let robot = load_robot(&a.robot)?.robot;
    let u = robot.units;
    let (len, ang) = (u.length, u.angle);
    let cube = a
        .cube
        .as_deref()
        .map(|s| -> Result<Cube> {
            let [x, y, z, side] = numbers::<4>("--cube", s, "CX,CY,CZ,SIDE: four numbers")?;
            if side <= 0.0 {
                bail!("--cube `{s}`: the side must be positive");
            }
            Ok(Cube {
                centre: [x, y, z].map(|v| u.to_si(Quantity::Length, v)),
                side: u.to_si(Quantity::Length, side),
            })
        })
        .transpose()?;
    let attitude = a
        .attitude
        .as_deref()
        .map(|s| numbers::<3>("--attitude", s, "A,B,C: three angles"))
        .transpose()?
        .map(|v| v.map(|x| u.to_si(Quantity::Angle, x)));
    if a.resolution < 3 {
        bail!("--resolution must be at least 3");
    }
    let p = plan(
        &robot,
        &PlanRequest {
            cube,
            attitude,
            resolution: a.resolution,
        },
    )?;
    let l = |v: f64| sig(u.from_si(Quantity::Length, v));
    let c = p.cube;
    println!(
        "cube: centre ({}, {}, {}) {len}, side {} {len}",
        l(c.centre[0]),
        l(c.centre[1]),
        l(c.centre[2]),
        l(c.side)
    );
    match &p.search {
        Some(s) => println!(
            "searched: {} grid points tested (step {} {len}), {} reached; the cube's test poses and \
             its 8 corners are reached inside the joint ranges (a search, not a proof of the largest \
             cube)",
            s.tested,
            l(s.step),
            s.reached
        ),
        None => println!("given: its test poses are reached inside the joint ranges"),
    }
    let mut header = format!("pose  {:>10} {:>10} {:>10}", "x", "y", "z");
    if p.attitude.is_some() {
        header += &format!(" {:>9} {:>9} {:>9}", "a", "b", "c");
    }
    header += "  readings";
    println!("{header}");
    for t in &p.poses {
        let mut line = format!(
            "P{}    {:>10} {:>10} {:>10}",
            t.pose,
            l(t.position[0]),
            l(t.position[1]),
            l(t.position[2])
        );
        if let Some(att) = t.attitude {
            for v in att {
                line += &format!(" {:>9}", sig(u.from_si(Quantity::Angle, v)));
            }
        }
        line += "  ";
        line += &t
            .readings
            .iter()
            .map(|&v| fmt_sig(v))
            .collect::<Vec<_>>()
            .join(",");
        println!("{line}");
    }
    println!(
        "each cycle visits P1, P5, P4, P3, P2; ISO 9283 asks for 30 cycles (lengths in {len}, angles \
         in {ang})"
    );
    if let Some(out) = &a.out {
        output::write_file(out, &write_plan(&robot, &p))?;
        eprintln!("wrote the test poses to {}", out.display());
    }
    Ok(())
}

fn run_simulate(a: Iso9283SimulateArgs) -> Result<()> {
    output::check_distinct(&[&a.out], &[Path::new(&a.robot), &a.poses])?;
    let robot = load_robot(&a.robot)?.robot;
    let u = robot.units;
    let s = Source::read(&a.poses)?;
    let poses = read_plan(&s.text, &s.name, &robot)?;
    if a.cycles == 0 {
        bail!("--cycles must be at least 1");
    }
    let (mut length, mut angle) = (0.0, 0.0);
    if let Some(spec) = &a.noise {
        let s = parse_spec("--noise", spec, &["length", "angle"])?;
        length = u.to_si(Quantity::Length, spec_value(&s, "length").unwrap_or(0.0));
        angle = u.to_si(Quantity::Angle, spec_value(&s, "angle").unwrap_or(0.0));
    }
    let log = simulate(
        &robot,
        &poses,
        &SimulateRequest {
            cycles: a.cycles,
            length_noise: length,
            angle_noise: angle,
            seed: a.seed,
        },
    )?;
    output::write_file(&a.out, &write_log(&log))?;
    eprintln!(
        "wrote a simulated log (not a measurement) of {} cycles at {} poses ({} rows) to {}",
        a.cycles,
        poses.len(),
        log.rows.len(),
        a.out.display()
    );
    Ok(())
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
            sig(v.mean),
            sig(v.p95),
            sig(v.max)
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
                    sig(rms.mean),
                    sig(b.mean),
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

/// The figures of one test as text: a table per pose, then the distances.
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
    let cell = |name: &str, v: String| format!("{name:<4} {v:<12}");
    for f in &e.poses {
        let _ = writeln!(s);
        let mut commanded = format!(
            "x {}, y {}, z {}",
            sig(f.commanded[0]),
            sig(f.commanded[1]),
            sig(f.commanded[2])
        );
        if let Some(c) = f.commanded_attitude {
            commanded += &format!("; a {}, b {}, c {}", sig(c[0]), sig(c[1]), sig(c[2]));
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
            cell("AP", sig(f.ap)),
            cell("APx", signed(f.ap_xyz[0])),
            cell("APy", signed(f.ap_xyz[1])),
            cell("APz", signed(f.ap_xyz[2]))
        );
        if let (Some(rp), Some(l_mean), Some(s_l)) = (f.rp, f.l_mean, f.s_l) {
            let _ = writeln!(
                s,
                "  {} {} {}",
                cell("RP", sig(rp)),
                cell("lbar", sig(l_mean)),
                cell("S_l", sig(s_l))
            );
        } else {
            let _ = writeln!(s, "  RP   n/a (1 cycle)");
        }
        if let Some(ap) = f.ap_abc {
            let _ = writeln!(
                s,
                "  {} {} {}",
                cell("APa", signed(ap[0])),
                cell("APb", signed(ap[1])),
                cell("APc", signed(ap[2]))
            );
        }
        if let Some(rp) = f.rp_abc {
            let _ = writeln!(
                s,
                "  {} {} {}",
                cell("RPa", format!("+-{}", sig(rp[0]))),
                cell("RPb", format!("+-{}", sig(rp[1]))),
                cell("RPc", format!("+-{}", sig(rp[2])))
            );
        }
        if let Some(m) = &f.multidirectional {
            let mut line = format!(
                "  {} from {} directions ({})",
                cell("vAP", sig(m.vap)),
                m.directions.len(),
                m.directions.join(", ")
            );
            if let Some(v) = m.vap_abc {
                line += &format!(
                    "; vAPa {}, vAPb {}, vAPc {}",
                    sig(v[0]),
                    sig(v[1]),
                    sig(v[2])
                );
            }
            let _ = writeln!(s, "{line}");
        }
        if let Some(c) = &f.compensated {
            let _ = writeln!(
                s,
                "  compensated (predicted): AP RMS {}, 95 % bound {} (readings from the {})",
                sig(c.ap_rms),
                sig(c.ap_95),
                c.readings_from
            );
        }
    }
    if !e.distances.is_empty() {
        let _ = writeln!(s);
        let _ = writeln!(
            s,
            "distances  {:>6} {:>12} {:>12} {:>12} {:>12}",
            "cycles", "Dc", "Dbar", "AD", "RD (+-)"
        );
        for d in &e.distances {
            let _ = writeln!(
                s,
                "{:<10} {:>6} {:>12} {:>12} {:>12} {:>12}",
                format!("{}-{}", pose_name(d.from), pose_name(d.to)),
                d.cycles,
                sig(d.commanded),
                sig(d.mean),
                signed(d.ad),
                d.rd.map_or_else(|| "n/a".to_string(), sig)
            );
        }
    }
    // No padding left at the ends of lines.
    s.lines().map(str::trim_end).collect::<Vec<_>>().join("\n") + "\n"
}

fn run_evaluate(a: Iso9283EvaluateArgs) -> Result<()> {
    let outputs: Vec<&Path> = a
        .json
        .iter()
        .chain(a.html.iter())
        .map(|p| p.as_path())
        .collect();
    let mut inputs: Vec<&Path> = vec![&a.data];
    inputs.extend(a.report.as_deref());
    inputs.extend(a.robot.as_deref().map(Path::new));
    output::check_distinct(&outputs, &inputs)?;
    let units = LogUnits {
        length: a
            .length_unit
            .as_deref()
            .map(str::parse)
            .transpose()
            .map_err(|e: String| anyhow!("--length-unit: {e}"))?,
        angle: a
            .angle_unit
            .as_deref()
            .map(str::parse)
            .transpose()
            .map_err(|e: String| anyhow!("--angle-unit: {e}"))?,
    };
    let s = Source::read(&a.data)?;
    let log = read_log(&s.text, &s.name, units)?;
    let mut e = evaluate(&log)?;
    if let (Some(robot), Some(report)) = (&a.robot, &a.report) {
        let (loaded, _, pr, target) =
            crate::predict::calibrated(robot, report, a.target.as_deref())?;
        let predictor = kinecal::predict::from_report(&loaded.robot, &pr)
            .map_err(|e| anyhow!("{}: {e}", report.display()))?;
        let target = crate::target_named(&loaded.robot, &target, "--target")?;
        predict_compensated(&mut e, &log, &predictor, target)?;
    }
    print!("{}", text(&e));
    for w in &e.warnings {
        eprintln!("warning: {w}");
    }
    let mut staged = output::Staged::new();
    if let Some(path) = &a.json {
        let mut json = serde_json::to_string_pretty(&e)?;
        json.push('\n');
        staged.text(path, &json)?;
    }
    if let Some(path) = &a.html {
        staged.text(path, &kinecal_report::iso9283::html_iso9283(&e))?;
    }
    staged.commit()?;
    for p in outputs {
        eprintln!("wrote {}", p.display());
    }
    Ok(())
}

fn run_log(a: Iso9283LogArgs) -> Result<()> {
    output::check_distinct(&[&a.out], &[Path::new(&a.robot), &a.data, &a.roles])?;
    let robot = load_robot(&a.robot)?.robot;
    let d = Source::read(&a.data)?;
    let data = kinecal::files::parse_measurements(&d.text, &d.name, &robot)?;
    let r = Source::read(&a.roles)?;
    let roles = read_roles(&r.text, &r.name)?;
    let PlacedLog {
        mut log,
        left_out,
        placed: missing,
    } = log_placed(&robot, &data, &roles)?;
    if let Some(u) = &a.length_unit {
        let u = u
            .parse()
            .map_err(|e: String| anyhow!("--length-unit: {e}"))?;
        log = log.with_length_unit(u)?;
    }
    let tests = {
        let mut t: Vec<&str> = log.rows.iter().filter_map(|r| r.test.as_deref()).collect();
        t.sort_unstable();
        t.dedup();
        t.len()
    };
    if !missing.is_empty() {
        eprintln!(
            "placed the measurement frame of session{} {} on {} (6 parameters{}, the robot held)",
            if missing.len() == 1 { "" } else { "s" },
            missing.join(", "),
            d.name,
            if missing.len() == 1 { "" } else { " each" }
        );
    }
    if !left_out.is_empty() {
        eprintln!(
            "left out {} measured posture{} without a role in {} ({})",
            left_out.len(),
            if left_out.len() == 1 { "" } else { "s" },
            r.name,
            left_out
                .iter()
                .take(5)
                .cloned()
                .collect::<Vec<_>>()
                .join(", ")
                + if left_out.len() > 5 { ", ..." } else { "" }
        );
    }
    output::write_file(&a.out, &write_log(&log))?;
    eprintln!(
        "wrote the ISO 9283 log of {} rows ({tests} test{}; commanded: {}'s model at the readings; \
         attained: measured, in its base frame) to {}",
        log.rows.len(),
        if tests == 1 { "" } else { "s" },
        a.robot,
        a.out.display()
    );
    Ok(())
}
