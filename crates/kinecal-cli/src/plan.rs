//! `kinecal plan`: which postures to measure.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{bail, Result};
use kinecal::files::{detect_format, parse_postures};
use kinecal::identifiability::{fmt_sig, AnalysisOptions};
use kinecal::kinematics::Target;
use kinecal::observe::Dataset;
use kinecal::plan::{candidates, plan, Criterion, Plan, PlanRequest};
use kinecal::source::Source;
use kinecal::workflow::Selection;
use kinecal::{simulate, Robot};

use crate::args::{CriterionArg, PlanArgs};
use crate::{load_robot, output, residual_settings};

impl From<CriterionArg> for Criterion {
    fn from(c: CriterionArg) -> Criterion {
        match c {
            CriterionArg::D => Criterion::D,
            CriterionArg::A => Criterion::A,
            CriterionArg::I => Criterion::I,
            CriterionArg::E => Criterion::E,
            CriterionArg::O1 => Criterion::O1,
            CriterionArg::O2 => Criterion::O2,
            CriterionArg::O3 => Criterion::O3,
            CriterionArg::O4 => Criterion::O4,
            CriterionArg::O5 => Criterion::O5,
        }
    }
}

/// Where the candidates came from.
enum Origin {
    /// Sampled postures, or a postures file: observations assumed from --sites.
    Postures,
    /// An observation file: observations as its rows say.
    Observations,
}

/// The targets measured at each posture: `--sites`, or every site, or the end effector.
fn targets(robot: &Robot, sites: Option<&str>) -> Result<Vec<Target>> {
    let Some(list) = sites else {
        return Ok(if robot.sites.is_empty() {
            vec![Target::EndEffector]
        } else {
            (0..robot.sites.len()).map(Target::Site).collect()
        });
    };
    let mut out = Vec::new();
    for name in list.split(',').map(str::trim) {
        let t = crate::target_named(robot, name, "--sites")?;
        if !out.contains(&t) {
            out.push(t);
        }
    }
    Ok(out)
}

/// Whether `text` is a postures file (its header names no measured quantity).
fn is_postures_file(text: &str) -> bool {
    if detect_format(text) != 0 {
        return false;
    }
    let header = text
        .lines()
        .map(str::trim)
        .find(|l| !l.is_empty() && !l.starts_with('#'))
        .unwrap_or("")
        .trim_start_matches('\u{feff}')
        .to_ascii_lowercase();
    !header
        .split([',', ';', '\t'])
        .any(|c| c.trim().trim_matches('"') == "x")
}

/// Reads candidates or kept postures from a file.
fn read(
    path: &Path,
    robot: &Robot,
    targets: &[Target],
    position_only: bool,
) -> Result<(Dataset, Origin)> {
    let s = Source::read(path)?;
    if is_postures_file(&s.text) {
        let postures = parse_postures(&s.text, &s.name, robot)?;
        return Ok((
            candidates(robot, postures, targets, position_only),
            Origin::Postures,
        ));
    }
    // An observation file: its rows say what is measured; --position-only reads its poses as
    // positions (a tracker that measures the probe's position only).
    let opts = kinecal::files::ReadOptions {
        position_only,
        ..Default::default()
    };
    let data = kinecal::files::read_observations(&s.text, &s.name, robot, &opts)?;
    Ok((data, Origin::Observations))
}

