//! Files in other units than the robot file's, attitudes in the other angle unit, pose files
//! read as positions, per-axis standard deviations: stated at the door and converted, or named
//! before any solving when they are not.

use kinecal::files::{read_observations, write_measurements, ColumnMap, ReadOptions};
use kinecal::observe::Observation;
use kinecal::units::{AngleUnit, LengthUnit, Units};
use kinecal::workflow::{self, Request};
use kinecal::{apps::simulate, Dataset, Error, JointKind, Robot, Warning};

fn robot_in(length: LengthUnit, angle: AngleUnit) -> Robot {
    let mut r = simulate::random_robot(&[JointKind::Revolute; 5], 41);
    r.units = Units { length, angle };
    r
}

/// Noisy poses of a slightly changed robot.
fn poses(robot: &Robot, n: usize) -> Dataset {
    let mut truth = robot.clone();
    truth.links[2].x += 0.002;
    let ps = simulate::sample_postures(robot, n, 5);
    let mut d = simulate::measure(&truth, &ps, false);
    simulate::add_noise(&mut d, 3e-5, 1e-4, 6);
    d
}

fn close(a: &Dataset, b: &Dataset) -> bool {
    a.observations.len() == b.observations.len()
        && a.observations
            .iter()
            .zip(&b.observations)
            .all(|(x, y)| match (x, y) {
                (Observation::Pose(p), Observation::Pose(q)) => {
                    (p.position - q.position).norm() < 1e-12 && (p.euler - q.euler).norm() < 1e-12
                }
                (Observation::Position(p), Observation::Position(q)) => {
                    (p.position - q.position).norm() < 1e-12
                }
                _ => false,
            })
}

/// A file written in mm and degrees reads, for a robot in metres and radians, as the same data
/// once its units are stated (as options or in the column mapping); stated twice differently, it
/// is refused.
#[test]
fn stated_units_are_converted() {
    let robot = robot_in(LengthUnit::M, AngleUnit::Rad);
    let data = poses(&robot, 12);
    let text = write_measurements(&robot_in(LengthUnit::Mm, AngleUnit::Deg), &data);
    let opts = ReadOptions {
        length_unit: Some(LengthUnit::Mm),
        angle_unit: Some(AngleUnit::Deg),
        ..ReadOptions::default()
    };
    assert!(close(
        &read_observations(&text, "d.csv", &robot, &opts).unwrap(),
        &data
    ));
    let mapped = ReadOptions {
        columns: ColumnMap::parse(&["length_unit=mm,angle_unit=deg"], "--columns").unwrap(),
        ..ReadOptions::default()
    };
    assert!(close(
        &read_observations(&text, "d.csv", &robot, &mapped).unwrap(),
        &data
    ));
    let both = ReadOptions {
        length_unit: Some(LengthUnit::M),
        ..mapped
    };
    let err = read_observations(&text, "d.csv", &robot, &both)
        .unwrap_err()
        .to_string();
    assert!(err.contains("stated twice"), "{err}");
    // A distances file in mm.
    let dist = "pair,a1,a2,a3,a4,a5,b1,b2,b3,b4,b5,distance\n1,0,0,0,0,0,0.1,0,0,0,0,250\n";
    let d = read_observations(dist, "b.csv", &robot, &opts).unwrap();
    let Observation::Distance(x) = &d.observations[0] else {
        panic!("a distance")
    };
    assert!((x.distance - 0.25).abs() < 1e-15);
}

