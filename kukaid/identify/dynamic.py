"""Joint fit of the dynamic-mode model on any trajectory: friction + Izz/Mx (+My, offset, extras).

Model on the dynamic-mode samples (``Prepared.dynamic``) of every log::

    Γ = Izz qdd + Mx cos q [+ My sin q] [+ offset] + F(qd) + sum_j c_j x_j

with F the Stribeck (eq. 1) or Coulomb + viscous friction and x_j optional extra regressor
columns (the diagnose stage adds candidate effects this way).  Stribeck: separable bounded
least squares, variable-projection start + IPOPT (:mod:`kukaid.identify.stribeck_fit`).
Coulomb + viscous: linear least squares (bounded only if the free solution breaks a bound).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from kukaid.errors import FitError
from kukaid.models.joint import GRAVITY_OPTIONS, rigid_columns
from kukaid.identify.stribeck_fit import _merge_bounds, at_bounds, default_bounds, natural_uncertainty, solve_separable
from kukaid.identify.uncertainty import Uncertainty, covariance
from kukaid.models.friction import friction_columns
from kukaid.models.torque import JointTorqueModel

FRICTION_MODELS = ("stribeck", "coulomb-viscous")


def _columns(pr: Any, friction_model: str, gravity: str, offset: bool,
             extra_cols: dict[str, np.ndarray] | None, rows: np.ndarray | slice) -> tuple[list[str], np.ndarray]:
    q, qd, qdd = pr.q[rows], pr.qd[rows], pr.qdd[rows]
    names, R = rigid_columns(q, qdd, gravity, offset)
    fn, F = friction_columns("coulomb-viscous", qd)  # the Stribeck column is the separable solver's
    names = [*names, *fn]
    cols = [R, F]
    for k, x in (extra_cols or {}).items():
        names.append(k)
        cols.append(np.asarray(x, dtype=float)[rows][:, None])
    return names, np.hstack(cols)


@dataclass
class DynamicFit:
    """Result of :func:`fit_dynamic`.

    Attributes
    ----------
    params_ : {name: value}: Izz, Mx (My, offset), Fc, Fv (Fs, vs, delta for Stribeck), extras.
    std_ : {name: standard deviation} (optimistic: see :mod:`kukaid.identify.uncertainty`).
    cov_ : (p, p) covariance in the order ``names_``.   uncertainty_ : correlation, condition.
    residual_ : per log, measured - predicted torque on *every* prepared sample, N·m (the fit
        used only the dynamic samples; ``fitted_`` holds those masks).
    mse_ : mean squared residual on the fitted samples, N²m².   cost_ : 0.5 sum r².
    ipopt_status : IPOPT return status ("linear" for the Coulomb + viscous model).
    """

    params_: dict[str, float]
    std_: dict[str, float]
    cov_: np.ndarray
    names_: list[str]
    uncertainty_: Uncertainty
    residual_: list[np.ndarray]
    fitted_: list[np.ndarray]
    mse_: float
    cost_: float
    ipopt_status: str
    friction_model: str
    gravity: str
    offset: bool
    extra_names: list[str] = field(default_factory=list)
    n_samples: int = 0
    info: dict[str, Any] = field(default_factory=dict)
    converged: bool = True
    at_bound_: list[dict[str, Any]] = field(default_factory=list)

    @property
    def model_(self) -> JointTorqueModel:
        """The fitted joint-torque model (without the extra columns)."""
        p = self.params_
        lin = {k: p[k] for k in ("Fc", "Fs", "Fv", "Izz", "Mx", "My", "offset") if k in p}
        return JointTorqueModel(self.friction_model, lin, p.get("vs", 0.04), p.get("delta", 1.0))

    def predict(self, prepared: Any, extra: dict[str, np.ndarray] | None = None) -> np.ndarray:
        """Predicted torque on every sample of ``prepared`` (N·m); ``extra`` columns as in the fit."""
        missing = [k for k in self.extra_names if not extra or k not in extra]
        if missing:
            raise FitError(f"predict: extra regressor(s) {missing} needed (they were fitted)")
        out = self.model_.predict_dynamic(prepared.q, prepared.qd, prepared.qdd)
        for k in self.extra_names:
            out = out + self.params_[k] * np.asarray(extra[k], dtype=float)
        return out


def fit_dynamic(prepared_list: Sequence[Any], friction_model: str = "stribeck", gravity: str = "cos",
                offset: bool = False, extra: dict[str, Sequence[np.ndarray]] | None = None,
                bounds: dict[str, tuple[float | None, float | None]] | None = None) -> DynamicFit:
    """Fit friction and rigid body jointly on the dynamic samples of all prepared logs.

    Parameters
    ----------
    prepared_list : prepared logs (:func:`kukaid.identify.preprocess`).
    friction_model : "stribeck" or "coulomb-viscous".
    gravity : "cos", "cos+sin" or "none".   offset : fit a constant torque (N·m).
    extra : {name: [column per prepared log]}, each column (n,) on that log's prepared samples;
        their coefficients are fitted jointly (free sign).
    bounds : {name: (lo, hi)} overriding the data-derived defaults (names: Izz, Mx, Fc, Fs-Fc,
        Fv, vs, delta, ...).

    Raises
    ------
    FitError : no dynamic samples, one direction of motion only, rank deficiency, failed solve.
    """
    if friction_model not in FRICTION_MODELS:
        raise FitError(f"friction model must be one of {FRICTION_MODELS}, got '{friction_model}'")
    if gravity not in GRAVITY_OPTIONS:
        raise FitError(f"gravity must be one of {GRAVITY_OPTIONS}, got '{gravity}'")
    preps = list(prepared_list)
    if not preps:
        raise FitError("no logs to fit")
    extra = dict(extra or {})
    for k, cols in extra.items():
        if len(cols) != len(preps):
            raise FitError(f"extra regressor '{k}': {len(cols)} columns for {len(preps)} logs")
        for pr, x in zip(preps, cols):
            if np.shape(x) != (pr.n,):
                raise FitError(f"extra regressor '{k}': column of shape {np.shape(x)} for a log of {pr.n} samples")
            if not np.all(np.isfinite(x)):
                raise FitError(f"extra regressor '{k}' has non-finite values")
    ys, As, vs = [], [], []
    names: list[str] = []
    for i, pr in enumerate(preps):
        m = pr.dynamic
        names, A = _columns(pr, friction_model, gravity, offset, {k: c[i] for k, c in extra.items()}, m)
        ys.append(pr.tau[m])
        As.append(A)
        vs.append(pr.qd[m])
    y, A, v = np.concatenate(ys), np.vstack(As), np.concatenate(vs)
    where = ", ".join(sorted({pr.source for pr in preps}))[:200]
    # a pre-sliding log (its experiment attribute) moves a fraction of a degree, below qd_thr: its own role
    ps = [pr.source for pr in preps if pr.kind == "presliding"]
    hint = (f"; {', '.join(ps)} records the pre-sliding experiment (attribute 'experiment'): give it as "
            "--presliding, beside a friction or inertia log" if ps else "")
    thr = f"|qd| >= qd_thr {preps[0].qd_thr:g} {'m/s' if preps[0].joint == 'prismatic' else 'rad/s'}"
    if y.size == 0:
        raise FitError(f"{where}: no dynamic-mode samples ({thr} away from reversals); the axis must move{hint}")
    if y.size < len(names) + 5:  # before the directions: a handful of samples may all be of one
        dec = max(int(pr.settings.get("decimate", 1)) for pr in preps)
        raise FitError(f"{where}: only {y.size} dynamic-mode samples for {len(names)} parameters"
                       + (f" (every {dec}th sample kept: --decimate {dec})" if dec > 1 else "") + hint)
    if not (np.any(v > 0) and np.any(v < 0)):
        raise FitError(f"{where}: the axis moves in one direction only at dynamic-mode speeds ({thr} away from "
                       f"reversals: {y.size} samples); friction and gravity cannot be separated (move both ways)"
                       + hint)
    if np.linalg.matrix_rank(A) < A.shape[1]:
        raise FitError(f"{where}: the regressor [{', '.join(names)}] is rank deficient on these data "
                       "(the motion does not excite every parameter)")
    if friction_model == "stribeck":
        sr = solve_separable(y, A, v, names, bounds=bounds, where=where)
        params, u = natural_uncertainty(sr)
        status, cost, res = sr.status, sr.cost, sr.residual
        info = {"start": dict(zip(sr.names, map(float, sr.start))), "start_cost": sr.start_cost,
                "iterations": sr.iterations, "solve_time": sr.solve_time, "bounds": sr.info["bounds"]}
        converged, on_bound = sr.converged, sr.at_bound(u.std)
    else:
        theta, status, info = linear_bounded(y, A, names, bounds, v)
        res = y - A @ theta
        cost = 0.5 * float(res @ res)
        u = covariance(res, A, names, theta)
        params = dict(zip(names, map(float, theta)))
        converged = True
        on_bound = at_bounds(names, theta, [info["bounds"][k] for k in names], u.std)
    order = [k for k in ("Izz", "Mx", "My", "offset", "Fc", "Fs", "vs", "delta", "Fv") if k in params]
    order += [k for k in params if k not in order]
    idx = [list(u.names).index(k) for k in order]
    u = Uncertainty(tuple(order), u.values[idx], u.cov[np.ix_(idx, idx)], u.sigma2, u.n, u.cond)
    params = {k: params[k] for k in order}
    fit = DynamicFit(params, u.std, u.cov, order, u, [], [pr.dynamic.copy() for pr in preps],
                     float(np.mean(res ** 2)), cost, status, friction_model, gravity, bool(offset),
                     list(extra), int(y.size), info, converged, on_bound)
    fit.residual_ = [pr.tau - fit.predict(pr, {k: c[i] for k, c in extra.items()}) for i, pr in enumerate(preps)]
    return fit


def linear_bounded(y: np.ndarray, A: np.ndarray, names: Sequence[str], bounds: dict | None,
                   v: np.ndarray) -> tuple[np.ndarray, str, dict[str, Any]]:
    """Linear least squares ``A theta ~ y`` within the bounds of the parameters ``names``: the data's
    (:func:`~kukaid.identify.stribeck_fit.default_bounds`, from ``y`` and the velocities ``v``) with
    ``bounds`` ({name: (lo, hi)}, the user's) over them.  Returns (theta, status "linear" or "linear
    (bounded)" when a bound is active, {"bounds": {name: [lo, hi]}})."""
    bnd = _merge_bounds(default_bounds(y, v, names), bounds)
    lo = np.array([bnd[k][0] for k in names])
    hi = np.array([bnd[k][1] for k in names])
    theta = np.linalg.lstsq(A, y, rcond=None)[0]
    if np.all(theta >= lo) and np.all(theta <= hi):
        return theta, "linear", {"bounds": {k: list(bnd[k]) for k in names}}
    from scipy.optimize import lsq_linear

    r = lsq_linear(A, y, bounds=(lo, hi), lsmr_tol="auto")
    if not r.success:
        raise FitError(f"bounded linear least squares failed: {r.message}")
    return r.x, "linear (bounded)", {"bounds": {k: list(bnd[k]) for k in names}}
