//! Calibrates the real QKM HL6 robot (FARO laser tracker data) and reports held-out accuracy.
//!
//! ```sh
//! cargo run --release -p kinecal --example qkm_hl6 -- ../shared/data/qkm_hl6_faro qkm-out
//! ```
//!
//! Converts the data set (see its README) into kinecal's files in the output folder:
//! `qkm_poe.toml` (the nominal product-of-exponentials model), `qkm.toml` (the same as a kinecal
//! robot, with the three reflectors as sites), `identification.csv` (46 positions) and
//! `validation.csv` (9 held-out points); then calibrates on the identification set, as
//! `kinecal calibrate --robot qkm.toml --data identification.csv --validate validation.csv
//! --estimate identifiable` would, and prints the held-out accuracy.

use std::path::PathBuf;

use kinecal::datasets::qkm_hl6;
use kinecal::estimation::{accuracy, calibrate, CalibrationOptions};
use kinecal::identifiability::{analyze, AnalysisOptions};
use kinecal::measurement_file::write_measurements;
use kinecal::robot_file::write_robot_toml;
use kinecal::{parse_param_list, ParamId};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let dir = PathBuf::from(
        args.next()
            .unwrap_or_else(|| "../shared/data/qkm_hl6_faro".into()),
    );
    let out = PathBuf::from(args.next().unwrap_or_else(|| "qkm-out".into()));
    let data = qkm_hl6::load(&dir)?;
    std::fs::create_dir_all(&out)?;
    std::fs::write(out.join("qkm_poe.toml"), &data.poe_toml)?;
    std::fs::write(out.join("qkm.toml"), write_robot_toml(&data.robot, None))?;
    std::fs::write(
        out.join("identification.csv"),
        write_measurements(&data.robot, &data.identification),
    )?;
    std::fs::write(
        out.join("validation.csv"),
        write_measurements(&data.robot, &data.validation),
    )?;
    println!(
        "wrote qkm_poe.toml, qkm.toml, identification.csv, validation.csv to {}",
        out.display()
    );
    let robot = &data.robot;
    let mm = |v: f64| v * 1e3;
    let nominal = accuracy(robot, &data.validation);
    println!(
        "nominal model on the 9 held-out points: mean {:.3} mm, max {:.3} mm",
        mm(nominal.mean_position),
        mm(nominal.max_position)
    );
    let slopes = parse_param_list("slopes", robot)?;
    let all: Vec<ParamId> = robot.param_ids().collect();
    let without_slopes: Vec<ParamId> = all
        .iter()
        .copied()
        .filter(|id| !slopes.contains(id))
        .collect();
    for (label, candidates) in [
        ("links, offsets, reflectors", &without_slopes),
        ("... and joint slopes (thesis model)", &all),
    ] {
        let base = analyze(
            robot,
            &data.identification,
            candidates,
            &AnalysisOptions::default(),
        )?
        .identifiable;
        let cal = calibrate(
            robot,
            &data.identification,
            &CalibrationOptions::new(base.clone()),
            &mut |_| {},
        )?;
        let (i, v) = (
            accuracy(&cal.calibrated, &data.identification),
            accuracy(&cal.calibrated, &data.validation),
        );
        println!(
            "{label}: {} identifiable parameters; identification mean {:.3} / max {:.3} mm; held-out mean {:.3} / max {:.3} mm",
            base.len(),
            mm(i.mean_position),
            mm(i.max_position),
            mm(v.mean_position),
            mm(v.max_position)
        );
    }
    Ok(())
}
