//! Line charts in panels.

use plotters::coord::ranged1d::ValueFormatter;
use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::prelude::*;

use crate::{register_fonts, DrawError};

/// One curve of a panel.
#[derive(Debug, Clone, PartialEq)]
pub struct Line {
    /// Legend label.
    pub label: String,
    /// Values, one per x.
    pub y: Vec<f64>,
    /// Draw points instead of a line.
    pub points: bool,
    /// Optional +- error bars.
    pub error: Option<Vec<f64>>,
    /// The palette colour (an index; default: the line's position in the panel).
    pub color: Option<usize>,
}

impl Line {
    /// A plain line.
    pub fn new(label: impl Into<String>, y: Vec<f64>) -> Self {
        Line {
            label: label.into(),
            y,
            points: false,
            error: None,
            color: None,
        }
    }
}

/// One chart.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Panel {
    /// Title.
    pub title: String,
    /// X axis label (with unit).
    pub x_label: String,
    /// Y axis label (with unit).
    pub y_label: String,
    /// X values.
    pub x: Vec<f64>,
    /// The curves.
    pub lines: Vec<Line>,
    /// A marked x (the nominal value): dotted vertical guide, and dotted horizontal guides from
    /// where each line crosses it to the y axis (as in the thesis's figures).
    pub mark_x: Option<f64>,
    /// Horizontal reference lines (value, label).
    pub h_lines: Vec<(f64, String)>,
    /// Vertical marks (x, label): events, drawn dash-dotted, each with its legend entry.
    pub v_lines: Vec<(f64, String)>,
    /// Logarithmic y axis.
    pub log_y: bool,
    /// A categorical x axis: `x` holds indices 0..n and these are their labels (parameter ids).
    pub x_names: Vec<String>,
    /// Bars `(from x, to x, height)` drawn as rectangles from 0 (a histogram); the y axis then
    /// counts, with integer ticks.
    pub bars: Vec<(f64, f64, f64)>,
}

/// A tick label for `v` on an axis whose ticks are about `step` apart: the fewest decimals that
/// tell neighbouring ticks apart, no exponent for ordinary magnitudes, no rounding noise
/// (`9.99999999999e-5`), `0` for a value within a thousandth of a step of zero.
pub fn tick_label(v: f64, step: f64) -> String {
    if !v.is_finite() {
        return String::new();
    }
    let step = step.abs().max(f64::MIN_POSITIVE);
    if v.abs() < step * 1e-3 {
        return "0".into();
    }
    let magnitude = v.abs().max(step);
    if !(1e-6..1e6).contains(&magnitude) {
        // Outside ordinary magnitudes: mantissa digits as the step needs.
        let mantissa_step = step / 10f64.powf(magnitude.log10().floor());
        let digits = ((-mantissa_step.log10() - 1e-9).ceil().max(0.0) as usize).min(6);
        return format!("{v:.digits$e}");
    }
    let decimals = (-(step.log10().floor()) as i32).clamp(0, 12) as usize;
    format!("{v:.decimals$}")
}

/// A tick label on a logarithmic axis: powers of ten as `1e-5` (`0.001` to `1000` plain), other
/// ticks with up to two significant digits, plain from 0.001 to 10,000 (`0.2`, `30`), else as
/// `2e-5`.
pub fn log_tick_label(v: f64) -> String {
    if !(v.is_finite() && v > 0.0) {
        return String::new();
    }
    let e = v.log10();
    if (e - e.round()).abs() < 1e-9 {
        let e = e.round() as i32;
        return match e {
            0..=3 => format!("{}", 10i64.pow(e as u32)),
            -3..=-1 => format!("{:.*}", (-e) as usize, 10f64.powi(e)),
            _ => format!("1e{e}"),
        };
    }
    if (1e-3..1e4).contains(&v) {
        let decimals = (1 - e.floor() as i32).max(0) as usize;
        let s = format!("{v:.decimals$}");
        return if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        };
    }
    let s = format!("{v:.1e}");
    s.replace(".0e", "e")
}

/// The most tick labels a logarithmic axis gets.
pub const MAX_LOG_TICKS: usize = 8;

