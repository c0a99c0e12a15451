"""A calibration report read back from Python is checked for sense before it is believed, as the
command line checks it (issue 38, scope item 3): a tampered report given to ``kinecal.predict``,
to ``kinecal.iso9283`` and to a ``report`` job through ``kinecal.run`` raises ``KinecalError``
naming the bad field by its JSON path, the same words ``kinecal predict`` and ``kinecal report
--from`` print for the same file.

Run by `bash crates/kinecal-py/test.sh`.
"""

import copy
import json
import os
import subprocess

import numpy as np
import pytest

import kinecal
import kinecal.history

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", ".."))


@pytest.fixture(scope="module")
def calibrated(cli, tmp_path_factory):
    """A GE A4 calibrated by the command line with its prediction and accuracy map (``--html
    --predict``): the folder, the report as a dict, the calibrated robot."""
    d = tmp_path_factory.mktemp("report_checks")
    for args in [
        (
            "simulate --robot ge-a4 --postures 30 --seed 7 --perturb p1=+0.05,p14=-0.02,"
            "joint2.offset=-0.5 --noise length=0.0005,angle=0.005 --out data.csv"
        ),
        (
            "calibrate --robot ge-a4 --data data.csv --estimate p1,p2,p8,p14,offsets,slopes "
            "--weights length=0.0005,angle=0.005 --out cal.toml --report report.json "
            "--html page.html --predict"
        ),
    ]:
        subprocess.run([cli, *args.split()], cwd=d, check=True, capture_output=True)
    with open(d / "report.json", encoding="utf-8") as f:
        report = json.load(f)
    return d, report, kinecal.Robot.from_toml(str(d / "cal.toml"))


def _scale_covariance(v):
    v["prediction"]["covariance"] = [
        [x * 1e300 for x in row] for row in v["prediction"]["covariance"]
    ]


def _negate_variances(v):
    for k, row in enumerate(v["prediction"]["covariance"]):
        row[k] = -row[k]


def _short_edges(v):
    v["prediction"]["map"]["joints"][0]["edges"].pop()


def _huge_map(v):
    values = v["prediction"]["map"]["slices"][0]["values"]
    v["prediction"]["map"]["slices"][0]["values"] = [None if x is None else 1e308 for x in values]


def _lever(v):
    v["prediction"]["levers"][1] = 1e308


def _sigma(v):
    v["parameters"][0]["sigma"] = 1e40


def _ids(v):
    v["parameters"][1]["id"] = v["parameters"][0]["id"]


# (name, edit, the JSON path and words the refusal gives)
TAMPERED = [
    ("covariance x 1e300", _scale_covariance, "prediction.covariance[0][0]: "),
    (
        "negative variances",
        _negate_variances,
        "prediction.covariance[0][0]: expected a variance of at least 0",
    ),
    ("bin edges one short", _short_edges, "prediction.map.joints[0].edges: 24 edges for 24 bins"),
    ("map values of 1e308", _huge_map, "prediction.map.slices[0].values["),
    ("a lever of 1e308", _lever, "prediction.levers[1]: 1e308 is beyond 1e100 in magnitude"),
    (
        "a sigma of 1e40",
        _sigma,
        "parameters[0].sigma: expected at least 0 and at most 1e12, found 1e40",
    ),
    ("a parameter id twice", _ids, "parameters[1].id: `p1` again"),
]


