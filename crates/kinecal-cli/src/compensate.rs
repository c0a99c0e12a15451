//! `kinecal compensate`: programs and targets through the calibrated model, row by row.

use std::path::Path;

use anyhow::{anyhow, bail, Result};
use kinecal::compensate::{
    goal_in_file_units, Compensator, Configuration, Options, Solved, TargetSearch,
};
use kinecal::files::controller::{joint_field, urscript_begin, urscript_end, urscript_move, Brand};
use kinecal::files::COMPENSATED_COLUMNS;
use kinecal::identifiability::fmt_sig;
use kinecal::units::Quantity;

use crate::args::{CompensateArgs, OutputFormat};
use crate::stream::{cell, Rows};
use crate::{load_robot, output, parse_spec, spec_value, EXIT_IMPLAUSIBLE};

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
    Targets {
        label: usize,
        /// A measurement file: its goal columns are written back with the solution (so that
        /// the output is a measurement file of where the robot must be).
        goal: Option<Vec<usize>>,
        site: Option<usize>,
        xyz: [usize; 3],
        euler: Option<[usize; 3]>,
        seed: Option<Vec<usize>>,
    },
}

/// Tells the layout from the header.
fn kind(rows: &Rows, robot: &kinecal::Robot) -> Result<Kind> {
    let dof = robot.dof();
    // `vK`, or the joint's name (a tree's, a URDF's).
    let columns: Vec<String> = (0..dof)
        .map(|j| kinecal::files::reading_column(robot, &rows.header, j))
        .collect();
    let readings: Option<Vec<usize>> = columns.iter().map(|c| rows.column(c)).collect();
    let reading = |h: &str| columns.iter().any(|c| c.eq_ignore_ascii_case(h));
    let known = |extra: &[&str]| {
        rows.header
            .iter()
            .find(|h| !(extra.contains(&h.as_str()) || reading(h)))
    };
    let label = rows.column("target").or_else(|| rows.column("posture"));
    if let (Some(label), true) = (
        label,
        rows.column("x").is_some() || rows.column("target").is_some(),
    ) {
        let (Some(x), Some(y), Some(z)) = (rows.column("x"), rows.column("y"), rows.column("z"))
        else {
            bail!(
                "{}:1: a targets file needs the columns target,x,y,z (and optionally site, \
                 alpha,beta,gamma and seed readings v1..v{dof})",
                rows.file
            );
        };
        let euler = match (
            rows.column("alpha"),
            rows.column("beta"),
            rows.column("gamma"),
        ) {
            (Some(a), Some(b), Some(g)) => Some([a, b, g]),
            (None, None, None) => None,
            _ => bail!("{}:1: give all of alpha,beta,gamma or none", rows.file),
        };
        let measured = rows.header[label] == "posture";
        if measured && readings.is_none() {
            bail!(
                "{}:1: a measurement file as targets needs its readings v1..v{dof} (the seeds)",
                rows.file
            );
        }
        let ignored: &[&str] = if measured { &MEASUREMENT_EXTRAS } else { &[] };
        let mut allowed = vec![
            "target", "posture", "site", "x", "y", "z", "alpha", "beta", "gamma",
        ];
        allowed.extend(ignored);
        allowed.extend(kinecal::files::PAYLOAD_COLUMNS);
        if let Some(h) = known(&allowed) {
            bail!("{}:1: unexpected column `{h}` in a targets file", rows.file);
        }
        let any_v = rows.header.iter().any(|h| h.starts_with('v'));
        if any_v && readings.is_none() {
            bail!(
                "{}:1: seed readings need every column v1..v{dof}",
                rows.file
            );
        }
        let goal = measured.then(|| {
            ["x", "y", "z", "alpha", "beta", "gamma"]
                .iter()
                .filter_map(|c| rows.column(c))
                .collect()
        });
        return Ok(Kind::Targets {
            label,
            goal,
            site: rows.column("site"),
            xyz: [x, y, z],
            euler,
            seed: readings,
        });
    }
    match (rows.column("posture"), readings) {
        (Some(_), Some(readings)) => {
            let mut allowed = vec!["posture"];
            allowed.extend(kinecal::files::PAYLOAD_COLUMNS);
            if let Some(h) = known(&allowed) {
                bail!(
                    "{}:1: unexpected column `{h}` in a program (posture,v1..v{dof})",
                    rows.file
                );
            }
            Ok(Kind::Program { readings })
        }
        _ => bail!(
            "{}:1: expected a program (posture,v1,...,v{dof}) or targets (target,x,y,z[,alpha,\
             beta,gamma][,v1..v{dof}]), found `{}`",
            rows.file,
            rows.header.join(",")
        ),
    }
}

