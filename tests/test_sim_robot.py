"""The six-axis virtual KR C4: truth physically consistent and away from nominal, servo, torque as measured."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

pin = pytest.importorskip("pinocchio")

from kukaid.models.urdf import load_model  # noqa: E402
from kukaid.sim.robot_plant import RobotSimConfig, VirtualRobotKRC4  # noqa: E402
from kukaid.sim.robot_truth import draw_truth, is_physical, nominal_pi  # noqa: E402
from robot_helpers import ROBOT, fourier_like  # noqa: E402


def test_truth_is_seeded_physical_and_away_from_nominal():
    model = load_model(ROBOT)
    a = draw_truth(ROBOT, model, seed=3)
    b = draw_truth(ROBOT, model, seed=3)
    c = draw_truth(ROBOT, model, seed=4)
    assert np.array_equal(a.pi, b.pi) and not np.allclose(a.pi, c.pi)
    assert all(is_physical(p) for p in a.pi)
    nom = nominal_pi(model)
    rel_mass = np.abs(a.pi[:, 0] / nom[:, 0] - 1)
    assert np.median(rel_mass) > 0.03  # seeded truth is not the URDF


def test_holds_still_and_measures_gravity():
    sim = VirtualRobotKRC4(RobotSimConfig(robot=ROBOT), seed=0)
    q0 = np.linspace(-0.3, 0.3, sim.n)
    sim.reset(q0)
    out = sim.advance(1.0)
    assert out["q"].shape == (250, sim.n) and out["tau"].shape == (250, sim.n)
    assert np.degrees(np.abs(out["q"] - q0)).max() < 0.05
    g = pin.computeGeneralizedGravity(sim.model, sim.model.createData(), q0) + sim.truth.offset
    assert np.allclose(out["tau"][-50:].mean(0), g, atol=4 * sim.noise_sigma.max() + 0.05)


def test_measured_torque_is_the_true_inverse_dynamics_while_moving():
    from scipy.signal import savgol_filter

    sim = VirtualRobotKRC4(RobotSimConfig(robot=ROBOT, noise_rel=0.0, quant_deg=0.0), seed=0)
    traj = fourier_like(sim.n, 12.0)
    log = sim.run(traj, settle=0.0)
    dt = log.sample_time
    sg = dict(window_length=21, polyorder=5, axis=0)
    q, qd = savgol_filter(log.q, **sg), savgol_filter(log.q, deriv=1, delta=dt, **sg)
    qdd = savgol_filter(log.q, deriv=2, delta=dt, **sg)
    d = sim.model.createData()
    pred = np.array([pin.rnea(sim.model, d, q[i], qd[i], qdd[i]) for i in range(len(q))]) + sim.truth.friction(qd)
    sl = slice(50, -50)
    fast = np.all(np.abs(qd[sl]) > 0.05, axis=1)
    err = (pred - log.tau)[sl][fast]
    rel = np.linalg.norm(err, axis=0) / np.linalg.norm(log.tau[sl][fast], axis=0)
    assert rel.max() < 0.06, rel
    # and the servo tracks the command
    assert np.degrees(np.abs(log.q - log.q_cmd)).max() < 1.0


def test_coupled_wrist_friction_truth_is_the_motors_friction_seen_at_the_joints():
    """A truth whose wrist motors' friction is on their coupled velocities: the measured torque is the
    inverse dynamics plus ``(I + C)^T f((I + C) qd)``, not the per-joint friction; it round-trips
    through JSON."""
    from dataclasses import replace

    from scipy.signal import savgol_filter

    from kukaid.sim.robot_truth import RobotTruth

    cfg = RobotSimConfig(robot=ROBOT, noise_rel=0.0, quant_deg=0.0)
    C = np.zeros((6, 6))
    C[4, 3], C[5, 3], C[5, 4] = 0.35, -0.3, 0.45
    truth = replace(draw_truth(ROBOT, load_model(ROBOT), seed=2), friction_coupling=C)
    assert np.array_equal(RobotTruth.from_dict(truth.to_dict()).friction_coupling, C)
    sim = VirtualRobotKRC4(cfg, seed=0, truth=truth)
    log = sim.run(fourier_like(sim.n, 12.0), settle=0.0)
    dt = log.sample_time
    sg = dict(window_length=21, polyorder=5, axis=0)
    q, qd = savgol_filter(log.q, **sg), savgol_filter(log.q, deriv=1, delta=dt, **sg)
    qdd = savgol_filter(log.q, deriv=2, delta=dt, **sg)
    d = sim.model.createData()
    rnea = np.array([pin.rnea(sim.model, d, q[i], qd[i], qdd[i]) for i in range(len(q))])
    sl = slice(50, -50)
    mix = np.eye(6) + C
    fast = np.all(np.abs((qd @ mix.T)[sl]) > 0.05, axis=1)

    def rel(pred):
        err = (pred - log.tau)[sl][fast]
        return np.linalg.norm(err, axis=0) / np.linalg.norm(log.tau[sl][fast], axis=0)
    coupled = rel(rnea + truth.friction(qd))
    per_joint = rel(rnea + replace(truth, friction_coupling=None).friction(qd))
    assert coupled.max() < 0.06, coupled
    assert per_joint[3] > 3 * coupled[3], (per_joint, coupled)      # A4 feels motors 5 and 6


def test_an_elastic_gear_lags_its_link_and_needs_a_fast_servo():
    """A2's gear a spring (3e4 N·m/rad): at 1 kHz the velocity loop on the motor alone is refused;
    at 5 kHz the robot holds still with its link hanging back by the gravity torque over the
    stiffness (the encoder on the motor) and follows a trajectory, finite and near the rigid one."""
    from dataclasses import replace

    from kukaid.errors import SimConfigError

    k = 3e4
    K, D = np.zeros(6), np.zeros(6)
    truth = draw_truth(ROBOT, load_model(ROBOT), seed=2)
    K[1], D[1] = k, 2 * 0.1 * np.sqrt(k * truth.armature[1])
    elastic = replace(truth, gear_stiffness=K, gear_damping=D)
    with pytest.raises(SimConfigError, match="servo_rate"):
        VirtualRobotKRC4(RobotSimConfig(robot=ROBOT), seed=0, truth=elastic)
    cfg = RobotSimConfig(robot=ROBOT, servo_rate=5000.0, noise_rel=0.0)
    sim = VirtualRobotKRC4(cfg, seed=0, truth=elastic)
    q0 = np.array([0.2, -1.0, 0.9, 0.0, 0.5, 0.0])
    sim.reset(q0)
    out = sim.advance(1.0)
    g = pin.computeGeneralizedGravity(sim.model, sim.model.createData(), sim._ql)
    assert np.isfinite(out["tau"]).all() and abs(sim.q[1] - q0[1]) < 1e-3
    assert sim._q[1] - sim._ql[1] == pytest.approx(g[1] / k, rel=0.02)
    assert out["tau"][-50:, 1].mean() == pytest.approx(g[1] + truth.offset[1], abs=0.05)
    rigid = VirtualRobotKRC4(cfg, seed=0, truth=truth).run(fourier_like(6, 6.0), settle=0.0)
    log = sim.run(fourier_like(6, 6.0), settle=0.0)
    diff = np.sqrt(np.mean((log.tau - rigid.tau) ** 2, axis=0))
    assert 0.05 < diff[1] < 3.0 and np.all(np.abs(log.q - rigid.q) < 0.01), diff


def test_one_axis_trajectory_keeps_the_other_axes_locked():
    sim = VirtualRobotKRC4(RobotSimConfig(robot=ROBOT), seed=1)
    t = np.arange(0, 4.0, 0.012)
    traj = SimpleNamespace(t=t, q=0.4 * (1 - np.cos(np.pi * t / 4.0)), axis=2, kind="custom")
    log = sim.run(traj, settle=0.2)
    moved = np.ptp(log.q, axis=0)
    assert moved[1] > 0.7
    assert np.degrees(np.delete(moved, 1)).max() < 0.1


def test_external_torque_shows_in_the_measured_torque_with_the_papers_sign():
    sim = VirtualRobotKRC4(RobotSimConfig(robot=ROBOT, noise_rel=0.0), seed=0)
    q0 = np.zeros(sim.n)
    sim.reset(q0)
    base = sim.advance(1.0)["tau"][-25:].mean(0)
    ext = np.zeros(sim.n)
    ext[1] = 5.0
    sim.set_external_torque(ext)
    out = sim.advance(6.0)
    assert np.allclose(out["tau_ext_true"][-1], ext)
    # the servo holds the position: the drive now delivers 5 N·m less on A2
    assert out["tau"][-25:, 1].mean() - base[1] == pytest.approx(-5.0, abs=0.2)


def test_same_seed_same_log_and_chunking_does_not_matter():
    cfg = RobotSimConfig(robot=ROBOT)
    a = VirtualRobotKRC4(cfg, seed=5)
    b = VirtualRobotKRC4(cfg, seed=5)
    traj = fourier_like(a.n, 2.0)
    for s in (a, b):
        s.reset(traj.q[0])
        s.follow(traj)
    x = a.advance(2.0)
    y = [b.advance(0.7), b.advance(1.3)]
    assert np.array_equal(x["q"], np.concatenate([p["q"] for p in y]))
    assert np.array_equal(x["time"], np.concatenate([p["time"] for p in y]))


def test_bad_config_is_one_clear_error():
    from kukaid.errors import SimConfigError

    with pytest.raises(SimConfigError, match="field 'Kv'"):
        RobotSimConfig(Kv=-1)
    with pytest.raises(SimConfigError, match="unknown field 'bogus'"):
        RobotSimConfig.from_dict({"bogus": 1})


def test_gear_ratios_are_read_from_the_urdf_transmissions():
    from kukaid.models.urdf import gear_ratios

    model = load_model(ROBOT)
    r = gear_ratios(ROBOT, tuple(model.names[1:]))
    assert r.shape == (model.nv,) and np.all(r > 0)
    if ROBOT == "kr6-r700-sixx":  # its transmissions (and a comment with "--" that XML parsers refuse)
        assert np.allclose(r, [121, 153, 121, 81, 81, 51])


def test_an_inertia_carried_with_the_joint_is_in_the_dynamics_and_in_the_true_external_torque():
    """``fn.inertia()`` (a hand moving with A3): the drive accelerates it too, and the hand's true
    torque on the link is its reaction -I qdd, so the measured torque changes by minus that."""
    t = np.arange(0, 3.0, 0.012)
    traj = SimpleNamespace(t=t, q=0.3 * (1 - np.cos(2 * np.pi * t / 1.5)), axis=3, kind="custom")

    def ext(tt, q, qd):
        return np.zeros(q.size)

    ext.inertia = lambda: np.array([0.0, 0.0, 1.2, 0.0, 0.0, 0.0])
    logs = []
    for fn in (None, ext):
        sim = VirtualRobotKRC4(RobotSimConfig(robot=ROBOT, noise_rel=0.0), seed=0)
        if fn is not None:
            sim.set_external_torque(fn)
        logs.append(sim.run(traj, settle=0.2))
    bare, hand = logs
    te = hand.tau_ext_true[:, 2]
    qdd_ref = 0.3 * (2 * np.pi / 1.5) ** 2 * np.cos(2 * np.pi * hand.time / 1.5)
    mid = (hand.time > 0.3) & (hand.time < 2.7)

    def rms(x):
        return float(np.sqrt(np.mean(x[mid] ** 2)))
    # (apart from short transients where the velocity reverses through Coulomb friction)
    assert rms(te + 1.2 * qdd_ref) < 0.25 * rms(1.2 * qdd_ref)      # the hand's reaction -I qdd
    assert rms(hand.tau[:, 2] - bare.tau[:, 2] + te) < 0.2 * rms(te)  # which the drive supplies
    assert np.allclose(np.delete(hand.tau_ext_true, 2, axis=1), 0.0)
