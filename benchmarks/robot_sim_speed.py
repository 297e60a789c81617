"""Speed of the six-axis virtual KR C4: a 10-minute, 250 Hz log of a Fourier excitation of all axes.

Run:  python benchmarks/robot_sim_speed.py [--minutes 10] [--robot kr6-r700-sixx] [--truth rigid] [--json]

``--truth coupled-friction``: the wrist motors' friction on coupled velocities (ratios 0.35, -0.3,
0.45); ``--truth elastic``: A2's gear a spring of 3e4 N·m/rad (10 % damping), the servo at 5 kHz
(the rate its velocity loop needs).

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
    ap.add_argument("--truth", default="rigid", choices=("rigid", "coupled-friction", "elastic"))
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    from dataclasses import replace

    import numpy as np

    from kukaid.excite.fourier import fourier
    from kukaid.models.urdf import load_model
    from kukaid.sim.robot_plant import RobotSimConfig, VirtualRobotKRC4
    from kukaid.sim.robot_truth import draw_truth

    period = 10.0
    traj = fourier(a.robot, period=period, periods=max(1, int(round(a.minutes * 60 / period))), iterations=0, starts=2)
    cfg = RobotSimConfig(robot=a.robot, **({"servo_rate": 5000.0} if a.truth == "elastic" else {}))
    truth = draw_truth(a.robot, load_model(a.robot), seed=cfg.truth_seed, size=cfg.perturb)
    n = truth.n
    if a.truth == "coupled-friction":
        C = np.zeros((n, n))
        C[n - 2, n - 3], C[n - 1, n - 3], C[n - 1, n - 2] = 0.35, -0.3, 0.45
        truth = replace(truth, friction_coupling=C)
    elif a.truth == "elastic":
        K, D = np.zeros(n), np.zeros(n)
        K[1], D[1] = 3e4, 2 * 0.1 * np.sqrt(3e4 * truth.armature[1])
        truth = replace(truth, gear_stiffness=K, gear_damping=D)
    sim = VirtualRobotKRC4(cfg, seed=0, truth=truth)
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
