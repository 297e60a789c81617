"""`kukaid fit` end to end: parameter file, table, and bad input -> one-line error, no file."""
from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from kukaid import excite
from kukaid.logs import AxisLog, write_hdf5
from kukaid.params import load_params
from kukaid.sim import SimConfig, VirtualKRC4
from kukaid_cli.main import cli

TRUTH = dict(Fc=13.4, Fs=16.9, vs=0.05, delta=1.6, Fv=11.8, Izz=2.05, Mx=21.3)


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    d = tmp_path_factory.mktemp("fitcli")
    cfg = SimConfig().replace(**TRUTH)
    paths = {}
    for kind, opts in (("friction", dict(n_speeds=6)), ("inertia", {}), ("presliding", {})):
        log = VirtualKRC4(cfg, seed=4).run(excite.generate(kind, **opts))
        paths[kind] = d / f"{kind}.h5"
        write_hdf5(log, paths[kind])
    return d, paths


def test_fit_writes_params_and_table(logs):
    d, p = logs
    out = d / "params.json"
    r = CliRunner().invoke(cli, ["fit", "--friction", str(p["friction"]), "--inertia", str(p["inertia"]),
                                 "--presliding", str(p["presliding"]), "-o", str(out)])
    assert r.exit_code == 0, r.output
    assert "Fc" in r.output and "+-" in r.output and "IPOPT" in r.output
    par = load_params(out)
    assert par["friction"]["model"] == "stribeck"
    assert par["inertial"]["Mx"] == pytest.approx(TRUTH["Mx"], rel=0.02)
    assert len(par["maxwell_slip"]["k"]) <= 3 and "uncertainty" in par and "metrics" in par
    assert par["metrics"]["ipopt_status"] == "Solve_Succeeded"
    # new-user trial 10: the +- are least-squares sigmas of white residuals, about 3x optimistic on these
    # filtered ones; the table gave them with a note to multiply (stop 41's review: the robot table's
    # are multiplied already). It now gives them times the factor, as the robot table does
    cf = par["metrics"]["residual_correlation_factor"]
    assert cf > 1.5 and f"least-squares standard deviations x the residual correlation factor {cf:.3g}" in r.output
    fc_row = next(ln for ln in r.output.splitlines() if ln.strip().startswith("Fc "))
    assert float(fc_row.split("+-")[1].split()[0]) == pytest.approx(par["uncertainty"]["Fc"] * cf, rel=2e-3), fc_row


def test_general_log_coulomb_viscous_with_options(logs):
    d, p = logs
    out = d / "cv.json"
    r = CliRunner().invoke(cli, ["fit", str(p["friction"]), str(p["inertia"]), "--friction-model", "coulomb-viscous",
                                 "--gravity", "cos+sin", "--offset", "--cutoff", "4", "--order", "2", "-o", str(out)])
    assert r.exit_code == 0, r.output
    par = json.loads(out.read_text())
    assert par["friction"]["model"] == "coulomb-viscous" and "My" in par["inertial"] and "offset" in par


def test_staged_method_and_bounds(logs):
    d, p = logs
    out = d / "staged.json"
    r = CliRunner().invoke(cli, ["fit", "--friction", str(p["friction"]), "--inertia", str(p["inertia"]),
                                 "--method", "staged", "--bound", "delta=0.5:2", "-o", str(out)])
    assert r.exit_code == 0, r.output
    assert load_params(out)["provenance"]["method"] == "staged"


