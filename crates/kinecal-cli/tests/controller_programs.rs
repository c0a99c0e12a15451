//! `kinecal compensate --format krl|rapid|tp`: KUKA KRL, ABB RAPID and FANUC TP programs of 50
//! compensated targets read back, by kinecal's reader and by this test's own, to the values of
//! the joint table (`--format joints-kuka`, ten decimals) within the six written decimals;
//! speed and zone in each language's words; programs refused, with the reason, for a robot
//! that is not a 6-axis arm, a name the controller would not take, a speed or zone it has not,
//! and a flagged row; `kinecal fk` reads the joint tables back.

mod common;

use std::path::Path;

use common::{argv, kinecal, run, run_err, run_ok};
use kinecal::files::controller::{read_program, Language, Zone, PROGRAM_READ_BACK};

/// A folder with the IRB 120, its "true" twin and 50 pose targets (`poses.csv`) that the twin
/// reaches without a flag.
fn setup() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::copy(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/robots/abb_irb120.toml"),
        d.join("irb120.toml"),
    )
    .unwrap();
    run_ok(
        d,
        &argv(
            "simulate --robot irb120.toml --postures 50 --seed 5
             --perturb-std length=0.001,angle=0.005 --out m.csv --truth true.toml",
        ),
    );
    let m = std::fs::read_to_string(d.join("m.csv")).unwrap();
    let mut poses = String::from("target,x,y,z,alpha,beta,gamma\n");
    for l in m.lines().skip(1) {
        let f: Vec<&str> = l.split(',').collect();
        poses += &format!("{},{}\n", f[0], f[8..14].join(","));
    }
    std::fs::write(d.join("poses.csv"), poses).unwrap();
    dir
}

/// `compensate` of `poses.csv` for the twin, with `extra` arguments: (exit code, stderr).
fn comp(d: &Path, extra: &str) -> (i32, String) {
    let (code, _, err) = run(
        d,
        &argv(&format!(
            "compensate --robot true.toml --nominal irb120.toml --in poses.csv {extra}"
        )),
    );
    (code, err)
}

/// The rows of a six-column table after its label (`target,A1..A6`, degrees; a pose file).
fn table(d: &Path, file: &str) -> Vec<[f64; 6]> {
    std::fs::read_to_string(d.join(file))
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| {
            let v: Vec<f64> = l.split(',').skip(1).map(|v| v.parse().unwrap()).collect();
            v.try_into().unwrap()
        })
        .collect()
}

/// This test's own reading of a program's joint values: the numbers of each move's six axes,
/// found by their text alone (no kinecal code).
fn independent(language: Language, text: &str) -> Vec<[f64; 6]> {
    let six = |v: Vec<f64>| -> [f64; 6] { v.try_into().unwrap() };
    match language {
        // PTP {A1 v, A2 v, ...}
        Language::Krl => text
            .lines()
            .filter(|l| l.starts_with("PTP {"))
            .map(|l| {
                let inner = &l[5..l.find('}').unwrap()];
                six(inner
                    .split(", ")
                    .enumerate()
                    .map(|(k, a)| {
                        let (name, v) = a.split_once(' ').unwrap();
                        assert_eq!(name, format!("A{}", k + 1), "{l}");
                        v.parse().unwrap()
                    })
                    .collect())
            })
            .collect(),
        // MoveAbsJ [[v,v,v,v,v,v],[9E9,...]]
        Language::Rapid => text
            .lines()
            .filter_map(|l| l.trim().strip_prefix("MoveAbsJ [["))
            .map(|l| {
                six(l[..l.find(']').unwrap()]
                    .split(',')
                    .map(|v| v.parse().unwrap())
                    .collect())
            })
            .collect(),
        // After /POS: every `Jk= v deg`, in order, six to a point.
        Language::Tp => {
            let pos = &text[text.find("\n/POS\n").unwrap()..];
            let mut values = Vec::new();
            let mut rest = pos;
            while let Some(i) = rest.find("J") {
                rest = &rest[i + 1..];
                let Some((k, after)) = rest.split_once("= ") else {
                    break;
                };
                if k.len() != 1 {
                    continue;
                }
                let v = after.trim_start().split(" deg").next().unwrap();
                assert_eq!(k, ((values.len() % 6) + 1).to_string(), "{rest}");
                values.push(v.trim().parse::<f64>().unwrap());
            }
            values.chunks(6).map(|c| six(c.to_vec())).collect()
        }
    }
}

