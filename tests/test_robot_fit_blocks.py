"""The robot fit's normal equations accumulated block by block: the same result as the fit that
built the whole (N, n, p) regressor (stored in tests/data/robot_fit_reference.json, written by that
fit on the same simulated log), whatever the block size; the speed benchmark's quick size runs."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from kukaid.identify import robot_fit
from kukaid.identify.robot_fit import RobotFitSettings, fit_robot
from kukaid.models.robot import RobotModel

from robot_sim_helpers import simulated_log

HERE = Path(__file__).resolve().parent
REFERENCE = json.loads((HERE / "data" / "robot_fit_reference.json").read_text())
#: the settings the reference was written with (the defaults then: sign friction, no mass bounds)
OLD = dict(v_smooth=0.0, deadband=0.0, mass_bounds=None, total_mass_bounds=None, choose=False)
CASES = {"default": RobotFitSettings(**OLD),
         "ls_torque": RobotFitSettings(consistent=False, weighting="torque", ripple=2, **OLD),
         "rotor": RobotFitSettings(rotor=True, **OLD)}


@pytest.fixture(scope="module")
def kr6_log():
    robot = RobotModel("kr6-r700-sixx")
    log, _ = simulated_log(robot, duration=12.0, fs=250, seed=5)
    return robot, log


def _close(a, b, rtol):
    a, b = np.asarray(a, float), np.asarray(b, float)
    ok = np.isfinite(b)
    assert np.array_equal(ok, np.isfinite(a))
    assert np.max(np.abs(a[ok] - b[ok])) <= rtol * np.max(np.abs(b[ok])), np.max(np.abs(a[ok] - b[ok]))


@pytest.mark.parametrize("case", ["default", "ls_torque", "rotor"])
def test_blockwise_fit_equals_the_whole_regressor_fit(kr6_log, case):
    robot, log = kr6_log
    p = fit_robot([log], robot, CASES[case])
    ref = REFERENCE[case]
    assert p["metrics"]["samples"] == ref["metrics"]["samples"]
    base_ls, friction_ls = np.asarray(ref["base_ls"], float), dict(ref["friction_ls"])
    if case == "rotor":
        # the reference fitted A1's and A2's rotors as columns of their own; each is one column with a link
        # inertia (ratio² qdd_j in joint j's equation alone), so the fit now folds them into the base
        # parameters (robot_fit.folded_rotors): the same least squares, the rotors' ratio² I moved there
        assert p["metrics"]["choices"]["rotor"]["folded"] == ["M1", "M2"]
        base = robot.base_parameters()
        drive = robot_fit._drive(robot, CASES[case])
        rng = np.random.default_rng(3)
        q, qd, qdd = (rng.uniform(-1.0, 1.0, (60, robot.n)) for _ in range(3))
        Y = robot.regressor(q, qd, qdd)[:, :, base.independent].reshape(-1, base.size)
        R = drive.rotor_regressor(qdd).reshape(-1, robot.n)
        for k in (0, 1):
            x = np.linalg.lstsq(Y, R[:, k], rcond=None)[0]
            assert np.allclose(Y @ x, R[:, k], atol=1e-9 * np.abs(R[:, k]).max())    # one column
            assert np.allclose(p["metrics"]["choices"]["rotor"]["folded_into"][k], x, rtol=1e-6, atol=1e-6 * np.abs(x).max())
            base_ls = base_ls + x * friction_ls[f"M{k + 1}.rotor_inertia"]
            friction_ls[f"M{k + 1}.rotor_inertia"] = 0.0
    _close(p["base_parameters"]["least_squares"], base_ls, 1e-8)
    _close(list(p["friction"]["least_squares"].values()), list(friction_ls.values()), 1e-8)
    _close(p["metrics"]["noise_sigma"], ref["metrics"]["noise_sigma"], 1e-6)
    _close([p["metrics"]["residual_correlation_factor"]], [ref["metrics"]["residual_correlation_factor"]], 1e-8)
    _close(p["metrics"]["relative_error_fit"], ref["metrics"]["relative_error_fit"], 1e-4)
    if case != "rotor":   # the reference's rotors were not folded: its consistent split and sigma differ
        _close(p["base_parameters"]["values"], ref["base_values"], 1e-7)
        _close(list(p["friction"]["values"].values()), list(ref["friction"].values()), 1e-6)
        _close(p["base_parameters"]["sigma"], ref["sigma"], 1e-6)


def test_block_size_does_not_change_the_normal_equations(kr6_log, monkeypatch):
    robot, log = kr6_log
    s = RobotFitSettings(v_smooth=0.02)
    drive = robot_fit._drive(robot, s)
    m = robot_fit._samples([log], robot.n, s, drive)
    G1, g1, u1 = robot_fit.normal_equations(robot, m, s, drive, block=m.q.shape[0])
    G2, g2, u2 = robot_fit.normal_equations(robot, m, s, drive, block=97)
    assert np.array_equal(u1, u2)
    assert np.allclose(G1, G2, rtol=1e-12, atol=1e-12 * np.abs(G1).max())
    assert np.allclose(g1, g2, rtol=1e-12, atol=1e-12 * np.abs(g1).max())


def test_speed_benchmark_quick_runs():
    r = subprocess.run([sys.executable, str(HERE.parent / "benchmarks" / "robot_fit_speed.py"), "--quick", "--json"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    row = out["rows"][0]
    assert row["duration_s"] == 20.0 and row["fitted_samples"] > 1000
    assert row["peak_mb"] > 0 and row["fit_cpu_s"] > 0 and out["targets"]["peak_mb"] == 500.0
