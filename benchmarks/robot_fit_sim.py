"""Accuracy of the whole-robot fit on simulated KR 6 R700 sixx logs (the tests' helper: Pinocchio
RNEA with seeded true links 15-40 % away from the bundled nominal ones, Coulomb-viscous friction,
offset, noise 0.05 N·m, multi-sine trajectory), over several seeds.

Prints per seed: the number of well-excited base parameters (:func:`well_excited`: least-squares
sigma times the residual correlation factor under 0.5 % of the estimate; the former rule, bare sigma
under 0.5 % of the true value, beside it), their largest relative error and largest error in units of
sigma (bare and corrected), the largest
relative friction error (Fc, Fv) and whether the estimate is physically consistent.

Run: python benchmarks/robot_fit_sim.py [--seeds 0 1 2] [--duration 60] [--json]
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, nargs="*", default=[0, 1, 2])
    ap.add_argument("--duration", type=float, default=60.0)
    ap.add_argument("--prior-weight", type=float, default=None, help="fit setting (default: the fit's default)")
    ap.add_argument("--cutoff", type=float, default=None, help="fit setting, Hz (default: the fit's default)")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    from robot_sim_helpers import simulated_log

    from kukaid.identify.robot_fit import RobotFitSettings, fit_robot, well_excited
    from kukaid.models.robot import RobotModel

    robot = RobotModel("kr6-r700-sixx")
    base = robot.base_parameters()
    rows = []
    for seed in a.seeds:
        log, truth = simulated_log(robot, duration=a.duration, seed=seed)
        kw = {k: v for k, v in (("prior_weight", a.prior_weight), ("cutoff", a.cutoff)) if v is not None}
        p = fit_robot([log], robot, RobotFitSettings(**kw))
        tb = base.of(truth["pi"])
        bp = p["base_parameters"]
        est, ls, sd = (np.asarray(bp[k]) for k in ("values", "least_squares", "sigma"))
        cf = p["metrics"]["residual_correlation_factor"]
        well = well_excited(p)                         # from the fit alone (sigma x correlation factor < 0.5 %)
        fr = p["friction"]["values"]
        ferr = max(abs(fr[f"A{j + 1}.{k}"] - truth[k][j]) / truth[k][j] for j in range(robot.n) for k in ("Fc", "Fv"))
        rel = np.abs(est - tb) / np.abs(tb)
        bare = sd < 0.005 * np.abs(tb)                 # the former rule: bare sigma against the true value
        row = {"seed": seed, "base": base.size, "well_excited": int(well.sum()),
               "max_rel_err_well": float(np.max(rel[well])),
               "max_err_sigma_ls_well": float(np.max(np.abs(ls - tb)[well] / sd[well])),
               "max_err_sigma_est_well": float(np.max(np.abs(est - tb)[well] / sd[well])),
               "max_err_corrected_sigma_est_well": float(np.max(np.abs(est - tb)[well] / (cf * sd[well]))),
               "bare_rule_well_excited": int(bare.sum()), "bare_rule_max_rel_err": float(np.max(rel[bare])),
               "max_rel_err_friction": float(ferr), "consistent": p["metrics"]["physically_consistent"],
               "condition_number": p["metrics"]["condition_number"],
               "residual_correlation_factor": cf}
        rows.append(row)
        if not a.json:
            print(f"seed {seed}: {row['well_excited']}/{row['base']} well excited, max error "
                  f"{100 * row['max_rel_err_well']:.2f} % ({row['max_err_sigma_est_well']:.1f} sigma, "
                  f"{row['max_err_corrected_sigma_est_well']:.1f} corrected; least squares "
                  f"{row['max_err_sigma_ls_well']:.1f} sigma) [bare-sigma rule: {row['bare_rule_well_excited']}, max "
                  f"{100 * row['bare_rule_max_rel_err']:.2f} %], friction max {100 * ferr:.2f} %, consistent "
                  f"{'yes' if row['consistent'] else 'NO'}, cond {row['condition_number']:.0f}, "
                  f"residual correlation factor {row['residual_correlation_factor']:.2f}", flush=True)
    if a.json:
        print(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
