"""MAT files (MATLAB) as axis logs: variables mapped to channels, with unit and scale options.

Example, the EMPS benchmark (prismatic drive, metres, force = gtau * vir)::

    read_mat("DATA_EMPS.mat", time="t", q="qm", tau="vir", tau_scale_var="gtau", q_cmd="qg",
             joint="prismatic", axis=1)

Each channel value is ``variable * scale``; ``q_scale`` converts the position to SI (e.g.
``pi/180`` for degrees).  The torque scale is given once: a number (``tau_scale``) or a scalar
variable of the file (``tau_scale_var``), not both.  MATLAB v7.3 files (HDF5) are read with h5py.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from kukaid.errors import LogFormatError

#: MATLAB classes of numeric arrays (v7.3 files name the class in the attribute MATLAB_class).
_NUMERIC_CLASSES = {"double", "single", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64", "uint64",
                    "logical"}


def _kind(x: np.ndarray) -> str | None:
    """What a non-numeric variable holds ("text", "complex numbers", ...); None if it is numeric."""
    k = np.asarray(x).dtype.kind
    if k in "biuf":
        return None
    if k in "US":
        return "text"
    if k == "c":
        return "complex numbers"
    if k == "V":
        return "a struct or object"
    return "a cell array or object"


def _load_vars(path: Path) -> tuple[dict[str, np.ndarray], dict[str, str]]:
    """The variables of a MAT file, and for each non-numeric one what it holds."""
    try:
        from scipy.io import loadmat

        d = loadmat(str(path))
        v = {k: x for k, x in d.items() if not k.startswith("__")}
        return v, {k: kind for k, x in v.items() if (kind := _kind(x)) is not None}
    except NotImplementedError:  # v7.3: HDF5
        pass
    except Exception as e:  # noqa: BLE001 - any parse failure is a format error
        raise LogFormatError(f"{path}: not a readable MAT file: {(str(e).splitlines() or [''])[0][:160]}") from None
    try:
        import h5py

        v, other = {}, {}
        with h5py.File(path, "r") as f:
            for k in f.keys():
                if not hasattr(f[k], "shape"):
                    continue  # groups: structs, and the '#refs#' of cell arrays
                cls = f[k].attrs.get("MATLAB_class", b"double")
                cls = cls.decode(errors="replace") if isinstance(cls, bytes) else str(cls)
                v[k] = np.asarray(f[k][()]).T
                if cls not in _NUMERIC_CLASSES:
                    other[k] = "text" if cls in ("char", "string") else f"a MATLAB {cls}"
                elif (kind := _kind(v[k])) is not None:
                    other[k] = kind
        return v, other
    except Exception as e:  # noqa: BLE001 - any parse failure is a format error
        raise LogFormatError(f"{path}: not a readable MAT file (v7.3): {(str(e).splitlines() or [''])[0][:160]}") \
            from None


def _scale(path: Path, value: Any, what: str, positive: bool = False) -> float | None:
    """A scale option as a float: finite and non-zero (positive for time); None stays None."""
    if value is None:
        return None
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise LogFormatError(f"{path}: {what} must be a number; got {value!r}") from None
    if not math.isfinite(x) or x == 0 or (positive and x < 0):
        need = "a finite positive number" if positive else "a finite non-zero number"
        raise LogFormatError(f"{path}: {what} must be {need}; got {x:g}")
    return x


def read_mat(path: str | Path, time: str | None = None, q: str | None = None, tau: str | None = None,
             q_cmd: str | None = None, temp: str | None = None, tau_scale: float | None = None,
             tau_scale_var: str | None = None, q_scale: float = 1.0, time_scale: float = 1.0,
             joint: str = "revolute", axis: int = 1, sample_time: float | None = None, **_ignored: Any):
    """Read a MAT file as a one-axis :class:`~kukaid.logs.axislog.AxisLog` (SI units).

    Parameters
    ----------
    time, q, tau, q_cmd, temp : names of the MAT variables (defaults: ``time``/``t``, ``q``,
        ``tau``; optional channels only when named).  Each must be numeric (not text, a cell
        array or a struct).
    tau_scale : torque (force) scale, e.g. 35.15 N/V; or ``tau_scale_var``: a scalar variable in
        the file holding it (``gtau`` in EMPS); not both.   q_scale : position (and q_cmd) scale
        to rad or m.  Every scale must be a finite non-zero number.
    time_scale : to seconds (positive).   sample_time : build the time base when the file has
        none (s, positive).
    joint : "revolute" or "prismatic".   axis : axis number to give the log.

    Raises
    ------
    LogFormatError : one line naming the file and the variable or option that is wrong.
    """
    from kukaid.logs.axislog import AxisLog

    path = Path(path)
    if tau_scale is not None and tau_scale_var is not None:
        raise LogFormatError(f"{path}: give the torque scale once, --tau-scale or --tau-scale-var, not both")
    tau_scale = _scale(path, tau_scale, "the torque scale (--tau-scale)")
    q_scale = _scale(path, 1.0 if q_scale is None else q_scale, "the position scale (--q-scale)")
    time_scale = _scale(path, 1.0 if time_scale is None else time_scale, "the time scale (--time-scale)",
                        positive=True)
    sample_time = _scale(path, sample_time, "the sample time (--sample-time)", positive=True)
    if not path.exists():
        raise LogFormatError(f"{path}: no such file")
    v, not_numeric = _load_vars(path)
    names = sorted(v)

    def get(name: str | None, role: str, required: bool) -> np.ndarray | None:
        if name is None:
            return None
        if name not in v:
            if required:
                raise LogFormatError(f"{path}: no variable '{name}' for {role} (variables: {', '.join(names)})")
            return None
        if name in not_numeric:
            raise LogFormatError(f"{path}: variable '{name}' ({role}) is not numeric: it holds {not_numeric[name]}")
        x = np.atleast_1d(np.asarray(v[name], dtype=float).squeeze())
        if x.ndim != 1:
            raise LogFormatError(f"{path}: variable '{name}' ({role}) has shape {np.shape(v[name])}, expected a vector")
        return x

    qn = q or ("q" if "q" in v else None)
    tn = tau or ("tau" if "tau" in v else None)
    if qn is None or tn is None:
        raise LogFormatError(f"{path}: name the position and torque variables (--q, --tau); variables: {', '.join(names)}")
    qa = get(qn, "position", True) * q_scale
    ta = get(tn, "torque", True)
    if tau_scale_var is not None:
        s = get(tau_scale_var, "torque scale", True)
        if s.size != 1:
            raise LogFormatError(f"{path}: torque scale variable '{tau_scale_var}' is not a scalar")
        if not (np.isfinite(s[0]) and s[0] != 0):
            raise LogFormatError(f"{path}: torque scale variable '{tau_scale_var}' is {s[0]:g}; a scale must be a "
                                 f"finite non-zero number")
        ta = ta * float(s[0])
    if tau_scale is not None:
        ta = ta * tau_scale
    tn_name = time or ("time" if "time" in v else ("t" if "t" in v else None))
    if tn_name is not None:
        t = get(tn_name, "time", True) * time_scale
    elif sample_time is not None:
        t = np.arange(qa.size) * sample_time
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
            extra[ch] = x * sc
    # unit mistakes (milliseconds as seconds, degrees without --q-scale) name the variables
    from kukaid.logs.axislog import check_samples, check_units

    labels = {"time": f"time variable '{tn_name}'" if tn_name else "the time base (--sample-time)",
              ("q", int(axis)): f"position variable '{qn}'"}
    if q_cmd:
        labels[("q_cmd", int(axis))] = f"commanded position variable '{q_cmd}'"
    chans = {"q": qa[:, None], "tau": ta[:, None], **{k: x[:, None] for k, x in extra.items()}}
    check_samples(t, chans, (int(axis),), str(path))
    check_units(t, chans, (int(axis),), (joint,), str(path), labels=labels)
    attrs = {"source_file": str(path), "source": "mat", "mat_variables": {"time": tn_name, "q": qn, "tau": tn, **{
        k: n for k, n in (("q_cmd", q_cmd), ("temp", temp)) if n}}}
    return AxisLog(time=t, q=qa, tau=ta, axes=(int(axis),), joint=(joint,), attrs=attrs, **extra)
