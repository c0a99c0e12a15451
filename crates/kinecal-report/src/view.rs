//! The calibration's view: what its text summary (`kinecal calibrate`) and its HTML page show,
//! built once from the report in display units and rendered by both. The verdict, the run (data,
//! method, convergence), the error tables (before, the solver's start, after; identification and
//! held out), the cross-validation folds, the parameter table, the determined combinations, the
//! outliers, the warnings ranked errors > cautions > notes, and the page's figures.
//!
//! Numbers stay numbers here: each renderer formats them for its medium (the text's fixed
//! columns, the page's four significant digits, both from [`crate::number`]); labels, units,
//! which rows and tables exist and in what order are decided here, once.

use kinecal::report::{CalibrationReport, ErrorStats};

use crate::chart::{tick_label, Line, Panel};
use crate::display::{self, combination_unit, Convert, DisplayUnits};
use crate::number::ratio;
use crate::verdict::{self, Ranked, Verdict};

/// A calibration as its summary and its page show it.
#[derive(Debug, Clone)]
pub struct CalibrationView {
    /// The report with every length and angle in display units ([`display::calibration`]):
    /// what the sections below are built from, and what a renderer reads for the rest.
    pub shown: CalibrationReport,
    /// The conversion to display units; every unit label comes from it.
    pub convert: Convert,
    /// The verdict: converged or not, the accuracy reached, what to do next.
    pub verdict: Verdict,
    /// What was solved, and how it ended.
    pub run: Run,
    /// Objective and errors on the identification data: before, at the solver's start, after.
    pub errors: ErrorTable,
    /// The errors on the identification and the held-out data, with validation data.
    pub validation: Option<Validation>,
    /// The held-out errors of each fold, with cross-validation.
    pub cross_validation: Option<CrossValidation>,
    /// The estimated parameters.
    pub parameters: Vec<ParameterRow>,
    /// The combinations of parameters the data determines but cannot separate.
    pub combinations: Vec<CombinationRow>,
    /// The observations beyond the outlier threshold.
    pub outliers: Vec<OutlierRow>,
    /// The warnings ranked: errors, then cautions, then notes.
    pub warnings: Vec<Ranked>,
    /// The page's figures.
    pub figures: Figures,
}

impl CalibrationView {
    /// The view of `rep`, its lengths and angles in `units`.
    pub fn new(rep: &CalibrationReport, units: DisplayUnits) -> CalibrationView {
        let convert = Convert::of(rep, units);
        let shown = display::calibration(rep, &convert);
        CalibrationView {
            verdict: verdict::verdict(rep, units),
            run: Run::of(&shown),
            errors: ErrorTable::of(&shown, &convert),
            validation: Validation::of(&shown, &convert),
            cross_validation: CrossValidation::of(&shown, &convert),
            parameters: ParameterRow::estimated(&shown),
            combinations: CombinationRow::all(&shown),
            outliers: OutlierRow::all(&shown),
            warnings: verdict::ranked_warnings(&shown),
            figures: Figures::of(&shown, &convert),
            shown,
            convert,
        }
    }

    /// The label of lengths shown: `mm`.
    pub fn l(&self) -> &'static str {
        self.convert.l()
    }

    /// The label of angles shown: `deg`.
    pub fn a(&self) -> &'static str {
        self.convert.a()
    }
}

/// What was solved, and how it ended.
#[derive(Debug, Clone, PartialEq)]
pub struct Run {
    /// The robot's name (empty for an unnamed robot, an imported DH table).
    pub robot: String,
    /// Postures measured.
    pub postures: usize,
    /// Observations.
    pub measurements: usize,
    /// The observations by kind: `30 distances, 40 contacts`.
    pub observations: String,
    /// Residual rows.
    pub residuals: usize,
    /// The solver: `lm`.
    pub method: String,
    /// The orientation residuals: `rotvec`.
    pub orientation_error: String,
    /// `solver` or `min-change`.
    pub solution: String,
    /// A given calibration, assessed (not solved).
    pub given: bool,
    /// Whether the solver converged.
    pub converged: bool,
    /// Its iterations.
    pub iterations: usize,
    /// Why it stopped.
    pub termination: String,
    /// The stationarity measures at the end: `reduction 1.3e-24, step 1.2e-16, gradient 7.0e-13`.
    pub stationarity: Option<String>,
    /// A far start's closed-form placement: the RMS position error before and after it.
    pub start_placement: Option<[f64; 2]>,
    /// The loss: `squared`, `huber 1.345 x robust spread`.
    pub loss: String,
    /// Under a robust loss, the residual rows it down-weighted.
    pub down_weighted_rows: Option<usize>,
}

