//! Python bindings of kinecal: the native module `kinecal._native`, wrapped by the pure-Python
//! package `kinecal` (`python/kinecal/__init__.py`), which adds the result classes; the stub
//! `python/kinecal/_native.pyi` describes this module (checked by stubtest in `test.sh`).
//!
//! Conventions, as in kinecal's files: readings are the transducer values of the robot file
//! (`q = offset + slope * V`); lengths are in the robot's length unit, angles in its angle unit;
//! attitudes are ZYX Euler angles `(alpha, beta, gamma)`, `R = Rz(alpha) Ry(beta) Rx(gamma)`.
//! Every array is checked (shape, dtype, finite and within +-1e9) before any work; bad input
//! raises `kinecal.KinecalError` (a `ValueError`) or `TypeError`, never crashes. Long work
//! (calibration, analysis, planning, compensation, DH and UR exports) runs with the GIL
//! released.

mod accuracy;
mod commands;
mod jobs;
mod outcome;

use std::ffi::CString;
use std::path::PathBuf;
use std::sync::Arc;

use kinecal::files::{detect_format, FORMATS};
use kinecal::import::dh::{robot_from_dh, Convention, DhRow};
use kinecal::model::robot_file::{parse_robot_toml, write_robot_toml_checked};
use kinecal::observe::point::{Pose, Position};
use kinecal::observe::Dataset;
use kinecal::source::Source;
use kinecal::spec::{AnalyzeSpec, CalibrationJob, CalibrationSpec};
use kinecal::units::plausible;
use kinecal::units::Quantity;
use kinecal::{Chain, JointKind, Posture, Target, Units, Workspace};
use nalgebra::Vector3;
use numpy::ndarray::{Array2, Array3, ArrayViewD};
use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArrayDyn};
use pyo3::exceptions::{PyTypeError, PyUserWarning, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyString;

pyo3::create_exception!(
    kinecal,
    KinecalError,
    PyValueError,
    "An error of kinecal: bad input (with `file`, `line` and `field` when it came from a \
     file) or a calibration that cannot be made."
);

pyo3::create_exception!(
    kinecal,
    ExportWarning,
    PyUserWarning,
    "What a robot export leaves to the user: what it cannot hold (a slope a URDF cannot \
     express, ...) with the deviation it leaves at the tool, what it left out (a UR export's \
     measurement frame) and what to enter on the controller (its TCP): the same words as the \
     command line's."
);

/// Issues an [`ExportWarning`].
fn export_warning(py: Python<'_>, message: &str) -> PyResult<()> {
    let message = CString::new(message.replace('\0', " ")).expect("no NUL left");
    PyErr::warn(py, &py.get_type::<ExportWarning>(), &message, 1)
}

/// An export's tolerance: `(length, angle)` in the robot's units, or the default for it.
fn tolerance_of(
    robot: &kinecal::Robot,
    tolerance: Option<(f64, f64)>,
) -> PyResult<kinecal::import::readback::Tolerance> {
    let mut t = kinecal::import::readback::Tolerance::default_for(robot);
    if let Some((l, a)) = tolerance {
        if !(l.is_finite() && a.is_finite() && l >= 0.0 && a >= 0.0) {
            return Err(bad(format!(
                "tolerance: ({l}, {a}) is not two non-negative finite numbers (length, angle)"
            )));
        }
        t.position = robot.units.to_si(Quantity::Length, l);
        t.attitude = robot.units.to_si(Quantity::Angle, a);
    }
    Ok(t)
}

/// A DH convention by name.
fn convention_of(convention: &str) -> PyResult<Convention> {
    match convention {
        "standard" => Ok(Convention::Standard),
        "modified" => Ok(Convention::Modified),
        other => Err(bad(format!(
            "convention `{other}`: expected \"standard\" or \"modified\""
        ))),
    }
}

/// A kinecal error as a Python exception, carrying `file`, `line` and `field` (or None). An
/// error of a function's keywords ([`jobs::KEYWORDS`]) carries its key path in `field`, with
/// `file` None: the Python package words it with the keyword.
fn error(py: Python<'_>, e: kinecal::Error) -> PyErr {
    if let kinecal::Error::Input { at, message } = &e {
        if at.file == jobs::KEYWORDS {
            let err = KinecalError::new_err(message.clone());
            let _ = err.value(py).setattr("field", at.field.clone());
            return err;
        }
    }
    let (file, line, field) = match &e {
        kinecal::Error::Input { at, .. } | kinecal::Error::ChainEnd { at, .. } => {
            (Some(at.file.clone()), at.line, at.field.clone())
        }
        kinecal::Error::Io { path, .. } => (Some(path.clone()), None, None),
        _ => (None, None, None),
    };
    let message = match &e {
        kinecal::Error::InvalidOption { setting, message } => {
            format!("{}: {message}", keyword(*setting))
        }
        kinecal::Error::ChainEnd { setting, .. } => {
            format!("{e} (give {}=LINK)", keyword(*setting))
        }
        _ => e.to_string(),
    };
    let err = KinecalError::new_err(message);
    let value = err.value(py);
    let _ = value.setattr("file", file);
    let _ = value.setattr("line", line);
    let _ = value.setattr("field", field);
    err
}

/// The Python keyword behind a library setting: its spec key, which the named functions'
/// keywords are (`validate/holdout/folds` for the way a calibration is checked).
fn keyword(setting: kinecal::Setting) -> &'static str {
    match setting {
        kinecal::Setting::Validation => "validate/holdout/folds",
        s => s.key(),
    }
}

fn bad(message: impl Into<String>) -> PyErr {
    KinecalError::new_err(message.into())
}

/// An array argument as contiguous float64 of `ndim` dimensions (or `ndim - 1` when
/// `allow_flat`, for one row), after checking that it holds real numbers, finite and within
/// +-1e9. Returns the values and the shape.
fn numbers(
    py: Python<'_>,
    obj: &Bound<'_, PyAny>,
    name: &str,
    ndim: usize,
) -> PyResult<(Vec<f64>, Vec<usize>)> {
    let np = py.import("numpy")?;
    let arr = np
        .call_method1("asarray", (obj,))
        .map_err(|e| PyTypeError::new_err(format!("{name}: not an array of numbers ({e})")))?;
    let kind: String = arr.getattr("dtype")?.getattr("kind")?.extract()?;
    if !matches!(kind.as_str(), "f" | "i" | "u") {
        let dtype = arr.getattr("dtype")?.str()?.to_string();
        return Err(PyTypeError::new_err(format!(
            "{name}: expected real numbers (float or integer dtype), got dtype {dtype}"
        )));
    }
    let arr = np.call_method1("ascontiguousarray", (arr, "float64"))?;
    let view: PyReadonlyArrayDyn<'_, f64> = arr.extract()?;
    let a: ArrayViewD<'_, f64> = view.as_array();
    let shape = a.shape().to_vec();
    if shape.len() != ndim {
        return Err(bad(format!(
            "{name}: expected a {ndim}-dimensional array, got shape {shape:?}"
        )));
    }
    let values: Vec<f64> = a.iter().copied().collect();
    if let Some(i) = values.iter().position(|v| !plausible(*v)) {
        let cols: usize = shape[1..].iter().product::<usize>().max(1);
        return Err(bad(format!(
            "{name}: row {}, column {}: expected a finite number within +-1e9, found {:?}",
            i / cols,
            i % cols,
            values[i]
        )));
    }
    Ok((values, shape))
}

