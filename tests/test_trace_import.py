"""KUKA Trace (.dat/.r64) import from files written here from known signals; malformed cases."""
from __future__ import annotations

import math
import subprocess
from pathlib import Path

import numpy as np
import pytest

from kukaid.errors import LogFormatError
from kukaid.logs import read_hdf5, read_log
from kukaid.logs import read_trace


def write_module(folder: Path, stem: str, step: float, n: int, channels: list[tuple[str, str, np.ndarray]],
                 start: float = 0.0, r64_name: str | None = None, extra_lines: dict | None = None) -> Path:
    """Write one Trace module: STEM.dat (DIAdem header) + STEM.r64 (interleaved float64)."""
    r64 = r64_name or f"{stem}.r64"
    lines = ["DIAEXTENDED  {@:ENGLISH", "", "#BEGINGLOBALHEADER", "1,WINDOWS 32Bit", "101,KRC-Trace",
             "104,11.22.2026", "#ENDGLOBALHEADER",
             "#BEGINCHANNELHEADER", "200,Zeit", "202,s", "210,IMPLIZIT", "213,BLOCK", "214,REAL64",
             f"220,{n}", f"240,{start!r}", f"241,{step!r}", "#ENDCHANNELHEADER"]
    for j, (name, unit, _) in enumerate(channels, start=1):
        lines += ["#BEGINCHANNELHEADER", f"200,{name}", "201,", f"202,{unit}", "210,EXPLIZIT", f"211,{r64}",
                  "213,BLOCK", "214,REAL64", "215,INTEL", f"220,{n}", f"221,{j}", "240,0.0", "241,1.0",
                  "#ENDCHANNELHEADER"]
    text = "\n".join(lines) + "\n"
    for k, v in (extra_lines or {}).items():
        text = text.replace(k, v)
    (folder / f"{stem}.dat").write_bytes(text.encode("latin-1"))
    np.column_stack([c[2] for c in channels]).astype("<f8").tofile(folder / r64)
    return folder / f"{stem}.dat"


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
