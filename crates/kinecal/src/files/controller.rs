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
//!
//! KUKA KRL, ABB RAPID and FANUC TP programs ([`Language`], [`Program`]) are one joint move per
//! row in degrees with six decimals ([`PROGRAM_DECIMALS`]: the controllers keep joint values
//! as single-precision floats, 1.5e-5 deg at 180 deg, so a seventh decimal would be dropped
//! there), their speed and zone checked against what each controller takes
//! ([`Language::speed`], [`Language::zone`]) and their name against its identifiers
//! ([`Language::program_name`]: refused, never silently changed, except TP's capitals). Each
//! is read back by [`read_program`] before it is written and must give every value within
//! half a unit of the sixth decimal ([`PROGRAM_READ_BACK`]).

use crate::error::{Error, Location, Result, Setting};
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
    /// Every brand.
    pub const ALL: [Brand; 4] = [Brand::Ur, Brand::Abb, Brand::Kuka, Brand::Fanuc];

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
                    "joint {} is prismatic: the {} joint targets hold angles only",
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

    /// A joint value in the brand's unit as a reading of `robot` (the robot file's angle
    /// unit): what [`Brand::values`] wrote, read back.
    pub fn reading(self, robot: &Robot, value: f64) -> f64 {
        let si = match self.angle_unit() {
            AngleUnit::Rad => value,
            AngleUnit::Deg => value.to_radians(),
        };
        robot.units.from_si(Quantity::Angle, si)
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

/// The decimals of a degree in a KRL, RAPID or TP program: 1e-6 deg, finer than the controllers
/// keep (their joint values are single-precision floats, KRL `REAL`, RAPID `num`, FANUC
/// positions: 24 bits, 1.5e-5 deg at 180 deg) and, at a 2 m reach, 35 nm at the tool.
pub const PROGRAM_DECIMALS: usize = 6;

/// How far a value read back from a program may lie from the value written: half a unit in
/// the last written decimal, plus the rounding of a decimal to binary (1e-12 deg for any
/// angle below 10,000 deg).
pub const PROGRAM_READ_BACK: f64 = 0.5e-6 + 1e-9;

/// The axes a KRL, RAPID or TP program drives.
const PROGRAM_AXES: usize = 6;

/// A controller program's language (`compensate --format krl|rapid|tp`).
///
/// Each program is one joint move per row, to the compensated readings in degrees, the robot
/// file's joints 1 to 6 taken as the controller's axes 1 to 6 (the file's header comment says
/// so), with [`PROGRAM_DECIMALS`] decimals:
///
/// - [`Language::Krl`], KUKA: a `.src` file, `DEF name()` ... `END`, the axis velocity
///   (`$VEL_AXIS`, percent of each axis's maximum) and acceleration (`$ACC_AXIS`, 100 %) set
///   for the six axes, then `PTP {A1 .., A2 .., A3 .., A4 .., A5 .., A6 ..}` per row, with
///   `C_PTP` (approximated, `$APO.CPTP` percent) when a zone is given. The name is the file's
///   (the controller loads a module whose `DEF` names its file).
/// - [`Language::Rapid`], ABB: a module `MODULE name` with `PROC main()` of one
///   `MoveAbsJ [[j1,..,j6],[9E9,9E9,9E9,9E9,9E9,9E9]]\NoEOffs, v100, fine, tool0;` per row.
/// - [`Language::Tp`], FANUC: a TP program in ASCII (`.ls`): `/PROG NAME`, `/ATTR`, `/MN` with
///   remark lines (the header) and `J P[n] 100% FINE ;` per row, `/POS` with each point in
///   joint representation (`J1= .. deg`), `/END`.
///
/// The last row always stops exactly (`fine`, no `C_PTP`): a program ends at its last point.
/// These programs are for 6-axis arms: a robot of another number of joints is refused, since
/// which of its joints is which axis (a KUKA palletizer's A1, A2, A3, A6; a seventh joint as
/// an external axis `E1`, `eax_a`) is the cell's configuration, not the robot file's.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Language {
    /// KUKA KRL.
    Krl,
    /// ABB RAPID.
    Rapid,
    /// FANUC TP (ASCII, `.ls`).
    Tp,
}

/// Where a program's moves end: stopped exactly at each point, or approximated (blended)
/// past it by the language's measure.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Zone {
    /// Exactly at each point: KRL without `C_PTP`, RAPID `fine`, TP `FINE`.
    #[default]
    Fine,
    /// Approximated: KRL `C_PTP` with `$APO.CPTP` this percent (1 to 100), RAPID zonedata
    /// `z` this many mm (a predefined one, 0 to 200), TP `CNT` this value (0 to 100).
    Blend(u32),
}

/// The speeds of RAPID's predefined speeddata (`v5` .. `v7000`, mm/s at the TCP).
pub const RAPID_SPEEDS: [u32; 25] = [
    5, 10, 20, 30, 40, 50, 60, 80, 100, 150, 200, 300, 400, 500, 600, 800, 1000, 1500, 2000, 2500,
    3000, 4000, 5000, 6000, 7000,
];

/// The sizes of RAPID's predefined zonedata (`z0` .. `z200`, mm).
pub const RAPID_ZONES: [u32; 14] = [0, 1, 5, 10, 15, 20, 30, 40, 50, 60, 80, 100, 150, 200];

/// KRL keywords a module may not be named (KRL is case-insensitive), and `I`, the program's own
/// loop variable.
const KRL_KEYWORDS: &str =
    "ANIN ANOUT AND B_AND B_EXOR B_NOT B_OR BOOL BRAKE C_DIS C_ORI C_PTP C_VEL CASE CHAR CIRC \
     CIRC_REL CONST CONTINUE DECL DEF DEFAULT DEFDAT DEFFCT DELAY DO ELSE END ENDDAT ENDFCT \
     ENDFOR ENDIF ENDLOOP ENDSWITCH ENDWHILE ENUM EXIT EXOR EXT EXTFCT FALSE FOR GLOBAL GOTO \
     HALT IF IMPORT INT INTERRUPT LIN LIN_REL LOOP NOT OR PTP PTP_REL REAL REPEAT RETURN \
     SWITCH WHILE TO STEP THEN UNTIL WAIT SEC WHEN STRUC SIGNAL TRIGGER PULSE ON OFF PUBLIC \
     PRIO DISTANCE MINIMUM MAXIMUM I";

