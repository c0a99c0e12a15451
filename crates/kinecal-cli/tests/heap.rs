//! The command's heap on Linux with glibc (`heap::prefer_huge_pages` in main.rs): grown ahead
//! in one large step and advised for 2 MB pages, so that a large run faults its memory in a few
//! pages at a time. Checked on a running `kinecal` (waiting for its data on standard input):
//! its heap mapping carries the kernel's `hg` flag (`MADV_HUGEPAGE`) in `/proc/PID/smaps`.
//! And the command is linked position-dependent (`build.rs`): nothing to relocate at start.
#![cfg(all(target_os = "linux", target_env = "gnu"))]

use std::io::Write as _;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// The `VmFlags` of each mapping named `[heap]` in `smaps` (advice on part of the heap splits
/// it into several).
fn heap_flags(smaps: &str) -> Vec<Vec<String>> {
    let mut in_heap = false;
    let mut found = Vec::new();
    for line in smaps.lines() {
        let first = line.split_whitespace().next().unwrap_or("");
        // A mapping's header line starts with its address range.
        if first.contains('-') && first.chars().all(|c| c.is_ascii_hexdigit() || c == '-') {
            in_heap = line.trim_end().ends_with("[heap]");
        } else if in_heap {
            if let Some(flags) = line.strip_prefix("VmFlags:") {
                found.push(flags.split_whitespace().map(str::to_string).collect());
            }
        }
    }
    found
}

/// Whether some part of the heap is advised for huge pages.
fn advised(smaps: &str) -> bool {
    heap_flags(smaps)
        .iter()
        .any(|f| f.iter().any(|x| x == "hg"))
}

#[test]
fn a_running_command_has_its_heap_advised_for_huge_pages() {
    // A kernel built without transparent huge pages refuses the advice (the command runs on
    // with its thresholds alone): nothing to check there.
    if !std::path::Path::new("/sys/kernel/mm/transparent_hugepage/enabled").exists() {
        eprintln!("skipped: this kernel has no transparent huge pages to advise");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let mut child = Command::new(assert_cmd::cargo::cargo_bin("kinecal"))
        .current_dir(dir.path())
        .args([
            "calibrate",
            "--robot",
            "ge-a4",
            "--data",
            "-",
            "--quiet",
            "--report",
            "r.json",
        ])
        .stdin(Stdio::piped())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let smaps = format!("/proc/{}/smaps", child.id());
    let started = Instant::now();
    let mut last = String::new();
    // The process reads standard input until it is closed: its heap is there meanwhile.
    while started.elapsed() < Duration::from_secs(20) && !advised(&last) {
        std::thread::sleep(Duration::from_millis(20));
        last = std::fs::read_to_string(&smaps).unwrap_or_default();
    }
    let _ = child.stdin.take().unwrap().write_all(b"");
    let _ = child.wait();
    assert!(
        advised(&last),
        "no part of the heap advised for huge pages within 20 s; the heap's flags: {:?}",
        heap_flags(&last)
    );
}

#[test]
fn the_smaps_reader_finds_the_heap_flags() {
    let smaps = "\
55d0c0000000-55d0c4000000 rw-p 00000000 00:00 0                          [heap]
Size:              65536 kB
VmFlags: rd wr mr mw me ac hg
7f0000000000-7f0000001000 r--p 00000000 fe:00 1234                       /usr/lib/libc.so.6
VmFlags: rd mr mw me
";
    assert_eq!(
        heap_flags(smaps),
        [["rd", "wr", "mr", "mw", "me", "ac", "hg"]]
    );
    assert!(advised(smaps));
    assert!(heap_flags("7f00-7f01 r--p 0 0:0 0 /x\nVmFlags: rd\n").is_empty());
    assert!(!advised(&smaps.replace(" hg", "")));
}

/// The ELF type of the file at `path` (`e_type`, little-endian at byte 16): 2 for a
/// position-dependent executable, 3 for a shared object (a position-independent one).
fn elf_type(path: &std::path::Path) -> u16 {
    let bytes = std::fs::read(path).unwrap();
    assert_eq!(
        &bytes[..4],
        b"\x7fELF",
        "{} is not an ELF file",
        path.display()
    );
    u16::from_le_bytes([bytes[16], bytes[17]])
}

#[test]
fn the_command_is_linked_position_dependent() {
    let exe = assert_cmd::cargo::cargo_bin("kinecal");
    assert_eq!(
        elf_type(&exe),
        2,
        "{} is not a position-dependent executable (ET_EXEC): build.rs links it with -no-pie",
        exe.display()
    );
    // The reader itself: this test's own binary is built position-independent (ET_DYN).
    assert_eq!(elf_type(&std::env::current_exe().unwrap()), 3);
}
