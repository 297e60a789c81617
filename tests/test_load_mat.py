"""MAT files as axis logs (`kukaid load`), and the EMPS real-data check of identification."""
from __future__ import annotations

import json
import os

import numpy as np
import pytest
from click.testing import CliRunner

from kukaid.errors import LogFormatError
from kukaid.identify import fit_axis
from kukaid.logs import read_hdf5, read_log
from kukaid_cli.main import cli
from shared_data import SHARED

EMPS = SHARED / "datasets" / "emps" / "DATA_EMPS.mat"
EMPS_OPTS = dict(time="t", q="qm", tau="vir", tau_scale_var="gtau", q_cmd="qg", joint="prismatic", axis=1)


@pytest.fixture
def small_mat(tmp_path):
    from scipy.io import savemat

    t = np.arange(500) * 0.001
    path = tmp_path / "x.mat"
    savemat(path, {"tt": t[:, None], "pos": np.sin(t)[:, None], "u": np.cos(t)[:, None], "g": np.array([[2.0]])})
    return path


def test_read_mat_mapping_and_scale(small_mat):
    log = read_log(small_mat, time="tt", q="pos", tau="u", tau_scale_var="g", joint="prismatic", axis=2)
    assert log.axes == (2,) and log.joint == ("prismatic",)
    assert np.allclose(log.tau[:, 0], 2 * np.cos(log.time))
    log = read_log(small_mat, time="tt", q="pos", tau="u", tau_scale=3.0, q_scale=np.pi / 180)
    assert np.allclose(log.q[:, 0], np.radians(np.sin(log.time)))


def test_read_mat_unknown_variable(small_mat):
    with pytest.raises(LogFormatError, match="no variable 'qm'.*variables: g, pos, tt, u"):
        read_log(small_mat, time="tt", q="qm", tau="u")


def test_cli_load_mat(small_mat, tmp_path):
    out = tmp_path / "o.h5"
    r = CliRunner().invoke(cli, ["load", str(small_mat), "--time", "tt", "--q", "pos", "--tau", "u",
                                 "--tau-scale", "35.15", "--joint", "prismatic", "--axis", "1", "-o", str(out)])
    assert r.exit_code == 0, r.output
    log = read_hdf5(out)
    assert log.joint == ("prismatic",) and np.allclose(log.tau[:, 0], 35.15 * np.cos(log.time))
    r = CliRunner().invoke(cli, ["load", str(small_mat), "--q", "nope", "--tau", "u", "-o", str(tmp_path / "n.h5")])
    assert r.exit_code != 0 and "no variable 'nope'" in r.output and not (tmp_path / "n.h5").exists()


@pytest.fixture(scope="module")
def emps():
    if not EMPS.exists():
        pytest.skip("../shared (EMPS data) not present")
    return read_log(EMPS, **EMPS_OPTS)


def test_emps_published_recipe_within_2_percent(emps):
    """Coulomb + viscous + offset + inertia, the published recipe: 4th order 100 Hz zero-phase,
    central differences, 50 edge samples, decimation by 10, all samples used."""
    p = fit_axis(logs=[emps], friction_model="coulomb-viscous", gravity="none", offset=True, cutoff=100.0, order=4,
                 edge=50, decimate=10, qd_thr=0.0, reversal_window=0.0)
    ref = {"M": 95.1089, "Fv": 203.5034, "Fc": 20.3935, "OF": -3.1648}
    got = {"M": p["inertial"]["Izz"], "Fv": p["friction"]["Fv"], "Fc": p["friction"]["Fc"], "OF": p["offset"]}
    for k in ref:
        assert got[k] == pytest.approx(ref[k], rel=0.02), (k, got[k], ref[k])


def test_emps_default_fit_within_2_percent(emps, tmp_path):
    """No options at all through the CLI: the Stribeck fit is not determined by these data (Fc and
    delta end on bounds), so Coulomb-viscous is kept; the prismatic axis's constant force is the
    offset; pre-processing from the sample rate."""
    from kukaid.logs import write_hdf5

    write_hdf5(emps, tmp_path / "emps.h5")
    r = CliRunner().invoke(cli, ["fit", str(tmp_path / "emps.h5"), "-o", str(tmp_path / "p.json")])
    assert r.exit_code == 0, r.output
    assert "friction model: coulomb-viscous: the Stribeck fit left" in r.output
    p = json.loads((tmp_path / "p.json").read_text())
    ref = {"M": 95.1089, "Fv": 203.5034, "Fc": 20.3935, "OF": -3.1648}
    got = {"M": p["inertial"]["Izz"], "Fv": p["friction"]["Fv"], "Fc": p["friction"]["Fc"], "OF": p["offset"]}
    for k in ref:
        assert got[k] == pytest.approx(ref[k], rel=0.02), (k, got[k], ref[k])
    r = CliRunner().invoke(cli, ["fit", str(tmp_path / "emps.h5"), "--gravity", "cos", "-o", str(tmp_path / "q.json")])
    _one_line_error(r, "prismatic", "emps.h5: --gravity cos")


