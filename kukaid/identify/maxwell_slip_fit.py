"""Maxwell-slip elements (eqs. 9-10) from a pre-sliding log, initial positions by eq. (12).

An element with break-away displacement ``d = W/k`` gives ``W * phi_d(z)`` where ``phi_d`` (the
element with unit saturation) depends on the displacement history ``z`` and on ``d`` only.  So,
for a grid of break-away displacements, the torque is *linear* in the saturations ``W``:

1. grid of ``d`` (log-spaced from a fraction of the smallest to the largest displacement swing
   of the data) -> non-negative least squares for ``W`` (plus a free constant torque: gravity at
   the stop position and the unmodelled ``Γu``);
2. the ``n_elements`` largest grid elements are kept and their ``d`` refined one at a time on a
   shrinking local grid of candidates (W by NNLS at every candidate), a few sweeps;
3. ``k = W / d``; initial positions by eq. (12): after the initiation move in direction ``s``
   stopping at ``z0`` every element is saturated, ``zeta_i = z0 - s d_i`` (stored relative to
   the stop position).

The fitted data are the quasi-static samples after the stop (the longest quasi-static stretch
of the log), filtered as every other log; ``z`` is the displacement from the stop position.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from kukaid.errors import FitError


def unit_elements(z: np.ndarray, d: np.ndarray, direction: float) -> np.ndarray:
    """phi (len(z), len(d)): unit-saturation element torques along z, saturated at start (eq. 12).

    Element position update of eq. (9) written as a clip: ``zeta <- clip(zeta, z - d, z + d)``
    (the element slips exactly when ``|z - zeta| >= d``); output ``(z - zeta) / d``.
    """
    z = np.asarray(z, dtype=float)
    d = np.asarray(d, dtype=float)
    zeta = z[0] - np.sign(direction) * d
    lo = z[:, None] - d[None, :]
    hi = z[:, None] + d[None, :]
    Z = np.empty((z.size, d.size))
    for j in range(z.size):
        np.maximum(zeta, lo[j], out=zeta)
        np.minimum(zeta, hi[j], out=zeta)
        Z[j] = zeta
    return (z[:, None] - Z) / d[None, :]


def nnls_gram(G: np.ndarray, b: np.ndarray, free: np.ndarray | None = None, max_iter: int = 200) -> np.ndarray:
    """min ||A x - y||^2 with x >= 0 (except ``free`` entries), from ``G = A^T A``, ``b = A^T y``.

    Lawson-Hanson active-set method on the normal equations (small problems: tens of columns).
    """
    n = b.size
    free = np.zeros(n, bool) if free is None else np.asarray(free, bool)
    P = free.copy()

    def solve(mask: np.ndarray) -> np.ndarray:
        out = np.zeros(n)
        idx = np.flatnonzero(mask)
        if idx.size:
            out[idx] = np.linalg.lstsq(G[np.ix_(idx, idx)], b[idx], rcond=None)[0]
        return out

    x = solve(P)
    tol = 1e-12 * max(1.0, float(np.abs(b).max()))
    for _ in range(max_iter):
        w = b - G @ x
        cand = ~P & (w > tol)
        if not cand.any():
            break
        P[int(np.argmax(np.where(cand, w, -np.inf)))] = True
        for _ in range(max_iter):
            s = solve(P)
            bad = P & ~free & (s <= 0)
            if not bad.any():
                x = s
                break
            # step from x towards s until the first passive variable hits zero
            ratio = np.where(bad, x / np.where(x - s != 0, x - s, 1.0), np.inf)
            alpha = float(np.clip(ratio.min(), 0.0, 1.0))
            x = x + alpha * (s - x)
            P = P & ~(~free & (x <= tol))
            x = np.where(P, x, 0.0)
    return np.where(free | (x > 0), x, 0.0)


def _nnls_const(Phi: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, float, float]:
    """min |Phi W + c - y| with W >= 0, c free; returns (W, c, rss)."""
    A = np.column_stack([Phi, np.ones(y.size)])
    free = np.zeros(A.shape[1], bool)
    free[-1] = True
    x = nnls_gram(A.T @ A, A.T @ y, free)
    r = y - A @ x
    return x[:-1], float(x[-1]), float(r @ r)


@dataclass
class MaxwellSlipFit:
    """Fitted Maxwell-slip model: k (N·m/rad), W (N·m), zeta0 (rad, relative to the stop)."""

    k: list[float]
    W: list[float]
    zeta0: list[float]
    constant: float
    rms: float
    direction: float
    n_samples: int
    stop_time: float
    swing: float = math.inf  # the fitted stretch's range of motion, rad: an element reverses within half of it

    @property
    def unsaturated(self) -> list[int]:
        """Elements whose break-away displacement is half the data's swing, the most the data can show (an
        element goes from one saturation to the other over twice it): their W, and the friction the axis
        holds at rest, are not determined beyond it."""
        return [i for i, (k, w) in enumerate(zip(self.k, self.W)) if w / k >= 0.99 * self.swing / 2.0]

    def to_dict(self) -> dict:
        return {"k": self.k, "W": self.W, "zeta0": self.zeta0}


def _quasi_static_stretch(pr: Any) -> tuple[int, int]:
    qs = pr.quasi_static
    idx = np.flatnonzero(np.diff(np.r_[0, qs.astype(int), 0]))
    runs = list(zip(idx[::2], idx[1::2]))
    if not runs:
        raise FitError(f"{pr.source}: pre-sliding fit: no quasi-static samples (|qd| < qd_thr)")
    a, b = max(runs, key=lambda r: r[1] - r[0])
    return int(a), int(b)


def fit_maxwell_slip(pr: Any, n_elements: int = 3, gravity: Callable[[np.ndarray], np.ndarray] | None = None,
                     n_grid: int = 30, sweeps: int = 4) -> MaxwellSlipFit:
    """Fit ``n_elements`` Maxwell-slip elements to the pre-sliding hysteresis of prepared log ``pr``.

    Parameters
    ----------
    pr : prepared pre-sliding log (initiation move, then standstill with micro-motion).
    n_elements : number of elements (default 3, the paper).
    gravity : optional q -> N·m gravity torque to subtract (else absorbed by the constant).

    Raises
    ------
    FitError : no quasi-static stretch, no motion in it, or no initiation move before it.
    """
    if n_elements < 1:
        raise FitError(f"Maxwell-slip: n_elements must be >= 1, got {n_elements}")
    a, b = _quasi_static_stretch(pr)
    if b - a < 20:
        raise FitError(f"{pr.source}: pre-sliding fit: the longest quasi-static stretch has only {b - a} samples")
    before = np.flatnonzero(np.abs(pr.qd[:a]) > 0)
    if a > 0 and before.size:
        direction = float(np.sign(pr.qd[a - 1]))
    else:
        direction = float(np.sign(pr.q[min(a + 1, b - 1)] - pr.q[a]) or 1.0)
    z = pr.q[a:b] - pr.q[a]
    y = pr.tau[a:b] - (gravity(pr.q[a:b]) if gravity is not None else 0.0)
    swing = float(np.ptp(z))
    if swing <= 0:
        raise FitError(f"{pr.source}: pre-sliding fit: the joint does not move at all while quasi-static")
    steps = np.abs(np.diff(z))
    dmin = max(float(np.percentile(steps[steps > 0], 50)) if np.any(steps > 0) else swing / 1e3, swing / 1e3)
    grid = np.geomspace(dmin, swing, n_grid)
    Phi = unit_elements(z, grid, direction)
    W, c, rss = _nnls_const(Phi, y)
    keep = np.argsort(W)[::-1][:n_elements]
    keep = keep[W[keep] > 0]
    if keep.size == 0:
        raise FitError(f"{pr.source}: pre-sliding fit: no hysteresis found (all element saturations zero)")
    d = np.sort(grid[keep])
    # an element's break-away W shows only where it goes from one saturation to the other, over twice its
    # break-away displacement: beyond half the data's swing it is a spring (or a constant) whose W they do not
    # show, and the grid's end made it (a gravity-loaded axis whose elements need more travel than the default
    # experiment's reversals: W 65-70 N·m for 7-15 true, the file refused before control); the refinement
    # keeps every element within it
    reach = swing / 2.0
    lg_lo, lg_hi = np.log(min(dmin, reach) / 3), np.log(reach)
    # refinement: one element at a time, a local grid of candidates evaluated in one pass
    # (the element columns of all candidates come from one simulation), the grid shrinking
    for sweep in range(sweeps):
        for i in range(d.size):
            others = np.delete(d, i)
            half = 1.5 / (sweep + 1)
            cand = np.exp(np.clip(np.log(d[i]) + np.linspace(-half, half, 17), lg_lo, lg_hi))
            P_all = unit_elements(z, np.r_[others, cand], direction)
            Po, Pc = P_all[:, :others.size], P_all[:, others.size:]
            costs = [_nnls_const(np.column_stack([Po, Pc[:, j]]), y)[2] for j in range(cand.size)]
            d[i] = cand[int(np.argmin(costs))]
    order = np.argsort(d)
    d = d[order]
    W, c, rss = _nnls_const(unit_elements(z, d, direction), y)
    ok = W > 0
    d, W = d[ok], W[ok]
    k = W / d
    zeta0 = -direction * d
    return MaxwellSlipFit([float(x) for x in k], [float(x) for x in W], [float(x) for x in zeta0], c,
                          float(np.sqrt(rss / y.size)), direction, int(y.size), float(pr.time[a]), swing)
