//! Denavit-Hartenberg tables, standard and modified (Craig), with the Hayati/Mooring `beta`:
//! read, and written from any robot exactly.
//!
//! A table is CSV with the header `kind,a,alpha,d,theta` and an optional `beta` column, one row
//! per joint (`revolute` or `prismatic`) or constant transform (`fixed`), after comment lines
//! that state its units and convention:
//!
//! ```text
//! # length_unit = mm
//! # angle_unit = deg
//! # convention = standard
//! kind,a,alpha,d,theta,beta
//! revolute,0,90,89.159,0,0
//! ```
//!
//! Standard: a row is `Rz(theta) Tz(d) Tx(a) Rx(alpha) Ry(beta)`; modified (Craig):
//! `Rx(alpha) Tx(a) Ry(beta) Rz(theta) Tz(d)`. A revolute joint's variable `q` adds to `theta`,
//! a prismatic joint's to `d`; a `fixed` row has none. `beta` (0 where the column is absent) is
//! the Hayati/Mooring parameter, the modified-DH extension industrial controllers use: a
//! rotation about the y axis of the frame on the common normal. With it, consecutive axes that
//! are nearly parallel are described by small numbers, where the classical common normal runs
//! off towards infinity (a calibrated UR5's `d` of hundreds of metres). Readings are the joint
//! values `q` in the table's units (slope 1); `theta` (revolute) or `d` (prismatic) becomes the
//! joint offset.
//!
//! A tree (two arms on a torso) is a table per branch under the one header, with a `name`
//! column (any column order): a joint's name heads its reading column, and a branch hangs from
//! a named row. The rows before the first `# branch = TIP, from = ROW` line are the trunk; each
//! such line starts a branch at the frame after row `ROW` (the trunk's end without `from`, the
//! global frame with `from = base`), ending in the tool frame `TIP`: the last branch's is the
//! end effector (so named, besides `ee`), the others' are sites on their branch's last joint.
//!
//! ```text
//! name,kind,a,alpha,d,theta
//! TORSO,revolute,0,0,800,0
//! # branch = LEFT_tool0, from = TORSO
//! LEFT_S,revolute,0,90,89.159,0
//! ...
//! # branch = RIGHT_tool0, from = TORSO
//! RIGHT_S,revolute,0,90,89.159,0
//! ...
//! ```

use nalgebra::{Matrix3, Vector3};

use super::readback::{self, ReadBack, Tolerance};
use super::{chain_from_frames, ImportedJoint, Lost};
use crate::error::{Error, Location, Result, Setting};
use crate::model::kinematics::Frame;
use crate::model::robot::{JointKind, Robot};
use crate::units::{AngleUnit, LengthUnit, Quantity, Units};

/// Which DH convention a table uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Convention {
    /// `Rz(theta) Tz(d) Tx(a) Rx(alpha) Ry(beta)` per row.
    Standard,
    /// `Rx(alpha) Tx(a) Ry(beta) Rz(theta) Tz(d)` per row (Craig).
    Modified,
}

impl Convention {
    /// The spelling in tables and on the command line.
    pub fn as_str(self) -> &'static str {
        match self {
            Convention::Standard => "standard",
            Convention::Modified => "modified",
        }
    }

    /// A row's transform, in words.
    pub fn formula(self) -> &'static str {
        match self {
            Convention::Standard => "Rz(theta) Tz(d) Tx(a) Rx(alpha) Ry(beta)",
            Convention::Modified => "Rx(alpha) Tx(a) Ry(beta) Rz(theta) Tz(d)",
        }
    }
}

/// What a row of a DH table is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RowKind {
    /// A revolute joint: its variable adds to `theta`.
    Revolute,
    /// A prismatic joint: its variable adds to `d`.
    Prismatic,
    /// A constant transform of the same form (a base or tool frame the DH frames cannot be).
    Fixed,
}

impl RowKind {
    /// The joint's kind, `None` for a fixed row.
    pub fn joint(self) -> Option<JointKind> {
        match self {
            RowKind::Revolute => Some(JointKind::Revolute),
            RowKind::Prismatic => Some(JointKind::Prismatic),
            RowKind::Fixed => None,
        }
    }

    /// The spelling in tables.
    pub fn as_str(self) -> &'static str {
        match self {
            RowKind::Revolute => "revolute",
            RowKind::Prismatic => "prismatic",
            RowKind::Fixed => "fixed",
        }
    }
}

impl From<JointKind> for RowKind {
    fn from(k: JointKind) -> Self {
        match k {
            JointKind::Revolute => RowKind::Revolute,
            JointKind::Prismatic => RowKind::Prismatic,
        }
    }
}

/// One row of a DH table (internal units).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DhRow {
    /// Joint kind, or fixed.
    pub kind: RowKind,
    /// Link length (m).
    pub a: f64,
    /// Link twist (rad).
    pub alpha: f64,
    /// Link offset (m).
    pub d: f64,
    /// Joint angle (rad).
    pub theta: f64,
    /// Hayati/Mooring twist about the common normal frame's y axis (rad); 0 in classical DH.
    pub beta: f64,
}

impl DhRow {
    /// A classical row (`beta` 0).
    pub fn new(kind: impl Into<RowKind>, a: f64, alpha: f64, d: f64, theta: f64) -> DhRow {
        DhRow {
            kind: kind.into(),
            a,
            alpha,
            d,
            theta,
            beta: 0.0,
        }
    }

    /// The row's transform with its joint variable 0.
    pub fn transform(&self, convention: Convention) -> Frame {
        match convention {
            Convention::Standard => rz(self.theta)
                .then(&tr(self.a, self.d))
                .then(&rx(self.alpha))
                .then(&ry(self.beta)),
            Convention::Modified => rx(self.alpha)
                .then(&tr(self.a, 0.0))
                .then(&ry(self.beta))
                .then(&rz(self.theta))
                .then(&tr(0.0, self.d)),
        }
    }
}

fn rz(t: f64) -> Frame {
    let (s, c) = t.sin_cos();
    Frame {
        rotation: Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0),
        translation: Vector3::zeros(),
    }
}

fn rx(t: f64) -> Frame {
    let (s, c) = t.sin_cos();
    Frame {
        rotation: Matrix3::new(1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c),
        translation: Vector3::zeros(),
    }
}

fn ry(t: f64) -> Frame {
    let (s, c) = t.sin_cos();
    Frame {
        rotation: Matrix3::new(c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c),
        translation: Vector3::zeros(),
    }
}

fn tr(x: f64, z: f64) -> Frame {
    Frame {
        rotation: Matrix3::identity(),
        translation: Vector3::new(x, 0.0, z),
    }
}

