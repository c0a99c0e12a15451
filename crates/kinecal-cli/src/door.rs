//! The command line's one door: each job command's flags become the library's spec of that job
//! (over `--spec`'s file, flags overriding it), `--write-spec` writes the spec down, and
//! [`kinecal::spec::run`] runs it. No job is computed here.

use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail, Result};
use kinecal::files::{ObservationFile, ReadSettings, FORMATS};
use kinecal::spec::{
    AnalyzeSpec, CheckSpec, CompensateSpec, CurveKind, CurvesSpec, Done, Env, ExportFormat,
    ExportSpec, FkSpec, ImportFormat, ImportSpec, Iso9283EvaluateSpec, Iso9283LogSpec,
    Iso9283PlanSpec, Iso9283SimulateSpec, Job, LengthAngle, Message, PlanSpec, PredictSpec,
    ProgramZone, Progress, ReportSpec, Residuals, SimulateSpec, Spec, Status,
};
use kinecal::Setting;

use crate::args::{
    AnalyzeArgs, CheckArgs, CompensateArgs, CurvesObjectiveArgs, CurvesPoseArgs, CurvesRobotArgs,
    ExportCameraInfoArgs, ExportDhArgs, ExportGltfArgs, ExportJointsArgs, ExportRosArgs,
    ExportStiffnessArgs, ExportUrArgs, ExportUrdfArgs, FkArgs, ImportDhArgs, ImportOutArgs,
    ImportPoeArgs, ImportUrArgs, ImportUrdfArgs, Iso9283EvaluateArgs, Iso9283LogArgs,
    Iso9283PlanArgs, Iso9283SimulateArgs, ObservationFiles, PlanArgs, PredictArgs, ReadBackArgs,
    ReportArgs, ResidualArgs, SimulateArgs, SpecArgs, SweepArgs,
};

/// Exit code when a check or a compensation flags what needs a person, or a strict calibration
/// meets a warning that its result is most likely wrong.
pub const EXIT_FLAGGED: u8 = 3;

/// Exit code when the solver stopped at its cap or stalled: the outputs are written.
pub const EXIT_NOT_CONVERGED: u8 = 4;

/// The exit code of a job's status.
pub fn exit_code(status: Status) -> u8 {
    match status {
        Status::NotConverged => EXIT_NOT_CONVERGED,
        Status::Implausible | Status::Flagged | Status::Refused => EXIT_FLAGGED,
        _ => 0,
    }
}

/// A path of the command line as a spec's string.
pub fn path_text(p: &Path) -> Result<String> {
    p.to_str()
        .map(str::to_string)
        .ok_or_else(|| anyhow!("{}: the path is not valid UTF-8", p.display()))
}

/// An optional path as a spec's string.
fn opt_path(p: &Option<PathBuf>) -> Result<Option<String>> {
    p.as_deref().map(path_text).transpose()
}

/// The spec `--spec` names, which must be of the job `S`; the default spec without it.
pub fn base<S: Spec + TryFrom<Job, Error = Job>>(door: &SpecArgs) -> Result<S> {
    let Some(path) = &door.spec else {
        return Ok(S::default());
    };
    let job = Job::read(path)?;
    let kind = job.kind();
    S::try_from(job).map_err(|_| {
        anyhow!(
            "{}: a spec of the job `{kind}`, not of `{}` (its `job` key)",
            path.display(),
            S::KIND
        )
    })
}

/// Sets `slot` to the flag's value when given.
pub fn set<T>(slot: &mut T, flag: Option<T>) {
    if let Some(v) = flag {
        *slot = v;
    }
}

/// Sets an optional `slot` to the flag's value when given.
pub fn over<T>(slot: &mut Option<T>, flag: Option<T>) {
    if flag.is_some() {
        *slot = flag;
    }
}

/// `length=L,angle=A` of `setting`, when given.
pub fn length_angle(text: Option<&str>, setting: Setting) -> Result<Option<LengthAngle>> {
    Ok(text.map(|t| LengthAngle::parse(t, setting)).transpose()?)
}

