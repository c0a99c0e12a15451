//! The `kinecal` command: a thin layer over the `kinecal` library. Each job command maps its
//! flags onto the library's spec of the job ([`door`]), the library runs it, and the command
//! prints the job's document as text ([`render`]); no calibration arithmetic happens here.

mod analyze;
mod args;
mod batch;
mod calibrate;
mod demo;
mod door;
/// The workspace's mutation driver, for the manifest reader's fuzz tests (`batch.rs`).
#[cfg(test)]
#[path = "../../kinecal/tests/fuzz_driver/mod.rs"]
mod fuzz_driver;
mod history;
mod iso9283;
mod plan;
mod render;
mod report;

use std::process::ExitCode;

use anyhow::{anyhow, bail, Context as _, Result};
use clap::{CommandFactory as _, FromArgMatches as _};

use args::{
    Cli, Command, CurvesCommand, DatasetArgs, ExportCommand, ImportCommand, Iso9283Command,
};
use kinecal::spec::{Document, Job};
use kinecal::{Setting, Warning};

pub use door::{EXIT_FLAGGED, EXIT_NOT_CONVERGED};

/// Exit code for errors in the input (files, parameter lists, unsolvable problems).
const EXIT_INPUT: u8 = 1;

/// The command line's definition, every value free to start with `-` (a negative number,
/// `-1`, is a value, not a flag: a bad value is then named as such).
fn command() -> clap::Command {
    fn negatives(c: clap::Command) -> clap::Command {
        c.allow_negative_numbers(true).mut_subcommands(negatives)
    }
    negatives(Cli::command())
}

