//! The shape of the code, kept honest: the library's modules import one another in one
//! direction (no cycle), in the documented order; no file of any crate imports, however far
//! round, a file that imports it; and the linear-algebra crate is used in one place only.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// Every `.rs` file under `p` (or `p` itself), however deep.
fn rust_files(p: &Path) -> Vec<std::path::PathBuf> {
    fn walk(p: &Path, out: &mut Vec<std::path::PathBuf>) {
        if p.is_dir() {
            for e in std::fs::read_dir(p).unwrap() {
                walk(&e.unwrap().path(), out);
            }
        } else if p.extension().is_some_and(|e| e == "rs") {
            out.push(p.to_path_buf());
        }
    }
    let mut out = Vec::new();
    walk(p, &mut out);
    out
}

/// The code of a file: its lines but comment lines (documentation may point anywhere).
fn code_of(file: &Path) -> String {
    std::fs::read_to_string(file)
        .unwrap()
        .lines()
        .filter(|l| !l.trim_start().starts_with("//"))
        .collect::<Vec<_>>()
        .join("\n")
}

/// The modules of `dir` (files and folders, `mod.rs` and `lib.rs` left out) and, for each, the
/// modules of that level its files name (`prefix` followed by the name), over every file of a
/// folder module, however deep.
fn imports(dir: &Path, prefix: &str) -> BTreeMap<String, BTreeSet<String>> {
    let mut out: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        let name = p.file_stem().unwrap().to_string_lossy().to_string();
        if name == "lib" || name == "mod" {
            continue;
        }
        let entry = out.entry(name.clone()).or_default();
        let all = rust_files(&p);
        // `kinematics.rs` and its folder `kinematics/` share a name: one module, one entry.
        for f in &all {
            let code = code_of(f);
            for (i, _) in code.match_indices(prefix) {
                let rest = &code[i + prefix.len()..];
                let used: String = rest
                    .chars()
                    .take_while(|c| c.is_alphanumeric() || *c == '_')
                    .collect();
                // Modules only (lower case); items re-exported at the root are not layers.
                if !used.is_empty() && used != name && used.starts_with(|c: char| c.is_lowercase())
                {
                    entry.insert(used);
                }
            }
        }
    }
    out
}

/// Every module of `dir` is in `order`, and uses only modules before it there.
fn check_order(dir: &Path, prefix: &str, order: &[&str]) {
    let rank = |m: &str| order.iter().position(|o| *o == m);
    for (module, uses) in &imports(dir, prefix) {
        let r = rank(module).unwrap_or_else(|| panic!("{prefix}{module} is not in the order"));
        for u in uses {
            // Only this level's modules are ranked: deeper paths are the level's own business.
            let Some(ru) = rank(u) else {
                continue;
            };
            assert!(
                ru < r,
                "{prefix}{module} uses {prefix}{u}, which comes after it: an import cycle or a \
                 layer inversion"
            );
        }
    }
}

fn src() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

#[test]
fn modules_import_in_one_direction() {
    // The documented order (lib.rs): a module may only use modules earlier in this list.
    let order = [
        "error",
        "units",
        "warning",
        "source",
        "linalg",
        // The robot and its kinematics.
        "model",
        "import",
        // The measurement model, then its files.
        "observe",
        "files",
        "solve",
        "identifiability",
        "uncertainty",
        // Predicted accuracy: the covariance through the Jacobian, the model error by
        // cross-validation (refits), the accuracy map; the report carries it.
        "predict",
        "report",
        "workflow",
        "apps",
        // The door: one spec per job, run through the modules above.
        "spec",
    ];
    let top = imports(&src(), "crate::");
    for m in top.keys() {
        assert!(
            order.contains(&m.as_str()),
            "module `{m}` is not in the order"
        );
    }
    check_order(&src(), "crate::", &order);
    // Within the groups too.
    check_order(
        &src().join("model"),
        "crate::model::",
        &[
            "params",
            "camera",
            "robot",
            "kinematics",
            "param_list",
            "prior",
            "robot_file",
            "examples",
        ],
    );
    check_order(
        &src().join("solve"),
        "crate::solve::",
        &[
            "problem",
            "estimation",
            "registration",
            "camera_start",
            "hand_eye",
            "outliers",
        ],
    );
    check_order(
        &src().join("apps"),
        "crate::apps::",
        &[
            "simulate",
            "plan",
            "compensate",
            "iso9283",
            "curves",
            "datasets",
        ],
    );
}

