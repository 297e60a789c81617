"""Run one task per log on Dask and stream the rows into the fleet table.

:func:`open_client` gives a Dask client: a local cluster of worker processes sized to the machine
(one thread each), or a running cluster by its scheduler's address; :func:`run_tasks` submits the
logs not yet in the table (known by content hash), appends each finished row to the table's
journal as it arrives (``as_completed``), rewrites the table atomically now and then and at the
end, and removes the journal.  A run killed at any point is resumed by running it again.
"""
from __future__ import annotations

import contextlib
import logging
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterator, Sequence

from kukaid.errors import KukaidError, OptionError
from kukaid.fleet.manifest import Entry, content_hash
from kukaid.fleet.table import Journal, TableLock, journal_path, read_journal, read_table, write_table
from kukaid.fleet.tasks import Job, duplicate_row, error_row

Progress = Callable[[int, int], None]


@dataclass
class RunSummary:
    """What a run did.  ``ran``: logs run now that gave a result (an ``ok`` row; a log run into an error
    row is not counted); ``errors``: error rows (of the logs run now, duplicates and missing files);
    ``skipped``: logs already in the table; ``repeated``: entries repeating an earlier one of the input (the
    same log and axis); ``first_error``: the error of this run's first error row
    (table order; duplicates aside), empty when none; ``peak_worker_mb``: the largest peak resident memory a
    worker process reported (MB); ``wall_s``: the run's wall time (s), cluster start included; ``tasks_s``: from the first task
    submitted to the last row received (s)."""

    total: int = 0
    ran: int = 0
    errors: int = 0
    skipped: int = 0
    repeated: int = 0
    duplicates: int = 0
    first_error: str = ""
    rows: int = 0
    wall_s: float = 0.0
    tasks_s: float = 0.0
    workers: int = 0
    peak_worker_mb: float = 0.0
    per_worker_mb: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return dict(self.__dict__)


@contextlib.contextmanager
def open_client(workers: int | None = None, scheduler: str | None = None,
                connect_timeout: float = 10.0) -> Iterator[Any]:
    """A ``dask.distributed`` client, closed on exit.

    Parameters
    ----------
    workers : worker processes of the local cluster (default: the machine's cores); one thread each.
    scheduler : address of a running scheduler (``tcp://host:8786``); then ``workers`` must be None.
    connect_timeout : s to wait for the scheduler.

    Raises
    ------
    OptionError : both given, or workers < 1.
    KukaidError : the scheduler does not answer.
    """
    from dask.distributed import Client, LocalCluster

    if scheduler is not None and workers is not None:
        raise OptionError("--workers applies to the local cluster; a running cluster (--scheduler) has its own workers")
    if workers is not None and workers < 1:
        raise OptionError(f"--workers must be at least 1, got {workers}")
    if scheduler is not None:
        try:
            client = Client(scheduler, timeout=connect_timeout)
        except (OSError, TimeoutError) as e:
            raise KukaidError(f"cannot reach the Dask scheduler at {scheduler}: {str(e).splitlines()[0][:160]}") from None
        try:
            yield client
        finally:
            client.close()
        return
    n = workers or os.cpu_count() or 1
    # Ctrl-C on a terminal reaches the workers too (one process group): each printed its own
    # KeyboardInterrupt traceback under the command's one line, and one while the cluster started
    # left it half made.  The workers ignore SIGINT (from birth: started while this process ignores
    # it, for the second or two the cluster takes to start; and a worker started again later, by the
    # plugin); the command stops them.
    import signal
    import threading

    main = threading.current_thread() is threading.main_thread()
    old = signal.signal(signal.SIGINT, signal.SIG_IGN) if main else None
    try:
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0",
                               silence_logs=logging.ERROR)
    finally:
        if main:  # None: a handler set outside Python, taken as Python's own
            signal.signal(signal.SIGINT, signal.default_int_handler if old is None else old)
    client = Client(cluster)
    try:
        client.register_plugin(_leave_ctrl_c_to_the_command())
        yield client
    finally:
        client.close()
        cluster.close()


#: what a busy worker logs when the command, stopped by Ctrl-C, closes the scheduler under it (with a
#: traceback, under the command's one line): no news to the user, whom the command has told
SCHEDULER_GONE = "Failed to communicate with scheduler during heartbeat"


def _not_scheduler_gone(record: logging.LogRecord) -> bool:
    return not str(record.msg).startswith(SCHEDULER_GONE)


