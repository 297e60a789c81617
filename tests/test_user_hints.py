"""What a new user met (issue 25): units a file leaves open, in-sample validation, a log given in
another role, text that names the wrong thing, a bare `kukaid`.  Each one line, naming the option
that fixes it."""
from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from kukaid.logs import write_hdf5
from kukaid_cli.main import cli
from shared_data import SHARED
from test_validate import sine_log

EMPS = SHARED / "datasets" / "emps" / "DATA_EMPS.mat"


def _run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def _warnings(r) -> list[str]:
    return [line for line in r.stderr.splitlines() if line.startswith("kukaid: warning: ")]


# -- 2. units guessed without a word -----------------------------------------------------------
def _emps_like(path):
    """A drive recorded as EMPS is: metres, a voltage, and its gain (N/V) beside them."""
    from scipy.io import savemat

    t = np.arange(0, 4, 0.001)
    savemat(path, {"t": t[:, None], "qm": (0.1 + 0.1 * np.sin(t))[:, None], "vir": np.cos(t)[:, None],
                   "gtau": np.array([[35.15]])})


def test_a_mat_file_read_with_assumed_units_says_which_option_fixes_them(tmp_path):
    _emps_like(tmp_path / "d.mat")
    r = _run("load", tmp_path / "d.mat", "--time", "t", "--q", "qm", "--tau", "vir", "-o", tmp_path / "a.h5")
    assert r.exit_code == 0, r.output
    w = _warnings(r)
    assert len(w) == 2 and "--joint prismatic" in w[0] and "--tau-scale-var gtau" in w[1], w
    r = _run("load", tmp_path / "d.mat", "--time", "t", "--q", "qm", "--tau", "vir", "--tau-scale-var", "gtau",
             "--joint", "prismatic", "-o", tmp_path / "b.h5")
    assert r.exit_code == 0 and _warnings(r) == [], r.output


def test_the_emps_file_without_its_options_is_warned_about(tmp_path):
    if not EMPS.exists():
        pytest.skip("../shared/datasets/emps is not present")
    r = _run("load", EMPS, "--time", "t", "--q", "qm", "--tau", "vir", "--q-cmd", "qg", "-o", tmp_path / "e.h5")
    w = " ".join(_warnings(r))
    assert r.exit_code == 0 and "--joint prismatic" in w and "--tau-scale-var gtau" in w, r.output


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    d = tmp_path_factory.mktemp("hints")
    write_hdf5(sine_log(1, 0.25), d / "a.h5")
    write_hdf5(sine_log(2, 0.18, amp=0.7), d / "b.h5")
    r = _run("fit", d / "a.h5", "--friction-model", "coulomb-viscous", "-o", d / "p.json")
    assert r.exit_code == 0, r.output
    return d


def test_validate_on_the_fitted_log_says_the_figures_are_in_sample(fitted):
    r = _run("validate", "--params", fitted / "p.json", fitted / "a.h5", fitted / "b.h5")
    assert r.exit_code == 0, r.output
    assert _warnings(r) == [f"kukaid: warning: validate: {fitted / 'a.h5'}: the model of {fitted / 'p.json'} was "
                            "fitted on this log (its provenance): these figures are in-sample, not a validation; "
                            "give a log it did not see"]
    r = _run("validate", "--params", fitted / "p.json", fitted / "b.h5", "--json")
    assert r.exit_code == 0 and _warnings(r) == [] and json.loads(r.stdout)["axes"]["A3"], r.output