def test_emps_stribeck_runs(emps, tmp_path):
    from kukaid.params import save_params

    p = fit_axis(logs=[emps], friction_model="stribeck", gravity="none", offset=True)
    assert p["metrics"]["ipopt_status"] in ("Solve_Succeeded", "Solved_To_Acceptable_Level")
    save_params(tmp_path / "emps.json", p)
    assert p["inertial"]["Izz"] == pytest.approx(95.1, rel=0.05)


def test_a_mat_file_without_q_and_tau_names_kukaid_load(small_mat, tmp_path):
    """New-user trial 13: `kukaid fit DATA_EMPS.mat` and `kukaid validate DATA_EMPS_PULSES.mat` said "name the
    position and torque variables (--q, --tau)", options neither command has: kukaid load names them."""
    from kukaid.params import save_params
    from kukaid.sim import SimConfig

    save_params(tmp_path / "p.json", SimConfig().truth_params())
    for args in (["fit", str(small_mat), "-o", str(tmp_path / "q.json")],
                 ["validate", str(small_mat), "--params", str(tmp_path / "p.json")],
                 ["load", str(small_mat), "-o", str(tmp_path / "x.h5")]):
        r = CliRunner().invoke(cli, args)
        _one_line_error(r, f"{small_mat}: no variables 'q' and 'tau'", f"kukaid load {small_mat} --q VAR --tau VAR -o "
                        "LOG.h5, and give LOG.h5; variables: g, pos, tt, u")
    assert sorted(os.listdir(tmp_path)) == ["p.json", "x.mat"]


# -- audit: text variables, scales, the torque scale given twice, unit mistakes --------------------
def _one_line_error(r, *parts):
    err = r.stderr if hasattr(r, "stderr") else r.output
    assert r.exit_code != 0 and err.startswith("kukaid: error: "), err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    for p in parts:
        assert str(p) in err, (p, err)
    return err


@pytest.fixture
def text_mat(tmp_path):
    from scipy.io import savemat

    t = np.arange(100) * 0.001
    path = tmp_path / "txt.mat"
    savemat(path, {"t": t[:, None], "pos": np.sin(t)[:, None], "u": np.cos(t)[:, None], "label": "measured torque",
                   "g": "35.15", "cell": np.array([["a"], [1.0]], dtype=object)})
    return path


@pytest.mark.parametrize("opts, var", [(dict(tau="label"), "label"), (dict(tau="u", tau_scale_var="g"), "g"),
                                       (dict(tau="u", q_cmd="cell"), "cell")])
def test_text_variable_is_not_numeric(text_mat, opts, var):
    with pytest.raises(LogFormatError, match=rf"txt.mat: variable '{var}' \(.*\) is not numeric"):
        read_log(text_mat, time="t", q="pos", **opts)


def test_text_variable_cli_one_line(text_mat, tmp_path):
    out = tmp_path / "o.h5"
    r = CliRunner().invoke(cli, ["load", str(text_mat), "--q", "pos", "--tau", "label", "-o", str(out)])
    _one_line_error(r, text_mat, "variable 'label' (torque) is not numeric: it holds text")
    assert not out.exists()


def _write_v73(path, variables):
    """A MATLAB v7.3 file: HDF5 behind the 128-byte MAT header, classes in attribute MATLAB_class."""
    import h5py

    with h5py.File(path, "w", userblock_size=512) as f:
        for name, (cls, data) in variables.items():
            d = f.create_dataset(name, data=data)
            d.attrs["MATLAB_class"] = np.bytes_(cls)
    head = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Jan  1 00:00:00 2024 HDF5 schema 1.00 ."
    with open(path, "r+b") as fh:
        fh.write(head.ljust(116) + b"\0" * 8 + b"\x00\x02IM")