def _leave_ctrl_c_to_the_command() -> Any:
    """A Dask worker plugin: the worker ignores SIGINT (set in its main thread, its event loop's), and
    does not log the scheduler closing under it (:data:`SCHEDULER_GONE`)."""
    from distributed.diagnostics.plugin import WorkerPlugin

    class LeaveCtrlCToTheCommand(WorkerPlugin):
        name = "kukaid-leave-ctrl-c-to-the-command"

        def setup(self, worker: Any) -> None:
            import signal
            import threading

            if threading.current_thread() is threading.main_thread():
                signal.signal(signal.SIGINT, signal.SIG_IGN)
            logging.getLogger("distributed.worker").addFilter(_not_scheduler_gone)

    return LeaveCtrlCToTheCommand()


def _key(row: dict) -> tuple[str, str, int | None]:
    """A row is of one log and one axis: a log listed for two of its axes gives two rows."""
    return (row.get("path") or "", row.get("sha256") or "", row.get("axis"))


def _sort(rows: list[dict]) -> list[dict]:
    return sorted(rows, key=lambda r: (r.get("robot") or "", r.get("date") or "", r.get("path") or "",
                                       r.get("axis") if r.get("axis") is not None else -1))


def prior_rows(table: Path, settings: dict) -> list[dict]:
    """Rows already done for ``table``: its own and those of an interrupted run's journal.

    Raises
    ------
    KukaidError : the table (or journal) was made with other settings.
    """
    rows: list[dict] = []
    if table.exists():
        rows, old = read_table(table)
        if old != settings:
            raise KukaidError(f"{table}: made with other settings ({_diff(old, settings)}); write another table "
                              "or remove this one")
    jrows, jset = read_journal(table)
    if jset is not None and jset != settings:
        raise KukaidError(f"{table}: an interrupted run with other settings ({_diff(jset, settings)}) left its "
                          f"journal; remove {table.name}'s journal (.{table.name}.journal) or write another table")
    seen = {_key(r) for r in rows}
    rows += [r for r in jrows if _key(r) not in seen]
    return rows


def _diff(a: dict, b: dict) -> str:
    keys = sorted(set(a) | set(b))
    return ", ".join(f"{k}: {a.get(k)!r}, now {b.get(k)!r}" for k in keys if a.get(k) != b.get(k)) or "unknown"


def plan(entries: Sequence[Entry], prior: list[dict], kind: str) -> tuple[list[Job], list[dict], int, int]:
    """Which logs to run: (jobs, rows made without running (missing files, duplicates), skipped, repeated:
    entries that repeat an earlier one of ``entries``, the same log and axis).

    A log whose (name, content hash) has a row of its axis (a whole-arm log: any row) is skipped; a
    log whose content is that of an earlier log (in the table or earlier in the input) becomes a
    duplicate row, never run twice."""
    done = {_key(r) for r in prior}
    done |= {k[:2] for k in done}  # (name, hash): an entry without an axis is done by any of its rows
    in_table, whole = set(done), set()
    first: dict[str, str] = {}
    for r in prior:
        if r.get("sha256") and not (r.get("error") or "").startswith("duplicate"):
            first.setdefault(r["sha256"], r["path"])
    jobs, direct, skipped, repeated = [], [], 0, 0
    for e in entries:
        if not os.path.isfile(e.path):
            job = Job(e.robot, e.axis, e.date, e.path, e.name, "", e.axis_from)
            key = (e.name, "") if e.axis is None else (e.name, "", e.axis)
            if key in done:  # still missing: its row stands
                skipped, repeated = (skipped + 1, repeated) if key in in_table else (skipped, repeated + 1)
                continue
            done |= {key, key[:2]}
            direct.append(error_row(job, kind, f"{e.name}: no such file"))
            continue
        sha = content_hash(e.path)
        job = Job(e.robot, e.axis, e.date, e.path, e.name, sha, e.axis_from)
        key = (e.name, sha) if e.axis is None else (e.name, sha, e.axis)
        if key in done or (e.name, sha) in whole:  # listed before in the input without an axis: every axis
            skipped, repeated = (skipped + 1, repeated) if key in in_table else (skipped, repeated + 1)
            continue
        done |= {key, key[:2]}
        if e.axis is None:
            whole.add(key)
        if sha in first and first[sha] != e.name:
            direct.append(duplicate_row(job, kind, first[sha]))
            continue
        first[sha] = e.name
        jobs.append(job)
    return jobs, direct, skipped, repeated


