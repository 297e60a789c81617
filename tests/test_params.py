"""Parameter file: validation names the field and the range; writes are atomic."""
from __future__ import annotations

import json

import numpy as np
import pytest

from kukaid.errors import ParamFileError
from kukaid.params import SCHEMA, load_params, model_from_params, save_params
from kukaid.models import MaxwellSlip, Stribeck


# effects as `kukaid diagnose -o` writes them
RIPPLE = {"model": "kukaid.diagnose/1", "n": 12.3, "a": 0.1, "b": 0.2, "std": {"a": 0.01, "b": None}, "A": 0.2236,
          "phi": 1.107}
DRIFT = {"model": "kukaid.diagnose/1", "coordinate": "energy", "form": "friction",
         "friction_ref": {"model": "stribeck", "Fc": -0.5, "Fv": 14.15, "Fs": 17.56, "vs": 0.04, "delta": 2.0},
         "c": 0.001, "std": {"c": None}, "unit": "fraction of the friction per J"}


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


def test_the_model_writes_back_the_file_it_read():
    """One model class in and out: the base sections come back byte for byte, a plain write-back
    adds only the empty uncertainty and effects sections."""
    from kukaid.params import model_sections, model_to_params

    d = {**good(), "offset": -0.25}
    m = model_from_params(d)
    sec = model_sections(m)
    assert json.dumps(sec) == json.dumps({k: d[k] for k in sec})
    assert model_to_params(m, d) == {**d, "uncertainty": {}, "effects": {}}


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
    # unknown or misspelt fields of the sections with fixed keys
    (lambda d: d.update(foo=1), r"unknown field 'foo' \(allowed: schema, axis, friction, inertial, offset, "),
    (lambda d: d["friction"].update(Fcc=12.0),
     r"unknown field 'friction.Fcc' \(allowed: model, Fc, Fv, Fs, vs, delta\)"),
    (lambda d: d["inertial"].update(Izz2=1.0), r"unknown field 'inertial.Izz2' \(allowed: Izz, Mx, My\)"),
    (lambda d: d["maxwell_slip"].update(zeta=[0.0, 0.0]),
     r"unknown field 'maxwell_slip.zeta' \(allowed: k, W, zeta0\)"),
    (lambda d: d["mode_switch"].update(qd_th=0.01), r"unknown field 'mode_switch.qd_th' \(allowed: qd_thr\)"),
    (lambda d: d.update(mode_switch=0.002), r"mode_switch must be a JSON object, got 0.002"),
    (lambda d: d["maxwell_slip"].update(zeta0=[0.0, float("nan")]), r"maxwell_slip.zeta0\[1\] must be a finite number"),
    (lambda d: d["maxwell_slip"].update(zeta0=0.0), r"maxwell_slip.k, .W and .zeta0"),
    # Stribeck: static friction at least the Coulomb level
    (lambda d: d["friction"].update(Fs=11.0), r"friction.Fs = 11.0 must not be below friction.Fc = 12.0"),
    # free-form sections are objects; uncertainties finite numbers >= 0 or null
    (lambda d: d.update(metrics=5), r"metrics must be a JSON object, got 5"),
    (lambda d: d.update(provenance="x"), r"provenance must be a JSON object, got \"x\""),
    (lambda d: d.update(provenance=list(range(1000))), r"provenance must be a JSON object, got \[0, 1, 2, .*\.\.\.$"),
    (lambda d: d.update(uncertainty=[0.1]), r"uncertainty must be an object \{parameter: standard deviation\}"),
    (lambda d: d.update(uncertainty={"Fc": "x"}), r"uncertainty.Fc must be a number, got \"x\""),
    (lambda d: d.update(uncertainty={"Fc": float("nan")}), r"uncertainty.Fc must be a finite number"),
    (lambda d: d.update(uncertainty={"Fc": -0.1}),
     r"uncertainty.Fc = -0.1 is outside the allowed range \[0, 1e\+100\]"),
])
def test_invalid_params(tmp_path, mutate, msg):
    d = good()
    mutate(d)
    _refused(tmp_path, d, msg)


