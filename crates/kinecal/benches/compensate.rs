//! Compensation throughput, one core: programs of an arm compensated for its perturbed twin
//! (1 mm, 0.3 deg), full poses; the poses those programs mean as Cartesian targets seeded by
//! the program's readings (what `fk` then `compensate` do); and Cartesian targets without
//! seeds (positions and poses the twin reaches inside its joint ranges), searched for a usable
//! solution. Three arms: a random 6-joint arm (the general closed form, see
//! `apps::compensate`'s `general` module; its cases keep their names), a UR10 (`ur10/`, the
//! UR-type closed form) and the ABB IRB 120 of `examples/robots` (`irb120/`, a spherical
//! wrist).
//!
//! Run: `cargo bench -p kinecal --bench compensate`. With `KINECAL_BENCH_CPU=1` it prints
//! instead, for each case, rows per CPU second of this thread (median of 5 rounds, the cases
//! alternating) and how many rows were flagged, and why; `KINECAL_BENCH_CPU=seeded` runs
//! only the cases whose names contain `seeded` (`ur10/` only the UR10's; `=NAME` the case so
//! named).
//! `KINECAL_BENCH_COST=1` (with `KINECAL_BENCH_CPU`) then prints where each target case's time
//! goes: per set of flags, its rows, their CPU time and the solver's forward kinematics
//! (deterministic: two builds' costs compared where rows per second are noisy).
//! `KINECAL_BENCH_DUMP=FILE` (with `KINECAL_BENCH_CPU`) appends every row's flags, remaining
//! errors, conditioning and readings to FILE, from a fresh search per case: two builds'
//! answers compared.

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use kinecal::apps::compensate::{Compensator, Goal, Options, Solved, TargetSearch};
use kinecal::apps::simulate::{self, PerturbStd};
use kinecal::{Chain, JointKind, Robot, Target, Workspace};

/// The arms: (prefix of the case names, nominal with ranges set, calibrated twin).
fn robots() -> Vec<(&'static str, Robot, Robot)> {
    use kinecal::import::dh::{robot_from_dh, Convention, DhRow};
    use std::f64::consts::FRAC_PI_2;
    let row = |a: f64, alpha: f64, d: f64| DhRow::new(JointKind::Revolute, a, alpha, d, 0.0);
    // The UR10's data-sheet DH (the nominal of ../shared/data/ipa_ur10_tracker).
    let ur10 = robot_from_dh(
        "UR10",
        kinecal::units::Units::default(),
        &[
            row(0.0, FRAC_PI_2, 0.1273),
            row(-0.612, 0.0, 0.0),
            row(-0.5723, 0.0, 0.0),
            row(0.0, FRAC_PI_2, 0.163941),
            row(0.0, -FRAC_PI_2, 0.1157),
            row(0.0, 0.0, 0.0922),
        ],
        Convention::Standard,
    );
    let irb120 = kinecal::model::robot_file::parse_robot_toml(
        include_str!("../../../examples/robots/abb_irb120.toml"),
        "abb_irb120.toml",
    )
    .unwrap();
    vec![
        (
            "",
            twin(simulate::random_robot(&[JointKind::Revolute; 6], 21)),
        ),
        ("ur10/", twin(ur10)),
        ("irb120/", twin(irb120)),
    ]
    .into_iter()
    .map(|(p, (n, c))| (p, n, c))
    .collect()
}

/// The nominal arm with ranges set (the file's, else +-150 deg) and its calibrated twin.
fn twin(mut nominal: Robot) -> (Robot, Robot) {
    for j in 0..6 {
        nominal.joints[j].range = Some(simulate::reading_range(&nominal, j));
    }
    let std = PerturbStd {
        length: 1e-3,
        angle: 0.3f64.to_radians(),
        slope_fraction: 0.002,
    };
    let calibrated = simulate::perturb(&nominal, std, 22);
    (nominal, calibrated)
}

/// The four workloads over 1,000 postures: (name, goals, seeds); no goals for programs.
type Case = (String, Vec<Goal>, Option<Vec<Vec<f64>>>);

