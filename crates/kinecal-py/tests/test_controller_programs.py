"""Controller programs (``compensate`` with ``format`` ``krl``, ``rapid``, ``tp``): the same
bytes from Python (``kinecal.run`` of the spec's keys) as from the command line, and, read by
this test's own regular expressions, the values of the command line's joint table and of
``kinecal.compensate``'s readings within the six written decimals."""

import os
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT

import kinecal

# Half a unit of the sixth written decimal, and the rounding of a decimal to binary.
READ_BACK = 0.5e-6 + 1e-9

NUMBER = r"(-?\d+\.\d+)"

# One move of each language: its six values, by their own text.
MOVE = {
    "krl": re.compile(
        r"^PTP \{" + ", ".join(f"A{k} {NUMBER}" for k in range(1, 7)) + r"\}( C_PTP)?$", re.MULTILINE
    ),
    "rapid": re.compile(
        r"^\s*MoveAbsJ \[\[" + ",".join([NUMBER] * 6)
        + r"\],\[9E9,9E9,9E9,9E9,9E9,9E9\]\]\\NoEOffs, v(\d+), (fine|z\d+), tool0;$",
        re.MULTILINE,
    ),
    "tp": re.compile(
        r"^P\[(\d+)\]\{\n   GP1:\n\tUF : 0, UT : 1,\t\n"
        + r"\tJ1=\s*{0} deg,\tJ2=\s*{0} deg,\tJ3=\s*{0} deg,\n".replace("{0}", NUMBER)
        + r"\tJ4=\s*{0} deg,\tJ5=\s*{0} deg,\tJ6=\s*{0} deg\n\};$".replace("{0}", NUMBER),
        re.MULTILINE,
    ),
}


def regex_values(fmt: str, text: str) -> np.ndarray:
    moves = MOVE[fmt].findall(text)
    if fmt == "tp":
        assert [int(m[0]) for m in moves] == list(range(1, len(moves) + 1))
        moves = [m[1:] for m in moves]
    return np.array([[float(v) for v in m[:6]] for m in moves])


@pytest.fixture(scope="module")
def cell(cli, tmp_path_factory):
    """The IRB 120 of examples/robots, its simulated twin (the calibrated robot) and 50 pose
    targets the twin reaches without a flag."""
    d = tmp_path_factory.mktemp("programs")
    shutil.copy(Path(ROOT) / "examples" / "robots" / "abb_irb120.toml", d / "irb120.toml")
    subprocess.run([cli, "simulate", "--robot", "irb120.toml", "--postures", "50", "--seed", "5",
                    "--perturb-std", "length=0.001,angle=0.005", "--out", "m.csv",
                    "--truth", "true.toml"], cwd=d, check=True, capture_output=True)
    rows = [line.split(",") for line in (d / "m.csv").read_text().splitlines()[1:]]
    (d / "poses.csv").write_text("target,x,y,z,alpha,beta,gamma\n" + "".join(
        f"{r[0]},{','.join(r[8:14])}\n" for r in rows))
    return d


@pytest.mark.parametrize("fmt,ext,extra", [
    ("krl", "src", {"speed": 50, "zone": 10}),
    ("rapid", "mod", {"speed": 200, "zone": "fine"}),
    ("tp", "ls", {"zone": 50}),
])
def test_a_program_comes_out_the_same_from_python_as_from_the_command_line(
        cli, cell, monkeypatch, fmt, ext, extra):
    d = cell
    flags = [a for k, v in extra.items() for a in (f"--{k}", str(v))]
    common = ["--robot", "true.toml", "--nominal", "irb120.toml", "--in", "poses.csv"]
    done = subprocess.run([cli, "compensate", *common, "--format", fmt, *flags,
                           "--out", f"prog.{ext}"], cwd=d, capture_output=True, text=True,
                          check=False)
    assert done.returncode == 0, done.stderr
    subprocess.run([cli, "compensate", *common, "--format", "joints-kuka", "--out", "table.csv"],
                   cwd=d, check=True, capture_output=True)
    # The same program from Python, into a folder of its own (a KRL module names its file).
    (d / "py").mkdir(exist_ok=True)
    monkeypatch.chdir(d)
    document = kinecal.run({"job": "compensate", "robot": "true.toml", "nominal": "irb120.toml",
                            "in": "poses.csv", "format": fmt, "out": f"py/prog.{ext}", **extra})
    assert document["written"] is True
    cli_text = (d / f"prog.{ext}").read_text()
    assert (d / "py" / f"prog.{ext}").read_text() == cli_text

    # Read by this test's regular expressions: the table's values within the written decimals.
    values = regex_values(fmt, cli_text)
    table = np.loadtxt(d / "table.csv", delimiter=",", skiprows=1, usecols=range(1, 7))
    assert values.shape == (50, 6)
    assert np.abs(values - table).max() <= READ_BACK
    # And kinecal.compensate's readings (rad), in degrees.
    calibrated = kinecal.Robot.from_toml(d / "true.toml")
    nominal = kinecal.Robot.from_toml(d / "irb120.toml")
    targets = np.loadtxt(d / "poses.csv", delimiter=",", skiprows=1, usecols=range(1, 7))
    result = kinecal.compensate(calibrated, nominal, targets=targets)
    assert not result.flagged.any(), result.flags
    assert np.abs(values - np.degrees(result.readings)).max() <= READ_BACK
    # Speed and zone in the language's words; the last move stops exactly.
    if fmt == "krl":
        assert "$VEL_AXIS[I]=50\n" in cli_text and "$APO.CPTP=10\n" in cli_text
        assert cli_text.count("} C_PTP\n") == 49
    elif fmt == "rapid":
        assert cli_text.count(", v200, fine, tool0;\n") == 50
    else:
        assert cli_text.count("] 100% CNT50    ;\n") == 49
        assert cli_text.count("] 100% FINE    ;\n") == 1


def test_a_setting_no_controller_takes_is_refused_naming_its_key(cell, monkeypatch):
    monkeypatch.chdir(cell)
    spec = {"job": "compensate", "robot": "true.toml", "nominal": "irb120.toml",
            "in": "poses.csv", "out": "bad.mod"}
    for extra, message in [
        ({"format": "rapid", "speed": 123}, "speed: expected the TCP speed (mm/s) of a predefined"),
        ({"format": "tp", "zone": "coarse"}, "zone: expected `fine` or a number (the TP zone)"),
        ({"format": "rapid", "name": "1st"}, "name: `1st` does not begin with a letter"),
        ({"format": "table", "speed": 50}, "speed: is for a controller program"),
    ]:
        with pytest.raises(kinecal.KinecalError, match=re.escape(message)):
            kinecal.run({**spec, **extra})
    assert not os.path.exists("bad.mod")
