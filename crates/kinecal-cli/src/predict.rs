//! `kinecal predict`: the predicted accuracy of a calibrated robot at postures (a thin layer
//! over `kinecal::predict`).

use std::path::Path;

use anyhow::{anyhow, bail, Result};
use kinecal::kinematics::Target;
use kinecal::predict;
use kinecal::report::CalibrationReport;
use kinecal::source::Source;

use crate::args::PredictArgs;
use crate::output;

/// Runs `kinecal predict`.
pub fn run(a: PredictArgs) -> Result<()> {
    let outputs: Vec<&Path> = a
        .out
        .iter()
        .chain(a.html.iter())
        .map(|p| p.as_path())
        .collect();
    let mut inputs: Vec<&Path> = vec![a.report.as_path(), Path::new(&a.robot)];
    inputs.extend(a.postures.as_deref());
    inputs.extend(a.targets.as_deref());
    output::check_distinct(&outputs, &inputs)?;
    let (loaded, report, pr, target_name) = calibrated(&a.robot, &a.report, a.target.as_deref())?;
    let robot = &loaded.robot;
    let predictor =
        predict::from_report(robot, &pr).map_err(|e| anyhow!("{}: {e}", a.report.display()))?;
    let target = crate::target_named(robot, &target_name, "--target")?;
    let pr = &pr;
    let postures: Vec<(String, Vec<f64>)> = match (&a.postures, a.sample) {
        (Some(path), _) => {
            let s = Source::read(path)?;
            kinecal::files::parse_postures(&s.text, &s.name, robot)?
                .into_iter()
                .map(|p| (p.label, p.readings))
                .collect()
        }
        (None, Some(n)) => {
            if n == 0 || n > 10_000_000 {
                bail!("--sample {n}: expected between 1 and 10,000,000 postures");
            }
            predict::sample_readings(robot, n, a.seed)
                .chunks(robot.dof())
                .enumerate()
                .map(|(i, r)| ((i + 1).to_string(), r.to_vec()))
                .collect()
        }
        (None, None) => match &a.targets {
            Some(path) => reach_targets(robot, path, target)?,
            None => bail!("give --postures, --sample or --targets"),
        },
    };
    let attitude = pr.attitude.is_some();
    let mut csv = predict::csv_header(robot, attitude);
    csv.push('\n');
    let mut s = predictor.scratch();
    let mut bounds = Vec::with_capacity(postures.len());
    for (label, readings) in &postures {
        let p = predictor.predict(readings, target, &mut s);
        bounds.push(p.position_error.bound);
        predict::csv_row(robot, label, readings, &p, &mut csv);
    }
    let mut staged = output::Staged::new();
    match &a.out {
        Some(path) => staged.text(path, &csv)?,
        None => print!("{csv}"),
    }
    if let Some(path) = &a.html {
        let measured: Vec<&[f64]> = pr.measured.iter().map(Vec::as_slice).collect();
        let map =
            predict::accuracy_map(&predictor, target, &measured, predict::MAP_SAMPLES, a.seed);
        let mut with_map = pr.clone();
        with_map.map = Some(map);
        staged.text(
            path,
            &kinecal_report::predict::page(
                &with_map,
                &report.robot,
                report.length_unit.as_str(),
                report.angle_unit.as_str(),
            ),
        )?;
    }
    staged.commit()?;
    bounds.sort_by(f64::total_cmp);
    let pick = |q: f64| {
        let rank = ((q * bounds.len() as f64).ceil() as usize).clamp(1, bounds.len());
        robot
            .units
            .from_si(kinecal::units::Quantity::Length, bounds[rank - 1])
    };
    eprintln!(
        "predicted {} postures of {} ({}): 95 % position bound median {}, 95th percentile {}, \
         largest {} {}",
        postures.len(),
        report.robot,
        target_name,
        crate::report::num(pick(0.5)),
        crate::report::num(pick(0.95)),
        crate::report::num(pick(1.0)),
        robot.units.length
    );
    for (path, what) in [(&a.out, "the predictions"), (&a.html, "the accuracy map")] {
        if let Some(p) = path {
            eprintln!("wrote {what} to {}", p.display());
        }
    }
    Ok(())
}

