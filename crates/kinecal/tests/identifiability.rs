//! Identifiability analysis against the thesis (4.4.3, 4.4.7, 4.4.8) and its formulas.

mod common;

use kinecal::identifiability::{analyze, AnalysisOptions};
use kinecal::{examples, parse_param_list, simulate, JointKind, Link, ParamId, Site};
use rand::{RngExt, SeedableRng};

fn ids(list: &str, robot: &kinecal::Robot) -> Vec<ParamId> {
    parse_param_list(list, robot).unwrap()
}

#[test]
fn ge_a4_full_model_rank_24_with_the_thesis_identical_groups() {
    let robot = examples::ge_a4();
    let data = simulate::measure(&robot, &simulate::sample_postures(&robot, 30, 1988), false);
    let a = analyze(
        &robot,
        &data,
        &ids("all", &robot),
        &AnalysisOptions::default(),
    )
    .unwrap();
    assert_eq!(a.rank, 24);
    assert_eq!(a.parameters.len() - a.rank, 14);
    assert_eq!(a.expected.as_ref().unwrap().rank, 24);
    assert_eq!(a.gap_rank, 24);
    assert!(a.gap_ratio > 1e8, "gap {}", a.gap_ratio);
    let mut groups: Vec<Vec<usize>> = a
        .identical_groups
        .iter()
        .map(|g| g.terms.iter().map(|(id, _)| id.0 + 1).collect())
        .collect();
    groups.sort();
    assert_eq!(
        groups,
        vec![
            vec![3, 9, 15, 21, 27, 33],
            vec![4, 31],
            vec![10, 32],
            vec![13, 19],
            vec![14, 20],
            vec![16, 22, 34]
        ]
    );
    // 11 identical redundancies: members minus one per group.
    assert_eq!(groups.iter().map(|g| g.len() - 1).sum::<usize>(), 11);
    // Eq. 4.1: p3 - p9 - p15 - p21 - p27 - p33 = 5.79.
    let z = a
        .identical_groups
        .iter()
        .find(|g| g.terms[0].0 == ParamId(2))
        .unwrap();
    let coefs: Vec<f64> = z.terms.iter().map(|t| t.1).collect();
    assert_eq!(coefs, vec![1.0, -1.0, -1.0, -1.0, -1.0, -1.0]);
    assert!((z.value - 5.79).abs() < 1e-9);
    assert_eq!(a.null_space.len(), 14);
    assert_eq!(a.identifiable.len(), 24);
    // Joint offsets are kept (thesis advice).
    for p in 31..=34 {
        assert!(a.identifiable.contains(&ParamId(p - 1)), "p{p}");
    }
    // The identifiable set is really independent: analysing it alone gives full rank.
    let b = analyze(&robot, &data, &a.identifiable, &AnalysisOptions::default()).unwrap();
    assert_eq!(b.rank, 24);

    // Without the slopes: 34 parameters, rank 20 (eq. 4.3).
    let mut no_slopes = ids("all", &robot);
    no_slopes.retain(|id| !ids("slopes", &robot).contains(id));
    let c = analyze(&robot, &data, &no_slopes, &AnalysisOptions::default()).unwrap();
    assert_eq!(
        (c.parameters.len(), c.rank, c.expected.unwrap().rank),
        (34, 20, 20)
    );
}

