"""Band-limited Fourier excitation of a whole robot, optimised for the regressor's condition number.

Every joint follows a finite sum of ``harmonics`` harmonics of the base frequency ``wf = 2π/period``
(Swevers et al. 1997), written so that it starts and ends each period at rest::

    d_i(t)   = Σ_l  a_il/(l wf) sin(l wf t) + b_il/(l wf) (1 - cos(l wf t))
    qd_i(t)  = Σ_l  a_il cos(l wf t) + b_il sin(l wf t)          with Σ_l a_il = 0    (qd = 0 at t = 0, T)
    qdd_i(t) = Σ_l  l wf (b_il cos(l wf t) - a_il sin(l wf t))   with Σ_l l b_il = 0  (qdd = 0 at t = 0, T)
    q_i(t)   = c_i + s_i (d_i(t) - m_i)

``c_i`` is the centre of the joint's range, ``m_i`` the centre of ``d_i``'s swing and ``s_i`` the
largest scale that keeps position, velocity and acceleration within ``margin`` of the joint's
limits, so every candidate is feasible and the optimiser (scipy L-BFGS-B) only trades the
coefficients for a smaller condition number of the *base* regressor: Pinocchio's joint-torque
regressor (``computeJointTorqueRegressor``) on the columns a numerical QR finds independent,
plus per-joint Coulomb, viscous, offset and rotor-inertia columns, stacked over one period.

The trajectory is sampled at the KR C4's IPO rate (12 ms), repeated ``periods`` times, checked
against the limits (:class:`kukaid.models.limits.AxisLimits` per axis) and refused with one
line naming the axis, the limit and the time when a limit is broken.  Everything is SI.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from kukaid import __version__
from kukaid.atomic import write_text_atomic
from kukaid.errors import LimitError, TrajectoryError
from kukaid.excite.trajectory import IPO_DT, MAX_DURATION, SCHEMA, Trajectory
from kukaid.jsonfile import read_json
from kukaid.models.limits import AxisLimits
from kukaid.models.urdf import load_model

ROBOT_SCHEMA = "kukaid.robot-trajectory/1"
#: acceleration limit assumed when neither the URDF nor the user gives one, rad/s²
DEFAULT_QDD_MAX = 10.0
_DEG = math.pi / 180.0


# ---------------------------------------------------------------------------------------------
# Trajectory of several axes
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class RobotTrajectory:
    """Commanded positions of several axes at the IPO rate.

    Parameters
    ----------
    t : (N,) s, uniformly spaced.   q : (N, A) rad.   axes : the A axis numbers (KUKA numbering).
    kind : experiment kind ("fourier").   params : the experiment's parameters (JSON-able, SI).
    limits : per axis, the limits the trajectory was checked against (``AxisLimits.to_dict``).
    robot : the robot (bundled name or URDF path) it was designed for.
    """

    t: np.ndarray
    q: np.ndarray
    axes: tuple[int, ...]
    kind: str = "fourier"
    params: dict[str, Any] = field(default_factory=dict)
    limits: list[dict[str, Any]] | None = None
    robot: str = ""

    def __post_init__(self) -> None:
        t = np.asarray(self.t, dtype=float)
        q = np.asarray(self.q, dtype=float)
        axes = tuple(int(a) for a in self.axes)
        if q.ndim != 2 or q.shape[1] != len(axes):
            raise TrajectoryError(f"trajectory: 'q' must have one column per axis ({len(axes)}), got shape {q.shape}")
        if len(set(axes)) != len(axes) or not all(1 <= a <= 12 for a in axes):
            raise TrajectoryError(f"trajectory: axes must be distinct numbers 1 to 12, got {list(axes)}")
        for j in range(q.shape[1]):  # the one-axis checks (finite, uniform time, duration) per column
            Trajectory(t=t, q=q[:, j], axis=axes[j])
        if self.limits is not None and len(self.limits) != len(axes):
            raise TrajectoryError(f"trajectory: 'limits' must have one entry per axis ({len(axes)})")
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "q", q)
        object.__setattr__(self, "axes", axes)

    @property
    def dt(self) -> float:
        return float(self.t[1] - self.t[0])

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0])

    @property
    def n_samples(self) -> int:
        return int(self.t.size)

    def column(self, axis: int) -> Trajectory:
        """The one-axis :class:`Trajectory` of ``axis``."""
        j = self.axes.index(int(axis))
        lim = self.limits[j] if self.limits else None
        return Trajectory(t=self.t, q=self.q[:, j], axis=int(axis), kind=self.kind, params=self.params, limits=lim)

    def axis_limits(self) -> list[AxisLimits]:
        """The stored limits of every axis as :class:`AxisLimits`."""
        if not self.limits:
            raise TrajectoryError("trajectory: no limits stored")
        return [AxisLimits.from_dict(d, where=f"trajectory: limits of A{a}") for a, d in zip(self.axes, self.limits)]

    def check(self, limits: Sequence[AxisLimits] | None = None) -> None:
        """Raise :class:`LimitError` (one line: axis, limit, value, time) if an axis breaks its limit."""
        limits = list(limits) if limits is not None else self.axis_limits()
        for a, lim in zip(self.axes, limits):
            v = lim.violations(self.column(a))
            if v:
                more = f" (and {len(v) - 1} more limit(s))" if len(v) > 1 else ""
                raise LimitError(v[0] + more)

    def to_dict(self) -> dict[str, Any]:
        return {
            "schema": ROBOT_SCHEMA, "kind": self.kind, "robot": self.robot, "axes": list(self.axes),
            "sample_time": self.dt, "duration": self.duration, "units": {"t": "s", "q": "rad"},
            "params": self.params, "limits": self.limits, "kukaid_version": __version__,
            "t": [float(x) for x in self.t], "q": [[float(x) for x in row] for row in self.q],
        }

    def json_text(self) -> str:
        return json.dumps(self.to_dict(), indent=None, allow_nan=False) + "\n"

    def to_json(self, path: str | Path) -> None:
        write_text_atomic(path, self.json_text())

    @classmethod
    def from_dict(cls, d: Any, where: str = "trajectory") -> "RobotTrajectory":
        if not isinstance(d, dict) or d.get("schema") != ROBOT_SCHEMA:
            raise TrajectoryError(f"{where}: field 'schema' must be \"{ROBOT_SCHEMA}\"")
        try:
            axes = tuple(int(a) for a in d["axes"])
            t = np.asarray(d["t"], dtype=float)
            q = np.asarray(d["q"], dtype=float)
        except KeyError as e:
            raise TrajectoryError(f"{where}: missing field {e}") from None
        except (TypeError, ValueError):
            raise TrajectoryError(f"{where}: fields 't', 'q' and 'axes' must be numbers (q: one row of "
                                  f"numbers per sample)") from None
        units = d.get("units", {"t": "s", "q": "rad"})
        if not isinstance(units, dict) or units.get("t", "s") != "s" or units.get("q", "rad") != "rad":
            raise TrajectoryError(f"{where}: field 'units' must be {{\"t\": \"s\", \"q\": \"rad\"}}")
        limits = d.get("limits")
        try:
            traj = cls(t=t, q=q, axes=axes, kind=str(d.get("kind", "custom")), params=dict(d.get("params") or {}),
                       limits=limits, robot=str(d.get("robot", "")))
            if limits is not None:
                traj.axis_limits()
        except TrajectoryError as e:
            raise TrajectoryError(f"{where}: {str(e).split(': ', 1)[-1]}") from None
        return traj

    @classmethod
    def from_json(cls, path: str | Path) -> "RobotTrajectory":
        return cls.from_dict(read_json(path, TrajectoryError), where=str(path))


def load_trajectory(path: str | Path) -> Trajectory | RobotTrajectory:
    """A trajectory file of one axis (``kukaid.trajectory/1``) or of several (``kukaid.robot-trajectory/1``)."""
    d = read_json(path, TrajectoryError)
    if isinstance(d, dict) and d.get("schema") == ROBOT_SCHEMA:
        return RobotTrajectory.from_dict(d, where=str(path))
    if isinstance(d, dict) and d.get("schema") not in (SCHEMA, ROBOT_SCHEMA):
        raise TrajectoryError(f"{path}: field 'schema' must be \"{SCHEMA}\" or \"{ROBOT_SCHEMA}\", "
                              f"got {d.get('schema')!r}")
    return Trajectory.from_dict(d, where=str(path))


# ---------------------------------------------------------------------------------------------
# Limits of a robot
# ---------------------------------------------------------------------------------------------
def robot_limits(model, qdd_max: float | Sequence[float] | None = None, robot: str = "") -> list[AxisLimits]:
    """Per-axis limits from the URDF (position, velocity); acceleration ``qdd_max`` (rad/s²,
    default :data:`DEFAULT_QDD_MAX`, an assumption the data sheets do not give)."""
    n = model.nv
    lo, hi = np.asarray(model.lowerPositionLimit, float), np.asarray(model.upperPositionLimit, float)
    vmax = np.asarray(model.velocityLimit, float)
    acc = np.broadcast_to(np.asarray(DEFAULT_QDD_MAX if qdd_max is None else qdd_max, float), (n,))
    out = []
    for i in range(n):
        if not (np.isfinite(lo[i]) and np.isfinite(hi[i]) and lo[i] < hi[i] and np.isfinite(vmax[i]) and vmax[i] > 0):
            raise TrajectoryError(f"{robot or 'robot'}: joint {i + 1} has no finite position/velocity limits in the "
                                  f"URDF; give them with --limits")
        out.append(AxisLimits(q_min=lo[i], q_max=hi[i], qd_max=vmax[i], qdd_max=float(acc[i]), name=f"A{i + 1}"))
    return out


# ---------------------------------------------------------------------------------------------
# The Fourier series
# ---------------------------------------------------------------------------------------------
def _project(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Coefficients (A, L) satisfying Σ_l a_l = 0 and Σ_l l b_l = 0 (rest at the period's ends)."""
    ell = np.arange(1, a.shape[1] + 1)
    a = a - a.mean(axis=1, keepdims=True)
    b = b - np.outer(b @ ell, ell) / (ell @ ell)
    return a, b


