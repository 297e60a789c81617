"""`kukaid excite fourier`: band-limited, at rest at both ends, within limits, optimised, KRL for all axes."""
from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

pytest.importorskip("pinocchio")

from kukaid.errors import KukaidError, LimitError  # noqa: E402
from kukaid.excite.fourier import RobotTrajectory, fourier, load_trajectory  # noqa: E402
from kukaid.krc.krl import krl_program_robot  # noqa: E402
from kukaid_cli.main import cli  # noqa: E402
from robot_helpers import ROBOT  # noqa: E402

FAST = dict(harmonics=3, period=5.0, periods=2, iterations=0, starts=2)


@pytest.fixture(scope="module")
def traj():
    return fourier(ROBOT, **FAST)


def test_at_rest_at_both_ends_and_periodic(traj):
    q = traj.q
    assert np.allclose(q[0], q[-1], atol=1e-9)
    n = int(round(5.0 / traj.dt))  # the period is rounded to whole IPO cycles
    assert np.allclose(q[:n], q[n:2 * n], atol=1e-9)  # repeated period
    qd = np.gradient(q, traj.dt, axis=0)
    assert np.abs(qd[0]).max() < 1e-3 and np.abs(qd[-1]).max() < 1e-3


def test_band_limited(traj):
    n = int(round(5.0 / traj.dt))  # the period is rounded to whole IPO cycles
    spec = np.abs(np.fft.rfft(traj.q[:n] - traj.q[:n].mean(0), axis=0)) ** 2
    # bins 1..3 are the harmonics of the 5 s period; nothing above
    assert spec[4:].sum() < 1e-6 * spec[1:4].sum()


def test_within_every_limit_and_uses_them(traj):
    traj.check()  # does not raise
    lim = traj.axis_limits()
    qd = np.abs(np.gradient(traj.q, traj.dt, axis=0)).max(0)
    qdd = np.abs(np.gradient(np.gradient(traj.q, traj.dt, axis=0), traj.dt, axis=0)).max(0)
    use = np.maximum(qd / [x.qd_max for x in lim], qdd / [x.qdd_max for x in lim])
    span = np.ptp(traj.q, axis=0) / [x.q_max - x.q_min for x in lim]
    # every axis is pushed to one of its limits (position span, velocity or acceleration)
    assert np.all((use > 0.8) | (span > 0.5))


def test_optimiser_lowers_the_condition_number():
    base = fourier(ROBOT, **{**FAST, "periods": 1})
    opt = fourier(ROBOT, **{**FAST, "periods": 1, "iterations": 2})
    assert opt.params["cond"] <= base.params["cond"]
    assert np.isfinite(opt.params["cond"])


def test_json_round_trip_and_dispatch(traj, tmp_path):
    p = tmp_path / "f.json"
    traj.to_json(p)
    back = load_trajectory(p)
    assert isinstance(back, RobotTrajectory) and back.axes == traj.axes
    assert np.array_equal(back.q, traj.q) and back.limits == traj.limits


def test_a_broken_limit_is_refused_with_one_line(tmp_path):
    out = tmp_path / "f.json"
    n = len(fourier(ROBOT, **{**FAST, "periods": 1}).axes)
    cent = ",".join(["0"] * (n - 1) + ["400"])
    r = CliRunner().invoke(cli, ["excite", "fourier", "--robot", ROBOT, "-o", str(out), "--iterations", "0",
                                 "--harmonics", "2", "--period", "4", "--repeat", "1", "--centres-deg", cent])
    assert r.exit_code != 0
    assert r.output.strip().count("\n") == 0 and "position limit" in r.output and f"A{n}" in r.output
    assert not out.exists()
    lim = {f"A{n}": {"qd_max": 0.0}}
    (tmp_path / "lim.json").write_text(json.dumps(lim))
    r = CliRunner().invoke(cli, ["excite", "fourier", "--robot", ROBOT, "-o", str(out), "--limits", str(tmp_path / "lim.json")])
    assert r.exit_code != 0 and "qd_max" in r.output and not out.exists()


def test_krl_for_all_axes(traj):
    six = RobotTrajectory(t=traj.t, q=traj.q[:, :6], axes=traj.axes[:6], kind="fourier", limits=traj.limits[:6])
    src, dat, summary = krl_program_robot(six)
    for a in range(1, 7):
        assert f"$VEL_AXIS[{a}] = VEL_PCT[I,{a}]" in src and f"P.A{a} = XP[I].A{a}" in src
    assert f"DECL INT VEL_PCT[{summary['points']},6]" in dat
    # every via point lies on the trajectory within the tolerance, on every axis
    pts = [line.split("=", 1)[1] for line in dat.splitlines() if line.strip().startswith("XP[")]
    first = np.array([float(x.split()[1]) for x in pts[0].strip(" {}").split(",")])
    i = summary["breakpoints"][1]
    assert np.allclose(first, np.degrees(six.q[i]), atol=1e-4)
    vel = [int(line.rsplit("=", 1)[1]) for line in dat.splitlines() if line.strip().startswith("VEL_PCT[")]
    assert 1 <= min(vel) and max(vel) <= 100
    from test_excite_krl import _check_override   # the operator's override: scaled, never raised, given back

    code = [ln for ln in (x.split(";")[0].strip() for x in src.splitlines()) if ln]
    _check_override(code, [line.rsplit("=", 1)[1] for line in dat.splitlines() if line.strip().startswith("OVR_PCT[")])


