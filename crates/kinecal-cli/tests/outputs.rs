//! How `kinecal` puts its output files in place (Unix): regular files replaced whole, with the
//! target's mode (a new one by the umask) and through symlinks; devices, FIFOs and standard
//! output written into, never renamed over; no temporary file left by a failed or stopped run,
//! and those of killed runs cleaned; `batch` refusing outputs over other rows' files.
//!
//! Nothing here can harm the machine when the code is wrong: the destructive cases run on
//! FIFOs, symlinks and device nodes made in a temporary folder, and `/dev/null` and
//! `/dev/stdout` are written only after the same case passed on such a stand-in.
#![cfg(unix)]

use std::fs;
use std::io::Read as _;
use std::os::unix::fs::{FileTypeExt as _, MetadataExt as _, OpenOptionsExt as _, PermissionsExt};
use std::os::unix::process::ExitStatusExt as _;
use std::path::Path;
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant, SystemTime};

mod common;

use common::argv;

const BIN: &str = env!("CARGO_BIN_EXE_kinecal");

fn kinecal(dir: &Path, args: &[&str]) -> Output {
    Command::new(BIN)
        .current_dir(dir)
        .args(args)
        .output()
        .unwrap()
}

fn ok(dir: &Path, args: &[&str]) -> Output {
    let out = kinecal(dir, args);
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Simulated measurements of the built-in GE A4 in `dir/name`.
fn data(dir: &Path, name: &str, seed: u32) {
    ok(
        dir,
        &argv(&format!(
            "simulate --robot ge-a4 --postures 20 --seed {seed} --out {name}"
        )),
    );
}

/// A short calibration of `d.csv` with `extra` outputs.
fn calibrate<'a>(extra: &[&'a str]) -> Vec<&'a str> {
    let mut v = argv("calibrate --robot ge-a4 --data d.csv --estimate p1");
    v.extend_from_slice(extra);
    v
}

/// The temporary files of kinecal in `dir`.
fn temporaries(dir: &Path) -> Vec<String> {
    fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains("kinecal-tmp"))
        .collect()
}

fn mkfifo(path: &Path) {
    let c = std::ffi::CString::new(path.as_os_str().as_encoded_bytes()).unwrap();
    // SAFETY: a valid NUL-terminated path.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0, "mkfifo");
}

/// A character device node (`major`, `minor`) at `path`, or why not (needs root).
fn mknod_char(path: &Path, major: u32, minor: u32) -> Result<(), std::io::Error> {
    let c = std::ffi::CString::new(path.as_os_str().as_encoded_bytes()).unwrap();
    // SAFETY: a valid NUL-terminated path.
    let r = unsafe {
        libc::mknod(
            c.as_ptr(),
            libc::S_IFCHR | 0o666,
            libc::makedev(major, minor),
        )
    };
    if r == 0 {
        Ok(())
    } else {
        Err(std::io::Error::last_os_error())
    }
}