@pytest.mark.parametrize("model", ["coulomb-viscous", "auto"])
def test_staged_coulomb_viscous_keeps_the_bounds_given(logs, model):
    """New-user trial 10: `--method staged --friction-model coulomb-viscous --bound Fc=0:1` wrote Fc = 16.6
    (its linear fit took no bounds); with auto the Stribeck fit hit the bound and fell back to that fit.
    New-user trial 11: the warning blamed the data ("the data do not determine these") for the bound the user
    gave; now it names that bound."""
    d, p = logs
    out = d / f"staged_cv_{model}.json"
    r = CliRunner().invoke(cli, ["fit", "--friction", str(p["friction"]), "--inertia", str(p["inertia"]),
                                 "--method", "staged", "--friction-model", model, "--bound", "Fc=0:1", "-o", str(out)])
    assert r.exit_code == 0, r.output
    par = load_params(out)
    assert par["friction"]["model"] == "coulomb-viscous"
    assert 0 <= par["friction"]["Fc"] <= 1 + 1e-9
    assert [(b["name"], b["given"]) for b in par["metrics"]["at_bound"]] == [("Fc", True)]
    assert "on the bound --bound gave: Fc = 1 (upper bound): the value is that bound" in r.output, r.output
    assert "at a bound: Fc (upper 1, --bound)" in r.output and "the data do not determine" not in r.output


def test_the_table_of_a_linear_fit_at_a_bound_with_user_settings(logs):
    """New-user trial nu12 item 17: a linear fit printed "IPOPT: linear" (no IPOPT ran), a parameter on
    its bound 0 as "5.5062e-28" (table and warning), and --qd-thr, --decimate were missing from "(set
    by the user: ...)"."""
    from kukaid.identify.fit import format_params

    d, p = logs
    out = d / "linear.json"
    r = CliRunner().invoke(cli, ["fit", str(p["friction"]), str(p["inertia"]), "--friction-model", "coulomb-viscous",
                                 "--qd-thr", "0.002", "--decimate", "2", "--diff", "spectral", "-o", str(out)])
    assert r.exit_code == 0, r.output
    assert "IPOPT" not in r.output and "; linear least squares" in r.output, r.output
    assert "set by the user: --qd-thr 0.002, --decimate 2, --diff spectral" in r.output, r.output
    par = json.loads(out.read_text())
    par["friction"]["Fc"] = 5.5062e-28
    par["metrics"]["at_bound"] = [{"name": "Fc", "value": 5.5062e-28, "bound": 0.0, "side": "lower", "given": False}]
    (row,) = [x for x in format_params(par).splitlines() if x.startswith("  Fc ")]
    assert row.split()[1] == "0" and "e-28" not in format_params(par), row
    # a standard deviation from the curvature is no interval at an active bound (it printed "+- 0.321" for delta 2)
    assert "(at its lower bound)" in row and "+-" not in row, row
    from kukaid.identify.adequacy import assess

    warnings, _ = assess(3, 1.0, 1.0, [], par["metrics"]["at_bound"], True, "linear (bounded)")
    assert warnings[0].startswith("on a bound: Fc = 0 (lower bound)"), warnings


def _bad(tmp_path, log, name="bad.h5"):
    path = tmp_path / name
    write_hdf5(log, path)
    return path


@pytest.mark.parametrize("case", ["standstill", "one_direction", "too_short", "nan", "staged_no_pairs"])
def test_bad_input_clear_error_no_file(tmp_path, case, logs):
    t = np.arange(3000) * 0.012
    if case == "standstill":
        src = _bad(tmp_path, AxisLog(time=t, q=np.full(t.size, 0.3), tau=np.full(t.size, 4.0), axes=(3,)))
        args, msg = [str(src)], "no dynamic-mode samples"
    elif case == "one_direction":
        q = 0.05 * t
        src = _bad(tmp_path, AxisLog(time=t, q=q, tau=20 * np.cos(q) + 14, axes=(3,)))
        args, msg = [str(src)], "one direction"
    elif case == "too_short":
        src = _bad(tmp_path, AxisLog(time=t[:50], q=np.sin(t[:50]), tau=np.cos(t[:50]), axes=(3,)))
        args, msg = [str(src)], "too short"
    elif case == "nan":
        src = tmp_path / "nan.csv"
        src.write_text("time_s,A3_deg,A3_Nm\n0,1,2\n0.012,nan,2\n0.024,1,2\n")
        args, msg = [str(src)], "not a finite number"
    else:
        src = _bad(tmp_path, VirtualKRC4(SimConfig().replace(**TRUTH), seed=2).run(excite.generate("inertia")))
        args, msg = ["--friction", str(src), "--method", "staged"], "no pair"
    out = tmp_path / "params.json"
    r = CliRunner().invoke(cli, ["fit", *args, "-o", str(out)])
    assert r.exit_code != 0
    assert "kukaid: error:" in r.output and msg in r.output, r.output
    assert len(r.output.strip().splitlines()) == 1
    assert not out.exists()


