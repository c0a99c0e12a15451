//! Mutation fuzzing of every reader, on stable Rust, in the test suite.
//!
//! Each target starts from real files (the repository's examples, files kinecal writes, and
//! the URDFs in `../shared/data` when present) and feeds its reader mutated copies: flipped and
//! deleted bytes, inserted tokens (`nan`, `inf`, `1e400`, `-1e308`, delimiters, quotes, TOML and
//! XML fragments, invalid UTF-8, a BOM), duplicated lines, truncation, swapped delimiters,
//! blown-up repetition and deep nesting. For every input the reader must:
//!
//! - not panic, and return within 1 s;
//! - when it accepts the input, give only finite numbers (and a robot that validates and reads
//!   back identically from what kinecal writes of it);
//! - when it refuses it, name the file in the message (and a line where the reader has lines).
//!
//! In the normal test run each target gets `KINECAL_FUZZ_ITERS` inputs (default 300) from a
//! fixed seed; `KINECAL_FUZZ_SEED=N` draws other inputs (a long run should take a seed no run
//! took before: the same seed repeats the same inputs). The long run (at least 10^6 inputs per
//! target):
//!
//! ```text
//! KINECAL_FUZZ_SEED=7 KINECAL_FUZZ_ITERS=1000000 cargo test --release -p kinecal --test fuzz -- --nocapture
//! ```
//!
//! Inputs that once failed are kept in `tests/fuzz-corpus/` and replayed first.

mod fuzz_driver;
#[path = "common/synthetic_datasets.rs"]
mod synthetic;

use fuzz_driver::{fuzz, repo, Outcome};
use kinecal::files::{
    parse_contacts, parse_distances, parse_measurements, parse_measurements_mapped, parse_postures,
    write_measurements, write_postures, ColumnMap,
};
use kinecal::model::robot_file::{parse_robot_toml, write_robot_toml};
use kinecal::observe::{Dataset, Observation};
use kinecal::units::Units;
use kinecal::{apps::simulate, model::examples, Robot};

/// A robot's every parameter finite, its structure valid, and what kinecal writes of it read
/// back to the same values.
fn check_robot(r: &Robot) -> Result<(), String> {
    r.validate()?;
    if let Some(id) = r.param_ids().find(|&id| !r.get(id).is_finite()) {
        return Err(format!("{} is {}", r.param_name(id), r.get(id)));
    }
    let written = write_robot_toml(r, None);
    let back = parse_robot_toml(&written, "w.toml").map_err(|e| format!("rewrite: {e}"))?;
    // The writer's contract: float noise, below `NOISE` times the file's largest number of the
    // same kind, is written as 0 (an Euler angle of -1.8e-12 rad at gimbal lock, next to angles
    // of pi); everything else reads back to 1e-12 of itself.
    let scale = |q: kinecal::units::Quantity| {
        r.param_ids()
            .filter(|&i| r.param_quantity(i) == q)
            .fold(0.0f64, |m, i| m.max(r.get_user(i).abs()))
    };
    for id in r.param_ids() {
        let (a, b) = (r.get_user(id), back.get_user(id));
        let noise = kinecal::units::number::NOISE * scale(r.param_quantity(id));
        if (a - b).abs() > (1e-12 * a.abs().max(1.0)).max(noise) {
            return Err(format!("{} reads back {b} for {a}", r.param_name(id)));
        }
    }
    Ok(())
}

fn check_data(d: &Dataset) -> Result<(), String> {
    for p in &d.postures {
        if p.readings.iter().any(|v| !v.is_finite()) {
            return Err(format!("posture {} has a non-finite reading", p.label));
        }
        if let Some(load) = &p.payload {
            if !(load.mass.is_finite()
                && load.mass >= 0.0
                && load.com.iter().all(|v| v.is_finite()))
            {
                return Err(format!("posture {} has a payload {load:?}", p.label));
            }
        }
    }
    for o in &d.observations {
        let finite = match o {
            Observation::Pose(p) => p
                .position
                .iter()
                .chain(p.euler.iter())
                .all(|v| v.is_finite()),
            Observation::Position(p) => p.position.iter().all(|v| v.is_finite()),
            Observation::Distance(x) => x.distance.is_finite(),
            Observation::Contact(c) => c.gap.is_finite(),
            Observation::Pixel(p) => {
                p.uv.iter().all(|v| v.is_finite()) && p.sigma.is_none_or(|s| s.is_finite())
            }
        };
        if !finite {
            return Err(format!(
                "the observation of line {} is not finite",
                o.line()
            ));
        }
    }
    Ok(())
}

fn outcome<T>(r: kinecal::Result<T>, check: impl Fn(&T) -> Result<(), String>) -> Outcome {
    match r {
        Ok(v) => Outcome::Accepted(check(&v)),
        Err(e) => Outcome::Refused(e.to_string()),
    }
}

/// The file is read as kinecal reads files: bytes, then UTF-8 (named by line when invalid).
fn read_text(b: &[u8], file: &str) -> Result<String, Outcome> {
    match kinecal::source::Source::from_bytes(file, b.to_vec()) {
        Ok(s) => Ok(s.text),
        Err(e) => Err(Outcome::Refused(e.to_string())),
    }
}

