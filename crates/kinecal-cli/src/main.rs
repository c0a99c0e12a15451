//! The `kinecal` command: a thin layer over the `kinecal` library.

mod analyze;
mod args;
mod curves;
mod demo;
mod history;
mod report;

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{anyhow, bail, Context, Result};
use clap::Parser;

use args::{
    CalibrateArgs, Cli, Command, ConventionArg, DampingArg, ExportCommand, ExportUrdfArgs, FkArgs,
    ImportCommand, LossArg, MethodArg, OrientationArg, ResidualArgs, SimulateArgs, SolutionArg,
};
use kinecal::estimation::{
    self, CalibrationOptions, Damping, Method, OrientationError, SolutionRule, SolverOptions,
    Weights,
};
use kinecal::identifiability::{analyze, AnalysisOptions};
use kinecal::measurement_file::{parse_measurements, parse_postures, write_measurements};
use kinecal::robot_file::{parse_robot_toml, write_robot_toml};
use kinecal::simulate::{self, PerturbStd};
use kinecal::units::Quantity;
use kinecal::{examples, parse_param_list, Robot};

/// Exit code for errors in the input (files, parameter lists, unsolvable problems).
const EXIT_INPUT: u8 = 1;

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Demo => demo::run().map(|()| 0),
        Command::Fk(a) => fk(a).map(|()| 0),
        Command::Simulate(a) => simulate(a).map(|()| 0),
        Command::Calibrate(a) => calibrate(a).map(|()| 0),
        Command::Analyze(a) => analyze::run(a).map(|()| 0),
        Command::Import(c) => import(c).map(|()| 0),
        Command::Export(ExportCommand::Urdf(a)) => export_urdf(a).map(|()| 0),
        Command::History(c) => history::run(c),
        Command::Check(a) => history::check(a),
        Command::Curves(c) => curves::run(c).map(|()| 0),
        Command::Report(a) => curves::report(a).map(|()| 0),
    };
    match result {
        Ok(code) => ExitCode::from(code),
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(EXIT_INPUT)
        }
    }
}

/// A robot as loaded: the model, the text it came from, and how to name it.
struct LoadedRobot {
    robot: Robot,
    text: String,
}

fn read_text(path: &Path) -> Result<String> {
    std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))
}

fn load_robot(spec: &str) -> Result<LoadedRobot> {
    let path = Path::new(spec);
    let (text, name) = if path.exists() {
        (read_text(path)?, spec.to_string())
    } else if let Some(text) = examples::builtin(spec) {
        (text.to_string(), format!("<built-in {spec}>"))
    } else {
        bail!(
            "{spec}: no such robot file, and not a built-in robot (built-in: {})",
            examples::BUILTIN_NAMES.join(", ")
        );
    };
    let robot = parse_robot_toml(&text, &name)?;
    Ok(LoadedRobot { robot, text })
}

/// Writes `contents` to `path` atomically: a temporary file in the same directory, then a rename,
/// so an interrupted run never leaves a half-written file in place of a good one.
fn write_file(path: &Path, contents: &str) -> Result<()> {
    let dir = path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = path
        .file_name()
        .ok_or_else(|| anyhow!("{}: not a file path", path.display()))?;
    let tmp: PathBuf = dir.join(format!(".{}.kinecal-tmp", name.to_string_lossy()));
    std::fs::write(&tmp, contents).with_context(|| format!("cannot write {}", tmp.display()))?;
    std::fs::rename(&tmp, path).with_context(|| {
        let _ = std::fs::remove_file(&tmp);
        format!("cannot write {}", path.display())
    })
}

