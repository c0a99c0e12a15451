//! Imported models (DH, POE) have the same forward kinematics as their source convention,
//! computed independently here with plain 4x4 matrices.

use kinecal::import::dh::{parse_dh_csv, robot_from_dh, Convention, RowKind};
use kinecal::import::poe::parse_poe_toml;
use kinecal::model::kinematics::Target;
use kinecal::{AngleUnit, LengthUnit, Units};
use nalgebra::{Matrix4, Rotation3, Unit, Vector3};
use rand::{RngExt, SeedableRng};

fn rot_z(t: f64) -> Matrix4<f64> {
    Rotation3::from_axis_angle(&Vector3::z_axis(), t).to_homogeneous()
}
fn rot_x(t: f64) -> Matrix4<f64> {
    Rotation3::from_axis_angle(&Vector3::x_axis(), t).to_homogeneous()
}
fn rot_y(t: f64) -> Matrix4<f64> {
    Rotation3::from_axis_angle(&Vector3::y_axis(), t).to_homogeneous()
}
fn trans(x: f64, y: f64, z: f64) -> Matrix4<f64> {
    Matrix4::new_translation(&Vector3::new(x, y, z))
}

fn compare(robot: &kinecal::Robot, readings: &[f64], expected: &Matrix4<f64>) {
    let f = kinecal::Chain::new(robot).frame_at(readings, Target::EndEffector);
    for i in 0..3 {
        assert!(
            (f.translation[i] - expected[(i, 3)]).abs() < 1e-9,
            "position {i}: {} vs {}",
            f.translation[i],
            expected[(i, 3)]
        );
        for j in 0..3 {
            assert!(
                (f.rotation[(i, j)] - expected[(i, j)]).abs() < 1e-9,
                "rotation ({i},{j})"
            );
        }
    }
}

/// PUMA 560 (Craig's modified table, and the standard one from Corke), metres and degrees.
#[test]
fn puma_560_dh_tables_match_textbook_fk() {
    let si = Units {
        length: LengthUnit::M,
        angle: AngleUnit::Deg,
    };
    let modified =
        "kind,a,alpha,d,theta\nrevolute,0,0,0,0\nrevolute,0,-90,0,0\nrevolute,0.4318,0,0.15005,0\n\
                    revolute,0.0203,-90,0.4318,0\nrevolute,0,90,0,0\nrevolute,0,-90,0,0\n";
    let standard = "kind,a,alpha,d,theta\nrevolute,0,90,0.6718,0\nrevolute,0.4318,0,0,0\nrevolute,0.0203,-90,0.15005,0\n\
                    revolute,0,90,0.4318,0\nrevolute,0,-90,0,0\nrevolute,0,0,0,0\n";
    let rm = robot_from_dh(
        "puma",
        si,
        &parse_dh_csv(modified, "m.csv", si).unwrap(),
        Convention::Modified,
    );
    let rs = robot_from_dh(
        "puma",
        si,
        &parse_dh_csv(standard, "s.csv", si).unwrap(),
        Convention::Standard,
    );
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(560);
    let table = |text: &str| -> Vec<[f64; 4]> {
        text.lines()
            .skip(1)
            .map(|l| {
                let f: Vec<f64> = l.split(',').skip(1).map(|v| v.parse().unwrap()).collect();
                [f[0], f[1].to_radians(), f[2], f[3].to_radians()]
            })
            .collect()
    };
    let (tm, ts) = (table(modified), table(standard));
    for _ in 0..100 {
        let q: Vec<f64> = (0..6).map(|_| rng.random_range(-180.0..180.0)).collect();
        let mut em = Matrix4::identity();
        let mut es = Matrix4::identity();
        for i in 0..6 {
            let qr = q[i].to_radians();
            let [a, al, d, th] = tm[i];
            em *= rot_x(al) * trans(a, 0.0, 0.0) * rot_z(th + qr) * trans(0.0, 0.0, d);
            let [a, al, d, th] = ts[i];
            es *= rot_z(th + qr) * trans(0.0, 0.0, d) * trans(a, 0.0, 0.0) * rot_x(al);
        }
        compare(&rm, &q, &em);
        compare(&rs, &q, &es);
    }
}

