"""Drive tests with live servers, threads and child processes by samples, not by wall-clock time.

A test that sleeps a fixed time and then expects so many samples passes or fails with the speed
of the machine.  These helpers wait for a *condition* instead (samples on disk, simulated time
elapsed, a variable's value) and fire events after a number of requests; the wall-clock limits
they take are only there to end a test that hangs, far beyond any expected wait.
"""
from __future__ import annotations

import subprocess
import threading
import time
from pathlib import Path
from typing import Any, Callable

import pytest

HANG = 60.0  # s: only a test that hangs waits this long


def wait_until(cond: Callable[[], Any], what: str, limit: float = HANG, poll: float = 0.01) -> Any:
    """Poll ``cond()`` until it returns something true; fail the test after ``limit`` seconds."""
    t_end = time.monotonic() + limit
    while True:
        v = cond()
        if v:
            return v
        if time.monotonic() > t_end:
            pytest.fail(f"{what}: not reached within {limit:g} s")
        time.sleep(poll)


def wait_sim(src: Any, seconds: float) -> None:
    """Wait until the simulator behind ``src`` (a SimSource) has advanced ``seconds`` of its own time."""
    t = src.sim_time
    wait_until(lambda: src.sim_time >= t + seconds, f"{seconds} s of simulated time")


def wait_for_samples(out: Path, proc: subprocess.Popen, n_min: int, limit: float = HANG) -> int:
    """Wait until the log a child process writes holds ``n_min`` samples on disk; their number."""
    from kukaid.errors import KukaidError
    from kukaid.logs import read_hdf5

    def enough() -> int:
        if proc.poll() is not None:
            pytest.fail(f"the process ended early (exit {proc.returncode})")
        try:
            n = read_hdf5(out).n_samples if out.exists() else 0
        except KukaidError:  # being created, or no sample flushed yet
            return 0
        return n if n >= n_min else 0

    return wait_until(enough, f"{n_min} samples in {out.name}", limit, poll=0.05)


class CountingSource:
    """A KUKAVARPROXY variable source that counts the reads of one variable and runs actions at
    given counts: a capture polls ``$AXIS_ACT_MEAS`` once a sample (``KID_WR`` once a ring poll),
    so a test can drop the link after sample 60 and stop after 60 more, at any speed."""

    def __init__(self, source: Any, name: str = "$AXIS_ACT_MEAS", step: Callable[[], None] | None = None) -> None:
        """``step``: called at every counted read before it is served (a SimSource that is not
        started, stepped one sample per poll: ``lambda: src.step(0.012)``)."""
        self.source = source
        self.name = name.upper()
        self.step = step
        self.n = 0
        self.times: list[float] = []  # time.monotonic() of every counted read
        self._actions: dict[int, Callable[[], None]] = {}
        self._lock = threading.Lock()

    def at(self, n: int, action: Callable[[], None]) -> "CountingSource":
        """Run ``action`` during the ``n``-th read (counting from the start)."""
        self._actions[n] = action
        return self

    def read(self, name: str) -> str | None:
        if name.upper() == self.name:
            with self._lock:
                self.n += 1
                self.times.append(time.monotonic())
                action = self._actions.pop(self.n, None)
            if self.step is not None:
                self.step()
            if action is not None:
                action()
        return self.source.read(name)

    def write(self, name: str, value: str) -> bool:
        return self.source.write(name, value)
