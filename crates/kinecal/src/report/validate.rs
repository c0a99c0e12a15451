//! A calibration report read from a file is checked for sense before anything believes it
//! ([`CalibrationReport::from_json`] calls `check`): `kinecal report --from`, `predict`,
//! `export gltf --report`, `report --calibration`, `history record` and Python's `predict` all
//! read reports through it. What it refuses, naming the field by its JSON path
//! (`prediction.covariance[3][4]`):
//!
//! - any number beyond [`MAX_NUMBER`] in magnitude (JSON holds no NaN or infinity; `1e308` is
//!   finite, and its square is not);
//! - a standard deviation, a model-error term or a joint lever that is negative or beyond
//!   [`MAX_SPREAD`] in the report's units;
//! - a covariance that is not square over the estimated parameters, not symmetric, or not
//!   positive semi-definite, within [`COVARIANCE_TOLERANCE`] (see there);
//! - a map whose bin edges are not one more than its bins and in increasing order, whose
//!   cells are not `nu x nv`, whose extents are empty, or whose joints are not the robot's;
//! - parameter ids that repeat, and ids elsewhere (the prediction's, the correlations', the
//!   combinations', the undetermined) that are not the report's parameters;
//! - a 3-D scene whose links or joints name nodes it does not have.

use std::collections::HashSet;

use serde_json::Value;

use super::CalibrationReport;
use crate::predict::{AccuracyMap, GrowthReport, PredictionReport};

/// The largest magnitude of any number in a report: 1e100. Every quantity a calibration of a
/// physical robot reports (objectives, coordinates, bounds) lies dozens of orders of magnitude
/// below it, and sums of a million squares of such numbers stay finite (1e206 against the
/// largest double, 1.8e308): a renderer or a predictor that squares them never overflows.
pub const MAX_NUMBER: f64 = 1e100;

/// The largest standard deviation, model-error term and joint lever a report may hold (the
/// predictor's own bound: [`crate::predict::MAX_SPREAD`]).
pub const MAX_SPREAD: f64 = crate::predict::MAX_SPREAD;

/// The tolerance of the covariance's checks, relative to its entries' scale (`sqrt(c_aa c_bb)`):
/// 1e-8. A covariance kinecal wrote is symmetric to the rounding of its computation (about
/// 1e-15 relative, `n` times the machine epsilon for `n` parameters up to a few hundred),
/// written with every digit (JSON numbers read back exactly); its correlation matrix's smallest
/// eigenvalue is at least `-n^2 eps`, about -1e-11 for 300 parameters, from rounding. A tampered
/// or mistyped entry moves either by far more: a correlation beyond 1 gives an eigenvalue of
/// `1 - |rho|`, a negative variance a negative diagonal. The eigenvalue tolerance is this times
/// the number of parameters (the correlation matrix's eigenvalues sum to it).
pub const COVARIANCE_TOLERANCE: f64 = 1e-8;

/// `v` as a person reads it back (`1e308`, `0.25`).
fn num(v: f64) -> String {
    crate::units::number::format_number(v)
}

