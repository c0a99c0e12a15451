//! The HTML page of an ISO 9283 evaluation: per pose, its figures and a scatter of the attained
//! positions about the commanded one (top and side views); the distance figures; the symbols.
//! Self-contained: inline CSS and SVG, no script, no URL.

use std::fmt::Write as _;

use kinecal::apps::iso9283::{pose_name, Evaluation, PoseFigures, Spread};

use crate::number::{num, signed};
use crate::page::{esc, page_head};

/// One view of the attained positions: a `w` x `w` panel at `x0`, positions relative to
/// `origin` along axes `(h, v)` (0 = x, 1 = y, 2 = z), `range` either side.
struct View<'a> {
    title: &'a str,
    axes: (usize, usize),
    origin: [f64; 3],
    range: f64,
}

fn view(svg: &mut String, f: &PoseFigures, v: &View<'_>, x0: f64, w: f64, unit: &str) {
    let (h, vv) = v.axes;
    let top = 22.0;
    let c = (x0 + w / 2.0, top + w / 2.0);
    let scale = (w / 2.0) / v.range;
    let rel = |p: [f64; 3]| {
        (
            c.0 + (p[h] - v.origin[h]) * scale,
            c.1 - (p[vv] - v.origin[vv]) * scale,
        )
    };
    let _ = write!(
        svg,
        "<text x=\"{:.1}\" y=\"14\" text-anchor=\"middle\" class=\"t\">{}</text>",
        c.0,
        esc(v.title)
    );
    let _ = write!(
        svg,
        "<rect x=\"{x0:.1}\" y=\"{top:.1}\" width=\"{w:.1}\" height=\"{w:.1}\" class=\"frame\"/>\
         <line x1=\"{x0:.1}\" y1=\"{cy:.1}\" x2=\"{x1:.1}\" y2=\"{cy:.1}\" class=\"axis\"/>\
         <line x1=\"{cx:.1}\" y1=\"{top:.1}\" x2=\"{cx:.1}\" y2=\"{y1:.1}\" class=\"axis\"/>",
        cx = c.0,
        cy = c.1,
        x1 = x0 + w,
        y1 = top + w
    );
    // The scale at the panel's edges.
    let _ = write!(
        svg,
        "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"end\" class=\"s\">+{} {unit}</text>\
         <text x=\"{:.1}\" y=\"{:.1}\" class=\"s\">+{} {unit}</text>",
        x0 + w - 3.0,
        c.1 - 4.0,
        num(v.range),
        c.0 + 4.0,
        top + 11.0,
        num(v.range)
    );
    // RP about the barycentre, the attained positions, the barycentre, the commanded position.
    let b = rel(f.barycentre);
    if let Some(rp) = f.rp {
        let _ = write!(
            svg,
            "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"{:.1}\" class=\"rp\"/>",
            b.0,
            b.1,
            rp * scale
        );
    }
    for p in &f.attained {
        let q = rel(*p);
        let _ = write!(
            svg,
            "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"2.5\" class=\"pt\"/>",
            q.0, q.1
        );
    }
    let _ = write!(
        svg,
        "<path d=\"M{:.1} {:.1}l8 8m0 -8l-8 8\" class=\"bary\"/>",
        b.0 - 4.0,
        b.1 - 4.0
    );
    let m = rel(f.commanded);
    if (m.0 - c.0).abs() <= w / 2.0 && (m.1 - c.1).abs() <= w / 2.0 {
        let _ = write!(
            svg,
            "<path d=\"M{:.1} {:.1}h12m-6 -6v12\" class=\"cmd\"/>",
            m.0 - 6.0,
            m.1
        );
    }
}

/// The scatter of one pose: top (x, y) and side (x, z) views of the attained positions about
/// the commanded one (the accuracy), and a top view about their barycentre, closer (the
/// repeatability); the barycentre and a circle of radius RP about it in each.
fn scatter(f: &PoseFigures, unit: &str) -> String {
    let far = f
        .attained
        .iter()
        .flat_map(|p| (0..3).map(move |k| (p[k] - f.commanded[k]).abs()))
        .fold(0.0, f64::max)
        .max(f.ap + f.rp.unwrap_or(0.0));
    let near = f
        .attained
        .iter()
        .flat_map(|p| (0..3).map(move |k| (p[k] - f.barycentre[k]).abs()))
        .fold(0.0, f64::max)
        .max(f.rp.unwrap_or(0.0));
    let range = |r: f64| if r > 0.0 { 1.15 * r } else { 1.0 };
    let views = [
        View {
            title: "top: x, y about the commanded",
            axes: (0, 1),
            origin: f.commanded,
            range: range(far),
        },
        View {
            title: "side: x, z about the commanded",
            axes: (0, 2),
            origin: f.commanded,
            range: range(far),
        },
        View {
            title: "top: x, y about the barycentre",
            axes: (0, 1),
            origin: f.barycentre,
            range: range(near),
        },
    ];
    let w = 170.0;
    let width = 3.0 * (w + 20.0) + 5.0;
    let mut svg = format!(
        "<svg width=\"{width:.0}\" height=\"{:.0}\" viewBox=\"0 0 {width:.0} {:.0}\" role=\"img\">",
        w + 30.0,
        w + 30.0,
    );
    for (i, v) in views.iter().enumerate() {
        view(&mut svg, f, v, 5.0 + i as f64 * (w + 20.0), w, unit);
    }
    svg += "</svg>";
    svg
}

