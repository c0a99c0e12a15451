//! The calibration report's 3-D view: the report's scene ([`kinecal::report::scene`]) drawn on
//! a canvas by a small renderer of this crate (`view3d.js`, in the page: nothing is fetched),
//! with its controls, its legend, the scale of the residual vectors, and the scene in words for
//! a reader without the picture.

use std::fmt::Write as _;

use kinecal::report::gltf::{board_lines, frustum_lines};
use kinecal::report::scene::{Scene, ScenePoint, ScenePosture, Skeleton};

use crate::display::DisplayUnits;
use crate::number::{num, sig};
use crate::page::esc;

/// The renderer.
const SCRIPT: &str = include_str!("view3d.js");

/// `x` (finite) as a short JSON number, to `f32` precision.
fn n(x: f64) -> String {
    let v = x as f32;
    if v == 0.0 || !v.is_finite() {
        "0".into()
    } else if (1e-3..1e7).contains(&v.abs()) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

fn v3(p: &[f64; 3], f: f64) -> String {
    format!("[{},{},{}]", n(p[0] * f), n(p[1] * f), n(p[2] * f))
}

fn axes(a: &[[f64; 3]; 3]) -> String {
    format!("[{},{},{}]", v3(&a[0], 1.0), v3(&a[1], 1.0), v3(&a[2], 1.0))
}

fn text(s: &str) -> String {
    serde_json::to_string(s).unwrap_or_else(|_| "\"\"".into())
}

fn skeleton(s: &Skeleton, f: f64) -> String {
    let nodes: Vec<String> = s.nodes.iter().map(|p| v3(p, f)).collect();
    let links: Vec<String> = s.links.iter().map(|[a, b]| format!("[{a},{b}]")).collect();
    let joints: Vec<String> = s
        .joints
        .iter()
        .map(|(i, a)| format!("[{i},{}]", v3(a, 1.0)))
        .collect();
    let tools: Vec<String> = s
        .tools
        .iter()
        .map(|t| {
            format!(
                "{{\"name\":{},\"origin\":{},\"axes\":{}}}",
                text(&t.name),
                v3(&t.origin, f),
                axes(&t.axes)
            )
        })
        .collect();
    format!(
        "{{\"nodes\":[{}],\"links\":[{}],\"joints\":[{}],\"tools\":[{}]}}",
        nodes.join(","),
        links.join(","),
        joints.join(","),
        tools.join(",")
    )
}

/// Line segments as JSON, `[[a, b], ...]`.
fn segments(lines: &[[[f64; 3]; 2]], f: f64) -> String {
    let l: Vec<String> = lines
        .iter()
        .map(|[a, b]| format!("[{},{}]", v3(a, f), v3(b, f)))
        .collect();
    format!("[{}]", l.join(","))
}

/// A posture's cameras and boards as JSON: each its name, frame and lines (a camera's frustum,
/// a board's grid), a board also the points seen there.
fn mounted(p: &ScenePosture, f: f64) -> String {
    let frame = |fr: &kinecal::report::scene::SceneFrame| {
        format!(
            "\"name\":{},\"origin\":{},\"axes\":{}",
            text(&fr.name),
            v3(&fr.origin, f),
            axes(&fr.axes)
        )
    };
    let cameras: Vec<String> = p
        .cameras
        .iter()
        .map(|c| {
            format!(
                "{{{},\"lines\":{}}}",
                frame(&c.frame),
                segments(&frustum_lines(c), f)
            )
        })
        .collect();
    let boards: Vec<String> = p
        .boards
        .iter()
        .map(|b| {
            let seen: Vec<String> = b.seen.iter().map(|&k| v3(&b.point(k), f)).collect();
            format!(
                "{{{},\"lines\":{},\"seen\":[{}]}}",
                frame(&b.frame),
                segments(&board_lines(b), f),
                seen.join(",")
            )
        })
        .collect();
    format!(
        "\"cameras\":[{}],\"boards\":[{}]",
        cameras.join(","),
        boards.join(",")
    )
}

/// A round length near `x`: 1, 2 or 5 times a power of ten, not above it.
fn round_down(x: f64) -> f64 {
    if !(x.is_finite() && x > 0.0) {
        return 1.0;
    }
    let p = 10f64.powf(x.log10().floor());
    let m = x / p;
    p * if m >= 5.0 {
        5.0
    } else if m >= 2.0 {
        2.0
    } else {
        1.0
    }
}

/// A round figure without trailing zeros: `500`, `0.25`, `2e-5`.
fn round(x: f64) -> String {
    let s = sig(x, 3);
    let (mantissa, exponent) = match s.split_once('e') {
        Some((m, e)) => (m, Some(e)),
        None => (s.as_str(), None),
    };
    let mantissa = if mantissa.contains('.') {
        mantissa.trim_end_matches('0').trim_end_matches('.')
    } else {
        mantissa
    };
    match exponent {
        Some(e) => format!("{mantissa}e{e}"),
        None => mantissa.to_string(),
    }
}

/// Thousands separated by commas.
fn count(k: usize) -> String {
    let s = k.to_string();
    let mut out = String::new();
    for (i, c) in s.chars().enumerate() {
        if i > 0 && (s.len() - i) % 3 == 0 {
            out.push(',');
        }
        out.push(c);
    }
    out
}

/// What the points shown are, of how many.
fn points_caption(scene: &Scene) -> String {
    let shown = scene.points.len();
    let mut s = if shown == scene.points_total {
        format!("all {} measured points", count(shown))
    } else {
        format!(
            "{} of {} measured points (the largest residuals and an even spread of the rest)",
            count(shown),
            count(scene.points_total)
        )
    };
    if scene.points_unplottable > 0 {
        let _ = write!(
            s,
            "; {} not drawn (not finite or beyond 1e6 m)",
            count(scene.points_unplottable)
        );
    }
    s
}

/// What every part of the section draws from: the scene, the page's length unit and the round
/// length the axes, the floor grid and the residual scales are stated in.
struct View<'a> {
    scene: &'a Scene,
    /// Display units per metre: a scene coordinate (m) times this is in `unit`.
    f: f64,
    /// The page's length unit (`mm`, `in`, ...).
    unit: &'static str,
    /// The length of the frame axes and the floor grid's squares, in `unit`: a round fifth of
    /// the robot's reach.
    axis: f64,
    /// Whether the scene draws a nominal robot beside the calibrated one.
    has_nominal: bool,
    /// Whether the points carry residuals before calibration (the nominal robot's).
    has_before: bool,
    /// Whether any posture has a camera or a board.
    has_cameras: bool,
}

