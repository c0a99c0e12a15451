//! ISO 9283 figures of a series of tests (several cubes, corners, one cycle per pose), logs made
//! from measurement files ([`kinecal::apps::iso9283::log_from_measurements`]) and the accuracy
//! predicted once a program is compensated ([`kinecal::apps::iso9283::predict_compensated`]), each
//! against an independent computation: hand-worked numbers, the true robot's forward kinematics,
//! the predictor called directly.

use kinecal::apps::iso9283::{
    cube_roles, evaluate, log_from_measurements, pose_name, predict_compensated, read_log,
    read_roles, write_log, write_roles, LogUnits, Role, CORNERS,
};
use kinecal::apps::simulate;
use kinecal::model::kinematics::{forward_pose, rot_zyx, Target};
use kinecal::model::robot::{Link, Session};
use kinecal::workflow::{self, Request, Selection};
use kinecal::{predict, Dataset};

#[test]
fn a_series_is_figured_test_by_test_and_summarized() {
    // Two tests. "a, left": P1 at the origin attained at (0,0,3), C8 at (1,1,1) attained at
    // (1,1,1) plus (0,4,0); one cycle each. "b": P1 at (0,0,0) attained (0,0,1) in cycle 1 and
    // (0,0,-1) in cycle 2 (AP 0, RP = 1 + 3*0 = 1), C1 at (-1,-1,-1) attained exactly in both.
    // By hand: AP of "a, left" P1 = 3, C8 = 4; "b" P1 = 0, C1 = 0. Distances only within a test:
    // "a, left" P1-C8: D = |(1,5,-2)| = sqrt(30), Dc = sqrt(3); "b" P1-C1 per cycle |(1,1,2)| =
    // sqrt(6) and |(1,1,0)| = sqrt(2), Dc = sqrt(3).
    let text = "\
# length_unit = mm
test,pose,cycle,xc,yc,zc,x,y,z,v1,v2
\"a, left\",P1,1,0,0,0,0,0,3,0.1,0.2
\"a, left\",C8,1,1,1,1,1,5,1,0.3,0.4
b,P1,1,0,0,0,0,0,1,0.5,0.6
b,C1,1,-1,-1,-1,-1,-1,-1,0.7,0.8
b,P1,2,0,0,0,0,0,-1,0.9,1.0
b,C1,2,-1,-1,-1,-1,-1,-1,1.1,1.2
";
    let log = read_log(text, "series.csv", LogUnits::default()).unwrap();
    assert_eq!(log.rows[0].test.as_deref(), Some("a, left"));
    assert_eq!(log.rows[1].pose, CORNERS + 8);
    assert_eq!(log.rows[3].readings.as_deref(), Some(&[0.7, 0.8][..]));
    // Written and read back: the same log (the label with a comma quoted).
    let again = read_log(&write_log(&log), "series.csv", LogUnits::default()).unwrap();
    let strip = |l: &kinecal::apps::iso9283::Log| {
        l.rows
            .iter()
            .map(|r| {
                let mut r = r.clone();
                r.line = 0;
                r
            })
            .collect::<Vec<_>>()
    };
    assert_eq!(strip(&again), strip(&log));
    let e = evaluate(&log).unwrap();
    assert_eq!(e.tests(), vec![Some("a, left"), Some("b")]);
    let ap: Vec<(String, f64)> = e
        .poses
        .iter()
        .map(|p| {
            (
                format!("{} {}", p.test.as_deref().unwrap(), pose_name(p.pose)),
                p.ap,
            )
        })
        .collect();
    assert_eq!(
        ap,
        vec![
            ("a, left P1".to_string(), 3.0),
            ("a, left C8".to_string(), 4.0),
            ("b P1".to_string(), 0.0),
            ("b C1".to_string(), 0.0),
        ]
    );
    assert_eq!(e.poses[2].rp, Some(1.0));
    assert_eq!(e.poses[0].rp, None);
    assert_eq!(e.distances.len(), 2, "{:?}", e.distances);
    let (da, db) = (&e.distances[0], &e.distances[1]);
    assert!((da.ad - (30f64.sqrt() - 3f64.sqrt())).abs() < 1e-14);
    assert!(da.rd.is_none());
    let m = (6f64.sqrt() + 2f64.sqrt()) / 2.0;
    assert!((db.ad - (m - 3f64.sqrt())).abs() < 1e-14);
    let s = ((6f64.sqrt() - m).powi(2) + (2f64.sqrt() - m).powi(2)).sqrt();
    assert!((db.rd.unwrap() - 3.0 * s).abs() < 1e-14);
    // The summary: per pose over the tests, then every pose.
    let sum = e.summary.as_ref().unwrap();
    assert_eq!(sum.tests, 2);
    let of = |pose: usize| sum.poses.iter().find(|p| p.pose == pose).unwrap();
    assert_eq!((of(1).ap.count, of(1).ap.mean, of(1).ap.max), (2, 1.5, 3.0));
    assert_eq!(
        (of(0).ap.count, of(0).ap.mean, of(0).ap.max),
        (4, 7.0 / 4.0, 4.0)
    );
    assert_eq!(of(1).rp.map(|r| r.count), Some(1));
    assert!(of(CORNERS + 8).rp.is_none());
    let ad = sum.ad.unwrap();
    assert_eq!(ad.count, 2);
    assert!((ad.max - (30f64.sqrt() - 3f64.sqrt())).abs() < 1e-14);
    assert_eq!(sum.rd.map(|r| r.count), Some(1));
    // One line for the cycles, not one per pose.
    let w: Vec<&String> = e.warnings.iter().filter(|w| w.contains("cycles")).collect();
    assert_eq!(w.len(), 1, "{:?}", e.warnings);
    assert!(
        w[0].contains("4 of the 4 poses of 2 tests") && w[0].contains("2 in 1 cycle"),
        "{w:?}"
    );
}