/// RAPID's reserved words (RAPID is case-insensitive), and the names the program itself uses:
/// `main` (the procedure inside), `tool0`, `fine`, `vmax`, `MoveAbsJ`, `NoEOffs` (and, checked
/// apart, the speeddata `vN` and zonedata `zN`).
const RAPID_RESERVED: &str =
    "ALIAS AND BACKWARD CASE CONNECT CONST DEFAULT DIV DO ELSE ELSEIF ENDFOR ENDFUNC ENDIF \
     ENDMODULE ENDPROC ENDRECORD ENDTEST ENDTRAP ENDWHILE ERROR EXIT FALSE FOR FROM FUNC GOTO \
     IF INOUT LOCAL MOD MODULE NOSTEPIN NOT NOVIEW OR PERS PROC RAISE READONLY RECORD RETRY \
     RETURN STEP SYSMODULE TEST THEN TO TRAP TRUE TRYNEXT UNDO VAR VIEWONLY WHILE WITH XOR \
     MAIN TOOL0 FINE VMAX MOVEABSJ NOEOFFS";

impl Language {
    /// The format's name on the command line.
    pub fn as_str(self) -> &'static str {
        match self {
            Language::Krl => "krl",
            Language::Rapid => "rapid",
            Language::Tp => "tp",
        }
    }

    /// The language's name in words.
    pub fn title(self) -> &'static str {
        match self {
            Language::Krl => "KRL",
            Language::Rapid => "RAPID",
            Language::Tp => "TP",
        }
    }

    /// The brand whose joint convention (names, degrees) the language uses.
    pub(crate) fn brand(self) -> Brand {
        match self {
            Language::Krl => Brand::Kuka,
            Language::Rapid => Brand::Abb,
            Language::Tp => Brand::Fanuc,
        }
    }

    /// The longest name the controller takes: KRL 24 characters (KUKA System Software 8),
    /// RAPID 32, TP 36 (R-30iA and later; controllers before it take 8).
    pub fn max_name(self) -> usize {
        match self {
            Language::Krl => 24,
            Language::Rapid => 32,
            Language::Tp => 36,
        }
    }

    /// The speed when none is given: KRL and TP 100 (%), RAPID 100 (`v100`, mm/s).
    pub fn default_speed(self) -> u32 {
        100
    }

    /// Checks that `robot` fits a program of the language: six revolute joints.
    pub fn check_robot(self, robot: &Robot) -> Result<()> {
        self.brand().columns(robot)?;
        let n = robot.dof();
        if n != PROGRAM_AXES {
            let axes = match self {
                Language::Krl => "A1..A6",
                Language::Rapid => "rax_1..rax_6",
                Language::Tp => "J1..J6",
            };
            return Err(Error::InvalidOption {
                setting: Setting::OutputFormat,
                message: format!(
                    "a {} program here drives the six axes of an arm ({axes}); this robot has \
                     {n} joints, and which of them is which axis of the controller (or an \
                     external axis) is the cell's configuration: format joints-{} writes \
                     them as a table",
                    self.title(),
                    self.brand().as_str()
                ),
            });
        }
        Ok(())
    }

    /// The program's name as written (TP's in capitals), or why `name` is not one the
    /// controller takes: letters, digits and `_`, a letter first, at most
    /// [`Language::max_name`] characters, no keyword of the language.
    pub fn program_name(self, name: &str) -> std::result::Result<String, String> {
        let rule = format!(
            "a {} program name is letters, digits and _, a letter first, at most {} characters",
            self.title(),
            self.max_name()
        );
        let n = name.chars().count();
        if n == 0 {
            return Err(format!("the name is empty: {rule}"));
        }
        if n > self.max_name() {
            return Err(format!("`{name}` has {n} characters: {rule}"));
        }
        if let Some(c) = name
            .chars()
            .find(|c| !(c.is_ascii_alphanumeric() || *c == '_'))
        {
            return Err(format!("`{name}` holds `{c}`: {rule}"));
        }
        if !name.starts_with(|c: char| c.is_ascii_alphabetic()) {
            return Err(format!("`{name}` does not begin with a letter: {rule}"));
        }
        let upper = name.to_ascii_uppercase();
        let reserved = match self {
            Language::Krl => KRL_KEYWORDS,
            Language::Rapid => RAPID_RESERVED,
            Language::Tp => "",
        };
        // RAPID's speeddata `vN` and zonedata `zN` are names the program uses too.
        let data_name = self == Language::Rapid
            && upper.len() > 1
            && upper.starts_with(['V', 'Z'])
            && upper[1..].bytes().all(|b| b.is_ascii_digit());
        if data_name || reserved.split_whitespace().any(|w| w == upper) {
            return Err(format!(
                "`{name}` is a reserved word of {}{}",
                self.title(),
                match self {
                    Language::Rapid => {
                        " (or a name the program uses: main, tool0, fine, vmax, vN, zN, \
                         MoveAbsJ, NoEOffs)"
                    }
                    Language::Krl => " (or I, the program's loop variable)",
                    Language::Tp => "",
                }
            ));
        }
        Ok(match self {
            Language::Tp => upper,
            _ => name.to_string(),
        })
    }

    /// The speed `v` checked for the language: KRL and TP a whole percent from 1 to 100 (KRL:
    /// of each axis's maximum velocity, `$VEL_AXIS`; TP: of the joint speed, `100%`), RAPID
    /// the TCP speed (mm/s) of a predefined speeddata, `v5` to `v7000`.
    pub fn speed(self, v: f64) -> std::result::Result<u32, String> {
        let whole =
            (v.is_finite() && v.fract() == 0.0 && (0.0..=1e9).contains(&v)).then_some(v as u32);
        match self {
            Language::Krl | Language::Tp => match whole {
                Some(s @ 1..=100) => Ok(s),
                _ => Err(format!(
                    "expected a whole percent from 1 to 100 ({}), not {v}",
                    if self == Language::Krl {
                        "KRL: of each axis's maximum velocity, $VEL_AXIS"
                    } else {
                        "TP: of the joint speed, J P[n] 100%"
                    }
                )),
            },
            Language::Rapid => match whole {
                Some(s) if RAPID_SPEEDS.contains(&s) => Ok(s),
                _ => Err(format!(
                    "expected the TCP speed (mm/s) of a predefined RAPID speeddata: one of {}, \
                     not {v}",
                    list(&RAPID_SPEEDS)
                )),
            },
        }
    }

    /// A blending zone `v` checked for the language: KRL `C_PTP` with `$APO.CPTP` a whole
    /// percent from 1 to 100; RAPID a predefined zonedata's size (mm): 0, 1, 5, .. 200; TP
    /// `CNT` 0 to 100.
    pub fn zone(self, v: f64) -> std::result::Result<Zone, String> {
        let whole =
            (v.is_finite() && v.fract() == 0.0 && (0.0..=1e9).contains(&v)).then_some(v as u32);
        match (self, whole) {
            (Language::Krl, Some(z @ 1..=100)) => Ok(Zone::Blend(z)),
            (Language::Tp, Some(z @ 0..=100)) => Ok(Zone::Blend(z)),
            (Language::Rapid, Some(z)) if RAPID_ZONES.contains(&z) => Ok(Zone::Blend(z)),
            (Language::Krl, _) => Err(format!(
                "expected `fine` or a whole percent from 1 to 100 (KRL C_PTP, $APO.CPTP), not \
                 {v}"
            )),
            (Language::Tp, _) => Err(format!(
                "expected `fine` or a whole CNT value from 0 to 100 (TP), not {v}"
            )),
            (Language::Rapid, _) => Err(format!(
                "expected `fine` or the size (mm) of a predefined RAPID zonedata: one of {}, \
                 not {v}",
                list(&RAPID_ZONES)
            )),
        }
    }
}

