//! Drift of determined quantities over a robot's history.
//!
//! Tracked quantities are the individually determined parameters and the determined
//! combinations of identically redundant groups, never a lone redundant parameter (its value
//! wanders with the solver's path, thesis Table 4.8). For each: the change from the baseline,
//! its significance `|delta| / sqrt(s1^2 + s2^2)`, the trend per 30 days (weighted regression
//! over the whole history, with its standard error), and a flag when the change exceeds `K`
//! sigma or a tolerance.
//!
//! Values and sigmas are converted to the units of the robot's first record before anything
//! is compared (lengths m/mm/in, angles deg/rad, slopes per transducer unit accordingly): a
//! calibration in inches and one in millimetres are never compared raw. What is not compared is
//! said, with the reason: quantities only one of the two runs determined
//! ([`DriftReport::left_out`]) and tolerance keys that match no tracked quantity
//! ([`DriftReport::unused_tolerances`]).

use std::collections::BTreeMap;

use kinecal::units::Units;
use serde::Serialize;

use crate::error::{Error, Result};
use crate::model::{Calibration, Event};
use crate::robot_model::{latest_model_start, ModelChange};
use crate::text::printable;
use crate::units::{conversion, parse_units};

/// Which calibration the latest one is compared with.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Baseline {
    /// The first recorded calibration.
    First,
    /// The most recent earlier calibration that itself showed no flag against the first.
    LatestOk,
    /// A calibration by id.
    Id(i64),
}

/// Per-quantity tolerances: keys are parameter names or ids (`link3.y`, `p14`) or combination
/// expressions (`p14 + p20`), values in the quantity's unit (that of the robot's first record).
///
/// One quantity takes one tolerance: a file naming it twice (the same key twice, or a parameter
/// by its id and by its name, `p1` and `link1.x`) is refused, naming both.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Tolerances {
    entries: Vec<(String, f64)>,
    /// The file, when read from one.
    file: Option<String>,
    /// The line of each entry in the file, when read from one.
    lines: Vec<Option<usize>>,
}

impl Tolerances {
    /// Reads a TOML file of `key = value` lines (optionally under `[tolerances]`). Keys may be
    /// quoted (`"p14 + p20" = 0.5`) or not: an unquoted dotted key (`link1.x = 0.001`, which
    /// TOML reads as a table `link1` holding `x`) is the parameter name `link1.x`.
    pub fn parse_toml(text: &str, file: &str) -> Result<Self> {
        let fail = |message: String| Error::Tolerance {
            file: file.to_string(),
            message,
        };
        let doc: tolerance_file::Table = tolerance_file::parse(text).map_err(fail)?;
        let mut entries: Vec<(String, f64)> = Vec::new();
        let mut lines = Vec::new();
        for (k, v, line) in doc {
            if !(v > 0.0 && v.is_finite()) {
                return Err(fail(format!(
                    "tolerance `{}` must be a positive number",
                    printable(&k)
                )));
            }
            if entries.iter().any(|(e, _)| *e == k) {
                return Err(fail(format!(
                    "tolerance `{}` is given twice",
                    printable(&k)
                )));
            }
            entries.push((k, v));
            lines.push(line);
        }
        Ok(Tolerances {
            entries,
            file: Some(file.to_string()),
            lines,
        })
    }

    /// A tolerance per key.
    pub fn from_entries(entries: Vec<(String, f64)>) -> Self {
        Tolerances {
            entries,
            ..Default::default()
        }
    }

