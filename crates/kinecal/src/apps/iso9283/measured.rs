//! ISO 9283 figures from a measurement series, and the accuracy a calibration predicts once the
//! program is compensated.
//!
//! # A log from measurements ([`log_from_measurements`])
//!
//! A measurement file ([`crate::files`]) holds readings and what an instrument measured (in its
//! own frame); ISO 9283 wants commanded and attained poses in the robot's base frame. With a
//! robot model and the roles of the postures ([`Roles`]: which test, pose and cycle each
//! posture is):
//!
//! - the **attained** pose of a row is the measurement taken into the robot's global frame
//!   through its session's measurement frame (which the robot must have: a calibration places
//!   it, `kinecal iso9283 log` re-estimates it on the file when the robot lacks it, as a
//!   validation does);
//! - the **commanded** pose of a test's pose is where the model puts the target at the mean of
//!   the readings of its cycles: the pose the robot was sent to, as the model sees it.
//!
//! So the figures are those of the robot driven by that model: with the nominal model, the
//! robot before calibration; with a calibrated one (identified on other data), the robot running
//! a program compensated with it (its error at these postures is what compensation leaves).
//!
//! # After compensation, predicted ([`predict_compensated`])
//!
//! A compensated program commands each pose through the calibrated model's inverse kinematics.
//! What remains of `AP` is the calibrated model's error there, which the calibration predicts
//! ([`crate::predict`]): per pose, the predicted RMS and 95 % bound of the position error at the
//! pose's readings (the log's, when it has them; otherwise the calibrated model's inverse
//! kinematics of the commanded pose). The repeatability is the robot's own: compensation does
//! not change it.

use std::collections::BTreeMap;

use nalgebra::{Matrix3, Vector3};

use super::figures::{Compensated, Evaluation};
use super::{pose_index, pose_name, Log, LogRow, Reacher, CORNERS};
use crate::error::{Error, Location, Result};
use crate::files::table;
use crate::model::kinematics::{euler_zyx, Chain, Target};
use crate::model::robot::Robot;
use crate::observe::{session_frame, Dataset, Observation, Posture, View};
use crate::predict::Predictor;
use crate::units::{AngleUnit, Quantity, Units};

/// The role of one posture in a series of ISO 9283 tests.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Role {
    /// The test (a label: one cube).
    pub test: String,
    /// The pose: 1 to 5 for `P1..P5`, 6 to 13 for the corners `C1..C8`.
    pub pose: usize,
    /// The cycle.
    pub cycle: u64,
}

/// The roles of the postures of a measurement file, by posture label.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Roles {
    /// The file they came from.
    pub file: String,
    /// Per posture label.
    pub by_posture: BTreeMap<String, Role>,
}

/// The header of a roles file.
pub(crate) const ROLES_HEADER: &str = "posture,test,pose,cycle";

/// Reads a roles file: `posture,test,pose,cycle`, one row per posture of a measurement file
/// (its label), `pose` as in a log (`P1..P5`, `C1..C8`). A posture named twice, or one test's
/// pose in one cycle twice, is refused with its line.
pub fn read_roles(text: &str, file: &str) -> Result<Roles> {
    let t = table::read(text, file)?;
    let known: Vec<String> = ROLES_HEADER.split(',').map(String::from).collect();
    t.refuse_unknown(&known, ROLES_HEADER)?;
    let cols: Vec<usize> = known
        .iter()
        .map(|c| t.require(c, ROLES_HEADER))
        .collect::<Result<_>>()?;
    t.check_rows()?;
    let mut by_posture = BTreeMap::new();
    let mut seen: BTreeMap<(String, usize, u64), usize> = BTreeMap::new();
    for (line, f) in t.rows() {
        let posture = f[cols[0]].to_string();
        let test = f[cols[1]].to_string();
        if posture.is_empty() || test.is_empty() {
            return Err(Error::input(
                t.at(
                    line,
                    if posture.is_empty() {
                        "posture"
                    } else {
                        "test"
                    },
                ),
                "expected a label, found an empty field",
            ));
        }
        let pose = pose_index(&t, line, &f[cols[2]], true)?;
        let cs = &f[cols[3]];
        let cycle: u64 = cs.parse().map_err(|_| {
            Error::input(
                t.at(line, "cycle"),
                format!("expected a cycle number (a whole number), found `{cs}`"),
            )
        })?;
        if let Some(first) = seen.insert((test.clone(), pose, cycle), line) {
            return Err(Error::input(
                t.at(line, "cycle"),
                format!(
                    "test `{test}`: {} in cycle {cycle} appears twice (also on line {first})",
                    pose_name(pose)
                ),
            ));
        }
        if by_posture
            .insert(posture.clone(), Role { test, pose, cycle })
            .is_some()
        {
            return Err(Error::input(
                t.at(line, "posture"),
                format!("posture `{posture}` is given a role twice"),
            ));
        }
    }
    if by_posture.is_empty() {
        return Err(Error::input(
            Location::file(file),
            "no rows: the roles file has a header but no postures",
        ));
    }
    Ok(Roles {
        file: file.to_string(),
        by_posture,
    })
}

