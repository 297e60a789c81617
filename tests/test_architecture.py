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


def test_architecture_page_names_every_module():
    """docs/architecture.md has one line per module: a module added or removed must be listed there."""
    section = (ROOT / "docs" / "architecture.md").read_text()
    modules = sorted(p.relative_to(ROOT).as_posix() for p in list((ROOT / "kukaid").rglob("*.py")) + list((ROOT / "cli").rglob("*.py"))
                     if p.name != "__init__.py")
    listed = {line.split("`")[1] for line in section.splitlines() if line.startswith("| `")}
    assert [m for m in modules if m not in listed] == []
    assert sorted(m for m in listed if m not in modules) == []
