"""`kukaid diagnose` end to end: JSON schema, refined parameter file, PDF report, errors."""
from __future__ import annotations

import json
import re

import numpy as np
import pytest
from click.testing import CliRunner

from kukaid_cli.main import cli
from pdf_layout import capture_pages, layout_problems


@pytest.fixture(scope="module")
def case(tmp_path_factory):
    from kukaid.diagnose.power import draw_effects, hidden_effect_logs, initial_fit
    from kukaid.logs import write_hdf5
    from kukaid.params import save_params

    d = tmp_path_factory.mktemp("diag")
    effects = draw_effects({"position_ripple": 1.5}, np.random.default_rng(8))
    logs = hidden_effect_logs(effects, seed=8, short=True)
    paths = []
    for k, log in enumerate(logs):
        p = d / f"log{k}.h5"
        write_hdf5(log, p)
        paths.append(p)
    params = d / "p.json"
    save_params(params, initial_fit(logs))
    return d, params, paths


def args(params, paths, *more):
    out = ["diagnose", "--params", str(params)]
    for p in paths:
        out += ["--log", str(p)]
    return out + list(more)


def test_json_schema_refined_file_and_report(case, monkeypatch):
    d, params, paths = case
    refined, report = d / "refined.json", d / "diag.pdf"
    problems = capture_pages(monkeypatch)
    r = CliRunner().invoke(cli, args(params, paths, "--json", "-o", str(refined), "--report", str(report)))
    assert r.exit_code == 0, r.output
    js = json.loads(r.stdout)
    assert {"effects", "rmse_before", "rmse_after", "noise_floor", "ambiguous", "rejected", "verdict"} <= set(js)
    assert [e["name"] for e in js["effects"]] == ["position_ripple"]
    e = js["effects"][0]
    assert set(e) == {"name", "params", "rmse_before", "rmse_after", "evidence"}
    assert e["rmse_after"] < e["rmse_before"] and js["rmse_after"] <= 1.15 * js["noise_floor"]
    assert e["params"]["A"] == pytest.approx(1.5, rel=0.15)
    assert e["evidence"]["p_value"] < 0.01
    assert report.read_bytes()[:4] == b"%PDF"
    assert not problems, problems
    boxes = [tuple(float(v) for v in b.split()) for b in re.findall(rb"/MediaBox \[([^\]]*)\]", report.read_bytes())]
    assert len(boxes) >= 2 and set(boxes) == {(0.0, 0.0, 595.44, 841.68)}  # every page A4
    # the refined file carries the effect; diagnosing it again finds nothing more
    p2 = json.loads(refined.read_text())
    assert p2["effects"]["position_ripple"]["n"] > 0
    r2 = CliRunner().invoke(cli, args(refined, paths, "--json"))
    assert r2.exit_code == 0, r2.output
    js2 = json.loads(r2.stdout)
    assert js2["effects"] == [] and js2["rmse_before"] <= 1.15 * js2["noise_floor"]


def test_report_text_wraps_within_the_page():
    """The summary page wraps long lines (an ambiguity's reason is a long sentence) and keeps every word."""
    from types import SimpleNamespace

    from kukaid.diagnose.plots import page_table

    long = ("ambiguous: backlash or presliding explain the same residual (a transient after each reversal; with "
            "one position sensor backlash and pre-sliding friction cannot be told apart (a load-side encoder "
            "would)); not guessing")
    lines = ["gap before: RMSE 2.184 N", long, "    evidence: " + long]
    (fig,), free = page_table(SimpleNamespace(lines=lambda: lines, steps=[]))
    assert free > 0.5  # room for the spectrum below a short summary
    assert not layout_problems(fig)
    assert " ".join(t.get_text() for t in fig.texts[1:]).split() == " ".join(lines).split()  # after the title
    # a long diagnosis continues on new pages, every page inside its margins, no word lost
    figs, _ = page_table(SimpleNamespace(lines=lambda: lines * 30, steps=[]))
    assert len(figs) > 1 and not any(layout_problems(f) for f in figs)
    words = " ".join(t.get_text() for f in figs for t in f.texts[1:]).split()
    assert words == " ".join(lines * 30).split()


def test_text_output(case):
    d, params, paths = case
    r = CliRunner().invoke(cli, args(params, paths, "--max-steps", "1"))
    assert r.exit_code == 0, r.output
    assert "step 1: position_ripple" in r.output and "gap after" in r.output


