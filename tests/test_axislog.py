"""Axis logs: HDF5 and CSV round trips, validation, incremental writing, malformed input."""
from __future__ import annotations

import re
import subprocess
import sys
import textwrap

import h5py
import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st

from kukaid.errors import KukaidError, LogFormatError
from kukaid.logs import AxisLog, AxisLogWriter, read_csv, read_hdf5, read_log, write_csv, write_hdf5
from kukaid_cli.main import cli


def make_log(n: int = 50, axes=(3,), seed: int = 0, extras: bool = True) -> AxisLog:
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.012
    a = len(axes)
    kw = {}
    if extras:
        kw = dict(q_cmd=rng.normal(size=(n, a)), temp=30 + rng.random((n, a)), tau_ext_true=rng.normal(size=(n, a)))
    return AxisLog(time=t, q=rng.normal(size=(n, a)), tau=10 * rng.normal(size=(n, a)), axes=axes,
                   attrs={"seed": seed, "experiment": "friction", "trajectory": {"speeds": [0.1, 0.2]}}, **kw)


def test_hdf5_round_trip_keeps_everything(tmp_path):
    log = make_log(axes=(2, 3))
    write_hdf5(log, tmp_path / "a.h5")
    back = read_hdf5(tmp_path / "a.h5")
    for name in ("time", "q", "tau", "q_cmd", "temp", "tau_ext_true"):
        assert np.array_equal(getattr(back, name), getattr(log, name)), name
    assert back.axes == (2, 3)
    assert back.attrs["trajectory"] == {"speeds": [0.1, 0.2]}
    assert back.attrs["seed"] == 0
    with h5py.File(tmp_path / "a.h5") as f:
        assert list(f.attrs["axes"]) == [2, 3]
        assert "rad" in f.attrs["units"]


@settings(max_examples=25, deadline=None)
@given(st.lists(st.floats(-720, 720, allow_nan=False, width=64).filter(lambda x: x == 0 or abs(x) > 1e-290),
                min_size=2, max_size=40))
def test_csv_hdf5_csv_round_trip_keeps_every_value(tmp_path_factory, values):
    d = tmp_path_factory.mktemp("rt")
    n = len(values)
    v = np.asarray(values)
    # a CSV as the KRC gives it: degrees (up to the plausible +-720) and N·m
    lines = ["time_s,A3_deg,A3_Nm,A3_cmd_deg,A3_temp_C"]
    for i in range(n):
        lines.append(f"{i * 0.012!r},{float(v[i])!r},{float(-v[i])!r},{float(v[i] / 3)!r},{40.0 + i!r}")
    (d / "in.csv").write_text("\n".join(lines) + "\n")
    runner = CliRunner()
    r = runner.invoke(cli, ["load", str(d / "in.csv"), "-o", str(d / "log.h5")])
    assert r.exit_code == 0, r.output
    r = runner.invoke(cli, ["load", str(d / "log.h5"), "-o", str(d / "out.csv")])
    assert r.exit_code == 0, r.output
    a = np.loadtxt(d / "in.csv", delimiter=",", skiprows=1, ndmin=2)
    b = np.loadtxt(d / "out.csv", delimiter=",", skiprows=1, ndmin=2)
    assert (d / "out.csv").read_text().splitlines()[0] == lines[0]
    # degrees -> rad -> degrees keeps every value to within one unit in the last place (subnormal
    # magnitudes, below 1e-290, are excluded: their conversion to radians underflows)
    np.testing.assert_allclose(b, a, rtol=4e-16, atol=0)
    assert np.array_equal(b[:, [0, 2, 4]], a[:, [0, 2, 4]])


