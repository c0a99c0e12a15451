//! Which parameters to estimate: a [`Selection`] and what it stands for on a dataset (the default
//! set, a list, or the identifiable set of one), and the measurement frames of a dataset's
//! sessions.

use crate::error::{Error, Result};
use crate::identifiability::{self, AnalysisOptions};
use crate::model::param_list::parse_param_list;
use crate::model::params::{ParamId, ParamKind};
use crate::model::robot::Robot;
use crate::observe::Dataset;
use crate::solve::estimation::{self, CalibrationOptions, Loss};
use crate::solve::problem::Linearized;

/// Which parameters to estimate.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Selection {
    /// The default set (see [`default_parameters`]) minus `fix`.
    Default {
        /// Parameters held.
        fix: Vec<ParamId>,
    },
    /// These parameters.
    List(Vec<ParamId>),
    /// The identifiable (base) set of the default parameters and `with`, minus `fix`, as the
    /// data at the reference robot determines it (see [`crate::identifiability`]).
    Identifiable {
        /// Parameters added to the default set before the selection (`identifiable,slopes`).
        with: Vec<ParamId>,
        /// Parameters held.
        fix: Vec<ParamId>,
    },
}

impl Default for Selection {
    fn default() -> Self {
        Selection::Default { fix: Vec::new() }
    }
}

impl Selection {
    /// Parses a parameter list (see [`crate::model::param_list`]) and the parameters to hold. An empty
    /// list is the default set. The keyword `identifiable` asks for the identifiable set of the
    /// union of the default set and the other entries: `identifiable` alone is that of the
    /// default set, `identifiable,slopes` adds the slopes first, `all,identifiable` is that of
    /// every parameter.
    pub fn parse(estimate: &str, fix: Option<&str>, robot: &Robot) -> Result<Selection> {
        let tokens: Vec<&str> = if estimate.trim().is_empty() {
            Vec::new()
        } else {
            estimate.split(',').map(str::trim).collect()
        };
        let identifiable = tokens.contains(&"identifiable");
        let rest: Vec<&str> = tokens
            .iter()
            .copied()
            .filter(|t| *t != "identifiable")
            .collect();
        let listed = if rest.is_empty() {
            Vec::new()
        } else {
            parse_param_list(&rest.join(","), robot)?
        };
        let fix = match fix {
            Some(f) => parse_param_list(f, robot)?,
            None => Vec::new(),
        };
        Ok(if identifiable {
            Selection::Identifiable { with: listed, fix }
        } else if rest.is_empty() {
            Selection::Default { fix }
        } else {
            let mut ids = listed;
            ids.retain(|id| !fix.contains(id));
            if ids.is_empty() {
                // Say why: a group this robot has none of, or everything listed also fixed.
                let empty: Vec<&str> = rest
                    .iter()
                    .map(|t| t.trim())
                    .filter(|t| parse_param_list(t, robot).is_ok_and(|v| v.is_empty()))
                    .collect();
                let message = if empty.is_empty() {
                    "no parameter is left to estimate (every listed parameter is also fixed)"
                        .to_string()
                } else {
                    format!(
                        "no parameter to estimate: this robot has no {} (none declared in its file)",
                        empty
                            .iter()
                            .map(|g| match *g {
                                "couplings" => "coupled joints",
                                "planes" => "planes",
                                "sites" => "sites",
                                g => g,
                            })
                            .collect::<Vec<_>>()
                            .join(", ")
                    )
                };
                return Err(Error::ParamList {
                    list: estimate.to_string(),
                    message,
                });
            }
            Selection::List(ids)
        })
    }
}

/// Why a total mass (`--total-mass`, `total_mass`) cannot be held with `selection` on `robot`:
/// the total holds the estimated masses, and this selection estimates none (the default set
/// never does: masses are asked for, `masses` or `body2.mass`). `None` when some mass may be
/// estimated. The identifiable set of a selection with masses may still keep none of them:
/// the report's prior then says `on 0 parameters`.
pub(crate) fn total_mass_problem(selection: &Selection, robot: &Robot) -> Option<String> {
    let mass = |id: &&ParamId| is_mass(robot, **id);
    let (some, what) = match selection {
        Selection::Default { .. } => (false, "the default parameters keep the robot file's masses"),
        Selection::List(ids) => (ids.iter().any(|id| mass(&id)), "the list names no mass"),
        Selection::Identifiable { with, fix } => (
            with.iter()
                .filter(|id| !fix.contains(id))
                .any(|id| mass(&id)),
            "the selection adds no mass to the default parameters",
        ),
    };
    (!some).then(|| {
        format!(
            "the total mass holds the sum of the estimated bodies' masses, and no mass is \
             estimated ({what}): estimate them (`masses`, or `body2.mass`, ...) or leave the \
             total mass out"
        )
    })
}

/// Whether `id` is a body's mass on `robot`.
fn is_mass(robot: &Robot, id: ParamId) -> bool {
    matches!(
        robot.try_param_kind(id),
        Some(ParamKind::Body {
            component: crate::model::params::BodyComponent::Mass,
            ..
        })
    )
}

