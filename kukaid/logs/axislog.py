"""Axis logs: the measured signals of one or more robot axes, in SI units.

The in-memory value is :class:`AxisLog`.  On disk it is HDF5 (the toolkit's own format, written
atomically or incrementally by :class:`AxisLogWriter`) or CSV (one row per sample, degrees and
N·m as the KRC gives them).  See ``../shared/DESIGN.md`` "File formats" for the contract.
"""
from __future__ import annotations

import contextlib
import json
import os
import re
import shutil
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Iterable, Iterator

import numpy as np

from kukaid import __version__
from kukaid.errors import DiskFullError, KukaidError, LogFormatError
from kukaid.atomic import atomic_path

#: Per-axis channels, each an (N, A) array.  ``q`` and ``tau`` are required.
CHANNELS = ("q", "tau", "q_cmd", "temp", "tau_ext_true")
OPTIONAL_CHANNELS = ("q_cmd", "temp", "tau_ext_true")
JOINT_TYPES = ("revolute", "prismatic")
#: Value of the HDF5 attribute ``format`` that marks a kukaid axis log.
FORMAT = "kukaid.axislog/1"
#: Largest plausible |position| of a revolute axis, rad (720 degrees).  Beyond it the numbers are
#: in another unit (millidegrees, degrees stored as radians), not a robot axis.
MAX_REVOLUTE_RAD = 4 * np.pi
#: Largest plausible median sample interval, s.  Above it the times are probably milliseconds.
MAX_SAMPLE_INTERVAL_S = 1.0


def channel_unit(channel: str, joint: str) -> str:
    """SI unit of a channel for a joint type ("revolute" or "prismatic")."""
    prismatic = joint == "prismatic"
    if channel in ("q", "q_cmd"):
        return "m" if prismatic else "rad"
    if channel in ("tau", "tau_ext_true"):
        return "N" if prismatic else "N*m"
    if channel == "temp":
        return "degC"
    if channel == "time":
        return "s"
    raise KeyError(channel)


