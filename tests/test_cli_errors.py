"""Bad input across the commands: one line on stderr, a non-zero exit, no traceback, no output
file, and nothing a command reads is ever written over."""
from __future__ import annotations

import json

import os
import stat
import subprocess

import pytest
from click.testing import CliRunner

from kukaid.errors import KukaidError
from kukaid.atomic import atomic_paths, check_output
from kukaid_cli.main import cli


def _run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def _one_line_error(r, *pieces, code=None):
    assert r.exit_code != 0 if code is None else r.exit_code == code, r.output
    lines = r.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("kukaid: error: "), r.output
    assert "Traceback" not in r.output
    for p in pieces:
        assert p in lines[0], (p, lines[0])


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("errs")
    r = _run("excite", "inertia", "-o", d / "inertia.json", "--period", "2", "--n-periods", "3")
    assert r.exit_code == 0, r.output
    r = _run("capture", d / "inertia.json", "-o", d / "inertia.h5", "--seed", "3")
    assert r.exit_code == 0, r.output
    r = _run("fit", d / "inertia.h5", "--friction-model", "coulomb-viscous", "-o", d / "params.json")
    assert r.exit_code == 0, r.output
    # run-admittance refuses a file without Maxwell-slip elements; give it the paper's (Table 2)
    p = json.loads((d / "params.json").read_text())
    p["maxwell_slip"] = {"k": [35894.0, 160065.0, 51893.0], "W": [7.3406, 1.371, 6.288], "zeta0": [0.0, 0.0, 0.0]}
    (d / "params.json").write_text(json.dumps(p))
    return d


