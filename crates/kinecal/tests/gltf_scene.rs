//! The 3-D scene written as GLB (`kinecal export gltf`), read back by an independent glTF
//! reader (the `gltf` crate): the container's header and chunks, the node per layer, and every
//! vertex equal to the scene's coordinates to `f32` precision.

use kinecal::apps::simulate::{
    add_noise, measure, perturb, random_robot, sample_postures, PerturbStd,
};
use kinecal::model::robot::JointKind;
use kinecal::report::gltf::{write_glb, LAYERS};
use kinecal::report::scene::{Scene, SceneOptions};

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(b[at..at + 4].try_into().unwrap())
}

/// The header and the two chunks of a GLB, checked by hand (glTF 2.0, section 4.4).
fn check_container(glb: &[u8]) {
    assert_eq!(&glb[0..4], b"glTF");
    assert_eq!(u32_at(glb, 4), 2, "version");
    assert_eq!(u32_at(glb, 8) as usize, glb.len(), "total length");
    let json_len = u32_at(glb, 12) as usize;
    assert_eq!(&glb[16..20], b"JSON");
    assert_eq!(json_len % 4, 0);
    let text = std::str::from_utf8(&glb[20..20 + json_len]).unwrap();
    let v: serde_json::Value = serde_json::from_str(text.trim_end()).unwrap();
    assert_eq!(v["asset"]["version"], "2.0");
    let at = 20 + json_len;
    let bin_len = u32_at(glb, at) as usize;
    assert_eq!(&glb[at + 4..at + 8], b"BIN\0");
    assert_eq!(bin_len % 4, 0);
    assert_eq!(at + 8 + bin_len, glb.len());
    assert_eq!(
        v["buffers"][0]["byteLength"].as_u64().unwrap() as usize,
        bin_len
    );
    // No NaN or infinity can be in JSON; the binary's floats are checked below.
    assert!(!text.contains("NaN") && !text.contains("inf"));
}

/// Every vertex of the layer named `name`, read by the `gltf` crate.
fn vertices(doc: &gltf::Gltf, name: &str) -> Option<Vec<[f32; 3]>> {
    let blob = doc.blob.as_deref().unwrap();
    let node = doc.nodes().find(|n| n.name() == Some(name))?;
    let mesh = node.mesh().unwrap();
    let prim = mesh.primitives().next().unwrap();
    let reader = prim.reader(|_| Some(blob));
    Some(reader.read_positions().unwrap().collect())
}

fn close(a: [f32; 3], b: &[f64; 3]) -> bool {
    (0..3).all(|k| (a[k] as f64 - b[k]).abs() <= 1e-6 * (1.0 + b[k].abs()))
}

fn scene() -> Scene {
    let calibrated = random_robot(&[JointKind::Revolute; 6], 7);
    let nominal = perturb(
        &calibrated,
        PerturbStd {
            length: 1e-3,
            angle: 1e-3,
            slope_fraction: 0.0,
        },
        3,
    );
    let postures = sample_postures(&calibrated, 300, 11);
    let mut data = measure(&calibrated, &postures, true);
    add_noise(&mut data, 50e-6, 0.0, 5);
    let options = SceneOptions {
        max_points: 100,
        ..Default::default()
    };
    Scene::new(Some(&nominal), &calibrated, Some(&data), &options).unwrap()
}

