"""Tests of the Python bindings, against the command line on real data, against closed-form
kinematics, and with the inputs users get wrong.

Run by `bash crates/kinecal-py/test.sh` (builds the wheel, installs it in a virtual
environment, runs pytest). The command-line comparisons use the `kinecal` binary of this
checkout (KINECAL_BIN, or built with cargo).
"""

import ast
import doctest
import functools
import inspect
import json
import os
import subprocess
import threading
import warnings
from typing import Any

import jsonschema
import numpy as np
import pytest

import kinecal

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", ".."))
with open(os.path.join(ROOT, "schemas", "calibration-report.schema.json")) as _f:
    REPORT_SCHEMA = jsonschema.Draft202012Validator(json.load(_f))


@pytest.fixture(autouse=True)
def _reports_follow_the_schema(monkeypatch):
    """Every report a test's calibration returns follows the shipped schema."""
    real = kinecal.calibrate

    @functools.wraps(real)
    def checked(*args, **kwargs):
        result = real(*args, **kwargs)
        REPORT_SCHEMA.validate(result.report)
        return result

    monkeypatch.setattr(kinecal, "calibrate", checked)

SHARED = os.environ.get("KINECAL_SHARED_DATA") or os.path.join(ROOT, "..", "shared", "data")
SKIP_REASON = "needs ../shared/data"


def shared_data(*parts):
    """A path in ../shared/data (or $KINECAL_SHARED_DATA), the public data sets the real-data
    tests need. When it is missing: with ``CI`` set (non-empty) the test fails naming it;
    otherwise it is skipped, and ``conftest.py`` counts the skips in a line of the summary
    (``skipped: N tests need ../shared/data``)."""
    path = os.path.join(SHARED, *parts)
    if not os.path.exists(path):
        if os.environ.get("CI"):
            pytest.fail(f"{path} is missing, and CI is set: the real-data tests need "
                        "../shared/data (or KINECAL_SHARED_DATA)", pytrace=False)
        pytest.skip(f"{SKIP_REASON} ({path} not found)")
    return path


@pytest.fixture(scope="session")
def qkm_files(cli, tmp_path_factory):
    """The QKM data set converted by the command line: qkm.toml, identification.csv,
    validation.csv."""
    qkm = shared_data("qkm_hl6_faro")
    d = tmp_path_factory.mktemp("qkm")
    subprocess.run([cli, "dataset", "qkm-hl6", qkm, "--out", str(d)], check=True,
                   capture_output=True)
    return d


def read_measurement_csv(path):
    """A kinecal measurement file read with numpy alone: readings, positions, sites."""
    with open(path) as f:
        header = f.readline().strip().split(",")
    rows = np.genfromtxt(path, delimiter=",", skip_header=1, dtype=str)
    col = {name: i for i, name in enumerate(header)}
    joints = [c for c in header if c.startswith("v")]
    readings = rows[:, [col[c] for c in joints]].astype(float)
    positions = rows[:, [col["x"], col["y"], col["z"]]].astype(float)
    sites = [None if s == "ee" else s for s in rows[:, col["site"]]]
    return readings, positions, sites, list(rows[:, col["posture"]])


# --- The same answers as the command line, on real data ---------------------------------------


def test_qkm_from_numpy_gives_the_cli_parameters_and_held_out_figures(cli, qkm_files, tmp_path):
    d = qkm_files
    report = tmp_path / "r.json"
    subprocess.run([cli, "calibrate", "--robot", str(d / "qkm.toml"),
                    "--data", str(d / "identification.csv"),
                    "--validate", str(d / "validation.csv"),
                    "--estimate", "all,identifiable", "--quiet", "--report", str(report)],
                   check=True, capture_output=True)
    expected = json.loads(report.read_text())

    robot = kinecal.Robot.from_toml(d / "qkm.toml")
    q, p, s, labels = read_measurement_csv(d / "identification.csv")
    data = kinecal.Measurements(robot, q, p, sites=s, postures=labels)
    q, p, s, labels = read_measurement_csv(d / "validation.csv")
    held = kinecal.Measurements(robot, q, p, sites=s, postures=labels)
    result = kinecal.calibrate(robot, data, estimate="all,identifiable", validate=held)

    mine = {x["name"]: x for x in result.report["parameters"]}
    assert len(mine) == len(expected["parameters"]) == 72
    for theirs in expected["parameters"]:
        m = mine[theirs["name"]]
        assert m["estimated_flag"] == theirs["estimated_flag"]
        scale = max(abs(theirs["estimated"]), 1.0)
        assert abs(m["estimated"] - theirs["estimated"]) <= 1e-12 * scale, theirs["name"]
    for k in ["mean_position", "rms_position", "max_position"]:
        a = result.validation["after"][k]
        b = expected["validation"]["after"][k]
        assert abs(a - b) <= 1e-12 * b, k
    # The figure the README states (0.210 mm held-out mean).
    assert round(result.validation["after"]["mean_position"], 3) == 0.210
    assert result.converged
    # The calibrated robot is the one the report describes, and writes back as TOML.
    again = kinecal.Robot.from_toml(result.robot.to_toml())
    names = again.parameter_names
    for name, value in result.estimates.items():
        assert again.values[names.index(name)] == pytest.approx(value, rel=1e-12, abs=1e-12)


def _without_timings(path):
    """A report but for when it was made and how long its phases took."""
    report = json.loads(path.read_text())
    REPORT_SCHEMA.validate(report)
    report.pop("timings")
    report.pop("created")
    return report


def test_one_job_four_ways_gives_the_same_calibration(cli, qkm_files, monkeypatch):
    """The same job said by flags, by a spec file, from Python and as a batch row (CSV and
    TOML) writes byte-identical calibrated robots and reports equal but for the timings."""
    monkeypatch.chdir(qkm_files)
    job = ["--robot", "qkm.toml", "--data", "identification.csv", "--validate", "validation.csv",
           "--estimate", "all,identifiable", "--loss", "huber", "--huber-scale", "2"]

    def run(*args):
        done = subprocess.run([cli, *args], check=False, capture_output=True, text=True)
        assert done.returncode == 0, done.stderr
        return done

    # 1. Flags, written down as a spec.
    run("calibrate", *job, "--out", "flags.toml", "--report", "flags.json",
        "--write-spec", "job.toml", "--quiet")
    spec_text = (qkm_files / "job.toml").read_text()
    assert 'estimate = "all,identifiable"' in spec_text and "huber_scale = 2" in spec_text, spec_text
    # 2. The spec file, its outputs overridden by flags.
    run("calibrate", "--spec", "job.toml", "--out", "spec.toml", "--report", "spec.json",
        "--quiet")
    # 3. Python, the spec as a dict.
    spec = {
        "robot": "qkm.toml",
        "observations": [{"file": "identification.csv", "kind": "data"}],
        "selection": {"estimate": "all,identifiable"},
        "residuals": {"loss": "huber", "huber_scale": 2},
        "validation": {"files": [{"file": "validation.csv"}]},
        "outputs": {"robot": "python.toml", "report": "python.json"},
    }
    result = kinecal.calibrate(spec)
    assert result.robot.to_toml() == (qkm_files / "python.toml").read_text()
    assert json.loads(result.to_json()) == json.loads((qkm_files / "python.json").read_text())
    # 4. Batch: a CSV row and a TOML [[robots]] table.
    (qkm_files / "fleet.csv").write_text(
        "serial,robot,data,options\n"
        'QKM-1,qkm.toml,identification.csv,"--validate validation.csv '
        "--estimate all,identifiable --loss huber --huber-scale 2 "
        '--out batch.toml --report batch.json"\n'
    )
    run("batch", "fleet.csv", "--quiet")
    # The spec as one table of a fleet: every key under [[robots]].
    lines = []
    for line in spec_text.splitlines():
        if line.startswith("[["):
            line = "[[robots." + line[2:]
        elif line.startswith("["):
            line = "[robots." + line[1:]
        lines.append(line)
    table = "\n".join(lines).replace('"flags.', '"batch2.')
    (qkm_files / "fleet.toml").write_text('[[robots]]\nserial = "QKM-1"\n' + table + "\n")
    run("batch", "fleet.toml", "--quiet")

    robot = (qkm_files / "flags.toml").read_text()
    report = _without_timings(qkm_files / "flags.json")
    assert report["validation"]["after"]["mean_position"] > 0
    for name in ["spec", "python", "batch", "batch2"]:
        assert (qkm_files / f"{name}.toml").read_text() == robot, name
        assert _without_timings(qkm_files / f"{name}.json") == report, name


def test_a_spec_is_checked_like_flags(qkm_files, monkeypatch, tmp_path):
    monkeypatch.chdir(qkm_files)
    with pytest.raises(kinecal.KinecalError, match="unknown variant `lx`"):
        kinecal.calibrate({"robot": "qkm.toml", "solver": {"method": "lx"}})
    with pytest.raises(kinecal.KinecalError, match="^observations: no observation file"):
        kinecal.calibrate({"robot": "qkm.toml"})
    with pytest.raises(kinecal.KinecalError, match="^weights: standard deviations"):
        kinecal.calibrate({"robot": "qkm.toml",
                           "observations": [{"file": "identification.csv"}],
                           "residuals": {"weights": {"length": -1}}})
    with pytest.raises(TypeError, match="give no data"):
        kinecal.calibrate({"robot": "qkm.toml"}, kinecal.Measurements.read_csv(
            "identification.csv", kinecal.Robot.from_toml("qkm.toml")))
    # A spec file's paths are its folder's.
    job = tmp_path / "job.toml"
    job.write_text(f'robot = "{qkm_files / "qkm.toml"}"\n'
                   '[[observations]]\nfile = "missing.csv"\n')
    with pytest.raises(kinecal.KinecalError, match=str(tmp_path / "missing.csv")):
        kinecal.calibrate(str(job))


def test_reading_the_files_and_building_from_arrays_are_the_same_data(qkm_files):
    d = qkm_files
    robot = kinecal.Robot.from_toml(d / "qkm.toml")
    from_file = kinecal.Measurements.read_csv(d / "identification.csv", robot)
    q, p, s, labels = read_measurement_csv(d / "identification.csv")
    from_arrays = kinecal.Measurements(robot, q, p, sites=s, postures=labels)
    assert len(from_file) == len(from_arrays) == 46
    assert from_file.postures == from_arrays.postures == 46
    np.testing.assert_array_equal(from_file.readings, from_arrays.readings)
    assert from_file.to_csv(robot) == from_arrays.to_csv(robot)


def test_the_dataset_adapter_and_its_suggestion(qkm_files):
    ds = kinecal.dataset("qkm-hl6", shared_data("qkm_hl6_faro"))
    assert ds.suggested == {"estimate": "all,identifiable"}
    result = kinecal.calibrate(ds.robot, ds.identification, validate=ds.validation,
                               **ds.suggested)
    assert round(result.validation["after"]["mean_position"], 3) == 0.210
    assert [n for n, _ in kinecal.datasets()] == ["qkm-hl6", "fanuc-r2000ic", "ur10e-camera",
                                                  "ipa-ur10"]


