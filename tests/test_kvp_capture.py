"""Capture over KUKAVARPROXY against the virtual KR C4: end to end, dropped links, kill, garbage."""
from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from kukaid.errors import ControllerError, KukaidError
from kukaid.logs import read_hdf5
from kukaid.krc.krl_logger import RingLayout
from kukaid.krc.kvp_capture import capture_kvp
from kukaid.krc.server import KvpServer, SimSource


def _excitation(duration: float = 8.0) -> SimpleNamespace:
    """A sine excitation of A3 (4 s period, 0.25 rad) around 0.3 rad, at the IPO rate."""
    t = np.arange(0.0, duration, 0.012)
    ramp = 0.5 - 0.5 * np.cos(np.pi * np.minimum(t / 1.0, 1.0))  # smooth start: within the axis limits
    q = 0.3 + 0.25 * np.sin(2 * np.pi * t / 4.0) * ramp
    return SimpleNamespace(t=t, q=q, axis=3)


@pytest.fixture
def virtual_krc4():
    from kukaid.sim import SimConfig, VirtualKRC4

    made = []

    def make(duration: float = 8.0, ring=RingLayout(axes=(3,))):
        sim = VirtualKRC4(SimConfig().replace(noise_sigma=0.3), seed=11, axis=3)
        src = SimSource(sim, axis=3, trajectory=_excitation(duration), ring=ring).start()
        srv = KvpServer(src, port=0).start()
        made.append((srv, src))
        return srv, src

    yield make
    for srv, src in made:
        srv.stop()
        src.stop()


def _match_truth(log, truth, min_pair_fraction=0.95, q_tol_deg=2e-6, tau_tol=2e-6):
    """Every logged position is a position the simulator measured; (q, tau) pairs come from one sample.

    Poll mode serves 6 decimals (deg, N·m); the ring logger's text has 4 (deg) and 3 (N·m).
    """
    tq, ttau = truth["q"], truth["tau"]
    q, tau = log.q[:, 0], log.tau[:, 0]
    dq = np.abs(np.degrees(q)[:, None] - np.degrees(tq)[None, :])
    assert np.all(dq.min(axis=1) < q_tol_deg), "a logged position is not one the simulator measured"
    pair = (dq < q_tol_deg) & (np.abs(tau[:, None] - ttau[None, :]) < tau_tol)
    frac = pair.any(axis=1).mean()
    assert frac >= min_pair_fraction, f"only {frac:.3f} of (q, tau) pairs match one simulator sample"
    return frac


def test_poll_capture_matches_ground_truth(virtual_krc4, tmp_path):
    srv, src = virtual_krc4()
    out = tmp_path / "kvp.h5"
    seen = []
    s = capture_kvp(out, "127.0.0.1", srv.port, [3], 1.5, False, "poll", seen.append,
                    attrs={"experiment": "inertia"})
    log = read_hdf5(out)
    assert log.n_samples == s["n_samples"] > 100
    assert log.axes == (3,) and log.has("temp")
    _match_truth(log, src.truth())
    # every simulator sample of the captured interval was seen at least once (polling beats 12 ms)
    # polling (sub-ms) sees most 12 ms simulator samples of the captured interval; what it misses
    # is lost to scheduling pauses (here the server shares the test's process and CPU: under load
    # the simulator thread advances in bursts and a poll sees only the newest sample) -- the
    # reason for ring mode.  Measured here (load average 5.5 on 2 cores): 0.99.
    tr = src.truth()
    k = [int(np.argmin(np.abs(tr["q"] - log.q[i, 0]) + np.abs(tr["tau"] - log.tau[i, 0]))) for i in (0, -1)]
    window = np.round(np.degrees(tr["q"][k[0]:k[1] + 1]), 6)
    seen_frac = np.isin(window, np.round(np.degrees(log.q[:, 0]), 6)).mean()
    assert seen_frac > 0.5, seen_frac
    # PC timestamps keep the controller's time scale: (sim time of the sample) - (PC stamp) is
    # constant up to the 12 ms sample age and scheduling jitter
    idx = np.array([int(np.argmin(np.abs(tr["q"] - log.q[i, 0]) + np.abs(tr["tau"] - log.tau[i, 0])))
                    for i in range(0, log.n_samples, 10)])
    offset = tr["time"][idx] - log.time[::10]
    assert np.mean(np.abs(offset - np.median(offset)) < 0.03) > 0.8
    for k in ("rate_hz", "latency_mean_s", "latency_p99_s", "latency_max_s", "n_requests"):
        assert k in log.attrs and log.attrs[k] > 0
    assert log.attrs["latency_p99_s"] >= log.attrs["latency_mean_s"]
    assert log.attrs["source"] == "kukavarproxy" and log.attrs["experiment"] == "inertia"
    assert 20 < log.temp[-1, 0] < 120  # kelvin converted to °C
    assert seen and 1.0 < seen[-1] <= 1.6
    assert log.attrs.get("gaps") is None and s["gaps"] == []


