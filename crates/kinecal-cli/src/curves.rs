//! `kinecal curves ...` and `kinecal report`.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{anyhow, bail, Result};
use kinecal::curves::{is_convex, local_minima, objective_curve, period, pose_curve};
use kinecal::files::parse_postures;
use kinecal::kinematics::Target;
use kinecal::report::CalibrationReport;
use kinecal::{parse_param_list, ParamId, Robot};
use kinecal_report::{render_png, render_svg, Line, Panel};

use crate::args::{CurvesCommand, CurvesObjectiveArgs, CurvesPoseArgs, ReportArgs, SweepArgs};
use crate::{load_observations, load_robot, read_text, residual_settings, write_file};

/// Runs a curves command.
pub fn run(c: CurvesCommand) -> Result<()> {
    match c {
        CurvesCommand::Pose(a) => pose(a),
        CurvesCommand::Objective(a) => objective(a),
    }
}

fn sweep(s: &SweepArgs, robot: &Robot, id: ParamId, objective: bool) -> Result<Vec<f64>> {
    let v = robot.get_user(id);
    let (a, b) = match (s.from, s.to, s.span) {
        (Some(a), Some(b), _) => (a, b),
        (_, _, Some(w)) => (v - w / 2.0, v + w / 2.0),
        _ => {
            let half = kinecal::curves::default_half_width(robot, id, objective);
            (v - half, v + half)
        }
    };
    Ok(kinecal::curves::sweep(a, b, s.points)?)
}

enum Out {
    Svg,
    Png,
    Csv,
}

fn out_kind(path: &Path) -> Result<Out> {
    match path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .as_deref()
    {
        Some("svg") => Ok(Out::Svg),
        Some("png") => Ok(Out::Png),
        Some("csv") => Ok(Out::Csv),
        _ => bail!(
            "--out {}: the name must end in .svg, .png or .csv",
            path.display()
        ),
    }
}

fn draw(path: &Path, panels: &[Panel], cols: usize) -> Result<()> {
    match out_kind(path)? {
        Out::Svg => write_file(path, &render_svg(panels, cols)?),
        Out::Png => {
            let mut staged = crate::output::Staged::new();
            staged.by_path(path, |tmp| Ok(render_png(panels, cols, tmp)?))?;
            staged.commit()
        }
        Out::Csv => unreachable!("CSV is written by the caller"),
    }
}