/// The robot with the same forward kinematics as the DH `rows`.
///
/// The chain is walked at joint value 0 (`q_model = 0`, so `Rz(0)` for a revolute joint and
/// `Tz(0)` for a prismatic one), recording the global frame in which each joint acts; `theta`
/// (revolute) or `d` (prismatic) becomes that joint's offset, `q_model = offset + V`. Fixed rows
/// fold into the links around them.
pub fn robot_from_dh(name: &str, units: Units, rows: &[DhRow], convention: Convention) -> Robot {
    let mut current = Frame::identity();
    let mut joints = Vec::with_capacity(rows.len());
    for row in rows {
        if let Some(joint) = walk_row(row, convention, &mut current) {
            joints.push(joint);
        }
    }
    chain_from_frames(name, units, &joints, &current)
}

/// Walks one row at joint value 0 from the global frame `current` (moved to the frame after the
/// row): the joint the row makes, acting in the global frame recorded, with `theta` (revolute) or
/// `d` (prismatic) as its offset; `None` for a fixed row (folded into `current`).
fn walk_row(row: &DhRow, convention: Convention, current: &mut Frame) -> Option<ImportedJoint> {
    let Some(kind) = row.kind.joint() else {
        *current = current.then(&row.transform(convention));
        return None;
    };
    // The part of the row before the joint, and the part after it.
    let (before, offset, after) = match (convention, kind) {
        (Convention::Standard, JointKind::Revolute) => (
            Frame::identity(),
            row.theta,
            tr(row.a, row.d).then(&rx(row.alpha)).then(&ry(row.beta)),
        ),
        (Convention::Standard, JointKind::Prismatic) => (
            rz(row.theta),
            row.d,
            tr(row.a, 0.0).then(&rx(row.alpha)).then(&ry(row.beta)),
        ),
        (Convention::Modified, JointKind::Revolute) => (
            rx(row.alpha).then(&tr(row.a, 0.0)).then(&ry(row.beta)),
            row.theta,
            tr(0.0, row.d),
        ),
        (Convention::Modified, JointKind::Prismatic) => (
            rx(row.alpha)
                .then(&tr(row.a, 0.0))
                .then(&ry(row.beta))
                .then(&rz(row.theta)),
            row.d,
            Frame::identity(),
        ),
    };
    let frame = current.then(&before);
    *current = frame.then(&after);
    Some(ImportedJoint {
        kind,
        frame,
        offset,
        range: None,
    })
}

/// A section of a tree's DH table: the trunk (the rows before the first `# branch` line) or a
/// branch.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct DhSection {
    /// The branch's tip (the tool frame after its last row); `None` for the trunk.
    pub tip: Option<String>,
    /// The row the branch hangs from (`base`: the global frame; `None`: the trunk's end).
    pub from: Option<String>,
    /// The `# branch` line.
    pub line: usize,
    /// Its rows.
    pub rows: Vec<NamedRow>,
}

/// The `# branch = TIP[, from = ROW]` lines of a DH table (`:` for `=` too), each with its
/// line; other comments are free text. An error names a line that starts `# branch` and says
/// anything else.
fn branch_lines(text: &str, file: &str) -> Result<Vec<(usize, String, Option<String>)>> {
    let mut out = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let Some(comment) = raw.trim_start_matches('\u{feff}').trim().strip_prefix('#') else {
            continue;
        };
        let comment = comment.trim();
        let Some(rest) = comment.strip_prefix("branch") else {
            continue;
        };
        if !rest.trim_start().starts_with(['=', ':']) {
            continue;
        }
        let at = || Location::file(file).at_line(i + 1).with_field("branch");
        let (mut tip, mut from) = (None, None);
        for part in comment.split(',') {
            let Some((key, value)) = part.split_once(['=', ':']) else {
                return Err(Error::input(
                    at(),
                    format!("`{}`: expected `# branch = TIP, from = ROW`", part.trim()),
                ));
            };
            let value = value.trim().trim_matches('"').to_string();
            let slot = match key.trim() {
                "branch" => &mut tip,
                "from" => &mut from,
                other => {
                    return Err(Error::input(
                        at(),
                        format!(
                            "unknown key `{other}`: expected `# branch = TIP, from = ROW` (the \
                             tool frame the branch ends in, the named row it hangs from)"
                        ),
                    ))
                }
            };
            if value.is_empty() {
                return Err(Error::input(at(), format!("`{}` needs a name", key.trim())));
            }
            *slot = Some(value);
        }
        let tip = tip.ok_or_else(|| Error::input(at(), "a branch needs its tip's name"))?;
        out.push((i + 1, tip, from));
    }
    Ok(out)
}

/// The sections of a DH table: its rows split at its `# branch` lines (a table without any is
/// one trunk, a chain).
pub(crate) fn dh_sections(text: &str, file: &str, units: Units) -> Result<Vec<DhSection>> {
    let rows = parse_dh_rows(text, file, units)?;
    let header_line = {
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        text.lines()
            .position(|l| !l.trim().is_empty() && !l.trim_start().starts_with('#'))
            .map_or(1, |i| i + 1)
    };
    let mut sections = vec![DhSection {
        tip: None,
        from: None,
        line: 0,
        rows: Vec::new(),
    }];
    for (line, tip, from) in branch_lines(text, file)? {
        if line < header_line {
            return Err(Error::input(
                Location::file(file).at_line(line).with_field("branch"),
                "a branch starts after the table's header",
            ));
        }
        sections.push(DhSection {
            tip: Some(tip),
            from,
            line,
            rows: Vec::new(),
        });
    }
    for row in rows {
        let s = sections
            .iter_mut()
            .rev()
            .find(|s| s.line < row.line)
            .expect("the trunk starts at line 0");
        s.rows.push(row);
    }
    Ok(sections)
}

/// Where a walk through a tree's table stands: the global frame at zero readings and the last
/// joint on the path from the base (1-based; 0 for none).
#[derive(Debug, Clone, Copy)]
struct Station {
    frame: Frame,
    joint: usize,
}

