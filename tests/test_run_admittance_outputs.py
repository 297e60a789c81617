"""`kukaid run-admittance`: what happens to its outputs when a run fails, is interrupted or is
given a parameter file of another axis.

* the run is recorded to ``NAME.partial.h5`` while the robot moves; the output (and the PDF) are
  replaced only when the run has ended: a failed --force run leaves the old log as it was and
  keeps what it recorded under the partial name, which the error line names;
* Ctrl-C / SIGTERM wherever it lands stops the run through the loop (exit 3, the control group
  kept); the report's comparison run is cut where the run was interrupted;
* a parameter file of a prismatic axis, or of another axis, is refused before anything moves.
"""
from __future__ import annotations

import json
import os
import signal
import shutil
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from kukaid.control.runlog import read_run
from kukaid.params import save_params
from kukaid.sim import SimConfig
from kukaid_cli.main import cli
from shared_data import SHARED

EMPS = SHARED / "datasets" / "emps" / "DATA_EMPS.mat"


@pytest.fixture(scope="module")
def params(tmp_path_factory):
    d = tmp_path_factory.mktemp("adm_out")
    save_params(d / "params.json", SimConfig().truth_params())
    return d / "params.json"


@pytest.fixture(scope="module")
def old_run(params, tmp_path_factory):
    """A finished run (log and PDF): what --force may replace, and must not lose otherwise."""
    d = tmp_path_factory.mktemp("adm_old")
    r = _run(["--params", params, "--duration", "1", "--operator", "push", "-o", d / "old.h5",
              "--report", d / "old.pdf"])
    assert r.exit_code == 0, r.output
    return d / "old.h5", d / "old.pdf"


def _run(args):
    return CliRunner().invoke(cli, ["run-admittance", *map(str, args)])


def _one_line(r, code):
    assert r.exit_code == code, r.output
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("kukaid: error: ") and "Traceback" not in r.output, r.output
    return lines[0]


def _copy_old(old_run, tmp_path):
    keep, pdf = tmp_path / "keep.h5", tmp_path / "keep.pdf"
    shutil.copy(old_run[0], keep)
    shutil.copy(old_run[1], pdf)
    return keep, pdf, keep.read_bytes(), pdf.read_bytes()


def _fail_at(monkeypatch, n, check=lambda: None):
    """The estimator fails (a bug) at its ``n``-th sample; ``check()`` runs at sample n // 2."""
    from kukaid.control.torque_residual import TorqueResidual

    real, calls = TorqueResidual.update, [0]

    def update(self, *a, **k):
        calls[0] += 1
        if calls[0] == n // 2:
            check()
        if calls[0] >= n:
            raise RuntimeError("boom")
        return real(self, *a, **k)

    monkeypatch.setattr(TorqueResidual, "update", update)


def test_a_failed_force_run_leaves_the_old_log_and_keeps_what_it_recorded(params, old_run, tmp_path, monkeypatch):
    """`cp radm1.h5 keep.h5; kukaid run-admittance ... -o keep.h5 --force` that crashes: keep.h5 was
    truncated when the run started and deleted or overwritten when it failed."""
    from kukaid.logs import read_hdf5

    keep, pdf, before, pdf_before = _copy_old(old_run, tmp_path)
    partial = tmp_path / "keep.partial.h5"
    seen = []
    _fail_at(monkeypatch, 400, lambda: seen.append((keep.read_bytes() == before, partial.exists())))
    r = _run(["--params", params, "--duration", "5", "-o", keep, "--report", pdf, "--force"])
    line = _one_line(r, 70)  # an internal error
    assert "internal error (RuntimeError: boom)" in line and str(partial) in line and "KUKAID_DEBUG" in line
    assert seen == [(True, True)]  # while the robot moved: the old log whole, the run recorded beside it
    assert keep.read_bytes() == before and pdf.read_bytes() == pdf_before
    log = read_hdf5(partial)  # the run up to the failure (a crashed run on a robot is worth keeping)
    assert 300 < log.n_samples < 400 and np.all(np.diff(log.time) > 0)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.h5", "keep.partial.h5", "keep.pdf"]
    # the partial record is never replaced by the next run: it is in the way until moved
    r = _run(["--params", params, "--duration", "1", "-o", keep, "--force"])
    line = _one_line(r, 1)
    assert str(partial) in line and "earlier run" in line
    assert keep.read_bytes() == before and read_hdf5(partial).n_samples == log.n_samples


