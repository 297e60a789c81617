"""How the robot fit's defaults were chosen on real data without looking at the held-out recording.

Blocked cross-validation on the fit recording only (``lwr4_1``): it is cut into K time blocks;
each block in turn is held out, the others are fitted (as separate logs), and the held-out block
is predicted. The score is the mean over folds of the mean relative error over the joints
(``||tau - tau_hat|| / ||tau||``). A setting is chosen by this score; the error on ``lwr4_3`` (a
different trajectory) is printed in a separate column for the record, never used to choose.

Run: python benchmarks/robot_lwr4_selection.py [--json] [--blocks 3]
     python benchmarks/robot_lwr4_selection.py --matrix   (defaults: every fit -> predict direction, per joint)
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
DATA = HERE.parent.parent / "shared" / "datasets" / "lwr4"

CANDIDATES = {
    "defaults": {},
    "no consistency (LS)": {"consistent": False},
    "no spring term": {"spring": False},
    "ripple 2": {"ripple": 2},
    "ripple 3": {"ripple": 3},
    "ripple 4": {"ripple": 4},
    "ripple 6": {"ripple": 6},
    "ripple 8": {"ripple": 8},
    "cutoff 3 Hz": {"cutoff": 3.0},
    "no prior": {"prior_weight": 0.0},
    "prior 1e-2": {"prior_weight": 1e-2},
    "prior 1e-1": {"prior_weight": 1e-1},
    "no reversal window": {"reversal_window": 0.0},
    "reversal window 1": {"reversal_window": 1.0},
    "cutoff 2 Hz": {"cutoff": 2.0},
    "cutoff 5 Hz": {"cutoff": 5.0},
    "tanh Coulomb 0.05": {"v_smooth": 0.05},
    "tanh Coulomb 0.1": {"v_smooth": 0.1},
    "Stribeck vs 0.1": {"friction": "stribeck", "vs": 0.1},
    "weights 1/rms torque": {"weighting": "torque"},
    "unweighted": {"weighting": "none"},
    "weights torque, 2 Hz": {"weighting": "torque", "cutoff": 2.0},
}


def cv_score(log, robot, settings, blocks: int) -> float:
    from kukaid.diagnose.validate import to_json, validate
    from kukaid.identify.fitted import RobotFile
    from kukaid.identify.robot_fit import fit_robot

    n = log.n_samples
    edges = np.linspace(0, n, blocks + 1).astype(int)
    scores = []
    for k in range(blocks):
        train = [log.select(slice(edges[i], edges[i + 1])) for i in range(blocks) if i != k]
        test = log.select(slice(edges[k], edges[k + 1]))
        p = fit_robot(train, robot, settings)
        scores.append(to_json(validate(RobotFile(p, robot=robot), [test]))["mean_relative_error"])
    return float(np.mean(scores))


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--blocks", type=int, default=3)
    ap.add_argument("--only", nargs="*", default=None)
    ap.add_argument("--matrix", action="store_true", help="defaults only: relative error per joint, every direction")
    a = ap.parse_args()
    if not DATA.is_dir():
        print(f"{DATA}: not found", file=sys.stderr)
        return 1
    from kukaid.diagnose.validate import to_json, validate
    from kukaid.identify.fitted import RobotFile
    from kukaid.identify.robot_fit import RobotFitSettings, fit_robot
    from kukaid.logs import read_log
    from kukaid.models.robot import RobotModel

    robot = RobotModel(DATA / "kuka_lwr4.urdf")
    if a.matrix:
        logs = {k: read_log(DATA / f"lwr4_{k}.csv") for k in (1, 2, 3)}
        fits = {k: fit_robot([lg], robot, RobotFitSettings()) for k, lg in logs.items()}
        out = []
        for f, p in ((1, 3), (2, 3), (3, 1), (3, 2), (1, 2), (2, 1)):
            v = to_json(validate(RobotFile(fits[f], robot=robot), [logs[p]]))
            e = [v["axes"][f"A{j}"]["rel_error"] for j in range(1, robot.n + 1)]
            out.append({"fit": f"lwr4_{f}", "predict": f"lwr4_{p}", "axes": e, "mean": v["mean_relative_error"]})
            if not a.json:
                print(f"lwr4_{f} -> lwr4_{p}  " + " ".join(f"{100 * x:5.1f}" for x in e)
                      + f"  mean {100 * v['mean_relative_error']:5.1f} %")
        if a.json:
            print(json.dumps(out, indent=1))
        return 0
    l1, l3 = read_log(DATA / "lwr4_1.csv"), read_log(DATA / "lwr4_3.csv")
    rows = []
    for name, kw in CANDIDATES.items():
        if a.only and name not in a.only:
            continue
        s = RobotFitSettings(**kw)
        cv = cv_score(l1, robot, s, a.blocks)
        v3 = to_json(validate(RobotFile(fit_robot([l1], robot, s), robot=robot), [l3]))
        rows.append({"setting": name, "cv_lwr4_1": cv, "lwr4_3": v3["mean_relative_error"],
                     "lwr4_3_axes": [r["rel_error"] for r in v3["axes"].values()]})
        if not a.json:
            r = rows[-1]
            print(f"{name:<22} CV(lwr4_1) {100 * cv:6.1f} %   lwr4_3 {100 * r['lwr4_3']:6.1f} %  "
                  + " ".join(f"{100 * x:5.1f}" for x in r["lwr4_3_axes"]), flush=True)
    if a.json:
        print(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
