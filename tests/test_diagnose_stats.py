"""Diagnosis statistics on synthetic residuals: noise floor, HAC Wald tests under AR(1) noise,
multiple-testing correction, candidate columns."""
from __future__ import annotations

import numpy as np
import pytest

from kukaid.diagnose import candidates as C
from kukaid.diagnose import selection as S
from kukaid.diagnose.noise import raw_noise_sigma


def ar1_noise(rng, n, rho, sigma=1.0):
    e = rng.standard_normal(n) * sigma * np.sqrt(1 - rho**2)
    x = np.empty(n)
    x[0] = rng.standard_normal() * sigma
    for k in range(1, n):
        x[k] = rho * x[k - 1] + e[k]
    return x


def test_raw_noise_sigma_ignores_smooth_signal_and_jumps():
    rng = np.random.default_rng(1)
    t = np.arange(4000) * 0.012
    smooth = 20 * np.sin(2 * np.pi * 0.25 * t) + 15 * np.sign(np.sin(2 * np.pi * 0.1 * t))  # friction jumps
    for sigma in (0.07, 0.37, 1.3):
        est = raw_noise_sigma(smooth + sigma * rng.standard_normal(t.size))
        assert est == pytest.approx(sigma, rel=0.08)


def test_raw_noise_sigma_coarse_quantisation_does_not_return_zero():
    rng = np.random.default_rng(2)
    x = np.round(0.2 * rng.standard_normal(3000) / 0.5) * 0.5  # mostly zeros
    assert raw_noise_sigma(x) > 0


def smooth_regressors(rng, n):
    t = np.linspace(0, 1, n)
    return np.column_stack([np.sin(2 * np.pi * (1.3 + rng.random()) * t + rng.random()), t - 0.5])


@pytest.mark.parametrize("rho", [0.0, 0.5, 0.8, 0.9])
def test_hac_wald_false_alarm_rate_under_ar1(rho):
    """Under H0 (no effect) with correlated residuals the 5 % test rejects about 5 % (<= 10 %
    allowed for 300 trials and the small effective sample: at rho = 0.9, 600 rows hold about 30
    independent samples).  The workflow's rows (decimated to the filter bandwidth) are far less
    correlated than this."""
    rng = np.random.default_rng(int(rho * 100) + 3)
    n, trials, rej = 600, 300, 0
    groups = np.zeros(n, int)
    for _ in range(trials):
        J = np.column_stack([np.ones(n), np.linspace(-1, 1, n)])
        U = S.basis(J)
        Z = smooth_regressors(rng, n)[:, :1]
        r = ar1_noise(rng, n, rho)
        rej += S.wald_test(r, Z, groups, U).p_value < 0.05
    assert rej / trials <= 0.10, f"false-alarm rate {rej / trials:.3f} at rho={rho}"


def test_ols_would_fail_where_hac_holds():
    """The point of HAC: with rho = 0.9 a white-noise (L=0) test rejects far too often."""
    rng = np.random.default_rng(7)
    n, trials, rej_white, rej_hac = 600, 200, 0, 0
    groups = np.zeros(n, int)
    for _ in range(trials):
        Z = smooth_regressors(rng, n)[:, :1]
        r = ar1_noise(rng, n, 0.9)
        rej_white += S.wald_test(r, Z, groups, None, bandwidth=0).p_value < 0.05
        rej_hac += S.wald_test(r, Z, groups, None).p_value < 0.05
    assert rej_white / trials > 0.3
    assert rej_hac / trials < 0.12


def test_hac_wald_detects_a_real_effect_and_estimates_it():
    rng = np.random.default_rng(11)
    n = 1500
    Z = smooth_regressors(rng, n)[:, :1]
    r = 0.6 * Z[:, 0] + ar1_noise(rng, n, 0.8)
    w = S.wald_test(r, Z, np.zeros(n, int))
    assert w.p_value < 1e-3
    assert w.coef[0] == pytest.approx(0.6, abs=4 * w.std[0])


def test_partial_out_removes_what_the_model_explains():
    rng = np.random.default_rng(5)
    n = 500
    J = np.column_stack([np.ones(n), rng.standard_normal(n)])
    Z = (2 * J[:, 1] + 1)[:, None]  # entirely in the model's span
    w = S.wald_test(rng.standard_normal(n), Z, np.zeros(n, int), S.basis(J))
    assert w.p_value == 1.0 and w.stat == 0.0


def test_holm_and_bonferroni():
    adj = S.holm({"a": 0.01, "b": 0.02, "c": 0.5})
    assert adj["a"] == pytest.approx(0.03)
    assert adj["b"] == pytest.approx(0.04)
    assert adj["c"] == pytest.approx(0.5)
    assert S.bonferroni(0.01, 7.5) == pytest.approx(0.075)
    assert S.bonferroni(0.3, 10) == 1.0


def test_andrews_bandwidth_grows_with_correlation():
    rng = np.random.default_rng(3)
    g = np.zeros(2000, int)
    L0 = S.andrews_bandwidth(rng.standard_normal((2000, 1)), g)
    L9 = S.andrews_bandwidth(ar1_noise(rng, 2000, 0.9)[:, None], g)
    assert L0 <= 3 < 10 < L9


def test_candidate_names_are_fixed():
    assert C.NAMES == ("gravity_sine", "torque_offset", "position_ripple", "thermal_drift",
                       "load_dependent_friction", "backlash", "stribeck", "presliding", "coupling")
    with pytest.raises(KeyError, match="known"):
        C.get("friction_wobble")
