//! Measurement planning: the criteria are what their formulas say, the search ends where no swap
//! improves the plan, a plan retains the pool's information, and it calibrates better than
//! random postures.

use kinecal::apps::plan::{candidates, plan, Criterion, PlanRequest};
use kinecal::apps::simulate::{self, PerturbStd};
use kinecal::model::kinematics::Target;
use kinecal::observe::accuracy;
use kinecal::workflow::{self, Request, Selection};
use kinecal::{Dataset, JointKind, Posture, Robot};
use nalgebra::DMatrix;

fn twin() -> (Robot, Robot) {
    let nominal = simulate::random_robot(&[JointKind::Revolute; 6], 31);
    let std = PerturbStd {
        length: 1e-3,
        angle: 0.2f64.to_radians(),
        slope_fraction: 0.002,
    };
    (nominal.clone(), simulate::perturb(&nominal, std, 5))
}

fn tool_positions(robot: &Robot, postures: Vec<Posture>) -> Dataset {
    candidates(robot, postures, &[Target::EndEffector], true)
}

/// Calibrates the identifiable set from `postures` measured on `truth` with 0.05 mm noise
/// (seed `seed`); the mean position error on `test`.
fn held_out(
    nominal: &Robot,
    truth: &Robot,
    postures: &[Posture],
    test: &Dataset,
    seed: u64,
) -> f64 {
    let mut data = tool_positions(truth, postures.to_vec());
    simulate::add_noise(&mut data, 0.05e-3, 0.0, seed);
    let mut req = Request::new(nominal.clone(), data);
    req.selection = Selection::Identifiable {
        with: vec![],
        fix: vec![],
    };
    let out = workflow::run(&req, &mut ()).expect("calibrates");
    accuracy(&out.calibration.calibrated, test).mean_position
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn postures_of(p: &kinecal::apps::plan::Plan) -> Vec<Posture> {
    p.postures
        .iter()
        .map(|q| Posture {
            label: q.label.clone(),
            readings: q.readings.clone(),
            session: None,
            payload: None,
        })
        .collect()
}

/// The test: 30 of 1,000 sampled candidates of a 6-joint robot (tracker positions of
/// the tool). The plan is judged by its expected held-out error: the median over 40 noise draws
/// against the median of 100 random plans (each with its own draw), both on 200 fresh postures
/// measured without noise, so that only the plan differs.
///
/// Measured on 5 robot/noise seeds while building it (release): D 16-21 % below the random
/// median, I 17-26 %; on this robot (the first seed tried) D 21 %, I 25 %. The theory says why
/// the margin is modest: a random plan's mean prediction variance is `n/K` inflated by about
/// `rows / (rows - n)` (here 90 rows, 33 parameters: 1.6), and a plan can at best remove that
/// inflation and some more: the I value of the plan is 0.57 of the random median's, so the
/// error, which scales with its square root, can fall by about 25 %.
#[test]
fn a_plan_of_30_from_1000_candidates_retains_the_information_and_beats_random_plans() {
    let (nominal, truth) = twin();
    let pool = tool_positions(&nominal, simulate::sample_postures(&nominal, 1000, 3));
    let test = tool_positions(&truth, simulate::sample_postures(&nominal, 200, 77));
    let random: Vec<f64> = (0..100)
        .map(|k| {
            let ps = simulate::sample_postures(&nominal, 30, 1000 + k);
            held_out(&nominal, &truth, &ps, &test, 9000 + k)
        })
        .collect();
    let random = median(random);
    for (criterion, below) in [(Criterion::D, 0.20), (Criterion::I, 0.20)] {
        let mut req = PlanRequest::new(nominal.clone(), pool.clone(), 30);
        req.criterion = criterion;
        let p = plan(&req).unwrap();
        assert_eq!(p.postures.len(), 30);
        assert_eq!(
            p.rank,
            p.parameters.len(),
            "the plan determines the identifiable set"
        );
        assert_eq!(p.pool_candidates, 1000);
        // The information per posture the plan retains: above the pool's average.
        let eff = p.efficiency.unwrap();
        assert!(eff >= 0.95, "{criterion:?}: D-efficiency {eff}");
        let r = p.random.as_ref().unwrap();
        assert!(
            r.beaten == r.draws,
            "{criterion:?}: beats every random plan by its criterion"
        );
        assert!(eff > r.median_efficiency.unwrap());
        let chosen = postures_of(&p);
        let own = median(
            (0..40)
                .map(|k| held_out(&nominal, &truth, &chosen, &test, 5000 + k))
                .collect(),
        );
        eprintln!(
            "{criterion:?}: plan {:.4} mm, random median {:.4} mm ({:.1} % below); efficiency \
             {eff:.3} (random median {:.3})",
            own * 1e3,
            random * 1e3,
            100.0 * (1.0 - own / random),
            r.median_efficiency.unwrap()
        );
        assert!(
            own <= (1.0 - below) * random,
            "{criterion:?}: {own} against {random}"
        );
    }
}

/// Every criterion the plan reports, recomputed from the stacked scaled Jacobian with a
/// different library (nalgebra's SVD and inverse) and the definitions; and the leverages sum to
/// the number of parameters.
#[test]
fn the_criteria_are_their_definitions() {
    let (nominal, _) = twin();
    let pool = candidates(
        &nominal,
        simulate::sample_postures(&nominal, 80, 4),
        &[Target::EndEffector],
        false,
    );
    let mut req = PlanRequest::new(nominal.clone(), pool.clone(), 12);
    req.criterion = Criterion::A;
    let p = plan(&req).unwrap();
    let n = p.parameters.len();
    assert_eq!(p.rank, n);
    // The scaled Jacobian, rebuilt: weighted rows, columns divided by their RMS per candidate.
    let jac = |data: &Dataset| -> DMatrix<f64> {
        let pr = kinecal::solve::problem::Problem::new(
            &nominal,
            data,
            &p.parameters,
            Default::default(),
            Default::default(),
        );
        let mut res = vec![0.0; pr.rows()];
        let mut j = kinecal::linalg::Matrix::zeros(0, 0);
        pr.evaluate(&nominal, &mut res, Some(&mut j));
        DMatrix::from_fn(j.nrows(), j.ncols(), |r, c| j[(r, c)])
    };
    let jp = jac(&pool);
    let scale: Vec<f64> = (0..n)
        .map(|c| (jp.column(c).norm_squared() / 80.0).sqrt())
        .collect();
    let scaled = |mut m: DMatrix<f64>| {
        for (c, s) in scale.iter().enumerate() {
            m.column_mut(c).scale_mut(1.0 / s);
        }
        m
    };
    let j = scaled(jac(&p.chosen));
    let w = scaled(jp.clone()).transpose() * scaled(jp) / 80.0;
    let m = j.transpose() * &j;
    let minv = m.clone().try_inverse().unwrap();
    let s = j.clone().svd(false, false).singular_values;
    let (smin, smax) = (s.min(), s.max());
    let rows = j.nrows() as f64;
    let expected = [
        (Criterion::D, s.iter().map(|v| 2.0 * v.ln()).sum::<f64>()),
        (Criterion::A, minv.trace()),
        (Criterion::I, (&w * &minv).trace()),
        (Criterion::E, smin * smin),
        (
            Criterion::O1,
            s.iter().product::<f64>().powf(1.0 / n as f64) / rows.sqrt(),
        ),
        (Criterion::O2, smin / smax),
        (Criterion::O3, smin),
        (Criterion::O4, smin * smin / smax),
        (Criterion::O5, 1.0 / s.iter().map(|v| 1.0 / v).sum::<f64>()),
    ];
    for (c, want) in expected {
        let got = p.values.iter().find(|(k, _)| *k == c).unwrap().1.unwrap();
        assert!(
            (got - want).abs() <= 1e-9 * want.abs().max(1.0),
            "{c:?}: {got} against {want}"
        );
    }
    assert_eq!(p.value, p.values[1].1);
    assert!((p.condition_number.unwrap() - smax / smin).abs() < 1e-9 * smax / smin);
    let lev: f64 = p.postures.iter().map(|q| q.leverage).sum();
    assert!((lev - n as f64).abs() < 1e-9, "leverages sum to {lev}");
    // Each posture's leverage is the trace of its rows' hat block.
    let q0 = &p.postures[0];
    let rows0: Vec<usize> = (0..6).collect();
    let h: f64 = rows0
        .iter()
        .map(|&r| (j.row(r) * &minv * j.row(r).transpose())[(0, 0)])
        .sum();
    assert!(
        (q0.leverage - h).abs() < 1e-9,
        "{} against {h}",
        q0.leverage
    );
}

/// The exchange stops where no single swap of a chosen posture for a candidate improves the
/// criterion: checked by brute force, recomputing each swapped plan's criterion from scratch.
#[test]
fn no_single_swap_improves_a_d_a_or_i_plan() {
    let (nominal, _) = twin();
    let pool = tool_positions(&nominal, simulate::sample_postures(&nominal, 40, 6));
    for criterion in [Criterion::D, Criterion::A, Criterion::I] {
        let mut req = PlanRequest::new(nominal.clone(), pool.clone(), 14);
        req.criterion = criterion;
        let p = plan(&req).unwrap();
        let chosen: Vec<usize> = p.postures.iter().map(|q| q.candidate.unwrap()).collect();
        let own = p.value.unwrap();
        let sign = if criterion.larger_is_better() {
            1.0
        } else {
            -1.0
        };
        for (slot, _) in chosen.iter().enumerate() {
            for c in 0..40 {
                if chosen.contains(&c) {
                    continue;
                }
                let mut set = chosen.clone();
                set[slot] = c;
                let v = rate_fixed(&nominal, &pool, &p.parameters, &set, criterion);
                assert!(
                    sign * v <= sign * own * (1.0 + 1e-9) + 1e-12,
                    "{criterion:?}: swapping slot {slot} for candidate {c} gives {v}, better \
                     than {own}"
                );
            }
        }
    }
}

/// A criterion of candidates `set` of `pool`, on the pool's column scale, computed with
/// nalgebra from the definitions.
fn rate_fixed(
    robot: &Robot,
    pool: &Dataset,
    params: &[kinecal::ParamId],
    set: &[usize],
    criterion: Criterion,
) -> f64 {
    let pr = kinecal::solve::problem::Problem::new(
        robot,
        pool,
        params,
        Default::default(),
        Default::default(),
    );
    let mut res = vec![0.0; pr.rows()];
    let mut j = kinecal::linalg::Matrix::zeros(0, 0);
    pr.evaluate(robot, &mut res, Some(&mut j));
    let n = params.len();
    let rows_per = j.nrows() / pool.postures.len();
    let full = DMatrix::from_fn(j.nrows(), n, |r, c| j[(r, c)]);
    let scale: Vec<f64> = (0..n)
        .map(|c| (full.column(c).norm_squared() / pool.postures.len() as f64).sqrt())
        .collect();
    let scaled = DMatrix::from_fn(full.nrows(), n, |r, c| full[(r, c)] / scale[c]);
    let w = scaled.transpose() * &scaled / pool.postures.len() as f64;
    let sub = DMatrix::from_fn(set.len() * rows_per, n, |r, c| {
        scaled[(set[r / rows_per] * rows_per + r % rows_per, c)]
    });
    let m = sub.transpose() * &sub;
    match criterion {
        Criterion::D => m.determinant().ln(),
        Criterion::A => m.try_inverse().unwrap().trace(),
        Criterion::I => (w * m.try_inverse().unwrap()).trace(),
        _ => unreachable!(),
    }
}

/// Kept postures are always in the plan, listed first; a plan is the same every time; bad
/// requests are refused with a message.
#[test]
fn kept_postures_determinism_and_refusals() {
    let (nominal, _) = twin();
    let sampled = simulate::sample_postures(&nominal, 300, 8);
    let pool = tool_positions(&nominal, sampled[..250].to_vec());
    let keep = tool_positions(&nominal, sampled[250..270].to_vec());
    let mut req = PlanRequest::new(nominal.clone(), pool.clone(), 10);
    req.keep = keep;
    let p = plan(&req).unwrap();
    assert_eq!(p.postures.len(), 30);
    assert!(p.postures[..20].iter().all(|q| q.candidate.is_none()));
    assert!(p.postures[20..].iter().all(|q| q.candidate.is_some()));
    assert_eq!(p.chosen.postures.len(), 10);
    let again = plan(&req).unwrap();
    assert_eq!(p.postures, again.postures);
    assert_eq!(p.random, again.random);
    // Without the kept ones the plan differs: the kept postures' information counts.
    let alone = plan(&PlanRequest::new(nominal.clone(), pool.clone(), 10)).unwrap();
    assert_ne!(
        alone
            .postures
            .iter()
            .map(|q| q.candidate)
            .collect::<Vec<_>>(),
        p.postures[20..]
            .iter()
            .map(|q| q.candidate)
            .collect::<Vec<_>>()
    );

    for (count, says) in [(0, "at least 1"), (251, "the pool has 250 candidates")] {
        let e = plan(&PlanRequest::new(nominal.clone(), pool.clone(), count)).unwrap_err();
        assert!(e.to_string().contains(says), "{e}");
    }
    let e = plan(&PlanRequest::new(nominal.clone(), Dataset::default(), 3)).unwrap_err();
    assert!(e.to_string().contains("no candidate"), "{e}");
    assert!("o6"
        .parse::<Criterion>()
        .unwrap_err()
        .to_string()
        .contains("o5"));
    assert_eq!("O4".parse::<Criterion>().unwrap(), Criterion::O4);

    // Too few postures for the parameters: the plan says what rank it reaches.
    let p = plan(&PlanRequest::new(nominal.clone(), pool, 4)).unwrap();
    assert!(p.rank < p.parameters.len());
    assert_eq!(p.value, None);
    assert_eq!(p.condition_number, None);
}
