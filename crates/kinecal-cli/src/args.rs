//! Command-line arguments.
// The doc comments here are clap's help texts, written in usage syntax (`LENGTH[,ANGLE]`), not
// rustdoc links.
#![allow(rustdoc::broken_intra_doc_links)]

use std::path::PathBuf;

use clap::{Arg, ArgAction, ArgMatches, Args, FromArgMatches, Parser, Subcommand};
use kinecal::apps::plan::Criterion;
use kinecal::import::dh::Convention;
use kinecal::observe::OrientationError;
use kinecal::solve::estimation::{Damping, Method, Spread};
use kinecal::spec::{LossKind, MatrixKind, MatrixUnits, ProgramFormat};
use kinecal::workflow::SolutionRule;

/// Robot kinematic calibration (Goswami 1988 model: 6 parameters per link, 2 per joint).
#[derive(Debug, Parser)]
#[command(name = "kinecal", version, about, long_about = None, after_help = "\
Examples:
  kinecal demo
  kinecal fk --robot ge-a4 --postures postures.csv
  kinecal simulate --robot ge-a4 --postures 30 --seed 1 --perturb p1=+0.1 --out data.csv
  kinecal calibrate --robot ge-a4 --data data.csv --out calibrated.toml --report report.json

A robot is a TOML file, or the name of a built-in robot (ge-a4).")]
pub struct Cli {
    /// The command.
    #[command(subcommand)]
    pub command: Command,
    /// No progress display on standard error (there is none either when standard error is
    /// not a terminal). Every command takes it.
    #[arg(long, short = 'q', global = true, display_order = 999)]
    pub quiet: bool,
}

/// A command's arguments, added to its `clap::Command` only when that command is the one run,
/// its help is asked for, or the whole tree is built (completions, `Command::build`;
/// `clap::Command::defer`): a run builds the arguments of one command, not of all of them.
/// Reads as the arguments themselves (`Deref`).
#[derive(Debug)]
pub struct Deferred<T>(pub T);

impl<T> std::ops::Deref for Deferred<T> {
    type Target = T;
    fn deref(&self) -> &T {
        &self.0
    }
}

impl<T> std::ops::DerefMut for Deferred<T> {
    fn deref_mut(&mut self) -> &mut T {
        &mut self.0
    }
}

impl<T: FromArgMatches> FromArgMatches for Deferred<T> {
    fn from_arg_matches(m: &ArgMatches) -> Result<Self, clap::Error> {
        T::from_arg_matches(m).map(Deferred)
    }
    fn from_arg_matches_mut(m: &mut ArgMatches) -> Result<Self, clap::Error> {
        T::from_arg_matches_mut(m).map(Deferred)
    }
    fn update_from_arg_matches(&mut self, m: &ArgMatches) -> Result<(), clap::Error> {
        self.0.update_from_arg_matches(m)
    }
    fn update_from_arg_matches_mut(&mut self, m: &mut ArgMatches) -> Result<(), clap::Error> {
        self.0.update_from_arg_matches_mut(m)
    }
}

impl<T: Args> Args for Deferred<T> {
    fn augment_args(cmd: clap::Command) -> clap::Command {
        cmd.defer(|cmd| keep_texts(&cmd.clone(), T::augment_args(cmd)))
    }
    fn augment_args_for_update(cmd: clap::Command) -> clap::Command {
        cmd.defer(|cmd| keep_texts(&cmd.clone(), T::augment_args_for_update(cmd)))
    }
    fn group_id() -> Option<clap::Id> {
        T::group_id()
    }
}

/// `built` with the help texts the command's own attributes gave it (`before`), as an
/// argument struct's doc comment would not override them had they come after it (the order of
/// a command built at once).
fn keep_texts(before: &clap::Command, built: clap::Command) -> clap::Command {
    let mut c = match before.get_about() {
        Some(t) => built.about(t.clone()),
        None => built.about(None::<&str>),
    };
    c = match before.get_long_about() {
        Some(t) => c.long_about(t.clone()),
        None => c.long_about(None::<&str>),
    };
    if let Some(t) = before.get_after_help() {
        c = c.after_help(t.clone());
    }
    if let Some(t) = before.get_after_long_help() {
        c = c.after_long_help(t.clone());
    }
    if let Some(t) = before.get_before_help() {
        c = c.before_help(t.clone());
    }
    if let Some(t) = before.get_before_long_help() {
        c = c.before_long_help(t.clone());
    }
    c
}

/// kinecal's commands.
#[derive(Debug, Subcommand)]
#[allow(clippy::large_enum_variant)] // parsed once per run: size does not matter
pub enum Command {
    /// Run the thesis's experiment (section 4.3) on the built-in GE A4.
    #[command(after_help = "Example:\n  kinecal demo")]
    Demo,
    /// Forward kinematics: the pose of the end effector (and every site) at each posture.
    #[command(after_help = "\
Example:
  kinecal fk --robot ge-a4 --postures postures.csv --out poses.csv

The postures file is CSV with the header posture,v1,...,vn (one transducer reading per joint),
and optionally payload_mass,payload_cx,payload_cy,payload_cz (what the tool carries: an elastic
robot sags under it). The output is in the measurement format, in the robot file's units.")]
    Fk(Deferred<FkArgs>),
    /// Synthesize measurements from a perturbed ("true") copy of a robot.
    #[command(after_help = "\
Example:
  kinecal simulate --robot ge-a4 --postures 30 --seed 7 \\
      --perturb p3=+0.1,joint2.offset=-0.5 --noise length=0.001,angle=0.01 \\
      --out data.csv --truth truth.toml

Readings are drawn uniformly in each joint's min..max (otherwise +-150 deg or +-0.1 m about the
offset). Perturbations are additive changes in the robot file's units.

With --camera and --board, the data is what a camera of the robot file sees of a board: a pixel
file (posture,camera,point,v1..vn,u,v), every board point in front of the camera and inside its
image, at postures drawn within the joint ranges until --postures of them see at least
--min-points board points (at most 1000 draws per posture asked for, and 1,000,000 in all):
  kinecal simulate --robot cell.toml --camera wrist --board board --postures 25 \\
      --noise pixel=0.3 --out views.csv --truth truth.toml
Narrow the joint ranges (min, max) about a posture that sees the board when too few views are
found.")]
    Simulate(Deferred<SimulateArgs>),
    /// What the data can and cannot determine: singular values, rank, redundancies, a base set.
    #[command(after_help = "\
Examples:
  kinecal analyze --robot ge-a4 --data data.csv
  kinecal analyze --robot ge-a4 --postures postures.csv --estimate all --fix slopes --json
  kinecal analyze --robot ge-a4 --data data.csv --estimate p1-p6,p14,p29 --print hessian \\
      --units file
  kinecal analyze --robot arm.toml --distances ballbar.csv --estimate links,offsets

Ranks and dependencies are decided on the scaled Jacobian (residuals weighted, columns
normalised), where units cannot distort them; the file-unit figures show what units do
(thesis Tables 4.4 and 4.5). The expected count is the thesis's, generalised: 4 per revolute
joint, 2 per prismatic, 1 per slope or coupling, 6 or 3 per observed frame, 3 per estimated
plane, minus the motions of the world the observations cannot see.")]
    Analyze(Deferred<AnalyzeArgs>),
    /// Convert a robot from another convention (product of exponentials, Denavit-Hartenberg).
    #[command(subcommand)]
    Import(ImportCommand),
    /// The maintenance history: record calibrations, list them, flag drift.
    #[command(subcommand)]
    History(HistoryCommand),
    /// Put a calibration to work: readings that make the calibrated robot reach what was meant.
    #[command(after_help = "\
Examples:
  kinecal compensate --robot calibrated.toml --nominal nominal.toml --in program.csv \\
      --out compensated.csv
  kinecal compensate --robot calibrated.toml --nominal nominal.toml --in targets.csv \\
      --configuration elbow=up,wrist=noflip --format urscript --out program.script
  kinecal compensate --robot calibrated.toml --nominal nominal.toml --in program.csv \\
      --format krl --speed 50 --zone 10 --out compensated.src

