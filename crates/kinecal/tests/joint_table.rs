//! Joint offset and gain tables: exact when a calibration changed only the transducers, and
//! otherwise saying how much the table cannot carry.

use kinecal::import::joints::joint_table;
use kinecal::import::readback::Tolerance;
use kinecal::model::examples;

#[test]
fn a_joint_table_carries_the_transducers_and_says_what_it_cannot() {
    let nominal = examples::ge_a4();
    let mut cal = nominal.clone();
    cal.joints[1].offset += 0.5f64.to_radians();
    cal.joints[3].slope *= 1.002;
    let e = joint_table(&cal, &nominal).unwrap();
    let (text, lost) = (e.text.clone(), e.lost.clone());
    assert!(lost.is_none(), "{lost:?}");
    // Read back onto the nominal robot, as the command line does before writing: exact.
    assert!(e.read_back.position < 1e-12, "{:?}", e.read_back);
    e.check(&cal, &Tolerance::default_for(&cal)).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines[0], "joint,offset,slope,offset_change,slope_change");
    assert_eq!(lines.len(), 5);
    // Joint 2's offset change in the file's unit (deg).
    let f: Vec<f64> = lines[2].split(',').map(|v| v.parse().unwrap()).collect();
    assert!((f[3] - 0.5).abs() < 1e-12, "{}", lines[2]);
    // The table read back into the nominal robot gives the calibrated one.
    let mut applied = nominal.clone();
    for (j, l) in lines[1..].iter().enumerate() {
        let f: Vec<f64> = l.split(',').map(|v| v.parse().unwrap()).collect();
        let k = applied.joints[j].kind;
        applied.joints[j].offset = applied.units.to_si(k.variable(), f[1]);
        applied.joints[j].slope = applied.units.to_si(k.slope(), f[2]);
    }
    let (p, a) = kinecal::import::deviation(&cal, &applied);
    assert!(p < 1e-12 && a < 1e-12, "{p} {a}");

    // A link change cannot be carried: named, with the deviation it leaves at the tool.
    cal.links[2].y += 0.01 * 0.0254; // 0.01 in
    let e = joint_table(&cal, &nominal).unwrap();
    let lost = e.lost.clone().expect("a link change is lost");
    assert!(lost.what.contains("link"));
    assert!((lost.position - 0.01 * 0.0254).abs() < 1e-9, "{lost:?}");
    // Beyond the default tolerance: refused, naming it; a looser one takes it.
    let err = e
        .check(&cal, &Tolerance::default_for(&cal))
        .unwrap_err()
        .to_string();
    assert!(err.contains("link and tool changes"), "{err}");
    e.check(
        &cal,
        &Tolerance {
            position: 0.001,
            attitude: 1e-3,
        },
    )
    .unwrap();
}