/// A roles file ([`read_roles`]) for `roles`, in posture order.
pub fn write_roles(roles: &[(String, Role)]) -> String {
    let mut out = String::from(ROLES_HEADER);
    out.push('\n');
    for (posture, r) in roles {
        out += &format!("{posture},{},{},{}\n", r.test, pose_name(r.pose), r.cycle);
    }
    out
}

/// The roles of a series of cubes each measured as its centre and its eight corners: `goals`
/// holds, per posture in order, the commanded position of the target (any frame, any unit:
/// only compared), in consecutive blocks of nine (the centre, then the corners in any order).
/// A block whose centre and corners repeat an earlier block's (within `tolerance`) is a further
/// cycle of that block's test. Tests are named `cube 1`, `cube 2`, ... in order of first
/// appearance; the corners get the ISO names `C1..C8` from their signs about the centre (`C1 =
/// (-,-,-)`, `x` changing fastest). Postures after the last whole block get no role. An error
/// when a block is not a centre with eight distinct corners of one cube.
pub fn cube_roles(goals: &[[f64; 3]], tolerance: f64) -> std::result::Result<Vec<Role>, String> {
    let mut tests: Vec<Vec<[f64; 3]>> = Vec::new();
    let mut cycles: Vec<u64> = Vec::new();
    let mut out = Vec::new();
    for (b, block) in goals.chunks_exact(9).enumerate() {
        let centre = block[0];
        let mut poses = Vec::with_capacity(9);
        poses.push(1);
        let mut half = None::<f64>;
        for (k, g) in block[1..].iter().enumerate() {
            let d: [f64; 3] = std::array::from_fn(|a| g[a] - centre[a]);
            let h = d.iter().map(|v| v.abs()).fold(0.0, f64::max);
            let h0 = *half.get_or_insert(h);
            if h0 <= tolerance || d.iter().any(|v| (v.abs() - h0).abs() > tolerance) {
                return Err(format!(
                    "block {} (postures {}..{}): posture {} is not a corner of a cube about the \
                     block's first posture",
                    b + 1,
                    9 * b + 1,
                    9 * b + 9,
                    9 * b + k + 2
                ));
            }
            let index = (0..3).map(|a| usize::from(d[a] > 0.0) << a).sum::<usize>();
            let pose = CORNERS + 1 + index;
            if poses.contains(&pose) {
                return Err(format!(
                    "block {} (postures {}..{}): corner {} appears twice",
                    b + 1,
                    9 * b + 1,
                    9 * b + 9,
                    pose_name(pose)
                ));
            }
            poses.push(pose);
        }
        let same = |t: &[[f64; 3]]| {
            t.iter()
                .zip(block)
                .all(|(a, b)| (0..3).all(|k| (a[k] - b[k]).abs() <= tolerance))
        };
        let t = match tests.iter().position(|t| same(t)) {
            Some(t) => {
                cycles[t] += 1;
                t
            }
            None => {
                tests.push(block.to_vec());
                cycles.push(1);
                tests.len() - 1
            }
        };
        for pose in poses {
            out.push(Role {
                test: format!("cube {}", t + 1),
                pose,
                cycle: cycles[t],
            });
        }
    }
    Ok(out)
}

