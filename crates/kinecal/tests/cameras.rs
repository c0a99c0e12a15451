//! Cameras and boards (issue 40): the pixel residual's derivatives, the files, and hand-eye
//! calibration from nothing, eye-in-hand and eye-to-hand, with the robot's kinematics or without.
//!
//! The set-up: an ABB IRB 120 (the data sheet's geometry), a 9 x 6 board of 25 mm, a 640 x 480
//! camera with fx 600, fy 610 and k1 = -0.2, 25-30 views drawn about a posture that sees the
//! board, 0.3 px of noise; the camera's and the board's poses start at zero.

use std::sync::Arc;

use kinecal::apps::simulate;
use kinecal::model::camera::{Board, Camera, Mount};
use kinecal::model::kinematics::{euler_zyx, Chain, Frame, Target, Workspace};
use kinecal::model::robot::Link;
use kinecal::observe::{Dataset, Noise, OrientationError, Posture, Weights};
use kinecal::predict::pixel::lateral_errors;
use kinecal::predict::Bound;
use kinecal::solve::problem::Problem;
use kinecal::workflow::{run, Request, Selection};
use kinecal::{ParamId, Robot};
use nalgebra::{Matrix3, Rotation3, Vector3};

const PIXEL_NOISE: f64 = 0.3;

fn irb120() -> Robot {
    kinecal::model::robot_file::parse_robot_toml(
        include_str!("../../../examples/robots/abb_irb120.toml"),
        "abb_irb120.toml",
    )
    .unwrap()
}

fn link_of(f: &Frame) -> Link {
    let e = euler_zyx(&f.rotation);
    Link {
        x: f.translation.x,
        y: f.translation.y,
        z: f.translation.z,
        alpha: e.x,
        beta: e.y,
        gamma: e.z,
    }
}

fn rot(alpha: f64, beta: f64, gamma: f64) -> Matrix3<f64> {
    *Rotation3::from_euler_angles(gamma, beta, alpha).matrix()
}

/// The posture every view is drawn about: the arm reaching forward, the flange tilted down.
const HOME: [f64; 6] = [0.0, 0.3, 0.2, 0.0, 0.6, 0.0];

fn ee_at(robot: &Robot, readings: &[f64]) -> Frame {
    let chain = Chain::new(robot);
    let mut ws = Workspace::new(robot);
    chain.forward(readings, &mut ws);
    chain.target_frame(&ws, Target::EndEffector)
}

fn camera(mount: Mount, pose: Link) -> Camera {
    Camera {
        name: "wrist".into(),
        mount,
        pose,
        fx: 600.0,
        fy: 610.0,
        cx: 320.0,
        cy: 240.0,
        distortion: [-0.2, 0.0, 0.0, 0.0, 0.0],
        width: 640,
        height: 480,
    }
}

fn board(mount: Mount, pose: Link) -> Board {
    Board {
        name: "board".into(),
        mount,
        pose,
        cols: 9,
        rows: 6,
        spacing: 0.025,
    }
}

/// The board's frame with its centre at `centre`, square to a camera of attitude `camera`
/// (tilted a few degrees), turned by `twist` about the optical axis.
fn facing(centre: Vector3<f64>, camera: &Matrix3<f64>, twist: f64) -> Frame {
    // The board's axes: x and y along the camera's (turned), z towards the camera.
    let r = camera * rot(twist, 0.08, -0.05);
    let half = Vector3::new(4.0 * 0.025, 2.5 * 0.025, 0.0);
    Frame {
        rotation: r,
        translation: centre - r * half,
    }
}