--in is a program (posture,v1,...,vn: readings taught or planned with the nominal model; the
pose each was meant to reach is the nominal model's), Cartesian targets
(target[,site],x,y,z[,alpha,beta,gamma][,v1,...,vn]: positions and optional ZYX attitudes in the
robot file's units, optional seed readings), or a measurement file (its poses the targets, its
readings the seeds). Targets without seeds are searched for a usable solution: reached, inside
the joint ranges, in --configuration, not near a singularity. The table written has the
compensated readings and, per row, the remaining position and attitude error, the iterations and
the flags (unreachable, outside range, near singularity, configuration change, not in the
configuration); for a measurement file it is a measurement file of where the robot must be, with
the compensated readings (`kinecal check --robot true.toml --data it` measures where they land).
Payload columns (payload_mass, payload_cx, payload_cy, payload_cz: kg, and the centre of mass in
the end-effector frame) give what the tool carries at each row: an elastic robot (one with a mass
model) is solved sagging under it, and the table keeps them. Files of any length stream through.
Exit code 3 when any row is flagged.")]
    Compensate(Deferred<CompensateArgs>),
    /// Calibrate a fleet: every robot of a manifest, in parallel, with a summary table.
    #[command(after_help = "\
Examples:
  kinecal batch fleet.csv --summary summary.csv
  kinecal batch fleet.toml --record --db fleet.sqlite --jobs 4

The manifest is CSV with the header serial,robot,data[,options], options being calibrate's
(its --help) quoted like a shell's:

  serial,robot,data,options
  A4-0042,a4.toml,a4-0042.csv,--estimate identifiable --holdout 0.2
  A4-0043,a4.toml,a4-0043.csv,--out a4-0043-calibrated.toml

or TOML: one [[robots]] table per robot, a calibration spec (as `calibrate --spec` reads) with
its serial (and strict = true for --strict), over an optional [defaults] spec they share:

  [defaults]
  robot = \"a4.toml\"
  selection = { estimate = \"identifiable\" }
  [[robots]]
  serial = \"A4-0042\"
  observations = [{ file = \"a4-0042.csv\" }]
  validation = { holdout = 0.2 }

Paths are relative to the manifest's folder. One robot's failure never stops the others.
--shard K/N runs the K-th of N shares (robots K, K+N, K+2N, ... of the manifest), e.g. one per
task of a Kubernetes indexed Job or a Slurm array, every shard recording into one PostgreSQL
history: kinecal batch fleet.csv --shard 3/8 --record --db postgres://writer@db/kinecal
Exit code 0: every robot
calibrated and converged; 1: some failed (the summary says why); 3: some flagged by --strict;
4: some did not converge.")]
    Batch(Deferred<BatchArgs>),
    /// Plan the measurements: which postures to measure to determine the parameters best.
    #[command(after_help = "\
Examples:
  kinecal plan --robot arm.toml --sample 1000 --seed 3 --count 30 --position-only --out plan.csv
  kinecal plan --robot qkm.toml --candidates identification.csv --count 20 --out chosen.csv
  kinecal plan --robot arm.toml --sample 2000 --count 10 --keep measured.csv --criterion i \\
      --html plan.html --out more.csv

Chooses --count postures from the candidates (a postures file, a measurement file whose rows
say what is measured at each posture, or --sample postures drawn within the joint ranges) to
maximise a criterion of the scaled identification Jacobian of the parameters (default: the
identifiable set the candidates determine): d (log det, the default), a (trace of the inverse),
i (mean prediction variance over the candidates: the criterion of held-out accuracy), e, and
the observability indices o1-o5. Greedy start, then exchange until no swap improves the plan;
--keep adds postures already measured. Prints the criterion, the rank and condition number
reached, the information per posture against the candidates' average (D-efficiency), and the
same figures for 100 random plans. --out gets the chosen postures (a measurement file when the
candidates were one).")]
    Plan(Deferred<PlanArgs>),
    /// Does a calibrated robot still meet its accuracy? (exit 0 yes, 3 no)
    #[command(after_help = "\
Example:
  kinecal check --robot calibrated.toml --data check.csv --threshold 0.5,0.1

Compares the robot's predictions with a few measured check postures. The threshold is the
largest acceptable position error (length unit) and, optionally, attitude error (angle unit).
Exit code 0: within the threshold; 3: recalibrate; 1: bad input. Usable from cron.")]
    Check(Deferred<CheckArgs>),
    /// Characteristic curves: the pose or the objective against one parameter at a time.
    #[command(subcommand)]
    Curves(CurvesCommand),
    /// ISO 9283 pose accuracy and repeatability: the test poses, and the figures of a log.
    #[command(
        subcommand,
        after_help = "\
Examples:
  kinecal iso9283 plan --robot arm.toml --attitude 3.141592653589793,0,0 --out poses.csv
  kinecal iso9283 evaluate --data tracker-log.csv --json iso.json --html iso.html

plan: the five test poses P1..P5 in a cube the robot reaches; evaluate: AP, RP, their attitude
parts, AD, RD and vAP of a log of attained poses; simulate: a log of a robot sent round the poses
(no measurement)."
    )]
    Iso9283(Iso9283Command),
    /// A self-contained HTML report of a calibration (inline SVG; opens offline).
    #[command(after_help = "\
Example:
  kinecal report --robot ge-a4 --data data.csv --calibrated calibrated.toml --out report.html
  kinecal report --robot ge-a4 --data data.csv --calibration report.json --out report.html
  kinecal report --from report.json --html report.html      # the calibrate --html page again

Sections: summary, residuals per posture before/after, error histogram, parameter changes with
+-sigma bars, singular-value spectrum with the rank cut, redundant groups and determined
combinations, warnings. `kinecal calibrate --html report.html` writes it directly.")]
    Report(Deferred<ReportArgs>),
    /// Write a robot as URDF, ROS 2 files, UR kinematics, DH or a joint table, checked by reading
    /// it back.
    #[command(subcommand)]
    Export(ExportCommand),
    /// Convert a public calibration data set (as in ../shared/data) into kinecal's files.
    #[command(after_help = "\
Example:
  kinecal dataset fanuc-r2000ic ../shared/data/fanuc_r2000ic_lasertracker --out fanuc
  kinecal calibrate --robot fanuc/fanuc.toml --data fanuc/measurements.csv --estimate identifiable

Data sets:
  qkm-hl6         QKM HL6 + FARO laser tracker (qkm_hl6_faro): 46 reflector positions, 9 held out
  fanuc-r2000ic   FANUC R-2000iC + laser tracker (fanuc_r2000ic_lasertracker): 36 postures x 3
                  reflectors, the controller's joint values, joint 3 coupled to joint 2
  ur10e-camera    UR10e + wrist camera (ur10e_camera): 23 camera-measured poses
  ipa-ur10        UR10 + Leica laser tracker (ipa_ur10_tracker): 16,811 probe positions in four
                  series A-D from three tracker placements, each a session of its own, with the
                  tracker's per-axis sigmas (B-D) and the temperatures (temperatures.csv)

Writes the robot file(s) and measurement files into the output folder and prints the
calibration the data set's README suggests (and, when the README gives them, the held-out
figures a correct calibration reaches). For ipa-ur10:
  kinecal dataset ipa-ur10 ../shared/data/ipa_ur10_tracker --out ipa
  kinecal calibrate --robot ipa/ur10.toml --data ipa/series_A.csv --validate ipa/series_C.csv \\
    --validate ipa/series_D.csv --estimate identifiable")]
    Dataset(Deferred<DatasetArgs>),
    /// Print a shell completion script.
    #[command(after_help = "\
Example:
  kinecal completions bash > ~/.local/share/bash-completion/completions/kinecal
  kinecal completions zsh > ~/.zfunc/_kinecal")]
    Completions(Deferred<CompletionsArgs>),
    /// Estimate kinematic parameters from observations: poses, positions, distances, contacts.
    #[command(after_help = "\
Examples:
  kinecal calibrate --robot ge-a4 --data data.csv --estimate all --fix slopes \\
      --out calibrated.toml --report report.json
  kinecal calibrate --robot arm.toml --contacts touches.csv --distances ballbar.csv \\
      --estimate identifiable
  kinecal calibrate --robot ge-a4 --data data.csv --folds 5 --write-spec job.toml
  kinecal calibrate --spec job.toml --method svd     # the job again, one setting changed
  kinecal calibrate --robot ge-a4 --data data.csv --estimate all --prior length=0.004,angle=0.02

Parameter lists take ids (p3), ranges (p1-p30), names (link1.x, joint2.offset, joint4.slope,
joint3.coupling, site.NAME.x, plane.NAME.offset), whole links, joints, sites or planes (link2,
joint3, site.NAME, plane.NAME) and the groups all, links, offsets, slopes, couplings, sites,
planes, separated by commas. `--estimate identifiable` estimates the identifiable (base) set
that `kinecal analyze` reports; `--solution min-change` estimates everything and returns, of the
equally good answers, the one closest to the --robot file (tolerances from its [tolerances]
table); with `--prior`, what the data cannot determine is held by a Gaussian prior on each
parameter's change. Observation files combine; rows may carry their own sigma_position and
sigma_angle.")]
    Calibrate(Deferred<CalibrateArgs>),
    /// Predicted accuracy of a calibrated robot: the 95 % bound on its position (and attitude)
    /// error at postures, and the accuracy map.
    #[command(after_help = "\
Examples:
  kinecal predict --robot calibrated.toml --report report.json --postures postures.csv \\
      --out predicted.csv
  kinecal predict --robot calibrated.toml --report report.json --sample 10000 --seed 1 \\
      --html map.html
  kinecal predict --robot calibrated.toml --report report.json --targets targets.csv

The report is the calibration's (`kinecal calibrate --report`): it holds the parameters'
covariance, the model-error term and the measured postures. The bound at a posture combines the
covariance through the Jacobian with a model error of per-axis variance s0^2 + (c d)^2, d the
joint-space distance to the nearest measured posture. The table has the readings, the target's
x,y,z, d, and per quantity the parameters' and the model error's parts (RMS), the 95 % bound, and
the 95 % bound of the parameters alone, in the robot file's units. --html draws the accuracy map
(colour maps of the bound on slices of the workspace and along each joint's range). --targets
takes Cartesian goals instead (positions, or poses with ZYX Euler angles), each reached by the
calibrated robot's inverse kinematics (what a compensated program commands); a goal out of reach
or outside a joint range is refused with its line.")]
    Predict(Deferred<PredictArgs>),
}

/// The job as a spec file, and the spec of this command line written down: every job command
/// has them.
#[derive(Debug, Args, Clone, Default)]
pub struct SpecArgs {
    /// The job as a spec file (TOML, its `job` key this command's; see docs/spec.md). Flags
    /// given with it override its values; files given replace its lists.
    #[arg(long, value_name = "JOB.toml")]
    pub spec: Option<PathBuf>,
    /// Write the job of this command line (with --spec's, flags overriding) as a spec file
    /// here, then run it (`-` prints it and runs nothing).
    #[arg(long, value_name = "JOB.toml")]
    pub write_spec: Option<PathBuf>,
}

/// The units of pages and summaries (shared by the commands that draw pages).
#[derive(Debug, Args)]
pub struct DisplayUnitsArgs {
    /// The units numbers are shown in on pages and summaries: `default` (mm and deg for a
    /// metre-radian robot, else its own), `robot`, or LENGTH-ANGLE (`mm-deg`, `um-deg`, `m-rad`).
    /// Files for programs keep the robot's units.
    #[arg(long, value_name = "UNITS", value_parser = display_units)]
    pub display_units: Option<kinecal::units::DisplayChoice>,
}

/// How far an export, read back, may miss the robot (shared by the exports of a robot).
#[derive(Debug, Args)]
pub struct ReadBackArgs {
    /// How far the export, read back, may miss the robot at the tool over the joint ranges:
    /// `length=L,angle=A` in the robot file's units, either or both (default: a millionth of the
    /// robot's reach and 1e-9 rad). Beyond it nothing is written (exit 1).
    #[arg(long, value_name = "length=L,angle=A")]
    pub tolerance: Option<String>,
}

/// `kinecal predict`.
#[derive(Debug, Args)]
#[command(group(
    clap::ArgGroup::new("where")
        .args(["postures", "sample", "targets"])
))]
pub struct PredictArgs {
    #[command(flatten)]
    pub door: SpecArgs,
    /// The calibrated robot file (TOML), as `kinecal calibrate --out` wrote it.
    #[arg(long, required_unless_present = "spec")]
    pub robot: Option<String>,
    /// The calibration's report (JSON), as `kinecal calibrate --report` wrote it.
    #[arg(long, required_unless_present = "spec")]
    pub report: Option<PathBuf>,
    /// Postures file: CSV `posture,v1,...,vn` (a measurement file also works).
    #[arg(long)]
    pub postures: Option<PathBuf>,
    /// Draw N postures uniformly in the joint ranges instead (1 to 10,000,000).
    #[arg(long, value_name = "N")]
    pub sample: Option<usize>,
    /// Cartesian targets instead: CSV `target,x,y,z[,alpha,beta,gamma]` (the robot file's units
    /// and global frame), reached through the calibrated robot's inverse kinematics.
    #[arg(long, value_name = "TARGETS.csv")]
    pub targets: Option<PathBuf>,
    /// Seed of --sample (and of the map's postures; 0 to 2^63-1, what a spec file holds)
    /// [default: 1].
    #[arg(long)]
    pub seed: Option<u64>,
    /// The target predicted: `ee` or a site's name (default: the report's, the target its data
    /// measured most).
    #[arg(long)]
    pub target: Option<String>,
    /// Write the predictions here instead of standard output.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Write the accuracy map as an HTML page here.
    #[arg(long)]
    pub html: Option<PathBuf>,
    #[command(flatten)]
    pub shown: DisplayUnitsArgs,
}

