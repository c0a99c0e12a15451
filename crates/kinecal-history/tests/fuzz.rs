//! Mutation fuzzing of the history's own reader, tolerance files (the driver and the rules are
//! those of `crates/kinecal/tests/fuzz.rs`: no panic, no hang, finite values when accepted, the
//! file named when refused). Long run:
//! `KINECAL_FUZZ_ITERS=1000000 cargo test --release -p kinecal-history --test fuzz -- --nocapture`.

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
