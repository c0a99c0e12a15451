//! # kinecal-report: pictures of kinecal results
//!
//! Characteristic curves (thesis Figs 4.2-4.11) as SVG or PNG, and a self-contained HTML
//! calibration report with inline SVG. Plots are drawn by `plotters` with its SVG and bitmap
//! backends; text uses the DejaVu Sans font bundled in this crate, so nothing is needed from
//! the system (no fontconfig, no freetype).

mod chart;
pub mod display;
pub mod fleet;
mod html;
pub mod iso9283;
mod kerned;
pub mod number;
mod page;
pub mod plan;
pub mod predict;
pub mod verdict;
pub mod view;
mod view3d;

pub use chart::{render_png, render_svg, Line, Panel};
pub use display::{DisplayChoice, DisplayUnits};
pub use html::{html_report, html_report_in};

/// The pages and pictures of kinecal's jobs, drawn by this crate: what a front end hands to
/// [`kinecal::spec::run`].
#[derive(Debug, Clone, Copy, Default)]
pub struct Artist;

impl kinecal::spec::Artist for Artist {
    fn draw(&self, page: kinecal::spec::Page<'_>) -> kinecal::Result<Vec<u8>> {
        use kinecal::spec::{Image, Page};
        let failed = |e: DrawError| kinecal::Error::Numerical(e.to_string());
        Ok(match page {
            Page::Calibration { report, units } => {
                html_report_in(report, units).map_err(failed)?.into_bytes()
            }
            Page::Plan {
                plan,
                robot,
                pool,
                described,
            } => plan::html_plan(plan, robot, pool, described)
                .map_err(failed)?
                .into_bytes(),
            Page::Prediction {
                prediction,
                robot,
                length_unit,
                angle_unit,
                units,
            } => {
                let c = display::Convert::new(units, length_unit, angle_unit);
                let shown = display::prediction(prediction, &c);
                predict::page(&shown, robot, c.l(), c.a()).into_bytes()
            }
            Page::Iso9283(e) => iso9283::html_iso9283(e).into_bytes(),
            Page::Curves { curves, image } => {
                let panels: Vec<Panel> = curves
                    .charts
                    .iter()
                    .map(|c| Panel {
                        title: c.title.clone(),
                        x_label: c.x_label.clone(),
                        y_label: c.y_label.clone(),
                        x: c.x.clone(),
                        lines: c
                            .lines
                            .iter()
                            .map(|(name, y)| Line::new(name.clone(), y.clone()))
                            .collect(),
                        mark_x: Some(c.mark_x),
                        ..Default::default()
                    })
                    .collect();
                match image {
                    Image::Svg => render_svg(&panels, curves.columns)
                        .map_err(failed)?
                        .into_bytes(),
                    Image::Png => render_png(&panels, curves.columns).map_err(failed)?,
                }
            }
            _ => unreachable!("every page is drawn"),
        })
    }
}

/// Errors of drawing.
#[derive(Debug)]
pub struct DrawError(pub String);

impl std::fmt::Display for DrawError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "drawing failed: {}", self.0)
    }
}

impl std::error::Error for DrawError {}

static FONT: &[u8] = include_bytes!("../fonts/DejaVuSans.ttf");

/// Registers the bundled font as `sans-serif` (once).
pub fn register_fonts() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        plotters::style::register_font("sans-serif", plotters::style::FontStyle::Normal, FONT)
            .unwrap_or_else(|_| panic!("the bundled DejaVu Sans font is valid"));
    });
}