/// Refuses a total mass (`--total-mass`, `total_mass`) that `estimate`, the parameters an
/// identifiable `selection` came to (`how`: the analysis that chose them), holds nothing of:
/// the selection names masses ([`total_mass_problem`] passed it), but the identifiability
/// analysis kept none of them, and the total would be dropped without a word (the report's
/// prior said `on 0 parameters`). `Ok` when a mass is estimated or no total is given.
pub(crate) fn check_total_mass_kept(
    total_mass: Option<f64>,
    selection: &Selection,
    estimate: &[ParamId],
    robot: &Robot,
    how: &str,
) -> Result<()> {
    if total_mass.is_none() || estimate.iter().any(|&id| is_mass(robot, id)) {
        return Ok(());
    }
    let named: Vec<String> = match selection {
        Selection::Identifiable { with, fix } => with
            .iter()
            .filter(|&&id| is_mass(robot, id) && !fix.contains(&id))
            .map(|&id| robot.param_name(id))
            .collect(),
        Selection::List(ids) => ids
            .iter()
            .filter(|&&id| is_mass(robot, id))
            .map(|&id| robot.param_name(id))
            .collect(),
        Selection::Default { .. } => Vec::new(),
    };
    Err(Error::InvalidOption {
        setting: crate::error::Setting::TotalMass,
        message: format!(
            "the total mass holds the sum of the estimated bodies' masses, and {how} keeps none \
             of the masses the selection names ({}): the data do not determine them (a mass \
             shows only through the deflections it causes, so it needs joints whose compliances \
             are not 0 and postures that load them); measure such postures, or leave the total \
             mass out",
            named.join(", ")
        ),
    })
}

/// The parameters a selection stands for on `data`, analysed at `robot` with `opts` (sorted),
/// and the default parameters left out because no observation sees them.
pub fn resolve(
    selection: &Selection,
    robot: &Robot,
    data: &Dataset,
    opts: &AnalysisOptions,
) -> Result<(Vec<ParamId>, Vec<ParamId>)> {
    resolve_linearized(selection, robot, data, opts).map(|r| (r.estimate, r.unseen))
}

/// What [`resolve_linearized`] found: the parameters to estimate (sorted), the default ones no
/// observation sees, the identifiability analysis's linearisation at the robot when it ran (a
/// fit starting there needs no first pass), and the parameters the analysis kept only because
/// the start placed them ([`identifiability::Analysis::placed_loose`]).
pub(super) struct Resolved {
    pub estimate: Vec<ParamId>,
    pub unseen: Vec<ParamId>,
    pub lin: Option<Linearized>,
    pub placed_loose: Vec<(ParamId, f64)>,
}

/// [`resolve`], with what else the identifiability analysis found (see [`Resolved`]).
pub(super) fn resolve_linearized(
    selection: &Selection,
    robot: &Robot,
    data: &Dataset,
    opts: &AnalysisOptions,
) -> Result<Resolved> {
    let mut lin = None;
    let mut placed_loose = Vec::new();
    let (mut ids, unseen) = match selection {
        Selection::Default { fix } => {
            let (mut ids, unseen) = default_parameters(robot, data);
            ids.retain(|id| !fix.contains(id));
            (ids, unseen)
        }
        Selection::List(ids) => (ids.clone(), Vec::new()),
        Selection::Identifiable { with, fix } => {
            let (mut ids, unseen) = default_parameters(robot, data);
            ids.extend(with.iter().copied());
            ids.sort();
            ids.dedup();
            ids.retain(|id| !fix.contains(id));
            if ids.is_empty() {
                return Err(Error::NothingToEstimate);
            }
            let (analysis, at) = identifiability::analyze_linearized(robot, data, &ids, opts)?;
            lin = Some(at);
            placed_loose = analysis.placed_loose;
            (analysis.identifiable, unseen)
        }
    };
    ids.sort();
    ids.dedup();
    if ids.is_empty() {
        return Err(Error::NothingToEstimate);
    }
    Ok(Resolved {
        estimate: ids,
        unseen,
        lin,
        placed_loose,
    })
}

