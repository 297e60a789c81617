"""`kukaid validate`: the fit's model evaluated on logs it was not fitted on (per axis RMSE,
relative error, R², samples), JSON shape, and the schema seam."""
from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from kukaid.logs import AxisLog, write_hdf5
from kukaid_cli.main import cli

TRUE = dict(Fc=9.0, Fv=6.0, Izz=1.4, Mx=15.0)


def sine_log(seed: int, freq: float, amp: float = 0.9, fs: float = 250.0, T: float = 24.0, noise: float = 0.3,
             axes=(3,)) -> AxisLog:
    """Two-sine motion, torque of the Coulomb-viscous + rigid-body model plus white noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, T, 1.0 / fs)
    w1, w2 = 2 * np.pi * freq, 2 * np.pi * 1.7 * freq
    q = amp * np.sin(w1 * t) + 0.3 * amp * np.sin(w2 * t + 0.4)
    qd = amp * w1 * np.cos(w1 * t) + 0.3 * amp * w2 * np.cos(w2 * t + 0.4)
    qdd = -amp * w1 ** 2 * np.sin(w1 * t) - 0.3 * amp * w2 ** 2 * np.sin(w2 * t + 0.4)
    tau = TRUE["Izz"] * qdd + TRUE["Mx"] * np.cos(q) + TRUE["Fc"] * np.sign(qd) + TRUE["Fv"] * qd
    tau = tau + noise * rng.standard_normal(t.size)
    Q = np.column_stack([q] * len(axes))
    U = np.column_stack([tau] * len(axes))
    return AxisLog(t, Q, U, axes=axes, attrs={"source_file": f"sine{seed}"})


def test_score_figures():
    from kukaid.diagnose.validate import score

    tau = np.array([1.0, -1.0, 2.0, -2.0])
    s = score(tau, tau)
    assert s.rmse == 0 and s.rel_error == 0 and s.r2 == 1 and s.samples == 4
    s = score(tau, np.zeros(4))
    assert s.rel_error == pytest.approx(1.0) and s.r2 == pytest.approx(0.0)
    assert s.rmse == pytest.approx(np.sqrt(2.5))


def test_validate_cli_table_and_json(tmp_path):
    fit_log, other = tmp_path / "a.h5", tmp_path / "b.h5"
    write_hdf5(sine_log(1, 0.25), fit_log)
    write_hdf5(sine_log(2, 0.18, amp=0.7), other)
    par = tmp_path / "p.json"
    r = CliRunner().invoke(cli, ["fit", str(fit_log), "--friction-model", "coulomb-viscous", "-o", str(par)])
    assert r.exit_code == 0, r.output
    r = CliRunner().invoke(cli, ["validate", "--params", str(par), str(other), "--json"])
    assert r.exit_code == 0, r.output
    d = json.loads(r.output)
    a = d["axes"]["A3"]
    assert set(a) == {"rmse", "rel_error", "r2", "samples"} and d["mean_relative_error"] == a["rel_error"]
    assert a["r2"] > 0.99 and a["rel_error"] < 0.05 and a["samples"] > 1000
    r = CliRunner().invoke(cli, ["validate", "--params", str(par), str(other)])
    assert r.exit_code == 0 and "A3" in r.output and "R2" in r.output


def test_validate_detects_a_wrong_model(tmp_path):
    from kukaid.diagnose.validate import validate

    log = sine_log(3, 0.2)
    good = {"schema": "kukaid.params/1", "axis": 3,
            "friction": {"model": "coulomb-viscous", "Fc": TRUE["Fc"], "Fv": TRUE["Fv"]},
            "inertial": {"Izz": TRUE["Izz"], "Mx": TRUE["Mx"]}}
    bad = json.loads(json.dumps(good))
    bad["inertial"]["Mx"] = 5.0
    sg, sb = validate(good, [log])[3], validate(bad, [log])[3]
    assert sg.r2 > 0.99 and sb.r2 < sg.r2 and sb.rmse > 3 * sg.rmse


def test_unknown_schema_and_missing_axis(tmp_path):
    from kukaid.diagnose.validate import validate
    from kukaid.errors import KukaidError, ParamFileError

    with pytest.raises(ParamFileError, match="no model evaluator"):
        validate({"schema": "other/1"}, [sine_log(1, 0.2)])
    p = {"schema": "kukaid.params/1", "axis": 2, "friction": {"model": "coulomb-viscous", "Fc": 1.0, "Fv": 1.0},
         "inertial": {"Izz": 1.0}}
    with pytest.raises(KukaidError, match="A2"):
        validate(p, [sine_log(1, 0.2)])


def test_a_log_where_the_axis_stands_is_named(tmp_path):
    """No dynamic-mode sample to compare: the error says which log (not only the axis)."""
    p = {"schema": "kukaid.params/1", "axis": 3, "friction": {"model": "coulomb-viscous", "Fc": 1.0, "Fv": 1.0},
         "inertial": {"Izz": 1.0, "Mx": 15.0}}
    par, still = tmp_path / "p.json", tmp_path / "still.h5"
    par.write_text(json.dumps(p))
    write_hdf5(sine_log(4, 0.2, amp=0.0), still)
    r = CliRunner().invoke(cli, ["validate", "--params", str(par), str(still)])
    assert r.exit_code == 1, r.output
    assert r.output.startswith("kukaid: error: ") and "still.h5" in r.output and "A3" in r.output
    assert len(r.output.strip().splitlines()) == 1


def test_validate_warns_when_other_axes_move(tmp_path):
    """A one-axis model checked on a log where other axes move is told why it fails (as fit does)."""
    fit_log, both = tmp_path / "a.h5", tmp_path / "b.h5"
    write_hdf5(sine_log(1, 0.25), fit_log)
    write_hdf5(sine_log(2, 0.18, axes=(2, 3)), both)
    par = tmp_path / "p.json"
    r = CliRunner().invoke(cli, ["fit", str(fit_log), "--friction-model", "coulomb-viscous", "-o", str(par)])
    assert r.exit_code == 0, r.output
    r = CliRunner().invoke(cli, ["validate", "--params", str(par), str(both)])
    assert r.exit_code == 0 and "warning: validate:" in r.output and "other axes (A2) move" in r.output, r.output
    r = CliRunner().invoke(cli, ["validate", "--params", str(par), str(fit_log)])  # in-sample: says so, not this
    assert r.exit_code == 0 and "other axes" not in r.output and "in-sample" in r.output, r.output