/// The HTML page of an evaluation: the log and its warnings; for a series of logs its table;
/// else each pose's figures and scatter, then the distances; the symbols last.
pub fn html_iso9283(e: &Evaluation) -> String {
    let l = e
        .length_unit
        .map_or_else(|| "(log's length unit)".to_string(), |u| u.to_string());
    let a = e
        .angle_unit
        .map_or_else(|| "(log's angle unit)".to_string(), |u| u.to_string());
    let mut h = page_head(&format!("ISO 9283 pose characteristics: {}", e.file));
    h += STYLE;
    h += &intro(e, &l, &a);
    if e.summary.is_some() {
        h += &series(e, &l);
        h += SYMBOLS;
        return h;
    }
    h += SCATTER_KEY;
    for f in &e.poses {
        h += &pose(f, &l, &a);
    }
    h += &distances(e, &l);
    h += SYMBOLS;
    h
}

/// The page's own style: poses side by side with their scatter, the scatter's marks.
const STYLE: &str = "<style>.pose{display:flex;flex-wrap:wrap;gap:1.5em;align-items:flex-start}\
          .pose table{margin:0}svg .t{font-size:12px}svg .s{font-size:10px;fill:#555}\
          svg .frame{fill:#fafafa;stroke:#bbb}svg .axis{stroke:#bbb;stroke-dasharray:3 3}\
          svg .pt{fill:#1f6fb4;fill-opacity:0.7}svg .bary{stroke:#c0392b;stroke-width:2;fill:none}\
          svg .cmd{stroke:#222;stroke-width:1.5;fill:none}\
          svg .rp{fill:none;stroke:#c0392b;stroke-dasharray:4 3}\
          .key{font-size:90%;color:#444}</style>\n";

/// How to read the scatters.
const SCATTER_KEY: &str = "<p class=\"key\">Per pose, the attained positions (blue dots) from \
         above and from the side about the commanded one (<b>+</b>), and from above about their \
         barycentre (<span style=\"color:#c0392b\">&times;</span>), closer; the dashed circle has \
         the radius RP about the barycentre.</p>\n";

/// The title, the log (simulated or measured), its poses and units, and its warnings.
fn intro(e: &Evaluation, l: &str, a: &str) -> String {
    let mut h = format!(
        "<h1>ISO 9283 pose characteristics</h1><p>Log <b>{}</b>{}: {} pose{}, lengths in {}, angles in {}.</p>\n",
        esc(&e.file),
        if e.simulated {
            " (<b>simulated</b>, not measured)"
        } else {
            ""
        },
        e.poses.len(),
        if e.poses.len() == 1 { "" } else { "s" },
        esc(l),
        esc(a)
    );
    for w in &e.warnings {
        let _ = writeln!(h, "<p class=\"warn\">Warning: {}</p>", esc(w));
    }
    h
}

/// One pose: its figures' table beside its scatter.
fn pose(f: &PoseFigures, l: &str, a: &str) -> String {
    let mut h = format!(
        "<h2>{}{}</h2><div class=\"pose\"><table><tr><th class=\"l\">figure</th><th>value</th><th class=\"l\">unit</th></tr>\n",
        f.test.as_deref().map(|t| format!("{}, ", esc(t))).unwrap_or_default(),
        pose_name(f.pose)
    );
    for (name, value, unit) in pose_figures(f, l, a) {
        let _ = writeln!(
            h,
            "<tr><td class=\"l\">{name}</td><td>{value}</td><td class=\"l\">{}</td></tr>",
            esc(unit)
        );
    }
    h += "</table>";
    h += &scatter(f, l);
    h += "</div>\n";
    h
}

