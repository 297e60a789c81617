"""kukaid fleet: manifest and folder input, error rows for bad logs, resume after kill -9 with no
log fitted twice, a separately started dask scheduler + worker, simulate's truth, wear on a
synthetic table (false flags, common drift), the CLI's one-line errors."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest

from fleet_helpers import DaskProcesses, fault_fleet, small_fleet

from kukaid.fleet.manifest import ManifestError, read_input, read_manifest, scan_folder
from kukaid.fleet.table import journal_path, read_journal, read_table


def _run(cmd, *args, timeout=180, **kw):
    return subprocess.run([*cmd, *map(str, args)], capture_output=True, text=True, timeout=timeout, **kw)


@pytest.fixture(scope="module")
def faults(tmp_path_factory):
    out = tmp_path_factory.mktemp("faults")
    return fault_fleet(out)


# -- input -----------------------------------------------------------------------------------

def test_manifest_and_folder_give_the_same_logs(tmp_path):
    man = small_fleet(tmp_path, robots=2, days=2)
    a = read_manifest(man)
    b = scan_folder(tmp_path / "logs", "{robot}/{date}/A{axis}.h5")
    assert [(e.robot, e.axis, e.date, e.path) for e in a] == [(e.robot, e.axis, e.date, e.path) for e in b]
    assert len(read_input(tmp_path / "logs")) == 4  # default pattern {robot}/{date}/*


def test_a_log_of_another_axis_in_a_folder_names_its_file_name_not_a_manifest(tmp_path):
    """New-user trial 16: `fleet fit FOLDER --pattern '{robot}/{date}/A{axis}.*'` with an A2 log saved as
    A3.h5 gave the error row "a log of A2, not of A3 as the manifest says": there was no manifest, the
    axis came from the file's name."""
    import shutil

    from click.testing import CliRunner

    from kukaid_cli.main import cli

    small_fleet(tmp_path / "a", robots=1, days=1, seed=12, axes=(2,))
    (tmp_path / "logs" / "R1" / "2026-01-05").mkdir(parents=True)
    shutil.copy(next((tmp_path / "a" / "logs").rglob("*.h5")), tmp_path / "logs" / "R1" / "2026-01-05" / "A3.h5")
    out = tmp_path / "t.parquet"
    r = CliRunner().invoke(cli, ["fleet", "fit", str(tmp_path / "logs"), "--pattern", "{robot}/{date}/A{axis}.*",
                                 "-o", str(out), "--workers", "1"])
    assert r.exit_code == 1, r.output  # its only log failed
    (row,), _ = read_table(out)
    assert row["error"] == ("R1/2026-01-05/A3.h5: a log of A2, not of A3 as its name (--pattern "
                            "'{robot}/{date}/A{axis}.*') says"), row["error"]


def test_a_folder_of_compressed_logs_is_scanned(tmp_path):
    """New-user trial 13: `fleet fit FOLDER` of A3.csv.gz logs said "no log matches the pattern" while a
    manifest naming them, and every other command, read them."""
    import gzip

    small_fleet(tmp_path, robots=1, days=2)
    for p in sorted((tmp_path / "logs").rglob("*.h5")):
        p.with_name(p.name + ".gz").write_bytes(gzip.compress(p.read_bytes()))
        p.unlink()
    got = scan_folder(tmp_path / "logs", "{robot}/{date}/A{axis}.h5.gz")
    assert len(got) == 2 and all(e.path.endswith("A3.h5.gz") and e.axis == 3 for e in got)
    assert len(read_input(tmp_path / "logs")) == 2  # the default pattern {robot}/{date}/*
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "notes.txt.gz").write_bytes(gzip.compress(b"x"))
    with pytest.raises(ManifestError, match=r"no log matches .* optionally compressed: \.gz, \.bz2, \.xz"):
        scan_folder(tmp_path / "other")


@pytest.mark.parametrize("text, phrase", [
    ("robot,date,path\nR1,2026-01-01,a.h5\n", "lacks column(s) axis"),
    # new-user trial 17: a manifest saved with semicolons said only which columns it lacked
    ("robot;axis;date;path\nR1;3;2026-01-01;a.h5\n", "its header is split by ';', and a manifest's columns by commas"),
    ("robot,axis,date,path\nR1,3,01/02/2026,a.h5\n", "not a date"),
    ("robot,axis,date,path\nR1,3,2026-02-30,a.h5\n", "line 2: date '2026-02-30' is not a date"),  # no such day
    ("robot,axis,date,path\nR1,3,2026-13-01,a.h5\n", "line 2: date '2026-13-01' is not a date"),  # nor month
    ("robot,axis,date,path\nR1,A13,2026-01-01,a.h5\n", "not an axis number"),
    ("robot,axis,date,path\n", "lists no logs"),
])
def test_bad_manifest_is_one_clear_error(tmp_path, text, phrase):
    p = tmp_path / "m.csv"
    p.write_text(text)
    with pytest.raises(ManifestError, match=phrase.replace("(", r"\(").replace(")", r"\)")):
        read_manifest(p)


@pytest.mark.parametrize("content, phrase", [
    (b"PAR1" + bytes(range(128, 256)) + b"PAR1", "is a Parquet table (kukaid fleet), not a fleet manifest (CSV"),
    (b"time_s,A3_deg,A3_Nm\n0,1,2\n0.012,2,3\n", "is an axis log (CSV), not a fleet manifest (CSV"),
])
def test_another_file_given_as_the_manifest_is_named(tmp_path, content, phrase):
    """New-user trial 22: `fleet validate table.parquet --table table.parquet` said "not a text CSV file" of the
    fleet table given where the manifest belongs; a log given there, that it lacked the manifest's columns."""
    p = tmp_path / "in.csv"
    p.write_bytes(content)
    with pytest.raises(ManifestError, match=phrase.replace("(", r"\(").replace(")", r"\)")):
        read_manifest(p)


def test_a_folder_date_that_is_no_day_is_one_clear_error(tmp_path):
    """A folder named like a date that does not exist stops the command before any work, as a
    manifest's does (it was fitted, then `fleet wear` failed on it with an internal error)."""
    small_fleet(tmp_path, robots=1, days=1)
    (day,) = (tmp_path / "logs" / "R001").iterdir()
    day.rename(day.with_name("2026-02-30"))
    with pytest.raises(ManifestError, match="date '2026-02-30' is not a date YYYY-MM-DD"):
        scan_folder(tmp_path / "logs", "{robot}/{date}/A{axis}.h5")


def test_a_log_the_folder_pattern_does_not_match_is_named_not_dropped(tmp_path):
    """New-user trial 15: a log in a folder not named as a date (R1/notadate/A3.h5, R1/2026-1-7/A3.h5) was
    left out of `fleet fit FOLDER` without a word; now the scan lists it and the command names it in one
    warning line before the run."""
    from click.testing import CliRunner

    from kukaid_cli.main import cli

    small_fleet(tmp_path, robots=1, days=2)
    logs = tmp_path / "logs"
    day = sorted((logs / "R001").iterdir())[0]
    (logs / "R001" / "2026-1-7").mkdir()
    (logs / "R001" / "2026-1-7" / "A3.h5").write_bytes((day / "A3.h5").read_bytes())
    (logs / "R001" / "A3.h5").write_bytes(b"x")
    (logs / "R001" / "notes.txt").write_text("not a log")
    unmatched: list[str] = []
    assert len(read_input(logs, None, unmatched)) == 2
    assert unmatched == ["R001/2026-1-7/A3.h5", "R001/A3.h5"]
    r = CliRunner().invoke(cli, ["fleet", "fit", str(logs), "-o", str(tmp_path / "t.parquet"), "--workers", "1"])
    assert r.exit_code == 0, r.output
    assert r.stderr.splitlines()[0] == (
        f"kukaid: warning: fleet fit: {logs}: 2 log files do not match the pattern '{{robot}}/{{date}}/*' and are "
        "not fitted: R001/2026-1-7/A3.h5, R001/A3.h5 ({robot} and {date} YYYY-MM-DD are one folder each; --pattern "
        "for another layout)"), r.stderr