@dataclass(frozen=True, eq=False)
class AxisLog:
    """Measured signals of the axes ``axes``, sampled at the instants ``time``.

    Parameters
    ----------
    time : (N,) array, s, strictly increasing.
    q : (N, A) array, rad (m for a prismatic axis), as $AXIS_ACT_MEAS.
    tau : (N, A) array, N·m (N), as $TORQUE_AXIS_ACT.
    axes : the A axis numbers, KUKA numbering (1..6, external axes 7..12).
    q_cmd, temp, tau_ext_true : optional (N, A) arrays: commanded position, motor temperature
        (°C), and, for simulated logs only, the true external torque.
    joint : per axis, "revolute" or "prismatic" (default all revolute).
    attrs : provenance and metadata (source, experiment, seed, trajectory, ...); JSON-able.
    """

    time: np.ndarray
    q: np.ndarray
    tau: np.ndarray
    axes: tuple[int, ...]
    q_cmd: np.ndarray | None = None
    temp: np.ndarray | None = None
    tau_ext_true: np.ndarray | None = None
    joint: tuple[str, ...] = ()
    attrs: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        where = self.attrs.get("source_file", "axis log")
        axes = tuple(int(a) for a in np.atleast_1d(self.axes))
        object.__setattr__(self, "axes", axes)
        if len(set(axes)) != len(axes) or not all(1 <= a <= 12 for a in axes):
            raise LogFormatError(f"{where}: axis numbers must be distinct, 1 to 12; got {list(axes)}")
        joint = tuple(self.joint) if self.joint else ("revolute",) * len(axes)
        if len(joint) != len(axes) or any(j not in JOINT_TYPES for j in joint):
            raise LogFormatError(f"{where}: joint types must be one of {JOINT_TYPES} per axis; got {list(joint)}")
        object.__setattr__(self, "joint", joint)
        t = np.asarray(self.time, dtype=float)
        if t.ndim != 1:
            raise LogFormatError(f"{where}: time must be one-dimensional, got shape {t.shape}")
        object.__setattr__(self, "time", t)
        for name in CHANNELS:
            x = getattr(self, name)
            if x is None:
                if name in ("q", "tau"):
                    raise LogFormatError(f"{where}: missing channel '{name}'")
                continue
            x = np.asarray(x, dtype=float)
            if x.ndim == 1 and len(axes) == 1:
                x = x[:, None]
            if x.shape != (t.size, len(axes)):
                raise LogFormatError(
                    f"{where}: channel '{name}' has shape {x.shape}, expected ({t.size}, {len(axes)})"
                )
            object.__setattr__(self, name, x)
        check_samples(self.time, {n: getattr(self, n) for n in CHANNELS}, axes, where)
        check_units(self.time, {n: getattr(self, n) for n in CHANNELS}, axes, joint, where)

    # -- access -----------------------------------------------------------------------------
    @property
    def n_samples(self) -> int:
        return int(self.time.size)

    @property
    def sample_time(self) -> float:
        """Median sample interval, s."""
        return float(np.median(np.diff(self.time)))

    @property
    def duration(self) -> float:
        return float(self.time[-1] - self.time[0])

    def index(self, axis: int) -> int:
        """Column of ``axis`` in the (N, A) channels; error naming the axes present."""
        try:
            return self.axes.index(int(axis))
        except ValueError:
            where = self.attrs.get("source_file", "axis log")
            raise LogFormatError(f"{where}: axis A{axis} is not in the log (axes: {list(self.axes)})") from None

    def channel(self, name: str, axis: int) -> np.ndarray:
        """One axis of a channel as a 1-D array (error if the channel is absent)."""
        x = getattr(self, name)
        if x is None:
            where = self.attrs.get("source_file", "axis log")
            raise LogFormatError(f"{where}: the log has no '{name}' channel")
        return x[:, self.index(axis)]

    def has(self, name: str) -> bool:
        return getattr(self, name) is not None

    def select(self, rows: slice | np.ndarray) -> "AxisLog":
        """Rows of the log (a slice or boolean mask), as a new log."""
        kw = {n: (getattr(self, n)[rows] if getattr(self, n) is not None else None) for n in CHANNELS}
        return replace(self, time=self.time[rows], **kw)

    def with_attrs(self, **attrs: Any) -> "AxisLog":
        return replace(self, attrs={**self.attrs, **attrs})


def check_samples(time: np.ndarray, channels: dict[str, np.ndarray | None], axes: Iterable[int],
                  where: str, row_offset: int = 0, row_word: str = "row") -> None:
    """Validate sample values: enough samples, finite, strictly increasing time.

    ``row_offset`` and ``row_word`` let a reader report file lines ("line 7") instead of rows.
    """
    axes = list(axes)
    if time.size < 2:
        raise LogFormatError(f"{where}: too few samples ({time.size}); a log needs at least 2")
    bad = np.flatnonzero(~np.isfinite(time))
    if bad.size:
        raise LogFormatError(f"{where}: time is not a finite number at {row_word} {bad[0] + row_offset}")
    dt = np.diff(time)
    bad = np.flatnonzero(dt <= 0)
    if bad.size:
        i = bad[0] + 1
        kind = "duplicated" if dt[bad[0]] == 0 else "decreasing"
        raise LogFormatError(
            f"{where}: time is not strictly increasing ({kind}) at {row_word} {i + row_offset}: "
            f"{time[i]:.6g} s after {time[i - 1]:.6g} s"
        )
    for name, x in channels.items():
        if x is None:
            continue
        bad = np.argwhere(~np.isfinite(x))
        if bad.size:
            r, c = bad[0]
            raise LogFormatError(
                f"{where}: channel '{name}' of axis A{axes[c]} is not a finite number (NaN or inf) "
                f"at {row_word} {r + row_offset}"
            )


