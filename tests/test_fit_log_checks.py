"""`kukaid fit` checks the data behind a result: a log of held samples (a KUKAVARPROXY poll faster
than the controller's 12 ms) is refused with one line naming it and what to do; a log given in the
role of another experiment (its `experiment` attribute) is a printed warning."""
from __future__ import annotations

import json
import os
import subprocess

import numpy as np
import pytest

from kukaid import excite
from kukaid.errors import FitError
from kukaid.identify import fit_axis
from kukaid.identify.adequacy import check_not_held, held_share, role_warnings
from kukaid.logs import AxisLog, read_log, write_hdf5
from kukaid.sim import SimConfig, VirtualKRC4


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    d = tmp_path_factory.mktemp("fitchecks")
    paths = {}
    for kind, opts, seed in (("friction", dict(n_speeds=6), 1), ("inertia", {}, 2)):
        log = VirtualKRC4(SimConfig(), seed=seed).run(excite.generate(kind, **opts))
        paths[kind] = d / f"{kind}.h5"
        write_hdf5(log, paths[kind])
    return d, paths


def held(log: AxisLog, times: int = 80, seed: int = 0) -> AxisLog:
    """The log as a poll ``times`` faster than its samples recorded it: each sample repeated, PC-stamped."""
    rng = np.random.default_rng(seed)
    t = log.time[0] + np.cumsum(rng.uniform(0.5, 1.5, size=log.n_samples * times) * 0.012 / times)
    idx = np.minimum(np.searchsorted(log.time, t, side="right") - 1, log.n_samples - 1)
    attrs = {k: v for k, v in log.attrs.items() if k != "source_file"}
    attrs.update(source="kukavarproxy", capture_mode="poll")
    return AxisLog(t - t[0], log.q[idx], log.tau[idx], axes=log.axes, attrs=attrs)


def test_held_log_is_refused_naming_it(logs, tmp_path, kukaid_cmd):
    d, p = logs
    lg = read_log(p["inertia"])
    assert held_share(lg) == 0.0
    srv = tmp_path / "srv.h5"
    write_hdf5(held(lg), srv)
    with pytest.raises(FitError, match=r"srv\.h5: 9\d% of the samples repeat the one before exactly .*--mode ring"):
        fit_axis(inertia=[srv], friction_model="stribeck")
    r = subprocess.run([*kukaid_cmd, "fit", "--inertia", str(srv), "-o", str(tmp_path / "p.json")],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 1 and not (tmp_path / "p.json").exists()
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"kukaid: error: {srv}: ") and "held" in lines[0], r.stderr
    # polled just twice per sample is held too; a KVP log faster than 4 ms is held whatever its values
    with pytest.raises(FitError, match="repeat the one before"):
        check_not_held(held(lg, times=2), "twice.h5")
    fast = AxisLog(np.arange(lg.n_samples) * 0.001, lg.q, lg.tau, axes=lg.axes, attrs={"source": "kukavarproxy"})
    with pytest.raises(FitError, match=r"fast\.h5: 0% .*1000 Hz"):
        check_not_held(fast, "fast.h5")
    # a 1 kHz log of another source (KUKA Trace drives, EMPS) with new values every sample is fine
    check_not_held(AxisLog(fast.time, lg.q, lg.tau, axes=lg.axes, attrs={"source": "mat"}), "ok.h5")


