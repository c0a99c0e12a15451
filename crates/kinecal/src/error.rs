//! The library's one error type.

use std::fmt;

/// A setting of a request, as errors name it ([`Error::InvalidOption`]). Each front end says it
/// in its own terms through one table (the command line's flag, the Python keyword), which a
/// test checks covers every setting; the library's own wording is [`Setting::name`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Setting {
    /// How many robust standard deviations make a residual an outlier.
    OutlierThreshold,
    /// The significance below which parameters are pruned.
    PruningThreshold,
    /// The relative singular-value tolerance of the rank.
    Rcond,
    /// The fraction of postures held out for validation.
    HoldoutFraction,
    /// The number of cross-validation folds.
    Folds,
    /// A model candidate of a choice by cross-validation.
    ModelCandidate,
    /// The candidate observations a plan chooses from.
    PlanCandidates,
    /// The number of postures a plan chooses.
    PlanCount,
    /// The optimality criterion of a plan.
    PlanCriterion,
    /// The spread of the Huber loss.
    HuberScale,
    /// The noise the noise-level identifiability rule assumes, over the stated sigmas.
    NoiseScale,
    /// The largest acceptable error of a check.
    CheckThreshold,
    /// A change made to a parameter (simulation).
    ParameterChange,
    /// The range and sampling of a characteristic curve.
    Sweep,
    /// The width of a characteristic curve's sweep.
    Span,
    /// The nominal robot of a compensation.
    NominalRobot,
    /// The first link of a chain read from a URDF file.
    ChainBase,
    /// The last link of a chain read from a URDF file.
    ChainTip,
    /// The robot to calibrate (a robot file or a built-in robot's name).
    Robot,
    /// The robot a calibration starts from.
    InitialRobot,
    /// The observation files of a calibration.
    Observations,
    /// The kind of an observation file.
    ObservationKind,
    /// The column mapping of a measurement file.
    Columns,
    /// The length unit of observation files.
    LengthUnit,
    /// The angle unit of observation files.
    AngleUnit,
    /// The default standard deviations of the residuals.
    Weights,
    /// The iteration cap of the solver.
    MaxIterations,
    /// How a calibration is checked (held-out files, a hold-out fraction or folds).
    Validation,
    /// The configuration (branch) compensated Cartesian targets must be in.
    Configuration,
    /// The form an output is written in.
    OutputFormat,
    /// The Gaussian prior on the parameters' changes.
    Prior,
    /// The bodies' total mass, which fixes the scale of estimated masses.
    TotalMass,
    /// The parameters an analysis prefers in the identifiable set.
    Priority,
    /// The number of candidate postures a plan samples.
    PlanSample,
    /// The postures a plan keeps.
    PlanKeep,
    /// The frames measured at each planned posture.
    Sites,
    /// The frame a prediction is for.
    Target,
    /// The frame that must reach a goal.
    Site,
    /// The postures of a job (a file, a count, readings).
    Postures,
    /// The number of postures sampled.
    Sample,
    /// A calibration report a job reads.
    Report,
    /// The largest acceptable error (of an export's read-back, of a compensation).
    Tolerance,
    /// The singularity threshold of a compensation.
    Singular,
    /// The largest joint turn of a compensation from its seed.
    Branch,
    /// A file a job writes.
    Output,
    /// The file a job reads (a program, targets, a file to import).
    Input,
    /// The cube of ISO 9283 test poses.
    Cube,
    /// The grid of an ISO 9283 cube search.
    Resolution,
    /// The cycles of a simulated ISO 9283 log.
    Cycles,
    /// The noise of simulated measurements.
    Noise,
    /// The random changes of a simulated true robot.
    PerturbStd,
    /// The roles of measured postures in an ISO 9283 log.
    Roles,
    /// The file a robot was imported from, for its export.
    Template,
    /// A DH convention.
    Convention,
    /// The calibrated robot a report assesses.
    Calibrated,
    /// The parameters to estimate.
    Estimate,
    /// The parameters held.
    Fix,
    /// The history a job reads or writes (a SQLite file or a PostgreSQL URL).
    History,
    /// A robot's serial number in a history.
    RobotId,
    /// When a calibration or a maintenance event happened.
    At,
    /// The time a fleet's horizon is counted from.
    Now,
    /// How many standard deviations of change flag a quantity.
    DriftSigma,
    /// How many days ahead a trend's crossing makes a robot due.
    Horizon,
    /// The calibration drift is measured from.
    Baseline,
    /// A recorded calibration's id.
    CalibrationId,
    /// The tracked quantities a job shows.
    Quantities,
    /// A history dump a job reads.
    Dump,
    /// A note recorded with a calibration or an event.
    Note,
    /// A random seed.
    Seed,
    /// How many shuffles a model choice's cross-validation repeats.
    Repeats,
    /// The name of a controller program.
    ProgramName,
    /// The speed of a controller program's moves.
    Speed,
    /// How a controller program's moves end (exactly, or approximated).
    Zone,
    /// A camera of the robot file, by name.
    Camera,
    /// A board of the robot file, by name.
    Board,
    /// The fewest board points a simulated view must see.
    MinPoints,
    /// Joint readings given inline (one posture).
    Readings,
}

