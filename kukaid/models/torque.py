"""The one joint-torque model of an axis: a sum of named terms, what every stage reads and writes.

    Γ = F(qd)                          friction term: Stribeck (eq. 1) or Coulomb + viscous
      + Izz qdd + Mx cos q [+ My sin q]   rigid-body term, eqs. (6)-(8)
      [+ offset]                       offset term
      + sum of effect terms            :mod:`kukaid.models.effects` (what a diagnosis adds)

and, at standstill, the Maxwell-slip pre-sliding term (eqs. 9-10) in place of F.  Every
parameter except the Stribeck vs and delta (and the effects' nonlinear settings) enters linearly:
:meth:`JointTorqueModel.regressor` gives the columns, :meth:`~JointTorqueModel.design` the
Jacobian of the filtered prediction.  :data:`BOUNDS` holds the physical bounds.  The parameter
file (``kukaid.params/1``) is read into and written out of this class by :mod:`kukaid.params.axis`.
Adding an effect is adding an :class:`~kukaid.models.effects.Effect` to the table there.
"""
from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from kukaid.models.effects import EFFECTS
from kukaid.models.friction import CoulombViscous, MaxwellSlip, Stribeck, friction_columns, friction_from_dict
from kukaid.models.joint import RigidBody, rigid_regressor
from kukaid.models.signals import LogSignals

#: the base terms and their parameters, in the parameter file's order
TERMS: dict[str, tuple[str, ...]] = {"friction": ("Fc", "Fs", "vs", "delta", "Fv"), "rigid_body": ("Izz", "Mx", "My"),
                                     "offset": ("offset",), "maxwell_slip": ("k", "W", "zeta0")}
#: physical bounds of the base parameters (the refit's; the others are free)
BOUNDS: dict[str, tuple[float, float]] = {"Fc": (0.0, math.inf), "Fs": (0.0, math.inf), "Fv": (0.0, math.inf),
                                          "Izz": (0.0, math.inf), "vs": (1e-4, 2.0), "delta": (0.5, 2.0)}
_RIGID = ("Izz", "Mx", "My", "offset")


@dataclass
class EffectTerm:
    """An effect in the model: its name, nonlinear settings and coefficients."""

    name: str
    nl: dict
    coefs: dict[str, float]

    def key(self, c: str) -> str:
        return f"{self.name}.{c}"


