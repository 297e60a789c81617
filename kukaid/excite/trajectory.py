"""The trajectory value: commanded position of one axis at the KR C4 IPO rate, its file format and checks."""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from kukaid import __version__
from kukaid.atomic import write_text_atomic
from kukaid.errors import TrajectoryError
from kukaid.jsonfile import read_json
from kukaid.models.limits import AxisLimits


#: KR C4 interpolation cycle (IPO), s.
IPO_DT = 0.012
SCHEMA = "kukaid.trajectory/1"
#: longest trajectory accepted, s
MAX_DURATION = 86400.0
KINDS = ("friction", "inertia", "presliding", "validation")
_DEG = math.pi / 180.0


# ---------------------------------------------------------------------------------------------
# Trajectory value
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Trajectory:
    """Commanded position of one axis at the IPO rate.

    Parameters
    ----------
    t : (N,) array, s, uniformly spaced (0.012 s for the KR C4), strictly increasing.
    q : (N,) array, rad, commanded axis position.
    axis : axis number, KUKA numbering (default 3).
    kind : experiment kind ("friction", "inertia", "presliding", "validation" or another name).
    params : the experiment's parameters (JSON-able), SI units.
    limits : the limits the trajectory was checked against (dict, see :class:`AxisLimits`), or None.
    """

    t: np.ndarray
    q: np.ndarray
    axis: int = 3
    kind: str = "custom"
    params: dict[str, Any] = field(default_factory=dict)
    limits: dict[str, Any] | None = None

    def __post_init__(self) -> None:
        t = np.asarray(self.t, dtype=float)
        q = np.asarray(self.q, dtype=float)
        _check_arrays(t, q, "trajectory")
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "q", q)
        object.__setattr__(self, "axis", int(self.axis))
        if not 1 <= self.axis <= 12:
            raise TrajectoryError(f"trajectory: axis must be 1 to 12, got {self.axis}")

    # -- derived signals ----------------------------------------------------------------------
    @property
    def dt(self) -> float:
        """Sample time, s."""
        return float(self.t[1] - self.t[0])

    @property
    def duration(self) -> float:
        """Duration, s."""
        return float(self.t[-1] - self.t[0])

    @property
    def n_samples(self) -> int:
        return int(self.t.size)

    @property
    def qd(self) -> np.ndarray:
        """Commanded velocity by central differences, rad/s."""
        return np.gradient(self.q, self.t)

    @property
    def qdd(self) -> np.ndarray:
        """Commanded acceleration by differences, rad/s²."""
        return np.gradient(self.qd, self.t)

    def __iter__(self):  # t, q = traj
        return iter((self.t, self.q))

    # -- JSON ---------------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        return {
            "schema": SCHEMA,
            "kind": self.kind,
            "axis": self.axis,
            "sample_time": self.dt,
            "duration": self.duration,
            "units": {"t": "s", "q": "rad"},
            "params": self.params,
            "limits": self.limits,
            "kukaid_version": __version__,
            "t": [float(x) for x in self.t],
            "q": [float(x) for x in self.q],
        }

    def json_text(self) -> str:
        """The trajectory file's text (``"schema": "kukaid.trajectory/1"``)."""
        return json.dumps(self.to_dict(), indent=1, allow_nan=False) + "\n"

    def to_json(self, path: str | Path) -> None:
        """Write the trajectory file atomically."""
        write_text_atomic(path, self.json_text())

    @classmethod
    def from_dict(cls, d: Any, where: str = "trajectory") -> "Trajectory":
        if not isinstance(d, dict):
            raise TrajectoryError(f"{where}: expected a JSON object at the top level")
        if d.get("schema") != SCHEMA:
            raise TrajectoryError(f"{where}: field 'schema' must be \"{SCHEMA}\", got {d.get('schema')!r}")
        for k in ("t", "q"):
            if k not in d:
                raise TrajectoryError(f"{where}: missing field '{k}'")
            if not isinstance(d[k], list) or not all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                                      for x in d[k]):
                bad = next((i for i, x in enumerate(d[k]) if not isinstance(x, (int, float)) or isinstance(x, bool)),
                           None) if isinstance(d[k], list) else None
                at = f" (element {bad}: {d[k][bad]!r})" if bad is not None else ""
                raise TrajectoryError(f"{where}: field '{k}' must be a list of numbers{at}")
        units = d.get("units", {"t": "s", "q": "rad"})
        if not isinstance(units, dict) or units.get("t", "s") != "s" or units.get("q", "rad") != "rad":
            raise TrajectoryError(f"{where}: field 'units' must be {{\"t\": \"s\", \"q\": \"rad\"}}, got {units!r}")
        axis = d.get("axis", 3)
        if not isinstance(axis, int) or isinstance(axis, bool) or not 1 <= axis <= 12:
            raise TrajectoryError(f"{where}: field 'axis' must be an integer 1 to 12, got {axis!r}")
        kind = d.get("kind", "custom")
        if not isinstance(kind, str):
            raise TrajectoryError(f"{where}: field 'kind' must be a string, got {kind!r}")
        params = d.get("params", {})
        if not isinstance(params, dict):
            raise TrajectoryError(f"{where}: field 'params' must be an object")
        limits = d.get("limits")
        if limits is not None:
            AxisLimits.from_dict(limits, where=f"{where}: field 'limits'")
        t = np.asarray(d["t"], dtype=float)
        q = np.asarray(d["q"], dtype=float)
        _check_arrays(t, q, where)
        return cls(t=t, q=q, axis=axis, kind=kind, params=params, limits=limits)

    @classmethod
    def from_json(cls, path: str | Path) -> "Trajectory":
        """Read and validate a trajectory file; one-line :class:`TrajectoryError` when malformed."""
        return cls.from_dict(read_json(path, TrajectoryError), where=str(path))


