//! The 3-D scene of a calibration: the nominal and the calibrated robot at chosen postures, the
//! measured points with their residual vectors, and the frames things are measured in. One
//! model, drawn twice: by the HTML report's 3-D view (`kinecal-report`) and written as glTF by
//! `kinecal export gltf` ([`super::gltf`]), so that both show the same scene.
//!
//! Every coordinate is in metres, in the robot's global frame (z up): a point measured in a
//! session with a frame of its own is brought back through the calibrated robot's session frame.
//! Every number in a scene is finite and within [`LIMIT`] metres of the origin: a point beyond
//! is left out (and counted), a robot beyond is refused.
//!
//! The calibrated robot's cameras and boards are drawn at each posture: a camera as its frame
//! and a frustum (the rays through the image's corners, cut at [`Scene::frustum_depth`]), a
//! board as its grid, with the points a camera saw in that posture marked. A pixel observation
//! has no measured 3-D point, so it adds no point nor residual vector: its error is in pixels,
//! in the report's pixel metric; the board points seen stand for it in the view.

use nalgebra::{Matrix3, Vector3};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::model::camera::Mount;
use crate::model::kinematics::{Chain, Frame, Target, Workspace};
use crate::model::robot::{JointKind, Robot};
use crate::observe::{for_each_observation, target_name, Dataset, Observation};
use crate::units::LengthUnit;

/// How far from the origin (m) a drawn coordinate may be: a robot or a point beyond is not
/// drawn (a thousand kilometres: far beyond any robot, well within `f32`).
pub const LIMIT: f64 = 1e6;

/// What a scene holds, and how much of it.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneOptions {
    /// The measured points drawn at most (the largest residuals first, then evenly spread over
    /// the rest).
    pub max_points: usize,
    /// The postures the robots are drawn at, at most.
    pub max_postures: usize,
    /// The posture drawn first, by label (default: the first measured).
    pub posture: Option<String>,
}

impl Default for SceneOptions {
    fn default() -> Self {
        SceneOptions {
            max_points: 2000,
            max_postures: 24,
            posture: None,
        }
    }
}

/// What a frame of the scene is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
#[non_exhaustive]
pub enum FrameKind {
    /// The robot's global frame (the measurement frame of data outside every session).
    Base,
    /// The measurement frame of a session (a laser tracker's position).
    Measurement,
    /// A tool frame of the robot at a posture: the end effector or a site.
    Tool,
    /// A camera's frame (OpenCV's: z along the optical axis, x right, y down).
    Camera,
    /// A calibration board's frame.
    Board,
}

impl FrameKind {
    /// The kind's name, as the renderers' legends write it.
    pub fn as_str(self) -> &'static str {
        match self {
            FrameKind::Base => "base",
            FrameKind::Measurement => "measurement",
            FrameKind::Tool => "tool",
            FrameKind::Camera => "camera",
            FrameKind::Board => "board",
        }
    }
}

/// A frame: its origin and its axes (unit vectors) in the global frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct SceneFrame {
    /// Its name.
    pub name: String,
    /// What it is.
    pub kind: FrameKind,
    /// Origin (m).
    pub origin: [f64; 3],
    /// The x, y and z axes.
    pub axes: [[f64; 3]; 3],
}

/// A robot at a posture: the origins of its joints and tools joined by its links.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct Skeleton {
    /// Points (m): the global frame's origin first, then each joint's, each tool's.
    pub nodes: Vec<[f64; 3]>,
    /// Links, as pairs of indices into `nodes`.
    pub links: Vec<[usize; 2]>,
    /// For each joint: the index of its node and its axis (a unit vector).
    pub joints: Vec<(usize, [f64; 3])>,
    /// The tool frames: the end effector and the sites.
    pub tools: Vec<SceneFrame>,
}

/// A camera of the calibrated robot at a posture: its frame (OpenCV's: z along the optical
/// axis, x right, y down in the image) and a frustum, the rays through the image's corners cut
/// at [`Scene::frustum_depth`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct SceneCamera {
    /// Its frame.
    pub frame: SceneFrame,
    /// The frustum's far corners (m): the image's corners `(0, 0)`, `(width, 0)`, `(width,
    /// height)`, `(0, height)` seen through the pinhole (without distortion) at the depth.
    pub corners: [[f64; 3]; 4],
}

/// A calibration board of the calibrated robot at a posture.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct SceneBoard {
    /// Its frame (the points in its x-y plane, point 0 at the origin).
    pub frame: SceneFrame,
    /// Points along x.
    pub cols: u32,
    /// Points along y.
    pub rows: u32,
    /// The grid's corners (m): points `0`, `cols - 1`, the last, `(rows - 1) cols`.
    pub corners: [[f64; 3]; 4],
    /// The points (0-based, row-major) a camera saw at this posture (pixel observations have no
    /// measured 3-D point: these are where the calibrated model puts the points seen).
    pub seen: Vec<usize>,
}

