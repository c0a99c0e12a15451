//! The analysis checked against the thesis's counts, second formulations and hand-made
//! cases.

use super::base::select_base;
use super::spectrum::dot;
use super::*;
use crate::files::parse_measurements;
use crate::linalg;

/// The greedy selection this module made before the pivoted QR (Gram-Schmidt, twice, on
/// every candidate at every step: O(n^4)), kept verbatim but for the tiers, which it is
/// handed: the reference the pivoted QR must agree with under the rounding rule alone.
fn greedy(js: &Matrix, order: &[usize], tier: &[usize], rank: usize, tol: f64) -> Vec<usize> {
    let m = js.nrows();
    let mut chosen: Vec<usize> = Vec::new();
    let mut q: Vec<Vec<f64>> = Vec::new(); // orthonormal basis of chosen columns
    let mut remaining: Vec<usize> = order.to_vec();
    while chosen.len() < rank && !remaining.is_empty() {
        let t = remaining.iter().map(|&j| tier[j]).min().expect("non-empty");
        let mut best: Option<(usize, f64, Vec<f64>)> = None;
        for &j in remaining.iter().filter(|&&j| tier[j] == t) {
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
            remaining.retain(|&k| tier[k] != t);
        }
    }
    chosen.sort();
    chosen
}

fn sorted(mut v: Vec<usize>) -> Vec<usize> {
    v.sort();
    v
}

