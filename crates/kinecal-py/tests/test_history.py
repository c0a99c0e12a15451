"""The history from Python: each ``kinecal.history`` function gives the document
``kinecal history <command> --json`` prints for the same job, and ``kinecal.run`` of the spec
the command line writes (``--write-spec``) does too; a bad value names the keyword."""

from __future__ import annotations

import json
import os
import subprocess
import warnings
from pathlib import Path
from typing import Any

import pytest

import kinecal

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", ".."))
FLEET = Path(ROOT) / "examples" / "fleet"


@pytest.fixture()
def histories(cli: str, tmp_path: Path) -> Path:
    """Two equal histories of the example fleet: ``cli.sqlite`` written by the command line,
    ``py.sqlite`` by Python; and a calibration report of a fifth robot."""
    def run(*args: str) -> None:
        subprocess.run([cli, *args], cwd=tmp_path, check=True, capture_output=True)

    run("history", "import", str(FLEET / "history.json"), "--db", "cli.sqlite")
    kinecal.history.import_dump(FLEET / "history.json", db=tmp_path / "py.sqlite")
    run("simulate", "--robot", "ge-a4", "--postures", "20", "--seed", "3", "--out", "data.csv")
    run("calibrate", "--robot", "ge-a4", "--data", "data.csv", "--report", "report.json", "-q")
    return tmp_path


def cli_json(cli: str, d: Path, *args: str) -> Any:
    out = subprocess.run([cli, *args, "--json"], cwd=d, check=False, capture_output=True,
                         text=True)
    assert out.returncode in (0, 3), out.stderr
    return json.loads(out.stdout.replace("cli.sqlite", "py.sqlite"))


