//! Wrong units end the run (issue 37, item 4): when a unit check fires and the fit ends far
//! above its stated noise, `calibrate` exits 3, writes the report and the HTML page with the
//! reason and no robot file; `--force-units` writes the robot anyway.

use std::path::Path;

mod common;

use common::{argv, run};

/// `file`'s columns named in `columns` multiplied by `factor` (a unit slip), written to `out`.
fn scaled(dir: &Path, file: &str, columns: &[&str], factor: f64, out: &str) {
    let text = std::fs::read_to_string(dir.join(file)).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let pick: Vec<bool> = header.iter().map(|h| columns.contains(h)).collect();
    let mut o = header.join(",") + "\n";
    for l in lines {
        let fields: Vec<String> = l
            .split(',')
            .zip(&pick)
            .map(|(f, &p)| match (p, f.parse::<f64>()) {
                (true, Ok(v)) => format!("{}", v * factor),
                _ => f.to_string(),
            })
            .collect();
        o += &(fields.join(",") + "\n");
    }
    std::fs::write(dir.join(out), o).unwrap();
}

fn robot_path() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples/robots/abb_irb120.toml")
        .to_string_lossy()
        .into_owned()
}

/// Degree readings into a radian robot, and millimetre positions into a metre robot: refused,
/// exit 3, no robot written; the report and the page say why; `--force-units` writes it.
#[test]
fn a_unit_slip_that_the_fit_cannot_absorb_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let robot = robot_path();
    let (code, _, e) = run(
        d,
        &argv(&format!(
            "simulate --robot {robot} --postures 40 --seed 3 --noise length=0.00005 \
             --perturb link2.z=0.001,joint3.offset=0.002 --out data.csv"
        )),
    );
    assert_eq!(code, 0, "{e}");
    scaled(
        d,
        "data.csv",
        &["v1", "v2", "v3", "v4", "v5", "v6"],
        180.0 / std::f64::consts::PI,
        "degrees.csv",
    );
    scaled(d, "data.csv", &["x", "y", "z"], 1000.0, "millimetres.csv");
    for file in ["degrees.csv", "millimetres.csv"] {
        let _ = std::fs::remove_file(d.join("cal.toml"));
        let (code, out, e) = run(
            d,
            &argv(&format!(
                "calibrate --robot {robot} --data {file} --out cal.toml --report r.json \
                 --html r.html -q"
            )),
        );
        assert_eq!(code, 3, "{file}: {out}{e}");
        assert!(e.contains("REFUSED: a unit check fired"), "{file}: {e}");
        assert!(!d.join("cal.toml").exists(), "{file}: a robot was written");
        let report = std::fs::read_to_string(d.join("r.json")).unwrap();
        assert!(report.contains("\"refused\""), "{file}");
        let page = std::fs::read_to_string(d.join("r.html")).unwrap();
        assert!(page.contains("REFUSED"), "{file}: the page has no banner");
        // Forced: the robot is written, the warnings stay.
        let (code, out, e) = run(
            d,
            &argv(&format!(
                "calibrate --robot {robot} --data {file} --out cal.toml --force-units -q"
            )),
        );
        assert!(code == 0 || code == 4, "{file}: {code} {out}{e}");
        assert!(
            d.join("cal.toml").exists(),
            "{file}: --force-units wrote nothing"
        );
    }
    // The same data in its own units stands.
    let (code, out, e) = run(
        d,
        &argv(&format!(
            "calibrate --robot {robot} --data data.csv --out cal.toml -q"
        )),
    );
    assert_eq!(code, 0, "{out}{e}");
    assert!(!e.contains("REFUSED"));
}
