"""The axis log: the measured signals of one or more robot axes, in SI units (:class:`AxisLog`),
and the checks every reader applies (sample values, unit mistakes, file errors as one line).

The formats live beside it: HDF5 (:mod:`.hdf5`, incremental :mod:`.writer`), CSV (:mod:`.csvlog`),
MAT (:mod:`.matlog`), KUKA Trace (:mod:`.trace`); :func:`kukaid.logs.read_log` picks the reader.
See ``../shared/DESIGN.md`` "File formats" for the contract.
"""
from __future__ import annotations

import contextlib
import math
import os
import re
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Iterable, Iterator, Sequence

import numpy as np

from kukaid.errors import KukaidError, LogFormatError
from kukaid.jsonfile import file_kind

#: Per-axis channels, each an (N, A) array.  ``q`` and ``tau`` are required.
CHANNELS = ("q", "tau", "q_cmd", "temp", "tau_ext_true")
OPTIONAL_CHANNELS = ("q_cmd", "temp", "tau_ext_true")
JOINT_TYPES = ("revolute", "prismatic")
#: Value of the HDF5 attribute ``format`` that marks a kukaid axis log.
FORMAT = "kukaid.axislog/1"
#: Largest plausible |position| of a revolute axis, rad (720 degrees).  Beyond it the numbers are
#: in another unit (millidegrees, degrees stored as radians), not a robot axis.
MAX_REVOLUTE_RAD = 4 * np.pi
#: Largest plausible |position| of a prismatic axis, m: longer than a robot's linear track (a
#: warning only: a wrong --q-scale, or millimetres as metres).
MAX_PRISMATIC_M = 100.0
#: Median sample interval, s, from which on the times are probably milliseconds (a drive's 1 ms
#: samples written in ms are exactly 1 "s" apart).
MAX_SAMPLE_INTERVAL_S = 1.0
#: ... less this fraction: a drive's clock a little off (EMPS's 1 kHz samples are 0.99998 ms apart, in
#: milliseconds 0.99998 "s", and loaded as a 1 Hz log of 6.9 hours)
SAMPLE_INTERVAL_CLOCK_TOL = 0.01
#: Median sample interval, s, below which the times are probably seconds divided by 1000 (a 12, 4
#: or 1 ms controller log scaled as if in ms: 12, 4 or 1 µs); no controller's trace samples faster
#: than 20 kHz (a drive's finest, 125 µs)
MIN_SAMPLE_INTERVAL_S = 5e-5


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


def log_fingerprint(log: "AxisLog") -> str:
    """A short hash of a log's samples (time, positions, torques of its axes): which logs a fit saw,
    whatever their file names, folders or format (``kukaid validate`` calls a recording the file keeps
    in its ``provenance.log_fingerprints`` in-sample; ``kukaid diagnose`` holds it out of nothing).

    It hashes sums over the samples, each rounded to 1e-9 of its channel's size, not the samples'
    bytes: a log converted to another format (``kukaid load run.h5 -o run.csv``: positions written in
    degrees, read back in radians) differs in the last bit of its samples, and the same recording got
    another fingerprint (new-user trial 13).  Files written before keep the bytes' hash
    (:func:`legacy_fingerprint`); :func:`fingerprints` gives both to match them."""
    import hashlib

    n = int(np.asarray(log.time).size)
    ramp = np.linspace(-1.0, 1.0, n)
    terms: list = [n, tuple(int(a) for a in log.axes)]
    for x in (np.asarray(log.time, float)[:, None], np.asarray(log.q, float), np.asarray(log.tau, float)):
        for col in x.reshape(n, -1).T:
            size = float(np.abs(col).sum())
            if size == 0.0 or not math.isfinite(size):
                terms.append(repr(size))
                continue
            terms += [round(float(col.sum()) / (1e-9 * size)), round(float(col @ ramp) / (1e-9 * size)),
                      f"{float(col @ col):.9g}"]
    return hashlib.sha256(repr(terms).encode()).hexdigest()[:16]


def legacy_fingerprint(log: "AxisLog") -> str:
    """The fingerprint files written before stop 39 keep: a hash of the samples' bytes (time, q, tau)."""
    import hashlib

    h = hashlib.sha256()
    for x in (log.time, log.q, log.tau):
        h.update(np.ascontiguousarray(np.asarray(x, float)).tobytes())
    return h.hexdigest()[:16]


def fingerprints(log: "AxisLog") -> tuple[str, str]:
    """The log's :func:`log_fingerprint` and its :func:`legacy_fingerprint`: a parameter file keeps one or
    the other of the logs it was fitted on."""
    return log_fingerprint(log), legacy_fingerprint(log)


