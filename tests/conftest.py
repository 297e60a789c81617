"""Shared fixtures."""
from __future__ import annotations

import sys

import pytest


@pytest.fixture(scope="session")
def kukaid_cmd() -> list[str]:
    """The ``kukaid`` command of the interpreter running the tests (the venv's, not whatever is on PATH)."""
    return [sys.executable, "-m", "kukaid_cli.main"]
