//! `kinecal compensate`: programs and targets through the calibrated model, row by row.

use std::io::Write as _;
use std::path::Path;

use anyhow::{anyhow, bail, Result};
use kinecal::compensate::{Compensator, Goal, NominalSeeds, Options, Solved};
use kinecal::identifiability::fmt_sig;
use kinecal::kinematics::{rot_zyx, Frame};
use kinecal::units::Quantity;
use nalgebra::Vector3;

use crate::args::CompensateArgs;
use crate::stream::{cell, Rows};
use crate::{load_robot, output, parse_spec, spec_value, EXIT_IMPLAUSIBLE};

/// What the input file holds.
enum Kind {
    /// `posture,v1..vn`.
    Program { readings: Vec<usize> },
    /// `target,x,y,z[,alpha,beta,gamma][,v1..vn]`.
    Targets {
        xyz: [usize; 3],
        euler: Option<[usize; 3]>,
        seed: Option<Vec<usize>>,
    },
}

/// Tells the layout from the header.
fn kind(rows: &Rows, dof: usize) -> Result<Kind> {
    let readings: Option<Vec<usize>> = (1..=dof).map(|j| rows.column(&format!("v{j}"))).collect();
    let reading = |h: &str| {
        h.strip_prefix('v')
            .and_then(|j| j.parse::<usize>().ok())
            .is_some_and(|j| (1..=dof).contains(&j))
    };
    let known = |extra: &[&str]| {
        rows.header
            .iter()
            .find(|h| !(extra.contains(&h.as_str()) || reading(h)))
    };
    if let Some(label) = rows.column("target") {
        let _ = label;
        let (Some(x), Some(y), Some(z)) = (rows.column("x"), rows.column("y"), rows.column("z"))
        else {
            bail!(
                "{}:1: a targets file needs the columns target,x,y,z (and optionally \
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
        if let Some(h) = known(&["target", "x", "y", "z", "alpha", "beta", "gamma"]) {
            bail!("{}:1: unexpected column `{h}` in a targets file", rows.file);
        }
        let any_v = rows.header.iter().any(|h| h.starts_with('v'));
        if any_v && readings.is_none() {
            bail!(
                "{}:1: seed readings need every column v1..v{dof}",
                rows.file
            );
        }
        return Ok(Kind::Targets {
            xyz: [x, y, z],
            euler,
            seed: readings,
        });
    }
    match (rows.column("posture"), readings) {
        (Some(_), Some(readings)) => {
            if let Some(h) = known(&["posture"]) {
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
    worst_position: f64,
    worst_attitude: f64,
}

impl Tally {
    fn add(&mut self, s: &Solved, reached_only: bool) {
        self.rows += 1;
        let f = &s.flags;
        if f.any() {
            self.flagged += 1;
        }
        self.unreachable += f.unreachable as usize;
        self.out_of_range += (f.out_of_range != 0) as usize;
        self.singular += f.singular as usize;
        self.branch += f.branch as usize;
        if !reached_only || !f.unreachable {
            self.worst_position = self.worst_position.max(s.position_error);
            self.worst_attitude = self.worst_attitude.max(s.attitude_error.unwrap_or(0.0));
        }
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
    let target = crate::target_named(&nominal, &a.site, "--site")?;
    let mut comp = Compensator::new(&calibrated, &nominal, options)
        .map_err(|e| anyhow!("--robot {} and --nominal {}: {e}", a.robot, a.nominal))?;
    let dof = nominal.dof();
    let mut rows = Rows::open(&a.input)?;
    let kind = kind(&rows, dof)?;
    if a.position_only && matches!(kind, Kind::Targets { .. }) {
        bail!("--position-only is for programs; a target without alpha,beta,gamma is a position");
    }
    let mut seeds = NominalSeeds::new(&nominal, options)
        .map_err(|e| anyhow!("--nominal {}: {e}", a.nominal))?;
    let mut tally = Tally::default();
    let mut staged = output::Staged::new();
    let l = |v: f64| units.from_si(Quantity::Length, v);
    let an = |v: f64| units.from_si(Quantity::Angle, v);
    staged.by_path(&a.out, |tmp| {
        let file = std::fs::File::create(tmp)?;
        let mut w = csv::Writer::from_writer(std::io::BufWriter::new(file));
        let first = match kind {
            Kind::Program { .. } => "posture",
            Kind::Targets { .. } => "target",
        };
        let mut header = vec![first.to_string()];
        header.extend((1..=dof).map(|j| format!("v{j}")));
        header
            .extend(["position_error", "attitude_error", "iterations", "flags"].map(String::from));
        w.write_record(&header)?;
        let mut out = vec![0.0; dof];
        let mut seed = vec![0.0; dof];
        let mut fields: Vec<String> = Vec::with_capacity(dof + 5);
        while let Some(line) = rows.advance()? {
            let (label, solved) = match &kind {
                Kind::Program { readings } => {
                    for (s, &c) in seed.iter_mut().zip(readings) {
                        *s = cell(&rows, line, c)?;
                    }
                    let col = rows.column("posture").expect("checked");
                    (
                        rows.field(col).to_string(),
                        comp.program(&seed, target, a.position_only, &mut out),
                    )
                }
                Kind::Targets {
                    xyz,
                    euler,
                    seed: cols,
                } => {
                    let col = rows.column("target").expect("checked");
                    let mut v = [0.0; 3];
                    for (k, &c) in xyz.iter().enumerate() {
                        v[k] = units.to_si(Quantity::Length, cell(&rows, line, c)?);
                    }
                    let p = Vector3::from(v);
                    let goal = match euler {
                        Some(e) => {
                            let mut r = [0.0; 3];
                            for (k, &c) in e.iter().enumerate() {
                                r[k] = units.to_si(Quantity::Angle, cell(&rows, line, c)?);
                            }
                            Goal::Pose(Frame {
                                rotation: rot_zyx(r[0], r[1], r[2]),
                                translation: p,
                            })
                        }
                        None => Goal::Position(p),
                    };
                    match cols {
                        Some(cols) => {
                            for (s, &c) in seed.iter_mut().zip(cols) {
                                *s = cell(&rows, line, c)?;
                            }
                        }
                        // The nominal model's solution nearest the previous row's (the middle
                        // of the ranges for the first): what the controller would command.
                        None => seeds.seed(&goal, target, &mut seed),
                    }
                    let s = comp.solve(&goal, target, &seed, &mut out);
                    if !s.flags.unreachable {
                        seeds.accept(&out);
                    }
                    (rows.field(col).to_string(), s)
                }
            };
            tally.add(&solved, false);
            fields.clear();
            fields.push(label);
            fields.extend(out.iter().map(|v| v.to_string()));
            fields.push(format!("{:.6e}", l(solved.position_error)));
            fields.push(
                solved
                    .attitude_error
                    .map_or(String::new(), |e| format!("{:.6e}", an(e))),
            );
            fields.push(solved.iterations.to_string());
            fields.push(solved.flags.describe());
            w.write_record(&fields)?;
        }
        w.flush()?;
        let mut inner = w.into_inner().map_err(|e| anyhow!("{e}"))?;
        inner.flush()?;
        Ok(())
    })?;
    if tally.rows == 0 {
        bail!("{}: no rows", rows.file);
    }
    staged.commit()?;
    eprintln!(
        "compensated {} rows into {}: {} flagged ({} unreachable, {} outside a joint range, {} \
         near a singularity, {} changing configuration); largest remaining error {} {}{}",
        tally.rows,
        a.out.display(),
        tally.flagged,
        tally.unreachable,
        tally.out_of_range,
        tally.singular,
        tally.branch,
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
    Ok(if tally.flagged > 0 {
        EXIT_IMPLAUSIBLE
    } else {
        0
    })
}
