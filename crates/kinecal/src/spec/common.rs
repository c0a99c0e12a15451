//! What every spec shares: reading a spec from TOML or JSON with errors that name the line and
//! the key, paths relative to the spec file, robots by file or built-in name, and the settings
//! several jobs have (a length and an angle, residual weights).

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Location, Result, Setting};
use crate::model::robot::Robot;
use crate::observe::{OrientationError, Weights};
use crate::source::Source;
use crate::units::Quantity;

use super::JobKind;

/// Whether `t` is its type's default (for `skip_serializing_if`).
pub(crate) fn is_default<T: Default + PartialEq>(t: &T) -> bool {
    *t == T::default()
}

/// An [`Error::InvalidOption`].
pub(crate) fn invalid(setting: Setting, message: impl Into<String>) -> Error {
    Error::InvalidOption {
        setting,
        message: message.into(),
    }
}

/// The 1-based line of byte `offset` in `text`.
fn line_of(text: &str, offset: usize) -> usize {
    text[..offset.min(text.len())].matches('\n').count() + 1
}

/// The kind of job `name` names, or an error naming the kinds.
pub(crate) fn kind_named(name: &str, file: &str) -> Result<JobKind> {
    JobKind::parse(name).ok_or_else(|| {
        Error::input(
            Location::file(file).with_field("job"),
            format!(
                "unknown job `{name}` (expected one of {})",
                JobKind::ALL.map(JobKind::name).join(", ")
            ),
        )
    })
}

/// TOML `text` (named `file` in errors) parsed, refused with the line of a syntax error or of a
/// number that is not finite.
fn parse_document<'t>(text: &'t str, file: &str) -> Result<toml_edit::Document<&'t str>> {
    let doc = toml_edit::Document::parse(text).map_err(|e| {
        let line = e.span().map(|s| line_of(text, s.start));
        Error::input(
            Location {
                file: file.to_string(),
                line,
                field: None,
            },
            e.message().trim().to_string(),
        )
    })?;
    check_finite(doc.as_table(), text, file, "")?;
    Ok(doc)
}

/// The kind of job a TOML spec names in its top-level `job` key, and the text with that key
/// blanked out (every other line where it was, so that errors keep their lines).
pub(crate) fn take_job_key(text: &str, file: &str) -> Result<(Option<JobKind>, String)> {
    let doc = parse_document(text, file)?;
    let Some((key, item)) = doc.get_key_value("job") else {
        return Ok((None, text.to_string()));
    };
    let at = |span: Option<std::ops::Range<usize>>| {
        Location {
            file: file.to_string(),
            line: span.map(|s| line_of(text, s.start)),
            field: None,
        }
        .with_field("job")
    };
    let name = item
        .as_str()
        .ok_or_else(|| Error::input(at(item.span()), "expected the name of a job, in quotes"))?;
    let kind = kind_named(name, file).map_err(|e| match e {
        Error::Input { message, .. } => Error::input(at(item.span()), message),
        e => e,
    })?;
    let (Some(k), Some(v)) = (key.span(), item.span()) else {
        unreachable!("a parsed document has spans")
    };
    let mut rest = text.as_bytes().to_vec();
    for b in &mut rest[k.start..v.end] {
        if *b != b'\n' {
            *b = b' ';
        }
    }
    let rest = String::from_utf8(rest).expect("ASCII spaces over whole characters");
    Ok((Some(kind), rest))
}

/// Refuses a number that is not finite anywhere in `table` (TOML reads `nan` and `inf`),
/// naming its key and line.
fn check_finite(table: &toml_edit::Table, text: &str, file: &str, prefix: &str) -> Result<()> {
    fn value(v: &toml_edit::Value, key: &str, text: &str, file: &str) -> Result<()> {
        match v {
            toml_edit::Value::Float(f) if !f.value().is_finite() => Err(Error::input(
                Location {
                    file: file.to_string(),
                    line: v.span().map(|s| line_of(text, s.start)),
                    field: Some(key.to_string()),
                },
                format!("expected a finite number, not {}", f.value()),
            )),
            toml_edit::Value::Array(a) => a.iter().try_for_each(|v| value(v, key, text, file)),
            toml_edit::Value::InlineTable(t) => t
                .iter()
                .try_for_each(|(k, v)| value(v, &format!("{key}.{k}"), text, file)),
            _ => Ok(()),
        }
    }
    for (k, item) in table.iter() {
        let key = if prefix.is_empty() {
            k.to_string()
        } else {
            format!("{prefix}.{k}")
        };
        match item {
            toml_edit::Item::Value(v) => value(v, &key, text, file)?,
            toml_edit::Item::Table(t) => check_finite(t, text, file, &key)?,
            toml_edit::Item::ArrayOfTables(a) => {
                for t in a.iter() {
                    check_finite(t, text, file, &key)?;
                }
            }
            toml_edit::Item::None => {}
        }
    }
    Ok(())
}

