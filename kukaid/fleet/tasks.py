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


def _finish(rows: list[dict], t0: float) -> list[dict]:
    now = datetime.now(timezone.utc).isoformat(timespec="seconds")
    for r in rows:
        r.update(task_s=time.perf_counter() - t0, worker=f"{platform.node()}:{os.getpid()}",
                 worker_peak_mb=peak_rss_mb(), finished_at=now)
    return rows


def error_row(job: Job, kind: str, reason: str) -> dict:
    """The row of a log that gave no result, with ``reason`` (one line)."""
    r = _base(job, kind)
    r.update(status="error", error=" ".join(str(reason).split())[:500])
    return r


def guarded(kind: str, body: Callable[[Job, Any], list[dict]], job: Job, options: Any) -> list[dict]:
    """Run ``body(job, options)``; any failure becomes one error row (a data problem with its
    message, anything else as an internal error naming the exception)."""
    t0 = time.perf_counter()
    try:
        rows = body(job, options)
    except KukaidError as e:
        rows = [error_row(job, kind, str(e))]
    except MemoryError:
        rows = [error_row(job, kind, "out of memory on the worker")]
    except Exception as e:  # a bug or a library failure: the batch goes on, the row says what
        rows = [error_row(job, kind, f"internal error ({type(e).__name__}: {e})")]
    return _finish(rows, t0)


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
                          f"not of A{job.axis} as the manifest says")
    return log


def _temp(log, axis: int) -> dict:
    if log.temp is None:
        return {}
    x = log.temp[:, log.index(axis)]
    return {"temp_mean": float(np.mean(x)), "temp_min": float(np.min(x)), "temp_max": float(np.max(x))}


@functools.lru_cache(maxsize=4)
def _robot_model(robot: str):
    from kukaid.models.robot import RobotModel

    m = RobotModel(robot)
    m.base_parameters()
    return m


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


def _fit_robot(job: Job, opts: FitOptions, log) -> list[dict]:
    from kukaid.identify.robot_fit import RobotFitSettings, fit_robot

    model = _robot_model(opts.robot)
    fm = "coulomb-viscous" if opts.friction_model == "auto" else opts.friction_model
    p = fit_robot([log], model, RobotFitSettings(friction=fm))
    fr = p["friction"]
    vals, sig = fr["values"], fr.get("sigma") or {}
    noise = (p.get("metrics") or {}).get("noise_sigma") or []
    text = json.dumps(p)
    rows = []
    for k, a in enumerate(log.axes):
        r = _base(job, "fit")
        g = lambda name, d=vals: d.get(f"A{a}.{name}")  # noqa: E731
        r.update(status="ok", axis=int(a), friction_model=fm, Fc=g("Fc"), Fv=g("Fv"), offset=g("offset"),
                 Fs=g("Fs"), Fc_std=g("Fc", sig), Fv_std=g("Fv", sig),
                 rmse=noise[k] if k < len(noise) else None, n_samples=log.n_samples, log_duration=log.duration,
                 result=text if k == 0 else None, **_temp(log, a))
        rows.append(r)
    return rows


def fit_task(job: Job, options: FitOptions) -> list[dict]:
    """The fleet's fit of one log: its rows (one per axis; an error row when it fails)."""
    return guarded("fit", _fit_body, job, options)


def duplicate_row(job: Job, kind: str, first: str) -> dict:
    """The row of a log whose content is that of ``first`` (not fitted again)."""
    return _finish([error_row(job, kind, f"duplicate: the same content as {first} (not fitted twice)")],
                   time.perf_counter())[0]
