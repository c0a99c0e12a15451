//! The `kinecal dataset` adapters on synthetic folders shaped like their data sets: what they
//! convert reads back, and damaged files (rows cut, fields lost, an index out of range, a
//! transform too short) are refused with the file, the line and the count, never a panic.

#[path = "common/synthetic_datasets.rs"]
mod synthetic;

use std::path::Path;

use kinecal::apps::datasets::{Folder, DATASETS};
use synthetic::{folder, with, Files};

fn convert(name: &str, files: Files) -> kinecal::Result<kinecal::apps::datasets::Converted> {
    let adapter = DATASETS.iter().find(|a| a.name == name).unwrap();
    (adapter.read)(&Folder::memory(Path::new("d"), files))
}

/// The message of a refusal, which must not be a panic.
fn refused(name: &str, files: Files) -> String {
    match std::panic::catch_unwind(|| convert(name, files)) {
        Ok(Ok(_)) => panic!("{name}: accepted"),
        Ok(Err(e)) => e.to_string(),
        Err(_) => panic!("{name}: panicked"),
    }
}

fn lines(text: &[u8], n: usize) -> Vec<u8> {
    let s = String::from_utf8(text.to_vec()).unwrap();
    s.lines()
        .take(n)
        .map(|l| format!("{l}\n"))
        .collect::<String>()
        .into_bytes()
}

#[test]
fn synthetic_folders_convert_and_read_back_from_memory_and_disk() {
    for a in DATASETS {
        let c = convert(a.name, folder(a.name)).unwrap_or_else(|e| panic!("{}: {e}", a.name));
        let robot_text = &c.files.iter().find(|f| f.0 == c.suggested.robot).unwrap().1;
        let robot = kinecal::model::robot_file::parse_robot_toml(robot_text, "r.toml").unwrap();
        let data_text = &c.files.iter().find(|f| f.0 == c.suggested.data).unwrap().1;
        let data = kinecal::files::parse_measurements(data_text, "d.csv", &robot).unwrap();
        assert!(!data.observations.is_empty());
        // The same files on disk convert to the same output.
        let dir =
            std::env::temp_dir().join(format!("kinecal-ds-{}-{}", a.name, std::process::id()));
        for (name, bytes) in folder(a.name) {
            let p = dir.join(name);
            std::fs::create_dir_all(p.parent().unwrap()).unwrap();
            std::fs::write(p, bytes).unwrap();
        }
        let disk = (a.convert)(&dir).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
        assert_eq!(disk.files, c.files, "{}", a.name);
    }
}

#[test]
fn a_transform_shorter_than_three_rows_is_refused_with_the_count() {
    let f = folder("fanuc-r2000ic");
    let t = f
        .iter()
        .find(|x| x.0 == "TransTractoWorld0.csv")
        .unwrap()
        .1
        .clone();
    for n in 0..3 {
        let msg = refused(
            "fanuc-r2000ic",
            with(f.clone(), "TransTractoWorld0.csv", &lines(&t, n)),
        );
        assert!(
            msg.starts_with(&format!("d/TransTractoWorld0.csv:{}: ", n + 1))
                && msg.contains(&format!("expected 3 rows of 4 numbers, found {n}")),
            "{msg}"
        );
    }
    // A row with a field missing.
    let short = String::from_utf8(t).unwrap().replacen(" ", "", 1);
    let short = short
        .split_once(' ')
        .map(|(a, b)| format!("{a}{b}"))
        .unwrap();
    let msg = refused(
        "fanuc-r2000ic",
        with(f.clone(), "TransTractoWorld0.csv", short.as_bytes()),
    );
    assert!(
        msg.starts_with("d/TransTractoWorld0.csv:1: expected 4 numbers, found"),
        "{msg}"
    );
    // Not a rotation.
    let msg = refused(
        "fanuc-r2000ic",
        with(f, "TransFlangtoNest0.csv", b"1 0 0 5\n0 2 0 6\n0 0 1 7\n"),
    );
    assert!(
        msg.starts_with("d/TransFlangtoNest0.csv:1: ") && msg.contains("not a rotation"),
        "{msg}"
    );
}

