"""Shared fixtures."""
from __future__ import annotations

import sys

import pytest


@pytest.fixture(scope="session")
def kukaid_cmd() -> list[str]:
    """The ``kukaid`` command of the interpreter running the tests (the venv's, not whatever is on PATH)."""
    return [sys.executable, "-m", "kukaid_cli.main"]



def pytest_terminal_summary(terminalreporter) -> None:
    """Say, also under -q, when the real datasets were not found: the tests that need them skip."""
    from shared_data import SHARED

    missing = [d for d in ("emps", "lwr4") if not (SHARED / "datasets" / d).is_dir()]
    if missing:
        n = len(terminalreporter.stats.get("skipped", []))
        terminalreporter.write_line(f"kukaid: {SHARED / 'datasets'} has no {' or '.join(missing)}: the tests and docs "
                                    f"examples that need the real datasets were skipped ({n} skips in all); put them "
                                    "there or set KUKAID_SHARED", yellow=True)
