//! Records checked before they are believed (issue 38), on SQLite and PostgreSQL: a damaged
//! dump (a calibration without parameters, a parameter twice or missing) is refused before
//! anything is imported, naming the record and what was expected; a report with a parameter
//! twice is refused by name, not by the store's constraint; a record without parameters already
//! stored makes `drift` and `fleet` say so, never "ok"; after an import into PostgreSQL the next
//! event and calibration get new ids (the sequences moved past the imported ones, and moved
//! again when an earlier kinecal's import left them behind).

mod common;

#[cfg(feature = "postgres")]
use common::pg::TestDb;
use common::report::{ge_a4_report, LINK1_XY_LINK3_Y};
use kinecal::model::examples;
use kinecal::report::CalibrationReport;
use kinecal_history::{drift, fleet, Database, DriftOptions, Dump, Error, FleetOptions, Verdict};

const T0: i64 = 1_790_000_000;
const DAY: i64 = 86_400;

/// A calibration of the GE A4 (link 1's x and y, link 3's y) on simulated data; `seed` varies
/// the data (and so the record's key).
fn report(seed: u64) -> CalibrationReport {
    let key = format!("seed {seed}");
    ge_a4_report(&examples::ge_a4(), 10, seed, &LINK1_XY_LINK3_Y, Some(&key))
}

/// What keeps a place alive: its folder, or its database on the server.
#[allow(dead_code)]
enum Keep {
    Folder(tempfile::TempDir),
    #[cfg(feature = "postgres")]
    Server(TestDb),
}

/// A fresh SQLite file and (with a server) a fresh PostgreSQL database, as (location, keep).
fn places(tag: &str) -> Vec<(String, Keep)> {
    let dir = tempfile::tempdir().unwrap();
    let mut v = vec![(
        dir.path().join("h.sqlite").display().to_string(),
        Keep::Folder(dir),
    )];
    #[cfg(feature = "postgres")]
    if let Some(db) = TestDb::new(tag) {
        v.push((db.url.clone(), Keep::Server(db)));
    }
    #[cfg(not(feature = "postgres"))]
    let _ = tag;
    v
}

/// Robot R1's three calibrations, a month apart, and one event, as a dump's JSON.
fn dump_value() -> serde_json::Value {
    static D: std::sync::OnceLock<serde_json::Value> = std::sync::OnceLock::new();
    D.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let db = Database::open(dir.path().join("h.sqlite")).unwrap();
        for k in 0..3 {
            db.add("R1", Some(T0 + k * 30 * DAY), &report(10 + k as u64), "")
                .unwrap();
        }
        db.add_event("R1", T0 + DAY, "gearbox J2 replaced").unwrap();
        serde_json::from_str(&db.dump().unwrap().to_json()).unwrap()
    })
    .clone()
}

fn dump(v: &serde_json::Value) -> Dump {
    Dump::from_json(&v.to_string(), "d.json").unwrap()
}

#[test]
fn a_damaged_dump_is_refused_naming_the_record_and_nothing_is_imported() {
    let whole = dump_value();
    let listed = whole["calibrations"][1]["parameters"]
        .as_array()
        .unwrap()
        .len();
    for (loc, _keep) in places("damaged_dump") {
        let db = Database::open(&loc).unwrap();
        // No parameters at all.
        let mut v = whole.clone();
        v["calibrations"][1]["parameters"] = serde_json::json!([]);
        let e = db.import(&dump(&v)).unwrap_err();
        assert!(matches!(e, Error::Input(_)), "{e}");
        let e = e.to_string();
        assert!(
            e.contains(&format!(
                "calibration 2 of the dump (the 2nd in its list, robot R1): it has no parameters; \
                 expected one row per parameter of its robot model (its report lists {listed})"
            )) && e.contains("nothing was imported"),
            "{loc}: {e}"
        );
        // One parameter row missing.
        let mut v = whole.clone();
        let removed = v["calibrations"][2]["parameters"]
            .as_array_mut()
            .unwrap()
            .remove(4);
        let e = db.import(&dump(&v)).unwrap_err().to_string();
        assert!(
            e.contains("calibration 3 of the dump (the 3rd in its list, robot R1)")
                && e.contains(&format!("no row for {}", removed["id"].as_str().unwrap())),
            "{loc}: {e}"
        );
        // A parameter twice.
        let mut v = whole.clone();
        let p = v["calibrations"][0]["parameters"][2].clone();
        v["calibrations"][0]["parameters"]
            .as_array_mut()
            .unwrap()
            .push(p.clone());
        let e = db.import(&dump(&v)).unwrap_err().to_string();
        assert!(
            e.contains("calibration 1 of the dump (the 1st in its list, robot R1)")
                && e.contains(&format!(
                    "parameter {} appears twice",
                    p["id"].as_str().unwrap()
                )),
            "{loc}: {e}"
        );
        assert!(!e.contains("UNIQUE") && !e.contains("duplicate key"), "{e}");
        // Nothing of the damaged dumps was written; the whole one imports.
        assert!(db.robots().unwrap().is_empty(), "{loc}");
        assert!(db.events(None).unwrap().is_empty(), "{loc}");
        let s = db.import(&dump(&whole)).unwrap();
        assert_eq!((s.added, s.events_added), (3, 1));
    }
}