/// A pose's figures as rows `(name, value, unit)`: cycles, commanded pose, AP (and its axes),
/// RP (with l-bar and S_l), AP once compensated, the attitude's AP and RP, vAP.
fn pose_figures<'a>(f: &PoseFigures, l: &'a str, a: &'a str) -> Vec<(String, String, &'a str)> {
    let mut rows = Vec::new();
    let mut row = |name: &str, value: String, unit: &'a str| {
        rows.push((name.to_string(), value, unit));
    };
    row("cycles n", f.cycles.to_string(), "");
    row(
        "commanded x<sub>c</sub>, y<sub>c</sub>, z<sub>c</sub>",
        f.commanded.map(num).join(", "),
        l,
    );
    if let Some(c) = f.commanded_attitude {
        row(
            "commanded a<sub>c</sub>, b<sub>c</sub>, c<sub>c</sub>",
            c.map(num).join(", "),
            a,
        );
    }
    row("<b>AP</b> pose accuracy", num(f.ap), l);
    row(
        "AP<sub>x</sub>, AP<sub>y</sub>, AP<sub>z</sub>",
        f.ap_xyz.map(|v| signed(v, 4)).join(", "),
        l,
    );
    match (f.rp, f.l_mean, f.s_l) {
        (Some(rp), Some(l_mean), Some(s_l)) => {
            row("<b>RP</b> pose repeatability", num(rp), l);
            row(
                "l&#772;, S<sub>l</sub>",
                format!("{}, {}", num(l_mean), num(s_l)),
                l,
            );
        }
        _ => row("<b>RP</b> pose repeatability", "n/a (1 cycle)".into(), ""),
    }
    if let Some(c) = &f.compensated {
        row(
            "AP once compensated (predicted): RMS, 95 % bound",
            format!("{}, {}", num(c.ap_rms), num(c.ap_95)),
            l,
        );
    }
    if let Some(ap) = f.ap_abc {
        row(
            "AP<sub>a</sub>, AP<sub>b</sub>, AP<sub>c</sub>",
            ap.map(|v| signed(v, 4)).join(", "),
            a,
        );
    }
    if let Some(rp) = f.rp_abc {
        row(
            "RP<sub>a</sub>, RP<sub>b</sub>, RP<sub>c</sub> (&plusmn;)",
            rp.map(num).join(", "),
            a,
        );
    }
    if let Some(m) = &f.multidirectional {
        row(
            &format!("<b>vAP</b> ({} directions)", m.directions.len()),
            num(m.vap),
            l,
        );
        if let Some(v) = m.vap_abc {
            row(
                "vAP<sub>a</sub>, vAP<sub>b</sub>, vAP<sub>c</sub>",
                v.map(num).join(", "),
                a,
            );
        }
    }
    rows
}

/// The distance accuracy and repeatability between pairs of poses.
fn distances(e: &Evaluation, l: &str) -> String {
    if e.distances.is_empty() {
        return String::new();
    }
    let mut h = String::from(
        "<h2>Distance accuracy and repeatability</h2><table><tr><th class=\"l\">poses</th><th>n</th>\
         <th>D<sub>c</sub></th><th>D&#772;</th><th>AD</th><th>AD<sub>x</sub></th><th>AD<sub>y</sub></th>\
         <th>AD<sub>z</sub></th><th>RD (&plusmn;)</th></tr>\n",
    );
    for d in &e.distances {
        let _ = writeln!(
            h,
            "<tr><td class=\"l\">{}-{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            pose_name(d.from),
            pose_name(d.to),
            d.cycles,
            num(d.commanded),
            num(d.mean),
            signed(d.ad, 4),
            signed(d.ad_xyz[0], 4),
            signed(d.ad_xyz[1], 4),
            signed(d.ad_xyz[2], 4),
            d.rd.map_or_else(|| "n/a".to_string(), num)
        );
    }
    let _ = writeln!(h, "</table><p class=\"key\">Lengths in {}.</p>", esc(l));
    h
}

