//! `compensate`: a program or Cartesian targets through the calibrated model, row by row, into
//! a table or a controller's program. The input streams through in flat memory.
//!
//! ```toml
//! job = "compensate"
//! robot = "calibrated.toml"       # how the robot really moves
//! nominal = "nominal.toml"        # what the controller uses
//! in = "program.csv"              # posture,v1..vn, or target,x,y,z[,alpha,beta,gamma]
//! format = "table"                # table, urscript, joints-ur|abb|kuka|fanuc, krl, rapid, tp
//! out = "compensated.csv"
//! ```
//!
//! A KRL, RAPID or TP program ([`Language`]) takes three more keys, refused with any other
//! format:
//!
//! ```toml
//! format = "krl"
//! out = "compensated.src"
//! name = "compensated"             # default: the output file's name without its extension
//! speed = 50                       # KRL, TP: percent (1..100); RAPID: speeddata vN (mm/s)
//! zone = 10                        # "fine" (default); KRL C_PTP %, RAPID zN (mm), TP CNTn
//! ```
//!
//! A program holds its moves in memory until the last row (a TP program's positions follow
//! its moves, and every program is read back before it is written: 48 bytes and the label
//! per row); tables and URScript stream through.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::apps::compensate::{
    goal_in_file_units, Compensator, Configuration, Goal, Options, Solved, TargetSearch,
};
use crate::error::{Error, Location, Result, Setting};
use crate::files::controller::{
    joint_field, read_program, urscript_begin, urscript_end, urscript_move, Brand, Language,
    Program, Zone,
};
use crate::files::stream::{cell, payload_at, payload_columns, Rows};
use crate::files::COMPENSATED_COLUMNS;
use crate::identifiability::fmt_sig;
use crate::model::kinematics::Target;
use crate::model::robot::Robot;
use crate::units::Quantity;

use super::common::{invalid, is_default, robot_as, visit_opt, LengthAngle};
use super::{Document, Done, Env, JobKind, Message, PathRole, Spec, Status};

/// What a compensation writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
#[non_exhaustive]
pub enum ProgramFormat {
    /// The readings with each row's remaining errors and flags.
    #[default]
    Table,
    /// A URScript program: one movej per row.
    Urscript,
    /// Joint targets in UR's convention (rad).
    JointsUr,
    /// Joint targets in ABB's convention (deg).
    JointsAbb,
    /// Joint targets in KUKA's convention (deg).
    JointsKuka,
    /// Joint targets in FANUC's convention (deg).
    JointsFanuc,
    /// A KUKA KRL program (.src): one PTP per row (deg).
    Krl,
    /// An ABB RAPID module: one MoveAbsJ per row (deg).
    Rapid,
    /// A FANUC TP program in ASCII (.ls): one joint move per row (deg).
    Tp,
}

impl ProgramFormat {
    /// The controller brand whose joint convention the format uses (none for the table).
    fn brand(self) -> Option<Brand> {
        match self {
            ProgramFormat::Table => None,
            ProgramFormat::Urscript | ProgramFormat::JointsUr => Some(Brand::Ur),
            ProgramFormat::JointsAbb => Some(Brand::Abb),
            ProgramFormat::JointsKuka => Some(Brand::Kuka),
            ProgramFormat::JointsFanuc => Some(Brand::Fanuc),
            ProgramFormat::Krl | ProgramFormat::Rapid | ProgramFormat::Tp => {
                self.language().map(Language::brand)
            }
        }
    }

    /// The language of a controller program (KRL, RAPID, TP).
    fn language(self) -> Option<Language> {
        match self {
            ProgramFormat::Krl => Some(Language::Krl),
            ProgramFormat::Rapid => Some(Language::Rapid),
            ProgramFormat::Tp => Some(Language::Tp),
            _ => None,
        }
    }
}

/// How a KRL, RAPID or TP program's moves end: `"fine"` (exactly at each point), or a number
/// ([`Language::zone`]: KRL `C_PTP` with `$APO.CPTP` percent, RAPID zonedata `zN` (mm), TP
/// `CNTn`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum ProgramZone {
    /// A number: the approximation's size in the language's measure.
    Size(f64),
    /// A word: `fine`.
    Named(String),
}

impl ProgramZone {
    /// `fine`, or a number.
    pub fn parse(text: &str) -> ProgramZone {
        match text.trim().parse::<f64>() {
            Ok(v) => ProgramZone::Size(v),
            Err(_) => ProgramZone::Named(text.trim().to_string()),
        }
    }

    /// The zone for `language`, or why it is not one.
    fn check(&self, language: Language) -> Result<Zone> {
        match self {
            ProgramZone::Named(n) if n.eq_ignore_ascii_case("fine") => Ok(Zone::Fine),
            ProgramZone::Named(n) => Err(invalid(
                Setting::Zone,
                format!(
                    "expected `fine` or a number (the {} zone), not `{n}`",
                    language.title()
                ),
            )),
            ProgramZone::Size(v) => language.zone(*v).map_err(|m| invalid(Setting::Zone, m)),
        }
    }
}

