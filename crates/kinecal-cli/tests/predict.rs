//! `kinecal predict` as a user runs it: the table it writes is the library's prediction, the
//! accuracy map is drawn, and bad input is refused with the file (and line) named, exit 1.

use std::path::Path;

mod common;

use common::{argv, run};

/// A calibrated GE A4 (30 poses) with its report, in `dir`.
fn calibrated(dir: &Path) {
    for args in [
        &argv(
            "simulate --robot ge-a4 --postures 30 --seed 7
             --perturb p1=+0.05,p14=-0.02,joint2.offset=-0.5 --noise length=0.0005,angle=0.005
             --out data.csv",
        )[..],
        &argv(
            "calibrate --robot ge-a4 --data data.csv --estimate p1,p2,p8,p14,offsets,slopes
             --weights length=0.0005,angle=0.005 --out cal.toml --report report.json --predict",
        ),
        &argv("simulate --robot ge-a4 --postures 12 --seed 9 --out some.csv"),
    ] {
        let (code, _, e) = run(dir, args);
        assert_eq!(code, 0, "{args:?}: {e}");
    }
}

/// The calibrated robot and its report, as [`calibrated`] wrote them in `dir`.
fn read_back(dir: &Path) -> (kinecal::Robot, kinecal::report::CalibrationReport) {
    let robot = kinecal::model::robot_file::parse_robot_toml(
        &std::fs::read_to_string(dir.join("cal.toml")).unwrap(),
        "cal.toml",
    )
    .unwrap();
    let report = kinecal::report::CalibrationReport::from_json(
        &std::fs::read_to_string(dir.join("report.json")).unwrap(),
    )
    .unwrap();
    (robot, report)
}

#[test]
fn the_table_is_the_library_prediction_and_the_map_is_drawn() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    calibrated(d);
    let (code, _, e) = run(
        d,
        &argv(
            "predict --robot cal.toml --report report.json --postures some.csv --out pred.csv
             --html map.html",
        ),
    );
    assert_eq!(code, 0, "{e}");
    assert!(e.contains("predicted 12 postures of GE A4 (ee)"), "{e}");
    common::check_reports(d);
    // The library's prediction, posture by posture, in the file's units.
    let (robot, report) = read_back(d);
    let pr = report.prediction.as_ref().unwrap();
    let p = kinecal::predict::from_report(&robot, pr).unwrap();
    let mut s = p.scratch();
    let postures = kinecal::files::parse_postures(
        &std::fs::read_to_string(d.join("some.csv")).unwrap(),
        "some.csv",
        &robot,
    )
    .unwrap();
    let table = std::fs::read_to_string(d.join("pred.csv")).unwrap();
    let mut lines = table.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert_eq!(header.len(), 1 + 4 + 4 + 4 + 4);
    let col = |h: &str| header.iter().position(|x| *x == h).unwrap();
    for (line, posture) in lines.zip(&postures) {
        let f: Vec<&str> = line.split(',').collect();
        let v = |h: &str| f[col(h)].parse::<f64>().unwrap();
        let q = p.predict(&posture.readings, kinecal::Target::EndEffector, &mut s);
        let inch = 0.0254;
        assert!((v("position_bound95") - q.position_error.bound / inch).abs() < 1e-12);
        assert!((v("x") - q.position.x / inch).abs() < 1e-9);
        assert!(v("position_bound95") >= v("position_bound95_parameters"));
        assert!(v("attitude_bound95").is_finite() && v("distance") >= 0.0);
    }
    let page = std::fs::read_to_string(d.join("map.html")).unwrap();
    assert!(page.contains("Accuracy map") && page.matches("<svg").count() >= 1 + 4 + 4);
    assert!(!page.contains("NaN") && !page.contains("inf"));
}

