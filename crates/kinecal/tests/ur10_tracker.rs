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

use kinecal::observe::point::ColumnMap;
use kinecal::observe::{read_observations, ReadOptions};
use kinecal::units::LengthUnit;
use kinecal::workflow::{self, Request, Selection, Validation};
use kinecal::{parse_param_list, Dataset, Robot};

fn shared() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data");
    if !dir.join("ipa_ur10_tracker").exists() {
        assert!(
            std::env::var_os("CI").is_none(),
            "{} is missing on CI",
            dir.display()
        );
        eprintln!("skipped: {} not found", dir.display());
        return None;
    }
    Some(dir)
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
