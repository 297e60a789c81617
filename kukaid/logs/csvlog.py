"""Axis logs as CSV: one row per sample, degrees and N·m as the KRC gives them."""
from __future__ import annotations

import csv
import re
from pathlib import Path
from typing import Any

import numpy as np

from kukaid.atomic import atomic_path
from kukaid.errors import LogFormatError
from kukaid.logs.core import CHANNELS, AxisLog, _os_errors, check_samples, check_units

# column suffix -> (channel, joint type or None for either, scale to SI)
_DEG = np.pi / 180.0
_CSV_SUFFIX = {
    "deg": ("q", "revolute", _DEG),
    "rad": ("q", "revolute", 1.0),
    "m": ("q", "prismatic", 1.0),
    "Nm": ("tau", "revolute", 1.0),
    "N": ("tau", "prismatic", 1.0),
    "cmd_deg": ("q_cmd", "revolute", _DEG),
    "cmd_rad": ("q_cmd", "revolute", 1.0),
    "cmd_m": ("q_cmd", "prismatic", 1.0),
    "temp_C": ("temp", None, 1.0),
    "ext_true_Nm": ("tau_ext_true", "revolute", 1.0),
    "ext_true_N": ("tau_ext_true", "prismatic", 1.0),
}
_CSV_COL = re.compile(r"^A(\d{1,2})_(\w+)$")


def read_csv(path: str | Path) -> AxisLog:
    """Read a CSV axis log (``time_s``, ``A{i}_deg``/``_rad``/``_m``, ``A{i}_Nm``/``_N``, ...)."""
    path = Path(path)
    if not path.exists():
        raise LogFormatError(f"{path}: no such file")
    with _os_errors(path, "cannot read"), open(path, "rb") as f:
        _check_text(path, f.read(4096))
    # Excel's 'CSV UTF-8' begins with a byte order mark
    with _os_errors(path, "cannot read"), open(path, encoding="utf-8-sig", errors="replace") as f:
        first = f.readline().rstrip("\r\n")
    if not first.strip():
        raise LogFormatError(f"{path}: empty file (expected a header row)")
    header = [_unquote(h).strip() for h in next(csv.reader([first]), [""])]  # names in quotes, as numbers in quotes
    if header[0] != "time_s":
        sep = next((c for c in (";", "\t") if c in header[0]), None) if len(header) == 1 else None
        if sep is not None:  # a spreadsheet's export where the comma is the decimal mark
            line = first.strip()
            line = line if len(line) <= 60 else line[:57] + "..."
            raise LogFormatError(f"{path}: columns must be separated by commas, not {sep!r}, with '.' as the "
                                 f"decimal mark (a header as 'time_s,A3_deg,A3_Nm,...'; this one is '{line}')")
        raise LogFormatError(f"{path}: first column must be 'time_s', found '{header[0]}'")
    cols: dict[tuple[int, str], tuple[int, float]] = {}
    joint_of: dict[int, str] = {}
    rev_q: dict[int, str] = {}  # the unit suffix of each revolute position column (deg, rad)
    for j, name in enumerate(header[1:], start=1):
        m = _CSV_COL.match(name)
        if not m or m.group(2) not in _CSV_SUFFIX:
            raise LogFormatError(
                f"{path}: unknown column '{name}' (column {j + 1}); expected A<i>_ with a unit suffix in "
                f"{sorted(_CSV_SUFFIX)}"
            )
        axis = int(m.group(1))
        chan, jt, scale = _CSV_SUFFIX[m.group(2)]
        if (axis, chan) in cols:
            raise LogFormatError(f"{path}: axis A{axis} has two '{chan}' columns (column {j + 1}: '{name}')")
        if jt is not None:
            if joint_of.setdefault(axis, jt) != jt:
                raise LogFormatError(f"{path}: column '{name}' mixes revolute and prismatic units for A{axis}")
        cols[(axis, chan)] = (j, scale)
        if chan == "q" and jt == "revolute":
            rev_q[axis] = m.group(2)
    axes = sorted({a for a, _ in cols})
    if not axes:
        raise LogFormatError(f"{path}: no axis columns in the header")
    for a in axes:
        for need in ("q", "tau"):
            if (a, need) not in cols:
                suffix = (("m" if need == "q" else "N") if joint_of.get(a) == "prismatic" else "Nm" if need == "tau"
                          else rev_q[min(rev_q)] if rev_q else "deg")  # as the log's other revolute positions
                raise LogFormatError(f"{path}: missing column A{a}_{suffix} (axis A{a} has no '{need}')")
    arr, lines = _body(path, len(header))
    data: dict[str, np.ndarray | None] = {}
    for chan in CHANNELS:
        present = [(a, chan) in cols for a in axes]
        if not any(present):
            data[chan] = None
            continue
        if not all(present):
            missing = [a for a, p in zip(axes, present) if not p]
            raise LogFormatError(f"{path}: channel '{chan}' is present for some axes but not A{missing[0]}")
        data[chan] = np.column_stack([arr[:, cols[(a, chan)][0]] * cols[(a, chan)][1] for a in axes])
    time = arr[:, 0]
    check_samples(time, data, axes, str(path), row_offset=2, row_word="line", row_lines=lines)
    joint = tuple(joint_of.get(a, "revolute") for a in axes)
    labels: dict[Any, str] = {(chan, a): header[j] for (a, chan), (j, _) in cols.items()}
    check_units(time, data, axes, joint, str(path), labels={**labels, "time": "time_s"})
    # the position columns by name, for a warning about their unit (kukaid.identify.adequacy.unit_warnings)
    positions = {str(a): labels[("q", a)] for a in axes}
    return AxisLog(time=time, axes=tuple(axes), joint=joint, attrs={"source_file": str(path),
                                                                     "position_columns": positions}, **data)