def test_a_run_that_fails_before_recording_leaves_nothing_and_the_old_log(params, old_run, tmp_path, monkeypatch):
    keep, pdf, before, _ = _copy_old(old_run, tmp_path)
    _fail_at(monkeypatch, 1)  # the first measurement at start
    r = _run(["--params", params, "--duration", "5", "-o", keep, "--force"])
    line = _one_line(r, 70)  # an internal error
    assert "internal error (RuntimeError: boom)" in line and "partial" not in line
    assert keep.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.h5", "keep.pdf"]


def test_a_report_that_cannot_be_made_replaces_neither_output(params, old_run, tmp_path, monkeypatch):
    """All outputs or none: the PDF fails after the run, the old log and PDF stay, the new run's
    whole record (control group too) is kept under the partial name."""
    import kukaid.control.plots as plots

    keep, pdf, before, pdf_before = _copy_old(old_run, tmp_path)

    def plot_runs(runs, path, title=""):
        Path(path).write_bytes(b"%PDF-half")
        raise RuntimeError("no fonts")

    monkeypatch.setattr(plots, "plot_runs", plot_runs)
    r = _run(["--params", params, "--duration", "1", "--operator", "push", "-o", keep, "--report", pdf, "--force"])
    line = _one_line(r, 70)  # an internal error
    partial = tmp_path / "keep.partial.h5"
    assert "no fonts" in line and str(partial) in line
    assert keep.read_bytes() == before and pdf.read_bytes() == pdf_before
    _, control, metrics = read_run(partial)
    assert metrics["status"] == "completed" and control["gamma_r"].size > 100
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.h5", "keep.partial.h5", "keep.pdf"]


def test_a_force_run_replaces_both_outputs_when_it_has_ended(params, old_run, tmp_path):
    keep, pdf, before, pdf_before = _copy_old(old_run, tmp_path)
    r = _run(["--params", params, "--duration", "2", "--operator", "push", "-o", keep, "--report", pdf, "--force"])
    assert r.exit_code == 0, r.output
    assert keep.read_bytes() != before and pdf.read_bytes() != pdf_before and pdf.read_bytes()[:5] == b"%PDF-"
    assert read_run(keep)[2]["status"] == "completed"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.h5", "keep.pdf"]


def _signal_at(monkeypatch, target, name, n, sig, more=()):
    """Send ``sig`` to this process at the ``n``-th call of ``target.name`` (and at each of ``more``)."""
    real, calls = getattr(target, name), [0]

    def wrapped(self, *a, **k):
        calls[0] += 1
        if calls[0] == n or calls[0] in more:
            os.kill(os.getpid(), sig)
        return real(self, *a, **k)

    monkeypatch.setattr(target, name, wrapped)
    return calls


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_an_interrupt_between_cycles_stops_the_run_and_keeps_the_control_group(params, old_run, tmp_path,
                                                                                monkeypatch, sig):
    """Ctrl-C or SIGTERM while the estimator runs (between two backend cycles): before, exit 130
    and no control group; now the loop stops the run (exit 3) and the log is whole.  A stopped
    run is a valid record: it replaces the old log, as --force asked."""
    from kukaid.control.torque_residual import TorqueResidual

    keep, _, before, _ = _copy_old(old_run, tmp_path)
    _signal_at(monkeypatch, TorqueResidual, "update", 250, sig)
    handlers = signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)  # SIGINT is ignored in a background job
    r = _run(["--params", params, "--duration", "30", "--operator", "push", "-o", keep, "--force"])
    assert r.exit_code == 3, r.output
    assert r.stderr.strip().splitlines() == [f"kukaid: error: run-admittance: stopped: interrupted (the run log {keep} "
                                             "holds every cycle until then)"]
    log, control, metrics = read_run(keep)
    assert metrics["status"] == "stopped: interrupted" and control["phase"][-1] == 3  # the log says it stopped
    assert control["gamma_r"].size == log.n_samples and 200 < log.n_samples < 260
    assert not (tmp_path / "keep.partial.h5").exists()
    assert (signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)) == handlers  # given back


def test_an_interrupt_in_the_first_cycle_records_nothing_and_blocks_nothing(params, tmp_path, monkeypatch):
    """Ctrl-C while the estimator takes its first samples: the run stops in its first cycle, which is
    no log (one sample); no partial file is left to stand in the way of the next run."""
    from kukaid.control.torque_residual import TorqueResidual

    _signal_at(monkeypatch, TorqueResidual, "update", 1, signal.SIGINT)
    out = tmp_path / "early.h5"
    r = _run(["--params", params, "--duration", "30", "--operator", "push", "-o", out])
    assert r.exit_code == 130, r.output
    assert r.stderr.strip().splitlines() == ["kukaid: error: run-admittance: stopped: interrupted in the first control "
                                             "cycle; nothing recorded"]
    assert list(tmp_path.iterdir()) == []