#[test]
fn random_robots_follow_the_formula() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(17);
    for dof in 1..=6 {
        for trial in 0..3 {
            let kinds: Vec<JointKind> = (0..dof)
                .map(|_| {
                    if rng.random_range(0.0..1.0) < 0.3 {
                        JointKind::Prismatic
                    } else {
                        JointKind::Revolute
                    }
                })
                .collect();
            let seed = 10 * dof as u64 + trial;
            let mut robot = simulate::random_robot(&kinds, seed);
            let nr = kinds.iter().filter(|k| **k == JointKind::Revolute).count();
            let np = dof - nr;
            for with_site in [false, true] {
                if with_site {
                    robot.sites.push(Site {
                        name: "s".into(),
                        joint: rng.random_range(1..=dof),
                        frame: Link {
                            x: 0.1,
                            y: 0.05,
                            z: -0.2,
                            alpha: 0.4,
                            beta: 0.3,
                            gamma: -0.7,
                        },
                    });
                }
                let postures = simulate::sample_postures(&robot, 40, seed);
                for position_only in [false, true] {
                    let data = simulate::measure(&robot, &postures, position_only);
                    let frame = if position_only { 3 } else { 6 };
                    let sites = robot.sites.len();
                    let all: Vec<ParamId> = robot.param_ids().collect();
                    let a = analyze(&robot, &data, &all, &AnalysisOptions::default()).unwrap();
                    let expected = 5 * nr + 3 * np + frame * (1 + sites);
                    assert_eq!(
                        a.rank, expected,
                        "{kinds:?} site {with_site} position-only {position_only}"
                    );
                    assert_eq!(a.expected.unwrap().rank, expected);
                    let mut no_slopes = all.clone();
                    let slopes = parse_param_list("slopes", &robot).unwrap();
                    no_slopes.retain(|id| !slopes.contains(id));
                    let b =
                        analyze(&robot, &data, &no_slopes, &AnalysisOptions::default()).unwrap();
                    assert_eq!(
                        b.rank,
                        4 * nr + 2 * np + frame * (1 + sites),
                        "{kinds:?} without slopes"
                    );
                }
            }
        }
    }
}

use kinecal::estimation::{calibrate, CalibrationOptions};
use kinecal::observe::Weights;
use kinecal::workflow::{self, Request, Selection, SolutionRule};

/// Table 4.8 with the minimum-change rule: the same answer from every printed guess, and that
/// answer is Table 4.1 itself (the data were made by it).
#[test]
fn min_change_answer_does_not_depend_on_the_guess() {
    let runs = common::TABLE_4_8_GUESSES;
    let nominal = examples::ge_a4();
    let est = ids(common::TABLE_4_8_PARAMS, &nominal);
    let data = simulate::measure(
        &nominal,
        &simulate::sample_postures(&nominal, 30, 1988),
        false,
    );
    for run in runs {
        let mut start = nominal.clone();
        for (&id, &v) in est.iter().zip(&run) {
            start.set(id, start.units.to_si(start.param_quantity(id), v));
        }
        let mut req = Request::new(nominal.clone(), data.clone());
        req.selection = Selection::List(est.clone());
        req.initial = Some(start);
        req.solution = SolutionRule::MinChange;
        let cal = workflow::run(&req, &mut ()).unwrap().calibration;
        assert!(cal.objective_after < 1e-12 * cal.objective_before);
        for &id in &est {
            let (got, want) = (cal.calibrated.get_user(id), nominal.get_user(id));
            assert!(
                (got - want).abs() < 1e-6,
                "{run:?}: {id} = {got}, Table 4.1 says {want}"
            );
        }
    }
    // The same with all 38 parameters, from a random start.
    let std = simulate::PerturbStd {
        length: 0.05 * 0.0254,
        angle: 0.5f64.to_radians(),
        slope_fraction: 0.005,
    };
    let start = simulate::perturb(&nominal, std, 77);
    let mut req = Request::new(nominal.clone(), data.clone());
    req.selection = Selection::List(ids("all", &nominal));
    req.initial = Some(start);
    req.solution = SolutionRule::MinChange;
    let cal = workflow::run(&req, &mut ()).unwrap().calibration;
    for id in nominal.param_ids() {
        let (got, want) = (cal.calibrated.get(id), nominal.get(id));
        assert!(
            (got - want).abs() < 1e-7,
            "{} = {got}, nominal {want}",
            nominal.param_name(id)
        );
    }
}

