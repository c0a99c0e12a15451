//! The model beyond the thesis: coupled joints and planes, in robot files and parameter lists.

use kinecal::model::robot_file::{parse_robot_toml, write_robot_toml};
use kinecal::{model::examples, parse_param_list, ParamId};
use nalgebra::Vector3;

/// The GE A4 with joint 3 coupled to joint 2 and a table plane.
fn coupled_a4() -> String {
    examples::GE_A4_TOML.replacen(
        "kind = \"prismatic\"",
        "kind = \"prismatic\"\ncoupling = { joint = 2, factor = 0.5 }  # in per unit of V2",
        1,
    ) + "\n# The table.\n[[planes]]\nname = \"table\"\nnormal = [0, 0, 2]\noffset = -3.5\n"
}

#[test]
fn couplings_and_planes_extend_the_numbering_without_changing_the_thesis_ids() {
    let plain = examples::ge_a4();
    let r = parse_robot_toml(&coupled_a4(), "a4.toml").unwrap();
    assert_eq!(plain.param_count(), 38);
    assert_eq!(r.param_count(), 38 + 1 + 3);
    for id in plain.param_ids() {
        assert_eq!(plain.param_name(id), r.param_name(id));
        assert_eq!(plain.get(id).to_bits(), r.get(id).to_bits());
    }
    assert_eq!(r.param_name(ParamId(38)), "joint3.coupling");
    assert_eq!(r.param_unit(ParamId(38)), "in/unit");
    assert!((r.get_user(ParamId(38)) - 0.5).abs() < 1e-12);
    assert_eq!(r.param_name(ParamId(39)), "plane.table.tilt_x");
    assert_eq!(r.param_name(ParamId(41)), "plane.table.offset");
    assert!((r.get_user(ParamId(41)) + 3.5).abs() < 1e-12);
    assert_eq!(
        parse_param_list("joint3.coupling", &r).unwrap(),
        vec![ParamId(38)]
    );
    assert_eq!(
        parse_param_list("couplings,planes", &r).unwrap(),
        (38..42).map(ParamId).collect::<Vec<_>>()
    );
    assert_eq!(
        parse_param_list("joint3", &r).unwrap(),
        vec![ParamId(32), ParamId(36), ParamId(38)]
    );
    assert_eq!(
        parse_param_list("plane.table", &r).unwrap(),
        vec![ParamId(39), ParamId(40), ParamId(41)]
    );
    let e = parse_param_list("joint2.coupling", &r).unwrap_err();
    assert!(e.to_string().contains("not coupled"), "{e}");
    // The joint value: q3 = offset + slope V3 + 0.5 in/unit * V2.
    let v = [1.0, 2.0, 3.0, 4.0];
    let j = &r.joints[2];
    let expected = j.offset + j.slope * 3.0 + 0.5 * 0.0254 * 2.0;
    assert!((j.value(&v, 2) - expected).abs() < 1e-15);
}

#[test]
fn couplings_and_planes_round_trip_through_the_file_keeping_comments() {
    let text = coupled_a4();
    let mut r = parse_robot_toml(&text, "a4.toml").unwrap();
    r.set(ParamId(38), 0.01);
    r.set(ParamId(39), 0.1);
    r.set(ParamId(41), -0.1);
    let out = write_robot_toml(&r, Some(&text));
    assert!(out.contains("# in per unit of V2"), "{out}");
    assert!(out.contains("# The table."), "{out}");
    let back = parse_robot_toml(&out, "b.toml").unwrap();
    assert!((back.get(ParamId(38)) - 0.01).abs() < 1e-12);
    // The tilted normal is written; read back, its tilts are 0 about a new reference.
    let (n0, n1) = (r.planes[0].normal(), back.planes[0].normal());
    assert!((n0 - n1).norm() < 1e-10, "{n0} vs {n1}");
    assert!((back.planes[0].offset + 0.1).abs() < 1e-12);
    // A robot without couplings or planes keeps its file as it was.
    let plain = examples::ge_a4();
    assert!(!write_robot_toml(&plain, Some(examples::GE_A4_TOML)).contains("plane"));
}

#[test]
fn plane_normal_parameterisation_is_regular_and_invertible() {
    for n in [
        Vector3::z(),
        -Vector3::y(),
        Vector3::new(0.3, -0.5, 0.8),
        Vector3::x(),
    ] {
        let mut p = kinecal::model::robot::Plane::new("p", n * 3.0, 0.2).unwrap();
        assert!((p.normal() - n.normalize()).norm() < 1e-15);
        // The reference frame is right-handed and orthonormal.
        let r = p.reference();
        assert!((r.transpose() * r - nalgebra::Matrix3::identity()).norm() < 1e-14);
        assert!((r.determinant() - 1.0).abs() < 1e-14);
        // Derivatives against central differences.
        p.tilt_x = 0.2;
        p.tilt_y = -0.3;
        let d = p.normal_derivatives();
        let h = 1e-6;
        for (k, dk) in d.iter().enumerate() {
            let (mut a, mut b) = (p.clone(), p.clone());
            if k == 0 {
                a.tilt_x += h;
                b.tilt_x -= h;
            } else {
                a.tilt_y += h;
                b.tilt_y -= h;
            }
            let fd = (a.normal() - b.normal()) / (2.0 * h);
            assert!((fd - dk).norm() < 1e-9, "{fd} vs {dk}");
        }
        // set_normal inverts normal().
        let target = p.normal();
        let mut q = kinecal::model::robot::Plane::new("q", n, 0.0).unwrap();
        assert!(q.set_normal(&target));
        assert!((q.tilt_x - 0.2).abs() < 1e-12 && (q.tilt_y + 0.3).abs() < 1e-12);
        assert!(!q.set_normal(&-n));
    }
    // A horizontal table tilts about the global axes.
    let p = kinecal::model::robot::Plane::new("t", Vector3::z(), 0.0).unwrap();
    assert_eq!(p.reference().column(0), Vector3::x());
    assert_eq!(p.reference().column(1), Vector3::y());
}

