"""One protocol for both parameter files (kukaid.identify.fitted): a one-axis file is a robot of one
joint, and validate, show, report and diagnose ask the protocol, not the schema."""
from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from click.testing import CliRunner

from kukaid.diagnose.validate import score, validate
from kukaid.errors import OptionError, ParamFileError
from kukaid.identify.fitted import AxisFile, RobotFile, load_model, model_for
from kukaid_cli.main import cli

from test_validate import TRUE, sine_log


@pytest.fixture(scope="module")
def robot_case():
    from kukaid.identify.robot_fit import fit_robot
    from kukaid.models.robot import RobotModel
    from robot_sim_helpers import simulated_log

    kr6 = RobotModel("kr6-r700-sixx")
    log, _ = simulated_log(kr6, duration=5.0, seed=0)
    return fit_robot([log], kr6), log


def axis_case():
    params = {"schema": "kukaid.params/1", "axis": 3,
              "friction": {"model": "coulomb-viscous", "Fc": TRUE["Fc"], "Fv": TRUE["Fv"]},
              "inertial": {"Izz": TRUE["Izz"], "Mx": TRUE["Mx"]}}
    return params, sine_log(3, 0.2)


@pytest.mark.parametrize("kind", ["axis", "robot"])
def test_both_files_answer_one_protocol(kind, robot_case, tmp_path):
    params, log = axis_case() if kind == "axis" else robot_case
    model = model_for(params)
    assert type(model) is (AxisFile if kind == "axis" else RobotFile)
    assert model.joints == ((3,) if kind == "axis" else (1, 2, 3, 4, 5, 6))
    model.check(log)
    pairs = model.predict(log)
    assert tuple(pairs) == model.joints
    for tau, hat in pairs.values():
        assert tau.shape == hat.shape and tau.size > 100
        assert np.linalg.norm(tau - hat) < 0.2 * np.linalg.norm(tau)
    scores = validate(model, [log])  # one code path: validate scores what predict gives
    assert {a: replace(s, noise_floor=0.0) for a, s in scores.items()} == \
        {a: replace(score(*pairs[a]), noise_floor=0.0) for a in model.joints}  # the floor beside, from the log
    assert validate(params, [log]) == scores
    one = model_for(params, axis=model.joints[-1])
    assert tuple(one.predict(log)) == (model.joints[-1],)
    np.testing.assert_array_equal(one.predict(log)[model.joints[-1]][1], pairs[model.joints[-1]][1])
    assert model.table().splitlines()[0]
    path = tmp_path / "p.json"
    model.save(path, model.check_file(json.loads(json.dumps(params)), "p.json"))
    back = load_model(path)
    assert type(back) is type(model) and back.joints == model.joints and back.source == str(path)


def test_the_robot_predicts_against_the_raw_torques_away_from_the_filter_edges(robot_case):
    params, log = robot_case
    tau, _ = model_for(params).predict(log)[2]
    edge = (log.n_samples - tau.size) // 2
    assert edge > 0 and tau.size == log.n_samples - 2 * edge
    np.testing.assert_array_equal(tau, log.channel("tau", 2)[edge:log.n_samples - edge])


def test_a_file_of_no_model_and_an_axis_it_does_not_model_are_refused(robot_case):
    with pytest.raises(ParamFileError, match="no model evaluator"):
        model_for({"schema": "other/1"})
    with pytest.raises(OptionError, match=r"parameters: the parameters are of axis A3, not A2 \(--axis 2\)"):
        model_for(axis_case()[0], axis=2)
    with pytest.raises(OptionError, match=r"parameters: the parameters are of axes A1..A6, not A7 \(--axis 7\)"):
        model_for(robot_case[0], axis=7)


