"""Six-axis capture: a fourier trajectory on the six-axis virtual KR C4, and over KUKAVARPROXY.

Driven by sample counts: the served simulator is advanced by the test, not by a clock.
"""
from __future__ import annotations

import threading

import numpy as np
import pytest
from click.testing import CliRunner

pytest.importorskip("pinocchio")

from kukaid.excite.fourier import fourier  # noqa: E402
from kukaid.krc.krl_logger import RingLayout  # noqa: E402
from kukaid.krc.kvp import KvpClient, parse_e6axis, parse_real  # noqa: E402
from kukaid.krc.server import KvpServer  # noqa: E402
from kukaid.krc.sim_source import SimSource  # noqa: E402
from kukaid.logs import read_hdf5  # noqa: E402
from kukaid.sim.robot_plant import RobotSimConfig, VirtualRobotKRC4  # noqa: E402
from kukaid_cli.main import cli  # noqa: E402
from robot_helpers import ROBOT  # noqa: E402

FAST = dict(harmonics=2, period=4.0, periods=1, iterations=0, starts=1)


@pytest.fixture(scope="module")
def traj():
    return fourier(ROBOT, **FAST)


@pytest.fixture(scope="module")
def traj_file(traj, tmp_path_factory):
    p = tmp_path_factory.mktemp("f") / "fourier.json"
    traj.to_json(p)
    return p


def test_capture_of_a_fourier_trajectory_is_a_six_axis_log_with_its_truth(traj, traj_file, tmp_path):
    out = tmp_path / "c.h5"
    r = CliRunner().invoke(cli, ["capture", str(traj_file), "-o", str(out), "--seed", "3", "--settle", "0.2"])
    assert r.exit_code == 0, r.output
    log = read_hdf5(out)
    n = len(traj.axes)
    expected = int(round((traj.duration + 0.2) / 0.004))
    assert log.axes == traj.axes and log.n_samples == expected
    assert log.q.shape == log.tau.shape == log.q_cmd.shape == (expected, n)
    assert log.attrs["truth"]["schema"] == "kukaid.robot-truth/1" and len(log.attrs["truth"]["pi"]) == n
    assert log.attrs["seed"] == 3 and log.attrs["experiment"] == "fourier"
    # every axis moved as commanded (within a degree) and its torque is logged
    assert np.all(np.ptp(log.q, axis=0) > 0.1)
    assert np.degrees(np.abs(log.q - log.q_cmd)).max() < 1.0
    # same seed, same log
    out2 = tmp_path / "c2.h5"
    CliRunner().invoke(cli, ["capture", str(traj_file), "-o", str(out2), "--seed", "3", "--settle", "0.2"])
    assert np.array_equal(read_hdf5(out2).tau, log.tau)


def test_one_axis_options_are_refused_for_a_robot_trajectory(traj_file, tmp_path):
    r = CliRunner().invoke(cli, ["capture", str(traj_file), "-o", str(tmp_path / "c.h5"), "--noise", "0.1"])
    assert r.exit_code != 0 and "one-axis" in r.output and not (tmp_path / "c.h5").exists()


def _served(traj, ring=None):
    sim = VirtualRobotKRC4(RobotSimConfig(robot=ROBOT), seed=4)
    src = SimSource(sim, trajectory=traj, ring=ring)  # not started: the test advances it
    srv = KvpServer(src, port=0).start()
    return sim, src, srv


def test_served_variables_carry_every_axis(traj):
    sim, src, srv = _served(traj)
    try:
        src._ingest(sim.advance(1.0))
        last = src.truth()
        c = KvpClient("127.0.0.1", srv.port)
        c.connect()
        pos = parse_e6axis(c.read("$AXIS_ACT_MEAS"), "$AXIS_ACT_MEAS")
        tau = [parse_real(c.read(f"$TORQUE_AXIS_ACT[{a}]"), "tau") for a in sim.axes]
        c.close()
    finally:
        srv.stop()
    assert last["q"].shape == (3 + 250, sim.n)  # the source primes one IPO cycle (12 ms)
    np.testing.assert_allclose([pos[f"A{a}"] for a in sim.axes], np.degrees(last["q"][-1]), atol=1e-5)
    np.testing.assert_allclose(tau, last["tau"][-1], atol=1e-5)


