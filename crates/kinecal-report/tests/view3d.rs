//! The HTML report's 3-D view: drawn in a real browser (headless Chromium: the canvas has
//! many drawn pixels, so the script ran and drew the scene), its legend and scale stated, its
//! size bounded at 16,810 postures, and a scene that cannot be drawn said so rather than drawn;
//! and the page around it within its window's width.
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
use kinecal::{Chain, Dataset, Frame, Link, Robot, Target};
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

/// A screenshot of `page`'s 3-D view by Chromium into `png` (when there is a Chromium); `close`:
/// the cameras and boards alone, filling the view.
fn screenshot(page: &str, png: &std::path::Path, close: bool) {
    let Some(browser) = chromium() else { return };
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("view.html");
    // The view alone (its section holds its data and script).
    let view = format!(
        "<!DOCTYPE html><html><head><meta charset=\"utf-8\"></head><body><h2 {}</body></html>",
        section(page, "view3d")
    );
    let view = if close {
        view.replacen(
            "</script>\n<script>",
            "</script>\n<script>(function () { var e = document.getElementById('v3d-data'), \
             d = JSON.parse(e.textContent); d.points = []; d.frames = []; d.postures = \
             d.postures.slice(0, 1); d.postures[0].nominal = null; d.postures[0].calibrated = \
             {nodes: [], links: [], joints: [], tools: []}; e.textContent = JSON.stringify(d); \
             })();</script>\n<script>",
            1,
        )
    } else {
        view
    };
    std::fs::write(&file, view).unwrap();
    let out = Command::new(browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--no-first-run",
            "--hide-scrollbars",
            "--virtual-time-budget=3000",
            "--window-size=1000,700",
        ])
        .arg(format!(
            "--user-data-dir={}",
            dir.path().join("profile").display()
        ))
        .arg(format!("--screenshot={}", png.display()))
        .arg(format!("file://{}", file.display()))
        .output()
        .expect("chromium runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
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

/// The arm of [`arm`] with a camera on its flange (640 x 480, 600 px focal length) and a 9 x 6
/// board of 25 mm fixed 45 cm in front of it at the first posture, facing it, and the data
/// with the pixels of the board points the camera sees at the first 5 postures.
fn with_a_camera(truth: &Robot, data: &Dataset) -> (Robot, Dataset) {
    use kinecal::model::camera::{Board, Camera, Mount};
    use kinecal::observe::pixel::{Pixel, Seen};
    let mut robot = truth.clone();
    let hand_eye = Link {
        x: 0.03,
        y: -0.05,
        z: 0.04,
        alpha: 0.05,
        beta: -0.03,
        gamma: 0.02,
    };
    robot.cameras.push(Camera {
        name: "wrist".into(),
        mount: Mount::EndEffector,
        pose: hand_eye,
        fx: 600.0,
        fy: 610.0,
        cx: 320.0,
        cy: 240.0,
        distortion: [-0.2, 0.0, 0.0, 0.0, 0.0],
        width: 640,
        height: 480,
    });
    let kinematics = robot.clone();
    let chain = Chain::new(&kinematics);
    let camera_at = |readings: &[f64]| {
        chain
            .frame_at(readings, Target::EndEffector)
            .then(&Frame::from_link(&hand_eye))
    };
    // The board square to the camera, its centre on the optical axis, turned a little.
    let c0 = camera_at(&data.postures[0].readings);
    let board = c0.then(&Frame::from_link(&Link {
        x: -0.1,
        y: -0.0625,
        z: 0.45,
        alpha: 0.3,
        beta: 0.08,
        gamma: -0.05,
    }));
    robot.boards.push(Board {
        name: "board".into(),
        mount: Mount::Base,
        pose: kinecal::import::link_of(&board),
        cols: 9,
        rows: 6,
        spacing: 0.025,
    });
    robot.validate().unwrap();
    let mut observations = data.observations.clone();
    for posture in 0..5 {
        let c = camera_at(&data.postures[posture].readings);
        for k in 0..robot.boards[0].points() {
            let p = board.rotation * robot.boards[0].point(k) + board.translation;
            let q = c.rotation.transpose() * (p - c.translation);
            let uv = robot.cameras[0].project(&q).uv;
            if q.z > 0.0 && robot.cameras[0].inside(&uv) {
                let seen = Seen::Board { board: 0, index: k };
                let px = Pixel::new(&robot, posture, 0, seen, [uv.x, uv.y]).unwrap();
                observations.push(px.into());
            }
        }
    }
    (robot, Dataset::new(data.postures.clone(), observations))
}

/// A robot with a camera: its frustum and its board drawn (the view draws more with them than
/// with the layer turned off), the board points seen at the posture shown marked, the pixel
/// rows adding no measured point. `KINECAL_VIEW3D_SCREENSHOT=FILE.png` keeps a screenshot.
#[test]
fn a_camera_and_its_board_are_drawn() {
    let (nominal, truth, data) = arm(60);
    let (robot, pixels) = with_a_camera(&truth, &data);
    let mut rep = report(&nominal, &data);
    let scene = Scene::new(None, &robot, Some(&pixels), &SceneOptions::default()).unwrap();
    // The pixel rows are no measured points; the board's points seen at the first posture are
    // the whole board (it faces the camera there).
    assert_eq!(scene.points_total, 60);
    let p0 = &scene.postures[0];
    assert_eq!(p0.cameras.len(), 1);
    assert_eq!(p0.boards[0].seen.len(), 54);
    // The frustum's far corners at the depth, along the rays through the image's corners.
    let cam = &p0.cameras[0];
    let depth = scene.frustum_depth;
    for corner in &cam.corners {
        let d: Vec<f64> = (0..3).map(|k| corner[k] - cam.frame.origin[k]).collect();
        let along_z: f64 = (0..3).map(|k| d[k] * cam.frame.axes[2][k]).sum();
        assert!((along_z - depth).abs() < 1e-12, "{along_z} {depth}");
    }
    // The board's corner k = 53 is point 53 where the calibrated model puts it.
    let b = &robot.boards[0];
    let f = Frame::from_link(&b.pose);
    let last = f.rotation * b.point(53) + f.translation;
    assert!((0..3).all(|k| (p0.boards[0].point(53)[k] - last[k]).abs() < 1e-12));
    rep.scene = Some(scene);
    let page = html_report(&rep).unwrap();
    let v = section(&page, "view3d");
    for words in [
        "name=\"cameras\"",
        "camera (frustum",
        "the points seen at the posture shown",
        "camera wrist at (",
        "board board (9 x 6 points)",
        "54 of its points seen",
        "Pixel observations have no measured 3-D point",
    ] {
        assert!(v.contains(words), "{words}");
    }
    if let Some(png) = std::env::var_os("KINECAL_VIEW3D_SCREENSHOT") {
        let png = std::path::Path::new(&png);
        screenshot(&page, png, false);
        screenshot(&page, &png.with_extension("close.png"), true);
    }
    let Some(dom) = rendered_dom(&page) else {
        return;
    };
    let drawn = attribute(&dom, "data-drawn").expect("the view's script ran to its end");
    // The cameras' layer turned off before the view draws: fewer pixels.
    let off = page.replace("name=\"cameras\" checked", "name=\"cameras\"");
    let dom = rendered_dom(&off).unwrap();
    let without = attribute(&dom, "data-drawn").unwrap();
    eprintln!("drawn with the camera and board: {drawn} pixels, without: {without}");
    // A frustum of 8 cm and a board of 20 x 12.5 cm by a robot of a metre: hundreds of
    // pixels.
    assert!(drawn > without + 400, "{drawn} vs {without}");
}

/// The page fits its window's width: a job with a long estimate list (one token of several
/// hundred characters, as `--estimate` writes it) wraps in the facts under the verdict rather
/// than widening the page past a 1,200-pixel window (it did before: a horizontal scroll bar).
#[test]
fn a_long_job_wraps_within_the_window() {
    let (nominal, _, data) = arm(30);
    let mut rep = report(&nominal, &data);
    let estimate: Vec<String> = (1..=7)
        .flat_map(|l| ["x", "y", "z", "alpha", "beta", "gamma"].map(|p| format!("link{l}.{p}")))
        .collect();
    rep.spec = Some(serde_json::json!({
        "robot": "a_robot_file_with_a_long_name.toml",
        "selection": {"estimate": estimate.join(",")},
    }));
    let page = html_report(&rep).unwrap().replace(
        "</body>",
        "<script>document.body.setAttribute('data-overflow', String(Math.max(0, \
         document.documentElement.scrollWidth - document.documentElement.clientWidth)));\
         </script></body>",
    );
    let Some(dom) = rendered_dom(&page) else {
        return;
    };
    assert!(dom.contains("link7.gamma"), "the job is on the page");
    assert_eq!(
        attribute(&dom, "data-overflow"),
        Some(0),
        "pixels of the page beyond the window's width"
    );
}
