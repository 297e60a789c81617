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
    # the gap closed: A4-A6 held out under 3x their noise floor (2.6x; before, 7.8x: the candidate
    # judged with the wrist links' inertial parameters and A4-A6's spring and ripple terms as the
    # file, fitted on a recording with the coupled friction, has them, and A5 and A6's own friction
    # beside the motors')
    after = np.asarray(d.after[3:]) * np.asarray(d.rms[3:]) / np.asarray(d.noise_floor[3:])
    assert float(np.mean(after)) < 3.0, (after, d.lines())
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


#: the elastic test's gear: A2's stiffness N·m/rad (a soft gear: its link lags by up to 0.006 rad)
STIFFNESS = 1.2e4


def _elastic_logs(kr6, k: float | None):
    """Four recordings of the motor side of a robot whose A2 gear is a spring of stiffness ``k``
    (None: rigid): the motors follow a multi-sine, A2's link lags by its spring's deflection, found
    by fixed-point iteration of ``q_l = theta - tau_rb(q_l, qd_l, qdd_l) / k`` (the link's velocity and
    acceleration differentiated from its positions), the measured torque the spring's plus the
    motor's rotor inertia and friction (the quasi-static two-mass joint: no resonance)."""
    pi, fr = true_parameters(kr6, 1), true_friction(6, 2)
    rotor = np.array([0.15, 0.17, 0.14, 0.04, 0.04, 0.014])
    out = []
    for r in range(4):
        t, q, qd, qdd = multisine(kr6, 10.0, 250.0, seed=80 + r)
        ql, qdl, qddl = q.copy(), qd.copy(), qdd.copy()
        for _ in range(6 if k else 0):
            tau_s = np.einsum("sjk,k->sj", kr6.regressor(ql, qdl, qddl), pi)[:, 1]
            ql[:, 1] = q[:, 1] - tau_s / k
            qdl[:, 1] = np.gradient(ql[:, 1], t)
            qddl[:, 1] = np.gradient(qdl[:, 1], t)
        tau = np.einsum("sjk,k->sj", kr6.regressor(ql, qdl, qddl), pi) + rotor * qdd + \
            fr["Fc"] * np.sign(qd) + fr["Fv"] * qd + fr["offset"]
        rng = np.random.default_rng(r)
        tau += 0.05 * rng.standard_normal(tau.shape)
        # the one-sided differences at the ends make the iteration diverge there (up to 8e4 N·m, which
        # fit refuses as a unit mistake): the recording is the motion between
        e = slice(EDGE, -EDGE)
        out.append(AxisLog(time=t[e] - t[EDGE], q=q[e] + 1e-5 * rng.standard_normal(q[e].shape), tau=tau[e],
                           axes=tuple(range(1, 7)), attrs={"source_file": f"rec{r}.h5"}))
    return out


#: samples left out at each end of an elastic recording
EDGE = 25


def test_gear_elasticity_is_named_and_its_compliance_recovered(kr6):
    logs = _elastic_logs(kr6, STIFFNESS)
    d = diagnose_robot(fit_robot(logs[:1], kr6), logs, kr6, max_steps=1)
    assert d.names == ["gear_elasticity@A2"], d.lines()
    c = d.steps[0]["params"]["compliance_rad_per_Nm"]
    # the first-order term takes about half of the two-mass torque, so the compliance comes out low
    # (25-45 % on the benchmark's cases, docs/robot.md; 30 % here)
    assert 0.6 < c * STIFFNESS < 1.1, c
    eff = d.params["effects"]["gear_elasticity@A2"]
    assert eff["coefficients"] == pytest.approx([c])     # the refined file keeps the diagnosed compliance
    tau = predict_robot(d.params, logs[1], kr6)
    bare = predict_robot({**d.params, "effects": {}}, logs[1], kr6)
    assert len(eff["coefficients"]) == 1 and not np.allclose(tau[2], bare[2])


def test_rigid_gears_name_no_elasticity(kr6):
    logs = _elastic_logs(kr6, None)
    d = diagnose_robot(fit_robot(logs[:1], kr6), logs, kr6, max_steps=1)
    assert {"gear_elasticity@A1", "gear_elasticity@A2", "gear_elasticity@A3"} <= {t["name"] for t in d.tried}
    assert d.names == [], d.lines()


@pytest.mark.parametrize("seed, max_steps", [(52, 1), pytest.param(52, 3, marks=pytest.mark.slow),
                                             pytest.param(42, 3, marks=pytest.mark.slow)])
