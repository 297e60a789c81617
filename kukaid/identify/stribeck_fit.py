"""Stribeck friction (eq. 1) by bounded interior-point least squares (CasADi + IPOPT).

The model is *separable*: given the Stribeck velocity ``vs`` and the shape exponent ``delta``,
every other parameter (Fc, Fs - Fc, Fv, and in the joint fit Izz, Mx, My, offset and any extra
regressor) enters linearly.  :func:`solve_separable` therefore

1. finds a start by **variable projection**: a grid over (log vs, delta) where, for each grid
   point, the linear parameters are eliminated by least squares (a QR of the fixed columns makes
   each grid point one dot product); the best grid point (with Fs - Fc >= 0) is the start, so
   the local solver does not land in a local minimum of the (vs, delta) valley;
2. refines all parameters together with IPOPT under bounds (``casadi.nlpsol``), in scaled
   variables (linear parameters divided by their start magnitude, ``log vs``);
3. refuses a failed solve (:class:`~kukaid.errors.FitError`) and keeps the better of start and
   solution.

Default bounds, derived from the data (overridable by ``bounds={name: (lo, hi)}``):
``Fc`` in [0, F99] and ``Fs - Fc`` in [0, F99] where F99 is the 99th percentile of |torque| over
the fitted samples; ``Fv`` in [0, inf); ``Izz`` in [IZZ_MIN, inf), the parameter file's minimum
(:data:`kukaid.params.axis.IZZ_MIN`; a user bound below it is raised to it); ``vs`` in [v1 / 2, v99]
with v1, v99 the 1st and 99th percentiles of |qd| over the fitted samples (outside that range the Stribeck
term is not informed by the data); ``delta`` in [0.5, 2] (the paper); Mx, My, offset and extra
coefficients free.
"""
from __future__ import annotations

import functools
import math
import time as _time
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from kukaid.errors import FitError
from kukaid.identify.solve_interrupt import interruptible_solve
from kukaid.identify.uncertainty import Uncertainty, covariance, transform
from kukaid.models.friction import stribeck_columns_at, stribeck_power
from kukaid.params.axis import IZZ_MIN

INF = float("inf")
DELTA_BOUNDS = (0.5, 2.0)
_OK_STATUS = ("Solve_Succeeded", "Solved_To_Acceptable_Level")
#: IPOPT stopped before its convergence test held but on a feasible point no worse than the start:
#: the best point is kept and the result is marked not converged (the fit says why and warns)
_STOPPED_STATUS = ("Maximum_Iterations_Exceeded", "Search_Direction_Becomes_Too_Small",
                   "Restoration_Failed", "Maximum_CpuTime_Exceeded")


@dataclass
class SeparableResult:
    """Solution of a separable Stribeck least-squares problem (natural parameters)."""

    names: list[str]            # linear names, then "dF", "vs", "delta" (dF = Fs - Fc)
    values: np.ndarray
    residual: np.ndarray        # y - prediction, (n,)
    jac: np.ndarray             # d prediction / d parameter, (n, p)
    cost: float                 # 0.5 * sum(residual**2)
    status: str
    start: np.ndarray
    start_cost: float
    iterations: int = 0
    solve_time: float = 0.0
    info: dict[str, Any] = field(default_factory=dict)
    converged: bool = True

    def at_bound(self, std: dict[str, float] | None = None) -> list[dict[str, Any]]:
        """Parameters that end on (or within a tiny tolerance of) a bound (:func:`at_bounds`)."""
        names = ["Fs-Fc" if k == "dF" else k for k in self.names]
        b = self.info.get("bounds", {})
        return at_bounds(names, self.values, [b[k] for k in self.names], std)


