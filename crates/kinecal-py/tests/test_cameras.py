"""Cameras from Python (issue 40): the robot file's cameras and boards, simulated views (the
pixel file), the ROS camera_info YAML both ways (PyYAML reads what kinecal writes to the same
numbers), and OpenCV's calibrateCamera + calibrateHandEye as the reference on the same
detections: kinecal's hand-eye at least as close to the truth."""

from __future__ import annotations

import csv
import io
import math
import os
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

import kinecal

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", ".."))
CAMERAS = Path(ROOT) / "examples" / "cameras"


def truth() -> kinecal.Robot:
    return kinecal.Robot.from_toml(CAMERAS / "eye_in_hand_truth.toml")


def test_cameras_and_boards_are_the_robot_file_s() -> None:
    robot = truth()
    (camera,) = robot.cameras
    assert camera["name"] == "wrist" and camera["mount"] == "ee"
    assert camera["pose"] == pytest.approx([0.03, -0.05, 0.04, 0.05, -0.03, 0.02], abs=1e-12)
    assert (camera["fx"], camera["fy"], camera["cx"], camera["cy"]) == (600, 610, 320, 240)
    assert camera["distortion"] == [-0.2, 0, 0, 0, 0]
    assert (camera["width"], camera["height"]) == (640, 480)
    (board,) = robot.boards
    assert (board["name"], board["mount"], board["cols"], board["rows"]) == ("board", "base", 9, 6)
    assert board["spacing"] == 0.025
    assert kinecal.Robot.builtin("ge-a4").cameras == []


def test_camera_info_round_trips_through_pyyaml(tmp_path: Path) -> None:
    robot = truth().with_value("wrist.fx", 601.2345678901234).with_value("wrist.k2", 1e-7)
    text = robot.to_camera_info("wrist")
    info = yaml.safe_load(text)
    fx, fy, cx, cy = 601.2345678901234, 610.0, 320.0, 240.0
    assert info["image_width"] == 640 and info["image_height"] == 480
    assert info["camera_name"] == "wrist"
    assert info["distortion_model"] == "plumb_bob"
    assert info["camera_matrix"] == {"rows": 3, "cols": 3,
                                     "data": [fx, 0, cx, 0, fy, cy, 0, 0, 1]}
    assert info["distortion_coefficients"] == {"rows": 1, "cols": 5,
                                               "data": [-0.2, 1e-7, 0, 0, 0]}
    assert info["rectification_matrix"]["data"] == [1, 0, 0, 0, 1, 0, 0, 0, 1]
    assert info["projection_matrix"] == {"rows": 3, "cols": 4,
                                         "data": [fx, 0, cx, 0, 0, fy, cy, 0, 0, 0, 1, 0]}
    # Every number a float, to the last bit (PyYAML reads 1e-07 without a dot as a string).
    for key in ("camera_matrix", "distortion_coefficients", "projection_matrix"):
        assert all(isinstance(v, float) for v in info[key]["data"]), key
    # Read back into a robot: the same lens.
    (tmp_path / "wrist.yaml").write_text(text)
    start = truth()
    back = start.with_camera_info(tmp_path / "wrist.yaml")
    assert back.get("wrist.fx") == fx and back.get("wrist.k2") == 1e-7
    assert back.to_camera_info() == text
    # A lens written by ROS's own tools (as PyYAML dumps it) reads too.
    ros = dict(info, camera_matrix=dict(info["camera_matrix"],
                                        data=[500.5, 0, 300.25, 0, 501.0, 200.0, 0, 0, 1]))
    other = start.with_camera_info(yaml.safe_dump(ros), "wrist")
    assert (other.get("wrist.fx"), other.get("wrist.cy")) == (500.5, 200.0)
    with pytest.raises(kinecal.KinecalError, match="unknown camera `left`"):
        start.to_camera_info("left")
    bad = text.replace("plumb_bob", "equidistant")
    with pytest.raises(kinecal.KinecalError, match="distortion_model"):
        start.with_camera_info(bad)


def test_simulated_views_are_run_s_and_the_pixel_file(tmp_path: Path) -> None:
    robot = truth()
    sim = kinecal.simulate(robot, 6, seed=3, camera="wrist", board="board",
                           noise={"pixel": 0.3})
    doc = kinecal.run({"job": "simulate", "robot": str(CAMERAS / "eye_in_hand_truth.toml"),
                       "postures": 6, "seed": 3, "camera": "wrist", "board": "board",
                       "noise": {"pixel": 0.3}})
    text = sim.measurements.to_csv(robot)
    assert text == doc["data"]
    assert text.startswith("posture,camera,point,v1,v2,v3,v4,v5,v6,u,v\n")
    assert sim.measurements.kinds == {"pixel": doc["measurements"]}
    # With readings: the views among them.
    views = kinecal.simulate(robot, sim.measurements.readings, camera="wrist", board="board")
    assert views.measurements.postures == 6
    with pytest.raises(kinecal.KinecalError) as e:
        kinecal.simulate(robot, 3, camera="nope", board="board")
    assert str(e.value).startswith("camera: unknown camera `nope`"), str(e.value)
    with pytest.raises(kinecal.KinecalError, match="min_points"):
        kinecal.simulate(robot, 3, camera="wrist", board="board", min_points=55)


# -- OpenCV as the reference ------------------------------------------------------------------


def rotation(alpha: float, beta: float, gamma: float) -> np.ndarray:
    """ZYX Euler angles (kinecal's) as a rotation matrix: Rz(alpha) Ry(beta) Rx(gamma)."""
    ca, sa, cb, sb, cg, sg = (math.cos(alpha), math.sin(alpha), math.cos(beta),
                              math.sin(beta), math.cos(gamma), math.sin(gamma))
    rz = np.array([[ca, -sa, 0], [sa, ca, 0], [0, 0, 1]])
    ry = np.array([[cb, 0, sb], [0, 1, 0], [-sb, 0, cb]])
    rx = np.array([[1, 0, 0], [0, cg, -sg], [0, sg, cg]])
    return rz @ ry @ rx


