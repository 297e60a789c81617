"""Capture over KUKAVARPROXY against the virtual KR C4: end to end, dropped links, kill, garbage."""
from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import threading
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from kukaid.errors import ControllerError, KukaidError
from kukaid.identify.adequacy import held_share
from kukaid.logs import read_hdf5
from kukaid.krc.krl_logger import RingLayout
from kukaid.krc.kvp_capture import capture_kvp
from kukaid.krc.server import KvpServer
from kukaid.krc.sim_source import SimSource
from live_helpers import CountingSource, wait_for_samples


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

    def make(duration: float = 8.0, ring=RingLayout(axes=(3,)), count: str = "$AXIS_ACT_MEAS", stepped: bool = False):
        """The server counts the reads of ``count`` in ``srv.reads`` (a CountingSource).  ``stepped``:
        the simulator does not run in real time but takes one 12 ms sample at every counted read
        (every poll sees a new sample, at any speed of the machine)."""
        sim = VirtualKRC4(SimConfig().replace(noise_sigma=0.3), seed=11, axis=3)
        src = SimSource(sim, axis=3, trajectory=_excitation(duration), ring=ring)
        if not stepped:
            src.start()
        reads = CountingSource(src, count, step=(lambda: src.step(0.012)) if stepped else None)
        srv = KvpServer(reads, port=0).start()
        srv.reads = reads
        made.append((srv, src))
        return srv, src

    yield make
    for srv, src in made:
        srv.stop()
        src.stop()


def _match_truth(log, truth, min_pair_fraction=None, q_tol_deg=2e-6, tau_tol=2e-6):
    """Every logged position is a position the simulator measured; (q, tau) pairs come from one sample.

    Poll mode serves 6 decimals (deg, N·m); the ring logger's text has 4 (deg) and 3 (N·m).  Poll
    mode reads the position and the torque in two requests: a new 12 ms sample between them splits
    that one pair, so by default at most one pair per 12 ms of the log (+2) may be split, a bound
    that holds at any polling rate (a fixed fraction would not: a slow poller splits more).
    """
    tq, ttau = truth["q"], truth["tau"]
    q, tau = log.q[:, 0], log.tau[:, 0]
    dq = np.abs(np.degrees(q)[:, None] - np.degrees(tq)[None, :])
    assert np.all(dq.min(axis=1) < q_tol_deg), "a logged position is not one the simulator measured"
    pair = (dq < q_tol_deg) & (np.abs(tau[:, None] - ttau[None, :]) < tau_tol)
    split = int((~pair.any(axis=1)).sum())
    if min_pair_fraction is None:
        assert split <= log.duration / 0.012 + 2, f"{split} (q, tau) pairs split, {log.duration:.3f} s of samples"
    else:
        frac = 1 - split / log.n_samples
        assert frac >= min_pair_fraction, f"only {frac:.3f} of (q, tau) pairs match one simulator sample"
    return split


