"""MAT files as axis logs (`kukaid load`), and the EMPS real-data check of identification."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from kukaid.errors import LogFormatError
from kukaid.identify import fit_axis
from kukaid.io.axislog import read_hdf5, read_log
from kukaid_cli.main import cli

SHARED = Path(__file__).resolve().parents[2] / "shared"
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


def test_emps_stribeck_runs(emps, tmp_path):
    from kukaid.io.params import save_params

    p = fit_axis(logs=[emps], friction_model="stribeck", gravity="none", offset=True)
    assert p["metrics"]["ipopt_status"] in ("Solve_Succeeded", "Solved_To_Acceptable_Level")
    save_params(tmp_path / "emps.json", p)
    assert p["inertial"]["Izz"] == pytest.approx(95.1, rel=0.05)
