//! Small synthetic folders shaped like the public data sets the adapters of
//! `kinecal::apps::datasets` read (the row counts, columns, separators and number formats their
//! READMEs describe; made-up values, no data copied), and a folder packed into one byte string
//! for the mutation driver.
#![allow(dead_code)] // each test binary uses what it needs

use nalgebra::{Matrix3, Rotation3, Vector3};

/// A folder: `(name in the folder, bytes)`.
pub type Files = Vec<(String, Vec<u8>)>;

fn rows(n: usize, f: impl Fn(usize) -> String) -> Vec<u8> {
    (0..n).map(f).collect::<String>().into_bytes()
}

/// An angle in degrees for posture `i`, joint `j`, with the digits of a controller's reading.
fn angle(i: usize, j: usize) -> f64 {
    ((i * 37 + j * 53) % 170) as f64 - 85.0 + 0.123456 * j as f64
}

/// Shaped like `qkm_hl6_faro`: `position_dataset/` with 3 reference points, 3 reflectors, 46
/// identification rows (tab-separated angles and the reflector's index; two-space separated
/// points) and 9 test rows (comma-separated angles).
pub fn qkm() -> Files {
    let point = |i: usize| {
        format!(
            "{:.6}  {:.6}  {:.6}\n",
            4000.0 + 7.5 * i as f64,
            400.0 + 11.25 * (i % 9) as f64,
            300.0 - 13.0 * (i % 7) as f64
        )
    };
    let d = |f: &str| format!("position_dataset/{f}");
    vec![
        (
            d("re_ref.txt"),
            b"3500.000000  630.000000  -620.000000\n3680.000000  -170.000000  -615.000000\n\
              3860.000000  710.000000  -617.000000\n"
                .to_vec(),
        ),
        (
            d("re_smr.txt"),
            b"3714.000000  258.000000  323.000000\n3738.000000  147.000000  210.000000\n\
              3688.000000  368.000000  209.000000\n"
                .to_vec(),
        ),
        (
            d("c_angles.txt"),
            rows(46, |i| {
                let a: Vec<String> = (0..6).map(|j| format!("{}", angle(i, j))).collect();
                format!("{}\t{}\n", a.join("\t"), i % 3 + 1)
            }),
        ),
        (d("c_poses.txt"), rows(46, point)),
        (
            d("test_points.txt"),
            rows(9, |i| {
                let a: Vec<String> = (0..6).map(|j| format!("{:.6}", angle(i + 50, j))).collect();
                format!("{}, {}\n", a.join(", "), i % 3 + 1)
            }),
        ),
        (d("re_test.txt"), rows(9, |i| point(i + 50))),
    ]
}

fn transform(r: Matrix3<f64>, t: Vector3<f64>) -> Vec<u8> {
    rows(3, |i| {
        format!(
            "{:.18e} {:.18e} {:.18e} {:.18e}\n",
            r[(i, 0)],
            r[(i, 1)],
            r[(i, 2)],
            t[i]
        )
    })
}

/// Shaped like `fanuc_r2000ic_lasertracker`: `N1N2N3Jval.csv` (36 rows of 21 space-separated
/// numbers in `%.18e`: three reflector positions, six zeros, J1..J6) and the two 3 x 4
/// transforms.
pub fn fanuc() -> Files {
    let nest = |i: usize| {
        let base = Vector3::new(700.0 - 4.0 * i as f64, -3100.0 + 9.0 * i as f64, 600.0);
        [
            base,
            base + Vector3::new(-140.0, 20.0, 200.0),
            base + Vector3::new(-170.0, 110.0, -140.0),
        ]
    };
    let r = Rotation3::from_euler_angles(0.005, -0.006, 0.386).into_inner();
    let n = Rotation3::from_euler_angles(0.5, -0.2, 0.9).into_inner();
    vec![
        (
            "N1N2N3Jval.csv".into(),
            rows(36, |i| {
                let mut v: Vec<f64> = nest(i).iter().flat_map(|p| p.iter().copied()).collect();
                v.extend([0.0; 6]);
                v.extend((0..6).map(|j| if j == i / 6 { angle(i, j) } else { 0.0 }));
                let s: Vec<String> = v.iter().map(|x| format!("{x:.18e}")).collect();
                s.join(" ") + "\n"
            }),
        ),
        (
            "TransTractoWorld0.csv".into(),
            transform(r, Vector3::new(-1393.48, -3662.79, -672.50)),
        ),
        (
            "TransFlangtoNest0.csv".into(),
            transform(n, Vector3::new(194.67, -46.51, 203.98)),
        ),
    ]
}

