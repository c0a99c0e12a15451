//! # kinecal-report: pictures of kinecal results
//!
//! Characteristic curves (thesis Figs 4.2-4.11) as SVG or PNG, and a self-contained HTML
//! calibration report with inline SVG. Plots are drawn by `plotters` with its SVG and bitmap
//! backends; text uses the DejaVu Sans font bundled in this crate, so nothing is needed from
//! the system (no fontconfig, no freetype).

mod chart;
pub mod fleet;
mod html;
pub mod iso9283;
pub mod plan;
pub mod predict;

pub use chart::{render_png, render_svg, Line, Panel};
pub use html::html_report;

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