@pytest.mark.parametrize("args, pieces", [
    (["capture", "x.json", "-o", "y.h5", "--axis", "13"], ["capture: Invalid value for '--axis'"]),
    # new-user trial 7: "'x' is not a valid integer range" (click's)
    (["validate", "--params", "p.json", "a.h5", "--axis", "x"],
     ["validate: Invalid value for '--axis': 'x' is not an axis number: give 1 to 12"]),
    (["excite", "inertia", "-o", "x.json", "--axis", "7"],
     ["excite: Invalid value for '--axis': '7' is not an axis number: give 1 to 6"]),
    (["excite", "bogus", "-o", "x.json"], ["excite: Invalid value", "'bogus'"]),
    (["excite", "friction"], ["excite: Missing option '-o'"]),
    (["nosuch"], ["No such command 'nosuch'"]),
    (["fleet", "fit"], ["kukaid: error: fleet fit: Missing argument 'INPUT'"]),  # not `fit:`, another command
    (["capture", "x.json", "-o", "y.h5", "--seed", "-1"], ["capture: Invalid value for '--seed'"]),
    (["fit", "a.h5", "-o", "p.json", "--order", "60"], ["fit: Invalid value for '--order'"]),
    # new-user trial 13: a negative seed was an internal error (exit 70), the fourier acceleration limit's
    # error named no option ("axis limits: 'qdd_max' must be positive", exit 1)
    (["excite", "fourier", "-o", "x.json", "--seed", "-1"], ["excite: Invalid value for '--seed'"]),
    (["fleet", "simulate", "-o", "fleet", "--seed", "-1"], ["fleet simulate: Invalid value for '--seed'"]),
    (["excite", "fourier", "-o", "x.json", "--qdd-max-deg", "0"], ["Invalid value for --qdd-max-deg", "> 0"]),
    (["excite", "fourier", "-o", "x.json", "--qdd-max-deg", "nan"], ["Invalid value for --qdd-max-deg", "> 0"]),
    (["excite", "inertia", "-o", "x.json", "--lead", "1e9"], ["--lead", "longer than an hour"]),
    # new-user trial 18: click's FloatRange takes nan within any range: serve-sim served at --speed nan and
    # --delay nan (exit 0), run-admittance --init-move nan passed the file's check and switched a robot's
    # follower on before "safety: reference nan is not a finite angle" (exit 1)
    (["serve-sim", "--port", "0", "--duration", "1", "--speed", "nan"], ["'--speed': nan is not a number"]),
    (["serve-sim", "--port", "0", "--duration", "1", "--delay", "nan"], ["'--delay': nan is not a number"]),
    (["serve-sim", "--port", "0", "--duration", "nan"], ["'--duration': nan is not a number"]),
    (["run-admittance", "--params", "p.json", "-o", "r.h5", "--init-move", "nan"], ["'--init-move': nan is not a number"]),
    (["capture", "x.json", "-o", "y.h5", "--settle", "nan"], ["'--settle': nan is not a number"]),
    (["krl-follower", "-o", "krl", "--q-min", "nan", "--q-max", "10"], ["'--q-min': nan is not a number"]),
    (["fleet", "simulate", "-o", "fleet", "--wear-share", "nan"], ["'--wear-share': nan is not a number"]),
    # new-user trial 18: said as "option --v-max: 1 rad/s is too fast ... (0.042 rad = 2.406 deg)" (friction), as
    # "trajectory: 'q' is not a finite number at index 0" (inertia), naming no option or another one
    (["excite", "friction", "-o", "x.json", "--centre-deg", "nan"],
     ["Invalid value for --centre-deg: nan is not a position in degrees"]),
    (["excite", "inertia", "-o", "x.json", "--centre-deg", "inf"],
     ["Invalid value for --centre-deg: inf is not a position in degrees"]),
    (["serve-sim", "--port", "0", "--duration", "1", "--q0", "nan"], ["--q0", "not a position"]),
    # new-user trial 17: served A3 (a KR 6 R700 sixx's, -120 to 156 degrees) standing at 300 degrees, as
    # run-admittance --q0 300 did before trial 10
    (["serve-sim", "--port", "0", "--duration", "1", "--q0", "300"],
     ["--q0", "300 degrees is outside the range of motion of the virtual KR C4's A3", "-120 to 156 degrees"]),
    (["serve-sim", "--port", "0", "--duration", "1", "--axis", "2", "--q0", "60"], ["--q0", "A2", "-190 to 45"]),
    # trial 20: a follower's window beyond the simulated axis's range was taken (exit 0)
    (["serve-sim", "--port", "0", "--duration", "1", "--follower", "0", "300"],
     ["--follower", "300 degrees is outside the range of motion of the virtual KR C4's A3"]),
    # options of serve-sim that did nothing, without a word: a simulated A3 served for --axis 4, a
    # grip or start of a hand that is not there, a heartbeat timeout of no follower
    (["serve-sim", "--port", "0", "--duration", "1", "--axis", "4", "--trajectory", "{traj}"],
     ["--axis 4 differs from the trajectory's axis A3"]),
    (["serve-sim", "--port", "0", "--duration", "1", "--grip", "firm"], ["--grip is for --operator human"]),
    (["serve-sim", "--port", "0", "--duration", "1", "--operator-start", "5"], ["--operator-start is for --operator"]),
    (["serve-sim", "--port", "0", "--duration", "1", "--stale-ms", "50"], ["--stale-ms is for --follower"]),
    # new-user trial 10: a malformed --pattern, or one with a manifest, was exit status 1 (a problem of the data)
    (["fleet", "fit", ".", "-o", "t.parquet", "--workers", "1", "--pattern", "{robot}/*"],
     ["fleet fit: Invalid value for --pattern", "must contain {robot} and {date}"]),
    (["fleet", "fit", "{traj}", "-o", "t.parquet", "--workers", "1", "--pattern", "{robot}/{date}/*"],
     ["--pattern applies to a folder of logs, not to a manifest file"]),
    # new-user trial 10: both accepted, the follower's window and heartbeat said nothing to the trajectory's motion
    (["serve-sim", "--port", "0", "--duration", "1", "--follower", "20", "50", "--trajectory", "{traj}"],
     ["--follower emulates the program of `kukaid krl-follower`", "not with --trajectory"]),
    # an axis given twice is the option's fault (it was exit 1)
    (["krl-logger", "-o", "krl", "--axis", "3", "--axis", "3"], ["--axis", "axes must be distinct", "[3, 3]"]),
    # new-user trial 17: a block too long for one KUKAVARPROXY reply said "Invalid value for --axis"
    (["krl-logger", "-o", "krl", *[x for a in range(1, 7) for x in ("--axis", str(a))], "--block-samples", "32"],
     ["Invalid value for --block-samples", "use fewer samples per block (at most 22)"]),
    (["serve-sim", "--port", "0", "--duration", "1", "--ring-axes", "3", "--ring-axes", "3"],
     ["--ring-axes", "axes must be distinct"]),
    # a one-axis simulator's ring logger of another axis recorded zeros (position and torque)
    (["serve-sim", "--port", "0", "--duration", "1", "--ring-axes", "4"],
     ["--ring-axes", "A4 is not simulated: the one-axis simulator runs A3 only"]),
])
def test_usage_errors_are_one_line(args, pieces, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    traj = tmp_path.parent / f"{tmp_path.name}-a3.json"  # a trajectory of A3, beside the folder that must stay empty
    if any("{traj}" in a for a in args):
        assert _run("excite", "inertia", "-o", traj, "--period", "2").exit_code == 0
    _one_line_error(_run(*[a.replace("{traj}", str(traj)) for a in args]), *pieces, code=2)
    assert os.listdir(tmp_path) == []


def test_a_folder_where_a_file_belongs(files, tmp_path):
    _one_line_error(_run("report", "--params", tmp_path, "-o", tmp_path / "r.pdf"), "is a directory")
    _one_line_error(_run("fit", files / "inertia.h5", "-o", tmp_path), "is a directory")
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("make_args", [
    lambda d: ["fit", d / "inertia.h5", "-o", d / "params.json", "--friction-model", "coulomb-viscous",
               "--inertia", d / "params.json"],
    lambda d: ["report", "--params", d / "params.json", "-o", d / "params.json"],
    lambda d: ["diagnose", "--params", d / "params.json", "--log", d / "inertia.h5", "-o", d / "params.json"],
    lambda d: ["diagnose", "--params", d / "params.json", "--log", d / "inertia.h5", "-o", d / "x.json",
               "--report", d / "x.json"],
    lambda d: ["capture", d / "inertia.json", "-o", d / "inertia.h5", "--force", "--sim-config", d / "inertia.h5"],
    lambda d: ["excite", "inertia", "-o", d / "limits.json", "--limits", d / "limits.json"],
    lambda d: ["run-admittance", "--params", d / "params.json", "-o", d / "r.h5", "--report", d / "r.h5"],
])
def test_no_command_writes_over_its_inputs_or_twice_into_one_file(files, make_args):
    (files / "limits.json").write_text('{"q_min_deg": -100, "q_max_deg": 100}')
    before = {p.name: p.read_bytes() for p in files.iterdir()}
    r = _run(*make_args(files))
    _one_line_error(r)
    assert "input of this command" in r.output or "two outputs" in r.output or "name it so" in r.output
    assert {p.name: p.read_bytes() for p in files.iterdir()} == before


def test_devices_and_folders_are_not_output_files(tmp_path):
    with pytest.raises(KukaidError, match="not a regular file"):
        check_output("/dev/null")
    with pytest.raises(KukaidError, match="is a folder"):
        check_output(tmp_path)
    (tmp_path / "f").write_text("x")
    with pytest.raises(KukaidError, match="is not a folder"):
        check_output(tmp_path / "f" / "out.json")
    r = _run("excite", "inertia", "-o", "/dev/null.json", "--krl", "/dev/null")
    _one_line_error(r)
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)


def test_outputs_are_all_or_nothing(tmp_path):
    a, b = tmp_path / "a.txt", tmp_path / "b.txt"
    b.write_text("old")
    with pytest.raises(RuntimeError):
        with atomic_paths(a, b) as (ta, tb):
            ta.write_text("new a")
            tb.write_text("new b")
            raise RuntimeError("the second output failed")
    assert not a.exists() and b.read_text() == "old" and sorted(os.listdir(tmp_path)) == ["b.txt"]
    with atomic_paths(a, b) as (ta, tb):
        ta.write_text("A")
        tb.write_text("B")
    assert a.read_text() == "A" and b.read_text() == "B" and sorted(os.listdir(tmp_path)) == ["a.txt", "b.txt"]


def test_a_write_error_names_the_output_not_its_temporary_file(tmp_path):
    out = tmp_path / "out.json"
    with pytest.raises(KukaidError) as e:
        with atomic_paths(out) as (t,):
            raise OSError(28, "No space left on device", str(t))
    assert str(e.value) == f"{out}: cannot write: No space left on device"
    assert os.listdir(tmp_path) == []


