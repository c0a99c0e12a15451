//! The command line's `compensate`, `plan` and `simulate` as functions over arrays (wrapped by
//! the Python package's `kinecal.compensate`, `kinecal.plan` and `kinecal.simulate`, which give
//! the result classes). Values are in the robot's units; results come back as dicts of numpy
//! arrays and Python values, one key per field of the result class.

use kinecal::compensate::{
    goal_in_file_units, Compensator, Configuration, Goal, Options, TargetSearch,
};
use kinecal::identifiability::AnalysisOptions;
use kinecal::observe::{Dataset, Observation};
use kinecal::plan::{candidates as candidate_pool, plan as choose, Criterion, PlanRequest};
use kinecal::simulate::{self as sim, PerturbStd};
use kinecal::units::Quantity;
use kinecal::workflow::Selection;
use kinecal::{Posture, Target};
use numpy::ndarray::Array2;
use numpy::IntoPyArray;
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict};

use crate::{bad, error, numbers, param_list, residual_settings, site_names, Measurements, Robot};

/// The frame named by `site`: None or `"ee"` (or the end effector's name) for the end
/// effector, else a site of `robot` ([`kinecal::files::site_target`]); an error naming
/// `keyword` and the robot's targets otherwise.
pub fn target_of(robot: &kinecal::Robot, site: Option<&str>, keyword: &str) -> PyResult<Target> {
    match site {
        None => Ok(Target::EndEffector),
        Some(s) => kinecal::files::site_target(robot, s).map_err(|m| {
            bad(format!(
                "{keyword}: `{s}` is not a site of {}: {m}",
                robot.name
            ))
        }),
    }
}

/// The error of row `row` of `targets` whose numbers look like another unit's.
pub fn goal_problem(p: &kinecal::compensate::GoalProblem, row: usize) -> PyErr {
    match p {
        kinecal::compensate::GoalProblem::Far(m) => {
            bad(format!("targets: row {row}: the position {m}"))
        }
        kinecal::compensate::GoalProblem::Turn(m) => bad(format!("targets: row {row}: {m}")),
    }
}

/// A whole number of at least `min` given as `keyword` (an integer, not a float or a bool).
fn whole(value: &Bound<'_, PyAny>, keyword: &str, min: u64) -> PyResult<u64> {
    let not_whole = || {
        let kind = value.get_type().name().map(|n| n.to_string());
        PyTypeError::new_err(format!(
            "{keyword}: expected an integer, got {}",
            kind.unwrap_or_else(|_| "something else".into())
        ))
    };
    if value.is_instance_of::<PyBool>() {
        return Err(not_whole());
    }
    match value.extract::<u64>() {
        Ok(v) if v >= min => Ok(v),
        Ok(v) => Err(bad(format!(
            "{keyword}: expected an integer of at least {min}, got {v}"
        ))),
        Err(_) => match value.extract::<i64>() {
            Ok(v) => Err(bad(format!(
                "{keyword}: expected an integer of at least {min}, got {v}"
            ))),
            Err(_) => Err(not_whole()),
        },
    }
}

/// Whether `value` is an integer (a count rather than an array).
fn is_whole(value: &Bound<'_, PyAny>) -> bool {
    !value.is_instance_of::<PyBool>() && value.extract::<i64>().is_ok()
}

/// A `(rows, cols)` array argument; returns the values and the row count.
fn table(
    py: Python<'_>,
    obj: &Bound<'_, PyAny>,
    keyword: &str,
    cols: &[usize],
    what: &str,
) -> PyResult<(Vec<f64>, usize)> {
    let (v, shape) = numbers(py, obj, keyword, 2)?;
    if shape[0] == 0 || !cols.contains(&shape[1]) {
        let want: Vec<String> = cols.iter().map(|c| format!("(rows, {c})")).collect();
        return Err(bad(format!(
            "{keyword}: expected shape {} ({what}), got {shape:?}",
            want.join(" or ")
        )));
    }
    Ok((v, shape[0]))
}

/// Postures from a `(rows, joints)` array of readings, labelled `1..rows`.
fn postures_of(
    py: Python<'_>,
    obj: &Bound<'_, PyAny>,
    keyword: &str,
    robot: &kinecal::Robot,
) -> PyResult<Vec<Posture>> {
    let n = robot.dof();
    let (v, rows) = table(py, obj, keyword, &[n], "readings, one column per joint")?;
    Ok((0..rows)
        .map(|i| Posture {
            label: (i + 1).to_string(),
            readings: v[i * n..(i + 1) * n].to_vec(),
            session: None,
            payload: None,
        })
        .collect())
}