/// The first problem of `report` (whose JSON is `value`), as `path: what`.
pub(crate) fn check(value: &Value, report: &CalibrationReport) -> Result<(), String> {
    numbers(value, &mut String::new())?;
    let ids = parameter_ids(report)?;
    let known = |path: String, id: &str| -> Result<(), String> {
        if ids.contains(id) {
            Ok(())
        } else {
            Err(format!(
                "{path}: `{id}` is not one of the report's parameters"
            ))
        }
    };
    for (i, p) in report.parameters.iter().enumerate() {
        spread(&format!("parameters[{i}].sigma"), p.sigma)?;
        spread(&format!("parameters[{i}].prior_sigma"), p.prior_sigma)?;
    }
    for (i, c) in report.combinations.iter().enumerate() {
        spread(&format!("combinations[{i}].sigma"), Some(c.sigma))?;
        for (k, t) in c.terms.iter().enumerate() {
            known(format!("combinations[{i}].terms[{k}].id"), &t.id)?;
        }
    }
    for (i, c) in report.correlations.iter().enumerate() {
        known(format!("correlations[{i}].a"), &c.a)?;
        known(format!("correlations[{i}].b"), &c.b)?;
        if c.rho.is_nan() || c.rho.abs() > 1.0 + COVARIANCE_TOLERANCE {
            return Err(format!(
                "correlations[{i}].rho: expected a correlation between -1 and 1, found {}",
                num(c.rho)
            ));
        }
    }
    for (i, id) in report.undetermined.iter().enumerate() {
        known(format!("undetermined[{i}]"), id)?;
    }
    for (path, w) in [
        ("weight_length", report.weight_length),
        ("weight_angle", report.weight_angle),
    ] {
        if !(w > 0.0 && w <= MAX_SPREAD) {
            return Err(format!(
                "{path}: expected a standard deviation above 0 and at most {MAX_SPREAD:e}, \
                 found {}",
                num(w)
            ));
        }
    }
    if report.variance_factor.is_some_and(|v| v < 0.0) {
        return Err("variance_factor: a ratio of sums of squares is at least 0".into());
    }
    if let Some(p) = &report.prediction {
        prediction(p, &known)?;
    }
    if let Some(s) = &report.scene {
        for (i, posture) in s.postures.iter().enumerate() {
            for (name, skeleton) in [
                ("calibrated", Some(&posture.calibrated)),
                ("nominal", posture.nominal.as_ref()),
            ] {
                let Some(k) = skeleton else { continue };
                let path = format!("scene.postures[{i}].{name}");
                let nodes = k.nodes.len();
                for (l, link) in k.links.iter().enumerate() {
                    if let Some(&n) = link.iter().find(|&&n| n >= nodes) {
                        return Err(format!(
                            "{path}.links[{l}]: node {n}, of {nodes} nodes (0 to {})",
                            nodes.saturating_sub(1)
                        ));
                    }
                }
                for (j, joint) in k.joints.iter().enumerate() {
                    if joint.0 >= nodes {
                        return Err(format!(
                            "{path}.joints[{j}]: node {}, of {nodes} nodes",
                            joint.0
                        ));
                    }
                }
            }
        }
    }
    Ok(())
}

/// Every number under `v` (at `path`) within [`MAX_NUMBER`]; the spec a report echoes is not
/// read as numbers.
fn numbers(v: &Value, path: &mut String) -> Result<(), String> {
    match v {
        Value::Number(n) => {
            let x = n.as_f64().unwrap_or(f64::INFINITY);
            if x.is_nan() || x.abs() > MAX_NUMBER {
                return Err(format!(
                    "{path}: {} is beyond {MAX_NUMBER:e} in magnitude, more than any \
                     calibration reports",
                    num(x)
                ));
            }
        }
        Value::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                let len = path.len();
                path.push_str(&format!("[{i}]"));
                numbers(x, path)?;
                path.truncate(len);
            }
        }
        Value::Object(o) => {
            for (k, x) in o {
                if path.is_empty() && k == "spec" {
                    continue;
                }
                let len = path.len();
                if !path.is_empty() {
                    path.push('.');
                }
                path.push_str(k);
                numbers(x, path)?;
                path.truncate(len);
            }
        }
        _ => {}
    }
    Ok(())
}

/// The parameters' ids, each once.
fn parameter_ids(report: &CalibrationReport) -> Result<HashSet<&str>, String> {
    let mut ids = HashSet::with_capacity(report.parameters.len());
    for (i, p) in report.parameters.iter().enumerate() {
        if !ids.insert(p.id.as_str()) {
            let first = report
                .parameters
                .iter()
                .position(|q| q.id == p.id)
                .unwrap_or(i);
            return Err(format!(
                "parameters[{i}].id: `{}` again (parameters[{first}] is `{}` too): ids are \
                 unique",
                p.id, p.id
            ));
        }
    }
    Ok(ids)
}

/// A standard deviation (or another non-negative spread: `s0`, `c`, a bound) at `path`: at least 0 and at most
/// [`MAX_SPREAD`].
fn spread(path: &str, v: Option<f64>) -> Result<(), String> {
    match v {
        Some(v) if !(0.0..=MAX_SPREAD).contains(&v) => Err(format!(
            "{path}: expected at least 0 and at most {MAX_SPREAD:e}, found {}",
            num(v)
        )),
        _ => Ok(()),
    }
}