fn robot_seeds() -> Vec<Vec<u8>> {
    let mut seeds = vec![examples::GE_A4_TOML.as_bytes().to_vec()];
    for f in [
        "examples/no-tracker/a4_table.toml",
        "examples/layouts/a4_markers.toml",
    ] {
        seeds.push(std::fs::read(repo().join(f)).unwrap());
    }
    let mut r = simulate::random_robot(&[kinecal::model::robot::JointKind::Revolute; 6], 3);
    r.joints[2].coupling = Some(kinecal::model::robot::Coupling {
        joint: 1,
        factor: 1.0,
    });
    seeds.push(write_robot_toml(&r, None).into_bytes());
    // A tree: named joints, parents, a named end effector and a site on the other branch.
    seeds.push(write_robot_toml(&simulate::random_tree(2, &[3, 2], 5), None).into_bytes());
    seeds.push(write_robot_toml(&a4_with_camera(), None).into_bytes());
    seeds
}

/// The GE A4 with a camera on its end effector and a board beside it (issue 40).
fn a4_with_camera() -> Robot {
    use kinecal::model::camera::{Board, Camera, Mount};
    let mut r = examples::ge_a4();
    r.cameras.push(Camera {
        name: "wrist".into(),
        mount: Mount::EndEffector,
        pose: kinecal::model::robot::Link {
            z: 0.05,
            alpha: 0.1,
            ..Default::default()
        },
        fx: 600.0,
        fy: 600.0,
        cx: 320.0,
        cy: 240.0,
        distortion: [-0.2, 0.05, 0.001, -0.0005, 0.0],
        width: 640,
        height: 480,
    });
    r.boards.push(Board {
        name: "board".into(),
        mount: Mount::Base,
        pose: kinecal::model::robot::Link {
            x: 0.5,
            ..Default::default()
        },
        cols: 9,
        rows: 6,
        spacing: 0.025,
    });
    r
}

#[test]
fn pixel_files() {
    let robot = a4_with_camera();
    let seeds = vec![
        b"posture,camera,point,v1,v2,v3,v4,u,v,sigma_px\n\
          1,wrist,board:0,1,2,3,4,320.5,240.25,0.3\n1,wrist,board:53,1,2,3,4,10,20,\n\
          2,wrist,board:17,0.5,-2,3,1e-3,600,470.125,\n"
            .to_vec(),
        b"posture;point;v1;v2;v3;v4;u;v\n1;board:3;1;2;3;4;320,5;240,25\n".to_vec(),
    ];
    fuzz("pixels", "f.csv", &seeds, &|b| {
        let t = match read_text(b, "f.csv") {
            Ok(t) => t,
            Err(o) => return o,
        };
        outcome(
            kinecal::files::parse_pixels(&t, "f.csv", &robot),
            check_data,
        )
    });
}

#[test]
fn robot_files() {
    fuzz("robot_toml", "f.toml", &robot_seeds(), &|b| {
        let t = match read_text(b, "f.toml") {
            Ok(t) => t,
            Err(o) => return o,
        };
        outcome(parse_robot_toml(&t, "f.toml"), check_robot)
    });
}

fn a4_with_sites() -> Robot {
    let text = std::fs::read_to_string(repo().join("examples/layouts/a4_markers.toml")).unwrap();
    parse_robot_toml(&text, "a4_markers.toml").unwrap()
}

#[test]
fn measurement_and_posture_files() {
    let robot = examples::ge_a4();
    let postures = simulate::sample_postures(&robot, 6, 1);
    let mut data = simulate::measure(&robot, &postures, false);
    simulate::add_noise(&mut data, 1e-4, 1e-4, 1);
    let mut seeds = vec![
        write_measurements(&robot, &data).into_bytes(),
        write_measurements(&robot, &simulate::measure(&robot, &postures, true)).into_bytes(),
        b"posture,site,v1,v2,v3,v4,x,y,z,alpha,beta,gamma,sigma_position,sigma_angle\n\
          1,ee,1,2,3,4,5,6,7,,,,0.001,\n2,ee,1,2,3,4,5,6,7,1,2,3,,0.01\n"
            .to_vec(),
    ];
    // Payload columns (what the tool carried at each posture).
    seeds.push(
        b"posture,site,v1,v2,v3,v4,x,y,z,payload_mass,payload_cx,payload_cy,payload_cz\n\
          1,ee,1,2,3,4,5,6,7,2.5,0,0,1.5\n2,ee,1,2,3,4,5,6,7,,,,\n1,ee,1,2,3,4,5,6,7,2.5,0,0,1.5\n"
            .to_vec(),
    );
    seeds.push(
        b"# exported\n\"posture\";\"v1\";\"v2\";\"v3\";\"v4\";\"x\";\"y\";\"z\"\r\n1;1,5;2;3;4;5;6;7\r\n"
            .to_vec(),
    );
    fuzz("measurements", "f.csv", &seeds, &|b| {
        let t = match read_text(b, "f.csv") {
            Ok(t) => t,
            Err(o) => return o,
        };
        outcome(parse_measurements(&t, "f.csv", &robot), check_data)
    });
    // A tree's rows, readings headed by the joints' names in another order, tools by name.
    let tree = simulate::random_tree(1, &[2, 2], 9);
    let tree_postures = simulate::sample_postures(&tree, 4, 2);
    let written = write_measurements(&tree, &simulate::measure(&tree, &tree_postures, false));
    let named = written.replacen("v1,v2,v3,v4,v5", "torso1,arm1_1,arm1_2,arm2_1,arm2_2", 1);
    fuzz(
        "tree_measurements",
        "f.csv",
        &[written.into_bytes(), named.into_bytes()],
        &|b| {
            let t = match read_text(b, "f.csv") {
                Ok(t) => t,
                Err(o) => return o,
            };
            outcome(parse_measurements(&t, "f.csv", &tree), check_data)
        },
    );
    let posture_seeds = vec![write_postures(&robot, &postures).into_bytes()];
    fuzz("postures", "f.csv", &posture_seeds, &|b| {
        let t = match read_text(b, "f.csv") {
            Ok(t) => t,
            Err(o) => return o,
        };
        outcome(parse_postures(&t, "f.csv", &robot), |p| {
            check_data(&Dataset::new(p.clone(), Vec::new()))
        })
    });
}

