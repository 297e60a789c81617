"""Speed of the whole-robot fit: a simulated six-axis log (KR 6 R700 sixx, Pinocchio RNEA, seeded
"true" links, friction, noise; the tests' helper) of DURATION s at FS Hz, fitted by
``fit_robot`` (filter, regressor, base least squares with sigma, physically consistent IPOPT fit).
Prints one row per duration (wall-clock s of each stage and in total) and, with ``--cli``, the
time of ``kukaid fit LOG.h5 --robot kr6-r700-sixx`` as a user runs it (process start included).

Run: python benchmarks/robot_fit_speed.py [--durations 60 600] [--fs 250] [--cli] [--json]
Target (issue 15): a 10-minute 250 Hz six-axis log in under 10 s. Wall-clock times depend on the
machine's load (the load average is printed); the fit's CPU time does not.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--durations", type=float, nargs="*", default=[60.0, 600.0])
    ap.add_argument("--fs", type=float, default=250.0)
    ap.add_argument("--cli", action="store_true", help="also time the kukaid fit command on an HDF5 log")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()

    import scipy.signal  # noqa: F401  (imports are not the fit's time)
    import casadi  # noqa: F401
    from robot_sim_helpers import simulated_log

    from kukaid.identify.robot_fit import fit_robot
    from kukaid.logs import write_hdf5
    from kukaid.models.robot import RobotModel

    robot = RobotModel("kr6-r700-sixx")
    robot.base_parameters()
    rows = []
    for dur in a.durations:
        log, _ = simulated_log(robot, duration=dur, fs=a.fs, seed=0)
        t0, c0 = time.perf_counter(), time.process_time()
        params = fit_robot([log], robot)
        row = {"duration_s": dur, "fs_hz": a.fs, "samples": log.n_samples,
               "fitted_samples": params["metrics"]["samples"], "fit_s": time.perf_counter() - t0,
               "fit_cpu_s": time.process_time() - c0,
               "ipopt_iterations": params["metrics"]["solver"]["iterations"]}
        if a.cli:
            with tempfile.TemporaryDirectory() as tmp:
                h5 = Path(tmp) / "log.h5"
                write_hdf5(log, h5)
                t0 = time.perf_counter()
                r = subprocess.run([sys.executable, "-m", "kukaid_cli.main", "fit", str(h5), "--robot",
                                    "kr6-r700-sixx", "-o", str(Path(tmp) / "p.json")], capture_output=True, text=True)
                row["cli_s"] = time.perf_counter() - t0 if r.returncode == 0 else None
        rows.append(row)
        if not a.json:
            print(f"{dur:7.0f} s log at {a.fs:g} Hz ({log.n_samples} samples, {row['fitted_samples']} fitted): "
                  f"fit_robot {row['fit_s']:.2f} s (CPU {row['fit_cpu_s']:.2f} s)" + (f", kukaid fit (CLI, HDF5) {row['cli_s']:.2f} s" if a.cli else ""),
                  flush=True)
    if a.json:
        print(json.dumps(rows, indent=1))
    else:
        import os

        print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    return 0


if __name__ == "__main__":
    sys.exit(main())