/// The ISO 9283 log of `data` for `robot` (see the module's documentation): one row per posture
/// with a role, in `robot`'s file units (lengths, angles), the readings kept (`v1..vn`), and the
/// labels of the measured postures without a role (left out). Each measured posture must be a
/// position or a pose of one target, in a session whose frame `robot` has (or in the global
/// frame), and all of them positions or all poses. An error names the session without a frame,
/// a pose measured at two targets, or a pose and a position mixed.
pub fn log_from_measurements(
    robot: &Robot,
    data: &Dataset,
    roles: &Roles,
) -> Result<(Log, Vec<String>)> {
    let file = roles.file.as_str();
    let (measured, left_out) = measured_in_global_frame(robot, data, roles)?;
    one_kind(&measured)?;
    let commanded = commanded_poses(robot, data, &measured)?;
    let rows = log_rows(robot.units, data, &measured, &commanded);
    if rows.is_empty() {
        return Err(Error::input(
            Location::file(file),
            "no measured posture of the data has a role here (are the posture labels the data's?)",
        ));
    }
    let log = Log {
        file: file.to_string(),
        length_unit: Some(robot.units.length),
        angle_unit: Some(robot.units.angle),
        simulated: false,
        rows,
    };
    Ok((log, left_out))
}

/// Refuses measurements that mix poses and positions: a log's rows all have attitudes or none
/// (a row without one would be written with zero angles).
fn one_kind(measured: &[Measured]) -> Result<()> {
    let pose = measured.iter().find(|m| m.rotation.is_some());
    let position = measured.iter().find(|m| m.rotation.is_none());
    if let (Some(pose), Some(position)) = (pose, position) {
        return Err(Error::Problem(format!(
            "the measurements mix poses (line {}) and positions (line {}): an ISO 9283 log has \
             attitudes in every row or in none; measure poses throughout, or give positions only",
            pose.line, position.line
        )));
    }
    Ok(())
}

/// One measured posture with a role, its measurement in the robot's global frame.
struct Measured {
    /// Its test, pose and cycle.
    role: Role,
    /// The posture (an index into the data's postures).
    posture: usize,
    /// The target measured.
    target: Target,
    /// The measured position (m, global frame).
    position: Vector3<f64>,
    /// The measured rotation (global frame), when a pose was measured.
    rotation: Option<Matrix3<f64>>,
    /// The measurement's line in its file.
    line: usize,
}

/// The measured postures of `data` that have a role, in the data's order, their measurements
/// taken into `robot`'s global frame; and the labels of those without a role (left out, one per
/// measurement). An error for an observation other than a position or a pose, a posture
/// measured twice, or a session `robot` has no measurement frame for.
fn measured_in_global_frame(
    robot: &Robot,
    data: &Dataset,
    roles: &Roles,
) -> Result<(Vec<Measured>, Vec<String>)> {
    let mut measured = Vec::new();
    let mut seen = vec![false; data.postures.len()];
    // A posture without a role is left out once, however many targets it measured.
    let mut left = vec![false; data.postures.len()];
    let mut left_out = Vec::new();
    for o in &data.observations {
        let Measurement {
            view,
            position,
            rotation,
            line,
        } = measurement(o)?;
        let posture = &data.postures[view.posture];
        let Some(role) = roles.by_posture.get(&posture.label) else {
            if !std::mem::replace(&mut left[view.posture], true) {
                left_out.push(posture.label.clone());
            }
            continue;
        };
        if std::mem::replace(&mut seen[view.posture], true) {
            return Err(Error::Problem(format!(
                "posture `{}` is measured twice (line {line}): an ISO 9283 log takes one \
                 measurement per pose and cycle",
                posture.label
            )));
        }
        let (position, rotation) = into_global_frame(robot, posture, position, rotation)?;
        measured.push(Measured {
            role: role.clone(),
            posture: view.posture,
            target: view.target,
            position,
            rotation,
            line,
        });
    }
    Ok((measured, left_out))
}

