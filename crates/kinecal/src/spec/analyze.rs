//! `analyze`: what the data can and cannot determine about a robot's parameters.
//!
//! ```toml
//! job = "analyze"
//! robot = "qkm_hl6.toml"
//!
//! [[observations]]
//! file = "identification.csv"     # or `postures = "p.csv"`: full poses assumed
//!
//! [selection]
//! estimate = "all"                # default: calibrate's default parameters
//! prior = "tolerances"            # default: the robot file's [priors]
//! ```

use serde::{Deserialize, Serialize};

use crate::error::{Result, Setting};
use crate::files::{ObservationFile, ReadSettings};
use crate::identifiability::{Analysis, AnalysisOptions, JacobianTable};
use crate::model::robot::Robot;
use crate::observe::Dataset;
use crate::report::AnalysisReport;
use crate::workflow::Selection;
use crate::ParamId;

use super::common::{
    invalid, is_default, read_observations, robot_as, visit_observations, visit_opt, Residuals,
};
use super::{Document, Done, Env, JobKind, Message, PathRole, Spec};

/// What to analyse (`[selection]` of an analysis).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct AnalysisSelection {
    /// The parameters to analyse ([`Selection::parse`]); calibrate's default parameters when
    /// absent, so that the identifiable set shown is the one `estimate = "identifiable"`
    /// estimates (`all` for every one).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub estimate: Option<String>,
    /// Parameters to leave out.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fix: Option<String>,
    /// Parameters to prefer in the identifiable set, most preferred first (default order: joint
    /// offsets, slopes, non-zero link lengths, non-zero link angles, zero-valued link
    /// components, sites).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub priority: Option<String>,
    /// A Gaussian prior on the changes, as a calibration fits it
    /// ([`crate::model::prior::parse_prior`]); the robot file's `[priors]` when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub prior: Option<String>,
    /// The bodies' total mass (kg), held as a calibration holds it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub total_mass: Option<f64>,
}

/// A matrix an analysis shows as well.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum MatrixKind {
    /// The Jacobian, rows labelled by posture, site and pose component.
    Jacobian,
    /// J^T J (the thesis's "Hessian").
    Hessian,
}

/// The units of a matrix shown.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum MatrixUnits {
    /// The robot file's units (thesis Tables 4.3-4.7 style).
    #[default]
    File,
    /// The solver's scaled units (weighted residuals, unit-norm columns).
    Scaled,
}

/// An identifiability analysis. See the [module documentation](self).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct AnalyzeSpec {
    /// The robot file (or a built-in robot's name): the model, analysed at its values.
    #[serde(default)]
    pub robot: String,
    /// How the observation files are read.
    #[serde(default, skip_serializing_if = "is_default")]
    pub read: ReadSettings,
    /// The observation files.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub observations: Vec<ObservationFile>,
    /// A postures file instead of observations: full poses of the end effector and every site
    /// are assumed (positions with `read.position_only`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub postures: Option<String>,
    /// What to analyse.
    #[serde(default, skip_serializing_if = "is_default")]
    pub selection: AnalysisSelection,
    /// The relative singular-value tolerance of the numerical rank (default
    /// [`crate::identifiability::DEFAULT_RANK_RCOND`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rcond: Option<f64>,
    /// The weights and the orientation residual.
    #[serde(default, skip_serializing_if = "is_default")]
    pub residuals: Residuals,
    /// A matrix to show as well (text only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub matrix: Option<MatrixKind>,
    /// Its units.
    #[serde(default, skip_serializing_if = "is_default")]
    pub matrix_units: MatrixUnits,
}

impl Spec for AnalyzeSpec {
    const KIND: JobKind = JobKind::Analyze;

    fn visit_paths(&mut self, f: &mut dyn FnMut(PathRole, &mut String)) {
        f(PathRole::Robot, &mut self.robot);
        visit_observations(f, &mut self.observations);
        visit_opt(f, PathRole::Input, &mut self.postures);
    }
}

/// A finished analysis: the library's analysis and its document.
#[derive(Debug)]
#[non_exhaustive]
pub struct AnalyzeOutcome {
    /// The analysis.
    pub analysis: Analysis,
    /// The robot analysed.
    pub robot: Robot,
    /// The document (the command line's `--json`).
    pub report: AnalysisReport,
    /// Postures, observations and the count of each kind of observation analysed.
    pub postures: usize,
    /// Observations.
    pub observations: usize,
    /// The count of each kind.
    pub kinds: Vec<(String, usize)>,
    /// The matrix asked for, and its units.
    pub matrix: Option<(MatrixKind, MatrixUnits, JacobianTable)>,
}

impl AnalyzeOutcome {
    /// The document.
    pub fn document(&self) -> &AnalysisReport {
        &self.report
    }
}

