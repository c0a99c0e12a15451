//! Measurements: transducer readings per posture and the externally measured poses.
//!
//! Values are internal (m, rad). A [`Dataset`] keeps its measurements grouped by posture so that
//! forward kinematics runs once per posture however many sites were measured in it.

use nalgebra::Vector3;

use crate::kinematics::Target;

/// One posture: a label and one transducer reading per joint.
#[derive(Debug, Clone, PartialEq)]
pub struct Posture {
    /// The posture's label in files (`posture` column).
    pub label: String,
    /// One reading per joint, in transducer units.
    pub readings: Vec<f64>,
}

/// One externally measured pose (or position) of one target in one posture.
#[derive(Debug, Clone, PartialEq)]
pub struct Measurement {
    /// Index into [`Dataset::postures`].
    pub posture: usize,
    /// The measured frame.
    pub target: Target,
    /// Measured origin in the global frame (m).
    pub position: Vector3<f64>,
    /// Measured ZYX Euler angles `(alpha, beta, gamma)` (rad); `None` for a position-only row.
    pub orientation: Option<Vector3<f64>>,
    /// Line of the file the measurement came from (0 when synthesized).
    pub line: usize,
}

impl Measurement {
    /// Number of residual rows: 6 for a full pose, 3 for a position.
    pub fn rows(&self) -> usize {
        if self.orientation.is_some() {
            6
        } else {
            3
        }
    }
}

/// A set of postures and their measurements.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Dataset {
    /// The postures.
    pub postures: Vec<Posture>,
    /// The measurements, sorted by posture.
    pub measurements: Vec<Measurement>,
}

impl Dataset {
    /// Builds a dataset, sorting measurements by posture (stable: file order within a posture).
    pub fn new(postures: Vec<Posture>, mut measurements: Vec<Measurement>) -> Self {
        measurements.sort_by_key(|m| m.posture);
        Dataset {
            postures,
            measurements,
        }
    }

    /// Total residual rows (6 per full pose, 3 per position).
    pub fn rows(&self) -> usize {
        self.measurements.iter().map(Measurement::rows).sum()
    }

    /// The measurements grouped by posture: `(posture, its measurements)`.
    pub fn by_posture(&self) -> impl Iterator<Item = (&Posture, &[Measurement])> {
        self.measurements
            .chunk_by(|a, b| a.posture == b.posture)
            .map(|group| (&self.postures[group[0].posture], group))
    }

    /// Measurements whose Euler angle beta is within `tolerance` (rad) of +-90 deg, where ZYX
    /// Euler angles are degenerate (gimbal lock).
    pub fn near_gimbal_lock(&self, tolerance: f64) -> Vec<&Measurement> {
        self.measurements
            .iter()
            .filter(|m| {
                m.orientation
                    .is_some_and(|e| (e.y.abs() - std::f64::consts::FRAC_PI_2).abs() < tolerance)
            })
            .collect()
    }
}

/// Splits `data` by posture: a fraction `holdout` of the postures (at least one, drawn with
/// `seed`) and their measurements go to the second dataset. Returns (identification, held out).
pub fn split_postures(data: &Dataset, holdout: f64, seed: u64) -> (Dataset, Dataset) {
    use rand::{seq::SliceRandom, SeedableRng};
    let n = data.postures.len();
    let k = ((holdout * n as f64).round() as usize).clamp(1, n);
    let mut order: Vec<usize> = (0..n).collect();
    order.shuffle(&mut rand_chacha::ChaCha8Rng::seed_from_u64(seed));
    let held: Vec<bool> = {
        let mut h = vec![false; n];
        for &i in &order[..k] {
            h[i] = true;
        }
        h
    };
    let part = |want: bool| {
        let mut map = vec![usize::MAX; n];
        let mut postures = Vec::new();
        for (i, p) in data.postures.iter().enumerate() {
            if held[i] == want {
                map[i] = postures.len();
                postures.push(p.clone());
            }
        }
        let measurements = data
            .measurements
            .iter()
            .filter(|m| held[m.posture] == want)
            .map(|m| Measurement {
                posture: map[m.posture],
                ..m.clone()
            })
            .collect();
        Dataset::new(postures, measurements)
    };
    (part(false), part(true))
}
