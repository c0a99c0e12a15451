//! The predicted accuracy in the HTML report: the summary table and the accuracy map (colour
//! maps of the predicted 95 % position bound on slices through the reachable space, and its
//! median and 95th percentile along each joint's range), drawn as inline SVG from the report's
//! figures alone.

use std::fmt::Write as _;

use kinecal::predict::{AccuracyMap, JointSweep, PredictionReport, Slice};

use crate::number::num;
use crate::page::{esc, page_head};

/// Colour stops of the scale (viridis, from low to high).
const STOPS: [(f64, [u8; 3]); 6] = [
    (0.0, [68, 1, 84]),
    (0.2, [65, 68, 135]),
    (0.4, [42, 120, 142]),
    (0.6, [34, 168, 132]),
    (0.8, [122, 209, 81]),
    (1.0, [253, 231, 37]),
];

/// The colour of `v` on the scale `[lo, hi]` (clamped).
fn colour(v: f64, lo: f64, hi: f64) -> String {
    let t = if hi > lo {
        ((v - lo) / (hi - lo)).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let k = STOPS
        .iter()
        .position(|s| s.0 >= t)
        .unwrap_or(STOPS.len() - 1)
        .max(1);
    let (a, b) = (STOPS[k - 1], STOPS[k]);
    let f = (t - a.0) / (b.0 - a.0);
    let c: Vec<u8> = (0..3)
        .map(|i| (a.1[i] as f64 + f * (b.1[i] as f64 - a.1[i] as f64)).round() as u8)
        .collect();
    format!("#{:02x}{:02x}{:02x}", c[0], c[1], c[2])
}

/// About five round ticks over `[lo, hi]`.
fn ticks(lo: f64, hi: f64) -> Vec<f64> {
    if hi.partial_cmp(&lo) != Some(std::cmp::Ordering::Greater) {
        return vec![lo];
    }
    let raw = (hi - lo) / 5.0;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 2.5, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * mag);
    // Counted, not stepped until past `hi`: a step below the spacing of the doubles near `lo`
    // (a span of 1e-3 at 1e20) would never get there.
    let first = (lo / step).ceil();
    let mut out = Vec::new();
    for k in 0..MAX_TICKS {
        let t = (first + k as f64) * step;
        if t.is_nan() || t > hi + 1e-9 * step {
            break;
        }
        out.push(if t.abs() < 1e-9 * step { 0.0 } else { t });
    }
    out
}

/// The most ticks an axis gets (about five are asked for).
const MAX_TICKS: usize = 12;