def test_v73_char_variable_is_not_numeric(tmp_path):
    t = np.arange(100) * 0.001
    path = tmp_path / "v73.mat"
    _write_v73(path, {"t": ("double", t[None, :]), "pos": ("double", np.sin(t)[None, :]),
                      "u": ("double", np.cos(t)[None, :]),
                      "name": ("char", np.frombuffer("torque".encode("utf-16-le"), dtype="<u2")[:, None])})
    log = read_log(path, time="t", q="pos", tau="u")  # numeric v7.3 variables are read
    assert np.allclose(log.tau[:, 0], np.cos(t))
    with pytest.raises(LogFormatError, match=r"v73.mat: variable 'name' \(torque\) is not numeric: it holds text"):
        read_log(path, time="t", q="pos", tau="name")


@pytest.mark.parametrize("option, value", [("--tau-scale", "0"), ("--tau-scale", "nan"), ("--tau-scale", "inf"),
                                           ("--q-scale", "0"), ("--q-scale", "-inf"), ("--time-scale", "0"),
                                           ("--time-scale", "-1")])
def test_scale_must_be_finite_non_zero(small_mat, tmp_path, option, value):
    out = tmp_path / "o.h5"
    r = CliRunner().invoke(cli, ["load", str(small_mat), "--time", "tt", "--q", "pos", "--tau", "u", option, value,
                                 "-o", str(out)])
    _one_line_error(r, small_mat, f"({option}) must be a finite")
    assert not out.exists()
    with pytest.raises(LogFormatError, match=r"must be a finite (non-zero|positive) number"):
        read_log(small_mat, time="tt", q="pos", tau="u", **{option[2:].replace("-", "_"): float(value)})


def test_scale_variable_must_be_finite_non_zero(tmp_path):
    from scipy.io import savemat

    t = np.arange(100) * 0.001
    savemat(tmp_path / "z.mat", {"t": t[:, None], "pos": t[:, None], "u": t[:, None], "g": np.array([[0.0]])})
    with pytest.raises(LogFormatError, match=r"z.mat: torque scale variable 'g' is 0; a scale must be a finite non-zero"):
        read_log(tmp_path / "z.mat", time="t", q="pos", tau="u", tau_scale_var="g")


def test_tau_scale_and_tau_scale_var_refused_together(small_mat, tmp_path):
    with pytest.raises(LogFormatError, match=r"x.mat: give the torque scale once, --tau-scale or --tau-scale-var, not both"):
        read_log(small_mat, time="tt", q="pos", tau="u", tau_scale=2.0, tau_scale_var="g")
    out = tmp_path / "o.h5"
    r = CliRunner().invoke(cli, ["load", str(small_mat), "--time", "tt", "--q", "pos", "--tau", "u", "--tau-scale", "2",
                                 "--tau-scale-var", "g", "-o", str(out)])
    _one_line_error(r, "not both")
    assert not out.exists()


def test_mat_unit_mistakes_name_the_variable(tmp_path):
    from scipy.io import savemat

    t = np.arange(200) * 0.012
    savemat(tmp_path / "u.mat", {"t_ms": 1000 * t[:, None], "t": t[:, None], "deg": (30 + 10 * np.sin(t))[:, None],
                                 "u": np.cos(t)[:, None]})
    with pytest.raises(LogFormatError, match=r"u.mat: position variable 'deg' reaches 40 rad \(2291.8\d* degrees\); "
                                             r"beyond \+-720 degrees: wrong unit"):
        read_log(tmp_path / "u.mat", time="t", q="deg", tau="u")
    with pytest.raises(LogFormatError, match=r"u.mat: time variable 't_ms' has a median sample interval of 12 s"):
        read_log(tmp_path / "u.mat", time="t_ms", q="deg", tau="u", q_scale=np.pi / 180)
    # the remedies: --q-scale for degrees, --time-scale for milliseconds
    log = read_log(tmp_path / "u.mat", time="t_ms", q="deg", tau="u", q_scale=np.pi / 180, time_scale=1e-3)
    assert np.allclose(log.time, t) and np.allclose(np.degrees(log.q[:, 0]), 30 + 10 * np.sin(t))
    out = tmp_path / "o.h5"
    r = CliRunner().invoke(cli, ["load", str(tmp_path / "u.mat"), "--time", "t_ms", "--q", "deg", "--tau", "u",
                                 "--q-scale", "0.017453292519943295", "--time-scale", "0.001", "-o", str(out)])
    assert r.exit_code == 0, r.output
    assert np.allclose(read_hdf5(out).time, t)
    # new-user trial 13: --time-scale 0.001 on a time in seconds (EMPS) gave a 1 MHz log of 0.02 s, and
    # fit wrote a mass of 9.5e-05 kg (95 kg) without a word
    out = tmp_path / "us.h5"
    r = CliRunner().invoke(cli, ["load", str(tmp_path / "u.mat"), "--time", "t", "--q", "deg", "--tau", "u",
                                 "--q-scale", "0.017453292519943295", "--time-scale", "0.001", "-o", str(out)])
    _one_line_error(r, "u.mat: time variable 't' has a median sample interval of 1.2e-05 s; under 5e-05 s",
                    "seconds divided by 1000")
    assert r.exit_code == 1 and not out.exists()


