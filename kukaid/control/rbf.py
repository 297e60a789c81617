"""Adaptive damping by a radial-basis-function network, eqs. (17)-(22).

    D*(x) = D0 + sum_i w_i G(||x - y_i||),   G = exp(-||(x - y_i) / s||² / 2)          (17)-(18)
    x     = [Γr(k-m) ... Γr(k), dΓr(k-m) ... dΓr(k)]   (dΓr: first difference of Γr)
    ξ     = ½ dΓr² + ½ λ Γr²                                                            (19)
    Δw_i  = -(η1 dΓr + λ η2 Γr) · s · G(||x - y_i||)                                     (20)-(21)
    w_i(k+1) = w_i(k) + Δw_i                                                             (22)

Choices this module makes where the paper leaves room (stated, not hidden):

* a constant bias ``D0`` (not adapted) so the untrained network gives the constant damping; the
  paper's sum alone starts from whatever the initial weights give;
* input scaling: Γr in units of ``force_scale`` (N·m), dΓr in units of ``dforce_scale`` (N·m per
  step), one width ``width`` in those units; centres on a grid of expected force levels and
  force-change levels (the same level on every lag).  With ``scale_to_seen`` the scales grow
  with the torques actually seen (an envelope of |Γr| and |dΓr| that forgets over
  ``scale_memory`` s), so the outermost centres sit at the largest recent torque and a firm
  grip's 60 N·m does not fall outside the network (the fixed scales are the minimum);
* the sign ``s`` of the unknown sensitivities ∂Γr/∂D, ∂dΓr/∂D: for Γr = I σ̈ + D σ̇ it is the sign
  of σ̇ (η1, η2 absorb the magnitudes, as in eq. 21); the paper's eq. (20) is the case s = +1.
  So a steady push lowers the damping (the robot gives way) and a growing contact force change
  against the motion raises it (the robot stops when the hand lets go);
* the damping is bounded to [D_min, D_max] with D_min > 0 (stability: the admittance also checks
  Δt D/I < 2); at a bound, updates that would push further are not applied (no wind-up);
* weights adapt only while an external torque is detected.
"""
from __future__ import annotations

import itertools
import math
import operator
from dataclasses import dataclass

import numpy as np

from kukaid.errors import KukaidError


@dataclass(frozen=True)
class RBFConfig:
    """Settings of :class:`RBFDamping` (SI: N·m, N·m·s/rad)."""

    D0: float = 50.0
    D_min: float = 15.0
    D_max: float = 100.0
    eta1: float = 2.0
    eta2: float = 0.5
    lam: float = 0.05
    m: int = 1
    force_levels: tuple[float, ...] = (-20.0, -10.0, 0.0, 10.0, 20.0)
    dforce_levels: tuple[float, ...] = (-0.5, 0.0, 0.5)
    force_scale: float = 10.0
    dforce_scale: float = 0.5
    width: float = 1.0
    scale_to_seen: bool = True
    scale_memory: float = 10.0

    def __post_init__(self) -> None:
        checks = [("D_min", self.D_min > 0), ("D_max", self.D_max >= self.D_min),
                  ("D0", self.D_min <= self.D0 <= self.D_max), ("eta1", self.eta1 >= 0), ("eta2", self.eta2 >= 0),
                  ("lam", self.lam >= 0), ("m", isinstance(self.m, int) and 0 <= self.m <= 10),
                  ("force_scale", self.force_scale > 0), ("dforce_scale", self.dforce_scale > 0),
                  ("width", self.width > 0), ("force_levels", len(self.force_levels) > 0),
                  ("dforce_levels", len(self.dforce_levels) > 0)]
        for name, ok in checks:
            if not ok:
                raise KukaidError(f"rbf damping: {name} = {getattr(self, name)} is not allowed "
                                  f"(need 0 < D_min <= D0 <= D_max, eta1, eta2, lam >= 0, 0 <= m <= 10, "
                                  f"positive scales and width, non-empty levels)")


def _gauss(history: list[float], scale: float, levels: list[float], k: float) -> list[float]:
    """exp(k Σ (x / scale - y)²) over the lags x of ``history``, for every level y (through Σx and Σx²)."""
    n = len(history)
    s = sum(history) / scale
    ss = sum(map(operator.mul, history, history)) / (scale * scale)
    return [math.exp(k * (ss + y * (n * y - 2.0 * s))) for y in levels]


