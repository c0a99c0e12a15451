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
    /// Angle per torque (a joint's compliance; rad/(N m) internally, the file's angle unit per
    /// newton times its length unit in files: `deg/(N mm)` for a millimetre-degree robot).
    Compliance,
    /// A mass (kg, in files too).
    Mass,
    /// A length in an image: pixels, in files too (a camera's focal lengths and principal
    /// point).
    Pixel,
    /// A pure number, the same in every unit (a lens's distortion coefficients).
    Ratio,
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
            Quantity::Compliance => self.angle.radians() / self.length.metres(),
            Quantity::Mass | Quantity::Pixel | Quantity::Ratio => 1.0,
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
            Quantity::Compliance => format!("{}/(N {})", self.angle, self.length),
            Quantity::Mass => "kg".into(),
            Quantity::Pixel => "px".into(),
            Quantity::Ratio => String::new(),
        }
    }
}

/// A unit of length a number is shown in to a person: the robot files' units and the
/// micrometre.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DisplayLength {
    /// Metre.
    M,
    /// Millimetre.
    Mm,
    /// Micrometre (`um`).
    Um,
    /// Inch (25.4 mm).
    In,
}

impl DisplayLength {
    /// Metres in one of this unit.
    pub fn metres(self) -> f64 {
        match self {
            DisplayLength::M => 1.0,
            DisplayLength::Mm => 1e-3,
            DisplayLength::Um => 1e-6,
            DisplayLength::In => 0.0254,
        }
    }

    /// Its label: `m`, `mm`, `um`, `in`.
    pub fn as_str(self) -> &'static str {
        match self {
            DisplayLength::M => "m",
            DisplayLength::Mm => "mm",
            DisplayLength::Um => "um",
            DisplayLength::In => "in",
        }
    }
}

impl From<LengthUnit> for DisplayLength {
    fn from(u: LengthUnit) -> Self {
        match u {
            LengthUnit::M => DisplayLength::M,
            LengthUnit::Mm => DisplayLength::Mm,
            LengthUnit::In => DisplayLength::In,
        }
    }
}

/// The units numbers are shown in to a person: the pages and summaries kinecal draws and
/// prints. Files for programs (reports, robot files) keep the robot file's units.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DisplayUnits {
    /// Unit of lengths shown.
    pub length: DisplayLength,
    /// Unit of angles shown.
    pub angle: AngleUnit,
}

impl DisplayUnits {
    /// The default for a robot whose files are in `length` and `angle`: millimetres for a
    /// metre robot, degrees for a radian one; a robot in millimetres, inches or degrees as it is
    /// (never micrometres by default).
    pub fn for_robot(length: LengthUnit, _angle: AngleUnit) -> DisplayUnits {
        DisplayUnits {
            length: match length {
                LengthUnit::M | LengthUnit::Mm => DisplayLength::Mm,
                LengthUnit::In => DisplayLength::In,
            },
            angle: AngleUnit::Deg,
        }
    }

    /// The robot file's own units.
    pub fn robot(length: LengthUnit, angle: AngleUnit) -> DisplayUnits {
        DisplayUnits {
            length: length.into(),
            angle,
        }
    }

    /// What a length in `from` is multiplied by to be shown.
    pub fn length_factor(self, from: LengthUnit) -> f64 {
        from.metres() / self.length.metres()
    }

    /// What an angle in `from` is multiplied by to be shown.
    pub fn angle_factor(self, from: AngleUnit) -> f64 {
        from.radians() / self.angle.radians()
    }
}

impl fmt::Display for DisplayUnits {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}-{}", self.length.as_str(), self.angle)
    }
}

impl FromStr for DisplayUnits {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let wrong = || {
            format!(
                "unknown display units `{s}` (expected a length unit m, mm, um or in, a dash and \
                 an angle unit deg or rad: `mm-deg`)"
            )
        };
        let (l, a) = s.split_once('-').ok_or_else(wrong)?;
        let length = match l {
            "m" => DisplayLength::M,
            "mm" => DisplayLength::Mm,
            "um" => DisplayLength::Um,
            "in" => DisplayLength::In,
            _ => return Err(wrong()),
        };
        let angle = a.parse().map_err(|_| wrong())?;
        Ok(DisplayUnits { length, angle })
    }
}

