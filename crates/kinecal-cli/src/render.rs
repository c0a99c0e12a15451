//! The documents of the smaller jobs as the command line shows them.

use kinecal::spec::Document;
use kinecal::units::Quantity;

use crate::report::num;

/// A prediction's summary line (standard error: the predictions go to standard output or a
/// file).
pub fn prediction(d: &Document) {
    let Document::Prediction(p) = d else { return };
    let s = &p.summary;
    let b = &s.position_bound95;
    eprintln!(
        "predicted {} postures of {} ({}): 95 % position bound median {}, 95th percentile {}, \
         largest {} {}",
        s.postures.len(),
        s.robot,
        s.target,
        num(b.median),
        num(b.p95),
        num(b.max),
        s.length_unit
    );
}

/// A check: its JSON document with `--json`, else the errors and the verdict.
pub fn check(d: &Document, json: bool) {
    let Document::Check(c) = d else { return };
    if json {
        println!("{}", c.report.to_json());
        return;
    }
    let u = c.robot.units;
    let len = |v: f64| u.from_si(Quantity::Length, v);
    let ang = |v: f64| u.from_si(Quantity::Angle, v);
    let acc = &c.verdict.accuracy;
    let (lmax, amax) = (len(c.thresholds.length), c.thresholds.angle.map(ang));
    if acc.positions > 0 {
        println!(
            "{} check measurements: max position error {:.6} {} (threshold {lmax}), RMS {:.6}",
            acc.positions,
            len(acc.max_position),
            u.length,
            len(acc.rms_position)
        );
    }
    for m in &acc.other {
        println!(
            "{} check {}s: max error {:.6} {} (threshold {lmax}), RMS {:.6}",
            m.count,
            m.metric,
            len(m.max),
            u.length,
            len(m.rms)
        );
    }
    if acc.orientations > 0 {
        println!(
            "max attitude error {:.6} {}{}",
            ang(acc.max_orientation),
            u.angle,
            amax.map_or(String::new(), |t| format!(" (threshold {t})"))
        );
    }
    println!(
        "{}",
        if c.verdict.ok {
            "OK: the robot meets its accuracy"
        } else {
            "RECALIBRATE: the robot no longer meets its accuracy"
        }
    );
}

/// An export: the tool correction to enter on the controller (UR), on standard output.
pub fn export(d: &Document) {
    let Document::Export(e) = d else { return };
    if let Some(tcp) = &e.tcp {
        println!("{tcp}");
    }
}

/// Curves: what they show (periods, minima, convexity).
pub fn curves(d: &Document) {
    let Document::Curves(c) = d else { return };
    for line in &c.findings {
        println!("{line}");
    }
}