def check_units(time: np.ndarray, channels: dict[str, np.ndarray | None], axes: Iterable[int],
                joint: Iterable[str], where: str, labels: dict[Any, str] | None = None) -> None:
    """Refuse values whose size betrays a unit mistake (the values are SI, already converted).

    A revolute position (``q``, ``q_cmd``) beyond +-720 degrees (4 pi rad) is millidegrees or
    degrees stored as radians; a median sample interval above 1 s is milliseconds stored as
    seconds.  Prismatic positions are not bounded (linear tracks are long).

    Parameters
    ----------
    time : (N,) s.   channels : name -> (N, A) array or None.   axes, joint : per column.
    where : file or place for the message.
    labels : names for the message instead of "time" and "channel 'q' of axis A3", keyed by
        ``"time"`` or ``(channel, axis)``: a reader's column or variable names.  A label ending in
        "deg" gives the position in degrees only.
    """
    labels = labels or {}
    if time.size >= 2:
        dt = float(np.median(np.diff(time)))
        if dt > MAX_SAMPLE_INTERVAL_S:
            raise LogFormatError(
                f"{where}: {labels.get('time', 'time')} has a median sample interval of {dt:.6g} s; above "
                f"{MAX_SAMPLE_INTERVAL_S:g} s: milliseconds written as seconds?"
            )
    for name in ("q", "q_cmd"):
        x = channels.get(name)
        if x is None or x.size == 0:
            continue
        for c, (a, j) in enumerate(zip(axes, joint)):
            if j != "revolute":
                continue
            peak = float(x[np.argmax(np.abs(x[:, c])), c])
            if abs(peak) > MAX_REVOLUTE_RAD:
                label = labels.get((name, a), f"channel '{name}' of axis A{a}")
                deg = np.degrees(peak)
                value = f"{deg:.6g} degrees" if label.endswith("deg") else f"{peak:.6g} rad ({deg:.6g} degrees)"
                raise LogFormatError(
                    f"{where}: {label} reaches {value}; beyond +-720 degrees: wrong unit (millidegrees, or "
                    f"degrees as radians)?"
                )


def _os_reason(e: OSError) -> str:
    """The operating system's reason for an OSError (h5py puts its own long text in strerror)."""
    if e.errno:
        return os.strerror(e.errno)
    m = re.search(r"error message = '([^']*)'", str(e))
    return m.group(1) if m else _short(e)


@contextlib.contextmanager
def _os_errors(path: str | Path, action: str = "cannot write") -> Iterator[None]:
    """Turn an OSError (read-only folder, no space, ...) into one line naming ``path`` and the reason."""
    try:
        yield
    except OSError as e:
        raise KukaidError(f"{path}: {action}: {_os_reason(e)}") from None


# -- HDF5 ------------------------------------------------------------------------------------
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
        raise LogFormatError(f"{path}: not a readable HDF5 file (truncated or corrupt): {_short(e)}") from None


def _short(e: Exception) -> str:
    return str(e).split("\n")[0].strip()[:160]


def read_hdf5(path: str | Path) -> AxisLog:
    """Read an HDF5 axis log; validate it and report what is wrong and where."""
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
                    raise LogFormatError(f"{path}: missing dataset '{name}'")
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
    if attrs.get("incremental"):
        # a killed incremental writer may leave datasets one block apart; keep the common part
        n = min(x.shape[0] for x in data.values())
    for k, x in data.items():
        if x.shape[0] != n and not attrs.get("incremental"):
            raise LogFormatError(f"{path}: dataset '{k}' has {x.shape[0]} rows but 'time' has {n}")
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