/// Parses `key=value,...` with numbers, allowing only `keys`.
fn parse_spec(option: &str, spec: &str, keys: &[&str]) -> Result<Vec<(String, f64)>> {
    let mut out = Vec::new();
    for part in spec.split(',').map(str::trim) {
        let (k, v) = part.split_once('=').ok_or_else(|| {
            anyhow!(
                "{option} `{spec}`: expected key=value pairs ({})",
                keys.iter()
                    .map(|k| format!("{k}=..."))
                    .collect::<Vec<_>>()
                    .join(",")
            )
        })?;
        let k = k.trim();
        if !keys.contains(&k) {
            bail!(
                "{option} `{spec}`: unknown key `{k}` (expected {})",
                keys.join(", ")
            );
        }
        let v: f64 = v
            .trim()
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite())
            .ok_or_else(|| anyhow!("{option} `{spec}`: `{}` is not a finite number", v.trim()))?;
        if v < 0.0 {
            bail!("{option} `{spec}`: `{k}` must not be negative");
        }
        out.push((k.to_string(), v));
    }
    Ok(out)
}

fn spec_value(spec: &[(String, f64)], key: &str) -> Option<f64> {
    spec.iter().find(|(k, _)| k == key).map(|(_, v)| *v)
}

/// Reads a measurement file, through a `--columns` mapping when given.
fn read_measurements(
    path: &Path,
    columns: Option<&str>,
    robot: &Robot,
) -> Result<kinecal::Dataset> {
    let file = path.display().to_string();
    let mut text = read_text(path)?;
    if let Some(spec) = columns {
        let mapping = kinecal::measurement_file::parse_column_mapping(spec)?;
        text = kinecal::measurement_file::remap_columns(&text, &file, &mapping, robot)?;
    }
    Ok(parse_measurements(&text, &file, robot)?)
}

/// The residual weights and orientation error chosen on the command line.
fn residual_settings(a: &ResidualArgs, robot: &Robot) -> Result<(Weights, OrientationError)> {
    let mut weights = Weights::default();
    if let Some(spec) = &a.weights {
        let s = parse_spec("--weights", spec, &["length", "angle"])?;
        if let Some(l) = spec_value(&s, "length") {
            weights.length = robot.units.to_si(Quantity::Length, l);
        }
        if let Some(an) = spec_value(&s, "angle") {
            weights.angle = robot.units.to_si(Quantity::Angle, an);
        }
        if weights.length <= 0.0 || weights.angle <= 0.0 {
            bail!("--weights: standard deviations must be positive");
        }
    }
    let orientation = match a.orientation_error {
        OrientationArg::Euler => OrientationError::Euler,
        OrientationArg::Rotvec => OrientationError::RotVec,
    };
    Ok((weights, orientation))
}

/// Parses `--estimate` minus `--fix`. The token `identifiable` stands for the identifiable set of
/// the other tokens (of the default list when alone), computed on `data`.
fn estimate_list(
    estimate: &str,
    fix: Option<&str>,
    robot: &Robot,
    data: &kinecal::Dataset,
    aopts: &AnalysisOptions,
) -> Result<Vec<kinecal::ParamId>> {
    let tokens: Vec<&str> = estimate.split(',').map(str::trim).collect();
    let identifiable = tokens.contains(&"identifiable");
    let rest: Vec<&str> = tokens
        .iter()
        .copied()
        .filter(|t| *t != "identifiable")
        .collect();
    let mut ids = if rest.is_empty() {
        parse_param_list(&default_estimate(robot), robot)?
    } else {
        parse_param_list(&rest.join(","), robot)?
    };
    if let Some(fix) = fix {
        let fixed = parse_param_list(fix, robot)?;
        ids.retain(|id| !fixed.contains(id));
    }
    if identifiable && !ids.is_empty() {
        ids = analyze(robot, data, &ids, aopts)?.identifiable;
    }
    if ids.is_empty() {
        bail!("--estimate `{estimate}` minus --fix leaves no parameter to estimate");
    }
    Ok(ids)
}

