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
    """

    name = "sim"

    def __init__(self, sim: Any, q0: float,
                 operator: Callable[[float, float, float], float] | float | None = None, program: Any = None) -> None:
        self.sim = sim
        self.q0 = float(q0) if np.ndim(q0) == 0 else np.asarray(q0, dtype=float)
        self.operator = operator
        self.program = program

    def start(self) -> Block:
        self.sim.reset(self.q0)
        if hasattr(self.operator, "reset"):
            self.operator.reset()  # a stateful operator (a human arm) starts afresh
        if self.operator is not None:
            self.sim.set_external_torque(self.operator)
        if self.program is not None:
            self.sim.follow(self.program)
        return self._block(self.sim.advance(self.sim.cfg.sample_time))

    @staticmethod
    def _block(b: dict) -> Block:
        te = b.get("tau_ext_true")
        if np.ndim(b["q"]) == 2:  # several axes: the channels only
            return Block((), channels=b)
        return Block((Sample(float(t), float(q), float(tau), float(te[i]) if te is not None else float("nan"))
                      for i, (t, q, tau) in enumerate(zip(b["time"], b["q"], b["tau"]))), channels=b)

    def now(self) -> float:
        return float(self.sim.t)

    def cycle(self, q_cmd: float | None, dt: float) -> Block:
        if q_cmd is not None:
            self.sim.command(q_cmd)
        return self._block(self.sim.advance(dt))

    def hold(self) -> None:
        pass  # the simulator's interpolator holds the last setpoint

    def close(self) -> None:
        pass