#[test]
fn bad_input_is_refused_with_the_file_named() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    calibrated(d);
    let base = ["predict", "--robot", "cal.toml", "--report", "report.json"];
    let with = |extra: &[&str]| -> Vec<String> {
        base.iter().chain(extra).map(|s| s.to_string()).collect()
    };
    let err = |args: Vec<String>| {
        let a: Vec<&str> = args.iter().map(String::as_str).collect();
        let (code, _, e) = run(d, &a);
        assert_eq!(code, 1, "{a:?}: {e}");
        e
    };
    // Not the calibrated robot of the report.
    let e = err(vec![
        "predict".into(),
        "--robot".into(),
        "ge-a4".into(),
        "--report".into(),
        "report.json".into(),
        "--sample".into(),
        "5".into(),
    ]);
    assert!(
        e.contains("report.json: ") && e.contains("is not the calibrated robot of this report"),
        "{e}"
    );
    // A report that is not one.
    std::fs::write(d.join("bad.json"), "{\"robot\": 3").unwrap();
    let e = err(vec![
        "predict".into(),
        "--robot".into(),
        "cal.toml".into(),
        "--report".into(),
        "bad.json".into(),
        "--sample".into(),
        "5".into(),
    ]);
    assert!(e.contains("bad.json: not a calibration report"), "{e}");
    // A report without a prediction (8 postures are too few).
    let (code, _, e) = run(
        d,
        &argv("simulate --robot ge-a4 --postures 8 --seed 3 --out few.csv"),
    );
    assert_eq!(code, 0, "{e}");
    let (code, _, e) = run(
        d,
        &argv(
            "calibrate --robot ge-a4 --data few.csv --estimate p1,offsets --out few.toml
             --report few.json --predict",
        ),
    );
    assert_eq!(code, 0, "{e}");
    let e = err(vec![
        "predict".into(),
        "--robot".into(),
        "few.toml".into(),
        "--report".into(),
        "few.json".into(),
        "--sample".into(),
        "5".into(),
    ]);
    assert!(e.contains("few.json: the report has no prediction"), "{e}");
    // A posture whose reading is not a number: its file and line.
    std::fs::write(
        d.join("p.csv"),
        "posture,v1,v2,v3,v4\n1,0,0,0,0\n2,0,nan,0,0\n",
    )
    .unwrap();
    let e = err(with(&["--postures", "p.csv"]));
    assert!(e.contains("p.csv:3"), "{e}");
    // An unknown target, a sample of nothing.
    let e = err(with(&["--sample", "3", "--target", "smr9"]));
    assert!(e.contains("--target: unknown site `smr9`"), "{e}");
    let e = err(with(&["--sample", "0"]));
    assert!(e.contains("--sample: expected between 1 and"), "{e}");
    // Neither postures nor a sample nor targets: refused, naming the choice.
    let a: Vec<&str> = base.to_vec();
    let (code, _, e) = run(d, &a);
    assert_eq!(code, 1);
    assert!(e.contains("--postures: give one of postures"), "{e}");
    // A report edited into nonsense (a negative model error) is refused, not predicted from.
    let text = std::fs::read_to_string(d.join("report.json")).unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["prediction"]["position"]["c"] = serde_json::json!(-1.0);
    std::fs::write(d.join("edited.json"), v.to_string()).unwrap();
    let e = err(vec![
        "predict".into(),
        "--robot".into(),
        "cal.toml".into(),
        "--report".into(),
        "edited.json".into(),
        "--sample".into(),
        "5".into(),
    ]);
    assert!(
        e.contains(
            "edited.json: not a calibration report: prediction.position.c: expected at least 0"
        ),
        "{e}"
    );
}

