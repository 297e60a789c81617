"""A fitted model, one axis or a whole robot, behind one protocol (:class:`FittedModel`).

A parameter file of either kind becomes a :class:`FittedModel` in one place, :func:`model_for`
(the only branch on the file's ``schema``): :class:`AxisFile` (``kukaid.params/1``, a robot of one
joint) and :class:`RobotFile` (``kukaid.robot_params/1``, fit --robot) are thin adapters over the
code each file kind already has.  ``validate``, ``show``, the report's and the diagnosis' entries
ask the protocol, not the schema:

- ``joints``: the KUKA axis numbers it models ((3,) for an A3 file);
- ``check(log)``: refuse a log it cannot be compared with (another joint type; torques in
  another unit than the URDF's limits), before anything is computed;
- ``predict(log) -> {axis: (tau, tau_hat)}``: measured and predicted torque on the samples the
  fit would compare, pre-processed with the fit's own settings; ``compare(log)`` the same with, per
  joint, the noise floor on those samples (the RMSE of a perfect model; NaN: not known), from the
  same pre-processing;
- ``warnings(log, where)``: what the user should read about a log (a one-axis model on a log
  where other axes move; a log pushed by hand);
- ``table()``: the text ``kukaid fit`` printed; ``check_file`` / ``save``: the file's own schema
  check and atomic writer (for a refined file ``kukaid diagnose -o`` writes);
- ``source`` (where the file was read) and ``cutoff_field`` (where it keeps its low-pass cut-off).

Around the protocol, one line for every command and both kinds: :func:`axis_option` (an ``--axis``
the file does not model), :func:`require_axis` (a log without the model's axis, named as the file's,
--axis's or the default's by :func:`axis_origin`), :func:`file_cutoff` (the file's cut-off a log's
rate cannot take), :func:`use_warnings` (validate's and report's
warnings, :func:`in_sample` among them).

The one-axis predictor evaluates exactly the model ``kukaid fit`` fits: the log pre-processed with
the fit's own settings (filter, mode threshold, reversal window from the file's provenance;
:func:`kukaid.identify.preprocess`), Γ̂ = Izz qdd + Mx cos q (+ My sin q) + offset + F(qd)
(:meth:`kukaid.models.torque.JointTorqueModel.predict_dynamic`) plus the diagnosed effects
(:meth:`~kukaid.models.torque.JointTorqueModel.effects_torque`), on the dynamic-mode samples away
from the filter's edges; the robot's is :func:`kukaid.identify.robot_fit.predict_robot` against
the raw torques, two cut-off periods from either end.
"""
from __future__ import annotations

import math
from contextlib import contextmanager
from functools import cached_property, lru_cache
from typing import Any, Iterator, Protocol, Sequence

import numpy as np

from kukaid.errors import KukaidError, OptionError, ParamFileError
from kukaid.params import (ROBOT_SCHEMA, SCHEMA, check_axis, check_model_of, save_params, save_robot_params, validate_params,
                           validate_robot_params)

Pairs = dict[int, tuple[np.ndarray, np.ndarray]]


class FittedModel(Protocol):
    """What every stage asks of a fitted model (see the module docstring)."""

    params: dict
    source: str
    joints: tuple[int, ...]
    unit: str
    cutoff_field: str  # where the file keeps the low-pass cut-off it filters new logs with

    def check(self, log: Any) -> None: ...

    def predict(self, log: Any) -> Pairs: ...

    def compare(self, log: Any) -> tuple[Pairs, dict[int, float]]: ...  # and per joint the noise floor on them

    def warnings(self, log: Any, where: str) -> list[str]: ...

    def table(self) -> str: ...

    def check_file(self, d: dict, where: str) -> dict: ...

    def save(self, path: Any, d: dict) -> None: ...