/// A robot model: links, joints, sites and planes, in the units of its file.
#[pyclass(module = "kinecal", name = "Robot")]
#[derive(Clone)]
struct Robot {
    robot: kinecal::Robot,
    /// The TOML text it was read from: the template of [`Robot::to_toml`], which keeps its
    /// comments and layout.
    text: Option<String>,
}

/// A URDF tip, or a tree's tips: `tip="tool0"` or `tip=["left_marker", "right_marker"]`.
#[derive(FromPyObject)]
enum Tips {
    One(String),
    Many(Vec<String>),
}

impl Tips {
    fn list(tips: &Option<Tips>) -> Vec<&str> {
        match tips {
            None => Vec::new(),
            Some(Tips::One(t)) => vec![t.as_str()],
            Some(Tips::Many(ts)) => ts.iter().map(String::as_str).collect(),
        }
    }
}

impl Robot {
    fn from_source(py: Python<'_>, s: &Source) -> PyResult<Robot> {
        let robot = parse_robot_toml(&s.text, &s.name).map_err(|e| error(py, e))?;
        Ok(Robot {
            robot,
            text: Some(s.text.clone()),
        })
    }

    fn param(&self, name: &str) -> PyResult<kinecal::ParamId> {
        let ids = kinecal::parse_param_list(name, &self.robot)
            .map_err(|e| bad(format!("{name}: {e}")))?;
        match ids.as_slice() {
            [id] => Ok(*id),
            _ => Err(bad(format!(
                "{name}: names {} parameters; give one (`link2.x`, `p8`)",
                ids.len()
            ))),
        }
    }

    fn target(&self, site: Option<&str>) -> PyResult<Target> {
        commands::target_of(&self.robot, site, "site")
    }

    /// A camera's or a board's mount as the robot file says it.
    fn mount_name(&self, m: kinecal::model::camera::Mount) -> String {
        use kinecal::model::camera::Mount;
        match m {
            Mount::Base => "base".into(),
            Mount::EndEffector => "ee".into(),
            Mount::Site(i) => self.robot.sites[i].name.clone(),
        }
    }

    /// The pose of camera or board `name` (file units): its six parameters.
    fn pose_of(&self, name: &str) -> PyResult<Vec<f64>> {
        ["x", "y", "z", "alpha", "beta", "gamma"]
            .iter()
            .map(|c| Ok(self.robot.get_user(self.param(&format!("{name}.{c}"))?)))
            .collect()
    }
}

fn site_names(robot: &kinecal::Robot) -> Vec<String> {
    robot.sites.iter().map(|s| s.name.clone()).collect()
}

fn units(length: &str, angle: &str) -> PyResult<Units> {
    Ok(Units {
        length: length
            .parse()
            .map_err(|e| bad(format!("length_unit: {e}")))?,
        angle: angle.parse().map_err(|e| bad(format!("angle_unit: {e}")))?,
    })
}

#[pymethods]
impl Robot {
    /// Reads a robot TOML file (a path) or TOML text (a string holding a newline or `=`).
    #[staticmethod]
    fn from_toml(py: Python<'_>, source: &Bound<'_, PyAny>) -> PyResult<Robot> {
        if let Ok(s) = source.cast::<PyString>() {
            let s: String = s.extract()?;
            if s.contains('\n') || s.contains('=') {
                return Robot::from_source(py, &Source::text("<text>", s));
            }
        }
        let path: PathBuf = source.extract()?;
        let s = Source::read(&path).map_err(|e| error(py, e))?;
        Robot::from_source(py, &s)
    }

    /// A robot built into kinecal, by name (`ge-a4`: the GE A4 of the thesis, Table 4.1).
    #[staticmethod]
    fn builtin(py: Python<'_>, name: &str) -> PyResult<Robot> {
        let text = kinecal::model::examples::builtin(name).ok_or_else(|| {
            bad(format!(
                "{name}: not a built-in robot (built-in: {})",
                kinecal::model::examples::BUILTIN_NAMES.join(", ")
            ))
        })?;
        Robot::from_source(py, &Source::text(format!("<built-in {name}>"), text))
    }

    /// Reads the chain from `base` to `tip` of a URDF file (metres, radians); `base` defaults
    /// to the root link, `tip` to the only leaf. A list of tips reads a tree (two arms on one
    /// torso): the last tip is the end effector, the others sites named after their links.
    /// `masses=True` takes the links' `<inertial>` masses as the robot's mass model (an elastic
    /// robot whose compliances can be estimated).
    #[staticmethod]
    #[pyo3(signature = (path, base=None, tip=None, masses=false))]
    fn from_urdf(
        py: Python<'_>,
        path: PathBuf,
        base: Option<&str>,
        tip: Option<Tips>,
        masses: bool,
    ) -> PyResult<Robot> {
        let s = Source::read(&path).map_err(|e| error(py, e))?;
        let tips = Tips::list(&tip);
        let imported =
            kinecal::import::urdf::import_urdf_with(&s.text, &s.name, base, &tips, masses)
                .map_err(|e| error(py, e))?;
        Ok(Robot {
            robot: imported.robot,
            text: None,
        })
    }

