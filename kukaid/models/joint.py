"""Rigid-body term of one axis moving alone, eqs. (6)-(8): Izz qdd + Mx cos q (+ My sin q) + offset."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kukaid.errors import FitError

GRAVITY_OPTIONS = ("cos", "cos+sin", "none")


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


def rigid_regressor(q: np.ndarray, qdd: np.ndarray, names: list[str]) -> np.ndarray:
    """Regressor columns of the rigid-body and offset parameters ``names`` (of Izz, Mx, My,
    offset): qdd, cos q, sin q, 1; an (n, len(names)) matrix."""
    col = {"Izz": lambda: qdd, "Mx": lambda: np.cos(q), "My": lambda: np.sin(q), "offset": lambda: np.ones_like(q)}
    return np.column_stack([col[k]() for k in names]) if names else np.zeros((np.size(q), 0))


def rigid_columns(q: np.ndarray, qdd: np.ndarray, gravity: str = "cos", offset: bool = False,
                  inertia: bool = True) -> tuple[list[str], np.ndarray]:
    """Regressor columns of the rigid body by the fit's options: names and the (n, k) matrix.

    ``gravity``: "cos" (Mx cos q), "cos+sin" (+ My sin q) or "none" (horizontal or prismatic
    axis); ``offset`` adds a constant torque; ``inertia`` the Izz qdd column.
    """
    if gravity not in GRAVITY_OPTIONS:
        raise FitError(f"gravity must be one of {GRAVITY_OPTIONS}, got '{gravity}'")
    names = (["Izz"] if inertia else []) + (["Mx"] if gravity != "none" else []) \
        + (["My"] if gravity == "cos+sin" else []) + (["offset"] if offset else [])
    return names, rigid_regressor(np.asarray(q), qdd, names)
