"""Each hidden effect changes the measured torque as kukaid.sim.effects documents it."""
from __future__ import annotations

import numpy as np
import pytest

from kukaid.sim import EFFECTS, SimConfig, VirtualKRC4, draw_effect
from kukaid.sim.config import SimConfigError
from kukaid.sim.friction_sim import steady_friction
from sim_helpers import Builder

BASE = dict(Fc=12.0, Fs=16.0, vs=0.02, delta=1.2, Fv=9.0, Mx=25.0, Izz=1.7, noise_sigma=0.0, vibration=False,
            quant_deg=0.0)
V = 0.25


def _traj():
    b = Builder(-0.3).hold(0.3)
    b.move(V, 2.4, ramp=0.3).hold(0.4)
    b.move(-V, 2.4, ramp=0.3).hold(0.4)
    return b.build()


def _diff(effects, **extra):
    """Torque with the effect minus torque without (same seed, noise-free), and the log."""
    tr = _traj()
    l0 = VirtualKRC4(SimConfig(**BASE, **extra), seed=2).run(tr)
    l1 = VirtualKRC4(SimConfig(**BASE, **extra, effects=effects), seed=2).run(tr)
    return l1.tau[:, 0] - l0.tau[:, 0], l1


def _plateaus(log):
    """Masks of the two constant-velocity plateaus (settled), direction +1 and -1."""
    t = log.time
    up = (t > 0.3 + 0.3 + 0.4) & (t < 0.3 + 0.3 + 2.4)
    t2 = 0.3 + 3.0 + 0.4
    down = (t > t2 + 0.3 + 0.4) & (t < t2 + 0.3 + 2.4)
    return up, down


def test_effect_table_is_complete():
    assert set(EFFECTS) == {"gravity_sine", "torque_offset", "position_ripple", "thermal_drift",
                            "load_dependent_friction", "backlash"}
    for name, spec in EFFECTS.items():
        assert spec["size"] and spec["draw"] and spec["params"]


def test_torque_offset():
    d, log = _diff({"torque_offset": {"offset": 1.3}})
    for m in _plateaus(log):
        assert d[m].mean() == pytest.approx(1.3, abs=0.02)


def test_gravity_sine():
    d, log = _diff({"gravity_sine": {"My": -2.0}})
    q = log.q[:, 0]
    for m in _plateaus(log):
        np.testing.assert_allclose(d[m], -2.0 * np.sin(q[m]), atol=0.05)


def test_position_ripple():
    d, log = _diff({"position_ripple": {"A": 0.8, "n": 6.0, "phi": 0.5}})
    q = log.q[:, 0]
    for m in _plateaus(log):
        np.testing.assert_allclose(d[m], 0.8 * np.sin(6.0 * q[m] + 0.5), atol=0.08)


def test_load_dependent_friction():
    d, log = _diff({"load_dependent_friction": {"c": 0.05}})
    q = log.q[:, 0]
    for m, sgn in zip(_plateaus(log), (1, -1)):
        np.testing.assert_allclose(d[m], sgn * 0.05 * np.abs(25.0 * np.cos(q[m])), atol=0.03)


def test_thermal_drift():
    # a warm motor (T0 = T_ref + 20 K): friction scaled by 1 + kappa (T - T_ref)
    d, log = _diff({"thermal_drift": {"kappa": -0.004, "T_ref": 25.0}}, T0=45.0)
    T = log.temp[:, 0]
    cfg = SimConfig(**BASE)
    for m, sgn in zip(_plateaus(log), (1, -1)):
        want = -0.004 * (T[m] - 25.0) * steady_friction(sgn * V, cfg)
        np.testing.assert_allclose(d[m], want, atol=0.03)
        assert np.all(np.abs(d[m]) > 1.0)
    assert T[0] > T[-1] > 25.0  # the motor cools toward ambient (losses are small here)


def test_thermal_model_heats_under_load():
    cfg = SimConfig(**BASE)
    log = VirtualKRC4(cfg, seed=0).run(_traj())
    assert log.temp[-1, 0] > log.temp[0, 0]


def test_backlash_transient_after_reversal():
    d, log = _diff({"backlash": {"A": 2.0, "tau": 0.1, "v_on": 0.01}})
    t, q = log.time, log.q[:, 0]
    qd = np.gradient(q, t)
    # first crossing of -v_on after the first plateau: the reversal
    i_rev = np.flatnonzero((t > 3.0) & (qd < -0.01))[0]
    i_fwd = np.flatnonzero(qd > 0.01)[0]
    for i, sgn in ((i_fwd, 1), (i_rev, -1)):
        win = (t >= t[i] - 0.05) & (t <= t[i] + 0.4)
        peak = d[win][np.argmax(np.abs(d[win]))]
        assert np.sign(peak) == sgn
        assert abs(peak) == pytest.approx(2.0, rel=0.15)
    # gone on the plateaus
    for m in _plateaus(log):
        assert np.abs(d[m][-20:]).max() < 0.05


def test_effects_change_nothing_when_absent():
    d, _ = _diff({})
    assert np.all(d == 0.0)


@pytest.mark.parametrize("name", sorted(EFFECTS))
def test_draw_effect_sizes(name):
    rng = np.random.default_rng(0)
    for size in (0.125, 1.0, 2.5):
        p = draw_effect(name, size, rng)
        cfg = SimConfig(effects={name: p})  # validates
        assert set(cfg.effects[name]) == set(EFFECTS[name]["params"])
        if name == "gravity_sine":
            assert abs(p["My"]) == pytest.approx(size)
        elif name == "torque_offset":
            assert abs(p["offset"]) == pytest.approx(size)
        elif name in ("position_ripple", "backlash"):
            assert p["A"] == pytest.approx(size)
        elif name == "thermal_drift":
            assert abs(p["kappa"]) * 3 * 20 == pytest.approx(size)
        else:
            assert p["c"] * 18.4789 == pytest.approx(size)
            assert draw_effect(name, size, rng, mx=-23.7)["c"] * 23.7 == pytest.approx(size)


def test_draw_effect_bad_input():
    with pytest.raises(SimConfigError, match="unknown effect 'friction_wobble'"):
        draw_effect("friction_wobble", 1.0, np.random.default_rng(0))
    with pytest.raises(SimConfigError, match="size"):
        draw_effect("torque_offset", -1.0, np.random.default_rng(0))
