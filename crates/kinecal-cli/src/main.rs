//! The `kinecal` command: a thin layer over the `kinecal` library. Arguments are mapped to the
//! library's requests, outcomes are rendered; no calibration arithmetic happens here.

mod analyze;
mod args;
mod curves;
mod demo;
mod history;
mod output;
mod report;

use std::path::Path;

pub use output::write_file;
use std::process::ExitCode;

use anyhow::{anyhow, bail, Context as _, Result};
use clap::Parser;

use args::{
    CalibrateArgs, Cli, Command, ConventionArg, DampingArg, DatasetArgs, ExportCommand,
    ExportUrdfArgs, FkArgs, ImportCommand, LossArg, MethodArg, ObservationFiles, OrientationArg,
    ResidualArgs, SimulateArgs, SolutionArg, SpreadArg,
};
use kinecal::estimation::{Damping, Loss, Method, SolverOptions};
use kinecal::observe::point::{
    parse_measurements_mapped, parse_postures, write_measurements, ColumnMap,
};
use kinecal::observe::{Dataset, OrientationError, Weights, FORMATS};
use kinecal::robot_file::{parse_robot_toml, write_robot_toml_checked};
use kinecal::simulate::{self, PerturbStd};
use kinecal::source::Source;
use kinecal::units::Quantity;
use kinecal::workflow::{self, Request, Selection, SolutionRule, Validation};
use kinecal::{examples, parse_param_list, Robot, Warning};

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
        Command::Calibrate(a) => calibrate(a),
        Command::Analyze(a) => analyze::run(a).map(|()| 0),
        Command::Import(c) => import(c).map(|()| 0),
        Command::Export(ExportCommand::Urdf(a)) => export_urdf(a).map(|()| 0),
        Command::History(c) => history::run(c),
        Command::Check(a) => history::check(a),
        Command::Curves(c) => curves::run(c).map(|()| 0),
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
            eprintln!("error: {e:#}");
            if let Some(hint) = e.downcast_ref::<kinecal::Error>().and_then(hint) {
                eprintln!("hint: {hint}");
            }
            ExitCode::from(EXIT_INPUT)
        }
    }
}

/// What the command line adds to a library error: which option to use.
fn hint(e: &kinecal::Error) -> Option<&'static str> {
    match e {
        kinecal::Error::SingularNormalEquations { .. } => {
            Some("use --method lm or --method svd, or --estimate identifiable")
        }
        kinecal::Error::TooFewResiduals { .. } => {
            Some("--estimate identifiable estimates only what the data determines")
        }
        kinecal::Error::Input { message, .. } if message.contains("the chain's") => {
            Some("--base LINK and --tip LINK choose the chain")
        }
        _ => None,
    }
}