/// Every value of `got` within half a unit of the sixth decimal (and a float's rounding) of
/// the table's.
fn assert_table(what: &str, got: &[[f64; 6]], table: &[[f64; 6]]) {
    assert_eq!(got.len(), table.len(), "{what}");
    for (i, (a, b)) in got.iter().zip(table).enumerate() {
        for k in 0..6 {
            assert!(
                (a[k] - b[k]).abs() <= PROGRAM_READ_BACK,
                "{what}: move {}, axis {}: {} against {}",
                i + 1,
                k + 1,
                a[k],
                b[k]
            );
        }
    }
}

/// The test: KRL, RAPID and TP programs of 50 compensated targets parse, by kinecal's
/// reader and by an independent one, to the table's values within the written decimals.
#[test]
fn programs_read_back_to_the_table() {
    let dir = setup();
    let d = dir.path();
    let (code, err) = comp(d, "--format joints-kuka --out table.csv");
    assert_eq!(code, 0, "{err}");
    let t = table(d, "table.csv");
    assert_eq!(t.len(), 50);
    for (language, out, name, axes) in [
        (Language::Krl, "prog.src", "prog", "A1..A6"),
        (Language::Rapid, "prog.mod", "prog", "rax_1..rax_6"),
        (Language::Tp, "prog.ls", "PROG", "J1..J6"),
    ] {
        let (code, err) = comp(d, &format!("--format {} --out {out}", language.as_str()));
        assert_eq!(code, 0, "{err}");
        assert!(err.contains(&format!("into {out}")), "{err}");
        let text = std::fs::read_to_string(d.join(out)).unwrap();
        let read = read_program(language, &text, out).unwrap();
        assert_eq!(read.name, name);
        assert_eq!((read.speed, read.zone), (100, Zone::Fine));
        assert_table(&format!("{out}, kinecal's reader"), &read.points, &t);
        assert_table(
            &format!("{out}, the test's reader"),
            &independent(language, &text),
            &t,
        );
        // The header says what the values are (TP's in remarks of 32 characters).
        let header = match language {
            Language::Tp => text
                .lines()
                .filter_map(|l| l.split_once(":  !").map(|(_, r)| r.trim_end_matches(" ;")))
                .collect::<Vec<_>>()
                .join(" "),
            _ => text.clone(),
        };
        assert!(
            header.contains(&format!(
                "{axes} (deg) are joints 1 to 6 of the robot file, taken as the axes of the \
                 controller"
            )),
            "{header}"
        );
        // Six decimals, no more, no fewer.
        let first = t[0][0];
        assert!(text.contains(&format!("{first:.6}")), "{first} {text}");
        match language {
            Language::Krl => {
                assert!(text.contains("\nDEF prog()\n"), "{text}");
                assert!(text.ends_with("\nEND\n"), "{text}");
                assert!(text.contains("$VEL_AXIS[I]=100"), "{text}");
                assert_eq!(text.matches("\nPTP {A1 ").count(), 50);
                assert!(!text.contains("C_PTP"), "{text}");
            }
            Language::Rapid => {
                assert!(text.starts_with("MODULE prog\n"), "{text}");
                assert!(text.ends_with("  ENDPROC\nENDMODULE\n"), "{text}");
                assert_eq!(
                    text.matches("],[9E9,9E9,9E9,9E9,9E9,9E9]]\\NoEOffs, v100, fine, tool0;\n")
                        .count(),
                    50
                );
            }
            Language::Tp => {
                assert!(text.starts_with("/PROG  PROG\n/ATTR\n"), "{text}");
                assert!(text.ends_with("};\n/END\n"), "{text}");
                for n in 1..=50 {
                    assert!(text.contains(&format!(":J P[{n}] 100% FINE    ;\n")), "{n}");
                    assert!(text.contains(&format!("\nP[{n}]{{\n   GP1:\n")), "{n}");
                }
                let remarks = text.lines().filter(|l| l.contains(":  !")).count();
                assert!(text.contains(&format!("LINE_COUNT\t= {};", 50 + remarks)));
                for l in text.lines().filter(|l| l.contains(":  !")) {
                    let remark = &l[l.find('!').unwrap() + 1..l.rfind(" ;").unwrap()];
                    assert!(remark.len() <= 32, "{l}");
                }
            }
        }
    }
}

