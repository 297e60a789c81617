"""Two candidate effects that explain the same residual: which measurement would tell them apart.

The diagnosis calls two significant candidates ambiguous when each loses its significance given
the other, and a reversal transient always so with one position sensor (backlash or pre-sliding
friction, :func:`kukaid.diagnose.candidates.separable_backlash`).  The residual is still there, so
the workflow models it with the candidate that predicts better on held-out data and says that the
mechanism is undetermined; :func:`settled_by` says what would settle it, per pair.
"""
from __future__ import annotations

from typing import Iterable

#: the two reversal-transient candidates one position sensor cannot tell apart
REVERSAL_PAIR = ("backlash", "presliding")

_WIDER_RANGE = ("a log over a wider position range, where the two torques differ")
_SLOW_PLATEAUS = ("slow constant-speed plateaus far from any reversal, where a Stribeck rise stays and a "
                  "transient after a reversal has faded")

#: frozenset({a, b}) -> the measurement or experiment that would tell a from b
SETTLE: dict[frozenset, str] = {
    frozenset(REVERSAL_PAIR): ("a load-side encoder, since play moves the motor without the load and "
                               "pre-sliding friction moves both"),
    frozenset(("gravity_sine", "torque_offset")): _WIDER_RANGE,
    frozenset(("gravity_sine", "position_ripple")): _WIDER_RANGE,
    frozenset(("torque_offset", "position_ripple")): _WIDER_RANGE,
    frozenset(("gravity_sine", "load_dependent_friction")): ("the same positions crossed in both "
                                                             "directions at several speeds"),
    frozenset(("torque_offset", "load_dependent_friction")): ("the same positions crossed in both "
                                                              "directions at several speeds"),
    frozenset(("torque_offset", "thermal_drift")): ("a motor temperature channel, or logs at other "
                                                    "temperatures"),
    frozenset(("thermal_drift", "load_dependent_friction")): ("logs at another load (pose or payload) "
                                                              "at the same motor temperature"),
    frozenset(("thermal_drift", "position_ripple")): "a motor temperature channel, or a longer log",
    frozenset(("stribeck", "presliding")): _SLOW_PLATEAUS,
    frozenset(("stribeck", "backlash")): _SLOW_PLATEAUS,
}


def settled_by(names: Iterable[str], modelled: str | None = None) -> str:
    """The measurement that would tell the candidates ``names`` apart (a pair; for more, the text of
    every pair, each once; with ``modelled``, only the pairs of the candidate that was modelled)."""
    names = list(dict.fromkeys(names))
    if "coupling" in names:
        return "a log with the other axes held still"
    texts = []
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            if modelled is not None and modelled not in (a, b):
                continue
            t = SETTLE.get(frozenset((a, b)))
            if t is None:
                t = f"a log where {a} and {b} give different torques (other positions, speeds or reversals)"
            if t not in texts:
                texts.append(t)
    return "; or ".join(texts)