impl Run {
    fn of(r: &CalibrationReport) -> Run {
        let observations = r
            .observations
            .iter()
            .map(|k| {
                format!(
                    "{} {}{}",
                    k.count,
                    k.kind,
                    if k.count == 1 { "" } else { "s" }
                )
            })
            .collect::<Vec<_>>()
            .join(", ");
        let stationarity = r.stationarity.as_ref().map(|st| {
            format!(
                "reduction {:.1e}, step {}, gradient {:.1e}",
                st.predicted_reduction,
                st.step.map_or("-".to_string(), |v| format!("{v:.1e}")),
                st.gradient
            )
        });
        Run {
            robot: r.robot.clone(),
            postures: r.postures,
            measurements: r.measurements,
            observations,
            residuals: r.residuals,
            method: r.method.as_str().to_string(),
            orientation_error: r.orientation_error.as_str().to_string(),
            solution: r.solution.clone(),
            given: r.given,
            converged: r.converged,
            iterations: r.iterations,
            termination: r.termination.describe().to_string(),
            stationarity,
            start_placement: r
                .start_placement
                .as_ref()
                .map(|p| [p.rms_before, p.rms_after]),
            loss: r.loss.clone(),
            down_weighted_rows: r.down_weighted_rows,
        }
    }

    /// `converged` or `NOT converged`.
    pub fn convergence(&self) -> &'static str {
        if self.converged {
            "converged"
        } else {
            "NOT converged"
        }
    }
}

/// One row of the [`ErrorTable`].
#[derive(Debug, Clone, PartialEq)]
pub struct ErrorRow {
    /// `RMS position error (mm)`.
    pub label: String,
    /// Before: the nominal robot.
    pub before: f64,
    /// At the solver's start, when it started elsewhere and has this figure.
    pub start: Option<f64>,
    /// After.
    pub after: f64,
}

/// The objective and the errors on the identification data, before and after (and at the
/// solver's start when it started from elsewhere than the nominal robot).
#[derive(Debug, Clone, PartialEq)]
pub struct ErrorTable {
    /// Whether the table has a start column.
    pub start: bool,
    /// The weighted objective.
    pub objective: ErrorRow,
    /// RMS and max of the position errors, the other metrics' (distances, contacts), then the
    /// attitude errors.
    pub rows: Vec<ErrorRow>,
}

impl ErrorTable {
    fn of(r: &CalibrationReport, c: &Convert) -> ErrorTable {
        let (l, a) = (c.l(), c.a());
        let start = r.start.as_ref();
        let row = |label: String, before: f64, start: Option<f64>, after: f64| ErrorRow {
            label,
            before,
            start,
            after,
        };
        let mut rows = Vec::new();
        let (ib, ia) = (&r.identification.before, &r.identification.after);
        if ib.positions > 0 {
            rows.push(row(
                format!("RMS position error ({l})"),
                r.rms_position_before,
                start.map(|st| st.rms_position),
                r.rms_position_after,
            ));
            rows.push(row(
                format!("max position error ({l})"),
                r.max_position_before,
                start.map(|st| st.max_position),
                r.max_position_after,
            ));
        }
        let is = r.identification.start.as_ref();
        for (k, (b, af)) in ib.other.iter().zip(&ia.other).enumerate() {
            let st = is.and_then(|st| st.other.get(k));
            let l = if b.metric == "pixel" { "px" } else { l };
            rows.push(row(
                format!("RMS {} error ({l})", b.metric),
                b.rms,
                st.map(|m| m.rms),
                af.rms,
            ));
            rows.push(row(
                format!("max {} error ({l})", b.metric),
                b.max,
                st.map(|m| m.max),
                af.max,
            ));
        }
        if let (Some(rb), Some(ra), Some(mb), Some(ma)) = (
            r.rms_orientation_before,
            r.rms_orientation_after,
            r.max_orientation_before,
            r.max_orientation_after,
        ) {
            rows.push(row(
                format!("RMS attitude error ({a})"),
                rb,
                start.and_then(|st| st.rms_orientation),
                ra,
            ));
            rows.push(row(
                format!("max attitude error ({a})"),
                mb,
                start.and_then(|st| st.max_orientation),
                ma,
            ));
        }
        ErrorTable {
            start: start.is_some(),
            objective: row(
                "objective (weighted)".into(),
                r.objective_before,
                start.map(|st| st.objective),
                r.objective_after,
            ),
            rows,
        }
    }
}

