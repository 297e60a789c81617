"""`kukaid report`: the PDF from a small simulated fit, its pages, and bad input -> one-line error, no PDF."""
from __future__ import annotations

import json
import re
from dataclasses import replace

import pytest
from click.testing import CliRunner

from kukaid import excite
from kukaid.identify import fit_axis
from kukaid.logs import write_hdf5
from kukaid.params import save_params
from kukaid.sim import SimConfig, VirtualKRC4
from kukaid_cli.main import cli
from pdf_layout import capture_pages, layout_problems

# truth away from the paper's values (Fc 15.70, Fs 17.56, vs 0.04, delta 2, Fv 14.15, Izz 2.28, Mx 18.48)
TRUTH = dict(Fc=13.4, Fs=16.9, vs=0.05, delta=1.6, Fv=11.8, Izz=2.05, Mx=21.3)


def _pages(path) -> int:
    return len(re.findall(rb"/Type\s*/Page(?![s\w])", path.read_bytes()))


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    d = tmp_path_factory.mktemp("report")
    cfg = SimConfig().replace(**TRUTH)
    short = {"friction": dict(n_speeds=5, span=0.6), "inertia": dict(period=3.0, ramp_periods=0.5, amplitude=0.5),
             "presliding": dict(hold=2.0, final_hold=2.0)}
    logs, paths = {}, {}
    for i, (kind, opts) in enumerate(short.items()):
        logs[kind] = VirtualKRC4(cfg, seed=10 + i).run(excite.generate(kind, **opts))
        paths[kind] = d / f"{kind}.h5"
        write_hdf5(logs[kind], paths[kind])
    params = fit_axis(friction=[paths["friction"]], inertia=[paths["inertia"]], presliding=paths["presliding"])
    paths["params"] = d / "params.json"
    save_params(paths["params"], params)
    return d, paths, logs, params


def _run(args):
    return CliRunner().invoke(cli, ["report", *map(str, args)])


def test_full_report_has_every_page(fitted):
    d, p, _, _ = fitted
    out = d / "full.pdf"
    r = _run(["--params", p["params"], "--friction", p["friction"], "--inertia", p["inertia"],
              "--presliding", p["presliding"], "-o", out])
    assert r.exit_code == 0, r.output
    assert out.read_bytes()[:5] == b"%PDF-"
    # parameters, friction, inertia prediction, pre-sliding, correlation + residuals
    assert _pages(out) == 5
    assert not [x for x in d.iterdir() if x.name.endswith(".tmp")]


def test_pages_follow_the_data_given(fitted):
    d, p, _, _ = fitted
    only = d / "only.pdf"
    r = _run(["--params", p["params"], "-o", only])
    assert r.exit_code == 0, r.output
    assert _pages(only) == 1  # the parameter page always, nothing else without data
    assert "report written, 1 page" in r.output and "1 pages" not in r.output
    two = d / "two.pdf"
    r = _run(["--params", p["params"], "--log", p["inertia"], "--log", p["friction"], "-o", two])
    assert r.exit_code == 0, r.output
    assert _pages(two) == 4  # parameters, two predictions, correlation + residuals


def test_library_pages_truth_and_caveat(fitted):
    from kukaid.report import build_report, load_report_data
    from kukaid.report.correlation import page_correlation
    from kukaid.report.parameters import page_parameters
    from kukaid.report.presliding import presliding_replay

    _, p, logs, params = fitted
    data = load_report_data(params, friction=[logs["friction"]], inertia=[logs["inertia"]],
                            presliding=logs["presliding"])
    assert data.truth is not None and data.truth["friction"]["Fc"] == pytest.approx(TRUTH["Fc"])
    figs = build_report(data)
    assert len(figs) == 5
    for fig in figs:
        assert not layout_problems(fig)
    text = " ".join(t.get_text() for t in figs[0].texts)
    assert "OPTIMISTIC" in text
    cf = params["metrics"]["residual_correlation_factor"]
    assert f"{cf:.2f}" in text
    cells = " ".join(c.get_text().get_text() for ax in figs[0].axes for tab in ax.tables
                     for c in tab.get_celld().values())
    assert "truth" in cells and "0.5249" in cells and "14.59" in cells
    # the Maxwell-slip model replayed on the fitted path reproduces the hysteresis as the fit reported
    rp = presliding_replay(data)
    assert rp["rms"] == pytest.approx(params["metrics"]["maxwell_slip_rms"], rel=0.05, abs=0.02)
    # without a stored correlation matrix (staged fits) the report computes one from the logs
    bare = json.loads(json.dumps(params))
    bare["metrics"].pop("correlation", None)
    data2 = load_report_data(bare, friction=[logs["friction"]], inertia=[logs["inertia"]])
    fig = page_correlation(data2)
    assert fig is not None and "computed by the report" in fig.axes[0].get_title()
    # the cut-off as the fit summary prints it (:.4g), whatever digits the parameter file stores
    odd = json.loads(json.dumps(params))
    odd["provenance"]["preprocess"]["cutoff"] = 5.0001234
    fig = page_correlation(load_report_data(odd, friction=[logs["friction"]], inertia=[logs["inertia"]]))
    labels = [t.get_text() for ax in fig.axes if ax.get_legend() for t in ax.get_legend().get_texts()]
    assert "filter cut-off 5 Hz" in labels
    # a general log is named so in the provenance
    text = " ".join(t.get_text() for t in page_parameters(load_report_data(params, logs=[logs["inertia"]])).texts)
    assert "general log in this report" in text and "log log" not in text
    # a prismatic axis (a force, N): its mass is named so and nothing sits beside the paper's torques
    pris = json.loads(json.dumps(params))
    pris["provenance"]["joint"] = "prismatic"
    fig = page_parameters(load_report_data(pris))
    cells = " ".join(c.get_text().get_text() for ax in fig.axes for tab in ax.tables for c in tab.get_celld().values())
    assert "M (Izz: mass)" in cells and "N²" in cells and "0.5249" not in cells and "14.59" not in cells
    assert not layout_problems(fig)


