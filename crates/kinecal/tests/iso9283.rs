//! ISO 9283 pose characteristics: the figures against an independent, plain computation on
//! synthetic logs (known offsets, Gaussian noise), exact small cases worked by hand, the test
//! poses of a plan where the standard puts them and reached by the robot, and bad logs refused
//! with their file, line and field.
#![allow(clippy::needless_range_loop)] // coordinates are indexed by axis, as in the formulas

use kinecal::apps::iso9283::{
    evaluate, plan, read_log, read_plan, simulate, write_log, write_plan, Cube, Log, LogRow,
    LogUnits, PlanRequest, SimulateRequest, CYCLE, STANDARD_CYCLES,
};
use kinecal::model::kinematics::{rot_zyx, Chain, Target};
use kinecal::model::robot_file::parse_robot_toml;
use kinecal::{AngleUnit, LengthUnit, Robot};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

fn irb120() -> Robot {
    parse_robot_toml(
        include_str!("../../../examples/robots/abb_irb120.toml"),
        "abb_irb120.toml",
    )
    .unwrap()
}

/// A standard normal draw (Box-Muller), independent of the library's noise.
fn gauss(rng: &mut ChaCha8Rng) -> f64 {
    use rand::RngExt;
    let u: f64 = rng.random_range(f64::EPSILON..1.0);
    let v: f64 = rng.random_range(0.0..1.0);
    (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

/// A log of `cycles` cycles at the five poses: commanded poses fixed, attained ones offset by
/// `offset[pose]` plus Gaussian noise of `sigma` (mm) and `sigma_angle` (deg).
fn synthetic(cycles: u64, offsets: &[[f64; 3]; 5], sigma: f64, sigma_angle: f64, seed: u64) -> Log {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let commanded = [
        [500.0, 0.0, 600.0],
        [420.0, 80.0, 680.0],
        [580.0, 80.0, 680.0],
        [580.0, -80.0, 520.0],
        [420.0, -80.0, 520.0],
    ];
    let mut rows = Vec::new();
    for cycle in 1..=cycles {
        for pose in CYCLE {
            let c = commanded[pose - 1];
            let o = offsets[pose - 1];
            // Near +-180 deg for `a`: the wrap is exercised.
            let ca = [180.0, 0.0, 45.0];
            let att = [
                ca[0] + 0.01 * pose as f64 + sigma_angle * gauss(&mut rng),
                ca[1] - 0.02 + sigma_angle * gauss(&mut rng),
                ca[2] + sigma_angle * gauss(&mut rng),
            ];
            let wrapped = att.map(|a| if a > 180.0 { a - 360.0 } else { a });
            rows.push(LogRow {
                line: 0,
                test: None,
                pose,
                cycle,
                commanded: c,
                commanded_attitude: Some(ca),
                attained: std::array::from_fn(|k| c[k] + o[k] + sigma * gauss(&mut rng)),
                attained_attitude: Some(wrapped),
                direction: None,
                readings: None,
            });
        }
    }
    Log {
        file: "synthetic.csv".into(),
        length_unit: Some(LengthUnit::Mm),
        angle_unit: Some(AngleUnit::Deg),
        simulated: false,
        rows,
    }
}

/// The figures of one pose, computed plainly: barycentre, distances, `n - 1` deviations.
fn by_hand(rows: &[&LogRow]) -> (f64, f64, [f64; 3], [f64; 3]) {
    let n = rows.len() as f64;
    let mut bary = [0.0; 3];
    for r in rows {
        for k in 0..3 {
            bary[k] += r.attained[k] / n;
        }
    }
    let c = rows[0].commanded;
    let ap =
        ((bary[0] - c[0]).powi(2) + (bary[1] - c[1]).powi(2) + (bary[2] - c[2]).powi(2)).sqrt();
    let l: Vec<f64> = rows
        .iter()
        .map(|r| {
            ((r.attained[0] - bary[0]).powi(2)
                + (r.attained[1] - bary[1]).powi(2)
                + (r.attained[2] - bary[2]).powi(2))
            .sqrt()
        })
        .collect();
    let lbar = l.iter().sum::<f64>() / n;
    let sl = (l.iter().map(|x| (x - lbar).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
    // Angles: unwrap each difference into (-180, 180].
    let mut apa = [0.0; 3];
    let mut rpa = [0.0; 3];
    for k in 0..3 {
        let d: Vec<f64> = rows
            .iter()
            .map(|r| {
                let mut x = r.attained_attitude.unwrap()[k] - r.commanded_attitude.unwrap()[k];
                while x > 180.0 {
                    x -= 360.0;
                }
                while x <= -180.0 {
                    x += 360.0;
                }
                x
            })
            .collect();
        let m = d.iter().sum::<f64>() / n;
        apa[k] = m;
        rpa[k] = 3.0 * (d.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
    }
    (ap, lbar + 3.0 * sl, apa, rpa)
}

#[test]
fn thirty_cycles_match_a_plain_computation() {
    let offsets = [
        [0.10, -0.05, 0.02],
        [0.0, 0.0, 0.0],
        [-0.2, 0.1, 0.3],
        [0.05, 0.05, -0.05],
        [1.0, 0.0, 0.0],
    ];
    let log = synthetic(30, &offsets, 0.02, 0.005, 1);
    let e = evaluate(&log).unwrap();
    assert!(e.warnings.is_empty(), "{:?}", e.warnings);
    assert_eq!(e.poses.len(), 5);
    for f in &e.poses {
        assert_eq!(f.cycles, 30);
        let rows: Vec<&LogRow> = log.rows.iter().filter(|r| r.pose == f.pose).collect();
        let (ap, rp, apa, rpa) = by_hand(&rows);
        assert!(
            (f.ap - ap).abs() < 1e-12,
            "P{}: AP {} vs {ap}",
            f.pose,
            f.ap
        );
        let f_rp = f.rp.unwrap();
        assert!((f_rp - rp).abs() < 1e-12, "P{}: RP {f_rp} vs {rp}", f.pose,);
        let (fa, fr) = (f.ap_abc.unwrap(), f.rp_abc.unwrap());
        for k in 0..3 {
            assert!(
                (fa[k] - apa[k]).abs() < 1e-10,
                "P{} APabc {fa:?} vs {apa:?}",
                f.pose
            );
            assert!(
                (fr[k] - rpa[k]).abs() < 1e-10,
                "P{} RPabc {fr:?} vs {rpa:?}",
                f.pose
            );
        }
        // The offset is found to within the noise of a mean of 30 (3 sigma / sqrt(30) per axis).
        let o = offsets[f.pose - 1];
        for k in 0..3 {
            assert!(
                (f.ap_xyz[k] - o[k]).abs() < 3.0 * 0.02 / 30f64.sqrt() * 1.5,
                "{f:?}"
            );
        }
        // RP of isotropic noise: l follows a Maxwell distribution of scale sigma, mean 1.596
        // sigma and deviation 0.673 sigma: RP near 3.6 sigma.
        assert!((f_rp / 0.02 - 3.6).abs() < 1.2, "RP {f_rp}");
        // The attitude offsets put in (a: +0.01 per pose index, b: -0.02), through the wrap.
        assert!((fa[0] - 0.01 * f.pose as f64).abs() < 0.005, "{fa:?}");
        assert!((fa[1] + 0.02).abs() < 0.005, "{fa:?}");
        assert!((fr[0] / 0.005 - 3.0).abs() < 1.2, "{fr:?}");
    }
    // Distances: every pair, against a plain computation.
    assert_eq!(e.distances.len(), 10);
    for d in &e.distances {
        let a: Vec<&LogRow> = log.rows.iter().filter(|r| r.pose == d.from).collect();
        let b: Vec<&LogRow> = log.rows.iter().filter(|r| r.pose == d.to).collect();
        let dist = |x: [f64; 3], y: [f64; 3]| {
            ((x[0] - y[0]).powi(2) + (x[1] - y[1]).powi(2) + (x[2] - y[2]).powi(2)).sqrt()
        };
        let ds: Vec<f64> = a
            .iter()
            .map(|r| {
                dist(
                    r.attained,
                    b.iter().find(|s| s.cycle == r.cycle).unwrap().attained,
                )
            })
            .collect();
        let n = ds.len() as f64;
        let m = ds.iter().sum::<f64>() / n;
        let s = (ds.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        let dc = dist(a[0].commanded, b[0].commanded);
        assert_eq!(d.cycles, 30);
        assert!((d.ad - (m - dc)).abs() < 1e-10, "{d:?}");
        assert!((d.rd.unwrap() - 3.0 * s).abs() < 1e-10, "{d:?}");
        assert!((d.commanded - dc).abs() < 1e-12);
    }
}

#[test]
fn three_cycles_worked_by_hand() {
    // P1 commanded at the origin; attained at (1,0,0), (0,1,0), (0,0,1) mm.
    // Barycentre (1/3, 1/3, 1/3): AP = sqrt(3)/3. Each l_j = sqrt((2/3)^2 + 2 (1/3)^2) =
    // sqrt(6)/3, all equal: S_l = 0, RP = sqrt(6)/3.
    // P2 commanded at (10,0,0); attained at (10,0,0), (12,0,0), (10,0,0): barycentre
    // (32/3, 0, 0), AP = 2/3; l = 2/3, 4/3, 2/3: lbar = 8/9, S_l = sqrt(((2/9)^2 + (4/9)^2 +
    // (2/9)^2) / 2) = sqrt(12)/9, RP = 8/9 + sqrt(12)/3.
    // Distances P1-P2 per cycle: |(9,0,0)|, |(12,-1,0)|, |(10,0,-1)|; commanded 10.
    let text = "\
# length_unit = mm
pose,cycle,xc,yc,zc,x,y,z
1,1,0,0,0,1,0,0
2,1,10,0,0,10,0,0
1,2,0,0,0,0,1,0
2,2,10,0,0,12,0,0
1,3,0,0,0,0,0,1
2,3,10,0,0,10,0,0
";
    let log = read_log(text, "hand.csv", LogUnits::default()).unwrap();
    let e = evaluate(&log).unwrap();
    let p1 = &e.poses[0];
    assert!((p1.ap - 3f64.sqrt() / 3.0).abs() < 1e-15);
    assert!((p1.rp.unwrap() - 6f64.sqrt() / 3.0).abs() < 1e-15);
    assert!(p1.s_l.unwrap().abs() < 1e-15);
    assert!(p1.ap_abc.is_none() && p1.rp_abc.is_none());
    let p2 = &e.poses[1];
    assert!((p2.ap - 2.0 / 3.0).abs() < 1e-14);
    assert!((p2.l_mean.unwrap() - 8.0 / 9.0).abs() < 1e-14);
    assert!((p2.s_l.unwrap() - 12f64.sqrt() / 9.0).abs() < 1e-14);
    assert!((p2.rp.unwrap() - (8.0 / 9.0 + 12f64.sqrt() / 3.0)).abs() < 1e-14);
    let d = &e.distances[0];
    let ds = [9.0, 145f64.sqrt(), 101f64.sqrt()];
    let m = ds.iter().sum::<f64>() / 3.0;
    let s = (ds.iter().map(|x| (x - m).powi(2)).sum::<f64>() / 2.0).sqrt();
    assert!((d.ad - (m - 10.0)).abs() < 1e-14);
    assert!((d.rd.unwrap() - 3.0 * s).abs() < 1e-14);
    // ADx: mean of x1 - x2 (-9, -12, -10) against -10: -31/3 + 10.
    assert!((d.ad_xyz[0] - (-31.0 / 3.0 + 10.0)).abs() < 1e-14);
    // Fewer cycles than the standard's: computed, and said (in one line for the poses of one
    // count).
    let short: Vec<&String> = e
        .warnings
        .iter()
        .filter(|w| w.contains("fewer than the 30"))
        .collect();
    assert_eq!(short.len(), 1, "{short:?}");
    assert!(
        short[0].starts_with("P1, P2: 3 cycles, fewer than the 30"),
        "{short:?}"
    );
    assert_eq!(e.length_unit, Some(LengthUnit::Mm));
}

#[test]
fn attitude_differences_wrap_round_the_half_turn() {
    // Commanded a = 180 deg, attained 179 and -179 (= 181): mean deviation 0, not -180.
    let text = "\
# angle_unit = deg
pose,cycle,xc,yc,zc,ac,bc,cc,x,y,z,a,b,c
1,1,0,0,0,180,0,0,0,0,0,179,0,0
1,2,0,0,0,180,0,0,0,0,0,-179,0,0
";
    let e = evaluate(&read_log(text, "w.csv", LogUnits::default()).unwrap()).unwrap();
    let p = &e.poses[0];
    assert!(p.ap_abc.unwrap()[0].abs() < 1e-12, "{p:?}");
    // Deviations -1 and +1: S = sqrt(2), RPa = 3 sqrt(2).
    assert!((p.rp_abc.unwrap()[0] - 3.0 * 2f64.sqrt()).abs() < 1e-12);
    // In radians the turn is 2 pi.
    let pi = std::f64::consts::PI;
    let text = format!(
        "pose,cycle,xc,yc,zc,ac,bc,cc,x,y,z,a,b,c\n1,1,0,0,0,{pi},0,0,0,0,0,{},0,0\n1,2,0,0,0,{pi},0,0,0,0,0,{},0,0\n",
        pi - 0.01,
        -pi + 0.01
    );
    let units = LogUnits {
        angle: Some(AngleUnit::Rad),
        ..LogUnits::default()
    };
    let e = evaluate(&read_log(&text, "w.csv", units).unwrap()).unwrap();
    assert!(e.poses[0].ap_abc.unwrap()[0].abs() < 1e-12);
}

#[test]
fn multidirectional_variation_is_the_largest_distance_between_barycentres() {
    // From +x: (1,0,0) and (1,0,0); from -x: (-1,0,0) and (-1,0,2); from +y: (0,3,0) twice.
    // Barycentres (1,0,0), (-1,0,1), (0,3,0): largest distance |(-1,-3,1)| = sqrt(11).
    let text = "\
pose,cycle,xc,yc,zc,x,y,z,direction
1,1,0,0,0,1,0,0,+x
1,2,0,0,0,1,0,0,+x
1,1,0,0,0,-1,0,0,-x
1,2,0,0,0,-1,0,2,-x
1,1,0,0,0,0,3,0,+y
1,2,0,0,0,0,3,0,+y
";
    let e = evaluate(&read_log(text, "v.csv", LogUnits::default()).unwrap()).unwrap();
    let m = e.poses[0].multidirectional.as_ref().unwrap();
    assert_eq!(m.directions.len(), 3);
    assert!((m.vap - 11f64.sqrt()).abs() < 1e-15);
    assert!(e
        .warnings
        .iter()
        .any(|w| w.contains("pool 3 approach directions")));
}

#[test]
fn one_cycle_gives_accuracy_without_repeatability() {
    // P1 in two cycles, P3 in one: P3 commanded at (5,0,0), attained at (5,3,4): AP 5; P1-P3
    // attained together in cycle 1 only: D = |(1,0,0) - (5,3,4)| = sqrt(41), Dc = 5, AD =
    // sqrt(41) - 5, no RD.
    let text = "pose,cycle,xc,yc,zc,x,y,z\n1,1,0,0,0,1,0,0\n1,2,0,0,0,1,0,0\nP3,1,5,0,0,5,3,4\n";
    let e = evaluate(&read_log(text, "one.csv", LogUnits::default()).unwrap()).unwrap();
    let p3 = &e.poses[1];
    assert_eq!((p3.pose, p3.cycles), (3, 1));
    assert!((p3.ap - 5.0).abs() < 1e-15);
    assert!(p3
        .ap_xyz
        .iter()
        .zip([0.0, 3.0, 4.0])
        .all(|(a, b)| (a - b).abs() < 1e-15));
    assert!(p3.rp.is_none() && p3.l_mean.is_none() && p3.s_l.is_none());
    assert_eq!(e.poses[0].rp, Some(0.0));
    let d = &e.distances[0];
    assert_eq!((d.from, d.to, d.cycles), (1, 3, 1));
    assert!((d.ad - (41f64.sqrt() - 5.0)).abs() < 1e-15);
    assert!(d.rd.is_none() && d.s_d.is_none());
    assert!(
        e.warnings.iter().any(
            |w| w.contains("P3: 1 cycle: its accuracy (AP, AD) is computed")
                && w.contains("needs at least 2 cycles")
        ),
        "{:?}",
        e.warnings
    );
    assert!(e.summary.is_none());
}

#[test]
fn bad_logs_name_file_line_and_field() {
    let cases = [
        (
            "pose,cycle,xc,yc,zc,x,y\n1,1,0,0,0,1,0\n",
            "log.csv:1",
            "no column `z`",
        ),
        (
            "pose,cycle,xc,yc,zc,x,y,z\n1,1,0,0,0,1,zero,0\n",
            "log.csv:2",
            "`y`",
        ),
        (
            "pose,cycle,xc,yc,zc,x,y,z\n1,1,0,0,0,1,NaN,0\n",
            "log.csv:2",
            "finite",
        ),
        (
            "pose,cycle,xc,yc,zc,x,y,z\n1,1,0,0,0,1,0,0\n6,1,0,0,0,1,0,0\n",
            "log.csv:3",
            "pose index 6 is out of 1..5",
        ),
        (
            "pose,cycle,xc,yc,zc,x,y,z\n0,1,0,0,0,1,0,0\n",
            "log.csv:2",
            "out of 1..5",
        ),
        // Some attitude columns: the field named is the first one missing.
        (
            "pose,cycle,xc,yc,zc,x,y,z,bc,cc,a,b,c\n1,1,0,0,0,1,0,0,0,0,0,0,0\n",
            "log.csv:1: field `ac`",
            "missing ac",
        ),
        (
            "pose,cycle,xc,yc,zc,x,y,z\n1,1.5,0,0,0,1,0,0\n",
            "log.csv:2",
            "cycle number",
        ),
        (
            "pose,cycle,xc,yc,zc,x,y,z,q\n1,1,0,0,0,1,0,0,3\n",
            "log.csv:1",
            "unknown column `q`",
        ),
        (
            "pose,cycle,xc,yc,zc,x,y,z\n1,1,0,0,0,1,0,0\n1,1,0,0,0,1,0,0\n",
            "log.csv:3",
            "appears twice",
        ),
        (
            "pose,cycle,xc,yc,zc,x,y,z\n1,1,0,0,0,1,0,0\n1,2,0,0,0,1,0\n",
            "log.csv:3",
            "expected 8 fields",
        ),
        (
            "# angle_unit = deg\npose,cycle,xc,yc,zc,ac,x,y,z\n1,1,0,0,0,0,1,0,0\n",
            "log.csv:2",
            "missing bc,cc,a,b,c",
        ),
    ];
    for (text, at, what) in cases {
        let e = read_log(text, "log.csv", LogUnits::default())
            .and_then(|l| evaluate(&l))
            .unwrap_err()
            .to_string();
        assert!(e.starts_with(at) && e.contains(what), "{text:?}: {e}");
    }
    // Attitudes without an angle unit.
    let e = read_log(
        "pose,cycle,xc,yc,zc,ac,bc,cc,x,y,z,a,b,c\n1,1,0,0,0,0,0,0,0,0,0,0,0,0\n",
        "log.csv",
        LogUnits::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("no angle unit"), "{e}");
    // A commanded pose that moves between cycles.
    let e = evaluate(
        &read_log(
            "pose,cycle,xc,yc,zc,x,y,z\n1,1,0,0,0,1,0,0\n1,2,0,0.5,0,1,0,0\n",
            "log.csv",
            LogUnits::default(),
        )
        .unwrap(),
    )
    .unwrap_err()
    .to_string();
    assert!(e.starts_with("log.csv:3") && e.contains("yc"), "{e}");
    // A stated unit that contradicts the one given.
    let e = read_log(
        "# length_unit = mm\npose,cycle,xc,yc,zc,x,y,z\n1,1,0,0,0,1,0,0\n",
        "log.csv",
        LogUnits {
            length: Some(LengthUnit::M),
            ..LogUnits::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("length_unit = mm"), "{e}");
}

#[test]
fn a_log_written_reads_back_the_same() {
    let log = synthetic(3, &[[0.0; 3]; 5], 0.01, 0.01, 4);
    let text = write_log(&log);
    let back = read_log(&text, "synthetic.csv", LogUnits::default()).unwrap();
    assert_eq!(back.rows.len(), log.rows.len());
    for (a, b) in back.rows.iter().zip(&log.rows) {
        assert_eq!(
            (a.pose, a.cycle, a.attained, a.attained_attitude),
            (b.pose, b.cycle, b.attained, b.attained_attitude)
        );
    }
    assert_eq!(
        evaluate(&back).unwrap().poses,
        evaluate(&log).unwrap().poses
    );
}

#[test]
fn test_positions_are_where_the_standard_puts_them() {
    let cube = Cube {
        centre: [1.0, 2.0, 3.0],
        side: 0.4,
    };
    let p = cube.test_positions();
    assert!(p[0]
        .iter()
        .zip(cube.centre)
        .all(|(a, b)| (a - b).abs() < 1e-15));
    let corners = cube.corners();
    // The measuring plane's diagonals C1-C7 and C2-C8 (C1 = (-,-,-), C2 = (+,-,-),
    // C7 = (+,+,+), C8 = (-,+,+)).
    let (c1, c2, c7, c8) = (corners[0], corners[1], corners[7], corners[6]);
    assert!(c8
        .iter()
        .zip([0.8, 2.2, 3.2])
        .all(|(a, b)| (a - b).abs() < 1e-12));
    let diagonal = 0.4 * 3f64.sqrt();
    let dist = |a: [f64; 3], b: [f64; 3]| {
        ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
    };
    // P2..P5 at 10 % of the diagonal from their corners, on the diagonal.
    for (pose, corner, other) in [(1, c8, c2), (2, c7, c1), (3, c2, c8), (4, c1, c7)] {
        assert!((dist(p[pose], corner) - 0.1 * diagonal).abs() < 1e-12);
        assert!((dist(p[pose], other) - 0.9 * diagonal).abs() < 1e-12);
    }
    // All five in one plane: through the x axis and the direction (0, 1, 1).
    for q in p {
        assert!(((q[1] - 2.0) - (q[2] - 3.0)).abs() < 1e-12);
    }
    assert_eq!(CYCLE, [1, 5, 4, 3, 2]);
    assert_eq!(STANDARD_CYCLES, 30);
}

/// The poses' readings reach them on the robot: the forward kinematics at the readings is the
/// pose, within the joint ranges.
fn check_reached(robot: &Robot, plan: &kinecal::apps::iso9283::TestPlan) {
    let chain = Chain::new(robot);
    let positions = plan.cube.test_positions();
    assert_eq!(plan.poses.len(), 5);
    for (p, want) in plan.poses.iter().zip(positions) {
        let f = chain.frame_at(&p.readings, Target::EndEffector);
        for k in 0..3 {
            assert!((f.translation[k] - want[k]).abs() < 1e-6, "P{}", p.pose);
        }
        if let Some([a, b, c]) = plan.attitude {
            let r = rot_zyx(c, b, a);
            assert!((f.rotation - r).norm() < 1e-6, "P{}", p.pose);
        }
        for (j, joint) in robot.joints.iter().enumerate() {
            if let Some((lo, hi)) = joint.range {
                assert!(
                    (lo..=hi).contains(&p.readings[j]),
                    "P{} joint {}",
                    p.pose,
                    j + 1
                );
            }
        }
    }
}

#[test]
fn a_searched_cube_is_reached_at_its_poses_and_corners() {
    let robot = irb120();
    let pi = std::f64::consts::PI;
    let t = std::time::Instant::now();
    let p = plan(
        &robot,
        &PlanRequest {
            attitude: Some([pi, 0.0, 0.0]),
            ..PlanRequest::default()
        },
    )
    .unwrap();
    eprintln!("searched in {:?}: {:?} {:?}", t.elapsed(), p.cube, p.search);
    check_reached(&robot, &p);
    // A cube worth the name on an arm of 0.58 m reach (data sheet): over 0.35 m a side (0.42 m
    // found when this was written; 0.30 m before the centre was moved off the grid).
    assert!(p.cube.side > 0.35, "{:?}", p.cube);
    // Its corners are reached too.
    let again = plan(
        &robot,
        &PlanRequest {
            cube: Some(p.cube),
            attitude: p.attitude,
            ..PlanRequest::default()
        },
    )
    .unwrap();
    check_reached(&robot, &again);
}

#[test]
fn a_given_cube_is_checked_and_written() {
    let robot = irb120();
    let pi = std::f64::consts::PI;
    let request = PlanRequest {
        cube: Some(Cube {
            centre: [0.35, 0.0, 0.35],
            side: 0.2,
        }),
        attitude: Some([pi, 0.0, 0.0]),
        ..PlanRequest::default()
    };
    let p = plan(&robot, &request).unwrap();
    check_reached(&robot, &p);
    // Written and read back: the same poses.
    let text = write_plan(&robot, &p);
    assert!(text.contains("# length_unit = m\n"), "{text}");
    let back = read_plan(&text, "poses.csv", &robot).unwrap();
    for (a, b) in back.iter().zip(&p.poses) {
        assert_eq!(
            (a.pose, a.position, a.readings.clone()),
            (b.pose, b.position, b.readings.clone())
        );
        assert_eq!(a.attitude, p.attitude);
    }
    // Out of reach: an error naming the pose.
    let far = PlanRequest {
        cube: Some(Cube {
            centre: [2.0, 0.0, 0.3],
            side: 0.2,
        }),
        ..request
    };
    let e = plan(&robot, &far).unwrap_err().to_string();
    assert!(
        e.contains("P1 (2, 0, 0.3 m)") && e.contains("out of reach"),
        "{e}"
    );
    // A centre that is not a number is named as such (it was worded as a bad side).
    let nowhere = PlanRequest {
        cube: Some(Cube {
            centre: [f64::NAN, 0.0, 0.3],
            side: 0.2,
        }),
        ..far
    };
    let e = plan(&robot, &nowhere).unwrap_err().to_string();
    assert!(
        e.contains("the cube's centre must be finite, got NaN"),
        "{e}"
    );
    // The simulated log of the plan on its own robot: AP within the noise, 30 cycles.
    let log = simulate(
        &robot,
        &back,
        &SimulateRequest {
            cycles: 30,
            length_noise: 1e-5,
            angle_noise: 1e-5,
            seed: 2,
        },
    )
    .unwrap();
    assert!(log.simulated);
    let e = evaluate(&read_log(&write_log(&log), "sim.csv", LogUnits::default()).unwrap()).unwrap();
    assert_eq!(e.poses.len(), 5);
    for f in &e.poses {
        assert_eq!(f.cycles, 30);
        assert!(f.ap < 1e-5, "{f:?}");
        assert!(f.rp.is_some_and(|rp| rp > 1e-5 && rp < 1e-4), "{f:?}");
        assert!(f.ap_abc.unwrap().iter().all(|a| a.abs() < 1e-5), "{f:?}");
    }
    assert!(e.warnings.iter().any(|w| w.contains("simulated")));
    // Saved by a spreadsheet as "CSV UTF-8" (a byte order mark first): the same log, still
    // marked simulated (before: its first comment line was read as the header).
    let bom = format!("\u{feff}{}", write_log(&log));
    let back = read_log(&bom, "sim.csv", LogUnits::default()).unwrap();
    assert!(back.simulated);
    assert_eq!(back.rows.len(), log.rows.len());
}