/// The predictions table writes its numbers as `kinecal fk` writes the same ones (one shared
/// writer, `kinecal::units::number`): a reading given as `-0` is `0` in both, and the readings
/// and the position of each posture are the same text. Before, predict wrote `-0` where fk
/// wrote `0`.
#[test]
fn the_table_writes_numbers_as_fk_does() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    calibrated(d);
    std::fs::write(
        d.join("p.csv"),
        "posture,v1,v2,v3,v4\nzero,0,0,0,0\nminus,-0,-0.0,0,-0\nsome,-6.883,13.301,4.122,-28.645\n",
    )
    .unwrap();
    let (code, pred, e) = run(
        d,
        &argv("predict --robot cal.toml --report report.json --postures p.csv --out -"),
    );
    assert_eq!(code, 0, "{e}");
    let (code, fk, e) = run(d, &argv("fk --robot cal.toml --postures p.csv"));
    assert_eq!(code, 0, "{e}");
    // The fields of `columns` of each row, by posture.
    let fields = |table: &str, columns: &[&str]| -> Vec<(String, Vec<String>)> {
        let mut lines = table.lines();
        let header: Vec<&str> = lines.next().unwrap().split(',').collect();
        lines
            .map(|l| {
                let f: Vec<&str> = l.split(',').collect();
                let at = |c: &str| f[header.iter().position(|h| h == &c).unwrap()].to_string();
                (at("posture"), columns.iter().map(|c| at(c)).collect())
            })
            .collect()
    };
    let columns = ["v1", "v2", "v3", "v4", "x", "y", "z"];
    let (p, f) = (fields(&pred, &columns), fields(&fk, &columns));
    assert_eq!(p.len(), 3, "{pred}");
    assert_eq!(p, f, "predict:\n{pred}\nfk:\n{fk}");
    assert_eq!(p[1].1[..4], ["0", "0", "0", "0"], "{pred}");
    for line in pred.lines() {
        assert!(!line.split(',').any(|v| v == "-0"), "{line}");
    }
}

/// A report is checked before it is believed (issue 38): every reader of a report's JSON
/// (`report --from`, `predict`) refuses a tampered one, naming the file and the field by its
/// JSON path, exit 1, at once. Before, a covariance times 1e300 gave NaN bounds, negative
/// variances a parameter part of 0, map values of 1e308 inf and NaN coordinates in the SVG,
/// bin edges one short a panic, a sigma near 1e308 a `report --from` that ran for ever and a
/// lever of 1e308 a panic in `predict`.
#[test]
fn a_report_that_makes_no_sense_is_refused_by_its_field() {
    use serde_json::{json, Value};
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    calibrated(d);
    // The same calibration with its accuracy map (--predict with an HTML report asks for it).
    let (code, _, e) = run(
        d,
        &argv(
            "calibrate --robot ge-a4 --data data.csv --estimate p1,p2,p8,p14,offsets,slopes
             --weights length=0.0005,angle=0.005 --out cal.toml --report report.json
             --html page.html --predict",
        ),
    );
    assert_eq!(code, 0, "{e}");
    let text = std::fs::read_to_string(d.join("report.json")).unwrap();
    let good: Value = serde_json::from_str(&text).unwrap();
    let (code, _, e) = run(d, &argv("report --from report.json --out again.html"));
    assert_eq!(code, 0, "{e}");
    type Edit = fn(&mut Value);
    let cases: [(&str, Edit, &str); 10] = [
        (
            "cov",
            |v| {
                for row in v["prediction"]["covariance"].as_array_mut().unwrap() {
                    for x in row.as_array_mut().unwrap() {
                        *x = json!(x.as_f64().unwrap() * 1e300);
                    }
                }
            },
            "prediction.covariance[0][0]: ",
        ),
        (
            "negative",
            |v| {
                let c = v["prediction"]["covariance"].as_array_mut().unwrap();
                for (k, row) in c.iter_mut().enumerate() {
                    let x = row[k].as_f64().unwrap();
                    row[k] = json!(-x);
                }
            },
            "prediction.covariance[0][0]: expected a variance of at least 0",
        ),
        (
            "asymmetric",
            |v| {
                let x = v["prediction"]["covariance"][1][0].as_f64().unwrap();
                v["prediction"]["covariance"][1][0] = json!(3.0 * x + 1e-9);
            },
            "prediction.covariance[1][0]: ",
        ),
        (
            "map",
            |v| {
                for x in v["prediction"]["map"]["slices"][0]["values"]
                    .as_array_mut()
                    .unwrap()
                {
                    if !x.is_null() {
                        *x = json!(1e308);
                    }
                }
            },
            "prediction.map.slices[0].values[",
        ),
        (
            "edges",
            |v| {
                v["prediction"]["map"]["joints"][0]["edges"]
                    .as_array_mut()
                    .unwrap()
                    .pop();
            },
            "prediction.map.joints[0].edges: 24 edges for 24 bins",
        ),
        (
            "sigma",
            |v| v["parameters"][0]["sigma"] = json!(1e307),
            "parameters[0].sigma: 1e307 is beyond 1e100 in magnitude",
        ),
        (
            "spread",
            |v| v["parameters"][0]["sigma"] = json!(1e40),
            "parameters[0].sigma: expected at least 0 and at most 1e12, found 1e40",
        ),
        (
            "lever",
            |v| v["prediction"]["levers"][1] = json!(1e50),
            "prediction.levers[1]: expected a lever (length unit per reading unit) of at least \
             0 and at most 1e12, found 1e50",
        ),
        (
            "ids",
            |v| {
                let id = v["parameters"][0]["id"].clone();
                v["parameters"][1]["id"] = id;
            },
            "parameters[1].id: `p1` again",
        ),
        (
            "unknown",
            |v| v["prediction"]["estimated"][0] = json!("p999"),
            "prediction.estimated[0]: `p999` is not one of the report's parameters",
        ),
    ];
    for (name, edit, words) in cases {
        let mut v = good.clone();
        edit(&mut v);
        let file = format!("{name}.json");
        std::fs::write(d.join(&file), v.to_string()).unwrap();
        let page = format!("{name}.html");
        for args in [
            vec!["report", "--from", &file, "--out", &page],
            vec![
                "predict", "--robot", "cal.toml", "--report", &file, "--sample", "5",
            ],
        ] {
            let start = std::time::Instant::now();
            let (code, _, e) = run(d, &args);
            assert_eq!(code, 1, "{args:?}: {e}");
            assert!(
                e.contains(&format!("{file}: not a")) && e.contains(words),
                "{args:?}: {e}"
            );
            assert!(start.elapsed().as_secs() < 10, "{args:?}");
        }
        assert!(!d.join(&page).exists(), "{name}");
    }
}

