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
the wrong type. Calibration, analysis, planning and compensation release the GIL.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping, Sequence
from typing import Any, NamedTuple, Union

import numpy as np
import numpy.typing as npt

from . import _native
from ._native import ExportWarning, KinecalError, Measurements, Robot, __version__

__all__ = [
    "Calibration",
    "Compensation",
    "Dataset",
    "ExportWarning",
    "IsoLog",
    "KinecalError",
    "Measurements",
    "Plan",
    "RandomPlans",
    "ResidualRow",
    "Robot",
    "Simulation",
    "__version__",
    "analyze",
    "calibrate",
    "compensate",
    "dataset",
    "datasets",
    "history",
    "iso9283",
    "iso9283_log",
    "plan",
    "predict",
    "run",
    "simulate",
]

ParamList = Union[str, Sequence[str], None]
Weights = Union[None, Sequence[float], dict[str, float]]
# Settings of a few named numbers: a sequence in the order of their names, or a dict of some.
Spec = Union[None, Sequence[float], Mapping[str, float]]
Floats = npt.NDArray[np.float64]
Bools = npt.NDArray[np.bool_]
Ints = npt.NDArray[np.int64]


class ResidualRow(NamedTuple):
    """What one residual row of :attr:`Calibration.residuals` is: the ``posture`` label of
    its observation (the first posture's, for a distance), the observation's ``kind``
    (``pose``, ``position``, ``distance``, ``contact``), its ``target`` (``ee`` or a site),
    the ``row`` (``x``, ``y``, ``z``, ``alpha``, ``beta``, ``gamma``, ``distance``, ...) and
    the row's standard deviation ``sigma`` (its own, else the weights), in the unit of the
    residual."""

    posture: str
    kind: str
    target: str
    row: str
    sigma: float