def fourier_series(t: np.ndarray, a: np.ndarray, b: np.ndarray, wf: float):
    """(d, qd, qdd), each (N, A), of the series with coefficients ``a, b`` (A, L) at times ``t`` (s)."""
    ell = np.arange(1, a.shape[1] + 1) * wf  # (L,)
    ph = np.outer(t, ell)  # (N, L)
    s, c = np.sin(ph), np.cos(ph)
    d = (s / ell) @ a.T + ((1 - c) / ell) @ b.T
    qd = c @ a.T + s @ b.T
    qdd = (c * ell) @ b.T - (s * ell) @ a.T
    return d, qd, qdd


def _fit_to_limits(d, qd, qdd, limits: Sequence[AxisLimits], margin: float, span: np.ndarray,
                   centre: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-axis scale ``s`` and offset so that ``c + s (d - m)`` stays within ``margin`` of every limit."""
    lo, hi = d.min(0), d.max(0)
    m = 0.5 * (lo + hi)
    half = np.maximum(0.5 * (hi - lo), 1e-12)
    room = np.array([min(centre[i] - L.q_min, L.q_max - centre[i]) for i, L in enumerate(limits)]) * span
    vmax = np.array([L.qd_max for L in limits]) * margin
    amax = np.array([L.qdd_max for L in limits]) * margin
    s = np.minimum.reduce([room / half, vmax / np.maximum(np.abs(qd).max(0), 1e-12),
                           amax / np.maximum(np.abs(qdd).max(0), 1e-12)])
    return s, m


class RegressorCondition:
    """Condition number of the base regressor of a robot along a trajectory.

    Columns: Pinocchio's joint-torque regressor (10 inertial parameters per link) and per joint a
    rotor inertia (qdd), Coulomb (sign qd), viscous (qd) and offset (1) column; the base columns
    are those a pivoted QR of the stacked regressor at random states finds independent.
    """

    def __init__(self, model, seed: int = 0, n_random: int = 60) -> None:
        import pinocchio as pin
        from scipy.linalg import qr

        self.model, self.data, self._pin = model, model.createData(), pin
        rng = np.random.default_rng(seed)
        lo = np.where(np.isfinite(model.lowerPositionLimit), model.lowerPositionLimit, -math.pi)
        hi = np.where(np.isfinite(model.upperPositionLimit), model.upperPositionLimit, math.pi)
        n = model.nv
        Q = rng.uniform(lo, hi, (n_random, n))
        W = self.regressor(Q, rng.normal(0, 1, (n_random, n)), rng.normal(0, 3, (n_random, n)))
        _, R, P = qr(W, mode="economic", pivoting=True)
        d = np.abs(np.diag(R))
        rank = int(np.sum(d > d[0] * 1e-8 * max(W.shape)))
        self.base = np.sort(P[:rank])

    def regressor(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
        """The full stacked regressor (N n, 10 n + 4 n) at states (N, n)."""
        pin, m, d = self._pin, self.model, self.data
        N, n = q.shape
        Y = np.empty((N, n, 10 * n))
        for k in range(N):
            Y[k] = pin.computeJointTorqueRegressor(m, d, q[k], qd[k], qdd[k])
        eye = np.eye(n)
        extra = np.concatenate([qdd[:, :, None] * eye, np.sign(qd)[:, :, None] * eye, qd[:, :, None] * eye,
                                np.broadcast_to(eye, (N, n, n))], axis=2)
        return np.concatenate([Y, extra], axis=2).reshape(N * n, -1)

    def __call__(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> float:
        from scipy.linalg import eigvalsh

        W = self.regressor(q, qd, qdd)[:, self.base]
        # singular values from the small Gram matrix (einsum: no threaded BLAS, which thrashes on a
        # busy machine); cond(W) = sqrt(cond(WᵀW)), exact enough below 1e7
        ev = eigvalsh(np.einsum("ij,ik->jk", W, W))
        return float(math.sqrt(ev[-1] / ev[0])) if ev[0] > 0 else math.inf


@dataclass(frozen=True)
class FourierDesign:
    """The optimised series: coefficients ``a, b`` (A, L) rad/s, base pulsation ``wf`` rad/s,
    per-axis scale and offsets (``q = centre + scale (d - mid)``), condition number ``cond``."""

    a: np.ndarray
    b: np.ndarray
    wf: float
    scale: np.ndarray
    mid: np.ndarray
    centre: np.ndarray
    cond: float

    def evaluate(self, t: np.ndarray):
        """(q, qd, qdd) at times ``t``, (N, A), SI."""
        d, qd, qdd = fourier_series(t, self.a, self.b, self.wf)
        return self.centre + self.scale * (d - self.mid), self.scale * qd, self.scale * qdd


#: the objective of :func:`design` (the log of the condition number) for a singular regressor
SINGULAR = 1e3


def design(model, limits: Sequence[AxisLimits], harmonics: int = 5, period: float = 10.0, margin: float = 0.9,
           span: float = 0.6, centre: np.ndarray | None = None, seed: int = 0, iterations: int = 10,
           n_eval: int = 100, starts: int = 16, progress: Callable[[float], None] | None = None) -> FourierDesign:
    """Coefficients minimising the base regressor's condition number within the limits.

    Parameters
    ----------
    model : Pinocchio model (nominal inertials are not used: only the regressor's structure).
    limits : per-axis :class:`AxisLimits`.
    harmonics : harmonics per joint.   period : s, the base period (band limit: harmonics / period Hz).
    margin : fraction of the velocity and acceleration limits used.
    span : fraction of each joint's range (around ``centre``) the motion may use.
    centre : (A,) rad, centre of the motion (default: middle of each range).
    seed : seed of the random starts.   iterations : L-BFGS-B iterations.   n_eval : states per period
    in the condition number.   starts : random starts; the best one is optimised.
    progress : called with the fraction done (0..1, from the evaluations of the condition number).
    """
    from scipy.optimize import minimize

    n, L = model.nv, int(harmonics)
    cen = np.array([0.5 * (lim.q_min + lim.q_max) for lim in limits]) if centre is None else np.asarray(centre, float)
    for i, lim in enumerate(limits):
        if not lim.q_min < cen[i] < lim.q_max:
            raise LimitError(f"trajectory breaks the position limit of {lim.name}: centre {cen[i] / _DEG:.4g} deg is "
                             f"outside {lim.q_min / _DEG:.4g} .. {lim.q_max / _DEG:.4g} deg")
    wf = 2 * math.pi / period
    cond = RegressorCondition(model, seed=seed)
    te = np.linspace(0, period, n_eval, endpoint=False)
    td = np.arange(0, period, IPO_DT / 2)  # dense: the limit scaling
    spanv = np.full(n, float(span))

    def unpack(x):
        a, b = _project(x[:n * L].reshape(n, L), x[n * L:].reshape(n, L))
        return a, b

    def scaled(x):
        a, b = unpack(x)
        s, m = _fit_to_limits(*fourier_series(td, a, b, wf), limits, margin, spanv, cen)
        return a, b, s, m

    # evaluations: the starts, then per L-BFGS-B iteration a gradient by differences (2 n L) and a step
    expected, done = max(1, starts) + int(iterations) * (2 * n * L + 2), [0]

    def objective(x):
        done[0] += 1
        if progress is not None:
            progress(min(1.0, done[0] / expected))
        a, b, s, m = scaled(x)
        d, qd, qdd = fourier_series(te, a, b, wf)
        c = cond(cen + s * (d - m), s * qd, s * qdd)
        return math.log(c) if math.isfinite(c) else SINGULAR

    rng = np.random.default_rng(seed)
    decay = np.tile(1.0 / np.arange(1, L + 1), 2 * n)  # favour low harmonics at the start
    x0s = [rng.normal(0, 1, 2 * n * L) * decay for _ in range(max(1, starts))]
    f0 = [objective(x) for x in x0s]
    x0 = x0s[int(np.argmin(f0))]
    x, fx = x0, min(f0)
    if iterations > 0:
        res = minimize(objective, x0, method="L-BFGS-B", options={"maxiter": int(iterations), "eps": 1e-4})
        if res.fun < fx:
            x, fx = res.x, float(res.fun)
    if not fx < SINGULAR:  # every start and step left a base parameter unexcited (exp(1e3) overflowed: exit 70)
        raise TrajectoryError(f"fourier: with {L} harmonic(s) no motion found excites every base parameter of the "
                              "robot (the regressor is singular at every start and step); give more harmonics "
                              "(--harmonics 2 or more)")
    a, b, s, m = scaled(x)
    if progress is not None:
        progress(1.0)
    return FourierDesign(a=a, b=b, wf=wf, scale=s, mid=m, centre=cen, cond=float(math.exp(fx)))


def fourier(robot: str = "kr6-r700-sixx", harmonics: int = 5, period: float = 10.0, periods: int = 3,
            margin: float = 0.9, span: float = 0.6, centre: Sequence[float] | None = None,
            limits: Sequence[AxisLimits] | None = None, qdd_max: float | None = None, seed: int = 0,
            iterations: int = 10, starts: int = 16, dt: float = IPO_DT, model: Any = None,
            progress: Callable[[float], None] | None = None) -> RobotTrajectory:
    """An optimised Fourier excitation of every axis of ``robot`` (bundled name or URDF path).

    See :func:`design` for the parameters; ``periods`` repeats the period (averaging noise);
    ``limits`` overrides the URDF's (per axis), ``qdd_max`` the assumed acceleration limit.
    Raises :class:`LimitError` (one line) when the result breaks a limit.
    """
    if not (isinstance(harmonics, int) and 1 <= harmonics <= 20):
        raise TrajectoryError(f"fourier: harmonics must be 1 to 20, got {harmonics!r}")
    for name, v, lo, hi in (("period", period, 1.0, 600.0), ("margin", margin, 0.05, 1.0), ("span", span, 0.01, 1.0)):
        if not (isinstance(v, (int, float)) and lo <= v <= hi):
            raise TrajectoryError(f"fourier: {name} must be {lo:g} to {hi:g}, got {v!r}")
    if not (isinstance(iterations, int) and 0 <= iterations <= 10_000 and isinstance(starts, int) and 1 <= starts <= 1000):
        raise TrajectoryError(f"fourier: iterations must be 0 to 10000 and starts 1 to 1000, got {iterations!r}, {starts!r}")
    if not (isinstance(periods, int) and periods >= 1) or periods * period > MAX_DURATION:
        raise TrajectoryError(f"fourier: periods must be a whole number >= 1 (total at most 24 h), got {periods!r}")
    model = model if model is not None else load_model(robot)
    lims = list(limits) if limits is not None else robot_limits(model, qdd_max, robot=str(robot))
    if len(lims) != model.nv:
        raise TrajectoryError(f"fourier: {len(lims)} axis limits for a robot of {model.nv} axes")
    cen = None if centre is None else np.asarray(centre, dtype=float)
    if cen is not None and cen.shape != (model.nv,):
        raise TrajectoryError(f"fourier: give one centre per axis ({model.nv}), got {len(cen)}")
    n_per = int(round(period / dt))
    period = n_per * dt  # a whole number of IPO cycles: the repeated periods join exactly
    des = design(model, lims, harmonics=harmonics, period=period, margin=margin, span=span, centre=cen, seed=seed,
                 iterations=iterations, starts=starts, progress=progress)
    t = np.arange(n_per * periods + 1) * dt
    q, _, _ = des.evaluate(t % period)
    params = {"robot": str(robot), "harmonics": harmonics, "period": period, "periods": periods, "margin": margin,
              "span": span, "seed": seed, "wf": des.wf, "a": des.a.tolist(), "b": des.b.tolist(),
              "scale": des.scale.tolist(), "mid": des.mid.tolist(), "centre": des.centre.tolist(), "cond": des.cond}
    traj = RobotTrajectory(t=t, q=q, axes=tuple(range(1, model.nv + 1)), kind="fourier", params=params,
                           limits=[lim.to_dict() for lim in lims], robot=str(robot))
    traj.check(lims)
    return traj