#[test]
fn other_layouts_through_column_mappings() {
    let robot = a4_with_sites();
    let seeds: Vec<Vec<u8>> = [
        "examples/layouts/tracker_export.csv",
        "examples/layouts/figaroh_wide.csv",
    ]
    .iter()
    .map(|f| std::fs::read(repo().join(f)).unwrap())
    .collect();
    let maps = [
        ColumnMap::parse(&["v1=J1,v2=J2,v3=J3,v4=J4,x=X,y=Y,z=Z"], "--columns"),
        ColumnMap::parse(
            &[
                "v1=q1,v2=q2,v3=q3,v4=q4",
                "m1:x=x1,y=y1,z=z1",
                "m2:x=x2,y=y2,z=z2",
            ],
            "--columns",
        ),
    ];
    let maps: Vec<ColumnMap> = maps.into_iter().map(Result::unwrap).collect();
    fuzz("mapped_measurements", "f.csv", &seeds, &|b| {
        let t = match read_text(b, "f.csv") {
            Ok(t) => t,
            Err(o) => return o,
        };
        for m in &maps {
            if let Ok(d) = parse_measurements_mapped(&t, "f.csv", &robot, m) {
                return Outcome::Accepted(check_data(&d));
            }
        }
        outcome(
            parse_measurements_mapped(&t, "f.csv", &robot, &maps[0]),
            check_data,
        )
    });
}

#[test]
fn distance_and_contact_files() {
    let text = std::fs::read_to_string(repo().join("examples/no-tracker/a4_table.toml")).unwrap();
    let robot = parse_robot_toml(&text, "a4_table.toml").unwrap();
    let seed = |f: &str| std::fs::read(repo().join("examples/no-tracker").join(f)).unwrap();
    fuzz("distances", "f.csv", &[seed("ballbar.csv")], &|b| {
        let t = match read_text(b, "f.csv") {
            Ok(t) => t,
            Err(o) => return o,
        };
        outcome(parse_distances(&t, "f.csv", &robot), check_data)
    });
    fuzz("contacts", "f.csv", &[seed("contacts.csv")], &|b| {
        let t = match read_text(b, "f.csv") {
            Ok(t) => t,
            Err(o) => return o,
        };
        outcome(parse_contacts(&t, "f.csv", &robot), check_data)
    });
}

#[test]
fn urdf_files() {
    let shared = repo().join("../shared/data/urdf");
    let mut seeds: Vec<Vec<u8>> = Vec::new();
    for f in [
        "universal_robots/urdf_plain/ur5_robot.urdf",
        "franka_panda/panda.urdf",
        "kuka_iiwa14/iiwa14_mukca.urdf",
    ] {
        if let Ok(b) = std::fs::read(shared.join(f)) {
            seeds.push(b);
        }
    }
    let tree_seed = std::fs::read(repo().join("examples/trees/upper_body.urdf")).unwrap();
    if seeds.is_empty() {
        assert!(
            std::env::var_os("CI").is_none(),
            "../shared is missing on CI"
        );
        seeds.push(
            br#"<?xml version="1.0"?>
<robot name="two">
  <link name="base"/><link name="l1"/><link name="tip"/>
  <!-- <joint name="j1" type="revolute"> commented out -->
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
    <origin xyz="0 0 0.3" rpy="0 0 0"/><axis xyz="0 0 1"/></joint>
  <joint name="j2" type="prismatic"><parent link="l1"/><child link="tip"/>
    <origin xyz="0.2 0 0" rpy="0 1.5707963 0"/><axis xyz="0 0 1"/></joint>
</robot>
"#
            .to_vec(),
        );
    }
    seeds.push(tree_seed);
    fuzz("urdf", "f.urdf", &seeds, &|b| {
        let t = match read_text(b, "f.urdf") {
            Ok(t) => t,
            Err(o) => return o,
        };
        // The chains the seeds are read with (as the tests of real URDFs read them).
        let chains = [
            (Some("base_link"), Some("tool0")),
            (None, Some("ball_link")),
            (Some("panda_link0"), Some("panda_leftfinger")),
        ];
        for (base, tip) in chains {
            if let Ok(u) = kinecal::import::urdf::import_urdf(&t, "f.urdf", base, tip) {
                return Outcome::Accepted(check_robot(&u.robot));
            }
        }
        let tips = ["left_marker", "right_marker"];
        if let Ok(u) = kinecal::import::urdf::import_urdf_tree(&t, "f.urdf", None, &tips) {
            return Outcome::Accepted(check_robot(&u.robot));
        }
        outcome(
            kinecal::import::urdf::import_urdf(&t, "f.urdf", None, None),
            |u| check_robot(&u.robot),
        )
    });
}