/// Speed and zone in each language's words; the last move always stops exactly; a spec file
/// gives the same program as the flags.
#[test]
fn speed_and_zone_in_each_language() {
    let dir = setup();
    let d = dir.path();
    let (code, err) = comp(d, "--format krl --speed 50 --zone 10 --out k.src");
    assert_eq!(code, 0, "{err}");
    let krl = std::fs::read_to_string(d.join("k.src")).unwrap();
    assert!(krl.contains("  $VEL_AXIS[I]=50\n"), "{krl}");
    assert!(krl.contains("\n$APO.CPTP=10\n"), "{krl}");
    assert_eq!(krl.matches("} C_PTP\n").count(), 49);
    let p = read_program(Language::Krl, &krl, "k.src").unwrap();
    assert_eq!((p.speed, p.zone), (50, Zone::Blend(10)));

    let (code, err) = comp(d, "--format rapid --speed 200 --zone 10 --out r.mod");
    assert_eq!(code, 0, "{err}");
    let rapid = std::fs::read_to_string(d.join("r.mod")).unwrap();
    assert_eq!(rapid.matches(", v200, z10, tool0;\n").count(), 49);
    assert_eq!(rapid.matches(", v200, fine, tool0;\n").count(), 1);
    let p = read_program(Language::Rapid, &rapid, "r.mod").unwrap();
    assert_eq!((p.speed, p.zone), (200, Zone::Blend(10)));

    let (code, err) = comp(d, "--format tp --speed 30 --zone 0 --out t.ls");
    assert_eq!(code, 0, "{err}");
    let tp = std::fs::read_to_string(d.join("t.ls")).unwrap();
    assert_eq!(tp.matches("] 30% CNT0    ;\n").count(), 49);
    assert_eq!(tp.matches("] 30% FINE    ;\n").count(), 1);
    let p = read_program(Language::Tp, &tp, "t.ls").unwrap();
    assert_eq!((p.speed, p.zone), (30, Zone::Blend(0)));

    // The same from a spec file, the zone a word or a number.
    std::fs::remove_file(d.join("k.src")).unwrap();
    std::fs::write(
        d.join("k.toml"),
        "job = \"compensate\"\nrobot = \"true.toml\"\nnominal = \"irb120.toml\"\n\
         in = \"poses.csv\"\nformat = \"krl\"\nspeed = 50\nzone = 10\nout = \"k.src\"\n",
    )
    .unwrap();
    run_ok(d, &argv("compensate --spec k.toml"));
    assert_eq!(std::fs::read_to_string(d.join("k.src")).unwrap(), krl);
    std::fs::write(
        d.join("t.toml"),
        "job = \"compensate\"\nrobot = \"true.toml\"\nnominal = \"irb120.toml\"\n\
         in = \"poses.csv\"\nformat = \"tp\"\nzone = \"fine\"\nname = \"tp_prog\"\nout = \"t.ls\"\n",
    )
    .unwrap();
    run_ok(d, &argv("compensate --spec t.toml"));
    let tp = std::fs::read_to_string(d.join("t.ls")).unwrap();
    assert!(tp.starts_with("/PROG  TP_PROG\n"), "{tp}");
    assert_eq!(tp.matches("] 100% FINE    ;\n").count(), 50);

    // A program of one move: that move is the last, and stops exactly (KRL still states its
    // $APO.CPTP); each reads back as written.
    let poses = std::fs::read_to_string(d.join("poses.csv")).unwrap();
    let one: String = poses.lines().take(2).map(|l| format!("{l}\n")).collect();
    std::fs::write(d.join("one.csv"), one).unwrap();
    for (language, out, last) in [
        (Language::Krl, "one.src", "}\nEND\n"),
        (
            Language::Rapid,
            "one.mod",
            ", v100, fine, tool0;\n  ENDPROC\nENDMODULE\n",
        ),
        (Language::Tp, "one.ls", ":J P[1] 100% FINE    ;\n/POS\n"),
    ] {
        run_ok(
            d,
            &argv(&format!(
                "compensate --robot true.toml --nominal irb120.toml --in one.csv --format {}
                 --zone 10 --out {out}",
                language.as_str()
            )),
        );
        let text = std::fs::read_to_string(d.join(out)).unwrap();
        assert!(text.contains(last), "{text}");
        assert_eq!(read_program(language, &text, out).unwrap().points.len(), 1);
    }

    // On standard output, the program is named kinecal_program.
    let (code, out, err) = run(
        d,
        &argv("compensate --robot true.toml --nominal irb120.toml --in poses.csv --format krl --out -"),
    );
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("\nDEF kinecal_program()\n"), "{out}");
    assert!(read_program(Language::Krl, &out, "-").is_ok());
}