/// A model-error term at `path`.
fn growth(path: &str, g: &GrowthReport) -> Result<(), String> {
    for (key, v) in [
        ("s0", g.s0),
        ("c", g.c),
        ("s0_floor", g.s0_floor),
        ("s0_constant", g.s0_constant),
        ("distance_median", g.distance_median),
        ("distance_max", g.distance_max),
    ] {
        spread(&format!("{path}.{key}"), Some(v))?;
    }
    if !(3.0 - 1e-9..=9.0 + 1e-9).contains(&g.shape) {
        return Err(format!(
            "{path}.shape: expected between 3 (even over the axes) and 9 (along one axis), \
             found {}",
            num(g.shape)
        ));
    }
    for (key, v) in [
        ("coverage", g.coverage),
        ("coverage_constant", g.coverage_constant),
        ("coverage_parameters_only", g.coverage_parameters_only),
    ] {
        if !(0.0..=1.0).contains(&v) {
            return Err(format!(
                "{path}.{key}: expected a share between 0 and 1, found {}",
                num(v)
            ));
        }
    }
    Ok(())
}

/// The prediction: its ids, covariance, levers, measured postures, terms and map.
fn prediction(
    p: &PredictionReport,
    known: &dyn Fn(String, &str) -> Result<(), String>,
) -> Result<(), String> {
    let mut seen = HashSet::new();
    for (i, id) in p.estimated.iter().enumerate() {
        known(format!("prediction.estimated[{i}]"), id)?;
        if !seen.insert(id.as_str()) {
            return Err(format!(
                "prediction.estimated[{i}]: `{id}` again: each estimated parameter once"
            ));
        }
    }
    covariance(&p.covariance)?;
    let dof = p.levers.len();
    if dof == 0 {
        return Err("prediction.levers: none: one lever per joint".into());
    }
    for (j, &l) in p.levers.iter().enumerate() {
        if !(0.0..=MAX_SPREAD).contains(&l) {
            return Err(format!(
                "prediction.levers[{j}]: expected a lever (length unit per reading unit) of at \
                 least 0 and at most {MAX_SPREAD:e}, found {}",
                num(l)
            ));
        }
    }
    if p.measured.is_empty() {
        return Err("prediction.measured: no measured posture to measure distances from".into());
    }
    for (i, r) in p.measured.iter().enumerate() {
        if r.len() != dof {
            return Err(format!(
                "prediction.measured[{i}]: {} readings, and {dof} joint levers",
                r.len()
            ));
        }
        if let Some(k) = r.iter().position(|v| !crate::units::plausible(*v)) {
            return Err(format!(
                "prediction.measured[{i}][{k}]: expected a reading within +-1e9, found {}",
                num(r[k])
            ));
        }
    }
    growth("prediction.position", &p.position)?;
    if let Some(a) = &p.attitude {
        growth("prediction.attitude", a)?;
    }
    let mut targets = HashSet::new();
    for (i, t) in p.targets.iter().enumerate() {
        if !targets.insert(t.target.as_str()) {
            return Err(format!(
                "prediction.targets[{i}].target: `{}` again: each target once",
                t.target
            ));
        }
        growth(&format!("prediction.targets[{i}].position"), &t.position)?;
        if let Some(a) = &t.attitude {
            growth(&format!("prediction.targets[{i}].attitude"), a)?;
        }
    }
    for (path, s) in [
        ("prediction.position_summary", Some(&p.position_summary)),
        ("prediction.attitude_summary", p.attitude_summary.as_ref()),
    ] {
        if let Some(s) = s {
            for (key, v) in [
                ("median", s.median),
                ("p95", s.p95),
                ("median_measured", s.median_measured),
            ] {
                spread(&format!("{path}.{key}"), Some(v))?;
            }
        }
    }
    if let Some(m) = &p.map {
        map(m, dof)?;
    }
    Ok(())
}

