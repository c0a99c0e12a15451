//! Measurements as real setups produce them: several reflectors per posture measured by
//! position only, outliers, robust loss, and files laid out differently.

use kinecal::apps::simulate::{self, PerturbStd};
use kinecal::files::{parse_measurements, parse_measurements_mapped, ColumnMap};
use kinecal::identifiability::{analyze, AnalysisOptions};
use kinecal::model::kinematics::Target;
use kinecal::observe::{accuracy, Observation, Weights};
use kinecal::solve::estimation::{calibrate, CalibrationOptions, Loss};
use kinecal::solve::outliers::outliers;
use kinecal::{JointKind, Link, ParamId, Site};
use nalgebra::Vector3;

fn six_r_with_reflectors() -> kinecal::Robot {
    let mut robot = simulate::random_robot(&[JointKind::Revolute; 6], 66);
    for (k, (x, y)) in [(0.05, 0.0), (-0.03, 0.05), (0.0, -0.06)]
        .iter()
        .enumerate()
    {
        robot.sites.push(Site {
            name: format!("smr{}", k + 1),
            joint: 6,
            frame: Link {
                x: *x,
                y: *y,
                z: 0.08,
                ..Link::default()
            },
        });
    }
    robot
}

/// Position-only data of three reflectors on a 6R arm, one reflector per posture as a laser
/// tracker measures them, 0.05 mm noise: the calibrated model predicts held-out postures of the
/// true robot to the noise level.
#[test]
fn position_only_reflectors_recover_the_truth_to_the_noise_level() {
    let nominal = six_r_with_reflectors();
    let std = PerturbStd {
        length: 1e-3,
        angle: 0.2f64.to_radians(),
        slope_fraction: 0.0,
    };
    let truth = simulate::perturb(&nominal, std, 8);
    let noise = 5e-5;
    let mut data = simulate::measure(&truth, &simulate::sample_postures(&nominal, 90, 4), true);
    // One reflector per posture, in turn.
    let mut k = 0;
    data.observations.retain(|m| {
        k += 1;
        m.target() == Target::Site((k - 1) / 4 % 3)
    });
    simulate::add_noise(&mut data, noise, 0.0, 9);
    let mut candidates: Vec<ParamId> =
        kinecal::parse_param_list("links,offsets,sites", &nominal).unwrap();
    candidates.sort();
    let a = analyze(&nominal, &data, &candidates, &AnalysisOptions::default()).unwrap();
    // 4 per revolute joint + 3 per measured point (QKM-style setup).
    assert_eq!(a.rank, 4 * 6 + 3 * 3);
    let mut opts = CalibrationOptions::new(a.identifiable.clone());
    opts.weights = Weights {
        length: noise,
        angle: 1e-3,
    };
    let cal = calibrate(&nominal, &data, &opts, &mut |_| {}).unwrap();
    // Held-out: fresh postures, every reflector, noise-free truth.
    let mut held = simulate::measure(&truth, &simulate::sample_postures(&nominal, 30, 77), true);
    // The reflectors only: the flange itself was never measured.
    held.observations
        .retain(|m| m.target() != Target::EndEffector);
    let acc = accuracy(&cal.calibrated, &held);
    // The fit's own error at a point is ~noise * sqrt(p / m) per coordinate (p = 33 parameters
    // over m = 270 residuals): ~0.35 noise per coordinate, ~0.6 noise in 3D. 1.5 noise is a
    // generous bound that a wrong model (mm-level errors) cannot meet.
    assert!(
        acc.rms_position < 1.5 * noise,
        "held-out RMS {} m for noise {noise}",
        acc.rms_position
    );
    eprintln!("held-out RMS {:.3e} m (noise {noise:e})", acc.rms_position);
    let nominal_acc = accuracy(&nominal, &held);
    assert!(nominal_acc.rms_position > 20.0 * noise);
}

