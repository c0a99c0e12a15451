//! The ISO 9283 figures of a log ([`evaluate`]): test by test, pose by pose and pair by pair,
//! and across the tests of a series ([`Summary`]). The symbols are the module's
//! ([`crate::apps::iso9283`]).

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use super::{pose_name, Log, LogRow, STANDARD_CYCLES};
use crate::error::{Error, Location, Result};
use crate::units::{AngleUnit, LengthUnit};

/// The figures of one pose (see the module's documentation for the symbols), in the log's
/// units.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[non_exhaustive]
pub struct PoseFigures {
    /// The test it belongs to, when the log holds several.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub test: Option<String>,
    /// The pose: 1 to 5 for `P1..P5`, 6 to 13 for the corners `C1..C8`
    /// ([`super::pose_name`]).
    pub pose: usize,
    /// `n`: the cycles (attained poses) it was measured in.
    pub cycles: usize,
    /// The commanded position `x_c, y_c, z_c`.
    pub commanded: [f64; 3],
    /// The commanded attitude `a_c, b_c, c_c`.
    pub commanded_attitude: Option<[f64; 3]>,
    /// The barycentre `xbar, ybar, zbar`.
    pub barycentre: [f64; 3],
    /// Pose accuracy `AP`.
    pub ap: f64,
    /// `APx, APy, APz`.
    pub ap_xyz: [f64; 3],
    /// `lbar`: the mean distance of the attained positions from the barycentre (`None` with
    /// one cycle).
    pub l_mean: Option<f64>,
    /// `S_l`: their standard deviation (`n - 1`; `None` with one cycle).
    pub s_l: Option<f64>,
    /// Pose repeatability `RP = lbar + 3 S_l` (`None` with one cycle: repeatability needs two).
    pub rp: Option<f64>,
    /// Attitude accuracy `APa, APb, APc`.
    pub ap_abc: Option<[f64; 3]>,
    /// Attitude repeatability `RPa, RPb, RPc` (`3 S`, read `+-`; `None` with one cycle).
    pub rp_abc: Option<[f64; 3]>,
    /// The multi-directional figures, when the pose was approached from several directions.
    pub multidirectional: Option<Multidirectional>,
    /// What a calibration predicts for this pose once the program is compensated
    /// ([`super::predict_compensated`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub compensated: Option<Compensated>,
    /// The attained positions, in the log's order.
    pub attained: Vec<[f64; 3]>,
}

/// The pose accuracy a calibration predicts for a pose once the program is compensated (the
/// commanded pose reached through the calibrated model's inverse kinematics), in the log's length
/// unit. The remaining systematic error is what the calibration does not know: the parameters'
/// uncertainty and the model error at that posture ([`crate::predict`]); the repeatability is
/// the robot's and does not change.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[non_exhaustive]
pub struct Compensated {
    /// The predicted RMS of `AP`: `sqrt(tr S)`, `S` the predicted covariance of the position
    /// error.
    pub ap_rms: f64,
    /// The predicted 95 % bound of `AP`.
    pub ap_95: f64,
    /// Where the readings came from: `"log"` (the mean of the logged readings) or `"inverse
    /// kinematics"` (the calibrated model's, at the commanded pose).
    pub readings_from: String,
}

/// Multi-directional pose accuracy variation of one pose.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[non_exhaustive]
pub struct Multidirectional {
    /// The approach directions, as the log names them.
    pub directions: Vec<String>,
    /// The barycentre of the positions reached from each direction.
    pub barycentres: Vec<[f64; 3]>,
    /// `vAP`: the largest distance between two of the barycentres.
    pub vap: f64,
    /// `vAPa, vAPb, vAPc`: the largest difference between two directions' mean angles.
    pub vap_abc: Option<[f64; 3]>,
}

