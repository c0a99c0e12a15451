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
        "predicted {} posture{} of {} ({}): 95 % position bound median {}, 95th percentile {}, \
         largest {} {}",
        s.postures.len(),
        if s.postures.len() == 1 { "" } else { "s" },
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
    let lmax = c
        .thresholds
        .length
        .map_or(String::from("none"), |l| len(l).to_string());
    let amax = c.thresholds.angle.map(ang);
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
        if m.metric == "pixel" {
            println!(
                "{} check pixels: max error {:.6} px (threshold {}), RMS {:.6}",
                m.count,
                m.max,
                c.thresholds.pixel.unwrap_or(f64::NAN),
                m.rms
            );
            continue;
        }
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

/// Curves: what they show (periods, minima, convexity); on standard error when the table is
/// written on standard output (`to_stderr`).
pub fn curves(d: &Document, to_stderr: bool) {
    let Document::Curves(c) = d else { return };
    for line in &c.findings {
        if to_stderr {
            eprintln!("{line}");
        } else {
            println!("{line}");
        }
    }
}

/// `s` followed by spaces to `w` characters. Padded by hand, not with `{:<w$}`: a format
/// width is at most 65,535 and panics beyond it (a table's column as wide as a long serial).
pub fn pad_right(s: &str, w: usize) -> String {
    let n = s.chars().count();
    let mut out = String::with_capacity(s.len() + w.saturating_sub(n));
    out.push_str(s);
    out.extend(std::iter::repeat_n(' ', w.saturating_sub(n)));
    out
}

/// Spaces to `w` characters, then `s` (see [`pad_right`]).
pub fn pad_left(s: &str, w: usize) -> String {
    let n = s.chars().count();
    let mut out: String = std::iter::repeat_n(' ', w.saturating_sub(n)).collect();
    out.push_str(s);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn padding_counts_characters_and_takes_any_width() {
        assert_eq!(pad_right("ab", 4), "ab  ");
        assert_eq!(pad_left("é", 3), "  é");
        assert_eq!(pad_right("abc", 1), "abc");
        let long = "S".repeat(70_000);
        assert_eq!(pad_right("x", long.len()).len(), 70_000);
        assert_eq!(pad_left(&long, 70_001).len(), 70_001);
    }
}