/// The observation files of the command line over the spec's: files given replace its list;
/// the reading settings given replace its.
pub fn observations(
    o: &ObservationFiles,
    read: &mut ReadSettings,
    list: &mut Vec<ObservationFile>,
) -> Result<()> {
    if !o.files.is_empty() {
        *list = o
            .files
            .iter()
            .map(|(k, p)| {
                Ok(ObservationFile {
                    kind: Some(FORMATS[*k].option.to_string()),
                    ..ObservationFile::new(path_text(p)?)
                })
            })
            .collect::<Result<_>>()?;
    }
    if !o.columns.is_empty() {
        read.columns = o.columns.clone();
    }
    over(&mut read.length_unit, o.length_unit.clone());
    over(&mut read.angle_unit, o.angle_unit.clone());
    read.position_only |= o.position_only;
    read.session_per_file |= o.session_per_file;
    Ok(())
}

/// The residual settings of the command line over the spec's.
pub fn residuals(a: &ResidualArgs, r: &mut Residuals) -> Result<()> {
    set(
        &mut r.weights,
        length_angle(a.weights.as_deref(), Setting::Weights)?,
    );
    set(&mut r.orientation_error, a.orientation_error);
    Ok(())
}

/// Writes the spec of a command line (`--write-spec`), checked not to replace an input or an
/// output of the job. `-` prints it: the job is then not run (`None`).
pub fn write_spec(job: &Job, door: &SpecArgs) -> Result<bool> {
    let Some(path) = &door.write_spec else {
        return Ok(true);
    };
    if path.as_os_str() == "-" {
        print!("{}", job.to_toml()?);
        return Ok(false);
    }
    let text = job.written_to(path)?.to_toml()?;
    let mut inputs = job.inputs();
    inputs.extend(job.outputs());
    inputs.extend(door.spec.iter().cloned());
    kinecal::files::output::check_distinct(
        &[path.as_path()],
        &inputs.iter().map(PathBuf::as_path).collect::<Vec<_>>(),
    )?;
    kinecal::files::output::write_file(path, &text)?;
    eprintln!("wrote the spec to {}", path.display());
    Ok(true)
}

/// Runs `job` through the library's door: the spec file and `also` are inputs no output may
/// replace. `None` when `--write-spec -` only printed the spec.
pub fn run(
    job: Job,
    door: &SpecArgs,
    progress: &mut dyn Progress,
    also: &[PathBuf],
) -> Result<Option<Done>> {
    run_with(job, door, progress, also, None)
}

/// What draws the jobs' pages.
static ARTIST: kinecal_report::Artist = kinecal_report::Artist;

/// What runs the history jobs (drawing through [`ARTIST`]).
pub static HISTORIAN: kinecal_history::jobs::Historian<'static> =
    kinecal_history::jobs::Historian::new(Some(&ARTIST));

/// [`run`], recording a calibration in a history with `recorder`.
pub fn run_with<'a>(
    job: Job,
    door: &SpecArgs,
    progress: &'a mut dyn Progress,
    also: &[PathBuf],
    recorder: Option<&'a mut dyn kinecal::spec::Recorder>,
) -> Result<Option<Done>> {
    // The outputs are checked against the inputs before anything, the spec written included.
    let mut inputs = job.inputs();
    inputs.extend(door.spec.iter().cloned());
    inputs.extend(also.iter().cloned());
    let mut outputs = job.outputs();
    outputs.extend(
        door.write_spec
            .iter()
            .filter(|p| p.as_os_str() != "-")
            .cloned(),
    );
    kinecal::files::output::check_distinct(
        &outputs.iter().map(PathBuf::as_path).collect::<Vec<_>>(),
        &inputs.iter().map(PathBuf::as_path).collect::<Vec<_>>(),
    )?;
    if !write_spec(&job, door)? {
        return Ok(None);
    }
    let mut env = Env::new(progress, Some(&ARTIST));
    env.also_inputs = door.spec.iter().chain(also).cloned().collect();
    env.recorder = recorder;
    env.historian = Some(&HISTORIAN);
    Ok(Some(kinecal::spec::run(&job, &mut env)?))
}

