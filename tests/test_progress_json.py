"""Progress on every step that can take over 2 s, on a terminal only, and `--json` on every command
that produces figures (issue 25, 4): before, `excite fourier` was silent for 28 s, `fit --robot`
11 s, `report` 11 s and `diagnose` minutes, and fit, capture, excite and load had no --json."""
from __future__ import annotations

import json

import pytest
from click.testing import CliRunner

import kukaid_cli._util as util
from kukaid_cli.main import cli

FOURIER = ["excite", "fourier", "--harmonics", "2", "--period", "2", "--repeat", "1", "--iterations", "1"]


def _run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    """One-axis friction and inertia logs, a fit, and a short six-axis log of the virtual KR 6."""
    d = tmp_path_factory.mktemp("progress")
    for kind, extra in (("friction", ["--n-speeds", "4"]), ("inertia", [])):
        assert _run("excite", kind, *extra, "-o", d / f"{kind}.json").exit_code == 0
        assert _run("capture", d / f"{kind}.json", "-o", d / f"{kind}.h5").exit_code == 0
    r = _run("fit", "--friction", d / "friction.h5", "--inertia", d / "inertia.h5", "-o", d / "p.json")
    assert r.exit_code == 0, r.output
    assert _run(*FOURIER, "-o", d / "fourier.json").exit_code == 0
    assert _run("capture", d / "fourier.json", "-o", d / "fourier.h5").exit_code == 0
    return d


def _steps(d):
    return {
        "excite fourier": [*FOURIER, "-o", d / "f2.json", "--force"],
        "fit --robot": ["fit", d / "fourier.h5", "--robot", "kr6-r700-sixx", "-o", d / "robot.json"],
        "report": ["report", "--params", d / "p.json", "--friction", d / "friction.h5", "-o", d / "r.pdf"],
        "diagnose": ["diagnose", "--params", d / "p.json", "--log", d / "friction.h5", "--log", d / "inertia.h5",
                     "--max-steps", "1"],
    }


@pytest.mark.parametrize("step", ["excite fourier", "fit --robot", "report", "diagnose"])
def test_long_steps_show_progress_on_a_terminal_only(logs, step, monkeypatch):
    args = _steps(logs)[step]
    quiet = _run(*args)
    assert quiet.exit_code == 0, quiet.output
    assert "kukaid: " + step.split()[0] not in quiet.stderr.replace("kukaid: warning", "")  # a pipe: no progress
    monkeypatch.setattr(util, "on_terminal", lambda: True)
    shown = _run(*args)
    assert shown.exit_code == 0, shown.output
    lines = shown.stderr.splitlines()
    if step == "excite fourier":  # a bar, labelled
        assert any(line.startswith("excite fourier") for line in lines), shown.stderr
    else:  # stage lines with the time since the start
        stages = [line for line in lines if line.startswith(f"kukaid: {step.split()[0]}: ") and line.endswith(" s)")]
        assert len(stages) >= 2, shown.stderr


def test_fit_capture_excite_and_load_print_json(logs, tmp_path):
    r = _run("excite", "inertia", "-o", tmp_path / "i.json", "--krl", tmp_path / "krl", "--json")
    assert r.exit_code == 0, r.output
    e = json.loads(r.stdout)
    assert e["output"] == str(tmp_path / "i.json") and e["kind"] == "inertia" and e["axes"] == [3]
    assert e["samples"] > 100 and e["duration"] > 10 and e["krl"]["via_points"] > 0
    r = _run(*FOURIER, "-o", tmp_path / "f.json", "--json")
    assert r.exit_code == 0 and json.loads(r.stdout)["condition_number"] > 1, r.output
    r = _run("capture", tmp_path / "i.json", "-o", tmp_path / "i.h5", "--seed", "3", "--json")
    assert r.exit_code == 0, r.output
    c = json.loads(r.stdout)
    assert c["samples"] > 100 and c["seed"] == 3 and c["backend"] == "sim" and c["complete"] is True
    r = _run("load", tmp_path / "i.h5", "-o", tmp_path / "i.csv", "--json")
    assert r.exit_code == 0, r.output
    lo = json.loads(r.stdout)
    assert lo["samples"] == c["samples"] and lo["axes"] == [3] and lo["warnings"] == []
    r = _run("fit", tmp_path / "i.h5", "-o", tmp_path / "p.json", "--json")
    assert r.exit_code == 0, r.output
    f = json.loads(r.stdout)
    assert f["output"] == str(tmp_path / "p.json") and f["axis"] == 3 and f["inertial"]["Izz"] > 0
    assert {k: v for k, v in f.items() if k != "output"} == json.loads((tmp_path / "p.json").read_text())
    r = _run("fit", logs / "fourier.h5", "--robot", "kr6-r700-sixx", "-o", tmp_path / "robot.json", "--json")
    assert r.exit_code == 0, r.output
    assert json.loads(r.stdout)["schema"] == "kukaid.robot_params/1"