def model_for(params: dict, axis: int | None = None, source: str = "parameters") -> FittedModel:
    """The :class:`FittedModel` of a parameter dictionary; ``axis``: compare only that axis (default:
    the file's axis, or every axis of a robot file; refused when the file does not model it).  A
    robot file's URDF is read once per process (:func:`robot_of`)."""
    schema = params.get("schema", SCHEMA)
    if schema == ROBOT_SCHEMA:
        return RobotFile(params, axis, source)
    if schema == SCHEMA:
        return AxisFile(params, axis, source)
    raise ParamFileError(f"schema '{schema}': no model evaluator for it (known: {SCHEMA}, {ROBOT_SCHEMA})")


def load_model(path: Any, axis: int | None = None, urdf: Any = None, need_urdf: bool = True) -> FittedModel:
    """Read and validate a parameter file of either kind (:func:`kukaid.params.load_any_params`: a
    robot file's URDF found, or ``urdf``, ``--urdf``)."""
    from kukaid.params import load_any_params

    return model_for(load_any_params(path, urdf, need_urdf), axis, str(path))


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


def axis_option(source: str, axes: tuple[int, ...], axis: int | None) -> None:
    """An ``axis`` asked for (``--axis``) that the file does not model: a usage error (exit status 2),
    one line for both file kinds and every command (:func:`kukaid.params.check_axis`)."""
    check_axis(source, axes, axis, f" (--axis {axis})", OptionError)


def axis_origin(params: dict, axis: int | None) -> str:
    """Where a one-axis model's axis came from, for :func:`require_axis`: the file's ``axis``, else
    ``axis`` (--axis), else the default A3 (a file without its axis fits any)."""
    if params.get("axis") is not None:
        return "of the parameter file"
    if axis is not None:
        return f"(--axis {axis})"
    return "(the default: the parameter file names no axis; --axis chooses one)"


def require_axis(log: Any, axis: int, where: str | None = None, origin: str = "of the parameter file") -> None:
    """A log without the model's axis: one line for every command (a problem of the data, exit status
    1); ``where``: the log's name (default its ``source_file``); ``origin``: :func:`axis_origin`."""
    if int(axis) not in tuple(int(a) for a in log.axes):
        raise KukaidError(f"{where or log.attrs.get('source_file', 'log')}: axis A{axis} {origin} is "
                          f"not in the log (axes: {list(log.axes)})")


@contextmanager
def file_cutoff(model: FittedModel) -> Iterator[None]:
    """A low-pass cut-off a log's rate cannot take that comes from the parameter file (the fit's,
    ``model.cutoff_field``) is the file's setting, named as such: the log's own error alone blamed
    the log.  Around validate's, report's and diagnose's use of the model (not with their --cutoff)."""
    try:
        yield
    except KukaidError as e:
        if "filter cut-off" not in str(e):
            raise
        raise ParamFileError(f"{model.source}: its low-pass cut-off ({model.cutoff_field}) does not suit this log: "
                             f"{e}; refit the model at this log's rate") from None


def fitted_logs(params: dict) -> list[str]:
    """The logs the model of ``params`` was fitted on, as its provenance names them (one axis:
    ``{"friction": [...], "inertia": [...], "presliding": ..., "general": [...]}``; a robot: a list)."""
    logs = (params.get("provenance") or {}).get("logs")
    if isinstance(logs, dict):
        logs = [x for v in logs.values() for x in (v if isinstance(v, list) else [v])]
    return [str(x) for x in logs or () if x]


def in_sample(params: dict, logs: Sequence[Any], params_path: Any = None, loaded: Sequence[Any] = ()) -> list[Any]:
    """The ``logs`` (paths) that the model of ``params`` was fitted on.  Given the ``loaded`` logs and
    a file that keeps its logs' fingerprints (``provenance.log_fingerprints``: fit and fit --robot),
    the same recording wherever it is now and whatever its name; else (an older file) the same file
    as a path of :func:`fitted_logs`, taken from the working folder or from the parameter file's."""
    import os
    from pathlib import Path

    from kukaid.logs import fingerprints

    prints = set((params.get("provenance") or {}).get("log_fingerprints") or ())
    if prints and len(loaded) == len(logs):
        return [p for p, lg in zip(logs, loaded) if prints.intersection(fingerprints(lg))]
    bases = [Path.cwd()] + ([Path(params_path).resolve().parent] if params_path is not None else [])
    fitted = {(b / f).resolve() for f in fitted_logs(params) for b in bases}
    out = []
    for p in logs:
        here = Path(p).resolve()
        if here in fitted or any(f.exists() and here.exists() and os.path.samefile(here, f) for f in fitted):
            out.append(p)
    return out


