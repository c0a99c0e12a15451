//! The JSON Schemas shipped in `schemas/` are the ones the code describes: the calibration
//! report, and the analysis, plan, check and ISO 9283 documents (regenerate with
//! `SNAPSHOTS=overwrite cargo test -p kinecal --test schema`).

use std::path::Path;

#[test]
fn the_shipped_schemas_are_the_code_s() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../schemas");
    let overwrite = std::env::var("SNAPSHOTS").is_ok_and(|v| v == "overwrite");
    for (file, generated, title, fields) in [
        (
            "calibration-report.schema.json",
            kinecal::report::calibration_report_schema(),
            "CalibrationReport",
            &[
                "schema_version",
                "created",
                "parameters",
                "observation_errors",
            ][..],
        ),
        (
            "analysis.schema.json",
            kinecal::report::analysis_schema(),
            "AnalysisReport",
            &["schema_version", "rank", "identifiable", "noise_dependent"][..],
        ),
        (
            "plan.schema.json",
            kinecal::apps::plan::plan_schema(),
            "PlanReport",
            &["schema_version", "criterion", "postures"][..],
        ),
        (
            "check.schema.json",
            kinecal::workflow::check_schema(),
            "CheckReport",
            &["schema_version", "ok"][..],
        ),
        (
            "iso9283.schema.json",
            kinecal::apps::iso9283::evaluation_schema(),
            "Evaluation",
            &[
                "schema_version",
                "poses",
                "distances",
                "summary",
                "warnings",
            ][..],
        ),
    ] {
        let path = dir.join(file);
        if overwrite {
            std::fs::write(&path, &generated).unwrap();
        }
        let shipped = std::fs::read_to_string(&path).unwrap_or_default();
        assert!(
            shipped == generated,
            "{} differs from the code's schema: regenerate it with \
             SNAPSHOTS=overwrite cargo test -p kinecal --test schema",
            path.display()
        );
        let v: serde_json::Value = serde_json::from_str(&generated).unwrap();
        assert_eq!(v["title"], title);
        for field in fields {
            assert!(v["properties"].get(field).is_some(), "{file}: {field}");
        }
    }
}