impl Setting {
    /// Every setting.
    pub const ALL: [Setting; 77] = [
        Setting::OutlierThreshold,
        Setting::PruningThreshold,
        Setting::Rcond,
        Setting::HoldoutFraction,
        Setting::Folds,
        Setting::ModelCandidate,
        Setting::PlanCandidates,
        Setting::PlanCount,
        Setting::PlanCriterion,
        Setting::HuberScale,
        Setting::NoiseScale,
        Setting::CheckThreshold,
        Setting::ParameterChange,
        Setting::Sweep,
        Setting::Span,
        Setting::NominalRobot,
        Setting::ChainBase,
        Setting::ChainTip,
        Setting::Robot,
        Setting::InitialRobot,
        Setting::Observations,
        Setting::ObservationKind,
        Setting::Columns,
        Setting::LengthUnit,
        Setting::AngleUnit,
        Setting::Weights,
        Setting::MaxIterations,
        Setting::Validation,
        Setting::Configuration,
        Setting::OutputFormat,
        Setting::Prior,
        Setting::TotalMass,
        Setting::Priority,
        Setting::PlanSample,
        Setting::PlanKeep,
        Setting::Sites,
        Setting::Target,
        Setting::Site,
        Setting::Postures,
        Setting::Sample,
        Setting::Report,
        Setting::Tolerance,
        Setting::Singular,
        Setting::Branch,
        Setting::Output,
        Setting::Input,
        Setting::Cube,
        Setting::Resolution,
        Setting::Cycles,
        Setting::Noise,
        Setting::PerturbStd,
        Setting::Roles,
        Setting::Template,
        Setting::Convention,
        Setting::Calibrated,
        Setting::Estimate,
        Setting::Fix,
        Setting::History,
        Setting::RobotId,
        Setting::At,
        Setting::Now,
        Setting::DriftSigma,
        Setting::Horizon,
        Setting::Baseline,
        Setting::CalibrationId,
        Setting::Quantities,
        Setting::Dump,
        Setting::Note,
        Setting::Seed,
        Setting::Repeats,
        Setting::ProgramName,
        Setting::Speed,
        Setting::Zone,
        Setting::Camera,
        Setting::Board,
        Setting::MinPoints,
        Setting::Readings,
    ];

