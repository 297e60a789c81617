"""A robot file's thermal friction in the form the diagnosis writes (``coulomb_viscous``: the
Coulomb and the viscous friction each changing with temperature, two coefficients) and the forms
of files from before (one coefficient)."""
import numpy as np
import pytest

from kukaid.models import robot_effects as RE
from kukaid.params import robot as P


def _signals(N=50, n=6, seed=0):
    rng = np.random.default_rng(seed)
    z = np.zeros((N, n))
    qd = rng.normal(size=(N, n))
    return RE.EffectSignals(q=z, sign=np.tanh(qd / 0.01), friction=2.0 * np.tanh(qd / 0.01) + 0.5 * qd,
                            gravity=z, rigid=z, payload=np.zeros((N, n, 4)), temp=30.0 + rng.uniform(0, 20, (N, n)),
                            qd=qd)


def test_coulomb_viscous_columns_and_torque():
    s = _signals()
    spec = {"form": "coulomb_viscous", "coefficients": [-0.02, -0.005]}
    B = RE.columns("thermal_friction@A3", spec, s)
    assert B.shape == (50, 2)
    np.testing.assert_allclose(B[:, 0], s.temp[:, 2] * s.sign[:, 2])
    np.testing.assert_allclose(B[:, 1], s.temp[:, 2] * s.qd[:, 2])
    tau = RE.torque({"thermal_friction@A3": spec}, s)
    np.testing.assert_allclose(tau[:, 2], B @ np.array([-0.02, -0.005]))
    assert not np.any(tau[:, [0, 1, 3, 4, 5]])
    # the old forms: one coefficient
    assert RE.columns("thermal_friction@A3", {"form": "friction"}, s).shape == (50, 1)
    assert RE.n_coefficients("thermal_friction", spec) == 2
    assert RE.n_coefficients("thermal_friction", {"form": "coulomb"}) == 1


def test_coulomb_viscous_in_a_file_is_validated_with_two_coefficients():
    P._effects("f.json", {"thermal_friction@A2": {"form": "coulomb_viscous", "coefficients": [-0.02, -0.005]}}, 6)
    P._effects("f.json", {"thermal_friction@A2": {"form": "coulomb", "coefficients": [-0.02]}}, 6)
    with pytest.raises(Exception, match="coefficients"):
        P._effects("f.json", {"thermal_friction@A2": {"form": "coulomb_viscous", "coefficients": [-0.02]}}, 6)
    with pytest.raises(Exception, match="form"):
        P._effects("f.json", {"thermal_friction@A2": {"form": "viscous", "coefficients": [-0.02]}}, 6)