#[test]
fn dh_with_prismatic_joints_and_offsets() {
    let u = Units {
        length: LengthUnit::Mm,
        angle: AngleUnit::Rad,
    };
    // Fixed rows (a base and a tool transform) and the Hayati/Mooring beta column.
    let text = "kind,a,alpha,d,theta,beta\nfixed,7,0.1,-3,0.5,0.02\nrevolute,100,0.3,50,0.2,0\n\
                prismatic,20,-1.2,300,0.7,0.01\nrevolute,0,1.57,10,-0.4,-0.03\nfixed,1,2,3,0.4,0.05\n";
    let rows = parse_dh_csv(text, "t.csv", u).unwrap();
    assert_eq!(rows.len(), 5);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    for conv in [Convention::Standard, Convention::Modified] {
        let robot = robot_from_dh("t", u, &rows, conv);
        assert_eq!(robot.dof(), 3);
        for _ in 0..100 {
            let q = [
                rng.random_range(-3.0..3.0),
                rng.random_range(-100.0..100.0),
                rng.random_range(-3.0..3.0),
            ];
            let mut e = Matrix4::identity();
            let mut i = 0;
            for row in &rows {
                let (th, d) = match row.kind {
                    RowKind::Revolute => (row.theta + q[i], row.d),
                    RowKind::Prismatic => (row.theta, row.d + q[i] * 1e-3),
                    RowKind::Fixed => (row.theta, row.d),
                };
                if row.kind != RowKind::Fixed {
                    i += 1;
                }
                e *= match conv {
                    Convention::Standard => {
                        rot_z(th)
                            * trans(0.0, 0.0, d)
                            * trans(row.a, 0.0, 0.0)
                            * rot_x(row.alpha)
                            * rot_y(row.beta)
                    }
                    Convention::Modified => {
                        rot_x(row.alpha)
                            * trans(row.a, 0.0, 0.0)
                            * rot_y(row.beta)
                            * rot_z(th)
                            * trans(0.0, 0.0, d)
                    }
                };
            }
            compare(&robot, &q, &e);
        }
    }
    let err = parse_dh_csv("kind,a,alpha,d,theta\nhelical,1,2,3,4\n", "bad.csv", u)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("bad.csv:2") && err.contains("helical"),
        "{err}"
    );
}

/// Exponential of a unit twist (rotation about `w` through `p`, or translation along `w`).
fn twist_exp(w: Vector3<f64>, p: Vector3<f64>, prismatic: bool, q: f64) -> Matrix4<f64> {
    if prismatic {
        return trans(w.x * q, w.y * q, w.z * q);
    }
    let r = Rotation3::from_axis_angle(&Unit::new_normalize(w), q).to_homogeneous();
    trans(p.x, p.y, p.z) * r * trans(-p.x, -p.y, -p.z)
}