def check_each_recording_once(logs: Sequence["AxisLog"], error: type[KukaidError] = KukaidError) -> None:
    """Raise ``error`` naming the first log that is the same recording as an earlier one (their
    :func:`log_fingerprint`).  One recording twice weighs it double in a fit (standard deviations too
    small by sqrt 2) and is its own held-out check in a diagnosis."""
    seen: dict[str, int] = {}
    for i, lg in enumerate(logs):
        first = seen.setdefault(log_fingerprint(lg), i)
        if first != i:
            name, other = lg.attrs.get("source_file", "log"), logs[first].attrs.get("source_file", "another log")
            what = "given twice" if name == other else f"the same recording as {other}"
            raise error(f"{name}: {what}; give each recording once")


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
                  where: str, row_offset: int = 0, row_word: str = "row",
                  row_lines: Sequence[int] | None = None) -> None:
    """Validate sample values: enough samples, finite, strictly increasing time.

    ``row_offset`` and ``row_word`` let a reader report file lines ("line 7") instead of rows;
    ``row_lines`` gives each row's line instead of the offset when they do not follow evenly (the
    blank lines of a CSV file).
    """
    axes = list(axes)

    def at(r: int) -> int:
        return int(row_lines[r]) if row_lines is not None else int(r) + row_offset
    if time.size < 2:
        raise LogFormatError(f"{where}: too few samples ({time.size}); a log needs at least 2")
    bad = np.flatnonzero(~np.isfinite(time))
    if bad.size:
        raise LogFormatError(f"{where}: time is not a finite number at {row_word} {at(bad[0])}")
    dt = np.diff(time)
    bad = np.flatnonzero(dt <= 0)
    if bad.size:
        i = bad[0] + 1
        kind = "duplicated" if dt[bad[0]] == 0 else "decreasing"
        raise LogFormatError(
            f"{where}: time is not strictly increasing ({kind}) at {row_word} {at(i)}: "
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
                f"at {row_word} {at(r)}"
            )


def check_units(time: np.ndarray, channels: dict[str, np.ndarray | None], axes: Iterable[int],
                joint: Iterable[str], where: str, labels: dict[Any, str] | None = None,
                fixes: dict[str, str] | None = None) -> None:
    """Refuse values whose size betrays a unit mistake (the values are SI, already converted).

    A revolute position (``q``, ``q_cmd``) beyond +-720 degrees (4 pi rad) is millidegrees or
    degrees stored as radians; a median sample interval of 1 s or more is milliseconds stored as
    seconds (1 ms samples are 1 "s" apart), one under 50 µs seconds divided by 1000.  Prismatic positions are not bounded (linear tracks are long).

    Parameters
    ----------
    time : (N,) s.   channels : name -> (N, A) array or None.   axes, joint : per column.
    where : file or place for the message.
    labels : names for the message instead of "time" and "channel 'q' of axis A3", keyed by
        ``"time"`` or ``(channel, axis)``: a reader's column or variable names.  A label ending in
        "deg" gives the position in degrees only.
    fixes : what corrects the unit, appended to the message, keyed by ``"time"`` (milliseconds as
        seconds) or ``"q"`` (a position's unit): a reader's options (a MAT file's scales).
    """
    labels = labels or {}
    fixes = {k: f"; {v}" for k, v in (fixes or {}).items()}
    if time.size >= 2:
        dt = float(np.median(np.diff(time)))
        if dt >= MAX_SAMPLE_INTERVAL_S * (1 - SAMPLE_INTERVAL_CLOCK_TOL):
            raise LogFormatError(
                f"{where}: {labels.get('time', 'time')} has a median sample interval of {dt:.6g} s; about "
                f"{MAX_SAMPLE_INTERVAL_S:g} s or more: milliseconds written as seconds?{fixes.get('time', '')}"
            )
        if 0 < dt < MIN_SAMPLE_INTERVAL_S:
            raise LogFormatError(
                f"{where}: {labels.get('time', 'time')} has a median sample interval of {dt:.6g} s; under "
                f"{MIN_SAMPLE_INTERVAL_S:g} s (faster than 20 kHz, faster than a controller records): seconds "
                "divided by 1000 (a time in seconds scaled as milliseconds)?"
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
                    f"degrees as radians)?{fixes.get('q', '')}"
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


def _short(e: Exception) -> str:
    """The first line of an exception's text, shortened for a one-line message."""
    return str(e).split("\n")[0].strip()[:160]


class OtherKindError(LogFormatError):
    """A file a log reader could not read that is another of the toolkit's files (:func:`other_kind`):
    said already, not to be looked at again."""


def other_kind(path: str | Path, fmt: str) -> OtherKindError | None:
    """The error for a file its ``fmt`` reader ("HDF5", "CSV", "MAT", "KUKA Trace") could not read when
    its first bytes say it is another of the toolkit's files (a report, a table, a log of another
    format renamed): "is a PDF (a report), not a CSV axis log"; None when they do not."""
    kind = file_kind(path)
    if kind is None or kind == f"an axis log ({fmt})":
        return None
    return OtherKindError(f"{path}: is {kind}, not {'an' if fmt == 'HDF5' else 'a'} {fmt} axis log")