/// Prints what a job said on standard error.
pub fn say(messages: &[Message]) {
    for m in messages {
        match m {
            Message::Note(t) => eprintln!("{t}"),
            Message::Warning(w) => eprintln!("warning: {}", crate::word(w)),
            Message::Caution(t) => eprintln!("warning: {t}"),
            _ => {}
        }
    }
}

/// `kinecal analyze`'s spec.
pub fn analyze(a: &AnalyzeArgs) -> Result<AnalyzeSpec> {
    let mut s: AnalyzeSpec = base(&a.door)?;
    set(&mut s.robot, a.robot.clone());
    observations(&a.observations, &mut s.read, &mut s.observations)?;
    if let Some(p) = &a.postures {
        s.postures = Some(path_text(p)?);
    }
    let sel = &mut s.selection;
    over(&mut sel.estimate, a.estimate.clone());
    over(&mut sel.fix, a.fix.clone());
    over(&mut sel.priority, a.priority.clone());
    over(&mut sel.prior, a.prior.clone());
    over(&mut sel.total_mass, a.total_mass);
    over(&mut s.rcond, a.rcond);
    residuals(&a.residuals, &mut s.residuals)?;
    over(&mut s.matrix, a.print);
    set(&mut s.matrix_units, a.units);
    Ok(s)
}

/// `kinecal plan`'s spec.
pub fn plan(a: &PlanArgs) -> Result<PlanSpec> {
    let mut s: PlanSpec = base(&a.door)?;
    set(&mut s.robot, a.robot.clone());
    if a.candidates.is_some() || a.sample.is_some() {
        s.candidates = opt_path(&a.candidates)?;
        s.sample = a.sample;
    }
    over(&mut s.seed, a.seed);
    set(&mut s.count, a.count);
    set(&mut s.criterion, a.criterion);
    s.position_only |= a.position_only;
    over(&mut s.sites, a.sites.clone());
    over(&mut s.estimate, a.estimate.clone());
    over(&mut s.fix, a.fix.clone());
    over(&mut s.keep, opt_path(&a.keep)?);
    residuals(&a.residuals, &mut s.residuals)?;
    over(&mut s.outputs.postures, opt_path(&a.out)?);
    over(&mut s.outputs.html, opt_path(&a.html)?);
    Ok(s)
}

/// `kinecal predict`'s spec (predictions on standard output unless written to a file).
pub fn predict(a: &PredictArgs) -> Result<PredictSpec> {
    let mut s: PredictSpec = base(&a.door)?;
    set(&mut s.robot, a.robot.clone());
    set(&mut s.report, opt_path(&a.report)?);
    if a.postures.is_some() || a.sample.is_some() || a.targets.is_some() {
        s.postures = opt_path(&a.postures)?;
        s.sample = a.sample;
        s.targets = opt_path(&a.targets)?;
    }
    over(&mut s.seed, a.seed);
    over(&mut s.target, a.target.clone());
    over(&mut s.outputs.predictions, opt_path(&a.out)?);
    over(&mut s.outputs.html, opt_path(&a.html)?);
    set(&mut s.outputs.display_units, a.shown.display_units);
    if s.outputs.predictions.is_none() {
        s.outputs.predictions = Some("-".into());
    }
    Ok(s)
}

/// `kinecal compensate`'s spec.
pub fn compensate(a: &CompensateArgs) -> Result<CompensateSpec> {
    let mut s: CompensateSpec = base(&a.door)?;
    set(&mut s.robot, a.robot.clone());
    set(&mut s.nominal, a.nominal.clone());
    set(&mut s.input, opt_path(&a.input)?);
    over(&mut s.site, a.site.clone());
    s.position_only |= a.position_only;
    set(
        &mut s.tolerance,
        length_angle(a.tolerance.as_deref(), Setting::Tolerance)?,
    );
    over(&mut s.singular, a.singular);
    over(&mut s.branch, a.branch);
    over(&mut s.configuration, a.configuration.clone());
    set(&mut s.format, a.format);
    over(&mut s.name, a.name.clone());
    over(&mut s.speed, a.speed);
    over(&mut s.zone, a.zone.as_deref().map(ProgramZone::parse));
    over(&mut s.out, opt_path(&a.out)?);
    Ok(s)
}

