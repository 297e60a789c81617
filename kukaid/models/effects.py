"""The effect terms of a joint's torque model: what ``kukaid diagnose`` can add, one class each.

Every effect is a small parametric torque term with a meaning.  For fixed values of its
nonlinear settings ``nl`` (the ripple order n, the backlash time constant, the drift coordinate)
the term is linear in its coefficients: :meth:`Effect.columns` gives their regressor columns on
a log's full sample grid (unfiltered).  The names are fixed: tests, users and parameter files
rely on them.  Which options a diagnosis tries and when an effect is plausible is the search's
business (:mod:`kukaid.diagnose.candidates`).

=========================  ==================================================================
name                       term (sign s = sign(qd))
=========================  ==================================================================
gravity_sine               My sin(q): centre of mass off the model's axis (revolute only)
torque_offset              offset: a constant torque while moving (asymmetric Coulomb friction)
position_ripple            a sin(n q) + b cos(n q) = A sin(n q + phi), n searched (gear/cogging)
thermal_drift              friction changing over the run: c * x * s (Coulomb) or c * x * F(qd)
                           (whole friction), x = temperature, elapsed time or dissipated energy
load_dependent_friction    Fc_load |cos q| s: Coulomb friction growing with the gravity load
                           |Mx cos q| (revolute, Mx != 0); mu = Fc_load / |Mx|
backlash                   A * s_r * shape((t - t_r) / tau) after every velocity reversal at t_r
                           (s_r the new direction): shape "pulse" x exp(1 - x) (peak A at tau)
                           or "decay" exp(-x)
stribeck                   dF s exp(-(|qd|/vs)^delta): a Stribeck rise on Coulomb + viscous friction
presliding                 A s_r exp(-|q - q_r| / x0) from each reversal (position q_r) on
coupling                   per other moving axis j: cos, sin of q + q_j and of q_j, and qdd_j
=========================  ==================================================================
"""
from __future__ import annotations

import math
from typing import Any, Protocol

import numpy as np

from kukaid.models.friction import stribeck_column
from kukaid.models.signals import LogSignals


class ModelView(Protocol):
    """What an effect term reads from the model it belongs to
    (:class:`kukaid.models.torque.JointTorqueModel`, which imports this module)."""

    def friction_torque(self, sig: LogSignals, friction: dict | None = None) -> np.ndarray: ...

#: marks an effect stored by ``kukaid diagnose`` (its coefficients and settings are read back)
TAG = "kukaid.diagnose/1"


def _num(v: Any) -> Any:
    return v.item() if isinstance(v, (np.floating, np.integer)) else v


class Effect:
    """Base class: one named effect term (a sum of coefficients times regressor columns)."""

    name: str = ""
    meaning: str = ""
    coef_names: tuple[str, ...] = ()
    #: an effect stored as a parameter of the rigid-body or offset term ("My", "offset") or None
    native: str | None = None
    #: keys written for the reader only (recomputed from the coefficients)
    derived: tuple[str, ...] = ()
    #: nonlinear settings a stored effect must have (besides its coefficients)
    settings: tuple[str, ...] = ()
    #: the unit of each number it stores, on a revolute joint (:func:`unit_of`)
    units: dict[str, str] = {}

    def columns(self, sig: LogSignals, nl: dict, model: ModelView) -> np.ndarray:
        """Regressor columns (n, len(coef_keys(nl))) on the full grid, unfiltered."""
        raise NotImplementedError

    def coef_keys(self, nl: dict) -> tuple[str, ...]:
        """Names of the coefficients at settings ``nl`` (fixed, except for ``coupling``)."""
        return self.coef_names

    def freeze(self, nl: dict, model: ModelView) -> dict:
        """Settings to store when the effect joins the model (fix what depends on the model)."""
        return nl

    def from_params(self, d: dict) -> tuple[dict, dict[str, float]]:
        """(nonlinear settings, coefficients) of a stored effect."""
        coefs = {k: float(d[k]) for k in self.coef_names}
        nl = {k: v for k, v in d.items() if k not in self.coef_names and k not in ("model", "std")
              and not k.startswith("_") and k not in self.derived}
        return nl, coefs

    def describe(self, nl: dict, coefs: dict[str, float], std: dict[str, float],
                 model: ModelView) -> dict[str, Any]:
        """The effect's parameters for the parameter file and the report (JSON-able)."""
        d: dict[str, Any] = {"model": TAG}
        d.update({k: _num(v) for k, v in nl.items()})
        d.update({k: float(v) for k, v in coefs.items()})
        d["std"] = {k: float(std.get(k, math.nan)) for k in coefs}
        return d


class GravitySine(Effect):
    name = "gravity_sine"
    meaning = "My sin(q): the centre of mass is off the model's axis"
    coef_names = ("My",)
    units = {"My": "N·m"}
    native = "My"

    def columns(self, sig, nl, model):
        return np.sin(sig.q)[:, None]


