//! The measurement model: what was observed, and how each kind of observation turns the robot's
//! frames into residuals.
//!
//! An observation looks at one or two *views* (a posture and a target frame: the end effector or
//! a site) and owns everything about its residual rows: how many, what each one is (a length or
//! an angle, and its label), its standard deviation when the file gives one, the residual
//! `model - measured`, the Jacobian rows built from the geometric Jacobians of its views, its
//! error metric for accuracy figures, and what it tells about the robot's placement in the world
//! (for the rank count). Estimation, identifiability, uncertainty, outliers, validation and the
//! reports all go through this interface, so a new instrument is one new file here (and its file
//! format one in [`crate::files`]).
//!
//! The kinds:
//! - [`point::Pose`]: a full pose (position and ZYX Euler angles) of a target, 6 rows;
//! - [`point::Position`]: a position, 3 rows;
//! - [`distance::Distance`]: the distance between a target's positions in two postures (ballbar,
//!   fixed-length artefact), 1 row;
//! - [`contact::Contact`]: a target touching a plane of the robot file, 1 row (its distance from
//!   the plane);
//! - [`pixel::Pixel`]: where a camera of the robot file saw a board's corner or a marker, 2 rows
//!   (the reprojection error in pixels).
//!
//! Values are internal (m, rad). A [`Dataset`] keeps its observations sorted by their first
//! posture so that forward kinematics runs once per posture however many targets it measured.

/// The [`Observe`] methods every kind answers from its fields alone, for a kind's `impl Observe`:
/// `kind` (its name, a string literal), `views` and `views_mut` (its field of views, an array),
/// `rows` (its residual rows, a `&'static [Row]`), and `line` (its `line` field). The residual,
/// its derivatives and the standard deviations stay the kind's own.
macro_rules! observe_fields {
    (kind: $kind:literal, views: $views:ident, rows: $rows:expr) => {
        fn kind(&self) -> &'static str {
            $kind
        }
        fn views(&self) -> &[View] {
            &self.$views
        }
        fn views_mut(&mut self) -> &mut [View] {
            &mut self.$views
        }
        fn rows(&self) -> &'static [Row] {
            $rows
        }
        fn line(&self) -> usize {
            self.line
        }
    };
}

pub mod contact;
pub mod distance;
pub mod pixel;
pub mod point;
pub(crate) mod sanity;
mod trig_cache;

use std::fmt;

use crate::error::{Error, Result};
use crate::model::kinematics::{Chain, Frame, ReadingTrig, Target, Workspace, BATCH};
use crate::model::params::ParamId;
use crate::model::robot::Robot;

/// One posture: a label and one transducer reading per joint.
#[derive(Debug, Clone, PartialEq)]
pub struct Posture {
    /// The posture's label in files (`posture` column).
    pub label: String,
    /// One reading per joint, in transducer units.
    pub readings: Vec<f64>,
    /// The measurement session the posture was measured in (`session` column, or one per
    /// file), when the data has sessions: its poses and positions are in that session's
    /// measurement frame ([`crate::model::robot::Session`]).
    pub session: Option<std::sync::Arc<str>>,
    /// What the tool carried (`payload_mass`, `payload_cx`, ... columns), when the data says:
    /// an elastic robot's joints yield to its weight too.
    pub payload: Option<crate::model::robot::Payload>,
}

/// A frame an observation looks at: a target in a posture.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct View {
    /// Index into [`Dataset::postures`].
    pub posture: usize,
    /// The frame.
    pub target: Target,
}

/// What a residual row measures, which decides its default standard deviation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum RowQuantity {
    /// A length (m).
    Length,
    /// An angle (rad).
    Angle,
    /// A position in an image (pixels).
    Pixel,
}

/// One residual row of a kind: its label (`x`, `alpha`, `distance`, ...) and quantity.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Row {
    /// Short label, e.g. `x` or `distance`.
    pub label: &'static str,
    /// Length or angle.
    pub quantity: RowQuantity,
}

/// The measurement standard deviations that weight residuals without a standard deviation of
/// their own (internal units).
///
/// The objective is `sum (length residual / sigma_L)^2 + (angle residual / sigma_A)^2`, which
/// makes it dimensionless and the same whatever units the files use. Defaults: 1 mm and 1 mrad
/// (0.0573 deg), i.e. an attitude error of 1 mrad counts like a 1 mm error, as it would at the
/// end of a 1 m lever. A row's own standard deviation (`sigma_position`, `sigma_angle` columns)
/// replaces these for that row.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Weights {
    /// Standard deviation of a length residual (m).
    pub length: f64,
    /// Standard deviation of an angle residual (rad).
    pub angle: f64,
}

impl Default for Weights {
    fn default() -> Self {
        Weights {
            length: 1e-3,
            angle: 1e-3,
        }
    }
}

impl Weights {
    /// The standard deviation of a pixel row without one of its own (`sigma_px`): 1 pixel, about
    /// what corner detectors reach on a focused image (0.1-1 px).
    pub const PIXEL: f64 = 1.0;

    /// The default standard deviation of a row of `quantity`.
    pub fn of(&self, quantity: RowQuantity) -> f64 {
        match quantity {
            RowQuantity::Length => self.length,
            RowQuantity::Angle => self.angle,
            RowQuantity::Pixel => Self::PIXEL,
        }
    }
}

/// The standard deviations of the Gaussian noise simulated data gets
/// ([`Observe::add_noise`]): lengths (m), angles (rad) and pixels.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Noise {
    /// Of lengths (m).
    pub length: f64,
    /// Of angles (rad).
    pub angle: f64,
    /// Of pixel coordinates (pixels).
    pub pixel: f64,
}

