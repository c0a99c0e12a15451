//! The library's one error type.

use std::fmt;

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
    pub fn at_line(&self, line: usize) -> Self {
        Self {
            line: Some(line),
            ..self.clone()
        }
    }

    /// The same place, naming `field`.
    pub fn with_field(&self, field: impl Into<String>) -> Self {
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
    #[error("{option}: {message}")]
    InvalidOption {
        /// The setting, as the library names it (e.g. `huber scale`).
        option: &'static str,
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