    /// Refuses tolerances that name one parameter of `history` twice: by its id and by its
    /// name (`p1 = 0.0001` and `link1.x = 1`); which one applied would depend on their order.
    fn check_names_against(&self, history: &[Calibration]) -> Result<()> {
        if self.entries.is_empty() {
            return Ok(());
        }
        let find = |k: &str| self.entries.iter().position(|(e, _)| e == k);
        for c in history {
            for p in &c.parameters {
                if p.id == p.name {
                    continue;
                }
                let (Some(a), Some(b)) = (find(&p.id), find(&p.name)) else {
                    continue;
                };
                let (a, b) = (a.min(b), a.max(b));
                let at = |k: usize| {
                    let key = format!("`{}`", printable(&self.entries[k].0));
                    match self.lines.get(k).copied().flatten() {
                        Some(line) => format!("{key} (line {line})"),
                        None => key,
                    }
                };
                let message = format!(
                    "tolerances {} and {} name the same quantity (parameter {} is {} in \
                     calibration {} of robot {}); give it one tolerance, by its id or by its name",
                    at(a),
                    at(b),
                    printable(&p.id),
                    printable(&p.name),
                    c.id,
                    printable(&c.robot_id)
                );
                return Err(match &self.file {
                    Some(file) => Error::Tolerance {
                        file: file.clone(),
                        message,
                    },
                    None => Error::Input(format!("the tolerances: {message}")),
                });
            }
        }
        Ok(())
    }

    /// The keys, in file order.
    pub fn keys(&self) -> impl Iterator<Item = &str> {
        self.entries.iter().map(|(k, _)| k.as_str())
    }

    fn get(&self, q: &Quantity) -> Option<f64> {
        self.entries
            .iter()
            .find(|(k, _)| matches_key(k, &q.key, &q.parameters))
            .map(|(_, v)| *v)
    }
}

/// Whether `k` names the quantity `key` (of parameter ids `parameters`): its name or
/// expression, or the id of its single parameter.
fn matches_key(k: &str, key: &str, parameters: &[String]) -> bool {
    k == key || (parameters.len() == 1 && k == parameters[0])
}

/// Settings of a drift analysis.
#[derive(Debug, Clone, PartialEq)]
pub struct DriftOptions {
    /// The baseline.
    pub baseline: Baseline,
    /// Flag changes beyond this many standard deviations (positive and finite).
    pub sigma: f64,
    /// Optional tolerances.
    pub tolerances: Tolerances,
}

impl Default for DriftOptions {
    fn default() -> Self {
        DriftOptions {
            baseline: Baseline::First,
            sigma: 3.0,
            tolerances: Tolerances::default(),
        }
    }
}

/// One tracked quantity.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct Quantity {
    /// The physical quantity in words, e.g. "link 3 length along y".
    pub quantity: String,
    /// The parameter name or the combination's expression.
    pub key: String,
    /// The parameter ids involved.
    pub parameters: Vec<String>,
    /// Unit (that of the robot's first record).
    pub unit: String,
    /// Value at the baseline.
    pub baseline: f64,
    /// Value at the latest calibration.
    pub latest: f64,
    /// `latest - baseline`.
    pub change: f64,
    /// `sqrt(s_baseline^2 + s_latest^2)`.
    pub sigma: f64,
    /// `|change| / sigma`.
    pub significance: f64,
    /// Tolerance from the file, if any.
    pub tolerance: Option<f64>,
    /// Weighted-regression slope over the whole history, per 30 days.
    pub trend_per_30_days: Option<f64>,
    /// Its standard error.
    pub trend_sigma: Option<f64>,
    /// Whether the change is flagged.
    pub flagged: bool,
    /// Why, when flagged.
    pub reason: Option<String>,
}

/// A quantity one of the two compared runs tracks and the other does not: not compared.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct LeftOut {
    /// The physical quantity in words.
    pub quantity: String,
    /// The parameter name or the combination's expression.
    pub key: String,
    /// The parameter ids involved.
    pub parameters: Vec<String>,
    /// Why it is not compared, e.g. "not determined by the data of the latest run
    /// (calibration 7)".
    pub reason: String,
}

/// A tolerance that applies to no compared quantity.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct UnusedTolerance {
    /// The key as written in the file.
    pub key: String,
    /// Why it is unused.
    pub reason: String,
}

