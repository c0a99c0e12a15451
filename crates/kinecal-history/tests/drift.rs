//! Drift detection on simulated maintenance histories.

use kinecal::apps::simulate::{self, PerturbStd};
use kinecal::observe::Weights;
use kinecal::report::CalibrationReport;
use kinecal::workflow::{self, Request, Selection, SolutionRule};
use kinecal::{model::examples, ParamId};
use kinecal_history::{drift, Database, DriftOptions};

const DAY: i64 = 86_400;

/// One calibration of `truth` from `start`, as `kinecal calibrate [--solution min-change]` does,
/// with the uncertainty in its report.
fn calibrate_report(
    nominal: &kinecal::Robot,
    truth: &kinecal::Robot,
    start: &kinecal::Robot,
    seed: u64,
    min_change: bool,
) -> CalibrationReport {
    let (sl, sa) = (0.0005 * 0.0254, 0.005f64.to_radians());
    let mut data = simulate::measure(truth, &simulate::sample_postures(nominal, 30, seed), false);
    simulate::add_noise(&mut data, sl, sa, seed + 1000);
    let mut req = Request::new(nominal.clone(), data);
    req.selection = Selection::List(nominal.param_ids().collect());
    req.initial = Some(start.clone());
    req.weights = Weights {
        length: sl,
        angle: sa,
    };
    if min_change {
        req.solution = SolutionRule::MinChange;
    }
    let outcome = workflow::run(&req, &mut ()).unwrap();
    assert!(outcome.uncertainty.is_some());
    outcome.report
}

/// A different starting guess each month, as in the thesis's Table 4.8: lengths, alpha angles,
/// offsets and slopes start elsewhere each time (beta and gamma stay at their design values, so
/// the design's parallel axes, and with them its redundancies, are kept).
fn guess(nominal: &kinecal::Robot, seed: u64) -> kinecal::Robot {
    let std = PerturbStd {
        length: 0.3 * 0.0254,
        angle: 2f64.to_radians(),
        slope_fraction: 0.002,
    };
    let mut g = simulate::perturb(nominal, std, seed);
    for (l, n) in g.links.iter_mut().zip(&nominal.links) {
        l.beta = n.beta;
        l.gamma = n.gamma;
    }
    g
}

/// Link 3's length grows 0.02 in during month 6, the robot is calibrated monthly for a year from
/// different initial guesses with measurement noise: drift flags that quantity (the determined
/// combination of link 3 and link 4 lengths along y, since the two cannot be told apart) within
/// 3 months of its change exceeding 3 sigma, and nothing else.
#[test]
fn wear_of_link_3_is_flagged_and_nothing_else() {
    let dir = tempfile::tempdir().unwrap();
    let db = Database::open(dir.path().join("h.sqlite")).unwrap();
    let nominal = examples::ge_a4();
    let p14 = ParamId(13);
    let wear = |month: f64| 0.02 * 0.0254 * (month - 6.0).clamp(0.0, 1.0);
    let mut first_exceeds: Option<usize> = None;
    let mut first_flag: Option<usize> = None;
    for month in 0..=12usize {
        let mut truth = nominal.clone();
        truth.set(p14, nominal.get(p14) + wear(month as f64));
        let rep = calibrate_report(
            &nominal,
            &truth,
            &guess(&nominal, 500 + month as u64),
            40 + month as u64,
            true,
        );
        db.add(
            "A4-WEAR",
            Some(1_780_000_000 + month as i64 * 30 * DAY),
            &rep,
            "monthly",
        )
        .unwrap();
        let r = drift(
            &db.calibrations(Some("A4-WEAR")).unwrap(),
            &DriftOptions::default(),
        )
        .unwrap();
        if month == 0 {
            // One calibration: nothing to compare yet.
            assert!(r.nothing_to_compare.is_some() && r.quantities.is_empty());
            continue;
        }
        let target = r
            .quantities
            .iter()
            .find(|q| q.key == "p14 + p20")
            .expect("link 3+4 y lengths are tracked");
        assert_eq!(target.quantity, "y lengths of links 3 and 4, together");
        // When does the true change (0.02 in) exceed 3 sigma of the comparison?
        if first_exceeds.is_none() && wear(month as f64) > 3.0 * target.sigma * 0.0254 {
            first_exceeds = Some(month);
        }
        if target.flagged && first_flag.is_none() {
            first_flag = Some(month);
        }
        for q in &r.quantities {
            assert!(
                !q.flagged || q.key == "p14 + p20",
                "month {month}: false flag on {} ({:.1} sigma)",
                q.quantity,
                q.significance
            );
        }
        // Never a lone redundant parameter.
        assert!(r
            .quantities
            .iter()
            .all(|q| q.key != "link3.y" && q.key != "link4.y"));
    }
    let (exceeds, flag) = (
        first_exceeds.expect("the change exceeds 3 sigma"),
        first_flag.expect("flagged"),
    );
    assert!(
        flag >= exceeds && flag <= exceeds + 3,
        "exceeds at month {exceeds}, flagged at {flag}"
    );
}

/// 50 histories of a robot that does not change, calibrated from different guesses with the
/// plain solver (so redundant parameters wander): at K = 3 at most 1 % of the tracked
/// quantities are flagged.
#[test]
fn no_false_alarms_on_an_unchanging_robot() {
    let nominal = examples::ge_a4();
    let (mut flagged, mut total, mut wandering) = (0usize, 0usize, 0usize);
    for h in 0..50u64 {
        let dir = tempfile::tempdir().unwrap();
        let db = Database::open(dir.path().join("h.sqlite")).unwrap();
        let mut wandered = 0.0f64;
        let mut first_p3 = None;
        for k in 0..3u64 {
            let rep = calibrate_report(
                &nominal,
                &nominal,
                &guess(&nominal, 10_000 + 10 * h + k),
                20_000 + 10 * h + k,
                false,
            );
            let p3 = rep.parameters[2].estimated;
            wandered = wandered.max((p3 - *first_p3.get_or_insert(p3)).abs());
            db.add(
                "A4-STILL",
                Some(1_780_000_000 + k as i64 * 30 * DAY),
                &rep,
                "",
            )
            .unwrap();
        }
        if wandered > 0.01 {
            wandering += 1;
        }
        let r = drift(
            &db.calibrations(Some("A4-STILL")).unwrap(),
            &DriftOptions::default(),
        )
        .unwrap();
        total += r.quantities.len();
        flagged += r.flags.len();
    }
    // The redundant z lengths really did wander (by more than 0.01 in, twenty times their
    // noise) in most histories: the trap of thesis Table 4.8 was set.
    assert!(
        wandering >= 40,
        "p3 wandered in only {wandering} of 50 histories"
    );
    assert!(total > 50 * 10);
    eprintln!("{flagged} of {total} quantities flagged, {wandering} of 50 histories wandered");
    assert!(
        (flagged as f64) <= 0.01 * total as f64,
        "{flagged} of {total} quantities flagged"
    );
}
