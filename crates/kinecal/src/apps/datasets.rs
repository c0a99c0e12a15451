//! Adapters for public calibration data sets whose files are laid out in their own way: each
//! reads a data set's folder (as in `../shared/data`, described by its README) into a kinecal
//! robot and observations, and [`DATASETS`] lists them for front ends (`kinecal dataset`).
//!
//! - [`qkm_hl6`]: QKM HL6 + FARO laser tracker: 46 identification positions of one of three
//!   reflectors (SMRs) per posture, and 9 held-out test points.
//! - [`fanuc_r2000ic`]: FANUC R-2000iC/165F + laser tracker: 36 postures (single-joint sweeps) x
//!   3 reflectors; the controller's joint values as read, with the J2/J3 coupling in the robot.
//! - [`ur10e_camera`]: UR10e with a wrist camera: 23 camera-measured poses.
//! - [`ipa_ur10`]: UR10 + Leica laser tracker: 16,811 probe positions in four series (one
//!   measurement session each), with the tracker's per-axis standard deviations and the
//!   temperatures.

use std::path::{Path, PathBuf};

use nalgebra::{Matrix3, Vector3};

use crate::error::{Error, Location, Result};
use crate::files::write_measurements;
use crate::model::robot_file::write_robot_toml;
use crate::source::Source;

/// A data set converted into kinecal's files.
#[derive(Debug, Clone)]
pub struct Converted {
    /// (file name, contents) to write.
    pub files: Vec<(String, String)>,
    /// What was converted, for the user.
    pub summary: String,
    /// The calibration the data set's README suggests, over the files.
    pub suggested: Suggested,
}

impl Converted {
    /// The mean held-out position error (m) a correct calibration reaches on the suggested
    /// validation files together, as `kinecal calibrate` pools them: the README's figure of each
    /// file ([`Suggested::held_out`]) weighted by its observation rows. `None` when the README
    /// gives no figure for some validation file.
    pub fn held_out_pooled(&self) -> Option<f64> {
        let s = &self.suggested;
        if s.validate.is_empty() {
            return None;
        }
        let (mut sum, mut rows) = (0.0, 0usize);
        for v in s.validate {
            let (_, m) = s.held_out.iter().find(|(f, _)| f == v)?;
            let (_, text) = self.files.iter().find(|(f, _)| f == v)?;
            // A measurement file kinecal writes: a header, then one observation per line.
            let n = text
                .lines()
                .skip(1)
                .filter(|l| !l.trim().is_empty())
                .count();
            sum += m * n as f64;
            rows += n;
        }
        (rows > 0).then(|| sum / rows as f64)
    }
}

/// The calibration a data set's README suggests: which files, what to estimate, how to weigh
/// and validate. Front ends turn it into their own form (a command line, a call).
#[derive(Debug, Clone, PartialEq)]
pub struct Suggested {
    /// The robot file (one of [`Converted::files`]).
    pub robot: &'static str,
    /// The measurement file.
    pub data: &'static str,
    /// Separate validation files, when the data set has them (checked together: one
    /// `--validate` each).
    pub validate: &'static [&'static str],
    /// The parameters to estimate, as a parameter list (`identifiable`, `link1,link7,offsets`).
    pub estimate: &'static str,
    /// The fraction of postures to hold out, when there is no validation file.
    pub holdout: Option<f64>,
    /// Standard deviations `(length, angle)` in the robot file's units, when not the default.
    pub weights: Option<(f64, f64)>,
    /// The attitude residual, when not the default (the rotation vector).
    pub orientation: Option<crate::observe::OrientationError>,
    /// What a correct calibration reaches on each validation file, per the data set's README:
    /// `(file, mean position error in m)`, each file checked alone (its session frames
    /// re-estimated on it). Empty when the README gives no such figure.
    pub held_out: &'static [(&'static str, f64)],
}

/// A data set adapter: its name, a line about it, and the conversion of its folder.
#[derive(Clone, Copy)]
pub struct Adapter {
    /// The name (`qkm-hl6`).
    pub name: &'static str,
    /// What it reads.
    pub about: &'static str,
    /// Converts the folder on disk.
    pub convert: fn(&Path) -> Result<Converted>,
    /// Converts the folder's files (on disk or in memory).
    pub read: fn(&Folder) -> Result<Converted>,
}

impl std::fmt::Debug for Adapter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Adapter({})", self.name)
    }
}

/// Every adapter.
pub const DATASETS: &[Adapter] = &[
    Adapter {
        name: "qkm-hl6",
        about: "QKM HL6 + FARO laser tracker (qkm_hl6_faro): 46 reflector positions, 9 held-out",
        convert: qkm_hl6::convert,
        read: qkm_hl6::convert_folder,
    },
    Adapter {
        name: "fanuc-r2000ic",
        about: "FANUC R-2000iC + laser tracker (fanuc_r2000ic_lasertracker): 36 postures x 3 \
                reflectors, controller joint values with the J2/J3 coupling",
        convert: fanuc_r2000ic::convert,
        read: fanuc_r2000ic::convert_folder,
    },
    Adapter {
        name: "ur10e-camera",
        about: "UR10e + wrist camera (ur10e_camera): 23 camera-measured poses",
        convert: ur10e_camera::convert,
        read: ur10e_camera::convert_folder,
    },
    Adapter {
        name: "ipa-ur10",
        about: "UR10 + Leica laser tracker (ipa_ur10_tracker): 16,811 probe positions in four \
                series A-D, one session each, per-axis tracker sigmas, temperatures",
        convert: ipa_ur10::convert,
        read: ipa_ur10::convert_folder,
    },
];

/// A data set's folder: its files read from disk, or (for tests and fuzzing) held in memory
/// under the names they would have in the folder. Either way a file is named in messages as
/// the folder joined with its name (`data/qkm_hl6_faro/position_dataset/c_angles.txt`).
#[derive(Debug, Clone)]
pub struct Folder {
    dir: PathBuf,
    memory: Option<Vec<(String, Vec<u8>)>>,
}

impl Folder {
    /// The folder `dir` on disk.
    pub fn disk(dir: &Path) -> Folder {
        Folder {
            dir: dir.to_path_buf(),
            memory: None,
        }
    }

    /// Files in memory, as `(name in the folder, bytes)` (`position_dataset/c_angles.txt`),
    /// named in messages as if in the folder `dir`. A name not among them reads as a missing
    /// file.
    pub fn memory(dir: &Path, files: Vec<(String, Vec<u8>)>) -> Folder {
        Folder {
            dir: dir.to_path_buf(),
            memory: Some(files),
        }
    }

    /// The folder as named in messages.
    pub fn name(&self) -> String {
        self.dir.display().to_string()
    }

    /// Reads the file `name` of the folder (a `/`-separated path inside it).
    pub fn read(&self, name: &str) -> Result<Source> {
        let path = self.dir.join(name);
        match &self.memory {
            None => Source::read(&path),
            Some(files) => match files.iter().find(|(n, _)| n == name) {
                Some((_, bytes)) => Source::from_bytes(path.display().to_string(), bytes.clone()),
                None => Err(Error::Io {
                    path: path.display().to_string(),
                    cause: std::io::Error::from(std::io::ErrorKind::NotFound),
                }),
            },
        }
    }
}