/// A pose file read as positions: by the option, or by leaving the angle columns out of the
/// mapping (`alpha=-`); a required column cannot be left out.
#[test]
fn pose_files_read_as_positions() {
    let robot = robot_in(LengthUnit::M, AngleUnit::Rad);
    let data = poses(&robot, 6);
    let text = write_measurements(&robot, &data);
    let positions = |d: &Dataset| {
        d.observations
            .iter()
            .all(|o| matches!(o, Observation::Position(_)))
    };
    let opts = ReadOptions {
        position_only: true,
        ..ReadOptions::default()
    };
    assert!(positions(
        &read_observations(&text, "d.csv", &robot, &opts).unwrap()
    ));
    let cols = ReadOptions {
        columns: ColumnMap::parse(&["alpha=-,beta=-,gamma=-"], "--columns").unwrap(),
        ..ReadOptions::default()
    };
    assert!(positions(
        &read_observations(&text, "d.csv", &robot, &cols).unwrap()
    ));
    let bad = ReadOptions {
        columns: ColumnMap::parse(&["x=-"], "--columns").unwrap(),
        ..ReadOptions::default()
    };
    let err = read_observations(&text, "d.csv", &robot, &bad)
        .unwrap_err()
        .to_string();
    assert!(err.contains("`x` cannot be left out"), "{err}");
}