/// `kinecal iso9283 plan`'s spec.
pub fn iso9283_plan(a: &Iso9283PlanArgs) -> Result<Iso9283PlanSpec> {
    let mut s: Iso9283PlanSpec = base(&a.door)?;
    set(&mut s.robot, a.robot.clone());
    if let Some(c) = &a.cube {
        s.cube = Some(numbers::<4>("--cube", c, "CX,CY,CZ,SIDE: four numbers")?);
    }
    if let Some(c) = &a.attitude {
        s.attitude = Some(numbers::<3>("--attitude", c, "A,B,C: three angles")?);
    }
    over(&mut s.resolution, a.resolution);
    over(&mut s.out, opt_path(&a.out)?);
    Ok(s)
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

/// `kinecal iso9283 simulate`'s spec.
pub fn iso9283_simulate(a: &Iso9283SimulateArgs) -> Result<Iso9283SimulateSpec> {
    let mut s: Iso9283SimulateSpec = base(&a.door)?;
    set(&mut s.robot, a.robot.clone());
    set(&mut s.poses, opt_path(&a.poses)?);
    over(&mut s.cycles, a.cycles);
    set(
        &mut s.noise,
        length_angle(a.noise.as_deref(), Setting::Noise)?,
    );
    over(&mut s.seed, a.seed);
    over(&mut s.out, opt_path(&a.out)?);
    Ok(s)
}

/// `kinecal iso9283 log`'s spec.
pub fn iso9283_log(a: &Iso9283LogArgs) -> Result<Iso9283LogSpec> {
    let mut s: Iso9283LogSpec = base(&a.door)?;
    set(&mut s.robot, a.robot.clone());
    set(&mut s.data, opt_path(&a.data)?);
    set(&mut s.roles, opt_path(&a.roles)?);
    over(&mut s.length_unit, a.length_unit.clone());
    over(&mut s.out, opt_path(&a.out)?);
    Ok(s)
}

/// `kinecal iso9283 evaluate`'s spec.
pub fn iso9283_evaluate(a: &Iso9283EvaluateArgs) -> Result<Iso9283EvaluateSpec> {
    let mut s: Iso9283EvaluateSpec = base(&a.door)?;
    set(&mut s.data, opt_path(&a.data)?);
    over(&mut s.length_unit, a.length_unit.clone());
    over(&mut s.angle_unit, a.angle_unit.clone());
    over(&mut s.robot, a.robot.clone());
    over(&mut s.report, opt_path(&a.report)?);
    over(&mut s.target, a.target.clone());
    over(&mut s.json, opt_path(&a.json)?);
    over(&mut s.html, opt_path(&a.html)?);
    Ok(s)
}

/// `kinecal simulate`'s spec.
pub fn simulate(a: &SimulateArgs) -> Result<SimulateSpec> {
    let mut s: SimulateSpec = base(&a.door)?;
    set(&mut s.robot, a.robot.clone());
    set(&mut s.postures, a.postures);
    over(&mut s.seed, a.seed);
    if let Some(list) = &a.perturb {
        s.perturb.clear();
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
            *s.perturb.entry(name.trim().to_string()).or_insert(0.0) += delta;
        }
    }
    if let Some(text) = &a.perturb_std {
        let mut p = kinecal::spec::PerturbSpread::default();
        for part in text.split(',').map(str::trim) {
            let (k, v) = part.split_once('=').ok_or_else(|| {
                anyhow!("--perturb-std `{text}`: expected length=L,angle=A,slope=F")
            })?;
            let v: f64 = v
                .trim()
                .parse()
                .map_err(|_| anyhow!("--perturb-std `{text}`: `{}` is not a number", v.trim()))?;
            match k.trim() {
                "length" => p.length = Some(v),
                "angle" => p.angle = Some(v),
                "slope" => p.slope = Some(v),
                other => bail!(
                    "--perturb-std `{text}`: unknown key `{other}` (expected length, angle, slope)"
                ),
            }
        }
        s.perturb_std = p;
    }
    if let Some(text) = &a.noise {
        s.noise = kinecal::spec::SimulateNoise::parse(text)?;
    }
    s.position_only |= a.position_only;
    over(&mut s.camera, a.camera.clone());
    over(&mut s.board, a.board.clone());
    over(&mut s.min_points, a.min_points);
    over(&mut s.out, opt_path(&a.out)?);
    over(&mut s.truth, opt_path(&a.truth)?);
    Ok(s)
}