def test_analyze_gives_the_cli_document(cli, qkm_files):
    d = qkm_files
    out = subprocess.run([cli, "analyze", "--robot", str(d / "qkm.toml"),
                          "--data", str(d / "identification.csv"), "--estimate", "all",
                          "--json"], check=True, capture_output=True, text=True).stdout
    expected = json.loads(out)
    robot = kinecal.Robot.from_toml(d / "qkm.toml")
    data = kinecal.Measurements.read_csv(d / "identification.csv", robot)
    mine = kinecal.analyze(robot, data, estimate="all")
    for key in ["rank", "identifiable", "undetermined", "unobservable", "parameter_ids"]:
        assert mine[key] == expected[key], key
    np.testing.assert_allclose(mine["singular_values_jacobian"],
                               expected["singular_values_jacobian"], rtol=1e-12)


# --- Kinematics against closed forms -----------------------------------------------------------


def test_fk_of_a_planar_dh_arm_is_the_closed_form():
    # Two revolute joints, a1 = 0.5, a2 = 0.3 (standard DH, metres, degrees).
    robot = kinecal.Robot.from_dh([[0.5, 0, 0, 0], [0.3, 0, 0, 0]], convention="standard",
                                  length_unit="m", angle_unit="deg")
    rng = np.random.default_rng(7)
    q = rng.uniform(-170, 170, size=(200, 2))
    poses = robot.fk(q)
    t1, t12 = np.radians(q[:, 0]), np.radians(q[:, 0] + q[:, 1])
    np.testing.assert_allclose(poses[:, 0], 0.5 * np.cos(t1) + 0.3 * np.cos(t12), atol=1e-12)
    np.testing.assert_allclose(poses[:, 1], 0.5 * np.sin(t1) + 0.3 * np.sin(t12), atol=1e-12)
    np.testing.assert_allclose(poses[:, 2], 0.0, atol=1e-12)
    # The transforms agree with the poses: rotation about z by q1 + q2.
    T = robot.fk(q, matrix=True)
    assert T.shape == (200, 4, 4)
    np.testing.assert_allclose(T[:, :3, 3], poses[:, :3], atol=1e-12)
    np.testing.assert_allclose(T[:, 0, 0], np.cos(t12), atol=1e-12)
    np.testing.assert_allclose(T[:, 3], np.tile([0, 0, 0, 1.0], (200, 1)), atol=0)


def test_fk_reproduces_the_thesis_table_4_2_posture_4():
    robot = kinecal.Robot.builtin("ge-a4")
    pose = robot.fk([-6.883, 13.301, 4.122, -28.645])  # one posture: a row back
    np.testing.assert_allclose(pose, [28.576, 13.995, 0.020, 47.600, 0.000, -90.000],
                               atol=0.01)


# --- Calibration recovers what it should -------------------------------------------------------


def test_a_perturbed_robot_is_recovered_from_its_simulated_measurements():
    nominal = kinecal.Robot.builtin("ge-a4")
    truth = nominal.with_value("link2.x", nominal.get("link2.x") + 0.05)
    truth = truth.with_value("joint1.offset", nominal.get("joint1.offset") + 0.3)
    rng = np.random.default_rng(3)
    q = rng.uniform(-40, 40, size=(30, 4))
    measured = truth.fk(q)
    data = kinecal.Measurements(nominal, q, measured[:, :3], orientations=measured[:, 3:])
    result = kinecal.calibrate(nominal, data, estimate="link2.x,joint1.offset")
    assert result.estimates["link2.x"] == pytest.approx(truth.get("link2.x"), abs=1e-9)
    assert result.estimates["joint1.offset"] == pytest.approx(truth.get("joint1.offset"),
                                                              abs=1e-9)
    assert result.report["rms_position_after"] < 1e-9
    np.testing.assert_allclose(result.robot.fk(q), measured, atol=1e-9)


def test_a_prior_makes_every_parameter_solvable():
    nominal = kinecal.Robot.builtin("ge-a4")
    truth = nominal.with_value("link2.x", nominal.get("link2.x") + 0.05)
    rng = np.random.default_rng(5)
    q = rng.uniform(-40, 40, size=(8, 4))
    measured = truth.fk(q)
    data = kinecal.Measurements(nominal, q, measured[:, :3], orientations=measured[:, 3:])
    result = kinecal.calibrate(nominal, data, estimate="all", method="gn",
                               prior="length=0.01,angle=0.05,slope=0.01")
    assert result.converged
    prior = result.report["prior"]
    assert prior["prior"] == "length=0.01,angle=0.05,slope=0.01"
    assert prior["rows"] == 38
    assert prior["data_rank"] < 38 and result.report["rank"] == 38
    assert prior["split_by_prior"]
    assert result.undetermined == []
    # Without it, Gauss-Newton refuses the rank-deficient system.
    with pytest.raises(kinecal.KinecalError):
        kinecal.calibrate(nominal, data, estimate="all", method="gn")


def test_weights_as_a_pair_or_a_dict(qkm_files):
    d = qkm_files
    robot = kinecal.Robot.from_toml(d / "qkm.toml")
    data = kinecal.Measurements.read_csv(d / "identification.csv", robot)
    pair = kinecal.calibrate(robot, data, weights=(0.05, 0.01))
    named = kinecal.calibrate(robot, data, weights={"angle": 0.01, "length": 0.05})
    assert pair.robot.to_toml() == named.robot.to_toml()
    assert pair.report["variance_factor"] == named.report["variance_factor"]
    # Either alone, the other at its default, as --weights and a spec take them.
    length = kinecal.calibrate(robot, data, weights={"length": 0.05})
    both = kinecal.calibrate(robot, data, weights={"length": 0.05, "angle": 0.001})
    assert length.report["variance_factor"] == both.report["variance_factor"]
    for bad, words in [
        ({"length": 0.05, "angel": 0.01}, "unknown field `angel`"),
        ({"length": "x", "angle": 0.01}, 'invalid type: string "x"'),
        ({"length": -1}, "must be positive"),
        ((0.05,), "expected \\(length, angle\\)"),
        ("0.05,0.01", "invalid type: string"),
    ]:
        with pytest.raises(kinecal.KinecalError, match=f"^weights: .*{words}"):
            kinecal.calibrate(robot, data, weights=bad)


def test_per_row_sigmas_and_validation_options(qkm_files):
    d = qkm_files
    robot = kinecal.Robot.from_toml(d / "qkm.toml")
    data = kinecal.Measurements.read_csv(d / "identification.csv", robot)
    folds = kinecal.calibrate(robot, data, estimate="all,identifiable", folds=6)
    cv = folds.cross_validation
    assert len(cv["folds"]) == 6
    assert 0.1 < cv["overall"]["mean"] < 0.5
    held = kinecal.calibrate(robot, data, estimate="all,identifiable", holdout=0.2, seed=4)
    assert held.validation["postures"] in (9, 10)
    with pytest.raises(kinecal.KinecalError, match="give one"):
        kinecal.calibrate(robot, data, holdout=0.2, folds=3)
    # A setting out of range is named by its keyword.
    for bad, keyword in [
        ({"holdout": 1.5}, "holdout"),
        ({"huber_scale": -1.0, "loss": "huber"}, "huber_scale"),
        ({"outlier_sigma": 0.0}, "outlier_sigma"),
        ({"prune": -2.0}, "prune"),
        ({"prior": "length=-1"}, "prior"),
        ({"prior": "lenght=1"}, "prior"),
    ]:
        with pytest.raises(kinecal.KinecalError, match=f"^{keyword}: "):
            kinecal.calibrate(robot, data, **bad)


# --- Inputs users get wrong --------------------------------------------------------------------


@pytest.mark.parametrize(
    "readings, error, words",
    [
        (np.zeros((3, 5)), kinecal.KinecalError, "expected shape (postures, 4)"),
        (np.zeros((2, 2, 4)), kinecal.KinecalError, "2-dimensional"),
        (np.full((2, 4), np.nan), kinecal.KinecalError, "row 0, column 0"),
        (np.array([[0, 0, np.inf, 0]]), kinecal.KinecalError, "column 2"),
        (np.array([[1e300, 0, 0, 0]]), kinecal.KinecalError, "within +-1e9"),
        (np.zeros((1, 4), dtype=complex), TypeError, "complex128"),
        (np.array([["a", "b", "c", "d"]]), TypeError, "expected real numbers"),
        ("abcd", TypeError, "expected real numbers"),
        (None, TypeError, "expected real numbers"),
        (np.zeros((0, 4)), kinecal.KinecalError, "expected shape"),
    ],
)
def test_bad_readings_raise_a_clear_exception(readings, error, words):
    robot = kinecal.Robot.builtin("ge-a4")
    with pytest.raises(error) as e:
        robot.fk(readings)
    assert words in str(e.value)
    with pytest.raises(error) as e:
        kinecal.Measurements(robot, readings, np.zeros((1, 3)))
    assert "readings" in str(e.value)


def test_integer_and_list_arrays_are_numbers():
    robot = kinecal.Robot.builtin("ge-a4")
    np.testing.assert_array_equal(robot.fk(np.zeros((2, 4), dtype=np.int32)),
                                  robot.fk([[0.0] * 4, [0.0] * 4]))
    # Fortran-ordered and strided arrays are read by value.
    q = np.asfortranarray(np.arange(12.0).reshape(3, 4))
    np.testing.assert_array_equal(robot.fk(q), robot.fk(np.ascontiguousarray(q)))
    np.testing.assert_array_equal(robot.fk(np.arange(24.0).reshape(3, 8)[:, ::2]),
                                  robot.fk(np.arange(24.0).reshape(3, 8)[:, ::2].copy()))


def test_bad_measurement_arrays_name_the_argument_and_row():
    robot = kinecal.Robot.builtin("ge-a4")
    q = np.zeros((3, 4))
    cases = [
        ({"positions": np.zeros((2, 3))}, "positions: expected shape [3, 3]"),
        ({"positions": np.zeros((3, 2))}, "positions: expected shape [3, 3]"),
        ({"positions": np.zeros((3, 3)), "orientations": np.zeros((3, 4))}, "orientations"),
        ({"positions": np.zeros((3, 3)), "sigma_position": [1, 0, 1]},
         "sigma_position: row 1: a standard deviation must be positive"),
        ({"positions": np.zeros((3, 3)), "sigma_angle": [1, 1, 1]}, "position-only rows"),
        ({"positions": np.zeros((3, 3)), "sites": ["tool", None, None]}, "not a site"),
        ({"positions": np.zeros((3, 3)), "sites": [None]}, "1 names for 3 rows"),
        ({"positions": np.zeros((3, 3)), "postures": ["a", "a", "b"]},
         "posture `a` has other readings"),
    ]
    q[1] = 1.0
    for kw, words in cases:
        with pytest.raises(kinecal.KinecalError) as e:
            kinecal.Measurements(robot, q, **kw)
        assert words in str(e.value), (kw, str(e.value))


