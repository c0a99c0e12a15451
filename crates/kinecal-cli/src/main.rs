//! The `kinecal` command: a thin layer over the `kinecal` library. Arguments are mapped to the
//! library's requests, outcomes are rendered; no calibration arithmetic happens here.

mod analyze;
mod args;
mod batch;
mod calibrate;
mod compensate;
mod curves;
mod demo;
mod fleet;
mod history;
mod iso9283;
mod output;
mod plan;
mod predict;
mod report;
mod stream;

use std::path::Path;

pub use output::write_file;
use std::process::ExitCode;

use anyhow::{anyhow, bail, Context as _, Result};
use clap::Parser;

use args::{
    Cli, Command, ConventionArg, DatasetArgs, ExportCommand, ExportUrdfArgs, FkArgs, ImportCommand,
    ObservationFiles, OrientationArg, ResidualArgs, SimulateArgs,
};
use kinecal::files::{parse_postures, write_measurements, FORMATS};
use kinecal::import::readback::Tolerance;
use kinecal::observe::{Dataset, OrientationError, Weights};
use kinecal::robot_file::write_robot_toml_checked;
use kinecal::simulate::{self, PerturbStd};
use kinecal::source::Source;
use kinecal::spec::WeightsSpec;
use kinecal::units::Quantity;
use kinecal::{parse_param_list, Robot, Setting, Warning};

/// Exit code for errors in the input (files, parameter lists, unsolvable problems).
const EXIT_INPUT: u8 = 1;

/// Exit code when the solver stopped at its iteration cap or stalled: the outputs are written,
/// the report says `converged: false`, and scripts can tell.
pub const EXIT_NOT_CONVERGED: u8 = 4;

/// Exit code of `calibrate --strict` when a warning says the result is most likely wrong (see
/// [`kinecal::Warning::implausible`]): nothing is written. The code `check` and `history drift`
/// use for "look at this robot".
pub const EXIT_IMPLAUSIBLE: u8 = 3;

fn main() -> ExitCode {
    // Output piped into `head` and closed: end quietly, as other command-line tools do, rather
    // than panic on the failed write.
    #[cfg(unix)]
    // SAFETY: restoring the default disposition of SIGPIPE before any thread or I/O exists.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Demo => demo::run().map(|()| 0),
        Command::Fk(a) => fk(a).map(|()| 0),
        Command::Simulate(a) => simulate(a).map(|()| 0),
        Command::Calibrate(a) => calibrate::run(a),
        Command::Analyze(a) => analyze::run(a).map(|()| 0),
        Command::Import(c) => import(c).map(|()| 0),
        Command::Export(ExportCommand::Urdf(a)) => export_urdf(a).map(|()| 0),
        Command::Export(ExportCommand::Ur(a)) => export_ur(a).map(|()| 0),
        Command::Export(ExportCommand::Joints(a)) => export_joints(a).map(|()| 0),
        Command::Export(ExportCommand::Dh(a)) => export_dh(a).map(|()| 0),
        Command::Export(ExportCommand::Stiffness(a)) => export_stiffness(a).map(|()| 0),
        Command::History(c) => history::run(c),
        Command::Plan(a) => plan::run(a).map(|()| 0),
        Command::Predict(a) => predict::run(a).map(|()| 0),
        Command::Batch(a) => batch::run(a),
        Command::Compensate(a) => compensate::run(a),
        Command::Check(a) => history::check(a),
        Command::Curves(c) => curves::run(c).map(|()| 0),
        Command::Iso9283(c) => iso9283::run(c).map(|()| 0),
        Command::Report(a) => curves::report(a).map(|()| 0),
        Command::Dataset(a) => dataset(a).map(|()| 0),
        Command::Completions(a) => {
            use clap::CommandFactory;
            clap_complete::generate(
                a.shell,
                &mut Cli::command(),
                "kinecal",
                &mut std::io::stdout(),
            );
            Ok(0)
        }
    };
    match result {
        Ok(code) => ExitCode::from(code),
        Err(e) => {
            eprintln!("error: {}", in_flags(&e));
            if let Some(hint) = e.downcast_ref::<kinecal::Error>().and_then(hint) {
                eprintln!("hint: {hint}");
            }
            ExitCode::from(EXIT_INPUT)
        }
    }
}