@pytest.mark.parametrize("name,edit,words", TAMPERED, ids=[t[0] for t in TAMPERED])
def test_a_tampered_report_raises_naming_its_json_path_as_the_command_line_refuses_it(
    calibrated, cli, name, edit, words
):
    d, good, robot = calibrated
    # The untampered report is read by every reader.
    postures = kinecal.simulate(robot, 5, seed=9).measurements.readings
    kinecal.predict(robot, good, postures=postures)
    bad = copy.deepcopy(good)
    edit(bad)
    file = d / f"{name.replace(' ', '_')}.json"
    file.write_text(json.dumps(bad), encoding="utf-8")
    # The command line: exit 1, the file and the field named.
    for args in [
        ["predict", "--robot", "cal.toml", "--report", file.name, "--sample", "5"],
        ["report", "--from", file.name, "--out", "page2.html"],
    ]:
        out = subprocess.run([cli, *args], cwd=d, capture_output=True, text=True, check=False)
        assert out.returncode == 1, out.stderr
        assert words in out.stderr, out.stderr
    # Python, the report as a dict, as JSON text and as a file: the same words.
    for report in (bad, json.dumps(bad), str(file)):
        with pytest.raises(kinecal.KinecalError) as e:
            kinecal.predict(robot, report, postures=postures)
        assert words in str(e.value)
    # A report job (the HTML page from the report), run through the one door.
    with pytest.raises(kinecal.KinecalError) as e:
        kinecal.run({"job": "report", "from": str(file), "out": str(d / "page3.html")})
    assert words in str(e.value)
    assert not os.path.exists(d / "page3.html")
    # Nothing was believed: no NaN came back from the good one either.
    p = kinecal.predict(robot, good, postures=postures)
    assert np.all(np.isfinite(p["position_bound95"]))


def test_every_front_end_refuses_the_same_output_over_an_input(cli, tmp_path):
    """One output writer for every front end (issue 38, scope item 1): a spec whose ``[outputs]``
    robot is its own data file under another name (a hard link: the same device and inode) is
    refused before any work, naming both, by the command line, ``kinecal.calibrate(spec)``,
    ``kinecal.run``, a batch job; the measurements are left as they were. A history export over
    its own database is refused by the command line and by ``kinecal.history.export``."""
    d = tmp_path
    subprocess.run(
        [
            cli,
            "simulate",
            "--robot",
            "ge-a4",
            "--postures",
            "20",
            "--seed",
            "7",
            "--out",
            "data.csv",
        ],
        cwd=d,
        check=True,
        capture_output=True,
    )
    os.link(d / "data.csv", d / "same.csv")
    before = (d / "data.csv").read_bytes()
    spec = (
        'job = "calibrate"\nrobot = "ge-a4"\n\n[[observations]]\nfile = "data.csv"\n\n'
        '[outputs]\nrobot = "same.csv"\n'
    )
    (d / "job.toml").write_text(spec, encoding="utf-8")
    said = "refusing to write an output over an input"
    out = subprocess.run(
        [cli, "calibrate", "--spec", "job.toml"], cwd=d, capture_output=True, text=True, check=False
    )
    assert out.returncode == 1 and said in out.stderr, out.stderr
    assert "same.csv" in out.stderr and "data.csv" in out.stderr, out.stderr
    for call in (kinecal.calibrate, kinecal.run):
        with pytest.raises(kinecal.KinecalError) as e:
            call(str(d / "job.toml"))
        assert said in str(e.value) and "same.csv" in str(e.value), str(e.value)
        assert "data.csv" in str(e.value), str(e.value)
    jobs = (
        '[[jobs]]\njob = "calibrate"\nname = "one"\nrobot = "ge-a4"\n'
        'observations = [{ file = "data.csv" }]\noutputs = { robot = "same.csv" }\n'
    )
    (d / "jobs.toml").write_text(jobs, encoding="utf-8")
    out = subprocess.run(
        [cli, "batch", "jobs.toml"], cwd=d, capture_output=True, text=True, check=False
    )
    assert out.returncode != 0 and said in out.stdout + out.stderr, out.stdout + out.stderr
    assert (d / "data.csv").read_bytes() == before
    # The history's export over its own database.
    dump = os.path.join(ROOT, "examples", "fleet", "history.json")
    subprocess.run(
        [cli, "history", "import", dump, "--db", "h.sqlite"], cwd=d, check=True, capture_output=True
    )
    os.link(d / "h.sqlite", d / "h2.sqlite")
    db = (d / "h.sqlite").read_bytes()
    out = subprocess.run(
        [cli, "history", "export", "--format", "csv", "--out", "h2.sqlite", "--db", "h.sqlite"],
        cwd=d,
        capture_output=True,
        text=True,
        check=False,
    )
    assert out.returncode == 1 and "h2.sqlite" in out.stderr, out.stderr
    with pytest.raises(kinecal.KinecalError) as e:
        kinecal.history.export(db=d / "h.sqlite", format="csv", out=d / "h2.sqlite")
    assert "h2.sqlite" in str(e.value), str(e.value)
    assert (d / "h.sqlite").read_bytes() == db
