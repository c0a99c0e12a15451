//! Mutation fuzzing of the history's own reader, tolerance files (the driver and the rules are
//! those of `crates/kinecal/tests/fuzz.rs`: no panic, no hang, finite values when accepted, the
//! file named when refused). Long run:
//! `KINECAL_FUZZ_ITERS=1000000 cargo test --release -p kinecal-history --test fuzz -- --nocapture`.

mod common;

#[path = "../../kinecal/tests/fuzz_driver/mod.rs"]
mod fuzz_driver;

use fuzz_driver::{fuzz, Outcome};
use kinecal_history::Tolerances;

#[test]
fn tolerance_files() {
    let seeds: Vec<Vec<u8>> = [
        "# tolerances of the A4\n[tolerances]\nlink1.x = 0.001\np14 = 0.002\n\"p14 + p20\" = 0.5\n",
        "\"joint2.offset\" = 0.05\n'link3.y' = 1e-3\n",
        "link1 = { x = 0.001, y = 0.002 }\n",
    ]
    .iter()
    .map(|s| s.as_bytes().to_vec())
    .collect();
    fuzz("tolerances", "t.toml", &seeds, &|b| {
        let text = match kinecal::source::Source::from_bytes("t.toml", b.to_vec()) {
            Ok(s) => s.text,
            Err(e) => return Outcome::Refused(e.to_string()),
        };
        match Tolerances::parse_toml(&text, "t.toml") {
            Ok(t) => Outcome::Accepted(if t.keys().count() < 100_000 {
                Ok(())
            } else {
                Err("absurd key count".into())
            }),
            Err(e) => Outcome::Refused(e.to_string()),
        }
    });
}

/// History dumps (issue 38): `history import`'s reader and its checks. A mutated dump is read,
/// and when it reads, imported into one SQLite history (the checks run before anything is
/// written): no panic, no hang, a refusal that names the file, and an accepted dump whose every
/// stored number is finite.
#[test]
fn history_dumps() {
    use kinecal::model::examples;
    use kinecal_history::{Database, Dump};

    let dir = tempfile::tempdir().unwrap();
    // The seeds: a dump of two calibrations of the GE A4 and an event.
    let seed = {
        let db = Database::open(dir.path().join("seed.sqlite")).unwrap();
        for k in 0..2u64 {
            let rep = common::report::ge_a4_report(
                &examples::ge_a4(),
                10,
                k,
                &common::report::LINK1_XY_LINK3_Y,
                None,
            );
            db.add("R1", Some(1_790_000_000 + k as i64 * 86_400), &rep, "")
                .unwrap();
        }
        db.add_event("R1", 1_790_000_000, "gearbox J2 replaced")
            .unwrap();
        db.dump().unwrap().to_json()
    };
    let target = Database::open(dir.path().join("h.sqlite")).unwrap();
    fuzz("history dump", "d.json", &[seed.into_bytes()], &|b| {
        let text = match kinecal::source::Source::from_bytes("d.json", b.to_vec()) {
            Ok(s) => s.text,
            Err(e) => return Outcome::Refused(e.to_string()),
        };
        let dump = match Dump::from_json(&text, "d.json") {
            Ok(d) => d,
            Err(e) => return Outcome::Refused(e.to_string()),
        };
        match target.import(&dump) {
            Ok(_) => Outcome::Accepted(
                if dump
                    .calibrations
                    .iter()
                    .flat_map(|c| c.parameters.iter())
                    .all(|p| p.value.is_finite())
                {
                    Ok(())
                } else {
                    Err("a parameter that is not finite was stored".into())
                },
            ),
            Err(e) => Outcome::Refused(format!("d.json: {e}")),
        }
    });
}