def test_poll_capture_matches_ground_truth(virtual_krc4, tmp_path):
    srv, src = virtual_krc4()
    out = tmp_path / "kvp.h5"
    seen = []
    s = capture_kvp(out, "127.0.0.1", srv.port, [3], 1.5, False, "poll", seen.append,
                    attrs={"experiment": "inertia"})
    log = read_hdf5(out)
    n = log.n_samples
    assert n == s["n_samples"] >= 2 and s["rate_hz"] == pytest.approx((n - 1) / s["duration_s"])
    # a poll reads $AXIS_ACT_MEAS once; polls faster than the 12 ms samples record each sample once
    assert log.attrs["n_polls"] == srv.reads.n == n + log.attrs["n_held_polls"] and n < srv.reads.n
    assert held_share(log) == 0.0  # never a row repeating the one before (a held sample)
    assert s["rate_hz"] < 1 / 0.012 + 1
    steps = np.diff(log.time) / 0.012  # stamped by $ROB_TIMER: whole 12 ms cycles apart
    assert np.allclose(steps, np.round(steps), atol=1e-6) and steps.min() >= 1 - 1e-6
    assert log.attrs["time_source"] == "controller $ROB_TIMER"
    assert log.axes == (3,) and log.has("temp")
    _match_truth(log, src.truth())
    # every simulator sample of the captured interval was seen at least once (polling beats 12 ms)
    # polling (sub-ms) sees most 12 ms simulator samples of the captured interval; what it misses
    # is lost to scheduling pauses (here the server shares the test's process and CPU: under load
    # the simulator thread advances in bursts and a poll sees only the newest sample) -- the
    # reason for ring mode.  Measured here (load average 5.5 on 2 cores): 0.99.  A machine that
    # polls slower than the 12 ms samples can only see rate x 12 ms of them: the bound follows.
    tr = src.truth()
    k = [int(np.argmin(np.abs(tr["q"] - log.q[i, 0]) + np.abs(tr["tau"] - log.tau[i, 0]))) for i in (0, -1)]
    window = np.round(np.degrees(tr["q"][k[0]:k[1] + 1]), 6)
    seen_frac = np.isin(window, np.round(np.degrees(log.q[:, 0]), 6)).mean()
    assert seen_frac > 0.5 * min(1.0, s["rate_hz"] * 0.012), (seen_frac, s["rate_hz"])
    # the controller's stamps: (sim time of the sample) - (stamp) is constant, up to the pairs a
    # sample arriving during a poll splits (and the jitter bound of PC stamps, without $ROB_TIMER)
    idx = np.array([int(np.argmin(np.abs(tr["q"] - log.q[i, 0]) + np.abs(tr["tau"] - log.tau[i, 0])))
                    for i in range(0, log.n_samples, 10)])
    offset = tr["time"][idx] - log.time[::10]
    jitter = 0.03 + 2 * s["latency_p99_s"]  # sample age + scheduling, and the request time measured
    assert np.mean(np.abs(offset - np.median(offset)) < jitter) > 0.8
    for k in ("rate_hz", "latency_mean_s", "latency_p99_s", "latency_max_s", "n_requests"):
        assert k in log.attrs and log.attrs[k] > 0
    assert log.attrs["latency_p99_s"] >= log.attrs["latency_mean_s"]
    assert log.attrs["source"] == "kukavarproxy" and log.attrs["experiment"] == "inertia"
    assert 20 < log.temp[-1, 0] < 120  # kelvin converted to °C
    # progress every 0.1 s up to the end: the last report is within 0.1 s + two sample intervals
    # (as measured) of the last sample, and never after the capture ended
    gap = float(np.max(np.diff(log.time)))
    assert seen == sorted(seen) and log.time[-1] - 0.1 - 2 * gap <= seen[-1] <= s["wall_s"]
    assert log.attrs.get("gaps") is None and s["gaps"] == []


def test_ring_capture_is_exact_at_12_ms(virtual_krc4, tmp_path):
    srv, src = virtual_krc4()
    out = tmp_path / "ring.h5"
    s = capture_kvp(out, "127.0.0.1", srv.port, [3], 1.2, False, "ring", None)
    log = read_hdf5(out)
    assert np.allclose(np.diff(log.time), 0.012)  # every 12 ms sample, none lost, whatever the speed
    assert log.n_samples >= 10 and s["gaps"] == []
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


def test_cli_capture_of_a_trajectory_records_the_axis_it_moves(virtual_krc4, tmp_path):
    """`capture TRAJ.json --backend kvp` without --axis recorded A3 whatever axis TRAJ moves: the
    log of an A2 experiment (its KRL program running) held the standing A3, labelled with that
    experiment.  It now records the trajectory's axis; an --axis other than it is a usage error."""
    from click.testing import CliRunner

    from kukaid.excite import Trajectory
    from kukaid_cli.main import cli

    srv, _ = virtual_krc4()
    ex = _excitation(8.0)
    traj = tmp_path / "inertia_a2.json"
    Trajectory(t=ex.t, q=ex.q, axis=2, kind="inertia").to_json(traj)
    out = tmp_path / "a2.h5"
    r = CliRunner().invoke(cli, ["capture", str(traj), "-o", str(out), "--backend", "kvp", "--port", str(srv.port),
                                 "--duration", "0.5"])
    assert r.exit_code == 0, r.output
    log = read_hdf5(out)
    assert list(log.axes) == [2] and log.attrs["experiment"] == "inertia"
    bad = tmp_path / "a3.h5"
    r = CliRunner().invoke(cli, ["capture", str(traj), "-o", str(bad), "--backend", "kvp", "--port", str(srv.port),
                                 "--duration", "0.5", "--axis", "3"])
    lines = [ln for ln in r.output.splitlines() if ln.strip()]
    assert r.exit_code == 2 and len(lines) == 1, r.output
    assert lines[0].startswith(f"kukaid: error: capture: option --axis 3 does not match {traj}: its experiment "
                               "moves A2"), r.output
    assert not bad.exists()


