"""KUKAVARPROXY capture rate and request latency against the virtual KR C4 on loopback.

Starts `kukaid serve-sim` (a separate process, as a controller would be) on a free port, runs the
poll capture (`kukaid.krc.kvp_capture.capture_kvp`) for one axis and for three axes, and prints
achieved samples per second, mean sample period, and request latency mean / p99 / max.
Targets (issue 4): < 1 ms per exchange on loopback; a full A3 sample (position + torque) every
12 ms or faster.  The paper reports about 5 ms per exchange and a 24 ms cycle over its network.

Usage: python benchmarks/kvp_rate.py [--seconds 3]
"""
from __future__ import annotations

import argparse
import re
import subprocess
import sys
import tempfile
from pathlib import Path


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=3.0)
    args = ap.parse_args()
    from kukaid.krc.kvp_capture import capture_kvp

    server = subprocess.Popen([sys.executable, "-m", "kukaid_cli.main", "serve-sim", "--port", "0"],
                              stderr=subprocess.PIPE, text=True)
    try:
        line = server.stderr.readline()
        m = re.search(r"listening on ([\d.]+):(\d+)", line)
        if not m:
            raise SystemExit(f"serve-sim did not start: {line}")
        port = int(m.group(2))
        rows = []
        with tempfile.TemporaryDirectory() as d:
            for axes in ([3], [1, 2, 3]):
                s = capture_kvp(Path(d) / f"a{len(axes)}.h5", "127.0.0.1", port, axes, args.seconds, False,
                                "poll", None)
                req_per_sample = s["n_requests"] / max(s["n_samples"], 1)
                rows.append((len(axes), s["n_samples"], s["rate_hz"], 1e3 / s["rate_hz"], req_per_sample,
                             s["latency_mean_s"] * 1e3, s["latency_p99_s"] * 1e3, s["latency_max_s"] * 1e3))
    finally:
        server.terminate()
        server.wait(timeout=10)
    print(f"KUKAVARPROXY poll capture on loopback against serve-sim, {args.seconds:g} s per run")
    print(f"{'axes':>4} {'samples':>8} {'samples/s':>10} {'period ms':>10} {'req/sample':>10} "
          f"{'lat mean ms':>11} {'lat p99 ms':>10} {'lat max ms':>10}")
    for r in rows:
        print(f"{r[0]:>4} {r[1]:>8} {r[2]:>10.0f} {r[3]:>10.3f} {r[4]:>10.2f} {r[5]:>11.3f} {r[6]:>10.3f} {r[7]:>10.3f}")
    ok_lat = all(r[5] < 1.0 for r in rows)
    ok_a3 = rows[0][3] <= 12.0
    print(f"target < 1 ms per exchange (mean): {'met' if ok_lat else 'NOT met'}; "
          f"full A3 sample every <= 12 ms: {'met' if ok_a3 else 'NOT met'} ({rows[0][3]:.3f} ms)")


if __name__ == "__main__":
    main()
