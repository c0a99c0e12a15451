//! The distance file: distances between a target's positions in two postures (ballbar,
//! fixed-length artefact); see the [module](super) for the format.

use std::collections::HashMap;

use super::table::{self, PostureTable};
use super::{site_target, Format};
use crate::error::{Error, Location, Result};
use crate::model::kinematics::Target;
use crate::model::robot::Robot;
use crate::observe::distance::Distance;
use crate::observe::{target_name, Dataset, Observation};
use crate::units::Quantity;

/// The distance file format.
pub(super) const FORMAT: Format = Format {
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
    t.refuse_unknown(&known, &header)?;
    let need = |name: &str| t.require(name, &header);
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
        let target = site_target(robot, site.map_or("", |i| f.get(i)))
            .map_err(|m| Error::input(t.at(line, "site"), m))?;
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
        let sigma = t.sigma_length(line, sigma.map(|i| &f[i]), units)?;
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
    postures.into_dataset(observations, file, "distances", &units)
}

/// Writes the distances of `data` as a distance file in `robot`'s units, read back by
/// [`parse_distances`] to the same numbers (readings and distances as
/// [`crate::units::number`] says, with the file's scale of each; sigmas exactly). A pair is
/// named after its postures when they were read from a distance file (`P/a` and `P/b`: pair
/// `P`), else numbered. Observations of other kinds are not written.
pub(crate) fn write_distances(robot: &Robot, data: &Dataset) -> String {
    use crate::units::number::{format_number, write, Scale};
    use std::fmt::Write as _;
    let n = robot.dof();
    let mut out = String::from("pair,site");
    for tag in ["a", "b"] {
        for j in 1..=n {
            let _ = write!(out, ",{tag}{j}");
        }
    }
    let distances: Vec<&Distance> = data
        .observations
        .iter()
        .filter_map(|o| match o {
            Observation::Distance(d) => Some(d),
            _ => None,
        })
        .collect();
    let with_sigma = distances.iter().any(|d| d.sigma.is_some());
    out.push_str(if with_sigma {
        ",distance,sigma_position\n"
    } else {
        ",distance\n"
    });
    let len = |v: f64| robot.units.from_si(Quantity::Length, v);
    let scale = Scale::of(distances.iter().map(|d| len(d.distance)));
    let readings = super::measurements::reading_scales(robot, &data.postures);
    for (k, d) in distances.iter().enumerate() {
        let (a, b) = (
            &data.postures[d.views[0].posture],
            &data.postures[d.views[1].posture],
        );
        let pair = match (a.label.strip_suffix("/a"), b.label.strip_suffix("/b")) {
            (Some(p), Some(q)) if p == q => p.to_string(),
            _ => format!("{}", k + 1),
        };
        let _ = write!(out, "{pair},{}", target_name(robot, d.views[0].target));
        super::measurements::write_readings(&mut out, &a.readings, &readings);
        super::measurements::write_readings(&mut out, &b.readings, &readings);
        let _ = write!(out, ",{}", write(len(d.distance), scale));
        if with_sigma {
            let s = d.sigma.map_or(String::new(), |s| format_number(len(s)));
            let _ = write!(out, ",{s}");
        }
        out.push('\n');
    }
    out
}
