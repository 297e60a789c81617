"""Noise floor of a torque comparison, estimated from the data.

The raw torque noise is estimated from the high-frequency content of the measured torque: the
second difference of a smooth signal is small, that of white noise of standard deviation sigma has
variance 6 sigma²; a median-absolute-deviation estimate ignores the few large second differences a
friction jump at a reversal leaves.  The noise floor of the filtered comparison is that sigma times
the square root of the filter's white-noise power gain: the RMSE a perfect model would reach.
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from kukaid.diagnose.signals import LogSignals
from kukaid.identify.adequacy import raw_noise_sigma, smooth_at_source

__all__ = ["raw_noise_sigma", "noise_sigma", "noise_floor", "row_noise_gain", "filtered_noise_floor"]


def noise_sigma(sigs: Sequence[LogSignals]) -> float:
    """Raw torque-noise standard deviation over several logs (pooled by sample count), N·m."""
    v = [raw_noise_sigma(s.tau_raw) ** 2 for s in sigs]
    w = [s.n for s in sigs]
    return float(np.sqrt(np.average(v, weights=w)))


def row_noise_gain(sig: LogSignals) -> np.ndarray:
    """White-noise power gain of the comparison at every compared row (standstill samples are
    zeroed before filtering, so rows next to a stop get slightly less noise)."""
    n = 1024
    imp = np.zeros(2 * n + 1)
    imp[n] = 1.0
    h = sig.filt(imp)
    w = np.ones(sig.n) if sig.weight is None else sig.weight
    # row r's gain is the full convolution at r + n (the kernel's centre); mode "same" centres on the
    # longer of the two, so a log shorter than the kernel (2n + 1 samples) read it off by up to n rows
    g = np.convolve(w, h * h, mode="full")[n:n + sig.n]
    return g[sig.rows]


def noise_floor(sigs: Sequence[LogSignals]) -> float:
    """RMSE of a perfect model in the filtered comparison over the compared rows, N·m; NaN when it
    cannot be estimated: a log's torque filtered before it was recorded (its second differences hold
    no white noise, :func:`kukaid.identify.adequacy.smooth_at_source`: the LWR4+'s read 2.4e-05 N·m,
    a residual of 22 N·m "946441 x the noise floor")."""
    if any(smooth_at_source(s.tau_raw) for s in sigs):
        return math.nan
    num = den = 0.0
    for s in sigs:
        sig2 = raw_noise_sigma(s.tau_raw) ** 2
        k = s.rows.size
        if k == 0:
            continue
        num += sig2 * float(np.sum(row_noise_gain(s)))
        den += k
    return float(np.sqrt(num / den)) if den else 0.0


def filtered_noise_floor(taus: Sequence[np.ndarray], fs: Sequence[float], cutoff: Sequence[float],
                         order: int) -> float:
    """The noise floor of one joint's torque through a zero-phase Butterworth low-pass (the robot
    fit's comparison), N·m: the raw noise of each log's torque ``taus`` (from its second
    differences) times the square root of the filter's white-noise power gain at that log's rate
    ``fs`` and ``cutoff`` (Hz), pooled over the logs by sample count: the RMSE of a perfect model."""
    from kukaid.identify.adequacy import filter_noise_gain

    num = den = 0.0
    for x, f, c in zip(taus, fs, cutoff):
        x = np.asarray(x, float)
        num += x.size * raw_noise_sigma(x) ** 2 * filter_noise_gain(float(f), float(c), int(order))
        den += x.size
    return float(np.sqrt(num / den)) if den else 0.0