def cost(gamma_r: np.ndarray, lam: float) -> np.ndarray:
    """Per-step cost ξ = ½ dΓr² + ½ λ Γr² of eq. (19) (dΓr first difference; first step dΓr = 0)."""
    g = np.asarray(gamma_r, dtype=float)
    d = np.diff(g, prepend=g[:1])
    return 0.5 * d * d + 0.5 * lam * g * g


class RBFDamping:
    """The adaptive damping law; call :meth:`step` once per control cycle."""

    def __init__(self, config: RBFConfig | None = None) -> None:
        self.config = c = config or RBFConfig()
        n_lag = c.m + 1
        # centres: every (force level, force-change level) pair, repeated on all lags
        pairs = list(itertools.product(c.force_levels, c.dforce_levels))
        self.centres = np.array([[f / c.force_scale] * n_lag + [d / c.dforce_scale] * n_lag for f, d in pairs])
        self._wl = [0.0] * len(pairs)
        self._fl = [f / c.force_scale for f in c.force_levels]  # centre levels in scaled units
        self._dl = [d / c.dforce_scale for d in c.dforce_levels]
        self._f_top = max(abs(f) for f in c.force_levels) / c.force_scale or 1.0
        self._d_top = max(abs(d) for d in c.dforce_levels) / c.dforce_scale or 1.0
        self.reset_history()

    @property
    def w(self) -> np.ndarray:
        """The weights w_i, N·m·s/rad (one per centre)."""
        return np.asarray(self._wl)

    def reset_history(self, gamma_r0: float = 0.0) -> None:
        n = self.config.m + 1
        self._g = [float(gamma_r0)] * n
        self._dg = [0.0] * n
        self._prev = float(gamma_r0)
        self.D = self.config.D0
        self._peak_g = 0.0
        self._peak_dg = 0.0

    def _levels(self) -> tuple[list[float], list[float]]:
        """The two factors of G: G of centre (i, j) is ``ef[i] * ed[j]``, ``ef`` over the force levels and
        ``ed`` over the force-change levels (plain floats: 15 small centres are faster than numpy's
        per-call overhead, and the factors make the sums over centres products of two short sums)."""
        c = self.config
        fs, ds = c.force_scale, c.dforce_scale
        if c.scale_to_seen:  # the outermost centre level sits at the largest recent torque
            fs = max(fs, self._peak_g / self._f_top)
            ds = max(ds, self._peak_dg / self._d_top)
        k = -0.5 / (c.width * c.width)
        return _gauss(self._g, fs, self._fl, k), _gauss(self._dg, ds, self._dl, k)

    _fade = 0.0  # per-step forgetting of the envelopes, set by :meth:`set_cycle`

    def set_cycle(self, cycle: float) -> None:
        """Tell the network its control cycle (s), for the envelopes' memory."""
        self._fade = min(float(cycle) / self.config.scale_memory, 1.0)

    def step(self, gamma_r: float, direction: float = 1.0, adapt: bool = True) -> float:
        """Feed Γr (N·m) of this cycle; return the damping D (N·m·s/rad) to use in it.

        ``direction`` is the sign of the reference velocity σ̇ (sign of the sensitivities);
        ``adapt`` False freezes the weights (no interaction).
        """
        c = self.config
        g = float(gamma_r)
        dg = g - self._prev
        self._prev = g
        self._g = self._g[1:] + [g]
        self._dg = self._dg[1:] + [dg]
        if c.scale_to_seen:
            fade = 1.0 - self._fade
            self._peak_g = max(abs(g), self._peak_g * fade)
            self._peak_dg = max(abs(dg), self._peak_dg * fade)
        ef, ed = self._levels()
        G = [e * d for e in ef for d in ed]  # the centres in the order of ``pairs``
        w = self._wl
        D_raw = c.D0 + sum(map(operator.mul, w, G))
        D = min(max(D_raw, c.D_min), c.D_max)
        if adapt:
            s = 1.0 if direction >= 0 else -1.0
            a = -(c.eta1 * dg + c.lam * c.eta2 * g) * s
            # the change of D this update makes: a times the sum of G² over the centres
            trend = a * sum(map(operator.mul, ef, ef)) * sum(map(operator.mul, ed, ed))
            # no wind-up: at a bound, do not push further out
            if not ((D_raw <= c.D_min and trend < 0) or (D_raw >= c.D_max and trend > 0)):
                self._wl = [wi + a * gi for wi, gi in zip(w, G)]
        self.D = D
        return D