class AxisLogWriter:
    """Write an HDF5 axis log incrementally, so an interrupted capture keeps what it recorded.

    The file is opened in SWMR mode: after every :meth:`flush` (done automatically every
    ``flush_interval`` seconds of log time or on demand) the file on disk is consistent, even if
    the process is then killed.  :func:`read_hdf5` opens such a file.  A file that cannot be
    created (read-only folder, a folder of that name, ...) is a :class:`KukaidError` naming the
    path and the operating system's reason.

    HDF5 leaves an unreadable file when a write fails on a full disk, so the writer stops first:
    an append that would leave less than ``reserve`` bytes of free disk space (or of the process's
    file-size limit) closes the log cleanly and raises :class:`DiskFullError`; what was recorded
    stays readable (a log without samples is removed).
    """

    reserve: int = 1 << 20  # bytes kept free for HDF5's metadata and the final flush

    def __init__(self, path: str | Path, axes: Iterable[int], channels: Iterable[str] = ("q", "tau"),
                 joint: Iterable[str] = (), attrs: dict[str, Any] | None = None,
                 flush_every: int = 64) -> None:
        import h5py

        self.path = Path(path)
        self.axes = tuple(int(a) for a in axes)
        self.joint = tuple(joint) or ("revolute",) * len(self.axes)
        self.channels = tuple(channels)
        for c in self.channels:
            if c not in CHANNELS:
                raise ValueError(f"unknown channel '{c}'; known: {CHANNELS}")
        if "q" not in self.channels or "tau" not in self.channels:
            raise ValueError("an axis log needs channels 'q' and 'tau'")
        for parent in self.path.parents:  # mkdir would say "File exists" for a file in the way
            if parent.exists():
                if not parent.is_dir():
                    raise KukaidError(f"{self.path}: cannot create: {parent} is not a folder")
                break
        with _os_errors(self.path, "cannot create"):
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._f = h5py.File(self.path, "w", libver="latest")
        a = len(self.axes)
        self._d = {"time": self._f.create_dataset("time", shape=(0,), maxshape=(None,), dtype="f8", chunks=(1024,))}
        for c in self.channels:
            self._d[c] = self._f.create_dataset(c, shape=(0, a), maxshape=(None, a), dtype="f8", chunks=(1024, a))
        self._d["gaps"] = self._f.create_dataset("gaps", shape=(0, 2), maxshape=(None, 2), dtype="f8", chunks=(64, 2))
        _write_attrs(self._f, {**_base_attrs(self.axes, self.joint, attrs or {}), "incremental": 1})
        self._f.swmr_mode = True
        self.n = 0
        self._last_t = -np.inf
        self._since_flush = 0
        self.flush_every = flush_every
        self._stopped: DiskFullError | None = None

    def room(self) -> int:
        """Bytes the log may still grow by: free disk space, and the file-size limit if one is set."""
        free = shutil.disk_usage(self.path.parent).free
        try:
            import resource

            soft = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
            if soft != resource.RLIM_INFINITY:
                free = min(free, soft - self.path.stat().st_size)
        except (ImportError, OSError):  # no resource module (Windows)
            pass
        return int(free)

    def _make_room(self, nbytes: int) -> None:
        if self._stopped is not None:
            raise self._stopped
        room = self.room()
        if room - nbytes >= self.reserve:
            return
        self.close()
        if self.n == 0:
            self.path.unlink(missing_ok=True)
            kept = "nothing had been recorded; no log written"
        else:
            kept = f"the log keeps the {self.n} samples up to t = {self._last_t:.3f} s"
        self._stopped = DiskFullError(
            f"{self.path}: only {max(room, 0) / 2**20:.2f} MiB of disk space (or file-size limit) left, less than "
            f"the {self.reserve / 2**20:g} MiB kept free: recording stopped; {kept}")
        raise self._stopped

    def append(self, time: np.ndarray | float, **channels: np.ndarray) -> None:
        """Append samples: ``time`` (n,) and each channel (n, A) (or (A,) for one sample)."""
        t = np.atleast_1d(np.asarray(time, dtype=float))
        m = t.size
        if m == 0:
            return
        if t[0] <= self._last_t or np.any(np.diff(t) <= 0):
            raise ValueError("appended time must be strictly increasing")
        missing = set(self.channels) - set(channels)
        if missing:
            raise ValueError(f"missing channels {sorted(missing)}")
        self._make_room(8 * m * (1 + len(self.channels) * len(self.axes)))
        # write channels first, time last: a reader trims every channel to the length of time
        for c in self.channels:
            x = np.asarray(channels[c], dtype=float).reshape(m, len(self.axes))
            d = self._d[c]
            d.resize((self.n + m, len(self.axes)))
            d[self.n:] = x
        d = self._d["time"]
        d.resize((self.n + m,))
        d[self.n:] = t
        self.n += m
        self._last_t = t[-1]
        self._since_flush += m
        if self._since_flush >= self.flush_every:
            self.flush()

    @property
    def last_time(self) -> float:
        """Time of the last appended sample, s (-inf before the first)."""
        return float(self._last_t)

    def mark_gap(self, t_start: float, t_end: float) -> None:
        """Record that no samples could be taken between ``t_start`` and ``t_end`` (s)."""
        self._make_room(16)
        d = self._d["gaps"]
        k = d.shape[0]
        d.resize((k + 1, 2))
        d[k] = (t_start, t_end)
        self.flush()

    def flush(self) -> None:
        if not self._f.id.valid:  # closed (also after a DiskFullError)
            return
        for d in self._d.values():
            d.flush()
        self._f.flush()
        self._since_flush = 0

    def close(self) -> None:
        if self._f.id.valid:
            self.flush()
            self._f.close()

    def __enter__(self) -> "AxisLogWriter":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