/// A kind of error a [`StatsTable`] shows.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Metric {
    Position,
    Attitude,
    Other(String),
}

impl Metric {
    /// RMS, mean, p95 and max of this kind in `e`, if it has any.
    fn pick(&self, e: &ErrorStats) -> Option<[f64; 4]> {
        match self {
            Metric::Position => (e.positions > 0).then_some([
                e.rms_position,
                e.mean_position,
                e.p95_position,
                e.max_position,
            ]),
            Metric::Attitude => Some([
                e.rms_orientation?,
                e.mean_orientation?,
                e.p95_orientation?,
                e.max_orientation?,
            ]),
            Metric::Other(metric) => e
                .other
                .iter()
                .find(|m| &m.metric == metric)
                .map(|m| [m.rms, m.mean, m.p95, m.max]),
        }
    }
}

/// One row of a [`StatsTable`]: a data set at one stage.
#[derive(Debug, Clone, PartialEq)]
pub struct StatsRow {
    /// `identification (46 postures) before`, `validation after`.
    pub label: String,
    /// RMS, mean, p95 and max; `None` where the set has no error of this kind.
    pub stats: Option<[f64; 4]>,
}

/// The errors of one kind (positions, attitudes, distances, contacts) on the identification and
/// the validation data, before, at the start and after.
#[derive(Debug, Clone, PartialEq)]
pub struct StatsTable {
    /// `position error (mm)`.
    pub title: String,
    /// The rows.
    pub rows: Vec<StatsRow>,
}

/// The accuracy on the identification and the held-out data.
#[derive(Debug, Clone, PartialEq)]
pub struct Validation {
    /// One table per kind of error present.
    pub tables: Vec<StatsTable>,
    /// What else to know, one sentence each: the residuals in their standard deviations, the
    /// sessions whose frames were re-estimated on the validation data.
    pub notes: Vec<String>,
}

impl Validation {
    fn of(r: &CalibrationReport, c: &Convert) -> Option<Validation> {
        let v = r.validation.as_ref()?;
        let (l, a) = (c.l(), c.a());
        let id = &r.identification;
        let mut sets = vec![(
            format!("identification ({} postures) before", id.postures),
            &id.before,
        )];
        if let Some(st) = &id.start {
            sets.push(("identification start".to_string(), st));
        }
        sets.push(("identification after".to_string(), &id.after));
        sets.push((
            format!("validation ({} postures) before", v.postures),
            &v.before,
        ));
        if let Some(st) = &v.start {
            sets.push(("validation start".to_string(), st));
        }
        sets.push(("validation after".to_string(), &v.after));
        // Positions, attitudes, then the other metrics in their first appearance's order.
        let mut metrics = Vec::new();
        if sets.iter().any(|(_, e)| e.positions > 0) {
            metrics.push((Metric::Position, format!("position error ({l})")));
        }
        if sets.iter().any(|(_, e)| e.rms_orientation.is_some()) {
            metrics.push((Metric::Attitude, format!("attitude error ({a})")));
        }
        for (_, e) in &sets {
            for m in &e.other {
                let other = Metric::Other(m.metric.clone());
                if !metrics.iter().any(|(k, _)| k == &other) {
                    let unit = if m.metric == "pixel" { "px" } else { l };
                    metrics.push((other, format!("{} error ({unit})", m.metric)));
                }
            }
        }
        let tables = metrics
            .into_iter()
            .map(|(metric, title)| StatsTable {
                title,
                rows: sets
                    .iter()
                    .map(|(label, e)| StatsRow {
                        label: label.clone(),
                        stats: metric.pick(e),
                    })
                    .collect(),
            })
            .collect();
        let mut notes = Vec::new();
        if let (Some(ni), Some(nv)) = (id.normalized_rms, v.normalized_rms) {
            notes.push(format!(
                "residuals in their standard deviations (RMS): identification {} -> {}, \
                 validation {} -> {}",
                ratio(ni[0]),
                ratio(ni[1]),
                ratio(nv[0]),
                ratio(nv[1])
            ));
        }
        if !v.sessions_refitted.is_empty() {
            notes.push(format!(
                "validation sessions identification never saw ({}): their measurement frames \
                 re-estimated on the validation data first (6 parameters each, the robot held), \
                 for both robots",
                v.sessions_refitted.join(", ")
            ));
        }
        Some(Validation { tables, notes })
    }
}

