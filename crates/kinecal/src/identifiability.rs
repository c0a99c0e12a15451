//! Identifiability (thesis 3.4, 4.4.2-4.4.8): what the data can and cannot determine.
//!
//! Everything here works on the Jacobian of the estimated parameters over a dataset, in two
//! unit systems:
//! - *scaled*: residuals weighted by the measurement standard deviations and every column divided
//!   by its norm, the space the solvers work in (see [`crate::estimation`]); ranks, gaps and
//!   dependencies are decided here, where units cannot distort them;
//! - *file*: rows in the robot file's length and angle units, columns per unit of each parameter,
//!   as the thesis prints its Tables 4.3-4.7.
//!
//! ```
//! use kinecal::{examples, simulate, identifiability::{analyze, AnalysisOptions}};
//! let robot = examples::ge_a4();
//! let data = simulate::measure(&robot, &simulate::sample_postures(&robot, 30, 1), false);
//! let all: Vec<_> = robot.param_ids().collect();
//! let a = analyze(&robot, &data, &all, &AnalysisOptions::default()).unwrap();
//! assert_eq!(a.rank, 24); // 5 nr + 3 np + 6 (eq. 4.2)
//! assert_eq!(a.expected.unwrap().rank, 24);
//! ```

use crate::error::{Error, Result};
use crate::kinematics::Target;
use crate::linalg::{self, Matrix, QrAccumulator, QR_BLOCK};
use crate::observe::{Anchoring, Dataset, OrientationError, RowQuantity, Weights};
use crate::params::{LinkComponent, ParamId, ParamKind, PlaneComponent};
use crate::problem::{Linearized, Problem};
use crate::robot::{JointKind, Robot};
use crate::units::Quantity;
use crate::warning::Warning;

/// Settings of an analysis.
#[derive(Debug, Clone, PartialEq)]
pub struct AnalysisOptions {
    /// Relative tolerance: singular values of the scaled Jacobian below `rcond * s_max` count as
    /// zero.
    pub rcond: f64,
    /// Residual weights (as in calibration).
    pub weights: Weights,
    /// Orientation residual (as in calibration).
    pub orientation: OrientationError,
    /// Parameters to prefer in the identifiable set, most preferred first; the rest follow in the
    /// default order (see [`default_priority`]).
    pub priority: Vec<ParamId>,
}

/// Default relative singular-value tolerance for the numerical rank.
pub const DEFAULT_RANK_RCOND: f64 = 1e-9;

impl Default for AnalysisOptions {
    fn default() -> Self {
        AnalysisOptions {
            rcond: DEFAULT_RANK_RCOND,
            weights: Weights::default(),
            orientation: OrientationError::RotVec,
            priority: Vec::new(),
        }
    }
}

/// The rank the thesis's formulas predict (eqs. 4.2, 4.3, 4.5).
#[derive(Debug, Clone, PartialEq)]
pub struct ExpectedRank {
    /// The predicted number of independent parameters.
    pub rank: usize,
    /// How it was computed, e.g. `4*4 + 2*1 ... `.
    pub formula: String,
}

/// A set of parameters whose Jacobian columns are equal or opposite at every posture (thesis
/// 4.4.3): the data determines only one combination of them.
#[derive(Debug, Clone, PartialEq)]
pub struct IdenticalGroup {
    /// Members and the coefficients of the determined combination (file units, first member 1).
    pub terms: Vec<(ParamId, f64)>,
    /// Value of the combination for the analysed robot (file units).
    pub value: f64,
    /// Whether the data determines the combination. It does unless members also take part in
    /// other dependencies (then only a larger combination is determined).
    pub determined: bool,
}

