"""The virtual KR C4's KUKAVARPROXY server: variables, clients, fault injection, ring-logger emulation."""
from __future__ import annotations

import math
import time

import numpy as np
import pytest

from kukaid.krc.krl_logger import RingLayout, parse_block, parse_config
from kukaid.krc.kvp import (KvpClient, KvpConnectionError, KvpProtocolError, KvpTimeoutError, KvpVariableError,
                           parse_e6axis)
from kukaid.krc.server import KvpServer, StaticSource
from kukaid.krc.sim_source import SimSource
from live_helpers import wait_sim, wait_until


@pytest.fixture
def static_server():
    src = StaticSource({"$OV_PRO": "100", "MYVAR": "{E6AXIS: A1 1, A2 2, A3 3, A4 4, A5 5, A6 6}"})
    srv = KvpServer(src, port=0).start()
    yield srv, src
    srv.stop()


def test_static_server_reads_writes_ping(static_server):
    srv, src = static_server
    assert srv.host == "127.0.0.1"
    with KvpClient("127.0.0.1", srv.port, timeout=2) as c:
        c.ping()
        assert c.read_int("$ov_pro") == 100  # KRL names are case-insensitive
        assert c.read_axis("MYVAR")["A6"] == 6.0
        with pytest.raises(KvpVariableError, match="empty"):
            c.read("$NOT_THERE")
        assert c.write("G_TARGET", "12.5") == "12.5"
        assert c.read_real("G_TARGET") == 12.5
    assert src.writes == [("G_TARGET", "12.5")]


def test_at_most_ten_clients(static_server):
    srv, _ = static_server
    clients = [KvpClient("127.0.0.1", srv.port, timeout=1) for _ in range(10)]
    try:
        for c in clients:
            c.connect()
            c.ping()
        extra = KvpClient("127.0.0.1", srv.port, timeout=1)
        with pytest.raises(KvpConnectionError):
            extra.connect()
            extra.ping()
        assert srv.n_refused >= 1
        clients[0].close()
        wait_until(lambda: srv.n_clients <= 9, "the server to see a client leave")
        extra.connect()
        extra.ping()  # a slot freed up
        extra.close()
    finally:
        for c in clients:
            c.close()


def test_faults_status_empty_garbage_drop_delay(static_server):
    srv, _ = static_server
    c = KvpClient("127.0.0.1", srv.port, timeout=5.0)  # an upper bound for prompt replies, even when loaded
    srv.faults.fail = {"$OV_PRO"}
    with pytest.raises(KvpVariableError, match="status 0"):
        c.read("$OV_PRO")
    srv.faults.fail = set()
    srv.faults.empty = {"$OV_PRO"}
    with pytest.raises(KvpVariableError, match="empty"):
        c.read("$OV_PRO")
    srv.faults.empty = set()
    srv.faults.garbage = 1
    with pytest.raises(KvpProtocolError):
        c.read("$OV_PRO")
    assert c.read("$OV_PRO") == "100"  # reconnected by the next call
    srv.faults.drop = 1
    with pytest.raises(KvpConnectionError, match="closed"):
        c.read("$OV_PRO")
    assert c.read("$OV_PRO") == "100"
    c.timeout = 0.3
    srv.faults.delay = 0.6  # the reply comes 0.6 s late at the earliest: a 0.3 s timeout expires first
    with pytest.raises(KvpTimeoutError):
        c.read("$OV_PRO")
    srv.faults.delay = 0.0
    c.timeout = 5.0
    srv.faults.split = True
    assert c.read("$OV_PRO") == "100"
    c.close()


def test_outage_and_reconnect_with_backoff(static_server):
    srv, _ = static_server
    c = KvpClient("127.0.0.1", srv.port, timeout=0.3, backoff=(0.02, 0.1))
    c.connect()
    srv.go_down(0.4)
    with pytest.raises(KvpConnectionError):
        c.read("$OV_PRO")
    t0 = time.monotonic()
    c.reconnect(max_wait=5.0)
    assert time.monotonic() - t0 >= 0.3
    assert c.read("$OV_PRO") == "100" and c.n_reconnects == 1
    srv.go_down(10.0)
    with pytest.raises(KvpConnectionError, match="could not reconnect within 0.3 s"):
        c.reconnect(max_wait=0.3)
    c.close()


