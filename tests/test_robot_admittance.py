"""run-admittance with a robot model: the guided axis's Γr from every axis's motion (six-axis virtual KR C4)."""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

pytest.importorskip("pinocchio")

from kukaid.control.loop import PHASE_ADMITTANCE, LoopConfig, run_admittance  # noqa: E402
from kukaid.control.robot_residual import RobotTorqueModel  # noqa: E402
from kukaid.control.safety import SafetyLimits  # noqa: E402
from kukaid.errors import KukaidError  # noqa: E402
from kukaid.robot import SimRobot  # noqa: E402
from kukaid.sim.robot_plant import RobotSimConfig, VirtualRobotKRC4  # noqa: E402
from robot_helpers import ROBOT  # noqa: E402

AXIS = 3          # guided
MOVING = 2        # another axis, moving along a program meanwhile
PUSH = 8.0        # N·m on the guided axis from T_PUSH on for 1.5 s
T_PUSH = 5.0


class _Alone(RobotTorqueModel):
    """The guided axis seen alone (the one-axis view): the other axes' velocities and accelerations unknown."""

    def __call__(self, q, qd, qdd):
        keep = np.zeros_like(qd)
        keep[AXIS - 1] = 1.0
        return super().__call__(q, qd * keep, qdd * keep)


def _run(model_cls, push: bool):
    sim = VirtualRobotKRC4(RobotSimConfig(robot=ROBOT), seed=3)
    q0 = np.zeros(sim.n)
    q0[1], q0[2] = -1.2, 1.4
    t = np.arange(0.0, 20.0, 0.012)
    q = np.tile(q0, (t.size, 1))
    q[:, MOVING - 1] += 0.35 * np.sin(2 * np.pi * 0.6 * t) * np.minimum(t / 1.0, 1.0) ** 2
    program = SimpleNamespace(t=t, q=q)
    op = (lambda tt, qq, qd: PUSH if T_PUSH <= tt < T_PUSH + 1.5 else 0.0) if push else None
    be = SimRobot(sim, q0, op, program=program, axis=AXIS)
    cfg = LoopConfig(I=20.0, D=50.0, threshold=3.0, cycle=0.012, sample_time=sim.cfg.sample_time, duration=7.0,
                     limits=SafetyLimits(q_min=q0[AXIS - 1] - 0.5, q_max=q0[AXIS - 1] + 0.5, tau_max=1e4))
    model = model_cls.from_truth(sim.truth.to_dict())
    return run_admittance(be, model, cfg)


@pytest.fixture(scope="module")
def quiet():
    return _run(RobotTorqueModel, push=False)


def test_guided_axis_residual_stays_near_zero_while_another_axis_moves(quiet):
    d = quiet.data
    ph = d["phase"] == PHASE_ADMITTANCE
    assert quiet.status == "completed"
    assert np.ptp(d["q"][ph]) < 1e-3            # the guided axis was not pushed: it stands
    rms = float(np.sqrt(np.mean(d["gamma_r"][ph] ** 2)))
    # what is left: Coulomb friction of the standing axis (sign of a differenced, quantised speed)
    assert rms < 0.8 and not d["detected"][ph].any()
    alone = _run(_Alone, push=False).data        # the one-axis view takes the coupling for a push
    rms_alone = float(np.sqrt(np.mean(alone["gamma_r"][ph] ** 2)))
    assert rms_alone > 2.5 * rms and alone["detected"][ph].any()


def test_guided_axis_detects_a_push_and_follows_it():
    run = _run(RobotTorqueModel, push=True)
    d = run.data
    t = d["time"]
    during = (d["phase"] == PHASE_ADMITTANCE) & (t > T_PUSH + 0.3) & (t < T_PUSH + 1.5)
    before = (d["phase"] == PHASE_ADMITTANCE) & (t < T_PUSH)
    assert run.status == "completed"
    assert d["detected"][during].mean() > 0.9 and not d["detected"][before].any()
    assert np.median(d["gamma_r"][during]) == pytest.approx(PUSH, rel=0.2)
    assert d["q"][-1] - d["q"][before][-1] > 0.05    # the axis moved with the push (positive Γr: positive q)


def test_robot_model_needs_every_axis():
    from kukaid.robot.interface import Block, Sample

    class OneAxis:
        axis = 1

        def start(self):
            return Block([Sample(0.0, 0.0, 0.0)])

        def hold(self):
            pass

        def close(self):
            pass

    sim = VirtualRobotKRC4(RobotSimConfig(robot=ROBOT), seed=0)
    with pytest.raises(KukaidError, match="every axis"):
        run_admittance(OneAxis(), RobotTorqueModel.from_truth(sim.truth.to_dict()), LoopConfig(duration=1.0))
    assert math.isfinite(sim.t)
