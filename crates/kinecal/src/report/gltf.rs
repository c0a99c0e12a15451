//! The 3-D [`Scene`] as glTF 2.0 binary (GLB), as `kinecal export gltf` writes it: the
//! robots' links as line meshes, the measured points as a point mesh, the residual vectors
//! (scaled as the scene says) and the frames' axes as lines, one material per layer (the
//! calibrated robot blue, the nominal robot grey, residuals after calibration red, before
//! orange; cameras as purple frustums, boards as grey grids with the points seen at the posture
//! as teal points). The robot's drawn posture is the scene's first.
//!
//! Coordinates are the scene's (metres, z up) as `f32`; one root node turns them to glTF's
//! y up, so that a viewer shows the robot standing. The JSON is made with `gltf-json`'s types,
//! and the file is read back (its JSON by `gltf-json`, every vertex from the binary chunk) and
//! compared with the scene before it is returned.

use gltf_json as json;
use json::validation::Checked::Valid;
use json::validation::USize64;

use super::scene::{Scene, SceneFrame};
use crate::error::{Error, Result};

/// One layer of the scene: a named node with one mesh of one primitive.
struct Layer {
    name: String,
    mode: json::mesh::Mode,
    color: [f32; 4],
    positions: Vec<[f32; 3]>,
}

/// The name of each layer's node, as the GLB holds them (a layer with nothing to draw is left
/// out).
pub const LAYERS: &[&str] = &[
    "calibrated robot",
    "calibrated joints",
    "nominal robot",
    "measured points",
    "residuals after",
    "residuals before",
    "frames x",
    "frames y",
    "frames z",
    "cameras",
    "boards",
    "board points seen",
];

/// The lines of camera frustums: from the camera's origin to each far corner, and the far
/// rectangle; the top edge (the image's first row, y down) doubled by a short tick outward,
/// so that a viewer tells up from down.
pub fn frustum_lines(c: &super::scene::SceneCamera) -> Vec<[[f64; 3]; 2]> {
    let o = c.frame.origin;
    let k = &c.corners;
    let mut out: Vec<[[f64; 3]; 2]> = k.iter().map(|p| [o, *p]).collect();
    for i in 0..4 {
        out.push([k[i], k[(i + 1) % 4]]);
    }
    // The tick: from the top edge's middle, away from the image's centre, a fifth of its width.
    let mid = [0, 1, 2].map(|i| (k[0][i] + k[1][i]) / 2.0);
    let centre = [0, 1, 2].map(|i| (k[0][i] + k[2][i]) / 2.0);
    let up = [0, 1, 2].map(|i| mid[i] + 0.4 * (mid[i] - centre[i]));
    out.push([mid, up]);
    out
}

/// The lines of a board: its outline and its grid's rows and columns (at most 20 each way,
/// evenly spread, on a larger grid).
pub fn board_lines(b: &super::scene::SceneBoard) -> Vec<[[f64; 3]; 2]> {
    let (cols, rows) = (b.cols.max(2) as usize, b.rows.max(2) as usize);
    let pick = |n: usize| -> Vec<usize> {
        if n <= 20 {
            (0..n).collect()
        } else {
            (0..20).map(|i| i * (n - 1) / 19).collect()
        }
    };
    let mut out = Vec::new();
    for c in pick(cols) {
        out.push([b.point(c), b.point(c + (rows - 1) * cols)]);
    }
    for r in pick(rows) {
        out.push([b.point(r * cols), b.point(r * cols + cols - 1)]);
    }
    out
}

fn f32s(v: &[f64; 3]) -> [f32; 3] {
    v.map(|x| x as f32)
}

fn along(p: &[f64; 3], v: &[f64; 3], k: f64) -> [f32; 3] {
    [0, 1, 2].map(|i| (p[i] + k * v[i]) as f32)
}

