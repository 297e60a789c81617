"""The run recorder: what a run of the admittance loop leaves on disk, whatever stops it.

A run is recorded to ``NAME.partial.h5`` beside the output while the robot moves (a killed run
leaves it, readable); the finished run's whole record (the ``control`` group added) replaces it,
and it replaces the output (and a PDF report its own) only when the run has ended and everything
is written: an output is never truncated or lost by a run that fails.  Ctrl-C and SIGTERM are
counted while the recorder is open and stop the run at the next cycle of its backend, so the loop
holds the robot and returns the run.

Usage (what ``kukaid run-admittance`` does)::

    with RunRecorder(output, axis=3, channels=("q", "tau", "q_cmd"), attrs=attrs, report=pdf) as rec:
        run = rec.record(lambda on_row: run_admittance(rec.guard(backend), model, cfg, on_row=on_row))
        rec.finish(run, report=lambda path: plot_runs([...], path))
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Callable

import numpy as np

from kukaid.errors import EXIT_INTERNAL, DiskFullError, KukaidError

#: the status of a run that an interrupt stopped (the loop's)
INTERRUPTED = "stopped: interrupted"


def partial_path(output: Path) -> Path:
    """Where a run is recorded while the robot moves: ``run.partial.h5`` beside ``run.h5``."""
    output = Path(output)
    return output.with_name(f"{output.stem}.partial{output.suffix}")


def check_no_partial(output: Path) -> None:
    """Refuse to start when the partial file of an earlier run that did not finish is in the way
    (recorded data, never replaced)."""
    partial = partial_path(output)
    if partial.exists() or partial.is_symlink():
        raise KukaidError(f"{partial}: the record of an earlier run that did not finish is in the way (a run is "
                          f"recorded there while the robot moves); move it away or remove it, then run again")


class Interrupts:
    """Ctrl-C and SIGTERM while a run goes on, counted instead of raised.

    A KeyboardInterrupt raised by the signal handler lands wherever Python happens to be: between
    two cycles, in the estimator, in the log writer, in a weakref callback (where Python prints it
    and drops it), after the loop.  Only one raised inside ``backend.cycle`` is the loop's to handle
    (it holds the robot and returns the run, "stopped: interrupted"); anywhere else it ended the
    command with exit 130 and no control group, or was lost.  So the handler only counts, and
    :class:`StopOnInterrupt` raises the interrupt inside ``backend.cycle``, at the next cycle."""

    def __init__(self) -> None:
        self.count = 0
        self._old: dict = {}

    def _on_signal(self, *_: object) -> None:
        self.count += 1

    def __enter__(self) -> "Interrupts":
        import signal

        for sig in (signal.SIGINT, signal.SIGTERM):
            self._old[sig] = signal.signal(sig, self._on_signal)
        return self

    def __exit__(self, *exc: object) -> None:
        import signal

        for sig, old in self._old.items():
            signal.signal(sig, old if old is not None else signal.SIG_DFL)
        self._old.clear()


class StopOnInterrupt:
    """A backend whose ``cycle`` raises KeyboardInterrupt once an interrupt newer than ``seen`` has
    come, before a new reference is sent (see :class:`Interrupts`); everything else is the backend's."""

    def __init__(self, backend: Any, interrupts: Interrupts, seen: int = 0) -> None:
        self._backend, self._interrupts, self._seen = backend, interrupts, seen

    def __getattr__(self, name: str) -> Any:
        return getattr(self._backend, name)

    def cycle(self, q_cmd: Any, dt: float) -> Any:
        if self._interrupts.count > self._seen:
            raise KeyboardInterrupt
        return self._backend.cycle(q_cmd, dt)


def kept(e: BaseException, n: int, partial: Path, output: Path) -> BaseException:
    """The error to raise when a run fails after it was set up: the old output is left as it was,
    and what the run recorded stays in the partial file, named in the error's one line.

    Kept, not removed: on a real robot the partial log is the only record of a motion that
    happened (what the axis did up to the failure, the thing to look at after a crash), and
    "nothing already recorded is ever lost".  It is not put in place of the output: a failed
    command does not replace what the output held (with --force, an earlier run's log).  A file
    without a sample records nothing and is removed."""
    if n == 0:
        partial.unlink(missing_ok=True)
        return e
    if not partial.exists():
        return e
    where = f"the {n} samples recorded are kept in {partial} ({output} is not changed)"
    if isinstance(e, KukaidError):
        new, code = KukaidError(f"{e}; {where}"), e.exit_code
    elif isinstance(e, KeyboardInterrupt):
        new, code = KukaidError(f"interrupted; {where}"), 130
    elif isinstance(e, OSError):
        at = f"{e.filename}: " if getattr(e, "filename", None) else ""
        new, code = KukaidError(f"{at}{e.strerror or e}; {where}"), 1
    elif isinstance(e, Exception) and not os.environ.get("KUKAID_DEBUG"):
        new, code = KukaidError(f"internal error ({type(e).__name__}: {e}); {where}; rerun with KUKAID_DEBUG=1 "
                                "for a traceback"), EXIT_INTERNAL
    else:
        return e
    new.exit_code = code
    return new


