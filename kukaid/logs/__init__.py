"""Axis logs and their file formats: HDF5 and CSV (:mod:`.axislog`), MAT (:mod:`.matlog`), KUKA Trace
(:mod:`.trace`); :func:`read_log` picks the reader by the file's suffix."""
from __future__ import annotations

from pathlib import Path
from typing import Any, Callable

from kukaid.errors import LogFormatError
from kukaid.logs.axislog import (AxisLog, AxisLogWriter, check_samples, check_units, read_csv, read_hdf5,
                                 write_csv, write_hdf5)
from kukaid.logs.matlog import read_mat
from kukaid.logs.trace import read_trace

#: one reader per file suffix; a reader takes the path and the format's own options
READERS: dict[str, Callable[..., AxisLog]] = {
    ".h5": lambda path, **_: read_hdf5(path),
    ".hdf5": lambda path, **_: read_hdf5(path),
    ".csv": lambda path, **_: read_csv(path),
    ".mat": read_mat,
    ".dat": read_trace,
}


def read_log(path: str | Path, **options: Any) -> AxisLog:
    """Read an axis log, choosing the reader by file suffix (.h5/.hdf5, .csv, .mat, .dat)."""
    path = Path(path)
    reader = READERS.get(path.suffix.lower())
    if reader is None:
        raise LogFormatError(f"{path}: unknown log format '{path.suffix.lower()}' "
                             f"(expected {', '.join(READERS)})")
    return reader(path, **options)


__all__ = ["AxisLog", "AxisLogWriter", "READERS", "check_samples", "check_units", "read_csv", "read_hdf5",
           "read_log", "read_mat", "read_trace", "write_csv", "write_hdf5"]