fn import(c: ImportCommand) -> Result<()> {
    let (robot, out) = match c {
        ImportCommand::Poe(a) => {
            let file = a.file.display().to_string();
            (
                kinecal::import::poe::parse_poe_toml(&read_text(&a.file)?, &file)?,
                a.out,
            )
        }
        ImportCommand::Urdf(a) => {
            let file = a.file.display().to_string();
            let imp = kinecal::import::urdf::import_urdf(
                &read_text(&a.file)?,
                &file,
                a.base.as_deref(),
                a.tip.as_deref(),
            )?;
            (imp.robot, a.out)
        }
        ImportCommand::Dh(a) => {
            let units = kinecal::Units {
                length: a
                    .length_unit
                    .parse()
                    .map_err(|e: String| anyhow!("--length-unit: {e}"))?,
                angle: a
                    .angle_unit
                    .parse()
                    .map_err(|e: String| anyhow!("--angle-unit: {e}"))?,
            };
            let file = a.file.display().to_string();
            let rows = kinecal::import::dh::parse_dh_csv(&read_text(&a.file)?, &file, units)?;
            let convention = match a.convention {
                ConventionArg::Standard => kinecal::import::dh::Convention::Standard,
                ConventionArg::Modified => kinecal::import::dh::Convention::Modified,
            };
            (
                kinecal::import::dh::robot_from_dh(&a.name, units, &rows, convention),
                a.out,
            )
        }
    };
    write_file(&out, &write_robot_toml(&robot, None))?;
    eprintln!(
        "wrote {} ({} joints, {} parameters) to {}",
        if robot.name.is_empty() {
            "the robot"
        } else {
            &robot.name
        },
        robot.dof(),
        robot.param_count(),
        out.display()
    );
    Ok(())
}

fn export_urdf(a: ExportUrdfArgs) -> Result<()> {
    let r = load_robot(&a.robot)?;
    let file = a.template.display().to_string();
    let (text, warnings) = kinecal::import::urdf::export_urdf(
        &r.robot,
        &read_text(&a.template)?,
        &file,
        a.base.as_deref(),
        a.tip.as_deref(),
    )?;
    for w in &warnings {
        eprintln!("warning: {w}");
    }
    write_file(&a.out, &text)?;
    eprintln!("wrote the calibrated URDF to {}", a.out.display());
    Ok(())
}

/// The default parameter list: all, except the slopes when every slope is 1 in the file's units
/// (the readings are already joint values).
fn default_estimate(robot: &Robot) -> String {
    let unit_slopes = robot
        .joints
        .iter()
        .all(|j| (robot.units.from_si(j.kind.slope(), j.slope) - 1.0).abs() < 1e-12);
    if unit_slopes {
        "links,offsets,sites".to_string()
    } else {
        "all".to_string()
    }
}

fn fk(a: FkArgs) -> Result<()> {
    let r = load_robot(&a.robot)?;
    let file = a.postures.display().to_string();
    let postures = parse_postures(&read_text(&a.postures)?, &file, &r.robot)?;
    let data = simulate::measure(&r.robot, &postures, false);
    let csv = write_measurements(&r.robot, &data);
    match a.out {
        Some(path) => {
            write_file(&path, &csv)?;
            eprintln!(
                "wrote {} poses to {}",
                data.measurements.len(),
                path.display()
            );
        }
        None => print!("{csv}"),
    }
    Ok(())
}

