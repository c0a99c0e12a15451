"""One door for every job, from Python: ``kinecal.run`` of the spec the command line writes
(``--write-spec``) gives the command line's outputs and document, and the named functions give
the same document as ``run`` of the same job. The command line's own four ways (flags, spec,
batch) are checked by ``crates/kinecal-cli/tests/door.rs``."""

from __future__ import annotations

import json
import os
import subprocess
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import kinecal

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", ".."))


def normal(text: str) -> Any:
    """A document or output as compared: JSON without ``created`` and ``timings``; other text
    as it is."""
    try:
        value = json.loads(text)
    except json.JSONDecodeError:
        return text

    def strip(v: Any) -> Any:
        if isinstance(v, dict):
            return {k: strip(x) for k, x in v.items() if k not in ("created", "timings")}
        if isinstance(v, list):
            return [strip(x) for x in v]
        return v

    return strip(value)


@pytest.fixture(scope="module")
def lab(cli: str, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The README's GE A4 session: data, a calibration with a prediction, a robot with
    [priors], the IRB 120's ISO 9283 poses and a log."""
    d = tmp_path_factory.mktemp("door")

    def run(*args: str) -> None:
        subprocess.run([cli, *args], cwd=d, check=True, capture_output=True)

    run("simulate", "--robot", "ge-a4", "--postures", "30", "--seed", "7", "--perturb",
        "p1=+0.05,p14=-0.02,joint2.offset=-0.5,joint4.slope=+0.02", "--noise",
        "length=0.0005,angle=0.005", "--out", "data.csv", "--truth", "truth.toml")
    run("calibrate", "--robot", "ge-a4", "--data", "data.csv", "--estimate",
        "p1,p2,p8,p14,offsets,slopes", "--predict", "--out", "cal.toml", "--report",
        "report.json", "-q")
    ge = (Path(ROOT) / "examples" / "robots" / "ge_a4.toml").read_text()
    (d / "priors.toml").write_text(ge + '\n[priors]\nlength = 0.004\nangle = 0.02\n')
    irb = Path(ROOT) / "examples" / "robots" / "abb_irb120.toml"
    (d / "irb.toml").write_text(irb.read_text())
    run("iso9283", "plan", "--robot", "irb.toml", "--attitude", "3.141592653589793,0,0",
        "--resolution", "4", "--out", "poses.csv")
    run("iso9283", "simulate", "--robot", "irb.toml", "--poses", "poses.csv", "--cycles", "3",
        "--noise", "length=0.01", "--out", "log.csv")
    run("export", "dh", "--robot", "irb.toml", "--convention", "modified", "--out", "dh.csv")
    # A camera on the IRB 120's flange and its views of a board (docs/cameras.md).
    cameras = Path(ROOT) / "examples" / "cameras"
    (d / "cam.toml").write_text((cameras / "eye_in_hand.toml").read_text())
    (d / "cam_truth.toml").write_text((cameras / "eye_in_hand_truth.toml").read_text())
    run("simulate", "--robot", "cam_truth.toml", "--camera", "wrist", "--board", "board",
        "--postures", "22", "--seed", "5", "--noise", "pixel=0.3", "--out", "views.csv")
    # Roles of an ISO 9283 test in the GE A4's data: postures 1-27 as 3 cycles of 9 poses.
    roles = ["posture,test,pose,cycle"] + [
        f"{k + 1},cube 1,{'P1' if k % 9 == 0 else f'C{k % 9}'},{k // 9 + 1}" for k in range(27)
    ]
    (d / "roles.csv").write_text("\n".join(roles) + "\n")
    return d


# Each job: its command line (outputs named a_*), whether it prints its document (--json).
CASES: list[tuple[str, list[str], bool]] = [
    ("simulate", ["simulate", "--robot", "ge-a4", "--postures", "12", "--seed", "3",
                  "--perturb", "p1=+0.05", "--noise", "length=0.001", "--out", "a_data.csv",
                  "--truth", "a_truth.toml"], False),
    ("calibrate", ["calibrate", "--robot", "ge-a4", "--data", "data.csv", "--estimate",
                   "identifiable", "--folds", "3", "--out", "a_cal.toml", "--report",
                   "a_report.json", "-q"], False),
    ("analyze", ["analyze", "--robot", "priors.toml", "--data", "data.csv", "--estimate", "all",
                 "--json"], True),
    ("plan", ["plan", "--robot", "ge-a4", "--sample", "150", "--seed", "3", "--count", "6",
              "--criterion", "i", "--out", "a_plan.csv", "--json"], True),
    ("predict", ["predict", "--robot", "cal.toml", "--report", "report.json", "--sample",
                 "40", "--seed", "2", "--out", "a_predicted.csv"], False),
    ("compensate", ["compensate", "--robot", "cal.toml", "--nominal", "ge-a4", "--in",
                    "data.csv", "--position-only", "--out", "a_compensated.csv"], False),
    ("check", ["check", "--robot", "cal.toml", "--data", "data.csv", "--threshold", "0.01,0.05",
               "--json"], True),
    ("fk", ["fk", "--robot", "truth.toml", "--postures", "data.csv", "--out", "a_poses.csv"],
     False),
    ("export", ["export", "dh", "--robot", "irb.toml", "--convention", "modified", "--out",
                "a_dh.csv"], False),
    ("report", ["report", "--from", "report.json", "--out", "a_page.html"], False),
    ("curves", ["curves", "objective", "--robot", "ge-a4", "--data", "data.csv", "--param",
                "p1", "--points", "11", "--out", "a_objective.csv"], False),
    ("export-joints", ["export", "joints", "--robot", "cal.toml", "--nominal", "ge-a4",
                       "--tolerance", "length=1,angle=1", "--out", "a_joints.csv"], False),
    ("import", ["import", "dh", "dh.csv", "--name", "from dh", "--out", "a_imported.toml"],
     False),
    ("iso9283-plan", ["iso9283", "plan", "--robot", "irb.toml", "--attitude",
                      "3.141592653589793,0,0", "--resolution", "4", "--out", "a_iso_poses.csv"],
     False),
    ("iso9283-simulate", ["iso9283", "simulate", "--robot", "irb.toml", "--poses", "poses.csv",
                          "--cycles", "3", "--noise", "length=0.001", "--out", "a_log.csv"],
     False),
    ("iso9283-log", ["iso9283", "log", "--robot", "ge-a4", "--data", "data.csv", "--roles",
                     "roles.csv", "--out", "a_iso_log.csv"], False),
    ("iso9283-evaluate", ["iso9283", "evaluate", "--data", "log.csv", "--json", "a_iso.json"],
     False),
    ("simulate-camera", ["simulate", "--robot", "cam_truth.toml", "--camera", "wrist",
                         "--board", "board", "--postures", "6", "--seed", "2", "--noise",
                         "pixel=0.5", "--min-points", "30", "--out", "a_views.csv"], False),
    ("calibrate-camera", ["calibrate", "--robot", "cam.toml", "--pixels", "views.csv",
                          "--estimate", "extrinsics,boards", "--predict", "--out", "a_cam.toml",
                          "--report", "a_cam.json", "-q"], False),
    ("analyze-camera", ["analyze", "--robot", "cam_truth.toml", "--pixels", "views.csv",
                        "--estimate", "identifiable,cameras,boards", "--json"], True),
    ("check-pixels", ["check", "--robot", "cam_truth.toml", "--pixels", "views.csv",
                      "--threshold", "0.001", "--pixel-threshold", "1.5", "--json"], True),
    ("export-camera-info", ["export", "camera-info", "--robot", "cam_truth.toml", "--camera",
                            "wrist", "--out", "a_wrist.yaml"], False),
]


@pytest.mark.parametrize("name, args, prints", CASES, ids=[c[0] for c in CASES])
def test_run_gives_the_command_line_s_outputs_and_document(
    cli: str, lab: Path, name: str, args: list[str], prints: bool
) -> None:
    flags = subprocess.run([cli, *args, "--write-spec", f"{name}.toml"], cwd=lab,
                           check=False, capture_output=True, text=True)
    assert flags.returncode in (0, 4), flags.stderr
    spec = (lab / f"{name}.toml").read_text()
    (lab / f"p_{name}.toml").write_text(spec.replace("a_", "p_"))
    outputs = [a for a in args if a.startswith("a_")]
    cwd = os.getcwd()
    os.chdir(lab)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            # By the spec file's path, and as its TOML text (paths as the command line's).
            document = kinecal.run(f"p_{name}.toml")
            again = kinecal.run(spec.replace("a_", "t_"))
    finally:
        os.chdir(cwd)
    if name == "report":
        assert document == {"written": "p_page.html"} and again == {"written": "t_page.html"}
        document = again = {}
    assert normal(json.dumps(document)) == normal(json.dumps(again)), name
    for out in outputs:
        want = normal((lab / out).read_text())
        assert normal((lab / out.replace("a_", "p_")).read_text()) == want, f"{name}: {out}"
        assert normal((lab / out.replace("a_", "t_")).read_text()) == want, f"{name}: {out}"
    if prints:
        assert normal(json.dumps(document)) == normal(flags.stdout), f"{name}: the document"
    if name == "calibrate":
        assert normal(json.dumps(document)) == normal((lab / "a_report.json").read_text())
    if name == "calibrate-camera":
        assert normal(json.dumps(document)) == normal((lab / "a_cam.json").read_text())
        assert document["prediction"]["position"]["points"] > 0


def test_named_functions_are_spellings_of_the_same_specs(lab: Path) -> None:
    """Each named function with data in memory gives the document ``run`` gives of the same job
    from files; the robot file's [priors] are used by both (Python's analyze once dropped
    them)."""
    priors = kinecal.Robot.from_toml(lab / "priors.toml")
    nominal = kinecal.Robot.builtin("ge-a4")
    data = kinecal.Measurements.read_csv(lab / "data.csv", priors)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        by_run = kinecal.run({"job": "analyze", "robot": str(lab / "priors.toml"),
                              "observations": [{"file": str(lab / "data.csv")}],
                              "selection": {"estimate": "all"}})
        named = kinecal.analyze(priors, data, estimate="all")
    assert named == by_run
    assert named["rank"] == len(named["parameter_ids"]), "the prior determines every parameter"
    without = kinecal.analyze(priors, data, estimate="all", prior="none")
    assert without["rank"] < named["rank"]
    # A calibration: the same numbers (the in-memory one has no files to fingerprint).
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        from_files = kinecal.calibrate({"robot": "ge-a4",
                                        "observations": [{"file": str(lab / "data.csv")}],
                                        "selection": {"estimate": "identifiable"},
                                        "residuals": {"loss": "huber"}})
        in_memory = kinecal.calibrate(nominal, kinecal.Measurements.read_csv(
            lab / "data.csv", nominal), estimate="identifiable", loss="huber")
    assert from_files.robot.to_toml() == in_memory.robot.to_toml()
    for key in ("parameters", "rank", "variance_factor", "identification"):
        assert from_files.report[key] == in_memory.report[key], key
    # A plan from the same sample, and a simulation.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        plan_doc = kinecal.run({"job": "plan", "robot": "ge-a4", "sample": 150, "seed": 3,
                                "count": 6, "criterion": "i"})
    plan = kinecal.plan(nominal, sample=150, seed=3, count=6, criterion="i")
    assert plan.criterion == plan_doc["criterion"] and plan.value == plan_doc["value"]
    assert plan.labels == [p["label"] for p in plan_doc["postures"]]
    sim_doc = kinecal.run({"job": "simulate", "robot": "ge-a4", "postures": 12, "seed": 3,
                           "perturb": {"p1": 0.05}, "noise": {"length": 0.001}})
    sim = kinecal.simulate(nominal, 12, seed=3, perturb={"p1": 0.05}, noise={"length": 0.001})
    assert sim.measurements.to_csv(nominal) == sim_doc["data"]
    assert sim.truth.to_toml() == sim_doc["truth"]


