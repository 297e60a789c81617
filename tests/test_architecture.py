"""The package architecture (pyproject's import-linter contracts): layers, no import circles, sockets in krc only."""
from __future__ import annotations

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_import_contracts_hold(capsys):
    cli = pytest.importorskip("importlinter.cli")
    code = cli.lint_imports(config_filename=str(ROOT / "pyproject.toml"), no_cache=True)
    out = capsys.readouterr().out
    assert code == 0, out
    assert "0 broken" in out


def test_only_krc_opens_sockets():
    """A plain scan beside the contract: no module outside kukaid/krc names the socket module."""
    offenders = [str(p.relative_to(ROOT)) for p in list((ROOT / "kukaid").rglob("*.py")) + list((ROOT / "cli").rglob("*.py"))
                 if "krc" not in p.parts and ("import socket" in p.read_text() or "from socket" in p.read_text())]
    assert offenders == []