/// `kinecal fk`.
#[derive(Debug, Args)]
pub struct FkArgs {
    #[command(flatten)]
    pub door: SpecArgs,
    /// Robot file (TOML) or built-in robot name.
    #[arg(long, required_unless_present = "spec")]
    pub robot: Option<String>,
    /// Postures file: CSV `posture,v1,...,vn` (a measurement file, or a table `kinecal
    /// compensate` writes with --format table or joints-ur|abb|kuka|fanuc, also works).
    #[arg(long, required_unless_present = "spec")]
    pub postures: Option<PathBuf>,
    /// Write the poses here instead of standard output.
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// `kinecal simulate`.
#[derive(Debug, Args)]
pub struct SimulateArgs {
    #[command(flatten)]
    pub door: SpecArgs,
    /// Nominal robot file (TOML) or built-in robot name.
    #[arg(long, required_unless_present = "spec")]
    pub robot: Option<String>,
    /// Number of postures to draw (1 to 10,000,000, and at most 10,000,000 measurements: the
    /// postures times the frames measured at each).
    #[arg(long, value_name = "N", required_unless_present = "spec")]
    pub postures: Option<usize>,
    /// Random seed, 0 to 2^63-1 (the same seed gives the same data on every machine).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Additive changes to named parameters, e.g. `p3=+0.1,joint2.offset=-0.5` (file units).
    #[arg(long, value_name = "LIST")]
    pub perturb: Option<String>,
    /// Random Gaussian changes to every parameter: `length=L,angle=A[,slope=F]` (file units; F a
    /// fraction of each slope).
    #[arg(long, value_name = "SPEC")]
    pub perturb_std: Option<String>,
    /// Gaussian measurement noise: `length=L,angle=A,pixel=P` (any of them; file units, pixels;
    /// at most the robot's reach, half a turn, the largest image's larger side).
    #[arg(long, value_name = "SPEC")]
    pub noise: Option<String>,
    /// Measure positions only (a laser tracker with one reflector).
    #[arg(long)]
    pub position_only: bool,
    /// Simulate what this camera of the robot file sees of --board: a pixel file.
    #[arg(long, value_name = "NAME", requires = "board")]
    pub camera: Option<String>,
    /// The board of the robot file the camera sees (with --camera).
    #[arg(long, value_name = "NAME", requires = "camera")]
    pub board: Option<String>,
    /// The fewest board points a kept view sees (with --camera) [default: 12].
    #[arg(long, value_name = "N")]
    pub min_points: Option<usize>,
    /// Measurement file to write (a pixel file with --camera).
    #[arg(long, required_unless_present = "spec")]
    pub out: Option<PathBuf>,
    /// Also write the perturbed ("true") robot file here.
    #[arg(long)]
    pub truth: Option<PathBuf>,
}

/// `kinecal import ...`.
#[derive(Debug, Subcommand)]
pub enum ImportCommand {
    /// A product-of-exponentials model (joint axes and points at zero, tool frame).
    #[command(after_help = "\
Example:
  kinecal import poe robot_poe.toml --out robot.toml

The file is TOML: length_unit, angle_unit, [[joints]] with kind, axis = [x, y, z], point = [x, y, z]
(a point on the axis), optional offset (joint value at zero reading), min, max; a [tool] table with
position = [x, y, z] and optional euler = [alpha, beta, gamma]; optional [[sites]] with name, joint,
position, euler at the zero configuration. Joint frames go on the axes with x along the common
normal, which keeps every link's beta at 0. Readings are joint values (slope 1).")]
    Poe(Deferred<ImportPoeArgs>),
    /// The serial chain of a URDF file.
    #[command(after_help = "\
Example:
  kinecal import urdf ur5_robot.urdf --base base_link --tip tool0 --out ur5.toml
  kinecal import urdf humanoid.urdf --tip left_marker --tip right_marker --out upper_body.toml

Revolute, continuous and prismatic joints become joints; fixed joints merge into the links; axes
other than +z are folded exactly into the neighbouring links. Readings are the URDF joint values
(rad, m) and joint limits become reading ranges. The model is written in metres and radians.
With --masses, the links' <inertial> masses become [[bodies]] of a mass model (gravity 9.81 m/s^2
along -z of the base, compliances 0): the robot is then elastic and each revolute joint gains a
compliance and a lateral compliance to estimate.")]
    Urdf(Deferred<ImportUrdfArgs>),
    /// A Denavit-Hartenberg table.
    #[command(after_help = "\
Example:
  kinecal import dh --convention modified puma560.csv --length-unit m --angle-unit deg \\
      --out puma.toml

The table is CSV `kind,a,alpha,d,theta`, with an optional `beta` column (the Hayati/Mooring twist
about y, 0 when absent), one row per joint or `fixed` transform. standard: Rz(theta+q) Tz(d) Tx(a)
Rx(alpha) Ry(beta); modified (Craig): Rx(alpha) Tx(a) Ry(beta) Rz(theta+q) Tz(d); for a prismatic
joint q adds to d; a fixed row has no q. Readings are the joint values (slope 1); theta (or d)
becomes the joint offset. The units and convention are those the table states in comment lines
before its header (`# length_unit = mm`, `# angle_unit = deg`, `# convention = standard`, as kinecal
export dh writes them); a table that states none needs --length-unit, --angle-unit and
--convention, and flags that contradict the table are refused.")]
    Dh(Deferred<ImportDhArgs>),
    /// A Universal Robots kinematics file (default_kinematics.yaml, or a robot's factory
    /// calibration extracted by the UR driver).
    #[command(after_help = "\
Example:
  kinecal import ur ur3e_calibration.yaml --out ur3e.toml

The file gives each joint's origin (x, y, z, roll, pitch, yaw) in its parent; the chain is the
UR description's, from base_link to tool0. Readings are the joint values (rad, slope 1), ranges
+-2 pi. The model is written in metres and radians.")]
    Ur(Deferred<ImportUrArgs>),
}

/// `kinecal import ur`.
#[derive(Debug, Args)]
pub struct ImportUrArgs {
    #[command(flatten)]
    pub door: SpecArgs,
    /// The kinematics file (YAML).
    #[arg(required_unless_present = "spec")]
    pub file: Option<PathBuf>,
    #[command(flatten)]
    pub written: ImportOutArgs,
}

/// `kinecal curves ...`.
#[derive(Debug, Subcommand)]
pub enum CurvesCommand {
    /// The six pose components of the end effector (or a site) against each parameter.
    #[command(after_help = "\
Example:
  kinecal curves pose --robot ge-a4 --readings -6.883,13.301,4.122,-28.645 --param p1,p4,p35 \\
      --out pose.svg

One panel pair (positions, angles) per parameter, the nominal value marked by dotted guide lines
(thesis Figs 4.2-4.5). Angles are unwrapped: no false jumps at +-180 deg. --out ending in .svg,
.png or .csv (columns param,value,x,y,z,alpha,beta,gamma), or - for the CSV on standard output
(what the curves show then goes to standard error). Default span, either side: the robot's reach
for lengths, 50 deg for angles, half the value for slopes. At most 100000 points.")]
    Pose(Deferred<CurvesPoseArgs>),
    /// The objective over a data set against each parameter.
    #[command(after_help = "\
Example:
  kinecal curves objective --robot ge-a4 --data data.csv --param p38 --span 100 --out p38.svg

Lists every local minimum inside the span and warns when the objective is not convex there (a
solver started there could stop in a false valley, thesis 4.4.4); prints the period of periodic
parameters (360 deg for angles, 360/V for a revolute slope at reading V). --out ending in .svg,
.png or .csv (columns param,value,objective), or - for the CSV on standard output (what the
curves show then goes to standard error). Default span, either side: a fifth of the robot's reach
for lengths, 10 deg for angles, a tenth of the value for slopes. At most 100000 points.")]
    Objective(Deferred<CurvesObjectiveArgs>),
}

/// `kinecal iso9283 ...`.
#[derive(Debug, Subcommand)]
pub enum Iso9283Command {
    /// The five test poses P1..P5 of ISO 9283 in a cube the robot reaches, with their readings.
    #[command(after_help = "\
Examples:
  kinecal iso9283 plan --robot arm.toml --attitude 3.141592653589793,0,0 --out poses.csv
  kinecal iso9283 plan --robot arm.toml --cube 400,0,500,300 --attitude 180,0,0 --out poses.csv

P1 is the cube's centre; P2..P5 lie on the diagonals of its diagonal plane through the edges at
low y, low z and high y, high z, at 10 % of the diagonal from the corners (ISO 9283:1998, 6.8).
Each cycle visits P1, P5, P4, P3, P2 (7.2), 30 cycles. The attitude a,b,c (rotations about the
base frame's x, y, z: R = Rz(c) Ry(b) Rx(a), the robot file's alpha = c, beta = b, gamma = a) is
the same at every pose; without it the poses are positions. Without --cube, a grid over the
working space is tested with the inverse kinematics and the largest cube of reached points is
grown or shrunk until its test poses and its eight corners are reached inside the joint ranges,
away from singularities: a search, not a proof of the largest cube. --out gets
pose,x,y,z[,a,b,c],v1..vn in the robot file's units.")]
    Plan(Deferred<Iso9283PlanArgs>),
    /// A simulated log: a robot sent round the test poses, plus noise (no measurement).
    #[command(after_help = "\
Example:
  kinecal iso9283 simulate --robot truth.toml --poses poses.csv --cycles 30 \\
      --noise length=0.00002,angle=0.00005 --seed 1 --out log.csv

The commanded poses are the plan's (the model it was planned with); the attained ones are --robot's
forward kinematics at the plan's readings (a \"true\" robot, e.g. from kinecal simulate --truth),
plus Gaussian noise of the given standard deviations (robot file units) on every coordinate and
angle. The log says it is simulated, and so do the figures of kinecal iso9283 evaluate.")]
    Simulate(Deferred<Iso9283SimulateArgs>),
    /// Pose accuracy and repeatability (AP, RP, AD, RD, vAP) from a log of attained poses.
    #[command(after_help = "\
Examples:
  kinecal iso9283 evaluate --data log.csv
  kinecal iso9283 evaluate --data tracker.csv --length-unit mm --angle-unit deg --json iso.json \\
      --html iso.html

The log is CSV: pose,cycle,xc,yc,zc[,ac,bc,cc],x,y,z[,a,b,c][,direction]: the pose index (1..5 or
P1..P5), the cycle, the commanded and the attained (measured) pose, optionally the approach
direction (a label) for the multi-directional test. Per pose: AP = |barycentre - commanded|
(APx, APy, APz), RP = lbar + 3 S_l (l the distances from the barycentre, S with n - 1), APa, APb,
APc (mean angle differences, wrapped) and RPa, RPb, RPc = +-3 S; vAP, the largest distance
between the barycentres of different directions; per pair of poses, AD = Dbar - Dc and RD = +-3
S_D. The figures are in the log's units, stated before its header (# length_unit = mm,
# angle_unit = deg) or given. Fewer than 30 cycles: computed, with a warning; one cycle: accuracy
(AP, AD) only, no repeatability. A log may also name the cube's corners (C1..C8), hold several
tests (a test column: the figures test by test and a summary across them), and carry the
readings v1..vn.

With --robot and --report (a calibrated robot and its report, calibrated with --predict), each
pose also gets the AP the calibration predicts once the program is compensated: the predicted
RMS and 95 % bound of the calibrated model's error at the pose's readings (the log's, or the
calibrated model's inverse kinematics of the commanded pose). The log must then be in the robot's
base frame.")]
    Evaluate(Deferred<Iso9283EvaluateArgs>),
    /// An ISO 9283 log from a measurement file: commanded and attained poses in the base frame.
    #[command(after_help = "\
Example:
  kinecal iso9283 log --robot ur10_A.toml --data ipa/series_D.csv --roles ipa/series_D_iso.csv \\
      --out D_after.csv

--roles says which test, pose and cycle each posture is (posture,test,pose,cycle; pose P1..P5 or
a corner C1..C8; kinecal dataset ipa-ur10 writes one for its cube series). The attained pose of a
row is the measurement taken into the robot's base frame through its session's measurement frame;
a session the robot has no frame for is placed first (6 parameters estimated on the file, the
robot held, as a validation does). The commanded pose is where --robot puts the target at the
mean readings of the pose's cycles. So the figures are those of the robot driven by --robot's
model: the nominal one before calibration, a calibrated one for the compensated robot. Postures
without a role are left out, and counted. The log is in the robot file's units, or its lengths in
--length-unit.")]
    Log(Deferred<Iso9283LogArgs>),
}

/// `kinecal iso9283 log`.
#[derive(Debug, Args)]
pub struct Iso9283LogArgs {
    #[command(flatten)]
    pub door: SpecArgs,
    /// The robot model (file or built-in name) that drives the robot.
    #[arg(long, required_unless_present = "spec")]
    pub robot: Option<String>,
    /// The measurement file (positions or poses).
    #[arg(
        long,
        value_name = "MEASUREMENTS.csv",
        required_unless_present = "spec"
    )]
    pub data: Option<PathBuf>,
    /// Which test, pose and cycle each posture is (CSV: posture,test,pose,cycle).
    #[arg(long, value_name = "ROLES.csv", required_unless_present = "spec")]
    pub roles: Option<PathBuf>,
    /// Write the log's lengths in this unit (default: the robot file's).
    #[arg(long, value_name = "UNIT", value_parser = ["m", "mm", "in"])]
    pub length_unit: Option<String>,
    /// The log to write (CSV).
    #[arg(long, required_unless_present = "spec")]
    pub out: Option<PathBuf>,
}

