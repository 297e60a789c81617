"""The vector torque residual on the six-axis virtual KR C4 with a known external torque."""
from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("pinocchio")

from kukaid.control.robot_residual import RobotResidual, RobotTorqueModel, robot_residual  # noqa: E402
from kukaid.excite.fourier import fourier  # noqa: E402
from kukaid.sim.robot_plant import RobotSimConfig, VirtualRobotKRC4  # noqa: E402
from robot_helpers import ROBOT  # noqa: E402

PUSH = 5.0  # N·m on A2, from 4 s to 8 s


@pytest.fixture(scope="module")
def run():
    traj = fourier(ROBOT, harmonics=3, period=6.0, periods=2, iterations=0, starts=1)
    sim = VirtualRobotKRC4(RobotSimConfig(robot=ROBOT), seed=2)
    sim.reset(sim.start_position(traj))
    sim.follow(traj)
    ext = np.zeros(sim.n)
    ext[1] = PUSH
    parts = [sim.advance(4.0)]
    sim.set_external_torque(ext)
    parts.append(sim.advance(4.0))
    sim.set_external_torque(np.zeros(sim.n))
    parts.append(sim.advance(4.0))
    d = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    return sim, d


def test_residual_of_every_axis_is_the_external_torque(run):
    sim, d = run
    model = RobotTorqueModel.from_truth(sim.truth.to_dict())
    r = robot_residual(d["q"], d["tau"], model, sim.cfg.sample_time, threshold=2.0)["gamma_r"]
    t = d["time"]
    push, quiet = (t > 4.5) & (t < 8.0), ((t > 1.0) & (t < 4.0)) | (t > 8.5)
    assert r[push, 1].mean() == pytest.approx(PUSH, abs=0.5)  # the paper's sign: Γr = +push
    assert np.abs(r[quiet].mean(axis=0)).max() < 0.3
    assert np.abs(np.delete(r[push], 1, axis=1).mean(axis=0)).max() < 0.3
    # detection with hysteresis on A2 only
    det = robot_residual(d["q"], d["tau"], model, sim.cfg.sample_time, threshold=2.5)["detected"]
    assert det[push, 1].mean() > 0.9 and det[quiet].mean() < 0.02


def test_the_other_axes_motion_matters(run):
    """Ignoring the others' motion (an axis seen alone, as the one-axis model) leaves a large residual."""
    sim, d = run
    model = RobotTorqueModel.from_truth(sim.truth.to_dict())
    t = d["time"]
    quiet = (t > 1.0) & (t < 4.0)
    full = robot_residual(d["q"], d["tau"], model, sim.cfg.sample_time)["gamma_r"][quiet, 1]

    class Alone(RobotTorqueModel):
        def __call__(self, q, qd, qdd):  # A2's view: the other joints' velocities and accelerations unknown
            keep = np.zeros_like(qd)
            keep[1] = 1.0
            return super().__call__(q, qd * keep, qdd * keep)

    alone = Alone.from_truth(sim.truth.to_dict())
    part = robot_residual(d["q"], d["tau"], alone, sim.cfg.sample_time)["gamma_r"][quiet, 1]
    rms = lambda x: float(np.sqrt(np.mean(x ** 2)))  # noqa: E731
    assert rms(part) > 3 * rms(full)


def test_params_file_and_truth_predict_the_same(run):
    sim, _ = run
    tr = sim.truth.to_dict()
    n = sim.n
    params = {"schema": "kukaid.robot_params/1", "robot": {"urdf": ROBOT}, "axes": list(range(1, n + 1)),
              "base_parameters": {"independent": list(range(10 * n)), "values": np.ravel(tr["pi"]).tolist()},
              "friction": {"model": "coulomb-viscous", "values": {
                  **{f"A{j + 1}.Fc": tr["friction"]["Fc"][j] for j in range(n)},
                  **{f"A{j + 1}.Fv": tr["friction"]["Fv"][j] for j in range(n)},
                  **{f"A{j + 1}.offset": tr["offset"][j] for j in range(n)},
                  **{f"M{j + 1}.rotor_inertia": tr["armature"][j] for j in range(n)}}},
              "drive": {"ratio": [1.0] * n, "coupling": np.zeros((n, n)).tolist()}}
    a, b = RobotTorqueModel.from_params(params), RobotTorqueModel.from_truth(tr)
    rng = np.random.default_rng(0)
    for _ in range(5):
        q, qd, qdd = rng.normal(size=(3, n))
        np.testing.assert_allclose(a(q, qd, qdd), b(q, qd, qdd), rtol=1e-9, atol=1e-9)