fn cases(prefix: &str, nominal: &Robot, calibrated: &Robot) -> (Vec<Vec<f64>>, Vec<Case>) {
    let postures: Vec<Vec<f64>> = simulate::sample_postures(nominal, 1000, 5)
        .into_iter()
        .map(|p| p.readings)
        .collect();
    let frames = |robot: &Robot| -> Vec<_> {
        let chain = Chain::new(robot);
        let mut ws = Workspace::new(robot);
        postures
            .iter()
            .map(|p| {
                chain.forward(p, &mut ws);
                chain.target_frame(&ws, Target::EndEffector)
            })
            .collect()
    };
    // Seeded: the poses the program means (the nominal model's), seeded by its readings.
    let meant = frames(nominal);
    // Unseeded: goals the calibrated twin reaches at postures inside its ranges.
    let reached = frames(calibrated);
    let cases = vec![
        (format!("{prefix}1000_programs_full_pose"), Vec::new(), None),
        (
            format!("{prefix}1000_targets_pose_seeded"),
            meant.iter().map(|f| Goal::Pose(*f)).collect(),
            Some(postures.clone()),
        ),
        (
            format!("{prefix}1000_targets_position_unseeded"),
            reached
                .iter()
                .map(|f| Goal::Position(f.translation))
                .collect(),
            None,
        ),
        (
            format!("{prefix}1000_targets_pose_unseeded"),
            reached.iter().map(|f| Goal::Pose(*f)).collect(),
            None,
        ),
    ];
    (postures, cases)
}

/// Runs one case once over its rows, calling `each` with every solution.
fn run(
    comp: &mut Compensator<'_>,
    search: &mut TargetSearch<'_>,
    postures: &[Vec<f64>],
    case: &Case,
    out: &mut [f64],
    mut each: impl FnMut(&Solved, &[f64]),
) {
    let (_, goals, seeds) = case;
    if goals.is_empty() {
        for p in postures {
            let s = black_box(comp.program(p, Target::EndEffector, false, out));
            each(&s, out);
        }
    } else {
        for (k, g) in goals.iter().enumerate() {
            let seed = seeds.as_ref().map(|s| s[k].as_slice());
            let s = black_box(search.solve(g, Target::EndEffector, seed, out));
            each(&s, out);
        }
    }
}

fn compensation(c: &mut Criterion) {
    let cpu = std::env::var("KINECAL_BENCH_CPU").ok();
    if cpu.is_some() {
        println!("case                                     rows/CPU s  flagged (unreachable, range, singular, branch, configuration)");
    }
    for (prefix, nominal, calibrated) in robots() {
        let (postures, cases) = cases(prefix, &nominal, &calibrated);
        let mut comp = Compensator::new(&calibrated, &nominal, Options::default()).unwrap();
        let mut out = vec![0.0; 6];
        if let Some(only) = &cpu {
            let cases: Vec<Case> = cases
                .into_iter()
                .filter(|c| match only.strip_prefix('=') {
                    Some(name) => c.0 == name,
                    None => only == "1" || c.0.contains(only.as_str()),
                })
                .collect();
            if !cases.is_empty() {
                cpu_figures(&calibrated, &nominal, &mut comp, &postures, &cases);
            }
            continue;
        }
        let mut group = c.benchmark_group("compensate_6R");
        group.throughput(Throughput::Elements(postures.len() as u64));
        for case in &cases {
            // A fresh search per case: no case starts from another's last solution.
            let mut search = TargetSearch::new(&calibrated, &nominal, Options::default()).unwrap();
            group.bench_function(&case.0, |b| {
                b.iter(|| run(&mut comp, &mut search, &postures, case, &mut out, |_, _| {}))
            });
        }
        group.finish();
    }
}

/// CPU time of this thread (ns), from `CLOCK_THREAD_CPUTIME_ID` (to the nanosecond: the
/// first field of `/proc/thread-self/schedstat`, read before, moved in 4 ms ticks on some
/// kernels, which rounded a case of 1,000 rows to 250k, 125k, 83k, 62.5k, 50k rows/s).
fn thread_cpu_ns() -> u64 {
    let mut t = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `t` is a valid timespec for the call to write.
    let r = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut t) };
    assert_eq!(r, 0, "clock_gettime(CLOCK_THREAD_CPUTIME_ID)");
    t.tv_sec as u64 * 1_000_000_000 + t.tv_nsec as u64
}