/// Distance accuracy and repeatability of a pair of poses.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[non_exhaustive]
pub struct DistanceFigures {
    /// The test the poses belong to, when the log holds several.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub test: Option<String>,
    /// The first pose.
    pub from: usize,
    /// The second pose.
    pub to: usize,
    /// `n`: the cycles in which both were attained.
    pub cycles: usize,
    /// `D_c`: the commanded distance.
    pub commanded: f64,
    /// `Dbar`: the mean attained distance.
    pub mean: f64,
    /// Distance accuracy `AD = Dbar - D_c`.
    pub ad: f64,
    /// `ADx, ADy, ADz`.
    pub ad_xyz: [f64; 3],
    /// `S_D`: the standard deviation of the attained distances (`n - 1`; `None` with one cycle).
    pub s_d: Option<f64>,
    /// Distance repeatability `RD = 3 S_D` (read `+-`; `None` with one cycle).
    pub rd: Option<f64>,
}

/// One figure over the poses (or pairs) of a series of tests.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[non_exhaustive]
pub struct Spread {
    /// How many values.
    pub count: usize,
    /// Their mean.
    pub mean: f64,
    /// Their 95th percentile (nearest rank).
    pub p95: f64,
    /// The largest.
    pub max: f64,
}

impl Spread {
    /// The spread of `v` (`None` when empty).
    pub fn of(v: &[f64]) -> Option<Spread> {
        if v.is_empty() {
            return None;
        }
        let (_, mean, p95, max) = crate::observe::stats(v.to_vec());
        Some(Spread {
            count: v.len(),
            mean,
            p95,
            max,
        })
    }
}

/// The figures of one pose over the tests of a series (or of every pose: `pose` 0).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[non_exhaustive]
pub struct PoseSummary {
    /// The pose (0: every pose together).
    pub pose: usize,
    /// `AP` over the tests.
    pub ap: Spread,
    /// `RP` over the tests that measured the pose in at least 2 cycles.
    pub rp: Option<Spread>,
    /// The predicted `AP` after compensation, its 95 % bound over the tests.
    pub compensated_95: Option<Spread>,
    /// The predicted RMS `AP` after compensation over the tests.
    pub compensated_rms: Option<Spread>,
    /// The share of tests whose measured `AP` is within the predicted 95 % bound after
    /// compensation (meaningful when the log is of the compensated robot).
    pub within_compensated_95: Option<f64>,
}

/// The figures across the tests of a log that holds several (a series of cubes).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[non_exhaustive]
pub struct Summary {
    /// The tests.
    pub tests: usize,
    /// Per pose over the tests, then every pose together (`pose` 0).
    pub poses: Vec<PoseSummary>,
    /// `|AD|` over every pair of poses of every test.
    pub ad: Option<Spread>,
    /// `RD` over the pairs attained together in at least 2 cycles.
    pub rd: Option<Spread>,
}

/// The version of the ISO 9283 document ([`Evaluation`] as JSON); its schema is
/// [`evaluation_schema`].
pub const SCHEMA_VERSION: u32 = 1;

/// The JSON Schema of [`Evaluation`] (what `kinecal iso9283 evaluate --json` writes), as shipped
/// in `schemas/iso9283.schema.json`.
pub fn evaluation_schema() -> String {
    let schema = schemars::schema_for!(Evaluation);
    serde_json::to_string_pretty(&schema).expect("a schema is JSON") + "\n"
}

/// The ISO 9283 figures of a log.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[non_exhaustive]
pub struct Evaluation {
    /// [`crate::apps::iso9283::SCHEMA_VERSION`] of the document.
    #[serde(default)]
    pub schema_version: u32,
    /// The log's file.
    pub file: String,
    /// The log's length unit, when known (the figures' lengths are in it).
    pub length_unit: Option<LengthUnit>,
    /// The log's angle unit, when known (the figures' angles are in it).
    pub angle_unit: Option<AngleUnit>,
    /// Whether the log was simulated.
    pub simulated: bool,
    /// The cycles the standard asks for.
    pub standard_cycles: usize,
    /// Per pose, test by test (in the log's order of tests), in pose order.
    pub poses: Vec<PoseFigures>,
    /// Per pair of poses of a test.
    pub distances: Vec<DistanceFigures>,
    /// Across the tests, when the log holds several.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub summary: Option<Summary>,
    /// What makes the figures differ from a standard test (fewer cycles than the standard's,
    /// pooled directions, a pair of poses without common cycles).
    pub warnings: Vec<String>,
}

