"""`kukaid excite` on the command line: outputs, options, refusals without output."""
from __future__ import annotations

import json
import math

import pytest
from click.testing import CliRunner

from kukaid_cli.main import cli

DEG = math.pi / 180


def run(*args):
    r = CliRunner().invoke(cli, list(args))
    return r.exit_code, r.output


def test_excite_writes_json_and_krl(tmp_path):
    out = tmp_path / "f.json"
    code, text = run("excite", "friction", "-o", str(out), "--krl", str(tmp_path / "krl"),
                     "--speeds", "0.02,0.2", "--plateau", "1.5", "--centre-deg", "10")
    assert code == 0, text
    d = json.loads(out.read_text())
    assert d["schema"] == "kukaid.trajectory/1" and d["kind"] == "friction"
    assert d["params"]["speeds"] == [0.02, 0.2]
    assert d["params"]["centre"] == pytest.approx(10 * DEG)
    assert (tmp_path / "krl" / "kukaid_friction.src").exists()
    assert (tmp_path / "krl" / "kukaid_friction.dat").exists()


def test_excite_every_kind_with_its_options(tmp_path):
    cases = {
        "inertia": ["--period", "3", "--n-periods", "3", "--amplitude-deg", "20"],
        "presliding": ["--step-deg", "0.8", "--reversals-deg", "0.02,0.01", "--direction", "-1"],
        "validation": ["--sine-time", "10", "--ramp", "2", "--moves-deg", "10,-5", "--move-speeds", "0.3,0.1"],
    }
    for kind, opts in cases.items():
        out = tmp_path / f"{kind}.json"
        code, text = run("excite", kind, "-o", str(out), *opts)
        assert code == 0, text
        assert json.loads(out.read_text())["kind"] == kind


def test_excite_refuses_a_limit_breaking_trajectory_and_writes_nothing(tmp_path):
    out = tmp_path / "f.json"
    krl = tmp_path / "krl"
    code, text = run("excite", "friction", "-o", str(out), "--krl", str(krl), "--speeds", "1.0",
                     "--qd-max-deg", "30")
    assert code != 0
    assert "kukaid: error: trajectory breaks the velocity limit of A3" in text
    assert "30 deg/s" in text
    assert not out.exists() and not krl.exists()
    assert list(tmp_path.iterdir()) == []


def test_excite_limits_from_json(tmp_path):
    lim = tmp_path / "lim.json"
    lim.write_text(json.dumps({"q_max_deg": 40.0}))
    out = tmp_path / "i.json"
    code, text = run("excite", "inertia", "-o", str(out), "--limits", str(lim), "--centre-deg", "18")
    assert code != 0 and "position limit of A3" in text and "40 deg" in text
    assert not out.exists()
    code, text = run("excite", "inertia", "-o", str(out), "--limits", str(lim), "--amplitude-deg", "10")
    assert code == 0, text
    assert json.loads(out.read_text())["limits"]["q_max"] == pytest.approx(40 * DEG)


def test_excite_option_for_another_kind_is_refused(tmp_path):
    code, text = run("excite", "inertia", "-o", str(tmp_path / "x.json"), "--speeds", "0.1")
    assert code != 0 and "--speeds does not apply to 'inertia'" in text
    code, text = run("excite", "friction", "-o", str(tmp_path / "x.json"), "--speeds", "0.1,abc")
    assert code != 0 and "not a comma-separated list" in text
    assert not (tmp_path / "x.json").exists()


def test_moves_without_their_speeds_say_which_option_is_missing(tmp_path):
    """New-user trial 10: `excite validation --moves-deg 10,20` said "option --move-speeds: need one speed per
    move (2), got 6", about speeds the user never gave (the default moves' six)."""
    code, text = run("excite", "validation", "-o", str(tmp_path / "v.json"), "--moves-deg", "10,20")
    assert code == 2 and "--moves-deg gives 2 move(s): give --move-speeds too" in text and "got 6" not in text
    assert not (tmp_path / "v.json").exists()
    code, text = run("excite", "validation", "-o", str(tmp_path / "v.json"), "--moves-deg", "10,20",
                     "--move-speeds", "0.1,0.2")
    assert code == 0, text


@pytest.mark.parametrize("kind, option", [("friction", "--span-deg [90]"), ("inertia", "--amplitude-deg [45.8]")])
def test_a_broken_position_limit_names_what_sets_the_motions_size(tmp_path, kind, option):
    """New-user trial 10: `excite friction --q-min-deg 0 --q-max-deg 30` said only that q = 60 deg breaks
    the 30 deg limit: the default span (90 deg) was not named."""
    code, text = run("excite", kind, "-o", str(tmp_path / "x.json"), "--q-min-deg", "0", "--q-max-deg", "30")
    assert code == 1 and "breaks the position limit of A3" in text
    assert f"the motion's size is {option}, its place --centre-deg" in text
    assert list(tmp_path.iterdir()) == []


def test_presliding_reversals_beyond_the_limit_name_their_option(tmp_path):
    """New-user trial 22: `excite presliding --reversals-deg 500` broke the position limit and the hint named
    only --step-deg [1], an option the user had not touched."""
    code, text = run("excite", "presliding", "-o", str(tmp_path / "p.json"), "--reversals-deg", "500")
    assert code == 1 and "breaks the position limit of A3" in text
    assert "the motion's size is --step-deg [1] and --reversals-deg [0.03,...], its place --centre-deg" in text
    assert list(tmp_path.iterdir()) == []
