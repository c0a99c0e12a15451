"""The summary line of the real-data tests skipped for want of ../shared/data (see
``shared_data`` in test_kinecal.py)."""

from typing import Any

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