impl Evaluation {
    /// The tests, in the log's order (one `None` when the log names none).
    pub fn tests(&self) -> Vec<Option<&str>> {
        let mut out: Vec<Option<&str>> = Vec::new();
        for p in &self.poses {
            if !out.contains(&p.test.as_deref()) {
                out.push(p.test.as_deref());
            }
        }
        out
    }

    /// Computes [`Evaluation::summary`] again (after [`super::predict_compensated`] added the
    /// predictions): `None` for a log of one test.
    pub(crate) fn summarize(&mut self) {
        let tests = self.tests().len();
        if tests < 2 {
            self.summary = None;
            return;
        }
        let mut indices: Vec<usize> = self.poses.iter().map(|p| p.pose).collect();
        indices.sort_unstable();
        indices.dedup();
        indices.push(0);
        let poses = indices
            .into_iter()
            .filter_map(|pose| {
                let of: Vec<&PoseFigures> = self
                    .poses
                    .iter()
                    .filter(|p| pose == 0 || p.pose == pose)
                    .collect();
                let ap: Vec<f64> = of.iter().map(|p| p.ap).collect();
                let rp: Vec<f64> = of.iter().filter_map(|p| p.rp).collect();
                let c95: Vec<f64> = of
                    .iter()
                    .filter_map(|p| p.compensated.as_ref().map(|c| c.ap_95))
                    .collect();
                let crms: Vec<f64> = of
                    .iter()
                    .filter_map(|p| p.compensated.as_ref().map(|c| c.ap_rms))
                    .collect();
                let within = of
                    .iter()
                    .filter(|p| p.compensated.as_ref().is_some_and(|c| p.ap <= c.ap_95))
                    .count();
                Some(PoseSummary {
                    pose,
                    ap: Spread::of(&ap)?,
                    rp: Spread::of(&rp),
                    compensated_95: Spread::of(&c95),
                    compensated_rms: Spread::of(&crms),
                    within_compensated_95: (!c95.is_empty())
                        .then(|| within as f64 / c95.len() as f64),
                })
            })
            .collect();
        let ad: Vec<f64> = self.distances.iter().map(|d| d.ad.abs()).collect();
        let rd: Vec<f64> = self.distances.iter().filter_map(|d| d.rd).collect();
        self.summary = Some(Summary {
            tests,
            poses,
            ad: Spread::of(&ad),
            rd: Spread::of(&rd),
        });
    }
}

/// The mean of `v`.
fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

/// The standard deviation of `v` with `n - 1` in the denominator (`None` for fewer than 2
/// values).
fn std_dev(v: &[f64]) -> Option<f64> {
    if v.len() < 2 {
        return None;
    }
    let m = mean(v);
    Some((v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (v.len() - 1) as f64).sqrt())
}

/// "`test`: " for a named test, "" otherwise.
fn in_test(test: Option<&str>) -> String {
    test.map(|t| format!("test `{t}`: ")).unwrap_or_default()
}

/// The ISO 9283 figures of `log` (see the module's documentation), test by test. A pose
/// measured in one cycle has its accuracy (`AP`, and `AD` with the poses of the same cycle) but
/// no repeatability, and a warning says so. An error when rows of one pose disagree on its
/// commanded pose.
pub fn evaluate(log: &Log) -> Result<Evaluation> {
    let g = Grouped::of(log);
    let mut warnings = Vec::new();
    // The poses measured in fewer cycles than the standard's, and their cycles.
    let mut short: Vec<(String, usize)> = Vec::new();
    let mut poses = Vec::new();
    for (&(t, pose), rows) in &g.by_pose {
        let test = g.tests[t];
        g.check_commanded(test, pose, rows)?;
        let n = rows.len();
        if n < STANDARD_CYCLES {
            short.push((pose_name(pose), n));
        }
        let figures = g.pose_figures(test, pose, rows);
        if let Some(m) = &figures.multidirectional {
            warnings.push(format!(
                "{}{}: AP and RP pool {} approach directions (the standard's AP and RP are \
                 unidirectional: log the multi-directional test apart)",
                in_test(test),
                pose_name(pose),
                m.directions.len()
            ));
        }
        poses.push(figures);
    }
    warnings.extend(cycles_warnings(&g.tests, &short, poses.len()));
    let distances = g.distances(&mut warnings);
    if log.simulated {
        warnings.push("the log is simulated (kinecal iso9283 simulate), not measured".into());
    }
    let mut e = Evaluation {
        schema_version: SCHEMA_VERSION,
        file: log.file.clone(),
        length_unit: log.length_unit,
        angle_unit: log.angle_unit,
        simulated: log.simulated,
        standard_cycles: STANDARD_CYCLES,
        poses,
        distances,
        summary: None,
        warnings,
    };
    e.summarize();
    Ok(e)
}

