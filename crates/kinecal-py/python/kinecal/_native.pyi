"""Type stubs of ``kinecal._native``, the compiled part of the kinecal package (pyo3).

The package (``kinecal/__init__.py``) re-exports ``Robot``, ``Measurements``,
``KinecalError``, ``ExportWarning`` and ``__version__`` and wraps the functions, which take
the package's keywords after normalising them (weights and settings as tuples) and return
tuples and dicts the package turns into its result classes.
"""

import os
from collections.abc import Sequence
from typing import Any, final

import numpy as np
import numpy.typing as npt
from typing_extensions import TypeAlias

__all__ = [
    "ExportWarning",
    "KinecalError",
    "Measurements",
    "Outcome",
    "Robot",
    "__version__",
    "analyze",
    "calibrate",
    "calibrate_job",
    "compensate",
    "dataset",
    "datasets",
    "iso9283_evaluate",
    "iso9283_log",
    "plan",
    "predict",
    "run",
    "simulate",
]

__version__: str

_PathLike: TypeAlias = str | os.PathLike[str]

class KinecalError(ValueError):
    """Bad input or a calibration that cannot be made. ``file``, ``line`` and ``field`` locate
    the problem when it came from a file (else None)."""

    file: str | None
    line: int | None
    field: str | None

class ExportWarning(UserWarning):
    """What a robot export cannot hold, with the deviation it leaves at the tool."""

