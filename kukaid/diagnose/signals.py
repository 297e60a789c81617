"""Signals of one logged axis as the diagnosis compares them with a model.

The comparison filters *both sides* with the same zero-phase Butterworth filter: the measured
torque, and every model term (rigid body, friction, candidate effect) evaluated on the full sample
grid.  A friction jump at a velocity reversal is then smoothed identically in the measurement and
in the prediction, so the residual of a correct model is filtered measurement noise only, and its
level (the noise floor) follows from the raw noise and the filter's noise gain.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from kukaid.errors import LogFormatError
from kukaid.identify.filtering import check_even_samples, evenly_sampled, filter_defaults, lowpass, reversal_distance
from kukaid.models.signals import LogSignals

__all__ = ["LogSignals", "decimation", "noise_gain", "prepare"]


def decimation(sig: LogSignals) -> np.ndarray:
    """Positions (into the compared rows) kept for the tests: one per ~1/(2.5 cutoff) s."""
    d = max(1, int(sig.fs / (2.5 * sig.cutoff))) if sig.cutoff > 0 else 1
    return np.flatnonzero(sig.rows % d == 0)


def noise_gain(sig: LogSignals) -> float:
    """Power gain of the comparison filter for white noise (variance out / variance in)."""
    n = 4096
    imp = np.zeros(n)
    imp[n // 2] = 1.0
    h = sig.filt(imp)
    return float(np.sum(h * h))


def _dilate(mask: np.ndarray, k: int) -> np.ndarray:
    """Boolean mask grown by ``k`` samples on both sides."""
    if k <= 0 or not mask.any():
        return mask
    c = np.convolve(mask.astype(float), np.ones(2 * k + 1), mode="same")
    return c > 0.5


def prepare(log: Any, axis: int | None = None, cutoff: float | None = None, order: int | None = None,
            qd_thr: float = 0.0017, reversal_window: float | None = None, edge: int | None = None,
            still_guard: float | None = None, name: str | None = None) -> LogSignals:
    """Filter one axis of an :class:`~kukaid.logs.core.AxisLog` for the comparison.

    The samples compared are dynamic-mode samples as identification selects them:
    ``|qd| >= qd_thr``, ``edge`` samples away from the log's ends, and at least
    ``reversal_window`` s from any reversal, start or stop (there the joint is in pre-sliding and
    the filtered friction jump is smeared: the sliding model does not hold).

    Parameters
    ----------
    log : AxisLog.   axis : KUKA axis number (default: the log's only or first axis).
    cutoff : Butterworth cut-off, Hz; order : filter order (default from the sample rate, see
        :func:`filter_defaults`).
    qd_thr : velocity threshold of the dynamic mode, rad/s (m/s).
    reversal_window : s, compared rows keep this distance from standstill samples (default
        0.5 / cutoff).   edge : samples (default ceil(5 fs / cutoff)).
    still_guard : s; standstill (|qd| < qd_thr) and velocity sign changes are grown by this much
        on both sides (pre-sliding) and zeroed before the comparison filter (default 0.25 / cutoff).
    """
    import math

    if axis is None:
        axis = log.axes[0]
    where = log.attrs.get("source_file", name or "log")
    j = log.index(axis)
    check_even_samples(log.time, str(where), log.attrs)  # the filters take the samples as evenly spaced
    log = evenly_sampled(log)[0]
    t = np.asarray(log.time, dtype=float)
    q_raw = np.asarray(log.q[:, j], dtype=float)
    tau_raw = np.asarray(log.tau[:, j], dtype=float)
    temp = None if log.temp is None else np.asarray(log.temp[:, j], dtype=float)
    joint = log.joint[j] if log.joint else "revolute"
    n = t.size
    fs = 1.0 / float(np.median(np.diff(t)))
    d = filter_defaults(fs)
    cutoff = float(d["cutoff"] if cutoff is None else cutoff)
    order = int(d["order"] if order is None else order)
    if not 0 < cutoff < 0.9 * fs / 2:
        raise LogFormatError(f"{where}: filter cut-off {cutoff:g} Hz must be in (0, {0.45 * fs:.4g}) Hz "
                             f"(0.9 x Nyquist at {fs:.4g} Hz)")
    edge = int(math.ceil(5.0 * fs / cutoff)) if edge is None else int(edge)
    if n < max(2 * edge + 32, 64):
        raise LogFormatError(f"{where}: only {n} samples; the diagnosis needs at least {max(2 * edge + 32, 64)} "
                             f"at {fs:.4g} Hz with a {cutoff:g} Hz filter")
    filt = lambda x: lowpass(x, fs, cutoff, order)[0]  # noqa: E731
    qf = filt(q_raw)
    _, qd, qdd = lowpass(q_raw, fs, cutoff, order, 2)
    _, qd_lin, qdd_lin = lowpass(q_raw, fs, None, order, 2)
    rw = 0.5 / cutoff if reversal_window is None else float(reversal_window)
    still_guard = 0.25 / cutoff if still_guard is None else float(still_guard)
    v_raw = np.convolve(np.gradient(q_raw, t), np.ones(3) / 3.0, mode="same")
    still = (np.abs(qd) < qd_thr) | (np.abs(v_raw) < qd_thr)
    flip = np.r_[np.sign(qd[1:]) * np.sign(qd[:-1]) < 0, False]
    still = _dilate(still | flip | np.r_[False, flip[:-1]], max(1, int(round(still_guard * fs))))
    weight = (~still).astype(float)
    keep = np.zeros(n, bool)
    keep[edge:n - edge] = True
    keep &= ~still
    keep &= reversal_distance(t, np.where(still, 0.0, qd), qd_thr) >= rw
    rows = np.flatnonzero(keep)
    from kukaid.identify.adequacy import moving_axes

    others = {}
    for a in moving_axes(log, axis):
        qa = np.asarray(log.q[:, log.index(a)], dtype=float)
        others[a] = (qa, lowpass(qa, fs, None, order, 2)[2])
    return LogSignals(t, q_raw, tau_raw, qf, qd, qdd, temp, rows, joint, fs, cutoff, order, name or str(where),
                      filt, qd_lin, qdd_lin, weight, others or None)