fn simulate(a: SimulateArgs) -> Result<()> {
    let r = load_robot(&a.robot)?;
    let nominal = &r.robot;
    if a.postures == 0 {
        bail!("--postures must be at least 1");
    }
    let units = nominal.units;
    let mut truth = nominal.clone();
    if let Some(spec) = &a.perturb_std {
        let s = parse_spec("--perturb-std", spec, &["length", "angle", "slope"])?;
        let std = PerturbStd {
            length: units.to_si(Quantity::Length, spec_value(&s, "length").unwrap_or(0.0)),
            angle: units.to_si(Quantity::Angle, spec_value(&s, "angle").unwrap_or(0.0)),
            slope_fraction: spec_value(&s, "slope").unwrap_or(0.0),
        };
        truth = simulate::perturb(&truth, std, a.seed);
    }
    if let Some(list) = &a.perturb {
        for part in list.split(',').map(str::trim) {
            let (name, delta) = part
                .split_once('=')
                .ok_or_else(|| anyhow!("--perturb `{part}`: expected NAME=DELTA, e.g. p3=+0.1"))?;
            let delta: f64 = delta
                .trim()
                .parse()
                .ok()
                .filter(|v: &f64| v.is_finite())
                .ok_or_else(|| {
                    anyhow!(
                        "--perturb `{part}`: `{}` is not a finite number",
                        delta.trim()
                    )
                })?;
            for id in parse_param_list(name.trim(), nominal)? {
                let q = nominal.param_quantity(id);
                truth.set(id, truth.get(id) + units.to_si(q, delta));
            }
        }
    }
    let postures = simulate::sample_postures(nominal, a.postures, a.seed);
    let mut data = simulate::measure(&truth, &postures, a.position_only);
    if let Some(spec) = &a.noise {
        let s = parse_spec("--noise", spec, &["length", "angle"])?;
        let l = units.to_si(Quantity::Length, spec_value(&s, "length").unwrap_or(0.0));
        let an = units.to_si(Quantity::Angle, spec_value(&s, "angle").unwrap_or(0.0));
        simulate::add_noise(&mut data, l, an, a.seed);
    }
    write_file(&a.out, &write_measurements(nominal, &data))?;
    eprintln!(
        "wrote {} measurements ({} postures) to {}",
        data.measurements.len(),
        postures.len(),
        a.out.display()
    );
    if let Some(path) = &a.truth {
        write_file(path, &write_robot_toml(&truth, Some(&r.text)))?;
        eprintln!("wrote the true robot to {}", path.display());
    }
    Ok(())
}

