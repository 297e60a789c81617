"""The truth of the six-axis virtual KR C4: a robot from a URDF, its real inertials and friction.

The URDF's inertial values are nominal (CAD or estimates); a real robot differs.  :func:`draw_truth`
draws, from a seed, a robot whose every link is perturbed *physically consistently*: the link's
4x4 pseudo-inertia matrix ``J = [[Σ, h], [hᵀ, m]]`` (``Σ = ½ tr(I) 1 - I`` about the joint frame,
``h = m c``) is positive definite exactly when the mass is positive and the inertia satisfies the
triangle inequalities, so perturbing its Cholesky factor (log-scale on the diagonal) always gives a
physical link.  Friction per joint (Coulomb ``Fc``, viscous ``Fv``, optional Stribeck ``Fs, vs``),
the reflected rotor inertia (``armature``) and a drive torque offset are drawn around defaults
that scale with the joint's torque limit (URDF ``effort``).

Everything is SI (kg, m, kg·m², N·m, N·m·s/rad, rad/s).
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from kukaid.errors import KukaidError

TRUTH_SCHEMA = "kukaid.robot-truth/1"
#: nominal reflected rotor inertia per N·m of the joint's torque limit, kg·m²/(N·m)
NOMINAL_ARMATURE = 1e-3

# -- inertial parameters <-> pseudo-inertia --------------------------------------------------------
def pseudo_inertia(pi: np.ndarray) -> np.ndarray:
    """4x4 pseudo-inertia of a link from its 10 dynamic parameters
    ``(m, mcx, mcy, mcz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz)`` (Pinocchio's order, inertia about the frame)."""
    m, hx, hy, hz, ixx, ixy, iyy, ixz, iyz, izz = pi
    I = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    J = np.zeros((4, 4))
    J[:3, :3] = 0.5 * np.trace(I) * np.eye(3) - I
    J[:3, 3] = J[3, :3] = (hx, hy, hz)
    J[3, 3] = m
    return J


def from_pseudo_inertia(J: np.ndarray) -> np.ndarray:
    """The 10 dynamic parameters of a link from its pseudo-inertia (inverse of :func:`pseudo_inertia`)."""
    S = J[:3, :3]
    I = np.trace(S) * np.eye(3) - S
    return np.array([J[3, 3], J[0, 3], J[1, 3], J[2, 3], I[0, 0], I[0, 1], I[1, 1], I[0, 2], I[1, 2], I[2, 2]])


def is_physical(pi: np.ndarray, tol: float = 0.0) -> bool:
    """True when the link's pseudo-inertia is positive definite (mass > 0, triangle inequalities)."""
    return bool(np.linalg.eigvalsh(pseudo_inertia(pi)).min() > tol)


def perturb_link(pi: np.ndarray, rng: np.random.Generator, size: float) -> np.ndarray:
    """A physically consistent random neighbour of a link: its pseudo-inertia's Cholesky factor is
    perturbed by about ``size`` (relative; log-scale on the diagonal).  A massless link stays one."""
    if pi[0] <= 0:
        return np.array(pi, dtype=float)
    J = pseudo_inertia(pi)
    # a point-mass-like link may be semi-definite: regularise by a tiny sphere before factoring
    w = np.linalg.eigvalsh(J)
    if w.min() <= 1e-12 * max(w.max(), 1e-12):
        J = J + np.diag([1e-6 * pi[0]] * 3 + [0.0])
    L = np.linalg.cholesky(J)
    d = np.log(np.diag(L)) + size * rng.standard_normal(4)
    off = np.tril(L, -1)
    scale = np.sqrt(np.outer(np.diag(L), np.diag(L)))  # off-diagonal noise relative to the diagonal's size
    off = off + np.tril(size * rng.standard_normal((4, 4)) * scale, -1) * 0.5
    L2 = off + np.diag(np.exp(d))
    return from_pseudo_inertia(L2 @ L2.T)


# -- the truth ------------------------------------------------------------------------------------
@dataclass(frozen=True)
class RobotTruth:
    """The simulated robot's true dynamics (SI), per link and per joint.

    Parameters
    ----------
    robot : bundled robot name or URDF path.
    pi : (n, 10) inertial parameters of the moving links, Pinocchio's order, about each joint frame.
    Fc, Fv, Fs, vs : (n,) Coulomb N·m, viscous N·m·s/rad, static (Stribeck peak) N·m, Stribeck
        velocity rad/s; ``Fs == Fc`` is pure Coulomb-viscous friction.
    armature : (n,) reflected rotor inertia, kg·m².
    offset : (n,) drive torque offset, N·m.
    friction_coupling : (n, n) strictly lower-triangular C or None: the friction is the motors', on
        their velocities ``(I + C) qd`` (joint units: a KUKA wrist's gearing couples A4's motion
        into the A5 and A6 drives, ``C[4, 3] = c54``, ``C[5, 3] = c64``, ``C[5, 4] = c65``), seen at
        the joints through ``(I + C)^T``; ``Fc, Fv, Fs, vs`` are then each motor's (None: per joint).
    gear_stiffness : (n,) N·m/rad or None: a torsional spring between each joint's motor and its link
        (0: rigid), the gear's elasticity; the encoder is on the motor side, the link lags by
        ``tau / k``; the rotor inertia and friction on the motor side.
    gear_damping : (n,) N·m·s/rad or None: the spring's damping (in parallel).
    """

    robot: str
    pi: np.ndarray
    Fc: np.ndarray
    Fv: np.ndarray
    Fs: np.ndarray
    vs: np.ndarray
    armature: np.ndarray
    offset: np.ndarray
    friction_coupling: np.ndarray | None = None
    gear_stiffness: np.ndarray | None = None
    gear_damping: np.ndarray | None = None

    @property
    def n(self) -> int:
        return int(self.Fc.size)

    def apply(self, model) -> Any:
        """A copy of the Pinocchio ``model`` carrying these inertials and this armature."""
        import pinocchio as pin

        m = model.copy()
        for j in range(1, m.njoints):
            m.inertias[j] = pin.Inertia.FromDynamicParameters(np.asarray(self.pi[j - 1], dtype=float))
        m.armature = np.asarray(self.armature, dtype=float).copy()
        return m

    def friction(self, qd: np.ndarray, eps: float = 0.0) -> np.ndarray:
        """Friction torque at joint velocities ``qd`` (rad/s; (n,) or (N, n)), N·m, plus the offset.

        ``eps`` > 0 replaces sign(qd) by tanh(qd / eps) (the simulator's regularisation)."""
        qd = np.asarray(qd, dtype=float)
        mix = self.friction_mix()
        v = qd if mix is None else qd @ mix.T          # the motors' velocities (joint units)
        s = np.tanh(v / eps) if eps > 0 else np.sign(v)
        g = self.Fc + (self.Fs - self.Fc) * np.exp(-(v / self.vs) ** 2)
        f = g * s + self.Fv * v
        return (f if mix is None else f @ mix) + self.offset

    def friction_mix(self) -> np.ndarray | None:
        """``I + C`` of :attr:`friction_coupling` (motor velocities ``mix @ qd``), None without one."""
        if self.friction_coupling is None or not np.any(np.asarray(self.friction_coupling) != 0):
            return None
        return np.eye(self.n) + np.asarray(self.friction_coupling, dtype=float)

    def to_dict(self) -> dict[str, Any]:
        """JSON-able dictionary (``"schema": "kukaid.robot-truth/1"``); :meth:`from_dict` reads it back."""
        model = "coulomb-viscous" if np.allclose(self.Fs, self.Fc) else "stribeck"
        return {
            "schema": TRUTH_SCHEMA,
            "robot": self.robot,
            "units": {"pi": "kg, kg·m, kg·m² (m, mc, I about the joint frame; Pinocchio order)",
                      "Fc": "N·m", "Fv": "N·m·s/rad", "Fs": "N·m", "vs": "rad/s", "armature": "kg·m²",
                      "offset": "N·m"},
            "pi": [[float(x) for x in row] for row in self.pi],
            "friction": {"model": model, "Fc": self.Fc.tolist(), "Fv": self.Fv.tolist(), "Fs": self.Fs.tolist(),
                         "vs": self.vs.tolist()},
            "armature": self.armature.tolist(),
            "offset": self.offset.tolist(),
            **({} if self.friction_coupling is None else
               {"friction_coupling": np.asarray(self.friction_coupling, float).tolist()}),
            **{k: np.asarray(getattr(self, k), float).tolist() for k in ("gear_stiffness", "gear_damping")
               if getattr(self, k) is not None},
        }

    def elastic(self) -> np.ndarray:
        """Indices of the joints with an elastic gear (:attr:`gear_stiffness` > 0)."""
        return np.zeros(0, int) if self.gear_stiffness is None else np.flatnonzero(np.asarray(self.gear_stiffness) > 0)

    @classmethod
    def from_dict(cls, d: dict[str, Any], where: str = "robot truth") -> "RobotTruth":
        try:
            f = d["friction"]
            arr = {k: np.asarray(f[k], dtype=float) for k in ("Fc", "Fv", "Fs", "vs")}
            fc = d.get("friction_coupling")
            return cls(robot=str(d["robot"]), pi=np.asarray(d["pi"], dtype=float), armature=np.asarray(d["armature"], dtype=float),
                       offset=np.asarray(d["offset"], dtype=float), **arr,
                       friction_coupling=None if fc is None else np.asarray(fc, dtype=float),
                       **{k: np.asarray(d[k], dtype=float) for k in ("gear_stiffness", "gear_damping") if k in d})
        except (KeyError, TypeError, ValueError) as e:
            raise KukaidError(f"{where}: not a {TRUTH_SCHEMA} object ({e})") from None

    def json_text(self) -> str:
        return json.dumps(self.to_dict(), indent=1) + "\n"


def nominal_pi(model) -> np.ndarray:
    """(n, 10) inertial parameters of the model's moving links (the URDF's nominal values)."""
    return np.array([model.inertias[j].toDynamicParameters() for j in range(1, model.njoints)])


def draw_truth(robot: str | Path, model, seed: int = 1, size: float = 0.15,
               friction_scale: float = 1.0, stribeck: bool = False) -> RobotTruth:
    """A seeded robot away from the URDF's nominal values.

    Parameters
    ----------
    robot : the robot's name or URDF path (recorded in the truth).
    model : its Pinocchio model (the nominal values).
    seed : seed of the draw; the same seed gives the same robot.
    size : relative size of the inertial perturbation (0.15: masses and inertias about 15 % away).
    friction_scale : scales the default friction (Coulomb 4 %, viscous 3 % of the joint's torque
        limit per rad/s, each drawn within +-30 %).
    stribeck : draw a Stribeck peak (Fs 10 to 40 % above Fc, vs 0.02 to 0.1 rad/s); else Fs = Fc.
    """
    if not (math.isfinite(size) and 0 <= size <= 1):
        raise KukaidError(f"robot truth: perturbation size must be 0 to 1, got {size}")
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 0x7287]))
    pi = np.array([perturb_link(p, rng, size) for p in nominal_pi(model)])
    n = model.nv
    effort = np.asarray(model.effortLimit, dtype=float)
    effort = np.where(np.isfinite(effort) & (effort > 0), effort, 100.0)
    u = lambda lo, hi: rng.uniform(lo, hi, n)  # noqa: E731
    Fc = friction_scale * 0.04 * effort * u(0.7, 1.3)
    Fv = friction_scale * 0.03 * effort * u(0.7, 1.3)
    Fs = Fc * u(1.1, 1.4) if stribeck else Fc.copy()
    vs = u(0.02, 0.1)
    # reflected rotor inertia: a fraction of the torque limit (N·m -> kg·m² at ~1 rad/s² scale)
    armature = NOMINAL_ARMATURE * effort * u(0.5, 1.5)
    offset = 0.005 * effort * rng.choice([-1.0, 1.0], n) * u(0.5, 1.0)
    return RobotTruth(robot=str(robot), pi=pi, Fc=Fc, Fv=Fv, Fs=Fs, vs=vs, armature=armature, offset=offset)
