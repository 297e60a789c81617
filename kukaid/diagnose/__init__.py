"""Discrepancy workflow: where model and data disagree, which physical effect is missing, refit.

:func:`diagnose` (compare -> find -> add and refit -> repeat) returns a :class:`Diagnosis`;
the candidate effects are in :mod:`kukaid.diagnose.candidates` (names fixed: gravity_sine,
torque_offset, position_ripple, thermal_drift, load_dependent_friction, backlash), the statistics
in :mod:`kukaid.diagnose.selection`, the noise floor in :mod:`kukaid.diagnose.noise`, the PDF
pages in :mod:`kukaid.diagnose.plots`.
"""
from kukaid.diagnose.candidates import CANDIDATES, NAMES
from kukaid.diagnose.workflow import Diagnosis, Step, diagnose, diagnose_signals

__all__ = ["diagnose", "diagnose_signals", "Diagnosis", "Step", "CANDIDATES", "NAMES"]
