"""The simulated human arm (kukaid.sim.human): a seeded person, physiological ranges, lets go on target."""
from __future__ import annotations

import math

import numpy as np
import pytest

from kukaid.sim.human import GRIPS, make_human


def _drive(arm, follow=1.0, t_end=14.0, dt=0.012):
    """A plant that follows the hand's torque as an admittance (I 10, D 60): returns t, q, tau."""
    q, qd, out = arm.p.q_start, 0.0, []
    for k in range(int(t_end / dt)):
        t = k * dt
        tau = arm(t, q, qd)
        qd += follow * dt * (tau - 60.0 * qd) / 10.0
        q += qd * dt
        out.append((t, q, tau))
    return np.array(out).T


def test_same_seed_same_person_and_noise():
    a, b = make_human(7, 0.5, 2.0), make_human(7, 0.5, 2.0)
    assert a.params() == b.params()
    assert np.array_equal(_drive(a)[2], _drive(b)[2])
    assert make_human(8, 0.5, 2.0).params() != a.params()


@pytest.mark.parametrize("grip", GRIPS)
def test_stiffness_ranges_and_release_on_target(grip):
    for seed in range(6):
        arm = make_human(seed, 0.0, 1.0, grip=grip)
        p = arm.p
        assert 60.0 <= p.K0 <= 500.0 and p.K0 <= p.K_max <= 1200.0
        assert 0.2 <= abs(p.distance) <= 0.5 and 0.03 <= p.reflex_delay <= 0.06
        t, q, tau = _drive(arm)
        assert arm.released_on_target, (grip, seed)
        i = np.searchsorted(t, arm.t_release)
        assert abs(q[i] - p.goal) <= p.on_target_tol  # on target when letting go
        assert np.all(tau[t > arm.t_release + p.release_time + 0.02] == 0.0)  # and gone after
        assert arm.K_peak <= p.K_max + 1e-9


def test_firm_grips_co_contract_to_high_stiffness_and_some_change_their_mind():
    peaks = []
    for seed in range(8):
        arm = make_human(seed, 0.0, 1.0, grip="firm")
        _drive(arm)
        peaks.append(arm.K_peak)
    assert max(peaks) > 900.0
    # the stiffness now (what a benchmark's oracle reads): nothing before the grasp, with effort while holding
    arm, q, seen = make_human(2, 0.0, 1.0, grip="firm"), 0.0, []
    for k in range(int(6.0 / 0.012)):
        arm(k * 0.012, q, 0.0)
        seen.append(arm.K)
    seen = np.array(seen)
    assert np.all(seen[: int(0.99 / 0.012)] == 0.0)
    assert arm.p.K0 <= seen.max() <= arm.p.K_max and seen.max() == arm.K_peak
    assert seen.max() > 1.5 * arm.p.K0  # a held link that does not follow: the arm co-contracts
    changes = [make_human(s).p.change_at is not None for s in range(30)]
    assert 3 <= sum(changes) <= 20


def test_stuck_robot_is_let_go_after_the_timeout():
    arm = make_human(3, 0.0, 1.0)
    t, q, tau = _drive(arm, follow=0.0, t_end=arm.p.t_plan_end + arm.p.timeout + 1.0)
    assert not arm.released_on_target and math.isfinite(arm.t_release)
    assert arm.t_release == pytest.approx(arm.p.t_plan_end + arm.p.timeout, abs=0.013)
