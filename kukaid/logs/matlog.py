"""MAT files (MATLAB) as axis logs: variables mapped to channels, with unit and scale options.

Example, the EMPS benchmark (prismatic drive, metres, force = gtau * vir)::

    read_mat("DATA_EMPS.mat", time="t", q="qm", tau="vir", tau_scale_var="gtau", q_cmd="qg",
             joint="prismatic", axis=1)

Each channel value is ``variable * scale``; ``q_scale`` converts the position to SI (e.g.
``pi/180`` for degrees).  The torque scale is given once: a number (``tau_scale``) or a scalar
variable of the file (``tau_scale_var``), not both.  MATLAB v7.3 files (HDF5) are read with h5py.

A struct field is a variable named with dots (``rec.act_pos_mot_deg``, ``rec.x.y``); a
(samples, axes) array is several axes at once (``axis=[1, 2, 3]``, ``--axis 1,2,3``).
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Iterable

import numpy as np

from kukaid.errors import LogFormatError
from kukaid.logs.core import AxisLog, check_samples, check_units

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


def _flatten(name: str, x: Any, v: dict[str, Any], other: dict[str, str]) -> None:
    """Add variable ``name`` to ``v``; a struct's fields too, as ``name.field`` (nested: ``a.b.c``)."""
    arr = np.asarray(x)
    v[name] = arr
    if arr.dtype.names:  # a MATLAB struct (scipy: a record array, each field an object cell)
        if arr.size != 1:
            other[name] = f"a struct array of {arr.size} elements"
            return
        other[name] = f"a struct with fields {', '.join(arr.dtype.names)}; name one as {name}.<field>"
        for f in arr.dtype.names:
            _flatten(f"{name}.{f}", arr[f].reshape(-1)[0], v, other)
    elif (kind := _kind(arr)) is not None:
        other[name] = kind


def _h5_flatten(name: str, obj, v: dict[str, Any], other: dict[str, str]) -> None:
    """v7.3: datasets are variables (MATLAB_class names the class), groups are structs."""
    cls = obj.attrs.get("MATLAB_class", b"double" if hasattr(obj, "shape") else b"struct")
    cls = cls.decode(errors="replace") if isinstance(cls, bytes) else str(cls)
    if not hasattr(obj, "shape"):
        if cls != "struct":
            other[name] = f"a MATLAB {cls}"
            v[name] = np.zeros(0)
            return
        fields = [k for k in obj.keys() if not k.startswith("#")]
        v[name] = np.zeros(0)
        other[name] = f"a struct with fields {', '.join(fields)}; name one as {name}.<field>"
        for k in fields:
            _h5_flatten(f"{name}.{k}", obj[k], v, other)
        return
    v[name] = np.asarray(obj[()]).T  # MATLAB stores column-major
    if cls not in _NUMERIC_CLASSES:
        other[name] = "text" if cls in ("char", "string") else f"a MATLAB {cls}"
    elif (kind := _kind(v[name])) is not None:
        other[name] = kind


def _load_vars(path: Path) -> tuple[dict[str, np.ndarray], dict[str, str]]:
    """The variables of a MAT file (struct fields as ``rec.field``), and for each non-numeric one
    what it holds."""
    try:
        from scipy.io import loadmat

        d = loadmat(str(path))
        v: dict[str, Any] = {}
        other: dict[str, str] = {}
        for k, x in d.items():
            if not k.startswith("__"):
                _flatten(k, x, v, other)
        return v, other
    except NotImplementedError:  # v7.3: HDF5
        pass
    except Exception as e:  # noqa: BLE001 - any parse failure is a format error
        raise LogFormatError(f"{path}: not a readable MAT file: {(str(e).splitlines() or [''])[0][:160]}") from None
    try:
        import h5py

        v, other = {}, {}
        with h5py.File(path, "r") as f:
            for k in f.keys():
                if not k.startswith("#"):  # '#refs#' holds the cells of cell arrays
                    _h5_flatten(k, f[k], v, other)
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


def check_mat_options(path: str | Path, tau_scale: Any = None, tau_scale_var: str | None = None, q_scale: Any = 1.0,
                      time_scale: Any = 1.0, sample_time: Any = None) -> tuple[Any, float, float, Any]:
    """The options of :func:`read_mat` that need no file: the torque scale given once, every scale
    finite and non-zero (time scale and sample time positive).  Returns (tau_scale, q_scale,
    time_scale, sample_time) as floats (None stays None); raises :class:`LogFormatError`."""
    path = Path(path)
    if tau_scale is not None and tau_scale_var is not None:
        raise LogFormatError(f"{path}: give the torque scale once, --tau-scale or --tau-scale-var, not both")
    return (_scale(path, tau_scale, "the torque scale (--tau-scale)"),
            _scale(path, 1.0 if q_scale is None else q_scale, "the position scale (--q-scale)"),
            _scale(path, 1.0 if time_scale is None else time_scale, "the time scale (--time-scale)", positive=True),
            _scale(path, sample_time, "the sample time (--sample-time)", positive=True))