def _refused(tmp_path, d, msg):
    """Reading and writing ``d`` both fail with one line naming the file and matching ``msg``."""
    (tmp_path / "p.json").write_text(json.dumps(d))
    with pytest.raises(ParamFileError, match=msg) as e:
        load_params(tmp_path / "p.json")
    text = str(e.value)
    assert text.startswith(f"{tmp_path / 'p.json'}: ") and "\n" not in text and len(text) < len(str(tmp_path)) + 250
    with pytest.raises(ParamFileError):
        save_params(tmp_path / "q.json", d) if "schema" in d else (_ for _ in ()).throw(ParamFileError("x"))
    assert not (tmp_path / "q.json").exists()


NAN, INF = float("nan"), float("inf")
FRICTION_REF = DRIFT["friction_ref"]


@pytest.mark.parametrize("effects, msg", [
    # every number finite (JSON from Python writes NaN and Infinity, and reads them back)
    ({"torque_offset": {"offset": NAN}}, r"effects.torque_offset.offset must be a finite number, got nan"),
    ({"gravity_sine": {"My": INF}}, r"effects.gravity_sine.My must be a finite number, got inf"),
    ({"torque_offset": {"offset": None}}, r"effects.torque_offset.offset must be a number, got null"),
    ({"torque_offset": {"offset": "abc"}}, r"effects.torque_offset.offset must be a number, got \"abc\""),
    ({"torque_offset": {"offset": True}}, r"effects.torque_offset.offset must be a number, got true"),
    ({"position_ripple": {**RIPPLE, "a": -INF}}, r"effects.position_ripple.a must be a finite number"),
    ({"backlash": {"model": "kukaid.diagnose/1", "shape": "pulse", "tau": 0.0, "A": 1.0}},
     r"effects.backlash.tau = 0.0 is outside the allowed range"),
    ({"thermal_drift": {"kappa": -0.01, "T_ref": "hot"}}, r"effects.thermal_drift.T_ref must be a number"),
    # uncertainties: finite >= 0 or null
    ({"position_ripple": {**RIPPLE, "std": {"a": NAN, "b": None}}}, r"effects.position_ripple.std.a must be a finite"),
    ({"position_ripple": {**RIPPLE, "std": {"a": -0.1}}}, r"effects.position_ripple.std.a = -0.1 is outside"),
    ({"position_ripple": {**RIPPLE, "std": 0.1}}, r"effects.position_ripple.std must be an object"),
    # metadata: strings, from their choices where the diagnosis reads them
    ({"thermal_drift": {**DRIFT, "coordinate": "temp"}},
     r"effects.thermal_drift.coordinate must be 'temperature' or 'time' or 'energy', got \"temp\""),
    ({"thermal_drift": {**DRIFT, "unit": 3}}, r"effects.thermal_drift.unit must be a string, got 3"),
    ({"torque_offset": {"offset": 0.5, "stored_as": "inertial.offset"}},
     r"effects.torque_offset.stored_as must be 'inertial.My' or 'offset'"),
    ({"thermal_drift": {**DRIFT, "friction_ref": {**FRICTION_REF, "Fv": NAN}}},
     r"effects.thermal_drift.friction_ref.Fv must be a finite number"),
    ({"thermal_drift": {**DRIFT, "friction_ref": {**FRICTION_REF, "Fcc": 1.0}}},
     r"unknown field 'effects.thermal_drift.friction_ref.Fcc'"),
    # what the readers need
    ({"position_ripple": {k: v for k, v in RIPPLE.items() if k != "n"}}, r"missing field effects.position_ripple.n"),
    ({"position_ripple": {"model": "kukaid.diagnose/1", "n": 12.0, "a": 0.1}},
     r"missing field effects.position_ripple.b"),
    ({"torque_offset": 0.5}, r"effects.torque_offset must be an object of parameters, got 0.5"),
    ([], r"effects must be an object \{name: parameters\}"),
    # known names only
    ({"bogus": {"x": 1.0}}, r"unknown effect 'effects.bogus' \(known: gravity_sine, torque_offset, position_ripple, "
                            r"thermal_drift, load_dependent_friction, backlash, stribeck, presliding, coupling\)"),
])
def test_invalid_effects(tmp_path, effects, msg):
    _refused(tmp_path, {**good(), "effects": effects}, msg)