/// The reported standard deviations agree with the spread of estimates over noisy repetitions.
#[test]
fn monte_carlo_sigmas_match_the_spread() {
    let nominal = examples::ge_a4();
    let postures = simulate::sample_postures(&nominal, 30, 5);
    let clean = simulate::measure(&nominal, &postures, false);
    let all = ids("all", &nominal);
    let base = analyze(&nominal, &clean, &all, &AnalysisOptions::default())
        .unwrap()
        .identifiable;
    let (sl, sa) = (0.002 * 0.0254, 0.02f64.to_radians());
    let mut opts = CalibrationOptions::new(base.clone());
    opts.weights = Weights {
        length: sl,
        angle: sa,
    };
    let runs = 300;
    let mut estimates = vec![Vec::with_capacity(runs); base.len()];
    let mut sigmas = vec![0.0; base.len()];
    let mut combo = (Vec::new(), 0.0);
    let mut full = ids("all", &nominal);
    full.retain(|id| !ids("slopes", &nominal).contains(id));
    for seed in 0..runs as u64 {
        let mut data = clean.clone();
        simulate::add_noise(&mut data, sl, sa, 1000 + seed);
        let cal = calibrate(&nominal, &data, &opts, &mut |_| {}).unwrap();
        let u = kinecal::uncertainty::uncertainty(&cal, &data, &nominal).unwrap();
        for (k, &id) in base.iter().enumerate() {
            estimates[k].push(cal.calibrated.get_user(id));
            sigmas[k] += u.parameter(id).unwrap().sigma.unwrap() / runs as f64;
        }
        assert!(
            (u.variance_factor - 1.0).abs() < 0.5,
            "variance factor {}",
            u.variance_factor
        );
        if seed < 100 {
            // A redundant model: the identical group's combination (eq. 4.1) has a sigma too.
            let mut o = opts.clone();
            o.estimate = full.clone();
            let cal = calibrate(&nominal, &data, &o, &mut |_| {}).unwrap();
            let u = kinecal::uncertainty::uncertainty(&cal, &data, &nominal).unwrap();
            let c = u
                .combinations
                .iter()
                .find(|c| c.terms[0].0 == ParamId(2))
                .unwrap();
            combo.0.push(c.value);
            combo.1 += c.sigma / 100.0;
            assert!(
                u.parameter(ParamId(2)).unwrap().sigma.is_none(),
                "p3 alone is not determined"
            );
        }
    }
    let spread = |v: &[f64]| {
        let mean = v.iter().sum::<f64>() / v.len() as f64;
        (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (v.len() - 1) as f64).sqrt()
    };
    // 300 runs estimate a standard deviation to ~4 % (1/sqrt(2*299)); 15 % is ~3.5 of those.
    for (k, &id) in base.iter().enumerate() {
        let s = spread(&estimates[k]);
        eprintln!("{}: ratio {:.3}", nominal.param_name(id), sigmas[k] / s);
        assert!(
            (sigmas[k] / s - 1.0).abs() < 0.15,
            "{}: reported {} vs spread {s}",
            nominal.param_name(id),
            sigmas[k]
        );
    }
    // 100 runs: ~7 %; 25 % is ~3.5 of those.
    let s = spread(&combo.0);
    assert!(
        (combo.1 / s - 1.0).abs() < 0.25,
        "eq. 4.1 combination: reported {} vs spread {s}",
        combo.1
    );
}

#[test]
fn a_link_at_beta_90_is_reported_as_a_parameterisation_singularity() {
    let mut robot = simulate::random_robot(&[JointKind::Revolute; 3], 8);
    robot.links[1].beta = std::f64::consts::FRAC_PI_2;
    let data = simulate::measure(&robot, &simulate::sample_postures(&robot, 30, 2), false);
    let a = analyze(
        &robot,
        &data,
        &ids("all", &robot),
        &AnalysisOptions::default(),
    )
    .unwrap();
    assert_eq!(a.euler_singular, vec!["link2".to_string()]);
    assert!(a
        .warnings
        .iter()
        .any(|w| w.to_string().contains("gimbal lock")));
    // alpha and gamma of link 2 now rotate about the same axis: identically redundant.
    let (alpha, gamma) = (ParamId(6 + 3), ParamId(6 + 5));
    assert!(a
        .identical_groups
        .iter()
        .any(|g| g.terms.iter().any(|t| t.0 == alpha) && g.terms.iter().any(|t| t.0 == gamma)));
}