/// Runs `kinecal plan`.
pub fn run(a: PlanArgs) -> Result<()> {
    let inputs: Vec<&Path> = [a.candidates.as_deref(), a.keep.as_deref()]
        .into_iter()
        .flatten()
        .chain(std::iter::once(Path::new(&a.robot)))
        .collect();
    let outputs: Vec<&Path> = std::iter::once(a.out.as_path())
        .chain(a.html.as_deref())
        .collect();
    output::check_distinct(&outputs, &inputs)?;
    let r = load_robot(&a.robot)?;
    let robot = &r.robot;
    let targets = targets(robot, a.sites.as_deref())?;
    let (pool, origin, described) = match (&a.candidates, a.sample) {
        (Some(path), _) => {
            let (d, o) = read(path, robot, &targets, a.position_only)?;
            let what = format!(
                "{} candidate postures from {}",
                d.postures.len(),
                path.display()
            );
            (d, o, what)
        }
        (None, Some(n)) => {
            if n == 0 {
                bail!("--sample must be at least 1");
            }
            let postures = simulate::sample_postures(robot, n, a.seed);
            (
                candidates(robot, postures, &targets, a.position_only),
                Origin::Postures,
                format!(
                    "{n} candidate postures sampled within the joint ranges (seed {})",
                    a.seed
                ),
            )
        }
        (None, None) => bail!("give --candidates FILE or --sample N"),
    };
    if matches!(origin, Origin::Observations) && a.sites.is_some() {
        bail!(
            "--sites describes postures; the candidates file is an observation file, whose rows \
             say what is measured"
        );
    }
    let keep = match &a.keep {
        Some(path) => read(path, robot, &targets, a.position_only)?.0,
        None => Dataset::default(),
    };
    if a.count == 0 {
        bail!("--count must be at least 1");
    }
    let (weights, orientation) = residual_settings(&a.residuals, robot)?;
    let req = PlanRequest {
        robot: robot.clone(),
        pool,
        keep,
        count: a.count,
        criterion: a.criterion.into(),
        selection: Selection::parse(&a.estimate, a.fix.as_deref(), robot)?,
        analysis: AnalysisOptions {
            weights,
            orientation,
            ..AnalysisOptions::default()
        },
        seed: a.seed,
    };
    if std::io::IsTerminal::is_terminal(&std::io::stderr()) {
        eprintln!("planning: {described} ...");
    }
    let p = plan(&req)?;

    let (csv, written) = p.chosen_file(robot, matches!(origin, Origin::Observations));
    let mut staged = output::Staged::new();
    staged.text(&a.out, &csv)?;
    if let Some(path) = &a.html {
        let page = kinecal_report::plan::html_plan(&p, robot, &req.pool, &described)
            .map_err(|e| anyhow::anyhow!("cannot draw the plan: {e}"))?;
        staged.text(path, &page)?;
    }
    staged.commit()?;
    if a.json {
        println!("{}", kinecal::plan::PlanReport::new(&p, robot).to_json());
    } else {
        print!("{}", text(&p, robot, &described));
    }
    eprintln!(
        "wrote the {} chosen {written} to {}{}",
        p.postures.iter().filter(|q| q.candidate.is_some()).count(),
        a.out.display(),
        a.html
            .as_ref()
            .map(|h| format!(" and the plan to {}", h.display()))
            .unwrap_or_default()
    );
    Ok(())
}

fn opt(v: Option<f64>) -> String {
    v.map(fmt_sig).unwrap_or_else(|| "n/a".into())
}

/// The plan as text.
pub fn text(p: &Plan, robot: &Robot, described: &str) -> String {
    let mut s = String::new();
    let n = p.parameters.len();
    let kept = p.postures.iter().filter(|q| q.candidate.is_none()).count();
    let chosen = p.postures.len() - kept;
    let _ = writeln!(s, "plan for {}: {described}", robot.name);
    let _ = writeln!(
        s,
        "chose {chosen} of {} candidates{}; {} residual rows for {n} parameters",
        p.pool_candidates,
        if kept > 0 {
            format!(", with {kept} kept postures")
        } else {
            String::new()
        },
        p.rows
    );
    let _ = writeln!(
        s,
        "parameters: {}",
        p.parameters
            .iter()
            .map(|&id| robot.param_name(id))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let _ = writeln!(
        s,
        "rank {} of {n}{}; condition number {}",
        p.rank,
        if p.rank < n {
            " (too few postures: the plan cannot determine every parameter)"
        } else {
            ""
        },
        opt(p.condition_number)
    );
    let _ = writeln!(
        s,
        "criterion {} ({}): {}",
        p.criterion.as_str(),
        p.criterion.describe(),
        opt(p.value)
    );
    if let Some(e) = p.efficiency {
        let _ = writeln!(
            s,
            "information per posture: {:.0} % of the candidates' average (D-efficiency)",
            100.0 * e
        );
    }
    if let Some(r) = &p.random {
        let _ = writeln!(
            s,
            "{} random plans of the same size: criterion median {}, information per posture \
             median {}; this plan is at least as good as {} of them",
            r.draws,
            opt(r.median_value),
            r.median_efficiency
                .map(|e| format!("{:.0} %", 100.0 * e))
                .unwrap_or_else(|| "n/a".into()),
            r.beaten
        );
    }
    let _ = writeln!(
        s,
        "search: greedy start, exchange {} swap{} in {} pass{}",
        p.exchanges,
        if p.exchanges == 1 { "" } else { "s" },
        p.passes,
        if p.passes == 1 { "" } else { "es" }
    );
    let _ = writeln!(
        s,
        "all criteria: {}",
        p.values
            .iter()
            .map(|(c, v)| format!("{} {}", c.as_str(), opt(*v)))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let _ = writeln!(
        s,
        "\npostures (leverage: how many of the {n} parameters' worth of information each carries)"
    );
    let dof = robot.dof();
    let _ = write!(s, "  {:<10} {:>8}", "posture", "leverage");
    for j in 0..dof {
        let _ = write!(s, " {:>10}", format!("v{}", j + 1));
    }
    let _ = writeln!(s);
    for q in &p.postures {
        let _ = write!(
            s,
            "  {:<10} {:>8.3}",
            if q.candidate.is_none() {
                format!("{} (kept)", q.label)
            } else {
                q.label.clone()
            },
            q.leverage
        );
        for v in &q.readings {
            let _ = write!(s, " {:>10}", fmt_sig(*v));
        }
        let _ = writeln!(s);
    }
    s
}
