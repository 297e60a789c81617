"""Friction models of the paper: Stribeck (eq. 1) for sliding, Maxwell-slip (eqs. 9-10) for pre-sliding."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


def stribeck_power(v: np.ndarray, vs: float, delta: float) -> tuple[np.ndarray, np.ndarray]:
    """The Stribeck column sign(v) exp(-(|v|/vs)^delta) and the power (|v|/vs)^delta it is made of
    (its derivatives by vs and delta are the column times -delta/vs and -log(|v|/vs) times it)."""
    v = np.asarray(v, dtype=float)
    with np.errstate(over="ignore", under="ignore", divide="ignore"):
        pw = np.power(np.abs(v) / vs, delta)
        return np.sign(v) * np.exp(-pw), pw


def stribeck_column(v: np.ndarray, vs: float, delta: float) -> np.ndarray:
    """sign(v) exp(-|v/vs|^delta): the regressor column multiplying Fs - Fc in eq. (1)."""
    return stribeck_power(v, vs, delta)[0]


def stribeck_columns_at(v: np.ndarray, vs: np.ndarray, delta: np.ndarray) -> np.ndarray:
    """The Stribeck columns of many (vs, delta) pairs at once: an (len(v), len(vs)) matrix (for
    grid searches; through logarithms, so it agrees with :func:`stribeck_column` to rounding)."""
    v = np.asarray(v, dtype=float)
    av = np.abs(v)
    logv = np.log(np.where(av > 0, av, 1e-300))[:, None]
    with np.errstate(over="ignore", under="ignore"):
        return np.sign(v)[:, None] * np.exp(-np.exp(np.asarray(delta)[None, :] * (logv - np.log(vs)[None, :])))


def friction_columns(kind: str, qd: np.ndarray, qd_lin: np.ndarray | None = None, vs: float = 0.04,
                     delta: float = 1.0) -> tuple[list[str], np.ndarray]:
    """Regressor of the sliding friction, linear in its levels: names and (n, k) columns.

    Stribeck (``kind`` "stribeck"): Fc sign(qd) (1 - E) + Fs sign(qd) E + Fv qd with
    E = exp(-(|qd|/vs)^delta) at fixed ``vs``, ``delta``; Coulomb + viscous: Fc sign(qd) + Fv qd.
    ``qd_lin`` is the velocity of the viscous column (default ``qd``).
    """
    s = np.sign(qd)
    if kind == "stribeck":
        e = stribeck_column(qd, vs, delta)
        names, cols = ["Fc", "Fs"], [s - e, e]
    else:
        names, cols = ["Fc"], [s]
    return names + ["Fv"], np.column_stack(cols + [qd if qd_lin is None else qd_lin])


@dataclass(frozen=True)
class Stribeck:
    """Stribeck friction, eq. (1): F(v) = (Fc + (Fs - Fc) exp(-|v/vs|^delta)) sign(v) + Fv v.

    Parameters
    ----------
    Fc : Coulomb friction, N·m.   Fs : static friction, N·m.   vs : Stribeck velocity, rad/s.
    delta : shape exponent (0.5 to 2).   Fv : viscous coefficient, N·m·s/rad.
    """

    Fc: float
    Fs: float
    vs: float
    delta: float
    Fv: float

    def __call__(self, v: np.ndarray | float) -> np.ndarray:
        v = np.asarray(v, dtype=float)
        return self.magnitude(np.abs(v)) * np.sign(v) + self.Fv * v

    def at(self, v: float) -> float:
        """F(v) of one velocity (plain floats: a control step's cost, not numpy's per-call overhead)."""
        if v == 0.0:
            return 0.0
        m = self.Fc + (self.Fs - self.Fc) * math.exp(-((abs(v) / self.vs) ** self.delta))
        return math.copysign(m, v) + self.Fv * v

    def magnitude(self, speed: np.ndarray | float) -> np.ndarray:
        """Coulomb + Stribeck part, Fc + (Fs - Fc) exp(-(speed/vs)^delta), for speed >= 0."""
        s = np.asarray(speed, dtype=float)
        return self.Fc + (self.Fs - self.Fc) * np.exp(-((s / self.vs) ** self.delta))

    def to_dict(self) -> dict:
        return {"model": "stribeck", "Fc": self.Fc, "Fs": self.Fs, "vs": self.vs, "delta": self.delta, "Fv": self.Fv}


@dataclass(frozen=True)
class CoulombViscous:
    """Coulomb + viscous friction: F(v) = Fc sign(v) + Fv v."""

    Fc: float
    Fv: float

    def __call__(self, v: np.ndarray | float) -> np.ndarray:
        v = np.asarray(v, dtype=float)
        return self.Fc * np.sign(v) + self.Fv * v

    def at(self, v: float) -> float:
        """F(v) of one velocity (plain floats)."""
        return (math.copysign(self.Fc, v) if v else 0.0) + self.Fv * v

    def magnitude(self, speed: np.ndarray | float) -> np.ndarray:
        return np.full_like(np.asarray(speed, dtype=float), self.Fc)

    def to_dict(self) -> dict:
        return {"model": "coulomb-viscous", "Fc": self.Fc, "Fv": self.Fv}


def friction_from_dict(d: dict) -> Stribeck | CoulombViscous:
    """Build a friction model from the parameter file's ``friction`` object."""
    model = d.get("model", "stribeck")
    if model == "stribeck":
        return Stribeck(*(float(d[k]) for k in ("Fc", "Fs", "vs", "delta", "Fv")))
    if model == "coulomb-viscous":
        return CoulombViscous(float(d["Fc"]), float(d["Fv"]))
    raise ValueError(f"unknown friction model '{model}' (expected 'stribeck' or 'coulomb-viscous')")