def test_logs_in_the_wrong_role_are_warned(logs, kukaid_cmd):
    d, p = logs
    out = d / "swapped.json"
    r = subprocess.run([*kukaid_cmd, "fit", "--friction", str(p["inertia"]), "--inertia", str(p["friction"]),
                        "-o", str(out)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert (f"warning: {p['inertia']} was given as --friction but records the 'inertia' experiment" in r.stdout
            and "give it as --inertia" in r.stdout), r.stdout
    assert f"warning: {p['friction']} was given as --inertia but records the 'friction' experiment" in r.stdout
    # the right roles: no such warning
    r = subprocess.run([*kukaid_cmd, "fit", "--friction", str(p["friction"]), "--inertia", str(p["inertia"]),
                        "-o", str(d / "right.json")], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0 and "was given as" not in r.stdout, r.stdout


def test_with_json_the_warnings_are_on_stderr_too(logs, kukaid_cmd):
    """--json: stdout is for a script, so a person sees the warnings on stderr (as run-admittance)."""
    d, p = logs
    r = subprocess.run([*kukaid_cmd, "fit", "--friction", str(p["inertia"]), "--inertia", str(p["friction"]),
                        "-o", str(d / "swapped_json.json"), "--json"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert (f"kukaid: warning: fit: {p['inertia']} was given as --friction but records the 'inertia' experiment"
            in r.stderr), r.stderr
    assert any("was given as --friction" in w for w in json.loads(r.stdout)["metrics"]["warnings"])


def test_a_log_that_skips_samples_is_refused(logs, kukaid_cmd, tmp_path):
    """A poll capture on a busy PC misses samples (6 % of the steps on one axis); the filters take
    the samples as evenly spaced, so it validated at 25 % relative error against 0.58 % in ring
    mode. Refused with one line naming the log and ring mode; a single gap (a reconnect) is not."""
    from kukaid.identify.filtering import check_even_samples

    lg = read_log(logs[1]["inertia"])
    keep = np.ones(lg.n_samples, bool)
    keep[10:-10:50] = False  # one sample in 50 missed
    gappy = AxisLog(lg.time[keep], lg.q[keep], lg.tau[keep], axes=lg.axes, attrs=dict(lg.attrs))
    path = tmp_path / "gappy.h5"
    write_hdf5(gappy, path)
    out = tmp_path / "g.json"
    r = subprocess.run([*kukaid_cmd, "fit", "--inertia", str(path), "-o", str(out)], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 1 and len(r.stderr.splitlines()) == 1, r.stderr
    assert f"{path}: 2.1 % of the steps between samples skip samples" in r.stderr and "--mode ring" in r.stderr
    assert not out.exists()
    good = tmp_path / "good.json"
    assert subprocess.run([*kukaid_cmd, "fit", "--inertia", str(logs[1]["inertia"]), "-o", str(good)],
                          capture_output=True, timeout=300).returncode == 0
    for cmd in (["validate", str(path)], ["diagnose", "--log", str(path)]):  # the one-axis diagnosis too
        r = subprocess.run([*kukaid_cmd, cmd[0], "--params", str(good), *cmd[1:]], capture_output=True, text=True,
                           timeout=300)
        assert r.returncode == 1 and len(r.stderr.splitlines()) == 1 and "--mode ring" in r.stderr, r.stderr
    one_gap = lg.time.copy()
    one_gap[500:] += 0.5
    check_even_samples(one_gap, "reconnect.h5")


def test_a_ring_capture_that_skips_samples_is_not_told_to_use_ring_mode(logs, kukaid_cmd, tmp_path):
    """A ring-mode capture whose PC fell behind (KUKAVARPROXY replies 150 ms late: 33 overflows,
    2 % of the steps skipped) was refused with 'record with capture --mode ring', the mode it was
    recorded in.  The line now names the ring's overflows and the longer ring of krl-logger."""
    from kukaid.identify.filtering import check_even_samples

    lg = read_log(logs[1]["inertia"])
    keep = np.ones(lg.n_samples, bool)
    keep[10:-10:50] = False
    attrs = dict(lg.attrs, source="kukavarproxy", capture_mode="ring", ring_overflows=33)
    path = tmp_path / "ring.h5"
    write_hdf5(AxisLog(lg.time[keep], lg.q[keep], lg.tau[keep], axes=lg.axes, attrs=attrs), path)
    out = tmp_path / "r.json"
    r = subprocess.run([*kukaid_cmd, "fit", "--inertia", str(path), "-o", str(out)], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 1 and len(r.stderr.splitlines()) == 1, r.stderr
    assert f"{path}: 2.1 % of the steps between samples skip samples" in r.stderr
    assert "33 ring overflows" in r.stderr and "krl-logger --blocks" in r.stderr and "--mode ring" not in r.stderr
    assert not out.exists()
    with pytest.raises(FitError, match="poll capture .* --mode ring"):  # a poll capture keeps its advice
        check_even_samples(lg.time[keep], "poll.h5", dict(attrs, capture_mode="poll"))


def test_a_run_admittance_log_is_warned_by_fit_validate_and_diagnose(logs, kukaid_cmd, tmp_path):
    """A run log's torque holds the person's push: the demo's run validated at 32 % relative error and
    diagnosed at 50 x the noise floor without a word on why; fit, validate and diagnose now say so."""
    d, p = logs
    lg = read_log(p["inertia"])
    run = AxisLog(lg.time, lg.q, lg.tau, axes=lg.axes, attrs={**lg.attrs, "experiment": "admittance",
                                                              "source": "kukaid run-admittance"})
    path = tmp_path / "run.h5"
    write_hdf5(run, path)
    what = f"{path} is a run log of kukaid run-admittance: its torque holds the push of the person"
    r = subprocess.run([*kukaid_cmd, "fit", str(p["friction"]), str(path), "-o", str(tmp_path / "f.json")],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0 and f"warning: {what}" in r.stdout, r.stdout + r.stderr
    r = subprocess.run([*kukaid_cmd, "fit", "--friction", str(p["friction"]), "--inertia", str(path),
                        "-o", str(tmp_path / "g.json")], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0 and what in r.stdout and "was given as" not in r.stdout, r.stdout + r.stderr
    for cmd in ("validate", "diagnose"):
        r = subprocess.run([*kukaid_cmd, cmd, "--params", str(tmp_path / "g.json"), *(["--log"] if cmd == "diagnose"
                            else []), str(path)], capture_output=True, text=True, timeout=300)
        assert r.returncode == 0 and f"kukaid: warning: {cmd}: {what}" in r.stderr, r.stderr
    r = subprocess.run([*kukaid_cmd, "validate", "--params", str(tmp_path / "g.json"), str(p["inertia"])],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0 and "run log" not in r.stderr, r.stderr


def test_a_fit_of_run_logs_only_says_they_are_run_logs(tmp_path, monkeypatch):
    """New-user trial 10: `kukaid fit run.h5` (a run-admittance log, pushed one way) said "the axis moves in
    one direction only": a fit of run logs only is refused naming them as run logs of hand guiding, not
    excitation logs; with an excitation log beside one it stays a warning (above)."""
    from click.testing import CliRunner

    from kukaid.params import save_params
    from kukaid_cli.main import cli

    monkeypatch.chdir(tmp_path)
    save_params("truth.json", SimConfig().truth_params())
    r = CliRunner().invoke(cli, ["run-admittance", "--params", "truth.json", "--operator", "push", "--seed", "4",
                                 "--duration", "7", "-o", "run.h5"])
    assert r.exit_code == 0, r.output
    said = ("is a run log of kukaid run-admittance (hand guiding), not an excitation log: its torque holds the push "
            "of the person guiding the axis")
    for args in (["run.h5"], ["--inertia", "run.h5"], ["run.h5", "--friction-model", "coulomb-viscous"]):
        r = CliRunner().invoke(cli, ["fit", *args, "-o", "p.json"])
        assert r.exit_code == 1 and r.stderr.startswith(f"kukaid: error: run.h5: {said}"), (args, r.output)
        assert len(r.output.splitlines()) == 1 and "one direction" not in r.output
    assert sorted(os.listdir(tmp_path)) == ["run.h5", "truth.json"]


def test_role_warning_needs_the_attribute():
    t = np.arange(100) * 0.012
    lg = AxisLog(t, np.sin(t)[:, None], np.cos(t)[:, None], axes=(3,), attrs={"source_file": "imported.csv"})
    assert role_warnings(lg, "inertia") == []  # imported from CSV/MAT: nothing recorded, nothing said
    lg.attrs["experiment"] = "inertia"
    assert role_warnings(lg, "inertia") == []
    lg.attrs["experiment"] = "validation"
    (w,) = role_warnings(lg, "friction")
    assert "imported.csv was given as --friction but records the 'validation' experiment" in w
    assert "general log" in w


def test_radians_under_a_degree_header_are_warned_naming_the_column(logs, tmp_path):
    """New-user trial nu12 item 7: a CSV with radians under A3_deg fitted with no unit warning (Izz and
    Fv 57 x the truth); now a warning names the column and the likely cause, and the fit still runs."""
    from kukaid.logs import write_csv

    d, p = logs
    good = tmp_path / "good.csv"
    write_csv(read_log(p["friction"]), good, angle_unit="rad")
    bad = tmp_path / "radasdeg.csv"
    lines = good.read_text().splitlines()
    bad.write_text("\n".join([lines[0].replace("_rad", "_deg"), *lines[1:]]) + "\n")
    params = fit_axis(friction=[bad], inertia=[p["inertia"]])
    (w,) = [w for w in params["metrics"]["warnings"] if "degree header" in w]
    assert w.startswith(f"{bad}: column A3_deg spans only ") and "radians written under a degree header?" in w
    assert not [w for w in fit_axis(friction=[good], inertia=[p["inertia"]])["metrics"]["warnings"]
                if "degree header" in w]


def test_a_presliding_log_given_as_a_general_log_says_to_give_it_as_presliding(tmp_path):
    """New-user trial nu12 item 16: `fit presliding.h5` said the axis moves in one direction only, though
    the log moves both ways (micro-reversals below qd_thr); now the line says it is at dynamic-mode
    speeds only, and that the log records the pre-sliding experiment: --presliding."""
    log = VirtualKRC4(SimConfig(), seed=3).run(excite.generate("presliding", hold=2.0, final_hold=2.0))
    path = tmp_path / "presliding.h5"
    write_hdf5(log, path)
    with pytest.raises(FitError) as e:
        fit_axis(logs=[path])
    msg = str(e.value)
    assert "presliding.h5 records the pre-sliding experiment (attribute 'experiment'): give it as --presliding" in msg
    assert "dynamic-mode" in msg and "qd_thr 0.0017 rad/s" in msg, msg


def test_time_stamps_with_jitter_fit_as_an_even_log(logs):
    """Trial 16: a controller's samples stamped by a PC with ±3 ms of jitter (12 ms steps) fitted Fv
    12 % low (differentiated on the stamps), and samples taken at ±3 ms jittered instants (the
    virtual KR C4's ``jitter``) were refused as skipping samples, 12 % low again when let through.
    The even grid now replaces stamps the positions are smoother without, and positions sampled at
    the stamps are interpolated onto it; both fit the even log's friction."""
    lg = read_log(logs[1]["friction"])
    even = fit_axis(friction=[lg])
    rng = np.random.default_rng(5)
    stamped = AxisLog(lg.time + rng.uniform(-0.003, 0.003, lg.n_samples), lg.q, lg.tau, axes=lg.axes,
                      attrs=dict(lg.attrs))
    sampled = VirtualKRC4(SimConfig(jitter=0.003), seed=1).run(excite.generate("friction", n_speeds=6))
    for log, base in ((stamped, "re-stamped"), (sampled, "resampled")):
        p = fit_axis(friction=[log])
        assert p["provenance"]["preprocess"]["time_base"] == base
        for k in ("Fc", "Fv"):
            assert p["friction"][k] == pytest.approx(even["friction"][k], rel=0.01), (base, k)
    assert even["provenance"]["preprocess"]["time_base"] == "even"


def test_a_logs_time_base_is_judged_once_for_all_its_axes(monkeypatch):
    """Stop 41's review: every preprocess judged the time base again (each axis of a compare, each
    column set of the robot fit): 0.7 s each on a 1-hour six-axis log with uneven stamps. One log's
    axes are now judged once, and another log with the same values is judged for itself."""
    import kukaid.identify.filtering as F

    calls = []
    real = F._roughness
    monkeypatch.setattr(F, "_roughness", lambda *a: calls.append(1) or real(*a))
    rng = np.random.default_rng(2)
    t = 0.004 * np.arange(3000)
    q = np.column_stack([0.4 * np.sin(0.7 * t + k) for k in range(6)])
    tau = np.column_stack([5.0 * np.sin(0.7 * t + k) for k in range(6)]) + 0.05 * rng.standard_normal((t.size, 6))
    stamps = t + rng.uniform(-0.001, 0.001, t.size)
    lg = AxisLog(stamps, q, tau, axes=tuple(range(1, 7)), attrs={"source_file": "six.csv"})
    bases = [F.preprocess(lg, axis=a).settings["time_base"] for a in range(1, 7)]
    assert bases == ["re-stamped"] * 6 and len(calls) == 2      # the grid and the stamps, once
    other = AxisLog(stamps.copy(), q.copy(), tau, axes=lg.axes, attrs={"source_file": "copy.csv"})
    assert F.evenly_sampled(other)[1] == "re-stamped" and len(calls) == 4


@pytest.mark.parametrize("share", [0.25, 0.4])
def test_stamp_jitter_is_no_skipped_sample(share):
    """Each stamp off by up to ``share`` of a 12 ms step: no step skips a sample (the first quartile
    of the steps, taken as the step, read the long ones as skips: refused at 0.4)."""
    from kukaid.identify.filtering import check_even_samples

    rng = np.random.default_rng(3)
    t = 0.012 * np.arange(20000) + rng.uniform(-share, share, 20000) * 0.012
    check_even_samples(t, "stamped.csv")
    keep = np.ones(t.size, bool)
    keep[::40] = False  # 2.5 % of the samples lost: refused, jitter or not
    with pytest.raises(FitError, match=r"stamped\.csv: [12]\.\d % of the steps between samples skip samples"):
        check_even_samples(t[keep], "stamped.csv")


def test_logs_at_several_rates_say_each_rates_filter(logs):
    """Trial 17: a friction log at 83 Hz and an inertia log at 250 Hz were each filtered by their own
    settings, but the fit said only the first's ("84 edge samples trimmed ... from the 83.33 Hz sample
    rate"); it now names each rate's."""
    fast = VirtualKRC4(SimConfig(sample_time=0.004), seed=2).run(excite.generate("inertia"))
    p = fit_axis(friction=[read_log(logs[1]["friction"])], inertia=[fast])
    why = p["provenance"]["preprocess"]["why"]
    assert "each filtered by its own settings" in why and "at 250 Hz 5 Hz order 3, 250 edge samples" in why, why
    one = fit_axis(friction=[read_log(logs[1]["friction"])], inertia=[read_log(logs[1]["inertia"])])
    assert "several sample rates" not in one["provenance"]["preprocess"]["why"]