/// Reads whitespace- or comma-separated rows of `cols` numbers (blank lines skipped), exactly
/// `rows` of them (the count the data set's README gives): a file with rows missing (truncated)
/// or extra is refused with the count, at the line where the next row was expected or the extra
/// row stands. Every number must be finite and within +-1e9 ([`crate::units::plausible`]).
/// Returns the rows and their line numbers.
fn read_rows(source: &Source, cols: usize, rows: usize) -> Result<(Vec<Vec<f64>>, Vec<usize>)> {
    let file = &source.name;
    let mut out = Vec::new();
    let mut lines = Vec::new();
    let mut last = 0;
    for (i, line) in source.text.lines().enumerate() {
        let line = line.trim_start_matches('\u{feff}');
        if line.trim().is_empty() {
            continue;
        }
        let at = Location::file(file).at_line(i + 1);
        if out.len() == rows {
            return Err(Error::input(
                at,
                format!("expected {rows} rows of {cols} numbers, found more"),
            ));
        }
        let fields: Vec<&str> = line
            .split(|c: char| c == ',' || c.is_whitespace())
            .filter(|s| !s.is_empty())
            .collect();
        if fields.len() != cols {
            return Err(Error::input(
                at,
                format!("expected {cols} numbers, found {}", fields.len()),
            ));
        }
        let mut vals = Vec::with_capacity(cols);
        for (k, s) in fields.iter().enumerate() {
            let at = at.with_field(format!("column {}", k + 1));
            let v: f64 = s
                .parse()
                .map_err(|_| Error::input(at.clone(), format!("expected a number, found `{s}`")))?;
            if !crate::units::plausible(v) {
                return Err(Error::input(
                    at,
                    format!("expected a finite number within +-1e9, found `{s}`"),
                ));
            }
            vals.push(v);
        }
        out.push(vals);
        lines.push(i + 1);
        last = i + 1;
    }
    if out.len() < rows {
        return Err(Error::input(
            Location::file(file).at_line(last + 1),
            format!(
                "expected {rows} rows of {cols} numbers, found {} (the file ends here: truncated?)",
                out.len()
            ),
        ));
    }
    Ok((out, lines))
}

/// A point of a file, in the file's units, refused when (after a change of frame) it is beyond
/// +-1e9: kinecal would refuse the file it writes.
fn plausible_point(p: Vector3<f64>, at: &Location, what: &str) -> Result<Vector3<f64>> {
    if p.iter().all(|v| crate::units::plausible(*v)) {
        Ok(p)
    } else {
        Err(Error::input(
            at.clone(),
            format!("{what} ({}, {}, {}) is beyond +-1e9", p.x, p.y, p.z),
        ))
    }
}

/// The rigid transform `[R | t]` of three rows of four numbers: `R` must be a rotation (its
/// columns orthonormal to 1e-6, determinant +1).
fn transform(source: &Source) -> Result<(Matrix3<f64>, Vector3<f64>)> {
    let (rows, _) = read_rows(source, 4, 3)?;
    let r = Matrix3::from_fn(|i, j| rows[i][j]);
    let t = Vector3::new(rows[0][3], rows[1][3], rows[2][3]);
    let off = (r.transpose() * r - Matrix3::identity()).amax();
    if off.is_nan() || off > 1e-6 || r.determinant() <= 0.0 {
        return Err(Error::input(
            Location::file(&source.name).at_line(1),
            format!(
                "columns 1-3 of the 3 rows are not a rotation (R^T R differs from the identity by \
                 {off:.1e}, det {:.3e})",
                r.determinant()
            ),
        ));
    }
    Ok((r, t))
}

/// The orthonormal frame with x along `x` and `y` from `y` made orthogonal to x, or `None` when
/// the two are (nearly) parallel or zero (relative to their lengths).
fn frame(x: Vector3<f64>, y: Vector3<f64>) -> Option<Matrix3<f64>> {
    let (nx, ny) = (x.norm(), y.norm());
    if !(nx > 0.0 && ny > 0.0) || x.cross(&y).norm() <= 1e-9 * nx * ny {
        return None;
    }
    let x = x / nx;
    let y = (y / ny - x * (y / ny).dot(&x)).normalize();
    Some(Matrix3::from_columns(&[x, y, x.cross(&y)]))
}

/// The nominal robot of a POE text built from the data (`name` for it), refused naming
/// `data_file` (the file whose values it holds) when it cannot be read.
fn nominal(poe: &str, name: &str, data_file: &str) -> Result<crate::model::robot::Robot> {
    crate::import::poe::parse_poe_toml(poe, name).map_err(|e| {
        Error::input(
            Location::file(data_file),
            format!("the nominal robot built with this file's values is refused: {e}"),
        )
    })
}

/// Appends a revolute joint to a product-of-exponentials text: its axis direction `w` and a
/// point `q` on the axis (the text's units, zero configuration), then `extra`, more lines of
/// the joint's table (each ending in a newline; empty for none).
fn push_revolute_joint(poe: &mut String, w: [i32; 3], q: [i32; 3], extra: &str) {
    use std::fmt::Write as _;
    let _ = write!(
        poe,
        "\n[[joints]]\nkind = \"revolute\"\naxis = [{}, {}, {}]\npoint = [{}, {}, {}]\n{extra}",
        w[0], w[1], w[2], q[0], q[1], q[2]
    );
}

/// Appends reflector `k` (0-based, named `smr1`, `smr2`, ...) as a site on joint 6 to a
/// product-of-exponentials text, at its zero-configuration position `p` (the text's units).
fn push_reflector_site(poe: &mut String, k: usize, p: Vector3<f64>) {
    use std::fmt::Write as _;
    let _ = write!(
        poe,
        "\n[[sites]]\nname = \"smr{}\"\njoint = 6\nposition = [{}, {}, {}]\n",
        k + 1,
        p.x,
        p.y,
        p.z
    );
}

/// The QKM HL6 data set.
pub mod qkm_hl6 {
    use std::path::Path;

    use nalgebra::{Matrix3, Vector3};

    use super::{
        frame, nominal, plausible_point, push_reflector_site, push_revolute_joint, read_rows,
        write_measurements, write_robot_toml, Converted, Folder,
    };
    use crate::error::{Error, Location, Result};
    use crate::model::kinematics::Target;
    use crate::model::robot::Robot;
    use crate::observe::point::Position;
    use crate::observe::{Dataset, Posture};
    use crate::source::Source;

    /// The files of the data set read, with the rows each must have (its README's counts).
    const REF: (&str, usize) = ("position_dataset/re_ref.txt", 3);
    const SMR: (&str, usize) = ("position_dataset/re_smr.txt", 3);
    const ANGLES: (&str, usize) = ("position_dataset/c_angles.txt", 46);
    const POINTS: (&str, usize) = ("position_dataset/c_poses.txt", 46);
    const TEST_ANGLES: (&str, usize) = ("position_dataset/test_points.txt", 9);
    const TEST_POINTS: (&str, usize) = ("position_dataset/re_test.txt", 9);

