"""Nobody touching the axis: does it stay where it is?  The plant family, both dampings, after the
initiation move up and down, and after a guided move has ended.

Usage: python benchmarks/admittance_rest.py [--seeds 0-9] [--duration 60] [--vibration 5e-5] [--json] [--quick]

For every member of kukaid.sim.family (seeded), damping (constant at 24 ms, adaptive at 12 ms) and
initiation move (+1 / -1 degree) two runs with the member's own parameter file:

* rest: ``--duration`` s of admittance with nobody there;
* after a guided move: a 15 N·m push for 2 s (0.3 s ramps) in the direction of the initiation
  move, let go; measured from when the reference has coasted to a stop.

Per run: drift (largest |q - q at the window's start|, degrees, the ambient vibration included),
detected cycles, the largest start threshold at rest the estimator needed (N·m).  A run passes
with drift < 0.05 degree and no detection.  ``--vibration A`` overrides every plant's ambient
vibration RMS (rad; the family draws 0-1e-5, the paper's A6 experiment is about 5e-5): the
stress rows of docs/admittance.md.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np


def one(args):
    from kukaid.control.loop import PHASE_ADMITTANCE, LoopConfig, run_admittance
    from kukaid.params import model_from_params
    from kukaid.robot import SimRobot
    from kukaid.sim import VirtualKRC4
    from kukaid.sim.family import plant
    from kukaid.sim.operator import PushOperator

    name, seed, damping, cycle, move, scenario, duration, vibration = args
    p = plant(name, seed)
    cfg_sim = p.cfg if vibration is None else p.cfg.replace(vibration=vibration > 0, vib_amplitude=vibration)
    op, t_from = None, 0.0
    if scenario == "after a guided move":
        op = PushOperator(amplitude=15.0 * move, t_start=2.0, duration=2.0, ramp=0.3)
        duration = max(duration / 2, 10.0)
    cfg = LoopConfig(damping=damping, cycle=cycle, duration=duration, init_move=math.radians(move))
    run = run_admittance(SimRobot(VirtualKRC4(cfg_sim, seed=seed), math.radians(30.0), op),
                         model_from_params(p.params), cfg)
    d = run.data
    if op is not None:  # from when the reference stands after the release (the guided move has ended)
        t_from = float(d["time"][(d["time"] > op.t_end) & (d["sigma_dot"] == 0.0)][0])
    w = (d["phase"] == PHASE_ADMITTANCE) & (d["time"] >= t_from)
    i0 = np.flatnonzero(w)[0]
    drift = float(np.degrees(np.max(np.abs(d["q"][w] - d["q"][i0]))))
    n_det = int(d["detected"][w].sum())
    return {"plant": name, "seed": seed, "damping": damping, "cycle": cycle, "move": move, "scenario": scenario,
            "vibration": float(cfg_sim.vib_amplitude if cfg_sim.vibration else 0.0), "drift_deg": drift,
            "detected_cycles": n_det, "rest_threshold_max": run.metrics["rest_threshold_max"],
            "passes": drift < 0.05 and n_det == 0, "status": run.status}


def main() -> None:
    from kukaid.sim.family import FAMILY

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="0-9", help="plant seeds, a range A-B or a list")
    ap.add_argument("--duration", type=float, default=60.0, help="seconds at rest")
    ap.add_argument("--vibration", type=float, help="ambient vibration RMS for every plant, rad [the member's]")
    ap.add_argument("--jobs", type=int, default=0, help="worker processes [the machine's cores]")
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--quick", action="store_true", help="one seed, two members (gms, lugre), 10 s")
    a = ap.parse_args()
    if "-" in a.seeds:
        lo, hi = (int(x) for x in a.seeds.split("-"))
        seeds = list(range(lo, hi + 1))
    else:
        seeds = [int(x) for x in a.seeds.split(",")]
    members = FAMILY
    if a.quick:
        seeds, a.duration, members = seeds[:1], 10.0, ("gms", "lugre")
    plan = [(name, s, damping, cycle, move, scenario, a.duration, a.vibration)
            for name in members for s in seeds for damping, cycle in (("constant", 0.024), ("adaptive", 0.012))
            for move in (1.0, -1.0) for scenario in ("rest", "after a guided move")]
    t = time.perf_counter()
    jobs = a.jobs or os.cpu_count() or 1
    if jobs > 1:
        with ProcessPoolExecutor(jobs) as ex:
            rows = list(ex.map(one, plan, chunksize=2))
    else:
        rows = [one(p) for p in plan]
    summary = []
    for name in members:
        for scenario in ("rest", "after a guided move"):
            rs = [r for r in rows if r["plant"] == name and r["scenario"] == scenario]
            summary.append({"plant": name, "scenario": scenario, "runs": len(rs),
                            "pass": sum(r["passes"] for r in rs),
                            "drift_max_deg": max(r["drift_deg"] for r in rs),
                            "detected_runs": sum(r["detected_cycles"] > 0 for r in rs),
                            "rest_threshold_max": max(r["rest_threshold_max"] for r in rs)})
    doc = {"seeds": seeds, "duration": a.duration, "vibration": a.vibration, "summary": summary, "runs": rows,
           "seconds": time.perf_counter() - t}
    if a.json:
        json.dump(doc, sys.stdout)
        print()
        return
    vib = "each member's" if a.vibration is None else f"{a.vibration:g} rad RMS"
    print(f"nobody touching: seeds {seeds[0]}-{seeds[-1]}, {a.duration:g} s at rest, vibration {vib}, both dampings, "
          f"moves up and down")
    print(f"{'plant':>14} {'scenario':>20} | {'pass':>7} | {'drift max':>9} | {'runs w/ det':>11} | {'thr at rest max':>15}")
    for r in summary:
        print(f"{r['plant']:>14} {r['scenario']:>20} | {r['pass']:3d}/{r['runs']:<3d} | {r['drift_max_deg']:7.4f} ° |"
              f" {r['detected_runs']:11d} | {r['rest_threshold_max']:11.2f} N·m")
    total = sum(r["pass"] for r in summary), sum(r["runs"] for r in summary)
    print(f"all: {total[0]}/{total[1]} runs pass ({doc['seconds']:.0f} s)")


if __name__ == "__main__":
    main()
