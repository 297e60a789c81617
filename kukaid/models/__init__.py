"""Physical models of one joint: its terms (friction, rigid body, effects) and the one joint-torque model."""
from kukaid.models.friction import CoulombViscous, MaxwellSlip, Stribeck
from kukaid.models.joint import RigidBody
from kukaid.models.torque import JointTorqueModel

__all__ = ["Stribeck", "CoulombViscous", "MaxwellSlip", "RigidBody", "JointTorqueModel"]