/// Counts of the flags, for the summary.
#[derive(Default)]
struct Tally {
    rows: usize,
    flagged: usize,
    unreachable: usize,
    out_of_range: usize,
    singular: usize,
    branch: usize,
    configuration: usize,
    worst_position: f64,
    worst_attitude: f64,
    /// The first flagged row's label and flags.
    first_flagged: (String, String),
}

impl Tally {
    fn add(&mut self, s: &Solved, label: &str) {
        self.rows += 1;
        let f = &s.flags;
        if f.any() {
            if self.flagged == 0 {
                self.first_flagged = (label.to_string(), f.describe());
            }
            self.flagged += 1;
        }
        self.configuration += f.configuration as usize;
        self.unreachable += f.unreachable as usize;
        self.out_of_range += (f.out_of_range != 0) as usize;
        self.singular += f.singular as usize;
        self.branch += f.branch as usize;
        self.worst_position = self.worst_position.max(s.position_error);
        self.worst_attitude = self.worst_attitude.max(s.attitude_error.unwrap_or(0.0));
    }
}

/// Runs `kinecal compensate`.
pub fn run(a: CompensateArgs) -> Result<u8> {
    output::check_distinct(
        &[&a.out],
        &[&a.input, Path::new(&a.robot), Path::new(&a.nominal)],
    )?;
    let calibrated = load_robot(&a.robot)?.robot;
    let nominal = load_robot(&a.nominal)?.robot;
    let units = nominal.units;
    let mut options = Options::default();
    if let Some(spec) = &a.tolerance {
        let s = parse_spec("--tolerance", spec, &["length", "angle"])?;
        if let Some(l) = spec_value(&s, "length") {
            options.position_tolerance = units.to_si(Quantity::Length, l);
        }
        if let Some(an) = spec_value(&s, "angle") {
            options.attitude_tolerance = units.to_si(Quantity::Angle, an);
        }
    }
    if !(a.singular >= 0.0 && a.singular < 1.0) {
        bail!("--singular must be between 0 and 1, got {}", a.singular);
    }
    options.singular = a.singular;
    if let Some(b) = a.branch {
        if !(b.is_finite() && b > 0.0) {
            bail!("--branch must be a positive angle, got {b}");
        }
        options.branch = units.to_si(Quantity::Angle, b);
    }
    let default_target = crate::target_named(&nominal, &a.site, "--site")?;
    let mut comp = Compensator::new(&calibrated, &nominal, options)
        .map_err(|e| anyhow!("--robot {} and --nominal {}: {e}", a.robot, a.nominal))?;
    let dof = nominal.dof();
    let mut rows = Rows::open(&a.input)?;
    let kind = kind(&rows, &nominal)?;
    // What the tool carries at each row: the elastic robot yields to it, and the output keeps
    // the columns so that `fk` and `check` see the same load.
    let payload_cols = crate::stream::payload_columns(&rows)?;
    let mut search = TargetSearch::new(&calibrated, &nominal, options)
        .map_err(|e| anyhow!("--robot {}: {e}", a.robot))?;
    if let Some(c) = &a.configuration {
        if matches!(kind, Kind::Program { .. }) {
            bail!("--configuration is for Cartesian targets; a program's readings keep their own");
        }
        let c = Configuration::parse(c)?;
        search = search.with_configuration(c)?;
    }
    let mut program = ProgramFormat::new(a.format, &nominal, &a.input)?;
    let mut tally = Tally::default();
    let mut staged = output::Staged::new();
    let l = |v: f64| units.from_si(Quantity::Length, v);
    let an = |v: f64| units.from_si(Quantity::Angle, v);
    staged.by_path(&a.out, |tmp| {
        let file = std::io::BufWriter::new(std::fs::File::create(tmp)?);
        let mut w = program.sink(file);
        let (first, site_column, mut goal_columns) = match &kind {
            Kind::Program { .. } => ("posture", false, Vec::new()),
            Kind::Targets {
                label, site, goal, ..
            } => (
                rows.header[*label].as_str(),
                site.is_some(),
                goal.iter()
                    .flatten()
                    .map(|&c| rows.header[c].clone())
                    .collect::<Vec<_>>(),
            ),
        };
        goal_columns.extend(
            payload_cols
                .iter()
                .flatten()
                .map(|&c| rows.header[c].clone()),
        );
        let first = first.to_string();
        program.begin(&mut w, &first, site_column, &goal_columns)?;
        let mut goal_fields: Vec<String> = Vec::new();
        let mut out = vec![0.0; dof];
        let mut seed = vec![0.0; dof];
        let mut fields: Vec<String> = Vec::with_capacity(dof + 6);
        while let Some(line) = rows.advance()? {
            let payload = crate::stream::payload_at(&rows, line, &payload_cols, &units)?;
            comp.set_payload(payload);
            search.set_payload(payload);
            goal_fields.clear();
            let (label, site, solved) = match &kind {
                Kind::Program { readings } => {
                    for (s, &c) in seed.iter_mut().zip(readings) {
                        *s = cell(&rows, line, c)?;
                    }
                    let col = rows.column("posture").expect("checked");
                    (
                        rows.field(col).to_string(),
                        None,
                        comp.program(&seed, default_target, a.position_only, &mut out),
                    )
                }
                Kind::Targets {
                    label,
                    goal: goal_cols,
                    site,
                    xyz,
                    euler,
                    seed: cols,
                } => {
                    let target = match site {
                        Some(c) => crate::target_named(&nominal, rows.field(*c), "site")
                            .map_err(|e| anyhow!("{}:{line}: {e}", rows.file))?,
                        None => default_target,
                    };
                    let mut v = [0.0; 3];
                    for (k, &c) in xyz.iter().enumerate() {
                        v[k] = cell(&rows, line, c)?;
                    }
                    // A measurement file's position rows leave the three angles empty; with
                    // --position-only the attitudes are not goals.
                    let euler = match euler.filter(|e| {
                        !a.position_only && e.iter().any(|&c| !rows.field(c).is_empty())
                    }) {
                        Some(e) => {
                            let mut r = [0.0; 3];
                            for (k, &c) in e.iter().enumerate() {
                                r[k] = cell(&rows, line, c)?;
                            }
                            Some(r)
                        }
                        None => None,
                    };
                    let goal = goal_in_file_units(&nominal, v, euler).map_err(|p| {
                        crate::goal_problem(
                            &p,
                            &format!("{}:{line}", rows.file),
                            &format!("target {}", rows.field(*label)),
                        )
                    })?;
                    let given = match cols {
                        Some(cols) => {
                            for (s, &c) in seed.iter_mut().zip(cols) {
                                *s = cell(&rows, line, c)?;
                            }
                            Some(seed.as_slice())
                        }
                        None => None,
                    };
                    let s = search.solve(&goal, target, given, &mut out);
                    goal_fields.extend(
                        goal_cols
                            .iter()
                            .flatten()
                            .map(|&c| rows.field(c).to_string()),
                    );
                    (
                        rows.field(*label).to_string(),
                        site.map(|c| rows.field(c).to_string()),
                        s,
                    )
                }
            };
            goal_fields.extend(
                payload_cols
                    .iter()
                    .flatten()
                    .map(|&c| rows.field(c).to_string()),
            );
            tally.add(&solved, &label);
            program.row(
                &mut w,
                &mut fields,
                &label,
                site,
                &out,
                &goal_fields,
                &solved,
                l,
                an,
            )?;
        }
        program.end(&mut w)?;
        w.finish()
    })?;
    if tally.rows == 0 {
        bail!("{}: no rows", rows.file);
    }
    let summary = format!(
        "{} rows: {} flagged ({} unreachable, {} outside a joint range, {} near a singularity, \
         {} changing configuration{}); largest remaining error {} {}{}",
        tally.rows,
        tally.flagged,
        tally.unreachable,
        tally.out_of_range,
        tally.singular,
        tally.branch,
        if search.configuration().is_some() {
            format!(", {} not in the configuration", tally.configuration)
        } else {
            String::new()
        },
        fmt_sig(l(tally.worst_position)),
        units.length.as_str(),
        if tally.worst_attitude > 0.0 {
            format!(
                ", {} {}",
                fmt_sig(an(tally.worst_attitude)),
                units.angle.as_str()
            )
        } else {
            String::new()
        }
    );
    if program.is_controller() && tally.flagged > 0 {
        // A controller program with a row left out or wrong moves the robot somewhere else.
        drop(staged);
        eprintln!(
            "compensated {summary}\nnothing written to {}: a controller program needs every row \
             usable (first flagged: {} {}: {}); --format table writes every row with its flags",
            a.out.display(),
            if matches!(kind, Kind::Program { .. }) {
                "posture"
            } else {
                "target"
            },
            tally.first_flagged.0,
            tally.first_flagged.1
        );
        return Ok(EXIT_IMPLAUSIBLE);
    }
    staged.commit()?;
    eprintln!("compensated {summary} into {}", a.out.display());
    Ok(if tally.flagged > 0 {
        EXIT_IMPLAUSIBLE
    } else {
        0
    })
}

