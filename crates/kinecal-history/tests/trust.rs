//! The history's promises under hostile input: foreign, corrupt, damaged, missing and read-only
//! databases; calibrations of another robot model or in other units; bad drift settings.

use std::path::Path;

use kinecal::apps::simulate;
use kinecal::observe::Weights;
use kinecal::report::CalibrationReport;
use kinecal::units::{LengthUnit, Units};
use kinecal::workflow::{self, Request, Selection, SolutionRule};
use kinecal::{model::examples, Robot};
use kinecal_history::{drift, AddOptions, Baseline, Database, DriftOptions, Error, Tolerances};
use rand::{RngExt, SeedableRng};

/// A calibration of the GE A4 (every parameter, minimum change) on 30 simulated postures,
/// with `robot`'s units.
fn calibrate(robot: &Robot, seed: u64) -> CalibrationReport {
    let (sl, sa) = (0.0005 * 0.0254, 0.005f64.to_radians());
    let mut data = simulate::measure(robot, &simulate::sample_postures(robot, 30, seed), false);
    simulate::add_noise(&mut data, sl, sa, seed + 1000);
    let mut req = Request::new(robot.clone(), data);
    req.selection = Selection::List(robot.param_ids().collect());
    req.weights = Weights {
        length: sl,
        angle: sa,
    };
    req.solution = SolutionRule::MinChange;
    workflow::run(&req, &mut ()).unwrap().report
}

fn report() -> CalibrationReport {
    static R: std::sync::OnceLock<CalibrationReport> = std::sync::OnceLock::new();
    R.get_or_init(|| calibrate(&examples::ge_a4(), 1)).clone()
}

/// A history of `n` calibrations of robot R1, a month apart, notes `note k`.
fn history(path: &Path, n: i64) {
    let db = Database::open(path).unwrap();
    for k in 0..n {
        db.add(
            "R1",
            Some(1_790_000_000 + k * 30 * 86_400),
            &report(),
            &format!("note {k}"),
        )
        .unwrap();
    }
}

fn sqlite(path: &Path) -> rusqlite::Connection {
    rusqlite::Connection::open(path).unwrap()
}

/// Every file in the folder with its length and a hash of its bytes.
fn snapshot(dir: &Path) -> Vec<(String, usize, u64)> {
    use std::hash::{Hash, Hasher};
    let mut v: Vec<(String, usize, u64)> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| {
            let e = e.unwrap();
            let bytes = std::fs::read(e.path()).unwrap_or_default();
            let mut h = std::hash::DefaultHasher::new();
            bytes.hash(&mut h);
            (
                e.file_name().to_string_lossy().to_string(),
                bytes.len(),
                h.finish(),
            )
        })
        .collect();
    v.sort();
    v
}

/// `after` is `before` plus, at most, the empty write-ahead log and the shared-memory index
/// SQLite's readers create beside a WAL database in a folder they can write (the next writer
/// removes them). The database file itself is unchanged.
fn same_but_reader_files(before: &[(String, usize, u64)], after: &[(String, usize, u64)]) -> bool {
    let kept: Vec<_> = after
        .iter()
        .filter(|(n, len, _)| !(n.ends_with("-shm") || (n.ends_with("-wal") && *len == 0)))
        .cloned()
        .collect();
    kept == before
}

#[test]
fn files_that_are_not_kinecal_histories_are_never_written() {
    let cases: [(&str, &str, &str); 5] = [
        ("negative user_version", "PRAGMA user_version = -3;", "-3"),
        (
            "negative version over kinecal's tables",
            "__KINECAL__ PRAGMA user_version = -1;",
            "-1",
        ),
        (
            "another application's table named calibrations",
            "CREATE TABLE calibrations (serial TEXT, offset REAL); PRAGMA user_version = 1;",
            "calibrations",
        ),
        (
            "kinecal's version without its tables",
            "CREATE TABLE calibrations (id INTEGER PRIMARY KEY); PRAGMA user_version = 1;",
            "parameters",
        ),
        (
            "kinecal's schema and a trigger",
            "__KINECAL__ CREATE TRIGGER t AFTER INSERT ON calibrations BEGIN DELETE FROM calibrations; END;",
            "trigger",
        ),
    ];
    for (what, sql, hint) in cases {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("h.sqlite");
        if let Some(rest) = sql.strip_prefix("__KINECAL__ ") {
            history(&path, 1);
            let c = sqlite(&path);
            c.execute_batch("PRAGMA journal_mode = DELETE;").unwrap();
            c.execute_batch(rest).unwrap();
        } else {
            sqlite(&path).execute_batch(sql).unwrap();
        }
        let before = snapshot(dir.path());
        for read_only in [false, true] {
            let e = if read_only {
                Database::open_read_only(&path).err()
            } else {
                Database::open(&path).err()
            };
            let e = e.unwrap_or_else(|| panic!("{what}: opened (read-only {read_only})"));
            assert!(
                matches!(e, Error::Foreign { .. }),
                "{what}: unexpected error {e}"
            );
            let msg = e.to_string();
            assert!(
                msg.contains("not a kinecal history")
                    && msg.contains("not modified")
                    && msg.contains(hint),
                "{what}: {msg}"
            );
            assert_eq!(snapshot(dir.path()), before, "{what}: the folder changed");
        }
        // The journal mode is still the file's own.
        let mode: String = sqlite(&path)
            .query_row("PRAGMA journal_mode", [], |r| r.get(0))
            .unwrap();
        assert_eq!(mode, "delete", "{what}");
    }
}