def test_failed_solve_writes_nothing(tmp_path, logs, monkeypatch):
    import kukaid.identify.stribeck_fit as sf

    monkeypatch.setattr(sf, "_ipopt", lambda y, A, v, p0, lo, hi, max_iter=300: (p0, "Infeasible_Problem_Detected",
                                                                                   False, 3, 0.0))
    d, p = logs
    out = tmp_path / "params.json"
    r = CliRunner().invoke(cli, ["fit", "--friction", str(p["friction"]), "--inertia", str(p["inertia"]), "-o", str(out)])
    assert r.exit_code != 0 and "IPOPT did not converge" in r.output and "Infeasible" in r.output
    assert not out.exists()


@pytest.mark.parametrize("bound,msg", [("vs=0.1", "expected NAME=LO:HI"), ("vs=0.2:0.1", "lower 0.2 is above upper 0.1")])
def test_bad_bound_option(logs, tmp_path, bound, msg):
    d, p = logs
    out = tmp_path / "params.json"
    r = CliRunner().invoke(cli, ["fit", "--friction", str(p["friction"]), "--inertia", str(p["inertia"]),
                                 "--bound", bound, "-o", str(out)])
    assert r.exit_code != 0 and msg in r.output and not out.exists()


@pytest.mark.parametrize("args,msg", [
    (["--robot", "kr6-r700-sixx", "--friction", "{f}"], "option --friction does not apply with --robot"),
    (["--robot", "kr6-r700-sixx", "--axis", "2"], "option --axis does not apply with --robot"),
    (["--robot", "kr6-r700-sixx", "--method", "staged"], "option --method does not apply with --robot"),
    (["--robot", "kr6-r700-sixx", "--no-offset"], "option --no-offset does not apply with --robot"),
    (["--robot", "kr6-r700-sixx", "--bound", "vs=0:1"], "option --bound does not apply with --robot"),
    (["--robot", "kr6-r700-sixx", "--stribeck-vs", "0.1"], "--stribeck-vs needs --friction-model stribeck"),
    (["--robot", "kr6-r700-sixx", "--friction-model", "auto"], "--friction-model auto does not apply with --robot"),
    (["--robot", "kr6-r700-sixx", "--coupling", "{f}"], "--coupling needs --torque-side motor or --rotor-inertia"),
    (["--stribeck-vs", "0.1"], "option --stribeck-vs needs --robot"),
    (["--torque-side", "joint"], "option --torque-side needs --robot"),
    (["--rotor-inertia"], "option --rotor-inertia needs --robot"),
    (["--no-rotor-inertia"], "option --no-rotor-inertia needs --robot"),
    (["--elements", "2"], "option --elements needs --presliding"),
])
def test_option_of_the_other_fit_is_a_usage_error(logs, tmp_path, args, msg):
    """Options that the chosen fit (single-axis or --robot) does not use are refused, not ignored."""
    d, p = logs
    out = tmp_path / "params.json"
    args = [a.format(f=p["friction"]) for a in args]
    r = CliRunner().invoke(cli, ["fit", str(p["inertia"]), *args, "-o", str(out)])
    assert r.exit_code == 2, r.output
    assert msg in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert not out.exists()