/// `kinecal iso9283 plan`.
#[derive(Debug, Args)]
pub struct Iso9283PlanArgs {
    #[command(flatten)]
    pub door: SpecArgs,
    /// Robot file (TOML) or built-in robot name.
    #[arg(long, required_unless_present = "spec")]
    pub robot: Option<String>,
    /// The cube: centre and side `CX,CY,CZ,SIDE` (the robot file's length unit, base frame).
    /// Default: search for a large cube the robot reaches.
    #[arg(long, value_name = "CX,CY,CZ,SIDE", allow_hyphen_values = true)]
    pub cube: Option<String>,
    /// The tool attitude `A,B,C` at every pose (the robot file's angle unit; see below).
    #[arg(long, value_name = "A,B,C", allow_hyphen_values = true)]
    pub attitude: Option<String>,
    /// Grid points along the longest side of the working space searched (3 to 200).
    #[arg(long, value_name = "N")]
    pub resolution: Option<usize>,
    /// Write the poses here (CSV).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// `kinecal iso9283 simulate`.
#[derive(Debug, Args)]
pub struct Iso9283SimulateArgs {
    #[command(flatten)]
    pub door: SpecArgs,
    /// The robot that moves (file or built-in name): a "true" robot, same units as the plan.
    #[arg(long, required_unless_present = "spec")]
    pub robot: Option<String>,
    /// The test poses (what `kinecal iso9283 plan --out` writes).
    #[arg(long, value_name = "POSES.csv", required_unless_present = "spec")]
    pub poses: Option<PathBuf>,
    /// Cycles (1 to 100,000) [default: 30].
    #[arg(long, value_name = "N")]
    pub cycles: Option<usize>,
    /// Gaussian noise on the attained poses: `length=L,angle=A` (robot file units; at most the
    /// robot's reach and half a turn).
    #[arg(long, value_name = "SPEC")]
    pub noise: Option<String>,
    /// Random seed, 0 to 2^63-1 (the same seed gives the same log on every machine).
    #[arg(long)]
    pub seed: Option<u64>,
    /// The log to write (CSV).
    #[arg(long, required_unless_present = "spec")]
    pub out: Option<PathBuf>,
}

/// `kinecal iso9283 evaluate`.
#[derive(Debug, Args)]
pub struct Iso9283EvaluateArgs {
    #[command(flatten)]
    pub door: SpecArgs,
    /// The log (CSV).
    #[arg(long, value_name = "LOG.csv", required_unless_present = "spec")]
    pub data: Option<PathBuf>,
    /// The log's length unit, when it states none (a label: nothing is converted).
    #[arg(long, value_name = "UNIT", value_parser = ["m", "mm", "in"])]
    pub length_unit: Option<String>,
    /// The log's angle unit, when it states none (needed with attitudes).
    #[arg(long, value_name = "UNIT", value_parser = ["deg", "rad"])]
    pub angle_unit: Option<String>,
    /// Write the figures as JSON here.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Write a self-contained HTML page here.
    #[arg(long, value_name = "FILE")]
    pub html: Option<PathBuf>,
    /// A calibrated robot (with --report): predict each pose's AP once compensated.
    #[arg(long, requires = "report")]
    pub robot: Option<String>,
    /// The calibrated robot's report (calibrated with --predict).
    #[arg(long, value_name = "REPORT.json", requires = "robot")]
    pub report: Option<PathBuf>,
    /// The target the log measured: ee (default: the report's) or a site.
    #[arg(long, requires = "report")]
    pub target: Option<String>,
}

/// The sweep of a curve.
#[derive(Debug, Args)]
pub struct SweepArgs {
    /// Parameters to sweep.
    #[arg(long, value_name = "LIST", required_unless_present = "spec")]
    pub param: Option<String>,
    /// Total width of the sweep, a positive number, centred on the nominal value (file units).
    #[arg(long, conflicts_with_all = ["from", "to"])]
    pub span: Option<f64>,
    /// Start of the sweep (with --to).
    #[arg(long, requires = "to", allow_hyphen_values = true)]
    pub from: Option<f64>,
    /// End of the sweep (with --from).
    #[arg(long, requires = "from", allow_hyphen_values = true)]
    pub to: Option<f64>,
    /// Samples per curve (3 to 100,000).
    #[arg(long)]
    pub points: Option<usize>,
    /// Output: .svg, .png or .csv, or - for the CSV on standard output.
    #[arg(long, required_unless_present = "spec")]
    pub out: Option<PathBuf>,
}

/// The spec door and the robot, shared by curves commands.
#[derive(Debug, Args)]
pub struct CurvesRobotArgs {
    #[command(flatten)]
    pub door: SpecArgs,
    /// Robot file or built-in name.
    #[arg(long, required_unless_present = "spec")]
    pub robot: Option<String>,
}

/// `kinecal curves pose`.
#[derive(Debug, Args)]
pub struct CurvesPoseArgs {
    #[command(flatten)]
    pub job: CurvesRobotArgs,
    /// Transducer readings, comma-separated.
    #[arg(long, allow_hyphen_values = true, conflicts_with = "postures")]
    pub readings: Option<String>,
    /// A postures (or measurement) file, with --posture.
    #[arg(long, requires = "posture")]
    pub postures: Option<PathBuf>,
    /// The posture label in --postures.
    #[arg(long)]
    pub posture: Option<String>,
    /// The frame: ee or a site name.
    #[arg(long)]
    pub site: Option<String>,
    #[command(flatten)]
    pub sweep: SweepArgs,
}

/// `kinecal curves objective`.
#[derive(Debug, Args)]
pub struct CurvesObjectiveArgs {
    #[command(flatten)]
    pub job: CurvesRobotArgs,
    #[command(flatten)]
    pub observations: ObservationFiles,
    #[command(flatten)]
    pub residuals: ResidualArgs,
    #[command(flatten)]
    pub sweep: SweepArgs,
}

/// `kinecal report`.
#[derive(Debug, Args)]
pub struct ReportArgs {
    #[command(flatten)]
    pub door: SpecArgs,
    /// Rebuild the HTML report of a calibration from its JSON report alone (`kinecal calibrate
    /// --report`): the page `calibrate --html` writes, nothing recomputed.
    #[arg(long, value_name = "REPORT.json", conflicts_with_all = ["robot", "calibrated", "calibration"])]
    pub from: Option<PathBuf>,
    /// The nominal robot (before calibration).
    #[arg(long)]
    pub robot: Option<String>,
    #[command(flatten)]
    pub observations: ObservationFiles,
    /// The calibrated robot file.
    #[arg(long, conflicts_with = "calibration")]
    pub calibrated: Option<String>,
    /// Or a calibration report (JSON from `kinecal calibrate --report`).
    #[arg(long)]
    pub calibration: Option<PathBuf>,
    #[command(flatten)]
    pub residuals: ResidualArgs,
    /// The HTML file to write.
    #[arg(long, visible_alias = "html", required_unless_present = "spec")]
    pub out: Option<PathBuf>,
    #[command(flatten)]
    pub shown: DisplayUnitsArgs,
}

/// `kinecal check`.
#[derive(Debug, Args)]
pub struct CheckArgs {
    #[command(flatten)]
    pub door: SpecArgs,
    /// The calibrated robot file.
    #[arg(long, required_unless_present = "spec")]
    pub robot: Option<String>,
    #[command(flatten)]
    pub observations: ObservationFiles,
    /// LENGTH[,ANGLE]: largest acceptable errors, in the robot file's units (not needed for
    /// pixels alone).
    #[arg(long, required_unless_present_any = ["spec", "pixel_threshold"])]
    pub threshold: Option<String>,
    /// Largest acceptable reprojection error of pixel observations, in pixels (required with
    /// them: pixels are not compared with a length).
    #[arg(long, value_name = "PX")]
    pub pixel_threshold: Option<f64>,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
}

/// `kinecal history ...`.
#[derive(Debug, Subcommand)]
pub enum HistoryCommand {
    /// Record an existing calibration report.
    #[command(
        after_help = "Example:\n  kinecal history add --robot-id A4-0042 --report report.json --at 2026-11-01"
    )]
    Add(Deferred<HistoryAddArgs>),
    /// List recorded calibrations (one robot or all).
    #[command(after_help = "Example:\n  kinecal history list --robot-id A4-0042")]
    List(Deferred<HistoryListArgs>),
    /// Show one calibration: by id, or the latest of a robot.
    #[command(
        after_help = "Example:\n  kinecal history show --robot-id A4-0042\n  kinecal history show --id 17"
    )]
    Show(Deferred<HistoryShowArgs>),
    /// Export the history as CSV (one row per parameter), JSON, or a dump for `history import`.
    #[command(
        after_help = "Examples:\n  kinecal history export --robot-id A4-0042 --format csv --out a4.csv\n  kinecal history export --format dump --out history.json   # every field, for history import"
    )]
    Export(Deferred<HistoryExportArgs>),
    /// Flag determined quantities that changed since the baseline (exit 0 none, 3 some).
    #[command(after_help = "\
Example:
  kinecal history drift --robot-id A4-0042 --sigma 3 --tolerance tolerances.toml --json

Tracks individually determined parameters and the determined combinations of redundant groups,
never a lone redundant parameter (it wanders between runs with no physical change). A tolerance
file has `key = value` lines, keys being parameter names or ids (link3.y, p14) or combination
expressions (\"p14 + p20\"), values in the quantity's unit.")]
    Drift(Deferred<HistoryDriftArgs>),
    /// Plot the history of each quantity with sigma bands and tolerance lines (SVG or PNG).
    #[command(
        after_help = "Example:\n  kinecal history plot --robot-id A4-0042 --out a4.svg\n\n\
Maintenance events are drawn as vertical lines; drift is computed since the latest one."
    )]
    Plot(Deferred<HistoryPlotArgs>),
    /// Every robot: last calibration, drift flags, trends, predicted tolerance crossings.
    #[command(after_help = "\
Examples:
  kinecal history fleet --tolerance tolerances.toml
  kinecal history fleet --db postgres://maint@db.plant/kinecal --tolerance tolerances.toml \\
      --html fleet.html --json fleet.json

One line per robot, most urgent first: FLAGGED (a determined quantity changed beyond its
tolerance or --sigma K standard deviations since the first calibration after the robot's latest
maintenance event), SERVICED (a maintenance event after its latest calibration), DUE (a trend
crosses a tolerance within --horizon days of --now), ok, or single (one calibration since its
latest event). The rate of each quantity is a weighted regression over that segment, per month
of 30 days with its standard error; a crossing is predicted when a tolerance applies and the
rate exceeds twice its standard error. --html writes a page with one chart per flagged or due
robot. Exit code 0 when every robot is ok, 3 when any is flagged, serviced or due.")]
    Fleet(Deferred<HistoryFleetArgs>),
    /// Record a maintenance event: drift is computed within the segments between events.
    #[command(after_help = "\
Example:
  kinecal history event A4-0042 --at 2026-11-15 --note \"gearbox J2 replaced\"

The calibrations at or after the event's time start a new segment: drift, trends and the fleet's
verdicts compare only calibrations of the same segment. The same event twice is recorded once.")]
    Event(Deferred<HistoryEventArgs>),
    /// List maintenance events.
    #[command(after_help = "Example:\n  kinecal history events --robot-id A4-0042")]
    Events(Deferred<HistoryListArgs>),
    /// Read a history dump (`history export --format dump`) into this history.
    #[command(after_help = "\
Example:
  kinecal history export --format dump --db history.sqlite --out history.json
  kinecal history import history.json --db postgres://maint@db.plant/kinecal