    /// A robot from a DH table: an `(n, 4)` array of `a, alpha, d, theta` rows (or `(n, 5)`
    /// with `beta`) in the given units (metres and degrees by default; `kinds`: "revolute" or
    /// "prismatic" per row, revolute by default), or the path of a DH CSV file
    /// (`kind,a,alpha,d,theta[,beta]`), in the units and convention it states (`kinecal export
    /// dh` writes them); a file that states none needs `length_unit`, `angle_unit` and
    /// `convention`. `convention`: "standard" or "modified".
    #[staticmethod]
    #[pyo3(signature = (table, convention=None, length_unit=None, angle_unit=None, kinds=None, name=None))]
    fn from_dh(
        py: Python<'_>,
        table: &Bound<'_, PyAny>,
        convention: Option<&str>,
        length_unit: Option<&str>,
        angle_unit: Option<&str>,
        kinds: Option<Vec<String>>,
        name: Option<&str>,
    ) -> PyResult<Robot> {
        let convention = convention.map(convention_of).transpose()?;
        if table.cast::<PyString>().is_ok() || table.hasattr("__fspath__")? {
            let path: PathBuf = table.extract()?;
            let s = Source::read(&path).map_err(|e| error(py, e))?;
            let length = length_unit
                .map(|l| l.parse().map_err(|e| bad(format!("length_unit: {e}"))))
                .transpose()?;
            let angle = angle_unit
                .map(|a| a.parse().map_err(|e| bad(format!("angle_unit: {e}"))))
                .transpose()?;
            // Unnamed: the file's name without its extension, as `kinecal import dh` names it.
            let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("");
            let name = name.unwrap_or(stem);
            let robot =
                kinecal::import::dh::import_dh(&s.text, &s.name, name, length, angle, convention)
                    .map_err(|e| error(py, e))?;
            return Ok(Robot { robot, text: None });
        }
        let convention = convention.unwrap_or(Convention::Standard);
        let u = units(length_unit.unwrap_or("m"), angle_unit.unwrap_or("deg"))?;
        let (v, shape) = numbers(py, table, "table", 2)?;
        if !(shape[1] == 4 || shape[1] == 5) || shape[0] == 0 {
            return Err(bad(format!(
                "table: expected shape (joints, 4) with columns a, alpha, d, theta (or (joints, \
                 5) with beta), got {shape:?}"
            )));
        }
        let kinds = match kinds {
            None => vec![JointKind::Revolute; shape[0]],
            Some(k) if k.len() == shape[0] => k
                .iter()
                .map(|s| match s.as_str() {
                    "revolute" => Ok(JointKind::Revolute),
                    "prismatic" => Ok(JointKind::Prismatic),
                    o => Err(bad(format!(
                        "kinds: `{o}`: expected \"revolute\" or \"prismatic\""
                    ))),
                })
                .collect::<PyResult<_>>()?,
            Some(k) => {
                return Err(bad(format!(
                    "kinds: {} entries for {} rows",
                    k.len(),
                    shape[0]
                )))
            }
        };
        let (l, a) = (u.length.metres(), u.angle.radians());
        let rows: Vec<DhRow> = v
            .chunks(shape[1])
            .zip(kinds)
            .map(|(r, kind)| DhRow {
                kind: kind.into(),
                a: r[0] * l,
                alpha: r[1] * a,
                d: r[2] * l,
                theta: r[3] * a,
                beta: r.get(4).map_or(0.0, |b| b * a),
            })
            .collect();
        let robot = robot_from_dh(name.unwrap_or("dh"), u, &rows, convention);
        robot
            .validate()
            .map_err(|m| bad(format!("table: the robot it describes is not usable: {m}")))?;
        Ok(Robot { robot, text: None })
    }

    /// The robot as a TOML file's text (keeping the comments and layout of the file it was read
    /// from, when it was read from one).
    fn to_toml(&self, py: Python<'_>) -> PyResult<String> {
        write_robot_toml_checked(&self.robot, self.text.as_deref()).map_err(|e| error(py, e))
    }

    /// The robot written into a URDF `template` (a path): only joint origins change, plus a
    /// fixed tool joint when the tip hangs off a movable joint. Returns the URDF text, read back
    /// and compared with the robot first: beyond `tolerance` (`(length, angle)` in the robot's
    /// units; by default a millionth of its reach and 1e-9 rad) a `KinecalError` says by how
    /// much and why, as `kinecal export urdf` refuses.
    #[pyo3(signature = (template, base=None, tip=None, tolerance=None))]
    fn to_urdf(
        &self,
        py: Python<'_>,
        template: PathBuf,
        base: Option<&str>,
        tip: Option<Tips>,
        tolerance: Option<(f64, f64)>,
    ) -> PyResult<String> {
        let tolerance = tolerance_of(&self.robot, tolerance)?;
        let s = Source::read(&template).map_err(|e| error(py, e))?;
        let robot = &self.robot;
        let tips = Tips::list(&tip);
        let e = py
            .detach(|| kinecal::import::urdf::export_urdf(robot, &s.text, &s.name, base, &tips))
            .map_err(|e| error(py, e))?;
        e.check(robot, &tolerance).map_err(|e| error(py, e))?;
        for w in &e.warnings {
            if !matches!(w, kinecal::Warning::UrdfSlope { .. }) {
                export_warning(py, &w.to_string())?;
            }
        }
        for l in &e.lost {
            export_warning(py, &l.line(robot.units))?;
        }
        Ok(e.text)
    }

    /// The robot as the files of a ROS 2 description, what `kinecal export ros` writes into a
    /// folder, by file name: `calibration.yaml` (the calibrated origins of the joints of the
    /// chains of the URDF `template`, a path), `<robot>.urdf.xacro` (the template reading them
    /// with `xacro.load_yaml`), `static_transforms.yaml` and `static_transforms.launch.py` (the
    /// frame the robot was measured in, named `measurement_frame`, below the base link, the
    /// session frames below it). The xacro, expanded with the YAML, is read back and compared
    /// with the robot first: beyond `tolerance` a `KinecalError`; what URDF cannot express is
    /// an `ExportWarning`.
    #[pyo3(signature = (template, base=None, tip=None, measurement_frame=None, tolerance=None))]
    fn to_ros(
        &self,
        py: Python<'_>,
        template: PathBuf,
        base: Option<&str>,
        tip: Option<Tips>,
        measurement_frame: Option<&str>,
        tolerance: Option<(f64, f64)>,
    ) -> PyResult<std::collections::BTreeMap<String, String>> {
        let tolerance = tolerance_of(&self.robot, tolerance)?;
        let s = Source::read(&template).map_err(|e| error(py, e))?;
        let robot = &self.robot;
        let tips = Tips::list(&tip);
        let e = py
            .detach(|| {
                kinecal::import::ros::export_ros(
                    robot,
                    &s.text,
                    &s.name,
                    base,
                    &tips,
                    measurement_frame,
                )
            })
            .map_err(|e| error(py, e))?;
        e.check(robot, &tolerance).map_err(|e| error(py, e))?;
        for w in &e.warnings {
            if !matches!(w, kinecal::Warning::UrdfSlope { .. }) {
                export_warning(py, &w.to_string())?;
            }
        }
        for n in &e.notes {
            export_warning(py, n)?;
        }
        for l in &e.lost {
            export_warning(py, &l.line(robot.units))?;
        }
        Ok(e.files()
            .iter()
            .map(|(n, t)| (n.to_string(), t.to_string()))
            .collect())
    }