/// What a controller would not take is refused before anything is computed or written, with
/// the flag and the rule; a flagged row writes no program.
#[test]
fn what_a_controller_would_not_take_is_refused() {
    let dir = setup();
    let d = dir.path();
    let refused = |extra: &str, expected: &str| {
        let err = run_err(
            d,
            &argv(&format!(
                "compensate --robot true.toml --nominal irb120.toml --in poses.csv {extra}"
            )),
        );
        assert!(err.contains(expected), "{extra}: {err}");
        for f in [
            "p.src",
            "p.mod",
            "p.ls",
            "p.csv",
            "my-prog.src",
            "other.src",
        ] {
            assert!(!d.join(f).exists(), "{extra}: {f} written");
        }
    };
    // Speeds and zones.
    for s in ["0", "101", "7.5", "-1"] {
        refused(
            &format!("--format krl --speed {s} --out p.src"),
            "--speed: expected a whole percent from 1 to 100",
        );
    }
    refused(
        "--format tp --speed 150 --out p.ls",
        "--speed: expected a whole percent from 1 to 100 (TP",
    );
    refused(
        "--format rapid --speed 123 --out p.mod",
        "--speed: expected the TCP speed (mm/s) of a predefined RAPID speeddata: one of 5, 10",
    );
    refused(
        "--format rapid --zone 7 --out p.mod",
        "--zone: expected `fine` or the size (mm) of a predefined RAPID zonedata",
    );
    refused(
        "--format krl --zone 0 --out p.src",
        "--zone: expected `fine` or a whole percent from 1 to 100 (KRL C_PTP",
    );
    refused(
        "--format tp --zone 101 --out p.ls",
        "--zone: expected `fine` or a whole CNT value from 0 to 100",
    );
    refused(
        "--format tp --zone coarse --out p.ls",
        "--zone: expected `fine` or a number (the TP zone), not `coarse`",
    );
    for flag in ["--speed 50", "--zone 10", "--name p"] {
        refused(
            &format!("--format joints-kuka {flag} --out p.csv"),
            "is for a controller program: format krl, rapid or tp",
        );
    }
    // Names.
    refused(
        "--format krl --out my-prog.src",
        "--name: the program is named after its file my-prog.src: `my-prog` holds `-`",
    );
    refused(
        "--format krl --name other --out p.src",
        "--name: `other` is not the name of p.src: a KRL module's DEF names its file",
    );
    refused(
        "--format krl --name a_name_of_25_characters_x --out p.src",
        "has 25 characters: a KRL program name is letters, digits and _, a letter first, at \
         most 24 characters",
    );
    refused(
        "--format rapid --name 1st --out p.mod",
        "--name: `1st` does not begin with a letter",
    );
    refused(
        "--format rapid --name module --out p.mod",
        "--name: `module` is a reserved word of RAPID",
    );
    refused(
        "--format rapid --name main --out p.mod",
        "is a reserved word of RAPID (or a name the program uses: main, tool0, fine",
    );
    refused(
        "--format rapid --name a_name_that_is_33_characters_long --out p.mod",
        "at most 32 characters",
    );
    refused("--format tp --name tp.prog --out p.ls", "holds `.`");
    refused(
        "--format tp --name a_name_that_is_thirty_seven_characters --out p.ls",
        "at most 36 characters",
    );
    refused(
        "--format krl --name END --out END.src",
        "is a reserved word of KRL",
    );
    // A KRL module named as its file in another case is its file's name.
    run_ok(
        d,
        &argv("compensate --robot true.toml --nominal irb120.toml --in poses.csv --format krl --name PROG --out prog.src"),
    );
    assert!(std::fs::read_to_string(d.join("prog.src"))
        .unwrap()
        .contains("\nDEF PROG()\n"));

    // A robot of another number of joints (the IRB 120 with a seventh revolute joint):
    // these programs drive six axes; a prismatic joint has no angle at all.
    let irb = std::fs::read_to_string(d.join("irb120.toml")).unwrap();
    std::fs::write(
        d.join("irb7.toml"),
        format!(
            "{irb}\n[[links]]\nx = 0.0\ny = 0.0\nz = 0.05\nalpha = 0.0\nbeta = 0.0\n\
             gamma = 0.0\n\n[[joints]]\nkind = \"revolute\"\noffset = 0.0\nslope = 1.0\n"
        ),
    )
    .unwrap();
    std::fs::write(
        d.join("p7.csv"),
        "posture,v1,v2,v3,v4,v5,v6,v7\n1,0,0.1,0.2,0,0.3,0,0\n",
    )
    .unwrap();
    std::fs::write(d.join("p4.csv"), "posture,v1,v2,v3,v4\n1,0,10,20,0\n").unwrap();
    for (format, axes) in [
        ("krl", "A1..A6"),
        ("rapid", "rax_1..rax_6"),
        ("tp", "J1..J6"),
    ] {
        let err = run_err(
            d,
            &argv(&format!(
                "compensate --robot irb7.toml --nominal irb7.toml --in p7.csv --format {format}
                 --out p7.out"
            )),
        );
        assert!(
            err.contains(&format!(
                "--format: a {} program here drives the six axes of an arm ({axes}); this robot \
                 has 7 joints",
                format.to_uppercase()
            )),
            "{err}"
        );
        assert!(!d.join("p7.out").exists());
        let err = run_err(
            d,
            &argv(&format!(
                "compensate --robot ge-a4 --nominal ge-a4 --in p4.csv --format {format} --out p4.out"
            )),
        );
        assert!(err.contains("--format: joint 3 is prismatic"), "{err}");
        assert!(!d.join("p4.out").exists());
    }

    // A flagged row: no program, exit 3, the row named.
    let poses = std::fs::read_to_string(d.join("poses.csv")).unwrap();
    std::fs::write(d.join("far.csv"), format!("{poses}far,2,0,0.5,0,0,0\n")).unwrap();
    for (format, out) in [("krl", "far.src"), ("rapid", "far.mod"), ("tp", "far.ls")] {
        let o = kinecal()
            .current_dir(d)
            .args(argv(&format!(
                "compensate --robot true.toml --nominal irb120.toml --in far.csv --format {format} --out {out}"
            )))
            .output()
            .unwrap();
        let err = String::from_utf8(o.stderr).unwrap();
        assert_eq!(o.status.code(), Some(3), "{err}");
        assert!(err.contains(&format!("nothing written to {out}")), "{err}");
        assert!(err.contains("far: unreachable"), "{err}");
        assert!(!d.join(out).exists());
    }
}