#[test]
fn an_out_of_range_reflector_index_is_refused_by_line_and_field() {
    let f = folder("qkm-hl6");
    let angles = String::from_utf8(
        f.iter()
            .find(|x| x.0.ends_with("c_angles.txt"))
            .unwrap()
            .1
            .clone(),
    )
    .unwrap();
    for bad in ["0", "4", "2.5", "-1", "1000000"] {
        let mut l: Vec<String> = angles.lines().map(str::to_string).collect();
        let (head, _) = l[4].rsplit_once('\t').unwrap();
        l[4] = format!("{head}\t{bad}");
        let text = l.join("\n") + "\n";
        let msg = refused(
            "qkm-hl6",
            with(f.clone(), "position_dataset/c_angles.txt", text.as_bytes()),
        );
        assert!(
            msg.starts_with("d/position_dataset/c_angles.txt:5: field `column 7`: expected the reflector (SMR) index 1, 2 or 3"),
            "{bad}: {msg}"
        );
    }
}

#[test]
fn truncated_files_are_refused_with_the_rows_expected_and_found() {
    let cases: [(&str, &str, usize, usize); 5] = [
        ("qkm-hl6", "position_dataset/c_angles.txt", 46, 7),
        ("qkm-hl6", "position_dataset/re_test.txt", 9, 3),
        ("qkm-hl6", "position_dataset/re_smr.txt", 3, 3),
        ("fanuc-r2000ic", "N1N2N3Jval.csv", 36, 21),
        ("ur10e-camera", "calibration.csv", 24, 12),
    ];
    for (set, file, n, cols) in cases {
        let f = folder(set);
        let text = f.iter().find(|x| x.0 == file).unwrap().1.clone();
        // Whole rows missing: the count, at the line after the last.
        let keep = n - 2;
        let msg = refused(set, with(f.clone(), file, &lines(&text, keep)));
        let rows = if set == "ur10e-camera" { n - 1 } else { n };
        let found = if set == "ur10e-camera" {
            keep - 1
        } else {
            keep
        };
        assert!(
            msg.starts_with(&format!("d/{file}:{}: ", keep + 1))
                && msg.contains(&format!("expected {rows} rows"))
                && msg.contains(&format!("found {found}")),
            "{msg}"
        );
        // The last row cut in the middle: the fields found.
        let mut cut = lines(&text, n);
        let last = String::from_utf8(lines(&text, n - 1)).unwrap().len();
        let row = &cut[last..];
        let mut k = 0;
        let mut fields = 0;
        for (i, &c) in row.iter().enumerate() {
            if c == b',' || c == b' ' || c == b'\t' {
                fields += 1;
                if fields == 2 {
                    k = i;
                    break;
                }
            }
        }
        cut.truncate(last + k);
        let msg = refused(set, with(f.clone(), file, &cut));
        assert!(
            msg.starts_with(&format!("d/{file}:{n}: expected {cols} numbers, found ")),
            "{msg}"
        );
        // A row too many.
        let mut more = text.clone();
        more.extend_from_slice(
            &lines(&text, n)[String::from_utf8(lines(&text, n - 1)).unwrap().len()..],
        );
        let msg = refused(set, with(f, file, &more));
        assert!(
            msg.starts_with(&format!("d/{file}:{}: ", n + 1)) && msg.contains("found more"),
            "{msg}"
        );
    }
}

#[test]
fn degenerate_geometry_and_missing_files_are_refused_naming_the_file() {
    let f = folder("qkm-hl6");
    let msg = refused(
        "qkm-hl6",
        with(
            f.clone(),
            "position_dataset/re_ref.txt",
            b"1 2 3\n1 2 3\n1 2 3\n",
        ),
    );
    assert!(
        msg.starts_with("d/position_dataset/re_ref.txt: ") && msg.contains("no frame"),
        "{msg}"
    );
    let mut missing = f;
    missing.retain(|x| !x.0.ends_with("re_test.txt"));
    let msg = refused("qkm-hl6", missing);
    assert!(msg.starts_with("d/position_dataset/re_test.txt: "), "{msg}");
    let f = folder("fanuc-r2000ic");
    let rows = String::from_utf8(f[0].1.clone()).unwrap();
    let mut l: Vec<String> = rows.lines().map(str::to_string).collect();
    let mut v: Vec<&str> = l[2].split(' ').collect();
    let same: Vec<&str> = v[3..6].to_vec();
    v[..3].copy_from_slice(&same);
    l[2] = v.join(" ");
    let msg = refused(
        "fanuc-r2000ic",
        with(f, "N1N2N3Jval.csv", (l.join("\n") + "\n").as_bytes()),
    );
    assert!(
        msg.starts_with("d/N1N2N3Jval.csv:3: ") && msg.contains("no nest frame"),
        "{msg}"
    );
}