#[test]
fn multi_site_data_calibrates_sites_and_follows_eq_4_5() {
    let mut nominal = simulate::random_robot(
        &[
            JointKind::Revolute,
            JointKind::Revolute,
            JointKind::Prismatic,
            JointKind::Revolute,
        ],
        21,
    );
    for (k, joint) in [(0, 1), (1, 3)] {
        nominal.sites.push(Site {
            name: format!("site{k}"),
            joint,
            frame: Link {
                x: 0.1,
                y: -0.05,
                z: 0.02,
                alpha: 0.2,
                beta: 0.1,
                gamma: -0.3,
            },
        });
    }
    let std = simulate::PerturbStd {
        length: 1e-3,
        angle: 0.3f64.to_radians(),
        slope_fraction: 0.002,
    };
    let truth = simulate::perturb(&nominal, std, 4);
    let data = simulate::measure(&truth, &simulate::sample_postures(&nominal, 30, 9), false);
    let all = ids("all", &nominal);
    let a = analyze(&nominal, &data, &all, &AnalysisOptions::default()).unwrap();
    // N_s = 5 nr + 3 np + 6 ns with ns = 3 measured frames (eq. 4.5).
    assert_eq!(a.rank, 5 * 3 + 3 + 6 * 3);
    let opts = CalibrationOptions::new(all);
    let cal = calibrate(&nominal, &data, &opts, &mut |_| {}).unwrap();
    assert!(cal.objective_after < 1e-12 * cal.objective_before);
    // Every site's pose is reproduced (the calibrated model predicts each measured frame).
    assert!(cal.accuracy_after.rms_position < 1e-9 && cal.accuracy_after.rms_orientation < 1e-9);
}

#[test]
fn priority_and_tolerances_are_the_users_to_set() {
    let robot = examples::ge_a4();
    let data = simulate::measure(&robot, &simulate::sample_postures(&robot, 30, 3), false);
    let all = ids("all", &robot);
    // Default: the joint offset p31 is kept, its identical twin p4 is not.
    let a = analyze(&robot, &data, &all, &AnalysisOptions::default()).unwrap();
    assert!(a.identifiable.contains(&ParamId(30)) && !a.identifiable.contains(&ParamId(3)));
    // Preferring p4 swaps them.
    let opts = AnalysisOptions {
        priority: vec![ParamId(3)],
        ..Default::default()
    };
    let b = analyze(&robot, &data, &all, &opts).unwrap();
    assert!(b.identifiable.contains(&ParamId(3)) && !b.identifiable.contains(&ParamId(30)));
    assert_eq!(b.identifiable.len(), 24);

    let text = format!(
        "{}\n[tolerances]\nlength = 0.04\nangle = 0.2\nslope = 0.02\n\"link3.y\" = 0.5\np31 = 1.0\n",
        kinecal::examples::GE_A4_TOML
    );
    let r = kinecal::robot_file::parse_robot_toml(&text, "t.toml").unwrap();
    assert!((r.tolerance(ParamId(0)) - 0.04 * 0.0254).abs() < 1e-15);
    assert!((r.tolerance(ParamId(3)) - 0.2f64.to_radians()).abs() < 1e-15);
    assert!((r.tolerance(ParamId(13)) - 0.5 * 0.0254).abs() < 1e-15);
    assert!((r.tolerance(ParamId(30)) - 1f64.to_radians()).abs() < 1e-15);
    assert!((r.tolerance(ParamId(34)) - 0.02 * 7.2f64.to_radians()).abs() < 1e-15);
    let bad = format!(
        "{}\n[tolerances]\nlink9.x = 1\n",
        kinecal::examples::GE_A4_TOML
    );
    let err = kinecal::robot_file::parse_robot_toml(&bad, "t.toml")
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("tolerances.link9.x") || err.contains("tolerances"),
        "{err}"
    );
    // The file keeps its [tolerances] table when written back.
    let out = kinecal::robot_file::write_robot_toml(&r, Some(&text));
    assert!(out.contains("\"link3.y\" = 0.5"));
}

