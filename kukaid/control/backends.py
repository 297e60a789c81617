"""Where the admittance loop reads measurements and sends its reference.

A backend has ``start() -> list[Sample]`` (measurements so far, the robot standing),
``cycle(q_cmd, dt) -> list[Sample]`` (send the reference, let ``dt`` s pass, return the new
measurements), ``now()`` (s, the backend's clock), ``hold()`` (stop motion: keep the last
reference) and ``close()``.

* :class:`SimBackend` — the virtual KR C4 (default), with an optional simulated operator.
* :class:`KvpBackend` — a KR C4 through KUKAVARPROXY: writes the reference angle (degrees) to the
  global REAL variable ``KID_TGT`` that the KRL follower program (``kukaid krl-follower``)
  follows, with a heartbeat, and reads ``$AXIS_ACT_MEAS`` and ``$TORQUE_AXIS_ACT[axis]``.  Only
  reachable through the CLI's ``--backend kvp --enable-motion`` with bounds (see
  :func:`kukaid.control.safety.check_motion_allowed`).
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
        if hasattr(self.operator, "reset"):
            self.operator.reset()  # a stateful operator (a human arm) starts afresh
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
    """A KR C4 over KUKAVARPROXY (``client`` a connected :class:`kukaid.io.kvp.KvpClient`), with the
    KRL follower program of :mod:`kukaid.io.krl_follower` running on the controller.

    Every cycle writes the reference (``KID_TGT``, degrees) and the heartbeat (``KID_HB``), then
    reads ``$AXIS_ACT_MEAS`` and ``$TORQUE_AXIS_ACT[axis]``; :meth:`start` enables the follower
    (``KID_RUN`` TRUE) once the first target is where the axis stands, :meth:`hold` disables it.
    Nothing else on the robot is written.

    The controller updates both variables once per interpolation cycle (``sample_time``, 12 ms)
    and the PC's cycle is not locked to it: a reading identical to the previous one is the same
    controller sample read again and is dropped (so a controller that stops updating looks stale
    to the watchdog) and the cycle is moved a quarter sample later, away from the controller's
    sample boundary; timestamps are the host's monotonic clock snapped to the controller's
    sample grid, so the estimator differentiates over whole sample intervals rather than over
    network jitter.
    """

    name = "kvp"

    def __init__(self, client: Any, axis: int = 3, target: str = "KID_TGT", heartbeat: str = "KID_HB",
                 run: str = "KID_RUN", sample_time: float = 0.012) -> None:
        self.client = client
        self.axis = int(axis)
        self.target, self.heartbeat, self.run = target, heartbeat, run
        self.sample_time = float(sample_time)
        self._t0 = time.monotonic()
        self._beat = 0
        self._enabled = False
        self._last: Sample | None = None
        self._k: int | None = None
        self._repeats = 0  # readings that repeated the previous controller sample
        self._t_next: float | None = None

    def now(self) -> float:
        return time.monotonic() - self._t0

    def _read(self) -> list[Sample]:
        try:
            q_deg = self.client.read_axis("$AXIS_ACT_MEAS")[f"A{self.axis}"]
            tau = self.client.read_real(f"$TORQUE_AXIS_ACT[{self.axis}]")
        except ControllerError:
            return []  # a missing reading: the watchdog decides
        q = math.radians(q_deg)
        prev = self._last
        if prev is not None and q == prev.q and tau == prev.tau:
            self._repeats += 1
            return []  # the same controller sample again
        k = round(self.now() / self.sample_time)  # the controller's sample count
        if self._k is not None and k <= self._k:
            k = self._k + 1
        self._k = k
        self._last = Sample(k * self.sample_time, q, tau)
        return [self._last]

    def _send(self, q: float) -> None:
        from kukaid.io.kvp import format_real

        self.client.write(self.target, format_real(math.degrees(q), 6))
        self._beat = (self._beat + 1) % 30000
        self.client.write(self.heartbeat, str(self._beat))

    def start(self) -> list[Sample]:
        s = self._read()
        if not s:
            raise ControllerError("kvp: cannot read $AXIS_ACT_MEAS / $TORQUE_AXIS_ACT at start")
        self._send(s[-1].q)  # the first target is where the axis stands: the follower does not jump
        self.client.write(self.run, "TRUE")
        self._enabled = True
        return s

    def cycle(self, q_cmd: float, dt: float) -> list[Sample]:
        # cycles on a fixed grid (not "dt after the last one"), so the PC's mean period is dt and
        # does not drift against the controller's sample clock; a late cycle resynchronises
        now = self.now()
        nxt = (self._t_next if self._t_next is not None else now) + dt
        self._t_next = nxt if nxt > now else now + dt
        self._send(q_cmd)
        repeats = self._repeats
        out = self._read()
        if self._repeats > repeats:
            # read just before the controller's next sample: move the cycle a quarter sample later,
            # away from the sample boundary, so reads do not alternate between a repeat and a skip
            self._t_next += self.sample_time / 4
        wait = self._t_next - self.now()
        if wait > 0:
            time.sleep(wait)
        return out

    def hold(self) -> None:
        """Stop the follower (``KID_RUN`` FALSE); if that write fails too, the follower's own
        heartbeat watchdog stops the axis."""
        if self._enabled:
            try:
                self.client.write(self.run, "FALSE")
                self._enabled = False
            except ControllerError:
                pass

    def close(self) -> None:
        self.hold()
        self.client.close()
