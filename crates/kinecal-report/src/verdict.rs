//! What a calibration's page opens with: the verdict (converged or not, suspect or not), the
//! accuracy reached, held out and predicted, and what to do next; then the facts of the run
//! (when, what was read, the job, the kinecal that ran it) and the warnings ranked, errors
//! first. A view of the report: built once from it, rendered as HTML and as text alike.

use kinecal::report::CalibrationReport;
use kinecal::warning::Severity;

use crate::display::{Convert, DisplayUnits};
use crate::number::sig;

/// How a calibration ended, for the banner.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Level {
    /// Converged, nothing says the result is wrong.
    Good,
    /// Converged, with cautions worth reading before the result is used.
    Caution,
    /// Not converged, or a warning says the result is most likely wrong.
    Failed,
}

impl Level {
    /// `good`, `caution` or `failed` (the page's CSS class).
    pub fn as_str(self) -> &'static str {
        match self {
            Level::Good => "good",
            Level::Caution => "caution",
            Level::Failed => "failed",
        }
    }
}

/// The verdict on a calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct Verdict {
    /// The banner's level.
    pub level: Level,
    /// One sentence: what happened.
    pub headline: String,
    /// The figures that say how good it is: label and value with its unit.
    pub figures: Vec<(String, String)>,
    /// What to do next, most important first.
    pub next: Vec<String>,
}

/// One warning of a report, with its rank.
#[derive(Debug, Clone, PartialEq)]
pub struct Ranked {
    /// Error, caution or note.
    pub severity: Severity,
    /// The sentence.
    pub text: String,
}

/// The report's warnings ranked: errors, then cautions, then notes, each in the report's order.
pub fn ranked_warnings(rep: &CalibrationReport) -> Vec<Ranked> {
    let mut out: Vec<Ranked> = if rep.warning_details.len() == rep.warnings.len() {
        rep.warning_details
            .iter()
            .zip(&rep.warnings)
            .map(|(w, text)| Ranked {
                severity: w.severity(),
                text: text.clone(),
            })
            .collect()
    } else {
        // A report of an older kinecal: its words only.
        rep.warnings
            .iter()
            .map(|text| Ranked {
                severity: Severity::Caution,
                text: text.clone(),
            })
            .collect()
    };
    out.sort_by_key(|r| r.severity);
    out
}

/// The verdict on `rep`, its figures in `units`: its level, the sentence that says what
/// happened, the figures of the accuracy reached, and what to do next.
pub fn verdict(rep: &CalibrationReport, units: DisplayUnits) -> Verdict {
    let ranked = ranked_warnings(rep);
    let count = |s: Severity| ranked.iter().filter(|r| r.severity == s).count();
    let (errors, cautions) = (count(Severity::Error), count(Severity::Caution));
    let c = Convert::of(rep, units);
    let held_out = held_out(rep);
    Verdict {
        level: level(rep, errors, cautions),
        headline: headline(rep, errors, cautions),
        figures: figures(rep, &c, held_out.as_ref()),
        next: next_steps(rep, errors, held_out.is_some()),
    }
}

/// Failed when not converged or when an error says the result is wrong; a caution otherwise
/// when any caution was raised.
fn level(rep: &CalibrationReport, errors: usize, cautions: usize) -> Level {
    if (!rep.converged && !rep.given) || errors > 0 || rep.refused.is_some() {
        Level::Failed
    } else if cautions > 0 {
        Level::Caution
    } else {
        Level::Good
    }
}

/// `n thing` or `n things`.
fn plural(n: usize, thing: &str) -> String {
    format!("{n} {thing}{}", if n == 1 { "" } else { "s" })
}

/// One sentence: given, not converged, suspect, or converged (with its cautions).
fn headline(rep: &CalibrationReport, errors: usize, cautions: usize) -> String {
    if rep.given {
        "A given calibration, assessed on these data (not solved here).".to_string()
    } else if let Some(why) = &rep.refused {
        why.clone()
    } else if !rep.converged {
        format!(
            "NOT CONVERGED after {} iterations ({}): the numbers below are not a calibration's.",
            rep.iterations,
            rep.termination.describe()
        )
    } else if errors > 0 {
        format!(
            "SUSPECT: converged after {} iterations, but {} say{} the result is most likely \
             wrong.",
            rep.iterations,
            plural(errors, "warning"),
            if errors == 1 { "s" } else { "" }
        )
    } else {
        format!(
            "Converged after {}{}.",
            plural(rep.iterations, "iteration"),
            if cautions > 0 {
                format!(", with {} (see the warnings)", plural(cautions, "caution"))
            } else {
                String::new()
            }
        )
    }
}

