//! Instruments other than a tracker or a camera: distances (ballbar, fixed-length artefacts),
//! read from their files, counted by the documented rank formula, and enough to recover a
//! perturbed 6-joint robot.

use kinecal::apps::simulate::{self, PerturbStd};
use kinecal::files::parse_distances;
use kinecal::identifiability::{analyze, AnalysisOptions};
use kinecal::model::kinematics::Target;
use kinecal::observe::distance::Distance;
use kinecal::observe::{accuracy, Dataset, Observation, Posture};
use kinecal::solve::estimation::{calibrate, CalibrationOptions};
use kinecal::{parse_param_list, JointKind, ParamId, Robot};

fn six_joint() -> Robot {
    simulate::random_robot(
        &[
            JointKind::Revolute,
            JointKind::Revolute,
            JointKind::Revolute,
            JointKind::Prismatic,
            JointKind::Revolute,
            JointKind::Revolute,
        ],
        303,
    )
}

/// `pairs` distances of the end effector between random postures, as `truth` measures them.
fn distances(truth: &Robot, pairs: usize, seed: u64) -> Dataset {
    let postures: Vec<Posture> = simulate::sample_postures(truth, 2 * pairs, seed);
    let observations: Vec<Observation> = (0..pairs)
        .map(|k| Distance::new(2 * k, 2 * k + 1, Target::EndEffector, 0.0).into())
        .collect();
    simulate::remeasure(truth, &Dataset::new(postures, observations))
}

#[test]
fn distances_alone_recover_a_6_joint_robot_except_its_placement() {
    let nominal = six_joint();
    let std = PerturbStd {
        length: 2e-3,
        angle: 0.5f64.to_radians(),
        slope_fraction: 0.0,
    };
    let truth = simulate::perturb(&nominal, std, 5);
    let data = distances(&truth, 120, 1);
    let candidates = parse_param_list("links,offsets", &nominal).unwrap();
    let a = analyze(&nominal, &data, &candidates, &AnalysisOptions::default()).unwrap();
    // 4 per revolute, 2 per prismatic, 3 for the measured point, minus the 6 motions of the
    // whole world that change no distance: 4*5 + 2*1 + 3 - 6 = 19.
    let expected = a.expected.clone().expect("the count applies");
    assert_eq!(expected.rank, 19, "{}", expected.formula);
    assert!(expected.formula.contains("- 6"), "{}", expected.formula);
    assert_eq!(
        a.rank, expected.rank,
        "gap {} at {}",
        a.gap_ratio, a.gap_rank
    );
    // The same postures measured by a tracker determine 6 more: the placement.
    let tracked = simulate::measure(&truth, &data.postures, true);
    let b = analyze(&nominal, &tracked, &candidates, &AnalysisOptions::default()).unwrap();
    assert_eq!(b.rank, 19 + 6);
    assert_eq!(b.expected.unwrap().rank, 25);

    let cal = calibrate(
        &nominal,
        &data,
        &CalibrationOptions::new(a.identifiable.clone()),
        &mut |_| {},
    )
    .unwrap();
    assert!(
        cal.objective_after < 1e-16 * cal.objective_before,
        "{} -> {}",
        cal.objective_before,
        cal.objective_after
    );
    // Fresh distances are predicted exactly ...
    let held = distances(&truth, 50, 99);
    let before = accuracy(&nominal, &held).other[0].max;
    let after = accuracy(&cal.calibrated, &held).other[0].max;
    assert!(before > 1e-3, "nominal misses by {before} m");
    assert!(after < 1e-9, "held-out distance error {after} m");
    // ... and so is the arm's whole geometry up to a rigid motion of the world: the calibrated
    // end-effector positions over fresh postures are the true ones moved rigidly.
    let fresh = simulate::sample_postures(&nominal, 40, 7);
    let p = |r: &Robot| -> Vec<nalgebra::Vector3<f64>> {
        fresh
            .iter()
            .map(|q| {
                kinecal::Chain::new(r)
                    .frame_at(&q.readings, Target::EndEffector)
                    .translation
            })
            .collect()
    };
    let (pt, pc) = (p(&truth), p(&cal.calibrated));
    for i in 0..pt.len() {
        for j in 0..i {
            let (dt, dc) = ((pt[i] - pt[j]).norm(), (pc[i] - pc[j]).norm());
            assert!((dt - dc).abs() < 1e-9, "{dt} vs {dc}");
        }
    }
}

