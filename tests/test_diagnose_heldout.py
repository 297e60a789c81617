"""Diagnose decides on data it did not fit, keeps the fit's options, refuses implausible effects,
and builds a coupling candidate from other moving axes (issue 13)."""
from __future__ import annotations

import numpy as np
import pytest

from kukaid.diagnose import candidates as C
from kukaid.diagnose import heldout
from kukaid.diagnose.signals import prepare
from kukaid.diagnose.workflow import diagnose
from kukaid.logs import AxisLog
from kukaid.params import model_from_params


def multisine_log(seed=0, T=40.0, fs=200.0, offset=0.0, axes=(2,), other=None):
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, T, 1.0 / fs)
    w1, w2 = 2 * np.pi * 0.21, 2 * np.pi * 0.37
    q = 0.7 * np.sin(w1 * t) + 0.3 * np.sin(w2 * t + 1.0)
    qd = 0.7 * w1 * np.cos(w1 * t) + 0.3 * w2 * np.cos(w2 * t + 1.0)
    qdd = -0.7 * w1 ** 2 * np.sin(w1 * t) - 0.3 * w2 ** 2 * np.sin(w2 * t + 1.0)
    tau = 1.3 * qdd + 20 * np.cos(q) + 5 * np.sign(qd) + 4 * qd + offset + 0.3 * rng.standard_normal(t.size)
    if other is None:
        return AxisLog(t, q[:, None], tau[:, None], axes=axes, attrs={"source_file": f"ms{seed}"})
    q3 = 1.2 * np.sin(2 * np.pi * 0.053 * t + 0.5)
    tau = tau + other * np.cos(q + q3)
    return AxisLog(t, np.column_stack([q, q3]), np.column_stack([tau, np.zeros(t.size)]), axes=(2, 3),
                   attrs={"source_file": f"ms{seed}"})


def params_of(log, **kw):
    from kukaid.identify import fit_axis

    return fit_axis(logs=[log], friction_model="coulomb-viscous", axis=2, **kw)


def test_folds_blocks_for_one_log_and_leave_one_out_for_three():
    s = prepare(multisine_log(0), 2)
    scheme, fs = heldout.folds([s])
    assert "4 contiguous blocks" in scheme and len(fs) == 4
    for train, test in fs:  # held-out rows never fitted, with a guard between them
        tr, te = train[0].rows, test[0].rows
        assert not np.intersect1d(tr, te).size
        assert np.min(np.abs(tr[:, None] - te[None, :])) >= int(np.ceil(2 * s.fs / s.cutoff))
    scheme, fs = heldout.folds([s, s, s])
    assert scheme.startswith("leave-one-log-out") and len(fs) == 3 and all(len(tr) == 2 for tr, _ in fs)


def test_offset_named_with_held_out_evidence_and_clean_log_names_nothing():
    log = multisine_log(1, offset=1.5)
    d = diagnose(params_of(log), [log])
    assert d.names == ["torque_offset"], d.lines()
    ho = d.steps[0].test.held_out
    assert ho is not None and ho.rmse_with < ho.rmse_without and ho.p_value < 0.05
    assert "held out" in "\n".join(d.lines())
    clean = multisine_log(2)
    d = diagnose(params_of(clean), [clean])
    assert d.names == [] and "no candidate improved the held-out error" in d.verdict, d.lines()


def test_max_steps_zero_tests_nothing_and_says_so():
    log = multisine_log(1, offset=1.5)
    d = diagnose(params_of(log), [log], max_steps=0)
    text = "\n".join(d.lines())
    assert d.names == [] and not d.tested
    assert "no candidate tested" in text and "not significant" not in text and "no effect is missing" not in text


def test_gravity_none_is_kept_by_the_refit():
    log = multisine_log(3, offset=1.5)
    p = params_of(log, gravity="none", offset=False)
    assert "Mx" not in p["inertial"]
    assert "Mx" not in model_from_params(p).lin
    d = diagnose(p, [log], max_steps=2)
    assert "Mx" not in d.params["inertial"] and "gravity_sine" not in d.names, d.lines()


def test_thermal_drift_needs_temperature_or_a_long_log():
    s = prepare(multisine_log(4, T=30.0), 2)
    m = model_from_params(params_of(multisine_log(4, T=30.0)))
    m2 = m.with_effect("thermal_drift", {"coordinate": "time", "form": "coulomb"}, {"c": 0.01})
    why = C.get("thermal_drift").rule(m2, [s], m2.effects[0].nl, {"c": 0.01})
    assert "too short" in why


def test_other_axis_motion_is_coupling_not_ripple_or_drift():
    log = multisine_log(5, other=6.0)
    p = params_of(log)
    assert p["metrics"]["other_axes_moving"] == [3]
    d = diagnose(p, [log], axis=2)
    assert d.names and d.names[0] == "coupling", d.lines()
    assert not {"position_ripple", "thermal_drift"} & set(d.names), d.lines()
    assert any(k.endswith("_A3") for k in d.params["effects"]["coupling"])
    from kukaid.diagnose.validate import validate

    other = multisine_log(6, other=6.0)
    assert validate(d.params, [other], axis=2)[2].rmse < validate(p, [other], axis=2)[2].rmse