Every record and event is written verbatim (ids kept where free), each in its own transaction;
what is already there (the same idempotency key, or the same id and contents) is skipped, so an
interrupted import is finished by running it again.")]
    Import(Deferred<HistoryImportArgs>),
    /// Create the history's schema, or migrate it to this kinecal's version.
    #[command(after_help = "\
Example:
  kinecal history init --db postgres://owner@db.plant/kinecal

Any write creates or migrates the schema when it may; on a PostgreSQL server that takes the
database owner, so the owner runs this once (and after upgrading kinecal), then writers and
readers use their own roles.")]
    Init(Deferred<HistoryArgs>),
}

/// `kinecal history fleet`.
#[derive(Debug, Args)]
pub struct HistoryFleetArgs {
    #[command(flatten)]
    pub history: HistoryArgs,
    /// Flag changes beyond K standard deviations [default: 3].
    #[arg(long, value_name = "K")]
    pub sigma: Option<f64>,
    /// Tolerance file (TOML `key = value`), the same for every robot.
    #[arg(long, value_name = "FILE")]
    pub tolerance: Option<PathBuf>,
    /// A robot is due when a trend crosses a tolerance within this many days of --now
    /// [default: 90].
    #[arg(long, value_name = "DAYS")]
    pub horizon: Option<f64>,
    /// "Now" for --horizon (RFC 3339 or YYYY-MM-DD; default: the current time).
    #[arg(long, value_name = "TIME")]
    pub now: Option<String>,
    /// Also write the fleet as JSON here.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Also write an HTML page here (one chart per flagged or due robot).
    #[arg(long, value_name = "FILE")]
    pub html: Option<PathBuf>,
}

/// `kinecal history event`.
#[derive(Debug, Args)]
pub struct HistoryEventArgs {
    #[command(flatten)]
    pub history: HistoryArgs,
    /// The robot's serial number (at most 128 characters).
    #[arg(required_unless_present = "spec")]
    pub robot_id: Option<String>,
    /// When (RFC 3339 or YYYY-MM-DD; default now).
    #[arg(long)]
    pub at: Option<String>,
    /// What was done (e.g. "gearbox J2 replaced"; at most 1,000 characters).
    #[arg(long, required_unless_present = "spec")]
    pub note: Option<String>,
}

/// `kinecal history import`.
#[derive(Debug, Args)]
pub struct HistoryImportArgs {
    #[command(flatten)]
    pub history: HistoryArgs,
    /// The dump (`kinecal history export --format dump`).
    #[arg(required_unless_present = "spec")]
    pub dump: Option<PathBuf>,
}

/// The spec door and the history, shared by history commands.
#[derive(Debug, Args)]
pub struct HistoryArgs {
    #[command(flatten)]
    pub door: SpecArgs,
    /// The history: a SQLite file, or a PostgreSQL server as postgres://USER@HOST:PORT/DBNAME
    /// (password from PGPASSWORD or ~/.pgpass; never printed). Default: $KINECAL_DB, else
    /// kinecal/history.sqlite in the user's data folder.
    #[arg(long, value_name = "PATH|URL")]
    pub db: Option<PathBuf>,
}

/// `kinecal history add`.
#[derive(Debug, Args)]
pub struct HistoryAddArgs {
    #[command(flatten)]
    pub history: HistoryArgs,
    /// The robot's serial number (at most 128 characters).
    #[arg(long, required_unless_present = "spec")]
    pub robot_id: Option<String>,
    /// A report written by `kinecal calibrate --report`.
    #[arg(long, required_unless_present = "spec")]
    pub report: Option<PathBuf>,
    /// When (RFC 3339 or YYYY-MM-DD; default now).
    #[arg(long)]
    pub at: Option<String>,
    /// A note (at most 1,000 characters).
    #[arg(long)]
    pub note: Option<String>,
    /// Record it even if the robot model differs from the earlier records of this serial
    /// (the robot was rebuilt: other joints, other parameters).
    #[arg(long)]
    pub force: bool,
}

/// `kinecal history list` and `kinecal history events`: the calibrations or the events of one
/// robot or all.
#[derive(Debug, Args)]
pub struct HistoryListArgs {
    #[command(flatten)]
    pub history: HistoryArgs,
    /// Only this robot.
    #[arg(long)]
    pub robot_id: Option<String>,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
}

/// `kinecal history show`.
#[derive(Debug, Args)]
pub struct HistoryShowArgs {
    #[command(flatten)]
    pub history: HistoryArgs,
    /// The latest calibration of this robot.
    #[arg(long, required_unless_present_any = ["id", "spec"])]
    pub robot_id: Option<String>,
    /// A calibration by id.
    #[arg(long)]
    pub id: Option<i64>,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
}

/// `kinecal history export`.
#[derive(Debug, Args)]
pub struct HistoryExportArgs {
    #[command(flatten)]
    pub history: HistoryArgs,
    /// Only this robot.
    #[arg(long)]
    pub robot_id: Option<String>,
    /// Format: csv (one row per calibration and parameter), json (every calibration with its
    /// parameters and combinations) or dump (every stored field, for `history import`)
    /// [default: csv].
    #[arg(long, value_enum)]
    pub format: Option<kinecal::spec::HistoryFormat>,
    /// Write here instead of standard output.
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// `kinecal history drift`.
#[derive(Debug, Args)]
pub struct HistoryDriftArgs {
    #[command(flatten)]
    pub history: HistoryArgs,
    /// The robot.
    #[arg(long, required_unless_present = "spec")]
    pub robot_id: Option<String>,
    /// first, latest-ok, or a calibration id [default: first].
    #[arg(long)]
    pub baseline: Option<String>,
    /// Flag changes beyond K standard deviations [default: 3].
    #[arg(long, value_name = "K")]
    pub sigma: Option<f64>,
    /// Tolerance file (TOML `key = value`).
    #[arg(long, value_name = "FILE")]
    pub tolerance: Option<PathBuf>,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
}

/// `kinecal history plot`.
#[derive(Debug, Args)]
pub struct HistoryPlotArgs {
    #[command(flatten)]
    pub history: HistoryArgs,
    /// The robot.
    #[arg(long, required_unless_present = "spec")]
    pub robot_id: Option<String>,
    /// Only these quantities (parameter names or ids, or combination expressions), comma-separated.
    #[arg(long, value_name = "LIST")]
    pub param: Option<String>,
    /// Tolerance file, drawn as lines around the first value.
    #[arg(long, value_name = "FILE")]
    pub tolerance: Option<PathBuf>,
    /// The file to write: .svg or .png (by its extension).
    #[arg(long, required_unless_present = "spec")]
    pub out: Option<PathBuf>,
}

/// `kinecal import urdf`.
#[derive(Debug, Args)]
pub struct ImportUrdfArgs {
    #[command(flatten)]
    pub door: SpecArgs,
    /// The URDF file (plain URDF; expand xacro first).
    #[arg(required_unless_present = "spec")]
    pub file: Option<PathBuf>,
    /// First link of the chain (default: the root link).
    #[arg(long)]
    pub base: Option<String>,
    /// Last link of the chain (default: the only leaf link). Given more than once, a tree: every
    /// tip's chain, the joints they share once; the last tip is the end effector, the others
    /// become sites named after their links.
    #[arg(long)]
    pub tip: Vec<String>,
    /// Take the links' `<inertial>` masses and centres of mass as the robot's mass model, so that
    /// its joint compliances can be estimated (`--estimate identifiable,compliance`).
    #[arg(long)]
    pub masses: bool,
    #[command(flatten)]
    pub written: ImportOutArgs,
}

/// `kinecal export`.
#[derive(Debug, Subcommand)]
pub enum ExportCommand {
    /// Write a calibrated robot into the URDF it was imported from.
    #[command(after_help = "\
Example:
  kinecal export urdf --robot calibrated.toml --template ur5_robot.urdf --base base_link \\
      --tip tool0 --out ur5_calibrated.urdf

Only the <origin> of the chain's movable joints (and of the first fixed joint after the last one,
for the tool frame) change, a joint without one gets one; visuals, inertias, limits, comments,
formatting and a byte-order mark are kept. Joint offsets are folded into the origins. The URDF is
read back and compared with the robot over the joint ranges (the largest deviation is printed);
beyond --tolerance nothing is written. A slope other than 1 cannot be expressed in URDF.")]
    Urdf(Deferred<ExportUrdfArgs>),
    /// Write a calibrated robot as ROS 2 description files: a calibration YAML, the URDF as a
    /// xacro that reads it, and static transforms of the measurement frames.
    #[command(after_help = "\
Example:
  kinecal export ros --robot calibrated.toml --template ur10_robot.urdf \\
      --base base_link --tip tool0 --out ur10_description

Writes into the folder (made when missing):
  calibration.yaml             each joint of the chains from the base to the tips: its origin
                               x, y, z, roll, pitch, yaw as calibrated (metres, radians); the
                               robot's name; a hash of the values
  <robot>.urdf.xacro           the template, those origins read from calibration.yaml by
                               xacro.load_yaml (the argument calibration:=FILE names another,
                               relative to the xacro's folder)
  static_transforms.yaml       the frame the robot was measured in (--measurement-frame) in the
                               base link, and each session's frame in it: parent, child, x, y, z,
                               qx, qy, qz, qw
  static_transforms.launch.py  a tf2_ros static_transform_publisher per transform of the YAML

The URDF keeps the template's base: what the calibration put before it is the measurement
frame's transform. Joint offsets are folded into the origins. The xacro, expanded with the YAML
as written, is read back and compared with the robot over the joint ranges; beyond --tolerance
nothing is written.")]
    Ros(Deferred<ExportRosArgs>),
    /// Write a calibrated UR arm as a Universal Robots kinematics file for the ROS driver.
    #[command(after_help = "\
Example:
  kinecal export ur --robot calibrated.toml --template default_kinematics.yaml \\
      --out my_robot_calibration.yaml

The robot must have been imported from the template (kinecal import ur). Joint offsets are
folded into the origins exactly. The controller's base stays the template's: the measurement
frame the calibration put into the robot's first link (where the instrument saw it) and any
session frames are left out, and said. The tool correction is printed as the TCP to enter on the
controller (mm and rotation vector, and as set_tcp). The file, with that TCP, is read back and
compared with the robot over the joint ranges; what it cannot hold (transducer slopes other than
1, couplings) is named with its deviation, and beyond --tolerance nothing is written.")]
    Ur(Deferred<ExportUrArgs>),
    /// Write the joint offsets and slopes as a table, for controllers that take only those.
    #[command(after_help = "\
Example:
  kinecal export joints --robot calibrated.toml --nominal nominal.toml --out joints.csv

Writes joint,offset,slope,offset_change,slope_change (the robot file's units: the joint value at
zero reading, joint units per reading unit, and their change from the nominal robot). The table
is read back onto the nominal robot and compared with the calibrated one over the joint ranges:
what a joint table cannot carry (link and tool changes, couplings) is the largest deviation it
leaves at the tool, and beyond --tolerance nothing is written.")]
    Joints(Deferred<ExportJointsArgs>),
    /// Write a robot as a Denavit-Hartenberg table, read back and compared before it is written.
    #[command(after_help = "\
Example:
  kinecal export dh --robot calibrated.toml --convention modified --out calibrated_dh.csv

Writes kind,a,alpha,d,theta per joint (and beta when a pair of consecutive axes is within 1 deg of
parallel: the Hayati/Mooring extension, where the classical common normal runs off to metres or
kilometres), in the robot file's units or --length-unit/--angle-unit, stated in comment lines
that kinecal import dh reads. A base or tool frame the DH frames cannot be is a `fixed` row. The
table is read back and compared with the robot over the joint ranges (the largest deviation is
printed); what DH cannot hold (transducer slopes other than 1, couplings: the table's joint
variables are the readings) is named, and beyond --tolerance nothing is written.")]
    Dh(Deferred<ExportDhArgs>),
    /// Write the joint compliances and stiffnesses of an elastic robot's calibration, with
    /// their standard deviations, as a table.
    #[command(after_help = "\
Example:
  kinecal export stiffness --report report.json --out stiffness.csv

Reads the report of a calibration of a robot with a mass model (kinecal calibrate --report) and
writes parameter,joint,axis,compliance,compliance_sigma,stiffness,stiffness_sigma,stiffness_unit,
estimated: one row per compliance (axis `joint` or `lateral`), compliance in the robot file's
angle unit per newton and length unit, stiffness its inverse (empty when the compliance is not
positive), sigmas empty where the data does not determine them.")]
    Stiffness(Deferred<ExportStiffnessArgs>),
    /// Write the 3-D scene of a calibration as glTF 2.0 binary (GLB): the calibrated and the
    /// nominal robot at a posture, the measured points, their residuals, the frames.
    #[command(after_help = "\
Example:
  kinecal export gltf --robot calibrated.toml --report report.json --data data.csv --out scene.glb

The scene the HTML report's 3-D view draws, for any glTF viewer (Blender, three.js, a browser's
model viewer): one node per layer under a root that turns the robot's z up into glTF's y up,
metres. Layers: the calibrated robot's links (lines, blue) and joints (points), the nominal
robot's links (grey), the measured points, the residual vectors after and before calibration
(lines, red and orange, scaled as said), the axes of the global, session and tool frames (red,
green, blue). With --report alone, the report's own scene (calibrate --html puts it there);
with --data, the points and residuals of those observations: before calibration from --nominal,
or the report's initial values. At most 2,000 points: the largest residuals, then an even
spread of the rest (the count is said).")]
    Gltf(Deferred<ExportGltfArgs>),
    /// Write a camera's lens as the ROS camera_info YAML (camera_calibration_parsers' format).
    #[command(after_help = "\
Example:
  kinecal export camera-info --robot calibrated.toml --camera wrist --out wrist.yaml

Writes image_width, image_height, camera_name, camera_matrix (fx, 0, cx, 0, fy, cy, 0, 0, 1),
distortion_model plumb_bob, distortion_coefficients (k1, k2, p1, p2, k3), rectification_matrix
(the identity: a monocular camera) and projection_matrix (fx, 0, cx, 0, 0, fy, cy, 0, 0, 0, 1, 0),
every number with all its digits, as ROS's camera_info_manager and image_proc read it. The file
is read back and compared with the robot file's camera before it is written. The camera's pose
(hand-eye) is not part of camera_info: it is in the calibrated robot file.")]
    CameraInfo(Deferred<ExportCameraInfoArgs>),
}