#[test]
fn dh_and_poe_files() {
    let dh = b"kind,a,alpha,d,theta\nrevolute,0,90,0.1625,0\nrevolute,-0.425,0,0,0\n\
               revolute,-0.3922,0,0,0\nrevolute,0,90,0.1333,0\nprismatic,0,-90,0.0997,0\n"
        .to_vec();
    let units = Units {
        length: kinecal::units::LengthUnit::M,
        angle: kinecal::units::AngleUnit::Deg,
    };
    fuzz("dh", "f.csv", &[dh], &|b| {
        let t = match read_text(b, "f.csv") {
            Ok(t) => t,
            Err(o) => return o,
        };
        for convention in [
            kinecal::import::dh::Convention::Standard,
            kinecal::import::dh::Convention::Modified,
        ] {
            let r = kinecal::import::dh::import_dh(
                &t,
                "f.csv",
                "dh",
                Some(units.length),
                Some(units.angle),
                Some(convention),
            );
            if let Err(e) = r {
                return Outcome::Refused(e.to_string());
            }
            if let Ok(robot) = &r {
                if let Err(why) = check_robot(robot) {
                    return Outcome::Accepted(Err(why));
                }
            }
        }
        Outcome::Accepted(Ok(()))
    });
    let seed = br#"name = "poe"
length_unit = "mm"
angle_unit = "deg"

[[joints]]
kind = "revolute"
axis = [0, 0, 1]
point = [0, 0, 0]

[[joints]]
kind = "revolute"
axis = [0, 1, 0]
point = [0, 0, 400]
coupling = { joint = 1, factor = 1.0 }

[[joints]]
kind = "prismatic"
axis = [1, 0, 0]
point = [300, 0, 400]
min = -100
max = 100

[tool]
x = 100
"#
    .to_vec();
    // A POE file kinecal's own data set adapter writes, when the data is here.
    let mut seeds = vec![seed];
    if let Some(d) = kinecal::apps::datasets::DATASETS
        .iter()
        .find(|d| d.name == "qkm-hl6")
    {
        if let Ok(c) = (d.convert)(&repo().join("../shared/data/qkm_hl6_faro")) {
            if let Some((_, text)) = c.files.iter().find(|(n, _)| n.ends_with("_poe.toml")) {
                seeds.push(text.clone().into_bytes());
            }
        }
    }
    fuzz("poe", "f.toml", &seeds, &|b| {
        let t = match read_text(b, "f.toml") {
            Ok(t) => t,
            Err(o) => return o,
        };
        outcome(
            kinecal::import::poe::parse_poe_toml(&t, "f.toml"),
            check_robot,
        )
    });
}

/// Universal Robots kinematics files: the description's defaults and the real factory
/// calibrations as seeds.
#[test]
fn ur_kinematics_files() {
    let dir = repo().join("../shared/data/urdf/universal_robots");
    let mut seeds = vec![b"kinematics:\n  shoulder:\n    x: 0\n    y: 0\n    z: 0.15\n    roll: 0\n    pitch: 0\n    yaw: 0\n  hash: calib_1\n".to_vec()];
    for f in [
        "config/ur3e/default_kinematics.yaml",
        "real_factory_calibration_ur3e/ur3e_calibration_1.yaml",
    ] {
        if let Ok(b) = std::fs::read(dir.join(f)) {
            seeds.push(b);
        }
    }
    fuzz("ur", "k.yaml", &seeds, &|b| {
        let t = match read_text(b, "k.yaml") {
            Ok(t) => t,
            Err(o) => return o,
        };
        outcome(
            kinecal::import::ur::import_ur(&t, "k.yaml").map(|i| i.robot),
            check_robot,
        )
    });
}

