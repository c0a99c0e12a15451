//! Line charts in panels.

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

/// A tick label on a logarithmic axis: powers of ten as `1e-5` (`1`, `10` and `100` plain),
/// other key points with two significant digits.
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
    let s = format!("{v:.1e}");
    s.replace(".0e", "e")
}

const COLORS: [RGBColor; 6] = [
    RGBColor(31, 95, 168),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(255, 127, 14),
    RGBColor(23, 190, 207),
];

fn bounds(p: &Panel) -> (f64, f64, f64, f64) {
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
            let e = l.error.as_ref().map_or(0.0, |e| e[i]);
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
    let entries = p.lines.len() + p.h_lines.len() + p.v_lines.len();
    let (w, h) = (0.32, 0.08 + 0.06 * entries as f64);
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

fn draw_panel<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, p: &Panel) -> Result<(), DrawError>
where
    DB::ErrorType: 'static,
{
    let err = |e: &dyn std::fmt::Display| DrawError(e.to_string());
    let (x0, x1, y0, y1) = bounds(p);
    let legend_at = legend_position(p, (x0, x1, y0, y1));
    let mut builder = ChartBuilder::on(area);
    builder
        .caption(&p.title, ("sans-serif", 16))
        .margin(12)
        .margin_right(28)
        .x_label_area_size(44)
        .y_label_area_size(84);
    // Tick steps as plotters chooses them (about 10 per axis): labels with just the decimals
    // that step needs.
    let x_step = nice_step((x1 - x0) / 10.0);
    let y_step = nice_step((y1 - y0) / 10.0);
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
    macro_rules! body {
        ($chart:ident) => {{
            $chart
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
                .map_err(|e| err(&e))?;
            if !p.bars.is_empty() {
                let color = COLORS[0];
                $chart
                    .draw_series(p.bars.iter().filter(|b| b.2 > 0.0).map(|&(a, b, c)| {
                        Rectangle::new([(a, 0.0), (b, c)], color.mix(0.75).filled())
                    }))
                    .map_err(|e| err(&e))?;
                $chart
                    .draw_series(p.bars.iter().filter(|b| b.2 > 0.0).map(|&(a, b, c)| {
                        Rectangle::new([(a, 0.0), (b, c)], WHITE.stroke_width(1))
                    }))
                    .map_err(|e| err(&e))?;
            }
            for (k, l) in p.lines.iter().enumerate() {
                let color = COLORS[l.color.unwrap_or(k) % COLORS.len()];
                let pts: Vec<(f64, f64)> =
                    p.x.iter()
                        .zip(&l.y)
                        .filter(|(_, y)| y.is_finite() && (!p.log_y || **y > 0.0))
                        .map(|(x, y)| (*x, *y))
                        .collect();
                if l.points {
                    $chart
                        .draw_series(
                            pts.iter()
                                .map(|&(x, y)| Circle::new((x, y), 3, color.filled())),
                        )
                        .map_err(|e| err(&e))?
                        .label(l.label.clone())
                        .legend(move |(x, y)| Circle::new((x + 10, y), 3, color.filled()));
                } else {
                    $chart
                        .draw_series(LineSeries::new(pts.clone(), color.stroke_width(2)))
                        .map_err(|e| err(&e))?
                        .label(l.label.clone())
                        .legend(move |(x, y)| {
                            PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
                        });
                }
                if let Some(e) = &l.error {
                    $chart
                        .draw_series(
                            p.x.iter()
                                .zip(&l.y)
                                .zip(e)
                                .filter(|((_, y), e)| y.is_finite() && e.is_finite())
                                .map(|((&x, &y), &e)| {
                                    PathElement::new(
                                        vec![(x, y - e), (x, y + e)],
                                        color.stroke_width(1),
                                    )
                                }),
                        )
                        .map_err(|e| err(&e))?;
                }
                if let Some(m) = p.mark_x {
                    // Where the line crosses the nominal value: dotted guide to the y axis.
                    if let Some(i) = p.x.iter().position(|&x| x >= m) {
                        let y = l.y[i];
                        if y.is_finite() && (!p.log_y || y > 0.0) {
                            $chart
                                .draw_series(DashedLineSeries::new(
                                    vec![(x0, y), (m, y)],
                                    4,
                                    4,
                                    color.mix(0.7).stroke_width(1),
                                ))
                                .map_err(|e| err(&e))?;
                        }
                    }
                }
            }
            if let Some(m) = p.mark_x {
                $chart
                    .draw_series(DashedLineSeries::new(
                        vec![(m, y0), (m, y1)],
                        4,
                        4,
                        BLACK.mix(0.6).stroke_width(1),
                    ))
                    .map_err(|e| err(&e))?;
            }
            for (v, label) in &p.h_lines {
                $chart
                    .draw_series(DashedLineSeries::new(
                        vec![(x0, *v), (x1, *v)],
                        6,
                        4,
                        RED.stroke_width(1),
                    ))
                    .map_err(|e| err(&e))?
                    .label(label.clone())
                    .legend(|(x, y)| {
                        PathElement::new(vec![(x, y), (x + 20, y)], RED.stroke_width(1))
                    });
            }
            for (v, label) in &p.v_lines {
                let ink = RGBColor(90, 60, 160);
                $chart
                    .draw_series(DashedLineSeries::new(
                        vec![(*v, y0), (*v, y1)],
                        8,
                        3,
                        ink.stroke_width(2),
                    ))
                    .map_err(|e| err(&e))?
                    .label(label.clone())
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 20, y)], ink.stroke_width(2))
                    });
            }
            let entries = p.lines.len() + p.h_lines.len() + p.v_lines.len();
            if entries > 0 {
                let (pw, ph) = $chart.plotting_area().dim_in_pixel();
                let entries = entries as f64;
                let top = legend_at.1 + 0.08 + 0.06 * entries;
                let at = SeriesLabelPosition::Coordinate(
                    (legend_at.0 * pw as f64) as i32,
                    ((1.0 - top) * ph as f64).max(0.0) as i32,
                );
                $chart
                    .configure_series_labels()
                    .position(at)
                    .label_font(("sans-serif", 12))
                    .background_style(WHITE.mix(0.8))
                    .border_style(BLACK.mix(0.3))
                    .draw()
                    .map_err(|e| err(&e))?;
            }
        }};
    }
    if p.log_y {
        let mut chart = builder
            .build_cartesian_2d(x0..x1, (y0..y1).log_scale())
            .map_err(|e| err(&e))?;
        body!(chart);
    } else {
        let mut chart = builder
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(|e| err(&e))?;
        body!(chart);
    }
    Ok(())
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
        let root =
            BitMapBackend::new(&path, (W * cols as u32, H * rows.max(1))).into_drawing_area();
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
}