def test_what_the_toolkit_writes_validates(tmp_path):
    """Simulator truth with every hidden effect, and a diagnosis with every candidate, round-trip."""
    from kukaid.diagnose.candidates import NAMES
    from kukaid.models.torque import EffectTerm
    from kukaid.params import model_to_params
    from kukaid.sim import SimConfig
    from kukaid.sim.effects import EFFECTS, draw_effect

    rng = np.random.default_rng(3)
    truth = SimConfig().replace(effects={n: draw_effect(n, 1.0, rng) for n in EFFECTS}).truth_params()
    assert set(truth["effects"]) == set(EFFECTS)
    save_params(tmp_path / "truth.json", truth)
    assert load_params(tmp_path / "truth.json") == truth

    base = {k: v for k, v in truth.items() if k != "effects"}
    m = model_from_params(base)
    m.lin.update(My=0.3, offset=-0.2)
    m.effects = [EffectTerm("position_ripple", {"n": 12.3}, {"a": 0.1, "b": 0.2}),
                 EffectTerm("thermal_drift", {"coordinate": "energy", "form": "friction",
                                              "friction_ref": {**m.friction_dict(), "Fc": -0.5}}, {"c": 1e-3}),
                 EffectTerm("load_dependent_friction", {}, {"Fc_load": 0.4}),
                 EffectTerm("backlash", {"shape": "pulse", "tau": 0.07}, {"A": 1.2}),
                 EffectTerm("presliding", {"x0": 0.004}, {"A": -0.8}),
                 EffectTerm("coupling", {"axes": "2,4"}, {f"{p}_A{a}": 0.1 for a in (2, 4)
                                                          for p in ("cos_sum", "sin_sum", "cos", "sin", "qdd")})]
    m.std = {"Fc": 0.1, "vs": float("nan"), "position_ripple.a": 0.01, "My": 0.02}  # nan -> null
    refined = model_to_params(m, base, ["gravity_sine", "torque_offset"])
    assert set(refined["effects"]) == set(NAMES) - {"stribeck"} and refined["effects"]["torque_offset"]["std"]["offset"] is None
    save_params(tmp_path / "refined.json", refined)
    again = model_from_params(load_params(tmp_path / "refined.json"))
    assert again.effect_names == ["position_ripple", "thermal_drift", "load_dependent_friction", "backlash",
                                  "presliding", "coupling"]
    assert again.effects[-1].nl == {"axes": "2,4"} and len(again.effects[-1].coefs) == 10
    # re-diagnosed on a prismatic log the derived mu has no Mx: null, still valid
    prism = model_to_params(model_from_params(refined, "prismatic"), refined)
    assert prism["effects"]["load_dependent_friction"]["mu"] is None
    save_params(tmp_path / "prism.json", prism)