impl<'a> View<'a> {
    /// The view of `scene` with lengths shown in `units`.
    fn new(scene: &'a Scene, units: DisplayUnits) -> Self {
        let f = 1.0 / units.length.metres();
        View {
            scene,
            f,
            unit: units.length.as_str(),
            axis: round_down(scene.reach * f / 5.0),
            has_nominal: scene.postures.iter().any(|p| p.nominal.is_some()),
            has_before: scene.points.iter().any(|p| p.before.is_some()),
            has_cameras: scene
                .postures
                .iter()
                .any(|p| !p.cameras.is_empty() || !p.boards.is_empty()),
        }
    }
}

/// The section of the page: the view, or why there is none. The view is, in order: the
/// controls, the canvas, the legend and scales, the scene in words, then the scene's data and
/// the renderer.
pub(crate) fn section(scene: Option<&Scene>, units: DisplayUnits) -> String {
    let mut h = String::from("<h2 id=\"view3d\">3-D view</h2>\n");
    let Some(scene) = scene else {
        h += "<p class=\"note\">No 3-D view: the report holds no scene (it is drawn when the \
              HTML report is asked for with the calibration, or by <code>kinecal report \
              --robot ... --data ...</code>).</p>\n";
        return h;
    };
    if let Err(e) = scene.check() {
        let _ = writeln!(
            h,
            "<p class=\"note\">No 3-D view: {}.</p>",
            esc(&e.to_string())
        );
        return h;
    }
    let v = View::new(scene, units);
    let scale_words = residual_scale_sentence(&v);
    h += "<div id=\"v3d\">";
    h += &controls(&v);
    h += &canvas(&v, &scale_words);
    h += &legend_and_scale(&v, &scale_words);
    h += &scene_in_words(&v);
    h += &data_and_renderer(&v);
    h
}