def test_file_errors_carry_file_line_and_field(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("name = 'x'\n# a comment\nlength_unit = 'furlong'\n")
    with pytest.raises(kinecal.KinecalError) as e:
        kinecal.Robot.from_toml(bad)
    assert (e.value.file, e.value.line, e.value.field) == (str(bad), 3, "length_unit")
    assert "furlong" in str(e.value)
    robot = kinecal.Robot.builtin("ge-a4")
    csv = tmp_path / "m.csv"
    csv.write_text("posture,site,v1,v2,v3,v4,x,y,z\n1,ee,0,0,0,0,1,2,3\n2,ee,0,0,zero,0,1,2,3\n")
    with pytest.raises(kinecal.KinecalError) as e:
        kinecal.Measurements.read_csv(csv, robot)
    assert (e.value.file, e.value.line, e.value.field) == (str(csv), 3, "v3")
    with pytest.raises(kinecal.KinecalError) as e:
        kinecal.Robot.from_toml(tmp_path / "missing.toml")
    assert e.value.file == str(tmp_path / "missing.toml")
    assert isinstance(e.value, ValueError)


def test_options_are_checked():
    robot = kinecal.Robot.builtin("ge-a4")
    q = np.random.default_rng(1).uniform(-30, 30, size=(12, 4))
    data = kinecal.Measurements(robot, q, robot.fk(q)[:, :3])
    for kw, words in [
        ({"method": "newton"}, "method: unknown variant `newton`, expected one of `lm`"),
        ({"huber_spread": "wide"}, "huber_spread: unknown variant `wide`"),
        ({"repeats": 3}, "choose: repeats is the number of shuffles"),
        ({"loss": "cauchy"}, "loss: unknown variant `cauchy`"),
        ({"estimate": "links,nonsense"}, "nonsense"),
        ({"estimate": 42}, "estimate: invalid type: integer `42`, expected a string"),
        ({"weights": (0, 1)}, "weights"),
        ({"solution": "best"}, "solution: unknown variant `best`"),
        ({"max_iterations": 0}, "max_iterations"),
        ({"prune": -1}, "prune"),
    ]:
        with pytest.raises((kinecal.KinecalError, TypeError)) as e:
            kinecal.calibrate(robot, data, **kw)
        assert words in str(e.value), (kw, str(e.value))
    other = kinecal.Robot.from_dh([[0.5, 0, 0, 0], [0.3, 0, 0, 0]])
    with pytest.raises(kinecal.KinecalError, match="built for a robot with 4 joints"):
        kinecal.calibrate(other, data)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs named pipes")
def test_the_gil_is_released_while_a_job_runs(tmp_path, cli):
    """A job reading its data from a named pipe, in a thread, waits for this thread to write
    the data: it can only if the job released the GIL (a held GIL would leave both waiting; the
    watchdog, which needs no GIL, then ends the process instead of hanging it)."""
    import faulthandler

    subprocess.run([cli, "simulate", "--robot", "ge-a4", "--postures", "20", "--out", "d.csv"],
                   cwd=tmp_path, check=True, capture_output=True)
    data = (tmp_path / "d.csv").read_bytes()
    pipe = tmp_path / "pipe.csv"
    os.mkfifo(pipe)
    spec = {"job": "calibrate", "robot": "ge-a4",
            "observations": [{"file": str(pipe), "kind": "data"}]}
    done: list[Any] = []
    worker = threading.Thread(target=lambda: done.append(kinecal.run(spec)))
    faulthandler.dump_traceback_later(120, exit=True)
    try:
        worker.start()
        with open(pipe, "wb") as f:  # blocks until the job opens the pipe to read it
            f.write(data)
        worker.join()
    finally:
        faulthandler.cancel_dump_traceback_later()
    assert done and done[0]["converged"]


def test_robot_round_trips_and_urdf_export(tmp_path):
    robot = kinecal.Robot.builtin("ge-a4")
    text = robot.to_toml()
    again = kinecal.Robot.from_toml(text)
    np.testing.assert_array_equal(again.values, robot.values)
    assert again.parameter_ids[:2] == ["p1", "p2"] and len(again.parameter_names) == 38
    assert robot.units == ("in", "deg")
    # A real URDF with comments and several leaves: the tip is named.
    path = shared_data("urdf", "franka_panda", "panda.urdf")
    with pytest.raises(kinecal.KinecalError, match="several leaf links.*give tip=LINK"):
        kinecal.Robot.from_urdf(path)
    with pytest.raises(kinecal.KinecalError, match="no link named `nowhere`.*give base=LINK"):
        kinecal.Robot.from_urdf(path, base="nowhere", tip="panda_hand_tcp")
    r = kinecal.Robot.from_urdf(path, tip="panda_hand_tcp")
    assert r.dof == 7 and r.units == ("m", "rad")
    moved = r.with_value("link3.z", r.get("link3.z") + 0.001)
    written = moved.to_urdf(path, tip="panda_hand_tcp")
    p2 = tmp_path / "back.urdf"
    p2.write_text(written)
    back = kinecal.Robot.from_urdf(p2, tip="panda_hand_tcp")
    q = np.random.default_rng(5).uniform(-1, 1, size=(20, r.dof))
    np.testing.assert_allclose(back.fk(q), moved.fk(q), atol=1e-9)
    assert np.abs(back.fk(q)[:, :3] - r.fk(q)[:, :3]).max() > 1e-4


def test_a_urdf_tree_imports_with_its_tips_and_exports_back(tmp_path):
    path = os.path.join(ROOT, "examples", "trees", "upper_body.urdf")
    tips = ["left_marker", "right_marker"]
    r = kinecal.Robot.from_urdf(path, tip=tips)
    assert r.dof == 14
    q = np.random.default_rng(2).uniform(-1, 1, size=(10, r.dof))
    left, right = r.fk(q, site="left_marker"), r.fk(q, site="right_marker")
    np.testing.assert_array_equal(right, r.fk(q))
    # The left arm's joints (3-8) do not move the right marker; the torso's move both.
    q2 = q.copy()
    q2[:, 2:8] += 0.3
    np.testing.assert_allclose(r.fk(q2, site="right_marker"), right, atol=1e-15)
    assert np.abs(r.fk(q2, site="left_marker") - left).max() > 1e-3
    moved = r.with_value("link1.z", r.get("link1.z") + 0.001)
    back_path = tmp_path / "back.urdf"
    back_path.write_text(moved.to_urdf(path, tip=tips))
    back = kinecal.Robot.from_urdf(back_path, tip=tips)
    for site in tips:
        np.testing.assert_allclose(back.fk(q, site=site), moved.fk(q, site=site), atol=1e-9)


def test_a_tree_program_reaches_each_named_tool_and_holds_the_torso():
    path = os.path.join(ROOT, "examples", "trees", "upper_body.urdf")
    tips = ["left_marker", "right_marker"]
    nominal = kinecal.Robot.from_urdf(path, tip=tips)
    real = nominal
    for name, dv in [("link1.z", 0.002), ("joint1.offset", 0.003), ("joint3.offset", -0.004),
                     ("joint10.offset", 0.002), ("link12.x", 0.001)]:
        real = real.with_value(name, real.get(name) + dv)
    q = np.random.default_rng(7).uniform(-0.8, 0.8, size=(6, nominal.dof))
    # The end effector (right marker) alone: the torso's and the left arm's joints as
    # programmed; both tools, as the command line's --site ee,left_marker: each at its pose.
    right = kinecal.compensate(real, nominal, program=q)
    both = kinecal.compensate(real, nominal, program=q, site="ee,left_marker")
    shared = [0, 1]
    left_arm = list(range(2, 8))
    np.testing.assert_array_equal(right.readings[:, shared + left_arm], q[:, shared + left_arm])
    np.testing.assert_array_equal(both.readings[:, shared], q[:, shared])
    # Rows near a wrist's singularity are flagged (unreachable there); the rest reach both.
    usable = ~both.flagged
    assert usable.sum() >= 4
    for site in tips:
        meant = nominal.fk(q[usable], site=site)
        got = real.fk(both.readings[usable], site=site)
        np.testing.assert_allclose(got, meant, atol=1e-9)
    with pytest.raises(kinecal.KinecalError, match="lie on one branch"):
        kinecal.compensate(real, nominal, program=q, site="ee,right_marker")
    with pytest.raises(kinecal.KinecalError, match="several tools are for a program"):
        kinecal.compensate(real, nominal, targets=nominal.fk(q), site="ee,left_marker")


def test_urdf_masses_make_an_elastic_robot():
    path = shared_data("urdf", "universal_robots", "urdf_plain", "ur10_robot.urdf")
    rigid = kinecal.Robot.from_urdf(path, base="base_link", tip="tool0")
    elastic = kinecal.Robot.from_urdf(path, base="base_link", tip="tool0", masses=True)
    # A compliance and a lateral compliance per joint, mass and centre of each of 6 bodies.
    assert len(elastic.parameter_names) == len(rigid.parameter_names) + 12 + 24
    assert "joint2.compliance" in elastic.parameter_names
    unit = elastic.parameter_units[elastic.parameter_names.index("joint2.lateral")]
    assert unit == "rad/(N m)"
    q = np.random.default_rng(3).uniform(-3, 3, size=(10, 6))
    # Zero compliance: the same poses as the rigid robot.
    np.testing.assert_allclose(elastic.fk(q), rigid.fk(q), atol=1e-12)
    # Joint 2 yields: the arm sags, by millimetres at the tool (2e-5 rad/(N m) under ~100 N m).
    soft = elastic.with_value("joint2.compliance", 2e-5)
    sag = np.linalg.norm(soft.fk(q)[:, :3] - rigid.fk(q)[:, :3], axis=1)
    assert 1e-4 < sag.max() < 1e-2, sag
    # Compliances that cannot converge are refused, not turned into poses.
    with pytest.raises(kinecal.KinecalError, match="gravity equilibrium did not converge"):
        elastic.with_value("joint2.compliance", 1.0).fk(q)


def test_the_python_pages_run_as_shown(monkeypatch):
    # From the repository root, where the pages' paths (../shared/data) hold: every Python
    # block of the README and of docs/ is a doctest.
    shared_data("qkm_hl6_faro")
    monkeypatch.chdir(ROOT)
    attempted = 0
    pages = ["README.md"] + sorted(
        os.path.join("docs", p) for p in os.listdir(os.path.join(ROOT, "docs"))
        if p.endswith(".md"))
    for page in pages:
        result = doctest.testfile(os.path.join(ROOT, page), module_relative=False,
                                  optionflags=doctest.NORMALIZE_WHITESPACE)
        assert result.failed == 0, page
        attempted += result.attempted
    assert attempted >= 10


def test_the_type_stubs_name_what_the_package_has():
    # The package's annotations live in __init__.py itself (a __init__.pyi would shadow them);
    # _native.pyi describes the compiled module (stubtest in test.sh checks the signatures).
    here = os.path.dirname(kinecal.__file__)
    assert not os.path.exists(os.path.join(here, "__init__.pyi"))
    assert os.path.exists(os.path.join(here, "py.typed"))
    with open(os.path.join(here, "_native.pyi")) as f:
        tree = ast.parse(f.read())
    native = kinecal._native
    top = {n.name for n in tree.body if isinstance(n, (ast.ClassDef, ast.FunctionDef))}
    assert top | {"__version__"} == set(native.__all__)
    for cls in tree.body:
        if isinstance(cls, ast.ClassDef) and cls.name in ("Robot", "Measurements"):
            stubbed = {n.name for n in cls.body if isinstance(n, ast.FunctionDef)}
            actual = {n for n in dir(getattr(native, cls.name)) if not n.startswith("_")}
            assert stubbed - {"__new__", "__len__"} == actual, cls.name
    # Everything the package exports is annotated, arguments and results.
    for name in kinecal.__all__:
        obj = getattr(kinecal, name)
        if inspect.isfunction(obj):
            sig = inspect.signature(obj)
            assert sig.return_annotation is not inspect.Signature.empty, name
            for p in sig.parameters.values():
                assert p.annotation is not inspect.Parameter.empty, (name, p.name)


def test_random_arrays_either_work_or_raise_a_clear_exception():
    # 3,000 random inputs: shapes, dtypes and values users and buggy scripts produce.
    robot = kinecal.Robot.builtin("ge-a4")
    rng = np.random.default_rng(20261124)
    specials = [np.nan, np.inf, -np.inf, 1e300, -1e10, 0.0, 1e-320]
    dtypes = [np.float64, np.float32, np.int64, np.uint8, np.bool_, np.complex128, object, "U3"]

    def random_array():
        ndim = int(rng.integers(0, 4))
        shape = tuple(int(rng.integers(0, 6)) for _ in range(ndim))
        a = rng.normal(0, 30, size=shape)
        if a.size and rng.random() < 0.3:
            a.flat[int(rng.integers(0, a.size))] = specials[int(rng.integers(0, len(specials)))]
        dtype = dtypes[int(rng.integers(0, len(dtypes)))] if rng.random() < 0.2 else np.float64
        try:
            with np.errstate(invalid="ignore", over="ignore"):
                return a.astype(dtype)
        except (TypeError, ValueError):
            return a

    worked = 0
    for _ in range(1000):
        q, p, o = random_array(), random_array(), random_array() if rng.random() < 0.5 else None
        for call in (lambda q=q: robot.fk(q),
                     lambda q=q: robot.fk(q, matrix=True),
                     lambda q=q, p=p, o=o: kinecal.Measurements(robot, q, p, orientations=o)):
            try:
                out = call()
            except (kinecal.KinecalError, TypeError) as e:
                assert str(e), "an exception without a message"
                continue
            worked += 1
            if isinstance(out, np.ndarray):
                assert np.isfinite(out).all()
    assert worked > 0


def test_tracker_series_from_another_lab(cli, tmp_path):
    """The UR10 tracker data as another lab wrote it (';', decimal commas, mm, its own column
    names): read with its units and a session per series, identified on series A and checked
    on series C, a session identification never saw (its frame re-estimated on it)."""
    ur10 = shared_data("ipa_ur10_tracker")
    yaml = shared_data("urdf", "universal_robots", "config", "ur10", "default_kinematics.yaml")
    subprocess.run([cli, "import", "ur", yaml, "--out", str(tmp_path / "ur10.toml")],
                   check=True, capture_output=True)
    robot = kinecal.Robot.from_toml(tmp_path / "ur10.toml")
    joints = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
              "wrist_2_joint", "wrist_3_joint"]
    columns = [",".join([f"v{i + 1}={j}" for i, j in enumerate(joints)]
                        + [f"{a}=measurement_{a}" for a in "xyz"])]
    a = kinecal.Measurements.read_csv(os.path.join(ur10, "Series_A", "measurements_grid.csv"),
                                      robot, columns=columns, length_unit="mm", session="A")
    c = kinecal.Measurements.read_csv(
        os.path.join(ur10, "Series_C", "measurements_random_poses.csv"), robot,
        columns=columns, length_unit="mm", session="C")
    with pytest.raises(kinecal.KinecalError, match="length_unit"):
        kinecal.Measurements.read_csv(os.path.join(ur10, "Series_C",
                                                   "measurements_random_poses.csv"),
                                      robot, columns=columns, length_unit="furlong")
    result = kinecal.calibrate(robot, a, estimate="identifiable", validate=c)
    report = result.report
    assert report["converged"], report["termination"]
    assert report["iterations"] <= 30
    validation = report["validation"]
    assert validation["sessions_refitted"] == ["C"]
    # The data set's README: an independent fit reaches a held-out mean of about 0.52 mm on C.
    assert validation["after"]["mean_position"] < 0.52e-3 * 1.02


