"""The evidence of one round of the diagnosis: the residual of a model, its Jacobian basis, and
the tests of candidate effects against them (HAC Wald tests on rows decimated to the filter
bandwidth, the model's Jacobian partialled out, Bonferroni over a candidate's grid)."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from kukaid.diagnose import candidates as C
from kukaid.diagnose import heldout
from kukaid.diagnose import selection as S
from kukaid.diagnose.signals import LogSignals, decimation
from kukaid.jsonfile import jsonable
from kukaid.models.torque import JointTorqueModel as Model


@dataclass
class CandidateTest:
    """The evidence for one candidate in one round."""

    name: str
    nl: dict
    wald: S.WaldResult
    n_effective: float
    p_candidate: float          # corrected for the candidate's own grid
    p_adjusted: float = 1.0     # also corrected for the number of candidates (Holm)
    effect_rms: float = 0.0     # RMS of the torque of the fitted term, N·m
    size: float = math.nan      # amplitude / peak of the effect in the final joint fit, N·m
    significant: bool = False
    reason: str = ""
    held_out: "heldout.HeldOut | None" = None
    #: when it stands for a mechanism the data cannot determine: {"candidates", "modelled_as",
    #: "held_out" (name -> held-out figures or why not), "settled_by"} (see :mod:`.ambiguity`)
    undetermined: dict | None = None
    #: the effects named before it when it was found (its evidence and held-out check are of that model)
    found_with: list[str] | None = None

    def evidence(self) -> dict[str, Any]:
        return jsonable({
            "test": "HAC Wald (Bartlett, Andrews bandwidth), decimated rows",
            "statistic": float(self.wald.stat), "dof": int(self.wald.dof),
            "p_value": float(self.p_adjusted), "p_uncorrected": float(self.wald.p_value),
            "n_effective_options": float(self.n_effective), "bandwidth": int(self.wald.bandwidth),
            "effect_rms": float(self.effect_rms), "size": float(self.size),
            "rss_share": float(self.wald.delta_rss / self.wald.rss) if self.wald.rss > 0 else 0.0,
            "held_out": self.held_out.to_json() if self.held_out is not None else None,
            "found_with": self.found_with,
        })


def rmse_of(model: Model, sigs: Sequence[LogSignals]) -> tuple[float, float]:
    """(RMSE, relative error ||tau - tau_hat|| / ||tau||) of the filtered comparison."""
    r = np.concatenate([model.residual(s) for s in sigs])
    y = np.concatenate([s.filtw(s.tau_raw)[s.rows] for s in sigs])
    ny = float(np.linalg.norm(y))
    return float(np.sqrt(np.mean(r * r))), (float(np.linalg.norm(r)) / ny if ny > 0 else math.nan)


class Round:
    """Residual, Jacobian basis and filtered candidate columns on the decimated rows."""

    def __init__(self, model: Model, sigs: Sequence[LogSignals]):
        self.model, self.sigs = model, sigs
        self.dec = [decimation(s) for s in sigs]
        self.r = np.concatenate([model.residual(s)[d] for s, d in zip(sigs, self.dec)])
        Js = []
        for s, d in zip(sigs, self.dec):
            self.names, J = model.design(s)
            Js.append(J[d])
        self.J = np.vstack(Js)
        self.U = S.basis(self.J)
        self.groups = np.concatenate([np.full(d.size, i) for i, d in enumerate(self.dec)])
        self.rp = S.partial_out(self.U, self.r[:, None])[:, 0]

    def columns(self, cand: C.Candidate, nl: dict, filtered: bool = True) -> np.ndarray:
        out = []
        for s, d in zip(self.sigs, self.dec):
            Z = cand.columns(s, nl, self.model)
            if filtered:
                Z = np.column_stack([s.filtw(Z[:, k]) for k in range(Z.shape[1])])
            out.append(Z[s.rows][d])
        return np.vstack(out)

    def delta_rss(self, Z: np.ndarray) -> float:
        Zp = S.partial_out(self.U, Z)
        b, *_ = np.linalg.lstsq(Zp, self.rp, rcond=None)
        f = Zp @ b
        return float(2 * f @ self.rp - f @ f)

    #: the prescan of a long option grid uses at most this many (evenly spaced) decimated rows
    PRESCAN_ROWS = 20000

    def prescan(self, cand: C.Candidate, opts: list[dict]) -> np.ndarray:
        """Residual sum of squares each option would remove, unfiltered, on at most
        :data:`PRESCAN_ROWS` rows: a ranking (the best few are then scored exactly), at a cost
        that does not grow with the log.  Candidates with a pointwise ``columns_at(q, options)``
        (the ripple) are scored for all options at once."""
        idx = np.unique(np.linspace(0, self.r.size - 1, min(self.r.size, self.PRESCAN_ROWS)).astype(int))
        U = S.basis(self.J[idx])
        r = S.partial_out(U, self.r[idx][:, None])[:, 0]
        if not hasattr(cand, "columns_at"):
            out = []
            for o in opts:
                Zp = S.partial_out(U, self.columns(cand, o, filtered=False)[idx])
                b, *_ = np.linalg.lstsq(Zp, r, rcond=None)
                f = Zp @ b
                out.append(float(2 * f @ r - f @ f))
            return np.array(out)
        q = np.concatenate([s.q[s.rows][d] for s, d in zip(self.sigs, self.dec)])[idx]
        out = np.zeros(len(opts))
        for a in range(0, len(opts), 100):  # options in chunks: (rows x 100) matrices
            X, Y = cand.columns_at(q, opts[a:a + 100])
            X, Y = X - U @ (U.T @ X), Y - U @ (U.T @ Y)
            g11, g22, g12 = (X * X).sum(0), (Y * Y).sum(0), (X * Y).sum(0)
            b1, b2 = X.T @ r, Y.T @ r
            det = g11 * g22 - g12 ** 2
            with np.errstate(divide="ignore", invalid="ignore"):
                dr = (g22 * b1 ** 2 - 2 * g12 * b1 * b2 + g11 * b2 ** 2) / det
            out[a:a + 100] = np.where(det > 1e-12 * np.maximum(g11 * g22, 1e-300), dr, 0.0)
        return out

    def best_option(self, cand: C.Candidate) -> tuple[dict, np.ndarray]:
        opts = cand.options(self.sigs, self.model)
        if len(opts) > 24:  # prescan without the filter (cheap), refine the best few with it
            scores = self.prescan(cand, opts)
            top = np.argsort(scores)[::-1][:6]
            opts_f = [opts[i] for i in top]
        else:
            opts_f = opts
        scored = [(self.delta_rss(Z), o, Z) for o in opts_f for Z in [self.columns(cand, o)]]
        dr, best, Z = max(scored, key=lambda x: x[0])
        if "n" in best and len(opts) > 1:  # refine a continuous order by golden-section search
            step = abs(opts[1]["n"] - opts[0]["n"])
            best, Z = self._refine_n(cand, best, step, opts[0]["n"], opts[-1]["n"])
        return best, Z

    def _refine_n(self, cand, best, step, lo, hi):
        a, b = max(best["n"] - step, lo), min(best["n"] + step, hi)
        g = (math.sqrt(5) - 1) / 2
        f = lambda n: -self.delta_rss(self.columns(cand, {**best, "n": n}))  # noqa: E731
        c, d = b - g * (b - a), a + g * (b - a)
        fc, fd = f(c), f(d)
        for _ in range(14):
            if fc < fd:
                b, d, fd = d, c, fc
                c = b - g * (b - a)
                fc = f(c)
            else:
                a, c, fc = c, d, fd
                d = a + g * (b - a)
                fd = f(d)
        n = c if fc < fd else d
        if -min(fc, fd) < self.delta_rss(self.columns(cand, best)):
            n = best["n"]
        nl = {**best, "n": float(n)}
        return nl, self.columns(cand, nl)

    def test(self, cand: C.Candidate) -> CandidateTest:
        """Search the candidate's options, test the best (its p corrected for the search)."""
        nl, Z = self.best_option(cand)
        return self._wald(cand, nl, Z, cand.n_effective(self.sigs, cand.options(self.sigs, self.model)))

    def test_fixed(self, cand: C.Candidate, nl: dict, n_effective: float) -> CandidateTest:
        """Test the candidate at settings ``nl`` found by an earlier search over ``n_effective`` options."""
        return self._wald(cand, nl, self.columns(cand, nl), n_effective)

    def _wald(self, cand: C.Candidate, nl: dict, Z: np.ndarray, m: float) -> CandidateTest:
        w = S.wald_test(self.r, Z, self.groups, self.U)
        # size of the effect: the torque the fitted term adds (not only its part the model cannot mimic)
        rms = float(np.sqrt(np.mean((Z @ w.coef) ** 2))) if Z.size else 0.0
        t = CandidateTest(cand.name, nl, w, m, S.bonferroni(w.p_value, m), effect_rms=rms)
        t._Z = Z  # kept for the ambiguity check
        return t

    def conditional_p(self, a: CandidateTest, b: CandidateTest) -> float:
        """p-value of candidate a given the model and candidate b."""
        U = S.basis(np.column_stack([self.J, b._Z]))
        return S.wald_test(self.r, a._Z, self.groups, U).p_value


def hac_std(model: Model, sigs: Sequence[LogSignals]) -> dict[str, float]:
    """HAC standard deviations of every parameter of ``model`` (decimated rows), SI."""
    rd = Round(model, sigs)
    J, e = rd.J, rd.r
    scale = np.linalg.norm(J, axis=0)
    scale[scale == 0] = 1.0
    Js = J / scale
    A = np.linalg.pinv(Js.T @ Js)
    scores = Js * e[:, None]
    L = S.andrews_bandwidth(scores, rd.groups)
    V = A @ S.hac_meat(scores, rd.groups, L) @ A
    sd = np.sqrt(np.clip(np.diag(V), 0, None)) / scale
    return dict(zip(rd.names, (float(x) for x in sd)))