/// A compensation. See the [module documentation](self).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct CompensateSpec {
    /// The calibrated robot: how the robot really moves.
    #[serde(default)]
    pub robot: String,
    /// The nominal robot the controller uses (and the program was made with).
    #[serde(default)]
    pub nominal: String,
    /// The program (`posture,v1..vn`) or the targets (`target,x,y,z[,alpha,beta,gamma]...`;
    /// `-` for standard input).
    #[serde(default, rename = "in")]
    pub input: String,
    /// The frame that must reach the goal: `ee` (default) or a site. A program of a tree may
    /// name one tool per branch, comma-separated (`ee,LEFT_tool0`): each reaches its pose with
    /// its own branch's joints, the joints the branches share held at the program's readings.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub site: Option<String>,
    /// Reach the positions only.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub position_only: bool,
    /// Largest acceptable remaining error (robot file's units; default 1 um and 1 urad).
    #[serde(default, skip_serializing_if = "is_default")]
    pub tolerance: LengthAngle,
    /// Flag solutions whose weighted reading Jacobian has a smallest singular value below this
    /// fraction of its largest (default 1e-3).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub singular: Option<f64>,
    /// Flag a revolute joint that turns more than this from the seed (robot file's angle unit;
    /// default 0.5 rad).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub branch: Option<f64>,
    /// The configuration Cartesian targets must be in ([`Configuration::parse`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub configuration: Option<String>,
    /// What to write (default `table`).
    #[serde(default, skip_serializing_if = "is_default")]
    pub format: ProgramFormat,
    /// The name of a KRL, RAPID or TP program (default: the output file's name without its
    /// extension, `kinecal_program` on standard output; [`Language::program_name`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// The speed of a KRL, RAPID or TP program's moves ([`Language::speed`]; default 100: KRL
    /// and TP 100 %, RAPID `v100`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub speed: Option<f64>,
    /// How a KRL, RAPID or TP program's moves end (default `fine`; the last always does).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub zone: Option<ProgramZone>,
    /// The file to write (`-` for standard output).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub out: Option<String>,
}

impl Spec for CompensateSpec {
    const KIND: JobKind = JobKind::Compensate;

    fn visit_paths(&mut self, f: &mut dyn FnMut(PathRole, &mut String)) {
        f(PathRole::Robot, &mut self.robot);
        f(PathRole::Robot, &mut self.nominal);
        f(PathRole::Input, &mut self.input);
        visit_opt(f, PathRole::Output, &mut self.out);
    }
}

/// The counts of a compensation's rows and flags (the document), in the robot file's units.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
#[non_exhaustive]
pub struct CompensationSummary {
    /// Rows compensated.
    #[serde(default)]
    pub rows: usize,
    /// Rows with a flag.
    #[serde(default)]
    pub flagged: usize,
    /// Rows out of reach.
    #[serde(default)]
    pub unreachable: usize,
    /// Rows outside a joint range.
    #[serde(default)]
    pub out_of_range: usize,
    /// Rows near a singularity.
    #[serde(default)]
    pub singular: usize,
    /// Rows that change configuration.
    #[serde(default)]
    pub branch: usize,
    /// Rows not in the configuration asked for (with one).
    pub configuration: Option<usize>,
    /// The largest remaining position error.
    pub worst_position: f64,
    /// The largest remaining attitude error.
    pub worst_attitude: f64,
    /// The robot file's length unit.
    #[serde(default)]
    pub length_unit: String,
    /// Its angle unit.
    #[serde(default)]
    pub angle_unit: String,
    /// The first flagged row's label and flags.
    pub first_flagged: Option<(String, String)>,
    /// Whether the output was written (a controller program is not when a row is flagged).
    pub written: bool,
}

impl CompensationSummary {
    fn add(&mut self, s: &Solved, label: &str) {
        self.rows += 1;
        let f = &s.flags;
        if f.any() {
            if self.flagged == 0 {
                self.first_flagged = Some((label.to_string(), f.describe()));
            }
            self.flagged += 1;
        }
        if let Some(c) = &mut self.configuration {
            *c += f.configuration as usize;
        }
        self.unreachable += f.unreachable as usize;
        self.out_of_range += (f.out_of_range != 0) as usize;
        self.singular += f.singular as usize;
        self.branch += f.branch as usize;
        self.worst_position = self.worst_position.max(s.position_error);
        self.worst_attitude = self.worst_attitude.max(s.attitude_error.unwrap_or(0.0));
    }

    /// `12 rows: 0 flagged (...); largest remaining error 3.1e-7 mm`.
    pub fn sentence(&self) -> String {
        format!(
            "{} row{}: {} flagged ({} unreachable, {} outside a joint range, {} near a \
             singularity, {} changing configuration{}); largest remaining error {} {}{}",
            self.rows,
            if self.rows == 1 { "" } else { "s" },
            self.flagged,
            self.unreachable,
            self.out_of_range,
            self.singular,
            self.branch,
            self.configuration
                .map(|c| format!(", {c} not in the configuration"))
                .unwrap_or_default(),
            fmt_sig(self.worst_position),
            self.length_unit,
            if self.worst_attitude > 0.0 {
                format!(", {} {}", fmt_sig(self.worst_attitude), self.angle_unit)
            } else {
                String::new()
            }
        )
    }
}

/// A finished compensation.
#[derive(Debug)]
#[non_exhaustive]
pub struct CompensateOutcome {
    /// The document.
    pub summary: CompensationSummary,
}

/// Columns of a measurement file that do not say where to go (read past when one is the
/// targets).
const MEASUREMENT_EXTRAS: [&str; 6] = [
    "sigma_position",
    "sigma_angle",
    "sigma_x",
    "sigma_y",
    "sigma_z",
    "session",
];