/// kinecal's readers refuse what is not a program of theirs, naming the line.
#[test]
fn the_readers_name_the_line_of_a_damaged_program() {
    let krl = "DEF p()\nDECL INT I\nFOR I=1 TO 6\n  $VEL_AXIS[I]=100\n  $ACC_AXIS[I]=100\nENDFOR\n\
               PTP {A1 1, A2 2, A3 3, A4 4, A5 5, A6 6}\nEND\n";
    let p = read_program(Language::Krl, krl, "p.src").unwrap();
    assert_eq!(p.points, vec![[1.0, 2.0, 3.0, 4.0, 5.0, 6.0]]);
    for (bad, expected) in [
        (
            krl.replace("A6 6", "A6 x"),
            "p.src:7: field `A6`: expected a number of degrees",
        ),
        (krl.replace(", A6 6", ""), "p.src:7: no A6"),
        (
            krl.replace("A6 6", "A7 6"),
            "p.src:7: `A7` is no axis A1..A6",
        ),
        (krl.replace("END\n", ""), "DEF p: no END"),
        (
            krl.replace("DECL INT I", "LIN P1"),
            "p.src:2: unexpected statement `LIN P1`",
        ),
    ] {
        let e = read_program(Language::Krl, &bad, "p.src")
            .unwrap_err()
            .to_string();
        assert!(e.contains(expected), "{e}");
    }
    let rapid = "MODULE m\n  PROC main()\n    MoveAbsJ [[1,2,3,4,5,6],[9E9,9E9,9E9,9E9,9E9,9E9]]\\NoEOffs, v100, fine, tool0;\n  ENDPROC\nENDMODULE\n";
    assert!(read_program(Language::Rapid, rapid, "m.mod").is_ok());
    for (bad, expected) in [
        (
            rapid.replace("[1,2,3,4,5,6]", "[1,2,3,4,5]"),
            "m.mod:3: robax has 5 values",
        ),
        (rapid.replace("[9E9,9E9", "[0,9E9"), "m.mod:3: extax"),
        (
            rapid.replace("fine, tool0;", "fine, tool0"),
            "m.mod:3: a statement ends with `;`",
        ),
        (rapid.replace("ENDMODULE\n", ""), "no ENDPROC and ENDMODULE"),
    ] {
        let e = read_program(Language::Rapid, &bad, "m.mod")
            .unwrap_err()
            .to_string();
        assert!(e.contains(expected), "{e}");
    }
    let tp = "/PROG  P\n/ATTR\n/MN\n   1:J P[1] 100% FINE    ;\n/POS\nP[1]{\n   GP1:\n\tUF : 0, UT : 1,\t\n\
              \tJ1=  1.0 deg,\tJ2=  2.0 deg,\tJ3=  3.0 deg,\n\tJ4=  4.0 deg,\tJ5=  5.0 deg,\tJ6=  6.0 deg\n};\n/END\n";
    let p = read_program(Language::Tp, tp, "p.ls").unwrap();
    assert_eq!(p.points, vec![[1.0, 2.0, 3.0, 4.0, 5.0, 6.0]]);
    for (bad, expected) in [
        (
            tp.replace("J P[1]", "J P[2]"),
            "p.ls:4: P[2] is not in /POS",
        ),
        (
            tp.replace("   1:J", "   2:J"),
            "p.ls:4: line number `2`: expected 1",
        ),
        (
            tp.replace("J6=  6.0 deg", "X = 6.0 mm"),
            "`X`: expected J1..J6",
        ),
        (tp.replace("/END\n", ""), "no /END"),
    ] {
        let e = read_program(Language::Tp, &bad, "p.ls")
            .unwrap_err()
            .to_string();
        assert!(e.contains(expected), "{e}");
    }
}