    /// The robot as a Denavit-Hartenberg table, what `kinecal export dh` writes: CSV in the
    /// robot's units (or `length_unit`, `angle_unit`), stating them, with a `beta` column where
    /// consecutive axes are nearly parallel and `fixed` rows for a base or tool frame. The table
    /// is read back and compared with the robot first: beyond `tolerance` (`(length, angle)` in
    /// the robot's units) a `KinecalError` names what a DH table cannot hold (slopes,
    /// couplings); within a looser one, each is an `ExportWarning` with its deviation.
    #[pyo3(signature = (convention="standard", length_unit=None, angle_unit=None, tolerance=None))]
    fn to_dh(
        &self,
        py: Python<'_>,
        convention: &str,
        length_unit: Option<&str>,
        angle_unit: Option<&str>,
        tolerance: Option<(f64, f64)>,
    ) -> PyResult<String> {
        let convention = convention_of(convention)?;
        let robot = &self.robot;
        let tolerance = tolerance_of(robot, tolerance)?;
        let u = units(
            length_unit.unwrap_or(robot.units.length.as_str()),
            angle_unit.unwrap_or(robot.units.angle.as_str()),
        )?;
        let e = py
            .detach(|| kinecal::import::dh::export_dh(robot, convention, u))
            .map_err(|e| error(py, e))?;
        e.check(robot, &tolerance).map_err(|e| error(py, e))?;
        for l in &e.lost {
            export_warning(py, &l.line(robot.units))?;
        }
        Ok(e.text)
    }

    /// The robot written into the Universal Robots kinematics file `template` (a path) it was
    /// imported from, what `kinecal export ur` writes: the controller's base stays the
    /// template's (the measurement frame in the robot's first link, and session frames, are
    /// left out: an `ExportWarning` says so), and the calibrated tool frame is the TCP to enter
    /// on the controller (an `ExportWarning` gives it). The file, with the TCP, is read back
    /// and compared with the robot first: beyond `tolerance` a `KinecalError` names what it
    /// cannot hold (slopes, couplings); within a looser one, each is an `ExportWarning`.
    #[pyo3(signature = (template, tolerance=None))]
    fn to_ur(
        &self,
        py: Python<'_>,
        template: PathBuf,
        tolerance: Option<(f64, f64)>,
    ) -> PyResult<String> {
        let s = Source::read(&template).map_err(|e| error(py, e))?;
        let robot = &self.robot;
        let tolerance = tolerance_of(robot, tolerance)?;
        let e = py
            .detach(|| kinecal::import::ur::export_ur(robot, &s.text, &s.name))
            .map_err(|e| error(py, e))?;
        e.check(&tolerance).map_err(|e| error(py, e))?;
        for line in e.left_out() {
            export_warning(py, &line)?;
        }
        for l in &e.lost {
            export_warning(py, &l.line(robot.units))?;
        }
        if e.tcp.is_some() {
            export_warning(py, &e.tcp_line())?;
        }
        Ok(e.text)
    }

    /// This (calibrated) robot's joint offsets and slopes as a table, with their change from
    /// `nominal` (`joint,offset,slope,offset_change,slope_change`, what `kinecal export joints`
    /// writes). The table is applied to `nominal` and compared with this robot first: beyond
    /// `tolerance` a `KinecalError` says what it cannot carry (link and tool changes); within a
    /// looser one, that is an `ExportWarning` with its deviation.
    #[pyo3(signature = (nominal, tolerance=None))]
    fn to_joints(
        &self,
        py: Python<'_>,
        nominal: &Robot,
        tolerance: Option<(f64, f64)>,
    ) -> PyResult<String> {
        let (cal, nom) = (&self.robot, &nominal.robot);
        let tolerance = tolerance_of(cal, tolerance)?;
        let e = py
            .detach(|| kinecal::import::joints::joint_table(cal, nom))
            .map_err(|e| error(py, e))?;
        e.check(cal, &tolerance).map_err(|e| error(py, e))?;
        if let Some(x) = &e.lost {
            export_warning(py, &x.line(cal.units))?;
        }
        Ok(e.text)
    }

    /// The lens of camera `camera` (the robot file's only camera when `None`) as ROS's
    /// `camera_info` YAML, what `kinecal export camera-info` writes (read back to the same bits
    /// first). The camera's pose (hand-eye) is not part of it.
    #[pyo3(signature = (camera=None))]
    fn to_camera_info(&self, py: Python<'_>, camera: Option<&str>) -> PyResult<String> {
        kinecal::import::camera_info::export_camera_info(&self.robot, camera)
            .map(|(_, text)| text)
            .map_err(|e| error(py, e))
    }

    /// A copy whose camera `camera` (the only one when `None`) has the lens of a ROS
    /// `camera_info` YAML file (a path, or the YAML text: a string holding a newline).
    #[pyo3(signature = (source, camera=None))]
    fn with_camera_info(
        &self,
        py: Python<'_>,
        source: &Bound<'_, PyAny>,
        camera: Option<&str>,
    ) -> PyResult<Robot> {
        let text = source.extract::<String>().ok().filter(|t| t.contains('\n'));
        let s = match text {
            Some(t) => Source::text("<text>", t),
            None => {
                let path: PathBuf = source.extract()?;
                Source::read(&path).map_err(|e| error(py, e))?
            }
        };
        let robot =
            kinecal::import::camera_info::with_camera_info(&self.robot, camera, &s.text, &s.name)
                .map_err(|e| error(py, e))?;
        Ok(Robot {
            robot,
            text: self.text.clone(),
        })
    }

    /// The cameras of the robot file: one dict each, `name`, `mount` (`ee`, `base` or a site's
    /// name), `pose` (x, y, z, alpha, beta, gamma in the file's units), `fx`, `fy`, `cx`, `cy`
    /// (pixels), `distortion` (k1, k2, p1, p2, k3), `width`, `height`.
    #[getter]
    fn cameras<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, pyo3::types::PyDict>>> {
        let r = &self.robot;
        r.cameras
            .iter()
            .map(|c| {
                let d = pyo3::types::PyDict::new(py);
                d.set_item("name", &c.name)?;
                d.set_item("mount", self.mount_name(c.mount))?;
                d.set_item("pose", self.pose_of(&c.name)?)?;
                d.set_item("fx", c.fx)?;
                d.set_item("fy", c.fy)?;
                d.set_item("cx", c.cx)?;
                d.set_item("cy", c.cy)?;
                d.set_item("distortion", c.distortion.to_vec())?;
                d.set_item("width", c.width)?;
                d.set_item("height", c.height)?;
                Ok(d)
            })
            .collect()
    }

    /// The calibration boards of the robot file: one dict each, `name`, `mount`, `pose` (as for
    /// cameras), `cols`, `rows`, `spacing` (the file's length unit).
    #[getter]
    fn boards<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, pyo3::types::PyDict>>> {
        let r = &self.robot;
        r.boards
            .iter()
            .map(|b| {
                let d = pyo3::types::PyDict::new(py);
                d.set_item("name", &b.name)?;
                d.set_item("mount", self.mount_name(b.mount))?;
                d.set_item("pose", self.pose_of(&b.name)?)?;
                d.set_item("cols", b.cols)?;
                d.set_item("rows", b.rows)?;
                d.set_item("spacing", r.units.from_si(Quantity::Length, b.spacing))?;
                Ok(d)
            })
            .collect()
    }