mod heap {
    /// On Linux with glibc: the heap's first 64 MB are reserved in one step and advised for
    /// 2 MB pages (as glibc's own `glibc.malloc.hugetlb=1` tunable would advise every growth),
    /// so that a run touches, and the kernel zeroes and maps, that memory a 2 MB page at a
    /// time rather than 4 KB at a time; and blocks of up to 32 MB come from the heap and stay
    /// there when freed (up to 512 MB free at its top), reused instead of being unmapped and
    /// faulted in again. A 10,000-pose calibration faults 4 times fewer pages and takes about
    /// 12 % less CPU; its peak memory grows by about 6 MB. The heap's head, below the first
    /// advised page, is filled by a block kept unused, so that a small run's memory comes from
    /// the advised part too. Advice only: where the kernel gives no huge pages, only the
    /// thresholds change.
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    pub(super) fn prefer_huge_pages() {
        const HUGE: usize = 2 << 20;
        // SAFETY: mallopt only changes malloc's thresholds; sbrk(0) reads the break; the
        // block is malloc's and freed at once; madvise only advises on whole pages of the
        // heap malloc just grew (inside its own mapping); the block that fills the heap's head
        // is malloc's, kept for the life of the process (only its address is read).
        unsafe {
            libc::mallopt(libc::M_MMAP_THRESHOLD, 32 << 20);
            libc::mallopt(libc::M_TRIM_THRESHOLD, 512 << 20);
            libc::mallopt(libc::M_TOP_PAD, 64 << 20);
            let before = libc::sbrk(0) as usize;
            // black_box: a malloc freed unused would be optimised away.
            let block = std::hint::black_box(libc::malloc(1 << 20));
            if block.is_null() {
                return;
            }
            libc::free(block);
            let after = libc::sbrk(0) as usize;
            // sbrk returns (void *) -1 when it fails.
            if before == usize::MAX || after == usize::MAX {
                return;
            }
            let start = before.next_multiple_of(HUGE);
            let end = after / HUGE * HUGE;
            if end > start {
                libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE);
                // Below the first advised page lies the heap's head (up to 2 MB, where the
                // kernel placed the break), in 4 KB pages: a small run's whole working set
                // would sit there and be faulted in 4 KB at a time (a 1,000-pose calibration:
                // 540 faults, against 270). A block from the top of the heap up to that page
                // is taken and kept, its memory never touched: what is allocated next comes
                // from the advised part. The freed block above was carved from the top, so its
                // chunk (16 bytes before it) is where the top starts; a request of `gap - 8`
                // bytes makes a chunk of exactly `gap` (a multiple of 16: both ends are). The
                // top may start below `before` (what malloc had left of the heap it made
                // before `main`, some 100 kB): the gap then exceeds 2 MB when the break lay
                // just past a 2 MB boundary (one start in 16 or so).
                let top = block as usize - 16;
                let gap = start.saturating_sub(top);
                if (64..2 * HUGE).contains(&gap) {
                    std::hint::black_box(libc::malloc(gap - 8));
                }
            }
        }
    }

    #[cfg(not(all(target_os = "linux", target_env = "gnu")))]
    pub(super) fn prefer_huge_pages() {}

    /// The allocator: the system's, except that blocks of a page's alignment and at least
    /// [`PAGED`] bytes are mapped on their own, outside the heap. Such blocks are scratch
    /// space sized for the largest problems, of which a run touches little: the matrix
    /// products' packing buffers (faer's `private-gemm`: 4 MB per thread on this machine, a
    /// few hundred KB of it used by a calibration's Gram matrices). On the heap, advised for
    /// 2 MB pages, each part touched costs the kernel a 2 MB page to zero; mapped on their
    /// own, they get 4 KB pages as they are touched.
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    pub(super) struct Allocator;

    /// The smallest block [`Allocator`] maps on its own (when page-aligned).
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    const PAGED: usize = 1 << 20;

    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    impl Allocator {
        const PAGE: usize = 4096;

        fn paged(layout: std::alloc::Layout) -> bool {
            layout.align() == Self::PAGE && layout.size() >= PAGED
        }
    }

    // SAFETY: every block is the system allocator's, or an anonymous private mapping of its
    // layout's size, page-aligned (its alignment); each is released by the way it was made,
    // which `paged` tells from the layout alone (a block keeps its layout).
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    unsafe impl std::alloc::GlobalAlloc for Allocator {
        unsafe fn alloc(&self, layout: std::alloc::Layout) -> *mut u8 {
            if Self::paged(layout) {
                // SAFETY: a fresh anonymous mapping; the kernel picks the address.
                let p = unsafe {
                    libc::mmap(
                        std::ptr::null_mut(),
                        layout.size(),
                        libc::PROT_READ | libc::PROT_WRITE,
                        libc::MAP_PRIVATE | libc::MAP_ANONYMOUS,
                        -1,
                        0,
                    )
                };
                if p == libc::MAP_FAILED {
                    std::ptr::null_mut()
                } else {
                    p.cast()
                }
            } else {
                // SAFETY: forwarded as given.
                unsafe { std::alloc::System.alloc(layout) }
            }
        }

        unsafe fn alloc_zeroed(&self, layout: std::alloc::Layout) -> *mut u8 {
            if Self::paged(layout) {
                // SAFETY: as `alloc`; an anonymous mapping is zeroed.
                unsafe { self.alloc(layout) }
            } else {
                // SAFETY: forwarded as given.
                unsafe { std::alloc::System.alloc_zeroed(layout) }
            }
        }

        unsafe fn dealloc(&self, ptr: *mut u8, layout: std::alloc::Layout) {
            if Self::paged(layout) {
                // SAFETY: `ptr` is the mapping `alloc` made for this layout.
                unsafe { libc::munmap(ptr.cast(), layout.size()) };
            } else {
                // SAFETY: forwarded as given.
                unsafe { std::alloc::System.dealloc(ptr, layout) }
            }
        }

        unsafe fn realloc(
            &self,
            ptr: *mut u8,
            layout: std::alloc::Layout,
            new_size: usize,
        ) -> *mut u8 {
            // SAFETY: the caller's layout and size, as `GlobalAlloc::realloc` requires.
            let new =
                unsafe { std::alloc::Layout::from_size_align_unchecked(new_size, layout.align()) };
            if !Self::paged(layout) && !Self::paged(new) {
                // SAFETY: forwarded as given (the system's block either way).
                return unsafe { std::alloc::System.realloc(ptr, layout, new_size) };
            }
            // Across the two kinds: a new block, the contents copied, the old one released.
            // SAFETY: `new` is a valid layout (the caller's alignment, a size it allows).
            let to = unsafe { self.alloc(new) };
            if !to.is_null() {
                // SAFETY: both blocks hold at least the smaller size and do not overlap.
                unsafe {
                    std::ptr::copy_nonoverlapping(ptr, to, layout.size().min(new_size));
                    self.dealloc(ptr, layout);
                }
            }
            to
        }
    }
}

#[cfg(all(target_os = "linux", target_env = "gnu"))]
#[global_allocator]
static ALLOCATOR: heap::Allocator = heap::Allocator;

