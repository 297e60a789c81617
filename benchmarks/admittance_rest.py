"""Nobody touching the axis: does it stay where it is?  The plant family, both dampings, after the
initiation move up and down, and after a guided move has ended.

Usage: python benchmarks/admittance_rest.py [--seeds 0-9] [--duration 60] [--vibration 5e-5] [--json] [--quick]
                                            [--outside NAME[,NAME...] | --outside all] [--files fitted]

For every member of kukaid.sim.family (seeded), damping (constant at 24 ms, adaptive at 12 ms) and
initiation move (+1 / -1 degree) two runs with the member's own parameter file:

* rest: ``--duration`` s of admittance with nobody there;
* after a guided move: a 15 N·m push for 2 s (0.3 s ramps) in the direction of the initiation
  move, let go; measured from when the reference has coasted to a stop.

Per run: drift (largest |q - q at the window's start|, degrees, the ambient vibration included),
detected cycles, the largest start threshold at rest the estimator needed (N·m), and whether the
loop's stick-slip watch raised the threshold at a stop (``stick-slip``: runs where it acted).  A run passes
with drift < 0.05 degree and no detection.  ``--vibration A`` overrides every plant's ambient
vibration RMS (rad; the family draws 0-1e-5, the paper's A6 experiment is about 5e-5): the
stress rows of docs/admittance.md.

``--files fitted``: instead of the member's parameter file (its truth with identification errors),
the file the toolkit's own identification gives on that plant: ``excite`` friction, inertia and
pre-sliding experiments run on it (the changed one with ``--outside``), then ``fit``; when the fit
warns that a Maxwell-slip element saturates only at the pre-sliding experiment's largest deflection,
the pre-sliding experiment again with the reversals it asks for (0.1, 0.05, 0.025, 0.0125 degrees).

``--outside``: every member is changed by what the family does not draw (each drawn from the run's
seed; the parameter file stays the member's own), one row per change and scenario:

=============  ===============================================================================
``stiction``   breakaway Fs 1.35-1.6 x Fc (the files' 1.1-1.3 x: a breakaway grows with dwell
               time and in the cold)
``cold``       all friction (Fc, Fs, Fv, pre-sliding) 25 % above the file's
``warm``       all friction 20 % below it
``backlash``   an impact transient after every reversal (3-8 N·m, kukaid.sim.effects)
``ripple``     a position ripple of 1-3 N·m, 20-80 periods per radian
``load``       Coulomb friction growing with the gravity load (5-15 %)
``offset``     a constant torque of up to 4 N·m the file does not have
``noise``      torque noise 1-2 N·m (the family's 0.3-0.7)
``delay``      the torque two samples late, quantised to 0.1 N·m
``jitter``     sample timing jitter of 2 ms
``servo``      integral gain 60-100 1/s, position gain 25-60 1/s (the family's 20-50, 30-50)
``vibration``  ambient vibration 1-3e-5 rad (the family's 0-1e-5)
``heavy``      a gravity-loaded axis (an A2): gravity 3-5 x, inertia 2-4 x, friction 1-2 x the
               member's (the servo's machine data too); with the member's own file a gravity
               error of 200-400 %: give it with ``--files fitted``
=============  ===============================================================================
"""
from __future__ import annotations

import argparse
import functools
import json
import math
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from kukaid.sim.family import gravity_loaded


#: what --outside changes in a member's simulator: name -> f(cfg, rng) -> cfg
OUTSIDE = {
    "stiction": lambda c, r: c.replace(Fs=c.Fc * r.uniform(1.35, 1.6)),
    "cold": lambda c, r: c.replace(Fc=c.Fc * 1.25, Fs=c.Fs * 1.25, Fv=c.Fv * 1.25, ms_W=tuple(w * 1.25 for w in c.ms_W)),
    "warm": lambda c, r: c.replace(Fc=c.Fc * 0.8, Fs=c.Fs * 0.8, Fv=c.Fv * 0.8, ms_W=tuple(w * 0.8 for w in c.ms_W)),
    "backlash": lambda c, r: c.replace(effects={"backlash": {"A": r.uniform(3, 8), "tau": r.uniform(0.06, 0.15)}}),
    "ripple": lambda c, r: c.replace(effects={"position_ripple": {"A": r.uniform(1, 3), "n": float(r.integers(20, 80)),
                                                                  "phi": r.uniform(-3, 3)}}),
    "load": lambda c, r: c.replace(effects={"load_dependent_friction": {"c": r.uniform(0.05, 0.15)}}),
    "offset": lambda c, r: c.replace(effects={"torque_offset": {"offset": r.uniform(-4, 4)}}),
    "noise": lambda c, r: c.replace(noise_sigma=r.uniform(1.0, 2.0)),
    "delay": lambda c, r: c.replace(tau_delay=2, tau_quant=0.1),
    "jitter": lambda c, r: c.replace(jitter=0.002),
    "servo": lambda c, r: c.replace(Ki=r.uniform(60, 100), Kp=r.uniform(25, 60)),
    "vibration": lambda c, r: c.replace(vibration=True, vib_amplitude=r.uniform(1e-5, 3e-5)),
    "heavy": lambda c, r: gravity_loaded(c, r.uniform(3.0, 5.0), r.uniform(2.0, 4.0), r.uniform(1.0, 2.0)),
}


