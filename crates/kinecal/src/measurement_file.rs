//! Measurement and posture files: CSV with a header, in the robot file's units.
//!
//! Measurement file: `posture,site,v1,...,vn,x,y,z,alpha,beta,gamma`. The `site` column may be
//! left out (every row is then the end effector, `ee`). A row whose `alpha,beta,gamma` are empty
//! is a position-only measurement. Rows of one posture must carry the same readings.
//!
//! Postures file: `posture,v1,...,vn`.

use std::collections::HashMap;
use std::fmt::Write as _;

use nalgebra::Vector3;

use crate::error::{Error, Location, Result};
use crate::kinematics::Target;
use crate::measurement::{Dataset, Measurement, Posture};
use crate::robot::Robot;
use crate::units::Quantity;

fn reading_columns(n: usize) -> Vec<String> {
    (1..=n).map(|i| format!("v{i}")).collect()
}

/// The measurement header for `robot` (with the `site` column).
pub fn measurement_header(robot: &Robot) -> Vec<String> {
    let mut h = vec!["posture".to_string(), "site".to_string()];
    h.extend(reading_columns(robot.dof()));
    h.extend(["x", "y", "z", "alpha", "beta", "gamma"].map(String::from));
    h
}

/// The postures-file header for `robot`.
pub fn postures_header(robot: &Robot) -> Vec<String> {
    let mut h = vec!["posture".to_string()];
    h.extend(reading_columns(robot.dof()));
    h
}

struct Rows {
    file: String,
    header: Vec<String>,
    /// (line, fields)
    rows: Vec<(usize, Vec<String>)>,
}

fn read_csv(text: &str, file: &str) -> Result<Rows> {
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(true)
        .flexible(true)
        .trim(csv::Trim::All)
        .comment(Some(b'#'))
        .from_reader(text.as_bytes());
    let loc = Location::file(file);
    let csv_err = |e: csv::Error| {
        let line = e.position().map(|p| p.line() as usize);
        let at = match line {
            Some(l) => loc.at_line(l),
            None => loc.clone(),
        };
        Error::input(at, format!("invalid CSV: {e}"))
    };
    let header: Vec<String> = rdr
        .headers()
        .map_err(csv_err)?
        .iter()
        .map(str::to_string)
        .collect();
    if header.iter().all(String::is_empty) {
        return Err(Error::input(
            loc.at_line(1),
            "empty file: a header line is required",
        ));
    }
    let mut rows = Vec::new();
    for rec in rdr.records() {
        let rec = rec.map_err(csv_err)?;
        let line = rec.position().map_or(0, |p| p.line() as usize);
        if rec.iter().all(str::is_empty) {
            continue;
        }
        rows.push((line, rec.iter().map(str::to_string).collect()));
    }
    Ok(Rows {
        file: file.to_string(),
        header,
        rows,
    })
}

impl Rows {
    fn check_header(&self, expected: &[String], also: Option<&[String]>) -> Result<bool> {
        let got: Vec<String> = self.header.iter().map(|h| h.to_ascii_lowercase()).collect();
        if got == expected {
            return Ok(true);
        }
        if let Some(alt) = also {
            if got == alt {
                return Ok(false);
            }
        }
        let mut msg = format!(
            "unexpected header `{}`: expected `{}`",
            self.header.join(","),
            expected.join(",")
        );
        if let Some(alt) = also {
            let _ = write!(msg, " or `{}`", alt.join(","));
        }
        Err(Error::input(Location::file(&self.file).at_line(1), msg))
    }

    fn at(&self, line: usize, field: &str) -> Location {
        Location::file(&self.file).at_line(line).with_field(field)
    }

    fn number(&self, line: usize, field: &str, s: &str) -> Result<f64> {
        let v: f64 = s.parse().map_err(|_| {
            Error::input(
                self.at(line, field),
                format!("expected a number, found `{s}`"),
            )
        })?;
        if !v.is_finite() {
            return Err(Error::input(
                self.at(line, field),
                format!("expected a finite number, found `{s}`"),
            ));
        }
        Ok(v)
    }
}

