"""Parameter uncertainty from the residual variance and the Jacobian, and fit metrics.

For a least-squares fit with residual r (n,) and Jacobian J = dr/dp (n, p) at the solution,
the covariance is ``s2 (J^T J)^-1`` with ``s2 = r^T r / (n - p)``.  This assumes independent,
identically distributed residuals.  The residuals of a fit on low-pass-filtered signals are
strongly correlated in time (the filter passes about ``2 cutoff / fs`` of the white-noise band),
so these standard deviations are **optimistic**: the true spread can be larger by roughly
``sqrt(fs / (2 cutoff))`` for noise-dominated parameters.  Parameters held at a bound get the
unconstrained value.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class Uncertainty:
    """Covariance and derived figures of a least-squares estimate (parameters in ``names``)."""

    names: tuple[str, ...]
    values: np.ndarray
    cov: np.ndarray
    sigma2: float
    n: int
    cond: float

    @property
    def std(self) -> dict[str, float]:
        return {k: float(np.sqrt(max(self.cov[i, i], 0.0))) for i, k in enumerate(self.names)}

    @property
    def rel_std(self) -> dict[str, float]:
        s = self.std
        return {k: (s[k] / abs(v) if v != 0 else float("inf")) for k, v in zip(self.names, self.values)}

    @property
    def corr(self) -> np.ndarray:
        d = np.sqrt(np.clip(np.diag(self.cov), 1e-300, None))
        return self.cov / np.outer(d, d)


def covariance(residual: np.ndarray, jac: np.ndarray, names: list[str] | tuple[str, ...],
               values: np.ndarray) -> Uncertainty:
    """Covariance ``s2 (J^T J)^-1`` and the condition number of the column-normalised Jacobian.

    Parameters
    ----------
    residual : (n,) residual at the solution (same unit as the data, N·m).
    jac : (n, p) derivative of the residual (or of the prediction: the sign does not matter).
    names, values : the p parameter names and values.
    """
    r = np.asarray(residual, dtype=float)
    J = np.asarray(jac, dtype=float)
    n, p = J.shape
    dof = max(n - p, 1)
    sigma2 = float(r @ r) / dof
    norms = np.linalg.norm(J, axis=0)
    norms[norms == 0] = 1.0
    Jn = J / norms
    sv = np.linalg.svd(Jn, compute_uv=False)
    cond = float(sv[0] / sv[-1]) if sv[-1] > 0 else float("inf")
    Ginv = np.linalg.pinv(Jn.T @ Jn)
    cov = sigma2 * Ginv / np.outer(norms, norms)
    return Uncertainty(tuple(names), np.asarray(values, dtype=float), cov, sigma2, n, cond)


def transform(u: Uncertainty, names: list[str], values: np.ndarray, T: np.ndarray) -> Uncertainty:
    """Covariance of linearly transformed parameters ``p' = T p`` (e.g. Fs = Fc + (Fs - Fc))."""
    return Uncertainty(tuple(names), np.asarray(values, dtype=float), T @ u.cov @ T.T, u.sigma2, u.n, u.cond)


def correlation_factor(residual: np.ndarray, max_lag: int) -> float:
    """sqrt(1 + 2 sum_{k=1..max_lag} rho_k): how much the residual's correlation in time inflates
    the standard deviations (1 for white residuals).  Multiply ``std`` by it for a less
    optimistic figure (exact for slowly varying regressors)."""
    r = np.asarray(residual, dtype=float)
    r = r - r.mean()
    v = float(r @ r)
    if r.size < 3 or v == 0:
        return 1.0
    L = int(min(max_lag, r.size - 2))
    rho = np.array([float(r[:-k] @ r[k:]) / v for k in range(1, L + 1)])
    return float(np.sqrt(max(1.0, 1.0 + 2.0 * rho.sum())))
