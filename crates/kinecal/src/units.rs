//! Units of the user's files, and the internal ones.
//!
//! Internally every length is in metres, every angle in radians, and a transducer slope in
//! metres or radians per transducer unit. A robot file declares its own `length_unit` and
//! `angle_unit`; all its numbers, and those of its measurement files, are in those units and are
//! converted once on reading and once on writing.

use std::fmt;
use std::str::FromStr;

/// A unit of length accepted in robot files.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize, schemars::JsonSchema,
)]
#[serde(rename_all = "lowercase")]
pub enum LengthUnit {
    /// Metre.
    M,
    /// Millimetre.
    Mm,
    /// Inch (25.4 mm).
    In,
}

impl LengthUnit {
    /// Metres in one of this unit.
    pub fn metres(self) -> f64 {
        match self {
            LengthUnit::M => 1.0,
            LengthUnit::Mm => 1e-3,
            LengthUnit::In => 0.0254,
        }
    }

    /// The spelling used in files.
    pub fn as_str(self) -> &'static str {
        match self {
            LengthUnit::M => "m",
            LengthUnit::Mm => "mm",
            LengthUnit::In => "in",
        }
    }
}

impl FromStr for LengthUnit {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "m" => Ok(LengthUnit::M),
            "mm" => Ok(LengthUnit::Mm),
            "in" => Ok(LengthUnit::In),
            _ => Err(format!(
                "unknown length unit `{s}` (expected \"m\", \"mm\" or \"in\")"
            )),
        }
    }
}

impl fmt::Display for LengthUnit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// A unit of angle accepted in robot files.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize, schemars::JsonSchema,
)]
#[serde(rename_all = "lowercase")]
pub enum AngleUnit {
    /// Degree.
    Deg,
    /// Radian.
    Rad,
}

impl AngleUnit {
    /// Radians in one of this unit.
    pub fn radians(self) -> f64 {
        match self {
            AngleUnit::Deg => std::f64::consts::PI / 180.0,
            AngleUnit::Rad => 1.0,
        }
    }

    /// The spelling used in files.
    pub fn as_str(self) -> &'static str {
        match self {
            AngleUnit::Deg => "deg",
            AngleUnit::Rad => "rad",
        }
    }
}

impl FromStr for AngleUnit {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "deg" => Ok(AngleUnit::Deg),
            "rad" => Ok(AngleUnit::Rad),
            _ => Err(format!(
                "unknown angle unit `{s}` (expected \"deg\" or \"rad\")"
            )),
        }
    }
}

impl fmt::Display for AngleUnit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// The physical kind of a number, which decides its unit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Quantity {
    /// A length (m internally).
    Length,
    /// An angle (rad internally).
    Angle,
    /// Length per transducer unit (prismatic slope; m per unit internally).
    LengthPerReading,
    /// Angle per transducer unit (revolute slope; rad per unit internally).
    AnglePerReading,
}

/// A pair of units: the ones a robot file (and its measurement files) is written in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Units {
    /// Unit of lengths.
    pub length: LengthUnit,
    /// Unit of angles.
    pub angle: AngleUnit,
}

impl Default for Units {
    fn default() -> Self {
        Units {
            length: LengthUnit::M,
            angle: AngleUnit::Rad,
        }
    }
}

impl Units {
    /// Internal (SI) value of one user unit of `q`.
    pub fn factor(&self, q: Quantity) -> f64 {
        match q {
            Quantity::Length | Quantity::LengthPerReading => self.length.metres(),
            Quantity::Angle | Quantity::AnglePerReading => self.angle.radians(),
        }
    }

    /// Converts a value in the file's unit to the internal unit.
    pub fn to_si(&self, q: Quantity, value: f64) -> f64 {
        value * self.factor(q)
    }

    /// Converts an internal value to the file's unit.
    pub fn from_si(&self, q: Quantity, value: f64) -> f64 {
        value / self.factor(q)
    }

    /// The unit's name for `q`, e.g. `in`, `deg`, `deg/unit`.
    pub fn label(&self, q: Quantity) -> String {
        match q {
            Quantity::Length => self.length.to_string(),
            Quantity::Angle => self.angle.to_string(),
            Quantity::LengthPerReading => format!("{}/unit", self.length),
            Quantity::AnglePerReading => format!("{}/unit", self.angle),
        }
    }
}

/// The largest magnitude any number in an input file may have, in the file's own units (1e9:
/// a million kilometres in metres, a thousand kilometres in millimetres). Larger values are
/// refused as unit mix-ups or corrupt data: their squares would overflow the objective.
pub const MAX_MAGNITUDE: f64 = 1e9;

/// Whether `v` is finite and within [`MAX_MAGNITUDE`].
pub fn plausible(v: f64) -> bool {
    v.is_finite() && v.abs() <= MAX_MAGNITUDE
}

/// A number as kinecal writes it into files (in the file's units): 0 for float noise below
/// 1e-12 (a computed `beta` of 1e-34), the value to 15 significant digits when that is within 4
/// units in the last place of it (an estimate of 15.28 that came out as 15.279999999999998
/// after unit conversions), else the value itself, written in the shortest form that reads back
/// exactly. A robot written and read back is the same to 1e-15.
pub fn tidy(v: f64) -> f64 {
    if v.abs() < 1e-12 || !v.is_finite() {
        return if v.is_finite() { 0.0 } else { v };
    }
    let short: f64 = format!("{v:.14e}").parse().unwrap_or(v);
    if (short - v).abs() <= 4.0 * f64::EPSILON * v.abs() {
        short
    } else {
        v
    }
}

/// A measured or computed value as kinecal writes it into data files: float noise below 1e-12
/// (in the file's unit) as 0, any other value exactly (shortest form that reads back the same).
pub fn snap(v: f64) -> f64 {
    if v.abs() < 1e-12 {
        0.0
    } else {
        v
    }
}

/// Wraps an angle in radians into (-pi, pi].
pub fn wrap_angle(a: f64) -> f64 {
    use std::f64::consts::PI;
    let mut w = a.rem_euclid(2.0 * PI);
    if w > PI {
        w -= 2.0 * PI;
    }
    w
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrap_is_half_open() {
        use std::f64::consts::PI;
        assert!((wrap_angle(PI) - PI).abs() < 1e-15);
        assert!((wrap_angle(-PI) - PI).abs() < 1e-15);
        assert!((wrap_angle(3.0 * PI / 2.0) + PI / 2.0).abs() < 1e-15);
        assert!((wrap_angle(0.1) - 0.1).abs() < 1e-15);
    }

    #[test]
    fn conversions_round_trip() {
        let u = Units {
            length: LengthUnit::In,
            angle: AngleUnit::Deg,
        };
        assert!((u.to_si(Quantity::Length, 1.0) - 0.0254).abs() < 1e-15);
        assert!((u.from_si(Quantity::Angle, std::f64::consts::PI) - 180.0).abs() < 1e-12);
    }
}