/// The result of [`drift`].
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct DriftReport {
    /// The robot.
    pub robot_id: String,
    /// Calibrations in the history.
    pub calibrations: usize,
    /// Baseline calibration id and time.
    pub baseline_id: i64,
    /// Baseline time (RFC 3339).
    pub baseline_at: String,
    /// Latest calibration id.
    pub latest_id: i64,
    /// Latest time (RFC 3339).
    pub latest_at: String,
    /// The threshold K.
    pub sigma_threshold: f64,
    /// The length unit of every value (the robot's first record's).
    pub length_unit: String,
    /// The angle unit of every value (the robot's first record's).
    pub angle_unit: String,
    /// The flagged quantities.
    pub flags: Vec<Quantity>,
    /// Every compared quantity.
    pub quantities: Vec<Quantity>,
    /// Quantities only one of the two runs tracks, with the reason.
    pub left_out: Vec<LeftOut>,
    /// Tolerance keys that match no compared quantity, with the reason.
    pub unused_tolerances: Vec<UnusedTolerance>,
    /// The maintenance event the compared calibrations follow, when the caller analysed the
    /// segment since one ([`crate::current_segment`]); `drift` itself leaves it empty.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub since_event: Option<Event>,
    /// The change of robot model the compared calibrations follow, when the history holds
    /// calibrations of another model (a rebuilt robot recorded with the force option): those
    /// before it are not compared ([`ModelChange::left_out`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub since_model_change: Option<ModelChange>,
    /// Why nothing was compared, when the baseline is the latest calibration itself (a history
    /// of one calibration, or `--baseline` naming the latest): no quantities, nothing flagged.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub nothing_to_compare: Option<String>,
}

/// A value with its sigma, words and members, keyed for matching across calibrations; in the
/// history's units.
struct Tracked {
    key: String,
    words: String,
    parameters: Vec<String>,
    unit: String,
    value: f64,
    sigma: f64,
}

/// Describes a parameter name in words: `link3.y` -> "link 3 length along y".
pub(crate) fn words(name: &str) -> String {
    let axis_word = |c: &str| match c {
        "x" | "y" | "z" => format!("length along {c}"),
        "alpha" => "rotation about z (alpha)".to_string(),
        "beta" => "rotation about y (beta)".to_string(),
        "gamma" => "rotation about x (gamma)".to_string(),
        other => other.to_string(),
    };
    if let Some(rest) = name.strip_prefix("link") {
        if let Some((n, c)) = rest.split_once('.') {
            return format!("link {n} {}", axis_word(c));
        }
    }
    if let Some(rest) = name.strip_prefix("joint") {
        if let Some((n, c)) = rest.split_once('.') {
            return match c {
                "offset" => format!("joint {n} zero offset"),
                "slope" => format!("joint {n} transducer slope"),
                "coupling" => format!("joint {n} coupling factor"),
                "compliance" => format!("joint {n} compliance (1 / stiffness)"),
                "lateral" => format!("joint {n} lateral compliance"),
                _ => name.to_string(),
            };
        }
    }
    if let Some(rest) = name.strip_prefix("site.") {
        if let Some((n, c)) = rest.rsplit_once('.') {
            let w = axis_word(c).replace("length", "position");
            return format!("site {n} {w}");
        }
    }
    name.to_string()
}

/// Describes a combination: link components of the same kind are grouped, e.g. "z lengths of
/// links 1, 2, 3, 4, 5 and joint 3 zero offset, together".
fn combination_words(names: &[String]) -> String {
    let mut by_comp: Vec<(String, Vec<String>)> = Vec::new();
    let mut others = Vec::new();
    for n in names {
        match n.strip_prefix("link").and_then(|r| r.split_once('.')) {
            Some((k, c)) => match by_comp.iter_mut().find(|(cc, _)| cc == c) {
                Some((_, v)) => v.push(k.to_string()),
                None => by_comp.push((c.to_string(), vec![k.to_string()])),
            },
            None => others.push(words(n)),
        }
    }
    let mut parts: Vec<String> = by_comp
        .into_iter()
        .map(|(c, ks)| {
            let what = match c.as_str() {
                "x" | "y" | "z" => format!("{c} lengths"),
                "alpha" => "z rotations (alpha)".into(),
                "beta" => "y rotations (beta)".into(),
                "gamma" => "x rotations (gamma)".into(),
                other => other.to_string(),
            };
            match ks.split_last() {
                Some((last, rest)) if !rest.is_empty() => {
                    format!("{what} of links {} and {last}", rest.join(", "))
                }
                _ => words(&format!("link{}.{c}", ks.join(""))),
            }
        })
        .collect();
    parts.extend(others);
    format!("{}, together", parts.join(" and "))
}

