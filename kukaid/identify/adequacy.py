"""Is the single-axis model adequate for a log?  Checks a fit reports instead of failing silently.

* :func:`raw_noise_sigma`: the torque-noise level of the raw samples (second differences, MAD);
  :func:`noise_floor`: the RMS a perfect model would leave after the fit's zero-phase filter.
* :func:`moving_axes`: the other axes of a log that move (their motion changes the gravity and
  inertia torque a multi-body robot puts on this axis, which the single-axis model cannot hold).
* :func:`assess`: warnings (one line each) from the solver status, the parameters on their
  bounds, the residual against the noise floor and the other axes' motion, with what to do.
"""
from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

_MAD = 1.482602218505602  # MAD -> standard deviation for a normal distribution

#: an axis "moves" when its position range exceeds this (rad, or m for a prismatic axis)
MOVE_RANGE = 0.02
#: a fit residual above this many noise floors is "far above noise"
FAR_ABOVE_NOISE = 5.0


def raw_noise_sigma(x: np.ndarray) -> float:
    """Standard deviation of white noise on the samples ``x`` (same unit as x).

    Uses the second difference d2 = x[k+1] - 2 x[k] + x[k-1], var(d2) = 6 sigma² for white
    noise, with a robust (MAD) scale; falls back to a trimmed RMS when more than half the second
    differences are exactly equal (coarse quantisation).
    """
    x = np.asarray(x, dtype=float)
    if x.size < 5:
        return 0.0
    d2 = np.diff(x, 2)
    med = np.median(d2)
    mad = np.median(np.abs(d2 - med))
    if mad > 0:
        return float(_MAD * mad / np.sqrt(6.0))
    a = np.sort(np.abs(d2 - med))
    a = a[: max(1, int(0.95 * a.size))]
    return float(np.sqrt(np.mean(a * a) / 6.0))


def filter_noise_gain(fs: float, cutoff: float, order: int) -> float:
    """White-noise power gain of the zero-phase Butterworth low-pass (variance out / in)."""
    from kukaid.identify.filtering import lowpass

    n = 4096
    imp = np.zeros(n)
    imp[n // 2] = 1.0
    h = lowpass(imp, fs, cutoff, order)[0]
    return float(np.sum(h * h))


def noise_floor(preps: Sequence[Any]) -> float:
    """RMS residual of a perfect model on the filtered torque of prepared logs, N·m (pooled)."""
    num = den = 0.0
    for pr in preps:
        st = pr.settings
        g = filter_noise_gain(st["fs"], st["cutoff"], st["order"]) if st.get("filter_torque", True) else 1.0
        k = int(np.count_nonzero(pr.dynamic))
        num += raw_noise_sigma(pr.tau_span) ** 2 * g * k  # at the original rate: see Prepared
        den += k
    return float(math.sqrt(num / den)) if den else 0.0


def moving_axes(log: Any, axis: int, min_range: float = MOVE_RANGE) -> list[int]:
    """The other axes of ``log`` whose position range exceeds ``min_range`` (rad or m)."""
    out = []
    for k, a in enumerate(log.axes):
        if a != axis and float(np.ptp(np.asarray(log.q[:, k], dtype=float))) > min_range:
            out.append(int(a))
    return out


def assess(axis: int, residual_rms: float, floor: float, others: Sequence[int], at_bound: Sequence[dict],
           converged: bool, status: str) -> tuple[list[str], dict[str, Any]]:
    """Warnings for a single-axis fit, and the figures behind them (for the parameter file).

    Returns (warnings, {"residual_over_noise", "other_axes_moving", "single_axis_adequate"}).
    """
    ratio = residual_rms / floor if floor > 0 else math.inf
    warnings = []
    if not converged:
        warnings.append(f"IPOPT stopped before converging ('{status}'); the best parameters it found are written "
                        "(never worse than the start)")
    if at_bound:
        warnings.append("on a bound: " + ", ".join(f"{b['name']} = {b['value']:.4g} ({b['side']} bound)"
                                                   for b in at_bound)
                        + ": the data do not determine these, or the model does not describe the data")
    inadequate = bool(others) and (ratio > FAR_ABOVE_NOISE or bool(at_bound) or not converged)
    if inadequate:
        warnings.append(
            f"the single-axis model cannot explain A{axis}: other axes ({', '.join(f'A{a}' for a in others)}) move "
            f"in the log, so the gravity and inertia torque on A{axis} depend on their positions (residual "
            f"{ratio:.3g} x the noise floor). Fit all axes together with a robot model (kukaid fit --robot URDF), "
            f"or record A{axis} moving alone; treat these parameters as a local description only")
    elif ratio > FAR_ABOVE_NOISE:
        warnings.append(f"residual {ratio:.3g} x the noise floor: the model misses an effect (run kukaid diagnose)")
    figures = {"residual_over_noise": ratio, "other_axes_moving": list(others), "single_axis_adequate": not inadequate}
    return warnings, figures
