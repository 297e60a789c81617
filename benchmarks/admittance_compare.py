"""Constant vs adaptive (RBF) damping on the same seeded operators: the paper's experiment-4 table.

Usage: python benchmarks/admittance_compare.py PARAMS.json [--seeds 0-9] [--operator pull]

For every seed both controllers meet the same simulated operator (the same seed draws the same
hand and the same noise); prints mean square dΓr (N²m²), mean cost ξ, displacement (rad),
Γr RMSE vs the true external torque, and the number of seeds where adaptive is lower.
Paper (reference, not a target): mean square dΓr 0.051 (adaptive) vs 0.060; ξ 1.309 vs 1.7853.
"""
from __future__ import annotations

import argparse
import math

import numpy as np


def run_one(params: dict, damping: str, seed: int, operator: str, duration: float = 9.0) -> dict:
    from kukaid.robot import SimRobot
    from kukaid.control.loop import LoopConfig, run_admittance
    from kukaid.params import model_from_params
    from kukaid.sim import SimConfig, VirtualKRC4
    from kukaid.sim.operator import make_operator

    q0 = math.radians(30.0)
    cfg = LoopConfig(damping=damping, duration=duration)
    op = make_operator(operator, seed, q0 + cfg.init_move, t_start=cfg.init_time + cfg.init_rest + 0.8)
    be = SimRobot(VirtualKRC4(SimConfig(), seed=seed), q0, op)
    run = run_admittance(be, model_from_params(params), cfg, zeta0=(params.get("maxwell_slip") or {}).get("zeta0"))
    return run.metrics


def main() -> None:
    from kukaid.params import load_params

    ap = argparse.ArgumentParser()
    ap.add_argument("params")
    ap.add_argument("--seeds", default="0-9")
    ap.add_argument("--operator", default="pull")
    a = ap.parse_args()
    lo, _, hi = a.seeds.partition("-")
    seeds = range(int(lo), int(hi or lo) + 1)
    params = load_params(a.params)
    rows = []
    print(f"operator {a.operator}; columns: mean sq dGr (N^2m^2), mean cost xi, displacement (rad), Gr RMSE (N*m)")
    print(f"{'seed':>4} | {'constant':^34} | {'adaptive':^34}")
    for s in seeds:
        c = run_one(params, "constant", s, a.operator)
        d = run_one(params, "adaptive", s, a.operator)
        rows.append((c, d))
        f = lambda m: f"{m['mean_sq_dgamma']:7.4f} {m['mean_cost']:7.4f} {m['displacement']:+7.3f} {m['residual_rmse']:6.3f}"
        print(f"{s:>4} | {f(c)} | {f(d)}")
    for key in ("mean_sq_dgamma", "mean_cost"):
        cv = np.array([r[0][key] for r in rows])
        dv = np.array([r[1][key] for r in rows])
        print(f"{key}: constant mean {np.nanmean(cv):.4f}, adaptive mean {np.nanmean(dv):.4f}; "
              f"adaptive lower on {int(np.sum(dv < cv))}/{len(rows)} seeds")


if __name__ == "__main__":
    main()
