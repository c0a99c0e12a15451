//! `plan`: which postures to measure.
//!
//! ```toml
//! job = "plan"
//! robot = "ge-a4"
//! sample = 2000                   # or `candidates = "pool.csv"` (postures or observations)
//! count = 25
//! criterion = "d"                 # d, a, i, e, o1..o5
//!
//! [outputs]
//! postures = "plan.csv"
//! html = "plan.html"
//! ```

use serde::{Deserialize, Serialize};

use crate::apps::plan::{Criterion, Plan, PlanReport, PlanRequest};
use crate::error::{Result, Setting};
use crate::files::{detect_format, parse_postures};
use crate::identifiability::AnalysisOptions;
use crate::model::kinematics::Target;
use crate::model::robot::Robot;
use crate::observe::Dataset;
use crate::source::Source;

use super::common::{count, invalid, is_default, read_source, robot_as, visit_opt, Residuals};
use super::{Document, Done, Env, JobKind, Page, PathRole, Spec};

/// The most candidate postures a plan samples (its information matrices are held at once).
pub(crate) const MAX_SAMPLE: usize = 1_000_000;

/// What a plan writes (`[outputs]`).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct PlanOutputs {
    /// The chosen postures (a postures file, or the chosen rows of an observation file).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub postures: Option<String>,
    /// An HTML page of the plan.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub html: Option<String>,
}

/// A measurement plan. See the [module documentation](self).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct PlanSpec {
    /// The robot file (or a built-in robot's name): the nominal model the plan is made for.
    #[serde(default)]
    pub robot: String,
    /// Candidate postures: a postures file, or an observation file (what each row measures is
    /// what the plan assumes).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub candidates: Option<String>,
    /// Instead, this many candidate postures sampled uniformly within the joint ranges.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sample: Option<usize>,
    /// The seed of the sample and of the random plans compared with (default 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
    /// How many postures to choose (besides the kept ones).
    #[serde(default)]
    pub count: usize,
    /// What the plan maximises (default `d`).
    #[serde(default, skip_serializing_if = "is_default")]
    pub criterion: Criterion,
    /// The targets measure positions only (a laser tracker) rather than full poses.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub position_only: bool,
    /// For postures: the frames measured at each, `ee` and site names, comma-separated
    /// (default: every site, or the end effector when the robot has none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sites: Option<String>,
    /// The parameters to determine (default `identifiable`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub estimate: Option<String>,
    /// Parameters to leave out.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fix: Option<String>,
    /// Postures already measured (a postures or observation file): always in the plan.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub keep: Option<String>,
    /// The weights and the orientation residual.
    #[serde(default, skip_serializing_if = "is_default")]
    pub residuals: Residuals,
    /// What is written.
    #[serde(default, skip_serializing_if = "is_default")]
    pub outputs: PlanOutputs,
}

impl Spec for PlanSpec {
    const KIND: JobKind = JobKind::Plan;

    fn visit_paths(&mut self, f: &mut dyn FnMut(PathRole, &mut String)) {
        f(PathRole::Robot, &mut self.robot);
        visit_opt(f, PathRole::Input, &mut self.candidates);
        visit_opt(f, PathRole::Input, &mut self.keep);
        visit_opt(f, PathRole::Output, &mut self.outputs.postures);
        visit_opt(f, PathRole::Output, &mut self.outputs.html);
    }
}

/// A pool of candidates and whether it came from observations (whose rows say what is
/// measured) rather than postures.
#[derive(Debug, Clone, Default)]
pub struct Pool {
    /// The candidate observations.
    pub data: Dataset,
    /// From an observation file.
    pub observed: bool,
    /// Where it came from, in words.
    pub described: String,
}

/// A finished plan.
#[derive(Debug)]
#[non_exhaustive]
pub struct PlanOutcome {
    /// The plan.
    pub plan: Plan,
    /// Its robot.
    pub robot: Robot,
    /// Where the candidates came from, in words.
    pub described: String,
    /// What was written as the chosen postures: `postures` or `observations`.
    pub written: &'static str,
    /// The chosen postures' file (what `outputs.postures` holds).
    pub file: String,
    /// The document.
    pub report: PlanReport,
}

