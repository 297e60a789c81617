"""Simulated whole-robot logs for the robot-identification tests and benchmark (until the six-axis
virtual KR C4 lands): Pinocchio RNEA with seeded "true" links away from the URDF's nominal ones,
per-joint Coulomb-viscous friction and offset, torque and position noise, along a seeded
multi-sine trajectory inside the joint limits."""
from __future__ import annotations

import numpy as np

from kukaid.logs import AxisLog
from kukaid.models.robot import RobotModel, consistency


def true_parameters(robot: RobotModel, seed: int = 1) -> np.ndarray:
    """Standard parameters 15-40 % away from the nominal ones, physically consistent.

    Each link is rebuilt from a perturbed mass, centre of mass and principal inertias, so the
    result is consistent by construction (checked)."""
    import pinocchio as pin

    rng = np.random.default_rng(seed)
    out = []
    for k in range(robot.n):
        p = robot.pi_nominal[10 * k: 10 * k + 10]
        inert = pin.Inertia.FromDynamicParameters(p)
        m = inert.mass * rng.choice([-1, 1]) * rng.uniform(0.15, 0.4) + inert.mass
        c = np.asarray(inert.lever) + rng.uniform(-0.03, 0.03, 3)
        Ic = np.asarray(inert.inertia)
        scale = 1.0 + rng.choice([-1, 1], 3) * rng.uniform(0.15, 0.4, 3)
        ev, V = np.linalg.eigh(Ic)
        ev = ev * scale
        ev = np.minimum(ev, 0.95 * (ev.sum() - ev))           # keep the triangle inequalities
        out.append(pin.Inertia(m, c, (V * ev) @ V.T).toDynamicParameters())
    pi = np.concatenate(out)
    assert all(c["ok"] for c in consistency(pi))
    return pi


def true_friction(n: int, seed: int = 2) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    return {"Fc": rng.uniform(0.5, 3.0, n), "Fv": rng.uniform(0.5, 4.0, n), "offset": rng.uniform(-1.0, 1.0, n)}


def multisine(robot: RobotModel, duration: float, fs: float, seed: int = 3, f0: float = 0.1,
              harmonics: int = 5) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Time and the exact q, qd, qdd (N, n) of a seeded multi-sine inside 80 % of the joint
    ranges and 60 % of the velocity limits (a Fourier trajectory as used for excitation)."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(round(duration * fs))) / fs
    n = robot.n
    mid = 0.5 * (robot.lower + robot.upper)
    half = 0.4 * (robot.upper - robot.lower)
    half = np.minimum(half, 1.2)
    w = 2 * np.pi * f0 * np.arange(1, harmonics + 1)
    q = np.zeros((t.size, n)); qd = np.zeros_like(q); qdd = np.zeros_like(q)
    for j in range(n):
        a = rng.standard_normal(harmonics) / np.arange(1, harmonics + 1)
        ph = rng.uniform(0, 2 * np.pi, harmonics)
        s = np.sin(np.outer(t, w) + ph)
        cc = np.cos(np.outer(t, w) + ph)
        x, xd, xdd = s @ a, cc @ (a * w), -(s @ (a * w * w))
        g = min(half[j] / np.abs(x).max(), 0.6 * robot.velocity[j] / np.abs(xd).max())
        q[:, j], qd[:, j], qdd[:, j] = mid[j] + g * x, g * xd, g * xdd
    return t, q, qd, qdd


def simulated_log(robot: RobotModel, duration: float = 60.0, fs: float = 250.0, seed: int = 0,
                  noise: float = 0.05, q_noise: float = 1e-5, trajectory: int | None = None,
                  f0: float = 0.1) -> tuple[AxisLog, dict]:
    """A whole-robot log (q, tau for A1..An) and its truth {pi, Fc, Fv, offset}; ``trajectory``: the
    multi-sine's seed (default ``seed + 3``: another trajectory of the same robot), ``f0`` its
    fundamental, Hz (harmonics up to 5 ``f0``)."""
    pi = true_parameters(robot, seed + 1)
    fr = true_friction(robot.n, seed + 2)
    t, q, qd, qdd = multisine(robot, duration, fs, seed + 3 if trajectory is None else trajectory, f0)
    tau = np.empty_like(q)
    for a in range(0, t.size, 20000):   # blocks: an hour's (N, n, 10 n) regressor would not fit in memory
        b = slice(a, a + 20000)
        tau[b] = np.einsum("sjk,k->sj", robot.regressor(q[b], qd[b], qdd[b]), pi)
    tau += fr["Fc"] * np.sign(qd) + fr["Fv"] * qd + fr["offset"]
    rng = np.random.default_rng(seed + 4 if trajectory is None else 7919 * trajectory + seed + 4)
    tau += noise * rng.standard_normal(tau.shape)
    qm = q + q_noise * rng.standard_normal(q.shape)
    log = AxisLog(time=t, q=qm, tau=tau, axes=tuple(range(1, robot.n + 1)),
                  attrs={"source": "test helper (Pinocchio RNEA)", "seed": seed})
    return log, {"pi": pi, **fr}