    /// The robot's name.
    #[getter]
    fn name(&self) -> String {
        self.robot.name.clone()
    }

    /// Number of joints.
    #[getter]
    fn dof(&self) -> usize {
        self.robot.dof()
    }

    /// `(length unit, angle unit)` of the file, e.g. `("mm", "deg")`.
    #[getter]
    fn units(&self) -> (String, String) {
        (
            self.robot.units.length.as_str().to_string(),
            self.robot.units.angle.as_str().to_string(),
        )
    }

    /// Names of the measurement sites.
    #[getter]
    fn sites(&self) -> Vec<String> {
        site_names(&self.robot)
    }

    /// Every parameter's name, in thesis order (`link1.x`, ..., `joint1.offset`, ...).
    #[getter]
    fn parameter_names(&self) -> Vec<String> {
        self.robot
            .param_ids()
            .map(|id| self.robot.param_name(id))
            .collect()
    }

    /// Every parameter's id (`p1`, `p2`, ...), in the same order.
    #[getter]
    fn parameter_ids(&self) -> Vec<String> {
        self.robot.param_ids().map(|id| id.to_string()).collect()
    }

    /// Every parameter's unit (`mm`, `deg`, `deg/unit`, ...), in the same order.
    #[getter]
    fn parameter_units(&self) -> Vec<String> {
        self.robot
            .param_ids()
            .map(|id| self.robot.param_unit(id))
            .collect()
    }

    /// Every parameter's value in the file's units, in the same order.
    #[getter]
    fn values<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        let v: Vec<f64> = self
            .robot
            .param_ids()
            .map(|id| self.robot.get_user(id))
            .collect();
        v.into_pyarray(py)
    }

    /// The value of one parameter (name or id) in the file's units.
    fn get(&self, name: &str) -> PyResult<f64> {
        Ok(self.robot.get_user(self.param(name)?))
    }

    /// A copy with one parameter (name or id) set to `value` in the file's units.
    fn with_value(&self, name: &str, value: f64) -> PyResult<Robot> {
        let id = self.param(name)?;
        if !plausible(value) {
            return Err(bad(format!(
                "{name}: expected a finite number within +-1e9, got {value}"
            )));
        }
        let mut r = self.clone();
        let q = r.robot.param_quantity(id);
        let si = r.robot.units.to_si(q, value);
        r.robot.set(id, si);
        r.robot
            .validate()
            .map_err(|m| bad(format!("{name} = {value}: {m}")))?;
        Ok(r)
    }

    /// Forward kinematics of `readings` (`(n, joints)` or one row of `joints`): the pose of the
    /// end effector (or of `site`) as `(n, 6)` rows `x, y, z, alpha, beta, gamma` (file
    /// units; ZYX Euler angles), or as `(n, 4, 4)` homogeneous transforms when
    /// `matrix=True` (translation in the length unit).
    #[pyo3(signature = (readings, site=None, matrix=false))]
    fn fk<'py>(
        &self,
        py: Python<'py>,
        readings: &Bound<'py, PyAny>,
        site: Option<&str>,
        matrix: bool,
    ) -> PyResult<Bound<'py, PyAny>> {
        let n = self.robot.dof();
        let (v, shape) = readings_array(py, readings, n)?;
        let target = self.target(site)?;
        let rows = shape[0];
        let robot = &self.robot;
        let (l, a) = (robot.units.length.metres(), robot.units.angle.radians());
        let out = py
            .detach(|| {
                let chain = Chain::new(robot);
                let mut ws = Workspace::new(robot);
                let mut out = Vec::with_capacity(rows * if matrix { 16 } else { 6 });
                for (row, r) in v.chunks(n).enumerate() {
                    chain.forward(r, &mut ws);
                    if let Some(eq) = ws.equilibrium().filter(|e| !e.converged) {
                        return Err(format!("readings: row {row}: the gravity equilibrium {eq}"));
                    }
                    let f = chain.target_frame(&ws, target);
                    if matrix {
                        for i in 0..3 {
                            for j in 0..3 {
                                out.push(f.rotation[(i, j)]);
                            }
                            out.push(f.translation[i] / l);
                        }
                        out.extend([0.0, 0.0, 0.0, 1.0]);
                    } else {
                        let p = f.pose();
                        out.extend(p.position.iter().map(|x| x / l));
                        out.extend(p.euler.iter().map(|x| x / a));
                    }
                }
                Ok(out)
            })
            .map_err(bad)?;
        if let Some(bad_row) = out
            .chunks(if matrix { 16 } else { 6 })
            .position(|r| r.iter().any(|x| !x.is_finite()))
        {
            return Err(bad(format!(
                "readings: row {bad_row}: the pose is not finite"
            )));
        }
        let flat = shape.len() == 1;
        Ok(if matrix {
            let arr = Array3::from_shape_vec((rows, 4, 4), out).expect("shape");
            if flat {
                arr.index_axis_move(numpy::ndarray::Axis(0), 0)
                    .into_pyarray(py)
                    .into_any()
            } else {
                arr.into_pyarray(py).into_any()
            }
        } else {
            let arr = Array2::from_shape_vec((rows, 6), out).expect("shape");
            if flat {
                arr.index_axis_move(numpy::ndarray::Axis(0), 0)
                    .into_pyarray(py)
                    .into_any()
            } else {
                arr.into_pyarray(py).into_any()
            }
        })
    }

    fn __repr__(&self) -> String {
        format!(
            "Robot({:?}: {} joints, {} sites, {} parameters, {}/{})",
            self.robot.name,
            self.robot.dof(),
            self.robot.sites.len(),
            self.robot.param_count(),
            self.robot.units.length.as_str(),
            self.robot.units.angle.as_str()
        )
    }
}

/// A `(rows, cols)` NumPy array of `values`, given row after row (`rows * cols` of them).
fn row_major_array<T: numpy::Element>(
    py: Python<'_>,
    (rows, cols): (usize, usize),
    values: Vec<T>,
) -> Bound<'_, PyArray2<T>> {
    Array2::from_shape_vec((rows, cols), values)
        .expect("shape")
        .into_pyarray(py)
}

/// Readings as `(rows, joints)`, or one row of `joints`: returns the values and the shape
/// `[rows]` for one row given flat, `[rows, joints]` otherwise.
fn readings_array(
    py: Python<'_>,
    readings: &Bound<'_, PyAny>,
    joints: usize,
) -> PyResult<(Vec<f64>, Vec<usize>)> {
    let ndim: usize = py
        .import("numpy")?
        .call_method1("ndim", (readings,))
        .map_err(|e| PyTypeError::new_err(format!("readings: not an array of numbers ({e})")))?
        .extract()?;
    let flat = ndim == 1;
    let (v, shape) = numbers(py, readings, "readings", if flat { 1 } else { 2 })?;
    if shape.last() != Some(&joints) || v.is_empty() {
        return Err(bad(format!(
            "readings: expected shape (postures, {joints}) for a robot of {joints} joints, got \
             {shape:?}"
        )));
    }
    let rows = v.len() / joints;
    Ok((v, if flat { vec![rows] } else { vec![rows, joints] }))
}