/// A covariance: square, symmetric and positive semi-definite within
/// [`COVARIANCE_TOLERANCE`], its standard deviations within [`MAX_SPREAD`].
fn covariance(c: &[Vec<f64>]) -> Result<(), String> {
    let n = c.len();
    let path = "prediction.covariance";
    for (a, row) in c.iter().enumerate() {
        if row.len() != n {
            return Err(format!(
                "{path}[{a}]: {} entries in a {n} x {n} covariance (one row and column per \
                 estimated parameter)",
                row.len()
            ));
        }
        let v = row[a];
        if !(v >= 0.0 && v.sqrt() <= MAX_SPREAD) {
            return Err(format!(
                "{path}[{a}][{a}]: expected a variance of at least 0 (a standard deviation of \
                 at most {MAX_SPREAD:e}), found {}",
                num(v)
            ));
        }
    }
    let tol = COVARIANCE_TOLERANCE;
    let s: Vec<f64> = (0..n).map(|a| c[a][a].sqrt()).collect();
    for a in 0..n {
        for b in 0..a {
            let scale = s[a] * s[b];
            if (c[a][b] - c[b][a]).abs() > tol * scale {
                return Err(format!(
                    "{path}[{a}][{b}]: {} against {} at [{b}][{a}]: a covariance is symmetric",
                    num(c[a][b]),
                    num(c[b][a])
                ));
            }
            if c[a][b].abs() > (1.0 + tol) * scale {
                return Err(format!(
                    "{path}[{a}][{b}]: {} is beyond the product of the two standard deviations \
                     ({scale:e}): a correlation beyond 1, not a covariance",
                    num(c[a][b])
                ));
            }
        }
    }
    if n < 3 {
        // Two parameters: the bound on the correlation above is the whole condition.
        return Ok(());
    }
    // The correlation matrix's smallest eigenvalue (a parameter of variance 0 keeps its zeros).
    let d: Vec<f64> = s
        .iter()
        .map(|&x| if x > 0.0 { 1.0 / x } else { 1.0 })
        .collect();
    let r = nalgebra::DMatrix::from_fn(n, n, |a, b| 0.5 * (c[a][b] + c[b][a]) * d[a] * d[b]);
    let low = r
        .symmetric_eigenvalues()
        .iter()
        .cloned()
        .fold(f64::INFINITY, f64::min);
    if low.is_nan() || low < -tol * n as f64 {
        return Err(format!(
            "{path}: not positive semi-definite: its correlation matrix has an eigenvalue of \
             {low:.3e} (a covariance's are at least 0; rounding leaves at most {:.0e} below)",
            tol * n as f64
        ));
    }
    Ok(())
}