#[test]
fn distances_with_slopes_and_positions_follow_the_count() {
    let nominal = six_joint();
    let data = distances(&nominal, 80, 3);
    // Slopes add one each.
    let all = parse_param_list("links,offsets,slopes", &nominal).unwrap();
    let a = analyze(&nominal, &data, &all, &AnalysisOptions::default()).unwrap();
    assert_eq!(a.expected.as_ref().unwrap().rank, 19 + 6);
    assert_eq!(a.rank, 19 + 6);
    // One tracked position fixes the world.
    let mut mixed = data.clone();
    let tracked = simulate::measure(&nominal, &mixed.postures[..3], true);
    mixed = mixed.merge(tracked);
    let b = analyze(&nominal, &mixed, &all, &AnalysisOptions::default()).unwrap();
    assert_eq!(b.expected.unwrap().rank, 19 + 6 + 6);
    assert_eq!(b.rank, 31);
}

#[test]
fn distance_files_read_with_their_lines_and_refuse_mistakes() {
    let robot = kinecal::model::examples::ge_a4();
    let text = "# ballbar run\npair,a1,a2,a3,a4,b1,b2,b3,b4,distance,sigma_position\n\
                1,-11,12,4,-11,-12,9,1.5,5,6.0,0.0004\n\
                2;x\n";
    let e = parse_distances(text, "d.csv", &robot)
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("d.csv:4:"), "{e}");
    let ok = "# ballbar run\npair,a1,a2,a3,a4,b1,b2,b3,b4,distance,sigma_position\n\
              1,-11,12,4,-11,-12,9,1.5,5,6.0,0.0004\n\
              2,-11,12,4,-11,-10,9,1.5,5,6.5,\n";
    let d = parse_distances(ok, "d.csv", &robot).unwrap();
    assert_eq!(d.observations.len(), 2);
    assert_eq!(d.postures.len(), 4);
    assert_eq!(d.postures[1].label, "1/b");
    let Observation::Distance(x) = &d.observations[0] else {
        panic!()
    };
    assert!((x.distance - 6.0 * 0.0254).abs() < 1e-15);
    assert!((x.sigma.unwrap() - 0.0004 * 0.0254).abs() < 1e-15);
    assert_eq!(x.line, 3);
    for (text, expect) in [
        (
            ok.replace("6.0,0.0004", "-6.0,0.0004"),
            "d.csv:3: field `distance`: a distance cannot be negative",
        ),
        (
            ok.replace("b4,distance", "b4,dist"),
            "unknown column `dist`",
        ),
        (ok.replace("b4,distance", "b4"), "no column `distance`"),
        (
            ok.replace("b4,distance", "b4"),
            "expected pair,site,a1..a4,b1..b4,distance[,sigma_position]",
        ),
        (
            ok.replace(",sigma_position", ",weight"),
            "unknown column `weight`",
        ),
        (ok.replace("6.0,0.0004", "6.0,0"), "must be positive"),
        (
            ok.replace(
                "\n2,-11,12,4,-11,-10,9,1.5,5,6.5,",
                "\n1,-11,12,4,-11,-12,9,1.5,5,6.5,",
            ),
            "d.csv:4: pair `1` measures ee twice (first on line 3)",
        ),
        (
            ok.replace("\n2,", "\n1,"),
            "d.csv:4: field `b1`: posture `1/b` appears earlier",
        ),
    ] {
        let e = parse_distances(&text, "d.csv", &robot)
            .unwrap_err()
            .to_string();
        assert!(e.contains(expect), "expected `{expect}` in {e}");
    }
    let _ = ParamId(0);
}

/// `per_plane` contacts of the end effector with each plane of `truth`, at random postures (the
/// known gap is each posture's true distance: touching at a known height).
fn contacts(truth: &Robot, per_plane: usize, seed: u64) -> Dataset {
    use kinecal::observe::contact::Contact;
    let n = truth.planes.len();
    let postures = simulate::sample_postures(truth, n * per_plane, seed);
    let observations: Vec<Observation> = (0..n * per_plane)
        .map(|i| Contact::new(i, Target::EndEffector, i % n).into())
        .collect();
    simulate::remeasure(truth, &Dataset::new(postures, observations))
}