class Calibration:
    """The outcome of :func:`calibrate`.

    ``robot`` is the calibrated robot; ``report`` the full report as a dict (the same
    document as ``kinecal calibrate --report``: every parameter, uncertainty, determined
    combinations, identification and validation accuracy, outliers, warnings, timings).
    Values are in the robot's units.

    What :func:`calibrate` returns keeps the library's outcome and makes each part when it is
    first read, then keeps it: the report's JSON text, its dict (:attr:`report`, which every
    figure is read from), :attr:`covariance`, :attr:`residuals` and :attr:`residual_rows`; a
    caller who uses only :attr:`robot` pays for none of them. ``Calibration(robot,
    report_json)`` makes one from a report's JSON text (without the outcome's arrays).
    """

    def __init__(
        self, robot: Robot, report_json: str, details: dict[str, Any] | None = None
    ) -> None:
        self.robot: Robot = robot
        self._json: str | None = report_json
        self._report: dict[str, Any] | None = None
        self._outcome: _native.Outcome | None = None
        self._details = details
        self._residuals: Floats | None = None
        self._rows: list[ResidualRow] | None = None
        if details is not None and details["covariance_names"] != self.estimated:
            raise KinecalError("the covariance is not in the order of the estimated parameters")

    @classmethod
    def _of(cls, robot: Robot, outcome: _native.Outcome) -> Calibration:
        """The calibration of ``outcome`` (the native module's), its parts made when read."""
        made = cls.__new__(cls)
        made.robot = robot
        made._json = None
        made._report = None
        made._outcome = outcome
        made._details = None
        made._residuals = None
        made._rows = None
        return made

    @property
    def report(self) -> dict[str, Any]:
        """The full report as a dict (the JSON of :meth:`to_json`, read when first asked
        for; the same dict after that)."""
        if self._report is None:
            self._report = json.loads(self.to_json())
        return self._report

    @report.setter
    def report(self, value: dict[str, Any]) -> None:
        self._report = value

    @property
    def converged(self) -> bool:
        """False only when the iteration cap stopped the solver."""
        return bool(self.report["converged"])

    @property
    def iterations(self) -> int:
        """Iterations the solver ran."""
        return int(self.report["iterations"])

    @property
    def estimated(self) -> list[str]:
        """Names of the estimated parameters, in thesis order."""
        return [p["name"] for p in self.report["parameters"] if p["estimated_flag"]]

    @property
    def values(self) -> Floats:
        """Estimated values of :attr:`estimated`, in the same order (file units)."""
        return np.array(
            [p["estimated"] for p in self.report["parameters"] if p["estimated_flag"]],
            dtype=float,
        )

    @property
    def estimates(self) -> dict[str, float]:
        """Estimated values by parameter name (file units)."""
        return dict(zip(self.estimated, self.values.tolist()))

    @property
    def sigmas(self) -> dict[str, float]:
        """Standard deviations (file units) of the estimated parameters the data determines
        individually; parameters determined only in combination are left out (see
        :attr:`combinations`)."""
        return {
            p["name"]: p["sigma"]
            for p in self.report["parameters"]
            if p["estimated_flag"] and p.get("sigma") is not None
        }

    def _detail(self, name: str) -> Any:
        if self._details is None:
            raise KinecalError(f"{name}: this Calibration was made without the outcome's arrays")
        return self._details[name]

    @property
    def covariance(self) -> Floats | None:
        """The covariance of the estimated parameters, ``(n, n)`` in the order of
        :attr:`estimated`, entry ``(a, b)`` in the unit of parameter ``a`` times that of ``b``
        (file units); None when the uncertainty could not be computed (a warning says why).

        It is the library's covariance over the directions the data determines (the variance
        factor times the pseudo-inverse of the information, linearised as the report's
        standard deviations are): the diagonal of a parameter in :attr:`sigmas` is its sigma
        squared, and for any determined combination ``c`` (see :attr:`combinations`)
        ``c @ covariance @ c`` is its variance. The entries of parameters determined only in
        combination mean nothing on their own."""
        if self._outcome is not None:
            return self._outcome.covariance()
        c: Floats | None = self._detail("covariance")
        return None if c is None else c.copy()

    @property
    def residuals(self) -> Floats:
        """The residuals of the calibrated robot on the identification data (the data minus
        any hold-out), ``model - measured``, one per residual row, in file units: lengths in
        the length unit, angles in the angle unit.

        Rows come observation after observation in the data's order (by posture), each
        observation's rows in its kind's order: ``x, y, z`` for a position; ``x, y, z`` then
        three angle rows for a pose (the rotation vector of ``R_measured^T R_model`` with
        ``orientation_error="rotvec"``, the differences of the ZYX Euler angles with
        ``"euler"``); one row for a distance or a plane contact. :attr:`residual_rows` names
        each row; dividing by its ``sigma`` gives the weighted residual the solver
        minimised."""
        if self._residuals is None:
            self._residuals = (
                self._detail("residuals") if self._outcome is None else self._outcome.residuals()
            )
        return self._residuals.copy()

    @property
    def residual_rows(self) -> list[ResidualRow]:
        """What each row of :attr:`residuals` is."""
        if self._rows is None:
            rows = (
                self._detail("residual_rows")
                if self._outcome is None
                else self._outcome.residual_rows()
            )
            self._rows = list(map(ResidualRow._make, rows))
        return list(self._rows)

    @property
    def undetermined(self) -> list[str]:
        """Estimated parameters the data does not determine individually (ids)."""
        return list(self.report["undetermined"])

    @property
    def combinations(self) -> list[dict[str, Any]]:
        """Combinations of parameters the data determines although their members are not
        (expression, terms, value, sigma)."""
        return list(self.report["combinations"])

    @property
    def identification(self) -> dict[str, Any]:
        """Accuracy on the data calibrated on (before and after)."""
        ident: dict[str, Any] = self.report["identification"]
        return ident

    @property
    def validation(self) -> dict[str, Any] | None:
        """Accuracy on the validation data or hold-out (None without one)."""
        return self.report.get("validation")

    @property
    def cross_validation(self) -> dict[str, Any] | None:
        """The cross-validation, when ``folds`` was given."""
        return self.report.get("cross_validation")

    @property
    def warnings(self) -> list[str]:
        """Everything the user should know, worded."""
        return list(self.report["warnings"])

    def to_json(self) -> str:
        """The report as JSON text (what ``kinecal calibrate --report`` writes)."""
        if self._json is None:
            assert self._outcome is not None
            self._json = self._outcome.report_json()
        return self._json

    def predict(
        self,
        postures: npt.ArrayLike | None = None,
        *,
        targets: npt.ArrayLike | None = None,
        site: str | None = None,
    ) -> dict[str, Floats]:
        """The predicted accuracy of the calibrated robot (see :func:`predict`); the
        calibration must have been asked for it (``calibrate(..., predict=True)``)."""
        return predict(self.robot, self, postures=postures, targets=targets, site=site)

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


def _pair(keyword: str, value: Any, keys: Sequence[str]) -> Any:
    """Named numbers as a spec holds them (a table of some of ``keys``), from a sequence of all of
    them in that order or a mapping of some of them; anything else is passed on for the
    library to refuse, naming ``keyword``."""
    if value is None or isinstance(value, (str, bytes, Mapping)):
        return value
    if isinstance(value, (Sequence, np.ndarray)):
        given = list(value)
        if len(given) != len(keys):
            raise KinecalError(
                f"{keyword}: expected ({', '.join(keys)}) or a dict of some of "
                f"{', '.join(map(repr, keys))}, got {len(given)} numbers"
            )
        return {k: v for k, v in zip(keys, given) if v is not None}
    return value


def _list(value: Any) -> Any:
    """A parameter (or site) list as a spec holds it: comma-separated text."""
    if isinstance(value, (list, tuple)) and all(isinstance(v, str) for v in value):
        return ",".join(value)
    return value


