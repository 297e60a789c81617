"""A KR C4 over KUKAVARPROXY as a :class:`~kukaid.robot.interface.Robot`: the reference angle goes
to the global REAL ``KID_TGT`` that the KRL follower program (``kukaid krl-follower``) follows, with
a heartbeat; ``$AXIS_ACT_MEAS`` and ``$TORQUE_AXIS_ACT[axis]`` come back.  Only reachable through
the CLI's ``--backend kvp --enable-motion`` with bounds (see
:func:`kukaid.control.safety.check_motion_allowed`).  The socket is the client's
(:class:`kukaid.krc.kvp.KvpClient`): this module opens none."""
from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from kukaid.errors import ControllerError
from kukaid.robot.interface import Block, Sample


#: every this many cycles (about 0.1 s at 12 ms) :meth:`KvpRobot.cycle` reads the follower's ``KID_STOP``
FOLLOWER_CHECK = 8


class KvpRobot:
    """A KR C4 over KUKAVARPROXY (``client`` a connected :class:`kukaid.krc.kvp.KvpClient`), with the
    KRL follower program of :mod:`kukaid.krc.krl_follower` running on the controller.

    Every cycle writes the reference (``KID_TGT``, degrees) and the heartbeat (``KID_HB``), then
    reads ``$AXIS_ACT_MEAS`` and ``$TORQUE_AXIS_ACT[axis]``; :meth:`start` enables the follower
    (``KID_RUN`` TRUE) once the first target is where the axis stands, :meth:`hold` disables it.
    Nothing else on the robot is written.  Every :data:`FOLLOWER_CHECK` cycles ``KID_STOP`` is read: a
    follower program that stopped by itself (its heartbeat watchdog) ends the run with a
    :class:`ControllerError` instead of guiding a reference the axis no longer follows.

    The controller updates both variables once per interpolation cycle (``sample_time``, 12 ms)
    and the PC's cycle is not locked to it: a reading identical to the previous one is the same
    controller sample read again and is dropped (so a controller that stops updating looks stale
    to the watchdog) and the cycle is moved a quarter sample later, away from the controller's
    sample boundary; timestamps are the host's monotonic clock snapped to the controller's
    sample grid, so the estimator differentiates over whole sample intervals rather than over
    network jitter.

    ``n_axes`` > 0 (a robot model): every cycle also reads ``$TORQUE_AXIS_ACT[1..n_axes]``, and the
    samples carry the positions (from the same ``$AXIS_ACT_MEAS``) and torques of A1..A``n_axes``
    in ``q_all``, ``tau_all``.
    """

    name = "kvp"

    def __init__(self, client: Any, axis: int = 3, target: str = "KID_TGT", heartbeat: str = "KID_HB",
                 run: str = "KID_RUN", stop: str = "KID_STOP", sample_time: float = 0.012, n_axes: int = 0,
                 window: tuple[float, float] | None = None) -> None:
        self.client = client
        #: the position window (rad) the axis must stand in for :meth:`start` to switch the follower on
        self.window = window
        self.axis = int(axis)
        self.n_axes = int(n_axes)
        self.target, self.heartbeat, self.run, self.stop = target, heartbeat, run, stop
        self.sample_time = float(sample_time)
        self._t0 = time.monotonic()
        self._beat = 0
        self._enabled = False
        self._last: Sample | None = None
        self._k: int | None = None
        self._repeats = 0  # readings that repeated the previous controller sample
        self._t_next: float | None = None
        self._cycles = 0  # cycles since start(), for the follower check every FOLLOWER_CHECK cycles

    def now(self) -> float:
        return time.monotonic() - self._t0

    def _read(self) -> Block:
        q_all = tau_all = None
        try:
            e6 = self.client.read_axis("$AXIS_ACT_MEAS")
            q_deg = e6[f"A{self.axis}"]
            if self.n_axes:
                q_all = np.radians([e6[f"A{j}"] for j in range(1, self.n_axes + 1)])
                tau_all = np.array([self.client.read_real(f"$TORQUE_AXIS_ACT[{j}]")
                                    for j in range(1, self.n_axes + 1)])
                tau = float(tau_all[self.axis - 1])
            else:
                tau = self.client.read_real(f"$TORQUE_AXIS_ACT[{self.axis}]")
        except (ControllerError, KeyError):
            return Block()  # a missing reading: the watchdog decides
        q = math.radians(q_deg)
        prev = self._last
        if prev is not None and q == prev.q and tau == prev.tau and (
                q_all is None or (np.array_equal(q_all, prev.q_all) and np.array_equal(tau_all, prev.tau_all))):
            self._repeats += 1
            return Block()  # the same controller sample again
        k = round(self.now() / self.sample_time)  # the controller's sample count
        if self._k is not None and k <= self._k:
            k = self._k + 1
        self._k = k
        self._last = Sample(k * self.sample_time, q, tau, math.nan, q_all, tau_all)
        return Block([self._last])

    def soft_limits(self) -> tuple[float, float] | None:
        """The axis's software limit switches, ``$SOFTN_END[axis]`` and ``$SOFTP_END[axis]`` (degrees on the
        KRC), in rad; None when the controller does not give them (a lost connection is an error)."""
        from kukaid.krc.kvp import KvpValueError, KvpVariableError

        try:
            lo = self.client.read_real(f"$SOFTN_END[{self.axis}]")
            hi = self.client.read_real(f"$SOFTP_END[{self.axis}]")
        except (KvpVariableError, KvpValueError):
            return None
        return (math.radians(lo), math.radians(hi)) if lo < hi else None

    def _send(self, q: float) -> None:
        from kukaid.krc.kvp import format_real

        self.client.write(self.target, format_real(math.degrees(q), 6))
        self._beat = (self._beat + 1) % 30000
        self.client.write(self.heartbeat, str(self._beat))

    def start(self) -> Block:
        s = self._read()
        if not s:
            raise ControllerError("kvp: cannot read $AXIS_ACT_MEAS / $TORQUE_AXIS_ACT at start")
        q = s[-1].q
        if self.window is not None and not self.window[0] <= q <= self.window[1]:
            # the follower would clamp its first target (where the axis stands) into the window, and drive there
            raise ControllerError(f"kvp: A{self.axis} stands at {math.degrees(q):.4g} degrees, outside the window "
                                  f"[{math.degrees(self.window[0]):.4g}, {math.degrees(self.window[1]):.4g}] degrees: "
                                  "nothing switched on; move it inside the window first")
        from kukaid.krc.kvp import KvpVariableError

        try:
            self._send(s[-1].q)  # the first target is where the axis stands: the follower does not jump
            self.client.write(self.run, "TRUE")
        except KvpVariableError as e:  # the follower's globals are not there: nothing was switched on
            raise ControllerError(f"kvp: {e}: the controller has no global {self.target}, {self.heartbeat} and "
                                  f"{self.run} to write; install and start the KRL follower program (kukaid "
                                  "krl-follower; on a virtual KR C4: serve-sim --follower)") from None
        self._enabled = True
        return s

    def cycle(self, q_cmd: float | None, dt: float) -> Block:
        # cycles on a fixed grid (not "dt after the last one"), so the PC's mean period is dt and
        # does not drift against the controller's sample clock; a late cycle resynchronises
        now = self.now()
        nxt = (self._t_next if self._t_next is not None else now) + dt
        self._t_next = nxt if nxt > now else now + dt
        if q_cmd is not None:
            self._send(q_cmd)
        self._cycles += 1
        if self._enabled and self._cycles % FOLLOWER_CHECK == 0:
            self._check_follower()
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

    def _check_follower(self) -> None:
        """Raise :class:`ControllerError` when the KRL follower program has stopped (``KID_STOP`` not 0: its
        heartbeat watchdog, the axis outside its window at its start, or a stop left from an earlier run
        of a program not started again): the axis no longer follows the reference.  A reading that fails
        is left to the measurement watchdog."""
        from kukaid.krc.krl_follower import STOP_BY_PC, STOP_OUTSIDE, STOP_STALE

        try:
            code = self.client.read_int(self.stop)
        except ControllerError:  # the link, or a reply that is no INT (KvpError): the watchdog's to judge
            return
        if code == 0:
            return
        why = {STOP_STALE: "its heartbeat watchdog found KID_HB stale (krl-follower --stale-ms)",
               STOP_OUTSIDE: "it found the axis outside its own window when it started",
               STOP_BY_PC: "it was stopped by the PC (a stop left from an earlier run: start the program again)"}
        self._enabled = False  # nothing to switch off: the program ended
        raise ControllerError(f"kvp: the KRL follower program has stopped ({self.stop} {code}: "
                              f"{why.get(code, 'an unknown reason')}), so A{self.axis} no longer follows the "
                              "reference; start the program again before the next run")

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