def test_csv_radians_and_prismatic(tmp_path):
    (tmp_path / "p.csv").write_text("time_s,A1_m,A1_N\n0,0.1,5\n0.001,0.2,6\n")
    log = read_csv(tmp_path / "p.csv")
    assert log.joint == ("prismatic",)
    assert np.allclose(log.q[:, 0], [0.1, 0.2])
    write_csv(log, tmp_path / "p2.csv")
    assert (tmp_path / "p2.csv").read_text().splitlines()[0] == "time_s,A1_m,A1_N"


def test_csv_with_every_field_in_quotes_is_read(tmp_path):
    """New-user trial 22: a CSV quoting every field (csv.QUOTE_ALL, many loggers) was refused at its header,
    "first column must be 'time_s', found '"time_s"'", though numbers in quotes are read."""
    (tmp_path / "q.csv").write_text('"time_s","A3_deg","A3_Nm"\n"0","1.5","2"\n"0.012","2","3"\n')
    log = read_csv(tmp_path / "q.csv")
    assert np.allclose(np.degrees(log.q[:, 0]), [1.5, 2.0]) and np.allclose(log.tau[:, 0], [2.0, 3.0])


def test_csv_numbers_in_quotes_lines_of_spaces_and_windows_line_ends_are_read(tmp_path):
    (tmp_path / "q.csv").write_bytes(b'\xef\xbb\xbftime_s,A3_deg,A3_Nm\r\n0,"1.5",2\r\n   \r\n0.012, 2 ,3\r\n')
    log = read_csv(tmp_path / "q.csv")
    assert np.allclose(np.degrees(log.q[:, 0]), [1.5, 2.0]) and np.allclose(log.tau[:, 0], [2.0, 3.0])


BAD_CSV = {
    "missing_column": ("time_s,A3_deg\n0,1\n0.012,2\n", "missing column A3_Nm"),
    # new-user trial 15: a log in radians without A4's position named 'A4_deg', a column no other axis has
    "missing_position_in_radians": ("time_s,A3_rad,A3_Nm,A4_Nm\n0,1,2,3\n0.012,2,3,4\n",
                                    "missing column A4_rad (axis A4 has no 'q')"),
    "missing_prismatic_force": ("time_s,A1_m,A1_N,A2_m\n0,1,2,3\n0.012,2,3,4\n", "missing column A2_N (axis"),
    "unknown_unit": ("time_s,A3_grad,A3_Nm\n0,1,2\n0.012,2,3\n", "unknown column 'A3_grad'"),
    "nan": ("time_s,A3_deg,A3_Nm\n0,1,2\n0.012,nan,3\n", "not a finite number (NaN or inf) at line 3"),
    "duplicated_time": ("time_s,A3_deg,A3_Nm\n0,1,2\n0,2,3\n", "duplicated) at line 3"),
    "decreasing_time": ("time_s,A3_deg,A3_Nm\n0,1,2\n0.02,2,3\n0.01,2,3\n", "decreasing) at line 4"),
    # new-user trial 22: the line read again for the NaN: its numbers in quotes are numbers, the NaN is
    # named (it said line 2: '"0"' is not a number)
    "nan_among_numbers_in_quotes": ('time_s,A3_deg,A3_Nm\n"0","1","2"\n0.012,nan,3\n', "(NaN or inf) at line 3"),
    # new-user trial 22: a blank line above shifted the line named by one
    "nan_after_blank_line": ("time_s,A3_deg,A3_Nm\n0,1,2\n\n0.012,nan,3\n", "(NaN or inf) at line 4"),
    "duplicated_time_after_blank_lines": ("time_s,A3_deg,A3_Nm\n0,1,2\n\n\r\n0.012,2,3\n0.012,2,3\n",
                                          "duplicated) at line 6"),
    # new-user trial 22: numbers in quotes with ',' as the decimal mark were "line 2 has 6 fields, the header has 3"
    "comma_decimals_in_quotes": ('time_s,A3_deg,A3_Nm\n"0,000","1,5","2,0"\n"0,012","1,6","2,1"\n',
                                 "line 2: '0,000' is not a number (',' as the decimal mark: kukaid reads '.'"),
    "empty": ("", "empty file"),
    "header_only": ("time_s,A3_deg,A3_Nm\n", "no data rows"),
    "ragged": ("time_s,A3_deg,A3_Nm\n0,1,2\n0.012,2\n", "line 3 has 2 fields"),
    "long_row": ("time_s,A3_deg,A3_Nm\n0,1,2\n0.012,2,3,4\n0.024,2,3\n", "line 3 has 4 fields"),
    "empty_field": ("time_s,A3_deg,A3_Nm\n0,1,2\n0.012,,3\n", "line 3: '' is not a number"),
    "text": ("time_s,A3_deg,A3_Nm\n0,1,2\n0.012,abc,3\n", "line 3: 'abc' is not a number"),
    "no_time": ("t,A3_deg,A3_Nm\n0,1,2\n", "first column must be 'time_s'"),
    "mixed_units": ("time_s,A3_deg,A3_N\n0,1,2\n0.1,1,2\n", "mixes revolute and prismatic"),
}