/// Found by the fuzzer: a URDF whose chain to `wrist_3_link` lost joints was read, and the
/// adapter wrote six readings per row for a robot of four, a file kinecal refused.
#[test]
fn a_urdf_chain_without_six_joints_is_refused() {
    let f = folder("ur10e-camera");
    let urdf = String::from_utf8(f[0].1.clone()).unwrap();
    let short = urdf.replace(
        "<parent link=\"shoulder_link\"/>\n    <child link=\"upper_arm_link\"/>",
        "<parent link=\"shoulder_link\"/>\n    <child link=\"wrist_1_link\"/>",
    );
    let short = short.replace(
        "<parent link=\"forearm_link\"/>\n    <child link=\"wrist_1_link\"/>",
        "<parent link=\"forearm_link\"/>\n    <child link=\"upper_arm_link\"/>",
    );
    assert_ne!(short, urdf);
    let msg = refused("ur10e-camera", with(f, "ur10_robot.urdf", short.as_bytes()));
    assert!(
        msg.starts_with("d/ur10_robot.urdf: the chain from `world` to `wrist_3_link` has 4 joints"),
        "{msg}"
    );
}

/// `ipa-ur10` on a synthetic copy cut to a few rows per series (in memory): converted with
/// those counts, and broken copies refused with the file, the line and the field.
mod ipa_ur10 {
    use std::path::Path;

    use kinecal::apps::datasets::{ipa_ur10, Folder};

    use super::synthetic::{ipa, with, Files, IPA_FEW};

    const A: &str = "Series_A/measurements_grid.csv";
    const B: &str = "Series_B/measurements_joint_configurations.csv";
    const D: &str = "Series_D/measurements_iso_cubes.csv";

    fn refused(files: Files) -> String {
        match std::panic::catch_unwind(|| {
            ipa_ur10::convert_trimmed(&Folder::memory(Path::new("d"), files), IPA_FEW)
        }) {
            Ok(Ok(_)) => panic!("accepted"),
            Ok(Err(e)) => e.to_string(),
            Err(_) => panic!("panicked"),
        }
    }

    /// `file` of `files` with line `line` (1-based) changed by `f`.
    fn edit(files: &Files, file: &str, line: usize, f: impl Fn(&str) -> String) -> Files {
        let text =
            String::from_utf8(files.iter().find(|x| x.0 == file).unwrap().1.clone()).unwrap();
        let mut l: Vec<String> = text.lines().map(str::to_string).collect();
        l[line - 1] = f(&l[line - 1]);
        with(files.clone(), file, (l.join("\r\n") + "\r\n").as_bytes())
    }

    /// The row with field `k` (0-based) replaced by `v`.
    fn field(row: &str, k: usize, v: &str) -> String {
        let mut f: Vec<&str> = row.split(';').collect();
        f[k] = v;
        f.join(";")
    }