#[test]
fn outliers_are_listed_and_huber_resists_them() {
    let nominal = kinecal::model::examples::ge_a4();
    let mut truth = nominal.clone();
    truth.set(ParamId(0), truth.get(ParamId(0)) + 0.002);
    let mut data = simulate::measure(&truth, &simulate::sample_postures(&nominal, 40, 2), false);
    simulate::add_noise(&mut data, 2e-5, 2e-5, 3);
    // Two bad rows: a reflector bumped by 2 mm.
    for i in [5, 17] {
        let Observation::Pose(p) = &mut data.observations[i] else {
            panic!("poses")
        };
        p.position += Vector3::new(2e-3, -1e-3, 0.0);
    }
    let ids = kinecal::parse_param_list("p1,p2,p8,p14,offsets", &nominal).unwrap();
    let mut opts = CalibrationOptions::new(ids);
    opts.weights = Weights {
        length: 2e-5,
        angle: 2e-5,
    };
    let ls = calibrate(&nominal, &data, &opts, &mut |_| {}).unwrap();
    // Least squares lets the two bad rows pull the fit: they are flagged, among others.
    let flagged: Vec<usize> = outliers(&ls, &data, 4.0)
        .iter()
        .map(|o| o.observation)
        .collect();
    assert!(flagged.contains(&5) && flagged.contains(&17), "{flagged:?}");
    opts.loss = Loss::huber(1.345);
    let hub = calibrate(&nominal, &data, &opts, &mut |_| {}).unwrap();
    // The robust fit is not pulled: exactly the two bad rows stand out.
    let flagged: Vec<usize> = outliers(&hub, &data, 4.0)
        .iter()
        .map(|o| o.observation)
        .collect();
    assert_eq!(flagged, vec![5, 17]);
    let err =
        |c: &kinecal::Calibration| (c.calibrated.get(ParamId(0)) - truth.get(ParamId(0))).abs();
    assert!(
        err(&hub) < 0.1 * err(&ls),
        "huber {} vs least squares {}",
        err(&hub),
        err(&ls)
    );
    assert!(err(&hub) < 1e-5);
    // Clean data: nothing flagged.
    let clean = simulate::measure(&truth, &simulate::sample_postures(&nominal, 40, 2), false);
    let c = calibrate(
        &nominal,
        &clean,
        &CalibrationOptions::new(vec![ParamId(0)]),
        &mut |_| {},
    )
    .unwrap();
    assert!(outliers(&c, &clean, 4.0).is_empty());
}

fn map(specs: &[&str]) -> ColumnMap {
    ColumnMap::parse(specs, "--columns").unwrap()
}

#[test]
fn column_mapping_reads_a_tracker_export() {
    let robot = kinecal::model::examples::ge_a4();
    let text =
        "Point,J1,J2,J3,J4,X,Y,Z,Quality\nA,-11.053,12.369,4.009,-11.583,14.071,19.083,0.177,ok\n\
                B,-12.696,9.037,1.493,5.156,6.098,14.220,3.700,ok\n";
    let m = map(&["posture=Point,v1=J1,v2=J2,v3=J3,v4=J4,x=X,y=Y,z=Z"]);
    let data = parse_measurements_mapped(text, "t.csv", &robot, &m).unwrap();
    assert_eq!(data.observations.len(), 2);
    assert!(data
        .observations
        .iter()
        .all(|m| m.kind() == "position" && m.target() == Target::EndEffector));
    let Observation::Position(p) = &data.observations[1] else {
        panic!()
    };
    assert!((p.position.z - 3.7 * 0.0254).abs() < 1e-12);
    assert_eq!(p.line, 3);
    let bad = text.replace("B,-12.696", "B,oops");
    let e = parse_measurements_mapped(&bad, "t.csv", &robot, &m).unwrap_err();
    assert!(e.to_string().contains("t.csv:3: field `J1`"), "{e}");
}