/// Cartesian targets: each reached by the calibrated robot's inverse kinematics, then predicted;
/// where the calibrated model puts the tool at the readings found is the target, and the
/// prediction is the library's at those readings. A target out of reach names its line.
#[test]
fn cartesian_targets_are_reached_then_predicted() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    calibrated(d);
    let (code, table, e) = run(
        d,
        &argv("predict --robot cal.toml --report report.json --postures some.csv"),
    );
    assert_eq!(code, 0, "{e}");
    // The positions the calibrated model gives at the 12 postures, as targets.
    let mut lines = table.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |h: &str| header.iter().position(|x| *x == h).unwrap();
    let mut targets = String::from("target,x,y,z\n");
    let mut goals = Vec::new();
    for (k, line) in lines.enumerate() {
        let f: Vec<f64> = line
            .split(',')
            .skip(1)
            .map(|v| v.parse().unwrap())
            .collect();
        let xyz = [f[col("x") - 1], f[col("y") - 1], f[col("z") - 1]];
        targets += &format!("T{},{},{},{}\n", k + 1, xyz[0], xyz[1], xyz[2]);
        goals.push(xyz);
    }
    std::fs::write(d.join("targets.csv"), &targets).unwrap();
    let (code, out, e) = run(
        d,
        &argv("predict --robot cal.toml --report report.json --targets targets.csv"),
    );
    assert_eq!(code, 0, "{e}");
    assert!(e.contains("predicted 12 postures of GE A4 (ee)"), "{e}");
    let (robot, report) = read_back(d);
    let p = kinecal::predict::from_report(&robot, report.prediction.as_ref().unwrap()).unwrap();
    let mut s = p.scratch();
    let inch = 0.0254;
    let mut rows = out.lines();
    rows.next();
    for (k, (line, goal)) in rows.zip(&goals).enumerate() {
        let f: Vec<&str> = line.split(',').collect();
        assert_eq!(f[0], format!("T{}", k + 1));
        let v = |h: &str| f[col(h)].parse::<f64>().unwrap();
        // Reached: the inverse kinematics' tolerance is 1 um.
        for (a, g) in ["x", "y", "z"].iter().zip(goal) {
            assert!((v(a) - g).abs() * inch < 2e-6, "{line}");
        }
        let readings: Vec<f64> = (1..=4).map(|j| v(&format!("v{j}"))).collect();
        let q = p.predict(&readings, kinecal::Target::EndEffector, &mut s);
        assert!((v("position_bound95") - q.position_error.bound / inch).abs() < 1e-12);
    }
    // Out of reach, and a column that is not a target's.
    let g = goals[0];
    std::fs::write(
        d.join("far.csv"),
        format!(
            "target,x,y,z\nnear,{},{},{}\nfar,150,0,0\n",
            g[0], g[1], g[2]
        ),
    )
    .unwrap();
    let (code, _, e) = run(
        d,
        &argv("predict --robot cal.toml --report report.json --targets far.csv"),
    );
    assert_eq!(code, 1, "{e}");
    assert!(
        e.contains("far.csv:3: target `far`: the calibrated robot does not reach it (unreachable"),
        "{e}"
    );
    // Millimetres in an inch file: the unit is named, not "unreachable".
    std::fs::write(d.join("mm.csv"), "target,x,y,z\nA,900,0,0\n").unwrap();
    let (code, _, e) = run(
        d,
        &argv("predict --robot cal.toml --report report.json --targets mm.csv"),
    );
    assert_eq!(code, 1, "{e}");
    assert!(
        e.contains("mm.csv:2: target `A` lies 16.") && e.contains("are the positions in in"),
        "{e}"
    );
    std::fs::write(d.join("odd.csv"), "target,x,y,z,w\nA,1,2,3,4\n").unwrap();
    let (code, _, e) = run(
        d,
        &argv("predict --robot cal.toml --report report.json --targets odd.csv"),
    );
    assert_eq!(code, 1, "{e}");
    assert!(e.contains("odd.csv:1: unknown column `w`"), "{e}");
}

