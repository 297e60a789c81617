"""Statistics that survive correlated residuals.

A filtered torque residual is strongly autocorrelated, so ordinary least-squares standard errors
would call almost any regressor significant.  The tests here

* decimate the residual to the filter bandwidth (the caller passes decimated rows),
* partial the current model's parameter Jacobian out of the candidate columns (the refit of all
  parameters is part of every candidate's explanation: Frisch-Waugh-Lovell),
* use a Wald statistic with a heteroscedasticity- and autocorrelation-consistent (HAC,
  Newey-West / Bartlett kernel) covariance whose bandwidth follows Andrews' AR(1) plug-in rule,
  computed per log (no lags across log boundaries) on AR(1)-prewhitened scores, referred to F(k, n / (L + 1)) rather than
  chi²(k) / k (a small-sample correction for long bandwidths),
* correct for several candidates (Holm) and for grid searches over a nonlinear parameter
  (Bonferroni over the effective number of independent grid points).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


def basis(J: np.ndarray, rtol: float = 1e-9) -> np.ndarray:
    """Orthonormal basis of the column space of ``J`` (rank-revealing SVD)."""
    if J is None or J.size == 0:
        return np.zeros((0 if J is None else J.shape[0], 0))
    scale = np.linalg.norm(J, axis=0)
    scale[scale == 0] = 1.0
    U, s, _ = np.linalg.svd(J / scale, full_matrices=False)
    keep = s > rtol * (s[0] if s.size else 1.0)
    return U[:, keep]


def partial_out(U: np.ndarray, X: np.ndarray) -> np.ndarray:
    """X minus its projection on the orthonormal basis U."""
    if U.shape[1] == 0:
        return X
    return X - U @ (U.T @ X)


def ar1(u: np.ndarray) -> float:
    """Lag-one autocorrelation of u (0 for a constant)."""
    u = np.asarray(u, dtype=float)
    if u.size < 3:
        return 0.0
    u = u - u.mean()
    den = float(u @ u)
    return float(u[1:] @ u[:-1] / den) if den > 0 else 0.0


def andrews_bandwidth(scores: np.ndarray, groups: np.ndarray, rho_max: float = 0.97) -> int:
    """Bartlett-kernel bandwidth (lags) by Andrews' (1991) AR(1) plug-in rule.

    ``scores`` (n, k) are the products column x residual; rho is estimated per column and group
    and averaged.
    """
    n = scores.shape[0]
    rhos = []
    for g in np.unique(groups):
        m = groups == g
        for c in range(scores.shape[1]):
            rhos.append(ar1(scores[m, c]))
    rho = float(np.clip(np.mean(rhos) if rhos else 0.0, -rho_max, rho_max))
    alpha = 4 * rho**2 / ((1 - rho) ** 2 * (1 + rho) ** 2)
    L = int(np.ceil(1.1447 * (alpha * n) ** (1.0 / 3.0)))
    return int(np.clip(L, 1, max(1, n // 4)))


def hac_meat(scores: np.ndarray, groups: np.ndarray, L: int) -> np.ndarray:
    """Newey-West long-run covariance sum_l w_l sum_t s_t s_{t-l}', per group, Bartlett weights."""
    k = scores.shape[1]
    S = np.zeros((k, k))
    for g in np.unique(groups):
        s = scores[groups == g]
        S += s.T @ s
        for lag in range(1, min(L, s.shape[0] - 1) + 1):
            w = 1.0 - lag / (L + 1.0)
            G = s[lag:].T @ s[:-lag]
            S += w * (G + G.T)
    return S


def hac_prewhitened(scores: np.ndarray, groups: np.ndarray, rho_max: float = 0.97) -> tuple[np.ndarray, int]:
    """Long-run covariance of ``scores`` with AR(1) prewhitening (Andrews and Monahan, 1992).

    Each column is whitened with its lag-one coefficient (pooled over the groups), the Bartlett /
    Andrews HAC estimate is taken of the whitened scores and recoloured by (1 - rho)^-1.
    Returns (covariance, bandwidth).
    """
    k = scores.shape[1]
    rho = np.zeros(k)
    for c in range(k):
        num = den = 0.0
        for g in np.unique(groups):
            x = scores[groups == g, c]
            if x.size > 2:
                num += float(x[1:] @ x[:-1])
                den += float(x[:-1] @ x[:-1])
        rho[c] = np.clip(num / den, -rho_max, rho_max) if den > 0 else 0.0
    parts, gs = [], []
    for g in np.unique(groups):
        x = scores[groups == g]
        if x.shape[0] > 1:
            parts.append(x[1:] - rho * x[:-1])
            gs.append(np.full(x.shape[0] - 1, g))
    u = np.vstack(parts) if parts else scores
    gu = np.concatenate(gs) if gs else groups
    L = andrews_bandwidth(u, gu)
    Su = hac_meat(u, gu, L) * (scores.shape[0] / max(u.shape[0], 1))
    Dinv = np.diag(1.0 / (1.0 - rho))
    return Dinv @ Su @ Dinv, L