fn cpu_figures(
    calibrated: &Robot,
    nominal: &Robot,
    comp: &mut Compensator<'_>,
    postures: &[Vec<f64>],
    cases: &[Case],
) {
    let mut out = vec![0.0; 6];
    let mut searches: Vec<TargetSearch<'_>> = cases
        .iter()
        .map(|_| TargetSearch::new(calibrated, nominal, Options::default()).unwrap())
        .collect();
    let mut rates = vec![Vec::new(); cases.len()];
    let mut flagged = vec![[0usize; 6]; cases.len()];
    let mut dump = std::env::var("KINECAL_BENCH_DUMP").ok().map(|path| {
        std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(path)
            .expect("KINECAL_BENCH_DUMP: a file to append to")
    });
    for round in 0..6 {
        for (k, case) in cases.iter().enumerate() {
            if round == 0 {
                if let Some(file) = dump.as_mut() {
                    use std::io::Write;
                    let mut row = 0;
                    run(comp, &mut searches[k], postures, case, &mut out, |s, v| {
                        writeln!(
                            file,
                            "{} {row} {:?} {:e} {:e} {:e} {:?}",
                            case.0,
                            s.flags,
                            s.position_error,
                            s.attitude_error.unwrap_or(0.0),
                            s.conditioning,
                            v,
                        )
                        .unwrap();
                        row += 1;
                    });
                }
            }
            let mut counts = [0usize; 6];
            let t = thread_cpu_ns();
            run(comp, &mut searches[k], postures, case, &mut out, |s, _| {
                let f = &s.flags;
                counts[0] += f.any() as usize;
                counts[1] += f.unreachable as usize;
                counts[2] += (f.out_of_range != 0) as usize;
                counts[3] += f.singular as usize;
                counts[4] += f.branch as usize;
                counts[5] += f.configuration as usize;
            });
            let dt = (thread_cpu_ns() - t) as f64 * 1e-9;
            // Round 0 warms up (and builds the searches' tables).
            if round > 0 {
                rates[k].push(postures.len() as f64 / dt);
            }
            flagged[k] = counts;
        }
    }
    if std::env::var_os("KINECAL_BENCH_COST").is_some() {
        for (k, case) in cases.iter().enumerate() {
            cost_by_flags(&mut searches[k], case, &mut out);
        }
    }
    for (k, case) in cases.iter().enumerate() {
        let r = &mut rates[k];
        r.sort_by(f64::total_cmp);
        let f = flagged[k];
        println!(
            "{:<40} {:>11.0}  {} ({}, {}, {}, {}, {})",
            case.0,
            r[r.len() / 2],
            f[0],
            f[1],
            f[2],
            f[3],
            f[4],
            f[5]
        );
    }
}

/// Prints, per set of flags the rows of a target case came back with, how many rows, their CPU
/// time and the solver's forward kinematics (a round of the case with `search` as it is).
fn cost_by_flags(search: &mut TargetSearch<'_>, case: &Case, out: &mut [f64]) {
    let (name, goals, seeds) = case;
    // (rows, CPU ns, forward kinematics) per flags, in the order first met.
    let mut by: Vec<(String, [u64; 3])> = Vec::new();
    for (k, goal) in goals.iter().enumerate() {
        let seed = seeds.as_ref().map(|s| s[k].as_slice());
        let (t, e) = (thread_cpu_ns(), search.evaluations());
        let s = search.solve(goal, Target::EndEffector, seed, out);
        let cost = [1, thread_cpu_ns() - t, search.evaluations() - e];
        let flags = if s.flags.any() {
            s.flags.describe()
        } else {
            "usable".to_string()
        };
        match by.iter_mut().find(|(f, _)| *f == flags) {
            Some((_, c)) => c.iter_mut().zip(cost).for_each(|(c, v)| *c += v),
            None => by.push((flags, cost)),
        }
    }
    for (flags, [rows, ns, fk]) in by {
        println!(
            "  {name}: {rows} {} {flags}: {:.2} ms CPU, {:.1} forward kinematics per row",
            if rows == 1 { "row" } else { "rows" },
            ns as f64 * 1e-6,
            fk as f64 / rows as f64
        );
    }
}

criterion_group!(benches, compensation);
criterion_main!(benches);
