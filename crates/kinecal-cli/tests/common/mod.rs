//! Shared by the command's tests (each test binary uses part of it): every calibration report
//! and `--json` document a test writes is checked against its schema shipped in `schemas/`.
#![allow(dead_code)]

use std::path::Path;

/// Checks every calibration report (a `.json` file with `schema_version` and `parameters`)
/// under `dir` against `schemas/calibration-report.schema.json`; returns how many it checked.
pub fn check_reports(dir: &Path) -> usize {
    static VALIDATOR: std::sync::OnceLock<jsonschema::Validator> = std::sync::OnceLock::new();
    let validator = VALIDATOR.get_or_init(|| {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../schemas/calibration-report.schema.json");
        let schema: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        jsonschema::validator_for(&schema).unwrap()
    });
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
            let errors: Vec<String> = validator
                .iter_errors(&v)
                .take(5)
                .map(|e| format!("{} at {}", e, e.instance_path()))
                .collect();
            assert!(
                errors.is_empty(),
                "{} does not follow the report schema:\n{}",
                path.display(),
                errors.join("\n")
            );
            checked += 1;
        }
    }
    checked
}

/// Checks a document printed by `--json` (`analysis`, `plan` or `check`) against its shipped
/// schema; returns it parsed.
pub fn check_document(kind: &str, text: &str) -> serde_json::Value {
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../../schemas/{kind}.schema.json"));
    let schema: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    let v: serde_json::Value = serde_json::from_str(text).unwrap();
    let validator = jsonschema::validator_for(&schema).unwrap();
    let errors: Vec<String> = validator
        .iter_errors(&v)
        .take(5)
        .map(|e| format!("{} at {}", e, e.instance_path()))
        .collect();
    assert!(
        errors.is_empty(),
        "not a {kind} document:\n{}",
        errors.join("\n")
    );
    v
}
