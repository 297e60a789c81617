"""kukaid fleet: many logs at once on Dask (fit, validate, diagnose), wear watch, a simulated fleet."""
from __future__ import annotations

from pathlib import Path

import click

from kukaid_cli._util import FloatRange

_INPUT = click.argument("source", metavar="INPUT", type=click.Path(exists=True, path_type=Path))
_PATTERN = click.option("--pattern", default=None, metavar="PATTERN",
                        help="With a folder INPUT: which files are logs, e.g. '{robot}/{date}/*.h5' "
                             "(fields {robot}, {date} YYYY-MM-DD, {axis}) [default: {robot}/{date}/*].")
_WORKERS = click.option("--workers", type=int, default=None,
                        help="Worker processes of the local Dask cluster [default: the machine's cores].")
_SCHEDULER = click.option("--scheduler", default=None, metavar="ADDRESS",
                          help="Use the running Dask cluster of this scheduler (tcp://host:8786) instead of a "
                               "local one; its workers must see the logs under the same paths.")


@click.group("fleet")
def command() -> None:
    """Many logs of many robots at once, on Dask: fit, validate and diagnose every log (one Parquet
    table), watch friction for wear, and simulate a fleet.

    INPUT is a manifest CSV with columns robot,axis,date,path (paths relative to the manifest,
    axis empty for a whole-arm log) or a folder of logs matched by --pattern.  A log that cannot
    be read or fitted becomes an error row (a run whose every log did exits with status 1); a run
    started again skips the logs already in the table (by content hash)."""


class _Progress:
    """A bar on a terminal (stderr), nothing in a pipe; the summary line comes after."""

    def __init__(self, label: str) -> None:
        self.label, self._cm, self._update = label, None, None

    def __call__(self, done: int, total: int) -> None:
        if self._update is None:
            from kukaid_cli._util import progress

            self._cm = progress(max(total, 1), self.label)
            self._update = self._cm.__enter__()
        self._update(done)

    def close(self) -> None:
        if self._cm is not None:
            self._cm.__exit__(None, None, None)
            self._cm = None


def _check_workers(workers: int | None, scheduler: str | None) -> None:
    if workers is not None and workers < 1:
        raise click.BadParameter(f"{workers} must be at least 1", param_hint="--workers")
    if workers is not None and scheduler is not None:
        raise click.UsageError("--workers applies to the local cluster; a running cluster (--scheduler) has its "
                               "own workers")
    if scheduler is not None:  # Dask's own error for a malformed address was an internal error (exit 70)
        import re

        m = re.fullmatch(r"(?:(?:tcp|tls)://)?([^\s/:]+|\[[0-9A-Fa-f:.]+\]):(\d{1,5})", scheduler)
        if not m or not 1 <= int(m.group(2)) <= 65535:
            raise click.BadParameter(f"{scheduler!r} is not a scheduler's address: tcp://host:port (e.g. "
                                     "tcp://fleet-scheduler:8786)", param_hint="--scheduler")


def _check_pattern(source: Path, pattern: str | None) -> None:
    """--pattern is an option's value: a malformed one, or one given with a manifest, is a usage error (exit 2)."""
    if pattern is None:
        return
    from kukaid.fleet.manifest import pattern_regex
    from kukaid_cli._util import usage_errors

    if Path(source).exists() and not Path(source).is_dir():
        raise click.UsageError(f"{source}: --pattern applies to a folder of logs, not to a manifest file")
    with usage_errors("--pattern"):
        pattern_regex(pattern)


def _table_output(output: Path, source: Path) -> None:
    from kukaid_cli._util import check_outputs, check_suffix

    check_suffix(output, ".parquet")
    check_outputs([output], [source] if source.is_file() else [])


def _entries(source: Path, pattern: str | None, command: str, verb: str) -> list:
    """The fleet's logs (:func:`kukaid.fleet.manifest.read_input`); log files in the folder that the
    pattern does not match are not run, and a warning line names them (the first three)."""
    from kukaid.fleet.manifest import DEFAULT_PATTERN, read_input

    unmatched: list[str] = []
    entries = read_input(source, pattern, unmatched)
    if unmatched:
        n = len(unmatched)
        names = ", ".join(unmatched[:3]) + (f" and {n - 3} more" if n > 3 else "")
        click.echo(f"kukaid: warning: fleet {command}: {source}: {_n(n, 'log file')} "
                   f"{'does' if n == 1 else 'do'} not match the pattern '{pattern or DEFAULT_PATTERN}' and "
                   f"{'is' if n == 1 else 'are'} not {verb}: {names} ({{robot}} and {{date}} YYYY-MM-DD are one "
                   "folder each; --pattern for another layout)", err=True)
    return entries