/// A non-negative finite number given as part of `keyword`.
fn non_negative(v: Option<f64>, keyword: &str, key: &str) -> PyResult<Option<f64>> {
    match v {
        Some(x) if !(x.is_finite() && x >= 0.0) => Err(bad(format!(
            "{keyword}: {key} must be a non-negative finite number, got {x}"
        ))),
        _ => Ok(v),
    }
}

/// Compensation (see the Python package's `kinecal.compensate`): the readings at which
/// `calibrated` reaches what `nominal` meant (`program`) or the Cartesian `targets`.
#[pyfunction]
#[pyo3(signature = (calibrated, nominal, *, program=None, targets=None, seeds=None, site=None, position_only=false, tolerance=None, singular=1e-3, branch=None, configuration=None))]
#[allow(clippy::too_many_arguments)]
pub fn compensate<'py>(
    py: Python<'py>,
    calibrated: &Robot,
    nominal: &Robot,
    program: Option<&Bound<'py, PyAny>>,
    targets: Option<&Bound<'py, PyAny>>,
    seeds: Option<&Bound<'py, PyAny>>,
    site: Option<&str>,
    position_only: bool,
    tolerance: Option<(Option<f64>, Option<f64>)>,
    singular: f64,
    branch: Option<f64>,
    configuration: Option<&str>,
) -> PyResult<Bound<'py, PyDict>> {
    let (cal, nom) = (&calibrated.robot, &nominal.robot);
    let units = nom.units;
    let mut options = Options::default();
    if let Some((l, a)) = tolerance {
        if let Some(l) = non_negative(l, "tolerance", "length")? {
            options.position_tolerance = units.to_si(Quantity::Length, l);
        }
        if let Some(a) = non_negative(a, "tolerance", "angle")? {
            options.attitude_tolerance = units.to_si(Quantity::Angle, a);
        }
    }
    if !(0.0..1.0).contains(&singular) {
        return Err(bad(format!(
            "singular: must be between 0 and 1, got {singular}"
        )));
    }
    options.singular = singular;
    if let Some(b) = branch {
        if !(b.is_finite() && b > 0.0) {
            return Err(bad(format!("branch: must be a positive angle, got {b}")));
        }
        options.branch = units.to_si(Quantity::Angle, b);
    }
    let target = target_of(nom, site, "site")?;
    let dof = nom.dof();
    // The goals: a program's readings, or targets with their seeds.
    enum Work {
        Program(Vec<f64>),
        Targets {
            goals: Vec<Goal>,
            seeds: Option<Vec<f64>>,
        },
    }
    let work = match (program, targets) {
        (Some(p), None) => {
            if seeds.is_some() {
                return Err(bad(
                    "seeds: a program's readings are its own seeds; seeds go with targets",
                ));
            }
            let (v, _) = table(py, p, "program", &[dof], "readings, one column per joint")?;
            Work::Program(v)
        }
        (None, Some(t)) => {
            let (v, rows) = table(
                py,
                t,
                "targets",
                &[3, 6],
                "x, y, z and optionally alpha, beta, gamma",
            )?;
            let cols = v.len() / rows;
            let goals = v
                .chunks(cols)
                .enumerate()
                .map(|(i, r)| {
                    let euler = (cols == 6 && !position_only).then(|| [r[3], r[4], r[5]]);
                    goal_in_file_units(nom, [r[0], r[1], r[2]], euler)
                        .map_err(|p| goal_problem(&p, i + 1))
                })
                .collect::<PyResult<Vec<Goal>>>()?;
            let seeds = match seeds {
                Some(s) => {
                    let (sv, srows) =
                        table(py, s, "seeds", &[dof], "readings, one column per joint")?;
                    if srows != rows {
                        return Err(bad(format!(
                            "seeds: {srows} rows for {rows} targets: give one row of readings \
                             per target"
                        )));
                    }
                    Some(sv)
                }
                None => None,
            };
            Work::Targets { goals, seeds }
        }
        (Some(_), Some(_)) => {
            return Err(bad(
                "program, targets: give one (a program's readings or Cartesian targets)",
            ))
        }
        (None, None) => {
            return Err(bad(
                "program, targets: give one (a program's readings or Cartesian targets)",
            ))
        }
    };
    // Built as the command line builds them, with its errors (`nominal: ...`).
    let mut comp = Compensator::new(cal, nom, options).map_err(|e| error(py, e))?;
    let mut search = TargetSearch::new(cal, nom, options).map_err(|e| error(py, e))?;
    if let Some(c) = configuration {
        if matches!(work, Work::Program(_)) {
            return Err(bad(
                "configuration: is for Cartesian targets; a program's readings keep their own",
            ));
        }
        let c = Configuration::parse(c).map_err(|e| error(py, e))?;
        search = search.with_configuration(c).map_err(|e| error(py, e))?;
    }
    let solved = py.detach(|| {
        let mut out = vec![0.0; dof];
        let mut rows = Vec::new();
        match &work {
            Work::Program(v) => {
                for r in v.chunks(dof) {
                    let s = comp.program(r, target, position_only, &mut out);
                    rows.push((out.clone(), s));
                }
            }
            Work::Targets { goals, seeds } => {
                for (i, goal) in goals.iter().enumerate() {
                    let given = seeds.as_ref().map(|sv| &sv[i * dof..(i + 1) * dof]);
                    let s = search.solve(goal, target, given, &mut out);
                    rows.push((out.clone(), s));
                }
            }
        }
        rows
    });
    let n = solved.len();
    let length = |v: f64| units.from_si(Quantity::Length, v);
    let angle = |v: f64| units.from_si(Quantity::Angle, v);
    let readings: Vec<f64> = solved.iter().flat_map(|(r, _)| r.iter().copied()).collect();
    let out_of_range: Vec<bool> = solved
        .iter()
        .flat_map(|(_, s)| (0..dof).map(move |j| s.flags.out_of_range & (1 << j) != 0))
        .collect();
    let d = PyDict::new(py);
    d.set_item(
        "readings",
        Array2::from_shape_vec((n, dof), readings)
            .expect("shape")
            .into_pyarray(py),
    )?;
    let column = |f: &dyn Fn(&kinecal::compensate::Solved) -> f64| -> Vec<f64> {
        solved.iter().map(|(_, s)| f(s)).collect()
    };
    d.set_item(
        "position_error",
        column(&|s| length(s.position_error)).into_pyarray(py),
    )?;
    d.set_item(
        "attitude_error",
        column(&|s| s.attitude_error.map_or(f64::NAN, angle)).into_pyarray(py),
    )?;
    d.set_item(
        "iterations",
        solved
            .iter()
            .map(|(_, s)| s.iterations as i64)
            .collect::<Vec<i64>>()
            .into_pyarray(py),
    )?;
    d.set_item("conditioning", column(&|s| s.conditioning).into_pyarray(py))?;
    let flag = |f: &dyn Fn(&kinecal::compensate::Flags) -> bool| -> Vec<bool> {
        solved.iter().map(|(_, s)| f(&s.flags)).collect()
    };
    d.set_item("unreachable", flag(&|f| f.unreachable).into_pyarray(py))?;
    d.set_item(
        "out_of_range",
        Array2::from_shape_vec((n, dof), out_of_range)
            .expect("shape")
            .into_pyarray(py),
    )?;
    d.set_item("singular", flag(&|f| f.singular).into_pyarray(py))?;
    d.set_item("branch", flag(&|f| f.branch).into_pyarray(py))?;
    d.set_item("configuration", flag(&|f| f.configuration).into_pyarray(py))?;
    d.set_item(
        "flags",
        solved
            .iter()
            .map(|(_, s)| s.flags.describe())
            .collect::<Vec<String>>(),
    )?;
    Ok(d)
}

