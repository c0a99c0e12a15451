//! The shape of the library, kept honest: modules import one another in one direction (no
//! cycle), in the documented order, and the linear-algebra crate is used in one place only.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// Top-level modules and the `crate::` modules each one's files name.
fn imports() -> BTreeMap<String, BTreeSet<String>> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut out: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    let mut visit = |module: &str, text: &str| {
        let entry = out.entry(module.to_string()).or_default();
        // Code only: documentation may point anywhere.
        let code: String = text
            .lines()
            .filter(|l| !l.trim_start().starts_with("//"))
            .collect::<Vec<_>>()
            .join("\n");
        let text = code.as_str();
        for (i, _) in text.match_indices("crate::") {
            let rest = &text[i + "crate::".len()..];
            let name: String = rest
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            // Modules only (lower case); items re-exported at the root are not layers.
            if !name.is_empty() && name != module && name.starts_with(|c: char| c.is_lowercase()) {
                entry.insert(name);
            }
        }
    };
    for e in std::fs::read_dir(&src).unwrap() {
        let p = e.unwrap().path();
        let name = p.file_stem().unwrap().to_string_lossy().to_string();
        if p.is_dir() {
            for f in std::fs::read_dir(&p).unwrap() {
                let f = f.unwrap().path();
                visit(&name, &std::fs::read_to_string(&f).unwrap());
            }
        } else if name != "lib" {
            visit(&name, &std::fs::read_to_string(&p).unwrap());
        }
    }
    out
}

#[test]
fn modules_import_in_one_direction() {
    // The documented order (lib.rs): a module may only use modules earlier in this list.
    let order = [
        "error",
        "units",
        "params",
        "robot",
        "linalg",
        "kinematics",
        // The compliance groups leave out the joints gravity cannot load.
        "param_list",
        // Priors are written as keyed parameter lists; robot files have them.
        "prior",
        "source",
        "warning",
        "robot_file",
        "observe",
        // The observation files: their readers build the measurement model's types.
        "files",
        "sanity",
        "registration",
        "problem",
        "estimation",
        "identifiability",
        "uncertainty",
        "outliers",
        // Predicted accuracy: the covariance through the Jacobian, the model error by
        // cross-validation (refits), the accuracy map; the report carries it.
        "predict",
        "report",
        "workflow",
        "import",
        "examples",
        "simulate",
        "plan",
        "compensate",
        // ISO 9283 test poses (through compensate's inverse kinematics) and figures.
        "iso9283",
        "curves",
        "datasets",
        // The door: one spec per job, run through the modules above.
        "spec",
    ];
    let rank = |m: &str| order.iter().position(|o| *o == m);
    let graph = imports();
    for (module, uses) in &graph {
        let r = rank(module).unwrap_or_else(|| panic!("module `{module}` is not in the order"));
        for u in uses {
            let ru = rank(u).unwrap_or_else(|| panic!("`{module}` uses unknown `{u}`"));
            assert!(
                ru < r,
                "`{module}` uses `{u}`, which comes after it: an import cycle or a layer \
                 inversion"
            );
        }
    }
}

#[test]
fn only_linalg_talks_to_faer() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut stack = vec![src];
    while let Some(dir) = stack.pop() {
        for e in std::fs::read_dir(dir).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else if p.file_name().unwrap() != "linalg.rs" {
                let text = std::fs::read_to_string(&p).unwrap();
                assert!(!text.contains("faer::"), "{} uses faer", p.display());
            }
        }
    }
}
