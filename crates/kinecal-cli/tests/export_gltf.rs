//! `kinecal export gltf`: the scene of a calibration as GLB, from the report `calibrate --html`
//! wrote (the scene its page draws, the same numbers) or from the robot and the data; the GLB's
//! container and JSON checked here (the library's tests read it back with a glTF reader);
//! refusals that write nothing.

mod common;

use std::path::Path;

use common::{argv, read_json, run_err, run_ok};

fn u32_at(b: &[u8], at: usize) -> usize {
    u32::from_le_bytes(b[at..at + 4].try_into().unwrap()) as usize
}

/// The JSON chunk of a GLB, its header and chunks checked.
fn glb_json(path: &Path) -> serde_json::Value {
    let b = std::fs::read(path).unwrap();
    assert_eq!(&b[..4], b"glTF");
    assert_eq!(u32_at(&b, 4), 2);
    assert_eq!(u32_at(&b, 8), b.len());
    let n = u32_at(&b, 12);
    assert_eq!(&b[16..20], b"JSON");
    assert_eq!(&b[20 + n + 4..20 + n + 8], b"BIN\0");
    assert_eq!(20 + n + 8 + u32_at(&b, 20 + n), b.len());
    serde_json::from_slice(&b[20..20 + n]).unwrap()
}

/// The vertex count of the node named `name`, if the GLB has it.
fn count(v: &serde_json::Value, name: &str) -> Option<u64> {
    let node = v["nodes"].as_array()?.iter().find(|n| n["name"] == name)?;
    let mesh = &v["meshes"][node["mesh"].as_u64()? as usize];
    let acc = mesh["primitives"][0]["attributes"]["POSITION"].as_u64()? as usize;
    v["accessors"][acc]["count"].as_u64()
}

#[test]
fn the_report_s_scene_and_the_data_s() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    run_ok(
        d,
        &argv("simulate --robot ge-a4 --postures 40 --seed 3 --perturb p1=+0.05 --out data.csv"),
    );
    run_ok(
        d,
        &argv("calibrate --robot ge-a4 --data data.csv --out c.toml --report r.json --html r.html"),
    );
    let report = read_json(&d.join("r.json"));
    let points = report["scene"]["points"].as_array().unwrap().len() as u64;
    assert_eq!(points, 40);

    // The report's scene, as its page draws it.
    let (_, _, err) = common::run(
        d,
        &argv("export gltf --robot c.toml --report r.json --out a.glb"),
    );
    assert!(
        err.contains("the report's scene: the nominal and the calibrated robot at posture 1, 40 of 40 measured points"),
        "{err}"
    );
    let a = glb_json(&d.join("a.glb"));
    assert_eq!(count(&a, "measured points"), Some(points));
    assert_eq!(count(&a, "residuals after"), Some(2 * points));
    let links = report["scene"]["postures"][0]["calibrated"]["links"]
        .as_array()
        .unwrap()
        .len() as u64;
    assert_eq!(count(&a, "calibrated robot"), Some(2 * links));
    assert!(count(&a, "nominal robot").is_some());
    // The robot, its nominal and its data: the same robots and points, at another posture.
    run_ok(
        d,
        &argv("export gltf --robot c.toml --nominal ge-a4 --data data.csv --posture 7 --out b.glb"),
    );
    let b = glb_json(&d.join("b.glb"));
    assert_eq!(count(&b, "measured points"), Some(points));
    assert!(b["scenes"][0]["name"]
        .as_str()
        .unwrap()
        .ends_with("at posture 7"));
    // The robot alone, at zero readings.
    run_ok(d, &argv("export gltf --robot c.toml --out c.glb"));
    let c = glb_json(&d.join("c.glb"));
    assert_eq!(count(&c, "measured points"), None);
    assert_eq!(count(&c, "nominal robot"), None);
    assert_eq!(count(&c, "calibrated robot"), Some(2 * links));
}

#[test]
fn what_cannot_be_drawn_is_refused_and_nothing_written() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    run_ok(
        d,
        &argv("simulate --robot ge-a4 --postures 20 --seed 4 --out data.csv"),
    );
    run_ok(
        d,
        &argv("calibrate --robot ge-a4 --data data.csv --out c.toml --report r.json --html r.html"),
    );
    let err = run_err(
        d,
        &argv("export gltf --robot c.toml --posture 3 --out x.glb"),
    );
    assert!(err.contains("no observations to find it in"), "{err}");
    let err = run_err(
        d,
        &argv("export gltf --robot c.toml --data data.csv --posture nope --out x.glb"),
    );
    assert!(err.contains("no posture `nope`"), "{err}");
    // A report whose scene was edited to a point a thousand kilometres off, or 1e308.
    let text = std::fs::read_to_string(d.join("r.json")).unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let measured = v["scene"]["points"][0]["measured"][0].clone();
    v["scene"]["points"][0]["measured"][0] = serde_json::json!(1e308);
    std::fs::write(d.join("far.json"), v.to_string()).unwrap();
    let err = run_err(
        d,
        &argv("export gltf --robot c.toml --report far.json --out x.glb"),
    );
    // Refused when the report is read (its numbers are held within 1e100), before drawing.
    assert!(
        err.contains("not a kinecal calibration report")
            && err.contains("scene.points[0].measured[0]"),
        "{err}"
    );
    // A report of another robot (its numbers restored).
    v["scene"]["points"][0]["measured"][0] = measured;
    v["robot"] = serde_json::json!("another");
    std::fs::write(d.join("other.json"), v.to_string()).unwrap();
    let err = run_err(
        d,
        &argv("export gltf --robot c.toml --report other.json --out x.glb"),
    );
    assert!(err.contains("the report is of robot `another`"), "{err}");
    // The spec is the door: a key of another export is refused.
    std::fs::write(
        d.join("s.toml"),
        "job = \"export\"\nformat = \"gltf\"\nrobot = \"c.toml\"\ntemplate = \"r.urdf\"\nout = \"x.glb\"\n",
    )
    .unwrap();
    let err = run_err(d, &argv("export gltf --spec s.toml"));
    assert!(err.contains("a gltf export takes no template"), "{err}");
    assert!(!d.join("x.glb").exists());
    // And the spec of a command line runs the same export.
    run_ok(
        d,
        &argv("export gltf --robot c.toml --report r.json --out y.glb --write-spec y.toml"),
    );
    let spec = std::fs::read_to_string(d.join("y.toml")).unwrap();
    assert!(spec.contains("format = \"gltf\""), "{spec}");
    std::fs::remove_file(d.join("y.glb")).unwrap();
    run_ok(d, &argv("export gltf --spec y.toml"));
    assert!(d.join("y.glb").exists());
}