def test_an_interrupt_cuts_the_reports_comparison_run(params, tmp_path, monkeypatch):
    """`--report` after Ctrl-C: the comparison run ends where the interrupted run did (it ran the
    whole --duration before), the PDF is made, a line says so, exit 3."""
    import kukaid.control.plots as plots
    from kukaid.robot import SimRobot

    real_plot, drawn = plots.plot_runs, []
    monkeypatch.setattr(plots, "plot_runs", lambda runs, path, title="": (drawn.append(runs),
                                                                          real_plot(runs, path, title)))
    _signal_at(monkeypatch, SimRobot, "cycle", 300, signal.SIGINT)  # inside a cycle, 2.4 s after the start
    out, pdf = tmp_path / "sig.h5", tmp_path / "sig.pdf"
    r = _run(["--params", params, "--duration", "60", "-o", out, "--report", pdf])
    assert r.exit_code == 3, r.output
    assert "stopped: interrupted" in r.stderr
    assert "the report's comparison run (adaptive damping) is cut at t = " in r.stdout
    assert pdf.read_bytes()[:5] == b"%PDF-" and read_run(out)[1]["gamma_r"].size > 0
    (runs,) = drawn
    t1, t2 = (max(d["time"]) for _, d, _ in runs)
    assert t1 == pytest.approx(3.6, abs=0.05) and t2 == pytest.approx(t1, abs=0.05)


def test_an_interrupt_during_the_comparison_run_stops_it(params, tmp_path, monkeypatch):
    """The run completed; Ctrl-C while the report's comparison runs stops that run, the PDF shows it
    until then, and the command says it was interrupted (exit 3)."""
    import kukaid.control.plots as plots
    from kukaid.robot import SimRobot

    real_plot, drawn = plots.plot_runs, []
    monkeypatch.setattr(plots, "plot_runs", lambda runs, path, title="": (drawn.append(runs),
                                                                          real_plot(runs, path, title)))
    n1 = round((0.6 + 0.6 + 2.0) / 0.012)  # cycles of the run itself
    _signal_at(monkeypatch, SimRobot, "cycle", n1 + 100, signal.SIGINT)
    out, pdf = tmp_path / "c.h5", tmp_path / "c.pdf"
    r = _run(["--params", params, "--duration", "2", "-o", out, "--report", pdf, "--damping", "adaptive"])
    assert r.exit_code == 3, r.output
    assert "interrupted after the run had completed" in r.stderr
    assert "comparison run (constant damping) stopped: interrupted at t = " in r.stdout
    assert read_run(out)[2]["status"] == "completed" and pdf.read_bytes()[:5] == b"%PDF-"
    (runs,) = drawn
    t = {lbl.split()[0]: max(d["time"]) for lbl, d, _ in runs}
    assert t["adaptive"] == pytest.approx(3.2, abs=0.05) and 1.0 < t["constant"] < 1.3


def _other_axis(params, tmp_path, **edit):
    p = json.loads(params.read_text())
    p.update({k: v for k, v in edit.items() if k != "joint"})
    if "joint" in edit:
        p["provenance"] = {"joint": edit["joint"]}
    (tmp_path / "other.json").write_text(json.dumps(p))
    return tmp_path / "other.json"


@pytest.mark.parametrize("edit, backend, code, pieces", [
    (dict(axis=1, joint="prismatic"), "sim", 1, ["a prismatic axis (A1, positions in m, forces in N)",
                                                "the virtual KR C4's A3"]),
    (dict(axis=2), "sim", 1, ["a model of A2 cannot drive the virtual KR C4's A3", "(--axis 2 simulates that axis)"]),
    (dict(axis=3, joint="prismatic"), "kvp", 1, ["a prismatic axis", "A3 of the KR C4"]),
    (dict(axis=2), "kvp", 2, ["a model of A2 cannot drive A3 of the KR C4 (--axis 3)", "pass --axis 2"]),
])
def test_a_parameter_file_of_another_axis_is_refused(params, tmp_path, edit, backend, code, pieces):
    """A prismatic EMPS model ran against the revolute virtual A3: 64 false detections and a
    torque-limit stop.  Refused before anything moves (kvp: nothing listens on port 9)."""
    bad = _other_axis(params, tmp_path, **edit)
    kvp = ["--backend", "kvp", "--port", "9", "--enable-motion", "--q-min", "0", "--q-max", "40"]
    r = _run(["--params", bad, "-o", tmp_path / "r.h5", *(kvp if backend == "kvp" else [])])
    line = _one_line(r, code)
    assert line.startswith(f"kukaid: error: {bad}: ") and all(p in line for p in pieces), line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["other.json"]