# -- faults, resume ------------------------------------------------------------------------------

def test_bad_logs_become_error_rows_and_the_rest_is_fitted(faults, tmp_path, kukaid_cmd):
    man, expect = faults
    table = tmp_path / "t.parquet"
    r = _run(kukaid_cmd, "fleet", "fit", man, "-o", table, "--workers", "2")
    assert r.returncode == 0, r.stderr
    rows, settings = read_table(table)
    assert settings["task"] == "fit"
    by = {row["path"]: row for row in rows}
    assert len(rows) == 9 + len(expect)
    for path, phrase in expect.items():
        assert by[path]["status"] == "error" and phrase in by[path]["error"], (path, by[path]["error"])
    ok = [row for row in rows if row["status"] == "ok"]
    assert len(ok) == 9 and all(row["Fc"] > 0 and row["Fv"] > 0 and row["temp_mean"] is not None for row in ok)
    assert "(9 fitted, 6 error rows" in r.stderr, r.stderr  # a log fitted into an error row is not "fitted"
    assert not journal_path(table).exists()
    # run again: nothing is fitted twice, the table is the same
    r2 = _run(kukaid_cmd, "fleet", "fit", man, "-o", table, "--workers", "1")
    assert r2.returncode == 0, r2.stderr
    assert "0 fitted" in r2.stderr and "already in the table" in r2.stderr
    rows2, _ = read_table(table)
    assert rows2 == rows


def test_logs_run_into_error_rows_are_not_counted_as_diagnosed(tmp_path, capsys):
    """New-user trial 7: `fleet diagnose` of a whole-arm manifest with a one-axis fit table said
    "2 rows (2 diagnosed, 2 error rows)": every log run was counted, its row an error or not."""
    import functools

    from dask.distributed import Client

    from kukaid.diagnose import diagnose_model
    from kukaid.errors import KukaidError
    from kukaid.fleet.run import run_tasks
    from kukaid.fleet.table import write_table
    from kukaid.fleet.tasks import CheckOptions, check_task
    from kukaid_cli.cmd_fleet import _report

    man = small_fleet(tmp_path / "arm", robots=1, days=2, seed=23, whole_arm=True)
    fit = tmp_path / "fit.parquet"
    write_table(fit, _synthetic_rows(1, 3, seed=1), {"task": "fit"})  # one axis, none of these logs
    opts = CheckOptions(table=str(fit), kind="diagnose", run=functools.partial(diagnose_model, max_steps=4))
    out = tmp_path / "dia.parquet"
    with Client(processes=False, n_workers=1, threads_per_worker=1, dashboard_address=":0") as client:
        s = run_tasks(read_input(man), out, check_task, opts, opts.settings(), kind="diagnose", client=client)
    rows, _ = read_table(out)
    assert [r["status"] for r in rows] == ["error", "error"] and "a whole-arm log (A1..A6), but" in rows[0]["error"]
    assert (s.ran, s.errors, s.rows) == (0, 2, 2)
    with pytest.raises(KukaidError, match="no log diagnosed, 2 error rows; the first: "):  # not one: a failed run
        _report(s, out, "diagnosed")
    s.ran += 1
    _report(s, out, "diagnosed")
    assert f"{out}: 2 rows (1 diagnosed, 2 error rows) in " in capsys.readouterr().err


def test_a_run_where_no_log_succeeded_exits_non_zero(tmp_path, kukaid_cmd):
    """New-user trial 8: `fleet fit` of a manifest whose every log failed exited 0 ("0 fitted, 2 error
    rows"), so a script could not tell it from a good run.  Now one line naming the first error,
    exit status 1; the table is still written (its error column says why per log)."""
    (tmp_path / "m.csv").write_text("robot,axis,date,path\nR1,3,2026-01-05,a.h5\nR1,3,2026-01-06,b.h5\n")
    table = tmp_path / "t.parquet"
    r = _run(kukaid_cmd, "fleet", "fit", tmp_path / "m.csv", "-o", table)
    assert r.returncode == 1 and r.stderr == (f"kukaid: error: {table}: no log fitted, 2 error rows; the first: a.h5: "
                                              "no such file\n"), r.stderr
    rows, _ = read_table(table)
    assert [row["status"] for row in rows] == ["error", "error"]
    r = _run(kukaid_cmd, "fleet", "fit", tmp_path / "m.csv", "-o", table)  # again: nothing run, nothing failed
    assert r.returncode == 0 and "(0 fitted, 0 error rows, 2 already in the table)" in r.stderr, r.stderr


def test_logs_of_the_other_kind_than_the_fits_say_what_was_given_and_expected(tmp_path, kukaid_cmd):
    """New-user trial 8: whole-arm logs checked against a table of one-axis fits (or one-axis logs
    against whole-arm fits) gave "no fit of this log in fit.parquet" (diagnose), "no fit of R001 A1
    from a day before ..." (validate) or, fit with --robot, the robot's missing axes: now the row and
    the command's one line say what the log is and what the table (or --robot) takes."""
    from kukaid.fleet.run import plan
    from kukaid.fleet.table import write_table
    from kukaid.fleet.tasks import CheckOptions, FitOptions, check_task, fit_task

    arm = plan(read_input(small_fleet(tmp_path / "arm", robots=1, days=1, seed=23, whole_arm=True)), [], "fit")[0][0]
    one = plan(read_input(small_fleet(tmp_path / "one", robots=1, days=1, seed=23)), [], "fit")[0][0]
    fit1, fit6 = tmp_path / "fit1.parquet", tmp_path / "fit6.parquet"
    write_table(fit1, _synthetic_rows(1, 3, seed=1), {"task": "fit", "friction_model": "auto", "robot": None})
    write_table(fit6, _synthetic_rows(1, 3, seed=1), {"task": "fit", "friction_model": "auto",
                                                      "robot": "kr6-r700-sixx"})
    for kind in ("validate", "diagnose"):
        (row,) = check_task(arm, CheckOptions(table=str(fit1), kind=kind, run=None))
        assert row["error"] == (f"{arm.name}: a whole-arm log (A1..A6), but fit1.parquet holds one-axis fits "
                                "(fleet fit without --robot): give the table fleet fit --robot made of these logs")
        (row,) = check_task(one, CheckOptions(table=str(fit6), kind=kind, run=None))
        assert row["error"] == (f"{one.name}: a log of one axis (A3), but fit6.parquet holds whole-arm fits (fleet "
                                "fit --robot kr6-r700-sixx): give the table fleet fit made of these logs without --robot")
    (row,) = fit_task(one, FitOptions(robot="kr6-r700-sixx"))
    assert row["error"] == (f"{one.name}: a log of one axis (A3), but fleet fit --robot fits whole-arm logs: fit logs "
                            "of one axis without --robot")
    out = tmp_path / "dia.parquet"
    r = _run(kukaid_cmd, "fleet", "diagnose", tmp_path / "arm" / "manifest.csv", "--table", fit1, "-o", out,
             "--workers", "1")
    assert r.returncode == 1 and r.stderr == (f"kukaid: error: {out}: no log diagnosed, 1 error row; the first: "
                                              f"{arm.name}: a whole-arm log (A1..A6), but fit1.parquet holds one-axis "
                                              "fits (fleet fit without --robot): give the table fleet fit --robot "
                                              "made of these logs\n"), r.stderr