/// The robot of a tree's DH table: the trunk's rows from the global frame, each branch's from
/// the frame after the row it hangs from (`from = ROW`; the trunk's end without, the global
/// frame for `from = base`), every joint once, named after its row. The last branch ends in the
/// end effector, named after its tip; every other tip becomes a site of that name on the last
/// joint of its path.
pub(crate) fn robot_from_dh_tree(
    name: &str,
    units: Units,
    sections: &[DhSection],
    convention: Convention,
    file: &str,
) -> Result<Robot> {
    let at = |line: usize, field: &str| Location::file(file).at_line(line).with_field(field);
    let mut joints: Vec<ImportedJoint> = Vec::new();
    let mut parents: Vec<usize> = Vec::new();
    let mut joint_names: Vec<Option<String>> = Vec::new();
    let mut named: Vec<(&str, Station)> = Vec::new();
    let base = Station {
        frame: Frame::identity(),
        joint: 0,
    };
    let mut trunk_end = base;
    // Each branch's tip: (name, where it is, its line).
    let mut tips: Vec<(&str, Station, usize)> = Vec::new();
    for s in sections {
        let mut at_row = match s.from.as_deref() {
            None => trunk_end,
            Some("base") => base,
            Some(row) => match named.iter().find(|(n, _)| *n == row) {
                Some((_, st)) => *st,
                None => {
                    return Err(Error::input(
                        at(s.line, "from"),
                        format!(
                            "no row named `{row}` before this branch (it hangs from a named row \
                             of the trunk or of an earlier branch, or from `base`)"
                        ),
                    ))
                }
            },
        };
        for r in &s.rows {
            if let Some(joint) = walk_row(&r.row, convention, &mut at_row.frame) {
                joints.push(joint);
                parents.push(at_row.joint);
                joint_names.push(r.name.clone());
                at_row.joint = joints.len();
            }
            if let Some(n) = &r.name {
                if n == "base" {
                    return Err(Error::input(
                        at(r.line, "name"),
                        "`base` is the global frame: name the row otherwise",
                    ));
                }
                named.push((n, at_row));
            }
        }
        match &s.tip {
            None => trunk_end = at_row,
            Some(tip) => tips.push((tip, at_row, s.line)),
        }
    }
    let (ee_name, ee, ee_line) = match tips.pop() {
        Some(t) => (Some(t.0), t.1, t.2),
        None => (None, trunk_end, 0),
    };
    if ee.joint != joints.len() {
        return Err(Error::input(
            at(ee_line, "branch"),
            "the last branch ends in the end effector and must end with the table's last joint: \
             put a branch with joints of its own last",
        ));
    }
    let mut robot = super::tree_from_frames(name, units, &joints, &parents, &ee.frame);
    for (joint, n) in robot.joints.iter_mut().zip(joint_names) {
        joint.name = n;
    }
    robot.end_effector = ee_name.filter(|n| *n != "ee").map(String::from);
    for (tip, st, line) in tips {
        if st.joint == 0 {
            return Err(Error::input(
                at(line, "branch"),
                format!("branch `{tip}`: no joint between the base and its tip"),
            ));
        }
        let carrier = joints[st.joint - 1].frame;
        robot.sites.push(crate::model::robot::Site {
            name: tip.to_string(),
            joint: st.joint,
            frame: super::link_of(&super::inverse(&carrier).then(&st.frame)),
        });
    }
    Ok(robot)
}

/// A DH table: its rows (internal units), and the units and convention it is written in.
#[derive(Debug, Clone, PartialEq)]
pub struct DhTable {
    /// The rows.
    pub rows: Vec<DhRow>,
    /// The units of its numbers (and of the readings: the joint values).
    pub units: Units,
    /// Its convention.
    pub convention: Convention,
}

/// What a table's comment lines state (`# length_unit = mm`, `# angle_unit = deg`,
/// `# convention = standard`), each with its line.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Stated {
    /// The length unit.
    pub length: Option<(LengthUnit, usize)>,
    /// The angle unit.
    pub angle: Option<(AngleUnit, usize)>,
    /// The convention.
    pub convention: Option<(Convention, usize)>,
}

/// Reads the `key = value` comment lines before a table's header (`key: value` too). Other
/// comments are free text; a stated key with a value it cannot take is refused with its line.
pub fn stated(text: &str, file: &str) -> Result<Stated> {
    let mut out = Stated::default();
    for (i, raw) in text.lines().enumerate() {
        let line = raw.trim_start_matches('\u{feff}').trim();
        if line.is_empty() {
            continue;
        }
        let Some(comment) = line.strip_prefix('#') else {
            break;
        };
        let Some((key, value)) = comment.split_once(['=', ':']) else {
            continue;
        };
        let (key, value) = (key.trim(), value.trim().trim_matches('"'));
        let at = || {
            Location::file(file)
                .at_line(i + 1)
                .with_field(key.to_string())
        };
        match key {
            "length_unit" => {
                let u = value.parse().map_err(|e: String| Error::input(at(), e))?;
                out.length = Some((u, i + 1));
            }
            "angle_unit" => {
                let u = value.parse().map_err(|e: String| Error::input(at(), e))?;
                out.angle = Some((u, i + 1));
            }
            "convention" => {
                let c = match value {
                    "standard" => Convention::Standard,
                    "modified" => Convention::Modified,
                    other => {
                        return Err(Error::input(
                            at(),
                            format!("unknown convention `{other}` (expected standard or modified)"),
                        ))
                    }
                };
                out.convention = Some((c, i + 1));
            }
            _ => {}
        }
    }
    Ok(out)
}

/// The one of a stated value and an asked one: both (they must agree), either, or neither (an
/// error saying what to give).
fn settle<T: PartialEq + Copy + std::fmt::Display>(
    stated: Option<(T, usize)>,
    asked: Option<T>,
    file: &str,
    setting: Setting,
    key: &str,
) -> Result<T> {
    match (stated, asked) {
        (Some((s, line)), Some(a)) if s != a => Err(Error::InvalidOption {
            setting,
            message: format!("{file}:{line} states `{key} = {s}`, not {a}"),
        }),
        (Some((s, _)), _) => Ok(s),
        (None, Some(a)) => Ok(a),
        (None, None) => Err(Error::InvalidOption {
            setting,
            message: format!(
                "{file} does not state its {} (a `# {key} = ...` line before the header, as \
                 kinecal export dh writes): give it",
                setting.name()
            ),
        }),
    }
}

/// Reads a DH table: the units and convention it states, or those given (which must agree with
/// what it states; for a table that states none they must be given), and its rows.
pub(crate) fn read_dh_table(
    text: &str,
    file: &str,
    length: Option<LengthUnit>,
    angle: Option<AngleUnit>,
    convention: Option<Convention>,
) -> Result<DhTable> {
    let s = stated(text, file)?;
    let units = Units {
        length: settle(s.length, length, file, Setting::LengthUnit, "length_unit")?,
        angle: settle(s.angle, angle, file, Setting::AngleUnit, "angle_unit")?,
    };
    let convention = match (s.convention, convention) {
        (Some((c, line)), Some(a)) if c != a => {
            return Err(Error::input(
                Location::file(file).at_line(line),
                format!(
                    "the table is in the {} convention, not {}",
                    c.as_str(),
                    a.as_str()
                ),
            ))
        }
        (Some((c, _)), _) => c,
        (None, Some(a)) => a,
        (None, None) => {
            return Err(Error::input(
                Location::file(file),
                "the table does not state its convention (a `# convention = standard` or \
                 `modified` line before the header): give it",
            ))
        }
    };
    Ok(DhTable {
        rows: parse_dh_csv(text, file, units)?,
        units,
        convention,
    })
}

