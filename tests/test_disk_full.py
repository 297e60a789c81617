"""A disk that fills up during recording: the writer stops before HDF5 fails, keeps what it
recorded readable, and every command says so in one line (no traceback, no unreadable file)."""
from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest

from kukaid.errors import DiskFullError
from kukaid.logs import AxisLogWriter, read_hdf5

resource = pytest.importorskip("resource")  # file-size limits: POSIX


def _shrinking_disk(monkeypatch, room_at_start: int):
    """Make every writer see ``room_at_start`` bytes beyond its reserve, less what it has written
    (8 bytes a value: time and every channel per sample, two per gap)."""

    def room(self):
        per_sample = 8 * (1 + len(self.channels) * len(self.axes))
        return self.reserve + room_at_start - per_sample * self.n - 16 * self._d["gaps"].shape[0]

    monkeypatch.setattr(AxisLogWriter, "room", room)


def test_writer_stops_cleanly_and_keeps_the_samples(tmp_path, monkeypatch):
    _shrinking_disk(monkeypatch, room_at_start=8 * 3 * 100)  # room for 100 samples of (time, q, tau)
    out = tmp_path / "log.h5"
    w = AxisLogWriter(out, axes=(3,))
    for k in range(10):
        w.append(np.arange(k * 10, k * 10 + 10) * 0.012, q=np.zeros((10, 1)), tau=np.ones((10, 1)))
    with pytest.raises(DiskFullError, match=r"recording stopped; the log keeps the 100 samples up to t = 1\.188 s"):
        w.append([1.2], q=[[0.0]], tau=[[1.0]])
    with pytest.raises(DiskFullError):  # and it stays stopped
        w.mark_gap(1.2, 1.3)
    w.flush()
    w.close()
    log = read_hdf5(out)
    assert log.n_samples == 100 and log.time[-1] == pytest.approx(1.188)


def test_a_first_batch_larger_than_the_room_keeps_what_fits(tmp_path, monkeypatch):
    """Samples already received are not dropped with the batch that does not fit (issue 16)."""
    _shrinking_disk(monkeypatch, room_at_start=8 * 3 * 100)  # room for 100 samples of (time, q, tau)
    out = tmp_path / "log.h5"
    w = AxisLogWriter(out, axes=(3,))
    t = np.arange(250) * 0.004
    q = np.sin(t)[:, None]
    with pytest.raises(DiskFullError, match=r"recording stopped; the log keeps the 100 samples up to t = 0\.396 s "
                                            r"\(150 later samples not written\)"):
        w.append(t, q=q, tau=2 * q)
    log = read_hdf5(out)
    assert log.n_samples == 100
    np.testing.assert_array_equal(log.time, t[:100])
    np.testing.assert_array_equal(log.q[:, 0], q[:100, 0])
    np.testing.assert_array_equal(log.tau[:, 0], 2 * q[:100, 0])


def test_nothing_recorded_leaves_no_file(tmp_path, monkeypatch):
    _shrinking_disk(monkeypatch, room_at_start=0)
    out = tmp_path / "log.h5"
    w = AxisLogWriter(out, axes=(3,))
    with pytest.raises(DiskFullError, match="nothing had been recorded; no log written"):
        w.append([0.0], q=[[0.0]], tau=[[1.0]])
    assert not out.exists()


def _limited(limit_bytes: int):
    def set_limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit_bytes, resource.getrlimit(resource.RLIMIT_FSIZE)[1]))
    return set_limit


@pytest.mark.parametrize("extra, kept", [(200 * 1024, True), (0, False)])
def test_capture_under_a_file_size_limit(tmp_path, kukaid_cmd, extra, kept):
    """A real limit (RLIMIT_FSIZE): without the guard HDF5 fails mid-write, prints tracebacks,
    may crash and leaves a file it cannot open again."""
    traj, out = tmp_path / "tf.json", tmp_path / "log.h5"
    subprocess.run([*kukaid_cmd, "excite", "friction", "-o", str(traj)], check=True, capture_output=True)
    r = subprocess.run([*kukaid_cmd, "capture", str(traj), "-o", str(out)], capture_output=True, text=True,
                       preexec_fn=_limited(AxisLogWriter.reserve + extra), timeout=120)
    assert r.returncode == 1, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
    assert str(out) in lines[0] and "recording stopped" in lines[0]
    if kept:
        log = read_hdf5(out)
        total = json.loads(traj.read_text())
        assert 100 < log.n_samples and log.time[-1] < total["t"][-1] - total["t"][0]
        assert f"keeps the {log.n_samples} samples" in lines[0]
    else:
        assert not out.exists() and "no log written" in lines[0]


def test_run_admittance_stops_the_robot_and_keeps_the_log(tmp_path, monkeypatch):
    """The measured log is written while the robot moves: a full disk stops the motion (hold),
    keeps the samples and exits with one line."""
    from click.testing import CliRunner

    from kukaid.params import save_params
    from kukaid.sim import SimConfig
    from kukaid_cli.main import cli

    save_params(tmp_path / "params.json", SimConfig().truth_params())
    _shrinking_disk(monkeypatch, room_at_start=8 * 5 * 300)  # about 300 cycles of (time, q, tau, q_cmd, ext)
    out = tmp_path / "run.h5"
    r = CliRunner().invoke(cli, ["run-admittance", "--params", str(tmp_path / "params.json"), "--duration", "8",
                                 "--operator", "push", "-o", str(out)])
    assert r.exit_code == 1, r.output
    assert "recording stopped" in r.output and "Traceback" not in r.output
    log = read_hdf5(out)
    assert log.n_samples == 300


def test_kvp_capture_keeps_the_samples(tmp_path, monkeypatch):
    from types import SimpleNamespace

    from kukaid.krc.kvp_capture import capture_kvp
    from kukaid.sim import SimConfig, VirtualKRC4
    from kukaid.krc.server import KvpServer
    from kukaid.krc.sim_source import SimSource

    t = np.arange(0.0, 30.0, 0.012)
    traj = SimpleNamespace(t=t, q=0.3 + 0.1 * np.sin(2 * np.pi * t / 4.0) * np.minimum(t, 1.0), axis=3)
    src = SimSource(VirtualKRC4(SimConfig(), seed=1, axis=3), axis=3, trajectory=traj).start()
    srv = KvpServer(src, port=0).start()
    try:
        _shrinking_disk(monkeypatch, room_at_start=8 * 4 * 1000)  # 1000 samples of (time, q, tau, temp)
        out = tmp_path / "kvp.h5"
        with pytest.raises(DiskFullError, match="recording stopped; the log keeps the") as e:
            capture_kvp(out, "127.0.0.1", srv.port, [3], 20.0, False, "poll", None)
        # the writer is handed a batch every 0.25 s, whatever its size (about 1400 samples on a
        # fast machine, a few dozen on a loaded one): the log fills to exactly its room either way;
        # a loaded machine can also miss a poll, and the gap it marks takes 16 bytes of that room
        log = read_hdf5(out)
        n = (8 * 4 * 1000 - 16 * len(log.attrs.get("gaps", []))) // (8 * 4)
        assert log.n_samples == n >= 990 and f"keeps the {n} samples" in str(e.value)
        assert np.all(np.diff(log.time) > 0) and np.all(np.abs(log.q[:, 0] - 0.3) <= 0.11)
    finally:
        srv.stop()
        src.stop()
