//! Cameras on the command line (issue 40): simulated views, a calibration from them, the check
//! against a pixel threshold, the ROS camera_info export read back, and bad input refused with
//! the flag, the file or the field named and a non-zero exit.

use std::path::Path;

mod common;

use common::{argv, run, run_err, run_ok};

fn examples() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/cameras")
}

fn setup() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    for f in [
        "eye_in_hand.toml",
        "eye_in_hand_truth.toml",
        "eye_to_hand_truth.toml",
    ] {
        std::fs::copy(examples().join(f), dir.path().join(f)).unwrap();
    }
    dir
}

#[test]
fn views_calibrate_check_and_export_camera_info() {
    let dir = setup();
    let d = dir.path();
    let out = run_ok(
        d,
        &argv(
            "simulate --robot eye_in_hand_truth.toml --camera wrist --board board --postures 12
             --seed 2 --noise pixel=0.3 --min-points 20 --out views.csv",
        ),
    );
    assert!(out.is_empty(), "{out}");
    let views = std::fs::read_to_string(d.join("views.csv")).unwrap();
    assert!(views.starts_with("posture,camera,point,v1,v2,v3,v4,v5,v6,u,v\n"));
    // Every view sees at least 20 points.
    let mut per: std::collections::BTreeMap<&str, usize> = Default::default();
    for line in views.lines().skip(1) {
        *per.entry(line.split(',').next().unwrap()).or_default() += 1;
    }
    assert_eq!(per.len(), 12);
    assert!(per.values().all(|&n| n >= 20), "{per:?}");
    let out = run_ok(
        d,
        &argv(
            "calibrate --robot eye_in_hand.toml --pixels views.csv --estimate extrinsics,boards
             --out cal.toml --html cal.html -q",
        ),
    );
    assert!(
        out.contains("mean pixel error: 0.") && out.contains(" px (from"),
        "{out}"
    );
    assert!(out.contains("RMS pixel error (px)"), "{out}");
    // The page's charts show pixels in pixels (they were drawn as lengths: 0.4 px as "400 mm").
    let page = std::fs::read_to_string(d.join("cal.html")).unwrap();
    assert!(
        page.contains("pixel error (px, log scale)"),
        "no pixel axis"
    );
    assert!(
        page.contains("pixel error (px; bins of"),
        "no pixel histogram axis"
    );
    assert!(
        !page.contains("pixel error (mm"),
        "pixels drawn as millimetres"
    );
    // The check: pixels against a pixel threshold, and only that.
    let err = run_err(
        d,
        &argv("check --robot cal.toml --pixels views.csv --threshold 0.001"),
    );
    assert!(err.contains("--pixel-threshold"), "{err}");
    let out = run_ok(
        d,
        &argv("check --robot cal.toml --pixels views.csv --threshold 0.001 --pixel-threshold 2"),
    );
    assert!(
        out.contains("check pixels: max error") && out.contains("px (threshold 2)"),
        "{out}"
    );
    let (code, _, _) = run(
        d,
        &argv("check --robot cal.toml --pixels views.csv --threshold 1 --pixel-threshold 0.1"),
    );
    assert_eq!(code, 3);
    // Pixels alone need no length threshold (it used to be required, and meant nothing); the
    // document then has none. Positions still need one.
    let out = run_ok(
        d,
        &argv("check --robot cal.toml --pixels views.csv --pixel-threshold 2 --json"),
    );
    let doc: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(doc["ok"], true, "{out}");
    assert!(doc.get("threshold_length").is_none(), "{out}");
    assert_eq!(doc["threshold_pixel"], 2.0);
    run_ok(
        d,
        &argv("simulate --robot eye_in_hand_truth.toml --postures 5 --out points.csv"),
    );
    let err = run_err(
        d,
        &argv("check --robot cal.toml --data points.csv --pixel-threshold 2"),
    );
    assert!(
        err.contains("--threshold") && err.contains("a length threshold is needed"),
        "{err}"
    );
    // The camera_info YAML, read back to the calibrated lens.
    run_ok(
        d,
        &argv("export camera-info --robot cal.toml --out wrist.yaml"),
    );
    let text = std::fs::read_to_string(d.join("wrist.yaml")).unwrap();
    let info = kinecal::import::camera_info::parse_camera_info(&text, "wrist.yaml").unwrap();
    let cal = kinecal::model::robot_file::parse_robot_toml(
        &std::fs::read_to_string(d.join("cal.toml")).unwrap(),
        "cal.toml",
    )
    .unwrap();
    assert_eq!(
        info,
        kinecal::import::camera_info::CameraInfo::of(&cal.cameras[0])
    );
}

#[test]
fn bad_camera_input_is_refused_with_its_flag() {
    let dir = setup();
    let d = dir.path();
    for (args, expected) in [
        (
            "simulate --robot eye_in_hand_truth.toml --camera left --board board --postures 3
             --out v.csv",
            "--camera: unknown camera `left` (the robot file's [[cameras]]: wrist)",
        ),
        (
            "simulate --robot eye_in_hand_truth.toml --camera wrist --board floor --postures 3
             --out v.csv",
            "--board: unknown board `floor`",
        ),
        (
            "simulate --robot eye_in_hand_truth.toml --camera wrist --board board --postures 3
             --min-points 55 --out v.csv",
            "--min-points: expected between 1 and 54",
        ),
        (
            "simulate --robot eye_in_hand_truth.toml --camera wrist --board board --postures 3
             --noise pixels=1 --out v.csv",
            "--noise: `pixels=1`: unknown key `pixels` (expected length, angle, pixel)",
        ),
        (
            // The camera 100 m to the side: no posture shows it the board.
            "simulate --robot eye_to_hand_truth.toml --camera fixed --board board --postures 2
             --perturb fixed.y=+100 --out v.csv",
            "--postures: only 0 of 2000 postures drawn within the joint ranges see at least 12 \
             points of board `board` from camera `fixed` (2 asked for): narrow the joint ranges",
        ),
        (
            "export camera-info --robot eye_in_hand.toml --camera left --out c.yaml",
            "--camera: unknown camera `left`",
        ),
        (
            "export camera-info --robot ge-a4 --out c.yaml",
            "the robot file has no [[cameras]]",
        ),
    ] {
        let err = run_err(d, &argv(args));
        assert!(err.contains(expected), "{args}: {err}");
        assert!(
            !d.join("v.csv").exists() && !d.join("c.yaml").exists(),
            "{args}"
        );
    }
    // --camera without --board, and the reverse.
    let (code, _, err) = run(
        d,
        &argv("simulate --robot eye_in_hand_truth.toml --camera wrist --postures 3 --out v.csv"),
    );
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("--board"), "{err}");
    // A camera_info file ROS cannot have written: its line and field.
    std::fs::write(
        d.join("bad.yaml"),
        "image_width: 640\nimage_height: 480\ncamera_matrix:\n  rows: 3\n  cols: 3\n  \
         data: [600, 0, 320, 0, x, 240, 0, 0, 1]\n",
    )
    .unwrap();
    let e = kinecal::import::camera_info::parse_camera_info(
        &std::fs::read_to_string(d.join("bad.yaml")).unwrap(),
        "bad.yaml",
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.starts_with("bad.yaml:6: field `camera_matrix.data`: `x` is not a finite number"),
        "{e}"
    );
}