    /// The data set converted to kinecal's model and measurements.
    #[derive(Debug, Clone)]
    pub struct QkmData {
        /// The nominal robot as a product-of-exponentials file (mm, deg; reference frame).
        pub(crate) poe_toml: String,
        /// The nominal robot: joints from the POE model, the three reflectors as sites on joint 6
        /// at their measured zero-configuration positions.
        pub robot: Robot,
        /// The 46 identification positions.
        pub identification: Dataset,
        /// The 9 held-out test points.
        pub validation: Dataset,
    }

    /// The user (reference) frame built from three tracker points (README: "method 1"): origin
    /// P1, x along P1 - P3, y along P2 - P1 made orthogonal to x, z = x cross y. Returns
    /// `(R, origin)`, mapping reference coordinates to tracker coordinates. (The original script
    /// does not re-normalise y; a rigid frame needs it, and the first link absorbs the base
    /// placement either way.)
    fn reference_frame(source: &Source) -> Result<(Matrix3<f64>, Vector3<f64>)> {
        let (p, _) = read_rows(source, 3, REF.1)?;
        let v = |r: &Vec<f64>| Vector3::new(r[0], r[1], r[2]);
        let (p1, p2, p3) = (v(&p[0]), v(&p[1]), v(&p[2]));
        let r = frame(p1 - p3, p2 - p1).ok_or_else(|| {
            Error::input(
                Location::file(&source.name),
                "the three reference points coincide or lie on a line: they define no frame",
            )
        })?;
        Ok((r, p1))
    }

    /// The postures of `angles` (six joint values and the reflector's index, 1 to 3, per row)
    /// and the positions of `points` (mm, tracker frame), in the reference frame.
    fn dataset(
        folder: &Folder,
        (angle_file, points_file): (&str, &str),
        rows: usize,
        to_ref: &dyn Fn(Vector3<f64>) -> Vector3<f64>,
        prefix: &str,
    ) -> Result<Dataset> {
        let angle_source = folder.read(angle_file)?;
        let (angles, angle_lines) = read_rows(&angle_source, 7, rows)?;
        let point_source = folder.read(points_file)?;
        let (points, point_lines) = read_rows(&point_source, 3, rows)?;
        let mut postures = Vec::new();
        let mut measurements = Vec::new();
        for (i, (a, p)) in angles.iter().zip(&points).enumerate() {
            postures.push(Posture {
                label: format!("{prefix}{}", i + 1),
                readings: a[..6].to_vec(),
                session: None,
                payload: None,
            });
            let smr = match a[6] {
                v if [1.0, 2.0, 3.0].contains(&v) => v as usize - 1,
                v => {
                    return Err(Error::input(
                        Location::file(&angle_source.name)
                            .at_line(angle_lines[i])
                            .with_field("column 7"),
                        format!("expected the reflector (SMR) index 1, 2 or 3, found {v}"),
                    ))
                }
            };
            let at = Location::file(&point_source.name).at_line(point_lines[i]);
            let q = plausible_point(
                to_ref(Vector3::new(p[0], p[1], p[2])),
                &at,
                "in the reference frame, the point",
            )?;
            let mut m = Position::new(i, Target::Site(smr), q * 1e-3);
            m.line = i + 1;
            measurements.push(m.into());
        }
        Ok(Dataset::new(postures, measurements))
    }

    /// Loads the data set from its folder (`../shared/data/qkm_hl6_faro`).
    pub fn load(dir: &Path) -> Result<QkmData> {
        load_folder(&Folder::disk(dir))
    }

    /// Loads the data set from its files: each must have the rows its README gives (46
    /// identification rows, 9 test rows, 3 reference and 3 reflector points), every number
    /// finite and within +-1e9, the reflector indices 1 to 3.
    pub(crate) fn load_folder(folder: &Folder) -> Result<QkmData> {
        let (r, o) = reference_frame(&folder.read(REF.0)?)?;
        let smr_source = folder.read(SMR.0)?;
        let (smr, smr_lines) = read_rows(&smr_source, 3, SMR.1)?;
        let to_ref = move |p: Vector3<f64>| r.transpose() * (p - o);
        // Nominal product-of-exponentials model (nominal_model.yaml), mm and degrees, with the
        // file's joint-3 convention theta3 = file value - 90 deg.
        let mut poe = String::from(
            "# QKM HL6, nominal product-of-exponentials model (reference frame, mm, deg).\n\
             name = \"QKM HL6\"\nlength_unit = \"mm\"\nangle_unit = \"deg\"\n",
        );
        let axes = [
            ([0, 0, 1], [-590, 410, 300], 0),
            ([0, 1, 0], [-590, 410, 491], 0),
            ([0, 1, 0], [-590, 410, 841], -90),
            ([1, 0, 0], [-240, 410, 841], 0),
            ([0, 1, 0], [-240, 410, 841], 0),
            ([1, 0, 0], [-240, 410, 841], 0),
        ];
        for (w, q, off) in axes {
            push_revolute_joint(&mut poe, w, q, &format!("offset = {off}\n"));
        }
        poe.push_str("\n# Flange: 84 mm beyond the wrist centre along x.\n[tool]\nposition = [-156, 410, 841]\n");
        for (k, s) in smr.iter().enumerate() {
            // Measured at controller angles (0, 0, 90, 0, 0, 0) = model zero.
            let p = plausible_point(
                to_ref(Vector3::new(s[0], s[1], s[2])),
                &Location::file(&smr_source.name).at_line(smr_lines[k]),
                "in the reference frame, the reflector",
            )?;
            push_reflector_site(&mut poe, k, p);
        }
        let robot = nominal(&poe, "<qkm_hl6 nominal>", &smr_source.name)?;
        Ok(QkmData {
            robot,
            identification: dataset(folder, (ANGLES.0, POINTS.0), ANGLES.1, &to_ref, "c")?,
            validation: dataset(
                folder,
                (TEST_ANGLES.0, TEST_POINTS.0),
                TEST_ANGLES.1,
                &to_ref,
                "t",
            )?,
            poe_toml: poe,
        })
    }

    /// Reads and converts the folder: `qkm_poe.toml`, `qkm.toml`, `identification.csv`,
    /// `validation.csv`.
    pub fn convert(dir: &Path) -> Result<Converted> {
        convert_folder(&Folder::disk(dir))
    }

    /// [`convert`] of the folder's files.
    pub fn convert_folder(folder: &Folder) -> Result<Converted> {
        let d = load_folder(folder)?;
        Ok(Converted {
            files: vec![
                ("qkm_poe.toml".into(), d.poe_toml.clone()),
                ("qkm.toml".into(), write_robot_toml(&d.robot, None)),
                (
                    "identification.csv".into(),
                    write_measurements(&d.robot, &d.identification),
                ),
                (
                    "validation.csv".into(),
                    write_measurements(&d.robot, &d.validation),
                ),
            ],
            summary: format!(
                "QKM HL6: {} identification positions, {} held-out test points; the three \
                 reflectors are sites smr1..smr3 on joint 6 (mm, deg, reference frame)",
                d.identification.observations.len(),
                d.validation.observations.len()
            ),
            suggested: super::Suggested {
                robot: "qkm.toml",
                data: "identification.csv",
                validate: &["validation.csv"],
                estimate: "all,identifiable",
                holdout: None,
                weights: None,
                orientation: None,
                held_out: &[],
            },
        })
    }
}