#[test]
fn poe_import_matches_exponential_fk() {
    let text = r#"
name = "poe test"
length_unit = "mm"
angle_unit = "deg"
[[joints]]
kind = "revolute"
axis = [0, 0, 1]
point = [-590, 410, 300]
[[joints]]
kind = "revolute"
axis = [0, 1, 0]
point = [-590, 410, 491]
[[joints]]
kind = "prismatic"
axis = [0.3, -0.2, 1]
offset = 50
[[joints]]
kind = "revolute"
axis = [0, 1, 0]
point = [-590, 410, 841]
offset = -90
[[joints]]
kind = "revolute"
axis = [1, 0, 0]
point = [-240, 410, 841]
[[joints]]
kind = "revolute"
axis = [0, -1, 0]
point = [-240, 410, 841]
[tool]
position = [-156, 410, 841]
euler = [10, 20, -30]
[[sites]]
name = "smr1"
position = [-150, 450, 800]
euler = [0, 0, 0]
[[sites]]
name = "wrist"
joint = 4
position = [-300, 400, 841]
euler = [0, 90, 0]
"#;
    let robot = parse_poe_toml(text, "poe.toml").unwrap();
    assert_eq!(robot.dof(), 6);
    // Common-normal frames keep every link away from beta = +-90 deg.
    for l in &robot.links[1..robot.dof()] {
        assert!(l.beta.abs() < 1e-9, "beta {}", l.beta);
    }
    // A tool or a site given without angles takes its joint's frame: angles exactly 0 (no
    // beta = -90 deg where the last axis is along x), position unchanged.
    let bare = text
        .replace("euler = [10, 20, -30]\n", "")
        .replacen("euler = [0, 0, 0]\n", "", 1);
    let b = parse_poe_toml(&bare, "bare.toml").unwrap();
    let last = b.links.last().unwrap();
    assert_eq!((last.alpha, last.beta, last.gamma), (0.0, 0.0, 0.0));
    let s0 = &b.sites[0].frame;
    assert_eq!((s0.alpha, s0.beta, s0.gamma), (0.0, 0.0, 0.0));
    let v = [10.0, -20.0, 30.0, 40.0, -50.0, 60.0];
    let (c1, c2) = (kinecal::Chain::new(&robot), kinecal::Chain::new(&b));
    for t in [Target::EndEffector, Target::Site(0)] {
        let d = c1.frame_at(&v, t).translation - c2.frame_at(&v, t).translation;
        assert!(d.norm() < 1e-12);
    }
    let mm = 1e-3;
    let axes: Vec<(Vector3<f64>, Vector3<f64>, bool, f64)> = vec![
        (
            Vector3::z(),
            Vector3::new(-590.0, 410.0, 300.0) * mm,
            false,
            0.0,
        ),
        (
            Vector3::y(),
            Vector3::new(-590.0, 410.0, 491.0) * mm,
            false,
            0.0,
        ),
        (
            Vector3::new(0.3, -0.2, 1.0).normalize(),
            Vector3::zeros(),
            true,
            50.0 * mm,
        ),
        (
            Vector3::y(),
            Vector3::new(-590.0, 410.0, 841.0) * mm,
            false,
            -90f64.to_radians(),
        ),
        (
            Vector3::x(),
            Vector3::new(-240.0, 410.0, 841.0) * mm,
            false,
            0.0,
        ),
        (
            -Vector3::y(),
            Vector3::new(-240.0, 410.0, 841.0) * mm,
            false,
            0.0,
        ),
    ];
    let tool = trans(-0.156, 0.410, 0.841)
        * kinecal::model::kinematics::rot_zyx(
            10f64.to_radians(),
            20f64.to_radians(),
            -30f64.to_radians(),
        )
        .to_homogeneous();
    let site = |pos: [f64; 3], beta: f64| {
        trans(pos[0] * mm, pos[1] * mm, pos[2] * mm)
            * kinecal::model::kinematics::rot_zyx(0.0, beta, 0.0).to_homogeneous()
    };
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    for _ in 0..100 {
        let v: Vec<f64> = (0..6)
            .map(|i| {
                if i == 2 {
                    rng.random_range(-100.0..100.0)
                } else {
                    rng.random_range(-170.0..170.0)
                }
            })
            .collect();
        let mut t: Matrix4<f64> = Matrix4::identity();
        let mut after4: Matrix4<f64> = Matrix4::identity();
        for (i, &(w, p, pr, off)) in axes.iter().enumerate() {
            let q = off + if pr { v[i] * mm } else { v[i].to_radians() };
            t *= twist_exp(w, p, pr, q);
            if i == 3 {
                after4 = t;
            }
        }
        compare(&robot, &v, &(t * tool));
        let chain = kinecal::Chain::new(&robot);
        let sites: [(usize, Matrix4<f64>); 2] = [
            (0, t * site([-150.0, 450.0, 800.0], 0.0)),
            (1, after4 * site([-300.0, 400.0, 841.0], 90f64.to_radians())),
        ];
        for (s, expected) in sites {
            let f = chain.frame_at(&v, Target::Site(s));
            for i in 0..3 {
                assert!(
                    (f.translation[i] - expected[(i, 3)]).abs() < 1e-9,
                    "site {s}"
                );
                for j in 0..3 {
                    assert!(
                        (f.rotation[(i, j)] - expected[(i, j)]).abs() < 1e-9,
                        "site {s} rotation"
                    );
                }
            }
        }
    }
    for (bad, expected) in [
        (
            text.replace("axis = [0, 0, 1]", "axis = [0, 0, 0]"),
            "zero vector",
        ),
        (
            text.replace("axis = [0, 0, 1]", "axis = [0, 1]"),
            "joints[0].axis",
        ),
        (text.replace("[tool]", "[tooling]"), "unknown key `tooling`"),
    ] {
        let err = parse_poe_toml(&bad, "poe.toml").unwrap_err().to_string();
        assert!(err.contains("poe.toml") && err.contains(expected), "{err}");
    }
}