/// The default parameters on `data`: every link and site parameter and every joint offset, and
/// the slopes unless every slope is 1 in the file's units (readings that are already joint
/// values); coupling factors and planes only when named. Left out, and returned second, are the
/// parameters of frames no observation sees: a site or the end effector never observed (their
/// link's six), or observed by position only (its three angles).
pub fn default_parameters(robot: &Robot, data: &Dataset) -> (Vec<ParamId>, Vec<ParamId>) {
    use crate::model::kinematics::Target;
    use crate::model::params::LinkComponent;
    let unit_slopes = robot
        .joints
        .iter()
        .all(|j| (robot.units.from_si(j.kind.slope(), j.slope) - 1.0).abs() < 1e-12);
    // The degrees of freedom observed of a frame (0, 3 or 6).
    let seen = data.observed_dofs();
    let ee = seen(Target::EndEffector);
    let last = robot.links.len() - 1;
    let unseen_component = |dof: usize, c: LinkComponent| {
        dof == 0 || (dof < 6 && c.quantity() == crate::units::Quantity::Angle)
    };
    let pixels: Vec<(usize, Option<usize>)> = data
        .observations
        .iter()
        .filter_map(|o| match o {
            crate::observe::Observation::Pixel(p) => Some((
                p.camera,
                match p.seen {
                    crate::observe::pixel::Seen::Board { board, .. } => Some(board),
                    crate::observe::pixel::Seen::Target(_) => None,
                },
            )),
            _ => None,
        })
        .collect::<std::collections::BTreeSet<_>>()
        .into_iter()
        .collect();
    let (mut ids, mut unseen) = (Vec::new(), Vec::new());
    for id in robot.param_ids() {
        let default = match robot.param_kind(id) {
            ParamKind::Link { link, component } => {
                if link == last && unseen_component(ee, component) {
                    unseen.push(id);
                    false
                } else {
                    true
                }
            }
            ParamKind::Site { site, component } => {
                if unseen_component(seen(Target::Site(site)), component) {
                    unseen.push(id);
                    false
                } else {
                    true
                }
            }
            ParamKind::Offset { .. } => true,
            ParamKind::Slope { .. } => !unit_slopes,
            // Compliances are asked for (`compliance`, `lateral`): the default is the rigid
            // geometry, with the robot file's compliances held.
            ParamKind::Coupling { .. }
            | ParamKind::Plane { .. }
            | ParamKind::Compliance { .. }
            | ParamKind::Lateral { .. }
            | ParamKind::Body { .. } => false,
            // A session's frame is estimated wherever its observations are.
            ParamKind::Session { session, .. } => {
                let name = robot.sessions[session].name.as_str();
                data.postures
                    .iter()
                    .any(|p| p.session.as_deref() == Some(name))
            }
            // So are the poses of the cameras and boards pixels see (the hand-eye); a lens is
            // asked for (`intrinsics`, `cameras`).
            ParamKind::Camera { camera, component } => {
                !component.is_intrinsic() && pixels.iter().any(|&(c, _)| c == camera)
            }
            ParamKind::Board { board, .. } => pixels.iter().any(|&(_, b)| b == Some(board)),
        };
        if default {
            ids.push(id);
        }
    }
    (ids, unseen)
}

/// `robot` with frames for the sessions `names` of `data`, placed in closed form and then
/// estimated on `data` (their six parameters each, the robot held, with `opts`' weights and
/// residuals): how a robot is checked on data measured from somewhere it has not been told.
pub fn refit_sessions(
    robot: &Robot,
    data: &Dataset,
    names: &[String],
    opts: &CalibrationOptions,
) -> Robot {
    let mut r = robot.clone();
    let first = r.sessions.len();
    for name in names {
        r.sessions.push(crate::model::robot::Session {
            name: name.clone(),
            frame: crate::model::robot::Link::default(),
        });
    }
    let ids: Vec<ParamId> = r
        .param_ids()
        .filter(|&id| matches!(r.param_kind(id), ParamKind::Session { session, .. } if session >= first))
        .collect();
    if let Some((placed, _, _)) = crate::solve::registration::place_sessions(&r, data, &ids) {
        r = placed;
    }
    let fit = CalibrationOptions {
        estimate: ids,
        solver: opts.solver,
        weights: opts.weights,
        orientation: opts.orientation,
        loss: Loss::Squared,
        prior: crate::model::robot::Prior::default(),
        model_error: opts.model_error,
    };
    match estimation::calibrate(&r, data, &fit, &mut |_| {}) {
        Ok(c) => c.calibrated,
        Err(_) => r,
    }
}

/// `robot` with a measurement frame for each session of `data` that needs one and it lacks:
/// every session but the first (in data order) when every posture has a session, every session
/// otherwise (the postures without one are in the global frame); `None` when none is missing.
/// A frame starts at the identity, to be placed in closed form and estimated.
pub(crate) fn session_frames_for(robot: &Robot, data: &Dataset) -> Option<Robot> {
    let sessions = data.sessions();
    let unframed: Vec<&std::sync::Arc<str>> = sessions
        .iter()
        .filter(|s| robot.session_index(s).is_none())
        .collect();
    let all_in_sessions = data.postures.iter().all(|p| p.session.is_some());
    // The global frame is the first session's unless some posture is in none, or the robot
    // already frames some session (then the global frame is the robot's own).
    let skip = usize::from(all_in_sessions && robot.sessions.is_empty());
    let new: Vec<&std::sync::Arc<str>> = unframed.into_iter().skip(skip).collect();
    if new.is_empty() {
        return None;
    }
    let mut r = robot.clone();
    for name in new {
        r.sessions.push(crate::model::robot::Session {
            name: name.to_string(),
            frame: crate::model::robot::Link::default(),
        });
    }
    Some(r)
}