# -- CSV -------------------------------------------------------------------------------------
# column suffix -> (channel, joint type or None for either, scale to SI)
_DEG = np.pi / 180.0
_CSV_SUFFIX = {
    "deg": ("q", "revolute", _DEG),
    "rad": ("q", "revolute", 1.0),
    "m": ("q", "prismatic", 1.0),
    "Nm": ("tau", "revolute", 1.0),
    "N": ("tau", "prismatic", 1.0),
    "cmd_deg": ("q_cmd", "revolute", _DEG),
    "cmd_rad": ("q_cmd", "revolute", 1.0),
    "cmd_m": ("q_cmd", "prismatic", 1.0),
    "temp_C": ("temp", None, 1.0),
    "ext_true_Nm": ("tau_ext_true", "revolute", 1.0),
    "ext_true_N": ("tau_ext_true", "prismatic", 1.0),
}
_CSV_COL = re.compile(r"^A(\d{1,2})_(\w+)$")


def read_csv(path: str | Path) -> AxisLog:
    """Read a CSV axis log (``time_s``, ``A{i}_deg``/``_rad``/``_m``, ``A{i}_Nm``/``_N``, ...)."""
    path = Path(path)
    if not path.exists():
        raise LogFormatError(f"{path}: no such file")
    text = path.read_text(errors="replace")
    lines = [ln for ln in text.splitlines()]
    if not lines or not lines[0].strip():
        raise LogFormatError(f"{path}: empty file (expected a header row)")
    header = [h.strip() for h in lines[0].split(",")]
    if header[0] != "time_s":
        raise LogFormatError(f"{path}: first column must be 'time_s', found '{header[0]}'")
    cols: dict[tuple[int, str], tuple[int, float]] = {}
    joint_of: dict[int, str] = {}
    for j, name in enumerate(header[1:], start=1):
        m = _CSV_COL.match(name)
        if not m or m.group(2) not in _CSV_SUFFIX:
            raise LogFormatError(
                f"{path}: unknown column '{name}' (column {j + 1}); expected A<i>_ with a unit suffix in "
                f"{sorted(_CSV_SUFFIX)}"
            )
        axis = int(m.group(1))
        chan, jt, scale = _CSV_SUFFIX[m.group(2)]
        if (axis, chan) in cols:
            raise LogFormatError(f"{path}: axis A{axis} has two '{chan}' columns (column {j + 1}: '{name}')")
        if jt is not None:
            if joint_of.setdefault(axis, jt) != jt:
                raise LogFormatError(f"{path}: column '{name}' mixes revolute and prismatic units for A{axis}")
        cols[(axis, chan)] = (j, scale)
    axes = sorted({a for a, _ in cols})
    if not axes:
        raise LogFormatError(f"{path}: no axis columns in the header")
    for a in axes:
        for need, hint in (("q", "A{a}_deg"), ("tau", "A{a}_Nm")):
            if (a, need) not in cols:
                raise LogFormatError(f"{path}: missing column {hint.format(a=a)} (axis A{a} has no '{need}')")
    body = [ln for ln in lines[1:]]
    rows = []
    for k, ln in enumerate(body, start=2):
        if not ln.strip():
            continue
        parts = ln.split(",")
        if len(parts) != len(header):
            raise LogFormatError(f"{path}: line {k} has {len(parts)} fields, the header has {len(header)}")
        try:
            rows.append([float(p) for p in parts])
        except ValueError:
            bad = next(p for p in parts if not _is_float(p))
            raise LogFormatError(f"{path}: line {k}: '{bad.strip()}' is not a number") from None
    if not rows:
        raise LogFormatError(f"{path}: no data rows after the header")
    arr = np.asarray(rows, dtype=float)
    data: dict[str, np.ndarray | None] = {}
    for chan in CHANNELS:
        present = [(a, chan) in cols for a in axes]
        if not any(present):
            data[chan] = None
            continue
        if not all(present):
            missing = [a for a, p in zip(axes, present) if not p]
            raise LogFormatError(f"{path}: channel '{chan}' is present for some axes but not A{missing[0]}")
        data[chan] = np.column_stack([arr[:, cols[(a, chan)][0]] * cols[(a, chan)][1] for a in axes])
    time = arr[:, 0]
    check_samples(time, data, axes, str(path), row_offset=2, row_word="line")
    joint = tuple(joint_of.get(a, "revolute") for a in axes)
    labels: dict[Any, str] = {(chan, a): header[j] for (a, chan), (j, _) in cols.items()}
    check_units(time, data, axes, joint, str(path), labels={**labels, "time": "time_s"})
    return AxisLog(time=time, axes=tuple(axes), joint=joint, attrs={"source_file": str(path)}, **data)