/// An error and its causes, as `{e:#}` words them, with the library's settings named by the
/// command line's flags.
fn in_flags(e: &anyhow::Error) -> String {
    e.chain()
        .map(|cause| match cause.downcast_ref::<kinecal::Error>() {
            Some(kinecal::Error::InvalidOption { setting, message }) => {
                format!("{}: {message}", flag_of(*setting))
            }
            _ => cause.to_string(),
        })
        .collect::<Vec<_>>()
        .join(": ")
}

/// The command-line flag behind a library setting: the one table.
pub fn flag_of(setting: Setting) -> &'static str {
    match setting {
        Setting::OutlierThreshold => "--outlier-sigma",
        Setting::PruningThreshold => "--prune",
        Setting::Rcond => "--rcond",
        Setting::HoldoutFraction => "--holdout",
        Setting::Folds => "--folds",
        Setting::ModelCandidate => "--choose",
        Setting::PlanCandidates => "--candidates",
        Setting::PlanCount => "--count",
        Setting::PlanCriterion => "--criterion",
        Setting::HuberScale => "--huber-scale",
        // Set by the library from a fit's residuals, never from the command line.
        Setting::NoiseScale => "noise scale",
        Setting::CheckThreshold => "--threshold",
        Setting::ParameterChange => "--perturb",
        Setting::Sweep => "--from/--to/--span/--points",
        Setting::NominalRobot => "--nominal",
        Setting::ChainBase => "--base",
        Setting::ChainTip => "--tip",
        Setting::Robot => "--robot",
        Setting::InitialRobot => "--initial",
        Setting::Observations => "--data/--distances/--contacts",
        // A spec file's `kind`: the command line's options are the kinds.
        Setting::ObservationKind => "kind",
        Setting::Columns => "--columns",
        Setting::LengthUnit => "--length-unit",
        Setting::AngleUnit => "--angle-unit",
        Setting::Weights => "--weights",
        Setting::MaxIterations => "--max-iter",
        Setting::Validation => "--validate/--holdout/--folds",
        Setting::Configuration => "--configuration",
        Setting::OutputFormat => "--format",
        Setting::Prior => "--prior",
        Setting::TotalMass => "--total-mass",
    }
}

/// What the command line adds to a library error: which option to use.
fn hint(e: &kinecal::Error) -> Option<&'static str> {
    match e {
        kinecal::Error::ChainEnd { .. } => Some("--base LINK and --tip LINK choose the chain"),
        kinecal::Error::SingularNormalEquations { .. } => {
            Some("use --method lm or --method svd, or --estimate identifiable")
        }
        kinecal::Error::TooFewResiduals { .. } => Some(
            "--estimate identifiable estimates only what the data determines; --prior holds the \
             rest",
        ),
        kinecal::Error::ExportMisses { .. } => {
            Some("--tolerance length=L,angle=A (the robot file's units) accepts a larger deviation")
        }
        _ => None,
    }
}

/// A warning as the command line words it: the library's sentence, and the option to use.
pub fn word(w: &Warning) -> String {
    let extra = match w {
        Warning::NotConverged { .. } => " (raise --max-iter)",
        Warning::Stalled { .. } => " (use --method lm)",
        Warning::UnclearRank { .. } | Warning::SmallGap { .. } => {
            " (kinecal analyze shows the spectrum; --rcond sets the tolerance)"
        }
        Warning::ScaleMismatch {
            likely: Some(_), ..
        } => " (--length-unit)",
        Warning::AttitudeMismatch {
            likely: Some(_), ..
        } => " (--angle-unit)",
        Warning::AttitudeMismatch { likely: None, .. } | Warning::AttitudesUnfit { .. } => {
            " (--position-only)"
        }
        _ => "",
    };
    format!("{w}{extra}")
}

