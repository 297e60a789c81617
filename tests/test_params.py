"""Parameter file: validation names the field and the range; writes are atomic."""
from __future__ import annotations

import json

import numpy as np
import pytest

from kukaid.errors import ParamFileError
from kukaid.io.params import SCHEMA, load_params, model_from_params, save_params
from kukaid.models import MaxwellSlip, Stribeck


def good() -> dict:
    return {
        "schema": SCHEMA,
        "axis": 3,
        "friction": {"model": "stribeck", "Fc": 12.0, "Fs": 14.0, "vs": 0.05, "delta": 1.5, "Fv": 9.0},
        "inertial": {"Izz": 1.7, "Mx": 22.0},
        "maxwell_slip": {"k": [1e4, 5e4], "W": [5.0, 6.0], "zeta0": [0.0, 0.0]},
        "mode_switch": {"qd_thr": 0.002},
    }


def test_round_trip_and_model(tmp_path):
    save_params(tmp_path / "p.json", good())
    d = load_params(tmp_path / "p.json")
    m = model_from_params(d)
    assert m.friction == Stribeck(12.0, 14.0, 0.05, 1.5, 9.0)
    assert m.rigid.Izz == 1.7 and m.qd_thr == 0.002
    tau = m.predict_dynamic(np.array([0.0]), np.array([0.1]), np.array([1.0]))
    assert tau[0] == pytest.approx(1.7 + 22.0 + m.friction(0.1))


@pytest.mark.parametrize("mutate, msg", [
    (lambda d: d.pop("schema"), "'schema' must be"),
    (lambda d: d["friction"].pop("Fc"), "missing field friction.Fc"),
    (lambda d: d["friction"].update(Fc=-1.0), "friction.Fc = -1.0 is outside the allowed range"),
    (lambda d: d["friction"].update(delta="2"), "friction.delta must be a number"),
    (lambda d: d["inertial"].update(Izz=0.0), "inertial.Izz = 0.0 is outside"),
    (lambda d: d["friction"].update(model="lugre"), "friction.model must be"),
    (lambda d: d.pop("inertial"), "missing section 'inertial'"),
    (lambda d: d["maxwell_slip"].update(W=[1.0]), "maxwell_slip.k, .W and .zeta0"),
    (lambda d: d.update(axis=9.5), "axis must be an integer"),
])
def test_invalid_params(tmp_path, mutate, msg):
    d = good()
    mutate(d)
    (tmp_path / "p.json").write_text(json.dumps(d))
    with pytest.raises(ParamFileError, match=msg):
        load_params(tmp_path / "p.json")
    with pytest.raises(ParamFileError):
        save_params(tmp_path / "q.json", d) if "schema" in d else (_ for _ in ()).throw(ParamFileError("x"))
    assert not (tmp_path / "q.json").exists()


def test_broken_json(tmp_path):
    (tmp_path / "p.json").write_text('{"schema": "kukaid.params/1",\n "friction": {')
    with pytest.raises(ParamFileError, match=r"p.json: not valid JSON \(line 2"):
        load_params(tmp_path / "p.json")
    with pytest.raises(ParamFileError, match="no such file"):
        load_params(tmp_path / "missing.json")


def test_stribeck_shape():
    s = Stribeck(Fc=10.0, Fs=13.0, vs=0.05, delta=2.0, Fv=5.0)
    assert s(0.0) == 0.0
    assert s(1e-9) == pytest.approx(13.0, abs=1e-6)
    assert s(-1.0) == pytest.approx(-(10.0 + 3.0 * np.exp(-400.0) + 5.0))
    assert s(1.0) == -s(-1.0)


def test_maxwell_slip_hysteresis():
    ms = MaxwellSlip(k=[1e4, 2e4, 5e4], W=[2.0, 3.0, 1.0])
    a = 2e-4  # break-away displacements W/k are 2e-4, 1.5e-4 and 2e-5 rad
    z = np.concatenate([np.linspace(0, a, 201), np.linspace(a, -a, 401), np.linspace(-a, a, 401)])
    F, _ = ms.simulate(z)
    assert F.max() == pytest.approx(6.0) and F.min() == pytest.approx(-6.0)
    # the loop: at z = 0 the torque is -2 going down and +2 going up (memory of the reversal)
    down = F[201:602][np.argmin(np.abs(z[201:602]))]
    up = F[602:][np.argmin(np.abs(z[602:]))]
    assert down == pytest.approx(-2.0) and up == pytest.approx(2.0)
    zeta = ms.saturated_state(0.0, +1.0)
    F2, _ = ms.simulate(np.array([0.0]), zeta)
    assert F2[0] == pytest.approx(6.0)
