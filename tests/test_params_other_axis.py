"""A parameter file of another axis or another kind of joint is refused by every command that
takes one, with the one line `report` gives (issue 25, 1): before, `validate --axis 4` scored a
model of A2 on A4 and `diagnose --axis 4 -o` wrote a "refined" file still saying A2."""
from __future__ import annotations

import json

import pytest
from click.testing import CliRunner

from kukaid.logs import write_hdf5
from kukaid_cli.main import cli
from test_validate import sine_log


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("other_axis")
    write_hdf5(sine_log(1, 0.25, axes=(2, 4)), d / "log.h5")
    r = CliRunner().invoke(cli, ["fit", str(d / "log.h5"), "--axis", "2", "--friction-model", "coulomb-viscous",
                                 "-o", str(d / "a2.json")])
    assert r.exit_code == 0, r.output
    p = json.loads((d / "a2.json").read_text())
    p["provenance"]["joint"] = "prismatic"
    (d / "slide.json").write_text(json.dumps(p))
    return d


def _commands(d, params, axis, out):
    log = str(d / "log.h5")
    return {"validate": ["validate", "--params", str(params), log, *axis],
            "diagnose": ["diagnose", "--params", str(params), "--log", log, *axis, "-o", str(out / "out.json")],
            "report": ["report", "--params", str(params), "--log", log, *axis, "-o", str(out / "out.pdf")],
            "run-admittance": ["run-admittance", "--params", str(params), *axis, "--duration", "1",
                               "-o", str(out / "run.h5")]}


@pytest.mark.parametrize("command", ["validate", "diagnose", "report"])
@pytest.mark.parametrize("kind", ["axis", "joint"])
def test_a_file_of_another_axis_or_kind_is_refused_alike(files, command, kind, tmp_path):
    params = files / ("a2.json" if kind == "axis" else "slide.json")
    axis = ["--axis", "4"] if kind == "axis" else ["--axis", "2"]
    r = CliRunner().invoke(cli, _commands(files, params, axis, tmp_path)[command])
    assert r.exit_code == (2 if kind == "axis" else 1), r.output     # --axis is an option: a usage error
    want = (f"kukaid: error: {params}: the parameters are of axis A2, not A4 (--axis 4)" if kind == "axis" else
            f"kukaid: error: {params}: the parameters are of a prismatic axis (A2, positions in m, forces in N), "
            "not of a revolute one")
    assert r.stderr.strip().splitlines() == [want]
    assert list(tmp_path.iterdir()) == []


def test_the_files_own_axis_still_works(files):
    r = CliRunner().invoke(cli, ["validate", "--params", str(files / "a2.json"), str(files / "log.h5"), "--axis", "2"])
    assert r.exit_code == 0, r.output


@pytest.mark.parametrize("command", ["validate", "diagnose", "report", "run-admittance"])
def test_an_axis_the_file_does_not_model_or_out_of_range_is_one_usage_error(files, command, tmp_path):
    """--axis named each command's way (run-admittance: the virtual KR C4's axis; validate of a robot
    file: exit 1) and a one-axis file took any number (new-user trial 6): now one line, exit 2."""
    r = CliRunner().invoke(cli, _commands(files, files / "a2.json", ["--axis", "4"], tmp_path)[command])
    assert r.exit_code == 2 and r.stderr.strip().splitlines() == [
        f"kukaid: error: {files / 'a2.json'}: the parameters are of axis A2, not A4 (--axis 4)"], r.output
    for bad in ("0", "13", "x"):  # new-user trial 7: 'x' was "not a valid integer range"
        r = CliRunner().invoke(cli, _commands(files, files / "a2.json", ["--axis", bad], tmp_path)[command])
        assert r.exit_code == 2 and r.stderr == (f"kukaid: error: {command}: Invalid value for '--axis': '{bad}' is "
                                                 "not an axis number: give 1 to 12 (the KUKA axis, as 3)\n"), r.output
    assert list(tmp_path.iterdir()) == []
