//! Identifiability analysis against the thesis (4.4.3, 4.4.7, 4.4.8) and its formulas.

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
    let a = analyze(&robot, &data, &ids("all", &robot), &AnalysisOptions::default()).unwrap();
    assert_eq!(a.rank, 24);
    assert_eq!(a.parameters.len() - a.rank, 14);
    assert_eq!(a.expected.as_ref().unwrap().rank, 24);
    assert_eq!(a.gap_rank, 24);
    assert!(a.gap_ratio > 1e8, "gap {}", a.gap_ratio);
    let mut groups: Vec<Vec<usize>> =
        a.identical_groups.iter().map(|g| g.terms.iter().map(|(id, _)| id.0 + 1).collect()).collect();
    groups.sort();
    assert_eq!(
        groups,
        vec![vec![3, 9, 15, 21, 27, 33], vec![4, 31], vec![10, 32], vec![13, 19], vec![14, 20], vec![16, 22, 34]]
    );
    // 11 identical redundancies: members minus one per group.
    assert_eq!(groups.iter().map(|g| g.len() - 1).sum::<usize>(), 11);
    // Eq. 4.1: p3 - p9 - p15 - p21 - p27 - p33 = 5.79.
    let z = a.identical_groups.iter().find(|g| g.terms[0].0 == ParamId(2)).unwrap();
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
    assert_eq!((c.parameters.len(), c.rank, c.expected.unwrap().rank), (34, 20, 20));
}

#[test]
fn random_robots_follow_the_formula() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(17);
    for dof in 1..=6 {
        for trial in 0..3 {
            let kinds: Vec<JointKind> = (0..dof)
                .map(|_| if rng.random_range(0.0..1.0) < 0.3 { JointKind::Prismatic } else { JointKind::Revolute })
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
                        frame: Link { x: 0.1, y: 0.05, z: -0.2, alpha: 0.4, beta: 0.3, gamma: -0.7 },
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
                    assert_eq!(a.rank, expected, "{kinds:?} site {with_site} position-only {position_only}");
                    assert_eq!(a.expected.unwrap().rank, expected);
                    let mut no_slopes = all.clone();
                    let slopes = parse_param_list("slopes", &robot).unwrap();
                    no_slopes.retain(|id| !slopes.contains(id));
                    let b = analyze(&robot, &data, &no_slopes, &AnalysisOptions::default()).unwrap();
                    assert_eq!(b.rank, 4 * nr + 2 * np + frame * (1 + sites), "{kinds:?} without slopes");
                }
            }
        }
    }
}
