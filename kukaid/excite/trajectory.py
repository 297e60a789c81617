"""Excitation trajectories of the paper's experiments, as a KR C4 can execute them.

A :class:`Trajectory` is the commanded position ``q`` (rad) of one axis, sampled at the KR C4
interpolation (IPO) rate of 12 ms, with the experiment's parameters.  Four generators build the
experiments of Yao et al. 2018:

``friction``
    Constant-velocity moves in both directions over the same position window, at a list of
    speeds (eqs. 2-4: Γf = (Γ+ - Γ-)/2 at equal q).  Cosine velocity ramps (continuous
    acceleration, bounded jerk) and a settle time at standstill between moves.  Slow speeds use
    a shorter window so that every plateau lasts about ``plateau`` seconds; the plateau times
    are recorded in ``params["plateaus"]``.
``inertia``
    A sine (default period 4 s, at least 3 full periods) whose amplitude is ramped in and out
    with a raised-cosine envelope (section 2.2, eqs. 6-8).
``presliding``
    The initiation stage of section 3.4: a small move (about 1 degree) and a standstill (the
    virtual KR C4 adds ambient vibration from axis 6), then a few quasi-static reversals of
    decreasing amplitude around the stop position.  The reversals are slower than qd_thr and
    larger than the Maxwell-slip saturation displacements W/k (2e-4 rad for the paper's
    elements) at first, smaller later, so the torque traces nested hysteresis loops with
    nonlocal memory: what a Maxwell-slip fit (eqs. 9-10) needs.
``validation``
    A mixed trajectory: a multi-sine (Schroeder phases, ramped) followed by point-to-point moves
    of different speeds and sizes with standstill between them (mode switches).

Every generator checks the result against :class:`AxisLimits` (A3 of a KR 6 R700 sixx unless
told otherwise) and raises :class:`~kukaid.errors.LimitError` naming the limit, the value and
the time.  Everything here is SI (rad, rad/s, rad/s², s).
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from kukaid import __version__
from kukaid.errors import TrajectoryError
from kukaid.models.limits import AxisLimits
from kukaid.atomic import write_text_atomic
from kukaid.jsonfile import read_json

#: KR C4 interpolation cycle (IPO), s.
IPO_DT = 0.012
SCHEMA = "kukaid.trajectory/1"
#: longest trajectory accepted, s
MAX_DURATION = 86400.0
KINDS = ("friction", "inertia", "presliding", "validation")
_DEG = math.pi / 180.0


# ---------------------------------------------------------------------------------------------
# Trajectory value
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Trajectory:
    """Commanded position of one axis at the IPO rate.

    Parameters
    ----------
    t : (N,) array, s, uniformly spaced (0.012 s for the KR C4), strictly increasing.
    q : (N,) array, rad, commanded axis position.
    axis : axis number, KUKA numbering (default 3).
    kind : experiment kind ("friction", "inertia", "presliding", "validation" or another name).
    params : the experiment's parameters (JSON-able), SI units.
    limits : the limits the trajectory was checked against (dict, see :class:`AxisLimits`), or None.
    """

    t: np.ndarray
    q: np.ndarray
    axis: int = 3
    kind: str = "custom"
    params: dict[str, Any] = field(default_factory=dict)
    limits: dict[str, Any] | None = None

    def __post_init__(self) -> None:
        t = np.asarray(self.t, dtype=float)
        q = np.asarray(self.q, dtype=float)
        _check_arrays(t, q, "trajectory")
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "q", q)
        object.__setattr__(self, "axis", int(self.axis))
        if not 1 <= self.axis <= 12:
            raise TrajectoryError(f"trajectory: axis must be 1 to 12, got {self.axis}")

    # -- derived signals ----------------------------------------------------------------------
    @property
    def dt(self) -> float:
        """Sample time, s."""
        return float(self.t[1] - self.t[0])

    @property
    def duration(self) -> float:
        """Duration, s."""
        return float(self.t[-1] - self.t[0])

    @property
    def n_samples(self) -> int:
        return int(self.t.size)

    @property
    def qd(self) -> np.ndarray:
        """Commanded velocity by central differences, rad/s."""
        return np.gradient(self.q, self.t)

    @property
    def qdd(self) -> np.ndarray:
        """Commanded acceleration by differences, rad/s²."""
        return np.gradient(self.qd, self.t)

    def __iter__(self):  # t, q = traj
        return iter((self.t, self.q))

    # -- JSON ---------------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        return {
            "schema": SCHEMA,
            "kind": self.kind,
            "axis": self.axis,
            "sample_time": self.dt,
            "duration": self.duration,
            "units": {"t": "s", "q": "rad"},
            "params": self.params,
            "limits": self.limits,
            "kukaid_version": __version__,
            "t": [float(x) for x in self.t],
            "q": [float(x) for x in self.q],
        }

    def json_text(self) -> str:
        """The trajectory file's text (``"schema": "kukaid.trajectory/1"``)."""
        return json.dumps(self.to_dict(), indent=1, allow_nan=False) + "\n"

    def to_json(self, path: str | Path) -> None:
        """Write the trajectory file atomically."""
        write_text_atomic(path, self.json_text())

    @classmethod
    def from_dict(cls, d: Any, where: str = "trajectory") -> "Trajectory":
        if not isinstance(d, dict):
            raise TrajectoryError(f"{where}: expected a JSON object at the top level")
        if d.get("schema") != SCHEMA:
            raise TrajectoryError(f"{where}: field 'schema' must be \"{SCHEMA}\", got {d.get('schema')!r}")
        for k in ("t", "q"):
            if k not in d:
                raise TrajectoryError(f"{where}: missing field '{k}'")
            if not isinstance(d[k], list) or not all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                                      for x in d[k]):
                bad = next((i for i, x in enumerate(d[k]) if not isinstance(x, (int, float)) or isinstance(x, bool)),
                           None) if isinstance(d[k], list) else None
                at = f" (element {bad}: {d[k][bad]!r})" if bad is not None else ""
                raise TrajectoryError(f"{where}: field '{k}' must be a list of numbers{at}")
        units = d.get("units", {"t": "s", "q": "rad"})
        if not isinstance(units, dict) or units.get("t", "s") != "s" or units.get("q", "rad") != "rad":
            raise TrajectoryError(f"{where}: field 'units' must be {{\"t\": \"s\", \"q\": \"rad\"}}, got {units!r}")
        axis = d.get("axis", 3)
        if not isinstance(axis, int) or isinstance(axis, bool) or not 1 <= axis <= 12:
            raise TrajectoryError(f"{where}: field 'axis' must be an integer 1 to 12, got {axis!r}")
        kind = d.get("kind", "custom")
        if not isinstance(kind, str):
            raise TrajectoryError(f"{where}: field 'kind' must be a string, got {kind!r}")
        params = d.get("params", {})
        if not isinstance(params, dict):
            raise TrajectoryError(f"{where}: field 'params' must be an object")
        limits = d.get("limits")
        if limits is not None:
            AxisLimits.from_dict(limits, where=f"{where}: field 'limits'")
        t = np.asarray(d["t"], dtype=float)
        q = np.asarray(d["q"], dtype=float)
        _check_arrays(t, q, where)
        return cls(t=t, q=q, axis=axis, kind=kind, params=params, limits=limits)

    @classmethod
    def from_json(cls, path: str | Path) -> "Trajectory":
        """Read and validate a trajectory file; one-line :class:`TrajectoryError` when malformed."""
        return cls.from_dict(read_json(path, TrajectoryError), where=str(path))


