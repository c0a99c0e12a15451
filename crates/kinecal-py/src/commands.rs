//! The command line's `compensate`, `plan` and `simulate` as functions over arrays (wrapped by
//! the Python package's `kinecal.compensate`, `kinecal.plan` and `kinecal.simulate`, which give
//! the result classes). Values are in the robot's units; results come back as dicts of numpy
//! arrays and Python values, one key per field of the result class.

use kinecal::apps::compensate::{goal_in_file_units, Compensator, Goal, TargetSearch};
use kinecal::apps::plan::{candidates as candidate_pool, plan as choose};
use kinecal::apps::simulate as sim;
use kinecal::observe::{Dataset, Observation};
use kinecal::spec::{CompensateSpec, PlanSpec, SimulateSpec};
use kinecal::units::Quantity;
use kinecal::{Posture, Target};
use numpy::IntoPyArray;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::{bad, error, numbers, site_names, Measurements, Robot};

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
pub fn goal_problem(p: &kinecal::apps::compensate::GoalProblem, row: usize) -> PyErr {
    match p {
        kinecal::apps::compensate::GoalProblem::Far(m) => {
            bad(format!("targets: row {row}: the position {m}"))
        }
        kinecal::apps::compensate::GoalProblem::Turn(m) => bad(format!("targets: row {row}: {m}")),
    }
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

/// Compensation (see the Python package's `kinecal.compensate`): the readings at which
/// `calibrated` reaches what `nominal` meant (`program`) or the Cartesian `targets`; `spec` is
/// the compensation spec of the keywords (site, position_only, tolerance, singular, branch,
/// configuration), translated as the command line's.
#[pyfunction]
#[pyo3(signature = (calibrated, nominal, spec, *, program=None, targets=None, seeds=None))]
pub fn compensate<'py>(
    py: Python<'py>,
    calibrated: &Robot,
    nominal: &Robot,
    spec: &str,
    program: Option<&Bound<'py, PyAny>>,
    targets: Option<&Bound<'py, PyAny>>,
    seeds: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let (cal, nom) = (&calibrated.robot, &nominal.robot);
    let spec: CompensateSpec = crate::jobs::settings(py, spec)?;
    let options = spec.options(nom).map_err(|e| error(py, e))?;
    let position_only = spec.position_only;
    let configuration = spec.configuration().map_err(|e| error(py, e))?;
    // The frames reached: the site named, or a tree program's tools (one per branch).
    let tools = spec.tools(nom).map_err(|e| error(py, e))?;
    let target = tools[0];
    let work = match (program, targets) {
        (Some(p), None) => {
            if seeds.is_some() {
                return Err(bad(
                    "seeds: a program's readings are its own seeds; seeds go with targets",
                ));
            }
            let (v, _) = table(
                py,
                p,
                "program",
                &[nom.dof()],
                "readings, one column per joint",
            )?;
            Work::Program(v)
        }
        (None, Some(_)) if tools.len() > 1 => {
            return Err(bad(
                "site: several tools are for a program of a tree (a target's frame is the one \
                 site)",
            ))
        }
        (None, Some(t)) => targets_work(py, nom, t, seeds, position_only)?,
        (Some(_), Some(_)) | (None, None) => {
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
        search = search.with_configuration(c).map_err(|e| error(py, e))?;
    }
    let dof = nom.dof();
    let solved = py.detach(|| {
        let mut out = vec![0.0; dof];
        let mut rows = Vec::new();
        match &work {
            Work::Program(v) => {
                for r in v.chunks(dof) {
                    let s = comp.program_tools(r, &tools, position_only, &mut out);
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
    compensated(py, &solved, nom)
}

/// What to compensate: a program's readings, or targets with their seeds.
enum Work {
    Program(Vec<f64>),
    Targets {
        goals: Vec<Goal>,
        seeds: Option<Vec<f64>>,
    },
}

/// The targets (`(rows, 3)` positions or `(rows, 6)` poses, in the robot file's units; the
/// attitudes dropped when `position_only`) with their seeds, one row of readings per target.
fn targets_work(
    py: Python<'_>,
    nom: &kinecal::Robot,
    t: &Bound<'_, PyAny>,
    seeds: Option<&Bound<'_, PyAny>>,
    position_only: bool,
) -> PyResult<Work> {
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
            goal_in_file_units(nom, [r[0], r[1], r[2]], euler).map_err(|p| goal_problem(&p, i + 1))
        })
        .collect::<PyResult<Vec<Goal>>>()?;
    let seeds = match seeds {
        Some(s) => {
            let (sv, srows) = table(
                py,
                s,
                "seeds",
                &[nom.dof()],
                "readings, one column per joint",
            )?;
            if srows != rows {
                return Err(bad(format!(
                    "seeds: {srows} rows for {rows} targets: give one row of readings per target"
                )));
            }
            Some(sv)
        }
        None => None,
    };
    Ok(Work::Targets { goals, seeds })
}

/// The compensated rows as the result class's fields: readings, remaining errors (in `nom`'s
/// units), iterations, conditioning, and each flag.
fn compensated<'py>(
    py: Python<'py>,
    solved: &[(Vec<f64>, kinecal::apps::compensate::Solved)],
    nom: &kinecal::Robot,
) -> PyResult<Bound<'py, PyDict>> {
    let (units, dof, n) = (nom.units, nom.dof(), solved.len());
    let length = |v: f64| units.from_si(Quantity::Length, v);
    let angle = |v: f64| units.from_si(Quantity::Angle, v);
    let readings: Vec<f64> = solved.iter().flat_map(|(r, _)| r.iter().copied()).collect();
    let out_of_range: Vec<bool> = solved
        .iter()
        .flat_map(|(_, s)| (0..dof).map(move |j| s.flags.out_of_range & (1 << j) != 0))
        .collect();
    let d = PyDict::new(py);
    d.set_item("readings", crate::row_major_array(py, (n, dof), readings))?;
    let column = |f: &dyn Fn(&kinecal::apps::compensate::Solved) -> f64| -> Vec<f64> {
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
    let flag = |f: &dyn Fn(&kinecal::apps::compensate::Flags) -> bool| -> Vec<bool> {
        solved.iter().map(|(_, s)| f(&s.flags)).collect()
    };
    d.set_item("unreachable", flag(&|f| f.unreachable).into_pyarray(py))?;
    d.set_item(
        "out_of_range",
        crate::row_major_array(py, (n, dof), out_of_range),
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
        let mut data = Dataset::clone(&m.data);
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

/// A measurement plan (see the Python package's `kinecal.plan`): `spec` is the plan spec of
/// the keywords (count, sample, seed, criterion, position_only, sites, estimate, fix, weights,
/// orientation_error), translated as the command line's; `candidates` and `keep` in memory.
#[pyfunction]
#[pyo3(signature = (robot, spec, candidates=None, keep=None))]
pub fn plan<'py>(
    py: Python<'py>,
    robot: &Robot,
    spec: &str,
    candidates: Option<&Bound<'py, PyAny>>,
    keep: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let r = &robot.robot;
    let spec: PlanSpec = crate::jobs::settings(py, spec)?;
    let targets = spec.targets(r).map_err(|e| error(py, e))?;
    let pool = plan_pool(py, r, &spec, candidates, &targets)?;
    let observed = pool.observed;
    let keep = match keep {
        Some(k) => pool_of(py, k, "keep", r, &targets, spec.position_only)?.0,
        None => Dataset::default(),
    };
    let req = spec.request(r, pool.data, keep).map_err(|e| error(py, e))?;
    let p = py.detach(|| choose(&req)).map_err(|e| error(py, e))?;
    planned(py, &p, r, observed)
}

/// The candidates a plan chooses from: given (Measurements or readings), or `sample` postures
/// drawn by the spec.
fn plan_pool(
    py: Python<'_>,
    r: &kinecal::Robot,
    spec: &PlanSpec,
    candidates: Option<&Bound<'_, PyAny>>,
    targets: &[Target],
) -> PyResult<kinecal::spec::Pool> {
    match (candidates, spec.sample) {
        (Some(c), None) => {
            let (data, observed) = pool_of(py, c, "candidates", r, targets, spec.position_only)?;
            if observed {
                spec.pool_of_observations(data, String::new())
            } else {
                Ok(kinecal::spec::Pool {
                    data,
                    observed: false,
                    described: String::new(),
                })
            }
            .map_err(|e| error(py, e))
        }
        (None, Some(_)) => spec.pool(r).map_err(|e| error(py, e)),
        _ => Err(bad(
            "candidates, sample: give one (candidate postures or Measurements, or a number \
             of postures to sample)",
        )),
    }
}

/// A plan as the result class's fields: its criteria, rank and search, the postures chosen
/// (labels, readings, leverage, kept or chosen), their observations, and the CSV
/// `kinecal plan --out` writes.
fn planned<'py>(
    py: Python<'py>,
    p: &kinecal::apps::plan::Plan,
    r: &kinecal::Robot,
    observed: bool,
) -> PyResult<Bound<'py, PyDict>> {
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
        crate::row_major_array(
            py,
            (k, r.dof()),
            p.postures
                .iter()
                .flat_map(|q| q.readings.iter().copied())
                .collect(),
        ),
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
            data: p.chosen.clone().into(),
            dof: r.dof(),
            sites: site_names(r),
        },
    )?;
    d.set_item("csv", csv)?;
    Ok(d)
}