#[test]
fn a_bad_pose_label_or_roles_file_names_its_line() {
    let bad = "test,pose,cycle,xc,yc,zc,x,y,z\nt,C9,1,0,0,0,0,0,0\n";
    let e = read_log(bad, "l.csv", LogUnits::default())
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("l.csv:2") && e.contains("C1..C8"), "{e}");
    let twice = "test,pose,cycle,xc,yc,zc,x,y,z\nt,C1,1,0,0,0,0,0,0\nt,C1,1,0,0,0,0,0,0\n";
    let e = read_log(twice, "l.csv", LogUnits::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("l.csv:3") && e.contains("test `t`: C1 in cycle 1 appears twice"),
        "{e}"
    );
    for (text, at, what) in [
        ("posture,test,pose\nD1,t,P1\n", "r.csv:1", "cycle"),
        (
            "posture,test,pose,cycle\nD1,t,P1,1\nD1,t,C1,1\n",
            "r.csv:3",
            "given a role twice",
        ),
        (
            "posture,test,pose,cycle\nD1,t,P1,1\nD2,t,P1,1\n",
            "r.csv:3",
            "P1 in cycle 1 appears twice",
        ),
        ("posture,test,pose,cycle\nD1,t,P7,1\n", "r.csv:2", "pose"),
        (
            "posture,test,pose,cycle\nD1,t,P1,x\n",
            "r.csv:2",
            "cycle number",
        ),
        (
            "posture,test,pose,cycle\nD1,,P1,1\n",
            "r.csv:2",
            "empty field",
        ),
    ] {
        let e = read_roles(text, "r.csv").unwrap_err().to_string();
        assert!(e.starts_with(at) && e.contains(what), "{text}: {e}");
    }
}