impl PlanOutcome {
    /// The document.
    pub fn document(&self) -> &PlanReport {
        &self.report
    }
}

/// Whether `text` is a postures file (its header names no measured quantity).
fn is_postures_file(text: &str) -> bool {
    if detect_format(text) != 0 {
        return false;
    }
    let header = text
        .lines()
        .map(str::trim)
        .find(|l| !l.is_empty() && !l.starts_with('#'))
        .unwrap_or("")
        .trim_start_matches('\u{feff}')
        .to_ascii_lowercase();
    !header
        .split([',', ';', '\t'])
        .any(|c| c.trim().trim_matches('"') == "x")
}

impl PlanSpec {
    /// The frames measured at each posture: `sites`, or every site, or the end effector.
    pub fn targets(&self, robot: &Robot) -> Result<Vec<Target>> {
        let Some(list) = &self.sites else {
            return Ok(if robot.sites.is_empty() {
                vec![Target::EndEffector]
            } else {
                (0..robot.sites.len()).map(Target::Site).collect()
            });
        };
        if list.trim().is_empty() {
            return Err(invalid(
                Setting::Sites,
                "an empty list: name the frames measured at each posture",
            ));
        }
        let mut out = Vec::new();
        for name in list.split(',').map(str::trim) {
            let t =
                crate::files::site_target(robot, name).map_err(|m| invalid(Setting::Sites, m))?;
            if !out.contains(&t) {
                out.push(t);
            }
        }
        if out.is_empty() {
            return Err(invalid(
                Setting::Sites,
                "name the frames measured at each posture",
            ));
        }
        Ok(out)
    }

    /// The candidates of postures: what `targets` measure at each.
    pub(crate) fn pool_of_postures(
        &self,
        robot: &Robot,
        postures: Vec<crate::Posture>,
        described: String,
    ) -> Result<Pool> {
        let targets = self.targets(robot)?;
        Ok(Pool {
            data: crate::apps::plan::candidates(robot, postures, &targets, self.position_only),
            observed: false,
            described,
        })
    }

    /// The candidates of observations (their rows say what is measured): refused with `sites`.
    pub fn pool_of_observations(&self, mut data: Dataset, described: String) -> Result<Pool> {
        if self.sites.is_some() {
            return Err(invalid(
                Setting::Sites,
                "describes postures; the candidates are observations (an observation file, \
                 Measurements), whose rows say what is measured",
            ));
        }
        if self.position_only {
            for o in &mut data.observations {
                if let crate::Observation::Pose(p) = o {
                    *o = p.to_position().into();
                }
            }
        }
        Ok(Pool {
            data,
            observed: true,
            described,
        })
    }

    /// Reads candidates or kept postures from the file `path`.
    fn read_pool(&self, path: &str, robot: &Robot, setting: Setting) -> Result<Pool> {
        let s: Source = read_source(path, setting)?;
        if is_postures_file(&s.text) {
            let postures = parse_postures(&s.text, &s.name, robot)?;
            let n = postures.len();
            return self.pool_of_postures(
                robot,
                postures,
                format!("{n} candidate postures from {path}"),
            );
        }
        let opts = crate::files::ReadOptions {
            position_only: self.position_only,
            ..Default::default()
        };
        let data = crate::files::read_observations(&s.text, &s.name, robot, &opts)?;
        let n = data.postures.len();
        self.pool_of_observations(data, format!("{n} candidate postures from {path}"))
    }

    /// The candidates the spec names: its file, or its sample.
    pub fn pool(&self, robot: &Robot) -> Result<Pool> {
        match (&self.candidates, self.sample) {
            (Some(path), None) => self.read_pool(path, robot, Setting::PlanCandidates),
            (None, Some(n)) => {
                let n = count(Setting::PlanSample, n, MAX_SAMPLE, "sampled postures")?;
                let seed = self.seed.unwrap_or(1);
                let postures = crate::apps::simulate::sample_postures(robot, n, seed);
                self.pool_of_postures(
                    robot,
                    postures,
                    format!("{n} candidate postures sampled within the joint ranges (seed {seed})"),
                )
            }
            (Some(_), Some(_)) => Err(invalid(
                Setting::PlanCandidates,
                "candidates and sample are two pools: give one",
            )),
            (None, None) => Err(invalid(
                Setting::PlanCandidates,
                "give candidate postures (a file) or a number of postures to sample",
            )),
        }
    }