/// A spec read from TOML `text` (named `file` in errors; no `job` key): unknown keys, wrong
/// types and numbers that are not finite are errors with the line and the key.
pub(crate) fn from_toml<T: serde::de::DeserializeOwned>(text: &str, file: &str) -> Result<T> {
    parse_document(text, file)?;
    toml_edit::de::from_str(text).map_err(|e| {
        let loc = Location {
            file: file.to_string(),
            line: e.span().map(|s| line_of(text, s.start)),
            field: None,
        };
        Error::input(loc, e.message().trim().to_string())
    })
}

/// A spec from a JSON value (Python's dicts; no `job` key): errors name the key path.
pub(crate) fn from_value<T: serde::de::DeserializeOwned>(
    value: serde_json::Value,
    file: &str,
) -> Result<T> {
    serde_path_to_error::deserialize(value).map_err(|e| {
        let path = e.path().to_string();
        let at = Location::file(file);
        let at = if path == "." { at } else { at.with_field(path) };
        Error::input(at, e.into_inner().to_string())
    })
}

/// `p` taken relative to `base` (absolute paths, `-` and an empty base leave it as it is).
pub(crate) fn rebase(base: &Path, p: &str) -> String {
    if base.as_os_str().is_empty() || Path::new(p).is_absolute() || p == "-" {
        p.to_string()
    } else {
        base.join(p).to_string_lossy().into_owned()
    }
}

/// Whether a history's location is a server's URL (`postgres://...`), not a file.
pub(crate) fn is_url(p: &str) -> bool {
    p.contains("://")
}

/// A robot name relative to `base`: a built-in robot's name stays as it is unless a file of
/// that name is there.
pub(crate) fn rebase_robot(base: &Path, name: &str) -> String {
    let file = rebase(base, name);
    if crate::model::examples::builtin(name).is_some() && !Path::new(&file).exists() {
        name.to_string()
    } else {
        file
    }
}

/// Whether the robot `name` is a file (or will be read as one), not a built-in robot.
pub(crate) fn is_robot_file(name: &str) -> bool {
    Path::new(name).exists() || crate::model::examples::builtin(name).is_none()
}

/// Calls `f` on an optional path.
pub(crate) fn visit_opt(
    f: &mut dyn FnMut(super::PathRole, &mut String),
    role: super::PathRole,
    p: &mut Option<String>,
) {
    if let Some(p) = p {
        f(role, p);
    }
}

/// Calls `f` on the path of every observation file, as input.
pub(crate) fn visit_observations(
    f: &mut dyn FnMut(super::PathRole, &mut String),
    observations: &mut [crate::files::ObservationFile],
) {
    for o in observations {
        f(super::PathRole::Input, &mut o.file);
    }
}

/// A length and an angle in the robot file's units, either or both: residual standard
/// deviations (`weights`), tolerances. Written `{ length = 0.05, angle = 0.01 }` in a spec and
/// `length=0.05,angle=0.01` on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LengthAngle {
    /// The length (robot file's length unit).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub length: Option<f64>,
    /// The angle (robot file's angle unit).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub angle: Option<f64>,
}

impl LengthAngle {
    /// Reads `length=L,angle=A` (either or both) for `setting`; numbers must be finite and not
    /// negative.
    pub fn parse(text: &str, setting: Setting) -> Result<LengthAngle> {
        let mut out = LengthAngle::default();
        for part in text.split(',').map(str::trim) {
            let (k, v) = part.split_once('=').ok_or_else(|| {
                invalid(
                    setting,
                    format!("`{text}`: expected length=L,angle=A (either or both)"),
                )
            })?;
            let v: f64 = v
                .trim()
                .parse()
                .ok()
                .filter(|v: &f64| v.is_finite())
                .ok_or_else(|| {
                    invalid(
                        setting,
                        format!("`{text}`: `{}` is not a finite number", v.trim()),
                    )
                })?;
            let slot = match k.trim() {
                "length" => &mut out.length,
                "angle" => &mut out.angle,
                other => {
                    return Err(invalid(
                        setting,
                        format!("`{text}`: unknown key `{other}` (expected length, angle)"),
                    ))
                }
            };
            *slot = Some(v);
        }
        out.check(setting, false)?;
        Ok(out)
    }