/// A list in the order given (for priorities).
fn ordered_list(list: &str, robot: &Robot) -> Result<Vec<ParamId>> {
    let mut out = Vec::new();
    for token in list.split(',') {
        for id in crate::model::param_list::parse_param_list(token.trim(), robot)
            .map_err(|e| invalid(Setting::Priority, e.to_string()))?
        {
            if !out.contains(&id) {
                out.push(id);
            }
        }
    }
    Ok(out)
}

impl AnalyzeSpec {
    /// The parameters to analyse and the options, for `robot`: the one translation of the
    /// settings, for files and for data given in memory (Python).
    pub fn request(&self, robot: &Robot) -> Result<(Selection, AnalysisOptions)> {
        let rcond = self
            .rcond
            .unwrap_or(crate::identifiability::DEFAULT_RANK_RCOND);
        if !(rcond > 0.0 && rcond < 1.0) {
            return Err(invalid(
                Setting::Rcond,
                format!("expected a tolerance between 0 and 1, not {rcond}"),
            ));
        }
        let s = &self.selection;
        let priority = match &s.priority {
            Some(list) => ordered_list(list, robot)?,
            None => Vec::new(),
        };
        let mut prior = match &s.prior {
            Some(text) => crate::model::prior::parse_prior(text, robot)?,
            None => robot.priors.clone(),
        };
        if let Some(total) = s.total_mass {
            crate::model::prior::set_total_mass(&mut prior, total, robot)
                .map_err(|m| invalid(Setting::TotalMass, m))?;
        }
        let (weights, orientation) = self.residuals.resolve(robot)?;
        let selection =
            super::common::selection(s.estimate.as_deref(), "", s.fix.as_deref(), robot)?;
        if s.total_mass.is_some() {
            if let Some(m) = crate::workflow::total_mass_problem(&selection, robot) {
                return Err(invalid(Setting::TotalMass, m));
            }
        }
        Ok((
            selection,
            AnalysisOptions {
                rcond,
                weights,
                orientation,
                priority,
                noise_scale: 1.0,
                prior,
                placed: Vec::new(),
            },
        ))
    }

    /// Analyses `data` on `robot` (read by the caller, or given in memory).
    pub fn analyze(&self, robot: &Robot, data: &Dataset) -> Result<(AnalyzeOutcome, Vec<Message>)> {
        let (selection, opts) = self.request(robot)?;
        let (params, unseen) = crate::workflow::resolve(&selection, robot, data, &opts)?;
        crate::workflow::check_total_mass_kept(
            self.selection.total_mass,
            &selection,
            &params,
            robot,
            "the identifiability analysis",
        )?;
        let mut messages = Vec::new();
        if !unseen.is_empty() {
            // A note here: the analysis shows what the data sees (a calibration warns).
            let w = crate::Warning::Unseen {
                parameters: unseen.iter().map(|&id| robot.param_name(id)).collect(),
            };
            messages.push(Message::Note(format!("note: {w}")));
        }
        let analysis = crate::identifiability::analyze(robot, data, &params, &opts)?;
        let report = AnalysisReport::new(&analysis, robot, &unseen);
        let matrix = self.matrix.map(|kind| {
            (
                kind,
                self.matrix_units,
                crate::identifiability::jacobian_table(robot, data, &analysis, &opts),
            )
        });
        messages.extend(analysis.warnings.iter().cloned().map(Message::Warning));
        Ok((
            AnalyzeOutcome {
                analysis,
                robot: robot.clone(),
                report,
                postures: data.postures.len(),
                observations: data.observations.len(),
                kinds: data
                    .kinds()
                    .iter()
                    .map(|(k, c)| (k.to_string(), *c))
                    .collect(),
                matrix,
            },
            messages,
        ))
    }

    /// Reads the robot and the data the spec names.
    pub fn load(&self) -> Result<(Robot, Dataset)> {
        let (robot, _) = robot_as(&self.robot, Setting::Robot)?;
        let data = match &self.postures {
            Some(path) => {
                if !self.observations.is_empty() {
                    return Err(invalid(
                        Setting::Observations,
                        "give observation files or postures, not both",
                    ));
                }
                let s = super::common::read_source(path, Setting::Observations)?;
                let postures = crate::files::parse_postures(&s.text, &s.name, &robot)?;
                crate::apps::simulate::measure(&robot, &postures, self.read.position_only)
            }
            None => read_observations(&self.read, &self.observations, &robot)?.0,
        };
        Ok((robot, data))
    }

    /// Reads the files and analyses.
    pub(crate) fn run(&self, env: &mut Env<'_>) -> Result<Done> {
        env.progress.say("reading");
        let (robot, data) = self.load()?;
        env.progress.say("analysing");
        let (outcome, messages) = self.analyze(&robot, &data)?;
        let mut done = Done::ok(Document::Analysis(Box::new(outcome)));
        done.messages = messages;
        Ok(done)
    }
}
