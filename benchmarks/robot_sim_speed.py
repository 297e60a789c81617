"""Speed of the six-axis virtual KR C4: a 10-minute, 250 Hz log of a Fourier excitation of all axes.

Run:  python benchmarks/robot_sim_speed.py [--minutes 10] [--robot kr6-r700-sixx] [--json]

Prints the simulated duration, the samples logged, the wall time and the real-time factor
(target, issue 15: a 10-minute 250 Hz log in well under a minute).
"""
from __future__ import annotations

import argparse
import json
import time


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--robot", default="kr6-r700-sixx")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    from kukaid.excite.fourier import fourier
    from kukaid.sim.robot_plant import RobotSimConfig, VirtualRobotKRC4

    period = 10.0
    traj = fourier(a.robot, period=period, periods=max(1, int(round(a.minutes * 60 / period))), iterations=0, starts=2)
    sim = VirtualRobotKRC4(RobotSimConfig(robot=a.robot), seed=0)
    t0 = time.perf_counter()
    log = sim.run(traj, settle=0.0)
    wall = time.perf_counter() - t0
    row = {"robot": a.robot, "simulated_s": log.duration, "samples": log.n_samples,
           "rate_hz": 1.0 / log.sample_time, "wall_s": wall, "realtime_factor": log.duration / wall}
    if a.json:
        print(json.dumps(row))
    else:
        print(f"{'robot':<16}{'simulated s':>12}{'samples':>10}{'rate Hz':>9}{'wall s':>9}{'x real time':>12}")
        print(f"{row['robot']:<16}{row['simulated_s']:>12.1f}{row['samples']:>10d}{row['rate_hz']:>9.0f}"
              f"{row['wall_s']:>9.1f}{row['realtime_factor']:>12.1f}")


if __name__ == "__main__":
    main()
