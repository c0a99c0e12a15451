//! Controller programs: compensated readings in the form a robot controller takes them.
//!
//! The readings kinecal computes are the controller's own joint coordinates (the values its
//! joints report and are commanded in: a robot file made by `kinecal import ur`, or one whose
//! transducer readings are the controller's joint values). Each brand takes them in its unit
//! and under its names:
//!
//! | brand   | unit | columns                                    |
//! |---------|------|--------------------------------------------|
//! | `ur`    | rad  | `base,shoulder,elbow,wrist1,wrist2,wrist3` |
//! | `abb`   | deg  | `rax_1..rax_n` (a `jointtarget`'s `robax`) |
//! | `kuka`  | deg  | `A1..An` (an `E6AXIS`)                     |
//! | `fanuc` | deg  | `J1..Jn`                                   |
//!
//! A URScript program is one `movej` per row, in radians, with UR's default joint
//! acceleration (1.4 rad/s^2) and speed (1.05 rad/s), inside `def kinecal_program():` and
//! called at the end, as the controller's script interface runs it. Numbers are written with
//! ten decimals (1e-10 rad, 1e-8 deg): far below any controller's resolution.

use crate::error::{Error, Result, Setting};
use crate::model::robot::{JointKind, Robot};
use crate::units::{AngleUnit, Quantity};

/// A robot brand's joint-target convention.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Brand {
    /// Universal Robots: radians, joints named base to wrist 3.
    Ur,
    /// ABB: degrees, `rax_1..rax_n`.
    Abb,
    /// KUKA: degrees, `A1..An`.
    Kuka,
    /// FANUC: degrees, `J1..Jn`.
    Fanuc,
}

impl Brand {
    /// The brand's name on the command line.
    pub fn as_str(self) -> &'static str {
        match self {
            Brand::Ur => "ur",
            Brand::Abb => "abb",
            Brand::Kuka => "kuka",
            Brand::Fanuc => "fanuc",
        }
    }

    /// The unit its controller takes revolute joints in.
    pub fn angle_unit(self) -> AngleUnit {
        match self {
            Brand::Ur => AngleUnit::Rad,
            _ => AngleUnit::Deg,
        }
    }

    /// The joint columns for `robot`, after checking it fits the brand (UR: six revolute
    /// joints; every brand: revolute joints only, as a joint target of theirs holds angles).
    pub fn columns(self, robot: &Robot) -> Result<Vec<String>> {
        let n = robot.dof();
        if let Some(j) = robot
            .joints
            .iter()
            .position(|j| j.kind != JointKind::Revolute)
        {
            return Err(Error::InvalidOption {
                setting: Setting::OutputFormat,
                message: format!(
                    "joint {} is prismatic: a {} joint target holds angles only",
                    j + 1,
                    self.as_str()
                ),
            });
        }
        Ok(match self {
            Brand::Ur => {
                if n != 6 {
                    return Err(Error::InvalidOption {
                        setting: Setting::OutputFormat,
                        message: format!("a UR arm has 6 joints; this robot has {n}"),
                    });
                }
                ["base", "shoulder", "elbow", "wrist1", "wrist2", "wrist3"]
                    .map(String::from)
                    .to_vec()
            }
            Brand::Abb => (1..=n).map(|j| format!("rax_{j}")).collect(),
            Brand::Kuka => (1..=n).map(|j| format!("A{j}")).collect(),
            Brand::Fanuc => (1..=n).map(|j| format!("J{j}")).collect(),
        })
    }

    /// Writes the readings in the brand's unit into `out`.
    pub fn values(self, robot: &Robot, readings: &[f64], out: &mut [f64]) {
        let unit = self.angle_unit();
        for (o, &r) in out.iter_mut().zip(readings) {
            // Readings are in the robot file's angle unit.
            let si = robot.units.to_si(Quantity::Angle, r);
            *o = match unit {
                AngleUnit::Rad => si,
                AngleUnit::Deg => si.to_degrees(),
            };
        }
    }
}

/// The opening of a URScript program.
pub(crate) fn urscript_begin(robot: &Robot, source: &str) -> String {
    format!(
        "# compensated joint targets for {} from {source}, written by kinecal {}\n\
         def kinecal_program():\n",
        robot.name,
        env!("CARGO_PKG_VERSION")
    )
}

/// One `movej` of a URScript program (`joints` in rad), with the row's label as a comment.
pub(crate) fn urscript_move(label: &str, joints: &[f64]) -> String {
    let q: Vec<String> = joints.iter().map(|v| format!("{:.10}", v)).collect();
    format!(
        "  # {}\n  movej([{}], a=1.4, v=1.05)\n",
        label.replace(['\n', '\r'], " "),
        q.join(", ")
    )
}

/// The end of a URScript program, and its call.
pub(crate) fn urscript_end() -> &'static str {
    "end\nkinecal_program()\n"
}

/// A joint value for a joint-target table (ten decimals, no `-0`).
pub(crate) fn joint_field(v: f64) -> String {
    let s = format!("{v:.10}");
    if s.trim_start_matches('-')
        .bytes()
        .all(|b| b == b'0' || b == b'.')
    {
        s.trim_start_matches('-').to_string()
    } else {
        s
    }
}