/// The result of [`analyze`].
#[derive(Debug, Clone)]
pub struct Analysis {
    /// The analysed parameters, in order.
    pub parameters: Vec<ParamId>,
    /// Number of residuals.
    pub residuals: usize,
    /// Singular values of the scaled Jacobian (non-increasing).
    pub singular_values_scaled: Vec<f64>,
    /// Singular values of the Jacobian in file units.
    pub singular_values_file: Vec<f64>,
    /// Numerical rank: scaled singular values above `rcond * s_max`.
    pub rank: usize,
    /// The tolerance used.
    pub rcond: f64,
    /// Position of the largest gap in the scaled spectrum: the rank it suggests.
    pub gap_rank: usize,
    /// The gap's size, `s[gap_rank - 1] / s[gap_rank]` (infinite for an exact zero).
    pub gap_ratio: f64,
    /// Whether the rank from the tolerance and the largest gap agree (at full rank: no gap over
    /// 1e3 elsewhere); a warning says so when not.
    pub rank_consistent: bool,
    /// The thesis's count, when it applies to the analysed parameters.
    pub expected: Option<ExpectedRank>,
    /// Parameters with a zero column: no measurement feels them.
    pub unobservable: Vec<ParamId>,
    /// Identically redundant groups.
    pub identical_groups: Vec<IdenticalGroup>,
    /// A basis of the null space in reduced form: each entry is a direction (file units) along
    /// which the parameters can move without changing any prediction.
    pub null_space: Vec<Vec<(ParamId, f64)>>,
    /// An identifiable (base) parameter set: a maximal independent subset, by priority.
    pub identifiable: Vec<ParamId>,
    /// For each analysed parameter: whether the data determines it individually (it has no
    /// component in the null space).
    pub determined: Vec<bool>,
    /// Links or sites whose beta is near +-90 deg: alpha and gamma then act alike, a singularity
    /// of the Euler parameterisation rather than a physical redundancy.
    pub euler_singular: Vec<String>,
    /// Warnings (unclear gap, ...).
    pub warnings: Vec<Warning>,
    /// Column scale factors (norms of the weighted SI columns).
    pub column_norms: Vec<f64>,
    /// Right singular vectors of the scaled Jacobian (n x n), in the order of the singular
    /// values: columns `rank..` span the null space.
    pub right_singular_vectors: Matrix,
}

impl Analysis {
    /// Condition number over the numerical rank, `s_1 / s_rank` (scaled units).
    pub fn condition_number(&self) -> f64 {
        cond(&self.singular_values_scaled, self.rank)
    }

    /// The same in file units.
    pub fn condition_number_file(&self) -> f64 {
        cond(&self.singular_values_file, self.rank)
    }

    /// Whether parameter `id` (one of the analysed) is individually determined.
    pub fn is_determined(&self, id: ParamId) -> bool {
        self.parameters
            .iter()
            .position(|&p| p == id)
            .is_some_and(|k| self.determined[k])
    }
}

fn cond(s: &[f64], rank: usize) -> f64 {
    if rank == 0 {
        return f64::INFINITY;
    }
    s[0] / s[rank - 1]
}

/// The default preference for the identifiable set (thesis 4.4.3 and 4.4.7: keep parameters
/// that carry physical meaning): joint offsets, then slopes, then link lengths and angles that
/// are non-zero in the nominal model, then zero-valued link components (redundant copies), then
/// site parameters. Earlier is preferred.
pub fn default_priority(robot: &Robot) -> Vec<ParamId> {
    let mut ids: Vec<ParamId> = robot.param_ids().collect();
    ids.sort_by_key(|&id| (default_tier(robot, id), id));
    ids
}

