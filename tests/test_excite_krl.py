"""KRL export: structure of the .src/.dat pair, point data in degrees, speeds within the limits."""
from __future__ import annotations

import math
import re

import numpy as np
import pytest

from kukaid.errors import KukaidError
from kukaid.excite import KINDS, AxisLimits, friction, generate, presliding
from kukaid.krc.krl import export_krl, krl_program

DEG = math.pi / 180


def _arrays(dat: str) -> dict[str, dict[int, str]]:
    out: dict[str, dict[int, str]] = {}
    for name, k, v in re.findall(r"^\s*(\w+)\[(\d+)\]\s*=\s*(.+)$", dat, flags=re.M):
        out.setdefault(name, {})[int(k)] = v.strip()
    return out


def _scalar(dat: str, name: str) -> str:
    m = re.search(rf"^\s*DECL \w+ {name}\s*=\s*(.+)$", dat, flags=re.M)
    assert m, name
    return m.group(1).strip()


def _check_structure(src: str, dat: str, name: str) -> int:
    code = [ln.split(";")[0].strip() for ln in src.splitlines()]
    code = [ln for ln in code if ln]
    assert code[0] == "&ACCESS RVP"
    defs = [ln for ln in code if re.match(r"^DEF\s", ln)]
    assert defs == [f"DEF {name}( )"]
    assert code[-1] == "END" and sum(ln == "END" for ln in code) == 1
    assert code.index(defs[0]) < code.index("END")
    for a, b in (("FOR", "ENDFOR"), ("IF", "ENDIF")):
        opens = sum(1 for ln in code if re.match(rf"^{a}\s", ln))
        closes = sum(1 for ln in code if ln == b)
        assert opens == closes > 0
    assert any(re.match(r"^PTP P$", ln) for ln in code) and any(ln == "PTP P C_PTP" for ln in code)
    dcode = [ln.split(";")[0].strip() for ln in dat.splitlines()]
    dcode = [ln for ln in dcode if ln]
    assert dcode[0] == "&ACCESS RVP"
    assert [ln for ln in dcode if ln.startswith("DEFDAT")] == [f"DEFDAT {name}"]
    assert dcode[-1] == "ENDDAT"
    n = int(_scalar(dat, "N_PTS"))
    arrays = _arrays(dat)
    for arr, typ in (("XP", "E6AXIS"), ("VEL_PCT", "INT"), ("OVR_PCT", "INT"), ("ACC_PCT", "INT"), ("WAIT_S", "REAL")):
        assert re.search(rf"^\s*DECL {typ} {arr}\[{n}\]$", dat, flags=re.M), arr
        assert sorted(arrays[arr]) == list(range(1, n + 1)), arr
    # every variable the program uses is declared in the .dat or the .src
    for var in ("N_PTS", "WAIT_START", "Q_START", "XP", "VEL_PCT", "OVR_PCT", "ACC_PCT", "WAIT_S"):
        assert re.search(rf"\b{var}\b", src)
    # KRL names: at most 24 characters
    assert len(name) <= 24
    _check_override(code, arrays["OVR_PCT"].values())
    return n


def _check_override(code: list[str], ovr_pct) -> None:
    """Trial 19: the program set $OV_PRO to its own values (up to 27 % with the operator's 10 % in T1) and
    left the last one in force. It now reads the operator's override first, scales its own by it (KRL's
    INT arithmetic, as below: never above the operator's) and gives it back at the end."""
    writes = [ln for ln in code if ln.startswith("$OV_PRO")]
    assert writes == ["$OV_PRO = OVR_SET", "$OV_PRO = OVR_USER"], writes
    assert code.index("OVR_USER = $OV_PRO") < code.index("$OV_PRO = OVR_SET")
    assert code[-2:] == ["$OV_PRO = OVR_USER", "END"]
    assert "OVR_SET = (OVR_PCT[I] * OVR_USER) / 100" in code and "IF (OVR_SET < 1) AND (OVR_USER > 0) THEN" in code
    for user in (0, 1, 10, 100):
        for pct in (int(v) for v in ovr_pct):
            ovr_set = (pct * user) // 100
            ovr_set = 1 if ovr_set < 1 and user > 0 else ovr_set
            assert ovr_set <= user


@pytest.mark.parametrize("kind", KINDS)
def test_krl_structure_for_every_kind(kind, tmp_path):
    tr = generate(kind)
    p_src, p_dat = export_krl(tr, tmp_path)
    name = f"kukaid_{kind}"
    assert p_src.name == f"{name}.src" and p_dat.name == f"{name}.dat"
    n = _check_structure(p_src.read_text(), p_dat.read_text(), name)
    assert 2 <= n <= 5000
    arrays = _arrays(p_dat.read_text())
    for arr in ("VEL_PCT", "OVR_PCT", "ACC_PCT"):
        vals = [int(v) for v in arrays[arr].values()]
        assert min(vals) >= 1 and max(vals) <= 100
    # the programmed speed never exceeds the limit
    lim = AxisLimits.kr6_r700_sixx(3)
    v = np.array([int(arrays["VEL_PCT"][k]) * int(arrays["OVR_PCT"][k]) / 1e4 * lim.qd_max for k in range(1, n + 1)])
    assert np.all(v <= lim.qd_max + 1e-12)


