//! Measurement sessions: an instrument moved between series of measurements, each series in its
//! own measurement frame. The frames are placed in closed form and estimated with the robot;
//! data from a session identification never saw is checked after its frame is re-estimated on
//! it.

use std::sync::Arc;

use kinecal::apps::simulate::{self, PerturbStd};
use kinecal::files::{parse_measurements, write_measurements};
use kinecal::model::robot::{Link, Session};
use kinecal::model::robot_file::{parse_robot_toml, write_robot_toml};
use kinecal::workflow::{self, Request, Selection, Validation};
use kinecal::{parse_param_list, Dataset, JointKind, Robot};

/// A frame metres away and turned, as a tracker set up elsewhere sees the robot.
fn far_frame(k: f64) -> Link {
    Link {
        x: 2.5 * k,
        y: -1.5 + k,
        z: -1.2,
        alpha: 2.6 * k,
        beta: 0.05,
        gamma: -0.1 * k,
    }
}

/// Noisy position data of `truth` at `n` postures, measured in session `name` (whose frame
/// `truth` holds, unless it is its global frame).
fn series(truth: &Robot, n: usize, seed: u64, name: &str) -> Dataset {
    let mut postures = simulate::sample_postures(truth, n, seed);
    for p in &mut postures {
        p.session = Some(Arc::from(name));
    }
    let mut data = simulate::measure(truth, &postures, true);
    simulate::add_noise(&mut data, 5e-5, 0.0, seed + 1);
    data
}

fn nominal_and_truth() -> (Robot, Robot) {
    let nominal = simulate::random_robot(&[JointKind::Revolute; 6], 31);
    let mut truth = simulate::perturb(
        &nominal,
        PerturbStd {
            length: 0.002,
            angle: 0.004,
            slope_fraction: 0.0,
        },
        32,
    );
    truth.sessions = vec![
        Session {
            name: "B".into(),
            frame: far_frame(1.0),
        },
        Session {
            name: "C".into(),
            frame: far_frame(-0.7),
        },
    ];
    (nominal, truth)
}

/// Two sessions in one calibration, the second measured from 3 m away and turned 2.6 rad: the
/// model gains a frame for it, placed in closed form and estimated with the robot; the fit
/// reaches the noise and finds the second session's frame where it is.
#[test]
fn a_second_session_gets_a_frame_estimated_with_the_robot() {
    let (nominal, truth) = nominal_and_truth();
    // The global frame is session A's: the truth's link 1 as it stands.
    let data = series(&truth, 40, 1, "A").merge(series(&truth, 40, 2, "B"));
    assert_eq!(data.sessions().len(), 2);
    let mut req = Request::new(nominal.clone(), data);
    req.selection = Selection::Identifiable {
        with: vec![],
        fix: vec![],
    };
    let out = workflow::run(&req, &mut ()).unwrap();
    let cal = &out.calibration;
    assert!(cal.converged(), "{:?}", cal.termination);
    assert!(cal.iterations <= 30, "{} iterations", cal.iterations);
    assert_eq!(cal.calibrated.sessions.len(), 1);
    assert_eq!(cal.calibrated.sessions[0].name, "B");
    let (got, want) = (&cal.calibrated.sessions[0].frame, &truth.sessions[0].frame);
    assert!(
        (got.x - want.x).abs() < 1e-3 && (got.alpha - want.alpha).abs() < 1e-3,
        "{got:?} vs {want:?}"
    );
    // At the noise (0.05 mm per coordinate: 0.087 mm RMS in 3D).
    assert!(
        cal.accuracy_after.rms_position < 1.2e-4,
        "{}",
        cal.accuracy_after.rms_position
    );
    // The session's parameters are named and listed in the report.
    assert!(out
        .report
        .parameters
        .iter()
        .any(|p| p.name == "session.B.alpha" && p.estimated_flag));
}

/// Identified on session A, validated on C (a session identification never saw, 2 m away):
/// without its frame the check would report metres; with it re-estimated on C (6 parameters),
/// the held-out error is at the noise, and the report says which session was refitted.
#[test]
fn a_validation_session_identification_never_saw_is_refitted() {
    let (nominal, truth) = nominal_and_truth();
    let ident = series(&truth, 60, 3, "A");
    let held = series(&truth, 30, 4, "C");
    let mut req = Request::new(nominal, ident);
    req.selection = Selection::Identifiable {
        with: vec![],
        fix: vec![],
    };
    req.validation = Validation::Data(Arc::new(held));
    let out = workflow::run(&req, &mut ()).unwrap();
    let v = out.validation.as_ref().unwrap();
    assert!(v.after.rms_position < 1.5e-4, "{}", v.after.rms_position);
    let rep = out.report.validation.as_ref().unwrap();
    assert_eq!(rep.sessions_refitted, ["C"]);
    // The calibrated robot itself gains no frame for C (it was only checked there).
    assert!(out.calibration.calibrated.session_index("C").is_none());
}

/// Sessions survive the robot file and the measurement file; their parameters have names and
/// a group.
#[test]
fn sessions_in_files_and_parameter_lists() {
    let (_, truth) = nominal_and_truth();
    let text = write_robot_toml(&truth, None);
    assert!(text.contains("[[sessions]]"), "{text}");
    let back = parse_robot_toml(&text, "r.toml").unwrap();
    assert_eq!(back.sessions.len(), 2);
    assert!((back.sessions[1].frame.alpha - truth.sessions[1].frame.alpha).abs() < 1e-12);
    let ids = parse_param_list("sessions", &truth).unwrap();
    assert_eq!(ids.len(), 12);
    assert_eq!(
        parse_param_list("session.C.gamma", &truth).unwrap(),
        [ids[11]]
    );
    assert!(parse_param_list("session.Z", &truth).is_err());
    // A session column reads back; a posture in two sessions is refused.
    let csv = "posture,session,v1,v2,v3,v4,v5,v6,x,y,z\n\
               1,A,0.1,0.2,0.3,0.4,0.5,0.6,1,2,3\n\
               2,B,0.2,0.2,0.3,0.4,0.5,0.6,1,2,3\n";
    let data = parse_measurements(csv, "s.csv", &truth).unwrap();
    assert_eq!(
        data.sessions()
            .iter()
            .map(|s| s.to_string())
            .collect::<Vec<_>>(),
        ["A", "B"]
    );
    let bad = "posture,session,v1,v2,v3,v4,v5,v6,x,y,z\n\
               1,A,0.1,0.2,0.3,0.4,0.5,0.6,1,2,3\n\
               1,B,0.1,0.2,0.3,0.4,0.5,0.6,1,2,4\n";
    let err = parse_measurements(bad, "s.csv", &truth)
        .unwrap_err()
        .to_string();
    assert!(err.contains("s.csv:3") && err.contains("session"), "{err}");
    // Written measurements keep their sessions.
    let written = write_measurements(&truth, &data);
    let back = parse_measurements(&written, "w.csv", &truth).unwrap();
    assert_eq!(back.sessions(), data.sessions());
}