/// Reads a DH table file (`text`, named `file` in errors), in the units and convention it
/// states or is given (`read_dh_table`), and builds the robot ([`robot_from_dh`]) in those
/// units, refusing a table whose robot is not usable (values beyond +-1e9 once converted).
pub fn import_dh(
    text: &str,
    file: &str,
    name: &str,
    length: Option<LengthUnit>,
    angle: Option<AngleUnit>,
    convention: Option<Convention>,
) -> Result<Robot> {
    let t = read_dh_table(text, file, length, angle, convention)?;
    let sections = dh_sections(text, file, t.units)?;
    let tree = sections.len() > 1
        || sections
            .iter()
            .flat_map(|s| &s.rows)
            .any(|r| r.name.is_some());
    let robot = if tree {
        robot_from_dh_tree(name, t.units, &sections, t.convention, file)?
    } else {
        robot_from_dh(name, t.units, &t.rows, t.convention)
    };
    robot.validate().map_err(|m| {
        Error::input(
            Location::file(file),
            format!("the robot these rows describe is not usable: {m}"),
        )
    })?;
    Ok(robot)
}

/// Parses a DH table's rows (`kind,a,alpha,d,theta[,beta]`) in `units`. Comment lines (`#`)
/// are skipped; a leading byte-order mark is not part of the header.
pub fn parse_dh_csv(text: &str, file: &str, units: Units) -> Result<Vec<DhRow>> {
    Ok(parse_dh_rows(text, file, units)?
        .into_iter()
        .map(|r| r.row)
        .collect())
}

/// A row of a DH table as the file has it: its name (the `name` column: a joint's reading
/// column, a frame a branch hangs from), the row, and its line.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct NamedRow {
    /// The row's name; `None` where the column is absent or the field empty.
    pub name: Option<String>,
    /// The row (internal units).
    pub row: DhRow,
    /// Its line in the file.
    pub line: usize,
}

/// The columns of a DH table: `kind, a, alpha, d, theta` required, `beta` and `name` optional,
/// in any order (case ignored); their indices in that order, `None` for an absent optional one.
fn dh_columns(header: &[String]) -> Option<[Option<usize>; 7]> {
    const COLUMNS: [&str; 7] = ["kind", "a", "alpha", "d", "theta", "beta", "name"];
    let mut at = [None; 7];
    for (i, h) in header.iter().enumerate() {
        let k = COLUMNS.iter().position(|c| c == h)?;
        if at[k].replace(i).is_some() {
            return None;
        }
    }
    at[..5].iter().all(Option::is_some).then_some(at)
}

/// [`parse_dh_csv`] with each row's name and line.
pub(crate) fn parse_dh_rows(text: &str, file: &str, units: Units) -> Result<Vec<NamedRow>> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut rdr = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .comment(Some(b'#'))
        .from_reader(text.as_bytes());
    let loc = Location::file(file);
    let record = rdr
        .headers()
        .map_err(|e| Error::input(loc.at_line(1), format!("invalid CSV: {e}")))?;
    // A record's line: the first line from its byte offset (where the previous record ended)
    // that is not blank or a comment. The reader's own count leaves out the comment lines it
    // skips.
    let line_of = |p: Option<&csv::Position>| {
        p.map_or(0, |p| {
            let mut at = (p.byte() as usize).min(text.len());
            let mut line = 1 + memchr::memchr_iter(b'\n', &text.as_bytes()[..at]).count();
            while let Some(rest) = text.get(at..).filter(|r| !r.is_empty()) {
                let end = rest.find('\n').map_or(rest.len(), |i| i + 1);
                let l = rest[..end].trim();
                if !(l.is_empty() || l.starts_with('#')) {
                    break;
                }
                at += end;
                line += 1;
            }
            line
        })
    };
    let header_line = line_of(record.position()).max(1);
    let header: Vec<String> = record.iter().map(|h| h.to_ascii_lowercase()).collect();
    const NAMES: [&str; 5] = ["a", "alpha", "d", "theta", "beta"];
    let Some(cols) = dh_columns(&header) else {
        return Err(Error::input(
            loc.at_line(header_line),
            format!(
                "unexpected header `{}`: expected `kind,a,alpha,d,theta` or \
                 `kind,a,alpha,d,theta,beta`, and optionally `name` (a joint's reading column, \
                 a frame a branch hangs from), in any order",
                header.join(",")
            ),
        ));
    };
    let mut rows: Vec<NamedRow> = Vec::new();
    for rec in rdr.records() {
        let rec = rec.map_err(|e| {
            let line = line_of(e.position());
            Error::input(loc.at_line(line), format!("invalid CSV: {e}"))
        })?;
        let line = line_of(rec.position());
        let at = |f: &str| loc.at_line(line).with_field(f);
        let field = |k: usize| cols[k].map_or("", |i| &rec[i]);
        let kind = match field(0) {
            "revolute" | "R" | "r" => RowKind::Revolute,
            "prismatic" | "P" | "p" => RowKind::Prismatic,
            "fixed" => RowKind::Fixed,
            other => {
                return Err(Error::input(
                    at("kind"),
                    format!("unknown joint kind `{other}` (expected revolute, prismatic or fixed)"),
                ))
            }
        };
        let mut v = [0.0; 5];
        for (k, name) in NAMES.iter().enumerate() {
            if cols[k + 1].is_none() {
                continue;
            }
            v[k] = field(k + 1)
                .parse::<f64>()
                .ok()
                .filter(|x| crate::units::plausible(*x))
                .ok_or_else(|| {
                    Error::input(
                        at(name),
                        format!(
                            "expected a finite number within +-1e9, found `{}`",
                            field(k + 1)
                        ),
                    )
                })?;
        }
        let name = Some(field(6)).filter(|n| !n.is_empty()).map(String::from);
        if let Some(n) = &name {
            if let Some(first) = rows.iter().find(|r| r.name.as_ref() == Some(n)) {
                return Err(Error::input(
                    at("name"),
                    format!("row name `{n}` used twice (first on line {})", first.line),
                ));
            }
        }
        rows.push(NamedRow {
            name,
            row: DhRow {
                kind,
                a: units.to_si(Quantity::Length, v[0]),
                alpha: units.to_si(Quantity::Angle, v[1]),
                d: units.to_si(Quantity::Length, v[2]),
                theta: units.to_si(Quantity::Angle, v[3]),
                beta: units.to_si(Quantity::Angle, v[4]),
            },
            line,
        });
    }
    if !rows.iter().any(|r| r.row.kind != RowKind::Fixed) {
        return Err(Error::input(
            loc,
            "no joints: the table has no revolute or prismatic row",
        ));
    }
    Ok(rows)
}

