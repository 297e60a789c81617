"""Compatibility: the axis log and its HDF5 and CSV formats under their former module name.

The code lives in :mod:`kukaid.logs.core` (:class:`AxisLog`, checks), :mod:`kukaid.logs.hdf5`,
:mod:`kukaid.logs.writer` and :mod:`kukaid.logs.csvlog`; import from :mod:`kukaid.logs`.
"""
from __future__ import annotations

from kukaid.logs.core import (CHANNELS, FORMAT, JOINT_TYPES, MAX_REVOLUTE_RAD, MAX_SAMPLE_INTERVAL_S,
                              OPTIONAL_CHANNELS, AxisLog, channel_unit, check_samples, check_units)
from kukaid.logs.csvlog import read_csv, write_csv
from kukaid.logs.hdf5 import read_hdf5, write_hdf5
from kukaid.logs.writer import AxisLogWriter

__all__ = ["CHANNELS", "FORMAT", "JOINT_TYPES", "MAX_REVOLUTE_RAD", "MAX_SAMPLE_INTERVAL_S", "OPTIONAL_CHANNELS",
           "AxisLog", "AxisLogWriter", "channel_unit", "check_samples", "check_units", "read_csv", "read_hdf5",
           "write_csv", "write_hdf5"]