# --- The command line's other commands: compensate, plan, simulate ------------------------------

# A PUMA 560 (standard DH, metres and degrees): six joints, so that poses can be reached.
PUMA = [[0, 90, 0, 0], [0.4318, 0, 0, 0], [0.0203, -90, 0.15005, 0], [0, 90, 0.4318, 0],
        [0, -90, 0, 0], [0, 0, 0, 0]]


def rotation_zyx(euler_deg):
    """R = Rz(alpha) Ry(beta) Rx(gamma) per row, with numpy alone."""
    a, b, g = np.radians(np.asarray(euler_deg)).T
    ca, sa, cb, sb, cg, sg = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(g), np.sin(g)
    return np.stack([
        np.stack([ca * cb, ca * sb * sg - sa * cg, ca * sb * cg + sa * sg], -1),
        np.stack([sa * cb, sa * sb * sg + ca * cg, sa * sb * cg - ca * sg], -1),
        np.stack([-sb, cb * sg, cb * cg], -1),
    ], -2)


def write_rows(path, header, labels, rows):
    """A CSV file with the exact values of `rows` (repr round-trips a float)."""
    with open(path, "w") as f:
        f.write(",".join(header) + "\n")
        f.writelines(",".join([str(label)] + [repr(float(v)) for v in row]) + "\n"
                     for label, row in zip(labels, rows))


def read_rows(path):
    """A CSV file as a header and rows of strings."""
    with open(path) as f:
        lines = f.read().splitlines()
    return lines[0].split(","), [line.split(",") for line in lines[1:]]


@pytest.fixture(scope="module")
def puma(tmp_path_factory):
    """A nominal PUMA and a perturbed twin (the real robot), both as files the command line
    reads and as the robots read back from them (so both sides use the same numbers)."""
    d = tmp_path_factory.mktemp("puma")
    nominal = kinecal.Robot.from_dh(PUMA, length_unit="m", angle_unit="deg", name="puma")
    (d / "nominal.toml").write_text(nominal.to_toml())
    nominal = kinecal.Robot.from_toml(d / "nominal.toml")
    truth = kinecal.simulate(nominal, 1, seed=5,
                             perturb_std={"length": 0.002, "angle": 0.2}).truth
    (d / "true.toml").write_text(truth.to_toml())
    truth = kinecal.Robot.from_toml(d / "true.toml")
    assert np.abs(truth.values - nominal.values).max() > 1e-3
    return d, nominal, truth


def puma_postures(seed, n):
    """Postures away from the PUMA's singularities (the wrist's at q5 = 0, the elbow's
    stretched near q3 = -87 deg)."""
    rng = np.random.default_rng(seed)
    q = rng.uniform(-90, 90, size=(n, 6))
    q[:, 2] = rng.uniform(-60, 60, size=n)
    q[:, 4] = rng.choice([-1, 1], size=n) * rng.uniform(20, 80, size=n)
    return q


def compensate_cli(cli, d, infile, *extra):
    out = d / ("out-" + infile)
    # Exit code 3 when a row is flagged: the rows are compared, not the code.
    subprocess.run([cli, "compensate", "--robot", "true.toml", "--nominal", "nominal.toml",
                    "--in", infile, "--out", out.name, *extra], cwd=d, capture_output=True,
                   check=False)
    return read_rows(out)


def assert_same_as_cli(result, rows):
    dof = result.readings.shape[1]
    assert len(rows) == len(result)
    np.testing.assert_array_equal(np.array([r[1:1 + dof] for r in rows], dtype=float),
                                  result.readings)
    np.testing.assert_allclose(np.array([r[1 + dof] for r in rows], dtype=float),
                               result.position_error, rtol=1e-6, atol=0)
    attitude = [float(r[2 + dof]) if r[2 + dof] else np.nan for r in rows]
    np.testing.assert_allclose(attitude, result.attitude_error, rtol=1e-6, atol=0)
    assert [int(r[3 + dof]) for r in rows] == result.iterations.tolist()
    assert [r[4 + dof] for r in rows] == result.flags


def test_compensated_programs_reach_the_nominal_poses_as_the_cli_computes_them(cli, puma):
    d, nominal, truth = puma
    q = puma_postures(11, 40)
    result = kinecal.compensate(truth, nominal, program=q)
    assert result.readings.shape == (40, 6)
    # Through the real robot, the compensated readings give the poses the nominal robot means
    # (a few rows near an ill-conditioned posture are flagged, not silently wrong).
    ok = ~result.flagged
    assert ok.sum() >= 36, result.flags
    reached, meant = truth.fk(result.readings, matrix=True), nominal.fk(q, matrix=True)
    np.testing.assert_allclose(reached[ok], meant[ok], atol=1e-9)
    assert np.abs(truth.fk(q)[:, :3] - nominal.fk(q)[:, :3]).max() > 1e-3  # it had to move
    assert (result.position_error[ok] < 1e-6).all() and (result.attitude_error[ok] < 1e-6).all()
    assert (result.position_error[result.unreachable] > 1e-6).all()
    write_rows(d / "program.csv", ["posture"] + [f"v{j}" for j in range(1, 7)], range(1, 41), q)
    assert_same_as_cli(result, compensate_cli(cli, d, "program.csv")[1])
    # Positions only: the meant positions, with the attitude left as it comes.
    moved = kinecal.compensate(truth, nominal, program=q, position_only=True)
    ok = ~moved.unreachable
    assert ok.sum() >= 36, moved.flags
    np.testing.assert_allclose(truth.fk(moved.readings)[ok, :3], nominal.fk(q)[ok, :3],
                               atol=1e-9)
    assert np.isnan(moved.attitude_error).all()
    assert_same_as_cli(moved, compensate_cli(cli, d, "program.csv", "--position-only")[1])