/// `5, 10, 20` (a list of numbers in words).
fn list(v: &[u32]) -> String {
    v.iter().map(u32::to_string).collect::<Vec<_>>().join(", ")
}

/// A controller program of joint moves: what is written, and what the reader gives back.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct Program {
    /// Its language.
    pub language: Language,
    /// Its name (KRL `DEF`, RAPID `MODULE`, TP `/PROG`).
    pub name: String,
    /// Its speed ([`Language::speed`]).
    pub speed: u32,
    /// How its moves end (the last always exactly).
    pub zone: Zone,
    /// The joint values (deg) of each move, in order: six per move.
    pub points: Vec<[f64; 6]>,
}

impl Program {
    /// An empty program.
    pub fn new(language: Language, name: String, speed: u32, zone: Zone) -> Program {
        Program {
            language,
            name,
            speed,
            zone,
            points: Vec::new(),
        }
    }

    /// The program's text: `header` as its opening comment (one line each), then one move per
    /// point, preceded by its label as a comment where the language has room (`labels`, one
    /// per point or none; TP keeps none: its points are numbered in order).
    pub fn text(&self, header: &[String], labels: &[String]) -> String {
        match self.language {
            Language::Krl => self.krl(header, labels),
            Language::Rapid => self.rapid(header, labels),
            Language::Tp => self.tp(header),
        }
    }

    fn krl(&self, header: &[String], labels: &[String]) -> String {
        let mut s = format!("&ACCESS RVP\n&REL 1\nDEF {}()\n", self.name);
        for h in header {
            s += &format!("; {}\n", printable(h));
        }
        s += "DECL INT I\n";
        s += &format!(
            "FOR I=1 TO 6\n  $VEL_AXIS[I]={}\n  $ACC_AXIS[I]=100\nENDFOR\n",
            self.speed
        );
        if let Zone::Blend(z) = self.zone {
            s += &format!("$APO.CPTP={z}\n");
        }
        let last = self.points.len().saturating_sub(1);
        for (i, p) in self.points.iter().enumerate() {
            if let Some(l) = labels.get(i) {
                s += &format!("; {}\n", printable(l));
            }
            let axes: Vec<String> = p
                .iter()
                .enumerate()
                .map(|(k, v)| format!("A{} {}", k + 1, degrees(*v)))
                .collect();
            s += &format!("PTP {{{}}}", axes.join(", "));
            if matches!(self.zone, Zone::Blend(_)) && i < last {
                s += " C_PTP";
            }
            s.push('\n');
        }
        s + "END\n"
    }

    fn rapid(&self, header: &[String], labels: &[String]) -> String {
        let mut s = format!("MODULE {}\n", self.name);
        for h in header {
            s += &format!("  ! {}\n", printable(h));
        }
        s += "  PROC main()\n";
        let last = self.points.len().saturating_sub(1);
        for (i, p) in self.points.iter().enumerate() {
            if let Some(l) = labels.get(i) {
                s += &format!("    ! {}\n", printable(l));
            }
            let axes: Vec<String> = p.iter().map(|v| degrees(*v)).collect();
            let zone = match self.zone {
                Zone::Blend(z) if i < last => format!("z{z}"),
                _ => "fine".to_string(),
            };
            s += &format!(
                "    MoveAbsJ [[{}],[9E9,9E9,9E9,9E9,9E9,9E9]]\\NoEOffs, v{}, {zone}, tool0;\n",
                axes.join(","),
                self.speed
            );
        }
        s + "  ENDPROC\nENDMODULE\n"
    }