#[test]
fn glb_reads_back_as_the_scene() {
    let scene = scene();
    assert_eq!(scene.points.len(), 100);
    assert_eq!(scene.points_total, 300);
    let glb = write_glb(&scene).unwrap();
    check_container(&glb);
    let doc = gltf::Gltf::from_slice(&glb).expect("a valid glTF");
    // One node per layer (the robot has no sessions: frames are the base and the tool; no
    // cameras nor boards: their 3 layers are left out), and the root that turns z up into y up.
    assert_eq!(doc.nodes().count(), LAYERS.len() - 3 + 1);
    let root = doc.default_scene().unwrap().nodes().next().unwrap();
    assert_eq!(root.children().count(), LAYERS.len() - 3);
    let (_, r, _) = root.transform().decomposed();
    let h = std::f32::consts::FRAC_1_SQRT_2;
    let turn = [-h, 0.0, 0.0, h];
    assert!((0..4).all(|i| (r[i] - turn[i]).abs() < 1e-7), "{r:?}");

    // The calibrated robot's links: pairs of its skeleton's nodes.
    let p = &scene.postures[0];
    let links = vertices(&doc, "calibrated robot").unwrap();
    assert_eq!(links.len(), 2 * p.calibrated.links.len());
    for (k, [a, b]) in p.calibrated.links.iter().enumerate() {
        assert!(close(links[2 * k], &p.calibrated.nodes[*a]));
        assert!(close(links[2 * k + 1], &p.calibrated.nodes[*b]));
    }
    let nominal = vertices(&doc, "nominal robot").unwrap();
    let nom = p.nominal.as_ref().unwrap();
    for (k, [_, b]) in nom.links.iter().enumerate() {
        assert!(close(nominal[2 * k + 1], &nom.nodes[*b]));
    }
    // The robots differ (by millimetres), and the file says so.
    assert!(links
        .iter()
        .zip(&nominal)
        .any(|(a, b)| (0..3).any(|k| (a[k] - b[k]).abs() > 1e-5)));

    // The measured points, and the residuals from them, scaled.
    let points = vertices(&doc, "measured points").unwrap();
    assert_eq!(points.len(), scene.points.len());
    let after = vertices(&doc, "residuals after").unwrap();
    let before = vertices(&doc, "residuals before").unwrap();
    let k = scene.residual_scale;
    for (i, sp) in scene.points.iter().enumerate() {
        assert!(close(points[i], &sp.measured));
        assert!(close(after[2 * i], &sp.measured));
        let tip = [0, 1, 2].map(|c| sp.measured[c] + k * sp.after[c]);
        assert!(close(after[2 * i + 1], &tip));
        let b = sp.before.unwrap();
        let kb = scene.residual_scale_before;
        let tip = [0, 1, 2].map(|c| sp.measured[c] + kb * b[c]);
        assert!(close(before[2 * i + 1], &tip));
    }
    // Residual vectors after calibration are the noise: tens of micrometres; before, the
    // nominal robot's millimetres, drawn at a smaller scale.
    assert!(scene.points.iter().all(|p| p.error_after() < 1e-3));
    assert!(scene.residual_scale_before < scene.residual_scale);

    // Materials: the calibrated robot blue, the nominal grey.
    let mat = |name: &str| {
        let node = doc.nodes().find(|n| n.name() == Some(name)).unwrap();
        let prim = node.mesh().unwrap().primitives().next().unwrap();
        prim.material().pbr_metallic_roughness().base_color_factor()
    };
    let (c, n) = (mat("calibrated robot"), mat("nominal robot"));
    assert!(c[2] > 0.7 && c[0] < 0.2, "{c:?}");
    assert!((n[0] - n[2]).abs() < 1e-6 && n[0] > 0.4, "{n:?}");
    // Every float of the binary chunk is finite.
    let blob = doc.blob.as_deref().unwrap();
    assert!(blob
        .chunks_exact(4)
        .all(|c| f32::from_le_bytes(c.try_into().unwrap()).is_finite()));
}

#[test]
fn a_scene_without_data_or_nominal_is_the_robot_alone() {
    let robot = random_robot(&[JointKind::Revolute, JointKind::Prismatic], 2);
    let scene = Scene::new(None, &robot, None, &SceneOptions::default()).unwrap();
    assert_eq!(scene.postures[0].label, "home");
    let glb = write_glb(&scene).unwrap();
    check_container(&glb);
    let doc = gltf::Gltf::from_slice(&glb).unwrap();
    assert!(vertices(&doc, "nominal robot").is_none());
    assert!(vertices(&doc, "measured points").is_none());
    // Links, joints and the frames' three axes.
    assert_eq!(doc.nodes().count(), 1 + 2 + 3);
}

/// A camera fixed beside the robot and a board on its flange: the frustum's 9 lines (4 rays,
/// the far rectangle, the top's tick) and the board's grid (9 + 6 lines) read back.
#[test]
fn cameras_and_boards_read_back() {
    use kinecal::model::camera::{Board, Camera, Mount};
    use kinecal::model::robot::Link;
    let mut robot = random_robot(&[JointKind::Revolute; 6], 7);
    robot.cameras.push(Camera {
        name: "fixed".into(),
        mount: Mount::Base,
        pose: Link {
            x: 0.8,
            y: 0.1,
            z: 0.5,
            alpha: 3.0,
            beta: 0.2,
            gamma: -1.7,
        },
        fx: 600.0,
        fy: 610.0,
        cx: 320.0,
        cy: 240.0,
        distortion: [0.0; 5],
        width: 640,
        height: 480,
    });
    robot.boards.push(Board {
        name: "board".into(),
        mount: Mount::EndEffector,
        pose: Link::default(),
        cols: 9,
        rows: 6,
        spacing: 0.025,
    });
    robot.validate().unwrap();
    let scene = Scene::new(None, &robot, None, &SceneOptions::default()).unwrap();
    let doc = gltf::Gltf::from_slice(&write_glb(&scene).unwrap()).unwrap();
    let p = &scene.postures[0];
    let cam = vertices(&doc, "cameras").unwrap();
    assert_eq!(cam.len(), 2 * 9);
    assert!(close(cam[0], &p.cameras[0].frame.origin));
    assert!(close(cam[1], &p.cameras[0].corners[0]));
    let board = vertices(&doc, "boards").unwrap();
    assert_eq!(board.len(), 2 * (9 + 6));
    assert!(close(board[0], &p.boards[0].corners[0]));
    // No data, so no board point seen.
    assert!(vertices(&doc, "board points seen").is_none());
}