/// The FANUC R-2000iC/165F laser-tracker data set (Boby & Klimchik; see
/// `../shared/data/fanuc_r2000ic_lasertracker/README.txt`).
///
/// The controller measures J3 from the horizontal: the model's joint 3 (ROS-Industrial's
/// `joint_3`) is `J2 + J3`. The adapter keeps the controller's values as the readings and puts
/// the coupling in the robot (joint 3 coupled to joint 2, factor 1), so that joint 3's slope
/// scales J3 itself. Points are converted from the tracker frame into the robot's World frame
/// with the data set's `TransTractoWorld0` (any error in it is absorbed by the first link); the
/// three reflectors are sites on joint 6, placed from `TransFlangtoNest0` and the reflector
/// spacing measured in the data. The end effector is the flange (`link_6`) frame.
pub mod fanuc_r2000ic {
    use std::fmt::Write as _;
    use std::path::Path;

    use nalgebra::{Matrix3, Vector3};

    use super::{
        nominal, plausible_point, push_reflector_site, push_revolute_joint, read_rows, transform,
        write_measurements, write_robot_toml, Converted, Folder,
    };
    use crate::error::{Error, Location, Result};
    use crate::model::kinematics::{rot_zyx, Target};
    use crate::model::robot::Robot;
    use crate::observe::point::Position;
    use crate::observe::{Dataset, Observation, Posture};

    /// The data set converted to kinecal's model and measurements.
    #[derive(Debug, Clone)]
    pub struct FanucData {
        /// The nominal robot as a product-of-exponentials file (mm, deg; robot World frame).
        pub(crate) poe_toml: String,
        /// The nominal robot, joint 3 coupled to joint 2.
        pub robot: Robot,
        /// 36 postures x 3 reflector positions (mm in files; the World frame).
        pub data: Dataset,
    }

    /// The postures in `N1N2N3Jval.csv` (its README: 36 rows of 21 numbers).
    const POSTURES: usize = 36;

    /// Loads the data set from its folder.
    pub fn load(dir: &Path) -> Result<FanucData> {
        load_folder(&Folder::disk(dir))
    }

    /// Loads the data set from its files: `N1N2N3Jval.csv` must have 36 rows of 21 numbers with
    /// three distinct reflector positions not on a line in each, the two transforms 3 rows of
    /// `[R | t]` with `R` a rotation; every number finite and within +-1e9.
    pub(crate) fn load_folder(folder: &Folder) -> Result<FanucData> {
        let source = folder.read("N1N2N3Jval.csv")?;
        let (rows, lines) = read_rows(&source, 21, POSTURES)?;
        let (rw, tw) = transform(&folder.read("TransTractoWorld0.csv")?)?;
        let nest_source = folder.read("TransFlangtoNest0.csv")?;
        let (rn, tn) = transform(&nest_source)?;
        // p_tracker = R p_world + t.
        let to_world = |p: Vector3<f64>| rw.transpose() * (p - tw);
        let point = |r: &[f64], k: usize| Vector3::new(r[3 * k], r[3 * k + 1], r[3 * k + 2]);
        // The reflectors in the nest frame (origin N2, x towards N1, N3 in the xy-plane),
        // averaged over the postures.
        let (mut n1, mut n3) = (Vector3::zeros(), Vector3::zeros());
        for (r, &line) in rows.iter().zip(&lines) {
            let (p1, p2, p3) = (point(r, 0), point(r, 1), point(r, 2));
            let (a, b) = (p1 - p2, p3 - p2);
            if a.cross(&b).norm() <= 1e-9 * a.norm() * b.norm() || a.norm() == 0.0 {
                return Err(Error::input(
                    Location::file(&source.name).at_line(line),
                    "the three reflector positions (columns 1-9) coincide or lie on a line: \
                     they define no nest frame",
                ));
            }
            let x = a.normalize();
            let z = x.cross(&b).normalize();
            let m = Matrix3::from_columns(&[x, z.cross(&x), z]);
            n1 += m.transpose() * (p1 - p2);
            n3 += m.transpose() * (p3 - p2);
        }
        let nest = [
            n1 / rows.len() as f64,
            Vector3::zeros(),
            n3 / rows.len() as f64,
        ];
        // ROS-Industrial's tool0 (the faceplate) at the zero configuration: the joint 6 centre,
        // rotated rpy(pi, -pi/2, 0) from link_6.
        let tool0 = rot_zyx(0.0, -std::f64::consts::FRAC_PI_2, std::f64::consts::PI);
        let wrist = Vector3::new(1807.0, 0.0, 1300.0);
        let mut poe = String::from(
            "# FANUC R-2000iC/165F, nominal (ROS-Industrial fanuc_r2000ic_support), World frame, \
             mm, deg.\n# Readings are the controller's J1..J6; J3 is measured from the \
             horizontal, so\n# the model's joint 3 is J2 + J3: joint 3 is coupled to joint 2.\n\
             name = \"FANUC R-2000iC/165F\"\nlength_unit = \"mm\"\nangle_unit = \"deg\"\n",
        );
        let joints = [
            ([0, 0, 1], [0, 0, 0], Some((-185, 185)), ""),
            ([0, 1, 0], [312, 0, 0], Some((-60, 76)), ""),
            (
                [0, -1, 0],
                [312, 0, 1075],
                None,
                "coupling = { joint = 2, factor = 1 }\n",
            ),
            ([-1, 0, 0], [312, 0, 1300], Some((-360, 360)), ""),
            ([0, -1, 0], [1592, 0, 1300], Some((-125, 125)), ""),
            ([-1, 0, 0], [1807, 0, 1300], Some((-360, 360)), ""),
        ];
        for (w, q, range, extra) in joints {
            push_revolute_joint(&mut poe, w, q, extra);
            if let Some((a, b)) = range {
                let _ = writeln!(poe, "min = {a}\nmax = {b}");
            }
        }
        poe.push_str("\n# The flange (link_6) frame.\n[tool]\nposition = [1807, 0, 1300]\n");
        for (k, n) in nest.iter().enumerate() {
            let p = plausible_point(
                wrist + tool0 * (rn * n + tn),
                &Location::file(&nest_source.name),
                &format!("reflector {} on the flange", k + 1),
            )?;
            push_reflector_site(&mut poe, k, p);
        }
        let robot = nominal(&poe, "<fanuc_r2000ic nominal>", &nest_source.name)?;
        let mut postures = Vec::new();
        let mut observations: Vec<Observation> = Vec::new();
        for (i, r) in rows.iter().enumerate() {
            postures.push(Posture {
                label: (i + 1).to_string(),
                readings: r[15..21].to_vec(),
                session: None,
                payload: None,
            });
            for k in 0..3 {
                let p = plausible_point(
                    to_world(point(r, k)),
                    &Location::file(&source.name).at_line(lines[i]),
                    &format!("in the World frame, reflector {}", k + 1),
                )?;
                let mut m = Position::new(i, Target::Site(k), p * 1e-3);
                m.line = i + 1;
                observations.push(m.into());
            }
        }
        Ok(FanucData {
            robot,
            data: Dataset::new(postures, observations),
            poe_toml: poe,
        })
    }

