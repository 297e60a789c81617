"""The friction experiment (eqs. 2-4): constant-velocity moves both ways at a list of speeds."""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from kukaid.errors import TrajectoryError
from kukaid.models.limits import AxisLimits

from kukaid.excite.path import _Path, _centre, _finish, _num
from kukaid.excite.trajectory import _DEG, IPO_DT, Trajectory


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
    # the option a speed comes from: the list given, or the range v_min..v_max
    source = "speeds" if speeds is not None else "v_max"
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
                    what = (f"{v:g} rad/s" if source == "speeds" else
                            f"{speeds[-1]:g} rad/s is too fast: its speed {v:g} rad/s (of {len(speeds)} from v_min)")
                    raise TrajectoryError(f"option {source}: {what} cannot be reached within the position window "
                                          f"({d:.4g} rad = {math.degrees(d):.4g} deg) at acc = {acc:g} rad/s²; lower it, widen option span or "
                                          "raise option acc")
                plateaus.append([round(p[0], 9), round(p[1], 9), p[2]])
                path.hold(settle)
    params = {"speeds": speeds, "centre": c, "span": span, "plateau": plateau, "settle": settle, "acc": acc,
              "ramp_min": ramp_min, "reposition_speed": reposition_speed, "cycles": cycles, "lead": lead,
              "plateaus": plateaus}
    return _finish(path, "friction", axis, params, limits, dt, tail=0.0)