def _check_arrays(t: np.ndarray, q: np.ndarray, where: str) -> None:
    if t.ndim != 1 or q.ndim != 1:
        raise TrajectoryError(f"{where}: 't' and 'q' must be one-dimensional")
    if t.size != q.size:
        raise TrajectoryError(f"{where}: 't' has {t.size} samples but 'q' has {q.size}")
    if t.size < 2:
        raise TrajectoryError(f"{where}: too few samples ({t.size}); a trajectory needs at least 2")
    for name, x in (("t", t), ("q", q)):
        bad = np.flatnonzero(~np.isfinite(x))
        if bad.size:
            raise TrajectoryError(f"{where}: '{name}' is not a finite number at index {bad[0]}")
    dt = np.diff(t)
    bad = np.flatnonzero(dt <= 0)
    if bad.size:
        i = int(bad[0]) + 1
        raise TrajectoryError(f"{where}: 't' is not strictly increasing at index {i} ({t[i]:.6g} s after {t[i-1]:.6g} s)")
    bad = np.flatnonzero(np.abs(dt - dt[0]) > 1e-6 * max(1.0, dt[0]) + 1e-9)
    if bad.size:
        i = int(bad[0]) + 1
        raise TrajectoryError(f"{where}: 't' is not uniformly sampled at index {i} (step {dt[i-1]:.6g} s, "
                              f"expected {dt[0]:.6g} s)")
    if not 1e-4 <= dt[0] <= 1.0:
        raise TrajectoryError(f"{where}: 't' steps by {dt[0]:.6g} s; a commanded trajectory is sampled every "
                              f"0.1 ms to 1 s (the KR C4's IPO rate is 12 ms): wrong time unit?")
    if t[-1] - t[0] > MAX_DURATION:
        raise TrajectoryError(f"{where}: lasts {t[-1] - t[0]:.6g} s, more than {MAX_DURATION:.0f} s (24 h)")


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