/// An accuracy map over `dof` joints.
fn map(m: &AccuracyMap, dof: usize) -> Result<(), String> {
    let path = "prediction.map";
    let [lo, hi] = m.scale;
    if !(0.0..=hi).contains(&lo) {
        return Err(format!(
            "{path}.scale: expected [low, high] with 0 <= low <= high, found [{}, {}]",
            num(lo),
            num(hi)
        ));
    }
    for (i, s) in m.slices.iter().enumerate() {
        let at = format!("{path}.slices[{i}]");
        let [u0, u1, v0, v1] = s.extent;
        if !(u0 < u1 && v0 < v1) {
            return Err(format!(
                "{at}.extent: expected [u_min, u_max, v_min, v_max] with each min below its \
                 max, found [{}, {}, {}, {}]",
                num(u0),
                num(u1),
                num(v0),
                num(v1)
            ));
        }
        if s.nu == 0 || s.nv == 0 || s.nu.checked_mul(s.nv) != Some(s.values.len()) {
            return Err(format!(
                "{at}.values: {} cells, and nu x nv is {} x {}: one value per cell",
                s.values.len(),
                s.nu,
                s.nv
            ));
        }
        if let Some(k) = s.values.iter().position(|v| v.is_some_and(|v| v < 0.0)) {
            return Err(format!(
                "{at}.values[{k}]: a bound of at least 0, found {}",
                num(s.values[k].unwrap_or_default())
            ));
        }
    }
    for (i, j) in m.joints.iter().enumerate() {
        let at = format!("{path}.joints[{i}]");
        if !(1..=dof).contains(&j.joint) {
            return Err(format!(
                "{at}.joint: {}, and the robot has joints 1 to {dof}",
                j.joint
            ));
        }
        let bins = j.median.len();
        if j.edges.len() != bins + 1 || j.p95.len() != bins || j.measured.len() != bins {
            return Err(format!(
                "{at}.edges: {} edges for {bins} bins ({} 95th percentiles, {} counts): the \
                 edges are one more than the bins",
                j.edges.len(),
                j.p95.len(),
                j.measured.len()
            ));
        }
        if let Some(k) = j
            .edges
            .windows(2)
            .position(|w| w[0].is_nan() || w[0] > w[1])
        {
            return Err(format!(
                "{at}.edges[{}]: {} after {}: the edges increase",
                k + 1,
                num(j.edges[k + 1]),
                num(j.edges[k])
            ));
        }
        for (name, values) in [("median", &j.median), ("p95", &j.p95)] {
            if let Some(k) = values.iter().position(|v| v.is_some_and(|v| v < 0.0)) {
                return Err(format!(
                    "{at}.{name}[{k}]: a bound of at least 0, found {}",
                    num(values[k].unwrap_or_default())
                ));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A covariance as kinecal computes one: `A A^T`, its entries rounded as computed.
    fn computed(n: usize, seed: u64) -> Vec<Vec<f64>> {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        // Mixed units: columns scaled from 1e-6 to 1e2.
        let a: Vec<Vec<f64>> = (0..n)
            .map(|i| {
                let s = 10f64.powi(i as i32 % 9 - 6);
                (0..n + 2)
                    .map(|_| s * rng.random_range(-1.0..1.0))
                    .collect()
            })
            .collect();
        (0..n)
            .map(|i| {
                (0..n)
                    .map(|j| a[i].iter().zip(&a[j]).map(|(x, y)| x * y).sum())
                    .collect()
            })
            .collect()
    }

    #[test]
    fn a_computed_covariance_passes_and_a_tampered_one_is_named() {
        for (n, seed) in [(1, 1), (2, 2), (7, 3), (60, 4)] {
            let c = computed(n, seed);
            covariance(&c).unwrap_or_else(|e| panic!("{n}: {e}"));
            // A rank-deficient one (two parameters the data cannot tell apart) too.
            let mut d = c.clone();
            if n > 2 {
                for row in d.iter_mut() {
                    row[1] = row[0];
                }
                d[1] = d[0].clone();
                d[1][1] = d[0][0];
                covariance(&d).unwrap_or_else(|e| panic!("{n}: {e}"));
            }
        }
        let c = computed(7, 3);
        // A negative variance.
        let mut d = c.clone();
        d[2][2] = -d[2][2];
        let e = covariance(&d).unwrap_err();
        assert!(
            e.starts_with("prediction.covariance[2][2]: expected a variance of at least 0"),
            "{e}"
        );
        // Not symmetric.
        let mut d = c.clone();
        d[4][1] *= 1.001;
        let e = covariance(&d).unwrap_err();
        assert!(
            e.starts_with("prediction.covariance[4][1]: ") && e.contains("symmetric"),
            "{e}"
        );
        // A correlation beyond 1.
        let mut d = c.clone();
        let r = 1.01 * (d[3][3] * d[5][5]).sqrt();
        (d[5][3], d[3][5]) = (r, r);
        let e = covariance(&d).unwrap_err();
        assert!(e.contains("a correlation beyond 1"), "{e}");
        // Every correlation within 1, and still not a covariance: 0.9, 0.9 and -0.9.
        let s = [1.0, 1e-6, 1e3];
        let rho = [[1.0, 0.9, 0.9], [0.9, 1.0, -0.9], [0.9, -0.9, 1.0]];
        let d: Vec<Vec<f64>> = (0..3)
            .map(|i| (0..3).map(|j| rho[i][j] * s[i] * s[j]).collect())
            .collect();
        let e = covariance(&d).unwrap_err();
        assert!(e.contains("not positive semi-definite"), "{e}");
        // Scaled by 1e300: beyond any standard deviation.
        let d: Vec<Vec<f64>> = c
            .iter()
            .map(|r| r.iter().map(|v| v * 1e300).collect())
            .collect();
        assert!(covariance(&d).unwrap_err().contains("at most 1e12"));
    }
}