@dataclass
class JointTorqueModel:
    """The torque model of one joint (SI: N·m, rad, s).

    Attributes
    ----------
    friction_kind : "stribeck" or "coulomb-viscous".
    lin : linear parameters of the base terms: Fc, (Fs,) Fv, Izz, (Mx, My, offset); a parameter
        not in ``lin`` is not part of the model (zero).
    vs, delta : Stribeck velocity (rad/s) and shape exponent.
    effects : the effect terms, in the order they were added.
    maxwell_slip, zeta0 : pre-sliding term and its element positions (rad) or None.
    qd_thr : velocity threshold between the quasi-static and dynamic modes, rad/s.
    std : standard deviations of the parameters ("name" or "effect.coefficient").
    stored_effects : the parameter file's ``effects`` section as read (the control stage reads
        effects in the simulator's format too).   ignored_effects : effects of the file that are
        not effect terms of this model (not written by ``kukaid diagnose``).
    """

    friction_kind: str
    lin: dict[str, float]
    vs: float = 0.04
    delta: float = 1.0
    effects: list[EffectTerm] = field(default_factory=list)
    maxwell_slip: MaxwellSlip | None = None
    zeta0: tuple[float, ...] | None = None
    qd_thr: float = 0.0017
    std: dict[str, float] = field(default_factory=dict)
    stored_effects: dict[str, Any] = field(default_factory=dict)
    ignored_effects: list[str] = field(default_factory=list)

    # -- terms and parameters -------------------------------------------------------------------
    def copy(self) -> "JointTorqueModel":
        return copy.deepcopy(self)

    def has(self, name: str) -> bool:
        """Whether ``name`` is a parameter of the base terms of this model."""
        return name in self.lin or (name in ("vs", "delta") and self.friction_kind == "stribeck")

    def value(self, name: str) -> float:
        return float(getattr(self, name)) if name in ("vs", "delta") else self.lin[name]

    def within_bounds(self) -> "JointTorqueModel":
        """A copy with vs and delta clipped to :data:`BOUNDS` (a refit's start)."""
        m = self.copy()
        m.vs, m.delta = float(np.clip(m.vs, *BOUNDS["vs"])), float(np.clip(m.delta, *BOUNDS["delta"]))
        return m

    @property
    def effect_names(self) -> list[str]:
        return [e.name for e in self.effects]

    def with_effect(self, name: str, nl: dict, coefs: dict[str, float]) -> "JointTorqueModel":
        """A copy with the effect added (native effects become base parameters)."""
        m = self.copy()
        eff = EFFECTS[name]
        if eff.native:
            m.lin[eff.native] = float(coefs[eff.coef_keys(nl)[0]])
        else:
            m.effects.append(EffectTerm(name, eff.freeze(dict(nl), self), dict(coefs)))
        return m

    def without(self, name: str) -> "JointTorqueModel":
        """A copy without the effect ``name``."""
        m = self.copy()
        if EFFECTS[name].native:
            m.lin.pop(EFFECTS[name].native, None)
        m.effects = [e for e in m.effects if e.name != name]
        return m

    def coef_vector(self, names: Sequence[str]) -> np.ndarray:
        out = []
        for n in names:
            if "." in n:
                en, cn = n.split(".", 1)
                out.append(next(e for e in self.effects if e.name == en).coefs[cn])
            else:
                out.append(self.lin[n])
        return np.asarray(out, dtype=float)

    def set_coefs(self, names: Sequence[str], values: np.ndarray) -> None:
        for n, v in zip(names, values):
            if "." in n:
                en, cn = n.split(".", 1)
                next(e for e in self.effects if e.name == en).coefs[cn] = float(v)
            else:
                self.lin[n] = float(v)

    # -- the terms as functions -----------------------------------------------------------------
    @property
    def rigid(self) -> RigidBody:
        """The rigid-body and offset terms."""
        return RigidBody(**{k: self.lin.get(k, 0.0) for k in _RIGID})

    @property
    def friction(self) -> Stribeck | CoulombViscous:
        """The sliding-friction term (a function of the velocity)."""
        return friction_from_dict(self.friction_dict())

    def friction_dict(self) -> dict[str, Any]:
        """The friction parameters as the parameter file's ``friction`` object."""
        d: dict[str, Any] = {"model": self.friction_kind, "Fc": self.lin["Fc"], "Fv": self.lin["Fv"]}
        if self.friction_kind == "stribeck":
            d.update(Fs=self.lin["Fs"], vs=self.vs, delta=self.delta)
        return d

    def predict_dynamic(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
        """Γp of eq. (13) without the effects: Izz qdd + gravity(q) + offset + F(qd), N·m."""
        return self.rigid.torque(q, qdd) + self.friction(qd)

    def friction_torque(self, sig: LogSignals, friction: dict | None = None) -> np.ndarray:
        """Sliding friction F(qd) on the full grid, N·m (``friction``: other parameters to use)."""
        return (self.friction if friction is None else friction_from_dict(friction))(sig.qd)

    def effects_torque(self, time: np.ndarray, q: np.ndarray, qd: np.ndarray, temp: np.ndarray | None = None,
                       others: dict[int, np.ndarray] | None = None) -> np.ndarray:
        """Torque of the effect terms (not the native ones, held by the rigid body), N·m, on plain
        samples (see :meth:`LogSignals.of`)."""
        if not self.effects:
            return np.zeros(np.size(time))
        ne, Xe = self.effect_columns(LogSignals.of(time, q, qd, temp, others=others))
        return Xe @ self.coef_vector(ne)

    # -- regressor and Jacobian -----------------------------------------------------------------
    def base_columns(self, sig: LogSignals, vs: float | None = None,
                     delta: float | None = None) -> tuple[list[str], np.ndarray]:
        """Names and raw (unfiltered) regressor columns of the base terms' linear parameters
        (friction at ``vs``, ``delta``, default the model's; rigid body; offset)."""
        names, F = friction_columns(self.friction_kind, sig.qd, sig.qd_lin, self.vs if vs is None else vs,
                                    self.delta if delta is None else delta)
        rn = [k for k in _RIGID if k in self.lin]
        R = rigid_regressor(sig.q_raw, sig.qdd if sig.qdd_lin is None else sig.qdd_lin, rn)
        return names + rn, np.column_stack([F, R])

    def effect_columns(self, sig: LogSignals) -> tuple[list[str], np.ndarray]:
        """Names (``effect.coefficient``) and raw regressor columns of the effect terms."""
        names, cols = [], []
        for e in self.effects:
            eff = EFFECTS[e.name]
            cols.append(eff.columns(sig, e.nl, self))
            names += [e.key(c) for c in eff.coef_keys(e.nl)]
        return (names, np.column_stack(cols)) if cols else ([], np.zeros((sig.n, 0)))

    def regressor(self, sig: LogSignals) -> tuple[list[str], np.ndarray]:
        """Names and raw columns of every linear parameter: base terms, then effect terms."""
        nb, Xb = self.base_columns(sig)
        ne, Xe = self.effect_columns(sig)
        return nb + ne, (np.column_stack([Xb, Xe]) if ne else Xb)

    def predict_raw(self, sig: LogSignals) -> np.ndarray:
        """Predicted torque on the full grid (before the comparison filter), N·m."""
        nb, Xb = self.base_columns(sig)
        ne, Xe = self.effect_columns(sig)
        return Xb @ self.coef_vector(nb) + (Xe @ self.coef_vector(ne) if ne else 0.0)

    def residual(self, sig: LogSignals) -> np.ndarray:
        """Filtered measured minus filtered predicted torque on the compared rows, N·m.

        (The sign is measured minus predicted here, the regression convention; the paper's
        torque residual Γr = Γp - Γm is its negative.)
        """
        return sig.filtw(sig.tau_raw - self.predict_raw(sig))[sig.rows]

    def design(self, sig: LogSignals) -> tuple[list[str], np.ndarray]:
        """Jacobian of the filtered prediction on the compared rows: linear columns, then
        d/d(vs), d/d(delta) for Stribeck friction (numerical)."""
        names, X = self.regressor(sig)
        F = sig.filtw  # noqa: N806
        J = np.column_stack([F(X[:, k])[sig.rows] for k in range(X.shape[1])])
        if self.friction_kind == "stribeck":
            extra = []
            for p in ("vs", "delta"):
                h = 1e-4 * max(abs(getattr(self, p)), 1e-3)
                _, Xp = self.base_columns(sig, **{p: getattr(self, p) + h})
                d = (Xp[:, :2] - X[:, :2]) @ np.array([self.lin["Fc"], self.lin["Fs"]]) / h
                extra.append(F(d)[sig.rows])
            J = np.column_stack([J] + extra)
            names = names + ["vs", "delta"]
        return names, J