/// Reads `fifo` (opened beforehand without waiting for a writer) until `child` has exited and
/// nothing is left: never hangs, whether or not the child ever opens the FIFO.
fn drain(reader: &mut fs::File, child: &mut Child) -> Vec<u8> {
    let start = Instant::now();
    let mut got = Vec::new();
    let mut chunk = [0u8; 8192];
    loop {
        let exited = child.try_wait().unwrap().is_some();
        match reader.read(&mut chunk) {
            Ok(n) if n > 0 => {
                got.extend_from_slice(&chunk[..n]);
                continue;
            }
            Ok(_) => {}
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {}
            Err(e) => panic!("reading the FIFO: {e}"),
        }
        if exited {
            return got;
        }
        if start.elapsed() > Duration::from_secs(300) {
            let _ = child.kill();
            panic!("kinecal did not finish");
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

fn open_fifo_for_reading(path: &Path) -> fs::File {
    fs::OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NONBLOCK)
        .open(path)
        .unwrap()
}

#[test]
fn an_output_into_a_fifo_is_written_into_it_and_it_stays_a_fifo() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    data(d, "d.csv", 3);
    let fifo = d.join("robot.fifo");
    mkfifo(&fifo);
    let mut reader = open_fifo_for_reading(&fifo);
    let mut child = Command::new(BIN)
        .current_dir(d)
        .args(calibrate(&["--out", "robot.fifo"]))
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let got = String::from_utf8(drain(&mut reader, &mut child)).unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(got.contains("[[links]]"), "the FIFO carried: {got:?}");
    assert!(
        fs::symlink_metadata(&fifo).unwrap().file_type().is_fifo(),
        "robot.fifo was replaced"
    );
    assert_eq!(temporaries(d), Vec::<String>::new());
}

#[test]
fn reports_to_standard_output_are_printed_there() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    data(d, "d.csv", 3);
    for target in ["-", "/dev/fd/1"] {
        let out = ok(d, &calibrate(&["--report", target]));
        let text = String::from_utf8(out.stdout).unwrap();
        assert!(text.contains("\"schema_version\""), "{target}: {text}");
        assert!(!d.join("-").exists());
    }
    // A link to standard output (as /dev/stdout is on Linux) is written through, and stays.
    let so = d.join("so");
    std::os::unix::fs::symlink("/dev/fd/1", &so).unwrap();
    let out = ok(d, &calibrate(&["--report", "so"]));
    assert!(String::from_utf8(out.stdout)
        .unwrap()
        .contains("\"schema_version\""));
    assert!(fs::symlink_metadata(&so).unwrap().file_type().is_symlink());
    // Standard output redirected to a file: the report is added to what was printed there, the
    // file is not replaced.
    let shell = Command::new("sh")
        .current_dir(d)
        .arg("-c")
        .arg(r#"exec "$0" "$@" > printed.txt"#)
        .arg(BIN)
        .args(calibrate(&["--report", "so"]))
        .output()
        .unwrap();
    assert!(shell.status.success());
    let printed = fs::read_to_string(d.join("printed.txt")).unwrap();
    assert!(printed.contains("\"schema_version\""), "{printed}");
    assert!(
        printed.contains("RMS position error"),
        "the summary is kept: {printed}"
    );
    // Now /dev/stdout itself, which the case above stands in for.
    let before = fs::symlink_metadata("/dev/stdout").unwrap().file_type();
    let out = ok(d, &calibrate(&["--report", "/dev/stdout"]));
    assert!(String::from_utf8(out.stdout)
        .unwrap()
        .contains("\"schema_version\""));
    assert_eq!(
        fs::symlink_metadata("/dev/stdout").unwrap().file_type(),
        before
    );
    assert_eq!(temporaries(d), Vec::<String>::new());
}

#[test]
fn devices_are_written_into_and_a_failed_write_replaces_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    data(d, "d.csv", 3);
    // Stand-ins for /dev/null and /dev/full in the temporary folder: if the code were wrong,
    // they, not the machine's, would be replaced.
    if let Err(e) = mknod_char(&d.join("null"), 1, 3)
        .and_then(|()| mknod_char(&d.join("full"), 1, 7))
        .and_then(|()| {
            fs::OpenOptions::new()
                .write(true)
                .open(d.join("null"))
                .map(drop)
        })
    {
        eprintln!("skipped: cannot make or open device nodes here ({e}); needs root");
        return;
    }
    ok(d, &calibrate(&["--out", "null"]));
    let meta = fs::symlink_metadata(d.join("null")).unwrap();
    assert!(meta.file_type().is_char_device(), "null was replaced");
    // A write that fails (a full device) fails the run, and no regular output is replaced.
    fs::write(d.join("r.json"), "keep").unwrap();
    let out = kinecal(d, &calibrate(&["--out", "full", "--report", "r.json"]));
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("full: No space left on device"), "{err}");
    assert!(fs::symlink_metadata(d.join("full"))
        .unwrap()
        .file_type()
        .is_char_device());
    assert_eq!(fs::read_to_string(d.join("r.json")).unwrap(), "keep");
    assert_eq!(temporaries(d), Vec::<String>::new());
    // Only now the machine's /dev/null (the stand-in above was handled in place).
    ok(d, &calibrate(&["--out", "/dev/null"]));
    let meta = fs::metadata("/dev/null").unwrap();
    assert!(meta.file_type().is_char_device(), "/dev/null was replaced");
    assert_eq!(meta.rdev(), libc::makedev(1, 3));
}

