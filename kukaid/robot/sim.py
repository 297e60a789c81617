"""The virtual KR C4 (:class:`kukaid.sim.VirtualKRC4`) as a :class:`~kukaid.robot.interface.Robot`."""
from __future__ import annotations

from typing import Any, Callable

import numpy as np

from kukaid.robot.interface import Block, Sample


class SimRobot:
    """The virtual KR C4 ``sim`` standing at ``q0`` rad, with an optional external torque
    ``operator`` (a function ``fn(t, q, qd)`` N·m, or a constant) acting on the axis.

    ``sim`` may also be the six-axis :class:`kukaid.sim.robot_plant.VirtualRobotKRC4` (``q0`` one
    position per axis): its blocks then carry the (N, A) ``channels`` and no one-axis samples.

    ``program`` (a trajectory: ``.t`` s, ``.q`` rad) is what a KRL program is on a real controller:
    the robot follows it from :meth:`start` on, and :meth:`cycle` with ``q_cmd`` None lets it run.

    ``axis`` (six-axis simulator only): the axis guided by :meth:`cycle`'s ``q_cmd`` (a number) and
    pushed by ``operator`` (one axis's torque), while the other axes follow ``program`` (an (N, A)
    trajectory; they stand at ``q0`` without one); the samples are that axis's, with every axis's
    positions and torques in ``q_all``, ``tau_all``.
    """

    name = "sim"

    def __init__(self, sim: Any, q0: float,
                 operator: Callable[[float, float, float], float] | float | None = None, program: Any = None,
                 axis: int | None = None) -> None:
        self.sim = sim
        self.q0 = float(q0) if np.ndim(q0) == 0 else np.asarray(q0, dtype=float)
        self.operator = operator
        self.program = program
        self.axis = axis

    def _guided(self) -> bool:
        return self.axis is not None and np.ndim(self.q0) == 1

    def start(self) -> Block:
        self.sim.reset(self.q0)
        if hasattr(self.operator, "reset"):
            self.operator.reset()  # a stateful operator (a human arm) starts afresh
        if self.operator is not None:
            self.sim.set_external_torque(self._on_axis(self.operator) if self._guided() else self.operator)
        if self.program is not None and not self._guided():  # guided: the program goes out with each cycle
            self.sim.follow(self.program)
        self._t_start = float(self.sim.t)
        h = self.sim.cfg.sample_time
        b = self.sim.advance(h)
        for _ in range(8):  # a sample due later than one interval (the KRC's timing jitter): wait for it
            if len(b["time"]):
                break
            b = self.sim.advance(h / 4)
        return self._block(b)

    def _on_axis(self, op: Any) -> Any:
        """One axis's external torque as the six-axis simulator's vector.

        An operator with a hand of its own mass (``hand_inertia()``, a :class:`~kukaid.sim.human.HumanArm`)
        has the simulator carry that inertia on the axis (``plant_inertia``): its differenced, held
        ``-I qdd`` reaction is unstable on a link lighter than the hand (the KR 6's A3)."""
        j, n = self.axis - 1, self.q0.size

        def vec(t: float, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
            out = np.zeros(n)
            out[j] = op(t, q[j], qd[j]) if callable(op) else float(op)
            return out

        if callable(getattr(op, "hand_inertia", None)) and hasattr(op, "plant_inertia"):
            op.plant_inertia = True

            def inertia() -> np.ndarray:
                out = np.zeros(n)
                out[j] = op.hand_inertia()
                return out
            vec.inertia = inertia  # type: ignore[attr-defined]
        return vec

    def _others(self, t: float) -> np.ndarray:
        """Where the program puts every axis at time ``t`` (s; the start position without one)."""
        p = self.program
        if p is None:
            return self.q0.copy()
        tt = np.asarray(p.t, float) - float(np.asarray(p.t)[0]) + self._t_start
        q = np.asarray(p.q, float).reshape(tt.size, -1)
        return np.array([np.interp(t, tt, q[:, j]) for j in range(q.shape[1])])

    def _block(self, b: dict) -> Block:
        te = b.get("tau_ext_true")
        if np.ndim(b["q"]) == 2:  # several axes: the guided one's samples, or the channels only
            if not self._guided():
                return Block((), channels=b)
            j = self.axis - 1
            return Block((Sample(float(t), float(q[j]), float(tau[j]),
                                 float(te[i, j]) if te is not None else float("nan"), q.copy(), tau.copy())
                          for i, (t, q, tau) in enumerate(zip(b["time"], b["q"], b["tau"]))), channels=b)
        return Block((Sample(float(t), float(q), float(tau), float(te[i]) if te is not None else float("nan"))
                      for i, (t, q, tau) in enumerate(zip(b["time"], b["q"], b["tau"]))), channels=b)

    def now(self) -> float:
        return float(self.sim.t)

    def cycle(self, q_cmd: float | None, dt: float) -> Block:
        if q_cmd is not None and self._guided():
            full = self._others(self.sim.t + dt)
            full[self.axis - 1] = q_cmd
            q_cmd = full
        if q_cmd is not None:
            self.sim.command(q_cmd)
        return self._block(self.sim.advance(dt))

    def hold(self) -> None:
        pass  # the simulator's interpolator holds the last setpoint

    def close(self) -> None:
        pass
