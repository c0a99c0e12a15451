//! The 3-D [`Scene`] as glTF 2.0 binary (GLB), as `kinecal export gltf` writes it: the
//! robots' links as line meshes, the measured points as a point mesh, the residual vectors
//! (scaled as the scene says) and the frames' axes as lines, one material per layer (the
//! calibrated robot blue, the nominal robot grey, residuals after calibration red, before
//! orange). The robot's drawn posture is the scene's first.
//!
//! Coordinates are the scene's (metres, z up) as `f32`; one root node turns them to glTF's
//! y up, so that a viewer shows the robot standing. The JSON is made with `gltf-json`'s types.

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
];

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
    let k = scene.residual_scale;
    let residuals = |before: bool| -> Vec<[f32; 3]> {
        scene
            .points
            .iter()
            .filter_map(|p| {
                let r = if before { p.before? } else { p.after };
                Some([f32s(&p.measured), along(&p.measured, &r, k)])
            })
            .flatten()
            .collect()
    };
    let mut frames: Vec<&SceneFrame> = scene.frames.iter().collect();
    frames.extend(&posture.calibrated.tools);
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
    ]
}

/// The length a frame's axes are drawn at (m): a tenth of the reach for the fixed frames, a
/// twentieth for the tools.
pub fn axis_length(scene: &Scene, f: &SceneFrame) -> f64 {
    match f.kind {
        super::scene::FrameKind::Tool => scene.reach / 20.0,
        _ => scene.reach / 10.0,
    }
}

/// `scene` as a GLB file's bytes.
pub fn write_glb(scene: &Scene) -> Result<Vec<u8>> {
    if scene.postures.is_empty() {
        return Err(Error::Numerical("a scene without a robot to draw".into()));
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
                    return Err(Error::Numerical(format!(
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
        .map_err(|e| Error::Numerical(format!("the glTF JSON: {e}")))?;
    Ok(glb(text, bin))
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
