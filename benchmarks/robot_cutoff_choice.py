"""The robot fit's low-pass cut-off chosen by held-out error, on the six-axis virtual KR C4 (known truth).

Per seed: three recordings of the KR 6 R700 sixx (the simulator's truth seed = the seed: links
perturbed 15 % from the URDF's, its friction, torque noise ``--noise-rel`` of the torque scale),
each a different Fourier trajectory; the fit on the first two with the cut-off chosen (the default:
each recording left out in turn; one recording keeps 10 Hz) and with it fixed at each candidate
(10 Hz: the default before the choice); all validated on the third against the same target: the raw measured torques on the same samples (two periods of the
lowest candidate cut-off trimmed at each end), per joint ``||tau - tau_hat|| / ||tau||``.

Run: python benchmarks/robot_cutoff_choice.py [--seeds 0 1 2] [--duration 20] [--noise-rel 0.002] [--quant-deg 1e-4]
     [--json] [--quick]
"""
from __future__ import annotations

import argparse
import json
import math
import sys

import numpy as np


def recordings(seed: int, duration: float, noise_rel: float, quant_deg: float, n: int = 3):
    """``n`` recordings of the virtual KR C4 (truth seed ``seed``), each its own trajectory."""
    from kukaid.excite.fourier import fourier
    from kukaid.sim.robot_plant import RobotSimConfig, VirtualRobotKRC4

    cfg = RobotSimConfig(truth_seed=seed, noise_rel=noise_rel, quant_deg=quant_deg)
    out = []
    for k in range(n):
        traj = fourier("kr6-r700-sixx", harmonics=4, period=duration / 2.0, periods=2, seed=100 * seed + k + 1,
                       iterations=0, starts=2, span=0.6)
        out.append(VirtualRobotKRC4(cfg, seed=1000 * seed + k).run(traj, settle=0.5))
    return out


def heldout_error(params: dict, logs, edge_s: float) -> np.ndarray:
    """(n,) relative error against the raw torques of ``logs``, pooled, on samples ``edge_s`` from the ends."""
    from kukaid.identify.robot_fit import predict_robot

    num, den = 0.0, 0.0
    for lg in logs:
        pred = predict_robot(params, lg)
        e = int(math.ceil(edge_s / lg.sample_time))
        rows = slice(e, lg.n_samples - e)
        tau = np.column_stack([lg.channel("tau", a)[rows] for a in sorted(pred)])
        th = np.column_stack([pred[a][rows] for a in sorted(pred)])
        num, den = num + np.sum((tau - th) ** 2, axis=0), den + np.sum(tau ** 2, axis=0)
    return np.sqrt(num / den)


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, nargs="*", default=[0, 1, 2])
    ap.add_argument("--duration", type=float, default=20.0, help="s of excitation per recording")
    ap.add_argument("--noise-rel", type=float, default=0.002, help="the simulator's torque noise (its default)")
    ap.add_argument("--quant-deg", type=float, default=1e-4, help="encoder quantum, deg (the simulator's)")
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--quick", action="store_true", help="one seed, 8 s recordings (what the test suite runs)")
    a = ap.parse_args()
    if a.quick:
        a.seeds, a.duration = a.seeds[:1], 8.0
    from kukaid.identify.robot_fit import CUTOFF_GRID, RobotFitSettings, fit_robot
    from kukaid.models.robot import RobotModel

    robot = RobotModel("kr6-r700-sixx")
    edge = 2.0 / min(CUTOFF_GRID)
    rows = []
    for seed in a.seeds:
        logs = recordings(seed, a.duration, a.noise_rel, a.quant_deg)
        chosen = fit_robot(logs[:2], robot, RobotFitSettings())
        co = chosen["metrics"]["choices"]["cutoff"]
        # every candidate fitted at that cut-off (the chosen one is the default fit itself)
        fits = {fc: chosen if fc == co["chosen"] else fit_robot(logs[:2], robot, RobotFitSettings(cutoff=fc))
                for fc in co["candidates"]}
        rows.append({"seed": seed, "chosen_hz": co["chosen"], "candidates_hz": co["candidates"],
                     "fold_error_mean": co["mean_relative_error"],
                     "heldout": {f"{fc:g}": heldout_error(p, logs[2:], edge).tolist() for fc, p in fits.items()}})
    if a.json:
        print(json.dumps({"noise_rel": a.noise_rel, "quant_deg": a.quant_deg, "duration_s": a.duration, "rows": rows},
                         indent=1))
        return 0
    print("mean relative error over the joints, %: the two fit recordings, each left out in turn (the choice's "
          "evidence) | the third recording")
    for r in rows:
        blk = " ".join(f"{c:g}Hz {100 * e:.2f}" for c, e in zip(r["candidates_hz"], r["fold_error_mean"]))
        oth = " ".join(f"{c}Hz {100 * np.mean(e):.2f}" for c, e in r["heldout"].items())
        print(f"seed {r['seed']}: chosen {r['chosen_hz']:g} Hz | {blk} | {oth}")
    ch = np.mean([np.mean(r["heldout"][f"{r['chosen_hz']:g}"]) for r in rows])
    fx = np.mean([np.mean(r["heldout"]["10"]) for r in rows if "10" in r["heldout"]])
    print(f"mean over seeds on the third recording: chosen {100 * ch:.2f} %, 10 Hz {100 * fx:.2f} % (raw torques, "
          f"{edge:g} s trimmed at each end; noise_rel {a.noise_rel:g}, quant_deg {a.quant_deg:g})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