/// `kinecal export camera-info`.
#[derive(Debug, Args)]
pub struct ExportCameraInfoArgs {
    #[command(flatten)]
    pub door: SpecArgs,
    /// The (calibrated) robot file with the camera.
    #[arg(long, required_unless_present = "spec")]
    pub robot: Option<String>,
    /// The camera, by name (default: the robot file's only camera).
    #[arg(long, value_name = "NAME")]
    pub camera: Option<String>,
    /// The YAML file to write.
    #[arg(long, value_name = "FILE.yaml", required_unless_present = "spec")]
    pub out: Option<PathBuf>,
}

/// `kinecal export gltf`.
#[derive(Debug, Args)]
pub struct ExportGltfArgs {
    #[command(flatten)]
    pub door: SpecArgs,
    /// The calibrated robot file.
    #[arg(long, required_unless_present = "spec")]
    pub robot: Option<String>,
    /// The calibration report (JSON from `kinecal calibrate --report`): its scene, or its
    /// initial values as the nominal robot.
    #[arg(long, value_name = "REPORT.json")]
    pub report: Option<PathBuf>,
    /// The nominal robot (before calibration), drawn beside the calibrated one.
    #[arg(long)]
    pub nominal: Option<String>,
    #[command(flatten)]
    pub observations: ObservationFiles,
    /// The posture the robots are drawn at, by label (default: the first measured).
    #[arg(long, value_name = "LABEL")]
    pub posture: Option<String>,
    /// The GLB file to write.
    #[arg(long, value_name = "FILE.glb", required_unless_present = "spec")]
    pub out: Option<PathBuf>,
}

/// `kinecal export stiffness`.
#[derive(Debug, Args)]
pub struct ExportStiffnessArgs {
    #[command(flatten)]
    pub door: SpecArgs,
    /// The calibration report (JSON) of an elastic robot.
    #[arg(long, required_unless_present = "spec")]
    pub report: Option<PathBuf>,
    /// The table to write (CSV).
    #[arg(long, required_unless_present = "spec")]
    pub out: Option<PathBuf>,
}

/// `kinecal export dh`.
#[derive(Debug, Args)]
pub struct ExportDhArgs {
    #[command(flatten)]
    pub door: SpecArgs,
    /// The robot file (TOML) or built-in robot name.
    #[arg(long, required_unless_present = "spec")]
    pub robot: Option<String>,
    /// DH convention of the table.
    #[arg(long, value_enum, required_unless_present = "spec")]
    pub convention: Option<Convention>,
    /// Length unit of the table (default: the robot file's); written into it.
    #[arg(long)]
    pub length_unit: Option<String>,
    /// Angle unit of the table and of its joint values (default: the robot file's); written
    /// into it.
    #[arg(long)]
    pub angle_unit: Option<String>,
    #[command(flatten)]
    pub read_back: ReadBackArgs,
    /// The table to write (CSV).
    #[arg(long, required_unless_present = "spec")]
    pub out: Option<PathBuf>,
}

/// `kinecal export joints`.
#[derive(Debug, Args)]
pub struct ExportJointsArgs {
    #[command(flatten)]
    pub door: SpecArgs,
    /// The calibrated robot.
    #[arg(long, required_unless_present = "spec")]
    pub robot: Option<String>,
    /// The nominal robot (what the controller uses).
    #[arg(long, required_unless_present = "spec")]
    pub nominal: Option<String>,
    #[command(flatten)]
    pub read_back: ReadBackArgs,
    /// The table to write (CSV).
    #[arg(long, required_unless_present = "spec")]
    pub out: Option<PathBuf>,
}

/// `kinecal export ur`.
#[derive(Debug, Args)]
pub struct ExportUrArgs {
    #[command(flatten)]
    pub door: SpecArgs,
    /// The calibrated robot file (imported from the template).
    #[arg(long, required_unless_present = "spec")]
    pub robot: Option<String>,
    /// The kinematics file the robot was imported from.
    #[arg(long, required_unless_present = "spec")]
    pub template: Option<PathBuf>,
    #[command(flatten)]
    pub read_back: ReadBackArgs,
    /// The kinematics file to write.
    #[arg(long, required_unless_present = "spec")]
    pub out: Option<PathBuf>,
}

/// `kinecal export ros`.
#[derive(Debug, Args)]
pub struct ExportRosArgs {
    #[command(flatten)]
    pub door: SpecArgs,
    /// The calibrated robot file (imported from the template).
    #[arg(long, required_unless_present = "spec")]
    pub robot: Option<String>,
    /// The original URDF.
    #[arg(long, required_unless_present = "spec")]
    pub template: Option<PathBuf>,
    /// First link of the chain, as at import.
    #[arg(long)]
    pub base: Option<String>,
    /// Last link of the chain, as at import (each tip of a tree, in the order of the import).
    #[arg(long)]
    pub tip: Vec<String>,
    /// Name of the frame the robot was measured in (default: measurement).
    #[arg(long, value_name = "FRAME")]
    pub measurement_frame: Option<String>,
    #[command(flatten)]
    pub read_back: ReadBackArgs,
    /// The folder to write the files into.
    #[arg(long, value_name = "DIR", required_unless_present = "spec")]
    pub out: Option<PathBuf>,
}

/// `kinecal export urdf`.
#[derive(Debug, Args)]
pub struct ExportUrdfArgs {
    #[command(flatten)]
    pub door: SpecArgs,
    /// The calibrated robot file (imported from the template).
    #[arg(long, required_unless_present = "spec")]
    pub robot: Option<String>,
    /// The original URDF.
    #[arg(long, required_unless_present = "spec")]
    pub template: Option<PathBuf>,
    /// First link of the chain, as at import.
    #[arg(long)]
    pub base: Option<String>,
    /// Last link of the chain, as at import (each tip of a tree, in the order of the import).
    #[arg(long)]
    pub tip: Vec<String>,
    #[command(flatten)]
    pub read_back: ReadBackArgs,
    /// The URDF to write.
    #[arg(long, required_unless_present = "spec")]
    pub out: Option<PathBuf>,
}

/// The robot file an import writes (shared by the imports).
#[derive(Debug, Args)]
pub struct ImportOutArgs {
    /// The robot file to write.
    #[arg(long, required_unless_present = "spec")]
    pub out: Option<PathBuf>,
}

/// `kinecal import poe`.
#[derive(Debug, Args)]
pub struct ImportPoeArgs {
    #[command(flatten)]
    pub door: SpecArgs,
    /// The product-of-exponentials file (TOML).
    #[arg(required_unless_present = "spec")]
    pub file: Option<PathBuf>,
    #[command(flatten)]
    pub written: ImportOutArgs,
}

/// `kinecal import dh`.
#[derive(Debug, Args)]
pub struct ImportDhArgs {
    #[command(flatten)]
    pub door: SpecArgs,
    /// The table (CSV `kind,a,alpha,d,theta[,beta]`).
    #[arg(required_unless_present = "spec")]
    pub file: Option<PathBuf>,
    /// Which convention the table uses (required when the table does not state it).
    #[arg(long, value_enum)]
    pub convention: Option<Convention>,
    /// Length unit of the table (and of the robot file written); required when the table does
    /// not state it.
    #[arg(long)]
    pub length_unit: Option<String>,
    /// Angle unit of the table (and of the robot file written); required when the table does
    /// not state it.
    #[arg(long)]
    pub angle_unit: Option<String>,
    /// Robot name (default: the table's file name without its extension).
    #[arg(long)]
    pub name: Option<String>,
    #[command(flatten)]
    pub written: ImportOutArgs,
}

/// `kinecal analyze`.
#[derive(Debug, Args)]
pub struct AnalyzeArgs {
    #[command(flatten)]
    pub door: SpecArgs,
    /// Robot file (TOML) or built-in robot name: the model, analysed at its parameter values.
    #[arg(long, required_unless_present = "spec")]
    pub robot: Option<String>,
    #[command(flatten)]
    pub observations: ObservationFiles,
    /// Postures file instead of observations: full poses of the end effector and every site are
    /// assumed.
    #[arg(long)]
    pub postures: Option<PathBuf>,
    /// Parameters to analyse (default: the default set of `calibrate`, so that the identifiable
    /// set shown is the one `calibrate --estimate identifiable` estimates; `all` for every one).
    #[arg(long, value_name = "LIST")]
    pub estimate: Option<String>,
    /// Parameters to leave out.
    #[arg(long, value_name = "LIST")]
    pub fix: Option<String>,
    /// Parameters to prefer in the identifiable set, most preferred first (default order: joint
    /// offsets, slopes, non-zero link lengths, non-zero link angles, zero-valued link components,
    /// sites).
    #[arg(long, value_name = "LIST")]
    pub priority: Option<String>,
    /// Relative singular-value tolerance for the numerical rank [default: 1e-9].
    #[arg(long, value_name = "X")]
    pub rcond: Option<f64>,
    /// Analyse the data with a Gaussian prior on the changes, as `calibrate --prior` fits it
    /// (`length=L,angle=A[,slope=F][,compliance=C]`, `tolerances`, `none`): the rank of both
    /// together, and which parameters the prior alone determines [default: the robot file's
    /// [priors], else none].
    #[arg(long, value_name = "PRIOR")]
    pub prior: Option<String>,
    /// The bodies' total mass (kg), held as `calibrate --total-mass` holds it.
    #[arg(long, value_name = "KG")]
    pub total_mass: Option<f64>,
    #[command(flatten)]
    pub residuals: ResidualArgs,
    /// Print a matrix as well.
    #[arg(long, value_enum)]
    pub print: Option<MatrixKind>,
    /// Units of the printed matrix.
    #[arg(long, value_enum)]
    pub units: Option<MatrixUnits>,
    /// Print a JSON document instead of text.
    #[arg(long)]
    pub json: bool,
}

