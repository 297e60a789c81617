"""Axis logs in HDF5, the toolkit's own format (``kukaid.axislog/1``): written atomically by
:func:`write_hdf5`, incrementally by :class:`kukaid.logs.writer.AxisLogWriter`, read and validated
by :func:`read_hdf5`."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from kukaid import __version__
from kukaid.atomic import atomic_path
from kukaid.errors import LogFormatError
from kukaid.logs.core import CHANNELS, FORMAT, JOINT_TYPES, AxisLog, _os_errors, _short, channel_unit, other_kind

_JSON_ATTRS = "_json_attrs"


def _encode_attrs(attrs: dict[str, Any]) -> tuple[dict[str, Any], list[str]]:
    plain, as_json = {}, []
    for k, v in attrs.items():
        if v is None:
            continue
        if isinstance(v, (list, tuple)) and v and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v):
            plain[k] = np.asarray(v)  # numeric lists (axes, sample counts) stay native HDF5 arrays
        elif isinstance(v, (dict, list, tuple)):
            plain[k] = json.dumps(v)
            as_json.append(k)
        elif isinstance(v, (bool, np.bool_)):
            plain[k] = int(v)
        else:
            plain[k] = v
    return plain, as_json


def _base_attrs(axes: tuple[int, ...], joint: tuple[str, ...], attrs: dict[str, Any]) -> dict[str, Any]:
    units = {"time": "s", **{c: [channel_unit(c, j) for j in joint] for c in CHANNELS}}
    out = {k: v for k, v in attrs.items() if k not in ("source_file", "incremental")}
    out.update(axes=list(axes), joint=list(joint), units=units, format=FORMAT)
    out.setdefault("kukaid_version", __version__)
    return out


def _write_attrs(h5obj, attrs: dict[str, Any]) -> None:
    plain, as_json = _encode_attrs(attrs)
    for k, v in plain.items():
        h5obj.attrs[k] = v
    h5obj.attrs[_JSON_ATTRS] = json.dumps(as_json)


def write_hdf5(log: AxisLog, path: str | Path) -> None:
    """Write ``log`` to ``path`` (HDF5) atomically: the file appears whole or not at all.

    A folder that cannot be written (read-only, no space, ...) is a :class:`KukaidError` naming
    ``path`` and the operating system's reason.
    """
    import h5py

    with atomic_path(path) as tmp, _os_errors(path):  # h5py's OSError text -> the OS's reason
        with h5py.File(tmp, "w") as f:
            f.create_dataset("time", data=log.time)
            for name in CHANNELS:
                x = getattr(log, name)
                if x is not None:
                    f.create_dataset(name, data=x)
            attrs = _base_attrs(log.axes, log.joint, log.attrs)
            attrs.setdefault("sample_time", log.sample_time)
            _write_attrs(f, attrs)


def _open_h5(path: Path):
    import h5py

    try:
        return h5py.File(path, "r")
    except OSError as e:
        if "already open for write" in str(e):
            # A capture that was killed leaves the SWMR consistency flag set; its data up to the
            # last flush is intact and readable in SWMR mode.
            try:
                return h5py.File(path, "r", swmr=True)
            except OSError:
                pass
        other = other_kind(path, "HDF5")  # a report, a table, a CSV log renamed .h5
        if other is not None:
            raise other from None
        raise LogFormatError(f"{path}: not a readable HDF5 file (truncated or corrupt): {_short(e)}") from None


def read_hdf5(path: str | Path, whole: bool = False) -> AxisLog:
    """Read an HDF5 axis log; validate it and report what is wrong and where.

    A writer killed mid-flush may leave the datasets of an incremental log of uneven lengths: their
    common rows are read, unless ``whole`` (a copy of the log, ``kukaid load``, must not drop rows
    without a word)."""
    path = Path(path)
    if not path.exists():
        raise LogFormatError(f"{path}: no such file")
    if path.stat().st_size == 0:
        raise LogFormatError(f"{path}: empty file")
    with _open_h5(path) as f:
        try:
            raw = dict(f.attrs)
            fmt = _decode(raw.get("format"))
            if fmt is not None and not (isinstance(fmt, str) and fmt == FORMAT):
                raise LogFormatError(f"{path}: attribute 'format' is {_show(fmt)}, expected '{FORMAT}' "
                                     f"(not a kukaid axis log, or another version)")
            for name in ("time", "q", "tau"):
                if name not in f:
                    other = ("" if fmt is not None else f" (and no 'format' attribute: not a kukaid axis log? Another "
                             "tool's data come in through kukaid load from CSV or MAT, docs/formats.md; its datasets: "
                             f"{', '.join(sorted(f.keys())[:6]) or 'none'})")
                    raise LogFormatError(f"{path}: missing dataset '{name}'{other}")
            if "axes" not in f.attrs:
                raise LogFormatError(f"{path}: missing attribute 'axes'")
            data = {}
            for n in ("time", *CHANNELS):
                if n in f:
                    if not hasattr(f[n], "dtype") or f[n].dtype.kind not in "biuf":
                        raise LogFormatError(f"{path}: '{n}' is not a numeric dataset")
                    data[n] = np.asarray(f[n][()], dtype=float)
            # intervals an incremental capture could not sample (AxisLogWriter.mark_gap), as [[t0, t1], ...]
            gaps = np.asarray(f["gaps"][()], dtype=float).reshape(-1, 2).tolist() if "gaps" in f else []
        except LogFormatError:
            raise
        except (OSError, KeyError, ValueError, TypeError) as e:
            raise LogFormatError(f"{path}: HDF5 data unreadable (truncated or corrupt): {_short(e)}") from None
    as_json = _json_attr(path, _JSON_ATTRS, raw.pop(_JSON_ATTRS, "[]"))
    if not isinstance(as_json, list) or not all(isinstance(k, str) for k in as_json):
        raise LogFormatError(f"{path}: attribute '{_JSON_ATTRS}' must be a JSON list of attribute names")
    attrs: dict[str, Any] = {}
    for k, v in raw.items():
        v = _decode(v)
        if k in as_json:
            v = _json_attr(path, k, v)
        elif isinstance(v, np.generic):
            v = v.item()
        elif isinstance(v, np.ndarray):
            v = v.tolist()
        attrs[k] = v
    axes, joint = _axes_and_joint(path, attrs, data["q"])
    _check_sample_time(path, attrs)
    _check_units(path, attrs, joint or ("revolute",) * len(axes))
    n = data["time"].size
    uneven = bool(attrs.get("incremental")) and not whole
    if uneven:
        # a killed incremental writer may leave datasets one block apart; keep the common part
        n = min(x.shape[0] for x in data.values())
    for k, x in data.items():
        if x.shape[0] != n and not uneven:
            raise LogFormatError(f"{path}: dataset '{k}' has {x.shape[0]} rows but 'time' has {n}"
                                 + (" (a capture killed mid-write? the other commands read the common rows)"
                                    if attrs.get("incremental") else ""))
        data[k] = x[:n]
    if gaps:
        attrs["gaps"] = gaps
    attrs["source_file"] = str(path)
    return AxisLog(axes=axes, joint=joint, attrs=attrs, **data)


def _decode(v: Any) -> Any:
    return v.decode(errors="replace") if isinstance(v, bytes) else v


def _show(v: Any) -> str:
    """An attribute value for a one-line message (quoted if text, shortened)."""
    s = repr(v) if isinstance(v, str) else str(v)
    s = " ".join(s.split())
    return s if len(s) <= 60 else s[:57] + "..."


def _json_attr(path: Path, key: str, text: Any) -> Any:
    """Parse the attribute ``key`` stored as JSON text; a LogFormatError naming it if it is not."""
    if not isinstance(text, str):
        raise LogFormatError(f"{path}: attribute '{key}' should be JSON text, found {type(text).__name__}")
    try:
        return json.loads(text)
    except ValueError as e:
        raise LogFormatError(f"{path}: attribute '{key}' is not valid JSON ({_short(e)})") from None


def _axes_and_joint(path: Path, attrs: dict[str, Any], q: np.ndarray) -> tuple[tuple[int, ...], tuple[str, ...]]:
    """Pop and check the attributes ``axes`` and ``joint`` against the columns of ``q``."""
    raw_axes = attrs.pop("axes")
    axes_list = list(np.atleast_1d(np.asarray(raw_axes, dtype=object)))
    if not axes_list or not all(isinstance(a, (int, float, np.integer, np.floating)) and not isinstance(a, bool)
                                and float(a).is_integer() for a in axes_list):
        raise LogFormatError(f"{path}: attribute 'axes' must list KUKA axis numbers (integers 1 to 12); "
                             f"got {_show(raw_axes)}")
    axes = tuple(int(a) for a in axes_list)
    if q.ndim not in (1, 2):
        raise LogFormatError(f"{path}: dataset 'q' has shape {q.shape}, expected (samples, axes)")
    columns = q.shape[1] if q.ndim == 2 else 1
    if len(axes) != columns:
        raise LogFormatError(f"{path}: attribute 'axes' lists {len(axes)} ax{'is' if len(axes) == 1 else 'es'} "
                             f"{list(axes)} but dataset 'q' has {columns} column{'s' if columns != 1 else ''}")
    joint = attrs.pop("joint", None)
    if joint is None:
        return axes, ()
    joint = [joint] if isinstance(joint, str) else list(np.atleast_1d(np.asarray(joint, dtype=object)))
    if len(joint) != len(axes):
        raise LogFormatError(f"{path}: attribute 'joint' has {len(joint)} entr{'y' if len(joint) == 1 else 'ies'} "
                             f"{joint} but attribute 'axes' lists {len(axes)} axes {list(axes)}")
    if any(j not in JOINT_TYPES for j in joint):
        raise LogFormatError(f"{path}: attribute 'joint' must give one of {JOINT_TYPES} per axis; got {joint}")
    return axes, tuple(str(j) for j in joint)


def _check_sample_time(path: Path, attrs: dict[str, Any]) -> None:
    """The attribute ``sample_time``, when present, is a finite positive number of seconds."""
    if "sample_time" not in attrs:
        return
    v = attrs["sample_time"]
    if isinstance(v, (bool, str)) or not isinstance(v, (int, float)):
        raise LogFormatError(f"{path}: attribute 'sample_time' is not a number ({_show(v)})")
    if not (np.isfinite(v) and v > 0):
        raise LogFormatError(f"{path}: attribute 'sample_time' is {v!r}; it must be a finite positive "
                             f"number of seconds")


def _check_units(path: Path, attrs: dict[str, Any], joint: tuple[str, ...]) -> None:
    units = attrs.get("units")
    if not isinstance(units, dict):
        return
    if units.get("time", "s") != "s":
        raise LogFormatError(f"{path}: time unit is '{units['time']}', expected 's'")
    for c in CHANNELS:
        got = units.get(c)
        if got is None:
            continue
        want = [channel_unit(c, j) for j in joint]
        if list(np.atleast_1d(got)) != want:
            raise LogFormatError(f"{path}: channel '{c}' has unit {got}, expected {want} (SI)")
