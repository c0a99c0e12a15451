//! Distances between a target's positions in two postures: a ballbar or telescoping bar between
//! the tool and a fixed pivot moved through two postures, or a fixed-length artefact touched at
//! both ends. No instrument coordinates are involved, so such data says nothing about where the
//! robot stands in the world: the six degrees of freedom of its placement are not determined
//! (see the rank count in [`crate::identifiability`]).
//!
//! Their file, the distance file, is read in [`crate::files`].

use super::{
    target_name, Anchoring, Context, Derivatives, ErrorSample, Noise, Observe, Posture, Row,
    RowQuantity, View,
};
use crate::model::kinematics::{Frame, Target};
use crate::model::robot::Robot;

const ROWS: &[Row] = &[Row {
    label: "distance",
    quantity: RowQuantity::Length,
}];

/// The measured distance between the origins of a target in two postures. One residual row:
/// `|p_a - p_b| - distance` (m).
#[derive(Debug, Clone, PartialEq)]
pub struct Distance {
    /// The two views (same target, two postures).
    pub views: [View; 2],
    /// The measured distance (m).
    pub distance: f64,
    /// The row's own standard deviation (m), if given.
    pub sigma: Option<f64>,
    /// Line in the file (0 when synthesized).
    pub line: usize,
}

impl Distance {
    /// The distance between `target`'s origins in postures `a` and `b`.
    pub fn new(a: usize, b: usize, target: Target, distance: f64) -> Self {
        Distance {
            views: [View { posture: a, target }, View { posture: b, target }],
            distance,
            sigma: None,
            line: 0,
        }
    }
}

impl Observe for Distance {
    observe_fields!(kind: "distance", views: views, rows: ROWS);
    fn sigma(&self, _row: usize) -> Option<f64> {
        self.sigma
    }

    fn evaluate(
        &self,
        _ctx: &Context<'_>,
        frames: &[Frame],
        res: &mut [f64],
        derivatives: Option<&mut Derivatives<'_>>,
    ) {
        let d = frames[0].translation - frames[1].translation;
        let len = d.norm();
        res[0] = len - self.distance;
        if let Some(der) = derivatives {
            // d|d|/dp = u . (dp_a - dp_b), u the unit vector from b to a (zero when they meet).
            let u = if len > 0.0 { d / len } else { d };
            for c in 0..der.cols {
                let v = u.dot(&(der.dp(0, c) - der.dp(1, c)));
                der.set(0, c, v);
            }
        }
    }

    fn error(&self, _ctx: &Context<'_>, frames: &[Frame]) -> ErrorSample {
        ErrorSample {
            metric: "distance",
            length: ((frames[0].translation - frames[1].translation).norm() - self.distance).abs(),
            angle: None,
        }
    }

    fn measured_frame(&self) -> (Target, usize) {
        (self.views[0].target, 3)
    }

    fn anchoring(&self) -> Anchoring {
        Anchoring::Relative
    }

    fn remeasure(&mut self, _ctx: &Context<'_>, frames: &[Frame]) {
        self.distance = (frames[0].translation - frames[1].translation).norm();
    }

    fn add_noise(&mut self, unit: &mut dyn FnMut() -> f64, noise: &Noise) {
        self.distance += unit() * noise.length;
    }

    fn describe(&self, postures: &[Posture], robot: &Robot) -> String {
        format!(
            "postures {} and {} site {}",
            postures[self.views[0].posture].label,
            postures[self.views[1].posture].label,
            target_name(robot, self.views[0].target)
        )
    }
}