/// 400 random corruptions of a 5-record database (1 to 4 bytes flipped at random offsets):
/// every one that fails `PRAGMA quick_check` is refused by `add` and left byte-identical. (400,
/// not 150 as for schema version 1: version 2's index and table add pages where most flips land
/// in free space, unseen by any check.)
#[test]
fn corrupt_databases_are_refused_untouched() {
    let dir = tempfile::tempdir().unwrap();
    let clean_path = dir.path().join("clean.sqlite");
    history(&clean_path, 5);
    let clean = std::fs::read(&clean_path).unwrap();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(20_261_122);
    let (mut failing, mut refused, mut added) = (0, 0, 0);
    for trial in 0..400 {
        let mut bytes = clean.clone();
        for _ in 0..rng.random_range(1..=4) {
            let at = rng.random_range(0..bytes.len());
            bytes[at] ^= rng.random_range(1..=255u8);
        }
        // The oracle: SQLite's own quick_check, on a copy.
        let probe = dir.path().join(format!("probe{trial}.sqlite"));
        std::fs::write(&probe, &bytes).unwrap();
        let check: Result<String, _> = rusqlite::Connection::open_with_flags(
            &probe,
            rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY,
        )
        .and_then(|c| c.query_row("PRAGMA quick_check", [], |r| r.get(0)));
        let sound = matches!(check.as_deref(), Ok("ok"));
        let sub = dir.path().join(format!("t{trial}"));
        std::fs::create_dir(&sub).unwrap();
        let path = sub.join("h.sqlite");
        std::fs::write(&path, &bytes).unwrap();
        let result = Database::open(&path).and_then(|db| db.add("R1", Some(1), &report(), ""));
        if !sound {
            failing += 1;
            let e = result.err().unwrap_or_else(|| {
                panic!("trial {trial}: recorded into a database failing quick_check ({check:?})")
            });
            assert!(e.to_string().contains("not modified"), "trial {trial}: {e}");
            assert_eq!(
                std::fs::read(&path).unwrap(),
                bytes,
                "trial {trial}: the file changed"
            );
            let names: Vec<String> = std::fs::read_dir(&sub)
                .unwrap()
                .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
                .collect();
            assert!(
                names
                    .iter()
                    .all(|n| ["h.sqlite", "h.sqlite-wal", "h.sqlite-shm"].contains(&n.as_str())),
                "trial {trial}: {names:?}"
            );
            refused += 1;
        } else if result.is_ok() {
            added += 1;
        }
    }
    eprintln!(
        "{failing} of 400 corruptions fail quick_check, all refused; {added} others recorded"
    );
    assert!(
        failing >= 10,
        "only {failing} corruptions failed quick_check"
    );
    assert_eq!(refused, failing);
}