def _n(count: int, noun: str, plural: str | None = None) -> str:
    """``1 error row``, ``2 error rows`` (``plural``: when it is not ``noun`` + s)."""
    return f"{count} {noun if count == 1 else plural or noun + 's'}"


def _report(summary, output: Path, what: str) -> None:
    """The summary line; a run whose every log (duplicates aside) became an error row fails: one line
    with the first error, exit status 1 (the table is written, its error column says why per log)."""
    parts = [f"{summary.ran} {what}", _n(summary.errors, "error row")]
    if summary.duplicates:
        parts.append(f"{_n(summary.duplicates, 'duplicate')} among them")  # duplicates are error rows too
    if summary.skipped:
        parts.append(f"{summary.skipped} already in the table")
    if summary.repeated:
        parts.append(f"{summary.repeated} listed twice in the input")
    if summary.ran == 0 and summary.errors > summary.duplicates:
        from kukaid.errors import KukaidError

        raise KukaidError(f"{output}: no log {what}, {', '.join(parts[1:])}; the first: {summary.first_error}")
    peak = f"; peak worker memory {summary.peak_worker_mb:.0f} MB" if summary.peak_worker_mb else ""
    # why a log failed is otherwise only in the table's error column: the first one is said
    first = (f"; the first error row: {summary.first_error} (the table's error column says why for each)"
             if summary.first_error else "")
    click.echo(f"{output}: {_n(summary.rows, 'row')} ({', '.join(parts)}) in {summary.wall_s:.1f} s"
               + (f" on {_n(summary.workers, 'worker')}" if summary.workers else "") + peak + first, err=True)


@command.command("fit")
@_INPUT
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="The fleet table to write or complete (Parquet).")
@_PATTERN
@_WORKERS
@_SCHEDULER
@click.option("--robot", default=None, metavar="URDF|NAME",
              help="Fit whole-arm logs jointly from this URDF (or kr6-r700-sixx), as kukaid fit --robot.")
@click.option("--friction-model", type=click.Choice(["auto", "stribeck", "coulomb-viscous"]), default="auto",
              show_default=True, help="Friction model of every fit (with --robot: auto is coulomb-viscous).")
def fit_cmd(source, output, pattern, workers, scheduler, robot, friction_model) -> None:
    """Fit every log of the fleet as kukaid fit would; one row per log and axis in the table.

    Columns: robot, axis, date, path, sha256, status, error, Fc, Fv, Fs, vs, Izz, Mx, offset,
    their sigma, rmse, temperature (mean, min, max), the full parameter file (result), the worker,
    its peak memory and the time."""
    from kukaid.fleet.run import run_tasks
    from kukaid.fleet.tasks import FitOptions, fit_task

    _check_workers(workers, scheduler)
    _check_pattern(source, pattern)
    _table_output(output, source)
    entries = _entries(source, pattern, "fit", "fitted")
    opts = FitOptions(friction_model=friction_model, robot=robot)
    bar = _Progress("fleet fit")
    try:
        s = run_tasks(entries, output, fit_task, opts, opts.settings(), kind="fit", workers=workers,
                      scheduler=scheduler, progress=bar)
    finally:
        bar.close()
    _report(s, output, "fitted")


@command.command("simulate")
@click.option("--robots", type=click.IntRange(1, 100_000), default=10, show_default=True, help="Robots in the fleet.")
@click.option("--days", type=click.IntRange(1, 100_000), default=30, show_default=True, help="Days, one log per robot (and axis) a day.")
@click.option("-o", "--output", "outdir", type=click.Path(file_okay=False, path_type=Path), required=True,
              help="Folder to write: logs/, manifest.csv, truth.json.")
@click.option("--axes", default="3", show_default=True, metavar="LIST",
              help="Axes logged one by one, e.g. 3 or 1,2,3,4,5,6 (not with --whole-arm).")