/// The quantities `c` tracks, converted to `units`; and those whose unit cannot be converted,
/// with the reason.
fn tracked(c: &Calibration, units: &Units) -> (Vec<Tracked>, Vec<LeftOut>) {
    let mut raw = Vec::new();
    for p in &c.parameters {
        if let (true, true, Some(s)) = (p.estimated, p.determined, p.sigma) {
            raw.push(Tracked {
                key: p.name.clone(),
                words: words(&p.name),
                parameters: vec![p.id.clone()],
                unit: p.unit.clone(),
                value: p.value,
                sigma: s,
            });
        }
    }
    for comb in &c.combinations {
        let names: Vec<String> = comb.terms.iter().map(|t| t.1.clone()).collect();
        // The combination's value is in its first member's unit.
        let unit = comb
            .terms
            .first()
            .and_then(|t| c.parameters.iter().find(|p| p.id == t.0))
            .map_or(String::new(), |p| p.unit.clone());
        raw.push(Tracked {
            key: comb.expression.clone(),
            words: combination_words(&names),
            parameters: comb.terms.iter().map(|t| t.0.clone()).collect(),
            unit,
            value: comb.value,
            sigma: comb.sigma,
        });
    }
    let mut out = Vec::new();
    let mut left_out = Vec::new();
    for mut t in raw {
        match conversion(&t.unit, units) {
            Some((factor, unit)) => {
                t.value *= factor;
                t.sigma *= factor.abs();
                t.unit = unit;
                out.push(t);
            }
            None => left_out.push(LeftOut {
                quantity: t.words,
                key: t.key,
                parameters: t.parameters,
                reason: format!(
                    "its unit `{}` in calibration {} is not one kinecal converts",
                    printable(&t.unit),
                    c.id
                ),
            }),
        }
    }
    (out, left_out)
}

/// Why `c` (the baseline or the latest run, `role`) does not track `key`.
fn why_not_tracked(c: &Calibration, key: &str, role: &str) -> String {
    let run = format!("{role} (calibration {})", c.id);
    match c.parameters.iter().find(|p| p.name == key) {
        Some(p) if !p.estimated => format!("not estimated by {run}"),
        Some(_) => format!("not determined by the data of {run}"),
        None if c.combinations.is_empty() && key.contains(' ') => {
            format!("{run} has no determined combination")
        }
        None if key.contains(' ') => {
            format!("not a determined combination of {run}")
        }
        None => format!("not a parameter of the robot model of {run}"),
    }
}

/// The units every value of `history` is converted to: those of its first record.
fn history_units(history: &[Calibration]) -> Result<Units> {
    let first = history
        .first()
        .ok_or_else(|| Error::Input("empty history".into()))?;
    parse_units(&first.length_unit, &first.angle_unit).ok_or_else(|| {
        Error::Input(format!(
            "calibration {}: units `{}` and `{}` are not kinecal units",
            first.id,
            printable(&first.length_unit),
            printable(&first.angle_unit)
        ))
    })
}