# new-user trial 22: a file that is not UTF-8 text had its header printed in the error, NUL bytes and all
BAD_CSV_BYTES = {
    "utf16": ("time_s,A3_deg,A3_Nm\n0,1,2\n0.012,2,3\n".encode("utf-16"), "is UTF-16 text"),
    "xlsx": (b"PK\x03\x04\x14\x00\x06\x00" + bytes(64), "is a binary file (a ZIP archive: an Excel workbook"),
    # a log cut short by a power cut: its end is NUL bytes (it said "line 4 has 1 fields, the header has 3")
    "nul_tail": (b"time_s,A3_deg,A3_Nm\n0,1,2\n0.012,2,3\n" + bytes(5000),
                 "line 4 holds NUL bytes, not text: the file was cut short while written (a crash, a power cut?); "
                 "the 2 lines of data above it can be kept by removing line 4 and after"),
    "binary": (b"\x89\x00\x01garbage\x00" * 8, "is a binary file, not CSV text"),
}


@pytest.mark.parametrize("case", sorted(BAD_CSV) + sorted(BAD_CSV_BYTES))
def test_malformed_csv_gives_one_line_and_no_output(tmp_path, case):
    text, msg = BAD_CSV[case] if case in BAD_CSV else BAD_CSV_BYTES[case]
    src = tmp_path / "bad.csv"
    src.write_bytes(text) if isinstance(text, bytes) else src.write_text(text)
    out = tmp_path / "out.h5"
    r = CliRunner().invoke(cli, ["load", str(src), "-o", str(out)])
    assert r.exit_code != 0
    err = r.stderr if hasattr(r, "stderr") else r.output
    assert msg in err, err
    assert err.startswith("kukaid: error: ") and str(src) in err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err and "\x00" not in err
    assert not out.exists() and list(tmp_path.iterdir()) == [src]


