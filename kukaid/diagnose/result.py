"""The result of a diagnosis: its steps (an effect added, the gap before and after, the evidence)
and the whole (:class:`Diagnosis`: verdict, text lines, JSON)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from kukaid.diagnose import candidates as C
from kukaid.diagnose.evidence import CandidateTest
from kukaid.diagnose.signals import LogSignals
from kukaid.identify.adequacy import UNKNOWN_FLOOR
from kukaid.jsonfile import jsonable
from kukaid.models.effects import unit_of
from kukaid.models.torque import JointTorqueModel as Model


@dataclass
class Step:
    """One effect added: its parameters, the gap before and after, the evidence."""

    name: str
    params: dict
    rmse_before: float
    rmse_after: float
    test: CandidateTest
    gap_closed: float
    rel_before: float
    rel_after: float
    model_before: Model = field(repr=False, default=None)
    model_after: Model = field(repr=False, default=None)

    def to_json(self) -> dict[str, Any]:
        ev = self.test.evidence()
        ev["share_of_gap_closed"] = float(self.gap_closed)
        out = {"name": self.name, "params": self.params, "rmse_before": float(self.rmse_before),
               "rmse_after": float(self.rmse_after), "evidence": ev}
        if self.test.undetermined:  # only on a step that stands for an undetermined mechanism
            out["undetermined"] = self.test.undetermined
        return jsonable(out)


@dataclass
class Diagnosis:
    """Result of :func:`diagnose`.  ``to_json()`` gives the documented JSON; ``lines()`` the text."""

    steps: list[Step]
    rmse_before: float
    rmse_after: float
    noise_floor: float
    noise_sigma: float
    ambiguous: list[dict]
    params: dict
    rel_before: float
    rel_after: float
    rmse_refit: float
    last_round: list[CandidateTest]
    sigs: list[LogSignals] = field(repr=False, default_factory=list)
    model_given: Model = field(repr=False, default=None)
    model_final: Model = field(repr=False, default=None)
    notes: list[str] = field(default_factory=list)
    tested: bool = True
    rejected: list[dict] = field(default_factory=list)
    scheme: str = ""

    @property
    def names(self) -> list[str]:
        return [s.name for s in self.steps]

    def __iter__(self):  # unpacks as ``steps, params = diagnose(...)``
        return iter((self.steps, self.params))

    def joints(self) -> list[dict[str, Any]]:
        """Per joint diagnosed (one here): ``axis``, after the effects found the ``rmse`` (N·m) and
        ``rel_error`` (RMS error over RMS torque), and the ``effects`` acting on it (as the robot's)."""
        return [{"axis": int(self.params.get("axis", 3)), "rmse": float(self.rmse_after),
                 "rel_error": float(self.rel_after), "effects": self.names}]

    def to_json(self) -> dict[str, Any]:
        return jsonable({"effects": [s.to_json() for s in self.steps], "rmse_before": float(self.rmse_before),
                        "rmse_after": float(self.rmse_after), "noise_floor": float(self.noise_floor),
                        "ambiguous": self.ambiguous, "rejected": self.rejected, "tested": self.tested,
                        "held_out_scheme": self.scheme, "verdict": self.verdict})

    @property
    def verdict(self) -> str:
        """One sentence: what was found, or why nothing was named."""
        if not self.tested:
            return "no candidate tested (--max-steps 0): the gap above is all this run measured"
        if self.steps:
            und = [s.test.undetermined for s in self.steps if s.test.undetermined]
            return "named: " + ", ".join(self.names) + "".join(
                f"; mechanism undetermined: {' or '.join(u['candidates'])}, modelled as {u['modelled_as']}; "
                f"to settle it: {u['settled_by']}" for u in und)
        if self.ambiguous:
            return "nothing named: candidates are ambiguous"
        if self.rejected:
            return ("no candidate improved the held-out error (" + self.scheme + "): "
                    + ", ".join(r["name"] for r in self.rejected) + " rejected")
        return "no candidate improved the held-out error: none is significant against the noise in the fit"

    def lines(self) -> list[str]:
        """Human-readable summary, one string per line."""
        u = "N" if self.sigs and self.sigs[0].joint == "prismatic" else "N·m"
        out = [f"gap before: RMSE {self.rmse_before:.4g} {u} = {self.rmse_before / self.noise_floor:.2f} x noise "
               f"floor {self.noise_floor:.4g} {u} (raw torque noise {self.noise_sigma:.4g} {u}); relative error "
               f"{100 * self.rel_before:.2f} %" if self.noise_floor > 0 else
               f"gap before: RMSE {self.rmse_before:.4g} {u}; relative error {100 * self.rel_before:.2f} %"
               + (f" ({UNKNOWN_FLOOR}: the gap is not read against it)" if math.isnan(self.noise_floor) else "")]
        if abs(self.rmse_refit - self.rmse_before) > 1e-3 * max(self.rmse_before, 1e-12):
            # the steps start from this refit; with none it is not kept, and the gap after is the file's own
            out.append(f"refit without new effects: RMSE {self.rmse_refit:.4g} {u}" + ("" if self.steps else
                       " (the file's own terms refitted on these logs, in-sample; not kept, as nothing was named: "
                       "the gap after is the file's as it was)"))
        for i, s in enumerate(self.steps, 1):
            ev = s.test
            par = ", ".join(_fmt_param(k, v, s.params.get("std", {}).get(k),
                                       unit_of(s.name, k, s.params, u == "N")) for k, v in s.params.items()
                            if k not in ("model", "std", "stored_as", "unit"))
            out.append(f"step {i}: {s.name} ({C.get(s.name).meaning}); size in the final fit {ev.size:.3g} {u}")
            out.append(f"    parameters at this step: {par}")
            before = self.names[:i - 1]
            found = ("" if ev.found_with is None or sorted(ev.found_with) == sorted(before) else
                     f" (when found, with {', '.join(ev.found_with)} in the model)" if ev.found_with else
                     " (when found, before any other effect)")
            out.append(f"    RMSE {s.rmse_before:.4g} -> {s.rmse_after:.4g} {u}, "
                       + ("" if math.isnan(s.gap_closed) else
                          f"{100 * s.gap_closed:.0f} % of the gap to the noise floor closed; ")
                       + f"relative error {100 * s.rel_before:.2f} % -> {100 * s.rel_after:.2f} %")
            out.append(f"    evidence{found}: HAC Wald {ev.wald.stat:.1f} (dof {ev.wald.dof}), corrected p = "
                       f"{ev.p_adjusted:.2g}, effect RMS {ev.effect_rms:.3g} {u}")
            if ev.held_out is not None:
                h = ev.held_out
                out.append(f"    held out{found} ({h.scheme}): RMSE {h.rmse_without:.4g} -> {h.rmse_with:.4g} {u}, "
                           f"better in {h.folds_improved}/{h.n_folds} folds, p = {h.p_value:.2g}")
            if ev.undetermined:
                und = ev.undetermined
                others = [n for n in und["candidates"] if n != s.name]
                out.append(f"    mechanism undetermined: {' or '.join(und['candidates'])} explain the same residual; "
                           f"modelled as {s.name}, the lower held-out error ({_held_out_figures(und, u)}); "
                           f"{' and '.join(others) or 'the other'} not ruled out; to settle it: {und['settled_by']}")
        for a in self.ambiguous:
            if a.get("modelled_as"):
                k = self.names.index(a["modelled_as"]) + 1 if a["modelled_as"] in self.names else 0
                what = f"modelled as {a['modelled_as']}" + (f" (step {k})" if k else "") + ", mechanism undetermined"
                settle = ""  # the step says what would settle it
            else:
                what = ("not guessing: none of them is plausible and lowers the held-out error" if a.get("held_out")
                        else "not guessing")
                settle = f"; to settle it: {a['settled_by']}" if a.get("settled_by") else ""
            out.append(f"ambiguous: {' or '.join(a['candidates'])} explain the same residual ({a['reason']}); "
                       f"{what}{settle}")
        for r in self.rejected:
            out.append(f"not named: {r['name']}: {r['reason']}")
        if not self.steps and not self.ambiguous:
            out.append(self.verdict)
        out.append(f"gap after: RMSE {self.rmse_after:.4g} {u}"
                   + (f" = {self.rmse_after / self.noise_floor:.2f} x noise floor" if self.noise_floor > 0 else "")
                   + f"; relative error {100 * self.rel_after:.2f} %")
        out += [f"note: {n}" for n in self.notes]
        return out


def _held_out_figures(und: dict, unit: str) -> str:
    """'held-out RMSE backlash 0.1661 N·m, presliding 0.102 N·m' (or why a candidate has no figure)."""
    parts = []
    for n in und["candidates"]:
        h = (und.get("held_out") or {}).get(n)
        if h is None:
            parts.append(f"{n} not tested")
        elif "rmse_with" in h:
            parts.append(f"{n} {h['rmse_with']:.4g} {unit}" + (f" ({h['reason']})" if h.get("reason") else ""))
        else:
            parts.append(f"{n}: {h.get('reason', 'no figure')}")
    return "held-out RMSE " + ", ".join(parts)


def _fmt_param(k: str, v: Any, sd: Any, unit: str = "") -> str:
    if isinstance(v, float):
        return (f"{k} = {v:.4g}" + (f" +/- {sd:.2g}" if isinstance(sd, float) and math.isfinite(sd) else "")
                + (f" {unit}" if unit and unit != "-" else ""))
    return f"{k} = {v}"