fn main() -> ExitCode {
    // Output piped into `head` and closed: end quietly, as other command-line tools do, rather
    // than panic on the failed write.
    #[cfg(unix)]
    // SAFETY: restoring the default disposition of SIGPIPE before any thread or I/O exists.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    heap::prefer_huge_pages();
    kinecal::files::output::remove_temporaries_on_signals();
    let cli = Cli::from_arg_matches(&command().get_matches()).unwrap_or_else(|e| e.exit());
    QUIET.store(cli.quiet, std::sync::atomic::Ordering::Relaxed);
    match run(cli.command) {
        Ok(code) => ExitCode::from(code),
        Err(e) => {
            eprintln!("error: {}", in_flags(&e));
            if let Some(hint) = e.downcast_ref::<kinecal::Error>().and_then(hint) {
                eprintln!("hint: {hint}");
            }
            ExitCode::from(EXIT_INPUT)
        }
    }
}

/// Runs a command: its job's spec from its flags ([`door`]), the job, its document shown;
/// the exit code.
fn run(cmd: Command) -> Result<u8> {
    match cmd {
        Command::Demo => demo::run().map(|()| 0),
        Command::Calibrate(mut a) => {
            a.quiet = quiet();
            calibrate::run(a.0)
        }
        Command::Analyze(a) => {
            door::analyze(&a).and_then(|s| job(s.into(), &a.door, |d| analyze::show(d, &a)))
        }
        Command::Plan(a) => {
            door::plan(&a).and_then(|s| job(s.into(), &a.door, |d| plan::show(d, a.json)))
        }
        Command::Predict(a) => {
            door::predict(&a).and_then(|s| job(s.into(), &a.door, render::prediction))
        }
        Command::Compensate(a) => door::compensate(&a).and_then(|s| job(s.into(), &a.door, |_| ())),
        Command::Check(a) => {
            door::check(&a).and_then(|s| job(s.into(), &a.door, |d| render::check(d, a.json)))
        }
        Command::Fk(a) => door::fk(&a).and_then(|s| job(s.into(), &a.door, |_| ())),
        Command::Simulate(a) => door::simulate(&a).and_then(|s| job(s.into(), &a.door, |_| ())),
        Command::Import(c) => import(c),
        Command::Export(c) => export(c),
        Command::Curves(c) => curves(c),
        Command::Iso9283(c) => iso9283_job(c),
        Command::Report(a) => door::report(&a).and_then(|s| job(s.into(), &a.door, |_| ())),
        Command::History(c) => history::run(c),
        Command::Batch(mut a) => {
            a.quiet = quiet();
            batch::run(a.0)
        }
        Command::Dataset(a) => dataset(a.0).map(|()| 0),
        Command::Completions(a) => {
            clap_complete::generate(a.shell, &mut command(), "kinecal", &mut std::io::stdout());
            Ok(0)
        }
    }
}

/// `kinecal import`: a robot from another convention.
fn import(c: ImportCommand) -> Result<u8> {
    match c {
        ImportCommand::Urdf(a) => {
            door::import_urdf(&a).and_then(|s| job(s.into(), &a.door, |_| ()))
        }
        ImportCommand::Dh(a) => door::import_dh(&a).and_then(|s| job(s.into(), &a.door, |_| ())),
        ImportCommand::Poe(a) => door::import_poe(&a).and_then(|s| job(s.into(), &a.door, |_| ())),
        ImportCommand::Ur(a) => door::import_ur(&a).and_then(|s| job(s.into(), &a.door, |_| ())),
    }
}

/// `kinecal export`: a robot for a controller or another tool.
fn export(c: ExportCommand) -> Result<u8> {
    match c {
        ExportCommand::Urdf(a) => {
            door::export_urdf(&a).and_then(|s| job(s.into(), &a.door, render::export))
        }
        ExportCommand::Ros(a) => {
            door::export_ros(&a).and_then(|s| job(s.into(), &a.door, render::export))
        }
        ExportCommand::Ur(a) => {
            door::export_ur(&a).and_then(|s| job(s.into(), &a.door, render::export))
        }
        ExportCommand::Dh(a) => {
            door::export_dh(&a).and_then(|s| job(s.into(), &a.door, render::export))
        }
        ExportCommand::Joints(a) => {
            door::export_joints(&a).and_then(|s| job(s.into(), &a.door, render::export))
        }
        ExportCommand::Stiffness(a) => {
            door::export_stiffness(&a).and_then(|s| job(s.into(), &a.door, render::export))
        }
        ExportCommand::Gltf(a) => {
            door::export_gltf(&a).and_then(|s| job(s.into(), &a.door, render::export))
        }
        ExportCommand::CameraInfo(a) => {
            door::export_camera_info(&a).and_then(|s| job(s.into(), &a.door, render::export))
        }
    }
}