def test_sample_time_option_builds_the_time_base(tmp_path):
    from scipy.io import savemat

    savemat(tmp_path / "n.mat", {"pos": np.zeros((50, 1)), "u": np.ones((50, 1))})
    out = tmp_path / "o.h5"
    r = CliRunner().invoke(cli, ["load", str(tmp_path / "n.mat"), "--q", "pos", "--tau", "u", "-o", str(out)])
    _one_line_error(r, "no time variable ('time' or 't'): name it or give the sample interval",
                    "--time VAR (or --sample-time S)")
    r = CliRunner().invoke(cli, ["load", str(tmp_path / "n.mat"), "--q", "pos", "--tau", "u", "--sample-time", "0.004",
                                 "-o", str(out)])
    assert r.exit_code == 0, r.output
    assert read_hdf5(out).sample_time == pytest.approx(0.004)


# -- struct fields and (samples, axes) arrays, v5 and v7.3 ------------------------------------------
def _recording(n=300):
    t = np.arange(n) * 0.004
    q_deg = np.column_stack([10 * a + 5 * np.sin(t * a) for a in (1, 2, 3)])
    tau = np.column_stack([100 * a * np.cos(t * a) for a in (1, 2, 3)])
    return t, q_deg, tau


def test_v5_struct_fields_nested_and_multi_axis(tmp_path):
    from scipy.io import savemat

    t, q_deg, tau = _recording()
    path = tmp_path / "rec.mat"
    savemat(path, {"rec": {"time": t[:, None], "act_pos_mot_deg": q_deg, "drive": {"tau": tau.T, "temp": 40 + 0 * tau}}})
    log = read_log(path, time="rec.time", q="rec.act_pos_mot_deg", tau="rec.drive.tau", temp="rec.drive.temp",
                   q_scale=np.pi / 180, axis=[1, 2, 3])
    assert log.axes == (1, 2, 3)
    np.testing.assert_array_equal(log.q, q_deg * (np.pi / 180))
    np.testing.assert_array_equal(log.tau, tau)  # stored (axes, samples): taken column-wise all the same
    np.testing.assert_array_equal(log.temp, 40 + 0 * tau)
    one = read_log(path, time="rec.time", q="rec.act_pos_mot_deg", tau="rec.drive.tau", q_scale=np.pi / 180,
                   axis=[4, 5, 6])
    assert one.axes == (4, 5, 6)
    with pytest.raises(LogFormatError, match=r"struct 'rec.drive' has no field 'torque' for torque \(fields: tau, temp\)"):
        read_log(path, time="rec.time", q="rec.act_pos_mot_deg", tau="rec.drive.torque", axis=[1, 2, 3])
    with pytest.raises(LogFormatError, match=r"variable 'rec.drive' \(torque\) is not numeric: it holds a struct with "
                                             r"fields tau, temp; name one as rec.drive.<field>"):
        read_log(path, time="rec.time", q="rec.act_pos_mot_deg", tau="rec.drive", axis=[1, 2, 3])
    with pytest.raises(LogFormatError, match=r"'rec.act_pos_mot_deg' \(position\) has shape \(300, 3\): 3 axes, but "
                                             r"--axis lists 2 \(1, 2\)"):
        read_log(path, time="rec.time", q="rec.act_pos_mot_deg", tau="rec.drive.tau", axis=[1, 2])
    with pytest.raises(LogFormatError, match=r"position variable 'rec.act_pos_mot_deg' \(column 1\) reaches"):
        read_log(path, time="rec.time", q="rec.act_pos_mot_deg", tau="rec.drive.tau", axis=[1, 2, 3])