/// Consecutive axes within this angle of parallel (or anti-parallel) take the Hayati/Mooring
/// form: where their classical common normal would lie more than `1/sin(1 deg)`, 57 times their
/// distance, away.
pub(crate) const NEAR_PARALLEL: f64 = 1.0 * std::f64::consts::PI / 180.0;

/// A joint axis (or the tool's z axis) at zero readings: a point on it and its unit direction.
#[derive(Debug, Clone, Copy)]
struct Line {
    p: Vector3<f64>,
    z: Vector3<f64>,
}

/// Where the next frame goes along a line nearly parallel to the current axis.
#[derive(Debug, Clone, Copy)]
enum Anchor {
    /// Where the line crosses the plane normal to the current axis through the current origin
    /// (the classical Hayati choice, `d = 0`).
    Plane,
    /// At (the foot on the current axis of) this point of the line: the robot's own frame on
    /// it, so that a DH robot's table comes back digit for digit.
    Point(Vector3<f64>),
}

fn near_parallel(a: &Vector3<f64>, b: &Vector3<f64>) -> bool {
    a.cross(b).norm() < NEAR_PARALLEL.sin()
}

/// From frame `f` (its z the current axis) towards `line`: the foot `o` on the current axis of
/// the next frame's x line, the unit x (perpendicular to the axis), and the point `q` of `line`
/// that x line reaches. Lines not nearly parallel: the common normal (x along it, the way
/// nearer `f`'s x; for crossing lines `+-z x z'`); nearly parallel: the normal through `anchor`.
fn toward(f: &Frame, line: &Line, anchor: Anchor) -> (Vector3<f64>, Vector3<f64>, Vector3<f64>) {
    let (o, z) = (f.translation, f.rotation.column(2).into_owned());
    let xf = f.rotation.column(0).into_owned();
    let (foot, q, fallback) = if near_parallel(&z, &line.z) {
        let foot = match anchor {
            Anchor::Plane => o,
            Anchor::Point(p) => o + z * z.dot(&(p - o)),
        };
        // Where the line crosses the plane through `foot` normal to z.
        let t = z.dot(&(foot - line.p)) / z.dot(&line.z);
        (foot, line.p + line.z * t, xf)
    } else {
        let w = o - line.p;
        let (b, d, e) = (z.dot(&line.z), z.dot(&w), line.z.dot(&w));
        let den = 1.0 - b * b;
        let s = (b * e - d) / den;
        let t = (e - b * d) / den;
        let n = z.cross(&line.z).normalize();
        let n = if n.dot(&xf) < 0.0 { -n } else { n };
        (o + z * s, line.p + line.z * t, n)
    };
    let gap = q - foot;
    let x = if gap.norm() > 1e-12 {
        gap.normalize()
    } else {
        fallback
    };
    let x = (x - z * x.dot(&z)).normalize();
    // Either way along the normal is a DH frame (a changes sign): the way nearer f's x, as DH
    // tables are written (theta near 0).
    let x = if x.dot(&xf) < -1e-12 { -x } else { x };
    (foot, x, q)
}

/// The angles `(alpha, beta)` with `Rx(alpha) Ry(beta) e_z = v` (`v` a unit vector in the frame
/// they turn): beta in `[-pi/2, pi/2]`, 0 when `v` is normal to x.
fn twist_to(v: &Vector3<f64>) -> (f64, f64) {
    let beta = if v.x.abs() < 1e-15 {
        0.0
    } else {
        v.x.clamp(-1.0, 1.0).asin()
    };
    ((-v.y).atan2(v.z), beta)
}

/// Whether `tool` can be a standard DH frame after `prev`: its x perpendicular to `prev`'s z and
/// crossing it.
fn standard_fits(prev: &Frame, tool: &Frame) -> bool {
    let (zp, x) = (prev.rotation.column(2), tool.rotation.column(0));
    if x.dot(&zp).abs() > 1e-12 {
        return false;
    }
    let w = tool.translation - prev.translation;
    let n = zp.cross(&x);
    // Lines o_p + s z_p and o_t + t x_t cross when w is in their plane.
    n.norm() > 1e-12 && (w.dot(&n) / n.norm()).abs() < 1e-12
}

/// Whether `tool` can be the last modified DH frame, on the axis `line`: its z along the axis
/// and its origin on it.
fn modified_fits(line: &Line, tool: &Frame) -> bool {
    let zt = tool.rotation.column(2).into_owned();
    let w = tool.translation - line.p;
    zt.dot(&line.z) > 0.0
        && zt.cross(&line.z).norm() < 1e-12
        && (w - line.z * w.dot(&line.z)).norm() < 1e-12
}

/// `Rz(theta) Tz(d)` of `rel` (a transform whose z axis and origin stay on the z axis).
fn along_z(rel: &Frame) -> (f64, f64) {
    (
        rel.rotation[(1, 0)].atan2(rel.rotation[(0, 0)]),
        rel.translation.z,
    )
}

/// A standard fixed row `Rz(theta) Tz(d) Tx(a) Rx(alpha) Ry(beta)` from the global frame to a
/// frame on `line` at its point `p`, its z along the line (the row's five values reach any
/// point and any direction).
fn placement_row(line: &Line) -> DhRow {
    let p = line.p;
    let radius = p.x.hypot(p.y);
    let theta = if radius > 1e-12 { p.y.atan2(p.x) } else { 0.0 };
    let (alpha, beta) = twist_to(&(rz(-theta).rotation * line.z));
    DhRow {
        kind: RowKind::Fixed,
        a: radius,
        alpha,
        d: p.z,
        theta,
        beta,
    }
}

/// Whether a row would be written as all zeros (the identity).
fn is_zero(r: &DhRow) -> bool {
    [r.a, r.alpha, r.d, r.theta, r.beta]
        .iter()
        .all(|v| v.abs() < 1e-13)
}