#[test]
fn bad_couplings_and_planes_are_refused_with_their_field() {
    let cases = [
        (
            examples::GE_A4_TOML.replacen(
                "kind = \"prismatic\"",
                "kind = \"prismatic\"\ncoupling = { joint = 3 }",
                1,
            ),
            "bad.toml:69: field `joints[2].coupling.joint`: joint 3 cannot be coupled to itself",
        ),
        (
            examples::GE_A4_TOML.replacen(
                "kind = \"prismatic\"",
                "kind = \"prismatic\"\ncoupling = { joint = 7 }",
                1,
            ),
            "field `joints[2].coupling.joint`: joint 3: there is no joint 7 (the robot has joints 1..4)",
        ),
        (
            examples::GE_A4_TOML.replacen(
                "kind = \"prismatic\"",
                "kind = \"prismatic\"\ncoupling = { joint = 2, gain = 1 }",
                1,
            ),
            "joints[2].coupling.gain",
        ),
        (
            examples::GE_A4_TOML.replacen(
                "kind = \"prismatic\"",
                "kind = \"prismatic\"\ncoupling = 2",
                1,
            ),
            "joints[2].coupling",
        ),
        (
            examples::GE_A4_TOML.to_string() + "\n[[planes]]\nname = \"t\"\nnormal = [0, 0, 0]\noffset = 0\n",
            "planes[0].normal",
        ),
        (
            examples::GE_A4_TOML.to_string() + "\n[[planes]]\nname = \"t\"\n",
            "planes[0].normal",
        ),
        (
            examples::GE_A4_TOML.to_string() + "\n[[planes]]\nname = \"t\"\nnormal = [0, 0, 1]\n",
            "planes[0].offset`: missing `offset`",
        ),
        (
            examples::GE_A4_TOML.to_string()
                + "\n[[planes]]\nname = \"t\"\nnormal = [0, 0, 1]\noffset = 0\n[[planes]]\nname = \"t\"\nnormal = [0, 1, 0]\noffset = 0\n",
            "used twice",
        ),
    ];
    for (text, expect) in cases {
        let e = parse_robot_toml(&text, "bad.toml").unwrap_err().to_string();
        assert!(e.contains(expect), "expected `{expect}` in: {e}");
        assert!(e.starts_with("bad.toml"), "{e}");
    }
}

/// A perturbed coupling factor is recovered, and counts one in the rank like a slope.
#[test]
fn a_perturbed_coupling_factor_is_recovered() {
    use kinecal::apps::simulate;
    use kinecal::identifiability::{analyze, AnalysisOptions};
    use kinecal::model::robot::Coupling;
    use kinecal::solve::estimation::{calibrate, CalibrationOptions};
    let mut nominal = simulate::random_robot(&[kinecal::JointKind::Revolute; 6], 41);
    nominal.joints[2].coupling = Some(Coupling {
        joint: 1,
        factor: nominal.joints[2].slope,
    });
    let coupling = parse_param_list("joint3.coupling", &nominal).unwrap()[0];
    let mut truth = simulate::perturb(
        &nominal,
        simulate::PerturbStd {
            length: 1e-3,
            angle: 0.2f64.to_radians(),
            slope_fraction: 0.0,
        },
        2,
    );
    truth.set(coupling, nominal.get(coupling) * 1.02);
    let data = simulate::measure(&truth, &simulate::sample_postures(&nominal, 40, 3), false);
    let candidates = parse_param_list("links,offsets,joint3.coupling", &nominal).unwrap();
    let a = analyze(&nominal, &data, &candidates, &AnalysisOptions::default()).unwrap();
    let expected = a.expected.as_ref().unwrap();
    assert_eq!(expected.rank, 4 * 6 + 6 + 1, "{}", expected.formula);
    assert!(
        expected.formula.contains("1 (couplings)"),
        "{}",
        expected.formula
    );
    assert_eq!(a.rank, expected.rank);
    assert!(a.identifiable.contains(&coupling));
    let cal = calibrate(
        &nominal,
        &data,
        &CalibrationOptions::new(a.identifiable.clone()),
        &mut |_| {},
    )
    .unwrap();
    assert!(cal.objective_after < 1e-16 * cal.objective_before);
    let (got, want) = (cal.calibrated.get(coupling), truth.get(coupling));
    assert!((got - want).abs() < 1e-9 * want.abs(), "{got} vs {want}");
}