    /// Reads and converts the folder: `fanuc_poe.toml`, `fanuc.toml`, `measurements.csv`.
    pub fn convert(dir: &Path) -> Result<Converted> {
        convert_folder(&Folder::disk(dir))
    }

    /// [`convert`] of the folder's files.
    pub fn convert_folder(folder: &Folder) -> Result<Converted> {
        let d = load_folder(folder)?;
        Ok(Converted {
            files: vec![
                ("fanuc_poe.toml".into(), d.poe_toml.clone()),
                ("fanuc.toml".into(), write_robot_toml(&d.robot, None)),
                (
                    "measurements.csv".into(),
                    write_measurements(&d.robot, &d.data),
                ),
            ],
            summary: format!(
                "FANUC R-2000iC/165F: {} postures x 3 reflector positions (sites smr1..smr3 on \
                 joint 6), controller joint values, joint 3 coupled to joint 2 (mm, deg, World \
                 frame); single-joint sweeps, no separate test set",
                d.data.postures.len()
            ),
            suggested: super::Suggested {
                robot: "fanuc.toml",
                data: "measurements.csv",
                validate: &[],
                estimate: "identifiable",
                holdout: Some(0.17),
                weights: None,
                orientation: None,
                held_out: &[],
            },
        })
    }
}

/// The UR10e wrist-camera data set of FIGAROH (see `../shared/data/ur10e_camera/README.txt`):
/// 23 camera-measured 6-D poses of a frame on the wrist, in an undocumented world frame. The
/// robot is imported from the data set's URDF (`world` to `wrist_3_link`); the first and the
/// last links absorb the unknown placement of the camera's world frame and of the measured
/// frame on the wrist. Orientations are pinocchio RPY, `R = Rz(phiz) Ry(phiy) Rx(phix)`: the
/// ZYX Euler angles `(phiz, phiy, phix)`.
pub mod ur10e_camera {
    use std::path::Path;

    use nalgebra::Vector3;

    use super::{write_measurements, write_robot_toml, Converted, Folder};
    use crate::error::{Error, Location, Result};
    use crate::model::kinematics::Target;
    use crate::model::robot::Robot;
    use crate::observe::point::Pose;
    use crate::observe::{Dataset, Observation, Posture};

    /// The data set converted to kinecal's model and measurements.
    #[derive(Debug, Clone)]
    pub struct Ur10eData {
        /// The nominal robot (m, rad), imported from the URDF.
        pub robot: Robot,
        /// The 23 poses.
        pub data: Dataset,
    }

    /// The poses in `calibration.csv` (its README: 23 rows after the header).
    const POSES: usize = 23;

    /// Loads the data set from its folder.
    pub fn load(dir: &Path) -> Result<Ur10eData> {
        load_folder(&Folder::disk(dir))
    }

    /// Loads the data set from its files: the URDF's chain from `world` to `wrist_3_link` must
    /// have 6 joints, `calibration.csv` the header and 23 rows of 12 numbers, each finite and
    /// within +-1e9.
    pub(crate) fn load_folder(folder: &Folder) -> Result<Ur10eData> {
        let urdf = folder.read("ur10_robot.urdf")?;
        let robot = crate::import::urdf::import_urdf(
            &urdf.text,
            &urdf.name,
            Some("world"),
            Some("wrist_3_link"),
        )?
        .robot;
        if robot.dof() != 6 {
            return Err(Error::input(
                Location::file(&urdf.name),
                format!(
                    "the chain from `world` to `wrist_3_link` has {} joints: expected the 6 of \
                     calibration.csv's joint columns",
                    robot.dof()
                ),
            ));
        }
        let csv = folder.read("calibration.csv")?;
        let mut lines = csv.text.lines().enumerate();
        let expected = "x1,y1,z1,phix1,phiy1,phiz1,shoulder_pan_joint,shoulder_lift_joint,\
                        elbow_joint,wrist_1_joint,wrist_2_joint,wrist_3_joint";
        match lines.next() {
            Some((_, h)) if h.trim().trim_start_matches('\u{feff}') == expected => {}
            _ => {
                return Err(Error::input(
                    Location::file(&csv.name).at_line(1),
                    format!("expected the header `{expected}`"),
                ))
            }
        }
        let mut postures = Vec::new();
        let mut observations: Vec<Observation> = Vec::new();
        let mut last = 1;
        for (i, line) in lines {
            if line.trim().is_empty() {
                continue;
            }
            let at = Location::file(&csv.name).at_line(i + 1);
            if postures.len() == POSES {
                return Err(Error::input(
                    at,
                    format!("expected {POSES} rows after the header, found more"),
                ));
            }
            let fields: Vec<&str> = line.split(',').map(str::trim).collect();
            if fields.len() != 12 {
                return Err(Error::input(
                    at,
                    format!("expected 12 numbers, found {} fields", fields.len()),
                ));
            }
            let mut v = Vec::with_capacity(12);
            for (k, s) in fields.iter().enumerate() {
                let at = at.with_field(expected.split(',').nth(k).expect("12 columns"));
                match s.parse::<f64>() {
                    Ok(x) if crate::units::plausible(x) => v.push(x),
                    _ => {
                        return Err(Error::input(
                            at,
                            format!("expected a finite number within +-1e9, found `{s}`"),
                        ))
                    }
                }
            }
            last = i + 1;
            let k = postures.len();
            postures.push(Posture {
                label: (k + 1).to_string(),
                readings: v[6..12].to_vec(),
                session: None,
                payload: None,
            });
            let mut p = Pose::new(
                k,
                Target::EndEffector,
                Vector3::new(v[0], v[1], v[2]),
                Vector3::new(v[5], v[4], v[3]),
            );
            p.line = i + 1;
            observations.push(p.into());
        }
        if postures.len() < POSES {
            return Err(Error::input(
                Location::file(&csv.name).at_line(last + 1),
                format!(
                    "expected {POSES} rows after the header, found {} (the file ends here: \
                     truncated?)",
                    postures.len()
                ),
            ));
        }
        Ok(Ur10eData {
            robot,
            data: Dataset::new(postures, observations),
        })
    }

    /// Reads and converts the folder: `ur10e.toml`, `poses.csv`.
    pub fn convert(dir: &Path) -> Result<Converted> {
        convert_folder(&Folder::disk(dir))
    }

