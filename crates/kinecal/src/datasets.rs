//! Adapters for public calibration data sets whose files are laid out in their own way.
//!
//! [`qkm_hl6`] reads the QKM HL6 + FARO laser tracker data (see
//! `../shared/data/qkm_hl6_faro/README.txt`): 46 identification positions of one of three
//! reflectors (SMRs) per posture, and 9 held-out test points.

/// The QKM HL6 data set.
pub mod qkm_hl6 {
    use std::fmt::Write as _;
    use std::path::Path;

    use nalgebra::{Matrix3, Vector3};

    use crate::error::{Error, Location, Result};
    use crate::import::poe::parse_poe_toml;
    use crate::kinematics::Target;
    use crate::observe::point::Position;
    use crate::observe::{Dataset, Posture};
    use crate::robot::Robot;

    /// The data set converted to kinecal's model and measurements.
    #[derive(Debug, Clone)]
    pub struct QkmData {
        /// The nominal robot as a product-of-exponentials file (mm, deg; reference frame).
        pub poe_toml: String,
        /// The nominal robot: joints from the POE model, the three reflectors as sites on joint 6
        /// at their measured zero-configuration positions.
        pub robot: Robot,
        /// The 46 identification positions.
        pub identification: Dataset,
        /// The 9 held-out test points.
        pub validation: Dataset,
    }

    fn read_rows(path: &Path, cols: usize) -> Result<Vec<Vec<f64>>> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| Error::Io {
            path: file.clone(),
            source: e,
        })?;
        let mut rows = Vec::new();
        for (i, line) in text.lines().enumerate() {
            if line.trim().is_empty() {
                continue;
            }
            let vals: Vec<f64> = line
                .split(|c: char| c == ',' || c.is_whitespace())
                .filter(|s| !s.is_empty())
                .map(|s| s.parse::<f64>())
                .collect::<std::result::Result<_, _>>()
                .map_err(|e| {
                    Error::input(
                        Location::file(&file).at_line(i + 1),
                        format!("not a number: {e}"),
                    )
                })?;
            if vals.len() != cols {
                return Err(Error::input(
                    Location::file(&file).at_line(i + 1),
                    format!("expected {cols} numbers, found {}", vals.len()),
                ));
            }
            rows.push(vals);
        }
        Ok(rows)
    }

    /// The user (reference) frame built from three tracker points (README: "method 1"): origin
    /// P1, x along P1 - P3, y along P2 - P1 made orthogonal to x, z = x cross y. Returns
    /// `(R, origin)`, mapping reference coordinates to tracker coordinates. (The original script
    /// does not re-normalise y; a rigid frame needs it, and the first link absorbs the base
    /// placement either way.)
    fn reference_frame(p: &[Vec<f64>]) -> (Matrix3<f64>, Vector3<f64>) {
        let v = |r: &Vec<f64>| Vector3::new(r[0], r[1], r[2]);
        let (p1, p2, p3) = (v(&p[0]), v(&p[1]), v(&p[2]));
        let x = (p1 - p3).normalize();
        let y0 = (p2 - p1).normalize();
        let y = (y0 - x * y0.dot(&x)).normalize();
        (Matrix3::from_columns(&[x, y, x.cross(&y)]), p1)
    }

    fn dataset(
        angles: &[Vec<f64>],
        points: &[Vec<f64>],
        to_ref: &dyn Fn(Vector3<f64>) -> Vector3<f64>,
        prefix: &str,
    ) -> Dataset {
        let mut postures = Vec::new();
        let mut measurements = Vec::new();
        for (i, (a, p)) in angles.iter().zip(points).enumerate() {
            postures.push(Posture {
                label: format!("{prefix}{}", i + 1),
                readings: a[..6].to_vec(),
            });
            let mut m = Position::new(
                i,
                Target::Site(a[6] as usize - 1),
                to_ref(Vector3::new(p[0], p[1], p[2])) * 1e-3,
            );
            m.line = i + 1;
            measurements.push(m.into());
        }
        Dataset::new(postures, measurements)
    }

    /// Loads the data set from its folder (`../shared/data/qkm_hl6_faro`).
    pub fn load(dir: &Path) -> Result<QkmData> {
        let pos = dir.join("position_dataset");
        let refp = read_rows(&pos.join("re_ref.txt"), 3)?;
        let smr = read_rows(&pos.join("re_smr.txt"), 3)?;
        let angles = read_rows(&pos.join("c_angles.txt"), 7)?;
        let points = read_rows(&pos.join("c_poses.txt"), 3)?;
        let test_angles = read_rows(&pos.join("test_points.txt"), 7)?;
        let test_points = read_rows(&pos.join("re_test.txt"), 3)?;
        let (r, o) = reference_frame(&refp);
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
            let _ = write!(
                poe,
                "\n[[joints]]\nkind = \"revolute\"\naxis = [{}, {}, {}]\npoint = [{}, {}, {}]\noffset = {off}\n",
                w[0], w[1], w[2], q[0], q[1], q[2]
            );
        }
        poe.push_str("\n# Flange: 84 mm beyond the wrist centre along x.\n[tool]\nposition = [-156, 410, 841]\n");
        for (k, s) in smr.iter().enumerate() {
            // Measured at controller angles (0, 0, 90, 0, 0, 0) = model zero.
            let p = to_ref(Vector3::new(s[0], s[1], s[2]));
            let _ = write!(
                poe,
                "\n[[sites]]\nname = \"smr{}\"\njoint = 6\nposition = [{}, {}, {}]\n",
                k + 1,
                p.x,
                p.y,
                p.z
            );
        }
        let robot = parse_poe_toml(&poe, "<qkm_hl6 nominal>")?;
        Ok(QkmData {
            robot,
            identification: dataset(&angles, &points, &to_ref, "c"),
            validation: dataset(&test_angles, &test_points, &to_ref, "t"),
            poe_toml: poe,
        })
    }
}