def test_the_robot_fit_never_writes_over_its_coupling_matrix(tmp_path):
    """New-user trial 18: `fit LOG --robot ... --torque-side motor --coupling c.json -o c.json --force` replaced
    the coupling matrix it had read with the parameter file (both are JSON); the logs were checked, the
    coupling was not.  Now it is refused as any other input is, and the file is left as it was."""
    pytest.importorskip("pinocchio")
    from kukaid.logs import write_hdf5
    from kukaid.models.robot import RobotModel
    from robot_sim_helpers import simulated_log

    write_hdf5(simulated_log(RobotModel("kr6-r700-sixx"), duration=5.0, seed=0)[0], tmp_path / "arm.h5")
    coupling = tmp_path / "coupling.json"
    coupling.write_text(json.dumps([[0.0] * 6 for _ in range(6)]))
    before = coupling.read_bytes()
    r = CliRunner().invoke(cli, ["fit", str(tmp_path / "arm.h5"), "--robot", "kr6-r700-sixx", "--torque-side", "motor",
                                 "--coupling", str(coupling), "-o", str(coupling), "--force"])
    assert r.exit_code == 1, r.output
    assert r.stderr.strip().splitlines() == [f"kukaid: error: {coupling}: is also an input of this command; write "
                                             "the output elsewhere"]
    assert coupling.read_bytes() == before


def test_staged_without_friction_logs_is_a_usage_error(logs, tmp_path):
    d, p = logs
    out = tmp_path / "params.json"
    r = CliRunner().invoke(cli, ["fit", str(p["inertia"]), "--method", "staged", "-o", str(out)])
    assert r.exit_code == 2 and "the staged method needs --friction logs" in r.stderr and not out.exists()


def _table_params(joint, Fc=5.5062e-28, maxwell=False):
    p = {"axis": 1, "friction": {"model": "coulomb-viscous", "Fc": Fc, "Fv": 203.26},
         "inertial": {"Izz": 95.125}, "offset": -3.1986,
         "uncertainty": {"Fc": 0.898, "Fv": 0.381, "Izz": 0.0356, "offset": 0.0145},
         "metrics": {"friction_fit_mse": 5.155, "torque_prediction_mse": 5.155}, "provenance": {"joint": joint}}
    if maxwell:
        p["maxwell_slip"] = {"k": [1000.0], "W": [2.0], "zeta0": [0.0]}
    return p


def test_table_prints_no_percentage_for_an_estimate_below_its_sigma():
    from kukaid.identify.fit import format_table

    text = format_table(_table_params("revolute"))
    fc = next(line for line in text.splitlines() if line.strip().startswith("Fc"))
    assert "%" not in fc and fc.split()[-2] == "-", fc
    fv = next(line for line in text.splitlines() if line.strip().startswith("Fv"))
    assert "0.19 %" in fv
    fc = next(line for line in format_table(_table_params("revolute", Fc=0.0)).splitlines()
              if line.strip().startswith("Fc"))
    assert "%" not in fc


def test_table_units_of_a_prismatic_axis():
    from kukaid.identify.fit import format_table

    text = format_table(_table_params("prismatic", maxwell=True))
    assert "MSE 5.155 N²;" in text and "N²m²" not in text
    m = next(line for line in text.splitlines() if "95.125" in line)
    assert m.split()[0] == "M" and m.endswith(" kg") and "Izz" not in text, text  # the slide's mass
    assert "k = 1000 N/m" in text and "W = 2 N" in text and "N·m" not in text
    text = format_table(_table_params("revolute", maxwell=True))
    assert "MSE 5.155 N²m²" in text and "k = 1000 N·m/rad" in text and "W = 2 N·m" in text


