"""The virtual KR C4's API: reproducibility (acceptance (d)), measurement, inputs, log attributes."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from kukaid.errors import KukaidError
from kukaid.logs import read_hdf5, write_hdf5
from kukaid.sim import SimConfig, VirtualKRC4
from sim_helpers import Builder


def _traj():
    return Builder(0.1).hold(0.2).move(0.2, 0.5).hold(0.3).move(-0.1, 0.3).hold(0.2).build()


def _same(a, b):
    for name in ("time", "q", "tau", "q_cmd", "temp", "tau_ext_true"):
        x, y = getattr(a, name), getattr(b, name)
        if x.shape != y.shape or x.tobytes() != y.tobytes():
            return False
    return True


def test_d_same_seed_same_log_bit_for_bit(tmp_path):
    cfg = SimConfig(jitter=0.002, effects={"backlash": {"A": 1.0}})
    a = VirtualKRC4(cfg, seed=7).run(_traj())
    b = VirtualKRC4(cfg, seed=7).run(_traj())
    assert _same(a, b)
    assert json.dumps(a.attrs, sort_keys=True) == json.dumps(b.attrs, sort_keys=True)
    write_hdf5(a, tmp_path / "a.h5")
    write_hdf5(b, tmp_path / "b.h5")
    assert _same(read_hdf5(tmp_path / "a.h5"), read_hdf5(tmp_path / "b.h5"))
    c = VirtualKRC4(cfg, seed=8).run(_traj())
    assert not np.array_equal(a.tau, c.tau)
    assert not np.array_equal(a.time, c.time)  # jitter differs too


def test_chunking_does_not_change_the_result():
    cfg = SimConfig(jitter=0.004)
    s1 = VirtualKRC4(cfg, seed=3)
    s1.follow(_traj())
    one = s1.advance(2.0)
    s2 = VirtualKRC4(cfg, seed=3)
    s2.follow(_traj())
    parts = [s2.advance(d) for d in (0.5, 0.013, 0.987, 0.5)]
    two = {k: np.concatenate([p[k] for p in parts]) for k in one}
    for k in one:
        assert one[k].tobytes() == two[k].tobytes(), k


def test_measurement_like_the_krc():
    cfg = SimConfig(noise_sigma=0.3)
    sim = VirtualKRC4(cfg, seed=1)
    log = sim.run(_traj())
    t = log.time
    np.testing.assert_allclose(np.diff(t), 0.012, atol=1e-12)
    qdeg = np.degrees(log.q[:, 0]) / 1e-4
    np.testing.assert_allclose(qdeg, np.round(qdeg), atol=1e-6)  # 1e-4 degree resolution
    # tracking: small error against the commanded trajectory
    assert np.max(np.abs(log.q[:, 0] - log.q_cmd[:, 0])) < 2e-3
    # the noise: standing still at the end, torque spread ~ sigma (plus tiny friction swing)
    assert log.attrs["source"] == "virtual-krc4"
    assert log.attrs["seed"] == 1
    assert log.attrs["experiment"] == "friction"
    assert log.attrs["truth"]["schema"] == "kukaid.params/1"
    assert log.attrs["truth"]["friction"]["Fc"] == cfg.Fc
    assert log.attrs["sample_time"] == 0.012
    assert np.all(log.tau_ext_true == 0.0)


def test_jitter_keeps_time_increasing():
    cfg = SimConfig(jitter=0.003)
    b = VirtualKRC4(cfg, seed=4).advance(1.0)
    dt = np.diff(b["time"])
    assert np.all(dt > 0) and dt.min() < 0.012 < dt.max()
    assert np.all(np.abs(b["time"] - 0.012 * np.arange(1, b["time"].size + 1)) <= 0.003 + 1e-3)


def test_external_torque_sign_and_truth():
    """A push on the link: Γr = Γp - Γm equals tau_ext, sliding and standing."""
    from kukaid.models.friction import MaxwellSlip

    cfg = SimConfig(noise_sigma=0.0, vibration=False, quant_deg=0.0)
    tr = Builder(0.2).move(0.3, 2.0).build()
    ref = VirtualKRC4(cfg, seed=0).run(tr, settle=0.0)
    sim = VirtualKRC4(cfg, seed=0)
    sim.set_external_torque(5.0)
    log = sim.run(tr, settle=0.0)
    assert np.all(log.tau_ext_true == 5.0)
    plateau = (log.time > 1.0) & (log.time < 2.2)
    np.testing.assert_allclose(log.tau[plateau, 0] - ref.tau[plateau, 0], -5.0, atol=0.05)
    # standing: the servo holds the axis; friction memory (Maxwell-slip) takes part of the push,
    # and the paper's quasi-static prediction Mx cos q + Fp(q) minus the measured torque is tau_ext
    sim = VirtualKRC4(cfg, seed=0)
    sim.reset(0.2)
    sim.set_external_torque(5.0)
    b = sim.advance(1.0)
    assert abs(b["q"][-1] - 0.2) < 1e-3
    ms = MaxwellSlip(cfg.ms_k, cfg.ms_W)
    q = np.concatenate([[0.2], b["q"]])
    Fp, _ = ms.simulate(q, 0.2 + np.asarray(cfg.ms_zeta0))
    resid = cfg.Mx * np.cos(b["q"]) + Fp[1:] - b["tau"]
    assert resid[-1] == pytest.approx(5.0, abs=0.1)
    # a function of (t, q, qd), evaluated once per 12 ms
    sim.set_external_torque(lambda t, q, qd: 2.0 if t > 1.5 else 0.0)
    c = sim.advance(1.0)
    assert c["tau_ext_true"][0] == 0.0 and c["tau_ext_true"][-1] == 2.0


def test_command_streaming_and_read():
    cfg = SimConfig(noise_sigma=0.0, vibration=False)
    sim = VirtualKRC4(cfg, seed=0)
    sim.reset(0.0)
    for i in range(1, 51):
        sim.command(0.002 * i)  # 0.1 rad in 50 steps of 24 ms
        sim.advance(0.024)
    sim.advance(0.5)
    m = sim.read()
    assert set(m) == {"q", "tau", "temp"}
    assert m["q"] == pytest.approx(0.1, abs=2e-4)
    assert sim.t == pytest.approx(50 * 0.024 + 0.5)
    assert m["tau"] == pytest.approx(cfg.Mx * math.cos(0.1), abs=cfg.sum_W + 1)


def test_torque_limit():
    cfg = SimConfig(tau_max=30.0, noise_sigma=0.0)
    b = Builder(0.0).move(2.0, 0.3, ramp=0.05).build()  # far too aggressive for 30 N·m
    log = VirtualKRC4(cfg, seed=0).run(b)
    assert np.max(np.abs(log.tau)) <= 30.0 + 1e-12


def test_bad_inputs():
    sim = VirtualKRC4(SimConfig(), seed=0)
    with pytest.raises(KukaidError, match="duration"):
        sim.advance(-1.0)
    with pytest.raises(KukaidError, match="finite"):
        sim.command(float("nan"))
    with pytest.raises(KukaidError, match="strictly increasing"):
        sim.follow(type("T", (), {"t": np.array([0.0, 0.0, 0.1]), "q": np.zeros(3)})())


def test_run_uses_excite_trajectory_when_available():
    excite = pytest.importorskip("kukaid.excite")
    try:
        traj = excite.presliding()
    except Exception as e:  # another engineer's module in progress
        pytest.skip(f"kukaid.excite.presliding not usable: {e}")
    log = VirtualKRC4(SimConfig(), seed=0).run(traj)
    assert log.attrs["experiment"] == traj.kind
    assert log.n_samples > 0.9 * (traj.t[-1] - traj.t[0]) / 0.012


def test_pure_python_kernel_matches_compiled():
    """The kernel runs unchanged without numba (fallback) and gives the same numbers."""
    from kukaid.sim import kernel

    cfg = SimConfig(effects={"backlash": {"A": 1.0}, "position_ripple": {"A": 0.5}})
    a = VirtualKRC4(cfg, seed=9)
    b = VirtualKRC4(cfg, seed=9)
    b._kernel = kernel.servo_block
    tr = Builder(0.0).move(0.2, 0.05, ramp=0.1).build()
    a.follow(tr)
    b.follow(tr)
    x, y = a.advance(0.3), b.advance(0.3)
    for k in x:
        np.testing.assert_allclose(x[k], y[k], rtol=0, atol=1e-9)


def test_many_short_advances_do_not_drift():
    sim = VirtualKRC4(SimConfig(), seed=0)
    n = 0
    for _ in range(1000):
        n += sim.advance(0.0004)["time"].size
    assert sim.t == pytest.approx(0.4, abs=1e-3)
    assert n == 33


def test_streamed_setpoints_give_a_continuous_reference_velocity():
    cfg = SimConfig(noise_sigma=0.0, vibration=False)
    sim = VirtualKRC4(cfg, seed=0)
    sim.reset(0.0)
    qc = []
    for i in range(1, 41):
        sim.command(0.1 * 0.024 * i)  # 0.1 rad/s, one setpoint per 24 ms
        qc.append(sim.advance(0.024)["q_cmd"])
    qc = np.concatenate(qc)
    v = np.diff(qc) / 0.012
    np.testing.assert_allclose(v[4:], 0.1, rtol=1e-6)  # no stop-and-go between setpoints