fn compare(
    series: &BTreeMap<String, Vec<Sample>>,
    units: &Units,
    base: &Calibration,
    latest: &Calibration,
    opts: &DriftOptions,
) -> (Vec<Quantity>, Vec<LeftOut>) {
    let (b, mut left_out) = tracked(base, units);
    let (l, left_latest) = tracked(latest, units);
    left_out.extend(left_latest);
    let mut out = Vec::new();
    for b in &b {
        if !l.iter().any(|q| q.key == b.key) && !left_out.iter().any(|q| q.key == b.key) {
            left_out.push(LeftOut {
                quantity: b.words.clone(),
                key: b.key.clone(),
                parameters: b.parameters.clone(),
                reason: why_not_tracked(latest, &b.key, "the latest run"),
            });
        }
    }
    for l in l {
        let Some(b) = b.iter().find(|q| q.key == l.key) else {
            if !left_out.iter().any(|q| q.key == l.key) {
                left_out.push(LeftOut {
                    reason: why_not_tracked(base, &l.key, "the baseline run"),
                    quantity: l.words,
                    key: l.key,
                    parameters: l.parameters,
                });
            }
            continue;
        };
        let change = l.value - b.value;
        let sigma = (b.sigma * b.sigma + l.sigma * l.sigma).sqrt();
        let significance = if sigma > 0.0 {
            change.abs() / sigma
        } else if change == 0.0 {
            0.0
        } else {
            f64::INFINITY
        };
        // Trend over every calibration that tracks this quantity.
        let pts: Vec<(f64, f64, f64)> = series
            .get(&l.key)
            .into_iter()
            .flatten()
            .map(|s| (s.at as f64 / 86400.0, s.value, s.sigma))
            .filter(|p| p.2 > 0.0)
            .collect();
        let (trend, trend_sigma) = regression(&pts);
        let mut q = Quantity {
            quantity: l.words.clone(),
            key: l.key.clone(),
            parameters: l.parameters.clone(),
            unit: l.unit.clone(),
            baseline: b.value,
            latest: l.value,
            change,
            sigma,
            significance,
            tolerance: None,
            trend_per_30_days: trend.map(|t| t * 30.0),
            trend_sigma: trend_sigma.map(|t| t * 30.0),
            flagged: false,
            reason: None,
        };
        q.tolerance = opts.tolerances.get(&q);
        if significance > opts.sigma {
            q.flagged = true;
            q.reason = Some(format!("change {:.1} sigma > {}", significance, opts.sigma));
        } else if let Some(t) = q.tolerance.filter(|t| change.abs() > *t) {
            q.flagged = true;
            q.reason = Some(format!("change {:.6} beyond tolerance {t}", change.abs()));
        }
        out.push(q);
    }
    (out, left_out)
}

/// Weighted least-squares slope of value over time (days) and its standard error.
fn regression(pts: &[(f64, f64, f64)]) -> (Option<f64>, Option<f64>) {
    if pts.len() < 2 {
        return (None, None);
    }
    let w: Vec<f64> = pts.iter().map(|p| 1.0 / (p.2 * p.2)).collect();
    let sw: f64 = w.iter().sum();
    let tm = pts.iter().zip(&w).map(|(p, w)| p.0 * w).sum::<f64>() / sw;
    let vm = pts.iter().zip(&w).map(|(p, w)| p.1 * w).sum::<f64>() / sw;
    let stt: f64 = pts
        .iter()
        .zip(&w)
        .map(|(p, w)| w * (p.0 - tm).powi(2))
        .sum();
    if stt <= 0.0 {
        return (None, None);
    }
    let slope = pts
        .iter()
        .zip(&w)
        .map(|(p, w)| w * (p.0 - tm) * (p.1 - vm))
        .sum::<f64>()
        / stt;
    (Some(slope), Some((1.0 / stt).sqrt()))
}

/// One calibration's value of a tracked quantity.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct Sample {
    /// The calibration's id.
    pub id: i64,
    /// Its time (Unix seconds).
    pub at: i64,
    /// The value, in the units of the history's first record.
    pub value: f64,
    /// Its standard deviation, same unit.
    pub sigma: f64,
}

/// Every tracked quantity's samples over `history`, by key (one pass over the records).
fn series_in(history: &[Calibration], units: &Units) -> BTreeMap<String, Vec<Sample>> {
    let mut out: BTreeMap<String, Vec<Sample>> = BTreeMap::new();
    for c in history {
        for q in tracked(c, units).0 {
            out.entry(q.key).or_default().push(Sample {
                id: c.id,
                at: c.at,
                value: q.value,
                sigma: q.sigma,
            });
        }
    }
    out
}

/// Every tracked quantity's values in a robot's `history` (oldest first), by key, converted to
/// the units of its first record: [`samples`] for every key at once.
pub fn all_samples(history: &[Calibration]) -> Result<BTreeMap<String, Vec<Sample>>> {
    Ok(series_in(history, &history_units(history)?))
}

