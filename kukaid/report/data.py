"""The report's inputs: parameter file and logs read and prepared once (:class:`ReportData`), shared helpers."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from kukaid.errors import FitError, KukaidError


#: The paper's figures (Yao et al. 2018, a real KR 6 R700 sixx, A3): references, not targets.
PAPER_FRICTION_MSE = 0.5249
PAPER_TORQUE_MSE = 14.59

A4 = (8.27, 11.69)
PARAM_ORDER = ("Fc", "Fs", "vs", "delta", "Fv", "Izz", "Mx", "My", "offset")
_UNITS_REV = {"Fc": "N·m", "Fs": "N·m", "vs": "rad/s", "delta": "-", "Fv": "N·m·s/rad", "Izz": "kg·m²",
              "Mx": "N·m", "My": "N·m", "offset": "N·m"}
_UNITS_PRIS = {"Fc": "N", "Fs": "N", "vs": "m/s", "delta": "-", "Fv": "N·s/m", "Izz": "kg", "Mx": "N",
               "My": "N", "offset": "N"}

class ReportError(KukaidError):
    """The report cannot be made from the given inputs (wrong axis, no usable samples, ...)."""


@dataclass
class ReportData:
    """Inputs of a report: the parameter file and the logs (prepared as the fit prepared them).

    params : validated parameter dictionary.   source : the parameter file's path (text).
    friction, inertia, general : lists of ``(log, prepared)``.   presliding : ``(log, prepared)``.
    truth : the one-axis simulator's truth (``log.attrs["truth"]``, a ``kukaid.params/1`` of the reported
        axis) when a log carries one, else None (the six-axis simulator's ``kukaid.robot-truth/1`` holds
        the whole robot, lists per axis, no Izz of one axis).
    warnings : lines for the user (a log given in a role whose experiment it does not record,
        as ``fit`` warns).
    model : the file as :class:`~kukaid.identify.fitted.AxisFile`, the predictor validate uses.
    fitted_on : ids of the logs the model was fitted on (:func:`~kukaid.identify.fitted.in_sample`):
        their prediction pages are in-sample, not a validation.
    """

    params: dict
    source: str = ""
    friction: list = field(default_factory=list)
    inertia: list = field(default_factory=list)
    general: list = field(default_factory=list)
    presliding: Any = None
    truth: dict | None = None
    truth_source: str = ""
    warnings: list = field(default_factory=list)
    model: Any = None
    fitted_on: set = field(default_factory=set)

    @property
    def prismatic(self) -> bool:
        return (self.params.get("provenance") or {}).get("joint") == "prismatic"

    @property
    def units(self) -> dict[str, str]:
        return _UNITS_PRIS if self.prismatic else _UNITS_REV

    @property
    def tu(self) -> str:
        """Torque unit (force for a prismatic axis)."""
        return "N" if self.prismatic else "N·m"

    @property
    def tu2(self) -> str:
        """The torque unit squared (of an MSE)."""
        return "N²" if self.prismatic else "N²m²"

    @property
    def vu(self) -> str:
        return "m/s" if self.prismatic else "rad/s"


# -- loading -------------------------------------------------------------------------------------
def _prep_options(params: dict, fs: float) -> dict:
    s = (params.get("provenance") or {}).get("preprocess") or {}
    opts = {k: s[k] for k in ("cutoff", "order", "qd_thr", "reversal_window", "qdd_tol", "diff") if s.get(k) is not None}
    if s.get("decimate"):
        opts["decimate"] = int(s["decimate"])
    if s.get("edge") is not None and s.get("fs") and abs(float(s["fs"]) - fs) <= 0.01 * fs:
        opts["edge"] = int(s["edge"])
    if "qd_thr" not in opts:
        opts["qd_thr"] = float((params.get("mode_switch") or {}).get("qd_thr", 0.0017))
    return opts


def _load_one(x: Any, axis: int, params: dict, origin: str = "of the parameter file") -> tuple[Any, Any]:
    from kukaid.identify import preprocess
    from kukaid.identify.fitted import require_axis
    from kukaid.logs import read_log

    if hasattr(x, "tau") and hasattr(x, "time"):
        log = x
    else:
        p = Path(x)
        if not p.exists():
            raise ReportError(f"{p}: no such file")
        log = read_log(p)
    where = log.attrs.get("source_file", str(x) if not hasattr(x, "tau") else "axis log")
    require_axis(log, axis, where, origin)
    fs = 1.0 / float(np.median(np.diff(np.asarray(log.time, dtype=float)))) if log.time.size > 1 else 1.0
    try:
        pr = preprocess(log, axis=axis, **_prep_options(params, fs))
    except FitError as e:
        raise ReportError(str(e)) from None
    return log, pr


def load_report_data(params: dict | str | Path, friction: Sequence[Any] = (), inertia: Sequence[Any] = (),
                     presliding: Any = None, logs: Sequence[Any] = (), axis: int | None = None,
                     source: str | None = None) -> ReportData:
    """Read the parameter file and the logs, and prepare the logs as the fit did.

    Parameters
    ----------
    params : parameter dictionary or path of a ``kukaid.params/1`` file.
    friction, inertia, logs : axis logs (paths or :class:`~kukaid.logs.core.AxisLog`).
    presliding : pre-sliding log, optional.
    axis : axis to report (default: the parameter file's ``axis``, else 3).
    source : where a dictionary ``params`` was read from (a path names itself).

    Raises
    ------
    ParamFileError : broken parameter file.   LogFormatError, ReportError : missing or broken log,
    log without the axis, log too short for the filter.
    """
    from kukaid.params import SCHEMA, check_model_of, load_params, validate_params

    if isinstance(params, dict):
        par = validate_params(params) if source is None else validate_params(params, source)
        source = source or "parameters"
    else:
        par, source = load_params(params), str(params)
    from kukaid.identify.fitted import axis_origin

    origin = axis_origin(par, axis)
    if axis is None:
        axis = int(par.get("axis") or 3)
    else:
        check_model_of(par, source, axis=axis)
    from kukaid.identify.fitted import AxisFile, in_sample, use_warnings

    data = ReportData(par, source, model=AxisFile(par, axis, source))
    data.friction = [_load_one(x, axis, par, origin) for x in friction]
    data.inertia = [_load_one(x, axis, par, origin) for x in inertia]
    data.general = [_load_one(x, axis, par, origin) for x in logs]
    if presliding is not None:
        data.presliding = _load_one(presliding, axis, par, origin)
    from kukaid.identify.adequacy import role_warnings

    for role, given in (("friction", data.friction), ("inertia", data.inertia),
                        ("presliding", [data.presliding] if data.presliding else [])):
        for log, _ in given:
            data.warnings.extend(role_warnings(log, role, command="report"))
    every = data.friction + data.inertia + data.general + ([data.presliding] if data.presliding else [])
    for log, _ in every:
        check_model_of(par, source, joint=log.joint[log.index(axis)])
    given = [*friction, *inertia, *logs] + ([presliding] if presliding is not None else [])  # the order of every
    names = [x if isinstance(x, (str, Path)) else log.attrs.get("source_file", "log") for x, (log, _) in zip(given, every)]
    said = use_warnings(data.model, names, [log for log, _ in every])  # validate's
    if data.presliding:  # the pre-sliding experiment moves a fraction of a degree (as fit: no unit warning)
        from kukaid.identify.adequacy import unit_warnings

        small = set(unit_warnings(data.presliding[0], axis, str(names[-1])))
        said = [w for w in said if w not in small]
    data.warnings.extend(said)
    fitted = in_sample(par, names, source, [log for log, _ in every])
    data.fitted_on = {id(log) for n, (log, _) in zip(names, every) if n in fitted}
    for log, _ in every:
        t = log.attrs.get("truth")
        if isinstance(t, dict) and t.get("schema") == SCHEMA and int(t.get("axis", axis)) == int(axis):
            data.truth = t
            data.truth_source = str(log.attrs.get("source_file", "log"))
            break
    return data


# -- helpers -------------------------------------------------------------------------------------
def _flat_params(par: dict) -> dict[str, float]:
    out = {k: float(v) for k, v in par["friction"].items() if k != "model"}
    out.update({k: float(v) for k, v in par["inertial"].items()})
    if "offset" in par:
        out["offset"] = float(par["offset"])
    return {k: out[k] for k in PARAM_ORDER if k in out} | {k: v for k, v in out.items() if k not in PARAM_ORDER}


def _fmt(x: Any, sig: int = 5) -> str:
    if x is None:
        return "-"
    x = float(x)
    if not math.isfinite(x):
        return "-"
    return f"{x:.{sig}g}"


def _model(par: dict):
    from kukaid.params import model_from_params

    return model_from_params(par)


def predicted(data: ReportData, log: Any, pr: Any) -> np.ndarray:
    """The parameter file's torque on the samples of ``pr`` (``log`` prepared as the fit did), N·m: the
    dynamic-mode model and the effects diagnose added, as validate predicts
    (:meth:`~kukaid.identify.fitted.AxisFile.prediction`, on the whole log, taken at ``pr``'s rows)."""
    return data.model.prediction(log)[1][pr.rows]


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    idx = np.flatnonzero(np.diff(np.r_[0, np.asarray(mask, dtype=int), 0]))
    return [(int(a), int(b)) for a, b in zip(idx[::2], idx[1::2])]


def dynamic_residual(data: ReportData, log: Any, pr: Any) -> np.ndarray:
    """Measured minus predicted torque (:func:`predicted`), every sample of ``pr``, N·m."""
    return pr.tau - predicted(data, log, pr)


# -- page 1: parameters ----------------------------------------------------------------------------