/// The lines and points of `scene`, layer by layer (in the order of [`LAYERS`]).
fn layers(scene: &Scene) -> Vec<Layer> {
    use json::mesh::Mode::{Lines, Points};
    let posture = &scene.postures[0];
    let links = |s: &super::scene::Skeleton| -> Vec<[f32; 3]> {
        s.links
            .iter()
            .flat_map(|[a, b]| [f32s(&s.nodes[*a]), f32s(&s.nodes[*b])])
            .collect()
    };
    let residuals = |before: bool| -> Vec<[f32; 3]> {
        scene
            .points
            .iter()
            .filter_map(|p| {
                let (r, k) = if before {
                    (p.before?, scene.residual_scale_before)
                } else {
                    (p.after, scene.residual_scale)
                };
                Some([f32s(&p.measured), along(&p.measured, &r, k)])
            })
            .flatten()
            .collect()
    };
    let mut frames: Vec<&SceneFrame> = scene.frames.iter().collect();
    frames.extend(&posture.calibrated.tools);
    frames.extend(posture.cameras.iter().map(|c| &c.frame));
    frames.extend(posture.boards.iter().map(|b| &b.frame));
    let axis = |c: usize| -> Vec<[f32; 3]> {
        frames
            .iter()
            .flat_map(|f| {
                let size = axis_length(scene, f);
                [f32s(&f.origin), along(&f.origin, &f.axes[c], size)]
            })
            .collect()
    };
    vec![
        Layer {
            name: LAYERS[0].into(),
            mode: Lines,
            color: [0.12, 0.39, 0.78, 1.0],
            positions: links(&posture.calibrated),
        },
        Layer {
            name: LAYERS[1].into(),
            mode: Points,
            color: [0.12, 0.39, 0.78, 1.0],
            positions: posture
                .calibrated
                .joints
                .iter()
                .map(|(n, _)| f32s(&posture.calibrated.nodes[*n]))
                .collect(),
        },
        Layer {
            name: LAYERS[2].into(),
            mode: Lines,
            color: [0.55, 0.55, 0.55, 1.0],
            positions: posture.nominal.as_ref().map(links).unwrap_or_default(),
        },
        Layer {
            name: LAYERS[3].into(),
            mode: Points,
            color: [0.1, 0.1, 0.1, 1.0],
            positions: scene.points.iter().map(|p| f32s(&p.measured)).collect(),
        },
        Layer {
            name: LAYERS[4].into(),
            mode: Lines,
            color: [0.84, 0.15, 0.16, 1.0],
            positions: residuals(false),
        },
        Layer {
            name: LAYERS[5].into(),
            mode: Lines,
            color: [1.0, 0.5, 0.05, 1.0],
            positions: residuals(true),
        },
        Layer {
            name: LAYERS[6].into(),
            mode: Lines,
            color: [0.9, 0.1, 0.1, 1.0],
            positions: axis(0),
        },
        Layer {
            name: LAYERS[7].into(),
            mode: Lines,
            color: [0.1, 0.7, 0.1, 1.0],
            positions: axis(1),
        },
        Layer {
            name: LAYERS[8].into(),
            mode: Lines,
            color: [0.1, 0.2, 0.9, 1.0],
            positions: axis(2),
        },
        Layer {
            name: LAYERS[9].into(),
            mode: Lines,
            color: [0.58, 0.2, 0.7, 1.0],
            positions: posture
                .cameras
                .iter()
                .flat_map(frustum_lines)
                .flat_map(|[a, b]| [f32s(&a), f32s(&b)])
                .collect(),
        },
        Layer {
            name: LAYERS[10].into(),
            mode: Lines,
            color: [0.3, 0.3, 0.3, 1.0],
            positions: posture
                .boards
                .iter()
                .flat_map(board_lines)
                .flat_map(|[a, b]| [f32s(&a), f32s(&b)])
                .collect(),
        },
        Layer {
            name: LAYERS[11].into(),
            mode: Points,
            color: [0.0, 0.6, 0.5, 1.0],
            positions: posture
                .boards
                .iter()
                .flat_map(|b| b.seen.iter().map(|&k| f32s(&b.point(k))))
                .collect(),
        },
    ]
}

/// The length a frame's axes are drawn at (m): a tenth of the reach for the fixed frames, a
/// twentieth for the tools, cameras and boards.
pub fn axis_length(scene: &Scene, f: &SceneFrame) -> f64 {
    use super::scene::FrameKind;
    match f.kind {
        FrameKind::Tool | FrameKind::Camera | FrameKind::Board => scene.reach / 20.0,
        _ => scene.reach / 10.0,
    }
}

