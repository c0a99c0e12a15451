//! A camera's lens as ROS's `camera_info` YAML, as `camera_calibration_parsers` writes and
//! reads it (`image_width`, `image_height`, `camera_name`, `camera_matrix`, `distortion_model`,
//! `distortion_coefficients`, `rectification_matrix`, `projection_matrix`): written with every
//! digit ([`write_camera_info`]) and read back ([`parse_camera_info`]), a ROS calibration's file
//! as well as kinecal's.
//!
//! The camera's pose (hand-eye) is not part of `camera_info`: the robot file holds it.

use crate::error::{Error, Location, Result, Setting};
use crate::model::camera::Camera;
use crate::model::robot::Robot;

/// The camera of `robot` called `name`, or its only camera when `name` is `None`; an error
/// naming [`Setting::Camera`] otherwise.
pub fn camera_index(robot: &Robot, name: Option<&str>) -> Result<usize> {
    let invalid = |message: String| Error::InvalidOption {
        setting: Setting::Camera,
        message,
    };
    let names = robot
        .cameras
        .iter()
        .map(|c| c.name.as_str())
        .collect::<Vec<_>>()
        .join(", ");
    match name.map(str::trim) {
        Some(name) => robot.camera_index(name).ok_or_else(|| {
            invalid(format!(
                "unknown camera `{name}` (the robot file's [[cameras]]: {})",
                if names.is_empty() { "none" } else { &names }
            ))
        }),
        None if robot.cameras.len() == 1 => Ok(0),
        None if robot.cameras.is_empty() => Err(invalid(
            "the robot file has no [[cameras]]: a camera_info holds a camera's lens".into(),
        )),
        None => Err(invalid(format!(
            "the robot file has {} cameras ({names}): name one",
            robot.cameras.len()
        ))),
    }
}

/// The `camera_info` YAML of camera `camera` of `robot` (its only one when `None`), read back
/// to the same bits before it is returned; and the lens it holds.
pub fn export_camera_info(robot: &Robot, camera: Option<&str>) -> Result<(CameraInfo, String)> {
    let c = camera_index(robot, camera)?;
    let info = CameraInfo::of(&robot.cameras[c]);
    let text = write_camera_info(&info);
    let back = parse_camera_info(&text, "the camera_info written")?;
    if back != info {
        return Err(Error::Problem(format!(
            "the camera_info of camera `{}` reads back as {back:?}, not {info:?}",
            info.name
        )));
    }
    Ok((info, text))
}

/// `robot` with the lens of a `camera_info` file (`text`, named `file` in errors) put into its
/// camera `camera` (its only one when `None`): a lens calibrated by ROS, brought into kinecal.
pub fn with_camera_info(
    robot: &Robot,
    camera: Option<&str>,
    text: &str,
    file: &str,
) -> Result<Robot> {
    let c = camera_index(robot, camera)?;
    let info = parse_camera_info(text, file)?;
    let mut out = robot.clone();
    info.apply(&mut out.cameras[c]);
    out.cameras[c]
        .validate()
        .map_err(|m| Error::input(Location::file(file), m))?;
    Ok(out)
}

/// The lens of a `camera_info` file.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct CameraInfo {
    /// `camera_name`.
    pub name: String,
    /// `image_width` (pixels).
    pub width: u32,
    /// `image_height` (pixels).
    pub height: u32,
    /// `fx, fy, cx, cy` from `camera_matrix` (pixels).
    pub intrinsics: [f64; 4],
    /// `k1, k2, p1, p2, k3` (`distortion_coefficients` of `plumb_bob`; missing ones 0).
    pub distortion: [f64; 5],
}

impl CameraInfo {
    /// The lens of `camera`.
    pub fn of(camera: &Camera) -> CameraInfo {
        CameraInfo {
            name: camera.name.clone(),
            width: camera.width,
            height: camera.height,
            intrinsics: [camera.fx, camera.fy, camera.cx, camera.cy],
            distortion: camera.distortion,
        }
    }

