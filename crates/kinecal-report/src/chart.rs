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
}

impl Line {
    /// A plain line.
    pub fn new(label: impl Into<String>, y: Vec<f64>) -> Self {
        Line {
            label: label.into(),
            y,
            points: false,
            error: None,
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
    /// Logarithmic y axis.
    pub log_y: bool,
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
    let x0 = p.x.iter().copied().fold(f64::INFINITY, f64::min);
    let x1 = p.x.iter().copied().fold(f64::NEG_INFINITY, f64::max);
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
    let pad = 0.06 * (y1 - y0).max(1e-12 * y1.abs().max(1.0));
    (x0, x1.max(x0 + 1e-12), y0 - pad, y1 + pad)
}

fn draw_panel<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, p: &Panel) -> Result<(), DrawError>
where
    DB::ErrorType: 'static,
{
    let err = |e: &dyn std::fmt::Display| DrawError(e.to_string());
    let (x0, x1, y0, y1) = bounds(p);
    let mut builder = ChartBuilder::on(area);
    builder
        .caption(&p.title, ("sans-serif", 16))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(80);
    macro_rules! body {
        ($chart:ident) => {{
            $chart
                .configure_mesh()
                .x_desc(&p.x_label)
                .y_desc(&p.y_label)
                .label_style(("sans-serif", 12))
                .light_line_style(WHITE.mix(0.0))
                .draw()
                .map_err(|e| err(&e))?;
            for (k, l) in p.lines.iter().enumerate() {
                let color = COLORS[k % COLORS.len()];
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
                        .draw_series(p.x.iter().zip(&l.y).zip(e).map(|((&x, &y), &e)| {
                            PathElement::new(vec![(x, y - e), (x, y + e)], color.stroke_width(1))
                        }))
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
            $chart
                .configure_series_labels()
                .label_font(("sans-serif", 12))
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK.mix(0.3))
                .draw()
                .map_err(|e| err(&e))?;
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

/// Renders `panels` as a PNG file.
pub fn render_png(panels: &[Panel], cols: usize, path: &std::path::Path) -> Result<(), DrawError> {
    register_fonts();
    let rows = panels.len().div_ceil(cols.max(1)) as u32;
    let root = BitMapBackend::new(path, (W * cols as u32, H * rows.max(1))).into_drawing_area();
    draw_all(root, panels, cols)
}
