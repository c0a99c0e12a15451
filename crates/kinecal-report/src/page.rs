//! The building blocks of every self-contained page kinecal draws (the calibration report, the
//! predicted accuracy, the posture plan, ISO 9283, the fleet): text escaping, the shared head
//! and inline style, and charts as inline SVG with no URL in the file.

use crate::chart::{render_svg, Panel};
use crate::DrawError;

/// `s` with the characters HTML gives a meaning (`& < > "`) escaped.
pub(crate) fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// Inline SVG: the namespace declaration is dropped (HTML5 knows inline SVG), so the file holds
/// no URL at all.
pub(crate) fn inline(svg: String) -> String {
    svg.replace(" xmlns=\"http://www.w3.org/2000/svg\"", "")
        .replace(" xmlns:xlink=\"http://www.w3.org/1999/xlink\"", "")
}

/// The start of a self-contained page titled `title` (escaped here): the shared inline style,
/// up to the opening `<body>`.
pub(crate) fn page_head(title: &str) -> String {
    format!(
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{}</title>\n\
         <style>body{{font-family:sans-serif;max-width:1200px;margin:2em auto;color:#222}}\
         table{{border-collapse:collapse;margin:1em 0}}td,th{{border:1px solid #bbb;padding:3px 8px;text-align:right}}\
         th{{background:#eee}}td.l,th.l{{text-align:left}}.warn{{color:#a33}}svg{{max-width:100%;height:auto}}.charts{{display:flex;flex-wrap:wrap;gap:0}}.charts svg{{max-width:50%}}\
         .verdict{{border-left:8px solid #4a4;background:#f2f8f2;padding:0.6em 1em;margin:1em 0}}.verdict.caution{{border-color:#c90;background:#fbf6ea}}.verdict.failed{{border-color:#c33;background:#fbeeee}}.verdict p.head{{font-size:1.15em;font-weight:bold;margin:0.2em 0}}\
         .error{{color:#a22;font-weight:bold}}.caution{{color:#8a5a00}}.note{{color:#555}}dl.facts{{display:grid;grid-template-columns:max-content minmax(0,1fr);gap:2px 1em;font-size:0.9em}}dl.facts dt{{color:#555}}dl.facts dd{{margin:0;overflow-wrap:anywhere}}</style></head><body>\n",
        esc(title)
    )
}

/// Each panel as its own inline SVG, side by side while the page is wide enough.
pub(crate) fn charts(panels: &[Panel]) -> Result<String, DrawError> {
    let mut out = String::from("<div class=\"charts\">");
    for p in panels {
        out += &inline(render_svg(std::slice::from_ref(p), 1)?);
    }
    out += "</div>";
    Ok(out)
}