@functools.lru_cache(maxsize=8)
def fitted_params(name: str, seed: int, outside: str | None, vibration: float | None) -> dict:
    """The parameter file ``kukaid fit`` gives on the plant: the default friction, inertia and
    pre-sliding experiments captured on it, fitted together."""
    from kukaid import excite
    from kukaid.identify import fit_axis
    from kukaid.sim import VirtualKRC4
    from kukaid.sim.family import plant

    cfg = plant_config(plant(name, seed), outside, vibration)
    logs = [VirtualKRC4(cfg, seed=1000 + 3 * seed + k, axis=3).run(traj)
            for k, traj in enumerate((excite.friction(), excite.inertia(), excite.presliding()))]
    fitted = fit_axis(friction=[logs[0]], inertia=[logs[1]], presliding=logs[2])
    if any("--reversals-deg" in w for w in fitted["metrics"]["warnings"]):  # as the warning says: larger reversals
        wide = excite.presliding(reversals=tuple(math.radians(r) for r in (0.1, 0.05, 0.025, 0.0125)))
        fitted = fit_axis(friction=[logs[0]], inertia=[logs[1]],
                          presliding=VirtualKRC4(cfg, seed=1000 + 3 * seed + 2, axis=3).run(wide))
    return fitted


def plant_config(p, outside: str | None, vibration: float | None):
    """The simulator of family member ``p`` (a :class:`kukaid.sim.family.Plant`), with ``--vibration`` and
    ``--outside``'s change (drawn from its seed)."""
    cfg = p.cfg
    if vibration is not None:
        cfg = cfg.replace(vibration=vibration > 0, vib_amplitude=vibration)
    if outside:
        cfg = OUTSIDE[outside](cfg, np.random.default_rng([p.seed, 7, list(OUTSIDE).index(outside)]))
    return cfg


def one(args):
    from kukaid.control.loop import PHASE_ADMITTANCE, LoopConfig, default_threshold, run_admittance
    from kukaid.params import model_from_params
    from kukaid.robot import SimRobot
    from kukaid.sim import VirtualKRC4
    from kukaid.sim.family import plant
    from kukaid.sim.operator import PushOperator

    name, seed, damping, cycle, move, scenario, duration, vibration, outside, files = args
    p = plant(name, seed)
    cfg_sim = plant_config(p, outside, vibration)
    params = fitted_params(name, seed, outside, vibration) if files == "fitted" else p.params
    op, t_from = None, 0.0
    if scenario == "after a guided move":
        op = PushOperator(amplitude=15.0 * move, t_start=2.0, duration=2.0, ramp=0.3)
        duration = max(duration / 2, 10.0)
    model = model_from_params(params)
    cfg = LoopConfig(damping=damping, cycle=cycle, duration=duration, init_move=math.radians(move),
                     threshold=default_threshold(model))  # run-admittance's default
    run = run_admittance(SimRobot(VirtualKRC4(cfg_sim, seed=seed), math.radians(30.0), op), model, cfg)
    d = run.data
    standing = (d["time"] > (op.t_end if op is not None else 0.0)) & (d["sigma_dot"] == 0.0)
    if op is not None and standing.any():  # from when the reference stands after the release (the move has ended)
        t_from = float(d["time"][standing][0])
    w = (d["phase"] == PHASE_ADMITTANCE) & (d["time"] >= t_from)
    if not w.any():  # stopped before control, or before the guided move ended: no rest to judge, a failure
        drift, n_det = math.nan, 0
    else:
        i0 = np.flatnonzero(w)[0]
        drift = float(np.degrees(np.max(np.abs(d["q"][w] - d["q"][i0]))))
        n_det = int(d["detected"][w].sum())
    return {"plant": name, "outside": outside, "seed": seed, "damping": damping, "cycle": cycle, "move": move, "scenario": scenario,
            "vibration": float(cfg_sim.vib_amplitude if cfg_sim.vibration else 0.0), "drift_deg": drift,
            "detected_cycles": n_det, "rest_threshold_max": run.metrics["rest_threshold_max"],
            "stick_slip_margin": run.metrics["stick_slip_margin"],
            "passes": drift < 0.05 and n_det == 0 and run.status == "completed", "status": run.status}