/// Candidates or kept postures: Measurements (their observations say what is measured) or an
/// array of readings (the `targets` measured at each). Returns the observations and whether
/// they came from Measurements.
fn pool_of(
    py: Python<'_>,
    obj: &Bound<'_, PyAny>,
    keyword: &str,
    robot: &kinecal::Robot,
    targets: &[Target],
    position_only: bool,
) -> PyResult<(Dataset, bool)> {
    if let Ok(m) = obj.extract::<PyRef<'_, Measurements>>() {
        m.check(robot, keyword)?;
        let mut data = m.data.clone();
        if position_only {
            for o in &mut data.observations {
                if let Observation::Pose(p) = o {
                    *o = p.to_position().into();
                }
            }
        }
        return Ok((data, true));
    }
    let postures = postures_of(py, obj, keyword, robot)?;
    Ok((
        candidate_pool(robot, postures, targets, position_only),
        false,
    ))
}

/// A measurement plan (see the Python package's `kinecal.plan`).
#[pyfunction]
#[pyo3(signature = (robot, candidates=None, *, count, sample=None, seed=None, criterion="d", position_only=false, sites=None, estimate=None, fix=None, keep=None, weights=None, orientation_error="rotvec"))]
#[allow(clippy::too_many_arguments)]
pub fn plan<'py>(
    py: Python<'py>,
    robot: &Robot,
    candidates: Option<&Bound<'py, PyAny>>,
    count: &Bound<'py, PyAny>,
    sample: Option<&Bound<'py, PyAny>>,
    seed: Option<&Bound<'py, PyAny>>,
    criterion: &str,
    position_only: bool,
    sites: Option<Vec<Option<String>>>,
    estimate: Option<&Bound<'py, PyAny>>,
    fix: Option<&Bound<'py, PyAny>>,
    keep: Option<&Bound<'py, PyAny>>,
    weights: Option<(f64, f64)>,
    orientation_error: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let r = &robot.robot;
    let count = whole(count, "count", 1)? as usize;
    let seed = seed.map(|s| whole(s, "seed", 0)).transpose()?.unwrap_or(1);
    let criterion: Criterion = criterion.parse().map_err(|e| error(py, e))?;
    let targets: Vec<Target> = match &sites {
        None if r.sites.is_empty() => vec![Target::EndEffector],
        None => (0..r.sites.len()).map(Target::Site).collect(),
        Some(list) => {
            if list.is_empty() {
                return Err(bad(
                    "sites: an empty list: name the frames measured at each posture",
                ));
            }
            let mut out = Vec::new();
            for s in list {
                let t = target_of(r, s.as_deref(), "sites")?;
                if !out.contains(&t) {
                    out.push(t);
                }
            }
            out
        }
    };
    let (pool, observed) =
        match (candidates, sample) {
            (Some(c), None) => pool_of(py, c, "candidates", r, &targets, position_only)?,
            (None, Some(n)) => {
                let n = whole(n, "sample", 1)? as usize;
                let postures = sim::sample_postures(r, n, seed);
                (candidate_pool(r, postures, &targets, position_only), false)
            }
            _ => return Err(bad(
                "candidates, sample: give one (candidate postures or Measurements, or a number \
                 of postures to sample)",
            )),
        };
    if observed && sites.is_some() {
        return Err(bad(
            "sites: describes postures; the candidates are Measurements, whose observations say \
             what is measured",
        ));
    }
    let keep = match keep {
        Some(k) => pool_of(py, k, "keep", r, &targets, position_only)?.0,
        None => Dataset::default(),
    };
    let (weights, orientation) = residual_settings(r, weights, orientation_error)?;
    let estimate = param_list(estimate, "estimate")?.unwrap_or_else(|| "identifiable".into());
    let fix = param_list(fix, "fix")?;
    let selection = Selection::parse(&estimate, fix.as_deref(), r).map_err(|e| error(py, e))?;
    let req = PlanRequest {
        robot: r.clone(),
        pool,
        keep,
        count,
        criterion,
        selection,
        analysis: AnalysisOptions {
            weights,
            orientation,
            ..AnalysisOptions::default()
        },
        seed,
    };
    let p = py.detach(|| choose(&req)).map_err(|e| error(py, e))?;
    // What `kinecal plan --out` writes.
    let (csv, _) = p.chosen_file(r, observed);
    let d = PyDict::new(py);
    d.set_item("criterion", p.criterion.as_str())?;
    d.set_item("value", p.value)?;
    let values = PyDict::new(py);
    for (c, v) in &p.values {
        values.set_item(c.as_str(), *v)?;
    }
    d.set_item("values", values)?;
    d.set_item(
        "parameters",
        p.parameters
            .iter()
            .map(|&id| r.param_name(id))
            .collect::<Vec<_>>(),
    )?;
    d.set_item("rows", p.rows)?;
    d.set_item("rank", p.rank)?;
    d.set_item("condition_number", p.condition_number)?;
    d.set_item("pool_candidates", p.pool_candidates)?;
    d.set_item("efficiency", p.efficiency)?;
    d.set_item(
        "random",
        p.random
            .as_ref()
            .map(|x| (x.draws, x.median_value, x.median_efficiency, x.beaten)),
    )?;
    d.set_item("exchanges", p.exchanges)?;
    d.set_item("passes", p.passes)?;
    let k = p.postures.len();
    d.set_item(
        "labels",
        p.postures
            .iter()
            .map(|q| q.label.clone())
            .collect::<Vec<_>>(),
    )?;
    d.set_item(
        "readings",
        Array2::from_shape_vec(
            (k, r.dof()),
            p.postures
                .iter()
                .flat_map(|q| q.readings.iter().copied())
                .collect(),
        )
        .expect("shape")
        .into_pyarray(py),
    )?;
    d.set_item(
        "leverage",
        p.postures
            .iter()
            .map(|q| q.leverage)
            .collect::<Vec<f64>>()
            .into_pyarray(py),
    )?;
    d.set_item(
        "kept",
        p.postures
            .iter()
            .map(|q| q.candidate.is_none())
            .collect::<Vec<bool>>()
            .into_pyarray(py),
    )?;
    d.set_item(
        "chosen",
        p.postures
            .iter()
            .filter_map(|q| q.candidate.map(|c| c as i64))
            .collect::<Vec<i64>>()
            .into_pyarray(py),
    )?;
    d.set_item(
        "observations",
        Measurements {
            data: p.chosen.clone(),
            dof: r.dof(),
            sites: site_names(r),
        },
    )?;
    d.set_item("csv", csv)?;
    Ok(d)
}

