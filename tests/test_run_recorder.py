"""The run recorder (kukaid.control.recorder), the library object behind `kukaid run-admittance`'s
outputs (issue 25, 6): a program that runs the loop itself records its runs as the command does."""
from __future__ import annotations

import pytest

from kukaid.control.recorder import RunRecorder, check_no_partial, partial_path
from kukaid.errors import KukaidError


def _rows(on_row, n):
    for i in range(n):
        on_row({"time": 0.012 * i, "q": 0.1 * i, "tau": 1.0, "q_cmd": 0.1 * i})


def test_a_failing_run_keeps_its_rows_in_the_partial_file_and_names_it(tmp_path):
    from kukaid.logs import read_hdf5

    out = tmp_path / "run.h5"
    assert partial_path(out) == tmp_path / "run.partial.h5"

    def run_fn(on_row):
        _rows(on_row, 50)
        raise RuntimeError("boom")

    with RunRecorder(out, axis=3, channels=("q", "tau", "q_cmd"), attrs={"backend": "test"}) as rec:
        with pytest.raises(KukaidError) as e:
            rec.record(run_fn)
    assert str(e.value).startswith("internal error (RuntimeError: boom); the 50 samples recorded are kept in "
                                   f"{partial_path(out)} ({out} is not changed)")
    assert e.value.exit_code == 70 and not out.exists()  # an internal error
    assert read_hdf5(partial_path(out)).n_samples == 50
    with pytest.raises(KukaidError, match="the record of an earlier run that did not finish is in the way"):
        check_no_partial(out)


def test_the_signals_are_counted_while_open_and_given_back(tmp_path):
    import os
    import signal

    before = signal.getsignal(signal.SIGTERM)
    with RunRecorder(tmp_path / "r.h5", axis=3, channels=("q",), attrs={}) as rec:
        os.kill(os.getpid(), signal.SIGTERM)
        assert rec.interrupts.count == 1

        class Backend:
            def cycle(self, q, dt):
                return "moved"

        with pytest.raises(KeyboardInterrupt):  # the loop's to handle: it holds the robot
            rec.guard(Backend()).cycle(0.0, 0.012)
        assert rec.guard(Backend(), seen=1).cycle(0.0, 0.012) == "moved"
    assert signal.getsignal(signal.SIGTERM) == before


def test_a_comparison_run_that_stopped_on_the_torque_limit_says_when_once(tmp_path):
    """A torque stop's status says when ("... at t = 3.672 s"); the note added " at t = 3.67 s" again."""
    from types import SimpleNamespace

    import numpy as np

    from kukaid.control.loop import LoopConfig

    stop = ("stopped: external torque Γr 101.2 N·m (the model's torque minus the measured -82.3 N·m) beyond the limit "
            "100 N·m at t = 3.672 s")
    run = SimpleNamespace(status="completed", data={"time": np.arange(0.0, 5.0, 0.012)}, metrics={})
    other = SimpleNamespace(status=stop, data={"time": np.arange(0.0, 3.68, 0.012)}, metrics={})
    notes: list[str] = []
    with RunRecorder(tmp_path / "r.h5", axis=3, channels=("q",), attrs={}) as rec:
        rec.comparison(run, LoopConfig(damping="constant"), lambda cfg, seen: other, notes)
    assert notes == [f"the report's comparison run (adaptive damping) {stop}; the report shows it until then"]