#[test]
fn an_output_through_a_symlink_updates_the_file_it_points_to() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    data(d, "d.csv", 3);
    fs::create_dir(d.join("real")).unwrap();
    fs::write(d.join("real/robot.toml"), "old").unwrap();
    std::os::unix::fs::symlink("real/robot.toml", d.join("robot.toml")).unwrap();
    // A chain of links, and a link to a file not written yet.
    std::os::unix::fs::symlink("robot.toml", d.join("chain.toml")).unwrap();
    std::os::unix::fs::symlink("real/new.json", d.join("new.json")).unwrap();
    ok(
        d,
        &calibrate(&["--out", "chain.toml", "--report", "new.json"]),
    );
    for link in ["robot.toml", "chain.toml", "new.json"] {
        assert!(
            fs::symlink_metadata(d.join(link))
                .unwrap()
                .file_type()
                .is_symlink(),
            "{link} was replaced"
        );
    }
    assert!(fs::read_to_string(d.join("real/robot.toml"))
        .unwrap()
        .contains("[[links]]"));
    assert!(fs::read_to_string(d.join("real/new.json"))
        .unwrap()
        .contains("\"schema_version\""));
    assert_eq!(temporaries(d), Vec::<String>::new());
    assert_eq!(temporaries(&d.join("real")), Vec::<String>::new());
    // Through a link, an input is still recognised.
    std::os::unix::fs::symlink("d.csv", d.join("data-link.csv")).unwrap();
    let out = kinecal(d, &calibrate(&["--out", "data-link.csv"]));
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("over an input"));
}

fn mode(path: &Path) -> u32 {
    fs::metadata(path).unwrap().permissions().mode() & 0o7777
}

