//! Gaussian priors as users write them: `length=L,angle=A,slope=F,compliance=C` and
//! per-parameter entries `NAME=V` (the robot file's units; slopes and coupling factors as a
//! fraction of their value), on the command line (`--prior`), in a calibration spec
//! (`selection.prior`), in Python (`prior=`) and, key by key, in a robot file's `[priors]` table
//! (the same keys as `[tolerances]`, plus `compliance`). Two words stand for whole priors:
//! `tolerances` (the robot file's `[tolerances]`, read as standard deviations) and `none`.
//!
//! What a prior does to a calibration (one residual row per estimated parameter with a prior)
//! is said in [`crate::solve::problem`]; the type is [`Prior`].

use crate::error::{Error, Result, Setting};
use crate::model::params::ParamId;
use crate::model::robot::{Prior, Robot};
use crate::units::{number::format_number, Quantity};

/// The group keys of a prior, in the order [`describe`] writes them.
pub(crate) const GROUPS: [&str; 4] = ["length", "angle", "slope", "compliance"];

/// Sets one key of `prior` (a group or a parameter, `value` in the robot file's units), or says
/// what is wrong with it (the caller names the key).
pub(crate) fn set_key(
    prior: &mut Prior,
    key: &str,
    value: f64,
    robot: &Robot,
) -> std::result::Result<(), String> {
    if !(value.is_finite() && value > 0.0) {
        return Err(format!(
            "a prior's standard deviation must be positive and finite, not {value}"
        ));
    }
    let u = robot.units;
    match key {
        "length" => prior.length = Some(u.to_si(Quantity::Length, value)),
        "angle" => prior.angle = Some(u.to_si(Quantity::Angle, value)),
        "slope" => prior.slope = Some(value),
        "compliance" => prior.compliance = Some(u.to_si(Quantity::Compliance, value)),
        name => {
            let id = crate::model::param_list::parse_param(name, robot).map_err(|e| {
                format!("{e} (expected length, angle, slope, compliance or a parameter)")
            })?;
            let si = u.to_si(robot.param_quantity(id), value);
            prior.overrides.retain(|(p, _)| *p != id);
            prior.overrides.push((id, si));
        }
    }
    Ok(())
}

/// Holds the bodies' total mass at `total` kg ([`Prior::total_mass`]), or says why it cannot:
/// not a mass, or a robot without bodies.
pub(crate) fn set_total_mass(
    prior: &mut Prior,
    total: f64,
    robot: &Robot,
) -> std::result::Result<(), String> {
    if !(total.is_finite() && total > 0.0 && total <= 1e6) {
        return Err(format!(
            "expected a mass in kg, above 0 and at most 1e6, not {total}"
        ));
    }
    if robot.body_count() == 0 {
        return Err(
            "the robot has no bodies to hold the total of (a mass model: [[bodies]] or \
                    [gravity] lumped_mass in the robot file)"
                .into(),
        );
    }
    prior.total_mass = Some(total);
    Ok(())
}

/// Parses a prior as written on the command line or in a spec: `none`, `tolerances`, or
/// comma-separated `KEY=VALUE` entries (groups and parameters, see the module
/// documentation). Errors name the entry, under [`Setting::Prior`].
pub fn parse_prior(text: &str, robot: &Robot) -> Result<Prior> {
    let bad = |message: String| Error::InvalidOption {
        setting: Setting::Prior,
        message,
    };
    match text.trim() {
        "none" => return Ok(Prior::default()),
        "tolerances" => return Ok(Prior::from_tolerances(&robot.tolerances)),
        "" => {
            return Err(bad(
                "empty: expected `length=L,angle=A[,slope=F][,compliance=C]`, `tolerances` or \
                 `none`"
                    .into(),
            ))
        }
        _ => {}
    }
    let mut prior = Prior::default();
    for entry in text.split(',').map(str::trim) {
        let Some((key, value)) = entry.split_once('=') else {
            return Err(bad(format!(
                "`{entry}`: expected KEY=VALUE (length, angle, slope, compliance or a parameter)"
            )));
        };
        let key = key.trim();
        let v: f64 = value
            .trim()
            .parse()
            .map_err(|_| bad(format!("`{key}`: `{}` is not a number", value.trim())))?;
        set_key(&mut prior, key, v, robot).map_err(|m| bad(format!("`{key}`: {m}")))?;
    }
    Ok(prior)
}

/// The prior as [`parse_prior`] reads it back, in the robot file's units (`none` for an empty
/// one): groups first, then parameters by name; a total mass (`--total-mass`, not a prior key)
/// follows in parentheses, `none (total mass 28 kg)`.
pub fn describe(prior: &Prior, robot: &Robot) -> String {
    if let Some(total) = prior.total_mass {
        let rest = Prior {
            total_mass: None,
            ..prior.clone()
        };
        return format!(
            "{} (total mass {} kg)",
            describe(&rest, robot),
            format_number(total)
        );
    }
    if prior.is_empty() {
        return "none".into();
    }
    let u = robot.units;
    let mut parts = Vec::new();
    for (key, value) in GROUPS.iter().zip([
        prior.length.map(|v| u.from_si(Quantity::Length, v)),
        prior.angle.map(|v| u.from_si(Quantity::Angle, v)),
        prior.slope,
        prior.compliance.map(|v| u.from_si(Quantity::Compliance, v)),
    ]) {
        if let Some(v) = value {
            parts.push(format!("{key}={}", format_number(v)));
        }
    }
    let mut overrides: Vec<&(ParamId, f64)> = prior.overrides.iter().collect();
    overrides.sort_by_key(|(id, _)| *id);
    for &&(id, v) in &overrides {
        let v = u.from_si(robot.param_quantity(id), v);
        parts.push(format!("{}={}", robot.param_name(id), format_number(v)));
    }
    parts.join(",")
}