def read_mat(path: str | Path, time: str | None = None, q: str | None = None, tau: str | None = None,
             q_cmd: str | None = None, temp: str | None = None, tau_scale: float | None = None,
             tau_scale_var: str | None = None, q_scale: float = 1.0, time_scale: float = 1.0,
             joint: str | None = "revolute", axis: int | Iterable[int] = 1, sample_time: float | None = None,
             hints: list[str] | None = None, **_ignored: Any):
    """Read a MAT file as an :class:`~kukaid.logs.core.AxisLog` of one or more axes (SI units).

    Parameters
    ----------
    time, q, tau, q_cmd, temp : names of the MAT variables (defaults: ``time``/``t``, ``q``,
        ``tau``; optional channels only when named).  A struct field is named with dots
        (``rec.act_pos_mot_deg``, nested ``rec.x.y``), in v5 and v7.3 (HDF5) files alike.  Each
        must be numeric (not text, a cell array or a struct): a vector for one axis, or a
        (samples, axes) array (or its transpose) with one column per number in ``axis``.
    tau_scale : torque (force) scale, e.g. 35.15 N/V; or ``tau_scale_var``: a scalar variable in
        the file holding it (``gtau`` in EMPS); not both.   q_scale : position (and q_cmd) scale
        to rad or m.  Every scale must be a finite non-zero number.
    time_scale : to seconds (positive).   sample_time : build the time base when the file has
        none (s, positive).
    joint : "revolute" or "prismatic" (every axis); None: not said, read as revolute (and a hint
        says so).   axis : the axis number of the log, or a list of them, one per column of the
        (samples, axes) arrays.
    hints : a list that gets one line per unit the file leaves open and the reading assumed (a MAT
        file carries no units): the joint type when ``joint`` is None, and a torque read unscaled
        while the file holds a scalar named like a torque or force gain (EMPS: ``gtau``), each
        naming the option that says otherwise.

    Raises
    ------
    LogFormatError : one line naming the file and the variable or option that is wrong.
    """
    path = Path(path)
    joint_said = joint is not None
    joint = joint or "revolute"
    axes = tuple(int(a) for a in np.atleast_1d(axis))
    n_ax = len(axes)
    tau_scale, q_scale, time_scale, sample_time = check_mat_options(path, tau_scale, tau_scale_var, q_scale,
                                                                    time_scale, sample_time)
    if not path.exists():
        raise LogFormatError(f"{path}: no such file")
    if path.stat().st_size == 0:  # as the other readers say it (scipy: "Mat file appears to be truncated")
        raise LogFormatError(f"{path}: empty file")
    v, not_numeric = _load_vars(path)
    # a struct is listed with its fields: a MATLAB recording is often one struct, whose fields are named with dots
    names = sorted(k for k in v if "." not in k)
    names = [f"{k} ({not_numeric[k]})" if "struct with fields" in not_numeric.get(k, "") else k for k in names]

    def lookup(name: str, role: str) -> np.ndarray:
        if name not in v:
            head, _, field = name.rpartition(".")
            if head in v and head in not_numeric and "struct with fields" in not_numeric[head]:
                fields = sorted(k[len(head) + 1:] for k in v if k.startswith(head + ".") and "." not in k[len(head) + 1:])
                raise LogFormatError(f"{path}: struct '{head}' has no field '{field}' for {role} "
                                     f"(fields: {', '.join(fields)})")
            raise LogFormatError(f"{path}: no variable '{name}' for {role} (variables: {', '.join(names)})")
        if name in not_numeric:
            raise LogFormatError(f"{path}: variable '{name}' ({role}) is not numeric: it holds {not_numeric[name]}")
        x = np.asarray(v[name], dtype=float)
        if x.size == 0:  # it said "shape (0, 0): 0 axes, but --axis lists 1"
            raise LogFormatError(f"{path}: variable '{name}' ({role}) is empty: no samples")
        return x

    def vector(name: str, role: str) -> np.ndarray:
        x = np.atleast_1d(lookup(name, role).squeeze())
        if x.ndim != 1:
            raise LogFormatError(f"{path}: variable '{name}' ({role}) has shape {np.shape(v[name])}, expected a vector")
        return x

    def per_axis(name: str, role: str) -> np.ndarray:
        """(samples, axes) from a vector (one axis) or a 2-D array with one column (or row) per axis."""
        x = lookup(name, role)
        x = x.reshape(x.shape[0], -1) if x.ndim > 2 and x.size else x
        if x.ndim <= 1 or 1 in x.shape:
            if n_ax == 1:
                return np.atleast_1d(x.squeeze()).reshape(-1, 1)
            raise LogFormatError(f"{path}: variable '{name}' ({role}) is a vector but --axis lists {n_ax} axes "
                                 f"{list(axes)}; give a (samples, {n_ax}) array")
        if x.ndim == 2 and x.shape[1] == n_ax:
            return x
        if x.ndim == 2 and x.shape[0] == n_ax:
            return x.T
        cols = min(x.shape) if x.ndim == 2 else x.shape
        raise LogFormatError(f"{path}: variable '{name}' ({role}) has shape {np.shape(v[name])}: {cols} axes, but "
                             f"--axis lists {n_ax} ({', '.join(map(str, axes))}); give one axis number per column")

    qn = q or ("q" if "q" in v else None)
    tn = tau or ("tau" if "tau" in v else None)
    if qn is None or tn is None:
        # the other commands read a MAT file with the defaults alone: the options are kukaid load's
        raise LogFormatError(f"{path}: no variables 'q' and 'tau': name the position and torque variables, "
                             f"kukaid load {path} --q VAR --tau VAR -o LOG.h5, and give LOG.h5; variables: "
                             f"{', '.join(names)}")
    qa = per_axis(qn, "position") * q_scale
    ta = per_axis(tn, "torque")
    if tau_scale_var is not None:
        s = vector(tau_scale_var, "torque scale")
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
        t = vector(tn_name, "time") * time_scale
    elif sample_time is not None:
        t = np.arange(qa.shape[0]) * sample_time
    else:
        raise LogFormatError(f"{path}: no time variable ('time' or 't'): name it or give the sample interval, kukaid "
                             f"load {path} --time VAR (or --sample-time S) -o LOG.h5, and give LOG.h5; variables: "
                             f"{', '.join(names)}")
    extra = {}
    for ch, nm, sc in (("q_cmd", q_cmd, q_scale), ("temp", temp, 1.0)):
        if nm is not None:
            extra[ch] = per_axis(nm, ch) * sc
    for nm, x in ((tn, ta), (qn, qa), *((n, extra[c]) for c, n in (("q_cmd", q_cmd), ("temp", temp)) if n)):
        if x.shape[0] != t.size:
            raise LogFormatError(f"{path}: variable '{nm}' has {x.shape[0]} samples but time has {t.size}")
    # unit mistakes (milliseconds as seconds, degrees without --q-scale) name the variables
    col = (lambda c: "") if n_ax == 1 else (lambda c: f" (column {c + 1})")
    labels: dict[Any, str] = {"time": f"time variable '{tn_name}'" if tn_name else "the time base (--sample-time)"}
    for c, a in enumerate(axes):
        labels[("q", a)] = f"position variable '{qn}'{col(c)}"
        if q_cmd:
            labels[("q_cmd", a)] = f"commanded position variable '{q_cmd}'{col(c)}"
    if hints is not None:
        hints.extend(_unit_hints(path, v, qn, tn, joint_said, tau_scale is not None or tau_scale_var is not None))
    chans = {"q": qa, "tau": ta, **extra}
    joints = (joint,) * n_ax
    check_samples(t, chans, axes, str(path), row_offset=1, row_word="MATLAB index")  # q(101) is row 100 from 0
    # the scales that correct them are kukaid load's options (the other commands read a MAT file with the defaults)
    fixes = {"q": f"kukaid load {path} --q-scale 0.0174533 reads degrees (1.74533e-05 millidegrees)",
             **({"time": f"kukaid load {path} --time-scale 0.001 reads milliseconds"} if tn_name else {})}
    check_units(t, chans, axes, joints, str(path), labels=labels, fixes=fixes)
    attrs = {"source_file": str(path), "source": "mat", "mat_variables": {"time": tn_name, "q": qn, "tau": tn, **{
        k: n for k, n in (("q_cmd", q_cmd), ("temp", temp)) if n}}}
    return AxisLog(time=t, q=qa, tau=ta, axes=axes, joint=joints, attrs=attrs, **extra)