/// `scene` as a GLB file's bytes.
pub fn write_glb(scene: &Scene) -> Result<Vec<u8>> {
    if scene.postures.is_empty() {
        return Err(Error::Problem("a scene without a robot to draw".into()));
    }
    let mut root = json::Root {
        asset: json::Asset {
            generator: Some(format!("kinecal {}", env!("CARGO_PKG_VERSION"))),
            ..Default::default()
        },
        ..Default::default()
    };
    let mut bin: Vec<u8> = Vec::new();
    let buffer = root.push(json::Buffer {
        byte_length: USize64(0),
        name: None,
        uri: None,
        extensions: None,
        extras: Default::default(),
    });
    let mut children = Vec::new();
    for layer in layers(scene) {
        if layer.positions.is_empty() {
            continue;
        }
        let offset = bin.len();
        let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
        for p in &layer.positions {
            for k in 0..3 {
                if !p[k].is_finite() {
                    return Err(Error::Problem(format!(
                        "a coordinate of the {} is not finite",
                        layer.name
                    )));
                }
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
                bin.extend_from_slice(&p[k].to_le_bytes());
            }
        }
        let view = root.push(json::buffer::View {
            buffer,
            byte_length: USize64::from(bin.len() - offset),
            byte_offset: Some(USize64::from(offset)),
            byte_stride: None,
            name: None,
            target: Some(Valid(json::buffer::Target::ArrayBuffer)),
            extensions: None,
            extras: Default::default(),
        });
        let accessor = root.push(json::Accessor {
            buffer_view: Some(view),
            byte_offset: Some(USize64(0)),
            count: USize64::from(layer.positions.len()),
            component_type: Valid(json::accessor::GenericComponentType(
                json::accessor::ComponentType::F32,
            )),
            extensions: None,
            extras: Default::default(),
            type_: Valid(json::accessor::Type::Vec3),
            min: Some(json::Value::from(lo.to_vec())),
            max: Some(json::Value::from(hi.to_vec())),
            name: Some(layer.name.clone()),
            normalized: false,
            sparse: None,
        });
        let material = root.push(json::Material {
            name: Some(layer.name.clone()),
            pbr_metallic_roughness: json::material::PbrMetallicRoughness {
                base_color_factor: json::material::PbrBaseColorFactor(layer.color),
                metallic_factor: json::material::StrengthFactor(0.0),
                roughness_factor: json::material::StrengthFactor(1.0),
                ..Default::default()
            },
            ..Default::default()
        });
        let mesh = root.push(json::Mesh {
            extensions: None,
            extras: Default::default(),
            name: Some(layer.name.clone()),
            primitives: vec![json::mesh::Primitive {
                attributes: [(Valid(json::mesh::Semantic::Positions), accessor)]
                    .into_iter()
                    .collect(),
                extensions: None,
                extras: Default::default(),
                indices: None,
                material: Some(material),
                mode: Valid(layer.mode),
                targets: None,
            }],
            weights: None,
        });
        children.push(root.push(json::Node {
            mesh: Some(mesh),
            name: Some(layer.name),
            ..Default::default()
        }));
    }
    root.buffers[0].byte_length = USize64::from(bin.len());
    // z up (robots) to y up (glTF): a quarter turn about x.
    let h = std::f32::consts::FRAC_1_SQRT_2;
    let top = root.push(json::Node {
        name: Some(format!("{} (z up)", scene.robot)),
        rotation: Some(json::scene::UnitQuaternion([-h, 0.0, 0.0, h])),
        children: Some(children),
        ..Default::default()
    });
    let s = root.push(json::Scene {
        extensions: None,
        extras: Default::default(),
        name: Some(format!(
            "{} at posture {}",
            scene.robot, scene.postures[0].label
        )),
        nodes: vec![top],
    });
    root.scene = Some(s);
    let text = root
        .to_vec()
        .map_err(|e| Error::Problem(format!("the glTF JSON: {e}")))?;
    let out = glb(text, bin);
    read_back(&out, &layers(scene))?;
    Ok(out)
}