#[test]
fn a_damaged_record_is_named_and_the_others_are_served() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("h.sqlite");
    history(&path, 5);
    {
        let c = sqlite(&path);
        c.execute_batch(
            "UPDATE calibrations SET note = CAST(x'6e6f7465ff' AS TEXT) WHERE id = 2;
             UPDATE calibrations SET report = '{\"robot\": ' WHERE id = 3;
             UPDATE combinations SET terms = 'garbage' WHERE calibration_id = 4;",
        )
        .unwrap();
    }
    let db = Database::open_read_only(&path).unwrap();
    assert_eq!(db.integrity_problem(), None);
    let r = db.records(Some("R1")).unwrap();
    let ids: Vec<i64> = r.calibrations.iter().map(|c| c.id).collect();
    assert_eq!(ids, [1, 5]);
    let damaged: Vec<(i64, &str)> = r
        .damaged
        .iter()
        .map(|d| (d.id, d.problem.as_str()))
        .collect();
    assert_eq!(damaged.len(), 3, "{damaged:?}");
    assert!(damaged[0].0 == 2 && damaged[0].1.contains("note") && damaged[0].1.contains("UTF-8"));
    assert!(damaged[1].0 == 3 && damaged[1].1.contains("stored report is not valid JSON"));
    assert!(damaged[2].0 == 4 && damaged[2].1.contains("terms are not valid JSON"));
    assert_eq!(db.records(None).unwrap().calibrations.len(), 2);
    // One by id: an error naming the record; the strict list names the first damaged one.
    let e = db.calibration(2).unwrap_err().to_string();
    assert!(e.contains("calibration 2") && e.contains("note"), "{e}");
    assert!(db.calibration(5).unwrap().is_some());
    let e = db.calibrations(Some("R1")).unwrap_err().to_string();
    assert!(e.contains("calibration 2"), "{e}");
    // Drift over what can be read.
    drift(&r.calibrations, &DriftOptions::default()).unwrap();
    // A new record can be written beside them (the file itself is sound).
    drop(db);
    Database::open(&path)
        .unwrap()
        .add("R1", None, &report(), "")
        .unwrap();
}

#[test]
fn reads_never_create_a_database() {
    let dir = tempfile::tempdir().unwrap();
    for p in ["missing.sqlite", "no/folder/h.sqlite"] {
        let path = dir.path().join(p);
        let e = Database::open_read_only(&path).err().expect("refused");
        assert!(matches!(e, Error::NoDatabase { .. }), "{e}");
        assert!(e.to_string().contains("no such history database"), "{e}");
    }
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    // An empty file (a database without tables yet) reads as an empty history, untouched.
    let empty = dir.path().join("empty.sqlite");
    std::fs::write(&empty, "").unwrap();
    let db = Database::open_read_only(&empty).unwrap();
    assert!(db.records(None).unwrap().calibrations.is_empty());
    assert!(db.add("R1", None, &report(), "").is_err());
    drop(db);
    assert_eq!(std::fs::read(&empty).unwrap(), b"");
}

#[cfg(unix)]
#[test]
fn a_read_only_database_serves_reads_untouched() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let sub = dir.path().join("ro");
    std::fs::create_dir(&sub).unwrap();
    let path = sub.join("h.sqlite");
    history(&path, 3);
    let before = snapshot(&sub);
    std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o444)).unwrap();
    std::fs::set_permissions(&sub, std::fs::Permissions::from_mode(0o555)).unwrap();
    let result = std::panic::catch_unwind(|| {
        let db = Database::open_read_only(&path).unwrap();
        let r = db.records(None).unwrap();
        assert_eq!(r.calibrations.len(), 3);
        assert!(r.damaged.is_empty());
        drift(&r.calibrations, &DriftOptions::default()).unwrap();
        assert!(db.add("R1", None, &report(), "").is_err());
    });
    std::fs::set_permissions(&sub, std::fs::Permissions::from_mode(0o755)).unwrap();
    std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o644)).unwrap();
    result.unwrap();
    // Nothing written (as root, whom permissions do not stop, SQLite's reader files may
    // appear beside it).
    assert!(same_but_reader_files(&before, &snapshot(&sub)));
}