def run_tasks(entries: Sequence[Entry], table: str | Path, task: Callable[[Job, Any], list[dict]], options: Any,
              settings: dict, kind: str = "fit", workers: int | None = None, scheduler: str | None = None,
              progress: Progress | None = None, checkpoint_s: float = 30.0, client: Any = None) -> RunSummary:
    """Run ``task(job, options)`` for every log not yet in ``table``; write the table.

    Parameters
    ----------
    entries : the fleet's logs (:mod:`kukaid.fleet.manifest`).
    table : the Parquet table to create or complete.
    task : a module-level function (Dask sends it to the workers by name) returning rows.
    options : its options (picklable); ``settings`` their JSON form, kept in the table.
    workers, scheduler : see :func:`open_client`.
    progress : called with (done, total) as rows arrive.
    checkpoint_s : s between atomic rewrites of the table while the run goes on.
    client : a Dask client to use instead of opening one (``workers`` and ``scheduler`` then unused).
    """
    from kukaid.atomic import check_output, make_folder, remove_folders

    t_start = time.perf_counter()
    table = check_output(table)
    try:  # made as every command makes its output's folder; removed again if the run fails with it empty
        made = make_folder(table.parent)
    except OSError as e:
        raise KukaidError(f"{table}: cannot write: {e.strerror or e}") from None
    try:
        with TableLock(table):  # a second run on this table stops here: each rewrote it with its own rows only
            return _run_locked(entries, table, task, options, settings, kind, workers, scheduler, progress,
                               checkpoint_s, client, t_start)
    except BaseException:
        remove_folders(made)  # a journal kept keeps its folder
        raise


def _run_locked(entries, table, task, options, settings, kind, workers, scheduler, progress, checkpoint_s, client,
                t_start) -> RunSummary:
    prior = prior_rows(table, settings)
    jobs, direct, skipped, repeated = plan(entries, prior, kind)
    names_now = {j.name: j.sha256 for j in jobs}
    # a log replaced by another file of the same name: its old rows go
    prior = [r for r in prior if not (r.get("path") in names_now and r.get("sha256") != names_now[r.get("path")])]
    s = RunSummary(total=len(entries), skipped=skipped, repeated=repeated, duplicates=sum(1 for r in direct
                                                                       if (r.get("error") or "").startswith("duplicate")))
    rows = list(prior)
    journal = Journal(table, settings)
    try:
        journal.append(direct)
        rows += direct
        s.errors += len(direct)
        if progress is not None:
            progress(0, len(jobs))
        if jobs:
            with contextlib.ExitStack() as stack:
                if client is None:
                    client = stack.enter_context(open_client(workers, scheduler))
                s.workers = len(client.nthreads())
                t0 = time.perf_counter()
                _stream(client, jobs, task, options, kind, rows, journal, s, table, settings, progress,
                        checkpoint_s)
                s.tasks_s = time.perf_counter() - t0
        write_table(table, _sort(rows), settings)
        journal.remove()
    except KeyboardInterrupt:  # Ctrl-C: say what is kept, and where, since the journal is a hidden file
        journal.close()
        done = len({r.get("path") for r in rows[len(prior):]})
        err = KukaidError(f"{table}: interrupted after {done} of {len(entries) - skipped - repeated} logs; the finished rows are "
                          f"kept (in {journal_path(table).name} beside it): run the same command again to go on")
        err.exit_code = 130
        raise err from None
    except BaseException:
        journal.close()  # the journal stays: the next run picks up from it
        raise
    s.first_error = next((r.get("error") or "" for r in _sort(rows[len(prior):]) if r.get("status") != "ok"
                          and not (r.get("error") or "").startswith("duplicate")), "")
    s.rows = len(rows)
    s.wall_s = time.perf_counter() - t_start
    return s


def _stream(client, jobs, task, options, kind, rows, journal, s, table, settings, progress, checkpoint_s) -> None:
    from dask.distributed import as_completed

    futures = client.map(task, jobs, options=options, pure=False)
    job_of = {f.key: j for f, j in zip(futures, jobs)}
    last = time.monotonic()
    done = 0
    for fut in as_completed(futures):
        job = job_of[fut.key]
        try:
            new = fut.result()
        except Exception as e:  # the worker died (KilledWorker) or the task could not run
            new = [error_row(job, kind, f"worker failed: {type(e).__name__}: {str(e).splitlines()[0][:200] if str(e) else ''}")]
        fut.release()
        journal.append(new)
        rows.extend(new)
        s.ran += any(r.get("status") == "ok" for r in new)  # fitted (validated, diagnosed): not an error row
        s.errors += sum(1 for r in new if r.get("status") != "ok")
        for r in new:
            w, mb = r.get("worker"), r.get("worker_peak_mb")
            if w and mb is not None:
                s.per_worker_mb[w] = max(s.per_worker_mb.get(w, 0.0), float(mb))
                s.peak_worker_mb = max(s.peak_worker_mb, float(mb))
        done += 1
        if progress is not None:
            progress(done, len(jobs))
        if time.monotonic() - last > checkpoint_s:
            write_table(table, _sort(rows), settings)
            last = time.monotonic()