    /// [`convert`] of the folder's files.
    pub fn convert_folder(folder: &Folder) -> Result<Converted> {
        let d = load_folder(folder)?;
        Ok(Converted {
            files: vec![
                ("ur10e.toml".into(), write_robot_toml(&d.robot, None)),
                ("poses.csv".into(), write_measurements(&d.robot, &d.data)),
            ],
            summary: format!(
                "UR10e: {} camera-measured poses of a wrist frame (m, rad); the camera's world \
                 frame and the measured frame on the wrist are unknown (links 1 and 7)",
                d.data.observations.len()
            ),
            suggested: super::Suggested {
                robot: "ur10e.toml",
                data: "poses.csv",
                validate: &[],
                estimate: "link1,link7,offsets",
                holdout: Some(0.3),
                weights: Some((0.001, 0.01)),
                orientation: None,
                held_out: &[],
            },
        })
    }
}

/// The UR10 laser-tracker data set of Fraunhofer IPA (Landgraf et al., IEEE CASE 2021; MIT; see
/// `../shared/data/ipa_ur10_tracker/README.txt`): 16,811 positions of a Leica T-Mac probe on a
/// UR10, in four series from three tracker placements, as the lab wrote them (`;`-separated,
/// decimal commas, millimetres, its own column names).
///
/// - The robot is the nominal UR10 of the UR description (`default_kinematics.yaml`, hash
///   `calib_17227329492635474227`, built in: [`ipa_ur10::UR10_KINEMATICS`]), from `base_link`
///   to `tool0`. The probe sits about 93 mm along the flange's z axis: the last link absorbs it, as the
///   first absorbs the tracker's placement (the calibration places both in closed form first).
/// - Each series is a measurement file of its own (`series_A.csv` .. `series_D.csv`), every row
///   in the measurement session named after the series (`session` column): the tracker was moved
///   between series, so a calibration made on one series is checked on another with that
///   session's frame re-estimated on it. Postures are labelled with the series and the data row
///   (`C17`: the 17th row of series C, line 18 of the lab's file). Positions only, in metres:
///   the attitudes (intrinsic X-Y'-Z'' Euler angles, many near a gimbal lock) are not read.
/// - Series B-D give the tracker's standard deviation per axis and row: written as `sigma_x`,
///   `sigma_y`, `sigma_z` (m). (About 0.01 mm: far below the robot's model error; kinecal judges
///   them against the residuals.)
/// - The temperature of every row (deg C) is kept in `temperatures.csv` (`posture,session,
///   temperature`), beside the measurement files: kinecal's measurement reader refuses columns
///   it does not know, and the temperature does not enter a calibration (0.75 K over series A).
/// - Series D's ISO 9283 cubes are `series_D_iso.csv`, the roles of its postures
///   (`posture,test,pose,cycle`, [`crate::apps::iso9283::read_roles`]) read from the commanded
///   ("Goal") positions: `kinecal iso9283 log` makes a log of them.
///
/// The row counts are checked: 11,911 rows in series A (the data set's README says 11,910; the
/// file has 11,911), 1,495 in B, 2,773 in C, 632 in D.
pub mod ipa_ur10 {
    use std::fmt::Write as _;
    use std::path::Path;

    use nalgebra::Vector3;

    use super::{write_measurements, write_robot_toml, Converted, Folder};
    use crate::error::{Error, Location, Result};
    use crate::model::kinematics::Target;
    use crate::model::robot::Robot;
    use crate::observe::point::Position;
    use crate::observe::{Dataset, Observation, Posture};
    use crate::source::Source;

    /// The nominal UR10 kinematics of the UR description (`ur_description/config/ur10/
    /// default_kinematics.yaml` of github.com/ros-industrial/universal_robot, BSD-3-Clause; as in
    /// `../shared/data/urdf/universal_robots/config/ur10/`): the standard DH lengths of the data
    /// set's README (d1 0.1273, a2 -0.612, a3 -0.5723, d4 0.163941, d5 0.1157, d6 0.0922 m).
    pub const UR10_KINEMATICS: &str = "\
kinematics:
  shoulder:
    x: 0
    y: 0
    z: 0.1273
    roll: 0
    pitch: 0
    yaw: 0
  upper_arm:
    x: 0
    y: 0
    z: 0
    roll: 1.570796327
    pitch: 0
    yaw: 0
  forearm:
    x: -0.612
    y: 0
    z: 0
    roll: 0
    pitch: 0
    yaw: 0
  wrist_1:
    x: -0.5723
    y: 0
    z: 0.163941
    roll: 0
    pitch: 0
    yaw: 0
  wrist_2:
    x: 0
    y: -0.1157
    z: -2.373046667922381e-11
    roll: 1.570796327
    pitch: 0
    yaw: 0
  wrist_3:
    x: 0
    y: 0.0922
    z: -1.891053610911353e-11
    roll: 1.570796326589793
    pitch: 3.141592653589793
    yaw: 3.141592653589793
  hash: calib_17227329492635474227
";

    /// A series of the data set.
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub struct Series {
        /// Its name, the session of its rows (`A`).
        pub name: &'static str,
        /// Its measurement file in the folder.
        pub file: &'static str,
        /// What it measured.
        pub about: &'static str,
        /// Its rows after the header.
        pub rows: usize,
        /// Whether it has the tracker's standard deviation columns.
        pub sigmas: bool,
    }

    /// The four series, A to D.
    pub const SERIES: [Series; 4] = [
        Series {
            name: "A",
            file: "Series_A/measurements_grid.csv",
            about: "a grid, overnight runs",
            rows: 11_911,
            sigmas: false,
        },
        Series {
            name: "B",
            file: "Series_B/measurements_joint_configurations.csv",
            about: "varied joint configurations",
            rows: 1_495,
            sigmas: true,
        },
        Series {
            name: "C",
            file: "Series_C/measurements_random_poses.csv",
            about: "random poses",
            rows: 2_773,
            sigmas: true,
        },
        Series {
            name: "D",
            file: "Series_D/measurements_iso_cubes.csv",
            about: "70 ISO 9283 cubes of 9 poses, and 2",
            rows: 632,
            sigmas: true,
        },
    ];

    /// The columns of a measurement file without the standard deviations (series A).
    const COLUMNS: [&str; 20] = [
        "Timestamp",
        "Goal x",
        "Goal y",
        "Goal z",
        "Goal roll",
        "Goal pitch",
        "Goal yaw",
        "shoulder_pan_joint",
        "shoulder_lift_joint",
        "elbow_joint",
        "wrist_1_joint",
        "wrist_2_joint",
        "wrist_3_joint",
        "measurement_temperature",
        "measurement_x",
        "measurement_y",
        "measurement_z",
        "measurement_rx",
        "measurement_ry",
        "measurement_rz",
    ];

    /// The columns of a measurement file with the standard deviations (series B-D).
    const COLUMNS_SIGMA: [&str; 26] = [
        "Timestamp",
        "Goal x",
        "Goal y",
        "Goal z",
        "Goal roll",
        "Goal pitch",
        "Goal yaw",
        "shoulder_pan_joint",
        "shoulder_lift_joint",
        "elbow_joint",
        "wrist_1_joint",
        "wrist_2_joint",
        "wrist_3_joint",
        "measurement_temperature",
        "measurement_x",
        "measurement_std_x",
        "measurement_y",
        "measurement_std_y",
        "measurement_z",
        "measurement_std_z",
        "measurement_rx",
        "measurement_std_rx",
        "measurement_ry",
        "measurement_std_ry",
        "measurement_rz",
        "measurement_std_rz",
    ];

