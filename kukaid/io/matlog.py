"""MAT files (MATLAB) as axis logs: variables mapped to channels, with unit and scale options.

Example, the EMPS benchmark (prismatic drive, metres, force = gtau * vir)::

    read_mat("DATA_EMPS.mat", time="t", q="qm", tau="vir", tau_scale_var="gtau", q_cmd="qg",
             joint="prismatic", axis=1)

Each channel value is ``variable * scale``; ``q_scale`` converts the position to SI (e.g.
``pi/180`` for degrees).  MATLAB v7.3 files (HDF5) are read with h5py.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from kukaid.errors import LogFormatError


def _load_vars(path: Path) -> dict[str, np.ndarray]:
    try:
        from scipy.io import loadmat

        d = loadmat(str(path))
        return {k: v for k, v in d.items() if not k.startswith("__")}
    except NotImplementedError:  # v7.3: HDF5
        import h5py

        with h5py.File(path, "r") as f:
            return {k: np.asarray(f[k][()]).T for k in f.keys() if hasattr(f[k], "shape")}
    except Exception as e:  # noqa: BLE001 - any parse failure is a format error
        raise LogFormatError(f"{path}: not a readable MAT file: {str(e).splitlines()[0][:160]}") from None


def read_mat(path: str | Path, time: str | None = None, q: str | None = None, tau: str | None = None,
             q_cmd: str | None = None, temp: str | None = None, tau_scale: float | None = None,
             tau_scale_var: str | None = None, q_scale: float = 1.0, time_scale: float = 1.0,
             joint: str = "revolute", axis: int = 1, sample_time: float | None = None, **_ignored: Any):
    """Read a MAT file as a one-axis :class:`~kukaid.io.axislog.AxisLog` (SI units).

    Parameters
    ----------
    time, q, tau, q_cmd, temp : names of the MAT variables (defaults: ``time``/``t``, ``q``,
        ``tau``; optional channels only when named).
    tau_scale : torque (force) scale, e.g. 35.15 N/V; or ``tau_scale_var``: a scalar variable in
        the file holding it (``gtau`` in EMPS).   q_scale : position (and q_cmd) scale to rad or m.
    time_scale : to seconds.   sample_time : build the time base when the file has none (s).
    joint : "revolute" or "prismatic".   axis : axis number to give the log.
    """
    from kukaid.io.axislog import AxisLog

    path = Path(path)
    if not path.exists():
        raise LogFormatError(f"{path}: no such file")
    v = _load_vars(path)
    names = sorted(v)

    def get(name: str | None, role: str, required: bool) -> np.ndarray | None:
        if name is None:
            return None
        if name not in v:
            if required:
                raise LogFormatError(f"{path}: no variable '{name}' for {role} (variables: {', '.join(names)})")
            return None
        x = np.atleast_1d(np.asarray(v[name], dtype=float).squeeze())
        if x.ndim != 1:
            raise LogFormatError(f"{path}: variable '{name}' ({role}) has shape {np.shape(v[name])}, expected a vector")
        return x

    qn = q or ("q" if "q" in v else None)
    tn = tau or ("tau" if "tau" in v else None)
    if qn is None or tn is None:
        raise LogFormatError(f"{path}: name the position and torque variables (--q, --tau); variables: {', '.join(names)}")
    qa = get(qn, "position", True) * float(q_scale)
    ta = get(tn, "torque", True)
    if tau_scale_var is not None:
        s = get(tau_scale_var, "torque scale", True)
        if s.size != 1:
            raise LogFormatError(f"{path}: torque scale variable '{tau_scale_var}' is not a scalar")
        ta = ta * float(s[0])
    if tau_scale is not None:
        ta = ta * float(tau_scale)
    tn_name = time or ("time" if "time" in v else ("t" if "t" in v else None))
    if tn_name is not None:
        t = get(tn_name, "time", True) * float(time_scale)
    elif sample_time is not None:
        t = np.arange(qa.size) * float(sample_time)
    else:
        raise LogFormatError(f"{path}: no time variable; name it (--time) or give --sample-time")
    for nm, x in ((tn, ta), (qn, qa)):
        if x.size != t.size:
            raise LogFormatError(f"{path}: variable '{nm}' has {x.size} samples but time has {t.size}")
    extra = {}
    for ch, nm, sc in (("q_cmd", q_cmd, q_scale), ("temp", temp, 1.0)):
        x = get(nm, ch, True)
        if x is not None:
            if x.size != t.size:
                raise LogFormatError(f"{path}: variable '{nm}' has {x.size} samples but time has {t.size}")
            extra[ch] = x * float(sc)
    attrs = {"source_file": str(path), "source": "mat", "mat_variables": {"time": tn_name, "q": qn, "tau": tn, **{
        k: n for k, n in (("q_cmd", q_cmd), ("temp", temp)) if n}}}
    return AxisLog(time=t, q=qa, tau=ta, axes=(int(axis),), joint=(joint,), attrs=attrs, **extra)