def test_a_refit_that_is_not_kept_says_so(tmp_path, monkeypatch):
    """New-user trial 10: a run-admittance log (the push in its torque) printed "refit without new effects:
    RMSE 2" beside "gap after: RMSE 13": the refit of the file's own terms (in-sample) is where the steps
    start; with nothing named it is not kept and the gap after is the file's as it was, and the line says so."""
    from kukaid.params import save_params
    from kukaid.sim import SimConfig

    monkeypatch.chdir(tmp_path)
    save_params("truth.json", SimConfig().truth_params())
    r = CliRunner().invoke(cli, ["run-admittance", "--params", "truth.json", "--operator", "push", "--seed", "4",
                                 "--duration", "7", "-o", "run.h5"])
    assert r.exit_code == 0, r.output
    r = CliRunner().invoke(cli, ["diagnose", "--params", "truth.json", "--log", "run.h5"])
    assert r.exit_code == 0 and "run.h5 is a run log of kukaid run-admittance" in r.stderr, r.output
    out = r.stdout.splitlines()
    (refit,) = [x for x in out if x.startswith("refit without new effects: RMSE")]
    assert refit.endswith("(the file's own terms refitted on these logs, in-sample; not kept, as nothing was named: "
                          "the gap after is the file's as it was)"), refit
    before, after = (re.search(r"RMSE (\S+)", x).group(1) for x in (out[0], out[-1]))
    assert out[0].startswith("gap before") and out[-1].startswith("gap after") and before == after


def test_a_refit_the_steps_start_from_is_printed_as_before(case):
    d, params, paths = case
    r = CliRunner().invoke(cli, args(params, paths, "--max-steps", "1"))
    out = r.output.splitlines()
    assert out[1] == "refit without new effects: RMSE 1.042 N·m" and "RMSE 1.042 -> " in r.output, r.output


def test_a_file_with_nothing_named_is_not_called_refined(case, tmp_path):
    """New-user trial 13: diagnose -o printed "refined parameters written" when no effect was named and
    the file written held the given parameters, unchanged (its provenance records the diagnosis)."""
    d, params, paths = case
    out = tmp_path / "same.json"
    r = CliRunner().invoke(cli, args(params, paths, "--max-steps", "0", "-o", str(out)))
    assert r.exit_code == 0 and "step 1" not in r.stdout, r.output
    assert f"{out}: parameters written as given (no effect named)" in r.stderr and "refined" not in r.stderr, r.stderr
    written, given = json.loads(out.read_text()), json.loads(params.read_text())
    assert written["provenance"]["diagnose"]["effects_added"] == []    # the diagnosis is recorded
    assert {k: v for k, v in written.items() if k != "provenance"} == {k: v for k, v in given.items() if k != "provenance"}


def test_a_model_that_does_not_describe_the_logs_is_warned_about_as_validate_does(case, tmp_path):
    """New-user trial 16: `kukaid diagnose --params params.json (the virtual KR C4's A3) --log lwr4_3.csv`
    printed "gap before: ... relative error 2230.55 %" and went on to weigh backlash against pre-sliding
    friction, without the warning validate gives (a model of another robot or axis, or another unit)."""
    d, params, paths = case
    p = json.loads(params.read_text())
    for k in ("Fc", "Fs", "Fv"):
        p["friction"][k] *= 1000.0                    # N·mm
    for k in p["inertial"]:
        p["inertial"][k] *= 1000.0
    nmm = tmp_path / "nmm.json"
    nmm.write_text(json.dumps(p))
    r = CliRunner().invoke(cli, args(nmm, paths[:1], "--max-steps", "0"))
    assert r.exit_code == 0, r.output
    said = [ln for ln in r.stderr.splitlines() if "does not describe these logs" in ln]
    assert len(said) == 1 and said[0].startswith(f"kukaid: warning: diagnose: the model of {nmm} does not describe "
                                                 "these logs on A"), r.stderr
    r = CliRunner().invoke(cli, args(params, paths[:1], "--max-steps", "0"))
    assert r.exit_code == 0 and "does not describe" not in r.stderr, r.stderr


def test_bad_inputs_give_one_line_errors(case, tmp_path):
    d, params, paths = case
    bad = tmp_path / "bad.json"
    bad.write_text('{"schema": "kukaid.params/1", "friction": {"Fc": 1}}')
    r = CliRunner().invoke(cli, args(bad, paths))
    assert r.exit_code == 1 and "kukaid: error:" in r.output and "Traceback" not in r.output
    r = CliRunner().invoke(cli, args(params, [tmp_path / "missing.h5"]))
    assert r.exit_code == 1 and "missing.h5" in r.output
    r = CliRunner().invoke(cli, args(params, paths, "--axis", "5"))
    assert r.exit_code == 2 and "not A5 (--axis 5)" in r.output  # a usage error (new-user trial 6)
    out = tmp_path / "never.json"
    r = CliRunner().invoke(cli, args(params, paths, "--alpha", "2", "-o", str(out)))
    assert r.exit_code != 0 and not out.exists()


