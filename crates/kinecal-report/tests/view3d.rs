//! The HTML report's 3-D view: drawn in a real browser (headless Chromium: the canvas has
//! many drawn pixels, so the script ran and drew the scene), its legend and scale stated, its
//! size bounded at 16,810 postures, and a scene that cannot be drawn said so rather than drawn.
//!
//! Chromium is `chromium` (or `chromium-browser`) on the PATH; without it the browser test is
//! skipped on a developer's machine and fails in CI (`CI=true`), where `.ci/run` installs it.

use std::path::PathBuf;
use std::process::Command;

use kinecal::apps::simulate;
use kinecal::model::robot::JointKind;
use kinecal::observe::Weights;
use kinecal::report::scene::{Scene, SceneOptions};
use kinecal::report::CalibrationReport;
use kinecal::workflow::{self, Request};
use kinecal::{Dataset, Robot};
use kinecal_report::html_report;

/// A 6-axis arm, its nominal model off by a millimetre and a milliradian, measured by
/// position at `postures` postures with 30 um of noise.
fn arm(postures: usize) -> (Robot, Robot, Dataset) {
    let truth = simulate::random_robot(&[JointKind::Revolute; 6], 21);
    let nominal = simulate::perturb(
        &truth,
        simulate::PerturbStd {
            length: 1e-3,
            angle: 1e-3,
            slope_fraction: 0.0,
        },
        4,
    );
    let mut data = simulate::measure(
        &truth,
        &simulate::sample_postures(&truth, postures, 9),
        true,
    );
    simulate::add_noise(&mut data, 30e-6, 0.0, 9);
    (nominal, truth, data)
}

/// The report of calibrating `nominal` on `data`, with its scene.
fn report(nominal: &Robot, data: &Dataset) -> CalibrationReport {
    let mut req = Request::new(nominal.clone(), data.clone());
    req.weights = Weights {
        length: 30e-6,
        angle: 1e-3,
    };
    let o = workflow::run(&req, &mut ()).unwrap();
    let mut rep = o.report;
    rep.scene = Some(
        Scene::new(
            Some(nominal),
            &o.calibration.calibrated,
            Some(data),
            &SceneOptions::default(),
        )
        .unwrap(),
    );
    rep
}

/// The part of the page under the heading with `id`, up to the next heading.
fn section<'a>(html: &'a str, id: &str) -> &'a str {
    let start = html
        .find(&format!("id=\"{id}\""))
        .unwrap_or_else(|| panic!("no section {id}"));
    let rest = &html[start..];
    let end = rest[1..].find("<h2").map_or(rest.len(), |e| e + 1);
    &rest[..end]
}

fn chromium() -> Option<PathBuf> {
    let path = std::env::var_os("PATH").unwrap_or_default();
    for dir in std::env::split_paths(&path).chain([PathBuf::from("/usr/bin")]) {
        for name in ["chromium", "chromium-browser"] {
            let p = dir.join(name);
            if p.is_file() {
                return Some(p);
            }
        }
    }
    None
}

/// The page as Chromium leaves it once its script ran: the DOM, serialized.
fn rendered_dom(page: &str) -> Option<String> {
    let Some(browser) = chromium() else {
        assert!(
            std::env::var("CI").map_or(true, |v| v != "true"),
            "Chromium is not installed: CI must run the 3-D view in a browser (.ci/run installs it)"
        );
        eprintln!("skipped: no chromium on this machine");
        return None;
    };
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("report.html");
    std::fs::write(&file, page).unwrap();
    let out = Command::new(browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--no-first-run",
            "--window-size=1200,1000",
        ])
        .arg(format!(
            "--user-data-dir={}",
            dir.path().join("profile").display()
        ))
        .arg("--dump-dom")
        .arg(format!("file://{}", file.display()))
        .output()
        .expect("chromium runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    Some(String::from_utf8_lossy(&out.stdout).into_owned())
}

fn attribute(dom: &str, name: &str) -> Option<u64> {
    let at = dom.find(&format!("{name}=\""))? + name.len() + 2;
    dom[at..].split('"').next()?.parse().ok()
}