    /// Puts the lens into `camera` (its name and pose kept).
    pub fn apply(&self, camera: &mut Camera) {
        [camera.fx, camera.fy, camera.cx, camera.cy] = self.intrinsics;
        camera.distortion = self.distortion;
        camera.width = self.width;
        camera.height = self.height;
    }
}

/// A number with every digit it has (Rust's shortest round-trip form, never an exponent, which
/// YAML 1.1 readers such as PyYAML would take for a string).
fn number(v: f64) -> String {
    let s = format!("{v}");
    if s.contains('.') || s.contains("inf") || s.contains("NaN") {
        s
    } else {
        // A whole number as a float (`600.0`): the matrices are of doubles.
        format!("{s}.0")
    }
}

fn data(values: &[f64]) -> String {
    values
        .iter()
        .map(|&v| number(v))
        .collect::<Vec<_>>()
        .join(", ")
}

/// A YAML scalar for a name: plain when it is safe, double-quoted otherwise.
fn name_scalar(name: &str) -> String {
    let plain = !name.is_empty()
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "_-./".contains(c))
        && !name.chars().next().is_some_and(|c| "-.".contains(c))
        && !matches!(
            name.to_ascii_lowercase().as_str(),
            "true" | "false" | "yes" | "no" | "on" | "off" | "null" | "y" | "n"
        )
        && name.parse::<f64>().is_err();
    if plain {
        return name.to_string();
    }
    let mut out = String::from("\"");
    for c in name.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            c if (c as u32) < 0x20 => out.push_str(&format!("\\x{:02x}", c as u32)),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

/// The `camera_info` YAML of `info`, laid out as `camera_calibration_parsers` writes it.
pub fn write_camera_info(info: &CameraInfo) -> String {
    let [fx, fy, cx, cy] = info.intrinsics;
    let matrix = |name: &str, rows: usize, cols: usize, values: &[f64]| {
        format!(
            "{name}:\n  rows: {rows}\n  cols: {cols}\n  data: [{}]\n",
            data(values)
        )
    };
    let mut out = format!(
        "image_width: {}\nimage_height: {}\ncamera_name: {}\n",
        info.width,
        info.height,
        name_scalar(&info.name)
    );
    out += &matrix(
        "camera_matrix",
        3,
        3,
        &[fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0],
    );
    out += "distortion_model: plumb_bob\n";
    out += &matrix("distortion_coefficients", 1, 5, &info.distortion);
    out += &matrix(
        "rectification_matrix",
        3,
        3,
        &[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
    );
    out += &matrix(
        "projection_matrix",
        3,
        4,
        &[fx, 0.0, cx, 0.0, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0],
    );
    out
}

/// One top-level key of the file: its line and its value (a scalar, or the nested keys'
/// lines and values).
struct Entry {
    line: usize,
    value: String,
    nested: Vec<(String, usize, String)>,
}

/// Reads a `camera_info` YAML file (the subset ROS writes: top-level keys, matrices as
/// `rows`, `cols` and a flow sequence `data: [...]`, which may span lines). `file` names it in
/// errors.
pub fn parse_camera_info(text: &str, file: &str) -> Result<CameraInfo> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let entries = Entries {
        file,
        list: read_entries(text, file)?,
    };
    let width = entries.pixels("image_width")?;
    let height = entries.pixels("image_height")?;
    let name = entries.camera_name();
    entries.check_distortion_model()?;
    let intrinsics = entries.intrinsics()?;
    let distortion = entries.distortion()?;
    Ok(CameraInfo {
        name,
        width,
        height,
        intrinsics,
        distortion,
    })
}

/// An input error at 1-based `line` of `file`, naming `field` (a key, `parent.key`, or the
/// offending text).
fn field_error(file: &str, line: usize, field: &str, message: String) -> Error {
    Error::input(
        Location {
            file: file.to_string(),
            line: Some(line),
            field: Some(field.to_string()),
        },
        message,
    )
}