/// `kinecal curves`: characteristic curves.
fn curves(c: CurvesCommand) -> Result<u8> {
    let (spec, door) = match &c {
        CurvesCommand::Pose(a) => (door::curves_pose(a)?, &a.job.door),
        CurvesCommand::Objective(a) => (door::curves_objective(a)?, &a.job.door),
    };
    // With the table on standard output (`--out -`), what the curves show goes to standard
    // error.
    let table_out = spec.out.as_deref() == Some("-");
    job(spec.into(), door, |d| render::curves(d, table_out))
}

/// `kinecal iso9283`: the test poses, a simulated or measured log, and its figures.
fn iso9283_job(c: Iso9283Command) -> Result<u8> {
    match c {
        Iso9283Command::Plan(a) => {
            door::iso9283_plan(&a).and_then(|s| job(s.into(), &a.door, iso9283::show))
        }
        Iso9283Command::Simulate(a) => {
            door::iso9283_simulate(&a).and_then(|s| job(s.into(), &a.door, |_| ()))
        }
        Iso9283Command::Log(a) => {
            door::iso9283_log(&a).and_then(|s| job(s.into(), &a.door, |_| ()))
        }
        Iso9283Command::Evaluate(a) => {
            door::iso9283_evaluate(&a).and_then(|s| job(s.into(), &a.door, iso9283::show))
        }
    }
}

/// `--quiet` (global: every command takes it).
static QUIET: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Whether `--quiet` was given.
pub fn quiet() -> bool {
    QUIET.load(std::sync::atomic::Ordering::Relaxed)
}

/// Progress of a job: a spinner on standard error with the time since the start and what the
/// job is doing now (`predicting: 40000 of 100000 postures`, `planning: posture 12 of 30`,
/// `prediction: fold 4 of 13`), drawn only on a terminal and not with `--quiet`.
#[derive(Default)]
pub struct Talk {
    bar: Option<indicatif::ProgressBar>,
    /// The latest message.
    latest: String,
}

impl Talk {
    /// A display for this process: hidden when `--quiet` or standard error is not a terminal.
    pub fn new() -> Talk {
        Talk::default()
    }

    fn shown(&self) -> bool {
        !quiet() && std::io::IsTerminal::is_terminal(&std::io::stderr())
    }

    /// Clears the display.
    pub fn done(&mut self) {
        if let Some(bar) = self.bar.take() {
            bar.finish_and_clear();
        }
    }
}

impl kinecal::spec::Progress for Talk {
    fn phase(&mut self, phase: kinecal::workflow::Phase) {
        kinecal::spec::Progress::say(self, phase.as_str());
    }

    fn say(&mut self, what: &str) {
        what.trim_end_matches([' ', '.'])
            .clone_into(&mut self.latest);
        if self.bar.is_none() && self.shown() {
            let bar = indicatif::ProgressBar::new_spinner();
            bar.set_style(
                indicatif::ProgressStyle::with_template("{spinner} {elapsed} {msg}")
                    .expect("a valid template"),
            );
            bar.enable_steady_tick(std::time::Duration::from_millis(120));
            self.bar = Some(bar);
        }
        if let Some(bar) = &self.bar {
            bar.set_message(self.latest.clone());
        }
    }
}

impl Drop for Talk {
    fn drop(&mut self) {
        self.done();
    }
}

/// Runs `job` (its spec made of the command line) and shows its document with `show` on
/// standard output, then what it said on standard error: the exit code of its status.
fn job(job: Job, door: &args::SpecArgs, show: impl FnOnce(&Document)) -> Result<u8> {
    let mut talk = Talk::new();
    let done = door::run(job, door, &mut talk, &[]);
    talk.done();
    let Some(done) = done? else {
        return Ok(0);
    };
    show(&done.document);
    door::say(&done.messages);
    Ok(door::exit_code(done.status))
}