/// The ticks of a logarithmic axis over `[lo, hi]`: 1, 2 and 5 (1, 2, 3 and 5 over about a
/// decade) times the powers of ten when the span is short; the powers of ten over a few decades;
/// every second, third, ... power beyond, so that never more than [`MAX_LOG_TICKS`] labels
/// crowd the axis, and always at least two.
pub fn log_ticks(lo: f64, hi: f64) -> Vec<f64> {
    if !(lo.is_finite() && hi.is_finite() && lo > 0.0 && hi > lo) {
        return Vec::new();
    }
    let (e0, e1) = (lo.log10().floor() as i32, hi.log10().ceil() as i32);
    let inside = |v: &f64| *v >= lo * (1.0 - 1e-9) && *v <= hi * (1.0 + 1e-9);
    let with = |mantissas: &[f64], every: i32| -> Vec<f64> {
        (e0..=e1)
            .filter(|e| e.rem_euclid(every) == 0)
            .flat_map(|e| mantissas.iter().map(move |m| m * 10f64.powi(e)))
            .filter(inside)
            .collect()
    };
    let sets: [&[f64]; 4] = [&[1.0, 2.0, 3.0, 5.0], &[1.0, 2.0, 5.0], &[1.0, 3.0], &[1.0]];
    for set in sets {
        let t = with(set, 1);
        if t.len() <= MAX_LOG_TICKS {
            if t.len() >= 2 {
                return t;
            }
            // A very short span: finer steps.
            let fine: Vec<f64> = (e0..=e1)
                .flat_map(|e| (10..100).map(move |k| k as f64 / 10.0 * 10f64.powi(e)))
                .filter(inside)
                .collect();
            let step = fine.len().div_ceil(MAX_LOG_TICKS).max(1);
            return fine.into_iter().step_by(step).collect();
        }
    }
    let decades = (e1 - e0).max(1);
    let every = (decades as usize).div_ceil(MAX_LOG_TICKS - 1).max(1) as i32;
    with(&[1.0], every)
}

const COLORS: [RGBColor; 6] = [
    RGBColor(31, 95, 168),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(255, 127, 14),
    RGBColor(23, 190, 207),
];

/// The data ranges of panel `p`'s axes ([`data_bounds`]), or the unit square when they are not
/// finite spans (values near the doubles' limits): plotters looks for ticks on an infinite span
/// for ever.
fn bounds(p: &Panel) -> (f64, f64, f64, f64) {
    let (x0, x1, y0, y1) = data_bounds(p);
    if [x0, x1, y0, y1, x1 - x0, y1 - y0]
        .iter()
        .all(|v| v.is_finite())
    {
        (x0, x1, y0, y1)
    } else {
        (0.0, 1.0, 0.0, 1.0)
    }
}

fn data_bounds(p: &Panel) -> (f64, f64, f64, f64) {
    if !p.bars.is_empty() {
        let x0 = p.bars.iter().map(|b| b.0).fold(f64::INFINITY, f64::min);
        let x1 = p.bars.iter().map(|b| b.1).fold(f64::NEG_INFINITY, f64::max);
        let top = p.bars.iter().map(|b| b.2).fold(0.0, f64::max);
        return (x0, x1.max(x0 + 1e-12), 0.0, (top * 1.1).max(top + 1.0));
    }
    let (mut x0, mut x1) = if p.x_names.is_empty() {
        (
            p.x.iter()
                .chain(p.v_lines.iter().map(|v| &v.0))
                .copied()
                .fold(f64::INFINITY, f64::min),
            p.x.iter()
                .chain(p.v_lines.iter().map(|v| &v.0))
                .copied()
                .fold(f64::NEG_INFINITY, f64::max),
        )
    } else {
        (-0.5, p.x_names.len() as f64 - 0.5)
    };
    if !(x0.is_finite() && x1.is_finite()) {
        (x0, x1) = (0.0, 1.0);
    }
    if p.x_names.is_empty() && p.lines.iter().any(|l| l.points) {
        // Points never on the frame: a margin of 3 % (half a unit for a single x).
        let pad = if x1 > x0 { 0.03 * (x1 - x0) } else { 0.5 };
        x0 -= pad;
        x1 += pad;
    }
    let mut y0 = f64::INFINITY;
    let mut y1 = f64::NEG_INFINITY;
    for l in &p.lines {
        for (i, &v) in l.y.iter().enumerate() {
            // A bar not drawn (a sigma not determined: NaN) widens nothing.
            let e = l.error.as_ref().map_or(0.0, |e| e[i]).abs();
            let e = if e.is_finite() { e } else { 0.0 };
            if v.is_finite() && (!p.log_y || v - e > 0.0) {
                y0 = y0.min(v - e);
                y1 = y1.max(v + e);
            }
        }
    }
    for (v, _) in &p.h_lines {
        if !p.log_y || *v > 0.0 {
            y0 = y0.min(*v);
            y1 = y1.max(*v);
        }
    }
    if !y0.is_finite() {
        (y0, y1) = (0.0, 1.0);
    }
    if p.log_y {
        y0 = y0.max(1e-300);
        if y1 <= y0 {
            y1 = y0 * 10.0;
        }
        return (x0, x1.max(x0 + 1e-12), y0 / 2.0, y1 * 2.0);
    }
    // A flat series (one value, or all equal): a span around it that ticks can divide.
    let span = (y1 - y0).max(1e-9 * y1.abs().max(y0.abs())).max(1e-300);
    let span = if y0 == 0.0 && y1 == 0.0 {
        // Exactly 0 throughout: a unit span, not one of 1e-13.
        1.0
    } else if y1 - y0 <= 1e-9 * y1.abs().max(y0.abs()) {
        y1.abs().max(1e-12) * 0.1
    } else {
        span
    };
    let pad = 0.08 * span;
    (x0, x1.max(x0 + 1e-12), y0 - pad, y1 + pad)
}