@click.option("--whole-arm", is_flag=True, help="One six-axis log per robot and day (fit with --robot kr6-r700-sixx).")
@click.option("--wear-share", type=FloatRange(0, 1), default=0.08, show_default=True,
              help="Share of the axes whose friction wears.")
@click.option("--wear", "wear_range", default="0.2:0.5", show_default=True, metavar="LO:HI",
              help="Friction growth of a wearing axis over the period, relative.")
@click.option("--temp-swing", type=FloatRange(0, 60), default=15.0, show_default=True,
              help="Day-to-day motor temperature swing, ± °C around 32 °C.")
@click.option("--seed", type=click.IntRange(0, 2**32 - 1), default=0, show_default=True, help="Seed of every draw.")
@_WORKERS
@_SCHEDULER
@click.option("--force", is_flag=True, help="Write into a folder that already holds files.")
def simulate_cmd(robots, days, outdir, axes, whole_arm, wear_share, wear_range, temp_swing, seed, workers,
                 scheduler, force) -> None:
    """A fleet from the virtual KR C4: per-axis truth spread, day-to-day motor temperature (the
    temp dataset), friction that depends on it, and wear in a share of the axes; the truth in
    truth.json apart from the logs."""
    from kukaid.fleet.simulate import FleetSimConfig, simulate_fleet
    from kukaid_cli._util import given, usage_errors

    _check_workers(workers, scheduler)
    if whole_arm and given("axes"):
        raise click.UsageError("--axes does not apply with --whole-arm (each log holds A1 to A6)")
    try:
        ax = tuple(int(a.strip().lstrip("Aa")) for a in axes.split(",") if a.strip())
    except ValueError:
        raise click.BadParameter(f"'{axes}': expected axis numbers like 1,2,3", param_hint="--axes") from None
    try:
        lo, hi = (float(x) for x in wear_range.split(":"))
    except ValueError:
        raise click.BadParameter(f"'{wear_range}': expected LO:HI like 0.2:0.5", param_hint="--wear") from None
    if outdir.exists() and not outdir.is_dir():
        raise click.BadParameter(f"{outdir}: is not a folder", param_hint="-o")
    if outdir.is_dir() and any(outdir.iterdir()) and not force:
        raise click.UsageError(f"{outdir}: the folder is not empty; choose another or pass --force")
    with usage_errors():
        cfg = FleetSimConfig(robots=robots, days=days, axes=ax, whole_arm=whole_arm, wear_share=wear_share,
                             wear_range=(lo, hi), temp_swing=temp_swing, seed=seed)
    fresh = not outdir.exists() or not any(outdir.iterdir())  # then the folder will hold only this run's files
    bar = _Progress("fleet simulate")
    try:
        s = simulate_fleet(cfg, outdir, workers=workers, scheduler=scheduler, progress=bar)
    except BaseException:  # Ctrl-C, a failure: no half-made fleet (logs without a manifest) in the way of the next run
        if fresh:
            import shutil

            shutil.rmtree(outdir, ignore_errors=True)
        raise
    finally:
        bar.close()
    click.echo(f"{outdir}: {_n(s.logs, 'log')} of {_n(s.axes, 'axis', 'axes')} ({s.wearing} wearing) in {s.wall_s:.1f} s; "
               f"manifest.csv, truth.json", err=True)


@command.command("wear")
@click.argument("table", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="The verdict per robot and axis (JSON, kukaid.fleet-wear/1).")
@click.option("--report", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="PDF: axes ranked by evidence, the trend of each flagged axis with its temperature.")
@click.option("--alpha", type=FloatRange(0.0001, 0.2), default=0.005, show_default=True,
              help="Share of healthy axes allowed ever to be flagged over the table's days (sets the threshold).")
@click.option("--baseline", type=click.IntRange(3, 10_000), default=None,
              help="Logs in each axis's baseline [default: a quarter of its logs, 5 to 14].")