/// Which units a page or a summary shows numbers in (a spec's `display_units`): `default`
/// ([`DisplayUnits::for_robot`]: millimetres and degrees for a metre-radian robot), `robot`
/// (the robot file's units), or given units such as `mm-deg`, `um-deg`, `m-rad`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(try_from = "String", into = "String")]
#[non_exhaustive]
pub enum DisplayChoice {
    /// [`DisplayUnits::for_robot`].
    #[default]
    Default,
    /// The robot file's units.
    Robot,
    /// These units.
    Units(DisplayUnits),
}

impl DisplayChoice {
    /// The units shown for a robot in `length` and `angle`.
    pub fn resolve(self, length: LengthUnit, angle: AngleUnit) -> DisplayUnits {
        match self {
            DisplayChoice::Default => DisplayUnits::for_robot(length, angle),
            DisplayChoice::Robot => DisplayUnits::robot(length, angle),
            DisplayChoice::Units(u) => u,
        }
    }

    /// Whether it is the default (left out of a spec written down).
    pub(crate) fn is_default(&self) -> bool {
        *self == DisplayChoice::Default
    }
}

impl fmt::Display for DisplayChoice {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DisplayChoice::Default => f.write_str("default"),
            DisplayChoice::Robot => f.write_str("robot"),
            DisplayChoice::Units(u) => u.fmt(f),
        }
    }
}

impl FromStr for DisplayChoice {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "default" => Ok(DisplayChoice::Default),
            "robot" => Ok(DisplayChoice::Robot),
            _ => s.parse().map(DisplayChoice::Units).map_err(|_| {
                format!(
                    "unknown display units `{s}` (expected `default`, `robot`, or a length unit \
                     m, mm, um or in, a dash and an angle unit deg or rad: `mm-deg`)"
                )
            }),
        }
    }
}

impl TryFrom<String> for DisplayChoice {
    type Error = String;
    fn try_from(s: String) -> Result<Self, String> {
        s.parse()
    }
}

impl From<DisplayChoice> for String {
    fn from(c: DisplayChoice) -> String {
        c.to_string()
    }
}

/// The largest magnitude any number in an input file may have, in the file's own units (1e9:
/// a million kilometres in metres, a thousand kilometres in millimetres). Larger values are
/// refused as unit mix-ups or corrupt data: their squares would overflow the objective.
pub const MAX_MAGNITUDE: f64 = 1e9;

/// The smallest standard deviation (`sigma_position`, `sigma_angle`) kinecal accepts, in a
/// file's units: 1e-140. A residual is weighed by 1 / sigma and squared: below about 1e-154 one
/// weight squared overflows, and residuals up to the 2e9 that plausible numbers allow, over
/// millions of rows, need the margin down to 1e-140 to keep the objective finite.
pub const MIN_SIGMA: f64 = 1e-140;

/// Why `v` cannot be a standard deviation (not finite, not positive, or below [`MIN_SIGMA`]).
pub fn sigma_problem(v: f64) -> Option<String> {
    if v.is_nan() || v <= 0.0 || !v.is_finite() {
        Some(format!("a standard deviation must be positive, found {v}"))
    } else if v < MIN_SIGMA {
        Some(format!(
            "a standard deviation below {MIN_SIGMA:e} would overflow its residual's weight \
             (1/sigma squared), found {v:e}"
        ))
    } else {
        None
    }
}

/// Whether `v` is finite and within [`MAX_MAGNITUDE`].
pub fn plausible(v: f64) -> bool {
    v.is_finite() && v.abs() <= MAX_MAGNITUDE
}

/// How kinecal writes numbers into its files (robot files; measurement, postures, distance and
/// contact files; the URDF export, with a scale of 1 m and 1 rad), in one place. (The DH table
/// writes 15 significant digits and the UR calibration file floats PyYAML reads; every export is
/// read back and checked against a tolerance before it is written.)
///
/// - **Noise.** A value below [`NOISE`](number::NOISE) (1e-12) times *the file's scale* of its kind is float
///   noise (a computed `z` of -2.458e-11 mm on a robot whose lengths reach 1807 mm) and is
///   written as 0. The scale of a kind is the largest magnitude of the numbers of that kind the
///   file holds, kinds being separate: lengths, angles and slopes of a robot file; positions,
///   angles, joint readings of each quantity of a measurement or postures file; a joint range
///   by its own larger bound (so that a range never collapses). So a value is
///   only noise next to larger values of its own kind: an attitude of 1e-13 rad in a robot file
///   whose angles are all that small, or a 1e-300 joint limit that is its range's only bound,
///   is kept. Standard deviations are stated, never noise (and 0 is none): written exactly, a
///   sigma of 1e-15 included.
/// - **Text.** Every other value is written in the shortest form that reads back to the same
///   `f64` ([`format_number`](number::format_number)): plain digits from 1e-5 to 1e16, else with an exponent
///   (`1e-300`, `5e-324` for subnormals), so a file written and read back gives the same
///   numbers, and writing it again the same text.
pub mod number {
    /// The relative size below which a value is noise next to its file's scale.
    pub const NOISE: f64 = 1e-12;

