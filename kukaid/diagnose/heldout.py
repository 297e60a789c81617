"""Decide on data not fitted: an effect is named only if it lowers the held-out error, significantly.

Folds (:func:`folds`):

* three logs or more: **leave one log out**: fit on the others, predict the one left out;
* one or two logs: **held-out contiguous blocks**: the compared rows of every log are cut into
  ``n_blocks`` pieces in time; fold k predicts block k of every log from a fit on the other
  blocks, with a guard of ``2 / cutoff`` s at the block's ends removed from the fit (the filtered
  residual is correlated over about that time).  (Two logs are often two different experiments,
  a friction sweep and a sine, neither of which identifies the whole model alone.)

For every fold the current model and the model with the candidate are both refitted on the fit
part (the candidate's discrete settings, such as a ripple order or a drift coordinate, are
searched again there), and both predict the held-out part.  The loss differential
``d = r_without² - r_with²`` on the held-out rows (decimated to the filter bandwidth) is tested
for a positive mean with a HAC standard error (Diebold-Mariano, one-sided, lags kept inside a
fold).  The candidate passes when the held-out sum of squares falls and that test is below
``alpha``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Callable, Sequence

import numpy as np

from kukaid.diagnose import selection as S
from kukaid.errors import KukaidError

#: leave one log out from this many logs on (fewer: contiguous blocks of every log)
LOLO_MIN_LOGS = 3

if TYPE_CHECKING:  # pragma: no cover
    from kukaid.models.signals import LogSignals
    from kukaid.models.torque import JointTorqueModel


@dataclass
class HeldOut:
    """Held-out evidence for one candidate (pooled over the folds)."""

    scheme: str                # "leave-one-log-out (k logs)" or "k contiguous blocks"
    rmse_without: float        # held-out RMSE of the current model, N·m
    rmse_with: float           # held-out RMSE with the candidate, N·m
    p_value: float             # one-sided Diebold-Mariano p of a lower held-out loss
    folds_improved: int
    n_folds: int

    @property
    def passed(self) -> bool:
        return self.rmse_with < self.rmse_without

    def to_json(self) -> dict:
        return {"scheme": self.scheme, "rmse_without": self.rmse_without, "rmse_with": self.rmse_with,
                "p_value": self.p_value, "folds_improved": self.folds_improved, "n_folds": self.n_folds}


def _blocks(s: "LogSignals", n_blocks: int, k: int) -> tuple[np.ndarray, np.ndarray]:
    """(fit rows, held-out rows) of block ``k`` of the compared rows of one log."""
    rows = s.rows
    guard = int(math.ceil(2.0 * s.fs / s.cutoff)) if s.cutoff > 0 else 0
    cuts = np.linspace(rows[0], rows[-1] + 1, n_blocks + 1).astype(int) if rows.size else np.zeros(n_blocks + 1, int)
    a, b = cuts[k], cuts[k + 1]
    return rows[(rows < a - guard) | (rows >= b + guard)], rows[(rows >= a) & (rows < b)]


def folds(sigs: Sequence["LogSignals"], n_blocks: int = 4,
          min_logs: int = LOLO_MIN_LOGS) -> tuple[str, list[tuple[list, list]]]:
    """(scheme, [(fit signals, held-out signals)]) as the module docstring describes.

    With at least ``min_logs`` logs, leave one log out; with fewer (one log, or a friction sweep
    and a sine that each cannot identify the whole model alone), block ``k`` of *every* log is
    held out in fold ``k``.
    """
    sigs = list(sigs)
    if len(sigs) >= min_logs:
        return (f"leave-one-log-out ({len(sigs)} logs)",
                [([s for j, s in enumerate(sigs) if j != k], [sigs[k]]) for k in range(len(sigs))])
    out = []
    for k in range(n_blocks):
        train, test = [], []
        for s in sigs:
            tr, te = _blocks(s, n_blocks, k)
            if tr.size >= 50:
                train.append(replace(s, rows=tr))
            if te.size >= 20:
                test.append(replace(s, rows=te))
        if train and test:
            out.append((train, test))
    what = "one log" if len(sigs) == 1 else f"each of {len(sigs)} logs"
    return f"{len(out)} contiguous blocks of {what}", out


def _dm_p(d: np.ndarray, groups: np.ndarray) -> float:
    """One-sided p-value of mean(d) > 0 with a HAC (prewhitened Bartlett) variance."""
    from scipy.stats import norm

    n = d.size
    if n < 5:
        return 1.0
    m = float(d.mean())
    V, _ = S.hac_prewhitened((d - m)[:, None], groups)
    se = math.sqrt(max(float(V[0, 0]), 1e-300) / n ** 2)
    return float(norm.sf(m / se)) if se > 0 else (0.0 if m > 0 else 1.0)


def evaluate(model: "JointTorqueModel", name: str, nl: dict, coefs: dict, sigs: Sequence["LogSignals"],
             search: Callable[["JointTorqueModel", list, object], dict], n_blocks: int = 4) -> HeldOut | None:
    """Held-out evidence for adding the effect ``name`` to ``model`` (None when no fold can be
    formed: too few compared rows).  ``search(model, signals, candidate)`` returns the candidate's
    best discrete settings on those signals (the workflow's option search)."""
    from kukaid.diagnose import candidates as C
    from kukaid.diagnose.refit import refit
    from kukaid.diagnose.signals import decimation

    cand = C.get(name)
    scheme, fs = folds(sigs, n_blocks)
    if not fs:
        return None
    ds, gs, sse0, sse1, n, improved = [], [], 0.0, 0.0, 0, 0
    for k, (train, test) in enumerate(fs):
        try:
            base = refit(model, train)
            ok, _ = cand.applies(train, base)
            # discrete settings searched again on the fit part; a continuous order (ripple n) is
            # refined by the refit itself, from the whole-data value
            nl_k = search(base, train, cand) if ok and "n" not in nl and len(cand.options(train, base)) > 1 else nl
            new = refit(base.with_effect(name, nl_k, coefs), train)
        except (KukaidError, np.linalg.LinAlgError, ValueError):  # a fold the model cannot be fitted on: no evidence
            continue
        f0, f1 = 0.0, 0.0
        for s in test:
            dec = decimation(s)
            r0, r1 = base.residual(s), new.residual(s)
            f0 += float(r0 @ r0)
            f1 += float(r1 @ r1)
            n += r0.size
            ds.append(r0[dec] ** 2 - r1[dec] ** 2)
            gs.append(np.full(dec.size, len(gs)))
        sse0, sse1 = sse0 + f0, sse1 + f1
        improved += int(f1 < f0)
    if not ds or n == 0:
        return None
    p = _dm_p(np.concatenate(ds), np.concatenate(gs))
    return HeldOut(scheme, math.sqrt(sse0 / n), math.sqrt(sse1 / n), p, improved, len(fs))
