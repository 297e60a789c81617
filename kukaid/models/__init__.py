"""Physical models of one axis: friction (Stribeck, Maxwell-slip) and the rigid body."""
from kukaid.models.friction import CoulombViscous, MaxwellSlip, Stribeck
from kukaid.models.joint import AxisModel, RigidBody

__all__ = ["Stribeck", "CoulombViscous", "MaxwellSlip", "RigidBody", "AxisModel"]
