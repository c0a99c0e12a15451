//! A target touching a plane: calibration without an external sensor (the robot touches a table
//! or a fixture face with a probe, and records its readings). The planes are declared in the
//! robot file (`[[planes]]`); their three parameters each are held unless estimated.
//!
//! Their file, the contact file, is read in [`crate::files`].

use super::{
    target_name, Anchoring, Context, Derivatives, ErrorSample, Noise, Observe, Posture, Row,
    RowQuantity, View,
};
use crate::model::kinematics::{Frame, Target};
use crate::model::params::{ParamKind, PlaneComponent};
use crate::model::robot::Robot;

const ROWS: &[Row] = &[Row {
    label: "contact",
    quantity: RowQuantity::Length,
}];

/// A target touching plane `plane` (an index into the robot's planes). One residual row: the
/// target origin's signed distance from the plane minus the known `gap` (m), `n . p - offset -
/// gap`.
#[derive(Debug, Clone, PartialEq)]
pub struct Contact {
    /// The posture and target.
    pub view: [View; 1],
    /// The plane touched.
    pub plane: usize,
    /// The target's known distance from the plane along its normal (m); 0 for a contact.
    pub gap: f64,
    /// The row's own standard deviation (m), if given.
    pub sigma: Option<f64>,
    /// Line in the file (0 when synthesized).
    pub line: usize,
}

impl Contact {
    /// `target` touching `plane` in `posture`.
    pub fn new(posture: usize, target: Target, plane: usize) -> Self {
        Contact {
            view: [View { posture, target }],
            plane,
            gap: 0.0,
            sigma: None,
            line: 0,
        }
    }
}

impl Observe for Contact {
    observe_fields!(kind: "contact", views: view, rows: ROWS);
    fn sigma(&self, _row: usize) -> Option<f64> {
        self.sigma
    }

    fn evaluate(
        &self,
        ctx: &Context<'_>,
        frames: &[Frame],
        res: &mut [f64],
        derivatives: Option<&mut Derivatives<'_>>,
    ) {
        let plane = &ctx.robot.planes[self.plane];
        let p = frames[0].translation;
        let n = plane.normal();
        res[0] = n.dot(&p) - plane.offset - self.gap;
        if let Some(d) = derivatives {
            for c in 0..d.cols {
                let v = n.dot(&d.dp(0, c));
                d.set(0, c, v);
            }
            // The plane's own parameters enter directly.
            let [dx, dy] = plane.normal_derivatives();
            for (component, value) in [
                (PlaneComponent::TiltX, dx.dot(&p)),
                (PlaneComponent::TiltY, dy.dot(&p)),
                (PlaneComponent::Offset, -1.0),
            ] {
                let id = ctx.robot.param_id(ParamKind::Plane {
                    plane: self.plane,
                    component,
                });
                if let Some(c) = d.column(id) {
                    d.set(0, c, value);
                }
            }
        }
    }

    fn error(&self, ctx: &Context<'_>, frames: &[Frame]) -> ErrorSample {
        let plane = &ctx.robot.planes[self.plane];
        ErrorSample {
            metric: "contact",
            length: (plane.distance(&frames[0].translation) - self.gap).abs(),
            angle: None,
        }
    }

    fn measured_frame(&self) -> (Target, usize) {
        (self.view[0].target, 3)
    }

    fn anchoring(&self) -> Anchoring {
        Anchoring::Plane(self.plane)
    }

    fn remeasure(&mut self, ctx: &Context<'_>, frames: &[Frame]) {
        self.gap = ctx.robot.planes[self.plane].distance(&frames[0].translation);
    }

    fn add_noise(&mut self, unit: &mut dyn FnMut() -> f64, noise: &Noise) {
        self.gap += unit() * noise.length;
    }

    fn describe(&self, postures: &[Posture], robot: &Robot) -> String {
        format!(
            "posture {} site {} plane {}",
            postures[self.view[0].posture].label,
            target_name(robot, self.view[0].target),
            robot.planes[self.plane].name
        )
    }
}