/// The step plotters puts between the ticks of an axis from `lo` to `hi` with at most
/// `most` of them: the finest of 1, 2 or 5 times a power of ten that puts at most `most` of its
/// multiples in the range (plotters' own rule, so that labels get the decimals its ticks need:
/// a step guessed coarser would print two neighbouring ticks alike).
fn tick_step(lo: f64, hi: f64, most: usize) -> f64 {
    let span = hi - lo;
    if !(span.is_finite() && span > 0.0 && lo.is_finite()) {
        return nice_step(span.abs());
    }
    // Multiples of `step` within the range, rounding aside.
    let count = |step: f64| {
        let first = (lo / step - 1e-9).ceil();
        let last = (hi / step + 1e-9).floor();
        (last - first + 1.0).max(0.0)
    };
    let mut step = 10f64.powf(span.log10().ceil());
    // From a step with at most two multiples in the range, finer while few enough.
    for _ in 0..64 {
        let finer = [step / 2.0, step / 5.0, step / 10.0];
        match finer
            .iter()
            .take_while(|s| count(**s) <= most as f64)
            .count()
        {
            0 => return step,
            3 => step = finer[2],
            n => return finer[n - 1],
        }
    }
    step
}

/// The step plotters puts between ticks for about `raw` (1, 2 or 5 times a power of ten, at
/// least `raw`).
fn nice_step(raw: f64) -> f64 {
    if !(raw.is_finite() && raw > 0.0) {
        return 1.0;
    }
    let p = 10f64.powf(raw.log10().floor());
    let m = raw / p;
    p * if m <= 1.0 + 1e-9 {
        1.0
    } else if m <= 2.0 + 1e-9 {
        2.0
    } else if m <= 5.0 + 1e-9 {
        5.0
    } else {
        10.0
    }
}

/// Where the legend covers the fewest points, error bars and bars (the legend never hides data
/// it could avoid): its lower-left corner in fractions of the plotting area, from the lower left.
fn legend_position(p: &Panel, (x0, x1, y0, y1): (f64, f64, f64, f64)) -> (f64, f64) {
    let fx = |x: f64| (x - x0) / (x1 - x0);
    let fy = |y: f64| {
        if p.log_y {
            (y.max(y0).ln() - y0.ln()) / (y1.ln() - y0.ln())
        } else {
            (y - y0) / (y1 - y0)
        }
    };
    // Data in fractions of the plot (0..1 from the lower left).
    let mut pts: Vec<(f64, f64)> = Vec::new();
    for l in &p.lines {
        for (i, (&x, &y)) in p.x.iter().zip(&l.y).enumerate() {
            if !y.is_finite() || (p.log_y && y <= 0.0) {
                continue;
            }
            pts.push((fx(x), fy(y)));
            if let Some(e) = &l.error {
                // Sample the bar.
                for t in [-1.0, -0.5, 0.5, 1.0] {
                    let v = y + t * e[i];
                    if !p.log_y || v > 0.0 {
                        pts.push((fx(x), fy(v)));
                    }
                }
            }
        }
    }
    for (v, _) in &p.h_lines {
        if !p.log_y || *v > 0.0 {
            for k in 0..=20 {
                pts.push((k as f64 / 20.0, fy(*v)));
            }
        }
    }
    for &(a, b, c) in &p.bars {
        for k in 0..=4 {
            pts.push((fx(a + (b - a) * k as f64 / 4.0), fy(c)));
        }
    }
    for (v, _) in &p.v_lines {
        for k in 0..=20 {
            pts.push((fx(*v), k as f64 / 20.0));
        }
    }
    let entries = legend_entries(p);
    let (w, h) = (legend_width(p), 0.08 + 0.06 * entries as f64);
    let covered = |bx: f64, by: f64| {
        pts.iter()
            .filter(|&&(x, y)| {
                x >= bx - 0.02 && x <= bx + w + 0.02 && y >= by - 0.02 && y <= by + h + 0.02
            })
            .count()
    };
    // Candidates: right, left and middle columns, from the top down; the first of the least
    // covered wins (so the upper right when it is free).
    let mut best = (usize::MAX, (1.0 - w - 0.01, 1.0 - h - 0.01));
    for k in 0..=8 {
        let by = (1.0 - h - 0.01) - k as f64 * (1.0 - h - 0.02) / 8.0;
        for bx in [1.0 - w - 0.01, 0.01, 0.5 - w / 2.0] {
            let c = covered(bx, by);
            if c < best.0 {
                best = (c, (bx, by));
            }
        }
    }
    best.1
}

/// The labels of a panel's legend: each distinct non-empty label once.
pub(crate) fn legend_entries(p: &Panel) -> usize {
    legend_labels(p).len()
}

/// The legend's width in fractions of the plotting area: the longest label at about 6.5
/// pixels a character (12-pixel sans-serif), after its marker and padding (45 pixels), at
/// least a third of the width; the area is the panel less its axes (about 100 pixels).
fn legend_width(p: &Panel) -> f64 {
    let longest = legend_labels(p)
        .iter()
        .map(|l| l.chars().count())
        .max()
        .unwrap_or(0);
    ((45.0 + 6.5 * longest as f64) / (W as f64 - 100.0)).clamp(0.32, 0.97)
}

