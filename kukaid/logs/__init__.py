"""Axis logs and their file formats: the log and its checks (:mod:`.core`), HDF5 (:mod:`.hdf5`, live
data :mod:`.writer`), CSV (:mod:`.csvlog`), MAT (:mod:`.matlog`), KUKA Trace (:mod:`.trace`, DIAdem
files :mod:`.diadem`); :func:`read_log` picks the reader by the file's suffix.  The formats import
the core, this registry imports the formats."""
from __future__ import annotations

from pathlib import Path
from typing import Any, Callable

from kukaid.errors import LogFormatError
from kukaid.jsonfile import file_kind
from kukaid.logs.core import (AxisLog, OtherKindError, check_each_recording_once, check_samples, check_units,
                              fingerprints, log_fingerprint, other_kind)
from kukaid.logs.csvlog import read_csv, write_csv
from kukaid.logs.hdf5 import read_hdf5, write_hdf5
from kukaid.logs.matlog import read_mat
from kukaid.logs.trace import read_trace
from kukaid.logs.writer import AxisLogWriter

#: per file suffix, the format it holds (as :func:`kukaid.jsonfile.file_kind` names a log of it) and its
#: reader, which takes the path and the format's own options
READERS: dict[str, tuple[str, Callable[..., AxisLog]]] = {
    ".h5": ("HDF5", lambda path, **_: read_hdf5(path)),
    ".hdf5": ("HDF5", lambda path, **_: read_hdf5(path)),
    ".csv": ("CSV", lambda path, **_: read_csv(path)),
    ".mat": ("MAT", read_mat),
    ".dat": ("KUKA Trace", read_trace),
    ".r64": ("KUKA Trace", read_trace),  # a Trace data file: its .dat header beside it
}

#: compressed logs, read transparently: the suffix before the compression's names the format
COMPRESSIONS = {".gz": "gzip", ".bz2": "bzip2", ".xz": "xz"}
_MODULES = {"gzip": "gzip", "bzip2": "bz2", "xz": "lzma"}


def format_suffix(path: str | Path) -> str:
    """The suffix naming a log's format, lower case: ``.csv`` of ``log.csv`` and of ``log.csv.gz``."""
    path = Path(path)
    return (Path(path.stem) if path.suffix.lower() in COMPRESSIONS else path).suffix.lower()


def read_log(path: str | Path, **options: Any) -> AxisLog:
    """Read an axis log, choosing the reader by file suffix (.h5/.hdf5, .csv, .mat, .dat/.r64);
    a log compressed with gzip, bzip2 or xz (``log.csv.gz``, ``.bz2``, ``.xz``) is decompressed
    on the fly (into a temporary file the reader opens, removed after)."""
    path = Path(path)
    comp = COMPRESSIONS.get(path.suffix.lower())
    suffix = format_suffix(path)
    if suffix not in READERS:
        expected = ", ".join(READERS)
        kind = file_kind(path) if comp is None and path.is_file() else None  # a table, a report, a parameter file
        if kind:
            raise OtherKindError(f"{path}: is {kind}, not an axis log (axis logs: {expected}, optionally compressed: "
                                 f"{', '.join(COMPRESSIONS)})")
        raise LogFormatError(f"{path}: unknown log format '{''.join(path.suffixes[-2:]).lower() or path.suffix}' "
                             f"(expected {expected}, optionally compressed: {', '.join(COMPRESSIONS)})")
    fmt, reader = READERS[suffix]
    if comp is None:
        return _read(reader, path, fmt, options)
    if fmt == "KUKA Trace":  # its data are in other files beside it, which one decompressed file does not bring
        raise LogFormatError(f"{path}: a KUKA Trace recording is several files (a .dat and a .r64 per module); "
                             "decompress them into one folder and give its .dat")
    return _read_compressed(path, comp, path.stem, lambda plain, **o: _read(reader, plain, fmt, o), options)


def _read(reader: Callable[..., AxisLog], path: Path, fmt: str, options: dict) -> AxisLog:
    """``reader`` on ``path``; a file it cannot read that is another of the toolkit's files (a report
    renamed .csv, an HDF5 log renamed .mat) is named as what it is."""
    try:
        return reader(path, **options)
    except LogFormatError as e:
        other = None if isinstance(e, OtherKindError) else other_kind(path, fmt)  # the HDF5 reader looks itself
        if other is not None:
            raise other from None
        raise


def _read_compressed(path: Path, comp: str, name: str, reader: Callable[..., AxisLog], options: dict) -> AxisLog:
    import importlib
    import shutil
    import tempfile

    if not path.exists():
        raise LogFormatError(f"{path}: no such file")
    mod = importlib.import_module(_MODULES[comp])
    with tempfile.TemporaryDirectory(prefix="kukaid_log_") as tmp:
        plain = Path(tmp) / name
        try:
            with mod.open(path, "rb") as src, open(plain, "wb") as dst:
                shutil.copyfileobj(src, dst, 1 << 20)
        except (OSError, EOFError, ValueError) as e:
            if isinstance(e, OSError) and e.errno is not None:      # a disk error, not a bad stream
                raise
            raise LogFormatError(f"{path}: not a valid {comp} file or truncated ({e})") from None
        try:
            log = reader(plain, **options)
        except LogFormatError as e:
            raise LogFormatError(str(e).replace(str(plain), str(path))) from None
    log.attrs["source_file"] = str(path)
    return log


__all__ = ["AxisLog", "AxisLogWriter", "COMPRESSIONS", "READERS", "format_suffix", "check_each_recording_once", "check_samples", "check_units", "fingerprints", "log_fingerprint", "read_csv", "read_hdf5",
           "read_log", "read_mat", "read_trace", "write_csv", "write_hdf5"]
