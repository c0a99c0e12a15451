"""Shared by the Python tests: the ``kinecal`` command of this checkout, and the summary line of
the real-data tests skipped for want of ../shared/data (see ``shared_data`` in
test_kinecal.py)."""

import os
import subprocess
from typing import Any

import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", ".."))

SKIP_REASON = "needs ../shared/data"


def pytest_terminal_summary(terminalreporter: Any) -> None:
    skipped = terminalreporter.stats.get("skipped", [])
    n = 0
    for report in skipped:
        longrepr = report.longrepr
        reason = longrepr[2] if isinstance(longrepr, tuple) else str(longrepr)
        if SKIP_REASON in reason:
            n += 1
    if n:
        terminalreporter.write_line(
            f"skipped: {n} tests need ../shared/data (clone it beside the repository or set "
            "KINECAL_SHARED_DATA; with CI set they fail)"
        )


@pytest.fixture(scope="session")
def cli() -> str:
    """The kinecal command of this checkout (``$KINECAL_BIN``, or built here)."""
    path = os.environ.get("KINECAL_BIN")
    if not path:
        subprocess.run(["cargo", "build", "-q", "-p", "kinecal-cli"], cwd=ROOT, check=True)
        path = os.path.join(ROOT, "target", "debug", "kinecal")
    return path