/// The legend's labels, each once.
fn legend_labels(p: &Panel) -> Vec<&str> {
    let mut seen: Vec<&str> = Vec::new();
    for label in p
        .lines
        .iter()
        .map(|l| l.label.as_str())
        .chain(p.h_lines.iter().map(|h| h.1.as_str()))
        .chain(p.v_lines.iter().map(|v| v.1.as_str()))
    {
        if !label.is_empty() && !seen.contains(&label) {
            seen.push(label);
        }
    }
    seen
}

/// The smallest height of an error bar, in pixels: taller than the point (radius 3) it crosses.
pub const MIN_BAR_PX: f64 = 10.0;

/// Half the width of an error bar's caps, in pixels.
const CAP_PX: f64 = 4.0;

/// The ends of the error bar `y +- e` on a y axis over `[y0, y1]` (logarithmic or not) of `px`
/// pixels: at least [`MIN_BAR_PX`] tall about `y`. On a logarithmic axis a lower end at or
/// below zero is the axis' bottom.
pub(crate) fn error_bar(y: f64, e: f64, log: bool, (y0, y1): (f64, f64), px: u32) -> (f64, f64) {
    let e = e.abs();
    let half = MIN_BAR_PX / 2.0 / px.max(1) as f64;
    if log {
        let k = half * (y1 / y0).ln();
        let lo = if y - e > 0.0 {
            (y - e).min(y * (-k).exp())
        } else {
            y0
        };
        (lo, (y + e).max(y * k.exp()))
    } else {
        let m = e.max(half * (y1 - y0));
        (y - m, y + m)
    }
}

/// A panel's chart: linear in x, linear or logarithmic in y.
type Chart<'a, DB, Y> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, Y>>;

/// A y axis a panel is drawn on: linear, or logarithmic with our own ticks.
trait YAxis: Ranged<ValueType = f64> + ValueFormatter<f64> {}
impl<Y: Ranged<ValueType = f64> + ValueFormatter<f64>> YAxis for Y {}

/// The data ranges of a panel's axes: `(x0, x1, y0, y1)`.
type Frame = (f64, f64, f64, f64);

fn failed(e: impl std::fmt::Display) -> DrawError {
    DrawError(e.to_string())
}

/// The labels already in the legend: each label once, at its first series.
#[derive(Default)]
struct Legend(Vec<String>);

impl Legend {
    /// Whether `label` is new to the legend (and now in it).
    fn first(&mut self, label: &str) -> bool {
        if label.is_empty() || self.0.iter().any(|s| s == label) {
            false
        } else {
            self.0.push(label.to_string());
            true
        }
    }
}

fn draw_panel<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, p: &Panel) -> Result<(), DrawError>
where
    DB::ErrorType: 'static,
{
    let frame = bounds(p);
    let (x0, x1, y0, y1) = frame;
    let mut builder = ChartBuilder::on(area);
    builder
        .caption(&p.title, ("sans-serif", 16))
        .margin(12)
        .margin_right(28)
        .x_label_area_size(44)
        .y_label_area_size(84);
    if p.log_y {
        // Our own ticks: plotters' crowd a short span's upper end (6, 7, 8, 9 next to each
        // other), leave a partial decade unlabelled, or stop short of a long span's end.
        let mut chart = builder
            .build_cartesian_2d(
                x0..x1,
                (y0..y1).log_scale().with_key_points(log_ticks(y0, y1)),
            )
            .map_err(failed)?;
        Canvas::new(&mut chart, p, frame).contents()
    } else {
        let mut chart = builder.build_cartesian_2d(x0..x1, y0..y1).map_err(failed)?;
        Canvas::new(&mut chart, p, frame).contents()
    }
}

/// A panel being drawn on its chart: the chart, the panel, and its axes' data ranges. Its
/// methods draw the panel's parts.
struct Canvas<'c, 'a, DB: DrawingBackend, Y: YAxis> {
    chart: &'c mut Chart<'a, DB, Y>,
    panel: &'c Panel,
    frame: Frame,
}

