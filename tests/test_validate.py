"""`kukaid validate`: the fit's model evaluated on logs it was not fitted on (per axis RMSE,
relative error, R², samples), JSON shape, and the schema seam."""
from __future__ import annotations

import json
import math

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
    assert set(a) == {"rmse", "rel_error", "r2", "samples", "noise_floor"} and d["mean_relative_error"] == a["rel_error"]
    assert a["r2"] > 0.99 and a["rel_error"] < 0.05 and a["samples"] > 1000
    r = CliRunner().invoke(cli, ["validate", "--params", str(par), str(other)])
    assert r.exit_code == 0 and "A3" in r.output and "R2" in r.output


def test_validate_reads_the_rmse_against_the_noise_floor(tmp_path):
    """New-user trial 10: validate printed "RMSE 0.1623 N·m" with nothing to read it against; fit and
    diagnose say "x the noise floor".  A right model on noisy torques sits at about 1 x the floor (its
    white noise through the fit's low-pass); the floor is pooled over the logs by samples."""
    fit_log, other = tmp_path / "a.h5", tmp_path / "b.h5"
    write_hdf5(sine_log(1, 0.25, noise=0.3), fit_log)
    write_hdf5(sine_log(2, 0.18, amp=0.7, noise=1.5), other)
    par = tmp_path / "p.json"
    assert CliRunner().invoke(cli, ["fit", str(fit_log), "--friction-model", "coulomb-viscous",
                                    "-o", str(par)]).exit_code == 0
    r = CliRunner().invoke(cli, ["validate", "--params", str(par), str(other), "--json"])
    assert r.exit_code == 0, r.output
    a = json.loads(r.output)["axes"]["A3"]
    assert 0.05 < a["noise_floor"] < 1.5  # 1.5 N·m white noise through a low-pass far below Nyquist
    assert 0.8 < a["rmse"] / a["noise_floor"] < 1.5
    r = CliRunner().invoke(cli, ["validate", "--params", str(par), str(other)])
    head, row = r.output.splitlines()[:2]
    assert "x noise" in head and f"{a['rmse'] / a['noise_floor']:.3g}" in row.split()
    pooled = CliRunner().invoke(cli, ["validate", "--params", str(par), str(other), str(fit_log), "--json"])
    assert json.loads(pooled.stdout)["axes"]["A3"]["noise_floor"] < a["noise_floor"]  # the quieter log pools in
    # a torque filtered before it was recorded: no white noise to tell the floor from, n/a and why
    from scipy.signal import butter, filtfilt

    noisy = sine_log(3, 0.18, amp=0.7, noise=0.3)
    tau = filtfilt(*butter(4, 10.0, fs=250.0), noisy.tau, axis=0)  # as the LWR4+'s torque sensors did
    write_hdf5(AxisLog(noisy.time, noisy.q, tau, axes=noisy.axes), tmp_path / "s.h5")
    r = CliRunner().invoke(cli, ["validate", "--params", str(par), str(tmp_path / "s.h5")])
    assert r.exit_code == 0 and r.output.splitlines()[1].split()[2] == "n/a", r.output
    assert "n/a for A3: the torque was filtered or resampled before it was recorded" in r.output
    # new-user trial 14: a log interpolated linearly to three times its rate (MATLAB's interp1 of 12 ms to
    # 4 ms) read "6.34e+12 x noise": its second differences vanish between the recorded samples
    t = np.arange(noisy.time[0], noisy.time[-1], 1.0 / 750.0)
    up = AxisLog(t, np.interp(t, noisy.time, noisy.q[:, 0])[:, None], np.interp(t, noisy.time, noisy.tau[:, 0])[:, None],
                 axes=noisy.axes)
    write_hdf5(up, tmp_path / "up.h5")
    r = CliRunner().invoke(cli, ["validate", "--params", str(par), str(tmp_path / "up.h5")])
    assert r.exit_code == 0 and r.output.splitlines()[1].split()[2] == "n/a", r.output


def test_validate_names_radians_under_a_degree_header_as_fit_does(tmp_path):
    """New-user trial 15: a log in radians whose header says degrees scored 86.5 % with "another robot or axis,
    or another unit?"; fit names the column and the mistake, and now validate does too."""
    from kukaid.logs import write_csv

    write_hdf5(sine_log(1, 0.25), tmp_path / "a.h5")
    par = tmp_path / "p.json"
    assert CliRunner().invoke(cli, ["fit", str(tmp_path / "a.h5"), "--friction-model", "coulomb-viscous",
                                    "-o", str(par)]).exit_code == 0
    write_csv(sine_log(2, 0.18, amp=0.7), tmp_path / "b.csv", angle_unit="rad")
    text = (tmp_path / "b.csv").read_text().replace("A3_rad", "A3_deg", 1)
    (tmp_path / "b.csv").write_text(text)
    r = CliRunner().invoke(cli, ["validate", "--params", str(par), str(tmp_path / "b.csv")])
    assert r.exit_code == 0, r.output
    assert "column A3_deg spans only" in r.stderr and "radians written under a degree header?" in r.stderr, r.stderr


