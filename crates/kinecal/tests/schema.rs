//! The JSON Schema of the calibration report shipped in `schemas/` is the one the code
//! describes (regenerate with `SNAPSHOTS=overwrite cargo test -p kinecal --test schema`).

use std::path::Path;

#[test]
fn the_shipped_report_schema_is_the_code_s() {
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../schemas/calibration-report.schema.json");
    let generated = kinecal::report::calibration_report_schema();
    if std::env::var("SNAPSHOTS").is_ok_and(|v| v == "overwrite") {
        std::fs::write(&path, &generated).unwrap();
    }
    let shipped = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        shipped == generated,
        "{} differs from the report's schema: regenerate it with \
         SNAPSHOTS=overwrite cargo test -p kinecal --test schema",
        path.display()
    );
    let v: serde_json::Value = serde_json::from_str(&generated).unwrap();
    assert_eq!(v["title"], "CalibrationReport");
    for field in [
        "schema_version",
        "created",
        "parameters",
        "observation_errors",
    ] {
        assert!(v["properties"].get(field).is_some(), "{field}");
    }
}