def test_pages_keep_a_margin_and_long_text_wraps(fitted, monkeypatch):
    """Every text and table of every page 10 pt or more inside the page, the title clear of the
    subtitle; a long parameter-file path wraps within the page."""
    d, p, _, _ = fitted
    deep = d / ("a_long_directory_name_" * 4) / "the_parameters_of_a_long_campaign.json"
    deep.parent.mkdir()
    deep.write_text(p["params"].read_text())
    import shutil

    logs = {k: deep.parent / (f"{k}_log_of_a_long_measurement_campaign_" * 2 + ".h5")
            for k in ("inertia", "presliding")}
    for k, dst in logs.items():  # the prediction and pre-sliding pages name their log under the title
        shutil.copy(p[k], dst)
    problems = capture_pages(monkeypatch)
    out = d / "margins.pdf"
    r = _run(["--params", deep, "--friction", p["friction"], "--inertia", p["inertia"], "--presliding",
              logs["presliding"], "--log", logs["inertia"], "-o", out])
    assert r.exit_code == 0, r.output
    assert _pages(out) == 6 and not problems, problems


def test_broken_param_file_gives_one_line_error_and_no_pdf(fitted):
    d, p, _, _ = fitted
    bad = d / "bad.json"
    bad.write_text('{"schema": "kukaid.params/1", "axis": 3, "friction": {"model": "stribeck"')
    out = d / "bad.pdf"
    r = _run(["--params", bad, "--inertia", p["inertia"], "-o", out])
    assert r.exit_code != 0
    assert r.output.startswith("kukaid: error:") and "bad.json" in r.output and "not valid JSON" in r.output
    assert len(r.output.strip().splitlines()) == 1
    assert not out.exists()
    missing = json.loads(p["params"].read_text())
    del missing["inertial"]["Izz"]
    bad.write_text(json.dumps(missing))
    r = _run(["--params", bad, "-o", out])
    assert r.exit_code != 0 and "inertial.Izz" in r.output and not out.exists()


def test_bad_logs_give_one_line_error_and_no_pdf(fitted):
    d, p, logs, _ = fitted
    out = d / "x.pdf"
    r = _run(["--params", p["params"], "--inertia", d / "nope.h5", "-o", out])
    assert r.exit_code != 0 and "nope.h5" in r.output and "no such file" in r.output
    assert len(r.output.strip().splitlines()) == 1 and not out.exists()
    other = d / "axis1.h5"
    write_hdf5(replace(logs["inertia"], axes=(1,)), other)
    r = _run(["--params", p["params"], "--inertia", other, "-o", out])
    assert r.exit_code != 0 and "A3" in r.output and "axis1.h5" in r.output
    assert len(r.output.strip().splitlines()) == 1 and not out.exists()
    r = _run(["--params", p["params"], "--inertia", p["inertia"], "--axis", "2", "-o", out])
    assert r.exit_code != 0 and "A2" in r.output and not out.exists()
    assert not [x for x in d.iterdir() if x.name.endswith(".tmp")]


def test_a_six_axis_log_is_reported_with_a_one_axis_parameter_file(fitted):
    """A log of the six-axis virtual KR C4 carries the whole robot's truth (lists per axis): the
    one-axis report draws its pages without it instead of failing on a list (as validate does)."""
    pytest.importorskip("pinocchio")
    from kukaid.excite.fourier import fourier
    from kukaid.sim.robot_plant import RobotSimConfig, VirtualRobotKRC4
    from robot_helpers import ROBOT

    d, p, _, _ = fitted
    traj = fourier(ROBOT, harmonics=2, period=4.0, periods=1, iterations=0, starts=1)
    six = d / "fourier.h5"
    write_hdf5(VirtualRobotKRC4(RobotSimConfig(robot=ROBOT), seed=2).run(traj, settle=0.2), six)
    for role in ("--log", "--inertia"):
        out = d / f"six{role}.pdf"
        r = _run(["--params", p["params"], role, six, "-o", out])
        assert r.exit_code == 0, r.output
        assert _pages(out) >= 2