def test_the_summary_line_says_one_row_not_one_rows(capsys):
    """New-user trial 7: "1 error rows" (and "1 rows", "1 duplicates", "on 1 workers")."""
    from kukaid.fleet.run import RunSummary
    from kukaid_cli.cmd_fleet import _report

    _report(RunSummary(ran=0, errors=1, duplicates=1, rows=1, wall_s=2.0, workers=1), Path("t.parquet"), "fitted")
    assert capsys.readouterr().err == "t.parquet: 1 row (0 fitted, 1 error row, 1 duplicate among them) in 2.0 s on 1 worker\n"
    _report(RunSummary(ran=2, errors=2, rows=3, wall_s=2.0, workers=2), Path("t.parquet"), "fitted")
    assert capsys.readouterr().err == "t.parquet: 3 rows (2 fitted, 2 error rows) in 2.0 s on 2 workers\n"


def test_the_summary_line_says_why_the_first_log_failed(capsys):
    """New-user trial 16: `fleet fit` of a folder with a truncated log said `14 rows (12 fitted, 2 error
    rows)` and nothing of which logs or why: that is in the Parquet table's error column, which no
    command prints.  The first error row is said, as a run that fitted nothing says it."""
    from kukaid.fleet.run import RunSummary
    from kukaid_cli.cmd_fleet import _report

    _report(RunSummary(ran=2, errors=1, rows=3, wall_s=2.0, workers=1,
                       first_error="R002/2026-01-09/A3.h5: not a readable HDF5 file (truncated or corrupt)"),
            Path("t.parquet"), "fitted")
    assert capsys.readouterr().err == ("t.parquet: 3 rows (2 fitted, 1 error row) in 2.0 s on 1 worker; the first "
                                       "error row: R002/2026-01-09/A3.h5: not a readable HDF5 file (truncated or "
                                       "corrupt) (the table's error column says why for each)\n")


def test_ctrl_c_mid_run_says_what_is_kept_and_how_to_go_on(tmp_path, monkeypatch):
    """Ctrl-C during `fleet fit` said only 'interrupted' (exit 130): the finished rows are in a
    hidden journal that the next run reads, which the line now says."""
    import kukaid.fleet.run as run
    from kukaid.errors import KukaidError
    from kukaid.fleet.tasks import error_row, fit_task

    man = small_fleet(tmp_path, robots=1, days=2)

    def stream(client, jobs, task, options, kind, rows, journal, *a, **k):
        new = [error_row(jobs[0], kind, "done before the interrupt")]
        journal.append(new)
        rows.extend(new)
        raise KeyboardInterrupt

    class Client:
        def nthreads(self):
            return {"w": 1}

    monkeypatch.setattr(run, "_stream", stream)
    table = tmp_path / "t.parquet"
    with pytest.raises(KukaidError) as e:
        run.run_tasks(read_input(man), table, fit_task, None, {"task": "fit"}, client=Client())
    assert e.value.exit_code == 130
    assert str(e.value) == (f"{table}: interrupted after 1 of 2 logs; the finished rows are kept (in "
                            f"{journal_path(table).name} beside it): run the same command again to go on")
    assert len(read_journal(table)[0]) == 1 and not table.exists()


def test_a_second_run_on_the_same_table_stops_before_any_work(tmp_path, monkeypatch):
    """New-user trial 19: two `fleet fit` runs of two halves of a manifest into one table, started a
    second apart, both said "200 rows (200 fitted ...)", exit 0; the table then held 208 rows: each run
    rewrote it with its own rows, and the first to end removed the journal the other appended to.  A
    run now holds a lock on its table; the second one stops at once with one line, and the table
    keeps every row of the first."""
    import kukaid.fleet.run as run
    from kukaid.errors import KukaidError
    from kukaid.fleet.tasks import error_row, fit_task

    man = small_fleet(tmp_path, robots=2, days=2)
    entries = read_input(man)
    table = tmp_path / "t.parquet"
    second: list[str] = []
    nested: list[bool] = []

    def stream(client, jobs, task, options, kind, rows, journal, *a, **k):
        if not nested:  # the other half of the manifest, run while this one goes on
            nested.append(True)
            try:
                run.run_tasks(entries[2:], table, fit_task, None, {"task": "fit"}, client=Client())
                second.append("ran")
            except KukaidError as e:
                second.append(str(e))
        new = [error_row(j, kind, "done") for j in jobs]
        journal.append(new)
        rows.extend(new)

    class Client:
        def nthreads(self):
            return {"w": 1}

    monkeypatch.setattr(run, "_stream", stream)
    run.run_tasks(entries[:2], table, fit_task, None, {"task": "fit"}, client=Client())
    assert second == [f"{table}: another kukaid fleet run is writing this table (process {os.getpid()}); wait for "
                      "it to end, or write another table"]
    assert len(read_table(table)[0]) == 2
    assert not (tmp_path / ".t.parquet.lock").exists() and not journal_path(table).exists()
    monkeypatch.setattr(run, "_stream", lambda client, jobs, task, options, kind, rows, journal, *a, **k: (
        journal.append([error_row(j, kind, "done") for j in jobs]), rows.extend(error_row(j, kind, "done") for j in jobs)))
    run.run_tasks(entries, table, fit_task, None, {"task": "fit"}, client=Client())  # the lock is free again
    assert len(read_table(table)[0]) == 4


def test_a_table_in_a_folder_not_yet_made_is_written_there(tmp_path, monkeypatch):
    """New-user trial 19: `fleet fit manifest.csv -o new/sub/t.parquet` failed, "new/sub/.t.parquet.journal:
    No such file or directory", naming a hidden file the user never gave; every other command makes
    its output's folder.  The folder is made, and removed again when the run fails before writing."""
    import kukaid.fleet.run as run
    from kukaid.errors import KukaidError
    from kukaid.fleet.tasks import error_row, fit_task

    man = small_fleet(tmp_path, robots=1, days=2)

    class Client:
        def nthreads(self):
            return {"w": 1}

    def stream(client, jobs, task, options, kind, rows, journal, *a, **k):
        new = [error_row(j, kind, "done") for j in jobs]
        journal.append(new)
        rows.extend(new)

    monkeypatch.setattr(run, "_stream", stream)
    table = tmp_path / "new" / "sub" / "t.parquet"
    run.run_tasks(read_input(man), table, fit_task, None, {"task": "fit"}, client=Client())
    assert len(read_table(table)[0]) == 2
    other = tmp_path / "other" / "sub" / "t.parquet"
    monkeypatch.setattr(run, "prior_rows", lambda *a: (_ for _ in ()).throw(KukaidError("stop")))
    with pytest.raises(KukaidError):
        run.run_tasks(read_input(man), other, fit_task, None, {"task": "fit"}, client=Client())
    assert not (tmp_path / "other").exists()


def _sigint_handler() -> str:
    """The SIGINT handler of this process, by name (run on a Dask worker)."""
    import signal

    h = signal.getsignal(signal.SIGINT)
    return getattr(h, "name", None) or getattr(h, "__name__", repr(h))


def _worker_logs(message: str) -> bool:
    """Whether a worker's ``distributed.worker`` logger passes an error record of ``message`` (run on a worker)."""
    import logging

    rec = logging.LogRecord("distributed.worker", logging.ERROR, __file__, 0, message, None, None)
    return bool(logging.getLogger("distributed.worker").filter(rec))


