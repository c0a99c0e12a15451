//! `kinecal compensate` on a tree (a torso under two arms, `examples/trees`): a program's rows
//! reach each named tool with its own branch's joints, the torso held at the program's
//! readings, so that compensating one arm never moves the other; a measurement file's rows of
//! one posture agree on the torso; a list of tools on one branch, or for targets, is refused.

// Held joints are compared to the bit: they are the program's readings, written back.
#![allow(clippy::float_cmp)]

mod common;

use std::path::Path;

use common::{argv, run, run_ok};

fn examples() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/trees")
}

/// Rows of a CSV file as maps of column name to field.
fn table(path: &Path) -> Vec<std::collections::HashMap<String, String>> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines().filter(|l| !l.starts_with('#'));
    let head: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    lines
        .map(|l| {
            head.iter()
                .cloned()
                .zip(l.split(',').map(String::from))
                .collect()
        })
        .collect()
}

fn num(row: &std::collections::HashMap<String, String>, key: &str) -> f64 {
    row[key].parse().unwrap()
}

/// The largest difference of position (mm) and attitude (deg, wrapped) between two `fk`
/// outputs, row by row.
fn largest_difference(a: &Path, b: &Path) -> (f64, f64) {
    let (a, b) = (table(a), table(b));
    assert_eq!(a.len(), b.len());
    let (mut p, mut r) = (0.0f64, 0.0f64);
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(x["site"], y["site"]);
        for k in ["x", "y", "z"] {
            p = p.max((num(x, k) - num(y, k)).abs());
        }
        for k in ["alpha", "beta", "gamma"] {
            let d = (num(x, k) - num(y, k)).rem_euclid(360.0);
            r = r.max(d.min(360.0 - d));
        }
    }
    (p, r)
}

