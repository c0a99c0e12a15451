//! Drift of determined quantities over a robot's history.
//!
//! Tracked quantities are the individually determined parameters and the determined
//! combinations of identically redundant groups, never a lone redundant parameter (its value
//! wanders with the solver's path, thesis Table 4.8). For each: the change from the baseline,
//! its significance `|delta| / sqrt(s1^2 + s2^2)`, the trend per 30 days (weighted regression
//! over the whole history, with its standard error), and a flag when the change exceeds `K`
//! sigma or a tolerance.

use serde::Serialize;

use crate::store::Calibration;
use crate::{Error, Result};

/// Which calibration the latest one is compared with.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Baseline {
    /// The first recorded calibration.
    First,
    /// The most recent earlier calibration that itself showed no flag against the first.
    LatestOk,
    /// A calibration by id.
    Id(i64),
}

/// Per-quantity tolerances: keys are parameter names or ids (`link3.y`, `p14`) or combination
/// expressions (`p14 + p20`), values in the quantity's unit.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Tolerances {
    entries: Vec<(String, f64)>,
}

impl Tolerances {
    /// Reads a TOML file of `key = value` lines (optionally under `[tolerances]`).
    pub fn parse_toml(text: &str, file: &str) -> Result<Self> {
        let doc: tolerance_file::Table =
            tolerance_file::parse(text).map_err(|e| Error::Input(format!("{file}: {e}")))?;
        let mut entries = Vec::new();
        for (k, v) in doc {
            if !(v > 0.0 && v.is_finite()) {
                return Err(Error::Input(format!(
                    "{file}: tolerance `{k}` must be a positive number"
                )));
            }
            entries.push((k, v));
        }
        Ok(Tolerances { entries })
    }

    fn get(&self, q: &Quantity) -> Option<f64> {
        self.entries
            .iter()
            .find(|(k, _)| *k == q.key || (q.parameters.len() == 1 && *k == q.parameters[0]))
            .map(|(_, v)| *v)
    }
}

/// Settings of a drift analysis.
#[derive(Debug, Clone, PartialEq)]
pub struct DriftOptions {
    /// The baseline.
    pub baseline: Baseline,
    /// Flag changes beyond this many standard deviations.
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
pub struct Quantity {
    /// The physical quantity in words, e.g. "link 3 length along y".
    pub quantity: String,
    /// The parameter name or the combination's expression.
    pub key: String,
    /// The parameter ids involved.
    pub parameters: Vec<String>,
    /// Unit.
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

/// The result of [`drift`].
#[derive(Debug, Clone, PartialEq, Serialize)]
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
    /// The flagged quantities.
    pub flags: Vec<Quantity>,
    /// Every tracked quantity.
    pub quantities: Vec<Quantity>,
}

/// A value with its sigma, words and members, keyed for matching across calibrations.
struct Tracked {
    key: String,
    words: String,
    parameters: Vec<String>,
    unit: String,
    value: f64,
    sigma: f64,
}

/// Describes a parameter name in words: `link3.y` -> "link 3 length along y".
pub fn words(name: &str) -> String {
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
            if ks.len() == 1 {
                words(&format!("link{}.{c}", ks[0]))
            } else {
                let (last, rest) = ks.split_last().expect("two or more");
                format!("{what} of links {} and {last}", rest.join(", "))
            }
        })
        .collect();
    parts.extend(others);
    format!("{}, together", parts.join(" and "))
}

fn tracked(c: &Calibration) -> Vec<Tracked> {
    let mut out = Vec::new();
    for p in &c.parameters {
        if let (true, true, Some(s)) = (p.estimated, p.determined, p.sigma) {
            out.push(Tracked {
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
        let unit = comb
            .terms
            .first()
            .and_then(|t| c.parameters.iter().find(|p| p.id == t.0))
            .map_or(String::new(), |p| p.unit.clone());
        out.push(Tracked {
            key: comb.expression.clone(),
            words: combination_words(&names),
            parameters: comb.terms.iter().map(|t| t.0.clone()).collect(),
            unit,
            value: comb.value,
            sigma: comb.sigma,
        });
    }
    out
}

fn compare(
    history: &[Calibration],
    base: &Calibration,
    latest: &Calibration,
    opts: &DriftOptions,
) -> Vec<Quantity> {
    let b = tracked(base);
    let mut out = Vec::new();
    for l in tracked(latest) {
        let Some(b) = b.iter().find(|q| q.key == l.key) else {
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
        let pts: Vec<(f64, f64, f64)> = history
            .iter()
            .filter_map(|c| {
                tracked(c)
                    .into_iter()
                    .find(|q| q.key == l.key)
                    .map(|q| (c.at as f64 / 86400.0, q.value, q.sigma))
            })
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
    out
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

/// Compares the latest calibration of a robot's `history` (oldest first) with the baseline.
pub fn drift(history: &[Calibration], opts: &DriftOptions) -> Result<DriftReport> {
    let (Some(first), Some(latest)) = (history.first(), history.last()) else {
        return Err(Error::Input("empty history".into()));
    };
    let base = match opts.baseline {
        Baseline::First => first,
        Baseline::Id(id) => history.iter().find(|c| c.id == id).ok_or_else(|| {
            Error::Input(format!(
                "calibration {id} is not in the history of robot `{}`",
                latest.robot_id
            ))
        })?,
        Baseline::LatestOk => history[..history.len() - 1]
            .iter()
            .rev()
            .find(|c| compare(history, first, c, opts).iter().all(|q| !q.flagged))
            .unwrap_or(first),
    };
    let quantities = compare(history, base, latest, opts);
    Ok(DriftReport {
        robot_id: latest.robot_id.clone(),
        calibrations: history.len(),
        baseline_id: base.id,
        baseline_at: base.at_text.clone(),
        latest_id: latest.id,
        latest_at: latest.at_text.clone(),
        sigma_threshold: opts.sigma,
        flags: quantities.iter().filter(|q| q.flagged).cloned().collect(),
        quantities,
    })
}

/// A minimal reader for tolerance files: `key = number` lines, `#` comments, an optional
/// `[tolerances]` header; keys may be quoted.
mod tolerance_file {
    pub type Table = Vec<(String, f64)>;

    pub fn parse(text: &str) -> Result<Table, String> {
        let doc: toml_edit::DocumentMut = text
            .parse()
            .map_err(|e: toml_edit::TomlError| e.to_string())?;
        let table = match doc.get("tolerances").and_then(|t| t.as_table()) {
            Some(t) => t.clone(),
            None => doc.as_table().clone(),
        };
        let mut out = Vec::new();
        for (k, v) in table.iter() {
            let n = v
                .as_float()
                .or_else(|| v.as_integer().map(|i| i as f64))
                .ok_or_else(|| format!("`{k}`: expected a number"))?;
            out.push((k.to_string(), n));
        }
        Ok(out)
    }
}