/// Keeps postures unique by label and checks that repeated labels carry the same readings.
struct PostureTable {
    postures: Vec<Posture>,
    index: HashMap<String, usize>,
}

impl PostureTable {
    fn new() -> Self {
        PostureTable {
            postures: Vec::new(),
            index: HashMap::new(),
        }
    }

    fn get_or_insert(
        &mut self,
        rows: &Rows,
        line: usize,
        label: &str,
        readings: Vec<f64>,
    ) -> Result<usize> {
        if label.is_empty() {
            return Err(Error::input(
                rows.at(line, "posture"),
                "empty posture label",
            ));
        }
        if let Some(&i) = self.index.get(label) {
            let known = &self.postures[i].readings;
            if let Some(j) = (0..known.len())
                .find(|&j| (known[j] - readings[j]).abs() > 1e-9 * known[j].abs().max(1.0))
            {
                return Err(Error::input(
                    rows.at(line, &format!("v{}", j + 1)),
                    format!(
                        "posture `{label}` appears earlier with reading {} here {}: rows of one \
                         posture must share the same readings",
                        known[j], readings[j]
                    ),
                ));
            }
            return Ok(i);
        }
        self.index.insert(label.to_string(), self.postures.len());
        self.postures.push(Posture {
            label: label.to_string(),
            readings,
        });
        Ok(self.postures.len() - 1)
    }
}

fn wrong_count(rows: &Rows, line: usize, got: usize) -> Error {
    Error::input(
        Location::file(&rows.file).at_line(line),
        format!(
            "expected {} columns ({}), found {got}",
            rows.header.len(),
            rows.header.join(",")
        ),
    )
}

/// Parses a measurement file for `robot`. `file` names it in error messages.
pub fn parse_measurements(text: &str, file: &str, robot: &Robot) -> Result<Dataset> {
    let rows = read_csv(text, file)?;
    let n = robot.dof();
    let full = measurement_header(robot);
    let no_site: Vec<String> = full.iter().filter(|h| *h != "site").cloned().collect();
    let has_site = rows.check_header(&full, Some(&no_site))?;
    let units = robot.units;
    let mut table = PostureTable::new();
    let mut measurements = Vec::new();
    let mut seen: HashMap<(usize, Target), usize> = HashMap::new();
    let base = if has_site { 2 } else { 1 };
    for (line, f) in &rows.rows {
        let line = *line;
        if f.len() != rows.header.len() {
            return Err(wrong_count(&rows, line, f.len()));
        }
        let target = if has_site {
            match f[1].as_str() {
                "" | "ee" => Target::EndEffector,
                name => Target::Site(robot.site_index(name).ok_or_else(|| {
                    let known: Vec<&str> = std::iter::once("ee")
                        .chain(robot.sites.iter().map(|s| s.name.as_str()))
                        .collect();
                    Error::input(
                        rows.at(line, "site"),
                        format!(
                            "unknown site `{name}` (the robot file defines: {})",
                            known.join(", ")
                        ),
                    )
                })?),
            }
        } else {
            Target::EndEffector
        };
        let readings = (0..n)
            .map(|j| rows.number(line, &format!("v{}", j + 1), &f[base + j]))
            .collect::<Result<Vec<_>>>()?;
        let posture = table.get_or_insert(&rows, line, &f[0], readings)?;
        let p = base + n;
        let mut pos = [0.0; 3];
        for (k, name) in ["x", "y", "z"].iter().enumerate() {
            pos[k] = units.to_si(Quantity::Length, rows.number(line, name, &f[p + k])?);
        }
        let angles = &f[p + 3..p + 6];
        let orientation = if angles.iter().all(String::is_empty) {
            None
        } else {
            let mut e = [0.0; 3];
            for (k, name) in ["alpha", "beta", "gamma"].iter().enumerate() {
                if angles[k].is_empty() {
                    return Err(Error::input(
                        rows.at(line, name),
                        "empty angle: give all of alpha, beta, gamma (a full pose) or none (a position)",
                    ));
                }
                e[k] = units.to_si(Quantity::Angle, rows.number(line, name, &angles[k])?);
            }
            Some(Vector3::from(e))
        };
        if let Some(first) = seen.insert((posture, target), line) {
            return Err(Error::input(
                Location::file(file).at_line(line),
                format!(
                    "posture `{}` measures the same site twice (first on line {first})",
                    f[0]
                ),
            ));
        }
        measurements.push(Measurement {
            posture,
            target,
            position: Vector3::from(pos),
            orientation,
            line,
        });
    }
    if measurements.is_empty() {
        return Err(Error::input(
            Location::file(file),
            "no measurements: the file has a header but no rows",
        ));
    }
    Ok(Dataset::new(table.postures, measurements))
}