@click.option("--json", "as_json", is_flag=True, help="Print the verdict as JSON on stdout (without the series).")
@click.option("--force", is_flag=True, help="Replace an existing -o file that is not a wear verdict.")
def wear_cmd(table, output, report, alpha, baseline, as_json, force) -> None:
    """Per robot and axis: friction (Fc, Fv) at a reference temperature (a temperature model fitted
    across the fleet), its trend, and a flag when it leaves its own baseline and the fleet's
    course by more than the scatter allows (one-sided CUSUM, threshold for at most --alpha of
    healthy axes ever flagged).  Prints the axes ranked by evidence."""
    import json

    from kukaid.atomic import atomic_paths
    from kukaid.fleet.table import FIT_TABLE, read_table
    from kukaid.fleet.wear import SCHEMA, WearSettings, assess, lines
    from kukaid_cli._util import check_outputs, check_suffix, refuse_other_kind

    check_suffix(output, ".json")
    check_suffix(report, ".pdf")
    check_outputs([output, report], [table])
    refuse_other_kind(output, force, SCHEMA)
    rows, _ = read_table(table, FIT_TABLE)
    result = assess(rows, WearSettings(alpha=alpha, baseline=baseline), source=str(table))
    result["table"] = str(table)
    with atomic_paths(*[p for p in (output, report) if p is not None]) as tmps:
        tmp = iter(tmps)
        next(tmp).write_text(json.dumps(result, indent=1) + "\n")
        if report is not None:
            from kukaid.report.wear import write_wear_report

            write_wear_report(next(tmp), result, str(table))
    if as_json:
        slim = {**result, "axes": [{k: v for k, v in a.items() if k != "series"} for a in result["axes"]]}
        click.echo(json.dumps(slim, indent=1))
    else:
        for line in lines(result):
            click.echo(line)
    click.echo(f"{output}: wear verdict written" + (f"; {report}: report written" if report else ""), err=True)


def _check(kind: str, source, table, output, pattern, workers, scheduler) -> None:
    from kukaid.fleet.run import run_tasks
    from kukaid.fleet.tasks import CheckOptions, check_task

    _check_workers(workers, scheduler)
    _check_pattern(source, pattern)
    _table_output(output, source)
    from kukaid_cli._util import check_outputs

    check_outputs([output], [table])
    if kind == "validate":
        from kukaid.diagnose.validate import validate as run
    else:
        import functools

        from kukaid.diagnose import diagnose_model

        run = functools.partial(diagnose_model, max_steps=4)  # what kukaid diagnose runs, its default --max-steps
    from kukaid.fleet.tasks import _fits

    # a table that is not a fit table: one line, before any work, naming it as typed (the workers get its full path)
    _fits(str(table), table.stat().st_mtime)
    entries = _entries(source, pattern, kind, "validated" if kind == "validate" else "diagnosed")
    opts = CheckOptions(table=str(table.resolve()), kind=kind, run=run)
    bar = _Progress(f"fleet {kind}")
    try:
        s = run_tasks(entries, output, check_task, opts, opts.settings(), kind=kind, workers=workers,
                      scheduler=scheduler, progress=bar)
    finally:
        bar.close()
    _report(s, output, "validated" if kind == "validate" else "diagnosed")


_FIT_TABLE = click.option("--table", "table", type=click.Path(exists=True, dir_okay=False, path_type=Path),
                          required=True, help="The fit table of the same fleet (kukaid fleet fit).")


@command.command("validate")
@_INPUT
@_FIT_TABLE
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="The validation table to write or complete (Parquet).")
@_PATTERN
@_WORKERS
@_SCHEDULER
def validate_cmd(source, table, output, pattern, workers, scheduler) -> None:
    """Each log predicted by the latest fit of its robot and axis from an earlier day (kukaid
    validate): RMSE, relative error, R² per log and axis; a model that stops predicting its
    robot's next day shows as a rising relative error."""
    _check("validate", source, table, output, pattern, workers, scheduler)


@command.command("diagnose")
@_INPUT
@_FIT_TABLE
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="The diagnosis table to write or complete (Parquet).")
@_PATTERN
@_WORKERS
@_SCHEDULER
def diagnose_cmd(source, table, output, pattern, workers, scheduler) -> None:
    """Each log against its own fit (kukaid diagnose): which physical effects the model misses
    (column effects), the RMSE after adding them, the whole diagnosis as JSON. A whole-arm log
    (fleet fit --robot) is diagnosed as kukaid diagnose does a robot parameter file: one row per
    joint, its held-out relative error after the effects (rel_error) and the effects acting on it."""
    _check("diagnose", source, table, output, pattern, workers, scheduler)