class TorqueOffset(Effect):
    name = "torque_offset"
    meaning = "a constant torque while moving (also asymmetric Coulomb friction)"
    coef_names = ("offset",)
    units = {"offset": "N·m"}
    native = "offset"

    def columns(self, sig, nl, model):
        return np.ones((sig.n, 1))


class PositionRipple(Effect):
    name = "position_ripple"
    meaning = "A sin(n q + phi): gear or cogging ripple with position"
    coef_names = ("a", "b")
    derived = ("A", "phi")
    settings = ("n",)
    units = {"a": "N·m", "b": "N·m", "A": "N·m", "phi": "rad", "n": "1/rad"}

    def columns(self, sig, nl, model):
        n = nl["n"]
        return np.column_stack([np.sin(n * sig.q), np.cos(n * sig.q)])

    def columns_at(self, q: np.ndarray, options: list[dict]) -> tuple[np.ndarray, np.ndarray]:
        """The sin and cos columns of many options at positions ``q``: two (len(q), len(options))."""
        ph = np.outer(q, [o["n"] for o in options])
        return np.sin(ph), np.cos(ph)

    def describe(self, nl, coefs, std, model):
        d = super().describe(nl, coefs, std, model)
        a, b = coefs["a"], coefs["b"]
        d["A"] = float(math.hypot(a, b))
        d["phi"] = float(math.atan2(b, a))
        return d


def dissipated_energy(sig: LogSignals, model: ModelView, friction: dict | None = None) -> np.ndarray:
    """Friction energy dissipated since the log started, J: integral of |F(qd) qd| dt."""
    p = np.abs(model.friction_torque(sig, friction) * sig.qd)
    dt = np.diff(sig.time, prepend=sig.time[0])
    return np.cumsum(p * dt)


class ThermalDrift(Effect):
    name = "thermal_drift"
    meaning = "friction changing over the run (temperature, elapsed time or dissipated energy)"
    coef_names = ("c",)
    derived = ("unit",)
    settings = ("coordinate", "form")

    def x(self, sig, coordinate, model, friction=None):
        """The drift coordinate on the full grid: temperature °C, elapsed time s or energy J."""
        if coordinate == "temperature":
            return sig.filt(sig.temp) if sig.temp is not None else np.zeros(sig.n)
        if coordinate == "time":
            return sig.elapsed
        return dissipated_energy(sig, model, friction)

    def freeze(self, nl, model):
        # the drift term scales the friction the model had when the effect was found
        return {**nl, "friction_ref": model.friction_dict()}

    def columns(self, sig, nl, model):
        fr = nl.get("friction_ref")
        x = self.x(sig, nl["coordinate"], model, fr)
        if nl["form"] == "coulomb":
            return (x * np.sign(sig.qd))[:, None]
        return (x * model.friction_torque(sig, fr))[:, None]

    def describe(self, nl, coefs, std, model):
        d = super().describe(nl, coefs, std, model)
        unit = {"temperature": "degC", "time": "s", "energy": "J"}[nl["coordinate"]]
        d["unit"] = (f"N·m per {unit} of Coulomb friction" if nl["form"] == "coulomb"
                     else f"fraction of the friction per {unit}")
        return d


class LoadDependentFriction(Effect):
    name = "load_dependent_friction"
    meaning = "Coulomb friction growing with the gravity load |Mx cos q|"
    coef_names = ("Fc_load",)
    derived = ("mu",)
    units = {"Fc_load": "N·m", "mu": "-"}

    def columns(self, sig, nl, model):
        return (np.abs(np.cos(sig.q)) * np.sign(sig.qd))[:, None]

    def describe(self, nl, coefs, std, model):
        d = super().describe(nl, coefs, std, model)
        mx = abs(model.lin.get("Mx", 0.0))
        d["mu"] = float(coefs["Fc_load"] / mx) if mx > 0 else math.nan
        return d