    fn tp(&self, header: &[String]) -> String {
        // Remarks of at most 32 characters, of characters every TP editor takes.
        let remarks: Vec<String> = header
            .iter()
            .flat_map(|h| wrap(&tp_remark(h), 32))
            .collect();
        let lines = remarks.len() + self.points.len();
        let mut s = format!(
            "/PROG  {}\n/ATTR\nOWNER\t\t= MNEDITOR;\nCOMMENT\t\t= \"kinecal\";\nPROG_SIZE\t= 0;\n\
             FILE_NAME\t= ;\nVERSION\t\t= 0;\nLINE_COUNT\t= {lines};\nMEMORY_SIZE\t= 0;\n\
             PROTECT\t\t= READ_WRITE;\nTCD:  STACK_SIZE\t= 0,\n      TASK_PRIORITY\t= 50,\n      \
             TIME_SLICE\t= 0,\n      BUSY_LAMP_OFF\t= 0,\n      ABORT_REQUEST\t= 0,\n      \
             PAUSE_REQUEST\t= 0;\nDEFAULT_GROUP\t= 1,*,*,*,*;\nCONTROL_CODE\t= 00000000 00000000;\n\
             /MN\n",
            self.name
        );
        for (i, r) in remarks.iter().enumerate() {
            s += &format!("{:>4}:  !{r} ;\n", i + 1);
        }
        let last = self.points.len().saturating_sub(1);
        for i in 0..self.points.len() {
            let zone = match self.zone {
                Zone::Blend(z) if i < last => format!("CNT{z}"),
                _ => "FINE".to_string(),
            };
            s += &format!(
                "{:>4}:J P[{}] {}% {zone}    ;\n",
                remarks.len() + i + 1,
                i + 1,
                self.speed
            );
        }
        s += "/POS\n";
        for (i, p) in self.points.iter().enumerate() {
            let j: Vec<String> = p
                .iter()
                .enumerate()
                .map(|(k, v)| format!("J{}= {:>12} deg", k + 1, degrees(*v)))
                .collect();
            s += &format!(
                "P[{}]{{\n   GP1:\n\tUF : 0, UT : 1,\t\n\t{},\t{},\t{},\n\t{},\t{},\t{}\n}};\n",
                i + 1,
                j[0],
                j[1],
                j[2],
                j[3],
                j[4],
                j[5]
            );
        }
        s + "/END\n"
    }

    /// The zone the text shows: a RAPID or TP program of one move shows none (its move is the
    /// last, which stops exactly), KRL's `$APO.CPTP` shows it anyway.
    fn written_zone(&self) -> Zone {
        if self.language != Language::Krl && self.points.len() < 2 {
            Zone::Fine
        } else {
            self.zone
        }
    }

    /// Where `read`, this program read back, differs from it: its name, speed, zone, number
    /// of moves, or a joint value by more than [`PROGRAM_READ_BACK`].
    pub fn differs(&self, read: &Program) -> Option<String> {
        if read.name != self.name {
            return Some(format!(
                "its name reads `{}`, not `{}`",
                read.name, self.name
            ));
        }
        if read.speed != self.speed || read.zone != self.written_zone() {
            return Some(format!(
                "its speed and zone read {} {:?}, not {} {:?}",
                read.speed,
                read.zone,
                self.speed,
                self.written_zone()
            ));
        }
        if read.points.len() != self.points.len() {
            return Some(format!(
                "it reads {} moves, not {}",
                read.points.len(),
                self.points.len()
            ));
        }
        for (i, (a, b)) in read.points.iter().zip(&self.points).enumerate() {
            for k in 0..PROGRAM_AXES {
                let d = (a[k] - b[k]).abs();
                if d.is_nan() || d > PROGRAM_READ_BACK {
                    return Some(format!(
                        "move {}, axis {}: reads {} deg, not {} deg",
                        i + 1,
                        k + 1,
                        a[k],
                        b[k]
                    ));
                }
            }
        }
        None
    }
}

/// A joint value in degrees with [`PROGRAM_DECIMALS`] decimals, no `-0`.
fn degrees(v: f64) -> String {
    let s = format!("{v:.PROGRAM_DECIMALS$}");
    if s.trim_start_matches('-')
        .bytes()
        .all(|b| b == b'0' || b == b'.')
    {
        s.trim_start_matches('-').to_string()
    } else {
        s
    }
}

/// `text` with characters other than printable ASCII written `?` (a comment of KRL or RAPID
/// holds one line of the controller's character set).
fn printable(text: &str) -> String {
    text.chars()
        .map(|c| if (' '..='~').contains(&c) { c } else { '?' })
        .collect()
}

/// `text` for a TP remark: letters, digits, spaces and `.,:_-()/=` kept, anything else a
/// space (a `;` would end the line, quotes and `!` confuse editors).
fn tp_remark(text: &str) -> String {
    text.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || " .,:_-()/=".contains(c) {
                c
            } else {
                ' '
            }
        })
        .collect()
}

/// `text`'s words in lines of at most `width` characters (a longer word cut).
fn wrap(text: &str, width: usize) -> Vec<String> {
    let mut lines: Vec<String> = Vec::new();
    let mut line = String::new();
    for word in text.split_whitespace() {
        let mut word = word.to_string();
        while word.len() > width {
            if !line.is_empty() {
                lines.push(std::mem::take(&mut line));
            }
            let rest = word.split_off(width);
            lines.push(word);
            word = rest;
        }
        if !line.is_empty() && line.len() + 1 + word.len() > width {
            lines.push(std::mem::take(&mut line));
        }
        if !line.is_empty() {
            line.push(' ');
        }
        line += &word;
    }
    if !line.is_empty() {
        lines.push(line);
    }
    lines
}

/// An error at `line` of the program `file`.
fn at(file: &str, line: usize, message: impl Into<String>) -> Error {
    Error::input(Location::file(file).at_line(line), message)
}

/// Reads a program of `language` (`text`, from `file`): what kinecal writes, as its language
/// spells it (keywords in any case, any spacing). Anything else in it is an error naming its
/// line: this reader is the check of kinecal's own programs, not a reader of any program.
pub fn read_program(language: Language, text: &str, file: &str) -> Result<Program> {
    match language {
        Language::Krl => read_krl(text, file),
        Language::Rapid => read_rapid(text, file),
        Language::Tp => read_tp(text, file),
    }
}

/// `text` without its leading `word` (any case) and the spaces after it, when it starts so
/// and the word ends there.
fn keyword<'t>(text: &'t str, word: &str) -> Option<&'t str> {
    let head = text.get(..word.len())?;
    let rest = &text[word.len()..];
    (head.eq_ignore_ascii_case(word)
        && !rest.starts_with(|c: char| c.is_ascii_alphanumeric() || c == '_'))
    .then(|| rest.trim_start())
}

