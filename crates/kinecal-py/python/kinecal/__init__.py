"""Robot kinematic calibration from Python: the kinecal library, from numpy arrays.

Conventions (as in kinecal's files): readings are the transducer values of the robot file
(``q = offset + slope * V``); lengths are in the robot's length unit and angles in its angle
unit (``Robot.units``); attitudes are ZYX Euler angles ``(alpha, beta, gamma)``,
``R = Rz(alpha) Ry(beta) Rx(gamma)``.

    >>> import kinecal
    >>> robot = kinecal.Robot.builtin("ge-a4")
    >>> robot.fk([[0, 0, 0, 0, 0]]).shape
    (1, 6)

Errors are raised as ``kinecal.KinecalError`` (a ``ValueError``) with ``file``, ``line`` and
``field`` attributes where the problem came from a file, or as ``TypeError`` for arguments of
the wrong type. Calibration and analysis release the GIL.
"""

from __future__ import annotations

import json
import os
from typing import Any, Dict, List, NamedTuple, Optional, Sequence, Union

import numpy as np

from ._native import KinecalError, Measurements, Robot, __version__
from . import _native

__all__ = [
    "Robot",
    "Measurements",
    "Calibration",
    "Dataset",
    "KinecalError",
    "calibrate",
    "analyze",
    "dataset",
    "datasets",
    "__version__",
]

ParamList = Union[str, Sequence[str], None]


class Calibration:
    """The outcome of :func:`calibrate`.

    ``robot`` is the calibrated robot; ``report`` the full report as a dict (the same
    document as ``kinecal calibrate --report``: every parameter, uncertainty, determined
    combinations, identification and validation accuracy, outliers, warnings, timings).
    Values are in the robot's units.
    """

    def __init__(self, robot: Robot, report_json: str) -> None:
        self.robot: Robot = robot
        self.report: Dict[str, Any] = json.loads(report_json)
        self._json = report_json

    @property
    def converged(self) -> bool:
        """False only when the iteration cap stopped the solver."""
        return bool(self.report["converged"])

    @property
    def iterations(self) -> int:
        """Iterations the solver ran."""
        return int(self.report["iterations"])

    @property
    def estimated(self) -> List[str]:
        """Names of the estimated parameters, in thesis order."""
        return [p["name"] for p in self.report["parameters"] if p["estimated_flag"]]

    @property
    def values(self) -> np.ndarray:
        """Estimated values of :attr:`estimated`, in the same order (file units)."""
        return np.array(
            [p["estimated"] for p in self.report["parameters"] if p["estimated_flag"]],
            dtype=float,
        )

    @property
    def estimates(self) -> Dict[str, float]:
        """Estimated values by parameter name (file units)."""
        return dict(zip(self.estimated, self.values.tolist()))

    @property
    def sigmas(self) -> Dict[str, float]:
        """Standard deviations (file units) of the estimated parameters the data determines
        individually; parameters determined only in combination are left out (see
        :attr:`combinations`)."""
        return {
            p["name"]: p["sigma"]
            for p in self.report["parameters"]
            if p["estimated_flag"] and p.get("sigma") is not None
        }

    @property
    def undetermined(self) -> List[str]:
        """Estimated parameters the data does not determine individually (ids)."""
        return list(self.report["undetermined"])

    @property
    def combinations(self) -> List[Dict[str, Any]]:
        """Combinations of parameters the data determines although their members are not
        (expression, terms, value, sigma)."""
        return list(self.report["combinations"])

    @property
    def identification(self) -> Dict[str, Any]:
        """Accuracy on the data calibrated on (before and after)."""
        return self.report["identification"]

    @property
    def validation(self) -> Optional[Dict[str, Any]]:
        """Accuracy on the validation data or hold-out (None without one)."""
        return self.report.get("validation")

    @property
    def cross_validation(self) -> Optional[Dict[str, Any]]:
        """The cross-validation, when ``folds`` was given."""
        return self.report.get("cross_validation")

    @property
    def warnings(self) -> List[str]:
        """Everything the user should know, worded."""
        return list(self.report["warnings"])

    def to_json(self) -> str:
        """The report as JSON text (what ``kinecal calibrate --report`` writes)."""
        return self._json

    def __repr__(self) -> str:
        # From the solver's start when the robot was placed (or rigidly fitted) first: the
        # nominal robot's error in a tracker's frame says nothing about the fit.
        state = "converged" if self.converged else "NOT converged"
        start = self.report.get("start")
        before = start["rms_position"] if start else self.report["rms_position_before"]
        label = "RMS position from the start" if start else "RMS position"
        return (
            f"Calibration({self.report['robot']!r}: {len(self.estimated)} parameters, "
            f"{state} in {self.iterations} iterations, {label} "
            f"{before:.4g} -> "
            f"{self.report['rms_position_after']:.4g} {self.report['length_unit']})"
        )


Weights = Union[None, Sequence[float], Dict[str, float]]


def _weights(weights: Weights) -> Optional[tuple]:
    """Standard deviations ``(length, angle)`` from a pair or a ``{"length", "angle"}`` dict."""
    if weights is None:
        return None
    if isinstance(weights, dict):
        unknown = sorted(set(weights) - {"length", "angle"})
        if unknown or len(weights) != 2:
            raise KinecalError(
                "weights: expected the keys length and angle"
                + (f", not {', '.join(map(repr, unknown))}" if unknown else "")
            )
        pair = [weights["length"], weights["angle"]]
    elif isinstance(weights, (str, bytes)):
        raise KinecalError("weights: expected (length, angle) or {'length': .., 'angle': ..}")
    else:
        pair = list(weights)
    if len(pair) != 2:
        raise KinecalError("weights: expected (length, angle) standard deviations")
    out = []
    for name, w in zip(("length", "angle"), pair):
        try:
            out.append(float(w))
        except (TypeError, ValueError):
            raise KinecalError(f"weights: {name} {w!r} is not a number") from None
    return tuple(out)


