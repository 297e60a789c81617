"""A fleet's logs: a manifest CSV (``robot,axis,date,path``) or a folder tree matched by a pattern
(``{robot}/{date}/*.h5``), read into :class:`Entry` values; content hashes for resuming."""
from __future__ import annotations

import csv
import hashlib
import re
from dataclasses import dataclass
from pathlib import Path

from kukaid.errors import KukaidError
from kukaid.logs import COMPRESSIONS, format_suffix

#: columns a manifest must have (``axis`` may be empty for a whole-arm log)
MANIFEST_COLUMNS = ("robot", "axis", "date", "path")
#: suffixes of logs the folder scan picks up (the readers of :mod:`kukaid.logs`)
LOG_SUFFIXES = (".h5", ".hdf5", ".csv", ".mat")
DEFAULT_PATTERN = "{robot}/{date}/*"
_DATE = re.compile(r"^\d{4}-\d{2}-\d{2}$")


class ManifestError(KukaidError):
    """The fleet's manifest or folder pattern is malformed (the whole batch stops: nothing is fitted)."""


@dataclass(frozen=True)
class Entry:
    """One log of the fleet.

    Parameters
    ----------
    robot : the robot's name (any text without a comma).
    axis : KUKA axis number the log is of, or None for a whole-arm log (or: the log's only axis).
    date : the day the log was recorded, ``YYYY-MM-DD``.
    path : absolute path of the log file.
    name : the path as the manifest or the scan gives it (relative to the manifest or the folder).
    axis_from : what said the axis, for a message when the log is of another one.
    """

    robot: str
    axis: int | None
    date: str
    path: str
    name: str
    axis_from: str = "the manifest"


def content_hash(path: str | Path, chunk: int = 1 << 20) -> str:
    """SHA-256 of the file's bytes (hex): a log is known by its content, whatever its name."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while True:
            b = f.read(chunk)
            if not b:
                return h.hexdigest()
            h.update(b)


def _axis(text: str, where: str) -> int | None:
    text = (text or "").strip()
    if not text:
        return None
    t = text[1:] if text[:1] in "Aa" else text
    if not t.isdigit() or not 1 <= int(t) <= 12:
        raise ManifestError(f"{where}: axis '{text}' is not an axis number 1 to 12 (or empty for a whole-arm log)")
    return int(t)


def _date(text: str, where: str) -> str:
    """A day of the calendar as YYYY-MM-DD (2026-02-30 is not one: the wear analysis reads them as dates)."""
    import datetime

    text = (text or "").strip()
    try:
        ok = bool(_DATE.match(text)) and datetime.date.fromisoformat(text).isoformat() == text
    except ValueError:
        ok = False
    if not ok:
        raise ManifestError(f"{where}: date '{text}' is not a date YYYY-MM-DD")
    return text


def _other_kind(path: Path) -> str | None:
    """"is a Parquet table (kukaid fleet), not a fleet manifest (CSV) ..." when ``path`` is another of the
    toolkit's files (the fleet table given as the input said "not a text CSV file": new-user trial 22)."""
    from kukaid.jsonfile import file_kind

    kind = file_kind(path)
    if kind is None or kind.startswith("a fleet manifest"):
        return None
    return (f"is {kind}, not a fleet manifest (CSV with the columns {','.join(MANIFEST_COLUMNS)}) or a folder "
            "of logs")