/// The name a controller takes is the name of the file written: through a symbolic link, the
/// link's target (the writer writes there; before, the KRL `DEF` named the link, and the
/// controller would refuse the file), made yet or not; and a batch's compensation job named
/// `name` writes the program its spec run alone writes (before, the batch took the name as
/// the job's label only, and the program was named after its file).
#[test]
fn a_program_is_named_after_the_file_written_and_a_batch_names_it_as_its_spec() {
    let dir = setup();
    let d = dir.path();
    std::os::unix::fs::symlink("target.src", d.join("link.src")).unwrap();
    for round in ["made by the run", "there already"] {
        let (code, err) = comp(d, "--format krl --out link.src");
        assert_eq!(code, 0, "{round}: {err}");
        assert!(d.join("link.src").is_symlink());
        let text = std::fs::read_to_string(d.join("target.src")).unwrap();
        assert!(text.contains("DEF target()"), "{round}: {text}");
    }
    let (code, err) = comp(d, "--format krl --name link --out link.src");
    assert_eq!(code, 1);
    assert!(
        err.contains("is not the name of link.src (a link to"),
        "{err}"
    );
    let job = "job = \"compensate\"\nname = \"cell5\"\nrobot = \"true.toml\"\n\
               nominal = \"irb120.toml\"\nin = \"poses.csv\"\nformat = \"rapid\"\n";
    std::fs::write(d.join("one.toml"), format!("{job}out = \"alone.mod\"\n")).unwrap();
    run_ok(d, &argv("compensate --spec one.toml"));
    std::fs::write(
        d.join("jobs.toml"),
        format!(
            "[[jobs]]\n{job}out = \"batch.mod\"\n\n[[jobs]]\n{}out = \"table.csv\"\n",
            job.replace("format = \"rapid\"\n", "")
                .replace("cell5", "as a table")
        ),
    )
    .unwrap();
    let (code, out, err) = run(d, &argv("batch jobs.toml"));
    assert_eq!(code, 0, "{out}{err}");
    let alone = std::fs::read_to_string(d.join("alone.mod")).unwrap();
    let batch = std::fs::read_to_string(d.join("batch.mod")).unwrap();
    assert!(alone.contains("MODULE cell5"), "{alone}");
    let strip = |t: &str| t.replace("alone.mod", "X").replace("batch.mod", "X");
    assert_eq!(strip(&alone), strip(&batch));
    // A table is no program: the name stays the job's label alone.
    assert!(
        out.contains("as a table") && d.join("table.csv").exists(),
        "{out}"
    );
}