/// A robot as loaded: the model and the file it came from.
pub struct LoadedRobot {
    /// The model.
    pub robot: Robot,
    /// The file (text and fingerprint).
    pub source: Source,
}

/// The target a command-line name stands for: `ee` (or the end effector's name) for the end
/// effector, else a site of `robot`; an error naming `option` and the valid names otherwise.
pub fn target_named(robot: &Robot, name: &str, option: &str) -> Result<kinecal::Target> {
    kinecal::files::site_target(robot, name).map_err(|m| anyhow!("{option}: {m}"))
}

/// The error of a Cartesian goal whose numbers look like another unit's, at `place` (file and
/// line): "place: target 7 lies ..." or "place: beta = 90 rad is more than a turn ...".
pub fn goal_problem(
    p: &kinecal::compensate::GoalProblem,
    place: &str,
    target: &str,
) -> anyhow::Error {
    match p {
        kinecal::compensate::GoalProblem::Far(m) => anyhow!("{place}: {target} {m}"),
        kinecal::compensate::GoalProblem::Turn(m) => anyhow!("{place}: {m}"),
    }
}

/// Reads a text file, naming it in errors.
pub fn read_text(path: &Path) -> Result<String> {
    Ok(Source::read(path)?.text)
}

/// Loads `--robot`: a file, or a built-in robot's name.
pub fn load_robot(name: &str) -> Result<LoadedRobot> {
    let (robot, source) = kinecal::spec::load_robot(name)?;
    Ok(LoadedRobot { robot, source })
}

