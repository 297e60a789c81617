"""Reading the toolkit's JSON inputs (parameter files, trajectories, limits, simulator truth)."""
from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from kukaid.errors import KukaidError, ParamFileError, SimConfigError, TrajectoryError


def read_json(path: str | Path, error: type[KukaidError] = KukaidError, what: str | None = None,
              schemas: tuple[str, ...] | None = None) -> Any:
    """Parse the JSON file ``path``; raise ``error`` with one line naming the file and the problem
    (an axis log given instead: said so, ``what`` the file should have been, by default from ``error``).
    ``schemas``: the toolkit's files (``"schema"``) the reader also takes; another of them is refused
    as what it is (``"is a kukaid.robot-trajectory/1 file, not a simulator configuration (JSON)"``)."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise error(f"{path}: no such file") from None
    except OSError as e:
        raise error(f"{path}: cannot read: {e.strerror}") from None
    text = raw.decode("utf-8-sig", errors="replace")  # a Windows editor's byte order mark first is allowed
    if not text.strip():
        raise error(f"{path}: empty file")
    try:
        d = json.loads(text)
    except json.JSONDecodeError as e:
        kind = _known_kind(raw)
        if kind is not None:
            raise error(f"{path}: is {kind}, not a {what or _expected(error)}") from None
        raise error(f"{path}: not valid JSON (line {e.lineno}, column {e.colno}: {e.msg})") from None
    schema = d.get("schema") if isinstance(d, dict) else None
    if schemas is not None and isinstance(schema, str) and schema not in schemas:
        raise error(f"{path}: is a {schema} file, not a {what or _expected(error)}")
    return d


def _log_format(raw: bytes) -> str | None:
    """"HDF5" or "CSV" when ``raw`` is an axis log (the HDF5 signature; the CSV log's header), else None."""
    if raw.startswith(b"\x89HDF\r\n\x1a\n"):
        return "HDF5"
    if raw.removeprefix(b"\xef\xbb\xbf").startswith(b"time_s,"):
        return "CSV"
    return None


def _output_kind(raw: bytes) -> str | None:
    """Which of the toolkit's outputs ``raw`` is: "an axis log (HDF5)" or "(CSV)", "a PDF (a report)", "a
    Parquet table (kukaid fleet)"; else None."""
    log = _log_format(raw)
    if log is not None:
        return f"an axis log ({log})"
    if raw.startswith(b"%PDF-"):
        return "a PDF (a report)"
    if raw.startswith(b"PAR1"):
        return "a Parquet table (kukaid fleet)"
    return None


def _urdf_kind(raw: bytes) -> str | None:
    """"a URDF (a robot's description, XML)" when ``raw`` begins as one (``fit --robot`` takes it), else None."""
    text = raw.removeprefix(b"\xef\xbb\xbf").lstrip()
    return "a URDF (a robot's description, XML)" if text[:1] == b"<" and b"<robot" in raw else None


def _manifest_kind(raw: bytes) -> str | None:
    """"a fleet manifest (CSV)" when ``raw``'s header names the columns robot, axis, date and path, else None."""
    head = raw.removeprefix(b"\xef\xbb\xbf").split(b"\n", 1)[0]
    return "a fleet manifest (CSV)" if {b"robot", b"axis", b"date", b"path"} <= {
        c.strip().strip(b'"') for c in head.split(b",")} else None


def _known_kind(raw: bytes) -> str | None:
    """Which of the toolkit's other files ``raw`` begins as (an output, a URDF, a fleet manifest), else None."""
    return _output_kind(raw) or _urdf_kind(raw) or _manifest_kind(raw)


def file_kind(path: str | Path) -> str | None:
    """What else of the toolkit's files ``path`` is, by its first bytes, for a reader it is not for:
    "an axis log (HDF5)", "a PDF (a report)", "a fleet manifest (CSV)", ...; None when unknown or unreadable."""
    try:
        with open(path, "rb") as f:
            raw = f.read(4096)
    except OSError:
        return None
    kind = _known_kind(raw)
    if kind is not None:
        return kind
    text = raw.removeprefix(b"\xef\xbb\xbf")
    if text.lstrip()[:1] == b"{":
        return "a JSON file"
    return None


def _expected(error: type[KukaidError]) -> str:
    for kind, name in ((SimConfigError, "simulator configuration (JSON)"), (ParamFileError, "parameter file (JSON)"),
                       (TrajectoryError, "trajectory file (JSON)")):
        if issubclass(error, kind):
            return name
    return "JSON file"


def jsonable(x: Any) -> Any:
    """``x`` with numpy scalars made Python numbers and non-finite floats made None (JSON has no NaN)."""
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, np.generic):
        x = x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x