/// The true robot of a case: eye-in-hand (camera on the flange, board on the floor in front)
/// or eye-to-hand (board on the flange, camera fixed looking at it).
fn truth(eye_in_hand: bool) -> Robot {
    let mut robot = irb120();
    let home = ee_at(&robot, &HOME);
    let hand_eye = Link {
        x: 0.03,
        y: -0.05,
        z: 0.04,
        alpha: 0.05,
        beta: -0.03,
        gamma: 0.02,
    };
    if eye_in_hand {
        let cam = home.then(&Frame::from_link(&hand_eye));
        let centre = cam.translation + cam.rotation * Vector3::new(0.0, 0.0, 0.45);
        let b = facing(centre, &cam.rotation, 0.3);
        robot.cameras.push(camera(Mount::EndEffector, hand_eye));
        robot.boards.push(board(Mount::Base, link_of(&b)));
    } else {
        let on_flange = Frame {
            rotation: rot(0.2, 0.0, 0.0),
            translation: Vector3::new(-0.1, -0.06, 0.03),
        };
        let b = home.then(&on_flange);
        let centre = b.rotation * Vector3::new(0.1, 0.0625, 0.0) + b.translation;
        // The camera 0.6 m out along the board's normal, looking back at it.
        let normal = b.rotation * Vector3::z();
        let z = -normal;
        let x = (b.rotation * Vector3::x() - z * z.dot(&(b.rotation * Vector3::x()))).normalize();
        let r = Matrix3::from_columns(&[x, z.cross(&x), z]) * rot(0.1, 0.05, -0.04);
        let cam = Frame {
            rotation: r,
            translation: centre + 0.6 * normal,
        };
        robot.cameras.push(camera(Mount::Base, link_of(&cam)));
        robot
            .boards
            .push(board(Mount::EndEffector, link_of(&on_flange)));
    }
    robot.validate().unwrap();
    robot
}

