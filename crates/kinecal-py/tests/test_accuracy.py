"""Predicted accuracy and ISO 9283 figures from Python: checked against the forward kinematics,
against numpy on the log, against the shipped schema, and with the inputs users get wrong.

Run by `bash crates/kinecal-py/test.sh`.
"""

import json
import os

import jsonschema
import numpy as np
import pytest

import kinecal

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", ".."))
with open(os.path.join(ROOT, "schemas", "iso9283.schema.json")) as _f:
    ISO_SCHEMA = jsonschema.Draft202012Validator(json.load(_f))


@pytest.fixture(scope="module")
def calibrated():
    """A GE A4 with its third link and joint 2 off, calibrated on 30 poses with a prediction;
    the true robot."""
    robot = kinecal.Robot.builtin("ge-a4")
    sim = kinecal.simulate(
        robot,
        30,
        seed=7,
        perturb={"p1": 0.05, "p14": -0.02, "joint2.offset": -0.5},
        noise=(0.0005, 0.005),
    )
    cal = kinecal.calibrate(
        robot,
        sim.measurements,
        estimate="p1,p2,p8,p14,offsets,slopes",
        weights=(0.0005, 0.005),
        predict=True,
    )
    return robot, cal, sim.truth


def test_a_prediction_is_where_the_model_puts_the_tool_with_its_bound(calibrated):
    robot, cal, _ = calibrated
    postures = kinecal.simulate(robot, 12, seed=9).measurements.readings
    p = cal.predict(postures)
    # Where the calibrated model puts the tool: its forward kinematics.
    np.testing.assert_allclose(p["position"], cal.robot.fk(postures)[:, :3], atol=1e-12)
    assert p["position_bound95"].shape == (12,)
    assert np.all(p["position_bound95"] >= p["position_bound95_parameters"])
    assert np.all(p["attitude_bound95"] > 0) and np.all(p["distance"] >= 0)
    # The bound of a Gaussian error: between the RMS length and 3 times it.
    rms = np.hypot(p["position_parameters"], p["position_model"])
    assert np.all(p["position_bound95"] > rms) and np.all(p["position_bound95"] < 3 * rms)
    # The same from the report as a dict, as JSON text and as a file.
    q = kinecal.predict(cal.robot, cal.report, postures=postures)
    np.testing.assert_array_equal(q["position_bound95"], p["position_bound95"])
    q = kinecal.predict(cal.robot, cal.to_json(), postures=postures)
    np.testing.assert_array_equal(q["position_bound95"], p["position_bound95"])


def test_cartesian_targets_are_reached_then_predicted(calibrated, tmp_path):
    robot, cal, _ = calibrated
    postures = kinecal.simulate(robot, 6, seed=9).measurements.readings
    at = cal.predict(postures)
    p = cal.predict(targets=at["position"])
    # Reached within the inverse kinematics' tolerance (1 um, here in inches).
    np.testing.assert_allclose(p["position"], at["position"], atol=2e-6 / 0.0254)
    # The prediction at the readings found.
    again = cal.predict(p["readings"])
    np.testing.assert_allclose(again["position_bound95"], p["position_bound95"], rtol=1e-12)
    with pytest.raises(kinecal.KinecalError, match="row 0: the calibrated robot does not reach"):
        cal.predict(targets=[[150.0, 0.0, 0.0]])
    with pytest.raises(kinecal.KinecalError, match="row 0: the position lies 16.* reaches"):
        cal.predict(targets=[[900.0, 0.0, 0.0]])
    with pytest.raises(kinecal.KinecalError, match=r"shape \(n, 3\)"):
        cal.predict(targets=[[1.0, 2.0]])


def test_a_prediction_needs_its_calibration(calibrated):
    robot, cal, _ = calibrated
    postures = kinecal.simulate(robot, 3, seed=9).measurements.readings
    with pytest.raises(kinecal.KinecalError, match="is not the calibrated robot"):
        kinecal.predict(robot, cal, postures=postures)
    sim = kinecal.simulate(robot, 30, seed=7, perturb={"p1": 0.05})
    plain = kinecal.calibrate(robot, sim.measurements, estimate="p1")
    with pytest.raises(kinecal.KinecalError, match="made no prediction"):
        plain.predict(postures)
    with pytest.raises(kinecal.KinecalError, match="give postures or targets"):
        cal.predict()


def test_iso_figures_of_a_measurement_series_before_and_after(calibrated):
    robot, cal, truth = calibrated
    # 18 postures measured on the true robot (positions), as two tests of nine poses, one
    # cycle each, and a 19th posture without a role.
    series = kinecal.simulate(
        robot,
        19,
        seed=11,
        perturb={"p1": 0.05, "p14": -0.02, "joint2.offset": -0.5},
        position_only=True,
    ).measurements
    roles = "posture,test,pose,cycle\n" + "".join(
        f"{k + 1},cube {k // 9 + 1},{'P1' if k % 9 == 0 else f'C{k % 9}'},1\n" for k in range(18)
    )
    before = kinecal.iso9283_log(robot, series, roles)
    assert before.left_out == ["19"] and before.placed == []
    figures = kinecal.iso9283(before.text)
    ISO_SCHEMA.validate(figures)
    assert figures["summary"]["tests"] == 2
    # One cycle: AP is the distance between the true robot and the nominal model, by numpy.
    readings = series.readings[:18]
    ap = np.linalg.norm(truth.fk(readings)[:, :3] - robot.fk(readings)[:, :3], axis=1)
    ours = {(p["test"], p["pose"]): p["ap"] for p in figures["poses"]}
    for k in range(18):
        pose = 1 if k % 9 == 0 else 5 + k % 9
        assert abs(ours[(f"cube {k // 9 + 1}", pose)] - ap[k]) < 1e-9
    # After: the calibrated model drives the robot; predicted once compensated.
    after = kinecal.iso9283_log(cal.robot, series, roles, length_unit="mm")
    figures = kinecal.iso9283(after.text, robot=cal.robot, report=cal)
    ISO_SCHEMA.validate(figures)
    assert figures["length_unit"] == "mm"
    every = next(p for p in figures["summary"]["poses"] if p["pose"] == 0)
    assert every["ap"]["mean"] < 0.1 * np.mean(ap) * 25.4
    assert all(p["compensated"]["readings_from"] == "log" for p in figures["poses"])
    with pytest.raises(kinecal.KinecalError, match="give robot and report together"):
        kinecal.iso9283(after.text, robot=cal.robot)
    with pytest.raises(kinecal.KinecalError, match="given a role twice"):
        kinecal.iso9283_log(robot, series, "posture,test,pose,cycle\n1,t,P1,1\n1,t,C1,1\n")