/// Random matrices with dependent and nearly dependent columns, random tiers and orders:
/// the pivoted QR (with downdated norms) chooses what the greedy Gram-Schmidt does.
#[test]
fn random_matrices_choose_as_the_greedy_selection_does() {
    use rand::{RngExt, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    for trial in 0..300 {
        let m = rng.random_range(6..30usize);
        let n = rng.random_range(2..14usize);
        let mut a = Matrix::from_fn(m, n, |_, _| rng.random_range(-1.0..1.0));
        // Some columns combinations of others (exactly, or with widely different scales).
        for j in 0..n {
            if j >= 2 && rng.random_range(0.0..1.0) < 0.3 {
                let (p, q) = (rng.random_range(0..j), rng.random_range(0..j));
                let (x, y) = (rng.random_range(-2.0..2.0), rng.random_range(-1e3..1e3));
                for i in 0..m {
                    a[(i, j)] = x * a[(i, p)] + y * a[(i, q)];
                }
            }
            if rng.random_range(0.0..1.0) < 0.2 {
                linalg::scale_col(&mut a, j, 10f64.powi(rng.random_range(-6..6)));
            }
        }
        let norms: Vec<f64> = (0..n).map(|j| linalg::col_norm(&a, j)).collect();
        let js = Matrix::from_fn(m, n, |i, j| a[(i, j)] / norms[j]);
        let mut order: Vec<usize> = (0..n).collect();
        for k in (1..n).rev() {
            order.swap(k, rng.random_range(0..=k));
        }
        let tiers: Vec<usize> = (0..n).map(|_| rng.random_range(0..3)).collect();
        let s = linalg::singular_values(&js).unwrap();
        let tol = 1e-9 * s[0];
        let rank = s.iter().filter(|&&v| v > tol).count();
        let old = greedy(&js, &order, &tiers, rank, tol);
        let new = select_base(&js, &vec![1.0; n], &order, &tiers, rank, tol, &vec![0.0; n]);
        assert_eq!(sorted(new.chosen.clone()), old, "trial {trial}");
        // And on the R of the same columns (what the analysis works on).
        let r = linalg::r_of_columns(&js, &(0..n).collect::<Vec<_>>());
        let on_r = select_base(&r, &vec![1.0; n], &order, &tiers, rank, tol, &vec![0.0; n]);
        assert_eq!(on_r.chosen, new.chosen, "trial {trial}");
    }
}

/// Identical columns (equal to rounding, or opposite) tie: the earliest in the order wins,
/// whatever the order, the same every time.
#[test]
fn ties_go_to_the_earliest_in_the_order() {
    let m = 9;
    let mut a = Matrix::from_fn(m, 4, |i, j| ((i * 7 + j * 3) as f64 * 0.9).sin());
    for i in 0..m {
        a[(i, 2)] = a[(i, 0)] * (1.0 + 3e-16);
        a[(i, 3)] = -a[(i, 0)];
    }
    let norms: Vec<f64> = (0..4).map(|j| linalg::col_norm(&a, j)).collect();
    let js = Matrix::from_fn(m, 4, |i, j| a[(i, j)] / norms[j]);
    let r = linalg::r_of_columns(&js, &[0, 1, 2, 3]);
    for first in [0, 2, 3] {
        let mut order = vec![first, 1];
        order.extend([0, 2, 3].iter().filter(|&&j| j != first));
        for mat in [&js, &r] {
            let sel = select_base(mat, &[1.0; 4], &order, &[0; 4], 2, 1e-9, &[0.0; 4]);
            assert_eq!(
                sorted(sel.chosen),
                sorted(vec![first, 1]),
                "order {order:?}"
            );
        }
    }
}

/// A column at a known angle to the span of two others: left out within the noise when
/// its sine is below 1/sqrt(m) (uniform weights), with its ratio r/e = sin sqrt(m) and its
/// regression on the two; kept above; left out silently (not reported) when it is
/// dependent at the rounding level.
#[test]
fn the_noise_rule_on_a_column_at_a_known_angle() {
    let m = 100;
    let root = (m as f64).sqrt();
    // Orthonormal u0, u1, u2 (by Gram-Schmidt of smooth columns).
    let mut u = Matrix::from_fn(m, 3, |i, j| ((i * (j + 2)) as f64 * 0.173 + j as f64).cos());
    for j in 0..3 {
        for k in 0..j {
            let d = dot(u.col(j), u.col(k));
            for i in 0..m {
                u[(i, j)] -= d * u[(i, k)];
            }
        }
        let nrm = linalg::col_norm(&u, j);
        linalg::scale_col(&mut u, j, 1.0 / nrm);
    }
    for (sine, noisy, kept) in [
        (0.5 / root, true, false),
        (0.99 / root, true, false),
        (1.01 / root, false, true),
        (0.3, false, true),
        (1e-13, false, false),
    ] {
        // c0 = u0, c1 = (u0 + u1) / sqrt 2, c2 = cos t (0.6 c0 + 0.8 c1)^ + sin t u2.
        let c1: Vec<f64> = (0..m)
            .map(|i| (u[(i, 0)] + u[(i, 1)]) / 2f64.sqrt())
            .collect();
        let mut mix: Vec<f64> = (0..m).map(|i| 0.6 * u[(i, 0)] + 0.8 * c1[i]).collect();
        let mn = dot(&mix, &mix).sqrt();
        mix.iter_mut().for_each(|x| *x /= mn);
        let cos = (1.0 - sine * sine).sqrt();
        let a = Matrix::from_fn(m, 3, |i, j| match j {
            0 => u[(i, 0)],
            1 => c1[i],
            _ => cos * mix[i] + sine * u[(i, 2)],
        });
        // Uniform weights: e_j = |a_j| / sqrt(m), so the gain of a unit column is sqrt(m).
        let sel = select_base(&a, &[root; 3], &[0, 1, 2], &[0, 0, 1], 3, 1e-9, &[1.0; 3]);
        assert_eq!(sel.chosen.contains(&2), kept, "sine {sine}");
        assert_eq!(sel.noise.len(), noisy as usize, "sine {sine}");
        if let Some(d) = sel.noise.first() {
            assert_eq!(d.column, 2);
            assert!(
                (d.ratio - sine * root).abs() < 1e-12,
                "{} vs {}",
                d.ratio,
                sine * root
            );
            // c2 = (cos / mn) (0.6 c0 + 0.8 c1) + sine u2, in the order chosen (c0, c1).
            let want = [0.6 * cos / mn, 0.8 * cos / mn];
            for (l, want) in want.iter().enumerate() {
                let c = d.coef[sel.chosen.iter().position(|&k| k == l).unwrap()];
                assert!((c - want).abs() < 1e-12, "{c} vs {want}");
            }
        }
    }
}

/// Odd input: nothing to choose from, zero and NaN columns, a rank of 0. No panic.
#[test]
fn odd_input_chooses_what_it_can() {
    let z = Matrix::zeros(3, 2);
    assert!(
        select_base(&z, &[0.0; 2], &[0, 1], &[0, 0], 2, 1e-9, &[1.0; 2])
            .chosen
            .is_empty()
    );
    let a = Matrix::from_fn(3, 2, |i, j| if j == 0 { f64::NAN } else { i as f64 });
    let s = select_base(&a, &[1.0; 2], &[0, 1], &[0, 0], 2, 1e-9, &[0.0; 2]);
    assert!(s.chosen.len() <= 2);
    let b = Matrix::from_fn(3, 2, |i, j| (i + j) as f64);
    assert!(
        select_base(&b, &[1.0; 2], &[0, 1], &[0, 1], 0, 1e-9, &[0.0; 2])
            .chosen
            .is_empty()
    );
    assert!(select_base(&b, &[1.0; 2], &[], &[0, 1], 2, 1e-9, &[0.0; 2])
        .chosen
        .is_empty());
}

/// A 5-joint arm (metres, radians) and `count` positions of its end effector at
/// pseudo-random readings, in CSV with a standard deviation per row: the first `anchors`
/// at `tiny`, the others at `sigma` (m). Made here from the forward kinematics (this module
/// may not use the simulation, which comes after it).
fn arm_positions(count: usize, anchors: usize, tiny: f64, sigma: f64) -> (Robot, Dataset) {
    let quarter = std::f64::consts::FRAC_PI_2;
    let links = [
        (0.0, 0.0, 0.3, 0.0, 0.0, 0.0),
        (0.05, 0.0, 0.1, 0.0, quarter, 0.0),
        (0.4, 0.02, 0.0, 0.1, 0.0, 0.0),
        (0.35, 0.0, 0.05, 0.0, -0.2, quarter),
        (0.0, 0.1, 0.12, 0.3, 0.1, -quarter),
        (0.02, 0.03, 0.15, 0.0, 0.0, 0.0),
    ];
    let mut toml = String::from("name = \"arm\"\nlength_unit = \"m\"\nangle_unit = \"rad\"\n");
    for (x, y, z, a, b, g) in links {
        toml.push_str(&format!(
            "[[links]]\nx = {x}\ny = {y}\nz = {z}\nalpha = {a}\nbeta = {b}\ngamma = {g}\n"
        ));
    }
    for k in 0..5 {
        toml.push_str(&format!(
            "[[joints]]\nkind = \"revolute\"\noffset = {}\nslope = {}\n",
            0.1 * k as f64,
            1.0 + 0.1 * k as f64
        ));
    }
    let robot = crate::model::robot_file::parse_robot_toml(&toml, "arm.toml").unwrap();
    let chain = crate::model::kinematics::Chain::new(&robot);
    let mut ws = crate::model::kinematics::Workspace::new(&robot);
    let mut csv = String::from("posture,v1,v2,v3,v4,v5,x,y,z,sigma_position\n");
    for i in 0..count {
        let v: Vec<f64> = (0..5)
            .map(|k| 2.5 * ((i * 7 + k * 13) as f64 * 0.618).sin())
            .collect();
        chain.forward(&v, &mut ws);
        let p = chain
            .target_frame(&ws, crate::model::kinematics::Target::EndEffector)
            .pose()
            .position;
        let s = if i < anchors { tiny } else { sigma };
        let v: Vec<String> = v.iter().map(|x| x.to_string()).collect();
        csv.push_str(&format!(
            "{},{},{},{},{},{s}\n",
            i + 1,
            v.join(","),
            p.x,
            p.y,
            p.z
        ));
    }
    let data = parse_measurements(&csv, "arm.csv", &robot).unwrap();
    (robot, data)
}

/// The clamp factors: none with uniform weights (the passes then tally nothing); with three
/// anchored postures (sigma 1e-9 among 5e-5), their nine rows' weights clamped at the median's,
/// the others' factor 1.
#[test]
fn row_clamp_is_empty_for_uniform_weights_and_clamps_the_anchors() {
    let params = |robot: &Robot| robot.param_ids().collect::<Vec<ParamId>>();
    let opts = AnalysisOptions::default();
    let (robot, data) = arm_positions(40, 0, 1e-9, 5e-5);
    let ids = params(&robot);
    let problem = Problem::new(&robot, &data, &ids, opts.weights, opts.orientation);
    assert!(base::row_clamp(&data, &problem).is_empty());
    let (robot, data) = arm_positions(40, 3, 1e-9, 5e-5);
    let problem = Problem::new(&robot, &data, &ids, opts.weights, opts.orientation);
    let clamp = base::row_clamp(&data, &problem);
    assert_eq!(clamp.len(), 120);
    for (i, &c) in clamp.iter().enumerate() {
        let want = if i < 9 { 1e-9 / 5e-5 } else { 1.0 };
        assert!((c - want).abs() <= 1e-12 * want, "row {i}: {c} vs {want}");
    }
}

/// The e_j travel with a linearisation: an analysis from it (no pass) is the analysis
/// that made it. From a bare R, e_j is bounded from the column norms: exact with uniform
/// weights; with anchors, below the exact values, and it leaves out no more than the rule.
#[test]
fn a_linearisation_carries_the_typical_rows() {
    for anchors in [0, 3] {
        let (robot, data) = arm_positions(40, anchors, 1e-9, 5e-5);
        // Every parameter: the tool link's angles, unseen by positions, are unobservable.
        let params: Vec<ParamId> = robot.param_ids().collect();
        let opts = AnalysisOptions::default();
        let (an, lin) = analyze_linearized(&robot, &data, &params, &opts).unwrap();
        assert_eq!(an.unobservable.len(), 3);
        assert_eq!(lin.typical_row, an.typical_row);
        let again = analyze_from_linearized(&robot, &data, &lin, &opts).unwrap();
        assert_eq!(again.identifiable, an.identifiable);
        assert_eq!(again.typical_row, an.typical_row);
        assert_eq!(again.noise_dependent, an.noise_dependent);
        assert_eq!(again.noise_rule, an.noise_rule);
        let bare = analyze_from_r(&robot, &data, &params, &opts, &lin.r).unwrap();
        if anchors == 0 {
            for (a, b) in bare.typical_row.iter().zip(&an.typical_row) {
                assert!((a - b).abs() <= 1e-12 * b, "{a} vs {b}");
            }
            assert_eq!(bare.identifiable, an.identifiable);
            assert!(!bare.noise_rule.contains("bounded below"));
        } else {
            assert!(bare.noise_rule.contains("bounded below"));
            for (a, b) in bare.typical_row.iter().zip(&an.typical_row) {
                assert!(*a <= b * (1.0 + 1e-12), "{a} vs {b}");
            }
            assert!(bare.noise_dependent.len() <= an.noise_dependent.len());
        }
    }
}

/// A 6R arm of random geometry (metres, radians; every link's six parameters non-zero) and
/// `count` measurements of its end effector at pseudo-random readings, poses or positions, in
/// CSV (made here from the forward kinematics: this module may not use the simulation). With
/// `held`, joint 6 stays at 0.3 rad in the first `held` postures.
fn random_arm(seed: u64, count: usize, pose: bool, held: usize) -> (Robot, Dataset) {
    random_arm_with(seed, count, pose, held, 0.0)
}

/// [`random_arm`] with joint 6 at 0.3 rad within `+-spread` at every posture.
fn random_arm_joint6(seed: u64, count: usize, pose: bool, spread: f64) -> (Robot, Dataset) {
    random_arm_with(seed, count, pose, count, spread)
}

/// A random arm and data; joint 6 at 0.3 rad within `+-spread` in the first `held` postures.
fn random_arm_with(
    seed: u64,
    count: usize,
    pose: bool,
    held: usize,
    spread: f64,
) -> (Robot, Dataset) {
    arm_data(seed, count, pose, held, spread, false)
}

/// A random arm of a DH table's kind (link twists of 0 or +-90 deg, no other angles, links
/// along x and z) and data, as [`random_arm`]: many of its dependences are one column equal
/// to another or its negative, where a random arm's are several terms each.
fn dh_arm(seed: u64, count: usize, pose: bool) -> (Robot, Dataset) {
    arm_data(seed, count, pose, 0, 0.0, true)
}

fn arm_data(
    seed: u64,
    count: usize,
    pose: bool,
    held: usize,
    spread: f64,
    dh: bool,
) -> (Robot, Dataset) {
    use rand::{RngExt, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut toml = String::from("name = \"arm\"\nlength_unit = \"m\"\nangle_unit = \"rad\"\n");
    for _ in 0..7 {
        let mut l: Vec<f64> = (0..3).map(|_| rng.random_range(-0.4..0.4)).collect();
        let mut a: Vec<f64> = (0..3).map(|_| rng.random_range(-1.2..1.2)).collect();
        if dh {
            l[1] = 0.0;
            let twist = [
                0.0,
                std::f64::consts::FRAC_PI_2,
                -std::f64::consts::FRAC_PI_2,
            ];
            a = vec![twist[rng.random_range(0..3)], 0.0, 0.0];
        }
        toml.push_str(&format!(
            "[[links]]\nx = {}\ny = {}\nz = {}\nalpha = {}\nbeta = {}\ngamma = {}\n",
            l[0], l[1], l[2], a[0], a[1], a[2]
        ));
    }
    for _ in 0..6 {
        let offset: f64 = rng.random_range(-3.0..3.0);
        toml.push_str(&format!(
            "[[joints]]\nkind = \"revolute\"\noffset = {offset}\n"
        ));
    }
    let robot = crate::model::robot_file::parse_robot_toml(&toml, "arm.toml").unwrap();
    let chain = crate::model::kinematics::Chain::new(&robot);
    let mut ws = crate::model::kinematics::Workspace::new(&robot);
    let mut csv = String::from("posture,v1,v2,v3,v4,v5,v6,x,y,z");
    csv.push_str(if pose { ",alpha,beta,gamma\n" } else { "\n" });
    for i in 0..count {
        let mut v: Vec<f64> = (0..6).map(|_| rng.random_range(-3.0..3.0)).collect();
        if i < held {
            v[5] = 0.3 + spread * v[5] / 3.0;
        }
        chain.forward(&v, &mut ws);
        let p = chain
            .target_frame(&ws, crate::model::kinematics::Target::EndEffector)
            .pose();
        let v: Vec<String> = v.iter().map(|x| x.to_string()).collect();
        let (x, e) = (p.position, p.euler);
        csv.push_str(&format!(
            "{},{},{},{},{}",
            i + 1,
            v.join(","),
            x.x,
            x.y,
            x.z
        ));
        if pose {
            csv.push_str(&format!(",{},{},{}", e.x, e.y, e.z));
        }
        csv.push('\n');
    }
    let data = parse_measurements(&csv, "arm.csv", &robot).unwrap();
    (robot, data)
}

/// Every parameter of `robot`, the default options, and the basis of their columns found on
/// `data`'s subsample (which a test's data is large enough to have).
fn subsample_basis(robot: &Robot, data: &Dataset) -> (Vec<ParamId>, AnalysisOptions, basis::Basis) {
    let params: Vec<ParamId> = robot.param_ids().collect();
    let opts = AnalysisOptions::default();
    let keep = basis::subsample(data, params.len()).expect("a subsample");
    let b = basis::Basis::of(robot, &data.subset(&keep), &params, &opts)
        .unwrap()
        .expect("dependent columns");
    (params, opts, b)
}

/// `R^T R` of two `R`s agree entry by entry within `tol` of the product of the columns' norms
/// (the inner products of the Jacobian's columns, which is all an `R` stands for); columns
/// unfelt in both (norms within 1e-12 of the largest, which the analysis zeroes) aside.
fn assert_same_inner_products(a: &Matrix, b: &Matrix, tol: f64) {
    let n = a.ncols();
    assert_eq!(n, b.ncols());
    let (ga, gb) = (linalg::gram(a), linalg::gram(b));
    let norm = |j: usize| ga[(j, j)].max(gb[(j, j)]).sqrt();
    let largest = (0..n).map(norm).fold(0.0, f64::max);
    let unfelt = |j: usize| norm(j) <= 1e-12 * largest;
    for i in 0..n {
        for j in 0..n {
            if unfelt(i) || unfelt(j) {
                continue;
            }
            let d = (ga[(i, j)] - gb[(i, j)]).abs() / (norm(i) * norm(j));
            assert!(
                d <= tol,
                "({i}, {j}): {} vs {} ({d:e})",
                ga[(i, j)],
                gb[(i, j)]
            );
        }
    }
}

/// The analysis of every row, and that of the rows folded through a subsample's basis:
/// the same identifiable set, rank, unobservable and noise-dependent parameters, and the same
/// inner products of the columns (to 1e-11 of their norms).
fn assert_same_analysis(robot: &Robot, data: &Dataset, params: &[ParamId], lin: &Linearized) {
    let opts = AnalysisOptions::default();
    let full = analyze_core(robot, data, params, &opts).unwrap();
    let fast = analyze_from_linearized(robot, data, lin, &opts).unwrap();
    assert_eq!(fast.identifiable, full.identifiable);
    assert_eq!(fast.rank, full.rank);
    assert_eq!(fast.unobservable, full.unobservable);
    let ids = |a: &Analysis| a.noise_dependent.iter().map(|d| d.id).collect::<Vec<_>>();
    assert_eq!(ids(&fast), ids(&full));
    let problem = Problem::new(robot, data, params, opts.weights, opts.orientation);
    let mut acc = linalg::QrAccumulator::new(params.len() + 1, 512);
    let mut r = vec![0.0; problem.rows()];
    problem.evaluate_qr(robot, &mut r, &mut acc);
    let mut whole = Matrix::zeros(0, 0);
    acc.r_into(&mut whole);
    assert_same_inner_products(&lin.r, &whole, 1e-11);
}

/// Random arms, poses and positions, every parameter analysed (the tool link's angles
/// unobservable from positions): large enough data is folded through a subsample's basis (108
/// postures measured by pose, 216 by position)
/// (36 of the 54 columns for poses, 33 for positions: the 18 or 21 others found dependent
/// there are proved so on every row), and the analysis is that of every row.
#[test]
fn rows_folded_through_a_subsample_basis_are_all_the_rows() {
    for seed in 0..4 {
        let pose = seed % 2 == 0;
        let (robot, data) = random_arm(seed, 1800, pose, 0);
        let params: Vec<ParamId> = robot.param_ids().collect();
        let opts = AnalysisOptions::default();
        let keep = basis::subsample(&data, params.len()).expect("a subsample of 1,800 postures");
        let kept = keep.iter().filter(|&&k| k).count();
        // 12 rows per parameter: 4 n positions, 2 n poses (n = 54).
        let expected = if pose { 100..=115 } else { 200..=225 };
        assert!(expected.contains(&kept), "{kept} postures kept");
        let sub = data.subset(&keep);
        let b = basis::Basis::of(&robot, &sub, &params, &opts)
            .unwrap()
            .unwrap();
        assert_eq!(b.basis.len(), if pose { 36 } else { 33 }, "seed {seed}");
        let problem = Problem::new(&robot, &data, &params, opts.weights, opts.orientation);
        let clamp = base::row_clamp(&data, &problem);
        assert!(b.fold_all(&robot, &problem, &clamp, opts.rcond).is_some());
        // The basis of these arms is well conditioned: its R comes from the Gram matrix, and
        // gives the columns' inner products that the QR's R gives.
        assert!(
            b.gram,
            "seed {seed}: the basis's condition on the subsample"
        );
        let folded = |by| match b.fold_all_by(&robot, &problem, &clamp, opts.rcond, by) {
            Some(basis::Folded::Rows(rows)) => rows.raug,
            Some(basis::Folded::NeedsQr) => panic!("seed {seed}: {by:?} needs a QR"),
            None => panic!("seed {seed}: {by:?} failed its proof"),
        };
        let (gram, qr) = (folded(basis::Fold::Gram), folded(basis::Fold::Qr));
        assert_same_inner_products(&gram, &qr, 1e-12);
        // A base set's dependences are a few terms each (mostly a column equal to another or
        // its negative): the proof takes them one by one, and agrees with the matrix product
        // of every coefficient.
        assert!(b.sparse(), "seed {seed}: the dependences' terms");
        let Some(basis::Folded::Rows(dense)) =
            b.clone()
                .dense()
                .fold_all_by(&robot, &problem, &clamp, opts.rcond, basis::Fold::Gram)
        else {
            panic!("seed {seed}: the dense proof");
        };
        assert_same_inner_products(&gram, &dense.raug, 1e-12);
        // The fold keeps the accuracy and each observation's error as the pass of the whole
        // rows does. With rows clamped (factors set here, as unequal weights would) it tallies
        // the typical-row sums as the pass does (`TypicalRowTally`), to the bit; with uniform
        // weights no row is clamped, neither tallies, and both take `e_j` from their `R`,
        // which agrees with the tally of the factors set to 1 to rounding.
        assert!(
            clamp.is_empty(),
            "seed {seed}: uniform weights clamp no row"
        );
        let ones = vec![1.0; problem.rows()];
        let factors: Vec<f64> = (0..problem.rows())
            .map(|i| {
                if i % 3 == 0 {
                    0.25 + (i % 7) as f64 * 0.1
                } else {
                    1.0
                }
            })
            .collect();
        let mut typical = Vec::new();
        for clamp in [&clamp[..], &ones[..], &factors[..]] {
            let whole = spectrum::rows(&robot, &problem, clamp, None, params.len()).unwrap();
            let Some(basis::Folded::Rows(rows)) =
                b.fold_all_by(&robot, &problem, clamp, opts.rcond, basis::Fold::Gram)
            else {
                panic!("seed {seed}: the fold");
            };
            let (fold, pass) = (rows.typical.unwrap(), whole.typical.unwrap());
            if clamp.is_empty() {
                // To rounding of the largest (an unfelt column, rounding noise in the pass, is
                // 0 through the basis).
                let largest = pass.iter().copied().fold(0.0, f64::max);
                for (a, b) in fold.iter().zip(&pass) {
                    assert!((a - b).abs() <= 1e-12 * largest, "seed {seed}: {a} vs {b}");
                }
            } else {
                assert_eq!(fold, pass, "seed {seed}");
            }
            typical.push(pass);
            assert!(rows.accuracy.is_some());
            assert_eq!(rows.accuracy, whole.accuracy, "seed {seed}");
        }
        for (a, b) in typical[0].iter().zip(&typical[1]) {
            assert!((a - b).abs() <= 1e-12 * b, "seed {seed}: {a} vs {b}");
        }
        let (_, lin) = analyze_linearized(&robot, &data, &params, &opts).unwrap();
        assert_same_analysis(&robot, &data, &params, &lin);
    }
}

/// Arms of a DH table's kind: many dependences are a single term (a column equal to another
/// or its negative), which the proof takes in a loop of their own, row by row; the fold
/// agrees with the proof by a matrix product of every coefficient, and the analysis is that
/// of every row.
#[test]
fn single_term_dependences_are_proved_row_by_row() {
    for (seed, pose) in [(5, true), (6, false)] {
        let (robot, data) = dh_arm(seed, 1800, pose);
        let (params, opts, b) = subsample_basis(&robot, &data);
        let counts = b.term_counts().expect("few terms");
        let single = counts.iter().filter(|&&c| c == 1).count();
        // Both loops of the proof run: the single terms' and the others'.
        assert!(
            single >= 3 && single < counts.len(),
            "seed {seed}: {single} single terms of {counts:?}"
        );
        let problem = Problem::new(&robot, &data, &params, opts.weights, opts.orientation);
        let clamp = base::row_clamp(&data, &problem);
        assert!(clamp.is_empty(), "uniform weights: proved row by row");
        let raug = |b: &basis::Basis| match b.fold_all_by(
            &robot,
            &problem,
            &clamp,
            opts.rcond,
            basis::Fold::Qr,
        ) {
            Some(basis::Folded::Rows(rows)) => rows.raug,
            _ => panic!("seed {seed}: the proof failed"),
        };
        assert_same_inner_products(&raug(&b), &raug(&b.clone().dense()), 1e-12);
        let (_, lin) = analyze_linearized(&robot, &data, &params, &opts).unwrap();
        assert_same_analysis(&robot, &data, &params, &lin);
    }
}

/// The proof bounds each dependent column's norm by its combination's, `|J_B c|`, from the
/// basis's `R_B` or its Gram matrix (no sum of its own squares): on every row of a random arm,
/// both give the dependent column's norm that the `R` of all the columns gives, to 1e-12 of
/// it (the coefficients' pruned terms are below `PRUNE * rcond`, 1e-13 of the column, and `R`
/// rounds at 1e-15), plus 1e-13 of the largest column for an unfelt one (zeroed
/// coefficients: rounding noise against 0).
#[test]
fn a_combination_norm_is_the_dependent_column_norm() {
    for (seed, pose) in [(2, true), (3, false)] {
        let (robot, data) = random_arm(seed, 1800, pose, 0);
        let (params, opts, b) = subsample_basis(&robot, &data);
        let problem = Problem::new(&robot, &data, &params, opts.weights, opts.orientation);
        let whole = spectrum::rows(&robot, &problem, &[], None, params.len()).unwrap();
        let rb = crate::linalg::r_of_columns(&whole.raug, &b.basis);
        let gram = Matrix::from_fn(b.basis.len(), b.basis.len(), |i, j| {
            let (ci, cj) = (whole.raug.col(b.basis[i]), whole.raug.col(b.basis[j]));
            ci.iter().zip(cj).map(|(x, y)| x * y).sum()
        });
        let by_r = basis::combination_norms(&b.coef, basis::CrossProducts::R(&rb));
        let by_gram = basis::combination_norms(&b.coef, basis::CrossProducts::Gram(&gram));
        let largest = (0..params.len())
            .map(|j| crate::linalg::col_norm(&whole.raug, j))
            .fold(0.0, f64::max);
        for (k, &d) in b.dependent.iter().enumerate() {
            let norm = crate::linalg::col_norm(&whole.raug, d);
            for c in [by_r[k], by_gram[k]] {
                assert!(
                    (c - norm).abs() <= 1e-12 * norm + 1e-13 * largest,
                    "seed {seed}: column {d}: {c} vs {norm}"
                );
            }
        }
    }
}

/// A problem with its columns in another order (the order the subsample basis's proof reads
/// them in) gives each parameter's column, and the residuals, to the bit.
#[test]
fn a_problem_with_its_columns_reordered_gives_the_same_columns() {
    let (robot, data) = random_arm(1, 60, true, 0);
    let params: Vec<ParamId> = robot.param_ids().collect();
    let opts = AnalysisOptions::default();
    let problem = Problem::new(&robot, &data, &params, opts.weights, opts.orientation);
    // Every third parameter first, then the rest, reversed.
    let mut order: Vec<ParamId> = params.iter().copied().step_by(3).collect();
    order.extend(params.iter().rev().filter(|id| id.0 % 3 != 0).copied());
    let reordered = problem.with_column_order(&order);
    let (m, n) = (problem.rows(), params.len());
    let (mut r1, mut r2) = (vec![0.0; m], vec![0.0; m]);
    let (mut j1, mut j2) = (Matrix::zeros(m, n), Matrix::zeros(m, n));
    problem.evaluate(&robot, &mut r1, Some(&mut j1));
    reordered.evaluate(&robot, &mut r2, Some(&mut j2));
    assert_eq!(r1, r2);
    let mut nonzero = 0;
    for (c2, id) in order.iter().enumerate() {
        let c1 = params.iter().position(|p| p == id).unwrap();
        for i in 0..m {
            assert_eq!(
                j1[(i, c1)].to_bits(),
                j2[(i, c2)].to_bits(),
                "{id:?}, row {i}"
            );
            nonzero += usize::from(j1[(i, c1)] != 0.0);
        }
    }
    assert!(nonzero > m * n / 2, "{nonzero} nonzero entries");
}

/// A fit that starts at the analysis's linearisation reports the errors at its start from
/// the analysis's pass, not a pass of its own: those of every observation, each within 1e-14
/// (m, rad) of a separate pass's, which takes the joint angles' sines from the dataset's table
/// (the same errors but for the rounding of coordinates about 1 m: 2.2e-16 m each).
#[test]
fn a_fit_from_the_linearisation_keeps_its_errors() {
    use crate::solve::estimation::{calibrate_from, CalibrationOptions};
    let (mut robot, data) = random_arm(1, 1800, true, 0);
    // Away from the robot that measured the data (every error non-zero): a link length and a
    // joint offset changed by 1 mm and 1 mrad.
    let params: Vec<ParamId> = robot.param_ids().collect();
    for (id, by) in [
        (ParamId(6), 1e-3),
        (robot.param_id(ParamKind::Offset { joint: 0 }), 1e-3),
    ] {
        robot.set(id, robot.get(id) + by);
    }
    let opts = AnalysisOptions::default();
    let (an, lin) = analyze_linearized(&robot, &data, &params, &opts).unwrap();
    let fit = CalibrationOptions::new(an.identifiable.clone());
    let cal = calibrate_from(&robot, &data, &fit, &mut |_| {}, Some(&lin)).unwrap();
    assert_eq!(cal.errors_before.as_ref(), Some(&lin.errors));
    let n = data.observations.len();
    let kept = lin
        .errors
        .for_robot(&robot, n)
        .expect("errors at the robot");
    let fresh = crate::observe::errors(&robot, &data);
    assert_eq!(kept.len(), fresh.len());
    for (k, f) in kept.iter().zip(&fresh) {
        assert_eq!(k.metric, f.metric);
        assert!((k.length - f.length).abs() <= 1e-14, "{k:?} vs {f:?}");
        let (ka, fa) = (k.angle.unwrap(), f.angle.unwrap());
        assert!((ka - fa).abs() <= 1e-14, "{k:?} vs {f:?}");
    }
    // Not the calibrated robot's: those the report computes.
    assert!(lin.errors.for_robot(&cal.calibrated, n).is_none());
}

/// A basis that the rows determine only poorly (joint 6 moved within +-2e-5 rad: its offset
/// and the tool link's roll nearly one column, though not within the rank tolerance) has a
/// Gram matrix too ill-conditioned for its `R` (a condition above 1e4): seen on the
/// subsample, the basis is folded by QR at once; forced through the Gram matrix of all the
/// rows, the fold asks for a QR. Either way the analysis is that of every row.
#[test]
fn an_ill_conditioned_basis_is_folded_by_qr() {
    let (robot, data) = random_arm_joint6(5, 1800, true, 2e-5);
    let (params, opts, b) = subsample_basis(&robot, &data);
    assert!(
        !b.gram,
        "the basis's condition on the subsample is above 1e4"
    );
    let problem = Problem::new(&robot, &data, &params, opts.weights, opts.orientation);
    let clamp = base::row_clamp(&data, &problem);
    let rows = b
        .fold_all(&robot, &problem, &clamp, opts.rcond)
        .expect("the basis's proof holds");
    let mut acc = linalg::QrAccumulator::new(params.len() + 1, 512);
    let mut r = vec![0.0; problem.rows()];
    problem.evaluate_qr(&robot, &mut r, &mut acc);
    let mut whole = Matrix::zeros(0, 0);
    acc.r_into(&mut whole);
    assert_same_inner_products(&rows.raug, &whole, 1e-11);
    assert!(matches!(
        b.fold_all_by(&robot, &problem, &clamp, opts.rcond, basis::Fold::Gram),
        Some(basis::Folded::NeedsQr)
    ));
    assert!(matches!(
        b.fold_all_by(&robot, &problem, &clamp, opts.rcond, basis::Fold::Qr),
        Some(basis::Folded::Rows(_))
    ));
    let (_, lin) = analyze_linearized(&robot, &data, &params, &opts).unwrap();
    assert_same_analysis(&robot, &data, &params, &lin);
}

/// A subsample that lost rank is not taken for all the data: its basis, from postures where
/// joint 6 stays put (its offset then one with the tool's roll), or from too few postures,
/// leaves out columns that are not combinations of it on every row, and the proof fails; a
/// subsample of full rank passes. Then the whole analysis runs, as without a subsample.
#[test]
fn a_subsample_that_lost_rank_fails_its_proof() {
    use rand::{RngExt, SeedableRng};
    let (robot, data) = random_arm(7, 1800, true, 300);
    let params: Vec<ParamId> = robot.param_ids().collect();
    let opts = AnalysisOptions::default();
    let problem = Problem::new(&robot, &data, &params, opts.weights, opts.orientation);
    let clamp = base::row_clamp(&data, &problem);
    let full = analyze_core(&robot, &data, &params, &opts).unwrap();
    assert_eq!(full.rank, 36);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let (mut lost, mut kept) = (0, 0);
    for trial in 0..24 {
        // Postures of the held joint (trial 0), or a few anywhere.
        let keep: Vec<bool> = if trial == 0 {
            (0..1800).map(|i| i < 300).collect()
        } else {
            let p = rng.random_range(0.001..0.012);
            (0..1800).map(|_| rng.random_range(0.0..1.0) < p).collect()
        };
        let sub = data.subset(&keep);
        if sub.observations.is_empty() {
            continue;
        }
        let b = basis::Basis::of(&robot, &sub, &params, &opts)
            .unwrap()
            .unwrap();
        let folded = b.fold_all(&robot, &problem, &clamp, opts.rcond);
        if b.basis.len() < full.rank {
            lost += 1;
            assert!(
                folded.is_none(),
                "trial {trial}: a basis of {}",
                b.basis.len()
            );
            // The same by a matrix product of every coefficient.
            let dense = b.clone().dense();
            assert!(dense
                .fold_all(&robot, &problem, &clamp, opts.rcond)
                .is_none());
        } else {
            kept += 1;
            let rows = folded.expect("a basis of full rank passes");
            let (accuracy, errors) = rows.accuracy.unwrap();
            let lin = Linearized {
                params: params.clone(),
                r: rows.raug,
                typical_row: rows.typical.unwrap(),
                accuracy,
                errors,
            };
            assert_same_analysis(&robot, &data, &params, &lin);
        }
    }
    assert!(lost >= 5 && kept >= 5, "{lost} lost rank, {kept} kept it");
    // Data whose subsample lost rank: the whole analysis.
    let (_, lin) = analyze_linearized(&robot, &data, &params, &opts).unwrap();
    assert_same_analysis(&robot, &data, &params, &lin);
}

/// The subsample keeps every kind of observation: 40 postures of a second session among
/// 3,000 are all kept (at least 2 n of each kind), the first session's evenly spaced.
#[test]
fn the_subsample_keeps_every_session() {
    let (_, mut data) = random_arm(3, 3000, false, 0);
    let other: std::sync::Arc<str> = "b".into();
    for p in data.postures.iter_mut().skip(1000).take(40) {
        p.session = Some(other.clone());
    }
    let keep = basis::subsample(&data, 30).unwrap();
    assert!(keep[1000..1040].iter().all(|&k| k));
    let first: Vec<usize> = (0..3000)
        .filter(|&i| keep[i] && !(1000..1040).contains(&i))
        .collect();
    assert_eq!(first.len(), 119);
    assert!(first[0] == 0 && *first.last().unwrap() > 2900);
    // Too small a dataset for a subsample to pay.
    assert!(basis::subsample(&data, 100).is_none());
}
