"""The history of calibrations: record each calibration and maintenance event of a robot, read
them back, and watch the quantities the data determines drift, one robot or a whole fleet.

Each function is a spelling of a ``history-*`` job of the library's door, the job
``kinecal history <command> --spec`` runs (``kinecal.run({"job": "history-drift", ...})`` runs
the same); each returns that job's document, as ``kinecal history <command> --json`` prints it.
``db`` is a SQLite file or a ``postgres://USER@HOST/DBNAME`` URL (the password from
``PGPASSWORD`` or ``~/.pgpass``); without it, ``$KINECAL_DB``, else ``kinecal/history.sqlite``
in the user's data folder. Times are RFC 3339 or ``YYYY-MM-DD`` (UTC).

A bad value raises :class:`kinecal.KinecalError` naming the keyword; the store's errors (a
database of a newer kinecal, a calibration of another robot model) name the database.
"""

from __future__ import annotations

import builtins
import json
import os
from collections.abc import Mapping, Sequence
from typing import Any, Literal, Union

from . import _Keywords, _native, _warn

__all__ = [
    "add",
    "drift",
    "event",
    "events",
    "export",
    "fleet",
    "import_dump",
    "init",
    "list",
    "plot",
    "show",
]

Path = Union[str, "os.PathLike[str]"]


def _run(job: str, given: Mapping[str, Any]) -> Any:
    """Runs the history job ``job`` of the keywords ``given`` (each at its spec key)."""
    with _Keywords(job, {k: (k, v) for k, v in given.items()}) as spec:
        _kind, document, messages, _status = _native.run(spec, "keywords")
    _warn(messages)
    return json.loads(document)


def add(
    robot_id: str,
    report: Path,
    *,
    db: Path | None = None,
    at: str | None = None,
    note: str | None = None,
    force: bool = False,
) -> dict[str, Any]:
    """Records the calibration report ``report`` (``kinecal calibrate --report``, or
    :meth:`kinecal.Calibration.report` written to a file) as a calibration of ``robot_id``,
    at ``at`` (default now). The same calibration twice is recorded once. A report of another
    robot model than the serial's earlier records is refused unless ``force`` (the forced record
    then starts a new segment: drift never compares two models). A report that says its
    calibration was refused (its ``refused`` field) is not recorded, nor a serial with white
    space at its start or end; a refused add creates no history file. Returns
    ``{"history", "robot_id", "id", "new"}``."""
    return dict(
        _run(
            "history-add",
            {"robot_id": robot_id, "report": report, "db": db, "at": at, "note": note,
             "force": force},
        )
    )


def list(
    robot_id: str | None = None, *, db: Path | None = None
) -> builtins.list[dict[str, Any]]:
    """The recorded calibrations of ``robot_id`` (every robot's when None), oldest first: each
    with its time, method, RMS errors, parameters and determined combinations."""
    return builtins.list(_run("history-list", {"robot_id": robot_id, "db": db}))


def show(
    robot_id: str | None = None, *, id: int | None = None, db: Path | None = None
) -> dict[str, Any]:
    """One calibration: ``id``, else the latest of ``robot_id``."""
    return dict(_run("history-show", {"robot_id": robot_id, "id": id, "db": db}))


def export(
    *,
    db: Path | None = None,
    robot_id: str | None = None,
    format: Literal["csv", "json", "dump"] = "csv",
    out: Path | None = None,
) -> dict[str, Any]:
    """The history as CSV (a row per calibration and parameter), JSON, or a lossless dump
    (every stored field, for :func:`import_dump`; the whole history). Written to ``out``, or
    returned as ``{"format", "text"}``. A ``robot_id`` with nothing recorded raises, as
    :func:`list` does."""
    return dict(
        _run("history-export", {"db": db, "robot_id": robot_id, "format": format, "out": out})
    )


def drift(
    robot_id: str,
    *,
    db: Path | None = None,
    baseline: str | int = "first",
    sigma: float = 3.0,
    tolerance: Path | None = None,
) -> dict[str, Any]:
    """The determined quantities of ``robot_id`` that changed since ``baseline`` (``"first"``
    of the segment since its latest maintenance event, ``"latest-ok"``, or a calibration's id):
    each with its change, sigma, significance and trend; ``flags`` lists those beyond ``sigma``
    standard deviations or their tolerance (``tolerance``: a TOML file of ``key = value``).
    With one calibration (or ``baseline`` naming the latest) nothing is compared:
    ``nothing_to_compare`` says why, and ``quantities`` is empty."""
    return dict(
        _run(
            "history-drift",
            {"robot_id": robot_id, "db": db, "baseline": baseline, "sigma": sigma,
             "tolerance": tolerance},
        )
    )


def plot(
    robot_id: str,
    out: Path,
    *,
    db: Path | None = None,
    param: Sequence[str] | None = None,
    tolerance: Path | None = None,
) -> dict[str, Any]:
    """Draws each tracked quantity of ``robot_id`` over time (``param``: only these) to
    ``out`` (``.svg`` or ``.png``), with sigma bars, the first value's 3-sigma band, tolerances
    and maintenance events: the whole history of its latest robot model, every segment (a robot
    serviced after its latest calibration is drawn too, with a warning to calibrate it).
    Returns ``{"written", "quantities"}``."""
    return dict(
        _run(
            "history-plot",
            {"robot_id": robot_id, "out": out, "db": db,
             "param": builtins.list(param) if param is not None else None,
             "tolerance": tolerance},
        )
    )


def fleet(
    *,
    db: Path | None = None,
    sigma: float = 3.0,
    tolerance: Path | None = None,
    horizon: float = 90.0,
    now: str | None = None,
    json: Path | None = None,
    html: Path | None = None,
) -> dict[str, Any]:
    """Every robot's state, most urgent first: flagged, serviced, due (a trend crosses a
    tolerance within ``horizon`` days of ``now``, at most 36500), ok or single. Also written as
    JSON to ``json`` and as a page to ``html`` when given."""
    return dict(
        _run(
            "history-fleet",
            {"db": db, "sigma": sigma, "tolerance": tolerance, "horizon": horizon, "now": now,
             "json": json, "html": html},
        )
    )


def event(
    robot_id: str, note: str, *, db: Path | None = None, at: str | None = None
) -> dict[str, Any]:
    """Records a maintenance event of ``robot_id`` (``note``: what was done) at ``at``
    (default now): the calibrations from then on start a new segment, within which drift is
    computed. Returns ``{"history", "event", "new"}``."""
    return dict(_run("history-event", {"robot_id": robot_id, "note": note, "db": db, "at": at}))


def events(
    robot_id: str | None = None, *, db: Path | None = None
) -> builtins.list[dict[str, Any]]:
    """The maintenance events of ``robot_id`` (every robot's when None)."""
    return builtins.list(_run("history-events", {"robot_id": robot_id, "db": db}))


def import_dump(dump: Path, *, db: Path | None = None) -> dict[str, Any]:
    """Reads a dump (:func:`export` with ``format="dump"``) into the history: every record
    and event verbatim, what is already there skipped. Every record is checked first (units,
    sigmas, times, serials, ...): a damaged dump raises naming the record and field, and
    nothing is written (no history file is created). Returns the counts."""
    return dict(_run("history-import", {"dump": dump, "db": db}))


def init(*, db: Path | None = None) -> dict[str, Any]:
    """Creates the history's schema, or migrates it to this kinecal's version (on a server,
    as the database's owner). Returns ``{"history", "backend", "schema_version"}``."""
    return dict(_run("history-init", {"db": db}))
