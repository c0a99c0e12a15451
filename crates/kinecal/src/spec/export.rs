//! `export` (a calibrated robot into the form a controller or a tool reads: URDF, UR kinematics,
//! DH table, joint table, stiffness table; every export read back and compared before it is
//! written; the 3-D scene of a calibration as glTF) and `import` (a robot file from URDF, DH,
//! product of exponentials or UR kinematics).
//!
//! ```toml
//! job = "export"
//! format = "urdf"
//! robot = "calibrated.toml"
//! template = "ur5_robot.urdf"
//! out = "ur5_calibrated.urdf"
//! ```

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Location, Result, Setting};
use crate::import::dh::Convention;
use crate::import::readback::Tolerance;
use crate::model::robot::Robot;
use crate::report::CalibrationReport;

use super::common::{
    invalid, is_default, read_observations, read_source, robot_as, visit_observations, visit_opt,
    LengthAngle,
};
use super::{Document, Done, Env, JobKind, Message, PathRole, Spec};
use crate::files::{ObservationFile, ReadSettings};

/// What an export writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
#[non_exhaustive]
pub enum ExportFormat {
    /// The calibrated robot written into the URDF it was imported from.
    #[default]
    Urdf,
    /// A Universal Robots kinematics file for the ROS driver.
    Ur,
    /// A Denavit-Hartenberg table.
    Dh,
    /// The joint offsets and slopes, for controllers that take only those.
    Joints,
    /// The joint compliances and stiffnesses of an elastic robot's calibration report.
    Stiffness,
    /// The files of a ROS 2 description: a calibration YAML, the URDF as a xacro that reads it,
    /// and the static transforms of the frames outside the robot (`out` is a folder).
    Ros,
    /// The 3-D scene of a calibration as glTF 2.0 binary (GLB): the calibrated (and nominal)
    /// robot at a posture, the measured points, the residuals, the frames
    /// ([`crate::report::scene`]), as the HTML report's 3-D view draws it.
    Gltf,
    /// A camera's lens as ROS's `camera_info` YAML ([`crate::import::camera_info`]).
    CameraInfo,
}

impl ExportFormat {
    /// The name in a spec.
    pub fn as_str(self) -> &'static str {
        match self {
            ExportFormat::Urdf => "urdf",
            ExportFormat::Ur => "ur",
            ExportFormat::Dh => "dh",
            ExportFormat::Joints => "joints",
            ExportFormat::Stiffness => "stiffness",
            ExportFormat::Ros => "ros",
            ExportFormat::Gltf => "gltf",
            ExportFormat::CameraInfo => "camera-info",
        }
    }
}

/// An export. Which keys a format takes: `urdf`: robot, template, base, tip; `ros`: those and
/// measurement_frame; `ur`: robot, template; `dh`: robot, convention, length_unit, angle_unit; `joints`:
/// robot, nominal; `stiffness`: report; `gltf`: robot, and optionally report, nominal,
/// observations (with read) and posture; `camera-info`: robot and camera. All but stiffness, gltf
/// and camera-info take a tolerance (a camera_info file is read back to the same bits).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct ExportSpec {
    /// What to write.
    #[serde(default)]
    pub format: ExportFormat,
    /// The calibrated robot.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub robot: Option<String>,
    /// The file the robot was imported from (URDF, UR kinematics).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub template: Option<String>,
    /// The first link of the chain, as at import (URDF).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub base: Option<String>,
    /// The last link of the chain, as at import (each tip of a tree, in the import's order).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub tip: Vec<String>,
    /// The nominal robot (joint table: what the controller uses).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nominal: Option<String>,
    /// The DH convention.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub convention: Option<Convention>,
    /// The DH table's length unit (default: the robot file's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub length_unit: Option<String>,
    /// The DH table's angle unit (default: the robot file's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub angle_unit: Option<String>,
    /// How far the export, read back, may miss the robot at the tool over the joint ranges
    /// (robot file's units; default a millionth of the reach and 1e-9 rad).
    #[serde(default, skip_serializing_if = "is_default")]
    pub tolerance: LengthAngle,
    /// The calibration report of an elastic robot (stiffness).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub report: Option<String>,
    /// The name of the frame the robot was measured in, published below the base link (ros;
    /// default `measurement`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub measurement_frame: Option<String>,
    /// The observations whose points and residuals the scene shows (gltf).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub observations: Vec<ObservationFile>,
    /// How the observation files are read (gltf).
    #[serde(default, skip_serializing_if = "is_default")]
    pub read: ReadSettings,
    /// The posture the robots are drawn at, by label (gltf; default the first measured).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub posture: Option<String>,
    /// The camera whose lens is written (camera-info; default the robot file's only camera).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera: Option<String>,
    /// The file to write (ros: the folder to write the files into).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub out: Option<String>,
}