# ---------------------------------------------------------------------------------------------
# Generators
# ---------------------------------------------------------------------------------------------
def friction(speeds: Sequence[float] | None = None, v_min: float = 0.01, v_max: float = 1.0,
             n_speeds: int = 10, centre: float | None = None, span: float = 90 * _DEG,
             plateau: float = 4.0, settle: float = 1.0, acc: float = 3.0, ramp_min: float = 0.2,
             reposition_speed: float = 0.3, cycles: int = 1, lead: float = 1.0, axis: int = 3,
             limits: AxisLimits | None = None, dt: float = IPO_DT) -> Trajectory:
    """Constant-velocity moves in both directions at several speeds (friction identification).

    Parameters
    ----------
    speeds : plateau speeds, rad/s (positive); default ``n_speeds`` log-spaced from ``v_min`` to
        ``v_max`` (0.01 to 1 rad/s: from below the Stribeck velocity to fast sliding).
    centre : centre of the position window, rad (default: middle of the axis range).
    span : widest position window, rad (the fast speeds use all of it).
    plateau : wanted duration of each constant-velocity plateau, s; slow speeds use a window
        ``speed * plateau`` wide (plus the ramps), fast ones are limited by ``span``.
    settle : standstill after each move, s.   acc : peak acceleration of the ramps, rad/s².
    ramp_min : shortest ramp, s.   reposition_speed : speed of the moves between windows, rad/s.
    cycles : back-and-forth moves per speed.   lead : standstill at the start, s.
    limits : axis limits to check (default KR 6 R700 sixx A3; None in ``limits=False`` sense is
        not allowed: pass :class:`AxisLimits`).

    Returns
    -------
    Trajectory with ``params["plateaus"]``: [t_start, t_end, velocity] of every plateau (s, rad/s).
    """
    limits = limits or AxisLimits.kr6_r700_sixx(axis)
    if speeds is None:
        v_min = _num("v_min", v_min)
        v_max = _num("v_max", v_max)
        n = int(_num("n_speeds", n_speeds, 1, 1000, lo_open=False))
        if v_max < v_min:
            raise TrajectoryError(f"option v_max: must be >= v_min ({v_min:g} rad/s), got {v_max:g}")
        speeds = list(np.geomspace(v_min, v_max, n)) if n > 1 else [v_min]
    speeds = [_num("speeds", v) for v in speeds]
    if not speeds:
        raise TrajectoryError("option speeds: give at least one speed")
    span = _num("span", span)
    plateau = _num("plateau", plateau)
    settle = _num("settle", settle, lo_open=False)
    acc = _num("acc", acc)
    ramp_min = _num("ramp_min", ramp_min, lo=dt, lo_open=False)
    reposition_speed = _num("reposition_speed", reposition_speed)
    cycles = int(_num("cycles", cycles, 1, 100, lo_open=False))
    lead = _num("lead", lead, lo_open=False)
    c = _centre(centre, limits)

    def window(v: float) -> float:
        Ta = max(ramp_min, math.pi * v / (2 * acc))
        return min(span, v * (plateau + Ta))

    path = _Path(c - window(speeds[0]) / 2)
    path.hold(lead)
    plateaus = []
    for v in speeds:
        d = window(v)
        lo, hi = c - d / 2, c + d / 2
        if abs(path.q - lo) > 1e-12:
            path.move(lo, reposition_speed, acc, ramp_min)
            path.hold(settle)
        for _ in range(cycles):
            for target in (hi, lo):
                p = path.move(target, v, acc, ramp_min)
                if p is None:
                    raise TrajectoryError(f"option speeds: {v:g} rad/s cannot be reached within the position "
                                          f"window ({d:.4g} rad) at acc = {acc:g} rad/s²; widen span or raise acc")
                plateaus.append([round(p[0], 9), round(p[1], 9), p[2]])
                path.hold(settle)
    params = {"speeds": speeds, "centre": c, "span": span, "plateau": plateau, "settle": settle, "acc": acc,
              "ramp_min": ramp_min, "reposition_speed": reposition_speed, "cycles": cycles, "lead": lead,
              "plateaus": plateaus}
    return _finish(path, "friction", axis, params, limits, dt, tail=0.0)