def test_free_form_parts_stay_free(tmp_path):
    d = good()
    d["metrics"] = {"anything": [1, "two", None], "nested": {"x": float("inf")}}
    d["provenance"] = {"note": "hand-made", "logs": None}
    d["uncertainty"] = {"Fc": 0.1, "Fs": None, "my_own_name": 0.0}
    d["effects"] = {"position_ripple": {**RIPPLE, "_comment": "found on 2024-05-02", "extra_coef": -3.0},
                    "thermal_drift": {"kappa": -0.01, "T_ref": None},  # simulator format: null = ambient
                    "torque_offset": {"offset": 0.5, "model": "my-tool/2"}}
    d["friction"]["Fs"] = d["friction"]["Fc"] * (1 - 1e-8)  # rounding below a bound Fs - Fc >= 0: accepted
    save_params(tmp_path / "p.json", d)
    assert load_params(tmp_path / "p.json")["effects"]["position_ripple"]["extra_coef"] == -3.0
    # coulomb-viscous friction has no static level to compare
    d["friction"].update(model="coulomb-viscous", Fs=1.0)
    save_params(tmp_path / "cv.json", d)
    # new-user trial 17: the table showed the Stribeck rows of such an edited file as if its model had them
    from kukaid.identify.fit import format_table

    text = format_table(load_params(tmp_path / "cv.json"))
    assert not any(ln.split()[:1] in (["Fs"], ["vs"], ["delta"]) for ln in text.splitlines()), text
    assert "not used: friction Fs, vs, delta (Stribeck parameters; friction.model is coulomb-viscous)" in text, text


@pytest.mark.parametrize("edit, message", [
    (lambda d: d.update(effects={"torque_offset": {"offset": float("nan")}}),
     "effects.torque_offset.offset must be a finite"),
    (lambda d: d.update(effects={"bogus": {}}), "unknown effect 'effects.bogus'"),
    (lambda d: d.update(foo=1), "unknown field 'foo'"),
    (lambda d: d["friction"].update(Fs=d["friction"]["Fc"] - 1.0), "friction.Fs"),
    (lambda d: d.update(metrics=5), "metrics must be a JSON object"),
])
def test_command_refuses_broken_file_in_one_line_and_writes_nothing(tmp_path, edit, message):
    from click.testing import CliRunner

    from kukaid.sim import SimConfig
    from kukaid_cli.main import cli

    d = SimConfig().truth_params()
    edit(d)
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(d))  # NaN is written as the token NaN, which Python's JSON reader accepts
    out = tmp_path / "run.h5"
    r = CliRunner().invoke(cli, ["run-admittance", "--params", str(bad), "--duration", "1", "-o", str(out)])
    assert r.exit_code == 1 and r.output.startswith(f"kukaid: error: {bad}: ") and message in r.output, r.output
    assert len(r.output.strip().splitlines()) == 1 and not out.exists()


@pytest.mark.parametrize("pre, message", [
    ({"cutoff": "x"}, "provenance.preprocess.cutoff must be a number, got \"x\""),
    ({"cutoff": 0}, "provenance.preprocess.cutoff = 0 is outside the allowed range"),
    ({"order": 99}, "provenance.preprocess.order = 99 is outside the allowed range [1, 8]"),
    ({"order": 3.5}, "provenance.preprocess.order must be a whole number, got 3.5"),
    ({"decimate": 0}, "provenance.preprocess.decimate = 0 is outside the allowed range"),
    ({"diff": "fancy"}, "provenance.preprocess.diff must be \"central\" or \"spectral\""),
])
def test_the_fits_preprocessing_the_readers_take_is_checked(tmp_path, pre, message):
    """New-user trial 13: provenance.preprocess.cutoff "x" was an internal error in show, validate and
    report (exit 70), an order of 99 filtered new logs with it, a decimation of 0 was ignored; the rest of
    provenance stays free-form."""
    from click.testing import CliRunner

    from kukaid_cli.main import cli

    d = good()
    d["provenance"] = {"note": "hand-made", "preprocess": {"cutoff": 5.0, "order": 3, "edge": 84, "decimate": 1,
                                                           "diff": "central", "why": "anything"}}
    save_params(tmp_path / "ok.json", d)
    d["provenance"]["preprocess"].update(pre)
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(d))
    r = CliRunner().invoke(cli, ["show", str(bad)])
    assert r.exit_code == 1 and r.output.startswith(f"kukaid: error: {bad}: ") and message in r.output, r.output
    assert len(r.output.strip().splitlines()) == 1


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