@pytest.mark.parametrize("command", ["validate", "report", "diagnose", "run-admittance"])
def test_a_robot_file_refuses_an_axis_it_does_not_have_with_the_one_axis_files_line(robot_case, command, tmp_path):
    """validate said 'axis A7 is not in the robot parameter file' (exit 1), run-admittance 'Invalid value
    for --axis: 7: the robot of ... has axes A1..A6', report and diagnose that --axis does not apply."""
    from kukaid.logs import write_hdf5
    from kukaid.params import save_robot_params

    save_robot_params(tmp_path / "robot.json", robot_case[0])
    write_hdf5(robot_case[1], tmp_path / "log.h5")
    par, log = str(tmp_path / "robot.json"), str(tmp_path / "log.h5")
    args = {"validate": [log], "report": ["--log", log, "-o", str(tmp_path / "r.pdf")],
            "diagnose": ["--log", log], "run-admittance": ["-o", str(tmp_path / "run.h5")]}[command]
    r = CliRunner().invoke(cli, [command, "--params", par, "--axis", "7", *args])
    assert r.exit_code == 2 and r.stderr.strip().splitlines() == [
        f"kukaid: error: {par}: the parameters are of axes A1..A6, not A7 (--axis 7)"], r.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["log.h5", "robot.json"]


def test_a_robot_report_takes_only_logs(robot_case, tmp_path):
    """New-user trial 7: `report --params robot.json --log L --axis 3` said "a robot parameter file takes
    only --log", naming neither the option refused nor the file; now both, as diagnose does."""
    from kukaid.logs import write_hdf5
    from kukaid.params import save_robot_params

    par = str(tmp_path / "robot.json")
    save_robot_params(par, robot_case[0])
    write_hdf5(robot_case[1], tmp_path / "log.h5")
    log = str(tmp_path / "log.h5")
    for opt, named in ((["--axis", "2"], "option --axis does not"),
                       (["--friction", log], "option --friction does not"),
                       (["--friction", log, "--axis", "2"], "options --friction, --axis do not")):
        r = CliRunner().invoke(cli, ["report", "--params", par, "--log", log, *opt, "-o", str(tmp_path / "r.pdf")])
        assert r.exit_code == 2 and len(r.output.strip().splitlines()) == 1, r.output
        assert r.stderr.startswith(f"kukaid: error: {par}: {named} apply to a robot parameter file: its report "
                                   "takes only --log"), r.stderr
        assert not (tmp_path / "r.pdf").exists()
    r = CliRunner().invoke(cli, ["diagnose", "--params", par, "--log", log, "--axis", "2"])
    assert r.exit_code == 2 and r.stderr.startswith(f"kukaid: error: {par}: option --axis does not apply to a robot "
                                                    "parameter file"), r.stderr


def test_a_one_axis_file_refuses_a_log_without_its_axis_before_anything_else():
    """check() refuses the log (diagnose's 'other axes move' warning came first, about the wrong axis)."""
    from kukaid.errors import KukaidError

    params, _ = axis_case()
    log = sine_log(1, 0.2, axes=(1,))  # A1 only
    with pytest.raises(KukaidError, match="axis A3 of the parameter file is not in the log"):
        AxisFile(params).check(log)


def test_a_robot_files_recording_is_in_sample_wherever_it_is_and_whatever_its_name(robot_case, tmp_path):
    """fit --robot keeps its logs' fingerprints: validate's in-sample warning does not depend on the
    working folder or the file's name (the provenance's paths were typed relative to another folder)."""
    from kukaid.identify.fitted import in_sample
    from kukaid.models.robot import RobotModel
    from robot_sim_helpers import simulated_log

    params, log = robot_case
    other, _ = simulated_log(RobotModel("kr6-r700-sixx"), duration=5.0, seed=1)
    paths = [tmp_path / "renamed copy.h5", tmp_path / "another.h5"]
    assert in_sample(params, paths, None, [log, other]) == [paths[0]]