#[test]
fn a_calibration_of_another_robot_model_is_refused_unless_forced() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("h.sqlite");
    history(&path, 1);
    let db = Database::open(&path).unwrap();
    let rep = report();
    // Joint 3 revolute instead of prismatic.
    let mut revolute = rep.clone();
    for p in &mut revolute.parameters {
        match p.name.as_str() {
            "joint3.offset" => p.unit = "deg".into(),
            "joint3.slope" => p.unit = "deg/unit".into(),
            _ => {}
        }
    }
    // A joint (and its link) fewer.
    let mut fewer = rep.clone();
    fewer
        .parameters
        .retain(|p| !p.name.starts_with("joint4.") && !p.name.starts_with("link5."));
    // A site more.
    let mut site = rep.clone();
    let mut extra = site.parameters[0].clone();
    extra.name = "site.tcp.x".into();
    extra.id = "p39".into();
    site.parameters.push(extra);
    for (what, r, words) in [
        (
            "kind",
            &revolute,
            &["joint 3 is revolute, earlier prismatic"][..],
        ),
        (
            "count",
            &fewer,
            &["3 joints, earlier 4", "`joint4.offset`"][..],
        ),
        ("names", &site, &["`site.tcp.x`"][..]),
    ] {
        let before = std::fs::read(&path).unwrap();
        let e = db.add("R1", None, r, "").unwrap_err();
        assert!(
            matches!(e, Error::ModelMismatch { earlier_id: 1, .. }),
            "{what}: {e}"
        );
        let msg = e.to_string();
        for w in words {
            assert!(msg.contains(w) && msg.contains("R1"), "{what}: {msg}");
        }
        assert_eq!(std::fs::read(&path).unwrap(), before);
        // Under another serial: a history of its own.
        db.add(&format!("R-{what}"), None, r, "").unwrap();
    }
    // Forced: recorded; after that, both models are the robot's.
    let forced = db
        .add_with("R1", None, &revolute, "rebuilt", AddOptions { force: true })
        .unwrap();
    assert!(forced > 1);
    // (Times given: the same report again without one is the same calibration, not recorded
    // twice; see `the_same_calibration_is_recorded_once`.)
    db.add("R1", Some(1_800_000_000), &revolute, "").unwrap();
    db.add("R1", Some(1_800_000_001), &rep, "").unwrap();
    // Units are not the model: the same robot in millimetres is accepted.
    let mut mm = examples::ge_a4();
    mm.units.length = LengthUnit::Mm;
    db.add("R1", None, &calibrate(&mm, 1), "").unwrap();
    assert_eq!(db.calibrations(Some("R1")).unwrap().len(), 5);
}

/// The same robot and the same data, calibrated in inches and in millimetres: drift converts
/// to the first record's units and flags nothing; compared raw, every length would "change".
#[test]
fn drift_converts_units_before_comparing() {
    let inch = examples::ge_a4();
    let mut mm = inch.clone();
    mm.units = Units {
        length: LengthUnit::Mm,
        angle: kinecal::units::AngleUnit::Rad,
    };
    let dir = tempfile::tempdir().unwrap();
    let db = Database::open(dir.path().join("h.sqlite")).unwrap();
    let (r_in, r_mm) = (calibrate(&inch, 7), calibrate(&mm, 7));
    assert_eq!(
        (r_mm.length_unit.as_str(), r_mm.angle_unit.as_str()),
        ("mm", "rad")
    );
    db.add("A4", Some(1_790_000_000), &r_in, "inches").unwrap();
    db.add("A4", Some(1_792_000_000), &r_mm, "millimetres")
        .unwrap();
    let history = db.calibrations(Some("A4")).unwrap();
    let r = drift(&history, &DriftOptions::default()).unwrap();
    assert_eq!(
        (r.length_unit.as_str(), r.angle_unit.as_str()),
        ("in", "deg")
    );
    assert!(r.quantities.len() > 10);
    assert!(r.left_out.is_empty(), "{:?}", r.left_out);
    assert!(r.flags.is_empty(), "{:?}", r.flags);
    for q in &r.quantities {
        assert!(
            q.change.abs() <= 1e-6 * (1.0 + q.baseline.abs()),
            "{}: {} {} -> {} {}",
            q.key,
            q.baseline,
            q.unit,
            q.latest,
            q.unit
        );
        assert!(
            ["in", "deg", "in/unit", "deg/unit"].contains(&q.unit.as_str()),
            "{}",
            q.unit
        );
    }
    let link1x = r.quantities.iter().find(|q| q.key == "link1.x").unwrap();
    assert!((link1x.latest - 15.08).abs() < 0.01, "{}", link1x.latest);
    // The other way round: millimetres first.
    let db2 = Database::open(dir.path().join("h2.sqlite")).unwrap();
    db2.add("A4", Some(1_790_000_000), &r_mm, "").unwrap();
    db2.add("A4", Some(1_792_000_000), &r_in, "").unwrap();
    let r = drift(
        &db2.calibrations(Some("A4")).unwrap(),
        &DriftOptions::default(),
    )
    .unwrap();
    assert!(r.flags.is_empty() && r.length_unit == "mm");
    let link1x = r.quantities.iter().find(|q| q.key == "link1.x").unwrap();
    assert!((link1x.latest - 15.08 * 25.4).abs() < 0.1 && link1x.unit == "mm");
    let s = kinecal_history::samples(&db2.calibrations(Some("A4")).unwrap(), "link1.x").unwrap();
    assert_eq!(s.len(), 2);
    assert!((s[0].value - s[1].value).abs() < 1e-6 * s[0].value);
}

