"""Shared fixtures."""
from __future__ import annotations

import importlib.util
import os
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _this_checkouts_cli() -> None:
    """``kukaid_cli`` from this checkout's ``cli/``, here and in the subprocesses the tests start.
    An editable install maps it to the checkout it was made from: a git worktree's tests run with
    ``PYTHONPATH=<worktree>`` took ``kukaid`` from the worktree and ``kukaid_cli`` from the install's
    checkout (its CLI, not the one under test)."""
    spec = importlib.util.find_spec("kukaid_cli")
    if spec is not None and spec.origin and Path(spec.origin).resolve().parent == (ROOT / "cli").resolve():
        return
    where = ROOT / ".pytest_cache" / "kukaid_cli_path"      # ignored by git
    link = where / "kukaid_cli"
    if not link.is_symlink():
        where.mkdir(parents=True, exist_ok=True)
        link.symlink_to(ROOT / "cli", target_is_directory=True)
    sys.path.insert(0, str(where))
    os.environ["PYTHONPATH"] = os.pathsep.join([str(where), *filter(None, [os.environ.get("PYTHONPATH")])])
    sys.modules.pop("kukaid_cli", None)


_this_checkouts_cli()


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


@pytest.fixture(scope="session")
def robot_hidden_bench():
    """``benchmarks/diagnose_robot_hidden.py`` imported: its cases (the six-axis virtual KR C4 with one
    hidden effect) are what the robot diagnosis tests run."""
    spec = importlib.util.spec_from_file_location("diagnose_robot_hidden", ROOT / "benchmarks" / "diagnose_robot_hidden.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("diagnose_robot_hidden", mod)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="session")
def doc_pages(tmp_path_factory):
    """The shell examples of README.md and docs/*.md, each page run once per session
    (:class:`test_docs_examples.PageRuns`): test_docs_examples.py runs every page, test_fleet_docs.py
    reads docs/fleet.md's run (it ran the page again, 30 s)."""
    from test_docs_examples import PageRuns

    return PageRuns(tmp_path_factory.mktemp("doc_pages"))