/// Per-axis standard deviations: read (in the file's unit), written back, refused when partial
/// or given beside `sigma_position`.
#[test]
fn per_axis_standard_deviations() {
    let robot = robot_in(LengthUnit::Mm, AngleUnit::Deg);
    let head = "posture,v1,v2,v3,v4,v5,x,y,z";
    let text = format!("{head},sigma_x,sigma_y,sigma_z\n1,0,0,0,0,0,1,2,3,0.01,0.02,0.5\n");
    let d = read_observations(&text, "s.csv", &robot, &ReadOptions::default()).unwrap();
    let Observation::Position(p) = &d.observations[0] else {
        panic!("a position")
    };
    let s = p.sigma_position.unwrap();
    assert!(
        (s.x - 1e-5).abs() < 1e-18 && (s.z - 5e-4).abs() < 1e-18,
        "{s}"
    );
    let again = write_measurements(&robot, &d);
    assert!(again.starts_with("posture,site,v1,v2,v3,v4,v5,x,y,z,alpha,beta,gamma,sigma_x,sigma_y,sigma_z,sigma_angle"), "{again}");
    let back = read_observations(&again, "w.csv", &robot, &ReadOptions::default()).unwrap();
    let Observation::Position(q) = &back.observations[0] else {
        panic!("a position")
    };
    assert!((q.sigma_position.unwrap() - s).norm() < 1e-18);
    let partial = format!("{head},sigma_x,sigma_y\n1,0,0,0,0,0,1,2,3,0.01,0.02\n");
    let err = read_observations(&partial, "s.csv", &robot, &ReadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(err.contains("all of sigma_x, sigma_y, sigma_z"), "{err}");
    let both =
        format!("{head},sigma_position,sigma_x,sigma_y,sigma_z\n1,0,0,0,0,0,1,2,3,1,1,1,1\n");
    let err = read_observations(&both, "s.csv", &robot, &ReadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(err.contains("not both"), "{err}");
}

/// A row's own standard deviation more than 10^6 below its file's median for that quantity
/// (issue 38): one row of 1e-15 mm among 0.01 mm outweighed the file 10^26 to 1, exit 0, a
/// robot written whose attitudes were ten times worse than the nominal's. Refused with the
/// file, the line and the column; an anchor stated 10^3 more precisely is read.
#[test]
fn a_standard_deviation_far_below_its_files_median_is_refused_with_its_line() {
    let robot = robot_in(LengthUnit::Mm, AngleUnit::Deg);
    let read = |text: &str| read_observations(text, "s.csv", &robot, &ReadOptions::default());
    let poses = |sigmas: [(&str, &str); 4]| {
        let mut t = String::from(
            "posture,v1,v2,v3,v4,v5,x,y,z,alpha,beta,gamma,sigma_position,sigma_angle\n",
        );
        for (k, (p, a)) in sigmas.iter().enumerate() {
            t += &format!("{k},0.{k},0,0,0,0,1,2,3,4,5,6,{p},{a}\n");
        }
        t
    };
    let ok = [("0.01", "0.001"); 4];
    read(&poses(ok)).expect("uniform sigmas");
    let mut anchor = ok;
    anchor[2] = ("1e-5", "1e-6");
    read(&poses(anchor)).expect("an anchor 10^3 more precise than the rest");
    let mut slip = ok;
    slip[1].0 = "1e-15";
    let err = read(&poses(slip)).unwrap_err().to_string();
    assert!(
        err.starts_with("s.csv:3: field `sigma_position`: a standard deviation of 1e-15 mm")
            && err.contains("median of the file's length standard deviations (0.01 mm)")
            && err.contains("at most 1e6 times below"),
        "{err}"
    );
    let mut slip = ok;
    slip[3].1 = "1e-10";
    let err = read(&poses(slip)).unwrap_err().to_string();
    assert!(
        err.starts_with("s.csv:5: field `sigma_angle`: a standard deviation of 1e-10 deg"),
        "{err}"
    );
    // Per axis: the axis is named.
    let axes = "posture,v1,v2,v3,v4,v5,x,y,z,sigma_x,sigma_y,sigma_z\n\
                1,0,0,0,0,0,1,2,3,0.01,0.01,0.02\n2,1,0,0,0,0,1,2,3,0.01,1e-9,0.02\n\
                3,2,0,0,0,0,1,2,3,0.01,0.01,0.02\n";
    let err = read(axes).unwrap_err().to_string();
    assert!(err.starts_with("s.csv:3: field `sigma_y`"), "{err}");
    // Distances too.
    let robot4 = simulate::random_robot(&[JointKind::Revolute; 4], 41);
    let ballbar = "pair,a1,a2,a3,a4,b1,b2,b3,b4,distance,sigma_position\n\
                   1,0,0,0,0,1,0,0,0,0.2,1e-4\n2,0,1,0,0,1,1,0,0,0.2,1e-4\n\
                   3,0,0,1,0,1,0,1,0,0.2,1e-12\n";
    let err = kinecal::files::parse_distances(ballbar, "b.csv", &robot4)
        .unwrap_err()
        .to_string();
    assert!(err.starts_with("b.csv:4: field `sigma_position`"), "{err}");
}

/// The files of one run are fitted together (issue 38): a distance file of one row stated at
/// 1e-12 mm beside a measurement file at 0.01 mm passed each file's own check (one row is its
/// own median) and outweighed the rest 10^20 to 1. The median is now of every file's standard
/// deviations of a quantity: refused naming that file, its line and column and the files whose
/// median it is; an anchor 10^3 more precise than the other file's rows is read.
#[test]
fn a_standard_deviation_far_below_the_median_of_the_runs_files_is_refused_with_its_line() {
    use kinecal::files::{read_files, ObservationFile, ReadSettings};
    let robot = robot_in(LengthUnit::Mm, AngleUnit::Deg);
    let tmp = tempfile::tempdir().unwrap();
    let mut poses =
        String::from("posture,v1,v2,v3,v4,v5,x,y,z,alpha,beta,gamma,sigma_position,sigma_angle\n");
    for k in 0..4 {
        poses += &format!("{k},0.{k},0,0,0,0,1,2,3,4,5,6,0.01,0.001\n");
    }
    let data = tmp.path().join("poses.csv");
    std::fs::write(&data, poses).unwrap();
    let distance = |sigma: &str| {
        let path = tmp.path().join(format!("ballbar{sigma}.csv"));
        std::fs::write(
            &path,
            format!(
                "pair,a1,a2,a3,a4,a5,b1,b2,b3,b4,b5,distance,sigma_position\n\
                 1,0,0,0,0,0,1,0,0,0,0,200,{sigma}\n"
            ),
        )
        .unwrap();
        path
    };
    let read = |other: &std::path::Path| {
        read_files(
            &ReadSettings::default(),
            &[
                ObservationFile::new(data.to_str().unwrap()),
                ObservationFile::new(other.to_str().unwrap()),
            ],
            &robot,
            &[],
        )
    };
    let anchor = distance("1e-5");
    let (both, _) = read(&anchor).expect("an anchor 10^3 more precise than the other file");
    assert_eq!(both.observations.len(), 5);
    let slip = distance("1e-12");
    let err = read(&slip).unwrap_err().to_string();
    let name = slip.to_str().unwrap();
    assert!(
        err.starts_with(&format!(
            "{name}:2: field `sigma_position`: a standard deviation of 1e-12 mm"
        )) && err.contains(&format!(
            "median of the run's files' ({}, {name}) length standard deviations (0.01 mm)",
            data.to_str().unwrap()
        )) && err.contains("at most 1e6 times below"),
        "{err}"
    );
    // Alone, the one row is its own median: the file's own check has nothing to compare.
    kinecal::files::parse_distances(&std::fs::read_to_string(&slip).unwrap(), "b.csv", &robot)
        .expect("one row alone");
}

/// What a caller that stops on implausible warnings sees.
struct Strict(Vec<Warning>);

impl workflow::Progress for Strict {
    fn data_checked(&mut self, warnings: &[Warning]) -> bool {
        self.0.extend(warnings.iter().cloned());
        !warnings.iter().any(|w| w.implausible())
    }
}

/// Millimetres read as metres, and degrees read as radians: each named from the nominal
/// prediction before any solving (the solver never runs: the caller stops the run there);
/// stated right, the same data passes.
#[test]
fn unit_mix_ups_are_named_before_the_solve() {
    let robot = robot_in(LengthUnit::M, AngleUnit::Rad);
    let data = poses(&robot, 20);
    // Lengths in mm, read as metres.
    let mm = write_measurements(&robot_in(LengthUnit::Mm, AngleUnit::Rad), &data);
    let read = read_observations(&mm, "mm.csv", &robot, &ReadOptions::default()).unwrap();
    let mut strict = Strict(Vec::new());
    let err = workflow::run(&Request::new(robot.clone(), read), &mut strict).unwrap_err();
    assert!(matches!(err, Error::Stopped { .. }), "{err}");
    assert!(
        strict
            .0
            .iter()
            .any(|w| matches!(w, Warning::ScaleMismatch { likely: Some(u), .. } if u == "mm")),
        "{:?}",
        strict.0
    );
    // Attitudes in degrees, read as radians.
    let deg = write_measurements(&robot_in(LengthUnit::M, AngleUnit::Deg), &data);
    let read = read_observations(&deg, "deg.csv", &robot, &ReadOptions::default()).unwrap();
    let mut strict = Strict(Vec::new());
    let err = workflow::run(&Request::new(robot.clone(), read), &mut strict).unwrap_err();
    assert!(matches!(err, Error::Stopped { .. }), "{err}");
    assert!(
        strict
            .0
            .iter()
            .any(|w| matches!(w, Warning::AttitudeMismatch { likely: Some(u), .. } if u == "deg")),
        "{:?}",
        strict.0
    );
    // Stated, both pass.
    let opts = ReadOptions {
        angle_unit: Some(AngleUnit::Deg),
        ..ReadOptions::default()
    };
    let read = read_observations(&deg, "deg.csv", &robot, &opts).unwrap();
    let mut strict = Strict(Vec::new());
    let out = workflow::run(&Request::new(robot.clone(), read), &mut strict).unwrap();
    assert!(strict.0.is_empty(), "{:?}", strict.0);
    assert!(out.calibration.converged());
}

/// Standard deviations 40 times too small (and 40 times too large) draw a warning with the
/// variance factor; stated near the noise, none.
#[test]
fn sigmas_off_by_more_than_ten_times_are_named() {
    let robot = robot_in(LengthUnit::M, AngleUnit::Rad);
    let data = poses(&robot, 30);
    let sigmas_off = |length: f64, angle: f64| {
        let mut req = Request::new(robot.clone(), data.clone());
        req.weights.length = length;
        req.weights.angle = angle;
        let out = workflow::run(&req, &mut ()).unwrap();
        out.warnings.iter().find_map(|w| match w {
            Warning::SigmasOff { variance_factor } => Some(*variance_factor),
            _ => None,
        })
    };
    let small = sigmas_off(3e-5 / 40.0, 1e-4 / 40.0).expect("too small");
    assert!((small / 1600.0 - 1.0).abs() < 0.5, "{small}");
    assert!(sigmas_off(3e-5 * 40.0, 1e-4 * 40.0).is_some());
    assert_eq!(sigmas_off(3e-5, 1e-4), None);
}