@final
class Robot:
    """A robot model (links, joints, sites, planes) in the units of its file."""

    @staticmethod
    def from_toml(source: _PathLike | str) -> Robot:
        """A robot TOML file (a path) or TOML text (a string holding a newline or ``=``)."""
    @staticmethod
    def builtin(name: str) -> Robot:
        """A built-in robot: ``"ge-a4"`` (the GE A4 of the thesis)."""
    @staticmethod
    def from_urdf(
        path: _PathLike,
        base: str | None = None,
        tip: str | list[str] | None = None,
        masses: bool = False,
    ) -> Robot:
        """The chain from ``base`` (default: the root) to ``tip`` (default: the only leaf); a
        list of tips reads a tree (the last the end effector, the others sites);
        ``masses=True`` takes the links' ``<inertial>`` masses as a mass model."""
    @staticmethod
    def from_dh(
        table: npt.ArrayLike | _PathLike,
        convention: str | None = None,
        length_unit: str | None = None,
        angle_unit: str | None = None,
        kinds: Sequence[str] | None = None,
        name: str | None = None,
    ) -> Robot:
        """An ``(n, 4)`` table of ``a, alpha, d, theta`` (``(n, 5)`` with ``beta``; metres and
        degrees unless given), or a DH CSV file in the units and convention it states;
        ``convention``: ``"standard"`` (default for arrays) or ``"modified"``; ``name``: the
        robot's (default: a file's name without its extension, ``"dh"`` for an array)."""
    def to_toml(self) -> str:
        """The robot file's text (keeping the comments of the file it came from)."""
    def to_urdf(
        self,
        template: _PathLike,
        base: str | None = None,
        tip: str | list[str] | None = None,
        tolerance: tuple[float, float] | None = None,
    ) -> str:
        """The robot written into a URDF template's joint origins (``kinecal export urdf``),
        read back first: beyond ``tolerance`` (length, angle) a ``KinecalError``; what URDF
        cannot express is an ``ExportWarning``."""
    def to_ros(
        self,
        template: _PathLike,
        base: str | None = None,
        tip: str | list[str] | None = None,
        measurement_frame: str | None = None,
        tolerance: tuple[float, float] | None = None,
    ) -> dict[str, str]:
        """The files ``kinecal export ros`` writes, by name: the calibration YAML, the template
        as a xacro that reads it, the static transforms and their launch file; read back
        first: beyond ``tolerance`` (length, angle) a ``KinecalError``; what URDF cannot
        express is an ``ExportWarning``."""
    def to_dh(
        self,
        convention: str = "standard",
        length_unit: str | None = None,
        angle_unit: str | None = None,
        tolerance: tuple[float, float] | None = None,
    ) -> str:
        """A DH table stating its units (``kinecal export dh``), read back first: beyond
        ``tolerance`` (length, angle) a ``KinecalError``; what DH cannot hold is an
        ``ExportWarning`` with its deviation."""
    def to_ur(self, template: _PathLike, tolerance: tuple[float, float] | None = None) -> str:
        """The Universal Robots kinematics file ``template`` rewritten (``kinecal export
        ur``), read back first; what it leaves out, cannot hold, and the TCP to enter are
        ``ExportWarning``s."""
    def to_camera_info(self, camera: str | None = None) -> str:
        """A camera's lens as ROS's ``camera_info`` YAML (``kinecal export camera-info``)."""
    def with_camera_info(
        self, source: str | os.PathLike[str], camera: str | None = None
    ) -> Robot:
        """A copy with a camera's lens from a ROS ``camera_info`` YAML file or text."""
    @property
    def cameras(self) -> list[dict[str, Any]]:
        """The cameras: name, mount, pose, fx, fy, cx, cy, distortion, width, height."""
    @property
    def boards(self) -> list[dict[str, Any]]:
        """The boards: name, mount, pose, cols, rows, spacing."""
    def to_joints(self, nominal: Robot, tolerance: tuple[float, float] | None = None) -> str:
        """The joint offsets and slopes and their change from ``nominal`` as CSV (``kinecal
        export joints``), applied to ``nominal`` and compared first; what the table cannot carry
        is an ``ExportWarning`` (beyond ``tolerance``, a ``KinecalError``)."""
    @property
    def name(self) -> str: ...
    @property
    def dof(self) -> int:
        """Number of joints."""
    @property
    def units(self) -> tuple[str, str]:
        """``(length unit, angle unit)``, e.g. ``("mm", "deg")``."""
    @property
    def sites(self) -> list[str]: ...
    @property
    def parameter_names(self) -> list[str]:
        """``link1.x``, ..., ``joint1.offset``, ... in thesis order."""
    @property
    def parameter_ids(self) -> list[str]:
        """``p1``, ``p2``, ... in the same order."""
    @property
    def parameter_units(self) -> list[str]: ...
    @property
    def values(self) -> npt.NDArray[np.float64]:
        """Every parameter's value, file units, in the same order."""
    def get(self, name: str) -> float:
        """One parameter (name or id), file units."""
    def with_value(self, name: str, value: float) -> Robot:
        """A copy with one parameter set (file units)."""
    def fk(
        self, readings: npt.ArrayLike, site: str | None = None, matrix: bool = False
    ) -> npt.NDArray[np.float64]:
        """Poses ``(n, 6)``: ``x, y, z, alpha, beta, gamma`` (ZYX Euler), or transforms
        ``(n, 4, 4)`` with ``matrix=True``; one posture given flat gives one row."""

@final
class Measurements:
    """Postures and what was measured in them, with optional per-row standard deviations."""

    def __new__(
        cls,
        robot: Robot,
        readings: npt.ArrayLike,
        positions: npt.ArrayLike,
        orientations: npt.ArrayLike | None = None,
        sites: Sequence[str | None] | None = None,
        sigma_position: npt.ArrayLike | None = None,
        sigma_angle: npt.ArrayLike | None = None,
        postures: Sequence[str] | None = None,
    ) -> Measurements:
        """``readings`` ``(n, joints)``; ``positions`` ``(n, 3)``; ``orientations`` ``(n, 3)``
        ZYX Euler angles for full poses; ``sites`` a site name (or None: the end effector)
        per row; sigmas ``(n,)``; ``postures`` a label per row (equal labels: one posture)."""
    @staticmethod
    def read_csv(
        path: _PathLike,
        robot: Robot,
        columns: Sequence[str] | None = None,
        length_unit: str | None = None,
        angle_unit: str | None = None,
        position_only: bool = False,
        session: str | None = None,
    ) -> Measurements:
        """A measurement, distance or contact file (told by its header); ``columns`` maps
        another tool's measurement columns (``["v1=J1", "x=X", ...]``)."""
    def merge(self, other: Measurements) -> Measurements: ...
    def to_csv(self, robot: Robot) -> str:
        """The CSV text of kinecal's file for the observations' kind (a measurement, distance
        or contact file), read back by ``read_csv`` to the same numbers; observations of two
        of these kinds are refused."""
    @property
    def readings(self) -> npt.NDArray[np.float64]:
        """``(postures, joints)``."""
    @property
    def postures(self) -> int: ...
    @property
    def residuals(self) -> int:
        """Number of residual rows."""
    @property
    def kinds(self) -> dict[str, int]: ...
    def __len__(self) -> int: ...

