"""`kukaid capture` on the virtual KR C4: end to end, incremental writing, interruption, --force."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from kukaid.capture import SimCapture, capture, load_kvp_capture, parse_effect, sim_config
from kukaid.errors import KukaidError
from kukaid.excite import Trajectory, friction
from kukaid.logs import read_hdf5
from kukaid_cli.main import cli
from live_helpers import wait_for_samples


def run(*args):
    r = CliRunner().invoke(cli, [str(a) for a in args])
    return r.exit_code, r.output


@pytest.fixture(scope="module")
def short_traj(tmp_path_factory) -> Path:
    tr = friction(speeds=[0.05, 0.3], plateau=1.5, settle=0.5, span=0.4)
    p = tmp_path_factory.mktemp("traj") / "short.json"
    tr.to_json(p)
    return p


def test_capture_end_to_end(short_traj, tmp_path):
    out = tmp_path / "log.h5"
    code, text = run("capture", short_traj, "-o", out, "--seed", 7)
    assert code == 0, text
    log = read_hdf5(out)
    tr = Trajectory.from_json(short_traj)
    assert log.axes == (3,)
    assert log.sample_time == pytest.approx(0.012)
    assert log.duration == pytest.approx(tr.duration + 0.5, abs=0.03)
    for ch in ("q_cmd", "temp", "tau_ext_true"):
        assert log.has(ch)
    a = log.attrs
    assert a["experiment"] == "friction" and a["seed"] == 7 and a["backend"] == "sim"
    assert a["trajectory"]["speeds"] == [0.05, 0.3]
    assert a["truth"]["schema"] == "kukaid.params/1" and "friction" in a["truth"]
    assert a["kukaid_version"] and a["source"] == "virtual-krc4"
    # the axis follows the command
    assert np.max(np.abs(log.channel("q", 3) - log.channel("q_cmd", 3))) < 0.01
    # the commanded schedule is the trajectory
    assert np.allclose(np.interp(log.time - log.time[0] + 0.012, tr.t, tr.q), log.channel("q_cmd", 3), atol=2e-3)


def test_chunked_capture_equals_one_simulator_run(short_traj, tmp_path):
    from kukaid.sim import SimConfig, VirtualKRC4

    tr = Trajectory.from_json(short_traj)
    out = tmp_path / "log.h5"
    capture(SimCapture(tr, seed=3, chunk=0.7), out)
    log = read_hdf5(out)
    sim = VirtualKRC4(SimConfig(), seed=3, axis=3)
    ref = sim.run(tr, settle=0.5)
    assert log.n_samples == ref.n_samples
    for ch in ("time", "q", "tau", "q_cmd", "temp", "tau_ext_true"):
        assert np.array_equal(getattr(log, ch), getattr(ref, ch)), ch


def test_same_seed_same_log_and_other_seed_differs(short_traj, tmp_path):
    logs = []
    for i, seed in enumerate((5, 5, 6)):
        out = tmp_path / f"l{i}.h5"
        assert run("capture", short_traj, "-o", out, "--seed", seed)[0] == 0
        logs.append(read_hdf5(out))
    assert np.array_equal(logs[0].tau, logs[1].tau)
    assert not np.array_equal(logs[0].tau, logs[2].tau)


def test_force_protects_an_existing_log(short_traj, tmp_path):
    out = tmp_path / "log.h5"
    out.write_bytes(b"precious")
    code, text = run("capture", short_traj, "-o", out)
    assert code != 0 and "already exists" in text and "--force" in text
    assert out.read_bytes() == b"precious"
    code, text = run("capture", short_traj, "-o", out, "--force")
    assert code == 0, text
    assert read_hdf5(out).n_samples > 100


def test_noise_and_effects_reach_the_simulator(short_traj, tmp_path):
    out = tmp_path / "log.h5"
    code, text = run("capture", short_traj, "-o", out, "--noise", "0.2", "--effect", "torque_offset=2.5",
                     "--effect", "gravity_sine", "--seed", 4)
    assert code == 0, text
    a = read_hdf5(out).attrs
    assert a["sim_config"]["noise_sigma"] == 0.2
    eff = a["truth"]["effects"]
    assert abs(eff["torque_offset"]["offset"]) == pytest.approx(2.5)
    drawn = abs(eff["gravity_sine"]["My"])
    assert 2 * 0.2 <= drawn <= 5 * 0.2  # size drawn from 2 to 5 noise sigmas
    assert a["effects_requested"] == [{"name": "torque_offset", "size": 2.5}, {"name": "gravity_sine", "size": drawn}]
    # the effect parameters are seeded
    c1, _ = sim_config(effects=[("position_ripple", 1.0)], seed=4)
    c2, _ = sim_config(effects=[("position_ripple", 1.0)], seed=4)
    assert c1.effects == c2.effects


def test_sim_config_file(short_traj, tmp_path):
    cfg = tmp_path / "truth.json"
    cfg.write_text(json.dumps({"Fc": 12.0, "noise_sigma": 0.1}))
    out = tmp_path / "log.h5"
    code, text = run("capture", short_traj, "-o", out, "--sim-config", cfg)
    assert code == 0, text
    assert read_hdf5(out).attrs["truth"]["friction"]["Fc"] == 12.0


def test_a_sim_config_of_another_axis_than_the_trajectorys_is_refused(short_traj, tmp_path):
    """New-user trial 10: a --sim-config saying "axis": 2 captured the A3 trajectory as A3 without a word
    (run-admittance simulates the config's axis); the file's own axis, or none, is taken as before."""
    for said, code in ((2, 1), (3, 0)):
        cfg = tmp_path / f"a{said}.json"
        cfg.write_text(json.dumps({"axis": said}))
        out = tmp_path / f"log{said}.h5"
        got, text = run("capture", short_traj, "-o", out, "--sim-config", cfg)
        assert got == code, text
        assert out.exists() == (code == 0)
    got, text = run("capture", short_traj, "-o", tmp_path / "x.h5", "--sim-config", tmp_path / "a2.json")
    assert text.startswith("kukaid: error: ") and f'a2.json: "axis": 2, but {short_traj} moves A3' in text
    assert "--axis 2" in text and text.count("\n") == 1
    # new-user trial 16: an external axis named the fix "excite the trajectory with --axis 9", which excite refuses
    (tmp_path / "a9.json").write_text(json.dumps({"axis": 9}))
    got, text = run("capture", short_traj, "-o", tmp_path / "x.h5", "--sim-config", tmp_path / "a9.json")
    assert got == 1 and '"axis": 9 is the external axis E3' in text and f'leave "axis" out: {short_traj} moves A3' in text
    assert "--axis 9" not in text and text.count("\n") == 1


@pytest.mark.parametrize("args, message", [
    (["--effect", "gremlins"], "unknown effect 'gremlins'"),
    (["--effect", "backlash=big"], "size 'big' is not a number"),
    (["--noise", "-1"], "-1.0 N·m is not a torque noise sigma"),
    (["--host", "10.0.0.1"], "--host is for --backend kvp"),
    (["-o", "log.csv"], "name it .h5 or .hdf5"),
])
def test_bad_capture_options(short_traj, tmp_path, args, message, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, text = run("capture", short_traj, "-o", "log.h5", *args)
    assert code != 0 and message in text
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("content, message", [
    ("not json", "not valid JSON (line 1, column 1"),
    ('{"schema": "kukaid.trajectory/1", "t": [0, 0.012], "q": [0]}', "'t' has 2 samples but 'q' has 1"),
    ('{"schema": "kukaid.trajectory/1", "t": [0, 0.012, 0.024], "q": [0, NaN, 0]}', "'q' is not a finite number at index 1"),
])
def test_bad_trajectory_file_gives_one_line_error_and_no_log(tmp_path, content, message):
    bad = tmp_path / "bad.json"
    bad.write_text(content)
    out = tmp_path / "log.h5"
    code, text = run("capture", bad, "-o", out)
    assert code != 0
    lines = [ln for ln in text.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith(f"kukaid: error: {bad}: ") and message in lines[0]
    assert not out.exists()


def test_capture_refuses_a_trajectory_breaking_its_limits(tmp_path):
    t = np.arange(0, 2.0, 0.012)
    p = tmp_path / "fast.json"
    Trajectory(t=t, q=0.3 + 0.5 * np.sin(2 * np.pi * t / 0.5)).to_json(p)  # 79 rad/s² peak
    out = tmp_path / "log.h5"
    code, text = run("capture", p, "-o", out)
    assert code != 0 and f"kukaid: error: {p}: trajectory breaks the acceleration limit of A3" in text
    assert not out.exists()


def test_kvp_backend_needs_duration_and_reports_a_missing_module(monkeypatch, tmp_path):
    code, text = run("capture", "-o", tmp_path / "k.h5", "--backend", "kvp")
    assert code != 0 and "--duration S or --until-interrupt" in text
    code, text = run("capture", "-o", tmp_path / "k.h5", "--backend", "kvp", "--duration", "1", "--seed", "1",
                     "--effect", "backlash")
    assert code != 0 and "--effect is for --backend sim" in text
    monkeypatch.setitem(sys.modules, "kukaid.krc.kvp_capture", None)
    with pytest.raises(KukaidError, match="kvp backend is not available"):
        load_kvp_capture()
    code, text = run("capture", "-o", tmp_path / "k.h5", "--backend", "kvp", "--duration", "1")
    assert code != 0 and "kvp backend is not available" in text
    assert not (tmp_path / "k.h5").exists()


def test_stop_event_ends_the_capture_cleanly(short_traj, tmp_path):
    import threading

    tr = Trajectory.from_json(short_traj)
    stop = threading.Event()
    seen = []

    def progress(done):
        seen.append(done)
        if len(seen) == 3:
            stop.set()

    out = tmp_path / "stopped.h5"
    res = capture(SimCapture(tr, seed=2, chunk=1.0), out, progress=progress, stop=stop)
    assert not res.complete and seen == [1.0, 2.0, 3.0]
    log = read_hdf5(out)
    assert log.n_samples == res.n_samples and log.time[-1] == pytest.approx(3.0, abs=0.013)


def test_parse_effect():
    assert parse_effect("backlash") == ("backlash", None)
    assert parse_effect("thermal_drift=0.8") == ("thermal_drift", 0.8)


# -- interrupted capture (a subprocess killed mid-way) -------------------------------------------
@pytest.fixture(scope="module")
def long_traj(tmp_path_factory) -> Path:
    t = np.arange(0, 400.0, 0.012)
    q = 0.3 + 0.4 * np.sin(2 * np.pi * t / 5.0) * np.minimum(1.0, t / 5.0)
    p = tmp_path_factory.mktemp("long") / "long.json"
    Trajectory(t=t, q=q, kind="validation", params={"note": "long test trajectory"}).to_json(p)
    return p


def _start_capture(traj: Path, out: Path) -> subprocess.Popen:
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    return subprocess.Popen([sys.executable, "-m", "kukaid_cli.main", "capture", str(traj), "-o", str(out),
                             "--chunk", "1.0", "--seed", "11"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)


def _check_prefix(out: Path, traj: Path) -> int:
    """The kept log is readable, strictly increasing, and equals the start of an uninterrupted run."""
    from kukaid.sim import SimConfig, VirtualKRC4

    log = read_hdf5(out)
    n = log.n_samples
    assert n >= 200
    assert np.all(np.diff(log.time) > 0)
    assert log.attrs["experiment"] == "validation" and log.attrs["seed"] == 11
    tr = Trajectory.from_json(traj)
    sim = VirtualKRC4(SimConfig(), seed=11, axis=3)
    sim.reset(tr.q[0])
    sim.follow(tr)
    ref = sim.advance(log.time[-1] + 0.006)
    assert ref["time"].size == n
    assert np.array_equal(ref["tau"], log.channel("tau", 3))
    assert np.array_equal(ref["q"], log.channel("q", 3))
    return n


def test_killed_capture_leaves_a_readable_log(long_traj, tmp_path):
    out = tmp_path / "killed.h5"
    proc = _start_capture(long_traj, out)
    wait_for_samples(out, proc, 300)
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)
    assert proc.returncode == -signal.SIGKILL
    _check_prefix(out, long_traj)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_interrupted_capture_keeps_data_and_says_so(long_traj, tmp_path, sig):
    out = tmp_path / "interrupted.h5"
    proc = _start_capture(long_traj, out)
    wait_for_samples(out, proc, 300)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=30)
    err = err.decode()
    assert proc.returncode == 130, err
    assert "capture interrupted" in err and "kept in" in err and "Traceback" not in err
    n = _check_prefix(out, long_traj)
    assert f"{n} samples" in err


@pytest.mark.parametrize("option", [["--seed", "5"], ["--chunk", "5"], ["--settle", "2"]])
def test_kvp_capture_refuses_a_simulator_option(tmp_path, option):
    """The robot runs its own program: a seed, block length or settle time of the simulator does
    nothing there, and was taken without a word (as --noise and --effect are not)."""
    out = tmp_path / "k.h5"
    code, text = run("capture", "-o", out, "--backend", "kvp", "--port", "1", "--duration", "1", *option)
    lines = [ln for ln in text.splitlines() if ln.strip()]
    assert code == 2 and lines == [f"kukaid: error: capture: option {option[0]} is for --backend sim"], text
    assert not out.exists()


def test_a_capture_interrupted_before_its_first_sample_does_not_report_the_old_log(short_traj, tmp_path, monkeypatch):
    """`capture --force` over an earlier log, Ctrl-C before the first block: nothing was recorded and
    the old log is untouched, but the line read the old log and said 'capture interrupted after
    58.27 of 415.9 s; 4857 samples kept'."""
    import kukaid.capture
    from kukaid.capture import CaptureResult

    out = tmp_path / "old.h5"
    assert run("capture", short_traj, "-o", out, "--seed", "1")[0] == 0
    before = out.read_bytes()
    monkeypatch.setattr(kukaid.capture, "capture",
                        lambda be, output, **k: CaptureResult(output=output, n_samples=0, duration=0.0, complete=False))
    code, text = run("capture", short_traj, "-o", out, "--seed", "2", "--force")
    assert code == 130 and text.strip().splitlines() == [
        f"kukaid: error: capture interrupted before its first sample; nothing recorded ({out} is not changed)"], text
    assert out.read_bytes() == before


def _fail_cycle_at(monkeypatch, n, seen=None, out=None, before=None):
    """SimRobot.cycle raises a ControllerError at its n-th call (after n - 1 blocks were written)."""
    from kukaid.errors import ControllerError
    from kukaid.robot import SimRobot

    real, calls = SimRobot.cycle, [0]

    def cycle(self, *a, **k):
        calls[0] += 1
        if seen is not None and calls[0] == n - 1:  # while the capture runs: the old log whole, the new one beside
            seen.append((out.read_bytes() == before, out.with_name(f"{out.stem}.partial{out.suffix}").exists()))
        if calls[0] == n:
            raise ControllerError("the controller stopped answering")
        return real(self, *a, **k)

    monkeypatch.setattr(SimRobot, "cycle", cycle)


def test_a_forced_capture_that_fails_leaves_the_old_log_and_keeps_what_it_recorded(short_traj, tmp_path, monkeypatch):
    """`capture --force` over an earlier log truncated it at the first block: a capture that then
    failed (or was killed) lost the earlier log for a part of the new one.  It is now recorded
    beside it (NAME.partial.h5) and put in its place only when it has ended."""
    from kukaid.logs import read_hdf5

    out = tmp_path / "old.h5"
    assert run("capture", short_traj, "-o", out, "--seed", "1", "--chunk", "0.5")[0] == 0
    before = out.read_bytes()
    partial = tmp_path / "old.partial.h5"
    seen = []
    _fail_cycle_at(monkeypatch, 4, seen, out, before)
    code, text = run("capture", short_traj, "-o", out, "--seed", "2", "--chunk", "0.5", "--force")
    lines = text.strip().splitlines()
    assert code == 1 and len(lines) == 1, text
    assert lines[0] == (f"kukaid: error: the controller stopped answering; the samples recorded are kept in {partial} "
                        f"({out} is not changed)")
    assert seen == [(True, True)] and out.read_bytes() == before
    assert read_hdf5(partial).n_samples > 100
    # the partial record is never replaced: the next capture refuses while it is in the way
    monkeypatch.undo()
    code, text = run("capture", short_traj, "-o", out, "--seed", "2", "--force")
    assert code == 1 and f"{partial}: the record of an earlier capture that did not finish is in the way" in text
    assert out.read_bytes() == before


def test_a_forced_capture_replaces_the_old_log_when_it_has_ended(short_traj, tmp_path):
    from kukaid.logs import read_hdf5

    out = tmp_path / "old.h5"
    assert run("capture", short_traj, "-o", out, "--seed", "1")[0] == 0
    code, text = run("capture", short_traj, "-o", out, "--seed", "2", "--force")
    assert code == 0 and text.startswith(f"{out}: ") and text.strip().endswith("(sim, seed 2)"), text
    assert read_hdf5(out).attrs["seed"] == 2 and sorted(p.name for p in tmp_path.iterdir()) == ["old.h5"]


def test_an_external_axis_trajectory_is_refused_by_the_virtual_kr_c4(short_traj, tmp_path):
    """A trajectory file may name axes 7-12 (the external axes a real controller drives); the virtual KR C4
    recorded the paper's A3 physics labelled A9."""
    d = json.loads(Path(short_traj).read_text())
    d["axis"] = 9
    traj = tmp_path / "e3.json"
    traj.write_text(json.dumps(d))
    code, text = run("capture", traj, "-o", tmp_path / "e3.h5")
    assert code == 1 and "axis 9 is the external axis E3; the virtual KR C4 has axes 1 to 6" in text, text
    assert "Traceback" not in text and not (tmp_path / "e3.h5").exists()


def test_a_trajectory_beyond_the_virtual_axis_is_not_simulated(tmp_path):
    """New-user trial 17: `excite inertia --q-max-deg 400` (a real robot's limit, perhaps) then `capture` on
    the virtual KR C4 recorded A3 at 185.8 degrees, beyond the simulated robot's 156 (it has no hard
    stops); refused before anything is written, as serve-sim --q0 is."""
    traj = tmp_path / "e.json"
    r = CliRunner().invoke(cli, ["excite", "inertia", "-o", str(traj), "--q-max-deg", "400"])
    assert r.exit_code == 0, r.output
    out = tmp_path / "e.h5"
    r = CliRunner().invoke(cli, ["capture", str(traj), "-o", str(out)])
    assert r.exit_code == 1 and len(r.stderr.splitlines()) == 1, r.output
    assert "beyond the range of motion of the virtual KR C4's A3" in r.stderr and "-120 to 156 degrees" in r.stderr
    assert not out.exists()


def test_an_axis_that_does_not_follow_its_command_is_warned(short_traj, tmp_path):
    """New-user trial 17: a --sim-config with tau_max 1 N·m let A3 fall 89.9 degrees from its command, and
    capture said only how many samples it wrote (a real KR C4 stops on its following error)."""
    cfg = tmp_path / "weak.json"
    cfg.write_text(json.dumps({"tau_max": 1.0}))
    r = CliRunner().invoke(cli, ["capture", str(short_traj), "-o", str(tmp_path / "w.h5"), "--sim-config", str(cfg)])
    assert r.exit_code == 0, r.output
    assert "warning: capture: the axis did not follow its command, up to" in r.stderr, r.stderr
    r = CliRunner().invoke(cli, ["capture", str(short_traj), "-o", str(tmp_path / "ok.h5")])
    assert r.exit_code == 0 and "warning" not in r.stderr, r.stderr