# -- the virtual KR C4 ---------------------------------------------------------------------------
@pytest.fixture
def sim_source():
    from kukaid.sim import SimConfig, VirtualKRC4

    sim = VirtualKRC4(SimConfig().replace(noise_sigma=0.2), seed=3, axis=3)
    sim.reset(0.4)
    src = SimSource(sim, axis=3, ring=RingLayout(axes=(2, 3), nb=4, bs=4)).start()
    srv = KvpServer(src, port=0).start()
    yield srv, src
    srv.stop()
    src.stop()


def test_sim_serves_live_variables_and_targets(sim_source):
    srv, src = sim_source
    with KvpClient("127.0.0.1", srv.port, timeout=2) as c:
        ax = c.read_axis("$AXIS_ACT_MEAS")
        assert ax["A3"] == pytest.approx(math.degrees(0.4), abs=0.05)
        assert ax["A2"] == -90.0
        assert parse_e6axis(c.read("$AXIS_ACT"))["A3"] == pytest.approx(math.degrees(0.4), abs=0.05)
        tau = c.read_real("$TORQUE_AXIS_ACT[3]")
        assert abs(tau) < 200
        assert c.read_real("$TORQUE_AXIS_ACT[1]") == 0.0
        assert 280 < c.read_real("$MOT_TEMP[3]") < 400  # kelvin
        assert c.read_int("$OV_PRO") == 100
        t1 = c.read_int("$ROB_TIMER")
        with pytest.raises(KvpVariableError):
            c.write("$AXIS_ACT_MEAS", "{A1 0}")  # system variables are read-only
        with pytest.raises(KvpVariableError, match="empty"):
            c.read("$TORQUE_AXIS_ACT[9]")
        c.write("KID_TGT", "30.0")  # the virtual KRL program follows this global
        wait_sim(src, 0.6)  # simulated time: a loaded machine runs the simulator in bursts
        assert c.read_int("$ROB_TIMER") - t1 >= 500  # the controller's clock
        assert c.read_axis("$AXIS_ACT_MEAS")["A3"] == pytest.approx(30.0, abs=1.0)
    assert src.sim_time > 0.5 and src.error is None


def test_sim_emulates_the_ring_logger(sim_source):
    srv, src = sim_source
    with KvpClient("127.0.0.1", srv.port, timeout=2) as c:
        layout = parse_config(c.read_string("KID_CFG"))
        assert layout == RingLayout(axes=(2, 3), nb=4, bs=4)
        wait_sim(src, 0.45)  # 37 samples: ring full (4 blocks of 4), later blocks dropped
        wr = c.read_int("KID_WR")
        assert wr == 4 and c.read_int("KID_OVF") >= 1
        rows = np.vstack([parse_block(c.read_string(f"KID_B{k}"), k, layout) for k in range(1, 5)])
        assert rows.shape == (16, 7)
        assert np.all(np.diff(rows[:, 0]) == 12)  # $ROB_TIMER stamps, one per IPO cycle
        assert np.all(rows[:, 1] == -90.0)  # A2 stands
        truth = src.truth()
        k0 = int(np.argmin(np.abs(truth["time"] - src.t0_sim - (rows[0, 0] - 1_000_000) / 1000)))
        np.testing.assert_allclose(rows[:, 2], np.degrees(truth["q"][k0:k0 + 16]), atol=5e-5)
        np.testing.assert_allclose(rows[:, 4], truth["tau"][k0:k0 + 16], atol=5e-4)
        c.write("KID_RD", "4")
        wait_sim(src, 0.1)  # 8 samples: 2 more blocks
        assert c.read_int("KID_WR") > 4
        with pytest.raises(KvpVariableError):
            c.write("KID_WR", "0")  # only the logger writes it
    with pytest.raises(Exception, match="overwritten"):
        parse_block('5|1000,1.0,2.0,3.0,4.0,5.0,6.0;', 1, layout)


def test_server_survives_garbage_from_a_client(static_server):
    import socket

    srv, _ = static_server
    for junk in (b"\xff" * 64, b"\x00\x01\x00\x03\x07\x00\x00", b"\x00\x01\x00\x05\x00\x00\x09AB"):
        s = socket.create_connection(("127.0.0.1", srv.port), timeout=2)
        s.sendall(junk)
        s.settimeout(2)
        try:
            assert s.recv(100) == b""  # the server hangs up on a client that does not speak the protocol
        except (ConnectionResetError, TimeoutError):
            pass
        s.close()
    with KvpClient("127.0.0.1", srv.port, timeout=2) as c:
        assert c.read("$OV_PRO") == "100"
