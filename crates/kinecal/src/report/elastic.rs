//! The compliances and stiffnesses of an elastic robot's calibration.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::model::params::ParamId;
use crate::model::robot::Robot;
use crate::observe::Dataset;
use crate::units::Quantity;

/// The mass model of an elastic robot (see [`crate::model::robot::Elastic`]), after calibration.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
#[non_exhaustive]
pub struct ElasticReport {
    /// Bodies of the model.
    pub bodies: usize,
    /// Their total mass (kg).
    pub total_mass: f64,
    /// Magnitude of gravity (length unit / s^2).
    pub gravity: f64,
    /// `converged` (to 1e-10 rad) or `N fixed iterations`.
    pub equilibrium: String,
    /// The most fixed-point iterations any identification posture took.
    pub iterations_max: usize,
    /// Postures whose equilibrium did not converge (0 when it is sound).
    pub unconverged_postures: usize,
    /// The largest deflection at any identification posture (angle unit).
    pub largest_deflection: f64,
    /// The largest gravity torque about any joint axis there (N m).
    pub largest_torque: f64,
    /// Each revolute joint's compliances, as compliance and as stiffness.
    pub joints: Vec<StiffnessReport>,
}

/// One compliance of one joint.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, JsonSchema)]
#[non_exhaustive]
pub struct StiffnessReport {
    /// The parameter, `joint2.compliance` or `joint2.lateral`.
    pub name: String,
    /// Its compliance (angle unit / (N length unit)).
    pub compliance: f64,
    /// Its standard deviation, when estimated and determined.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub compliance_sigma: Option<f64>,
    /// The stiffness `1 / compliance` (N length unit / angle unit), when the compliance is
    /// positive.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stiffness: Option<f64>,
    /// Its standard deviation, `sigma / compliance^2` (first order), when both exist.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stiffness_sigma: Option<f64>,
    /// The stiffness's unit, `N m/rad`.
    pub stiffness_unit: String,
    /// Whether it was estimated.
    pub estimated: bool,
}

/// The header of [`ElasticReport::table`].
pub const STIFFNESS_COLUMNS: [&str; 9] = [
    "parameter",
    "joint",
    "axis",
    "compliance",
    "compliance_sigma",
    "stiffness",
    "stiffness_sigma",
    "stiffness_unit",
    "estimated",
];

impl ElasticReport {
    /// The compliance table as CSV ([`STIFFNESS_COLUMNS`]): one row per compliance, `joint` its
    /// number, `axis` `joint` or `lateral`, compliance and stiffness in the report's units with
    /// their sigmas (empty when not determined or not positive), `estimated` 1 or 0. Numbers are
    /// written as [`crate::units::number`] says: the shortest text that reads back to the same
    /// value.
    pub fn table(&self) -> String {
        use crate::units::number::{write, Scale};
        let mut out = STIFFNESS_COLUMNS.join(",");
        out.push('\n');
        let num = |v: Option<f64>| v.map_or(String::new(), |v| write(v, Scale::of([v])));
        for j in &self.joints {
            let (joint, axis) = j
                .name
                .strip_prefix("joint")
                .and_then(|r| r.split_once('.'))
                .unwrap_or(("", ""));
            let axis = if axis == "lateral" {
                "lateral"
            } else {
                "joint"
            };
            out.push_str(&format!(
                "{},{joint},{axis},{},{},{},{},{},{}\n",
                j.name,
                num(Some(j.compliance)),
                num(j.compliance_sigma),
                num(j.stiffness),
                num(j.stiffness_sigma),
                j.stiffness_unit,
                u8::from(j.estimated)
            ));
        }
        out
    }

    /// The report of `robot`'s mass model at the postures of `data` (`None` for a rigid robot).
    pub fn new(robot: &Robot, data: &Dataset, estimated: &[ParamId]) -> Option<ElasticReport> {
        let model = robot.elastic.as_ref()?;
        let u = robot.units;
        let chain = crate::model::kinematics::Chain::new(robot);
        let mut ws = crate::model::kinematics::Workspace::new(robot);
        let (mut iterations_max, mut unconverged) = (0, 0);
        let (mut largest, mut torque) = (0.0f64, 0.0f64);
        for p in &data.postures {
            chain.forward_loaded(&p.readings, None, p.payload.as_ref(), &mut ws);
            let eq = ws.equilibrium()?;
            iterations_max = iterations_max.max(eq.iterations);
            unconverged += usize::from(!eq.converged);
            largest = largest.max(eq.largest);
            for t in ws.gravity_torques()?.iter() {
                torque = torque.max(t.abs());
            }
        }
        let stiffness_unit = format!("N {}/{}", u.length, u.angle);
        let joints = robot
            .param_ids()
            .filter(|&id| {
                matches!(
                    robot.param_kind(id),
                    crate::model::params::ParamKind::Compliance { .. }
                        | crate::model::params::ParamKind::Lateral { .. }
                )
            })
            .map(|id| {
                let compliance = robot.get_user(id);
                StiffnessReport {
                    name: robot.param_name(id),
                    compliance,
                    compliance_sigma: None,
                    stiffness: (compliance > 0.0).then(|| 1.0 / compliance),
                    stiffness_sigma: None,
                    stiffness_unit: stiffness_unit.clone(),
                    estimated: estimated.contains(&id),
                }
            })
            .collect();
        Some(ElasticReport {
            bodies: model.bodies.len(),
            total_mass: model.bodies.iter().map(|b| b.mass).sum(),
            gravity: u.from_si(Quantity::Length, model.gravity.norm()),
            equilibrium: match model.iterations {
                Some(n) => format!("{n} fixed iterations"),
                None => "converged".into(),
            },
            iterations_max,
            unconverged_postures: unconverged,
            largest_deflection: u.from_si(Quantity::Angle, largest),
            largest_torque: torque,
            joints,
        })
    }
}