fn pose(a: CurvesPoseArgs) -> Result<()> {
    let r = load_robot(&a.robot)?;
    let robot = &r.robot;
    let readings: Vec<f64> = match (&a.readings, &a.postures, &a.posture) {
        (Some(list), _, _) => list
            .split(',')
            .map(|v| {
                v.trim()
                    .parse::<f64>()
                    .ok()
                    .filter(|x| x.is_finite())
                    .ok_or_else(|| anyhow!("--readings: `{}` is not a number", v.trim()))
            })
            .collect::<Result<_>>()?,
        (None, Some(path), Some(label)) => {
            let ps = parse_postures(&read_text(path)?, &path.display().to_string(), robot)?;
            ps.into_iter()
                .find(|p| &p.label == label)
                .ok_or_else(|| anyhow!("{}: no posture `{label}`", path.display()))?
                .readings
        }
        _ => bail!("give --readings, or --postures with --posture"),
    };
    if readings.len() != robot.dof() {
        bail!(
            "--readings: {} values for a robot with {} joints",
            readings.len(),
            robot.dof()
        );
    }
    let target = match a.site.as_str() {
        "ee" => Target::EndEffector,
        name => Target::Site(
            robot
                .site_index(name)
                .ok_or_else(|| anyhow!("--site: the robot has no site `{name}`"))?,
        ),
    };
    let ids = parse_param_list(&a.sweep.param, robot)?;
    let (l, an) = (
        robot.units.length.to_string(),
        robot.units.angle.to_string(),
    );
    let mut panels = Vec::new();
    let mut csv = String::from("param,value,x,y,z,alpha,beta,gamma\n");
    for &id in &ids {
        let x = sweep(&a.sweep, robot, id, false)?;
        let c = pose_curve(robot, &readings, target, id, &x);
        let name = robot.param_name(id);
        let unit = robot.param_unit(id);
        for (v, row) in x.iter().zip(&c) {
            let _ = writeln!(
                csv,
                "{id},{v},{},{},{},{},{},{}",
                row[0], row[1], row[2], row[3], row[4], row[5]
            );
        }
        let col = |k: usize| c.iter().map(|r| r[k]).collect::<Vec<_>>();
        let mark = Some(robot.get_user(id));
        panels.push(Panel {
            title: format!("{id} ({name}): position"),
            x_label: format!("{name} ({unit})"),
            y_label: format!("position ({l})"),
            x: x.clone(),
            lines: vec![
                Line::new("x", col(0)),
                Line::new("y", col(1)),
                Line::new("z", col(2)),
            ],
            mark_x: mark,
            ..Default::default()
        });
        panels.push(Panel {
            title: format!("{id} ({name}): attitude (unwrapped)"),
            x_label: format!("{name} ({unit})"),
            y_label: format!("ZYX Euler angle ({an})"),
            x,
            lines: vec![
                Line::new("alpha", col(3)),
                Line::new("beta", col(4)),
                Line::new("gamma", col(5)),
            ],
            mark_x: mark,
            ..Default::default()
        });
        match period(robot, id, Some(&readings)) {
            Some(t) => println!("{id} ({name}): periodic, period {t:.6} {unit}"),
            None => println!("{id} ({name}): not periodic"),
        }
    }
    match out_kind(&a.sweep.out)? {
        Out::Csv => write_file(&a.sweep.out, &csv)?,
        _ => draw(&a.sweep.out, &panels, 2)?,
    }
    eprintln!("wrote {}", a.sweep.out.display());
    Ok(())
}

fn objective(a: CurvesObjectiveArgs) -> Result<()> {
    let mut inputs: Vec<&Path> = a
        .observations
        .files
        .iter()
        .map(|(_, p)| p.as_path())
        .collect();
    inputs.push(Path::new(&a.robot));
    crate::output::check_distinct(&[&a.sweep.out], &inputs)?;
    let r = load_robot(&a.robot)?;
    let robot = &r.robot;
    let (data, _) = load_observations(&a.observations, robot)?;
    let (weights, orientation) = residual_settings(&a.residuals, robot)?;
    let ids = parse_param_list(&a.sweep.param, robot)?;
    let mut panels = Vec::new();
    let mut csv = String::from("param,value,objective\n");
    let single = (data.postures.len() == 1).then(|| data.postures[0].readings.clone());
    for &id in &ids {
        let x = sweep(&a.sweep, robot, id, true)?;
        let f = objective_curve(robot, &data, id, &x, weights, orientation);
        let name = robot.param_name(id);
        let unit = robot.param_unit(id);
        for (v, o) in x.iter().zip(&f) {
            let _ = writeln!(csv, "{id},{v},{o}");
        }
        let minima = local_minima(&x, &f);
        println!("{id} ({name}), {} .. {} {unit}:", x[0], x[x.len() - 1]);
        if minima.is_empty() {
            println!("  no interior local minimum (the minimum is at an end of the span)");
        }
        for (v, o) in &minima {
            println!("  local minimum at {v:.6} {unit}: objective {o:.6e}");
        }
        if !is_convex(&f) {
            println!(
                "  warning: the objective is not convex over this span ({} valleys): a solver started here could stop in a false valley",
                minima.len()
            );
        }
        match period(robot, id, single.as_deref()) {
            Some(t) => println!("  periodic: period {t:.6} {unit}"),
            None if matches!(robot.param_kind(id), kinecal::ParamKind::Slope { .. })
                && robot.joints[slope_joint(robot, id)].kind == kinecal::JointKind::Revolute =>
            {
                let periods: Vec<String> = data
                    .postures
                    .iter()
                    .filter_map(|p| {
                        period(robot, id, Some(&p.readings)).map(|t| format!("{}: {t:.3}", p.label))
                    })
                    .take(8)
                    .collect();
                println!(
                    "  each posture alone repeats every 360/V {unit} ({}{})",
                    periods.join(", "),
                    if data.postures.len() > 8 { ", ..." } else { "" }
                );
            }
            None => {}
        }
        panels.push(Panel {
            title: format!("Objective against {id} ({name})"),
            x_label: format!("{name} ({unit})"),
            y_label: "objective (weighted sum of squares)".into(),
            x,
            lines: vec![Line::new("objective", f)],
            mark_x: Some(robot.get_user(id)),
            ..Default::default()
        });
    }
    match out_kind(&a.sweep.out)? {
        Out::Csv => write_file(&a.sweep.out, &csv)?,
        _ => draw(&a.sweep.out, &panels, 1)?,
    }
    eprintln!("wrote {}", a.sweep.out.display());
    Ok(())
}