/// The poses (`x..gamma`) of an `fk` output, row by row.
fn poses(d: &Path, file: &str) -> Vec<[f64; 6]> {
    let text = std::fs::read_to_string(d.join(file)).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let x = header.iter().position(|h| *h == "x").unwrap();
    lines
        .map(|l| {
            let v: Vec<f64> = l.split(',').skip(x).map(|v| v.parse().unwrap()).collect();
            v.try_into().unwrap()
        })
        .collect()
}

/// `kinecal fk` reads every table `kinecal compensate` writes, as the docs say: the plain table
/// (its remaining errors and flags read past, with a note naming them) and the joint targets of
/// each brand (`joints-ur|abb|kuka|fanuc`, in the brand's names and unit), and through the
/// true robot each lands on the targets. A program is refused with the tables it does read
/// named (before, every `joints-*` table was refused as an "unexpected header", the message
/// saying fk read "what `kinecal compensate` writes").
#[test]
fn fk_reads_every_table_compensate_writes() {
    let dir = setup();
    let d = dir.path();
    let targets = table(d, "poses.csv");
    for format in [
        "table",
        "joints-ur",
        "joints-abb",
        "joints-kuka",
        "joints-fanuc",
    ] {
        let (code, err) = comp(d, &format!("--format {format} --out {format}.csv"));
        assert_eq!(code, 0, "{format}: {err}");
        let (code, _, err) = run(
            d,
            &argv(&format!(
                "fk --robot true.toml --postures {format}.csv --out {format}_fk.csv"
            )),
        );
        assert_eq!(code, 0, "{format}: {err}");
        assert!(
            err.contains(&format!("wrote 50 poses to {format}_fk.csv")),
            "{err}"
        );
        let read_past = format!(
            "{format}.csv: columns `position_error`, `attitude_error`, `iterations`, `flags` are \
             what `kinecal compensate` adds (its remaining errors and flags): read past"
        );
        assert_eq!(
            err.contains(&read_past),
            format == "table",
            "{format}: {err}"
        );
        let landed = poses(d, &format!("{format}_fk.csv"));
        assert_eq!(landed.len(), targets.len(), "{format}");
        for (i, (a, b)) in landed.iter().zip(&targets).enumerate() {
            for k in 0..6 {
                // Ten decimals of a radian (UR) move the tool by less than 1e-9 m.
                let d = (a[k] - b[k]).abs();
                let d = if k < 3 {
                    d
                } else {
                    d.min(std::f64::consts::TAU - d)
                };
                assert!(d < 1e-8, "{format}: row {}, {k}: {a:?} {b:?}", i + 1);
            }
        }
    }
    // A program is not a table: the message names what fk reads, for this robot.
    let (code, err) = comp(d, "--format krl --out prog.src");
    assert_eq!(code, 0, "{err}");
    let err = run_err(d, &argv("fk --robot true.toml --postures prog.src"));
    for said in [
        "prog.src:1: unexpected header",
        "a table of `kinecal compensate`: `--format table`, `joints-ur` (`base..wrist3` in rad), \
         `joints-abb` (`rax_1..rax_6` in deg), `joints-kuka` (`A1..A6` in deg) or \
         `joints-fanuc` (`J1..J6` in deg); not its programs",
    ] {
        assert!(err.contains(said), "{err}");
    }
}