def test_diagnose_leaves_neither_output_when_the_report_fails(files, tmp_path, monkeypatch):
    import kukaid.diagnose.plots as plots

    def broken(result, path):
        raise KukaidError(f"{path}: the report could not be drawn")

    monkeypatch.setattr(plots, "write_report", broken)
    r = _run("diagnose", "--params", files / "params.json", "--log", files / "inertia.h5", "-o", tmp_path / "d.json",
             "--report", tmp_path / "d.pdf")
    _one_line_error(r, "could not be drawn")
    assert os.listdir(tmp_path) == []


def test_excite_writes_the_trajectory_only_with_its_krl(tmp_path):
    (tmp_path / "file").write_text("x")
    r = _run("excite", "inertia", "-o", tmp_path / "t.json", "--krl", tmp_path / "file" / "krl")
    _one_line_error(r, "is not a folder")
    assert sorted(os.listdir(tmp_path)) == ["file"]


def test_capture_refuses_the_same_effect_twice(files, tmp_path):
    r = _run("capture", files / "inertia.json", "-o", tmp_path / "x.h5", "--effect", "torque_offset=1",
             "--effect", "torque_offset=2")
    _one_line_error(r, "torque_offset is given twice", code=2)
    assert os.listdir(tmp_path) == []


def test_serve_sim_checks_its_truth_file_before_serving(files, tmp_path):
    r = _run("serve-sim", "--port", "0", "--duration", "60", "--truth", tmp_path / "truth.csv")
    _one_line_error(r, "truth.csv", ".h5")
    (tmp_path / "truth.h5").write_text("recorded")
    r = _run("serve-sim", "--port", "0", "--duration", "60", "--truth", tmp_path / "truth.h5")
    _one_line_error(r, "already exists")
    assert (tmp_path / "truth.h5").read_text() == "recorded"


def test_serve_sim_simulates_the_axis_its_sim_config_names(tmp_path):
    """New-user trial 10: serve-sim --sim-config with "axis": 2 served A3 (the file's axis dropped without a
    word; run-admittance and capture simulate or check it): now it simulates A2, and refuses --axis 3 with it."""
    (tmp_path / "a2.json").write_text('{"axis": 2}')
    r = _run("serve-sim", "--port", "0", "--duration", "1", "--sim-config", tmp_path / "a2.json", "--ring-axes", "3")
    _one_line_error(r, "A3 is not simulated: the one-axis simulator runs A2 only", code=2)
    r = _run("serve-sim", "--port", "0", "--duration", "1", "--sim-config", tmp_path / "a2.json", "--axis", "3")
    _one_line_error(r, 'a2.json: "axis": 2, but --axis 3 moves A3', code=1)


