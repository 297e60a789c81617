"""Safety of the admittance loop: every reference that can move a robot is bounded and watched.

* :class:`SafetyLimits` — position window (rad), velocity (rad/s), acceleration (rad/s²) limits on
  the reference, the largest external torque Γr (N·m: the model's torque minus the measured one) and the
  largest age of a measurement (s) the loop may act on.
* :class:`ReferenceLimiter` — clips a new reference to the window and to the velocity and
  acceleration limits relative to the previous reference (so a step never reaches the robot).
* :class:`Watchdog` — a stale or missing measurement (older than ``max_age``) stops motion: the
  loop then holds the last reference and ends.
* :func:`check_motion_allowed` — the real-robot path (KUKAVARPROXY) is off unless explicitly
  enabled with bounds.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from kukaid.errors import KukaidError, LimitError

#: the oldest latest measurement (s) any setting lets the loop act on (``max_age``): a larger one let a
#: KUKAVARPROXY link at 1.2 s a reply move the robot on measurements that old (new-user trial 18)
MAX_AGE_LIMIT = 1.0

def _deg(q: float) -> str:
    """An angle in rad as the user gives it (degrees), rounded: 0.5235987 -> '30'."""
    return f"{math.degrees(q):.4g}"


@dataclass(frozen=True)
class SafetyLimits:
    """Bounds on the admittance reference (SI).

    q_min, q_max : position window, rad (errors name it in degrees, the unit of the options).   qd_max : reference speed limit, rad/s.
    qdd_max : reference acceleration limit, rad/s².
    tau_max : largest external torque |Γr|, N·m (the model's torque minus the measured one: what a person
        or an obstacle exerts, not the gravity load or the other axes' motion): beyond it motion stops (a
        collision, a jammed axis, a push too hard or a model far off; the KRC's own torque monitoring and
        collision detection stay in force).
    max_age : largest age of the latest measurement, s, before motion stops.
    """

    q_min: float = -math.inf
    q_max: float = math.inf
    qd_max: float = 0.5
    qdd_max: float = 5.0
    tau_max: float = 100.0
    max_age: float = 0.1

    def __post_init__(self) -> None:
        for name in ("qd_max", "qdd_max", "tau_max", "max_age"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise LimitError(f"safety: {name} = {v} must be a finite number > 0")
        if self.max_age > MAX_AGE_LIMIT:
            raise LimitError(f"safety: max_age = {self.max_age:g} s is above {MAX_AGE_LIMIT:g} s: the loop would move "
                             "the robot on measurements that old (every 12-24 ms it acts on the latest one)")
        if math.isnan(self.q_min) or math.isnan(self.q_max) or not self.q_min < self.q_max:
            raise LimitError(f"safety: position window [{_deg(self.q_min)}, {_deg(self.q_max)}] degrees must have "
                             "q_min < q_max")

    @property
    def bounded(self) -> bool:
        """True when the position window is finite (required for a real robot)."""
        return math.isfinite(self.q_min) and math.isfinite(self.q_max)


class ReferenceLimiter:
    """Clip successive references (one per cycle of ``dt`` s) to :class:`SafetyLimits`."""

    def __init__(self, limits: SafetyLimits, dt: float, q0: float) -> None:
        if not (dt > 0 and math.isfinite(dt)):
            raise LimitError(f"safety: cycle time must be > 0 s, got {dt}")
        if not limits.q_min <= q0 <= limits.q_max:
            raise LimitError(f"safety: start position {_deg(q0)} degrees is outside the window "
                             f"[{_deg(limits.q_min)}, {_deg(limits.q_max)}] degrees")
        self.limits, self.dt = limits, float(dt)
        self.q = float(q0)
        self.v = 0.0
        self.clipped = 0  # number of references changed by the limiter

    def apply(self, q_ref: float) -> tuple[float, bool]:
        """The bounded reference for this cycle and whether it was clipped."""
        q_ref = float(q_ref)
        if not math.isfinite(q_ref):
            raise LimitError(f"safety: reference {q_ref} is not a finite angle")
        L, h = self.limits, self.dt
        v = (q_ref - self.q) / h
        v_c = min(max(v, max(-L.qd_max, self.v - L.qdd_max * h)), min(L.qd_max, self.v + L.qdd_max * h))
        # the window has priority: never approach an edge faster than qdd_max can brake before it
        room_hi = max(L.q_max - self.q, 0.0)
        room_lo = max(self.q - L.q_min, 0.0)
        v_c = min(v_c, math.sqrt(2.0 * L.qdd_max * room_hi), room_hi / h)
        v_c = max(v_c, -math.sqrt(2.0 * L.qdd_max * room_lo), -room_lo / h)
        q_new = min(max(self.q + v_c * h, L.q_min), L.q_max)
        clipped = abs(q_new - q_ref) > 1e-12
        self.v = (q_new - self.q) / h
        self.q = q_new
        self.clipped += int(clipped)
        return q_new, clipped


class Watchdog:
    """Motion stops when the latest measurement is older than ``max_age`` s (or missing)."""

    def __init__(self, max_age: float) -> None:
        if not (max_age > 0 and math.isfinite(max_age)):
            raise LimitError(f"safety: max_age must be > 0 s, got {max_age}")
        self.max_age = float(max_age)
        self.t_last: float | None = None
        self.tripped: str | None = None

    def feed(self, t_measurement: float) -> None:
        self.t_last = float(t_measurement)

    def check(self, now: float) -> bool:
        """True while measurements are fresh; once it trips it stays tripped (``tripped`` says why)."""
        if self.tripped:
            return False
        if self.t_last is None:
            self.tripped = f"no measurement by t = {now:.3f} s"
        elif now - self.t_last > self.max_age:
            self.tripped = (f"measurement stale: {1000 * (now - self.t_last):.0f} ms old at t = {now:.3f} s "
                            f"(limit {1000 * self.max_age:.0f} ms)")
        return self.tripped is None


def check_motion_allowed(backend: str, enable_motion: bool, limits: SafetyLimits | None) -> None:
    """Refuse to move a real robot unless asked explicitly and bounded.

    ``backend`` "sim" always passes; "kvp" needs ``enable_motion`` and a finite position window.
    """
    if backend == "sim":
        return
    if backend != "kvp":
        raise KukaidError(f"run-admittance: unknown backend {backend!r} (sim or kvp)")
    if not enable_motion:
        raise KukaidError("run-admittance: refusing to move a real robot: --backend kvp needs --enable-motion "
                          "and bounds (--q-min/--q-max, --qd-max); check the KRL program that follows KID_TGT first")
    if limits is None or not limits.bounded:
        raise KukaidError("run-admittance: --backend kvp --enable-motion needs a finite position window "
                          "(--q-min and --q-max, degrees)")