/// A two-arm tree (site `arm1` the left arm's tool, the end effector `arm2` the right's),
/// calibrated with a prediction in `dir` from both arms' positions: `tree.toml`, `cal.toml`,
/// `report.json`.
fn calibrated_tree(dir: &Path) -> kinecal::Robot {
    let robot = kinecal::apps::simulate::random_tree(2, &[4, 4], 11);
    std::fs::write(
        dir.join("tree.toml"),
        kinecal::model::robot_file::write_robot_toml(&robot, None),
    )
    .unwrap();
    for args in [
        &argv(
            "simulate --robot tree.toml --postures 60 --seed 3 --position-only
             --perturb-std length=0.001,angle=0.05 --noise length=0.00005,angle=0 --out data.csv",
        )[..],
        &argv(
            "calibrate --robot tree.toml --data data.csv --estimate identifiable
             --weights length=0.00005,angle=0.001 --out cal.toml --report report.json --predict",
        ),
    ] {
        let (code, _, e) = run(dir, args);
        assert_eq!(code, 0, "{args:?}: {e}");
    }
    robot
}

#[test]
fn a_site_column_predicts_each_row_at_its_site() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let robot = calibrated_tree(d);
    // A mixed postures file: rows of the left arm (`arm1`), the right (`ee` and its name).
    let postures = kinecal::apps::simulate::sample_postures(&robot, 6, 21);
    let sites = ["arm1", "ee", "arm2", "arm1", "arm1", "ee"];
    let mut text = String::from("posture,site");
    for j in 1..=robot.dof() {
        text += &format!(",v{j}");
    }
    text.push('\n');
    for (p, site) in postures.iter().zip(sites) {
        text += &format!("{},{site}", p.label);
        for v in &p.readings {
            text += &format!(",{v}");
        }
        text.push('\n');
    }
    std::fs::write(d.join("mixed.csv"), &text).unwrap();
    let (code, _, e) = run(
        d,
        &argv("predict --robot cal.toml --report report.json --postures mixed.csv --out pred.csv"),
    );
    assert_eq!(code, 0, "{e}");
    // `kinecal fk` of the same postures: every frame of each.
    let mut plain = String::from("posture");
    for j in 1..=robot.dof() {
        plain += &format!(",v{j}");
    }
    plain.push('\n');
    for line in text.lines().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        plain += &format!("{},{}\n", f[0], f[2..].join(","));
    }
    std::fs::write(d.join("plain.csv"), plain).unwrap();
    let (code, _, e) = run(
        d,
        &argv("fk --robot cal.toml --postures plain.csv --out fk.csv"),
    );
    assert_eq!(code, 0, "{e}");
    let fk = std::fs::read_to_string(d.join("fk.csv")).unwrap();
    let fk_header: Vec<&str> = fk.lines().next().unwrap().split(',').collect();
    let fcol = |h: &str| fk_header.iter().position(|x| *x == h).unwrap();
    let cal = kinecal::model::robot_file::parse_robot_toml(
        &std::fs::read_to_string(d.join("cal.toml")).unwrap(),
        "cal.toml",
    )
    .unwrap();
    let report = kinecal::report::CalibrationReport::from_json(
        &std::fs::read_to_string(d.join("report.json")).unwrap(),
    )
    .unwrap();
    let pr = report.prediction.as_ref().unwrap();
    assert_eq!(pr.targets.len(), 2, "a term per arm: {:?}", pr.targets);
    let p = kinecal::predict::from_report(&cal, pr).unwrap();
    let mut s = p.scratch();
    let table = std::fs::read_to_string(d.join("pred.csv")).unwrap();
    let mut lines = table.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert_eq!(&header[..3], &["posture", "site", "v1"], "{header:?}");
    let col = |h: &str| header.iter().position(|x| *x == h).unwrap();
    let mut rows = 0;
    for ((line, posture), site) in lines.zip(&postures).zip(sites) {
        let f: Vec<&str> = line.split(',').collect();
        let v = |h: &str| f[col(h)].parse::<f64>().unwrap();
        let target = kinecal::files::site_target(&cal, site).unwrap();
        // The site written is the target's name (`ee` and `arm2` name one frame).
        let name = if target == kinecal::Target::EndEffector {
            "arm2"
        } else {
            site
        };
        assert_eq!(f[0], posture.label);
        // Where fk puts that frame at that posture (a row per posture and frame).
        let at = fk
            .lines()
            .skip(1)
            .map(|l| l.split(',').collect::<Vec<_>>())
            .find(|g| {
                g[0] == posture.label
                    && (g[fcol("site")] == name
                        || (target == kinecal::Target::EndEffector && g[fcol("site")] == "ee"))
            })
            .unwrap_or_else(|| panic!("fk has no row {} {site}:\n{fk}", posture.label));
        for axis in ["x", "y", "z"] {
            let fkv: f64 = at[fcol(axis)].parse().unwrap();
            assert!(
                (v(axis) - fkv).abs() < 1e-9,
                "{site} {axis}: {} {fkv}",
                v(axis)
            );
        }
        // Its own arm's term.
        let q = p.predict(&posture.readings, target, &mut s);
        assert!((v("position_bound95") - q.position_error.bound).abs() < 1e-12);
        assert!((v("position_model") - q.position_error.model).abs() < 1e-12);
        rows += 1;
    }
    assert_eq!(rows, sites.len());
    // A measurement file (fk's: both arms at each posture) predicts each row at its site.
    let (code, _, e) = run(
        d,
        &argv("predict --robot cal.toml --report report.json --postures fk.csv --out pred_fk.csv"),
    );
    assert_eq!(code, 0, "{e}");
    let pred = std::fs::read_to_string(d.join("pred_fk.csv")).unwrap();
    assert_eq!(pred.lines().count(), fk.lines().count());
    for (a, b) in pred.lines().zip(fk.lines()).skip(1) {
        let (a, b): (Vec<&str>, Vec<&str>) = (a.split(',').collect(), b.split(',').collect());
        assert_eq!(a[..2], b[..2]);
        for axis in ["x", "y", "z"] {
            let (x, y): (f64, f64) = (
                a[col(axis)].parse().unwrap(),
                b[fcol(axis)].parse().unwrap(),
            );
            assert!((x - y).abs() < 1e-9, "{a:?} {b:?}");
        }
    }
    // A site the robot does not have is refused with its line.
    std::fs::write(d.join("bad.csv"), text.replacen(",arm1,", ",arm9,", 1)).unwrap();
    let (code, _, e) = run(
        d,
        &argv("predict --robot cal.toml --report report.json --postures bad.csv --out x.csv"),
    );
    assert_eq!(code, 1, "{e}");
    assert!(
        e.contains("bad.csv:2") && e.contains("unknown site `arm9`"),
        "{e}"
    );
}
