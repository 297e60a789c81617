"""One task per log: read it, fit it as ``kukaid fit`` would, return its table rows.

A task never raises: a log that cannot be read or fitted becomes an error row with its reason, so
one bad log never stops a batch.  The functions here run on Dask workers; they import the
identification on first use, so each worker holds one log (and its fit) at a time.
"""
from __future__ import annotations

import functools
import json
import math
import os
import platform
import resource
import time
from dataclasses import asdict, dataclass
from datetime import datetime, timezone
from typing import Any, Callable

import numpy as np

from kukaid import __version__
from kukaid.errors import KukaidError
from kukaid.fleet.table import empty_row


@dataclass(frozen=True)
class Job:
    """What a task needs: the log's entry fields and its content hash (small: sent to a worker)."""

    robot: str
    axis: int | None
    date: str
    path: str
    name: str
    sha256: str
    axis_from: str = "the manifest"  # what said the axis (a folder's scan: the file's name)


@dataclass(frozen=True)
class FitOptions:
    """Options of the fit of every log (those of ``kukaid fit`` a fleet needs).

    friction_model : "auto", "stribeck" or "coulomb-viscous" (one-axis fit; whole arm:
        "coulomb-viscous" or "stribeck").
    robot : URDF path or bundled robot name for whole-arm fits (``kukaid fit --robot``), or None.
    """

    friction_model: str = "auto"
    robot: str | None = None

    def settings(self) -> dict:
        return {"task": "fit", **asdict(self)}


def peak_rss_mb() -> float:
    """Peak resident memory of this process so far, MB (Linux reports KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _base(job: Job, kind: str) -> dict:
    r = empty_row()
    r.update(robot=job.robot, axis=job.axis, date=job.date, path=job.name, sha256=job.sha256, kind=kind,
             kukaid_version=__version__)
    return r


def _finish(rows: list[dict], t0: float, c0: float | None = None) -> list[dict]:
    now = datetime.now(timezone.utc).isoformat(timespec="seconds")
    for r in rows:
        r.update(task_s=time.perf_counter() - t0, task_cpu_s=time.process_time() - c0 if c0 is not None else None,
                 worker=f"{platform.node()}:{os.getpid()}", worker_peak_mb=peak_rss_mb(), finished_at=now)
    return rows


def error_row(job: Job, kind: str, reason: str) -> dict:
    """The row of a log that gave no result, with ``reason`` (one line)."""
    r = _base(job, kind)
    r.update(status="error", error=" ".join(str(reason).split())[:500])
    return r


def guarded(kind: str, body: Callable[[Job, Any], list[dict]], job: Job, options: Any) -> list[dict]:
    """Run ``body(job, options)``; any failure becomes one error row (a data problem with its
    message, anything else as an internal error naming the exception)."""
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        rows = body(job, options)
    except KukaidError as e:  # the log named as the manifest or the folder names it, as the other rows do
        rows = [error_row(job, kind, str(e).replace(job.path, job.name) if job.name else str(e))]
    except MemoryError:
        rows = [error_row(job, kind, "out of memory on the worker")]
    except Exception as e:  # a bug or a library failure: the batch goes on, the row says what
        rows = [error_row(job, kind, f"internal error ({type(e).__name__}: {e})")]
    return _finish(rows, t0, c0)


def read_job_log(job: Job):
    """Read the job's log and check it against the manifest: the axis it should be of is in it.

    Raises
    ------
    KukaidError : unreadable, malformed (NaN, truncated, empty) or of another axis.
    """
    from kukaid.logs import read_log

    if not os.path.isfile(job.path):
        raise KukaidError(f"{job.name}: no such file")
    log = read_log(job.path)
    if job.axis is not None and job.axis not in log.axes:
        raise KukaidError(f"{job.name}: a log of {', '.join(f'A{a}' for a in log.axes)}, "
                          f"not of A{job.axis} as {job.axis_from} says")
    return log


def _temp(log, axis: int) -> dict:
    if log.temp is None:
        return {}
    x = log.temp[:, log.index(axis)]
    return {"temp_mean": float(np.mean(x)), "temp_min": float(np.min(x)), "temp_max": float(np.max(x))}


def _fit_body(job: Job, opts: FitOptions) -> list[dict]:
    log = read_job_log(job)
    if opts.robot is not None:
        return _fit_robot(job, opts, log)
    from kukaid.identify import fit_axis

    axis = job.axis if job.axis is not None else (log.axes[0] if len(log.axes) == 1 else None)
    if axis is None:
        raise KukaidError(f"{job.name}: holds axes {', '.join(f'A{a}' for a in log.axes)}; give the axis in the "
                          "manifest, or fit whole arms with --robot")
    p = fit_axis(logs=[log], axis=axis, friction_model=opts.friction_model)
    fr, ine, unc = p["friction"], p.get("inertial", {}), p.get("uncertainty", {})
    mse = (p.get("metrics") or {}).get("torque_prediction_mse")
    r = _base(job, "fit")
    r.update(status="ok", axis=int(p["axis"]), friction_model=fr["model"], Fc=fr.get("Fc"), Fv=fr.get("Fv"),
             Fs=fr.get("Fs"), vs=fr.get("vs"), Izz=ine.get("Izz"), Mx=ine.get("Mx"), offset=p.get("offset"),
             Fc_std=unc.get("Fc"), Fv_std=unc.get("Fv"), Izz_std=unc.get("Izz"), Mx_std=unc.get("Mx"),
             rmse=math.sqrt(mse) if mse is not None else None, n_samples=log.n_samples,
             log_duration=log.duration, result=json.dumps(p), **_temp(log, int(p["axis"])))
    return [r]


def _axes_text(axes) -> str:
    """``A3``, ``A1..A6``, ``A2, A4``."""
    axes = [int(a) for a in axes]
    if len(axes) > 1 and axes == list(range(axes[0], axes[0] + len(axes))):
        return f"A{axes[0]}..A{axes[-1]}"
    return ", ".join(f"A{a}" for a in axes)


def _fit_robot(job: Job, opts: FitOptions, log) -> list[dict]:
    from kukaid.identify.fitted import robot_of
    from kukaid.identify.robot_fit import RobotFitSettings, fit_robot

    if len(log.axes) == 1:  # what the log is and what --robot takes, not the robot's axes it lacks
        raise KukaidError(f"{job.name}: a log of one axis ({_axes_text(log.axes)}), but fleet fit --robot fits "
                          "whole-arm logs: fit logs of one axis without --robot")
    model = robot_of(opts.robot)  # the URDF read once per worker
    fm = "coulomb-viscous" if opts.friction_model == "auto" else opts.friction_model
    p = fit_robot([log], model, RobotFitSettings(friction=fm))
    fr = p["friction"]
    vals, sig = fr["values"], fr.get("sigma") or {}
    noise = (p.get("metrics") or {}).get("noise_sigma") or []
    # a friction term on its bound 0 is the bound's value (the solver leaves -1e-8: show and report print 0)
    at_bound = set((p.get("metrics") or {}).get("at_bound") or [])
    text = json.dumps(p)
    rows = []
    for k, a in enumerate(log.axes):
        r = _base(job, "fit")
        g = lambda name, d=vals: d.get(f"A{a}.{name}")  # noqa: E731
        fric = {n: 0.0 if f"A{a}.{n}" in at_bound and g(n) is not None else g(n) for n in ("Fc", "Fv", "Fs")}
        r.update(status="ok", axis=int(a), friction_model=fm, **fric, offset=g("offset"),
                 Fc_std=g("Fc", sig), Fv_std=g("Fv", sig),
                 rmse=noise[k] if k < len(noise) else None, n_samples=log.n_samples, log_duration=log.duration,
                 result=text if k == 0 else None, **_temp(log, a))
        rows.append(r)
    return rows


def fit_task(job: Job, options: FitOptions) -> list[dict]:
    """The fleet's fit of one log: its rows (one per axis; an error row when it fails)."""
    return guarded("fit", _fit_body, job, options)


