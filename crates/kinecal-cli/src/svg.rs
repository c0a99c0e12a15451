//! A small SVG writer for history plots: one panel per quantity, values with +-1 sigma bars,
//! a +-K sigma band around the first value, and tolerance lines.

use std::fmt::Write as _;

use kinecal_history::Quantity;

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// One panel: the quantity and its points (unix time, value, sigma).
pub type Series = (Quantity, Vec<(i64, f64, f64)>);

/// The SVG document for `series`.
pub fn history_svg(robot: &str, series: &[Series]) -> String {
    let (w, ph, top) = (900.0, 220.0, 50.0);
    let h = top + ph * series.len() as f64 + 20.0;
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" viewBox="0 0 {w} {h}" font-family="sans-serif" font-size="12">"#
    );
    let _ = writeln!(s, r#"<rect width="100%" height="100%" fill="white"/>"#);
    let _ = writeln!(
        s,
        r#"<text x="20" y="28" font-size="16">Calibration history of robot {}</text>"#,
        esc(robot)
    );
    for (k, (q, pts)) in series.iter().enumerate() {
        let y0 = top + ph * k as f64;
        let (left, right, pt, pb) = (110.0, w - 30.0, y0 + 30.0, y0 + ph - 40.0);
        let t0 = pts.iter().map(|p| p.0).min().unwrap_or(0) as f64;
        let t1 = (pts.iter().map(|p| p.0).max().unwrap_or(0) as f64).max(t0 + 86400.0);
        let first = pts.first().map_or(q.baseline, |p| p.1);
        let band = 3.0 * pts.first().map_or(q.sigma, |p| p.2);
        let mut lo = pts.iter().map(|p| p.1 - p.2).fold(first - band, f64::min);
        let mut hi = pts.iter().map(|p| p.1 + p.2).fold(first + band, f64::max);
        if let Some(t) = q.tolerance {
            lo = lo.min(first - t);
            hi = hi.max(first + t);
        }
        if hi - lo < 1e-15 {
            hi += 1e-12;
            lo -= 1e-12;
        }
        let pad = 0.08 * (hi - lo);
        let (lo, hi) = (lo - pad, hi + pad);
        let x = |t: f64| left + (right - left) * (t - t0) / (t1 - t0);
        let y = |v: f64| pb - (pb - pt) * (v - lo) / (hi - lo);
        let _ = writeln!(
            s,
            r#"<text x="{left}" y="{}" font-size="13">{}{} [{}]</text>"#,
            y0 + 20.0,
            esc(&q.quantity),
            if q.flagged { "  (FLAGGED)" } else { "" },
            esc(&q.unit)
        );
        let _ = writeln!(
            s,
            r##"<rect x="{left}" y="{pt}" width="{}" height="{}" fill="none" stroke="#888"/>"##,
            right - left,
            pb - pt
        );
        // +-3 sigma band around the first value.
        let _ = writeln!(
            s,
            r##"<rect x="{left}" y="{}" width="{}" height="{}" fill="#4a90d9" fill-opacity="0.12"/>"##,
            y(first + band),
            right - left,
            (y(first - band) - y(first + band)).max(0.5)
        );
        if let Some(t) = q.tolerance {
            for v in [first - t, first + t] {
                let _ = writeln!(
                    s,
                    r##"<line x1="{left}" x2="{right}" y1="{0}" y2="{0}" stroke="#d0021b" stroke-dasharray="6 4"/>"##,
                    y(v)
                );
            }
        }
        // Axis labels: value range and dates.
        for v in [lo + pad, hi - pad] {
            let _ = writeln!(
                s,
                r#"<text x="{}" y="{}" text-anchor="end">{:.6}</text>"#,
                left - 6.0,
                y(v) + 4.0,
                v
            );
        }
        for t in [t0, t1] {
            let _ = writeln!(
                s,
                r#"<text x="{}" y="{}" text-anchor="middle">{}</text>"#,
                x(t),
                pb + 16.0,
                esc(&kinecal_history::format_time(t as i64)[..10])
            );
        }
        let path: Vec<String> = pts
            .iter()
            .map(|p| format!("{:.2},{:.2}", x(p.0 as f64), y(p.1)))
            .collect();
        let _ = writeln!(
            s,
            r##"<polyline points="{}" fill="none" stroke="#333"/>"##,
            path.join(" ")
        );
        for p in pts {
            let (px, py) = (x(p.0 as f64), y(p.1));
            let _ = writeln!(
                s,
                r##"<line x1="{px:.2}" x2="{px:.2}" y1="{:.2}" y2="{:.2}" stroke="#333"/>"##,
                y(p.1 - p.2),
                y(p.1 + p.2)
            );
            let _ = writeln!(
                s,
                r##"<circle cx="{px:.2}" cy="{py:.2}" r="3" fill="#1f5fa8"/>"##
            );
        }
    }
    s.push_str("</svg>\n");
    s
}