def test_a_model_of_another_axis_runs_on_that_simulated_axis(params, tmp_path):
    bad = _other_axis(params, tmp_path, axis=2, joint="revolute")
    (tmp_path / "a2.json").write_text('{"axis": 2}')
    r = _run(["--params", bad, "--sim-config", tmp_path / "a2.json", "--duration", "1", "-o", tmp_path / "r.h5"])
    assert r.exit_code == 0, r.output
    assert read_run(tmp_path / "r.h5")[0].axes == (2,)


def test_axis_names_the_simulated_axis_of_a_one_axis_file(params, tmp_path):
    """New-user trial 14: a file fitted on A2 (excite/capture --axis 2 simulate A2) was refused with --axis 2, "the
    virtual KR C4 simulates A3 (a --sim-config's "axis" sets another)": --axis now names the simulated axis, as the
    trajectory's axis does for capture; another axis than the file's is still refused, and so is an external one."""
    a2 = _other_axis(params, tmp_path, axis=2, joint="revolute")
    r = _run(["--params", a2, "--axis", "2", "--duration", "1", "-o", tmp_path / "r.h5"])
    assert r.exit_code == 0, r.output
    log = read_run(tmp_path / "r.h5")[0]
    assert log.axes == (2,) and log.attrs["truth"]["axis"] == 2
    # and starts mid-range: the default 30 degrees is 15 from A2's upper end, and a person guiding 0.2-0.5 rad
    # from there left the window (199 clipped cycles)
    assert np.degrees(log.q[0, 0]) == pytest.approx(-72.5, abs=0.1)
    assert "the parameters are of axis A2, not A1" in _one_line(
        _run(["--params", a2, "--axis", "1", "--duration", "1", "-o", tmp_path / "r1.h5"]), 2)
    par = json.loads(params.read_text())
    par.pop("axis", None)
    (tmp_path / "any.json").write_text(json.dumps(par))
    assert "the virtual KR C4 has axes 1 to 6" in _one_line(
        _run(["--params", tmp_path / "any.json", "--axis", "8", "--duration", "1", "-o", tmp_path / "r8.h5"]), 2)
    assert not (tmp_path / "r1.h5").exists() and not (tmp_path / "r8.h5").exists()


def test_the_emps_drive_is_not_the_virtual_a3(tmp_path):
    if not EMPS.exists():
        pytest.skip("../shared/datasets/emps is not present")
    from kukaid.identify import fit_axis
    from kukaid.logs import read_mat

    log = read_mat(EMPS, time="t", q="qm", tau="vir", tau_scale_var="gtau", joint="prismatic", q_cmd="qg")
    (tmp_path / "emps.json").write_text(json.dumps(fit_axis(logs=[log], friction_model="coulomb-viscous",
                                                            gravity="none", offset=True)))
    r = _run(["--params", tmp_path / "emps.json", "-o", tmp_path / "e.h5"])
    assert "prismatic axis (A1" in _one_line(r, 1)
    assert not (tmp_path / "e.h5").exists()


def test_a_second_interrupt_before_the_comparison_run_skips_it(params, tmp_path, monkeypatch):
    """Ctrl-C twice: the run stops at the first, the second (while the log is written) skips the
    report's comparison run; the log and a PDF of the run alone are still written."""
    import kukaid.control.plots as plots
    import kukaid.control.runlog as runlog
    from kukaid.robot import SimRobot

    real_plot, drawn = plots.plot_runs, []
    monkeypatch.setattr(plots, "plot_runs", lambda runs, path, title="": (drawn.append(runs),
                                                                          real_plot(runs, path, title)))
    real_write = runlog.write_run

    def write_run(*a, **k):
        os.kill(os.getpid(), signal.SIGINT)
        return real_write(*a, **k)

    monkeypatch.setattr(runlog, "write_run", write_run)
    _signal_at(monkeypatch, SimRobot, "cycle", 300, signal.SIGINT)
    out, pdf = tmp_path / "two.h5", tmp_path / "two.pdf"
    r = _run(["--params", params, "--duration", "60", "-o", out, "--report", pdf])
    assert r.exit_code == 3, r.output
    assert "the report has no comparison run (adaptive damping): interrupted before it started" in r.stdout
    assert read_run(out)[2]["status"] == "stopped: interrupted" and pdf.read_bytes()[:5] == b"%PDF-"
    assert [len(runs) for runs in drawn] == [1]