def test_an_axis_files_diagnosis_does_not_replace_a_robot_fit_without_force(case, tmp_path):
    """Trial 18: `diagnose --params axis.json ... -o robot.json` replaced the robot fit there without
    --force ("parameters written as given"); fit refuses it. A parameter file of the other kind is
    now kept unless --force, as any other file."""
    d, params, paths = case
    robot = tmp_path / "robot.json"
    text = '{"schema": "kukaid.robot_params/1", "robot": {"urdf": "kr6-r700-sixx"}}'
    robot.write_text(text)
    r = CliRunner().invoke(cli, args(params, paths, "--max-steps", "0", "-o", str(robot)))
    assert r.exit_code == 1 and "already exists and is a kukaid.robot_params/1 file" in r.output, r.output
    assert robot.read_text() == text
    r = CliRunner().invoke(cli, args(params, paths, "--max-steps", "0", "-o", str(robot), "--force"))
    assert r.exit_code == 0, r.output
    assert '"kukaid.params/1"' in robot.read_text()


def test_show_of_a_refined_file(case, tmp_path):
    """`kukaid show` of the file diagnose refined: the fit's residual warning was of the model without
    the effect (it goes once the effect explains the gap), and the effect's std stands beside its values."""
    from kukaid.identify.adequacy import with_effects

    d, params, paths = case
    fitted = json.loads(params.read_text())
    warning = "residual 5.69 x the noise floor: the model misses an effect (run kukaid diagnose)"
    kept = [w for w in fitted["metrics"].get("warnings", []) if not w.startswith("residual ")]
    fitted["metrics"].update(residual_over_noise=5.69, warnings=[*kept, warning])  # as a fit writes it
    (tmp_path / "p.json").write_text(json.dumps(fitted))
    refined = tmp_path / "refined.json"
    r = CliRunner().invoke(cli, args(tmp_path / "p.json", paths, "-o", str(refined)))
    assert r.exit_code == 0, r.output
    s = CliRunner().invoke(cli, ["show", str(refined)])
    assert s.exit_code == 0, s.output
    assert "misses an effect" not in s.stdout and "{" not in s.stdout
    # with their units (new-user trial 17: "n 28.98, a 1.453 +- 0.00902, ..." said none)
    assert re.search(r"position_ripple n [\d.]+ 1/rad, a -?[\d.]+ \+- [\d.]+ N·m, b -?[\d.]+ \+- [\d.]+ N·m, "
                     r"A [\d.]+ N·m, phi -?[\d.]+ rad", s.stdout), s.stdout
    assert re.search(r"parameters at this step: n = [\d.]+ 1/rad, a = -?[\d.]+ \+/- [\d.]+ N·m", r.stdout), r.stdout
    # still far above the noise with the effect: both figures, and which effects they include
    m = with_effects(fitted["metrics"], ["position_ripple"], 0.9, 0.6, 0.1)
    assert warning not in m["warnings"]
    assert any("5.69 x the noise floor in the fit; with the effects diagnose added (position_ripple) 9 -> 6 x" in w
               for w in m["warnings"])


def test_a_refined_file_keeps_the_fits_figures_as_the_original_fits(case, tmp_path):
    """New-user trial nu12 item 4: the refined file kept the fit's MSEs and residual correlation factor as
    its own, so `show` and `report` printed error figures about 40 x too large for it and told the
    reader to multiply its HAC standard deviations by the factor.  They are now under
    metrics.original_fit, said to be of the model without the effects; the file's own figures are
    diagnose's refit's."""
    d, params, paths = case
    fitted = json.loads(params.read_text())
    refined = tmp_path / "refined.json"
    r = CliRunner().invoke(cli, args(params, paths, "--json", "-o", str(refined)))
    assert r.exit_code == 0, r.output
    m = json.loads(refined.read_text())["metrics"]
    assert m["original_fit"]["torque_prediction_mse"] == fitted["metrics"]["torque_prediction_mse"]
    assert "torque_prediction_mse" not in m and "residual_correlation_factor" not in m and "correlation" not in m
    assert m["torque_rmse"] == pytest.approx(json.loads(r.stdout)["rmse_after"])
    s = CliRunner().invoke(cli, ["show", str(refined)]).stdout
    assert "multiply by the residual correlation factor" not in s, s
    assert "original fit, without the effects diagnose added: friction fit MSE" in s, s
    assert f"torque RMSE {m['torque_rmse']:.4g} N·m on the logs diagnose was given" in s and "HAC" in s, s
    # diagnosed again: the fit's figures stay the fit's, not the first refinement's
    again = tmp_path / "again.json"
    r = CliRunner().invoke(cli, args(refined, paths, "-o", str(again)))
    assert r.exit_code == 0, r.output
    m2 = json.loads(again.read_text())["metrics"]
    assert m2["original_fit"] == m["original_fit"]