    /// Refuses numbers that are not finite, negative, or (with `positive`) zero.
    pub(crate) fn check(&self, setting: Setting, positive: bool) -> Result<()> {
        for (name, v) in [("length", self.length), ("angle", self.angle)] {
            if let Some(v) = v {
                if !v.is_finite() || v < 0.0 || (positive && v == 0.0) {
                    return Err(invalid(
                        setting,
                        format!(
                            "the {name} must be {} and finite, not {v}",
                            if positive { "positive" } else { "non-negative" }
                        ),
                    ));
                }
            }
        }
        Ok(())
    }

    /// The two in SI (metres, radians) for `robot`, or `None` where not given.
    pub(crate) fn si(&self, robot: &Robot) -> (Option<f64>, Option<f64>) {
        (
            self.length.map(|v| robot.units.to_si(Quantity::Length, v)),
            self.angle.map(|v| robot.units.to_si(Quantity::Angle, v)),
        )
    }
}

/// Refuses a noise no instrument has, so that the file a simulation writes can be read back
/// (a noise of 1e300 wrote coordinates the readers refuse): `[length, angle, pixel]` in
/// `robot`'s file units and pixels, at most the robot's reach, half a turn, and the larger
/// side of the robot file's largest image.
pub(crate) fn check_noise(setting: Setting, robot: &Robot, noise: [Option<f64>; 3]) -> Result<()> {
    let units = robot.units;
    let image = robot
        .cameras
        .iter()
        .map(|c| c.width.max(c.height))
        .max()
        .map_or(f64::INFINITY, f64::from);
    let most = [
        (
            "length",
            Quantity::Length,
            robot.reach(),
            "the robot's reach",
        ),
        (
            "angle",
            Quantity::Angle,
            std::f64::consts::PI,
            "half a turn",
        ),
        (
            "pixel",
            Quantity::Pixel,
            image,
            "the larger side of the robot file's largest image",
        ),
    ];
    for (given, (name, q, bound, what)) in noise.into_iter().zip(most) {
        let Some(v) = given.filter(|&v| units.to_si(q, v) > bound) else {
            continue;
        };
        let unit = units.label(q);
        let v = if v.abs() >= 1e6 {
            format!("{v:e}")
        } else {
            crate::identifiability::fmt_sig(v)
        };
        return Err(invalid(
            setting,
            format!(
                "the {name} noise {v} {unit} is more than any instrument's: at most {} {unit} \
                 ({what})",
                crate::identifiability::fmt_sig(units.from_si(q, bound))
            ),
        ));
    }
    Ok(())
}

/// How residuals are formed, for the jobs that form them without fitting (`[residuals]` of
/// analyze, plan, curves, report): the weights and the orientation residual.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Residuals {
    /// Default residual standard deviations (robot file's units; 1 mm and 1 mrad when absent).
    #[serde(default, skip_serializing_if = "is_default")]
    pub weights: LengthAngle,
    /// Orientation residuals: `rotvec` (default) or `euler`.
    #[serde(default, skip_serializing_if = "is_default")]
    pub orientation_error: OrientationError,
}

impl Residuals {
    /// The weights (SI) and the orientation residual for `robot`.
    pub(crate) fn resolve(&self, robot: &Robot) -> Result<(Weights, OrientationError)> {
        Ok((weights(robot, &self.weights)?, self.orientation_error))
    }
}

/// A count that must be at least 1 and at most `max` (what a machine can hold and finish).
pub(crate) fn count(setting: Setting, n: usize, max: usize, what: &str) -> Result<usize> {
    if n == 0 || n > max {
        return Err(invalid(
            setting,
            format!("expected between 1 and {max} {what}, not {n}"),
        ));
    }
    Ok(n)
}