@dataclass(frozen=True)
class MaxwellSlip:
    """Maxwell-slip pre-sliding friction, eqs. (9)-(10): N elasto-slide elements in parallel.

    Element i has stiffness ``k[i]`` (N·m/rad) and saturation torque ``W[i]`` (N·m); its position
    ``zeta[i]`` (rad) is the anchor of its spring.  While ``|z - zeta_i| < W_i/k_i`` it acts as a
    spring, k_i (z - zeta_i); beyond, it slips and carries sign(z - zeta_i) W_i.  The model has
    non-local memory: the torque depends on the history of z, not only on z.
    """

    k: tuple[float, ...]
    W: tuple[float, ...]

    def __post_init__(self) -> None:
        k = tuple(float(x) for x in np.atleast_1d(self.k))
        W = tuple(float(x) for x in np.atleast_1d(self.W))
        if len(k) != len(W) or not k:
            raise ValueError("k and W must be non-empty and of equal length")
        if min(k) <= 0 or min(W) < 0:
            raise ValueError("Maxwell-slip stiffnesses must be > 0 and saturations >= 0")
        object.__setattr__(self, "k", k)
        object.__setattr__(self, "W", W)

    @property
    def n(self) -> int:
        return len(self.k)

    @property
    def breakaway(self) -> np.ndarray:
        """Break-away displacement W_i / k_i of every element, rad."""
        return np.asarray(self.W) / np.asarray(self.k)

    def saturated_state(self, z0: float, direction: float) -> np.ndarray:
        """Element positions after a move in ``direction`` (sign) stopping at ``z0``, eq. (12)."""
        return z0 - np.sign(direction) * self.breakaway

    def simulate(self, z: np.ndarray, zeta0: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Torque along the displacement path ``z``; returns (F (len(z),), final element positions)."""
        z = np.asarray(z, dtype=float)
        k = np.asarray(self.k)
        W = np.asarray(self.W)
        zeta = np.zeros_like(k) if zeta0 is None else np.array(zeta0, dtype=float)
        lim = W / k
        F = np.empty_like(z)
        for j, zj in enumerate(z):
            d = zj - zeta
            over = np.abs(d) >= lim
            zeta = np.where(over, zj - np.sign(d) * lim, zeta)
            F[j] = np.sum(k * (zj - zeta))
        return F, zeta

    def to_dict(self, zeta0: np.ndarray | None = None) -> dict:
        d = {"k": list(self.k), "W": list(self.W)}
        d["zeta0"] = [0.0] * self.n if zeta0 is None else [float(x) for x in zeta0]
        return d