/// How an orientation residual is formed (in a calibration spec: `euler`, `rotvec`).
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Eq,
    Default,
    serde::Serialize,
    serde::Deserialize,
    schemars::JsonSchema,
)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[non_exhaustive]
pub enum OrientationError {
    /// Differences of the ZYX Euler angles, each wrapped to (-180, 180] deg (thesis eq. 3.1).
    /// Undefined at gimbal lock: refused when a measured attitude is within 1 deg of it.
    Euler,
    /// The rotation vector of `R_measured^T R_model` (its three components, in rad): defined
    /// everywhere, including at beta = +-90 deg where Euler angles lock. The default.
    #[default]
    #[cfg_attr(feature = "clap", value(name = "rotvec"))]
    RotVec,
}

impl OrientationError {
    /// `euler` or `rotvec`.
    pub fn as_str(self) -> &'static str {
        match self {
            OrientationError::Euler => "euler",
            OrientationError::RotVec => "rotvec",
        }
    }
}

/// What observations need besides their views' frames.
#[derive(Debug, Clone, Copy)]
pub struct Context<'a> {
    /// The robot being evaluated (planes, sites).
    pub robot: &'a Robot,
    /// How pose observations form orientation residuals.
    pub orientation: OrientationError,
}

/// The derivatives an observation builds its Jacobian rows from, and where it writes them.
pub struct Derivatives<'b> {
    /// Number of estimated columns `k`.
    pub cols: usize,
    /// Per view: the geometric Jacobian of the view's target over the estimated columns, 6 x k
    /// column-major (entry `(i, c)` at `6 * c + i`): rows 0-2 the origin's derivative (m per
    /// parameter unit), rows 3-5 the angular velocity in the global frame (rad per unit).
    pub blocks: &'b [&'b [f64]],
    /// The estimated column of each parameter (indexed by `ParamId.0`), for parameters that
    /// enter an observation directly (planes).
    pub columns: &'b [Option<usize>],
    /// Where row `i`'s entries start in `out`: every `stride` entries (at least `k`).
    pub stride: usize,
    /// The output: row `i`'s `k` derivatives at `i * stride`, zeroed.
    pub out: &'b mut [f64],
}

impl Derivatives<'_> {
    /// Column `c` of view `v`'s origin derivative.
    #[inline]
    pub fn dp(&self, v: usize, c: usize) -> nalgebra::Vector3<f64> {
        let b = &self.blocks[v][6 * c..6 * c + 3];
        nalgebra::Vector3::new(b[0], b[1], b[2])
    }

    /// Column `c` of view `v`'s angular velocity.
    #[inline]
    pub fn w(&self, v: usize, c: usize) -> nalgebra::Vector3<f64> {
        let b = &self.blocks[v][6 * c + 3..6 * c + 6];
        nalgebra::Vector3::new(b[0], b[1], b[2])
    }

    /// The estimated column of parameter `id`, if estimated.
    #[inline]
    pub fn column(&self, id: ParamId) -> Option<usize> {
        self.columns.get(id.0).copied().flatten()
    }

    /// Sets entry (row, column).
    #[inline]
    pub fn set(&mut self, row: usize, c: usize, v: f64) {
        self.out[row * self.stride + c] = v;
    }
}

/// What an observation tells about where the robot stands in the world, for the rank count.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Anchoring {
    /// Measured in the global frame (a tracker's or camera's coordinates): fixes the placement.
    Absolute,
    /// Invariant under any rigid motion of the world (distances): fixes nothing.
    Relative,
    /// Fixes the placement only across the plane with this index (a contact).
    Plane(usize),
}

/// One observation's error in its own metric, for accuracy figures.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ErrorSample {
    /// The metric: `position` (3D distance, and attitude angle for poses), `distance` (error of
    /// a measured distance), `contact` (distance from the plane), ...
    pub metric: &'static str,
    /// The length error (m, non-negative).
    pub length: f64,
    /// The attitude error (rad, non-negative), for observations of an attitude.
    pub angle: Option<f64>,
}