def use_warnings(model: FittedModel, paths: Sequence[Any], logs: Sequence[Any]) -> list[str]:
    """What ``validate`` and ``report`` say about ``model`` compared with ``logs`` (read from ``paths``):
    each log's ``model.warnings`` (other axes move; a log pushed by hand), then the logs it was fitted
    on (:func:`in_sample`)."""
    out = [w for p, lg in zip(paths, logs) for w in model.warnings(lg, str(p))]
    return out + [f"{p}: the model of {model.source} was fitted on this log (its provenance): these figures are "
                  "in-sample, not a validation; give a log it did not see" for p in in_sample(model.params, paths,
                                                                                               model.source, logs)]


@lru_cache(maxsize=4)
def robot_of(urdf: str):
    """The :class:`~kukaid.models.robot.RobotModel` of a URDF, built once per process (a fleet's
    worker meets the same arm in every log)."""
    from kukaid.models.robot import RobotModel

    return RobotModel(urdf)


class AxisFile:
    """A ``kukaid.params/1`` file as a :class:`FittedModel`: a robot of one joint."""

    check_file = staticmethod(validate_params)
    save = staticmethod(save_params)
    cutoff_field = "provenance.preprocess.cutoff"

    def __init__(self, params: dict, axis: int | None = None, source: str = "parameters") -> None:
        if params.get("axis") is not None:  # a file without its axis fits any
            axis_option(source, (int(params["axis"]),), axis)
        self.params, self.source = params, source
        self.axis = int(params.get("axis", 3)) if axis is None else int(axis)
        self.origin = axis_origin(params, axis)
        self.joints = (self.axis,)
        self.unit = "N" if (params.get("provenance") or {}).get("joint") == "prismatic" else "N·m"

    def check(self, log: Any) -> None:
        require_axis(log, self.axis, origin=self.origin)
        check_model_of(self.params, self.source, joint=log.joint[log.index(self.axis)])

    def predict(self, log: Any) -> Pairs:
        return self.compare(log)[0]

    def prediction(self, log: Any) -> tuple[Any, np.ndarray]:
        """The log pre-processed with the fit's settings on its whole grid (edge 0: the effects' time and
        energy coordinates start with the log) and the model's torque on every sample of it, the effects
        diagnose added included: ``(prepared, tau_hat)``."""
        from kukaid.identify.filtering import preprocess
        from kukaid.params import model_from_params

        self.check(log)
        ax, params = self.axis, self.params
        st = fit_settings(params)
        pr = preprocess(log, ax, edge=0, **st)
        model = model_from_params(params)
        tau_hat = model.predict_dynamic(pr.q, pr.qd, pr.qdd)
        if params.get("effects"):
            temp = None if log.temp is None else np.asarray(log.temp[:, log.index(ax)], dtype=float)
            others = ({a: preprocess(log, a, edge=0, **st).q for a in log.axes if a != ax}
                      if "coupling" in params["effects"] else None)
            tau_hat = tau_hat + model.effects_torque(pr.time, pr.q, pr.qd, temp, others)
        return pr, tau_hat

    def compare(self, log: Any) -> tuple[Pairs, dict[int, float]]:
        """:meth:`prediction` on the dynamic-mode samples away from the filter's edges.  The noise floor
        is the torque's white noise over the compared span through the fit's low-pass
        (:func:`kukaid.identify.adequacy.noise_floor`); NaN for a torque filtered before it was recorded
        (its noise not white)."""
        from dataclasses import replace

        from kukaid.identify.adequacy import noise_floor, smooth_at_source

        pr, tau_hat = self.prediction(log)
        ax = self.axis
        edge = int(math.ceil(5.0 * pr.fs / pr.settings["cutoff"]))
        keep = pr.dynamic.copy()
        keep[:edge] = False
        keep[pr.n - edge:] = False
        floor = (math.nan if smooth_at_source(pr.tau_span) else  # edge=0: the whole log's torque
                 noise_floor([replace(pr, tau_span=pr.tau_span[edge:pr.tau_span.size - edge], dynamic=keep)]))
        return {ax: (pr.tau[keep], tau_hat[keep])}, {ax: floor}

    def warnings(self, log: Any, where: str) -> list[str]:
        from kukaid.identify.adequacy import moving_axes, pushed_log_warnings, unit_warnings

        others = moving_axes(log, self.axis)
        out = []
        if others:  # a one-axis model on a log where other axes move: say why it fails
            moving = ", ".join(f"A{a}" for a in others)
            out.append(f"{where}: other axes ({moving}) move, so the gravity and inertia torque on A{self.axis} "
                       f"depend on their positions, which the single-axis model of {self.source} does not see; "
                       "fit all axes together (kukaid fit --robot URDF)")
        return unit_warnings(log, self.axis, where) + out + pushed_log_warnings(log, where)

    def table(self) -> str:
        from kukaid.identify.fit import format_params

        return format_params(self.params)


