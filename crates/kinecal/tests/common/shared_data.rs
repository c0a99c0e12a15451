//! `../shared/data`: the public data sets (QKM, FANUC, UR10 tracker series, URDFs) the real-data
//! tests of the workspace need, found beside the repository or at `$KINECAL_SHARED_DATA`. One
//! helper for every such test (`#[path]`-included by each test file that needs it).
//!
//! When the data is missing, a test either fails or is counted as skipped:
//!
//! - with the environment variable `CI` set (non-empty), the test fails, naming the path;
//! - otherwise it returns without checking anything, and when the test binary exits it prints
//!   `skipped: N tests need ../shared/data (...)` on standard error. The line is written
//!   outside the test harness's capture of `print!`/`eprint!` (which shows a passing test's
//!   output only with `--nocapture`), so plain `cargo test` shows it after the binary's
//!   `test result:` line.
#![allow(dead_code)] // each test binary uses what it needs

use std::collections::BTreeSet;
use std::io::Write as _;
use std::path::PathBuf;
use std::sync::{Mutex, Once};

/// The shared data folder: `$KINECAL_SHARED_DATA` when set, else `../shared/data` beside the
/// repository.
pub fn root() -> PathBuf {
    match std::env::var_os("KINECAL_SHARED_DATA") {
        Some(d) if !d.is_empty() => PathBuf::from(d),
        _ => PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"),
    }
}

/// The tests that found the data missing (by thread name: the harness names each test's
/// thread after it).
static SKIPPED: Mutex<BTreeSet<String>> = Mutex::new(BTreeSet::new());
static AT_EXIT: Once = Once::new();

unsafe extern "C" {
    fn atexit(f: extern "C" fn()) -> std::os::raw::c_int;
}

extern "C" fn report() {
    let n = SKIPPED.lock().map(|s| s.len()).unwrap_or(0);
    if n > 0 {
        let _ = writeln!(
            std::io::stderr(),
            "skipped: {n} tests need ../shared/data ({} not found; clone it beside the \
             repository or set KINECAL_SHARED_DATA; with CI set they fail)",
            root().display()
        );
    }
}

/// Whether a missing data set fails the test: `CI` set and not empty.
pub fn required() -> bool {
    std::env::var_os("CI").is_some_and(|v| !v.is_empty())
}

/// `rel` in the shared data folder, when it exists. When it does not: with `CI` set the test
/// fails saying what is missing; otherwise the test is counted as skipped (see the module) and
/// `None` is returned: the test should then return.
pub fn shared_data(rel: &str) -> Option<PathBuf> {
    let path = root().join(rel);
    if path.exists() {
        return Some(path);
    }
    assert!(
        !required(),
        "{} is missing, and CI is set: the real-data tests need ../shared/data (or \
         KINECAL_SHARED_DATA)",
        path.display()
    );
    let name = std::thread::current().name().map_or_else(
        || format!("{:?}", std::thread::current().id()),
        str::to_string,
    );
    SKIPPED.lock().unwrap().insert(name);
    AT_EXIT.call_once(|| {
        // SAFETY: `report` is a plain function that only reads a static and writes to stderr.
        unsafe {
            atexit(report);
        }
    });
    None
}