/// What the input file holds.
enum Kind {
    /// `posture,v1..vn`.
    Program { readings: Vec<usize> },
    /// `target[,site],x,y,z[,alpha,beta,gamma][,v1..vn]`, or a measurement file
    /// (`posture[,site],v1..vn,x,y,z[,alpha,beta,gamma]`, its standard deviations and session
    /// ignored).
    Targets(TargetColumns),
}

/// The columns of a targets file.
struct TargetColumns {
    label: usize,
    /// A measurement file: its goal columns are written back with the solution (so that the
    /// output is a measurement file of where the robot must be).
    goal: Option<Vec<usize>>,
    site: Option<usize>,
    xyz: [usize; 3],
    euler: Option<[usize; 3]>,
    seed: Option<Vec<usize>>,
}

/// An error in the header of `rows`.
fn header_error(rows: &Rows, message: impl Into<String>) -> Error {
    Error::input(Location::file(&rows.file).at_line(1), message)
}

/// Tells the layout from the header.
fn kind(rows: &Rows, robot: &Robot) -> Result<Kind> {
    let dof = robot.dof();
    // `vK`, or the joint's name (a tree's, a URDF's); other joints' columns read past.
    let mut own = vec![
        "target", "posture", "site", "x", "y", "z", "alpha", "beta", "gamma",
    ];
    own.extend(MEASUREMENT_EXTRAS);
    own.extend(crate::files::PAYLOAD_COLUMNS);
    let found = crate::files::ReadingColumns::of(robot, &rows.spelled, &own);
    if rows.column("x").is_none() {
        // A program: its readings' unit.
        found.check_brand_clash(robot, &rows.file)?;
    }
    found.note(&rows.file, robot);
    let columns = &found.names;
    let readings: Option<Vec<usize>> = columns.iter().map(|c| rows.column(c)).collect();
    let reading = |h: &str| columns.iter().any(|c| c.eq_ignore_ascii_case(h)) || found.is_other(h);
    let known = |extra: &[&str]| {
        rows.header
            .iter()
            .find(|h| !(extra.contains(&h.as_str()) || reading(h)))
            .cloned()
    };
    let label = rows.column("target").or_else(|| rows.column("posture"));
    if let (Some(label), true) = (
        label,
        rows.column("x").is_some() || rows.column("target").is_some(),
    ) {
        let (Some(x), Some(y), Some(z)) = (rows.column("x"), rows.column("y"), rows.column("z"))
        else {
            return Err(header_error(
                rows,
                format!(
                    "a targets file needs the columns target,x,y,z (and optionally site, \
                     alpha,beta,gamma and seed readings v1..v{dof})"
                ),
            ));
        };
        let euler = match (
            rows.column("alpha"),
            rows.column("beta"),
            rows.column("gamma"),
        ) {
            (Some(a), Some(b), Some(g)) => Some([a, b, g]),
            (None, None, None) => None,
            _ => return Err(header_error(rows, "give all of alpha,beta,gamma or none")),
        };
        let measured = rows.header[label] == "posture";
        if measured && readings.is_none() {
            return Err(header_error(
                rows,
                format!("a measurement file as targets needs its readings v1..v{dof} (the seeds)"),
            ));
        }
        let ignored: &[&str] = if measured { &MEASUREMENT_EXTRAS } else { &[] };
        let mut allowed = vec![
            "target", "posture", "site", "x", "y", "z", "alpha", "beta", "gamma",
        ];
        allowed.extend(ignored);
        allowed.extend(crate::files::PAYLOAD_COLUMNS);
        if let Some(h) = known(&allowed) {
            return Err(header_error(
                rows,
                format!("unexpected column `{h}` in a targets file"),
            ));
        }
        let any_v = rows.header.iter().any(|h| h.starts_with('v'));
        if any_v && readings.is_none() {
            return Err(header_error(
                rows,
                format!("seed readings need every column v1..v{dof}"),
            ));
        }
        let goal = measured.then(|| {
            ["x", "y", "z", "alpha", "beta", "gamma"]
                .iter()
                .filter_map(|c| rows.column(c))
                .collect()
        });
        return Ok(Kind::Targets(TargetColumns {
            label,
            goal,
            site: rows.column("site"),
            xyz: [x, y, z],
            euler,
            seed: readings,
        }));
    }
    match (rows.column("posture"), readings) {
        (Some(_), Some(readings)) => {
            let mut allowed = vec!["posture"];
            allowed.extend(crate::files::PAYLOAD_COLUMNS);
            if let Some(h) = known(&allowed) {
                return Err(header_error(
                    rows,
                    format!("unexpected column `{h}` in a program (posture,v1..v{dof})"),
                ));
            }
            Ok(Kind::Program { readings })
        }
        _ => Err(header_error(
            rows,
            format!(
                "expected a program (posture,v1,...,v{dof}) or targets (target,x,y,z[,alpha,\
                 beta,gamma][,v1..v{dof}]), found `{}`",
                rows.header.join(",")
            ),
        )),
    }
}

/// A write error of the output `path`.
fn write_error(path: &Path, e: impl std::fmt::Display) -> Error {
    Error::Io {
        path: path.display().to_string(),
        cause: std::io::Error::other(e.to_string()),
    }
}

/// Where the rows go: a CSV table or a program's text.
enum Sink<W: std::io::Write> {
    Csv(Box<csv::Writer<W>>),
    Text(W),
}

