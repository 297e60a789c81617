"""Compare -> find -> add and refit -> repeat: the discrepancy workflow of ``kukaid diagnose``.

1. **Compare**: predict the measured torque of every log with the model of the parameter file
   (inverse dynamics, both sides through the same zero-phase filter) and measure the gap: RMSE,
   RMSE against the noise floor estimated from the data, relative error ||tau - tau_hat|| / ||tau||.
2. **Find**: refit the model as it is, then test the residual against every candidate effect that
   applies (HAC Wald test on rows decimated to the filter bandwidth, the model's Jacobian
   partialled out, Bonferroni over a candidate's grid, Holm over the candidates) and require a
   minimum effect size against the noise.  The significant candidate that removes the most residual
   is named, unless another significant candidate explains the same thing (each one is no longer
   significant given the other; a reversal transient with one position sensor, which backlash and
   pre-sliding friction give alike): then the residual is still modelled, by the candidate of the
   group that predicts better on held-out data (plausible, and passing the held-out test), and
   both are named with "mechanism undetermined" and the measurement that would settle it
   (:mod:`kukaid.diagnose.ambiguity`).  When neither passes, nothing is added.
3. **Add and refit** all parameters jointly with the effect; repeat until nothing is significant.
4. **Prune and order by size**: with several effects, an effect the later ones explain is dropped,
   each one's discrete settings are searched again given the others, and the steps are listed
   (and their refits redone) in order of each effect's size in the final joint fit: amplitude or
   peak in N·m, as the simulator documents sizes.  The search order (most residual explained
   first) is kept in a note.
"""
from __future__ import annotations

import copy
import math
from typing import Any, Callable, Sequence

import numpy as np

from kukaid.diagnose import ambiguity as A
from kukaid.diagnose import candidates as C
from kukaid.diagnose import heldout
from kukaid.diagnose import selection as S
from kukaid.diagnose.evidence import CandidateTest, Round, hac_std, rmse_of
from kukaid.diagnose.noise import noise_floor, noise_sigma
from kukaid.diagnose.refit import refit
from kukaid.diagnose.result import Diagnosis, Step
from kukaid.diagnose.signals import LogSignals, prepare
from kukaid.errors import FitError, KukaidError
from kukaid.identify.adequacy import with_effects
from kukaid.jsonfile import jsonable
from kukaid.models.torque import JointTorqueModel as Model
from kukaid.params.axis import model_from_params, model_to_params

__all__ = ["CandidateTest", "Diagnosis", "Step", "diagnose", "diagnose_signals", "hac_std", "rmse_of"]


def _add(model: Model, test: CandidateTest, coefs: dict, sigs: Sequence[LogSignals], rmse_before: float,
         rel_before: float, floor: float) -> Step:
    """Add the tested effect to ``model`` (start: ``coefs``), refit everything, measure the gap."""
    cand = C.get(test.name)
    new = refit(model.with_effect(test.name, test.nl, coefs), sigs)
    new.std = hac_std(new, sigs)
    r_after, rel_after = rmse_of(new, sigs)
    gap = rmse_before - floor
    closed = (rmse_before - r_after) / gap if gap > 0 else math.nan if math.isnan(floor) else 0.0
    if cand.native:
        coefs_new = {cand.native: new.lin[cand.native]}
        std = {cand.native: new.std.get(cand.native, math.nan)}
    else:
        term = next(e for e in new.effects if e.name == test.name)
        coefs_new = dict(term.coefs)
        std = {c: new.std.get(term.key(c), math.nan) for c in term.coefs}
    test.nl = dict(next((e.nl for e in new.effects if e.name == test.name), test.nl))
    test.size = cand.size(test.nl, coefs_new, sigs, new)
    desc = jsonable(cand.describe(test.nl, coefs_new, std, new))
    return Step(test.name, desc, rmse_before, r_after, test, closed, rel_before, rel_after, model, new)