/// An error and its causes, as `{e:#}` words them, with the library's settings named by the
/// command line's flags.
fn in_flags(e: &anyhow::Error) -> String {
    e.chain()
        .map(|cause| match cause.downcast_ref::<kinecal::Error>() {
            Some(kinecal::Error::InvalidOption { setting, message }) => {
                format!("{}: {message}", named(*setting))
            }
            _ => cause.to_string(),
        })
        .collect::<Vec<_>>()
        .join(": ")
}

/// A setting as this command line gave it: its flag when the flag was given, else its key in
/// the `--spec` file when there is one.
fn named(setting: Setting) -> String {
    let flag = flag_of(setting);
    let args: Vec<String> = std::env::args().collect();
    let given = flag.split('/').any(|f| {
        args.iter()
            .any(|a| a == f || a.strip_prefix(f).is_some_and(|rest| rest.starts_with('=')))
    });
    let spec = args
        .iter()
        .position(|a| a == "--spec")
        .and_then(|i| args.get(i + 1))
        .or_else(|| {
            args.iter()
                .find_map(|a| a.strip_prefix("--spec=").map(|_| a))
        });
    match spec {
        Some(file) if !given => {
            format!("{}: {}", file.trim_start_matches("--spec="), setting.key())
        }
        _ => flag.to_string(),
    }
}

/// The command-line flag behind a library setting: the one table.
pub fn flag_of(setting: Setting) -> &'static str {
    match setting {
        Setting::OutlierThreshold => "--outlier-sigma",
        Setting::PruningThreshold => "--prune",
        Setting::Rcond => "--rcond",
        Setting::HoldoutFraction => "--holdout",
        Setting::Folds => "--folds",
        Setting::ModelCandidate => "--choose",
        Setting::PlanCandidates => "--candidates",
        Setting::PlanCount => "--count",
        Setting::PlanCriterion => "--criterion",
        Setting::HuberScale => "--huber-scale",
        // Set by the library from a fit's residuals, never from the command line.
        Setting::NoiseScale => "noise scale",
        Setting::CheckThreshold => "--threshold",
        Setting::ParameterChange => "--perturb",
        Setting::Sweep => "--from/--to/--span/--points",
        Setting::Span => "--span",
        Setting::NominalRobot => "--nominal",
        Setting::ChainBase => "--base",
        Setting::ChainTip => "--tip",
        Setting::Robot => "--robot",
        Setting::InitialRobot => "--initial",
        Setting::Observations => "--data/--distances/--contacts",
        // A spec file's `kind`: the command line's options are the kinds.
        Setting::ObservationKind => "kind",
        Setting::Columns => "--columns",
        Setting::LengthUnit => "--length-unit",
        Setting::AngleUnit => "--angle-unit",
        Setting::Weights => "--weights",
        Setting::MaxIterations => "--max-iter",
        Setting::Validation => "--validate/--holdout/--folds",
        Setting::Configuration => "--configuration",
        Setting::OutputFormat => "--format",
        Setting::Prior => "--prior",
        Setting::TotalMass => "--total-mass",
        Setting::Priority => "--priority",
        Setting::PlanSample => "--sample",
        Setting::PlanKeep => "--keep",
        Setting::Sites => "--sites",
        Setting::Target => "--target",
        Setting::Site => "--site",
        Setting::Postures => "--postures",
        Setting::Sample => "--sample",
        Setting::Report => "--report",
        Setting::Tolerance => "--tolerance",
        Setting::Singular => "--singular",
        Setting::Branch => "--branch",
        Setting::Output => "--out",
        Setting::Input => "--in",
        Setting::Cube => "--cube",
        Setting::Resolution => "--resolution",
        Setting::Cycles => "--cycles",
        Setting::Noise => "--noise",
        Setting::PerturbStd => "--perturb-std",
        Setting::Roles => "--roles",
        Setting::Template => "--template",
        Setting::Convention => "--convention",
        Setting::Calibrated => "--calibrated/--calibration",
        Setting::Estimate => "--estimate",
        Setting::Fix => "--fix",
        Setting::History => "--db",
        Setting::RobotId => "--robot-id",
        Setting::At => "--at",
        Setting::Now => "--now",
        Setting::DriftSigma => "--sigma",
        Setting::Horizon => "--horizon",
        Setting::Baseline => "--baseline",
        Setting::CalibrationId => "--id",
        Setting::Quantities => "--param",
        Setting::Dump => "DUMP",
        Setting::Note => "--note",
        Setting::Seed => "--seed",
        Setting::Repeats => "--repeats",
        Setting::ProgramName => "--name",
        Setting::Speed => "--speed",
        Setting::Zone => "--zone",
        Setting::Camera => "--camera",
        Setting::Board => "--board",
        Setting::MinPoints => "--min-points",
        Setting::Readings => "--readings",
        // A setting of a later kinecal: named in the library's words.
        _ => setting.name(),
    }
}

