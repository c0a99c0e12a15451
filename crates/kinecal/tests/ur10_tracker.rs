//! Data nobody here had seen: a UR10 measured by a laser tracker at another lab
//! (`../shared/data/ipa_ur10_tracker`, MIT), in four series from three tracker placements, read
//! as that lab wrote it (`;`, decimal commas, mm, its own column names). Each series is a
//! measurement session; a calibration identified on one series is checked on another after that
//! series' tracker placement is re-estimated on it (6 parameters).
//!
//! The data set's README gives an independent fit (numpy/scipy least squares, standard DH
//! errors with Hayati parameters, base and probe frames, positions) and its held-out mean
//! position errors after re-estimating the placement: identified on A, 0.52 mm on C and 0.43 mm
//! on D; identified on C, 0.71 mm on D and 0.74 mm on A. The identifiable sets here, with and
//! without the joint transducer slopes, must converge in at most 30 iterations and come within
//! 2 % of those figures (or below); slopes identified on C, whose narrow ranges they cannot be
//! extrapolated from, make the held-out errors worse, and a warning must say so.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use kinecal::files::{read_observations, ColumnMap, ReadOptions};
use kinecal::units::LengthUnit;
use kinecal::workflow::{self, Request, Selection, Validation};
use kinecal::{parse_param_list, Dataset, Robot};

#[path = "common/shared_data.rs"]
mod shared_data;

/// The shared data folder, when it holds the tracker series.
fn shared() -> Option<PathBuf> {
    shared_data::shared_data("ipa_ur10_tracker")?;
    Some(shared_data::root())
}

fn robot(shared: &Path) -> Robot {
    let yaml = shared.join("urdf/universal_robots/config/ur10/default_kinematics.yaml");
    let text = std::fs::read_to_string(&yaml).unwrap();
    kinecal::import::ur::import_ur(&text, "default_kinematics.yaml")
        .unwrap()
        .robot
}

const COLUMNS: &str = "v1=shoulder_pan_joint,v2=shoulder_lift_joint,v3=elbow_joint,\
                       v4=wrist_1_joint,v5=wrist_2_joint,v6=wrist_3_joint,\
                       x=measurement_x,y=measurement_y,z=measurement_z";

/// A series, read as the lab wrote it, in its own session.
fn series(shared: &Path, robot: &Robot, file: &str, session: &str) -> Dataset {
    let path = shared.join("ipa_ur10_tracker").join(file);
    let text = std::fs::read_to_string(&path).unwrap();
    let opts = ReadOptions {
        columns: ColumnMap::parse(&[COLUMNS], "columns").unwrap(),
        length_unit: Some(LengthUnit::Mm),
        ..ReadOptions::default()
    };
    let mut data = read_observations(&text, file, robot, &opts).unwrap();
    data.set_session(session);
    data
}

