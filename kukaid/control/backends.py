"""Where the admittance loop reads measurements and sends its reference.

A backend has ``start() -> list[Sample]`` (measurements so far, the robot standing),
``cycle(q_cmd, dt) -> list[Sample]`` (send the reference, let ``dt`` s pass, return the new
measurements), ``now()`` (s, the backend's clock), ``hold()`` (stop motion: keep the last
reference) and ``close()``.

* :class:`SimBackend` — the virtual KR C4 (default), with an optional simulated operator.
* :class:`KvpBackend` — a KR C4 through KUKAVARPROXY: writes the reference angle (degrees) to the
  global REAL variable ``KID_TGT`` that a KRL program follows, reads ``$AXIS_ACT_MEAS`` and
  ``$TORQUE_AXIS_ACT[axis]``.  Only reachable through the CLI's ``--backend kvp --enable-motion``
  with bounds (see :func:`kukaid.control.safety.check_motion_allowed`).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any, Callable

from kukaid.errors import ControllerError


@dataclass(frozen=True)
class Sample:
    """One measurement: ``t`` s (backend clock), ``q`` rad, ``tau`` N·m, ``tau_ext_true`` N·m (NaN unknown)."""

    t: float
    q: float
    tau: float
    tau_ext_true: float = math.nan


class SimBackend:
    """The virtual KR C4 with an external torque (operator) ``fn(t, q, qd)``."""

    name = "sim"

    def __init__(self, sim: Any, q0: float, operator: Callable[[float, float, float], float] | float | None = None) -> None:
        self.sim = sim
        self.q0 = float(q0)
        self.operator = operator

    def start(self) -> list[Sample]:
        self.sim.reset(self.q0)
        if self.operator is not None:
            self.sim.set_external_torque(self.operator)
        return self._samples(self.sim.advance(self.sim.cfg.sample_time))

    @staticmethod
    def _samples(b: dict) -> list[Sample]:
        return [Sample(float(t), float(q), float(tau), float(te))
                for t, q, tau, te in zip(b["time"], b["q"], b["tau"], b["tau_ext_true"])]

    def now(self) -> float:
        return float(self.sim.t)

    def cycle(self, q_cmd: float, dt: float) -> list[Sample]:
        self.sim.command(q_cmd)
        return self._samples(self.sim.advance(dt))

    def hold(self) -> None:
        pass  # the simulator's interpolator holds the last setpoint

    def close(self) -> None:
        pass


class KvpBackend:
    """A KR C4 over KUKAVARPROXY (``client`` a connected :class:`kukaid.io.kvp.KvpClient`).

    The KRL side must run a program that follows ``target`` (global REAL, degrees) with its own
    position control (e.g. a loop of short PTP/SPLINE moves, or an RSI/interrupt-driven follower),
    within the robot's software limit switches.  Timestamps are the host's monotonic clock at the
    moment a reading returned.
    """

    name = "kvp"

    def __init__(self, client: Any, axis: int = 3, target: str = "KID_TGT") -> None:
        self.client = client
        self.axis = int(axis)
        self.target = target
        self._t0 = time.monotonic()
        self._last_cmd: float | None = None

    def now(self) -> float:
        return time.monotonic() - self._t0

    def _read(self) -> list[Sample]:
        try:
            q_deg = self.client.read_axis("$AXIS_ACT_MEAS")[f"A{self.axis}"]
            tau = self.client.read_real(f"$TORQUE_AXIS_ACT[{self.axis}]")
        except ControllerError:
            return []  # a missing reading: the watchdog decides
        return [Sample(self.now(), math.radians(q_deg), tau)]

    def start(self) -> list[Sample]:
        s = self._read()
        if not s:
            raise ControllerError("kvp: cannot read $AXIS_ACT_MEAS / $TORQUE_AXIS_ACT at start")
        # start by commanding where the axis stands, so the follower does not jump
        self._write(s[-1].q)
        return s

    def _write(self, q: float) -> None:
        from kukaid.io.kvp import format_real

        self.client.write(self.target, format_real(math.degrees(q), 6))
        self._last_cmd = q

    def cycle(self, q_cmd: float, dt: float) -> list[Sample]:
        t_next = self.now() + dt
        self._write(q_cmd)
        out = self._read()
        wait = t_next - self.now()
        if wait > 0:
            time.sleep(wait)
        return out

    def hold(self) -> None:
        if self._last_cmd is not None:
            try:
                self._write(self._last_cmd)
            except ControllerError:
                pass

    def close(self) -> None:
        self.hold()