def test_ring_capture_is_exact_at_12_ms(virtual_krc4, tmp_path):
    srv, src = virtual_krc4()
    out = tmp_path / "ring.h5"
    s = capture_kvp(out, "127.0.0.1", srv.port, [3], 1.2, False, "ring", None)
    log = read_hdf5(out)
    assert np.allclose(np.diff(log.time), 0.012)
    assert log.n_samples >= 72 and s["gaps"] == []
    tr = src.truth()
    k0 = int(np.argmin(np.abs(tr["q"] - log.q[0, 0]) + np.abs(tr["tau"] - log.tau[0, 0])))
    n = log.n_samples
    np.testing.assert_allclose(np.degrees(log.q[:, 0]), np.degrees(tr["q"][k0:k0 + n]), atol=5e-5)
    np.testing.assert_allclose(log.tau[:, 0], tr["tau"][k0:k0 + n], atol=5e-4)
    np.testing.assert_allclose(log.time, tr["time"][k0:k0 + n] - tr["time"][k0], atol=1e-9)
    assert log.attrs["time_source"] == "controller $ROB_TIMER"
    assert s["ring_overflows"] == 0 and log.attrs["ring_overflows"] == 0


def test_ring_capture_refuses_axes_the_logger_does_not_record(virtual_krc4, tmp_path):
    srv, _ = virtual_krc4()
    with pytest.raises(ControllerError, match="records axes \\[3\\], not A2"):
        capture_kvp(tmp_path / "x.h5", "127.0.0.1", srv.port, [2, 3], 0.5, False, "ring", None)


def test_dropped_connection_resumes_and_marks_gap(virtual_krc4, tmp_path):
    srv, src = virtual_krc4()
    out = tmp_path / "drop.h5"
    timer = threading.Timer(0.7, srv.go_down, args=(0.5,))
    timer.start()
    try:
        s = capture_kvp(out, "127.0.0.1", srv.port, [3], 2.0, False, "poll", None, reconnect_wait=5.0)
    finally:
        timer.cancel()
    log = read_hdf5(out)
    assert len(s["gaps"]) == 1 and s["n_reconnects"] == 1
    g0, g1 = log.attrs["gaps"][0]
    assert 0.5 < g0 < 0.9 and g1 - g0 >= 0.45
    before, after = log.time <= g0, log.time >= g1
    assert before.sum() > 50 and after.sum() > 50 and (before | after).all()
    _match_truth(log, src.truth())  # samples on both sides intact


def test_garbage_mid_capture_is_survived_and_persistent_garbage_is_a_clear_error(virtual_krc4, tmp_path):
    srv, src = virtual_krc4()
    timer = threading.Timer(0.3, lambda: setattr(srv.faults, "garbage", 1))
    timer.start()
    s = capture_kvp(tmp_path / "g1.h5", "127.0.0.1", srv.port, [3], 0.8, False, "poll", None)
    assert len(s["gaps"]) == 1
    _match_truth(read_hdf5(tmp_path / "g1.h5"), src.truth())
    timer = threading.Timer(0.3, lambda: setattr(srv.faults, "garbage", 10_000))
    timer.start()
    with pytest.raises(ControllerError, match=r"capture stopped after \d+ samples \(kept in .*g2.h5\).*garbage"):
        capture_kvp(tmp_path / "g2.h5", "127.0.0.1", srv.port, [3], 5.0, False, "poll", None, reconnect_wait=1.0)
    srv.faults.garbage = 0
    log = read_hdf5(tmp_path / "g2.h5")
    assert log.n_samples > 10
    _match_truth(log, src.truth())


def test_empty_value_and_unreachable_proxy_are_clear_errors(virtual_krc4, tmp_path):
    srv, _ = virtual_krc4()
    srv.faults.empty = {"$TORQUE_AXIS_ACT[3]"}
    with pytest.raises(ControllerError, match=r"\$TORQUE_AXIS_ACT\[3\] came back empty"):
        capture_kvp(tmp_path / "e.h5", "127.0.0.1", srv.port, [3], 0.5, False, "poll", None)
    srv.stop()
    with pytest.raises(ControllerError, match="cannot connect"):
        capture_kvp(tmp_path / "u.h5", "127.0.0.1", srv.port, [3], 0.5, False, "poll", None)
    assert not (tmp_path / "u.h5").exists()
    with pytest.raises(KukaidError, match="--duration S or --until-interrupt"):
        capture_kvp(tmp_path / "d.h5", "127.0.0.1", srv.port, [3], None, False, "poll", None)


_CAPTURE_CHILD = (
    "import sys; from kukaid.krc.kvp_capture import capture_kvp; "
    "s = capture_kvp(sys.argv[1], '127.0.0.1', int(sys.argv[2]), [3], None, True, sys.argv[3], None); "
    "print('stopped_by', s['stopped_by'], s['n_samples'])"
)


def _child(out: Path, port: int, mode: str = "poll") -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-c", _CAPTURE_CHILD, str(out), str(port), mode],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _wait_samples(out: Path, proc: subprocess.Popen, seconds: float) -> None:
    deadline = time.monotonic() + 20
    while not out.exists() and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.05)
    time.sleep(seconds)