def test_kvp_ring_capture_records_all_axes(traj, tmp_path):
    from kukaid.krc.kvp_capture import capture_kvp

    ring = RingLayout(axes=(1, 2, 3, 4, 5, 6), nb=8, bs=4)
    sim, src, srv = _served(traj, ring)
    out = tmp_path / "kvp.h5"
    stop = threading.Event()
    res: dict = {}
    th = threading.Thread(target=lambda: res.update(capture_kvp(out, "127.0.0.1", srv.port, range(1, 7), None, True,
                                                                "ring", stop_event=stop, ring_poll=0.002)))
    th.start()
    try:
        # wait (by request count) until the capture has taken the ring over, then feed 20 blocks
        for _ in range(5000):
            if srv.n_requests >= 4:
                break
            threading.Event().wait(0.002)
        for _ in range(20):  # a block of the program's samples: one per 12 ms interpolation cycle
            src._ingest(sim.advance(ring.bs * 0.012))
            for _ in range(5000):  # the consumer keeps up: every block handed back before the next
                if src.globals["KID_RD"] == src.globals["KID_WR"]:
                    break
                threading.Event().wait(0.002)
    finally:
        stop.set()
        th.join(10)
        srv.stop()
    log = read_hdf5(out)
    truth = src.truth()
    assert log.axes == (1, 2, 3, 4, 5, 6)
    k = log.n_samples
    assert k == 20 * ring.bs
    # the samples are the simulator's, in order, for every axis (ring text: 4 decimals deg, 3 N·m), one per
    # 12 ms interpolation cycle as the KRL program takes them: every third of the six-axis simulator's 4 ms
    # samples (trial 17: the emulation took all of them, where the program it emulates waits 12 ms)
    assert np.allclose(np.diff(log.time), 0.012, atol=1e-9), np.unique(np.round(np.diff(log.time), 4))
    assert round(0.012 / sim.cfg.sample_time) == 3
    q_ipo, tau_ipo = truth["q"][::3], truth["tau"][::3]
    first = int(np.argmin(np.abs(np.degrees(q_ipo) - np.degrees(log.q[0])).max(axis=1)))
    np.testing.assert_allclose(np.degrees(log.q), np.degrees(q_ipo[first:first + k]), atol=1e-4)
    np.testing.assert_allclose(log.tau, tau_ipo[first:first + k], atol=1e-3)


def test_serve_sim_refuses_one_axis_options_with_a_robot(traj_file, tmp_path):
    for extra in (["--axis", "2"], ["--q0", "10"], ["--noise", "0.1"], ["--operator", "push"]):
        r = CliRunner().invoke(cli, ["serve-sim", "--trajectory", str(traj_file), "--port", "0", "--duration", "0.01"]
                               + extra)
        assert r.exit_code != 0 and "one-axis simulator" in r.output, (extra, r.output)
    r = CliRunner().invoke(cli, ["serve-sim", "--robot", "no-such-robot", "--port", "0", "--duration", "0.01"])
    assert r.exit_code != 0 and "no-such-robot" in r.output and r.output.count("\n") <= 1


def test_a_robot_trajectory_without_stored_limits_is_checked_against_the_urdf(tmp_path):
    from kukaid.errors import LimitError
    from kukaid.capture import check_limits
    from kukaid.excite.fourier import RobotTrajectory

    t = np.arange(0, 2, 0.012)
    q = np.zeros((t.size, 6))
    q[:, 0] = 4.0 * np.sin(t)  # A1 beyond +-170 degrees
    with pytest.raises(LimitError, match="position limit of A1"):
        check_limits(RobotTrajectory(t=t, q=q, axes=range(1, 7), robot="kr6-r700-sixx"), "x.json")
    check_limits(RobotTrajectory(t=t, q=q * 0.1, axes=range(1, 7), robot="kr6-r700-sixx"), "x.json")


def test_kvp_poll_capture_records_all_axes(traj, tmp_path):
    """Poll mode: every controller sample once (no held repeats however fast the PC polls), every axis."""
    from kukaid.krc.kvp_capture import capture_kvp

    sim, src, srv = _served(traj)
    src._ingest(sim.advance(0.5))
    out = tmp_path / "poll.h5"
    stop = threading.Event()
    th = threading.Thread(target=lambda: capture_kvp(out, "127.0.0.1", srv.port, range(1, 7), None, True, "poll",
                                                     stop_event=stop))
    th.start()
    try:
        for _ in range(20):  # 20 controller cycles (12 ms), each polled several times before the next
            n = srv.n_requests
            for _ in range(5000):  # a poll: the position, $ROB_TIMER and six torques
                if srv.n_requests >= n + 4 * 8:
                    break
                threading.Event().wait(0.002)
            src._ingest(sim.advance(0.012))
    finally:
        stop.set()
        th.join(10)
        srv.stop()
    log = read_hdf5(out)
    truth = src.truth()
    assert log.axes == (1, 2, 3, 4, 5, 6) and 15 <= log.n_samples <= 61  # 20 cycles of three 4 ms samples
    # every row is one of the simulator's samples, on every axis, and none is repeated
    rows = np.hstack([np.degrees(truth["q"]), truth["tau"]])
    for row in np.hstack([np.degrees(log.q), log.tau]):
        assert np.min(np.max(np.abs(rows - row), axis=1)) < 1e-5  # one sample's position and torques
    logged = np.hstack([log.q, log.tau])
    assert np.all(np.any(np.diff(logged, axis=0) != 0, axis=1)) and np.all(np.diff(log.time) > 0)
