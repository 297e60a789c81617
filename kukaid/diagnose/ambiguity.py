"""Two candidate effects that explain the same residual: which measurement would tell them apart.

The one-axis diagnosis calls two significant candidates ambiguous when each loses its significance
given the other, and a reversal transient always so with one position sensor (backlash or
pre-sliding friction, :func:`kukaid.diagnose.candidates.separable_backlash`); a robot's diagnosis
two candidates on the same joints whose held-out gains the data do not tell apart, when neither
lowers the held-out error given the other (:mod:`kukaid.diagnose.robot`).  The residual is still
there, so either models it with the candidate that predicts better on held-out data and says that
the mechanism is undetermined; :func:`settled_by` says what would settle it, per pair.
"""
from __future__ import annotations

from typing import Iterable

#: the two reversal-transient candidates one position sensor cannot tell apart
REVERSAL_PAIR = ("backlash", "presliding")

_WIDER_RANGE = ("a log over a wider position range, where the two torques differ")
_ONE_WRIST_AXIS = ("a recording that moves one wrist axis at a time: the coupled drives' friction then shows "
                   "on the axes that stand")
_LOAD_SIDE = "a load-side encoder (the link's angle beside the motor's)"
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
    # a robot's candidates (:mod:`kukaid.diagnose.robot_candidates`), by kind (the name before "@")
    frozenset(("counterbalance", "position_ripple")): ("a recording that takes the joint over its whole range, "
                                                       "where a gas spring's torque changes one way with the "
                                                       "angle and a ripple's repeats"),
    frozenset(("counterbalance", "payload")): ("recordings with a known mass at the flange and without it: a "
                                               "payload's torque changes with it, a spring's does not"),
    frozenset(("thermal_friction", "load_dependent_friction")): ("logs at another load (pose or payload) "
                                                                 "at the same motor temperature"),
    frozenset(("coupled_wrist_friction", "load_dependent_friction")): _ONE_WRIST_AXIS,
    frozenset(("coupled_wrist_friction", "thermal_friction")): _ONE_WRIST_AXIS,
    frozenset(("coupled_wrist_friction", "position_ripple")): _ONE_WRIST_AXIS,
}


def settled_by(names: Iterable[str], modelled: str | None = None) -> str:
    """The measurement that would tell the candidates ``names`` apart (a pair; for more, the text of
    every pair, each once; with ``modelled``, only the pairs of the candidate that was modelled).
    A robot's candidates are looked up by kind (``load_dependent_friction@A3``: its name before "@")."""
    names = list(dict.fromkeys(names))
    if "coupling" in names:
        return "a log with the other axes held still"
    texts = []
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            if modelled is not None and modelled not in (a, b):
                continue
            kinds = frozenset(x.split("@")[0] for x in (a, b))   # a robot's "position_ripple@A2" is a ripple
            t = _LOAD_SIDE if "gear_elasticity" in kinds else SETTLE.get(kinds)
            if t is None:
                t = f"a log where {a} and {b} give different torques (other positions, speeds or reversals)"
            if t not in texts:
                texts.append(t)
    return "; or ".join(texts)
