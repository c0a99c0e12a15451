//! The pixel file: where a camera of the robot file saw board corners or markers, with the
//! robot's readings; see the [module](super) for the format.

use std::collections::HashMap;

use super::table::{self, PostureTable};
use super::{site_target, Format};
use crate::error::{Error, Location, Result};
use crate::model::robot::Robot;
use crate::observe::pixel::{Pixel, Seen};
use crate::observe::{target_name, Dataset, Observation};

/// The pixel file format.
pub(super) const FORMAT: Format = Format {
    option: "pixels",
    kinds: &["pixel"],
    marks: &["camera", "u", "v"],
    help: "Pixel file: where a camera of the robot file saw board points or markers",
    header: "posture,camera,point,v1..vn,u,v[,sigma_px]",
    parse: parse_pixels,
};

/// What a `point` field names: `BOARD:K` (point K, 0-based, of a board) or a target (`ee`, a
/// site); otherwise the message of the error.
fn seen(robot: &Robot, field: &str) -> std::result::Result<Seen, String> {
    if let Some((board, k)) = field.split_once(':') {
        let b = robot.board_index(board.trim()).ok_or_else(|| {
            format!(
                "unknown board `{board}` (the robot file defines: {})",
                names(robot.boards.iter().map(|b| b.name.as_str()))
            )
        })?;
        let n = robot.boards[b].points();
        return match k.trim().parse::<usize>() {
            Ok(index) if index < n => Ok(Seen::Board { board: b, index }),
            _ => Err(format!(
                "`{field}`: board `{board}` has points 0..{} (row-major, `{board}:K`)",
                n - 1
            )),
        };
    }
    site_target(robot, field)
        .map(Seen::Target)
        .map_err(|m| format!("{m}; or a board's point as `BOARD:K`"))
}

fn names<'a>(it: impl Iterator<Item = &'a str>) -> String {
    let v: Vec<&str> = it.collect();
    if v.is_empty() {
        "none".into()
    } else {
        v.join(", ")
    }
}

/// Parses a pixel file for `robot`. `file` names it in error messages.
pub fn parse_pixels(text: &str, file: &str, robot: &Robot) -> Result<Dataset> {
    let t = table::read(text, file)?;
    if robot.cameras.is_empty() {
        return Err(Error::input(
            Location::file(file),
            "the robot file declares no [[cameras]] to have seen these pixels",
        ));
    }
    let n = robot.dof();
    let header = FORMAT.header.replace("v1..vn", &format!("v1..v{n}"));
    let own = ["posture", "camera", "point", "u", "v", "sigma_px"];
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
    let (point_col, u_col, v_col) = (need("point")?, need("u")?, need("v")?);
    let camera_col = match (t.column("camera"), robot.cameras.len()) {
        (Some(i), _) => Some(i),
        (None, 1) => None,
        (None, _) => {
            return Err(Error::input(
                t.header_at().with_field("camera"),
                format!(
                    "no column `camera` (needed when the robot file has {} cameras): expected \
                     {header}",
                    robot.cameras.len()
                ),
            ))
        }
    };
    let sigma = t.column("sigma_px");
    t.check_rows()?;
    let mut postures = PostureTable::new();
    let mut observations: Vec<Observation> = Vec::new();
    let mut seen_at: HashMap<(usize, usize, Seen), usize> = HashMap::new();
    for (line, f) in t.rows() {
        let values = cols
            .iter()
            .zip(&readings)
            .map(|(&i, name)| t.number(line, name, &f[i]))
            .collect::<Result<Vec<_>>>()?;
        let posture =
            postures.get_or_insert(&t, line, &f[posture_col], values, &|j| readings[j].clone())?;
        let camera = match camera_col {
            None => 0,
            Some(i) => robot.camera_index(&f[i]).ok_or_else(|| {
                Error::input(
                    t.at(line, "camera"),
                    format!(
                        "unknown camera `{}` (the robot file defines: {})",
                        &f[i],
                        names(robot.cameras.iter().map(|c| c.name.as_str()))
                    ),
                )
            })?,
        };
        let what = seen(robot, &f[point_col]).map_err(|m| Error::input(t.at(line, "point"), m))?;
        let mut uv = [0.0; 2];
        for (slot, (col, name)) in uv.iter_mut().zip([(u_col, "u"), (v_col, "v")]) {
            let x = t.number(line, name, &f[col])?;
            // A pixel far outside any image is a unit or column mix-up, not a measurement.
            if x.abs() > 1e6 {
                return Err(Error::input(
                    t.at(line, name),
                    format!("{x} is not a pixel coordinate (expected within +-1e6 pixels)"),
                ));
            }
            *slot = x;
        }
        let sigma = match sigma.map(|i| &f[i]) {
            None | Some("") => None,
            Some(s) => t.sigma(line, "sigma_px", s)?,
        };
        if let Some(first) = seen_at.insert((posture, camera, what), line) {
            return Err(Error::input(
                Location::file(file).at_line(line),
                format!(
                    "posture `{}`: camera `{}` sees point `{}` twice (first on line {first})",
                    &f[posture_col], robot.cameras[camera].name, &f[point_col]
                ),
            ));
        }
        let mut o = Pixel::new(robot, posture, camera, what, uv)
            .map_err(|m| Error::input(t.at(line, "point"), m))?;
        o.sigma = sigma;
        o.line = line;
        observations.push(o.into());
    }
    postures.into_dataset(observations, file, "pixels", &robot.units)
}

/// Writes the pixels of `data` as a pixel file, read back by [`parse_pixels`] to the same
/// numbers (readings as [`crate::units::number`] says; pixels and sigmas exactly). Observations
/// of other kinds are not written.
pub(crate) fn write_pixels(robot: &Robot, data: &Dataset) -> String {
    use crate::units::number::format_number;
    use std::fmt::Write as _;
    let pixels: Vec<&Pixel> = data
        .observations
        .iter()
        .filter_map(|o| match o {
            Observation::Pixel(p) => Some(&**p),
            _ => None,
        })
        .collect();
    let with_sigma = pixels.iter().any(|p| p.sigma.is_some());
    let mut out = String::from("posture,camera,point");
    for j in 1..=robot.dof() {
        let _ = write!(out, ",v{j}");
    }
    out.push_str(if with_sigma {
        ",u,v,sigma_px\n"
    } else {
        ",u,v\n"
    });
    let readings = super::measurements::reading_scales(robot, &data.postures);
    for p in pixels {
        let posture = &data.postures[p.view[0].posture];
        let point = match p.seen {
            Seen::Board { board, index } => format!("{}:{index}", robot.boards[board].name),
            Seen::Target(t) => target_name(robot, t).to_string(),
        };
        let _ = write!(
            out,
            "{},{},{point}",
            posture.label, robot.cameras[p.camera].name
        );
        super::measurements::write_readings(&mut out, &posture.readings, &readings);
        let _ = write!(
            out,
            ",{},{}",
            format_number(p.uv[0]),
            format_number(p.uv[1])
        );
        if with_sigma {
            let s = p.sigma.map_or(String::new(), format_number);
            let _ = write!(out, ",{s}");
        }
        out.push('\n');
    }
    out
}