def test_a_one_axis_files_recording_is_in_sample_wherever_it_is_and_another_of_its_name_is_not(tmp_path,
                                                                                                  monkeypatch):
    """fit keeps its logs' fingerprints (as fit --robot does): the in-sample warning no longer depends
    on the working folder (new-user trial 6)."""
    import shutil

    fit_dir, elsewhere = tmp_path / "fit", tmp_path / "elsewhere"
    fit_dir.mkdir()
    elsewhere.mkdir()
    write_hdf5(sine_log(1, 0.25), fit_dir / "a.h5")
    write_hdf5(sine_log(2, 0.18, amp=0.7), elsewhere / "a.h5")       # another recording, the same name
    monkeypatch.chdir(fit_dir)
    assert _run("fit", "a.h5", "--friction-model", "coulomb-viscous", "-o", "p.json").exit_code == 0
    shutil.copy(fit_dir / "a.h5", elsewhere / "renamed.h5")          # the fitted recording, moved and renamed
    monkeypatch.chdir(elsewhere)
    r = _run("validate", "--params", fit_dir / "p.json", "a.h5", "renamed.h5")
    assert r.exit_code == 0, r.output
    assert [w.split(": ")[3] for w in _warnings(r) if "in-sample" in w] == ["renamed.h5"], r.stderr
    old = json.loads((fit_dir / "p.json").read_text())                # a file written before: paths only
    del old["provenance"]["log_fingerprints"]
    (fit_dir / "p.json").write_text(json.dumps(old))
    # one at a time: the same recording given twice is refused now, as fit and diagnose refuse it
    r = _run("validate", "--params", fit_dir / "p.json", fit_dir / "a.h5")
    assert [w.split(": ")[3] for w in _warnings(r) if "in-sample" in w] == [str(fit_dir / "a.h5")], r.stderr
    r = _run("validate", "--params", fit_dir / "p.json", "renamed.h5")
    assert r.exit_code == 0 and not [w for w in _warnings(r) if "in-sample" in w], r.stderr


def test_a_recording_converted_to_another_format_is_the_same_recording(fitted, tmp_path):
    """New-user trial 13: the fitted a.h5 written as CSV (`kukaid load a.h5 -o a.csv`: positions in degrees,
    read back in radians, the last bit of a sample changed) got another fingerprint, and validate called its
    figures a validation.  A file written before (the bytes' hash) still knows its recording."""
    from kukaid.logs import fingerprints, read_log

    assert _run("load", fitted / "a.h5", "-o", tmp_path / "a.csv").exit_code == 0
    h5, csv = read_log(fitted / "a.h5"), read_log(tmp_path / "a.csv")
    assert not np.array_equal(h5.q, csv.q)  # the conversion changed the samples' last bits
    assert fingerprints(h5)[0] == fingerprints(csv)[0] and fingerprints(h5)[1] != fingerprints(csv)[1]
    r = _run("validate", "--params", fitted / "p.json", tmp_path / "a.csv", fitted / "b.h5")
    assert [w for w in _warnings(r) if "in-sample" in w and "a.csv" in w], r.stderr
    old = json.loads((fitted / "p.json").read_text())
    old["provenance"]["log_fingerprints"] = [fingerprints(h5)[1]]  # as fit wrote it before
    (tmp_path / "old.json").write_text(json.dumps(old))
    r = _run("validate", "--params", tmp_path / "old.json", fitted / "a.h5", fitted / "b.h5")
    assert [w for w in _warnings(r) if "in-sample" in w and "a.h5" in w], r.stderr
    r = _run("fit", fitted / "a.h5", tmp_path / "a.csv", "--friction-model", "coulomb-viscous", "-o", tmp_path / "p.json")
    assert r.exit_code != 0 and "the same recording as" in r.output, r.output  # one recording twice


def test_report_warns_of_a_log_given_in_another_role_as_fit_does(fitted, tmp_path):
    """The issue's case: a friction capture given as --presliding draws a hysteresis page from a
    short quasi-static stretch; now with the role warning `fit` gives."""
    assert _run("excite", "friction", "--n-speeds", "2", "-o", tmp_path / "f.json").exit_code == 0
    assert _run("capture", tmp_path / "f.json", "-o", tmp_path / "f.h5").exit_code == 0
    r = _run("report", "--params", fitted / "p.json", "--presliding", tmp_path / "f.h5", "-o", tmp_path / "r.pdf")
    assert r.exit_code == 0, r.output
    assert _warnings(r) == [f"kukaid: warning: report: {tmp_path / 'f.h5'} was given as --presliding but records the "
                            "'friction' experiment (attribute 'experiment'): the pre-sliding page is drawn from the "
                            "wrong data; give it as --friction"]


def test_report_gives_validates_warnings(fitted):
    """report printed none of them (new-user trial 6): in-sample, other axes moving (and a pushed log)."""
    write_hdf5(sine_log(4, 0.2, axes=(3, 2)), fitted / "two.h5")     # A2 moves too
    logs = [fitted / "a.h5", fitted / "two.h5"]
    v = _run("validate", "--params", fitted / "p.json", *logs)
    r = _run("report", "--params", fitted / "p.json", *[x for lg in logs for x in ("--log", lg)],
             "-o", fitted / "r.pdf")
    assert v.exit_code == 0 and r.exit_code == 0, r.output
    said = [[w.split(": ", 3)[3] for w in _warnings(x)] for x in (v, r)]
    assert said[0] == said[1] and len(said[0]) == 2, said
    assert "in-sample" in said[0][1] and "other axes (A2) move" in said[0][0]