def test_the_local_workers_leave_ctrl_c_to_the_command():
    """A terminal's Ctrl-C reaches the whole process group: a local Dask worker then printed its
    KeyboardInterrupt traceback (and its nanny's) under the command's one line, at about one
    Ctrl-C in three.  The workers ignore SIGINT; the command, whose own handler stays, stops them.
    A worker busy when the command closed the scheduler still logged its failed heartbeat with a
    traceback (fleet simulate, one Ctrl-C in seven): that line is no news; other errors are logged."""
    from kukaid.fleet.run import SCHEDULER_GONE, open_client

    before = signal.getsignal(signal.SIGINT)
    with open_client(workers=1) as client:
        assert signal.getsignal(signal.SIGINT) is before
        handlers = client.run(_sigint_handler)
        gone = client.run(_worker_logs, SCHEDULER_GONE + ".")
        other = client.run(_worker_logs, "Unexpected exception during heartbeat. Closing worker.")
    assert list(handlers.values()) == ["SIG_IGN"], handlers
    assert list(gone.values()) == [False] and list(other.values()) == [True]


def test_kill_mid_run_then_rerun_completes_without_refitting(tmp_path, kukaid_cmd):
    man = small_fleet(tmp_path / "f", robots=4, days=8, seed=21)
    table = tmp_path / "t.parquet"
    jpath = journal_path(table)
    p = subprocess.Popen([*kukaid_cmd, "fleet", "fit", str(man), "-o", str(table), "--workers", "1"],
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        t_end = time.monotonic() + 120
        while time.monotonic() < t_end and p.poll() is None:
            if jpath.exists() and len(jpath.read_text().splitlines()) >= 6:  # settings + 5 rows
                break
            time.sleep(0.05)
        assert p.poll() is None, "the run ended before it could be killed"
        os.killpg(p.pid, signal.SIGKILL)  # the driver and its local cluster, by their process group
        p.wait(timeout=10)
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
    before = [json.loads(line) for line in jpath.read_text().splitlines()[1:] if line.strip().endswith("}")]
    assert 5 <= len(before) < 32 and not table.exists()
    r = _run(kukaid_cmd, "fleet", "fit", man, "-o", table, "--workers", "1")
    assert r.returncode == 0, r.stderr
    rows, _ = read_table(table)
    assert len(rows) == 32 and len({row["path"] for row in rows}) == 32
    assert all(row["status"] == "ok" for row in rows)
    by = {row["path"]: row for row in rows}
    for old in before:  # fitted once: the row from before the kill is kept as it was
        assert by[old["path"]]["finished_at"] == old["finished_at"] and by[old["path"]]["worker"] == old["worker"]
    assert f"{32 - len(before)} fitted" in r.stderr
    assert not jpath.exists()


def test_separately_started_scheduler_and_worker(tmp_path, kukaid_cmd):
    man = small_fleet(tmp_path / "f", robots=2, days=3, seed=31)
    table = tmp_path / "t.parquet"
    with DaskProcesses(tmp_path, workers=1) as dask:
        r = _run(kukaid_cmd, "fleet", "fit", man, "-o", table, "--scheduler", dask.address, timeout=120)
    assert r.returncode == 0, r.stderr
    rows, _ = read_table(table)
    assert len(rows) == 6 and all(row["status"] == "ok" for row in rows)
    assert "on 1 worker;" in r.stderr


def test_unreachable_scheduler_and_bad_options_are_one_line(tmp_path, kukaid_cmd):
    man = small_fleet(tmp_path / "f", robots=1, days=1, seed=41)
    from kukaid.errors import KukaidError
    from kukaid.fleet.run import open_client

    with pytest.raises(KukaidError, match="cannot reach the Dask scheduler at tcp://127.0.0.1:9"):
        with open_client(scheduler="tcp://127.0.0.1:9", connect_timeout=1.0):
            pass
    r = _run(kukaid_cmd, "fleet", "fit", man, "-o", tmp_path / "t.csv")
    assert r.returncode == 2 and "name it so" in r.stderr and "Traceback" not in r.stderr
    r = _run(kukaid_cmd, "fleet", "fit", man, "-o", tmp_path / "t.parquet", "--workers", "0")
    assert r.returncode == 2 and "--workers" in r.stderr


def test_table_made_with_other_settings_is_not_mixed(tmp_path, kukaid_cmd):
    from kukaid.fleet.table import write_table
    from kukaid.fleet.tasks import FitOptions

    man = small_fleet(tmp_path / "f", robots=1, days=2, seed=51)
    table = tmp_path / "t.parquet"
    write_table(table, [], FitOptions(friction_model="coulomb-viscous").settings())
    r = _run(kukaid_cmd, "fleet", "fit", man, "-o", table, "--workers", "1")
    assert r.returncode == 1 and "other settings" in r.stderr and r.stderr.count("\n") == 1


# -- simulate -----------------------------------------------------------------------------------

def test_an_interrupted_simulate_leaves_no_half_made_fleet(tmp_path, monkeypatch):
    """Ctrl-C during `fleet simulate` left the logs simulated so far without a manifest, and the next
    run refused the folder ('not empty'); a folder that held files before keeps them."""
    import kukaid.fleet.simulate as simulate
    from click.testing import CliRunner

    from kukaid_cli.main import cli

    def interrupted(cfg, outdir, **k):
        (Path(outdir) / "logs" / "R001").mkdir(parents=True)
        (Path(outdir) / "logs" / "R001" / "A3.h5").write_bytes(b"half")
        raise KeyboardInterrupt

    monkeypatch.setattr(simulate, "simulate_fleet", interrupted)
    out = tmp_path / "fleet"
    r = CliRunner().invoke(cli, ["fleet", "simulate", "--robots", "1", "--days", "1", "-o", str(out)])
    assert r.exit_code == 130 and r.output.strip() == "kukaid: error: interrupted", r.output
    assert not out.exists()
    out.mkdir()
    (out / "mine.txt").write_text("kept")
    r = CliRunner().invoke(cli, ["fleet", "simulate", "--robots", "1", "--days", "1", "-o", str(out), "--force"])
    assert r.exit_code == 130 and (out / "mine.txt").read_text() == "kept"


def test_simulate_option_errors_name_the_command_once(tmp_path):
    """New-user trial 9: `fleet simulate --wear 0.5:0.2` said "fleet simulate: fleet simulate: wear range ..."."""
    from click.testing import CliRunner

    from kukaid_cli.main import cli

    for opt, msg in ((["--wear", "0.5:0.2"], "wear range must be 0 <= low <= high <= 5, got 0.5, 0.2"),
                     (["--axes", "7"], "axes must be numbers 1 to 6, got [7]")):
        r = CliRunner().invoke(cli, ["fleet", "simulate", "--robots", "1", "--days", "1", "-o", str(tmp_path / "f"), *opt])
        assert r.exit_code == 2 and r.stderr == f"kukaid: error: fleet simulate: {msg}\n", r.stderr
    assert not (tmp_path / "f").exists()
    # --axes with --whole-arm (its help: "not with --whole-arm") was ignored: six-axis logs all the same
    r = CliRunner().invoke(cli, ["fleet", "simulate", "--robots", "1", "--days", "1", "-o", str(tmp_path / "f"),
                                 "--axes", "1", "--whole-arm"])
    assert r.exit_code == 2 and r.stderr == ("kukaid: error: fleet simulate: --axes does not apply with --whole-arm "
                                             "(each log holds A1 to A6)\n"), r.stderr
    assert not (tmp_path / "f").exists()


def test_simulate_counts_in_words():
    """New-user trial 10: a fleet of one robot and one day said "1 logs of 1 axes"."""
    from kukaid_cli.cmd_fleet import _n

    assert [_n(1, "log"), _n(2, "log"), _n(1, "axis", "axes"), _n(6, "axis", "axes")] == \
        ["1 log", "2 logs", "1 axis", "6 axes"]


def test_simulate_keeps_the_truth_apart(tmp_path):
    from kukaid.logs import read_log

    man = small_fleet(tmp_path, robots=4, days=3, seed=61, wear_share=0.25)
    truth = json.loads((tmp_path / "truth.json").read_text())
    assert truth["schema"] == "kukaid.fleet-truth/1"
    assert sum(a["wearing"] for a in truth["axes"]) == 1
    assert len({round(a["friction_factor"], 6) for a in truth["axes"]}) == 4  # every axis its own truth
    assert all(a["friction_factor"] != 1.0 and a["kappa"] < 0 for a in truth["axes"])
    e = read_manifest(man)[0]
    log = read_log(e.path)
    assert log.temp is not None and "truth" not in log.attrs and "sim_config" not in log.attrs
    t = np.array(truth["temperature"]["R001"])
    assert np.ptp(t) > 3 and np.all(np.abs(t - 32.0) <= 15.0)


# -- wear on a synthetic table ----------------------------------------------------------------------

def _synthetic_rows(n_axes: int, days: int, seed: int, wearing=(), common=0.0, noise=0.004, kappa=-0.005):
    rng = np.random.default_rng(seed)
    rows = []
    for i in range(n_axes):
        fc, fv = 15 * np.exp(0.2 * rng.standard_normal()), 14 * np.exp(0.2 * rng.standard_normal())
        k_i = kappa + 0.0015 * rng.standard_normal()
        for d in range(days):
            T = 32 + rng.uniform(-15, 15)
            w = 1.0 + (0.3 * max(0, d - days // 2) / (days // 2) if i in wearing else 0.0)
            s = (1 + k_i * (T - 25)) * w * (1 + common * (d > days // 2))
            rows.append({"robot": f"R{i:03d}", "axis": 3, "date": f"2026-{1 + d // 28:02d}-{1 + d % 28:02d}",
                         "status": "ok", "kind": "fit", "friction_model": "coulomb-viscous",
                         "Fc": fc * s * np.exp(noise * rng.standard_normal()),
                         "Fv": fv * s * np.exp(noise * rng.standard_normal()), "temp_mean": T})
    return rows


def test_wear_flags_wearing_axes_and_few_healthy_ones():
    from kukaid.fleet.wear import assess

    wearing = set(range(0, 300, 30))
    res = assess(_synthetic_rows(300, 40, seed=7, wearing=wearing))
    flagged = {int(a["robot"][1:]) for a in res["axes"] if a["flagged"]}
    assert wearing <= flagged
    assert len(flagged - wearing) <= 0.01 * 290
    assert abs(res["temperature_model"]["Fc_per_K"] + 0.005) < 0.001
    for a in res["axes"]:
        if int(a["robot"][1:]) in wearing:
            assert a["first_flagged"] > "2026-01-20"  # after the onset (day 20)


def test_wear_ignores_a_drift_the_whole_fleet_shares():
    from kukaid.fleet.wear import assess

    res = assess(_synthetic_rows(60, 30, seed=8, common=0.15))
    assert res["summary"]["flagged"] <= 1


def test_wear_of_a_small_fleet_prints_no_numpy_warning():
    """Two axes give no spread of the temperature slopes (each axis takes the fleet's): `fleet wear`
    printed numpy's 'RuntimeWarning: invalid value encountered in divide' and its source line."""
    import warnings

    from kukaid.fleet.wear import assess

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = assess(_synthetic_rows(2, 24, seed=9))
    assert res["summary"]["assessed"] == 2 and res["temperature_model"]["Fc_per_K"] is not None


def test_wear_of_axes_whose_friction_does_not_scatter_prints_no_numpy_warning():
    """New-user trial 8: `fleet wear` printed numpy's 'RuntimeWarning: invalid value encountered in
    divide' when no baseline residual of Fc (or Fv) scattered (no correlation of the two to estimate),
    and 'divide by zero' with NaN in the verdict when an axis's baseline had neither a temperature
    spread nor a scatter (its own temperature slope undetermined: it takes the fleet's)."""
    import warnings

    from kukaid.fleet.wear import assess

    flat = [{**r, "Fc": 10.0} for r in _synthetic_rows(3, 24, seed=1)]
    still = [({**r, "temp_mean": 30.0, "Fc": 10.0, "Fv": 5.0} if r["robot"] == "R000" else r)
             for r in _synthetic_rows(5, 24, seed=1)]
    for rows in (flat, still):
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            res = assess(rows)
        json.dumps(res, allow_nan=False)  # no NaN in the verdict
        assert res["summary"]["assessed"] == len({r["robot"] for r in rows})
    assert res["residual_correlation_Fc_Fv"] != 0.0
    assert assess(flat)["residual_correlation_Fc_Fv"] == 0.0
    r000 = next(a for a in res["axes"] if a["robot"] == "R000")
    assert not r000["flagged"] and r000["temperature_coefficient"]["Fc"] == res["temperature_model"]["Fc_per_K"]


def test_wear_says_why_there_is_no_temperature_model(tmp_path):
    """New-user trial 7: `fleet wear` printed "temperature model: none (no temperature logged)" though
    every row had temp_mean: the axes had too few logs for a baseline, which only the JSON said.
    New-user trial 11: with no axis assessed it exited 0 with "0 axes assessed, 0 flagged" and wrote that
    verdict, which reads as no wear where none was looked for: now an error, and nothing written."""
    from click.testing import CliRunner

    from kukaid.fleet.table import write_table
    from kukaid.fleet.wear import assess, lines
    from kukaid_cli.main import cli

    rows = _synthetic_rows(7, 2, seed=3)
    assert all(r["temp_mean"] is not None for r in rows)
    write_table(tmp_path / "t.parquet", rows, {"task": "fit"})
    r = CliRunner().invoke(cli, ["fleet", "wear", str(tmp_path / "t.parquet"), "-o", str(tmp_path / "w.json")])
    assert r.exit_code == 1 and r.stderr == (f"kukaid: error: {tmp_path / 't.parquet'}: no axis has logs enough to "
                                             "assess: the most, 2 (R000 A3), are fewer than a baseline of 5 and one "
                                             "more\n"), r.output
    assert not (tmp_path / "w.json").exists()
    out = lines(assess(rows + [{**r, "robot": "R100"} for r in _synthetic_rows(1, 10, seed=4)]))
    assert out[0] == "1 axis assessed, 0 flagged (of 8)", out
    assert "R000         A3 not assessed: too few logs (2; a baseline of 5 and at least one more are needed)" in out
    assert out[-1] == "... and 2 more axes not assessed (the verdict file lists them)"
    rows = [{**r, "temp_mean": None} for r in _synthetic_rows(7, 10, seed=3)]  # enough logs, no temperature
    assert lines(assess(rows))[1] == "temperature model: none (no temperature logged)"


def test_wear_table_gives_each_change_its_scatter_and_says_what_the_figures_are():
    """New-user trial 10: `fleet wear` printed "+18.4%" and an evidence of 2.87 with nothing to weigh them by:
    the change now carries the baseline's day-to-day scatter (the verdict's scatter_rel), and a line says
    what evidence and the change are."""
    from kukaid.fleet.wear import assess, lines

    res = assess(_synthetic_rows(5, 24, seed=1))
    out = lines(res)
    a = next(a for a in res["axes"] if "evidence" in a)
    row = next(line for line in out if line.startswith(f"{a['robot']:<10} {'A' + str(a['axis']):>4}"))
    sc = a["baseline"]["scatter_rel"]
    assert f"{100 * a['change']['Fc']:+.1f}±{100 * sc[0]:.1f}%" in row.split()
    assert f"{100 * a['change']['Fv']:+.1f}±{100 * sc[1]:.1f}%" in row.split()
    assert any(line.startswith("evidence: the largest CUSUM over its threshold (above 1: flagged)") for line in out)


def test_wear_trend_carries_its_standard_error():
    """New-user trial nu12 item 20: a healthy axis showed "Fc per 30 d +9.7 %" (a slope over 5 noisy daily
    logs, extrapolated 6 x) with no uncertainty while its change got a ±; now the trend carries its
    standard error (one log's scatter over the days' spread) in wear.json and in the PDF's table."""
    import matplotlib.pyplot as plt
    from pdf_layout import layout_problems

    from kukaid.fleet.wear import assess
    from kukaid.report.wear import ranking_pages

    res = assess(_synthetic_rows(5, 10, seed=1))
    a = next(a for a in res["axes"] if "evidence" in a)
    t, nb = a["trend_per_30d"], a["baseline"]["logs"]
    days = np.arange(nb, 10, dtype=float)
    assert t["days"] == np.ptp(days)
    sxx = float(((days - days.mean()) ** 2).sum())
    assert t["Fc_se"] == pytest.approx(30 * a["baseline"]["scatter_rel"][0] / sxx ** 0.5)
    page = ranking_pages(res)[0]
    cells = [c.get_text().get_text() for ax in page.axes for tab in ax.tables for c in tab.get_celld().values()]
    assert f"{100 * t['Fc']:+.1f}±{100 * t['Fc_se']:.1f} %" in cells and not layout_problems(page)
    plt.close(page)


def test_wear_needs_a_temperature_spread_for_a_slope():
    """New-user trial 9: `fleet simulate --temp-swing 0` then `fleet wear` printed "temperature model:
    Fc +105.35 %/K, Fv +113.65 %/K": a slope fitted to the tenths of a kelvin a log's own heating moves
    its mean temperature (and a wearing axis heats more). A baseline spanning less than 3 K determines
    no slope: with none wider the model is none and says so; a narrow axis beside wide ones takes the
    fleet's slope and adds nothing to it."""
    from kukaid.fleet.wear import MIN_TEMP_SPREAD_K, assess, lines

    assert MIN_TEMP_SPREAD_K == 3.0
    rng = np.random.default_rng(5)
    narrow = [{**r, "robot": "N" + r["robot"][1:], "temp_mean": 32.7 + 0.05 * rng.standard_normal()}
              for r in _synthetic_rows(4, 8, seed=5)]
    res = assess(narrow)
    tm = res["temperature_model"]
    assert tm["T_ref"] is None and tm["Fc_per_K"] == 0.0 and tm["Fv_per_K"] == 0.0
    assert tm["note"].startswith("no axis's baseline spans 3 K of motor temperature (the widest 0.")
    assert tm["note"].endswith(" K): the temperature slope is not determined"), tm["note"]
    assert lines(res)[1] == f"temperature model: none ({tm['note']})"
    assert all(a["temperature_coefficient"]["Fc"] == 0.0 for a in res["axes"])
    # the PDF said "no temperature logged" whenever there was no model, whatever the reason
    import matplotlib.pyplot as plt

    from kukaid.report.wear import ranking_pages

    for rows_ in (narrow, [{**r, "temp_mean": None} for r in narrow]):
        r_ = assess(rows_)
        page = ranking_pages(r_)[0]
        text = " ".join(" ".join(t.get_text() for t in page.texts).split())
        plt.close(page)
        assert f"no temperature model ({r_['temperature_model']['note']}): friction not normalised" in text, text
    wide = _synthetic_rows(20, 24, seed=9)
    mixed = narrow + wide
    res, ref = assess(mixed), assess(wide)
    assert res["temperature_model"]["Fc_per_K"] == pytest.approx(ref["temperature_model"]["Fc_per_K"], rel=1e-9)
    b = res["temperature_model"]["Fc_per_K"]
    assert all(a["temperature_coefficient"]["Fc"] == b for a in res["axes"] if a["robot"].startswith("N"))


def test_a_manifest_or_a_report_given_for_the_fit_table_is_named_so(tmp_path, monkeypatch):
    """New-user trial 10: `fleet validate/diagnose --table manifest.csv` said "/abs/path/manifest.csv: not a
    readable Parquet file (Parquet magic bytes not found in footer...)": one line, the path as typed, what
    the file is and which table to give; nothing is written."""
    from click.testing import CliRunner

    from kukaid_cli.main import cli

    monkeypatch.chdir(tmp_path)
    Path("manifest.csv").write_text("robot,axis,date,path\nr1,3,2024-01-01,a.h5\n")
    Path("r.pdf").write_bytes(b"%PDF-1.4\n" + bytes(range(256)))
    Path("t.csv").write_text("a,b\n1,2\n")
    give = ", not a fleet table (Parquet): give the table `kukaid fleet fit` wrote\n"
    for table, said in (("manifest.csv", "manifest.csv: is a fleet manifest (CSV)" + give),
                        ("r.pdf", "r.pdf: is a PDF (a report)" + give),
                        ("t.csv", "t.csv: not" + give.removeprefix(", not"))):
        for args in (["validate", "manifest.csv", "--table", table, "-o", "v.parquet"],
                     ["diagnose", "manifest.csv", "--table", table, "-o", "v.parquet"],
                     ["wear", table, "-o", "w.json"]):
            r = CliRunner().invoke(cli, ["fleet", *args])
            assert r.exit_code == 1 and r.stderr == f"kukaid: error: {said}", (args, r.output)
    assert sorted(os.listdir(tmp_path)) == ["manifest.csv", "r.pdf", "t.csv"]


def test_wear_of_a_diagnose_table_says_it_is_not_a_fit_table(tmp_path):
    """New-user trial 7: `fleet wear` of the table of `fleet diagnose` said "the table has no fitted rows
    (status ok)", though every row was ok: it is not a fit table, and says so, naming it and its kind."""
    from click.testing import CliRunner

    from kukaid.fleet.table import write_table
    from kukaid_cli.main import cli

    for kind in ("diagnose", "validate"):
        rows = [{**r, "kind": kind} for r in _synthetic_rows(2, 8, seed=4)]
        table = tmp_path / f"{kind}.parquet"
        write_table(table, rows, {"task": kind})
        r = CliRunner().invoke(cli, ["fleet", "wear", str(table), "-o", str(tmp_path / "w.json")])
        assert r.exit_code == 1 and r.stderr == (f"kukaid: error: {table}: not a table of fleet fit (its rows are of "
                                                 f"fleet {kind}): fleet wear assesses the friction of a fit table "
                                                 "(kukaid fleet fit)\n"), r.output
        assert not (tmp_path / "w.json").exists()
    rows = [{**r, "status": "error"} for r in _synthetic_rows(2, 8, seed=4)]  # a fit table of error rows only
    write_table(tmp_path / "fit.parquet", rows, {"task": "fit"})
    r = CliRunner().invoke(cli, ["fleet", "wear", str(tmp_path / "fit.parquet"), "-o", str(tmp_path / "w.json")])
    assert r.exit_code == 1 and "fit.parquet: the table has no fitted rows (status ok) to assess" in r.stderr


def test_wear_replaces_only_a_wear_verdict_without_force(tmp_path):
    """New-user trial 9: `fleet wear -o params.json` replaced a parameter file with the verdict, silently;
    every other JSON output (excite, fit, diagnose -o) replaces only a file of its own kind."""
    from click.testing import CliRunner

    from kukaid.fleet.table import write_table
    from kukaid_cli.main import cli

    write_table(tmp_path / "t.parquet", _synthetic_rows(3, 8, seed=4), {"task": "fit"})
    params = tmp_path / "params.json"
    params.write_text('{"schema": "kukaid.params/1"}\n')
    args = ["fleet", "wear", str(tmp_path / "t.parquet"), "-o", str(params)]
    r = CliRunner().invoke(cli, args)
    assert r.exit_code == 1 and r.stderr == (f"kukaid: error: {params}: already exists and is a kukaid.params/1 file, "
                                             "not kukaid.fleet-wear/1; choose another name or pass --force to "
                                             "replace it\n"), r.output
    assert params.read_text() == '{"schema": "kukaid.params/1"}\n'
    r = CliRunner().invoke(cli, [*args, "--force"])
    assert r.exit_code == 0 and json.loads(params.read_text())["schema"] == "kukaid.fleet-wear/1", r.output
    r = CliRunner().invoke(cli, args)  # a verdict by a verdict: derived from the table again
    assert r.exit_code == 0, r.output


def test_wear_cli_writes_json_and_pdf(tmp_path, kukaid_cmd):
    from kukaid.fleet.table import write_table

    rows = _synthetic_rows(20, 24, seed=9, wearing={3})
    write_table(tmp_path / "t.parquet", rows, {"task": "fit"})
    r = _run(kukaid_cmd, "fleet", "wear", tmp_path / "t.parquet", "-o", tmp_path / "w.json", "--report",
             tmp_path / "w.pdf")
    assert r.returncode == 0, r.stderr
    w = json.loads((tmp_path / "w.json").read_text())
    assert w["schema"] == "kukaid.fleet-wear/1"
    top = w["axes"][0]
    assert (top["robot"], top["axis"], top["flagged"]) == ("R003", 3, True) and top["first_flagged"]
    assert {"robot", "axis", "flagged", "first_flagged", "evidence"} <= set(top)
    assert (tmp_path / "w.pdf").read_bytes()[:4] == b"%PDF"


def test_wear_report_plots_every_axis_change_with_its_standard_error():
    """New-user trial 11: the wear PDF had the ranking table and no figure of the fleet: now a page plots each
    assessed axis's change of Fc and Fv with its standard error, the flagged ones red and named."""
    from matplotlib.container import ErrorbarContainer
    from pdf_layout import layout_problems

    from kukaid.fleet.wear import assess
    from kukaid.report.wear import change_page, change_se

    res = assess(_synthetic_rows(20, 24, seed=9, wearing={3}))
    fig = change_page(res)
    assert not layout_problems(fig)
    bars = [c for c in fig.axes[0].containers if isinstance(c, ErrorbarContainer)]
    flagged = [a for a in res["axes"] if a.get("flagged")]
    assert [len(c.lines[0].get_xdata()) for c in bars] == [20 - len(flagged), len(flagged)]
    a = flagged[0]
    (x,), (y,) = bars[1].lines[0].get_xdata(), bars[1].lines[0].get_ydata()
    assert (x, y) == (100 * a["change"]["Fc"], 100 * a["change"]["Fv"])
    se = change_se(a)  # the last 7 logs against a baseline of 6, one log's scatter each
    assert se[0] == pytest.approx((1 + a["change"]["Fc"]) * a["baseline"]["scatter_rel"][0] * (1 / 7 + 1 / 6) ** 0.5)
    assert f"{a['robot']} A{a['axis']}" in [t.get_text() for t in fig.axes[0].texts]


def test_validate_and_diagnose_over_the_fleet(tmp_path, kukaid_cmd):
    man = small_fleet(tmp_path / "f", robots=1, days=3, seed=71)
    fit, val, dia = tmp_path / "fit.parquet", tmp_path / "val.parquet", tmp_path / "dia.parquet"
    assert _run(kukaid_cmd, "fleet", "fit", man, "-o", fit, "--workers", "1").returncode == 0
    r = _run(kukaid_cmd, "fleet", "validate", man, "--table", fit, "-o", val, "--workers", "1")
    assert r.returncode == 0, r.stderr
    rows, settings = read_table(val)
    assert settings["task"] == "validate" and [row["status"] for row in rows] == ["error", "ok", "ok"]
    assert "no fit of R001 A3 from a day before" in rows[0]["error"]
    assert rows[1]["model_date"] == rows[0]["date"] and 0 < rows[1]["rel_error"] < 0.2
    r = _run(kukaid_cmd, "fleet", "diagnose", man, "--table", fit, "-o", dia, "--workers", "1")
    assert r.returncode == 0, r.stderr
    rows, _ = read_table(dia)
    assert all(row["status"] == "ok" and row["rmse"] > 0 and row["effects"] is not None for row in rows)
    r = _run(kukaid_cmd, "fleet", "validate", man, "--table", val, "-o", tmp_path / "x.parquet")
    assert r.returncode == 1 and "not a table of fleet fit" in r.stderr and r.stderr.count("\n") == 1


def _two_model_rows(n_cv: int, n_st: int) -> list[dict]:
    """One axis fitted on n_cv + n_st days, alternately coulomb-viscous and stribeck (fleet fit's default
    friction model, auto, chooses per log)."""
    rows = _synthetic_rows(1, n_cv + n_st, seed=2)
    models = np.random.default_rng(0).permutation(["coulomb-viscous"] * n_cv + ["stribeck"] * n_st)
    for r, m in zip(rows, models):
        r["friction_model"] = str(m)
    return rows


def test_wear_says_which_logs_another_friction_model_left_out(tmp_path):
    """New-user trial 15: six daily logs of an axis fitted with fleet fit's default friction model (auto:
    stribeck on four days, coulomb-viscous on two) gave 'no axis has logs enough to assess: the most, 4
    (R1 A3)', the other two dropped without a word; now the line says how many were left out and why, and
    an assessed axis with logs left out says so below the table."""
    from kukaid.errors import KukaidError
    from kukaid.fleet.wear import assess, lines

    with pytest.raises(KukaidError) as e:
        assess(_two_model_rows(2, 4), source="t.parquet")
    assert str(e.value) == ("t.parquet: no axis has logs enough to assess: the most, 4 (R000 A3), are fewer than a "
                            "baseline of 5 and one more; 2 of its 6 fitted logs are of coulomb-viscous, not mixed "
                            "with its 4 stribeck fits (fleet fit --friction-model stribeck or coulomb-viscous fits "
                            "every log with one model)")
    res = assess(_two_model_rows(3, 8) + _synthetic_rows(3, 11, seed=4)[11:])
    a = next(a for a in res["axes"] if a["robot"] == "R000")
    assert a["n_logs"] == 8 and a["rows_not_used"] == 3 and "3 of its 11 fitted logs are of coulomb-viscous" in a["left_out"]
    assert any(line.startswith("R000         A3 assessed on 8 logs: 3 of its 11 fitted logs") for line in lines(res))
    assert not any("assessed on" in line for line in lines(assess(_synthetic_rows(3, 11, seed=4))))


def test_wear_says_a_second_log_of_a_day_is_left_out_as_such():
    """New-user trial 19: an axis with two logs on one day (fleet wear takes one log a day) said
    'assessed on 10 logs: 1 with Fc or Fv at 0 (on its bound: no relative change to follow)'; neither
    log had Fc or Fv at 0.  The line says a second log of a day was left out."""
    from kukaid.fleet.wear import assess, lines

    rows = _synthetic_rows(3, 11, seed=4)
    rows.append({**rows[3], "path": "again.h5", "Fc": rows[3]["Fc"] * 1.01})  # R000's fourth day, logged twice
    a = next(a for a in assess(rows)["axes"] if a["robot"] == "R000")
    assert a["n_logs"] == 11 and a["rows_not_used"] == 1
    assert a["left_out"] == "1 more log of a day already logged (one log a day: the first by path)"
    assert "R000         A3 assessed on 11 logs: 1 more log of a day already logged (one log a day: the first by " \
           "path)" in lines(assess(rows))
    zero = _synthetic_rows(3, 11, seed=4)
    zero[3] = {**zero[3], "Fv": 0.0}
    a = next(a for a in assess(zero)["axes"] if a["robot"] == "R000")
    assert a["left_out"] == "1 with Fc or Fv at 0 (on its bound: no relative change to follow)"


def test_wear_picks_the_same_friction_model_of_a_tie_in_every_run():
    """Equally many logs of two friction models: the axis's model was max() over a set of names, whose
    order is the string hashes' (PYTHONHASHSEED differs per process), so runs of fleet wear on one table
    could assess different logs."""
    code = ("import sys; sys.path.insert(0, 'tests'); from test_fleet import _two_model_rows; "
            "from kukaid.fleet.wear import assess; print(assess(_two_model_rows(6, 6))['axes'][0]['friction_model'])")
    root = Path(__file__).resolve().parent.parent
    got = {subprocess.run([os.environ.get("PYTHON", __import__("sys").executable), "-c", code], cwd=root, check=True,
                          capture_output=True, text=True, env={**os.environ, "PYTHONHASHSEED": str(seed)}).stdout.strip()
           for seed in range(8)}
    assert len(got) == 1, got


def test_an_error_row_names_the_log_as_the_manifest_does(tmp_path):
    """New-user trial 15: the error row of a log cut short (its header unreadable) named it by its absolute path
    (/tmp/.../logs/R4/2026-01-05/A3.h5: not a readable HDF5 file ...), and so did a fit's refusal of a whole-arm
    log, while every other row names the log as the manifest or the folder does (R4/2026-01-05/A3.h5)."""
    from kukaid.fleet.manifest import content_hash
    from kukaid.fleet.tasks import FitOptions, Job, fit_task

    small_fleet(tmp_path, robots=1, days=1)
    (good,) = sorted((tmp_path / "logs").rglob("*.h5"))
    cut = tmp_path / "logs" / "R4" / "2026-01-05" / "A3.h5"
    cut.parent.mkdir(parents=True)
    cut.write_bytes(good.read_bytes()[:3000])
    job = Job("R4", 3, "2026-01-05", str(cut), "R4/2026-01-05/A3.h5", content_hash(cut))
    (row,) = fit_task(job, FitOptions())
    assert row["status"] == "error" and row["error"].startswith("R4/2026-01-05/A3.h5: not a readable HDF5 file"), row
    assert str(tmp_path) not in row["error"]
    from kukaid.fleet.tasks import duplicate_row

    dup = Job("R5", 3, "2026-01-05", str(good), "R5/2026-01-05/A3.h5", content_hash(good))
    assert duplicate_row(dup, "validate", "R001/x.h5")["error"] == ("duplicate: the same content as R001/x.h5 (not "
                                                                    "validated twice)")


def test_one_log_listed_for_two_of_its_axes_fits_both(tmp_path):
    """New-user trial 17: a manifest listing a two-axis log for A2 and again for A3 (as `fleet fit`
    asks: "holds axes A2, A3; give the axis in the manifest") fitted A2 only and said "1 already in
    the table" of a table just made; a log is done per axis, and a whole-arm entry by any of its rows."""
    from kukaid.fleet.manifest import Entry, content_hash
    from kukaid.fleet.run import plan

    log = tmp_path / "arm.csv"
    log.write_text("time_s,A2_deg,A2_Nm,A3_deg,A3_Nm\n0,0,0,0,0\n")
    a2, a3, arm = (Entry("R1", axis, "2026-01-05", str(log), "arm.csv") for axis in (2, 3, None))
    jobs, direct, skipped, repeated = plan([a2, a3], [], "fit")
    assert [j.axis for j in jobs] == [2, 3] and not direct and skipped == repeated == 0
    done = {"path": "arm.csv", "sha256": content_hash(log), "axis": 2, "status": "ok"}
    jobs, direct, skipped, repeated = plan([a2, a3], [done], "fit")
    assert [j.axis for j in jobs] == [3] and not direct and (skipped, repeated) == (1, 0)
    jobs, direct, skipped, repeated = plan([arm], [done], "fit")   # a whole-arm entry: its rows are of every axis
    assert not jobs and (skipped, repeated) == (1, 0)
    jobs, direct, skipped, repeated = plan([arm, a3], [], "fit")   # listed without an axis, then for one
    assert [j.axis for j in jobs] == [None] and (skipped, repeated) == (0, 1)
    failed = {**done, "axis": None, "status": "error"}             # "holds axes A2, A3; give the axis": given now
    jobs, direct, skipped, repeated = plan([a2, a3], [failed], "fit")
    assert [j.axis for j in jobs] == [2, 3] and (skipped, repeated) == (0, 0)


def test_a_manifest_line_given_twice_is_not_said_to_be_in_the_table(tmp_path, capsys):
    """New-user trial 17: a manifest listing one log twice (the same line), fitted into a new table,
    said "1 already in the table"; it was the input that repeated it."""
    from kukaid.fleet.manifest import Entry
    from kukaid.fleet.run import RunSummary, plan
    from kukaid_cli.cmd_fleet import _report

    log = tmp_path / "a.csv"
    log.write_text("time_s,A3_deg,A3_Nm\n0,0,0\n")
    a = Entry("R1", 3, "2026-01-05", str(log), "a.csv")
    jobs, direct, skipped, repeated = plan([a, a], [], "fit")
    assert len(jobs) == 1 and (skipped, repeated) == (0, 1)
    _report(RunSummary(total=2, ran=1, rows=1, repeated=1), tmp_path / "t.parquet", "fitted")
    err = capsys.readouterr().err
    assert "1 listed twice in the input" in err and "already in the table" not in err, err


def test_fleet_diagnose_and_validate_take_the_fit_of_the_logs_axis(tmp_path):
    """New-user trial 17: a two-axis log fitted for A2 and A3 (two rows, one content hash): `fleet
    diagnose` took A3's fit for the A2 entry, "its fit in t.parquet: the parameters are of axis A3,
    not A2", an error row; the fit of a log is looked up by its hash and axis."""
    from kukaid.fleet.table import write_table
    from kukaid.fleet.tasks import CheckOptions, Job, _model_for

    rows = [{"robot": "R1", "axis": a, "date": d, "path": "arm.csv", "sha256": sha, "status": "ok", "kind": "fit",
             "result": json.dumps({"axis": a, "day": d})} for d, sha in (("2026-01-05", "s1"), ("2026-01-06", "s2"))
            for a in (2, 3)]
    table = tmp_path / "t.parquet"
    write_table(table, rows, {"task": "fit"})
    for kind, sha, date in (("diagnose", "s2", "2026-01-06"), ("validate", "s2", "2026-01-06")):
        opts = CheckOptions(table=str(table), kind=kind, run=None)
        for axis in (2, 3):
            params, _ = _model_for(Job("R1", axis, date, "/x/arm.csv", "arm.csv", sha), opts, axis)
            assert params["axis"] == axis, (kind, axis, params)


@pytest.mark.parametrize("address", ["notaurl", "tcp://127.0.0.1", "tcp://host:abc", "http://host:8786",
                                     "tcp://host:70000"])
def test_a_scheduler_address_that_is_none_is_a_usage_error(tmp_path, address):
    """New-user trial 17: `fleet fit manifest.csv -o t.parquet --scheduler notaurl` was an internal
    error (ValueError: missing port number in address, exit 70); an address without a port, with a
    port that is no number or another scheme is the option's error, before any work."""
    from click.testing import CliRunner

    from kukaid_cli.main import cli

    man = small_fleet(tmp_path / "f", robots=1, days=1, seed=41)
    for args, out in ((["fit", str(man)], "t.parquet"), (["validate", str(man), "--table", str(man)], "v.parquet"),
                      (["simulate", "--robots", "1", "--days", "1"], "fleet")):
        r = CliRunner().invoke(cli, ["fleet", *args, "-o", str(tmp_path / out), "--scheduler", address])
        assert r.exit_code == 2 and "Invalid value for --scheduler" in r.stderr and "tcp://host:port" in r.stderr, \
            (args, r.output)
        assert len(r.stderr.strip().splitlines()) == 1 and not (tmp_path / out).exists()