#[test]
fn drift_threshold_must_be_positive_and_finite() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("h.sqlite");
    history(&path, 2);
    let h = Database::open(&path).unwrap().calibrations(None).unwrap();
    for sigma in [f64::INFINITY, f64::NAN, 0.0, -1.0, f64::NEG_INFINITY] {
        let e = drift(
            &h,
            &DriftOptions {
                sigma,
                ..Default::default()
            },
        )
        .unwrap_err();
        assert!(matches!(e, Error::InvalidSigma { .. }), "{sigma}: {e}");
        assert!(e.to_string().contains("positive, finite"), "{e}");
    }
}

#[test]
fn drift_says_what_it_left_out() {
    let dir = tempfile::tempdir().unwrap();
    let db = Database::open(dir.path().join("h.sqlite")).unwrap();
    let first = report();
    let mut second = calibrate(&examples::ge_a4(), 2);
    let p = second
        .parameters
        .iter_mut()
        .find(|p| p.name == "link1.x")
        .unwrap();
    assert_eq!(p.determined, Some(true));
    p.determined = Some(false);
    p.sigma = None;
    let q = second
        .parameters
        .iter_mut()
        .find(|p| p.name == "link1.y")
        .unwrap();
    q.estimated_flag = false;
    q.determined = None;
    q.sigma = None;
    db.add("R", Some(1_790_000_000), &first, "").unwrap();
    db.add("R", Some(1_792_000_000), &second, "").unwrap();
    let history = db.calibrations(Some("R")).unwrap();
    // A parameter both runs determine, for a tolerance written as an unquoted dotted key.
    let both = drift(&history, &DriftOptions::default()).unwrap();
    let tracked = &both
        .quantities
        .iter()
        .find(|q| q.key.starts_with("link") && !q.key.contains(' '))
        .expect("a link parameter is tracked")
        .key;
    let tol = Tolerances::parse_toml(
        &format!("[tolerances]\n{tracked} = 0.5\nlink1.x = 0.1\nlink9.x = 0.1\np99 = 0.2\n"),
        "tol.toml",
    )
    .unwrap();
    assert_eq!(
        tol.keys().collect::<Vec<_>>(),
        [tracked.as_str(), "link1.x", "link9.x", "p99"]
    );
    let r = drift(
        &history,
        &DriftOptions {
            tolerances: tol,
            ..Default::default()
        },
    )
    .unwrap();
    let reason = |key: &str| {
        r.left_out
            .iter()
            .find(|q| q.key == key)
            .map(|q| q.reason.clone())
            .unwrap_or_else(|| panic!("{key} not said: {:?}", r.left_out))
    };
    assert_eq!(
        reason("link1.x"),
        "not determined by the data of the latest run (calibration 2)"
    );
    assert_eq!(
        reason("link1.y"),
        "not estimated by the latest run (calibration 2)"
    );
    assert_eq!(r.left_out.len(), 2, "{:?}", r.left_out);
    let unused: Vec<(&str, &str)> = r
        .unused_tolerances
        .iter()
        .map(|t| (t.key.as_str(), t.reason.as_str()))
        .collect();
    assert_eq!(unused.len(), 3, "{unused:?}");
    assert!(unused[0].0 == "link1.x" && unused[0].1.contains("left out"));
    assert!(unused[1].0 == "link9.x" && unused[1].1.contains("matches no tracked quantity"));
    assert_eq!(unused[2].0, "p99");
    let q = r.quantities.iter().find(|q| q.key == *tracked).unwrap();
    assert_eq!(q.tolerance, Some(0.5));
}

