"""Identification: pre-processing, Stribeck friction (IPOPT), Izz/Mx, Maxwell-slip, uncertainty.

Public interface (see ``briefs``/DESIGN): :func:`preprocess` -> :class:`Prepared`;
:func:`fit_dynamic` -> :class:`DynamicFit`; :func:`fit_axis` (the ``kukaid fit`` flow).
"""
from kukaid.identify.dynamic import DynamicFit, fit_dynamic
from kukaid.identify.filtering import Prepared, filter_defaults, preprocess
from kukaid.identify.fit import fit_axis, format_params, format_table, staged_friction
from kukaid.identify.least_squares import fit_rigid
from kukaid.identify.maxwell_slip_fit import MaxwellSlipFit, fit_maxwell_slip

__all__ = ["preprocess", "Prepared", "filter_defaults", "fit_dynamic", "DynamicFit", "fit_axis", "format_params", "format_table",
           "staged_friction", "fit_rigid", "fit_maxwell_slip", "MaxwellSlipFit"]