    /// The data set converted to kinecal's model and measurements.
    #[derive(Debug, Clone)]
    pub struct IpaData {
        /// The nominal UR10 (m, rad), without session frames.
        pub robot: Robot,
        /// The series A to D, each in its session (named after it); positions of the probe (m,
        /// in that series' tracker frame) at the end effector.
        pub series: Vec<Dataset>,
        /// The temperature of each series' postures (deg C), in posture order.
        pub temperatures: Vec<Vec<f64>>,
        /// The commanded ("Goal") position of the probe of each series' postures (m, the ROS
        /// `base` frame), in posture order.
        pub goals: Vec<Vec<[f64; 3]>>,
    }

    /// The nominal UR10 ([`UR10_KINEMATICS`] imported): the robot the adapter writes beside
    /// the series.
    pub fn nominal_robot() -> Robot {
        let mut robot = crate::import::ur::import_ur(UR10_KINEMATICS, "<ur10 default_kinematics>")
            .expect("the built-in UR10 kinematics import")
            .robot;
        robot.name = "UR10 (calib_17227329492635474227)".into();
        robot
    }

    /// A number as the lab wrote it: a decimal comma (a dot is refused: it would be a thousands
    /// separator in that format), finite and within +-1e9.
    fn number(s: &str, at: &Location) -> Result<f64> {
        let s = s.trim();
        let v = if s.contains('.') {
            None
        } else {
            s.replace(',', ".").parse::<f64>().ok()
        };
        match v {
            Some(v) if crate::units::plausible(v) => Ok(v),
            _ => Err(Error::input(
                at.clone(),
                format!(
                    "expected a finite number within +-1e9 with a decimal comma (`-0,5`), found \
                     `{s}`"
                ),
            )),
        }
    }

    /// Reads one series' file: the header, then exactly `rows` rows (blank lines skipped).
    fn read_series(
        source: &Source,
        series: &Series,
        rows: usize,
    ) -> Result<(Dataset, Vec<f64>, Vec<[f64; 3]>)> {
        let file = &source.name;
        let columns: &[&str] = if series.sigmas {
            &COLUMNS_SIGMA
        } else {
            &COLUMNS
        };
        let col = |name: &str| {
            columns
                .iter()
                .position(|c| *c == name)
                .expect("a column of the table")
        };
        let mut lines = source.text.lines().enumerate();
        let header = lines
            .next()
            .map(|(_, h)| h.trim_start_matches('\u{feff}'))
            .unwrap_or_default();
        let names: Vec<&str> = header.split(';').map(str::trim).collect();
        let at_header = Location::file(file).at_line(1);
        if names.len() != columns.len() {
            return Err(Error::input(
                at_header,
                format!(
                    "expected the header of {} `;`-separated columns (`{}` .. `{}`{}), found {} \
                     fields",
                    columns.len(),
                    columns[0],
                    columns[columns.len() - 1],
                    if series.sigmas {
                        ", with the tracker's standard deviations"
                    } else {
                        ""
                    },
                    names.len()
                ),
            ));
        }
        if let Some(k) = (0..columns.len()).find(|&k| names[k] != columns[k]) {
            return Err(Error::input(
                at_header.with_field(format!("column {}", k + 1)),
                format!("expected the column `{}`, found `{}`", columns[k], names[k]),
            ));
        }
        let joints: Vec<usize> = crate::import::ur::JOINTS.iter().map(|j| col(j.1)).collect();
        let goal = [col("Goal x"), col("Goal y"), col("Goal z")];
        let (temperature, xyz) = (
            col("measurement_temperature"),
            [
                col("measurement_x"),
                col("measurement_y"),
                col("measurement_z"),
            ],
        );
        let std = series.sigmas.then(|| {
            [
                col("measurement_std_x"),
                col("measurement_std_y"),
                col("measurement_std_z"),
            ]
        });
        let session: std::sync::Arc<str> = series.name.into();
        let mut postures = Vec::with_capacity(rows);
        let mut observations: Vec<Observation> = Vec::with_capacity(rows);
        let mut temperatures = Vec::with_capacity(rows);
        let mut goals = Vec::with_capacity(rows);
        // Each row's line and per-axis standard deviations (mm), for the spread check below.
        let mut stated: Vec<(usize, [f64; 3])> = Vec::new();
        let mut last = 1;
        for (i, line) in lines {
            if line.trim().is_empty() {
                continue;
            }
            let at = Location::file(file).at_line(i + 1);
            if postures.len() == rows {
                return Err(Error::input(
                    at,
                    format!("expected {rows} rows after the header, found more"),
                ));
            }
            let fields: Vec<&str> = line.split(';').collect();
            if fields.len() != columns.len() {
                return Err(Error::input(
                    at,
                    format!(
                        "expected {} `;`-separated fields, found {}",
                        columns.len(),
                        fields.len()
                    ),
                ));
            }
            let value = |k: usize| number(fields[k], &at.with_field(columns[k]));
            let readings = joints
                .iter()
                .map(|&k| value(k))
                .collect::<Result<Vec<_>>>()?;
            let t = value(temperature)?;
            goals.push([value(goal[0])?, value(goal[1])?, value(goal[2])?]);
            let p = Vector3::new(value(xyz[0])?, value(xyz[1])?, value(xyz[2])?);
            let sigma = match std {
                Some(cols) => {
                    let mut s = Vector3::zeros();
                    for (a, &k) in cols.iter().enumerate() {
                        s[a] = value(k)?;
                        let problem = if s[a] <= 0.0 {
                            Some("expected a positive standard deviation".to_string())
                        } else {
                            // As kinecal reads it back, in m.
                            crate::units::sigma_problem(s[a] * 1e-3).map(|p| format!("in m, {p}"))
                        };
                        if let Some(p) = problem {
                            return Err(Error::input(
                                at.with_field(columns[k]),
                                format!("{p}, found `{}`", fields[k].trim()),
                            ));
                        }
                    }
                    stated.push((i + 1, [s.x, s.y, s.z]));
                    Some(s * 1e-3)
                }
                None => None,
            };
            last = i + 1;
            let k = postures.len();
            postures.push(Posture {
                label: format!("{}{}", series.name, k + 1),
                readings,
                session: Some(session.clone()),
                payload: None,
            });
            let mut m = Position::new(k, Target::EndEffector, p * 1e-3);
            m.sigma_position = sigma;
            m.line = i + 1;
            observations.push(m.into());
            temperatures.push(t);
        }
        if postures.len() < rows {
            return Err(Error::input(
                Location::file(file).at_line(last + 1),
                format!(
                    "expected {rows} rows after the header, found {} (the file ends here: \
                     truncated?)",
                    postures.len()
                ),
            ));
        }
        if let Some(cols) = std {
            spread_of_sigmas(file, &stated, cols.map(|k| columns[k]))?;
        }
        Ok((Dataset::new(postures, observations), temperatures, goals))
    }