def test_krl_points_are_the_trajectory_in_degrees_within_tolerance():
    tr = friction(speeds=[0.05, 0.4], plateau=2.0)
    tol = 0.005
    src, dat, s = krl_program(tr, tol_deg=tol)
    xp = _arrays(dat)["XP"]
    q_deg = np.array([float(re.match(r"\{A3 ([-\d.]+)\}", xp[k]).group(1)) for k in sorted(xp)])
    assert q_deg.size == s["points"]
    # the points are trajectory samples, converted to degrees (5 decimals)
    idx = np.searchsorted(tr.t, np.array(s["time"]) - 1e-9)
    assert np.allclose(q_deg, tr.q[idx] / DEG, atol=1e-5)
    start = float(re.match(r"\{A3 ([-\d.]+)\}", _scalar(dat, "Q_START")).group(1))
    assert start == pytest.approx(tr.q[0] / DEG, abs=1e-5)
    assert q_deg.min() >= tr.q.min() / DEG - 1e-5 and q_deg.max() <= tr.q.max() / DEG + 1e-5
    # the straight pieces between via points stay within the tolerance of the trajectory
    bp = np.array(s["breakpoints"])
    assert set(idx) <= set(bp) and bp[0] == 0 and bp[-1] == tr.n_samples - 1
    tk, qk = tr.t[bp], tr.q[bp]
    assert np.max(np.abs(np.interp(tr.t, tk, qk) - tr.q)) / DEG <= tol + 1e-9
    # the plateau speeds are programmed right (integer percentages: within 2 %)
    arrays = _arrays(dat)
    lim = AxisLimits.kr6_r700_sixx(3)
    v = np.array([int(arrays["VEL_PCT"][k]) * int(arrays["OVR_PCT"][k]) / 1e4 * lim.qd_max for k in sorted(xp)])
    for want in (0.05, 0.4):
        assert np.min(np.abs(v / want - 1)) < 0.02
    # standstills are WAIT SEC of the settle time
    waits = np.array([float(arrays["WAIT_S"][k]) for k in sorted(xp)])
    assert np.sum(waits > 0.9) >= 4


def test_krl_presliding_keeps_the_micro_reversals():
    tr = presliding()
    src, dat, s = krl_program(tr)
    q = np.array(s["q_deg"])
    stop = tr.params["stop_q"] / DEG
    # the extremes of the reversals are via points
    for a in tr.params["reversals"]:
        assert np.min(np.abs(np.abs(q - stop) - a / DEG)) < 1e-5


@pytest.mark.parametrize("name", ["DEF", "end", "Ptp", "wait", "P", "xp", "N_PTS", "OVR_NOW", "BAS"])
def test_krl_refuses_a_keyword_or_a_name_the_program_uses(name):
    """New-user trial 17: --krl-name DEF (or P, the program's own pose variable) was accepted and the
    program began `DEF DEF( )`, which no KR C4 compiles; KRL ignores case."""
    with pytest.raises(KukaidError, match=f"'{name}' is a KRL keyword or a name the program uses"):
        krl_program(friction(speeds=[0.1], plateau=1.0), name=name)


def test_krl_refuses_bad_names_and_axes(tmp_path):
    tr = friction(speeds=[0.1], plateau=1.0)
    with pytest.raises(KukaidError, match="not a KRL name"):
        krl_program(tr, name="9lives")
    with pytest.raises(KukaidError, match="not a KRL name"):
        krl_program(tr, name="a" * 25)
    from kukaid.excite import Trajectory

    with pytest.raises(KukaidError, match="not a robot axis"):
        krl_program(Trajectory(t=tr.t, q=tr.q, axis=7, kind="custom"))
    with pytest.raises(KukaidError, match="via points exceed"):
        krl_program(generate("inertia"), tol_deg=1e-6, max_points=100)


from hypothesis import given, settings, strategies as st  # noqa: E402


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(-0.02, 0.02), min_size=3, max_size=300), st.floats(1e-4, 0.05))
def test_via_points_stay_within_tolerance(steps, tol_deg):
    """Any sampled path: the via points include both ends and the straight pieces stay within tol."""
    from kukaid.krc.krl import via_points

    q = np.concatenate([[0.0], np.cumsum(np.where(np.abs(steps) < 1e-3, 0.0, steps))])
    t = np.arange(q.size) * 0.012
    idx = via_points(t, q, tol_deg * DEG)
    assert idx[0] == 0 and idx[-1] == q.size - 1
    assert all(a < b for a, b in zip(idx, idx[1:]))
    assert np.max(np.abs(np.interp(t, t[idx], q[idx]) - q)) <= tol_deg * DEG + 1e-12


def test_excite_says_when_the_krl_runs_far_off_its_speed(tmp_path):
    """New-user trial 10: the pre-sliding KRL runs its reversals 1778 % too fast (speeds below 0.01 % of
    the maximum cannot be programmed); that was written only in the .dat's header comment."""
    import json

    from click.testing import CliRunner

    from kukaid_cli.main import cli

    r = CliRunner().invoke(cli, ["excite", "presliding", "-o", str(tmp_path / "p.json"), "--krl", str(tmp_path / "k"),
                                 "--json"])
    assert r.exit_code == 0, r.output
    assert json.loads(r.stdout)["krl"]["max_speed_error"] > 10
    assert "kukaid: warning: excite: the KRL program runs a piece of 0.5 s or more" in r.stderr
    assert "0.036 deg/s" in r.stderr
    r = CliRunner().invoke(cli, ["excite", "inertia", "-o", str(tmp_path / "i.json"), "--krl", str(tmp_path / "k")])
    assert r.exit_code == 0 and "warning" not in r.stderr, r.output
