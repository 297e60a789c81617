"""Excitation experiments: trajectories with limit checks (:mod:`.trajectory`), exported as KRL by
:mod:`kukaid.krc.krl`."""
from kukaid.excite.trajectory import (IPO_DT, KINDS, MAX_DURATION, SCHEMA, AxisLimits, Trajectory, TrajectoryError, friction, generate, inertia,
                                      presliding, validation)

__all__ = ["IPO_DT", "KINDS", "MAX_DURATION", "SCHEMA", "AxisLimits", "Trajectory", "TrajectoryError", "friction", "generate", "inertia", "presliding",
           "validation"]