/// Synthesized measurements (see the Python package's `kinecal.simulate`): returns them and
/// the true robot.
#[pyfunction]
#[pyo3(signature = (robot, postures, *, seed=None, perturb=None, perturb_std=None, noise=None, position_only=false))]
#[allow(clippy::too_many_arguments)]
pub fn simulate<'py>(
    py: Python<'py>,
    robot: &Robot,
    postures: &Bound<'py, PyAny>,
    seed: Option<&Bound<'py, PyAny>>,
    perturb: Option<Vec<(String, f64)>>,
    perturb_std: Option<(Option<f64>, Option<f64>, Option<f64>)>,
    noise: Option<(Option<f64>, Option<f64>)>,
    position_only: bool,
) -> PyResult<(Measurements, Robot)> {
    let nominal = &robot.robot;
    let units = nominal.units;
    let seed = seed.map(|s| whole(s, "seed", 0)).transpose()?.unwrap_or(1);
    let postures = if is_whole(postures) {
        let n = whole(postures, "postures", 1)? as usize;
        sim::sample_postures(nominal, n, seed)
    } else {
        postures_of(py, postures, "postures", nominal)?
    };
    let mut truth = nominal.clone();
    if let Some((l, a, s)) = perturb_std {
        let std = PerturbStd {
            length: units.to_si(
                Quantity::Length,
                non_negative(l, "perturb_std", "length")?.unwrap_or(0.0),
            ),
            angle: units.to_si(
                Quantity::Angle,
                non_negative(a, "perturb_std", "angle")?.unwrap_or(0.0),
            ),
            slope_fraction: non_negative(s, "perturb_std", "slope")?.unwrap_or(0.0),
        };
        truth = sim::perturb(&truth, std, seed);
    }
    if let Some(list) = perturb {
        let mut changes = Vec::new();
        for (name, delta) in &list {
            if !delta.is_finite() {
                return Err(bad(format!(
                    "perturb: {name}: {delta} is not a finite number"
                )));
            }
            let ids = kinecal::parse_param_list(name, nominal)
                .map_err(|e| bad(format!("perturb: {e}")))?;
            changes.extend(ids.into_iter().map(|id| (id, *delta)));
        }
        truth = sim::changed(&truth, &changes).map_err(|e| error(py, e))?;
    }
    let mut data = sim::measure(&truth, &postures, position_only);
    if let Some((l, a)) = noise {
        let l = non_negative(l, "noise", "length")?.unwrap_or(0.0);
        let a = non_negative(a, "noise", "angle")?.unwrap_or(0.0);
        sim::add_noise(
            &mut data,
            units.to_si(Quantity::Length, l),
            units.to_si(Quantity::Angle, a),
            seed,
        );
    }
    Ok((
        Measurements {
            data,
            dof: nominal.dof(),
            sites: site_names(nominal),
        },
        Robot {
            robot: truth,
            text: robot.text.clone(),
        },
    ))
}