def pose_error(pose: list[float], r: np.ndarray, t: np.ndarray) -> tuple[float, float]:
    """Translation (mm) and rotation (deg) between a pose (m, rad) and (R, t)."""
    dr = rotation(*pose[3:]).T @ r
    angle = math.degrees(math.acos(max(-1.0, min(1.0, (np.trace(dr) - 1) / 2))))
    return float(np.linalg.norm(np.array(pose[:3]) - t.ravel()) * 1e3), angle


def opencv() -> Any:
    try:
        import cv2
    except ImportError:
        if os.environ.get("CI") == "true":
            raise
        pytest.skip("OpenCV is not installed (pip install 'opencv-python-headless<5'): the "
                    "reference comparison is skipped")
    if not hasattr(cv2, "calibrateHandEye"):
        pytest.fail(f"OpenCV {cv2.__version__} has no calibrateHandEye (the 5.x wheel): "
                    "install opencv-python-headless<5")
    return cv2


def test_hand_eye_is_at_least_as_close_as_opencv_s(tmp_path: Path) -> None:
    """Eye-in-hand, a 9 x 6 board, 25 views that see all of it (what findChessboardCorners
    returns), 0.3 px of noise, k1 = -0.2: the lens and the hand-eye from the same detections,
    by OpenCV's calibrateCamera then calibrateHandEye (Tsai, Park, Horaud, Andreff,
    Daniilidis), and by kinecal from poses at zero with the lens estimated too."""
    cv2 = opencv()
    robot = truth()
    sim = kinecal.simulate(robot, 25, seed=11, camera="wrist", board="board", min_points=54,
                           noise={"pixel": 0.3})
    text = sim.measurements.to_csv(robot)
    (tmp_path / "views.csv").write_text(text)
    rows = list(csv.DictReader(io.StringIO(text)))
    postures: dict[str, list[dict[str, str]]] = {}
    for row in rows:
        postures.setdefault(row["posture"], []).append(row)
    assert len(postures) == 25 and all(len(v) == 54 for v in postures.values())
    board = robot.boards[0]
    objects, images, readings = [], [], []
    for view in postures.values():
        k = np.array([int(r["point"].split(":")[1]) for r in view])
        obj = np.zeros((len(k), 3), np.float32)
        obj[:, 0] = (k % board["cols"]) * board["spacing"]
        obj[:, 1] = (k // board["cols"]) * board["spacing"]
        objects.append(obj)
        images.append(np.array([[float(r["u"]), float(r["v"])] for r in view], np.float32))
        readings.append([float(view[0][f"v{j + 1}"]) for j in range(6)])
    rms, matrix, dist, rvecs, tvecs = cv2.calibrateCamera(objects, images, (640, 480), None,
                                                          None)
    flange = robot.fk(np.array(readings))
    r_g2b = [rotation(*f[3:]) for f in flange]
    t_g2b = [f[:3].reshape(3, 1) for f in flange]
    r_t2c = [cv2.Rodrigues(r)[0] for r in rvecs]
    true_pose = robot.cameras[0]["pose"]
    methods = {"tsai": cv2.CALIB_HAND_EYE_TSAI, "park": cv2.CALIB_HAND_EYE_PARK,
               "horaud": cv2.CALIB_HAND_EYE_HORAUD, "andreff": cv2.CALIB_HAND_EYE_ANDREFF,
               "daniilidis": cv2.CALIB_HAND_EYE_DANIILIDIS}
    theirs = {}
    for name, method in methods.items():
        r, t = cv2.calibrateHandEye(r_g2b, t_g2b, r_t2c, list(tvecs), method=method)
        theirs[name] = pose_error(true_pose, r, t)
    # kinecal: the lens, the hand-eye and the board from the same pixels, from poses at zero.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cal = kinecal.calibrate({"robot": str(CAMERAS / "eye_in_hand.toml"),
                                 "observations": [{"file": str(tmp_path / "views.csv"),
                                                   "kind": "pixels"}],
                                 "selection": {"estimate": "cameras,boards"}})
    mine_pose = cal.robot.cameras[0]["pose"]
    mine = pose_error(true_pose, rotation(*mine_pose[3:]), np.array(mine_pose[:3]))
    best = min(theirs.values(), key=lambda e: e[0])
    print(f"\nOpenCV {cv2.__version__}: calibrateCamera RMS {rms:.4f} px, fx {matrix[0, 0]:.3f} "
          f"fy {matrix[1, 1]:.3f} cx {matrix[0, 2]:.3f} cy {matrix[1, 2]:.3f} "
          f"k1 {dist.ravel()[0]:.5f}")
    for name, (dt, da) in theirs.items():
        print(f"  calibrateHandEye {name:10s}: {dt:.4f} mm, {da:.5f} deg")
    lens = cal.robot.cameras[0]
    print(f"kinecal: fx {lens['fx']:.3f} fy {lens['fy']:.3f} cx {lens['cx']:.3f} "
          f"cy {lens['cy']:.3f} k1 {lens['distortion'][0]:.5f}; hand-eye {mine[0]:.4f} mm, "
          f"{mine[1]:.5f} deg")
    assert mine[0] <= best[0] and mine[1] <= min(e[1] for e in theirs.values()), (mine, theirs)
    # And near the floor the issue states for the lens estimated from the same views.
    assert mine[0] < 1.0 and mine[1] < 0.1, mine