def term_rms(model: Model, name: str, sigs: Sequence[LogSignals]) -> float:
    """RMS (compared rows, filtered) of the torque the effect ``name`` of ``model`` adds, N·m."""
    cand = C.get(name)
    nl, coefs = C.get(name).term(model)
    parts = []
    for s in sigs:
        Z = cand.columns(s, nl, model)
        parts.append(s.filtw(Z @ np.array([coefs[c] for c in cand.coef_keys(nl)]))[s.rows])
    x = np.concatenate(parts)
    return float(np.sqrt(np.mean(x * x))) if x.size else 0.0


def _final_terms(model: Model, sigs: Sequence[LogSignals]) -> dict[str, tuple[float, dict, dict]]:
    """name -> (size N·m, settings, coefficients) of every effect of ``model``."""
    out = {}
    for name, cand in C.CANDIDATES.items():
        t = cand.term(model)
        if t is not None:
            out[name] = (cand.size(*t, sigs, model), *t)
    return out


def _backfit(model: Model, sigs: Sequence[LogSignals]) -> Model:
    """Search each effect's discrete settings (backlash shape and time constant, drift coordinate)
    again given all the other effects: an effect found first was searched while the later ones
    were still in the residual.  A ripple's order needs no search: every refit refines it."""
    for term in list(model.effects):
        cand = C.get(term.name)
        if "n" in term.nl or len(cand.options(sigs, model)) < 2:
            continue
        rest = model.without(term.name)
        nl, _ = Round(rest, sigs).best_option(cand)
        if any(term.nl.get(k) != v for k, v in nl.items()):
            model = refit(rest.with_effect(term.name, nl, term.coefs), sigs)
    return model


def _prune(steps: list[Step], model: Model, sigs: Sequence[LogSignals], alpha: float,
           min_rms: float) -> tuple[Model, list[str]]:
    """Backward step: drop, one at a time (the weakest first), every effect that is no longer
    significant given all the others or whose refitted torque RMS fell below ``min_rms`` (an
    effect found early can be made redundant by the ones found after it)."""
    dropped: list[str] = []
    while len(dropped) < len(steps) - 1:  # the last one stands: it was significant, in-sample and held out, alone
        weakest, worst_p = None, -1.0
        for s in steps:
            if s.name in dropped:
                continue
            t = Round(model.without(s.name), sigs).test_fixed(C.get(s.name), C.get(s.name).term(model)[0],
                                                               s.test.n_effective)
            p = 1.0 if term_rms(model, s.name, sigs) < min_rms else t.p_candidate
            if p >= alpha and p > worst_p:
                weakest, worst_p = s.name, p
        if weakest is None:
            break
        dropped.append(weakest)
        model = refit(model.without(weakest), sigs)
    return model, dropped


def _in_order_of_size(steps: list[Step], base: Model, final: Model, sigs: Sequence[LogSignals],
                      floor: float, n_candidates: int) -> list[Step]:
    """The steps redone from ``base`` in order of the effects' sizes in ``final`` (largest first).

    The search adds the effect that explains most residual first; a term the base model partly
    mimics (load-dependent Coulomb friction inside Fc) can be the larger one and still explain
    less.  The final joint fit (after :func:`_backfit`) estimates every size; the chain of refits
    is redone in that order with each step's evidence tested against the steps before it.
    """
    final = _backfit(final, sigs)
    terms = _final_terms(final, sigs)
    order = sorted(steps, key=lambda s: -terms[s.name][0])
    if [s.name for s in order] != [s.name for s in steps] or final is not steps[-1].model_after:
        model, (rmse, rel) = base, rmse_of(base, sigs)
        out = []
        for s in order:
            _, nl, coefs = terms[s.name]
            t = s.test  # the evidence is the one the effect was found with (in-sample and held out)
            t.nl = dict(nl or t.nl)
            out.append(_add(model, t, coefs, sigs, rmse, rel, floor))
            model, rmse, rel = out[-1].model_after, out[-1].rmse_after, out[-1].rel_after
        steps = out
    for s in steps:  # an earlier step's own estimate misses the later effects: report the final size
        s.test.size = terms[s.name][0]
    return steps


# -- the workflow ----------------------------------------------------------------------------
def _reject(rejected: list[dict], name: str, reason: str) -> None:
    """Record why a candidate was not named (its latest reason only)."""
    rejected[:] = [r for r in rejected if r["name"] != name] + [{"name": name, "reason": reason}]


