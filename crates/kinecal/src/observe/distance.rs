//! Distances between a target's positions in two postures: a ballbar or telescoping bar between
//! the tool and a fixed pivot moved through two postures, or a fixed-length artefact touched at
//! both ends. No instrument coordinates are involved, so such data says nothing about where the
//! robot stands in the world: the six degrees of freedom of its placement are not determined
//! (see the rank count in [`crate::identifiability`]).
//!
//! File (CSV, the robot file's units): `pair, site, a1..an, b1..bn, distance` and optionally
//! `sigma_position` (the row's own standard deviation of the distance). `a*` and `b*` are the
//! readings of the two postures, `site` as in measurement files (`ee` when left out). The two
//! postures of pair `P` are labelled `P/a` and `P/b`.

use std::collections::HashMap;

use super::table::{self, PostureTable};
use super::{
    target_name, Anchoring, Context, Dataset, Derivatives, ErrorSample, Format, Observation,
    Observe, Posture, Row, RowQuantity, View,
};
use crate::error::{Error, Location, Result};
use crate::kinematics::{Frame, Target};
use crate::robot::Robot;
use crate::units::Quantity;

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
    fn kind(&self) -> &'static str {
        "distance"
    }
    fn views(&self) -> &[View] {
        &self.views
    }
    fn views_mut(&mut self) -> &mut [View] {
        &mut self.views
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

    fn add_noise(&mut self, unit: &mut dyn FnMut() -> f64, length: f64, _angle: f64) {
        self.distance += unit() * length;
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

/// The distance file format.
pub const FORMAT: Format = Format {
    option: "distances",
    kinds: &["distance"],
    marks: &["pair", "distance"],
    help: "Distance file: the distance between a target's positions in two postures (ballbar, \
           fixed-length artefact)",
    header: "pair,site,a1..an,b1..bn,distance[,sigma_position]",
    parse: parse_distances,
};

/// Parses a distance file for `robot`. `file` names it in error messages.
pub fn parse_distances(text: &str, file: &str, robot: &Robot) -> Result<Dataset> {
    let t = table::read(text, file)?;
    let n = robot.dof();
    let header = FORMAT
        .header
        .replace("a1..an", &format!("a1..a{n}"))
        .replace("b1..bn", &format!("b1..b{n}"));
    let a: Vec<String> = (1..=n).map(|i| format!("a{i}")).collect();
    let b: Vec<String> = (1..=n).map(|i| format!("b{i}")).collect();
    let mut known: Vec<String> = vec!["pair".into(), "site".into()];
    known.extend(a.iter().cloned());
    known.extend(b.iter().cloned());
    known.extend(["distance".into(), "sigma_position".into()]);
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
    let pair = need("pair")?;
    let ca = a.iter().map(|c| need(c)).collect::<Result<Vec<_>>>()?;
    let cb = b.iter().map(|c| need(c)).collect::<Result<Vec<_>>>()?;
    let distance = need("distance")?;
    let (site, sigma) = (t.column("site"), t.column("sigma_position"));
    t.check_rows()?;
    let units = robot.units;
    let mut postures = PostureTable::new();
    let mut observations: Vec<Observation> = Vec::new();
    let mut seen: HashMap<(String, Target), usize> = HashMap::new();
    for (line, f) in t.rows() {
        let label = &f[pair];
        if label.is_empty() {
            return Err(Error::input(t.at(line, "pair"), "empty pair label"));
        }
        let target = match site.map_or("", |i| f.get(i)) {
            "" | "ee" => Target::EndEffector,
            name => Target::Site(robot.site_index(name).ok_or_else(|| {
                Error::input(
                    t.at(line, "site"),
                    format!("unknown site `{name}` (the robot file defines: ee{})", {
                        robot
                            .sites
                            .iter()
                            .map(|s| format!(", {}", s.name))
                            .collect::<String>()
                    }),
                )
            })?),
        };
        let mut ends = [0; 2];
        for (k, (cols, names, tag)) in [(&ca, &a, "a"), (&cb, &b, "b")].into_iter().enumerate() {
            let readings = cols
                .iter()
                .zip(names)
                .map(|(&i, name)| t.number(line, name, &f[i]))
                .collect::<Result<Vec<_>>>()?;
            ends[k] =
                postures.get_or_insert(&t, line, &format!("{label}/{tag}"), readings, &|j| {
                    names[j].clone()
                })?;
        }
        let d = t.number(line, "distance", &f[distance])?;
        if d < 0.0 {
            return Err(Error::input(
                t.at(line, "distance"),
                format!("a distance cannot be negative, found {d}"),
            ));
        }
        let sigma = match sigma {
            Some(i) => t
                .sigma(line, "sigma_position", &f[i])?
                .map(|s| units.to_si(Quantity::Length, s)),
            None => None,
        };
        if let Some(first) = seen.insert((label.to_string(), target), line) {
            return Err(Error::input(
                Location::file(file).at_line(line),
                format!(
                    "pair `{label}` measures {} twice (first on line {first})",
                    target_name(robot, target)
                ),
            ));
        }
        let mut o = Distance::new(ends[0], ends[1], target, units.to_si(Quantity::Length, d));
        o.sigma = sigma;
        o.line = line;
        observations.push(o.into());
    }
    if observations.is_empty() {
        return Err(Error::input(
            Location::file(file),
            "no distances: the file has a header but no rows",
        ));
    }
    Ok(Dataset::new(postures.postures, observations))
}
