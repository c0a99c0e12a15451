//! The IPA UR10's series D (`../shared/data/ipa_ur10_tracker`, through `kinecal dataset
//! ipa-ur10`): ISO 9283 cube poses at one tool attitude, identified and held out on series A.
//! The data must be here: this test fails, naming the folder, when it is not.

use std::sync::Arc;

use kinecal::apps::datasets::{ipa_ur10, Converted};
use kinecal::files::parse_measurements;
use kinecal::model::robot_file::parse_robot_toml;
use kinecal::workflow::{self, Request, Selection, Validation};
use kinecal::{Dataset, Observation, Warning};

#[path = "common/shared_data.rs"]
mod shared_data;

fn file<'a>(c: &'a Converted, name: &str) -> &'a str {
    &c.files
        .iter()
        .find(|f| f.0 == name)
        .unwrap_or_else(|| panic!("no {name} written"))
        .1
}

/// Series D measures the T-Mac at one attitude: its offset along the flange axis (link6.y plus
/// link7.z, 185.3 mm on series A, B and C) is nearly a shift of the tracker frame, determined
/// by D to about 33 mm. The start's closed-form placement put link7.z at 131.5 mm (the sum
/// 223.7); without sigma columns the identifiable set left both lengths out at the default
/// weights (1 mm; link6.y determined only to 100.6 mm, above 2 % of the reach) and the fit kept
/// the placement's value: held out on A, 4.869 mm mean (4.924 at the start). With the
/// tracker's sigma columns link6.y was estimated (the set chosen at the residuals' noise) and
/// A held out at 1.080 mm. Now link7.z, set by the placement, is estimated either way: 1.080
/// and 1.081 mm, with a warning naming it.
#[test]
fn series_d_holds_out_on_a_with_and_without_sigma_columns() {
    let dir = shared_data::root().join("ipa_ur10_tracker");
    assert!(
        dir.exists(),
        "{} is missing: this test needs the IPA UR10 data set of ../shared/data (or \
         KINECAL_SHARED_DATA)",
        dir.display()
    );
    let c = ipa_ur10::convert(&dir).unwrap();
    let robot = parse_robot_toml(file(&c, "ur10.toml"), "ur10.toml").unwrap();
    let read = |n: &str| parse_measurements(file(&c, n), n, &robot).unwrap();
    let (with, held) = (read("series_D.csv"), Arc::new(read("series_A.csv")));
    let mut bare = with.clone();
    for o in &mut bare.observations {
        if let Observation::Position(p) = o {
            assert!(p.sigma_position.is_some());
            p.sigma_position = None;
        }
    }
    let fit = |data: &Dataset| {
        let mut req = Request::new(robot.clone(), data.clone());
        req.selection = Selection::parse("identifiable", None, &robot).unwrap();
        req.validation = Validation::Data(held.clone());
        workflow::run(&req, &mut ()).unwrap()
    };
    for (name, data) in [("with sigma columns", &with), ("without", &bare)] {
        let out = fit(data);
        let v = out.validation.as_ref().unwrap();
        let (start, after) = (
            v.start.as_ref().unwrap().mean_position,
            v.after.mean_position,
        );
        eprintln!(
            "D -> A {name}: {:?} after {} iterations; held-out mean {:.4} mm (start {:.4})",
            out.calibration.termination,
            out.calibration.iterations,
            after * 1e3,
            start * 1e3
        );
        assert!(out.calibration.converged(), "{name}");
        // 1.1 mm: the figure with sigma columns before (1.080), which the data's looseness
        // along the flange axis (about 33 mm) leaves far above A -> D's 0.44.
        assert!(after <= 1.1e-3, "{name}: {after}");
        assert!(after < 0.25 * start, "{name}: {start} -> {after}");
        if name == "without" {
            let named = |w: &Warning| match w {
                Warning::PlacedLoose { parameters } => {
                    parameters.iter().any(|p| p.starts_with("link7.z"))
                }
                _ => false,
            };
            assert!(out.warnings.iter().any(named), "{:?}", out.warnings);
        }
    }
}