def test_no_progress_bar_in_a_pipe(files, tmp_path, kukaid_cmd):
    """stderr of a command that is not on a terminal holds what it says, and no bar."""
    r = subprocess.run([*kukaid_cmd, "capture", str(files / "inertia.json"), "-o", str(tmp_path / "x.h5"),
                        "--seed", "4"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and r.stderr.count("\n") == 1 and "samples" in r.stderr, r.stderr


@pytest.mark.parametrize("args, pieces", [
    (["run-admittance", "--params", "{d}/params.json", "-o", "r.h5", "--release", "8", "--threshold", "3"],
     ["release 8.0 N·m must be in [0, threshold 3.0]"]),
    (["run-admittance", "--params", "{d}/params.json", "-o", "r.h5", "--duration", "0"], ["--duration", "0.0<x<=3600.0"]),
    (["run-admittance", "--params", "{d}/params.json", "-o", "r.h5", "--noise", "-1"], ["--noise", "-1.0 N·m is not"]),
    (["run-admittance", "--params", "{d}/params.json", "-o", "r.h5", "--axis", "5"], ["the parameters are of axis A3, not A5 (--axis 5)"]),
    (["run-admittance", "--params", "{d}/params.json", "-o", "r.h5", "--tau-max", "-1"], ["--tau-max"]),
    (["run-admittance", "--params", "{d}/params.json", "-o", "r.h5", "--qd-max", "0"], ["--qd-max"]),
    (["excite", "friction", "-o", "x.json", "--plateau", "-1"], ["option --plateau: must be > 0"]),
    (["run-admittance", "--params", "{d}/params.json", "-o", "r.h5", "--damping", "adaptive", "--D-min", "100"],
     ["--D-min (100)"]),
    (["capture", "{d}/inertia.json", "-o", "c.h5", "--noise", "-1"], ["--noise", "-1.0 N·m is not"]),
    (["capture", "{d}/inertia.json", "-o", "c.h5", "--effect", "bogus"], ["unknown effect 'bogus'"]),
    (["capture", "--backend", "kvp", "-o", "c.h5"], ["needs --duration S or --until-interrupt"]),
    (["excite", "friction", "-o", "x.json", "--n-speeds", "0"], ["--n-speeds"]),
    (["excite", "friction", "-o", "x.json", "--q-min-deg", "50", "--q-max-deg", "10"], ["50 deg", "10 deg"]),
    (["krl-follower", "--q-min", "50", "--q-max", "10", "-o", "krl"], ["window"]),
    # new-user trial 21: a heartbeat timeout of one cycle stopped the follower at once
    (["krl-follower", "--q-min", "0", "--q-max", "10", "-o", "krl", "--stale-ms", "12"], ["stale_ms = 12", "60 to 5000"]),
    (["serve-sim", "--port", "0", "--duration", "1", "--follower", "0", "60", "--stale-ms", "12"], ["60 to 5000"]),
    (["fit", "{d}/inertia.h5", "-o", "p.json", "--bound", "vs=0.2:0.1"], ["--bound", "lower 0.2 is above upper 0.1"]),
    (["fit", "{d}/inertia.h5", "-o", "p.json", "--bound", "nope=0:1"], ["--bound", "no such parameter"]),
    (["fit", "-o", "p.json"], ["no logs to fit"]),
    (["fit", "{d}/inertia.h5", "-o", "p.txt"], ["p.txt: this output is .json"]),
    (["fit", "{d}/inertia.h5", "-o", "p.json", "--robot", "kr6-r700-sixx", "--cutoff", "0"], ["--cutoff"]),
    (["diagnose", "--params", "{d}/params.json", "--log", "{d}/inertia.h5", "--cutoff", "0"], ["--cutoff"]),
    (["excite", "fourier", "-o", "x.json", "--harmonics", "0"], ["harmonics must be 1 to 20"]),
    (["run-admittance", "--params", "{d}/params.json", "-o", "r.h5", "--report", "r.png"], ["r.png", ".pdf"]),
    (["run-admittance", "--params", "{d}/params.json", "-o", "r.h5", "--cycle", "0.0125"],
     ["whole number of sample times"]),
    (["run-admittance", "--params", "{d}/params.json", "-o", "r.h5", "--cutoff", "50"], ["cut-off 50.0 Hz"]),
    (["run-admittance", "--params", "{d}/params.json", "-o", "r.h5", "--backend", "kvp", "--axis", "7"],
     ["--axis", "A1..A6"]),
    (["excite", "inertia", "-o", "x.json", "--krl", "kt", "--krl-tol", "-1"], ["--krl-tol"]),
    (["excite", "inertia", "-o", "x.json", "--krl", "kt", "--krl-tol", "0"], ["--krl-tol"]),
    (["excite", "inertia", "-o", "x.json", "--krl-tol", "0.01"], ["--krl-tol needs --krl"]),
    (["excite", "inertia", "-o", "x.json", "--krl", "kt", "--krl-name", "9x"], ["--krl-name", "not a KRL name"]),
    (["excite", "fourier", "-o", "x.json", "--krl", "kt", "--krl-name", "a-b"], ["--krl-name"]),
    (["excite", "inertia", "-o", "x.json", "--period", "nan"], ["--period", "nan is not a number"]),
    (["capture", "{d}/inertia.json", "-o", "c.h5", "--noise", "1e9"], ["--noise", "(0 to 100 N·m)"]),
    (["capture", "{d}/inertia.json", "-o", "c.h5", "--effect", "backlash=1e9"], ["--effect", "backlash=1e9"]),
    (["capture", "--backend", "kvp", "-o", "c.h5", "--duration", "1", "--until-interrupt"],
     ["--duration and --until-interrupt"]),
    # the value and unit the user typed, the command's option names, an order not an ordinal
    (["excite", "presliding", "-o", "x.json", "--reversals-deg", "-1,nan"],
     ["option --reversals-deg: must be > 0, got -1 deg"]),
    (["excite", "friction", "-o", "x.json", "--v-max", "1e9"], ["(1.571 rad = 90 deg)", "widen option --span-deg or"]),
    # options whose range depends on the log: still usage errors, naming the option and the log
    (["fit", "{d}/inertia.h5", "-o", "p.json", "--edge", "100000"], ["inertia.h5:", "order 3", "--edge 100000"]),
    (["fit", "{d}/inertia.h5", "-o", "p.json", "--cutoff", "1e6"], ["inertia.h5: --cutoff 1e+06 Hz must be in"]),
    (["fit", "{d}/inertia.h5", "-o", "p.json", "--cutoff", "0.001"], ["inertia.h5:", "--cutoff 0.001 Hz"]),
    (["fit", "{d}/inertia.h5", "-o", "p.json", "--robot", "kr6-r700-sixx", "--prior-weight", "-1"],
     ["--prior-weight", "-1.0 must be a finite number >= 0"]),
    (["capture", "{d}/inertia.json", "-o", "c11.csv"], ["c11.csv", "name it .h5 or .hdf5"]),
    (["capture", "-o", "c12.h5", "--backend", "kvp", "--port", "9", "--duration", "1", "--axis", "3", "--axis", "3"],
     ["capture: --axis 3 is given twice"]),
    # new-user trial 9: a port beyond 65535 connected to another (70000 wraps to 4464) or said
    # "cannot connect (Servname not supported ...)", exit status 1, blaming the robot
    (["capture", "{d}/inertia.json", "-o", "c13.h5", "--backend", "kvp", "--port", "70000", "--duration", "1"],
     ["capture: Invalid value for '--port': 70000 is not in the range 1<=x<=65535"]),
    (["capture", "{d}/inertia.json", "-o", "c14.h5", "--backend", "kvp", "--port", "-5", "--duration", "1"],
     ["capture: Invalid value for '--port': -5 is not in the range 1<=x<=65535"]),
    (["run-admittance", "--params", "{d}/params.json", "-o", "r.h5", "--backend", "kvp", "--port", "70000",
      "--enable-motion", "--q-min", "0", "--q-max", "10"],
     ["run-admittance: Invalid value for '--port': 70000 is not in the range 1<=x<=65535"]),
])
def test_option_errors_are_usage_errors(files, tmp_path, monkeypatch, args, pieces):
    """Contradictory or out-of-range options: exit status 2 (the usage error of docs/errors.md), one line, no output."""
    monkeypatch.chdir(tmp_path)
    _one_line_error(_run(*[a.format(d=files) for a in args]), *pieces, code=2)
    assert os.listdir(tmp_path) == []


def test_a_controller_not_answering_is_named_by_the_command_as_capture_names_it(files, tmp_path, monkeypatch):
    """New-user trial 12: capture said 'capture: KUKAVARPROXY at ...: cannot connect', run-admittance the same
    line without its name."""
    monkeypatch.chdir(tmp_path)
    r = _run("run-admittance", "--params", files / "params.json", "-o", "r.h5", "--backend", "kvp", "--port", "1",
             "--enable-motion", "--q-min", "0", "--q-max", "10")
    _one_line_error(r, "run-admittance: KUKAVARPROXY at 127.0.0.1:1: cannot connect", code=1)
    assert os.listdir(tmp_path) == []


def test_load_option_errors_are_usage_errors_and_data_errors_are_not(tmp_path):
    from scipy.io import savemat
    import numpy as np

    t = np.arange(100) * 0.01
    savemat(tmp_path / "m.mat", {"t": t[:, None], "q": t[:, None], "u": t[:, None], "g": np.array([[2.0]])})
    base = ["load", tmp_path / "m.mat", "--time", "t", "--q", "q", "--tau", "u", "-o", tmp_path / "o.h5"]
    _one_line_error(_run(*base, "--tau-scale", "2", "--tau-scale-var", "g"), "not both", code=2)
    _one_line_error(_run(*base, "--q-scale", "0"), "(--q-scale) must be a finite", code=2)
    _one_line_error(_run(*base, "--tau-scale-var", "nope"), "no variable 'nope'", code=1)  # found in the file
    _one_line_error(_run(*base, "--sample-time", "0.001"), "--time and --sample-time", code=2)
    # an axis number out of range or given twice is the option's fault (it was exit 1, unnamed)
    _one_line_error(_run(*base, "--axis", "0"), "--axis must be distinct axis numbers 1 to 12; got '0'", code=2)
    _one_line_error(_run(*base, "--axis", "1,1"), "--axis must be distinct axis numbers 1 to 12; got '1,1'", code=2)
    assert not (tmp_path / "o.h5").exists()


def test_load_warns_of_a_prismatic_axis_longer_than_any_track(tmp_path):
    from scipy.io import savemat
    import numpy as np

    t = np.arange(100) * 0.01
    savemat(tmp_path / "m.mat", {"t": t[:, None], "q": 0.1 + 0.2 * t[:, None], "u": t[:, None]})
    base = ["load", tmp_path / "m.mat", "--time", "t", "--q", "q", "--tau", "u", "--joint", "prismatic"]
    r = _run(*base, "-o", tmp_path / "a.h5")
    assert r.exit_code == 0 and "warning" not in r.output, r.output
    r = _run(*base, "--q-scale", "10000", "-o", tmp_path / "b.h5")
    assert r.exit_code == 0 and (tmp_path / "b.h5").exists(), r.output
    assert "warning" in r.output and "A1 (prismatic) reaches 2980 m" in r.output and "--q-scale" in r.output


def test_load_refuses_a_log_whose_datasets_differ_in_length(files, tmp_path):
    """A capture log (incremental) whose 'tau' is short: the copy would silently drop rows."""
    import h5py

    src = tmp_path / "shape.h5"
    src.write_bytes((files / "inertia.h5").read_bytes())
    with h5py.File(src, "a") as f:
        n = f["time"].shape[0]
        f["tau"].resize((n - 5, f["tau"].shape[1]))
    r = _run("load", src, "-o", tmp_path / "s.csv")
    _one_line_error(r, "shape.h5", f"'tau' has {n - 5} rows but 'time' has {n}", code=1)
    assert sorted(os.listdir(tmp_path)) == ["shape.h5"]


@pytest.mark.parametrize("args, piece", [
    (["capture", "{log}", "-o", "c.h5"], "not a trajectory file (JSON)"),
    (["show", "{log}"], "not a parameter file (JSON)"),
    (["report", "--params", "{log}", "-o", "r.pdf"], "not a parameter file (JSON)"),
    (["validate", "--params", "{log}", "{log}"], "not a parameter file (JSON)"),
    (["excite", "inertia", "-o", "x.json", "--limits", "{log}"], "not a limits file (JSON)"),
])
@pytest.mark.parametrize("fmt", ["h5", "csv"])
def test_an_axis_log_given_for_a_json_file_is_named_so(files, tmp_path, monkeypatch, args, piece, fmt):
    """An axis log where a JSON file belongs: said so, not 'not valid JSON (line 1, column 1 ...)'."""
    log = files / "inertia.h5"
    if fmt == "csv":
        log = files / "inertia.csv"
        if not log.exists():
            assert _run("load", files / "inertia.h5", "-o", log).exit_code == 0
    monkeypatch.chdir(tmp_path)
    r = _run(*[a.format(log=log) for a in args])
    _one_line_error(r, f"{log}: is an axis log ({fmt.upper() if fmt == 'csv' else 'HDF5'}), {piece}", code=1)
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("name, head, kind", [("r.pdf", b"%PDF-1.4\n", "a PDF (a report)"),
                                              ("t.parquet", b"PAR1\x15\x04", "a Parquet table (kukaid fleet)"),
                                              ("manifest.csv", b"robot,axis,date,path\r\nR001,3,2026-01-05,a.h5\n",
                                               "a fleet manifest (CSV)")])
def test_a_report_or_a_fleet_table_given_for_a_json_file_is_named_so(tmp_path, monkeypatch, name, head, kind):
    """New-user trial 9: `kukaid show fits.parquet` (or report.pdf) said "not valid JSON (line 1, column 1:
    Expecting value)"; an axis log given so was already named as one.  New-user trial 16: a fleet's
    manifest.csv still said "not valid JSON" (fit and validate named it a manifest)."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / name).write_bytes(head + bytes(range(256)))
    for args, piece in ((["show", name], "not a parameter file (JSON)"),
                        (["capture", name, "-o", "c.h5"], "not a trajectory file (JSON)")):
        _one_line_error(_run(*args), f"{name}: is {kind}, {piece}", code=1)
    assert os.listdir(tmp_path) == [name]


@pytest.mark.parametrize("name, fmt", [("run.csv", "a CSV"), ("run.mat", "a MAT"), ("run.csv.gz", "a CSV")])
def test_a_report_or_another_log_given_as_a_csv_or_mat_log_is_named_so(files, tmp_path, monkeypatch, name, fmt):
    """Left from new-user trial 10: a PDF renamed run.csv was "first column must be 'time_s', found
    '%PDF-1.4'", renamed run.mat "not a readable MAT file: Unknown mat file type, version 116, 101";
    named as what it is, as the HDF5 reader names it; so is an HDF5 log renamed.  A CSV log's own
    fault is still said as it was."""
    import gzip

    monkeypatch.chdir(tmp_path)
    pack = gzip.compress if name.endswith(".gz") else (lambda b: b)
    for head, kind in ((b"%PDF-1.4\n", "a PDF (a report)"), (b"\x89HDF\r\n\x1a\n", "an axis log (HDF5)")):
        (tmp_path / name).write_bytes(pack(head + bytes(range(256))))
        for args in (["fit", name, "-o", "p.json"], ["validate", "--params", files / "params.json", name]):
            _one_line_error(_run(*args), f"{name}: is {kind}, not {fmt} axis log", code=1)
    assert os.listdir(tmp_path) == [name]
    if name == "run.csv":
        (tmp_path / name).write_text("time_s,A3_deg\n0,1\n0.012,1\n")
        r = _run("fit", name, "-o", "p.json")
        assert r.exit_code != 0 and "axis log" not in r.output, r.output  # its own fault (a column missing)


def test_a_urdf_and_a_parameter_file_given_for_each_other_are_named_so(files, tmp_path, monkeypatch):
    """New-user trial 10: `kukaid validate --params robot.urdf ...` said "not valid JSON (line 1, column 1:
    Expecting value)", and `fit --robot p.json` (or a log) "not a URDF Pinocchio can read (The file ... does
    not contain a valid URDF model.)": each is named as what it is."""
    from kukaid.models.urdf import robot_urdf

    monkeypatch.chdir(tmp_path)
    urdf = robot_urdf("kr6-r700-sixx")
    for args in (["show", urdf], ["validate", "--params", urdf, files / "inertia.h5"],
                 ["run-admittance", "--params", urdf, "-o", "run.h5"]):
        _one_line_error(_run(*args), f"{urdf}: is a URDF (a robot's description, XML), not a parameter file (JSON)",
                        code=1)
    (tmp_path / "p.json").write_text('{"schema": "kukaid.params/1"}')
    _one_line_error(_run("fit", files / "inertia.h5", "--robot", "p.json", "-o", "q.json"),
                    "p.json: is a JSON file, not a URDF", code=1)
    _one_line_error(_run("fit", files / "inertia.h5", "--robot", files / "inertia.h5", "-o", "q.json"),
                    "inertia.h5: is an axis log (HDF5), not a URDF", code=1)
    assert os.listdir(tmp_path) == ["p.json"]


@pytest.mark.parametrize("head, kind", [(b"%PDF-1.4\n", "a PDF (a report)"),
                                        (b"PAR1\x15\x04", "a Parquet table (kukaid fleet)"),
                                        (b"time_s,q_A3,tau_A3\n0,0,0\n", "an axis log (CSV)")])
def test_a_report_or_a_table_given_as_an_hdf5_log_is_named_so(files, tmp_path, monkeypatch, head, kind):
    """New-user trial 10: a PDF renamed run.h5, given as a log, was "not a readable HDF5 file
    (truncated or corrupt)": named as what it is, as the JSON inputs name it."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "run.h5").write_bytes(head + bytes(range(256)))
    for args in (["fit", "run.h5", "-o", "p.json"], ["validate", "--params", files / "params.json", "run.h5"],
                 ["diagnose", "--params", files / "params.json", "--log", "run.h5"]):
        _one_line_error(_run(*args), f"run.h5: is {kind}, not an HDF5 axis log", code=1)
    assert os.listdir(tmp_path) == ["run.h5"]
    (tmp_path / "run.h5").write_bytes(b"\x89HDF\r\n\x1a\n" + bytes(100))  # an HDF5 file cut short: as before
    _one_line_error(_run("fit", "run.h5", "-o", "p.json"), "run.h5: not a readable HDF5 file (truncated or corrupt)")


def test_fit_of_logs_of_different_axes_names_each_log_and_its_axis(files, tmp_path):
    """New-user trial 9: `fit --friction friction.h5 --inertia i2.h5` said "the logs are of different axes
    [2, 3]; choose one with --axis": which log was which went unsaid, and --axis 3 then failed on i2.h5."""
    assert _run("excite", "inertia", "--axis", "2", "-o", tmp_path / "i2.json", "--period", "2",
                "--n-periods", "3").exit_code == 0
    assert _run("capture", tmp_path / "i2.json", "-o", tmp_path / "i2.h5", "--seed", "3").exit_code == 0
    r = _run("fit", "--friction", files / "inertia.h5", "--inertia", tmp_path / "i2.h5", "-o", tmp_path / "p.json")
    _one_line_error(r, f"the logs are of different axes ({files / 'inertia.h5'}: A3, {tmp_path / 'i2.h5'}: A2): "
                       "a fit is of one axis; give the logs of one",
                    code=1)
    assert not (tmp_path / "p.json").exists()


def test_one_recording_given_twice_is_refused_by_fit_and_diagnose(files, tmp_path):
    """New-user trial 10: `fit --friction f.h5 --friction f.h5` weighed the recording double (standard
    deviations too small by sqrt 2) and `diagnose --log a.h5 --log b.h5 --log a.h5` held a.h5 out with its
    copy in the fit ("held out ... better in 3/3 folds"); fit --robot already refused it."""
    log = files / "inertia.h5"
    copy = tmp_path / "copy.h5"
    copy.write_bytes(log.read_bytes())  # another name, the same samples
    for args, what in ((["fit", "--friction", log, "--inertia", copy, "-o", tmp_path / "p.json"],
                        ": the same recording as "),
                       (["fit", log, log, "--friction-model", "coulomb-viscous", "-o", tmp_path / "p.json"],
                        f"{log}: given twice"),  # new-user trial 15: it said the same recording as itself
                       (["diagnose", "--params", files / "params.json", "--log", log, "--log", copy, "-o",
                         tmp_path / "p.json"], ": the same recording as ")):
        r = _run(*args)
        _one_line_error(r, what, "give each recording once", code=1)
    assert sorted(os.listdir(tmp_path)) == ["copy.h5"]


def test_a_kukaid_file_given_as_limits_is_named_so(files, tmp_path, monkeypatch):
    """New-user trial 9: `excite --limits params.json` said "unknown key 'schema' (known: q_min, ...)"."""
    monkeypatch.chdir(tmp_path)
    for name, schema in (("params.json", "kukaid.params/1"), ("inertia.json", "kukaid.trajectory/1")):
        r = _run("excite", "inertia", "-o", "x.json", "--limits", files / name)
        _one_line_error(r, f"{files / name}: is a {schema} file, not a limits file (JSON: q_min, q_max, qd_max, "
                           "qdd_max, optionally with _deg)", code=1)
    assert os.listdir(tmp_path) == []


def test_a_kukaid_file_given_as_another_json_input_is_named_so(files, tmp_path, monkeypatch):
    """New-user trial 13: a trajectory given as --sim-config said "unknown field 'schema' (known: ...)", as a
    gear-ratio file "'schema' is not an axis (A1 to A12)", as --coupling "must be a 6 x 6 matrix of numbers",
    and a parameter file as a fourier --limits file "expected an object {axis name: limits}"."""
    from trace_set import write_kr_c4_set

    monkeypatch.chdir(tmp_path)
    traj, params = files / "inertia.json", files / "params.json"
    robot_traj = tmp_path / "robot.json"
    robot_traj.write_text(json.dumps({"schema": "kukaid.robot-trajectory/1"}))
    write_kr_c4_set(tmp_path, duration=0.1)
    for args, what in (
            (["capture", traj, "-o", "c.h5", "--sim-config", traj], f"{traj}: is a kukaid.trajectory/1 file, not a "
             "simulator configuration (JSON)"),
            (["run-admittance", "--params", params, "-o", "r.h5", "--sim-config", robot_traj],
             f"{robot_traj}: is a kukaid.robot-trajectory/1 file, not a simulator configuration (JSON)"),
            (["excite", "fourier", "-o", "f.json", "--limits", params], f"{params}: is a kukaid.params/1 file, not a "
             "limits file (JSON)"),
            (["fit", files / "inertia.h5", "--robot", "kr6-r700-sixx", "--rotor-inertia", "--coupling", params, "-o",
              "p.json"], f"{params}: is a kukaid.params/1 file, not a coupling matrix (JSON)"),
            (["load", tmp_path / "Rec_NextGenDrive#1.dat", "--gear-ratio", traj, "-o", "g.h5"],
             f"{traj}: is a kukaid.trajectory/1 file, not a JSON file of gear ratios")):
        _one_line_error(_run(*args), what, code=1)
    assert not [f for f in os.listdir(tmp_path) if not f.startswith(("Rec_", "robot.json"))]


@pytest.mark.parametrize("ratios, said", [("A1=0", "gear ratio of A1 must be finite and non-zero; got 0"),
                                           ("A1=x", "gear ratio of A1 is not a number: 'x'"),
                                           ("A13=100", "'A13' is not an axis (A1 to A12)"),
                                           ("A1:100", "'A1:100' is not AXIS=RATIO")])
def test_gear_ratios_typed_on_the_command_line_are_usage_errors(ratios, said, tmp_path):
    """New-user trial 13: `load rec.dat --gear-ratio A1=0` was exit status 1, a problem of the data; the
    ratios typed as the option's value are the option's (exit 2), as every option out of range."""
    from trace_set import write_kr_c4_set

    write_kr_c4_set(tmp_path, duration=0.1)
    r = _run("load", tmp_path / "Rec_NextGenDrive#1.dat", "--gear-ratio", ratios, "-o", tmp_path / "g.h5")
    _one_line_error(r, "--gear-ratio", said, code=2)
    assert not (tmp_path / "g.h5").exists()


def test_a_robot_sim_config_whose_coupling_is_of_another_size_is_named(tmp_path, monkeypatch):
    """New-user trial 13: `capture fourier.json --sim-config c.json` with a 1 x 1 coupling said "robot sim
    config: field 'coupling' must be 6 x 6 for this robot", not which file."""
    monkeypatch.chdir(tmp_path)
    traj = tmp_path / "robot.json"
    traj.write_text(json.dumps({"schema": "kukaid.robot-trajectory/1", "kind": "fourier", "robot": "kr6-r700-sixx",
                                "axes": [1, 2, 3, 4, 5, 6], "sample_time": 0.012, "t": [0.0, 0.012],
                                "q": [[0.0] * 6, [0.0] * 6]}))
    (tmp_path / "c.json").write_text(json.dumps({"coupling": [[1.0]]}))
    r = _run("capture", traj, "-o", "c.h5", "--sim-config", "c.json")
    _one_line_error(r, "c.json: field 'coupling' must be 6 x 6 for this robot, got (1, 1)", code=1)
    assert not (tmp_path / "c.h5").exists()


def test_fit_cutoff_above_the_logs_nyquist_names_the_option(files):
    """Its limit depends on the log's sample rate: found with the data, but an option out of range
    (exit 2) that says --cutoff and the log; the defaults' limits stay data errors (exit 1)."""
    r = _run("fit", files / "inertia.h5", "-o", files / "p_cut.json", "--cutoff", "100")
    _one_line_error(r, "inertia.h5: --cutoff 100 Hz must be in", code=2)
    r = _run("diagnose", "--params", files / "params.json", "--log", files / "inertia.h5", "--cutoff", "100")
    _one_line_error(r, "inertia.h5: --cutoff 100 Hz must be in", code=2)
    assert not (files / "p_cut.json").exists()


@pytest.mark.parametrize("make_args, kind", [
    (lambda d, o: ["excite", "friction", "-o", o], "kukaid.params/1"),
    (lambda d, o: ["excite", "friction", "-o", o], "kukaid.robot-trajectory/1"),  # six axes are not one
    (lambda d, o: ["fit", d / "inertia.h5", "--friction-model", "coulomb-viscous", "-o", o], "kukaid.trajectory/1"),
    (lambda d, o: ["fit", d / "inertia.h5", "--friction-model", "coulomb-viscous", "-o", o], None),
    (lambda d, o: ["diagnose", "--params", d / "params.json", "--log", d / "inertia.h5", "-o", o],
     "kukaid.trajectory/1"),
])
def test_a_json_output_replaces_only_its_own_kind_without_force(files, tmp_path, make_args, kind):
    """A fitted parameter file is not lost to a trajectory written under its name, nor the reverse;
    --force replaces it.  Notes of the user's (not kukaid JSON) are kept too."""
    out = tmp_path / "out.json"
    text = '{"schema": "%s", "mine": 1}' % kind if kind else '{"notes": "by hand"}'
    out.write_text(text)
    _one_line_error(_run(*make_args(files, out)), "out.json: already exists", "--force", code=1)
    assert out.read_text() == text and os.listdir(tmp_path) == ["out.json"]
    r = _run(*make_args(files, out), "--force")
    assert r.exit_code == 0, r.output
    assert out.read_text() != text


def test_a_json_output_of_the_same_kind_is_replaced(files, tmp_path):
    """Trajectories and fitted parameters are derived from options and logs: writing them again is allowed."""
    traj, params = tmp_path / "t.json", tmp_path / "p.json"
    for _ in range(2):
        assert _run("excite", "inertia", "-o", traj, "--period", "2").exit_code == 0
        r = _run("fit", files / "inertia.h5", "--friction-model", "coulomb-viscous", "-o", params)
        assert r.exit_code == 0, r.output
    assert '"kukaid.trajectory/1"' in traj.read_text() and '"kukaid.params/1"' in params.read_text()


def test_excite_keeps_existing_krl_files_without_force(tmp_path):
    """As krl-follower and krl-logger: a KRL file may have been edited for the robot."""
    krl = tmp_path / "krl"
    args = ["excite", "inertia", "-o", tmp_path / "t.json", "--krl", krl]
    assert _run(*args).exit_code == 0
    src = krl / "kukaid_inertia.src"
    assert b"\r\n" in src.read_bytes()  # the controller's CR LF line ends, as krl-follower's and krl-logger's
    src.write_text(src.read_text() + "; tuned on the robot\n")
    edited = src.read_bytes()
    before = (tmp_path / "t.json").read_bytes()
    _one_line_error(_run(*args, "--period", "3"), "kukaid_inertia.src: already exists", "--force", code=1)
    assert src.read_bytes() == edited and (tmp_path / "t.json").read_bytes() == before  # all or nothing
    assert _run(*args, "--period", "3", "--force").exit_code == 0
    assert src.read_bytes() != edited


def test_an_internal_error_has_its_own_exit_status(files, monkeypatch):
    """A bug is one line too, but not exit status 2, which says the user's options were wrong: 70
    (EX_SOFTWARE), distinct from every status docs/errors.md gives (1, 2, 3, 4, 130, 141)."""
    import kukaid.params

    from kukaid.errors import EXIT_INTERNAL

    def boom(*a, **k):
        raise RuntimeError("boom")

    monkeypatch.delenv("KUKAID_DEBUG", raising=False)
    monkeypatch.setattr(kukaid.params, "load_any_params", boom)
    r = _run("show", files / "params.json")
    _one_line_error(r, "internal error (RuntimeError: boom)", "KUKAID_DEBUG=1", code=70)
    assert EXIT_INTERNAL == 70 and EXIT_INTERNAL not in (0, 1, 2, 3, 4, 130, 141)


def test_a_fit_decimated_to_a_handful_of_samples_says_so(files, tmp_path):
    """`fit --decimate 300` leaves a sample or two: the error said the axis moves in one direction only."""
    r = _run("fit", files / "inertia.h5", "--friction-model", "coulomb-viscous", "--decimate", "300",
             "-o", tmp_path / "p.json")
    _one_line_error(r, "inertia.h5: only ", "dynamic-mode samples for 4 parameters", "--decimate 300", code=1)
    assert "one direction" not in r.output and not (tmp_path / "p.json").exists()


def test_files_a_windows_editor_saved_with_a_byte_order_mark_are_read(files, tmp_path):
    """Excel's 'CSV UTF-8' and Notepad put a UTF-8 byte order mark first: a log CSV was refused
    with "first column must be 'time_s', found 'time_s'" (the mark unseen), a JSON file with
    'Unexpected UTF-8 BOM', a fleet manifest lacked its column 'robot'."""
    from kukaid.fleet.manifest import read_manifest

    bom = b"\xef\xbb\xbf"
    assert _run("load", files / "inertia.h5", "-o", tmp_path / "log.csv").exit_code == 0
    (tmp_path / "bom.csv").write_bytes(bom + (tmp_path / "log.csv").read_bytes())
    r = _run("load", tmp_path / "bom.csv", "-o", tmp_path / "bom.h5")
    assert r.exit_code == 0, r.output
    (tmp_path / "bom.json").write_bytes(bom + (files / "params.json").read_bytes())
    r = _run("show", tmp_path / "bom.json")
    assert r.exit_code == 0 and "Izz" in r.output, r.output
    (tmp_path / "m.csv").write_bytes(bom + b"robot,axis,date,path\nR1,3,2026-01-05,log.csv\n")
    assert [(e.robot, e.axis) for e in read_manifest(tmp_path / "m.csv")] == [("R1", 3)]


def test_a_log_csv_with_semicolons_says_so(tmp_path):
    """A spreadsheet set to a decimal comma exports ';'-separated columns: the error quoted the
    whole header as the first column's name."""
    p = tmp_path / "semi.csv"
    p.write_text("time_s;A3_deg;A3_Nm\n0,012;1,5;2,0\n")
    r = _run("load", p, "-o", tmp_path / "x.h5")
    _one_line_error(r, "semi.csv: columns must be separated by commas, not ';'", code=1)
    # new-user trial 9: "(the header is 'time_s,A3_deg,A3_Nm,...')" read as this file's header, which it is not
    assert r.output.strip().endswith("decimal mark (a header as 'time_s,A3_deg,A3_Nm,...'; this one is "
                                     "'time_s;A3_deg;A3_Nm')"), r.output


@pytest.mark.parametrize("make_args, said", [
    (lambda d, o: ["excite", "friction", "-o", o, "--speeds", "0.1,abc"], "Invalid value for --speeds"),
    (lambda d, o: ["fit", d / "inertia.h5", "-o", o, "--bound", "vs=1:0"], "Invalid value for --bound"),
    (lambda d, o: ["load", d / "inertia.h5", "-o", o.with_suffix(".h5"), "--time-scale", "-1"],
     "option --time-scale is for MAT (.mat) sources"),
])
def test_a_wrong_option_is_said_before_an_existing_output(files, tmp_path, make_args, said):
    """New-user trial 17: with an output that already exists, excite, fit and load said "already exists"
    and only after --force the option that was wrong (trial 6 mended run-admittance's order alone)."""
    out = tmp_path / "other.json"
    out.write_text('{"notes": "by hand"}')
    out.with_suffix(".h5").write_bytes(b"mine")
    _one_line_error(_run(*make_args(files, out)), said, code=2)
    assert out.read_text() == '{"notes": "by hand"}' and out.with_suffix(".h5").read_bytes() == b"mine"


def test_a_failed_write_leaves_no_folder_it_made(tmp_path):
    """Trial 18: outputs' missing folders are made (as documented), and a command that then failed left
    the new, empty folders behind. Folders made for the outputs are removed again on a failure; a
    folder that was there, or that holds something else by then, stays."""
    from kukaid.atomic import atomic_paths

    with pytest.raises(RuntimeError):
        with atomic_paths(tmp_path / "new" / "sub" / "a.json", tmp_path / "new" / "b.pdf"):
            raise RuntimeError("drawing failed")
    assert sorted(p.name for p in tmp_path.iterdir()) == []
    (tmp_path / "kept").mkdir()
    with pytest.raises(RuntimeError):
        with atomic_paths(tmp_path / "kept" / "deep" / "a.json"):
            (tmp_path / "kept" / "other.txt").write_text("x")
            raise RuntimeError("drawing failed")
    assert sorted(p.name for p in (tmp_path / "kept").iterdir()) == ["other.txt"]
    with atomic_paths(tmp_path / "made" / "c.json") as (tmp,):
        tmp.write_text("{}")
    assert (tmp_path / "made" / "c.json").read_text() == "{}"
