"""Speed and memory of reading a long log: a six-axis log of DURATION s at FS Hz (seeded sines and
noise), written as CSV, CSV gzip-compressed and HDF5, each read by ``kukaid.logs.read_log`` in a fresh
process: its CPU time (the read alone) and the process's peak resident memory (imports included).

Run: python benchmarks/log_read_speed.py [--duration 3600] [--fs 200] [--json]
New-user trial 15 found a 1-hour 200 Hz CSV read in 7.5 s and 1 GB (parsed line by line in Python);
pandas' C parser now reads it, and a file it cannot read as numbers is read again line by line to
name the line.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path


def _child(path: str) -> None:
    import resource
    import time

    from kukaid.logs import read_log

    t0 = time.process_time()
    lg = read_log(path)
    cpu = time.process_time() - t0
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    print(json.dumps({"cpu_s": cpu, "peak_mb": peak, "rows": int(lg.time.size)}))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--duration", type=float, default=3600.0, help="log length, s")
    ap.add_argument("--fs", type=float, default=200.0, help="sample rate, Hz")
    ap.add_argument("--json", action="store_true", help="print the rows as JSON")
    a = ap.parse_args()
    import numpy as np

    from kukaid.logs import AxisLog, write_csv, write_hdf5

    n = int(a.duration * a.fs)
    t = np.arange(n) / a.fs
    rng = np.random.default_rng(0)
    q = np.column_stack([0.5 * np.sin(0.3 * t + k) for k in range(6)])
    tau = np.column_stack([20.0 * np.cos(0.3 * t + k) + rng.normal(0.0, 0.5, n) for k in range(6)])
    lg = AxisLog(time=t, axes=(1, 2, 3, 4, 5, 6), joint=("revolute",) * 6, q=q, tau=tau)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        paths = {"csv": Path(tmp) / "log.csv", "csv.gz": Path(tmp) / "log.csv.gz", "h5": Path(tmp) / "log.h5"}
        write_csv(lg, paths["csv"])
        write_hdf5(lg, paths["h5"])
        import gzip
        import shutil

        with open(paths["csv"], "rb") as src, gzip.open(paths["csv.gz"], "wb", compresslevel=1) as dst:
            shutil.copyfileobj(src, dst, 1 << 20)
        for fmt, p in paths.items():
            out = subprocess.run([sys.executable, __file__, "--child", str(p)], capture_output=True, text=True,
                                 check=True)
            r = json.loads(out.stdout.strip().splitlines()[-1])
            rows.append({"format": fmt, "size_mb": p.stat().st_size / 1e6, **r})
    if a.json:
        print(json.dumps({"duration_s": a.duration, "fs": a.fs, "rows": rows}, indent=1))
        return
    print(f"a six-axis log of {a.duration:.0f} s at {a.fs:.0f} Hz ({n} samples), read by read_log in a fresh process")
    print(f"{'format':>8} | {'file MB':>8} | {'CPU s':>6} | {'peak MB':>8}")
    for r in rows:
        print(f"{r['format']:>8} | {r['size_mb']:8.1f} | {r['cpu_s']:6.2f} | {r['peak_mb']:8.0f}")


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "--child":
        _child(sys.argv[2])
    else:
        main()