def inertia(period: float = 4.0, n_periods: int = 3, amplitude: float = 0.8, centre: float | None = None,
            ramp_periods: float = 1.0, lead: float = 1.0, tail: float = 1.0, axis: int = 3,
            limits: AxisLimits | None = None, dt: float = IPO_DT) -> Trajectory:
    """Sine excitation for the inertial parameters (Izz, Mx), ramped in and out.

    Parameters
    ----------
    period : s (paper: 4 s).   n_periods : full-amplitude periods (>= 3, the paper averages 3).
    amplitude : rad.   centre : rad (default: middle of the axis range).
    ramp_periods : duration of the raised-cosine ramp in and of the ramp out, in periods.
    lead, tail : standstill before and after, s.

    Returns
    -------
    Trajectory with ``params["full_amplitude"] = [t_start, t_end]`` of the full-amplitude periods.
    """
    limits = limits or AxisLimits.kr6_r700_sixx(axis)
    period = _num("period", period)
    n_periods = int(_num("n_periods", n_periods, 3, 1000, lo_open=False))
    amplitude = _num("amplitude", amplitude)
    ramp_periods = _num("ramp_periods", ramp_periods, lo_open=False)
    lead = _num("lead", lead, lo_open=False)
    tail = _num("tail", tail, lo_open=False)
    c = _centre(centre, limits)
    w = 2 * math.pi / period
    Tr = ramp_periods * period
    Tf = n_periods * period
    T = 2 * Tr + Tf

    def fn(tau: np.ndarray) -> np.ndarray:
        env = np.ones_like(tau)
        if Tr > 0:
            m = tau < Tr
            env[m] = 0.5 * (1 - np.cos(math.pi * tau[m] / Tr))
            m = tau > Tr + Tf
            env[m] = 0.5 * (1 + np.cos(math.pi * (tau[m] - Tr - Tf) / Tr))
        return c + amplitude * env * np.sin(w * tau)

    path = _Path(c)
    path.hold(lead)
    path.curve(T, fn)
    path.q = c  # sin(w T) is 0 up to rounding
    params = {"period": period, "n_periods": n_periods, "amplitude": amplitude, "centre": c,
              "ramp_periods": ramp_periods, "lead": lead, "tail": tail,
              "full_amplitude": [lead + Tr, lead + Tr + Tf]}
    return _finish(path, "inertia", axis, params, limits, dt, tail=tail)