def test_named_functions_of_the_other_jobs_give_run_s_results(lab: Path) -> None:
    """predict, compensate, iso9283_log and iso9283 with data in memory give what ``run`` of the
    same job from files gives: the same numbers to the last bit, the same log, the same
    figures."""
    nominal = kinecal.Robot.builtin("ge-a4")
    calibrated = kinecal.Robot.from_toml(lab / "cal.toml")
    data = kinecal.Measurements.read_csv(lab / "data.csv", nominal)
    readings = data.readings
    # The data's readings as a program (a file with measured poses would make them targets).
    program = ["posture," + ",".join(f"v{j + 1}" for j in range(readings.shape[1]))]
    program += [f"{i + 1}," + ",".join(repr(float(v)) for v in row)
                for i, row in enumerate(readings)]
    (lab / "program.csv").write_text("\n".join(program) + "\n")
    cwd = os.getcwd()
    os.chdir(lab)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            kinecal.run({"job": "predict", "robot": "cal.toml", "report": "report.json",
                         "postures": "data.csv", "outputs": {"predictions": "n_predict.csv"}})
            kinecal.run({"job": "compensate", "robot": "cal.toml", "nominal": "ge-a4",
                         "in": "program.csv", "position_only": True,
                         "out": "n_compensated.csv"})
            log_doc = kinecal.run({"job": "iso9283-log", "robot": "ge-a4", "data": "data.csv",
                                   "roles": "roles.csv"})
            iso_doc = kinecal.run({"job": "iso9283-evaluate", "data": "log.csv"})
    finally:
        os.chdir(cwd)
    table = np.genfromtxt(lab / "n_predict.csv", delimiter=",", names=True)
    predicted = kinecal.predict(calibrated, lab / "report.json", postures=readings)
    for column in ("position_bound95", "position_parameters", "position_model",
                   "attitude_bound95", "distance"):
        assert np.array_equal(predicted[column], table[column]), column
    compensated = np.genfromtxt(lab / "n_compensated.csv", delimiter=",", names=True)
    named = kinecal.compensate(calibrated, nominal, program=readings, position_only=True)
    for j in range(readings.shape[1]):
        assert np.array_equal(named.readings[:, j], compensated[f"v{j + 1}"]), f"v{j + 1}"
    assert np.array_equal(named.iterations, compensated["iterations"])
    assert not named.flagged.any()
    log = kinecal.iso9283_log(nominal, data, lab / "roles.csv")
    assert log.text == log_doc["log"]
    assert log.left_out == log_doc["left_out"] == ["28", "29", "30"]
    figures = kinecal.iso9283(lab / "log.csv")
    # The log's name as each was given it: a path, and a path relative to the working folder.
    assert figures.pop("file") == str(lab / "log.csv") and iso_doc.pop("file") == "log.csv"
    assert figures == iso_doc