def test_a_coupled_wrist_friction_is_judged_at_every_prior_strength(kr6, robot_hidden_bench, seed, max_steps):
    """The benchmark's wrist cases (six-axis virtual KR C4, four 10 s recordings): the baseline's
    prior strength was chosen on a torque the coupled friction dominated, and the candidate judged
    there only. Seed 52: judged there, another effect was named first (A4-A6 2.99x the noise floor after);
    seed 42: not named at all before the robot fit left out the equations of stopping joints (a9b8b72),
    2.72x after it. Judged at every strength, as
    a payload is, preferring those that make no joint worse: the wrist first, A4-A6 at 2.3x and 2.4x
    (twins 1.85x, 2.40x), its ratios within 0.01 of the truth. Seed 52 in one step in the default
    suite (the second round names nothing: the same figures, 16 s of CPU, not 22), three with -m slow."""
    bench = robot_hidden_bench
    spec = bench.draw("wrist_friction", seed, kr6)
    row = bench.run_case(spec, 10.0, kr6, twin=False, n_rec=4, max_steps=max_steps)
    assert row["named"][:1] == ["coupled_wrist_friction"], (row["named"], row["rejected"])
    assert row["after_x_floor"] < 3.0, row["after_x_floor"]
    p = row["steps"][0]["params"]
    for k in ("c54", "c64", "c65"):        # within 0.01 of the truth
        assert abs(p[k] - spec[k]) < 0.01, (k, p, spec)


def test_the_wrist_frees_the_last_links_first_moments(kr6):
    """The coupled wrist friction is judged with every inertial parameter of links 4-6 free of the
    file's prior, the last link's first moments too (a fit on a recording with the coupled friction
    took part of it there: dev seed 2's link 6 ``mz`` 9.8 of the file's uncertainties from the truth),
    and its ratios chosen with those first moments held (``moments=False``); a link the wrist does
    not move keeps its information."""
    from kukaid.diagnose.robot import BaseCorrection

    base = kr6.base_parameters()
    ind = base.independent
    B = BaseCorrection(kr6, {"base_parameters": {"independent": ind.tolist(), "sigma": [1.0] * ind.size,
                                                 "values": [0.0] * ind.size},
                             "metrics": {"residual_correlation_factor": 1.0}})
    K = base.K(kr6.n_std)
    info = lambda pr, k: float(K[:, k] @ pr[0] @ K[:, k])  # noqa: E731  the prior's information along a standard parameter
    judged, picked = B.freed_inertia(B.prior, [3, 4, 5]), B.freed_inertia(B.prior, [3, 4, 5], moments=False)
    for k in (52, 53):                  # link 6's my, mz
        assert info(B.prior, k) == pytest.approx(1.0)
        assert info(judged, k) == pytest.approx(0.0, abs=1e-9)
        assert info(picked, k) == pytest.approx(1.0)
    for pr in (judged, picked):
        assert info(pr, 54) == pytest.approx(0.0, abs=1e-9)      # link 6's Ixx: free either way
        assert info(pr, 23) > 0.9 * info(B.prior, 23)            # link 3's mz: held (bar the wrist links' masses in it)


@pytest.mark.slow
@pytest.mark.parametrize("seed, limit", [(2, 2.5), (61, 3.0)])
def test_the_wrist_gap_with_the_last_links_first_moments_free(kr6, robot_hidden_bench, seed, limit):
    """The benchmark's wrist cases (six-axis virtual KR C4, four 10 s recordings, one step). Seed 2:
    with the last link's first moments held at the file's uncertainty A4-A6 ended 5.70x the noise
    floor (twin 1.51x), freed 1.96x. Seed 61: its ratios chosen with them free came out c65 -0.443
    for -0.377 (A4-A6 7.9x), chosen with them held 2.89x (3.08x before, twin 2.38x)."""
    bench = robot_hidden_bench
    spec = bench.draw("wrist_friction", seed, kr6)
    row = bench.run_case(spec, 10.0, kr6, twin=False, n_rec=4, max_steps=1)
    assert row["named"] == ["coupled_wrist_friction"], (row["named"], row["rejected"])
    assert row["after_x_floor"] < limit, row["after_x_floor"]
    p = row["steps"][0]["params"]
    for k in ("c54", "c64", "c65"):
        assert abs(p[k] - spec[k]) < 0.01, (k, p, spec)