impl<'c, 'a, DB, Y> Canvas<'c, 'a, DB, Y>
where
    DB: DrawingBackend + 'a,
    DB::ErrorType: 'static,
    Y: YAxis,
{
    fn new(chart: &'c mut Chart<'a, DB, Y>, panel: &'c Panel, frame: Frame) -> Self {
        Canvas {
            chart,
            panel,
            frame,
        }
    }

    /// What a panel shows, in the order it is drawn: the mesh, the bars, each line (its points or
    /// its curve, its error bars, its guide to the nominal value), the nominal value's mark, the
    /// horizontal and vertical reference lines, and the legend where it hides the least.
    fn contents(&mut self) -> Result<(), DrawError> {
        let (p, frame) = (self.panel, self.frame);
        let mut legend = Legend::default();
        self.mesh()?;
        self.bars()?;
        for (k, l) in p.lines.iter().enumerate() {
            let color = COLORS[l.color.unwrap_or(k) % COLORS.len()];
            self.line(l, color, &mut legend)?;
            if let Some(e) = &l.error {
                self.error_bars(l, e, color)?;
            }
            if let Some(m) = p.mark_x {
                self.crossing(l, m, color)?;
            }
        }
        if let Some(m) = p.mark_x {
            let (_, _, y0, y1) = frame;
            self.chart
                .draw_series(DashedLineSeries::new(
                    vec![(m, y0), (m, y1)],
                    4,
                    4,
                    BLACK.mix(0.6).stroke_width(1),
                ))
                .map_err(failed)?;
        }
        self.reference_lines(&mut legend)?;
        self.legend(legend_position(p, frame))
    }

    /// The axes, their ticks and labels: tick steps as plotters chooses them (about 10 per axis),
    /// labels with just the decimals that step needs; parameter names on a categorical x axis;
    /// integer counts on a histogram's y axis.
    fn mesh(&mut self) -> Result<(), DrawError> {
        let (chart, p, frame) = (&mut *self.chart, self.panel, self.frame);
        let (x0, x1, y0, y1) = frame;
        let x_step = tick_step(x0, x1, 10);
        let y_step = tick_step(y0, y1, 10);
        let x_fmt = |v: &f64| -> String {
            if p.x_names.is_empty() {
                tick_label(*v, x_step)
            } else {
                let i = v.round();
                if (v - i).abs() < 1e-6 && i >= 0.0 {
                    p.x_names.get(i as usize).cloned().unwrap_or_default()
                } else {
                    String::new()
                }
            }
        };
        let integer_y = !p.bars.is_empty();
        let y_fmt = |v: &f64| -> String {
            if p.log_y {
                log_tick_label(*v)
            } else if integer_y {
                if (v - v.round()).abs() < 1e-9 {
                    format!("{:.0}", v)
                } else {
                    String::new()
                }
            } else {
                tick_label(*v, y_step)
            }
        };
        let x_labels = if p.x_names.is_empty() {
            10
        } else {
            p.x_names.len().min(20)
        };
        let y_labels = if integer_y {
            (y1.ceil() as usize + 1).min(11)
        } else {
            10
        };
        chart
            .configure_mesh()
            .x_desc(&p.x_label)
            .y_desc(&p.y_label)
            .x_labels(x_labels)
            .y_labels(y_labels)
            .x_label_formatter(&x_fmt)
            .y_label_formatter(&y_fmt)
            .label_style(("sans-serif", 12))
            .light_line_style(WHITE.mix(0.0))
            .draw()
            .map_err(failed)
    }

    /// A histogram's bars, filled, with white edges between them.
    fn bars(&mut self) -> Result<(), DrawError> {
        let (chart, p) = (&mut *self.chart, self.panel);
        if p.bars.is_empty() {
            return Ok(());
        }
        let color = COLORS[0];
        chart
            .draw_series(
                p.bars
                    .iter()
                    .filter(|b| b.2 > 0.0)
                    .map(|&(a, b, c)| Rectangle::new([(a, 0.0), (b, c)], color.mix(0.75).filled())),
            )
            .map_err(failed)?;
        chart
            .draw_series(
                p.bars
                    .iter()
                    .filter(|b| b.2 > 0.0)
                    .map(|&(a, b, c)| Rectangle::new([(a, 0.0), (b, c)], WHITE.stroke_width(1))),
            )
            .map_err(failed)?;
        Ok(())
    }

    /// A line's points (a dot, with a bar in the legend when it has error bars) or its curve,
    /// labelled in the legend the first time its label comes.
    fn line(&mut self, l: &Line, color: RGBColor, legend: &mut Legend) -> Result<(), DrawError> {
        let (chart, p) = (&mut *self.chart, self.panel);
        let pts: Vec<(f64, f64)> =
            p.x.iter()
                .zip(&l.y)
                .filter(|(_, y)| y.is_finite() && (!p.log_y || **y > 0.0))
                .map(|(x, y)| (*x, *y))
                .collect();
        if l.points {
            let anno = chart
                .draw_series(
                    pts.iter()
                        .map(|&(x, y)| Circle::new((x, y), 3, color.filled())),
                )
                .map_err(failed)?;
            if legend.first(&l.label) {
                let bars = l.error.is_some();
                anno.label(l.label.clone()).legend(move |(x, y)| {
                    let dot = Circle::new((x + 10, y), 3, color.filled());
                    let bar = PathElement::new(
                        if bars {
                            vec![(x + 10, y - 6), (x + 10, y + 6)]
                        } else {
                            vec![]
                        },
                        color.stroke_width(1),
                    );
                    EmptyElement::at((0, 0)) + dot + bar
                });
            }
        } else {
            let anno = chart
                .draw_series(LineSeries::new(pts, color.stroke_width(2)))
                .map_err(failed)?;
            if legend.first(&l.label) {
                anno.label(l.label.clone()).legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
                });
            }
        }
        Ok(())
    }

    /// A line's error bars `y +- e`, every bar at least [`MIN_BAR_PX`] tall, with caps: a sigma
    /// smaller than its point, on an axis scaled by larger values, still shows.
    fn error_bars(&mut self, l: &Line, e: &[f64], color: RGBColor) -> Result<(), DrawError> {
        let (chart, p, frame) = (&mut *self.chart, self.panel, self.frame);
        let (x0, x1, y0, y1) = frame;
        let (pw, ph) = chart.plotting_area().dim_in_pixel();
        let cap = CAP_PX * (x1 - x0) / pw.max(1) as f64;
        let bars: Vec<(f64, f64, f64)> =
            p.x.iter()
                .zip(&l.y)
                .zip(e)
                .filter(|((_, y), e)| {
                    y.is_finite() && (!p.log_y || **y > 0.0) && e.is_finite() && **e != 0.0
                })
                .map(|((&x, &y), &e)| {
                    let (lo, hi) = error_bar(y, e, p.log_y, (y0, y1), ph);
                    (x, lo, hi)
                })
                .collect();
        let ink = color.stroke_width(1);
        chart
            .draw_series(bars.iter().flat_map(|&(x, lo, hi)| {
                [
                    PathElement::new(vec![(x, lo), (x, hi)], ink),
                    PathElement::new(vec![(x - cap, lo), (x + cap, lo)], ink),
                    PathElement::new(vec![(x - cap, hi), (x + cap, hi)], ink),
                ]
            }))
            .map_err(failed)?;
        Ok(())
    }

    /// Where a line crosses the nominal value `m`: a dotted guide to the y axis.
    fn crossing(&mut self, l: &Line, m: f64, color: RGBColor) -> Result<(), DrawError> {
        let (chart, p, frame) = (&mut *self.chart, self.panel, self.frame);
        let Some(i) = p.x.iter().position(|&x| x >= m) else {
            return Ok(());
        };
        let y = l.y[i];
        if y.is_finite() && (!p.log_y || y > 0.0) {
            chart
                .draw_series(DashedLineSeries::new(
                    vec![(frame.0, y), (m, y)],
                    4,
                    4,
                    color.mix(0.7).stroke_width(1),
                ))
                .map_err(failed)?;
        }
        Ok(())
    }

    /// The horizontal reference lines (red, dashed: a tolerance's two sides are one legend entry)
    /// and the vertical marks (events, dash-dotted).
    fn reference_lines(&mut self, legend: &mut Legend) -> Result<(), DrawError> {
        let (chart, p, frame) = (&mut *self.chart, self.panel, self.frame);
        let (x0, x1, y0, y1) = frame;
        for (v, label) in &p.h_lines {
            let anno = chart
                .draw_series(DashedLineSeries::new(
                    vec![(x0, *v), (x1, *v)],
                    6,
                    4,
                    RED.stroke_width(1),
                ))
                .map_err(failed)?;
            if legend.first(label) {
                anno.label(label.clone()).legend(|(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], RED.stroke_width(1))
                });
            }
        }
        for (v, label) in &p.v_lines {
            let ink = RGBColor(90, 60, 160);
            let anno = chart
                .draw_series(DashedLineSeries::new(
                    vec![(*v, y0), (*v, y1)],
                    8,
                    3,
                    ink.stroke_width(2),
                ))
                .map_err(failed)?;
            if legend.first(label) {
                anno.label(label.clone()).legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], ink.stroke_width(2))
                });
            }
        }
        Ok(())
    }

    /// The legend, its lower-left corner at `at` (fractions of the plotting area from the lower
    /// left, [`legend_position`]), when the panel has any label.
    fn legend(&mut self, at: (f64, f64)) -> Result<(), DrawError> {
        let (chart, p) = (&mut *self.chart, self.panel);
        let entries = legend_entries(p);
        if entries == 0 {
            return Ok(());
        }
        let (pw, ph) = chart.plotting_area().dim_in_pixel();
        let top = at.1 + 0.08 + 0.06 * entries as f64;
        let at = SeriesLabelPosition::Coordinate(
            (at.0 * pw as f64) as i32,
            ((1.0 - top) * ph as f64).max(0.0) as i32,
        );
        chart
            .configure_series_labels()
            .position(at)
            .label_font(("sans-serif", 12))
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK.mix(0.3))
            .draw()
            .map_err(failed)
    }
}

