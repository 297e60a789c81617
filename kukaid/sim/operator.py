"""A simulated operator: a person's hand as an external torque on the link (N·m).

Each operator is a callable ``fn(t, q, qd) -> torque`` for
:meth:`kukaid.sim.VirtualKRC4.set_external_torque` (evaluated once per 12 ms sample period).
Positive torque pushes the joint towards positive q.

* :class:`PushOperator` — a smooth push of ``amplitude`` N·m (raised-cosine ramps) held for a few
  seconds, then released; it does not react to the motion (open loop).
* :class:`HandOperator` — a spring-damper hand whose own target moves point to point (minimum
  jerk) and drags the joint along: ``tau = K (q_hand(t) - q) - B qd``, limited to ``max_torque``;
  it lets go at ``t_release``.  The torque depends on how readily the robot follows, so it is the
  operator on which damping choices differ (the paper's experiment 4: a point-to-point move by hand).

:func:`make_operator` draws a seeded variation (size, timing) of either kind, or (``"human"``, the
default of the admittance experiments) a person's arm of :mod:`kukaid.sim.human`: an impedance
around an intended minimum-jerk motion that reacts, co-contracts and lets go when on target.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from kukaid.errors import KukaidError

OPERATORS = ("human", "push", "pull", "hand")


def _ramp(x: float) -> float:
    """Raised-cosine ramp 0 -> 1 for x in [0, 1]."""
    x = min(max(x, 0.0), 1.0)
    return 0.5 - 0.5 * math.cos(math.pi * x)


def _min_jerk(x: float) -> float:
    x = min(max(x, 0.0), 1.0)
    return x ** 3 * (10.0 - 15.0 * x + 6.0 * x * x)


@dataclass(frozen=True)
class PushOperator:
    """Smooth push: 0 until ``t_start`` s, ramp (``ramp`` s) to ``amplitude`` N·m, hold until
    ``t_start + duration``, ramp back to 0 (the release)."""

    amplitude: float = 15.0
    t_start: float = 2.0
    duration: float = 3.0
    ramp: float = 0.5

    def __call__(self, t: float, q: float = 0.0, qd: float = 0.0) -> float:
        up = _ramp((t - self.t_start) / self.ramp)
        down = _ramp((self.t_start + self.duration - t) / self.ramp)
        return self.amplitude * min(up, down)

    @property
    def t_end(self) -> float:
        return self.t_start + self.duration


@dataclass(frozen=True)
class HandOperator:
    """Spring-damper hand dragging the joint from ``q_start`` by ``distance`` rad.

    The hand's target moves with a minimum-jerk profile from ``t_start`` over ``move_time`` s;
    torque ``K (q_hand - q) - B qd`` (``stiffness`` N·m/rad, ``damping`` N·m·s/rad) bounded by
    ``max_torque`` N·m, grasped smoothly over ``ramp`` s and released (zero) from ``t_release``.
    """

    q_start: float = 0.0
    distance: float = 0.3
    t_start: float = 2.0
    move_time: float = 3.0
    stiffness: float = 150.0
    damping: float = 10.0
    max_torque: float = 40.0
    t_release: float = 7.0
    ramp: float = 0.3

    def target(self, t: float) -> float:
        return self.q_start + self.distance * _min_jerk((t - self.t_start) / self.move_time)

    def __call__(self, t: float, q: float, qd: float) -> float:
        if t < self.t_start or t >= self.t_release + self.ramp:
            return 0.0
        tau = self.stiffness * (self.target(t) - q) - self.damping * qd
        tau = max(-self.max_torque, min(self.max_torque, tau))
        grip = min(_ramp((t - self.t_start) / self.ramp), _ramp((self.t_release + self.ramp - t) / self.ramp))
        return grip * tau

    @property
    def t_end(self) -> float:
        return self.t_release + self.ramp


def make_operator(kind: str, seed: int = 0, q0: float = 0.0, t_start: float = 2.0,
                  amplitude: float | None = None, distance: float | None = None, grip: str | None = None):
    """A seeded operator of ``kind`` ("human": :func:`kukaid.sim.human.make_human`, with ``grip``;
    "push"; or "pull"/"hand": the open-loop spring-damper hand).

    The seed varies the push size (12-18 N·m) and duration (2.5-3.5 s), or the hand's travel
    (0.25-0.35 rad, sign from the seed), move time (2.5-3.5 s) and stiffness (120-180 N·m/rad).
    """
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 0x0b5]))
    if kind == "push":
        amp = float(rng.uniform(12.0, 18.0)) if amplitude is None else float(amplitude)
        sign = 1.0 if rng.random() < 0.5 else -1.0
        return PushOperator(amplitude=sign * amp if amplitude is None else amp, t_start=t_start,
                            duration=float(rng.uniform(2.5, 3.5)), ramp=0.5)
    if kind == "human":
        from kukaid.sim.human import make_human

        return make_human(seed, q0, t_start, grip=grip, distance=distance)
    if kind in ("pull", "hand"):
        d = float(rng.uniform(0.25, 0.35)) * (1.0 if rng.random() < 0.5 else -1.0)
        if distance is not None:
            d = float(distance)
        mt = float(rng.uniform(2.5, 3.5))
        return HandOperator(q_start=q0, distance=d, t_start=t_start, move_time=mt,
                            stiffness=float(rng.uniform(120.0, 180.0)), damping=10.0,
                            t_release=t_start + mt + 1.5)
    raise KukaidError(f"operator: unknown kind {kind!r}; choose one of {', '.join(OPERATORS)}")


def operator_params(op) -> dict | None:
    """What defines ``op`` (JSON-able), for a run's log."""
    if op is None:
        return None
    return op.params() if hasattr(op, "params") else dict(op.__dict__)
