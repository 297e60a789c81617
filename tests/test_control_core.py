"""Fast tests of the control stage: admittance discretisation, stability checks, safety, residual."""
from __future__ import annotations

import math

import numpy as np
import pytest

from kukaid.control.admittance import Admittance, check_admittance
from kukaid.robot import SimRobot
from kukaid.control.loop import LoopConfig, run_admittance
from kukaid.control.safety import ReferenceLimiter, SafetyLimits, Watchdog, check_motion_allowed
from kukaid.control.torque_residual import TorqueResidual
from kukaid.errors import KukaidError
from kukaid.params import model_from_params
from kukaid.sim.operator import PushOperator
from kukaid.sim import SimConfig, VirtualKRC4


def test_discretisation_matches_continuous():
    adm = Admittance(I=20.0, D=50.0, dt=0.012)
    errs = []
    for k in range(1, 400):
        s, sd = adm.step(10.0)
        sc, sdc = adm.continuous(10.0, k * 0.012)
        errs.append((abs(s - sc), abs(sd - sdc)))
    e = np.array(errs)
    assert e[:, 1].max() < 0.01 * 0.2 and e[:, 0].max() < 2e-3
    for _ in range(3000):
        s, sd = adm.step(10.0)
    assert sd == pytest.approx(0.2, abs=1e-9)  # 10 N·m / 50 N·m·s/rad


@pytest.mark.parametrize("I,D,dt", [(0, 50, 0.012), (-1, 50, 0.012), (20, 0, 0.012), (20, -5, 0.012),
                                    (20, math.nan, 0.012), (1, 200, 0.012)])
def test_unstable_parameters_refused(I, D, dt):
    with pytest.raises(KukaidError, match="admittance"):
        check_admittance(I, D, dt)


def test_limiter_clips_window_speed_acceleration():
    lim = ReferenceLimiter(SafetyLimits(q_min=-0.1, q_max=0.1, qd_max=0.5, qdd_max=5.0), 0.012, 0.0)
    q, c = lim.apply(1.0)  # a step: limited by acceleration
    assert c and q == pytest.approx(5.0 * 0.012 ** 2)
    qs = [lim.apply(1.0)[0] for _ in range(300)]
    v = np.diff([0.0] + qs) / 0.012
    assert np.all(np.abs(v) <= 0.5 + 1e-9) and max(qs) <= 0.1


def test_stale_reading_stops_motion():
    class Stale(SimRobot):
        def cycle(self, q_cmd, dt):
            out = super().cycle(q_cmd, dt)
            return out if self.sim.t < 2.0 else []  # readings stop arriving at 2 s

    # pushed from after the loop's own move and rest (a push during them is read as the model's error)
    be = Stale(VirtualKRC4(SimConfig(), seed=1), 0.5, PushOperator(15.0, 1.3, 10.0))
    run = run_admittance(be, model_from_params(SimConfig().truth_params()), LoopConfig(duration=5.0))
    assert run.status.startswith("stopped: measurement stale")
    assert run.data["time"][-1] < 2.2


def test_watchdog_missing():
    w = Watchdog(0.1)
    assert not w.check(0.0) and "no measurement" in w.tripped


def test_kvp_motion_refused_without_flag():
    with pytest.raises(KukaidError, match="--enable-motion"):
        check_motion_allowed("kvp", False, SafetyLimits(q_min=0, q_max=1))
    with pytest.raises(KukaidError, match="position window"):
        check_motion_allowed("kvp", True, SafetyLimits())
    check_motion_allowed("sim", False, None)


def test_residual_quasi_static_truth_away_from_paper():
    cfg = SimConfig(Fc=12.0, Fs=14.0, Fv=10.0, Izz=1.8, Mx=22.0, ms_W=(6.0, 1.0, 5.0))
    model = model_from_params(cfg.truth_params())
    sim = VirtualKRC4(cfg, seed=5)
    sim.reset(0.4)
    sim.set_external_torque(lambda t, q, qd: 0.0 if t < 6 else 10.0 * min((t - 6) / 0.5, 1.0))
    est = TorqueResidual(model, threshold=5.0)
    rows = []
    while sim.t < 9.0:
        x = min(sim.t / 0.6, 1.0)
        sim.command(0.4 + math.radians(1) * x ** 3 * (10 - 15 * x + 6 * x * x))  # initiation move
        b = sim.advance(0.012)
        for t, q, tau, te in zip(b["time"], b["q"], b["tau"], b["tau_ext_true"]):
            r = est.update(q, tau)
            rows.append((t, r.gamma_r, te, r.detected))
    a = np.array(rows)
    rest = (a[:, 0] > 1.5) & (a[:, 0] < 6.0)  # ~4.5 s free standstill with vibration
    assert not a[rest, 3].any()
    push = a[:, 0] > 7.0
    assert np.sqrt(np.mean((a[push, 1] - a[push, 2]) ** 2)) < 1.5


def test_residual_takes_each_diagnosed_effect_once_in_either_format():
    p = SimConfig().truth_params()
    p["inertial"]["My"] = 0.3
    p["offset"] = -0.2
    # diagnose keeps My and the offset in the rigid body and marks the effects stored_as
    p["effects"] = {"gravity_sine": {"My": 0.3, "stored_as": "inertial.My"},
                    "torque_offset": {"offset": -0.2, "stored_as": "offset"}}
    est = TorqueResidual(model_from_params(p))
    q = 1.1
    rigid = p["inertial"]["Mx"] * math.cos(q) + 0.3 * math.sin(q) - 0.2
    assert est.static_torque(q) == pytest.approx(rigid)
    # a ripple as diagnose writes it (a, b) and as the simulator does (A, phi) is the same torque
    for ripple in ({"n": 12.0, "a": 0.6, "b": 0.8}, {"n": 12.0, "A": 1.0, "phi": math.atan2(0.8, 0.6)}):
        p["effects"] = {"position_ripple": ripple}
        est = TorqueResidual(model_from_params(p))
        assert est.static_torque(q) - rigid == pytest.approx(0.6 * math.sin(12 * q) + 0.8 * math.cos(12 * q))