/// Parses a postures file (`posture,v1,...,vn`) for `robot`. A measurement file is accepted too
/// (its readings are used).
pub fn parse_postures(text: &str, file: &str, robot: &Robot) -> Result<Vec<Posture>> {
    let rows = read_csv(text, file)?;
    let got: Vec<String> = rows.header.iter().map(|h| h.to_ascii_lowercase()).collect();
    if got.len() > 1 + robot.dof() && got.iter().any(|h| h == "x") {
        return Ok(parse_measurements(text, file, robot)?.postures);
    }
    rows.check_header(&postures_header(robot), None)?;
    let mut table = PostureTable::new();
    for (line, f) in &rows.rows {
        if f.len() != rows.header.len() {
            return Err(wrong_count(&rows, *line, f.len()));
        }
        let readings = (0..robot.dof())
            .map(|j| rows.number(*line, &format!("v{}", j + 1), &f[1 + j]))
            .collect::<Result<Vec<_>>>()?;
        if table.index.contains_key(&f[0]) {
            return Err(Error::input(
                rows.at(*line, "posture"),
                format!("posture `{}` listed twice", f[0]),
            ));
        }
        table.get_or_insert(&rows, *line, &f[0], readings)?;
    }
    if table.postures.is_empty() {
        return Err(Error::input(
            Location::file(file),
            "no postures: the file has a header but no rows",
        ));
    }
    Ok(table.postures)
}

fn site_name(robot: &Robot, t: Target) -> &str {
    match t {
        Target::EndEffector => "ee",
        Target::Site(s) => &robot.sites[s].name,
    }
}

/// Writes a measurement file in `robot`'s units. Numbers are written with full precision.
pub fn write_measurements(robot: &Robot, data: &Dataset) -> String {
    let units = robot.units;
    let mut out = measurement_header(robot).join(",");
    out.push('\n');
    for m in &data.measurements {
        let p = &data.postures[m.posture];
        let _ = write!(out, "{},{}", p.label, site_name(robot, m.target));
        for v in &p.readings {
            let _ = write!(out, ",{v}");
        }
        for k in 0..3 {
            let _ = write!(out, ",{}", units.from_si(Quantity::Length, m.position[k]));
        }
        match m.orientation {
            Some(e) => {
                for k in 0..3 {
                    let _ = write!(out, ",{}", units.from_si(Quantity::Angle, e[k]));
                }
            }
            None => out.push_str(",,,"),
        }
        out.push('\n');
    }
    out
}

/// Writes a postures file.
pub fn write_postures(robot: &Robot, postures: &[Posture]) -> String {
    let mut out = postures_header(robot).join(",");
    out.push('\n');
    for p in postures {
        out.push_str(&p.label);
        for v in &p.readings {
            let _ = write!(out, ",{v}");
        }
        out.push('\n');
    }
    out
}