impl SceneBoard {
    /// Point `k` of the grid (m), from its corners.
    pub fn point(&self, k: usize) -> [f64; 3] {
        let cols = self.cols.max(2) as usize;
        let rows = self.rows.max(2) as usize;
        let (a, b) = (
            (k % cols) as f64 / (cols - 1) as f64,
            (k / cols) as f64 / (rows - 1) as f64,
        );
        let c = &self.corners;
        [0, 1, 2].map(|i| c[0][i] + a * (c[1][i] - c[0][i]) + b * (c[3][i] - c[0][i]))
    }
}

/// One posture the robots are drawn at.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ScenePosture {
    /// Its label in the data (`home` without data).
    pub label: String,
    /// Its index in the data's postures (0 without data).
    pub index: usize,
    /// The nominal robot there, when the scene has one.
    pub nominal: Option<Skeleton>,
    /// The calibrated robot there.
    pub calibrated: Skeleton,
    /// The calibrated robot's cameras there.
    #[serde(default)]
    pub cameras: Vec<SceneCamera>,
    /// The calibrated robot's boards there.
    #[serde(default)]
    pub boards: Vec<SceneBoard>,
}

/// A measured point and its residuals (`model - measured`, m, global frame's axes).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ScenePoint {
    /// The index of its posture in the data.
    pub posture: usize,
    /// The target measured (`ee` or a site's name).
    pub target: String,
    /// The measured point (m).
    pub measured: [f64; 3],
    /// The calibrated robot's residual.
    pub after: [f64; 3],
    /// The nominal robot's residual, when the scene has a nominal robot.
    pub before: Option<[f64; 3]>,
}

impl ScenePoint {
    /// The length of the calibrated robot's residual (m).
    pub fn error_after(&self) -> f64 {
        norm(&self.after)
    }
}

/// The scene: see the module's documentation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[non_exhaustive]
pub struct Scene {
    /// The robot's name.
    pub robot: String,
    /// The robot file's length unit (the coordinates are metres whatever it is).
    pub length_unit: LengthUnit,
    /// The robot's reach (m): the distance from the global frame's origin to the farthest
    /// node over the drawn postures, at least 1 mm.
    pub reach: f64,
    /// The postures the robots are drawn at; the first is the one shown first.
    pub postures: Vec<ScenePosture>,
    /// Postures in the data.
    pub postures_total: usize,
    /// The measured points drawn, in the data's order.
    pub points: Vec<ScenePoint>,
    /// Measured points (positions and poses) in the data.
    pub points_total: usize,
    /// Measured points left out because a coordinate or residual was not finite or beyond
    /// [`LIMIT`].
    pub points_unplottable: usize,
    /// Residual vectors after calibration are drawn this many times their length.
    pub residual_scale: f64,
    /// Residual vectors before calibration (the nominal robot's, often far longer) are drawn
    /// this many times their length.
    #[serde(default = "unit_scale")]
    pub residual_scale_before: f64,
    /// The frames that do not move with the robot: the global frame and the sessions'
    /// measurement frames.
    pub frames: Vec<SceneFrame>,
    /// The depth (m) the cameras' frustums are cut at: a twelfth of the reach (8 cm for a
    /// robot of a metre), whatever the lens.
    #[serde(default)]
    pub frustum_depth: f64,
}