#: names of scalars that hold a torque or force gain (EMPS: gtau, N/V)
_GAIN_NAME = ("tau", "torque", "force", "gain", "kt")


def _unit_hints(path: Path, v: dict[str, Any], qn: str, tn: str, joint_said: bool, tau_scaled: bool) -> list[str]:
    """The units :func:`read_mat` assumed where the file says nothing, each with the option that
    says otherwise (see its ``hints``)."""
    out = []
    if not joint_said:
        out.append(f"{path}: a MAT file does not say its units: '{qn}' is read as rad and '{tn}' as N·m (a revolute "
                   "axis); for a linear axis (m, N) pass --joint prismatic (--joint revolute confirms this reading)")
    if not tau_scaled:
        gains = sorted(k for k, x in v.items() if k != tn and any(g in k.rsplit(".", 1)[-1].lower() for g in _GAIN_NAME)
                       and np.size(x) == 1 and _kind(np.asarray(x)) is None and np.isfinite(np.asarray(x, float)).all())
        if gains:
            g = gains[0]
            out.append(f"{path}: '{tn}' is read as a torque unscaled, but the file holds {g} = "
                       f"{float(np.asarray(v[g], float).squeeze()):.6g}, a scalar named like a torque or force gain: if "
                       f"'{tn}' is a drive signal (a voltage, a current), pass --tau-scale-var {g}")
    return out