impl Spec for ExportSpec {
    const KIND: JobKind = JobKind::Export;

    fn visit_paths(&mut self, f: &mut dyn FnMut(PathRole, &mut String)) {
        visit_opt(f, PathRole::Robot, &mut self.robot);
        visit_opt(f, PathRole::Input, &mut self.template);
        visit_opt(f, PathRole::Robot, &mut self.nominal);
        visit_opt(f, PathRole::Input, &mut self.report);
        visit_observations(f, &mut self.observations);
        match (&mut self.out, self.format) {
            // A folder: when it exists, its files with fixed names are the outputs (the
            // xacro's, named after the robot, is checked when known), and the folder follows
            // what `f` does to them; a folder yet to be made is the output itself.
            (Some(dir), ExportFormat::Ros) if Path::new(dir.as_str()).is_dir() => {
                use crate::import::ros::{CALIBRATION_FILE, LAUNCH_FILE, TRANSFORMS_FILE};
                let mut files: Vec<String> = [CALIBRATION_FILE, TRANSFORMS_FILE, LAUNCH_FILE]
                    .iter()
                    .map(|n| {
                        Path::new(dir.as_str())
                            .join(n)
                            .to_string_lossy()
                            .into_owned()
                    })
                    .collect();
                for p in &mut files {
                    f(PathRole::Output, p);
                }
                if let Some(parent) = Path::new(&files[0]).parent() {
                    *dir = parent.to_string_lossy().into_owned();
                }
            }
            (out, _) => visit_opt(f, PathRole::Output, out),
        }
    }
}

/// What an import reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
#[non_exhaustive]
pub enum ImportFormat {
    /// A URDF file (plain URDF; expand xacro first).
    #[default]
    Urdf,
    /// A Denavit-Hartenberg table (`kind,a,alpha,d,theta[,beta]`).
    Dh,
    /// A product-of-exponentials file (TOML).
    Poe,
    /// A Universal Robots kinematics file (the ROS driver's calibration YAML).
    Ur,
}

/// An import. `urdf` takes base, tip and masses; `dh` takes convention, units and name.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct ImportSpec {
    /// What the file is.
    #[serde(default)]
    pub format: ImportFormat,
    /// The file.
    #[serde(default)]
    pub file: String,
    /// The first link of the chain (URDF; default the root link).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub base: Option<String>,
    /// The last link of the chain (URDF; default the only leaf); several make a tree.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub tip: Vec<String>,
    /// Take the links' `<inertial>` masses as the robot's mass model (URDF).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub masses: bool,
    /// The DH convention, when the table does not state it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub convention: Option<Convention>,
    /// The DH table's length unit, when it does not state it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub length_unit: Option<String>,
    /// The DH table's angle unit, when it does not state it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub angle_unit: Option<String>,
    /// The robot's name (DH; default: the table's file name without its extension).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub robot_name: Option<String>,
    /// The robot file to write.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub out: Option<String>,
}

impl Spec for ImportSpec {
    const KIND: JobKind = JobKind::Import;

    fn visit_paths(&mut self, f: &mut dyn FnMut(PathRole, &mut String)) {
        f(PathRole::Input, &mut self.file);
        visit_opt(f, PathRole::Output, &mut self.out);
    }
}