/// A whole number of a statement.
fn whole(file: &str, line: usize, text: &str, what: &str) -> Result<u32> {
    text.trim().parse().map_err(|_| {
        at(
            file,
            line,
            format!("{what}: expected a whole number, found `{text}`"),
        )
    })
}

/// A joint value (deg).
fn value(file: &str, line: usize, text: &str, axis: &str) -> Result<f64> {
    match text.trim().parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(Error::input(
            Location::file(file).at_line(line).with_field(axis),
            format!("expected a number of degrees, found `{}`", text.trim()),
        )),
    }
}

/// The zone of a program's moves, from each move's (`None`: exact), in order: every move but
/// the last alike, the last exact.
fn zone_of(file: &str, moves: &[(usize, Option<u32>)]) -> Result<Zone> {
    let Some(((last_line, last), rest)) = moves.split_last() else {
        return Ok(Zone::Fine);
    };
    if last.is_some() {
        return Err(at(
            file,
            *last_line,
            "the last move is approximated: a program ends exactly at its last point",
        ));
    }
    let zone = rest.first().map_or(Zone::Fine, |(_, z)| match z {
        Some(z) => Zone::Blend(*z),
        None => Zone::Fine,
    });
    for (line, z) in rest {
        let this = z.map_or(Zone::Fine, Zone::Blend);
        if this != zone {
            return Err(at(
                file,
                *line,
                format!("this move ends {this:?}, the first {zone:?}: the moves end alike"),
            ));
        }
    }
    Ok(zone)
}

fn read_krl(text: &str, file: &str) -> Result<Program> {
    let mut name: Option<String> = None;
    let mut speed = None;
    let mut cptp = None;
    let mut moves = Vec::new();
    let mut points = Vec::new();
    let mut end = None;
    let mut last = 0;
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        last = line;
        let code = raw.split(';').next().unwrap_or("").trim();
        if code.is_empty() || (name.is_none() && code.starts_with('&')) {
            continue;
        }
        if end.is_some() {
            return Err(at(file, line, format!("`{code}` after END")));
        }
        let Some(n) = &name else {
            let def = keyword(code, "DEF")
                .and_then(|r| r.strip_suffix(')'))
                .and_then(|r| r.trim_end().strip_suffix('('))
                .map(str::trim)
                .filter(|n| !n.is_empty());
            match def {
                Some(d) => name = Some(d.to_string()),
                None => {
                    return Err(at(
                        file,
                        line,
                        format!("expected `DEF name()`, found `{code}`"),
                    ))
                }
            }
            continue;
        };
        let _ = n;
        let squeezed: String = code
            .chars()
            .filter(|c| !c.is_whitespace())
            .collect::<String>()
            .to_ascii_uppercase();
        if let Some(rest) = keyword(code, "PTP") {
            let (axes, blend) = krl_axes(file, line, rest)?;
            points.push(axes);
            moves.push((line, blend));
        } else if let Some(v) = squeezed.strip_prefix("$VEL_AXIS[I]=") {
            speed = Some(whole(file, line, v, "$VEL_AXIS")?);
        } else if let Some(v) = squeezed.strip_prefix("$ACC_AXIS[I]=") {
            whole(file, line, v, "$ACC_AXIS")?;
        } else if let Some(v) = squeezed.strip_prefix("$APO.CPTP=") {
            cptp = Some(whole(file, line, v, "$APO.CPTP")?);
        } else if squeezed == "END" {
            end = Some(line);
        } else if !["DECLINTI", "FORI=1TO6", "ENDFOR"].contains(&squeezed.as_str()) {
            return Err(at(
                file,
                line,
                format!(
                    "unexpected statement `{code}` (kinecal's KRL: DEF, the axis velocities and \
                     accelerations, $APO.CPTP, PTP {{A1 ..}}, END)"
                ),
            ));
        }
    }
    let Some(name) = name else {
        return Err(at(file, last.max(1), "no `DEF name()`"));
    };
    if end.is_none() {
        return Err(at(file, last.max(1), format!("DEF {name}: no END")));
    }
    let Some(speed) = speed else {
        return Err(at(file, last.max(1), "no axis velocity ($VEL_AXIS[I]=..)"));
    };
    // `C_PTP` on every move but the last when `$APO.CPTP` is set, on none when not.
    let blended: Vec<(usize, Option<u32>)> = moves
        .iter()
        .map(|&(line, c)| (line, c.then_some(cptp.unwrap_or(0))))
        .collect();
    let zone = match (zone_of(file, &blended)?, cptp) {
        (Zone::Fine, Some(c)) if moves.len() <= 1 => Zone::Blend(c),
        (Zone::Fine, Some(_)) => {
            return Err(at(
                file,
                moves[0].0,
                "$APO.CPTP is set but this move is not approximated (no C_PTP)",
            ))
        }
        (Zone::Blend(_), None) => {
            return Err(at(file, moves[0].0, "C_PTP without $APO.CPTP"));
        }
        (z, _) => z,
    };
    Ok(Program {
        language: Language::Krl,
        name,
        speed,
        zone,
        points,
    })
}

/// The axes of a `PTP {A1 .., .., A6 ..}` (the text after `PTP`) and whether it is
/// approximated (`C_PTP`).
fn krl_axes(file: &str, line: usize, rest: &str) -> Result<([f64; 6], bool)> {
    let bad = |m: String| at(file, line, m);
    let inner = rest
        .strip_prefix('{')
        .and_then(|r| r.split_once('}'))
        .ok_or_else(|| bad(format!("expected PTP {{A1 .., A6 ..}}, found `PTP {rest}`")))?;
    let (aggregate, after) = inner;
    let blend = match after.trim() {
        "" => false,
        a if a.eq_ignore_ascii_case("C_PTP") => true,
        a => return Err(bad(format!("unexpected `{a}` after the axes"))),
    };
    let mut axes = [f64::NAN; 6];
    for part in aggregate.split(',') {
        let mut words = part.split_whitespace();
        let (Some(axis), Some(v), None) = (words.next(), words.next(), words.next()) else {
            return Err(bad(format!("expected `A1 value`, found `{}`", part.trim())));
        };
        let k = axis
            .strip_prefix(['A', 'a'])
            .and_then(|k| k.parse::<usize>().ok())
            .filter(|k| (1..=6).contains(k))
            .ok_or_else(|| bad(format!("`{axis}` is no axis A1..A6")))?;
        if !axes[k - 1].is_nan() {
            return Err(bad(format!("{axis} twice")));
        }
        axes[k - 1] = value(file, line, v, axis)?;
    }
    if let Some(k) = axes.iter().position(|v| v.is_nan()) {
        return Err(bad(format!("no A{}: a move gives all six axes", k + 1)));
    }
    Ok((axes, blend))
}