def _check_text(path: Path, head: bytes) -> None:
    """Refuse a file that is not UTF-8 text with one line saying what it is (its header, read as UTF-8,
    was printed with NUL bytes and replacement characters in the error: new-user trial 22)."""
    if head.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise LogFormatError(f"{path}: is UTF-16 text (Excel's 'Unicode Text', a Windows PowerShell redirect); "
                             "save it as UTF-8 ('CSV UTF-8')")
    if b"\x00" in head.split(b"\n", 1)[0]:  # NUL bytes after the header: a log cut short (_body says it)
        what = " (a ZIP archive: an Excel workbook .xlsx?)" if head.startswith(b"PK\x03\x04") else ""
        raise LogFormatError(f"{path}: is a binary file{what}, not CSV text; export the log as CSV")


def _body(path: Path, width: int) -> tuple[np.ndarray, np.ndarray | None]:
    """The data rows under the header, (n, width) floats, and each row's line in the file (None when row
    r is line r + 2).  pandas' C parser reads them (a 1-hour 200 Hz
    six-axis log, 170 MB: 0.9 s CPU and 0.4 GB, where Python line by line took 5.1 s and 1 GB:
    ``benchmarks/log_read_speed.py``); what it cannot read as ``width`` numbers a row (a short row, which it
    fills with NaN, a word, a line of spaces, a blank line) is read again line by line, for the line and
    field to name (a blank line read by pandas shifted every later row's line: a NaN on line 53 was
    named at line 52)."""
    import pandas as pd

    try:
        with _os_errors(path, "cannot read"):
            arr = pd.read_csv(path, skiprows=1, header=None, names=range(width), dtype=float, engine="c",
                              encoding="utf-8-sig", encoding_errors="replace",
                              skip_blank_lines=False).to_numpy()
    except ValueError:  # pandas' ParserError and EmptyDataError are ValueErrors
        arr = None
    if arr is not None and arr.shape[0] and not np.isnan(arr).any():
        return arr, None
    rows, lines = [], []
    with _os_errors(path, "cannot read"), open(path, encoding="utf-8-sig", errors="replace") as f:
        next(f)
        for k, ln in enumerate(f, start=2):
            if not ln.strip():
                continue
            if "\x00" in ln:  # a file extended but never written: a writer killed, a power cut
                raise LogFormatError(f"{path}: line {k} holds NUL bytes, not text: the file was cut short while "
                                     f"written (a crash, a power cut?); the {k - 2} lines of data above it can be kept "
                                     f"by removing line {k} and after")
            # numbers in quotes, as pandas reads them (a comma inside the quotes is no separator)
            parts = [_unquote(p) for p in next(csv.reader([ln.rstrip("\r\n")]), [""])]
            if len(parts) != width:
                raise LogFormatError(f"{path}: line {k} has {len(parts)} fields, the header has {width}")
            try:
                rows.append([float(p) for p in parts])
                lines.append(k)
            except ValueError:
                bad = next(p for p in parts if not _is_float(p))
                comma = (" (',' as the decimal mark: kukaid reads '.', as in '1.5')"
                         if re.fullmatch(r"\s*[-+]?\d*,\d+\s*", bad) else "")
                raise LogFormatError(f"{path}: line {k}: '{bad.strip()}' is not a number{comma}") from None
    if not rows:
        raise LogFormatError(f"{path}: no data rows after the header")
    return np.asarray(rows, dtype=float), np.asarray(lines)


def _unquote(field: str) -> str:
    f = field.strip()
    return f[1:-1] if len(f) >= 2 and f[0] == f[-1] == '"' else field


def _is_float(s: str) -> bool:
    try:
        float(s)
        return True
    except ValueError:
        return False


def write_csv(log: AxisLog, path: str | Path, angle_unit: str = "deg") -> None:
    """Write ``log`` as CSV (atomically).  Revolute positions in degrees (or ``rad``).

    A folder that cannot be written is a :class:`KukaidError` naming ``path`` and the reason.
    """
    if angle_unit not in ("deg", "rad"):
        raise ValueError("angle_unit must be 'deg' or 'rad'")
    names, cols = ["time_s"], [log.time]
    suffix = {  # channel -> (revolute suffix, prismatic suffix)
        "q": (angle_unit, "m"),
        "tau": ("Nm", "N"),
        "q_cmd": ("cmd_" + angle_unit, "cmd_m"),
        "temp": ("temp_C", "temp_C"),
        "tau_ext_true": ("ext_true_Nm", "ext_true_N"),
    }
    for chan in CHANNELS:
        x = getattr(log, chan)
        if x is None:
            continue
        for c, (a, jt) in enumerate(zip(log.axes, log.joint)):
            s = suffix[chan][jt == "prismatic"]
            names.append(f"A{a}_{s}")
            scale = 1.0 / _DEG if s.endswith("deg") else 1.0
            cols.append(x[:, c] * scale)
    table = np.column_stack(cols)
    with atomic_path(path) as tmp, _os_errors(path):
        with open(tmp, "w") as fh:
            fh.write(",".join(names) + "\n")
            for row in table:
                fh.write(",".join(repr(float(v)) for v in row) + "\n")