def test_bad_input_is_a_clear_error(run):
    from kukaid.errors import KukaidError, ParamFileError

    sim, _ = run
    res = RobotResidual(RobotTorqueModel.from_truth(sim.truth.to_dict()), sample_time=0.004)
    with pytest.raises(KukaidError, match="expected 6 positions"):
        res.update(np.zeros(3), np.zeros(3))
    with pytest.raises(ParamFileError, match="robot_params/1"):
        RobotTorqueModel.from_params({"robot": {"urdf": ROBOT}})


def test_base_parameters_with_their_dependency_predict_as_the_regressor():
    """A fitted file's base parameters (β = π[ind] + R π[dep]) give the same torques by RNEA."""
    from kukaid.excite.fourier import RegressorCondition
    from kukaid.models.urdf import load_model
    from scipy.linalg import qr, solve_triangular

    model = load_model(ROBOT)
    rc = RegressorCondition(model)
    rng = np.random.default_rng(1)
    n = model.nv
    W = rc.regressor(rng.uniform(-1, 1, (60, n)), rng.normal(size=(60, n)), rng.normal(size=(60, n)))[:, :10 * n]
    _, Rq, piv = qr(W, mode="economic", pivoting=True)
    r = int(np.sum(np.abs(np.diag(Rq)) > 1e-8 * abs(Rq[0, 0]) * W.shape[0]))
    ind, dep = piv[:r], piv[r:]
    R = solve_triangular(Rq[:r, :r], Rq[:r, r:])
    beta = rng.normal(size=r)
    fast = RobotTorqueModel(model, base=(ind, beta), dependent=(dep, R))
    slow = RobotTorqueModel(model, base=(ind, beta))
    assert fast.base is None and slow.base is not None  # RNEA and regressor paths
    for _ in range(5):
        q, qd, qdd = rng.normal(size=(3, n))
        np.testing.assert_allclose(fast(q, qd, qdd), slow(q, qd, qdd), rtol=1e-7, atol=1e-7)


def test_coupled_wrist_drives_and_motor_side_torques():
    """Drives with a coupled wrist, torques logged on the motor side: converted back with G^T, the
    residual of every axis is again the external torque."""
    n = 6
    C = np.zeros((n, n))
    C[4, 3], C[5, 3], C[5, 4] = 0.2, -0.1, 0.15  # the A5 and A6 motors also turn with A4 (and A6 with A5)
    cfg = RobotSimConfig(robot=ROBOT, torque_side="motor", coupling=C.tolist())
    sim = VirtualRobotKRC4(cfg, seed=3)
    traj = fourier(ROBOT, harmonics=2, period=4.0, periods=2, iterations=0, starts=1)
    sim.reset(sim.start_position(traj))
    sim.follow(traj)
    ext = np.zeros(n)
    ext[4] = 1.0  # on A5, whose motor is coupled
    parts = [sim.advance(3.0)]
    sim.set_external_torque(ext)
    parts.append(sim.advance(3.0))
    d = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    truth = sim.log_attrs()["truth"]
    assert truth["drive"]["torque_side"] == "motor" and np.allclose(truth["drive"]["coupling"], C)
    G = np.diag(truth["drive"]["ratio"]) @ (np.eye(n) + C)
    assert np.abs(d["tau"] - d["tau"] @ G).max() > 1.0  # motor side: not the joint torques
    r = robot_residual(d["q"], d["tau"], RobotTorqueModel.from_truth(truth), sim.cfg.sample_time,
                       torque_side="motor", drive_G=G)["gamma_r"]
    t = d["time"]
    quiet, push = (t > 0.5) & (t < 3.0), t > 3.5
    assert r[push, 4].mean() == pytest.approx(1.0, abs=0.15)
    assert np.abs(r[quiet].mean(axis=0)).max() < 0.15