/// One fold of a [`CrossValidation`] (or all of them together).
#[derive(Debug, Clone, PartialEq)]
pub struct FoldRow {
    /// Postures held out.
    pub postures: usize,
    /// Observations held out.
    pub observations: usize,
    /// Mean, RMS, p95 and max of the held-out errors.
    pub stats: [f64; 4],
    /// The held-out posture with the largest error.
    pub worst_posture: Option<String>,
    /// The rank of the fold's fit.
    pub rank: Option<usize>,
    /// The parameters the fold estimated.
    pub estimated: usize,
    /// Whether the fold's fit converged.
    pub converged: bool,
}

/// Cross-validation by posture folds: each fold's calibration checked on the postures it left
/// out.
#[derive(Debug, Clone, PartialEq)]
pub struct CrossValidation {
    /// `6 folds by posture (interleaved in file order)`.
    pub folds_by: String,
    /// `held-out position error (mm)`.
    pub measure: String,
    /// The folds.
    pub folds: Vec<FoldRow>,
    /// All the held-out errors together (its rank and worst posture empty).
    pub all: FoldRow,
    /// The bootstrap 95 % interval of the held-out mean.
    pub mean_interval: [f64; 2],
}

impl CrossValidation {
    fn of(r: &CalibrationReport, c: &Convert) -> Option<CrossValidation> {
        let cv = r.cross_validation.as_ref()?;
        let stats = |m: &kinecal::report::MetricStats| [m.mean, m.rms, m.p95, m.max];
        let folds = cv
            .folds
            .iter()
            .map(|f| FoldRow {
                postures: f.postures,
                observations: f.errors.count,
                stats: stats(&f.errors),
                worst_posture: f.worst_posture.clone(),
                rank: f.rank,
                estimated: f.estimated.len(),
                converged: f.converged,
            })
            .collect();
        Some(CrossValidation {
            folds_by: format!(
                "{} folds by posture ({})",
                cv.folds.len(),
                match cv.seed {
                    Some(seed) => format!("shuffled with seed {seed}"),
                    None => "interleaved in file order".to_string(),
                }
            ),
            measure: format!("held-out {} error ({})", cv.metric, c.l()),
            folds,
            all: FoldRow {
                postures: cv.folds.iter().map(|f| f.postures).sum(),
                observations: cv.overall.count,
                stats: stats(&cv.overall),
                worst_posture: None,
                rank: None,
                estimated: 0,
                converged: true,
            },
            mean_interval: [cv.mean_low, cv.mean_high],
        })
    }
}

/// One estimated parameter.
#[derive(Debug, Clone, PartialEq)]
pub struct ParameterRow {
    /// `p12`.
    pub id: String,
    /// `link2.z`.
    pub name: String,
    /// Its unit shown: `mm`, `deg/unit`.
    pub unit: String,
    /// Before.
    pub initial: f64,
    /// After.
    pub estimated: f64,
    /// The change.
    pub change: f64,
    /// Its standard deviation, when determined.
    pub sigma: Option<f64>,
    /// The change in sigmas.
    pub significance: Option<f64>,
    /// Whether the change is within the noise.
    pub within_noise: bool,
    /// Whether the data (and the prior) determine it alone (`None`: not known).
    pub determined: Option<bool>,
    /// Whether the prior alone determines it.
    pub by_prior_alone: bool,
    /// A compliance (an angle per torque, 1e-6..1e-3): shown in significant digits, not
    /// fixed decimals.
    pub compliance: bool,
}

impl ParameterRow {
    fn estimated(r: &CalibrationReport) -> Vec<ParameterRow> {
        r.parameters
            .iter()
            .filter(|p| p.estimated_flag)
            .map(|p| ParameterRow {
                id: p.id.clone(),
                name: p.name.clone(),
                unit: p.unit.clone(),
                initial: p.initial,
                estimated: p.estimated,
                change: p.change,
                sigma: p.sigma,
                significance: p.significance,
                within_noise: p.within_noise == Some(true),
                determined: p.determined,
                by_prior_alone: p.determined_by.as_deref() == Some("prior"),
                compliance: p.unit.contains("/(N "),
            })
            .collect()
    }
}