/// Runs kinecal under `umask`.
fn with_umask(dir: &Path, umask: &str, args: &[&str]) {
    let out = Command::new("sh")
        .current_dir(dir)
        .arg("-c")
        .arg(format!(r#"umask {umask}; exec "$0" "$@""#))
        .arg(BIN)
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn new_outputs_follow_the_umask_and_existing_ones_keep_their_mode() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sim = |out: &'static str| {
        vec![
            "simulate",
            "--robot",
            "ge-a4",
            "--postures",
            "5",
            "--out",
            out,
        ]
    };
    with_umask(d, "022", &sim("a.csv"));
    assert_eq!(mode(&d.join("a.csv")), 0o644);
    with_umask(d, "077", &sim("b.csv"));
    assert_eq!(mode(&d.join("b.csv")), 0o600);
    for (m, umask) in [(0o640, "022"), (0o664, "077")] {
        fs::write(d.join("c.csv"), "old").unwrap();
        fs::set_permissions(d.join("c.csv"), fs::Permissions::from_mode(m)).unwrap();
        with_umask(d, umask, &sim("c.csv"));
        assert_ne!(fs::read_to_string(d.join("c.csv")).unwrap(), "old");
        assert_eq!(mode(&d.join("c.csv")), m, "umask {umask}");
    }
    assert_eq!(temporaries(d), Vec::<String>::new());
}

/// A calibration in `d` that waits at the FIFO `wait.fifo` (nobody reads it) with its report
/// staged beside `r.json` (which holds "keep"), started with SIGINT, SIGTERM and SIGHUP at their
/// default actions whatever this test inherited (a shell's background job ignores SIGINT), or
/// with SIGHUP ignored when `nohup`.
fn waiting_at_a_fifo(d: &Path, nohup: bool) -> Child {
    use std::os::unix::process::CommandExt as _;
    data(d, "d.csv", 3);
    fs::write(d.join("r.json"), "keep").unwrap();
    mkfifo(&d.join("wait.fifo"));
    let mut command = Command::new(BIN);
    command
        .current_dir(d)
        .args(calibrate(&["--out", "wait.fifo", "--report", "r.json"]))
        .stdout(Stdio::null())
        .stderr(Stdio::null());
    // SAFETY: only sets signals' dispositions in the child before it runs kinecal (`signal` is
    // async-signal-safe).
    unsafe {
        command.pre_exec(move || {
            for sig in [libc::SIGINT, libc::SIGTERM, libc::SIGHUP] {
                libc::signal(sig, libc::SIG_DFL);
            }
            if nohup {
                libc::signal(libc::SIGHUP, libc::SIG_IGN);
            }
            Ok(())
        });
    }
    let mut child = command.spawn().unwrap();
    let start = Instant::now();
    while temporaries(d).is_empty() {
        assert!(
            child.try_wait().unwrap().is_none(),
            "kinecal ended without waiting at the FIFO"
        );
        assert!(
            start.elapsed() < Duration::from_secs(300),
            "no staging seen"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
    std::thread::sleep(Duration::from_millis(300));
    child
}

/// The run `waiting_at_a_fifo` started ended by `sig`: its status says so, its temporary file
/// is gone, `r.json` and the FIFO are as they were.
fn ended_by(d: &Path, child: &mut Child, sig: i32) {
    let status = child.wait().unwrap();
    assert_eq!(status.signal(), Some(sig), "{status:?}");
    assert_eq!(temporaries(d), Vec::<String>::new(), "signal {sig}");
    assert_eq!(fs::read_to_string(d.join("r.json")).unwrap(), "keep");
    assert!(fs::symlink_metadata(d.join("wait.fifo"))
        .unwrap()
        .file_type()
        .is_fifo());
}

#[test]
fn a_stopped_run_removes_its_temporary_files() {
    for sig in [libc::SIGTERM, libc::SIGINT, libc::SIGHUP] {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let mut child = waiting_at_a_fifo(d, false);
        // SAFETY: signalling our own child.
        unsafe { libc::kill(child.id() as i32, sig) };
        ended_by(d, &mut child, sig);
    }
}

#[test]
fn a_signal_ignored_at_the_start_stays_ignored() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut child = waiting_at_a_fifo(d, true);
    // SAFETY: signalling our own child.
    unsafe { libc::kill(child.id() as i32, libc::SIGHUP) };
    std::thread::sleep(Duration::from_millis(300));
    assert!(
        child.try_wait().unwrap().is_none(),
        "SIGHUP ended a run started with it ignored"
    );
    assert_eq!(temporaries(d).len(), 1, "the staged report is gone");
    // SAFETY: as above.
    unsafe { libc::kill(child.id() as i32, libc::SIGTERM) };
    ended_by(d, &mut child, libc::SIGTERM);
}

#[test]
fn temporary_files_of_killed_runs_are_removed_by_the_next_run() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A process that has ended: its id names no live process.
    let mut gone = Command::new("true").spawn().unwrap();
    let dead = gone.id();
    gone.wait().unwrap();
    let two_minutes_ago = SystemTime::now() - Duration::from_secs(120);
    let plant = |name: &str, old: bool| {
        let f = fs::File::create(d.join(name)).unwrap();
        if old {
            f.set_modified(two_minutes_ago).unwrap();
        }
    };
    let stale = format!(".kinecal-tmp-{dead}-AbC123-out.csv");
    let young = format!(".kinecal-tmp-{dead}-XyZ789-out.csv");
    let running = format!(".kinecal-tmp-{}-QwE456-out.csv", std::process::id());
    plant(&stale, true);
    plant(&young, false);
    plant(&running, true);
    plant(".notes.txt", true);
    let out = ok(
        d,
        &argv("simulate --robot ge-a4 --postures 5 --out out.csv"),
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!d.join(&stale).exists(), "the stale file is still there");
    assert!(err.contains(&stale), "no note of the removal: {err}");
    for kept in [&young, &running, ".notes.txt"] {
        assert!(d.join(kept).exists(), "{kept} was removed");
    }
}

#[test]
fn batch_refuses_an_output_over_another_rows_file_before_running() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    data(d, "d1.csv", 1);
    data(d, "d2.csv", 2);
    let d2 = fs::read(d.join("d2.csv")).unwrap();
    std::os::unix::fs::symlink("d2.csv", d.join("link.csv")).unwrap();
    let head = "serial,robot,data,options\n";
    for (name, rows, extra, says) in [
        (
            "m1.csv",
            "A,ge-a4,d1.csv,--out d2.csv\nB,ge-a4,d2.csv,\n",
            None,
            "m1.csv:2: the output d2.csv is an input of B (m1.csv:3)",
        ),
        (
            "m2.csv",
            "A,ge-a4,d1.csv,--report r.json\nB,ge-a4,d2.csv,--report ./r.json\n",
            None,
            "m2.csv:3: the output ./r.json is also written for A (m2.csv:2)",
        ),
        (
            "m3.csv",
            "A,ge-a4,d2.csv,\nB,ge-a4,d1.csv,--out link.csv\n",
            None,
            "m3.csv:3: the output link.csv is an input of A (m3.csv:2)",
        ),
        (
            "m4.csv",
            "A,ge-a4,d1.csv,--out m4.csv\n",
            None,
            "m4.csv:2: the output m4.csv is the manifest",
        ),
        (
            "m5.csv",
            "A,ge-a4,d1.csv,\nB,ge-a4,d2.csv,--out x.toml\n",
            Some("./d1.csv"),
            "--summary ./d1.csv is an input of A (m5.csv:2)",
        ),
    ] {
        fs::write(d.join(name), format!("{head}{rows}")).unwrap();
        let mut args = vec!["batch", name, "--quiet"];
        if let Some(s) = extra {
            args.extend(["--summary", s]);
        }
        let out = kinecal(d, &args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{name}: {err}");
        assert!(err.contains(says), "{name}: {err}");
        assert!(out.stdout.is_empty(), "{name}: a robot ran");
        assert_eq!(fs::read(d.join("d2.csv")).unwrap(), d2, "{name}");
        assert!(!d.join("r.json").exists() && !d.join("x.toml").exists());
    }
}
