"""The library of candidate physical effects a diagnosis tests the residual against.

Every candidate is a small parametric torque term with a meaning.  For fixed values of its
nonlinear parameters (the ripple order n, the backlash time constant, the drift coordinate) the
term is linear in its coefficients, so a candidate offers a small grid of ``options`` and, per
option, regressor ``columns`` on a log's full sample grid (unfiltered; the workflow filters them
like the torque).  The names are fixed: tests and users rely on them.

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
                           or "decay" exp(-x); shape and tau searched
=========================  ==================================================================
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    from kukaid.diagnose.model import DiagModel
    from kukaid.diagnose.signals import LogSignals

from kukaid.models.effects import COEFFICIENTS, NAMES, TAG  # noqa: F401  (the names the parameter file knows)


def _sign(sig: "LogSignals") -> np.ndarray:
    return np.sign(sig.qd)


class Candidate:
    """Base class: one named effect."""

    name: str = ""
    meaning: str = ""
    coef_names: tuple[str, ...] = ()
    #: a candidate stored as a native parameter of the rigid body ("My", "offset") or None
    native: str | None = None

    def applies(self, sigs: Sequence["LogSignals"], model: "DiagModel") -> tuple[bool, str]:
        return True, ""

    def options(self, sigs: Sequence["LogSignals"], model: "DiagModel") -> list[dict]:
        return [{}]

    def n_effective(self, sigs: Sequence["LogSignals"], options: list[dict]) -> float:
        """Effective number of independent options (for the multiple-testing correction)."""
        return 1.0

    def columns(self, sig: "LogSignals", nl: dict, model: "DiagModel") -> np.ndarray:
        raise NotImplementedError

    def coordinate(self, sig: "LogSignals", nl: dict) -> tuple[np.ndarray, str]:
        """The coordinate the effect lives on (for plots): values on the full grid and a label."""
        return sig.q, "position q (rad)"

    def describe(self, nl: dict, coefs: dict[str, float], std: dict[str, float],
                 model: "DiagModel") -> dict[str, Any]:
        """The effect's parameters for the parameter file and the report (JSON-able)."""
        d: dict[str, Any] = {"model": TAG}
        d.update({k: _num(v) for k, v in nl.items()})
        d.update({k: float(v) for k, v in coefs.items()})
        d["std"] = {k: float(std.get(k, math.nan)) for k in coefs}
        return d

    def size(self, nl: dict, coefs: dict[str, float], sigs: Sequence["LogSignals"], model: "DiagModel") -> float:
        """The effect's size, N·m: its amplitude or peak, as the simulator documents sizes
        (:data:`kukaid.sim.effects.EFFECTS`), not only the part of it the base model cannot mimic."""
        return abs(float(coefs[self.coef_names[0]]))

    def freeze(self, nl: dict, model: "DiagModel") -> dict:
        """Settings to store when the effect joins the model (fix what depends on the model)."""
        return nl

    def from_params(self, d: dict) -> tuple[dict, dict[str, float]]:
        """(nonlinear settings, coefficients) of a stored effect."""
        coefs = {k: float(d[k]) for k in self.coef_names}
        nl = {k: v for k, v in d.items() if k not in self.coef_names and k not in ("model", "std")
              and not k.startswith("_") and k not in self.derived}
        return nl, coefs

    derived: tuple[str, ...] = ()


def _num(v: Any) -> Any:
    if isinstance(v, (np.floating, np.integer)):
        return v.item()
    return v


class GravitySine(Candidate):
    name = "gravity_sine"
    meaning = "My sin(q): the centre of mass is off the model's axis"
    coef_names = ("My",)
    native = "My"

    def applies(self, sigs, model):
        if any(s.joint != "revolute" for s in sigs):
            return False, "prismatic axis: no gravity angle"
        if "My" in model.lin:
            return False, "the model already has My"
        return True, ""

    def columns(self, sig, nl, model):
        return np.sin(sig.q)[:, None]


class TorqueOffset(Candidate):
    name = "torque_offset"
    meaning = "a constant torque while moving (also asymmetric Coulomb friction)"
    coef_names = ("offset",)
    native = "offset"

    def applies(self, sigs, model):
        if "offset" in model.lin:
            return False, "the model already has an offset"
        return True, ""

    def columns(self, sig, nl, model):
        return np.ones((sig.n, 1))