#[test]
fn other_layouts_load_as_they_are() {
    let robot = kinecal::model::examples::ge_a4();
    // No posture column: rows number the postures. Comment lines before the header, `;` as
    // the delimiter (as tracker software exports).
    let text = "# Tracker export 2026-11-22\n# units: in, deg\nJ1;J2;J3;J4;X;Y;Z\n\
                -11.053;12.369;4.009;-11.583;14.071;19.083;0.177\n\
                -12.696;9.037;1.493;5.156;6.098;14.220;3.700\n";
    let m = map(&["v1=J1,v2=J2,v3=J3,v4=J4,x=X,y=Y,z=Z"]);
    let d = parse_measurements_mapped(text, "t.csv", &robot, &m).unwrap();
    assert_eq!(d.postures.len(), 2);
    assert_eq!(d.postures[1].label, "2");
    assert_eq!(d.observations[1].line(), 5);
    // A spreadsheet in a decimal-comma locale: `;` between fields, `,` in numbers, and a
    // delimiter ending every data row (not the header).
    let euro = "J1;J2;J3;J4;X;Y;Z\n-11,053;12,369;4,009;-11,583;14,071;19,083;0,177;\n\
                -12,696;9,037;1,493;5,156;6,098;14,220;3,700;\n";
    let e = parse_measurements_mapped(euro, "t.csv", &robot, &m).unwrap();
    assert_eq!(e.observations.len(), 2);
    for (a, b) in e.observations.iter().zip(&d.observations) {
        let (Observation::Position(a), Observation::Position(b)) = (a, b) else {
            panic!()
        };
        assert_eq!(a.position, b.position);
    }
    assert_eq!(e.postures[1].readings, d.postures[1].readings);
    // Two commas are not a number.
    let bad = euro.replace("0,177", "0,1,77");
    let err = parse_measurements_mapped(&bad, "t.csv", &robot, &m).unwrap_err();
    assert!(err.to_string().contains("t.csv:2: field `Z`"), "{err}");
    // Tabs, and the plain reader (kinecal's own column names) also reads them.
    let tabbed = "posture\tv1\tv2\tv3\tv4\tx\ty\tz\n1\t1\t2\t3\t4\t5\t6\t7\n";
    let d = parse_measurements(tabbed, "t.tsv", &robot).unwrap();
    assert_eq!(d.observations.len(), 1);
    // FIGAROH's wide layout: several markers side by side, one mapping per site.
    let mut a4 = robot.clone();
    for name in ["m1", "m2"] {
        a4.sites.push(Site {
            name: name.into(),
            joint: 4,
            frame: Link::default(),
        });
    }
    let wide = "x1,y1,z1,x2,y2,z2,q1,q2,q3,q4\n\
                1,2,3,4,5,6,-11,12,4,-11\n\
                1,2,3,,,,-12,9,1.5,5\n";
    let m = map(&[
        "v1=q1,v2=q2,v3=q3,v4=q4",
        "m1:x=x1,y=y1,z=z1",
        "m2:x=x2,y=y2,z=z2",
    ]);
    let d = parse_measurements_mapped(wide, "w.csv", &a4, &m).unwrap();
    assert_eq!(d.postures.len(), 2);
    // The second marker was not measured in the second row.
    assert_eq!(d.observations.len(), 3);
    assert_eq!(d.observations[1].target(), Target::Site(1));
    // Mistakes are refused with a message.
    for (specs, expect) in [
        (&["v1=q1,v1=q2"][..], "mapped twice"),
        (&["v1=q1,v2=q1"][..], "mapped to both"),
        (&["m1:v1=q1"][..], "not a marker column"),
        (&["v1=q1", "v2=q2"][..], "only one mapping"),
    ] {
        let e = ColumnMap::parse(specs, "--columns")
            .unwrap_err()
            .to_string();
        assert!(e.contains(expect), "{specs:?}: {e}");
    }
    let e = parse_measurements_mapped(
        wide,
        "w.csv",
        &a4,
        &map(&["v1=q1,v2=q2,v3=q3,v4=q4", "m9:x=x1,y=y1,z=z1"]),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("unknown site `m9`"), "{e}");
    // A mapping to a column the file does not have, a shared marker column next to markers,
    // and one file column read for two markers are refused, never silently ignored.
    for (specs, expect) in [
        (
            &["v1=q1,v2=q2,v3=q3,v4=q4,x=x1,y=y1,z=z1,sigma_position=RMS"][..],
            "column mapping `sigma_position=RMS`: no column `RMS`",
        ),
        (
            &["v1=q1,v2=q2,v3=q3,v4=q4", "m1:x=x1,y=y1,z=z1,alpha=Rz"][..],
            "column mapping `alpha=Rz`: no column `Rz`",
        ),
        (
            &["v1=q1,v2=q2,v3=q3,v4=q4,posture=Point", "m1:x=x1,y=y1,z=z1"][..],
            "column mapping `posture=Point`",
        ),
        (
            &["v1=q1,v2=q2,v3=q3,v4=q4,x=x1", "m1:x=x1,y=y1,z=z1"][..],
            "`x=x1` in the shared mapping is not used when markers are given",
        ),
        (
            &[
                "v1=q1,v2=q2,v3=q3,v4=q4",
                "m1:x=x1,y=y1,z=z1",
                "m2:x=x1,y=y2,z=z2",
            ][..],
            "file column `x1` is mapped for both markers `m1` and `m2`",
        ),
    ] {
        let e = parse_measurements_mapped(wide, "w.csv", &a4, &map(specs))
            .unwrap_err()
            .to_string();
        assert!(e.contains(expect), "{specs:?}: {e}");
    }
    // A plain file with a column kinecal does not know says what it expected.
    let e = parse_measurements("posture,v1,v2,v3,v4,v5,x,y,z\n", "p.csv", &robot)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("unknown column `v5` (the robot has 4 joints)"),
        "{e}"
    );
}

