"""Izz and Mx by linear least squares with friction compensated, eqs. (6)-(8).

``[qdd  cos q  (sin q)  (1)] [Izz Mx (My) (offset)]^T = Γ - Γf`` stacked over the dynamic-mode
samples of the inertia experiment(s) and solved by least squares (the paper's
``theta = (H^T H)^-1 H^T (Γ - Γf)``, computed with an orthogonal factorisation).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from kukaid.errors import FitError
from kukaid.identify.uncertainty import Uncertainty, covariance
from kukaid.models.joint import rigid_columns


@dataclass
class RigidFit:
    """Result of :func:`fit_rigid`: ``params_``, ``std_``, ``uncertainty_``, per-log residuals."""

    params_: dict[str, float]
    std_: dict[str, float]
    uncertainty_: Uncertainty
    residual_: list[np.ndarray]
    mse_: float


def fit_rigid(preps: Sequence[Any], friction: Any, gravity: str = "cos", offset: bool = False) -> RigidFit:
    """Izz, Mx (My, offset) on the dynamic samples of ``preps`` with ``friction`` compensated.

    Parameters
    ----------
    preps : prepared logs (:class:`~kukaid.identify.filtering.Prepared`) of the inertia experiment.
    friction : a friction model (callable velocity -> N·m), e.g. the Stribeck fit.
    gravity, offset : see :func:`rigid_columns`.

    Raises
    ------
    FitError : no dynamic samples or a rank-deficient regressor.
    """
    ys, Hs = [], []
    names: list[str] = []
    for pr in preps:
        m = pr.dynamic
        names, H = rigid_columns(pr.q[m], pr.qdd[m], gravity, offset)
        ys.append(pr.tau[m] - friction(pr.qd[m]))
        Hs.append(H)
    y = np.concatenate(ys) if ys else np.zeros(0)
    if y.size < len(names) + 2:
        raise FitError(f"inertia fit: only {y.size} dynamic-mode samples; the axis must move (|qd| >= qd_thr)")
    H = np.vstack(Hs)
    if np.linalg.matrix_rank(H) < H.shape[1]:
        raise FitError(f"inertia fit: the regressor [{', '.join(names)}] is rank deficient on these data "
                       "(the motion does not excite every parameter)")
    theta = np.linalg.lstsq(H, y, rcond=None)[0]
    res = y - H @ theta
    u = covariance(res, H, names, theta)
    residual = []
    for pr in preps:
        _, Hf = rigid_columns(pr.q, pr.qdd, gravity, offset)
        residual.append(pr.tau - friction(pr.qd) - Hf @ theta)
    return RigidFit(dict(zip(names, map(float, theta))), u.std, u, residual, float(np.mean(res ** 2)))
