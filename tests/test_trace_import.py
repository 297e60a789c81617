"""KUKA Trace (.dat/.r64) import from files written here from known signals; malformed cases."""
from __future__ import annotations

import json
import math
import subprocess

import numpy as np
import pytest

from kukaid.errors import LogFormatError
from kukaid.logs import read_hdf5, read_log
from kukaid.logs import read_trace
from trace_set import DEG, GEAR, write_kr_c4_set, write_module


def _signals(t):
    q = 30.0 + 20.0 * np.sin(2 * np.pi * t / 4.0)  # deg
    tau = 12.0 * np.cos(2 * np.pi * t / 4.0) - 7.5  # N·m
    temp = 31.0 + 0.5 * t  # °C
    return q, tau, temp


def test_single_module(tmp_path):
    t = np.arange(400) * 0.012
    q, tau, temp = _signals(t)
    dat = write_module(tmp_path, "REC_NextGenDrive#1", 0.012, t.size, [
        ("Istposition A3", "Grad", q), ("Istmoment A3", "Nm", tau), ("Motortemperatur A3", "°C", temp),
        ("Istposition A2", "Grad", np.full(t.size, -90.0)), ("Sonstiges", "V", np.zeros(t.size))])
    log = read_trace(dat)
    assert log.axes == (3,)  # A2 has no torque channel: not logged
    np.testing.assert_allclose(log.time, t, rtol=0, atol=1e-12)
    np.testing.assert_allclose(log.q[:, 0], q * math.pi / 180, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(log.tau[:, 0], tau)
    np.testing.assert_array_equal(log.temp[:, 0], temp)
    assert log.q_cmd is None and log.attrs["source"] == "kuka-trace"
    assert log.attrs["trace_channels"]["q A3"].startswith("Istposition A3")


def test_multi_module_different_sample_times_on_one_time_base(tmp_path):
    td = np.arange(1500) * 0.004  # drive module, 4 ms, starts at 0
    q, tau, temp = _signals(td)
    write_module(tmp_path, "REC_NextGenDrive#1", 0.004, td.size, [
        ("Istposition A3", "rad", q * math.pi / 180), ("Istposition A1", "Grad", 0.1 * td),
        ("Istmoment A3", "Nm", tau), ("Istmoment A1", "Nm", -tau)])
    ti = 0.048 + np.arange(480) * 0.012  # interpolator, 12 ms, starts later, ends earlier
    qc = 30.0 + 20.0 * np.sin(2 * np.pi * (ti - 0.02) / 4.0)
    write_module(tmp_path, "REC_KRCIpo", 0.012, ti.size, [
        ("AxisPos A3", "Grad", qc), ("AxisPos A1", "Grad", 0.1 * ti)], start=0.048)
    write_module(tmp_path, "REC_Temp", 0.1, 61, [("Motortemperatur A3", "K", 304.15 + 0.0 * np.arange(61)),
                                                  ("Motortemperatur A1", "K", 300.15 + 0.0 * np.arange(61))])
    log = read_trace(tmp_path / "REC_KRCIpo.dat")  # any module of the recording
    assert log.axes == (1, 3)
    # time base: the drive's 4 ms, cut to where every module has data
    assert np.allclose(np.diff(log.time), 0.004)
    assert log.time[0] == pytest.approx(0.048) and log.time[-1] <= ti[-1] + 1e-9
    k0 = int(round(0.048 / 0.004))
    np.testing.assert_array_equal(log.tau[:, 1], tau[k0:k0 + log.n_samples])
    np.testing.assert_allclose(log.q[:, 1], (q * math.pi / 180)[k0:k0 + log.n_samples], rtol=0, atol=1e-15)
    # the 12 ms setpoints are interpolated onto the 4 ms base: exact where instants coincide
    on_ipo = np.isin(np.round(log.time / 0.004).astype(int), np.round(ti / 0.004).astype(int))
    np.testing.assert_allclose(np.degrees(log.q_cmd[on_ipo, 1]), qc[:on_ipo.sum()], atol=1e-9)
    np.testing.assert_allclose(np.degrees(log.q_cmd[:, 0]), 0.1 * log.time, atol=1e-9)  # linear: exact
    np.testing.assert_allclose(log.temp[:, 1], 31.0, atol=1e-9)
    assert len(log.attrs["trace_files"]) == 3
    fine = read_trace(tmp_path / "REC_KRCIpo.dat", time_base="finest")  # the drive's 4 ms is the finest too
    np.testing.assert_array_equal(fine.time, log.time)
    # siblings=False reads one module only
    with pytest.raises(LogFormatError, match="no axis has both"):
        read_trace(tmp_path / "REC_KRCIpo.dat", siblings=False)


def test_kukaid_load_converts_a_trace(tmp_path, kukaid_cmd):
    t = np.arange(100) * 0.012
    q, tau, _ = _signals(t)
    dat = write_module(tmp_path, "R_Drive", 0.012, t.size, [("Istposition A3", "Grad", q), ("Istmoment A3", "Nm", tau)])
    r = subprocess.run([*kukaid_cmd, "load", str(dat), "-o", str(tmp_path / "log.h5")], capture_output=True, text=True,
                       timeout=60)
    assert r.returncode == 0, r.stderr
    log = read_hdf5(tmp_path / "log.h5")
    np.testing.assert_allclose(np.degrees(log.q[:, 0]), q, atol=1e-12)
    assert read_log(dat).n_samples == 100


@pytest.mark.parametrize("edit, match", [
    ({"DIAEXTENDED  {@:ENGLISH": "HELLO"}, r"line 1: not a KUKA Trace/DIAdem header"),
    ({"200,Istmoment A3": "200,Istmoment A3\nthis is not a code line"}, r"line \d+: expected 'code,value'"),
    ({"214,REAL64\n215,INTEL\n220,50\n221,2": "214,REAL32\n215,INTEL\n220,50\n221,2"},
     r"channel 'Istmoment A3'.*REAL32.*not supported"),
    ({"220,50\n221,2": "220,5x0\n221,2"}, r"channel 'Istmoment A3'.*code 220 value '5x0' is not a number"),
    ({"202,Nm": "202,A"}, r"channel 'Istmoment A3'.*unit 'A' is not supported for tau"),
    ({"#ENDGLOBALHEADER": ""}, r"line \d+: #BEGINCHANNELHEADER inside the section opened at line 3"),
    ({"211,M_Drive.r64\n213,BLOCK\n214,REAL64\n215,INTEL\n220,50\n221,2":
      "211,other.r64\n213,BLOCK\n214,REAL64\n215,INTEL\n220,50\n221,2"}, r"channel 'Istmoment A3'.*'other.r64' not found"),
])
def test_malformed_headers_name_line_or_channel(tmp_path, edit, match):
    t = np.arange(50) * 0.012
    q, tau, _ = _signals(t)
    dat = write_module(tmp_path, "M_Drive", 0.012, t.size, [("Istposition A3", "Grad", q), ("Istmoment A3", "Nm", tau)],
                       extra_lines=edit)
    with pytest.raises(LogFormatError, match=match):
        read_trace(dat)


def test_wrong_data_file_size_names_file_and_channel(tmp_path, kukaid_cmd):
    t = np.arange(50) * 0.012
    q, tau, _ = _signals(t)
    dat = write_module(tmp_path, "W_Drive", 0.012, t.size, [("Istposition A3", "Grad", q), ("Istmoment A3", "Nm", tau)])
    r64 = tmp_path / "W_Drive.r64"
    r64.write_bytes(r64.read_bytes()[:-8])
    with pytest.raises(LogFormatError, match=r"W_Drive.r64: 792 bytes, but channel 'Istposition A3'.*50 values x 2 "
                                             r"columns x 8 bytes = 800 bytes"):
        read_trace(dat)
    r = subprocess.run([*kukaid_cmd, "load", str(dat), "-o", str(tmp_path / "x.h5")], capture_output=True, text=True,
                       timeout=60)
    assert r.returncode != 0 and r.stderr.startswith("kukaid: error: ") and "Traceback" not in r.stderr
    assert not (tmp_path / "x.h5").exists()


def test_nan_in_data_and_no_overlap(tmp_path):
    t = np.arange(50) * 0.012
    q, tau, _ = _signals(t)
    tau = tau.copy()
    tau[7] = np.nan
    dat = write_module(tmp_path, "N_Drive", 0.012, t.size, [("Istposition A3", "Grad", q), ("Istmoment A3", "Nm", tau)])
    with pytest.raises(LogFormatError, match="channel 'Istmoment A3': value 8 is not a finite number"):
        read_trace(dat)
    write_module(tmp_path, "O_Drive", 0.012, 50, [("Istposition A3", "Grad", q)])
    write_module(tmp_path, "O_Other", 0.012, 50, [("Istmoment A3", "Nm", q)], start=10.0)
    with pytest.raises(LogFormatError, match="do not overlap"):
        read_trace(tmp_path / "O_Drive.dat")


# -- a recording as a KR C4 writes it: six NextGenDrive#N modules + KRCIpo ---------------------
RATIOS = ",".join(f"A{a}={r:g}" for a, r in GEAR.items())


@pytest.mark.parametrize("given", ["Rec_NextGenDrive#4.dat", "Rec_KRCIpo.r64", "Rec_NextGenDrive#1.r64"])
def test_kr_c4_set_loads_every_axis_exactly(tmp_path, given):
    ts = write_kr_c4_set(tmp_path)
    log = read_trace(tmp_path / given, gear_ratio=RATIOS)
    assert log.axes == (1, 2, 3, 4, 5, 6) and log.joint == ("revolute",) * 6
    assert len(log.attrs["trace_files"]) == 7
    # time base: the drives' 1 ms instants where the 12 ms setpoints also have data
    k0, k1 = int(round(ts.t_ipo[0] / 0.001)), int(round(ts.t_ipo[-1] / 0.001))
    np.testing.assert_allclose(log.time, ts.t_drive[k0:k1 + 1], rtol=0, atol=1e-12)
    rows = slice(k0, k1 + 1)
    for c, a in enumerate(log.axes):
        r = GEAR[a]
        # exact: the file's raw * factor + offset, degrees -> rad, motor -> joint (q / r, tau * r)
        np.testing.assert_array_equal(log.q[:, c], ts.value("Istposition", a)[rows] * DEG / r)
        np.testing.assert_array_equal(log.tau[:, c], ts.value("Istmoment", a)[rows] * r)
        np.testing.assert_array_equal(log.temp[:, c], ts.value("Motortemperatur", a)[rows])
        # and it is the joint motion the set was made from (up to the raw numbers' rounding)
        half_step = {ch: 0.5 * ts.scale[(ch, a)][0] * (1 + 1e-9) for ch in ("Istposition", "Istmoment")}
        np.testing.assert_allclose(np.degrees(log.q[:, c]), ts.q_joint_deg[a][rows], rtol=0,
                                   atol=half_step["Istposition"] / abs(r))
        np.testing.assert_allclose(log.tau[:, c], ts.tau_joint[a][rows], rtol=0, atol=half_step["Istmoment"] * abs(r))
        # the 12 ms setpoints: as recorded at their own instants, linear in between
        on = np.isin(np.round(log.time / 0.001).astype(int), np.round(ts.t_ipo / 0.001).astype(int))
        assert on.sum() == ts.t_ipo.size
        np.testing.assert_array_equal(log.q_cmd[on, c], ts.value("Sollposition", a) * DEG)
        np.testing.assert_allclose(log.q_cmd[:, c], np.interp(log.time, ts.t_ipo, ts.value("Sollposition", a) * DEG),
                                   rtol=0, atol=1e-15)
    assert log.attrs["time_base"] == "position"
    assert log.attrs["interpolated"] == [f"q_cmd A{a}" for a in range(1, 7)]
    assert "Istposition (A1, Rec_NextGenDrive#1), 1 ms" in log.attrs["time_base_note"]
    assert log.attrs["trace_sample_times"]["Rec_KRCIpo"] == pytest.approx(0.012)
    assert log.attrs["gear_ratio"] == {f"A{a}": r for a, r in GEAR.items()}
    assert log.attrs["trace_channels"]["tau A5"] == "Istmoment (Rec_NextGenDrive#5.dat)"


def test_kr_c4_set_on_the_common_grid_is_not_interpolated(tmp_path):
    ts = write_kr_c4_set(tmp_path)
    log = read_trace(tmp_path / "Rec_KRCIpo.dat", gear_ratio={a: r for a, r in GEAR.items()}, time_base="common")
    np.testing.assert_allclose(log.time, ts.t_ipo, rtol=0, atol=1e-12)
    k = np.round(ts.t_ipo / 0.001).astype(int)
    for c, a in enumerate(log.axes):
        np.testing.assert_array_equal(log.q[:, c], ts.value("Istposition", a)[k] * DEG / GEAR[a])
        np.testing.assert_array_equal(log.q_cmd[:, c], ts.value("Sollposition", a) * DEG)
    assert log.attrs["interpolated"] == [] and "no interpolation" in log.attrs["time_base_note"]


def test_kr_c4_set_without_gear_ratios_says_the_positions_are_motor_side(tmp_path):
    write_kr_c4_set(tmp_path)
    with pytest.raises(LogFormatError, match=r"Rec_NextGenDrive#1.dat: line \d+: channel 'Istposition': reaches "
                                             r"[\d.]+ degrees.*motor-side position; give the gear ratios"):
        read_trace(tmp_path / "Rec_KRCIpo.dat")
    with pytest.raises(LogFormatError, match=r"channel 'Istposition'.*no gear ratio for A3 \(given for A1, A2\)"):
        read_trace(tmp_path / "Rec_KRCIpo.dat", gear_ratio="A1=2,A2=3")


def test_a_trace_without_gear_ratios_given_to_fit_names_kukaid_load(tmp_path):
    """New-user trial 16: `kukaid fit Rec_NextGenDrive#3.dat --axis 3` said `give the gear ratios
    (--gear-ratio A1=...,A2=... or a JSON file)`, an option fit does not have (`No such option`):
    kukaid load has it, and is named with the file."""
    from click.testing import CliRunner

    from kukaid_cli.main import cli

    write_kr_c4_set(tmp_path, duration=0.1)
    dat = tmp_path / "Rec_NextGenDrive#3.dat"
    r = CliRunner().invoke(cli, ["fit", str(dat), "--axis", "3", "-o", str(tmp_path / "p.json")])
    assert r.exit_code == 1 and len(r.stderr.strip().splitlines()) == 1, r.output
    assert f"give the gear ratios, kukaid load {dat} --gear-ratio A1=...,A2=... (or a JSON file) -o LOG.h5" in r.stderr
    assert not (tmp_path / "p.json").exists()


@pytest.mark.parametrize("spec, match", [("A1=0", "gear ratio of A1 must be finite and non-zero"),
                                         ("A1:3", "'A1:3' is not AXIS=RATIO"), ("A13=2", "'A13' is not an axis"),
                                         ("A1=x", "gear ratio of A1 is not a number")])
def test_bad_gear_ratios(tmp_path, spec, match):
    write_kr_c4_set(tmp_path, duration=0.1)
    with pytest.raises(LogFormatError, match=match):
        read_trace(tmp_path / "Rec_KRCIpo.dat", gear_ratio=spec)


def test_kukaid_load_reads_the_set_with_a_gear_ratio_file(tmp_path, kukaid_cmd):
    ts = write_kr_c4_set(tmp_path, duration=0.5)
    ratios = tmp_path / "gear.json"
    ratios.write_text(json.dumps({f"A{a}": r for a, r in GEAR.items()}))
    out = tmp_path / "rec.h5"
    r = subprocess.run([*kukaid_cmd, "load", str(tmp_path / "Rec_NextGenDrive#3.dat"), "--gear-ratio", str(ratios),
                        "-o", str(out)], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    assert "time base: the sample instants of Istposition (A1, Rec_NextGenDrive#1), 1 ms" in r.stdout
    assert "linearly interpolated onto it: q_cmd A1" in r.stdout and "gear ratios A1=-161" in r.stdout
    log = read_hdf5(out)
    assert log.axes == (1, 2, 3, 4, 5, 6) and log.attrs["time_base"] == "position"
    k0 = int(round(ts.t_ipo[0] / 0.001))
    np.testing.assert_array_equal(log.tau[:, 2], ts.value("Istmoment", 3)[k0:k0 + log.n_samples] * GEAR[3])
    r = subprocess.run([*kukaid_cmd, "load", str(tmp_path / "Rec_KRCIpo.dat"), "--gear-ratio", RATIOS,
                        "--time-base", "common", "-o", str(tmp_path / "c.h5")], capture_output=True, text=True,
                       timeout=60)
    assert r.returncode == 0, r.stderr
    assert read_hdf5(tmp_path / "c.h5").n_samples == ts.t_ipo.size
    r = subprocess.run([*kukaid_cmd, "load", str(tmp_path / "Rec_KRCIpo.dat"), "-o", str(tmp_path / "m.h5")],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode != 0 and r.stderr.startswith("kukaid: error: ") and "--gear-ratio" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and not (tmp_path / "m.h5").exists()


def test_kukaid_load_json_of_a_trace_is_json_alone(tmp_path):
    """New-user trial 17: `kukaid load Rec_NextGenDrive#1.dat --gear-ratio ... --json` printed the
    'time base: ...' line on stdout before the JSON, so `| python -m json.tool` failed; the note is
    now in the JSON (and on stderr)."""
    from click.testing import CliRunner

    from kukaid_cli.main import cli

    write_kr_c4_set(tmp_path, duration=0.2)
    r = CliRunner().invoke(cli, ["load", str(tmp_path / "Rec_NextGenDrive#1.dat"), "--gear-ratio", RATIOS, "--json",
                                 "-o", str(tmp_path / "rec.h5")])
    assert r.exit_code == 0, r.output
    got = json.loads(r.stdout)
    assert got["time_base_note"].startswith("time base: the sample instants of Istposition")
    assert "time base: " in r.stderr


def _drop_channel(dat, channel: str) -> None:
    """Remove one channel's header from a module's .dat (the recording then lacks that channel)."""
    text = dat.read_text(encoding="latin-1")
    blocks = text.split("#BEGINCHANNELHEADER")
    dat.write_text("#BEGINCHANNELHEADER".join(b for b in blocks if f"200,{channel}\n" not in b), encoding="latin-1")


def test_a_trace_set_missing_a_channel_says_what_the_log_left_out(tmp_path):
    """New-user trial 19: a KR C4 recording whose A3 drive had no torque channel loaded as a log of
    A1, A2, A4, A5, A6 without a word (A3 gone; `--json` "warnings": []), and one drive without its
    motor temperature dropped every axis's temperature, again silently (a fleet's wear watch then
    has no temperature model).  Each is a warning line, in the JSON's warnings too."""
    from click.testing import CliRunner

    from kukaid_cli.main import cli

    write_kr_c4_set(tmp_path, duration=0.2)
    _drop_channel(tmp_path / "Rec_NextGenDrive#3.dat", "Istmoment")
    _drop_channel(tmp_path / "Rec_NextGenDrive#5.dat", "Motortemperatur")
    r = CliRunner().invoke(cli, ["load", str(tmp_path / "Rec_NextGenDrive#1.dat"), "--gear-ratio", RATIOS, "--json",
                                 "-o", str(tmp_path / "rec.h5")])
    assert r.exit_code == 0, r.output
    got = json.loads(r.stdout)
    dat = tmp_path / "Rec_NextGenDrive#1.dat"
    assert got["axes"] == [1, 2, 4, 5, 6]
    assert got["warnings"] == [
        f"{dat}: A3 is not in the log: the recording has its measured position (Istposition) but no torque "
        "(Istmoment) channel",
        f"{dat}: no motor temperature (Motortemperatur) in the log, for any axis: the recording has none for A5"]
    for w in got["warnings"]:
        assert f"kukaid: warning: load: {w}" in r.stderr
    # new-user trial 22: a drive module not copied with the others (its .dat and .r64 gone) left its axis out
    # without a word, though the KRCIpo module has its setpoints
    (tmp_path / "gone").mkdir()
    write_kr_c4_set(tmp_path / "gone", duration=0.2)
    for f in (tmp_path / "gone").glob("Rec_NextGenDrive#4.*"):
        f.unlink()
    dat = tmp_path / "gone" / "Rec_NextGenDrive#1.dat"
    r = CliRunner().invoke(cli, ["load", str(dat), "--gear-ratio", RATIOS, "--json", "-o", str(tmp_path / "gone.h5")])
    assert r.exit_code == 0, r.output
    got = json.loads(r.stdout)
    assert got["axes"] == [1, 2, 3, 5, 6]
    assert got["warnings"] == [
        f"{dat}: A4 is not in the log: the recording has its commanded position (KRCIpo setpoint) but no measured "
        "position (Istposition) and no torque (Istmoment) channel (its drive module, NextGenDrive#4, missing?)"]
    assert f"kukaid: warning: load: {got['warnings'][0]}" in r.stderr
    (tmp_path / "whole").mkdir()
    write_kr_c4_set(tmp_path / "whole", duration=0.2)  # a whole recording: nothing to say
    r = CliRunner().invoke(cli, ["load", str(tmp_path / "whole" / "Rec_NextGenDrive#1.dat"), "--gear-ratio", RATIOS,
                                 "--json", "-o", str(tmp_path / "whole.h5")])
    assert r.exit_code == 0 and json.loads(r.stdout)["warnings"] == [] and "warning" not in r.stderr