/// What the command line adds to a library error: which option to use.
fn hint(e: &kinecal::Error) -> Option<&'static str> {
    match e {
        kinecal::Error::ChainEnd { .. } => Some("--base LINK and --tip LINK choose the chain"),
        kinecal::Error::SingularNormalEquations { .. } => {
            Some("use --method lm or --method svd, or --estimate identifiable")
        }
        kinecal::Error::TooFewResiduals { .. } => Some(
            "--estimate identifiable estimates only what the data determines; --prior holds the \
             rest",
        ),
        kinecal::Error::ExportMisses { .. } => {
            Some("--tolerance length=L,angle=A (the robot file's units) accepts a larger deviation")
        }
        _ => None,
    }
}

/// A warning as the command line words it: the library's sentence, and the option to use.
pub fn word(w: &Warning) -> String {
    let extra = match w {
        Warning::NotConverged { .. } => " (raise --max-iter)",
        Warning::Stalled { .. } => " (use --method lm)",
        Warning::UnclearRank { .. } | Warning::SmallGap { .. } => {
            " (kinecal analyze shows the spectrum; --rcond sets the tolerance)"
        }
        Warning::ScaleMismatch {
            likely: Some(_), ..
        } => " (--length-unit)",
        Warning::AttitudeMismatch {
            likely: Some(_), ..
        } => " (--angle-unit)",
        Warning::AttitudeMismatch { likely: None, .. } | Warning::AttitudesUnfit { .. } => {
            " (--position-only)"
        }
        _ => "",
    };
    format!("{w}{extra}")
}

fn dataset(a: DatasetArgs) -> Result<()> {
    let adapter = kinecal::apps::datasets::DATASETS
        .iter()
        .find(|d| d.name == a.name)
        .ok_or_else(|| {
            anyhow!(
                "unknown data set `{}` (known: {})",
                a.name,
                kinecal::apps::datasets::DATASETS
                    .iter()
                    .map(|d| d.name)
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        })?;
    if !a.dir.is_dir() {
        bail!("{}: no such folder", a.dir.display());
    }
    let converted = (adapter.convert)(&a.dir).map_err(|e| match e {
        kinecal::Error::Io { .. } => anyhow!(
            "{e}\nhint: is {} the folder of the data set ({})?",
            a.dir.display(),
            adapter.about
        ),
        e => e.into(),
    })?;
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("cannot create {}", a.out.display()))?;
    let mut staged = kinecal::files::output::Staged::new();
    for (name, text) in &converted.files {
        staged.text(&a.out.join(name), text)?;
    }
    staged.commit()?;
    println!("{}", converted.summary);
    println!(
        "wrote {} to {}",
        converted
            .files
            .iter()
            .map(|f| f.0.as_str())
            .collect::<Vec<_>>()
            .join(", "),
        a.out.display()
    );
    println!(
        "next, in {}: {}",
        a.out.display(),
        suggested_command(&converted.suggested)
    );
    // The held-out figures the data set's README gives, per validation file, and pooled as
    // `kinecal calibrate` reports several --validate files.
    let held_out = converted.suggested.held_out;
    if !held_out.is_empty() {
        let each: Vec<String> = held_out
            .iter()
            .map(|(f, m)| format!("{:.2} mm on {f}", m * 1e3))
            .collect();
        let each = match each.split_last() {
            Some((last, rest)) if !rest.is_empty() => format!("{} and {last}", rest.join(", ")),
            _ => each.join(""),
        };
        let pooled = match converted.held_out_pooled() {
            Some(p) if held_out.len() > 1 => format!(
                " (each alone; about {:.2} mm pooled over the --validate files, as kinecal \
                 reports it)",
                p * 1e3
            ),
            _ => String::new(),
        };
        println!(
            "held out, the data set's README gives for a correct calibration a mean position \
             error of about {each}{pooled}"
        );
    }
    Ok(())
}

