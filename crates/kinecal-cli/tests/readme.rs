//! The README and the pages of `docs/` cannot drift from the program: every ```console block in
//! them runs here, page after page in the order of [`PAGES`], in one scratch folder (with
//! `examples/` and `../shared` reachable as from the repository root), and its output must match
//! what the page shows; and every command's `--help` is a snapshot under `tests/snapshots/help/`.
//!
//! In the README, `$ ` starts a command (a trailing `\` continues it), the lines after it are
//! its expected output (standard output, then standard error): a line `...` stands for any
//! number of lines, `[..]` for any text within a line. A command that should fail ends with
//! `# exit N`. Run with `SNAPSHOTS=overwrite` to rewrite the help snapshots and to print the
//! actual output of any README command that does not match.

#[path = "../../kinecal/tests/common/shared_data.rs"]
mod shared_data;

use std::path::{Path, PathBuf};
use std::process::Command;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The pages whose sessions run, in this order (later pages use what earlier ones wrote).
const PAGES: &[&str] = &[
    "README.md",
    "docs/your-robot.md",
    "docs/calibrate.md",
    "docs/analyze.md",
    "docs/real-robots.md",
    "docs/observations.md",
    "docs/cameras.md",
    "docs/spec.md",
    "docs/compensate.md",
    "docs/accuracy.md",
    "docs/reports.md",
    "docs/history.md",
    "docs/commands.md",
    "docs/files.md",
    "docs/library.md",
    "docs/python.md",
    "docs/verification.md",
];

/// Every page of `docs/` is in [`PAGES`], and every page of it exists.
#[test]
fn every_page_runs() {
    for p in PAGES {
        assert!(repo().join(p).exists(), "{p}");
    }
    for e in std::fs::read_dir(repo().join("docs")).unwrap() {
        let name = format!("docs/{}", e.unwrap().file_name().to_string_lossy());
        if name.ends_with(".md") {
            assert!(PAGES.contains(&name.as_str()), "{name} is not in PAGES");
        }
    }
}

fn overwrite() -> bool {
    std::env::var("SNAPSHOTS").is_ok_and(|v| v == "overwrite")
}

/// Whether `line` matches `pattern`, where `[..]` stands for any text.
fn line_matches(pattern: &str, line: &str) -> bool {
    let parts: Vec<&str> = pattern.split("[..]").collect();
    if parts.len() == 1 {
        return pattern == line;
    }
    let (first, last) = (parts[0], parts[parts.len() - 1]);
    if !line.starts_with(first) || !line[first.len()..].ends_with(last) {
        return false;
    }
    let mut rest = &line[first.len()..line.len() - last.len()];
    for p in &parts[1..parts.len() - 1] {
        match rest.find(p) {
            Some(i) => rest = &rest[i + p.len()..],
            None => return false,
        }
    }
    true
}

/// Whether `actual` matches `expected`, where a line `...` stands for any number of lines.
fn text_matches(expected: &[&str], actual: &[&str]) -> bool {
    match expected.split_first() {
        None => actual.is_empty(),
        Some((&"...", rest)) => (0..=actual.len()).any(|k| text_matches(rest, &actual[k..])),
        Some((e, rest)) => match actual.split_first() {
            Some((a, arest)) => line_matches(e, a) && text_matches(rest, arest),
            None => false,
        },
    }
}

/// Splits a command line into words: spaces separate, double quotes group.
fn words(line: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut cur = String::new();
    let (mut quoted, mut any) = (false, false);
    for c in line.chars() {
        match c {
            '"' => {
                quoted = !quoted;
                any = true;
            }
            ' ' if !quoted => {
                if any {
                    out.push(std::mem::take(&mut cur));
                    any = false;
                }
            }
            c => {
                cur.push(c);
                any = true;
            }
        }
    }
    if any {
        out.push(cur);
    }
    out
}

struct Session {
    page: &'static str,
    line: usize,
    command: String,
    expected: Vec<String>,
}

