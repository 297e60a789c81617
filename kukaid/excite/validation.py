"""A validation trajectory: a ramped Schroeder multi-sine, then point-to-point moves with standstill."""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from kukaid.errors import TrajectoryError
from kukaid.models.limits import AxisLimits

from kukaid.excite.path import _Path, _centre, _finish, _num
from kukaid.excite.trajectory import IPO_DT, Trajectory


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