def test_each_function_gives_the_command_line_s_document(
    cli: str, histories: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    d = histories
    monkeypatch.chdir(d)
    db = "py.sqlite"
    subprocess.run([cli, "history", "event", "A4-0104", "--at", "2026-12-10", "--note", "cable",
                    "--db", "cli.sqlite"], cwd=d, check=True, capture_output=True)
    recorded = kinecal.history.event("A4-0104", "cable", at="2026-12-10", db=db)
    assert recorded["new"] and recorded["event"]["note"] == "cable"
    subprocess.run([cli, "history", "add", "--robot-id", "A4-0105", "--report", "report.json",
                    "--at", "2026-12-12", "--db", "cli.sqlite"], cwd=d, check=True,
                   capture_output=True)
    added = kinecal.history.add("A4-0105", d / "report.json", at="2026-12-12", db=db)
    assert added["new"] and added["robot_id"] == "A4-0105"
    # The same calibration twice is recorded once.
    assert not kinecal.history.add("A4-0105", d / "report.json", at="2026-12-12", db=db)["new"]
    assert kinecal.history.list("A4-0101", db=db) == cli_json(
        cli, d, "history", "list", "--robot-id", "A4-0101", "--db", "cli.sqlite")
    assert kinecal.history.show(id=3, db=db) == cli_json(
        cli, d, "history", "show", "--id", "3", "--db", "cli.sqlite")
    assert kinecal.history.show("A4-0105", db=db)["robot_id"] == "A4-0105"
    drift = kinecal.history.drift("A4-0101", db=db, tolerance=FLEET / "tolerances.toml")
    assert drift == cli_json(cli, d, "history", "drift", "--robot-id", "A4-0101", "--tolerance",
                             str(FLEET / "tolerances.toml"), "--db", "cli.sqlite")
    assert [f["key"] for f in drift["flags"]] == ["p14 + p20"]
    # One calibration: nothing compared, and the reason, from both front ends.
    alone = kinecal.history.drift("A4-0105", db=db)
    assert alone == cli_json(cli, d, "history", "drift", "--robot-id", "A4-0105", "--db",
                             "cli.sqlite")
    assert "one calibration" in alone["nothing_to_compare"] and alone["quantities"] == []
    assert kinecal.history.events(db=db) == cli_json(cli, d, "history", "events", "--db",
                                                     "cli.sqlite")
    fleet = kinecal.history.fleet(db=db, now="2026-12-15", tolerance=FLEET / "tolerances.toml",
                                  json=d / "py-fleet.json")
    subprocess.run([cli, "history", "fleet", "--now", "2026-12-15", "--tolerance",
                    str(FLEET / "tolerances.toml"), "--json", "cli-fleet.json", "--db",
                    "cli.sqlite"], cwd=d, check=False, capture_output=True)
    by_cli = json.loads((d / "cli-fleet.json").read_text().replace("cli.sqlite", "py.sqlite"))
    assert fleet == by_cli == json.loads((d / "py-fleet.json").read_text())
    assert fleet["robots"][0]["robot_id"] == "A4-0101"
    assert fleet["robots"][0]["verdict"] == "flagged"
    plot = kinecal.history.plot("A4-0101", d / "p.svg", db=db, param=["p14 + p20"])
    assert plot["quantities"] == ["p14 + p20"] and (d / "p.svg").read_text().startswith("<svg")
    csv = kinecal.history.export(db=db, robot_id="A4-0101")
    assert csv["text"].startswith("calibration,robot_id,at,")
    # The two histories hold the same records and events.
    dumps = [kinecal.history.export(db=f, format="dump")["text"]
             for f in ("cli.sqlite", "py.sqlite")]
    assert dumps[0] == dumps[1]
    assert kinecal.history.init(db=db)["backend"] == "sqlite"


def test_run_of_the_written_spec_gives_the_same_document(
    cli: str, histories: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    d = histories
    args = ["history", "drift", "--robot-id", "A4-0101", "--sigma", "2.5", "--db", "py.sqlite"]
    out = subprocess.run([cli, *args, "--write-spec", "drift.toml", "--json"], cwd=d,
                         check=False, capture_output=True, text=True)
    assert out.returncode == 3, out.stderr
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        by_run = kinecal.run(d / "drift.toml")
    assert by_run == json.loads(out.stdout)
    monkeypatch.chdir(d)
    assert kinecal.history.drift("A4-0101", sigma=2.5, db="py.sqlite") == by_run
    with pytest.warns(UserWarning, match="history-drift: flagged"):
        kinecal.run({"job": "history-drift", "robot_id": "A4-0101", "db": "py.sqlite"})


@pytest.mark.parametrize(
    "call, keyword",
    [
        (lambda db: kinecal.history.drift("A", sigma=-1, db=db), "sigma"),
        (lambda db: kinecal.history.drift("A", baseline="last", db=db), "baseline"),
        (lambda db: kinecal.history.drift("", db=db), "robot_id"),
        (lambda db: kinecal.history.fleet(horizon=float("inf"), db=db), "horizon"),
        (lambda db: kinecal.history.fleet(horizon="soon", db=db), "horizon"),
        (lambda db: kinecal.history.fleet(horizon=1e9, db=db), "horizon"),
        (lambda db: kinecal.history.add("  A  ", FLEET / "history.json", db=db), "robot_id"),
        (lambda db: kinecal.history.event("A", "x", at="yesterday", db=db), "at"),
        (lambda db: kinecal.history.event("A", "", db=db), "note"),
        (lambda db: kinecal.history.show(db=db), "id"),
        (lambda db: kinecal.history.export(format="xml", db=db), "format"),  # type: ignore[arg-type]
        (lambda db: kinecal.history.plot("A", "p.jpg", db=db), "out"),
        (lambda db: kinecal.history.list(db=7), "db"),
    ],
)
def test_a_bad_value_names_its_keyword(call: Any, keyword: str, tmp_path: Path) -> None:
    db = str(tmp_path / "h.sqlite")
    with pytest.raises(kinecal.KinecalError) as e:
        call(db)
    assert str(e.value).startswith(f"{keyword}: "), str(e.value)
    # A refused job creates no history.
    assert not os.path.exists(db)


def test_store_errors_name_the_database(tmp_path: Path) -> None:
    with pytest.raises(kinecal.KinecalError, match="no such history database"):
        kinecal.history.list(db=tmp_path / "missing.sqlite")
    (tmp_path / "foreign.sqlite").write_text("not a database")
    with pytest.raises(kinecal.KinecalError, match="foreign.sqlite"):
        kinecal.history.add("A", tmp_path / "foreign.sqlite", db=tmp_path / "foreign.sqlite")


def test_a_refused_report_is_not_recorded(tmp_path: Path) -> None:
    report = json.loads((FLEET / "history.json").read_text())["calibrations"][0]["report"]
    refused = json.loads(report)
    refused["refused"] = "REFUSED: a unit check fired: no calibrated robot is written or recorded."
    (tmp_path / "refused.json").write_text(json.dumps(refused))
    db = tmp_path / "h.sqlite"
    with pytest.raises(kinecal.KinecalError, match="refused.json: the report says the calibration"):
        kinecal.history.add("RF", tmp_path / "refused.json", db=db)
    assert not db.exists()
    # An export of a robot with nothing recorded raises, as list does.
    kinecal.history.import_dump(FLEET / "history.json", db=db)
    for fmt in ("csv", "json"):
        with pytest.raises(kinecal.KinecalError, match="no calibration recorded for robot `NOPE`"):
            kinecal.history.export(robot_id="NOPE", format=fmt, db=db)  # type: ignore[arg-type]