/// The ABB setup: test points on the tool known only from one precise measurement at the zero
/// posture. Each is anchored by that single row with its own standard deviation (1 um), not by
/// repeating the row: the held-out accuracy equals that of the same data fitted with the points
/// fixed exactly (the robot fitted on the flange data, then each point placed so that it passes
/// through its zero-posture measurement), to 1 %, and the statistics are not distorted.
#[test]
fn tool_points_anchored_by_one_precise_row_match_points_fixed_exactly() {
    use kinecal::observe::Posture;
    let mut truth = simulate::random_robot(&[JointKind::Revolute; 6], 120);
    let tips = [(0.05, 0.0, 0.10), (0.0, 0.05, 0.12), (-0.04, -0.03, 0.09)];
    for (k, &(x, y, z)) in tips.iter().enumerate() {
        truth.sites.push(Site {
            name: format!("tip{}", k + 1),
            joint: 6,
            frame: Link {
                x,
                y,
                z,
                ..Link::default()
            },
        });
    }
    let std = PerturbStd {
        length: 1e-3,
        angle: 0.2f64.to_radians(),
        slope_fraction: 0.0,
    };
    let mut nominal = simulate::perturb(&truth, std, 3);
    for s in &mut nominal.sites {
        s.frame.x += 2e-3; // the points are known only roughly before the measurement
    }
    let noise = 2e-5;
    // The flange marker at 40 postures, 20 um noise.
    let postures = simulate::sample_postures(&nominal, 40, 5);
    let mut flange = simulate::measure(&truth, &postures, true);
    flange
        .observations
        .retain(|o| o.target() == Target::EndEffector);
    simulate::add_noise(&mut flange, noise, 0.0, 6);
    // The three tool points, once each, at the zero posture, 1 um.
    let zero = vec![Posture {
        label: "zero".into(),
        readings: vec![0.0; 6],
        session: None,
        payload: None,
    }];
    let mut anchors = simulate::measure(&truth, &zero, true);
    anchors
        .observations
        .retain(|o| o.target() != Target::EndEffector);
    simulate::add_noise(&mut anchors, 1e-6, 0.0, 7);
    for o in &mut anchors.observations {
        if let Observation::Position(p) = o {
            p.sigma_position = Some(nalgebra::Vector3::repeat(1e-6));
        }
    }
    let data = flange.clone().merge(anchors.clone());
    let weights = Weights {
        length: noise,
        angle: 1e-3,
    };
    let robot_params = kinecal::parse_param_list("links,offsets", &nominal).unwrap();
    let mut with_points = robot_params.clone();
    for k in 1..=3 {
        with_points.extend(
            kinecal::parse_param_list(
                &format!("site.tip{k}.x,site.tip{k}.y,site.tip{k}.z"),
                &nominal,
            )
            .unwrap(),
        );
    }
    with_points.sort();
    let aopts = AnalysisOptions {
        weights,
        ..Default::default()
    };
    // A: one fit, the points anchored by their rows.
    let a_set = analyze(&nominal, &data, &with_points, &aopts)
        .unwrap()
        .identifiable;
    let mut opts = CalibrationOptions::new(a_set);
    opts.weights = weights;
    let a = calibrate(&nominal, &data, &opts, &mut |_| {}).unwrap();
    // B: the robot from the flange data, then the points fixed exactly through their rows.
    let b_set = analyze(&nominal, &flange, &robot_params, &aopts)
        .unwrap()
        .identifiable;
    let mut opts = CalibrationOptions::new(b_set);
    opts.weights = weights;
    let mut b = calibrate(&nominal, &flange, &opts, &mut |_| {})
        .unwrap()
        .calibrated;
    let chain = kinecal::Chain::new(&b);
    let mut ws = kinecal::Workspace::new(&b);
    chain.forward(&[0.0; 6], &mut ws);
    // The frame right after joint 6 is the proximal frame of the last link: the end effector
    // frame with the last link undone.
    let last = kinecal::Frame::from_link(b.links.last().unwrap());
    let after6 = ws.end_effector().then(&kinecal::import::inverse(&last));
    for o in &anchors.observations {
        let Observation::Position(p) = o else {
            panic!()
        };
        let Target::Site(s) = p.view[0].target else {
            panic!()
        };
        let local = after6.rotation.transpose() * (p.position - after6.translation);
        b.sites[s].frame.x = local.x;
        b.sites[s].frame.y = local.y;
        b.sites[s].frame.z = local.z;
    }
    // Held out: the tool points at fresh postures, noise-free.
    let mut held = simulate::measure(&truth, &simulate::sample_postures(&nominal, 30, 77), true);
    held.observations
        .retain(|o| o.target() != Target::EndEffector);
    let (ea, eb) = (
        accuracy(&a.calibrated, &held).mean_position,
        accuracy(&b, &held).mean_position,
    );
    eprintln!(
        "held-out mean: anchored {ea:.4e} m ({:?} after {} iterations), fixed exactly {eb:.4e} m",
        a.termination, a.iterations
    );
    assert!(a.converged() && a.iterations <= 50, "{:?}", a.termination);
    assert!((ea - eb).abs() <= 0.01 * eb, "anchored {ea} vs fixed {eb}");
    assert!(eb < 3.0 * noise, "{eb}");
    // The anchor rows are fitted, not flagged, and the variance factor is the flange data's.
    let outcome_flags = outliers(&a, &data, 4.0);
    assert!(
        outcome_flags
            .iter()
            .all(|o| data.observations[o.observation].target() == Target::EndEffector),
        "{outcome_flags:?}"
    );
    let ua = kinecal::uncertainty::uncertainty(&a, &data, &nominal).unwrap();
    assert!(
        (ua.variance_factor - 1.0).abs() < 0.35,
        "variance factor {}",
        ua.variance_factor
    );
}