/// The residual vectors' magnification in words, for the page and the canvas's description:
/// "residual vectors drawn 500 times their length (100 mm on the view is 0.2 mm of error)",
/// with the before-calibration scale when the scene has those residuals.
fn residual_scale_sentence(v: &View<'_>) -> String {
    let l = v.unit;
    let axis = v.axis;
    let k = v.scene.residual_scale;
    let kb = v.scene.residual_scale_before;
    let mut scale_words = format!(
        "residual vectors drawn {} times their length ({} {l} on the view is {} {l} of error)",
        round(k),
        round(axis),
        round(axis / k)
    );
    if v.has_before {
        let _ = write!(
            scale_words,
            ", those before calibration {} times ({} {l} is {} {l})",
            round(kb),
            round(axis),
            round(axis / kb)
        );
    }
    scale_words
}

/// The controls above the view: the posture picker (when there are several postures) and a
/// checkbox per layer the scene has, as a `<p class="controls">` line.
fn controls(v: &View<'_>) -> String {
    let mut h = String::from("<p class=\"controls\">");
    if v.scene.postures.len() > 1 {
        h += &posture_picker(v.scene);
    }
    let scene = v.scene;
    let mut toggle = |name: &str, words: &str, on: bool, present: bool| {
        if present {
            let _ = write!(
                h,
                "<label><input type=\"checkbox\" name=\"{name}\"{}> {words}</label> ",
                if on { " checked" } else { "" }
            );
        }
    };
    toggle("nominal", "nominal robot", true, v.has_nominal);
    toggle("points", "measured points", true, !scene.points.is_empty());
    toggle("after", "residuals after", true, !scene.points.is_empty());
    toggle("before", "residuals before", false, v.has_before);
    toggle("cameras", "cameras and boards", true, v.has_cameras);
    toggle("frames", "frames", true, true);
    toggle("grid", "floor grid", true, true);
    h += "</p>\n";
    h
}

/// The posture drop-down: one option per drawn posture, the one with the largest residual and
/// the first measured one marked.
fn posture_picker(scene: &Scene) -> String {
    let mut h = String::from("<label>posture <select id=\"v3d-posture\">");
    let worst = scene
        .points
        .iter()
        .max_by(|a, b| a.error_after().total_cmp(&b.error_after()))
        .map(|p| p.posture);
    for (i, p) in scene.postures.iter().enumerate() {
        let note = if Some(p.index) == worst {
            " (largest residual)"
        } else if i == 0 && p.index == 0 {
            " (first measured)"
        } else {
            ""
        };
        let _ = write!(h, "<option value=\"{i}\">{}{note}</option>", esc(&p.label));
    }
    h += "</select></label> ";
    h
}

/// The canvas the renderer draws on, its label and fallback content describing the view for a
/// reader who cannot see it.
fn canvas(v: &View<'_>, scale_words: &str) -> String {
    let scene = v.scene;
    let has_nominal = v.has_nominal;
    let described = format!(
        "The {} robot{} at posture {}{}, {}, {}.",
        if has_nominal {
            "nominal (grey, dashed) and the calibrated (blue)"
        } else {
            "calibrated (blue)"
        },
        if has_nominal { "s" } else { "" },
        scene.postures[0].label,
        if v.has_cameras {
            " with its cameras (purple frustums) and boards (grey grids)"
        } else {
            ""
        },
        points_caption(scene),
        scale_words
    );
    format!(
        "<canvas id=\"v3d-canvas\" width=\"900\" height=\"540\" tabindex=\"0\" role=\"img\" \
         aria-label=\"{}\" style=\"width:100%;max-width:1000px;border:1px solid #ccc;\
         touch-action:none;cursor:grab\">{}</canvas>\n",
        esc(&described),
        esc(&described)
    )
}

