//! The fleet's state: every robot's last calibration, its drift flags, the trend of each
//! determined quantity and when a tolerance will be crossed, most urgent first.
//!
//! A robot's history is cut into segments by its maintenance events ([`Event`]) and by changes
//! of its robot model ([`ModelChange`]): a repaired or rebuilt robot is another robot as far as
//! drift goes, so drift and trends are computed within the current segment (the calibrations
//! at or after its latest event, of its latest model since that changed).

use serde::Serialize;

use crate::drift::{all_samples, drift, without_parameters, Baseline, DriftOptions, Sample};
use crate::error::{Error, Result};
use crate::model::{Calibration, Event};
use crate::robot_model::{latest_model_start, ModelChange};
use crate::timefmt::format_time;

/// Seconds in the month of the rates (30 days).
pub(crate) const MONTH: f64 = 30.0 * 86_400.0;

/// A robot's current segment: what drift compares.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct Segment<'a> {
    /// The calibrations since the robot's latest maintenance event and since the latest change
    /// of its robot model (oldest first); empty when the robot was serviced after its latest
    /// calibration.
    pub calibrations: &'a [Calibration],
    /// The latest maintenance event, if any.
    pub event: Option<&'a Event>,
    /// The change of robot model that starts the segment, when one does (a calibration of a
    /// rebuilt robot recorded with the force option, after the latest event).
    pub model_change: Option<ModelChange>,
}

/// The current segment of a robot's `history` (oldest first): the calibrations since its
/// latest maintenance event in `events` (a calibration at the event's time belongs to the new
/// segment) and, within those, since the latest change of robot model (drift never compares
/// two models: a change starts a segment as an event does). An event after the latest
/// calibration gives an empty segment (the robot was serviced and not calibrated since).
pub fn segment_of<'a>(history: &'a [Calibration], events: &'a [Event]) -> Segment<'a> {
    let robot = history.first().map(|c| c.robot_id.as_str());
    let last = events
        .iter()
        .filter(|e| robot.is_none_or(|r| r == e.robot_id))
        .max_by_key(|e| (e.at, e.id));
    let since_event = match last {
        None => history,
        Some(e) => &history[history.partition_point(|c| c.at < e.at)..],
    };
    let (start, model_change) = latest_model_start(since_event);
    Segment {
        calibrations: &since_event[start..],
        event: last,
        model_change,
    }
}

/// The calibrations of [`segment_of`] and the robot's latest event.
pub fn current_segment<'a>(
    history: &'a [Calibration],
    events: &'a [Event],
) -> (&'a [Calibration], Option<&'a Event>) {
    let s = segment_of(history, events);
    (s.calibrations, s.event)
}

/// How a robot stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "kebab-case")]
#[non_exhaustive]
pub enum Verdict {
    /// A quantity changed beyond its tolerance or K sigma: recalibrate and inspect.
    Flagged,
    /// The robot's calibrations could not be compared (e.g. one has no parameters, a damaged
    /// record): its state is unknown, never "ok" ([`RobotState::problem`] says why).
    Unknown,
    /// Serviced (a maintenance event) after its latest calibration: calibrate it.
    Serviced,
    /// A trend crosses a tolerance within the horizon.
    Due,
    /// Nothing flagged, no crossing within the horizon.
    Ok,
    /// One calibration since its latest event: nothing to compare yet.
    Single,
}

impl Verdict {
    /// The word printed.
    pub fn word(self) -> &'static str {
        match self {
            Verdict::Flagged => "FLAGGED",
            Verdict::Unknown => "UNKNOWN",
            Verdict::Serviced => "SERVICED",
            Verdict::Due => "DUE",
            Verdict::Ok => "ok",
            Verdict::Single => "single",
        }
    }
}

/// The trend of one determined quantity of a robot, within its current segment.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct Trend {
    /// The quantity in words.
    pub quantity: String,
    /// Parameter name or combination expression.
    pub key: String,
    /// Unit (the robot's first record's).
    pub unit: String,
    /// Change from the segment's first calibration to its latest.
    pub change: f64,
    /// `|change| / sigma`.
    pub significance: f64,
    /// The tolerance, if one applies.
    pub tolerance: Option<f64>,
    /// Whether `drift` flags it.
    pub flagged: bool,
    /// Why.
    pub reason: Option<String>,
    /// Rate of change per month (30 days), weighted regression over the segment.
    pub rate_per_month: Option<f64>,
    /// Its standard error.
    pub rate_sigma: Option<f64>,
    /// When the trend line leaves the tolerance band (Unix seconds): only for a tolerance and a
    /// trend beyond 2 of its sigmas. The band is centred on the trend line's value at the
    /// segment's first calibration.
    pub crossing: Option<i64>,
    /// The same as RFC 3339.
    pub crossing_at: Option<String>,
    /// The calibrations' values of this quantity in the segment (for charts).
    #[serde(skip)]
    pub samples: Vec<Sample>,
    /// The tolerance band's centre: the trend line's value at the segment's first calibration
    /// (its value, without a trend).
    pub reference: f64,
    /// The trend line's value at `t0` (Unix seconds) and its slope per second.
    #[serde(skip)]
    pub line: Option<(f64, f64, f64)>,
}

