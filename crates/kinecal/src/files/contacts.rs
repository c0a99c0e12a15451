//! The contact file: a target touching a plane of the robot file, recorded by the robot's own
//! readings; see the [module](super) for the format.

use std::collections::HashMap;

use super::table::{self, PostureTable};
use super::{site_target, Format};
use crate::error::{Error, Location, Result};
use crate::model::kinematics::Target;
use crate::model::robot::Robot;
use crate::observe::contact::Contact;
use crate::observe::{target_name, Dataset, Observation};
use crate::units::Quantity;

/// The contact file format.
pub(super) const FORMAT: Format = Format {
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
    let own = ["posture", "site", "plane", "gap", "sigma_position"];
    let columns = super::ReadingColumns::of(robot, &t.header, &own);
    let readings = columns.names.clone();
    let mut known: Vec<String> = own.map(String::from).to_vec();
    known.extend(readings.iter().cloned());
    known.extend(columns.others.iter().cloned());
    t.refuse_unknown(&known, &header)?;
    columns.note(file, robot);
    let need = |name: &str| t.require(name, &header);
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
        let target = site_target(robot, site.map_or("", |i| f.get(i)))
            .map_err(|m| Error::input(t.at(line, "site"), m))?;
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
        let sigma = t.sigma_length(line, sigma.map(|i| &f[i]), units)?;
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
    postures.into_dataset(observations, file, "contacts", &units)
}

/// Writes the contacts of `data` as a contact file in `robot`'s units, read back by
/// [`parse_contacts`] to the same numbers (readings and gaps as [`crate::units::number`] says,
/// with the file's scale of each; sigmas exactly). Observations of other kinds are not written.
pub(crate) fn write_contacts(robot: &Robot, data: &Dataset) -> String {
    use crate::units::number::{format_number, write, Scale};
    use std::fmt::Write as _;
    let contacts: Vec<&Contact> = data
        .observations
        .iter()
        .filter_map(|o| match o {
            Observation::Contact(c) => Some(c),
            _ => None,
        })
        .collect();
    let with_sigma = contacts.iter().any(|c| c.sigma.is_some());
    let mut out = String::from("posture,site,plane");
    for j in 1..=robot.dof() {
        let _ = write!(out, ",v{j}");
    }
    out.push_str(if with_sigma {
        ",gap,sigma_position\n"
    } else {
        ",gap\n"
    });
    let len = |v: f64| robot.units.from_si(Quantity::Length, v);
    let scale = Scale::of(contacts.iter().map(|c| len(c.gap)));
    let readings = super::measurements::reading_scales(robot, &data.postures);
    for c in contacts {
        let p = &data.postures[c.view[0].posture];
        let _ = write!(
            out,
            "{},{},{}",
            p.label,
            target_name(robot, c.view[0].target),
            robot.planes[c.plane].name
        );
        super::measurements::write_readings(&mut out, &p.readings, &readings);
        let _ = write!(out, ",{}", write(len(c.gap), scale));
        if with_sigma {
            let s = c.sigma.map_or(String::new(), |s| format_number(len(s)));
            let _ = write!(out, ",{s}");
        }
        out.push('\n');
    }
    out
}
