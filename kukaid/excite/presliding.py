"""The pre-sliding experiment (section 3.4): a small move, a standstill, quasi-static reversals."""
from __future__ import annotations

from typing import Sequence


from kukaid.errors import TrajectoryError
from kukaid.models.limits import AxisLimits

from kukaid.excite.path import _Path, _centre, _finish, _num
from kukaid.excite.trajectory import _DEG, IPO_DT, Trajectory


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