#: what a task does to a log, as the duplicate row says it ("not validated twice")
_DONE = {"fit": "fitted", "validate": "validated", "diagnose": "diagnosed"}


def duplicate_row(job: Job, kind: str, first: str) -> dict:
    """The row of a log whose content is that of ``first`` (not fitted again)."""
    return _finish([error_row(job, kind, f"duplicate: the same content as {first} "
                                            f"(not {_DONE.get(kind, kind)} twice)")],
                   time.perf_counter())[0]


@dataclass(frozen=True)
class CheckOptions:
    """Options of ``fleet validate`` and ``fleet diagnose``: the models come from a fit table.

    table : absolute path of the fleet table of ``fleet fit`` (read once per worker).
    kind : "validate" (each log predicted by the latest earlier fit of its robot and axis) or
        "diagnose" (each log against its own fit).
    run : the stage's function, passed in by the caller (a strategy: ``validate(params, logs, axis)``
        returning {axis: score}, or what ``kukaid diagnose`` runs on a fitted model of either kind,
        ``run(model, logs)`` (:func:`kukaid.diagnose.diagnose_model`) returning (diagnosis, draw), the
        diagnosis with ``to_json()`` and ``joints()``); sent to the workers by reference.
    """

    table: str
    kind: str
    run: Callable[..., Any]

    def settings(self) -> dict:
        return {"task": self.kind, "table": self.table}