def test_validate_takes_its_logs_with_log_as_diagnose_and_report_do(tmp_path, monkeypatch):
    """New-user trial 10: `validate --params p.json --log x.h5` (as diagnose and report take logs)
    said only "No such option '--log'"; both forms, and a mix, score the same logs."""
    monkeypatch.chdir(tmp_path)
    write_hdf5(sine_log(1, 0.25), "a.h5")
    write_hdf5(sine_log(2, 0.18, amp=0.7), "b.h5")
    write_hdf5(sine_log(3, 0.21, amp=0.8), "c.h5")
    r = CliRunner().invoke(cli, ["fit", "a.h5", "--friction-model", "coulomb-viscous", "-o", "p.json"])
    assert r.exit_code == 0, r.output
    runs = [["b.h5", "c.h5"], ["--log", "b.h5", "--log", "c.h5"], ["b.h5", "--log", "c.h5"]]
    out = []
    for logs in runs:
        r = CliRunner().invoke(cli, ["validate", "--params", "p.json", *logs, "--json"])
        assert r.exit_code == 0, r.output
        out.append(json.loads(r.output))
    assert out[0] == out[1] == out[2] and out[0]["axes"]["A3"]["samples"] > 2000
    r = CliRunner().invoke(cli, ["validate", "--params", "p.json"])
    assert r.exit_code == 2 and r.output.strip().splitlines() == [
        "kukaid: error: validate: Missing argument 'LOGS...' (or --log)"], r.output
    r = CliRunner().invoke(cli, ["validate", "--help"])
    assert "--log" in r.output


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


def test_a_torque_column_that_does_not_vary_is_warned_about_and_left_out_of_the_mean():
    """New-user trial 7: a log whose A2 torque column was all zeros scored A2 nan %, the mean nan %
    (null in --json, the good axes lost), without a warning, exit 0 with --strict; at 1e-6 N·m it
    was called a model of another robot.  Now one warning names the log and the axis, and the mean
    is of the other axes, naming the one left out."""
    from kukaid.diagnose.validate import AxisScore, flat_warnings, mismatch_warnings, table, to_json

    good, zero, const = AxisScore(0.4, 0.2, 0.9, 100), AxisScore(19.7, math.nan, math.nan, 100), \
        AxisScore(19.7, 1.97e7, math.nan, 100)
    for flat, what in ((zero, "is zero in all 100 samples compared"), (const, "does not vary (1e-06 N·m")):
        scores = {1: good, 2: flat, 3: AxisScore(0.2, 0.1, 0.95, 100)}
        (w,) = flat_warnings([scores], ["z.csv"], scores)
        assert w.startswith("z.csv: the measured torque of A2 " + what) and w.endswith("A2 is left out of the mean")
        assert mismatch_warnings([scores], ["z.csv"], "robot.json") == []  # not a model of another robot
        d = to_json(scores)
        assert d["mean_relative_error"] == pytest.approx(0.15) and d["mean_excludes"] == ["A2"]
        mean_line = next(line for line in table(scores) if line.startswith("mean"))
        assert mean_line.split()[:2] == ["mean", "15.00%"] and "without A2" in mean_line
    # one axis: warned, nothing to leave out of
    (w,) = flat_warnings([{3: zero}], ["z.csv"], {3: zero})
    assert "A3 is zero" in w and "mean" not in w
    assert flat_warnings([{3: good}], ["z.csv"], {3: good}) == []


def test_validate_strict_on_a_zero_torque_column_one_axis(tmp_path):
    fit_log, zero = tmp_path / "a.h5", tmp_path / "zero.h5"
    write_hdf5(sine_log(1, 0.25), fit_log)
    lg = sine_log(2, 0.18, amp=0.7)
    write_hdf5(AxisLog(lg.time, lg.q, np.zeros_like(lg.tau), axes=lg.axes, attrs=lg.attrs), zero)
    par = tmp_path / "p.json"
    r = CliRunner().invoke(cli, ["fit", str(fit_log), "--friction-model", "coulomb-viscous", "-o", str(par)])
    assert r.exit_code == 0, r.output
    r = CliRunner().invoke(cli, ["validate", "--params", str(par), str(zero), "--strict"])
    assert r.exit_code == 4, r.output
    assert f"kukaid: warning: validate: {zero}: the measured torque of A3 is zero in all" in r.stderr
    assert "Traceback" not in r.output


