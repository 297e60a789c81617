"""Out-of-sample validation: a parameter file's model evaluated on logs it was not fitted on.

:func:`validate` returns, per axis, the RMSE, the relative error ||tau - tau_hat|| / ||tau||, the
coefficient of determination R² and the number of samples, pooled over the logs given.

The seam for other model kinds (small on purpose)
-------------------------------------------------
A *predictor* is a function ``predict(params, log, axis) -> {axis: (tau, tau_hat)}`` that returns,
for every axis it models, the measured torque and the model's torque on the samples it compares
(two (n,) arrays, N·m), pre-processed the way that model's fit pre-processes.  :data:`PREDICTORS`
maps a parameter file's ``schema`` to the import path ``"module:function"`` of its predictor
(imported only when used).  A multi-axis robot parameter file adds one line there with its own
schema; nothing else changes (``kukaid.robot_params/1``: the six-axis robot fit).

The single-axis predictor (:func:`predict_axis`, schema ``kukaid.params/1``) evaluates exactly
the model ``kukaid fit`` fits: the log pre-processed with the fit's own settings (filter, mode
threshold, reversal window from the file's provenance; :func:`kukaid.identify.preprocess`),
Γ̂ = Izz qdd + Mx cos q (+ My sin q) + offset + F(qd) (:meth:`kukaid.models.torque.JointTorqueModel.
predict_dynamic`) plus the diagnosed effects (:meth:`~kukaid.models.torque.JointTorqueModel.effects_torque`), on
the dynamic-mode samples (``Prepared.dynamic``) away from the filter's edges.
"""
from __future__ import annotations

import importlib
import math
from dataclasses import dataclass
from typing import Any, Callable, Sequence

import numpy as np

from kukaid.errors import KukaidError, ParamFileError

#: schema -> "module:function" of its predictor (see the module docstring)
PREDICTORS: dict[str, str] = {
    "kukaid.params/1": "kukaid.diagnose.validate:predict_axis",
    "kukaid.robot_params/1": "kukaid.identify.robot_fit:robot_predictor",
}

Predictor = Callable[[dict, Any, "int | None"], "dict[int, tuple[np.ndarray, np.ndarray]]"]


@dataclass(frozen=True)
class AxisScore:
    """Out-of-sample figures of one axis (pooled over logs): N·m, dimensionless, samples."""

    rmse: float
    rel_error: float
    r2: float
    samples: int

    def to_json(self) -> dict[str, Any]:
        return {"rmse": self.rmse, "rel_error": self.rel_error, "r2": self.r2, "samples": self.samples}


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


def predictor_for(params: dict) -> Predictor:
    """The predictor of the parameter file's schema (:data:`PREDICTORS`)."""
    schema = params.get("schema", "kukaid.params/1")
    path = PREDICTORS.get(schema)
    if path is None:
        raise ParamFileError(f"schema '{schema}': no model evaluator for it (known: {', '.join(PREDICTORS)})")
    mod, fn = path.split(":")
    return getattr(importlib.import_module(mod), fn)


def load_model_file(path: Any) -> dict:
    """Read a parameter file of any schema in :data:`PREDICTORS`; ``kukaid.params/1`` is validated
    here, other schemas by their predictor."""
    from kukaid.jsonfile import read_json
    from kukaid.params import SCHEMA, validate_params

    d = read_json(path, ParamFileError)
    if not isinstance(d, dict):
        raise ParamFileError(f"{path}: top level must be a JSON object")
    if d.get("schema") == SCHEMA or d.get("schema") not in PREDICTORS:
        validate_params(d, str(path))
    return d


def fit_settings(params: dict) -> dict[str, Any]:
    """Pre-processing options of the fit that wrote ``params`` (its provenance), for
    :func:`kukaid.identify.preprocess`; empty when the file does not say (defaults by sample rate)."""
    pre = (params.get("provenance") or {}).get("preprocess")
    pre = pre if isinstance(pre, dict) else {}
    out: dict[str, Any] = {}
    for k, typ in (("cutoff", float), ("order", int), ("reversal_window", float), ("diff", str)):
        if pre.get(k) is not None:
            out[k] = typ(pre[k])
    qd_thr = (params.get("mode_switch") or {}).get("qd_thr", pre.get("qd_thr"))
    if qd_thr is not None:
        out["qd_thr"] = float(qd_thr)
    return out