@pytest.mark.parametrize(
    "call, keyword",
    [
        (lambda r, d: kinecal.calibrate(r, d, huber_spread=-1), "huber_spread"),
        (lambda r, d: kinecal.calibrate(r, d, max_iterations="many"), "max_iterations"),
        (lambda r, d: kinecal.calibrate(r, d, rcond=2.0, method="svd"), "rcond"),
        (lambda r, d: kinecal.calibrate(r, d, folds=np.int64(0)), "folds"),
        (lambda r, d: kinecal.analyze(r, d, rcond=-1), "rcond"),
        (lambda r, d: kinecal.analyze(r, d, priority=7), "priority"),
        (lambda r, d: kinecal.plan(r, sample=10, count=-1), "count"),
        (lambda r, d: kinecal.plan(r, sample=10, count=3, criterion=1), "criterion"),
        (lambda r, d: kinecal.simulate(r, 5, noise={"length": "x"}), "noise"),
        (lambda r, d: kinecal.compensate(r, r, program=np.zeros((1, 4)), singular=[1]),
         "singular"),
        (lambda r, d: kinecal.calibrate(r, d, weights={"length": float("nan")}), "weights"),
        (lambda r, d: kinecal.calibrate(r, d, estimate=object()), "estimate"),
    ],
)
def test_a_bad_value_names_its_keyword_never_a_type_error(call: Any, keyword: str) -> None:
    robot = kinecal.Robot.builtin("ge-a4")
    q = np.random.default_rng(1).uniform(-30, 30, size=(12, 4))
    data = kinecal.Measurements(robot, q, robot.fk(q)[:, :3])
    with pytest.raises(kinecal.KinecalError) as e:
        call(robot, data)
    assert str(e.value).startswith(f"{keyword}: "), str(e.value)
    assert e.value.field == keyword or keyword in str(e.value)


def test_run_refuses_a_spec_of_no_job_and_writes_no_input(lab: Path) -> None:
    with pytest.raises(kinecal.KinecalError, match="unknown job `calibrat`"):
        kinecal.run({"job": "calibrat", "robot": "ge-a4"})
    with pytest.raises(kinecal.KinecalError, match="refusing to write an output over an input"):
        kinecal.run({"job": "simulate", "robot": str(lab / "priors.toml"), "postures": 3,
                     "out": str(lab / "priors.toml")})
    with pytest.raises(TypeError, match="expected a spec"):
        kinecal.run(42)  # type: ignore[arg-type]