@functools.lru_cache(maxsize=2)
def _fits(table: str, mtime: float) -> tuple[dict, dict, str | None]:
    """{sha256: parameter dict JSON, and (sha256, axis): that of the axis} and {(robot, axis): [(date, sha256)]
    sorted} of a fit table's ok rows, and the robot (URDF or name) of its whole-arm fits (fleet fit --robot;
    None: one-axis fits).  A log fitted for two of its axes has one hash and a fit per axis."""
    from kukaid.fleet.table import FIT_TABLE, read_table

    rows, settings = read_table(table, FIT_TABLE)
    if settings.get("task") != "fit":
        raise KukaidError(f"{table}: not a table of fleet fit (its rows are of fleet {settings.get('task')})")
    params, by_axis = {}, {}
    for r in rows:
        if r["status"] != "ok":
            continue
        if r.get("result"):
            params.setdefault(r["sha256"], r["result"])
            params[(r["sha256"], r["axis"])] = r["result"]
        by_axis.setdefault((r["robot"], r["axis"]), []).append((r["date"], r["sha256"]))
    for v in by_axis.values():
        v.sort()
    return params, by_axis, settings.get("robot")


def _model_for(job: Job, opts: CheckOptions, axis: int | None) -> tuple[dict, str]:
    params, by_axis, _ = _fits(opts.table, os.path.getmtime(opts.table))

    def fit_of(sha: str) -> str | None:  # the fit of this axis of the log, else the log's (a whole arm's)
        return params.get((sha, axis)) or params.get(sha)

    if opts.kind == "diagnose":
        if fit_of(job.sha256) is None:
            raise KukaidError(f"{job.name}: no fit of this log in {os.path.basename(opts.table)}")
        return json.loads(fit_of(job.sha256)), job.date
    earlier = [(d, sha) for d, sha in by_axis.get((job.robot, axis), []) if d < job.date and fit_of(sha) is not None]
    if not earlier:
        what = f"{job.robot} A{axis}" if axis is not None else job.robot
        raise KukaidError(f"{job.name}: no fit of {what} from a day before {job.date} in "
                          f"{os.path.basename(opts.table)} to validate")
    d, sha = earlier[-1]
    return json.loads(fit_of(sha)), d


def _other_kind(job: Job, log, table: str) -> None:
    """A log of the other kind than the table's fits (a whole-arm log and one-axis fits, or the
    reverse): one line saying what the log is and what the table holds."""
    robot = _fits(table, os.path.getmtime(table))[2]
    name = os.path.basename(table)
    if robot is None and job.axis is None and len(log.axes) > 1:
        raise KukaidError(f"{job.name}: a whole-arm log ({_axes_text(log.axes)}), but {name} holds one-axis fits "
                          "(fleet fit without --robot): give the table fleet fit --robot made of these logs")
    if robot is not None and len(log.axes) == 1:
        raise KukaidError(f"{job.name}: a log of one axis ({_axes_text(log.axes)}), but {name} holds whole-arm fits "
                          f"(fleet fit --robot {robot}): give the table fleet fit made of these logs without --robot")


def _check_body(job: Job, opts: CheckOptions) -> list[dict]:
    log = read_job_log(job)
    axis = job.axis if job.axis is not None else (log.axes[0] if len(log.axes) == 1 else None)
    first = axis if axis is not None else log.axes[0]
    try:
        params, model_date = _model_for(job, opts, first)
    except KukaidError:
        _other_kind(job, log, opts.table)  # no fit of it: say so of a log the table could not have fitted
        raise
    if opts.kind == "validate":
        scores = opts.run(params, [log], axis)
        rows = []
        for ax, sc in scores.items():
            r = _base(job, "validate")
            r.update(status="ok", axis=int(ax), rmse=sc.rmse, rel_error=sc.rel_error, n_samples=log.n_samples,
                     log_duration=log.duration, model_date=model_date,
                     result=json.dumps({"axis": int(ax), **sc.to_json(), "model_date": model_date}), **_temp(log, ax))
            rows.append(r)
        return rows
    from kukaid.identify.fitted import model_for
    from kukaid.jsonfile import jsonable

    # as kukaid diagnose: one entry for a fit of one axis or of a whole arm
    model = model_for(params, axis, f"{job.name}: its fit in {os.path.basename(opts.table)}")
    d, _ = opts.run(model, [log])
    text = json.dumps(jsonable(d.to_json()))
    rows = []
    for k, j in enumerate(d.joints()):
        r = _base(job, "diagnose")
        r.update(status="ok", axis=j["axis"], rmse=j["rmse"], rel_error=j["rel_error"], n_samples=log.n_samples,
                 log_duration=log.duration, effects=",".join(j["effects"]), result=text if k == 0 else None,
                 **(_temp(log, j["axis"]) if j["axis"] in log.axes else {}))
        rows.append(r)
    return rows


def check_task(job: Job, options: CheckOptions) -> list[dict]:
    """``fleet validate`` / ``fleet diagnose`` of one log: its rows (an error row when it fails)."""
    return guarded(options.kind, _check_body, job, options)