/// Shaped like `ur10e_camera`: a URDF from `world` to `wrist_3_link` (UR10e lengths) and
/// `calibration.csv` (the header and 23 rows of 12 comma-separated numbers).
pub fn ur10e() -> Files {
    let joint = |name: &str, parent: &str, child: &str, xyz: &str, rpy: &str| {
        format!(
            "  <joint name=\"{name}\" type=\"revolute\">\n    <parent link=\"{parent}\"/>\n    \
             <child link=\"{child}\"/>\n    <origin xyz=\"{xyz}\" rpy=\"{rpy}\"/>\n    \
             <axis xyz=\"0 0 1\"/>\n    <limit lower=\"-6.283\" upper=\"6.283\" effort=\"330\" \
             velocity=\"2.09\"/>\n  </joint>\n"
        )
    };
    let mut urdf = String::from("<?xml version=\"1.0\" ?>\n<robot name=\"ur10\">\n");
    for l in [
        "world",
        "base_link",
        "shoulder_link",
        "upper_arm_link",
        "forearm_link",
        "wrist_1_link",
        "wrist_2_link",
        "wrist_3_link",
    ] {
        urdf += &format!("  <link name=\"{l}\"/>\n");
    }
    urdf += "  <joint name=\"base_joint\" type=\"fixed\">\n    <parent link=\"world\"/>\n    \
             <child link=\"base_link\"/>\n    <origin xyz=\"0 0 0.9\" rpy=\"0 0 -1.5707963267948966\"/>\n  \
             </joint>\n";
    let pi2 = "1.570796327";
    urdf += &joint(
        "shoulder_pan_joint",
        "base_link",
        "shoulder_link",
        "0 0 0.1807",
        "0 0 0",
    );
    urdf += &joint(
        "shoulder_lift_joint",
        "shoulder_link",
        "upper_arm_link",
        "0 0 0",
        &format!("{pi2} 0 0"),
    );
    urdf += &joint(
        "elbow_joint",
        "upper_arm_link",
        "forearm_link",
        "-0.6127 0 0",
        "0 0 0",
    );
    urdf += &joint(
        "wrist_1_joint",
        "forearm_link",
        "wrist_1_link",
        "-0.57155 0 0.17415",
        "0 0 0",
    );
    urdf += &joint(
        "wrist_2_joint",
        "wrist_1_link",
        "wrist_2_link",
        "0 -0.11985 0",
        &format!("{pi2} 0 0"),
    );
    urdf += &joint(
        "wrist_3_joint",
        "wrist_2_link",
        "wrist_3_link",
        "0 0.11655 0",
        &format!("-{pi2} 0 0"),
    );
    urdf += "</robot>\n";
    let mut csv = String::from(
        "x1,y1,z1,phix1,phiy1,phiz1,shoulder_pan_joint,shoulder_lift_joint,elbow_joint,\
         wrist_1_joint,wrist_2_joint,wrist_3_joint\n",
    );
    for i in 0..23 {
        let v: Vec<String> = (0..12)
            .map(|j| {
                let x = angle(i, j) / 60.0;
                format!("{}", if j < 3 { 0.8 + x / 5.0 } else { x })
            })
            .collect();
        csv += &(v.join(",") + "\n");
    }
    vec![
        ("ur10_robot.urdf".into(), urdf.into_bytes()),
        ("calibration.csv".into(), csv.into_bytes()),
    ]
}

/// A number with a decimal comma, as the IPA lab writes them.
fn comma(v: f64) -> String {
    format!("{v}").replace('.', ",")
}