fn slope_joint(robot: &Robot, id: ParamId) -> usize {
    match robot.param_kind(id) {
        kinecal::ParamKind::Slope { joint } | kinecal::ParamKind::Offset { joint } => joint,
        _ => 0,
    }
}

/// `kinecal report`.
pub fn report(a: ReportArgs) -> Result<()> {
    if let Some(from) = &a.from {
        crate::output::check_distinct(&[&a.out], &[from])?;
        let rep = CalibrationReport::from_json(&read_text(from)?)
            .map_err(|e| anyhow!("{}: not a kinecal calibration report: {e}", from.display()))?;
        write_file(&a.out, &kinecal_report::html_report(&rep)?)?;
        eprintln!("wrote {}", a.out.display());
        return Ok(());
    }
    let Some(robot) = &a.robot else {
        bail!("give --robot with the data, or --from a report");
    };
    let mut inputs: Vec<&Path> = a
        .observations
        .files
        .iter()
        .map(|(_, p)| p.as_path())
        .collect();
    inputs.push(Path::new(robot));
    inputs.extend(a.calibration.as_deref());
    if let Some(c) = &a.calibrated {
        inputs.push(Path::new(c));
    }
    crate::output::check_distinct(&[&a.out], &inputs)?;
    let r = load_robot(robot)?;
    let nominal = &r.robot;
    let (data, sources) = load_observations(&a.observations, nominal)?;
    let (weights, orientation) = residual_settings(&a.residuals, nominal)?;
    let calibrated = match (&a.calibrated, &a.calibration) {
        (Some(spec), _) => load_robot(spec)?.robot,
        (None, Some(path)) => {
            let rep = CalibrationReport::from_json(&read_text(path)?).map_err(|e| {
                anyhow!("{}: not a kinecal calibration report: {e}", path.display())
            })?;
            if rep.parameters.len() != nominal.param_count() {
                bail!(
                    "{}: the report has {} parameters, the robot {}",
                    path.display(),
                    rep.parameters.len(),
                    nominal.param_count()
                );
            }
            let mut c = nominal.clone();
            for (id, p) in nominal.param_ids().zip(&rep.parameters) {
                c.set(
                    id,
                    nominal.units.to_si(nominal.param_quantity(id), p.estimated),
                );
            }
            c
        }
        _ => bail!("give --calibrated or --calibration"),
    };
    let sources: Vec<_> = std::iter::once(r.source.clone()).chain(sources).collect();
    let mut outcome =
        kinecal::workflow::assess(nominal, &calibrated, &data, weights, orientation, &sources)?;
    // The predicted accuracy and its map, as `calibrate --html` gives them.
    kinecal::workflow::add_prediction(&mut outcome, nominal, kinecal::predict::Level::Map);
    write_file(&a.out, &kinecal_report::html_report(&outcome.report)?)?;
    eprintln!("wrote {}", a.out.display());
    Ok(())
}