    /// The kept postures the spec names (none when absent).
    pub fn kept(&self, robot: &Robot) -> Result<Dataset> {
        match &self.keep {
            Some(path) => Ok(self.read_pool(path, robot, Setting::PlanKeep)?.data),
            None => Ok(Dataset::default()),
        }
    }

    /// The library request for `robot` from `pool`, keeping `keep`: the one translation of the
    /// settings, for files and for candidates given in memory (Python).
    pub fn request(&self, robot: &Robot, pool: Dataset, keep: Dataset) -> Result<PlanRequest> {
        if self.count == 0 {
            return Err(invalid(Setting::PlanCount, "must be at least 1"));
        }
        let count = self.count;
        let (weights, orientation) = self.residuals.resolve(robot)?;
        Ok(PlanRequest {
            robot: robot.clone(),
            pool,
            keep,
            count,
            criterion: self.criterion,
            selection: super::common::selection(
                self.estimate.as_deref(),
                "identifiable",
                self.fix.as_deref(),
                robot,
            )?,
            analysis: AnalysisOptions {
                weights,
                orientation,
                ..AnalysisOptions::default()
            },
            seed: self.seed.unwrap_or(1),
        })
    }

    /// Plans on `pool` (and `keep`) for `robot`.
    pub fn plan(
        &self,
        robot: &Robot,
        pool: Pool,
        keep: Dataset,
        env: &mut Env<'_>,
    ) -> Result<(PlanOutcome, Dataset)> {
        env.progress
            .say(&format!("planning: {} ...", pool.described));
        let req = self.request(robot, pool.data, keep)?;
        let plan = crate::apps::plan::plan_with(&req, &mut |w| env.progress.say(w))?;
        let (file, written) = plan.chosen_file(robot, pool.observed);
        let report = PlanReport::new(&plan, robot);
        Ok((
            PlanOutcome {
                plan,
                robot: robot.clone(),
                described: pool.described,
                written,
                file,
                report,
            },
            req.pool,
        ))
    }

    /// Reads the files, plans and writes the outputs.
    pub(crate) fn run(&self, env: &mut Env<'_>) -> Result<Done> {
        let (robot, _) = robot_as(&self.robot, Setting::Robot)?;
        let pool = self.pool(&robot)?;
        let keep = self.kept(&robot)?;
        let (outcome, pool) = self.plan(&robot, pool, keep, env)?;
        let mut staged = crate::files::output::Staged::new();
        if let Some(path) = &self.outputs.postures {
            staged.text(std::path::Path::new(path), &outcome.file)?;
        }
        if let Some(path) = &self.outputs.html {
            let page = env.draw(
                Page::Plan {
                    plan: &outcome.plan,
                    robot: &robot,
                    pool: &pool,
                    described: &outcome.described,
                },
                path,
            )?;
            staged.bytes(std::path::Path::new(path), &page)?;
        }
        staged.commit()?;
        let chosen = outcome
            .plan
            .postures
            .iter()
            .filter(|q| q.candidate.is_some())
            .count();
        let note = match (&self.outputs.postures, &self.outputs.html) {
            (Some(p), Some(h)) => Some(format!(
                "wrote the {chosen} chosen {} to {p} and the plan to {h}",
                outcome.written
            )),
            (Some(p), None) => Some(format!(
                "wrote the {chosen} chosen {} to {p}",
                outcome.written
            )),
            (None, Some(h)) => Some(format!("wrote the plan to {h}")),
            (None, None) => None,
        };
        let mut done = Done::ok(Document::Plan(Box::new(outcome)));
        done.messages.extend(note.map(super::Message::Note));
        Ok(done)
    }
}