/// `kinecal compensate`.
#[derive(Debug, Args)]
pub struct CompensateArgs {
    #[command(flatten)]
    pub door: SpecArgs,
    /// The calibrated robot (TOML) or built-in robot name: how the robot really moves.
    #[arg(long, required_unless_present = "spec")]
    pub robot: Option<String>,
    /// The nominal robot the controller uses (and the program was made with).
    #[arg(long, required_unless_present = "spec")]
    pub nominal: Option<String>,
    /// The program (posture,v1,...,vn), the targets (target,x,y,z[,alpha,beta,gamma]...), or a
    /// measurement file (its measured poses are the targets, its readings their seeds).
    #[arg(long = "in", value_name = "FILE", required_unless_present = "spec")]
    pub input: Option<PathBuf>,
    /// The frame that must reach the goal: `ee` (default) or a site of the robot. A program of
    /// a tree may name one tool per branch, comma-separated (`ee,LEFT_tool0`): each reaches its
    /// pose with its own branch's joints, the joints the branches share held as programmed.
    #[arg(long)]
    pub site: Option<String>,
    /// Reach the positions only: a program's meant positions, or the targets' positions with
    /// their attitudes left out (the attitude then changes as little as it can).
    #[arg(long)]
    pub position_only: bool,
    /// Largest acceptable remaining error: `length=L,angle=A` (file units; default 1 um and 1
    /// urad).
    #[arg(long, value_name = "SPEC")]
    pub tolerance: Option<String>,
    /// Flag solutions whose weighted reading Jacobian has a smallest singular value below this
    /// fraction of its largest [default: 1e-3].
    #[arg(long, value_name = "X")]
    pub singular: Option<f64>,
    /// Flag a revolute joint that turns more than this from the seed (the file's angle unit;
    /// default 0.5 rad).
    #[arg(long, value_name = "ANGLE")]
    pub branch: Option<f64>,
    /// The configuration Cartesian targets must be in: `shoulder=front|back`, `elbow=up|down`,
    /// `wrist=noflip|flip` (any of them, comma-separated; an arm of six revolute joints), or a
    /// sign pattern of the joint values, one of `+`, `-`, `*` per joint (`+,*,-,*,+,*`).
    #[arg(long, value_name = "SPEC", allow_hyphen_values = true)]
    pub configuration: Option<String>,
    /// What to write: `table` (the readings with each row's remaining errors and flags),
    /// `urscript` (a UR program of movej), a controller's joint targets: `joints-ur` (rad),
    /// `joints-abb`, `joints-kuka`, `joints-fanuc` (deg), or a controller's program of one joint
    /// move per row (deg, six axes): `krl` (KUKA .src, PTP), `rapid` (ABB module, MoveAbsJ),
    /// `tp` (FANUC TP in ASCII, .ls). A controller program is written only when no row is
    /// flagged, and is read back before it is written.
    #[arg(long, value_enum)]
    pub format: Option<ProgramFormat>,
    /// The name of a krl, rapid or tp program: letters, digits and _, a letter first, at most
    /// 24 (KRL), 32 (RAPID) or 36 (TP, written in capitals) characters [default: the --out
    /// file's name without its extension; a KRL module's DEF must name its file].
    #[arg(long, value_name = "NAME")]
    pub name: Option<String>,
    /// The speed of a krl, rapid or tp program's moves: KRL percent of each axis's maximum
    /// velocity ($VEL_AXIS, 1 to 100), RAPID the TCP speed of a predefined speeddata (v5 to
    /// v7000, mm/s), TP percent (1 to 100) [default: 100].
    #[arg(long, value_name = "N")]
    pub speed: Option<f64>,
    /// How a krl, rapid or tp program's moves end: `fine` (exactly at each point), or
    /// approximated: KRL C_PTP with $APO.CPTP percent (1 to 100), RAPID zonedata zN (N mm: 0,
    /// 1, 5, 10, 15, 20, 30, 40, 50, 60, 80, 100, 150, 200), TP CNTn (0 to 100); the last move
    /// ends exactly [default: fine].
    #[arg(long, value_name = "fine|N")]
    pub zone: Option<String>,
    /// The file to write.
    #[arg(long, value_name = "FILE", required_unless_present = "spec")]
    pub out: Option<PathBuf>,
}

/// `kinecal batch`.
#[derive(Debug, Args)]
pub struct BatchArgs {
    /// The manifest: CSV (serial,robot,data[,options]) or TOML ([[robots]] tables, each a
    /// calibration spec with its serial, over a [defaults] table).
    pub manifest: PathBuf,
    /// Robots calibrated at once (default: one per core; more than two per core run two per
    /// core, with a note).
    #[arg(long, value_name = "N")]
    pub jobs: Option<usize>,
    /// Record every calibration in the history under its serial (see --db).
    #[arg(long)]
    pub record: bool,
    /// The history for --record: a SQLite file or a postgres:// URL (default: $KINECAL_DB,
    /// else the user's data folder).
    #[arg(long, value_name = "PATH|URL", requires = "record")]
    pub db: Option<PathBuf>,
    /// Run only the K-th of N shares of the manifest (1 <= K <= N): its robots K, K+N, K+2N,
    /// ... in manifest order, so N machines with K = 1..N run every robot exactly once.
    #[arg(long, value_name = "K/N")]
    pub shard: Option<String>,
    /// Also write the summary as CSV.
    #[arg(long, value_name = "FILE")]
    pub summary: Option<PathBuf>,
    /// Also write each job's document (what its command's `--json` or report gives) into this
    /// folder, as NAME.json (the robot's serial or the job's name; characters other than
    /// letters, digits, `.`, `_` and `-` written `_`).
    #[arg(long, value_name = "DIR")]
    pub documents: Option<PathBuf>,
    /// No progress bar: the global `--quiet`.
    #[arg(skip)]
    pub quiet: bool,
}

/// `kinecal plan`.
#[derive(Debug, Args)]
pub struct PlanArgs {
    #[command(flatten)]
    pub door: SpecArgs,
    /// Robot file (TOML) or built-in robot name: the nominal model the plan is made for.
    #[arg(long, required_unless_present = "spec")]
    pub robot: Option<String>,
    /// Candidate postures: a postures file (posture,v1,...,vn) or an observation file (what
    /// each row measures is what the plan assumes).
    #[arg(long, value_name = "FILE", conflicts_with = "sample")]
    pub candidates: Option<PathBuf>,
    /// Sample this many candidate postures uniformly within the joint ranges instead (1 to
    /// 1,000,000).
    #[arg(long, value_name = "N")]
    pub sample: Option<usize>,
    /// Random seed of the sample and of the random plans compared with (0 to 2^63-1).
    #[arg(long)]
    pub seed: Option<u64>,
    /// How many postures to choose (besides the kept ones).
    #[arg(long, value_name = "K", required_unless_present = "spec")]
    pub count: Option<usize>,
    /// What the plan maximises.
    #[arg(long, value_enum)]
    pub criterion: Option<Criterion>,
    /// The targets measure positions only (a laser tracker) rather than full poses: for
    /// postures (sampled or a postures file), and for an observation file whose poses are then
    /// read as positions.
    #[arg(long)]
    pub position_only: bool,
    /// For postures: the targets measured at each, `ee` for the end effector and site names
    /// (default: every site of the robot, or the end effector when it has none).
    #[arg(long, value_name = "LIST")]
    pub sites: Option<String>,
    /// Parameters to determine (as calibrate's --estimate; default `identifiable`).
    #[arg(long, value_name = "LIST")]
    pub estimate: Option<String>,
    /// Parameters to leave out.
    #[arg(long, value_name = "LIST")]
    pub fix: Option<String>,
    /// Postures already measured (a postures file or an observation file): always in the plan.
    #[arg(long, value_name = "FILE")]
    pub keep: Option<PathBuf>,
    #[command(flatten)]
    pub residuals: ResidualArgs,
    /// Print a JSON document instead of text.
    #[arg(long)]
    pub json: bool,
    /// Also write an HTML page of the plan (the postures in joint space, the information each
    /// carries).
    #[arg(long, value_name = "FILE")]
    pub html: Option<PathBuf>,
    /// The file to write the chosen postures to.
    #[arg(long, value_name = "FILE", required_unless_present = "spec")]
    pub out: Option<PathBuf>,
}

/// How residuals are formed (shared by analyze and calibrate).
#[derive(Debug, Args)]
pub struct ResidualArgs {
    /// Orientation residual [default: rotvec].
    #[arg(long, value_enum)]
    pub orientation_error: Option<OrientationError>,
    /// Measurement standard deviations weighting the residuals: `length=L,angle=A` (file units;
    /// default 1 mm and 1 mrad).
    #[arg(long, value_name = "SPEC")]
    pub weights: Option<String>,
}