def _is_float(s: str) -> bool:
    try:
        float(s)
        return True
    except ValueError:
        return False


def write_csv(log: AxisLog, path: str | Path, angle_unit: str = "deg") -> None:
    """Write ``log`` as CSV (atomically).  Revolute positions in degrees (or ``rad``).

    A folder that cannot be written is a :class:`KukaidError` naming ``path`` and the reason.
    """
    if angle_unit not in ("deg", "rad"):
        raise ValueError("angle_unit must be 'deg' or 'rad'")
    names, cols = ["time_s"], [log.time]
    suffix = {  # channel -> (revolute suffix, prismatic suffix)
        "q": (angle_unit, "m"),
        "tau": ("Nm", "N"),
        "q_cmd": ("cmd_" + angle_unit, "cmd_m"),
        "temp": ("temp_C", "temp_C"),
        "tau_ext_true": ("ext_true_Nm", "ext_true_N"),
    }
    for chan in CHANNELS:
        x = getattr(log, chan)
        if x is None:
            continue
        for c, (a, jt) in enumerate(zip(log.axes, log.joint)):
            s = suffix[chan][jt == "prismatic"]
            names.append(f"A{a}_{s}")
            scale = 1.0 / _DEG if s.endswith("deg") else 1.0
            cols.append(x[:, c] * scale)
    table = np.column_stack(cols)
    with atomic_path(path) as tmp, _os_errors(path):
        with open(tmp, "w") as fh:
            fh.write(",".join(names) + "\n")
            for row in table:
                fh.write(",".join(repr(float(v)) for v in row) + "\n")
