"""Type stubs of the kinecal package (robot kinematic calibration from numpy)."""

import os
from typing import Any, Dict, List, NamedTuple, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str

ArrayLike = npt.ArrayLike
PathLike = Union[str, os.PathLike[str]]
ParamList = Union[str, Sequence[str], None]

class KinecalError(ValueError):
    """Bad input or a calibration that cannot be made. ``file``, ``line`` and ``field`` locate
    the problem when it came from a file (else None)."""

    file: Optional[str]
    line: Optional[int]
    field: Optional[str]

class Robot:
    """A robot model (links, joints, sites, planes) in the units of its file."""

    @staticmethod
    def from_toml(source: Union[PathLike, str]) -> Robot:
        """A robot TOML file (a path) or TOML text (a string holding a newline or ``=``)."""
    @staticmethod
    def builtin(name: str) -> Robot:
        """A built-in robot: ``"ge-a4"`` (the GE A4 of the thesis)."""
    @staticmethod
    def from_urdf(path: PathLike, base: Optional[str] = None, tip: Optional[str] = None) -> Robot:
        """The chain from ``base`` (default: the root) to ``tip`` (default: the only leaf)."""
    @staticmethod
    def from_dh(
        table: Union[ArrayLike, PathLike],
        convention: str = "standard",
        length_unit: str = "m",
        angle_unit: str = "deg",
        kinds: Optional[Sequence[str]] = None,
        name: str = "dh",
    ) -> Robot:
        """An ``(n, 4)`` table of ``a, alpha, d, theta`` (or a DH CSV file);
        ``convention``: ``"standard"`` or ``"modified"``."""
    def to_toml(self) -> str:
        """The robot file's text (keeping the comments of the file it came from)."""
    def to_urdf(self, template: PathLike, base: Optional[str] = None, tip: Optional[str] = None) -> str:
        """The robot written into a URDF template's joint origins."""
    @property
    def name(self) -> str: ...
    @property
    def dof(self) -> int:
        """Number of joints."""
    @property
    def units(self) -> Tuple[str, str]:
        """``(length unit, angle unit)``, e.g. ``("mm", "deg")``."""
    @property
    def sites(self) -> List[str]: ...
    @property
    def parameter_names(self) -> List[str]:
        """``link1.x``, ..., ``joint1.offset``, ... in thesis order."""
    @property
    def parameter_ids(self) -> List[str]:
        """``p1``, ``p2``, ... in the same order."""
    @property
    def parameter_units(self) -> List[str]: ...
    @property
    def values(self) -> npt.NDArray[np.float64]:
        """Every parameter's value, file units, in the same order."""
    def get(self, name: str) -> float:
        """One parameter (name or id), file units."""
    def with_value(self, name: str, value: float) -> Robot:
        """A copy with one parameter set (file units)."""
    def fk(self, readings: ArrayLike, site: Optional[str] = None, matrix: bool = False) -> npt.NDArray[np.float64]:
        """Poses ``(n, 6)``: ``x, y, z, alpha, beta, gamma`` (ZYX Euler), or transforms
        ``(n, 4, 4)`` with ``matrix=True``; one posture given flat gives one row."""

class Measurements:
    """Postures and what was measured in them, with optional per-row standard deviations."""

    def __init__(
        self,
        robot: Robot,
        readings: ArrayLike,
        positions: ArrayLike,
        orientations: Optional[ArrayLike] = None,
        sites: Optional[Sequence[Optional[str]]] = None,
        sigma_position: Optional[ArrayLike] = None,
        sigma_angle: Optional[ArrayLike] = None,
        postures: Optional[Sequence[str]] = None,
    ) -> None:
        """``readings`` ``(n, joints)``; ``positions`` ``(n, 3)``; ``orientations`` ``(n, 3)``
        ZYX Euler angles for full poses; ``sites`` a site name (or None: the end effector)
        per row; sigmas ``(n,)``; ``postures`` a label per row (equal labels: one posture)."""
    @staticmethod
    def read_csv(
        path: PathLike,
        robot: Robot,
        columns: Optional[Sequence[str]] = None,
        length_unit: Optional[str] = None,
        angle_unit: Optional[str] = None,
        position_only: bool = False,
        session: Optional[str] = None,
    ) -> Measurements:
        """A measurement, distance or contact file (told by its header); ``columns`` maps
        another tool's measurement columns (``["v1=J1", "x=X", ...]``)."""
    def merge(self, other: Measurements) -> Measurements: ...
    def to_csv(self, robot: Robot) -> str: ...
    @property
    def readings(self) -> npt.NDArray[np.float64]:
        """``(postures, joints)``."""
    @property
    def postures(self) -> int: ...
    @property
    def residuals(self) -> int: ...
    @property
    def kinds(self) -> Dict[str, int]: ...
    def __len__(self) -> int: ...

class Calibration:
    """The outcome of :func:`calibrate`."""

    robot: Robot
    report: Dict[str, Any]
    @property
    def converged(self) -> bool: ...
    @property
    def iterations(self) -> int: ...
    @property
    def estimated(self) -> List[str]: ...
    @property
    def values(self) -> npt.NDArray[np.float64]: ...
    @property
    def estimates(self) -> Dict[str, float]: ...
    @property
    def sigmas(self) -> Dict[str, float]: ...
    @property
    def undetermined(self) -> List[str]: ...
    @property
    def combinations(self) -> List[Dict[str, Any]]: ...
    @property
    def identification(self) -> Dict[str, Any]: ...
    @property
    def validation(self) -> Optional[Dict[str, Any]]: ...
    @property
    def cross_validation(self) -> Optional[Dict[str, Any]]: ...
    @property
    def warnings(self) -> List[str]: ...
    def to_json(self) -> str: ...

Spec = Union[Dict[str, Any], str, "os.PathLike[str]"]

def calibrate(
    robot: Union[Robot, Spec],
    data: Optional[Measurements] = None,
    *,
    estimate: ParamList = None,
    fix: ParamList = None,
    method: str = "lm",
    loss: str = "squared",
    huber_scale: float = 1.345,
    weights: Union[None, Sequence[float], Dict[str, float]] = None,
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
    """The workflow of ``kinecal calibrate``, on arrays."""

def analyze(
    robot: Robot,
    data: Measurements,
    *,
    estimate: ParamList = "identifiable",
    fix: ParamList = None,
    weights: Union[None, Sequence[float], Dict[str, float]] = None,
    orientation_error: str = "rotvec",
    rcond: Optional[float] = None,
) -> Dict[str, Any]:
    """The document of ``kinecal analyze --json``, plus ``unseen``."""

class Dataset(NamedTuple):
    robot: Robot
    identification: Measurements
    validation: Optional[Measurements]
    suggested: Dict[str, Any]

def datasets() -> List[Tuple[str, str]]: ...
def dataset(name: str, folder: PathLike) -> Dataset: ...