/// `kinecal fk`'s spec.
pub fn fk(a: &FkArgs) -> Result<FkSpec> {
    let mut s: FkSpec = base(&a.door)?;
    set(&mut s.robot, a.robot.clone());
    set(&mut s.postures, opt_path(&a.postures)?);
    over(&mut s.out, opt_path(&a.out)?);
    Ok(s)
}

/// `kinecal check`'s spec.
pub fn check(a: &CheckArgs) -> Result<CheckSpec> {
    let mut s: CheckSpec = base(&a.door)?;
    set(&mut s.robot, a.robot.clone());
    observations(&a.observations, &mut s.read, &mut s.observations)?;
    if let Some(t) = &a.threshold {
        let parts: Vec<&str> = t.split(',').map(str::trim).collect();
        let num = |v: &str| -> Result<f64> {
            v.parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| anyhow!("--threshold `{t}`: `{v}` is not a number"))
        };
        s.threshold = match parts.as_slice() {
            [l] => LengthAngle {
                length: Some(num(l)?),
                angle: None,
            },
            [l, a] => LengthAngle {
                length: Some(num(l)?),
                angle: Some(num(a)?),
            },
            _ => {
                bail!("--threshold `{t}`: give LENGTH or LENGTH,ANGLE (in the robot file's units)")
            }
        };
    }
    over(&mut s.pixel_threshold, a.pixel_threshold);
    Ok(s)
}

/// The spec of an export command over `--spec`'s (which must be an export of `format`).
fn export_base(door: &SpecArgs, format: ExportFormat) -> Result<ExportSpec> {
    let mut s: ExportSpec = base(door)?;
    if door.spec.is_some() && s.format != format {
        bail!(
            "{}: a spec of a {} export, not of {}",
            door.spec.as_deref().unwrap_or(Path::new("")).display(),
            s.format.as_str(),
            format.as_str()
        );
    }
    s.format = format;
    Ok(s)
}

/// The read-back tolerance of an export over the spec's.
fn read_back(a: &ReadBackArgs, s: &mut ExportSpec) -> Result<()> {
    set(
        &mut s.tolerance,
        length_angle(a.tolerance.as_deref(), Setting::Tolerance)?,
    );
    Ok(())
}

/// `kinecal export urdf`'s spec.
pub fn export_urdf(a: &ExportUrdfArgs) -> Result<ExportSpec> {
    let mut s = export_base(&a.door, ExportFormat::Urdf)?;
    over(&mut s.robot, a.robot.clone());
    over(&mut s.template, opt_path(&a.template)?);
    over(&mut s.base, a.base.clone());
    if !a.tip.is_empty() {
        s.tip = a.tip.clone();
    }
    read_back(&a.read_back, &mut s)?;
    over(&mut s.out, opt_path(&a.out)?);
    Ok(s)
}

/// `kinecal export ros`'s spec.
pub fn export_ros(a: &ExportRosArgs) -> Result<ExportSpec> {
    let mut s = export_base(&a.door, ExportFormat::Ros)?;
    over(&mut s.robot, a.robot.clone());
    over(&mut s.template, opt_path(&a.template)?);
    over(&mut s.base, a.base.clone());
    if !a.tip.is_empty() {
        s.tip = a.tip.clone();
    }
    over(&mut s.measurement_frame, a.measurement_frame.clone());
    read_back(&a.read_back, &mut s)?;
    over(&mut s.out, opt_path(&a.out)?);
    Ok(s)
}

