"""The model a diagnosis compares with the data and refits: rigid body + friction + effects.

Torque prediction on a log's full sample grid (N·m):

    Izz qdd + Mx cos q [+ My sin q] [+ offset] + F(qd) + sum of effect terms

with Stribeck friction F = (Fc (1 - E) + Fs E) sign(qd) + Fv qd, E = exp(-(|qd|/vs)^delta) (or
Coulomb + viscous).  Every parameter except vs and delta (and the effects' nonlinear settings)
enters linearly, so the joint refit is a variable projection: an outer bounded least-squares over
(vs, delta), an inner linear least-squares over everything else.  Residuals are formed after the
comparison filter (see :mod:`kukaid.diagnose.signals`).
"""
from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from kukaid.diagnose import candidates as C
from kukaid.diagnose.signals import LogSignals
from kukaid.errors import FitError, ParamFileError
from kukaid.jsonfile import jsonable

VS_BOUNDS = (1e-4, 2.0)
DELTA_BOUNDS = (0.5, 2.0)


@dataclass
class EffectTerm:
    """An effect in the model: candidate name, nonlinear settings, coefficients."""

    name: str
    nl: dict
    coefs: dict[str, float]

    def key(self, c: str) -> str:
        return f"{self.name}.{c}"


@dataclass
class DiagModel:
    """Parameters of the compared model (SI)."""

    friction_kind: str
    lin: dict[str, float]                   # linear base parameters: Fc, Fs, Fv, Izz, Mx, My, offset
    vs: float = 0.04
    delta: float = 1.0
    effects: list[EffectTerm] = field(default_factory=list)
    std: dict[str, float] = field(default_factory=dict)
    ignored_effects: list[str] = field(default_factory=list)

    # -- construction -----------------------------------------------------------------------
    @classmethod
    def from_params(cls, d: dict, joint: str = "revolute") -> "DiagModel":
        """The model of a (validated) ``kukaid.params/1`` dictionary."""
        fr = d.get("friction") or {}
        kind = fr.get("model", "stribeck")
        lin: dict[str, float] = {"Fc": float(fr.get("Fc", 0.0)), "Fv": float(fr.get("Fv", 0.0))}
        vs, delta = 0.04, 1.0
        if kind == "stribeck":
            lin["Fs"] = float(fr.get("Fs", lin["Fc"]))
            vs = float(np.clip(fr.get("vs", 0.04), *VS_BOUNDS))
            delta = float(np.clip(fr.get("delta", 1.0), *DELTA_BOUNDS))
        elif kind != "coulomb-viscous":
            raise ParamFileError(f"friction.model '{kind}' is not supported by the diagnosis")
        inert = d.get("inertial") or {}
        lin["Izz"] = float(inert.get("Izz", 0.0))
        if joint == "revolute":
            lin["Mx"] = float(inert.get("Mx", 0.0))
            if "My" in inert:
                lin["My"] = float(inert["My"])
        if "offset" in d:
            lin["offset"] = float(d["offset"])
        m = cls(kind, lin, vs, delta)
        for name, e in (d.get("effects") or {}).items():
            if not isinstance(e, dict) or e.get("model") != C.TAG or name not in C.CANDIDATES:
                m.ignored_effects.append(name)
                continue
            cand = C.get(name)
            if cand.native:
                lin.setdefault(cand.native, float(e.get(cand.native, 0.0)))
                continue
            nl, coefs = cand.from_params(e)
            m.effects.append(EffectTerm(name, nl, coefs))
        return m

    def copy(self) -> "DiagModel":
        return copy.deepcopy(self)

    @property
    def effect_names(self) -> list[str]:
        return [e.name for e in self.effects]

    def with_effect(self, name: str, nl: dict, coefs: dict[str, float]) -> "DiagModel":
        """A copy with the effect added (native effects become base parameters)."""
        m = self.copy()
        cand = C.get(name)
        if cand.native:
            m.lin[cand.native] = float(coefs[cand.coef_names[0]])
        else:
            m.effects.append(EffectTerm(name, cand.freeze(dict(nl), self), dict(coefs)))
        return m

    def without(self, name: str) -> "DiagModel":
        """A copy without the effect ``name``."""
        m = self.copy()
        native = C.get(name).native
        if native:
            m.lin.pop(native, None)
        m.effects = [e for e in m.effects if e.name != name]
        return m

    def friction_dict(self) -> dict[str, Any]:
        """The friction parameters as the parameter file's ``friction`` object."""
        d: dict[str, Any] = {"model": self.friction_kind, "Fc": self.lin["Fc"], "Fv": self.lin["Fv"]}
        if self.friction_kind == "stribeck":
            d.update(Fs=self.lin["Fs"], vs=self.vs, delta=self.delta)
        return d

    # -- evaluation on the full grid --------------------------------------------------------
    def friction_torque(self, sig: LogSignals, friction: dict | None = None) -> np.ndarray:
        """Sliding friction F(qd) on the full grid, N·m (``friction``: other parameters to use)."""
        s = np.sign(sig.qd)
        if friction is not None:
            from kukaid.models.friction import friction_from_dict

            return friction_from_dict(friction)(sig.qd)
        if self.friction_kind == "stribeck":
            E = np.exp(-((np.abs(sig.qd) / self.vs) ** self.delta))
            return (self.lin["Fc"] * (1 - E) + self.lin["Fs"] * E) * s + self.lin["Fv"] * sig.qd
        return self.lin["Fc"] * s + self.lin["Fv"] * sig.qd

    def base_columns(self, sig: LogSignals, vs: float | None = None,
                     delta: float | None = None) -> tuple[list[str], np.ndarray]:
        """Names and raw (unfiltered) columns of the linear base parameters."""
        vs = self.vs if vs is None else vs
        delta = self.delta if delta is None else delta
        s = np.sign(sig.qd)
        names, cols = [], []
        if self.friction_kind == "stribeck":
            E = np.exp(-((np.abs(sig.qd) / vs) ** delta))
            names += ["Fc", "Fs"]
            cols += [s * (1 - E), s * E]
        else:
            names.append("Fc")
            cols.append(s)
        names.append("Fv")
        cols.append(sig.qd if sig.qd_lin is None else sig.qd_lin)
        names.append("Izz")
        cols.append(sig.qdd if sig.qdd_lin is None else sig.qdd_lin)
        if "Mx" in self.lin:
            names.append("Mx")
            cols.append(np.cos(sig.q_raw))
        if "My" in self.lin:
            names.append("My")
            cols.append(np.sin(sig.q_raw))
        if "offset" in self.lin:
            names.append("offset")
            cols.append(np.ones(sig.n))
        return names, np.column_stack(cols)

    def effect_columns(self, sig: LogSignals) -> tuple[list[str], np.ndarray]:
        names, cols = [], []
        for e in self.effects:
            Z = C.get(e.name).columns(sig, e.nl, self)
            names += [e.key(c) for c in C.get(e.name).coef_names]
            cols.append(Z)
        if not cols:
            return [], np.zeros((sig.n, 0))
        return names, np.column_stack(cols)

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
        nb, Xb = self.base_columns(sig)
        ne, Xe = self.effect_columns(sig)
        names = nb + ne
        X = np.column_stack([Xb, Xe]) if ne else Xb
        F = sig.filtw  # noqa: N806
        J = np.column_stack([F(X[:, k])[sig.rows] for k in range(X.shape[1])])
        if self.friction_kind == "stribeck":
            extra = []
            for p in ("vs", "delta"):
                h = 1e-4 * max(abs(getattr(self, p)), 1e-3)
                kw = {p: getattr(self, p) + h}
                _, Xp = self.base_columns(sig, **kw)
                d = (Xp[:, :2] - Xb[:, :2]) @ np.array([self.lin["Fc"], self.lin["Fs"]]) / h
                extra.append(F(d)[sig.rows])
            J = np.column_stack([J] + extra)
            names = names + ["vs", "delta"]
        return names, J

    # -- refit ------------------------------------------------------------------------------
    def refit(self, sigs: Sequence[LogSignals]) -> "DiagModel":
        """Refit every parameter jointly; returns a copy.

        Outer bounded least squares over the nonlinear parameters (Stribeck vs and delta, the
        ripple order n of a position_ripple already in the model, within +-0.5 of its value),
        inner linear least squares over all the others (variable projection).
        """
        from scipy.optimize import least_squares

        m = self.copy()
        y = np.concatenate([s.filtw(s.tau_raw)[s.rows] for s in sigs])
        if y.size == 0:
            raise FitError("no dynamic-mode samples to compare (is the axis moving?)")
        free = [k for k, e in enumerate(m.effects) if "n" in e.nl]  # effects with a continuous order

        def eff_block(s: LogSignals, ns: Sequence[float]) -> tuple[list[str], np.ndarray]:
            names, cols = [], []
            for k, e in enumerate(m.effects):
                nl = dict(e.nl)
                if k in free:
                    nl["n"] = ns[free.index(k)]
                Z = C.get(e.name).columns(s, nl, m)
                names += [e.key(c) for c in C.get(e.name).coef_names]
                cols += [s.filtw(Z[:, j])[s.rows] for j in range(Z.shape[1])]
            return names, (np.column_stack(cols) if cols else np.zeros((s.rows.size, 0)))

        fixed_eff = None if free else [eff_block(s, [])[1] for s in sigs]
        # filtered base columns that do not depend on (vs, delta): computed once
        n_fr = 2 if m.friction_kind == "stribeck" else 0
        fixed_base = []
        for s in sigs:
            nb0, Xb0 = m.base_columns(s)
            fixed_base.append(np.column_stack([s.filtw(Xb0[:, k]) for k in range(n_fr, Xb0.shape[1])])[s.rows])
        ne = eff_block(sigs[0], [m.effects[k].nl["n"] for k in free])[0] if m.effects else []
        stribeck = m.friction_kind == "stribeck"
        cache: dict = {}

        def solve(p: np.ndarray):
            key = tuple(np.round(p, 12))
            if key in cache:
                return cache[key]
            vs, delta = (math.exp(p[0]), p[1]) if stribeck else (m.vs, m.delta)
            ns = list(p[2:]) if stribeck else list(p)
            blocks = []
            for i, s in enumerate(sigs):
                if n_fr:
                    nb, Xb = m.base_columns(s, vs, delta)
                    Xv = np.column_stack([s.filtw(Xb[:, k]) for k in range(n_fr)])[s.rows]
                    Xf = np.column_stack([Xv, fixed_base[i]])
                else:
                    nb, _ = m.base_columns(s)
                    Xf = fixed_base[i]
                E = fixed_eff[i] if fixed_eff is not None else eff_block(s, ns)[1]
                blocks.append(np.column_stack([Xf, E]))
            X = np.vstack(blocks)
            scale = np.linalg.norm(X, axis=0)
            scale[scale == 0] = 1.0
            theta, *_ = np.linalg.lstsq(X / scale, y, rcond=None)
            theta = theta / scale
            out = (nb + ne, theta, y - X @ theta)
            cache[key] = out
            return out

        p0, lb, ub = [], [], []
        if stribeck:
            p0 += [math.log(m.vs), m.delta]
            lb += [math.log(VS_BOUNDS[0]), DELTA_BOUNDS[0]]
            ub += [math.log(VS_BOUNDS[1]), DELTA_BOUNDS[1]]
        n_lo = C.get("position_ripple").lowest_order(sigs) if free else 0.0
        for k in free:
            n0 = float(m.effects[k].nl["n"])
            p0.append(n0)
            lb.append(max(n0 - 0.5, min(n0, n_lo)))  # not below the search's lowest order
            ub.append(n0 + 0.5)
        if p0:
            lb_a, ub_a = np.array(lb), np.array(ub)
            sol = least_squares(lambda p: solve(p)[2], np.clip(np.array(p0), lb_a + 1e-9, ub_a - 1e-9),
                                bounds=(lb_a, ub_a), diff_step=1e-4, xtol=1e-7, ftol=1e-9, max_nfev=80)
            x = sol.x
        else:
            x = np.zeros(0)
        if stribeck:
            m.vs, m.delta = math.exp(x[0]), float(x[1])
        for j, k in enumerate(free):
            m.effects[k].nl["n"] = float(x[(2 if stribeck else 0) + j])
        names, theta, _ = solve(x)
        m.set_coefs(names, theta)
        return m

    # -- output -----------------------------------------------------------------------------
    def to_params(self, base: dict, added: Sequence[str] = ()) -> dict:
        """A ``kukaid.params/1`` dictionary: ``base`` with this model's values and effects.

        ``added`` names the effects the diagnosis added (native ones, My and offset, are stored in
        the rigid body and recorded in ``effects`` with ``stored_as``)."""
        d = copy.deepcopy(base)
        fr = dict(d.get("friction") or {})
        fr["model"] = self.friction_kind
        fr["Fc"] = max(self.lin["Fc"], 0.0)
        fr["Fv"] = max(self.lin["Fv"], 0.0)
        if self.friction_kind == "stribeck":
            # the refit leaves Fs free; Fs below Fc (data with no Stribeck rise) is stored as Fs = Fc,
            # the parameter file's (and the fit's) Stribeck model having Fs >= Fc
            fr.update(Fs=max(self.lin["Fs"], fr["Fc"]), vs=self.vs, delta=self.delta)
        d["friction"] = fr
        inert = dict(d.get("inertial") or {})
        inert["Izz"] = max(self.lin["Izz"], 1e-12)
        for k in ("Mx", "My"):
            if k in self.lin:
                inert[k] = self.lin[k]
        d["inertial"] = inert
        if "offset" in self.lin:
            d["offset"] = self.lin["offset"]
        unc = dict(d.get("uncertainty") or {})
        for k, v in self.std.items():
            if "." not in k and math.isfinite(v):
                unc[k] = v
        d["uncertainty"] = unc
        effects = {k: v for k, v in (d.get("effects") or {}).items()}
        for name in C.NAMES:
            cand = C.get(name)
            if cand.native and cand.native in self.lin and (name in effects or name in added):
                effects[name] = {"model": C.TAG, cand.native: self.lin[cand.native],
                                 "std": {cand.native: self.std.get(cand.native, math.nan)},
                                 "stored_as": "inertial.My" if cand.native == "My" else "offset"}
        for e in self.effects:
            std = {c: self.std.get(e.key(c), math.nan) for c in e.coefs}
            effects[e.name] = C.get(e.name).describe(e.nl, e.coefs, std, self)
        d["effects"] = jsonable(effects)
        return d


