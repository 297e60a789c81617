"""The paper's experiment-4 measures of a hand-guided run, over a fixed window.

Eq. (19): the operator's cost per control cycle ξ(k) = ½ dΓ(k)² + ½ λ Γ(k)², with dΓ(k) = Γ(k) -
Γ(k-1) the change of the contact torque from one control cycle to the next.  The paper reports
the mean of ξ and the mean of dΓ² over the experiment.  Both are computed here over a window that
is the same for every controller meeting the same operator (from the grasp to the release plus
1 s), on the estimated Γr and, in simulation, on the true hand torque.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np


def paper_costs(gamma: np.ndarray, lam: float) -> tuple[float, float]:
    """(mean ξ, mean dΓ²) of eq. (19) over one window of per-cycle torques ``gamma`` (N·m)."""
    g = np.asarray(gamma, dtype=float)
    if g.size < 2:
        return math.nan, math.nan
    d = np.diff(g)
    gg = g[1:]
    return float(np.mean(0.5 * d * d + 0.5 * lam * gg * gg)), float(np.mean(d * d))


def oscillation_ptp(time: np.ndarray, torque: np.ndarray, f_lo: float = 1.5, span: float = 1.0) -> np.ndarray:
    """Peak-to-peak (N·m) of the torque's content above ``f_lo`` Hz over the ``span`` s window
    starting at every sample (empty when too short).

    Offline (zero-phase Butterworth high-pass); a person's intended guiding torque lies below
    about 1 Hz, physiological tremor is a few tenths of a N·m: large values mean the coupled
    person-robot system oscillates.
    """
    from numpy.lib.stride_tricks import sliding_window_view
    from scipy.signal import butter, sosfiltfilt

    t = np.asarray(time, dtype=float)
    x = np.asarray(torque, dtype=float)
    if t.size < 16:
        return np.zeros(0)
    fs = 1.0 / float(np.median(np.diff(t)))
    hp = sosfiltfilt(butter(2, f_lo, btype="highpass", fs=fs, output="sos"), x)
    n = min(max(int(round(span * fs)), 2), hp.size)
    w = sliding_window_view(hp, n)
    return w.max(axis=1) - w.min(axis=1)


def oscillation_runs(time: np.ndarray, torque: np.ndarray, limit: float = 10.0, max_half_period: float = 0.8,
                     min_lobes: int = 4) -> list[tuple[float, float]]:
    """Oscillations of a torque record: [(start s, end s), ...].

    The record's turning points are found with a hysteresis of ``limit`` N·m (a maximum counts once
    the torque has come down ``limit`` from it, a minimum once it has come back up ``limit``: noise
    and tremor make none).  An oscillation is a run of at least ``min_lobes`` successive
    half-cycles (turning point to turning point, each ``limit`` N·m peak to peak at least) each
    shorter than ``max_half_period`` s, from its first turning point to its last.  A guiding move or
    a push, however large, rises and falls once: one or two half-cycles.  (Lobes of a zero-phase
    high-pass, the earlier definition, counted a smooth 80 N·m push as 3 s of oscillation: the
    filter rings before and after each edge.)
    """
    t = np.asarray(time, dtype=float)
    x = np.asarray(torque, dtype=float)
    if t.size < 16:
        return []
    turns: list[int] = []
    hi = lo = 0
    seeking = 0  # +1 a maximum (after a minimum), -1 a minimum, 0 either (at the start)
    for i in range(1, x.size):
        if x[i] > x[hi]:
            hi = i
        if x[i] < x[lo]:
            lo = i
        if seeking >= 0 and x[hi] - x[i] >= limit:
            turns.append(hi)
            seeking, lo = -1, i
        elif seeking <= 0 and x[i] - x[lo] >= limit:
            turns.append(lo)
            seeking, hi = 1, i
    runs: list[tuple[float, float]] = []
    n, start = 0, 0
    for a, b in zip(turns[:-1], turns[1:]):
        if t[b] - t[a] <= max_half_period:
            start = a if n == 0 else start
            n += 1
            if n == min_lobes:
                runs.append((float(t[start]), float(t[b])))
            elif n > min_lobes:
                runs[-1] = (float(t[start]), float(t[b]))
        else:
            n = 0
    return runs


def oscillation(time: np.ndarray, torque: np.ndarray, limit: float = 10.0) -> tuple[float, float]:
    """(largest peak-to-peak N·m over 1 s of the content above 0.6 Hz, seconds of the longest of
    :func:`oscillation_runs`)."""
    ptp = oscillation_ptp(time, torque, 0.6)
    runs = oscillation_runs(time, torque, limit)
    return (float(ptp.max()) if ptp.size else 0.0), max((e - s for s, e in runs), default=0.0)


def window_metrics(data: dict[str, np.ndarray], t_from: float, t_to: float, lam: float) -> dict[str, Any]:
    """Experiment-4 measures of one run (``data`` as :func:`kukaid.control.loop.run_admittance`
    records it) over ``t_from`` <= time <= ``t_to`` (s, the run's time axis).

    Keys: ``xi``, ``dgamma2`` (on Γr), ``xi_true``, ``dgamma2_true`` (on the true hand torque, NaN
    without truth), ``dgamma2_ratio`` (estimated / true), ``gamma_rms`` N·m, ``osc_ptp`` N·m
    and ``osc_seconds`` s (:func:`oscillation` of the hand torque, or of Γr without truth),
    ``osc_runs`` (:func:`oscillation_runs`),
    ``window`` (t_from, t_to).
    """
    t = data["time"]
    w = (t >= t_from) & (t <= t_to)
    out: dict[str, Any] = {"window": [float(t_from), float(t_to)]}
    out["xi"], out["dgamma2"] = paper_costs(data["gamma_r"][w], lam)
    te = data["tau_ext_true"][w]
    if te.size and np.all(np.isfinite(te)):
        out["xi_true"], out["dgamma2_true"] = paper_costs(te, lam)
        out["dgamma2_ratio"] = out["dgamma2"] / out["dgamma2_true"] if out["dgamma2_true"] > 0 else math.nan
        out["osc_ptp"], out["osc_seconds"] = oscillation(t[w], te)
        out["osc_runs"] = oscillation_runs(t[w], te)
    else:
        out["xi_true"] = out["dgamma2_true"] = out["dgamma2_ratio"] = math.nan
        out["osc_ptp"], out["osc_seconds"] = oscillation(t[w], data["gamma_r"][w])
        out["osc_runs"] = oscillation_runs(t[w], data["gamma_r"][w])
    out["gamma_rms"] = float(np.sqrt(np.mean(data["gamma_r"][w] ** 2))) if w.any() else math.nan
    return out


def operator_metrics(data: dict[str, np.ndarray], operator: Any, lam: float, t_offset: float) -> dict[str, Any]:
    """:func:`window_metrics` of a simulated run with a human arm (:mod:`kukaid.sim.human`) over
    its fixed window (grasp to release + 1 s), plus ``goal`` rad, ``end_error`` (|q_end - goal| /
    |move|) and ``false_after_release`` (detections once the hand is gone).  ``t_offset`` s: the
    simulator's time at the run's time 0.  Empty for other operators."""
    p = getattr(operator, "p", None)
    if p is None or not hasattr(p, "t_grasp"):
        return {}
    t_rel = operator.t_release if math.isfinite(operator.t_release) else math.inf
    t_end = float(data["time"][-1])
    out = window_metrics(data, p.t_grasp - t_offset, min(t_rel + 1.0 - t_offset, t_end), lam)
    move = p.goal - p.q_start
    out["goal"] = float(p.goal)
    out["end_error"] = float(abs(data["q"][-1] - p.goal) / abs(move)) if move else math.nan
    gone = data["time"] > t_rel - t_offset + p.release_time + 0.05
    out["false_after_release"] = int(np.sum(data["detected"][gone])) if math.isfinite(t_rel) else 0
    out["t_release"] = float(t_rel - t_offset) if math.isfinite(t_rel) else math.nan
    return out


def damping_delay(runs: list[tuple[float, float]], event_times: list[float]) -> tuple[float, bool]:
    """How long oscillations outlast the stability monitor's action, s, and whether one is
    sustained: still there more than 1.5 s after the monitor's first event during it (or lasting
    more than 2 s when it never acted).  ``runs`` from :func:`oscillation_runs`, ``event_times``
    the monitor's events (s, the same time axis)."""
    late_max, sustained = 0.0, False
    for s, e in runs:
        acted = [t for t in event_times if s - 0.5 <= t <= e]
        late = e - acted[0] if acted else e - s
        late_max = max(late_max, late)
        sustained |= late > (1.5 if acted else 2.0)
    return late_max, sustained