/// A combination of parameters the data determines but cannot separate.
#[derive(Debug, Clone, PartialEq)]
pub struct CombinationRow {
    /// `p3 - p9 - p15`.
    pub expression: String,
    /// Its value after.
    pub value: f64,
    /// Its unit: its members' when they share one.
    pub unit: String,
    /// Its value before.
    pub initial: f64,
    /// Its standard deviation.
    pub sigma: f64,
    /// The change in sigmas.
    pub significance: f64,
    /// Whether the change is within the noise.
    pub within_noise: bool,
}

impl CombinationRow {
    fn all(r: &CalibrationReport) -> Vec<CombinationRow> {
        r.combinations
            .iter()
            .map(|c| CombinationRow {
                expression: c.expression.clone(),
                value: c.value,
                unit: combination_unit(r, &c.expression),
                initial: c.initial,
                sigma: c.sigma,
                significance: c.significance,
                within_noise: c.within_noise,
            })
            .collect()
    }
}

/// An observation beyond the outlier threshold (listed, kept in the fit).
#[derive(Debug, Clone, PartialEq)]
pub struct OutlierRow {
    /// Its kind: `position`, `distance`.
    pub kind: String,
    /// Its line in its file.
    pub line: usize,
    /// Its posture.
    pub posture: String,
    /// Its site.
    pub site: String,
    /// The error's metric: `position`, `distance`.
    pub metric: String,
    /// The error.
    pub error: f64,
    /// The attitude error, of a pose.
    pub attitude: Option<f64>,
    /// The error in robust sigmas.
    pub sigmas: f64,
}

impl OutlierRow {
    fn all(r: &CalibrationReport) -> Vec<OutlierRow> {
        r.outliers
            .iter()
            .map(|o| OutlierRow {
                kind: o.kind.clone(),
                line: o.line,
                posture: o.posture.clone(),
                site: o.site.clone(),
                metric: if o.metric.is_empty() {
                    "position".to_string()
                } else {
                    o.metric.clone()
                },
                error: o.position_error,
                attitude: o.orientation_error,
                sigmas: o.sigmas,
            })
            .collect()
    }
}

/// The page's figures, drawn from the report's numbers alone.
#[derive(Debug, Clone, Default)]
pub struct Figures {
    /// The errors of each observation before and after (log axes): the position (or other
    /// metric's) errors, and the attitude errors of poses.
    pub per_observation: Vec<Panel>,
    /// The histogram of the errors after calibration.
    pub histogram: Option<Panel>,
    /// The parameters' changes with +-1 sigma bars, one chart per unit.
    pub changes: Vec<Panel>,
    /// The singular values of the scaled Jacobian, with the rank cut.
    pub spectrum: Option<Panel>,
}

impl Figures {
    fn of(r: &CalibrationReport, c: &Convert) -> Figures {
        Figures {
            per_observation: per_observation(r, c),
            histogram: histogram(r, c),
            changes: changes(r),
            spectrum: spectrum(r),
        }
    }
}

/// `s` with its first letter in capitals.
pub(crate) fn cap(s: &str) -> String {
    let mut c = s.chars();
    c.next()
        .map(|f| f.to_uppercase().chain(c).collect())
        .unwrap_or_default()
}

/// The unit errors of `metric` are shown in: `px` for pixels, else the page's length unit.
fn error_unit(metric: &str, c: &Convert) -> String {
    if metric == "pixel" {
        "px".into()
    } else {
        c.l().to_string()
    }
}

