"""Joint limits of a robot axis (position, velocity, acceleration), checked against trajectories.

Used by excitation (:mod:`kukaid.excite`), capture and the KRL export (:mod:`kukaid.krc.krl`)."""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from kukaid.errors import LimitError, TrajectoryError
from kukaid.jsonfile import read_json

_DEG = math.pi / 180.0


@dataclass(frozen=True)
class AxisLimits:
    """Position, velocity and acceleration limits of one axis (SI).

    The default, :meth:`kr6_r700_sixx`, is axis A3 of a KUKA KR 6 R700 sixx (KR AGILUS):
    range of motion +156° / -120° and 360 °/s (data-sheet figures).  The data sheet gives no
    acceleration; 10 rad/s² (573 °/s²) is an assumption of this toolkit, comfortably inside
    what the KR AGILUS reaches, and the excitation defaults use at most about a third of it.
    Override any figure with options or a JSON file (keys ``q_min``, ``q_max`` (rad),
    ``qd_max`` (rad/s), ``qdd_max`` (rad/s²), or the same names with ``_deg``).
    """

    q_min: float
    q_max: float
    qd_max: float
    qdd_max: float
    name: str = "A3"

    def __post_init__(self) -> None:
        for k in ("q_min", "q_max", "qd_max", "qdd_max"):
            v = getattr(self, k)
            if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v):
                raise TrajectoryError(f"axis limits: '{k}' must be a finite number, got {v!r}")
            object.__setattr__(self, k, float(v))
        if self.q_min >= self.q_max:
            raise TrajectoryError(f"axis limits: q_min ({self.q_min:.4g} rad, {self.q_min / _DEG:.4g} deg) must be "
                                  f"below q_max ({self.q_max:.4g} rad, {self.q_max / _DEG:.4g} deg)")
        for k in ("qd_max", "qdd_max"):
            if getattr(self, k) <= 0:
                raise TrajectoryError(f"axis limits: '{k}' must be positive, got {getattr(self, k):g}")

    @classmethod
    def kr6_r700_sixx(cls, axis: int = 3) -> "AxisLimits":
        """Axis limits of a KR 6 R700 sixx (data sheet ranges and speeds; acceleration assumed)."""
        table = {  # axis: (min deg, max deg, deg/s)
            1: (-170, 170, 360), 2: (-190, 45, 360), 3: (-120, 156, 360),
            4: (-185, 185, 381), 5: (-120, 120, 388), 6: (-350, 350, 615),
        }
        if axis not in table:
            raise TrajectoryError(f"axis limits: no built-in limits for axis A{axis}; give them with options or JSON")
        lo, hi, v = table[axis]
        return cls(q_min=lo * _DEG, q_max=hi * _DEG, qd_max=v * _DEG, qdd_max=10.0, name=f"A{axis}")

    default = kr6_r700_sixx

    @classmethod
    def from_dict(cls, d: Any, base: "AxisLimits | None" = None, where: str = "axis limits") -> "AxisLimits":
        """Limits from a dict; missing keys come from ``base`` (default: KR 6 R700 sixx A3)."""
        if not isinstance(d, dict):
            raise TrajectoryError(f"{where}: expected a JSON object")
        if isinstance(d.get("schema"), str):  # another of kukaid's files (a parameter file, a trajectory)
            raise TrajectoryError(f"{where}: is a {d['schema']} file, not a limits file (JSON: q_min, q_max, qd_max, "
                                  "qdd_max, optionally with _deg)")
        base = base or cls.kr6_r700_sixx()
        kw: dict[str, Any] = {}
        allowed = {"q_min", "q_max", "qd_max", "qdd_max", "name"}
        for k, v in d.items():
            key, scale = (k[:-4], _DEG) if k.endswith("_deg") else (k, 1.0)
            if key not in allowed:
                raise TrajectoryError(f"{where}: unknown key '{k}' (known: q_min, q_max, qd_max, qdd_max, "
                                      f"optionally with _deg)")
            if key != k and key in d:
                raise TrajectoryError(f"{where}: both '{key}' and '{k}' are given; give one")
            if key == "name":
                kw["name"] = str(v)
                continue
            if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v):
                raise TrajectoryError(f"{where}: '{k}' must be a finite number, got {v!r}")
            kw[key] = float(v) * scale
        try:
            return replace(base, **kw)
        except TrajectoryError as e:
            raise TrajectoryError(f"{where}: {str(e).split(': ', 1)[-1]}") from None

    @classmethod
    def load(cls, path: str | Path, base: "AxisLimits | None" = None) -> "AxisLimits":
        return cls.from_dict(read_json(path, TrajectoryError, "limits file (JSON)"), base=base, where=str(path))

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "q_min": self.q_min, "q_max": self.q_max, "qd_max": self.qd_max,
                "qdd_max": self.qdd_max}

    def violations(self, traj: Any) -> list[str]:
        """Every limit the trajectory breaks, as messages naming the limit, the value and the time."""
        t, q = traj.t, traj.q
        qd, qdd = traj.qd, traj.qdd
        out = []
        eps = 1e-9
        checks = (
            ("position", "q", q > self.q_max + eps * (1 + abs(self.q_max)), q - self.q_max, "rad", "deg",
             f"above the maximum {self.q_max:.4g} rad ({self.q_max / _DEG:.4g} deg)"),
            ("position", "q", q < self.q_min - eps * (1 + abs(self.q_min)), q - self.q_min, "rad", "deg",
             f"below the minimum {self.q_min:.4g} rad ({self.q_min / _DEG:.4g} deg)"),
            ("velocity", "|qd|", np.abs(qd) > self.qd_max * (1 + 1e-6), np.abs(qd), "rad/s", "deg/s",
             f"above the maximum {self.qd_max:.4g} rad/s ({self.qd_max / _DEG:.4g} deg/s)"),
            ("acceleration", "|qdd|", np.abs(qdd) > self.qdd_max * (1 + 1e-6), np.abs(qdd), "rad/s²", "deg/s²",
             f"above the maximum {self.qdd_max:.4g} rad/s² ({self.qdd_max / _DEG:.4g} deg/s²)"),
        )
        for limit, sym, mask, x, unit, unit_deg, what in checks:
            idx = np.flatnonzero(mask)
            if idx.size:
                i = int(idx[np.argmax(np.abs(x[idx]))])  # the worst sample
                first = float(t[idx[0]])
                val = q[i] if sym == "q" else x[i]
                out.append(
                    f"trajectory breaks the {limit} limit of {self.name}: {sym} = {val:.4g} {unit} "
                    f"({val / _DEG:.4g} {unit_deg}) at t = {t[i]:.3f} s is {what}"
                    + (f" (from t = {first:.3f} s)" if first != t[i] else "")
                )
        return out

    def check(self, traj: Any) -> None:
        """Raise :class:`LimitError` (one line, the first broken limit) if ``traj`` breaks a limit."""
        v = self.violations(traj)
        if v:
            more = f" (and {len(v) - 1} more limit(s))" if len(v) > 1 else ""
            raise LimitError(v[0] + more)