fn calibrate(a: CalibrateArgs) -> Result<()> {
    let r = load_robot(&a.robot)?;
    let robot = &r.robot;
    let data = read_measurements(&a.data, a.columns.as_deref(), robot)?;
    let (weights, orientation) = residual_settings(&a.residuals, robot)?;
    let aopts = AnalysisOptions {
        weights,
        orientation,
        ..Default::default()
    };
    // Open the history first, so that an unwritable database fails before the work.
    let record_at = history::parse_at(a.at.as_deref())?;
    let record_db = match &a.record {
        Some(_) => Some(history::open_db(a.db.as_deref())?),
        None => None,
    };
    let (data, validation) = match (&a.validate, a.holdout) {
        (Some(path), _) => {
            let v = read_measurements(path, a.columns.as_deref(), robot)?;
            (data, Some(v))
        }
        (None, Some(f)) => {
            if !(f > 0.0 && f < 1.0) {
                bail!("--holdout must be a fraction between 0 and 1, got {f}");
            }
            let (ident, held) = kinecal::measurement::split_postures(&data, f, a.seed);
            if held.measurements.is_empty() || ident.measurements.is_empty() {
                bail!("--holdout {f} leaves an empty identification or validation set");
            }
            (ident, Some(held))
        }
        (None, None) => (data, None),
    };
    let estimate_spec = a
        .estimate
        .clone()
        .unwrap_or_else(|| default_estimate(robot));
    let estimate = estimate_list(&estimate_spec, a.fix.as_deref(), robot, &data, &aopts)?;
    let method = match a.method {
        MethodArg::Lm => Method::LevenbergMarquardt,
        MethodArg::Gn => Method::GaussNewton,
        MethodArg::Sd => Method::SteepestDescent,
        MethodArg::Svd => Method::Svd,
    };
    let mut solver = SolverOptions::new(method);
    if let Some(n) = a.max_iter {
        solver.max_iterations = n;
    }
    solver.damping = match a.damping {
        DampingArg::Marquardt => Damping::Marquardt,
        DampingArg::Identity => Damping::Identity,
    };
    if !(a.rcond > 0.0 && a.rcond < 1.0) {
        bail!("--rcond must be between 0 and 1, got {}", a.rcond);
    }
    solver.rcond = a.rcond;
    let opts = CalibrationOptions {
        estimate,
        solver,
        weights,
        orientation,
        loss: match a.loss {
            LossArg::Squared => estimation::Loss::Squared,
            LossArg::Huber => estimation::Loss::Huber(a.huber_scale),
        },
        solution: match a.solution {
            SolutionArg::Solver => SolutionRule::Solver,
            SolutionArg::MinChange => SolutionRule::MinChange(Box::new(robot.clone())),
        },
    };
    let start = match &a.initial {
        None => robot.clone(),
        Some(spec) => {
            let guess = load_robot(spec)?.robot;
            if guess.links.len() != robot.links.len()
                || guess.sites.len() != robot.sites.len()
                || guess
                    .joints
                    .iter()
                    .zip(&robot.joints)
                    .any(|(g, r)| g.kind != r.kind)
            {
                bail!(
                    "--initial {spec}: not the same robot structure as --robot {}",
                    a.robot
                );
            }
            let mut start = robot.clone();
            for id in robot.param_ids() {
                start.set(id, guess.get(id));
            }
            start
        }
    };
    if a.verbose {
        eprintln!(
            "{:>5} {:>14} {:>11} {:>10} {:>5}",
            "iter", "objective", "step", "lambda/t", "evals"
        );
    }
    let cal = estimation::calibrate(&start, &data, &opts, &mut |it| {
        if a.verbose {
            eprintln!(
                "{:>5} {:>14.6e} {:>11.3e} {:>10.1e} {:>5}",
                it.iteration, it.objective, it.step, it.lambda, it.evaluations
            );
        }
    })?;
    let report_of = |cal: &estimation::Calibration| -> Result<kinecal::report::CalibrationReport> {
        if a.outlier_sigma.is_nan() || a.outlier_sigma <= 0.0 {
            bail!("--outlier-sigma must be positive");
        }
        let mut rep = kinecal::report::CalibrationReport::new(cal, &data).with_outliers(
            cal,
            &data,
            a.outlier_sigma,
        );
        if let Some(v) = &validation {
            rep.add_validation(cal, v);
        }
        match kinecal::uncertainty::uncertainty_at(cal, &data, robot) {
            Ok(u) => rep.add_uncertainty(cal, &u),
            Err(e) => rep.warnings.push(format!("no uncertainty: {e}")),
        }
        Ok(rep)
    };
    let mut rep = report_of(&cal)?;
    let mut final_cal = cal;
    if let Some(k) = a.prune {
        if !(k > 0.0 && k.is_finite()) {
            bail!("--prune must be a positive number of standard deviations, got {k}");
        }
        let (full, pruned, removed) = estimation::calibrate_pruned(&start, &data, &opts, k)?;
        println!("== full fit ==");
        print!("{}", report::summary(&rep));
        println!();
        println!(
            "== pruned fit: removed {} (changes below {k} sigma, one at a time) ==",
            if removed.is_empty() {
                "nothing".to_string()
            } else {
                removed
                    .iter()
                    .map(|id| id.to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            }
        );
        rep = report_of(&pruned)?;
        rep.add_pruning(k, &removed, &full);
        final_cal = pruned;
    }
    print!("{}", report::summary(&rep));
    for w in &rep.warnings {
        eprintln!("warning: {w}");
    }
    if !rep.converged {
        eprintln!(
            "warning: the solver stopped at the iteration cap before converging (--max-iter)"
        );
    }
    let cal = final_cal;
    if let Some(path) = &a.out {
        write_file(path, &write_robot_toml(&cal.calibrated, Some(&r.text)))?;
        eprintln!("wrote the calibrated robot to {}", path.display());
    }
    rep.robot_file_sha256 = Some(kinecal_history::fingerprint(r.text.as_bytes()));
    rep.data_file_sha256 = Some(kinecal_history::fingerprint(&std::fs::read(&a.data)?));
    if let Some(path) = &a.report {
        write_file(path, &(rep.to_json() + "\n"))?;
        eprintln!("wrote the report to {}", path.display());
    }
    if let Some(path) = &a.html {
        write_file(path, &curves::html_of(&cal, &data, &rep, robot)?)?;
        eprintln!("wrote the HTML report to {}", path.display());
    }
    if let (Some(serial), Some(db)) = (&a.record, &record_db) {
        let id = db.add(serial, record_at, &rep, &a.note)?;
        eprintln!("recorded as calibration {id} of robot {serial}");
    }
    Ok(())
}