/// The thesis's predicted rank for estimating `params` on `data`, generalised to coupled joints,
/// planes and observations that do not fix the robot's placement; `None` when its assumptions
/// fail.
///
/// Assumptions: every link parameter and joint offset estimated, the end effector observed, the
/// six parameters of every observed site estimated (of a frame observed only as a point, its
/// position parameters suffice), and each plane touched either fully estimated or fully fixed. Then each revolute joint contributes 4, each prismatic 2 (eq. 4.3),
/// each estimated slope or coupling factor 1 (eq. 4.2), each observed frame 6 when a pose of it
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
    let seen = |t: Target| {
        data.observations
            .iter()
            .filter(|o| o.measured_frame().0 == t)
            .map(|o| o.measured_frame().1)
            .max()
            .unwrap_or(0)
    };
    // A frame observed as a point needs only its position parameters: its angles change nothing.
    let needed = |dof: usize, c: LinkComponent| dof == 6 || c.quantity() == Quantity::Length;
    let ee = seen(Target::EndEffector);
    let all_links = (0..6 * nl)
        .all(|i| has(ParamId(i)) || (i / 6 == nl - 1 && !needed(ee, LinkComponent::ALL[i % 6])));
    let all_offsets = (0..nj).all(|j| has(robot.param_id(ParamKind::Offset { joint: j })));
    if !(all_links && all_offsets && ee > 0) {
        return None;
    }
    let nr = robot
        .joints
        .iter()
        .filter(|j| j.kind == JointKind::Revolute)
        .count();
    let np = nj - nr;
    let slopes = (0..nj)
        .filter(|&j| has(robot.param_id(ParamKind::Slope { joint: j })))
        .count();
    let couplings = robot
        .coupled_joints()
        .filter(|&j| has(robot.param_id(ParamKind::Coupling { joint: j })))
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

/// Analyses what `data` determines about `params` of `robot`.
pub fn analyze(
    robot: &Robot,
    data: &Dataset,
    params: &[ParamId],
    opts: &AnalysisOptions,
) -> Result<Analysis> {
    analyze_with(robot, data, params, opts, None, true).map(|(a, _)| a)
}

/// [`analyze`] without what only a display needs: the row labels, the file-unit Jacobian and
/// its singular values are left empty (the uncertainty needs none of them, and they cost an
/// m x n copy, a second factorization and a string per row).
pub(crate) fn analyze_core(
    robot: &Robot,
    data: &Dataset,
    params: &[ParamId],
    opts: &AnalysisOptions,
) -> Result<Analysis> {
    analyze_with(robot, data, params, opts, None, false).map(|(a, _)| a)
}

/// [`analyze_core`], keeping the linearisation it made at `robot` (for a solver that starts
/// there: its first evaluation then costs no pass).
pub(crate) fn analyze_linearized(
    robot: &Robot,
    data: &Dataset,
    params: &[ParamId],
    opts: &AnalysisOptions,
) -> Result<(Analysis, Linearized)> {
    let (analysis, lin) = analyze_with(robot, data, params, opts, None, false)?;
    let lin = lin.ok_or_else(|| Error::Numerical("no linearisation was made".into()))?;
    Ok((analysis, lin))
}

/// [`analyze_core`] from the `R` of the QR of the weighted `[J | r]` at `robot`, over `params`
/// in ascending order, already at hand (a solver's first evaluation at its start is one): no
/// pass of forward kinematics.
pub(crate) fn analyze_from_r(
    robot: &Robot,
    data: &Dataset,
    params: &[ParamId],
    opts: &AnalysisOptions,
    raug: &Matrix,
) -> Result<Analysis> {
    analyze_with(robot, data, params, opts, Some(raug), false).map(|(a, _)| a)
}