/// The calibrated robot `robot` (a file or built-in name) and the prediction of its calibration
/// report `report`, checked to be that robot's, and the target to predict (`target`, or the
/// report's). An error when the report has no prediction or is another robot's.
pub fn calibrated(
    robot: &str,
    report: &Path,
    target: Option<&str>,
) -> Result<(
    crate::LoadedRobot,
    CalibrationReport,
    predict::PredictionReport,
    String,
)> {
    let loaded = crate::load_robot(robot)?;
    let source = Source::read(report)?;
    let parsed = CalibrationReport::from_json(&source.text)
        .map_err(|e| anyhow!("{}: not a calibration report: {e}", source.name))?;
    let Some(pr) = parsed.prediction.clone() else {
        bail!(
            "{}: the report has no prediction (its calibration was not asked for one, had fewer \
             than {} postures measured by position or pose, or its kinecal made none): calibrate \
             again with --predict",
            source.name,
            predict::MIN_POSTURES
        );
    };
    // The robot must be the report's calibrated robot.
    parsed
        .check_calibrated(&loaded.robot, robot)
        .map_err(|e| anyhow!("{}: {e}", source.name))?;
    let target = target.unwrap_or(&pr.target).to_string();
    Ok((loaded, parsed, pr, target))
}

/// The readings that reach each Cartesian goal of `path` (`target,x,y,z[,alpha,beta,gamma]`,
/// `robot`'s file units and global frame) through `robot`'s inverse kinematics, labelled by
/// the goals' names. A goal out of reach or outside a joint range is an error naming its line.
fn reach_targets(
    robot: &kinecal::Robot,
    path: &Path,
    target: Target,
) -> Result<Vec<(String, Vec<f64>)>> {
    use kinecal::compensate::{goal_in_file_units, Options, TargetSearch};
    let mut rows = crate::stream::Rows::open(path)?;
    let expected = "target,x,y,z[,alpha,beta,gamma]";
    let col = |rows: &crate::stream::Rows, name: &str| {
        rows.column(name).ok_or_else(|| {
            anyhow!(
                "{}:1: no column `{name}` in the header (expected {expected})",
                rows.file
            )
        })
    };
    let label = col(&rows, "target")?;
    let xyz = [col(&rows, "x")?, col(&rows, "y")?, col(&rows, "z")?];
    let euler: Option<Vec<usize>> = ["alpha", "beta", "gamma"]
        .iter()
        .map(|n| rows.column(n))
        .collect();
    if let Some(h) = rows.header.iter().find(|h| {
        !["target", "x", "y", "z", "alpha", "beta", "gamma"]
            .iter()
            .any(|k| h.eq_ignore_ascii_case(k))
    }) {
        bail!(
            "{}:1: unknown column `{h}` (expected {expected})",
            rows.file
        );
    }
    let u = robot.units;
    let mut search = TargetSearch::new(robot, robot, Options::default())
        .map_err(|e| anyhow!("{}: {e}", path.display()))?;
    let mut out = vec![0.0; robot.dof()];
    let mut reached = Vec::new();
    while let Some(line) = rows.advance()? {
        let mut p = [0.0; 3];
        for (k, &c) in xyz.iter().enumerate() {
            p[k] = crate::stream::cell(&rows, line, c)?;
        }
        let euler = match &euler {
            Some(e) if e.iter().any(|&c| !rows.field(c).is_empty()) => {
                let mut r = [0.0; 3];
                for (k, &c) in e.iter().enumerate() {
                    r[k] = crate::stream::cell(&rows, line, c)?;
                }
                Some(r)
            }
            _ => None,
        };
        let goal = goal_in_file_units(robot, p, euler).map_err(|p| {
            crate::goal_problem(
                &p,
                &format!("{}:{line}", rows.file),
                &format!("target `{}`", rows.field(label)),
            )
        })?;
        let s = search.solve(&goal, target, None, &mut out);
        let name = rows.field(label).to_string();
        if s.flags.unreachable || s.flags.out_of_range != 0 {
            bail!(
                "{}:{line}: target `{name}`: the calibrated robot does not reach it ({}): is it \
                 in the robot's global frame and length unit ({})?",
                rows.file,
                s.flags.describe(),
                u.length
            );
        }
        if s.flags.singular {
            eprintln!(
                "warning: {}:{line}: target `{name}` is reached near a singularity",
                rows.file
            );
        }
        reached.push((name, out.clone()));
    }
    if reached.is_empty() {
        bail!(
            "{}: no targets: the file has a header but no rows",
            rows.file
        );
    }
    Ok(reached)
}
