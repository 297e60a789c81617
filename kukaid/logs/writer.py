"""Incremental HDF5 axis logs for live data (captures, robot runs): :class:`AxisLogWriter`."""
from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any, Iterable

import numpy as np

from kukaid.errors import DiskFullError, KukaidError
from kukaid.logs.core import CHANNELS, _os_errors
from kukaid.logs.hdf5 import _base_attrs, _write_attrs


class AxisLogWriter:
    """Write an HDF5 axis log incrementally, so an interrupted capture keeps what it recorded.

    The file is opened in SWMR mode: after every :meth:`flush` (done automatically every
    ``flush_interval`` seconds of log time or on demand) the file on disk is consistent, even if
    the process is then killed.  :func:`read_hdf5` opens such a file.  A file that cannot be
    created (read-only folder, a folder of that name, ...) is a :class:`KukaidError` naming the
    path and the operating system's reason.

    HDF5 leaves an unreadable file when a write fails on a full disk, so the writer stops first:
    an append that would leave less than ``reserve`` bytes of free disk space (or of the process's
    file-size limit) writes the leading samples that fit, closes the log cleanly and raises
    :class:`DiskFullError` naming the samples kept; what was recorded stays readable (a log
    without samples is removed).
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

    def _fits(self, m: int, per_sample: int) -> tuple[int, int]:
        """How many of ``m`` records of ``per_sample`` bytes fit and keep ``reserve`` bytes free,
        and the room (bytes) measured.  Raises the stored error once the log has stopped."""
        if self._stopped is not None:
            raise self._stopped
        room = self.room()
        return int(min(m, max(0, (room - self.reserve) // per_sample))), room

    def _stop(self, room_left: int, dropped: int) -> DiskFullError:
        """Close the log (remove it when empty) and return the error that says what it kept."""
        self.close()
        if self.n == 0:
            self.path.unlink(missing_ok=True)
            kept = "nothing had been recorded; no log written"
        else:
            kept = f"the log keeps the {self.n} samples up to t = {self._last_t:.3f} s"
        if dropped:
            kept += f" ({dropped} later sample{'s' if dropped != 1 else ''} not written)"
        self._stopped = DiskFullError(
            f"{self.path}: only {max(room_left, 0) / 2**20:.2f} MiB of disk space (or file-size limit) left, less "
            f"than the {self.reserve / 2**20:g} MiB kept free: recording stopped; {kept}")
        return self._stopped

    def append(self, time: np.ndarray | float, **channels: np.ndarray) -> None:
        """Append samples: ``time`` (n,) and each channel (n, A) (or (A,) for one sample).

        When the disk (or file-size limit) has room for only the first k < n samples, those k
        are written, the log is closed and :class:`DiskFullError` names the samples kept.
        """
        t = np.atleast_1d(np.asarray(time, dtype=float))
        m = t.size
        if m == 0:
            return
        if t[0] <= self._last_t or np.any(np.diff(t) <= 0):
            raise ValueError("appended time must be strictly increasing")
        missing = set(self.channels) - set(channels)
        if missing:
            raise ValueError(f"missing channels {sorted(missing)}")
        xs = [np.asarray(channels[c], dtype=float).reshape(m, len(self.axes)) for c in self.channels]
        per_sample = 8 * (1 + len(self.channels) * len(self.axes))
        k, room = self._fits(m, per_sample)
        if k:
            self._write(t[:k], [x[:k] for x in xs])
        if k < m:
            raise self._stop(room - k * per_sample, m - k)

    def _write(self, t: np.ndarray, xs: list[np.ndarray]) -> None:
        m = t.size
        # write channels first, time last: a reader trims every channel to the length of time
        for c, x in zip(self.channels, xs):
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
        k, room = self._fits(1, 16)
        if not k:
            raise self._stop(room, 0)
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