@dataclass
class WaldResult:
    """A HAC Wald test of candidate columns against a residual (given the model's Jacobian)."""

    coef: np.ndarray          # fitted coefficients of the candidate columns
    cov: np.ndarray           # their HAC covariance
    stat: float               # Wald statistic, chi² with ``dof`` degrees of freedom under H0
    dof: int
    p_value: float            # uncorrected
    delta_rss: float          # residual sum of squares the columns remove (decimated rows)
    rss: float                # residual sum of squares before (decimated rows)
    bandwidth: int
    extra: dict = field(default_factory=dict)

    @property
    def std(self) -> np.ndarray:
        return np.sqrt(np.clip(np.diag(self.cov), 0, None))


def wald_test(r: np.ndarray, Z: np.ndarray, groups: np.ndarray, U: np.ndarray | None = None,
              bandwidth: int | None = None) -> WaldResult:
    """Test whether the columns ``Z`` explain part of the residual ``r`` beyond the basis ``U``.

    Parameters
    ----------
    r : (n,) residual on decimated rows.   Z : (n, k) candidate columns on the same rows.
    groups : (n,) log index of each row (HAC lags stay inside a log).
    U : orthonormal basis of the model's Jacobian (partialled out of Z and r), or None.
    bandwidth : Bartlett lags without prewhitening; default: AR(1)-prewhitened scores with
        Andrews' plug-in bandwidth (:func:`hac_prewhitened`).
    """
    from scipy.special import betainc

    Z = np.asarray(Z, dtype=float).reshape(r.size, -1)
    norm0 = np.linalg.norm(Z, axis=0)
    if U is not None:
        Z = partial_out(U, Z)
        r = partial_out(U, r[:, None])[:, 0]
    k = Z.shape[1]
    rss = float(r @ r)
    A = Z.T @ Z
    degenerate = np.linalg.norm(Z, axis=0) <= 1e-8 * np.maximum(norm0, 1e-300)
    if not np.all(np.isfinite(A)) or degenerate.any() or np.linalg.matrix_rank(A) < k:
        return WaldResult(np.zeros(k), np.full((k, k), np.inf), 0.0, k, 1.0, 0.0, rss, 0)
    Ainv = np.linalg.inv(A)
    b = Ainv @ (Z.T @ r)
    e = r - Z @ b
    scores = Z * e[:, None]
    if bandwidth is None:
        S, L = hac_prewhitened(scores, groups)
    else:
        L = int(bandwidth)
        S = hac_meat(scores, groups, L)
    V = Ainv @ S @ Ainv
    try:
        stat = float(b @ np.linalg.solve(V, b))
    except np.linalg.LinAlgError:
        stat = 0.0
    stat = max(stat, 0.0)
    # small-sample correction: F(k, n / (L + 1)) instead of chi2(k) / k (heavier tail when the
    # bandwidth is long compared with the record)
    df = max(2.0, r.size / (L + 1.0))
    x = stat / k
    p = float(betainc(df / 2.0, k / 2.0, df / (df + k * x))) if x > 0 else 1.0  # F(k, df) survival
    return WaldResult(b, V, stat, k, p, rss - float(e @ e), rss, L)


def holm(p_values: dict[str, float]) -> dict[str, float]:
    """Holm step-down adjusted p-values (family-wise error control over the candidates)."""
    names = sorted(p_values, key=lambda n: p_values[n])
    m = len(names)
    out, running = {}, 0.0
    for i, n in enumerate(names):
        running = max(running, min(1.0, (m - i) * p_values[n]))
        out[n] = running
    return out


def bonferroni(p: float, m: float) -> float:
    """p corrected for ``m`` effectively independent tries (m >= 1)."""
    return float(min(1.0, p * max(1.0, m)))
