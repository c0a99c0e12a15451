//! The choice of a model: candidate parameter sets scored by repeated cross-validation, the
//! simplest within one standard error of the best chosen.

use crate::error::{Error, Result};
use crate::model::robot::{Prior, Robot};
use crate::units::Quantity;

use super::outcome::Outcome;
use super::request::{Request, Validation};
use super::run::{cross_validate_runs, run};
use super::selection::Selection;

/// A candidate model for [`choose`]: what to estimate, whether to prune, and under which
/// prior.
#[derive(Debug, Clone, PartialEq)]
pub struct Candidate {
    /// How it is written (`identifiable,slopes prune=3`, `all prior=length=0.1,angle=0.01`).
    pub label: String,
    /// What to estimate.
    pub selection: Selection,
    /// Pruning threshold, if any.
    pub prune: Option<f64>,
    /// The prior of this candidate ([`crate::model::prior::parse_prior`]; `none` for none); `None`:
    /// the request's.
    pub prior: Option<Prior>,
}

impl Candidate {
    /// Parses `LIST [fix=LIST] [prune=K] [prior=PRIOR]` (a parameter list as for
    /// [`Selection::parse`], a prior as for [`crate::model::prior::parse_prior`], without spaces).
    /// Candidates that differ only in the strength of their prior compare it: list the
    /// strongest prior (the most constrained model) first, as the one-standard-error rule takes
    /// the first candidate within reach of the best.
    pub fn parse(text: &str, robot: &Robot) -> Result<Candidate> {
        let mut words = text.split_whitespace();
        let list = words.next().unwrap_or("");
        let (mut fix, mut prune, mut prior) = (None, None, None);
        for w in words {
            match w.split_once('=') {
                Some(("fix", f)) => fix = Some(f),
                Some(("prior", p)) => {
                    prior = Some(crate::model::prior::parse_prior(p, robot).map_err(|e| {
                        Error::InvalidOption {
                            setting: crate::error::Setting::ModelCandidate,
                            message: format!("`{text}`: prior: {}", inner_message(e)),
                        }
                    })?)
                }
                Some(("prune", k)) => {
                    prune = Some(
                        k.parse::<f64>()
                            .ok()
                            .filter(|k| k.is_finite() && *k > 0.0)
                            .ok_or_else(|| Error::InvalidOption {
                                setting: crate::error::Setting::ModelCandidate,
                                message: format!("`{text}`: prune={k} is not a positive number"),
                            })?,
                    )
                }
                _ => {
                    return Err(Error::InvalidOption {
                        setting: crate::error::Setting::ModelCandidate,
                        message: format!(
                            "`{text}`: expected `LIST [fix=LIST] [prune=K] [prior=PRIOR]`, found \
                             `{w}`"
                        ),
                    })
                }
            }
        }
        Ok(Candidate {
            label: text.split_whitespace().collect::<Vec<_>>().join(" "),
            selection: Selection::parse(list, fix, robot)?,
            prune,
            prior,
        })
    }

    /// The default candidates, from the simplest up: the identifiable set of the geometric
    /// model (links, offsets, sites: slopes held); with the coupling factors, when the robot
    /// has coupled joints; with the joint transducer slopes (and the couplings); and the latter
    /// pruned stepwise at 2 and at 3 standard deviations.
    pub fn defaults(robot: &Robot) -> Result<Vec<Candidate>> {
        let mut texts = vec!["identifiable fix=slopes"];
        let coupled = robot.coupled_joints().next().is_some();
        if coupled {
            texts.push("identifiable,couplings fix=slopes");
            texts.extend([
                "identifiable,slopes,couplings",
                "identifiable,slopes,couplings prune=2",
                "identifiable,slopes,couplings prune=3",
            ]);
        } else {
            texts.extend([
                "identifiable,slopes",
                "identifiable,slopes prune=2",
                "identifiable,slopes prune=3",
            ]);
        }
        texts.iter().map(|t| Candidate::parse(t, robot)).collect()
    }
}

/// The message of an invalid setting (without the setting's name), else the error's words.
fn inner_message(e: Error) -> String {
    match e {
        Error::InvalidOption { message, .. } => message,
        e => e.to_string(),
    }
}

/// One candidate of a model choice, cross-validated.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct Scored {
    /// The candidate.
    pub candidate: Candidate,
    /// Parameters its fit on all the data estimates.
    pub parameters: usize,
    /// Its held-out mean (m).
    pub mean: f64,
    /// The standard error of that mean: the standard deviation of the folds' means over the
    /// square root of the number of folds.
    pub standard_error: f64,
}

/// The result of [`choose`].
#[derive(Debug)]
#[non_exhaustive]
pub struct Choice {
    /// Every candidate, in the order given.
    pub scored: Vec<Scored>,
    /// The index of the chosen one.
    pub chosen: usize,
    /// The chosen candidate's calibration on all the data, with its cross-validation.
    pub outcome: Outcome,
}