/// Observations of a robot: postures (readings) and what was measured in them (poses,
/// positions, distances, plane contacts), with optional per-row standard deviations.
#[pyclass(module = "kinecal", name = "Measurements")]
#[derive(Clone)]
struct Measurements {
    /// Shared with the calibrations run on it (the library takes a dataset by `Arc`): a call
    /// copies none of it.
    data: Arc<Dataset>,
    /// The robot's joint count and site names when built (checked against the robot used).
    dof: usize,
    sites: Vec<String>,
}

impl Measurements {
    fn check(&self, robot: &kinecal::Robot, name: &str) -> PyResult<()> {
        if self.dof != robot.dof() || self.sites != site_names(robot) {
            return Err(bad(format!(
                "{name}: built for a robot with {} joints and sites [{}], not for this one \
                 ({} joints, sites [{}])",
                self.dof,
                self.sites.join(", "),
                robot.dof(),
                site_names(robot).join(", ")
            )));
        }
        Ok(())
    }
}

/// The measured columns of [`Measurements`]' rows, each checked against the rows' count:
/// positions, orientations (ZYX Euler angles, for poses), and the rows' standard deviations
/// (positive and finite).
struct RowColumns {
    positions: Vec<f64>,
    orientations: Option<Vec<f64>>,
    sigma_position: Option<Vec<f64>>,
    sigma_angle: Option<Vec<f64>>,
}

impl RowColumns {
    fn read(
        py: Python<'_>,
        rows: usize,
        positions: &Bound<'_, PyAny>,
        orientations: Option<&Bound<'_, PyAny>>,
        sigma_position: Option<&Bound<'_, PyAny>>,
        sigma_angle: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<RowColumns> {
        let shaped = |name: &str, v: (Vec<f64>, Vec<usize>), cols: Option<usize>| {
            let want: Vec<usize> = match cols {
                Some(c) => vec![rows, c],
                None => vec![rows],
            };
            if v.1 != want {
                return Err(bad(format!(
                    "{name}: expected shape {want:?} (one row per row of readings), got {:?}",
                    v.1
                )));
            }
            Ok(v.0)
        };
        let p = shaped(
            "positions",
            numbers(py, positions, "positions", 2)?,
            Some(3),
        )?;
        let o = match orientations {
            Some(o) => Some(shaped(
                "orientations",
                numbers(py, o, "orientations", 2)?,
                Some(3),
            )?),
            None => None,
        };
        let positive = |name: &str, v: &[f64]| {
            for (i, s) in v.iter().enumerate() {
                if let Some(why) = kinecal::units::sigma_problem(*s) {
                    return Err(bad(format!("{name}: row {i}: {why}")));
                }
            }
            Ok(())
        };
        let sp = match sigma_position {
            Some(s) => Some(shaped(
                "sigma_position",
                numbers(py, s, "sigma_position", 1)?,
                None,
            )?),
            None => None,
        };
        let sa = match sigma_angle {
            Some(s) => {
                if o.is_none() {
                    return Err(bad(
                        "sigma_angle: position-only rows have no angle: give orientations too",
                    ));
                }
                Some(shaped(
                    "sigma_angle",
                    numbers(py, s, "sigma_angle", 1)?,
                    None,
                )?)
            }
            None => None,
        };
        if let Some(s) = &sp {
            positive("sigma_position", s)?;
        }
        if let Some(s) = &sa {
            positive("sigma_angle", s)?;
        }
        Ok(RowColumns {
            positions: p,
            orientations: o,
            sigma_position: sp,
            sigma_angle: sa,
        })
    }
}

/// The frame each row measures: `sites` (a name per row, None for the end effector), or the
/// end effector throughout.
fn row_targets(
    r: &kinecal::Robot,
    sites: Option<Vec<Option<String>>>,
    rows: usize,
) -> PyResult<Vec<Target>> {
    match sites {
        None => Ok(vec![Target::EndEffector; rows]),
        Some(s) if s.len() == rows => s
            .iter()
            .enumerate()
            .map(|(i, name)| commands::target_of(r, name.as_deref(), &format!("sites: row {i}")))
            .collect(),
        Some(s) => Err(bad(format!(
            "sites: {} names for {rows} rows of readings",
            s.len()
        ))),
    }
}

/// Each row's posture label: `postures`, or the rows numbered from 1.
fn row_labels(postures: Option<Vec<String>>, rows: usize) -> PyResult<Vec<String>> {
    match postures {
        None => Ok((1..=rows).map(|i| i.to_string()).collect()),
        Some(p) if p.len() == rows => Ok(p),
        Some(p) => Err(bad(format!(
            "postures: {} labels for {rows} rows of readings",
            p.len()
        ))),
    }
}

/// The rows as a dataset: one posture per label (rows of one label must have its readings),
/// a pose or a position observed in each row, in SI units.
fn rows_dataset(
    r: &kinecal::Robot,
    q: &[f64],
    c: &RowColumns,
    targets: &[Target],
    labels: &[String],
) -> PyResult<Dataset> {
    let n = r.dof();
    let (p, sp, sa) = (&c.positions, &c.sigma_position, &c.sigma_angle);
    let (l, a) = (r.units.length.metres(), r.units.angle.radians());
    let mut posture_list: Vec<Posture> = Vec::new();
    let mut index: std::collections::HashMap<&str, usize> = Default::default();
    let mut observations = Vec::with_capacity(labels.len());
    for i in 0..labels.len() {
        let reading = &q[i * n..(i + 1) * n];
        let k = match index.get(labels[i].as_str()) {
            Some(&k) => {
                if posture_list[k].readings != reading {
                    return Err(bad(format!(
                        "postures: row {i}: posture `{}` has other readings in an earlier row",
                        labels[i]
                    )));
                }
                k
            }
            None => {
                posture_list.push(Posture {
                    label: labels[i].clone(),
                    readings: reading.to_vec(),
                    session: None,
                    payload: None,
                });
                index.insert(labels[i].as_str(), posture_list.len() - 1);
                posture_list.len() - 1
            }
        };
        let pos = Vector3::new(p[3 * i], p[3 * i + 1], p[3 * i + 2]) * l;
        let obs: kinecal::Observation = match &c.orientations {
            Some(o) => {
                let e = Vector3::new(o[3 * i], o[3 * i + 1], o[3 * i + 2]) * a;
                let mut m = Pose::new(k, targets[i], pos, e);
                m.sigma_position = sp.as_ref().map(|s| Vector3::repeat(s[i] * l));
                m.sigma_angle = sa.as_ref().map(|s| s[i] * a);
                m.line = i + 1;
                m.into()
            }
            None => {
                let mut m = Position::new(k, targets[i], pos);
                m.sigma_position = sp.as_ref().map(|s| Vector3::repeat(s[i] * l));
                m.line = i + 1;
                m.into()
            }
        };
        observations.push(obs);
    }
    Ok(Dataset::new(posture_list, observations))
}

#[pymethods]
impl Measurements {
    /// Measurements from arrays: `readings` `(n, joints)`; `positions` `(n, 3)` in the robot's
    /// length unit; `orientations` `(n, 3)` ZYX Euler angles in its angle unit (full poses;
    /// omit for position-only data); `sites`: one site name per row (None: the end effector);
    /// `sigma_position`, `sigma_angle`: per-row standard deviations `(n,)` in file units;
    /// `postures`: a label per row (rows with the same label share one posture).
    #[new]
    #[pyo3(signature = (robot, readings, positions, orientations=None, sites=None, sigma_position=None, sigma_angle=None, postures=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        robot: &Robot,
        readings: &Bound<'_, PyAny>,
        positions: &Bound<'_, PyAny>,
        orientations: Option<&Bound<'_, PyAny>>,
        sites: Option<Vec<Option<String>>>,
        sigma_position: Option<&Bound<'_, PyAny>>,
        sigma_angle: Option<&Bound<'_, PyAny>>,
        postures: Option<Vec<String>>,
    ) -> PyResult<Measurements> {
        let r = &robot.robot;
        let n = r.dof();
        let (q, qs) = numbers(py, readings, "readings", 2)?;
        if qs[1] != n || qs[0] == 0 {
            return Err(bad(format!(
                "readings: expected shape (rows, {n}) for a robot of {n} joints, got {qs:?}"
            )));
        }
        let rows = qs[0];
        let columns = RowColumns::read(
            py,
            rows,
            positions,
            orientations,
            sigma_position,
            sigma_angle,
        )?;
        let targets = row_targets(r, sites, rows)?;
        let labels = row_labels(postures, rows)?;
        Ok(Measurements {
            data: Arc::new(rows_dataset(r, &q, &columns, &targets, &labels)?),
            dof: n,
            sites: site_names(r),
        })
    }