def test_prediction_pages_predict_with_the_files_effects_as_validate_does(fitted):
    """A file diagnose refined (an effect in ``effects``): the report's prediction page and residual
    statistics use the effect, as validate does; its MSE is validate's on the same samples."""
    import numpy as np

    from kukaid.identify.fitted import AxisFile
    from kukaid.report import load_report_data
    from kukaid.report.prediction import page_prediction

    _, _, logs, params = fitted
    refined = json.loads(json.dumps(params))
    refined["effects"] = {"position_ripple": {"model": "kukaid.diagnose/1", "n": 12.0, "a": 1.3, "b": 0.7}}
    data = load_report_data(refined, inertia=[logs["inertia"]])
    log, pr = data.inertia[0]
    title = page_prediction(data, log, pr).axes[0].get_title(loc="left")
    mse = float(re.search(r"samples: ([0-9.e+-]+)", title).group(1))
    tau, tau_hat = AxisFile(refined).predict(log)[3]
    assert mse == pytest.approx(float(np.mean((tau - tau_hat) ** 2)), rel=1e-3)
    plain = page_prediction(load_report_data(params, inertia=[logs["inertia"]]), log, pr).axes[0].get_title(loc="left")
    assert plain != title  # the ripple is in the prediction: not the file's terms alone


def test_a_prediction_page_of_a_log_the_model_was_fitted_on_is_not_called_a_validation(fitted):
    """New-user trial nu12 item 18: the page of a general log the fit saw was titled "(validation)"
    under the warning that its figures are in-sample; the residual legend said "not fitted" on a
    page where nothing is fitted."""
    from kukaid.report import load_report_data
    from kukaid.report.prediction import page_prediction

    _, p, logs, _ = fitted
    unseen = VirtualKRC4(SimConfig().replace(**TRUTH), seed=99).run(excite.generate("inertia", period=3.0,
                                                                                    ramp_periods=0.5, amplitude=0.5))
    data = load_report_data(p["params"], logs=[p["inertia"], unseen])
    titles = [page_prediction(data, log, pr, "general").texts[0].get_text() for log, pr in data.general]
    assert titles[0].endswith("(in-sample)") and titles[1].endswith("(validation)"), titles
    legend = page_prediction(data, *data.general[1], "general").axes[1].get_legend().get_title().get_text()
    assert legend == "grey: not compared (quasi-static / near a reversal)"


def test_a_model_that_does_not_describe_the_log_is_warned_about_as_validate_does(fitted, tmp_path):
    """New-user trial 16: `kukaid report --params params.json (the virtual KR C4's A3) --log lwr4_3.csv` wrote
    the PDF without the warning validate and diagnose give (a model of another robot or axis, or another unit)."""
    d, p, _, params = fitted
    nmm = json.loads(p["params"].read_text())
    for k in ("Fc", "Fs", "Fv"):
        nmm["friction"][k] *= 1000.0                    # N·mm
    for k in nmm["inertial"]:
        nmm["inertial"][k] *= 1000.0
    (tmp_path / "nmm.json").write_text(json.dumps(nmm))
    for k, (f, warned) in enumerate(((tmp_path / "nmm.json", True), (p["params"], False))):
        r = _run(["--params", f, "--log", p["inertia"], "-o", tmp_path / f"r{k}.pdf"])
        assert r.exit_code == 0, r.output
        said = [ln for ln in r.stderr.splitlines() if "does not describe this log" in ln]
        assert len(said) == int(warned), r.stderr


def test_a_presliding_log_given_as_presliding_is_not_taken_for_radians_under_degrees(fitted):
    """New-user trial 21: `make demo`'s report warned `presliding.h5: the position of A3 spans only 1.02
    degrees ... radians written under a degree header?` for the pre-sliding log given as --presliding,
    whose experiment moves a fraction of a degree by design (fit says nothing about it in that role)."""
    d, p, _, _ = fitted
    out = d / "psl.pdf"
    r = _run(["--params", p["params"], "--presliding", p["presliding"], "-o", out])
    assert r.exit_code == 0, r.output
    assert "degree header" not in r.stderr, r.stderr
    r = _run(["--params", p["params"], "--log", p["presliding"], "-o", d / "psl_log.pdf"])
    assert r.exit_code == 0 and "degree header" not in r.stderr, r.stderr  # the log says it is a pre-sliding one