#[test]
fn a_program_of_two_arms_reaches_each_tool_and_never_moves_the_other_arm() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let dh = examples().join("dual_arm_dh.csv");
    run_ok(
        d,
        &[
            "import",
            "dh",
            dh.to_str().unwrap(),
            "--name",
            "dual",
            "--out",
            "dual.toml",
        ],
    );
    // The real robot: millimetres and tenths of a degree off the table.
    run_ok(
        d,
        &argv(
            "simulate --robot dual.toml --postures 25 --seed 4 --perturb-std length=0.3,angle=0.02
             --out m.csv --truth real.toml",
        ),
    );
    // Postures away from the wrists' singularities, headed by joint names in another order.
    std::fs::write(
        d.join("program.csv"),
        "posture,RIGHT_S,RIGHT_L,RIGHT_U,RIGHT_R,RIGHT_B,RIGHT_T,TORSO,LEFT_S,LEFT_L,LEFT_U,LEFT_R,LEFT_B,LEFT_T\n\
         a,30,-60,45,-80,90,10,15,-30,-120,-45,-100,-90,-10\n\
         b,-20,-80,60,-60,45,-30,-25,40,-100,-30,-70,60,20\n\
         c,10,-70,30,-90,-60,0,5,-10,-110,-60,-80,-45,90\n",
    )
    .unwrap();
    run_ok(
        d,
        &argv("fk --robot dual.toml --postures program.csv --out meant.csv"),
    );
    let program = table(&d.join("program.csv"));
    let reached = |out: &str| {
        let rows = table(&d.join(out));
        let mut postures = String::from("posture");
        for j in 1..=13 {
            postures += &format!(",v{j}");
        }
        postures.push('\n');
        for r in &rows {
            postures += &r["posture"];
            for j in 1..=13 {
                postures += &format!(",{}", r[&format!("v{j}")]);
            }
            postures.push('\n');
        }
        std::fs::write(d.join("readings.csv"), postures).unwrap();
        run_ok(
            d,
            &argv("fk --robot real.toml --postures readings.csv --out got.csv"),
        );
        rows
    };
    // The robot file's joint order: TORSO, LEFT_S..LEFT_T, RIGHT_S..RIGHT_T.
    let names = [
        "TORSO", "LEFT_S", "LEFT_L", "LEFT_U", "LEFT_R", "LEFT_B", "LEFT_T", "RIGHT_S", "RIGHT_L",
        "RIGHT_U", "RIGHT_R", "RIGHT_B", "RIGHT_T",
    ];
    // The end effector alone: the right arm reaches its poses, the torso and the left arm keep
    // the program's readings (before: the torso moved and the left tool ended further off),
    // and a note says what was left as programmed.
    let (code, _, err) = run(
        d,
        &argv("compensate --robot real.toml --nominal dual.toml --in program.csv --out right.csv"),
    );
    assert_eq!(code, 0, "{err}");
    assert!(
        err.contains("TORSO (shared with another branch) stays at the program's readings")
            && err.contains("LEFT_tool0 is left as programmed")
            && err.contains("--site RIGHT_tool0,LEFT_tool0"),
        "{err}"
    );
    let rows = reached("right.csv");
    for (r, p) in rows.iter().zip(&program) {
        for (j, name) in names.iter().enumerate().take(7) {
            assert_eq!(num(r, &format!("v{}", j + 1)), num(p, name), "{name}");
        }
    }
    let got = table(&d.join("got.csv"));
    let meant = table(&d.join("meant.csv"));
    for (g, m) in got.iter().zip(&meant) {
        let off = ["x", "y", "z"]
            .map(|k| (num(g, k) - num(m, k)).abs())
            .into_iter();
        let off = off.fold(0.0, f64::max);
        if g["site"] == "RIGHT_tool0" {
            assert!(off < 1e-6, "{off} mm");
        } else {
            // As programmed: the real robot's error there, a millimetre or so.
            assert!(off > 0.05, "{off} mm");
        }
    }
    // Both tools named: each reaches its pose, with the torso still as programmed.
    let (code, _, err) = run(
        d,
        &argv(
            "compensate --robot real.toml --nominal dual.toml --in program.csv
             --site ee,LEFT_tool0 --out both.csv",
        ),
    );
    assert_eq!(code, 0, "{err}");
    assert!(
        err.contains("TORSO (shared by the branches) stays"),
        "{err}"
    );
    let rows = reached("both.csv");
    for (r, p) in rows.iter().zip(&program) {
        assert_eq!(num(r, "v1"), num(p, "TORSO"));
        assert!(r["flags"].is_empty(), "{r:?}");
    }
    let (p, a) = largest_difference(&d.join("got.csv"), &d.join("meant.csv"));
    // The solver's tolerance is 1e-15 m and rad; the files' 16 digits of mm and deg.
    assert!(p < 1e-6 && a < 1e-7, "{p} mm, {a} deg");
    // Two tools on one branch, or a list for targets: refused.
    let (code, _, err) = run(
        d,
        &argv(
            "compensate --robot real.toml --nominal dual.toml --in program.csv
             --site ee,RIGHT_tool0 --out x.csv",
        ),
    );
    assert_eq!(code, 1);
    assert!(err.contains("lie on one branch"), "{err}");
    let (code, _, err) = run(
        d,
        &argv(
            "compensate --robot real.toml --nominal dual.toml --in program.csv
             --site ee,,LEFT_tool0 --out x.csv",
        ),
    );
    assert_eq!(code, 1);
    assert!(err.contains("an empty name in the list of tools"), "{err}");
    // The other arm's tool alone: the end effector is the tool left as programmed.
    let (code, _, err) = run(
        d,
        &argv(
            "compensate --robot real.toml --nominal dual.toml --in program.csv
             --site LEFT_tool0 --out left.csv",
        ),
    );
    assert_eq!(code, 0, "{err}");
    assert!(
        err.contains("RIGHT_tool0 is left as programmed")
            && err.contains("--site LEFT_tool0,RIGHT_tool0"),
        "{err}"
    );
    let (code, _, err) = run(
        d,
        &argv(
            "compensate --robot real.toml --nominal dual.toml --in m.csv
             --site ee,LEFT_tool0 --out x.csv",
        ),
    );
    assert_eq!(code, 1);
    assert!(err.contains("a list is for a program of a tree"), "{err}");
    assert!(!d.join("x.csv").exists());
    // A measurement file's rows (seeded targets, one per tool): each posture's rows agree on
    // the torso, the measured posture's own reading.
    let (code, _, err) = run(
        d,
        &argv("compensate --robot real.toml --nominal dual.toml --in m.csv --out targets.csv"),
    );
    assert!(code == 0 || code == 3, "{err}");
    let measured = table(&d.join("m.csv"));
    let rows = table(&d.join("targets.csv"));
    assert_eq!(rows.len(), measured.len());
    for (r, m) in rows.iter().zip(&measured) {
        assert_eq!(r["posture"], m["posture"]);
        assert_eq!(num(r, "v1"), num(m, "v1"), "posture {}", r["posture"]);
    }
}