/// What one observation measured, in the instrument's frame.
struct Measurement {
    /// The posture and target.
    view: View,
    /// The measured position (m).
    position: Vector3<f64>,
    /// The measured rotation, for a pose.
    rotation: Option<Matrix3<f64>>,
    /// The observation's line in its file.
    line: usize,
}

/// What an observation measured (the rotation of a pose from its ZYX Euler angles `alpha,
/// beta, gamma`); an error for an observation that is neither a position nor a pose.
fn measurement(o: &Observation) -> Result<Measurement> {
    let (view, position, rotation, line) = match o {
        Observation::Position(p) => (p.view[0], p.position, None, p.line),
        Observation::Pose(p) => (
            p.view[0],
            p.position,
            Some(crate::model::kinematics::rot_zyx(
                p.euler.x, p.euler.y, p.euler.z,
            )),
            p.line,
        ),
        _ => {
            return Err(Error::Problem(format!(
                "an ISO 9283 log takes positions or poses; the data has {} observations",
                o.kind()
            )))
        }
    };
    Ok(Measurement {
        view,
        position,
        rotation,
        line,
    })
}

/// A measured position (m) and rotation taken from the instrument's frame into the global frame
/// through `posture`'s session frame `(R, t)`, the global frame's pose in the instrument's
/// frame: `R^T (p - t)` and `R^T R_measured`. Unchanged when the posture has no session, or
/// `robot` no session frames at all; an error names a session `robot` has no frame for.
fn into_global_frame(
    robot: &Robot,
    posture: &Posture,
    position: Vector3<f64>,
    rotation: Option<Matrix3<f64>>,
) -> Result<(Vector3<f64>, Option<Matrix3<f64>>)> {
    match session_frame(robot, posture) {
        Some(f) => {
            let rt = f.rotation.transpose();
            Ok((rt * (position - f.translation), rotation.map(|r| rt * r)))
        }
        None => {
            if let Some(s) = posture
                .session
                .as_deref()
                .filter(|_| !robot.sessions.is_empty())
            {
                return Err(Error::Problem(format!(
                    "session `{s}` has no measurement frame in the robot: calibrate with this \
                     data, or let `kinecal iso9283 log` re-estimate it"
                )));
            }
            Ok((position, rotation))
        }
    }
}

/// A commanded pose: the position (m, global frame), and the attitude as ISO's `a, b, c` (rad;
/// kinecal's ZYX `gamma, beta, alpha`) when the pose was measured as a pose.
type Commanded = (Vector3<f64>, Option<Vector3<f64>>);

/// The commanded pose of each test's pose (by test label and pose number): where `robot`'s
/// model puts the measured target at the mean readings of the pose's cycles, with an attitude
/// when its first measurement is a pose. An error when a pose was measured at two targets.
fn commanded_poses(
    robot: &Robot,
    data: &Dataset,
    measured: &[Measured],
) -> Result<BTreeMap<(String, usize), Commanded>> {
    let chain = Chain::new(robot);
    let mut commanded = BTreeMap::new();
    for (key, members) in &by_test_and_pose(measured) {
        let first = &measured[members[0]];
        if let Some(other) = members
            .iter()
            .find(|&&k| measured[k].target != first.target)
        {
            return Err(Error::Problem(format!(
                "test `{}`: {} is measured at two targets (lines {} and {})",
                key.0,
                pose_name(key.1),
                first.line,
                measured[*other].line
            )));
        }
        let mean = mean_readings(robot.dof(), data, measured, members);
        let f = chain.frame_at(&mean, first.target);
        let e = euler_zyx(&f.rotation);
        commanded.insert(
            key.clone(),
            (
                f.translation,
                first.rotation.map(|_| Vector3::new(e.z, e.y, e.x)),
            ),
        );
    }
    Ok(commanded)
}