def test_v73_struct_fields_and_multi_axis(tmp_path):
    import h5py

    t, q_deg, tau = _recording()
    path = tmp_path / "rec73.mat"
    _write_v73(path, {"gtau": ("double", np.array([[2.0]]))})
    with h5py.File(path, "a") as f:  # MATLAB stores column-major: an (N, A) array is an (A, N) dataset
        rec = f.create_group("rec")
        rec.attrs["MATLAB_class"] = np.bytes_("struct")
        for name, data in (("t", t[None, :]), ("act_pos_mot_deg", q_deg.T)):
            rec.create_dataset(name, data=data).attrs["MATLAB_class"] = np.bytes_("double")
        sub = rec.create_group("x")
        sub.attrs["MATLAB_class"] = np.bytes_("struct")
        sub.create_dataset("y", data=tau.T).attrs["MATLAB_class"] = np.bytes_("double")
    log = read_log(path, time="rec.t", q="rec.act_pos_mot_deg", tau="rec.x.y", tau_scale_var="gtau",
                   q_scale=np.pi / 180, axis=[1, 2, 3])
    assert log.axes == (1, 2, 3)
    np.testing.assert_array_equal(log.q, q_deg * (np.pi / 180))
    np.testing.assert_array_equal(log.tau, 2 * tau)
    with pytest.raises(LogFormatError, match=r"variable 'rec.act_pos_mot_deg' \(position\) has shape \(300, 3\)"):
        read_log(path, time="rec.t", q="rec.act_pos_mot_deg", tau="rec.x.y", q_scale=np.pi / 180)


def test_cli_load_struct_field_with_an_axis_list(tmp_path):
    from scipy.io import savemat

    t, q_deg, tau = _recording()
    savemat(tmp_path / "rec.mat", {"rec": {"t": t[:, None], "act_pos_mot_deg": q_deg, "tau": tau}})
    out = tmp_path / "o.h5"
    r = CliRunner().invoke(cli, ["load", str(tmp_path / "rec.mat"), "--time", "rec.t", "--q", "rec.act_pos_mot_deg",
                                 "--tau", "rec.tau", "--q-scale", str(np.pi / 180), "--axis", "1,2,3", "-o", str(out)])
    assert r.exit_code == 0, r.output
    log = read_hdf5(out)
    assert log.axes == (1, 2, 3) and np.allclose(np.degrees(log.q), q_deg, rtol=0, atol=1e-12)
    r = CliRunner().invoke(cli, ["load", str(tmp_path / "rec.mat"), "--time", "rec.t", "--q", "rec.act_pos_mot_deg",
                                 "--tau", "rec.tau", "--axis", "1,x", "-o", str(tmp_path / "b.h5")])
    _one_line_error(r, "--axis must be an axis number or a list such as 1,2,3")
    r = CliRunner().invoke(cli, ["load", str(tmp_path / "rec.mat"), "--gear-ratio", "A1=2", "-o", str(tmp_path / "g.h5")])
    _one_line_error(r, "option --gear-ratio is for KUKA Trace (.dat, .r64) sources")


def test_a_recording_in_one_struct_lists_its_fields_and_how_to_name_them(tmp_path):
    """New-user trial 16: a MATLAB recording saved as one struct (`save rec.mat data`, data.t, data.q,
    data.tau) gave `no variables 'q' and 'tau': ... variables: data`, and nothing said its fields are
    named `data.q`; the struct is listed with its fields."""
    from scipy.io import savemat

    t = np.arange(0.0, 2.0, 0.012)
    savemat(tmp_path / "rec.mat", {"data": {"t": t, "q": np.sin(t), "tau": np.cos(t)}, "gain": 2.0})
    r = CliRunner().invoke(cli, ["load", str(tmp_path / "rec.mat"), "-o", str(tmp_path / "x.h5")])
    _one_line_error(r, "no variables 'q' and 'tau'",
                    "variables: data (a struct with fields t, q, tau; name one as data.<field>), gain")
    assert not (tmp_path / "x.h5").exists()


