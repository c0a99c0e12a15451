//! The rank the thesis's formulas predict (eqs. 4.2, 4.3, 4.5), generalised to trees, couplings
//! and planes.

use crate::model::kinematics::Target;
use crate::model::params::{LinkComponent, ParamId, ParamKind, PlaneComponent};
use crate::model::robot::{JointKind, Robot};
use crate::observe::{Anchoring, Dataset};
use crate::units::Quantity;

use super::ExpectedRank;

/// The thesis's predicted rank for estimating `params` on `data`, generalised to coupled joints,
/// planes and observations that do not fix the robot's placement; `None` when its assumptions
/// fail.
///
/// Assumptions: every link parameter and joint offset on the way to an observed frame estimated,
/// the six parameters of every observed site estimated (of a frame observed only as a point,
/// its position parameters suffice), and each plane touched either fully estimated or fully
/// fixed. Then each revolute joint that some observed frame hangs past contributes 4, each such
/// prismatic one 2 (eq. 4.3; in a tree, a branch no observation sees contributes nothing, and
/// the shared joints count once), each estimated slope or coupling factor 1 (eq. 4.2), each
/// observed frame 6 when a pose of it
/// is measured or 3 when only its origin is (positions, distances, contacts; eq. 4.5), and each
/// estimated plane 3. From this, the motions of the whole world that change no observation are
/// subtracted: none when some observation is in the global frame (poses, positions); otherwise
/// the rigid motions that keep every fixed plane touched in place: 6 with none (distances
/// only), 3 with one normal direction (slides in the plane and turns about its normal), 1 with
/// two (slides along their intersection), 0 with three independent normals.
pub fn expected_rank(robot: &Robot, data: &Dataset, params: &[ParamId]) -> Option<ExpectedRank> {
    let has = |id: ParamId| params.binary_search(&id).is_ok();
    let (nl, nj) = (robot.links.len(), robot.dof());
    // The degrees of freedom observed of a frame (0, 3 or 6).
    let seen = data.observed_dofs();
    // A frame observed as a point needs only its position parameters: its angles change nothing.
    let needed = |dof: usize, c: LinkComponent| dof == 6 || c.quantity() == Quantity::Length;
    let ee = seen(Target::EndEffector);
    // The joints some observed frame hangs past (all of them for a serial robot whose end
    // effector is observed): in a tree, a branch no observation sees adds nothing.
    let mut observed = vec![false; nj];
    let mut any = false;
    for t in std::iter::once(Target::EndEffector).chain((0..robot.sites.len()).map(Target::Site)) {
        if seen(t) > 0 {
            any = true;
            let path = robot.path_to(crate::model::kinematics::target_joint(robot, t));
            for (o, p) in observed.iter_mut().zip(path) {
                *o |= p;
            }
        }
    }
    let link_observed = |i: usize| observed.get(i).copied().unwrap_or(ee > 0);
    let all_links = (0..6 * nl).all(|i| {
        has(ParamId(i))
            || !link_observed(i / 6)
            || (i / 6 == nl - 1 && !needed(ee, LinkComponent::ALL[i % 6]))
    });
    let all_offsets = (0..nj)
        .filter(|&j| observed[j])
        .all(|j| has(robot.param_id(ParamKind::Offset { joint: j })));
    if !(all_links && all_offsets && any) {
        return None;
    }
    let nr = (0..nj)
        .filter(|&j| observed[j] && robot.joints[j].kind == JointKind::Revolute)
        .count();
    let np = (0..nj).filter(|&j| observed[j]).count() - nr;
    let slopes = (0..nj)
        .filter(|&j| observed[j] && has(robot.param_id(ParamKind::Slope { joint: j })))
        .count();
    let couplings = robot
        .coupled_joints()
        .filter(|&j| observed[j] && has(robot.param_id(ParamKind::Coupling { joint: j })))
        .count();
    let mut frames = Vec::new();
    let mut targets: Vec<Target> = vec![Target::EndEffector];
    targets.extend((0..robot.sites.len()).map(Target::Site));
    for t in targets {
        let dof = seen(t);
        if dof == 0 {
            continue;
        }
        if let Target::Site(s) = t {
            let all = LinkComponent::ALL.iter().all(|&component| {
                has(robot.param_id(ParamKind::Site { site: s, component }))
                    || !needed(dof, component)
            });
            if !all {
                return None;
            }
        }
        frames.push(dof);
    }
    let mut absolute = false;
    let mut touched: Vec<usize> = Vec::new();
    for o in &data.observations {
        match o.anchoring() {
            Anchoring::Absolute => absolute = true,
            Anchoring::Relative => {}
            Anchoring::Plane(k) => {
                if !touched.contains(&k) {
                    touched.push(k);
                }
            }
        }
    }
    touched.sort();
    let mut estimated_planes = 0;
    let mut fixed_normals = Vec::new();
    for &k in &touched {
        let n = PlaneComponent::ALL
            .iter()
            .filter(|&&component| {
                has(robot.param_id(ParamKind::Plane {
                    plane: k,
                    component,
                }))
            })
            .count();
        match n {
            3 => estimated_planes += 1,
            0 => fixed_normals.push(robot.planes[k].normal()),
            _ => return None,
        }
    }
    let free_motions = if absolute {
        0
    } else {
        match independent_directions(&fixed_normals) {
            0 => 6,
            1 => 3,
            2 => 1,
            _ => 0,
        }
    };
    let positive =
        4 * nr + 2 * np + slopes + couplings + frames.iter().sum::<usize>() + 3 * estimated_planes;
    let rank = positive.checked_sub(free_motions)?;
    let frame_terms: Vec<String> = frames.iter().map(|f| f.to_string()).collect();
    let mut formula = format!(
        "4*{nr} (revolute) + 2*{np} (prismatic) + {slopes} (slopes) + {} (observed frames: 6 per pose, 3 per point)",
        frame_terms.join(" + ")
    );
    if couplings > 0 {
        formula.push_str(&format!(" + {couplings} (couplings)"));
    }
    if estimated_planes > 0 {
        formula.push_str(&format!(" + 3*{estimated_planes} (planes)"));
    }
    if free_motions > 0 {
        formula.push_str(&format!(
            " - {free_motions} (motions of the world no observation sees: {})",
            match free_motions {
                6 => "no observation in the global frame",
                3 => "sliding in the touched plane and turning about its normal",
                _ => "sliding along the touched planes' intersection",
            }
        ));
    }
    formula.push_str(&format!(" = {rank}"));
    Some(ExpectedRank { rank, formula })
}

/// The number of linearly independent directions among unit vectors (0 to 3).
fn independent_directions(normals: &[nalgebra::Vector3<f64>]) -> usize {
    let Some(a) = normals.first() else { return 0 };
    let Some(b) = normals.iter().find(|n| a.cross(n).norm() > 1e-6) else {
        return 1;
    };
    let c = a.cross(b);
    if normals.iter().any(|n| c.dot(n).abs() > 1e-6 * c.norm()) {
        3
    } else {
        2
    }
}