fn read_rapid(text: &str, file: &str) -> Result<Program> {
    let mut name: Option<String> = None;
    let (mut proc_at, mut endproc, mut endmodule) = (None, false, false);
    let mut speed: Option<u32> = None;
    let mut moves = Vec::new();
    let mut points = Vec::new();
    let mut last = 0;
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        last = line;
        let code = raw.split('!').next().unwrap_or("").trim();
        if code.is_empty() {
            continue;
        }
        if endmodule {
            return Err(at(file, line, format!("`{code}` after ENDMODULE")));
        }
        if name.is_none() {
            match keyword(code, "MODULE").filter(|n| !n.is_empty()) {
                Some(n) => name = Some(n.to_string()),
                None => {
                    return Err(at(
                        file,
                        line,
                        format!("expected `MODULE name`, found `{code}`"),
                    ))
                }
            }
            continue;
        }
        let squeezed: String = code.chars().filter(|c| !c.is_whitespace()).collect();
        if proc_at.is_none() {
            if squeezed.eq_ignore_ascii_case("PROCmain()") {
                proc_at = Some(line);
                continue;
            }
            return Err(at(
                file,
                line,
                format!("expected `PROC main()`, found `{code}`"),
            ));
        }
        if endproc {
            if squeezed.eq_ignore_ascii_case("ENDMODULE") {
                endmodule = true;
                continue;
            }
            return Err(at(
                file,
                line,
                format!("expected ENDMODULE, found `{code}`"),
            ));
        }
        if squeezed.eq_ignore_ascii_case("ENDPROC") {
            endproc = true;
            continue;
        }
        let Some(rest) = keyword(code, "MoveAbsJ") else {
            return Err(at(
                file,
                line,
                format!("unexpected statement `{code}` (kinecal's RAPID: MoveAbsJ in PROC main)"),
            ));
        };
        let (axes, v, zone) = rapid_move(file, line, rest)?;
        if let Some(s) = speed.filter(|&s| s != v) {
            return Err(at(
                file,
                line,
                format!("speed v{v}, the first move's v{s}: the moves go alike"),
            ));
        }
        speed = Some(v);
        points.push(axes);
        moves.push((line, zone));
    }
    let Some(name) = name else {
        return Err(at(file, last.max(1), "no `MODULE name`"));
    };
    if !(endproc && endmodule) {
        return Err(at(file, last.max(1), "no ENDPROC and ENDMODULE at the end"));
    }
    Ok(Program {
        language: Language::Rapid,
        name,
        speed: speed.unwrap_or(0),
        zone: zone_of(file, &moves)?,
        points,
    })
}

/// A `MoveAbsJ` (the text after it): the six robot axes, the speed (`vN`) and the zone
/// (`fine`: `None`, `zN`).
fn rapid_move(file: &str, line: usize, rest: &str) -> Result<([f64; 6], u32, Option<u32>)> {
    let bad = |m: String| at(file, line, m);
    let squeezed: String = rest.chars().filter(|c| !c.is_whitespace()).collect();
    let body = squeezed
        .strip_suffix(';')
        .ok_or_else(|| bad("a statement ends with `;`".into()))?;
    let (target, args) = body
        .strip_prefix("[[")
        .and_then(|b| b.split_once("]]"))
        .ok_or_else(|| {
            bad(format!(
                "expected MoveAbsJ [[j1,..,j6],[e1,..,e6]]..., found `{rest}`"
            ))
        })?;
    let (robax, extax) = target
        .split_once("],[")
        .ok_or_else(|| bad("expected a jointtarget [[robax],[extax]]".into()))?;
    let values: Vec<&str> = robax.split(',').collect();
    if values.len() != 6 {
        return Err(bad(format!(
            "robax has {} values, not the six axes",
            values.len()
        )));
    }
    let mut axes = [0.0; 6];
    for (k, v) in values.iter().enumerate() {
        axes[k] = value(file, line, v, &format!("rax_{}", k + 1))?;
    }
    if extax.split(',').count() != 6
        || !extax
            .split(',')
            .all(|e| e.parse::<f64>().is_ok_and(|e| (e - 9e9).abs() < 1.0))
    {
        return Err(bad(format!(
            "extax `[{extax}]`: expected six 9E9 (no external axes)"
        )));
    }
    let args: Vec<&str> = args.split(',').collect();
    let [switch, speed, zone, tool] = args.as_slice() else {
        return Err(bad(format!(
            "expected \\NoEOffs, speed, zone, tool after the jointtarget, found `{}`",
            args.join(",")
        )));
    };
    if !switch.eq_ignore_ascii_case("\\NoEOffs") {
        return Err(bad(format!("expected \\NoEOffs, found `{switch}`")));
    }
    let speed = speed
        .strip_prefix(['v', 'V'])
        .and_then(|s| s.parse().ok())
        .ok_or_else(|| bad(format!("expected a speeddata vN, found `{speed}`")))?;
    let zone = if zone.eq_ignore_ascii_case("fine") {
        None
    } else {
        Some(
            zone.strip_prefix(['z', 'Z'])
                .and_then(|z| z.parse().ok())
                .ok_or_else(|| bad(format!("expected fine or a zonedata zN, found `{zone}`")))?,
        )
    };
    if tool.is_empty() {
        return Err(bad("no tool".into()));
    }
    Ok((axes, speed, zone))
}