    /// A series' standard deviations as kinecal reads them back from the file it is written
    /// to: none more than [`SIGMA_SPREAD`](crate::files::table::SIGMA_SPREAD) times below
    /// the median of the series' (the measurement reader refuses such a row as a slip, see
    /// `files::table::sigma_spread_problem`), refused here with the source's line and column.
    /// `stated`: each row's line and per-axis values (mm); `columns`: the axes' column names.
    fn spread_of_sigmas(
        file: &str,
        stated: &[(usize, [f64; 3])],
        columns: [&str; 3],
    ) -> Result<()> {
        use crate::files::table::SIGMA_SPREAD;
        let mut all: Vec<f64> = stated.iter().flat_map(|(_, s)| *s).collect();
        if all.len() < 2 {
            return Ok(());
        }
        all.sort_by(f64::total_cmp);
        // The upper median, as the reader takes it.
        let median = all[all.len() / 2];
        for (line, s) in stated {
            for (a, &v) in s.iter().enumerate() {
                if v * SIGMA_SPREAD < median {
                    return Err(Error::input(
                        Location::file(file).at_line(*line).with_field(columns[a]),
                        format!(
                            "a standard deviation of {v} mm is {:.1e} times the median of the \
                             series' ({median} mm): expected at most {SIGMA_SPREAD:.0e} times \
                             below it (converted, kinecal would refuse the row as a slip: it \
                             would outweigh the rest 10^12 to 1); correct the value",
                            v / median
                        ),
                    ));
                }
            }
        }
        Ok(())
    }

    /// Loads the data set from its folder (`../shared/data/ipa_ur10_tracker`).
    pub fn load(dir: &Path) -> Result<IpaData> {
        load_folder(&Folder::disk(dir))
    }

    /// Loads the data set from its files: each series' file must have its header (the columns
    /// of its README, the standard deviations in B-D) and the rows of [`SERIES`]; every field
    /// read (the joints, the temperature, the position and its standard deviations) a finite
    /// number within +-1e9 with a decimal comma, the standard deviations positive.
    pub(crate) fn load_folder(folder: &Folder) -> Result<IpaData> {
        load_trimmed(folder, SERIES.map(|s| s.rows))
    }

    /// [`load_folder`] of a copy of the data set cut to `rows` rows per series, A to D (a quick
    /// look, tests): the row counts checked are these.
    pub(crate) fn load_trimmed(folder: &Folder, rows: [usize; 4]) -> Result<IpaData> {
        let mut series = Vec::with_capacity(4);
        let mut temperatures = Vec::with_capacity(4);
        let mut goals = Vec::with_capacity(4);
        for (s, n) in SERIES.iter().zip(rows) {
            let (d, t, g) = read_series(&folder.read(s.file)?, s, n)?;
            series.push(d);
            temperatures.push(t);
            goals.push(g);
        }
        Ok(IpaData {
            robot: nominal_robot(),
            series,
            temperatures,
            goals,
        })
    }

    /// The name of a series' measurement file in the converted folder (`series_A.csv`).
    pub fn file_of(series: &str) -> String {
        format!("series_{series}.csv")
    }

    /// The file of the ISO 9283 roles of series D's postures ([`crate::apps::iso9283::read_roles`]).
    pub const ISO_ROLES: &str = "series_D_iso.csv";

    /// Series D's cubes as ISO 9283 roles (`posture,test,pose,cycle`): blocks of nine postures,
    /// the centre and the eight corners of a cube, read from the commanded ("Goal") positions; a
    /// cube measured again is a further cycle of its test (the first, 400 mm cube was measured
    /// three times). The 2 postures after the 70th block have no role. `None` for a copy cut
    /// to fewer than nine rows of D (no whole cube). An error names series D's file when a
    /// block is not a cube's centre and corners.
    fn cube_roles_file(d: &IpaData) -> Result<Option<String>> {
        let (k, s) = SERIES
            .iter()
            .enumerate()
            .find(|(_, s)| s.name == "D")
            .expect("series D");
        if d.goals[k].len() < 9 {
            return Ok(None);
        }
        // The goals of one cube's cycles agree to 1e-6 m; distinct cubes differ by 1 mm or more.
        let roles = crate::apps::iso9283::cube_roles(&d.goals[k], 1e-4)
            .map_err(|e| Error::input(Location::file(s.file), format!("{e} (the Goal columns)")))?;
        let labelled: Vec<(String, crate::apps::iso9283::Role)> = d.series[k]
            .postures
            .iter()
            .map(|p| p.label.clone())
            .zip(roles)
            .collect();
        Ok(Some(crate::apps::iso9283::write_roles(&labelled)))
    }

    /// The temperatures of every series as a CSV: `posture,session,temperature` (deg C).
    fn temperature_file(d: &IpaData) -> String {
        let mut out = String::from("posture,session,temperature\n");
        for ((s, data), t) in SERIES.iter().zip(&d.series).zip(&d.temperatures) {
            for (p, t) in data.postures.iter().zip(t) {
                let _ = writeln!(out, "{},{},{t}", p.label, s.name);
            }
        }
        out
    }

    /// Reads and converts the folder: `ur10.toml`, `series_A.csv` .. `series_D.csv`,
    /// `temperatures.csv`.
    pub fn convert(dir: &Path) -> Result<Converted> {
        convert_folder(&Folder::disk(dir))
    }

    /// [`convert`] of the folder's files.
    pub fn convert_folder(folder: &Folder) -> Result<Converted> {
        convert_trimmed(folder, SERIES.map(|s| s.rows))
    }

    /// [`convert`] of a copy cut to `rows` rows per series (`load_trimmed`).
    pub fn convert_trimmed(folder: &Folder, rows: [usize; 4]) -> Result<Converted> {
        let d = load_trimmed(folder, rows)?;
        let mut files = vec![("ur10.toml".to_string(), write_robot_toml(&d.robot, None))];
        for (s, data) in SERIES.iter().zip(&d.series) {
            files.push((file_of(s.name), write_measurements(&d.robot, data)));
        }
        files.push(("temperatures.csv".into(), temperature_file(&d)));
        if let Some(roles) = cube_roles_file(&d)? {
            files.push((ISO_ROLES.into(), roles));
        }
        let counts: Vec<String> = SERIES
            .iter()
            .zip(&d.series)
            .map(|(s, data)| format!("{} {} ({})", s.name, data.postures.len(), s.about))
            .collect();
        Ok(Converted {
            files,
            summary: format!(
                "UR10 + Leica laser tracker: positions of the T-Mac probe in four series, each a \
                 measurement session of its own (the tracker moved between them): {}; the \
                 tracker's per-axis standard deviations in B-D (sigma_x, sigma_y, sigma_z), the \
                 temperatures (deg C) in temperatures.csv (m, rad; the UR description's nominal \
                 UR10)",
                counts.join(", ")
            ),
            suggested: super::Suggested {
                robot: "ur10.toml",
                data: "series_A.csv",
                validate: &["series_C.csv", "series_D.csv"],
                estimate: "identifiable",
                holdout: None,
                weights: None,
                orientation: None,
                held_out: &[("series_C.csv", 0.52e-3), ("series_D.csv", 0.43e-3)],
            },
        })
    }
}