/// Where the rows go: a CSV table or a program's text.
enum Sink<W: std::io::Write> {
    Csv(Box<csv::Writer<W>>),
    Text(W),
}

impl<W: std::io::Write> Sink<W> {
    fn record(&mut self, fields: &[String]) -> Result<()> {
        match self {
            Sink::Csv(w) => w.write_record(fields)?,
            Sink::Text(_) => unreachable!("a program is text"),
        }
        Ok(())
    }

    fn text(&mut self, text: &str) -> Result<()> {
        match self {
            Sink::Text(w) => w.write_all(text.as_bytes())?,
            Sink::Csv(_) => unreachable!("a table is CSV"),
        }
        Ok(())
    }

    fn finish(self) -> Result<()> {
        let mut inner = match self {
            Sink::Csv(w) => w.into_inner().map_err(|e| anyhow!("{e}"))?,
            Sink::Text(w) => w,
        };
        inner.flush()?;
        Ok(())
    }
}

/// How the rows are written.
struct ProgramFormat<'r> {
    format: OutputFormat,
    robot: &'r kinecal::Robot,
    source: String,
    brand: Option<Brand>,
    joints: Vec<f64>,
}

impl<'r> ProgramFormat<'r> {
    fn new(format: OutputFormat, robot: &'r kinecal::Robot, input: &Path) -> Result<Self> {
        let brand = match format {
            OutputFormat::Table => None,
            OutputFormat::Urscript | OutputFormat::JointsUr => Some(Brand::Ur),
            OutputFormat::JointsAbb => Some(Brand::Abb),
            OutputFormat::JointsKuka => Some(Brand::Kuka),
            OutputFormat::JointsFanuc => Some(Brand::Fanuc),
        };
        if let Some(b) = brand {
            b.columns(robot)?;
        }
        Ok(ProgramFormat {
            format,
            robot,
            source: input.display().to_string(),
            brand,
            joints: vec![0.0; robot.dof()],
        })
    }

