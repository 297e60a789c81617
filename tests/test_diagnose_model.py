"""The compared model on synthetic data made with numpy only (no simulator): the both-sides
filtered comparison is exact for a correct model, a refit recovers the parameters, stored effects
round-trip through the parameter file."""
from __future__ import annotations

import numpy as np
import pytest

from kukaid.diagnose.noise import noise_floor
from kukaid.diagnose.refit import refit
from kukaid.diagnose.signals import prepare
from kukaid.diagnose.workflow import diagnose, rmse_of
from kukaid.logs import AxisLog
from kukaid.models.friction import Stribeck
from kukaid.params import model_from_params

TRUE = {"schema": "kukaid.params/1", "axis": 3,
        "friction": {"model": "stribeck", "Fc": 11.3, "Fs": 13.9, "vs": 0.07, "delta": 1.3, "Fv": 8.7},
        "inertial": {"Izz": 1.62, "Mx": 27.4}}


def synthetic_log(extra=None, noise=0.0, seed=0, dt=0.012):
    """Sine sweeps and constant-velocity moves, torque from the exact model (+ extra(q, qd, t))."""
    rng = np.random.default_rng(seed)
    tt = np.arange(0.0, 40.0, 0.001)
    q = 0.3 + 0.7 * np.sin(2 * np.pi * tt / 4.0) * np.minimum(1.0, tt / 4.0) + 0.1 * np.sin(2 * np.pi * tt / 9.0)
    qd = np.gradient(q, tt)
    qdd = np.gradient(qd, tt)
    f = TRUE["friction"]
    tau = TRUE["inertial"]["Izz"] * qdd + TRUE["inertial"]["Mx"] * np.cos(q) + \
        Stribeck(f["Fc"], f["Fs"], f["vs"], f["delta"], f["Fv"])(qd)
    if extra is not None:
        tau = tau + extra(q, qd, tt)
    k = np.arange(0, tt.size, int(round(dt / 0.001)))
    return AxisLog(time=tt[k], q=q[k], tau=tau[k] + noise * rng.standard_normal(k.size), axes=(3,))


def test_correct_model_leaves_no_residual():
    log = synthetic_log()
    sig = prepare(log, 3)
    r = model_from_params(TRUE).residual(sig)
    assert np.sqrt(np.mean(r**2)) < 0.02  # N*m, on torques of about 40 N*m


def test_refit_recovers_parameters_from_a_poor_start():
    sigs = [prepare(synthetic_log(noise=0.3, seed=1), 3)]
    start = {"friction": {"model": "stribeck", "Fc": 5.0, "Fs": 5.0, "vs": 0.2, "delta": 1.0, "Fv": 1.0},
             "inertial": {"Izz": 1.0, "Mx": 0.0}}
    m = refit(model_from_params(start), sigs)
    assert m.lin["Izz"] == pytest.approx(1.62, rel=0.02)
    assert m.lin["Mx"] == pytest.approx(27.4, rel=0.01)
    assert m.lin["Fc"] == pytest.approx(11.3, rel=0.03)
    assert m.lin["Fv"] == pytest.approx(8.7, rel=0.03)
    assert rmse_of(m, sigs)[0] <= 1.05 * noise_floor(sigs)


def test_synthetic_ripple_is_found_and_round_trips():
    A, n, phi = 0.8, 13.0, 0.4
    log = synthetic_log(lambda q, qd, t: A * np.sin(n * q + phi), noise=0.3, seed=2)
    d = diagnose(TRUE, [log])
    assert d.names == ["position_ripple"], d.lines()
    e = d.params["effects"]["position_ripple"]
    assert e["n"] == pytest.approx(n, abs=0.05) and e["A"] == pytest.approx(A, rel=0.05)
    t = np.linspace(0, 3, 300)
    q = 0.2 * np.sin(t)
    assert np.allclose(model_from_params(d.params).effects_torque(t, q, 0.2 * np.cos(t)), e["A"] * np.sin(e["n"] * q + e["phi"]))
    again = diagnose(d.params, [log])
    assert again.names == [] and again.rmse_before == pytest.approx(d.rmse_after, rel=0.02)