def test_show_prints_the_table_fit_printed(logs):
    """`kukaid show FILE`: an axis parameter file's table, as fit printed it (issue 23)."""
    d, p = logs
    out = d / "show.json"
    r = CliRunner().invoke(cli, ["fit", "--friction", str(p["friction"]), "--inertia", str(p["inertia"]), "-o", str(out)])
    assert r.exit_code == 0, r.output
    s = CliRunner().invoke(cli, ["show", str(out)])
    assert s.exit_code == 0, s.output
    assert s.stdout.strip() == r.stdout.strip()
    (d / "other.json").write_text('{"schema": "something/1"}')
    s = CliRunner().invoke(cli, ["show", str(d / "other.json")])
    assert s.exit_code == 1 and "not a kukaid parameter file" in s.output and len(s.output.strip().splitlines()) == 1


def test_the_bound_examples_of_the_help_and_the_error_are_accepted(tmp_path):
    """New-user trial 16: `kukaid fit ... --bound vs=0:0.1`, the example of fit --help and of the
    malformed --bound error, failed: `bounds for vs: the lower bound must be > 0, got 0`."""
    import re

    from kukaid.errors import FitError
    from kukaid.identify.stribeck_fit import check_bound

    help_text = " ".join(CliRunner().invoke(cli, ["fit", "--help"]).output.split())
    bad = CliRunner().invoke(cli, ["fit", "x.h5", "--bound", "vs", "-o", str(tmp_path / "p.json")])
    examples = re.findall(r"--bound (\S+=\S*:\S*?)[ )]", help_text) + re.findall(r"e\.g\. (\S+=\S*:[\d.]+)", bad.output)
    examples = [ex for ex in examples if not ex.startswith("NAME=")]  # the metavar
    assert len(examples) >= 3, (help_text, bad.output)
    for ex in examples:
        name, rng = ex.split("=", 1)
        lo, hi = rng.split(":", 1)
        try:
            check_bound(name, float(lo) if lo else None, float(hi) if hi else None)
        except FitError as e:
            pytest.fail(f"{ex}: {e}")


def test_a_bound_below_what_a_parameter_file_holds_is_refused_before_the_fit(tmp_path):
    """New-user trial 16: `kukaid fit --friction friction.h5 --inertia inertia.h5 --bound Fc=-100:-1 -o neg.json`
    fitted, then said `neg.json: friction.Fc = -1.0 is outside the allowed range [0, 1e+06]`, the output named
    as if it were a broken input; a parameter file holds Fc, Fv >= 0: the option is refused first (exit 2)."""
    log = tmp_path / "x.h5"
    log.write_bytes(b"")   # never read: the option is refused first
    for bound, said in (("Fc=-100:-1", "bounds for Fc: the upper bound must be >= 0"),
                        ("Fv=:-0.5", "bounds for Fv: the upper bound must be >= 0")):
        r = CliRunner().invoke(cli, ["fit", "--friction", str(log), "--bound", bound, "-o", str(tmp_path / "p.json")])
        assert r.exit_code == 2 and said in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.output
    assert not (tmp_path / "p.json").exists()


def test_a_bound_on_izz_with_an_inertia_log_is_refused_not_printed_as_honoured(tmp_path):
    """New-user trial 16: `kukaid fit --friction friction.h5 --inertia inertia.h5 --bound Izz=2e6:3e6` printed
    "Izz 2e+06 ... at a bound: Izz (lower 2e+06, --bound)" while the file held Izz 53.9: the inertia logs'
    least squares (eqs. 6-8) takes no bounds and replaced the bounded value; the table showed the bound."""
    from kukaid.errors import OptionError
    from kukaid.identify import fit_axis

    with pytest.raises(OptionError, match=r"--bound Izz: with --inertia logs beside friction or general logs"):
        fit_axis(friction=["f.h5"], inertia=["i.h5"], bounds={"Izz": (2e6, 3e6)})  # before any log is read
    r = CliRunner().invoke(cli, ["fit", "--friction", "f.h5", "--inertia", "i.h5", "--bound", "Mx=0:1", "-o",
                                 str(tmp_path / "p.json")])
    assert r.exit_code == 2 and "--bound Mx: with --inertia logs" in r.stderr, r.output
    assert not (tmp_path / "p.json").exists()