def at_bounds(names: Sequence[str], values: Sequence[float], bounds: Sequence[Sequence[float]],
              std: dict[str, float] | None = None, rtol: float = 1e-6) -> list[dict[str, Any]]:
    """Parameters whose value is on a bound: ``[{"name", "value", "bound", "side"}]``.

    "On" means within ``rtol`` of the scale of the parameter (the bound interval's width when it
    is finite, else the largest of |bound|, |value| and the parameter's standard deviation: a value
    1e-10 above a bound of 0 with a standard deviation of 7 is on the bound), or within 1 % of its
    standard deviation: an interior-point solution stops a little inside an active bound (delta
    1.9999964 with a bound of 2 and a standard deviation of 0.22), a distance the data cannot see.
    """
    out = []
    std = std or {}
    for k, v, (lo, hi) in zip(names, values, bounds):
        v, lo, hi = float(v), float(lo), float(hi)
        width = hi - lo
        for side, b in (("lower", lo), ("upper", hi)):
            if not math.isfinite(b):
                continue
            sd = float(std.get(k, 0.0) or 0.0)
            sd = sd if math.isfinite(sd) else 0.0
            scale = width if math.isfinite(width) and width > 0 else max(abs(b), abs(v), sd)
            if abs(v - b) <= max(rtol * max(scale, 1e-12), 0.01 * sd):
                out.append({"name": k, "value": v, "bound": b, "side": side})
                break
    return out


def default_bounds(y: np.ndarray, v: np.ndarray, lin_names: Sequence[str]) -> dict[str, tuple[float, float]]:
    """Bounds derived from the data (see the module docstring)."""
    f99 = float(np.percentile(np.abs(y), 99)) if y.size else 1.0
    f99 = max(f99, 1e-9)
    s = np.abs(v)
    v1, v99 = (float(np.percentile(s, 1)), float(np.percentile(s, 99))) if s.size else (1e-3, 1.0)
    vlo = max(v1 / 2.0, 1e-9)
    vhi = max(v99, vlo * 10.0)
    b = {"Fc": (0.0, f99), "dF": (0.0, f99), "Fv": (0.0, INF), "Izz": (IZZ_MIN, INF), "vs": (vlo, vhi),
         "delta": DELTA_BOUNDS}
    return {k: b.get(k, (-INF, INF)) for k in (*lin_names, "dF", "vs", "delta")}


def check_bound(name: str, lo: float | None, hi: float | None) -> tuple[float, float]:
    """One user bound as (lo, hi) floats (None: unbounded), checked: numbers, lo <= hi, vs and delta
    above 0, Izz raised to the parameter file's minimum, Fc and Fv to 0.  Raises :class:`FitError`."""
    lo = -INF if lo is None else float(lo)
    hi = INF if hi is None else float(hi)
    if math.isnan(lo) or math.isnan(hi):
        raise FitError(f"bounds for {name}: a bound is not a number")
    if not lo <= hi:
        raise FitError(f"bounds for {name}: lower {lo:g} is above upper {hi:g}")
    if name == "Izz":  # a parameter file holds Izz >= IZZ_MIN: the fit never goes below
        if hi < IZZ_MIN:
            raise FitError(f"bounds for {name}: the upper bound must be >= {IZZ_MIN:g} (the parameter file's "
                           f"minimum), got {hi:g}")
        lo = max(lo, IZZ_MIN)
    if name in ("Fc", "Fv"):  # a parameter file holds them >= 0: a fit below would be refused when it is written
        if hi < 0:
            raise FitError(f"bounds for {name}: the upper bound must be >= 0 (a parameter file holds {name} >= 0), "
                           f"got {hi:g}")
        lo = max(lo, 0.0)
    if name in ("vs", "delta") and not lo > 0:
        raise FitError(f"bounds for {name}: the lower bound must be > 0, got {lo:g}")
    return lo, hi


def _merge_bounds(defaults: dict, bounds: dict | None) -> dict[str, tuple[float, float]]:
    out = dict(defaults)
    for k, (lo, hi) in (bounds or {}).items():
        key = "dF" if k in ("Fs-Fc", "dF") else k
        if key not in out:
            continue  # a parameter of another stage of the fit
        out[key] = check_bound(k, lo, hi)
    return out


