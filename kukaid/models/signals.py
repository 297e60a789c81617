"""Samples of one joint on a log's full time grid: what the joint-torque model's regressors read.

The diagnosis fills every field (:func:`kukaid.diagnose.signals.prepare`: the comparison filter,
the compared rows); other stages evaluate the model on plain samples (:meth:`LogSignals.of`).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass(frozen=True, eq=False)
class LogSignals:
    """One axis of one log on its full sample grid, with the filter used for the comparison.

    Attributes
    ----------
    time : (N,) s.   q_raw : (N,) rad (m), measured position.   tau_raw : (N,) N·m (N).
    q, qd, qdd : (N,) filtered position (rad), velocity (rad/s), acceleration (rad/s²).
    qd_lin, qdd_lin : (N,) unfiltered spectral derivatives of q_raw: the columns of terms linear
        in velocity or acceleration (filtered once, like the torque, in the comparison).
    temp : (N,) °C or None.
    rows : indices of the samples compared (dynamic mode, away from the log's ends).
    joint : "revolute" or "prismatic".   fs : sample rate, Hz.   cutoff : filter cut-off, Hz.
    name : label of the log (file name).
    others : {axis: (q, qdd)} of the log's other axes that move (raw position, rad, and its
        unfiltered spectral second derivative, rad/s²), for the ``coupling`` candidate.
    """

    time: np.ndarray
    q_raw: np.ndarray
    tau_raw: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    temp: np.ndarray | None
    rows: np.ndarray
    joint: str
    fs: float
    cutoff: float
    order: int
    name: str = "log"
    lowpass: Any = field(default=None, repr=False)
    qd_lin: np.ndarray | None = field(default=None, repr=False)
    qdd_lin: np.ndarray | None = field(default=None, repr=False)
    weight: np.ndarray | None = field(default=None, repr=False)
    others: dict[int, tuple[np.ndarray, np.ndarray]] | None = field(default=None, repr=False)

    def filtw(self, x: np.ndarray) -> np.ndarray:
        """Filter after zeroing the standstill samples (where the sliding model does not apply).

        Both the measured torque and every model column go through this, so a standstill sample
        contributes nothing to either side and cannot leak a model error into its neighbours.
        """
        x = np.asarray(x, dtype=float)
        return self.filt(x if self.weight is None else x * self.weight)

    def filt(self, x: np.ndarray) -> np.ndarray:
        """The comparison filter (zero-phase Butterworth) applied to a full-grid signal."""
        x = np.asarray(x, dtype=float)
        return x if self.lowpass is None else self.lowpass(x)

    @property
    def tau(self) -> np.ndarray:
        """Filtered measured torque (standstill samples zeroed) on the full grid, N·m."""
        return self.filtw(self.tau_raw)

    @property
    def n(self) -> int:
        return int(self.time.size)

    @property
    def elapsed(self) -> np.ndarray:
        """Time since the log started, s."""
        return self.time - self.time[0]

    @classmethod
    def of(cls, time: np.ndarray, q: np.ndarray, qd: np.ndarray, temp: np.ndarray | None = None,
           joint: str = "revolute", others: dict[int, np.ndarray] | None = None) -> "LogSignals":
        """Plain samples (no filter, every row): ``time`` s, ``q`` rad, ``qd`` rad/s (smooth),
        ``temp`` °C, ``others`` {axis: position, rad} of the other axes (their accelerations by
        finite differences)."""
        t = np.asarray(time, dtype=float)
        q = np.asarray(q, dtype=float)
        qd = np.asarray(qd, dtype=float)
        grad = (lambda x: np.gradient(x, t)) if t.size > 1 else (lambda x: np.zeros(t.size))
        oth = None
        if others:
            oth = {}
            for a, qa in others.items():
                qa = np.asarray(qa, dtype=float)
                oth[int(a)] = (qa, grad(grad(qa)))
        return cls(t, q, np.zeros(t.size), q, qd, grad(qd), None if temp is None else np.asarray(temp, dtype=float),
                   np.arange(t.size), joint, 1.0 / float(np.median(np.diff(t))) if t.size > 1 else 1.0, 0.0, 0,
                   "signals", others=oth)