#[test]
fn a_report_with_a_parameter_twice_is_refused_by_name() {
    let mut rep = report(1);
    let twice = rep.parameters[1].clone();
    rep.parameters.push(twice.clone());
    for (loc, _keep) in places("param_twice") {
        let db = Database::open(&loc).unwrap();
        let e = db.add("R1", Some(T0), &rep, "").unwrap_err();
        assert!(matches!(e, Error::Input(_)), "{e}");
        let e = e.to_string();
        assert!(
            e.contains(&format!(
                "the report of robot R1: parameter {} appears twice",
                twice.id
            )) && e.contains("not recorded"),
            "{loc}: {e}"
        );
        assert!(!e.contains("UNIQUE") && !e.contains("duplicate key"), "{e}");
        assert!(db.robots().unwrap().is_empty());
    }
}

/// A record without parameters already stored (written by hand, or by an earlier kinecal's
/// import): `drift` refuses to compare, `fleet` gives the robot the verdict UNKNOWN with the
/// reason; neither calls it ok.
#[test]
fn a_stored_record_without_parameters_is_never_ok() {
    for (loc, keep) in places("no_parameters") {
        let db = Database::open(&loc).unwrap();
        for k in 0..3u64 {
            db.add("R1", Some(T0 + k as i64 * 30 * DAY), &report(20 + k), "")
                .unwrap();
            db.add("R2", Some(T0 + k as i64 * 30 * DAY), &report(30 + k), "")
                .unwrap();
        }
        let latest = db.calibrations(Some("R1")).unwrap().last().unwrap().id;
        let sql = format!("DELETE FROM {{s}}parameters WHERE calibration_id = {latest}");
        match &keep {
            Keep::Folder(_) => {
                rusqlite::Connection::open(&loc)
                    .unwrap()
                    .execute_batch(&sql.replace("{s}", ""))
                    .unwrap();
            }
            #[cfg(feature = "postgres")]
            Keep::Server(t) => {
                t.client()
                    .batch_execute(&sql.replace("{s}", "kinecal."))
                    .unwrap();
            }
        }
        let records = db.records(None).unwrap();
        let r1: Vec<_> = records
            .calibrations
            .iter()
            .filter(|c| c.robot_id == "R1")
            .cloned()
            .collect();
        let e = drift(&r1, &DriftOptions::default())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(&format!(
                "calibration {latest} of robot R1 has no parameters"
            )),
            "{loc}: {e}"
        );
        let states = fleet(
            &records.calibrations,
            &[],
            &FleetOptions {
                drift: DriftOptions::default(),
                now: T0 + 90 * DAY,
                horizon: 90 * DAY,
            },
        )
        .unwrap();
        let r1 = states.iter().find(|s| s.robot_id == "R1").unwrap();
        assert_eq!(r1.verdict, Verdict::Unknown, "{loc}");
        assert!(
            r1.problem.as_deref().unwrap().contains("has no parameters"),
            "{loc}: {:?}",
            r1.problem
        );
        let r2 = states.iter().find(|s| s.robot_id == "R2").unwrap();
        assert_eq!(r2.verdict, Verdict::Ok, "{loc}");
        // The unknown robot comes first after the flagged ones.
        assert_eq!(states[0].robot_id, "R1");
    }
}