    /// The largest magnitude among numbers of one kind: the scale [`denoise`] compares with.
    #[derive(Debug, Clone, Copy, Default, PartialEq)]
    pub struct Scale(pub f64);

    impl Scale {
        /// The scale of `values` (non-finite ones ignored; 0 when there are none).
        pub fn of(values: impl IntoIterator<Item = f64>) -> Scale {
            let mut s = Scale(0.0);
            for v in values {
                s.include(v);
            }
            s
        }

        /// Widens the scale to `v`.
        pub fn include(&mut self, v: f64) {
            if v.is_finite() {
                self.0 = self.0.max(v.abs());
            }
        }
    }

    /// `v` with float noise (below [`NOISE`] times `scale`) as 0, and -0 as 0; any other value
    /// unchanged (subnormals included).
    pub fn denoise(v: f64, scale: Scale) -> f64 {
        if v == 0.0 || v.abs() < NOISE * scale.0 {
            0.0
        } else {
            v
        }
    }

    /// The shortest text that reads back (with Rust's or any correctly rounding parser) to
    /// exactly `v`: Rust's `{}` from 1e-5 to 1e16 in magnitude (`0.25`, `1807`, `-3`), `{:e}`
    /// outside (`1e-300`, `4.9e-324`, `1.5e20`), `0` for either zero.
    pub fn format_number(v: f64) -> String {
        let a = v.abs();
        if v == 0.0 {
            "0".into()
        } else if !v.is_finite() || (1e-5..1e16).contains(&a) {
            format!("{v}")
        } else {
            format!("{v:e}")
        }
    }

    /// [`format_number`] of [`denoise`].
    pub fn write(v: f64, scale: Scale) -> String {
        format_number(denoise(v, scale))
    }
}

/// A model parameter as kinecal writes it into robot files (in the file's units), given the
/// file's scale of its kind (see [`number`]): 0 for float noise, the value to 15 significant
/// digits when that is within 4 units in the last place of it (an estimate of 15.28 that came
/// out as 15.279999999999998 after unit conversions), else the value itself. A robot written and
/// read back is the same to 1e-15, and writing it again gives the same file.
pub(crate) fn tidy(v: f64, scale: number::Scale) -> f64 {
    let v = number::denoise(v, scale);
    if v == 0.0 || !v.is_finite() {
        return v;
    }
    let short: f64 = format!("{v:.14e}").parse().unwrap_or(v);
    if (short - v).abs() <= 4.0 * f64::EPSILON * v.abs() {
        short
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
    fn display_units_default_to_millimetres_and_degrees_for_a_metre_radian_robot() {
        use LengthUnit::{In, Mm, M};
        let d = |l, a| DisplayUnits::for_robot(l, a).to_string();
        assert_eq!(d(M, AngleUnit::Rad), "mm-deg");
        assert_eq!(d(Mm, AngleUnit::Deg), "mm-deg");
        assert_eq!(d(In, AngleUnit::Deg), "in-deg");
        assert_eq!(d(M, AngleUnit::Deg), "mm-deg");
        let u = DisplayUnits::for_robot(M, AngleUnit::Rad);
        assert!((u.length_factor(M) - 1000.0).abs() < 1e-12);
        assert!((u.angle_factor(AngleUnit::Rad) - 180.0 / std::f64::consts::PI).abs() < 1e-12);
        let robot = DisplayChoice::Robot.resolve(M, AngleUnit::Rad);
        assert_eq!(robot.to_string(), "m-rad");
        let um: DisplayChoice = "um-deg".parse().unwrap();
        assert!((um.resolve(M, AngleUnit::Rad).length_factor(Mm) - 1000.0).abs() < 1e-9);
        for bad in ["mm", "km-deg", "mm-grad", ""] {
            assert!(bad.parse::<DisplayChoice>().is_err(), "{bad}");
        }
        for good in ["default", "robot", "mm-deg", "m-rad", "um-deg", "in-rad"] {
            assert_eq!(good.parse::<DisplayChoice>().unwrap().to_string(), good);
        }
    }

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