def test_dropped_connection_resumes_and_marks_gap(virtual_krc4, tmp_path):
    """The link drops during poll 60 (the controller is away 0.5 s, its clock goes on); the capture
    reconnects and is stopped 60 polls later.  Driven by polls (the simulator takes a sample at
    each), the counts hold at any speed: under load a real-time simulator stalled, polls saw old
    samples, and the gap could fall between two polls of one sample."""
    srv, src = virtual_krc4(stepped=True)
    stop = threading.Event()
    srv.reads.at(60, lambda: (srv.go_down(0.5), src.step(0.5))).at(120, stop.set)
    out = tmp_path / "drop.h5"
    s = capture_kvp(out, "127.0.0.1", srv.port, [3], 60.0, False, "poll", None, reconnect_wait=5.0,
                    stop_event=stop)
    log = read_hdf5(out)
    assert s["stopped_by"] == "stop-event" and len(s["gaps"]) == 1 and s["n_reconnects"] == 1
    g0, g1 = log.attrs["gaps"][0]
    before, after = log.time <= g0, log.time >= g1
    assert (before | after).all() and log.attrs["n_polls"] == 119  # poll 60 lost to the drop
    assert log.n_samples == 119 and log.attrs["n_held_polls"] == 0  # every poll a new sample
    assert before.sum() == 59 and after.sum() == 60
    nb = int(before.sum())
    # in the controller's time: from the last sample before to the first after the reconnection
    assert g0 == log.time[nb - 1] and g1 == log.time[nb] and g1 - g0 >= 0.5
    _match_truth(log, src.truth())  # samples on both sides intact


@pytest.mark.parametrize("mode, count, stepped", [("poll", "$AXIS_ACT_MEAS", True), ("ring", "KID_WR", False)])
def test_a_stop_while_the_link_is_down_ends_the_capture_cleanly(virtual_krc4, tmp_path, mode, count, stepped):
    """Ctrl-C / SIGTERM while capture waited for the controller to come back was reported as a
    failure ('could not reconnect within 30 s', exit 1, stopped_by error) a moment after the signal,
    and `--until-interrupt`, whose normal end is that interrupt, failed.  The stop now ends the
    capture as it does with the link up: the samples recorded are the log."""
    import time

    srv, _ = virtual_krc4(count=count, stepped=stepped)  # poll: a new sample at every poll, at any speed
    stop = threading.Event()
    srv.reads.at(20, lambda: (srv.go_down(60.0), threading.Timer(0.5, stop.set).start()))
    out = tmp_path / f"down_{mode}.h5"
    t = time.monotonic()
    s = capture_kvp(out, "127.0.0.1", srv.port, [3], None, True, mode, None, reconnect_wait=30.0, stop_event=stop)
    assert time.monotonic() - t < 20.0  # ended by the stop, not by the reconnection's limit
    assert s["stopped_by"] == "stop-event" and s["n_reconnects"] == 0
    log = read_hdf5(out)
    assert log.n_samples == s["n_samples"] >= 2 and log.attrs["stopped_by"] == "stop-event"


@pytest.mark.parametrize("mode, count", [("poll", "$AXIS_ACT_MEAS"), ("ring", "KID_WR")])
def test_a_controller_that_restarts_mid_capture_stops_it_with_the_samples_kept(virtual_krc4, tmp_path, mode, count):
    """Trial 20: a controller restarted during a capture ($ROB_TIMER from its start again). Poll mode
    dropped its samples without a word until the clock caught up and joined the rest on; ring mode took
    the restarted logger's counter as read, never acknowledged its blocks, and recorded nothing more
    (exit 0). The capture now stops there, naming the restart, the samples before it kept."""
    from kukaid.sim import SimConfig, VirtualKRC4

    srv, _ = virtual_krc4(count=count, stepped=True)
    again = SimSource(VirtualKRC4(SimConfig().replace(noise_sigma=0.3), seed=12, axis=3), axis=3,
                      trajectory=_excitation(8.0), ring=RingLayout(axes=(3,)))

    def restart():   # the controller comes back with its clock, and its logger, from the start
        srv.reads.source, srv.reads.step = again, (lambda: again.step(0.012))
        srv.drop_clients()

    srv.reads.at(60, restart)
    out = tmp_path / f"restart_{mode}.h5"
    with pytest.raises(ControllerError, match=r"capture stopped after \d+ samples \(kept in .*\): the controller's clock "
                                              r"\(\$ROB_TIMER\) went back by .* it restarted"):
        capture_kvp(out, "127.0.0.1", srv.port, [3], 20.0, False, mode, None, reconnect_wait=5.0)
    log = read_hdf5(out)
    assert log.n_samples >= 2 and np.all(np.diff(log.time) > 0)