Spec = Union[Dict[str, Any], str, "os.PathLike[str]"]


def _calibrate_spec(spec: Spec) -> Calibration:
    """Runs a calibration spec (a dict, or a spec file's path) and writes its outputs."""
    if isinstance(spec, dict):
        robot_out, report, outputs = _native.calibrate_spec(json=json.dumps(spec))
    elif isinstance(spec, (str, os.PathLike)):
        robot_out, report, outputs = _native.calibrate_spec(path=os.fspath(spec))
    else:
        raise TypeError(
            f"calibrate: expected a Robot (with data) or a spec (a dict or a spec file's path), "
            f"not {type(spec).__name__}"
        )
    for path, text in outputs:
        # Written into what is there (a symlink's target, a device), with the umask's mode.
        with open(path, "w", encoding="utf-8", newline="") as f:
            f.write(text)
    return Calibration(robot_out, report)


def calibrate(
    robot: Union[Robot, Spec],
    data: Optional[Measurements] = None,
    *,
    estimate: ParamList = None,
    fix: ParamList = None,
    method: str = "lm",
    loss: str = "squared",
    huber_scale: float = 1.345,
    weights: Weights = None,
    orientation_error: str = "rotvec",
    validate: Optional[Measurements] = None,
    holdout: Optional[float] = None,
    folds: Optional[int] = None,
    seed: Optional[int] = None,
    prune: Optional[float] = None,
    solution: str = "solver",
    initial: Optional[Robot] = None,
    max_iterations: Optional[int] = None,
    outlier_sigma: Optional[float] = None,
) -> Calibration:
    """Calibrates ``robot`` on ``data``: the same workflow as ``kinecal calibrate``.

    ``estimate``/``fix``: parameter lists as ``--estimate``/``--fix`` take them
    (``"identifiable,slopes"``, ``["link2", "offsets"]``); by default the parameters the data
    can see. ``method``: ``"lm"``, ``"gn"``, ``"sd"`` or ``"svd"``. ``loss``: ``"squared"``
    or ``"huber"`` (threshold ``huber_scale`` robust spreads). ``weights``: standard
    deviations in file units, ``(length, angle)`` or ``{"length": ..., "angle": ...}``. One of ``validate`` (other measurements),
    ``holdout`` (a fraction of the postures, drawn with ``seed``) or ``folds`` (k-fold
    cross-validation) checks the result. ``prune``: drop changes below this many standard
    deviations. ``solution``: ``"solver"`` or ``"min-change"``.

    ``calibrate(spec)`` runs a whole job instead: ``spec`` is a calibration spec, the document
    ``kinecal calibrate --spec`` reads, as a dict (``{"robot": "arm.toml", "observations":
    [{"file": "data.csv"}], "validation": {"folds": 5}}``; paths relative to the working
    folder) or a spec file's path (paths relative to its folder); the outputs it names are
    written. It gives the same calibration as the command line given the same job.
    """
    if not isinstance(robot, Robot):
        if data is not None:
            raise TypeError("calibrate(spec): the spec names its data; give no data")
        return _calibrate_spec(robot)
    if data is None:
        raise TypeError("calibrate: data is needed with a Robot (or give a spec)")
    weights = _weights(weights)
    robot_out, report = _native.calibrate(
        robot,
        data,
        estimate=estimate,
        fix=fix,
        method=method,
        loss=loss,
        huber_scale=huber_scale,
        weights=weights,
        orientation_error=orientation_error,
        validate=validate,
        holdout=holdout,
        folds=folds,
        seed=seed,
        prune=prune,
        solution=solution,
        initial=initial,
        max_iterations=max_iterations,
        outlier_sigma=outlier_sigma,
    )
    return Calibration(robot_out, report)


def analyze(
    robot: Robot,
    data: Measurements,
    *,
    estimate: ParamList = "identifiable",
    fix: ParamList = None,
    weights: Weights = None,
    orientation_error: str = "rotvec",
    rcond: Optional[float] = None,
) -> Dict[str, Any]:
    """What ``data`` determines about the parameters of ``estimate``: the same document as
    ``kinecal analyze --json`` (rank, singular values, the identifiable set, identically
    redundant combinations, null space, warnings), plus ``unseen``: parameters left out of
    the default set because no measurement sees them."""
    weights = _weights(weights)
    return json.loads(
        _native.analyze(
            robot,
            data,
            estimate=estimate,
            fix=fix,
            weights=weights,
            orientation_error=orientation_error,
            rcond=rcond,
        )
    )


class Dataset(NamedTuple):
    """A published data set read as it is: the robot, the data, and the calibration its
    README suggests (keywords for :func:`calibrate`)."""

    robot: Robot
    identification: Measurements
    validation: Optional[Measurements]
    suggested: Dict[str, Any]


def datasets() -> List[tuple]:
    """The published data sets kinecal reads as they are: ``(name, about)`` pairs."""
    return _native.datasets()


def dataset(name: str, folder: str) -> Dataset:
    """Reads a published data set's folder (e.g. ``dataset("qkm-hl6",
    "shared/data/qkm_hl6_faro")``)."""
    robot, ident, valid, suggested = _native.dataset(name, folder)
    kw = json.loads(suggested)
    if "weights" in kw:
        kw["weights"] = tuple(kw["weights"])
    return Dataset(robot, ident, valid, kw)