def prediction_and_jac(A: np.ndarray, v: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Prediction and its Jacobian for natural parameters p = [theta (m), dF, vs, delta]."""
    m = A.shape[1]
    theta, dF, vs, delta = p[:m], p[m], p[m + 1], p[m + 2]
    s, pw = stribeck_power(v, vs, delta)
    with np.errstate(divide="ignore", under="ignore", over="ignore", invalid="ignore"):
        ratio = np.abs(v) / vs
        lr = np.where(ratio > 0, np.log(np.where(ratio > 0, ratio, 1.0)), 0.0)
        d_vs = dF * s * pw * delta / vs
        d_delta = -dF * s * pw * lr
    pred = A @ theta + dF * s
    jac = np.column_stack([A, s, d_vs, d_delta])
    return pred, np.nan_to_num(jac)


def vp_start(y: np.ndarray, A: np.ndarray, v: np.ndarray, bnd: dict, n_vs: int = 24,
             deltas: Sequence[float] | None = None) -> tuple[np.ndarray, float]:
    """Variable-projection grid search over (vs, delta); returns (natural start p, its cost)."""
    vlo, vhi = bnd["vs"]
    dlo, dhi = bnd["delta"]
    vss = np.geomspace(vlo, vhi, n_vs)
    if deltas is None:
        deltas = np.linspace(dlo, dhi, 7) if dhi > dlo else np.array([dlo])
    Q, _ = np.linalg.qr(A, mode="reduced") if A.shape[1] else (np.zeros((y.size, 0)), None)
    rB = y - Q @ (Q.T @ y)
    base = float(rB @ rB)
    grid = [(a, d) for d in deltas for a in vss]
    C = stribeck_columns_at(v, np.array([a for a, _ in grid]), np.array([d for _, d in grid]))
    # projection of each candidate column off the fixed columns, without forming it:
    # c_B^T r_B = c^T r_B (r_B is orthogonal to Q), |c_B|^2 = |c|^2 - |Q^T c|^2
    num = C.T @ rB
    QtC = Q.T @ C
    den = np.einsum("ij,ij->j", C, C) - np.einsum("ij,ij->j", QtC, QtC)
    coef = np.where(den > 1e-12 * max(1.0, den.max()), num / np.where(den > 0, den, 1.0), 0.0)
    dlo_F, dhi_F = bnd["dF"]
    coef = np.clip(coef, dlo_F, dhi_F)
    cost = base - 2 * coef * num + coef ** 2 * den
    k = int(np.argmin(cost))
    vs0, d0 = grid[k]
    s = C[:, k]
    dF = float(coef[k])
    theta = np.linalg.lstsq(A, y - dF * s, rcond=None)[0] if A.shape[1] else np.zeros(0)
    p0 = np.r_[theta, dF, vs0, d0]
    pred, _ = prediction_and_jac(A, v, p0)
    return p0, 0.5 * float(np.sum((y - pred) ** 2))


def _clip_into(p: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    span = np.where(np.isfinite(hi - lo), hi - lo, 1.0)
    eps = 1e-6 * np.maximum(span, 1e-12)
    lo2 = np.where(np.isfinite(lo), lo + eps, lo)
    hi2 = np.where(np.isfinite(hi), hi - eps, hi)
    return np.minimum(np.maximum(p, np.minimum(lo2, hi2)), np.maximum(lo2, hi2))


@functools.lru_cache(maxsize=None)
def _numpy_function():
    """A CasADi Function class whose value (and Jacobian, when given) numpy computes."""
    import casadi as ca

    class NumpyFunction(ca.Callback):
        def __init__(self, name, sizes_in, sparsity_out, fn, jac=None):
            ca.Callback.__init__(self)
            self._sizes_in, self._sparsity_out, self._fn, self._jac = sizes_in, sparsity_out, fn, jac
            self._jac_fn = None  # kept alive as long as this function
            self.construct(name, {"enable_fd": False})

        def get_n_in(self):
            return len(self._sizes_in)

        def get_n_out(self):
            return len(self._sparsity_out)

        def get_sparsity_in(self, i):
            return ca.Sparsity.dense(*self._sizes_in[i])

        def get_sparsity_out(self, i):
            return self._sparsity_out[i]

        def has_jacobian(self):
            return self._jac is not None

        def get_jacobian(self, name, inames, onames, opts):
            n = self._sizes_in[0][0]
            self._jac_fn = NumpyFunction(name, [(n, 1), (1, 1)], [ca.Sparsity.dense(1, n)],
                                         lambda x, _: [self._jac(x).reshape(1, -1)])
            return self._jac_fn

        def eval(self, args):
            return self._fn(np.asarray(args[0], dtype=float).ravel(), *args[1:])

    return NumpyFunction


def _ipopt(y, A, v, p0, lo, hi, max_iter=300):
    """Refine all parameters from ``p0`` with IPOPT (CasADi's ``nlpsol``) under the bounds.

    The least-squares cost, its gradient and the Gauss-Newton Hessian J^T J come from the same
    numpy model as everywhere else (:func:`prediction_and_jac`) through CasADi callbacks, so no
    symbolic copy of the model is built per call.  The gradient is exact, so IPOPT's convergence
    test is on the true optimality conditions; J^T J is positive semidefinite.  Variables are
    scaled: linear parameters (and Fs - Fc) over their start magnitude, log vs, delta.
    """
    import casadi as ca

    m = A.shape[1]
    p = m + 3
    scale = np.ones(p)
    scale[: m + 1] = np.maximum(np.abs(p0[: m + 1]), 1e-3 * max(1.0, float(np.max(np.abs(p0[: m + 1]), initial=1.0))))

    def to_p(x):
        return np.r_[x[: m + 1] * scale[: m + 1], np.exp(x[m + 1]), x[m + 2]]

    def to_x(q):
        with np.errstate(divide="ignore"):
            return np.r_[q[: m + 1] / scale[: m + 1], np.log(q[m + 1]), q[m + 2]]

    last: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}

    def residual_jac(x):  # residual and d residual / d x, for the latest x (IPOPT asks several times)
        key = x.tobytes()
        if key not in last:
            pred, J = prediction_and_jac(A, v, to_p(x))
            last.clear()
            last[key] = (y - pred, -J * np.r_[scale[: m + 1], np.exp(x[m + 1]), 1.0])
        return last[key]

    x0 = to_x(np.asarray(p0, dtype=float))
    norm = max(float(residual_jac(x0)[0] @ residual_jac(x0)[0]), 1e-12)  # the cost starts near 0.5
    Fn = _numpy_function()
    f = Fn("f", [(p, 1)], [ca.Sparsity.dense(1, 1)],
           lambda x: [0.5 * float(residual_jac(x)[0] @ residual_jac(x)[0]) / norm],
           jac=lambda x: residual_jac(x)[1].T @ residual_jac(x)[0] / norm)
    hess = Fn("hess_lag", [(p, 1), (0, 1), (1, 1), (0, 1)], [ca.Sparsity.upper(p)],
              lambda x, _p, lam_f, _g: [float(lam_f) * np.triu(residual_jac(x)[1].T @ residual_jac(x)[1]) / norm])
    xs = ca.MX.sym("x", p)
    solver = ca.nlpsol("s", "ipopt", {"x": xs, "f": f(xs)},
                       {"ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes",
                        "ipopt.max_iter": max_iter, "ipopt.tol": 1e-8, "hess_lag": hess,
                        # the start is the variable-projection optimum, close to the solution:
                        # a small initial barrier parameter saves most of the iterations
                        "ipopt.mu_init": 1e-5})
    lbx, ubx = to_x(np.asarray(lo, dtype=float)), to_x(np.asarray(hi, dtype=float))
    t0 = _time.perf_counter()
    with interruptible_solve():  # Ctrl-C: KeyboardInterrupt, not "IPOPT failed to run"
        sol = solver(x0=x0, lbx=np.where(np.isfinite(lbx), lbx, -1e20), ubx=np.where(np.isfinite(ubx), ubx, 1e20))
    dt = _time.perf_counter() - t0
    st = solver.stats()
    out = to_p(np.asarray(sol["x"]).ravel())
    return out, str(st.get("return_status", "")), bool(st.get("success", False)), int(st.get("iter_count", 0)), dt


def solve_separable(y: np.ndarray, A: np.ndarray, v: np.ndarray, lin_names: Sequence[str],
                    bounds: dict | None = None, fixed: dict | None = None, where: str = "fit") -> SeparableResult:
    """Fit ``y ~ A theta + (Fs - Fc) sign(v) exp(-|v/vs|^delta)`` with bounds (VP start + IPOPT).

    Parameters
    ----------
    y : (n,) measured torque (or extracted friction), N·m.
    A : (n, m) linear regressor columns named ``lin_names``.
    v : (n,) velocity, rad/s (no zeros).
    bounds : {name: (lo, hi)} overriding :func:`default_bounds` (names: linear names, "dF" or
        "Fs-Fc", "vs", "delta").
    fixed : unused placeholder for fixed parameters (reserved).

    Raises
    ------
    FitError : no samples, non-finite data, or IPOPT failed (infeasible, error).  When IPOPT stops
        at its iteration limit (or cannot improve further) the best point is kept, never worse
        than the start, with ``converged = False``: the caller warns.
    """
    y = np.asarray(y, dtype=float)
    A = np.asarray(A, dtype=float).reshape(y.size, -1)
    v = np.asarray(v, dtype=float)
    lin_names = list(lin_names)
    names = [*lin_names, "dF", "vs", "delta"]
    p = len(names)
    if y.size < p + 2:
        raise FitError(f"{where}: {y.size} samples for {p} parameters; not enough data to fit")
    if not (np.all(np.isfinite(y)) and np.all(np.isfinite(A)) and np.all(np.isfinite(v))):
        raise FitError(f"{where}: non-finite values in the data to fit")
    bnd = _merge_bounds(default_bounds(y, v, lin_names), bounds)
    lo = np.array([bnd[k][0] for k in names])
    hi = np.array([bnd[k][1] for k in names])
    p0, c0 = vp_start(y, A, v, bnd)
    p0 = _clip_into(p0, lo, hi)
    c0 = 0.5 * float(np.sum((y - prediction_and_jac(A, v, p0)[0]) ** 2))
    try:
        ps, status, ok, iters, dt = _ipopt(y, A, v, p0, lo, hi)
    except RuntimeError as e:  # CasADi/IPOPT raised
        raise FitError(f"{where}: IPOPT failed to run: {str(e).splitlines()[0][:160]}") from None
    converged = ok and status in _OK_STATUS
    ps = np.minimum(np.maximum(ps, lo), hi)  # IPOPT relaxes its bounds slightly (bound_relax_factor)
    if not np.all(np.isfinite(ps)) or not (converged or status in _STOPPED_STATUS):
        raise FitError(f"{where}: IPOPT did not converge (return status '{status}'); no parameters written")
    pred, jac = prediction_and_jac(A, v, ps)
    res = y - pred
    cost = 0.5 * float(res @ res)
    if cost > c0 * (1 + 1e-9):  # never worse than the variable-projection start
        ps = p0
        pred, jac = prediction_and_jac(A, v, ps)
        res = y - pred
        cost = c0
    return SeparableResult(names, ps, res, jac, cost, status, p0, c0, iters, dt,
                           {"bounds": {k: list(bnd[k]) for k in names}}, converged)


def natural_uncertainty(sr: SeparableResult) -> tuple[dict[str, float], Uncertainty]:
    """Parameters with Fs in place of dF (= Fs - Fc), and their covariance."""
    u = covariance(sr.residual, sr.jac, sr.names, sr.values)
    names = ["Fs" if k == "dF" else k for k in sr.names]
    T = np.eye(len(names))
    vals = sr.values.copy()
    if "Fc" in sr.names:
        i, j = sr.names.index("dF"), sr.names.index("Fc")
        T[i, j] = 1.0
        vals = T @ sr.values
    return dict(zip(names, (float(x) for x in vals))), transform(u, names, vals, T)


# -- staged method (the paper's eqs. 2-5) -----------------------------------------------------
@dataclass
class FrictionPoints:
    """Friction extracted from paired constant-velocity moves, eqs. (2)-(4).

    v : (k,) speed, rad/s (> 0).   gamma_f : (k,) friction torque (Γ+ - Γ-)/2, N·m.
    q : (k,) position, rad.   gravity : (k,) (Γ+ + Γ-)/2 = Q(q), N·m.   pairs : moves paired.
    """

    v: np.ndarray
    gamma_f: np.ndarray
    q: np.ndarray
    gravity: np.ndarray
    pairs: int


def _segments(mask: np.ndarray) -> list[tuple[int, int]]:
    idx = np.flatnonzero(np.diff(np.r_[0, mask.astype(int), 0]))
    return [(int(a), int(b)) for a, b in zip(idx[::2], idx[1::2])]


def extract_friction(preps: Sequence[Any], min_samples: int = 5, speed_tol: float = 0.05) -> FrictionPoints:
    """Γf = (Γ+ - Γ-)/2 and Q = (Γ+ + Γ-)/2 at the same positions and speeds, eqs. (2)-(4).

    Constant-velocity segments (``Prepared.plateau``, one sign) are paired with a segment of the
    opposite direction whose mean speed is within ``speed_tol`` (relative) and whose position
    range overlaps; the opposite torque is interpolated at the positions of the first.

    Raises
    ------
    FitError : no pair of opposite constant-velocity moves at the same speed.
    """
    vs, gf, qs, gr = [], [], [], []
    pairs = 0
    for pr in preps:
        segs = []
        for a, b in _segments(pr.plateau):
            if b - a < min_samples:
                continue
            sgn = np.sign(pr.qd[a:b])
            if not np.all(sgn == sgn[0]):
                continue
            segs.append((a, b, float(sgn[0]), float(np.median(np.abs(pr.qd[a:b])))))
        pos = [s for s in segs if s[2] > 0]
        neg = [s for s in segs if s[2] < 0]
        used = set()
        for a, b, _, sp in pos:
            best = None
            for j, (c, d, _, sn) in enumerate(neg):
                if j in used or abs(sn - sp) > speed_tol * max(sp, sn):
                    continue
                qlo = max(pr.q[a:b].min(), pr.q[c:d].min())
                qhi = min(pr.q[a:b].max(), pr.q[c:d].max())
                if qhi <= qlo:
                    continue
                gap = abs(0.5 * (c + d) - 0.5 * (a + b))
                if best is None or gap < best[0]:
                    best = (gap, j, qlo, qhi)
            if best is None:
                continue
            _, j, qlo, qhi = best
            used.add(j)
            c, d = neg[j][0], neg[j][1]
            qp, tp, vp = pr.q[a:b], pr.tau[a:b], pr.qd[a:b]
            qn, tn, vn = pr.q[c:d], pr.tau[c:d], pr.qd[c:d]
            order = np.argsort(qn)
            sel = (qp >= qlo) & (qp <= qhi)
            if sel.sum() < min_samples:
                continue
            tn_at = np.interp(qp[sel], qn[order], tn[order])
            vn_at = np.interp(qp[sel], qn[order], np.abs(vn[order]))
            vs.append(0.5 * (np.abs(vp[sel]) + vn_at))
            gf.append(0.5 * (tp[sel] - tn_at))
            gr.append(0.5 * (tp[sel] + tn_at))
            qs.append(qp[sel])
            pairs += 1
    if not pairs:
        raise FitError("staged friction: no pair of opposite constant-velocity moves at the same speed "
                       "(the staged method needs sweep data; use the joint method for general trajectories)")
    return FrictionPoints(np.concatenate(vs), np.concatenate(gf), np.concatenate(qs), np.concatenate(gr), pairs)