    #[test]
    fn a_copy_converts_with_its_counts_and_the_files_read_back() {
        let c = ipa_ur10::convert_trimmed(&Folder::memory(Path::new("d"), ipa(IPA_FEW)), IPA_FEW)
            .unwrap();
        let robot =
            kinecal::model::robot_file::parse_robot_toml(&c.files[0].1, "ur10.toml").unwrap();
        for (k, s) in ipa_ur10::SERIES.iter().enumerate() {
            let (name, text) = &c.files[k + 1];
            assert_eq!(name, &format!("series_{}.csv", s.name));
            let d = kinecal::files::parse_measurements(text, name, &robot).unwrap();
            assert_eq!(d.postures.len(), IPA_FEW[k]);
            assert!(d
                .postures
                .iter()
                .all(|p| p.session.as_deref() == Some(s.name)));
            assert_eq!(text.lines().next().unwrap().contains("sigma_x"), s.sigmas);
        }
        let t = &c.files[5];
        assert_eq!(t.0, "temperatures.csv");
        assert_eq!(t.1.lines().count(), 1 + IPA_FEW.iter().sum::<usize>());
        assert!(
            t.1.starts_with("posture,session,temperature\nA1,A,23.0000003051758\n"),
            "{}",
            t.1
        );
        // The README's counts refuse the copy, naming series A's count.
        let msg = (kinecal::apps::datasets::ipa_ur10::convert_folder)(&Folder::memory(
            Path::new("d"),
            ipa(IPA_FEW),
        ))
        .unwrap_err()
        .to_string();
        assert_eq!(
            msg,
            "d/Series_A/measurements_grid.csv:9: expected 11911 rows after the header, found 7 \
             (the file ends here: truncated?)"
        );
    }

    #[test]
    fn a_missing_series_a_bad_number_and_a_short_row_are_refused_where_they_are() {
        let f = ipa(IPA_FEW);
        // A series missing.
        let mut missing = f.clone();
        missing.retain(|x| x.0 != B);
        let msg = refused(missing);
        assert!(msg.starts_with(&format!("d/{B}: ")), "{msg}");
        // A bad number (line 4 of series B, the 3rd row; its field measurement_y).
        for bad in ["12.5", "1,2,3", "x", "", "nan", "inf", "1e10"] {
            let msg = refused(edit(&f, B, 4, |r| field(r, 16, bad)));
            assert_eq!(
                msg,
                format!(
                    "d/{B}:4: field `measurement_y`: expected a finite number within +-1e9 with a \
                     decimal comma (`-0,5`), found `{bad}`"
                )
            );
        }
        // A joint value.
        let msg = refused(edit(&f, A, 3, |r| field(r, 9, "0,1x")));
        assert!(
            msg.starts_with(&format!("d/{A}:3: field `elbow_joint`: ")),
            "{msg}"
        );
        // A standard deviation that is not positive.
        let msg = refused(edit(&f, D, 2, |r| field(r, 19, "0")));
        assert_eq!(
            msg,
            format!("d/{D}:2: field `measurement_std_z`: expected a positive standard deviation, found `0`")
        );
        // A short row, a long row.
        let msg = refused(edit(&f, D, 3, |r| {
            r.rsplit_once(';').unwrap().0.to_string()
        }));
        assert_eq!(
            msg,
            format!("d/{D}:3: expected 26 `;`-separated fields, found 25")
        );
        let msg = refused(edit(&f, A, 5, |r| format!("{r};1")));
        assert_eq!(
            msg,
            format!("d/{A}:5: expected 20 `;`-separated fields, found 21")
        );
        // A row too many, a row too few.
        let msg = refused(edit(&f, D, 4, |r| format!("{r}\r\n{r}")));
        assert_eq!(
            msg,
            format!("d/{D}:5: expected 3 rows after the header, found more")
        );
        let msg = refused(edit(&f, D, 4, |_| String::new()));
        assert_eq!(
            msg,
            format!("d/{D}:4: expected 3 rows after the header, found 2 (the file ends here: truncated?)")
        );
        // A header without the standard deviations where the series has them, a column renamed.
        let msg = refused(edit(&f, B, 1, |_| {
            String::from_utf8(f[0].1.clone())
                .unwrap()
                .lines()
                .next()
                .unwrap()
                .to_string()
        }));
        assert!(
            msg.starts_with(&format!(
                "d/{B}:1: expected the header of 26 `;`-separated columns"
            )),
            "{msg}"
        );
        let msg = refused(edit(&f, A, 1, |r| {
            r.replace("measurement_y", "measurement_Y")
        }));
        assert_eq!(
            msg,
            format!("d/{A}:1: field `column 16`: expected the column `measurement_y`, found `measurement_Y`")
        );
    }
}