/// A DH table of `robot` in `convention` with the same forward kinematics, the readings its
/// joint variables (the slopes and couplings it cannot hold aside: [`export_dh`] says so).
///
/// The frames are built from the joint axes at zero readings. Standard: frame `k` on axis
/// `k + 1`, reached from axis `k` along their common normal; the last frame on the tool's z
/// axis, or the tool itself when its x crosses the last axis at a right angle (as a DH robot's
/// does). Modified: frame `k` on axis `k`, its x along the common normal to the next axis (the
/// tool's z axis after the last), or the tool itself when it sits on the last axis. Consecutive
/// axes within [`NEAR_PARALLEL`] of parallel take the Hayati/Mooring `beta` instead of a common
/// normal, through the robot's own joint frame (so exactly parallel axes keep their `d`).
/// What the DH frames cannot place is a `fixed` row: before the first joint when its axis is
/// not the base z axis (standard) or when the base x is not the first common normal
/// (modified), after the last one for the tool. Every value is finite; an error names the
/// joint otherwise.
pub(crate) fn dh_rows(robot: &Robot, convention: Convention) -> Result<Vec<DhRow>> {
    let axes = Axes::of(robot);
    // The robot's size without its placement (link1: for a robot calibrated in an instrument's
    // frame, where the instrument saw it, metres away), and its longest link: a base row that
    // meets axis 1 farther than that from joint 1's own frame would put the placement into
    // the joint rows.
    let lengths = robot.links[1..]
        .iter()
        .map(|l| (l.x * l.x + l.y * l.y + l.z * l.z).sqrt());
    let size = lengths.clone().sum::<f64>().max(1e-3);
    let longest = lengths.fold(1e-3, f64::max);
    let rows = match convention {
        Convention::Standard => standard_rows(&axes, longest),
        Convention::Modified => {
            let rows = modified_rows(&axes);
            placement_in_joint_rows(&rows, &axes, size)?;
            rows
        }
    };
    all_finite(&rows, convention)?;
    Ok(rows)
}

/// The joint axes at zero readings (the global frame in which joint `k` acts is the one after
/// joint `k - 1` through link `k`), the tool frame and its z axis, and each joint's row kind.
struct Axes {
    lines: Vec<Line>,
    tool: Frame,
    tool_line: Line,
    kinds: Vec<RowKind>,
}

impl Axes {
    fn of(robot: &Robot) -> Axes {
        use crate::model::kinematics::{Chain, Target, Workspace};
        let n = robot.dof();
        let chain = Chain::new(robot);
        let mut ws = Workspace::new(robot);
        chain.forward(&vec![0.0; n], &mut ws);
        let lines = (0..n)
            .map(|k| {
                let f = ws.after_joint(k).then(&Frame::from_link(&robot.links[k]));
                Line {
                    p: f.translation,
                    z: f.rotation.column(2).into_owned(),
                }
            })
            .collect();
        let tool = chain.target_frame(&ws, Target::EndEffector);
        Axes {
            lines,
            tool,
            tool_line: Line {
                p: tool.translation,
                z: tool.rotation.column(2).into_owned(),
            },
            kinds: robot.joints.iter().map(|j| RowKind::from(j.kind)).collect(),
        }
    }

    /// The line after joint `k`'s axis: the next joint's, or the tool's z axis after the last.
    fn next_line(&self, k: usize) -> Line {
        if k + 1 < self.lines.len() {
            self.lines[k + 1]
        } else {
            self.tool_line
        }
    }
}

/// The standard table: frame `k` on axis `k + 1`, reached from axis `k` along their common
/// normal; a fixed base row when axis 1 is not the base z axis (at joint 1's own frame, with
/// the whole placement, when the base frame meets axis 1 farther than the `longest` link); the
/// tool as the last joint's frame when it fits, else a fixed tool row.
fn standard_rows(axes: &Axes, longest: f64) -> Vec<DhRow> {
    let n = axes.lines.len();
    let mut rows = Vec::with_capacity(n + 2);
    // One standard step: from s (on an axis) to the next line.
    let step = |s: &Frame, line: &Line, anchor: Anchor, kind: RowKind| {
        let (foot, x, q) = toward(s, line, anchor);
        let (xf, yf, z) = (
            s.rotation.column(0).into_owned(),
            s.rotation.column(1).into_owned(),
            s.rotation.column(2).into_owned(),
        );
        let theta = x.dot(&yf).atan2(x.dot(&xf));
        let turned = Matrix3::from_columns(&[x, z.cross(&x), z]);
        let (alpha, beta) = twist_to(&(turned.transpose() * line.z));
        let row = DhRow {
            kind,
            a: (q - foot).dot(&x),
            alpha,
            d: (foot - s.translation).dot(&z),
            theta,
            beta,
        };
        let next = s.then(&row.transform(Convention::Standard));
        (row, next)
    };
    // Frame 0 on axis 1: the global frame when axis 1 is its z axis, else a fixed row.
    let (mut base, mut s) = step(
        &Frame::identity(),
        &axes.lines[0],
        Anchor::Plane,
        RowKind::Fixed,
    );
    if (s.translation - axes.lines[0].p).norm() > longest {
        // Frame 0 farther from joint 1's own frame than any link is long: the placement
        // would go on into joint 1's d. Frame 0 at joint 1's own frame instead, the
        // whole placement in the base row.
        base = placement_row(&axes.lines[0]);
        s = base.transform(Convention::Standard);
    }
    if !is_zero(&base) {
        rows.push(base);
    } else {
        s = Frame::identity();
    }
    let mut tool_done = false;
    for k in 0..n {
        if k + 1 == n && standard_fits(&s, &axes.tool) {
            let rel = super::inverse(&s).then(&axes.tool);
            let theta = rel.rotation[(1, 0)].atan2(rel.rotation[(0, 0)]);
            let (c, si) = (theta.cos(), theta.sin());
            // R = Rz(theta) Rx(alpha): alpha from Rz(-theta) R.
            let m = Matrix3::new(c, si, 0.0, -si, c, 0.0, 0.0, 0.0, 1.0) * rel.rotation;
            rows.push(DhRow {
                kind: axes.kinds[k],
                a: rel.translation.x * c + rel.translation.y * si,
                alpha: m[(2, 1)].atan2(m[(1, 1)]),
                d: rel.translation.z,
                theta,
                beta: 0.0,
            });
            tool_done = true;
            break;
        }
        let line = axes.next_line(k);
        let (row, next) = step(&s, &line, Anchor::Point(line.p), axes.kinds[k]);
        rows.push(row);
        s = next;
    }
    if !tool_done {
        let (theta, d) = along_z(&super::inverse(&s).then(&axes.tool));
        let row = DhRow::new(RowKind::Fixed, 0.0, 0.0, d, theta);
        if !is_zero(&row) {
            rows.push(row);
        }
    }
    rows
}