/// Calibration reports, as `report --from`, `predict`, `export gltf --report` and `history
/// record` read them: a report without a prediction, and one with its prediction and accuracy
/// map. What the reader accepts must be believable: finite parameters, and a prediction that
/// either its robot refuses (naming why) or predicts finite bounds from, with a map whose bins
/// and cells add up.
#[test]
fn report_json() {
    let robot = examples::ge_a4();
    let data = simulate::measure(&robot, &simulate::sample_postures(&robot, 12, 2), false);
    let mut req = kinecal::workflow::Request::new(robot.clone(), data);
    req.selection = kinecal::workflow::Selection::parse("p1,p14,offsets", None, &robot).unwrap();
    let out = kinecal::workflow::run(&req, &mut ()).unwrap();
    let mut seeds = vec![out.report.to_json().into_bytes()];
    let postures = simulate::sample_postures(&robot, 24, 5);
    let mut req =
        kinecal::workflow::Request::new(robot.clone(), simulate::measure(&robot, &postures, false));
    req.selection = kinecal::workflow::Selection::parse("p1,p14,offsets", None, &robot).unwrap();
    req.prediction = kinecal::predict::Level::Map;
    let out = kinecal::workflow::run(&req, &mut ()).unwrap();
    assert!(out
        .report
        .prediction
        .as_ref()
        .is_some_and(|p| p.map.is_some()));
    seeds.push(out.report.to_json().into_bytes());
    let calibrated = out.calibration.calibrated.clone();
    let readings: Vec<&[f64]> = postures
        .iter()
        .take(3)
        .map(|p| p.readings.as_slice())
        .collect();
    // serde_json names no file: the caller adds it, as `kinecal report` does.
    fuzz("report_json", "f.json", &seeds, &|b| {
        let t = match read_text(b, "f.json") {
            Ok(t) => t,
            Err(o) => return o,
        };
        match kinecal::report::CalibrationReport::from_json(&t) {
            Ok(r) => Outcome::Accepted(believable(&r, &calibrated, &readings)),
            Err(e) => Outcome::Refused(format!("f.json: {e}")),
        }
    });
}

/// What a report the reader accepted must hold (see [`report_json`]).
fn believable(
    r: &kinecal::report::CalibrationReport,
    robot: &Robot,
    readings: &[&[f64]],
) -> Result<(), String> {
    if !r
        .parameters
        .iter()
        .all(|p| p.estimated.is_finite() && p.initial.is_finite())
    {
        return Err("a parameter is not finite".into());
    }
    let Some(pr) = &r.prediction else {
        return Ok(());
    };
    if let Some(m) = &pr.map {
        for s in &m.slices {
            if s.nu * s.nv != s.values.len() || s.extent[0] >= s.extent[1] {
                return Err(format!("a slice of {} x {} cells", s.nu, s.nv));
            }
        }
        for j in &m.joints {
            if j.edges.len() != j.median.len() + 1 || j.edges.windows(2).any(|w| w[0] > w[1]) {
                return Err(format!("joint {}'s bins do not add up", j.joint));
            }
        }
    }
    // Its robot may refuse it (another robot's parameters): `predict` says so, with the file.
    let Ok(p) = kinecal::predict::from_report(robot, pr) else {
        return Ok(());
    };
    let mut s = p.scratch();
    for q in readings {
        let b = p
            .predict(q, kinecal::Target::EndEffector, &mut s)
            .position_error;
        if ![b.bound, b.parameters, b.model, b.parameters_bound]
            .iter()
            .all(|v| v.is_finite())
        {
            return Err(format!("a predicted bound is not finite: {b:?}"));
        }
    }
    Ok(())
}

/// The spec reader of every job: a spec file, mutated, is read or refused with the file named;
/// what is read writes back to a spec that reads the same.
#[test]
fn spec_toml() {
    use kinecal::spec::Job;
    let seed = std::fs::read(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/fleet/a4-0042.toml"),
    )
    .unwrap();
    let mut spec = kinecal::spec::CalibrationSpec::default();
    spec.robot = "ge-a4".into();
    spec.observations = vec![kinecal::files::ObservationFile::new("d.csv")];
    spec.validation.folds = Some(3);
    spec.validation.choose = Some(vec!["identifiable".into()]);
    let full = Job::Calibrate(spec);
    let mut seeds = vec![seed, full.to_toml().unwrap().into_bytes()];
    for text in [
        "job = \"analyze\"\nrobot = \"ge-a4\"\nrcond = 1e-9\n[[observations]]\nfile = \"d.csv\"\n[selection]\nestimate = \"all\"\n",
        "job = \"plan\"\nrobot = \"ge-a4\"\nsample = 200\ncount = 5\ncriterion = \"o3\"\n[outputs]\npostures = \"p.csv\"\n",
        "job = \"simulate\"\nrobot = \"ge-a4\"\npostures = 3\nperturb = { p1 = 0.05 }\nnoise = { length = 0.1 }\n",
        "job = \"export\"\nformat = \"dh\"\nrobot = \"ge-a4\"\nconvention = \"modified\"\ntolerance = { length = 1e-6 }\n",
        "job = \"curves\"\ncurve = \"pose\"\nrobot = \"ge-a4\"\nreadings = [1.0, 2.0, 3.0, 4.0]\nsweep = { param = \"p4\", span = 360.0 }\n",
        "job = \"iso9283-plan\"\nrobot = \"ge-a4\"\ncube = [10.0, 0.0, 5.0, 4.0]\n",
    ] {
        seeds.push(text.as_bytes().to_vec());
    }
    fuzz("spec_toml", "job.toml", &seeds, &|b| {
        let t = match read_text(b, "job.toml") {
            Ok(t) => t,
            Err(o) => return o,
        };
        match Job::from_toml(&t, "job.toml") {
            // A number beyond its bound is refused before it is written (and run).
            Ok(job) => match job.to_toml() {
                Err(e) => Outcome::Refused(e.to_string()),
                Ok(text) => Outcome::Accepted(match Job::from_toml(&text, "again") {
                    Ok(again) if again == job => {
                        match Job::from_json(&job.to_json(), "again.json") {
                            Ok(j) if j == job => Ok(()),
                            Ok(_) => Err("as JSON, it reads differently".into()),
                            Err(e) => Err(format!("as JSON, it is refused: {e}")),
                        }
                    }
                    Ok(_) => Err("written back, it reads differently".into()),
                    Err(e) => Err(format!("written back, it is refused: {e}")),
                }),
            },
            Err(e) => Outcome::Refused(e.to_string()),
        }
    });
}

