"""Discrepancy workflow: where model and data disagree, which physical effect is missing, refit.

:func:`diagnose` (compare -> find -> add and refit -> repeat) returns a :class:`Diagnosis`;
the effects are terms of the one joint-torque model (:mod:`kukaid.models.effects`, names fixed);
which to try and when one is plausible is :mod:`kukaid.diagnose.candidates`, the evidence of a
round :mod:`kukaid.diagnose.evidence`, the refit :mod:`kukaid.diagnose.refit`, the statistics
:mod:`kukaid.diagnose.selection`, the noise floor :mod:`kukaid.diagnose.noise`, the PDF pages
:mod:`kukaid.diagnose.plots`.
"""
from kukaid.diagnose.candidates import CANDIDATES, NAMES
from kukaid.diagnose.workflow import Diagnosis, Step, diagnose, diagnose_signals

__all__ = ["diagnose", "diagnose_signals", "Diagnosis", "Step", "CANDIDATES", "NAMES"]
