"""`kukaid diagnose --params robot.json -o refined.json --report r.pdf`: the refined robot file with the
named effects in it, read by validate (predicting with them), show, report and diagnose again; the
PDF of where the gap closed per joint; the output rules of the one-axis path (atomic, both files or
neither, a parameter file replaced, any other file only with --force, one clear line on a bad input).

The case: a 3.5 kg payload hidden in the six-axis virtual KR C4 (benchmarks/diagnose_robot_hidden.py,
seed 0, four 4 s recordings), the file fitted on a recording without it; diagnosed on three, the
fourth kept out for validate."""
from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from kukaid.logs import write_hdf5
from pdf_layout import capture_pages
from test_cli_errors import _one_line_error, _run
from test_report_pdf import _pages


@pytest.fixture(scope="module")
def case(tmp_path_factory, robot_hidden_bench):
    """The payload case on disk, diagnosed once with -o (onto a note file, with --force) and --report."""
    from kukaid.identify.robot_fit import fit_robot
    from kukaid.models.robot import RobotModel
    from kukaid.params import save_robot_params

    B = robot_hidden_bench
    robot = RobotModel(B.ROBOT)
    spec = B.draw("payload", 0, robot)
    d = tmp_path_factory.mktemp("robot_out")
    save_robot_params(d / "robot.json", fit_robot(B.recordings(spec, 4.0, 1, hidden=False), robot))
    logs = []
    for k, lg in enumerate(B.recordings(spec, 4.0, 4)):
        write_hdf5(lg, d / f"rec{k}.h5")
        logs.append(d / f"rec{k}.h5")
    (d / "refined.json").write_text("notes, not a parameter file\n")
    r = _run("diagnose", "--params", d / "robot.json", *[x for p in logs[:3] for x in ("--log", p)],
             "-o", d / "refined.json", "--force", "--report", d / "diagnosis.pdf")
    assert r.exit_code == 0, r.output
    return d, logs, r


def _validate(params, log) -> float:
    r = _run("validate", "--params", params, log, "--json")
    assert r.exit_code == 0, r.output
    return json.loads(r.stdout)["mean_relative_error"]


def test_the_refined_file_predicts_with_the_payload(case):
    """validate on a recording no step saw predicts with the payload: its error falls (72.5 -> 8.8 %)."""
    d, logs, r = case
    assert "step 1: payload" in r.stdout and "refined parameters written" in r.stderr
    refined = json.loads((d / "refined.json").read_text())
    # the hidden box: 3.50 kg; from four 4 s recordings it comes out at 3.47 kg (seed 0; 2.56 kg, 27 % off,
    # while the equations of stopping joints were fitted: then seeds 1 and 2 were 0.3 and 18 % off with the
    # file's rotor inertias, seeds 0, 1, 2 2, 21 and 95 % without them)
    assert list(refined["effects"]) == ["payload"] and refined["effects"]["payload"]["coefficients"][0] == \
        pytest.approx(3.5, rel=0.35)
    before, after = _validate(d / "robot.json", logs[3]), _validate(d / "refined.json", logs[3])
    assert after < 0.25 * before, (before, after)


def test_the_refined_file_is_read_by_show_report_and_diagnose_which_holds_its_effects(case):
    d, logs, _ = case
    again = _run("diagnose", "--params", d / "refined.json", *[x for p in logs[:3] for x in ("--log", p)], "--json")
    assert again.exit_code == 0, again.output
    out = json.loads(again.stdout)
    assert out["effects_in_the_file"] == ["payload"] and "payload" not in [s["name"] for s in out["steps"]]
    shown = _run("show", d / "refined.json")
    mass = json.loads((d / "refined.json").read_text())["effects"]["payload"]["coefficients"][0]
    assert shown.exit_code == 0 and f"payload: coefficients {mass:.4g}, " in shown.stdout
    rep = _run("report", "--params", d / "refined.json", "--log", logs[3], "-o", d / "fit.pdf")
    assert rep.exit_code == 0 and _pages(d / "fit.pdf") == 3, rep.output