/// The document of an export or an import.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct ExportOutcome {
    /// The read-back line (`read back: largest deviation ... over N postures`).
    pub read_back: Option<String>,
    /// What the export cannot hold, each with its deviation.
    #[serde(default)]
    pub lost: Vec<String>,
    /// What a user must know or do (left out frames, the TCP to enter, units).
    #[serde(default)]
    pub notes: Vec<String>,
    /// The tool correction to enter on the controller (UR).
    pub tcp: Option<String>,
    /// The text written.
    #[serde(default)]
    pub text: String,
    /// The files written into a folder (ros), by name.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub files: Vec<(String, String)>,
    /// The bytes written, for a binary file (gltf: the GLB).
    #[serde(skip)]
    pub bytes: Vec<u8>,
}

/// The calibration report at `path`.
fn read_report(path: &str) -> Result<CalibrationReport> {
    let s = read_source(path, Setting::Report)?;
    CalibrationReport::from_json(&s.text).map_err(|e| {
        Error::input(
            Location::file(&s.name),
            format!("not a kinecal calibration report: {e}"),
        )
    })
}

/// A unit named by `setting`.
fn unit<U: std::str::FromStr<Err = String>>(
    u: Option<&str>,
    setting: Setting,
) -> Result<Option<U>> {
    u.map(str::parse)
        .transpose()
        .map_err(|m: String| invalid(setting, m))
}

/// A URDF export's warnings as notes, but for the slopes: a slope is said with its deviation,
/// as what the URDF cannot hold.
fn urdf_warning_notes(warnings: &[crate::Warning]) -> impl Iterator<Item = String> + '_ {
    warnings
        .iter()
        .filter(|w| !matches!(w, crate::Warning::UrdfSlope { .. }))
        .map(|w| format!("warning: {w}"))
}

/// The tolerance of an export of `robot`: the spec's over the default.
fn tolerance(t: &LengthAngle, robot: &Robot) -> Result<Tolerance> {
    t.check(Setting::Tolerance, false)?;
    let mut out = Tolerance::default_for(robot);
    let (l, a) = t.si(robot);
    if let Some(l) = l {
        out.position = l;
    }
    if let Some(a) = a {
        out.attitude = a;
    }
    Ok(out)
}

impl ExportSpec {
    /// Refuses keys the format does not take.
    fn check_keys(&self) -> Result<()> {
        let f = self.format;
        let takes = |formats: &[ExportFormat]| formats.contains(&f);
        use ExportFormat::*;
        for (key, given, formats) in [
            (
                "robot",
                self.robot.is_some(),
                &[Urdf, Ur, Dh, Joints, Ros, Gltf, CameraInfo][..],
            ),
            ("template", self.template.is_some(), &[Urdf, Ur, Ros]),
            ("base", self.base.is_some(), &[Urdf, Ros]),
            ("tip", !self.tip.is_empty(), &[Urdf, Ros]),
            (
                "measurement_frame",
                self.measurement_frame.is_some(),
                &[Ros],
            ),
            ("nominal", self.nominal.is_some(), &[Joints, Gltf]),
            ("convention", self.convention.is_some(), &[Dh]),
            ("length_unit", self.length_unit.is_some(), &[Dh]),
            ("angle_unit", self.angle_unit.is_some(), &[Dh]),
            (
                "tolerance",
                !is_default(&self.tolerance),
                &[Urdf, Ur, Dh, Joints, Ros],
            ),
            ("report", self.report.is_some(), &[Stiffness, Gltf]),
            ("observations", !self.observations.is_empty(), &[Gltf]),
            ("read", !is_default(&self.read), &[Gltf]),
            ("posture", self.posture.is_some(), &[Gltf]),
            ("camera", self.camera.is_some(), &[CameraInfo]),
        ] {
            if given && !takes(formats) {
                return Err(invalid(
                    Setting::OutputFormat,
                    format!("a {} export takes no {key}", f.as_str()),
                ));
            }
        }
        Ok(())
    }