def test_compensated_targets_with_and_without_seeds(cli, puma):
    d, nominal, truth = puma
    q = puma_postures(12, 25)
    targets = np.vstack([nominal.fk(q), [[3.0, 0, 0, 0, 0, 0]]])  # and one out of reach
    result = kinecal.compensate(truth, nominal, targets=targets)
    assert result.unreachable[-1] and "unreachable" in result.flags[-1]
    reached = ~result.unreachable
    assert reached.sum() >= 20
    T = truth.fk(result.readings[reached], matrix=True)
    np.testing.assert_allclose(T[:, :3, 3], targets[reached, :3], atol=1e-9)
    np.testing.assert_allclose(T[:, :3, :3], rotation_zyx(targets[reached, 3:]), atol=1e-9)
    # Seeded by the nominal model as the command line seeds a targets file.
    write_rows(d / "targets.csv", ["target", "x", "y", "z", "alpha", "beta", "gamma"],
               [f"t{i}" for i in range(26)], targets)
    assert_same_as_cli(result, compensate_cli(cli, d, "targets.csv")[1])
    # With seeds: the solution of each seed's configuration, reached.
    seeded = kinecal.compensate(truth, nominal, targets=targets[:-1], seeds=q)
    ok = ~seeded.flagged
    assert ok.sum() >= 22, seeded.flags
    # A correction near each seed, not a new branch.
    assert np.median(np.abs(seeded.readings - q)) < 1.0
    np.testing.assert_allclose(truth.fk(seeded.readings, matrix=True)[ok, :3, 3],
                               targets[:-1, :3][ok], atol=1e-9)
    # Positions as targets: no attitude error, the same as the command line's.
    positions = kinecal.compensate(truth, nominal, targets=targets[:-1, :3])
    assert np.isnan(positions.attitude_error).all()
    write_rows(d / "positions.csv", ["target", "x", "y", "z"], [f"t{i}" for i in range(25)],
               targets[:-1, :3])
    assert_same_as_cli(positions, compensate_cli(cli, d, "positions.csv")[1])
    np.testing.assert_allclose(truth.fk(positions.readings)[~positions.unreachable, :3],
                               targets[:-1, :3][~positions.unreachable], atol=1e-9)
    # position_only leaves the targets' attitudes out: the same as positions.
    np.testing.assert_array_equal(
        kinecal.compensate(truth, nominal, targets=targets[:-1], position_only=True).readings,
        positions.readings)
    # In a configuration: each row in it (checked against the command line's), or flagged so.
    front_up = kinecal.compensate(truth, nominal, targets=targets[:-1],
                                  configuration="shoulder=front,elbow=up,wrist=noflip")
    ok = ~front_up.flagged
    assert ok.sum() >= 20, front_up.flags
    np.testing.assert_allclose(truth.fk(front_up.readings, matrix=True)[ok, :3, 3],
                               targets[:-1, :3][ok], atol=1e-9)
    assert_same_as_cli(
        kinecal.compensate(truth, nominal, targets=targets,
                           configuration="shoulder=front,elbow=up,wrist=noflip"),
        compensate_cli(cli, d, "targets.csv", "--configuration",
                       "shoulder=front,elbow=up,wrist=noflip")[1])


def test_compensation_flags_and_its_settings():
    ge = kinecal.Robot.builtin("ge-a4")
    q = np.array([[-10.0, 10.0, 2.0, 0.0], [-10.0, 20.0, 2.0, 0.0]])  # joint 2: 6 to 14
    moved = ge.with_value("link2.x", ge.get("link2.x") + 0.05)
    result = kinecal.compensate(moved, ge, program=q, position_only=True)
    assert result.out_of_range.shape == (2, 4)
    assert result.out_of_range[1, 1] and not result.out_of_range[0].any()
    assert result.flags[1] == "outside range: joint 2" and result.flags[0] == ""
    assert result.flagged.tolist() == [False, True]
    assert "1 flagged" in repr(result)
    np.testing.assert_allclose(moved.fk(result.readings)[:, :3], ge.fk(q)[:, :3], atol=1e-9)
    # A branch of 1e-9 deg flags a row whose revolute joints moved at all.
    assert kinecal.compensate(moved, ge, program=q[:1], position_only=True,
                              branch=1e-9).branch.all()
    # A target out of reach is unreachable, unless the tolerance allows for that much.
    far = [[100.0, 0.0, 0.0]]
    assert kinecal.compensate(ge, ge, targets=far).unreachable.all()
    assert not kinecal.compensate(ge, ge, targets=far, tolerance={"length": 200}).unreachable[0]


@pytest.mark.parametrize(
    "kw, error, words",
    [
        ({}, kinecal.KinecalError, "program, targets: give one"),
        ({"program": np.zeros((2, 4)), "targets": np.zeros((2, 3))}, kinecal.KinecalError,
         "program, targets: give one"),
        ({"program": np.zeros((2, 5))}, kinecal.KinecalError,
         "program: expected shape (rows, 4)"),
        ({"program": "abc"}, TypeError, "program: expected real numbers"),
        ({"program": [[0, 0, np.nan, 0]]}, kinecal.KinecalError, "program: row 0, column 2"),
        ({"targets": np.zeros((2, 4))}, kinecal.KinecalError,
         "targets: expected shape (rows, 3) or (rows, 6)"),
        ({"targets": np.zeros((2, 3)), "seeds": np.zeros((3, 4))}, kinecal.KinecalError,
         "seeds: 3 rows for 2 targets"),
        ({"program": np.zeros((2, 4)), "seeds": np.zeros((2, 4))}, kinecal.KinecalError,
         "seeds: a program's readings are its own seeds"),
        ({"targets": [[0.3, 0.0, 0.5, 0.0, 400.0, 0.0]]}, kinecal.KinecalError,
         "targets: row 1: beta = 400 deg is more than a turn"),
        ({"targets": [[0.3, 0.0, 0.5], [300.0, 0.0, 500.0]]}, kinecal.KinecalError,
         "targets: row 2: the position lies"),
        ({"targets": np.zeros((2, 3)), "configuration": "elbow=sideways"},
         kinecal.KinecalError, "configuration: elbow=sideways: expected up or down"),
        ({"targets": np.zeros((2, 3)), "configuration": "elbow=up"}, kinecal.KinecalError,
         "configuration: shoulder, elbow and wrist name the configurations of an arm of six"),
        ({"program": np.zeros((2, 4)), "configuration": "+,+,+,+"}, kinecal.KinecalError,
         "configuration: is for Cartesian targets"),
        ({"program": np.zeros((1, 4)), "site": "tcp"}, kinecal.KinecalError,
         "site: unknown site `tcp` (the robot file defines: ee)"),
        ({"program": np.zeros((1, 4)), "singular": 1.5}, kinecal.KinecalError,
         "singular: expected a fraction from 0 to below 1, not 1.5"),
        ({"program": np.zeros((1, 4)), "branch": -1.0}, kinecal.KinecalError,
         "branch: expected a positive angle, not -1"),
        ({"program": np.zeros((1, 4)), "tolerance": {"lenght": 1}}, kinecal.KinecalError,
         "tolerance: unknown field `lenght`, expected `length` or `angle`"),
        ({"program": np.zeros((1, 4)), "tolerance": (1, "x")}, kinecal.KinecalError,
         "tolerance: invalid type: string \"x\", expected f64"),
        ({"program": np.zeros((1, 4)), "tolerance": {"length": -1}}, kinecal.KinecalError,
         "tolerance: the length must be positive and finite, not -1"),
        ({"program": np.zeros((1, 4)), "tolerance": 0.1}, kinecal.KinecalError,
         "tolerance: invalid type: floating point `0.1`, expected struct LengthAngle"),
    ],
)
def test_compensation_input_mistakes_are_named(kw, error, words):
    ge = kinecal.Robot.builtin("ge-a4")
    with pytest.raises(error) as e:
        kinecal.compensate(ge, ge, **kw)
    assert words in str(e.value), str(e.value)


def test_compensation_needs_the_same_robot_twice():
    ge = kinecal.Robot.builtin("ge-a4")
    other = kinecal.Robot.from_dh([[0.5, 0, 0, 0]] * 4)  # four joints, none prismatic
    with pytest.raises(kinecal.KinecalError, match="^nominal: the calibrated and the nominal"):
        kinecal.compensate(ge, other, program=np.zeros((1, 4)))


def plan_cli(cli, cwd, *args):
    out = subprocess.run([cli, "plan", "--json", "--out", "plan-out.csv", *args], cwd=cwd,
                         check=True, capture_output=True, text=True).stdout
    with open(os.path.join(cwd, "plan-out.csv")) as f:
        return json.loads(out), f.read()


def assert_plan_is(p, doc, text):
    assert p.to_csv() == text
    assert p.criterion == doc["criterion"] and p.rank == doc["rank"] and p.rows == doc["rows"]
    assert p.parameters == doc["parameter_names"]
    assert p.pool_candidates == doc["pool_candidates"]
    assert (p.exchanges, p.passes) == (doc["exchanges"], doc["passes"])
    for mine, theirs in [(p.value, doc["value"]), (p.efficiency, doc["efficiency"]),
                         (p.condition_number, doc["condition_number"])]:
        assert mine == pytest.approx(theirs, rel=1e-12)
    assert p.values == pytest.approx(doc["values"], rel=1e-12)
    assert p.random == (doc["random"]["draws"], pytest.approx(doc["random"]["median_value"]),
                        pytest.approx(doc["random"]["median_efficiency"]),
                        doc["random"]["at_least_as_good_as"])
    assert p.labels == [q["label"] for q in doc["postures"]]
    assert p.kept.tolist() == [q["kept"] for q in doc["postures"]]
    assert p.chosen.tolist() == [q["candidate"] for q in doc["postures"] if not q["kept"]]
    np.testing.assert_array_equal(p.readings, [q["readings"] for q in doc["postures"]])
    np.testing.assert_allclose(p.leverage, [q["leverage"] for q in doc["postures"]], rtol=1e-12)
    # Independent of the command line: a plan that determines every parameter carries n
    # parameters' worth of information in all.
    assert p.rank == len(p.parameters)
    assert p.leverage.sum() == pytest.approx(len(p.parameters), rel=1e-9)


def test_plan_of_measured_candidates_is_the_cli_plan(cli, qkm_files):
    d = qkm_files
    robot = kinecal.Robot.from_toml(d / "qkm.toml")
    data = kinecal.Measurements.read_csv(d / "identification.csv", robot)
    p = kinecal.plan(robot, data, count=20, estimate="identifiable,slopes")
    doc, text = plan_cli(cli, d, "--robot", "qkm.toml", "--candidates", "identification.csv",
                         "--count", "20", "--estimate", "identifiable,slopes")
    assert_plan_is(p, doc, text)
    assert len(p.chosen) == 20 and p.random.at_least_as_good_as == 100
    # The chosen observations are the candidates' own, and calibrate as the README's do.
    assert p.observations.postures == 20
    assert p.to_csv() == p.observations.to_csv(robot)
    np.testing.assert_array_equal(p.observations.readings, data.readings[p.chosen])


def test_plan_of_sampled_and_given_postures_is_the_cli_plan(cli, tmp_path):
    ge = kinecal.Robot.builtin("ge-a4")
    p = kinecal.plan(ge, sample=200, count=8, seed=3, criterion="i")
    doc, text = plan_cli(cli, tmp_path, "--robot", "ge-a4", "--sample", "200", "--seed", "3",
                         "--count", "8", "--criterion", "i")
    assert_plan_is(p, doc, text)
    assert text.startswith("posture,v1,v2,v3,v4\n")
    # The same postures given as an array (and as a postures file to the command line), with
    # two of them kept, positions only, weights and a fixed parameter.
    q = p.readings
    pool = np.random.default_rng(4).uniform(-40, 40, size=(60, 4))
    mine = kinecal.plan(ge, pool, count=5, keep=q[:2], position_only=True,
                        weights=(0.01, 0.1), fix="slopes", criterion="a")
    write_rows(tmp_path / "pool.csv", ["posture", "v1", "v2", "v3", "v4"], range(1, 61), pool)
    write_rows(tmp_path / "keep.csv", ["posture", "v1", "v2", "v3", "v4"], range(1, 3), q[:2])
    doc, text = plan_cli(cli, tmp_path, "--robot", "ge-a4", "--candidates", "pool.csv",
                         "--keep", "keep.csv", "--count", "5", "--position-only",
                         "--weights", "length=0.01,angle=0.1", "--fix", "slopes",
                         "--criterion", "a")
    assert_plan_is(mine, doc, text)
    assert mine.kept.tolist() == [True, True] + [False] * 5
    np.testing.assert_array_equal(mine.readings[2:], pool[mine.chosen])
    assert all(p.startswith("link") or "offset" in p for p in mine.parameters)