/// The commands of the README's console blocks, with their expected output.
fn sessions(page: &'static str, readme: &str) -> Vec<Session> {
    let mut out: Vec<Session> = Vec::new();
    let mut in_block = false;
    let mut continuing = false;
    for (i, line) in readme.lines().enumerate() {
        if line.trim_start().starts_with("```") {
            in_block = line.trim() == "```console";
            continuing = false;
            continue;
        }
        if !in_block {
            continue;
        }
        if continuing {
            let s = out.last_mut().expect("a command");
            let l = line.trim();
            continuing = l.ends_with('\\');
            s.command.push(' ');
            s.command.push_str(l.trim_end_matches('\\').trim());
        } else if let Some(cmd) = line.strip_prefix("$ ") {
            continuing = cmd.trim_end().ends_with('\\');
            out.push(Session {
                page,
                line: i + 1,
                command: cmd.trim_end().trim_end_matches('\\').trim().to_string(),
                expected: Vec::new(),
            });
        } else if let Some(s) = out.last_mut() {
            s.expected.push(line.to_string());
        }
    }
    for s in &mut out {
        while s.expected.last().is_some_and(|l| l.trim().is_empty()) {
            s.expected.pop();
        }
    }
    out
}

#[test]
fn readme_sessions_run_as_shown() {
    let Some(data) = shared_data::shared_data(".") else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let work = tmp.path().join("work");
    std::fs::create_dir(&work).unwrap();
    // The sessions' `../shared/data`.
    std::fs::create_dir(tmp.path().join("shared")).unwrap();
    std::os::unix::fs::symlink(data.canonicalize().unwrap(), tmp.path().join("shared/data"))
        .unwrap();
    std::os::unix::fs::symlink(
        repo().join("examples").canonicalize().unwrap(),
        work.join("examples"),
    )
    .unwrap();
    let mut sessions = Vec::new();
    for page in PAGES {
        let text = std::fs::read_to_string(repo().join(page)).unwrap();
        sessions.extend(self::sessions(page, &text));
    }
    assert!(sessions.len() >= 10, "{} sessions", sessions.len());
    let mut failures = Vec::new();
    for s in &sessions {
        let (command, exit) = match s.command.split_once("# exit ") {
            Some((c, code)) => (c.trim().to_string(), code.trim().parse::<i32>().unwrap()),
            None => (s.command.clone(), 0),
        };
        let w = words(&command);
        assert_eq!(w[0], "kinecal", "{} line {}: {command}", s.page, s.line);
        let out = Command::new(env!("CARGO_BIN_EXE_kinecal"))
            .args(&w[1..])
            .env("COLUMNS", "100")
            .current_dir(&work)
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stdout).to_string()
            + &String::from_utf8_lossy(&out.stderr);
        let actual: Vec<&str> = text.lines().map(str::trim_end).collect();
        let expected: Vec<&str> = s.expected.iter().map(|l| l.trim_end()).collect();
        let code = out.status.code().unwrap_or(-1);
        if code != exit || !text_matches(&expected, &actual) {
            failures.push(format!(
                "{} line {}: `{command}` exited {code} (expected {exit}); its output:\n{text}",
                s.page, s.line
            ));
            if !overwrite() {
                break;
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Every command's `--help` (found by walking `Commands:` sections), as a snapshot.
#[test]
fn help_texts_match_their_snapshots() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/snapshots/help");
    if overwrite() {
        std::fs::create_dir_all(&dir).unwrap();
    }
    let mut todo: Vec<Vec<String>> = vec![Vec::new()];
    let mut seen = 0;
    let mut failures = Vec::new();
    while let Some(path) = todo.pop() {
        // Help is wrapped to the terminal, or to COLUMNS when there is none: fix it.
        let out = Command::new(env!("CARGO_BIN_EXE_kinecal"))
            .env("COLUMNS", "100")
            .args(&path)
            .arg("--help")
            .output()
            .unwrap();
        assert!(out.status.success(), "{path:?}");
        let text = String::from_utf8(out.stdout).unwrap();
        let mut in_commands = false;
        for line in text.lines() {
            if line == "Commands:" {
                in_commands = true;
            } else if in_commands {
                match line.split_whitespace().next() {
                    None => in_commands = false,
                    Some("help") => {}
                    Some(sub) if line.starts_with("  ") && !line.starts_with("   ") => {
                        let mut p = path.clone();
                        p.push(sub.to_string());
                        todo.push(p);
                    }
                    _ => {}
                }
            }
        }
        if let Some(line) = wrapped_example(&text) {
            failures.push(format!(
                "`kinecal {} --help`: an example wrapped at 100 columns, so that its first line \
                 run as shown lacks the rest (break it with ` \\`): `{line}`",
                path.join(" ")
            ));
        }
        let name = if path.is_empty() {
            "kinecal".to_string()
        } else {
            format!("kinecal-{}", path.join("-"))
        };
        let file = dir.join(format!("{name}.txt"));
        seen += 1;
        if overwrite() {
            std::fs::write(&file, &text).unwrap();
        } else {
            let snap = std::fs::read_to_string(&file).unwrap_or_default();
            if snap != text {
                failures.push(format!(
                    "{}: `kinecal {} --help` differs from its snapshot (SNAPSHOTS=overwrite \
                     rewrites it):\n{text}",
                    file.display(),
                    path.join(" ")
                ));
            }
        }
    }
    assert!(seen >= 20, "only {seen} commands found");
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The first line of a help's examples that is neither a command (`  kinecal ...`) nor the
/// continuation (indented deeper) of a line broken with ` \`: a command the help's wrapping
/// broke, whose first line, copied, runs without the rest.
fn wrapped_example(help: &str) -> Option<String> {
    let mut in_examples = false;
    let mut continued = false;
    for line in help.lines() {
        if line == "Example:" || line == "Examples:" {
            in_examples = true;
            continue;
        }
        if !in_examples {
            continue;
        }
        if line.is_empty() {
            in_examples = false;
            continue;
        }
        let command = line.starts_with("  kinecal ");
        if !(command || continued && line.starts_with("      ")) {
            return Some(line.to_string());
        }
        continued = line.trim_end().ends_with(" \\");
    }
    None
}

#[test]
fn matching_rules() {
    assert_eq!(
        wrapped_example("Examples:\n  kinecal a --x \\\n      --y\n  kinecal b\n\nText\n"),
        None
    );
    assert_eq!(
        wrapped_example("Example:\n  kinecal a --x\n  y\n").as_deref(),
        Some("  y")
    );
    assert_eq!(
        wrapped_example("Example:\n  kinecal a --x\n      --y\n").as_deref(),
        Some("      --y")
    );
    assert!(line_matches("a [..] c", "a b c"));
    assert!(line_matches("[..]x", "yyx"));
    assert!(!line_matches("a [..] c", "a b d"));
    assert!(text_matches(&["a", "...", "d"], &["a", "b", "c", "d"]));
    assert!(text_matches(&["a", "...", "d"], &["a", "d"]));
    assert!(!text_matches(&["a", "...", "d"], &["a", "b"]));
    assert_eq!(
        words(r#"kinecal x --columns "a=b c" -v"#),
        ["kinecal", "x", "--columns", "a=b c", "-v"]
    );
}

/// A TOML block a page introduces with a link to an example file (the line before the block
/// ends with `(examples/....toml):` or `(../examples/....toml):`) shows that file as it is.
#[test]
fn readme_toml_blocks_show_their_example_files() {
    let mut checked = 0;
    for page in PAGES {
        let readme = std::fs::read_to_string(repo().join(page)).unwrap();
        let lines: Vec<&str> = readme.lines().collect();
        for (i, line) in lines.iter().enumerate() {
            if line.trim() != "```toml" || i < 2 {
                continue;
            }
            let intro = lines[..i]
                .iter()
                .rev()
                .find(|l| !l.trim().is_empty())
                .expect("text before");
            let Some(file) = intro
                .rsplit_once("](")
                .and_then(|(_, rest)| rest.strip_suffix("):"))
            else {
                continue;
            };
            let end = lines[i + 1..]
                .iter()
                .position(|l| l.trim() == "```")
                .expect("a closed block");
            let shown = lines[i + 1..i + 1 + end].join("\n") + "\n";
            let file = file.trim_start_matches("../");
            let actual = std::fs::read_to_string(repo().join(file)).unwrap();
            assert_eq!(shown, actual, "{page} line {}: {file} differs", i + 1);
            checked += 1;
        }
    }
    assert!(checked >= 1, "no example file shown");
}