/// The measurements of each test's pose (indices into `measured`, in order), by test label and
/// pose number.
fn by_test_and_pose(measured: &[Measured]) -> BTreeMap<(String, usize), Vec<usize>> {
    let mut groups: BTreeMap<(String, usize), Vec<usize>> = BTreeMap::new();
    for (k, r) in measured.iter().enumerate() {
        groups
            .entry((r.role.test.clone(), r.role.pose))
            .or_default()
            .push(k);
    }
    groups
}

/// The mean of the joint readings (transducer units, `dof` of them) of the postures of the
/// measurements `members` (indices into `measured`).
fn mean_readings(dof: usize, data: &Dataset, measured: &[Measured], members: &[usize]) -> Vec<f64> {
    let mut mean = vec![0.0; dof];
    for &k in members {
        for (m, v) in mean
            .iter_mut()
            .zip(&data.postures[measured[k].posture].readings)
        {
            *m += v / members.len() as f64;
        }
    }
    mean
}

/// The log's rows, one per measurement in order, in `units` (the robot file's): the commanded
/// pose of its test's pose, the attained pose measured (its attitude only with a commanded
/// one), and the posture's readings.
fn log_rows(
    units: Units,
    data: &Dataset,
    measured: &[Measured],
    commanded: &BTreeMap<(String, usize), Commanded>,
) -> Vec<LogRow> {
    let l = |v: f64| units.from_si(Quantity::Length, v);
    let a = |v: f64| units.from_si(Quantity::Angle, v);
    let mut out = Vec::with_capacity(measured.len());
    for r in measured {
        let (c, c_abc) = commanded[&(r.role.test.clone(), r.role.pose)];
        let commanded_attitude = c_abc.map(|v| [a(v.x), a(v.y), a(v.z)]);
        let attained_attitude = r
            .rotation
            .zip(commanded_attitude)
            .map(|(rot, ca)| attained_abc(&rot, ca, units));
        let readings = data.postures[r.posture].readings.clone();
        out.push(LogRow {
            line: r.line,
            test: Some(r.role.test.clone()),
            pose: r.role.pose,
            cycle: r.role.cycle,
            commanded: [l(c.x), l(c.y), l(c.z)],
            commanded_attitude,
            attained: [l(r.position.x), l(r.position.y), l(r.position.z)],
            attained_attitude,
            direction: None,
            readings: Some(readings),
        });
    }
    out
}

/// A measured rotation (global frame) as ISO's `a, b, c` (kinecal's ZYX `gamma, beta, alpha`)
/// in `units`' angle unit, each angle within half a turn of the commanded one `commanded` (same
/// unit).
fn attained_abc(rotation: &Matrix3<f64>, commanded: [f64; 3], units: Units) -> [f64; 3] {
    let a = |v: f64| units.from_si(Quantity::Angle, v);
    let turn = full_turn(units.angle);
    let e = euler_zyx(rotation);
    let abc = [a(e.z), a(e.y), a(e.x)];
    std::array::from_fn(|k| {
        let d = abc[k] - commanded[k];
        commanded[k] + d - turn * (d / turn).round()
    })
}

/// A whole turn in `unit`: 360 deg, or `2 pi` rad.
fn full_turn(unit: AngleUnit) -> f64 {
    match unit {
        AngleUnit::Deg => 360.0,
        _ => std::f64::consts::TAU,
    }
}

/// What [`log_placed`] made: the log, the measured postures left out (no role), and the sessions
/// whose measurement frame was placed on the data.
#[derive(Debug, Clone, PartialEq)]
pub struct PlacedLog {
    /// The log ([`log_from_measurements`]).
    pub log: Log,
    /// The labels of the measured postures without a role.
    pub left_out: Vec<String>,
    /// The sessions of the data the robot had no frame for, placed first.
    pub placed: Vec<String>,
}

