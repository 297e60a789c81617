"""One interface to a robot, real or virtual: measurements out, commands in.

A :class:`Robot` has ``start() -> Block`` (the measurements so far, the robot standing),
``cycle(q_cmd, dt) -> Block`` (send the position reference ``q_cmd`` in rad, or None to let the
robot follow what it was given, let ``dt`` s pass, return the new measurements), ``now()`` (s, the
robot's clock), ``hold()`` (stop motion, keep the last reference) and ``close()``.

Implementations: :class:`kukaid.robot.sim.SimRobot` (the virtual KR C4) and
:class:`kukaid.robot.kvp.KvpRobot` (a KR C4 over KUKAVARPROXY with the KRL follower program).
``kukaid capture`` (simulator) and ``kukaid run-admittance`` (both) drive robots through it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np


@dataclass(frozen=True)
class Sample:
    """One measurement: ``t`` s (robot clock), ``q`` rad, ``tau`` N·m, ``tau_ext_true`` N·m (NaN unknown)
    of the controlled axis; on a robot read as a whole, ``q_all`` rad and ``tau_all`` N·m of every
    axis (A1..An; None otherwise)."""

    t: float
    q: float
    tau: float
    tau_ext_true: float = math.nan
    q_all: np.ndarray | None = None
    tau_all: np.ndarray | None = None


class Block(list):
    """The measurements of one cycle: a list of :class:`Sample` (of the controlled axis), with the
    whole record as arrays in :attr:`channels` when the robot has them (``time`` (N,), ``q``,
    ``tau``, ``q_cmd``, ``temp``, ``tau_ext_true`` as the robot logs them)."""

    def __init__(self, samples=(), channels: dict[str, np.ndarray] | None = None) -> None:
        super().__init__(samples)
        self.channels: dict[str, np.ndarray] = channels or {}


class Robot(Protocol):
    """What capture and the admittance loop need from a robot."""

    name: str

    def start(self) -> Block: ...

    def cycle(self, q_cmd: float | None, dt: float) -> Block: ...

    def now(self) -> float: ...

    def hold(self) -> None: ...

    def close(self) -> None: ...