/// The symbols' table, and the page's end.
const SYMBOLS: &str = "<h2>Symbols (ISO 9283:1998, 7.2 and 7.3)</h2><table class=\"key\">\
          <tr><td class=\"l\">AP</td><td class=\"l\">&radic;((x&#772; &minus; x<sub>c</sub>)&sup2; + (y&#772; &minus; y<sub>c</sub>)&sup2; + (z&#772; &minus; z<sub>c</sub>)&sup2;): the barycentre of the attained positions from the commanded one</td></tr>\
          <tr><td class=\"l\">RP</td><td class=\"l\">l&#772; + 3 S<sub>l</sub>: l<sub>j</sub> the distance of attained position j from the barycentre, S<sub>l</sub> their standard deviation (n &minus; 1)</td></tr>\
          <tr><td class=\"l\">AP<sub>a</sub>, RP<sub>a</sub></td><td class=\"l\">the mean of a<sub>j</sub> &minus; a<sub>c</sub> (wrapped to half a turn), &plusmn;3 S<sub>a</sub> (n &minus; 1); likewise b, c</td></tr>\
          <tr><td class=\"l\">AD, RD</td><td class=\"l\">D&#772; &minus; D<sub>c</sub> and &plusmn;3 S<sub>D</sub>: D<sub>j</sub> the distance between two poses attained in cycle j</td></tr>\
          <tr><td class=\"l\">vAP</td><td class=\"l\">the largest distance between the barycentres reached from different approach directions</td></tr>\
          </table></body></html>\n";

/// `count, mean, p95, max` cells of a spread.
fn cells(v: Option<&Spread>) -> String {
    match v {
        Some(v) => format!(
            "<td>{}</td><td>{}</td><td>{}</td><td>{}</td>",
            v.count,
            num(v.mean),
            num(v.p95),
            num(v.max)
        ),
        None => "<td>0</td><td>-</td><td>-</td><td>-</td>".into(),
    }
}

/// A series of tests: the summary across them, then every test's poses in one table.
fn series(e: &Evaluation, l: &str) -> String {
    let Some(sum) = &e.summary else {
        return String::new();
    };
    let mut h = String::new();
    let name = |pose: usize| {
        if pose == 0 {
            "every pose".to_string()
        } else {
            pose_name(pose)
        }
    };
    let compensated = sum.poses.iter().any(|p| p.compensated_95.is_some());
    let _ = writeln!(
        h,
        "<h2>Across the {} tests</h2><table><tr><th class=\"l\">pose</th><th>n</th><th>AP mean</th>\
         <th>AP p95</th><th>AP max</th><th>RP n</th><th>RP mean</th><th>RP p95</th><th>RP max</th>{}</tr>",
        sum.tests,
        if compensated {
            "<th>compensated AP RMS (predicted, mean)</th><th>95 % bound (mean)</th><th>measured AP within the bound</th>"
        } else {
            ""
        }
    );
    for p in &sum.poses {
        let mut extra = String::new();
        if let (Some(r), Some(b)) = (&p.compensated_rms, &p.compensated_95) {
            extra = format!(
                "<td>{}</td><td>{}</td><td>{:.1} %</td>",
                num(r.mean),
                num(b.mean),
                100.0 * p.within_compensated_95.unwrap_or(0.0)
            );
        }
        let _ = writeln!(
            h,
            "<tr><td class=\"l\">{}</td>{}{}{extra}</tr>",
            name(p.pose),
            cells(Some(&p.ap)),
            cells(p.rp.as_ref())
        );
    }
    let _ = writeln!(
        h,
        "</table><table><tr><th class=\"l\">distances</th><th>n</th><th>mean</th><th>p95</th><th>max</th></tr>\
         <tr><td class=\"l\">|AD|</td>{}</tr><tr><td class=\"l\">RD</td>{}</tr></table>\
         <p class=\"key\">Lengths in {}. RP and RD over the poses and pairs measured in 2 cycles or more.</p>",
        cells(sum.ad.as_ref()),
        cells(sum.rd.as_ref()),
        esc(l)
    );
    let _ = writeln!(
        h,
        "<h2>Every test</h2><table><tr><th class=\"l\">test</th><th class=\"l\">pose</th><th>n</th>\
         <th>AP</th><th>AP<sub>x</sub>, AP<sub>y</sub>, AP<sub>z</sub></th><th>RP</th>{}</tr>",
        if compensated {
            "<th>compensated AP, predicted 95 % bound</th>"
        } else {
            ""
        }
    );
    for f in &e.poses {
        let _ = writeln!(
            h,
            "<tr><td class=\"l\">{}</td><td class=\"l\">{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td>{}</tr>",
            esc(f.test.as_deref().unwrap_or("")),
            pose_name(f.pose),
            f.cycles,
            num(f.ap),
            f.ap_xyz.map(|v| signed(v, 4)).join(", "),
            f.rp.map_or_else(|| "n/a".to_string(), num),
            f.compensated
                .as_ref()
                .map(|c| format!("<td>{}</td>", num(c.ap_95)))
                .unwrap_or_default()
        );
    }
    h += "</table>\n";
    h
}
