"""The inertia experiment (section 2.2, eqs. 6-8): a sine with a raised-cosine envelope."""
from __future__ import annotations

import math

import numpy as np

from kukaid.models.limits import AxisLimits

from kukaid.excite.path import _Path, _centre, _finish, _num
from kukaid.excite.trajectory import IPO_DT, Trajectory


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
