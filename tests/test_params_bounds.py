"""Physically absurd parameter values are refused when a parameter file is read, with one line
naming the file and the field; values at the ceilings no real KUKA axis reaches still evaluate
without a numpy RuntimeWarning on stderr (validate, report, diagnose)."""
from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest

from kukaid.errors import ParamFileError
from kukaid.logs import AxisLog, write_hdf5
from kukaid.params import load_params
from kukaid.params.axis import FV_MAX, IZZ_MAX, STD_MAX, TORQUE_MAX


def good() -> dict:
    return {"schema": "kukaid.params/1", "axis": 3,
            "friction": {"model": "stribeck", "Fc": 12.0, "Fv": 8.0, "Fs": 14.0, "vs": 0.05, "delta": 2.0},
            "inertial": {"Izz": 2.3, "Mx": 20.0}, "mode_switch": {"qd_thr": 0.0017},
            "uncertainty": {"Izz": 0.01, "Fc": 0.1}, "provenance": {"gravity": "cos"}}


def sine_log(seed: int = 4, fs: float = 83.333, T: float = 16.0) -> AxisLog:
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, T, 1.0 / fs)
    w = 2 * np.pi * 0.4
    q = 0.3 + 0.8 * np.sin(w * t)
    qd, qdd = 0.8 * w * np.cos(w * t), -0.8 * w * w * np.sin(w * t)
    tau = 2.3 * qdd + 20.0 * np.cos(q) + 12.0 * np.sign(qd) + 8.0 * qd + 0.3 * rng.standard_normal(t.size)
    return AxisLog(t, q[:, None], tau[:, None], axes=(3,), attrs={"source_file": f"sine{seed}"})


@pytest.mark.parametrize("mutate, field", [
    (lambda d: d["inertial"].update(Izz=1e300), "inertial.Izz = 1e+300"),
    (lambda d: d["inertial"].update(Izz=IZZ_MAX * 1.01), "inertial.Izz"),
    (lambda d: d["inertial"].update(Mx=-1e300), "inertial.Mx = -1e+300"),
    (lambda d: d["friction"].update(Fc=2e6, Fs=3e6), "friction.Fc = 2000000.0"),
    (lambda d: d["friction"].update(Fv=FV_MAX * 10), "friction.Fv"),
    (lambda d: d["friction"].update(vs=1e9), "friction.vs"),
    (lambda d: d.update(offset=1e300), "offset = 1e+300"),
    (lambda d: d.update(maxwell_slip={"k": [1e300], "W": [1.0], "zeta0": [0.0]}), "maxwell_slip.k[0]"),
    (lambda d: d.update(maxwell_slip={"k": [1e4], "W": [1e300], "zeta0": [0.0]}), "maxwell_slip.W[0]"),
    (lambda d: d.update(uncertainty={"Izz": 1e300}), "uncertainty.Izz = 1e+300"),
    (lambda d: d.update(effects={"torque_offset": {"model": "x", "offset": 1e300}}), "effects.torque_offset.offset"),
])
def test_absurd_values_are_refused_on_read(tmp_path, mutate, field):
    d = good()
    mutate(d)
    p = tmp_path / "p_huge.json"
    p.write_text(json.dumps(d))
    with pytest.raises(ParamFileError) as e:
        load_params(p)
    msg = str(e.value)
    assert msg.startswith(f"{p}: {field}") and "outside the allowed range" in msg and "\n" not in msg


def test_ceilings_hold_real_robots_and_are_documented():
    # the heaviest KUKA arm (KR 1000 titan): torques ~1e5 N·m, inertias ~1e4 kg·m²: inside, with room
    assert TORQUE_MAX >= 1e6 and IZZ_MAX >= 1e5 and FV_MAX >= 1e5
    assert STD_MAX ** 2 < np.finfo(float).max  # a standard deviation squares without overflow
    d = good()
    d["inertial"].update(Izz=5e4, Mx=-2e5)
    d["friction"].update(Fc=3e4, Fs=3.5e4, Fv=1e4)
    from kukaid.params.axis import validate_params

    validate_params(d)


def _run(cmd: list[str], cwd) -> subprocess.CompletedProcess:
    return subprocess.run(cmd, capture_output=True, text=True, cwd=cwd, timeout=300)


def test_cli_refuses_a_huge_izz_and_leaks_no_runtime_warning(tmp_path, kukaid_cmd):
    write_hdf5(sine_log(), tmp_path / "validation.h5")
    d = good()
    d["inertial"]["Izz"] = 1e300
    (tmp_path / "p_huge.json").write_text(json.dumps(d))
    for args in (["validate", "--params", "p_huge.json", "validation.h5"],
                 ["report", "--params", "p_huge.json", "--inertia", "validation.h5", "-o", "r.pdf"],
                 ["diagnose", "--params", "p_huge.json", "--log", "validation.h5"]):
        r = _run([*kukaid_cmd, *args], tmp_path)
        assert r.returncode == 1, (args, r.stdout, r.stderr)
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("kukaid: error: p_huge.json: inertial.Izz = 1e+300"), r.stderr
        assert "Warning" not in r.stderr and "Traceback" not in r.stderr
    assert not (tmp_path / "r.pdf").exists()
    # at the ceilings the numbers are absurd but finite: no numpy overflow on the way
    d = good()
    d["inertial"].update(Izz=IZZ_MAX, Mx=-TORQUE_MAX)
    d["friction"].update(Fc=TORQUE_MAX, Fs=TORQUE_MAX, Fv=FV_MAX)
    d["uncertainty"] = {"Izz": STD_MAX, "Fc": STD_MAX}
    (tmp_path / "p_max.json").write_text(json.dumps(d))
    for args in (["validate", "--params", "p_max.json", "validation.h5"],
                 ["report", "--params", "p_max.json", "--inertia", "validation.h5", "-o", "m.pdf"],
                 ["diagnose", "--params", "p_max.json", "--log", "validation.h5"]):
        r = _run([*kukaid_cmd, *args], tmp_path)
        assert r.returncode == 0, (args, r.stderr)
        assert "Warning" not in r.stderr and "Traceback" not in r.stderr, (args, r.stderr)