@pytest.mark.parametrize(
    "args, kw, error, words",
    [
        ((), {"count": 3}, kinecal.KinecalError, "candidates, sample: give one"),
        ((np.zeros((5, 4)),), {"count": 3, "sample": 10}, kinecal.KinecalError,
         "candidates, sample: give one"),
        ((), {"count": 0, "sample": 10}, kinecal.KinecalError, "count: must be at least 1"),
        ((), {"count": -2, "sample": 10}, kinecal.KinecalError,
         "count: invalid value: integer `-2`, expected usize"),
        ((), {"count": 2.5, "sample": 10}, kinecal.KinecalError,
         "count: invalid type: floating point `2.5`, expected usize"),
        ((), {"count": 3, "sample": True}, kinecal.KinecalError,
         "sample: invalid type: boolean `true`, expected usize"),
        ((), {"count": 3, "sample": 10, "seed": -1}, kinecal.KinecalError,
         "seed: invalid value: integer `-1`, expected u64"),
        ((), {"count": 3, "sample": 10, "criterion": "z"}, kinecal.KinecalError,
         "criterion: unknown variant `z`, expected one of `d`"),
        ((), {"count": 3, "sample": 10, "sites": ["tcp"]}, kinecal.KinecalError,
         "sites: unknown site `tcp`"),
        ((), {"count": 3, "sample": 10, "sites": []}, kinecal.KinecalError, "sites: an empty"),
        ((np.zeros((5, 3)),), {"count": 3}, kinecal.KinecalError,
         "candidates: expected shape (rows, 4)"),
        ((), {"count": 3, "sample": 10, "keep": "abc"}, TypeError, "keep: expected real"),
        ((), {"count": 3, "sample": 10, "estimate": "nonsense"}, kinecal.KinecalError,
         "nonsense"),
        ((), {"count": 3, "sample": 10, "weights": (0, 1)}, kinecal.KinecalError, "weights"),
        ((), {"count": 3, "sample": 10, "orientation_error": "quat"}, kinecal.KinecalError,
         "orientation_error: unknown variant `quat`"),
    ],
)
def test_plan_input_mistakes_are_named(args, kw, error, words):
    ge = kinecal.Robot.builtin("ge-a4")
    with pytest.raises(error) as e:
        kinecal.plan(ge, *args, **kw)
    assert words in str(e.value), str(e.value)


def test_plan_sites_describe_postures_not_measurements():
    ge = kinecal.Robot.builtin("ge-a4")
    q = np.random.default_rng(1).uniform(-30, 30, size=(12, 4))
    data = kinecal.Measurements(ge, q, ge.fk(q)[:, :3])
    with pytest.raises(kinecal.KinecalError, match="^sites: describes postures"):
        kinecal.plan(ge, data, count=3, sites=["ee"])
    with pytest.raises(kinecal.KinecalError, match="^candidates: built for a robot"):
        kinecal.plan(kinecal.Robot.from_dh(PUMA), data, count=3)


def test_simulated_measurements_are_the_cli_ones_and_the_true_robot_gives_them(cli, tmp_path):
    ge = kinecal.Robot.builtin("ge-a4")
    sim = kinecal.simulate(ge, 30, seed=7, perturb={"p3": 0.1, "joint2.offset": -0.5},
                           noise={"length": 0.001, "angle": 0.01})
    subprocess.run([cli, "simulate", "--robot", "ge-a4", "--postures", "30", "--seed", "7",
                    "--perturb", "p3=+0.1,joint2.offset=-0.5",
                    "--noise", "length=0.001,angle=0.01", "--out", "data.csv",
                    "--truth", "truth.toml"], cwd=tmp_path, check=True, capture_output=True)
    assert sim.measurements.to_csv(ge) == (tmp_path / "data.csv").read_text()
    assert sim.truth.to_toml() == (tmp_path / "truth.toml").read_text()
    assert sim.truth.get("p3") - ge.get("p3") == pytest.approx(0.1, abs=1e-12)
    assert sim.truth.get("joint2.offset") - ge.get("joint2.offset") == pytest.approx(-0.5)
    # Without noise, the measurements are the true robot's forward kinematics.
    clean = kinecal.simulate(ge, 30, seed=7, perturb={"p3": 0.1, "joint2.offset": -0.5})
    _, rows = read_rows_text(clean.measurements.to_csv(ge))
    measured = np.array([r[6:12] for r in rows], dtype=float)
    np.testing.assert_allclose(measured, clean.truth.fk(clean.measurements.readings),
                               atol=1e-9)
    np.testing.assert_array_equal(clean.measurements.readings, sim.measurements.readings)
    # The noise has the stated spread (2,000 postures: within 5 %).
    many = kinecal.simulate(ge, 2000, seed=8, noise=(0.001, 0.01))
    _, rows = read_rows_text(many.measurements.to_csv(ge))
    error = np.array([r[6:12] for r in rows], dtype=float) - ge.fk(many.measurements.readings)
    assert np.std(error[:, :3]) == pytest.approx(0.001, rel=0.05)
    assert np.std(error[:, 3:]) == pytest.approx(0.01, rel=0.05)
    # Random perturbations and positions only, as the command line makes them.
    sim = kinecal.simulate(ge, 12, seed=9, perturb_std={"length": 0.01, "angle": 0.1},
                           position_only=True)
    subprocess.run([cli, "simulate", "--robot", "ge-a4", "--postures", "12", "--seed", "9",
                    "--perturb-std", "length=0.01,angle=0.1", "--position-only",
                    "--out", "data2.csv", "--truth", "truth2.toml"], cwd=tmp_path, check=True,
                   capture_output=True)
    assert sim.measurements.to_csv(ge) == (tmp_path / "data2.csv").read_text()
    assert sim.truth.to_toml() == (tmp_path / "truth2.toml").read_text()
    assert sim.measurements.kinds == {"position": 12}


def read_rows_text(text):
    lines = text.splitlines()
    return lines[0].split(","), [line.split(",") for line in lines[1:]]


def test_simulation_at_given_postures_calibrates_back_to_the_truth():
    puma = kinecal.Robot.from_dh(PUMA, length_unit="m", angle_unit="deg")
    q = np.random.default_rng(6).uniform(-120, 120, size=(40, 6))
    sim = kinecal.simulate(puma, q, perturb={"link3.x": 0.003, "joint4.offset": 0.2})
    np.testing.assert_array_equal(sim.measurements.readings, q)
    result = kinecal.calibrate(puma, sim.measurements, estimate="link3.x,joint4.offset")
    assert result.estimates["link3.x"] == pytest.approx(sim.truth.get("link3.x"), abs=1e-9)
    assert result.estimates["joint4.offset"] == pytest.approx(sim.truth.get("joint4.offset"),
                                                              abs=1e-9)


@pytest.mark.parametrize(
    "postures, kw, error, words",
    [
        (0, {}, kinecal.KinecalError, "postures: expected between 1 and"),
        (np.zeros((3, 5)), {}, kinecal.KinecalError, "postures: expected shape (rows, 4)"),
        ("many", {}, TypeError, "postures: expected real numbers"),
        (5, {"seed": -1}, kinecal.KinecalError, "seed: invalid value: integer `-1`, expected u64"),
        (5, {"seed": 1.5}, kinecal.KinecalError, "seed: invalid type: floating point `1.5`"),
        (5, {"perturb": {"nonsense": 1.0}}, kinecal.KinecalError, "perturb: "),
        (5, {"perturb": {"p1": "x"}}, kinecal.KinecalError,
         "perturb: invalid type: string \"x\", expected f64"),
        (5, {"perturb": {"p1": float("inf")}}, kinecal.KinecalError,
         "perturb: expected a finite number, not inf"),
        (5, {"perturb": {"p1": 1e300}}, kinecal.KinecalError, "perturb: p1 (link1.x) would"),
        (5, {"perturb": "p1=1"}, kinecal.KinecalError, "perturb: invalid type: string \"p1=1\", expected a map"),
        (5, {"noise": {"length": -1}}, kinecal.KinecalError,
         "noise: the length must be non-negative and finite, not -1"),
        (5, {"noise": (1, 2, 3)}, kinecal.KinecalError, "noise: expected (length, angle)"),
        (5, {"perturb_std": {"len": 1}}, kinecal.KinecalError,
         "perturb_std: unknown field `len`, expected one of `length`, `angle`, `slope`"),
        (5, {"perturb_std": {"slope": float("nan")}}, kinecal.KinecalError,
         "perturb_std: expected a finite number, not nan"),
    ],
)
def test_simulation_input_mistakes_are_named(postures, kw, error, words):
    ge = kinecal.Robot.builtin("ge-a4")
    with pytest.raises(error) as e:
        kinecal.simulate(ge, postures, **kw)
    assert words in str(e.value), str(e.value)


# --- Robot exports: the command line's `kinecal export` -----------------------------------------


def test_dh_export_reads_back_and_is_the_cli_table(cli, puma, tmp_path):
    d, nominal, truth = puma
    q = np.random.default_rng(2).uniform(-150, 150, size=(30, 6))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # exact: no warning
        for convention in ("standard", "modified"):
            table = nominal.to_dh(convention=convention)
            assert "# length_unit = m\n# angle_unit = deg\n" in table
            (tmp_path / f"{convention}.csv").write_text(table)
            # The table states its units and convention: nothing to give.
            back = kinecal.Robot.from_dh(tmp_path / f"{convention}.csv")
            np.testing.assert_allclose(back.fk(q, matrix=True), nominal.fk(q, matrix=True),
                                       atol=1e-9)
            # Named after its file, as `kinecal import dh` names it.
            assert back.name == convention
        # The perturbed twin's geometry is a DH table too (beta, base and tool rows), exactly,
        # and the command line writes the same table.
        table = truth.to_dh("modified")
    out = subprocess.run([cli, "export", "dh", "--robot", "true.toml", "--convention",
                          "modified", "--out", str(tmp_path / "t.csv")], cwd=d, check=True,
                         capture_output=True, text=True)
    assert (tmp_path / "t.csv").read_text() == table
    assert "read back: largest deviation" in out.stderr
    (tmp_path / "t.csv").write_text(table)
    back = kinecal.Robot.from_dh(tmp_path / "t.csv")
    np.testing.assert_allclose(back.fk(q, matrix=True), truth.fk(q, matrix=True), atol=1e-9)
    # A slope a DH table cannot hold: refused with the command line's words, and written as a
    # warning with its deviation under a looser tolerance.
    sloped = truth.with_value("joint2.slope", 1.001)
    (d / "sloped.toml").write_text(sloped.to_toml())
    with pytest.raises(kinecal.KinecalError, match="it cannot hold joint 2 slope 1.001") as e:
        sloped.to_dh("modified")
    out = subprocess.run([cli, "export", "dh", "--robot", "sloped.toml", "--convention",
                          "modified", "--out", str(tmp_path / "s.csv")], cwd=d, check=False,
                         capture_output=True, text=True)
    assert out.returncode == 1 and str(e.value) in out.stderr
    assert not (tmp_path / "s.csv").exists()
    with pytest.warns(kinecal.ExportWarning, match="^not written: joint 2 slope 1.001"):
        sloped.to_dh("modified", tolerance=(1.0, 1.0))
    with pytest.raises(kinecal.KinecalError, match="convention `craig`"):
        nominal.to_dh("craig")


