"""The diagnosis' joint refit of a :class:`~kukaid.models.torque.JointTorqueModel` on filtered logs.

Every parameter except the Stribeck vs and delta (and the effects' nonlinear settings) enters
linearly, so the refit is a variable projection: an outer bounded least-squares over (vs, delta)
(and a ripple order already in the model), an inner linear least-squares over everything else,
bounded where physics bounds it (:data:`~kukaid.models.torque.BOUNDS`).  Residuals are formed
after the comparison filter (see :mod:`kukaid.diagnose.signals`).
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from kukaid.diagnose import candidates as C
from kukaid.errors import FitError
from kukaid.models.effects import EFFECTS
from kukaid.models.signals import LogSignals
from kukaid.models.torque import BOUNDS, JointTorqueModel

#: lower bounds of the linear parameters (friction levels and the inertia are not negative)
LOWER: dict[str, float] = {k: lo for k, (lo, hi) in BOUNDS.items() if k not in ("vs", "delta")}


def bounded_lstsq(X: np.ndarray, y: np.ndarray, lower: Sequence[float]) -> np.ndarray:
    """Least squares ``X theta ~ y`` with lower bounds (-inf for a free parameter): the ordinary
    solution when it keeps the bounds, else bounded least squares (scipy ``lsq_linear``)."""
    theta, *_ = np.linalg.lstsq(X, y, rcond=None)
    lo = np.asarray(lower, dtype=float)
    if np.all(theta >= lo):
        return theta
    from scipy.optimize import lsq_linear

    return lsq_linear(X, y, bounds=(lo, np.full(lo.size, np.inf)), lsmr_tol="auto", method="bvls").x


def refit(model: JointTorqueModel, sigs: Sequence[LogSignals]) -> JointTorqueModel:
    """Refit every parameter of ``model`` jointly on the compared rows of ``sigs``; returns a copy.

    Outer bounded least squares over the nonlinear parameters (Stribeck vs and delta, the
    ripple order n of a position_ripple already in the model, within +-0.5 of its value),
    inner linear least squares over all the others (variable projection).
    """
    from scipy.optimize import least_squares

    m = model.copy()
    y = np.concatenate([s.filtw(s.tau_raw)[s.rows] for s in sigs])
    if y.size == 0:
        raise FitError("no dynamic-mode samples to compare (is the axis moving?)")
    free = [k for k, e in enumerate(m.effects) if "n" in e.nl]  # effects with a continuous order

    def eff_block(s: LogSignals, ns: Sequence[float]) -> tuple[list[str], np.ndarray]:
        names, cols = [], []
        for k, e in enumerate(m.effects):
            nl = dict(e.nl)
            if k in free:
                nl["n"] = ns[free.index(k)]
            Z = EFFECTS[e.name].columns(s, nl, m)
            names += [e.key(c) for c in EFFECTS[e.name].coef_keys(nl)]
            cols += [s.filtw(Z[:, j])[s.rows] for j in range(Z.shape[1])]
        return names, (np.column_stack(cols) if cols else np.zeros((s.rows.size, 0)))

    fixed_eff = None if free else [eff_block(s, [])[1] for s in sigs]
    # filtered base columns that do not depend on (vs, delta): computed once
    n_fr = 2 if m.friction_kind == "stribeck" else 0
    fixed_base = []
    for s in sigs:
        nb0, Xb0 = m.base_columns(s)
        fixed_base.append(np.column_stack([s.filtw(Xb0[:, k]) for k in range(n_fr, Xb0.shape[1])])[s.rows])
    ne = eff_block(sigs[0], [m.effects[k].nl["n"] for k in free])[0] if m.effects else []
    stribeck = m.friction_kind == "stribeck"
    cache: dict = {}

    def solve(p: np.ndarray):
        key = tuple(np.round(p, 12))
        if key in cache:
            return cache[key]
        vs, delta = (math.exp(p[0]), p[1]) if stribeck else (m.vs, m.delta)
        ns = list(p[2:]) if stribeck else list(p)
        blocks = []
        for i, s in enumerate(sigs):
            if n_fr:
                nb, Xb = m.base_columns(s, vs, delta)
                Xv = np.column_stack([s.filtw(Xb[:, k]) for k in range(n_fr)])[s.rows]
                Xf = np.column_stack([Xv, fixed_base[i]])
            else:
                nb, _ = m.base_columns(s)
                Xf = fixed_base[i]
            E = fixed_eff[i] if fixed_eff is not None else eff_block(s, ns)[1]
            blocks.append(np.column_stack([Xf, E]))
        X = np.vstack(blocks)
        scale = np.linalg.norm(X, axis=0)
        scale[scale == 0] = 1.0
        names = nb + ne
        theta = bounded_lstsq(X / scale, y, [LOWER.get(k, -np.inf) * 1.0 for k in names]) / scale
        out = (names, theta, y - X @ theta)
        cache[key] = out
        return out

    p0, lb, ub = [], [], []
    if stribeck:
        p0 += [math.log(m.vs), m.delta]
        lb += [math.log(BOUNDS["vs"][0]), BOUNDS["delta"][0]]
        ub += [math.log(BOUNDS["vs"][1]), BOUNDS["delta"][1]]
    n_lo = C.get("position_ripple").lowest_order(sigs) if free else 0.0
    for k in free:
        n0 = float(m.effects[k].nl["n"])
        p0.append(n0)
        lb.append(max(n0 - 0.5, min(n0, n_lo)))  # not below the search's lowest order
        ub.append(n0 + 0.5)
    if p0:
        lb_a, ub_a = np.array(lb), np.array(ub)
        sol = least_squares(lambda p: solve(p)[2], np.clip(np.array(p0), lb_a + 1e-9, ub_a - 1e-9),
                            bounds=(lb_a, ub_a), diff_step=1e-4, xtol=1e-7, ftol=1e-9, max_nfev=80)
        x = sol.x
    else:
        x = np.zeros(0)
    if stribeck:
        m.vs, m.delta = math.exp(x[0]), float(x[1])
    for j, k in enumerate(free):
        m.effects[k].nl["n"] = float(x[(2 if stribeck else 0) + j])
    names, theta, _ = solve(x)
    m.set_coefs(names, theta)
    return m
