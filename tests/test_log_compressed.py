"""Compressed logs (.gz, .bz2, .xz) are read as the plain file would be; a broken stream is one line."""
from __future__ import annotations

import bz2
import gzip
import lzma

import numpy as np
import pytest
from click.testing import CliRunner

from kukaid.errors import LogFormatError
from kukaid.logs import AxisLog, read_log, write_csv, write_hdf5


@pytest.fixture(scope="module")
def plain(tmp_path_factory):
    d = tmp_path_factory.mktemp("comp")
    t = np.arange(500) * 0.004
    log = AxisLog(time=t, q=np.column_stack([np.sin(t), np.cos(t)]), tau=np.column_stack([t, -t]), axes=(1, 2))
    write_csv(log, d / "log.csv")
    write_hdf5(log, d / "log.h5")
    return d


@pytest.mark.parametrize("name", ["log.csv", "log.h5"])
@pytest.mark.parametrize("ext,mod", [(".gz", gzip), (".bz2", bz2), (".xz", lzma)])
def test_compressed_log_reads_as_the_plain_one(plain, name, ext, mod):
    src = plain / name
    comp = plain / (name + ext)
    with mod.open(comp, "wb") as f:
        f.write(src.read_bytes())
    a, b = read_log(src), read_log(comp)
    assert a.axes == b.axes and np.array_equal(a.q, b.q) and np.array_equal(a.tau, b.tau)
    assert b.attrs["source_file"] == str(comp)


def test_broken_or_unknown_compressed_log_is_one_clear_error(plain):
    bad = plain / "bad.csv.gz"
    bad.write_bytes(b"not gzip at all")
    with pytest.raises(LogFormatError, match="not a valid gzip file"):
        read_log(bad)
    cut = plain / "cut.csv.xz"
    cut.write_bytes(lzma.compress((plain / "log.csv").read_bytes())[:200])
    with pytest.raises(LogFormatError, match="not a valid xz file"):
        read_log(cut)
    with pytest.raises(LogFormatError, match="unknown log format '.txt.gz'"):
        read_log(plain / "x.txt.gz")
    from kukaid_cli.main import cli

    r = CliRunner().invoke(cli, ["validate", "--params", str(plain / "nope.json"), str(bad)])
    assert r.exit_code != 0 and "Traceback" not in r.output


@pytest.mark.parametrize("ext, mod", [(".gz", gzip), (".bz2", bz2), (".xz", lzma)])
def test_a_compressed_mat_file_takes_the_mat_options(tmp_path, ext, mod):
    """New-user trial 13: `kukaid load DATA_EMPS.mat.bz2 --time t --q qm --tau vir ...` said "option --time is
    for MAT (.mat) sources", though every reader opens a compressed MAT file."""
    from scipy.io import savemat

    from kukaid.logs import read_hdf5
    from kukaid_cli.main import cli

    t = np.arange(300) * 0.001
    savemat(tmp_path / "rec.mat", {"tt": t[:, None], "pos": np.sin(t)[:, None], "u": np.cos(t)[:, None]})
    src = tmp_path / f"rec.mat{ext}"
    src.write_bytes(mod.compress((tmp_path / "rec.mat").read_bytes()))
    out = tmp_path / "rec.h5"
    r = CliRunner().invoke(cli, ["load", str(src), "--time", "tt", "--q", "pos", "--tau", "u", "--joint", "revolute",
                                 "-o", str(out)])
    assert r.exit_code == 0, r.output
    log = read_hdf5(out)
    assert np.allclose(log.time, t) and np.allclose(log.q[:, 0], np.sin(t)) and np.allclose(log.tau[:, 0], np.cos(t))


def test_a_compressed_kuka_trace_file_says_the_recording_is_several_files(tmp_path):
    """A Trace .dat.gz was decompressed alone, and the reader then said '.r64 not found beside .dat'
    though the user had it there (compressed or not)."""
    import gzip

    from kukaid.errors import LogFormatError
    from kukaid.logs import read_log

    p = tmp_path / "REC_NextGenDrive#1.dat.gz"
    p.write_bytes(gzip.compress(b"DIAEXTENDED  {@:ENGLISH\n"))
    (tmp_path / "REC_NextGenDrive#1.r64").write_bytes(b"\0" * 16)
    with pytest.raises(LogFormatError, match="several files .* decompress them into one folder and give its .dat"):
        read_log(p)