/// Errors per observation, before and after: positions (or lengths of another metric), and
/// attitudes when the observations are poses. Log axes: the errors after calibration are
/// 10-1000 times smaller than before, and both must be readable.
fn per_observation(r: &CalibrationReport, c: &Convert) -> Vec<Panel> {
    let Some(oe) = &r.observation_errors else {
        return Vec::new();
    };
    let (l, a) = (error_unit(&oe.metric, c), c.a());
    let kind_of_error = oe.metric.as_str();
    let note = if oe.run == 1 {
        String::new()
    } else {
        format!(" (largest of each {} consecutive)", oe.run)
    };
    let x: Vec<f64> = (0..oe.before.len())
        .map(|i| (i * oe.run + 1) as f64)
        .collect();
    let before_after = |before: Vec<f64>, after: Vec<f64>| {
        vec![
            Line {
                points: true,
                ..Line::new("before", before)
            },
            Line {
                points: true,
                ..Line::new("after", after)
            },
        ]
    };
    let mut panels = vec![Panel {
        title: format!("{} error per observation{note}", cap(kind_of_error)),
        x_label: "observation (file order by posture)".into(),
        y_label: format!("{kind_of_error} error ({l}, log scale)"),
        log_y: true,
        x: x.clone(),
        lines: before_after(oe.before.clone(), oe.after.clone()),
        ..Default::default()
    }];
    if let (Some(ab), Some(aa)) = (&oe.attitude_before, &oe.attitude_after) {
        let nan = |v: &[Option<f64>]| v.iter().map(|a| a.unwrap_or(f64::NAN)).collect();
        panels.push(Panel {
            title: format!("Attitude error per observation{note}"),
            x_label: "observation (file order by posture)".into(),
            y_label: format!("attitude error ({a}, log scale)"),
            log_y: true,
            x,
            lines: before_after(nan(ab), nan(aa)),
            ..Default::default()
        });
    }
    panels
}

/// The histogram of the errors after calibration: bars of a round width, integer counts.
fn histogram(r: &CalibrationReport, c: &Convert) -> Option<Panel> {
    let oe = r.observation_errors.as_ref()?;
    let kind_of_error = oe.metric.as_str();
    let width = oe.histogram_width;
    Some(Panel {
        title: format!(
            "Histogram of {kind_of_error} errors after calibration ({} observations)",
            oe.observations
        ),
        x_label: format!(
            "{kind_of_error} error ({}; bins of {})",
            error_unit(&oe.metric, c),
            tick_label(width, width)
        ),
        y_label: "observations".into(),
        bars: oe
            .histogram
            .iter()
            .enumerate()
            .map(|(i, &n)| (i as f64 * width, (i + 1) as f64 * width, n as f64))
            .collect(),
        ..Default::default()
    })
}

/// The estimated parameters' changes with +-1 sigma bars, one chart per unit (no bar for a
/// sigma not determined).
fn changes(r: &CalibrationReport) -> Vec<Panel> {
    // (unit, [(parameter id, change, sigma)])
    type Group = (String, Vec<(String, f64, f64)>);
    let mut groups: Vec<Group> = Vec::new();
    for p in r.parameters.iter().filter(|p| p.estimated_flag) {
        let entry = match groups.iter_mut().position(|g| g.0 == p.unit) {
            Some(k) => &mut groups[k],
            None => {
                groups.push((p.unit.clone(), Vec::new()));
                groups.last_mut().expect("just pushed")
            }
        };
        entry
            .1
            .push((p.id.clone(), p.change, p.sigma.unwrap_or(f64::NAN)));
    }
    groups
        .iter()
        .map(|(unit, pts)| Panel {
            title: format!("Parameter changes ({unit}), +-1 sigma"),
            x_label: "parameter".into(),
            y_label: format!("change ({unit})"),
            x: (0..pts.len()).map(|i| i as f64).collect(),
            x_names: pts.iter().map(|p| p.0.clone()).collect(),
            lines: vec![Line {
                points: true,
                error: Some(pts.iter().map(|p| p.2).collect()),
                ..Line::new("change", pts.iter().map(|p| p.1).collect())
            }],
            h_lines: vec![(0.0, "no change".into())],
            ..Default::default()
        })
        .collect()
}

/// The singular values of the scaled Jacobian (log axis, the zeros at 1e-18 of the largest),
/// with the rank cut.
fn spectrum(r: &CalibrationReport) -> Option<Panel> {
    let an = r.spectrum.as_ref()?;
    let n = an.singular_values_scaled.len();
    let smax = an.singular_values_scaled.first().copied().unwrap_or(1.0);
    let floor = smax * 1e-18;
    Some(Panel {
        title: format!(
            "Singular values of the scaled Jacobian: rank {} of {n}",
            an.rank
        ),
        x_label: "index".into(),
        y_label: "singular value (scaled)".into(),
        x: (1..=n).map(|i| i as f64).collect(),
        lines: vec![Line {
            points: true,
            ..Line::new(
                "singular value",
                an.singular_values_scaled
                    .iter()
                    .map(|s| s.max(floor))
                    .collect(),
            )
        }],
        h_lines: vec![(
            an.rcond * smax,
            format!("rank cut ({:e} x largest)", an.rcond),
        )],
        log_y: true,
        ..Default::default()
    })
}
