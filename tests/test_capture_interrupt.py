"""`kukaid capture --backend kvp` cut short by Ctrl-C: the log is kept, and the command says it was
interrupted (exit status 130, as the sim backend); with --until-interrupt Ctrl-C is the normal end."""
from __future__ import annotations

import signal
import subprocess

import numpy as np
import pytest

from kukaid.krc.server import KvpServer
from kukaid.krc.sim_source import SimSource
from kukaid.logs import read_hdf5
from live_helpers import wait_for_samples


@pytest.fixture
def kvp_port():
    from types import SimpleNamespace

    from kukaid.sim import SimConfig, VirtualKRC4

    t = np.arange(0.0, 120.0, 0.012)
    q = 0.3 + 0.25 * np.sin(2 * np.pi * t / 4.0) * np.minimum(t, 1.0)
    sim = VirtualKRC4(SimConfig(), seed=3, axis=3)
    src = SimSource(sim, axis=3, trajectory=SimpleNamespace(t=t, q=q, axis=3)).start()
    srv = KvpServer(src, port=0).start()
    yield srv.port
    srv.stop()
    src.stop()


@pytest.mark.parametrize("until_interrupt", [False, True])
def test_ctrl_c_ends_a_kvp_capture_and_says_whether_it_was_cut_short(kvp_port, tmp_path, kukaid_cmd, until_interrupt):
    out = tmp_path / "sig.h5"
    end = ["--until-interrupt"] if until_interrupt else ["--duration", "20"]
    proc = subprocess.Popen([*kukaid_cmd, "capture", "--backend", "kvp", "--port", str(kvp_port), *end, "-o", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        wait_for_samples(out, proc, 100)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    log = read_hdf5(out)  # kept either way: it is recorded data
    assert log.n_samples >= 100 and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1, err
    if until_interrupt:
        assert proc.returncode == 0 and err.startswith(f"{out}: {log.n_samples} samples"), err
    else:
        assert proc.returncode == 130, err
        assert err.startswith(f"kukaid: error: capture interrupted after {log.duration:.2f} of 20 s; "
                              f"{log.n_samples} samples kept in {out}"), err
