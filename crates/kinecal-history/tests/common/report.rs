//! The calibration report most history tests store: the GE A4 fitted on simulated data.

#![allow(dead_code)]

use kinecal::report::CalibrationReport;
use kinecal::solve::estimation::{calibrate, CalibrationOptions};
use kinecal::{apps::simulate, model::examples, ParamId, Robot};

/// Link 1's x and y and link 3's y of the GE A4: what most history tests estimate.
pub const LINK1_XY_LINK3_Y: [ParamId; 3] = [ParamId(0), ParamId(1), ParamId(13)];

/// A report of the nominal GE A4 calibrated on `postures` postures measured (positions and
/// attitudes) on `truth` (postures drawn with `seed`, noise of 1e-5 m and 1e-5 rad drawn with
/// `seed + 1`), `estimate` estimated, with its uncertainty. With `data_key`, the files'
/// fingerprints are set as `kinecal calibrate` sets them (the robot file's `ge-a4`, the data's
/// `data_key`): a history keys records by them.
pub fn ge_a4_report(
    truth: &Robot,
    postures: usize,
    seed: u64,
    estimate: &[ParamId],
    data_key: Option<&str>,
) -> CalibrationReport {
    let nominal = examples::ge_a4();
    let mut data = simulate::measure(
        truth,
        &simulate::sample_postures(truth, postures, seed),
        false,
    );
    simulate::add_noise(&mut data, 1e-5, 1e-5, seed + 1);
    let cal = calibrate(
        &nominal,
        &data,
        &CalibrationOptions::new(estimate.to_vec()),
        &mut |_| {},
    )
    .unwrap();
    let u = kinecal::uncertainty::uncertainty(&cal, &data, &nominal).unwrap();
    let mut rep = CalibrationReport::new(&cal, &data);
    rep.set_uncertainty(&cal, &u);
    if let Some(key) = data_key {
        rep.robot_file_sha256 = Some(kinecal_history::fingerprint(b"ge-a4"));
        rep.data_file_sha256 = Some(kinecal_history::fingerprint(key.as_bytes()));
    }
    rep
}