impl<W: std::io::Write> Sink<W> {
    fn record(&mut self, fields: &[String]) -> std::io::Result<()> {
        match self {
            Sink::Csv(w) => w.write_record(fields).map_err(std::io::Error::other),
            Sink::Text(_) => unreachable!("a program is text"),
        }
    }

    fn text(&mut self, text: &str) -> std::io::Result<()> {
        match self {
            Sink::Text(w) => w.write_all(text.as_bytes()),
            Sink::Csv(_) => unreachable!("a table is CSV"),
        }
    }

    fn finish(self) -> std::io::Result<()> {
        let mut inner = match self {
            Sink::Csv(w) => w
                .into_inner()
                .map_err(|e| std::io::Error::other(e.to_string()))?,
            Sink::Text(w) => w,
        };
        inner.flush()
    }
}

/// How the rows are written.
struct Writer<'r> {
    format: ProgramFormat,
    robot: &'r Robot,
    source: String,
    brand: Option<Brand>,
    joints: Vec<f64>,
    /// A KRL, RAPID or TP program: its moves so far, and their labels.
    program: Option<(Program, Vec<String>)>,
}

impl<'r> Writer<'r> {
    /// A writer of `format` for `robot`'s rows from `input`; `program`: the (empty) program
    /// of a KRL, RAPID or TP format ([`CompensateSpec::program`]).
    fn new(
        format: ProgramFormat,
        robot: &'r Robot,
        input: &str,
        program: Option<Program>,
    ) -> Result<Self> {
        let brand = format.brand();
        if let Some(b) = brand {
            b.columns(robot)?;
        }
        if let Some(l) = format.language() {
            l.check_robot(robot)?;
        }
        Ok(Writer {
            format,
            robot,
            source: input.to_string(),
            brand,
            joints: vec![0.0; robot.dof()],
            program: program.map(|p| (p, Vec::new())),
        })
    }

    /// The opening comment of a KRL, RAPID or TP program.
    fn header(&self, language: Language) -> Vec<String> {
        let axes = match language {
            Language::Krl => "A1..A6",
            Language::Rapid => "rax_1..rax_6",
            Language::Tp => "J1..J6",
        };
        vec![
            format!(
                "compensated joint targets for {} from {}, written by kinecal {}",
                self.robot.name,
                self.source,
                env!("CARGO_PKG_VERSION")
            ),
            format!(
                "{axes} (deg) are joints 1 to 6 of the robot file, taken as the axes of the \
                 controller"
            ),
        ]
    }

    /// Reads the program written to `written` back with kinecal's reader of its language: an
    /// error (nothing is written) unless it gives what was meant, to the written decimals.
    fn read_back(&self, written: &Path, out: &Path) -> Result<()> {
        let Some((program, _)) = &self.program else {
            return Ok(());
        };
        let title = program.language.title();
        let text = std::fs::read_to_string(written).map_err(|e| write_error(out, e))?;
        let refuse = |m: String| Error::Output {
            path: out.display().to_string(),
            message: format!("the {title} program, read back, {m}: nothing written"),
        };
        let read = read_program(program.language, &text, &out.display().to_string())
            .map_err(|e| refuse(format!("does not read: {e}")))?;
        match program.differs(&read) {
            Some(d) => Err(refuse(format!("differs from what was meant: {d}"))),
            None => Ok(()),
        }
    }

    fn sink<W: std::io::Write>(&self, w: W) -> Sink<W> {
        if self.format == ProgramFormat::Urscript || self.program.is_some() {
            Sink::Text(w)
        } else {
            Sink::Csv(Box::new(csv::Writer::from_writer(w)))
        }
    }

    fn is_controller(&self) -> bool {
        self.format != ProgramFormat::Table
    }

    fn begin<W: std::io::Write>(
        &self,
        w: &mut Sink<W>,
        first: &str,
        site: bool,
        goal: &[String],
    ) -> Result<std::io::Result<()>> {
        let dof = self.robot.dof();
        let mut header = vec![first.to_string()];
        match (self.format, self.brand) {
            (ProgramFormat::Table, _) => {
                if site {
                    header.push("site".into());
                }
                header.extend((1..=dof).map(|j| format!("v{j}")));
                header.extend(goal.iter().cloned());
                header.extend(COMPENSATED_COLUMNS.map(String::from));
            }
            (ProgramFormat::Urscript, _) => {
                return Ok(w.text(&urscript_begin(self.robot, &self.source)));
            }
            // A program is written whole at the end.
            (ProgramFormat::Krl | ProgramFormat::Rapid | ProgramFormat::Tp, _) => {
                return Ok(Ok(()));
            }
            (_, Some(brand)) => {
                if site {
                    header.push("site".into());
                }
                header.extend(brand.columns(self.robot)?);
            }
            (_, None) => unreachable!("every controller format has a brand"),
        }
        Ok(w.record(&header))
    }