/// Reads the observation files `list` (as `read` says) for `robot`; `all` are every file of
/// the job (for naming sessions apart).
pub(crate) fn read_observations(
    read: &crate::files::ReadSettings,
    list: &[crate::files::ObservationFile],
    robot: &Robot,
) -> Result<(crate::Dataset, Vec<crate::source::Fingerprint>)> {
    if list.is_empty() {
        return Err(invalid(Setting::Observations, "no observation file given"));
    }
    let all: Vec<&Path> = list.iter().map(|f| Path::new(&f.file)).collect();
    crate::files::read_files(read, list, robot, &all)
}

/// The robot `name` (a file or a built-in name), its errors naming `setting`.
pub(crate) fn robot_as(name: &str, setting: Setting) -> Result<(Robot, crate::source::Source)> {
    if name.is_empty() {
        return Err(invalid(setting, "no robot given"));
    }
    load_robot(name).map_err(|e| match e {
        Error::InvalidOption { message, .. } => invalid(setting, message),
        e => e,
    })
}

/// A text file of the job, read.
pub(crate) fn read_source(path: &str, setting: Setting) -> Result<crate::source::Source> {
    if path.is_empty() {
        return Err(invalid(setting, "no file given"));
    }
    crate::source::Source::read(Path::new(path))
}

/// The residual weights of `w` (robot units) in SI, the defaults where absent.
pub fn weights(robot: &Robot, w: &LengthAngle) -> Result<Weights> {
    let mut out = Weights::default();
    for (value, quantity, slot) in [
        (w.length, Quantity::Length, &mut out.length),
        (w.angle, Quantity::Angle, &mut out.angle),
    ] {
        if let Some(v) = value {
            if !(v > 0.0 && v.is_finite()) {
                return Err(invalid(
                    Setting::Weights,
                    format!("standard deviations must be positive and finite, not {v}"),
                ));
            }
            let si = robot.units.to_si(quantity, v);
            if si < SMALLEST_SIGMA {
                return Err(invalid(
                    Setting::Weights,
                    format!(
                        "a standard deviation of {v:e} {} is below {:.2e} {0}: finer than any \
                         instrument resolves, and the squared residuals it divides overflow",
                        robot.units.label(quantity),
                        robot.units.from_si(quantity, SMALLEST_SIGMA),
                    ),
                ));
            }
            *slot = si;
        }
    }
    Ok(out)
}

/// The smallest standard deviation a weight may state, in SI (1e-15 m, a femtometre; 1e-15
/// rad): a residual of the robot's size over it squared stays far from overflow (1e30), and no
/// instrument resolves less.
const SMALLEST_SIGMA: f64 = 1e-15;

/// Loads a robot: the file `name`, or the built-in robot of that name when no such file
/// exists.
pub fn load_robot(name: &str) -> Result<(Robot, Source)> {
    let path = Path::new(name);
    let source = if path.exists() {
        Source::read(path)?
    } else if let Some(text) = crate::model::examples::builtin(name) {
        Source::text(format!("<built-in {name}>"), text)
    } else {
        return Err(invalid(
            Setting::Robot,
            format!(
                "{name}: no such robot file, and not a built-in robot (built-in: {})",
                crate::model::examples::BUILTIN_NAMES.join(", ")
            ),
        ));
    };
    let robot = crate::model::robot_file::parse_robot_toml(&source.text, &source.name)?;
    Ok((robot, source))
}

/// The parameters a job estimates, from its `estimate` and `fix` keys: `default_list` when
/// `estimate` is absent ([`Selection::parse`](crate::workflow::Selection::parse)). An
/// `estimate` given empty is refused: it reads as "nothing", and running the default set
/// instead would answer a question nobody asked.
pub(crate) fn selection(
    estimate: Option<&str>,
    default_list: &str,
    fix: Option<&str>,
    robot: &Robot,
) -> Result<crate::workflow::Selection> {
    if estimate.is_some_and(|e| e.trim().is_empty()) {
        return Err(invalid(
            Setting::Estimate,
            "an empty parameter list: leave it out for the default parameters, or name them \
             (for example `identifiable`)",
        ));
    }
    // A list that names nothing is refused as the setting it came from, so that each front end
    // names its flag or its key (`--fix: ...`, `job.toml: estimate: ...`).
    crate::workflow::Selection::parse(estimate.unwrap_or(default_list), fix, robot).map_err(|e| {
        match e {
            Error::ParamList { list, message } => invalid(
                if fix.is_some_and(|f| f == list) {
                    Setting::Fix
                } else {
                    Setting::Estimate
                },
                format!("parameter list `{list}`: {message}"),
            ),
            e => e,
        }
    })
}
