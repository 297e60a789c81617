"""A continuous position profile built from segments, sampled at the IPO rate; shared option checks."""
from __future__ import annotations

import math
from typing import Any, Callable

import numpy as np

from kukaid.errors import TrajectoryError
from kukaid.models.limits import AxisLimits

from kukaid.excite.trajectory import IPO_DT, Trajectory


# ---------------------------------------------------------------------------------------------
# Piecewise path builder
# ---------------------------------------------------------------------------------------------
class _Path:
    """A continuous position profile built from segments, sampled at the IPO rate."""

    def __init__(self, q0: float) -> None:
        self.segs: list[tuple[float, float, Callable[[np.ndarray], np.ndarray]]] = []
        self.t = 0.0
        self.q = float(q0)

    def _add(self, T: float, fn: Callable[[np.ndarray], np.ndarray], q_end: float) -> None:
        if T <= 0:
            return
        self.segs.append((self.t, T, fn))
        self.t += T
        self.q = float(q_end)

    def hold(self, T: float) -> None:
        q = self.q
        self._add(T, lambda tau: np.full_like(tau, q), q)

    def move(self, q1: float, v: float, a: float, t_ramp_min: float = 0.2) -> tuple[float, float, float] | None:
        """Move to ``q1`` with cruise speed ``v`` and cosine ramps of peak acceleration <= ``a``.

        Returns (t_start, t_end, velocity) of the constant-velocity part, or None if the move is
        too short to reach ``v`` (then a cycloidal rest-to-rest profile is used).
        """
        q0 = self.q
        D = abs(q1 - q0)
        if D == 0:
            return None
        s = 1.0 if q1 > q0 else -1.0
        Ta = max(t_ramp_min, math.pi * v / (2 * a))
        if D >= v * Ta:
            Tc = (D - v * Ta) / v
            ramp = v * Ta / 2

            def fn(tau: np.ndarray) -> np.ndarray:
                x = np.empty_like(tau)
                m1 = tau < Ta
                m2 = (~m1) & (tau < Ta + Tc)
                m3 = ~(m1 | m2)
                u = tau[m1]
                x[m1] = v * (u / 2 - Ta / (2 * math.pi) * np.sin(math.pi * u / Ta))
                x[m2] = ramp + v * (tau[m2] - Ta)
                u = tau[m3] - Ta - Tc
                x[m3] = ramp + v * Tc + v / 2 * (u + Ta / math.pi * np.sin(math.pi * u / Ta))
                return q0 + s * np.minimum(x, D)

            t0 = self.t
            self._add(2 * Ta + Tc, fn, q1)
            return (t0 + Ta, t0 + Ta + Tc, s * v)
        self.cycloid(q1, max(2 * t_ramp_min, math.sqrt(2 * math.pi * D / a), 2 * D / v))
        return None

    def cycloid(self, q1: float, T: float) -> None:
        """Rest-to-rest move to ``q1`` in ``T`` s (velocity 1-cos: peak 2D/T, peak acceleration 2πD/T²)."""
        q0 = self.q
        D = q1 - q0
        self._add(T, lambda tau: q0 + D * (tau / T - np.sin(2 * math.pi * tau / T) / (2 * math.pi)), q1)

    def curve(self, T: float, fn: Callable[[np.ndarray], np.ndarray]) -> None:
        """A segment ``q = fn(tau)``, tau in [0, T]; ``fn(0)`` must equal the current position."""
        self._add(T, fn, float(fn(np.array([T]))[0]))

    def sample(self, dt: float = IPO_DT, tail: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """Sample at ``dt``; the last position is held so the trajectory ends on a sample."""
        if tail > 0:
            self.hold(tail)
        n = int(math.ceil(self.t / dt - 1e-9)) + 1
        t = np.arange(n) * dt
        q = np.full(n, self.q)
        starts = np.array([s[0] for s in self.segs])
        k = np.searchsorted(starts, t, side="right") - 1
        for j, (t0, T, fn) in enumerate(self.segs):
            m = (k == j) & (t <= t0 + T)
            if np.any(m):
                q[m] = fn(t[m] - t0)
        return t, q


def _num(name: str, v: Any, lo: float = 0.0, hi: float = math.inf, lo_open: bool = True) -> float:
    """Validate a numeric generator option: finite, within (lo, hi]."""
    try:
        x = float(v)
    except (TypeError, ValueError):
        raise TrajectoryError(f"option {name}: must be a number, got {v!r}") from None
    bad = not math.isfinite(x) or x > hi or (x <= lo if lo_open else x < lo)
    if bad:
        lo_s = f"> {lo:g}" if lo_open else f">= {lo:g}"
        hi_s = f" and <= {hi:g}" if hi != math.inf else ""
        raise TrajectoryError(f"option {name}: must be {lo_s}{hi_s}, got {v!r}")
    return x


def _centre(centre: float | None, limits: AxisLimits) -> float:
    return 0.5 * (limits.q_min + limits.q_max) if centre is None else float(centre)


def _finish(path: _Path, kind: str, axis: int, params: dict[str, Any], limits: AxisLimits | None,
            dt: float, tail: float) -> Trajectory:
    t, q = path.sample(dt, tail=tail)
    traj = Trajectory(t=t, q=q, axis=axis, kind=kind, params=params,
                      limits=limits.to_dict() if limits is not None else None)
    if limits is not None:
        limits.check(traj)
    return traj