fn read_tp(text: &str, file: &str) -> Result<Program> {
    #[derive(PartialEq)]
    enum Section {
        Start,
        Attr,
        Main,
        Pos,
        End,
    }
    let mut section = Section::Start;
    let mut name = String::new();
    let mut mn_lines = 0;
    let mut speed: Option<u32> = None;
    // Each move: its line, its point, its zone.
    let mut moves: Vec<(usize, usize, Option<u32>)> = Vec::new();
    // By number: a point's number is the program's to choose (`P[1000000]` alone is one
    // point, not a million).
    let mut positions: std::collections::BTreeMap<usize, [f64; 6]> = Default::default();
    // The point being read: its number, the line it began, its text.
    let mut point: Option<(usize, usize, String)> = None;
    let mut last = 0;
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        last = line;
        let code = raw.trim();
        if code.is_empty() {
            continue;
        }
        match section {
            Section::Start => {
                match keyword(code, "/PROG").and_then(|r| r.split_whitespace().next()) {
                    Some(n) => {
                        name = n.to_string();
                        section = Section::Attr;
                    }
                    None => {
                        return Err(at(
                            file,
                            line,
                            format!("expected `/PROG NAME`, found `{code}`"),
                        ))
                    }
                }
            }
            Section::Attr => {
                if code.eq_ignore_ascii_case("/MN") {
                    section = Section::Main;
                } else if code.starts_with('/')
                    && !code.eq_ignore_ascii_case("/ATTR")
                    && !code.eq_ignore_ascii_case("/APPL")
                {
                    return Err(at(file, line, format!("expected /MN, found `{code}`")));
                }
            }
            Section::Main => {
                if code.eq_ignore_ascii_case("/POS") {
                    section = Section::Pos;
                    continue;
                }
                let (number, body) = code.split_once(':').ok_or_else(|| {
                    at(file, line, format!("expected `n: ... ;`, found `{code}`"))
                })?;
                mn_lines += 1;
                if number.trim().parse::<usize>().ok() != Some(mn_lines) {
                    return Err(at(
                        file,
                        line,
                        format!("line number `{}`: expected {mn_lines}", number.trim()),
                    ));
                }
                let body = body
                    .trim()
                    .strip_suffix(';')
                    .ok_or_else(|| at(file, line, "a TP line ends with `;`"))?
                    .trim();
                if body.is_empty() || body.starts_with('!') {
                    continue;
                }
                let (p, v, zone) = tp_move(file, line, body)?;
                if let Some(s) = speed.filter(|&s| s != v) {
                    return Err(at(
                        file,
                        line,
                        format!("speed {v}%, the first move's {s}%: the moves go alike"),
                    ));
                }
                speed = Some(v);
                moves.push((line, p, zone));
            }
            Section::Pos => {
                if let Some((n, begun, mut body)) = point.take() {
                    if code == "};" {
                        let axes = tp_point(file, begun, &body)?;
                        if positions.insert(n, axes).is_some() {
                            return Err(at(file, begun, format!("P[{n}] twice")));
                        }
                    } else {
                        body += code;
                        body.push('\n');
                        point = Some((n, begun, body));
                    }
                } else if code.eq_ignore_ascii_case("/END") {
                    section = Section::End;
                } else {
                    let n = code
                        .strip_prefix("P[")
                        .and_then(|r| r.strip_suffix("]{"))
                        .and_then(|n| n.parse::<usize>().ok())
                        .filter(|&n| n >= 1)
                        .ok_or_else(|| {
                            at(file, line, format!("expected `P[n]{{`, found `{code}`"))
                        })?;
                    point = Some((n, line, String::new()));
                }
            }
            Section::End => return Err(at(file, line, format!("`{code}` after /END"))),
        }
    }
    if section != Section::End {
        return Err(at(
            file,
            last.max(1),
            if point.is_some() {
                "a point without its `};`"
            } else {
                "no /END (a TP program has /PROG, /ATTR, /MN, /POS and /END)"
            },
        ));
    }
    let mut points = Vec::with_capacity(moves.len());
    for &(line, p, _) in &moves {
        match positions.get(&p) {
            Some(&a) => points.push(a),
            None => return Err(at(file, line, format!("P[{p}] is not in /POS"))),
        }
    }
    let zones: Vec<(usize, Option<u32>)> = moves.iter().map(|&(l, _, z)| (l, z)).collect();
    Ok(Program {
        language: Language::Tp,
        name,
        speed: speed.unwrap_or(0),
        zone: zone_of(file, &zones)?,
        points,
    })
}

/// A TP joint move `J P[n] S% FINE|CNTz` (no `;`): its point, speed and zone.
fn tp_move(file: &str, line: usize, body: &str) -> Result<(usize, u32, Option<u32>)> {
    let bad = || {
        at(
            file,
            line,
            format!("expected `J P[n] S% FINE` or `CNTz`, found `{body}`"),
        )
    };
    let words: Vec<&str> = body.split_whitespace().collect();
    let [j, p, s, z] = words.as_slice() else {
        return Err(bad());
    };
    if *j != "J" {
        return Err(bad());
    }
    let p = p
        .strip_prefix("P[")
        .and_then(|p| p.strip_suffix(']'))
        .and_then(|p| p.parse::<usize>().ok())
        .filter(|&p| p >= 1)
        .ok_or_else(bad)?;
    let s = s
        .strip_suffix('%')
        .and_then(|s| s.parse().ok())
        .ok_or_else(bad)?;
    let z = if z.eq_ignore_ascii_case("FINE") {
        None
    } else {
        Some(
            z.strip_prefix("CNT")
                .and_then(|c| c.parse().ok())
                .ok_or_else(bad)?,
        )
    };
    Ok((p, s, z))
}