#[test]
fn only_linalg_talks_to_faer() {
    for p in rust_files(&src()) {
        if p.file_name().unwrap() != "linalg.rs" {
            let text = std::fs::read_to_string(&p).unwrap();
            assert!(!text.contains("faer::"), "{} uses faer", p.display());
        }
    }
}

/// The module path of `file` under `src` (`a/b.rs` and `a/b/mod.rs` are `[a, b]`).
fn module_path(src: &Path, file: &Path) -> Vec<String> {
    let rel = file.strip_prefix(src).unwrap().with_extension("");
    let mut segs: Vec<String> = rel
        .components()
        .map(|c| c.as_os_str().to_string_lossy().to_string())
        .collect();
    if matches!(
        segs.last().map(String::as_str),
        Some("mod" | "lib" | "main")
    ) {
        segs.pop();
    }
    segs
}

/// The file of the longest prefix of `segs` that is a module file of `src`.
fn module_file(
    src: &Path,
    segs: &[String],
    files: &BTreeSet<std::path::PathBuf>,
) -> Option<std::path::PathBuf> {
    (1..=segs.len()).rev().find_map(|k| {
        let base = segs[..k].iter().fold(src.to_path_buf(), |p, s| p.join(s));
        [base.with_extension("rs"), base.join("mod.rs")]
            .into_iter()
            .find(|c| files.contains(c))
    })
}

/// The lower-case path segments that follow position `at` of `code` (`a::b::c`).
fn path_at(code: &str, at: usize) -> Vec<String> {
    let mut segs = Vec::new();
    let mut rest = &code[at..];
    loop {
        let seg: String = rest
            .chars()
            .take_while(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || *c == '_')
            .collect();
        if seg.is_empty() {
            break;
        }
        rest = &rest[seg.len()..];
        segs.push(seg);
        match rest.strip_prefix("::") {
            Some(r) => rest = r,
            None => break,
        }
    }
    segs
}

#[test]
fn no_file_imports_a_file_that_imports_it_back() {
    // Over every crate of the workspace: file A names a path into file B (`crate::` or
    // `super::`, outside its tests and comments), B into A, however long the way round.
    let crates = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut circles = Vec::new();
    for krate in std::fs::read_dir(&crates).unwrap() {
        let src = krate.unwrap().path().join("src");
        if !src.is_dir() {
            continue;
        }
        let files: BTreeSet<_> = rust_files(&src).into_iter().collect();
        let mut edges: BTreeMap<std::path::PathBuf, BTreeSet<std::path::PathBuf>> = BTreeMap::new();
        for f in &files {
            let code = code_of(f);
            let code = code.split("#[cfg(test)]").next().unwrap();
            let me = module_path(&src, f);
            let mut targets = BTreeSet::new();
            for (i, _) in code.match_indices("crate::") {
                if code[..i].ends_with(|c: char| c.is_alphanumeric() || c == '_') {
                    continue;
                }
                targets.insert(path_at(code, i + "crate::".len()));
            }
            for (i, _) in code.match_indices("super::") {
                let before = &code[..i];
                if before.ends_with("super::")
                    || before.ends_with(|c: char| c.is_alphanumeric() || c == '_')
                {
                    continue;
                }
                let mut ups = 0;
                let mut at = i;
                while code[at..].starts_with("super::") {
                    ups += 1;
                    at += "super::".len();
                }
                let mut segs = me[..me.len().saturating_sub(ups)].to_vec();
                segs.extend(path_at(code, at));
                targets.insert(segs);
            }
            let out = edges.entry(f.clone()).or_default();
            for t in targets {
                if let Some(file) = module_file(&src, &t, &files) {
                    if &file != f {
                        out.insert(file);
                    }
                }
            }
        }
        // A file on a circle reaches itself.
        for start in &files {
            let mut seen = BTreeSet::new();
            let mut todo: Vec<_> = edges[start].iter().cloned().collect();
            while let Some(f) = todo.pop() {
                if &f == start {
                    circles.push(start.strip_prefix(&crates).unwrap().display().to_string());
                    break;
                }
                if seen.insert(f.clone()) {
                    todo.extend(edges[&f].iter().cloned());
                }
            }
        }
    }
    assert!(
        circles.is_empty(),
        "these files import, through others, a file that imports them: {circles:?}"
    );
}