def test_validate_strict_on_a_robot_log_with_a_zero_torque_column(tmp_path):
    """The trial's case: the LWR4+ fit of lwr4_1.csv on lwr4_3.csv with A2's torque all zero."""
    import pandas as pd

    from shared_data import SHARED

    lwr4 = SHARED / "datasets" / "lwr4"
    if not (lwr4 / "lwr4_1.csv").exists():
        pytest.skip(f"{lwr4} not found (set KUKAID_SHARED)")
    par, zero = tmp_path / "robot.json", tmp_path / "zero.csv"
    r = CliRunner().invoke(cli, ["fit", str(lwr4 / "lwr4_1.csv"), "--robot", str(lwr4 / "kuka_lwr4.urdf"),
                                 "-o", str(par)])
    assert r.exit_code == 0, r.output
    d = pd.read_csv(lwr4 / "lwr4_3.csv")
    d["A2_Nm"] = 0.0
    d.to_csv(zero, index=False)
    r = CliRunner().invoke(cli, ["validate", "--params", str(par), str(zero), "--strict", "--json"])
    assert r.exit_code == 4, r.output
    out = json.loads(r.stdout)
    assert out["mean_excludes"] == ["A2"] and 0 < out["mean_relative_error"] < 0.5
    (w,) = [line for line in r.stderr.splitlines() if line.startswith("kukaid: warning:")]
    assert "the measured torque of A2 is zero" in w and "A2 is left out of the mean" in w


def test_validate_json_holds_its_warnings(tmp_path):
    """New-user trial 7: `validate --strict --json` exited 4 with the warnings on stderr only; the JSON
    (a script's input) had no list of them, as run-admittance's has."""
    fit_log, other, both = tmp_path / "a.h5", tmp_path / "b.h5", tmp_path / "c.h5"
    write_hdf5(sine_log(1, 0.25), fit_log)
    write_hdf5(sine_log(2, 0.18, amp=0.7), other)
    write_hdf5(sine_log(3, 0.18, axes=(2, 3)), both)
    par = tmp_path / "p.json"
    r = CliRunner().invoke(cli, ["fit", str(fit_log), "--friction-model", "coulomb-viscous", "-o", str(par)])
    assert r.exit_code == 0, r.output
    r = CliRunner().invoke(cli, ["validate", "--params", str(par), str(other), "--json", "--strict"])
    assert r.exit_code == 0 and json.loads(r.stdout)["warnings"] == [], r.output
    r = CliRunner().invoke(cli, ["validate", "--params", str(par), str(both), str(fit_log), "--json", "--strict"])
    assert r.exit_code == 4, r.output
    said = [line.removeprefix("kukaid: warning: validate: ") for line in r.stderr.splitlines()
            if line.startswith("kukaid: warning: validate: ")]
    got = json.loads(r.stdout)["warnings"]
    assert got == said and len(got) == 2 and "other axes (A2) move" in got[0] and "in-sample" in got[1], got


def test_validate_refuses_one_recording_given_twice_as_fit_and_diagnose_do(tmp_path, monkeypatch):
    """New-user trial 17: `validate --params p.json b.h5 --log b.h5` (or b.h5 and a copy of it) pooled
    the recording twice: the table said 2x its samples and weighed it double in the pooled figures;
    fit and diagnose refuse it, `b.h5: given twice; give each recording once`."""
    import shutil

    monkeypatch.chdir(tmp_path)
    write_hdf5(sine_log(1, 0.25), "a.h5")
    write_hdf5(sine_log(2, 0.18, amp=0.7), "b.h5")
    shutil.copy("b.h5", "copy.h5")
    assert CliRunner().invoke(cli, ["fit", "a.h5", "--friction-model", "coulomb-viscous", "-o", "p.json"]).exit_code == 0
    for logs, said in ((["b.h5", "--log", "b.h5"], "given twice"), (["b.h5", "copy.h5"], "the same recording as")):
        r = CliRunner().invoke(cli, ["validate", "--params", "p.json", *logs])
        assert r.exit_code == 1 and len(r.output.strip().splitlines()) == 1, r.output
        assert r.output.startswith("kukaid: error: ") and said in r.output and "give each recording once" in r.output