class RunRecorder:
    """Records one run of the admittance loop to ``output`` (and its PDF to ``report``) safely.

    Parameters
    ----------
    output : Path
        The run log to write (HDF5); recorded to :func:`partial_path` meanwhile.
    axis : int
        KUKA number of the axis the run moves (the log's axis).
    channels : tuple of str
        The loop's row fields streamed to the partial log (``q``, ``tau``, ``q_cmd``, ...).
    attrs : dict
        Attributes of the run log (backend, parameter file, simulator truth, ...).
    report : Path, optional
        A PDF written with the run (replaced only when the log is).
    force : bool
        Outputs that existed before the run may be replaced; without it an output that appears
        while the robot moves is not.

    Open it as a context manager: while it is open, Ctrl-C and SIGTERM are counted
    (:attr:`interrupts`), not raised; backends wrapped by :meth:`guard` stop at the next cycle.
    """

    def __init__(self, output: Path, *, axis: int, channels: tuple[str, ...], attrs: dict,
                 report: Path | None = None, force: bool = False) -> None:
        self.output, self.report = Path(output), (Path(report) if report is not None else None)
        self.partial = partial_path(self.output)
        self.axis, self.channels, self.attrs, self.force = axis, tuple(channels), dict(attrs), force
        self.interrupts = Interrupts()
        #: interrupts the run has answered (it stopped at one): any later one is new
        self.answered = 0
        self._writer: Any = None

    def __enter__(self) -> "RunRecorder":
        self.interrupts.__enter__()
        return self

    def __exit__(self, *exc: object) -> None:
        self.interrupts.__exit__(*exc)

    @property
    def n(self) -> int:
        """Samples recorded so far."""
        return self._writer.n if self._writer is not None else 0

    def guard(self, backend: Any, seen: int = 0) -> StopOnInterrupt:
        """``backend`` stopping at its next cycle once an interrupt newer than ``seen`` has come."""
        return StopOnInterrupt(backend, self.interrupts, seen)

    def _on_row(self, row: dict) -> None:
        if row["time"] > self._writer.last_time:  # a stop repeats the last measurement
            self._writer.append(row["time"], **{c: [row[c]] for c in self.channels})

    def record(self, run_fn: Callable[[Callable[[dict], None]], Any]) -> Any:
        """Run ``run_fn(on_row)`` (the loop, given ``on_row`` to stream each cycle's row) while its
        rows are recorded to the partial file; returns its run.

        A failure keeps what was recorded in the partial file and names it in one line (see
        :func:`kept`); a full disk stops recording and the robot, and the samples recorded replace
        the output as a stopped run's do.  A run that stopped in its first cycle records nothing:
        :class:`KukaidError` (exit status 130 when interrupted, else 3), no file left."""
        from kukaid.logs import AxisLogWriter

        self._writer = writer = AxisLogWriter(self.partial, axes=(self.axis,), channels=self.channels,
                                              attrs={**self.attrs, "source": "kukaid run-admittance (while running)",
                                                     "experiment": "admittance"})
        try:
            if self.interrupts.count:  # before the robot starts: it does not
                raise KeyboardInterrupt
            run = run_fn(self._on_row)
            self.answered = self.interrupts.count if run.status == INTERRUPTED else 0
        except DiskFullError as e:
            writer.close()
            if writer.n == 0 or not self.partial.exists():
                raise
            os.replace(self.partial, self.output)
            msg = str(e)
            if msg.startswith(f"{self.partial}: "):
                msg = f"{self.output}: {msg[len(str(self.partial)) + 2:]}"
            if self.report is not None:
                msg += "; no report made" + (f" ({self.report} is not changed)" if self.report.exists() else "")
            raise DiskFullError(msg) from None
        except BaseException as e:
            writer.close()
            err = kept(e, writer.n, self.partial, self.output)
            if err is e:
                raise
            raise err from e
        writer.close()
        if np.unique(run.data["time"]).size < 2:  # stopped in its first cycle: no log to write, nothing to keep
            self.partial.unlink(missing_ok=True)
            err = KukaidError(f"run-admittance: {run.status} in the first control cycle; nothing recorded"
                              + (f" ({self.output} is not changed)" if self.output.exists() else ""))
            err.exit_code = 130 if run.status == INTERRUPTED else 3
            raise err
        return run

    def finish(self, run: Any, *, metrics: Callable[[], None] | None = None,
               report: Callable[[Path], None] | None = None) -> None:
        """Write the run's whole record and put it (and the report) in place of the outputs.

        ``metrics()`` first completes ``run.metrics``; the record is written over the partial file
        (atomic: the streamed log until it is written); ``report(path)`` then draws the PDF to a
        temporary file beside the report.  The log replaces the output only when all of this has
        worked, and the PDF replaces the report after it; a failure leaves both outputs as they
        were and keeps the partial file (:func:`kept`)."""
        import tempfile

        from kukaid.control import runlog

        pdf_tmp: Path | None = None
        try:
            if metrics is not None:
                metrics()
            runlog.write_run(self.partial, run, axis=self.axis, attrs=self.attrs)
            if self.report is not None and report is not None:
                fd, name = tempfile.mkstemp(prefix=f".{self.report.name}.", suffix=".tmp", dir=self.report.parent)
                os.close(fd)
                pdf_tmp = Path(name)
                report(pdf_tmp)
            if not self.force:  # refused before the run; someone may have made one meanwhile
                for p in (self.output, self.report):
                    if p is not None and p.exists():
                        raise KukaidError(f"{p}: appeared while the robot moved; not replaced")
            os.replace(self.partial, self.output)
        except BaseException as e:
            if pdf_tmp is not None:
                pdf_tmp.unlink(missing_ok=True)
            err = kept(e, self.n, self.partial, self.output)
            if err is e:
                raise
            raise err from e
        if pdf_tmp is not None:
            try:
                os.replace(pdf_tmp, self.report)
            except OSError as e:
                pdf_tmp.unlink(missing_ok=True)
                raise KukaidError(f"{self.report}: cannot write: {e.strerror or e}; the run log {self.output} is "
                                  "complete") from None

    def comparison(self, run: Any, cfg: Any, run_fn: Callable[[Any, int], Any], notes: list[str]) -> Any | None:
        """The report's other controller on the same simulated person: ``run_fn(cfg2, seen)`` runs
        it (a backend guarded with ``seen``) with ``cfg2`` the other damping; returns
        ``(other, run2, cut)`` (``cut``: how it was cut short, or "") or None when there is nothing to compare.

        After an interrupt it is cut where the run stopped (a Ctrl-C asks for an end, not for
        another run of the full length); an interrupt newer than the answered ones skips it, or
        stops it while it runs.  What was cut or left out is said in ``notes`` and in
        ``run2.metrics["status"]``."""
        import dataclasses

        other = "adaptive" if cfg.damping == "constant" else "constant"
        cfg2 = dataclasses.replace(cfg, damping=other, rbf=None if other == "constant" else cfg.rbf)
        interrupted = run.status == INTERRUPTED
        if self.interrupts.count > self.answered:
            notes.append(f"the report has no comparison run ({other} damping): interrupted before it started")
            return None
        t_end = float(run.data["time"][-1]) if run.data["time"].size else 0.0
        if interrupted:
            t_adm = (cfg.init_time if cfg.init_move else 0.0) + cfg.init_rest
            if t_end - t_adm < cfg.cycle:
                notes.append(f"the report has no comparison run ({other} damping): this run was interrupted at "
                             f"t = {t_end:.2f} s, before the admittance started")
                return None
            cfg2 = dataclasses.replace(cfg2, duration=t_end - t_adm)
        run2 = run_fn(cfg2, self.answered)
        cut = ""
        if not run2.status.startswith("completed"):
            t2 = float(run2.data["time"][-1]) if run2.data["time"].size else 0.0
            at = "" if " at t = " in run2.status else f" at t = {t2:.2f} s"  # a torque stop says when itself
            notes.append(f"the report's comparison run ({other} damping) {run2.status}{at}; the report shows it until "
                         "then")
            cut = run2.metrics["status"] = run2.status
        elif interrupted:
            notes.append(f"the report's comparison run ({other} damping) is cut at t = {t_end:.2f} s, where this run "
                         "was interrupted")
            cut = f"cut at t = {t_end:.2f} s"
            run2.metrics["status"] = f"cut at t = {t_end:.2f} s (the run was interrupted)"
        return other, run2, cut