@pytest.mark.parametrize("command", ["validate", "diagnose"])
def test_a_log_in_n_mm_under_n_m_is_warned_about_as_a_mismatch(fitted, tmp_path, command):
    """New-user trial 21: a log whose torques were 1000 x the model's (N·mm under an N·m column) scored a
    relative error of 99.90 % and validate and diagnose said nothing, exit 0 (--strict too): torques k times
    the model's score 1 - 1/k, never the 100 % the warning waited for."""
    from kukaid.logs import AxisLog

    lg = sine_log(5, 0.2)
    big = AxisLog(lg.time, lg.q, 1000.0 * lg.tau, axes=lg.axes, attrs={"source_file": "big"})
    write_hdf5(big, tmp_path / "big.h5")
    args = ["--log", tmp_path / "big.h5"] if command == "diagnose" else [tmp_path / "big.h5", "--strict"]
    r = _run(command, "--params", fitted / "p.json", *args)
    said = " ".join(_warnings(r))
    assert "does not describe" in said and "no better than predicting" in said and "another unit" in said, r.output
    if command == "validate":
        assert r.exit_code == 4, r.output


def test_a_model_that_does_not_describe_the_log_is_warned_about_first_and_strict_fails(fitted, tmp_path):
    """A one-axis file validated on another robot's log scored 2226 % with no word (new-user trial 6):
    now an axis whose error is at least its measured torque is the first warning, --strict exits 4."""
    from kukaid.logs import AxisLog

    lg = sine_log(5, 0.2)
    small = AxisLog(lg.time, lg.q, 0.05 * lg.tau, axes=lg.axes, attrs={"source_file": "small"})  # a 20x weaker axis
    write_hdf5(small, tmp_path / "small.h5")
    for strict in ([], ["--strict"]):
        r = _run("validate", "--params", fitted / "p.json", tmp_path / "small.h5", fitted / "a.h5", *strict)
        assert r.exit_code == (4 if strict else 0) and "A3" in r.stdout, r.output
        w = _warnings(r)
        assert len(w) == 2 and w[0].startswith(f"kukaid: warning: validate: {tmp_path / 'small.h5'}: the model of "
                                               f"{fitted / 'p.json'} does not describe this log on A3: its error "), w
        assert "worse than predicting none; is it of another robot or axis, or in another unit?" in w[0]
        assert r.stderr.strip().splitlines()[-1] == ("kukaid: error: validate: completed with 2 warning(s) (--strict)"
                                                     if strict else w[-1])
    r = _run("validate", "--params", fitted / "p.json", fitted / "b.h5", "--strict")
    assert r.exit_code == 0 and r.stderr == "", r.output


# -- 3. misleading text ------------------------------------------------------------------------
def test_the_preprocessing_note_says_which_values_the_user_set(fitted, tmp_path):
    r = _run("fit", fitted / "a.h5", "--friction-model", "coulomb-viscous", "--cutoff", "3", "--edge", "10",
             "-o", tmp_path / "u.json")
    assert r.exit_code == 0, r.output
    why = json.loads((tmp_path / "u.json").read_text())["provenance"]["preprocess"]["why"]
    assert why.startswith("set by the user: --cutoff 3, --edge 10; order from the 250 Hz sample rate"), why
    assert "cut-off from" not in why and "edge = 5 periods" not in why and why in r.stdout
    default = json.loads((fitted / "p.json").read_text())["provenance"]["preprocess"]["why"]
    assert default.startswith("cut-off and order from the 250 Hz sample rate") and "user" not in default


@pytest.mark.parametrize("args, option", [(["--v-max", "10"], "--v-max"), (["--speeds", "0.1,10"], "--speeds")])
def test_an_unreachable_speed_names_the_option_given(tmp_path, args, option):
    r = _run("excite", "friction", *args, "-o", tmp_path / "f.json")
    assert r.exit_code == 2 and r.stderr.startswith(f"kukaid: error: excite: option {option}: "), r.output
    assert len(r.stderr.strip().splitlines()) == 1 and not (tmp_path / "f.json").exists()


def test_bare_kukaid_prints_the_help():
    r = _run()
    assert r.exit_code == 0 and r.stdout == _run("--help").stdout and r.stderr == ""
    assert r.stdout.startswith("Usage: ") and len(r.stdout.splitlines()) > 10