    #[allow(clippy::too_many_arguments)]
    fn row<W: std::io::Write>(
        &mut self,
        w: &mut Sink<W>,
        fields: &mut Vec<String>,
        label: &str,
        site: Option<String>,
        out: &[f64],
        goal: &[String],
        solved: &Solved,
    ) -> std::io::Result<()> {
        let units = self.robot.units;
        fields.clear();
        fields.push(label.to_string());
        match (self.format, self.brand) {
            (ProgramFormat::Table, _) => {
                fields.extend(site);
                fields.extend(out.iter().map(|v| v.to_string()));
                fields.extend(goal.iter().cloned());
                fields.push(format!(
                    "{:.6e}",
                    units.from_si(Quantity::Length, solved.position_error)
                ));
                fields.push(solved.attitude_error.map_or(String::new(), |e| {
                    format!("{:.6e}", units.from_si(Quantity::Angle, e))
                }));
                fields.push(solved.iterations.to_string());
                fields.push(solved.flags.describe());
            }
            (ProgramFormat::Urscript, _) => {
                Brand::Ur.values(self.robot, out, &mut self.joints);
                let text = match site {
                    Some(s) => format!("{label} ({s})"),
                    None => label.to_string(),
                };
                return w.text(&urscript_move(&text, &self.joints));
            }
            (ProgramFormat::Krl | ProgramFormat::Rapid | ProgramFormat::Tp, Some(brand)) => {
                brand.values(self.robot, out, &mut self.joints);
                if let Some((program, labels)) = &mut self.program {
                    let mut axes = [0.0; 6];
                    axes.copy_from_slice(&self.joints[..6]);
                    program.points.push(axes);
                    labels.push(match site {
                        Some(s) => format!("{label} ({s})"),
                        None => label.to_string(),
                    });
                }
                return Ok(());
            }
            (_, Some(brand)) => {
                brand.values(self.robot, out, &mut self.joints);
                fields.extend(site);
                fields.extend(self.joints.iter().map(|&v| joint_field(v)));
            }
            (_, None) => unreachable!("every controller format has a brand"),
        }
        w.record(fields)
    }

    fn end<W: std::io::Write>(&self, w: &mut Sink<W>) -> std::io::Result<()> {
        if self.format == ProgramFormat::Urscript {
            w.text(urscript_end())?;
        }
        if let Some((program, labels)) = &self.program {
            w.text(&program.text(&self.header(program.language), labels))?;
        }
        Ok(())
    }
}

impl CompensateSpec {
    /// The solver options of the spec for `nominal` (file units converted): the one
    /// translation, for files and for Python's arrays.
    pub fn options(&self, nominal: &Robot) -> Result<Options> {
        let mut options = Options::default();
        self.tolerance.check(Setting::Tolerance, true)?;
        let (l, a) = self.tolerance.si(nominal);
        if let Some(l) = l {
            options.position_tolerance = l;
        }
        if let Some(a) = a {
            options.attitude_tolerance = a;
        }
        if let Some(s) = self.singular {
            if !(0.0..1.0).contains(&s) {
                return Err(invalid(
                    Setting::Singular,
                    format!("expected a fraction from 0 to below 1, not {s}"),
                ));
            }
            options.singular = s;
        }
        if let Some(b) = self.branch {
            if !(b.is_finite() && b > 0.0) {
                return Err(invalid(
                    Setting::Branch,
                    format!("expected a positive angle, not {b}"),
                ));
            }
            options.branch = nominal.units.to_si(Quantity::Angle, b);
        }
        Ok(options)
    }

    /// The empty program of a KRL, RAPID or TP format, its name, speed and zone checked (the
    /// name by default `out`'s without its extension); `None` for another format, which
    /// refuses a name, speed or zone.
    pub fn program(&self, out: &str) -> Result<Option<Program>> {
        let Some(language) = self.format.language() else {
            for (given, setting) in [
                (self.name.is_some(), Setting::ProgramName),
                (self.speed.is_some(), Setting::Speed),
                (self.zone.is_some(), Setting::Zone),
            ] {
                if given {
                    return Err(invalid(
                        setting,
                        "is for a controller program: format krl, rapid or tp",
                    ));
                }
            }
            return Ok(None);
        };
        let speed = match self.speed {
            Some(v) => language.speed(v).map_err(|m| invalid(Setting::Speed, m))?,
            None => language.default_speed(),
        };
        let zone = match &self.zone {
            Some(z) => z.check(language)?,
            None => Zone::Fine,
        };
        // The file's own name, unless the output is standard output or a device; through a
        // symbolic link, the name of the file written (the link's target).
        let path = Path::new(out);
        let resolved = path.is_symlink().then(|| {
            std::fs::canonicalize(path).unwrap_or_else(|_| {
                // A link to a file not made yet: its target, beside the link when relative.
                let target = std::fs::read_link(path).unwrap_or_else(|_| path.into());
                path.parent().map_or(target.clone(), |d| d.join(&target))
            })
        });
        let shown = match &resolved {
            Some(r) => format!("{out} (a link to {})", r.display()),
            None => out.to_string(),
        };
        let path = resolved.as_deref().unwrap_or(path);
        let device = out == "-" || path.starts_with("/dev") || path.starts_with("/proc");
        let stem = (!device)
            .then(|| path.file_stem().and_then(|s| s.to_str()))
            .flatten();
        let name = match (&self.name, stem) {
            (Some(n), stem) => {
                let name = language
                    .program_name(n)
                    .map_err(|m| invalid(Setting::ProgramName, m))?;
                if let (Language::Krl, Some(stem)) = (language, stem) {
                    if !stem.eq_ignore_ascii_case(&name) {
                        return Err(invalid(
                            Setting::ProgramName,
                            format!(
                                "`{name}` is not the name of {shown}: a KRL module's DEF names \
                                 its file (write it to {name}.src, or leave the name out)"
                            ),
                        ));
                    }
                }
                name
            }
            (None, Some(stem)) => language.program_name(stem).map_err(|m| {
                invalid(
                    Setting::ProgramName,
                    format!(
                        "the program is named after its file {shown}: {m}; {}",
                        if language == Language::Krl {
                            "name the file so (a KRL module's DEF names its file)"
                        } else {
                            "give the program a name"
                        }
                    ),
                )
            })?,
            (None, None) => language
                .program_name("kinecal_program")
                .unwrap_or_else(|_| "KINECAL_PROGRAM".into()),
        };
        Ok(Some(Program::new(language, name, speed, zone)))
    }

