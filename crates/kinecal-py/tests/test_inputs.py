"""Values given from Python, read as meant or refused naming the keyword: an empty parameter
list is not "the default parameters"; text that is neither a file nor a document is named as
such, not reported as a missing file."""

from __future__ import annotations

import numpy as np
import pytest

import kinecal


def _robot_and_data() -> tuple[kinecal.Robot, kinecal.Measurements]:
    robot = kinecal.Robot.builtin("ge-a4")
    q = np.random.default_rng(4).uniform(-30, 30, size=(12, 4))
    return robot, kinecal.Measurements(robot, q, robot.fk(q)[:, :3])


def test_an_empty_parameter_list_is_refused_naming_the_keyword() -> None:
    robot, data = _robot_and_data()
    for call in (
        lambda: kinecal.calibrate(robot, data, estimate=""),
        lambda: kinecal.analyze(robot, data, estimate=" "),
        lambda: kinecal.plan(robot, sample=40, count=4, estimate=""),
    ):
        with pytest.raises(kinecal.KinecalError, match=r"^estimate: an empty parameter list"):
            call()


def test_text_that_is_neither_a_file_nor_a_document_is_named() -> None:
    robot, _ = _robot_and_data()
    with pytest.raises(
        kinecal.KinecalError,
        match=r"^report: 'not a report' is neither a report file nor a report's JSON text",
    ):
        kinecal.predict(robot, "not a report", postures=np.zeros((1, 4)))
    with pytest.raises(kinecal.KinecalError, match=r"^log: 'no-such-log.csv' is neither a file"):
        kinecal.iso9283("no-such-log.csv")
