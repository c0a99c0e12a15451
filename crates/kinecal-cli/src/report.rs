//! Human-readable summaries.

use std::fmt::Write as _;

use kinecal::report::CalibrationReport;

/// The text summary `kinecal calibrate` prints.
pub fn summary(r: &CalibrationReport) -> String {
    let mut s = String::new();
    let (l, a) = (&r.length_unit, &r.angle_unit);
    let _ = writeln!(
        s,
        "{}: {} postures, {} measurements, {} residuals; method {}, {} orientation residuals",
        if r.robot.is_empty() {
            "robot"
        } else {
            &r.robot
        },
        r.postures,
        r.measurements,
        r.residuals,
        r.method,
        r.orientation_error
    );
    let _ = writeln!(
        s,
        "{} after {} iterations: {}",
        if r.converged {
            "converged"
        } else {
            "NOT converged"
        },
        r.iterations,
        r.termination
    );
    let _ = writeln!(s);
    let _ = writeln!(s, "{:<28} {:>14} {:>14}", "", "before", "after");
    let _ = writeln!(
        s,
        "{:<28} {:>14.6e} {:>14.6e}",
        "objective (weighted)", r.objective_before, r.objective_after
    );
    let _ = writeln!(
        s,
        "{:<28} {:>14.6} {:>14.6}",
        format!("RMS position error ({l})"),
        r.rms_position_before,
        r.rms_position_after
    );
    let _ = writeln!(
        s,
        "{:<28} {:>14.6} {:>14.6}",
        format!("max position error ({l})"),
        r.max_position_before,
        r.max_position_after
    );
    if r.rms_orientation_before > 0.0 || r.rms_orientation_after > 0.0 {
        let _ = writeln!(
            s,
            "{:<28} {:>14.6} {:>14.6}",
            format!("RMS attitude error ({a})"),
            r.rms_orientation_before,
            r.rms_orientation_after
        );
        let _ = writeln!(
            s,
            "{:<28} {:>14.6} {:>14.6}",
            format!("max attitude error ({a})"),
            r.max_orientation_before,
            r.max_orientation_after
        );
    }
    let _ = writeln!(s);
    let _ = writeln!(
        s,
        "{:<5} {:<20} {:<9} {:>14} {:>14} {:>14}",
        "id", "name", "unit", "initial", "estimated", "change"
    );
    for p in r.parameters.iter().filter(|p| p.estimated_flag) {
        let _ = writeln!(
            s,
            "{:<5} {:<20} {:<9} {:>14.6} {:>14.6} {:>+14.6}",
            p.id, p.name, p.unit, p.initial, p.estimated, p.change
        );
    }
    s
}