/// After an import into PostgreSQL, the next event and calibration get new ids (issue 38: the
/// README's dump holds one event, id 1, and the next `history event` failed with a raw
/// duplicate key). A history imported by an earlier kinecal, whose sequences were left behind,
/// heals on its next write.
#[cfg(feature = "postgres")]
#[test]
fn postgres_ids_after_an_import_are_new() {
    let Some(t) = TestDb::new("import_ids") else {
        return;
    };
    let db = Database::open(&t.url).unwrap();
    let whole = dump_value();
    db.import(&dump(&whole)).unwrap();
    let mut c = t.client();
    let seq = |c: &mut postgres::Client, table: &str| -> (i64, bool) {
        let r = c
            .query_one(
                &format!("SELECT last_value, is_called FROM kinecal.{table}_id_seq"),
                &[],
            )
            .unwrap();
        (r.get(0), r.get(1))
    };
    // The sequences moved past the imported ids (the event's id 1 included: a sequence never
    // used hands out its start value next).
    assert_eq!(seq(&mut c, "events"), (1, true));
    assert_eq!(seq(&mut c, "calibrations"), (3, true));
    let e = db
        .add_event("R1", T0 + 50 * DAY, "motor J1 replaced")
        .unwrap();
    assert_eq!((e.id, e.new), (2, true));
    let id = db.add("R1", Some(T0 + 100 * DAY), &report(13), "").unwrap();
    assert_eq!(id, 4);
    // As an earlier kinecal left them: the sequences at their start.
    c.batch_execute(
        "SELECT setval('kinecal.events_id_seq', 1, false);
         SELECT setval('kinecal.calibrations_id_seq', 1, false);",
    )
    .unwrap();
    let e = db
        .add_event("R1", T0 + 60 * DAY, "J3 encoder replaced")
        .unwrap();
    assert_eq!((e.id, e.new), (3, true));
    let id = db.add("R1", Some(T0 + 110 * DAY), &report(14), "").unwrap();
    assert_eq!(id, 5);
    assert_eq!(db.events(None).unwrap().len(), 3);
    assert_eq!(db.calibrations(None).unwrap().len(), 5);
}