class PositionRipple(Candidate):
    name = "position_ripple"
    meaning = "A sin(n q + phi): gear or cogging ripple with position"
    coef_names = ("a", "b")
    derived = ("A", "phi")

    def _range(self, sigs):
        q = np.concatenate([s.q[s.rows] for s in sigs if s.rows.size])
        speed = np.concatenate([np.abs(s.qd[s.rows]) for s in sigs if s.rows.size])
        R = float(np.ptp(q)) if q.size else 0.0
        v = float(np.percentile(speed, 75)) if speed.size else 0.0
        return R, v

    def _limits(self, sigs):
        R, v = self._range(sigs)
        fc = min(s.cutoff if s.cutoff > 0 else 0.25 * s.fs for s in sigs)
        # at least one full period over the range (the periodogram's resolution: a slower "ripple" is
        # a smooth function of q that gravity and offset terms mimic); above 1.5/rad on a revolute
        # axis (n = 1 is gravity)
        n_lo = max(2 * math.pi / R, 1.5 if sigs[0].joint == "revolute" else 0.0) if R > 0 else math.inf
        n_hi = 2 * math.pi * 0.8 * fc / v if v > 0 else 0.0
        return R, n_lo, n_hi

    def lowest_order(self, sigs) -> float:
        """The lowest ripple order (1/rad) the logs resolve."""
        return self._limits(sigs)[1]

    def applies(self, sigs, model):
        if "position_ripple" in model.effect_names:
            return False, "already in the model"
        R, lo, hi = self._limits(sigs)
        if not hi > lo:
            return False, "position range or filter bandwidth too small to resolve a ripple"
        return True, ""

    def options(self, sigs, model):
        R, lo, hi = self._limits(sigs)
        step = 0.25 * 2 * math.pi / R
        ns = np.arange(lo, hi + step, step)
        if ns.size > 2000:
            ns = np.geomspace(lo, hi, 2000)
        return [{"n": float(n)} for n in ns]

    def n_effective(self, sigs, options):
        R, lo, hi = self._limits(sigs)
        return max(1.0, (hi - lo) * R / (2 * math.pi))

    def columns(self, sig, nl, model):
        n = nl["n"]
        return np.column_stack([np.sin(n * sig.q), np.cos(n * sig.q)])

    def coordinate(self, sig, nl):
        return np.mod(nl["n"] * sig.q, 2 * math.pi), f"ripple phase n q mod 2 pi (n = {nl['n']:.3g})"

    def size(self, nl, coefs, sigs, model):
        return float(math.hypot(coefs["a"], coefs["b"]))

    def describe(self, nl, coefs, std, model):
        d = super().describe(nl, coefs, std, model)
        a, b = coefs["a"], coefs["b"]
        d["A"] = float(math.hypot(a, b))
        d["phi"] = float(math.atan2(b, a))
        return d


def dissipated_energy(sig: "LogSignals", model: "DiagModel", friction: dict | None = None) -> np.ndarray:
    """Friction energy dissipated since the log started, J: integral of |F(qd) qd| dt."""
    p = np.abs(model.friction_torque(sig, friction) * sig.qd)
    dt = np.diff(sig.time, prepend=sig.time[0])
    return np.cumsum(p * dt)


class ThermalDrift(Candidate):
    name = "thermal_drift"
    meaning = "friction changing over the run (temperature, elapsed time or dissipated energy)"
    coef_names = ("c",)

    def _coords(self, sigs):
        out = []
        if all(s.temp is not None and np.ptp(s.temp) > 0.05 for s in sigs):
            out.append("temperature")
        out += ["time", "energy"]
        return out

    def applies(self, sigs, model):
        if "thermal_drift" in model.effect_names:
            return False, "already in the model"
        return True, ""

    def options(self, sigs, model):
        return [{"coordinate": c, "form": f} for c in self._coords(sigs) for f in ("coulomb", "friction")]

    def n_effective(self, sigs, options):
        return float(len(options))

    def x(self, sig, coordinate, model, friction=None):
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
            return (x * _sign(sig))[:, None]
        return (x * model.friction_torque(sig, fr))[:, None]

    def coordinate(self, sig, nl):
        lab = {"temperature": "temperature (degC)", "time": "elapsed time (s)", "energy": "dissipated energy (J)"}
        if nl["coordinate"] == "temperature" and sig.temp is not None:
            return sig.temp, lab["temperature"]
        if nl["coordinate"] == "energy":
            return sig.elapsed, "elapsed time (s)"
        return sig.elapsed, lab["time"]

    def size(self, nl, coefs, sigs, model):
        """The change of the friction over the logs (the largest change of the drift coordinate)."""
        fr = nl.get("friction_ref")
        out = 0.0
        for s in sigs:
            x = self.x(s, nl["coordinate"], model, fr)[s.rows]
            level = 1.0 if nl["form"] == "coulomb" else float(np.mean(np.abs(model.friction_torque(s, fr)[s.rows])))
            out = max(out, abs(coefs["c"]) * float(np.ptp(x)) * level if x.size else 0.0)
        return out

    def describe(self, nl, coefs, std, model):
        d = super().describe(nl, coefs, std, model)
        unit = {"temperature": "degC", "time": "s", "energy": "J"}[nl["coordinate"]]
        d["unit"] = (f"N*m per {unit} of Coulomb friction" if nl["form"] == "coulomb"
                     else f"fraction of the friction per {unit}")
        return d

    derived = ("unit",)