#[test]
fn the_view_is_drawn_in_a_browser() {
    let (nominal, _, data) = arm(300);
    let page = html_report(&report(&nominal, &data)).unwrap();
    let Some(dom) = rendered_dom(&page) else {
        return;
    };
    let drawn = attribute(&dom, "data-drawn").expect("the view's script ran to its end");
    let pixels = attribute(&dom, "data-pixels").unwrap();
    // The robot, 300 points with their residuals, the frames and the floor: a few percent of
    // the canvas at least (a blank canvas, or one with only its captions, draws well under 1 %).
    assert!(pixels > 100_000, "{pixels}");
    assert!(
        drawn * 100 > 3 * pixels,
        "{drawn} of {pixels} pixels drawn: is the canvas blank?"
    );

    // Dragged, zoomed, another posture chosen, a layer turned on: each draws anew (a script
    // of the test's, after the view's, acts as the mouse and the controls would).
    let acted = page.replace(
        "</body>",
        "<script>(function () {\n\
         var c = document.getElementById('v3d-canvas'), seen = [c.toDataURL()];\n\
         function changed() { var u = c.toDataURL(); var n = seen.indexOf(u) < 0; seen.push(u); return n ? 1 : 0; }\n\
         c.dispatchEvent(new PointerEvent('pointerdown', {clientX: 100, clientY: 100, pointerId: 1}));\n\
         c.dispatchEvent(new PointerEvent('pointermove', {clientX: 180, clientY: 130, pointerId: 1}));\n\
         c.dispatchEvent(new PointerEvent('pointerup', {pointerId: 1}));\n\
         var n = changed();\n\
         c.dispatchEvent(new WheelEvent('wheel', {deltaY: -400, cancelable: true}));\n\
         n += changed();\n\
         var s = document.getElementById('v3d-posture'); s.value = '1';\n\
         s.dispatchEvent(new Event('change'));\n\
         n += changed();\n\
         var b = document.querySelector('#v3d input[name=before]'); b.checked = true;\n\
         b.dispatchEvent(new Event('change'));\n\
         n += changed();\n\
         c.setAttribute('data-changes', String(n));\n\
         })();</script></body>",
    );
    let dom = rendered_dom(&acted).unwrap();
    assert_eq!(
        attribute(&dom, "data-changes"),
        Some(4),
        "drag, wheel, posture, layer"
    );

    // The same page without points draws the robot and its frames: fewer pixels, not none.
    let mut rep = report(&nominal, &data);
    let scene = rep.scene.as_mut().unwrap();
    scene.points.clear();
    let page = html_report(&rep).unwrap();
    let dom = rendered_dom(&page).unwrap();
    let alone = attribute(&dom, "data-drawn").unwrap();
    assert!(alone > 1000 && alone < drawn, "{alone} vs {drawn}");
}

#[test]
fn the_view_states_its_scale_legend_and_what_it_shows() {
    let (nominal, _, data) = arm(300);
    let rep = report(&nominal, &data);
    let page = html_report(&rep).unwrap();
    let v = section(&page, "view3d");
    let scene = rep.scene.as_ref().unwrap();
    // Millimetres on the page of a metre robot: the scale in words, on the canvas too.
    let k = scene.residual_scale;
    assert!(
        v.contains(&format!("residual vectors drawn {k} times their length")),
        "{k}"
    );
    assert!(v.contains("all 300 measured points"));
    for words in [
        "calibrated robot",
        "nominal robot",
        "residual after calibration",
        "residual before",
        "Drag to turn, wheel to zoom",
        "The scene in words",
        "role=\"img\"",
        "aria-label=",
        "<noscript>",
    ] {
        assert!(v.contains(words), "{words}");
    }
    // The postures to choose from: the first measured, and the one of the largest residual.
    assert!(v.contains("<select id=\"v3d-posture\">"));
    assert!(v.contains("(first measured)"));
    assert!(v.contains("(largest residual)"));
    // Nothing outside the page.
    for bad in ["http:", "https:", "src="] {
        assert!(!v.contains(bad), "{bad}");
    }
    // The data is JSON (so every number in it finite), in metres shown as millimetres.
    let at = v.find("id=\"v3d-data\">").unwrap() + "id=\"v3d-data\">".len();
    let json = &v[at..at + v[at..].find("</script>").unwrap()];
    let data: serde_json::Value = serde_json::from_str(json).unwrap();
    assert_eq!(data["unit"], "mm");
    assert_eq!(data["points"].as_array().unwrap().len(), 300);
    let p = &scene.points[7];
    let shown = data["points"][7]["measured"][0].as_f64().unwrap();
    assert!((shown - p.measured[0] * 1e3).abs() < 1e-4 * (1.0 + shown.abs()));
}

#[test]
fn sixteen_thousand_postures_keep_the_page_small() {
    let (nominal, truth, small) = arm(40);
    let mut rep = report(&nominal, &small);
    let (_, _, big) = arm(16_810);
    rep.scene =
        Some(Scene::new(Some(&nominal), &truth, Some(&big), &SceneOptions::default()).unwrap());
    let page = html_report(&rep).unwrap();
    let v = section(&page, "view3d");
    assert!(
        v.contains("2,000 of 16,810 measured points"),
        "{}",
        &v[..2000.min(v.len())]
    );
    eprintln!("the 3-D view of 16,810 postures: {} bytes", v.len());
    assert!(v.len() < 600_000, "the 3-D view takes {} bytes", v.len());
}

#[test]
fn a_scene_that_cannot_be_drawn_is_said_so() {
    let (nominal, _, data) = arm(30);
    let mut rep = report(&nominal, &data);
    // A report edited by hand: a point a long way off, and a link to no joint.
    let scene = rep.scene.as_mut().unwrap();
    scene.points[0].measured[0] = 1e308;
    let page = html_report(&rep).unwrap();
    let v = section(&page, "view3d");
    assert!(v.contains("No 3-D view"), "{v}");
    assert!(!v.contains("<canvas") && !v.contains("<script"));
    let scene = rep.scene.as_mut().unwrap();
    scene.points[0].measured[0] = 0.5;
    scene.postures[0].calibrated.links.push([0, 999]);
    let v = html_report(&rep).unwrap();
    assert!(section(&v, "view3d").contains("No 3-D view"));
    // A report without a scene says where one comes from.
    rep.scene = None;
    let v = html_report(&rep).unwrap();
    assert!(section(&v, "view3d").contains("the report holds no scene"));
}