/// A dump whose records were damaged field by field (issue: damaged records imported, then
/// wrong drift): each is refused before anything is written, naming the record, the field,
/// its value and what was expected.
#[test]
fn a_dump_with_a_damaged_field_is_refused_naming_the_field() {
    let whole = dump_value();
    // (what is damaged, the damage, the words of the refusal)
    type Damage = fn(&mut serde_json::Value);
    let cases: Vec<(&str, Damage, Vec<String>)> = vec![
        (
            "a negative sigma",
            |v| v["calibrations"][1]["parameters"][0]["sigma"] = serde_json::json!(-0.0004),
            vec![
                "calibration 2 of the dump (the 2nd in its list, robot R1)".into(),
                "parameter p1 (link1.x) has the sigma -0.0004; expected a positive, finite \
                 standard deviation"
                    .into(),
            ],
        ),
        (
            "a zero sigma",
            |v| v["calibrations"][0]["parameters"][1]["sigma"] = serde_json::json!(0.0),
            vec!["parameter p2 (link1.y) has the sigma 0; expected a positive".into()],
        ),
        (
            "a combination's negative sigma",
            |v| {
                v["calibrations"][2]["combinations"] = serde_json::json!([{
                    "expression": "p14 + p20",
                    "terms": "[[\"p14\",\"link3.y\",1.0],[\"p20\",\"link4.y\",1.0]]",
                    "value": 11.81,
                    "sigma": -1.0,
                }])
            },
            vec![
                "calibration 3 of the dump (the 3rd in its list, robot R1)".into(),
                "the combination `p14 + p20` has the sigma -1; expected a positive, finite \
                 standard deviation"
                    .into(),
            ],
        ),
        (
            "a length in millimetres in a record in inches",
            |v| v["calibrations"][0]["parameters"][0]["unit"] = serde_json::json!("mm"),
            vec![
                "parameter p1 (link1.x) has the unit `mm`; expected `in`, the unit of a length \
                 in a record in in and deg"
                    .into(),
            ],
        ),
        (
            "a slope in another length unit",
            |v| {
                let ps = v["calibrations"][0]["parameters"].as_array_mut().unwrap();
                let p = ps.iter_mut().find(|p| p["name"] == "joint3.slope").unwrap();
                p["unit"] = serde_json::json!("mm/unit");
            },
            vec!["has the unit `mm/unit`; expected `in/unit`".into()],
        ),
        (
            "an angle in a length's place",
            |v| v["calibrations"][0]["parameters"][0]["unit"] = serde_json::json!("deg"),
            vec![
                "parameter p1 (link1.x) has the unit `deg`; expected `in`, its unit in the \
                  record's report"
                    .into(),
            ],
        ),
        (
            "a unit that is no unit",
            |v| v["calibrations"][0]["parameters"][0]["unit"] = serde_json::json!("furlong"),
            vec!["has the unit `furlong`, which is not a kinecal unit".into()],
        ),
        (
            "an unknown length unit",
            |v| v["calibrations"][1]["length_unit"] = serde_json::json!("furlong"),
            vec!["its length_unit `furlong` is not a kinecal unit; expected m, mm or in".into()],
        ),
        (
            "an unknown angle unit",
            |v| v["calibrations"][1]["angle_unit"] = serde_json::json!("grad"),
            vec!["its angle_unit `grad` is not a kinecal unit; expected deg or rad".into()],
        ),
        (
            "a time far in the future",
            |v| v["calibrations"][0]["at"] = serde_json::json!(1_000_000_000_000_000i64),
            vec![
                "its at: 1000000000000000 Unix seconds is not a time of years 0000 to 9999".into(),
            ],
        ),
        (
            "a time far in the past",
            |v| v["calibrations"][2]["at"] = serde_json::json!(-1_000_000_000_000i64),
            vec!["its at: -1000000000000 Unix seconds is not a time of years 0000".into()],
        ),
        (
            "an event's time",
            |v| v["events"][0]["at"] = serde_json::json!(1_000_000_000_000_000i64),
            vec!["event 1 of the dump (the 1st in its list of events, robot R1): its at:".into()],
        ),
        (
            "a serial with spaces",
            |v| v["calibrations"][1]["robot_id"] = serde_json::json!("  R1  "),
            vec![
                "its robot_id: the robot id (serial) `  R1  ` has white space at its start or \
                  end"
                .into(),
            ],
        ),
        (
            "a serial longer than history add takes",
            |v| v["calibrations"][1]["robot_id"] = serde_json::json!("R".repeat(129)),
            vec![
                "robot RRRRRRRRRRRRRRRRRRRRRRRRRRRRRRRRRRRRRRRR... (129 characters)".into(),
                "its robot_id: the robot serial: expected a serial of at most 128 characters, \
                 not 129"
                    .into(),
            ],
        ),
        (
            "an event's serial longer than history add takes",
            |v| v["events"][0]["robot_id"] = serde_json::json!("R".repeat(129)),
            vec!["at most 128 characters, not 129".into()],
        ),
    ];
    for (loc, _keep) in places("damaged_fields") {
        let db = Database::open(&loc).unwrap();
        for (what, damage, words) in &cases {
            let mut v = whole.clone();
            damage(&mut v);
            let e = db.import(&dump(&v)).unwrap_err();
            assert!(matches!(e, Error::Input(_)), "{what}: {e}");
            let e = e.to_string();
            for w in words {
                assert!(e.contains(w.as_str()), "{loc}: {what}: {e}\n(expected {w})");
            }
            assert!(e.ends_with("nothing was imported"), "{what}: {e}");
            // The same check, before a history is opened.
            assert_eq!(
                kinecal_history::check_dump(&dump(&v))
                    .unwrap_err()
                    .to_string(),
                e
            );
        }
        assert!(db.robots().unwrap().is_empty(), "{loc}");
        assert!(db.events(None).unwrap().is_empty(), "{loc}");
        // The whole dump imports, its times at the ends of what a date can show included.
        let mut v = whole.clone();
        v["calibrations"][0]["at"] = serde_json::json!(-62_167_219_200i64);
        v["calibrations"][2]["at"] = serde_json::json!(253_402_300_799i64);
        let s = db.import(&dump(&v)).unwrap();
        assert_eq!((s.added, s.events_added), (3, 1));
        let times: Vec<String> = db
            .calibrations(None)
            .unwrap()
            .into_iter()
            .map(|c| c.at_text)
            .collect();
        assert!(
            times.contains(&"0000-01-01T00:00:00Z".to_string()),
            "{times:?}"
        );
        assert!(
            times.contains(&"9999-12-31T23:59:59Z".to_string()),
            "{times:?}"
        );
    }
}