fn with_planes(mut robot: Robot, normals: &[[f64; 3]]) -> Robot {
    for (k, n) in normals.iter().enumerate() {
        robot.planes.push(
            kinecal::model::robot::Plane::new(
                format!("p{k}"),
                nalgebra::Vector3::from(*n),
                0.1 * k as f64,
            )
            .unwrap(),
        );
    }
    robot
}

#[test]
fn plane_contacts_recover_a_6_joint_robot_and_follow_the_count() {
    let std = PerturbStd {
        length: 2e-3,
        angle: 0.5f64.to_radians(),
        slope_fraction: 0.0,
    };
    // Three fixed planes with independent normals fix the placement: 4*5 + 2 + 3 = 25.
    // One normal leaves sliding in the plane and turning about its normal: 25 - 3 = 22.
    // Two normals leave sliding along their intersection: 25 - 1 = 24.
    for (normals, rank) in [
        (&[[0.0, 0.0, 1.0], [1.0, 0.0, 0.2], [0.1, 1.0, 0.0]][..], 25),
        (&[[0.0, 0.0, 1.0]][..], 22),
        (&[[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]][..], 22),
        (&[[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]][..], 24),
    ] {
        let nominal = with_planes(six_joint(), normals);
        let truth = simulate::perturb(&nominal, std, 11);
        // The planes are fixed (known): keep them as in the nominal robot.
        let mut truth = truth;
        truth.planes = nominal.planes.clone();
        let data = contacts(&truth, 150 / normals.len(), 2);
        let candidates = parse_param_list("links,offsets", &nominal).unwrap();
        let a = analyze(&nominal, &data, &candidates, &AnalysisOptions::default()).unwrap();
        let expected = a.expected.clone().expect("the count applies");
        assert_eq!(expected.rank, rank, "{normals:?}: {}", expected.formula);
        assert_eq!(
            a.rank, rank,
            "{normals:?}: gap {} at {}",
            a.gap_ratio, a.gap_rank
        );
        let cal = calibrate(
            &nominal,
            &data,
            &CalibrationOptions::new(a.identifiable.clone()),
            &mut |_| {},
        )
        .unwrap();
        assert!(cal.objective_after < 1e-16 * cal.objective_before);
        let held = contacts(&truth, 20, 9);
        let before = accuracy(&nominal, &held).other[0].max;
        let after = accuracy(&cal.calibrated, &held).other[0].max;
        assert!(
            before > 1e-3 && after < 1e-9,
            "{normals:?}: {before} -> {after}"
        );
        if rank == 25 {
            // Placement fixed: the end effector's positions are the true ones.
            for p in simulate::sample_postures(&nominal, 20, 5) {
                let (t, c) = (
                    kinecal::Chain::new(&truth).frame_at(&p.readings, Target::EndEffector),
                    kinecal::Chain::new(&cal.calibrated).frame_at(&p.readings, Target::EndEffector),
                );
                assert!((t.translation - c.translation).norm() < 1e-9);
            }
        }
    }
}

#[test]
fn estimated_planes_join_the_count_and_are_recovered() {
    let nominal = with_planes(
        six_joint(),
        &[[0.0, 0.0, 1.0], [1.0, 0.0, 0.2], [0.1, 1.0, 0.0]],
    );
    // A tracker anchors the placement; the planes' tilts and offsets are unknown.
    let std = PerturbStd {
        length: 2e-3,
        angle: 0.5f64.to_radians(),
        slope_fraction: 0.0,
    };
    let truth = simulate::perturb(&nominal, std, 13);
    let data = contacts(&truth, 60, 4).merge(simulate::measure(
        &truth,
        &simulate::sample_postures(&nominal, 10, 6),
        true,
    ));
    let candidates = parse_param_list("links,offsets,planes", &nominal).unwrap();
    let a = analyze(&nominal, &data, &candidates, &AnalysisOptions::default()).unwrap();
    let expected = a.expected.clone().unwrap();
    assert_eq!(expected.rank, 25 + 9, "{}", expected.formula);
    assert_eq!(a.rank, 34);
    // Contacts alone with every plane estimated: the world's six motions return.
    let alone = contacts(&truth, 60, 4);
    let b = analyze(&nominal, &alone, &candidates, &AnalysisOptions::default()).unwrap();
    assert_eq!(b.expected.unwrap().rank, 25 + 9 - 6);
    assert_eq!(b.rank, 28);
    let cal = calibrate(
        &nominal,
        &data,
        &CalibrationOptions::new(a.identifiable.clone()),
        &mut |_| {},
    )
    .unwrap();
    assert!(cal.objective_after < 1e-16 * cal.objective_before);
    for k in 0..3 {
        let (t, c) = (&truth.planes[k], &cal.calibrated.planes[k]);
        assert!((t.normal() - c.normal()).norm() < 1e-9);
        assert!((t.offset - c.offset).abs() < 1e-9);
    }
}