fn slice_svg(s: &Slice, scale: [f64; 2], unit: &str) -> String {
    let [u0, u1, v0, v1] = s.extent;
    let plot_w = 420.0;
    let plot_h = (plot_w * (v1 - v0) / (u1 - u0)).clamp(120.0, 460.0);
    let (left, top) = (62.0, 34.0);
    let (w, h) = (left + plot_w + 16.0, top + plot_h + 46.0);
    let x = |u: f64| left + (u - u0) / (u1 - u0) * plot_w;
    let y = |v: f64| top + plot_h - (v - v0) / (v1 - v0) * plot_h;
    let mut o = String::new();
    let _ = write!(
        o,
        "<svg width=\"{w:.0}\" height=\"{h:.0}\" viewBox=\"0 0 {w:.0} {h:.0}\" font-family=\"sans-serif\" font-size=\"12\">\
         <text x=\"{:.0}\" y=\"18\" text-anchor=\"middle\" font-size=\"13\">{}</text>\
         <rect x=\"{left}\" y=\"{top}\" width=\"{plot_w}\" height=\"{plot_h:.1}\" fill=\"#f4f4f4\" stroke=\"#888\"/>",
        left + plot_w / 2.0,
        esc(&s.title)
    );
    let (cw, ch) = ((u1 - u0) / s.nu as f64, (v1 - v0) / s.nv as f64);
    for (k, v) in s.values.iter().enumerate() {
        if let Some(v) = v {
            let (iu, iv) = (k % s.nu, k / s.nu);
            let (ua, va) = (u0 + iu as f64 * cw, v0 + iv as f64 * ch);
            let _ = write!(
                o,
                "<rect x=\"{:.2}\" y=\"{:.2}\" width=\"{:.2}\" height=\"{:.2}\" fill=\"{}\"><title>{} {unit}</title></rect>",
                x(ua),
                y(va + ch),
                x(ua + cw) - x(ua) + 0.3,
                y(va) - y(va + ch) + 0.3,
                colour(*v, scale[0], scale[1]),
                num(*v)
            );
        }
    }
    for p in &s.measured {
        let _ = write!(
            o,
            "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"2.2\" fill=\"white\" stroke=\"black\" stroke-width=\"0.8\"/>",
            x(p[0]),
            y(p[1])
        );
    }
    for t in ticks(u0, u1) {
        let _ = write!(
            o,
            "<line x1=\"{0:.1}\" x2=\"{0:.1}\" y1=\"{1:.1}\" y2=\"{2:.1}\" stroke=\"#888\"/><text x=\"{0:.1}\" y=\"{3:.1}\" text-anchor=\"middle\">{4}</text>",
            x(t),
            top + plot_h,
            top + plot_h + 4.0,
            top + plot_h + 17.0,
            tick(t)
        );
    }
    for t in ticks(v0, v1) {
        let _ = write!(
            o,
            "<line x1=\"{0:.1}\" x2=\"{1:.1}\" y1=\"{2:.1}\" y2=\"{2:.1}\" stroke=\"#888\"/><text x=\"{3:.1}\" y=\"{4:.1}\" text-anchor=\"end\">{5}</text>",
            left - 4.0,
            left,
            y(t),
            left - 6.0,
            y(t) + 4.0,
            tick(t)
        );
    }
    let _ = write!(
        o,
        "<text x=\"{:.0}\" y=\"{:.0}\" text-anchor=\"middle\">{} ({unit})</text>\
         <text x=\"14\" y=\"{:.0}\" text-anchor=\"middle\" transform=\"rotate(-90 14 {:.0})\">{} ({unit})</text></svg>",
        left + plot_w / 2.0,
        top + plot_h + 36.0,
        esc(&s.axes[0]),
        top + plot_h / 2.0,
        top + plot_h / 2.0,
        esc(&s.axes[1])
    );
    o
}

