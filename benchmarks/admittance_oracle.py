"""Firm grips: can any damping both stay free of oscillation and cost the person less than D 50?

Usage: python benchmarks/admittance_oracle.py [--seed-offsets 0,1000,2000,3000,4000] [--operators 30]
                                              [--cycles 0.024,0.012] [--arm human|spring] [--json]

Issue 12 asks, with firm grips, for no adaptive run oscillating and for the adaptive law to cost
the person less (ξ of the true hand torque) than constant D 50 with its stability monitor for at
least 80 % of operators.  This benchmark asks whether any damping could do both for the operator
models of admittance_paper.py, by giving the controller what no controller can know:

* **oracle ζ**: the adaptive law (RBF damping, stability monitor as shipped, or without it) whose
  grip floor is replaced by one that reads the person's true stiffness at every cycle (the human
  arm's K(t), which rises with effort; SpringArm's K) and the loop's true delay (the estimator
  filter's phase delay at the coupled mode sqrt(K / I), one control cycle, the robot's lag as the
  floor measures it, plus the arm's own: the reflex share of its stiffness times the reflex delay,
  or SpringArm's whole delay), and holds the damping at D_crit(K, T) + 2 ζ sqrt(K I) while the
  person holds the link (ζ = 0: on the stability limit of kukaid.control.stability.critical_damping;
  ζ < 0: below it);
* **constant D**: 100, 150, 200 N·m·s/rad with the monitor, as `run-admittance` runs constant
  damping.

Every firm operator (i % 3 == 2 of each seed set, as in admittance_paper.py) meets D 50 and every
policy with the same seed.  Per policy and cycle: wins against D 50 on ξ (true), the mean paired
relative difference with its 95 % CI (t), runs counted as oscillating (admittance_paper.py's
definition, unchanged) and torque-stop trips.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import admittance_paper as ap  # noqa: E402

ZETAS = (-0.1, 0.0, 0.1, 0.2, 0.3, 0.5)


def oracle_floor(zeta: float):
    """``floor(operator)`` for :func:`admittance_paper.run_one`: a grip floor from the operator's true state."""
    from kukaid.control.stability import CouplingFloor, critical_damping

    def make(op):
        p = op.p
        arm_delay = p.reflex_share * p.reflex_delay if hasattr(p, "reflex_share") else p.delay

        class OracleFloor(CouplingFloor):
            def step(self, gamma_r: float, contact: bool, D_in_use: float = 0.0) -> float:
                super().step(gamma_r, contact, D_in_use)  # keeps the robot-lag estimate and events
                K = (float(op.K) if hasattr(op, "K") else p.K) if contact else 0.0
                if K <= 0.0:
                    self.floor = 0.0
                    return 0.0
                w = math.sqrt(K / self.I)
                T = self._filter_delay(w) + self.cycle + self.robot_lag + arm_delay
                self.floor = min(max(critical_damping(K, self.I, T) + 2.0 * zeta * math.sqrt(K * self.I), 0.0),
                                 self.D_cap)
                return self.floor

        return OracleFloor

    return make


def policies(with_monitor_off: bool = True):
    from kukaid.control.stability import CouplingConfig

    out = [("adaptive (shipped)", dict(damping="adaptive", D=50.0))]
    for z in ZETAS:
        out.append((f"oracle zeta {z:+.1f}", dict(damping="adaptive", D=50.0, floor=oracle_floor(z))))
    if with_monitor_off:
        for z in ZETAS:
            out.append((f"oracle zeta {z:+.1f}, no monitor", dict(damping="adaptive", D=50.0, floor=oracle_floor(z),
                                                                   coupling=CouplingConfig(monitor_lobes=100))))
    out += [(f"constant D {D:.0f}", dict(damping="constant", D=D)) for D in (100.0, 150.0, 200.0)]
    return out


def run(seeds: list[int], cycles: tuple[float, ...], arm: str) -> dict:
    model = ap.controller_model()
    res: dict = {}
    pol = policies()
    for cyc in cycles:
        ref = [ap.run_one(model, s, "constant", 50.0, cyc, grip="firm", arm=arm) for s in seeds]
        rows = []
        for label, kw in pol:
            kw = dict(kw)
            damping, D = kw.pop("damping"), kw.pop("D")
            rs = [ap.run_one(model, s, damping, D, cyc, grip="firm", arm=arm, **kw) for s in seeds]
            pr = ap.paired(np.array([r["xi_true"] for r in rs]), np.array([r["xi_true"] for r in ref]))
            rows.append({"policy": label, "wins": pr["wins"], "n": pr["n"], "rel": pr["rel"],
                         "ci_rel": [c / pr["mean_b"] for c in pr["ci"]], "xi_true": pr["mean_a"],
                         "oscillating": int(sum(r["oscillating"] for r in rs)),
                         "torque_stop": int(sum(r["torque_stop"] for r in rs))})
            print(f"  {cyc * 1000:.0f} ms {label}: {rows[-1]['wins']}/{rows[-1]['n']} osc {rows[-1]['oscillating']}",
                  file=sys.stderr, flush=True)
        res[f"{cyc:g}"] = {"D50": {"xi_true": float(np.mean([r["xi_true"] for r in ref])),
                                   "oscillating": int(sum(r["oscillating"] for r in ref))}, "rows": rows}
    return res


def print_table(res: dict, seeds: list[int], arm: str) -> None:
    print(f"\n== firm grips ({arm}, {len(seeds)} operators): each policy vs constant D 50 with its monitor ==")
    for cyc, r in res.items():
        print(f"\n-- {float(cyc) * 1000:.0f} ms: D 50 mean xi (true) {r['D50']['xi_true']:.2f}, "
              f"oscillating {r['D50']['oscillating']} --")
        print(f"{'policy':>30} | {'wins':>7} | {'xi rel [95% CI]':>24} | {'osc':>3} {'stop':>4}")
        for row in r["rows"]:
            print(f"{row['policy']:>30} | {row['wins']:3d}/{row['n']:3d} | {100 * row['rel']:+6.1f}% "
                  f"[{100 * row['ci_rel'][0]:+6.1f}, {100 * row['ci_rel'][1]:+6.1f}] | {row['oscillating']:3d} "
                  f"{row['torque_stop']:4d}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed-offsets", default="0,1000,2000,3000,4000")
    parser.add_argument("--operators", type=int, default=30, help="per seed set (a third are firm)")
    parser.add_argument("--cycles", default="0.024,0.012")
    parser.add_argument("--arm", choices=("human", "spring"), default="human")
    parser.add_argument("--json", action="store_true", help="print the results as JSON instead of the table")
    a = parser.parse_args()
    offsets = [int(x) for x in a.seed_offsets.split(",")]
    if a.arm == "human":
        seeds = [o + i for o in offsets for i in range(a.operators) if i % 3 == 2]
    else:  # SpringArm's grip comes from its own stiffness draw
        seeds = [o + i for o in offsets for i in range(a.operators) if ap.SpringArm(o + i, 0.0, 0.0).p.grip == "firm"]
    res = run(seeds, tuple(float(c) for c in a.cycles.split(",")), a.arm)
    if a.json:
        print(json.dumps({"seeds": seeds, "arm": a.arm, "results": res}, indent=1))
    else:
        print_table(res, seeds, a.arm)


if __name__ == "__main__":
    main()