    /// Reads an observation file of any kind kinecal reads, told by its header (measurements,
    /// distances, contacts); `columns` maps another tool's measurement columns
    /// (`["v1=J1", "x=X", ...]`, as `--columns`); `length_unit` (`"m"`, `"mm"`, `"in"`) and
    /// `angle_unit` (`"deg"`, `"rad"`) state the file's units when they are not the robot
    /// file's; `position_only` reads poses as positions; `session` puts the file's postures
    /// (those without a `session` column value) in that measurement session, with a frame of
    /// its own (an instrument moved between files).
    #[staticmethod]
    #[pyo3(signature = (path, robot, columns=None, length_unit=None, angle_unit=None, position_only=false, session=None))]
    #[allow(clippy::too_many_arguments)]
    fn read_csv(
        py: Python<'_>,
        path: PathBuf,
        robot: &Robot,
        columns: Option<Vec<String>>,
        length_unit: Option<&str>,
        angle_unit: Option<&str>,
        position_only: bool,
        session: Option<&str>,
    ) -> PyResult<Measurements> {
        let r = &robot.robot;
        let file = path
            .to_str()
            .ok_or_else(|| bad(format!("{}: the path is not valid UTF-8", path.display())))?;
        // The one reader of observation files, as the command line and a spec read them; the
        // mapping is this file's own.
        let f = kinecal::files::ObservationFile {
            session: session.map(str::to_string),
            columns: columns.unwrap_or_default(),
            length_unit: length_unit.map(str::to_string),
            angle_unit: angle_unit.map(str::to_string),
            ..kinecal::files::ObservationFile::new(file)
        };
        let read = kinecal::files::ReadSettings {
            position_only,
            ..Default::default()
        };
        let (data, _) =
            kinecal::files::read_files(&read, &[f], r, &[]).map_err(|e| error(py, e))?;
        Ok(Measurements {
            data: Arc::new(data),
            dof: r.dof(),
            sites: site_names(r),
        })
    }

    /// These measurements and `other` together (distances with positions, say).
    fn merge(&self, other: &Measurements) -> PyResult<Measurements> {
        if self.dof != other.dof || self.sites != other.sites {
            return Err(bad("merge: the two were built for different robots"));
        }
        Ok(Measurements {
            data: Arc::new(Dataset::clone(&self.data).merge(Dataset::clone(&other.data))),
            dof: self.dof,
            sites: self.sites.clone(),
        })
    }

    /// The observations as the CSV text of kinecal's file for their kind (`read_csv` reads it
    /// back to the same numbers): a measurement file for poses and positions, a distance file,
    /// or a contact file. Observations of two of these are refused (one file holds one).
    fn to_csv(&self, py: Python<'_>, robot: &Robot) -> PyResult<String> {
        self.check(&robot.robot, "to_csv")?;
        kinecal::files::write_observations(&robot.robot, &self.data).map_err(|e| error(py, e))
    }

    /// The readings of every posture, `(postures, joints)`.
    #[getter]
    fn readings<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let v: Vec<f64> = self
            .data
            .postures
            .iter()
            .flat_map(|p| p.readings.iter().copied())
            .collect();
        row_major_array(py, (self.data.postures.len(), self.dof), v)
    }

    /// Number of postures.
    #[getter]
    fn postures(&self) -> usize {
        self.data.postures.len()
    }

    /// Number of residual rows.
    #[getter]
    fn residuals(&self) -> usize {
        self.data.rows()
    }

    /// Observations of each kind, e.g. `{"position": 46}`.
    #[getter]
    fn kinds(&self) -> std::collections::BTreeMap<String, usize> {
        self.data
            .kinds()
            .into_iter()
            .map(|(k, n)| (k.to_string(), n))
            .collect()
    }

    /// Number of observations.
    fn __len__(&self) -> usize {
        self.data.observations.len()
    }

    fn __repr__(&self) -> String {
        let kinds: Vec<String> = self
            .data
            .kinds()
            .into_iter()
            .map(|(k, n)| format!("{n} {k}"))
            .collect();
        format!(
            "Measurements({} postures: {})",
            self.data.postures.len(),
            kinds.join(", ")
        )
    }
}

