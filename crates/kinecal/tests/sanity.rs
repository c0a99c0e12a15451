//! Units and readings that do not match the robot file are said, never fitted silently.

use kinecal::files::{parse_measurements, write_measurements};
use kinecal::model::robot::JointKind;
use kinecal::units::{AngleUnit, LengthUnit};
use kinecal::workflow::{self, Request, Selection};
use kinecal::{apps::simulate, Robot, Warning};

/// A 6R robot in metres and degrees whose readings are the joint angles (slope 1).
fn robot() -> Robot {
    let mut r = simulate::random_robot(&[JointKind::Revolute; 6], 11);
    r.units.length = LengthUnit::M;
    r.units.angle = AngleUnit::Deg;
    for j in &mut r.joints {
        j.slope = 1f64.to_radians();
        j.offset = 0.0;
    }
    r
}

/// Data of `truth` written in `written`'s units, read back against `read_as`.
fn data_in(truth: &Robot, written: &Robot, read_as: &Robot) -> kinecal::Dataset {
    let postures = simulate::sample_postures(truth, 40, 5);
    let mut d = simulate::measure(truth, &postures, true);
    simulate::add_noise(&mut d, 1e-5, 0.0, 5);
    parse_measurements(&write_measurements(written, &d), "d.csv", read_as).unwrap()
}

fn run(robot: &Robot, data: kinecal::Dataset) -> workflow::Outcome {
    let mut req = Request::new(robot.clone(), data);
    req.selection = Selection::parse("links,offsets", None, robot).unwrap();
    workflow::run(&req, &mut ()).unwrap()
}

fn implausible(o: &workflow::Outcome) -> Vec<&Warning> {
    o.warnings.iter().filter(|w| w.implausible()).collect()
}

#[test]
fn data_in_millimetres_against_a_robot_in_metres_is_said() {
    let m = robot();
    let mut mm = m.clone();
    mm.units.length = LengthUnit::Mm;
    // The same robot, the data in mm, read as metres: 1000 times too far apart.
    let out = run(&m, data_in(&m, &mm, &m));
    let w = implausible(&out);
    assert!(
        w.iter().any(
            |w| matches!(w, Warning::ScaleMismatch { ratio, likely: Some(l), .. }
            if (ratio / 1000.0 - 1.0).abs() < 0.05 && l == "mm")
        ),
        "{w:?}"
    );
    let text = w
        .iter()
        .map(|w| w.to_string())
        .collect::<Vec<_>>()
        .join("\n");
    assert!(
        text.contains("are they in mm? the data is read in the robot file's length unit (m)"),
        "{text}"
    );
    // And the fit, which "converges" to links of hundreds of metres, says so too.
    assert!(
        w.iter().any(
            |w| matches!(w, Warning::ChangeBeyondReach { parameters, .. } if !parameters.is_empty())
        ),
        "{w:?}"
    );
    // The reverse: data in metres against a robot in millimetres.
    let out = run(&mm, data_in(&mm, &m, &mm));
    assert!(
        implausible(&out).iter().any(
            |w| matches!(w, Warning::ScaleMismatch { ratio, likely: Some(l), .. }
            if (ratio * 1000.0 - 1.0).abs() < 0.05 && l == "m")
        ),
        "{:?}",
        out.warnings
    );
}

#[test]
fn clean_data_from_a_far_tracker_raises_nothing() {
    let m = robot();
    let mut truth = m.clone();
    // The tracker 3 m away and turned: the base link absorbs it.
    truth.links[0].x += 3.0;
    truth.links[0].y -= 1.5;
    truth.links[0].gamma += 0.7;
    let out = run(&m, data_in(&truth, &m, &m));
    assert!(implausible(&out).is_empty(), "{:?}", out.warnings);
    assert!(out.calibration.converged());
}

#[test]
fn readings_in_the_other_angle_unit_or_outside_the_ranges_are_named() {
    let deg = robot();
    let mut rad = deg.clone();
    rad.units.angle = AngleUnit::Rad;
    for j in &mut rad.joints {
        j.slope = 1.0;
    }
    // Radian readings against the degree robot (slope 1 deg per unit).
    let mut d = data_in(&deg, &deg, &deg);
    for p in &mut d.postures {
        p.readings.iter_mut().for_each(|v| *v = v.to_radians());
    }
    let out = run(&deg, d);
    assert!(
        out.warnings.iter().any(
            |w| matches!(w, Warning::AngleUnitMismatch { looks_like, joints, .. }
            if looks_like == "rad" && joints.len() == 6)
        ),
        "{:?}",
        out.warnings
    );
    // Degree readings against the radian robot (slope 1 rad per unit).
    let mut d = data_in(&rad, &rad, &rad);
    for p in &mut d.postures {
        p.readings.iter_mut().for_each(|v| *v = v.to_degrees());
    }
    let out = run(&rad, d);
    assert!(
        out.warnings.iter().any(
            |w| matches!(w, Warning::AngleUnitMismatch { looks_like, .. }
            if looks_like == "deg")
        ),
        "{:?}",
        out.warnings
    );
    // Right units: nothing.
    for r in [&deg, &rad] {
        let out = run(r, data_in(r, r, r));
        assert!(implausible(&out).is_empty(), "{:?}", out.warnings);
    }
    // Ranges: joint 2 may read -90..90 deg; three postures read beyond it.
    let mut ranged = deg.clone();
    ranged.joints[1].range = Some((-90.0, 90.0));
    let mut d = data_in(&deg, &deg, &deg);
    for p in d.postures.iter_mut().take(3) {
        p.readings[1] = 150.0;
    }
    for p in d.postures.iter_mut().skip(3) {
        p.readings[1] = p.readings[1].clamp(-90.0, 90.0);
    }
    let labels: Vec<String> = d.postures.iter().take(3).map(|p| p.label.clone()).collect();
    let out = run(&ranged, d);
    let w = out
        .warnings
        .iter()
        .find(|w| matches!(w, Warning::ReadingsOutOfRange { .. }))
        .expect("out of range");
    assert_eq!(
        *w,
        Warning::ReadingsOutOfRange {
            joint: 2,
            count: 3,
            postures: labels.clone(),
            min: -90.0,
            max: 90.0
        }
    );
    assert!(w.to_string().starts_with(&format!(
        "joint 2: 3 posture(s) read outside its range [-90, 90] (postures {})",
        labels.join(", ")
    )));
}