/// A legend entry: a short line in `color`, solid or dashed, then `words`.
fn swatch(color: &str, dashed: bool, words: &str) -> String {
    format!(
        "<span style=\"display:inline-block;width:22px;border-top:3px {} {color};\
         vertical-align:middle\"></span> {words}",
        if dashed { "dashed" } else { "solid" }
    )
}

/// The legend (a colour swatch per layer the scene has) and the paragraph under it: the
/// scales, what the points shown are, and how to turn and zoom the view.
fn legend_and_scale(v: &View<'_>, scale_words: &str) -> String {
    let scene = v.scene;
    let mut legend = vec![swatch(
        "#1f63c7",
        false,
        "calibrated robot (joints: dots and axes)",
    )];
    if v.has_nominal {
        legend.push(swatch("#8c8c8c", true, "nominal robot"));
    }
    if !scene.points.is_empty() {
        legend.push(
            "<span style=\"color:#222\">&#9679;</span> measured point \
             (<span style=\"color:#e08a00\">&#9675;</span> those of the posture shown)"
                .into(),
        );
        legend.push(swatch("#d62728", false, "residual after calibration"));
        if v.has_before {
            legend.push(swatch("#ff7f0e", false, "residual before"));
        }
    }
    if v.has_cameras {
        legend.push(swatch(
            "#9433b3",
            false,
            "camera (frustum to the image's corners; the tick marks the image's top)",
        ));
        legend.push(
            "<span style=\"display:inline-block;width:22px;border-top:3px solid #4d4d4d;\
             vertical-align:middle\"></span> board (<span style=\"color:#00998a\">&#9679;\
             </span> the points seen at the posture shown)"
                .into(),
        );
    }
    legend.push(format!(
        "frames: {}, {}, {}",
        swatch("#d62728", false, "x"),
        swatch("#2ca02c", false, "y"),
        swatch("#1f4fe0", false, "z")
    ));
    let l = v.unit;
    format!(
        "<p class=\"legend\">{}</p>\n<p>Scale: {scale_words}; axes and floor grid squares \
         {} {l}. Shown: {}. Drag to turn, wheel to zoom (arrow keys and +/- when the view has \
         the focus), double-click to reset.</p>\n",
        legend.join(" &nbsp; "),
        round(v.axis),
        esc(&points_caption(scene)),
    )
}

/// The scene in words, a `<details>` block for a reader without the picture: where the tool is
/// at the first posture, the largest residuals, the fixed frames and the cameras and boards;
/// then the `<noscript>` note.
fn scene_in_words(v: &View<'_>) -> String {
    let mut h = String::from("<details><summary>The scene in words</summary>\n");
    h += &tool_positions(v);
    h += &largest_residuals_table(v);
    h += &frames_in_words(v);
    if v.has_cameras {
        h += &cameras_and_boards_in_words(v);
    }
    h += "</details>\n<noscript><p class=\"note\">The 3-D view is drawn by the page's \
          script, which this browser does not run: the scene in words above holds its \
          figures.</p></noscript>\n";
    h
}

/// A skeleton's first tool's origin, `(x, y, z)` in display units (empty without a tool).
fn tool_tip(s: &Skeleton, f: f64) -> String {
    s.tools
        .first()
        .map(|t| {
            format!(
                "({}, {}, {})",
                num(t.origin[0] * f),
                num(t.origin[1] * f),
                num(t.origin[2] * f)
            )
        })
        .unwrap_or_default()
}