def test_sigkill_leaves_every_flushed_sample(virtual_krc4, tmp_path):
    srv, src = virtual_krc4()
    out = tmp_path / "killed.h5"
    proc = _child(out, srv.port)
    try:
        _wait_samples(out, proc, 1.2)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
    log = read_hdf5(out)
    # flushed at least every 0.25 s: at most the last 0.5 s may be missing
    assert log.duration > 0.6 and log.n_samples > 100
    _match_truth(log, src.truth())


def test_sigterm_stops_cleanly(virtual_krc4, tmp_path):
    srv, _ = virtual_krc4()
    out = tmp_path / "term.h5"
    proc = _child(out, srv.port, "ring")
    try:
        _wait_samples(out, proc, 0.8)
        proc.send_signal(signal.SIGTERM)
        stdout, stderr = proc.communicate(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, stderr
    assert stdout.startswith("stopped_by signal")
    log = read_hdf5(out)
    assert log.attrs["stopped_by"] == "signal" and log.n_samples >= 24


def test_serve_sim_subprocess_end_to_end(tmp_path, kukaid_cmd):
    """`kukaid serve-sim` in the background; capture through the protocol; compare with its truth."""
    from kukaid.excite import Trajectory

    ex = _excitation(4.0)
    traj = Trajectory(t=ex.t, q=ex.q, axis=3, kind="inertia")
    traj.to_json(tmp_path / "traj.json")
    truth = tmp_path / "truth.h5"
    server = subprocess.Popen([*kukaid_cmd, "serve-sim", "--port", "0", "--trajectory", str(tmp_path / "traj.json"),
                               "--duration", "4", "--seed", "5", "--truth", str(truth)],
                              stderr=subprocess.PIPE, text=True)
    try:
        line = server.stderr.readline()
        m = re.search(r"listening on 127\.0\.0\.1:(\d+)", line)
        assert m, line
        port = int(m.group(1))
        out = tmp_path / "log.h5"
        r = subprocess.run([*kukaid_cmd, "capture", str(tmp_path / "traj.json"), "-o", str(out), "--backend", "kvp",
                            "--host", "127.0.0.1", "--port", str(port), "--axis", "3", "--duration", "2"],
                           capture_output=True, text=True, timeout=60)
        assert r.returncode == 0, r.stderr
        server.wait(timeout=30)
        assert server.returncode == 0, server.stderr.read()
    finally:
        if server.poll() is None:
            server.kill()
        server.stderr.close()
    tr = read_hdf5(truth)
    assert tr.attrs["source"].startswith("virtual-krc4") and tr.has("tau_ext_true")
    log = read_hdf5(out)
    _match_truth(log, {"q": tr.q[:, 0], "tau": tr.tau[:, 0]})
    # the captured motion follows the excitation: same range of positions as the truth over that time
    assert np.ptp(log.q) > 0.1


def test_slow_replies_lower_the_rate_and_show_in_the_latency(virtual_krc4, tmp_path):
    srv, src = virtual_krc4()
    srv.faults.delay = 0.01
    s = capture_kvp(tmp_path / "slow.h5", "127.0.0.1", srv.port, [3], 0.8, False, "poll", None)
    log = read_hdf5(tmp_path / "slow.h5")
    assert log.attrs["latency_mean_s"] >= 0.01 and s["rate_hz"] < 1 / 0.02
    # position and torque now come from requests >= 10 ms apart, often from different 12 ms
    # samples: only the positions are checked (this skew is what ring mode avoids)
    _match_truth(log, src.truth(), min_pair_fraction=0.0)


@pytest.mark.parametrize("ring, outage, expect_gap", [(RingLayout(axes=(3,)), 0.3, False),
                                                      (RingLayout(axes=(3,), nb=2, bs=2), 0.5, True)])
def test_ring_mode_rides_out_an_outage_shorter_than_the_ring(virtual_krc4, tmp_path, ring, outage, expect_gap):
    """Unacknowledged blocks wait in the ring: a short outage loses nothing; a long one is a marked gap."""
    srv, src = virtual_krc4(ring=ring)
    timer = threading.Timer(0.4, srv.go_down, args=(outage,))
    timer.start()
    try:
        s = capture_kvp(tmp_path / "ro.h5", "127.0.0.1", srv.port, [3], 1.6, False, "ring", None, reconnect_wait=5)
    finally:
        timer.cancel()
    log = read_hdf5(tmp_path / "ro.h5")
    assert s["n_reconnects"] == 1
    steps = np.round(np.diff(log.time) / 0.012).astype(int)
    if expect_gap:
        assert s["ring_overflows"] >= 1 and len(log.attrs["gaps"]) >= 1
        g0, g1 = log.attrs["gaps"][0]
        assert g1 - g0 > 0.1 and steps.max() > 1
    else:
        assert s["gaps"] == [] and s["ring_overflows"] == 0 and np.all(steps == 1)
    _match_truth(log, src.truth(), min_pair_fraction=1.0, q_tol_deg=5.1e-5, tau_tol=5.1e-4)