def test_garbage_mid_capture_is_survived_and_persistent_garbage_is_a_clear_error(virtual_krc4, tmp_path):
    srv, src = virtual_krc4(stepped=True)  # a new sample at every poll, at any speed of the machine
    stop = threading.Event()
    # the reply after poll 30's position (its torque) is garbage; stopped at poll 80
    srv.reads.at(30, lambda: setattr(srv.faults, "garbage", 1)).at(80, stop.set)
    s = capture_kvp(tmp_path / "g1.h5", "127.0.0.1", srv.port, [3], 60.0, False, "poll", None, stop_event=stop)
    assert len(s["gaps"]) == 1 and s["n_polls"] == 79  # poll 30 lost to the garbage
    assert s["n_samples"] == 79 and s["n_held_polls"] == 0
    _match_truth(read_hdf5(tmp_path / "g1.h5"), src.truth())
    srv.reads.at(srv.reads.n + 30, lambda: setattr(srv.faults, "garbage", 10_000))
    with pytest.raises(ControllerError, match=r"capture stopped after (\d+) samples \(kept in .*g2.h5\).*garbage") as e:
        capture_kvp(tmp_path / "g2.h5", "127.0.0.1", srv.port, [3], 60.0, False, "poll", None, reconnect_wait=1.0)
    srv.faults.garbage = 0
    log = read_hdf5(tmp_path / "g2.h5")
    assert log.n_samples == 29 and f"after {log.n_samples} samples" in str(e.value)
    _match_truth(log, src.truth())


def test_empty_value_and_unreachable_proxy_are_clear_errors(virtual_krc4, tmp_path):
    srv, _ = virtual_krc4()
    srv.faults.empty = {"$TORQUE_AXIS_ACT[3]"}
    with pytest.raises(ControllerError, match=r"\$TORQUE_AXIS_ACT\[3\] came back empty") as e:
        capture_kvp(tmp_path / "e.h5", "127.0.0.1", srv.port, [3], 0.5, False, "poll", None)
    # not a sample: no log (it said 'kept in e.h5' and left an empty file that a second try needed --force for)
    assert "with no sample recorded, no log written" in str(e.value) and "kept" not in str(e.value)
    assert not (tmp_path / "e.h5").exists()
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


def test_sigkill_leaves_every_flushed_sample(virtual_krc4, tmp_path):
    srv, src = virtual_krc4()
    out = tmp_path / "killed.h5"
    proc = _child(out, srv.port)
    try:
        flushed = wait_for_samples(out, proc, 200)  # on disk, whatever the speed
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
    log = read_hdf5(out)
    assert log.n_samples >= flushed >= 200  # every sample flushed before the kill is kept
    _match_truth(log, src.truth())