fn analyze_with(
    robot: &Robot,
    data: &Dataset,
    params: &[ParamId],
    opts: &AnalysisOptions,
    known_r: Option<&Matrix>,
    display: bool,
) -> Result<(Analysis, Option<Linearized>)> {
    let mut params = params.to_vec();
    params.sort();
    params.dedup();
    if params.is_empty() {
        return Err(Error::NothingToEstimate);
    }
    if let Some(bad) = params.iter().find(|id| id.0 >= robot.param_count()) {
        return Err(Error::Problem(format!(
            "parameter {bad} does not exist in this robot"
        )));
    }
    let n = params.len();
    data.check_orientation(robot, opts.orientation)?;
    let problem = Problem::new(robot, data, &params, opts.weights, opts.orientation);
    let m = problem.rows();
    // The weighted Jacobian is never held: its rows go into the R of a QR, a block at a time
    // (the same inner products between columns, n long instead of m; memory flat in m).
    let mut r = Vec::new();
    let mut acc = QrAccumulator::new(n + 1, QR_BLOCK);
    let mut raug = Matrix::zeros(0, 0);
    let mut accuracy = None;
    match known_r {
        Some(known) if known.nrows() == n + 1 && known.ncols() == n + 1 => raug = known.clone(),
        Some(_) => {
            return Err(Error::Numerical(
                "the given R does not match the parameters analysed".into(),
            ))
        }
        None => {
            r.resize(m, 0.0);
            accuracy = Some(problem.evaluate_qr_checked(robot, &mut r, &mut acc).1);
            acc.r_into(&mut raug);
        }
    }
    // R of [W J | W r]: its leading n x n block is the R of W J alone.
    let rw = Matrix::from_fn(n, n, |i, j| raug[(i, j)]);

    let units = robot.units;
    let col_factor: Vec<f64> = params
        .iter()
        .map(|&id| units.factor(robot.param_quantity(id)))
        .collect();

    let column_norms: Vec<f64> = (0..n).map(|j| linalg::col_norm(&rw, j)).collect();
    let max_norm = column_norms.iter().copied().fold(0.0, f64::max);
    let unobservable: Vec<ParamId> = (0..n)
        .filter(|&j| column_norms[j] <= 1e-12 * max_norm.max(1e-300))
        .map(|j| params[j])
        .collect();
    let mut r_scaled = rw;
    for (j, &c) in column_norms.iter().enumerate() {
        // Unobservable columns hold only rounding noise: zero them rather than blow it up.
        let s = if unobservable.contains(&params[j]) {
            0.0
        } else {
            1.0 / c
        };
        linalg::scale_col(&mut r_scaled, j, s);
    }
    // Singular values and right vectors of the scaled Jacobian are those of its R (n x n).
    let (s_scaled, v_scaled, _) = linalg::right_svd(&r_scaled)
        .ok_or_else(|| Error::Numerical("SVD did not converge".into()))?;
    let sv_file = if display {
        // The Jacobian in file units: rows back from weighted to file units, columns to the
        // file's units; a second pass, again through a QR's R only.
        let row_scale = file_row_scale(robot, data, &problem);
        let fp = problem.with_row_scale(&row_scale);
        r.resize(m, 0.0);
        acc.clear();
        fp.evaluate_qr(robot, &mut r, &mut acc);
        acc.r_into(&mut raug);
        let rf = Matrix::from_fn(n, n, |i, j| raug[(i, j)] * col_factor[j]);
        linalg::singular_values_qr(&rf)
            .ok_or_else(|| Error::Numerical("SVD did not converge".into()))?
    } else {
        Vec::new()
    };
    let s = &s_scaled;
    let smax = s.first().copied().unwrap_or(0.0);
    let rank = s.iter().filter(|&&v| v > opts.rcond * smax).count();
    // The largest gap, on a log scale, between consecutive singular values.
    // Values below the rounding level of the SVD are all "zero": clamp them there, so that
    // the gap between two rounding-level values (or an exact 0) is not taken for the real one.
    let floor = f64::EPSILON * smax * m.max(n) as f64;
    let (mut gap_rank, mut gap_ratio) = (s.len(), 1.0);
    for i in 0..s.len().saturating_sub(1) {
        let (a, b) = (s[i].max(floor), s[i + 1].max(floor));
        let ratio = if b > 0.0 { a / b } else { f64::INFINITY };
        if ratio > gap_ratio {
            gap_rank = i + 1;
            gap_ratio = ratio;
        }
    }
    let mut warnings = Vec::new();
    // The tolerance and the largest gap disagree: below full rank, whenever they differ; at
    // full rank, when the spectrum has a clear gap (over 1e3) somewhere else.
    let rank_consistent = gap_rank == rank || (rank == n && gap_ratio <= 1e3);
    if !rank_consistent {
        warnings.push(Warning::UnclearRank {
            rank,
            rcond: opts.rcond,
            gap_rank,
            gap_ratio,
        });
    } else if rank < n && gap_ratio < 1e4 {
        warnings.push(Warning::SmallGap { rank, gap_ratio });
    } else if rank == n && smax > 0.0 && s[n - 1] / smax < 1e-6 {
        warnings.push(Warning::BarelyDetermined {
            ratio: s[n - 1] / smax,
        });
    }

    // Null space (scaled coordinates) and which parameters it touches.
    let null: Vec<Vec<f64>> = (rank..n)
        .map(|k| (0..n).map(|j| v_scaled[(j, k)]).collect())
        .collect();
    let determined: Vec<bool> = (0..n)
        .map(|j| null.iter().map(|v| v[j] * v[j]).sum::<f64>().sqrt() < 1e-6)
        .collect();

    // Identical redundancies: equal or opposite unit columns.
    let mut group_of: Vec<Option<usize>> = vec![None; n];
    let mut groups: Vec<Vec<(usize, f64)>> = Vec::new();
    for i in 0..n {
        if group_of[i].is_some() || column_norms[i] == 0.0 || unobservable.contains(&params[i]) {
            continue;
        }
        let mut g = vec![(i, 1.0)];
        for j in i + 1..n {
            if group_of[j].is_some() || unobservable.contains(&params[j]) {
                continue;
            }
            // On R's columns: the same inner products as the Jacobian's, n long instead of m.
            let dot: f64 = (0..r_scaled.nrows())
                .map(|k| r_scaled[(k, i)] * r_scaled[(k, j)])
                .sum();
            if (dot.abs() - 1.0).abs() < 1e-10 {
                g.push((j, dot.signum()));
            }
        }
        if g.len() > 1 {
            for &(j, _) in &g {
                group_of[j] = Some(groups.len());
            }
            groups.push(g);
        }
    }
    // Null space in file units, for estimability checks and the reduced form below.
    let file_null: Vec<Vec<f64>> = null
        .iter()
        .map(|v| {
            (0..n)
                .map(|j| {
                    if column_norms[j] > 0.0 {
                        v[j] / column_norms[j] / col_factor[j]
                    } else {
                        v[j]
                    }
                })
                .collect()
        })
        .collect();
    let file_norm = |j: usize| column_norms[j] * col_factor[j];
    let identical_groups = groups
        .iter()
        .map(|g| {
            let first = g[0].0;
            let terms: Vec<(ParamId, f64)> = g
                .iter()
                .map(|&(j, sign)| (params[j], tidy_coef(sign * file_norm(j) / file_norm(first))))
                .collect();
            let value = terms.iter().map(|&(id, c)| c * robot.get_user(id)).sum();
            // Determined iff the combination does not change along any undetermined direction.
            let determined = file_null.iter().all(|nv| {
                let along: f64 = g
                    .iter()
                    .zip(&terms)
                    .map(|(&(j, _), &(_, c))| c * nv[j])
                    .sum();
                let scale: f64 = g
                    .iter()
                    .zip(&terms)
                    .map(|(&(j, _), &(_, c))| (c * nv[j]).abs())
                    .sum::<f64>()
                    + nv.iter().map(|x| x.abs()).fold(0.0, f64::max);
                along.abs() <= 1e-8 * scale
            });
            IdenticalGroup {
                terms,
                value,
                determined,
            }
        })
        .collect();

    // Identifiable set: greedy by priority, column pivoting within each priority tier.
    let mut order = opts.priority.clone();
    for id in default_priority(robot) {
        if !order.contains(&id) {
            order.push(id);
        }
    }
    let order: Vec<usize> = order
        .iter()
        .filter_map(|id| params.iter().position(|p| p == id))
        .collect();
    // On R's columns (n long, the same inner products as the scaled Jacobian's m-long ones).
    let identifiable = select_base(
        &r_scaled,
        &order,
        rank,
        opts.rcond * smax,
        robot,
        &params,
        &opts.priority,
    );

    // Null space in reduced form, pivots on the least preferred parameters, in file units.
    let reverse: Vec<usize> = order.iter().rev().copied().collect();
    let null_space = reduced_form(&file_null, &reverse)
        .into_iter()
        .map(|row| {
            row.into_iter()
                .map(|(j, c)| (params[j], tidy_coef(c)))
                .collect()
        })
        .collect();

    // A frame at beta = +-90 deg matters only when its alpha and gamma are both analysed and
    // felt by some measurement.
    let felt = |k: ParamKind| {
        let id = robot.param_id(k);
        params.contains(&id) && !unobservable.contains(&id)
    };
    let euler_singular = robot
        .links
        .iter()
        .enumerate()
        .filter(|(i, l)| {
            l.beta.cos().abs() < 1e-3
                && felt(ParamKind::Link {
                    link: *i,
                    component: LinkComponent::Alpha,
                })
                && felt(ParamKind::Link {
                    link: *i,
                    component: LinkComponent::Gamma,
                })
        })
        .map(|(i, _)| format!("link{}", i + 1))
        .chain(
            robot
                .sites
                .iter()
                .enumerate()
                .filter(|(k, s)| {
                    s.frame.beta.cos().abs() < 1e-3
                        && felt(ParamKind::Site {
                            site: *k,
                            component: LinkComponent::Alpha,
                        })
                        && felt(ParamKind::Site {
                            site: *k,
                            component: LinkComponent::Gamma,
                        })
                })
                .map(|(_, s)| format!("site.{}", s.name)),
        )
        .collect::<Vec<_>>();
    for name in &euler_singular {
        warnings.push(Warning::EulerSingular {
            frame: name.clone(),
        });
    }

    let lin = accuracy.map(|accuracy| Linearized {
        params: params.clone(),
        r: raug,
        accuracy,
    });
    let analysis = Analysis {
        expected: expected_rank(robot, data, &params),
        parameters: params,
        residuals: m,
        singular_values_scaled: s.clone(),
        singular_values_file: sv_file,
        rank,
        rcond: opts.rcond,
        gap_rank,
        gap_ratio,
        rank_consistent,
        unobservable,
        identical_groups,
        null_space,
        identifiable,
        determined,
        euler_singular,
        warnings,
        column_norms,
        right_singular_vectors: v_scaled,
    };
    Ok((analysis, lin))
}