    /// The configuration Cartesian targets must be in, when the spec gives one.
    pub fn configuration(&self) -> Result<Option<Configuration>> {
        self.configuration
            .as_deref()
            .map(Configuration::parse)
            .transpose()
    }

    /// The frames the rows reach: the site named (the end effector by default), or a tree's
    /// tools, one per branch, comma-separated (a program's; see
    /// [`Compensator::program_tools`]).
    pub fn tools(&self, robot: &Robot) -> Result<Vec<Target>> {
        let names = self.site.as_deref().unwrap_or("ee");
        let mut tools: Vec<Target> = Vec::new();
        for name in names.split(',').map(str::trim) {
            if name.is_empty() && names.contains(',') {
                return Err(invalid(
                    Setting::Site,
                    format!("`{names}`: an empty name in the list of tools"),
                ));
            }
            let t =
                crate::files::site_target(robot, name).map_err(|m| invalid(Setting::Site, m))?;
            if let Some(&u) = tools
                .iter()
                .find(|&&u| crate::apps::compensate::on_one_branch(robot, t, u))
            {
                return Err(invalid(
                    Setting::Site,
                    format!(
                        "{name} and {} lie on one branch (one moves the other, or they are \
                         the same frame): a program reaches one tool per branch of a tree",
                        crate::observe::target_name(robot, u)
                    ),
                ));
            }
            tools.push(t);
        }
        Ok(tools)
    }

    /// Reads the robots and the input, compensates row by row and writes the output.
    pub(crate) fn run(&self, env: &mut Env<'_>) -> Result<Done> {
        let (calibrated, _) = robot_as(&self.robot, Setting::Robot)?;
        let (nominal, _) = robot_as(&self.nominal, Setting::NominalRobot)?;
        let out = self
            .out
            .as_deref()
            .ok_or_else(|| invalid(Setting::Output, "no output file given"))?;
        let options = self.options(&nominal)?;
        let tools = self.tools(&nominal)?;
        let default_target = tools[0];
        let comp = Compensator::new(&calibrated, &nominal, options).map_err(|e| {
            invalid(
                Setting::NominalRobot,
                format!("robot {} and nominal {}: {e}", self.robot, self.nominal),
            )
        })?;
        if self.input.is_empty() {
            return Err(invalid(Setting::Input, "no program or targets given"));
        }
        let mut rows = Rows::open(Path::new(&self.input))?;
        let kind = kind(&rows, &nominal)?;
        if tools.len() > 1 && !matches!(kind, Kind::Program { .. }) {
            return Err(invalid(
                Setting::Site,
                format!(
                    "{} names several tools: a list is for a program of a tree (a target \
                     row's frame is its site column's, else one --site)",
                    self.site.as_deref().unwrap_or_default()
                ),
            ));
        }
        if matches!(kind, Kind::Program { .. }) {
            note_tools_left_as_programmed(&nominal, &tools);
        }
        // What the tool carries at each row: the elastic robot yields to it, and the output
        // keeps the columns so that `fk` and `check` see the same load.
        let payload = payload_columns(&rows)?;
        let search = self.target_search(&calibrated, &nominal, options, &kind)?;
        let program = self.program(out)?;
        let mut writer = Writer::new(self.format, &nominal, &self.input, program)?;
        let units = nominal.units;
        let mut tally = CompensationSummary {
            length_unit: units.length.to_string(),
            angle_unit: units.angle.to_string(),
            configuration: search.configuration().map(|_| 0),
            ..CompensationSummary::default()
        };
        let mut solver = RowSolver {
            nominal: &nominal,
            payload,
            default_target,
            tools,
            position_only: self.position_only,
            comp,
            search,
            seed: vec![0.0; nominal.dof()],
            solution: vec![0.0; nominal.dof()],
            goal_fields: Vec::new(),
        };
        env.progress.say("compensating");
        let mut staged = crate::files::output::Staged::new();
        staged.by_path(Path::new(out), |tmp| -> Result<()> {
            let file = std::io::BufWriter::new(
                std::fs::File::create(tmp).map_err(|e| write_error(Path::new(out), e))?,
            );
            let mut w = writer.sink(file);
            compensate_rows(
                &mut w,
                &mut writer,
                &mut rows,
                &kind,
                &mut solver,
                &mut tally,
                Path::new(out),
            )?;
            writer
                .end(&mut w)
                .and_then(|()| w.finish())
                .map_err(|e| write_error(Path::new(out), e))?;
            writer.read_back(tmp, Path::new(out))
        })?;
        if tally.rows == 0 {
            return Err(Error::input(Location::file(&rows.file), "no rows"));
        }
        tally.worst_position = units.from_si(Quantity::Length, tally.worst_position);
        tally.worst_attitude = units.from_si(Quantity::Angle, tally.worst_attitude);
        let (messages, status) = conclude(&mut tally, writer.is_controller(), staged, &kind, out)?;
        Ok(Done {
            document: Document::Compensation(Box::new(CompensateOutcome { summary: tally })),
            messages,
            status,
            pending: None,
        })
    }

