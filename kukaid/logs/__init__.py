"""Axis logs and their file formats: the log and its checks (:mod:`.core`), HDF5 (:mod:`.hdf5`, live
data :mod:`.writer`), CSV (:mod:`.csvlog`), MAT (:mod:`.matlog`), KUKA Trace (:mod:`.trace`, DIAdem
files :mod:`.diadem`); :func:`read_log` picks the reader by the file's suffix.  The formats import
the core, this registry imports the formats."""
from __future__ import annotations

from pathlib import Path
from typing import Any, Callable

from kukaid.errors import LogFormatError
from kukaid.logs.core import AxisLog, check_samples, check_units
from kukaid.logs.csvlog import read_csv, write_csv
from kukaid.logs.hdf5 import read_hdf5, write_hdf5
from kukaid.logs.matlog import read_mat
from kukaid.logs.trace import read_trace
from kukaid.logs.writer import AxisLogWriter

#: one reader per file suffix; a reader takes the path and the format's own options
READERS: dict[str, Callable[..., AxisLog]] = {
    ".h5": lambda path, **_: read_hdf5(path),
    ".hdf5": lambda path, **_: read_hdf5(path),
    ".csv": lambda path, **_: read_csv(path),
    ".mat": read_mat,
    ".dat": read_trace,
    ".r64": read_trace,  # a Trace data file: its .dat header beside it
}


def read_log(path: str | Path, **options: Any) -> AxisLog:
    """Read an axis log, choosing the reader by file suffix (.h5/.hdf5, .csv, .mat, .dat/.r64)."""
    path = Path(path)
    reader = READERS.get(path.suffix.lower())
    if reader is None:
        raise LogFormatError(f"{path}: unknown log format '{path.suffix.lower()}' "
                             f"(expected {', '.join(READERS)})")
    return reader(path, **options)


__all__ = ["AxisLog", "AxisLogWriter", "READERS", "check_samples", "check_units", "read_csv", "read_hdf5",
           "read_log", "read_mat", "read_trace", "write_csv", "write_hdf5"]