/// The measurement model of one kind of observation. Object safe: [`Observation`] dereferences
/// to it.
pub trait Observe: fmt::Debug {
    /// The kind's name: `pose`, `position`, `distance`, `contact`.
    fn kind(&self) -> &'static str;
    /// The frames it looks at (one or two).
    fn views(&self) -> &[View];
    /// The same, to renumber postures.
    fn views_mut(&mut self) -> &mut [View];
    /// Its residual rows.
    fn rows(&self) -> &'static [Row];
    /// Row `row`'s own standard deviation (internal units), when the file gives one.
    fn sigma(&self, row: usize) -> Option<f64>;
    /// Appends each row's standard deviation (internal units): its own ([`Observe::sigma`]),
    /// else `weights`' for the row's quantity (one call per observation, not per row).
    fn push_sigmas(&self, weights: Weights, out: &mut Vec<f64>) {
        for (k, row) in self.rows().iter().enumerate() {
            out.push(self.sigma(k).unwrap_or(weights.of(row.quantity)));
        }
    }
    /// The line of the file it came from (0 when synthesized).
    fn line(&self) -> usize;
    /// Residuals `model - measured` (internal units, unweighted) from the frames of its views,
    /// and, when asked, their derivatives.
    fn evaluate(
        &self,
        ctx: &Context<'_>,
        frames: &[Frame],
        residuals: &mut [f64],
        derivatives: Option<&mut Derivatives<'_>>,
    );
    /// Its error in its own metric.
    fn error(&self, ctx: &Context<'_>, frames: &[Frame]) -> ErrorSample;
    /// The target frame whose geometry it measures, and how many of the frame's degrees of
    /// freedom a set of such observations determines (6 for poses, 3 for points).
    fn measured_frame(&self) -> (Target, usize);
    /// What it tells about the robot's placement in the world.
    fn anchoring(&self) -> Anchoring;
    /// Replaces the measured value with the model's (for synthesizing data).
    fn remeasure(&mut self, ctx: &Context<'_>, frames: &[Frame]);
    /// Adds Gaussian noise to the measured value: `unit()` draws a standard normal number,
    /// `noise` holds the standard deviations (internal units).
    fn add_noise(&mut self, unit: &mut dyn FnMut() -> f64, noise: &Noise);
    /// Whether its residual metric is degenerate here (a pose near gimbal lock under Euler
    /// residuals).
    fn degenerate(&self, _ctx: &Context<'_>) -> bool {
        false
    }
    /// A short description for listings: posture label(s), the target, and what it touched.
    fn describe(&self, postures: &[Posture], robot: &Robot) -> String;
    /// The first view's target.
    fn target(&self) -> Target {
        self.views()[0].target
    }
    /// The first view's posture.
    fn posture(&self) -> usize {
        self.views()[0].posture
    }
}

/// The name of a target as files write it: the end effector's name (`ee` unless the robot file
/// names it) or the site's name.
pub fn target_name(robot: &Robot, t: Target) -> &str {
    match t {
        Target::EndEffector => robot.end_effector.as_deref().unwrap_or("ee"),
        Target::Site(s) => &robot.sites[s].name,
    }
}

macro_rules! observation_kinds {
    ($($(#[$doc:meta])* $variant:ident($ty:ty),)*) => {
        /// One observation, of any kind. Dereferences to [`Observe`].
        #[derive(Debug, Clone, PartialEq)]
        pub enum Observation {
            $($(#[$doc])* $variant($ty),)*
        }

        impl std::ops::Deref for Observation {
            type Target = dyn Observe;
            fn deref(&self) -> &(dyn Observe + 'static) {
                match self {
                    $(Observation::$variant(o) => o.observe(),)*
                }
            }
        }

        impl std::ops::DerefMut for Observation {
            fn deref_mut(&mut self) -> &mut (dyn Observe + 'static) {
                match self {
                    $(Observation::$variant(o) => o.observe_mut(),)*
                }
            }
        }

        $(impl From<$ty> for Observation {
            fn from(o: $ty) -> Self {
                Observation::$variant(o)
            }
        })*
    };
}

/// How a kind of observation is held in an [`Observation`]: in place, or boxed.
trait Held {
    fn observe(&self) -> &(dyn Observe + 'static);
    fn observe_mut(&mut self) -> &mut (dyn Observe + 'static);
}

impl<T: Observe + 'static> Held for Box<T> {
    fn observe(&self) -> &(dyn Observe + 'static) {
        &**self
    }
    fn observe_mut(&mut self) -> &mut (dyn Observe + 'static) {
        &mut **self
    }
}

macro_rules! held_in_place {
    ($($ty:ty),*) => {
        $(impl Held for $ty {
            fn observe(&self) -> &(dyn Observe + 'static) {
                self
            }
            fn observe_mut(&mut self) -> &mut (dyn Observe + 'static) {
                self
            }
        })*
    };
}
held_in_place!(point::Position, distance::Distance, contact::Contact);

// The kinds of observation. A new kind: a file in this folder implementing `Observe`, a line
// here, and its file format in `crate::files::FORMATS`. Kinds larger than a position are
// boxed, so that an observation takes 96 bytes, a file of positions (the common case) is
// looped over in steps of that size: 224 bytes in place cost a tenth of a 10,000-position
// calibration's CPU (`docs/verification.md`).
observation_kinds! {
    /// A full pose (boxed: `point::Pose::into()` makes one).
    Pose(Box<point::Pose>),
    /// A position.
    Position(point::Position),
    /// A distance between two postures' positions of a target.
    Distance(distance::Distance),
    /// A target touching a plane.
    Contact(contact::Contact),
    /// A camera's pixel of a point (boxed: `pixel::Pixel::into()` makes one).
    Pixel(Box<pixel::Pixel>),
}

impl From<point::Pose> for Observation {
    fn from(o: point::Pose) -> Self {
        Observation::Pose(Box::new(o))
    }
}

impl From<pixel::Pixel> for Observation {
    fn from(o: pixel::Pixel) -> Self {
        Observation::Pixel(Box::new(o))
    }
}

/// A set of postures and the observations made in them.
#[derive(Debug, Clone, Default)]
pub struct Dataset {
    /// The postures.
    pub postures: Vec<Posture>,
    /// The observations, sorted by their first posture.
    pub observations: Vec<Observation>,
    /// The sines and cosines of the readings, made on first use by a pass of forward
    /// kinematics and shared by the passes after it ([`Dataset::reading_trig`]).
    trig: trig_cache::TrigCache,
}

/// Datasets are equal when their postures and observations are (the kept tables are not
/// data).
impl PartialEq for Dataset {
    fn eq(&self, other: &Self) -> bool {
        self.postures == other.postures && self.observations == other.observations
    }
}

/// The robust spread of residual rows, taken per group of rows *alike*: the same kind of
/// observation and the same quantity (lengths apart from angles), as 1.4826 times the median
/// absolute value (the MAD about zero, the standard deviation for Gaussian rows; a few bad rows
/// cannot inflate it). `r` holds the weighted residuals of `data`'s rows in order (in standard
/// deviations); the spread is in the same units, floored at 1e-6 so that noise-free data has a
/// positive one.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct RobustSpread {
    /// The spread of each row's group, per row.
    pub(crate) per_row: Vec<f64>,
    /// Each group (observation kind, quantity) with its spread and row count, in order of first
    /// appearance.
    pub groups: Vec<(&'static str, RowQuantity, f64, usize)>,
}

impl RobustSpread {
    /// The spread of the rows of `data` whose weighted residuals are `r`.
    pub fn of(data: &Dataset, r: &[f64]) -> RobustSpread {
        let mut keys: Vec<(&'static str, RowQuantity)> = Vec::new();
        let mut values: Vec<Vec<f64>> = Vec::new();
        let mut group_of = Vec::with_capacity(r.len());
        let mut row = 0;
        for o in &data.observations {
            for spec in o.rows() {
                let key = (o.kind(), spec.quantity);
                let g = keys.iter().position(|k| *k == key).unwrap_or_else(|| {
                    keys.push(key);
                    values.push(Vec::new());
                    keys.len() - 1
                });
                values[g].push(r[row].abs());
                group_of.push(g);
                row += 1;
            }
        }
        let spread: Vec<f64> = values
            .iter_mut()
            .map(|v| {
                // The median: the element a sort would put in the middle, found in linear time.
                let mid = v.len() / 2;
                let (_, median, _) = v.select_nth_unstable_by(mid, f64::total_cmp);
                (1.4826 * *median).max(1e-6)
            })
            .collect();
        RobustSpread {
            per_row: group_of.iter().map(|&g| spread[g]).collect(),
            groups: keys
                .iter()
                .zip(&spread)
                .zip(&values)
                .map(|((&(k, q), &s), v)| (k, q, s, v.len()))
                .collect(),
        }
    }
}

impl Dataset {
    /// Builds a dataset, sorting observations by their first posture (stable: file order within
    /// a posture).
    pub fn new(postures: Vec<Posture>, mut observations: Vec<Observation>) -> Self {
        // Files list a posture's rows together: most arrive sorted, and are left as they are.
        if !observations.is_sorted_by_key(|o| o.posture()) {
            observations.sort_by_key(|o| o.posture());
        }
        Dataset {
            postures,
            observations,
            trig: Default::default(),
        }
    }

    /// The sines and cosines of the reading parts of `robot`'s joint angles at every posture
    /// (a table for its slopes and couplings; see [`crate::model::kinematics::ReadingTrig`]),
    /// made once and kept: the passes of forward kinematics over these postures share it.
    pub(crate) fn reading_trig(
        &self,
        robot: &Robot,
    ) -> std::sync::Arc<crate::model::kinematics::ReadingTrig> {
        self.trig.get(robot, &self.postures)
    }

    /// Total residual rows.
    pub fn rows(&self) -> usize {
        self.observations.iter().map(|o| o.rows().len()).sum()
    }

    /// Whether there is no observation.
    pub fn is_empty(&self) -> bool {
        self.observations.is_empty()
    }

    /// The degrees of freedom of each frame its observations determine
    /// ([`Observe::measured_frame`]), as a function of the frame: 6 when a pose of it is
    /// measured, 3 when only its origin is (positions, distances, contacts), 0 when no
    /// observation sees it. One pass over the observations.
    pub fn observed_dofs(&self) -> impl Fn(Target) -> usize {
        let mut seen: Vec<(Target, usize)> = Vec::new();
        for o in &self.observations {
            let (t, dof) = o.measured_frame();
            match seen.iter_mut().find(|(u, _)| *u == t) {
                Some(e) => e.1 = e.1.max(dof),
                None => seen.push((t, dof)),
            }
        }
        move |t| seen.iter().find(|(u, _)| *u == t).map_or(0, |e| e.1)
    }

    /// The observations of each kind: `(kind, count)` in order of first appearance.
    pub fn kinds(&self) -> Vec<(&'static str, usize)> {
        let mut out: Vec<(&'static str, usize)> = Vec::new();
        for o in &self.observations {
            match out.iter_mut().find(|(k, _)| *k == o.kind()) {
                Some(e) => e.1 += 1,
                None => out.push((o.kind(), 1)),
            }
        }
        out
    }

    /// This dataset followed by `other`'s postures and observations (renumbered).
    pub fn merge(mut self, other: Dataset) -> Dataset {
        if self.postures.is_empty() && self.observations.is_empty() {
            return Dataset::new(other.postures, other.observations);
        }
        let shift = self.postures.len();
        self.postures.extend(other.postures);
        for mut o in other.observations {
            for v in o.views_mut() {
                v.posture += shift;
            }
            self.observations.push(o);
        }
        Dataset::new(self.postures, self.observations)
    }

    /// The measurement sessions of the postures, in the order they first appear (postures
    /// without a session aside).
    pub fn sessions(&self) -> Vec<std::sync::Arc<str>> {
        let mut out: Vec<std::sync::Arc<str>> = Vec::new();
        for p in &self.postures {
            if let Some(s) = &p.session {
                if !out.contains(s) {
                    out.push(s.clone());
                }
            }
        }
        out
    }

    /// Puts every posture without a session into session `name` (one session per file).
    pub fn set_session(&mut self, name: &str) {
        let name: std::sync::Arc<str> = name.into();
        for p in &mut self.postures {
            if p.session.is_none() {
                p.session = Some(name.clone());
            }
        }
    }

    /// Groups of postures that must stay together when data is split (postures linked by an
    /// observation, such as the two ends of a distance), in order of their first posture.
    pub(crate) fn posture_groups(&self) -> Vec<Vec<usize>> {
        let (group_of, count) = self.posture_group_of();
        let mut groups: Vec<Vec<usize>> = vec![Vec::new(); count];
        for (p, &g) in group_of.iter().enumerate() {
            groups[g].push(p);
        }
        groups
    }

    /// The groups of [`Dataset::posture_groups`] as each posture's group (numbered in the
    /// same order), and their number: no list per group.
    pub(crate) fn posture_group_of(&self) -> (Vec<usize>, usize) {
        let n = self.postures.len();
        let mut parent: Vec<usize> = (0..n).collect();
        fn root(parent: &mut [usize], mut i: usize) -> usize {
            while parent[i] != i {
                parent[i] = parent[parent[i]];
                i = parent[i];
            }
            i
        }
        for o in &self.observations {
            let v = o.views();
            for w in &v[1..] {
                let (a, b) = (
                    root(&mut parent, v[0].posture),
                    root(&mut parent, w.posture),
                );
                if a != b {
                    parent[a.max(b)] = a.min(b);
                }
            }
        }
        let mut index = vec![usize::MAX; n];
        let mut group_of = vec![0; n];
        let mut count = 0;
        for (p, g) in group_of.iter_mut().enumerate() {
            let r = root(&mut parent, p);
            if index[r] == usize::MAX {
                index[r] = count;
                count += 1;
            }
            *g = index[r];
        }
        (group_of, count)
    }

    /// The postures for which `keep` is true and the observations all of whose postures are
    /// kept, renumbered.
    pub fn subset(&self, keep: &[bool]) -> Dataset {
        let mut map = vec![usize::MAX; self.postures.len()];
        let mut postures = Vec::new();
        for (i, p) in self.postures.iter().enumerate() {
            if keep[i] {
                map[i] = postures.len();
                postures.push(p.clone());
            }
        }
        let observations = self
            .observations
            .iter()
            .filter(|o| o.views().iter().all(|v| keep[v.posture]))
            .map(|o| {
                let mut o = o.clone();
                for v in o.views_mut() {
                    v.posture = map[v.posture];
                }
                o
            })
            .collect();
        Dataset::new(postures, observations)
    }

    /// Splits by posture groups: a fraction `holdout` of the groups (at least one, drawn with
    /// `seed`) and their observations go to the second dataset. Returns (identification, held
    /// out).
    pub fn split(&self, holdout: f64, seed: u64) -> (Dataset, Dataset) {
        use rand::{seq::SliceRandom, SeedableRng};
        let groups = self.posture_groups();
        let n = groups.len();
        let k = ((holdout * n as f64).round() as usize).clamp(1, n);
        let mut order: Vec<usize> = (0..n).collect();
        order.shuffle(&mut rand_chacha::ChaCha8Rng::seed_from_u64(seed));
        let mut held = vec![false; self.postures.len()];
        for &g in &order[..k] {
            for &p in &groups[g] {
                held[p] = true;
            }
        }
        let kept: Vec<bool> = held.iter().map(|h| !h).collect();
        (self.subset(&kept), self.subset(&held))
    }

    /// `k` folds by posture group (postures an observation links stay together; every target
    /// of a posture with it): group `g`, in posture order, goes to fold `g mod k`, so that each
    /// fold samples the whole file (every sweep of single-joint sweeps), or, with a `seed`, to
    /// the fold of its place in a shuffled order. Returns (training, held-out) per fold; `None`
    /// when `k` is below 2 or above the number of groups.
    pub fn folds(&self, k: usize, seed: Option<u64>) -> Option<Vec<(Dataset, Dataset)>> {
        use rand::{seq::SliceRandom, SeedableRng};
        let groups = self.posture_groups();
        if k < 2 || k > groups.len() {
            return None;
        }
        let mut order: Vec<usize> = (0..groups.len()).collect();
        if let Some(seed) = seed {
            order.shuffle(&mut rand_chacha::ChaCha8Rng::seed_from_u64(seed));
        }
        let mut fold_of = vec![0; self.postures.len()];
        for (place, &g) in order.iter().enumerate() {
            for &p in &groups[g] {
                fold_of[p] = place % k;
            }
        }
        Some(
            (0..k)
                .map(|f| {
                    let held: Vec<bool> = fold_of.iter().map(|&x| x == f).collect();
                    let kept: Vec<bool> = held.iter().map(|h| !h).collect();
                    (self.subset(&kept), self.subset(&held))
                })
                .collect(),
        )
    }

    /// The observations whose residual metric is degenerate (poses near gimbal lock under Euler
    /// residuals).
    pub(crate) fn degenerate(&self, ctx: &Context<'_>) -> Vec<&Observation> {
        self.observations
            .iter()
            .filter(|o| o.degenerate(ctx))
            .collect()
    }

    /// Refuses `orientation` when it is undefined at some measured attitude
    /// ([`Error::EulerNearGimbalLock`]: Euler residuals within 1 deg of gimbal lock).
    pub(crate) fn check_orientation(
        &self,
        robot: &Robot,
        orientation: OrientationError,
    ) -> Result<()> {
        let near = self.degenerate(&Context { robot, orientation });
        if near.is_empty() {
            return Ok(());
        }
        Err(Error::EulerNearGimbalLock {
            count: near.len(),
            lines: near.iter().take(5).map(|o| o.line()).collect(),
        })
    }
}

/// Unweighted accuracy of a robot on a dataset (internal units), per metric.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Accuracy {
    /// Observations with the `position` metric (poses and positions).
    pub positions: usize,
    /// Root mean square of the 3D position errors (m).
    pub rms_position: f64,
    /// Mean 3D position error (m).
    pub mean_position: f64,
    /// 95th percentile of the 3D position errors (m; nearest rank).
    pub p95_position: f64,
    /// Largest 3D position error (m).
    pub max_position: f64,
    /// Observations with an attitude (poses).
    pub orientations: usize,
    /// Root mean square of the attitude errors (rad): the angle of `R_measured^T R_model`.
    pub rms_orientation: f64,
    /// Mean attitude error (rad).
    pub mean_orientation: f64,
    /// 95th percentile of the attitude errors (rad).
    pub p95_orientation: f64,
    /// Largest attitude error (rad).
    pub max_orientation: f64,
    /// The other metrics (`distance`, `contact`, ...), in order of first appearance.
    pub other: Vec<MetricAccuracy>,
}

/// Length errors of one metric other than `position`.
#[derive(Debug, Clone, PartialEq)]
pub struct MetricAccuracy {
    /// The metric's name.
    pub metric: &'static str,
    /// Observations.
    pub count: usize,
    /// Root mean square (m).
    pub rms: f64,
    /// Mean (m).
    pub mean: f64,
    /// 95th percentile (m; nearest rank).
    pub p95: f64,
    /// Largest (m).
    pub max: f64,
}

impl MetricAccuracy {
    /// The figures of `metric` over its length errors `e` (m, non-negative), as [`stats`]
    /// gives them.
    pub fn of_errors(metric: &'static str, e: Vec<f64>) -> Self {
        let count = e.len();
        let (rms, mean, p95, max) = stats(e);
        MetricAccuracy {
            metric,
            count,
            rms,
            mean,
            p95,
            max,
        }
    }
}

/// RMS, mean, 95th percentile (nearest rank) and max of non-negative errors. The sums run in
/// the errors' order; the percentile and the max are the elements a sort by
/// [`f64::total_cmp`] would put at their ranks, found in linear time (a sort of 10,000 errors
/// cost a 10,000-pose calibration about 1 % of its CPU, four times over).
pub fn stats(mut e: Vec<f64>) -> (f64, f64, f64, f64) {
    let Some(&first) = e.first() else {
        return (0.0, 0.0, 0.0, 0.0);
    };
    let n = e.len() as f64;
    let rms = (e.iter().map(|x| x * x).sum::<f64>() / n).sqrt();
    let mean = e.iter().sum::<f64>() / n;
    let max = e
        .iter()
        .copied()
        .fold(first, |m, x| if x.total_cmp(&m).is_gt() { x } else { m });
    let rank = ((0.95 * n).ceil() as usize).clamp(1, e.len());
    let (_, p95, _) = e.select_nth_unstable_by(rank - 1, f64::total_cmp);
    (rms, mean, *p95, max)
}

/// The measurement frame `posture`'s poses and positions are in, when its session has a frame
/// of its own in `robot` ([`crate::model::robot::Session`]): the pose of the global frame there.
pub(crate) fn session_frame(robot: &Robot, posture: &Posture) -> Option<Frame> {
    let name = posture.session.as_deref()?;
    let s = robot.sessions.iter().find(|s| s.name == name)?;
    Some(Frame::from_link(&s.frame))
}

/// The frames of `o`'s views for `robot` as its instrument sees them: each view's target frame,
/// seen through the view's session frame when `o` is measured in one (a pose or a position).
pub(crate) fn observed_frame(
    robot: &Robot,
    data: &Dataset,
    o: &Observation,
    view: View,
    frame: Frame,
) -> Frame {
    if !matches!(o.anchoring(), Anchoring::Absolute) || robot.sessions.is_empty() {
        return frame;
    }
    match session_frame(robot, &data.postures[view.posture]) {
        Some(t) => t.then(&frame),
        None => frame,
    }
}

/// Evaluates `f` on every observation of `data` with the frames of its views for `robot` (as
/// [`observed_frame`] gives them), running forward kinematics once per posture.
pub(crate) fn for_each_observation(
    robot: &Robot,
    data: &Dataset,
    mut f: impl FnMut(usize, &Observation, &[Frame]),
) {
    let chain = crate::model::kinematics::Chain::new(robot);
    let mut cache = FrameCache::new(robot);
    let trig = data.reading_trig(robot);
    let mut frames = [Frame::identity(); 2];
    for (i, o) in data.observations.iter().enumerate() {
        let views = o.views();
        for (k, v) in views.iter().enumerate() {
            let ws = cache.posture_with(&chain, data, v.posture, Some(&trig));
            let at = chain.target_frame(ws, v.target);
            frames[k] = observed_frame(robot, data, o, *v, at);
        }
        f(i, o, &frames[..views.len()]);
    }
}

/// Two groups of workspaces holding the frames of the postures of the last two misses, the group
/// used last kept by the next miss: observations sorted by posture reuse them, and a distance's
/// second posture does not evict its first. A rigid serial robot whose passes walk the postures in
/// order fills a group with the posture missed and the next [`BATCH`]` - 1` at once
/// ([`Chain::forward_batch`]), so that the next calls find theirs; otherwise (a tree, an elastic
/// robot, a jump, the last postures) a group holds the one posture missed.
pub(crate) struct FrameCache {
    ws: [[Workspace; BATCH]; 2],
    /// The posture each workspace holds (`usize::MAX`: none).
    at: [[usize; BATCH]; 2],
    /// The group the next miss fills.
    next: usize,
}

impl FrameCache {
    pub fn new(robot: &Robot) -> Self {
        let group = || std::array::from_fn(|_| Workspace::new(robot));
        FrameCache {
            ws: [group(), group()],
            at: [[usize::MAX; BATCH]; 2],
            next: 0,
        }
    }

    /// The group and slot holding `posture`'s frames.
    fn find(&self, posture: usize) -> Option<(usize, usize)> {
        (0..2).find_map(|g| {
            let s = self.at[g].iter().position(|&p| p == posture)?;
            Some((g, s))
        })
    }

    /// The workspace holding `posture`'s frames, computing them if needed, with the reading
    /// parts of the joint angles' sines and cosines known when `trig` is given (a table that
    /// fits the chain's robot: [`Dataset::reading_trig`]).
    pub(crate) fn posture_with(
        &mut self,
        chain: &Chain<'_>,
        data: &Dataset,
        posture: usize,
        trig: Option<&ReadingTrig>,
    ) -> &Workspace {
        if let Some((g, s)) = self.find(posture) {
            // The group used last is not the one the next miss fills.
            self.next = 1 - g;
            return &self.ws[g][s];
        }
        // In order: the first posture, or the one after a posture held.
        let in_order = posture == 0 || self.find(posture - 1).is_some();
        let batched = in_order
            && chain.is_serial()
            && chain.robot().elastic.is_none()
            && posture + BATCH <= data.postures.len();
        let g = self.next;
        self.next = 1 - g;
        self.at[g] = [usize::MAX; BATCH];
        if batched {
            let readings = std::array::from_fn(|k| data.postures[posture + k].readings.as_slice());
            let rows = trig.map(|t| std::array::from_fn(|k| t.posture(posture + k)));
            chain.forward_batch(readings, rows, &mut self.ws[g]);
            self.at[g] = std::array::from_fn(|k| posture + k);
        } else {
            let p = &data.postures[posture];
            chain.forward_loaded(
                &p.readings,
                trig.map(|t| t.posture(posture)),
                p.payload.as_ref(),
                &mut self.ws[g][0],
            );
            self.at[g][0] = posture;
        }
        &self.ws[g][0]
    }
}

/// The error of every observation of `data` for `robot`, in order.
pub fn errors(robot: &Robot, data: &Dataset) -> Vec<ErrorSample> {
    let ctx = Context {
        robot,
        orientation: OrientationError::default(),
    };
    let mut out = Vec::with_capacity(data.observations.len());
    for_each_observation(robot, data, |_, o, frames| out.push(o.error(&ctx, frames)));
    out
}

/// How far `robot`'s predictions are from the observations in `data`. (Error metrics do not
/// depend on how residuals are formed.)
pub fn accuracy(robot: &Robot, data: &Dataset) -> Accuracy {
    let ctx = Context {
        robot,
        orientation: OrientationError::default(),
    };
    let mut acc = AccuracyTally::for_observations(data.observations.len());
    for_each_observation(robot, data, |_, o, frames| acc.push(o.error(&ctx, frames)));
    acc.finish()
}

/// Errors gathered one observation at a time, summarised as an [`Accuracy`].
#[derive(Default)]
pub(crate) struct AccuracyTally {
    positions: Vec<f64>,
    orientations: Vec<f64>,
    other: Vec<(&'static str, Vec<f64>)>,
    /// Every observation's error, in order.
    samples: Vec<ErrorSample>,
}

/// Each observation's error at one robot, kept from the pass of forward kinematics that
/// computed them for the accuracy figures, so that the report's chart of errors reuses them
/// instead of another pass. They are used only for the same robot, bit for bit, and as many
/// observations ([`KeptErrors::for_robot`]).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct KeptErrors {
    robot: Robot,
    /// Shared: a linearisation and the fits that start from it hold the same errors.
    samples: std::sync::Arc<Vec<ErrorSample>>,
}

impl KeptErrors {
    pub(crate) fn new(robot: &Robot, samples: Vec<ErrorSample>) -> Self {
        KeptErrors {
            robot: robot.clone(),
            samples: std::sync::Arc::new(samples),
        }
    }

    /// The errors, when they were computed for `robot` over `observations` observations.
    pub(crate) fn for_robot(&self, robot: &Robot, observations: usize) -> Option<&[ErrorSample]> {
        (self.robot == *robot && self.samples.len() == observations)
            .then_some(self.samples.as_slice())
    }
}

impl AccuracyTally {
    /// An empty tally with room for `observations` errors (and as many positions): a pass
    /// over the data grows no list, copying what it holds, as it goes.
    pub(crate) fn for_observations(observations: usize) -> Self {
        AccuracyTally {
            positions: Vec::with_capacity(observations),
            samples: Vec::with_capacity(observations),
            ..Default::default()
        }
    }

    pub(crate) fn push(&mut self, e: ErrorSample) {
        self.samples.push(e);
        if e.metric == "position" {
            self.positions.push(e.length);
            if let Some(a) = e.angle {
                self.orientations.push(a);
            }
        } else {
            match self.other.iter_mut().find(|(m, _)| *m == e.metric) {
                Some(g) => g.1.push(e.length),
                None => self.other.push((e.metric, vec![e.length])),
            }
        }
    }

    pub(crate) fn finish(self) -> Accuracy {
        self.finish_keeping().0
    }

    /// [`AccuracyTally::finish`], with every observation's error in order.
    pub(crate) fn finish_keeping(self) -> (Accuracy, Vec<ErrorSample>) {
        let (positions, orientations) = (self.positions.len(), self.orientations.len());
        let (rms_position, mean_position, p95_position, max_position) = stats(self.positions);
        let (rms_orientation, mean_orientation, p95_orientation, max_orientation) =
            stats(self.orientations);
        let accuracy = Accuracy {
            positions,
            rms_position,
            mean_position,
            p95_position,
            max_position,
            orientations,
            rms_orientation,
            mean_orientation,
            p95_orientation,
            max_orientation,
            other: self
                .other
                .into_iter()
                .map(|(metric, e)| MetricAccuracy::of_errors(metric, e))
                .collect(),
        };
        (accuracy, self.samples)
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector3;

    use super::{Dataset, FrameCache, Observation, Posture, BATCH};
    use crate::model::kinematics::{Chain, Workspace};
    use crate::model::robot::{Body, Coupling, Elastic, Joint, JointKind, Link, Robot};

    /// An observation is no larger than a position and its tag: the kinds larger than that
    /// are boxed (a file of positions is looped over in steps of this size).
    #[test]
    fn an_observation_is_the_size_of_a_position() {
        let position = std::mem::size_of::<super::point::Position>();
        assert!(position <= 88, "a position takes {position} bytes");
        let size = std::mem::size_of::<Observation>();
        assert!(size <= position + 8, "an observation takes {size} bytes");
    }

    /// A 7-joint arm with a prismatic joint, slopes other than 1 and a coupling: serial,
    /// or with its sixth joint hung after the third (a tree), or elastic.
    fn arm(shape: &str) -> Robot {
        let link = |i: usize| {
            let x = i as f64;
            Link {
                x: 0.1 * x,
                y: 0.05 - 0.02 * x,
                z: 0.3,
                alpha: 0.4 * x - 1.0,
                beta: 0.1 * x - 0.3,
                gamma: 1.2 - 0.3 * x,
            }
        };
        let mut joints: Vec<Joint> = (0..7)
            .map(|j| {
                let kind = if j == 2 {
                    JointKind::Prismatic
                } else {
                    JointKind::Revolute
                };
                Joint::new(kind, 0.3 * j as f64 - 0.5, 1.0 - 0.15 * j as f64)
            })
            .collect();
        joints[6].coupling = Some(Coupling {
            joint: 4,
            factor: -0.7,
        });
        let mut robot = Robot {
            name: shape.into(),
            units: Default::default(),
            links: (0..8).map(link).collect(),
            joints,
            sites: Vec::new(),
            planes: Vec::new(),
            sessions: Vec::new(),
            tolerances: Default::default(),
            priors: Default::default(),
            elastic: None,
            end_effector: None,
            cameras: Vec::new(),
            boards: Vec::new(),
        };
        match shape {
            "tree" => robot.joints[5].parent = Some(2),
            "elastic" => {
                let bodies = (1..=7)
                    .map(|joint| Body {
                        joint,
                        mass: 2.0,
                        com: Vector3::new(0.1, 0.0, 0.05),
                    })
                    .collect();
                let mut model = Elastic::new(&robot, bodies);
                for j in &mut model.joints {
                    j.compliance = 2e-4;
                    j.lateral = 1e-4;
                }
                robot.elastic = Some(model);
            }
            _ => {}
        }
        robot
    }

    /// The cache against one fresh pass per posture, every frame to the bit (a workspace's
    /// `Debug` text writes each number as the shortest text that reads back to it), over 11
    /// postures (not a multiple of [`BATCH`]) visited in order, by pairs as distances visit
    /// them, backwards and by jumps; and a distance's first posture is still held after its
    /// second. A serial rigid arm visited in order has the next postures computed with the
    /// first.
    /// The statistics against their definition on a sorted copy: the percentile and the max
    /// to the bit (the same elements), the sums within the rounding of `n` additions in
    /// another order (`n` times the unit roundoff, relative: all terms are non-negative).
    #[test]
    fn stats_are_those_of_the_sorted_errors() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        for n in (1..40).chain([97, 1000, 4321]) {
            // Ties too: a fifth of the errors repeat an earlier one.
            let mut e: Vec<f64> = Vec::with_capacity(n);
            for i in 0..n {
                let x = if i > 0 && rng.random::<f64>() < 0.2 {
                    e[rng.random_range(0..i)]
                } else {
                    rng.random::<f64>() * 10f64.powi(rng.random_range(-3..3))
                };
                e.push(x);
            }
            let mut sorted = e.clone();
            sorted.sort_by(f64::total_cmp);
            let rank = ((0.95 * n as f64).ceil() as usize).clamp(1, n);
            let rms = (sorted.iter().map(|x| x * x).sum::<f64>() / n as f64).sqrt();
            let mean = sorted.iter().sum::<f64>() / n as f64;
            let (r, m, p95, max) = super::stats(e);
            assert_eq!(p95.to_bits(), sorted[rank - 1].to_bits(), "n = {n}");
            assert_eq!(max.to_bits(), sorted[n - 1].to_bits(), "n = {n}");
            let tol = n as f64 * f64::EPSILON;
            assert!((r - rms).abs() <= tol * rms, "n = {n}: {r} against {rms}");
            assert!(
                (m - mean).abs() <= tol * mean,
                "n = {n}: {m} against {mean}"
            );
        }
        assert_eq!(super::stats(Vec::new()), (0.0, 0.0, 0.0, 0.0));
    }

    #[test]
    fn the_frame_cache_holds_what_one_pass_per_posture_gives() {
        let postures: Vec<Posture> = (0..11)
            .map(|p| Posture {
                label: p.to_string(),
                readings: (0..7)
                    .map(|j| ((p * 7 + j) as f64 * 1.37).sin() * 2.5)
                    .collect(),
                session: None,
                payload: None,
            })
            .collect();
        let data = Dataset::new(postures, Vec::new());
        let in_order: Vec<usize> = (0..11).collect();
        let pairs: Vec<usize> = (0..10).flat_map(|p| [p, p + 1]).collect();
        let far_pairs: Vec<usize> = (0..6).flat_map(|p| [p, p + 5]).collect();
        let backwards: Vec<usize> = (0..11).rev().collect();
        let jumps = vec![3, 9, 4, 10, 0, 7, 1, 8, 2, 6, 5, 10, 9];
        for shape in ["serial", "tree", "elastic"] {
            let robot = arm(shape);
            let chain = Chain::new(&robot);
            let trig = data.reading_trig(&robot);
            let mut fresh = Workspace::new(&robot);
            for table in [None, Some(&*trig)] {
                for (name, order) in [
                    ("in order", &in_order),
                    ("pairs", &pairs),
                    ("far pairs", &far_pairs),
                    ("backwards", &backwards),
                    ("jumps", &jumps),
                ] {
                    let mut cache = FrameCache::new(&robot);
                    for (i, &p) in order.iter().enumerate() {
                        let what = format!("{shape}, {name}, call {i}, posture {p}");
                        let held = format!("{:?}", cache.posture_with(&chain, &data, p, table));
                        chain.forward_with(
                            &data.postures[p].readings,
                            table.map(|t| t.posture(p)),
                            &mut fresh,
                        );
                        assert_eq!(held, format!("{fresh:?}"), "{what}");
                        if name.contains("pairs") && i % 2 == 1 {
                            assert!(cache.find(order[i - 1]).is_some(), "{what}: first kept");
                        }
                        if shape == "serial" && name == "in order" && p + BATCH <= 11 {
                            let last = p / BATCH * BATCH + BATCH - 1;
                            assert!(cache.find(last).is_some(), "{what}: batch");
                        }
                    }
                }
            }
        }
    }
}