    fn sink<W: std::io::Write>(&self, w: W) -> Sink<W> {
        if self.format == OutputFormat::Urscript {
            Sink::Text(w)
        } else {
            Sink::Csv(Box::new(csv::Writer::from_writer(w)))
        }
    }

    fn is_controller(&self) -> bool {
        self.format != OutputFormat::Table
    }

    fn begin<W: std::io::Write>(
        &self,
        w: &mut Sink<W>,
        first: &str,
        site: bool,
        goal: &[String],
    ) -> Result<()> {
        let dof = self.robot.dof();
        let mut header = vec![first.to_string()];
        match (self.format, self.brand) {
            (OutputFormat::Table, _) => {
                if site {
                    header.push("site".into());
                }
                header.extend((1..=dof).map(|j| format!("v{j}")));
                header.extend(goal.iter().cloned());
                header.extend(COMPENSATED_COLUMNS.map(String::from));
            }
            (OutputFormat::Urscript, _) => {
                return w.text(&urscript_begin(self.robot, &self.source));
            }
            (_, Some(brand)) => {
                if site {
                    header.push("site".into());
                }
                header.extend(brand.columns(self.robot)?);
            }
            (_, None) => unreachable!("every controller format has a brand"),
        }
        w.record(&header)
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
        l: impl Fn(f64) -> f64,
        an: impl Fn(f64) -> f64,
    ) -> Result<()> {
        fields.clear();
        fields.push(label.to_string());
        match (self.format, self.brand) {
            (OutputFormat::Table, _) => {
                fields.extend(site);
                fields.extend(out.iter().map(|v| v.to_string()));
                fields.extend(goal.iter().cloned());
                fields.push(format!("{:.6e}", l(solved.position_error)));
                fields.push(
                    solved
                        .attitude_error
                        .map_or(String::new(), |e| format!("{:.6e}", an(e))),
                );
                fields.push(solved.iterations.to_string());
                fields.push(solved.flags.describe());
            }
            (OutputFormat::Urscript, _) => {
                Brand::Ur.values(self.robot, out, &mut self.joints);
                let text = match site {
                    Some(s) => format!("{label} ({s})"),
                    None => label.to_string(),
                };
                return w.text(&urscript_move(&text, &self.joints));
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

    fn end<W: std::io::Write>(&self, w: &mut Sink<W>) -> Result<()> {
        if self.format == OutputFormat::Urscript {
            w.text(urscript_end())?;
        }
        Ok(())
    }
}