    /// The search of Cartesian targets, in the spec's configuration when it gives one (which a
    /// program's readings refuse: they keep their own).
    fn target_search<'r>(
        &self,
        calibrated: &'r Robot,
        nominal: &'r Robot,
        options: Options,
        kind: &Kind,
    ) -> Result<TargetSearch<'r>> {
        let mut search = TargetSearch::new(calibrated, nominal, options)
            .map_err(|e| invalid(Setting::Robot, format!("{}: {e}", self.robot)))?;
        if let Some(c) = self.configuration()? {
            if matches!(kind, Kind::Program { .. }) {
                return Err(invalid(
                    Setting::Configuration,
                    "the configuration is for Cartesian targets; a program's readings keep their \
                     own",
                ));
            }
            search = search.with_configuration(c)?;
        }
        Ok(search)
    }
}

/// Writes the output's header, then compensates the input row by row into it (the output
/// `out`), counting in `tally`.
fn compensate_rows<W: std::io::Write>(
    w: &mut Sink<W>,
    writer: &mut Writer<'_>,
    rows: &mut Rows,
    kind: &Kind,
    solver: &mut RowSolver<'_>,
    tally: &mut CompensationSummary,
    out: &Path,
) -> Result<()> {
    let (first, site_column, goal_columns) = output_columns(rows, kind, &solver.payload);
    writer
        .begin(w, &first, site_column, &goal_columns)?
        .map_err(|e| write_error(out, e))?;
    let mut fields: Vec<String> = Vec::with_capacity(solver.nominal.dof() + 6);
    while let Some(line) = rows.advance()? {
        let (label, site, solved) = solver.solve_row(rows, line, kind)?;
        tally.add(&solved, &label);
        writer
            .row(
                w,
                &mut fields,
                &label,
                site,
                &solver.solution,
                &solver.goal_fields,
                &solved,
            )
            .map_err(|e| write_error(out, e))?;
    }
    Ok(())
}

/// The output's first column (`posture`, or the targets' label), whether it has a site column,
/// and the input's columns written back after the solution: a measurement file's goal, then
/// the payload.
fn output_columns(
    rows: &Rows,
    kind: &Kind,
    payload: &[Option<usize>; 4],
) -> (String, bool, Vec<String>) {
    let (first, site_column, mut goal_columns) = match kind {
        Kind::Program { .. } => ("posture", false, Vec::new()),
        Kind::Targets(t) => (
            rows.header[t.label].as_str(),
            t.site.is_some(),
            t.goal
                .iter()
                .flatten()
                .map(|&c| rows.header[c].clone())
                .collect::<Vec<_>>(),
        ),
    };
    goal_columns.extend(payload.iter().flatten().map(|&c| rows.header[c].clone()));
    (first.to_string(), site_column, goal_columns)
}

/// How the run ends: a controller program with a flagged row is not written (it would move
/// the robot somewhere else), anything else is committed; with what to say of it.
fn conclude(
    tally: &mut CompensationSummary,
    controller: bool,
    staged: crate::files::output::Staged,
    kind: &Kind,
    out: &str,
) -> Result<(Vec<Message>, Status)> {
    let summary = tally.sentence();
    let mut messages = Vec::new();
    let status = if controller && tally.flagged > 0 {
        // A controller program with a row left out or wrong moves the robot somewhere else.
        drop(staged);
        let (label, flags) = tally.first_flagged.clone().unwrap_or_default();
        messages.push(Message::Caution(format!(
            "compensated {summary}\nnothing written to {out}: a controller program needs \
             every row usable (first flagged: {} {label}: {flags}); format table writes \
             every row with its flags",
            if matches!(kind, Kind::Program { .. }) {
                "posture"
            } else {
                "target"
            },
        )));
        Status::Flagged
    } else {
        staged.commit()?;
        tally.written = true;
        messages.push(Message::Note(format!("compensated {summary} into {out}")));
        if tally.flagged > 0 {
            Status::Flagged
        } else {
            Status::Ok
        }
    };
    Ok((messages, status))
}

/// Joint `j`'s (0-based) name, else its reading column `v{j+1}`.
fn joint_name(robot: &Robot, j: usize) -> String {
    robot.joints[j]
        .name
        .clone()
        .unwrap_or_else(|| format!("v{}", j + 1))
}

/// On a tree, a program that reaches some tools and leaves another branch's tool as
/// programmed says so, with the joints held and how to name every tool.
fn note_tools_left_as_programmed(robot: &Robot, tools: &[Target]) {
    let held: u64 = tools.iter().fold(0, |h, &t| {
        h | crate::apps::compensate::shared_joints(robot, t)
    });
    if held == 0 {
        return;
    }
    // A tool on each branch no tool named reaches: the end effector, else the first site there.
    let mut others: Vec<Target> = Vec::new();
    let candidates = std::iter::once(Target::EndEffector);
    for t in candidates.chain((0..robot.sites.len()).map(Target::Site)) {
        let on = |u: &Target| crate::apps::compensate::on_one_branch(robot, t, *u);
        if !tools.iter().chain(&others).any(on) {
            others.push(t);
        }
    }
    let names = |ts: &[Target]| -> Vec<&str> {
        ts.iter()
            .map(|&t| crate::observe::target_name(robot, t))
            .collect()
    };
    let (reached, others) = (names(tools), names(&others));
    let all = [reached.clone(), others.clone()].concat();
    let joints: Vec<String> = (0..robot.dof())
        .filter(|j| held & (1 << j) != 0)
        .map(|j| joint_name(robot, j))
        .collect();
    if others.is_empty() {
        crate::files::note(format!(
            "a tree: the program reaches {} each with its own branch's joints; {} (shared by \
             the branches) {} at the program's readings",
            reached.join(", "),
            joints.join(", "),
            if joints.len() == 1 { "stays" } else { "stay" }
        ));
    } else {
        crate::files::note(format!(
            "a tree: the program reaches {} with its own branch's joints; {} (shared with \
             another branch) {} at the program's readings and {} {} left as programmed: name \
             every tool to compensate {} too (--site {})",
            reached.join(", "),
            joints.join(", "),
            if joints.len() == 1 { "stays" } else { "stay" },
            others.join(", "),
            if others.len() == 1 { "is" } else { "are" },
            if others.len() == 1 { "it" } else { "them" },
            all.join(",")
        ));
    }
}

