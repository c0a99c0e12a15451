//! Restarts of a fit that ended far from any calibration of the robot.
//!
//! A fit whose measured positions stay beyond 2 % of the robot's reach (RMS) after the solver
//! stopped ([`positions_unfit`]) is at a local minimum of a start far from the robot, or the data
//! are not this robot's. Ordinary fits never get here: nothing below runs unless that check
//! fires. When it does, the fit is run again from other starts and the lowest objective kept:
//!
//! 1. the nominal robot with its measurement and tool frames placed in closed form
//!    ([`register`]), when the run started elsewhere (an initial guess);
//! 2. the local minimum itself with its frames placed again in closed form;
//! 3. [`SPREAD_STARTS`] well-spread starts: the given start's estimated lengths moved by a tenth
//!    of the reach and its angles by half a radian (normal draws from a fixed seed, so that the
//!    same run tries the same starts), each placed in closed form.
//!
//! What was tried goes into a [`Warning::Restarted`]. When every start ends unfit, the kept fit's
//! termination says so ([`Termination::LocalMinimum`]): it is not called converged.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use crate::error::Result;
use crate::model::robot::Robot;
use crate::observe::Dataset;
use crate::solve::estimation::{Calibration, Termination};
use crate::solve::registration::register;
use crate::units::Quantity;
use crate::warning::{StartTried, Warning};

use super::progress::Progress;

/// How many well-spread starts are tried after the closed-form placements.
pub const SPREAD_STARTS: u64 = 8;

/// The seed of the spread starts' draws (fixed: a run tries the same starts each time).
const SPREAD_SEED: u64 = 0x6b69_6e65;

/// The spread of the well-spread starts: lengths by this fraction of the robot's reach,
/// angles by [`SPREAD_ANGLE`] (one standard deviation).
const SPREAD_LENGTH: f64 = 0.1;

/// The angular spread of the well-spread starts (rad, one standard deviation).
const SPREAD_ANGLE: f64 = 0.5;

/// True when `cal`'s positions stay beyond [`crate::observe::sanity::POSITION_LIMIT`] of
/// `nominal`'s reach (RMS) after the fit: the check behind [`Warning::PositionsUnfit`].
pub(super) fn positions_unfit(nominal: &Robot, cal: &Calibration) -> bool {
    let reach = nominal.reach();
    cal.accuracy_after.positions > 0
        && reach > 0.0
        && cal.accuracy_after.rms_position > crate::observe::sanity::POSITION_LIMIT * reach
}

/// The starts to try after `cal` (fitted from `start`) ended unfit, each with its name.
fn other_starts(
    nominal: &Robot,
    start: &Robot,
    cal: &Calibration,
    data: &Dataset,
) -> Vec<(String, Robot)> {
    let estimate = &cal.estimated;
    let mut out = Vec::new();
    let differs = estimate
        .iter()
        .any(|&id| nominal.get(id).to_bits() != start.get(id).to_bits());
    if differs {
        let placed = register(nominal, data, estimate).map_or_else(|| nominal.clone(), |r| r.robot);
        out.push(("nominal placed".to_string(), placed));
    }
    if let Some(r) = register(&cal.calibrated, data, estimate) {
        out.push(("local minimum placed".to_string(), r.robot));
    }
    let reach = nominal.reach();
    let unit = Normal::new(0.0, 1.0).expect("a valid normal");
    for k in 1..=SPREAD_STARTS {
        let mut rng = ChaCha8Rng::seed_from_u64(SPREAD_SEED);
        rng.set_stream(k);
        let mut s = start.clone();
        for &id in estimate {
            let spread = match start.param_quantity(id) {
                Quantity::Length => SPREAD_LENGTH * reach,
                Quantity::Angle => SPREAD_ANGLE,
                _ => 0.0,
            };
            s.set(id, start.get(id) + spread * unit.sample(&mut rng));
        }
        if s.validate().is_err() {
            continue;
        }
        let s = register(&s, data, estimate).map_or(s, |r| r.robot);
        out.push((format!("spread {k}"), s));
    }
    out
}

/// `cal` (fitted from `start` by `fit`) when its positions fit; otherwise the fit with the lowest
/// objective among it and the fits from the other starts (see the module documentation), with a
/// [`Warning::Restarted`] saying what was tried. The kept fit keeps `cal`'s start (its
/// `initial`, objective and errors before) and counts every start's iterations; it is
/// [`Termination::LocalMinimum`] when every start ends unfit.
pub(super) fn restart_if_unfit(
    nominal: &Robot,
    start: &Robot,
    data: &Dataset,
    cal: Calibration,
    fit: &mut dyn FnMut(&Robot, &mut dyn Progress) -> Result<Calibration>,
    progress: &mut dyn Progress,
) -> Result<(Calibration, Option<Warning>)> {
    if !positions_unfit(nominal, &cal) {
        return Ok((cal, None));
    }
    let length = |v: f64| nominal.units.from_si(Quantity::Length, v);
    let tried = |name: &str, c: &Calibration| StartTried {
        start: name.to_string(),
        objective: c.total_objective(),
        rms_position: length(c.accuracy_after.rms_position),
        converged: c.converged(),
    };
    let mut starts = vec![tried("given", &cal)];
    let mut iterations = cal.iterations;
    let (mut best, mut kept) = (cal.clone(), "given".to_string());
    for (name, s) in other_starts(nominal, start, &cal, data) {
        progress.say(&format!("restart from {name}"));
        // A start the model cannot evaluate (a non-finite residual) is skipped.
        let Ok(c) = fit(&s, progress) else { continue };
        starts.push(tried(&name, &c));
        iterations += c.iterations;
        if c.total_objective() < best.total_objective() {
            (best, kept) = (c, name);
        }
    }
    best.iterations = iterations;
    best.initial = cal.initial;
    best.objective_before = cal.objective_before;
    best.accuracy_before = cal.accuracy_before;
    best.errors_before = cal.errors_before;
    best.start_r = cal.start_r;
    if positions_unfit(nominal, &best) && best.converged() {
        best.termination = Termination::LocalMinimum;
    }
    Ok((best, Some(Warning::Restarted { starts, kept })))
}