def test_report_and_validate_refuse_a_log_without_the_files_axis_with_one_line(tmp_path, monkeypatch):
    """report hinted "choose it with --axis", and --axis then was refused as another axis than the file's."""
    from kukaid.logs import write_hdf5

    params, _ = axis_case()
    monkeypatch.chdir(tmp_path)
    (tmp_path / "p.json").write_text(json.dumps(params))
    write_hdf5(sine_log(1, 0.2, axes=(1,)), tmp_path / "a1.h5")
    lines = []
    for args in (["report", "--params", "p.json", "--log", "a1.h5", "-o", "r.pdf"], ["validate", "a1.h5", "--params", "p.json"]):
        r = CliRunner().invoke(cli, args)
        assert r.exit_code == 1 and not (tmp_path / "r.pdf").exists()
        lines.append(r.stderr.strip())
    assert lines[0] == lines[1] == "kukaid: error: a1.h5: axis A3 of the parameter file is not in the log (axes: [1])"


def test_a_log_without_the_axis_names_where_the_axis_came_from(tmp_path, monkeypatch):
    """New-user trial 9: a one-axis file without an axis field, given --axis 2 (or no --axis: A3 by
    default), and a log without that axis: validate, report and diagnose said "axis A2 of the parameter
    file is not in the log", blaming the file for an axis that came from --axis or the default."""
    from kukaid.logs import write_hdf5

    params, _ = axis_case()
    params.pop("axis", None)
    monkeypatch.chdir(tmp_path)
    (tmp_path / "p.json").write_text(json.dumps(params))
    write_hdf5(sine_log(1, 0.2, axes=(1,)), tmp_path / "a1.h5")
    for axis, origin in ((["--axis", "2"], "A2 (--axis 2)"),
                         ([], "A3 (the default: the parameter file names no axis; --axis chooses one)")):
        lines = []
        for args in (["report", "--params", "p.json", "--log", "a1.h5", "-o", "r.pdf"],
                     ["validate", "a1.h5", "--params", "p.json"], ["diagnose", "--params", "p.json", "--log", "a1.h5"]):
            r = CliRunner().invoke(cli, [*args, *axis])
            assert r.exit_code == 1 and not (tmp_path / "r.pdf").exists(), r.output
            lines.append(r.stderr.strip())
        assert set(lines) == {f"kukaid: error: a1.h5: axis {origin} is not in the log (axes: [1])"}, lines