/// The six joints of a TP point's body (between `P[n]{` and `};`, the point beginning at
/// `line`): `GP1:`, `UF : u, UT : t,`, then `J1= v deg, ..., J6= v deg`.
fn tp_point(file: &str, line: usize, body: &str) -> Result<[f64; 6]> {
    let rest = body
        .trim_start()
        .strip_prefix("GP1:")
        .ok_or_else(|| at(file, line, "expected the point of group 1 (GP1:)"))?;
    let mut axes = [f64::NAN; 6];
    for item in rest.split(',').map(str::trim).filter(|t| !t.is_empty()) {
        let (key, v) = item.split_once([':', '=']).ok_or_else(|| {
            at(
                file,
                line,
                format!("expected `key = value`, found `{item}`"),
            )
        })?;
        let key = key.trim();
        if key == "UF" || key == "UT" {
            whole(file, line, v, key)?;
            continue;
        }
        let k = key
            .strip_prefix('J')
            .and_then(|k| k.parse::<usize>().ok())
            .filter(|k| (1..=6).contains(k))
            .ok_or_else(|| {
                at(
                    file,
                    line,
                    format!("`{key}`: expected J1..J6 (a point in joint representation)"),
                )
            })?;
        let v = v.trim().strip_suffix("deg").ok_or_else(|| {
            at(
                file,
                line,
                format!("{key}: expected a value in deg, found `{v}`"),
            )
        })?;
        if !axes[k - 1].is_nan() {
            return Err(at(file, line, format!("{key} twice")));
        }
        axes[k - 1] = value(file, line, v, key)?;
    }
    if let Some(k) = axes.iter().position(|v| v.is_nan()) {
        return Err(at(
            file,
            line,
            format!("no J{}: a point gives all six joints", k + 1),
        ));
    }
    Ok(axes)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each language's reader gives back what its writer wrote, to half a unit of the sixth
    /// decimal (no `-0`), and a value moved by two units is seen.
    #[test]
    fn every_language_reads_back_what_it_writes_and_a_change_is_seen() {
        for language in [Language::Krl, Language::Rapid, Language::Tp] {
            for zone in [Zone::Fine, Zone::Blend(10)] {
                let mut p = Program::new(language, "P1".into(), 30, zone);
                p.points = vec![
                    [0.0, -0.0, 179.999_999_6, -359.25, 1e-7, -1e-7],
                    [12.5, -0.000_000_4, 90.0, 400.123_456_7, -45.5, 3.0],
                    [1.0, 2.0, 3.0, 4.0, 5.0, 6.0],
                ];
                let labels = ["a; b".to_string(), "ü".to_string(), "3".to_string()];
                let text = p.text(&["a header, of the program".into()], &labels);
                assert!(!text.contains("-0.000000"), "{text}");
                let read = read_program(language, &text, "p").unwrap();
                assert_eq!(p.differs(&read), None, "{text}");
                let mut moved = p.clone();
                moved.points[1][3] += 2e-6;
                assert!(
                    moved
                        .differs(&read)
                        .is_some_and(|d| d.contains("move 2, axis 4")),
                    "{language:?}"
                );
            }
        }
    }

    /// A TP program's point numbers are its own: `P[1000000000000000]` is one point (it was
    /// a table of that many, and the process aborted asking for 18 PB; a fuzzed input), and a
    /// move to a number /POS lacks is refused by name.
    #[test]
    fn tp_point_numbers_may_be_sparse_and_large() {
        let mut p = Program::new(Language::Tp, "P1".into(), 30, Zone::Fine);
        p.points = vec![
            [1.0, 2.0, 3.0, 4.0, 5.0, 6.0],
            [6.0, 5.0, 4.0, 3.0, 2.0, 1.0],
        ];
        let text = p.text(&[], &["a".to_string(), "b".to_string()]);
        let big = "1000000000000000";
        let sparse = text.replace("P[2]", &format!("P[{big}]"));
        assert_ne!(sparse, text);
        let read = read_program(Language::Tp, &sparse, "p.ls").unwrap();
        assert_eq!(p.differs(&read), None, "{sparse}");
        // The move to it left pointing at a number /POS lacks.
        let missing = sparse.replacen(&format!("P[{big}]{{"), "P[7]{", 1);
        let err = read_program(Language::Tp, &missing, "p.ls")
            .unwrap_err()
            .to_string();
        assert!(err.contains(&format!("P[{big}] is not in /POS")), "{err}");
    }

    #[test]
    fn names_speeds_and_zones_are_the_controllers() {
        assert_eq!(Language::Tp.program_name("prog_1").unwrap(), "PROG_1");
        assert_eq!(Language::Krl.program_name("Prog_1").unwrap(), "Prog_1");
        assert!(Language::Krl.program_name(&"a".repeat(24)).is_ok());
        assert!(Language::Krl.program_name(&"a".repeat(25)).is_err());
        assert!(Language::Rapid.program_name(&"a".repeat(32)).is_ok());
        assert!(Language::Tp.program_name(&"a".repeat(37)).is_err());
        assert!(Language::Krl.program_name("ptp").is_err());
        assert!(Language::Rapid.program_name("_a").is_err());
        assert!(Language::Rapid.program_name("").is_err());
        // Names the program itself uses: KRL's loop variable, RAPID's tool, zones and speeds.
        for (language, name) in [
            (Language::Krl, "i"),
            (Language::Krl, "While"),
            (Language::Rapid, "tool0"),
            (Language::Rapid, "Fine"),
            (Language::Rapid, "v100"),
            (Language::Rapid, "z10"),
            (Language::Rapid, "MoveAbsJ"),
        ] {
            assert!(language.program_name(name).is_err(), "{name}");
        }
        assert!(Language::Rapid.program_name("v100a").is_ok());
        assert!(Language::Krl.program_name("i2").is_ok());
        assert_eq!(Language::Rapid.speed(7000.0), Ok(7000));
        assert!(Language::Rapid.speed(f64::NAN).is_err());
        assert!(Language::Krl.speed(1e12).is_err());
        assert_eq!(Language::Tp.zone(0.0), Ok(Zone::Blend(0)));
        assert!(Language::Krl.zone(0.0).is_err());
        assert_eq!(Language::Rapid.zone(200.0), Ok(Zone::Blend(200)));
        assert!(Language::Rapid.zone(250.0).is_err());
        assert_eq!(
            wrap("a bb ccc dddddddddd", 4),
            ["a bb", "ccc", "dddd", "dddd", "dd"]
        );
    }
}