def presliding(step: float = 1.0 * _DEG, step_time: float = 1.0, hold: float = 5.0,
               reversals: Sequence[float] = (0.03 * _DEG, 0.015 * _DEG, 0.0075 * _DEG, 0.00375 * _DEG),
               reversal_time: float = 2.0, dwell: float = 1.0, final_hold: float = 5.0,
               direction: int = 1, centre: float | None = None, lead: float = 1.0, axis: int = 3,
               limits: AxisLimits | None = None, dt: float = IPO_DT) -> Trajectory:
    """Pre-sliding experiment: initiation move, standstill, quasi-static reversals.

    Parameters
    ----------
    step : initiation move, rad (paper: about 1 degree); the move ends at ``centre``.
    step_time : duration of the initiation move (cycloidal, rest to rest), s.
    hold : standstill after the initiation move, s (ambient vibration acts in the simulator).
    reversals : amplitudes, rad, of the reversing moves around the stop position, alternately
        against and along the initiation direction (default 0.03, 0.015, 0.0075, 0.00375 deg:
        the first exceeds 2 W/k of the paper's elements, the later ones give nested minor loops).
    reversal_time : duration of each reversing move, s (kept slow: below qd_thr = 0.0017 rad/s).
    dwell : standstill after each reversal, s.   final_hold : standstill at the end, s.
    direction : +1 or -1, direction of the initiation move.

    Returns
    -------
    Trajectory with ``params["stop_time"]`` (s) and ``params["stop_q"]`` (rad): end of the
    initiation move, where the Maxwell-slip elements are saturated (eq. 12).
    """
    limits = limits or AxisLimits.kr6_r700_sixx(axis)
    step = _num("step", step)
    step_time = _num("step_time", step_time)
    hold = _num("hold", hold, lo_open=False)
    reversals = [_num("reversals", a) for a in reversals]
    reversal_time = _num("reversal_time", reversal_time)
    dwell = _num("dwell", dwell, lo_open=False)
    final_hold = _num("final_hold", final_hold, lo_open=False)
    lead = _num("lead", lead, lo_open=False)
    if direction not in (1, -1):
        raise TrajectoryError(f"option direction: must be +1 or -1, got {direction!r}")
    c = _centre(centre, limits)
    path = _Path(c - direction * step)
    path.hold(lead)
    path.cycloid(c, step_time)
    stop_time = path.t
    path.hold(hold)
    sign = -direction
    for a in reversals:
        path.cycloid(c + sign * a, reversal_time)
        path.hold(dwell)
        sign = -sign
    if reversals:
        path.cycloid(c, reversal_time)
    params = {"step": step, "step_time": step_time, "hold": hold, "reversals": reversals,
              "reversal_time": reversal_time, "dwell": dwell, "final_hold": final_hold, "direction": direction,
              "centre": c, "lead": lead, "stop_time": stop_time, "stop_q": c}
    return _finish(path, "presliding", axis, params, limits, dt, tail=final_hold)