def test_krl_refuses_a_speed_above_the_limit(traj):
    lim = [dict(d, qd_max=d["qd_max"] * 0.1) for d in traj.limits[:6]]
    six = RobotTrajectory(t=traj.t, q=traj.q[:, :6], axes=traj.axes[:6], kind="fourier", limits=lim)
    with pytest.raises(KukaidError, match="above the velocity limit"):
        krl_program_robot(six)
    with pytest.raises(LimitError):
        six.check()


def test_a_bad_urdf_is_one_line_on_stderr(tmp_path, kukaid_cmd):
    import subprocess

    bad = tmp_path / "bad.urdf"
    bad.write_text("<robot>")
    r = subprocess.run(kukaid_cmd + ["excite", "fourier", "--robot", str(bad), "-o", str(tmp_path / "f.json")],
                       capture_output=True, text=True)
    assert r.returncode != 0
    assert r.stderr.startswith("kukaid: error: ") and r.stderr.count("\n") == 1, r.stderr
    assert not (tmp_path / "f.json").exists()


def test_a_badly_conditioned_excitation_is_written_with_a_warning(tmp_path):
    out = tmp_path / "f.json"
    r = CliRunner().invoke(cli, ["excite", "fourier", "--robot", ROBOT, "-o", str(out), "--qdd-max-deg", "1",
                                 "--iterations", "0"])
    assert r.exit_code == 0 and out.exists(), r.output
    # on stderr in the form every warning has (docs/errors.md), naming the command
    assert "kukaid: warning: excite: regressor condition number" in r.stderr and "poorly determined" in r.stderr
    r = CliRunner().invoke(cli, ["excite", "fourier", "--robot", ROBOT, "-o", str(tmp_path / "g.json"),
                                 "--harmonics", "3", "--period", "5"])
    assert r.exit_code == 0 and "warning" not in r.output, r.output


def _chain_urdf(n: int) -> str:
    """A serial robot of ``n`` revolute joints (z axes, 0.2 m apart), each link 2 kg."""
    links = "".join(f'<link name="l{i}"><inertial><origin xyz="0 0 0.1"/><mass value="2"/>'
                    f'<inertia ixx="0.01" iyy="0.01" izz="0.005" ixy="0" ixz="0" iyz="0"/></inertial></link>'
                    for i in range(n + 1))
    joints = "".join(f'<joint name="j{i}" type="revolute"><parent link="l{i - 1}"/><child link="l{i}"/>'
                     f'<origin xyz="0 0 0.2" rpy="{1.5708 * (i % 2)} 0 0"/><axis xyz="0 0 1"/>'
                     f'<limit lower="-2.9" upper="2.9" velocity="2" effort="100"/></joint>' for i in range(1, n + 1))
    return f'<?xml version="1.0"?><robot name="chain{n}">{links}{joints}</robot>'


def test_krl_for_a_robot_of_seven_joints_is_refused_before_the_optimiser(tmp_path, monkeypatch):
    """New-user trial 10: `excite fourier --robot kuka_lwr4.urdf --krl krl/` optimised for 54 s, then said
    "KRL export: axes [1, ..., 7] are not robot axes (1 to 6)" and wrote nothing."""
    import kukaid.excite.fourier as fourier_module

    urdf = tmp_path / "chain7.urdf"
    urdf.write_text(_chain_urdf(7))

    def no_optimiser(*a, **k):
        raise AssertionError("the optimiser ran")

    monkeypatch.setattr(fourier_module, "fourier", no_optimiser)
    r = CliRunner().invoke(cli, ["excite", "fourier", "--robot", str(urdf), "-o", str(tmp_path / "f.json"),
                                 "--krl", str(tmp_path / "krl")])
    assert r.exit_code == 1, r.output
    assert "--krl writes a KR C4 program, which moves A1..A6; this robot has 7 joints" in r.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["chain7.urdf"]


def test_one_harmonic_that_cannot_excite_the_robot_is_one_line_not_an_internal_error(tmp_path):
    """New-user trial 21: `excite fourier --robot kr6-r700-sixx --harmonics 1 --period 2 --repeat 1
    --iterations 1` ended in `internal error (OverflowError: math range error)`, exit 70: the regressor was
    singular at every start, and exp() of the objective's sentinel overflowed.  Now one line naming the
    option, exit status 2, nothing written."""
    out = tmp_path / "f.json"
    r = CliRunner().invoke(cli, ["excite", "fourier", "--robot", "kr6-r700-sixx", "--harmonics", "1", "--period",
                                 "2", "--repeat", "1", "--iterations", "0", "-o", str(out)])
    assert r.exit_code == 2, r.output
    err = r.stderr.strip().splitlines()
    assert len(err) == 1 and "--harmonics 2 or more" in err[0] and "internal error" not in err[0], err
    assert not out.exists()