/// Calibrates `robot` on `data` (see the Python package's `kinecal.calibrate`): `spec` is the
/// calibration spec of the keywords, which the library translates as every front end's
/// (`validate` and `initial` given in memory). Returns the calibrated robot and the
/// outcome, whose report and arrays are made when Python reads them
/// ([`outcome::CalibrationOutcome`]).
#[pyfunction]
#[pyo3(signature = (robot, data, spec, validate=None, initial=None))]
fn calibrate(
    py: Python<'_>,
    robot: &Robot,
    data: &Measurements,
    spec: &str,
    validate: Option<&Measurements>,
    initial: Option<&Robot>,
) -> PyResult<(Robot, outcome::CalibrationOutcome)> {
    let r = &robot.robot;
    data.check(r, "data")?;
    if let Some(v) = validate {
        v.check(r, "validate")?;
    }
    let mut spec: CalibrationSpec = jobs::settings(py, spec)?;
    spec.robot = r.name.clone();
    let force_units = spec.force_units;
    let request = spec
        .request(
            r,
            data.data.clone(),
            initial.map(|i| i.robot.clone()),
            validate.map(|v| Dataset::clone(&v.data)),
        )
        .map_err(|e| error(py, e))?;
    let text = robot.text.clone().unwrap_or_default();
    let job = CalibrationJob::new(spec, request, Source::text(r.name.clone(), text))
        .map_err(|e| error(py, e))?;
    let outcome = py
        .detach(move || job.calibrate(&mut ()))
        .map_err(|e| error(py, e))?;
    if let Some(why) = kinecal::spec::calibrate::refusal(&outcome).filter(|_| !force_units) {
        return Err(bad(format!("calibrate: {why}")));
    }
    let calibrated = Robot {
        robot: outcome.calibration.calibrated.clone(),
        text: robot.text.clone(),
    };
    Ok((
        calibrated,
        outcome::CalibrationOutcome::new(Box::new(outcome)),
    ))
}

/// What `data` determines about `robot`'s parameters (see the Python package's
/// `kinecal.analyze`): `spec` is the analysis spec of the keywords. Returns the analysis as
/// JSON text (what `kinecal analyze --json` prints).
#[pyfunction]
fn analyze(py: Python<'_>, robot: &Robot, data: &Measurements, spec: &str) -> PyResult<String> {
    let r = &robot.robot;
    data.check(r, "data")?;
    let mut spec: AnalyzeSpec = jobs::settings(py, spec)?;
    spec.robot = r.name.clone();
    let d = &data.data;
    let (outcome, _) = py.detach(|| spec.analyze(r, d)).map_err(|e| error(py, e))?;
    Ok(outcome.report.to_json())
}

/// The data sets kinecal can read as they are published (`qkm-hl6`, `fanuc-r2000ic`,
/// `ur10e-camera`, `ipa-ur10`): `(name, about)` pairs.
#[pyfunction]
fn datasets() -> Vec<(String, String)> {
    kinecal::apps::datasets::DATASETS
        .iter()
        .map(|a| (a.name.to_string(), a.about.to_string()))
        .collect()
}

/// Converts a published data set's folder: returns the robot, the identification data, the
/// validation data (or None) and the suggested calibration as a dict of `calibrate` keywords.
#[pyfunction]
fn dataset(
    py: Python<'_>,
    name: &str,
    folder: PathBuf,
) -> PyResult<(Robot, Measurements, Option<Measurements>, String)> {
    let adapter = kinecal::apps::datasets::DATASETS
        .iter()
        .find(|a| a.name == name)
        .ok_or_else(|| {
            bad(format!(
                "{name}: not a data set kinecal reads (known: {})",
                kinecal::apps::datasets::DATASETS
                    .iter()
                    .map(|a| a.name)
                    .collect::<Vec<_>>()
                    .join(", ")
            ))
        })?;
    let converted = py
        .detach(|| (adapter.convert)(&folder))
        .map_err(|e| error(py, e))?;
    let s = &converted.suggested;
    let file = |n: &str| {
        converted
            .files
            .iter()
            .find(|(f, _)| f == n)
            .map(|(_, t)| t.clone())
            .ok_or_else(|| bad(format!("{name}: the conversion wrote no {n}")))
    };
    let robot = Robot::from_source(py, &Source::text(s.robot, file(s.robot)?))?;
    let read = |n: &str| -> PyResult<Measurements> {
        let text = file(n)?;
        let data = match detect_format(&text) {
            0 => kinecal::files::parse_measurements(&text, n, &robot.robot),
            i => (FORMATS[i].parse)(&text, n, &robot.robot),
        }
        .map_err(|e| error(py, e))?;
        Ok(Measurements {
            data: Arc::new(data),
            dof: robot.robot.dof(),
            sites: site_names(&robot.robot),
        })
    };
    let identification = read(s.data)?;
    let mut validation: Option<Measurements> = None;
    for v in s.validate {
        let m = read(v)?;
        validation = Some(match validation {
            None => m,
            Some(mut all) => {
                all.data = Arc::new(Dataset::clone(&all.data).merge(Dataset::clone(&m.data)));
                all
            }
        });
    }
    let mut kw = serde_json::Map::new();
    kw.insert("estimate".into(), s.estimate.into());
    if let Some(h) = s.holdout {
        kw.insert("holdout".into(), h.into());
    }
    if let Some((l, a)) = s.weights {
        kw.insert("weights".into(), serde_json::json!([l, a]));
    }
    if let Some(o) = s.orientation {
        kw.insert("orientation_error".into(), o.as_str().into());
    }
    Ok((
        robot,
        identification,
        validation,
        serde_json::Value::Object(kw).to_string(),
    ))
}

/// The native part of the `kinecal` Python package.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let error_type = m.py().get_type::<KinecalError>();
    // Every KinecalError has `file`, `line` and `field`: None unless set on the instance (an
    // error read from a file; see `error`), also for errors raised without a kinecal::Error
    // behind them (a bad keyword) and by the Python package itself.
    for attribute in ["file", "line", "field"] {
        error_type.setattr(attribute, m.py().None())?;
    }
    m.add("KinecalError", error_type)?;
    m.add("ExportWarning", m.py().get_type::<ExportWarning>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<Robot>()?;
    m.add_class::<Measurements>()?;
    m.add_class::<outcome::CalibrationOutcome>()?;
    m.add_function(wrap_pyfunction!(jobs::run, m)?)?;
    m.add_function(wrap_pyfunction!(jobs::calibrate_job, m)?)?;
    m.add_function(wrap_pyfunction!(calibrate, m)?)?;
    m.add_function(wrap_pyfunction!(analyze, m)?)?;
    m.add_function(wrap_pyfunction!(datasets, m)?)?;
    m.add_function(wrap_pyfunction!(dataset, m)?)?;
    m.add_function(wrap_pyfunction!(commands::compensate, m)?)?;
    m.add_function(wrap_pyfunction!(commands::plan, m)?)?;
    m.add_function(wrap_pyfunction!(commands::simulate, m)?)?;
    m.add_function(wrap_pyfunction!(accuracy::predict, m)?)?;
    m.add_function(wrap_pyfunction!(accuracy::iso9283_log, m)?)?;
    m.add_function(wrap_pyfunction!(accuracy::iso9283_evaluate, m)?)?;
    Ok(())
}