def effects_torque(params: dict, time: np.ndarray, q: np.ndarray, qd: np.ndarray,
                   temp: np.ndarray | None = None, joint: str = "revolute") -> np.ndarray:
    """Torque of the diagnosed effects stored in ``params["effects"]`` (N·m), for other stages.

    Only the effects not already held by the rigid body are included (gravity_sine is
    ``inertial.My`` and torque_offset is ``offset``; :meth:`kukaid.models.joint.AxisModel.
    predict_dynamic` has those).  ``time`` s, ``q`` rad, ``qd`` rad/s (a smooth velocity),
    ``temp`` °C (for a temperature-driven thermal_drift).
    """
    t = np.asarray(time, dtype=float)
    q = np.asarray(q, dtype=float)
    qd = np.asarray(qd, dtype=float)
    m = DiagModel.from_params(params, joint)
    if not m.effects:
        return np.zeros(t.size)
    sig = LogSignals(t, q, np.zeros(t.size), q, qd, np.gradient(qd, t) if t.size > 1 else np.zeros(t.size),
                     None if temp is None else np.asarray(temp, dtype=float), np.arange(t.size), joint,
                     1.0 / float(np.median(np.diff(t))) if t.size > 1 else 1.0, 0.0, 0, "signals")
    ne, Xe = m.effect_columns(sig)
    return Xe @ m.coef_vector(ne)
