"""Tests of the Python bindings, against the command line on real data, against closed-form
kinematics, and with the inputs users get wrong.

Run by `bash crates/kinecal-py/test.sh` (builds the wheel, installs it in a virtual
environment, runs pytest). The command-line comparisons use the `kinecal` binary of this
checkout (KINECAL_BIN, or built with cargo).
"""

import ast
import doctest
import json
import os
import subprocess
import threading
import time

import numpy as np
import pytest

import kinecal

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", ".."))
SHARED = os.path.join(ROOT, "..", "shared", "data")
QKM = os.path.join(SHARED, "qkm_hl6_faro")


@pytest.fixture(scope="session")
def cli():
    """The kinecal command of this checkout."""
    path = os.environ.get("KINECAL_BIN")
    if not path:
        subprocess.run(["cargo", "build", "-q", "-p", "kinecal-cli"], cwd=ROOT, check=True)
        path = os.path.join(ROOT, "target", "debug", "kinecal")
    return path


@pytest.fixture(scope="session")
def qkm_files(cli, tmp_path_factory):
    """The QKM data set converted by the command line: qkm.toml, identification.csv,
    validation.csv."""
    d = tmp_path_factory.mktemp("qkm")
    subprocess.run([cli, "dataset", "qkm-hl6", QKM, "--out", str(d)], check=True,
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
    report = json.loads(path.read_text())
    report.pop("timings")
    return report


def test_one_job_four_ways_gives_the_same_calibration(cli, qkm_files, monkeypatch):
    """The same job said by flags, by a spec file, from Python and as a batch row (CSV and
    TOML) writes byte-identical calibrated robots and reports equal but for the timings."""
    monkeypatch.chdir(qkm_files)
    job = ["--robot", "qkm.toml", "--data", "identification.csv", "--validate", "validation.csv",
           "--estimate", "all,identifiable", "--loss", "huber", "--huber-scale", "2"]

    def run(*args):
        done = subprocess.run([cli, *args], capture_output=True, text=True)
        assert done.returncode == 0, done.stderr
        return done

    # 1. Flags, written down as a spec.
    run("calibrate", *job, "--out", "flags.toml", "--report", "flags.json",
        "--write-spec", "job.toml", "--quiet")
    spec_text = open("job.toml").read()
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
    assert result.robot.to_toml() == open("python.toml").read()
    assert json.loads(result.to_json()) == json.loads(open("python.json").read())
    # 4. Batch: a CSV row and a TOML [[robots]] table.
    with open("fleet.csv", "w") as f:
        f.write("serial,robot,data,options\n")
        f.write('QKM-1,qkm.toml,identification.csv,"--validate validation.csv '
                "--estimate all,identifiable --loss huber --huber-scale 2 "
                '--out batch.toml --report batch.json"\n')
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
    with open("fleet.toml", "w") as f:
        f.write('[[robots]]\nserial = "QKM-1"\n' + table + "\n")
    run("batch", "fleet.toml", "--quiet")

    robot = open("flags.toml").read()
    report = _without_timings(qkm_files / "flags.json")
    assert report["validation"]["after"]["mean_position"] > 0
    for name in ["spec", "python", "batch", "batch2"]:
        assert open(f"{name}.toml").read() == robot, name
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
    ds = kinecal.dataset("qkm-hl6", QKM)
    assert ds.suggested == {"estimate": "all,identifiable"}
    result = kinecal.calibrate(ds.robot, ds.identification, validate=ds.validation,
                               **ds.suggested)
    assert round(result.validation["after"]["mean_position"], 3) == 0.210
    assert [n for n, _ in kinecal.datasets()] == ["qkm-hl6", "fanuc-r2000ic", "ur10e-camera"]


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


def test_weights_as_a_pair_or_a_dict(qkm_files):
    d = qkm_files
    robot = kinecal.Robot.from_toml(d / "qkm.toml")
    data = kinecal.Measurements.read_csv(d / "identification.csv", robot)
    pair = kinecal.calibrate(robot, data, weights=(0.05, 0.01))
    named = kinecal.calibrate(robot, data, weights={"angle": 0.01, "length": 0.05})
    assert pair.robot.to_toml() == named.robot.to_toml()
    assert pair.report["variance_factor"] == named.report["variance_factor"]
    for bad, words in [
        ({"length": 0.05}, "expected the keys length and angle"),
        ({"length": 0.05, "angel": 0.01}, "not 'angel'"),
        ({"length": "x", "angle": 0.01}, "length 'x' is not a number"),
        ((0.05,), "expected \\(length, angle\\)"),
        ("0.05,0.01", "expected \\(length, angle\\)"),
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
        (dict(holdout=1.5), "holdout"),
        (dict(huber_scale=-1.0, loss="huber"), "huber_scale"),
        (dict(outlier_sigma=0.0), "outlier_sigma"),
        (dict(prune=-2.0), "prune"),
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
        (dict(positions=np.zeros((2, 3))), "positions: expected shape [3, 3]"),
        (dict(positions=np.zeros((3, 2))), "positions: expected shape [3, 3]"),
        (dict(positions=np.zeros((3, 3)), orientations=np.zeros((3, 4))), "orientations"),
        (dict(positions=np.zeros((3, 3)), sigma_position=[1, 0, 1]),
         "sigma_position: row 1: a standard deviation must be positive"),
        (dict(positions=np.zeros((3, 3)), sigma_angle=[1, 1, 1]), "position-only rows"),
        (dict(positions=np.zeros((3, 3)), sites=["tool", None, None]), "not a site"),
        (dict(positions=np.zeros((3, 3)), sites=[None]), "1 names for 3 rows"),
        (dict(positions=np.zeros((3, 3)), postures=["a", "a", "b"]),
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
        (dict(method="newton"), "method `newton`"),
        (dict(loss="cauchy"), "loss `cauchy`"),
        (dict(estimate="links,nonsense"), "nonsense"),
        (dict(estimate=42), "parameter list"),
        (dict(weights=(0, 1)), "weights"),
        (dict(solution="best"), "solution `best`"),
        (dict(max_iterations=0), "max_iterations"),
        (dict(prune=-1), "prune"),
    ]:
        with pytest.raises((kinecal.KinecalError, TypeError)) as e:
            kinecal.calibrate(robot, data, **kw)
        assert words in str(e.value), (kw, str(e.value))
    other = kinecal.Robot.from_dh([[0.5, 0, 0, 0], [0.3, 0, 0, 0]])
    with pytest.raises(kinecal.KinecalError, match="built for a robot with 4 joints"):
        kinecal.calibrate(other, data)


def test_the_gil_is_released_during_a_calibration():
    robot = kinecal.Robot.builtin("ge-a4")
    ticks = [0]
    stop = threading.Event()

    def count():
        while not stop.is_set():
            ticks[0] += 1

    t = threading.Thread(target=count)
    t.start()
    try:
        # The counter's rate when it has the interpreter to itself (this thread sleeping).
        before = ticks[0]
        time.sleep(0.2)
        rate = (ticks[0] - before) / 0.2
        # Postures enough for the call to last (a release build is 20 times faster).
        for postures in [1000, 4000, 16000, 64000]:
            q = np.random.default_rng(2).uniform(-40, 40, size=(postures, 4))
            data = kinecal.Measurements(robot, q, robot.fk(q)[:, :3] + 0.001)
            before = ticks[0]
            start = time.perf_counter()
            kinecal.calibrate(robot, data, estimate="identifiable")
            spent = time.perf_counter() - start
            during = ticks[0] - before
            if spent > 0.2:
                break
    finally:
        stop.set()
        t.join()
    # A held GIL lets the counter run only at the switch intervals (5 ms each, a few of them);
    # a released one lets it count all along, at about its own rate (two cores here).
    assert spent > 0.1, f"the calibration took {spent:.3f} s: too short to tell"
    assert during > 0.3 * rate * spent, (during, rate, spent)


def test_robot_round_trips_and_urdf_export(tmp_path):
    robot = kinecal.Robot.builtin("ge-a4")
    text = robot.to_toml()
    again = kinecal.Robot.from_toml(text)
    np.testing.assert_array_equal(again.values, robot.values)
    assert again.parameter_ids[:2] == ["p1", "p2"] and len(again.parameter_names) == 38
    assert robot.units == ("in", "deg")
    # A real URDF with comments and several leaves: the tip is named.
    path = os.path.join(SHARED, "urdf", "franka_panda", "panda.urdf")
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


def test_the_readme_session_runs_as_shown(monkeypatch):
    # From the repository root, where the README's paths (../shared/data) hold.
    monkeypatch.chdir(ROOT)
    result = doctest.testfile(os.path.join(ROOT, "README.md"), module_relative=False,
                              optionflags=doctest.NORMALIZE_WHITESPACE)
    assert result.attempted >= 10
    assert result.failed == 0


def test_the_type_stubs_name_what_the_package_has():
    stub = os.path.join(os.path.dirname(kinecal.__file__), "__init__.pyi")
    tree = ast.parse(open(stub).read())
    top = {n.name for n in tree.body if isinstance(n, (ast.ClassDef, ast.FunctionDef))}
    assert top == set(kinecal.__all__) - {"__version__"}
    for cls in tree.body:
        if isinstance(cls, ast.ClassDef) and cls.name in ("Robot", "Measurements", "Calibration"):
            stubbed = {n.name for n in cls.body if isinstance(n, ast.FunctionDef)}
            actual = {n for n in dir(getattr(kinecal, cls.name)) if not n.startswith("_")}
            assert stubbed - {"__init__", "__len__"} == actual, cls.name


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
        for call in (lambda: robot.fk(q),
                     lambda: robot.fk(q, matrix=True),
                     lambda: kinecal.Measurements(robot, q, p, orientations=o)):
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
    ur10 = os.path.join(SHARED, "ipa_ur10_tracker")
    yaml = os.path.join(SHARED, "urdf", "universal_robots", "config", "ur10",
                        "default_kinematics.yaml")
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