/// Synthesized measurements (see the Python package's `kinecal.simulate`): `spec` is the
/// simulation spec of the keywords (seed, perturb, perturb_std, noise, position_only; `postures`
/// its count when sampled), translated as the command line's; or readings in memory. Returns
/// the measurements and the true robot.
#[pyfunction]
#[pyo3(signature = (robot, spec, postures=None))]
pub fn simulate<'py>(
    py: Python<'py>,
    robot: &Robot,
    spec: &str,
    postures: Option<&Bound<'py, PyAny>>,
) -> PyResult<(Measurements, Robot)> {
    let nominal = &robot.robot;
    let spec: SimulateSpec = crate::jobs::settings(py, spec)?;
    let truth = spec.truth(nominal).map_err(|e| error(py, e))?;
    let data = match postures {
        None => spec
            .measurements(nominal, &truth)
            .map_err(|e| error(py, e))?,
        Some(p) => {
            let postures = postures_of(py, p, "postures", nominal)?;
            let mut data = match spec.camera_and_board(nominal).map_err(|e| error(py, e))? {
                // The views among the postures that see enough of the board.
                Some(cb) => sim::camera_views(
                    &truth,
                    &postures,
                    cb.0,
                    cb.1,
                    spec.min_points.unwrap_or(kinecal::spec::MIN_POINTS),
                ),
                None => sim::measure(&truth, &postures, spec.position_only),
            };
            spec.add_noise(nominal, &mut data)
                .map_err(|e| error(py, e))?;
            data
        }
    };
    Ok((
        Measurements {
            data: data.into(),
            dof: nominal.dof(),
            sites: site_names(nominal),
        },
        Robot {
            robot: truth,
            text: robot.text.clone(),
        },
    ))
}