fn samples_in(history: &[Calibration], units: &Units, key: &str) -> Vec<Sample> {
    history
        .iter()
        .filter_map(|c| {
            tracked(c, units)
                .0
                .into_iter()
                .find(|q| q.key == key)
                .map(|q| Sample {
                    id: c.id,
                    at: c.at,
                    value: q.value,
                    sigma: q.sigma,
                })
        })
        .collect()
}

/// Every calibration's value of the quantity `key` (a parameter name or a combination's
/// expression) in a robot's `history` (oldest first), converted to the units of its first
/// record; calibrations that do not track it are skipped.
pub fn samples(history: &[Calibration], key: &str) -> Result<Vec<Sample>> {
    Ok(samples_in(history, &history_units(history)?, key))
}

/// [`samples`] in the units of the record `like` (the first of the segment whose quantities
/// are drawn), not of `history`'s first.
pub(crate) fn samples_like(
    history: &[Calibration],
    like: &Calibration,
    key: &str,
) -> Result<Vec<Sample>> {
    Ok(samples_in(
        history,
        &history_units(std::slice::from_ref(like))?,
        key,
    ))
}

/// Why a robot's `history` cannot be compared, when one of its calibrations has no parameters
/// (a damaged record: there would be nothing to find changed).
pub(crate) fn without_parameters(history: &[Calibration]) -> Option<String> {
    let c = history.iter().find(|c| c.parameters.is_empty())?;
    Some(format!(
        "calibration {} of robot {} has no parameters (a damaged record): its drift cannot be \
         computed; record the calibration again, or mark what was done with a maintenance event",
        c.id,
        printable(&c.robot_id)
    ))
}

/// Compares the latest calibration of a robot's `history` (oldest first) with the baseline.
/// A history holding a calibration without parameters (a damaged record) is refused
/// ([`Error::Input`]): nothing would be found changed. When the baseline is the latest
/// calibration itself (a history of one, or a baseline naming the latest), nothing is
/// compared: no quantities, and [`DriftReport::nothing_to_compare`] says why (every change
/// would be zero, and "nothing flagged" would read as a clean bill of health). Calibrations
/// of two robot models are never compared: when `history` changes model (a rebuilt robot
/// recorded with the force option), only the calibrations since the latest change are, and
/// [`DriftReport::since_model_change`] names the change and the calibrations left out.
pub fn drift(history: &[Calibration], opts: &DriftOptions) -> Result<DriftReport> {
    let mut report = drift_or_tracked(history, opts)?;
    if report.baseline_id == report.latest_id {
        report.nothing_to_compare = Some(if report.calibrations == 1 {
            format!(
                "one calibration of robot `{}` to look at (calibration {}): drift compares the \
                 latest calibration with an earlier one; record another to compare",
                printable(&report.robot_id),
                report.latest_id
            )
        } else {
            format!(
                "the baseline is the latest calibration itself (calibration {}): name an \
                 earlier one",
                report.latest_id
            )
        });
        report.quantities.clear();
        report.flags.clear();
        report.left_out.clear();
        report.unused_tolerances.clear();
    }
    Ok(report)
}

