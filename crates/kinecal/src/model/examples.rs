//! Robots built into kinecal.

use crate::model::robot::Robot;

/// The GE A4 robot file (thesis Table 4.1), as shipped in `examples/robots/ge_a4.toml`.
pub const GE_A4_TOML: &str = include_str!("../../../../examples/robots/ge_a4.toml");

/// Names accepted by [`builtin`].
pub const BUILTIN_NAMES: &[&str] = &["ge-a4"];

/// The text of a built-in robot file by name (`ge-a4`).
pub fn builtin(name: &str) -> Option<&'static str> {
    match name {
        "ge-a4" => Some(GE_A4_TOML),
        _ => None,
    }
}

/// The GE A4 of thesis Table 4.1 (RRPR; inches and degrees).
pub fn ge_a4() -> Robot {
    crate::model::robot_file::parse_robot_toml(GE_A4_TOML, "<built-in ge-a4>")
        .expect("the built-in GE A4 file is valid")
}
