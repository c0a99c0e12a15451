//! The fleet page: one table row per robot, one small chart per robot that needs attention.
//! The figures come from the caller (kinecal-history's fleet analysis); nothing is computed here.

use std::fmt::Write as _;

use crate::html::{esc, inline, page_head};
use crate::{render_svg, DrawError, Panel};

/// One row of the fleet table.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FleetRow {
    /// The cells, as text.
    pub cells: Vec<String>,
    /// The verdict, used as the row's class (`flagged`, `serviced`, `due`, `ok`, `single`).
    pub verdict: String,
}

/// One robot's chart.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FleetChart {
    /// The heading (serial and verdict).
    pub heading: String,
    /// Lines of text under the heading (the flagged quantities, the crossing).
    pub notes: Vec<String>,
    /// The chart.
    pub panel: Panel,
}

/// The fleet page's contents.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FleetPage {
    /// Title.
    pub title: String,
    /// A sentence under the title.
    pub summary: String,
    /// Column headings.
    pub columns: Vec<String>,
    /// Rows, most urgent first.
    pub rows: Vec<FleetRow>,
    /// Charts, in the rows' order.
    pub charts: Vec<FleetChart>,
}

/// The fleet page as a self-contained HTML document (inline SVG; opens offline).
pub fn html_fleet(p: &FleetPage) -> Result<String, DrawError> {
    let mut h = page_head(&p.title);
    h.push_str(
        "<style>tr.flagged td{background:#fbe3e3}tr.serviced td{background:#ece4f7}\
         tr.due td{background:#fff4d6}td.v{font-weight:bold;text-align:left}\
         .robots{display:grid;grid-template-columns:repeat(auto-fill,minmax(480px,1fr));gap:12px}\
         .robot{border:1px solid #ccc;padding:6px}.robot h3{margin:2px 0;font-size:15px}\
         .robot p{margin:2px 0;font-size:12px}.robot svg{width:100%;height:auto}</style>\n",
    );
    let _ = writeln!(h, "<h1>{}</h1>\n<p>{}</p>", esc(&p.title), esc(&p.summary));
    h.push_str("<table><tr>");
    for (k, c) in p.columns.iter().enumerate() {
        let class = if k == 0 || k == 1 || k + 1 == p.columns.len() {
            " class=\"l\""
        } else {
            ""
        };
        let _ = write!(h, "<th{class}>{}</th>", esc(c));
    }
    h.push_str("</tr>\n");
    for r in &p.rows {
        let _ = write!(h, "<tr class=\"{}\">", esc(&r.verdict));
        for (k, c) in r.cells.iter().enumerate() {
            let class = if k == 1 {
                " class=\"v\""
            } else if k == 0 || k + 1 == r.cells.len() {
                " class=\"l\""
            } else {
                ""
            };
            let _ = write!(h, "<td{class}>{}</td>", esc(c));
        }
        h.push_str("</tr>\n");
    }
    h.push_str("</table>\n");
    if !p.charts.is_empty() {
        h.push_str("<h2>Robots that need attention</h2>\n<div class=\"robots\">\n");
        for c in &p.charts {
            let _ = write!(h, "<div class=\"robot\"><h3>{}</h3>", esc(&c.heading));
            for n in &c.notes {
                let _ = write!(h, "<p>{}</p>", esc(n));
            }
            h.push_str(&inline(render_svg(std::slice::from_ref(&c.panel), 1)?));
            h.push_str("</div>\n");
        }
        h.push_str("</div>\n");
    }
    h.push_str("</body></html>\n");
    Ok(h)
}
