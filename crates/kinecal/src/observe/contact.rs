//! A target touching a plane: calibration without an external sensor (the robot touches a table
//! or a fixture face with a probe, and records its readings). The planes are declared in the
//! robot file (`[[planes]]`); their three parameters each are held unless estimated.
//!
//! File (CSV, the robot file's units): `posture, site, plane, v1..vn` and optionally `gap` (the
//! target's known distance from the plane along its normal: a probe ball's radius, a gauge
//! block; default 0) and `sigma_position` (the row's own standard deviation). `site` as in
//! measurement files (`ee` when left out); `plane` names a plane of the robot file and may be
//! left out when the robot has only one.

use std::collections::HashMap;

use super::table::{self, PostureTable};
use super::{
    target_name, Anchoring, Context, Dataset, Derivatives, ErrorSample, Format, Observation,
    Observe, Posture, Row, RowQuantity, View,
};
use crate::error::{Error, Location, Result};
use crate::kinematics::{Frame, Target};
use crate::params::{ParamKind, PlaneComponent};
use crate::robot::Robot;
use crate::units::Quantity;

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
    fn kind(&self) -> &'static str {
        "contact"
    }
    fn views(&self) -> &[View] {
        &self.view
    }
    fn views_mut(&mut self) -> &mut [View] {
        &mut self.view
    }
    fn rows(&self) -> &'static [Row] {
        ROWS
    }
    fn sigma(&self, _row: usize) -> Option<f64> {
        self.sigma
    }
    fn line(&self) -> usize {
        self.line
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

    fn add_noise(&mut self, unit: &mut dyn FnMut() -> f64, length: f64, _angle: f64) {
        self.gap += unit() * length;
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

/// The contact file format.
pub const FORMAT: Format = Format {
    option: "contacts",
    kinds: &["contact"],
    marks: &["plane"],
    help: "Contact file: a target touching a plane of the robot file (no external sensor)",
    header: "posture,site,plane,v1..vn[,gap][,sigma_position]",
    parse: parse_contacts,
};

/// Parses a contact file for `robot`. `file` names it in error messages.
pub fn parse_contacts(text: &str, file: &str, robot: &Robot) -> Result<Dataset> {
    let t = table::read(text, file)?;
    if robot.planes.is_empty() {
        return Err(Error::input(
            Location::file(file),
            "the robot file declares no [[planes]] to touch",
        ));
    }
    let n = robot.dof();
    let header = FORMAT.header.replace("v1..vn", &format!("v1..v{n}"));
    let readings: Vec<String> = (1..=n).map(|i| format!("v{i}")).collect();
    let mut known: Vec<String> = ["posture", "site", "plane", "gap", "sigma_position"]
        .map(String::from)
        .to_vec();
    known.extend(readings.iter().cloned());
    if let Some(h) = t
        .header
        .iter()
        .find(|h| !known.iter().any(|k| k.eq_ignore_ascii_case(h)))
    {
        return Err(Error::input(
            t.header_at().with_field(h.clone()),
            format!("unknown column `{h}`: expected {header}"),
        ));
    }
    let need = |name: &str| {
        t.column(name).ok_or_else(|| {
            Error::input(
                t.header_at().with_field(name),
                format!("no column `{name}` in the header: expected {header}"),
            )
        })
    };
    let posture_col = need("posture")?;
    let cols = readings
        .iter()
        .map(|c| need(c))
        .collect::<Result<Vec<_>>>()?;
    let plane_col = match (t.column("plane"), robot.planes.len()) {
        (Some(i), _) => Some(i),
        (None, 1) => None,
        (None, _) => {
            return Err(Error::input(
                t.header_at().with_field("plane"),
                format!(
                    "no column `plane` (needed when the robot file has {} planes): expected \
                     {header}",
                    robot.planes.len()
                ),
            ))
        }
    };
    let (site, gap, sigma) = (
        t.column("site"),
        t.column("gap"),
        t.column("sigma_position"),
    );
    t.check_rows()?;
    let units = robot.units;
    let mut postures = PostureTable::new();
    let mut observations: Vec<Observation> = Vec::new();
    let mut seen: HashMap<(usize, Target, usize), usize> = HashMap::new();
    for (line, f) in t.rows() {
        let values = cols
            .iter()
            .zip(&readings)
            .map(|(&i, name)| t.number(line, name, &f[i]))
            .collect::<Result<Vec<_>>>()?;
        let posture =
            postures.get_or_insert(&t, line, &f[posture_col], values, &|j| readings[j].clone())?;
        let target = match site.map_or("", |i| f.get(i)) {
            "" | "ee" => Target::EndEffector,
            name => Target::Site(robot.site_index(name).ok_or_else(|| {
                Error::input(
                    t.at(line, "site"),
                    format!(
                        "unknown site `{name}` (the robot file defines: ee{})",
                        robot
                            .sites
                            .iter()
                            .map(|s| format!(", {}", s.name))
                            .collect::<String>()
                    ),
                )
            })?),
        };
        let plane = match plane_col {
            None => 0,
            Some(i) => robot.plane_index(&f[i]).ok_or_else(|| {
                Error::input(
                    t.at(line, "plane"),
                    format!(
                        "unknown plane `{}` (the robot file defines: {})",
                        &f[i],
                        robot
                            .planes
                            .iter()
                            .map(|p| p.name.as_str())
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                )
            })?,
        };
        let gap = match gap.map(|i| f.get(i)) {
            None | Some("") => 0.0,
            Some(s) => units.to_si(Quantity::Length, t.number(line, "gap", s)?),
        };
        let sigma = match sigma {
            Some(i) => t
                .sigma(line, "sigma_position", &f[i])?
                .map(|s| units.to_si(Quantity::Length, s)),
            None => None,
        };
        if let Some(first) = seen.insert((posture, target, plane), line) {
            return Err(Error::input(
                Location::file(file).at_line(line),
                format!(
                    "posture `{}` touches plane `{}` with {} twice (first on line {first})",
                    &f[posture_col],
                    robot.planes[plane].name,
                    target_name(robot, target)
                ),
            ));
        }
        let mut o = Contact::new(posture, target, plane);
        o.gap = gap;
        o.sigma = sigma;
        o.line = line;
        observations.push(o.into());
    }
    if observations.is_empty() {
        return Err(Error::input(
            Location::file(file),
            "no contacts: the file has a header but no rows",
        ));
    }
    Ok(Dataset::new(postures.postures, observations))
}