def _check_arrays(t: np.ndarray, q: np.ndarray, where: str) -> None:
    if t.ndim != 1 or q.ndim != 1:
        raise TrajectoryError(f"{where}: 't' and 'q' must be one-dimensional")
    if t.size != q.size:
        raise TrajectoryError(f"{where}: 't' has {t.size} samples but 'q' has {q.size}")
    if t.size < 2:
        raise TrajectoryError(f"{where}: too few samples ({t.size}); a trajectory needs at least 2")
    for name, x in (("t", t), ("q", q)):
        bad = np.flatnonzero(~np.isfinite(x))
        if bad.size:
            raise TrajectoryError(f"{where}: '{name}' is not a finite number at index {bad[0]}")
    dt = np.diff(t)
    bad = np.flatnonzero(dt <= 0)
    if bad.size:
        i = int(bad[0]) + 1
        raise TrajectoryError(f"{where}: 't' is not strictly increasing at index {i} ({t[i]:.6g} s after {t[i-1]:.6g} s)")
    bad = np.flatnonzero(np.abs(dt - dt[0]) > 1e-6 * max(1.0, dt[0]) + 1e-9)
    if bad.size:
        i = int(bad[0]) + 1
        raise TrajectoryError(f"{where}: 't' is not uniformly sampled at index {i} (step {dt[i-1]:.6g} s, "
                              f"expected {dt[0]:.6g} s)")
    if not 1e-4 <= dt[0] <= 1.0:
        raise TrajectoryError(f"{where}: 't' steps by {dt[0]:.6g} s; a commanded trajectory is sampled every "
                              f"0.1 ms to 1 s (the KR C4's IPO rate is 12 ms): wrong time unit?")
    if t[-1] - t[0] > MAX_DURATION:
        raise TrajectoryError(f"{where}: lasts {t[-1] - t[0]:.6g} s, more than {MAX_DURATION:.0f} s (24 h)")