#[test]
fn cube_roles_name_the_corners_and_count_the_cycles() {
    // A cube of side 0.4 about (1, 2, 3), its corners in a scrambled order; the same cube again
    // (a second cycle), a cube of side 0.1 elsewhere, then 2 postures outside any block.
    let cube = |c: [f64; 3], h: f64, order: [usize; 8]| {
        let mut v = vec![c];
        for k in order {
            v.push(std::array::from_fn(|a| {
                c[a] + if k & (1 << a) != 0 { h } else { -h }
            }));
        }
        v
    };
    let order = [6, 2, 5, 1, 7, 3, 4, 0];
    let mut goals = cube([1.0, 2.0, 3.0], 0.2, order);
    goals.extend(cube([1.0, 2.0, 3.0], 0.2, order));
    goals.extend(cube([0.0, 0.0, 1.0], 0.05, [0, 1, 2, 3, 4, 5, 6, 7]));
    goals.extend([[9.0, 9.0, 9.0], [8.0, 8.0, 8.0]]);
    let roles = cube_roles(&goals, 1e-6).unwrap();
    assert_eq!(roles.len(), 27);
    let r = |test: &str, pose: usize, cycle: u64| Role {
        test: test.into(),
        pose,
        cycle,
    };
    assert_eq!(roles[0], r("cube 1", 1, 1));
    // Corner k (bits x, y, z of the + side) is C(k+1): C1 = (-,-,-), C8 = (+,+,+).
    assert_eq!(roles[1], r("cube 1", CORNERS + 7, 1));
    assert_eq!(roles[8], r("cube 1", CORNERS + 1, 1));
    assert_eq!(roles[9], r("cube 1", 1, 2));
    assert_eq!(roles[18], r("cube 2", 1, 1));
    assert_eq!(roles[26], r("cube 2", CORNERS + 8, 1));
    // Written as a roles file and read back.
    let labelled: Vec<(String, Role)> = roles
        .iter()
        .enumerate()
        .map(|(k, r)| (format!("D{}", k + 1), r.clone()))
        .collect();
    let back = read_roles(&write_roles(&labelled), "roles.csv").unwrap();
    assert_eq!(back.by_posture.len(), 27);
    assert_eq!(back.by_posture["D10"], r("cube 1", 1, 2));
    // A block that is not a cube about its first posture is refused.
    let mut bad = cube([0.0, 0.0, 0.0], 0.1, order);
    bad[4][2] += 0.05;
    let e = cube_roles(&bad, 1e-6).unwrap_err();
    assert!(e.contains("posture 5 is not a corner"), "{e}");
}

/// A UR-like 6R, a "true" one 1 mm / 0.1 deg off, and the tracker placement of a session.
fn robots() -> (kinecal::Robot, kinecal::Robot, Link) {
    let nominal = simulate::random_robot(&[kinecal::model::robot::JointKind::Revolute; 6], 11);
    let truth = simulate::perturb(
        &nominal,
        simulate::PerturbStd {
            length: 0.001,
            angle: 0.1f64.to_radians(),
            ..Default::default()
        },
        5,
    );
    let tracker = Link {
        x: 2.1,
        y: -1.3,
        z: -0.9,
        alpha: 0.7,
        beta: -0.2,
        gamma: 0.1,
    };
    (nominal, truth, tracker)
}