/// `kinecal calibrate`.
#[derive(Debug, Args)]
pub struct CalibrateArgs {
    #[command(flatten)]
    pub door: SpecArgs,
    /// Nominal robot file (TOML) or built-in robot name: the model and the starting point.
    #[arg(long, required_unless_present = "spec")]
    pub robot: Option<String>,
    #[command(flatten)]
    pub observations: ObservationFiles,
    /// Least-squares method [default: lm].
    #[arg(long, value_enum)]
    pub method: Option<Method>,
    /// Parameters to estimate. Default: links, offsets, sites and, unless every slope is 1
    /// (readings that are already joint values), slopes; couplings and planes only when named.
    #[arg(long, value_name = "LIST")]
    pub estimate: Option<String>,
    /// Parameters to hold at their nominal values (removed from --estimate).
    #[arg(long, value_name = "LIST")]
    pub fix: Option<String>,
    /// A Gaussian prior on each estimated parameter's change from its start:
    /// `length=L,angle=A[,slope=F][,compliance=C]` standard deviations in the robot file's units
    /// (slopes as a fraction), with per-parameter entries `NAME=V`; `tolerances` takes the robot
    /// file's [tolerances], `none` none. One residual row per parameter: what the data cannot
    /// determine the prior holds, so any selection (`--estimate all`) can be solved [default:
    /// the robot file's [priors], else none].
    #[arg(long, value_name = "PRIOR")]
    pub prior: Option<String>,
    /// The bodies' total mass (kg) of an elastic robot, held while their masses are estimated
    /// (`--estimate ...,masses`): it fixes their scale, which positions alone cannot tell from
    /// the compliances' (without it, one mass is held and the rest are relative to it).
    /// Refused when the selection estimates no mass (the default parameters do not).
    #[arg(long, value_name = "KG")]
    pub total_mass: Option<f64>,
    /// Iteration cap of each fit, 1 to 1,000,000 (default 100; 5000 for sd); the model-error
    /// floor's and the Huber loss's refits each get it, and the iterations reported are all
    /// the fits'.
    #[arg(long, value_name = "N")]
    pub max_iter: Option<usize>,
    #[command(flatten)]
    pub residuals: ResidualArgs,
    /// Which answer to return when some parameters are undetermined: the solver's, or the one
    /// closest to the --robot file [default: solver].
    #[arg(long, value_enum)]
    pub solution: Option<SolutionRule>,
    /// Start the solver from this robot file instead of --robot (which stays the nominal model).
    #[arg(long, value_name = "GUESS.toml")]
    pub initial: Option<String>,
    /// Then refit, removing one at a time the least significant change while it is below K
    /// standard deviations; both fits are reported.
    #[arg(long, value_name = "K")]
    pub prune: Option<f64>,
    /// Choose the model by cross-validation: fit each candidate (`LIST [fix=LIST] [prune=K]
    /// [prior=PRIOR]`, listed from the simplest up: the strongest prior first) under the same
    /// --folds (default 5) and keep the first whose held-out mean is within one standard error
    /// of the best. Without candidates: the identifiable geometric set (slopes held), + slopes,
    /// + pruning at 2 and 3 sigma.
    #[arg(
        long,
        num_args = 0..,
        value_name = "CANDIDATE",
        conflicts_with_all = ["estimate", "prune", "holdout"]
    )]
    pub choose: Option<Vec<String>>,
    /// Held-out observation file, repeatable: measurements (read like --data), distances or
    /// contacts, told apart by their header. Reports the accuracy on them before and after.
    #[arg(long, value_name = "V.csv", conflicts_with = "holdout")]
    pub validate: Vec<PathBuf>,
    /// Hold out this fraction of the postures (drawn with --seed; postures an observation links
    /// stay together) for validation.
    #[arg(long, value_name = "FRACTION", conflicts_with = "folds")]
    pub holdout: Option<f64>,
    /// Cross-validate: calibrate on all the data, and run the same calibration on K folds of
    /// the postures, each checked on the postures it left out (interleaved in file order, so
    /// every fold samples every sweep; shuffled with --seed). Reports each fold's held-out
    /// errors, the overall ones and a bootstrap 95 % interval of the held-out mean.
    #[arg(long, value_name = "K")]
    pub folds: Option<usize>,
    /// Seed for --holdout (default 1) or --folds (default: no shuffle); 0 to 2^63-1, what a
    /// spec file holds.
    #[arg(long)]
    pub seed: Option<u64>,
    /// With --choose: repeat the cross-validation over this many shuffles of the postures (the
    /// first as --seed says, the others with the seeds after it), so that the choice does not
    /// hang on one split (1 to 100) [default: 5].
    #[arg(long, value_name = "N")]
    pub repeats: Option<usize>,
    /// Predict the calibrated robot's accuracy over the workspace: a model-error term fitted by
    /// cross-validation, the predicted 95 % bound's median and 95th percentile over the joint
    /// ranges in the summary and the report (what `kinecal predict` needs), and with `--html`
    /// the page's accuracy map. Costs some 13 more fits, so `--html` alone does not ask for it.
    #[arg(long)]
    pub predict: bool,
    /// Loss on the weighted residuals: least squares, or Huber (robust to a few bad rows)
    /// [default: squared].
    #[arg(long, value_enum)]
    pub loss: Option<LossKind>,
    /// Rows with sigma columns: weighted by max(sigma, m), the model error m estimated from the
    /// residuals when they show more than the sigmas (auto), or by the sigmas alone (none)
    /// [default: auto].
    #[arg(long, value_enum)]
    pub model_error: Option<kinecal::solve::estimation::ModelErrorMode>,
    /// Huber threshold, in spreads of the residuals (see --huber-spread) [default: 1.345].
    #[arg(long, value_name = "K")]
    pub huber_scale: Option<f64>,
    /// What one spread of the Huber threshold is: the residuals' robust spread, re-estimated
    /// per kind of row at every reweighting, or the stated standard deviations [default:
    /// robust].
    #[arg(long, value_enum, value_name = "SPREAD")]
    pub huber_spread: Option<Spread>,
    /// List observations with a residual beyond K robust standard deviations of the rows like
    /// them (never dropped). K is raised for large data so that clean Gaussian noise is expected
    /// to show no outlier (4.15 for 3,000 residual rows, 4.8 for 60,000) [default: 4].
    #[arg(long, value_name = "K")]
    pub outlier_sigma: Option<f64>,
    /// Levenberg-Marquardt damping [default: marquardt].
    #[arg(long, value_enum)]
    pub damping: Option<Damping>,
    /// Relative singular-value threshold for svd (dropped) and gn (refused) [default: 1e-9].
    #[arg(long, value_name = "X")]
    pub rcond: Option<f64>,
    /// Write the calibrated robot file here (same schema, other fields and comments kept; `-`:
    /// standard output, the summary then on standard error).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Write a JSON report here.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Record the calibration in the history database under this robot serial (at most 128
    /// characters).
    #[arg(long, value_name = "SERIAL")]
    pub record: Option<String>,
    /// The history for --record: a SQLite file or a postgres:// URL (default: $KINECAL_DB,
    /// else kinecal/history.sqlite in the user's data folder).
    #[arg(long, value_name = "PATH|URL")]
    pub db: Option<PathBuf>,
    /// Time of the calibration for --record (RFC 3339 or YYYY-MM-DD; default now).
    #[arg(long, value_name = "TIME")]
    pub at: Option<String>,
    /// A note stored with --record (at most 1,000 characters).
    #[arg(long, default_value = "")]
    pub note: String,
    /// With --record: record even if the robot model differs from the earlier records of
    /// this serial (the robot was rebuilt).
    #[arg(long, requires = "record")]
    pub force: bool,
    /// Also write a self-contained HTML report here (with the predicted accuracy and its map
    /// when --predict asks for them).
    #[arg(long, value_name = "FILE")]
    pub html: Option<PathBuf>,
    #[command(flatten)]
    pub shown: DisplayUnitsArgs,
    /// Treat warnings that say the result is most likely wrong (data in another unit than the
    /// robot file, readings outside the joint ranges or in the other angle unit, lengths moved
    /// beyond the robot's reach) as failures: exit 3, write and record nothing.
    #[arg(long)]
    pub strict: bool,
    /// Write the calibrated robot (and record it) even when a unit check fired and the fit
    /// ended far above its stated noise (without it such a run is refused: exit 3, the report
    /// and the HTML page written with the reason, no robot).
    #[arg(long)]
    pub force_units: bool,
    /// Print one line per iteration (to standard error).
    #[arg(long, short)]
    pub verbose: bool,
    /// No progress display on standard error: the global `--quiet`.
    #[arg(skip)]
    pub quiet: bool,
}

/// Observation files, one option per file format of the library (`--data`, `--distances`, ...),
/// and the column mapping of measurement files. At least one file is needed unless the command
/// says otherwise.
#[derive(Debug, Clone, Default)]
pub struct ObservationFiles {
    /// (index into `kinecal::files::FORMATS`, path), in the order of the formats.
    pub files: Vec<(usize, PathBuf)>,
    /// `--columns` mappings.
    pub columns: Vec<String>,
    /// `--length-unit`.
    pub length_unit: Option<String>,
    /// `--angle-unit`.
    pub angle_unit: Option<String>,
    /// `--position-only`.
    pub position_only: bool,
    /// `--session-per-file`.
    pub session_per_file: bool,
    /// The command's `--validate` files, when it has them (to name sessions apart).
    pub validate: Vec<PathBuf>,
}

impl FromArgMatches for ObservationFiles {
    fn from_arg_matches(m: &ArgMatches) -> Result<Self, clap::Error> {
        let mut out = ObservationFiles::default();
        out.update_from_arg_matches(m)?;
        Ok(out)
    }

    fn update_from_arg_matches(&mut self, m: &ArgMatches) -> Result<(), clap::Error> {
        self.files = kinecal::files::FORMATS
            .iter()
            .enumerate()
            .flat_map(|(i, f)| {
                m.get_many::<PathBuf>(f.option)
                    .into_iter()
                    .flatten()
                    .map(move |p| (i, p.clone()))
            })
            .collect();
        self.columns = m
            .get_many::<String>("columns")
            .map(|v| v.cloned().collect())
            .unwrap_or_default();
        self.length_unit = m.get_one::<String>("length-unit").cloned();
        self.angle_unit = m.get_one::<String>("angle-unit").cloned();
        self.position_only = m.get_flag("position-only");
        self.session_per_file = m.get_flag("session-per-file");
        self.validate = m
            .try_get_many::<PathBuf>("validate")
            .ok()
            .flatten()
            .map(|v| v.cloned().collect())
            .unwrap_or_default();
        Ok(())
    }
}

impl Args for ObservationFiles {
    fn augment_args(mut cmd: clap::Command) -> clap::Command {
        for f in kinecal::files::FORMATS {
            cmd = cmd.arg(
                Arg::new(f.option)
                    .long(f.option)
                    .value_name("FILE")
                    .value_parser(clap::value_parser!(PathBuf))
                    .action(ArgAction::Append)
                    .help(format!("{} (repeatable): CSV `{}`", f.help, f.header)),
            );
        }
        cmd.arg(
            Arg::new("columns")
                .long("columns")
                .value_name("MAP")
                .action(ArgAction::Append)
                .requires(kinecal::files::FORMATS[0].option)
                .help(
                    "Read --data (and --validate) through a column mapping `ours=theirs,...`, e.g. \
                     `v1=q1,v2=q2,x=X,y=Y,z=Z` (missing posture: rows number the postures; missing \
                     site: end effector; missing angles: positions; other columns ignored). \
                     Repeat with a `SITE:` prefix for markers side by side in one row: \
                     `--columns v1=q1,... --columns smr1:x=x1,y=y1,z=z1 --columns smr2:x=x2,...`. \
                     `alpha=-` leaves a column out; `length_unit=mm`, `angle_unit=deg` state the \
                     file's units",
                ),
        )
        .arg(
            Arg::new("length-unit")
                .long("length-unit")
                .value_name("UNIT")
                .value_parser(["m", "mm", "in"])
                .help(
                    "The unit of the observation files' lengths (positions, distances, their \
                     sigmas), when not the robot file's: converted on reading",
                ),
        )
        .arg(
            Arg::new("angle-unit")
                .long("angle-unit")
                .value_name("UNIT")
                .value_parser(["deg", "rad"])
                .help(
                    "The unit of the observation files' attitudes (and sigma_angle), when not the \
                     robot file's: converted on reading",
                ),
        )
        .arg(
            Arg::new("position-only")
                .long("position-only")
                .action(ArgAction::SetTrue)
                .help(
                    "Read measured poses as positions: their attitudes (and sigma_angle) are left \
                     out",
                ),
        )
        .arg(
            Arg::new("session-per-file")
                .long("session-per-file")
                .action(ArgAction::SetTrue)
                .help(
                    "Each observation file is a measurement session with its own measurement \
                     frame (the instrument moved between them), named after the file: the \
                     frames are placed and estimated with the robot, and a validation file's \
                     frame is re-estimated on it when identification never saw its session. \
                     Without it, a `session` column (or mapping) says the session per row",
                ),
        )
    }

    fn augment_args_for_update(cmd: clap::Command) -> clap::Command {
        Self::augment_args(cmd)
    }
}

/// `kinecal dataset`.
#[derive(Debug, Args)]
pub struct DatasetArgs {
    /// The data set.
    #[arg(value_parser = dataset_names())]
    pub name: String,
    /// Its folder (e.g. ../shared/data/qkm_hl6_faro).
    pub dir: PathBuf,
    /// The folder to write kinecal's files into (created if missing).
    #[arg(long)]
    pub out: PathBuf,
}

/// `kinecal completions`.
#[derive(Debug, Args)]
pub struct CompletionsArgs {
    /// The shell.
    #[arg(value_enum)]
    pub shell: clap_complete::Shell,
}

/// The names of the data set adapters, for `kinecal dataset NAME` (checked and completed).
fn dataset_names() -> clap::builder::PossibleValuesParser {
    clap::builder::PossibleValuesParser::new(
        kinecal::apps::datasets::DATASETS.iter().map(|d| d.name),
    )
}

/// `--display-units`.
fn display_units(s: &str) -> Result<kinecal::units::DisplayChoice, String> {
    s.parse()
}
