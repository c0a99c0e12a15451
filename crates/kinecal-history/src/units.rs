//! Unit labels as stored with each parameter (`in`, `mm`, `deg`, `rad/unit`, ...), and
//! conversions between unit systems.

use kinecal::units::{AngleUnit, LengthUnit, Quantity, Units};

/// The quantity of a unit label and the SI value of one unit, e.g. `mm` -> (length, 0.001).
pub(crate) fn parse_label(label: &str) -> Option<(Quantity, f64)> {
    match label {
        "kg" => return Some((Quantity::Mass, 1.0)),
        "px" => return Some((Quantity::Pixel, 1.0)),
        "" => return Some((Quantity::Ratio, 1.0)),
        _ => {}
    }
    // A compliance: `ANGLE/(N LENGTH)`.
    if let Some(inner) = label
        .split_once("/(N ")
        .and_then(|(a, rest)| Some((a, rest.strip_suffix(')')?)))
    {
        let (a, l) = (
            inner.0.parse::<AngleUnit>().ok()?,
            inner.1.parse::<LengthUnit>().ok()?,
        );
        return Some((Quantity::Compliance, a.radians() / l.metres()));
    }
    let (base, per_reading) = match label.strip_suffix("/unit") {
        Some(b) => (b, true),
        None => (label, false),
    };
    if let Ok(l) = base.parse::<LengthUnit>() {
        let q = if per_reading {
            Quantity::LengthPerReading
        } else {
            Quantity::Length
        };
        return Some((q, l.metres()));
    }
    if let Ok(a) = base.parse::<AngleUnit>() {
        let q = if per_reading {
            Quantity::AnglePerReading
        } else {
            Quantity::Angle
        };
        return Some((q, a.radians()));
    }
    None
}

/// The units of a record's `length_unit` and `angle_unit`.
pub(crate) fn parse_units(length: &str, angle: &str) -> Option<Units> {
    Some(Units {
        length: length.parse().ok()?,
        angle: angle.parse().ok()?,
    })
}

/// The factor taking a value in unit `label` into `to`'s unit of the same quantity, and that
/// unit's label; `None` for a label that is not a kinecal unit.
pub(crate) fn conversion(label: &str, to: &Units) -> Option<(f64, String)> {
    let (q, from) = parse_label(label)?;
    Some((from / to.factor(q), to.label(q)))
}

/// The quantity in words, with its article: "a length", "an angle per reading".
pub(crate) fn quantity_words(q: Quantity) -> &'static str {
    match q {
        Quantity::Length => "a length",
        Quantity::Angle => "an angle",
        Quantity::LengthPerReading => "a length per reading (prismatic slope)",
        Quantity::AnglePerReading => "an angle per reading (revolute slope)",
        Quantity::Compliance => "an angle per torque (joint compliance)",
        Quantity::Mass => "a mass",
        Quantity::Pixel => "a number of pixels (a camera's lens)",
        Quantity::Ratio => "a pure number (a lens's distortion)",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn labels_convert() {
        let mm = Units {
            length: LengthUnit::Mm,
            angle: AngleUnit::Rad,
        };
        let (f, l) = conversion("in", &mm).unwrap();
        assert!((f - 25.4).abs() < 1e-12 && l == "mm");
        let (f, l) = conversion("deg/unit", &mm).unwrap();
        assert!((f - std::f64::consts::PI / 180.0).abs() < 1e-15 && l == "rad/unit");
        assert!(conversion("furlong", &mm).is_none());
        // deg/(N in) into rad/(N mm): (pi/180) / 25.4.
        let (f, l) = conversion("deg/(N in)", &mm).unwrap();
        assert!((f - std::f64::consts::PI / 180.0 / 25.4).abs() < 1e-15 && l == "rad/(N mm)");
        assert!(conversion("deg/(N furlong)", &mm).is_none());
    }
}
