//! Shared by the command's tests (each test binary uses part of it): running the binary, and
//! every calibration report and `--json` document a test writes checked against its schema
//! shipped in `schemas/`.
#![allow(dead_code)]

use std::collections::HashMap;
use std::path::Path;
use std::sync::{Mutex, OnceLock};

use assert_cmd::Command;

/// The `kinecal` binary under test, away from the history of whoever runs the tests
/// (`$KINECAL_DB` unset).
pub fn kinecal() -> Command {
    let mut c = Command::cargo_bin("kinecal").unwrap();
    c.env_remove("KINECAL_DB");
    c
}

/// A command line written as one string: its words, split at whitespace (line breaks
/// included), so that `argv("fk --robot ge-a4 --postures p.csv")` is the five arguments.
pub fn argv(line: &str) -> Vec<&str> {
    line.split_whitespace().collect()
}

/// Runs `kinecal args` in `dir`: (exit code, -1 when killed by a signal; standard output;
/// standard error), both UTF-8. A panic fails the test.
pub fn run(dir: &Path, args: &[&str]) -> (i32, String, String) {
    let out = kinecal().current_dir(dir).args(args).output().unwrap();
    let (o, e) = (
        String::from_utf8(out.stdout).unwrap(),
        String::from_utf8(out.stderr).unwrap(),
    );
    assert!(!e.contains("panicked"), "{args:?}: {e}");
    (out.status.code().unwrap_or(-1), o, e)
}

/// [`run`], bytes that are not UTF-8 (a damaged file's, quoted) replaced.
pub fn run_lossy(dir: &Path, args: &[&str]) -> (i32, String, String) {
    let out = kinecal().current_dir(dir).args(args).output().unwrap();
    let (o, e) = (
        String::from_utf8_lossy(&out.stdout).to_string(),
        String::from_utf8_lossy(&out.stderr).to_string(),
    );
    assert!(!e.contains("panicked"), "{args:?}: {e}");
    (out.status.code().unwrap_or(-1), o, e)
}

/// Runs a command expected to exit 0; returns its standard output. Every report in `dir` then
/// follows the shipped schema.
pub fn run_ok(dir: &Path, args: &[&str]) -> String {
    let (code, out, err) = run(dir, args);
    assert_eq!(code, 0, "{args:?}: {out}{err}");
    check_reports(dir);
    out
}

/// Runs a command expected to fail with exit code 1; returns its standard error.
pub fn run_err(dir: &Path, args: &[&str]) -> String {
    let (code, out, err) = run(dir, args);
    assert_eq!(code, 1, "{args:?}: {out}{err}");
    err
}

/// Asserts that `v` follows `schemas/{kind}.schema.json` (validators built once per schema),
/// naming `what` and the first few violations otherwise.
fn assert_follows(kind: &'static str, v: &serde_json::Value, what: &str) {
    static VALIDATORS: OnceLock<Mutex<HashMap<&'static str, &'static jsonschema::Validator>>> =
        OnceLock::new();
    let validator = *VALIDATORS
        .get_or_init(Default::default)
        .lock()
        .unwrap()
        .entry(kind)
        .or_insert_with(|| {
            let path = Path::new(env!("CARGO_MANIFEST_DIR"))
                .join(format!("../../schemas/{kind}.schema.json"));
            let schema: serde_json::Value =
                serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
            Box::leak(Box::new(jsonschema::validator_for(&schema).unwrap()))
        });
    let errors: Vec<String> = validator
        .iter_errors(v)
        .take(5)
        .map(|e| format!("{} at {}", e, e.instance_path()))
        .collect();
    assert!(
        errors.is_empty(),
        "{what} does not follow the {kind} schema:\n{}",
        errors.join("\n")
    );
}

/// Checks every calibration report (a `.json` file with `schema_version` and `parameters`)
/// under `dir` against `schemas/calibration-report.schema.json`; returns how many it checked.
pub fn check_reports(dir: &Path) -> usize {
    let mut checked = 0;
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() && !path.is_symlink() {
                stack.push(path);
                continue;
            }
            if path.extension().is_none_or(|e| e != "json") {
                continue;
            }
            let Ok(v) = serde_json::from_str::<serde_json::Value>(
                &std::fs::read_to_string(&path).unwrap_or_default(),
            ) else {
                continue;
            };
            if v.get("schema_version").is_none() || v.get("parameters").is_none() {
                continue;
            }
            assert_follows("calibration-report", &v, &path.display().to_string());
            checked += 1;
        }
    }
    checked
}

/// The JSON file at `path`, parsed.
pub fn read_json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// [`check_document`] of the file at `path`.
pub fn check_document_file(kind: &'static str, path: &Path) -> serde_json::Value {
    check_document(kind, &std::fs::read_to_string(path).unwrap())
}

/// Checks a document printed by `--json` (`analysis`, `plan` or `check`) against its shipped
/// schema; returns it parsed.
pub fn check_document(kind: &'static str, text: &str) -> serde_json::Value {
    let v: serde_json::Value = serde_json::from_str(text).unwrap();
    assert_follows(kind, &v, &format!("a {kind} document"));
    v
}