/// What a data set adapter converted: its robot files read back (the robot validated and
/// rewritten identically), its measurement files read with the robot, every number finite.
fn check_converted(c: &kinecal::apps::datasets::Converted) -> Result<(), String> {
    let text = |n: &str| {
        c.files
            .iter()
            .find(|(f, _)| f == n)
            .map(|(_, t)| t.as_str())
            .ok_or(format!("no {n} written"))
    };
    let robot = parse_robot_toml(text(c.suggested.robot)?, c.suggested.robot)
        .map_err(|e| format!("its robot is refused: {e}"))?;
    check_robot(&robot)?;
    for (name, t) in &c.files {
        if name.ends_with("_poe.toml") {
            let poe = kinecal::import::poe::parse_poe_toml(t, name)
                .map_err(|e| format!("its POE file is refused: {e}"))?;
            check_robot(&poe)?;
        } else if name == "temperatures.csv" {
            check_temperatures(t)?;
        } else if name.ends_with("_iso.csv") {
            kinecal::apps::iso9283::read_roles(t, name)
                .map_err(|e| format!("its own {name} is refused: {e}"))?;
        } else if name.ends_with(".csv") {
            let d = parse_measurements(t, name, &robot)
                .map_err(|e| format!("its own {name} is refused: {e}"))?;
            check_data(&d)?;
        }
    }
    Ok(())
}

/// A temperature table an adapter wrote (`posture,session,temperature`): every row three
/// fields, the temperature a finite number.
fn check_temperatures(t: &str) -> Result<(), String> {
    let mut lines = t.lines();
    if lines.next() != Some("posture,session,temperature") {
        return Err("temperatures.csv has another header".into());
    }
    for l in lines {
        let f: Vec<&str> = l.split(',').collect();
        match f[..] {
            [_, _, v] if v.parse::<f64>().is_ok_and(f64::is_finite) => {}
            _ => return Err(format!("temperatures.csv has the row `{l}`")),
        }
    }
    Ok(())
}

/// Every `kinecal dataset` adapter, on a synthetic folder shaped like its data set (see
/// `common/synthetic_datasets.rs`) packed into one byte string: the mutations damage the files
/// (rows cut, fields lost, numbers replaced) and the marks between them (files lost, renamed).
/// A refusal names the folder (`d/...`).
#[test]
fn dataset_folders() {
    // `ipa-ur10`'s folder has 16,811 rows: its own target fuzzes a copy cut to a few rows.
    for adapter in kinecal::apps::datasets::DATASETS
        .iter()
        .filter(|a| a.name != "ipa-ur10")
    {
        let seeds = vec![synthetic::pack(&synthetic::folder(adapter.name))];
        let target = format!("dataset_{}", adapter.name.replace('-', "_"));
        fuzz(&target, "d", &seeds, &|b| {
            let folder = kinecal::apps::datasets::Folder::memory(
                std::path::Path::new("d"),
                synthetic::unpack(b),
            );
            outcome((adapter.read)(&folder), check_converted)
        });
    }
}

/// The `ipa-ur10` adapter on a synthetic copy of the data set cut to a few rows per series
/// (`ipa_ur10::convert_trimmed`: the row counts checked are the copy's), packed into one byte
/// string like the other adapters' folders.
#[test]
fn dataset_ipa_ur10() {
    let seeds = vec![synthetic::pack(&synthetic::ipa(synthetic::IPA_FEW))];
    fuzz("dataset_ipa_ur10", "d", &seeds, &|b| {
        let folder = kinecal::apps::datasets::Folder::memory(
            std::path::Path::new("d"),
            synthetic::unpack(b),
        );
        outcome(
            kinecal::apps::datasets::ipa_ur10::convert_trimmed(&folder, synthetic::IPA_FEW),
            check_converted,
        )
    });
}