def run(spec: str, form: str) -> tuple[str, str, list[tuple[str, str]], str]:
    """Runs a spec (``form``: ``path``, ``toml`` or ``json``): the job's kind, its document as
    JSON text, what it said (``(note|warning, text)``) and its status."""

@final
class Outcome:
    """A calibration's outcome, kept whole: its report and arrays made when asked for."""

    def report_json(self) -> str:
        """The report as JSON text (what ``kinecal calibrate --report`` writes)."""
    def covariance(self) -> npt.NDArray[np.float64] | None:
        """The covariance of the estimated parameters in the report's order (file units), or
        None when the uncertainty could not be computed."""
    def residuals(self) -> npt.NDArray[np.float64]:
        """The identification data's residuals, ``model - measured`` per row (file units)."""
    def residual_rows(self) -> list[tuple[str, str, str, str, float]]:
        """``(posture, kind, target, row, sigma)`` per residual row, sigma in file units."""

def calibrate_job(
    spec: str, form: str
) -> tuple[Robot, Outcome, list[tuple[str, str]]]:
    """Runs a calibration spec, its outputs written: the calibrated robot, the outcome and what
    it said."""

def calibrate(
    robot: Robot,
    data: Measurements,
    spec: str,
    validate: Measurements | None = None,
    initial: Robot | None = None,
) -> tuple[Robot, Outcome]:
    """The calibrated robot and the outcome (its report and arrays made when read)."""

def analyze(robot: Robot, data: Measurements, spec: str) -> str:
    """The document of ``kinecal analyze --json`` as JSON text, plus ``unseen``."""

def compensate(
    calibrated: Robot,
    nominal: Robot,
    spec: str,
    *,
    program: npt.ArrayLike | None = None,
    targets: npt.ArrayLike | None = None,
    seeds: npt.ArrayLike | None = None,
) -> dict[str, Any]:
    """The fields of a :class:`kinecal.Compensation`."""

def plan(
    robot: Robot,
    spec: str,
    candidates: npt.ArrayLike | Measurements | None = None,
    keep: npt.ArrayLike | Measurements | None = None,
) -> dict[str, Any]:
    """The fields of a :class:`kinecal.Plan`."""

def simulate(
    robot: Robot, spec: str, postures: npt.ArrayLike | None = None
) -> tuple[Measurements, Robot]:
    """The measurements and the true robot."""

def datasets() -> list[tuple[str, str]]:
    """``(name, about)`` of each data set kinecal reads as published."""

def dataset(
    name: str, folder: _PathLike
) -> tuple[Robot, Measurements, Measurements | None, str]:
    """The robot, identification and validation data, and the suggested calibration as
    JSON text (``calibrate`` keywords)."""

def predict(
    robot: Robot,
    report_json: str,
    *,
    postures: npt.ArrayLike | None = None,
    targets: npt.ArrayLike | None = None,
    site: str | None = None,
) -> dict[str, npt.NDArray[np.float64]]:
    """The arrays of ``kinecal.predict``."""

def iso9283_log(
    robot: Robot,
    measurements: Measurements,
    roles: str,
    *,
    roles_file: str = "roles",
    length_unit: str | None = None,
) -> tuple[str, list[str], list[str]]:
    """``(log CSV, postures left out, sessions placed)``."""

def iso9283_evaluate(
    log: str,
    *,
    file: str = "log",
    length_unit: str | None = None,
    angle_unit: str | None = None,
    robot: Robot | None = None,
    report_json: str | None = None,
    site: str | None = None,
) -> str:
    """The ISO 9283 document as JSON text."""