/// Shaped like `ipa_ur10_tracker`, with `rows` rows per series A-D: the four measurement files
/// (`;`-separated, decimal commas, CRLF; A without the standard deviation columns, B-D with
/// them; timestamps as the spreadsheet export left them in B-D).
pub fn ipa(rows: [usize; 4]) -> Files {
    let mut out = Vec::new();
    for (s, n) in ["A", "B", "C", "D"].iter().zip(rows) {
        let sigmas = *s != "A";
        let file = match *s {
            "A" => "Series_A/measurements_grid.csv",
            "B" => "Series_B/measurements_joint_configurations.csv",
            "C" => "Series_C/measurements_random_poses.csv",
            _ => "Series_D/measurements_iso_cubes.csv",
        };
        let mut text = String::from(
            "Timestamp;Goal x;Goal y;Goal z;Goal roll;Goal pitch;Goal yaw;shoulder_pan_joint;\
             shoulder_lift_joint;elbow_joint;wrist_1_joint;wrist_2_joint;wrist_3_joint;\
             measurement_temperature;",
        );
        text += if sigmas {
            "measurement_x;measurement_std_x;measurement_y;measurement_std_y;measurement_z;\
             measurement_std_z;measurement_rx;measurement_std_rx;measurement_ry;\
             measurement_std_ry;measurement_rz;measurement_std_rz\r\n"
        } else {
            "measurement_x;measurement_y;measurement_z;measurement_rx;measurement_ry;\
             measurement_rz\r\n"
        };
        for i in 0..n {
            let mut f: Vec<String> = vec![if sigmas {
                "2,02011E+13".into()
            } else {
                format!("{}", 20200714163904u64 + 20 * i as u64)
            }];
            if *s == "D" {
                // Series D's goals: blocks of nine, a cube's centre and its eight corners (the
                // third block the first cube again, as in the data set).
                let (b, k) = ((i / 9) % 5, i % 9);
                let b = if b == 2 { 0 } else { b };
                let centre = [0.1 * b as f64, 0.6, 0.7];
                let half = 0.05 + 0.025 * b as f64;
                let goal: Vec<f64> = (0..3)
                    .map(|a| {
                        let sign = if k == 0 {
                            0.0
                        } else if (k - 1) & (1 << a) != 0 {
                            1.0
                        } else {
                            -1.0
                        };
                        centre[a] + sign * half
                    })
                    .collect();
                f.extend(goal.iter().map(|v| comma(*v)));
                f.extend((3..6).map(|j| comma(angle(i, j) / 100.0)));
            } else {
                f.extend((0..6).map(|j| comma(angle(i, j) / 100.0)));
            }
            f.extend((0..6).map(|j| comma(angle(i, j + 6).to_radians())));
            f.push(comma(23.0 + 0.125 * (i % 7) as f64 + 0.0000003051758));
            let p = [
                2000.0 + 3.25 * (i % 97) as f64,
                -1500.0 - 2.5 * (i % 31) as f64,
                100.0 + 1.125 * (i % 53) as f64,
            ];
            let r = [-90.5 + 0.01 * (i % 11) as f64, -59.25, -90.875];
            let std = |k: usize| comma(0.0005 + 0.0001 * ((i + k) % 700) as f64);
            for (a, v) in p.iter().chain(&r).enumerate() {
                f.push(comma(*v));
                if sigmas {
                    f.push(std(a));
                }
            }
            text += &(f.join(";") + "\r\n");
        }
        out.push((file.to_string(), text.into_bytes()));
    }
    out
}

/// The row counts of the IPA series A-D in the data set.
pub const IPA_ROWS: [usize; 4] = [11_911, 1_495, 2_773, 632];

/// A few rows per IPA series, for the mutation driver (the adapter's
/// `ipa_ur10::convert_trimmed` with these counts).
pub const IPA_FEW: [usize; 4] = [7, 4, 5, 3];

/// The synthetic folder of the adapter `name`.
pub fn folder(name: &str) -> Files {
    match name {
        "qkm-hl6" => qkm(),
        "fanuc-r2000ic" => fanuc(),
        "ur10e-camera" => ur10e(),
        "ipa-ur10" => ipa(IPA_ROWS),
        other => panic!("no synthetic folder for {other}"),
    }
}

/// A file of `files` replaced (by name).
pub fn with(mut files: Files, name: &str, bytes: &[u8]) -> Files {
    let f = files
        .iter_mut()
        .find(|(n, _)| n == name)
        .unwrap_or_else(|| panic!("no {name}"));
    f.1 = bytes.to_vec();
    files
}

const MARK: &[u8] = b"==> ";
const END: &[u8] = b" <==";

/// The files as one byte string: each as a line `==> name <==` and its bytes (for the mutation
/// driver, which mutates one byte string: a damaged mark loses, renames or merges files).
pub fn pack(files: &Files) -> Vec<u8> {
    let mut b = Vec::new();
    for (name, bytes) in files {
        b.extend_from_slice(MARK);
        b.extend_from_slice(name.as_bytes());
        b.extend_from_slice(END);
        b.push(b'\n');
        b.extend_from_slice(bytes);
        if !bytes.ends_with(b"\n") {
            b.push(b'\n');
        }
    }
    b
}

/// The files of a [`pack`]ed byte string (bytes before the first mark are dropped; a mark line
/// that is not valid UTF-8 is part of the file before it).
pub fn unpack(b: &[u8]) -> Files {
    let mut files: Files = Vec::new();
    for line in b.split_inclusive(|&c| c == b'\n') {
        let body = line.strip_suffix(b"\n").unwrap_or(line);
        let name = body
            .strip_prefix(MARK)
            .and_then(|r| r.strip_suffix(END))
            .and_then(|n| std::str::from_utf8(n).ok());
        match (name, files.last_mut()) {
            (Some(n), _) => files.push((n.to_string(), Vec::new())),
            (None, Some(f)) => f.1.extend_from_slice(line),
            (None, None) => {}
        }
    }
    files
}