def test_truncated_hdf5(tmp_path):
    write_hdf5(make_log(n=5000), tmp_path / "a.h5")
    data = (tmp_path / "a.h5").read_bytes()
    (tmp_path / "cut.h5").write_bytes(data[: len(data) // 3])
    with pytest.raises(LogFormatError, match="cut.h5: .*(truncated|corrupt)"):
        read_hdf5(tmp_path / "cut.h5")
    r = CliRunner().invoke(cli, ["load", str(tmp_path / "cut.h5"), "-o", str(tmp_path / "o.csv")])
    assert r.exit_code == 1 and "truncated" in r.output and not (tmp_path / "o.csv").exists()


def test_hdf5_missing_dataset_nan_and_wrong_unit(tmp_path):
    write_hdf5(make_log(), tmp_path / "a.h5")
    with h5py.File(tmp_path / "a.h5", "a") as f:
        del f["tau"]
    with pytest.raises(LogFormatError, match="missing dataset 'tau'"):
        read_hdf5(tmp_path / "a.h5")
    write_hdf5(make_log(), tmp_path / "b.h5")
    with h5py.File(tmp_path / "b.h5", "a") as f:
        f["q"][7, 0] = np.nan
    with pytest.raises(LogFormatError, match="channel 'q' of axis A3 .* row 7"):
        read_hdf5(tmp_path / "b.h5")
    write_hdf5(make_log(), tmp_path / "c.h5")
    with h5py.File(tmp_path / "c.h5", "a") as f:
        f.attrs["units"] = '{"time": "ms"}'
    with pytest.raises(LogFormatError, match="time unit is 'ms'"):
        read_hdf5(tmp_path / "c.h5")
    (tmp_path / "e.h5").write_bytes(b"")
    with pytest.raises(LogFormatError, match="empty file"):
        read_hdf5(tmp_path / "e.h5")


def test_unknown_extension(tmp_path):
    (tmp_path / "x.txt").write_text("hi")
    with pytest.raises(LogFormatError, match="unknown log format '.txt'"):
        read_log(tmp_path / "x.txt")
    # new-user trial 17: kukaid fleet's table given as a log said only "unknown log format '.parquet'"
    (tmp_path / "t.parquet").write_bytes(b"PAR1" + bytes(16) + b"PAR1")
    with pytest.raises(LogFormatError, match=r"t\.parquet: is a Parquet table \(kukaid fleet\), not an axis log"):
        read_log(tmp_path / "t.parquet")


def test_one_table_names_each_suffix_format_and_reader():
    """Code review: kukaid.logs kept two tables keyed by the same suffixes (READERS, FORMATS), which could
    drift apart; now one holds both, the format's name beside its reader."""
    import kukaid.logs as logs

    assert not hasattr(logs, "FORMATS")
    assert {s: fmt for s, (fmt, _) in logs.READERS.items()} == {
        ".h5": "HDF5", ".hdf5": "HDF5", ".csv": "CSV", ".mat": "MAT", ".dat": "KUKA Trace", ".r64": "KUKA Trace"}
    assert all(callable(reader) for _, reader in logs.READERS.values())


def test_a_file_named_h5_of_another_kind_is_looked_at_once(tmp_path, monkeypatch):
    """Code review: a report renamed .h5 had its first bytes read twice on the error path (by the HDF5
    reader, then again by read_log); once now, and still named as what it is."""
    import kukaid.logs.core as core

    calls = []
    real = core.file_kind
    monkeypatch.setattr(core, "file_kind", lambda p: calls.append(p) or real(p))
    (tmp_path / "r.h5").write_bytes(b"%PDF-1.4\n" + bytes(range(256)))
    with pytest.raises(LogFormatError, match=r"r\.h5: is a PDF \(a report\), not an HDF5 axis log"):
        read_log(tmp_path / "r.h5")
    assert len(calls) == 1


def test_writer_survives_sigkill(tmp_path):
    path = tmp_path / "live.h5"
    code = textwrap.dedent(f"""
        import numpy as np, os, sys
        from kukaid.logs import AxisLogWriter
        w = AxisLogWriter({str(path)!r}, axes=(3,), attrs={{"experiment": "x"}}, flush_every=10)
        n = 0
        while True:
            t = (n + np.arange(10)) * 0.012
            w.append(t, q=t[:, None], tau=2 * t[:, None])
            n += 10
            if n == 500:
                print("ready", flush=True)
    """)
    p = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    assert p.stdout.readline().strip() == "ready"
    p.kill()
    p.wait()
    log = read_hdf5(path)
    assert log.n_samples >= 500
    assert np.allclose(log.tau, 2 * log.q) and np.allclose(log.q[:, 0], log.time)


def test_writer_rejects_non_increasing_time(tmp_path):
    with AxisLogWriter(tmp_path / "w.h5", axes=(3,)) as w:
        w.append([0.0, 0.1], q=np.zeros((2, 1)), tau=np.zeros((2, 1)))
        with pytest.raises(ValueError):
            w.append([0.1], q=np.zeros((1, 1)), tau=np.zeros((1, 1)))
    assert read_hdf5(tmp_path / "w.h5").n_samples == 2


def test_axislog_accessors():
    log = make_log(axes=(3, 6))
    assert log.index(6) == 1
    assert np.array_equal(log.channel("tau", 3), log.tau[:, 0])
    with pytest.raises(LogFormatError, match="axis A1 is not in the log"):
        log.index(1)
    part = log.select(slice(10, 20))
    assert part.n_samples == 10 and part.q_cmd.shape == (10, 2)
    assert log.sample_time == pytest.approx(0.012)


def test_cli_version_and_help():
    r = CliRunner().invoke(cli, ["--version"])
    assert r.exit_code == 0 and "0.1.0" in r.output
    out = subprocess.run([sys.executable, "-c",
                          "import sys, kukaid_cli.main as m; m.main()", "--help"],
                         capture_output=True, text=True)
    assert out.returncode == 0 and "load" in out.stdout
    # heavy libraries are not imported to answer --help
    probe = subprocess.run([sys.executable, "-c",
                            "import sys; sys.argv=['kukaid','--help'];\n"
                            "import kukaid_cli.main as m\n"
                            "try:\n m.main()\nexcept SystemExit: pass\n"
                            "print(sorted(x for x in ('numpy','scipy','casadi','h5py','matplotlib','pandas') if x in sys.modules))"],
                           capture_output=True, text=True)
    assert probe.stdout.strip().splitlines()[-1] == "[]"


def test_killed_writer_with_uneven_datasets_keeps_common_rows(tmp_path):
    """SWMR flushes datasets in any order: a kill can leave 'time' ahead of a channel."""
    w = AxisLogWriter(tmp_path / "k.h5", axes=(3,))
    t = np.arange(20) * 0.012
    w.append(t, q=t[:, None], tau=t[:, None])
    w.close()
    with h5py.File(tmp_path / "k.h5", "a") as f:
        f["tau"].resize((15, 1))
    log = read_hdf5(tmp_path / "k.h5")
    assert log.n_samples == 15 and np.array_equal(log.tau[:, 0], t[:15])
    # a file written whole (not incremental) with uneven datasets is corrupt, and says so
    write_hdf5(log, tmp_path / "whole.h5")
    with h5py.File(tmp_path / "whole.h5", "a") as f:
        del f["tau"]
        f["tau"] = np.zeros((10, 1))
    with pytest.raises(LogFormatError, match="dataset 'tau' has 10 rows but 'time' has 15"):
        read_hdf5(tmp_path / "whole.h5")


# -- audit: malformed HDF5 attributes, implausible units, `kukaid load` outputs, unwritable folders --
def _one_line_error(r, *names):
    """A CLI failure: non-zero exit, one line `kukaid: error: ...` naming ``names``, no traceback."""
    err = r.stderr if hasattr(r, "stderr") else r.output
    assert r.exit_code != 0, err
    assert err.startswith("kukaid: error: ") and len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    for n in names:
        assert str(n) in err, (n, err)
    return err


def _edited_h5(tmp_path, edit, name="a.h5", log=None):
    path = tmp_path / name
    write_hdf5(log or make_log(), path)
    with h5py.File(path, "a") as f:
        edit(f)
    return path


@pytest.mark.parametrize("key, text", [("trajectory", '{"speeds": [0.1, 0.2'), ("truth", "not json"),
                                       ("_json_attrs", "[trajectory")])
def test_hdf5_invalid_json_attribute_names_file_and_attribute(tmp_path, key, text):
    path = _edited_h5(tmp_path, lambda f: f.attrs.__setitem__(key, text))
    if key == "truth":  # a simulated log's truth, listed as JSON
        with h5py.File(path, "a") as f:
            f.attrs["_json_attrs"] = '["trajectory", "units", "joint", "truth"]'
    with pytest.raises(LogFormatError, match=rf"a.h5: attribute '{key}' is not valid JSON"):
        read_hdf5(path)
    out = tmp_path / "o.csv"
    _one_line_error(CliRunner().invoke(cli, ["load", str(path), "-o", str(out)]), path, f"attribute '{key}'")
    assert not out.exists()


def test_hdf5_wrong_format_marker(tmp_path):
    path = _edited_h5(tmp_path, lambda f: f.attrs.__setitem__("format", "someone.else/3"))
    with pytest.raises(LogFormatError, match=r"a.h5: attribute 'format' is 'someone.else/3', expected 'kukaid.axislog/1'"):
        read_hdf5(path)
    with h5py.File(tmp_path / "a.h5", "a") as f:  # what the writer sets is accepted, as text or bytes
        f.attrs["format"] = np.bytes_(b"kukaid.axislog/1")
    assert read_hdf5(path).n_samples == 50


@pytest.mark.parametrize("value", [-0.012, 0.0, np.nan, np.inf, "12 ms"])
def test_hdf5_bad_sample_time(tmp_path, value):
    path = _edited_h5(tmp_path, lambda f: f.attrs.__setitem__("sample_time", value))
    with pytest.raises(LogFormatError, match=r"a.h5: attribute 'sample_time' is"):
        read_hdf5(path)


def test_hdf5_axes_attribute_against_columns(tmp_path):
    path = _edited_h5(tmp_path, lambda f: f.attrs.__setitem__("axes", [2, 3]))
    with pytest.raises(LogFormatError, match=r"attribute 'axes' lists 2 axes \[2, 3\] but dataset 'q' has 1 column$"):
        read_hdf5(path)
    path = _edited_h5(tmp_path, lambda f: f.attrs.__setitem__("joint", '["revolute"]'), name="b.h5",
                      log=make_log(axes=(2, 3)))
    with pytest.raises(LogFormatError, match=r"attribute 'joint' has 1 entry \['revolute'\] but attribute 'axes' lists 2"):
        read_hdf5(path)
    path = _edited_h5(tmp_path, lambda f: f.attrs.__setitem__("axes", "A3"), name="c.h5")
    with pytest.raises(LogFormatError, match=r"attribute 'axes' must list KUKA axis numbers"):
        read_hdf5(path)


UNIT_MISTAKES = {
    "millidegrees": ("time_s,A3_deg,A3_Nm\n0,45000,1\n0.012,44990,2\n0.024,44980,3\n",
                     "A3_deg reaches 45000 degrees; beyond +-720 degrees: wrong unit"),
    "degrees_as_rad": ("time_s,A3_rad,A3_Nm\n0,90,1\n0.012,91,2\n",
                       "A3_rad reaches 91 rad (5213.92 degrees); beyond +-720 degrees: wrong unit"),
    "command_millidegrees": ("time_s,A3_deg,A3_Nm,A3_cmd_deg\n0,45,1,-45000\n0.012,45,2,-45000\n",
                             "A3_cmd_deg reaches -45000 degrees"),
    "milliseconds": ("time_s,A3_deg,A3_Nm\n0,45,1\n12,45.1,2\n24,45.2,3\n",
                     "time_s has a median sample interval of 12 s; about 1 s or more: milliseconds written as seconds?"),
    # new-user trial 10: a 1 kHz drive log with its time in ms is exactly 1 "s" apart, and was taken
    # for a 1 Hz log (fit then asked for a cut-off below 0.45 Hz)
    "milliseconds_at_1kHz": ("time_s,A3_deg,A3_Nm\n0,45,1\n1,45.1,2\n2,45.2,3\n3,45.3,4\n",
                             "time_s has a median sample interval of 1 s; about 1 s or more: milliseconds written as "
                             "seconds?"),
    # new-user trial 22: a drive's clock a little off (EMPS: 0.99998 ms a sample), its time in ms, loaded as a 1 Hz
    # log of 24840 s
    "milliseconds_at_1kHz_clock_off": ("time_s,A3_deg,A3_Nm\n0,45,1\n0.99998,45.1,2\n1.99996,45.2,3\n2.99994,45.3,4\n",
                                       "time_s has a median sample interval of 0.99998 s; about 1 s or more: "
                                       "milliseconds written as seconds?"),
}


@pytest.mark.parametrize("case", sorted(UNIT_MISTAKES))
def test_csv_implausible_units_refused(tmp_path, case):
    text, msg = UNIT_MISTAKES[case]
    src = tmp_path / "log.csv"
    src.write_text(text)
    with pytest.raises(LogFormatError, match=re.escape(f"{src}: {msg}")):
        read_csv(src)
    out = tmp_path / "o.h5"
    _one_line_error(CliRunner().invoke(cli, ["load", str(src), "-o", str(out)]), src, msg)
    assert not out.exists()


def test_hdf5_implausible_units_refused(tmp_path):
    path = _edited_h5(tmp_path, lambda f: f["q"].write_direct(f["q"][()] * 1000))
    with pytest.raises(LogFormatError, match=r"a.h5: channel 'q' of axis A3 reaches .* rad \(.* degrees\); beyond "
                                             r"\+-720 degrees: wrong unit"):
        read_hdf5(path)
    path = _edited_h5(tmp_path, lambda f: f["time"].write_direct(f["time"][()] * 1000), name="ms.h5")
    with pytest.raises(LogFormatError, match=r"ms.h5: time has a median sample interval of 12 s"):
        read_hdf5(path)


def test_plausible_units_accepted():
    t = np.arange(100) * 0.012
    # two full turns either way of a revolute axis, a long prismatic track (m), 0.5 s samples (1 s is the
    # line: a 1 kHz log in milliseconds)
    AxisLog(time=t, q=np.linspace(-4 * np.pi, 4 * np.pi, t.size), tau=np.zeros(t.size), axes=(6,))
    AxisLog(time=t, q=np.linspace(0, 30.0, t.size), tau=np.zeros(t.size), axes=(7,), joint=("prismatic",))
    AxisLog(time=np.arange(10) * 0.5, q=np.zeros(10), tau=np.zeros(10), axes=(3,))
    with pytest.raises(LogFormatError, match=r"axis log: channel 'q' of axis A6 reaches 12.6 rad"):
        AxisLog(time=t, q=np.full(t.size, 12.6), tau=np.zeros(t.size), axes=(6,))


def test_load_output_suffix_checked_before_reading(tmp_path):
    src = tmp_path / "in.csv"
    src.write_text("time_s,A3_deg,A3_Nm\n0,1,2\n0.012,2,3\n")
    for name in ("out.txt", "out", "out.H5.bak"):
        r = CliRunner().invoke(cli, ["load", str(tmp_path / "missing.csv"), "-o", str(tmp_path / name)])
        _one_line_error(r, tmp_path / name, ".h5 or .hdf5 or .csv")
        assert not (tmp_path / name).exists()
    for name in ("out.HDF5", "out.csv"):  # the suffix decides the format, in any case
        r = CliRunner().invoke(cli, ["load", str(src), "-o", str(tmp_path / name)])
        assert r.exit_code == 0, r.output
    assert read_hdf5(tmp_path / "out.HDF5").n_samples == 2
    assert read_csv(tmp_path / "out.csv").n_samples == 2


def test_load_never_overwrites_input_or_existing_log(tmp_path, monkeypatch):
    src = tmp_path / "a.csv"
    src.write_text("time_s,A3_deg,A3_Nm\n0,1,2\n0.012,2,3\n")
    h5 = tmp_path / "a.h5"
    write_hdf5(make_log(), h5)
    before = {p: p.read_bytes() for p in (src, h5)}
    monkeypatch.chdir(tmp_path)
    for args in (["a.csv", "-o", "a.csv"], ["a.h5", "-o", str(h5)], ["a.h5", "-o", "./sub/../a.h5", "--force"]):
        _one_line_error(CliRunner().invoke(cli, ["load", *args]), "is also an input")
    (tmp_path / "link.h5").symlink_to(h5)
    _one_line_error(CliRunner().invoke(cli, ["load", "link.h5", "-o", "a.h5", "--force"]), "is also an input")
    # an existing log is replaced only with --force
    _one_line_error(CliRunner().invoke(cli, ["load", "a.csv", "-o", "a.h5"]), "a.h5: already exists", "--force")
    assert {p: p.read_bytes() for p in (src, h5)} == before
    r = CliRunner().invoke(cli, ["load", "a.csv", "-o", "a.h5", "--force"])
    assert r.exit_code == 0, r.output
    assert read_hdf5(h5).n_samples == 2 and src.read_bytes() == before[src]


def test_load_refuses_mat_options_for_other_sources(tmp_path):
    src = tmp_path / "a.csv"
    src.write_text("time_s,A3_deg,A3_Nm\n0,1,2\n0.012,2,3\n")
    r = CliRunner().invoke(cli, ["load", str(src), "--q-scale", "2", "-o", str(tmp_path / "o.h5")])
    _one_line_error(r, src, "option --q-scale is for MAT (.mat) sources")
    assert not (tmp_path / "o.h5").exists()


def _raise_oserror(errno_, *args, **kwargs):
    raise OSError(errno_, f"Unable to synchronously create file (unable to open file: name = 'x', errno = {errno_}, "
                          f"error message = 'Read-only file system', flags = 13, o_flags = 242)")


def test_writer_unwritable_path_is_one_line(tmp_path, monkeypatch):
    (tmp_path / "d.h5").mkdir()
    with pytest.raises(KukaidError, match=r"d.h5: cannot create: Is a directory$"):
        AxisLogWriter(tmp_path / "d.h5", axes=(3,))
    (tmp_path / "file").write_text("x")
    with pytest.raises(KukaidError, match=r"file/out.h5: cannot create: \S*file is not a folder$"):
        AxisLogWriter(tmp_path / "file" / "out.h5", axes=(3,))
    # a read-only file system (the tests may run as root, whom permissions do not stop: simulated)
    monkeypatch.setattr(h5py, "File", lambda *a, **k: _raise_oserror(30))
    with pytest.raises(KukaidError, match=r"^\S*out.h5: cannot create: Read-only file system$"):
        AxisLogWriter(tmp_path / "out.h5", axes=(3,))
    with pytest.raises(KukaidError, match=r"^\S*out.h5: cannot write: Read-only file system$"):
        write_hdf5(make_log(), tmp_path / "out.h5")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d.h5", "file"]


def test_write_csv_unwritable_folder_is_one_line(tmp_path, monkeypatch):
    import tempfile

    def refuse(*a, **k):
        raise OSError(30, "Read-only file system")

    monkeypatch.setattr(tempfile, "mkstemp", refuse)
    with pytest.raises(KukaidError, match=r"o.csv: cannot write: Read-only file system$"):
        write_csv(make_log(), tmp_path / "o.csv")


def test_an_hdf5_file_of_another_tool_is_named_as_such(tmp_path):
    """New-user trial 22: an HDF5 file written by another tool was told only "missing dataset 'time'"."""
    import h5py

    p = tmp_path / "other.h5"
    with h5py.File(p, "w") as f:
        f["t"] = np.arange(10.0)
        f["joint_pos"] = np.zeros((10, 6))
    with pytest.raises(LogFormatError) as e:
        read_hdf5(p)
    msg = str(e.value)
    assert "missing dataset 'time'" in msg and "not a kukaid axis log" in msg and "joint_pos, t" in msg
    assert "\n" not in msg
