"""Latency of one six-axis torque-residual step (RobotResidual.update), p50 / p99 / max.

Run:  python benchmarks/robot_residual_step.py [--steps 20000] [--robot kr6-r700-sixx] [--json]

Feeds a recorded six-axis log (the six-axis virtual KR C4 on a Fourier excitation) sample by
sample, once with the model's standard parameters (RNEA) and once with base parameters
(the joint-torque regressor on the base columns: the fallback for a file without the base
parameters' dependency; with it a fitted file is evaluated by RNEA too).  Wall-clock latency
(p50 / p99 / max) and the thread's CPU time per step (p50 / p99: the step's own cost, without the
time other processes take the core).  Target (issue 15): p99 below 100 µs.  Prints; asserts nothing.
"""
from __future__ import annotations

import argparse
import json
import time

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=20000)
    ap.add_argument("--robot", default="kr6-r700-sixx")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    from kukaid.control.robot_residual import RobotResidual, RobotTorqueModel
    from kukaid.excite.fourier import fourier
    from kukaid.sim.robot_plant import RobotSimConfig, VirtualRobotKRC4

    sim = VirtualRobotKRC4(RobotSimConfig(robot=a.robot), seed=0)
    period = 10.0
    traj = fourier(a.robot, period=period, periods=max(1, int(np.ceil(a.steps * sim.cfg.sample_time / period))),
                   iterations=0, starts=1)
    log = sim.run(traj, settle=0.0)
    q, tau = log.q[:a.steps], log.tau[:a.steps]
    truth = sim.truth.to_dict()
    n = sim.n
    models = {
        "standard (RNEA)": RobotTorqueModel.from_truth(truth),
        "base (regressor)": RobotTorqueModel(sim.model_nominal, base=(np.arange(10 * n), np.ravel(truth["pi"])),
                                             Fc=truth["friction"]["Fc"], Fv=truth["friction"]["Fv"],
                                             offset=truth["offset"], rotor=np.asarray(truth["armature"])),
    }
    rows = []
    for name, model in models.items():
        res = RobotResidual(model, sample_time=sim.cfg.sample_time)
        res.update(q[0], tau[0])
        lat, cpu = np.empty(len(q)), np.empty(len(q))
        clock, tclock = time.perf_counter_ns, time.thread_time_ns
        for i in range(len(q)):
            c0, t0 = tclock(), clock()
            res.update(q[i], tau[i])
            lat[i], cpu[i] = clock() - t0, tclock() - c0
        us, cus = lat / 1e3, cpu / 1e3
        rows.append({"model": name, "axes": n, "steps": int(len(q)), "p50_us": float(np.percentile(us, 50)),
                     "p99_us": float(np.percentile(us, 99)), "max_us": float(us.max()),
                     "cpu_p50_us": float(np.percentile(cus, 50)), "cpu_p99_us": float(np.percentile(cus, 99))})
    if a.json:
        print(json.dumps(rows))
        return
    print(f"{'model':<18}{'axes':>5}{'steps':>8}{'p50 µs':>9}{'p99 µs':>9}{'max µs':>9}{'CPU p50':>9}{'CPU p99':>9}")
    for r in rows:
        print(f"{r['model']:<18}{r['axes']:>5}{r['steps']:>8}{r['p50_us']:>9.1f}{r['p99_us']:>9.1f}{r['max_us']:>9.0f}"
              f"{r['cpu_p50_us']:>9.1f}{r['cpu_p99_us']:>9.1f}")


if __name__ == "__main__":
    main()