/// What compensates one row after another: the solvers of programs and targets, the input's
/// payload columns and the row's buffers.
struct RowSolver<'r> {
    nominal: &'r Robot,
    payload: [Option<usize>; 4],
    /// Where a row without a site column aims (the spec's site, else the end effector).
    default_target: Target,
    /// What a program's rows reach: the default target, or a tree's tools, one per branch.
    tools: Vec<Target>,
    position_only: bool,
    comp: Compensator<'r>,
    search: TargetSearch<'r>,
    seed: Vec<f64>,
    /// The row's solution: the readings to command.
    solution: Vec<f64>,
    /// The input's fields written back with the row: a measurement file's goal, the payload.
    goal_fields: Vec<String>,
}

impl RowSolver<'_> {
    /// Compensates the row at `line` under its payload: its label, its site and how it was
    /// solved, the readings in `self.solution`.
    fn solve_row(
        &mut self,
        rows: &Rows,
        line: u64,
        kind: &Kind,
    ) -> Result<(String, Option<String>, Solved)> {
        let payload = payload_at(rows, line, &self.payload, &self.nominal.units)?;
        self.comp.set_payload(payload);
        self.search.set_payload(payload);
        self.goal_fields.clear();
        let solved = match kind {
            Kind::Program { readings } => self.program_row(rows, line, readings)?,
            Kind::Targets(t) => self.target_row(rows, line, t)?,
        };
        self.goal_fields.extend(
            self.payload
                .iter()
                .flatten()
                .map(|&c| rows.field(c).to_string()),
        );
        Ok(solved)
    }

    /// A program's row: its commanded readings, compensated.
    fn program_row(
        &mut self,
        rows: &Rows,
        line: u64,
        readings: &[usize],
    ) -> Result<(String, Option<String>, Solved)> {
        for (s, &c) in self.seed.iter_mut().zip(readings) {
            *s = cell(rows, line, c)?;
        }
        let col = rows.column("posture").expect("checked");
        let solved = self.comp.program_tools(
            &self.seed,
            &self.tools,
            self.position_only,
            &mut self.solution,
        );
        Ok((rows.field(col).to_string(), None, solved))
    }

    /// A Cartesian target's row: the readings that put its site at its goal, from its seed
    /// readings when it gives them.
    fn target_row(
        &mut self,
        rows: &Rows,
        line: u64,
        t: &TargetColumns,
    ) -> Result<(String, Option<String>, Solved)> {
        let target = match t.site {
            Some(c) => crate::files::site_target(self.nominal, rows.field(c)).map_err(|m| {
                Error::input(
                    Location::file(&rows.file)
                        .at_line(line as usize)
                        .with_field("site"),
                    m,
                )
            })?,
            None => self.default_target,
        };
        let goal = self.goal(rows, line, t)?;
        let given = match &t.seed {
            Some(cols) => {
                for (s, &c) in self.seed.iter_mut().zip(cols) {
                    *s = cell(rows, line, c)?;
                }
                Some(self.seed.as_slice())
            }
            None => None,
        };
        let s = self.search.solve(&goal, target, given, &mut self.solution);
        self.goal_fields
            .extend(t.goal.iter().flatten().map(|&c| rows.field(c).to_string()));
        Ok((
            rows.field(t.label).to_string(),
            t.site.map(|c| rows.field(c).to_string()),
            s,
        ))
    }

    /// The row's goal: its position, with its attitude when it gives one and attitudes are
    /// goals.
    fn goal(&self, rows: &Rows, line: u64, t: &TargetColumns) -> Result<Goal> {
        let mut v = [0.0; 3];
        for (k, &c) in t.xyz.iter().enumerate() {
            v[k] = cell(rows, line, c)?;
        }
        // A measurement file's position rows leave the three angles empty; with
        // `position_only` the attitudes are not goals.
        let euler = match t
            .euler
            .filter(|e| !self.position_only && e.iter().any(|&c| !rows.field(c).is_empty()))
        {
            Some(e) => {
                let mut r = [0.0; 3];
                for (k, &c) in e.iter().enumerate() {
                    r[k] = cell(rows, line, c)?;
                }
                Some(r)
            }
            None => None,
        };
        goal_in_file_units(self.nominal, v, euler).map_err(|p| {
            super::predict::goal_error(
                &p,
                &rows.file,
                line,
                &format!("target {}", rows.field(t.label)),
            )
        })
    }
}