/// The top-level keys of a `camera_info` file's `text` (its BOM already removed; `file` names
/// it in errors), in file order, each with its 1-based line, its value and its nested keys.
fn read_entries(text: &str, file: &str) -> Result<Vec<(String, Entry)>> {
    let lines: Vec<&str> = text.lines().collect();
    let mut entries: Vec<(String, Entry)> = Vec::new();
    let mut i = 0;
    while i < lines.len() {
        let raw = lines[i];
        let n = i + 1;
        i += 1;
        let content = strip_comment(raw);
        if content.trim().is_empty() || content.trim() == "---" || content.trim() == "..." {
            continue;
        }
        let indented = content.starts_with(' ') || content.starts_with('\t');
        let trimmed = content.trim();
        // A block sequence's item (`- 500.5`, as PyYAML dumps lists): onto the last key's list.
        if trimmed == "-" || trimmed.starts_with("- ") {
            push_list_item(&mut entries, n, trimmed[1..].trim(), file)?;
            continue;
        }
        let Some((key, value)) = trimmed.split_once(':') else {
            return Err(field_error(
                file,
                n,
                content.trim(),
                "expected `key: value` (a camera_info YAML file)".into(),
            ));
        };
        let (key, mut value) = (key.trim().to_string(), value.trim().to_string());
        // A flow sequence spanning lines: read on to its `]`.
        if value.starts_with('[') {
            i = read_flow_sequence(&lines, i, &mut value, n, &key, file)?;
        }
        push_key(&mut entries, n, key, value, indented, file)?;
    }
    Ok(entries)
}

/// Appends block-sequence `item` (at 1-based `line`) to the last nested key's value, kept as
/// an unclosed flow sequence `[a, b`; an error outside a matrix or after a value.
fn push_list_item(
    entries: &mut [(String, Entry)],
    line: usize,
    item: &str,
    file: &str,
) -> Result<()> {
    let Some(value) = entries
        .last_mut()
        .and_then(|(_, e)| e.nested.last_mut())
        .map(|(_, _, v)| v)
    else {
        return Err(field_error(
            file,
            line,
            item,
            "a list item outside any matrix".into(),
        ));
    };
    if value.is_empty() {
        *value = format!("[{item}");
    } else if value.starts_with('[') && !value.contains(']') {
        value.push_str(", ");
        value.push_str(item);
    } else {
        return Err(field_error(
            file,
            line,
            item,
            "a list item after a value".into(),
        ));
    }
    Ok(())
}

/// Appends to `value` (key `key`'s flow sequence, begun at 1-based `line`) the lines from
/// index `next` on until its `]`; returns the index of the line after it.
fn read_flow_sequence(
    lines: &[&str],
    next: usize,
    value: &mut String,
    line: usize,
    key: &str,
    file: &str,
) -> Result<usize> {
    let mut i = next;
    while !value.contains(']') && i < lines.len() {
        value.push(' ');
        value.push_str(strip_comment(lines[i]).trim());
        i += 1;
    }
    if !value.contains(']') {
        return Err(field_error(file, line, key, "a `[` without its `]`".into()));
    }
    Ok(i)
}

/// Adds `key: value` (at 1-based `line`): nested under the last top-level key when
/// `indented`, else a new top-level key; an error for a key given twice or misplaced.
fn push_key(
    entries: &mut Vec<(String, Entry)>,
    line: usize,
    key: String,
    value: String,
    indented: bool,
    file: &str,
) -> Result<()> {
    if indented {
        let Some((parent, entry)) = entries.last_mut() else {
            return Err(field_error(
                file,
                line,
                &key,
                "an indented key outside any matrix".into(),
            ));
        };
        if !entry.value.is_empty() {
            return Err(field_error(
                file,
                line,
                &format!("{parent}.{key}"),
                format!("`{parent}` has a value: it holds no keys"),
            ));
        }
        entry.nested.push((key, line, value));
    } else {
        if entries.iter().any(|(k, _)| *k == key) {
            return Err(field_error(
                file,
                line,
                &key,
                format!("`{key}` given twice"),
            ));
        }
        entries.push((
            key,
            Entry {
                line,
                value,
                nested: Vec::new(),
            },
        ));
    }
    Ok(())
}