/// `count` postures about [`HOME`] that see at least 20 of the board's points, and their pixels.
fn views(robot: &Robot, count: usize, seed: u64) -> Dataset {
    let mut rng = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    let mut uniform = || {
        rng = rng
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (rng >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    let spread = [0.25, 0.2, 0.2, 0.5, 0.35, 0.6];
    let postures: Vec<Posture> = (0..8 * count)
        .map(|i| Posture {
            label: format!("{seed}-{i}"),
            readings: HOME
                .iter()
                .zip(spread)
                .map(|(h, s)| h + s * uniform())
                .collect(),
            session: None,
            payload: None,
        })
        .collect();
    let all = simulate::camera_views(robot, &postures, 0, 0, 20);
    // The first `count` postures that see the board.
    let keep = count.min(all.postures.len());
    let observations = all
        .observations
        .into_iter()
        .filter(|o| o.posture() < keep)
        .collect();
    Dataset::new(all.postures[..keep].to_vec(), observations)
}

/// The truth with its camera's and board's poses at zero: where a user starts.
fn from_nothing(truth: &Robot) -> Robot {
    let mut r = truth.clone();
    r.cameras[0].pose = Link::default();
    r.boards[0].pose = Link::default();
    r
}

/// Translation (m) and rotation (rad) between two poses.
fn pose_error(a: &Link, b: &Link) -> (f64, f64) {
    let (fa, fb) = (Frame::from_link(a), Frame::from_link(b));
    let dr = fa.rotation.transpose() * fb.rotation;
    let angle = ((dr.trace() - 1.0) / 2.0).clamp(-1.0, 1.0).acos();
    ((fa.translation - fb.translation).norm(), angle)
}

fn fit(start: &Robot, data: &Dataset, estimate: &str) -> kinecal::workflow::Outcome {
    let mut req = Request::new(start.clone(), Arc::new(data.clone()));
    req.selection = Selection::parse(estimate, None, start).unwrap();
    run(&req, &mut ()).unwrap()
}

/// The pixel rows' derivatives with respect to every parameter (the robot's, the camera's pose
/// and lens, the board's pose), against central differences, for the camera on the flange, on
/// the base, and a fixed camera seeing a marker site.
#[test]
fn pixel_jacobian_matches_central_differences() {
    for eye_in_hand in [true, false] {
        let robot = truth(eye_in_hand);
        let data = views(&robot, 4, 3);
        assert!(data.rows() > 100, "{} rows", data.rows());
        let all: Vec<ParamId> = robot.param_ids().collect();
        let problem = Problem::new(
            &robot,
            &data,
            &all,
            Weights::default(),
            OrientationError::default(),
        );
        let m = problem.rows();
        let mut r = vec![0.0; m];
        let mut jac = kinecal::linalg::Matrix::zeros(m, all.len());
        problem.evaluate(&robot, &mut r, Some(&mut jac));
        let x0 = problem.values(&robot);
        let (mut rp, mut rm) = (vec![0.0; m], vec![0.0; m]);
        for c in 0..all.len() {
            // Steps of 1e-6 of each parameter's scale (1 for the pixel and distortion terms'
            // values of hundreds and tenths, metres and radians for the rest): truncation
            // h^2 |f'''| stays below 1e-6 px, rounding eps |r| / h below 1e-7 px.
            let h = 1e-6 * x0[c].abs().max(1.0);
            let mut x = x0.clone();
            x[c] += h;
            problem.evaluate(&problem.robot_at(&x), &mut rp, None);
            x[c] -= 2.0 * h;
            problem.evaluate(&problem.robot_at(&x), &mut rm, None);
            for i in 0..m {
                let fd = (rp[i] - rm[i]) / (2.0 * h);
                assert!(
                    (fd - jac[(i, c)]).abs() <= 1e-5 * (1.0 + jac[(i, c)].abs()),
                    "eye in hand {eye_in_hand}: row {i} {}: analytic {} vs {fd}",
                    robot.param_name(all[c]),
                    jac[(i, c)]
                );
            }
        }
    }
}

/// A robot file with a camera and a board reads back to the same model, and a pixel file to
/// the same observations.
#[test]
fn robot_and_pixel_files_round_trip() {
    let robot = truth(true);
    let text = kinecal::model::robot_file::write_robot_toml(&robot, None);
    assert!(
        text.contains("[[cameras]]") && text.contains("[[boards]]"),
        "{text}"
    );
    let back = kinecal::model::robot_file::parse_robot_toml(&text, "cam.toml").unwrap();
    assert_eq!(back.cameras.len(), 1);
    for id in robot.param_ids() {
        let (a, b) = (robot.get(id), back.get(id));
        assert!(
            (a - b).abs() <= 1e-12 * a.abs().max(1.0),
            "{}: {a} vs {b}",
            robot.param_name(id)
        );
    }
    assert_eq!(back.cameras[0].mount, Mount::EndEffector);
    assert_eq!(back.boards[0].mount, Mount::Base);
    assert_eq!(
        robot.param_name(ParamId(robot.param_count() - 7)),
        "wrist.k3"
    );
    let data = views(&robot, 3, 1);
    let csv = kinecal::files::write_observations(&robot, &data).unwrap();
    assert!(csv.starts_with("posture,camera,point,v1"), "{csv}");
    let again =
        kinecal::files::read_observations(&csv, "px.csv", &robot, &Default::default()).unwrap();
    assert_eq!(again.observations.len(), data.observations.len());
    for (a, b) in data.observations.iter().zip(&again.observations) {
        let mut b = b.clone();
        if let kinecal::observe::Observation::Pixel(p) = &mut b {
            p.line = 0;
        }
        assert_eq!(a, &b);
    }
}

/// Broken camera files: each error names the field or the line.
#[test]
fn bad_cameras_and_pixels_are_refused_clearly() {
    let base = kinecal::model::robot_file::write_robot_toml(&truth(true), None);
    for (from, to, expect) in [
        ("fx = 600", "fx = -600", "cameras[0].fx"),
        (
            "mount = \"ee\"",
            "mount = \"wrist3\"",
            "unknown mount `wrist3`",
        ),
        ("cols = 9", "cols = 1", "boards[0].cols"),
        ("name = \"board\"", "name = \"link2\"", "link2"),
    ] {
        assert!(base.contains(from), "{from}");
        let text = base.replacen(from, to, 1);
        let e = kinecal::model::robot_file::parse_robot_toml(&text, "cam.toml")
            .unwrap_err()
            .to_string();
        assert!(e.contains(expect), "{to}: {e}");
    }
    let robot = truth(true);
    for (csv, expect) in [
        (
            "posture,camera,point,v1,v2,v3,v4,v5,v6,u,v\n1,wrist,board:54,0,0,0,0,0,0,1,2\n",
            "points 0..53",
        ),
        (
            "posture,camera,point,v1,v2,v3,v4,v5,v6,u,v\n1,eye,board:3,0,0,0,0,0,0,1,2\n",
            "unknown camera `eye`",
        ),
        (
            "posture,camera,point,v1,v2,v3,v4,v5,v6,u,v\n1,wrist,board:3,0,0,0,0,0,0,1e9,2\n",
            "pixel coordinate",
        ),
        (
            "posture,camera,point,v1,v2,v3,v4,v5,v6,u,v\n1,wrist,ee,0,0,0,0,0,0,1,2\n",
            "same frame",
        ),
    ] {
        let e = kinecal::files::read_observations(csv, "px.csv", &robot, &Default::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains(expect) && e.contains("px.csv"), "{csv}: {e}");
    }
}

/// Runs one hand-eye case from nothing and checks the recovered poses against the truth
/// within the fit's own standard deviations.
fn hand_eye_case(eye_in_hand: bool, lens: bool) {
    let truth = truth(eye_in_hand);
    let mut data = views(&truth, 25, 11);
    assert_eq!(data.postures.len(), 25);
    simulate::add_noise_with(
        &mut data,
        &Noise {
            pixel: PIXEL_NOISE,
            ..Default::default()
        },
        5,
    );
    let mut start = from_nothing(&truth);
    let estimate = if lens {
        // The lens from a guess: the focal length off by 5 %, the centre by 10 px, no
        // distortion.
        start.cameras[0].fx = 630.0;
        start.cameras[0].fy = 630.0;
        start.cameras[0].cx = 330.0;
        start.cameras[0].cy = 230.0;
        start.cameras[0].distortion = [0.0; 5];
        "cameras,boards"
    } else {
        "extrinsics,boards"
    };
    let out = fit(&start, &data, estimate);
    let cal = &out.calibration.calibrated;
    let rms = out.calibration.accuracy_after.other[0].rms;
    // The residuals are the noise: RMS of 2-D errors of 0.3 px per axis is 0.42 px.
    assert!(
        rms < 1.2 * PIXEL_NOISE * 2f64.sqrt(),
        "eye in hand {eye_in_hand}, lens {lens}: RMS {rms} px"
    );
    let (dt, da) = pose_error(&cal.cameras[0].pose, &truth.cameras[0].pose);
    let (bt, ba) = pose_error(&cal.boards[0].pose, &truth.boards[0].pose);
    eprintln!(
        "eye in hand {eye_in_hand}, lens {lens}: RMS {rms:.3} px; camera {:.4} mm {:.5} deg, \
         board {:.4} mm {:.5} deg; {} iterations",
        dt * 1e3,
        da.to_degrees(),
        bt * 1e3,
        ba.to_degrees(),
        out.calibration.iterations
    );
    let (t_bound, a_bound) = if lens {
        (1e-3, 0.3f64.to_radians())
    } else {
        (2e-4, 0.02f64.to_radians())
    };
    assert!(
        dt < t_bound && da < a_bound && bt < 2.0 * t_bound && ba < 2.0 * a_bound,
        "eye in hand {eye_in_hand}, lens {lens}: camera {:.3} mm {:.4} deg, board {:.3} mm {:.4} \
         deg",
        dt * 1e3,
        da.to_degrees(),
        bt * 1e3,
        ba.to_degrees()
    );
    // Every estimated parameter within 4 of its own standard deviations of the truth: over the
    // 21-27 parameters of a case, a 3-sigma bound would fail a correct fit about once in 14
    // runs (0.27 % each); 4 sigma once in 600.
    let u = out.uncertainty.as_ref().expect("an uncertainty");
    for p in &u.parameters {
        let Some(s) = p.sigma else { continue };
        let mut err = cal.get(p.id) - truth.get(p.id);
        if truth.param_quantity(p.id) == kinecal::units::Quantity::Angle {
            err -= std::f64::consts::TAU * (err / std::f64::consts::TAU).round();
        }
        assert!(
            err.abs() <= 4.0 * s,
            "eye in hand {eye_in_hand}, lens {lens}: {} off by {err:e}, sigma {s:e}",
            truth.param_name(p.id)
        );
    }
}

#[test]
fn eye_in_hand_from_nothing_with_the_lens_known() {
    hand_eye_case(true, false);
}

#[test]
fn eye_to_hand_from_nothing_with_the_lens_known() {
    hand_eye_case(false, false);
}

#[test]
fn eye_in_hand_from_nothing_with_the_lens_estimated() {
    hand_eye_case(true, true);
}

#[test]
fn eye_to_hand_from_nothing_with_the_lens_estimated() {
    hand_eye_case(false, true);
}

/// With the robot's kinematics off by 1 mm and 0.1 deg, the joint fit of kinematics and
/// hand-eye predicts fresh views near the pixel noise, several times better than the hand-eye
/// alone on the nominal robot.
#[test]
fn kinematics_and_hand_eye_together_predict_fresh_views() {
    let truth = truth(true);
    let nominal_arm = truth.clone();
    let bent = simulate::perturb(
        &truth,
        simulate::PerturbStd {
            length: 1e-3,
            angle: 0.1f64.to_radians(),
            slope_fraction: 0.0,
        },
        8,
    );
    let mut truth = bent;
    // Only the arm is perturbed: the camera, board and lens stay the truth's.
    truth.cameras = nominal_arm.cameras.clone();
    truth.boards = nominal_arm.boards.clone();
    let noise = Noise {
        pixel: PIXEL_NOISE,
        ..Default::default()
    };
    let mut data = views(&truth, 30, 21);
    simulate::add_noise_with(&mut data, &noise, 6);
    let mut fresh = views(&truth, 20, 99);
    simulate::add_noise_with(&mut fresh, &noise, 7);
    let start = from_nothing(&nominal_arm);
    let rms = |r: &Robot| {
        let e = kinecal::observe::accuracy(r, &fresh);
        e.other[0].rms
    };
    let alone = fit(&start, &data, "extrinsics,boards");
    let joint = fit(&start, &data, "identifiable,extrinsics,boards");
    let (a, j) = (
        rms(&alone.calibration.calibrated),
        rms(&joint.calibration.calibrated),
    );
    // The noise alone gives 0.42 px RMS (0.3 px per axis); the fit's own error adds a little.
    assert!(j < 0.6, "joint fit: {j} px on fresh views");
    // Measured: 1.05 px against 0.42 px (2.5 times).
    assert!(a > 2.0 * j, "hand-eye alone {a} px vs joint {j} px");
}

/// A camera's calibration predicts its robot's accuracy (issue 40): with the kinematics off by
/// 1 mm and 0.1 deg and only pixels measured, the joint fit's prediction takes its model-error
/// term from the held-out pixels (turned into lengths across their lines of sight), at least
/// the noise's own length there, and 90-98 % of fresh views' errors fall within their bounds.
#[test]
fn a_camera_calibration_predicts_its_accuracy_from_pixels() {
    let nominal_arm = truth(true);
    let mut truth = simulate::perturb(
        &nominal_arm,
        simulate::PerturbStd {
            length: 1e-3,
            angle: 0.1f64.to_radians(),
            slope_fraction: 0.0,
        },
        8,
    );
    truth.cameras = nominal_arm.cameras.clone();
    truth.boards = nominal_arm.boards.clone();
    let noise = Noise {
        pixel: PIXEL_NOISE,
        ..Default::default()
    };
    let mut data = views(&truth, 30, 21);
    simulate::add_noise_with(&mut data, &noise, 6);
    let mut fresh = views(&truth, 40, 123);
    simulate::add_noise_with(&mut fresh, &noise, 17);
    let start = from_nothing(&nominal_arm);
    let mut req = Request::new(start.clone(), Arc::new(data.clone()));
    req.selection = Selection::parse("identifiable,extrinsics,boards", None, &start).unwrap();
    req.prediction = kinecal::predict::Level::Summary;
    let out = run(&req, &mut ()).unwrap();
    let report = out
        .report
        .prediction
        .as_ref()
        .expect("a prediction from pixels alone");
    let cal = &out.calibration.calibrated;
    let u = out.uncertainty.as_ref().unwrap();
    // The noise's own length across the lines of sight: the truth's errors on the fresh views
    // (0.3 px at about 0.45 m with f = 600 px: about 0.22 mm per axis).
    let pure = lateral_errors(&truth, &fresh, &[], None).unwrap();
    let noise_len = (pure
        .iter()
        .map(|l| l.error[0] * l.error[0] + l.error[1] * l.error[1])
        .sum::<f64>()
        / (2 * pure.len()) as f64)
        .sqrt();
    let s0 = report.position.s0; // in the robot file's unit, m
    assert!(
        s0 > 0.9 * noise_len && s0 < 2.0 * noise_len,
        "s0 {s0} m against the noise's {noise_len} m"
    );
    // The cross-validation's own coverage, and a fresh one.
    assert!(
        (0.90..=0.98).contains(&report.position.coverage),
        "{}",
        report.position.coverage
    );
    let predictor = kinecal::predict::from_report(cal, report).unwrap();
    let mut scratch = predictor.scratch();
    let errors = lateral_errors(
        cal,
        &fresh,
        &u.analysis.parameters,
        Some(u.covariance_internal()),
    )
    .unwrap();
    assert!(errors.len() > 1000, "{} pixels", errors.len());
    let inside = errors
        .iter()
        .filter(|l| {
            let d = predictor.distance(&fresh.postures[l.posture].readings, &mut scratch);
            let v = predictor.model(l.target).position.variance(d);
            let p = l.parameters;
            let p3 = [[p[0][0], p[0][1], 0.0], [p[1][0], p[1][1], 0.0], [0.0; 3]];
            let e = (l.error[0] * l.error[0] + l.error[1] * l.error[1]).sqrt();
            e <= Bound::across(&p3, v).bound
        })
        .count();
    let coverage = inside as f64 / errors.len() as f64;
    eprintln!(
        "s0 {s0:.3e} m (noise {noise_len:.3e} m), cross-validated coverage {:.3}, fresh {coverage:.3} of {}",
        report.position.coverage,
        errors.len()
    );
    assert!(
        (0.90..=0.98).contains(&coverage),
        "fresh coverage {coverage}"
    );
}

/// `--perturb-std` moves the cameras' and boards' poses by its lengths and angles and keeps
/// their lenses: a spread in metres or radians says nothing of pixels or distortion.
#[test]
fn a_perturbation_moves_poses_and_keeps_lenses() {
    let truth = truth(true);
    let bent = simulate::perturb(
        &truth,
        simulate::PerturbStd {
            length: 1e-3,
            angle: 1e-3,
            slope_fraction: 0.0,
        },
        3,
    );
    let (a, b) = (&truth.cameras[0], &bent.cameras[0]);
    assert_eq!(
        (a.fx, a.fy, a.cx, a.cy, a.distortion),
        (b.fx, b.fy, b.cx, b.cy, b.distortion)
    );
    let (t, r) = pose_error(&a.pose, &b.pose);
    assert!(
        t > 1e-5 && r > 1e-5,
        "the camera's pose moved {t} m, {r} rad"
    );
    let (t, r) = pose_error(&truth.boards[0].pose, &bent.boards[0].pose);
    assert!(
        t > 1e-5 && r > 1e-5,
        "the board's pose moved {t} m, {r} rad"
    );
}

/// A prediction asked for and impossible (12 views: fewer postures than a cross-validation
/// needs) is said, with the reason, where it used to be dropped without a word.
#[test]
fn a_prediction_that_cannot_be_made_is_said() {
    let truth = truth(true);
    let mut data = views(&truth, 12, 4);
    simulate::add_noise_with(
        &mut data,
        &Noise {
            pixel: PIXEL_NOISE,
            ..Default::default()
        },
        2,
    );
    let start = from_nothing(&truth);
    let mut req = Request::new(start.clone(), Arc::new(data));
    req.selection = Selection::parse("extrinsics,boards", None, &start).unwrap();
    req.prediction = kinecal::predict::Level::Summary;
    let out = run(&req, &mut ()).unwrap();
    assert!(out.report.prediction.is_none());
    let said: Vec<&String> = out
        .report
        .warnings
        .iter()
        .filter(|w| w.starts_with("no predicted accuracy"))
        .collect();
    assert_eq!(said.len(), 1, "{:?}", out.report.warnings);
    assert!(
        said[0]
            .contains("at least 20 postures measured by position, pose or pixel; the data has 12"),
        "{}",
        said[0]
    );
}

/// The closed forms alone (homographies, board poses, AX = YB) land near the truth from poses at
/// zero: within 5 mm and 0.5 deg for 0.3 px of noise, close enough for the fit to converge.
#[test]
fn the_closed_forms_alone_land_near_the_truth() {
    for eye_in_hand in [true, false] {
        let truth = truth(eye_in_hand);
        let mut data = views(&truth, 25, 11);
        simulate::add_noise_with(
            &mut data,
            &Noise {
                pixel: PIXEL_NOISE,
                ..Default::default()
            },
            5,
        );
        let start = from_nothing(&truth);
        let ids: Vec<ParamId> =
            kinecal::model::param_list::parse_param_list("extrinsics,boards", &start).unwrap();
        let placed = kinecal::solve::hand_eye::place_cameras(&start, &data, &ids)
            .expect("placed in closed form");
        let (dt, da) = pose_error(&placed.cameras[0].pose, &truth.cameras[0].pose);
        let (bt, ba) = pose_error(&placed.boards[0].pose, &truth.boards[0].pose);
        eprintln!(
            "closed form, eye in hand {eye_in_hand}: camera {:.3} mm {:.4} deg, board {:.3} mm \
             {:.4} deg",
            dt * 1e3,
            da.to_degrees(),
            bt * 1e3,
            ba.to_degrees()
        );
        assert!(dt < 5e-3 && da < 0.5f64.to_radians() && bt < 5e-3 && ba < 0.5f64.to_radians());
    }
}

/// The identifiability analysis covers a camera's parameters: from 3 views k3 (the r^6 term)
/// is not determined beyond the noise, and the tool link and the camera's pose on it are one
/// frame to the pixels (the analysis says which of them the data cannot tell apart); from 25
/// views the poses and k1 are.
#[test]
fn the_analysis_names_what_few_views_cannot_determine() {
    use kinecal::identifiability::{analyze, AnalysisOptions};
    let truth = truth(true);
    let few = views(&truth, 3, 11);
    let lens_and_poses =
        kinecal::model::param_list::parse_param_list("cameras,boards", &truth).unwrap();
    let k3 = kinecal::model::param_list::parse_param_list("wrist.k3", &truth).unwrap()[0];
    let a = analyze(&truth, &few, &lens_and_poses, &AnalysisOptions::default()).unwrap();
    assert!(
        !a.identifiable.contains(&k3),
        "k3 from 3 views: identifiable {:?}",
        a.identifiable
    );
    let many = views(&truth, 25, 11);
    let a = analyze(&truth, &many, &lens_and_poses, &AnalysisOptions::default()).unwrap();
    let left: Vec<String> = lens_and_poses
        .iter()
        .filter(|id| !a.identifiable.contains(id))
        .map(|&id| truth.param_name(id))
        .collect();
    eprintln!("25 views leave out: {left:?}");
    // Both poses and the distortion's leading terms are determined; within the noise (1 px
    // by default) the focal lengths trade off against the distance and the principal point
    // against the camera's rotation for views of a board near the image's middle at one
    // distance, and the analysis names them.
    let needed =
        kinecal::model::param_list::parse_param_list("wrist.k1,extrinsics,boards", &truth).unwrap();
    for id in needed {
        assert!(
            a.identifiable.contains(&id),
            "{} not identifiable from 25 views",
            truth.param_name(id)
        );
    }
    assert!(left.len() < lens_and_poses.len() - 15, "{left:?}");
    // With the tool link too, 6 directions are the same motion seen two ways.
    let mut with_tool = lens_and_poses.clone();
    with_tool.extend(kinecal::model::param_list::parse_param_list("link7", &truth).unwrap());
    let a = analyze(&truth, &many, &with_tool, &AnalysisOptions::default()).unwrap();
    assert_eq!(a.rank, with_tool.len() - 6, "rank {}", a.rank);
}

/// Pixel rows take part in everything rows do: a corner mislocated by 25 px is flagged as an
/// outlier, validation data of fresh views is checked in pixels, and a plan drawn from postures
/// of a robot with a camera is a plan of views.
#[test]
fn outliers_validation_and_plans_see_pixels() {
    let truth = truth(true);
    let noise = Noise {
        pixel: PIXEL_NOISE,
        ..Default::default()
    };
    let mut data = views(&truth, 20, 11);
    simulate::add_noise_with(&mut data, &noise, 5);
    let bad = 37;
    if let kinecal::observe::Observation::Pixel(p) = &mut data.observations[bad] {
        p.uv[0] += 25.0;
        p.line = 1000;
    }
    let mut fresh = views(&truth, 10, 77);
    simulate::add_noise_with(&mut fresh, &noise, 9);
    let mut req = Request::new(from_nothing(&truth), Arc::new(data.clone()));
    req.selection = Selection::parse("extrinsics,boards", None, &truth).unwrap();
    req.validation = kinecal::workflow::Validation::Data(Arc::new(fresh));
    let out = run(&req, &mut ()).unwrap();
    assert!(
        out.outliers
            .iter()
            .any(|o| out.data.observations[o.observation].line() == 1000),
        "outliers: {:?}",
        out.outliers
    );
    let v = out.validation.as_ref().expect("validated");
    let after = &v.after.other[0];
    assert_eq!(after.metric, "pixel");
    assert!(after.rms < 0.6, "validation RMS {} px", after.rms);
    // A plan from sampled postures: its candidates are what the camera sees.
    let postures = views(&truth, 40, 5).postures;
    let pool = kinecal::apps::plan::candidates(&truth, postures, &[Target::EndEffector], false);
    assert!(pool.observations.iter().all(|o| o.kind() == "pixel"));
    assert_eq!(pool.postures.len(), 40);
}