#[test]
fn contact_files_read_and_refuse_mistakes() {
    use kinecal::files::parse_contacts;
    let text = kinecal::model::examples::GE_A4_TOML.to_string()
        + "\n[[planes]]\nname = \"table\"\nnormal = [0, 0, 1]\noffset = -2\n";
    let robot = kinecal::model::robot_file::parse_robot_toml(&text, "a4.toml").unwrap();
    let ok = "posture,site,plane,v1,v2,v3,v4,gap,sigma_position\n\
              1,ee,table,-11,12,4,-11,0.25,0.001\n\
              2,,table,-12,9,1.5,5,,\n";
    let d = parse_contacts(ok, "c.csv", &robot).unwrap();
    assert_eq!(d.observations.len(), 2);
    let Observation::Contact(c) = &d.observations[0] else {
        panic!()
    };
    assert!((c.gap - 0.25 * 0.0254).abs() < 1e-15);
    assert_eq!((c.line, c.plane), (2, 0));
    // With one plane, the plane column may be left out.
    let short = "posture,v1,v2,v3,v4\n1,-11,12,4,-11\n";
    assert_eq!(
        parse_contacts(short, "c.csv", &robot)
            .unwrap()
            .observations
            .len(),
        1
    );
    for (text, expect) in [
        (
            ok.replace(",table,-11", ",floor,-11"),
            "c.csv:2: field `plane`: unknown plane `floor`",
        ),
        (ok.replace("gap,", "height,"), "unknown column `height`"),
        (
            ok.replace("\n2,,", "\n1,,"),
            "c.csv:3: field `v1`: posture `1` appears earlier",
        ),
        (
            ok.replace("0.25,0.001", "x,0.001"),
            "c.csv:2: field `gap`: expected a number",
        ),
    ] {
        let e = parse_contacts(&text, "c.csv", &robot)
            .unwrap_err()
            .to_string();
        assert!(e.contains(expect), "expected `{expect}` in {e}");
    }
    let e = parse_contacts(short, "c.csv", &kinecal::model::examples::ge_a4())
        .unwrap_err()
        .to_string();
    assert!(e.contains("no [[planes]]"), "{e}");
}

/// Orientation residuals default to the rotation vector; Euler-angle residuals are refused,
/// naming the lines, when a measured attitude is within 1 deg of gimbal lock (beta = +-90 deg),
/// and accepted 2 deg away.
#[test]
fn euler_residuals_are_refused_near_gimbal_lock() {
    use kinecal::observe::OrientationError;
    assert_eq!(
        CalibrationOptions::new(vec![]).orientation,
        OrientationError::RotVec
    );
    let robot = kinecal::model::examples::ge_a4();
    let postures = simulate::sample_postures(&robot, 12, 5);
    for (beta_deg, refused) in [(89.5, true), (-89.2, true), (88.0, false)] {
        let mut data = simulate::measure(&robot, &postures, false);
        for (k, o) in data.observations.iter_mut().enumerate() {
            if k % 4 == 1 {
                if let kinecal::Observation::Pose(p) = o {
                    p.euler.y = f64::to_radians(beta_deg);
                }
            }
        }
        let mut opts = CalibrationOptions::new(vec![kinecal::ParamId(0)]);
        opts.orientation = OrientationError::Euler;
        let got = calibrate(&robot, &data, &opts, &mut |_| {});
        if refused {
            let err = got.unwrap_err();
            assert!(
                matches!(err, kinecal::Error::EulerNearGimbalLock { count: 3, .. }),
                "{err}"
            );
            assert!(err.to_string().contains("gimbal lock"), "{err}");
        } else {
            assert!(got.is_ok(), "{:?}", got.err());
        }
        // The rotation vector takes the same data.
        opts.orientation = OrientationError::RotVec;
        assert!(calibrate(&robot, &data, &opts, &mut |_| {}).is_ok());
    }
}