#[test]
fn a_log_from_measurements_puts_the_tracker_data_in_the_base_frame() {
    let (nominal, truth, tracker) = robots();
    // Six postures: test "t" P1 in cycles 1 and 2 (readings 1e-3 rad apart), C1 and C2 once;
    // test "u" P1 once; and one posture without a role.
    let base = simulate::sample_postures(&nominal, 4, 3);
    let mut postures = vec![
        base[0].clone(),
        base[0].clone(),
        base[1].clone(),
        base[2].clone(),
    ];
    postures[1].readings[1] += 1e-3;
    postures.push(base[3].clone());
    postures.push(base[3].clone());
    for (k, p) in postures.iter_mut().enumerate() {
        p.label = format!("D{}", k + 1);
        p.session = Some("D".into());
    }
    let roles_text =
        "posture,test,pose,cycle\nD1,t,P1,1\nD2,t,P1,2\nD3,t,C1,1\nD4,t,C2,1\nD5,u,P1,1\n";
    let roles = read_roles(roles_text, "roles.csv").unwrap();
    // Measured by a tracker placed at `tracker` (the global frame's pose in the tracker frame).
    let t = kinecal::model::kinematics::Frame::from_link(&tracker);
    let truth_frame = |r: &[f64]| forward_pose(&truth, r, Target::EndEffector);
    for position_only in [true, false] {
        let mut data: Dataset = simulate::measure(&truth, &postures, position_only);
        for o in &mut data.observations {
            match o {
                kinecal::observe::Observation::Position(p) => {
                    p.position = t.rotation * p.position + t.translation
                }
                kinecal::observe::Observation::Pose(p) => {
                    p.position = t.rotation * p.position + t.translation;
                    let r = t.rotation * rot_zyx(p.euler.x, p.euler.y, p.euler.z);
                    p.euler = kinecal::model::kinematics::euler_zyx(&r);
                }
                _ => unreachable!(),
            }
        }
        let mut model = nominal.clone();
        model.sessions.push(Session {
            name: "D".into(),
            frame: tracker,
        });
        let (log, left_out) = log_from_measurements(&model, &data, &roles).unwrap();
        assert_eq!(left_out, vec!["D6".to_string()]);
        assert_eq!(log.rows.len(), 5);
        for (row, p) in log.rows.iter().zip(&postures) {
            // Attained: the true robot's position, to rounding.
            let truth_at = truth_frame(&p.readings);
            for k in 0..3 {
                assert!(
                    (row.attained[k] - truth_at.position[k]).abs() < 1e-12,
                    "{row:?}"
                );
            }
            assert_eq!(row.readings.as_deref(), Some(p.readings.as_slice()));
            // Attitudes: ISO a, b, c are kinecal's gamma, beta, alpha.
            if let Some(abc) = row.attained_attitude {
                let e = truth_at.euler;
                for (k, v) in [e.z, e.y, e.x].iter().enumerate() {
                    let d = kinecal::units::wrap_angle(abc[k] - v);
                    assert!(d.abs() < 1e-10, "{abc:?} vs {e:?}");
                }
            }
        }
        // Commanded: the model at the mean readings of the pose's cycles.
        let mut mean = postures[0].readings.clone();
        mean[1] += 0.5e-3;
        let c = forward_pose(&nominal, &mean, Target::EndEffector).position;
        for row in &log.rows[..2] {
            for k in 0..3 {
                assert!((row.commanded[k] - c[k]).abs() < 1e-12);
            }
        }
        // One cycle: AP is the model's error at that posture.
        let e = evaluate(&log).unwrap();
        let c1 = e.poses.iter().find(|p| p.pose == CORNERS + 1).unwrap();
        let model_at = forward_pose(&nominal, &postures[2].readings, Target::EndEffector).position;
        let want = (truth_frame(&postures[2].readings).position - model_at).norm();
        assert!((c1.ap - want).abs() < 1e-12, "{} vs {want}", c1.ap);
        assert!(e.summary.is_some());
    }
    // A posture without a role is left out once, however often it was measured (it was listed
    // once per measurement); poses mixed with positions are refused (a row without an attitude
    // was written with zero angles).
    let mut model = nominal.clone();
    model.sessions.push(Session {
        name: "D".into(),
        frame: tracker,
    });
    let mut data: Dataset = simulate::measure(&truth, &postures, false);
    let again = data.observations[5].clone();
    data.observations.push(again);
    let (_, left_out) = log_from_measurements(&model, &data, &roles).unwrap();
    assert_eq!(left_out, vec!["D6".to_string()]);
    if let kinecal::observe::Observation::Pose(p) = &data.observations[2] {
        let position = kinecal::observe::Observation::Position(kinecal::observe::point::Position {
            view: p.view,
            position: p.position,
            sigma_position: None,
            line: 4,
        });
        data.observations[2] = position;
    }
    let e = log_from_measurements(&model, &data, &roles)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("the measurements mix poses (line ") && e.contains(") and positions (line 4)"),
        "{e}"
    );
    // A robot without the session's frame is refused, saying what to do.
    let mut other = nominal.clone();
    other.sessions.push(Session {
        name: "E".into(),
        frame: Link::default(),
    });
    let data = simulate::measure(&truth, &postures, true);
    let e = log_from_measurements(&other, &data, &roles)
        .unwrap_err()
        .to_string();
    assert!(e.contains("session `D` has no measurement frame"), "{e}");
}