/// Reads `glb` back (its container, its JSON by `gltf-json`, each layer's vertices from the
/// binary chunk) and compares it with `expected`, bit for bit: what is written is the scene.
fn read_back(glb: &[u8], expected: &[Layer]) -> Result<()> {
    let differs = |what: String| {
        Err(Error::Problem(format!(
            "the GLB read back is not the scene: {what}"
        )))
    };
    let word = |at: usize| -> Option<usize> {
        glb.get(at..at + 4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize)
    };
    if glb.get(..4) != Some(b"glTF") || word(4) != Some(2) || word(8) != Some(glb.len()) {
        return differs("its header".into());
    }
    let json_len = word(12).unwrap_or(0);
    let bin_at = 20 + json_len;
    if glb.get(16..20) != Some(b"JSON") || glb.get(bin_at + 4..bin_at + 8) != Some(b"BIN\0") {
        return differs("its chunks".into());
    }
    let bin_len = word(bin_at).unwrap_or(0);
    let (Some(text), Some(bin)) = (
        glb.get(20..bin_at),
        glb.get(bin_at + 8..bin_at + 8 + bin_len),
    ) else {
        return differs("its chunks' lengths".into());
    };
    let root = json::Root::from_slice(text)
        .map_err(|e| Error::Problem(format!("the GLB read back: its JSON: {e}")))?;
    let layers: Vec<&Layer> = expected
        .iter()
        .filter(|l| !l.positions.is_empty())
        .collect();
    if root.nodes.len() != layers.len() + 1 {
        return differs(format!("{} nodes", root.nodes.len()));
    }
    for (node, layer) in root.nodes.iter().zip(layers) {
        let vertices = node
            .mesh
            .and_then(|m| root.meshes.get(m.value()))
            .and_then(|m| m.primitives.first())
            .and_then(|p| p.attributes.get(&Valid(json::mesh::Semantic::Positions)))
            .and_then(|a| root.accessors.get(a.value()))
            .and_then(|a| {
                let view = root.buffer_views.get(a.buffer_view?.value())?;
                let at = view.byte_offset.map_or(0, |o| o.0 as usize);
                let count = a.count.0 as usize;
                let bytes = bin.get(at..at + 12 * count)?;
                Some(
                    bytes
                        .chunks_exact(12)
                        .map(|v| {
                            [0, 4, 8]
                                .map(|k| f32::from_le_bytes([v[k], v[k + 1], v[k + 2], v[k + 3]]))
                        })
                        .collect::<Vec<[f32; 3]>>(),
                )
            });
        let same = node.name.as_deref() == Some(layer.name.as_str())
            && vertices.is_some_and(|v| {
                v.len() == layer.positions.len()
                    && v.iter()
                        .zip(&layer.positions)
                        .all(|(a, b)| (0..3).all(|k| a[k].to_bits() == b[k].to_bits()))
            });
        if !same {
            return differs(format!("the layer `{}`", layer.name));
        }
    }
    Ok(())
}

/// The GLB container: a 12-byte header, the JSON chunk (padded with spaces) and the binary
/// chunk (padded with zeros), each 4-byte aligned.
fn glb(mut text: Vec<u8>, mut bin: Vec<u8>) -> Vec<u8> {
    while text.len() % 4 != 0 {
        text.push(b' ');
    }
    while bin.len() % 4 != 0 {
        bin.push(0);
    }
    let total = 12 + 8 + text.len() + if bin.is_empty() { 0 } else { 8 + bin.len() };
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(text.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&text);
    if !bin.is_empty() {
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&bin);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::scene::SceneOptions;

    #[test]
    fn a_changed_vertex_or_header_is_caught_on_reading_back() {
        let robot = crate::model::examples::ge_a4();
        let scene = Scene::new(None, &robot, None, &SceneOptions::default()).unwrap();
        let good = write_glb(&scene).unwrap();
        let expected = layers(&scene);
        assert!(read_back(&good, &expected).is_ok());
        // The last vertex's last byte, in the binary chunk.
        let mut bad = good.clone();
        let last = bad.len() - 1;
        bad[last] ^= 0x40;
        let e = read_back(&bad, &expected).unwrap_err();
        assert!(e.to_string().contains("the layer"), "{e}");
        let mut bad = good.clone();
        bad[8] ^= 1;
        let e = read_back(&bad, &expected).unwrap_err();
        assert!(e.to_string().contains("header"), "{e}");
        assert!(read_back(&good[..30], &expected).is_err());
    }
}