@pytest.mark.parametrize("variables, said", [
    ({"q": np.degrees(np.sin(np.arange(0.0, 20.0, 0.012)))}, "--q-scale 0.0174533 reads degrees"),
    ({"t": 1000 * np.arange(0.0, 20.0, 0.012)}, "--time-scale 0.001 reads milliseconds"),
])
def test_a_unit_mistake_in_a_mat_file_names_the_scale_that_corrects_it(tmp_path, variables, said):
    """New-user trial 16: a MAT file with positions in degrees (MATLAB users log degrees) said `position
    variable 'q' reaches -28.6479 rad (-1641.4 degrees); beyond +-720 degrees: wrong unit (millidegrees,
    or degrees as radians)?`, and nothing of kukaid load's --q-scale (nor of --time-scale for ms)."""
    from scipy.io import savemat

    t = np.arange(0.0, 20.0, 0.012)
    path = tmp_path / "rec.mat"
    savemat(path, {"t": t, "q": np.sin(t), "tau": np.cos(t), **variables})
    for cmd in (["load", str(path), "-o", str(tmp_path / "x.h5")], ["fit", str(path), "-o", str(tmp_path / "p.json")]):
        r = CliRunner().invoke(cli, cmd)
        _one_line_error(r, "wrong unit" if "q" in variables else "milliseconds written as seconds?",
                        f"kukaid load {path} {said}")
    assert sorted(os.listdir(tmp_path)) == ["rec.mat"]


def test_a_mat_file_without_time_given_to_fit_names_kukaid_load(tmp_path):
    """New-user trial 16: `kukaid fit n.mat` (q and tau, no time) said `no time variable; name it (--time)
    or give --sample-time`, options fit does not have (`No such option '--sample-time'`)."""
    from scipy.io import savemat

    savemat(tmp_path / "n.mat", {"q": np.zeros((50, 1)), "tau": np.ones((50, 1))})
    r = CliRunner().invoke(cli, ["fit", str(tmp_path / "n.mat"), "-o", str(tmp_path / "p.json")])
    _one_line_error(r, f"kukaid load {tmp_path / 'n.mat'} --time VAR (or --sample-time S) -o LOG.h5, and give "
                    "LOG.h5; variables: q, tau")
    assert sorted(os.listdir(tmp_path)) == ["n.mat"]


def test_an_empty_mat_file_or_variable_is_said_so(tmp_path):
    """New-user trial 22: an empty variable said "has shape (0, 0): 0 axes, but --axis lists 1 (1); give one
    axis number per column", and a 0-byte .mat "Mat file appears to be truncated"."""
    from scipy.io import savemat

    path = tmp_path / "e.mat"
    savemat(path, {"t": np.arange(10) * 0.01, "q": np.zeros(0), "tau": np.zeros(10)})
    r = CliRunner().invoke(cli, ["load", str(path), "--time", "t", "--q", "q", "--tau", "tau", "--joint", "revolute",
                                 "-o", str(tmp_path / "o.h5")])
    err = _one_line_error(r, f"{path}: variable 'q' (position) is empty: no samples")
    assert "axes" not in err and not (tmp_path / "o.h5").exists()
    (tmp_path / "z.mat").write_bytes(b"")
    r = CliRunner().invoke(cli, ["load", str(tmp_path / "z.mat"), "-o", str(tmp_path / "o.h5")])
    _one_line_error(r, f"{tmp_path / 'z.mat'}: empty file")
    assert not (tmp_path / "o.h5").exists()


def test_a_bad_sample_of_a_mat_file_is_named_by_its_matlab_index(tmp_path):
    """New-user trial 22: a NaN at q(101) was named "at row 100" (the index from 0), where MATLAB shows a
    finite number; the samples of a MAT file are named by MATLAB's index, from 1."""
    from scipy.io import savemat

    t, q = np.arange(300) * 0.004, np.zeros(300)
    q[100] = np.nan  # MATLAB's q(101)
    savemat(tmp_path / "n.mat", {"t": t, "q": q, "tau": np.ones(300)})
    t2 = t.copy()
    t2[100] = t2[99]  # t(101) == t(100)
    savemat(tmp_path / "d.mat", {"t": t2, "q": np.zeros(300), "tau": np.ones(300)})
    with pytest.raises(LogFormatError, match=r"not a finite number \(NaN or inf\) at MATLAB index 101$"):
        read_log(tmp_path / "n.mat", time="t", joint="revolute")
    with pytest.raises(LogFormatError, match=r"\(duplicated\) at MATLAB index 101: 0.396 s after 0.396 s"):
        read_log(tmp_path / "d.mat", time="t", joint="revolute")