def read_manifest(path: str | Path) -> list[Entry]:
    """Entries of a manifest CSV with a header ``robot,axis,date,path`` (paths relative to the manifest).

    Raises
    ------
    ManifestError : a missing column, an empty robot, a bad axis or date (naming the line).
    """
    path = Path(path)
    base = path.resolve().parent
    try:
        with open(path, newline="", encoding="utf-8-sig") as f:  # Excel's 'CSV UTF-8' begins with a mark
            rows = list(csv.reader(f))
    except UnicodeDecodeError:
        raise ManifestError(f"{path}: {_other_kind(path) or 'not a text CSV file'}") from None
    if not rows:
        raise ManifestError(f"{path}: empty manifest; expected a header row {','.join(MANIFEST_COLUMNS)}")
    head = [h.strip().lower() for h in rows[0]]
    missing = [c for c in MANIFEST_COLUMNS if c not in head]
    if missing:
        other = _other_kind(path)  # an axis log given for the manifest
        if other is not None:
            raise ManifestError(f"{path}: {other}")
        sep = next((c for c in ";\t|" if len(rows[0]) == 1 and c in rows[0][0]), None)
        raise ManifestError(f"{path}: manifest lacks column(s) {', '.join(missing)} "
                            f"(header must name {','.join(MANIFEST_COLUMNS)})"
                            + (f"; its header is split by {sep!r}, and a manifest's columns by commas" if sep else ""))
    col = {c: head.index(c) for c in MANIFEST_COLUMNS}
    out = []
    for i, row in enumerate(rows[1:], start=2):
        if not any(x.strip() for x in row):
            continue
        where = f"{path}: line {i}"
        if len(row) < len(head):
            raise ManifestError(f"{where}: {len(row)} fields, the header has {len(head)}")
        robot, name = row[col["robot"]].strip(), row[col["path"]].strip()
        if not robot or not name:
            raise ManifestError(f"{where}: robot and path must not be empty")
        out.append(Entry(robot, _axis(row[col["axis"]], where), _date(row[col["date"]], where),
                         str((base / name).resolve()), name))
    if not out:
        raise ManifestError(f"{path}: the manifest lists no logs")
    return out


def pattern_regex(pattern: str) -> re.Pattern:
    """The regular expression of a folder pattern: ``{robot}``, ``{date}`` and ``{axis}`` name one
    path component (``{axis}`` may read ``A3`` or ``3``), ``*`` any text within a component."""
    if "{robot}" not in pattern or "{date}" not in pattern:
        raise ManifestError(f"pattern '{pattern}': must contain {{robot}} and {{date}}, e.g. {DEFAULT_PATTERN}.h5")
    out, i = "", 0
    fields = {"{robot}": r"(?P<robot>[^/]+?)", "{date}": r"(?P<date>\d{4}-\d{2}-\d{2})",
              "{axis}": r"[Aa]?(?P<axis>\d{1,2})"}
    while i < len(pattern):
        for k, v in fields.items():
            if pattern.startswith(k, i):
                out += v
                i += len(k)
                break
        else:
            c = pattern[i]
            out += "[^/]*" if c == "*" else re.escape(c)
            i += 1
    return re.compile(out + r"\Z")


def scan_folder(root: str | Path, pattern: str = DEFAULT_PATTERN, unmatched: list[str] | None = None) -> list[Entry]:
    """Entries of the logs under ``root`` whose relative path matches ``pattern`` (see
    :func:`pattern_regex`); only files with a log suffix (.h5, .hdf5, .csv, .mat), optionally
    compressed (``A3.csv.gz``, ``.bz2``, ``.xz``: read as every command reads them).  The relative
    paths of files with a log suffix that do not match are appended to ``unmatched`` (when given):
    a log in a misnamed folder is not run, and the caller says so."""
    root = Path(root)
    rx = pattern_regex(pattern)
    out = []
    for p in sorted(root.rglob("*")):
        if not p.is_file() or format_suffix(p) not in LOG_SUFFIXES or any(s.startswith(".") for s in p.parts[-3:]):
            continue
        rel = p.relative_to(root).as_posix()
        m = rx.match(rel)
        if m is None:
            if unmatched is not None:
                unmatched.append(rel)
            continue
        g = m.groupdict()
        where = f"{root}/{rel}"
        out.append(Entry(g["robot"], _axis(g.get("axis") or "", where), _date(g["date"], where), str(p.resolve()), rel,
                         f"its name (--pattern '{pattern}')"))
    if not out:
        raise ManifestError(f"{root}: no log matches the pattern '{pattern}' (logs: {', '.join(LOG_SUFFIXES)}, "
                            f"optionally compressed: {', '.join(COMPRESSIONS)})")
    return out


def read_input(source: str | Path, pattern: str | None = None, unmatched: list[str] | None = None) -> list[Entry]:
    """The fleet's logs from a manifest CSV file or a folder (scanned with ``pattern``; the log files
    it does not match are appended to ``unmatched``, see :func:`scan_folder`)."""
    source = Path(source)
    if source.is_dir():
        return scan_folder(source, pattern or DEFAULT_PATTERN, unmatched)
    if pattern is not None:
        raise ManifestError(f"{source}: --pattern applies to a folder, not to a manifest file")
    if not source.exists():
        raise ManifestError(f"{source}: no such manifest or folder")
    return read_manifest(source)