class RobotFile:
    """A ``kukaid.robot_params/1`` file (fit --robot) as a :class:`FittedModel`."""

    check_file = staticmethod(validate_robot_params)
    save = staticmethod(save_robot_params)
    unit = "N·m"
    cutoff_field = "settings.cutoff"

    def __init__(self, params: dict, axis: int | None = None, source: str = "parameters", robot: Any = None) -> None:
        self.params, self.source = validate_robot_params(params, source), source
        if robot is not None:  # a RobotModel of the file's URDF the caller has built already
            self.robot = robot
        axes = tuple(range(1, len(params["axes"]) + 1))
        axis_option(source, axes, axis)
        self.joints = axes if axis is None else (int(axis),)

    @cached_property
    def robot(self):
        """The robot model of the file's URDF (when first asked; :func:`robot_of`)."""
        return robot_of(self.params["robot"]["urdf"])

    def check(self, log: Any) -> None:
        from kukaid.identify.robot_fit import check_torque_scale

        check_torque_scale(log, self.robot)

    def predict(self, log: Any) -> Pairs:
        """The raw measured torques against the prediction, two cut-off periods from either end."""
        from kukaid.identify.robot_fit import RobotFitSettings, _cutoff, predict_robot

        pred = predict_robot(self.params, log, self.robot, self.source)
        fs = 1.0 / log.sample_time
        fc = _cutoff(RobotFitSettings(cutoff=self.params["settings"].get("cutoff")), fs)
        edge = int(math.ceil(2.0 * fs / fc))
        rows = slice(edge, log.n_samples - edge)
        return {a: (log.channel("tau", a)[rows], pred[a][rows]) for a in self.joints}

    def compare(self, log: Any) -> tuple[Pairs, dict[int, float]]:
        """:meth:`predict`, and per joint the RMSE a perfect model would reach on its samples (raw
        torques: their white noise), N·m; NaN for a torque filtered before it was recorded (its noise
        not white)."""
        from kukaid.identify.adequacy import raw_noise_sigma, smooth_at_source

        out = {}
        for a in self.joints:
            tau = log.channel("tau", a)
            out[a] = math.nan if smooth_at_source(tau) else raw_noise_sigma(tau)
        return self.predict(log), out

    def warnings(self, log: Any, where: str) -> list[str]:
        from kukaid.identify.adequacy import pushed_log_warnings, unit_warnings

        return ([w for a in self.joints if a in log.axes for w in unit_warnings(log, a, where)]
                + pushed_log_warnings(log, where))

    def table(self) -> str:
        from kukaid.identify.robot_fit import format_robot_table

        return format_robot_table(self.params)


__all__ = ["AxisFile", "FittedModel", "RobotFile", "axis_option", "file_cutoff", "fit_settings", "fitted_logs",
           "axis_origin", "in_sample", "load_model", "model_for", "require_axis", "robot_of", "use_warnings"]