def test_a_robot_file_finds_its_urdf_after_the_project_moved_or_says_how_to_give_it(robot_case, tmp_path):
    """The file kept only the URDF's absolute path: a moved project failed with "robot '...': no such
    robot" (new-user trial 6).  Now the URDF is also looked for from the file's folder (robot.urdf_relative,
    or its name beside the file), the same URDF by its sha256; else one line naming it and --urdf."""
    import shutil
    from pathlib import Path

    from kukaid.logs import write_hdf5
    from kukaid.models.urdf import robot_urdf
    from kukaid.params import save_robot_params

    params, log = robot_case
    proj = tmp_path / "proj"
    (proj / "robot").mkdir(parents=True)
    (proj / "fits").mkdir()
    shutil.copy(robot_urdf("kr6-r700-sixx"), proj / "robot" / "kr6.urdf")
    save_robot_params(proj / "fits" / "p.json", {**params, "robot": {**params["robot"],
                                                                      "urdf": str(proj / "robot" / "kr6.urdf")}})
    assert json.loads((proj / "fits" / "p.json").read_text())["robot"]["urdf_relative"] == "../robot/kr6.urdf"
    write_hdf5(log, tmp_path / "log.h5")
    moved = tmp_path / "moved"
    proj.rename(moved)
    par = str(moved / "fits" / "p.json")

    def validate_cli(*more):
        return CliRunner().invoke(cli, ["validate", "--params", par, str(tmp_path / "log.h5"), *more])

    assert validate_cli().exit_code == 0                                   # ../robot/kr6.urdf from the file
    (moved / "robot" / "kr6.urdf").rename(moved / "fits" / "kr6.urdf")
    assert validate_cli().exit_code == 0                                   # its name beside the file
    (moved / "fits" / "kr6.urdf").rename(tmp_path / "kr6.urdf")
    r = validate_cli()
    assert r.exit_code == 1 and r.stderr.strip().splitlines() == [
        f"kukaid: error: {par}: its URDF {proj / 'robot' / 'kr6.urdf'} (robot.urdf) is not there, nor the same file "
        "beside the parameter file; give its new place with --urdf PATH"], r.output
    assert validate_cli("--urdf", str(tmp_path / "kr6.urdf")).exit_code == 0
    other = tmp_path / "other.urdf"
    other.write_text((tmp_path / "kr6.urdf").read_text().replace("<robot ", "<robot  ", 1))   # another file
    r = validate_cli("--urdf", str(other))
    assert r.exit_code == 1 and "not the URDF" in r.stderr and "robot.sha256" in r.stderr, r.output
    (moved / "fits" / "kr6.urdf").write_text(other.read_text())            # another URDF of its name: not taken
    assert "is not there, nor the same file" in validate_cli().stderr
    r = CliRunner().invoke(cli, ["run-admittance", "--params", par, "-o", str(tmp_path / "run.h5")])
    assert r.exit_code == 1 and "(robot.urdf) is not there" in r.stderr and not (tmp_path / "run.h5").exists()
    r = CliRunner().invoke(cli, ["show", par])                             # the table needs no URDF
    assert r.exit_code == 0 and Path(par).name not in r.stderr, r.output
    # new-user trial 13: it printed the masses in kg where the table has them as multiples of the URDF's,
    # without a word why
    (masses,) = [x for x in r.stdout.splitlines() if x.startswith("link masses")]
    assert masses.startswith("link masses kg: ") and masses.endswith(
        f"(its URDF {proj / 'robot' / 'kr6.urdf'} not found: --urdf PATH gives them as multiples of the URDF's)"), masses
    r = CliRunner().invoke(cli, ["show", par, "--urdf", str(tmp_path / "kr6.urdf")])
    assert r.exit_code == 0 and "link masses / URDF: " in r.stdout, r.output


def test_the_robot_report_says_the_cut_off_and_how_it_was_chosen(robot_case):
    """settings.cutoff and metrics.choices.cutoff were in the table of `show`, not in the report (trial 6)."""
    from kukaid.report.robot import page_base_parameters
    from pdf_layout import layout_problems

    params, _ = robot_case
    text = lambda p: " ".join(t.get_text() for t in page_base_parameters(p, "p.json").texts).replace("\n", " ")  # noqa: E731
    fig = page_base_parameters(params, "p.json")
    assert "low-pass 10 Hz: the default 10 Hz" in text(params) and layout_problems(fig) == []
    older = json.loads(json.dumps(params))
    del older["metrics"]["choices"]["cutoff"]
    older["settings"]["cutoff"] = 20.0
    assert "low-pass 20 Hz: settings.cutoff" in text(older)


@pytest.mark.parametrize("command", ["validate", "report", "diagnose"])
def test_a_files_cut_off_above_the_logs_nyquist_names_the_files_setting(robot_case, command, tmp_path):
    """A robot file's settings.cutoff of 500 Hz on a 250 Hz log: the error blamed the log alone
    (new-user trial 6); now it names the parameter file's setting."""
    from kukaid.logs import write_hdf5
    from kukaid.params import save_robot_params

    params, log = robot_case
    save_robot_params(tmp_path / "p.json", {**params, "settings": {**params["settings"], "cutoff": 500.0}})
    write_hdf5(log, tmp_path / "log.h5")
    par, lg = str(tmp_path / "p.json"), str(tmp_path / "log.h5")
    args = {"validate": [lg], "report": ["--log", lg, "-o", str(tmp_path / "r.pdf")], "diagnose": ["--log", lg]}
    r = CliRunner().invoke(cli, [command, "--params", par, *args[command]])
    lines = r.stderr.strip().splitlines()
    assert r.exit_code == 1 and len(lines) == 1 and not (tmp_path / "r.pdf").exists(), r.output
    assert lines[0].startswith(f"kukaid: error: {par}: its low-pass cut-off (settings.cutoff) does not suit this "
                               f"log: {lg}: filter cut-off 500 Hz must be in (0, "), lines