/// One robot of the fleet.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct RobotState {
    /// Serial.
    pub robot_id: String,
    /// The verdict.
    pub verdict: Verdict,
    /// Calibrations recorded in all.
    pub calibrations: usize,
    /// Calibrations in the current segment.
    pub in_segment: usize,
    /// The latest maintenance event, if any.
    pub since_event: Option<Event>,
    /// The change of robot model that starts the current segment, if one does.
    pub model_change: Option<ModelChange>,
    /// The latest calibration's id.
    pub last_id: i64,
    /// Its time (RFC 3339).
    pub last_at: String,
    /// Its RMS position error after calibration (robot file's length unit).
    pub last_rms_after: f64,
    /// The length unit.
    pub length_unit: String,
    /// The flagged quantities' keys.
    pub flags: Vec<String>,
    /// The earliest predicted crossing (Unix seconds), and its quantity.
    pub earliest_crossing: Option<(i64, String)>,
    /// Every tracked quantity's trend.
    pub trends: Vec<Trend>,
    /// Why the robot could not be analysed, if it could not (the others are served).
    pub problem: Option<String>,
}

/// Settings of [`fleet`].
#[derive(Debug, Clone, PartialEq)]
pub struct FleetOptions {
    /// The drift settings (K sigma, tolerances; the baseline is the segment's first record).
    pub drift: DriftOptions,
    /// "Now" (Unix seconds): crossings before `now + horizon` make a robot due.
    pub now: i64,
    /// The horizon, seconds.
    pub horizon: i64,
}

/// The fleet's state, most urgent first: flagged robots (by their largest significance), then
/// serviced ones, then those due (earliest crossing first), then the others by serial.
/// `calibrations` is every calibration (any order of robots, each robot's oldest first, as
/// [`crate::Database::records`] gives them); `events` every event.
pub fn fleet(
    calibrations: &[Calibration],
    events: &[Event],
    opts: &FleetOptions,
) -> Result<Vec<RobotState>> {
    let mut out = Vec::new();
    let mut start = 0;
    while start < calibrations.len() {
        let robot = &calibrations[start].robot_id;
        let end = start
            + calibrations[start..]
                .iter()
                .position(|c| &c.robot_id != robot)
                .unwrap_or(calibrations.len() - start);
        let history = &calibrations[start..end];
        start = end;
        let own: Vec<Event> = events
            .iter()
            .filter(|e| &e.robot_id == robot)
            .cloned()
            .collect();
        out.push(robot_state(history, &own, opts)?);
    }
    let urgency = |r: &RobotState| {
        let worst = r
            .trends
            .iter()
            .filter(|t| t.flagged)
            .map(|t| t.significance)
            .fold(0.0, f64::max);
        (
            r.verdict,
            -(worst.min(1e300) * 1e3) as i64,
            r.earliest_crossing.as_ref().map_or(i64::MAX, |c| c.0),
            r.robot_id.clone(),
        )
    };
    out.sort_by_cached_key(urgency);
    Ok(out)
}