/// Parses `key=value,...` with numbers, allowing only `keys`.
pub fn parse_spec(option: &str, spec: &str, keys: &[&str]) -> Result<Vec<(String, f64)>> {
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

/// The value of `key` in a parsed `key=value` spec.
pub fn spec_value(spec: &[(String, f64)], key: &str) -> Option<f64> {
    spec.iter().find(|(k, _)| k == key).map(|(_, v)| *v)
}

/// Reads every observation file given (`--data`, `--distances`, ...) into one dataset, through
/// the library's one reader; an error when none is given.
pub fn load_observations(
    files: &ObservationFiles,
    robot: &Robot,
) -> Result<(Dataset, Vec<Source>)> {
    if files.files.is_empty() {
        bail!(
            "no observations: give {}",
            FORMATS
                .iter()
                .map(|f| format!("--{}", f.option))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    let (read, list) = files.spec()?;
    let all = files.all_paths();
    Ok(kinecal::files::read_files(&read, &list, robot, &all)?)
}

/// `--weights length=L,angle=A` (robot file units), when given.
pub fn weights_of(a: &ResidualArgs) -> Result<Option<WeightsSpec>> {
    let Some(spec) = &a.weights else {
        return Ok(None);
    };
    let s = parse_spec("--weights", spec, &["length", "angle"])?;
    Ok(Some(WeightsSpec {
        length: spec_value(&s, "length"),
        angle: spec_value(&s, "angle"),
    }))
}

/// `--orientation-error`, when given.
pub fn orientation_of(a: &ResidualArgs) -> Option<OrientationError> {
    a.orientation_error.map(|o| match o {
        OrientationArg::Euler => OrientationError::Euler,
        OrientationArg::Rotvec => OrientationError::RotVec,
    })
}

/// The residual weights and orientation error chosen on the command line.
pub fn residual_settings(a: &ResidualArgs, robot: &Robot) -> Result<(Weights, OrientationError)> {
    let weights = kinecal::spec::weights(robot, &weights_of(a)?.unwrap_or_default())?;
    Ok((weights, orientation_of(a).unwrap_or_default()))
}

fn import(c: ImportCommand) -> Result<()> {
    let (input, output) = match &c {
        ImportCommand::Poe(a) => (&a.file, &a.out),
        ImportCommand::Urdf(a) => (&a.file, &a.out),
        ImportCommand::Dh(a) => (&a.file, &a.out),
        ImportCommand::Ur(a) => (&a.file, &a.out),
    };
    output::check_distinct(&[output], &[input])?;
    let (robot, out) = match c {
        ImportCommand::Ur(a) => {
            let s = Source::read(&a.file)?;
            (
                kinecal::import::ur::import_ur(&s.text, &s.name)?.robot,
                a.out,
            )
        }
        ImportCommand::Poe(a) => {
            let s = Source::read(&a.file)?;
            (
                kinecal::import::poe::parse_poe_toml(&s.text, &s.name)?,
                a.out,
            )
        }
        ImportCommand::Urdf(a) => {
            let s = Source::read(&a.file)?;
            let imp = kinecal::import::urdf::import_urdf_with(
                &s.text,
                &s.name,
                a.base.as_deref(),
                &a.tip.iter().map(String::as_str).collect::<Vec<_>>(),
                a.masses,
            )?;
            if let Some(e) = &imp.robot.elastic {
                eprintln!(
                    "mass model: {} bodies, {} kg in all, gravity {} m/s^2 along -z",
                    e.bodies.len(),
                    // To the gram: the sum of the file's masses without float noise.
                    kinecal::units::number::format_number(
                        (e.bodies.iter().map(|b| b.mass).sum::<f64>() * 1e3).round() / 1e3
                    ),
                    kinecal::units::number::format_number(e.gravity.norm())
                );
            }
            (imp.robot, a.out)
        }
        ImportCommand::Dh(a) => {
            let (length, angle) = units_of(a.length_unit.as_deref(), a.angle_unit.as_deref())?;
            let s = Source::read(&a.file)?;
            (
                kinecal::import::dh::import_dh(
                    &s.text,
                    &s.name,
                    &a.name,
                    length,
                    angle,
                    a.convention.map(convention_of),
                )?,
                a.out,
            )
        }
    };
    write_file(&out, &write_robot_toml_checked(&robot, None)?)?;
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

/// `--length-unit` and `--angle-unit`, when given.
fn units_of(
    length: Option<&str>,
    angle: Option<&str>,
) -> Result<(Option<kinecal::LengthUnit>, Option<kinecal::AngleUnit>)> {
    Ok((
        length
            .map(str::parse)
            .transpose()
            .map_err(|e: String| anyhow!("--length-unit: {e}"))?,
        angle
            .map(str::parse)
            .transpose()
            .map_err(|e: String| anyhow!("--angle-unit: {e}"))?,
    ))
}

fn convention_of(c: ConventionArg) -> kinecal::import::dh::Convention {
    match c {
        ConventionArg::Standard => kinecal::import::dh::Convention::Standard,
        ConventionArg::Modified => kinecal::import::dh::Convention::Modified,
    }
}

/// `--tolerance length=L,angle=A` (robot file units) over the default for `robot`.
fn tolerance_of(spec: Option<&str>, robot: &Robot) -> Result<Tolerance> {
    let mut t = Tolerance::default_for(robot);
    if let Some(spec) = spec {
        let s = parse_spec("--tolerance", spec, &["length", "angle"])?;
        if let Some(l) = spec_value(&s, "length") {
            t.position = robot.units.to_si(Quantity::Length, l);
        }
        if let Some(a) = spec_value(&s, "angle") {
            t.attitude = robot.units.to_si(Quantity::Angle, a);
        }
    }
    Ok(t)
}

/// What an export cannot hold, each on its own line, with the deviation it causes.
fn say_lost(lost: &[kinecal::import::Lost], robot: &Robot) {
    for l in lost {
        eprintln!("{}", l.line(robot.units));
    }
}

fn export_urdf(a: ExportUrdfArgs) -> Result<()> {
    output::check_distinct(&[&a.out], &[&a.template, Path::new(&a.robot)])?;
    let r = load_robot(&a.robot)?;
    let tolerance = tolerance_of(a.tolerance.as_deref(), &r.robot)?;
    let template = Source::read(&a.template)?;
    let e = kinecal::import::urdf::export_urdf(
        &r.robot,
        &template.text,
        &template.name,
        a.base.as_deref(),
        &a.tip.iter().map(String::as_str).collect::<Vec<_>>(),
    )?;
    e.check(&r.robot, &tolerance)?;
    // A slope is said with its deviation, as what the URDF cannot hold.
    for w in &e.warnings {
        if !matches!(w, Warning::UrdfSlope { .. }) {
            eprintln!("warning: {}", word(w));
        }
    }
    say_lost(&e.lost, &r.robot);
    eprintln!("{}", e.read_back.line(r.robot.units));
    write_file(&a.out, &e.text)?;
    eprintln!("wrote the calibrated URDF to {}", a.out.display());
    Ok(())
}

fn export_dh(a: args::ExportDhArgs) -> Result<()> {
    output::check_distinct(&[&a.out], &[Path::new(&a.robot)])?;
    let robot = load_robot(&a.robot)?.robot;
    let tolerance = tolerance_of(a.tolerance.as_deref(), &robot)?;
    let (length, angle) = units_of(a.length_unit.as_deref(), a.angle_unit.as_deref())?;
    let units = kinecal::Units {
        length: length.unwrap_or(robot.units.length),
        angle: angle.unwrap_or(robot.units.angle),
    };
    let convention = convention_of(a.convention);
    let e = kinecal::import::dh::export_dh(&robot, convention, units)?;
    e.check(&robot, &tolerance)?;
    say_lost(&e.lost, &robot);
    eprintln!("{}", e.read_back.line(robot.units));
    for note in e.notes() {
        eprintln!("{note}");
    }
    write_file(&a.out, &e.text)?;
    eprintln!(
        "wrote the {} DH table ({}, {}) to {}",
        convention.as_str(),
        units.length,
        units.angle,
        a.out.display()
    );
    Ok(())
}

fn export_joints(a: args::ExportJointsArgs) -> Result<()> {
    output::check_distinct(&[&a.out], &[Path::new(&a.robot), Path::new(&a.nominal)])?;
    let cal = load_robot(&a.robot)?.robot;
    let nominal = load_robot(&a.nominal)?.robot;
    let tolerance = tolerance_of(a.tolerance.as_deref(), &cal)?;
    let e = kinecal::import::joints::joint_table(&cal, &nominal)?;
    e.check(&cal, &tolerance)?;
    say_lost(e.lost.as_slice(), &cal);
    eprintln!("{}", e.read_back.line(cal.units));
    write_file(&a.out, &e.text)?;
    eprintln!("wrote the joint table to {}", a.out.display());
    Ok(())
}

fn export_stiffness(a: args::ExportStiffnessArgs) -> Result<()> {
    output::check_distinct(&[&a.out], &[&a.report])?;
    let s = Source::read(&a.report)?;
    let report = kinecal::report::CalibrationReport::from_json(&s.text)
        .map_err(|e| anyhow!("{}: not a kinecal calibration report: {e}", s.name))?;
    let Some(elastic) = &report.elastic else {
        bail!(
            "{}: the calibrated robot `{}` has no mass model, so no compliances (add [[bodies]] \
             to its robot file, or import its URDF with --masses)",
            s.name,
            report.robot
        );
    };
    write_file(&a.out, &elastic.table())?;
    eprintln!(
        "wrote {} compliances ({} estimated) to {}",
        elastic.joints.len(),
        elastic.joints.iter().filter(|j| j.estimated).count(),
        a.out.display()
    );
    Ok(())
}

fn export_ur(a: args::ExportUrArgs) -> Result<()> {
    output::check_distinct(&[&a.out], &[&a.template, Path::new(&a.robot)])?;
    let r = load_robot(&a.robot)?;
    let tolerance = tolerance_of(a.tolerance.as_deref(), &r.robot)?;
    let template = Source::read(&a.template)?;
    let e = kinecal::import::ur::export_ur(&r.robot, &template.text, &template.name)?;
    e.check(&tolerance)?;
    for line in e.left_out() {
        eprintln!("{line}");
    }
    say_lost(&e.lost, &r.robot);
    eprintln!("{}", e.read_back.line(r.robot.units));
    write_file(&a.out, &e.text)?;
    eprintln!("wrote the calibrated kinematics to {}", a.out.display());
    println!("{}", e.tcp_line());
    Ok(())
}

fn fk(a: FkArgs) -> Result<()> {
    if let Some(out) = &a.out {
        output::check_distinct(&[out], &[&a.postures, Path::new(&a.robot)])?;
    }
    let r = load_robot(&a.robot)?;
    let robot = &r.robot;
    let mut rows = stream::Rows::open(&a.postures)?;
    let mut poses = 0;
    // A postures file streams through row by row (flat memory, any length); a measurement
    // file is read whole (its postures are those of its rows, merged).
    let mut emit = |w: &mut dyn std::io::Write| -> Result<()> {
        if rows.column("x").is_some() {
            let s = Source::read(&a.postures)?;
            let postures = parse_postures(&s.text, &s.name, robot)?;
            let readings = postures
                .iter()
                .map(|p| (p.readings.as_slice(), p.payload.as_ref()));
            if let Some((i, eq)) = kinecal::kinematics::unconverged_posture(robot, readings) {
                bail!(
                    "{}: posture `{}`: the gravity equilibrium {eq}",
                    s.name,
                    postures[i].label
                );
            }
            let data = simulate::measure(robot, &postures, false);
            poses = data.observations.len();
            w.write_all(write_measurements(robot, &data).as_bytes())?;
            return Ok(());
        }
        // A postures file, or what `kinecal compensate` writes (its label `target` or
        // `posture`, a `site`, and the remaining errors and flags, read past).
        let dof = robot.dof();
        let label = rows.column("posture").or_else(|| rows.column("target"));
        let readings: Option<Vec<usize>> = (0..dof)
            .map(|j| rows.column(&kinecal::files::reading_column(robot, &rows.header, j)))
            .collect();
        let compensated = [
            "site",
            "position_error",
            "attitude_error",
            "iterations",
            "flags",
        ];
        let payload_cols = stream::payload_columns(&rows)?;
        let unknown = rows.header.iter().enumerate().find(|(i, h)| {
            Some(*i) != label
                && !readings.as_ref().is_some_and(|r| r.contains(i))
                && !compensated.contains(&h.as_str())
                && !payload_cols.contains(&Some(*i))
        });
        let (Some(label), Some(readings), None) = (label, readings, unknown) else {
            bail!(
                "{}:1: unexpected header `{}`: expected `{}` (or what `kinecal compensate` \
                 writes)",
                rows.file,
                rows.header.join(","),
                kinecal::files::postures_header(robot).join(",")
            );
        };
        let mut first = true;
        let mut posture = kinecal::Posture {
            label: String::new(),
            readings: vec![0.0; robot.dof()],
            session: None,
            payload: None,
        };
        while let Some(line) = rows.advance()? {
            posture.label.clear();
            posture.label.push_str(rows.field(label));
            for (j, &c) in readings.iter().enumerate() {
                posture.readings[j] = stream::cell(&rows, line, c)?;
            }
            // With payload columns every row writes them: an empty one is no load, 0 kg.
            posture.payload = stream::payload_at(&rows, line, &payload_cols, &robot.units)?
                .or_else(|| {
                    payload_cols[0].map(|_| kinecal::robot::Payload {
                        mass: 0.0,
                        com: nalgebra::Vector3::zeros(),
                    })
                });
            if let Some((_, eq)) = kinecal::kinematics::unconverged_posture(
                robot,
                [(posture.readings.as_slice(), posture.payload.as_ref())],
            ) {
                bail!("{}:{line}: the gravity equilibrium {eq}", rows.file);
            }
            let data = simulate::measure(robot, std::slice::from_ref(&posture), false);
            poses += data.observations.len();
            let text = write_measurements(robot, &data);
            let body = if first {
                text.as_str()
            } else {
                text.split_once('\n').map_or("", |(_, rest)| rest)
            };
            w.write_all(body.as_bytes())?;
            first = false;
        }
        if first {
            bail!(
                "{}: no postures: the file has a header but no rows",
                rows.file
            );
        }
        Ok(())
    };
    match &a.out {
        Some(path) => {
            let mut staged = output::Staged::new();
            staged.by_path(path, |tmp| {
                let mut w = std::io::BufWriter::new(std::fs::File::create(tmp)?);
                emit(&mut w)?;
                std::io::Write::flush(&mut w)?;
                Ok(())
            })?;
            staged.commit()?;
            eprintln!("wrote {poses} poses to {}", path.display());
        }
        None => {
            let stdout = std::io::stdout();
            let mut w = std::io::BufWriter::new(stdout.lock());
            emit(&mut w)?;
            std::io::Write::flush(&mut w)?;
        }
    }
    Ok(())
}

fn simulate(a: SimulateArgs) -> Result<()> {
    let outputs: Vec<&Path> = std::iter::once(a.out.as_path())
        .chain(a.truth.as_deref())
        .collect();
    output::check_distinct(&outputs, &[Path::new(&a.robot)])?;
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
        let mut changes = Vec::new();
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
                changes.push((id, delta));
            }
        }
        truth = simulate::changed(&truth, &changes).map_err(|e| anyhow!("--perturb: {e}"))?;
    }
    let postures = simulate::sample_postures(nominal, a.postures, a.seed);
    let readings = postures
        .iter()
        .map(|p| (p.readings.as_slice(), p.payload.as_ref()));
    if let Some((i, eq)) = kinecal::kinematics::unconverged_posture(&truth, readings) {
        bail!(
            "the true robot's gravity equilibrium at posture {} {eq}",
            postures[i].label
        );
    }
    let mut data = simulate::measure(&truth, &postures, a.position_only);
    if let Some(spec) = &a.noise {
        let s = parse_spec("--noise", spec, &["length", "angle"])?;
        let l = units.to_si(Quantity::Length, spec_value(&s, "length").unwrap_or(0.0));
        let an = units.to_si(Quantity::Angle, spec_value(&s, "angle").unwrap_or(0.0));
        simulate::add_noise(&mut data, l, an, a.seed);
    }
    let mut staged = output::Staged::new();
    staged.text(&a.out, &write_measurements(nominal, &data))?;
    if let Some(path) = &a.truth {
        staged.text(
            path,
            &write_robot_toml_checked(&truth, Some(&r.source.text))?,
        )?;
    }
    staged.commit()?;
    eprintln!(
        "wrote {} measurements ({} postures) to {}",
        data.observations.len(),
        postures.len(),
        a.out.display()
    );
    if let Some(path) = &a.truth {
        eprintln!("wrote the true robot to {}", path.display());
    }
    Ok(())
}

fn dataset(a: DatasetArgs) -> Result<()> {
    let adapter = kinecal::datasets::DATASETS
        .iter()
        .find(|d| d.name == a.name)
        .ok_or_else(|| {
            anyhow!(
                "unknown data set `{}` (known: {})",
                a.name,
                kinecal::datasets::DATASETS
                    .iter()
                    .map(|d| d.name)
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        })?;
    if !a.dir.is_dir() {
        bail!("{}: no such folder", a.dir.display());
    }
    let converted = (adapter.convert)(&a.dir).map_err(|e| match e {
        kinecal::Error::Io { .. } => anyhow!(
            "{e}\nhint: is {} the folder of the data set ({})?",
            a.dir.display(),
            adapter.about
        ),
        e => e.into(),
    })?;
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("cannot create {}", a.out.display()))?;
    let mut staged = output::Staged::new();
    for (name, text) in &converted.files {
        staged.text(&a.out.join(name), text)?;
    }
    staged.commit()?;
    println!("{}", converted.summary);
    println!(
        "wrote {} to {}",
        converted
            .files
            .iter()
            .map(|f| f.0.as_str())
            .collect::<Vec<_>>()
            .join(", "),
        a.out.display()
    );
    println!(
        "next, in {}: {}",
        a.out.display(),
        suggested_command(&converted.suggested)
    );
    // The held-out figures the data set's README gives, per validation file, and pooled as
    // `kinecal calibrate` reports several --validate files.
    let held_out = converted.suggested.held_out;
    if !held_out.is_empty() {
        let each: Vec<String> = held_out
            .iter()
            .map(|(f, m)| format!("{:.2} mm on {f}", m * 1e3))
            .collect();
        let each = match each.split_last() {
            Some((last, rest)) if !rest.is_empty() => format!("{} and {last}", rest.join(", ")),
            _ => each.join(""),
        };
        let pooled = match converted.held_out_pooled() {
            Some(p) if held_out.len() > 1 => format!(
                " (each alone; about {:.2} mm pooled over the --validate files, as kinecal \
                 reports it)",
                p * 1e3
            ),
            _ => String::new(),
        };
        println!(
            "held out, the data set's README gives for a correct calibration a mean position \
             error of about {each}{pooled}"
        );
    }
    Ok(())
}

/// The command line of a data set's suggested calibration.
fn suggested_command(s: &kinecal::datasets::Suggested) -> String {
    let mut c = format!("kinecal calibrate --robot {} --data {}", s.robot, s.data);
    for v in s.validate {
        c += &format!(" --validate {v}");
    }
    c += &format!(" --estimate {}", s.estimate);
    if let Some(o) = s.orientation {
        c += &format!(" --orientation-error {}", o.as_str());
    }
    if let Some((l, a)) = s.weights {
        c += &format!(" --weights length={l},angle={a}");
    }
    if let Some(h) = s.holdout {
        c += &format!(" --holdout {h}");
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every library setting has a flag, and the flag is one the command line has (the noise
    /// scale excepted: the library sets it from a fit's residuals; and a spec file's `kind`:
    /// on the command line, the options are the kinds).
    #[test]
    fn every_setting_names_a_flag_of_the_command_line() {
        use clap::CommandFactory;
        fn longs(c: &clap::Command, out: &mut Vec<String>) {
            for a in c.get_arguments() {
                if let Some(l) = a.get_long() {
                    out.push(format!("--{l}"));
                }
            }
            for s in c.get_subcommands() {
                longs(s, out);
            }
        }
        let mut known = Vec::new();
        longs(&Cli::command(), &mut known);
        for s in Setting::ALL {
            if matches!(s, Setting::NoiseScale | Setting::ObservationKind) {
                continue;
            }
            for flag in flag_of(s).split('/') {
                assert!(known.iter().any(|k| k == flag), "{s:?}: {flag} is no flag");
            }
        }
    }

    /// A library error names the flag, through a context too.
    #[test]
    fn an_invalid_setting_is_worded_with_its_flag() {
        let e = anyhow::Error::from(kinecal::Error::InvalidOption {
            setting: Setting::HoldoutFraction,
            message: "expected a fraction between 0 and 1, got 2".into(),
        })
        .context("calibrating");
        assert_eq!(
            in_flags(&e),
            "calibrating: --holdout: expected a fraction between 0 and 1, got 2"
        );
    }
}