/// The command line of a data set's suggested calibration.
fn suggested_command(s: &kinecal::apps::datasets::Suggested) -> String {
    let mut c = format!("kinecal calibrate --robot {} --data {}", s.robot, s.data);
    for v in s.validate {
        c += &format!(" --validate {v}");
    }
    c += &format!(" --estimate {}", s.estimate);
    if let Some(o) = s.orientation {
        c += &format!(" --orientation-error {}", o.as_str());
    }
    if let Some((l, a)) = s.weights {
        c += &format!(" --weights length={l},angle={a}");
    }
    if let Some(h) = s.holdout {
        c += &format!(" --holdout {h}");
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The allocator's blocks of a page's alignment and at least a megabyte (mappings of their
    /// own) are page-aligned, zeroed when asked, and keep their contents across a reallocation
    /// into the heap and out of it; other blocks are the system allocator's, reallocated as
    /// before.
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    #[test]
    fn paged_blocks_are_mapped_on_their_own() {
        use std::alloc::{GlobalAlloc, Layout};
        let a = heap::Allocator;
        let big = Layout::from_size_align(3 << 20, 4096).unwrap();
        // SAFETY: layouts of nonzero size; each block written and read within its size,
        // reallocated with its own layout and released once.
        unsafe {
            let p = a.alloc_zeroed(big);
            assert!(!p.is_null() && p as usize % 4096 == 0);
            let block = std::slice::from_raw_parts_mut(p, big.size());
            assert!(block.iter().all(|&b| b == 0));
            for (i, b) in block.iter_mut().enumerate() {
                *b = (i % 251) as u8;
            }
            // Into the heap (below the threshold) and back out: the contents kept.
            let q = a.realloc(p, big, 4096);
            let small = Layout::from_size_align(4096, 4096).unwrap();
            assert!((0..4096).all(|i| *q.add(i) == (i % 251) as u8));
            let r = a.realloc(q, small, 2 << 20);
            let mid = Layout::from_size_align(2 << 20, 4096).unwrap();
            assert!(r as usize % 4096 == 0);
            assert!((0..4096).all(|i| *r.add(i) == (i % 251) as u8));
            a.dealloc(r, mid);
            // Not page-aligned, or small: the system's (through the heap as before).
            let other = Layout::from_size_align(3 << 20, 64).unwrap();
            let o = a.alloc(other);
            assert!(!o.is_null());
            *o = 7;
            let o = a.realloc(o, other, 4 << 20);
            assert_eq!(*o, 7);
            a.dealloc(o, Layout::from_size_align(4 << 20, 64).unwrap());
        }
    }

    /// Every library setting has a flag, and the flag is one the command line has (the noise
    /// scale excepted: the library sets it from a fit's residuals; a spec file's `kind`: on the
    /// command line, the options are the kinds; and a history dump, the positional `DUMP` of
    /// `history import`).
    #[test]
    fn every_setting_names_a_flag_of_the_command_line() {
        use clap::CommandFactory;
        fn longs(c: &clap::Command, out: &mut Vec<String>) {
            for a in c.get_arguments() {
                if let Some(l) = a.get_long() {
                    out.push(format!("--{l}"));
                }
            }
            for s in c.get_subcommands() {
                longs(s, out);
            }
        }
        let mut known = Vec::new();
        // Built: each command's arguments are added when it is built (`args::Deferred`).
        let mut cli = Cli::command();
        cli.build();
        longs(&cli, &mut known);
        for s in Setting::ALL {
            if matches!(
                s,
                Setting::NoiseScale | Setting::ObservationKind | Setting::Dump
            ) {
                continue;
            }
            for flag in flag_of(s).split('/') {
                assert!(known.iter().any(|k| k == flag), "{s:?}: {flag} is no flag");
            }
        }
    }

    /// A library error names the flag, through a context too.
    #[test]
    fn an_invalid_setting_is_worded_with_its_flag() {
        let e = anyhow::Error::from(kinecal::Error::InvalidOption {
            setting: Setting::HoldoutFraction,
            message: "expected a fraction between 0 and 1, got 2".into(),
        })
        .context("calibrating");
        assert_eq!(
            in_flags(&e),
            "calibrating: --holdout: expected a fraction between 0 and 1, got 2"
        );
    }
}