def test_ur_export_round_trips_and_names_what_it_cannot_hold(cli, tmp_path):
    yaml = shared_data("urdf", "universal_robots", "real_factory_calibration_ur3e",
                       "ur3e_calibration_1.yaml")
    subprocess.run([cli, "import", "ur", yaml, "--out", "ur3e.toml"], cwd=tmp_path, check=True,
                   capture_output=True)
    robot = kinecal.Robot.from_toml(tmp_path / "ur3e.toml")
    moved = robot.with_value("link3.x", robot.get("link3.x") + 0.002)
    moved = moved.with_value("joint2.offset", robot.get("joint2.offset") + 0.01)
    (tmp_path / "moved.toml").write_text(moved.to_toml())
    moved = kinecal.Robot.from_toml(tmp_path / "moved.toml")
    text = moved.to_ur(yaml)
    subprocess.run([cli, "export", "ur", "--robot", "moved.toml", "--template", yaml,
                    "--out", "cli.yaml"], cwd=tmp_path, check=True, capture_output=True)
    assert text == (tmp_path / "cli.yaml").read_text()
    # Read back by the library's importer: the same robot.
    (tmp_path / "back.yaml").write_text(text)
    subprocess.run([cli, "import", "ur", "back.yaml", "--out", "back.toml"], cwd=tmp_path,
                   check=True, capture_output=True)
    back = kinecal.Robot.from_toml(tmp_path / "back.toml")
    q = np.random.default_rng(3).uniform(-3, 3, size=(20, 6))
    np.testing.assert_allclose(back.fk(q, matrix=True), moved.fk(q, matrix=True), atol=1e-9)
    assert np.abs(back.fk(q)[:, :3] - robot.fk(q)[:, :3]).max() > 1e-3
    # A slope the file cannot hold: refused, and under a looser tolerance said so, as the
    # command line says it.
    sloped = moved.with_value("joint1.slope", 1.001)
    (tmp_path / "sloped.toml").write_text(sloped.to_toml())
    sloped = kinecal.Robot.from_toml(tmp_path / "sloped.toml")
    with pytest.raises(kinecal.KinecalError, match=r"joint 1 \(shoulder_pan_joint\) slope"):
        sloped.to_ur(yaml)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        text = sloped.to_ur(yaml, tolerance=(0.1, 0.1))
    said = [str(w.message) for w in caught if issubclass(w.category, kinecal.ExportWarning)]
    assert said[0].startswith("not written: joint 1 (shoulder_pan_joint) slope 1.001"), said
    out = subprocess.run([cli, "export", "ur", "--robot", "sloped.toml", "--template", yaml,
                          "--tolerance", "length=0.1,angle=0.1", "--out", "sloped.yaml"],
                         cwd=tmp_path, check=True, capture_output=True, text=True)
    assert (tmp_path / "sloped.yaml").read_text() == text
    assert [line for line in out.stderr.splitlines() if line.startswith("not written")] == said
    # A tool correction is the TCP to enter on the controller, printed by the command line.
    tooled = moved.with_value("link7.z", moved.get("link7.z") + 0.1)
    (tmp_path / "tooled.toml").write_text(tooled.to_toml())
    tooled = kinecal.Robot.from_toml(tmp_path / "tooled.toml")
    with pytest.warns(kinecal.ExportWarning, match="^TCP to enter on the controller") as w:
        tooled.to_ur(yaml)
    out = subprocess.run([cli, "export", "ur", "--robot", "tooled.toml", "--template", yaml,
                          "--out", "tooled.yaml"], cwd=tmp_path, check=True,
                         capture_output=True, text=True)
    assert out.stdout.strip() == str(w[0].message)
    assert "set_tcp(p[" in out.stdout


def test_joint_table_export_is_the_robots_offsets_and_slopes(cli, puma, tmp_path):
    d, nominal, truth = puma
    changed = nominal.with_value("joint2.offset", nominal.get("joint2.offset") + 0.3)
    changed = changed.with_value("joint5.slope", 1.002)
    (tmp_path / "changed.toml").write_text(changed.to_toml())
    changed = kinecal.Robot.from_toml(tmp_path / "changed.toml")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # offsets and slopes only: nothing lost
        table = changed.to_joints(nominal)
    subprocess.run([cli, "export", "joints", "--robot", str(tmp_path / "changed.toml"),
                    "--nominal", str(d / "nominal.toml"), "--out", str(tmp_path / "j.csv")],
                   check=True, capture_output=True)
    assert table == (tmp_path / "j.csv").read_text()
    header, rows = read_rows_text(table)
    assert header == ["joint", "offset", "slope", "offset_change", "slope_change"]
    for r in rows:
        j = int(r[0])
        assert float(r[1]) == pytest.approx(changed.get(f"joint{j}.offset"), abs=1e-12)
        assert float(r[2]) == pytest.approx(changed.get(f"joint{j}.slope"), abs=1e-12)
        assert float(r[3]) == pytest.approx(
            changed.get(f"joint{j}.offset") - nominal.get(f"joint{j}.offset"), abs=1e-12)
    # The truth's link changes cannot go into a joint table: refused, and under a looser
    # tolerance said so.
    with pytest.raises(kinecal.KinecalError, match="link and tool changes"):
        truth.to_joints(nominal)
    with pytest.warns(kinecal.ExportWarning, match="^not written: link and tool changes"):
        truth.to_joints(nominal, tolerance=(1.0, 10.0))
    with pytest.raises(kinecal.KinecalError):
        truth.to_joints(kinecal.Robot.builtin("ge-a4"))


def test_urdf_export_names_what_urdf_cannot_express():
    path = shared_data("urdf", "franka_panda", "panda.urdf")
    r = kinecal.Robot.from_urdf(path, tip="panda_hand_tcp")
    with pytest.raises(kinecal.KinecalError, match="panda_joint2`\\) slope 1.001"):
        r.with_value("joint2.slope", 1.001).to_urdf(path, tip="panda_hand_tcp")
    with pytest.warns(kinecal.ExportWarning, match="slope"):
        r.with_value("joint2.slope", 1.001).to_urdf(path, tip="panda_hand_tcp",
                                                     tolerance=(0.1, 0.1))


# --- What the calibration's outcome holds besides the report -----------------------------------


def test_covariance_is_the_reports_uncertainty(qkm_files):
    robot = kinecal.Robot.from_toml(qkm_files / "qkm.toml")
    data = kinecal.Measurements.read_csv(qkm_files / "identification.csv", robot)
    result = kinecal.calibrate(robot, data, estimate="all,identifiable")
    c = result.covariance
    n = len(result.estimated)
    assert c.shape == (n, n) and n == 39
    np.testing.assert_array_equal(c, c.T)
    eig = np.linalg.eigvalsh(c)
    assert eig.min() >= -1e-12 * eig.max()
    sigmas = result.sigmas
    assert len(sigmas) == n  # the identifiable set: every one determined
    for k, name in enumerate(result.estimated):
        assert np.sqrt(c[k, k]) == pytest.approx(sigmas[name], rel=1e-9), name
    # A copy each time: the result cannot be changed through it.
    c[0, 0] = -1
    assert result.covariance[0, 0] > 0


def test_covariance_of_redundant_parameters_gives_the_combinations_variance():
    ge = kinecal.Robot.builtin("ge-a4")
    sim = kinecal.simulate(ge, 30, seed=1, perturb={"p1": 0.1}, noise=(0.001, 0.01))
    result = kinecal.calibrate(ge, sim.measurements, estimate="all", fix="slopes")
    assert result.combinations, "the GE A4's z parameters are identically redundant"
    c, names = result.covariance, result.estimated
    eig = np.linalg.eigvalsh(c)
    assert eig.min() >= -1e-12 * eig.max()
    for combo in result.combinations:
        v = np.zeros(len(names))
        for t in combo["terms"]:
            v[names.index(t["name"])] = t["coefficient"]
        assert np.sqrt(v @ c @ v) == pytest.approx(combo["sigma"], rel=1e-9)
    for name, sigma in result.sigmas.items():
        k = names.index(name)
        assert np.sqrt(c[k, k]) == pytest.approx(sigma, rel=1e-9)


def test_residuals_are_the_calibrated_robots_errors_on_the_data(qkm_files):
    d = qkm_files
    robot = kinecal.Robot.from_toml(d / "qkm.toml")
    q, p, s, labels = read_measurement_csv(d / "identification.csv")
    data = kinecal.Measurements(robot, q, p, sites=s, postures=labels)
    result = kinecal.calibrate(robot, data, estimate="all,identifiable")
    r, rows = result.residuals, result.residual_rows
    assert r.shape == (data.residuals,) == (138,)
    assert [x.row for x in rows[:3]] == ["x", "y", "z"]
    assert {x.kind for x in rows} == {"position"}
    # Model - measured, row by row, from the calibrated robot's forward kinematics.
    by_label = {label: k for k, label in enumerate(labels)}
    for k in range(0, len(rows), 3):
        row = rows[k]
        i = by_label[row.posture]
        assert row.target == (s[i] or "ee")
        model = result.robot.fk(q[i], site=s[i])[:3]
        np.testing.assert_allclose(r[k:k + 3], model - p[i], atol=1e-9)
    # The report's figures follow from them.
    norms = np.linalg.norm(r.reshape(-1, 3), axis=1)
    after = result.identification["after"]
    assert np.sqrt(np.mean(norms ** 2)) == pytest.approx(after["rms_position"], rel=1e-9)
    sigma = np.array([x.sigma for x in rows])
    assert sigma == pytest.approx(0.01 * 100)  # the default 1 mm, in mm
    assert np.sum((r / sigma) ** 2) == pytest.approx(result.report["objective_after"], rel=1e-9)