def _search(model: Model, sigs: Sequence[LogSignals], cand: C.Candidate) -> dict:
    """The candidate's best discrete settings given ``model`` on ``sigs`` (held-out folds)."""
    return Round(model, sigs).best_option(cand)[0]


def _undetermined_size(step: Step) -> str:
    """Why the joint refit does not determine the size of the step's effect ("" when it does: some
    coefficient at least 2 HAC standard deviations from zero).  An effect that stands for a group
    of explanations is modelled only when its size is determined."""
    std = step.params.get("std") or {}
    ratios = {k: abs(float(v)) / float(std[k]) for k, v in step.params.items()
              if k in std and isinstance(v, (int, float)) and std[k] and math.isfinite(float(std[k]))}
    if ratios and max(ratios.values()) < 2.0:
        k = max(ratios, key=ratios.get)
        return (f"its size is not determined in the joint refit ({k} = {step.params[k]:.3g} +/- "
                f"{float(std[k]):.2g})")
    return ""


def _settle(group: Sequence[CandidateTest], model: Model, sigs: Sequence[LogSignals], rmse: float, rel: float,
            floor: float, given: Model, alpha_held_out: float) -> tuple[Step | None, dict]:
    """Candidates that explain the same residual: each one's refit checked for plausibility and on
    held-out data; the significant one with the lowest held-out error among those that pass the
    held-out test is the step (None when none passes).  Returns (step, {"candidates",
    "modelled_as", "held_out": name -> figures or why not, "settled_by"})."""
    figures: dict[str, dict] = {}
    best: Step | None = None
    for t in group:
        coefs = dict(zip(C.get(t.name).coef_keys(t.nl), t.wald.coef))
        st = _add(model, t, coefs, sigs, rmse, rel, floor)
        why = C.get(t.name).implausible(st.model_after, sigs, given) or _undetermined_size(st)
        if why:
            figures[t.name] = {"reason": why}
            continue
        ho = heldout.evaluate(model, t.name, t.nl, coefs, sigs, _search)
        t.held_out = ho
        if ho is None:
            figures[t.name] = {"reason": "no held-out data to check it on"}
            continue
        figures[t.name] = ho.to_json()
        if not (ho.passed and ho.p_value < alpha_held_out):
            figures[t.name]["reason"] = f"held-out error not significantly lower (p = {ho.p_value:.2g})"
        elif not t.significant:
            figures[t.name]["reason"] = "not significant in the fit"
        elif best is None or ho.rmse_with < best.test.held_out.rmse_with:
            best = st
    names = list(dict.fromkeys(t.name for t in group))
    info = {"candidates": names, "modelled_as": best.name if best else None, "held_out": figures,
            "settled_by": A.settled_by(names, best.name if best else None)}
    if best is not None:
        best.test.undetermined = info
    return best, info


def _mechanism_note(u: dict) -> str:
    return (f"mechanism undetermined: {' or '.join(u['candidates'])} explain the same residual; modelled as "
            f"{u['modelled_as']}, the lower held-out error; to settle it: {u['settled_by']}")


def _undetermined(steps: list[Step], ambiguous: list[dict]) -> list[dict]:
    """The undetermined mechanisms the final model keeps (one per step that stands for a group);
    an ambiguity whose modelled term was dropped later (a note says so) is left unmodelled."""
    kept = {s.name for s in steps}
    for x in ambiguous:
        if x.get("modelled_as") is not None and x["modelled_as"] not in kept:
            x["modelled_as"] = None
    return [s.test.undetermined for s in steps if s.test.undetermined]