class LoadDependentFriction(Candidate):
    name = "load_dependent_friction"
    meaning = "Coulomb friction growing with the gravity load |Mx cos q|"
    coef_names = ("Fc_load",)
    derived = ("mu",)

    def applies(self, sigs, model):
        if any(s.joint != "revolute" for s in sigs):
            return False, "prismatic axis: no gravity load"
        if abs(model.lin.get("Mx", 0.0)) <= 0:
            return False, "the model has no gravity load (Mx = 0)"
        if "load_dependent_friction" in model.effect_names:
            return False, "already in the model"
        return True, ""

    def columns(self, sig, nl, model):
        return (np.abs(np.cos(sig.q)) * _sign(sig))[:, None]

    def coordinate(self, sig, nl):
        return np.abs(np.cos(sig.q)), "gravity load |cos q|"

    def describe(self, nl, coefs, std, model):
        d = super().describe(nl, coefs, std, model)
        mx = abs(model.lin.get("Mx", 0.0))
        d["mu"] = float(coefs["Fc_load"] / mx) if mx > 0 else math.nan
        return d


def reversals(sig: "LogSignals", qd_thr: float | None = None) -> tuple[np.ndarray, np.ndarray]:
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


class Backlash(Candidate):
    name = "backlash"
    meaning = "a decaying transient after every velocity reversal (backlash in the reducer)"
    coef_names = ("A",)
    taus = (0.02, 0.04, 0.07, 0.1, 0.14, 0.2, 0.3, 0.5)
    shapes = ("pulse", "decay")

    def applies(self, sigs, model):
        if "backlash" in model.effect_names:
            return False, "already in the model"
        if sum(reversals(s)[0].size for s in sigs) < 2:
            return False, "fewer than two velocity reversals"
        return True, ""

    def options(self, sigs, model):
        dt = min(1.0 / s.fs for s in sigs)
        return [{"shape": sh, "tau": t} for sh in self.shapes for t in self.taus if t >= 0.5 * dt]

    def n_effective(self, sigs, options):
        return max(1.0, len(options) / 3.0)

    def columns(self, sig, nl, model):
        tau = nl["tau"]
        idx, new = reversals(sig)
        col = np.zeros(sig.n)
        bounds = list(idx) + [sig.n]
        for k, i in enumerate(idx):
            j = bounds[k + 1]
            x = (sig.time[i:j] - sig.time[i]) / tau
            shape = np.exp(-x) if nl.get("shape", "decay") == "decay" else x * np.exp(1.0 - np.minimum(x, 50.0))
            col[i:j] = new[k] * shape
        return col[:, None]

    def coordinate(self, sig, nl):
        idx, _ = reversals(sig)
        since = np.full(sig.n, np.nan)
        bounds = list(idx) + [sig.n]
        for k, i in enumerate(idx):
            since[i:bounds[k + 1]] = sig.time[i:bounds[k + 1]] - sig.time[i]
        return since, "time since the last reversal (s)"


CANDIDATES: dict[str, Candidate] = {c.name: c for c in (GravitySine(), TorqueOffset(), PositionRipple(),
                                                        ThermalDrift(), LoadDependentFriction(), Backlash())}
assert {n: c.coef_names for n, c in CANDIDATES.items()} == COEFFICIENTS, "models.effects and the candidates disagree"


def get(name: str) -> Candidate:
    """The candidate called ``name`` (KeyError listing the names otherwise)."""
    try:
        return CANDIDATES[name]
    except KeyError:
        raise KeyError(f"unknown effect '{name}'; known: {', '.join(NAMES)}") from None