/// A `camera_info` file's top-level keys (as [`read_entries`] reads them) and the file's
/// name, for errors.
struct Entries<'a> {
    file: &'a str,
    list: Vec<(String, Entry)>,
}

impl Entries<'_> {
    /// The entry of top-level `key`, if the file has it.
    fn get(&self, key: &str) -> Option<&Entry> {
        self.list.iter().find(|(k, _)| k == key).map(|(_, e)| e)
    }

    /// The entry of top-level `key`; an error naming the file (no line) when it has none.
    fn need(&self, key: &str) -> Result<&Entry> {
        self.get(key).ok_or_else(|| {
            Error::input(
                Location::file(self.file),
                format!("no `{key}`: not a camera_info YAML file"),
            )
        })
    }

    /// The value of required key `key` (`image_width`, `image_height`) as a positive whole
    /// number of pixels.
    fn pixels(&self, key: &str) -> Result<u32> {
        let e = self.need(key)?;
        e.value
            .parse::<u32>()
            .ok()
            .filter(|&v| v > 0)
            .ok_or_else(|| {
                field_error(
                    self.file,
                    e.line,
                    key,
                    format!("expected a positive number of pixels, not `{}`", e.value),
                )
            })
    }

    /// `camera_name`, unquoted; empty when the file has none.
    fn camera_name(&self) -> String {
        match self.get("camera_name") {
            Some(e) => unquote(&e.value),
            None => String::new(),
        }
    }

    /// Checks `distortion_model`, when given, is `plumb_bob` or `rational_polynomial`.
    fn check_distortion_model(&self) -> Result<()> {
        if let Some(e) = self.get("distortion_model") {
            let model = unquote(&e.value);
            if model != "plumb_bob" && model != "rational_polynomial" {
                return Err(field_error(
                    self.file,
                    e.line,
                    "distortion_model",
                    format!(
                        "`{model}`: kinecal's lens is OpenCV's plumb_bob (k1, k2, p1, p2, k3); \
                         equidistant (fisheye) lenses are not modelled"
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The numbers (row-major) of required matrix `key`: `rows` x `cols` of them, its `rows`
    /// and `cols` checked when given; with `rows * cols` 0, any count of at least `at_least`.
    fn matrix(&self, key: &str, rows: usize, cols: usize, at_least: usize) -> Result<Vec<f64>> {
        let e = self.need(key)?;
        let field = |k: &str| e.nested.iter().find(|(n, _, _)| n == k);
        for (k, want) in [("rows", rows), ("cols", cols)] {
            if let Some((_, line, v)) = field(k) {
                if want > 0 && v.parse::<usize>().ok() != Some(want) {
                    return Err(field_error(
                        self.file,
                        *line,
                        &format!("{key}.{k}"),
                        format!("expected {want}, not `{v}`"),
                    ));
                }
            }
        }
        let Some((_, line, v)) = field("data") else {
            return Err(field_error(
                self.file,
                e.line,
                key,
                format!("`{key}` has no `data`"),
            ));
        };
        let values = data_values(self.file, *line, key, v)?;
        let expected = if rows * cols > 0 {
            rows * cols
        } else {
            at_least
        };
        if values.len() < at_least || (rows * cols > 0 && values.len() != expected) {
            return Err(field_error(
                self.file,
                *line,
                &format!("{key}.data"),
                format!("expected {expected} numbers, found {}", values.len()),
            ));
        }
        Ok(values)
    }

    /// `fx, fy, cx, cy` (pixels) from `camera_matrix`, which must be
    /// `[fx, 0, cx, 0, fy, cy, 0, 0, 1]` (no skew) with fx and fy positive.
    fn intrinsics(&self) -> Result<[f64; 4]> {
        let k = self.matrix("camera_matrix", 3, 3, 9)?;
        let line = self.need("camera_matrix")?.line;
        if [k[1], k[3], k[6], k[7]].iter().any(|&v| v != 0.0) || (k[8] - 1.0).abs() > 1e-12 {
            return Err(field_error(
                self.file,
                line,
                "camera_matrix.data",
                "expected [fx, 0, cx, 0, fy, cy, 0, 0, 1] (no skew)".into(),
            ));
        }
        let intrinsics = [k[0], k[4], k[2], k[5]];
        if !(intrinsics[0] > 0.0 && intrinsics[1] > 0.0) {
            return Err(field_error(
                self.file,
                line,
                "camera_matrix.data",
                format!(
                    "fx and fy must be positive, not {} and {}",
                    intrinsics[0], intrinsics[1]
                ),
            ));
        }
        Ok(intrinsics)
    }

    /// `k1, k2, p1, p2, k3` from `distortion_coefficients` (missing ones 0; all 0 without the
    /// key); an error when the rational model's k4, k5, k6 are not 0.
    fn distortion(&self) -> Result<[f64; 5]> {
        let mut distortion = [0.0; 5];
        if self.get("distortion_coefficients").is_some() {
            let d = self.matrix("distortion_coefficients", 0, 0, 0)?;
            let e = self.need("distortion_coefficients")?;
            if d.len() > 5 && d[5..].iter().any(|&v| v != 0.0) {
                return Err(field_error(
                    self.file,
                    e.line,
                    "distortion_coefficients.data",
                    format!(
                        "{} coefficients: kinecal's lens has five (k1, k2, p1, p2, k3); the \
                         rational model's k4, k5, k6 must be 0",
                        d.len()
                    ),
                ));
            }
            for (slot, v) in distortion.iter_mut().zip(&d) {
                *slot = *v;
            }
        }
        Ok(distortion)
    }
}

/// The finite numbers of matrix `key`'s `data` value `v` (a flow sequence, or a block
/// sequence read as an unclosed `[a, b`), at 1-based `line` of `file`.
fn data_values(file: &str, line: usize, key: &str, v: &str) -> Result<Vec<f64>> {
    // A block sequence read as `[a, b` (its items, without a closing bracket).
    let v = if v.starts_with('[') && !v.contains(']') {
        format!("{v}]")
    } else {
        v.to_string()
    };
    let inner = v
        .trim()
        .strip_prefix('[')
        .and_then(|s| s.trim_end().strip_suffix(']'))
        .ok_or_else(|| {
            field_error(
                file,
                line,
                &format!("{key}.data"),
                "expected a list `[a, b, ...]`".into(),
            )
        })?;
    inner
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| {
            s.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    field_error(
                        file,
                        line,
                        &format!("{key}.data"),
                        format!("`{s}` is not a finite number"),
                    )
                })
        })
        .collect()
}

/// A line without its comment (`#` at the start or after a space, outside quotes).
fn strip_comment(line: &str) -> &str {
    let mut quote: Option<char> = None;
    let mut prev = ' ';
    for (i, c) in line.char_indices() {
        match quote {
            Some(q) if c == q => quote = None,
            Some(_) => {}
            None if c == '"' || c == '\'' => quote = Some(c),
            None if c == '#' && prev.is_whitespace() => return &line[..i],
            None => {}
        }
        prev = c;
    }
    line
}

/// A YAML scalar's text: quotes removed (with `\"` and `\\` in double quotes, `''` in single).
fn unquote(v: &str) -> String {
    let v = v.trim();
    if let Some(inner) = v.strip_prefix('"').and_then(|s| s.strip_suffix('"')) {
        inner.replace("\\\"", "\"").replace("\\\\", "\\")
    } else if let Some(inner) = v.strip_prefix('\'').and_then(|s| s.strip_suffix('\'')) {
        inner.replace("''", "'")
    } else {
        v.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn info() -> CameraInfo {
        CameraInfo {
            name: "wrist".into(),
            width: 640,
            height: 480,
            intrinsics: [600.123456789012, 610.0, 320.5, 239.99999999999997],
            distortion: [-0.2, 0.01, 1e-4, -3.3e-5, 0.1 + 0.2],
        }
    }

    #[test]
    fn written_files_read_back_to_the_same_bits() {
        let text = write_camera_info(&info());
        assert!(text.starts_with("image_width: 640\nimage_height: 480\ncamera_name: wrist\n"));
        assert!(text.contains(
            "projection_matrix:\n  rows: 3\n  cols: 4\n  data: [600.123456789012, 0.0, 320.5, \
             0.0, 0.0, 610.0, 239.99999999999997, 0.0, 0.0, 0.0, 1.0, 0.0]\n"
        ));
        assert!(!text.contains('E') && !text.contains("e-"), "{text}");
        let back = parse_camera_info(&text, "wrist.yaml").unwrap();
        assert_eq!(back, info());
        // An odd name is quoted and comes back.
        let odd = CameraInfo {
            name: "left cam: \"A\"".into(),
            ..info()
        };
        let back = parse_camera_info(&write_camera_info(&odd), "odd.yaml").unwrap();
        assert_eq!(back.name, odd.name);
    }

    #[test]
    fn ros_s_own_layout_reads() {
        // As camera_calibration's cameracalibrator writes it: matrices over several lines.
        let text = "image_width: 1280\nimage_height: 1024\ncamera_name: narrow_stereo\n\
            camera_matrix:\n  rows: 3\n  cols: 3\n  data: [ 1034.5,    0.     ,  640.25,\n\
            \x20      0.     , 1035.75,  512.5 ,\n         0.     ,    0.     ,    1.     ]\n\
            distortion_model: plumb_bob  # OpenCV's\ndistortion_coefficients:\n  rows: 1\n\
            \x20 cols: 5\n  data: [-0.3, 0.1, 0.001, -0.002, 0.]\n";
        let c = parse_camera_info(text, "ros.yaml").unwrap();
        // Exact: the text's numbers read to the same doubles.
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&c.intrinsics), bits(&[1034.5, 1035.75, 640.25, 512.5]));
        // Lists as block sequences (PyYAML's dump), keys in any order.
        let block = "camera_matrix:\n  cols: 3\n  data:\n  - 1034.5\n  - 0\n  - 640.25\n  - 0\n  \
            - 1035.75\n  - 512.5\n  - 0\n  - 0\n  - 1\n  rows: 3\nimage_height: 1024\n\
            image_width: 1280\n";
        let b = parse_camera_info(block, "dump.yaml").unwrap();
        assert_eq!(bits(&b.intrinsics), bits(&c.intrinsics));
        assert_eq!(bits(&b.distortion), bits(&[0.0; 5]));
        assert_eq!(bits(&c.distortion), bits(&[-0.3, 0.1, 0.001, -0.002, 0.0]));
        assert_eq!((c.width, c.height), (1280, 1024));
    }

    #[test]
    fn bad_files_name_the_line_and_the_field() {
        let good = write_camera_info(&info());
        for (bad, expected) in [
            (
                good.replace("image_width: 640", "image_width: -3"),
                "wrist.yaml:1: field `image_width`: expected a positive number",
            ),
            (
                good.replace("data: [-0.2", "data: [x"),
                "field `distortion_coefficients.data`: `x` is not a finite number",
            ),
            (
                good.replace("plumb_bob", "equidistant"),
                "field `distortion_model`: `equidistant`",
            ),
            (
                good.replace(
                    "data: [600.123456789012, 0.0, 320.5, 0.0, 610",
                    "data: [1, 2",
                ),
                "camera_matrix.data",
            ),
            (
                good.replace("camera_matrix", "camera_matrx"),
                "no `camera_matrix`",
            ),
        ] {
            let e = parse_camera_info(&bad, "wrist.yaml")
                .unwrap_err()
                .to_string();
            assert!(e.contains(expected), "{e}\n{bad}");
        }
    }
}