/// A warning as the command line words it: the library's sentence, and the option to use.
pub fn word(w: &Warning) -> String {
    let extra = match w {
        Warning::GimbalLock { .. } => " (--orientation-error rotvec)",
        Warning::NotConverged { .. } => " (raise --max-iter)",
        Warning::Stalled { .. } => " (use --method lm)",
        Warning::UnclearRank { .. } | Warning::SmallGap { .. } => {
            " (kinecal analyze shows the spectrum; --rcond sets the tolerance)"
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

/// Reads a text file, naming it in errors.
pub fn read_text(path: &Path) -> Result<String> {
    Ok(Source::read(path)?.text)
}

/// Loads `--robot`: a file, or a built-in robot's name.
pub fn load_robot(spec: &str) -> Result<LoadedRobot> {
    let path = Path::new(spec);
    let source = if path.exists() {
        Source::read(path)?
    } else if let Some(text) = examples::builtin(spec) {
        Source::text(format!("<built-in {spec}>"), text)
    } else {
        bail!(
            "{spec}: no such robot file, and not a built-in robot (built-in: {})",
            examples::BUILTIN_NAMES.join(", ")
        );
    };
    let robot = parse_robot_toml(&source.text, &source.name)?;
    Ok(LoadedRobot { robot, source })
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

/// Reads a measurement file through the `--columns` mappings.
fn read_measurements(path: &Path, columns: &[String], robot: &Robot) -> Result<(Dataset, Source)> {
    let source = Source::read(path)?;
    let specs: Vec<&str> = columns.iter().map(String::as_str).collect();
    let map = ColumnMap::parse(&specs, "--columns")?;
    let data = parse_measurements_mapped(&source.text, &source.name, robot, &map)?;
    Ok((data, source))
}

/// Reads an observation file of any kind, told by its header (measurements through the
/// `--columns` mapping).
fn read_any(path: &Path, columns: &[String], robot: &Robot) -> Result<(Dataset, Source)> {
    let source = Source::read(path)?;
    let data = match kinecal::observe::detect_format(&source.text) {
        0 => {
            let specs: Vec<&str> = columns.iter().map(String::as_str).collect();
            let map = ColumnMap::parse(&specs, "--columns")?;
            parse_measurements_mapped(&source.text, &source.name, robot, &map)?
        }
        i => (FORMATS[i].parse)(&source.text, &source.name, robot)?,
    };
    Ok((data, source))
}

/// Reads every observation file given (`--data`, `--distances`, ...) into one dataset; an
/// error when none is given.
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
    let mut data = Dataset::default();
    let mut sources = Vec::new();
    for (i, path) in &files.files {
        let format = &FORMATS[*i];
        let (d, source) = if *i == 0 {
            read_measurements(path, &files.columns, robot)?
        } else {
            let source = Source::read(path)?;
            ((format.parse)(&source.text, &source.name, robot)?, source)
        };
        data = data.merge(d);
        sources.push(source);
    }
    Ok((data, sources))
}

/// The residual weights and orientation error chosen on the command line.
pub fn residual_settings(a: &ResidualArgs, robot: &Robot) -> Result<(Weights, OrientationError)> {
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

fn import(c: ImportCommand) -> Result<()> {
    let (input, output) = match &c {
        ImportCommand::Poe(a) => (&a.file, &a.out),
        ImportCommand::Urdf(a) => (&a.file, &a.out),
        ImportCommand::Dh(a) => (&a.file, &a.out),
    };
    output::check_distinct(&[output], &[input])?;
    let (robot, out) = match c {
        ImportCommand::Poe(a) => {
            let s = Source::read(&a.file)?;
            (
                kinecal::import::poe::parse_poe_toml(&s.text, &s.name)?,
                a.out,
            )
        }
        ImportCommand::Urdf(a) => {
            let s = Source::read(&a.file)?;
            let imp = kinecal::import::urdf::import_urdf(
                &s.text,
                &s.name,
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
            let s = Source::read(&a.file)?;
            let convention = match a.convention {
                ConventionArg::Standard => kinecal::import::dh::Convention::Standard,
                ConventionArg::Modified => kinecal::import::dh::Convention::Modified,
            };
            (
                kinecal::import::dh::import_dh(&s.text, &s.name, &a.name, units, convention)?,
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

fn export_urdf(a: ExportUrdfArgs) -> Result<()> {
    output::check_distinct(&[&a.out], &[&a.template, Path::new(&a.robot)])?;
    let r = load_robot(&a.robot)?;
    let template = Source::read(&a.template)?;
    let (text, warnings) = kinecal::import::urdf::export_urdf(
        &r.robot,
        &template.text,
        &template.name,
        a.base.as_deref(),
        a.tip.as_deref(),
    )?;
    for w in &warnings {
        eprintln!("warning: {}", word(w));
    }
    write_file(&a.out, &text)?;
    eprintln!("wrote the calibrated URDF to {}", a.out.display());
    Ok(())
}

fn fk(a: FkArgs) -> Result<()> {
    if let Some(out) = &a.out {
        output::check_distinct(&[out], &[&a.postures, Path::new(&a.robot)])?;
    }
    let r = load_robot(&a.robot)?;
    let s = Source::read(&a.postures)?;
    let postures = parse_postures(&s.text, &s.name, &r.robot)?;
    let data = simulate::measure(&r.robot, &postures, false);
    let csv = write_measurements(&r.robot, &data);
    match a.out {
        Some(path) => {
            write_file(&path, &csv)?;
            eprintln!(
                "wrote {} poses to {}",
                data.observations.len(),
                path.display()
            );
        }
        None => print!("{csv}"),
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
    Ok(())
}

/// The command line of a data set's suggested calibration.
fn suggested_command(s: &kinecal::datasets::Suggested) -> String {
    let mut c = format!("kinecal calibrate --robot {} --data {}", s.robot, s.data);
    if let Some(v) = s.validate {
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

/// Prints the solver's iterations (to standard error) when asked.
struct Verbose(bool);

impl workflow::Progress for Verbose {
    fn phase(&mut self, phase: workflow::Phase) {
        if self.0 && phase == workflow::Phase::Estimation {
            eprintln!(
                "{:>5} {:>14} {:>11} {:>10} {:>5}",
                "iter", "objective", "step", "lambda/t", "evals"
            );
        }
    }

    fn iteration(&mut self, it: &kinecal::estimation::Iteration) {
        if self.0 {
            eprintln!(
                "{:>5} {:>14.6e} {:>11.3e} {:>10.1e} {:>5}",
                it.iteration, it.objective, it.step, it.lambda, it.evaluations
            );
        }
    }
}

fn calibrate(a: CalibrateArgs) -> Result<u8> {
    let outputs: Vec<&Path> = [&a.out, &a.report, &a.html]
        .into_iter()
        .flatten()
        .map(|p| p.as_path())
        .collect();
    let mut inputs: Vec<&Path> = a
        .observations
        .files
        .iter()
        .map(|(_, p)| p.as_path())
        .collect();
    inputs.extend(a.validate.iter().map(|p| p.as_path()));
    inputs.push(Path::new(&a.robot));
    if let Some(i) = &a.initial {
        inputs.push(Path::new(i));
    }
    if let Some(db) = &a.db {
        inputs.push(db);
    }
    output::check_distinct(&outputs, &inputs)?;
    let r = load_robot(&a.robot)?;
    let robot = &r.robot;
    let (data, data_sources) = load_observations(&a.observations, robot)?;
    let (weights, orientation) = residual_settings(&a.residuals, robot)?;
    // Open the history first, so that an unwritable database fails before the work.
    let record_at = history::parse_at(a.at.as_deref())?;
    let record_db = match &a.record {
        Some(_) => Some(history::open_db(a.db.as_deref())?),
        None => None,
    };
    if a.folds.is_some() && !a.validate.is_empty() && a.choose.is_none() {
        bail!(
            "--folds and --validate are two ways to check a calibration: give one (with --choose, \
             the folds choose the model and the validation file checks it)"
        );
    }
    let validation = match (a.validate.is_empty(), a.holdout) {
        (false, _) => {
            let mut v = Dataset::default();
            for path in &a.validate {
                v = v.merge(read_any(path, &a.observations.columns, robot)?.0);
            }
            Validation::Data(v)
        }
        (true, Some(fraction)) => Validation::Holdout {
            fraction,
            seed: a.seed.unwrap_or(1),
        },
        (true, None) => match a.folds {
            Some(k) => Validation::Folds { k, seed: a.seed },
            None => Validation::None,
        },
    };
    let mut solver = SolverOptions::new(match a.method {
        MethodArg::Lm => Method::LevenbergMarquardt,
        MethodArg::Gn => Method::GaussNewton,
        MethodArg::Sd => Method::SteepestDescent,
        MethodArg::Svd => Method::Svd,
    });
    if let Some(n) = a.max_iter {
        solver.max_iterations = n;
    }
    solver.damping = match a.damping {
        DampingArg::Marquardt => Damping::Marquardt,
        DampingArg::Identity => Damping::Identity,
    };
    solver.rcond = a.rcond;
    let mut req = Request::new(robot.clone(), data);
    if a.estimate.is_some() || a.fix.is_some() {
        req.selection =
            Selection::parse(a.estimate.as_deref().unwrap_or(""), a.fix.as_deref(), robot)?;
    }
    req.initial = match &a.initial {
        None => None,
        Some(spec) => {
            let guess = load_robot(spec)?.robot;
            if !robot.same_structure(&guess) {
                bail!(
                    "--initial {spec}: not the same robot structure as --robot {}",
                    a.robot
                );
            }
            Some(guess)
        }
    };
    req.solver = solver;
    req.loss = match a.loss {
        LossArg::Squared => Loss::Squared,
        LossArg::Huber => Loss::Huber {
            k: a.huber_scale,
            spread: match a.huber_spread {
                SpreadArg::Robust => kinecal::estimation::Spread::Robust,
                SpreadArg::Stated => kinecal::estimation::Spread::Stated,
            },
        },
    };
    req.weights = weights;
    req.orientation = orientation;
    req.solution = match a.solution {
        SolutionArg::Solver => SolutionRule::Solver,
        SolutionArg::MinChange => SolutionRule::MinChange,
    };
    req.prune = a.prune;
    req.validation = validation;
    req.outlier_sigmas = a.outlier_sigma;
    req.sources = std::iter::once(r.source.clone())
        .chain(data_sources)
        .collect();
    let files = a.observations.files.clone();
    let result = match &a.choose {
        None => workflow::run(&req, &mut Verbose(a.verbose)),
        Some(list) => {
            let candidates = if list.is_empty() {
                workflow::Candidate::defaults(robot)
            } else {
                list.iter()
                    .map(|t| workflow::Candidate::parse(t, robot))
                    .collect()
            };
            candidates
                .and_then(|c| workflow::choose(&req, &c, a.folds.unwrap_or(5), a.seed))
                .map(|choice| {
                    print!("{}", report::choice_table(&choice.outcome.report));
                    choice.outcome
                })
        }
    };
    let outcome = result.map_err(|e| match e {
        kinecal::Error::InvalidOption { option, message } => {
            anyhow!("{}: {message}", flag_of(option))
        }
        kinecal::Error::NonFiniteResidual { line, kind, .. } => {
            // Name the file the observation came from (one file per format).
            let file = files
                .iter()
                .find(|(i, _)| FORMATS[*i].kinds.contains(&kind))
                .map_or(String::from("?"), |(_, p)| p.display().to_string());
            anyhow!("{file}:{line}: {e}")
        }
        e => e.into(),
    })?;
    if let Some(p) = &outcome.pruning {
        println!("== full fit ==");
        print!("{}", report::summary(&p.full_report));
        println!();
        println!(
            "== pruned fit: removed {} (changes below {} sigma, one at a time) ==",
            if p.removed.is_empty() {
                "nothing".to_string()
            } else {
                p.removed
                    .iter()
                    .map(|id| id.to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            },
            p.k
        );
    }
    print!("{}", report::summary(&outcome.report));
    for w in &outcome.warnings {
        eprintln!("warning: {}", word(w));
    }
    let implausible = outcome.warnings.iter().filter(|w| w.implausible()).count();
    if a.strict && implausible > 0 {
        eprintln!(
            "STRICT: {implausible} warning(s) above say the result is most likely wrong (units, \
             readings or a model that does not fit this robot); nothing written or recorded"
        );
        return Ok(EXIT_IMPLAUSIBLE);
    }
    // Everything is computed, and every output written beside its target, before anything is
    // replaced; the history record is the last step that can fail.
    let mut staged = output::Staged::new();
    if let Some(path) = &a.out {
        staged.text(
            path,
            &write_robot_toml_checked(&outcome.calibration.calibrated, Some(&r.source.text))?,
        )?;
    }
    if let Some(path) = &a.report {
        staged.text(path, &(outcome.report.to_json() + "\n"))?;
    }
    if let Some(path) = &a.html {
        staged.text(path, &kinecal_report::html_report(&outcome)?)?;
    }
    if let (Some(serial), Some(db)) = (&a.record, &record_db) {
        let options = kinecal_history::AddOptions { force: a.force };
        let id = db.add_with(serial, record_at, &outcome.report, &a.note, options)?;
        eprintln!("recorded as calibration {id} of robot {serial}");
    }
    staged.commit()?;
    for (path, what) in [
        (&a.out, "the calibrated robot"),
        (&a.report, "the report"),
        (&a.html, "the HTML report"),
    ] {
        if let Some(p) = path {
            eprintln!("wrote {what} to {}", p.display());
        }
    }
    Ok(if outcome.calibration.converged() {
        0
    } else {
        EXIT_NOT_CONVERGED
    })
}

/// The command-line option behind a library setting.
fn flag_of(option: &str) -> &str {
    match option {
        "outlier threshold" => "--outlier-sigma",
        "pruning threshold" => "--prune",
        "rcond" => "--rcond",
        "hold-out fraction" => "--holdout",
        "folds" => "--folds",
        "candidate" => "--choose",
        "Huber scale" => "--huber-scale",
        other => other,
    }
}
