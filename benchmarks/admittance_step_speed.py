"""Speed of one control step: torque-residual estimator + adaptive (RBF) damping + admittance
+ oscillation monitor + grip floor, as the loop runs them every cycle.

Usage: python benchmarks/admittance_step_speed.py [--steps 100000] [--json]

Feeds recorded-like measurements (a slow sine with noise) and times each step twice: wall clock
(perf_counter_ns, includes the time the process is preempted on a loaded machine) and the
thread's CPU time (thread_time_ns, the step's own cost); prints p50, p99 and the maximum in
microseconds (never asserted: the time depends on the machine).  Budget: p99 under 100 us (a
12 ms cycle leaves the rest to I/O).
"""
from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np


def main() -> None:
    from kukaid.control.admittance import Admittance
    from kukaid.control.rbf import RBFConfig, RBFDamping
    from kukaid.control.filters import CausalButterworth
    from kukaid.control.stability import (CouplingConfig, CouplingFloor, OscillationMonitor, StabilityConfig,
                                          StickSlipWatch)
    from kukaid.control.torque_residual import TorqueResidual
    from kukaid.params import model_from_params
    from kukaid.sim import SimConfig

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=100_000)
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    model = model_from_params(SimConfig().truth_params())
    est = TorqueResidual(model, sample_time=0.012, threshold=5.0)
    rbf = RBFDamping(RBFConfig())
    rbf.set_cycle(0.012)
    mon = OscillationMonitor(StabilityConfig(), 0.012, 50.0, 3000.0)
    grip = CouplingFloor(CouplingConfig(), 0.012, 20.0, 500.0, CausalButterworth(5.0, 1 / 0.012, 3).phase_delay)
    adm = Admittance(20.0, 50.0, 0.012, sigma0=0.5)
    slip = StickSlipWatch(0.012, cap=15.0)
    rng = np.random.default_rng(0)
    n = a.steps
    t = np.arange(n) * 0.012
    q = 0.5 + 0.3 * np.sin(2 * math.pi * t / 7.0) * (np.sin(2 * math.pi * t / 31.0) > 0)
    tau = 18.0 * np.cos(q) + 15.0 * np.sign(np.gradient(q)) + 8.0 * np.sin(t) + 0.5 * rng.standard_normal(n)
    dt = np.empty(n)
    dc = np.empty(n)
    D = 50.0
    for i in range(n):
        t0 = time.perf_counter_ns()
        c0 = time.thread_time_ns()
        r = est.update(q[i], tau[i])
        est.cycle_margin = slip.step(adm.sigma_dot, r.detected, r.gamma_r)
        g = r.gamma_r if r.detected else 0.0
        floor = max(mon.step(r.gamma_r, D), grip.step(r.gamma_r, r.detected, D))
        grip.observe_robot(adm.sigma, q[i])
        D = max(rbf.step(r.gamma_r, direction=adm.sigma_dot or g, adapt=r.detected and not mon.oscillating), floor)
        adm.step(g, D)
        dc[i] = (time.thread_time_ns() - c0) / 1000.0
        dt[i] = (time.perf_counter_ns() - t0) / 1000.0
    import os

    res = {"steps": n, "load_average": list(os.getloadavg())}
    for name, x in (("wall", dt), ("cpu", dc)):
        res[name] = {"p50_us": float(np.percentile(x, 50)), "p99_us": float(np.percentile(x, 99)),
                     "max_us": float(x.max())}
    if a.json:
        print(json.dumps(res))
    else:
        print("control step (estimator + oscillation monitor + grip floor + RBF damping + stick-slip watch + "
              f"admittance), {n} steps (budget p99 < 100 us; load average {res['load_average'][0]:.1f} on {os.cpu_count()} cores):")
        for name in ("cpu", "wall"):
            r = res[name]
            print(f"  {name:4s}: p50 {r['p50_us']:.1f} us, p99 {r['p99_us']:.1f} us, max {r['max_us']:.0f} us")


if __name__ == "__main__":
    main()
