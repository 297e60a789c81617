"""The search side of the diagnosis: which effects to try, with which options, and when one is plausible.

The effect terms themselves (names, coefficients, regressor columns, how they are stored) are
the joint-torque model's (:mod:`kukaid.models.effects`).  Each candidate here is such an effect
plus what the search needs: whether it applies to the logs and the model (``applies``), the grid
of nonlinear settings to try (``options``) and its effective size for the multiple-testing
correction (``n_effective``), the coordinate it lives on (for plots), its size and the
plausibility rules a refitted model with it must pass (``implausible``).
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING, Sequence

import numpy as np

from kukaid.models import effects as E
from kukaid.models.effects import NAMES, reversals

if TYPE_CHECKING:  # pragma: no cover
    from kukaid.models.signals import LogSignals
    from kukaid.models.torque import JointTorqueModel as Model


class Candidate(E.Effect):
    """Base class: the search side of one named effect."""

    def applies(self, sigs: Sequence["LogSignals"], model: "Model") -> tuple[bool, str]:
        return True, ""

    def options(self, sigs: Sequence["LogSignals"], model: "Model") -> list[dict]:
        return [{}]

    def n_effective(self, sigs: Sequence["LogSignals"], options: list[dict]) -> float:
        """Effective number of independent options (for the multiple-testing correction)."""
        return 1.0

    def coordinate(self, sig: "LogSignals", nl: dict) -> tuple[np.ndarray, str]:
        """The coordinate the effect lives on (for plots): values on the full grid and a label."""
        return sig.q, "position q (rad)"

    def size(self, nl: dict, coefs: dict[str, float], sigs: Sequence["LogSignals"], model: "Model") -> float:
        """The effect's size, N·m: its amplitude or peak, as the simulator documents sizes
        (:data:`kukaid.sim.effects.EFFECTS`), not only the part of it the base model cannot mimic."""
        return abs(float(coefs[self.coef_keys(nl)[0]]))

    #: the largest plausible size of the effect, as a share of the torque scale (99th percentile of |tau|)
    max_share: float = 0.5

    def term(self, model: "Model") -> tuple[dict, dict[str, float]] | None:
        """(settings, coefficients) of this effect in ``model``; None when it is not there."""
        if self.native:
            return ({}, {self.native: model.lin[self.native]}) if self.native in model.lin else None
        e = next((e for e in model.effects if e.name == self.name), None)
        return (dict(e.nl), dict(e.coefs)) if e else None

    def implausible(self, model: "Model", sigs: Sequence["LogSignals"], given: "Model") -> str:
        """Why the refitted ``model`` with this effect is not physical ("" when it is).

        Common rules: friction levels and the inertia stay positive; the effect's size is at most
        ``max_share`` of the torque scale; its coefficients do not cancel another parameter
        (|correlation| above :data:`CANCEL_CORR` in the refit's Jacobian).  Then the effect's own
        rule (:meth:`rule`)."""
        for k in ("Fc", "Fv", "Izz", "Fs"):
            if k in model.lin and model.lin[k] < 0 and given.lin.get(k, 0.0) >= 0:
                return f"with it the refit gives {k} = {model.lin[k]:.4g} (must be positive)"
        if "Izz" in model.lin and given.lin.get("Izz", 0.0) > 0 and model.lin["Izz"] < 1e-3 * given.lin["Izz"]:
            return f"with it the refit drives Izz to {model.lin['Izz']:.3g} (it takes over the inertia)"
        t = self.term(model)
        if t is None:
            return ""
        scale = torque_scale(sigs)
        size = self.size(*t, sigs, model)
        if scale > 0 and size > self.max_share * scale:
            return (f"size {size:.4g} is more than {self.max_share:g} x the torque scale {scale:.4g} "
                    "(99th percentile of |tau|)")
        worst, other = cancelling(model, sigs, self)
        if worst > CANCEL_CORR:
            return f"its coefficient cancels {other} (correlation {worst:.4f}): the two cannot be told apart"
        return self.rule(model, sigs, *t)

    def rule(self, model: "Model", sigs: Sequence["LogSignals"], nl: dict, coefs: dict[str, float]) -> str:
        """The effect's own size / time-scale rule ("" when it holds)."""
        return ""


#: |correlation| of two estimated coefficients above which they cancel each other
CANCEL_CORR = 0.999


def torque_scale(sigs: Sequence["LogSignals"]) -> float:
    """99th percentile of |tau| over the compared rows, N·m."""
    x = np.concatenate([np.abs(s.tau_raw[s.rows]) for s in sigs]) if sigs else np.zeros(0)
    return float(np.percentile(x, 99)) if x.size else 0.0


def cancelling(model: "Model", sigs: Sequence["LogSignals"], cand: "Candidate") -> tuple[float, str]:
    """Largest |correlation| between a coefficient of ``cand`` and any other parameter in the
    refit of ``model`` (from the filtered Jacobian on decimated rows), and that parameter's name."""
    from kukaid.diagnose.signals import decimation

    Js, names = [], []
    for s in sigs:
        names, J = model.design(s)
        Js.append(J[decimation(s)])
    J = np.vstack(Js)
    norms = np.linalg.norm(J, axis=0)
    norms[norms == 0] = 1.0
    cov = np.linalg.pinv((J / norms).T @ (J / norms))
    d = np.sqrt(np.clip(np.diag(cov), 1e-300, None))
    corr = cov / np.outer(d, d)
    mine = [i for i, n in enumerate(names) if n == cand.native or n.startswith(cand.name + ".")]
    worst, other = 0.0, ""
    for i in mine:
        for j, n in enumerate(names):
            if j not in mine and abs(corr[i, j]) > worst:
                worst, other = float(abs(corr[i, j])), n
    return worst, other


class GravitySine(Candidate, E.GravitySine):
    def applies(self, sigs, model):
        if any(s.joint != "revolute" for s in sigs):
            return False, "prismatic axis: no gravity angle"
        if "Mx" not in model.lin:
            return False, "the fit had no gravity (--gravity none)"
        if "My" in model.lin:
            return False, "the model already has My"
        return True, ""


class TorqueOffset(Candidate, E.TorqueOffset):
    def applies(self, sigs, model):
        if "offset" in model.lin:
            return False, "the model already has an offset"
        return True, ""


class PositionRipple(Candidate, E.PositionRipple):
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
        """The lowest ripple order (rad/rad: n in sin(n q)) the logs resolve."""
        return self._limits(sigs)[1]

    def applies(self, sigs, model):
        if "position_ripple" in model.effect_names:
            return False, "already in the model"
        R, lo, hi = self._limits(sigs)
        if not hi > lo:
            return False, "position range or filter bandwidth too small to resolve a ripple"
        return True, ""

    def order_step(self, sigs) -> float:
        """The order grid's step, rad/rad: a quarter period over the position range."""
        return 0.25 * 2 * math.pi / self._limits(sigs)[0]

    def options(self, sigs, model):
        R, lo, hi = self._limits(sigs)
        step = self.order_step(sigs)
        ns = np.arange(lo, hi + step, step)
        if ns.size > 2000:
            ns = np.geomspace(lo, hi, 2000)
        return [{"n": float(n)} for n in ns]

    def n_effective(self, sigs, options):
        R, lo, hi = self._limits(sigs)
        return max(1.0, (hi - lo) * R / (2 * math.pi))

    def coordinate(self, sig, nl):
        return np.mod(nl["n"] * sig.q, 2 * math.pi), f"ripple phase n q mod 2 pi (n = {nl['n']:.3g})"

    def size(self, nl, coefs, sigs, model):
        return float(math.hypot(coefs["a"], coefs["b"]))

    #: a ripple must repeat at least this often over the position range of the data; when other
    #: axes move (multi-body torque is a slow function of the positions) at least MIN_PERIODS_COUPLED
    MIN_PERIODS = 1.0
    MIN_PERIODS_COUPLED = 3.0

    def rule(self, model, sigs, nl, coefs):
        R, lo, _ = self._limits(sigs)
        periods = R * float(nl["n"]) / (2 * math.pi)
        unit = "m" if sigs[0].joint == "prismatic" else "rad"
        if float(nl["n"]) < lo + self.order_step(sigs):  # within a quarter period of the slowest searched
            plural = "" if round(periods, 2) == 1 else "s"
            return (f"order n = {nl['n']:.3g} is the lowest the {R:.3g} {unit} range resolves ({periods:.2g} period{plural}): "
                    "the best fit would be slower still, a smooth position-dependent torque, not a repeating ripple")
        coupled = any(s.others for s in sigs)
        need = self.MIN_PERIODS_COUPLED if coupled else self.MIN_PERIODS
        if periods < need:
            return (f"order n = {nl['n']:.3g} gives {periods:.2g} periods over the {R:.3g} {unit} range; a ripple needs "
                    f"at least {need:g}" + (" when other axes move (their torque is a slow function of the "
                                            "positions)" if coupled else ""))
        return ""


class ThermalDrift(Candidate, E.ThermalDrift):
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

    #: without a temperature channel, drift in time or energy needs logs at least this long, s
    MIN_DURATION = 60.0
    #: the friction may change by at most this share of its level over the logs
    MAX_CHANGE = 0.5

    def rule(self, model, sigs, nl, coefs):
        if nl["coordinate"] != "temperature":
            dur = sum(float(s.time[-1] - s.time[0]) for s in sigs)
            if dur < self.MIN_DURATION:
                return (f"no temperature channel and {dur:.3g} s of data: too short for a motor to heat "
                        f"(at least {self.MIN_DURATION:g} s)")
        level = float(np.mean(np.concatenate([np.abs(model.friction_torque(s, nl.get("friction_ref"))[s.rows])
                                              for s in sigs])))
        size = self.size(nl, coefs, sigs, model)
        if level > 0 and size > self.MAX_CHANGE * level:
            return (f"friction would change by {size:.3g}, more than {self.MAX_CHANGE:g} x its mean level "
                    f"{level:.3g} over the logs")
        return ""


class LoadDependentFriction(Candidate, E.LoadDependentFriction):
    def applies(self, sigs, model):
        if any(s.joint != "revolute" for s in sigs):
            return False, "prismatic axis: no gravity load"
        if abs(model.lin.get("Mx", 0.0)) <= 0:
            return False, "the model has no gravity load (Mx = 0)"
        if "load_dependent_friction" in model.effect_names:
            return False, "already in the model"
        return True, ""

    def coordinate(self, sig, nl):
        return np.abs(np.cos(sig.q)), "gravity load |cos q|"

    #: largest plausible friction coefficient Fc_load / |Mx| (steel on steel, dry: about 0.2-0.5)
    MAX_MU = 0.5

    def rule(self, model, sigs, nl, coefs):
        mx = abs(model.lin.get("Mx", 0.0))
        c = float(coefs["Fc_load"])
        if c <= 0:
            return f"Fc_load = {c:.3g}: friction would fall as the load grows"
        if mx > 0 and c / mx > self.MAX_MU:
            return f"mu = Fc_load / |Mx| = {c / mx:.3g} is above {self.MAX_MU:g}"
        return ""


class Backlash(Candidate, E.Backlash):
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

    def coordinate(self, sig, nl):
        idx, _ = reversals(sig)
        since = np.full(sig.n, np.nan)
        bounds = list(idx) + [sig.n]
        for k, i in enumerate(idx):
            since[i:bounds[k + 1]] = sig.time[i:bounds[k + 1]] - sig.time[i]
        return since, "time since the last reversal (s)"

    # no rule of its own: with one position sensor backlash and pre-sliding friction give the same
    # transient; the workflow then models it with the one that predicts better on held-out data and
    # says the mechanism is undetermined (kukaid.diagnose.ambiguity)


def separable_backlash(sigs: Sequence["LogSignals"]) -> bool:
    """Whether the logs can tell backlash from pre-sliding friction: only with a second, load-side
    position measurement (the play shows as motor motion without load motion).  The axis log
    holds one measured position per axis (``q``; ``q_cmd`` is the controller's setpoint, not a
    second sensor), so this is False for every log the toolkit reads today."""
    return all(getattr(s, "q_load", None) is not None for s in sigs)


class StribeckRise(Candidate, E.StribeckRise):
    def applies(self, sigs, model):
        if model.friction_kind != "coulomb-viscous":
            return False, "the model's friction is already Stribeck"
        if "stribeck" in model.effect_names:
            return False, "already in the model"
        return True, ""

    def options(self, sigs, model):
        v = np.concatenate([np.abs(s.qd[s.rows]) for s in sigs])
        lo, hi = (float(np.percentile(v, 2)), float(np.percentile(v, 60))) if v.size else (1e-3, 1.0)
        lo = max(lo, 1e-6)
        hi = max(hi, 2 * lo)
        return [{"vs": float(vs), "delta": d} for vs in np.geomspace(lo, hi, 10) for d in (1.0, 2.0)]

    def n_effective(self, sigs, options):
        return max(1.0, len(options) / 3.0)

    def coordinate(self, sig, nl):
        return sig.qd, "velocity (rad/s)"

    def rule(self, model, sigs, nl, coefs):
        if coefs["dF"] <= 0:
            return f"Fs - Fc = {coefs['dF']:.3g}: a Stribeck rise is positive"
        return ""


class PreSliding(Candidate, E.PreSliding):
    taus = Backlash.taus

    def applies(self, sigs, model):
        if "presliding" in model.effect_names:
            return False, "already in the model"
        if sum(reversals(s)[0].size for s in sigs) < 2:
            return False, "fewer than two velocity reversals"
        return True, ""

    def options(self, sigs, model):
        v = np.concatenate([np.abs(s.qd[s.rows]) for s in sigs])
        v50 = float(np.percentile(v, 50)) if v.size else 0.0
        dt = min(1.0 / s.fs for s in sigs)
        return [{"x0": float(v50 * t)} for t in self.taus if t >= 0.5 * dt and v50 > 0]

    def n_effective(self, sigs, options):
        return max(1.0, len(options) / 3.0)

    def coordinate(self, sig, nl):
        idx, _ = reversals(sig)
        since = np.full(sig.n, np.nan)
        bounds = list(idx) + [sig.n]
        for k, i in enumerate(idx):
            since[i:bounds[k + 1]] = np.abs(sig.q[i:bounds[k + 1]] - sig.q[i])
        return since, "displacement since the last reversal"

    #: the largest plausible pre-sliding displacement x0: rad on a revolute axis, m on a prismatic one
    #: (pre-sliding ends within a few degrees; a longer "transient" is a trend after each reversal)
    MAX_X0 = {"revolute": 0.05, "prismatic": 0.01}

    def rule(self, model, sigs, nl, coefs):
        lim = self.MAX_X0.get(sigs[0].joint if sigs else "revolute", 0.05)
        if nl["x0"] > lim:
            unit = "m" if sigs and sigs[0].joint == "prismatic" else "rad"
            return (f"x0 = {nl['x0']:.3g} {unit} is above {lim:g} {unit}: pre-sliding ends within a small "
                    "displacement, not over a long stretch of the motion")
        if coefs["A"] >= 0:
            return f"A = {coefs['A']:.3g}: pre-sliding friction lags the Coulomb step (A < 0)"
        lim = 2.5 * max(model.lin.get("Fs", 0.0), model.lin.get("Fc", 0.0))
        if -coefs["A"] > lim:
            return f"|A| = {-coefs['A']:.3g} above 2.5 x the friction level {lim / 2.5:.3g}"
        return ""


class Coupling(Candidate, E.Coupling):
    max_share = 2.0

    def applies(self, sigs, model):
        if "coupling" in model.effect_names:
            return False, "already in the model"
        axes = [tuple(sorted(s.others or {})) for s in sigs]
        if not axes[0] or any(a != axes[0] for a in axes):
            return False, "no other axis moves in every log"
        return True, ""

    def options(self, sigs, model):
        return [{"axes": ",".join(str(a) for a in sorted(sigs[0].others))}]

    def coordinate(self, sig, nl):
        a = self.axes(nl)[0]
        return (sig.others or {})[a][0], f"position of A{a} (rad)"

    def size(self, nl, coefs, sigs, model):
        """RMS of the coupling torque over the compared rows, N·m."""
        keys = self.coef_keys(nl)
        x = np.concatenate([(self.columns(s, nl, model) @ np.array([coefs[k] for k in keys]))[s.rows] for s in sigs])
        return float(np.sqrt(np.mean(x * x))) if x.size else 0.0


CANDIDATES: dict[str, Candidate] = {c.name: c for c in (GravitySine(), TorqueOffset(), PositionRipple(),
                                                        ThermalDrift(), LoadDependentFriction(), Backlash(),
                                                        StribeckRise(), PreSliding(), Coupling())}


def get(name: str) -> Candidate:
    """The candidate called ``name`` (KeyError listing the names otherwise)."""
    try:
        return CANDIDATES[name]
    except KeyError:
        raise KeyError(f"unknown effect '{name}'; known: {', '.join(NAMES)}") from None