def test_the_report_has_a_page_per_joint_and_nothing_is_written_on_a_bad_input(case, tmp_path):
    d, logs, r = case
    pdf = d / "diagnosis.pdf"
    assert pdf.read_bytes()[:5] == b"%PDF-" and _pages(pdf) == 1 + 6 and "report written" in r.stderr
    bad = tmp_path / "bad.h5"
    bad.write_bytes(b"not an HDF5 file")
    for extra, what in ((["--log", bad], "bad.h5"), (["--log", tmp_path / "missing.h5"], "missing.h5"),
                        (["--report", tmp_path], "is a directory")):
        r = _run("diagnose", "--params", d / "robot.json", "--log", logs[0], "--log", logs[1],
                 "-o", tmp_path / "out.json", *(extra if extra[0] == "--report" else
                                                [*extra, "--report", tmp_path / "out.pdf"]))
        _one_line_error(r, what)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.h5"]


def test_the_report_pages_keep_within_the_paper_with_no_effect_named(case, tmp_path, monkeypatch):
    """Nothing to name (--max-steps 0): the report still shows each joint's residual and says so."""
    d, logs, _ = case
    problems = capture_pages(monkeypatch)
    r = _run("diagnose", "--params", d / "robot.json", *[x for p in logs[:3] for x in ("--log", p)],
             "--max-steps", "0", "--report", tmp_path / "none.pdf")
    assert r.exit_code == 0, r.output
    assert _pages(tmp_path / "none.pdf") == 7 and problems == []


def test_o_replaces_a_parameter_file_and_refuses_any_other_without_force(case, tmp_path):
    d, logs, _ = case
    note = tmp_path / "note.json"
    note.write_text('{"schema": "something/1"}')
    r = _run("diagnose", "--params", d / "robot.json", "--log", logs[1], "--log", logs[2], "-o", note)
    _one_line_error(r, "already exists", "--force")
    assert note.read_text() == '{"schema": "something/1"}'
    # the forced run of the case replaced its note; an existing parameter file is replaced without it
    assert json.loads((d / "refined.json").read_text())["schema"] == "kukaid.robot_params/1"
    old = tmp_path / "old.json"
    old.write_text((d / "refined.json").read_text())
    r = _run("diagnose", "--params", d / "robot.json", "--log", logs[1], "--log", logs[2], "--max-steps", "0",
             "-o", old)
    assert r.exit_code == 0, r.output
    assert json.loads(old.read_text()).get("effects") is None     # nothing named: the file as it was


def test_axis_cutoff_alpha_stay_refused_for_a_robot_file(case):
    d, logs, _ = case
    for opt in (["--axis", "2"], ["--cutoff", "5"], ["--alpha", "0.05"]):
        r = _run("diagnose", "--params", d / "robot.json", "--log", logs[0], *opt)
        assert r.exit_code == 2 and "does not apply to a robot parameter file" in r.output


def test_a_robot_file_names_its_effects_right():
    from kukaid.errors import ParamFileError
    from kukaid.models.robot_effects import parse
    from kukaid.params import validate_robot_params

    assert parse("counterbalance@A2") == ("counterbalance", 1) and parse("payload") == ("payload", None)
    for bad in ("payload@A1", "counterbalance", "spring@A2"):
        with pytest.raises(ValueError):
            parse(bad)
    with pytest.raises(ParamFileError, match="effects.position_ripple@A2.coefficients"):
        validate_robot_params(_minimal({"position_ripple@A2": {"n": 7.0, "coefficients": [1.0]}}))
    with pytest.raises(ParamFileError, match="unknown robot effect 'gravity_sine@A1'"):
        validate_robot_params(_minimal({"gravity_sine@A1": {"coefficients": [1.0]}}))


def _minimal(effects):
    return {"schema": "kukaid.robot_params/1", "robot": {"urdf": "kr6-r700-sixx"}, "axes": [1, 2],
            "base_parameters": {"names": ["a"], "values": [1.0], "independent": [0], "dependent": list(range(1, 20)),
                                "R": [[0.0] * 19]},
            "friction": {"model": "coulomb-viscous", "values": {}}, "settings": {}, "effects": effects}