def _plain(keyword: str, value: Any) -> Any:
    """A keyword's value as JSON holds it: numpy scalars as numbers, paths as text; a number
    that is not finite, or a value of no spec type, is refused naming the keyword."""
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not np.isfinite(value):
        raise KinecalError(f"{keyword}: expected a finite number, not {value}")
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    if isinstance(value, Mapping):
        return {str(k): _plain(keyword, v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(keyword, v) for v in value]
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    raise KinecalError(f"{keyword}: {type(value).__name__} is not a value a setting takes")


class _Keywords:
    """A named function's keywords as a spec of ``job``: each keyword's value at its key path.
    Errors the library finds in them are raised naming the keyword."""

    def __init__(self, job: str, given: Mapping[str, tuple[str, Any]]) -> None:
        self.paths = {path: keyword for keyword, (path, _) in given.items()}
        spec: dict[str, Any] = {"job": job}
        for keyword, (path, value) in given.items():
            if value is None:
                continue
            at = spec
            parts = path.split(".")
            for part in parts[:-1]:
                at = at.setdefault(part, {})
            at[parts[-1]] = _plain(keyword, value)
        self.json = json.dumps(spec)

    def __enter__(self) -> str:
        return self.json

    def __exit__(
        self, kind: object, error: BaseException | None, trace: object
    ) -> None:
        if not isinstance(error, KinecalError) or error.file is not None or not error.field:
            return
        field = str(error.field)
        keyword = next(
            (k for p, k in sorted(self.paths.items(), key=lambda x: -len(x[0]))
             if field == p or field.startswith((p + ".", p + "["))),
            field.split(".")[-1],
        )
        wrapped = KinecalError(f"{keyword}: {error}")
        wrapped.field = keyword
        raise wrapped from None


JobSpec = Union[Mapping[str, Any], str, "os.PathLike[str]"]


def run(spec: JobSpec) -> dict[str, Any]:
    """Runs a job of any kind, as ``kinecal <job> --spec`` runs it: ``spec`` is a spec file's
    path (its paths relative to its folder), a spec's TOML text, or a dict of its keys (paths
    relative to the working folder), with its kind in ``job`` (``"calibrate"`` when absent).
    The outputs the spec names are written (never over an input). Returns the job's document,
    as the command line's ``--json`` or report gives it; its warnings are issued as
    ``UserWarning`` (and a calibration that did not converge, a check that failed or a
    compensation with flagged rows warns too)."""
    import warnings

    form, text = _spec_form(spec)
    kind, document, messages, status = _native.run(text, form)
    _warn(messages)
    if status != "ok":
        warnings.warn(f"{kind}: {status.replace('-', ' ')}", UserWarning, stacklevel=2)
    result: dict[str, Any] = json.loads(document)
    return result


def _spec_form(spec: JobSpec) -> tuple[str, str]:
    """How a spec is given (``path``, ``toml`` or ``json``) and its text."""
    if isinstance(spec, Mapping):
        return "json", json.dumps(_plain("spec", spec))
    if isinstance(spec, os.PathLike) or (
        isinstance(spec, str) and "\n" not in spec and "=" not in spec
    ):
        return "path", os.fspath(spec)
    if isinstance(spec, str):
        return "toml", spec
    raise TypeError(
        f"expected a spec (a dict, TOML text or a spec file's path), not {type(spec).__name__}"
    )


def _warn(messages: Sequence[tuple[str, str]]) -> None:
    """Issues a job's warnings as ``UserWarning``."""
    import warnings

    for level, message in messages:
        if level == "warning":
            warnings.warn(message, UserWarning, stacklevel=3)


def calibrate(
    robot: Robot | JobSpec,
    data: Measurements | None = None,
    *,
    estimate: ParamList = None,
    fix: ParamList = None,
    method: str | None = None,
    loss: str | None = None,
    huber_scale: float | None = None,
    huber_spread: str | None = None,
    weights: Weights = None,
    orientation_error: str | None = None,
    validate: Measurements | None = None,
    holdout: float | None = None,
    folds: int | None = None,
    seed: int | None = None,
    prune: float | None = None,
    solution: str | None = None,
    initial: Robot | None = None,
    max_iterations: int | None = None,
    damping: str | None = None,
    rcond: float | None = None,
    outlier_sigma: float | None = None,
    choose: Sequence[str] | None = None,
    repeats: int | None = None,
    prior: str | None = None,
    total_mass: float | None = None,
    predict: bool = False,
    force_units: bool = False,
) -> Calibration:
    """Calibrates ``robot`` on ``data``: the same workflow as ``kinecal calibrate``.

    ``estimate``/``fix``: parameter lists as ``--estimate``/``--fix`` take them
    (``"identifiable,slopes"``, ``["link2", "offsets"]``); by default the parameters the data
    can see. ``method``: ``"lm"``, ``"gn"``, ``"sd"`` or ``"svd"``. ``loss``: ``"squared"``
    or ``"huber"`` (threshold ``huber_scale``, default 1.345, spreads: ``huber_spread``
    ``"robust"``, the residuals' own, or ``"stated"``, the standard deviations). ``weights``: standard
    deviations in file units, ``(length, angle)`` or ``{"length": ..., "angle": ...}``. One of
    ``validate`` (other measurements), ``holdout`` (a fraction of the postures, drawn with
    ``seed``) or ``folds`` (k-fold cross-validation) checks the result. ``prune``: drop
    changes below this many standard deviations. ``solution``: ``"solver"`` or
    ``"min-change"``. ``choose``: model candidates (as ``--choose`` takes them; ``[]`` for the
    defaults) chosen among by ``folds`` (default 5) repeated ``repeats`` times. ``prior``: a
    Gaussian prior on each parameter's change, as ``--prior`` takes it
    (``"length=0.1,angle=0.05"`` in file units, slopes as a fraction, per-parameter entries
    ``"link3.y=0.5"``; ``"tolerances"``; ``"none"``); by default the robot file's ``[priors]``.
    ``total_mass``: the robot's known total mass (kg) for an elastic robot's masses, as
    ``--total-mass``. ``force_units``: return the calibration even when a unit check fired
    and the fit ended far above its stated noise (such a calibration raises
    :class:`KinecalError` otherwise, as ``kinecal calibrate`` refuses it without
    ``--force-units``). ``predict``: also work out the predicted accuracy (``--predict``; the
    report's ``prediction``, and :meth:`Calibration.predict`). ``max_iterations``,
    ``damping`` (``"marquardt"`` or ``"identity"``) and ``rcond`` (the singular-value
    threshold of ``svd`` and ``gn``) as ``--max-iter``, ``--damping`` and ``--rcond``. None
    leaves a setting at the library's default. Every keyword is a key of the calibration spec
    (``kinecal calibrate --write-spec`` writes one): a bad value raises :class:`KinecalError`
    naming the keyword.

    ``calibrate(spec)`` runs a whole job instead: ``spec`` is a calibration spec, the document
    ``kinecal calibrate --spec`` reads, as a dict (``{"robot": "arm.toml", "observations":
    [{"file": "data.csv"}], "validation": {"folds": 5}}``; paths relative to the working
    folder) or a spec file's path (paths relative to its folder); the outputs it names are
    written. It gives the same calibration as the command line given the same job.
    """
    if not isinstance(robot, Robot):
        if data is not None:
            raise TypeError("calibrate(spec): the spec names its data; give no data")
        form, text = _spec_form(robot)
        robot_out, outcome, messages = _native.calibrate_job(text, form)
        _warn(messages)
        return Calibration._of(robot_out, outcome)
    if data is None:
        raise TypeError("calibrate: data is needed with a Robot (or give a spec)")
    keywords = _Keywords(
        "calibrate",
        {
            "estimate": ("selection.estimate", _list(estimate)),
            "fix": ("selection.fix", _list(fix)),
            "prune": ("selection.prune", prune),
            "prior": ("selection.prior", prior),
            "total_mass": ("selection.total_mass", total_mass),
            "method": ("solver.method", method),
            "max_iterations": ("solver.max_iterations", max_iterations),
            "damping": ("solver.damping", damping),
            "rcond": ("solver.rcond", rcond),
            "solution": ("solver.solution", solution),
            "loss": ("residuals.loss", loss),
            "huber_scale": ("residuals.huber_scale", huber_scale),
            "huber_spread": ("residuals.huber_spread", huber_spread),
            "weights": ("residuals.weights", _pair("weights", weights, ("length", "angle"))),
            "orientation_error": ("residuals.orientation_error", orientation_error),
            "outlier_sigma": ("residuals.outlier_sigma", outlier_sigma),
            "holdout": ("validation.holdout", holdout),
            "folds": ("validation.folds", folds),
            "seed": ("validation.seed", seed),
            "choose": ("validation.choose", None if choose is None else list(choose)),
            "repeats": ("validation.repeats", repeats),
            "predict": ("validation.predict", predict or None),
            "force_units": ("force_units", force_units or None),
        },
    )
    with keywords as spec:
        robot_out, outcome = _native.calibrate(robot, data, spec, validate, initial)
    return Calibration._of(robot_out, outcome)


def analyze(
    robot: Robot,
    data: Measurements,
    *,
    estimate: ParamList = None,
    fix: ParamList = None,
    priority: ParamList = None,
    prior: str | None = None,
    total_mass: float | None = None,
    weights: Weights = None,
    orientation_error: str | None = None,
    rcond: float | None = None,
) -> dict[str, Any]:
    """What ``data`` determines about the parameters of ``estimate``: the same document as
    ``kinecal analyze --json`` (rank, singular values, the identifiable set, identically
    redundant combinations, null space, warnings), plus ``unseen``: parameters left out of
    the default set because no measurement sees them. ``estimate``: by default
    :func:`calibrate`'s default parameters (so that the identifiable set is the one
    ``estimate="identifiable"`` estimates; ``"all"`` for every one). ``priority``: parameters
    to prefer in the identifiable set. ``prior`` (default: the robot file's ``[priors]``) and
    ``total_mass`` as for :func:`calibrate`: the rank is then of the data and the prior
    together."""
    keywords = _Keywords(
        "analyze",
        {
            "estimate": ("selection.estimate", _list(estimate)),
            "fix": ("selection.fix", _list(fix)),
            "priority": ("selection.priority", _list(priority)),
            "prior": ("selection.prior", prior),
            "total_mass": ("selection.total_mass", total_mass),
            "weights": ("residuals.weights", _pair("weights", weights, ("length", "angle"))),
            "orientation_error": ("residuals.orientation_error", orientation_error),
            "rcond": ("rcond", rcond),
        },
    )
    with keywords as spec:
        document: dict[str, Any] = json.loads(_native.analyze(robot, data, spec))
    return document


class Compensation:
    """The outcome of :func:`compensate`, one row per program posture or target.

    ``readings`` ``(n, joints)``: the compensated readings. ``position_error`` ``(n,)`` and
    ``attitude_error`` ``(n,)``: what remains of the goal through the calibrated robot
    (length and angle unit; the attitude error is NaN for a position goal). ``iterations``
    ``(n,)``: of the damped least squares. ``conditioning`` ``(n,)``: smallest over largest
    singular value of the weighted reading Jacobian at the solution. The flags, as booleans:
    ``unreachable`` (the goal is not reached within the tolerances), ``out_of_range``
    ``(n, joints)`` (a reading outside the robot file's range), ``singular`` (conditioning
    below ``singular``), ``branch`` (a revolute joint turned more than ``branch`` from the
    seed: a change of configuration), ``configuration`` (no solution in the configuration
    asked for was found); ``flags``: the same in words, as ``kinecal
    compensate`` writes them (empty when none).
    """

    def __init__(self, fields: dict[str, Any]) -> None:
        self.readings: Floats = fields["readings"]
        self.position_error: Floats = fields["position_error"]
        self.attitude_error: Floats = fields["attitude_error"]
        self.iterations: Ints = fields["iterations"]
        self.conditioning: Floats = fields["conditioning"]
        self.unreachable: Bools = fields["unreachable"]
        self.out_of_range: Bools = fields["out_of_range"]
        self.singular: Bools = fields["singular"]
        self.branch: Bools = fields["branch"]
        self.configuration: Bools = fields["configuration"]
        self.flags: list[str] = fields["flags"]

    @property
    def flagged(self) -> Bools:
        """Rows with any flag: not to be used as they are."""
        flagged: Bools = (
            self.unreachable
            | self.out_of_range.any(axis=1)
            | self.singular
            | self.branch
            | self.configuration
        )
        return flagged

    def __len__(self) -> int:
        return len(self.flags)

    def __repr__(self) -> str:
        return (
            f"Compensation({len(self)} rows: {int(self.flagged.sum())} flagged "
            f"({int(self.unreachable.sum())} unreachable, "
            f"{int(self.out_of_range.any(axis=1).sum())} outside a joint range, "
            f"{int(self.singular.sum())} near a singularity, "
            f"{int(self.branch.sum())} changing configuration"
            + (f", {int(self.configuration.sum())} not in the configuration"
               if self.configuration.any() else "")
            + "))"
        )


def compensate(
    calibrated: Robot,
    nominal: Robot,
    *,
    program: npt.ArrayLike | None = None,
    targets: npt.ArrayLike | None = None,
    seeds: npt.ArrayLike | None = None,
    site: str | None = None,
    position_only: bool = False,
    tolerance: Spec = None,
    singular: float | None = None,
    branch: float | None = None,
    configuration: str | None = None,
) -> Compensation:
    """The readings that make the real (``calibrated``) robot reach what was meant: the
    same as ``kinecal compensate``, in the robot's units.

    Give one of ``program`` (``(n, joints)`` readings taught or planned with the ``nominal``
    model, which the controller uses: each row's goal is the pose the nominal model gives
    it, its position only with ``position_only``, which also leaves out the attitudes of
    targets) or ``targets`` (``(n, 3)`` positions or
    ``(n, 6)`` poses ``x, y, z, alpha, beta, gamma``, ZYX Euler angles), optionally with
    ``seeds`` (``(n, joints)`` readings to start each target from: the usable solution nearest
    the seed wins). Without seeds the solutions are searched from the previous row's and from
    postures sampled within the joint ranges whose frames lie near the goal, and the first
    usable one (reached, inside the joint ranges, in the configuration, not singular) is
    taken. ``configuration``: the configuration targets must be in, as ``kinecal compensate
    --configuration`` takes it (``"shoulder=front,elbow=up,wrist=noflip"``, any of them, for an
    arm of six revolute joints; or a sign pattern of the joint values ``"+,*,-,*,+,*"``). ``site``: the frame that must reach the goal (None or ``"ee"``: the
    end effector); a program of a tree may name one tool per branch, comma-separated
    (``"ee,left_marker"``): each reaches its pose with its own branch's joints, the joints
    the branches share held as programmed. ``tolerance``: the largest acceptable remaining error, ``(length,
    angle)`` or a dict of either (default 1 um and 1 urad). ``singular``: flag solutions
    whose conditioning is below it. ``branch``: flag a revolute joint turning more than this
    angle from the seed (default 0.5 rad).
    """
    keywords = _Keywords(
        "compensate",
        {
            "site": ("site", site),
            "position_only": ("position_only", position_only or None),
            "tolerance": ("tolerance", _pair("tolerance", tolerance, ("length", "angle"))),
            "singular": ("singular", singular),
            "branch": ("branch", branch),
            "configuration": ("configuration", configuration),
        },
    )
    with keywords as spec:
        fields = _native.compensate(
            calibrated, nominal, spec, program=program, targets=targets, seeds=seeds
        )
    return Compensation(fields)


class RandomPlans(NamedTuple):
    """Random plans of the same size from the same candidates, for comparison: how many
    were drawn, their median criterion value and median D-efficiency (None when the median
    plan does not determine every parameter and the criterion needs it), and how many of
    them the plan is at least as good as."""

    draws: int
    median_value: float | None
    median_efficiency: float | None
    at_least_as_good_as: int


class Plan:
    """The outcome of :func:`plan`: the same figures as ``kinecal plan --json``.

    ``criterion`` (``"d"``, ...) and its ``value`` for the plan (None when the plan does not
    determine every parameter and the criterion needs it); ``values``: every criterion's;
    ``parameters``: the names of the parameters planned for; ``rows``: residual rows of the
    plan; ``rank`` and ``condition_number`` of its scaled Jacobian; ``pool_candidates``;
    ``efficiency``: the D-efficiency against the candidates' average (1: as informative per
    posture as the average candidate); ``random``: :class:`RandomPlans`; ``exchanges`` and
    ``passes`` of the search.

    The plan's postures, kept ones first, then the chosen ones in the candidates' order:
    ``labels``, ``readings`` ``(k, joints)``, ``leverage`` ``(k,)`` (how many parameters'
    worth of information each carries), ``kept`` ``(k,)``. ``chosen``: the indices of the
    chosen candidates' postures into the candidates (rows of the candidate array, or
    postures of the candidate Measurements). ``observations``: the chosen candidates'
    observations as :class:`Measurements` (for candidates given as readings or sampled, with
    the values the nominal robot predicts).
    """

    def __init__(self, fields: dict[str, Any]) -> None:
        self.criterion: str = fields["criterion"]
        self.value: float | None = fields["value"]
        self.values: dict[str, float | None] = fields["values"]
        self.parameters: list[str] = fields["parameters"]
        self.rows: int = fields["rows"]
        self.rank: int = fields["rank"]
        self.condition_number: float | None = fields["condition_number"]
        self.pool_candidates: int = fields["pool_candidates"]
        self.efficiency: float | None = fields["efficiency"]
        random = fields["random"]
        self.random: RandomPlans | None = None if random is None else RandomPlans(*random)
        self.exchanges: int = fields["exchanges"]
        self.passes: int = fields["passes"]
        self.labels: list[str] = fields["labels"]
        self.readings: Floats = fields["readings"]
        self.leverage: Floats = fields["leverage"]
        self.kept: Bools = fields["kept"]
        self.chosen: Ints = fields["chosen"]
        self.observations: Measurements = fields["observations"]
        self._csv: str = fields["csv"]

    def to_csv(self) -> str:
        """The chosen postures as ``kinecal plan --out`` writes them: a postures file, or a
        measurement file when the candidates were Measurements of poses and positions."""
        return self._csv

    def __repr__(self) -> str:
        value = "n/a" if self.value is None else f"{self.value:.6g}"
        return (
            f"Plan({len(self.chosen)} of {self.pool_candidates} candidates for "
            f"{len(self.parameters)} parameters: rank {self.rank}, criterion "
            f"{self.criterion} {value})"
        )


Candidates = Union[npt.ArrayLike, Measurements, None]


def plan(
    robot: Robot,
    candidates: Candidates = None,
    *,
    count: int,
    sample: int | None = None,
    seed: int | None = None,
    criterion: str | None = None,
    position_only: bool = False,
    sites: Sequence[str | None] | None = None,
    estimate: ParamList = None,
    fix: ParamList = None,
    keep: Candidates = None,
    weights: Weights = None,
    orientation_error: str | None = None,
) -> Plan:
    """Which postures to measure: ``count`` of the ``candidates`` chosen to determine the
    parameters of ``estimate`` best, as ``kinecal plan`` chooses them.

    ``candidates``: ``(n, joints)`` readings (the frames of ``sites`` measured at each, full
    poses or positions only with ``position_only``) or :class:`Measurements` (their
    observations say what is measured; ``position_only`` reads their poses as positions);
    or ``sample`` postures drawn within the joint ranges with ``seed``. ``criterion``:
    ``"d"`` (log det, the default), ``"a"``, ``"i"`` (mean prediction variance over the
    candidates), ``"e"`` or ``"o1"``-``"o5"``. ``sites``: the frames measured at each
    posture (None or ``"ee"`` for the end effector, site names; default every site, or the
    end effector when the robot has none). ``keep``: postures already measured (readings or
    Measurements), always in the plan. ``weights`` and ``orientation_error`` as for
    :func:`calibrate`. ``seed`` also draws the random plans the result is compared with.
    """
    keywords = _Keywords(
        "plan",
        {
            "count": ("count", count),
            "sample": ("sample", sample),
            "seed": ("seed", seed),
            "criterion": ("criterion", criterion),
            "position_only": ("position_only", position_only or None),
            "sites": ("sites", None if sites is None else ",".join(s or "ee" for s in sites)),
            "estimate": ("estimate", _list(estimate)),
            "fix": ("fix", _list(fix)),
            "weights": ("residuals.weights", _pair("weights", weights, ("length", "angle"))),
            "orientation_error": ("residuals.orientation_error", orientation_error),
        },
    )
    with keywords as spec:
        fields = _native.plan(robot, spec, candidates=candidates, keep=keep)
    return Plan(fields)


class Simulation(NamedTuple):
    """The outcome of :func:`simulate`: the synthesized ``measurements`` (of the nominal
    robot's structure) and the ``truth``, the perturbed robot that gave them."""

    measurements: Measurements
    truth: Robot


def simulate(
    robot: Robot,
    postures: int | npt.ArrayLike,
    *,
    seed: int | None = None,
    perturb: Mapping[str, float] | None = None,
    perturb_std: Spec = None,
    noise: Spec = None,
    position_only: bool = False,
    camera: str | None = None,
    board: str | None = None,
    min_points: int | None = None,
) -> Simulation:
    """Synthesized measurements from a perturbed ("true") copy of ``robot``: the same as
    ``kinecal simulate`` (the same seed gives the same data).

    ``postures``: a number of postures drawn within the joint ranges with ``seed``, or
    ``(n, joints)`` readings. ``perturb``: additive changes by parameter (names, ids or
    lists, e.g. ``{"p3": 0.1, "joint2.offset": -0.5}``, file units). ``perturb_std``:
    random Gaussian changes to every parameter, ``{"length": L, "angle": A, "slope": F}``
    (any of them; F a fraction of each slope) or ``(L, A, F)``. ``noise``: Gaussian
    measurement noise, ``(length, angle)`` or a dict of any of ``length``, ``angle`` and
    ``pixel`` (pixels). ``position_only``: measure positions only (a laser tracker). The end
    effector and every site are measured at each posture.

    ``camera`` and ``board``: what that camera of the robot file sees of that board instead (as
    ``kinecal simulate --camera --board``): the pixels of every board point in front of the
    camera and inside its image, at the postures that see at least ``min_points`` of them
    (default 12): with a number of postures, drawn within the joint ranges until that many
    do; with readings, those of them that do. ``measurements.to_csv(robot)`` is the pixel
    file.
    """
    count = postures if isinstance(postures, (int, np.integer)) and not isinstance(
        postures, bool) else None
    keywords = _Keywords(
        "simulate",
        {
            "postures": ("postures", count),
            "seed": ("seed", seed),
            "perturb": ("perturb", perturb),
            "perturb_std": (
                "perturb_std", _pair("perturb_std", perturb_std, ("length", "angle", "slope"))
            ),
            "noise": ("noise", _pair("noise", noise, ("length", "angle"))),
            "position_only": ("position_only", position_only or None),
            "camera": ("camera", camera),
            "board": ("board", board),
            "min_points": ("min_points", min_points),
        },
    )
    with keywords as spec:
        measurements, truth = _native.simulate(
            robot, spec, postures=None if count is not None else postures
        )
    return Simulation(measurements, truth)


def _report_json(report: Calibration | Mapping[str, Any] | str | os.PathLike[str]) -> str:
    """A calibration report as JSON text: a :class:`Calibration`, the report as a dict, JSON
    text, or the path of a report file (``kinecal calibrate --report``)."""
    if isinstance(report, Calibration):
        return report.to_json()
    if isinstance(report, Mapping):
        return json.dumps(report)
    if isinstance(report, str) and "{" not in report and not os.path.isfile(report):
        raise KinecalError(
            f"report: {report[:80]!r} is neither a report file nor a report's JSON text"
        )
    if isinstance(report, os.PathLike) or (isinstance(report, str) and "{" not in report):
        with open(report, encoding="utf-8") as f:
            return f.read()
    if isinstance(report, str):
        return report
    raise TypeError(f"report: expected a Calibration, a dict, JSON text or a path, not {report!r}")


def _text(value: str | os.PathLike[str], keyword: str) -> tuple[str, str]:
    """``(text, name)`` of a CSV given as text (it has a line break) or as a path."""
    if isinstance(value, str) and "\n" not in value and not os.path.isfile(value):
        raise KinecalError(
            f"{keyword}: {value[:80]!r} is neither a file nor CSV text (CSV text has a header "
            "line and rows)"
        )
    if isinstance(value, os.PathLike) or (isinstance(value, str) and "\n" not in value):
        with open(value, encoding="utf-8") as f:
            return f.read(), os.fspath(value)
    if isinstance(value, str):
        return value, keyword
    raise TypeError(f"{keyword}: expected CSV text or a path, not {value!r}")


def predict(
    robot: Robot,
    report: Calibration | Mapping[str, Any] | str | os.PathLike[str],
    *,
    postures: npt.ArrayLike | None = None,
    targets: npt.ArrayLike | None = None,
    site: str | None = None,
) -> dict[str, Floats]:
    """The predicted accuracy of a calibrated ``robot`` (what ``kinecal predict`` writes),
    from its calibration ``report`` (a :class:`Calibration` made with ``predict=True``, the
    report as a dict or JSON text, or a report file's path).

    At ``postures`` (readings ``(n, joints)``) or at Cartesian ``targets`` (``(n, 3)``
    positions or ``(n, 6)`` poses with ZYX Euler angles, the robot's units and global frame,
    each reached through the calibrated robot's inverse kinematics; a target out of reach
    raises). ``site`` names the target frame (default: the report's). Returns arrays in the
    robot's units: ``readings``, ``position`` ``(n, 3)`` (where the calibrated model puts the
    target), ``distance`` (to the nearest measured posture), and ``position_parameters``,
    ``position_model`` (the RMS lengths of the two parts), ``position_bound95``,
    ``position_bound95_parameters``, and the same for ``attitude_`` when poses were
    measured."""
    return _native.predict(
        robot, _report_json(report), postures=postures, targets=targets, site=site
    )


class IsoLog(NamedTuple):
    """What :func:`iso9283_log` made: the log as CSV ``text`` (what ``kinecal iso9283 log``
    writes), the measured postures ``left_out`` (no role) and the sessions whose measurement
    frame was ``placed`` on the data first."""

    text: str
    left_out: list[str]
    placed: list[str]


def iso9283_log(
    robot: Robot,
    measurements: Measurements,
    roles: str | os.PathLike[str],
    *,
    length_unit: str | None = None,
) -> IsoLog:
    """An ISO 9283 log of ``measurements`` for the robot model ``robot`` (what ``kinecal
    iso9283 log`` writes): ``roles`` (CSV text or a path, ``posture,test,pose,cycle``) gives
    each posture its test, pose (``P1..P5``, ``C1..C8``) and cycle; the attained pose is the
    measurement in the base frame, the commanded pose the model's at the pose's mean
    readings."""
    text, name = _text(roles, "roles")
    log, left_out, placed = _native.iso9283_log(
        robot, measurements, text, roles_file=name, length_unit=length_unit
    )
    return IsoLog(log, list(left_out), list(placed))


def iso9283(
    log: str | os.PathLike[str],
    *,
    length_unit: str | None = None,
    angle_unit: str | None = None,
    robot: Robot | None = None,
    report: Calibration | Mapping[str, Any] | str | os.PathLike[str] | None = None,
    site: str | None = None,
) -> dict[str, Any]:
    """The ISO 9283 figures of a log (CSV text or a path), as the document ``kinecal iso9283
    evaluate --json`` writes (``poses``, ``distances``, ``summary`` for a log of several
    tests, ``warnings``). With ``robot`` and ``report`` (a calibrated robot and its
    calibration, made with ``predict=True``), each pose gets ``compensated``: the ``AP``
    predicted once the program is compensated."""
    text, name = _text(log, "log")
    if (robot is None) != (report is None):
        raise KinecalError("iso9283: give robot and report together")
    doc = _native.iso9283_evaluate(
        text,
        file=name,
        length_unit=length_unit,
        angle_unit=angle_unit,
        robot=robot,
        report_json=None if report is None else _report_json(report),
        site=site,
    )
    figures: dict[str, Any] = json.loads(doc)
    return figures


class Dataset(NamedTuple):
    """A published data set read as it is: the robot, the data, and the calibration its
    README suggests (keywords for :func:`calibrate`)."""

    robot: Robot
    identification: Measurements
    validation: Measurements | None
    suggested: dict[str, Any]


def datasets() -> list[tuple[str, str]]:
    """The published data sets kinecal reads as they are: ``(name, about)`` pairs."""
    return _native.datasets()


def dataset(name: str, folder: str | os.PathLike[str]) -> Dataset:
    """Reads a published data set's folder (e.g. ``dataset("qkm-hl6",
    "shared/data/qkm_hl6_faro")``)."""
    robot, ident, valid, suggested = _native.dataset(name, folder)
    kw: dict[str, Any] = json.loads(suggested)
    if "weights" in kw:
        kw["weights"] = tuple(kw["weights"])
    return Dataset(robot, ident, valid, kw)


# The history jobs (`kinecal.history.add`, ...): after the helpers they use.
from . import history