def predict_axis(params: dict, log: Any, axis: int | None = None) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """Measured and predicted torque of the axis of a ``kukaid.params/1`` file on ``log``.

    The prediction is the fit's model (see the module docstring) on the dynamic-mode samples of
    the log pre-processed with the fit's settings; effects are evaluated on the whole log (their
    time and energy coordinates start with it).
    """
    from kukaid.identify.filtering import preprocess
    from kukaid.params import model_from_params

    ax = int(params.get("axis", 3)) if axis is None else int(axis)
    if ax not in log.axes:
        raise KukaidError(f"{log.attrs.get('source_file', 'log')}: axis A{ax} of the parameter file is not in "
                          f"the log (axes: {list(log.axes)})")
    st = fit_settings(params)
    pr = preprocess(log, ax, edge=0, **st)  # the whole grid: effects start with the log
    edge = int(math.ceil(5.0 * pr.fs / pr.settings["cutoff"]))
    keep = pr.dynamic.copy()
    keep[:edge] = False
    keep[pr.n - edge:] = False
    model = model_from_params(params)
    tau_hat = model.predict_dynamic(pr.q, pr.qd, pr.qdd)
    if params.get("effects"):
        temp = None if log.temp is None else np.asarray(log.temp[:, log.index(ax)], dtype=float)
        others = ({a: preprocess(log, a, edge=0, **st).q for a in log.axes if a != ax}
                  if "coupling" in params["effects"] else None)
        tau_hat = tau_hat + model.effects_torque(pr.time, pr.q, pr.qd, temp, others)
    return {ax: (pr.tau[keep], tau_hat[keep])}


def validate(params: dict, logs: Sequence[Any], axis: int | None = None,
             source: str = "parameters") -> dict[int, AxisScore]:
    """Per-axis out-of-sample figures of the model of ``params`` (read from ``source``) on ``logs`` (pooled).

    Raises
    ------
    KukaidError : an axis is missing from a log, or no sample is compared.
    ParamFileError : a one-axis file of another axis than ``axis``, or of another joint type than the logs'.
    """
    from kukaid.params import SCHEMA, check_model_of

    if not logs:
        raise KukaidError("validate needs at least one log")
    if params.get("schema", SCHEMA) == SCHEMA:
        ax = int(params.get("axis", 3)) if axis is None else int(axis)
        check_model_of(params, source, axis=axis)
        for log in logs:
            if ax in log.axes:
                check_model_of(params, source, joint=log.joint[log.index(ax)])
    predict = predictor_for(params)
    parts: dict[int, list[tuple[np.ndarray, np.ndarray]]] = {}
    names: dict[int, list[str]] = {}
    for log in logs:
        for ax, pair in predict(params, log, axis).items():
            parts.setdefault(int(ax), []).append(pair)
            names.setdefault(int(ax), []).append(str(log.attrs.get("source_file", "log")))
    out = {}
    for ax in sorted(parts):
        tau = np.concatenate([p[0] for p in parts[ax]])
        hat = np.concatenate([p[1] for p in parts[ax]])
        if tau.size == 0:
            raise KukaidError(f"{', '.join(names[ax])}: no dynamic-mode samples of A{ax} to compare (the axis does "
                              "not move, or only where the filter trims the log's ends)")
        out[ax] = score(tau, hat)
    return out


def fitted_logs(params: dict) -> list[str]:
    """The logs the model of ``params`` was fitted on, as its provenance names them (one axis:
    ``{"friction": [...], "inertia": [...], "presliding": ..., "general": [...]}``; a robot: a list)."""
    logs = (params.get("provenance") or {}).get("logs")
    if isinstance(logs, dict):
        logs = [x for v in logs.values() for x in (v if isinstance(v, list) else [v])]
    return [str(x) for x in logs or () if x]


def in_sample(params: dict, logs: Sequence[Any], params_path: Any = None) -> list[Any]:
    """The ``logs`` (paths) that the model of ``params`` was fitted on (:func:`fitted_logs`): the
    same file, the provenance's path taken from the working folder or from the parameter file's."""
    import os
    from pathlib import Path

    bases = [Path.cwd()] + ([Path(params_path).resolve().parent] if params_path is not None else [])
    fitted = {(b / f).resolve() for f in fitted_logs(params) for b in bases}
    out = []
    for p in logs:
        here = Path(p).resolve()
        if here in fitted or any(f.exists() and here.exists() and os.path.samefile(here, f) for f in fitted):
            out.append(p)
    return out


def to_json(scores: dict[int, AxisScore]) -> dict[str, Any]:
    """``{"axes": {"A3": {"rmse": ..., "rel_error": ..., "r2": ..., "samples": ...}},
    "mean_relative_error": ...}`` (the mean of the axes' relative errors)."""
    return {"axes": {f"A{ax}": s.to_json() for ax, s in scores.items()},
            "mean_relative_error": float(np.mean([s.rel_error for s in scores.values()])) if scores else math.nan}


def table(scores: dict[int, AxisScore], unit: str = "N·m") -> list[str]:
    """A text table, one line per axis."""
    out = [f"{'axis':<5} {'RMSE (' + unit + ')':>13} {'rel. error':>11} {'R2':>8} {'samples':>8}"]
    for ax, s in scores.items():
        out.append(f"A{ax:<4} {s.rmse:>13.4g} {100 * s.rel_error:>10.2f}% {s.r2:>8.4f} {s.samples:>8d}")
    if len(scores) > 1:
        out.append(f"{'mean':<5} {'':>13} {100 * float(np.mean([s.rel_error for s in scores.values()])):>10.2f}%")
    return out
