"""The robot diagnosis' coupled wrist friction (issue 23): the friction of a KUKA wrist's motors 5
and 6 on their coupled velocities is named on logs that have it, its coupling ratios recovered;
nothing named on clean logs of the same robot; the refined file predicts with it."""
from __future__ import annotations

import numpy as np
import pytest

from kukaid.diagnose.robot import diagnose_robot
from kukaid.identify.robot_fit import fit_robot, predict_robot
from kukaid.logs import AxisLog
from kukaid.models.robot import RobotModel
from kukaid.models import robot_effects as RE

from robot_sim_helpers import multisine, true_friction, true_parameters

#: the test's coupling ratios (joint units; off the candidate's grids) and the wrist motors' friction
COUPLING = {"c54": 0.27, "c64": -0.33, "c65": 0.46}
MOTOR_FC, MOTOR_FV = np.array([1.1, 0.7]), np.array([0.9, 0.5])


@pytest.fixture(scope="module")
def kr6() -> RobotModel:
    return RobotModel("kr6-r700-sixx")


def _logs(kr6, coupled: bool):
    """Four recordings (each its own multi-sine, 10 s at 250 Hz); A5 and A6's friction is their
    motors' on the coupled velocities (``coupled``) or on their own joints' (clean)."""
    pi, fr = true_parameters(kr6, 1), true_friction(6, 2)
    mix = RE.wrist_mix(6, COUPLING if coupled else {"c54": 0.0, "c64": 0.0, "c65": 0.0})
    out = []
    for k in range(4):
        t, q, qd, qdd = multisine(kr6, 10.0, 250.0, seed=60 + k)
        tau = np.einsum("sjk,k->sj", kr6.regressor(q, qd, qdd), pi) + fr["offset"]
        tau[:, :4] += fr["Fc"][:4] * np.sign(qd[:, :4]) + fr["Fv"][:4] * qd[:, :4]
        vm = qd @ mix.T
        tau += (MOTOR_FC * np.tanh(vm / 0.002) + MOTOR_FV * vm) @ mix
        rng = np.random.default_rng(k)
        tau += 0.02 * rng.standard_normal(tau.shape)
        out.append(AxisLog(time=t, q=q + 1e-5 * rng.standard_normal(q.shape), tau=tau, axes=tuple(range(1, 7)),
                           attrs={"source_file": f"rec{k}.h5"}))
    return out


def test_coupled_wrist_friction_is_named_and_its_ratios_recovered(kr6):
    logs = _logs(kr6, True)
    d = diagnose_robot(fit_robot(logs[:1], kr6), logs, kr6, max_steps=1)
    assert d.names == ["coupled_wrist_friction"], d.lines()
    p = d.steps[0]["params"]
    for k, v in COUPLING.items():           # within 0.05 of the truth
        assert abs(p[k] - v) < 0.05, (k, p)
    assert d.steps[0]["mean_after"] < 0.7 * d.steps[0]["mean_before"]
    # the refined file carries it and predicts with it (kukaid validate's predictor)
    eff = d.params["effects"]["coupled_wrist_friction"]
    assert set(eff) >= {"c54", "c64", "c65", "v_smooth", "coefficients"} and len(eff["coefficients"]) == 4
    tau = predict_robot(d.params, logs[1], kr6)
    bare = predict_robot({**d.params, "effects": {}}, logs[1], kr6)
    assert not np.allclose(tau[4], bare[4])


def test_clean_wrist_names_nothing(kr6):
    logs = _logs(kr6, False)
    d = diagnose_robot(fit_robot(logs[:1], kr6), logs, kr6, max_steps=1)
    assert "coupled_wrist_friction" in {t["name"] for t in d.tried}
    assert d.names == [], d.lines()