def validation(periods: Sequence[float] = (6.0, 2.9, 1.3), amplitude: float = 0.6,
               weights: Sequence[float] = (0.6, 0.3, 0.1), sine_time: float = 18.0, ramp: float = 3.0,
               moves: Sequence[float] = (0.5, -0.4, 0.15, 0.16, -0.1, 0.0),
               move_speeds: Sequence[float] = (0.4, 0.8, 0.05, 0.02, 0.6, 0.2), dwell: float = 1.5,
               acc: float = 3.0, centre: float | None = None, lead: float = 1.0, axis: int = 3,
               limits: AxisLimits | None = None, dt: float = IPO_DT) -> Trajectory:
    """Mixed validation trajectory: ramped multi-sine, then point-to-point moves with standstill.

    Parameters
    ----------
    periods : periods of the sine components, s.   weights : their relative amplitudes.
    amplitude : sum of the component amplitudes, rad.   sine_time : duration of the multi-sine, s.
    ramp : raised-cosine ramp in and out of the multi-sine, s.
    moves : targets of the point-to-point moves, rad relative to ``centre``.
    move_speeds : cruise speed of each move, rad/s.   dwell : standstill after each move, s.
    acc : peak acceleration of the move ramps, rad/s².
    """
    limits = limits or AxisLimits.kr6_r700_sixx(axis)
    periods = [_num("periods", p) for p in periods]
    weights = [_num("weights", w, lo_open=False) for w in weights]
    if len(weights) != len(periods) or sum(weights) <= 0:
        raise TrajectoryError(f"option weights: need one non-negative weight per period ({len(periods)}), "
                              f"not all zero; got {len(weights)}")
    amplitude = _num("amplitude", amplitude)
    sine_time = _num("sine_time", sine_time)
    ramp = _num("ramp", ramp, lo_open=False)
    if 2 * ramp > sine_time:
        raise TrajectoryError(f"option ramp: must be at most half of sine_time ({sine_time:g} s), got {ramp:g}")
    moves = [float(m) for m in moves]
    move_speeds = [_num("move_speeds", v) for v in move_speeds]
    if len(move_speeds) != len(moves):
        raise TrajectoryError(f"option move_speeds: need one speed per move ({len(moves)}), got {len(move_speeds)}")
    dwell = _num("dwell", dwell, lo_open=False)
    acc = _num("acc", acc)
    lead = _num("lead", lead, lo_open=False)
    c = _centre(centre, limits)
    K = len(periods)
    amps = np.asarray(weights) / sum(weights) * amplitude
    ws = 2 * math.pi / np.asarray(periods)
    phases = np.array([-math.pi * k * (k - 1) / K for k in range(1, K + 1)])  # Schroeder phases
    off = float(np.sum(amps * np.sin(phases)))

    def fn(tau: np.ndarray) -> np.ndarray:
        env = np.ones_like(tau)
        if ramp > 0:
            m = tau < ramp
            env[m] = 0.5 * (1 - np.cos(math.pi * tau[m] / ramp))
            m = tau > sine_time - ramp
            env[m] = 0.5 * (1 + np.cos(math.pi * (tau[m] - sine_time + ramp) / ramp))
        s = np.sum(amps[:, None] * np.sin(ws[:, None] * tau[None, :] + phases[:, None]), axis=0) - off
        return c + env * s

    path = _Path(c)
    path.hold(lead)
    path.curve(sine_time, fn)
    path.q = c
    path.hold(dwell)
    for m, v in zip(moves, move_speeds):
        path.move(c + m, v, acc)
        path.hold(dwell)
    params = {"periods": periods, "amplitude": amplitude, "weights": weights, "sine_time": sine_time,
              "ramp": ramp, "moves": moves, "move_speeds": move_speeds, "dwell": dwell, "acc": acc,
              "centre": c, "lead": lead, "phases": phases.tolist()}
    return _finish(path, "validation", axis, params, limits, dt, tail=0.0)


GENERATORS: dict[str, Callable[..., Trajectory]] = {
    "friction": friction, "inertia": inertia, "presliding": presliding, "validation": validation,
}


def generate(kind: str, **options: Any) -> Trajectory:
    """Build the trajectory of experiment ``kind`` (one of :data:`KINDS`) with ``options``."""
    if kind not in GENERATORS:
        raise TrajectoryError(f"unknown experiment kind '{kind}' (known: {', '.join(KINDS)})")
    return GENERATORS[kind](**options)