/// [`log_from_measurements`] after placing the measurement frame of every session of `data`
/// that `robot` has none for (6 parameters each, estimated on `data`, the robot held: as a
/// validation on another session does, [`crate::workflow::refit_sessions`]).
pub fn log_placed(robot: &Robot, data: &Dataset, roles: &Roles) -> Result<PlacedLog> {
    let placed: Vec<String> = data
        .sessions()
        .iter()
        .filter(|s| !robot.sessions.iter().any(|r| r.name == ***s))
        .map(|s| s.to_string())
        .collect();
    let model = if placed.is_empty() {
        robot.clone()
    } else {
        crate::workflow::refit_sessions(
            robot,
            data,
            &placed,
            &crate::solve::estimation::CalibrationOptions::new(Vec::new()),
        )
    };
    let (log, left_out) = log_from_measurements(&model, data, roles)?;
    Ok(PlacedLog {
        log,
        left_out,
        placed,
    })
}

/// Adds to every pose of `evaluation` (of `log`) the accuracy `predictor`'s calibration
/// predicts once the program is compensated (see the module's documentation), and summarizes
/// again. The log must be in the robot's global frame and state its length unit (the
/// calibrated robot's file units are converted); readings from the log (their mean over the
/// pose's cycles), otherwise the calibrated model's inverse kinematics of the commanded pose
/// (an error when it does not reach it inside the joint ranges).
pub fn predict_compensated(
    evaluation: &mut Evaluation,
    log: &Log,
    predictor: &Predictor<'_>,
    target: Target,
) -> Result<()> {
    let robot = predictor.robot();
    let Some(lu) = log.length_unit else {
        return Err(Error::Problem(format!(
            "{} states no length unit: a prediction needs the log's lengths in a known unit \
             (give --length-unit, or write `# length_unit = mm` before the header)",
            log.file
        )));
    };
    let to_m = |v: f64| v * lu.metres();
    let from_m = |v: f64| v / lu.metres();
    let mut scratch = predictor.scratch();
    let n = robot.dof();
    for p in &mut evaluation.poses {
        let rows: Vec<&LogRow> = log
            .rows
            .iter()
            .filter(|r| r.test == p.test && r.pose == p.pose)
            .collect();
        let logged: Option<Vec<&Vec<f64>>> = rows.iter().map(|r| r.readings.as_ref()).collect();
        let (readings, from) = match logged {
            Some(all) if !all.is_empty() => {
                if let Some(bad) = all.iter().find(|r| r.len() != n) {
                    return Err(Error::Problem(format!(
                        "{}: {} has {} readings, the robot {n} joints",
                        log.file,
                        pose_name(p.pose),
                        bad.len()
                    )));
                }
                let mut mean = vec![0.0; n];
                for r in &all {
                    for (m, v) in mean.iter_mut().zip(r.iter()) {
                        *m += v / all.len() as f64;
                    }
                }
                (mean, "log")
            }
            _ => {
                let attitude = match (p.commanded_attitude, log.angle_unit) {
                    (Some(c), Some(au)) => Some(c.map(|v| v * au.radians())),
                    _ => None,
                };
                let mut reacher = Reacher::new(robot, attitude)?;
                let goal = p.commanded.map(to_m);
                let Some(t) = reacher.reach(goal) else {
                    return Err(Error::Problem(format!(
                        "{}: the calibrated robot does not reach {}{} (commanded at {:?} in {lu}) \
                         inside its joint ranges: is the log in the robot's base frame?",
                        log.file,
                        p.test
                            .as_deref()
                            .map(|t| format!("test `{t}` "))
                            .unwrap_or_default(),
                        pose_name(p.pose),
                        p.commanded
                    )));
                };
                (t.readings, "inverse kinematics")
            }
        };
        if readings.iter().any(|v| !v.is_finite()) {
            return Err(Error::Problem(format!(
                "{}: {} has a reading that is not finite",
                log.file,
                pose_name(p.pose)
            )));
        }
        let pr = predictor.predict(&readings, target, &mut scratch);
        let b = pr.position_error;
        p.compensated = Some(Compensated {
            ap_rms: from_m(b.parameters.hypot(b.model)),
            ap_95: from_m(b.bound),
            readings_from: from.to_string(),
        });
    }
    evaluation.summarize();
    Ok(())
}
