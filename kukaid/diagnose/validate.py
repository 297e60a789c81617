"""Out-of-sample validation: a parameter file's model evaluated on logs it was not fitted on.

:func:`validate` returns, per axis, the RMSE, the relative error ||tau - tau_hat|| / ||tau||, the
coefficient of determination R² and the number of samples, pooled over the logs given.

The model is the parameter file's :class:`~kukaid.identify.fitted.FittedModel` (one axis or a
whole robot, :func:`~kukaid.identify.fitted.model_for`): its ``predict(log)`` gives, for every axis
it models, the measured torque and the model's torque on the samples it compares (two (n,)
arrays, N·m), pre-processed the way that model's fit pre-processes; one code path scores both.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any, Sequence

import numpy as np

from kukaid.errors import KukaidError


@dataclass(frozen=True)
class AxisScore:
    """Out-of-sample figures of one axis (pooled over logs): N·m, dimensionless, samples; ``noise_floor``
    N·m, the RMSE a perfect model would reach on these samples (the torque's white noise; NaN when not
    known), against which the RMSE reads."""

    rmse: float
    rel_error: float
    r2: float
    samples: int
    noise_floor: float = math.nan

    def to_json(self) -> dict[str, Any]:
        return {"rmse": self.rmse, "rel_error": self.rel_error, "r2": self.r2, "samples": self.samples,
                "noise_floor": self.noise_floor}


def score(tau: np.ndarray, tau_hat: np.ndarray) -> AxisScore:
    """RMSE, ||tau - tau_hat|| / ||tau||, R² = 1 - SS_res / SS_tot (about the mean), samples."""
    tau = np.asarray(tau, dtype=float)
    r = tau - np.asarray(tau_hat, dtype=float)
    n = int(tau.size)
    if n == 0:
        return AxisScore(math.nan, math.nan, math.nan, 0)
    ss_res = float(r @ r)
    ny = float(np.linalg.norm(tau))
    dev = tau - tau.mean()
    ss_tot = float(dev @ dev)
    return AxisScore(math.sqrt(ss_res / n), math.sqrt(ss_res) / ny if ny > 0 else math.nan,
                     1.0 - ss_res / ss_tot if ss_tot > 0 else math.nan, n)


def validate(params: Any, logs: Sequence[Any], axis: int | None = None, source: str = "parameters",
             per_log: list[dict[int, AxisScore]] | None = None) -> dict[int, AxisScore]:
    """Per-axis out-of-sample figures of the model of ``params`` (a parameter dictionary read from
    ``source``, or its :class:`~kukaid.identify.fitted.FittedModel`) on ``logs`` (pooled);
    ``per_log`` (a list) gets each log's own figures, in order.

    Raises
    ------
    KukaidError : an axis is missing from a log, or no sample is compared.
    ParamFileError : a one-axis file of another axis than ``axis``, or of another joint type than the
        logs'; a schema of no model.
    """
    from kukaid.identify.fitted import file_cutoff, model_for

    if not logs:
        raise KukaidError("validate needs at least one log")
    model = model_for(params, axis, source) if isinstance(params, dict) else params
    for log in logs:
        model.check(log)
    parts: dict[int, list[tuple[np.ndarray, np.ndarray]]] = {}
    names: dict[int, list[str]] = {}
    floors: dict[int, list[float]] = {}
    for log in logs:
        with file_cutoff(model):
            pairs, floor = model.compare(log)
        for ax, pair in pairs.items():
            parts.setdefault(int(ax), []).append(pair)
            names.setdefault(int(ax), []).append(str(log.attrs.get("source_file", "log")))
            floors.setdefault(int(ax), []).append(float(floor.get(ax, math.nan)))
        if per_log is not None:
            per_log.append({int(ax): replace(score(*pair), noise_floor=float(floor.get(ax, math.nan)))
                            for ax, pair in sorted(pairs.items())})
    out = {}
    for ax in sorted(parts):
        tau = np.concatenate([p[0] for p in parts[ax]])
        hat = np.concatenate([p[1] for p in parts[ax]])
        if tau.size == 0:
            raise KukaidError(f"{', '.join(names[ax])}: no dynamic-mode samples of A{ax} to compare (the axis does "
                              "not move, or only where the filter trims the log's ends)")
        n = np.array([p[0].size for p in parts[ax]], float)  # pooled as the RMSE is: by samples
        out[ax] = replace(score(tau, hat), noise_floor=float(np.sqrt(n @ np.square(floors[ax]) / n.sum())))
    return out


#: relative error at or above which a model does not describe a log: its error is as large as the
#: measured torque itself, no better than predicting no torque at all (a model of another robot or axis,
#: or torques in another unit: EMPS's model, read as revolute, on a 1 kHz capture of the virtual KR C4's A1
#: scores 603 %).  Just under 1: a log whose torques are k times the model's scores 1 - 1/k, under 100 %
#: however large k is (N·mm under an N·m column, k = 1000: 99.9 %, said nothing at 1.0, new-user trial 21);
#: 0.98 says it from k = 50 on
MISMATCH = 0.98


def mismatch_warnings(per_log: Sequence[dict[int, AxisScore]], paths: Sequence[Any], source: Any,
                      unit: str = "N·m") -> list[str]:
    """One line per log and axis (``per_log``: :func:`validate`'s, the logs read from ``paths``) whose
    relative error is at least :data:`MISMATCH`, naming the model's error and the measured torque (RMS,
    ``unit``).  A measured torque that does not vary is :func:`flat_warnings`' (not a model's mismatch)."""
    return [f"{path}: the model of {source} does not describe this log on A{ax}: its error (RMS {s.rmse:.4g} {unit}) "
            f"is {s.rel_error:.3g} x the measured torque (RMS {s.rmse / s.rel_error:.4g} {unit}), "
            f"{'worse than' if s.rel_error >= 1.0 else 'no better than'} predicting none; is it of another robot or "
            "axis, or in another unit?"
            for path, scores in zip(paths, per_log) for ax, s in scores.items()
            if s.rel_error >= MISMATCH and not _flat(s)]


def _flat(s: AxisScore) -> bool:
    """The measured torque of the samples ``s`` scores does not vary (R² undefined: all zero, or one value)."""
    return s.samples > 0 and not math.isfinite(s.r2)


def flat_warnings(per_log: Sequence[dict[int, AxisScore]], paths: Sequence[Any], pooled: dict[int, AxisScore],
                  unit: str = "N·m") -> list[str]:
    """One line per log and axis whose measured torque does not vary over the samples compared (an
    empty or filled-in torque column: R² undefined, and all zero the relative error too).  An axis
    whose pooled measured torque (``pooled``: :func:`validate`'s) does not vary is left out of the
    mean (:func:`mean_relative_error`), and the line says so."""
    left_out = mean_relative_error(pooled)[1] if len(pooled) > 1 else []
    out = []
    for path, scores in zip(paths, per_log):
        for ax, s in scores.items():
            if not _flat(s):
                continue
            what = (f"is zero in all {s.samples} samples compared (an empty torque column?): its relative error and "
                    "R² are undefined" if not math.isfinite(s.rel_error) else
                    f"does not vary ({s.rmse / s.rel_error:.4g} {unit} in all {s.samples} samples compared: a "
                    "filled-in torque column?): its R² is undefined, its relative error says nothing of the model")
            out.append(f"{path}: the measured torque of A{ax} {what}"
                       + (f"; A{ax} is left out of the mean" if ax in left_out else ""))
    return out


def mean_relative_error(scores: dict[int, AxisScore]) -> tuple[float, list[int]]:
    """The mean of the axes' relative errors, and the axes left out of it: those whose measured torque
    does not vary (all zero: relative error undefined; one value: it says nothing of the model); NaN
    when none is left."""
    left_out = [ax for ax, s in scores.items() if _flat(s) or not math.isfinite(s.rel_error)]
    kept = [s.rel_error for ax, s in scores.items() if ax not in left_out]
    return (float(np.mean(kept)) if kept else math.nan), left_out


def to_json(scores: dict[int, AxisScore]) -> dict[str, Any]:
    """``{"axes": {"A3": {"rmse": ..., "rel_error": ..., "r2": ..., "samples": ...}},
    "mean_relative_error": ..., "mean_excludes": [...]}`` (the mean of the axes' relative errors
    without those whose measured torque does not vary, named in ``mean_excludes``)."""
    mean, left_out = mean_relative_error(scores)
    return {"axes": {f"A{ax}": s.to_json() for ax, s in scores.items()}, "mean_relative_error": mean,
            "mean_excludes": [f"A{ax}" for ax in left_out]}


def table(scores: dict[int, AxisScore], unit: str = "N·m") -> list[str]:
    """A text table, one line per axis."""
    out = [f"{'axis':<5} {'RMSE (' + unit + ')':>13} {'x noise':>8} {'rel. error':>11} {'R2':>8} {'samples':>8}"]
    for ax, s in scores.items():
        ratio = s.rmse / s.noise_floor if s.noise_floor > 0 else math.nan  # NaN: not known
        out.append(f"A{ax:<4} {s.rmse:>13.4g} {'n/a' if math.isnan(ratio) else f'{ratio:.3g}':>8} "
                   f"{100 * s.rel_error:>10.2f}% {s.r2:>8.4f} {s.samples:>8d}")
    if len(scores) > 1:
        mean, left_out = mean_relative_error(scores)
        out.append(f"{'mean':<5} {'':>13} {'':>8} {100 * mean:>10.2f}%"
                   + (f"  (without {', '.join(f'A{ax}' for ax in left_out)}: measured torque does not vary)"
                      if left_out else ""))
    unknown = [f"A{ax}" for ax, s in scores.items() if not s.noise_floor > 0 and not _flat(s)]
    if unknown:
        out.append(f"x noise: the RMSE over the noise floor (what a perfect model would reach); n/a for "
                   f"{', '.join(unknown)}: the torque was filtered or resampled before it was recorded, so its noise is not "
                   "white and cannot be told from it")
    return out
