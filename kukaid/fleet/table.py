"""The fleet table: one row per log and axis (parameters, sigma, fit quality, temperature,
provenance, or the reason the log failed), stored as Parquet (pyarrow).

Writing is atomic (a temporary file beside the table, renamed onto it), and every finished row is
first appended to a journal beside the table (``.TABLE.parquet.journal``, one JSON line per row),
so a run killed at any moment loses no finished fit: the next run reads the table and the journal,
and fits only the logs found in neither (by content hash)."""
from __future__ import annotations

import errno
import json
import math
import os
from pathlib import Path
from typing import Any, Iterable, Sequence

from kukaid.errors import KukaidError
from kukaid.jsonfile import file_kind

SCHEMA = "kukaid.fleet-table/1"
#: what a command that reads fits wants, named when it is given another file
FIT_TABLE = "the table `kukaid fleet fit` wrote"

#: column -> (pyarrow type name, unit or meaning); the table's columns in this order
COLUMNS: dict[str, tuple[str, str]] = {
    "robot": ("string", "robot name"),
    "axis": ("int64", "KUKA axis number (null: the log's axis could not be read)"),
    "date": ("string", "day of the log, YYYY-MM-DD"),
    "path": ("string", "the log as the manifest or folder scan names it"),
    "sha256": ("string", "SHA-256 of the log file's bytes"),
    "status": ("string", "ok or error"),
    "error": ("string", "why the log gave no result (null when ok)"),
    "kind": ("string", "what the row holds: fit, validate or diagnose"),
    "friction_model": ("string", "stribeck or coulomb-viscous"),
    "Fc": ("float64", "Coulomb friction, N·m"),
    "Fv": ("float64", "viscous friction, N·m·s/rad"),
    "Fs": ("float64", "static friction, N·m (Stribeck)"),
    "vs": ("float64", "Stribeck velocity, rad/s"),
    "Izz": ("float64", "moment of inertia, kg·m² (one-axis fit)"),
    "Mx": ("float64", "gravity amplitude, N·m (one-axis fit)"),
    "offset": ("float64", "torque offset, N·m"),
    "Fc_std": ("float64", "standard deviation of Fc, N·m"),
    "Fv_std": ("float64", "standard deviation of Fv, N·m·s/rad"),
    "Izz_std": ("float64", "standard deviation of Izz, kg·m²"),
    "Mx_std": ("float64", "standard deviation of Mx, N·m"),
    "rmse": ("float64", "torque prediction RMS error of the fit (or of the validation, or after a diagnosis: "
                        "the joint's, after the effects found), N·m"),
    "rel_error": ("float64", "validation: RMS error over RMS torque; diagnose: the joint's RMS error over RMS "
                             "torque after the effects found (a whole arm's: held out)"),
    "n_samples": ("int64", "samples in the log"),
    "log_duration": ("float64", "log duration, s"),
    "temp_mean": ("float64", "mean motor temperature in the log, °C (null: not logged)"),
    "temp_min": ("float64", "lowest motor temperature, °C"),
    "temp_max": ("float64", "highest motor temperature, °C"),
    "model_date": ("string", "validate: the day of the fit whose model predicted this log"),
    "effects": ("string", "diagnose: the effects found, comma-separated (empty: none); whole-arm log: those "
                          "acting on the row's joint"),
    "result": ("string", "the full result as JSON (parameter file, validation or diagnosis; of a whole-arm log: "
                         "on its first row)"),
    "task_s": ("float64", "wall time of the task on its worker, s"),
    "task_cpu_s": ("float64", "CPU time of the task on its worker, s"),
    "worker": ("string", "the worker that ran the task"),
    "worker_peak_mb": ("float64", "peak resident memory of that worker process so far, MB"),
    "kukaid_version": ("string", "version that produced the row"),
    "finished_at": ("string", "UTC time the task finished, ISO 8601"),
}


def empty_row() -> dict[str, Any]:
    """A row with every column null."""
    return {c: None for c in COLUMNS}


def _arrow_schema(settings: dict | None):
    import pyarrow as pa

    types = {"string": pa.string(), "int64": pa.int64(), "float64": pa.float64()}
    meta = {b"kukaid": json.dumps({"schema": SCHEMA, "settings": settings or {}}).encode()}
    return pa.schema([(c, types[t]) for c, (t, _) in COLUMNS.items()], metadata=meta)


def _clean(v: Any, typ: str) -> Any:
    if v is None:
        return None
    if typ == "float64":
        v = float(v)
        return v if math.isfinite(v) else None
    if typ == "int64":
        return int(v)
    return str(v)