fn norm(v: &[f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

fn arr(v: &Vector3<f64>) -> [f64; 3] {
    [v.x, v.y, v.z]
}

fn drawable(v: &[f64; 3]) -> bool {
    v.iter().all(|x| x.is_finite() && x.abs() <= LIMIT)
}

fn frame_drawable(f: &SceneFrame) -> bool {
    drawable(&f.origin) && f.axes.iter().all(drawable)
}

fn frame_of(name: &str, kind: FrameKind, f: &Frame) -> SceneFrame {
    let r = &f.rotation;
    SceneFrame {
        name: name.to_string(),
        kind,
        origin: arr(&f.translation),
        axes: [0, 1, 2].map(|c| [r[(0, c)], r[(1, c)], r[(2, c)]]),
    }
}

/// The inverse of a rigid transform.
fn inverse(f: &Frame) -> Frame {
    let rt: Matrix3<f64> = f.rotation.transpose();
    Frame {
        rotation: rt,
        translation: -(rt * f.translation),
    }
}

/// `robot` at `readings` (with the posture's payload, for an elastic robot).
pub fn skeleton(
    robot: &Robot,
    readings: &[f64],
    payload: Option<&crate::model::robot::Payload>,
) -> Result<Skeleton> {
    let n = robot.dof();
    if readings.len() != n {
        return Err(Error::Problem(format!(
            "a posture of {} readings for a robot of {n} joints",
            readings.len()
        )));
    }
    let chain = Chain::new(robot);
    let mut ws = Workspace::new(robot);
    chain.forward_loaded(readings, None, payload, &mut ws);
    let mut nodes = vec![[0.0; 3]];
    let mut links = Vec::new();
    let mut joints = Vec::new();
    // The node of the frame right after each joint (0: the global frame).
    let mut after = vec![0usize; n + 1];
    for i in 0..=n {
        let parent = robot.link_parent(i);
        let from = after[parent];
        // The distal end of link i: where joint i + 1 turns (or slides from), the end
        // effector for the last link.
        let distal = ws
            .after_joint(parent)
            .then(&Frame::from_link(&robot.links[i]));
        nodes.push(arr(&distal.translation));
        let at = nodes.len() - 1;
        links.push([from, at]);
        if i < n {
            joints.push((at, arr(&distal.rotation.column(2).into_owned())));
            after[i + 1] = match robot.joints[i].kind {
                JointKind::Revolute => at,
                JointKind::Prismatic => {
                    nodes.push(arr(&ws.after_joint(i + 1).translation));
                    links.push([at, nodes.len() - 1]);
                    nodes.len() - 1
                }
            };
        }
    }
    let mut tools = vec![frame_of(
        robot.end_effector.as_deref().unwrap_or("ee"),
        FrameKind::Tool,
        ws.end_effector(),
    )];
    for (s, site) in robot.sites.iter().enumerate() {
        let f = chain.target_frame(&ws, Target::Site(s));
        nodes.push(arr(&f.translation));
        links.push([after[site.joint.min(n)], nodes.len() - 1]);
        tools.push(frame_of(&site.name, FrameKind::Tool, &f));
    }
    let bad = nodes.iter().any(|p| !drawable(p))
        || tools
            .iter()
            .any(|t| !drawable(&t.origin) || t.axes.iter().any(|a| !drawable(a)))
        || joints.iter().any(|(_, a)| !drawable(a));
    if bad {
        return Err(Error::Problem(format!(
            "robot `{}` has a frame that is not finite or lies beyond {LIMIT:e} m at this \
             posture: it cannot be drawn",
            robot.name
        )));
    }
    Ok(Skeleton {
        nodes,
        links,
        joints,
        tools,
    })
}

/// The cameras and boards of `robot` at `readings` (the points each board shows as seen: those
/// of `seen`, by board).
fn cameras_and_boards(
    robot: &Robot,
    readings: &[f64],
    payload: Option<&crate::model::robot::Payload>,
    depth: f64,
    seen: &[Vec<usize>],
) -> (Vec<SceneCamera>, Vec<SceneBoard>) {
    if robot.cameras.is_empty() && robot.boards.is_empty() {
        return (Vec::new(), Vec::new());
    }
    let chain = Chain::new(robot);
    let mut ws = Workspace::new(robot);
    chain.forward_loaded(readings, None, payload, &mut ws);
    let at = |m: Mount, pose: &crate::model::robot::Link| {
        let mount = match crate::observe::pixel::mount_target(m) {
            None => Frame::identity(),
            Some(t) => chain.target_frame(&ws, t),
        };
        mount.then(&Frame::from_link(pose))
    };
    let point = |f: &Frame, p: Vector3<f64>| arr(&(f.rotation * p + f.translation));
    let cameras = robot
        .cameras
        .iter()
        .map(|c| {
            let f = at(c.mount, &c.pose);
            let (w, h) = (c.width as f64, c.height as f64);
            let corners = [(0.0, 0.0), (w, 0.0), (w, h), (0.0, h)].map(|(u, v)| {
                point(
                    &f,
                    depth * Vector3::new((u - c.cx) / c.fx, (v - c.cy) / c.fy, 1.0),
                )
            });
            SceneCamera {
                frame: frame_of(&c.name, FrameKind::Camera, &f),
                corners,
            }
        })
        .collect();
    let boards = robot
        .boards
        .iter()
        .enumerate()
        .map(|(i, b)| {
            let f = at(b.mount, &b.pose);
            let n = b.points().max(1);
            let corners =
                [0, b.cols as usize - 1, n - 1, n - b.cols as usize].map(|k| point(&f, b.point(k)));
            SceneBoard {
                frame: frame_of(&b.name, FrameKind::Board, &f),
                cols: b.cols,
                rows: b.rows,
                corners,
                seen: seen.get(i).cloned().unwrap_or_default(),
            }
        })
        .collect();
    (cameras, boards)
}

/// For each posture of `data`, by board: the points a camera saw there.
fn seen_points(robot: &Robot, data: &Dataset) -> Vec<Vec<Vec<usize>>> {
    let mut out = vec![vec![Vec::new(); robot.boards.len()]; data.postures.len()];
    for o in &data.observations {
        if let Observation::Pixel(p) = o {
            if let crate::observe::pixel::Seen::Board { board, index } = p.seen {
                if let Some(v) = out.get_mut(o.posture()).and_then(|b| b.get_mut(board)) {
                    if !v.contains(&index) {
                        v.push(index);
                    }
                }
            }
        }
    }
    for b in out.iter_mut().flatten() {
        b.sort_unstable();
    }
    out
}

/// The measured point and the model's, in the measurement frame, of a position or a pose.
fn measured(o: &Observation) -> Option<Vector3<f64>> {
    match o {
        Observation::Position(p) => Some(p.position),
        Observation::Pose(p) => Some(p.position),
        _ => None,
    }
}

/// For every observation with a measured point: `(index, measured, model)`, in the
/// measurement frame.
fn model_points(robot: &Robot, data: &Dataset) -> Vec<Option<(Vector3<f64>, Vector3<f64>)>> {
    let mut out = vec![None; data.observations.len()];
    for_each_observation(robot, data, |i, o, frames| {
        if let (Some(m), Some(f)) = (measured(o), frames.first()) {
            out[i] = Some((m, f.translation));
        }
    });
    out
}

/// Evenly spread picks of `k` of `n` indices (all when `k >= n`).
fn spread(n: usize, k: usize) -> Vec<usize> {
    if k >= n {
        return (0..n).collect();
    }
    if k == 0 {
        return Vec::new();
    }
    (0..k).map(|i| i * n / k).collect()
}

impl Scene {
    /// The scene of `calibrated` (and `nominal`, when given, of the same structure) on `data`
    /// (none: the robots at zero readings, no points).
    pub fn new(
        nominal: Option<&Robot>,
        calibrated: &Robot,
        data: Option<&Dataset>,
        options: &SceneOptions,
    ) -> Result<Scene> {
        check_same_structure(nominal, calibrated)?;
        let empty = Dataset::default();
        let data = data.unwrap_or(&empty);

        let candidates = global_points(nominal, calibrated, data);
        let (points, worst_posture) = pick_points(candidates.points, options.max_points);

        let chosen = choose_postures(data, options, worst_posture)?;
        let mut postures = posture_skeletons(nominal, calibrated, data, &chosen)?;
        let reach = reach_of(&postures);

        // The cameras and boards at each posture drawn, with the board points seen there.
        let frustum_depth = reach / 12.0;
        mount_cameras_and_boards(calibrated, data, &chosen, frustum_depth, &mut postures)?;

        // The residuals' scales: the 95th percentile of the drawn residuals, after calibration
        // and before, a twentieth of the robot's size, rounded down to 1, 2 or 5 times a power
        // of ten.
        let errors: Vec<f64> = points.iter().map(ScenePoint::error_after).collect();
        let before: Vec<f64> = points
            .iter()
            .filter_map(|p| p.before.as_ref().map(norm))
            .collect();
        let residual_scale = scale_of(errors, reach);
        let residual_scale_before = scale_of(before, reach);

        let scene = Scene {
            robot: calibrated.name.clone(),
            length_unit: calibrated.units.length,
            reach,
            postures,
            postures_total: data.postures.len(),
            points,
            points_total: candidates.total,
            points_unplottable: candidates.unplottable,
            residual_scale,
            residual_scale_before,
            frames: fixed_frames(calibrated),
            frustum_depth,
        };
        scene.check()?;
        Ok(scene)
    }
}

/// Refuses a `nominal` robot whose structure differs from `calibrated`'s (one scene draws both
/// on the same nodes); `Ok` without a nominal robot.
fn check_same_structure(nominal: Option<&Robot>, calibrated: &Robot) -> Result<()> {
    if let Some(nom) = nominal {
        if !nom.same_structure(calibrated) {
            return Err(Error::Problem(format!(
                "the nominal robot `{}` and the calibrated robot `{}` differ in structure: \
                 one scene cannot hold both",
                nom.name, calibrated.name
            )));
        }
    }
    Ok(())
}

/// The measured points of a dataset that can be drawn, and how many there are in all.
struct GlobalPoints {
    /// The drawable points (m, global frame), in the data's order.
    points: Vec<ScenePoint>,
    /// Measured points (positions and poses) in the data.
    total: usize,
    /// Measured points left out: a coordinate or residual not finite or beyond [`LIMIT`].
    unplottable: usize,
}

/// The measured points of `data` and their residuals (m), brought from each posture's
/// measurement frame into the global frame through `calibrated`'s session frames.
fn global_points(nominal: Option<&Robot>, calibrated: &Robot, data: &Dataset) -> GlobalPoints {
    let after = model_points(calibrated, data);
    let before = nominal.map(|r| model_points(r, data));
    let to_global = |posture: usize| -> Option<Frame> {
        let p = data.postures.get(posture)?;
        crate::observe::session_frame(calibrated, p).map(|f| inverse(&f))
    };
    let mut candidates = Vec::new();
    let mut points_total = 0;
    let mut points_unplottable = 0;
    for (i, o) in data.observations.iter().enumerate() {
        let Some((m, model)) = after[i] else {
            continue;
        };
        points_total += 1;
        let posture = o.posture();
        let (m, r, rb) = match to_global(posture) {
            Some(g) => (
                g.rotation * m + g.translation,
                g.rotation * (model - m),
                before
                    .as_ref()
                    .and_then(|b| b[i])
                    .map(|(_, nm)| g.rotation * (nm - m)),
            ),
            None => (
                m,
                model - m,
                before.as_ref().and_then(|b| b[i]).map(|(_, nm)| nm - m),
            ),
        };
        let point = ScenePoint {
            posture,
            target: target_name(calibrated, o.target()).to_string(),
            measured: arr(&m),
            after: arr(&r),
            before: rb.map(|v| arr(&v)),
        };
        if drawable(&point.measured)
            && drawable(&point.after)
            && point.before.as_ref().is_none_or(drawable)
        {
            candidates.push(point);
        } else {
            points_unplottable += 1;
        }
    }
    GlobalPoints {
        points: candidates,
        total: points_total,
        unplottable: points_unplottable,
    }
}

/// At most `max_points` of `candidates` (the largest residuals always, then evenly spread over
/// the rest), in their order; and the posture index of the largest residual, if any.
fn pick_points(candidates: Vec<ScenePoint>, max_points: usize) -> (Vec<ScenePoint>, Option<usize>) {
    let mut order: Vec<usize> = (0..candidates.len()).collect();
    order.sort_by(|&a, &b| {
        candidates[b]
            .error_after()
            .total_cmp(&candidates[a].error_after())
    });
    let largest = (max_points / 20).min(order.len());
    let mut keep = vec![false; candidates.len()];
    for &i in &order[..largest] {
        keep[i] = true;
    }
    let rest: Vec<usize> = (0..candidates.len()).filter(|i| !keep[*i]).collect();
    for k in spread(rest.len(), max_points.saturating_sub(largest)) {
        keep[rest[k]] = true;
    }
    let worst_posture = order.first().map(|&i| candidates[i].posture);
    let points: Vec<ScenePoint> = candidates
        .into_iter()
        .zip(keep)
        .filter_map(|(p, k)| k.then_some(p))
        .collect();
    (points, worst_posture)
}

/// The indices into `data.postures` to draw: the chosen one first, the worst point's, then
/// evenly spread, without repeats (empty without data; an error for a posture not found).
fn choose_postures(
    data: &Dataset,
    options: &SceneOptions,
    worst_posture: Option<usize>,
) -> Result<Vec<usize>> {
    let mut chosen: Vec<usize> = Vec::new();
    if data.postures.is_empty() {
        if options.posture.is_some() {
            return Err(Error::Problem(
                "a posture to draw is named, and there is no data to find it in".into(),
            ));
        }
    } else {
        let first = match &options.posture {
            Some(label) => data
                .postures
                .iter()
                .position(|p| &p.label == label)
                .ok_or_else(|| {
                    Error::Problem(format!("no posture `{label}` in the data to draw"))
                })?,
            None => 0,
        };
        chosen.push(first);
        chosen.extend(worst_posture);
        chosen.extend(spread(data.postures.len(), options.max_postures));
        let mut seen = std::collections::HashSet::new();
        chosen.retain(|p| seen.insert(*p));
        chosen.truncate(options.max_postures.max(1));
    }
    Ok(chosen)
}

/// The robots' skeletons (m, global frame) at the `chosen` postures of `data`, or at zero
/// readings (`home`) when none is chosen; cameras and boards still empty.
fn posture_skeletons(
    nominal: Option<&Robot>,
    calibrated: &Robot,
    data: &Dataset,
    chosen: &[usize],
) -> Result<Vec<ScenePosture>> {
    let mut postures = Vec::new();
    if chosen.is_empty() {
        let zero = vec![0.0; calibrated.dof()];
        postures.push(ScenePosture {
            label: "home".into(),
            index: 0,
            nominal: nominal.map(|r| skeleton(r, &zero, None)).transpose()?,
            calibrated: skeleton(calibrated, &zero, None)?,
            cameras: Vec::new(),
            boards: Vec::new(),
        });
    }
    for &p in chosen {
        let posture = &data.postures[p];
        let payload = posture.payload.as_ref();
        postures.push(ScenePosture {
            label: posture.label.clone(),
            index: p,
            nominal: nominal
                .map(|r| skeleton(r, &posture.readings, payload))
                .transpose()?,
            calibrated: skeleton(calibrated, &posture.readings, payload)?,
            cameras: Vec::new(),
            boards: Vec::new(),
        });
    }
    Ok(postures)
}

/// The reach (m): the largest distance from the global frame's origin to a node of the
/// calibrated robot over `postures`, at least 1 mm.
fn reach_of(postures: &[ScenePosture]) -> f64 {
    postures
        .iter()
        .flat_map(|p| p.calibrated.nodes.iter())
        .map(norm)
        .fold(1e-3, f64::max)
}

/// Fills in each of `postures` the `calibrated` robot's cameras (frustums cut at `depth`, m)
/// and boards with the points seen there; an error when one cannot be drawn.
fn mount_cameras_and_boards(
    calibrated: &Robot,
    data: &Dataset,
    chosen: &[usize],
    depth: f64,
    postures: &mut [ScenePosture],
) -> Result<()> {
    let seen = seen_points(calibrated, data);
    for sp in postures {
        let (readings, payload, seen) = match data.postures.get(sp.index) {
            Some(p) if !chosen.is_empty() => (
                p.readings.clone(),
                p.payload.as_ref(),
                seen[sp.index].as_slice(),
            ),
            _ => (vec![0.0; calibrated.dof()], None, &[][..]),
        };
        let (cameras, boards) = cameras_and_boards(calibrated, &readings, payload, depth, seen);
        let ok = cameras
            .iter()
            .all(|c| frame_drawable(&c.frame) && c.corners.iter().all(drawable))
            && boards
                .iter()
                .all(|b| frame_drawable(&b.frame) && b.corners.iter().all(drawable));
        if !ok {
            return Err(Error::Problem(format!(
                "a camera or board of `{}` is not finite or lies beyond {LIMIT:e} m at \
                 posture {}: it cannot be drawn",
                calibrated.name, sp.label
            )));
        }
        sp.cameras = cameras;
        sp.boards = boards;
    }
    Ok(())
}

/// The frames that do not move with the robot: the global frame, then `calibrated`'s session
/// (measurement) frames in the global frame, those that can be drawn.
fn fixed_frames(calibrated: &Robot) -> Vec<SceneFrame> {
    let mut frames = vec![frame_of(
        "global frame",
        FrameKind::Base,
        &Frame::identity(),
    )];
    for s in &calibrated.sessions {
        let f = inverse(&Frame::from_link(&s.frame));
        let sf = frame_of(&s.name, FrameKind::Measurement, &f);
        if drawable(&sf.origin) && sf.axes.iter().all(drawable) {
            frames.push(sf);
        }
    }
    frames
}

impl Scene {
    /// Whether the scene can be drawn as it is (one read from a file is checked before it is):
    /// a posture to draw, every coordinate finite and within [`LIMIT`], every index of a link
    /// or joint a node, a positive finite scale.
    pub fn check(&self) -> Result<()> {
        let bad = |what: &str| {
            Err(Error::Problem(format!(
                "the 3-D scene of `{}` cannot be drawn: {what}",
                self.robot
            )))
        };
        if self.postures.is_empty() {
            return bad("it has no posture");
        }
        let positive = |x: f64| x.is_finite() && x > 0.0;
        if !positive(self.residual_scale) || !positive(self.reach) || self.reach > LIMIT {
            return bad("its residual scale or reach is not a positive finite number");
        }
        let frame_ok = |f: &SceneFrame| drawable(&f.origin) && f.axes.iter().all(drawable);
        let skeleton_ok = |s: &Skeleton| {
            s.nodes.iter().all(drawable)
                && s.links.iter().flatten().all(|&i| i < s.nodes.len())
                && s.joints
                    .iter()
                    .all(|(i, a)| *i < s.nodes.len() && drawable(a))
                && s.tools.iter().all(frame_ok)
        };
        let mounted_ok = |p: &ScenePosture| {
            p.cameras
                .iter()
                .all(|c| frame_ok(&c.frame) && c.corners.iter().all(drawable))
                && p.boards.iter().all(|b| {
                    frame_ok(&b.frame)
                        && b.corners.iter().all(drawable)
                        && (2..=1_000_000).contains(&(b.cols as u64 * b.rows as u64))
                        && b.cols >= 2
                        && b.rows >= 2
                        && b.seen
                            .iter()
                            .all(|&k| k < b.cols as usize * b.rows as usize)
                })
        };
        if !self.postures.iter().all(|p| {
            skeleton_ok(&p.calibrated)
                && p.nominal.as_ref().is_none_or(skeleton_ok)
                && mounted_ok(p)
        }) {
            return bad(
                "a robot, camera or board has a coordinate beyond 1e6 m or not finite, a link to \
                 no joint, or a board a grid or seen point out of its size",
            );
        }
        if !self.points.iter().all(|p| {
            drawable(&p.measured) && drawable(&p.after) && p.before.as_ref().is_none_or(drawable)
        }) || !self.frames.iter().all(frame_ok)
        {
            return bad("a point, a residual or a frame is beyond 1e6 m or not finite");
        }
        if !positive(self.residual_scale_before) {
            return bad("its residual scale before calibration is not a positive finite number");
        }
        // A residual drawn scaled stays within f32 too.
        let longest = |r: &dyn Fn(&ScenePoint) -> Option<[f64; 3]>| {
            self.points
                .iter()
                .filter_map(r)
                .map(|v| norm(&v))
                .fold(0.0, f64::max)
        };
        if longest(&|p| Some(p.after)) * self.residual_scale > 1e3 * LIMIT
            || longest(&|p| p.before) * self.residual_scale_before > 1e3 * LIMIT
        {
            return bad("a residual drawn at the scene's scale reaches beyond 1e9 m");
        }
        Ok(())
    }
}

fn unit_scale() -> f64 {
    1.0
}

/// The scale of residuals of lengths `errors` (m) in a scene of size `size` (m): the 95th
/// percentile's [`residual_scale`], made smaller (by tens) until the longest, scaled, is within
/// 1e9 m.
fn scale_of(mut errors: Vec<f64>, size: f64) -> f64 {
    errors.sort_by(f64::total_cmp);
    let typical = errors
        .get((errors.len() * 95 / 100).min(errors.len().saturating_sub(1)))
        .copied()
        .unwrap_or(0.0);
    let longest = errors.last().copied().unwrap_or(0.0);
    let mut k = residual_scale(typical, size);
    while k > 1.0 && longest * k > 1e3 * LIMIT {
        k /= 10.0;
    }
    k
}

/// The scale that draws a residual of `typical` metres a twentieth of `size`, rounded down to 1,
/// 2 or 5 times a power of ten, between 1 and 1e9 (1 when there is no residual).
pub fn residual_scale(typical: f64, size: f64) -> f64 {
    if !(typical > 0.0 && typical.is_finite() && size.is_finite() && size > 0.0) {
        return 1.0;
    }
    let want = (size / 20.0 / typical).clamp(1.0, 1e9);
    let p = 10f64.powf(want.log10().floor());
    let m = want / p;
    let step = if m >= 5.0 {
        5.0
    } else if m >= 2.0 {
        2.0
    } else {
        1.0
    };
    (step * p).clamp(1.0, 1e9)
}

#[cfg(test)]
#[allow(clippy::float_cmp)] // exact values: a scale is a round number, a node a link's offset
mod tests {
    use super::*;
    use crate::model::examples;
    use crate::observe::point::Position;
    use crate::observe::{Posture, View};

    fn posture(label: &str, readings: Vec<f64>) -> Posture {
        Posture {
            label: label.into(),
            readings,
            session: None,
            payload: None,
        }
    }

    #[test]
    fn skeleton_ends_at_the_end_effector_of_forward_kinematics() {
        let robot = examples::ge_a4();
        let q = vec![0.1, -0.4, 0.03, 0.7];
        let s = skeleton(&robot, &q, None).unwrap();
        let ee = Chain::new(&robot).frame_at(&q, Target::EndEffector);
        let last = s.nodes[s.links.last().unwrap()[1]];
        for (k, x) in last.iter().enumerate() {
            assert!((x - ee.translation[k]).abs() < 1e-12);
            assert!((s.tools[0].origin[k] - ee.translation[k]).abs() < 1e-12);
        }
        assert_eq!(s.joints.len(), 4);
        // The prismatic joint 3 adds a node: its slide.
        assert_eq!(s.nodes.len(), 1 + 5 + 1);
        assert_eq!(s.nodes[0], [0.0; 3]);
        // Joint 1 at the end of the first link.
        let l1 = &robot.links[0];
        assert_eq!(s.nodes[s.joints[0].0], [l1.x, l1.y, l1.z]);
    }

    #[test]
    fn points_carry_residuals_and_the_largest_are_kept() {
        let robot = examples::ge_a4();
        let mut nominal = robot.clone();
        nominal.links[2].x += 0.002;
        let mut postures = Vec::new();
        let mut obs = Vec::new();
        for i in 0..200 {
            let t = i as f64 * 0.01;
            let q = vec![t, -t, 0.01 * t, 0.3];
            let mut p = Chain::new(&robot)
                .frame_at(&q, Target::EndEffector)
                .translation;
            if i == 123 {
                p.x += 0.01; // the bad reflector
            }
            postures.push(posture(&format!("p{i}"), q));
            obs.push(Observation::from(Position {
                view: [View {
                    posture: i,
                    target: Target::EndEffector,
                }],
                position: p,
                sigma_position: None,
                line: 0,
            }));
        }
        let data = Dataset::new(postures, obs);
        let options = SceneOptions {
            max_points: 40,
            ..Default::default()
        };
        let scene = Scene::new(Some(&nominal), &robot, Some(&data), &options).unwrap();
        assert_eq!(scene.points_total, 200);
        assert_eq!(scene.points.len(), 40);
        let bad = scene.points.iter().find(|p| p.posture == 123).unwrap();
        assert!((bad.after[0] + 0.01).abs() < 1e-12, "{:?}", bad.after);
        assert!(scene.points.iter().all(|p| p.before.is_some()));
        // The worst point's posture is drawn, after the first.
        assert_eq!(scene.postures[0].label, "p0");
        assert_eq!(scene.postures[1].label, "p123");
        assert!(scene.postures.iter().all(|p| p.nominal.is_some()));
        assert!(scene.residual_scale >= 1.0);
    }

    #[test]
    fn far_points_are_left_out_and_a_far_robot_refused() {
        let robot = examples::ge_a4();
        let q = vec![0.0; 4];
        let obs = |x: f64| {
            Observation::from(Position {
                view: [View {
                    posture: 0,
                    target: Target::EndEffector,
                }],
                position: Vector3::new(x, 0.0, 0.0),
                sigma_position: None,
                line: 0,
            })
        };
        let data = Dataset::new(
            vec![posture("a", q.clone())],
            vec![obs(1e308), obs(f64::NAN), obs(0.5)],
        );
        let scene = Scene::new(None, &robot, Some(&data), &SceneOptions::default()).unwrap();
        assert_eq!(scene.points_total, 3);
        assert_eq!(scene.points_unplottable, 2);
        assert_eq!(scene.points.len(), 1);
        let mut far = robot.clone();
        far.links[1].x = 1e308;
        let e = Scene::new(None, &far, Some(&data), &SceneOptions::default()).unwrap_err();
        assert!(e.to_string().contains("cannot be drawn"), "{e}");
    }

    #[test]
    fn a_session_s_points_are_brought_into_the_global_frame() {
        use crate::model::robot::{Link, Session};
        let mut robot = examples::ge_a4();
        let frame = Link {
            x: 2.0,
            y: -1.0,
            z: 0.5,
            alpha: 0.7,
            beta: -0.2,
            gamma: 0.3,
        };
        robot.sessions.push(Session {
            name: "tracker2".into(),
            frame,
        });
        let q = vec![0.2, -0.3, 0.02, 0.5];
        let ee = Chain::new(&robot).frame_at(&q, Target::EndEffector);
        // The instrument of session tracker2 sees the tool at S * p (1 mm off in its x).
        let seen = Frame::from_link(&frame).then(&ee).translation + Vector3::new(0.001, 0.0, 0.0);
        let mut p = posture("a", q);
        p.session = Some("tracker2".into());
        let data = Dataset::new(
            vec![p],
            vec![Observation::from(Position {
                view: [View {
                    posture: 0,
                    target: Target::EndEffector,
                }],
                position: seen,
                sigma_position: None,
                line: 0,
            })],
        );
        let scene = Scene::new(None, &robot, Some(&data), &SceneOptions::default()).unwrap();
        let point = &scene.points[0];
        // In the global frame the measured point is the tool plus the 1 mm error, turned back
        // through the session's rotation; the residual is that error reversed.
        let back = Frame::from_link(&frame).rotation.transpose() * Vector3::new(0.001, 0.0, 0.0);
        for k in 0..3 {
            assert!((point.measured[k] - (ee.translation[k] + back[k])).abs() < 1e-12);
            assert!((point.after[k] + back[k]).abs() < 1e-12);
        }
        // The session's measurement frame is drawn where it is in the global frame.
        let f = scene.frames.iter().find(|f| f.name == "tracker2").unwrap();
        assert_eq!(f.kind, FrameKind::Measurement);
        let origin = inverse(&Frame::from_link(&frame)).translation;
        assert!((0..3).all(|k| (f.origin[k] - origin[k]).abs() < 1e-12));
    }

    #[test]
    fn scale_is_one_two_or_five_times_a_power_of_ten() {
        assert_eq!(residual_scale(1e-5, 1.0), 5000.0);
        assert_eq!(residual_scale(0.0, 1.0), 1.0);
        assert_eq!(residual_scale(f64::NAN, 1.0), 1.0);
        assert_eq!(residual_scale(1.0, 1.0), 1.0);
        assert_eq!(residual_scale(1e-300, 1.0), 1e9);
    }
}