/// [`drift`], with the latest calibration compared with itself when it is the baseline: every
/// quantity it tracks, for a plot of one calibration.
pub(crate) fn drift_or_tracked(
    history: &[Calibration],
    opts: &DriftOptions,
) -> Result<DriftReport> {
    if !(opts.sigma.is_finite() && opts.sigma > 0.0) {
        return Err(Error::InvalidSigma { value: opts.sigma });
    }
    if history.is_empty() {
        return Err(Error::Input("empty history".into()));
    }
    if let Some(problem) = without_parameters(history) {
        return Err(Error::Input(problem));
    }
    // Two robot models are never compared: only the calibrations of the latest one, since it
    // changed.
    let (start, model_change) = latest_model_start(history);
    let (whole, history) = (history, &history[start..]);
    let (Some(first), Some(latest)) = (history.first(), history.last()) else {
        return Err(Error::Input("empty history".into()));
    };
    opts.tolerances.check_names_against(history)?;
    let units = history_units(history)?;
    let series = series_in(history, &units);
    let base =
        match opts.baseline {
            Baseline::First => first,
            Baseline::Id(id) => history.iter().find(|c| c.id == id).ok_or_else(|| {
                match model_change
                    .as_ref()
                    .filter(|_| whole.iter().any(|c| c.id == id))
                {
                    Some(m) => Error::Input(format!(
                        "calibration {id} cannot be the baseline of robot `{}`: {}; name a \
                     calibration of the latest model",
                        printable(&latest.robot_id),
                        m.reason()
                    )),
                    None => Error::Input(format!(
                        "calibration {id} is not in the history of robot `{}`",
                        printable(&latest.robot_id)
                    )),
                }
            })?,
            Baseline::LatestOk => history[..history.len() - 1]
                .iter()
                .rev()
                .find(|c| {
                    compare(&series, &units, first, c, opts)
                        .0
                        .iter()
                        .all(|q| !q.flagged)
                })
                .unwrap_or(first),
        };
    let (quantities, left_out) = compare(&series, &units, base, latest, opts);
    let unused_tolerances = opts
        .tolerances
        .keys()
        .filter(|k| {
            !quantities
                .iter()
                .any(|q| matches_key(k, &q.key, &q.parameters))
        })
        .map(|k| {
            let reason = match left_out
                .iter()
                .find(|q| matches_key(k, &q.key, &q.parameters))
            {
                Some(q) => format!("its quantity `{}` is left out: {}", q.key, q.reason),
                None => "matches no tracked quantity (the name or id of a determined parameter, or a determined combination's expression)".to_string(),
            };
            UnusedTolerance {
                key: k.to_string(),
                reason,
            }
        })
        .collect();
    Ok(DriftReport {
        robot_id: latest.robot_id.clone(),
        calibrations: history.len(),
        baseline_id: base.id,
        baseline_at: base.at_text.clone(),
        latest_id: latest.id,
        latest_at: latest.at_text.clone(),
        sigma_threshold: opts.sigma,
        length_unit: units.length.to_string(),
        angle_unit: units.angle.to_string(),
        flags: quantities.iter().filter(|q| q.flagged).cloned().collect(),
        quantities,
        left_out,
        unused_tolerances,
        since_event: None,
        since_model_change: model_change,
        nothing_to_compare: None,
    })
}

/// A minimal reader for tolerance files: `key = number` lines, `#` comments, an optional
/// `[tolerances]` header; keys may be quoted, and dotted keys name dotted parameters.
mod tolerance_file {
    use toml_edit::{Item, TableLike};

    /// Each key, its value and its line (1 first).
    pub(super) type Table = Vec<(String, f64, Option<usize>)>;

    pub(super) fn parse(text: &str) -> Result<Table, String> {
        // A parsed document (not an editable one) keeps where each value is: its line.
        let doc = toml_edit::Document::parse(text).map_err(|e| e.to_string())?;
        let root = doc.as_table();
        let mut out = Vec::new();
        match root.get("tolerances").and_then(Item::as_table_like) {
            Some(t) => {
                if let Some((k, _)) = root.iter().find(|(k, _)| *k != "tolerances") {
                    return Err(format!(
                        "`{k}` is outside the [tolerances] table: put every tolerance under it"
                    ));
                }
                flatten(text, "", t, &mut out)?;
            }
            None => flatten(text, "", root, &mut out)?,
        }
        Ok(out)
    }

    /// `link1.x = 1` is a table `link1` holding `x`: its keys joined with dots.
    fn flatten(
        text: &str,
        prefix: &str,
        table: &dyn TableLike,
        out: &mut Table,
    ) -> Result<(), String> {
        for (k, v) in table.iter() {
            let key = if prefix.is_empty() {
                k.to_string()
            } else {
                format!("{prefix}.{k}")
            };
            if let Some(t) = v.as_table_like() {
                flatten(text, &key, t, out)?;
                continue;
            }
            let n = v
                .as_float()
                .or_else(|| v.as_integer().map(|i| i as f64))
                .ok_or_else(|| format!("`{key}`: expected a number"))?;
            let line = v
                .span()
                .and_then(|r| text.get(..r.start))
                .map(|before| before.matches('\n').count() + 1);
            out.push((key, n, line));
        }
        Ok(())
    }
}