/// `kinecal export ur`'s spec.
pub fn export_ur(a: &ExportUrArgs) -> Result<ExportSpec> {
    let mut s = export_base(&a.door, ExportFormat::Ur)?;
    over(&mut s.robot, a.robot.clone());
    over(&mut s.template, opt_path(&a.template)?);
    read_back(&a.read_back, &mut s)?;
    over(&mut s.out, opt_path(&a.out)?);
    Ok(s)
}

/// `kinecal export dh`'s spec.
pub fn export_dh(a: &ExportDhArgs) -> Result<ExportSpec> {
    let mut s = export_base(&a.door, ExportFormat::Dh)?;
    over(&mut s.robot, a.robot.clone());
    over(&mut s.convention, a.convention);
    over(&mut s.length_unit, a.length_unit.clone());
    over(&mut s.angle_unit, a.angle_unit.clone());
    read_back(&a.read_back, &mut s)?;
    over(&mut s.out, opt_path(&a.out)?);
    Ok(s)
}

/// `kinecal export joints`'s spec.
pub fn export_joints(a: &ExportJointsArgs) -> Result<ExportSpec> {
    let mut s = export_base(&a.door, ExportFormat::Joints)?;
    over(&mut s.robot, a.robot.clone());
    over(&mut s.nominal, a.nominal.clone());
    read_back(&a.read_back, &mut s)?;
    over(&mut s.out, opt_path(&a.out)?);
    Ok(s)
}

/// `kinecal export gltf`'s spec.
pub fn export_gltf(a: &ExportGltfArgs) -> Result<ExportSpec> {
    let mut s = export_base(&a.door, ExportFormat::Gltf)?;
    over(&mut s.robot, a.robot.clone());
    over(&mut s.report, opt_path(&a.report)?);
    over(&mut s.nominal, a.nominal.clone());
    observations(&a.observations, &mut s.read, &mut s.observations)?;
    over(&mut s.posture, a.posture.clone());
    over(&mut s.out, opt_path(&a.out)?);
    Ok(s)
}

/// `kinecal export camera-info`'s spec.
pub fn export_camera_info(a: &ExportCameraInfoArgs) -> Result<ExportSpec> {
    let mut s = export_base(&a.door, ExportFormat::CameraInfo)?;
    over(&mut s.robot, a.robot.clone());
    over(&mut s.camera, a.camera.clone());
    over(&mut s.out, opt_path(&a.out)?);
    Ok(s)
}

/// `kinecal export stiffness`'s spec.
pub fn export_stiffness(a: &ExportStiffnessArgs) -> Result<ExportSpec> {
    let mut s = export_base(&a.door, ExportFormat::Stiffness)?;
    over(&mut s.report, opt_path(&a.report)?);
    over(&mut s.out, opt_path(&a.out)?);
    Ok(s)
}

/// The spec of an import command over `--spec`'s (which must be an import of `format`), with
/// its file and the robot file it writes.
fn import_base(
    door: &SpecArgs,
    format: ImportFormat,
    file: &Option<PathBuf>,
    written: &ImportOutArgs,
) -> Result<ImportSpec> {
    let mut s: ImportSpec = base(door)?;
    if door.spec.is_some() && s.format != format {
        bail!(
            "{}: a spec of another import",
            door.spec.as_deref().unwrap_or(Path::new("")).display()
        );
    }
    s.format = format;
    set(&mut s.file, opt_path(file)?);
    over(&mut s.out, opt_path(&written.out)?);
    Ok(s)
}

/// `kinecal import urdf`'s spec.
pub fn import_urdf(a: &ImportUrdfArgs) -> Result<ImportSpec> {
    let mut s = import_base(&a.door, ImportFormat::Urdf, &a.file, &a.written)?;
    over(&mut s.base, a.base.clone());
    if !a.tip.is_empty() {
        s.tip = a.tip.clone();
    }
    s.masses |= a.masses;
    Ok(s)
}