/// A log's rows grouped by test (in the order they first appear) and pose (in index order
/// within each), with the wrapping of its angle unit.
struct Grouped<'a> {
    log: &'a Log,
    tests: Vec<Option<&'a str>>,
    by_pose: BTreeMap<(usize, usize), Vec<&'a LogRow>>,
    /// A full turn in the log's angle unit.
    turn: f64,
}

impl<'a> Grouped<'a> {
    fn of(log: &'a Log) -> Grouped<'a> {
        let turn = match log.angle_unit {
            Some(AngleUnit::Deg) => 360.0,
            _ => std::f64::consts::TAU,
        };
        let mut tests: Vec<Option<&str>> = Vec::new();
        let mut by_pose: BTreeMap<(usize, usize), Vec<&LogRow>> = BTreeMap::new();
        for r in &log.rows {
            let t = match tests.iter().position(|t| *t == r.test.as_deref()) {
                Some(t) => t,
                None => {
                    tests.push(r.test.as_deref());
                    tests.len() - 1
                }
            };
            by_pose.entry((t, r.pose)).or_default().push(r);
        }
        Grouped {
            log,
            tests,
            by_pose,
            turn,
        }
    }

    /// An angle difference wrapped to half a turn.
    fn wrap(&self, d: f64) -> f64 {
        d - self.turn * (d / self.turn).round()
    }

    /// Each attained angle `k`'s difference from the commanded one, wrapped (none when a row
    /// has no attitude).
    fn deviations(&self, rows: &[&LogRow], k: usize) -> Option<Vec<f64>> {
        rows.iter()
            .map(|r| Some(self.wrap(r.attained_attitude?[k] - r.commanded_attitude?[k])))
            .collect()
    }

    /// One commanded pose per pose index: an error naming the row that differs.
    fn check_commanded(&self, test: Option<&str>, pose: usize, rows: &[&LogRow]) -> Result<()> {
        let name = pose_name(pose);
        let first = rows[0];
        let at = |r: &LogRow, field: &str| {
            Location::file(&self.log.file)
                .at_line(r.line)
                .with_field(field)
        };
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * a.abs().max(b.abs()).max(1.0);
        let differs = |r: &LogRow, field: &str, here: f64, there: f64| {
            Error::input(
                at(r, field),
                format!(
                    "{}{name} is commanded at {field} = {here} here but {there} on line {}: one \
                     pose, one commanded pose",
                    in_test(test),
                    first.line
                ),
            )
        };
        for r in &rows[1..] {
            let xyz = ["xc", "yc", "zc"];
            if let Some(k) = (0..3).find(|&k| !close(r.commanded[k], first.commanded[k])) {
                return Err(differs(r, xyz[k], r.commanded[k], first.commanded[k]));
            }
            if let (Some(a), Some(b)) = (r.commanded_attitude, first.commanded_attitude) {
                let abc = ["ac", "bc", "cc"];
                if let Some(k) = (0..3).find(|&k| !close(self.wrap(a[k] - b[k]) + b[k], b[k])) {
                    return Err(differs(r, abc[k], a[k], b[k]));
                }
            }
        }
        Ok(())
    }

    /// The figures of one pose from its rows.
    fn pose_figures(&self, test: Option<&str>, pose: usize, rows: &[&LogRow]) -> PoseFigures {
        let first = rows[0];
        let n = rows.len();
        let axis = |k: usize| rows.iter().map(|r| r.attained[k]).collect::<Vec<f64>>();
        let bary: [f64; 3] = std::array::from_fn(|k| mean(&axis(k)));
        let ap_xyz: [f64; 3] = std::array::from_fn(|k| bary[k] - first.commanded[k]);
        let ap = ap_xyz.iter().map(|v| v * v).sum::<f64>().sqrt();
        let l: Vec<f64> = rows
            .iter()
            .map(|r| {
                (0..3)
                    .map(|k| (r.attained[k] - bary[k]).powi(2))
                    .sum::<f64>()
                    .sqrt()
            })
            .collect();
        let s_l = std_dev(&l);
        let l_mean = s_l.map(|_| mean(&l));
        // Attitudes: each attained angle's difference from the commanded one, wrapped.
        let (ap_abc, rp_abc) = match (0..3)
            .map(|k| self.deviations(rows, k))
            .collect::<Option<Vec<_>>>()
        {
            Some(d) => (
                Some(std::array::from_fn(|k| mean(&d[k]))),
                (n >= 2).then(|| std::array::from_fn(|k| 3.0 * std_dev(&d[k]).unwrap_or_default())),
            ),
            None => (None, None),
        };
        PoseFigures {
            test: test.map(str::to_string),
            pose,
            cycles: n,
            commanded: first.commanded,
            commanded_attitude: first.commanded_attitude,
            barycentre: bary,
            ap,
            ap_xyz,
            l_mean,
            s_l,
            rp: s_l.map(|s| mean(&l) + 3.0 * s),
            ap_abc,
            rp_abc,
            multidirectional: self.multidirectional(rows),
            compensated: None,
            attained: rows.iter().map(|r| r.attained).collect(),
        }
    }

    /// A pose approached from two directions or more: each direction's barycentre and mean
    /// attitude deviation, and the largest differences between them (vAP).
    fn multidirectional(&self, rows: &[&LogRow]) -> Option<Multidirectional> {
        let mut by_direction: BTreeMap<&str, Vec<&LogRow>> = BTreeMap::new();
        for r in rows {
            if let Some(d) = &r.direction {
                by_direction.entry(d.as_str()).or_default().push(r);
            }
        }
        if by_direction.len() < 2 {
            return None;
        }
        let barycentres: Vec<[f64; 3]> = by_direction
            .values()
            .map(|rs| {
                std::array::from_fn(|k| mean(&rs.iter().map(|r| r.attained[k]).collect::<Vec<_>>()))
            })
            .collect();
        let means: Option<Vec<[f64; 3]>> = by_direction
            .values()
            .map(|rs| {
                let d = (0..3)
                    .map(|k| self.deviations(rs, k))
                    .collect::<Option<Vec<_>>>()?;
                Some(std::array::from_fn(|k| mean(&d[k])))
            })
            .collect();
        let mut vap: f64 = 0.0;
        let mut vap_abc = means.as_ref().map(|_| [0.0f64; 3]);
        for h in 0..barycentres.len() {
            for k in h + 1..barycentres.len() {
                let d = (0..3)
                    .map(|c| (barycentres[h][c] - barycentres[k][c]).powi(2))
                    .sum::<f64>()
                    .sqrt();
                vap = vap.max(d);
                if let (Some(m), Some(v)) = (&means, &mut vap_abc) {
                    for c in 0..3 {
                        v[c] = v[c].max(self.wrap(m[h][c] - m[k][c]).abs());
                    }
                }
            }
        }
        Some(Multidirectional {
            directions: by_direction.keys().map(|d| d.to_string()).collect(),
            barycentres,
            vap,
            vap_abc,
        })
    }

    /// Distances between every pair of poses of a test, cycle by cycle; a warning for a pair
    /// never attained in the same cycle.
    fn distances(&self, warnings: &mut Vec<String>) -> Vec<DistanceFigures> {
        let mut distances = Vec::new();
        let keys: Vec<(usize, usize)> = self.by_pose.keys().copied().collect();
        for (i, &(t, p)) in keys.iter().enumerate() {
            for &(_, q) in keys[i + 1..].iter().filter(|(u, _)| *u == t) {
                match self.distance(t, p, q) {
                    Some(d) => distances.push(d),
                    None => warnings.push(format!(
                        "{}{} and {} were never attained in the same cycle: no distance figures",
                        in_test(self.tests[t]),
                        pose_name(p),
                        pose_name(q)
                    )),
                }
            }
        }
        distances
    }

    /// The distance figures of poses `p` and `q` of test `t` (none when never attained in the
    /// same cycle).
    fn distance(&self, t: usize, p: usize, q: usize) -> Option<DistanceFigures> {
        let keyed = |rows: &[&LogRow]| -> BTreeMap<(u64, Option<String>), [f64; 3]> {
            rows.iter()
                .map(|r| ((r.cycle, r.direction.clone()), r.attained))
                .collect()
        };
        let (a, b) = (keyed(&self.by_pose[&(t, p)]), keyed(&self.by_pose[&(t, q)]));
        let pairs: Vec<([f64; 3], [f64; 3])> = a
            .iter()
            .filter_map(|(key, x)| b.get(key).map(|y| (*x, *y)))
            .collect();
        if pairs.is_empty() {
            return None;
        }
        let (cp, cq) = (
            self.by_pose[&(t, p)][0].commanded,
            self.by_pose[&(t, q)][0].commanded,
        );
        let dc: [f64; 3] = std::array::from_fn(|k| cp[k] - cq[k]);
        let commanded = dc.iter().map(|v| v * v).sum::<f64>().sqrt();
        let d: Vec<f64> = pairs
            .iter()
            .map(|(x, y)| (0..3).map(|k| (x[k] - y[k]).powi(2)).sum::<f64>().sqrt())
            .collect();
        let ad_xyz: [f64; 3] = std::array::from_fn(|k| {
            mean(&pairs.iter().map(|(x, y)| x[k] - y[k]).collect::<Vec<_>>()) - dc[k]
        });
        let m = mean(&d);
        let s_d = std_dev(&d);
        Some(DistanceFigures {
            test: self.tests[t].map(str::to_string),
            from: p,
            to: q,
            cycles: pairs.len(),
            commanded,
            mean: m,
            ad: m - commanded,
            ad_xyz,
            s_d,
            rd: s_d.map(|s| 3.0 * s),
        })
    }
}

/// The warnings of poses measured in fewer cycles than the standard's (`short`: each pose's
/// name and cycles): for one test, a line per number of cycles naming its poses; for a series,
/// one line.
fn cycles_warnings(tests: &[Option<&str>], short: &[(String, usize)], poses: usize) -> Vec<String> {
    let mut warnings = Vec::new();
    if tests.len() == 1 {
        let mut counts: Vec<usize> = short.iter().map(|s| s.1).collect();
        counts.sort_unstable();
        counts.dedup();
        for n in counts {
            let names: Vec<&str> = short
                .iter()
                .filter(|s| s.1 == n)
                .map(|s| s.0.as_str())
                .collect();
            let which = format!("{}{}", in_test(tests[0]), names.join(", "));
            if n == 1 {
                warnings.push(format!(
                    "{which}: 1 cycle: its accuracy (AP, AD) is computed; its repeatability (RP, \
                     RD) needs at least 2 cycles (ISO 9283 asks for {STANDARD_CYCLES})"
                ));
            } else {
                warnings.push(format!(
                    "{which}: {n} cycles, fewer than the {STANDARD_CYCLES} ISO 9283 asks for: the \
                     figures are computed, but they are not those of a standard test"
                ));
            }
        }
    } else if !short.is_empty() {
        let single = short.iter().filter(|s| s.1 == 1).count();
        warnings.push(format!(
            "{} of the {poses} poses of {} tests were measured in fewer than the \
             {STANDARD_CYCLES} cycles ISO 9283 asks for ({single} in 1 cycle: accuracy only, no \
             repeatability): the figures are computed, but they are not those of a standard test",
            short.len(),
            tests.len()
        ));
    }
    warnings
}
