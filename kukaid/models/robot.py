"""The robot model from a URDF (Pinocchio): joint-torque regressor, base parameters, per-joint
friction and offset, and the drive side (gear ratios, rotor inertia, coupled wrist).

The rigid-body torque is linear in the links' inertial parameters, ``tau = Y(q, qd, qdd) pi``,
with ``pi`` ten numbers per link in Pinocchio's order ``[m, m cx, m cy, m cz, Ixx, Ixy, Iyy, Ixz,
Iyz, Izz]`` (first moments and inertia at the joint frame, kg, kg·m, kg·m²). Only some
combinations of ``pi`` move the joints: the *base parameters* ``beta = K pi``, found here by a QR
decomposition with column pivoting of the regressor at random states (numerical, as Gautier 1990).

As in Pinocchio, the model is built once (:class:`RobotModel`) and every computation makes its own
``pinocchio.Data``, so models can be shared across threads.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from kukaid.models.urdf import gear_ratios, load_model, robot_urdf, urdf_sha256

#: names of the ten inertial parameters of a link, Pinocchio's order
LINK_PARAMS = ("m", "mx", "my", "mz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")
FRICTION_MODELS = ("coulomb-viscous", "stribeck")


@dataclass(frozen=True)
class DriveModel:
    """The drive side: motor angles ``theta = G q`` with ``G = diag(ratio) (I + coupling)``.

    ratio : (n,) gear ratios, motor turns per joint turn (1 = torque given on the joint side).
    coupling : (n, n) strictly lower-triangular coupling of the joints' motions into the motors
        (a KUKA wrist: the A5 and A6 motors also turn when A4 turns), dimensionless.
    rotor_inertia : (n,) motor rotor (plus gear input) inertia, kg·m², motor side.

    Power balance gives the joint torque of the motor torques, ``tau_joint = G^T tau_motor``,
    and rotors add ``G^T diag(rotor_inertia) G qdd`` to the link-side torque.
    """

    ratio: np.ndarray
    coupling: np.ndarray
    rotor_inertia: np.ndarray

    @classmethod
    def direct(cls, n: int) -> "DriveModel":
        """Torques measured on the joint side: no gear, no coupling, no rotor."""
        return cls(np.ones(n), np.zeros((n, n)), np.zeros(n))

    @property
    def G(self) -> np.ndarray:
        return np.diag(np.asarray(self.ratio, float)) @ (np.eye(len(self.ratio)) + np.asarray(self.coupling, float))

    def joint_torque(self, tau_motor: np.ndarray) -> np.ndarray:
        """Joint-side torques (N, n) from motor-side torques (N, n), N·m."""
        return np.asarray(tau_motor, float) @ self.G

    def motor_torque(self, tau_joint: np.ndarray) -> np.ndarray:
        """Motor-side torques (N, n) from joint-side torques (N, n), N·m."""
        return np.linalg.solve(self.G.T, np.asarray(tau_joint, float).T).T

    def rotor_regressor(self, qdd: np.ndarray) -> np.ndarray:
        """(N, n, n) joint-side torque per unit rotor inertia of each motor, ``G^T e_k e_k^T G qdd``."""
        G = self.G
        th = np.asarray(qdd, float) @ G.T                 # motor accelerations (N, n)
        return th[:, None, :] * G.T[None, :, :]           # [s, j, k] = G[k, j] * thdd[s, k]


@dataclass(frozen=True)
class BaseParameters:
    """Base parameters ``beta = pi[independent] + R pi[dependent]`` (numerical QR).

    independent : indices of the standard parameters kept (columns of the regressor).
    dependent : indices of the others.
    R : (len(independent), len(dependent)) matrix regrouping the dependent ones.
    names : one readable name per base parameter, e.g. ``link3.Izz + 0.1 link4.m``.
    """

    independent: np.ndarray
    dependent: np.ndarray
    R: np.ndarray
    names: tuple[str, ...]

    @property
    def size(self) -> int:
        return int(self.independent.size)

    def K(self, n_std: int) -> np.ndarray:
        """(b, n_std) matrix with ``beta = K pi``."""
        K = np.zeros((self.size, n_std))
        K[np.arange(self.size), self.independent] = 1.0
        K[:, self.dependent] = self.R
        return K

    def of(self, pi: np.ndarray) -> np.ndarray:
        """Base parameters of the standard parameters ``pi``."""
        pi = np.asarray(pi, float)
        return pi[self.independent] + self.R @ pi[self.dependent]


class RobotModel:
    """A serial robot from its URDF: kinematics and nominal inertial parameters (Pinocchio).

    Parameters
    ----------
    urdf : path of the URDF, or a bundled name (see :data:`kukaid.models.urdf.BUNDLED`).

    Attributes
    ----------
    n : number of actuated joints (axes A1..An in the URDF's order).
    joint_names, link_names : names from the URDF.
    pi_nominal : (10 n,) the URDF's inertial parameters (the nominal values).
    ratio : (n,) gear ratios from the URDF's transmissions (1 where none).
    lower, upper, velocity, effort : (n,) joint limits, rad, rad/s, N·m.
    """

    def __init__(self, urdf: str | Path):
        self.path = robot_urdf(urdf)
        self.source = str(urdf)
        self.sha256 = urdf_sha256(self.path)
        self.model = load_model(self.path)
        m = self.model
        self.n = int(m.nv)
        self.joint_names = tuple(m.names[1:])
        self.link_names = tuple(self._child_links())
        self.pi_nominal = np.concatenate([m.inertias[j].toDynamicParameters() for j in range(1, m.njoints)])
        self.lower = np.asarray(m.lowerPositionLimit, float)
        self.upper = np.asarray(m.upperPositionLimit, float)
        self.velocity = np.asarray(m.velocityLimit, float)
        self.effort = np.asarray(m.effortLimit, float)
        self.ratio = gear_ratios(self.path, self.joint_names)
        self._base: BaseParameters | None = None

    # -- URDF extras ----------------------------------------------------------------------------
    def _child_links(self) -> list[str]:
        import pinocchio as pin

        m = self.model
        out = []
        for j in range(1, m.njoints):
            names = [f.name for f in m.frames if f.parentJoint == j and f.type == pin.FrameType.BODY]
            out.append(names[0] if names else m.names[j])
        return out

    @property
    def n_std(self) -> int:
        return 10 * self.n

    @property
    def std_names(self) -> tuple[str, ...]:
        return tuple(f"{link}.{p}" for link in self.link_names for p in LINK_PARAMS)

    # -- dynamics -------------------------------------------------------------------------------
    def regressor(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
        """Joint-torque regressor, (N, n, 10 n): ``tau[s] = Y[s] @ pi`` (N·m per parameter unit)."""
        import pinocchio as pin

        q, qd, qdd = (np.atleast_2d(np.asarray(x, float)) for x in (q, qd, qdd))
        data = self.model.createData()
        Y = np.empty((q.shape[0], self.n, self.n_std))
        f = pin.computeJointTorqueRegressor
        for s in range(q.shape[0]):
            Y[s] = f(self.model, data, q[s], qd[s], qdd[s])
        return Y

    def rnea(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, pi: np.ndarray | None = None) -> np.ndarray:
        """Rigid-body joint torques (N, n), N·m, for standard parameters ``pi`` (default nominal)."""
        import pinocchio as pin

        model = self.model if pi is None else self.with_parameters(pi)
        data = model.createData()
        q, qd, qdd = (np.atleast_2d(np.asarray(x, float)) for x in (q, qd, qdd))
        return np.array([pin.rnea(model, data, q[s], qd[s], qdd[s]) for s in range(q.shape[0])])

    def with_parameters(self, pi: np.ndarray):
        """A copy of the Pinocchio model with the standard parameters ``pi`` (physically consistent)."""
        import pinocchio as pin

        m = self.model.copy()
        pi = np.asarray(pi, float)
        for j in range(1, m.njoints):
            m.inertias[j] = pin.Inertia.FromDynamicParameters(pi[10 * (j - 1): 10 * j])
        return m

    # -- base parameters ------------------------------------------------------------------------
    def base_parameters(self, samples: int = 400, seed: int = 0, rtol: float = 1e-8) -> BaseParameters:
        """Base parameters by QR with column pivoting of the regressor at random states (cached).

        The states are uniform within the joint limits (±π where none), velocities and
        accelerations standard normal: generic enough that every combination the dynamics can
        show is excited. A column is dependent when its |R_ii| is below ``rtol`` times the largest.
        """
        if self._base is not None:
            return self._base
        from scipy.linalg import qr, solve_triangular

        rng = np.random.default_rng(seed)
        lo = np.where(np.isfinite(self.lower) & (self.lower > -1e10), self.lower, -np.pi)
        hi = np.where(np.isfinite(self.upper) & (self.upper < 1e10), self.upper, np.pi)
        q = rng.uniform(lo, hi, (samples, self.n))
        Y = self.regressor(q, rng.standard_normal((samples, self.n)), rng.standard_normal((samples, self.n)))
        W = Y.reshape(-1, self.n_std)
        _, Rq, piv = qr(W, mode="economic", pivoting=True)
        d = np.abs(np.diag(Rq))
        r = int(np.sum(d > rtol * d[0]))
        ind, dep = np.sort(piv[:r]), piv[r:]
        order = np.argsort(piv[:r])
        R1 = Rq[:r, :r]
        R2 = Rq[:r, r:]
        Rb = solve_triangular(R1, R2)[order]              # rows in the order of `ind`
        Rb[np.abs(Rb) < 1e-10] = 0.0
        names = self.std_names
        labels = []
        for i, k in enumerate(ind):
            terms = [names[k]] + [f"{'+' if c > 0 else '-'} {abs(c):.4g} {names[dep[j]]}"
                                  for j, c in enumerate(Rb[i]) if c != 0.0]
            labels.append(" ".join(terms))
        self._base = BaseParameters(ind, np.asarray(dep), Rb, tuple(labels))
        return self._base


def friction_regressor(qd: np.ndarray, model: str = "coulomb-viscous", offset: bool = True,
                       vs: np.ndarray | None = None, delta: float = 2.0, v_smooth=0.0,
                       qd_range: np.ndarray | None = None, deadband=0.0) -> np.ndarray:
    """Per-joint friction and offset columns, (N, n, n f): joint j's torque has its own columns.

    Coulomb-viscous: ``sign(qd)`` (``tanh(qd / v_smooth)`` where ``v_smooth > 0``; a number or one
    per joint, rad/s), ``qd``; Stribeck
    adds ``sign(qd) exp(-|qd/vs|^delta)`` (the static-minus-Coulomb part, ``vs`` per joint fixed);
    the offset is a constant column. Order per joint: Fc, Fv, [Fs-Fc], [offset]. ``qd_range``
    (n, 2): the viscous column's velocity held within [low, high] per joint (the velocities a fit saw).
    ``deadband`` (rad/s, a number or one per joint): the Coulomb column is 0 for speeds below it.
    """
    qd = np.atleast_2d(np.asarray(qd, float))
    N, n = qd.shape
    sgn = smooth_sign(qd, v_smooth, deadband)
    cols = [sgn, qd if qd_range is None else np.clip(qd, np.asarray(qd_range, float)[:, 0], np.asarray(qd_range, float)[:, 1])]
    if model == "stribeck":
        vs = np.broadcast_to(np.asarray(vs if vs is not None else 0.05, float), (n,))
        cols.append(sgn * np.exp(-np.abs(qd / vs) ** delta))
    if offset:
        cols.append(np.ones_like(qd))
    nf = len(cols)
    F = np.zeros((N, n, n * nf))
    for j in range(n):
        for c, col in enumerate(cols):
            F[:, j, j * nf + c] = col[:, j]
    return F


def smooth_sign(qd: np.ndarray, v_smooth=0.0, deadband=0.0) -> np.ndarray:
    """``tanh(x / v_smooth)`` per joint (``sign(x)`` where ``v_smooth`` is 0) of the velocity with a
    dead-band, ``x = sign(qd) max(|qd| - deadband, 0)``: 0 at speeds within the dead-band (a joint at
    rest, its velocity noise). ``v_smooth``, ``deadband``: numbers or one per joint (the last axis of
    ``qd``), rad/s."""
    qd = np.asarray(qd, float)
    d = np.broadcast_to(np.asarray(0.0 if deadband is None else deadband, float), qd.shape[-1:])
    if np.any(d > 0):
        qd = np.sign(qd) * np.maximum(np.abs(qd) - d, 0.0)
    v = np.broadcast_to(np.asarray(0.0 if v_smooth is None else v_smooth, float), qd.shape[-1:])
    if not np.any(v > 0):
        return np.sign(qd)
    return np.where(v > 0, np.tanh(qd / np.where(v > 0, v, 1.0)), np.sign(qd))


def friction_names(n: int, model: str = "coulomb-viscous", offset: bool = True) -> list[str]:
    """Parameter names of :func:`friction_regressor`'s columns, ``A1.Fc`` ..."""
    per = ["Fc", "Fv"] + (["Fs-Fc"] if model == "stribeck" else []) + (["offset"] if offset else [])
    return [f"A{j + 1}.{p}" for j in range(n) for p in per]


def pseudo_inertia(pi10: np.ndarray) -> np.ndarray:
    """The 4x4 pseudo-inertia matrix of one link's ten parameters; positive definite exactly when
    the link is physically consistent (a positive mass whose inertia is that of a real density:
    this implies the triangle inequalities)."""
    m, mx, my, mz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz = np.asarray(pi10, float)
    I = np.array([[Ixx, Ixy, Ixz], [Ixy, Iyy, Iyz], [Ixz, Iyz, Izz]])
    S = 0.5 * np.trace(I) * np.eye(3) - I
    h = np.array([mx, my, mz])
    return np.block([[S, h[:, None]], [h[None, :], np.array([[m]])]])


def consistency(pi: np.ndarray, tol: float = 0.0) -> list[dict]:
    """Per link: mass, triangle inequalities of the inertia at the centre of mass, smallest
    eigenvalue of the pseudo-inertia; ``ok`` when the mass is positive and the triangle
    inequalities hold (within ``tol``, kg·m²)."""
    pi = np.asarray(pi, float)
    out = []
    for k in range(pi.size // 10):
        p = pi[10 * k: 10 * k + 10]
        m = p[0]
        c = p[1:4] / m if m > 0 else np.zeros(3)
        I = np.array([[p[4], p[5], p[7]], [p[5], p[6], p[8]], [p[7], p[8], p[9]]])
        Ic = I - m * (np.dot(c, c) * np.eye(3) - np.outer(c, c)) if m > 0 else I
        ev = np.sort(np.linalg.eigvalsh(Ic))
        tri = min(ev[0] + ev[1] - ev[2], ev[0])
        lam = float(np.linalg.eigvalsh(pseudo_inertia(p))[0])
        out.append({"mass": float(m), "triangle_margin": float(tri), "pseudo_inertia_min_eig": lam,
                    "ok": bool(m > 0 and tri >= -tol)})
    return out