/// A robot whose joints are named as a brand names its joint targets (`J1..J6`, FANUC's) but in
/// another unit (radians, FANUC's are degrees): a file headed `J1..J6` could be either, so `fk`,
/// `compensate` and the postures readers (`analyze` here) refuse it, saying how to tell (before, `fk` read the
/// `joints-fanuc` table's degrees as radians, every joint moved, exit 0). With `v1..v6` the
/// same readings are read, and the robot without names reads the FANUC table as FANUC's.
#[test]
fn joint_names_that_are_a_brands_in_another_unit_are_refused() {
    let dir = setup();
    let d = dir.path();
    let text = std::fs::read_to_string(d.join("true.toml")).unwrap();
    let mut named = String::new();
    for (k, part) in text.split("[[joints]]\n").enumerate() {
        if k > 0 {
            named += &format!("[[joints]]\nname = \"J{k}\"\n");
        }
        named += part;
    }
    std::fs::write(d.join("named.toml"), named).unwrap();
    let (code, err) = comp(d, "--format joints-fanuc --out fanuc.csv");
    assert_eq!(code, 0, "{err}");
    let said = "fanuc.csv:1: the columns `J1..J6` are this robot's joint names (readings in rad) \
                and FANUC's joint targets too (`kinecal compensate --format joints-fanuc` \
                writes them in deg): the file's unit cannot be told; head the readings `v1..v6` \
                (in rad), or give the robot's joints other names";
    for line in [
        "fk --robot named.toml --postures fanuc.csv --out named_fk.csv",
        "compensate --robot named.toml --nominal named.toml --in fanuc.csv --out c.csv",
        "analyze --robot named.toml --postures fanuc.csv",
    ] {
        let err = run_err(d, &argv(line));
        assert!(err.contains(said), "{line}: {err}");
    }
    for file in ["named_fk.csv", "c.csv"] {
        assert!(!d.join(file).exists(), "{file}");
    }
    // Read by the robot without names, the table is FANUC's: the true robot lands on the
    // targets.
    run_ok(
        d,
        &argv("fk --robot true.toml --postures fanuc.csv --out fanuc_fk.csv"),
    );
    let targets = table(d, "poses.csv");
    for (a, b) in poses(d, "fanuc_fk.csv").iter().zip(&targets) {
        assert!((a[0] - b[0]).abs() < 1e-8, "{a:?} {b:?}");
    }
    // The same readings headed `v1..v6`, in radians, read by the named robot: the same poses.
    let fk = std::fs::read_to_string(d.join("fanuc_fk.csv")).unwrap();
    let mut postures = String::from("posture,v1,v2,v3,v4,v5,v6\n");
    for l in fk.lines().skip(1) {
        let f: Vec<&str> = l.split(',').collect();
        postures += &format!("{},{}\n", f[0], f[2..8].join(","));
    }
    std::fs::write(d.join("v.csv"), postures).unwrap();
    run_ok(
        d,
        &argv("fk --robot named.toml --postures v.csv --out v_fk.csv"),
    );
    for (a, b) in poses(d, "v_fk.csv").iter().zip(&targets) {
        for k in 0..3 {
            assert!((a[k] - b[k]).abs() < 1e-8, "{a:?} {b:?}");
        }
    }
}