/// How many times [`choose`] repeats its cross-validation, over as many shuffles of the
/// postures, by default.
pub const CHOICE_REPEATS: usize = 5;

/// Chooses among `candidates`, listed from the simplest model up, by `k`-fold cross-validation
/// repeated over `repeats` shuffles of the postures (the same folds for all candidates; the
/// first repeat with `seed`, the others with the seeds after it), so that the choice does not
/// hang on one split: the first whose held-out mean over all repeats is within one standard
/// error of the best (the one-standard-error rule: a more elaborate model must earn its place
/// by more than the noise of the estimate; a pruned fit counts as more elaborate than the set it
/// prunes, as its parameters were chosen from the data), and returns its calibration (checked on
/// `req`'s validation data too, when it is a separate dataset). The standard error is that of
/// one `k`-fold estimate: the spread of the folds' means over `sqrt(k)`.
pub fn choose(
    req: &Request,
    candidates: &[Candidate],
    k: usize,
    seed: Option<u64>,
    repeats: usize,
) -> Result<Choice> {
    if candidates.is_empty() {
        return Err(Error::InvalidOption {
            setting: crate::error::Setting::ModelCandidate,
            message: "no candidate to choose from".into(),
        });
    }
    let started = std::time::Instant::now();
    let mut scored = Vec::with_capacity(candidates.len());
    let mut outcomes = Vec::with_capacity(candidates.len());
    for c in candidates {
        let mut sub = req.clone();
        sub.selection = c.selection.clone();
        sub.prediction = crate::predict::Level::Off;
        sub.prune = c.prune;
        if let Some(p) = &c.prior {
            sub.prior = p.clone();
        }
        sub.validation = Validation::Folds { k, seed };
        let out = run(&sub, &mut ())?;
        let cv = out.cross_validation.as_ref().expect("folds asked for");
        let mut means: Vec<f64> = cv.folds.iter().map(|f| f.errors.mean).collect();
        let (mut sum, mut count) = (cv.overall.mean * cv.overall.count as f64, cv.overall.count);
        for r in 1..repeats.max(1) {
            let shuffle = seed.unwrap_or(0).wrapping_add(r as u64);
            let again = cross_validate_runs(&sub, k, Some(shuffle))?;
            means.extend(again.folds.iter().map(|f| f.errors.mean));
            sum += again.overall.mean * again.overall.count as f64;
            count += again.overall.count;
        }
        let m = means.iter().sum::<f64>() / means.len() as f64;
        let var =
            means.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (means.len() - 1).max(1) as f64;
        scored.push(Scored {
            candidate: c.clone(),
            parameters: out.calibration.estimated.len(),
            mean: sum / count.max(1) as f64,
            standard_error: (var / k as f64).sqrt(),
        });
        outcomes.push(out);
    }
    let best = (0..scored.len())
        .min_by(|&a, &b| scored[a].mean.total_cmp(&scored[b].mean))
        .expect("candidates");
    let limit = scored[best].mean + scored[best].standard_error;
    let chosen = (0..scored.len())
        .find(|&i| scored[i].mean <= limit)
        .expect("the best qualifies");
    let mut outcome = outcomes.swap_remove(chosen);
    // Held-out data of its own (a separate file) checks the chosen model too.
    if let Validation::Data(_) = &req.validation {
        let mut sub = req.clone();
        sub.selection = candidates[chosen].selection.clone();
        sub.prune = candidates[chosen].prune;
        if let Some(p) = &candidates[chosen].prior {
            sub.prior = p.clone();
        }
        let mut checked = run(&sub, &mut ())?;
        checked.report.cross_validation = outcome.report.cross_validation.take();
        checked.cross_validation = outcome.cross_validation.take();
        outcome = checked;
    }
    let len = |v: f64| req.robot.units.from_si(Quantity::Length, v);
    outcome.report.model_choice_repeats = Some(repeats.max(1));
    outcome.report.model_choice = scored
        .iter()
        .enumerate()
        .map(|(i, s)| crate::report::ChoiceReport {
            candidate: s.candidate.label.clone(),
            parameters: s.parameters,
            mean: len(s.mean),
            standard_error: len(s.standard_error),
            chosen: i == chosen,
        })
        .collect();
    // The chosen model's run has its phases; the other candidates' runs and the repeated folds
    // are the phase `model choice`, so that the timings add up to the choice's wall time.
    let phases: f64 = outcome.report.timings.iter().map(|t| t.seconds).sum();
    outcome.report.timings.push(crate::report::PhaseTime {
        phase: "model choice".into(),
        seconds: (started.elapsed().as_secs_f64() - phases).max(0.0),
    });
    Ok(Choice {
        scored,
        chosen,
        outcome,
    })
}