/// The accuracy on data the calibration did not see: the validation data's mean position
/// error, else the cross-validated held-out mean; its label, its metric and its value in the
/// robot's unit (pixels for `pixel`).
fn held_out(rep: &CalibrationReport) -> Option<(String, String, f64)> {
    rep.validation
        .as_ref()
        .and_then(|v| {
            if v.after.positions > 0 {
                Some((
                    format!("held out ({} postures), mean position error", v.postures),
                    "position".to_string(),
                    v.after.mean_position,
                ))
            } else {
                // Pixels without positions: their mean reprojection error.
                v.after.other.iter().find(|m| m.metric == "pixel").map(|m| {
                    (
                        format!(
                            "held out ({} postures), mean {} error",
                            v.postures, m.metric
                        ),
                        m.metric.clone(),
                        m.mean,
                    )
                })
            }
        })
        .or_else(|| {
            rep.cross_validation.as_ref().map(|c| {
                (
                    format!(
                        "cross-validated ({} folds), mean held-out {} error",
                        c.folds.len(),
                        c.metric
                    ),
                    c.metric.clone(),
                    c.overall.mean,
                )
            })
        })
}

/// The accuracy reached: on the identification data (from the nominal's), held out, and
/// predicted over the joint ranges.
fn figures(
    rep: &CalibrationReport,
    c: &Convert,
    held_out: Option<&(String, String, f64)>,
) -> Vec<(String, String)> {
    let l = c.l();
    // A length shown.
    let len = |v: f64| sig(c.length(v), 4);
    // A value of `metric` shown with its unit: pixels stay pixels, lengths in the display unit.
    let of = |metric: &str, v: f64| {
        if metric == "pixel" {
            format!("{} px", sig(v, 4))
        } else {
            format!("{} {l}", len(v))
        }
    };
    let mut figures = Vec::new();
    let (b, a) = (&rep.identification.before, &rep.identification.after);
    if b.positions > 0 {
        figures.push((
            "identification, mean position error".to_string(),
            format!(
                "{} {l} (from {})",
                len(a.mean_position),
                len(b.mean_position)
            ),
        ));
    } else if let (Some(mb), Some(ma)) = (b.other.first(), a.other.first()) {
        figures.push((
            format!("identification, mean {} error", mb.metric),
            if ma.metric == "pixel" {
                // From the solver's start when it is not the robot file's: cameras and boards
                // placed in closed form from poses at zero, where the file's put the points
                // behind the camera (1e17 px).
                match rep
                    .identification
                    .start
                    .as_ref()
                    .and_then(|s| s.other.iter().find(|m| m.metric == "pixel"))
                {
                    Some(ms) => format!(
                        "{} px (from {} px at the solver's start, {} px with the robot file's \
                         poses)",
                        sig(ma.mean, 4),
                        sig(ms.mean, 4),
                        sig(mb.mean, 4)
                    ),
                    None => format!("{} px (from {})", sig(ma.mean, 4), sig(mb.mean, 4)),
                }
            } else {
                format!("{} {l} (from {})", len(ma.mean), len(mb.mean))
            },
        ));
    }
    if let Some((label, metric, v)) = held_out {
        figures.push((label.clone(), of(metric, *v)));
    }
    if let Some(p) = &rep.prediction {
        figures.push((
            "predicted 95 % position bound over the joint ranges".to_string(),
            format!(
                "median {} {l}, 95th percentile {} {l}",
                len(p.position_summary.median),
                len(p.position_summary.p95)
            ),
        ));
    }
    figures
}

/// What to do next, most important first: converge, fix what the errors name, check on
/// unseen data, predict the accuracy, state the noise; or, when nothing is missing, use it.
fn next_steps(rep: &CalibrationReport, errors: usize, held_out: bool) -> Vec<String> {
    let mut next = Vec::new();
    if !rep.converged && !rep.given {
        next.push(
            "Raise the iteration cap, or start nearer (an initial robot), and calibrate again."
                .to_string(),
        );
    }
    if errors > 0 {
        next.push(
            "Read the errors among the warnings first: units, readings or a model that does not \
             fit this robot; fix the data or the robot file before using this result."
                .to_string(),
        );
    }
    if !held_out && !rep.given {
        next.push(
            "Check it on data it did not see: held-out files, a hold-out fraction or folds."
                .to_string(),
        );
    }
    if rep.prediction.is_none() && !rep.given {
        next.push(
            "Ask for the predicted accuracy (a prediction) to state a 95 % bound anywhere in the \
             workspace."
                .to_string(),
        );
    }
    if let Some(vf) = rep.variance_factor {
        if !(0.1..=10.0).contains(&vf) {
            next.push(format!(
                "The residuals are {} times the stated standard deviations: state the \
                 instrument's noise (weights, sigma columns) so that the uncertainties mean \
                 what they say.",
                sig(vf.sqrt(), 2)
            ));
        }
    }
    if next.is_empty() {
        next.push(
            "Write it to the robot (an export, or compensated programs) and record it in the \
             history to watch it drift."
                .to_string(),
        );
    }
    next
}

/// The verdict as text: the headline, the figures, what to do next.
pub fn text(v: &Verdict) -> String {
    use std::fmt::Write as _;
    let mut s = format!("verdict: {}\n", v.headline);
    for (label, value) in &v.figures {
        let _ = writeln!(s, "  {label}: {value}");
    }
    for n in &v.next {
        let _ = writeln!(s, "  next: {n}");
    }
    s
}