def test_validate_preprocesses_a_log_once_for_a_one_axis_file(monkeypatch):
    """Code review: validate pre-processed each log twice for a one-axis file, for the prediction and again
    for its noise floor; now compare() hands out both from one pre-processing, the floor as it was."""
    import kukaid.identify.filtering as filtering
    from kukaid.identify.adequacy import noise_floor
    from kukaid.identify.fitted import fit_settings

    params, log = axis_case()
    floor = noise_floor([filtering.preprocess(log, 3, **fit_settings(params))])  # what it was, pre-processed apart
    calls = []
    real = filtering.preprocess
    monkeypatch.setattr(filtering, "preprocess", lambda *a, **k: calls.append(1) or real(*a, **k))
    scores = validate(params, [log])
    assert len(calls) == 1 and scores[3].noise_floor == pytest.approx(floor, rel=1e-12)


def test_the_robot_reports_relative_sigma_is_fits_sigma_percent(robot_case):
    """New-user trial nu12 item 5: the report divided σ by the least-squares value (100-1000 x the
    estimate on the LWR4+), so it listed base parameters at 3 % that fit called not identifiable
    (504 %); now its column is fit's sigma %: σ x the correlation factor over |estimate|."""
    from kukaid.report.robot import page_base_parameters

    params = json.loads(json.dumps(robot_case[0]))
    bp = params["base_parameters"]
    bp["values"][0], bp["least_squares"][0], bp["sigma"][0] = 0.014, -2.246, 0.0705
    params["metrics"]["residual_correlation_factor"] = 5.75
    fig = page_base_parameters(params, "p.json")
    cells = {(r, c): cell.get_text().get_text() for ax in fig.axes for tab in ax.tables
             for (r, c), cell in tab.get_celld().items()}
    assert cells[(0, 5)] == "σ × cf / |est.|"
    assert cells[(1, 5)] == f"{100 * 0.0705 * 5.75 / 0.014:.0f} %"  # 2896 %, not 3.1 %


def test_show_does_not_give_masses_as_multiples_of_a_urdf_edited_since_the_fit(robot_case, tmp_path):
    """New-user trial 18: with the URDF at the path the file names edited since the fit (another link mass),
    `show` printed the fitted masses as multiples of the edited URDF's, and flagged bounds on them, without a
    word; validate refuses that URDF (its sha256).  Now the masses are given in kg, saying why."""
    import shutil

    from kukaid.models.urdf import robot_urdf
    from kukaid.params import save_robot_params

    params, _ = robot_case
    urdf = tmp_path / "kr6.urdf"
    shutil.copy(robot_urdf("kr6-r700-sixx"), urdf)
    save_robot_params(tmp_path / "p.json", {**params, "robot": {**params["robot"], "urdf": str(urdf)}})

    def masses():
        r = CliRunner().invoke(cli, ["show", str(tmp_path / "p.json")])
        assert r.exit_code == 0, r.output
        (line,) = [x for x in r.stdout.splitlines() if x.startswith("link masses")]
        return line

    assert masses().startswith("link masses / URDF: ")
    urdf.write_text(urdf.read_text().replace('<mass value="', '<mass value="1', 2))
    assert masses().startswith("link masses kg: ") and masses().endswith(
        f"(its URDF {urdf} is not the one the file was fitted with (its sha256): --urdf PATH of that one gives them "
        "as multiples of the URDF's)"), masses()