def test_a_thermal_effect_needs_the_temperature_and_run_admittance_refuses_effects(case):
    """validate of a file with a thermal effect on a log without temperatures: one clear line;
    the real-time torque model (run-admittance) has no effects yet: it refuses the file."""
    from kukaid.control.robot_residual import RobotTorqueModel
    from kukaid.errors import ParamFileError
    from kukaid.logs import read_log

    d, logs, _ = case
    p = json.loads((d / "refined.json").read_text())
    p["effects"]["thermal_friction@A2"] = {"form": "coulomb", "coefficients": [-0.01]}
    (d / "thermal.json").write_text(json.dumps(p))
    write_hdf5(replace(read_log(logs[3]), temp=None), d / "cold.h5")
    _one_line_error(_run("validate", "--params", d / "thermal.json", d / "cold.h5"), "temperature channel")
    with pytest.raises(ParamFileError, match="payload.*not in the real-time torque model"):
        RobotTorqueModel.from_params(p)


def test_a_file_its_own_terms_refitted_beat_by_far_is_said_to_be_worth_refitting():
    """New-user trial 13: the file as it is 9-10 % against 1.0 % held out with its terms refitted, nothing
    named, the file written unchanged, and nothing said about how to get the better model."""
    from kukaid.diagnose.robot import RobotDiagnosis

    stale = RobotDiagnosis(axes=[1, 2], folds="x", before=[0.010, 0.011], after=[0.010, 0.011], in_sample=[0.09, 0.10])
    said = [ln for ln in stale.lines() if "kukaid fit --robot" in ln]
    assert len(said) == 1 and "1.0 % against 9.5 %" in said[0], stale.lines()
    fine = RobotDiagnosis(axes=[1, 2], folds="x", before=[0.26, 0.015], after=[0.26, 0.015], in_sample=[0.277, 0.016])
    assert not any("kukaid fit --robot" in ln for ln in fine.lines())  # the LWR4+'s: 0.95 of it


def test_max_steps_0_says_no_candidate_was_tested():
    """New-user trial 16: `kukaid diagnose --params lwr.json --log lwr4_3.csv --max-steps 0` said "no effect
    named: none lowers the held-out error enough", though no candidate was tried (the one-axis diagnosis
    says "no candidate tested (--max-steps 0)")."""
    from kukaid.diagnose.robot import diagnose_robot
    from kukaid.identify.robot_fit import fit_robot
    from kukaid.models.robot import RobotModel
    from robot_sim_helpers import simulated_log

    kr6 = RobotModel("kr6-r700-sixx")
    logs = [simulated_log(kr6, duration=6.0, seed=s)[0] for s in (0, 1)]
    d = diagnose_robot(fit_robot(logs[:1], kr6), logs[1:], kr6, max_steps=0)
    lines = d.lines()
    assert "no candidate tested (--max-steps 0): the figures above are all this run measured" in lines, lines
    assert not any(ln.startswith("no effect named") for ln in lines) and not d.tried, lines


def test_after_a_unit_warning_the_remedy_is_the_unit_not_a_refit():
    """New-user trial 16: `kukaid diagnose --params lwr.json --log wrongunit.csv` (radians under degree headers)
    warned about the unit, then said "`kukaid fit --robot` on these logs gives that model": a refit that fits the
    mistake."""
    from kukaid.diagnose import diagnose_model
    from kukaid.diagnose.robot import RobotDiagnosis
    from kukaid.identify.fitted import model_for
    from kukaid.identify.robot_fit import fit_robot
    from kukaid.models.robot import RobotModel
    from robot_sim_helpers import simulated_log

    stale = RobotDiagnosis(axes=[1, 2], folds="x", before=[0.010, 0.011], after=[0.010, 0.011], in_sample=[0.09, 0.10],
                           unit_doubt=True)
    said = [ln for ln in stale.lines() if "1.0 % against 9.5 %" in ln]
    assert len(said) == 1 and "mend the logs' position unit first" in said[0] and "kukaid fit --robot" not in said[0]
    kr6 = RobotModel("kr6-r700-sixx")
    logs = [simulated_log(kr6, duration=6.0, seed=s)[0] for s in (0, 1)]
    small = replace(logs[1], q=np.radians(logs[1].q))  # radians read as degrees: 57 x too small
    small.attrs.update(source_file="small.csv", position_columns={str(a): f"A{a}_deg" for a in small.axes})
    warned = []
    d, _ = diagnose_model(model_for(fit_robot(logs[:1], kr6)), [small], max_steps=0, warn=warned.append)
    assert d.unit_doubt and any("radians written under a degree header" in w for w in warned), warned
    d, _ = diagnose_model(model_for(fit_robot(logs[:1], kr6)), logs[1:], max_steps=0)
    assert not d.unit_doubt