def write_table(path: str | Path, rows: Sequence[dict], settings: dict | None = None) -> None:
    """Write the rows as a Parquet table at ``path``, atomically (write, then rename).

    Parameters
    ----------
    rows : dicts keyed by :data:`COLUMNS` (missing keys are null).
    settings : the options the rows were made with (kept in the file's metadata, checked on resume).
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    from kukaid.atomic import atomic_path

    schema = _arrow_schema(settings)
    cols = {c: [_clean(r.get(c), t) for r in rows] for c, (t, _) in COLUMNS.items()}
    table = pa.Table.from_pydict(cols, schema=schema)
    with atomic_path(path) as tmp:
        pq.write_table(table, tmp)


def read_table(path: str | Path, expected: str | None = None) -> tuple[list[dict], dict]:
    """Rows and settings of a fleet table (:func:`write_table`); ``expected``, the table the caller
    wants (``the table `kukaid fleet fit` wrote``), is named when ``path`` is no Parquet file.

    Raises
    ------
    KukaidError : not a Parquet file, or not a kukaid fleet table.
    """
    import pyarrow.parquet as pq

    path = Path(path)
    if not path.is_file():
        raise KukaidError(f"{path}: no such fleet table")
    try:
        pf = pq.ParquetFile(path)
        meta = pf.schema_arrow.metadata or {}
        info = json.loads(meta.get(b"kukaid", b"{}"))
        table = pf.read()
    except (OSError, ValueError) as e:
        kind = file_kind(path)
        if kind is not None and kind.startswith("a Parquet"):  # a Parquet file cut short: pyarrow's reason
            raise KukaidError(f"{path}: not a readable Parquet file ({str(e).splitlines()[0][:120]})") from None
        what = f"is {kind}, not" if kind else "not"  # a manifest, a log, a report: named as what it is
        give = f": give {expected}" if expected else ""
        raise KukaidError(f"{path}: {what} a fleet table (Parquet){give}") from None
    if info.get("schema") != SCHEMA:
        raise KukaidError(f"{path}: not a kukaid fleet table ({SCHEMA})")
    data = table.to_pydict()
    n = table.num_rows
    rows = [{c: data[c][i] if c in data else None for c in COLUMNS} for i in range(n)]
    return rows, info.get("settings", {})


def journal_path(table: str | Path) -> Path:
    """The journal of a table being written: ``.NAME.journal`` beside it."""
    table = Path(table)
    return table.with_name(f".{table.name}.journal")


class Journal:
    """Append-only record of finished rows (one JSON line each, flushed at once) while a run goes
    on; a line cut short by a kill is ignored when read back (:func:`read_journal`)."""

    def __init__(self, table: str | Path, settings: dict) -> None:
        self.path = journal_path(table)
        new = not self.path.exists()
        self._f = open(self.path, "a", encoding="utf-8")
        if new:
            self._f.write(json.dumps({"settings": settings}) + "\n")
            self._f.flush()

    def append(self, rows: Iterable[dict]) -> None:
        for r in rows:
            self._f.write(json.dumps(r) + "\n")
        self._f.flush()

    def close(self) -> None:
        self._f.close()

    def remove(self) -> None:
        self.close()
        try:
            os.unlink(self.path)
        except FileNotFoundError:
            pass


def lock_path(table: str | Path) -> Path:
    """The lock of a table being written: ``.NAME.lock`` beside it (removed at the end of the run)."""
    table = Path(table)
    return table.with_name(f".{table.name}.lock")


class TableLock:
    """An exclusive lock on a table for one run (``flock`` on ``.NAME.lock`` beside it), so that two
    runs writing the same table do not each rewrite it with their own rows only: the second stops at
    once, before any work.  A run killed with ``kill -9`` leaves the file, not the lock (the system
    releases it); the next run takes it over.

    Raises
    ------
    KukaidError : another run holds the lock.
    """

    def __init__(self, table: str | Path) -> None:
        import fcntl

        self.table = Path(table)
        self.path = lock_path(table)
        while True:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError as e:
                if e.errno not in (errno.EAGAIN, errno.EWOULDBLOCK, errno.EACCES):  # a file system without locks
                    break
                try:
                    other = os.read(fd, 64).decode(errors="replace").strip()
                finally:
                    os.close(fd)
                pid = f" (process {other})" if other.isdigit() else ""
                raise KukaidError(f"{self.table}: another kukaid fleet run is writing this table{pid}; wait for it "
                                  "to end, or write another table") from None
            try:  # the run before removed the file between our open and our lock: lock the new one
                same = os.fstat(fd).st_ino == os.stat(self.path).st_ino
            except FileNotFoundError:
                same = False
            if same:
                break
            os.close(fd)
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
        self._fd = fd

    def release(self) -> None:
        """Remove the lock file and release the lock (removed first: a run waiting on it locks a new one)."""
        if self._fd is None:
            return
        try:
            os.unlink(self.path)
        except FileNotFoundError:
            pass
        os.close(self._fd)
        self._fd = None

    def __enter__(self) -> "TableLock":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.release()


def read_journal(table: str | Path) -> tuple[list[dict], dict | None]:
    """Rows of an interrupted run's journal and its settings (``[], None`` when there is none)."""
    p = journal_path(table)
    if not p.exists():
        return [], None
    rows, settings = [], None
    with open(p, encoding="utf-8", errors="replace") as f:
        for line in f:
            try:
                d = json.loads(line)
            except ValueError:  # the line a kill cut short
                continue
            if not isinstance(d, dict):
                continue
            if "settings" in d and "status" not in d:
                settings = d["settings"]
            else:
                rows.append({c: d.get(c) for c in COLUMNS})
    return rows, settings
