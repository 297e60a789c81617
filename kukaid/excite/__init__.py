"""Excitation trajectories of the paper's experiments, as a KR C4 can execute them.

A :class:`Trajectory` is the commanded position ``q`` (rad) of one axis, sampled at the KR C4
interpolation (IPO) rate of 12 ms, with the experiment's parameters.  Four generators build the
experiments of Yao et al. 2018:

``friction``
    Constant-velocity moves in both directions over the same position window, at a list of
    speeds (eqs. 2-4: Γf = (Γ+ - Γ-)/2 at equal q).  Cosine velocity ramps (continuous
    acceleration, bounded jerk) and a settle time at standstill between moves.  Slow speeds use
    a shorter window so that every plateau lasts about ``plateau`` seconds; the plateau times
    are recorded in ``params["plateaus"]``.
``inertia``
    A sine (default period 4 s, at least 3 full periods) whose amplitude is ramped in and out
    with a raised-cosine envelope (section 2.2, eqs. 6-8).
``presliding``
    The initiation stage of section 3.4: a small move (about 1 degree) and a standstill (the
    virtual KR C4 adds ambient vibration from axis 6), then a few quasi-static reversals of
    decreasing amplitude around the stop position.  The reversals are slower than qd_thr and
    larger than the Maxwell-slip saturation displacements W/k (2e-4 rad for the paper's
    elements) at first, smaller later, so the torque traces nested hysteresis loops with
    nonlocal memory: what a Maxwell-slip fit (eqs. 9-10) needs.
``validation``
    A mixed trajectory: a multi-sine (Schroeder phases, ramped) followed by point-to-point moves
    of different speeds and sizes with standstill between them (mode switches).

Every generator checks the result against :class:`AxisLimits` (A3 of a KR 6 R700 sixx unless
told otherwise) and raises :class:`~kukaid.errors.LimitError` naming the limit, the value and
the time.  Everything here is SI (rad, rad/s, rad/s², s).
"""
from __future__ import annotations

from typing import Any, Callable

from kukaid.errors import TrajectoryError
from kukaid.excite.friction import friction
from kukaid.excite.inertia import inertia
from kukaid.excite.presliding import presliding
from kukaid.excite.trajectory import IPO_DT, KINDS, MAX_DURATION, SCHEMA, Trajectory
from kukaid.excite.validation import validation
from kukaid.models.limits import AxisLimits

GENERATORS: dict[str, Callable[..., Trajectory]] = {
    "friction": friction, "inertia": inertia, "presliding": presliding, "validation": validation,
}


def generate(kind: str, **options: Any) -> Trajectory:
    """Build the trajectory of experiment ``kind`` (one of :data:`KINDS`) with ``options``."""
    if kind not in GENERATORS:
        raise TrajectoryError(f"unknown experiment kind '{kind}' (known: {', '.join(KINDS)})")
    return GENERATORS[kind](**options)


__all__ = ["GENERATORS", "IPO_DT", "KINDS", "MAX_DURATION", "SCHEMA", "AxisLimits", "Trajectory", "TrajectoryError",
           "friction", "generate", "inertia", "presliding", "validation"]