/// The modified table: frame `k` on axis `k`, its x along the common normal to the next axis;
/// a fixed base row when the base x is not the first common normal, the tool as the last
/// joint's frame when it sits on the last axis, else a fixed tool row.
fn modified_rows(axes: &Axes) -> Vec<DhRow> {
    let n = axes.lines.len();
    let mut rows = Vec::with_capacity(n + 2);
    // Frame k on axis k, its x towards the next line: `Rz(theta) Tz(d)` from `l` (the
    // frame where the previous row landed on the axis), and the point it points to.
    let place = |l: &Frame, line: &Line, anchor: Anchor| {
        let (foot, x, q) = toward(l, line, anchor);
        let (xl, yl, z) = (
            l.rotation.column(0).into_owned(),
            l.rotation.column(1).into_owned(),
            l.rotation.column(2).into_owned(),
        );
        let theta = x.dot(&yl).atan2(x.dot(&xl));
        let d = (foot - l.translation).dot(&z);
        let m = l.then(&rz(theta)).then(&tr(0.0, d));
        (theta, d, m, q)
    };
    // From frame m along its x to `q` on `line`, turned onto the line: `Rx(alpha) Tx(a)
    // Ry(beta)`, and the frame it lands in.
    let land = |m: &Frame, line: &Line, q: &Vector3<f64>| {
        let a = (q - m.translation).dot(&m.rotation.column(0));
        let (alpha, beta) = twist_to(&(m.rotation.transpose() * line.z));
        let l = m.then(&rx(alpha)).then(&tr(a, 0.0)).then(&ry(beta));
        (alpha, a, beta, l)
    };
    let (theta0, d0, mut m, mut q) = place(&Frame::identity(), &axes.lines[0], Anchor::Plane);
    let base = DhRow::new(RowKind::Fixed, 0.0, 0.0, d0, theta0);
    if !is_zero(&base) {
        rows.push(base);
    } else {
        m = Frame::identity();
    }
    let mut tool_done = false;
    for (k, axis) in axes.lines.iter().enumerate() {
        let (alpha, a, beta, l) = land(&m, axis, &q);
        let (theta, d) = if k + 1 == n && modified_fits(axis, &axes.tool) {
            tool_done = true;
            along_z(&super::inverse(&l).then(&axes.tool))
        } else {
            let line = axes.next_line(k);
            let (theta, d, next, nq) = place(&l, &line, Anchor::Point(line.p));
            m = next;
            q = nq;
            (theta, d)
        };
        rows.push(DhRow {
            kind: axes.kinds[k],
            a,
            alpha,
            d,
            theta,
            beta,
        });
    }
    if !tool_done {
        let (alpha, a, beta, l) = land(&m, &axes.tool_line, &q);
        let (theta, d) = along_z(&super::inverse(&l).then(&axes.tool));
        let row = DhRow {
            kind: RowKind::Fixed,
            a,
            alpha,
            d,
            theta,
            beta,
        };
        if !is_zero(&row) {
            rows.push(row);
        }
    }
    rows
}

/// Refuses a modified table whose first joint row holds the robot's placement (beyond its
/// `size` and a metre): a controller does not take it.
fn placement_in_joint_rows(rows: &[DhRow], axes: &Axes, size: f64) -> Result<()> {
    if let Some(r) = rows.iter().find(|r| r.kind != RowKind::Fixed) {
        // Beyond the robot's size and beyond a metre (a small robot's own DH base offsets
        // stay): a placement, not a link.
        let far = size.max(1.0);
        if r.a.abs().max(r.d.abs()) > far && axes.lines[0].p.norm() > far {
            return Err(Error::Problem(format!(
                "the robot's base frame is {:.3} m from its first joint (link1, e.g. a \
                 tracker's frame where the robot was calibrated): a modified DH table \
                 would write that placement into joint 1's row (a = {:.3} m, d = {:.3} m, \
                 beyond the robot's size of {:.3} m without it), which a controller does \
                 not take; export the standard convention (`--convention standard`: its \
                 fixed base row holds the placement), or place the robot in its own base \
                 frame first",
                axes.lines[0].p.norm(),
                r.a,
                r.d,
                size
            )));
        }
    }
    Ok(())
}

/// Refuses a table with a value that is not finite, naming the row.
fn all_finite(rows: &[DhRow], convention: Convention) -> Result<()> {
    let mut joint = 0;
    for r in rows {
        if ![r.a, r.alpha, r.d, r.theta, r.beta]
            .iter()
            .all(|v| crate::units::plausible(*v))
        {
            return Err(Error::Problem(format!(
                "the {} DH row {} of the robot is not finite ({r:?}): the robot's frames are not \
                 usable",
                convention.as_str(),
                if r.kind == RowKind::Fixed {
                    "of a fixed transform".to_string()
                } else {
                    format!("of joint {}", joint + 1)
                }
            )));
        }
        if r.kind != RowKind::Fixed {
            joint += 1;
        }
    }
    Ok(())
}

/// A number as a DH table holds it: 15 significant digits (the frames are products along the
/// chain, whose last digit is rounding), below 1e-12 as 0.
fn num(v: f64) -> String {
    if v.abs() < 1e-12 {
        return "0".into();
    }
    let r: f64 = format!("{v:.14e}").parse().unwrap_or(v);
    format!("{r}")
}

/// A DH table as text, read back by `read_dh_table`: comment lines stating the convention
/// (with its formula) and the units, then `kind,a,alpha,d,theta`, with a `beta` column when a
/// row has one.
pub fn write_dh_table(rows: &[DhRow], units: Units, convention: Convention) -> String {
    write_named_dh_table(rows, &[], units, convention)
}

/// [`write_dh_table`] with a `name` column when a row has a name (`names[k]`, row `k`'s; rows
/// past the list have none): a joint row's name is its joint's, which heads its reading
/// column in measurement and postures files (quoted when it holds a comma, a quote or a line
/// break, or begins or ends with a space).
pub fn write_named_dh_table(
    rows: &[DhRow],
    names: &[Option<&str>],
    units: Units,
    convention: Convention,
) -> String {
    let with_names = names.iter().take(rows.len()).any(|n| n.is_some());
    let with_beta = rows.iter().any(|r| num(r.beta) != "0");
    let mut out = format!(
        "# DH table ({} convention): each row is {}, a revolute joint's variable added to \
         theta, a prismatic joint's to d; a fixed row is a constant transform\n\
         # length_unit = {}\n# angle_unit = {}\n# convention = {}\n",
        convention.as_str(),
        if with_beta {
            convention.formula()
        } else {
            match convention {
                Convention::Standard => "Rz(theta) Tz(d) Tx(a) Rx(alpha)",
                Convention::Modified => "Rx(alpha) Tx(a) Rz(theta) Tz(d)",
            }
        },
        units.length,
        units.angle,
        convention.as_str()
    );
    out.push_str(if with_beta {
        "kind,a,alpha,d,theta,beta"
    } else {
        "kind,a,alpha,d,theta"
    });
    out.push_str(if with_names { ",name\n" } else { "\n" });
    for (k, r) in rows.iter().enumerate() {
        out.push_str(&format!(
            "{},{},{},{},{}",
            r.kind.as_str(),
            num(units.from_si(Quantity::Length, r.a)),
            num(units.from_si(Quantity::Angle, r.alpha)),
            num(units.from_si(Quantity::Length, r.d)),
            num(units.from_si(Quantity::Angle, r.theta))
        ));
        if with_beta {
            out.push_str(&format!(",{}", num(units.from_si(Quantity::Angle, r.beta))));
        }
        if with_names {
            out.push(',');
            out.push_str(&csv_field(names.get(k).copied().flatten().unwrap_or("")));
        }
        out.push('\n');
    }
    out
}