#[test]
fn the_compensated_accuracy_is_the_prediction_at_the_poses_readings() {
    let (nominal, truth, _) = robots();
    let postures = simulate::sample_postures(&nominal, 40, 21);
    let mut data = simulate::measure(&truth, &postures, true);
    simulate::add_noise(&mut data, 5e-5, 0.0, 2);
    let mut req = Request::new(nominal.clone(), data);
    req.selection = Selection::parse("identifiable", None, &nominal).unwrap();
    req.prediction = predict::Level::Summary;
    let out = workflow::run(&req, &mut ()).unwrap();
    let cal = &out.calibration.calibrated;
    let report = out.report.prediction.as_ref().unwrap();
    let predictor = predict::from_report(cal, report).unwrap();
    // A log in mm of three poses at postures the calibration did not see; with readings, and
    // without (then reached by the calibrated model's inverse kinematics).
    let test = simulate::sample_postures(&nominal, 3, 77);
    let mut text =
        String::from("# length_unit = mm\npose,cycle,xc,yc,zc,x,y,z,v1,v2,v3,v4,v5,v6\n");
    for (k, p) in test.iter().enumerate() {
        let c = forward_pose(cal, &p.readings, Target::EndEffector).position * 1e3;
        let a = forward_pose(&truth, &p.readings, Target::EndEffector).position * 1e3;
        let r: Vec<String> = p.readings.iter().map(|v| v.to_string()).collect();
        text += &format!(
            "{},1,{},{},{},{},{},{},{}\n",
            k + 1,
            c.x,
            c.y,
            c.z,
            a.x,
            a.y,
            a.z,
            r.join(",")
        );
    }
    let log = read_log(&text, "c.csv", LogUnits::default()).unwrap();
    let mut e = evaluate(&log).unwrap();
    predict_compensated(&mut e, &log, &predictor, Target::EndEffector).unwrap();
    let mut s = predictor.scratch();
    for (f, p) in e.poses.iter().zip(&test) {
        let c = f.compensated.as_ref().unwrap();
        let want = predictor.predict(&p.readings, Target::EndEffector, &mut s);
        let b = want.position_error;
        assert!(
            (c.ap_95 - b.bound * 1e3).abs() < 1e-12 * c.ap_95.max(1.0),
            "{c:?} {b:?}"
        );
        assert!((c.ap_rms - b.parameters.hypot(b.model) * 1e3).abs() < 1e-12);
        assert_eq!(c.readings_from, "log");
        // The bound is a bound: 0.05 mm noise, 1 mm / 0.1 deg errors calibrated away.
        assert!(c.ap_95 > 0.0 && c.ap_95 < 1.0, "{c:?}");
    }
    // Without readings: the inverse kinematics reaches the commanded position, and the
    // prediction is the one at the readings it found.
    let bare: String = text
        .lines()
        .map(|l| l.split(',').take(8).collect::<Vec<_>>().join(","))
        .collect::<Vec<_>>()
        .join("\n");
    let log = read_log(&bare, "c.csv", LogUnits::default()).unwrap();
    assert!(log.rows.iter().all(|r| r.readings.is_none()));
    let mut e2 = evaluate(&log).unwrap();
    predict_compensated(&mut e2, &log, &predictor, Target::EndEffector).unwrap();
    for f in &e2.poses {
        let c = f.compensated.as_ref().unwrap();
        assert_eq!(c.readings_from, "inverse kinematics");
        assert!(c.ap_95 > 0.0 && c.ap_95.is_finite());
    }
    // A log without a length unit cannot be predicted: its lengths could be anything.
    let unitless = bare.replace("# length_unit = mm\n", "");
    let log = read_log(&unitless, "c.csv", LogUnits::default()).unwrap();
    let mut e3 = evaluate(&log).unwrap();
    let err = predict_compensated(&mut e3, &log, &predictor, Target::EndEffector)
        .unwrap_err()
        .to_string();
    assert!(err.contains("states no length unit"), "{err}");
    // A commanded pose out of reach (the log in another frame) is refused.
    let far: String = bare
        .lines()
        .enumerate()
        .map(|(k, l)| {
            if k == 2 {
                let mut f: Vec<&str> = l.split(',').collect();
                f[2] = "99999";
                f.join(",")
            } else {
                l.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    let log = read_log(&far, "c.csv", LogUnits::default()).unwrap();
    let mut e4 = evaluate(&log).unwrap();
    let err = predict_compensated(&mut e4, &log, &predictor, Target::EndEffector)
        .unwrap_err()
        .to_string();
    assert!(err.contains("does not reach"), "{err}");
}
