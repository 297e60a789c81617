"""Names and coefficients of the effects a diagnosis can add to a joint's torque model.

The terms themselves (regressors, options, plausibility) live in :mod:`kukaid.diagnose.candidates`;
this table is what the parameter file needs to read them back without importing the diagnosis."""
from __future__ import annotations

#: marks an effect stored by ``kukaid diagnose`` (its coefficients and settings are read back)
TAG = "kukaid.diagnose/1"

#: effect name -> names of its linear coefficients (in the parameter file's ``effects`` section)
COEFFICIENTS: dict[str, tuple[str, ...]] = {
    "gravity_sine": ("My",),
    "torque_offset": ("offset",),
    "position_ripple": ("a", "b"),
    "thermal_drift": ("c",),
    "load_dependent_friction": ("Fc_load",),
    "backlash": ("A",),
}

NAMES: tuple[str, ...] = tuple(COEFFICIENTS)