/// `kinecal import dh`'s spec.
pub fn import_dh(a: &ImportDhArgs) -> Result<ImportSpec> {
    let mut s = import_base(&a.door, ImportFormat::Dh, &a.file, &a.written)?;
    over(&mut s.convention, a.convention);
    over(&mut s.length_unit, a.length_unit.clone());
    over(&mut s.angle_unit, a.angle_unit.clone());
    over(&mut s.robot_name, a.name.clone());
    Ok(s)
}

/// `kinecal import poe`'s spec.
pub fn import_poe(a: &ImportPoeArgs) -> Result<ImportSpec> {
    import_base(&a.door, ImportFormat::Poe, &a.file, &a.written)
}

/// `kinecal import ur`'s spec.
pub fn import_ur(a: &ImportUrArgs) -> Result<ImportSpec> {
    import_base(&a.door, ImportFormat::Ur, &a.file, &a.written)
}

/// `kinecal report`'s spec.
pub fn report(a: &ReportArgs) -> Result<ReportSpec> {
    let mut s: ReportSpec = base(&a.door)?;
    over(&mut s.from, opt_path(&a.from)?);
    over(&mut s.robot, a.robot.clone());
    observations(&a.observations, &mut s.read, &mut s.observations)?;
    over(&mut s.calibrated, a.calibrated.clone());
    over(&mut s.calibration, opt_path(&a.calibration)?);
    residuals(&a.residuals, &mut s.residuals)?;
    over(&mut s.out, opt_path(&a.out)?);
    set(&mut s.display_units, a.shown.display_units);
    Ok(s)
}

/// The sweep of a curves command over the spec's.
fn sweep(a: &SweepArgs, s: &mut CurvesSpec) -> Result<()> {
    set(&mut s.sweep.param, a.param.clone());
    if a.span.is_some() || a.from.is_some() {
        s.sweep.span = a.span;
        s.sweep.from = a.from;
        s.sweep.to = a.to;
    }
    over(&mut s.sweep.points, a.points);
    over(&mut s.out, opt_path(&a.out)?);
    Ok(())
}

/// The spec of a curves command over `--spec`'s (which must be of `curve`), with its robot.
fn curves_base(job: &CurvesRobotArgs, curve: CurveKind) -> Result<CurvesSpec> {
    let door = &job.door;
    let mut s: CurvesSpec = base(door)?;
    if door.spec.is_some() && s.curve != curve {
        bail!(
            "{}: a spec of the other curve",
            door.spec.as_deref().unwrap_or(Path::new("")).display()
        );
    }
    s.curve = curve;
    set(&mut s.robot, job.robot.clone());
    Ok(s)
}

/// `kinecal curves pose`'s spec.
pub fn curves_pose(a: &CurvesPoseArgs) -> Result<CurvesSpec> {
    let mut s = curves_base(&a.job, CurveKind::Pose)?;
    if let Some(list) = &a.readings {
        s.readings = Some(
            list.split(',')
                .map(|v| {
                    v.trim()
                        .parse::<f64>()
                        .ok()
                        .filter(|x| x.is_finite())
                        .ok_or_else(|| anyhow!("--readings: `{}` is not a number", v.trim()))
                })
                .collect::<Result<_>>()?,
        );
        (s.postures, s.posture) = (None, None);
    }
    if a.postures.is_some() {
        s.postures = opt_path(&a.postures)?;
        s.posture = a.posture.clone();
        s.readings = None;
    }
    over(&mut s.site, a.site.clone());
    sweep(&a.sweep, &mut s)?;
    Ok(s)
}

/// `kinecal curves objective`'s spec.
pub fn curves_objective(a: &CurvesObjectiveArgs) -> Result<CurvesSpec> {
    let mut s = curves_base(&a.job, CurveKind::Objective)?;
    observations(&a.observations, &mut s.read, &mut s.observations)?;
    residuals(&a.residuals, &mut s.residuals)?;
    sweep(&a.sweep, &mut s)?;
    Ok(s)
}