def diagnose_signals(params: dict, sigs: Sequence[LogSignals], *, alpha: float = 0.01, min_effect: float = 0.15,
                     max_steps: int = 4, candidates: Sequence[str] | None = None,
                     max_held_out: int = 3, alpha_held_out: float = 0.05,
                     stage: Callable[[str], None] | None = None) -> Diagnosis:
    """Run the workflow on prepared signals (see :func:`diagnose`)."""
    stage = stage or (lambda text: None)
    if not sigs:
        raise KukaidError("diagnose needs at least one log")
    if sum(s.rows.size for s in sigs) < 50:
        names = ", ".join(dict.fromkeys(s.name for s in sigs))
        raise FitError(f"{names}: fewer than 50 dynamic-mode samples in the logs ({sum(s.rows.size for s in sigs)}): "
                       "the axis barely moves; nothing to diagnose (give logs of an excitation: kukaid excite friction, "
                       "inertia or validation)")
    joint = sigs[0].joint
    stage("comparing the model with the data, refitting it as it is")
    given = model_from_params(params, joint).within_bounds()
    rmse0, rel0 = rmse_of(given, sigs)
    floor = noise_floor(sigs)
    sigma = noise_sigma(sigs)
    model = refit(given, sigs)
    model.std = hac_std(model, sigs)
    rmse_r, rel_r = rmse_of(model, sigs)
    # the size an effect must have: min_effect x the raw noise, or, when the torque was filtered before it
    # was recorded (no noise floor: its second differences hold almost no noise), x the refit's residual
    scale, per = (sigma, "noise") if math.isfinite(floor) else (rmse_r, "the refit model's residual RMSE")
    found_base = model
    names = list(candidates) if candidates is not None else list(C.NAMES)
    for n in names:
        C.get(n)
    steps: list[Step] = []
    ambiguous: list[dict] = []
    notes = [f"effect '{n}' in the parameter file is not in the diagnosis format; ignored" for n in given.ignored_effects]
    if not math.isfinite(floor):
        notes.append(f"the torque's noise is not known: an effect is named from {min_effect:g} x {per} "
                     f"({min_effect * scale:.3g} N·m RMS) on")
    added: list[str] = []
    cur_rmse, cur_rel = rmse_r, rel_r
    tests: list[CandidateTest] = []
    first_round: list[CandidateTest] = []
    rejected: list[dict] = []
    excluded: set[str] = set()
    tested = max_steps > 0
    for k in range(max_steps):
        stage(f"round {k + 1} of at most {max_steps}: testing the candidate effects")
        rd = Round(model, sigs)
        tests = []
        for n in names:
            cand = C.get(n)
            ok, why = cand.applies(sigs, model)
            if not ok or n in added or n in excluded:
                continue
            tests.append(rd.test(cand))
        if not tests:
            break
        first_round = first_round or tests
        adj = S.holm({t.name: t.p_candidate for t in tests})
        for t in tests:
            t.p_adjusted = adj[t.name]
            big = t.effect_rms >= min_effect * scale
            t.significant = t.p_adjusted < alpha and big
            t.reason = ("significant" if t.significant else
                        "not significant" if t.p_adjusted >= alpha else
                        f"effect RMS below {min_effect:g} x {per}")
        sig_tests = sorted([t for t in tests if t.significant], key=lambda t: -t.wald.delta_rss)
        if not sig_tests:
            break
        # two significant candidates "explain the same thing" when each loses its significance
        # given the other; if the best one is in such a pair, nothing is guessed
        best = sig_tests[0]
        amb = []
        for i, a in enumerate(sig_tests):
            for b in sig_tests[i + 1:]:
                p_ab = rd.conditional_p(a, b)
                p_ba = rd.conditional_p(b, a)
                if p_ab >= alpha and p_ba >= alpha:
                    amb.append({"candidates": [a.name, b.name],
                                "reason": f"each loses significance given the other (p = {p_ab:.2g}, {p_ba:.2g})"})
        step, retry = None, False
        if any(best.name in x["candidates"] for x in amb):
            # the residual is still modelled: by the one of the group that predicts better on held-out
            # data; the mechanism is undetermined.  The search goes on without the group.
            group_names = {n for x in amb if best.name in x["candidates"] for n in x["candidates"]}
            step, info = _settle([t for t in sig_tests if t.name in group_names], model, sigs, cur_rmse, cur_rel,
                                 floor, given, alpha_held_out)
            for x in amb:
                x["modelled_as"] = info["modelled_as"] if info["modelled_as"] in x["candidates"] else None
                x["held_out"] = {n: info["held_out"][n] for n in x["candidates"] if n in info["held_out"]}
                x["settled_by"] = A.settled_by(x["candidates"])
                excluded.update(x["candidates"])
            ambiguous += amb
            if step is None:
                continue
        # the decision is taken on data not fitted: the first significant candidate (most residual
        # explained first) whose refit is plausible and that lowers the held-out error, significantly
        for t in ([] if step is not None else sig_tests[:max_held_out]):
            if t.name in A.REVERSAL_PAIR and not C.separable_backlash(sigs):
                # one position sensor: a reversal transient is backlash or pre-sliding friction alike;
                # modelled by the one that predicts better held out, the mechanism undetermined
                group = [t] + [u for u in tests if u.name in A.REVERSAL_PAIR and u.name != t.name]
                step, info = _settle(group, model, sigs, cur_rmse, cur_rel, floor, given, alpha_held_out)
                info.update(candidates=list(A.REVERSAL_PAIR), settled_by=A.settled_by(A.REVERSAL_PAIR))
                ambiguous.append({"candidates": list(A.REVERSAL_PAIR),
                                  "reason": "a transient after each reversal; with one position sensor backlash and "
                                            "pre-sliding friction cannot be told apart (a load-side encoder would)",
                                  **{k: v for k, v in info.items() if k != "candidates"}})
                excluded.update(A.REVERSAL_PAIR)
                retry = step is None
                break
            coefs = dict(zip(C.get(t.name).coef_keys(t.nl), t.wald.coef))
            cand_step = _add(model, t, coefs, sigs, cur_rmse, cur_rel, floor)
            why = C.get(t.name).implausible(cand_step.model_after, sigs, given)
            if why:
                _reject(rejected, t.name, why)
                continue
            ho = heldout.evaluate(model, t.name, t.nl, coefs, sigs, _search)
            t.held_out = ho
            if ho is None:
                _reject(rejected, t.name, "no held-out data to check it on")
            elif not (ho.passed and ho.p_value < alpha_held_out):
                _reject(rejected, t.name, f"held-out RMSE {ho.rmse_without:.4g} -> {ho.rmse_with:.4g} "
                                          f"({ho.scheme}), p = {ho.p_value:.2g}")
            else:
                step = cand_step
                break
        if step is None:
            if retry:
                continue  # search the other candidates without the ambiguous pair
            break
        step.test.found_with = list(added)  # the baseline its evidence is of, whatever order the steps are listed in
        added.append(step.name)
        rejected[:] = [r for r in rejected if r["name"] != step.name]
        steps.append(step)
        model, cur_rmse, cur_rel = step.model_after, step.rmse_after, step.rel_after
    if len(steps) > 1:
        found = [s.name for s in steps]
        final, dropped = _prune(steps, model, sigs, alpha, min_effect * scale)
        steps = [s for s in steps if s.name not in dropped]
        for n in dropped:
            notes.append(f"{n} was found first but the effects found after it explain it (not significant or "
                         f"below {min_effect:g} x {per} given them): dropped")
        steps = _in_order_of_size(steps, found_base, final, sigs, floor, n_candidates=len(first_round))
        if [s.name for s in steps] != [n for n in found if n not in dropped]:
            notes.append(f"effects listed in order of size (amplitude or peak in the final fit, not the residual "
                         f"each explains); found in the order {', '.join(found)} (most residual explained first), "
                         "each step's evidence and held-out check are of the model it was found in")
        model, cur_rmse, cur_rel = steps[-1].model_after, steps[-1].rmse_after, steps[-1].rel_after
    added = [s.name for s in steps]
    # nothing named: the parameter file stays as it was (a refit without new effects is no finding)
    out_params = model_to_params(model, params, added) if added else copy.deepcopy(params)
    if not added:
        model, cur_rmse, cur_rel = given, rmse0, rel0
    undetermined = _undetermined(steps, ambiguous)
    for u in undetermined:  # the refined file says it next to the term ("_" keys are notes) and in provenance
        eff = (out_params.get("effects") or {}).get(u["modelled_as"])
        if isinstance(eff, dict):
            eff["_mechanism"] = _mechanism_note(u)
    prov = dict(out_params.get("provenance") or {})
    prov["diagnose"] = {"effects_added": added, "rmse_before": rmse0, "rmse_after": cur_rmse, "noise_floor": floor}
    if undetermined:
        prov["diagnose"]["undetermined"] = [{k: u[k] for k in ("candidates", "modelled_as", "settled_by")}
                                            for u in undetermined]
    out_params["provenance"] = jsonable(prov)
    if added:  # the fit's figures are of the model without the effects
        out_params["metrics"] = jsonable(with_effects(out_params.get("metrics") or {}, added, rmse0, cur_rmse, floor))
    steps = [st for st in steps if st.test.p_adjusted < alpha]  # never a step with p >= alpha as found
    return Diagnosis(steps, rmse0, cur_rmse, floor, sigma, ambiguous, out_params, rel0, cur_rel, rmse_r, tests,
                     list(sigs), given, model, notes, tested=tested, rejected=rejected,
                     scheme=heldout.folds(sigs)[0])