/// Property: any random robot (1-7 joints of random kinds, couplings, sites, planes, joint
/// ranges, every unit combination) is written and read back with the same parameters, to 8
/// ulps (the writer rounds to 15 significant digits when that is within 4 ulps of the file
/// value, and the conversions to and from the file's unit round once each); writing what was
/// read gives the same file, byte for byte; and its forward kinematics is finite.
#[test]
fn random_robots_read_back_identically_and_have_finite_kinematics() {
    use kinecal::model::robot::{Coupling, JointKind, Plane};
    use kinecal::units::{AngleUnit, LengthUnit};
    use rand::{RngExt, SeedableRng};
    let n = (fuzz_driver::iterations() / 3).max(50);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(17);
    for k in 0..n {
        let dof = rng.random_range(1..=7);
        let kinds: Vec<JointKind> = (0..dof)
            .map(|_| {
                if rng.random_range(0..4) == 0 {
                    JointKind::Prismatic
                } else {
                    JointKind::Revolute
                }
            })
            .collect();
        let mut r = simulate::random_robot(&kinds, k as u64);
        r.units.length = [LengthUnit::M, LengthUnit::Mm, LengthUnit::In][rng.random_range(0..3)];
        r.units.angle = [AngleUnit::Deg, AngleUnit::Rad][rng.random_range(0..2)];
        if dof >= 2 && rng.random_range(0..2) == 0 {
            r.joints[dof - 1].coupling = Some(Coupling {
                joint: rng.random_range(0..dof - 1),
                factor: rng.random_range(-2.0..2.0),
            });
        }
        if rng.random_range(0..2) == 0 {
            let lo: f64 = rng.random_range(-200.0..0.0);
            r.joints[0].range = Some((lo, lo + rng.random_range(1.0..300.0)));
        }
        if rng.random_range(0..2) == 0 {
            r.sites.push(kinecal::Site {
                name: format!("s{k}"),
                joint: rng.random_range(1..=dof),
                frame: kinecal::Link {
                    x: rng.random_range(-0.3..0.3),
                    y: rng.random_range(-0.3..0.3),
                    z: rng.random_range(-0.3..0.3),
                    alpha: rng.random_range(-3.0..3.0),
                    beta: rng.random_range(-1.5..1.5),
                    gamma: rng.random_range(-3.0..3.0),
                },
            });
        }
        if rng.random_range(0..2) == 0 {
            let n = nalgebra::Vector3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(0.1..1.0),
            );
            r.planes
                .push(Plane::new("p", n, rng.random_range(-1.0..1.0)).unwrap());
        }
        let text = write_robot_toml(&r, None);
        let back = parse_robot_toml(&text, "r.toml").unwrap_or_else(|e| panic!("{e}\n{text}"));
        assert!(r.same_structure(&back), "{text}");
        for id in r.param_ids() {
            let (a, b) = (r.get(id), back.get(id));
            assert!(
                (a - b).abs() <= 8.0 * f64::EPSILON * a.abs().max(f64::MIN_POSITIVE),
                "robot {k}: {} {a} read back as {b}\n{text}",
                r.param_name(id)
            );
        }
        assert_eq!(
            write_robot_toml(&back, None),
            text,
            "robot {k}: not a fixed point"
        );
        for p in simulate::sample_postures(&r, 5, k as u64) {
            let f = kinecal::Chain::new(&r).frame_at(&p.readings, kinecal::Target::EndEffector);
            assert!(f
                .translation
                .iter()
                .chain(f.rotation.iter())
                .all(|v| v.is_finite()));
        }
    }
}

/// ISO 9283 logs (read, figured, written back and read again to the same figures) and roles
/// files: every figure of an accepted log finite (a one-cycle pose has no repeatability: `None`,
/// never NaN), its JSON document free of `null` where a number is due.
#[test]
fn iso9283_logs_and_roles() {
    use kinecal::apps::iso9283::{evaluate, read_log, read_roles, write_log, LogUnits};
    let thirty: String = {
        let mut s = String::from("# length_unit = mm\n# angle_unit = deg\npose,cycle,xc,yc,zc,ac,bc,cc,x,y,z,a,b,c,direction\n");
        for c in 1..=4 {
            for p in 1..=5 {
                s += &format!(
                    "{p},{c},{},{},{},180,0,45,{},{},{},179.9{c},0.0{p},45.{c},+x\n",
                    100 * p,
                    -20 * p,
                    500,
                    100.0 * p as f64 + 0.01 * c as f64,
                    -20.0 * p as f64 - 0.02,
                    500.003
                );
            }
        }
        s
    };
    let seeds = vec![
        thirty.into_bytes(),
        b"# length_unit = m\ntest,pose,cycle,xc,yc,zc,x,y,z,v1,v2\n\"cube 1\",P1,1,0,0,0,0,0,0.001,0.1,0.2\n\"cube 1\",C8,1,1,1,1,1,1.001,1,0.3,0.4\ncube 2,1,1,0,0,0,0,0,-0.001,0.5,0.6\ncube 2,1,2,0,0,0,0,0,0.001,0.5,0.6\n"
            .to_vec(),
    ];
    fuzz("iso9283_log", "log.csv", &seeds, &|b| {
        let t = match read_text(b, "log.csv") {
            Ok(t) => t,
            Err(o) => return o,
        };
        let log = match read_log(&t, "log.csv", LogUnits::default()) {
            Ok(l) => l,
            Err(e) => return Outcome::Refused(e.to_string()),
        };
        match evaluate(&log) {
            Err(e) => Outcome::Refused(e.to_string()),
            Ok(e) => Outcome::Accepted((|| {
                let json = serde_json::to_value(&e).map_err(|x| x.to_string())?;
                fn finite(v: &serde_json::Value) -> bool {
                    match v {
                        serde_json::Value::Number(n) => n.as_f64().is_some_and(f64::is_finite),
                        serde_json::Value::Array(a) => a.iter().all(finite),
                        serde_json::Value::Object(o) => o.values().all(finite),
                        _ => true,
                    }
                }
                if !finite(&json) || e.poses.iter().any(|p| !p.ap.is_finite()) {
                    return Err("a figure is not finite".into());
                }
                let again = read_log(&write_log(&log), "log.csv", LogUnits::default())
                    .map_err(|x| format!("written back, it is refused: {x}"))?;
                let e2 = evaluate(&again).map_err(|x| format!("written back: {x}"))?;
                if e2.poses.len() != e.poses.len() || e2.distances.len() != e.distances.len() {
                    return Err("written back, it has other figures".into());
                }
                for (a, b) in e.poses.iter().zip(&e2.poses) {
                    if (a.ap - b.ap).abs() > 1e-9 * a.ap.abs().max(1.0) {
                        return Err(format!("written back, AP {} for {}", b.ap, a.ap));
                    }
                }
                Ok(())
            })()),
        }
    });
    let roles = vec![
        b"posture,test,pose,cycle\nD1,cube 1,P1,1\nD2,cube 1,C7,1\nD3,\"cube, 2\",c1,2\n".to_vec(),
    ];
    fuzz("iso9283_roles", "roles.csv", &roles, &|b| {
        let t = match read_text(b, "roles.csv") {
            Ok(t) => t,
            Err(o) => return o,
        };
        outcome(read_roles(&t, "roles.csv"), |r| {
            if r.by_posture.values().all(|x| (1..=13).contains(&x.pose)) {
                Ok(())
            } else {
                Err("a pose out of 1..13".into())
            }
        })
    });
}