/// Full rank by the tolerance, but a clear gap in the spectrum before the last singular value:
/// not "consistent", and a warning says so.
#[test]
fn a_full_rank_with_a_clear_gap_elsewhere_is_not_called_consistent() {
    let mut robot = examples::ge_a4();
    // Joint 1's axis tilted by 0.001 deg: link 2's z (along it) and link 1's z are nearly, not
    // exactly, redundant.
    robot.links[0].gamma = 1e-3f64.to_radians();
    let data = simulate::measure(&robot, &simulate::sample_postures(&robot, 30, 3), false);
    let a = analyze(
        &robot,
        &data,
        &ids("p3,p8,p9,p14", &robot),
        &AnalysisOptions::default(),
    )
    .unwrap();
    assert_eq!(a.rank, 4);
    assert_eq!(a.gap_rank, 3);
    assert!(a.gap_ratio > 1e3, "{}", a.gap_ratio);
    assert!(!a.rank_consistent);
    assert!(a.warnings.iter().any(|w| matches!(
        w,
        kinecal::Warning::UnclearRank {
            rank: 4,
            gap_rank: 3,
            ..
        }
    )));
    // A well-conditioned full-rank set is consistent.
    let b = analyze(
        &robot,
        &data,
        &ids("p1,p2,p8,p14", &robot),
        &AnalysisOptions::default(),
    )
    .unwrap();
    assert!(
        b.rank_consistent && b.warnings.is_empty(),
        "{:?}",
        b.warnings
    );
}

/// The analysis works on the R accumulated a block of rows at a time; the Jacobian table
/// (`analyze --print`) is the whole m x n matrix, formed directly. Their singular values, in
/// scaled and in file units, agree, and the scaled table has unit (or zeroed) columns: more
/// rows than one accumulation block, so the block folding is exercised.
#[test]
fn the_accumulated_analysis_matches_the_whole_jacobian() {
    let robot = simulate::random_robot(&[JointKind::Revolute; 6], 11);
    let data = simulate::measure(&robot, &simulate::sample_postures(&robot, 300, 5), false);
    let params: Vec<ParamId> = robot.param_ids().collect();
    let opts = AnalysisOptions::default();
    let an = analyze(&robot, &data, &params, &opts).unwrap();
    let table = kinecal::identifiability::jacobian_table(&robot, &data, &an, &opts);
    assert_eq!(table.row_labels.len(), 1800);
    let sv = |m: &kinecal::linalg::Matrix| {
        nalgebra::DMatrix::from_fn(m.nrows(), m.ncols(), |i, j| m[(i, j)])
            .singular_values()
            .as_slice()
            .to_vec()
    };
    for (mine, whole) in [
        (&an.singular_values_scaled, sv(&table.scaled)),
        (&an.singular_values_file, sv(&table.file)),
    ] {
        let mut whole = whole;
        whole.sort_by(|a, b| b.total_cmp(a));
        assert_eq!(mine.len(), whole.len());
        // Both are backward stable: agreement to a few hundred ulps of the largest.
        for (a, b) in mine.iter().zip(&whole) {
            assert!((a - b).abs() < 1e-12 * whole[0], "{a} vs {b}");
        }
    }
    for j in 0..params.len() {
        let norm = table
            .scaled
            .col(j)
            .iter()
            .map(|x| x * x)
            .sum::<f64>()
            .sqrt();
        assert!(
            norm < 1e-12 || (norm - 1.0).abs() < 1e-12,
            "column {j}: {norm}"
        );
    }
}