    /// The library's words for it.
    pub fn name(self) -> &'static str {
        match self {
            Setting::OutlierThreshold => "outlier threshold",
            Setting::PruningThreshold => "pruning threshold",
            Setting::Rcond => "rcond",
            Setting::HoldoutFraction => "hold-out fraction",
            Setting::Folds => "folds",
            Setting::ModelCandidate => "model candidate",
            Setting::PlanCandidates => "plan candidates",
            Setting::PlanCount => "plan size",
            Setting::PlanCriterion => "plan criterion",
            Setting::HuberScale => "Huber scale",
            Setting::NoiseScale => "noise scale",
            Setting::CheckThreshold => "check threshold",
            Setting::ParameterChange => "parameter change",
            Setting::Sweep => "sweep",
            Setting::Span => "sweep span",
            Setting::NominalRobot => "nominal robot",
            Setting::ChainBase => "chain base",
            Setting::ChainTip => "chain tip",
            Setting::Robot => "robot",
            Setting::InitialRobot => "initial robot",
            Setting::Observations => "observations",
            Setting::ObservationKind => "observation kind",
            Setting::Columns => "column mapping",
            Setting::LengthUnit => "length unit",
            Setting::AngleUnit => "angle unit",
            Setting::Weights => "weights",
            Setting::MaxIterations => "iteration cap",
            Setting::Validation => "validation",
            Setting::Configuration => "configuration",
            Setting::OutputFormat => "output format",
            Setting::Prior => "prior",
            Setting::TotalMass => "total mass",
            Setting::Priority => "priority",
            Setting::PlanSample => "plan sample",
            Setting::PlanKeep => "kept postures",
            Setting::Sites => "sites",
            Setting::Target => "target",
            Setting::Site => "site",
            Setting::Postures => "postures",
            Setting::Sample => "sample",
            Setting::Report => "report",
            Setting::Tolerance => "tolerance",
            Setting::Singular => "singularity threshold",
            Setting::Branch => "branch angle",
            Setting::Output => "output",
            Setting::Input => "input",
            Setting::Cube => "cube",
            Setting::Resolution => "resolution",
            Setting::Cycles => "cycles",
            Setting::Noise => "noise",
            Setting::PerturbStd => "perturbation spread",
            Setting::Roles => "roles",
            Setting::Template => "template",
            Setting::Convention => "convention",
            Setting::Calibrated => "calibrated robot",
            Setting::Estimate => "parameters to estimate",
            Setting::Fix => "parameters held",
            Setting::History => "history",
            Setting::RobotId => "robot serial",
            Setting::At => "time",
            Setting::Now => "now",
            Setting::DriftSigma => "drift threshold",
            Setting::Horizon => "horizon",
            Setting::Baseline => "baseline",
            Setting::CalibrationId => "calibration id",
            Setting::Quantities => "quantities",
            Setting::Dump => "dump",
            Setting::Note => "note",
            Setting::Seed => "seed",
            Setting::Repeats => "repeats",
            Setting::ProgramName => "program name",
            Setting::Speed => "speed",
            Setting::Zone => "zone",
            Setting::Camera => "camera",
            Setting::Board => "board",
            Setting::MinPoints => "fewest board points per view",
            Setting::Readings => "readings",
        }
    }

    /// The key of a spec that holds it (the last part of its path: `rcond` for `solver.rcond`),
    /// which is also Python's keyword.
    pub fn key(self) -> &'static str {
        match self {
            Setting::OutlierThreshold => "outlier_sigma",
            Setting::PruningThreshold => "prune",
            Setting::Rcond => "rcond",
            Setting::HoldoutFraction => "holdout",
            Setting::Folds => "folds",
            Setting::ModelCandidate => "choose",
            Setting::PlanCandidates => "candidates",
            Setting::PlanCount => "count",
            Setting::PlanCriterion => "criterion",
            Setting::HuberScale => "huber_scale",
            Setting::NoiseScale => "noise_scale",
            Setting::CheckThreshold => "threshold",
            Setting::ParameterChange => "perturb",
            Setting::Sweep => "sweep",
            Setting::Span => "span",
            Setting::NominalRobot => "nominal",
            Setting::ChainBase => "base",
            Setting::ChainTip => "tip",
            Setting::Robot => "robot",
            Setting::InitialRobot => "initial",
            Setting::Observations => "observations",
            Setting::ObservationKind => "kind",
            Setting::Columns => "columns",
            Setting::LengthUnit => "length_unit",
            Setting::AngleUnit => "angle_unit",
            Setting::Weights => "weights",
            Setting::MaxIterations => "max_iterations",
            Setting::Validation => "validation",
            Setting::Configuration => "configuration",
            Setting::OutputFormat => "format",
            Setting::Prior => "prior",
            Setting::TotalMass => "total_mass",
            Setting::Priority => "priority",
            Setting::PlanSample => "sample",
            Setting::PlanKeep => "keep",
            Setting::Sites => "sites",
            Setting::Target => "target",
            Setting::Site => "site",
            Setting::Postures => "postures",
            Setting::Sample => "sample",
            Setting::Report => "report",
            Setting::Tolerance => "tolerance",
            Setting::Singular => "singular",
            Setting::Branch => "branch",
            Setting::Output => "out",
            Setting::Input => "in",
            Setting::Cube => "cube",
            Setting::Resolution => "resolution",
            Setting::Cycles => "cycles",
            Setting::Noise => "noise",
            Setting::PerturbStd => "perturb_std",
            Setting::Roles => "roles",
            Setting::Template => "template",
            Setting::Convention => "convention",
            Setting::Calibrated => "calibrated",
            Setting::Estimate => "estimate",
            Setting::Fix => "fix",
            Setting::History => "db",
            Setting::RobotId => "robot_id",
            Setting::At => "at",
            Setting::Now => "now",
            Setting::DriftSigma => "sigma",
            Setting::Horizon => "horizon",
            Setting::Baseline => "baseline",
            Setting::CalibrationId => "id",
            Setting::Quantities => "param",
            Setting::Dump => "dump",
            Setting::Note => "note",
            Setting::Seed => "seed",
            Setting::Repeats => "repeats",
            Setting::ProgramName => "name",
            Setting::Speed => "speed",
            Setting::Zone => "zone",
            Setting::Camera => "camera",
            Setting::Board => "board",
            Setting::MinPoints => "min_points",
            Setting::Readings => "readings",
        }
    }
}

