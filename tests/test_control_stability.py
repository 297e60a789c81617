"""The oscillation monitor (kukaid.control.stability) and the paper's measures (kukaid.control.metrics)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from kukaid.control.metrics import oscillation_runs, paper_costs
from kukaid.control.stability import OscillationMonitor, StabilityConfig
from kukaid.errors import KukaidError

CYCLE = 0.024


def _feed(signal, D=50.0, contact=True):
    mon = OscillationMonitor(StabilityConfig(), CYCLE, D, D_limit=1500.0)
    floors = [mon.step(x, D, contact=contact) for x in signal]
    return mon, np.array(floors)


def test_an_alternating_torque_raises_the_damping_within_a_second():
    t = np.arange(0.0, 4.0, CYCLE)
    osc = np.where(t > 1.0, 15.0 * np.sin(2 * math.pi * 1.5 * (t - 1.0)), 0.0)
    mon, floor = _feed(osc)
    assert mon.events and 1.0 < mon.events[0]["time"] < 2.0  # three half-cycles of 0.33 s
    assert floor.max() == pytest.approx(500.0)  # doubled while it goes on, up to 10 D
    assert "alternating half-cycles" in mon.events[0]["reason"]


@pytest.mark.parametrize("shape", ["step", "pulse"])
def test_a_quick_push_or_a_guiding_move_is_not_an_oscillation(shape):
    t = np.arange(0.0, 6.0, CYCLE)
    if shape == "step":  # a firm grasp: 0 -> 40 N·m in 0.2 s
        x = 40.0 * np.clip((t - 1.0) / 0.2, 0.0, 1.0)
    else:  # pull, then brake: one minimum-jerk-like move of 2 s
        x = 20.0 * np.sin(2 * math.pi * (t - 1.0) / 2.0) * ((t > 1.0) & (t < 3.0))
    mon, floor = _feed(x)
    assert not mon.events and floor.max() == 0.0


def test_the_floor_stays_during_the_contact_and_relaxes_after_it():
    t = np.arange(0.0, 3.0, CYCLE)
    osc = 15.0 * np.sin(2 * math.pi * 1.5 * t)
    mon, _ = _feed(osc)
    held = [mon.step(0.0, 50.0, contact=True) for _ in range(200)]
    assert min(held) == pytest.approx(500.0)  # still gripping: kept
    after = [mon.step(0.0, 50.0, contact=False) for _ in range(1000)]
    assert after[-1] == 0.0 and not mon.active


def _ringing(sigma, amplitude, f=1.5, seconds=5.0):
    """Γr of a mode ringing at f Hz from t = 1 s whose envelope changes at sigma per second."""
    t = np.arange(0.0, seconds, CYCLE)
    return np.where(t > 1.0, amplitude * np.exp(sigma * (t - 1.0)) * np.sin(2 * math.pi * f * (t - 1.0)), 0.0)


def _feed_decay(signal, D=60.0):
    mon = OscillationMonitor(StabilityConfig(raise_rule="decay", lobes=4), CYCLE, 50.0, D_limit=1500.0, I=20.0)
    floors = [mon.step(x, D, contact=True) for x in signal]
    return mon, np.array(floors)


def test_the_decay_rule_raises_a_growing_mode_to_the_damping_its_envelope_needs():
    """Envelope growing at 0.3/s with D 60: one step to D + 2 I (σ* - σ), σ* = max(ζ ω, ln(A/threshold) / 1 s),
    not a doubling to the cap."""
    mon, floor = _feed_decay(_ringing(0.3, 15.0))
    first = mon.events[0]
    w = 2 * math.pi * 1.5
    assert 1.5 < first["time"] < 2.5  # at the fourth half-cycle
    # the band-pass's lobes give ω and σ to within about 10 %
    assert first["D_floor"] == pytest.approx(60.0 + 2 * 20.0 * (0.2 * w + 0.3), rel=0.15)
    assert "growing" in first["reason"] and "envelope" in first["reason"]
    assert floor.max() < 250.0


def test_the_decay_rule_leaves_a_mode_that_decays_fast_enough_alone():
    """Envelope decaying at 2/s (ζ ≈ 0.2 at 1.5 Hz, down to the threshold within a second): no raise;
    the doubling rule takes the same ringing to the cap."""
    ring = _ringing(-2.0, 60.0)
    mon, floor = _feed_decay(ring)
    assert not mon.events and floor.max() < 60.0
    doubling = OscillationMonitor(StabilityConfig(lobes=4), CYCLE, 50.0, D_limit=1500.0)
    assert max(doubling.step(x, 60.0, contact=True) for x in ring) == pytest.approx(500.0)


def test_the_decay_rule_needs_the_inertia():
    with pytest.raises(KukaidError):
        OscillationMonitor(StabilityConfig(raise_rule="decay"), CYCLE, 50.0, D_limit=1500.0)
    with pytest.raises(KukaidError):
        StabilityConfig(raise_rule="halve")


def test_paper_costs_are_eq_19_per_cycle():
    g = np.array([0.0, 1.0, 3.0, 2.0])
    xi, dg2 = paper_costs(g, lam=0.5)
    d = np.array([1.0, 2.0, -1.0])
    assert dg2 == pytest.approx(np.mean(d ** 2))
    assert xi == pytest.approx(np.mean(0.5 * d ** 2 + 0.25 * g[1:] ** 2))


def test_oscillation_runs_find_alternations_not_moves():
    t = np.arange(0.0, 8.0, 0.012)
    move = 30.0 * np.sin(math.pi * np.clip((t - 1.0) / 2.5, 0.0, 1.0)) ** 2  # a guiding push
    assert oscillation_runs(t, move) == []
    osc = move + 12.0 * np.sin(2 * math.pi * 1.2 * t) * ((t > 4.0) & (t < 7.0))
    runs = oscillation_runs(t, osc)
    assert len(runs) == 1 and runs[0][0] == pytest.approx(4.0, abs=0.6) and runs[0][1] == pytest.approx(7.0, abs=0.6)


@pytest.mark.parametrize("ramp", [0.1, 0.15, 0.2])
def test_a_large_smooth_push_is_not_an_oscillation(ramp):
    """A firm grip's 80 N·m push with quick raised-cosine ramps, no ringing in it: no oscillation
    (lobes of a zero-phase high-pass counted 3 s of it: the filter rings before and after an edge)."""
    t = np.arange(0.0, 8.0, 0.012)
    r = lambda x: 0.5 - 0.5 * np.cos(np.pi * np.clip(x, 0.0, 1.0))  # noqa: E731
    push = 80.0 * np.minimum(r((t - 2.5) / ramp), r((4.5 - t) / ramp))
    assert oscillation_runs(t, push) == []
    assert oscillation_runs(t, push - 24.0 * np.sin(np.pi * np.clip((t - 4.6) / 0.5, 0.0, 1.0))) == []  # a pull-back


# --- the adaptive law's grip-stiffness floor (CouplingFloor) ---------------------------------------

from kukaid.control.stability import CouplingConfig, CouplingFloor, critical_damping, probe_time  # noqa: E402


def test_critical_damping_is_the_delayed_loops_stability_boundary():
    """I s² + D s + K e^{-sT} has a root on the imaginary axis at D = critical_damping(K, I, T):
    ≈ K T for small ωT, growing with K and T, 0 without delay."""
    K, I, T = 1200.0, 20.0, 0.09
    D = critical_damping(K, I, T)
    w = np.linspace(0.1, 30.0, 200001)
    char = -I * w ** 2 + 1j * D * w + K * np.exp(-1j * w * T)
    assert np.min(np.abs(char)) < 1e-3 * K
    assert 0.7 * K * T < D < K * T
    assert critical_damping(400.0, I, T) < D and critical_damping(K, I, 0.05) < D
    assert critical_damping(K, I, 1e-9) == pytest.approx(0.0, abs=1e-3)


def _ring(K, I=20.0, T=0.064 + CYCLE, seconds=3.0):
    """Γr of a grip K ringing against the admittance through the loop delay T: a slowly decaying
    oscillation at the frequency where K cos ωT = I ω² (the delayed loop's mode)."""
    lo, hi = 0.0, 0.5 * math.pi / T
    for _ in range(60):
        w = 0.5 * (lo + hi)
        lo, hi = (w, hi) if K * math.cos(w * T) > I * w * w else (lo, w)
    t = np.arange(0.0, seconds, CYCLE)
    return np.where(t > 0.5, 30.0 * np.exp(-0.3 * (t - 0.5)) * np.sin(w * (t - 0.5)), 0.0)


@pytest.mark.parametrize("K", [600.0, 900.0, 1200.0])
def test_the_grip_floor_follows_the_stiffness_from_the_ringing(K):
    cf = CouplingFloor(CouplingConfig(), CYCLE, 20.0, D_cap=1000.0, filter_delay=lambda w: 0.064)
    floors = [cf.step(x, contact=True) for x in _ring(K)]
    first = next(i for i, f in enumerate(floors) if f > 0)
    half = math.pi / math.sqrt(K / 20.0)
    assert first * CYCLE < 0.5 + 2 * half + 0.25  # on the second half-cycle, not the third
    assert K <= cf.K_est <= 1.7 * K  # the band-pass shortens the first lobes: on the safe side
    T = 0.064 + CYCLE
    assert cf.floor >= critical_damping(cf.K_est, 20.0, T)
    assert cf.floor == pytest.approx(critical_damping(cf.K_est, 20.0, T) + 0.4 * math.sqrt(cf.K_est * 20.0))
    assert "N·m/rad" in cf.events[0]["reason"]


def test_a_guiding_move_or_no_contact_gives_no_grip_floor():
    t = np.arange(0.0, 6.0, CYCLE)
    move = 20.0 * np.sin(2 * math.pi * (t - 1.0) / 2.0) * ((t > 1.0) & (t < 3.0))
    cf = CouplingFloor(CouplingConfig(probe=False), CYCLE, 20.0, D_cap=1000.0)
    assert max(cf.step(x, contact=True) for x in move) == 0.0
    cf = CouplingFloor(CouplingConfig(), CYCLE, 20.0, D_cap=1000.0)
    assert max(cf.step(x, contact=False) for x in _ring(1200.0)) == 0.0


def test_the_grip_floor_rises_with_a_slower_robot_and_relaxes_after_the_release():
    floors = []
    for lag in (0.0, 0.05):
        cf = CouplingFloor(CouplingConfig(), CYCLE, 20.0, D_cap=1000.0, filter_delay=lambda w: 0.064)
        for k in range(100):  # the axis moves at 0.1 rad/s, lag s behind the reference
            q = 0.1 * k * CYCLE
            cf.observe_robot(q + 0.1 * lag, q)
        assert cf.robot_lag == pytest.approx(lag, abs=1e-6)
        for x in _ring(1000.0):
            cf.step(x, contact=True)
        floors.append(cf.floor)
    assert floors[1] > 1.2 * floors[0]
    after = [cf.step(0.0, contact=False) for _ in range(2000)]
    assert after[-1] == 0.0


def test_a_new_contact_keeps_d0_until_a_rebound_would_have_shown():
    """For one period of the slowest mode D0 cannot hold the floor ramps down from D0; a stiffer
    grip would have rebounded by then."""
    T = 0.064 + CYCLE
    P = probe_time(50.0, 20.0, T)
    K = 50.0 / T  # about the stiffness D0 holds: its mode's period
    assert critical_damping(K, 20.0, T) == pytest.approx(50.0, rel=0.25)
    assert 2 * math.pi / math.sqrt(1.5 * K / 20.0) < P < 2 * math.pi / math.sqrt(0.5 * K / 20.0)
    assert probe_time(50.0, 20.0, 2 * T) > P  # a slower loop: a longer wait
    cf = CouplingFloor(CouplingConfig(), CYCLE, 20.0, D_cap=1000.0, filter_delay=lambda w: 0.064, D0=50.0)
    floors = np.array([cf.step(0.0, contact=True) for _ in range(200)])
    assert floors[0] == pytest.approx(50.0, rel=0.05) and cf.probe_time == pytest.approx(P)
    n = int(P / CYCLE)
    assert np.all(np.diff(floors[:n]) < 0) and np.all(floors[n + 1:] == 0.0)