/// Per row of `problem`, the factor from its weighted residual to file units (its sigma in
/// the file's length or angle unit).
fn file_row_scale(robot: &Robot, data: &Dataset, problem: &Problem<'_>) -> Vec<f64> {
    let units = robot.units;
    let sigma = problem.row_sigma();
    let mut scale = Vec::with_capacity(problem.rows());
    for o in &data.observations {
        for row in o.rows() {
            let i = scale.len();
            scale.push(match row.quantity {
                RowQuantity::Length => sigma[i] / units.length.metres(),
                RowQuantity::Angle => sigma[i] / units.angle.radians(),
            });
        }
    }
    scale
}

/// The Jacobian of an [`Analysis`], row by row, for display (`kinecal analyze --print`): an
/// m x n matrix and a label per row, so build it only to show it; the analysis itself never
/// holds it.
#[derive(Debug, Clone)]
pub struct JacobianTable {
    /// Per row: posture label(s) (`a&b` for a pair), target, row label.
    pub row_labels: Vec<(String, String, &'static str)>,
    /// The scaled Jacobian `W J D^-1` (unit columns; unfelt columns zeroed), as analysed.
    pub scaled: Matrix,
    /// The Jacobian in file units: rows in the file's length or angle unit per the parameter's
    /// file unit.
    pub file: Matrix,
}

/// The Jacobian that `analysis` (of `data` on `robot`, with `opts`) analysed, for display.
pub fn jacobian_table(
    robot: &Robot,
    data: &Dataset,
    analysis: &Analysis,
    opts: &AnalysisOptions,
) -> JacobianTable {
    let params = &analysis.parameters;
    let problem = Problem::new(robot, data, params, opts.weights, opts.orientation);
    let (m, n) = (problem.rows(), params.len());
    let mut r = vec![0.0; m];
    let mut jw = Matrix::zeros(m, n);
    problem.evaluate(robot, &mut r, Some(&mut jw));
    let mut row_labels = Vec::with_capacity(m);
    for o in &data.observations {
        let postures: Vec<&str> = o
            .views()
            .iter()
            .map(|v| data.postures[v.posture].label.as_str())
            .collect();
        let postures = postures.join("&");
        let site = crate::observe::target_name(robot, o.target()).to_string();
        for row in o.rows() {
            row_labels.push((postures.clone(), site.clone(), row.label));
        }
    }
    let row_scale = file_row_scale(robot, data, &problem);
    let units = robot.units;
    let col_factor: Vec<f64> = params
        .iter()
        .map(|&id| units.factor(robot.param_quantity(id)))
        .collect();
    let file = Matrix::from_fn(m, n, |i, j| jw[(i, j)] * row_scale[i] * col_factor[j]);
    let scaled = Matrix::from_fn(m, n, |i, j| {
        let c = analysis.column_norms[j];
        if analysis.unobservable.contains(&params[j]) || c <= 0.0 {
            0.0
        } else {
            jw[(i, j)] / c
        }
    });
    JacobianTable {
        row_labels,
        scaled,
        file,
    }
}

/// Rounds coefficients within 1e-9 of an integer to it, and drops float noise.
fn tidy_coef(c: f64) -> f64 {
    let r = c.round();
    if (c - r).abs() < 1e-9 {
        r
    } else {
        c
    }
}

/// Greedy base selection: tiers from the priority list (each user-given parameter its own tier,
/// then the default tiers), and within a tier the column with the largest residual after
/// projection on the already chosen ones (QR with column pivoting), while that residual exceeds
/// `tol`; residuals within 1e-9 of each other are a tie, won by the earlier in `order`. `js` may
/// be the scaled Jacobian or the `R` of its QR (the same inner products, n rows instead of m).
fn select_base(
    js: &Matrix,
    order: &[usize],
    rank: usize,
    tol: f64,
    robot: &Robot,
    params: &[ParamId],
    user: &[ParamId],
) -> Vec<ParamId> {
    let m = js.nrows();
    let tier_of = |j: usize| -> usize {
        match user.iter().position(|&p| p == params[j]) {
            Some(k) => k,
            None => user.len() + default_tier(robot, params[j]),
        }
    };
    let mut chosen: Vec<usize> = Vec::new();
    let mut q: Vec<Vec<f64>> = Vec::new(); // orthonormal basis of chosen columns
    let mut remaining: Vec<usize> = order.to_vec();
    while chosen.len() < rank && !remaining.is_empty() {
        let tier = remaining
            .iter()
            .map(|&j| tier_of(j))
            .min()
            .expect("non-empty");
        // Residual norms of this tier's candidates.
        let mut best: Option<(usize, f64, Vec<f64>)> = None;
        for &j in remaining.iter().filter(|&&j| tier_of(j) == tier) {
            let mut v: Vec<f64> = (0..m).map(|i| js[(i, j)]).collect();
            for _ in 0..2 {
                for b in &q {
                    let d: f64 = v.iter().zip(b).map(|(x, y)| x * y).sum();
                    for (x, y) in v.iter_mut().zip(b) {
                        *x -= d * y;
                    }
                }
            }
            let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
            // Equal up to rounding is a tie, which the order decides.
            if best.as_ref().is_none_or(|b| norm > b.1 * (1.0 + 1e-9)) {
                best = Some((j, norm, v));
            }
        }
        let (j, norm, v) = best.expect("tier has a candidate");
        if norm > tol.max(1e-12) {
            chosen.push(j);
            q.push(v.iter().map(|x| x / norm).collect());
            remaining.retain(|&k| k != j);
        } else {
            // Nothing left in this tier adds a direction.
            remaining.retain(|&k| tier_of(k) != tier);
        }
    }
    let mut ids: Vec<ParamId> = chosen.iter().map(|&j| params[j]).collect();
    ids.sort();
    ids
}

fn default_tier(robot: &Robot, id: ParamId) -> usize {
    let nonzero = robot.get(id).abs() > 1e-12;
    match robot.param_kind(id) {
        ParamKind::Offset { .. } => 0,
        ParamKind::Slope { .. } | ParamKind::Coupling { .. } => 1,
        ParamKind::Link { component, .. } => match (component.quantity(), nonzero) {
            (Quantity::Length, true) => 2,
            (_, true) => 3,
            (Quantity::Length, false) => 4,
            _ => 5,
        },
        ParamKind::Site { .. } => 6,
        ParamKind::Plane { .. } => 7,
    }
}

/// Gauss-Jordan reduction of the rows `vectors` (each of length n) with pivots searched in the
/// column order `order`; entries below 1e-9 of their row's largest are dropped. Returns each
/// reduced row as (column, coefficient) with the pivot's coefficient 1.
fn reduced_form(vectors: &[Vec<f64>], order: &[usize]) -> Vec<Vec<(usize, f64)>> {
    let mut rows: Vec<Vec<f64>> = vectors.to_vec();
    let k = rows.len();
    let mut pivots = Vec::new();
    let mut r = 0;
    for &c in order {
        if r == k {
            break;
        }
        // Partial pivoting among the remaining rows.
        let (best, val) = (r..k)
            .map(|i| (i, rows[i][c].abs()))
            .fold((r, 0.0), |a, b| if b.1 > a.1 { b } else { a });
        let scale = rows
            .iter()
            .flat_map(|row| row.iter())
            .fold(0.0f64, |a, &b| a.max(b.abs()));
        if val <= 1e-8 * scale {
            continue;
        }
        rows.swap(r, best);
        let p = rows[r][c];
        for x in rows[r].iter_mut() {
            *x /= p;
        }
        for i in 0..k {
            if i != r {
                let f = rows[i][c];
                if f != 0.0 {
                    let pivot_row = rows[r].clone();
                    for (x, y) in rows[i].iter_mut().zip(&pivot_row) {
                        *x -= f * y;
                    }
                }
            }
        }
        pivots.push(c);
        r += 1;
    }
    rows.truncate(r);
    rows.iter()
        .zip(&pivots)
        .map(|(row, &pc)| {
            let big = row.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
            let mut terms: Vec<(usize, f64)> = row
                .iter()
                .enumerate()
                .filter(|(_, &v)| v.abs() > 1e-9 * big)
                .map(|(j, &v)| (j, v))
                .collect();
            // Pivot first, then by parameter order.
            terms.sort_by_key(|&(j, _)| (j != pc, j));
            terms
        })
        .collect()
}

/// Writes `sum c_j p_j` readably: `p3 - p9 - p15`, `p4 + 0.5 p31`.
pub fn format_combination(terms: &[(ParamId, f64)]) -> String {
    let mut s = String::new();
    for (k, &(id, c)) in terms.iter().enumerate() {
        let sign = if c < 0.0 { "-" } else { "+" };
        let mag = c.abs();
        let coef = if (mag - 1.0).abs() < 1e-12 {
            String::new()
        } else {
            format!("{} ", fmt_sig(mag))
        };
        if k == 0 {
            s.push_str(if c < 0.0 { "-" } else { "" });
        } else {
            s.push_str(&format!(" {sign} "));
        }
        s.push_str(&format!("{coef}{id}"));
    }
    s
}

/// A number with 6 significant digits and no trailing zeros.
pub fn fmt_sig(v: f64) -> String {
    let s = format!("{:.6}", v);
    let s = if v != 0.0 && v.abs() < 1e-3 {
        format!("{v:.4e}")
    } else {
        s
    };
    if s.contains('.') && !s.contains('e') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}
