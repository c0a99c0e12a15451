//! Files written by other tools load as they are: Python's TOML writers (inline arrays of
//! tables), Python's CSV writer (CRLF line ends, quoted fields, `;`).

use std::path::Path;

use kinecal::files::parse_measurements;
use kinecal::model::robot_file::{parse_robot_toml, write_robot_toml};

fn fixture(name: &str) -> String {
    std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/fixtures")
            .join(name),
    )
    .unwrap()
}

#[test]
fn robot_files_from_python_toml_writers_load() {
    let reference = kinecal::model::examples::ge_a4();
    for name in ["ge_a4_tomli_w.toml", "ge_a4_toml.toml", "ge_a4_inline.toml"] {
        let text = fixture(name);
        let r = parse_robot_toml(&text, name).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(r.param_count(), reference.param_count());
        for id in r.param_ids() {
            assert!((r.get(id) - reference.get(id)).abs() < 1e-15, "{name} {id}");
        }
        // Written back (as [[sections]] where it was inline), it reads the same.
        let again = parse_robot_toml(&write_robot_toml(&r, Some(&text)), name).unwrap();
        assert_eq!(again, r, "{name}");
    }
    // A mistake inside an inline table still names its field and line.
    let bad = fixture("ge_a4_tomli_w.toml").replace("slope = 7.2", "slope = \"fast\"");
    let e = parse_robot_toml(&bad, "b.toml").unwrap_err().to_string();
    assert!(
        e.contains("b.toml:") && e.contains("joints[0].slope"),
        "{e}"
    );
}

#[test]
fn measurement_files_from_python_csv_writers_load() {
    let robot = kinecal::model::examples::ge_a4();
    let plain = parse_measurements(&fixture("data_python_csv.csv"), "a.csv", &robot).unwrap();
    let quoted =
        parse_measurements(&fixture("data_python_csv_quoted.csv"), "b.csv", &robot).unwrap();
    assert_eq!(plain.observations.len(), 10);
    assert_eq!(plain, quoted);
    assert_eq!(plain.observations[9].line(), 11);
}

/// Files kinecal writes carry no float noise: exact zeros are 0, other values read back to the
/// same robot (to 1e-15), whatever the units.
#[test]
fn written_robots_read_back_the_same_without_float_noise() {
    use kinecal::apps::simulate;
    let kinds = [kinecal::JointKind::Revolute; 6];
    for (k, (length, angle)) in [
        (kinecal::LengthUnit::M, kinecal::AngleUnit::Rad),
        (kinecal::LengthUnit::Mm, kinecal::AngleUnit::Deg),
        (kinecal::LengthUnit::In, kinecal::AngleUnit::Deg),
    ]
    .into_iter()
    .enumerate()
    {
        let mut r = simulate::random_robot(&kinds, 70 + k as u64);
        r.units = kinecal::Units { length, angle };
        r.links[2].beta = 0.0;
        r.links[3].y = 0.0;
        let text = write_robot_toml(&r, None);
        let back = parse_robot_toml(&text, "r.toml").unwrap();
        for id in r.param_ids() {
            let (a, b) = (r.get(id), back.get(id));
            assert!(
                (a - b).abs() <= 1e-15 * a.abs().max(1.0),
                "{id}: {a} vs {b}"
            );
        }
        assert!(text.contains("beta = 0.0\n"), "{text}");
        // No value is written as float noise (tiny exponents).
        assert!(
            !text.contains("e-1") && !text.contains("e-2") && !text.contains("e-3"),
            "{text}"
        );
    }
    // The poses `fk` writes: an exact 0 angle is 0, not 6.6e-15.
    let a4 = kinecal::model::examples::ge_a4();
    let data = simulate::measure(&a4, &simulate::sample_postures(&a4, 5, 1), false);
    let csv = kinecal::files::write_measurements(&a4, &data);
    let noise = csv
        .split(['\n', ','])
        .filter_map(|f| f.parse::<f64>().ok())
        .any(|v| v != 0.0 && v.abs() < 1e-9);
    assert!(!noise, "{csv}");
}

/// A posture that measures the same target twice is refused, naming both lines: the end
/// effector, a site, and a site beyond the 64th (kept apart from the first ones); the same
/// sites in other postures, or other sites in the same posture, are accepted.
#[test]
fn a_target_measured_twice_in_one_posture_is_refused_with_both_lines() {
    let mut robot = kinecal::model::examples::ge_a4();
    for s in 0..70 {
        robot.sites.push(kinecal::Site {
            name: format!("s{s}"),
            joint: 4,
            frame: kinecal::Link {
                x: 0.1 * s as f64,
                y: 0.0,
                z: 0.0,
                alpha: 0.0,
                beta: 0.0,
                gamma: 0.0,
            },
        });
    }
    let row = |posture: &str, site: &str| format!("{posture},{site},1,2,3,4,5,6,7\n");
    let header = "posture,site,v1,v2,v3,v4,x,y,z\n";
    let file = |rows: &[(&str, &str)]| {
        header.to_string() + &rows.iter().map(|(p, s)| row(p, s)).collect::<String>()
    };
    let ok = file(&[
        ("1", "ee"),
        ("1", "s0"),
        ("1", "s69"),
        ("2", "ee"),
        ("2", "s0"),
        ("2", "s69"),
        ("1", "s68"),
    ]);
    assert_eq!(
        parse_measurements(&ok, "m.csv", &robot)
            .unwrap()
            .observations
            .len(),
        7
    );
    for (rows, expect) in [
        (
            &[("1", "ee"), ("2", "ee"), ("1", "ee")][..],
            "m.csv:4: posture `1` measures ee twice (first on line 2)",
        ),
        (
            &[("1", "s0"), ("2", "s0"), ("2", "s1"), ("2", "s0")][..],
            "m.csv:5: posture `2` measures s0 twice (first on line 3)",
        ),
        (
            &[("1", "s69"), ("1", "s68"), ("1", "s69")][..],
            "m.csv:4: posture `1` measures s69 twice (first on line 2)",
        ),
    ] {
        let e = parse_measurements(&file(rows), "m.csv", &robot)
            .unwrap_err()
            .to_string();
        assert!(e.contains(expect), "expected `{expect}` in {e}");
    }
}
