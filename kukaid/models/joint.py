"""Rigid-body model of one axis moving alone, eqs. (6)-(8): Izz qdd + Mx cos q (+ My sin q) + offset."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from kukaid.models.friction import CoulombViscous, MaxwellSlip, Stribeck


@dataclass(frozen=True)
class RigidBody:
    """Inertia and gravity of the links that one axis moves (links 3-6 for A3).

    Izz : moment of inertia about the joint, kg·m² (mass, kg, for a prismatic axis).
    Mx, My : gravity torque amplitudes, N·m: gravity torque = Mx cos(q) + My sin(q).
    offset : constant torque, N·m.
    """

    Izz: float
    Mx: float = 0.0
    My: float = 0.0
    offset: float = 0.0

    def gravity(self, q: np.ndarray | float) -> np.ndarray:
        q = np.asarray(q, dtype=float)
        return self.Mx * np.cos(q) + self.My * np.sin(q)

    def torque(self, q: np.ndarray, qdd: np.ndarray) -> np.ndarray:
        """Torque the motor must give to the rigid body (no friction), N·m."""
        return self.Izz * np.asarray(qdd, dtype=float) + self.gravity(q) + self.offset


@dataclass(frozen=True)
class AxisModel:
    """The identified model of one axis, as a parameter file describes it.

    ``predict_dynamic`` is the dynamic-mode prediction Γp of eq. (13); the quasi-static mode uses
    ``maxwell_slip`` through the torque-residual estimator (control stage).
    """

    rigid: RigidBody
    friction: Stribeck | CoulombViscous
    maxwell_slip: MaxwellSlip | None = None
    qd_thr: float = 0.0017
    effects: dict[str, Any] = field(default_factory=dict)

    def predict_dynamic(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
        """Γp = Izz qdd + gravity(q) + offset + F(qd), N·m (sliding friction everywhere)."""
        return self.rigid.torque(q, qdd) + self.friction(qd)