/// `text` as one CSV field: quoted (its quotes doubled) when it holds a comma, a quote or a line
/// break, or begins or ends with whitespace.
fn csv_field(text: &str) -> String {
    let plain = !text.contains([',', '"', '\n', '\r']) && text.trim() == text;
    if plain {
        text.to_string()
    } else {
        format!("\"{}\"", text.replace('"', "\"\""))
    }
}

/// A DH export: the table, its text, and what it reproduces of the robot.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct DhExport {
    /// The table.
    pub table: DhTable,
    /// Its text ([`write_dh_table`]).
    pub text: String,
    /// The text read back by [`import_dh`] and compared with the robot.
    pub read_back: ReadBack,
    /// What a DH table cannot hold (transducer slopes other than 1, couplings), each with the
    /// deviation it alone causes.
    pub lost: Vec<Lost>,
}

impl DhExport {
    /// The pairs of consecutive axes the table describes with the Hayati/Mooring `beta`, each
    /// as `2-3` (joints 2 and 3), `base-1` (the base z axis and joint 1) or `6-tool` (joint 6
    /// and the tool's z axis).
    pub fn hayati_pairs(&self) -> Vec<String> {
        let rows = &self.table.rows;
        let n = rows.iter().filter(|r| r.kind != RowKind::Fixed).count();
        let name = |k: usize| match k {
            0 => "base".to_string(),
            k if k > n => "tool".to_string(),
            k => k.to_string(),
        };
        // The joint number each row ends at (standard: the row of joint k ends on axis k + 1;
        // modified: on axis k), fixed rows before the first joint at 0, after the last at n + 1.
        let mut out = Vec::new();
        let mut joint = 0;
        for (i, r) in rows.iter().enumerate() {
            let fixed = r.kind == RowKind::Fixed;
            if !fixed {
                joint += 1;
            }
            if num(r.beta) == "0" {
                continue;
            }
            let (from, to) = match (self.table.convention, fixed) {
                (Convention::Standard, false) => (joint, joint + 1),
                (Convention::Modified, false) => (joint - 1, joint),
                (_, true) if i == 0 => (0, 1),
                (_, true) => (n, n + 1),
            };
            out.push(format!("{}-{}", name(from), name(to)));
        }
        out
    }

    /// What the table holds beyond classical DH, in sentences: the axes that took beta, the
    /// fixed rows.
    pub fn notes(&self) -> Vec<String> {
        let mut out = Vec::new();
        let pairs = self.hayati_pairs();
        if !pairs.is_empty() {
            out.push(format!(
                "beta (Hayati/Mooring) for the axes within 1 deg of parallel: {}",
                pairs.join(", ")
            ));
        }
        let (base, tool) = self.fixed_rows();
        if base || tool {
            out.push(format!(
                "fixed rows: {}",
                [
                    base.then_some(
                        "the base (the first DH frame is not the robot's global frame; for a \
                         robot calibrated in an instrument's frame it holds where the instrument \
                         saw the robot)",
                    ),
                    tool.then_some("the tool (the tool frame is not a DH frame of the last joint)"),
                ]
                .into_iter()
                .flatten()
                .collect::<Vec<_>>()
                .join("; ")
            ));
        }
        out
    }

    /// Whether the table has a fixed row before the first joint (the base) and after the last
    /// one (the tool).
    pub fn fixed_rows(&self) -> (bool, bool) {
        let rows = &self.table.rows;
        (
            rows.first().is_some_and(|r| r.kind == RowKind::Fixed),
            rows.last().is_some_and(|r| r.kind == RowKind::Fixed),
        )
    }

    /// `Ok` when the table, read back, reproduces the robot within `tolerance`
    /// ([`ReadBack::check`]).
    pub fn check(&self, robot: &Robot, tolerance: &Tolerance) -> Result<()> {
        self.read_back.check(
            tolerance,
            robot.units,
            "the DH table (its joint variables are the readings)",
            &self.lost,
        )
    }
}

/// `robot` as a DH table in `convention` and `units` (`dh_rows`, [`write_dh_table`]), read
/// back with [`import_dh`] (the units and convention the text states) and compared with the
/// robot over the joint ranges ([`readback`]): the table's joint variables are the readings,
/// converted from the robot file's units to the table's.
pub fn export_dh(robot: &Robot, convention: Convention, units: Units) -> Result<DhExport> {
    if robot.is_tree() {
        return Err(Error::Problem(format!(
            "{} is a tree (its joints branch): a DH table describes one serial chain; write the \
             tree into its URDF (`kinecal export urdf` with each --tip)",
            robot.name
        )));
    }
    let rows = dh_rows(robot, convention)?;
    // A joint row is the next joint's (the chain's joints in order), and carries its name.
    let mut joints = robot.joints.iter();
    let names: Vec<Option<&str>> = rows
        .iter()
        .map(|r| match r.kind {
            RowKind::Fixed => None,
            _ => joints.next().and_then(|j| j.name.as_deref()),
        })
        .collect();
    // `base` names the global frame in a table: a joint so named keeps `vK` columns.
    let names = if names.contains(&Some("base")) {
        Vec::new()
    } else {
        names
    };
    let text = write_named_dh_table(&rows, &names, units, convention);
    let back = import_dh(
        &text,
        "<the DH table written>",
        &robot.name,
        None,
        None,
        None,
    )?;
    let scale = readback::unit_scale(robot, units);
    let read_back = readback::compare(
        robot,
        &back,
        &|v, out| {
            for ((o, v), s) in out.iter_mut().zip(v).zip(&scale) {
                *o = v * s;
            }
        },
        None,
    );
    let lost = readback::gains_lost(robot, &|j| format!("joint {}", j + 1), &|_| false);
    Ok(DhExport {
        table: DhTable {
            rows,
            units,
            convention,
        },
        text,
        read_back,
        lost,
    })
}