def reversals(sig: LogSignals, qd_thr: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Indices where the axis starts moving in the direction opposite to its previous motion.

    Returns (indices into the full grid, new direction +1/-1).  ``qd_thr`` defaults to
    0.01 rad/s (m/s), at most 5 % of the 95th percentile of |qd|.
    """
    qd = sig.qd
    if qd_thr is None:
        qd_thr = min(0.01, 0.05 * float(np.percentile(np.abs(qd), 95))) if qd.size else 0.0
    s = np.where(qd > qd_thr, 1, np.where(qd < -qd_thr, -1, 0))
    idx = np.flatnonzero(s)
    if idx.size < 2:
        return np.zeros(0, int), np.zeros(0)
    ss = s[idx]
    ch = np.flatnonzero(ss[1:] != ss[:-1]) + 1
    return idx[ch], ss[ch].astype(float)


def _after_reversals(sig: LogSignals, shape) -> np.ndarray:
    """One column: s_r shape(i, j) on every stretch [i, j) from a reversal i (new direction s_r) on."""
    idx, new = reversals(sig)
    col = np.zeros(sig.n)
    bounds = list(idx) + [sig.n]
    for k, i in enumerate(idx):
        j = bounds[k + 1]
        col[i:j] = new[k] * shape(i, j)
    return col[:, None]


class Backlash(Effect):
    name = "backlash"
    meaning = "a decaying transient after every velocity reversal (backlash in the reducer)"
    coef_names = ("A",)
    settings = ("tau",)
    units = {"A": "N·m", "tau": "s"}

    def columns(self, sig, nl, model):
        def shape(i, j):
            x = (sig.time[i:j] - sig.time[i]) / nl["tau"]
            return np.exp(-x) if nl.get("shape", "decay") == "decay" else x * np.exp(1.0 - np.minimum(x, 50.0))

        return _after_reversals(sig, shape)


class StribeckRise(Effect):
    name = "stribeck"
    meaning = "friction rising above Coulomb at low speed (Stribeck), on a Coulomb + viscous model"
    coef_names = ("dF",)
    settings = ("vs", "delta")
    units = {"dF": "N·m", "vs": "rad/s", "delta": "-"}

    def columns(self, sig, nl, model):
        return stribeck_column(sig.qd, nl["vs"], nl["delta"])[:, None]


class PreSliding(Effect):
    name = "presliding"
    meaning = ("pre-sliding friction: after a reversal friction builds up over a small displacement "
               "(Dahl-like), not at once")
    coef_names = ("A",)
    settings = ("x0",)
    units = {"A": "N·m", "x0": "rad"}

    def columns(self, sig, nl, model):
        """s_r exp(-|q - q_r| / x0) from each reversal r (position q_r, new direction s_r) on."""
        return _after_reversals(sig, lambda i, j: np.exp(-np.abs(sig.q[i:j] - sig.q[i]) / nl["x0"]))


class Coupling(Effect):
    """Torque from the motion of the other axes of a multi-body robot, without a robot model:
    per other moving axis j, gravity on the relative angle (cos and sin of q + q_j), gravity of
    the links it moves (cos, sin of q_j) and inertial coupling (qdd_j)."""

    name = "coupling"
    meaning = "torque from the other axes' motion (multi-body gravity and inertia, no robot model)"
    coef_names = ()
    parts = ("cos_sum", "sin_sum", "cos", "sin", "qdd")

    @staticmethod
    def axes(nl: dict) -> list[int]:
        return [int(a) for a in str(nl["axes"]).split(",") if a]

    def coef_keys(self, nl):
        return tuple(f"{p}_A{a}" for a in self.axes(nl) for p in self.parts)

    def from_params(self, d):
        coefs = {k: float(v) for k, v in d.items() if any(k.startswith(p + "_A") for p in self.parts)}
        axes = sorted({int(k.rsplit("_A", 1)[1]) for k in coefs})
        return {"axes": ",".join(map(str, axes))}, coefs

    def columns(self, sig, nl, model):
        others = sig.others or {}
        cols = []
        for a in self.axes(nl):
            if a not in others:
                from kukaid.errors import ParamFileError

                raise ParamFileError(f"coupling: the log has no axis A{a} (its motion is part of the model)")
            qj, qddj = others[a]
            cols += [np.cos(sig.q_raw + qj), np.sin(sig.q_raw + qj), np.cos(qj), np.sin(qj), qddj]
        return np.column_stack(cols)

    def describe(self, nl, coefs, std, model):
        d: dict[str, Any] = {"model": TAG}
        d.update({k: float(v) for k, v in coefs.items()})
        d["std"] = {k: float(std.get(k, math.nan)) for k in coefs}
        return d


#: every effect term by name, in the diagnosis' order
EFFECTS: dict[str, Effect] = {e.name: e for e in (GravitySine(), TorqueOffset(), PositionRipple(), ThermalDrift(),
                                                  LoadDependentFriction(), Backlash(), StribeckRise(), PreSliding(),
                                                  Coupling())}


def unit_of(effect: str, key: str, stored: dict | None = None, prismatic: bool = False) -> str:
    """The unit of the number ``key`` of the effect ``effect`` (the file's ``unit`` text for a thermal drift's
    ``c``, a coupling's by its part: the other axis's gravity and inertia), "" when it has none; on a
    prismatic joint in N and m."""
    e = EFFECTS.get(effect)
    if e is None:
        return ""
    u = e.units.get(key, "")
    if effect == "thermal_drift" and key == "c" and isinstance((stored or {}).get("unit"), str):
        u = stored["unit"]
    elif effect == "coupling":
        u = "kg·m²" if key.startswith("qdd_") else "N·m" if key.startswith(("cos", "sin")) else ""
    if prismatic:
        u = u.replace("kg·m²", "kg").replace("N·m", "N").replace("rad", "m")
    return u


#: effect name -> names of its linear coefficients (``coupling``: one per other axis and part)
COEFFICIENTS: dict[str, tuple[str, ...]] = {n: e.coef_names for n, e in EFFECTS.items()}
NAMES: tuple[str, ...] = tuple(EFFECTS)
