"""SimConfig: paper defaults, JSON overrides, validation errors that name the field."""
from __future__ import annotations

import json

import pytest

from kukaid.errors import KukaidError
from kukaid.params import validate_params
from kukaid.sim import SimConfig, SimConfigError, load_sim_config


def test_paper_defaults_and_truth_params():
    cfg = SimConfig()
    assert (cfg.Fc, cfg.Fs, cfg.vs, cfg.delta, cfg.Fv) == (15.70, 17.56, 0.04, 2.0, 14.15)
    assert cfg.ms_k == (35894.0, 160065.0, 51893.0) and cfg.ms_W == (7.3406, 1.371, 6.288)
    assert (cfg.Izz, cfg.Mx, cfg.noise_sigma, cfg.sample_time) == (2.2836, 18.4789, 0.5, 0.012)
    assert cfg.servo_rate >= 1000
    p = cfg.replace(effects={"torque_offset": {"offset": 0.7}}).truth_params()
    validate_params(p)
    assert p["effects"] == {"torque_offset": {"offset": 0.7}}
    assert p["maxwell_slip"]["W"] == list(cfg.ms_W)
    json.dumps(cfg.to_dict())


def test_replace_is_a_validated_copy():
    cfg = SimConfig()
    c2 = cfg.replace(noise_sigma=0.3)
    assert c2.noise_sigma == 0.3 and cfg.noise_sigma == 0.5
    with pytest.raises(SimConfigError, match="'noise_sigma'.*outside the allowed range"):
        cfg.replace(noise_sigma=-1.0)
    with pytest.raises(SimConfigError, match="unknown field 'nosie_sigma'"):
        cfg.replace(nosie_sigma=0.3)


def test_load_flat_and_param_file_shapes(tmp_path):
    f = tmp_path / "truth.json"
    f.write_text(json.dumps({"friction": {"model": "stribeck", "Fc": 12.5, "Fv": 9.0}, "inertial": {"Mx": 21.0},
                             "maxwell_slip": {"k": [1e4, 2e4], "W": [3.0, 4.0], "zeta0": [0.0, 0.0]},
                             "noise_sigma": 0.2, "effects": {"gravity_sine": {"My": 1.5}}, "schema": "kukaid.params/1"}))
    cfg = load_sim_config(f)
    assert (cfg.Fc, cfg.Fv, cfg.Mx, cfg.noise_sigma) == (12.5, 9.0, 21.0, 0.2)
    assert cfg.ms_W == (3.0, 4.0) and cfg.sum_W == 7.0
    assert cfg.effects["gravity_sine"]["My"] == 1.5
    # round trip through to_dict
    g = tmp_path / "again.json"
    g.write_text(json.dumps(cfg.to_dict()))
    assert load_sim_config(g) == cfg


@pytest.mark.parametrize("content, words", [
    ({"Fc": "high"}, ["'Fc'", "must be a number"]),
    ({"Fv": -2.0}, ["'Fv'", "outside the allowed range"]),
    ({"friction": {"vs": 0.0}}, ["'vs'", "outside"]),
    ({"ms_k": [1.0, 2.0], "ms_W": [1.0]}, ["'ms_k'", "one length"]),
    ({"maxwell_slip": {"W": [1.0, -2.0, 1.0]}}, ["'ms_W[1]'", "outside"]),
    ({"substeps": 1.5}, ["'substeps'", "integer"]),
    ({"vibration": "yes"}, ["'vibration'", "true or false"]),
    ({"jitter": 0.007}, ["'jitter'"]),
    ({"frictoin": {}}, ["unknown field 'frictoin'"]),
    ({"friction": {"Fcc": 1.0}}, ["unknown field 'friction.Fcc'"]),
    ({"friction": {"model": "coulomb-viscous"}}, ["friction.model"]),
    ({"effects": {"wobble": {}}}, ["unknown effect 'wobble'"]),
    ({"effects": {"torque_offset": {}}}, ["missing parameter 'effects.torque_offset.offset'"]),
    ({"effects": {"backlash": {"A": 1.0, "tau": 9.0}}}, ["'effects.backlash.tau'", "outside"]),
    ({"effects": {"position_ripple": {"A": 1.0, "m": 3}}}, ["unknown parameter 'effects.position_ripple.m'"]),
    # new-user trial nu12 item 15: refused as a parameter file's reader refuses it
    ({"friction": {"model": "stribeck", "Fc": 15, "Fs": 10, "vs": 0.04, "delta": 2, "Fv": 14}},
     ["'Fs' = 10 must not be below field 'Fc' = 15"]),
    ([1, 2], ["top level must be a JSON object"]),
])
def test_validation_errors_name_file_and_field(tmp_path, content, words):
    f = tmp_path / "bad.json"
    f.write_text(json.dumps(content))
    with pytest.raises(SimConfigError) as e:
        load_sim_config(f)
    msg = str(e.value)
    assert "\n" not in msg
    assert msg.startswith(str(f))
    for w in words:
        assert w in msg


def test_file_errors(tmp_path):
    with pytest.raises(KukaidError, match="no such file"):
        load_sim_config(tmp_path / "missing.json")
    f = tmp_path / "broken.json"
    f.write_text('{"Fc": 1.0,\n "Fv": }')
    with pytest.raises(KukaidError, match=r"not valid JSON \(line 2"):
        load_sim_config(f)


def test_a_parameter_file_can_be_the_truth(tmp_path):
    from kukaid.params import save_params

    f = tmp_path / "fitted.json"
    save_params(f, {"axis": 3, "friction": {"model": "stribeck", "Fc": 14.0, "Fs": 16.5, "vs": 0.03, "delta": 1.5,
                                            "Fv": 12.0},
                    "inertial": {"Izz": 2.1, "Mx": 19.5}, "offset": 0.4,
                    "maxwell_slip": {"k": [4e4, 9e4], "W": [6.0, 3.0], "zeta0": [1e-4, -2e-5]},
                    "mode_switch": {"qd_thr": 0.002}, "uncertainty": {"Fc": 0.1}, "metrics": {"mse": 0.3},
                    "provenance": {"note": "test"}})
    cfg = load_sim_config(f)
    assert (cfg.Fc, cfg.Izz, cfg.ms_W, cfg.v_blend) == (14.0, 2.1, (6.0, 3.0), 0.002)
    assert cfg.effects == {"torque_offset": {"offset": 0.4}}