def test_options_a_robot_file_refuses_say_why(tmp_path):
    """--axis, --cutoff and --alpha with a robot parameter file: the line said "the robot diagnosis
    prints its findings (--json for a machine)" whatever the option; now why that option does not apply."""
    from kukaid.identify.robot_fit import fit_robot
    from kukaid.logs import write_hdf5
    from kukaid.models.robot import RobotModel
    from kukaid.params import save_robot_params
    from robot_sim_helpers import simulated_log

    kr6 = RobotModel("kr6-r700-sixx")
    log, _ = simulated_log(kr6, duration=5.0, seed=0)
    write_hdf5(log, tmp_path / "rec.h5")
    save_robot_params(tmp_path / "robot.json", fit_robot([log], kr6))
    for opt, why in ((["--axis", "2"], "every axis together"), (["--cutoff", "5"], "as the robot fit did"),
                     (["--alpha", "0.05"], "drop of the held-out error")):
        r = CliRunner().invoke(cli, ["diagnose", "--params", str(tmp_path / "robot.json"), "--log",
                                     str(tmp_path / "rec.h5"), *opt])
        assert r.exit_code == 2 and len(r.output.strip().splitlines()) == 1, r.output
        assert f"option {opt[0]} does not apply to a robot parameter file (yet): " in r.stderr and why in r.stderr
        assert "prints its findings" not in r.stderr


def test_when_the_backward_step_would_drop_every_effect_the_last_one_stands():
    """A one-axis fit of the LWR4+'s A4 diagnosed on lwr4_2 and lwr4_3 (the other joints move): coupling
    was found, then a Stribeck rise; the backward step dropped the rise (0.62 N·m, below 0.15 x the
    residual) and then coupling as well, and the steps kept the first (coupling) while the model had
    none: "internal error (KeyError: 'coupling')" (the time stamps put on their grid changed the rows
    compared). The last effect standing is now kept in the model as in the steps."""
    from shared_data import SHARED

    lwr4 = SHARED / "datasets" / "lwr4"
    if not lwr4.is_dir():
        pytest.skip("real LWR4+ data (../shared/datasets/lwr4) not present")
    from kukaid.diagnose import diagnose
    from kukaid.identify.fit import fit_axis_auto
    from kukaid.logs import read_log

    params = fit_axis_auto(logs=[read_log(lwr4 / "lwr4_1.csv")], axis=4)  # as kukaid fit lwr4_1.csv --axis 4
    res = diagnose(params, [read_log(lwr4 / f"lwr4_{k}.csv") for k in (2, 3)], axis=4)
    assert [s.name for s in res.steps] == ["coupling"], [s.name for s in res.steps]
    assert "coupling" in (res.params.get("effects") or {})


def test_a_presliding_log_alone_is_one_line_naming_it(tmp_path):
    """New-user trial 21: `diagnose --params p.json --log presliding.h5` printed a warning that the log's
    1.02 degrees looked like radians under a degree header (the pre-sliding experiment moves that little by
    design), then `kukaid: error: fewer than 50 dynamic-mode samples in the logs: ...` naming no log.  Now
    one line that names it and says which logs to give."""
    from kukaid import excite
    from kukaid.logs import write_hdf5
    from kukaid.params import save_params
    from kukaid.sim import SimConfig, VirtualKRC4

    log = VirtualKRC4(SimConfig(), seed=3).run(excite.generate("presliding", hold=2.0, final_hold=2.0))
    write_hdf5(log, tmp_path / "presliding.h5")
    save_params(tmp_path / "p.json", SimConfig().truth_params())
    r = CliRunner().invoke(cli, ["diagnose", "--params", str(tmp_path / "p.json"), "--log",
                                 str(tmp_path / "presliding.h5")])
    assert r.exit_code == 1, r.output
    err = r.stderr.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"kukaid: error: {tmp_path / 'presliding.h5'}: fewer than 50"), err
    assert "kukaid excite" in err[0]
