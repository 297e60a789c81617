"""The run log of ``kukaid run-admittance``: an HDF5 axis log plus a ``control`` group.

Top level: the axis-log contract (``time``, ``q``, ``tau``, ``q_cmd``, ``tau_ext_true`` as (N, 1)
arrays, attribute ``axes``), so ``kukaid.logs.read_hdf5`` reads it.  Group ``control``:
per-cycle datasets ``gamma_r``, ``gamma_p`` (N·m), ``sigma`` (rad), ``sigma_dot`` (rad/s), ``D``
(N·m·s/rad), ``osc_index`` (N·m, the oscillation index), ``D_floor`` (N·m·s/rad, the damping the
stability monitor imposes, 0 when inactive), ``dynamic``, ``detected``, ``clipped`` (0/1), ``phase`` (0 initiation move, 1 rest,
2 admittance, 3 stopped), and attributes ``metrics`` and ``config`` (JSON). A run of a robot
parameter file (a backend that reads every axis each cycle) also keeps ``q_all`` (rad) and
``tau_all`` (N·m), (N, A) over axes A1..A(A), in ``control``: the model's Γr of the guided axis can
be computed again from them.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from kukaid.atomic import atomic_path
from kukaid.jsonfile import jsonable


def _json(x: Any) -> str:
    return json.dumps(jsonable(x))


def write_run(path: str | Path, run: Any, axis: int = 3, attrs: dict[str, Any] | None = None) -> None:
    """Write an :class:`~kukaid.control.loop.AdmittanceRun` to ``path`` atomically."""
    import h5py

    from kukaid.control.loop import PHASE_STOPPED, config_dict
    from kukaid.logs import AxisLog, write_hdf5

    d = dict(run.data)
    te = d["tau_ext_true"]
    # keep the time axis strictly increasing (a stopped run's last row may repeat a measurement):
    # the stop is then marked on the row it repeats, so the log's last phase says the run stopped
    keep = np.concatenate([[True], np.diff(d["time"]) > 0]) if d["time"].size else np.zeros(0, bool)
    stopped = np.flatnonzero(~keep & (d["phase"] == PHASE_STOPPED))
    if stopped.size:
        d["phase"] = d["phase"].copy()
        d["phase"][stopped - 1] = PHASE_STOPPED
    log = AxisLog(time=d["time"][keep], q=d["q"][keep, None], tau=d["tau"][keep, None], axes=(axis,),
                  q_cmd=d["q_cmd"][keep, None],
                  tau_ext_true=te[keep, None] if np.all(np.isfinite(te)) else None,
                  attrs={"source": "kukaid run-admittance", "experiment": "admittance", **(attrs or {})})
    with atomic_path(path) as tmp:
        write_hdf5(log, tmp)
        with h5py.File(tmp, "a") as f:
            g = f.create_group("control")
            for k in ("gamma_r", "gamma_p", "sigma", "sigma_dot", "D", "osc_index", "D_floor", "D_grip", "q_all",
                      "tau_all"):
                if k in d:
                    g.create_dataset(k, data=d[k][keep])
            for k in ("dynamic", "detected", "clipped", "phase"):
                g.create_dataset(k, data=d[k][keep].astype(np.int8))
            g.attrs["metrics"] = _json(run.metrics)
            g.attrs["config"] = _json(config_dict(run.config))
            g.attrs["units"] = _json({"gamma_r": "N*m", "gamma_p": "N*m", "sigma": "rad", "sigma_dot": "rad/s",
                                      "D": "N*m*s/rad", "osc_index": "N*m", "D_floor": "N*m*s/rad",
                                      "D_grip": "N*m*s/rad", "q_all": "rad", "tau_all": "N*m"})


def read_run(path: str | Path) -> tuple[Any, dict[str, np.ndarray], dict[str, Any]]:
    """Read a run log: (AxisLog, control datasets, metrics)."""
    import h5py

    from kukaid.errors import LogFormatError
    from kukaid.logs import read_hdf5

    log = read_hdf5(path)
    with h5py.File(path, "r") as f:
        if "control" not in f:
            raise LogFormatError(f"{path}: not a run-admittance log (no 'control' group)")
        g = f["control"]
        data = {k: np.asarray(g[k][()]) for k in g}
        metrics = json.loads(g.attrs["metrics"])
    return log, data, metrics