/// Clean Gaussian data, with weights that overstate the position noise 40 times and the angle
/// noise not at all (so a pooled robust scale would flag every second pose): at most 1 % of the
/// observations are flagged at the default threshold, for 30 and for 1,000 postures.
#[test]
fn clean_gaussian_data_flags_at_most_one_percent() {
    let nominal = kinecal::model::examples::ge_a4();
    let mut truth = nominal.clone();
    truth.set(ParamId(0), truth.get(ParamId(0)) + 0.05 * 0.0254);
    for (postures, seed) in [(30, 7), (1000, 8)] {
        let mut data = simulate::measure(
            &truth,
            &simulate::sample_postures(&nominal, postures, seed),
            false,
        );
        simulate::add_noise(&mut data, 0.0005 * 0.0254, 0.005f64.to_radians(), seed);
        let ids = kinecal::parse_param_list("p1,p2,p8,p14,offsets,slopes", &nominal).unwrap();
        let cal = calibrate(&nominal, &data, &CalibrationOptions::new(ids), &mut |_| {}).unwrap();
        let flagged = outliers(&cal, &data, kinecal::solve::outliers::DEFAULT_SIGMAS).len();
        assert!(
            flagged as f64 <= 0.01 * postures as f64,
            "{flagged} of {postures} flagged"
        );
    }
}