def preprocess_settings(params: dict) -> dict:
    """Filter settings of the fit that produced ``params`` (provenance), else None (defaults by
    sample rate: the paper's 5 Hz, 3rd order at the KR C4's 83 Hz)."""
    prov = params.get("provenance") or {}
    pre = prov.get("preprocess") if isinstance(prov.get("preprocess"), dict) else {}
    out = {"cutoff": float(pre["cutoff"]) if "cutoff" in pre else None,
           "order": int(pre["order"]) if "order" in pre else None}
    out["qd_thr"] = float((params.get("mode_switch") or {}).get("qd_thr", pre.get("qd_thr", 0.0017)))
    return out


def diagnose(params: dict, logs: Sequence[Any], axis: int | None = None, *, cutoff: float | None = None,
             order: int | None = None, qd_thr: float | None = None, alpha: float = 0.01,
             min_effect: float = 0.15, max_steps: int = 4, candidates: Sequence[str] | None = None,
             source: str = "parameters", stage: Callable[[str], None] | None = None) -> Diagnosis:
    """Find the effects the model of ``params`` misses in ``logs``, add them, refit.

    Parameters
    ----------
    params : a validated ``kukaid.params/1`` dictionary.
    logs : AxisLog objects (one or several experiments of the same axis).
    axis : KUKA axis number (default: the parameter file's, else the logs' first).
    cutoff, order, qd_thr : comparison filter (Hz), its order, dynamic-mode threshold (rad/s);
        default: the fit's settings from the parameter file, else 5 Hz, 3, 0.0017 rad/s.
    alpha : family-wise false-alarm probability per round (Holm over candidates).
    min_effect : smallest effect worth naming, as RMS torque over the raw torque-noise sigma.
    max_steps : at most this many effects are added.
    candidates : restrict the library to these names.
    stage : told what is being done (progress lines).
    source : where ``params`` came from, for messages (a file of another axis than ``axis``, or of
        another joint type than the logs', is refused: :func:`kukaid.params.check_model_of`).

    Returns
    -------
    Diagnosis, with ``steps``, ``rmse_before``/``rmse_after`` (N·m), ``noise_floor`` (N·m),
    ``ambiguous`` and the refined ``params``.
    """
    pre = preprocess_settings(params)
    if cutoff is not None:
        pre["cutoff"] = float(cutoff)
    if order is not None:
        pre["order"] = int(order)
    if qd_thr is not None:
        pre["qd_thr"] = float(qd_thr)
    from kukaid.params import check_model_of

    check_model_of(params, source, axis=axis)
    if axis is None:
        axis = params.get("axis")
    sigs = []
    for i, log in enumerate(logs):
        ax = axis if axis is not None and axis in log.axes else (log.axes[0] if axis is None else axis)
        if ax in log.axes:
            check_model_of(params, source, joint=log.joint[log.index(ax)])
        sigs.append(prepare(log, ax, cutoff=pre["cutoff"], order=pre["order"], qd_thr=pre["qd_thr"],
                            name=str(log.attrs.get("source_file", f"log {i + 1}"))))
    return diagnose_signals(params, sigs, alpha=alpha, min_effect=min_effect, max_steps=max_steps,
                            candidates=candidates, stage=stage)