/// Where the calibrated (and the nominal) robot's tool is at the first posture, as a paragraph.
fn tool_positions(v: &View<'_>) -> String {
    let (f, l) = (v.f, v.unit);
    let p0 = &v.scene.postures[0];
    let mut h = String::new();
    let _ = write!(
        h,
        "<p>At posture {}, the calibrated robot's tool is at {} {l}",
        esc(&p0.label),
        tool_tip(&p0.calibrated, f)
    );
    if let Some(nom) = &p0.nominal {
        let _ = write!(h, ", the nominal robot's at {} {l}", tool_tip(nom, f));
    }
    h += ".</p>\n";
    h
}

/// The table of the ten largest residuals after calibration: posture, target, measured point
/// and error; empty when the scene has no points.
fn largest_residuals_table(v: &View<'_>) -> String {
    let (f, l, scene) = (v.f, v.unit, v.scene);
    let mut worst: Vec<&ScenePoint> = scene.points.iter().collect();
    worst.sort_by(|a, b| b.error_after().total_cmp(&a.error_after()));
    worst.truncate(10);
    let mut h = String::new();
    if worst.is_empty() {
        return h;
    }
    let _ = writeln!(
        h,
        "<table><tr><th class=\"l\">largest residuals: posture</th><th class=\"l\">target</th>\
         <th>x</th><th>y</th><th>z</th><th>error after ({l})</th></tr>"
    );
    let labels: std::collections::HashMap<usize, &str> = scene
        .postures
        .iter()
        .map(|p| (p.index, p.label.as_str()))
        .collect();
    for p in worst {
        let posture = labels
            .get(&p.posture)
            .map(|s| s.to_string())
            .unwrap_or_else(|| format!("#{}", p.posture + 1));
        let _ = writeln!(
            h,
            "<tr><td class=\"l\">{}</td><td class=\"l\">{}</td><td>{}</td><td>{}</td>\
             <td>{}</td><td>{}</td></tr>",
            esc(&posture),
            esc(&p.target),
            num(p.measured[0] * f),
            num(p.measured[1] * f),
            num(p.measured[2] * f),
            num(p.error_after() * f)
        );
    }
    h += "</table>\n";
    h
}

/// The fixed frames (global, measurement frames) with their kinds and origins, as a paragraph.
fn frames_in_words(v: &View<'_>) -> String {
    let (f, l) = (v.f, v.unit);
    let frames: Vec<String> = v
        .scene
        .frames
        .iter()
        .map(|fr| {
            format!(
                "{} ({}) at ({}, {}, {}) {l}",
                esc(&fr.name),
                fr.kind.as_str(),
                num(fr.origin[0] * f),
                num(fr.origin[1] * f),
                num(fr.origin[2] * f)
            )
        })
        .collect();
    format!("<p>Frames: {}.</p>", frames.join("; "))
}

/// The first posture's cameras (where each is and looks) and boards (where, its size, the
/// points seen), as a paragraph that also says why pixel observations draw no residual.
fn cameras_and_boards_in_words(v: &View<'_>) -> String {
    let (f, l) = (v.f, v.unit);
    let p0 = &v.scene.postures[0];
    let mut words: Vec<String> = p0
        .cameras
        .iter()
        .map(|c| {
            format!(
                "camera {} at ({}, {}, {}) {l}, looking along ({}, {}, {})",
                esc(&c.frame.name),
                num(c.frame.origin[0] * f),
                num(c.frame.origin[1] * f),
                num(c.frame.origin[2] * f),
                num(c.frame.axes[2][0]),
                num(c.frame.axes[2][1]),
                num(c.frame.axes[2][2])
            )
        })
        .collect();
    words.extend(p0.boards.iter().map(|b| {
        format!(
            "board {} ({} x {} points) at ({}, {}, {}) {l}, {} of its points seen",
            esc(&b.frame.name),
            b.cols,
            b.rows,
            num(b.frame.origin[0] * f),
            num(b.frame.origin[1] * f),
            num(b.frame.origin[2] * f),
            b.seen.len()
        )
    }));
    format!(
        "\n<p>At posture {}: {}. Pixel observations have no measured 3-D point: they add \
         no point nor residual vector (their error, in pixels, is in the summary); the board \
         points seen stand for them.</p>",
        esc(&p0.label),
        words.join("; ")
    )
}