#[test]
fn tolerance_files_accept_dotted_keys_and_refuse_ambiguity() {
    let t = Tolerances::parse_toml(
        "link1.x = 0.001\n\"link2.y\" = 2\n\"p14 + p20\" = 0.5\nsite.tcp.x = 0.3\n[joint3]\noffset = 0.01\n",
        "t.toml",
    )
    .unwrap();
    assert_eq!(
        t.keys().collect::<Vec<_>>(),
        [
            "link1.x",
            "link2.y",
            "p14 + p20",
            "site.tcp.x",
            "joint3.offset"
        ]
    );
    for (text, words) in [
        ("link1.x = 1\n\"link1.x\" = 2\n", "given twice"),
        ("link1.x = \"a\"\n", "`link1.x`: expected a number"),
        ("link1.x = inf\n", "positive"),
        (
            "p1 = 1\n[tolerances]\np2 = 1\n",
            "outside the [tolerances] table",
        ),
    ] {
        let e = Tolerances::parse_toml(text, "t.toml")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("t.toml: ") && e.contains(words),
            "{text}: {e}"
        );
    }
}

/// A history of one calibration, or a baseline that is the latest calibration, has nothing to
/// compare: no table of zero changes that "flags nothing", but the reason. Two calibrations
/// compare as before.
#[test]
fn drift_of_the_latest_against_itself_says_there_is_nothing_to_compare() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("h.sqlite");
    history(&path, 1);
    let one = Database::open(&path).unwrap().calibrations(None).unwrap();
    let opts = DriftOptions {
        tolerances: Tolerances::from_entries(vec![("link1.x".into(), 0.01)]),
        ..Default::default()
    };
    let r = drift(&one, &opts).unwrap();
    let why = r.nothing_to_compare.as_deref().expect("nothing to compare");
    assert!(why.contains("one calibration of robot `R1`"), "{why}");
    assert!(r.quantities.is_empty() && r.flags.is_empty() && r.left_out.is_empty());
    // A tolerance is not "unused" where nothing was compared.
    assert!(r.unused_tolerances.is_empty(), "{:?}", r.unused_tolerances);
    let db = Database::open(&path).unwrap();
    db.add("R1", Some(1_795_000_000), &report(), "later")
        .unwrap();
    let two = db.calibrations(None).unwrap();
    assert_eq!(two.len(), 2);
    let latest = two.last().unwrap().id;
    let r = drift(
        &two,
        &DriftOptions {
            baseline: Baseline::Id(latest),
            ..Default::default()
        },
    )
    .unwrap();
    let why = r.nothing_to_compare.as_deref().expect("nothing to compare");
    assert!(
        why.contains("the baseline is the latest calibration itself"),
        "{why}"
    );
    assert!(r.quantities.is_empty());
    let r = drift(&two, &DriftOptions::default()).unwrap();
    assert!(r.nothing_to_compare.is_none() && !r.quantities.is_empty());
}

/// A tolerance file naming one quantity twice, by its parameter's id and by its name, was
/// resolved by line order (the first line won): refused, naming both keys and their lines,
/// by `drift` and by the fleet.
#[test]
fn a_tolerance_file_naming_a_parameter_by_id_and_by_name_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("h.sqlite");
    history(&path, 2);
    let db = Database::open(&path).unwrap();
    let two = db.calibrations(None).unwrap();
    for text in [
        "p1 = 0.0001\n# link 1\nlink1.x = 1\n",
        "[tolerances]\nlink1.x = 1\n\"p1\" = 0.0001\n",
    ] {
        let tolerances = Tolerances::parse_toml(text, "t.toml").unwrap();
        let opts = DriftOptions {
            tolerances,
            ..Default::default()
        };
        let e = drift(&two, &opts).unwrap_err();
        assert!(matches!(e, Error::Tolerance { .. }), "{e}");
        let e = e.to_string();
        let (first, second) = if text.starts_with("p1") {
            ("`p1` (line 1)", "`link1.x` (line 3)")
        } else {
            ("`link1.x` (line 2)", "`p1` (line 3)")
        };
        assert!(
            e.starts_with("t.toml: ")
                && e.contains(&format!(
                    "tolerances {first} and {second} name the same quantity"
                ))
                && e.contains("parameter p1 is link1.x"),
            "{e}"
        );
        let f = kinecal_history::fleet(
            &two,
            &[],
            &kinecal_history::FleetOptions {
                drift: opts,
                now: 1_800_000_000,
                horizon: 86_400,
            },
        )
        .unwrap_err()
        .to_string();
        assert_eq!(f, e);
    }
    // Each named once: accepted.
    let opts = DriftOptions {
        tolerances: Tolerances::parse_toml("p1 = 0.0001\nlink1.y = 1\n", "t.toml").unwrap(),
        ..Default::default()
    };
    drift(&two, &opts).unwrap();
}