    /// A required key of the format.
    fn needs<'a>(&self, v: &'a Option<String>, setting: Setting, what: &str) -> Result<&'a str> {
        v.as_deref().ok_or_else(|| {
            invalid(
                setting,
                format!("a {} export needs {what}", self.format.as_str()),
            )
        })
    }

    /// The exported text and what the export says.
    pub fn export(&self) -> Result<ExportOutcome> {
        self.check_keys()?;
        let mut out = ExportOutcome {
            read_back: None,
            lost: Vec::new(),
            notes: Vec::new(),
            tcp: None,
            text: String::new(),
            files: Vec::new(),
            bytes: Vec::new(),
        };
        if self.format == ExportFormat::Stiffness {
            self.stiffness(&mut out)?;
            return Ok(out);
        }
        let name = self.needs(&self.robot, Setting::Robot, "the calibrated robot")?;
        let (robot, _) = robot_as(name, Setting::Robot)?;
        let tol = tolerance(&self.tolerance, &robot)?;
        match self.format {
            ExportFormat::Urdf => self.urdf(&robot, &tol, &mut out)?,
            ExportFormat::Ur => self.ur(&robot, &tol, &mut out)?,
            ExportFormat::Dh => self.dh(&robot, &tol, &mut out)?,
            ExportFormat::Joints => self.joints(&robot, &tol, &mut out)?,
            ExportFormat::Ros => self.ros(&robot, &tol, &mut out)?,
            ExportFormat::Gltf => self.gltf(&robot, &mut out)?,
            ExportFormat::CameraInfo => self.camera_info(&robot, &mut out)?,
            ExportFormat::Stiffness => unreachable!("handled above"),
        }
        Ok(out)
    }

    /// The stiffness table of a calibration report's mass model.
    fn stiffness(&self, out: &mut ExportOutcome) -> Result<()> {
        let path = self.needs(&self.report, Setting::Report, "a calibration report")?;
        let report = read_report(path)?;
        let Some(elastic) = &report.elastic else {
            return Err(Error::input(
                Location::file(path),
                format!(
                    "the calibrated robot `{}` has no mass model, so no compliances (add \
                     [[bodies]] to its robot file, or import its URDF with masses)",
                    report.robot
                ),
            ));
        };
        out.text = elastic.table();
        out.notes.push(format!(
            "{} compliances ({} estimated)",
            elastic.joints.len(),
            elastic.joints.iter().filter(|j| j.estimated).count()
        ));
        Ok(())
    }

    /// The URDF the robot was imported from (`template`), read.
    fn urdf_template(&self) -> Result<crate::source::Source> {
        read_source(
            self.needs(
                &self.template,
                Setting::Template,
                "the URDF it was imported from",
            )?,
            Setting::Template,
        )
    }

    /// A URDF: the template with the calibrated joint origins, read back within `tol`.
    fn urdf(&self, robot: &Robot, tol: &Tolerance, out: &mut ExportOutcome) -> Result<()> {
        let units = robot.units;
        let t = self.urdf_template()?;
        let tips: Vec<&str> = self.tip.iter().map(String::as_str).collect();
        let e =
            crate::import::urdf::export_urdf(robot, &t.text, &t.name, self.base.as_deref(), &tips)?;
        e.check(robot, tol)?;
        out.notes.extend(urdf_warning_notes(&e.warnings));
        out.lost = e.lost.iter().map(|l| l.line(units)).collect();
        out.read_back = Some(e.read_back.line(units));
        out.text = e.text;
        Ok(())
    }

    /// A Universal Robots kinematics file (the template's, with the calibration), read back
    /// within `tol`.
    fn ur(&self, robot: &Robot, tol: &Tolerance, out: &mut ExportOutcome) -> Result<()> {
        let units = robot.units;
        let t = read_source(
            self.needs(
                &self.template,
                Setting::Template,
                "the kinematics file it was imported from",
            )?,
            Setting::Template,
        )?;
        let e = crate::import::ur::export_ur(robot, &t.text, &t.name)?;
        e.check(tol)?;
        out.notes.extend(e.left_out());
        out.lost = e.lost.iter().map(|l| l.line(units)).collect();
        out.read_back = Some(e.read_back.line(units));
        out.tcp = Some(e.tcp_line());
        out.text = e.text;
        Ok(())
    }

    /// A DH table in the convention and units asked for, read back within `tol`.
    fn dh(&self, robot: &Robot, tol: &Tolerance, out: &mut ExportOutcome) -> Result<()> {
        let units = robot.units;
        let convention = self
            .convention
            .ok_or_else(|| invalid(Setting::Convention, "a dh export needs the convention"))?;
        let dh_units = crate::Units {
            length: unit(self.length_unit.as_deref(), Setting::LengthUnit)?.unwrap_or(units.length),
            angle: unit(self.angle_unit.as_deref(), Setting::AngleUnit)?.unwrap_or(units.angle),
        };
        let e = crate::import::dh::export_dh(robot, convention, dh_units)?;
        e.check(robot, tol)?;
        out.lost = e.lost.iter().map(|l| l.line(units)).collect();
        out.read_back = Some(e.read_back.line(units));
        out.notes.extend(e.notes());
        out.notes.push(format!(
            "the {} DH table ({}, {})",
            convention.as_str(),
            dh_units.length,
            dh_units.angle
        ));
        out.text = e.text;
        Ok(())
    }

    /// The joint table (each joint's calibrated offset and slope, and their changes from the
    /// nominal robot's), read back within `tol`.
    fn joints(&self, robot: &Robot, tol: &Tolerance, out: &mut ExportOutcome) -> Result<()> {
        let units = robot.units;
        let n = self.needs(&self.nominal, Setting::NominalRobot, "the nominal robot")?;
        let (nominal, _) = robot_as(n, Setting::NominalRobot)?;
        let e = crate::import::joints::joint_table(robot, &nominal)?;
        e.check(robot, tol)?;
        out.lost = e.lost.iter().map(|l| l.line(units)).collect();
        out.read_back = Some(e.read_back.line(units));
        out.text = e.text;
        Ok(())
    }

    /// The ROS 2 description files, read back within `tol`.
    fn ros(&self, robot: &Robot, tol: &Tolerance, out: &mut ExportOutcome) -> Result<()> {
        let units = robot.units;
        let t = self.urdf_template()?;
        let tips: Vec<&str> = self.tip.iter().map(String::as_str).collect();
        let e = crate::import::ros::export_ros(
            robot,
            &t.text,
            &t.name,
            self.base.as_deref(),
            &tips,
            self.measurement_frame.as_deref(),
        )?;
        e.check(robot, tol)?;
        out.notes.extend(urdf_warning_notes(&e.warnings));
        out.notes.extend(e.notes.iter().cloned());
        out.lost = e.lost.iter().map(|l| l.line(units)).collect();
        out.read_back = Some(e.read_back.line(units));
        out.text = e.calibration.clone();
        out.files = e
            .files()
            .iter()
            .map(|(n, t)| (n.to_string(), t.to_string()))
            .collect();
        Ok(())
    }

    /// The 3-D scene as a binary glTF.
    fn gltf(&self, robot: &Robot, out: &mut ExportOutcome) -> Result<()> {
        let (scene, from) = self.scene(robot)?;
        out.bytes = crate::report::gltf::write_glb(&scene)?;
        let posture = &scene.postures[0];
        let robots = if posture.nominal.is_some() {
            "the nominal and the calibrated robot"
        } else {
            "the calibrated robot"
        };
        out.notes.push(if scene.postures_total == 0 {
            format!("{from}: {robots} at zero readings (no observations given)")
        } else {
            format!(
                "{from}: {robots} at posture {}, {} of {} measured points, residuals \
                 drawn {} times their length{}",
                posture.label,
                scene.points.len(),
                scene.points_total,
                scene.residual_scale,
                if scene.points.iter().any(|p| p.before.is_some()) {
                    format!(" ({} before calibration)", scene.residual_scale_before)
                } else {
                    String::new()
                }
            )
        });
        if scene.points_unplottable > 0 {
            out.notes.push(format!(
                "{} measured points not drawn: not finite or beyond {:e} m",
                scene.points_unplottable,
                crate::report::scene::LIMIT
            ));
        }
        Ok(())
    }

    /// A camera's lens as a ROS camera_info file.
    fn camera_info(&self, robot: &Robot, out: &mut ExportOutcome) -> Result<()> {
        let (info, text) =
            crate::import::camera_info::export_camera_info(robot, self.camera.as_deref())?;
        let [fx, fy, cx, cy] = info.intrinsics;
        let [k1, k2, p1, p2, k3] = info.distortion;
        out.read_back = Some(format!(
            "read back: the same lens to the last bit ({} x {} px; fx {fx}, fy {fy}, cx \
             {cx}, cy {cy}; k1, k2, p1, p2, k3 {k1}, {k2}, {p1}, {p2}, {k3})",
            info.width, info.height,
        ));
        out.notes.push(format!(
            "camera `{}`: its lens (camera_info holds no pose: the hand-eye stays in the \
             robot file)",
            info.name
        ));
        out.text = text;
        Ok(())
    }

    /// The scene a gltf export writes, and where it came from: the report's own (the one its
    /// HTML page draws) when the export gives nothing else; otherwise `robot` (the calibrated
    /// robot) on the observations, beside the nominal robot (`nominal`, or the report's initial
    /// values on `robot`'s structure), at `posture`.
    fn scene(&self, robot: &Robot) -> Result<(crate::report::scene::Scene, &'static str)> {
        use crate::report::scene::{Scene, SceneOptions};
        let report = self.report.as_deref().map(read_report).transpose()?;
        if let Some(rep) = &report {
            if rep.robot != robot.name {
                return Err(invalid(
                    Setting::Report,
                    format!(
                        "the report is of robot `{}`, the robot file of `{}`",
                        rep.robot, robot.name
                    ),
                ));
            }
        }
        if let Some(scene) = report.as_ref().and_then(|r| r.scene.as_ref()) {
            if self.observations.is_empty() && self.nominal.is_none() && self.posture.is_none() {
                scene.check()?;
                return Ok((scene.clone(), "the report's scene"));
            }
        }
        let data = if self.observations.is_empty() {
            if self.posture.is_some() {
                return Err(invalid(
                    Setting::Observations,
                    "a posture to draw is named, and no observations to find it in are given",
                ));
            }
            None
        } else {
            Some(read_observations(&self.read, &self.observations, robot)?.0)
        };
        if let (Some(label), Some(d)) = (&self.posture, &data) {
            if !d.postures.iter().any(|p| &p.label == label) {
                return Err(invalid(
                    Setting::Observations,
                    format!("no posture `{label}` in the observations"),
                ));
            }
        }
        let nominal = match (&self.nominal, &report) {
            (Some(n), _) => Some(robot_as(n, Setting::NominalRobot)?.0),
            (None, Some(rep)) => {
                let path = self.report.as_deref().unwrap_or_default();
                if rep.parameters.len() != robot.param_count() {
                    return Err(Error::input(
                        Location::file(path),
                        format!(
                            "the report has {} parameters, the robot {}",
                            rep.parameters.len(),
                            robot.param_count()
                        ),
                    ));
                }
                let units = crate::Units {
                    length: rep.length_unit,
                    angle: rep.angle_unit,
                };
                let mut n = robot.clone();
                for (id, p) in robot.param_ids().zip(&rep.parameters) {
                    n.set(id, units.to_si(robot.param_quantity(id), p.initial));
                }
                Some(n)
            }
            (None, None) => None,
        };
        let options = SceneOptions {
            posture: self.posture.clone(),
            ..SceneOptions::default()
        };
        let scene = Scene::new(nominal.as_ref(), robot, data.as_ref(), &options)?;
        Ok((scene, "the scene"))
    }

    /// Exports and writes the file.
    pub(crate) fn run(&self, env: &mut Env<'_>) -> Result<Done> {
        let out = self.export()?;
        let mut messages: Vec<Message> = Vec::new();
        let written = |path: &str| match self.format {
            ExportFormat::Urdf => format!("wrote the calibrated URDF to {path}"),
            ExportFormat::Ur => format!("wrote the calibrated kinematics to {path}"),
            ExportFormat::Dh => format!(
                "wrote {} to {path}",
                out.notes.last().map_or("", String::as_str)
            ),
            ExportFormat::Joints => format!("wrote the joint table to {path}"),
            ExportFormat::Stiffness => format!(
                "wrote {} to {path}",
                out.notes.last().map_or("", String::as_str)
            ),
            ExportFormat::Gltf => format!("wrote the 3-D scene to {path}"),
            ExportFormat::CameraInfo => format!("wrote the camera_info to {path}"),
            ExportFormat::Ros => format!(
                "wrote {} into {path}",
                out.files
                    .iter()
                    .map(|(n, _)| n.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        };
        let shown_notes = match self.format {
            // The last note names what is written.
            ExportFormat::Dh | ExportFormat::Stiffness => {
                &out.notes[..out.notes.len().saturating_sub(1)]
            }
            _ => &out.notes[..],
        };
        let (before, after): (Vec<&String>, Vec<&String>) = match self.format {
            // UR: what is left out first; DH: its notes after the read-back.
            ExportFormat::Ur | ExportFormat::Urdf | ExportFormat::Ros => {
                (shown_notes.iter().collect(), Vec::new())
            }
            _ => (Vec::new(), shown_notes.iter().collect()),
        };
        messages.extend(before.into_iter().map(|n| Message::Note(n.clone())));
        messages.extend(out.lost.iter().map(|l| Message::Note(l.clone())));
        messages.extend(out.read_back.iter().map(|l| Message::Note(l.clone())));
        messages.extend(after.into_iter().map(|n| Message::Note(n.clone())));
        match &self.out {
            Some(p) if self.format == ExportFormat::Ros => {
                self.write_folder(p, &out.files, env)?;
                messages.push(Message::Note(written(p)));
            }
            Some(p) if self.format == ExportFormat::Gltf => {
                let mut staged = crate::files::output::Staged::new();
                staged.bytes(Path::new(p), &out.bytes)?;
                staged.commit()?;
                messages.push(Message::Note(written(p)));
            }
            Some(p) => {
                crate::files::output::write_file(Path::new(p), &out.text)?;
                messages.push(Message::Note(written(p)));
            }
            None => {}
        }
        Ok(Done {
            document: Document::Export(out),
            messages,
            status: super::Status::Ok,
            pending: None,
        })
    }
}

impl ExportSpec {
    /// Writes `files` into the folder `dir` (made when missing, as `kinecal dataset` does),
    /// each through the output writer, all or none: refused when `dir` is not a folder or a
    /// file would replace an input of the run.
    fn write_folder(&self, dir: &str, files: &[(String, String)], env: &Env<'_>) -> Result<()> {
        let folder = Path::new(dir);
        if folder.exists() && !folder.is_dir() {
            return Err(Error::Output {
                path: dir.to_string(),
                message: "is not a folder: a ros export writes its files into a folder".into(),
            });
        }
        let paths: Vec<std::path::PathBuf> = files.iter().map(|(n, _)| folder.join(n)).collect();
        let mut inputs: Vec<std::path::PathBuf> = Vec::new();
        let mut spec = self.clone();
        spec.visit_paths(&mut |role, p| {
            if role == PathRole::Input
                || (role == PathRole::Robot && super::common::is_robot_file(p))
            {
                inputs.push(std::path::PathBuf::from(p.as_str()));
            }
        });
        inputs.extend(env.also_inputs.iter().cloned());
        // Outputs against inputs first (a folder not there yet holds no input), then the folder
        // made: a refused export leaves nothing behind.
        if folder.exists() {
            crate::files::output::check_distinct(
                &paths.iter().map(|p| p.as_path()).collect::<Vec<_>>(),
                &inputs.iter().map(|p| p.as_path()).collect::<Vec<_>>(),
            )?;
        } else {
            std::fs::create_dir_all(folder).map_err(|cause| Error::Io {
                path: dir.to_string(),
                cause,
            })?;
        }
        let mut staged = crate::files::output::Staged::new();
        for (path, (_, text)) in paths.iter().zip(files) {
            staged.text(path, text)?;
        }
        staged.commit()
    }
}

impl ImportSpec {
    /// The robot the file describes, and what the import says.
    pub fn import(&self) -> Result<(Robot, Vec<String>)> {
        let s = read_source(&self.file, Setting::Input)?;
        let urdf_only = self.base.is_some() || !self.tip.is_empty() || self.masses;
        let dh_only = self.convention.is_some()
            || self.length_unit.is_some()
            || self.angle_unit.is_some()
            || self.robot_name.is_some();
        if (urdf_only && self.format != ImportFormat::Urdf)
            || (dh_only && self.format != ImportFormat::Dh)
        {
            return Err(invalid(
                Setting::OutputFormat,
                "base, tip and masses are for URDF files; convention, units and robot_name for DH \
                 tables",
            ));
        }
        let mut notes = Vec::new();
        let robot = match self.format {
            ImportFormat::Ur => crate::import::ur::import_ur(&s.text, &s.name)?.robot,
            ImportFormat::Poe => crate::import::poe::parse_poe_toml(&s.text, &s.name)?,
            ImportFormat::Urdf => {
                let tips: Vec<&str> = self.tip.iter().map(String::as_str).collect();
                let imp = crate::import::urdf::import_urdf_with(
                    &s.text,
                    &s.name,
                    self.base.as_deref(),
                    &tips,
                    self.masses,
                )?;
                if let Some(e) = &imp.robot.elastic {
                    notes.push(format!(
                        "mass model: {} bodies, {} kg in all, gravity {} m/s^2 along -z",
                        e.bodies.len(),
                        // To the gram: the sum of the file's masses without float noise.
                        crate::units::number::format_number(
                            (e.bodies.iter().map(|b| b.mass).sum::<f64>() * 1e3).round() / 1e3
                        ),
                        crate::units::number::format_number(e.gravity.norm())
                    ));
                }
                imp.robot
            }
            ImportFormat::Dh => crate::import::dh::import_dh(
                &s.text,
                &s.name,
                // Unnamed: the table's file name without its extension.
                self.robot_name.as_deref().unwrap_or_else(|| {
                    std::path::Path::new(&self.file)
                        .file_stem()
                        .and_then(|s| s.to_str())
                        .unwrap_or("")
                }),
                unit(self.length_unit.as_deref(), Setting::LengthUnit)?,
                unit(self.angle_unit.as_deref(), Setting::AngleUnit)?,
                self.convention,
            )?,
        };
        Ok((robot, notes))
    }

    /// Imports and writes the robot file.
    pub(crate) fn run(&self, _env: &mut Env<'_>) -> Result<Done> {
        let (robot, notes) = self.import()?;
        let text = crate::model::robot_file::write_robot_toml_checked(&robot, None)?;
        let mut messages: Vec<Message> = notes.iter().cloned().map(Message::Note).collect();
        if let Some(p) = &self.out {
            crate::files::output::write_file(Path::new(p), &text)?;
            messages.push(Message::Note(format!(
                "wrote {} ({} joints, {} parameters) to {p}",
                if robot.name.is_empty() {
                    "the robot"
                } else {
                    &robot.name
                },
                robot.dof(),
                robot.param_count(),
            )));
        }
        Ok(Done {
            document: Document::Export(ExportOutcome {
                read_back: None,
                lost: Vec::new(),
                notes,
                tcp: None,
                text,
                files: Vec::new(),
                bytes: Vec::new(),
            }),
            messages,
            status: super::Status::Ok,
            pending: None,
        })
    }
}