def test_sigterm_stops_cleanly(virtual_krc4, tmp_path):
    srv, _ = virtual_krc4()
    out = tmp_path / "term.h5"
    proc = _child(out, srv.port, "ring")
    try:
        flushed = wait_for_samples(out, proc, 24)
        proc.send_signal(signal.SIGTERM)
        stdout, stderr = proc.communicate(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, stderr
    assert stdout.startswith("stopped_by signal")
    log = read_hdf5(out)
    assert log.attrs["stopped_by"] == "signal" and log.n_samples >= flushed >= 24


def test_serve_sim_subprocess_end_to_end(tmp_path, kukaid_cmd):
    """`kukaid serve-sim` in the background; capture through the protocol; compare with its truth."""
    from kukaid.excite import Trajectory

    ex = _excitation(60.0)  # longer than the capture takes to start on any machine
    traj = Trajectory(t=ex.t, q=ex.q, axis=3, kind="inertia")
    traj.to_json(tmp_path / "traj.json")
    truth = tmp_path / "truth.h5"
    server = subprocess.Popen([*kukaid_cmd, "serve-sim", "--port", "0", "--trajectory", str(tmp_path / "traj.json"),
                               "--duration", "120", "--seed", "5", "--truth", str(truth)],
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
        server.send_signal(signal.SIGTERM)  # stops cleanly and writes the truth
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


@pytest.mark.parametrize("ring, outage", [(RingLayout(axes=(3,)), 0.3), (RingLayout(axes=(3,), nb=2, bs=2), 0.5)])
def test_ring_mode_rides_out_an_outage_shorter_than_the_ring(virtual_krc4, tmp_path, ring, outage):
    """Unacknowledged blocks wait in the ring: a short outage loses nothing; a long one is a marked gap.

    The link drops at the 10th ring poll and the capture stops 20 polls after it is back.  Whether
    samples are lost depends on how long the ring went unread (the outage plus the reconnection,
    and any stall between polls of a loaded machine): measured, and compared with what it holds."""
    srv, src = virtual_krc4(ring=ring, count="KID_WR")
    stop = threading.Event()
    srv.reads.at(10, lambda: srv.go_down(outage)).at(31, stop.set)  # read 10 is lost, 11 is the first after
    s = capture_kvp(tmp_path / "ro.h5", "127.0.0.1", srv.port, [3], 60.0, False, "ring", None, reconnect_wait=5,
                    stop_event=stop)
    log = read_hdf5(tmp_path / "ro.h5")
    assert s["n_reconnects"] == 1 and s["stopped_by"] == "stop-event"
    t = np.asarray(srv.reads.times)
    away = t[10] - t[8]  # from the last poll acknowledged before the outage to the first after it
    assert away >= outage
    # the longest the ring went unread: the outage, or a stall of a loaded machine between polls
    worst = max(away, np.diff(t[:9]).max(), np.diff(t[10:]).max())
    holds = ring.nb * ring.bs * 0.012  # s of samples the ring keeps unacknowledged
    block = ring.bs * 0.012
    steps = np.round(np.diff(log.time) / 0.012).astype(int)
    gaps = np.asarray(log.attrs.get("gaps", []), dtype=float).reshape(-1, 2)
    if worst < holds - block - 0.03:  # always room for a whole block: nothing lost
        assert s["gaps"] == [] and s["ring_overflows"] == 0 and np.all(steps == 1)
    else:  # overflows are counted and every lost stretch is a marked gap
        assert (s["ring_overflows"] >= 1) == (len(gaps) >= 1) == bool(steps.max() > 1)
    if away > holds + 0.03:  # the outage overflowed the ring: its gap is the samples not kept
        assert s["ring_overflows"] >= 1
        assert (gaps[:, 1] - gaps[:, 0]).max() >= outage - holds - block - 0.012
    _match_truth(log, src.truth(), min_pair_fraction=1.0, q_tol_deg=5.1e-5, tau_tol=5.1e-4)


def test_cli_capture_says_when_the_ring_overflowed(virtual_krc4, tmp_path):
    """A ring capture whose PC read the ring too slowly (replies 50 ms late, a ring of 48 ms) lost
    samples and ended with only '... samples, ... s (kvp)', exit 0: the loss was first heard of when
    fit refused the log.  A warning line now says how many gaps and overflows there were."""
    from click.testing import CliRunner

    from kukaid_cli.main import cli

    srv, _ = virtual_krc4(ring=RingLayout(axes=(3,), nb=2, bs=2), count="KID_WR")
    srv.faults.delay = 0.05
    out = tmp_path / "ovf.h5"
    r = CliRunner().invoke(cli, ["capture", "-o", str(out), "--backend", "kvp", "--port", str(srv.port),
                                 "--mode", "ring", "--duration", "1.5"])
    assert r.exit_code == 0, r.output
    log = read_hdf5(out)
    assert log.attrs["ring_overflows"] > 0 and log.attrs["n_gaps"] > 0
    warn = [ln for ln in r.output.splitlines() if ln.startswith("kukaid: warning: capture:")]
    assert len(warn) == 1 and f"{log.attrs['n_gaps']} gap(s) in {out}" in warn[0], r.output
    assert f"the ring overflowed {log.attrs['ring_overflows']} times" in warn[0]


def test_rob_timer_is_read_across_its_rollover():
    """$ROB_TIMER rolls over after 2**31 ms (taken to restart at 0, as both capture modes assume);
    the capture's time goes on. Going back by more than 0.1 s otherwise is a restart of the controller."""
    from kukaid.krc.kvp_capture import _RobTimer

    clock = _RobTimer()
    raws = [2**31 - 24, 2**31 - 12, 0, 12]
    assert [clock(r) for r in raws] == [0.0, 12.0, 24.0, 36.0]
    clock = _RobTimer()
    assert [clock(r) for r in (1_002_000, 1_002_012, 1_001_950)] == [0.0, 12.0, -50.0]   # a sample read late
    with pytest.raises(ControllerError, match=r"went back by 0.950 s: it restarted"):
        clock(1_001_000)


def test_poll_keeps_each_controller_sample_once():
    """The rule of poll mode (`_NewSample`) on the clocks a controller may have."""
    from kukaid.krc.kvp_capture import _NewSample

    v = np.array([0.1, 5.0])
    w = np.array([0.2, 5.5])
    # $ROB_TIMER as the sample's stamp (the virtual KR C4): a standing axis repeats its values
    # exactly, and each new stamp seen by two polls in a row is a new sample
    ns = _NewSample(12)
    kept = [ns(ms, v, True) for ms in (0, 0, 0, 12, 12, 12, 24, 24)]
    assert kept == [True, False, False, False, True, False, False, True]
    # a sample arriving during a poll: old values under the new stamp are not a new sample; the
    # next poll, one sample throughout, records it
    ns = _NewSample(12)
    assert [ns(0, v, True), ns(12, v, True), ns(12, w, True), ns(12, w, True)] == [True, False, True, False]
    # ... nor is a poll during which it arrived (the new position with an old torque) once the clock is
    # known to stamp samples: only the next, whole one
    ns = _NewSample(12)
    mixed = np.array([0.2, 5.0])
    assert [ns(0, v, True), ns(0, v, True), ns(12, mixed, True), ns(12, w, True)] == [True, False, False, True]
    # a controller whose $ROB_TIMER runs every ms: a new sample is new values (or repeated ones
    # two cycles later)
    ns = _NewSample(12)
    kept = [ns(ms, v, True) for ms in range(0, 24)] + [ns(24, w, True), ns(25, w, True)]
    assert sum(kept) == 2 and kept[0] and kept[24] and not kept[25]
    # no controller clock (PC time, ms): the same, standing values once every two cycles
    ns = _NewSample(12)
    kept = [ns(float(ms), v, False) for ms in np.arange(0.0, 60.0, 0.5)]
    assert sum(kept) == 3


class _NoTimer:
    """A controller that does not answer $ROB_TIMER."""

    def __init__(self, source):
        self.source = source

    def read(self, name):
        return None if name.upper() == "$ROB_TIMER" else self.source.read(name)

    def write(self, name, value):
        return self.source.write(name, value)


def test_poll_without_controller_clock_drops_held_repeats(tmp_path, monkeypatch):
    """Polled every 2 ms of the capture's clock, a controller that gives a new 12 ms sample every sixth
    poll: both clocks are the test's (one poll moves the PC clock 2 ms; every sixth steps the
    simulator), so what is kept does not depend on how fast the machine is (a real-time simulator
    thread starved by a busy machine held its values for two cycles, and one repeat was kept)."""
    import kukaid.krc.kvp_capture as kc
    from kukaid.sim import SimConfig, VirtualKRC4

    clock = SimpleNamespace(t=0.0)
    monkeypatch.setattr(kc, "time", SimpleNamespace(monotonic=lambda: clock.t, time=lambda: clock.t))
    sim = VirtualKRC4(SimConfig().replace(noise_sigma=0.3), seed=11, axis=3)
    src = SimSource(sim, axis=3, trajectory=_excitation(8.0))

    def poll():
        clock.t += 0.002
        if reads.n % 6 == 0:
            src.step(0.012)
    reads = CountingSource(_NoTimer(src), step=poll)
    srv = KvpServer(reads, port=0).start()
    try:
        out = tmp_path / "pc.h5"
        s = capture_kvp(out, "127.0.0.1", srv.port, [3], 1.0, False, "poll", None)
    finally:
        srv.stop()
    log = read_hdf5(out)
    assert log.attrs["time_source"] == "pc-monotonic"
    # never a held repeat, and every sample once: 500 polls, a new sample every sixth
    assert held_share(log) == 0.0 and reads.n >= 500 and abs(log.n_samples - reads.n / 6) <= 1
    assert s["rate_hz"] < 2 / 0.012
    _match_truth(log, src.truth())