def test_pose_residuals_are_rotation_vectors_or_euler_differences():
    ge = kinecal.Robot.builtin("ge-a4")
    sim = kinecal.simulate(ge, 20, seed=2, perturb={"p1": 0.1}, noise=(0.002, 0.05))
    q = sim.measurements.readings
    _, rows = read_rows_text(sim.measurements.to_csv(ge))
    measured = np.array([x[6:12] for x in rows], dtype=float)
    for orientation in ("rotvec", "euler"):
        result = kinecal.calibrate(ge, sim.measurements, estimate="identifiable",
                                   orientation_error=orientation)
        r = result.residuals.reshape(-1, 6)
        assert [x.row for x in result.residual_rows[:6]] == ["x", "y", "z", "alpha", "beta",
                                                              "gamma"]
        model = result.robot.fk(q)
        np.testing.assert_allclose(r[:, :3], model[:, :3] - measured[:, :3], atol=1e-9)
        if orientation == "euler":
            diff = (model[:, 3:] - measured[:, 3:] + 180) % 360 - 180
            np.testing.assert_allclose(r[:, 3:], diff, atol=1e-9)
        else:
            # log(R_measured^T R_model), in degrees.
            R = rotation_zyx(measured[:, 3:]).transpose(0, 2, 1) @ rotation_zyx(model[:, 3:])
            angle = np.arccos(np.clip((np.trace(R, axis1=1, axis2=2) - 1) / 2, -1, 1))
            axis = np.stack([R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0],
                             R[:, 1, 0] - R[:, 0, 1]], -1) / (2 * np.sin(angle))[:, None]
            np.testing.assert_allclose(r[:, 3:], np.degrees(axis * angle[:, None]), atol=1e-7)
        assert np.sum((r.ravel() / [x.sigma for x in result.residual_rows]) ** 2) == \
            pytest.approx(result.report["objective_after"], rel=1e-9)


def test_residuals_leave_the_holdout_out():
    ge = kinecal.Robot.builtin("ge-a4")
    sim = kinecal.simulate(ge, 40, seed=3, noise=(0.001, 0.01), position_only=True)
    result = kinecal.calibrate(ge, sim.measurements, estimate="identifiable", holdout=0.25)
    kept = {x.posture for x in result.residual_rows}
    assert len(kept) == result.identification["postures"] == 30
    assert len(result.residuals) == 3 * 30


def test_no_covariance_without_degrees_of_freedom():
    ge = kinecal.Robot.builtin("ge-a4")
    sim = kinecal.simulate(ge, 1, seed=1, perturb={"p1": 0.01}, position_only=True)
    result = kinecal.calibrate(ge, sim.measurements, estimate="p1,p2,p3")
    assert result.covariance is None and result.sigmas == {}
    assert any("no degrees of freedom" in w for w in result.warnings)
    assert result.residuals.shape == (3,) and np.abs(result.residuals).max() < 1e-9
    with pytest.raises(kinecal.KinecalError, match="^residuals: this Calibration was made"):
        _ = kinecal.Calibration(result.robot, result.to_json()).residuals


def test_a_calibration_reads_its_report_when_a_figure_is_asked_for(monkeypatch):
    # calibrate() returns the library's outcome: the report's JSON is written and read when a
    # figure of it is first read, once (its reading was an eighth of a 1,000-pose calibration
    # from Python, and the residual rows' tuples another eighth), and the arrays when theirs is.
    ge = kinecal.Robot.builtin("ge-a4")
    sim = kinecal.simulate(ge, 30, seed=1, perturb={"p1": 0.01}, noise=(0.001, 0.01))
    read = []
    loads = json.loads
    monkeypatch.setattr(json, "loads", lambda text, **kw: read.append(text) or loads(text, **kw))
    # Past the suite's schema check, which reads every report.
    result = kinecal.calibrate.__wrapped__(ge, sim.measurements, estimate="identifiable")
    assert read == []
    assert result.converged and result.report is result.report and result.values.shape == (24,)
    assert read == [result.to_json()]
    # The arrays, read in any order and as often, are the same; each read gives a copy.
    rows, r = result.residual_rows, result.residuals
    r[:] = 0
    assert result.residual_rows == rows and np.abs(result.residuals).max() > 0
    assert len(rows) == len(result.residuals) == 180 and rows[0].posture == "1"
    assert np.sum((result.residuals / [x.sigma for x in rows]) ** 2) == \
        pytest.approx(result.report["objective_after"], rel=1e-9)
    assert len(read) == 1


def test_a_model_choice_from_python_is_the_command_lines(cli, qkm_files, monkeypatch):
    monkeypatch.chdir(qkm_files)
    done = subprocess.run(
        [cli, "calibrate", "--robot", "qkm.toml", "--data", "identification.csv",
         "--choose", "identifiable", "identifiable,slopes", "--folds", "3", "--repeats", "1",
         "--report", "choice.json", "--quiet"],
        check=True, capture_output=True, text=True)
    expected = json.loads((qkm_files / "choice.json").read_text())
    robot = kinecal.Robot.from_toml("qkm.toml")
    data = kinecal.Measurements.read_csv("identification.csv", robot)
    result = kinecal.calibrate(robot, data, choose=["identifiable", "identifiable,slopes"],
                               folds=3, repeats=1)
    assert len(expected["model_choice"]) == 2, expected["model_choice"]
    assert result.report["model_choice"] == expected["model_choice"], done.stdout
    assert result.estimates == {p["name"]: p["estimated"] for p in expected["parameters"]
                                if p["estimated_flag"]}


NO_TRACKER = os.path.join(ROOT, "examples", "no-tracker")


def _error_paths(tmp_path):
    """Ways to get a KinecalError: from files (file, line, field set), from arguments (None),
    from the Python package itself (None)."""
    ge = kinecal.Robot.builtin("ge-a4")
    bad_toml = tmp_path / "bad.toml"
    bad_toml.write_text("name = 'x'\nlength_unit = 'furlong'\n")
    bad_csv = tmp_path / "bad.csv"
    bad_csv.write_text("posture,site,v1,v2,v3,v4,x,y,z\n1,ee,0,0,zero,0,1,2,3\n")
    q = np.zeros((3, 4))
    return [
        lambda: kinecal.Robot.from_toml(bad_toml),
        lambda: kinecal.Robot.from_toml(tmp_path / "missing.toml"),
        lambda: kinecal.Measurements.read_csv(bad_csv, ge),
        lambda: kinecal.Measurements.read_csv(tmp_path / "missing.csv", ge),
        lambda: kinecal.Robot.builtin("nothing"),
        lambda: kinecal.Measurements(ge, q, np.zeros((3, 3)), sigma_position=[1, -1, 1]),
        lambda: kinecal.Measurements(ge, q, np.zeros((2, 3))),
        lambda: kinecal.dataset("nothing", tmp_path),
        lambda: kinecal.dataset("qkm-hl6", tmp_path),
        lambda: kinecal.calibrate(ge, kinecal.simulate(ge, postures=q).measurements,
                                  weights=(1, 2, 3)),
        lambda: kinecal.calibrate(ge, kinecal.simulate(ge, postures=q).measurements,
                                  method="nothing"),
        lambda: kinecal.calibrate(ge, kinecal.simulate(ge, postures=q).measurements,
                                  holdout=2.0),
        lambda: kinecal.simulate(ge, postures=np.zeros((3, 5))),
        lambda: kinecal.plan(ge, count=0, sample=10),
        lambda: ge.with_value("nothing", 1.0),
        lambda: ge.get("p999"),
        lambda: ge.to_dh(convention="sideways"),
    ]


def test_every_kinecal_error_has_file_line_and_field(tmp_path):
    """Whatever raised it (a file, an argument, the package), a KinecalError has ``file``,
    ``line`` and ``field``: set when it came from a file, else None."""
    raised = 0
    for k, call in enumerate(_error_paths(tmp_path)):
        with pytest.raises(kinecal.KinecalError) as e:
            call()
        raised += 1
        err = e.value
        for attribute in ("file", "line", "field"):
            assert hasattr(err, attribute), (k, attribute, str(err))
        assert err.file is None or isinstance(err.file, str), k
        assert err.line is None or isinstance(err.line, int), k
        assert err.field is None or isinstance(err.field, str), k
    assert raised >= 15
    # From files: named.
    with pytest.raises(kinecal.KinecalError) as e:
        kinecal.Robot.builtin("nothing")
    assert (e.value.file, e.value.line, e.value.field) == (None, None, None)
    # Raised by the package's own Python code.
    assert kinecal.KinecalError("x").file is None


def test_a_sigma_below_1e_140_is_refused_naming_the_file(tmp_path):
    ge = kinecal.Robot.builtin("ge-a4")
    sim = kinecal.simulate(ge, postures=np.zeros((3, 4)))
    lines = sim.measurements.to_csv(ge).splitlines()
    text = lines[0] + ",sigma_position\n" + "".join(f"{row},1e-160\n" for row in lines[1:])
    path = tmp_path / "s.csv"
    path.write_text(text)
    with pytest.raises(kinecal.KinecalError, match="below 1e-140") as e:
        kinecal.Measurements.read_csv(path, ge)
    assert (e.value.file, e.value.line, e.value.field) == (str(path), 2, "sigma_position")
    with pytest.raises(kinecal.KinecalError, match="sigma_position: row 0: .*below 1e-140"):
        kinecal.Measurements(ge, np.zeros((1, 4)), np.zeros((1, 3)), sigma_position=[1e-160])


def _round_trip(robot, m, tmp_path, name):
    """``to_csv``, read back by kinecal's reader, gives the same observations: the same text
    again, the same readings and kinds."""
    text = m.to_csv(robot)
    path = tmp_path / name
    path.write_text(text)
    back = kinecal.Measurements.read_csv(path, robot)
    assert back.kinds == m.kinds
    np.testing.assert_array_equal(back.readings, m.readings)
    assert back.to_csv(robot) == text
    return text


def test_to_csv_writes_every_observation_kind_or_refuses(tmp_path):
    table = kinecal.Robot.from_toml(os.path.join(NO_TRACKER, "a4_table.toml"))
    distances = kinecal.Measurements.read_csv(os.path.join(NO_TRACKER, "ballbar.csv"), table)
    contacts = kinecal.Measurements.read_csv(os.path.join(NO_TRACKER, "contacts.csv"), table)
    assert set(distances.kinds) == {"distance"} and set(contacts.kinds) == {"contact"}
    text = _round_trip(table, distances, tmp_path, "d.csv")
    assert text.startswith("pair,site,a1,a2,a3,a4,b1,b2,b3,b4,distance\n1,ee,")
    text = _round_trip(table, contacts, tmp_path, "c.csv")
    assert text.startswith("posture,site,plane,v1,v2,v3,v4,gap\nt1,ee,table,")
    # Poses and positions, with sigmas of 1e-15 kept (not written as 0).
    ge = kinecal.Robot.builtin("ge-a4")
    q = np.random.default_rng(3).uniform(-20, 20, size=(5, 4))
    poses = kinecal.simulate(ge, postures=q).measurements
    fk = ge.fk(q)
    tiny = kinecal.Measurements(ge, q, fk[:, :3], fk[:, 3:], sigma_position=[1e-15] * 5,
                                sigma_angle=[1e-15] * 5)
    for k, m in enumerate([poses, tiny]):
        text = _round_trip(ge, m, tmp_path, f"m{k}.csv")
    assert text.splitlines()[1].endswith(",1e-15,1e-15")
    # Two kinds in one: refused, naming them.
    with pytest.raises(kinecal.KinecalError, match="one file holds.*distance.*contact") as e:
        distances.merge(contacts).to_csv(table)
    assert e.value.file is None