/// Rewrites a CSV whose columns are named or ordered otherwise into kinecal's measurement
/// layout. `mapping` pairs kinecal's column names (`posture`, `site`, `v1`..`vn`, `x`, `y`, `z`,
/// `alpha`, `beta`, `gamma`) with the file's header names, e.g. `("v1", "q1")`; a kinecal column
/// not in the mapping is looked up under its own name. `site` may be missing (every row is
/// then the end effector) and so may the three angles (position-only rows); columns the mapping
/// does not use are ignored. Line numbers are preserved, so later errors still point into the
/// original file.
pub fn remap_columns(
    text: &str,
    file: &str,
    mapping: &[(String, String)],
    robot: &Robot,
) -> Result<String> {
    let loc = Location::file(file);
    let canonical = measurement_header(robot);
    for (ours, _) in mapping {
        if !canonical.contains(ours) {
            return Err(Error::input(
                loc.clone(),
                format!(
                    "--columns: `{ours}` is not a kinecal column (expected one of {})",
                    canonical.join(", ")
                ),
            ));
        }
    }
    let mut lines = text.lines();
    let header_line = lines
        .next()
        .ok_or_else(|| Error::input(loc.at_line(1), "empty file: a header line is required"))?;
    let mut hdr = csv::ReaderBuilder::new()
        .has_headers(false)
        .trim(csv::Trim::All)
        .from_reader(header_line.as_bytes());
    let theirs: Vec<String> = match hdr.records().next() {
        Some(Ok(r)) => r.iter().map(str::to_string).collect(),
        _ => return Err(Error::input(loc.at_line(1), "unreadable header")),
    };
    let mut source: Vec<Option<usize>> = Vec::new();
    for col in &canonical {
        let name = mapping
            .iter()
            .find(|(o, _)| o == col)
            .map_or(col.as_str(), |(_, t)| t.as_str());
        let idx = theirs.iter().position(|h| h == name);
        let optional = matches!(col.as_str(), "site" | "alpha" | "beta" | "gamma");
        if idx.is_none() && !optional {
            return Err(Error::input(
                loc.at_line(1).with_field(name),
                format!(
                    "no column `{name}` (for kinecal's `{col}`) in the header `{}`",
                    theirs.join(",")
                ),
            ));
        }
        source.push(idx);
    }
    let mut out = canonical.join(",");
    out.push('\n');
    for (i, line) in lines.enumerate() {
        if line.trim().is_empty() || line.trim_start().starts_with('#') {
            out.push_str(line);
            out.push('\n');
            continue;
        }
        let mut rdr = csv::ReaderBuilder::new()
            .has_headers(false)
            .trim(csv::Trim::All)
            .from_reader(line.as_bytes());
        let rec = match rdr.records().next() {
            Some(Ok(r)) => r,
            _ => return Err(Error::input(loc.at_line(i + 2), "unreadable CSV row")),
        };
        if rec.len() != theirs.len() {
            return Err(Error::input(
                loc.at_line(i + 2),
                format!(
                    "expected {} columns ({}), found {}",
                    theirs.len(),
                    theirs.join(","),
                    rec.len()
                ),
            ));
        }
        let fields: Vec<&str> = source.iter().map(|s| s.map_or("", |k| &rec[k])).collect();
        out.push_str(&fields.join(","));
        out.push('\n');
    }
    Ok(out)
}

/// Parses a `--columns` value: `ours=theirs,...`.
pub fn parse_column_mapping(spec: &str) -> Result<Vec<(String, String)>> {
    spec.split(',')
        .map(|part| {
            let (a, b) = part.split_once('=').ok_or_else(|| {
                Error::input(
                    Location::file("--columns"),
                    format!("`{part}`: expected KINECAL_COLUMN=FILE_COLUMN, e.g. v1=q1"),
                )
            })?;
            Ok((a.trim().to_string(), b.trim().to_string()))
        })
        .collect()
}