#[test]
fn identified_on_one_series_validated_on_another() {
    let Some(shared) = shared() else { return };
    let robot = robot(&shared);
    let a = series(&shared, &robot, "Series_A/measurements_grid.csv", "A");
    let c = series(
        &shared,
        &robot,
        "Series_C/measurements_random_poses.csv",
        "C",
    );
    let d = series(&shared, &robot, "Series_D/measurements_iso_cubes.csv", "D");
    let cases = [
        ("A", &a, "C", &c, 0.52),
        ("A", &a, "D", &d, 0.43),
        ("C", &c, "D", &d, 0.71),
        ("C", &c, "A", &a, 0.74),
    ];
    let mut failures = Vec::new();
    for (ident_name, ident, held_name, held, reference_mm) in cases {
        for with_slopes in [false, true] {
            let mut req = Request::new(robot.clone(), ident.clone());
            req.selection = Selection::Identifiable {
                with: if with_slopes {
                    parse_param_list("slopes", &robot).unwrap()
                } else {
                    Vec::new()
                },
                fix: Vec::new(),
            };
            req.validation = Validation::Data(Arc::new(held.clone()));
            let out = workflow::run(&req, &mut ()).unwrap();
            let cal = &out.calibration;
            let v = out.validation.as_ref().unwrap();
            let mean_mm = v.after.mean_position * 1e3;
            eprintln!(
                "{ident_name} -> {held_name}{}: {:?} after {} iterations, held-out mean {mean_mm:.3} mm (independent fit {reference_mm}), start {:.3} mm",
                if with_slopes { " (slopes)" } else { "" },
                cal.termination,
                cal.iterations,
                v.start.as_ref().map_or(f64::NAN, |s| s.mean_position * 1e3),
            );
            // The README's figures are printed to two decimals ("about 0.43"): within 2 % of
            // them, or of their rounding.
            let within = mean_mm <= reference_mm * 1.02 + 0.005;
            // Slopes estimated on series C (one elbow configuration, narrow shoulder ranges)
            // extrapolate to the wide ranges of A and D worse than the geometry alone (the
            // independent fit estimates no slopes): that must be said, not hidden.
            let extrapolating_slopes = with_slopes && ident_name == "C";
            if !cal.converged() || cal.iterations > 30 || !(within || extrapolating_slopes) {
                failures.push(format!(
                    "{ident_name} -> {held_name} slopes {with_slopes}: {:?} after {}, {mean_mm:.3} mm",
                    cal.termination, cal.iterations
                ));
            }
            let start = v.start.as_ref().unwrap();
            if v.after.mean_position > start.mean_position {
                assert!(
                    out.warnings
                        .iter()
                        .any(|w| matches!(w, kinecal::Warning::WorseOnValidation { .. })),
                    "worse held out than the start, and no warning"
                );
            }
            let refitted = &out.report.validation.as_ref().unwrap().sessions_refitted;
            assert_eq!(refitted, &[held_name.to_string()]);
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Series C and D state the tracker's own standard deviations per axis (about 0.01 mm), far
/// below the robot's model error (about 0.4 mm). Read with them, the fit's residuals are about
/// 50 times the stated sigmas: the identifiable set judged at the stated sigmas keeps joint-6
/// terms only that precision determines (correlated -1.000; the solver crawled along their
/// valley to the iteration cap). It must be chosen again at the residuals' noise, converge,
/// and say both things: the set chosen again, and the model error added to the sigmas.
#[test]
fn the_trackers_own_sigmas_are_judged_by_the_residuals() {
    let Some(shared) = shared() else { return };
    let robot = robot(&shared);
    let read = |file: &str, session: &str| {
        let path = shared.join("ipa_ur10_tracker").join(file);
        let text = std::fs::read_to_string(&path).unwrap();
        let opts = ReadOptions {
            columns: ColumnMap::parse(
                &[&format!(
                    "{COLUMNS},sigma_x=measurement_std_x,sigma_y=measurement_std_y,\
                     sigma_z=measurement_std_z"
                )],
                "columns",
            )
            .unwrap(),
            length_unit: Some(LengthUnit::Mm),
            ..ReadOptions::default()
        };
        let mut data = read_observations(&text, file, &robot, &opts).unwrap();
        data.set_session(session);
        data
    };
    let c = read("Series_C/measurements_random_poses.csv", "C");
    let d = read("Series_D/measurements_iso_cubes.csv", "D");
    let kinecal::Observation::Position(p) = &c.observations[0] else {
        panic!("positions")
    };
    let s = p.sigma_position.unwrap();
    assert!(
        s.max() < 5e-5 && s.min() > 0.0,
        "per-axis sigmas in m: {s:?}"
    );
    let mut req = Request::new(robot.clone(), c);
    req.selection = Selection::Identifiable {
        with: Vec::new(),
        fix: Vec::new(),
    };
    req.validation = Validation::Data(Arc::new(d));
    let out = workflow::run(&req, &mut ()).unwrap();
    let cal = &out.calibration;
    assert!(
        cal.converged() && cal.iterations <= 30,
        "{:?} after {}",
        cal.termination,
        cal.iterations
    );
    let left_out = out
        .warnings
        .iter()
        .find_map(|w| match w {
            kinecal::Warning::ChosenAtResidualNoise { scale, left_out } => Some((*scale, left_out)),
            _ => None,
        })
        .expect("the set chosen again at the residuals' noise");
    assert!((20.0..200.0).contains(&left_out.0), "{left_out:?}");
    for name in ["link6.alpha", "link6.gamma"] {
        assert!(left_out.1.iter().any(|n| n == name), "{left_out:?}");
        assert!(!cal
            .options
            .estimate
            .iter()
            .any(|&id| robot.param_name(id) == name));
    }
    // The rows' sigmas are 50 times below their residuals: each row is weighted by its sigma and
    // the model error the residuals show (a note gives it), so the weights describe the data
    // (no `SigmasOff`) and the held-out error is the uniform fit's 0.71 mm (0.79 weighted by the
    // sigmas alone).
    let floor = out
        .warnings
        .iter()
        .find_map(|w| match w {
            kinecal::Warning::ModelErrorFloor {
                scale, length_mm, ..
            } => Some((*scale, *length_mm)),
            _ => None,
        })
        .expect("the model-error floor named");
    assert!(
        (20.0..200.0).contains(&floor.0) && (0.1..0.5).contains(&floor.1),
        "{floor:?}"
    );
    assert!(!out
        .warnings
        .iter()
        .any(|w| matches!(w, kinecal::Warning::SigmasOff { .. })));
    let v = out.validation.as_ref().unwrap();
    let (after, start) = (
        v.after.mean_position,
        v.start.as_ref().unwrap().mean_position,
    );
    eprintln!("C -> D with the tracker's sigmas: start {start:.6} m, after {after:.6} m");
    assert!(after < start && after < 0.715e-3, "{start} -> {after}");
}
