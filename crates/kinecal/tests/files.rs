//! Files written by other tools load as they are: Python's TOML writers (inline arrays of
//! tables), Python's CSV writer (CRLF line ends, quoted fields, `;`).

use std::path::Path;

use kinecal::observe::point::parse_measurements;
use kinecal::robot_file::{parse_robot_toml, write_robot_toml};

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
    let reference = kinecal::examples::ge_a4();
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
    let robot = kinecal::examples::ge_a4();
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
    use kinecal::simulate;
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
    let a4 = kinecal::examples::ge_a4();
    let data = simulate::measure(&a4, &simulate::sample_postures(&a4, 5, 1), false);
    let csv = kinecal::observe::point::write_measurements(&a4, &data);
    let noise = csv
        .split(['\n', ','])
        .filter_map(|f| f.parse::<f64>().ok())
        .any(|v| v != 0.0 && v.abs() < 1e-9);
    assert!(!noise, "{csv}");
}