fn tick(v: f64) -> String {
    let s = format!("{v:.6}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" {
        "0".into()
    } else {
        s.to_string()
    }
}

fn colour_bar(scale: [f64; 2], unit: &str) -> String {
    let (w, h, left) = (520.0, 58.0, 20.0);
    let bar_w = 440.0;
    let mut o = format!(
        "<svg width=\"{w}\" height=\"{h}\" viewBox=\"0 0 {w} {h}\" font-family=\"sans-serif\" font-size=\"12\">"
    );
    for k in 0..110 {
        let t = k as f64 / 110.0;
        let _ = write!(
            o,
            "<rect x=\"{:.2}\" y=\"8\" width=\"{:.2}\" height=\"16\" fill=\"{}\"/>",
            left + t * bar_w,
            bar_w / 110.0 + 0.3,
            colour(scale[0] + t * (scale[1] - scale[0]), scale[0], scale[1])
        );
    }
    for t in ticks(scale[0], scale[1]) {
        let xx = left + (t - scale[0]) / (scale[1] - scale[0]).max(1e-300) * bar_w;
        let _ = write!(
            o,
            "<line x1=\"{xx:.1}\" x2=\"{xx:.1}\" y1=\"24\" y2=\"28\" stroke=\"#333\"/><text x=\"{xx:.1}\" y=\"40\" text-anchor=\"middle\">{}</text>",
            tick(t)
        );
    }
    let _ = write!(
        o,
        "<text x=\"{:.0}\" y=\"54\" text-anchor=\"middle\">predicted 95 % position bound ({unit}); the top colour includes everything above</text></svg>",
        left + bar_w / 2.0
    );
    o
}

fn sweep_svg(j: &JointSweep, unit: &str, hi: f64) -> String {
    let (left, top, pw, ph) = (56.0, 28.0, 300.0, 150.0);
    let (w, h) = (left + pw + 14.0, top + ph + 44.0);
    let (a, b) = (j.edges[0], *j.edges.last().unwrap_or(&1.0));
    let x = |v: f64| left + (v - a) / (b - a).max(1e-300) * pw;
    let y = |v: f64| top + ph - (v / hi).clamp(0.0, 1.05) * ph;
    let mut o = format!(
        "<svg width=\"{w:.0}\" height=\"{h:.0}\" viewBox=\"0 0 {w:.0} {h:.0}\" font-family=\"sans-serif\" font-size=\"12\">\
         <text x=\"{:.0}\" y=\"16\" text-anchor=\"middle\" font-size=\"13\">joint {}</text>\
         <rect x=\"{left}\" y=\"{top}\" width=\"{pw}\" height=\"{ph}\" fill=\"none\" stroke=\"#888\"/>",
        left + pw / 2.0,
        j.joint
    );
    // The measured postures per bin, as grey bars (scaled to the tallest).
    let most = j.measured.iter().copied().max().unwrap_or(0).max(1) as f64;
    for (k, &m) in j.measured.iter().enumerate() {
        if m > 0 {
            let bh = 0.35 * ph * m as f64 / most;
            let _ = write!(
                o,
                "<rect x=\"{:.1}\" y=\"{:.1}\" width=\"{:.1}\" height=\"{bh:.1}\" fill=\"#ccc\"><title>{m} measured</title></rect>",
                x(j.edges[k]),
                top + ph - bh,
                x(j.edges[k + 1]) - x(j.edges[k])
            );
        }
    }
    for (vals, style) in [
        (&j.p95, "stroke=\"#d62728\" stroke-dasharray=\"4 3\""),
        (&j.median, "stroke=\"#1f77b4\""),
    ] {
        let mut path = String::new();
        for (k, v) in vals.iter().enumerate() {
            if let Some(v) = v {
                let c = 0.5 * (j.edges[k] + j.edges[k + 1]);
                let _ = write!(
                    path,
                    "{}{:.1},{:.1} ",
                    if path.is_empty() || vals[k - 1].is_none() {
                        "M"
                    } else {
                        "L"
                    },
                    x(c),
                    y(*v)
                );
            }
        }
        let _ = write!(
            o,
            "<path d=\"{path}\" fill=\"none\" stroke-width=\"2\" {style}/>"
        );
    }
    for t in ticks(a, b) {
        let _ = write!(
            o,
            "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\">{}</text>",
            x(t),
            top + ph + 16.0,
            tick(t)
        );
    }
    for t in ticks(0.0, hi) {
        let _ = write!(
            o,
            "<line x1=\"{0:.1}\" x2=\"{1:.1}\" y1=\"{2:.1}\" y2=\"{2:.1}\" stroke=\"#eee\"/><text x=\"{3:.1}\" y=\"{4:.1}\" text-anchor=\"end\">{5}</text>",
            left,
            left + pw,
            y(t),
            left - 4.0,
            y(t) + 4.0,
            tick(t)
        );
    }
    let _ = write!(
        o,
        "<text x=\"{:.0}\" y=\"{:.0}\" text-anchor=\"middle\">reading</text><text x=\"12\" y=\"{:.0}\" text-anchor=\"middle\" transform=\"rotate(-90 12 {:.0})\">bound ({unit})</text></svg>",
        left + pw / 2.0,
        top + ph + 36.0,
        top + ph / 2.0,
        top + ph / 2.0
    );
    o
}

/// The accuracy map's pictures (no heading).
pub fn accuracy_map(map: &AccuracyMap) -> String {
    let unit = map.unit.as_str();
    let mut h = String::new();
    let _ = writeln!(
        h,
        "<p>The predicted 95 % bound on the error of <b>{}</b>'s position, over {} postures drawn in the joint ranges. \
         Frame: the first link's (z along joint 1's axis). A cell's colour is the median bound of the drawn postures whose target falls in it \
         (empty: none reaches it); white dots are measured postures within the slice. Where the colour is dark, the calibration holds; \
         where it is bright, measure more postures there.</p>",
        esc(&map.target),
        map.samples
    );
    h += &colour_bar(map.scale, unit);
    h += "<div class=\"charts\">";
    for s in &map.slices {
        h += &slice_svg(s, map.scale, unit);
    }
    h += "</div>\n<p>Along each joint's range: the median (solid) and 95th percentile (dashed) of the bound of the drawn postures, per bin of the joint's reading; grey bars: the measured postures in each bin.</p><div class=\"charts\">";
    let hi = map
        .joints
        .iter()
        .flat_map(|j| j.p95.iter().flatten())
        .fold(0.0f64, |a, &b| a.max(b))
        .max(1e-300)
        * 1.05;
    for j in &map.joints {
        h += &sweep_svg(j, unit, hi);
    }
    h += "</div>\n";
    h
}

/// The report's predicted-accuracy section: the model-error term, its cross-validated
/// coverage, the summary over the joint ranges and, when the report holds it, the map.
pub fn section(p: &PredictionReport, length: &str, angle: &str) -> String {
    let mut h = String::from("<h2 id=\"prediction\">Predicted accuracy</h2>\n");
    let _ = writeln!(
        h,
        "<p>The error of the calibrated robot at a posture: the parameters' covariance through the Jacobian, plus a model error of per-axis variance \
         <code>s0&sup2; + (c d)&sup2;</code>, <code>d</code> the distance in joint space to the nearest measured posture \
         (each joint's reading difference times its lever on the target), estimated by cross-validation on blocks of nearby postures ({} blocks).</p>",
        p.folds
            .iter()
            .map(|f| f.to_string())
            .collect::<Vec<_>>()
            .join(" and ")
    );
    let _ = writeln!(
        h,
        "<table><tr><th class=\"l\"></th><th>s0</th><th>c</th><th>shape</th><th>held out</th><th>within the 95 % bound</th><th>a single variance</th><th>the parameters alone</th></tr>"
    );
    let mut row = |name: &str, g: &kinecal::predict::GrowthReport, unit: &str| {
        let _ = writeln!(
            h,
            "<tr><td class=\"l\">{name} ({unit})</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{:.1} %</td><td>{:.1} %</td><td>{:.1} %</td></tr>",
            num(g.s0),
            num(g.c),
            num(g.shape),
            g.points,
            100.0 * g.coverage,
            100.0 * g.coverage_constant,
            100.0 * g.coverage_parameters_only
        );
    };
    row("position", &p.position, length);
    if let Some(a) = &p.attitude {
        row("attitude", a, angle);
    }
    let _ = writeln!(h, "</table>");
    let _ = writeln!(
        h,
        "<table><tr><th class=\"l\">predicted 95 % bound</th><th>median</th><th>95th percentile</th><th>median at the measured postures</th></tr>\
         <tr><td class=\"l\">position over {} postures in the joint ranges ({length})</td><td>{}</td><td>{}</td><td>{}</td></tr>",
        p.samples,
        num(p.position_summary.median),
        num(p.position_summary.p95),
        num(p.position_summary.median_measured)
    );
    if let Some(a) = &p.attitude_summary {
        let _ = writeln!(
            h,
            "<tr><td class=\"l\">attitude ({angle})</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            num(a.median),
            num(a.p95),
            num(a.median_measured)
        );
    }
    let _ = writeln!(h, "</table>");
    if let Some(m) = &p.map {
        let _ = writeln!(h, "<h3 id=\"accuracy-map\">Accuracy map</h3>");
        h += &accuracy_map(m);
    }
    h
}

/// A page of its own for `kinecal predict --html`: the section of `p` (whose map is shown).
pub fn page(p: &PredictionReport, robot: &str, length: &str, angle: &str) -> String {
    let mut h = page_head(&format!("kinecal predicted accuracy: {robot}"));
    let _ = writeln!(h, "<h1>Predicted accuracy: {}</h1>", esc(robot));
    h += &section(p, length, angle);
    h += "</body></html>\n";
    h
}