def main() -> None:
    from kukaid.sim.family import FAMILY

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="0-9", help="plant seeds, a range A-B or a list")
    ap.add_argument("--duration", type=float, default=60.0, help="seconds at rest")
    ap.add_argument("--vibration", type=float, help="ambient vibration RMS for every plant, rad [the member's]")
    ap.add_argument("--jobs", type=int, default=0, help="worker processes [the machine's cores]")
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--quick", action="store_true", help="one seed, two members (gms, lugre), 10 s")
    ap.add_argument("--files", choices=("family", "fitted"), default="family",
                    help="the member's parameter file, or the one the toolkit's own identification gives [family]")
    ap.add_argument("--outside", help="change every member by what the family does not draw: names from "
                                      f"{', '.join(OUTSIDE)}, comma-separated, or 'all' (a row per change)")
    a = ap.parse_args()
    outside = [None] if not a.outside else list(OUTSIDE) if a.outside == "all" else a.outside.split(",")
    for o in outside:
        if o is not None and o not in OUTSIDE:
            ap.error(f"--outside: unknown change {o!r}; choose from {', '.join(OUTSIDE)} or all")
    if "-" in a.seeds:
        lo, hi = (int(x) for x in a.seeds.split("-"))
        seeds = list(range(lo, hi + 1))
    else:
        seeds = [int(x) for x in a.seeds.split(",")]
    members = FAMILY
    if a.quick:
        seeds, a.duration, members = seeds[:1], 10.0, ("gms", "lugre")
    plan = [(name, s, damping, cycle, move, scenario, a.duration, a.vibration, o, a.files)
            for o in outside for name in members for s in seeds for damping, cycle in (("constant", 0.024), ("adaptive", 0.012))
            for move in (1.0, -1.0) for scenario in ("rest", "after a guided move")]
    t = time.perf_counter()
    jobs = a.jobs or os.cpu_count() or 1
    if jobs > 1:
        with ProcessPoolExecutor(jobs) as ex:
            rows = list(ex.map(one, plan, chunksize=8 if a.files == "fitted" else 2))  # a plant's runs, one fit
    else:
        rows = [one(p) for p in plan]
    summary = []  # a row per member, or with --outside per change (over every member)
    for key in (outside if a.outside else members):
        for scenario in ("rest", "after a guided move"):
            rs = [r for r in rows if key in (r["plant"], r["outside"]) and r["scenario"] == scenario]
            summary.append({"plant": "every member" if a.outside else key, "outside": key if a.outside else None,
                            "scenario": scenario, "runs": len(rs),
                            "pass": sum(r["passes"] for r in rs),
                            "drift_max_deg": max((r["drift_deg"] for r in rs if r["drift_deg"] == r["drift_deg"]), default=math.nan),
                            "detected_runs": sum(r["detected_cycles"] > 0 for r in rs),
                            "stick_slip_runs": sum(r["stick_slip_margin"] > 0 for r in rs),
                            "rest_threshold_max": max(r["rest_threshold_max"] for r in rs)})
    doc = {"seeds": seeds, "duration": a.duration, "vibration": a.vibration, "outside": a.outside, "files": a.files,
           "summary": summary,
           "runs": rows,
           "seconds": time.perf_counter() - t}
    if a.json:
        json.dump(doc, sys.stdout)
        print()
        return
    vib = "each member's" if a.vibration is None else f"{a.vibration:g} rad RMS"
    print(f"nobody touching: seeds {seeds[0]}-{seeds[-1]}, {a.duration:g} s at rest, vibration {vib}, both dampings, "
          "moves up and down, " + ("files fitted on each plant" if a.files == "fitted" else "the members' files"))
    print(f"{'outside' if a.outside else 'plant':>14} {'scenario':>20} | {'pass':>7} | {'drift max':>9} | "
          f"{'runs w/ det':>11} | {'stick-slip':>10} | {'thr at rest max':>15}")
    for r in summary:
        print(f"{r['outside'] or r['plant']:>14} {r['scenario']:>20} | {r['pass']:3d}/{r['runs']:<3d} | {r['drift_max_deg']:7.4f} ° |"
              f" {r['detected_runs']:11d} | {r['stick_slip_runs']:10d} | {r['rest_threshold_max']:11.2f} N·m")
    for r in rows:
        if a.outside and not r["passes"]:
            print(f"  fails: {r['outside']} {r['plant']} seed {r['seed']} {r['damping']} move {r['move']:+g} "
                  f"{r['scenario']}: drift {r['drift_deg']:.3f} °, {r['detected_cycles']} cycles detected"
                  + ("" if r["status"] == "completed" else f"; {r['status'][:160]}"))
    total = sum(r["pass"] for r in summary), sum(r["runs"] for r in summary)
    print(f"all: {total[0]}/{total[1]} runs pass ({doc['seconds']:.0f} s)")


if __name__ == "__main__":
    main()