impl fmt::Display for Setting {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Where in an input file something went wrong: enough for a user to find and fix it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Location {
    /// The file name as the user gave it (or `<built-in ge-a4>`, `<input>`).
    pub file: String,
    /// 1-based line number, when known.
    pub line: Option<usize>,
    /// The field (TOML key path such as `links[2].beta`, or CSV column name), when known.
    pub field: Option<String>,
}

impl Location {
    /// A location in `file` with nothing more precise known.
    pub fn file(file: impl Into<String>) -> Self {
        Self {
            file: file.into(),
            line: None,
            field: None,
        }
    }

    /// The same file, at `line`.
    pub(crate) fn at_line(&self, line: usize) -> Self {
        Self {
            line: Some(line),
            ..self.clone()
        }
    }

    /// The same place, naming `field`.
    pub(crate) fn with_field(&self, field: impl Into<String>) -> Self {
        Self {
            field: Some(field.into()),
            ..self.clone()
        }
    }
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file)?;
        if let Some(line) = self.line {
            write!(f, ":{line}")?;
        }
        if let Some(field) = &self.field {
            write!(f, ": field `{field}`")?;
        }
        Ok(())
    }
}

/// Everything that can go wrong in kinecal's library.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// An input file (robot TOML, measurement CSV) is malformed.
    #[error("{at}: {message}")]
    Input {
        /// Where.
        at: Location,
        /// What was wrong and what was expected.
        message: String,
    },
    /// The chain to read from a file of several chains or a tree (URDF) needs an end named: the
    /// one given is not in the file, or the file has several candidates.
    #[error("{at}: {message}")]
    ChainEnd {
        /// The file.
        at: Location,
        /// Which end: [`Setting::ChainBase`] or [`Setting::ChainTip`].
        setting: Setting,
        /// What was wrong, with the candidates.
        message: String,
    },
    /// A parameter list (`--estimate`, `--fix`, `--perturb`) names something that does not exist.
    #[error("parameter list `{list}`: {message}")]
    ParamList {
        /// The list as given.
        list: String,
        /// What was wrong.
        message: String,
    },
    /// The problem cannot be solved as posed.
    #[error("{0}")]
    Problem(String),
    /// A calibration was asked of data without observations.
    #[error("no observations to calibrate from")]
    NoObservations,
    /// A robot given beside the nominal robot (the initial guess of a calibration, the
    /// calibrated robot of a check) does not have its structure: give one with the same joints,
    /// couplings, sites and planes.
    #[error(
        "{robot} does not have the nominal robot's structure (joints, couplings, sites, planes)"
    )]
    OtherStructure {
        /// Which robot: `the initial guess` or `the calibrated robot`.
        robot: &'static str,
    },
    /// An elastic robot's gravity equilibrium does not converge at a measured posture, so the
    /// robot gives no answer there: its compliances are implausibly large, or it would buckle.
    #[error("the {robot}'s gravity equilibrium at posture `{posture}` {equilibrium}")]
    EquilibriumNotConverged {
        /// Which robot: `nominal robot` or `initial guess`.
        robot: &'static str,
        /// The posture's label.
        posture: String,
        /// Where the iteration stopped, as [`crate::model::kinematics::Equilibrium`] says it
        /// (`did not converge: the deflections still changed by ...`).
        equilibrium: String,
        /// The largest change of a deflection in the last iteration (rad).
        change: f64,
        /// Fixed-point iterations taken.
        iterations: usize,
    },
    /// Too few postures measured by position, pose or pixel for a prediction: measure more.
    #[error(
        "a prediction needs at least {needed} postures measured by position, pose or pixel; the \
         data has {found}"
    )]
    TooFewPostures {
        /// The least the prediction needs ([`crate::predict::MIN_POSTURES`]).
        needed: usize,
        /// Postures measured by position, pose or pixel in the data (0 when it measures none
        /// that way).
        found: usize,
    },
    /// A test pose of an ISO 9283 cube is out of the robot's reach (inside its joint ranges,
    /// away from singularities): a smaller cube, or another centre or attitude.
    #[error("{message}")]
    CubeOutOfReach {
        /// The test pose, 1 to 5 (`P1` to `P5`).
        pose: usize,
        /// The whole sentence, in the robot file's units.
        message: String,
    },
    /// Nothing was left to estimate.
    #[error("no parameters to estimate")]
    NothingToEstimate,
    /// Fewer residuals than estimated parameters.
    #[error(
        "{residuals} residuals ({observations} observations) cannot determine {parameters} \
         parameters: measure more postures or estimate fewer parameters"
    )]
    TooFewResiduals {
        /// Residual rows.
        residuals: usize,
        /// Observations.
        observations: usize,
        /// Estimated parameters.
        parameters: usize,
    },
    /// No degrees of freedom are left to estimate the noise from.
    #[error(
        "{residuals} residuals leave no degrees of freedom over rank {rank}: no uncertainty can \
         be estimated"
    )]
    NoDegreesOfFreedom {
        /// Residual rows.
        residuals: usize,
        /// Numerical rank.
        rank: usize,
    },
    /// A setting of a request is out of its range.
    #[error("{setting}: {message}")]
    InvalidOption {
        /// The setting; front ends name it in their own terms (a flag, a keyword).
        setting: Setting,
        /// What was wrong and what is expected.
        message: String,
    },
    /// An observation's residual is not finite at the starting point.
    #[error(
        "the {kind} observation from line {line} has a non-finite `{row}` residual at the \
         starting point (numbers too large for the model?)"
    )]
    NonFiniteResidual {
        /// Line of the observation in its file (0 when synthesized).
        line: usize,
        /// The observation's kind.
        kind: &'static str,
        /// The residual row's label.
        row: &'static str,
    },
    /// Gauss-Newton met a singular normal matrix (thesis 3.3.3).
    #[error(
        "Gauss-Newton cannot proceed: the normal matrix J^T J is singular (numerical rank {rank} \
         of {parameters} estimated parameters, relative tolerance {rcond:e}); the data cannot \
         separate some of the estimated parameters (thesis 3.3.3): use Levenberg-Marquardt or \
         truncated SVD, or estimate fewer parameters"
    )]
    SingularNormalEquations {
        /// Numerical rank of the scaled Jacobian.
        rank: usize,
        /// Number of estimated parameters.
        parameters: usize,
        /// Relative singular-value tolerance used for the rank.
        rcond: f64,
    },
    /// Euler-angle orientation residuals were asked for, but measured attitudes come within 1
    /// deg of gimbal lock (ZYX beta = +-90 deg), where Euler differences are undefined.
    #[error(
        "Euler-angle orientation residuals are undefined at gimbal lock, and {count} measured \
         pose(s) have ZYX beta within 1 deg of +-90 deg (lines {}{}): use rotation-vector \
         residuals (the default)",
        lines.iter().map(ToString::to_string).collect::<Vec<_>>().join(", "),
        if *count > lines.len() { ", ..." } else { "" }
    )]
    EulerNearGimbalLock {
        /// How many poses.
        count: usize,
        /// Their lines (the first few).
        lines: Vec<usize>,
    },
    /// The caller stopped the run (its progress observer said so).
    #[error("stopped after {after}")]
    Stopped {
        /// Where.
        after: &'static str,
    },
    /// A numerical routine failed (should not happen on finite input).
    #[error("numerical failure: {0}")]
    Numerical(String),
    /// The objective (the weighted sum of squared residuals) is not finite where the solver
    /// evaluates it: numbers too large for the model (a unit mix-up?), or a start far off.
    #[error("numerical failure: the objective is not finite at {at}")]
    NonFiniteObjective {
        /// Where: `the starting point` or `an accepted point`.
        at: &'static str,
    },
    /// An export, read back with the matching importer, misses the robot by more than the
    /// tolerance: nothing may be written ([`crate::import::readback`]).
    #[error("{message}")]
    ExportMisses {
        /// The largest position deviation at the tool over the sampled postures (m).
        position: f64,
        /// The largest attitude deviation (rad).
        attitude: f64,
        /// The tolerance it exceeds: position (m) and attitude (rad).
        tolerance: (f64, f64),
        /// What the export's form cannot hold, each with the deviation it alone causes.
        reasons: Vec<String>,
        /// The whole sentence, in the robot file's units.
        message: String,
    },
    /// An output cannot be written where it was asked for: it would replace an input of the
    /// run or another output, or its path names a folder or no folder
    /// ([`crate::files::output`]).
    #[error("{path}: {message}")]
    Output {
        /// The output as given.
        path: String,
        /// Why not.
        message: String,
    },
    /// A calibration could not be recorded in its history (what the store said).
    #[error("{0}")]
    Record(String),
    /// A history job failed in its store (`kinecal-history`'s error, which the host may
    /// downcast).
    #[error("{0}")]
    History(Box<dyn std::error::Error + Send + Sync>),
    /// Reading or writing a file failed.
    #[error("{path}: {cause}")]
    Io {
        /// The path.
        path: String,
        /// The OS error (in the message, not a separate source, so it is printed once).
        cause: std::io::Error,
    },
}

impl Error {
    /// An input error at `at`.
    pub fn input(at: Location, message: impl Into<String>) -> Self {
        Error::Input {
            at,
            message: message.into(),
        }
    }
}

/// Result with kinecal's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;