/// Controller programs (KRL, RAPID, TP) as `compensate --format krl|rapid|tp` writes them, read
/// back by kinecal's reader of each language: what it accepts holds finite joint values, six per
/// move.
#[test]
fn controller_programs() {
    use kinecal::files::controller::{read_program, Language, Program, Zone};
    for language in [Language::Krl, Language::Rapid, Language::Tp] {
        let mut seeds = Vec::new();
        for (k, zone) in [Zone::Fine, Zone::Blend(10)].into_iter().enumerate() {
            let mut p = Program::new(language, format!("prog{k}"), 50, zone);
            for i in 0..4 {
                let v = i as f64;
                p.points
                    .push([10.5 * v, -20.25, 30.0 + v, -179.999999, 0.000001, 90.0 - v]);
            }
            let labels: Vec<String> = (1..=4).map(|i| format!("P{i}")).collect();
            seeds.push(
                p.text(&["written by kinecal".to_string()], &labels)
                    .into_bytes(),
            );
        }
        let file = match language {
            Language::Krl => "p.src",
            Language::Rapid => "p.mod",
            Language::Tp => "p.ls",
        };
        fuzz(language.as_str(), file, &seeds, &|b| {
            let t = match read_text(b, file) {
                Ok(t) => t,
                Err(o) => return o,
            };
            outcome(read_program(language, &t, file), |p| {
                if p.points.iter().flatten().all(|v| v.is_finite()) {
                    Ok(())
                } else {
                    Err("a non-finite joint value".into())
                }
            })
        });
    }
}

/// The two YAML files of `export ros` (`calibration.yaml`, `static_transforms.yaml`), from an
/// export of the UR10 URDF: what the readers accept holds finite values, and unit quaternions.
#[test]
fn ros_calibration_files() {
    use kinecal::import::ros::{export_ros, parse_calibration, parse_transforms};
    let path = repo().join("../shared/data/urdf/universal_robots/urdf_plain/ur10_robot.urdf");
    let template = std::fs::read_to_string(&path).expect("the UR10 URDF in ../shared/data");
    let robot = kinecal::import::urdf::import_urdf_tree(&template, "t.urdf", None, &["tool0"])
        .unwrap()
        .robot;
    let e = export_ros(&robot, &template, "t.urdf", None, &["tool0"], None).unwrap();
    fuzz(
        "ros-calibration",
        "calibration.yaml",
        &[e.calibration.clone().into_bytes()],
        &|b| {
            let t = match read_text(b, "calibration.yaml") {
                Ok(t) => t,
                Err(o) => return o,
            };
            outcome(parse_calibration(&t, "calibration.yaml"), |c| {
                if c.joints.iter().flat_map(|j| j.origin).all(f64::is_finite) {
                    Ok(())
                } else {
                    Err("a non-finite origin".into())
                }
            })
        },
    );
    fuzz(
        "ros-transforms",
        "static_transforms.yaml",
        &[e.transforms_yaml.clone().into_bytes()],
        &|b| {
            let t = match read_text(b, "static_transforms.yaml") {
                Ok(t) => t,
                Err(o) => return o,
            };
            outcome(parse_transforms(&t, "static_transforms.yaml"), |s| {
                for tr in &s.transforms {
                    if !tr.values.iter().all(|v| v.is_finite()) {
                        return Err("a non-finite value".into());
                    }
                    let q = &tr.values[3..];
                    let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
                    if (n - 1.0).abs() > 1e-6 {
                        return Err(format!("a quaternion of norm {n}"));
                    }
                }
                Ok(())
            })
        },
    );
}