fn robot_state(
    history: &[Calibration],
    events: &[Event],
    opts: &FleetOptions,
) -> Result<RobotState> {
    let last = history.last().expect("a robot has a calibration");
    let Segment {
        calibrations: segment,
        event,
        model_change,
    } = segment_of(history, events);
    let mut state = RobotState {
        robot_id: last.robot_id.clone(),
        verdict: Verdict::Single,
        calibrations: history.len(),
        in_segment: segment.len(),
        since_event: event.cloned(),
        model_change,
        last_id: last.id,
        last_at: last.at_text.clone(),
        last_rms_after: last.rms_position_after,
        length_unit: last.length_unit.clone(),
        flags: Vec::new(),
        earliest_crossing: None,
        trends: Vec::new(),
        problem: None,
    };
    if segment.is_empty() {
        state.verdict = Verdict::Serviced;
        return Ok(state);
    }
    if let Some(problem) = without_parameters(segment) {
        state.verdict = Verdict::Unknown;
        state.problem = Some(problem);
        return Ok(state);
    }
    if segment.len() < 2 {
        return Ok(state);
    }
    let report = match drift(
        segment,
        &DriftOptions {
            baseline: Baseline::First,
            ..opts.drift.clone()
        },
    ) {
        Ok(r) => r,
        // The tolerance file is at fault, not the robot: the fleet is refused, naming it.
        Err(e @ Error::Tolerance { .. }) => return Err(e),
        Err(e) => {
            state.verdict = Verdict::Unknown;
            state.problem = Some(e.to_string());
            return Ok(state);
        }
    };
    let mut series = all_samples(segment)?;
    for q in &report.quantities {
        let pts = series.remove(&q.key).unwrap_or_default();
        let fit = line_fit(&pts);
        // The band's centre: the trend line at the segment's first calibration (one noisy
        // value would move every prediction), else that calibration's value.
        let reference = match (fit, pts.first()) {
            (Some((t0, v0, slope, _)), Some(first)) => v0 + slope * (first.at - t0) as f64,
            (_, Some(first)) => first.value,
            _ => q.baseline,
        };
        let crossing = match (fit, q.tolerance) {
            (Some((t0, v0, slope, slope_sigma)), Some(tol))
                if slope != 0.0 && slope.abs() > 2.0 * slope_sigma =>
            {
                let target = reference + tol * slope.signum();
                Some(t0 + ((target - v0) / slope).round() as i64)
            }
            _ => None,
        };
        if let Some(c) = crossing {
            if state.earliest_crossing.as_ref().is_none_or(|e| c < e.0) {
                state.earliest_crossing = Some((c, q.key.clone()));
            }
        }
        if q.flagged {
            state.flags.push(q.key.clone());
        }
        state.trends.push(Trend {
            quantity: q.quantity.clone(),
            key: q.key.clone(),
            unit: q.unit.clone(),
            change: q.change,
            significance: q.significance,
            tolerance: q.tolerance,
            flagged: q.flagged,
            reason: q.reason.clone(),
            rate_per_month: fit.map(|f| f.2 * MONTH),
            rate_sigma: fit.map(|f| f.3 * MONTH),
            crossing,
            crossing_at: crossing.map(format_time),
            samples: pts,
            reference,
            line: fit.map(|f| (f.0 as f64, f.1, f.2)),
        });
    }
    state.verdict = if !state.flags.is_empty() {
        Verdict::Flagged
    } else if state
        .earliest_crossing
        .as_ref()
        .is_some_and(|c| c.0 <= opts.now.saturating_add(opts.horizon))
    {
        Verdict::Due
    } else {
        Verdict::Ok
    };
    Ok(state)
}

/// Weighted least-squares line through the samples: `(t0, value at t0, slope per second,
/// slope's standard error)`, `t0` the weighted mean time; `None` for fewer than 2 distinct
/// times.
fn line_fit(pts: &[Sample]) -> Option<(i64, f64, f64, f64)> {
    let pts: Vec<&Sample> = pts.iter().filter(|s| s.sigma > 0.0).collect();
    if pts.len() < 2 {
        return None;
    }
    let origin = pts[0].at;
    let w: Vec<f64> = pts.iter().map(|p| 1.0 / (p.sigma * p.sigma)).collect();
    let sw: f64 = w.iter().sum();
    let t = |p: &Sample| (p.at - origin) as f64;
    let tm = pts.iter().zip(&w).map(|(p, w)| t(p) * w).sum::<f64>() / sw;
    let vm = pts.iter().zip(&w).map(|(p, w)| p.value * w).sum::<f64>() / sw;
    let stt: f64 = pts
        .iter()
        .zip(&w)
        .map(|(p, w)| w * (t(p) - tm).powi(2))
        .sum();
    if stt <= 0.0 {
        return None;
    }
    let slope = pts
        .iter()
        .zip(&w)
        .map(|(p, w)| w * (t(p) - tm) * (p.value - vm))
        .sum::<f64>()
        / stt;
    let t0 = origin + tm.round() as i64;
    let v0 = vm + slope * (t0 - origin) as f64 - slope * tm;
    Some((t0, v0, slope, (1.0 / stt).sqrt()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_straight_line_is_fitted_exactly() {
        let pts: Vec<Sample> = (0..5)
            .map(|k| Sample {
                id: k,
                at: 1_000_000 + k * 86_400,
                value: 2.0 + 0.5 * k as f64,
                sigma: 0.1,
            })
            .collect();
        let (t0, v0, slope, s) = line_fit(&pts).unwrap();
        assert_eq!(t0, 1_000_000 + 2 * 86_400);
        assert!((v0 - 3.0).abs() < 1e-12 && (slope * 86_400.0 - 0.5).abs() < 1e-12);
        // sigma 0.1, times -2..2 days: 1/sqrt(sum w t^2) = 0.1/sqrt(10) per day.
        assert!((s * 86_400.0 - 0.1 / 10f64.sqrt()).abs() < 1e-12);
        assert!(line_fit(&pts[..1]).is_none());
    }
}