fn draw_all<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    panels: &[Panel],
    cols: usize,
) -> Result<(), DrawError>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(|e| DrawError(e.to_string()))?;
    let rows = panels.len().div_ceil(cols.max(1));
    let areas = root.split_evenly((rows.max(1), cols.max(1)));
    for (p, a) in panels.iter().zip(areas.iter()) {
        draw_panel(a, p)?;
    }
    root.present().map_err(|e| DrawError(e.to_string()))
}

/// Panel size in pixels.
const W: u32 = 560;
const H: u32 = 340;

/// Renders `panels` in a grid of `cols` columns as an SVG document.
pub fn render_svg(panels: &[Panel], cols: usize) -> Result<String, DrawError> {
    register_fonts();
    let rows = panels.len().div_ceil(cols.max(1)) as u32;
    let mut s = String::new();
    {
        let root =
            SVGBackend::with_string(&mut s, (W * cols as u32, H * rows.max(1))).into_drawing_area();
        draw_all(root, panels, cols)?;
    }
    Ok(s)
}

/// Renders `panels` in a grid of `cols` columns as a PNG file's bytes.
pub fn render_png(panels: &[Panel], cols: usize) -> Result<Vec<u8>, DrawError> {
    register_fonts();
    let rows = panels.len().div_ceil(cols.max(1)) as u32;
    // The encoder writes a file: a private temporary one, read back.
    let dir = tempfile::tempdir().map_err(|e| DrawError(e.to_string()))?;
    let path = dir.path().join("chart.png");
    {
        // The bitmap backend with its text laid out by `kerned` (plotters' drifts).
        let root = crate::kerned::Kerned(BitMapBackend::new(
            &path,
            (W * cols as u32, H * rows.max(1)),
        ))
        .into_drawing_area();
        draw_all(root, panels, cols)?;
    }
    std::fs::read(&path).map_err(|e| DrawError(e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tick_labels_have_the_digits_their_step_needs() {
        // Neighbouring ticks stay apart; no rounding noise; no exponent for ordinary values.
        assert_eq!(tick_label(37.0, 0.0002), "37.0000");
        assert_eq!(tick_label(37.0002, 0.0002), "37.0002");
        assert_eq!(tick_label(0.05, 0.01), "0.05");
        assert_eq!(tick_label(-0.00005, 0.00005), "-0.00005");
        assert_eq!(tick_label(1e-19, 0.01), "0");
        assert_eq!(tick_label(2500.0, 500.0), "2500");
        assert_eq!(tick_label(3e7, 1e7), "3e7");
        assert_eq!(log_tick_label(1e-5), "1e-5");
        assert_eq!(log_tick_label(9.99999999999e-5), "1e-4");
        assert_eq!(log_tick_label(0.001), "0.001");
        assert_eq!(log_tick_label(100.0), "100");
        assert_eq!(log_tick_label(2e-5), "2e-5");
        assert!((nice_step(0.0075) - 0.01).abs() < 1e-15);
        assert!((nice_step(0.3) - 0.5).abs() < 1e-15);
    }

    /// Over random ranges, the ticks plotters draws (at most 10) are the multiples of
    /// [`tick_step`], and their labels are all different (a history plot labelled `11.812` twice
    /// where plotters put ticks 0.0005 apart).
    #[test]
    fn tick_labels_tell_plotters_ticks_apart() {
        use plotters::coord::ranged1d::Ranged;
        use plotters::coord::types::RangedCoordf64;
        let mut rng = 12345u64;
        let mut next = || {
            rng = rng
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (rng >> 11) as f64 / (1u64 << 53) as f64
        };
        for _ in 0..20_000 {
            let centre = (next() - 0.5) * 10f64.powf(next() * 8.0 - 3.0);
            let span = 10f64.powf(next() * 10.0 - 6.0);
            let (lo, hi) = (centre - next() * span, centre + next() * span + 1e-300);
            let coord: RangedCoordf64 = (lo..hi).into();
            let ticks = coord.key_points(10);
            let step = tick_step(lo, hi, 10);
            let labels: Vec<String> = ticks.iter().map(|v| tick_label(*v, step)).collect();
            for w in ticks.windows(2) {
                // A difference of ticks loses the rounding of their magnitude.
                assert!(
                    (w[1] - w[0] - step).abs() <= 1e-6 * step + 1e-12 * w[0].abs(),
                    "{lo}..{hi}: ticks {ticks:?}, step {step}"
                );
            }
            for w in labels.windows(2) {
                assert_ne!(w[0], w[1], "{lo}..{hi}: ticks {ticks:?}, labels {labels:?}");
            }
        }
        // Ten multiples of 0.0005 fit (11.8075 to 11.8120): ticks 0.0005 apart, four decimals
        // (a step guessed from the span over 10, 0.00049, rounded up, said 0.001).
        let step = tick_step(11.8075, 11.8124, 10);
        assert!((step - 0.0005).abs() < 1e-15, "{step}");
        assert_eq!(tick_label(11.8115, step), "11.8115");
    }

    /// The texts of an SVG (tick labels, titles, legend entries).
    fn texts(svg: &str) -> Vec<String> {
        svg.split("<text")
            .skip(1)
            .filter_map(|t| {
                let open = t.find('>')?;
                let close = t.find("</text>")?;
                Some(t[open + 1..close].trim().to_string())
            })
            .collect()
    }

    /// Vertical two-point polylines of `svg` in the first line colour (error bars, and the
    /// legend's glyph of one): their heights in pixels.
    fn vertical_segments(svg: &str) -> Vec<f64> {
        svg.split("<polyline")
            .skip(1)
            .filter(|t| t[..t.find('>').unwrap_or(0)].contains("#1F5FA8"))
            .filter_map(|t| {
                let pts = t.split("points=\"").nth(1)?.split('"').next()?;
                let p: Vec<(f64, f64)> = pts
                    .split_whitespace()
                    .filter_map(|xy| {
                        let (x, y) = xy.split_once(',')?;
                        Some((x.parse().ok()?, y.parse().ok()?))
                    })
                    .collect();
                (p.len() == 2 && (p[0].0 - p[1].0).abs() < 1e-9 && (p[0].1 - p[1].1).abs() > 1e-9)
                    .then(|| (p[0].1 - p[1].1).abs())
            })
            .collect()
    }

    fn history_like() -> Panel {
        Panel {
            title: "link1.x".into(),
            x_label: "days".into(),
            y_label: "p1 (mm)".into(),
            x: vec![0.0, 30.0, 60.0, 90.0],
            lines: vec![Line {
                points: true,
                error: Some(vec![0.002, 0.002, 0.003, 0.002]),
                ..Line::new("value +-1 sigma", vec![612.7, 612.701, 612.703, 612.71])
            }],
            h_lines: vec![(612.2, "tolerance".into()), (613.2, "tolerance".into())],
            v_lines: vec![(45.0, "event: gearbox".into())],
            ..Default::default()
        }
    }

    #[test]
    fn a_label_is_in_the_legend_once() {
        let p = history_like();
        assert_eq!(legend_entries(&p), 3);
        let svg = render_svg(&[p], 1).unwrap();
        let t = texts(&svg);
        assert_eq!(t.iter().filter(|t| *t == "tolerance").count(), 1, "{t:?}");
        assert_eq!(t.iter().filter(|t| *t == "value +-1 sigma").count(), 1);
    }

    #[test]
    fn error_bars_show_however_small_the_sigma() {
        // Sigmas of 0.002 on an axis spanning a whole millimetre: under a pixel at scale.
        let svg = render_svg(&[history_like()], 1).unwrap();
        let bars = vertical_segments(&svg);
        // Four bars and the legend's.
        assert_eq!(bars.len(), 5, "{bars:?}");
        assert!(bars.iter().all(|h| *h >= MIN_BAR_PX - 0.5), "{bars:?}");
        // A large sigma keeps its true length.
        let (lo, hi) = error_bar(0.0, 3.0, false, (-10.0, 10.0), 200);
        assert_eq!((lo, hi), (-3.0, 3.0));
        let (lo, hi) = error_bar(0.0, 1e-6, false, (-10.0, 10.0), 200);
        assert!((hi - lo - MIN_BAR_PX * 20.0 / 200.0).abs() < 1e-12);
        // On a log axis, about the point.
        let (lo, hi) = error_bar(1e-3, 1e-9, true, (1e-5, 1e-1), 400);
        assert!(lo < 1e-3 && hi > 1e-3 && ((hi / 1e-3).ln() + (lo / 1e-3).ln()).abs() < 1e-9);
    }

    #[test]
    fn log_axes_have_a_few_labels_over_any_span() {
        for (lo, hi) in [
            (0.105, 1.75),
            (0.45, 18.0),
            (1e-31, 2.0),
            (5e-19, 8.0),
            (1.05e-5, 2.1e-4),
            (0.21, 0.25),
            (3.0, 3000.0),
        ] {
            let t = log_ticks(lo, hi);
            assert!((2..=MAX_LOG_TICKS).contains(&t.len()), "{lo}..{hi}: {t:?}");
            assert!(t.iter().all(|v| *v >= lo * 0.999 && *v <= hi * 1.001));
            // Spread over the span: the first in its lower half, the last in its upper half
            // (log scale).
            let mid = (lo.ln() + hi.ln()) / 2.0;
            assert!(
                t[0].ln() <= mid && t[t.len() - 1].ln() >= mid,
                "{lo}..{hi}: {t:?}"
            );
        }
        // Within a decade: 1, 2, 3, 5 times powers of ten; never 6, 7, 8, 9 side by side.
        assert_eq!(log_ticks(0.45, 18.0), [0.5, 1.0, 2.0, 3.0, 5.0, 10.0]);
        assert_eq!(log_tick_label(0.2), "0.2");
        assert_eq!(log_tick_label(3000.0 * 5.0 / 3.0), "5000");
        assert_eq!(log_tick_label(3e-5), "3e-5");
        // Drawn: a thirty-decade axis labelled to its end, with few labels.
        let p = Panel {
            log_y: true,
            x: (0..31).map(f64::from).collect(),
            lines: vec![Line::new("s", (0..31).map(|i| 10f64.powi(-i)).collect())],
            ..Default::default()
        };
        let svg = render_svg(&[p], 1).unwrap();
        let labels: Vec<String> = texts(&svg)
            .into_iter()
            .filter(|t| t.starts_with("1e") || t == "1")
            .collect();
        assert!(labels.len() <= MAX_LOG_TICKS, "{labels:?}");
        assert!(labels.iter().any(|t| t == "1e-30"), "{labels:?}");
    }
}