/// The scene as the renderer's JSON data block, then the renderer itself, closing the view's
/// `<div>`.
fn data_and_renderer(v: &View<'_>) -> String {
    // Nothing in the data can close its element.
    let json = scene_json(v).replace('<', "\\u003c");
    format!(
        "<script type=\"application/json\" id=\"v3d-data\">{json}</script>\n<script>\n{SCRIPT}</script>\n</div>\n"
    )
}

/// The scene as the JSON `view3d.js` reads: title, caption, unit, scales, and the postures
/// (both robots, cameras, boards), points and frames, every length in display units.
fn scene_json(v: &View<'_>) -> String {
    let (f, scene) = (v.f, v.scene);
    let postures: Vec<String> = scene.postures.iter().map(|p| posture_json(p, f)).collect();
    let points: Vec<String> = scene
        .points
        .iter()
        .map(|p| {
            format!(
                "{{\"posture\":{},\"measured\":{},\"after\":{},\"before\":{}}}",
                p.posture,
                v3(&p.measured, f),
                v3(&p.after, f),
                p.before.as_ref().map_or("null".into(), |b| v3(b, f))
            )
        })
        .collect();
    let frames: Vec<String> = scene
        .frames
        .iter()
        .map(|fr| {
            format!(
                "{{\"name\":{},\"kind\":{},\"origin\":{},\"axes\":{}}}",
                text(&fr.name),
                text(fr.kind.as_str()),
                v3(&fr.origin, f),
                axes(&fr.axes)
            )
        })
        .collect();
    format!(
        "{{\"title\":{},\"caption\":{},\"unit\":{},\"reach\":{},\"axis\":{},\"scale\":{},\
         \"scale_before\":{},\"postures\":[{}],\"points\":[{}],\"frames\":[{}]}}",
        text(&scene.robot),
        text(&canvas_caption(v)),
        text(v.unit),
        n(scene.reach * f),
        n(v.axis),
        n(scene.residual_scale),
        n(scene.residual_scale_before),
        postures.join(","),
        points.join(","),
        frames.join(",")
    )
}

/// A posture as JSON: its label and index, the calibrated and nominal (or `null`) robots, its
/// cameras and boards.
fn posture_json(p: &ScenePosture, f: f64) -> String {
    format!(
        "{{\"label\":{},\"index\":{},\"calibrated\":{},\"nominal\":{},{}}}",
        text(&p.label),
        p.index,
        skeleton(&p.calibrated, f),
        p.nominal.as_ref().map_or("null".into(), |s| skeleton(s, f)),
        mounted(p, f)
    )
}

/// The short scale line the renderer writes on the canvas: "residuals x500: 100 mm shown =
/// 0.2 mm of error (before: x5); grid 100 mm".
fn canvas_caption(v: &View<'_>) -> String {
    let l = v.unit;
    let axis = v.axis;
    let k = v.scene.residual_scale;
    let kb = v.scene.residual_scale_before;
    format!(
        "residuals x{}: {} {l} shown = {} {l} of error{}; grid {} {l}",
        round(k),
        round(axis),
        round(axis / k),
        if v.has_before {
            format!(" (before: x{})", round(kb))
        } else {
            String::new()
        },
        round(axis)
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    #[allow(clippy::float_cmp)] // round numbers, exactly
    fn numbers_are_short_and_finite() {
        assert_eq!(n(0.1), "0.1");
        assert_eq!(n(1e-5), "1e-5");
        assert_eq!(n(f64::NAN), "0");
        assert_eq!(n(1e308), "0");
        assert_eq!(n(-2.5e7), "-2.5e7");
        assert_eq!(count(16810), "16,810");
        assert_eq!(count(999), "999");
        assert_eq!(round_down(130.0), 100.0);
        assert_eq!(round_down(0.3), 0.2);
        assert_eq!(round(500.0), "500");
        assert_eq!(round(0.25), "0.25");
        assert_eq!(round(2e-5), "2e-5");
    }
}
